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

*Broad phase.*  A k-d tree (``scipy.spatial.cKDTree``) of element bounding
spheres gives, for every slave, the master elements within reach: cost
``O(n log n)``, not ``O(n^2)``.  Each candidate gets a rigorous lower bound
of its distance (to the capsules around the chords of the element's three
sub-arcs, :func:`_capsules`); candidates bounded beyond ``reach`` go.

*Narrow phase.*  A safeguarded Newton projection of the slave point on a
candidate cubic element (parameter clamped to the element, started from
the best of five samples; monomial coefficients, vectorized over pairs).
Per slave the candidate with the smallest bound is projected first, then
only those whose bound is below the closest admissible distance found: the
same answer as projecting every candidate, with a number of projections
per slave that stays bounded under refinement (``Pairs.n_candidates``
counts the projections).  Per slave the closest admissible projection is
kept; a projection that lands on the exclusion boundary is not a contact
and is dropped.
"""
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..element import shape_functions


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


def _coefficients(r_el):
    """Monomial coefficients ``(m, 4, 3)`` of element curves ``r_el``."""
    return _MONO @ r_el


def _curve(C, xi):
    """Positions and first/second xi-derivatives ``(3, m)`` of element
    curves given by monomial coefficients ``C`` ``(4, 3, m)`` (component
    major: every operation runs on contiguous rows)."""
    c1, c2, c3 = C[1], C[2], C[3]
    y = ((c3 * xi + c2) * xi + c1) * xi + C[0]
    y1 = (3.0 * c3 * xi + 2.0 * c2) * xi + c1
    y2 = 6.0 * c3 * xi + 2.0 * c2
    return y, y1, y2


def _project(x, C, iterations=12):
    """:func:`project` for points ``x`` ``(3, m)`` on curves ``C``
    ``(4, 3, m)``; also returns the closest points ``(3, m)``."""
    m = x.shape[1]
    samples = np.linspace(0.0, 1.0, 5)
    d2 = np.stack([np.sum((((C[3] * t + C[2]) * t + C[1]) * t + C[0] - x) ** 2, axis=0)
                   for t in samples])
    xi = samples[np.argmin(d2, axis=0)]
    todo = np.arange(m)
    Ct, xt, xit = C, x, xi.copy()
    for _ in range(iterations):
        y, y1, y2 = _curve(Ct, xit)
        g = y - xt
        n1 = np.sum(y1 * y1, axis=0)
        f = np.sum(g * y1, axis=0)
        fp = n1 + np.sum(g * y2, axis=0)
        # Newton where the distance is locally convex, a gradient step else
        step = np.where(fp > 1e-12 * n1, f / np.where(fp == 0, 1, fp), 0.25 * np.sign(f))
        new = np.clip(xit - step, 0.0, 1.0)
        moved = np.abs(new - xit) > 1e-15
        xi[todo] = new
        if not moved.all():
            todo, Ct, xt, xit = todo[moved], Ct[:, :, moved], xt[:, moved], new[moved]
            if todo.size == 0:
                break
        else:
            xit = new
    y, y1, _ = _curve(C, xi)
    g = y - x
    f = np.abs(np.sum(g * y1, axis=0))
    interior = (xi > 0.0) & (xi < 1.0) & (f <= 1e-9 * (np.sqrt(np.sum(y1 * y1, axis=0))
                                                          * np.sqrt(np.sum(g * g, axis=0)) + 1e-300))
    return xi, interior, y


def project(x, r_el, iterations=12):
    """Closest points on cubic curves ``r_el`` ``(m, 4, 3)`` (scikit-fem
    local node order) to points ``x`` ``(m, 3)``, parameter in [0, 1].

    Returns ``xi`` (m,) and a flag ``interior`` (stationary point strictly
    inside the element)."""
    C = np.ascontiguousarray(_coefficients(r_el).transpose(1, 2, 0))
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


def search(mesh, r, slaves, reach, exclusion):
    """All slave/master pairs with a centreline distance below ``reach``.

    Parameters
    ----------
    mesh : RodMesh
    r : (n_nodes, 3) nodal positions
    slaves : Slaves
    reach : float
        Largest centreline distance of interest (``2 eps`` plus a margin).
    exclusion : float
        Excluded arclength around each slave (see module docstring).

    Notes
    -----
    The candidates (slave, master element) come from a k-d tree of element
    bounding spheres; each gets a lower bound of its distance, that to the
    element's chord capsule (:func:`_capsules`).  Per slave, the candidate
    with the smallest bound (preferring elements wholly outside ``I_s``) is
    projected first; then only candidates whose bound is below the closest
    admissible distance found so far are projected.  The answer is the same
    as projecting every candidate (a skipped candidate cannot be closer),
    at a cost per slave that does not grow under mesh refinement.
    """
    ne, ns = slaves.s.shape
    r_el = r[mesh.nodes]                                     # (ne, 4, 3)
    C = _coefficients(r_el).transpose(1, 2, 0)               # (4, 3, ne)
    x = np.einsum("qI,eIc->eqc", slaves.N, r_el).reshape(-1, 3)
    s_sl = slaves.s.ravel()
    p0, p1, dev = _capsules(r_el)                            # sub-arc capsules
    # bounding spheres of the whole element curves (rigorous: whole chord
    # capsule, deviation bounded as for the sub-arcs)
    e0, e1, edev = _capsules(r_el, 1)
    centre = 0.5 * (e0[:, 0] + e1[:, 0])
    rad = 0.5 * np.linalg.norm(e1[:, 0] - e0[:, 0], axis=1) + edev[:, 0]
    tree_s, tree_c = cKDTree(x), cKDTree(centre)
    cand = tree_s.sparse_distance_matrix(tree_c, rad.max() + reach, output_type="ndarray")
    i, j = cand["i"].astype(np.int64), cand["j"].astype(np.int64)
    keep = cand["v"] <= rad[j] + reach
    # drop master elements that lie entirely inside the excluded arclength
    lo, hi = mesh.vertices[j], mesh.vertices[j + 1]
    si = s_sl[i]
    keep &= (lo <= si - exclusion) | (hi >= si + exclusion)
    i, j = i[keep], j[keep]
    # lower bound of the distance: to the nearest sub-arc capsule
    lb = np.full(i.size, np.inf)
    for q in range(p0.shape[1]):
        a0 = p0[j, q]
        xp = x[i] - a0
        cj = p1[j, q] - a0
        t = np.clip(np.einsum("ij,ij->i", xp, cj)
                    / np.maximum(np.einsum("ij,ij->i", cj, cj), 1e-300), 0.0, 1.0)
        lb = np.minimum(lb, np.linalg.norm(xp - t[:, None] * cj, axis=1) - dev[j, q])
    keep = lb < reach
    i, j, lb = i[keep], j[keep], lb[keep]
    if i.size == 0:
        return _empty(0)
    si = s_sl[i]
    outside = (mesh.vertices[j] >= si + exclusion) | (mesh.vertices[j + 1] <= si - exclusion)
    order = np.lexsort((lb, ~outside, i))
    first = order[np.r_[True, i[order][1:] != i[order][:-1]]]

    xT = np.ascontiguousarray(x.T)

    def narrow(k):
        jk = j[k]
        xi, interior, y = _project(xT[:, i[k]], C[:, :, jk])
        s_bar = mesh.vertices[jk] + xi * (mesh.vertices[jk + 1] - mesh.vertices[jk])
        dvec = (xT[:, i[k]] - y).T
        dist = np.linalg.norm(dvec, axis=1)
        ok = (np.abs(s_bar - s_sl[i[k]]) >= exclusion) & (dist < reach) & (dist > 0)
        return k[ok], xi[ok], interior[ok], s_bar[ok], dvec[ok], dist[ok]

    r1 = narrow(first)
    best = np.full(ne * ns, np.inf)
    best[i[r1[0]]] = r1[5]
    rest = np.ones(i.size, bool)
    rest[first] = False
    rest &= lb <= best[i] * (1.0 + 1e-10)
    second = np.flatnonzero(rest)
    n_cand = first.size + second.size
    r2 = narrow(second)
    k, xi, interior, s_bar, dvec, dist = (np.concatenate([u, v]) for u, v in zip(r1, r2))
    if k.size == 0:
        return _empty(n_cand)
    ik = i[k]
    order = np.lexsort((k, dist, ik))        # ties: first candidate, as a full pass would
    sel = order[np.r_[True, ik[order][1:] != ik[order][:-1]]]
    isel = ik[sel]
    return Pairs(slave=isel, s_elem=isel // ns, s_xi=slaves.xi[isel % ns], m_elem=j[k[sel]],
                 m_xi=xi[sel], s=s_sl[isel], s_bar=s_bar[sel], distance=dist[sel],
                 normal=dvec[sel] / dist[sel, None], interior=interior[sel],
                 weight=slaves.w.ravel()[isel], n_candidates=n_cand)


def _empty(n_cand):
    z = np.zeros(0)
    zi = np.zeros(0, dtype=np.int64)
    return Pairs(slave=zi, s_elem=zi, s_xi=z, m_elem=zi, m_xi=z, s=z, s_bar=z,
                 distance=z, normal=np.zeros((0, 3)), interior=np.zeros(0, bool),
                 weight=z, n_candidates=n_cand)
