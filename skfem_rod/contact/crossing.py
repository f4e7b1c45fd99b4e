r"""Curve-to-curve contact of crossing strands: the true minimum distance
between strands and point-to-point contact pairs at the minima of the
strand distance (after Meier, Popp & Wall 2016-2017: all-angle beam
contact, its point-to-point part).

Point-to-curve pairs at Gauss slave points (the paper's, :mod:`.search`)
miss strands that cross between two slave points: with elements several
contact radii long two strands can overlap by most of a radius while no
slave point sees the other strand.  Here both parameters are free: for a
pair of elements ``(e, f)`` the closest points ``X(u)``, ``Y(v)``
(``u, v`` in [0, 1]) solve

    min_{u, v} |X(u) - Y(v)|^2 / 2,    X, Y the cubic element curves,

by a safeguarded 2 x 2 Newton (projected on the box, one-sided where a
parameter sits on a bound, backtracking; started from the three best points
of a 7 x 7 grid, the best result kept), per pair in a compiled loop
(:mod:`.kernels`).
Candidates come from a k-d tree of element bounding spheres, then a lower
bound of their distance (chord to chord minus the bounds of each curve's
distance from its chord, :func:`_bounds`); element pairs wholly inside the
excluded arclength (periodic on a closed rod) go before they are solved,
closest points closer than ``exclusion`` in arclength are dropped (as in
:mod:`.search`).  :func:`min_distance` solves the pairs in order of their
lower bound and stops at the closest admissible distance found (branch and
bound).  The design (thresholds, weights, why) is docs/crossing-contact.md.

* :func:`min_distance`: the smallest distance between non-neighbouring
  strands, with its arclengths (``s, s_bar``): the true penetration
  ``2 eps - distance`` of a state, whatever the slave density.
* :func:`crossing_pairs`: a point pair at every strict local minimum of
  the strand distance (interior, or on a node held by the kink of the C0
  centreline), both parameters free, with a weight (:func:`_weigh`): how
  far the distance rises at probes half a Gauss-point gap before and after
  the minimum on either strand, against a minimum at the angle the Gauss
  slave points sample to the tolerance (:func:`sampled_angle`), times a
  factor of the local effective angle.  1 at a crossing, 0 at a line
  contact (the Gauss pairs' job), continuous where a minimum hops along a
  flat valley, splits, crosses a node, forms or vanishes.
  Multipliers are carried by place, ``(s, s_bar)`` (:func:`carry`), not
  by element pair.
* :func:`crossing_work`: a point force at the pair, gap
  ``d = 2 eps - |X(u) - Y(v)|`` and the augmented-Lagrangian law of
  :mod:`.law` (``f = [d + mu lambda]_+ / mu``, a force, ``mu`` a compliance
  per unit force) times the weight; residual and exact tangent with the
  free parameters' closest-point conditions differentiated (the reduced
  Hessian ``F_qq - F_qp F_pp^{-1} F_pq`` of ``F = l^2 / 2``; a parameter
  held on a node does not move) and the weight's derivative.

A crossing pair and Gauss-point pairs can act at one crossing together:
redundant constraints of the same gap, which the augmented Lagrangian
handles (the multipliers share the load; the converged state is the same).
"""
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from ..element import shape_functions
from .law import gap, normal_force, potential
from .search import (monomial_coefficients, curve_point, curve_position, arclength_period,
                     arc_distance, project)


#: minima closer than this fraction of an element in both arclengths are
#: one crossing (:func:`_one_per_crossing`)
TWIN = 0.05


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _hessian(D, X1, X2, Y1, Y2):
    """The Hessian ``(F_uu, F_vv, F_uv)`` of ``F = |X(u) - Y(v)|^2 / 2`` in
    the curve parameters, from ``D = X - Y`` and the curves' first and second
    derivatives (components on the first axis)."""
    return _dot(X1, X1) + _dot(D, X2), _dot(Y1, Y1) - _dot(D, Y2), -_dot(X1, Y1)


def closest_points(C1, C2, iterations=40, grid=7, starts=3):
    """Closest points ``(u, v)`` of cubic curve pairs with monomial
    coefficients ``C1``, ``C2`` ``(4, 3, m)``; also their distance: the
    best of :func:`local_minima`."""
    k, u, v, d = local_minima(C1, C2, iterations, grid, starts)
    first = np.r_[True, k[1:] != k[:-1]]            # sorted by pair, closest first
    return u[first], v[first], d[first]


def local_minima(C1, C2, iterations=40, grid=7, starts=3):
    """The distinct local minima of the distance between cubic curve pairs
    (monomial coefficients ``C1``, ``C2`` ``(4, 3, m)``): the safeguarded
    Newton runs from the ``starts`` lowest local minima of a ``grid x
    grid`` sampling (topped up with its lowest other points), and results
    closer than :data:`TWIN` in both parameters to a closer one of the same
    pair are dropped.  Returns ``(k, u, v, d)``: the pair index of each
    minimum, its parameters and distance, at least one per pair.

    A result held on the element's end (a node) does not shadow an interior
    one: in the plectoneme's winding (friction, 1.96 turns) a strict
    interior minimum 0.044 from a node, carrying a crossing pair of force
    19.6, had a closer result on the node 0.05 away in both parameters,
    which the node test then dropped (the neighbour element held a closer
    point).  When the parameters came within 0.05 for a state change of
    1e-5, the pair vanished with its force, and every damped step failed
    down to ``dt`` = 7e-9.

    Two wrapped strands can have two minima in one element pair, half an
    element apart at nearly equal distances.  Keeping only the closer one
    (as before) let the minimum hop between the two for state changes of
    1e-6, and a crossing pair following it moved by half an element (the
    plectoneme's winding, 2.06 turns: Newton failed at every pseudo-time
    step down to 1e-8 of the first)."""
    m = C1.shape[2]
    t = np.linspace(0.0, 1.0, grid)
    tg = t[:, None, None]
    P1, P2 = curve_position(C1, tg), curve_position(C2, tg)                # (g, 3, m)
    d2 = np.sum((P1[:, None] - P2[None]) ** 2, axis=2)                      # (g, g, m)
    pad = np.full((grid + 2, grid + 2, m), np.inf)        # d2 with a border of inf
    pad[1:-1, 1:-1] = d2
    # a grid point is a local minimum where it is not above any of its 8
    # neighbours: not above their minimum (a NaN among them: no minimum)
    around = np.full(d2.shape, np.inf)
    for a in (0, 1, 2):
        for b in (0, 1, 2):
            if (a, b) != (1, 1):
                np.minimum(around, pad[a:a + grid, b:b + grid], out=around)
    lowest = d2 <= around
    d2 = d2.reshape(grid * grid, m)
    rank = d2 + ~lowest.reshape(grid * grid, m) * (d2.max(axis=0) + 1.0)    # local minima first
    k = _lowest_rows(rank, starts).ravel()                                  # (starts * m,)
    u, v, d = _newton(np.tile(C1, starts), np.tile(C2, starts), t[k // grid], t[k % grid],
                      iterations)
    pair = np.repeat(np.arange(m)[None], starts, axis=0).ravel()
    # closest first per pair; a result next to a closer kept one is dropped
    order = np.lexsort((d, pair))
    pair, u, v, d = pair[order], u[order], v[order], d[order]
    at_rank = np.arange(pair.size) % starts                  # starts results per pair
    keep = np.ones(pair.size, bool)
    # a result held on the element's end (a node) shadows no interior one:
    # whether it is a minimum at all is decided with the neighbour element
    # (_node_minimum), and one crossing's twins are merged by place later
    # (_one_per_crossing)
    inside = (u > 0) & (u < 1) & (v > 0) & (v < 1)
    for j in range(1, starts):
        at = np.flatnonzero(at_rank == j)
        for o in range(1, j + 1):
            prev = at - o
            twin = keep[prev] & (np.abs(u[prev] - u[at]) < TWIN) & (np.abs(v[prev] - v[at]) < TWIN)
            twin &= inside[prev] | ~inside[at]
            keep[at[twin]] = False
    return pair[keep], u[keep], v[keep], d[keep]


def _lowest_rows(rank, n):
    """The first ``n`` rows of ``np.argsort(rank, axis=0, kind="stable")``
    (per column the rows of the ``n`` lowest values, ties by row), by ``n``
    arg-minima instead of a sort of every column (a fifth of its time);
    the sort where a value is not finite (a masked pick could then tie)."""
    if not np.isfinite(rank).all():
        return np.argsort(rank, axis=0, kind="stable")[:n]
    r = np.ascontiguousarray(rank.T)                         # one column per row
    cols = np.arange(r.shape[0])
    out = np.empty((n, r.shape[0]), np.int64)
    for i in range(n):
        out[i] = np.argmin(r, axis=1)                        # the first lowest
        r[cols, out[i]] = np.inf
    return out


def _newton(C1, C2, u, v, iterations):
    """Projected, safeguarded Newton on ``|X(u) - Y(v)|^2 / 2`` from
    ``(u, v)`` per pair of curves (monomial coefficients ``C1``, ``C2``
    ``(4, 3, m)``), at most ``iterations`` each; returns ``(u, v,
    distance)``.  The loop per pair is compiled
    (:func:`skfem_rod.contact.kernels.closest_points_newton`, which says
    what an iteration does).

    Where both parameters are free but the quadratic model has no minimum
    (a saddle or a flat valley: wrapped strands) the step is Newton's on
    the Hessian shifted to positive definite, at most a quarter element
    long, so that the halvings search along the valley to where it ends.
    The coordinate steps used there before crept along it (updates of
    1.5e-3 per iteration after 40 iterations in the knot's braid, which
    kept every call at the iteration limit)."""
    from .kernels import closest_points_newton
    C = np.stack([C1, C2], axis=2)                           # (4, 3, 2, m)
    return closest_points_newton(C, np.asarray(u, float), np.asarray(v, float),
                                 int(iterations))


def _segment_pairs(p0, p1, q0, q1):
    """Distance between segments ``[p0, p1]`` and ``[q0, q1]`` (``(3, m)``;
    nonzero lengths), after Ericson, Real-Time Collision Detection 5.1.9."""
    d1, d2, r = p1 - p0, q1 - q0, p0 - q0
    a, e, f = _dot(d1, d1), _dot(d2, d2), _dot(d2, r)
    c, b = _dot(d1, r), _dot(d1, d2)
    den = a * e - b * b
    s = np.where(den > 1e-12 * a * e, np.clip((b * f - c * e) / np.where(den > 0, den, 1.0),
                                              0.0, 1.0), 0.0)
    t = (b * s + f) / e
    s = np.where(t < 0, np.clip(-c / a, 0.0, 1.0), np.where(t > 1, np.clip((b - c) / a, 0.0, 1.0),
                                                            s))
    t = np.clip(t, 0.0, 1.0)
    D = p0 + s * d1 - q0 - t * d2
    return np.sqrt(_dot(D, D))


def _bounds(r_el):
    """Per element: chord ends ``(3, ne)``, a bound ``dev`` of the curve's
    distance from its chord and ``alpha``, a bound of the angle between the
    curve's tangent and its chord.  The curve minus its chord is
    ``xi (1 - xi) (A + B xi)``: ``|dev| <= max(|A|, |A + B|) / 4`` and its
    xi-derivative is at most ``|A| + 1.25 |B|``."""
    p0, p1, q1, q2 = r_el[:, 0], r_el[:, 1], r_el[:, 2], r_el[:, 3]
    e1 = q1 - (2.0 * p0 + p1) / 3.0
    e2 = q2 - (p0 + 2.0 * p1) / 3.0
    B = 13.5 * (e2 - e1)
    A = 9.0 * e1 - 4.5 * e2
    nA, nB = np.linalg.norm(A, axis=1), np.linalg.norm(B, axis=1)
    dev = 0.25 * np.maximum(nA, np.linalg.norm(A + B, axis=1))
    chord = np.linalg.norm(p1 - p0, axis=1)
    alpha = np.arcsin(np.minimum(1.0, (nA + 1.25 * nB) / np.maximum(chord, 1e-300)))
    return np.ascontiguousarray(p0.T), np.ascontiguousarray(p1.T), dev, alpha


def _element_pairs(mesh, r, reach, exclusion):
    """Candidate element pairs ``(e, f)``, ``e < f``, with a lower bound
    ``lb`` of their distance below ``reach`` (chord-to-chord distance minus
    both deviation bounds), not wholly inside each other's excluded
    arclength."""
    r_el = r[mesh.nodes]
    P0, P1, dev, _ = _bounds(r_el)
    centre = 0.5 * (P0 + P1).T
    rad = 0.5 * np.sqrt(_dot(P1 - P0, P1 - P0)) + dev
    P = cKDTree(centre).query_pairs(2 * rad.max() + reach, output_type="ndarray")
    none = np.zeros(0, dtype=np.int64)
    if P.size == 0:
        return none, none, np.zeros(0), r_el
    e = np.minimum(P[:, 0], P[:, 1]).astype(np.int64)
    f = np.maximum(P[:, 0], P[:, 1]).astype(np.int64)
    keep = np.linalg.norm(centre[e] - centre[f], axis=1) - rad[e] - rad[f] < reach
    e, f = e[keep], f[keep]
    v, period = mesh.vertices, arclength_period(mesh)
    # wholly inside: every point of f within the exclusion of every point of
    # e (the largest distance is between end points while both lie on an
    # arc shorter than half the ring)
    far = np.zeros(e.size)
    for a in (v[e], v[e + 1]):
        for b in (v[f], v[f + 1]):
            far = np.maximum(far, arc_distance(a, b, period))
    inside = far < exclusion
    if period is not None:
        inside &= (v[e + 1] - v[e]) + (v[f + 1] - v[f]) + exclusion < 0.5 * period
    e, f = e[~inside], f[~inside]
    lb = (_segment_pairs(P0.take(e, axis=1), P1.take(e, axis=1), P0.take(f, axis=1),
                         P1.take(f, axis=1)) - dev[e] - dev[f])
    keep = lb < reach
    return e[keep], f[keep], lb[keep], r_el


@dataclass
class CrossingPairs:
    """Point-to-point contact pairs: strict local minima of the distance
    between two strands, one per minimum (``e < f`` the elements holding
    it; at a node, one of the element pairs sharing it)."""
    e: np.ndarray         # (m,) first element
    f: np.ndarray         # (m,) second element
    u: np.ndarray         # (m,) reference coordinate on e
    v: np.ndarray         # (m,) on f
    s: np.ndarray         # (m,) arclength of X(u)
    s_bar: np.ndarray     # (m,) arclength of Y(v)
    distance: np.ndarray  # (m,) |X(u) - Y(v)|
    normal: np.ndarray    # (m, 3) (X - Y) / distance
    cos_angle: np.ndarray # (m,) |t_e . t_f| at the closest points
    key: np.ndarray       # (m, 5) s, s_bar, carry radius, beta, held index (:func:`carry`)
    u_free: np.ndarray = None   # (m,) u interior (free); False: at a node (held)
    v_free: np.ndarray = None   # (m,) v interior
    beta: np.ndarray = None     # (m,) effective angle of the minimum (radians)
    length: np.ndarray = None   # (m,) |X(u) - Y(v)| of the acting pair (distance:
                                # the Uzawa gap's, see crossing_pairs)
    weight: np.ndarray = None   # (m,) the pair's share of its force (:func:`_weigh`)
    slope: "WeightSlope" = None  # the weight's derivatives (the tangent's fade blocks)

    @property
    def size(self):
        return self.e.size


@dataclass
class WeightSlope:
    """The derivatives of the pairs' weights ``w(rise, l, sin^2 beta)``
    (:func:`_weigh`) that :func:`crossing_work`'s tangent reads."""
    rise: np.ndarray        # (m,) dw / d rise
    length: np.ndarray      # (m,) dw / d l at a fixed rise
    beta: np.ndarray        # (m,) dw / d sin^2 beta
    probe_dofs: np.ndarray  # (m, 24) position dofs of the lowest probe
    probe_dq: np.ndarray    # (m, 24) its distance's derivative there
    probe_dp: np.ndarray    # (m, 2) and in the pair's parameters u, v
    reading: np.ndarray = None  # (m, 2) which second derivatives the weight's
                                # sin^2 beta reads, per strand (:func:`_fold_reading`)

    def fading(self):
        """Indices of the pairs whose weight has a slope (in a fade zone;
        most pairs sit at weight 1 with all three slopes 0)."""
        return np.flatnonzero((self.rise != 0) | (self.length != 0) | (self.beta != 0))


def _solve(mesh, e, f, r_el, every=False):
    """Closest points of the element pairs ``(e, f)``; with ``every``, each
    distinct local minimum (:func:`local_minima`; ``e``, ``f`` repeated)."""
    C = np.ascontiguousarray(monomial_coefficients(r_el).transpose(1, 2, 0))   # (4, 3, ne)
    if every:
        k, u, v, dist = local_minima(C[:, :, e], C[:, :, f])
        e, f = e[k], f[k]
    else:
        u, v, dist = closest_points(C[:, :, e], C[:, :, f])
    vt = mesh.vertices
    s = vt[e] + u * (vt[e + 1] - vt[e])
    s_bar = vt[f] + v * (vt[f + 1] - vt[f])
    return e, f, u, v, s, s_bar, dist, C


@dataclass
class MinDistance:
    """The closest approach of non-neighbouring strands."""
    distance: float       # inf if no strands within reach
    s: float
    s_bar: float
    elements: tuple
    xi: tuple

    def penetration(self, radius):
        """``2 eps - distance`` (positive: the tubes overlap)."""
        return 2.0 * radius - self.distance


def min_distance(mesh, r, radius, exclusion, reach=None):
    """The true minimum distance between points of the centreline at least
    ``exclusion`` apart in arclength (periodic on a closed rod), over
    element pairs within ``reach`` (default ``3 radius``)."""
    reach = 3.0 * radius if reach is None else reach
    e, f, lb, r_el = _element_pairs(mesh, r, reach, exclusion)
    period = arclength_period(mesh)
    # branch and bound: the pairs with the smallest lower bounds first, then
    # only those whose bound is below the closest admissible distance found
    order = np.argsort(lb, kind="stable")
    e, f, lb = e[order], f[order], lb[order]
    best, out = np.inf, []
    start = 0
    bound = lambda: min(best * (1 - 1e-9), reach)                      # noqa: E731
    while start < e.size and lb[start] < bound():
        stop = min(e.size, start + max(64, start))
        stop = start + int(np.searchsorted(lb[start:stop], bound()))
        sl = slice(start, max(stop, start + 1))
        _, _, u, v, s, s_bar, dist, _ = _solve(mesh, e[sl], f[sl], r_el)
        ok = (arc_distance(s, s_bar, period) >= exclusion) & (dist > 0) & (dist < reach)
        if ok.any():
            k = np.flatnonzero(ok)[np.argmin(dist[ok])]
            if dist[k] < best:
                best = dist[k]
                out = [e[sl][k], f[sl][k], u[k], v[k], s[k], s_bar[k]]
        start = sl.stop
    if not out:
        return MinDistance(np.inf, np.nan, np.nan, (-1, -1), (np.nan, np.nan))
    return MinDistance(float(best), float(out[4]), float(out[5]), (int(out[0]), int(out[1])),
                       (float(out[2]), float(out[3])))


def overlaps(mesh, r, radius, exclusion, depth):
    """The local minima of the strand distance (closest points of element
    pairs, both parameters free; each element pair's distinct minima) where
    the tubes of radius ``radius`` overlap by more than ``depth`` (a
    negative ``depth``: stand apart by less than ``-depth``): arrays
    ``(s, s_bar, penetration)``, ``penetration = 2 radius - distance``.
    Only element pairs whose lower bound lies within ``2 radius - depth``
    are solved."""
    reach = 2.0 * radius - depth
    none = np.zeros(0)
    if reach <= 0:
        return none, none, none
    e, f, lb, r_el = _element_pairs(mesh, r, reach, exclusion)
    keep = lb < reach
    if not keep.any():
        return none, none, none
    _, _, _, _, s, s_bar, dist, _ = _solve(mesh, e[keep], f[keep], r_el, every=True)
    ok = (arc_distance(s, s_bar, arclength_period(mesh)) >= exclusion) & (dist < reach)
    return s[ok], s_bar[ok], 2.0 * radius - dist[ok]


def slave_half_gap(n_slave):
    """The largest arclength from a point of an element to its nearest
    Gauss slave point, in element lengths (0.194 for the paper's three)."""
    if isinstance(n_slave, bool) or not (isinstance(n_slave, (int, np.integer)) and n_slave >= 1):
        raise ValueError(f"n_slave must be an integer >= 1, got {n_slave!r}")
    return _half_gap(int(n_slave))


@lru_cache(maxsize=None)
def _half_gap(n_slave):
    """:func:`slave_half_gap` of a valid ``n_slave``, computed once per
    value (the Gauss points come from an eigenvalue problem: about 0.3 ms,
    and every evaluation with crossing contact asks for it)."""
    x = 0.5 * (np.polynomial.legendre.leggauss(n_slave)[0] + 1.0)
    return float(max(x[0], 0.5 * np.diff(x).max(initial=0.0)))


#: a point pair is added where the Gauss slave points could miss more than
#: this fraction of the contact tolerance at a minimum (:func:`sampled_angle`)
SAMPLING_SHARE = 0.25


def sampled_angle(h, radius, n_slave=3, tolerance=1e-3):
    """The effective angle ``beta_h`` below which the Gauss slave points of
    elements ``h`` long sample a minimum of the strand distance to
    ``SAMPLING_SHARE * tolerance * eps``.  Near a minimum of effective angle
    ``beta`` the distance seen at arclength ``t`` from it along a strand is
    ``2 eps + (t sin beta)^2 / (4 eps)``; ``t`` is at most
    ``slave_half_gap * h``, so ``sin beta_h = 2 eps sqrt(share tol) /
    (half_gap h)``."""
    for name, v in (("radius", radius), ("tolerance", tolerance)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
    h = np.asarray(h, dtype=float)
    if not np.all(np.isfinite(h) & (h > 0)):
        raise ValueError(f"element lengths h must be finite and > 0, got {h!r}")
    x = 2.0 * radius * np.sqrt(SAMPLING_SHARE * tolerance) / (slave_half_gap(n_slave) * h)
    return np.arcsin(np.minimum(x, 1.0))


def _node_minimum(C, e, u, G, ne, closed):
    """For parameters on an element end: does ``F = |X - Y|^2 / 2`` also
    grow into the neighbouring element (``G``: ``dF/du = G . X'``)?  The
    closest point then sits on the node (a local minimum of the whole
    strand, held there by the kink of the C0 centreline or a minimum at the
    node itself); else the neighbour holds the minimum.  True where ``u``
    is interior."""
    ok = np.ones(e.size, bool)
    for end, step in ((u >= 1.0, 1), (u <= 0.0, -1)):
        k = np.flatnonzero(end)
        nb = e[k] + step
        if closed:
            nb = np.mod(nb, ne)
        inside = (nb >= 0) & (nb < ne)                     # the rod's ends: no minimum
        nb = np.where(inside, nb, 0)
        c = C[:, :, nb]
        T = c[1] if step == 1 else c[1] + 2.0 * c[2] + 3.0 * c[3]
        g = _dot(G[:, k], T)
        small = 1e-12 * np.sqrt(_dot(G[:, k], G[:, k]) * _dot(T, T))
        ok[k] = inside & ((g >= -small) if step == 1 else (g <= small))
    return ok


def _minima(mesh, r, radius, exclusion, reach, held=None):
    """Strict local minima of the distance between strands: per minimum
    the elements, parameters, arclengths, distance, ``D = X - Y``, the
    free flags, ``sin^2 beta``, tangents' ``|cos|`` (one per minimum: a
    node minimum is found from every element pair sharing the node)."""
    e, f, lb, r_el = _element_pairs(mesh, r, reach, exclusion)
    e, f, u, v, s, s_bar, dist, C = _solve(mesh, e, f, r_el, every=True)
    period = arclength_period(mesh)
    ok = (arc_distance(s, s_bar, period) >= exclusion) & (dist > 0) & (dist < reach)
    e, f, u, v, s, s_bar, dist = (a[ok] for a in (e, f, u, v, s, s_bar, dist))
    # both strands in one call each (elementwise: the same values as apart)
    n = e.size
    ef, uv = np.concatenate([e, f]), np.concatenate([u, v])
    P, P1, P2 = curve_point(C.take(ef, axis=2), uv)
    X, X1, X2, Y, Y1, Y2 = P[:, :n], P1[:, :n], P2[:, :n], P[:, n:], P1[:, n:], P2[:, n:]
    D = X - Y
    ne = mesh.nodes.shape[0]
    closed = period is not None
    ok = _node_minimum(C, ef, uv, np.concatenate([D, -D], axis=1), ne, closed)
    ok = ok[:n] & ok[n:]
    fu, fv = (u > 0) & (u < 1), (v > 0) & (v < 1)
    n1, n2 = _dot(X1, X1), _dot(Y1, Y1)
    huu, hvv, huv = _hessian(D, X1, X2, Y1, Y2)
    det = huu * hvv - huv * huv
    # a strict minimum in the free parameters (a parameter held on a node
    # sits at a kink: strict there)
    both = fu & fv
    strict = np.where(both, det / np.maximum(huu * hvv, 1e-300),
                      np.where(fu, huu / n1, np.where(fv, hvv / n2, 1.0)))
    ok &= ~((fu & (huu <= 0)) | (fv & (hvv <= 0))) & (strict > 0)
    # the effective angle that weighs it (_weigh): the smooth one of the
    # element pair's curves, a held parameter included.  A minimum on a
    # node is strict by the kink of the C0 centreline, but a kink of a
    # converged curve is tiny: strands wrapped around each other (a flat
    # minimum, beta = 0) have their minimum hop from one strand's node to
    # the other's between states 1e-7 apart (measured in the knot: u = 1,
    # v = 0.1175 <-> u = 0.8825, v = 0), and a pair following it 2-cycled.
    # (Away from nodes, for a strict interior minimum, this is ``strict``.)
    # The curves' second derivatives jump at the nodes (the C1 contact curve
    # too), and with them the curvature terms D.X'' of the Hessian: measured
    # in the plectoneme at 200 elements (curvature 11, D = 2 eps), one node
    # minimum had 26 deg by one element's curve and 5.7 deg by the other's,
    # and its weight jumped between 1 and 0 from one Newton iterate to the
    # next.  The angle that weighs a minimum therefore reads the second
    # derivatives made continuous across the nodes (:func:`_second`).
    k = np.flatnonzero(ok)
    k = k[_canonical(mesh, e[k], f[k], u[k], v[k], s[k], s_bar[k])]
    k = k[_one_per_crossing(s[k], s_bar[k], dist[k],
                            TWIN * float(np.mean(np.diff(mesh.vertices))), held)]
    X2c = _second(mesh, r, np.concatenate([e[k], f[k]]), np.concatenate([u[k], v[k]]))[0].T
    X2c, Y2c = X2c[:, :k.size], X2c[:, k.size:]
    huu, hvv, huv = _hessian(D[:, k], X1[:, k], X2c, Y1[:, k], Y2c)
    sin2 = np.clip((huu * hvv - huv * huv) / np.maximum(np.abs(huu * hvv), 1e-300), 0.0, 1.0)
    cos = np.abs(_dot(X1, Y1)) / np.sqrt(n1 * n2)
    mn = dict(e=e[k], f=f[k], u=u[k], v=v[k], s=s[k], s_bar=s_bar[k], distance=dist[k],
              D=D[:, k].T, u_free=fu[k], v_free=fv[k], sin2=sin2, cos=cos[k])
    _fold_reading(mesh, r, mn, X1[:, k], X2[:, k], Y1[:, k], Y2[:, k])
    return mn


#: a reading of the local angle from the elements' own second derivatives
#: (:func:`_fold_reading`) weighs a minimum where it is below this share of
#: the blended one's ``sin^2 beta``
FOLD_SHARE = 0.25


def _psd_sin2(huu, hvv, huv):
    """``det / (F_uu F_vv)`` of a Hessian, clipped to [0, 1]; 0 where it is
    not positive in both parameters."""
    pos = (huu > 0) & (hvv > 0)
    den = np.where(pos, huu * hvv, 1.0)
    return np.where(pos, np.clip((huu * hvv - huv * huv) / den, 0.0, 1.0), 0.0)


def _nearest_node(mesh, e, u):
    """Per point ``(e, u)``: the share ``g = 1 - a / BLEND`` (clipped to
    [0, 1]; ``a`` the distance in elements to the element's nearer node),
    ``dg/du``, and whether an element lies beyond that node."""
    a = np.minimum(u, 1.0 - u)
    g = 1.0 - a / BLEND
    dg = np.where((g > 0) & (g < 1), np.where(u < 0.5, -1.0, 1.0) / BLEND, 0.0)
    ne = mesh.nodes.shape[0]
    nb = e + np.where(u < 0.5, -1, 1)
    beyond = np.ones(e.size, bool) if arclength_period(mesh) is not None \
        else (nb >= 0) & (nb < ne)
    return np.clip(g, 0.0, 1.0), dg, beyond


def _fold_reading(mesh, r, mn, X1, X2, Y1, Y2):
    """Adds to the minima ``mn`` the ``sin^2 beta`` their weight reads,
    ``weigh_sin2``, and which second derivatives it was read from,
    ``reading`` ``(m, 2)`` (per strand: :data:`BLENDED`, :data:`OWN`,
    :data:`ACROSS`).

    An interior minimum vanishes at a fold of the distance, where its own
    elements' Hessian is singular.  Within :data:`BLEND` of a node the
    blended Hessian (:func:`_second`) need not be: measured in the
    frictional plectoneme at 1.95 turns, a minimum a tenth of an element
    from a node of both strands had ``sin^2 beta`` 7 times the threshold's
    by the blended second derivatives and 6e-6 of it by its own; it
    sat at the fold with weight 1 and force 41.8, and every damped step failed
    (residual 0.016 -> 66).  So the weight also reads the Hessian of the
    elements' own second derivatives, and near a node the one with the
    neighbour's second derivative at that node (as if the minimum had
    crossed it: an indefinite one there reads 0, so a minimum that would
    vanish on crossing fades before it), plus ``1 - g`` (:func:`_nearest_node`:
    0 at the node, 1 from :data:`BLEND` away, where it counts no more).  At
    the node the readings from either element are the same set, so their
    least is continuous as the minimum crosses it, and it is the reading of
    a minimum held on the node (``g = 1``).  That least, divided by
    :data:`FOLD_SHARE`, replaces the blended ``sin^2 beta`` where it is
    smaller."""
    m = mn["e"].size
    mn["weigh_sin2"], mn["reading"] = mn["sin2"].copy(), np.full((m, 2), BLENDED)
    gx, _, bx = _nearest_node(mesh, mn["e"], mn["u"])
    gy, _, by = _nearest_node(mesh, mn["f"], mn["v"])
    # farther than BLEND from the nodes the blended second derivatives are
    # the elements' own, and the reading over FOLD_SHARE is not smaller
    k = np.flatnonzero((gx > 0) | (gy > 0))
    if k.size == 0:
        return
    D, X1, X2, Y1, Y2 = (a[:, k] for a in (mn["D"].T, X1, X2, Y1, Y2))
    across = np.full(k.size, ACROSS)
    X2n = _second(mesh, r, mn["e"][k], mn["u"][k], across)[0].T
    Y2n = _second(mesh, r, mn["f"][k], mn["v"][k], across)[0].T
    px = np.where(bx[k] & (gx[k] > 0), 1.0 - gx[k], np.inf)
    py = np.where(by[k] & (gy[k] > 0), 1.0 - gy[k], np.inf)
    cand = np.array([_psd_sin2(*_hessian(D, X1, X2, Y1, Y2)),
                     _psd_sin2(*_hessian(D, X1, X2n, Y1, Y2)) + px,
                     _psd_sin2(*_hessian(D, X1, X2, Y1, Y2n)) + py,
                     _psd_sin2(*_hessian(D, X1, X2n, Y1, Y2n)) + px + py])
    j = np.argmin(cand, axis=0)
    fold = cand[j, np.arange(k.size)] / FOLD_SHARE
    use = fold < mn["sin2"][k]
    sides = np.array([[OWN, OWN], [ACROSS, OWN], [OWN, ACROSS], [ACROSS, ACROSS]])[j]
    mn["weigh_sin2"][k[use]] = fold[use]
    mn["reading"][k[use]] = sides[use]


#: the second derivatives that weigh a minimum blend across a node within
#: this fraction of an element of it (:func:`_second`)
BLEND = 0.25
#: which second derivatives :func:`_second` gives: blended across the
#: nodes, the element's own, or the neighbour's at the nearer node
BLENDED, OWN, ACROSS = 0, 1, 2
#: third derivatives of the cubic Lagrange shape functions (nodes 0, 1, 1/3, 2/3)
_D3N = np.array([-27.0, 27.0, 81.0, -81.0])
#: second xi-derivatives of the cubic Lagrange shape functions at xi = 0 and 1
_D2N0, _D2N1 = shape_functions(0.0)[2], shape_functions(1.0)[2]


def _second(mesh, r, e, u, reading=None):
    """The second xi-derivative ``X''`` of the curve at ``(e, u)`` made
    continuous across the nodes: the element's own, plus a share ``t`` of
    the jump to the neighbour's at a node (in arclength units, ``X'' /
    h^2``) within :data:`BLEND` of it, ``t = (1 - a / BLEND)^2 / 2`` at
    ``a`` (the distance from the node, in elements).  At a node both
    elements give the mean of their second derivatives; at the rod's ends
    the element's own.  Linear in the positions: returns ``X''`` and
    ``dX''/du`` ``(m, 3)``, the coefficients of ``X''`` on the element's
    nodes ``(m, 4)`` and on its neighbours' ``(m, 8)`` (the element before,
    then after), and those nodes ``(m, 8)``.  ``reading`` ``(m,)``
    (optional, default :data:`BLENDED`): :data:`OWN`, the element's own
    ``X''``; :data:`ACROSS`, the neighbour's at the element's nearer node
    (constant in ``u``; the element's own where there is no neighbour)."""
    ne, vt = mesh.nodes.shape[0], mesh.vertices
    closed = arclength_period(mesh) is not None
    m = e.size
    he = vt[e + 1] - vt[e]
    a = shape_functions(u)[2].T.copy()
    au = np.tile(_D3N, (m, 1))
    b, bu = np.zeros((m, 8)), np.zeros((m, 8))
    nodes = np.empty((m, 8), np.int64)
    for j, (step, a_, sign, own, theirs) in enumerate(((-1, u, 1.0, _D2N0, _D2N1),
                                                        (1, 1.0 - u, -1.0, _D2N1, _D2N0))):
        g = np.clip(1.0 - a_ / BLEND, 0.0, 1.0)
        t, dt = 0.5 * g * g, -sign * g / BLEND             # share and d share / du
        nb = e + step
        ok = np.ones(m, bool) if closed else (nb >= 0) & (nb < ne)
        nb = np.mod(nb, ne) if closed else np.where(ok, nb, e)
        ratio = (he / (vt[nb + 1] - vt[nb])) ** 2
        if reading is not None:
            near = (u < 0.5) if step == -1 else (u >= 0.5)
            t = np.where(reading == OWN, 0.0, np.where(reading == ACROSS, near * 1.0, t))
            dt = np.where(reading == BLENDED, dt, 0.0)
        t, dt = np.where(ok, t, 0.0), np.where(ok, dt, 0.0)
        a -= t[:, None] * own
        au -= dt[:, None] * own
        b[:, 4 * j:4 * j + 4] = (t * ratio)[:, None] * theirs
        bu[:, 4 * j:4 * j + 4] = (dt * ratio)[:, None] * theirs
        nodes[:, 4 * j:4 * j + 4] = mesh.nodes[nb]
    if reading is not None:               # across: the neighbour's alone
        gone = (reading == ACROSS) & (np.abs(b).sum(axis=1) > 0)
        a[gone], au[gone] = 0.0, 0.0
    re, rn = r[mesh.nodes[e]], r[nodes]
    X2 = np.einsum("mk,mkc->mc", a, re) + np.einsum("mk,mkc->mc", b, rn)
    X2u = np.einsum("mk,mkc->mc", au, re) + np.einsum("mk,mkc->mc", bu, rn)
    return X2, X2u, a, b, nodes


def _canonical(mesh, e, f, u, v, s, s_bar):
    """Indices of the minima to keep of one found twice on a node: a
    parameter held on a node is found from the element pairs on either side
    of it, at the same place to round-off.  At a kink of the C0 centreline
    the two differ (``X'`` jumps there, and with it the Hessian that weighs
    the minimum), and which one the clustering of :func:`_one_per_crossing`
    kept flipped with round-off (measured: ``sin^2 beta`` 0.40 against 0.74
    between states 1e-6 apart).  The one on the element after the node is
    kept: a result held at ``u = 1`` (or ``v = 1``) of an element with a
    next one is dropped where a result within 1e-6 of an element in both
    arclengths is not so held."""
    n = e.size
    ne = mesh.nodes.shape[0]
    after = (lambda x: np.ones(x.size, bool)) if arclength_period(mesh) is not None \
        else (lambda x: x + 1 < ne)
    second = ((u >= 1.0) & after(e)) | ((v >= 1.0) & after(f))
    if not second.any() or second.all():
        return np.arange(n)
    tol = 1e-6 * float(np.mean(np.diff(mesh.vertices)))
    first = np.flatnonzero(~second)
    d = cKDTree(np.c_[s[first], s_bar[first]]).query(np.c_[s[second], s_bar[second]],
                                                     p=np.inf)[0]
    keep = np.ones(n, bool)
    keep[np.flatnonzero(second)[d <= tol]] = False
    return np.flatnonzero(keep)


def _one_per_crossing(s, s_bar, dist, within, held=None):
    """Indices (sorted) of the minima to keep: of the minima closer than
    ``within`` in both arclengths (a cluster, transitively), the one nearest
    to a held pair's place (``held``: ``(s, s_bar)`` rows, the keys of the
    last multiplier update, fixed during a solve), else the closest.
    A node minimum is found from every element pair sharing the node; and
    at a kink of the C0 centreline one crossing can have twin minima, one
    on each side of the node, a hair apart and equally far (measured in the
    plectoneme: 1e-4 apart, distances equal to 1e-8; a held pair then
    followed one twin or the other from one Newton iterate to the next and
    the residual 2-cycled; keeping the closest twin, the choice flipped with
    distances 4e-6 eps apart, so the twin nearest the held place is kept)."""
    n = s.size
    if n < 2:
        return np.arange(n)
    P = cKDTree(np.c_[s, s_bar]).query_pairs(within, p=np.inf, output_type="ndarray")
    if P.size == 0:
        return np.arange(n)
    g = sp.coo_matrix((np.ones(len(P)), (P[:, 0], P[:, 1])), shape=(n, n))
    lab = connected_components(g, directed=False)[1]
    near = np.full(n, np.inf)
    if held is not None and len(held):
        near = cKDTree(np.asarray(held)[:, :2]).query(np.c_[s, s_bar], p=np.inf)[0]
        near[near > within] = np.inf          # only a twin of the held place itself
    order = np.lexsort((np.arange(n), dist, near, lab))
    return np.sort(order[np.r_[True, lab[order][1:] != lab[order][:-1]]])


@dataclass(frozen=True)
class PairThreshold:
    """The angle at which a crossing pair acts with its full weight:
    ``min(min_angle, beta_h)``, ``beta_h`` the effective angle below which
    the ``n_slave`` Gauss slave points per element hold a minimum to
    ``SAMPLING_SHARE`` of the Uzawa ``tolerance`` (:func:`sampled_angle`).
    It is measured at the sampling scale, by probes (:func:`_weigh`).
    From the contact options:
    :meth:`skfem_rod.contact.ContactOptions.crossing_threshold`."""
    min_angle: float = float(np.radians(15.0))
    n_slave: int = 3
    tolerance: float = 1e-3

    def angle(self, h, radius):
        """The threshold ``min(min_angle, beta_h)`` for elements ``h`` long."""
        return np.minimum(self.min_angle, sampled_angle(h, radius, self.n_slave, self.tolerance))


def crossing_pairs(mesh, r, radius, exclusion, reach=None, threshold=PairThreshold(),
                   held=None):
    """Point-to-point contact pairs at the strict local minima of the
    distance between strands, each with its weight (see module doc and
    docs/crossing-contact.md).

    *Minima.*  Strict local minima of the distance along both whole strands
    (interior stationary points, or a node where the distance grows into
    both elements beside it), closer than ``reach`` and at least
    ``exclusion`` apart in arclength.

    *Weight.*  A pair acts with the weight :func:`_weigh` gives its minimum:
    how far the distance rises at probes half a slave gap before and after
    it on either strand, against the rise of a minimum at the angle of
    ``threshold`` (a :class:`PairThreshold`), times a factor of its local
    effective angle: 1 at a crossing, 0 at a line contact (the Gauss-point
    pairs' job), continuous in between and at the moments a minimum hops,
    splits, forms or vanishes.  Minima of weight 0 get no pair.

    *Held minima.*  ``held = (key, multipliers)``, the pairs of the last
    multiplier update (``Multipliers.crossing_key``, ``.crossing``): each
    follows the nearest minimum within its carry radius (the key's 4th
    entry then holds its index, :func:`carry` gives it its multiplier).
    ``held = (key, multipliers, track)``: ``track`` (optional, ``(k, 2)``)
    the places ``(s, s_bar)`` from which the held pairs look for their
    minimum, the places they followed at the last evaluation
    (``Multipliers.crossing_places`` of :mod:`skfem_rod.problem`; default
    their keys' places): a minimum that moves by about an element within a
    solve left the carry radius of its key, and its multiplier switched on
    and off from one Newton iterate to the next (measured in the
    plectoneme's damped steps: the minimum 0.0092 <-> 0.0099 from a key
    with carry radius 0.01, the residual 0.61 <-> 0.76).

    Examples
    --------
    >>> from skfem_rod.mesh import RodMesh
    >>> mesh = RodMesh(3.0, 3)
    >>> r = np.zeros((mesh.n_nodes, 3))
    >>> t = np.array([0.0, 1.0, 1 / 3, 2 / 3])[:, None]
    >>> r[mesh.nodes[0]] = (t - 0.5) * [1.0, 0.0, 0.0]
    >>> r[mesh.nodes[2]] = (t - 0.5) * [0.0, 1.0, 0.0] + [0.0, 0.0, 0.15]
    >>> r[mesh.nodes[1, 2:]] = [[0.2, 0.2, 1.0], [0.0, 0.2, 1.0]]
    >>> cp = crossing_pairs(mesh, r, 0.1, 0.3)
    >>> cp.size, round(float(cp.distance[0]), 12), round(float(cp.u[0]), 12)
    (1, 0.15, 0.5)
    >>> float(cp.weight[0])
    1.0
    """
    reach = 3.0 * radius if reach is None else reach
    old = np.zeros((0, 4)) if held is None else np.asarray(held[0], float)
    valid = bool(old.size) and old.ndim == 2 and old.shape[1] >= 4
    near = old
    if valid and len(held) > 2 and held[2] is not None:       # follow from the tracked places
        near = old.copy()
        near[:, :2] = held[2]
    mn = _minima(mesh, r, radius, exclusion, reach, near if valid else None)
    _describe(mesh, mn)
    _weigh(mesh, r, mn, radius, threshold, exclusion)
    # each minimum once: held index of the pair following it, or -1
    held_index = np.full(mn["e"].size, -1.0)
    if valid:
        follow = _follow(mn["mkey"], near)
        i = np.flatnonzero(follow >= 0)
        held_index[follow[i]] = i
    k = np.flatnonzero(mn["weight"] > 0)
    pairs = {n: a[k] for n, a in mn.items()}
    pairs["key"] = np.c_[mn["mkey"][k], held_index[k]]
    return _collect(mesh, r, pairs)


#: a crossing pair fades in as the distance its probes see rises from
#: FADE[0] to FADE[1] times the rise of a minimum at the threshold angle
FADE = (0.5, 1.0)


def _curve_at(mesh, r, s):
    """Element, reference coordinate, shape values ``(k, 4)``, point and
    xi-derivative ``(k, 3)`` at arclengths ``s`` (periodic on a closed rod,
    clamped to the ends of an open one), and whether the point moves with
    ``s`` (not clamped)."""
    vt, ne = mesh.vertices, mesh.nodes.shape[0]
    period = arclength_period(mesh)
    if period is None:
        moving = (s > vt[0]) & (s < vt[-1])
        s = np.clip(s, vt[0], vt[-1])
    else:
        moving = np.ones(s.size, bool)
        s = vt[0] + np.mod(s - vt[0], period)
    e = np.clip(np.searchsorted(vt, s, side="right") - 1, 0, ne - 1)
    xi = np.clip((s - vt[e]) / (vt[e + 1] - vt[e]), 0.0, 1.0)
    N, dN, _ = shape_functions(xi)
    re = r[mesh.nodes[e]]
    return (e, N.T, np.einsum("kI,kIc->kc", N.T, re), np.einsum("kI,kIc->kc", dN.T, re), moving,
            s)


def _first_lowest(d):
    """Per column of ``d`` ``(p, k)`` the row a running minimum over the
    rows ends on, replacing only where strictly lower: the first lowest
    row (ties: the earlier), row 0 where nothing is lower than it (also a
    NaN there, which nothing replaces; a NaN in a later row never wins)."""
    d = d.copy()
    d[1:][np.isnan(d[1:])] = np.inf
    return np.argmin(d, axis=0)


def _near(mesh, r, x, sx, f, exclusion):
    """The closest point to ``x`` ``(k, 3)`` (at arclength ``sx``) on the
    elements ``f - 1, f, f + 1``, at least ``exclusion`` away in arclength:
    distance, ``x - y``, element and shape values.

    The three elements of every point are projected in one call of
    :func:`.search.project` (stacked offset-major: ``f``, ``f - 1``, ``f +
    1``), then per point the first closest of the three is kept (``inf``
    where none is admissible)."""
    ne, vt = mesh.nodes.shape[0], mesh.vertices
    period = arclength_period(mesh)
    k = f.size
    fb = (f + np.array([0, -1, 1])[:, None]).ravel()         # (3 k,) offset-major
    if period is None:
        ok = (fb >= 0) & (fb < ne)
        fb = np.where(ok, fb, np.tile(f, 3))
    else:
        ok = np.ones(fb.size, bool)
        fb = np.mod(fb, ne)
    x3, re = np.tile(x, (3, 1)), r[mesh.nodes[fb]]
    eta, _ = project(x3, re)
    Nb = shape_functions(eta)[0].T
    D = x3 - np.einsum("kI,kIc->kc", Nb, re)
    ok &= arc_distance(np.tile(sx, 3), vt[fb] + eta * (vt[fb + 1] - vt[fb]), period) >= exclusion
    d = np.where(ok, np.sqrt(np.sum(D * D, axis=1)), np.inf)
    pick = _first_lowest(d.reshape(3, k)) * k + np.arange(k)
    return d[pick], D[pick], fb[pick], Nb[pick]


def _weigh(mesh, r, mn, radius, threshold, exclusion):
    """The weight of the pair each minimum of ``mn`` would carry, the
    product of two smoothsteps (:func:`_smoothstep`): of the rise at probes
    ``delta`` (the Gauss slave points' half gap) before and after the
    minimum on either strand, each at its distance from the other strand
    (elements next to the minimum's), the lowest rise above the minimum's
    distance against the rise of straight strands at the threshold angle
    ``beta_min``; and of the local ``sin^2 beta`` against ``sin^2
    beta_min`` (where it is small the minimum's place is ill-conditioned).
    Adds ``weight``, its slopes and the lowest probe's derivative pieces
    (docs/crossing-contact.md, section 4)."""
    m = mn["e"].size
    vt = mesh.vertices
    e, f = mn["e"], mn["f"]
    he, hf = vt[e + 1] - vt[e], vt[f + 1] - vt[f]
    hmin = np.minimum(he, hf)
    delta = slave_half_gap(threshold.n_slave) * hmin
    # the rise at the threshold angle, at the minimum's own distance l
    sin_min = np.sin(threshold.angle(hmin, radius))          # of the threshold angle
    c2 = (delta * sin_min) ** 2
    l = mn["distance"]
    R = np.sqrt(l * l + c2) - l
    dR = l / np.sqrt(l * l + c2) - 1.0                      # dR / dl
    # the local sharpness first: where sin^2 beta is small the minimum's
    # place moves by delta / sin^2 beta for a change delta of the state;
    # a minimum with no local factor needs no probes (line contacts: most)
    sb2 = sin_min ** 2
    w_beta, slope_beta = _smoothstep(mn["weigh_sin2"] / sb2)
    todo = np.flatnonzero(w_beta > 0)
    rise = np.full(m, np.inf)
    dofs, dq, dp = np.zeros((m, 24), np.int64), np.zeros((m, 24)), np.zeros((m, 2))
    # the four probes of every minimum, stacked probe-major in the order
    # (side, sign) = (0, -1), (0, +1), (1, -1), (1, +1): side 0 probes the
    # first strand at s* -+ delta against the second (elements next to f),
    # side 1 the second at s_bar* -+ delta against the first
    t = todo.size
    side = np.repeat([0, 0, 1, 1], t)
    first = side == 0
    k4 = np.tile(todo, 4)
    s0 = np.where(first, mn["s"][k4], mn["s_bar"][k4])
    B, h = np.where(first, f[k4], e[k4]), np.where(first, he[k4], hf[k4])
    sign = np.repeat([-1.0, 1.0, -1.0, 1.0], t)
    ep, Np, x, x1, moving, sp_ = _curve_at(mesh, r, s0 + sign * delta[k4])
    d, D, fb, Nb = _near(mesh, r, x, sp_, B, exclusion)
    # per minimum the first lowest probe whose rise is below inf (as a
    # running minimum over the four in that order: ties keep the earlier)
    val = (d - l[k4]).reshape(4, t)
    val = np.where(np.isnan(val), np.inf, val)
    p = np.argmin(val, axis=0) * t + np.arange(t)          # the lowest probe of each
    j = p[val.reshape(-1)[p] < np.inf]
    if j.size:
        k = k4[j]
        nrm = D[j] / d[j][:, None]
        # the probe point X(s* +- delta) rides on the minimum's parameter
        c = np.where(moving[j], _dot(nrm.T, x1[j].T) * h[j] / (vt[ep[j] + 1] - vt[ep[j]]), 0.0)
        one = first[j][:, None]
        a = np.where(one, np.concatenate([Np[j], -Nb[j]], axis=1),
                     np.concatenate([-Nb[j], Np[j]], axis=1))
        nodes = np.where(one, np.concatenate([mesh.nodes[ep[j]], mesh.nodes[fb[j]]], axis=1),
                         np.concatenate([mesh.nodes[fb[j]], mesh.nodes[ep[j]]], axis=1))
        rise[k] = d[j] - l[k]
        dq[k] = (a[:, :, None] * nrm[:, None, :]).reshape(j.size, 24)
        dofs[k] = (6 * nodes[:, :, None] + np.arange(3)).reshape(j.size, 24)
        dp[k, side[j]] = c
    w_rise, slope = _smoothstep(rise / R)
    mn["weight"] = w_rise * w_beta
    mn["weight_slope"] = w_beta * slope / R
    # (no admissible probe at all: rise = inf, weight 1, no slope)
    finite = np.where(np.isfinite(rise), rise, 0.0)
    mn["weight_slope_l"] = -w_beta * slope * finite * dR / (R * R)
    mn["weight_slope_beta"] = w_rise * slope_beta / sb2
    mn["probe_dofs"], mn["probe_dq"], mn["probe_dp"] = dofs, dq, dp


def _smoothstep(x):
    """``S(t) = 3 t^2 - 2 t^3`` of ``t = (x - FADE[0]) / (FADE[1] - FADE[0])``
    clipped to [0, 1], and ``dS/dx``."""
    t = (x - FADE[0]) / (FADE[1] - FADE[0])
    tc = np.clip(t, 0.0, 1.0)
    slope = np.where((t > 0) & (t < 1), 6.0 * tc * (1.0 - tc), 0.0) / (FADE[1] - FADE[0])
    return tc * tc * (3.0 - 2.0 * tc), slope


def _describe(mesh, mn):
    """Adds to the minima ``mn`` (of :func:`_minima`) their effective
    angle ``beta``, the acting ``length`` and the place key ``mkey``
    ``(m, 4)``: ``s, s_bar``, the carry radius (the longer element) and
    ``beta``."""
    vt = mesh.vertices
    e, f = mn["e"], mn["f"]
    beta = np.arcsin(np.sqrt(np.clip(mn["sin2"], 0.0, 1.0)))
    mn["mkey"] = np.c_[mn["s"], mn["s_bar"], np.maximum(vt[e + 1] - vt[e], vt[f + 1] - vt[f]),
                       beta]
    mn["length"], mn["beta"] = mn["distance"], beta

def _follow(mkey, old):
    """Per held pair (key ``old``) the minimum it follows (index into
    ``mkey``, -1: none): the nearest within its carry radius, in
    ``(s, s_bar)`` (max norm), one to one, nearest first."""
    follow = np.full(old.shape[0], -1)
    if mkey.shape[0]:
        dist, j = cKDTree(mkey[:, :2]).query(old[:, :2], p=np.inf)
        hit = np.flatnonzero(dist <= old[:, 2])
        hit = hit[np.lexsort((dist[hit], j[hit]))]
        hit = hit[np.r_[True, j[hit][1:] != j[hit][:-1]]] if hit.size else hit
        follow[hit] = j[hit]
    return follow


def _collect(mesh, r, p):
    """The :class:`CrossingPairs` of the per-pair arrays ``p``, with the
    tangents' ``|cos|`` at the pairs."""
    e, f, u, v = p["e"], p["f"], p["u"], p["v"]
    C = monomial_coefficients(r[mesh.nodes]).transpose(1, 2, 0)
    X1 = curve_point(C[:, :, e], u)[1]
    Y1 = curve_point(C[:, :, f], v)[1]
    cos = np.abs(_dot(X1, Y1)) / np.sqrt(_dot(X1, X1) * _dot(Y1, Y1))
    return CrossingPairs(e, f, u, v, p["s"], p["s_bar"], p["distance"],
                         p["D"].reshape(-1, 3) / p["length"][:, None], cos, p["key"],
                         p["u_free"], p["v_free"], p["beta"], p["length"], p["weight"],
                         WeightSlope(p["weight_slope"], p["weight_slope_l"],
                                     p["weight_slope_beta"], p["probe_dofs"], p["probe_dq"],
                                     p["probe_dp"], p["reading"]))


def _outer(a, c):
    """Per pair, the outer product of ``a (m, k)`` and ``c (m, 3)``
    flattened to ``(m, 3 k)``: a coefficient row on ``k`` nodes times a
    vector, as a row on their position dofs."""
    return (a[:, :, None] * c[:, None, :]).reshape(a.shape[0], -1)


def _dsin2(mesh, r, e, f, u, v, D, X1, X2, Y1, Y2, aD, aX1, aY1, S, reading=None):
    """``d(sin^2 beta)/dq`` of the minima at ``(e, u)``, ``(f, v)`` (the
    per-pair arrays of :func:`crossing_work`), ``sin^2 beta = det F_pp /
    (F_uu F_vv)`` with the second derivatives continuous across nodes
    (:func:`_second`; the node-held parameter included), through the
    positions at fixed parameters and the minimum's motion ``dp/dq = -S``.
    Returns the derivative on the pair's dofs ``(m, 24)``, on the dofs of
    the elements beside its two ``(m, 48)``, and those dofs.

    ``reading`` ``(m, 2)``: where not :data:`BLENDED`, the derivative of the
    fold reading the weight took instead (:func:`_fold_reading`): the
    Hessian of those second derivatives, plus ``1 - g`` per strand read
    across a node, over :data:`FOLD_SHARE`."""
    m = D.shape[0]
    z = np.zeros((m, 4))
    rx, ry = (None, None) if reading is None else (reading[:, 0], reading[:, 1])
    X2c, X2u, ax, bx, nx = _second(mesh, r, e, u, rx)
    Y2c, Y2v, ay, by, ny = _second(mesh, r, f, v, ry)
    dot = lambda a, b: _dot(a.T, b.T)                                 # noqa: E731
    Fuu, Fvv, Fuv = _hessian(D.T, X1.T, X2c.T, Y1.T, Y2c.T)
    aX2 = np.concatenate([ax, z], axis=1)
    aY2 = np.concatenate([z, ay], axis=1)
    # at fixed parameters
    dFuu = 2 * _outer(aX1, X1) + _outer(aD, X2c) + _outer(aX2, D)
    dFvv = 2 * _outer(aY1, Y1) - _outer(aD, Y2c) - _outer(aY2, D)
    dFuv = -(_outer(aX1, Y1) + _outer(aY1, X1))
    # along the parameters (a held parameter does not move: S's row is 0);
    # |X'|^2 and X'.Y' move with the curves' own X'', D.X'' with the
    # continuous one and its u-derivative
    pu = [2 * dot(X1, X2) + dot(X1, X2c) + dot(D, X2u), -dot(Y1, X2c)]   # dFuu/du, /dv
    pv = [-dot(X1, Y2c), 2 * dot(Y1, Y2) + dot(Y1, Y2c) - dot(D, Y2v)]   # dFvv/du, /dv
    pw = [-dot(X2, Y1), -dot(X1, Y2)]                                  # dFuv/du, /dv
    for k in (0, 1):
        dpk = -S[:, k]                                                 # (m, 24)
        dFuu = dFuu + pu[k][:, None] * dpk
        dFvv = dFvv + pv[k][:, None] * dpk
        dFuv = dFuv + pw[k][:, None] * dpk
    det, den = Fuu * Fvv - Fuv * Fuv, Fuu * Fvv
    ddet = dFuu * Fvv[:, None] + Fuu[:, None] * dFvv - 2 * Fuv[:, None] * dFuv
    dden = dFuu * Fvv[:, None] + Fuu[:, None] * dFvv
    inside = (det > 0) & (det < den)                        # not clipped to [0, 1]
    blended = np.ones(m, bool) if reading is None else rx == BLENDED
    inside &= blended | ((Fuu > 0) & (Fvv > 0))              # _psd_sin2
    own = np.where(inside[:, None], ddet / den[:, None] - (det / den ** 2)[:, None] * dden, 0.0)
    # the neighbours enter F_uu (X side) and F_vv (Y side) through D.X''
    # only: d sin^2 = (1 - sin^2) (F_vv dF_uu + F_uu dF_vv) / den
    c = np.where(inside, (1.0 - det / den) / den, 0.0)
    beside = np.concatenate([(c * Fvv)[:, None] * _outer(bx, D),
                             -(c * Fuu)[:, None] * _outer(by, D)], axis=1)
    dofs = (6 * np.concatenate([nx, ny], axis=1)[:, :, None] + np.arange(3)).reshape(m, 48)
    if reading is not None and not blended.all():
        # a strand read across a node adds 1 - g(p): d/dq = g'(p) S
        for k, (el, p) in enumerate(((e, u), (f, v))):
            dg = _nearest_node(mesh, el, p)[1] * (reading[:, k] == ACROSS)
            own = own + dg[:, None] * S[:, k]
        scale = np.where(blended, 1.0, 1.0 / FOLD_SHARE)[:, None]
        own, beside = own * scale, beside * scale
    return own, beside, dofs


def carry(old_key, old_lam, new_key):
    """Multipliers of the new pairs: for a pair of a held minimum (its
    key's 4th entry, the index of the held pair) the held multiplier; else
    that of the nearest old pair (in ``(s, s_bar)``, max norm) within the
    new pair's carry radius (the longer of its two elements; each old pair
    to at most one new pair, the nearest), 0 for new minima.  Keyed by
    place, not by element pair: a minimum moving across a node keeps its
    multiplier.  ``old_lam`` may hold a vector per pair (``(k, 3)``: the
    friction multipliers); the result has the same trailing shape."""
    new_key = np.asarray(new_key, dtype=float)
    new_key = new_key.reshape(-1, new_key.shape[-1]) if new_key.size else np.zeros((0, 3))
    old_lam = np.asarray(old_lam, float)
    lam = np.zeros((new_key.shape[0],) + old_lam.shape[1:])
    old_key = np.asarray(old_key, dtype=float)
    if old_key.size == 0 or new_key.shape[0] == 0:
        return lam
    old_key = old_key.reshape(-1, old_key.shape[-1])
    n_old = old_lam.shape[0]
    idx = new_key[:, 4].astype(np.int64) if new_key.shape[1] > 4 \
        else np.full(new_key.shape[0], -1)
    direct = (idx >= 0) & (idx < n_old)
    lam[direct] = old_lam[idx[direct]]
    rest = np.flatnonzero(~direct & (idx < 0))
    taken = np.zeros(n_old, bool)
    taken[idx[direct]] = True
    if rest.size:
        dist, j = cKDTree(old_key[:, :2]).query(new_key[rest, :2], p=np.inf)
        ok = (dist <= new_key[rest, 2]) & ~taken[np.minimum(j, n_old - 1)]
        hit = np.flatnonzero(ok)
        hit = hit[np.lexsort((dist[hit], j[hit]))]
        hit = hit[np.r_[True, j[hit][1:] != j[hit][:-1]]] if hit.size else hit
        lam[rest[hit]] = old_lam[j[hit]]
    return lam


def gap_gradients(mesh, pairs):
    """The derivative of each pair's distance ``l`` with respect to the
    position dofs of its two elements at fixed weight (the row ``dl/dq``
    of :func:`crossing_work`): ``(dofs, dl)``, both ``(m, 24)``."""
    Nu = shape_functions(pairs.u)[0].T
    Nv = shape_functions(pairs.v)[0].T
    # d (l^2 / 2) / dq = (X - Y) . delta(X - Y), divided by l
    lq = _outer(np.concatenate([Nu, -Nv], axis=1), pairs.normal)
    nodes = np.concatenate([mesh.nodes[pairs.e], mesh.nodes[pairs.f]], axis=1)
    dofs = (6 * nodes[:, :, None] + np.arange(3)).reshape(pairs.size, 24)
    return dofs, lq


def crossing_work(mesh, r, pairs, lam, mu, radius, tangent=True, fade=True, offset=None,
                  weight_rows=False, stiffen=1.0):
    """Energy, force vector ``(n_dofs,)``, tangent (CSC or None) and the
    per-pair forces ``f_N`` of the crossing pairs (``pairs`` from
    :func:`crossing_pairs` at ``r``; ``lam`` ``(m,)`` their multipliers,
    ``mu`` the compliance of the point law).  scikit-fem dof numbering as
    :func:`.assembly.contact_work` (6 dofs per node, positions first).

    Each pair acts with its weight ``w`` (:func:`_weigh`): force
    ``w f_N dl/dq``, energy ``w phi``.  The tangent has the weight's
    derivative (through the lowest probe, its own dofs and the minimum's
    motion), so the force is no energy's gradient where ``0 < w < 1``:
    there the tangent is not symmetric.  ``fade=False`` leaves that
    derivative out (the frozen-weight tangent the stability checks read,
    :meth:`skfem_rod.problem.Problem.free_tangent`).  The per-pair forces
    returned are ``w f_N``.

    ``offset`` ``(m,)``: the pairs' gap offsets
    (:func:`skfem_rod.augmented.adjust_offsets`); a pair holds the distance
    ``2 radius + w offset``.  The offset fades with the weight: a fading
    pair shares its gap with the Gauss pairs, which hold their own offsets
    (docs/crossing-contact.md, section 4).  Its derivative through ``w`` is
    in the tangent.

    ``weight_rows`` (with ``tangent``): a fifth output, the ``(m, n_dofs)``
    CSR matrix of the weights' derivatives ``dw/dq`` (zero rows where a
    pair's weight has no slope), read by the generalized Newton's
    complementarity rows (:func:`skfem_rod.nonsmooth.contact_blocks`).
    ``stiffen``: the pairs' ``df_N / d gap`` times this in the tangent, the
    forces unchanged (the constrained stability test)."""
    n = mesh.n_dofs
    m = pairs.size
    if m == 0:
        out = (0.0, np.zeros(n), (sp.csc_matrix((n, n)) if tangent else None), np.zeros(0))
        return out + (sp.csr_matrix((0, n)),) if weight_rows and tangent else out
    l = pairs.distance if pairs.length is None else pairs.length
    w = np.ones(m) if pairs.weight is None else pairs.weight
    off = np.zeros(m) if offset is None else np.asarray(offset, float)
    d = gap(l, radius) + w * off
    fN, dfN = normal_force(d, lam, mu)
    energy = float(np.sum(w * potential(d, lam, mu)))
    Nu, dNu, d2Nu = (a.T for a in shape_functions(pairs.u))       # (m, 4)
    Nv, dNv, d2Nv = (a.T for a in shape_functions(pairs.v))
    re, rf = r[mesh.nodes[pairs.e]], r[mesh.nodes[pairs.f]]       # (m, 4, 3)
    X1, X2 = np.einsum("mk,mkc->mc", dNu, re), np.einsum("mk,mkc->mc", d2Nu, re)
    Y1, Y2 = np.einsum("mk,mkc->mc", dNv, rf), np.einsum("mk,mkc->mc", d2Nv, rf)
    D = pairs.normal * l[:, None]
    z = np.zeros((m, 4))
    aD = np.concatenate([Nu, -Nv], axis=1)                        # (m, 8): delta D
    aX1 = np.concatenate([dNu, z], axis=1)                        # delta X'
    aY1 = np.concatenate([z, dNv], axis=1)                        # delta Y'
    dofs, lq = gap_gradients(mesh, pairs)                         # dl/dq
    force = np.bincount(dofs.ravel(), weights=(-(w * fN)[:, None] * lq).ravel(), minlength=n)
    if not tangent:
        return energy, force, None, w * fN
    Fpq = np.stack([_outer(aX1, D) + _outer(aD, X1), -(_outer(aY1, D) + _outer(aD, Y1))], axis=1)
    Fpp = np.empty((m, 2, 2))
    Fpp[:, 0, 0], Fpp[:, 1, 1], Fpp[:, 0, 1] = _hessian(D.T, X1.T, X2.T, Y1.T, Y2.T)
    Fpp[:, 1, 0] = Fpp[:, 0, 1]
    # a parameter held on a node (the kink of the C0 centreline) does not
    # move: its row of F_pq goes and F_pp gets a unit row and column
    for k, free in ((0, pairs.u_free), (1, pairs.v_free)):
        if free is not None:
            held = ~np.asarray(free, bool)
            Fpq[held, k] = 0.0
            Fpp[held, k, :] = 0.0
            Fpp[held, :, k] = 0.0
            Fpp[held, k, k] = 1.0
    Fqq = (aD[:, :, None, None, None] * aD[:, None, None, :, None]
           * np.eye(3)[None, None, :, None, :]).reshape(m, 24, 24)
    S = np.linalg.solve(Fpp, Fpq)                                 # -dp/dq
    H = Fqq - np.swapaxes(Fpq, 1, 2) @ S                          # reduced Hessian of F
    lqq = H / l[:, None, None] - lq[:, :, None] * lq[:, None, :] / l[:, None, None]
    Ke = w[:, None, None] * (stiffen * dfN[:, None, None] * lq[:, :, None] * lq[:, None, :]
                             - fN[:, None, None] * lqq)
    rows, cols = [dofs], [dofs]
    blocks = [Ke]
    dw_parts = []                                  # (pair, dofs, dw/dq) of fading pairs
    if (fade or weight_rows) and pairs.slope is not None:
        # the weight's derivative, for the pairs whose weight has a slope:
        # w(rise, l, sin^2 beta), rise = (lowest probe's distance) - l, the
        # probe riding on the pair's parameters (dp/dq = -S) and on its own
        # dofs (probe_dq)
        ps = pairs.slope
        i = ps.fading()
        if i.size:
            ws, wl, wb = ps.rise[i, None], ps.length[i, None], ps.beta[i, None]
            dw = ws * (-np.einsum("mk,mkq->mq", ps.probe_dp[i], S[i]) - lq[i]) + wl * lq[i]
            own, beside, bdofs = _dsin2(mesh, r, pairs.e[i], pairs.f[i], pairs.u[i], pairs.v[i],
                                        D[i], X1[i], X2[i], Y1[i], Y2[i], aD[i], aX1[i],
                                        aY1[i], S[i],
                                        None if ps.reading is None else ps.reading[i])
            dw = dw + wb * own
            dw_parts = [(i, dofs[i], dw), (i, ps.probe_dofs[i], ws * ps.probe_dq[i]),
                        (i, bdofs, wb * beside)]
            if fade:
                # w f_N(d) with d = 2 eps + w offset - l: the weight's
                # derivative enters through the factor and through the gap
                g = -(fN[i] + w[i] * dfN[i] * off[i])[:, None, None] * lq[i, :, None]
                blocks += [g * v[:, None, :] for _, _, v in dw_parts]
                rows += [dofs[i]] * 3
                cols += [c for _, c, _ in dw_parts]
    ij = [(np.broadcast_to(a[:, :, None], b.shape).ravel(),
           np.broadcast_to(c[:, None, :], b.shape).ravel()) for a, c, b in zip(rows, cols, blocks)]
    K = sp.csc_matrix((np.concatenate([b.ravel() for b in blocks]),
                       (np.concatenate([i for i, _ in ij]), np.concatenate([j for _, j in ij]))),
                      shape=(n, n))
    if not weight_rows:
        return energy, force, K, w * fN
    if dw_parts:
        vals = np.concatenate([v.ravel() for _, _, v in dw_parts])
        prs = np.concatenate([np.broadcast_to(i[:, None], c.shape).ravel() for i, c, _ in dw_parts])
        dcs = np.concatenate([c.ravel() for _, c, _ in dw_parts])
        Wq = sp.csr_matrix((vals, (prs, dcs)), shape=(m, n))
    else:
        Wq = sp.csr_matrix((m, n))
    return energy, force, K, w * fN, Wq
