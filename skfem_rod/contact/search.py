r"""Contact search: slave points, broad phase, closest-point projection.

Slaves are the ``n_slave`` Gauss points of every element (the paper's
three, sec. 7.1).  Each slave ``s`` is projected on the rod outside its
excluded neighbourhood ``I_s`` (eq. 3.1):

    s_bar = argmin_{|sigma - s| >= exclusion} |r(s) - r(sigma)|.

*Exclusion length.*  Neighbouring points of a rod are always closer than
its diameter, so pairs with ``|sigma - s| < exclusion`` are never contacts.
For a rod whose radius of curvature never falls below its radius ``eps``,
the chord between two points ``Delta s`` apart is at least
``2 eps sin(Delta s / (2 eps))``, which first reaches the contact distance
``2 eps`` at ``Delta s = pi eps``: the default is ``exclusion = pi eps``.

*Closed rods.*  On a closed rod (``mesh.closed``) arclength distances are
periodic, ``min(|s - sigma|, L - |s - sigma|)``: the exclusion wraps around
the closure point, so an unloaded ring has no contact.

*Broad phase.*  A branch and bound down a hierarchy of element capsules
(:func:`_broad_phase`, :func:`_hierarchy`): nodes of ``4^k`` consecutive
elements, each a chord with a rigorous bound of the curve's distance from
it.  It starts with a k-d tree query (``scipy.spatial.cKDTree``) at the
level whose nodes are about ``reach`` long and descends level by level,
dropping before they are expanded the nodes wholly inside the slave's
exclusion (its own neighbours) and those farther than an upper bound of the
slave's closest admissible distance.  The candidates alive per slave stay
bounded whatever the ratio of element size to contact radius, so memory
and time grow linearly with the number of elements
(``benchmarks/bench_search.py``; the exhaustive query of every element
within reach grew as ``n^2`` when elements are shorter than the radius).
Each candidate gets a rigorous lower bound of its distance (to the
capsules around the chords of the element's three sub-arcs,
:func:`_capsules`); candidates bounded beyond ``reach`` go.

*Neighbour list.*  Between the searches of one solve the nodes move by
little (Newton iterations, proximal and damped steps), so the
:class:`~skfem_rod.problem.Problem` keeps the broad phase's pairs in a
:class:`NeighbourList` (a Verlet list): found with a margin of ``2 LEBESGUE
skin`` and kept until a node has moved ``skin`` (half a contact radius) or
the reach has grown.  Every distance then changes by less than the margin,
so the kept pairs hold every candidate of a new broad phase, and the
search returns the same pairs (``tests/test_contact_search.py``).

*Narrow phase.*  A safeguarded Newton projection of the slave point on a
candidate cubic element (parameter clamped to the element, started from
the best of five samples; monomial coefficients, the iterations per pair
in a compiled loop: :mod:`.kernels`).
Per slave the candidate with the smallest bound is projected first, then
only those whose bound is below the closest admissible distance found: the
same answer as projecting every candidate, with a number of projections
per slave that stays bounded under refinement (``Pairs.n_candidates``
counts the projections).  Per slave the closest admissible projection is
kept; a projection that lands on the exclusion boundary is not a contact
and is dropped.

*Kinks at nodes: the master element is kept.*  The interpolated centreline
is C0 at the nodes: its tangent turns by a small angle there.  A slave on
the concave side of a node has two orthogonal projections, one on each
element, at distances that differ by a hair; the closest one switches
element as the slave moves by a hair, and with it the contact normal (the
two normals differ by the kink angle), so the residual jumps.  A Newton
solve then 2-cycles between the two choices (measured in the plectoneme's
damped steps: residual 0.396 <-> 0.429 for ever, one slave flipping
between xi = 0.993 on one element and xi = 0.005 on the next, distances
2.00028 eps both).  With a :class:`Preference` (the master element each
slave had at the last evaluation and a ``tolerance``) the search keeps a
slave's master element as long as its projection there is within
``tolerance`` of the closest one: the gap it reports is then at most
``tolerance`` above the true one (``Problem`` passes ``KEEP_MASTER`` = 10 %
of the contact tolerance), and Newton sees one smooth branch.  Only an
orthogonal projection (interior) is kept: where the closest point has
crossed a node onto the next element, the last element's projection is
clamped at its end, farther by a hair but with its normal tilted, and
keeping it made the residual depend on the evaluation before (on the smooth
curve, which has no kink, the plectoneme's damped Newton 2-cycled on it:
residual 0.032 <-> 0.044, and 0.008 from a fresh search).  In the knot
of demos/knot.py the switches come with distance differences of 1e-3 eps
and more on iterates far from converged, and this does not remove them.
The smooth contact curve (:mod:`.curve`) has no kinks to switch at.
"""
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..element import shape_functions


@dataclass(frozen=True)
class Preference:
    """The master element ``element[k]`` slave ``k`` had last (-1: none),
    kept while its projection is within ``tolerance`` of the closest."""
    element: np.ndarray
    tolerance: float


@dataclass
class Slaves:
    """Slave points: ``n_slave`` Gauss points per element."""
    xi: np.ndarray        # (ns,) reference coordinates in an element
    N: np.ndarray         # (ns, 4) shape functions at xi
    s: np.ndarray         # (ne, ns) arclengths
    w: np.ndarray         # (ne, ns) integration weights (ds)


def slave_points(mesh, n_slave=3):
    """Gauss points used as contact slaves."""
    x, w = np.polynomial.legendre.leggauss(n_slave)
    xi, w = 0.5 * (x + 1), 0.5 * w
    h = np.diff(mesh.vertices)
    N, _, _ = shape_functions(xi)
    return Slaves(xi=xi, N=N.T, s=mesh.vertices[:-1, None] + h[:, None] * xi,
                  w=h[:, None] * w)


@dataclass
class Pairs:
    """Closest-point pairs, one per slave in contact range."""
    slave: np.ndarray     # (m,) global slave index  e * ns + q
    s_elem: np.ndarray    # (m,) slave element
    s_xi: np.ndarray      # (m,) slave reference coordinate
    m_elem: np.ndarray    # (m,) master element
    m_xi: np.ndarray      # (m,) master reference coordinate
    s: np.ndarray         # (m,) slave arclength
    s_bar: np.ndarray     # (m,) master arclength
    distance: np.ndarray  # (m,) |r(s) - r(s_bar)|
    normal: np.ndarray    # (m, 3) N = (r(s) - r(s_bar)) / distance
    interior: np.ndarray  # (m,) projection inside the element (stationary)
    weight: np.ndarray    # (m,) quadrature weight (ds) of the slave point
    n_candidates: int = 0 # narrow-phase candidate pairs tested

    @property
    def size(self):
        return self.slave.size


#: monomial coefficients of the cubic from its nodal values (local order
#: 0, 1, 1/3, 2/3): ``y(xi) = sum_p (_MONO @ r_el)[p] xi^p``
_MONO = np.linalg.inv(np.vander(np.array([0.0, 1.0, 1.0 / 3.0, 2.0 / 3.0]), 4,
                                increasing=True))


def monomial_coefficients(r_el):
    """Monomial coefficients ``(m, 4, 3)`` of element curves ``r_el``."""
    return _MONO @ r_el


def curve_position(C, xi):
    """The positions alone of :func:`curve_point` (the same Horner scheme,
    the same round-off): ``C`` ``(4, 3, ...)``, ``xi`` broadcasting
    against ``C[0]``."""
    return ((C[3] * xi + C[2]) * xi + C[1]) * xi + C[0]


def curve_point(C, xi):
    """Positions and first/second xi-derivatives ``(3, m)`` of element
    curves given by monomial coefficients ``C`` ``(4, 3, m)`` (component
    major: every operation runs on contiguous rows)."""
    c1, c2, c3 = C[1], C[2], C[3]
    y = curve_position(C, xi)
    y1 = (3.0 * c3 * xi + 2.0 * c2) * xi + c1
    y2 = 6.0 * c3 * xi + 2.0 * c2
    return y, y1, y2


#: the start of the projection: the best of five samples of the element
_SAMPLES = np.linspace(0.0, 1.0, 5)
_SAMPLE_POWERS = np.vander(_SAMPLES, 4, increasing=True)          # (5, 4): 1, t, t^2, t^3


def _project(x, C, iterations=12):
    """:func:`project` for points ``x`` ``(3, m)`` on curves ``C``
    ``(4, 3, m)``; also returns the closest points ``(3, m)``.

    The Newton iterations run per point in a compiled loop
    (:func:`skfem_rod.contact.kernels.projection_newton`), with the
    coefficients of the first and second derivatives formed once (``3
    c3``, ``2 c2``, ``6 c3``: the products :func:`curve_point` forms, so
    the same round-off)."""
    from .kernels import projection_newton
    d = np.einsum("tp,pcm->tcm", _SAMPLE_POWERS, C) - x       # (5, 3, m)
    xi = _SAMPLES[np.argmin(np.einsum("tcm,tcm->tm", d, d), axis=0)]
    E = np.concatenate([C, [3.0 * C[3], 2.0 * C[2], 6.0 * C[3]]])   # (7, 3, m)
    xi = projection_newton(np.ascontiguousarray(x, dtype=float), E, xi, int(iterations))
    dot = np.add.reduce          # np.sum over the components, without its wrapper
    y, y1, _ = curve_point(C, xi)
    g = y - x
    f = np.abs(dot(g * y1, axis=0))
    interior = (xi > 0.0) & (xi < 1.0) & (f <= 1e-9 * (np.sqrt(dot(y1 * y1, axis=0))
                                                          * np.sqrt(dot(g * g, axis=0)) + 1e-300))
    return xi, interior, y


def project(x, r_el, iterations=12):
    """Closest points on cubic curves ``r_el`` ``(m, 4, 3)`` (scikit-fem
    local node order) to points ``x`` ``(m, 3)``, parameter in [0, 1].

    Returns ``xi`` (m,) and a flag ``interior`` (stationary point strictly
    inside the element)."""
    C = np.ascontiguousarray(monomial_coefficients(r_el).transpose(1, 2, 0))
    xi, interior, _ = _project(np.ascontiguousarray(x.T), C, iterations)
    return xi, interior


#: shape functions at xi = k / 9: the element split in three sub-arcs
_NINTHS = np.stack(shape_functions(np.arange(10) / 9.0)[0], axis=1)   # (10, 4)


def _capsules(r_el, parts=3):
    """Chord ends ``p0, p1`` ``(ne, parts, 3)`` of ``parts`` equal sub-arcs
    of every element curve and bounds ``dev`` ``(ne, parts)`` on the
    distance of each sub-arc from its chord: a cubic minus its chord is
    ``xi (1 - xi) (A + B xi)`` on the sub-arc's own parameter (it vanishes
    at both ends), so ``|y - chord| <= max(|A|, |A + B|) / 4``."""
    pts = np.einsum("kI,eIc->ekc", _NINTHS if parts == 3 else
                    np.stack(shape_functions(np.arange(3 * parts + 1) / (3.0 * parts))[0], 1),
                    r_el)
    p0, q1, q2, p1 = pts[:, 0:-1:3], pts[:, 1::3], pts[:, 2::3], pts[:, 3::3]
    e1 = q1 - (2.0 * p0 + p1) / 3.0                  # = (2/9) (A + B/3)
    e2 = q2 - (p0 + 2.0 * p1) / 3.0                  # = (2/9) (A + 2B/3)
    dev = 0.25 * np.maximum(np.linalg.norm(9.0 * e1 - 4.5 * e2, axis=-1),
                            np.linalg.norm(9.0 * e2 - 4.5 * e1, axis=-1))
    return p0, p1, dev


def arc_distance(a, b, period=None):
    """Arclength distance ``|a - b|``, periodic (``min(|a - b|, P - |a - b|)``)
    for a closed rod of length ``period``."""
    d = np.abs(a - b)
    return d if period is None else np.minimum(d, period - d)


def _inside_exclusion(lo, hi, s, exclusion, period=None):
    """Arcs ``[lo, hi]`` wholly inside the excluded neighbourhood
    ``(s - exclusion, s + exclusion)`` (taken modulo ``period`` on a closed
    rod)."""
    if period is None:
        return (lo > s - exclusion) & (hi < s + exclusion)
    t = np.mod(lo - (s - exclusion), period)
    return (t > 0) & (t + (hi - lo) < 2.0 * exclusion)


def _outside_exclusion(lo, hi, s, exclusion, period=None):
    """Arcs ``[lo, hi]`` wholly outside ``(s - exclusion, s + exclusion)``."""
    if period is None:
        return (lo >= s + exclusion) | (hi <= s - exclusion)
    t = np.mod(lo - (s + exclusion), period)
    return t + (hi - lo) <= period - 2.0 * exclusion


def arclength_period(mesh):
    """The rod's length if it is closed (periodic arclength), else None."""
    if getattr(mesh, "closed", False):
        return float(mesh.vertices[-1] - mesh.vertices[0])
    return None


#: children per node of the capsule hierarchy of the broad phase
BRANCHING = 4
#: the broad phase starts at the coarsest level whose nodes are at most
#: ``START * reach`` long (measured: 0.5 to 4 give the same cost within
#: the timing noise of the shared machine)
START = 1.0


def _segment_distance(x, a, b):
    """Distance of points ``x`` to segments ``[a, b]`` and the segment
    parameter ``t`` of the closest point (all ``(3, m)``: component major,
    every operation on contiguous rows)."""
    ab = b - a
    xa = x - a
    den = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2]
    t = (xa[0] * ab[0] + xa[1] * ab[1] + xa[2] * ab[2]) / np.maximum(den, 1e-300)
    np.clip(t, 0.0, 1.0, out=t)
    xa -= t * ab
    return np.sqrt(xa[0] * xa[0] + xa[1] * xa[1] + xa[2] * xa[2]), t


def _norm3(d):
    """Norms of the columns of ``d`` ``(3, m)``."""
    return np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])


def _hierarchy(r_el, branching=BRANCHING):
    """Capsule hierarchy over the elements in arclength order.

    Level ``k`` has nodes of ``branching^k`` consecutive elements (the last
    one shorter); a node is the chord between its end vertices and a bound
    ``dev`` on the distance of its curve from that chord: for the elements
    that of :func:`_capsules`, for a parent the largest over its children
    of the child's bound plus the distance of the child's chord from the
    parent's (a convex function: largest at the child's chord ends).  Per
    level ``(first, last, dev)``: first and one-past-last element (the
    chord runs from vertex ``first`` to vertex ``last``)."""
    ne = r_el.shape[0]
    vx = np.concatenate([r_el[:, 0], r_el[-1:, 1]])          # vertex positions
    vxT = np.ascontiguousarray(vx.T)
    _, _, edev = _capsules(r_el, 1)
    first = np.arange(ne)
    levels = [(first, first + 1, edev[:, 0])]
    size = 1
    while first.size > 1:
        cf, cl, cd = levels[-1]
        size *= branching
        first = np.arange(0, ne, size)
        last = np.minimum(first + size, ne)
        m = first.size
        pad = np.minimum(np.arange(m * branching), cf.size - 1).reshape(m, branching)
        a = np.repeat(vxT[:, first], branching, axis=1)
        b = np.repeat(vxT[:, last], branching, axis=1)
        d0, _ = _segment_distance(vxT[:, cf[pad].ravel()], a, b)
        d1, _ = _segment_distance(vxT[:, cl[pad].ravel()], a, b)
        dev = (cd[pad] + np.maximum(d0, d1).reshape(m, branching)).max(axis=1)
        levels.append((first, last, dev))
    return vxT, levels


def _broad_phase(x, s_sl, r_el, vertices, reach, exclusion, period, branching=BRANCHING,
                 margin=0.0):
    """Candidate (slave, element) pairs: the elements not wholly inside the
    slave's excluded arclength whose capsule comes closer than ``reach``
    and than an upper bound of the slave's closest admissible distance
    (with ``margin``: closer than ``reach + margin`` and than that bound
    plus ``2 margin``, so that the pairs stay a superset of the answer
    while every distance changes by at most ``margin``: a
    :class:`NeighbourList`).

    Branch and bound down the capsule hierarchy (:func:`_hierarchy`),
    vectorized over the slaves level by level.  It starts at the level
    whose nodes are about ``reach`` long (a k-d tree query of the slaves
    against the nodes' bounding spheres: a bounded number per slave); at
    every level it drops the nodes wholly inside the slave's exclusion
    (its own neighbours) before they are expanded, and the nodes whose
    lower bound (distance to the chord minus ``dev``) exceeds an upper
    bound of the closest admissible distance: the distance to the vertex
    nearest the slave's projection on a chord, if that vertex is at least
    ``exclusion + h_max`` from the slave (the element beside it then lies
    wholly outside the exclusion, and its projection is at most that far).
    The pairs alive per slave stay bounded for any ratio of element size to
    radius: memory and time linear in the number of elements."""
    vxT, levels = _hierarchy(r_el, branching)
    xT = np.ascontiguousarray(x.T)
    h = np.diff(vertices)
    h_mean, h_max = h.mean(), h.max()
    K = 0
    while K + 1 < len(levels) and branching ** (K + 1) * h_mean <= START * reach:
        K += 1
    f, l, dev = levels[K]
    centre = 0.5 * (vxT[:, f] + vxT[:, l]).T
    rad = 0.5 * _norm3(vxT[:, l] - vxT[:, f]) + dev
    tree_s, tree_c = cKDTree(x), cKDTree(centre)
    cand = tree_s.sparse_distance_matrix(tree_c, rad.max() + reach + margin,
                                         output_type="ndarray")
    i, j = cand["i"].astype(np.int64), cand["j"].astype(np.int64)
    ub = np.full(x.shape[0], np.inf)
    for k in range(K, -1, -1):
        f, l, dev = levels[k]
        fj, lj = f[j], l[j]
        keep = ~_inside_exclusion(vertices[fj], vertices[lj], s_sl[i], exclusion, period)
        i, j, fj, lj = i[keep], j[keep], fj[keep], lj[keep]
        xi = xT[:, i]
        dist, t = _segment_distance(xi, vxT[:, fj], vxT[:, lj])
        lb = dist - dev[j]
        v = fj + np.rint(t * (lj - fj)).astype(np.int64)
        ok = np.flatnonzero(arc_distance(vertices[v], s_sl[i], period) >= exclusion + h_max)
        np.minimum.at(ub, i[ok], _norm3(xi[:, ok] - vxT[:, v[ok]]))
        keep = (lb < reach + margin) & (lb <= ub[i] * (1.0 + 1e-10) + 2.0 * margin)
        i, j = i[keep], j[keep]
        if k == 0:
            break
        n_child = levels[k - 1][0].size
        j = (branching * j[:, None] + np.arange(branching)).ravel()
        i = np.repeat(i, branching)
        keep = j < n_child
        i, j = i[keep], j[keep]
    keep = lb[keep] <= ub[i] * (1.0 + 1e-10) + 2.0 * margin
    return i[keep], j[keep]


#: Lebesgue constant of the cubic element's nodal basis (equispaced
#: nodes), with a hair of slack: no point of an element curve moves more
#: than this times the largest move of the element's nodes
LEBESGUE = 1.0001 * float(np.abs(np.stack(shape_functions(np.linspace(0.0, 1.0, 20001))[0]))
                          .sum(axis=0).max())


@dataclass
class NeighbourList:
    """Broad-phase candidates kept between searches (a Verlet list).

    The broad phase (:func:`_broad_phase`) is run with a margin ``2
    spread skin`` and its pairs are kept while no node has moved more
    than ``skin`` from where they were found and ``reach`` has not grown:
    a slave point and an element curve then move by at most ``spread
    skin`` each, every distance by at most the margin, and the kept pairs
    are a superset of what a new broad phase would return.  The narrow
    phase sees the same closest points (a candidate beyond them is bounded
    out or projected farther), so a search with the list gives the answer
    of one without it; the lower bounds of the candidates are recomputed
    at every search.  Newton iterations, proximal and damped steps move the
    nodes by small amounts, so most searches skip the broad phase.

    ``spread``: how far a point of what is searched moves where no node
    moves by more than one unit -- ``LEBESGUE`` for points of the element
    curves (the default), 1 for the nodes themselves (the node barrier's
    pairs, :mod:`.barrier`), whose margin is then ``2 skin``."""
    skin: float
    spread: float = LEBESGUE
    r: np.ndarray = None          # nodal positions where the pairs were found
    reach: float = None           # the reach they were found for
    i: np.ndarray = None
    j: np.ndarray = None
    builds: int = 0               # broad phases run (benchmarks, tests)

    def pairs(self, r, reach, find):
        """The kept ``(i, j)``, or new ones from ``find(margin)`` when
        ``r`` moved beyond ``skin`` or ``reach`` grew."""
        if (self.r is None or r.shape != self.r.shape or not reach <= self.reach
                or not np.einsum("nc,nc->n", r - self.r, r - self.r).max() <= self.skin ** 2):
            # (written so that a NaN also finds the pairs anew, as without the list)
            self.i, self.j = find(2.0 * self.spread * self.skin)
            self.r, self.reach = r.copy(), reach
            self.builds += 1
        return self.i, self.j


@dataclass(frozen=True)
class _Query:
    """One search: the slave points (positions ``x`` ``(n, 3)`` and ``xT``
    ``(3, n)``, arclengths ``s`` ``(n,)``), the element curves (monomial
    coefficients ``C`` ``(4, 3, ne)``, ``vertices``), the arclength
    ``period`` (None: open rod), ``reach`` and ``exclusion``."""
    x: np.ndarray
    xT: np.ndarray
    s: np.ndarray
    C: np.ndarray
    vertices: np.ndarray
    period: object
    reach: float
    exclusion: float
    prefer: Preference = None


def search(mesh, r, slaves, reach, exclusion, prefer=None, neighbours=None):
    """All slave/master pairs with a centreline distance below ``reach``.

    Parameters
    ----------
    mesh : RodMesh
        On a closed rod (``mesh.closed``) arclength distances are periodic:
        the exclusion wraps around the closure point.
    r : (n_nodes, 3) nodal positions
    slaves : Slaves
    reach : float
        Largest centreline distance of interest (``2 eps`` plus a margin).
    exclusion : float
        Excluded arclength around each slave (see module docstring).
    prefer : :class:`Preference`, optional
        The master elements to keep (module docstring: kinks at nodes).
    neighbours : :class:`NeighbourList`, optional
        Broad-phase pairs kept between searches of one rod (same answer).

    Notes
    -----
    The candidates (slave, master element) come from a branch and bound
    down a hierarchy of element bounding spheres (:func:`_broad_phase`),
    which prunes the slave's own neighbours by the exclusion length and far
    elements by an upper bound of the closest distance before they are
    materialized; each candidate gets a lower bound of its distance, that
    to the element's chord capsule (:func:`_capsules`).  Per slave, the
    candidate with the smallest bound (preferring elements wholly outside
    ``I_s``) is projected first; then only candidates whose bound is below
    the closest admissible distance found so far are projected.  The
    answer is the same as projecting every element (a skipped candidate
    cannot be closer), at a cost per slave that does not grow under mesh
    refinement.
    """
    r_el = r[mesh.nodes]                                     # (ne, 4, 3)
    x = np.einsum("qI,eIc->eqc", slaves.N, r_el).reshape(-1, 3)
    q = _Query(x=x, xT=np.ascontiguousarray(x.T), s=slaves.s.ravel(),
               C=monomial_coefficients(r_el).transpose(1, 2, 0),      # (4, 3, ne)
               vertices=mesh.vertices, period=arclength_period(mesh), reach=reach,
               exclusion=exclusion, prefer=prefer)
    i, j, lb = _candidates(q, r_el, r, neighbours)
    if i.size == 0:
        return _empty(0)
    found, n_cand = _narrow_phase(q, i, j, lb)
    if found[0].size == 0:
        return _empty(n_cand)
    return _closest(q, slaves, i, j, found, n_cand)


def _candidates(q, r_el, r, neighbours=None):
    """Candidate (slave ``i``, element ``j``) pairs of the broad phase (or
    of the :class:`NeighbourList` ``neighbours`` at nodal positions ``r``)
    in a deterministic order, with ``lb``, a lower bound of their distance
    (to the nearest sub-arc capsule, :func:`_capsules`), below ``reach``."""
    p0, p1, dev = _capsules(r_el)                            # sub-arc capsules
    ne = r_el.shape[0]

    def find(margin=0.0):
        i, j = _broad_phase(q.x, q.s, r_el, q.vertices, q.reach, q.exclusion, q.period,
                            margin=margin)
        order = np.argsort(i * ne + j, kind="stable")        # deterministic order:
        return i[order], j[order]                            # by slave, then element
    i, j = find() if neighbours is None else neighbours.pairs(r, q.reach, find)
    key = i * ne + j
    if not np.all(key[1:] > key[:-1]):                       # (kept pairs come sorted)
        order = np.argsort(key, kind="stable")
        i, j = i[order], j[order]
    # the bound to the nearest sub-arc capsule, the three sub-arcs at once:
    # chord ends (3, parts, k), the slave points broadcast over the parts
    # (``take`` on component-major copies: gathers of contiguous rows)
    parts = p0.shape[1]
    a = np.ascontiguousarray(p0.transpose(2, 1, 0)).reshape(3 * parts, -1)
    b = np.ascontiguousarray(p1.transpose(2, 1, 0)).reshape(3 * parts, -1)
    dq, _ = _segment_distance(q.xT.take(i, axis=1)[:, None],
                              a.take(j, axis=1).reshape(3, parts, -1),
                              b.take(j, axis=1).reshape(3, parts, -1))
    lb = np.minimum.reduce(dq - np.ascontiguousarray(dev.T).take(j, axis=1), axis=0,
                           initial=np.inf)
    keep = lb < q.reach
    return i[keep], j[keep], lb[keep]


def _project_candidates(q, i, j, k):
    """Projections of the candidates ``k`` (slave ``i[k]`` on element
    ``j[k]``), the admissible ones: ``(k, xi, interior, s_bar, dvec,
    dist)``."""
    jk = j[k]
    v = q.vertices
    x = q.xT.take(i[k], axis=1)
    xi, interior, y = _project(x, q.C.take(jk, axis=2))
    s_bar = v[jk] + xi * (v[jk + 1] - v[jk])
    dvec = (x - y).T
    dist = np.linalg.norm(dvec, axis=1)
    ok = ((arc_distance(s_bar, q.s[i[k]], q.period) >= q.exclusion) & (dist < q.reach)
          & (dist > 0))
    return k[ok], xi[ok], interior[ok], s_bar[ok], dvec[ok], dist[ok]


def _narrow_phase(q, i, j, lb):
    """Branch and bound per slave: the candidate with the smallest bound
    (elements wholly outside the exclusion first) projected, then those
    whose bound is below the closest admissible distance found.  Returns
    the admissible projections (:func:`_project_candidates`, both passes)
    and the number of candidates projected."""
    v = q.vertices
    outside = _outside_exclusion(v[j], v[j + 1], q.s[i], q.exclusion, q.period)
    order = np.lexsort((lb, ~outside, i))
    first = order[np.r_[True, i[order][1:] != i[order][:-1]]]
    r1 = _project_candidates(q, i, j, first)
    best = np.full(q.s.size, np.inf)
    best[i[r1[0]]] = r1[5]
    rest = np.ones(i.size, bool)
    rest[first] = False
    keep = lb <= best[i] * (1.0 + 1e-10)
    if q.prefer is not None:                 # the preferred element, if it can be kept
        keep |= (q.prefer.element[i] == j) & (lb <= best[i] + q.prefer.tolerance)
    rest &= keep
    second = np.flatnonzero(rest)
    r2 = _project_candidates(q, i, j, second)
    found = tuple(np.concatenate([u, w]) for u, w in zip(r1, r2))
    return found, first.size + second.size


def _closest(q, slaves, i, j, found, n_cand):
    """The :class:`Pairs`: per slave the closest admissible projection of
    ``found`` (:func:`_narrow_phase`)."""
    ns = slaves.s.shape[1]
    k, xi, interior, s_bar, dvec, dist = found
    ik = i[k]
    key = dist
    if q.prefer is not None:                 # the last master element, within tolerance,
        # where its projection is orthogonal (interior): one clamped to an
        # element end is not a projection of the curve, only of the element
        key = np.where((q.prefer.element[ik] == j[k]) & interior, dist - q.prefer.tolerance,
                       dist)
    order = np.lexsort((k, key, ik))         # ties: first candidate, as a full pass would
    sel = order[np.r_[True, ik[order][1:] != ik[order][:-1]]]
    isel = ik[sel]
    return Pairs(slave=isel, s_elem=isel // ns, s_xi=slaves.xi[isel % ns], m_elem=j[k[sel]],
                 m_xi=xi[sel], s=q.s[isel], s_bar=s_bar[sel], distance=dist[sel],
                 normal=dvec[sel] / dist[sel, None], interior=interior[sel],
                 weight=slaves.w.ravel()[isel], n_candidates=n_cand)


def _empty(n_cand):
    z = np.zeros(0)
    zi = np.zeros(0, dtype=np.int64)
    return Pairs(slave=zi, s_elem=zi, s_xi=z, m_elem=zi, m_xi=z, s=z, s_bar=z,
                 distance=z, normal=np.zeros((0, 3)), interior=np.zeros(0, bool),
                 weight=z, n_candidates=n_cand)
