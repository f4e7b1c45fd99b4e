r"""A smooth barrier between the centreline's nodes: the contact model of the
energy-minimizing experiment of issue 13 (``benchmarks/bench_plectoneme_barrier.py``,
docs/contact-solve.md "A smooth barrier between nodes").

Not the paper's model.  The paper (sec. 3-4) imposes ``d >= 2 eps`` at slave
Gauss points projected on the master curve, by an augmented Lagrangian.
Here every pair of centreline nodes ``i, j`` (the P3 nodes, which lie on
the curve, a third of an element apart) at least ``exclusion`` apart in
arclength carries the barrier energy of Li et al. (IPC, ACM TOG 39, 2020)
on its gap ``g = |x_i - x_j| - D``:

    b(g) = -kappa (g - g_hat)^2 ln(g / g_hat)   for 0 < g < g_hat,  0 beyond,

which is C2 at ``g_hat`` (``b = b' = b'' = 0`` there) and infinite at
``g = 0``: a configuration with a node pair closer than ``D`` has infinite
energy, and a line search that keeps the energy finite (with
:func:`step_bound` along each update) never lets a strand through another.
The total energy stays smooth, so Newton on it sees no active-set switch,
no projection jump and no multiplier update.

*Contact distance.*  The nodes sample the curve at spacing ``a``; where two
straight strands cross at distance ``2 eps``, the nearest nodes can be
farther apart by up to ``a^2 / (8 eps)`` (both strands' nodes half a
spacing away from the crossing; ``a^2 / (16 eps)`` for parallel strands).
Where a strand curves between nodes (curvature ``k``) it sags towards
the other by ``k a^2 / 8`` below the chord; a tube of radius ``eps``
bends no tighter than ``1 / eps`` without overlapping itself
(``TUBE_CURVATURE``).  The node spheres touch at

    D = 2 eps + 3 a^2 / (8 eps)        (``SAMPLING = 3``, :func:`node_offset`)

the crossing offset and the sag of both strands at that curvature
(:meth:`Barrier.for_nodes`): the centrelines keep ``2 eps`` to second
order in ``a / eps`` at any crossing angle wherever the strands bend no
tighter than a tube can (tests/test_barrier.py measures it on densely
sampled arcs), and stand off by up to ``D - 2 eps`` where they are straight
and the nodes in step (6.7e-3 eps at 100 elements of the plectoneme,
1.7e-3 eps at 200; the node spacing must stay well below the radius).
Before 2026-12-01 D held the crossing offset alone; the 100-element
frictional plectoneme then reached a state near the ends whose strands,
bent to 0.88 and 0.52 / eps towards each other, overlapped by 1.02e-3
eps between nodes, and no step from it converged.  Tighter bends (the
bend barrier allows 2 / eps against kinks) can still dip below
``2 eps``; the callers measure the true distance
(:func:`skfem_rod.contact.crossing.min_distance`) and refuse such a
step.

*Width and stiffness.*  ``g_hat`` (default 0.02 eps) bounds how far apart
touching strands stand; ``kappa`` is set so that a pair at ``g_hat / 2``
pushes with ``force`` (``|b'(g_hat/2)| = (ln 2 + 1/2) kappa g_hat``).

*Handles.*  A rod whose ends are held keeps its link (twist + writhe,
closed far away along the end tangents) only while no strand passes
around an end: crossing the straight continuation of the rod beyond an
end changes the link by 2 without any strand touching another.  With
``Barrier.handles`` the ends are continued by rigid straight handles of
the rod's radius along the end tangents (the closure made material:
:class:`Handles`, :func:`handle_pairs`); every node at least
``exclusion`` from the end in arclength keeps the distance ``D`` from
the handle (its cap the end node's sphere), with the same barrier, and
the node pairs with the end node are the handle's.  The handles are
frictionless and meant for ends whose rotation is held (their direction
is data within a step).

*Local self-contact.*  Pairs closer than ``exclusion`` (default ``pi
eps``) in arclength carry no barrier: a tube of radius ``eps`` meets
itself there only where its centreline bends tighter than about ``eps``.
A Newton update far from equilibrium can still draw the nodes into a
kink -- a loop of a few node spacings, moved by a shear the rotations do
not follow -- and pass it through itself, which releases two turns of
link with no pair ever in reach (measured: the 100-element frictional
plectoneme, a loop of radius 0.07 eps at the clamp, grown over 40
iterations of one solve).  :class:`Bend` keeps the nodes' polyline from
turning by more than ``limit`` at any node, with the same barrier on
``g = t_0 . t_1 - cos(limit)`` (``t`` the unit chords on either side):
:func:`bend_work`.  The solve sets the limit to a curvature of ``2 /
eps`` (a loop of half the radius) and the barrier to act only beyond
``1.5 / eps``; the plectoneme's converged states bend to at most ``1.3 /
eps``.  Likewise the sections: where ``d3`` tilts far off the
centreline (a shear the linear law lets through at a high torque), the
twist about the centreline is undefined and can come out a turn less --
a phase slip, measured in the same run.  :class:`Shear` keeps the angle
between each section's ``d3`` and the chords to its neighbours below
``a / eps + 0.5`` rad (the chord's own turn from the tangent plus half a
radian; acting beyond ``a / eps + 0.3``): :func:`shear_work`.

Everything is vectorized over pairs (``scipy.spatial.cKDTree.query_pairs``
for the pairs within reach).
"""
from dataclasses import dataclass, replace
from typing import NamedTuple, Optional

import numpy as np
import scipy.sparse as sp

from ..rotations import cross, expm, hat, vee

#: ``|b'(g_hat / 2)| / (kappa g_hat)``: the force of a pair at half the width
HALF_WIDTH_FORCE = np.log(2.0) + 0.5
#: the largest curvature (times the radius) that the bend barrier lets the
#: nodes' polyline take (:meth:`Bend.for_rod`): a guard against kinks
BEND_CURVATURE = 2.0
#: the largest curvature (times the radius) of a tube of radius eps that
#: does not overlap itself locally: the curvature the contact distance
#: allows for between nodes
TUBE_CURVATURE = 1.0
#: the node spheres' distance ``D = 2 eps + SAMPLING a^2 / (8 eps)``: the
#: crossing offset (1) and the sag of both strands at TUBE_CURVATURE
#: (module doc, "Contact distance")
SAMPLING = 1.0 + 2.0 * TUBE_CURVATURE


def node_offset(a, radius):
    """``D - 2 eps`` for nodes ``a`` apart, contact radius ``radius``."""
    return SAMPLING * a ** 2 / (8 * radius)


def node_spacing(offset, radius):
    """The node spacing whose :func:`node_offset` is ``offset``."""
    return float(np.sqrt(8 * radius * offset / SAMPLING))


@dataclass(frozen=True)
class Barrier:
    """The barrier's parameters (lengths in the rod's units)."""
    distance: float      # D: where the node spheres touch
    width: float         # g_hat: the barrier acts for 0 < g < g_hat
    stiffness: float     # kappa
    exclusion: float     # node pairs closer than this in arclength never touch
    period: object = None  # a closed rod's length (arclength is periodic), or None
    #: end nodes continued by rigid straight handles (module doc); their
    #: node pairs are the handles'
    handles: tuple = ()

    def __post_init__(self):
        for name in ("distance", "width", "stiffness"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"Barrier {name} must be a finite number > 0, not {v!r}")
        if not (np.isfinite(self.exclusion) and self.exclusion >= 0):
            raise ValueError(f"Barrier exclusion must be a finite number >= 0, "
                             f"not {self.exclusion!r}")
        if self.handles and self.period is not None:
            raise ValueError("Barrier handles continue the ends of an open rod; a closed rod "
                             "(period given) has none")

    @classmethod
    def for_nodes(cls, s, radius, width=0.02, force=1.0, exclusion=None, period=None,
                  handles=()):
        """The barrier for nodes at arclengths ``s`` (any order) of a rod of
        contact radius ``radius``: ``D = 2 radius +`` :func:`node_offset`
        with ``a`` the largest node spacing, ``g_hat = width radius``, the
        stiffness from ``force`` (module doc), ``exclusion`` default
        ``pi radius`` (:mod:`.search`); ``period``: a closed rod's length
        (:func:`.search.arclength_period`), the exclusion then wraps around
        the closure; ``handles``: the end nodes continued by handles (an
        open rod only)."""
        if not (np.isfinite(radius) and radius > 0):
            raise ValueError(f"radius must be a finite number > 0, not {radius!r}")
        if not (np.isfinite(width) and 0 < width):
            raise ValueError(f"width must be a finite number > 0 (times the radius), "
                             f"not {width!r}")
        if not (np.isfinite(force) and force > 0):
            raise ValueError(f"force must be a finite number > 0, not {force!r}")
        a = _chain(s)[1]
        ghat = width * radius
        return cls(distance=2 * radius + node_offset(a, radius), width=ghat,
                   stiffness=force / (HALF_WIDTH_FORCE * ghat),
                   exclusion=np.pi * radius if exclusion is None else float(exclusion),
                   period=None if period is None else float(period),
                   handles=tuple(int(k) for k in handles))


def _chain(s):
    """The nodes at arclengths ``s`` (any order) in arclength order, and
    their largest spacing ``a`` (what the barrier's distance and the bend
    and shear limits are set from)."""
    s = np.asarray(s, float)
    order = np.argsort(s)
    return order, float(np.diff(s[order]).max(initial=0.0))


def potential(g, width, stiffness):
    """``b, b', b''`` of the barrier at gaps ``0 < g < width`` (arrays)."""
    g = np.asarray(g, float)
    lg = np.log(g / width)
    gm = g - width
    b = -stiffness * gm ** 2 * lg
    b1 = -stiffness * (2 * gm * lg + gm ** 2 / g)
    b2 = -stiffness * (2 * lg + 4 * gm / g - gm ** 2 / g ** 2)
    return b, b1, b2


def _blocks(blk, dof, size):
    """The sparse ``size x size`` matrix of the dense blocks ``blk`` (``(k,
    m, m)``) at the global dofs ``dof`` (``(k, m)``), duplicates summed."""
    m = dof.shape[1]
    rows = np.repeat(dof, m, axis=1).ravel()
    cols = np.tile(dof, (1, m)).ravel()
    return sp.coo_matrix((blk.ravel(), (rows, cols)), shape=(size, size)).tocsc()


class NodePattern:
    """The CSC pattern of a sum of dense node blocks (:func:`_node_blocks`)
    built for one list of node tuples, kept while the list recurs: within
    a Newton solve the friction's pairs are the lag's, fixed, and the
    barrier's active pairs seldom change.  Where the list is the last
    one, the matrix's data is one weighted ``bincount`` of the blocks'
    entries into it (no sort): 1.2 ms against 8.6 ms for 3400 pairs of
    12 x 12 blocks (measured).  One per tangent term and solve (a fresh
    one keeps nothing between calls)."""

    def __init__(self):
        self.key = self.nodes = None
        self.dest = self.indices = self.indptr = None
        self.nnz = 0
        self.builds = 0           # patterns built (tests, benchmarks)

    def matrix(self, blk, nodes, n, dofs, m):
        """The ``(n dofs) x (n dofs)`` CSC matrix (indices sorted, no
        duplicates) of the blocks ``blk`` ``(k, nn m, nn m)`` over the
        nodes ``nodes`` ``(k, nn)`` (:func:`_node_blocks`)."""
        key = (n, dofs, m)
        if not (self.key == key and self.nodes.shape == nodes.shape
                and np.array_equal(self.nodes, nodes)):
            self.dest, self.indices, self.indptr, self.nnz = _block_pattern(nodes, n, dofs, m)
            self.key, self.nodes = key, nodes.copy()
            self.builds += 1
        data = np.bincount(self.dest, weights=blk.ravel(), minlength=self.nnz)
        H = sp.csc_matrix((data, self.indices.copy(), self.indptr.copy()),
                          shape=(n * dofs, n * dofs))
        H.has_sorted_indices = True
        H.has_canonical_format = True
        return H


def _block_pattern(nodes, n, dofs, m):
    """The CSC pattern of dense blocks over the nodes ``nodes`` (``(k,
    nn)``), each node's ``m`` rows and columns its first ``m`` of ``dofs``
    (duplicates summed): ``(dest, indices, indptr, nnz)``, ``dest`` the
    data position of each entry of the blocks ``(k, nn m, nn m)``
    raveled.  Built from the node blocks (a sort of ``k nn^2`` keys)
    instead of entry by entry, with no pass to sort the indices."""
    k, nn = nodes.shape
    if k == 0:
        return (np.zeros(0, np.int64), np.zeros(0, np.int32),
                np.zeros(n * dofs + 1, np.int32), 0)
    p = np.broadcast_to(nodes[:, :, None], (k, nn, nn)).ravel().astype(np.int64)
    q = np.broadcast_to(nodes[:, None, :], (k, nn, nn)).ravel().astype(np.int64)
    key = q * n + p                     # [term, row node, col node]
    o = np.argsort(key)                 # the order among duplicates: only summed
    ks = key[o]
    first = np.r_[True, ks[1:] != ks[:-1]]
    uid = np.empty(key.size, np.int64)
    uid[o] = np.cumsum(first) - 1       # each node block's unique block
    q, p = np.divmod(ks[first], n)
    cnt = np.bincount(q, minlength=n)
    cstart = np.r_[0, np.cumsum(cnt)]
    rank = np.arange(q.size) - cstart[q]
    # node q's columns hold m m cnt[q] entries from m m cstart[q]: column
    # j of them m cnt[q], the block of rank r m rows from r m, in order of p
    ar = np.arange(m)
    pos = (m * m * cstart[q][:, None, None] + ar[None, None, :] * (m * cnt[q])[:, None, None]
           + (m * rank)[:, None, None] + ar[None, :, None])           # [u, i, j]
    indices = np.empty(m * m * q.size, dtype=np.int32)
    indices[pos] = (dofs * p)[:, None, None] + ar[None, :, None]
    jj = np.minimum(np.arange(dofs), m)
    indptr = (m * m * cstart[:-1, None] + jj[None, :] * (m * cnt)[:, None]).ravel()
    indptr = np.r_[indptr, m * m * q.size].astype(np.int32)
    # entry [t, a, i, b, j] of the blocks: row i of node a, column j of node b
    dest = pos[uid].reshape(k, nn, nn, m, m).transpose(0, 1, 3, 2, 4).ravel()
    return dest, indices, indptr, m * m * q.size


def _node_blocks(blk, nodes, n, dofs, m, pattern=None):
    """The sparse ``(n dofs) x (n dofs)`` CSC matrix (indices sorted, no
    duplicates) of the dense blocks ``blk`` (``(k, nn m, nn m)``) over the
    nodes ``nodes`` (``(k, nn)``), each node's ``m`` rows and columns its
    first ``m`` of ``dofs`` (duplicates summed); ``pattern`` a
    :class:`NodePattern` that keeps the pattern between calls (default:
    built for this call)."""
    return (pattern or NodePattern()).matrix(blk, nodes, n, dofs, m)


def _pair_block(M):
    """``[[M, -M], [-M, M]]`` per pair: a term in ``x_i - x_j`` over
    ``(x_i, x_j)``."""
    return np.concatenate([np.concatenate([M, -M], 2), np.concatenate([-M, M], 2)], 1)


def node_pairs(x, s, reach, exclusion, period=None):
    """Pairs ``(k, 2)`` of nodes (positions ``x``, arclengths ``s``) closer
    than ``reach`` in space and at least ``exclusion`` apart in arclength
    (periodic with ``period``: a closed rod)."""
    from scipy.spatial import cKDTree
    pr = cKDTree(x).query_pairs(reach, output_type="ndarray")
    if pr.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    arc = np.abs(s[pr[:, 0]] - s[pr[:, 1]])
    if period is not None:
        arc = np.minimum(arc, period - arc)
    return pr[arc >= exclusion]


def _pairs(x, s, reach, barrier):
    """:func:`node_pairs` of ``barrier`` within ``reach``, without the
    pairs of its handles' nodes (the handles' own, :func:`handle_pairs`)."""
    pr = node_pairs(x, s, reach, barrier.exclusion, barrier.period)
    if barrier.handles and pr.shape[0]:
        pr = pr[~np.isin(pr, barrier.handles).any(axis=1)]
    return pr


def _near_pairs(x, s, reach, barrier, near=None):
    """:func:`_pairs` of ``barrier`` within ``reach``; with ``near`` (a
    :class:`~skfem_rod.contact.search.NeighbourList`) from the candidates
    it keeps across calls (found with its margin, kept while no node has
    moved by more than its skin: a superset of the pairs within the
    reach), filtered to the reach by their present distance."""
    if near is None:
        return _pairs(x, s, reach, barrier)
    i, j = near.pairs(x, reach, lambda margin: tuple(_pairs(x, s, reach + margin, barrier).T))
    d = x[i] - x[j]
    keep = np.einsum("ij,ij->i", d, d) < reach * reach
    return np.column_stack([i[keep], j[keep]])


class Handles(NamedTuple):
    """The nodes near the handles of a :class:`Barrier` at one
    configuration (one row per node and handle): node ``i`` against the
    half-line ``x_k + t e``, ``t >= 0``, of the handle at end node ``k``
    (``e`` its unit direction, away from the rod)."""
    pairs: np.ndarray         # (m, 2): node i, end node k
    q: np.ndarray             # (m, 3): x_i - (the handle's nearest point)
    along: np.ndarray         # (m,): t of the nearest point (0: the cap, the end node)
    direction: np.ndarray     # (m, 3): the handle's e


def handle_pairs(x, s, barrier, directions, reach):
    """:class:`Handles`: the nodes within ``reach`` of the handles of
    ``barrier`` (``directions`` ``(h, 3)``: each handle's unit direction,
    in the order of ``barrier.handles``) and at least ``exclusion`` from
    its end in arclength."""
    rows = []
    for k, e in zip(barrier.handles, np.asarray(directions, float).reshape(-1, 3)):
        i = np.flatnonzero(np.abs(s - s[k]) >= barrier.exclusion)
        u = x[i] - x[k]
        t = np.maximum(u @ e, 0.0)
        q = u - t[:, None] * e
        near = np.einsum("ij,ij->i", q, q) < reach ** 2
        m = int(near.sum())
        rows.append((np.column_stack([i[near], np.full(m, k)]), q[near], t[near],
                     np.broadcast_to(e, (m, 3))))
    if not rows:
        return Handles(np.zeros((0, 2), np.int64), np.zeros((0, 3)), np.zeros(0),
                       np.zeros((0, 3)))
    return Handles(*(np.concatenate(c) for c in zip(*rows)))


class Bend(NamedTuple):
    """The barrier on the nodes' turning angles (module doc, "Local
    self-contact"): ``g = t_0 . t_1 - cos(limit)`` at each node with a
    chord on either side, acting for ``0 < g < width``."""
    order: np.ndarray         # (n,) the nodes in arclength order
    closed: bool              # a ring: the first and last nodes are neighbours
    limit: float              # the largest turning angle at a node (rad)
    width: float              # the barrier acts for 0 < g < width
    stiffness: float          # kappa

    @classmethod
    def for_rod(cls, s, radius, bending, curvature=BEND_CURVATURE, onset=1.5, closed=False):
        """For nodes at arclengths ``s`` of a rod of radius ``radius``
        and bending stiffness ``bending``: the limit angle ``curvature /
        radius`` times the largest node spacing (at most 2.5 rad), the
        barrier acting beyond ``onset / radius``; ``kappa`` such that
        ``|b'(width / 2)| sin(limit) = bending * curvature / radius``: a
        node at half the width resists with about that moment."""
        order, a = _chain(s)
        limit = min(curvature * a / radius, 2.5)
        width = float(np.cos(onset / curvature * limit) - np.cos(limit))
        # |dE/dphi| = |b'(g)| sin(phi) at half the width: the moment
        moment = bending * curvature / radius
        stiffness = moment / (HALF_WIDTH_FORCE * width * np.sin(limit))
        return cls(order, bool(closed), limit, width, stiffness)


class LocalWork(NamedTuple):
    """The bend or the shear barrier at one configuration."""
    energy: float             # inf where a node turns (a section tilts) by the limit or more
    gradient: np.ndarray      # per node: (n, 3) dE/dx (bend), (n, 6) dE/dx, dE/dw (shear)
    hessian: object           # sparse (n * dofs, n * dofs); None if not asked or none active
    active: int               # terms with 0 < g < width


#: d(e_0, e_1) / d(x_a, x_b, x_c): e_0 = x_b - x_a, e_1 = x_c - x_b
_CHORDS = np.kron(np.array([[-1.0, 1.0, 0.0], [0.0, -1.0, 1.0]]), np.eye(3))


def bend_work(x, bend, hessian=True, dofs=3):
    """Energy, gradient and (``hessian``) exact Hessian of the bend
    barrier :class:`Bend` at node positions ``x``: at each node ``b``
    between ``a`` and ``c`` (arclength order), ``f = t_0 . t_1`` of its
    unit chords, ``df/de_0 = P_0 t_1 / |e_0|`` (``P_0 = I - t_0 t_0^T``),
    ``d2f/de_0^2 = -(t_0 g_0^T + g_0 t_0^T) / |e_0| - f P_0 / |e_0|^2``,
    ``d2f/de_0 de_1 = P_0 P_1 / (|e_0| |e_1|)``."""
    x = np.asarray(x, float)
    n = x.shape[0]
    o = bend.order
    idx = np.column_stack([np.roll(o, 1), o, np.roll(o, -1)]) if bend.closed else \
        np.column_stack([o[:-2], o[1:-1], o[2:]])
    grad = np.zeros((n, 3))
    e0, e1 = x[idx[:, 1]] - x[idx[:, 0]], x[idx[:, 2]] - x[idx[:, 1]]
    n0, n1 = np.linalg.norm(e0, axis=1), np.linalg.norm(e1, axis=1)
    t0, t1 = e0 / n0[:, None], e1 / n1[:, None]
    f = np.einsum("ij,ij->i", t0, t1)
    g = f - np.cos(bend.limit)
    if np.any(g <= 0):
        return LocalWork(np.inf, grad, None, int(np.sum(g < bend.width)))
    act = g < bend.width
    if not act.any():                  # (no empty Hessian to add: a sparse sum copies)
        return LocalWork(0.0, grad, None, 0)
    idx, t0, t1, n0, n1, f, g = idx[act], t0[act], t1[act], n0[act], n1[act], f[act], g[act]
    b, b1, b2 = potential(g, bend.width, bend.stiffness)
    g0 = (t1 - f[:, None] * t0) / n0[:, None]             # df/de_0
    g1 = (t0 - f[:, None] * t1) / n1[:, None]             # df/de_1
    df = np.hstack([g0, g1]) @ _CHORDS                   # df/dx: (k, 9)
    np.add.at(grad, idx.ravel(), (b1[:, None] * df).reshape(-1, 3))
    H = None
    if hessian:
        eye = np.eye(3)
        P0 = eye - t0[:, :, None] * t0[:, None, :]
        P1 = eye - t1[:, :, None] * t1[:, None, :]

        def own(t, gv, P, nn):
            return (-(t[:, :, None] * gv[:, None, :] + gv[:, :, None] * t[:, None, :])
                    / nn[:, None, None] - f[:, None, None] * P / (nn ** 2)[:, None, None])
        H01 = np.einsum("kij,kjl->kil", P0, P1) / (n0 * n1)[:, None, None]
        He = np.zeros((idx.shape[0], 6, 6))
        He[:, :3, :3], He[:, 3:, 3:] = own(t0, g0, P0, n0), own(t1, g1, P1, n1)
        He[:, :3, 3:], He[:, 3:, :3] = H01, H01.transpose(0, 2, 1)
        Hx = _CHORDS.T @ He @ _CHORDS                               # (k, 9, 9)
        blk = b2[:, None, None] * df[:, :, None] * df[:, None, :] + b1[:, None, None] * Hx
        H = _blocks(blk, (idx[:, :, None] * dofs + np.arange(3)).reshape(-1, 9), n * dofs)
    return LocalWork(float(b.sum()), grad, H, int(act.sum()))


class Shear(NamedTuple):
    """The barrier on the angle between each section's ``d3`` and the
    chords to its neighbours (module doc, "Local self-contact"): ``g = d3 .
    c - cos(limit)`` (``c`` the unit chord), acting for ``0 < g < width``."""
    order: np.ndarray         # (n,) the nodes in arclength order
    closed: bool              # a ring: the first and last nodes are neighbours
    limit: float              # the largest angle between d3 and a chord (rad)
    width: float              # the barrier acts for 0 < g < width
    stiffness: float          # kappa

    @classmethod
    def for_rod(cls, s, radius, bending, angle=0.5, onset=0.3, closed=False):
        """For nodes at arclengths ``s`` of a rod of radius ``radius`` and
        bending stiffness ``bending``: the limit ``a / radius + angle``
        (``a`` the largest node spacing: a chord turns from the tangent by
        up to ``a / radius`` where the bend barrier allows a curvature of
        ``2 / radius``), at most 2 rad, the barrier acting beyond ``a /
        radius + onset``; ``kappa`` such that ``|b'(width / 2)|
        sin(limit) = 2 bending / radius``: a section at half the width
        resists with about that moment."""
        order, a = _chain(s)
        limit = min(a / radius + angle, 2.0)
        width = float(np.cos(limit - (angle - onset)) - np.cos(limit))
        stiffness = 2 * bending / radius / (HALF_WIDTH_FORCE * width * np.sin(limit))
        return cls(order, bool(closed), limit, width, stiffness)


def shear_work(x, R, shear, hessian=True):
    """Energy, gradient and (``hessian``) tangent of the shear barrier
    :class:`Shear` at nodes ``(x, R)``, over the 6 dofs per node
    (positions; spatial spins, ``R <- exp(w) R``).  Per chord ``e = x_j -
    x_i`` and each of its two sections ``p``: ``f = d3_p . c``; ``df/de =
    P_c d3 / |e|``, ``df/dw_p = d3 x c``; the tangent is the derivative
    of that gradient (the spins' block ``d3 c^T - f I`` as the spin turns
    ``d3``, not symmetric, as :func:`friction_work`'s)."""
    x = np.asarray(x, float)
    n = x.shape[0]
    o = shear.order
    i, j = (o, np.roll(o, -1)) if shear.closed else (o[:-1], o[1:])
    e = x[j] - x[i]
    ne = np.linalg.norm(e, axis=1)
    c = e / ne[:, None]
    # each chord twice: with its first node's section, then its second's
    i, j, c, ne = (np.concatenate([v, v]) for v in (i, j, c, ne))
    p = np.concatenate([o[:-1], o[1:]] if not shear.closed else [o, np.roll(o, -1)])
    d3 = R[p][:, :, 2]
    f = np.einsum("ij,ij->i", d3, c)
    g = f - np.cos(shear.limit)
    grad = np.zeros((n, 6))
    if np.any(g <= 0):
        return LocalWork(np.inf, grad, None, int(np.sum(g < shear.width)))
    act = g < shear.width
    if not act.any():
        return LocalWork(0.0, grad, None, 0)
    i, j, p, c, ne, d3, f, g = (v[act] for v in (i, j, p, c, ne, d3, f, g))
    b, b1, b2 = potential(g, shear.width, shear.stiffness)
    ge = (d3 - f[:, None] * c) / ne[:, None]               # df/de
    gw = cross(d3, c)                                      # df/dw_p
    np.add.at(grad[:, :3], i, -b1[:, None] * ge)
    np.add.at(grad[:, :3], j, b1[:, None] * ge)
    np.add.at(grad[:, 3:], p, b1[:, None] * gw)
    H = None
    if hessian:
        k = f.size
        eye = np.eye(3)
        Pc = eye - c[:, :, None] * c[:, None, :]
        Hee = (-(c[:, :, None] * ge[:, None, :] + ge[:, :, None] * c[:, None, :])
               / ne[:, None, None] - f[:, None, None] * Pc / (ne ** 2)[:, None, None])
        Hew = -np.einsum("kab,kbc->kac", Pc, hat(d3)) / ne[:, None, None]   # d(ge)/dw
        Hww = d3[:, :, None] * c[:, None, :] - f[:, None, None] * eye      # d(gw)/dw
        # the local dofs (x_i, x_j, w_p); e = x_j - x_i
        df = np.hstack([-ge, ge, gw])
        D = np.zeros((k, 9, 9))
        D[:, :6, :6] = _pair_block(Hee)                    # e = x_j - x_i
        D[:, :3, 6:], D[:, 3:6, 6:] = -Hew, Hew
        D[:, 6:, :3], D[:, 6:, 3:6] = -Hew.transpose(0, 2, 1), Hew.transpose(0, 2, 1)
        D[:, 6:, 6:] = Hww
        blk = b2[:, None, None] * df[:, :, None] * df[:, None, :] + b1[:, None, None] * D
        dof = np.concatenate([i[:, None] * 6 + np.arange(3), j[:, None] * 6 + np.arange(3),
                              p[:, None] * 6 + 3 + np.arange(3)], axis=1)
        H = _blocks(blk, dof, 6 * n)
    return LocalWork(float(b.sum()), grad, H, int(act.sum()))


class PairForces(NamedTuple):
    """The barrier's normal forces on given node pairs at one configuration."""
    normal: np.ndarray        # (k, 3) unit (x_i - x_j) / |x_i - x_j|
    distance: np.ndarray      # (k,) |x_i - x_j|
    force: np.ndarray         # (k,) -b'(g) >= 0: 0 beyond the width, inf at or inside D
    stiffness: np.ndarray     # (k,) d force / d g = -b''(g) (0 beyond the width)


def pair_forces(x, pairs, barrier):
    """The normal force ``-b'(g)`` of each node pair of ``pairs``
    (``(k, 2)``) at the node positions ``x``, its derivative in the gap and
    the pair's normal: :class:`PairForces`."""
    d = x[pairs[:, 0]] - x[pairs[:, 1]]
    dist = np.linalg.norm(d, axis=1)
    g = dist - barrier.distance
    force, stiff = np.zeros(g.size), np.zeros(g.size)
    on = (g > 0) & (g < barrier.width)
    _, b1, b2 = potential(g[on], barrier.width, barrier.stiffness)
    force[on], stiff[on] = -b1, -b2
    force[g <= 0] = np.inf
    return PairForces(d / dist[:, None], dist, force, stiff)


class BarrierWork(NamedTuple):
    """The barrier at one configuration."""
    energy: float             # inf where a pair is at or inside D
    gradient: np.ndarray      # (n, 3) dE/dx per node
    hessian: object           # sparse (n * dofs, n * dofs), or None
    active: int               # pairs with 0 < g < g_hat
    min_gap: float            # least gap g of the pairs in reach (inf: none)
    #: (n, 3) dE/d(spin) per node: the handles' moments on their ends
    #: (zero without handles)
    spin_gradient: np.ndarray = None


def barrier_work(x, s, barrier, hessian=True, dofs=3, directions=None, near=None,
                 pattern=None):
    """Energy, gradient and (``hessian``) exact Hessian of the barrier at
    node positions ``x`` (``(n, 3)``), arclengths ``s``: per pair the block
    ``b'' n n^T + b'/|d| (P - n n^T)`` (the second part negative; Newton's
    shift handles the indefinite tangent; ``P`` the identity for node
    pairs, the projection normal to the handle for a node against a
    handle's side).  The Hessian is laid out with ``dofs`` unknowns per
    node, the position first (6: a rod's positions and spins).  With
    handles, ``directions`` are theirs (:func:`handle_pairs`); their
    moments on the end sections are in ``spin_gradient`` (the Hessian has
    no spin terms: the ends' rotations are held).  ``near``: a
    :class:`~skfem_rod.contact.search.NeighbourList` to find the pairs
    with (default: a k-d tree at each call); ``pattern``: a
    :class:`NodePattern` that keeps the Hessian's pattern between calls."""
    x = np.asarray(x, float)
    n = x.shape[0]
    bw = barrier
    reach = bw.distance + bw.width
    pr = _near_pairs(x, s, reach, bw, near)
    d = x[pr[:, 0]] - x[pr[:, 1]]
    along = np.zeros(pr.shape[0])
    axis = np.zeros((pr.shape[0], 3))          # the handle's e (0: a node pair)
    if bw.handles:
        if directions is None:
            raise ValueError("barrier_work: the barrier has handles; give their directions")
        hp = handle_pairs(x, s, bw, directions, reach)
        pr, d = np.concatenate([pr, hp.pairs]), np.concatenate([d, hp.q])
        along, axis = np.concatenate([along, hp.along]), np.concatenate([axis, hp.direction])
    grad, spin = np.zeros((n, 3)), np.zeros((n, 3))
    empty = sp.csc_matrix((n * dofs, n * dofs)) if hessian else None
    if pr.shape[0] == 0:
        return BarrierWork(0.0, grad, empty, 0, np.inf, spin)
    dist = np.linalg.norm(d, axis=1)
    g = dist - bw.distance
    gmin = float(g.min())
    if gmin <= 0:
        return BarrierWork(np.inf, grad, empty, int(np.sum(g < bw.width)), gmin, spin)
    act = g < bw.width
    pr, d, dist, g, along, axis = pr[act], d[act], dist[act], g[act], along[act], axis[act]
    b, b1, b2 = potential(g, bw.width, bw.stiffness)
    nv = d / dist[:, None]
    f = b1[:, None] * nv
    np.add.at(grad, pr[:, 0], f)
    np.add.at(grad, pr[:, 1], -f)
    # a handle's point x_k + t e turns with its end: d/d(spin) (t e) x dE/dp
    np.add.at(spin, pr[:, 1], cross(along[:, None] * axis, -f))
    H = None
    if hessian:
        nn = nv[:, :, None] * nv[:, None, :]
        proj = np.eye(3) - axis[:, :, None] * axis[:, None, :]      # on the side only
        proj[along <= 0] = np.eye(3)
        blk = b2[:, None, None] * nn + (b1 / dist)[:, None, None] * (proj - nn)
        H = _node_blocks(_pair_block(blk), pr, n, dofs, 3, pattern)
    return BarrierWork(float(b.sum()), grad, H, int(act.sum()), gmin, spin)


def _first_root(A, B, C):
    """The first ``t >= 0`` with ``A t^2 + B t + C = 0`` where the
    quadratic falls into it from ``C > 0`` (inf: none)."""
    disc = B ** 2 - 4 * A * C
    hit = (A > 0) & (disc >= 0) & (B < 0)
    t = np.full(A.shape, np.inf)
    # the smaller root, in the cancellation-free form 2C / (-B + sqrt(disc))
    t[hit] = 2 * C[hit] / (-B[hit] + np.sqrt(disc[hit]))
    t[t < 0] = np.inf
    return t


def step_bound(x, dx, s, barrier, fraction=0.8, directions=None, near=None):
    """The largest ``alpha`` in ``(0, 1]`` such that moving the nodes along
    ``x + t dx`` for ``t <= alpha / fraction`` keeps every node pair (at
    least ``exclusion`` apart in arclength) farther apart than ``D``:
    ``fraction`` times the first root of ``|d + t e|^2 = D^2`` over the
    pairs that can reach it (continuous collision detection, exact for the
    straight paths of the positions).  With handles (``directions``), each
    node also keeps ``D`` from each handle: its side (a cylinder, the
    root counted where it lies beyond the end) and its cap (the end
    node's sphere); exact for handles that do not turn within the step.
    ``near``: a :class:`~skfem_rod.contact.search.NeighbourList` to find
    the pairs with (default: a k-d tree at each call)."""
    x, dx = np.asarray(x, float), np.asarray(dx, float)
    bw = barrier
    m = float(np.linalg.norm(dx, axis=1).max(initial=0.0))
    reach = bw.distance + 2 * m                        # within reach of D
    pr = _near_pairs(x, s, reach, bw, near)
    d0, e = x[pr[:, 0]] - x[pr[:, 1]], dx[pr[:, 0]] - dx[pr[:, 1]]
    t = [_first_root(np.einsum("ij,ij->i", e, e), 2 * np.einsum("ij,ij->i", d0, e),
                     np.einsum("ij,ij->i", d0, d0) - bw.distance ** 2)]
    if bw.handles:
        if directions is None:
            raise ValueError("step_bound: the barrier has handles; give their directions")
        hp = handle_pairs(x, s, bw, directions, reach)
        i, k, a = hp.pairs[:, 0], hp.pairs[:, 1], hp.direction
        u, w = x[i] - x[k], dx[i] - dx[k]
        t.append(_first_root(np.einsum("ij,ij->i", w, w), 2 * np.einsum("ij,ij->i", u, w),
                             np.einsum("ij,ij->i", u, u) - bw.distance ** 2))     # the cap
        pu = u - np.einsum("ij,ij->i", u, a)[:, None] * a
        pw = w - np.einsum("ij,ij->i", w, a)[:, None] * a
        side = _first_root(np.einsum("ij,ij->i", pw, pw), 2 * np.einsum("ij,ij->i", pu, pw),
                           np.einsum("ij,ij->i", pu, pu) - bw.distance ** 2)
        # the infinite cylinder's root counts where it lies beyond the end:
        # before it, the path enters the half-cylinder through the cap
        beyond = np.isfinite(side)
        beyond[beyond] = np.einsum("ij,ij->i", u[beyond] + side[beyond, None] * w[beyond],
                                   a[beyond]) >= 0
        t.append(np.where(beyond, side, np.inf))
    return float(min(1.0, fraction * min(float(v.min(initial=np.inf)) for v in t)))


# -- friction ---------------------------------------------------------------
#
# Coulomb friction at the node pairs after IPC (Li et al. 2020).  Each
# pair's contact point -- the two nodes' midpoint where the pair's history
# starts -- is a material point of both sections (an arm in each body frame,
# held for the step, :func:`friction_lag`); the two points coincided then,
# so the slip u_k is their separation now, projected on the plane normal to
# the normal (carried with the sections' finite rotations: a rigid motion
# gives none).  A step of a load path starts with the slip each pair had at
# its start, cut to eps_v (:func:`carry_slip`, the friction's memory): its
# two points are set that far apart.  The friction force on the points is
#
#     phi_k = mu lambda_k f1(|u_k|) u_k / |u_k|,
#
# f1 smoothing |u| below eps_v (2y/eps_v - y^2/eps_v^2 below eps_v, 1
# above): at most mu lambda, equal to it where the pair slips by eps_v or
# more (Coulomb's law, the stick state regularized by a slip of at most
# eps_v, as the paper's tangential penalty regularizes it).
#
# With the normal force lambda_k and the normal lagged (:class:`FrictionLag`)
# the force is the gradient of IPC's dissipation potential
# D = sum_k mu lambda_k f0(|u_k|), f0' = f1 (:func:`friction_work`, Newton on
# the energy).  With both the state's own (:func:`friction_live`) it is no
# potential's gradient, and Coulomb's law holds at the state itself; the
# solve (skfem_rod.minimize) ends there.


@dataclass(frozen=True)
class FrictionLag:
    """The lagged quantities of the node pairs' friction (one row per pair)."""
    pairs: np.ndarray     # (k, 2) node indices
    normal: np.ndarray    # (k, 3) unit (x_i - x_j) / |x_i - x_j| at the lag
    force: np.ndarray     # (k,) normal force -b'(g) >= 0 at the lag
    arm_i: np.ndarray     # (k, 3) the contact point on section i, in its body frame
    arm_j: np.ndarray     # (k, 3) the contact point on section j, in its body frame
    #: (k, 3, 3) ``R_i^T R_j`` where the pair's history starts: the two
    #: sections' relative orientation (the rotational law's reference;
    #: None: no rotational friction)
    turn: Optional[np.ndarray] = None


def _pair_lookup(pairs, n_nodes, keys_of):
    """Index into ``keys_of`` (a ``(k, 2)`` pair array) of each row of
    ``pairs``, -1 where it has none."""
    key = pairs[:, 0] * n_nodes + pairs[:, 1]
    old = keys_of[:, 0] * n_nodes + keys_of[:, 1]
    if old.size == 0:
        return np.full(key.size, -1)
    order = np.argsort(old)
    at = np.clip(np.searchsorted(old[order], key), 0, old.size - 1)
    return np.where(old[order][at] == key, order[at], -1)


def _carried(values, pairs_of, pairs, n_nodes):
    """``values`` (one per row of ``pairs_of``) on the node pairs
    ``pairs``: 0 for a pair ``pairs_of`` does not have."""
    at = _pair_lookup(pairs, n_nodes, pairs_of)
    out = np.zeros(pairs.shape[0])
    out[at >= 0] = values[at[at >= 0]]
    return out


def lag_change(a, b, n_nodes):
    """The largest change of a node pair's normal force between the lags
    ``a`` and ``b`` (a pair missing from one counts with 0 there)."""
    at = _pair_lookup(b.pairs, n_nodes, a.pairs)
    was = _carried(a.force, a.pairs, b.pairs, n_nodes)
    gone = np.ones(a.pairs.shape[0], bool)
    gone[at[at >= 0]] = False
    return float(max(np.abs(b.force - was).max(initial=0.0), a.force[gone].max(initial=0.0)))


def same_friction(lag, new, held, n_nodes):
    """Whether the friction of ``new`` (the lag taken at a state solved
    with ``lag``, :func:`friction_lag` with ``previous=lag`` and ``held``)
    is ``lag``'s at that state, with the normal forces and normals live
    (:func:`friction_live`): every pair of ``lag`` is in ``new`` with its
    material points, and every pair new to ``new`` met during the step
    (not in ``held``), so its points coincide at the state: no slip, no
    force.  The state is then an equilibrium with its own lag, and the
    solve need not check that again."""
    if not np.all(_pair_lookup(lag.pairs, n_nodes, new.pairs) >= 0):
        return False
    added = new.pairs[_pair_lookup(new.pairs, n_nodes, lag.pairs) < 0]
    return not np.any(_pair_lookup(added, n_nodes, np.asarray(held).reshape(-1, 2)) >= 0)


class Relaxation:
    """Aitken's dynamic relaxation of the lag's normal forces (Irons &
    Tuck 1969; Kuettler & Wall 2008 for coupled solves): the fixed-point
    residual ``rho = lambda(state) - lambda(lag)`` per pair, and the next
    lag's forces ``lambda(lag) + omega rho`` with ``omega`` the secant
    estimate ``-omega_last rho_last . (rho - rho_last) / |rho -
    rho_last|^2``, kept in ``[lower, upper]``.  A lag that alternates
    (``omega`` falls below 1) and one that creeps (above 1) both settle
    faster than unrelaxed; the fixed point is the same.  Pairs are matched
    by their nodes; a pair missing from a lag counts with force 0 there."""

    def __init__(self, n_nodes, omega=1.0, lower=0.05, upper=10.0):
        self.n_nodes, self.omega, self.lower, self.upper = n_nodes, omega, lower, upper
        self.last = None                      # (pairs, rho) of the last lag

    def __call__(self, new, previous):
        """The next lag: ``new`` (the lag at the state solved with
        ``previous``) with its normal forces relaxed."""
        was = _carried(previous.force, previous.pairs, new.pairs, self.n_nodes)
        rho = new.force - was
        if self.last is not None:
            pairs, rho_last = self.last
            old = _carried(rho_last, pairs, new.pairs, self.n_nodes)
            d = rho - old
            dd = float(d @ d)
            if dd > 0:
                self.omega = float(np.clip(-self.omega * float(old @ d) / dd,
                                           self.lower, self.upper))
        self.last = (new.pairs, rho)
        return replace(new, force=np.maximum(was + self.omega * rho, 0.0))


def _arms(x, R, i, j, apart=None):
    """The midpoint of nodes ``i``, ``j`` at ``(x, R)`` as a material point
    of both sections: its arms in the two body frames.  ``apart``: the
    point of section i that far from section j's instead (``(k, 3)``,
    half of it each way from the midpoint)."""
    mid = 0.5 * (x[i] + x[j])
    half = 0.0 if apart is None else 0.5 * apart
    arm_i = np.einsum("kba,kb->ka", R[i], mid + half - x[i])     # R_i^T (p_i - x_i)
    arm_j = np.einsum("kba,kb->ka", R[j], mid - half - x[j])
    return arm_i, arm_j


def _turn(R, i, j, pivot=None, normal=None):
    """``R_i^T R_j`` of the node pairs ``(i, j)`` at the rotations ``R``:
    their sections' relative orientation, the rotational law's reference
    where a pair's history starts.  ``pivot`` (``(k,)``, with the unit
    ``normal``): the reference the sections have turned that far from
    about the normal, as the rotational law measures it
    (:func:`_pivot`: ``sin`` of the angle), i.e. ``R_i^T exp(phi n)
    R_j`` with ``sin phi = pivot``."""
    if pivot is None:
        return np.einsum("kba,kbc->kac", R[i], R[j])
    phi = np.arcsin(np.clip(pivot, -1.0, 1.0))
    return np.einsum("kba,kbc,kcd->kad", R[i], expm(phi[:, None] * normal), R[j])


def friction_lag(x, R, x0, R0, s, barrier, previous=None, held=None):
    """The :class:`FrictionLag` at the configuration ``(x, R)`` of a step
    that started at ``(x0, R0)`` (node positions ``(n, 3)``, rotations
    ``(n, 3, 3)``): the pairs inside the barrier's width, their normal
    forces and normals there, and each pair's contact point as a material
    point of both sections (its arms in the two body frames).

    The contact point is the midpoint of the two nodes -- on the touching
    surfaces to within the barrier's width -- where the pair's history
    starts: at the step's start for the pairs in ``held`` (``(k, 2)``, in
    contact then; all pairs when ``held`` is None), and where the pair is
    now for the others (they met during the step: their points have no
    common history before that).  A pair that ``previous`` (an earlier lag
    of the step) has keeps its points.  The two material points coincide
    where the history starts, so the slip is their separation now, and a
    rigid motion (any rotation) moves them together: no slip."""
    bw = barrier
    pr = _pairs(x, s, bw.distance + bw.width, bw)
    pf = pair_forces(x, pr, bw)
    keep = np.isfinite(pf.force) & (pf.force > 0)          # inside the barrier's width
    pr, n, lam = pr[keep], pf.normal[keep], pf.force[keep]
    i, j = pr[:, 0], pr[:, 1]
    arm_i, arm_j = _arms(x0, R0, i, j)
    turn = _turn(R0, i, j)
    if held is not None:
        new = _pair_lookup(pr, x.shape[0], np.asarray(held).reshape(-1, 2)) < 0
        arm_i[new], arm_j[new] = _arms(x, R, i[new], j[new])
        turn[new] = _turn(R, i[new], j[new])
    if previous is not None:
        at = _pair_lookup(pr, x.shape[0], previous.pairs)
        had = at >= 0
        k = at[had]
        arm_i[had], arm_j[had] = previous.arm_i[k], previous.arm_j[k]
        if previous.turn is not None:
            turn[had] = previous.turn[k]
    return FrictionLag(pr, n, lam, arm_i, arm_j, turn)


def carry_slip(lag, x, R, previous, eps_v, eps_R=None):
    """``lag`` (taken at ``(x, R)``, where a step starts) with the slips
    that its pairs had in ``previous`` (the lag the state ``(x, R)`` was
    solved with) carried into the step: the friction's memory.

    Each pair that ``previous`` has keeps its slip there, projected on the
    plane normal to ``lag``'s normal and cut to at most ``eps_v`` long: its
    two material points are set that far apart about the nodes' midpoint
    (re-centred there at every step: points kept where they were drift
    off the nodes as the sections turn, measured, docs/contact-solve.md).
    The step then starts with the friction force the pair had at the
    state (a stuck pair's force from its slip below ``eps_v``, a sliding
    pair's ``mu lambda`` along its slip), not from zero: a step that adds
    no load leaves the state as it is, and a pair that stuck does not
    creep by a slip of up to ``eps_v`` per step to build its force up
    again.  What slip exceeds ``eps_v`` is dropped (the smoothed law is
    flat there: the force is the same), as a return mapping of an
    elastic-plastic tangential spring does; a pair that turns back slips
    through ``2 eps_v`` before its force has turned.  With ``eps_R`` the
    rotational law's slip (the pivot about ``lag``'s normal,
    :func:`_pivot`) is carried likewise, cut to ``eps_R``."""
    at = _pair_lookup(lag.pairs, x.shape[0], previous.pairs)
    had = at >= 0
    if not had.any():
        return lag
    delta = _slip(x, R, previous)[4][at[had]]         # the old points' separation
    i, j = lag.pairs[had, 0], lag.pairs[had, 1]
    n = lag.normal[had]
    u = delta - np.einsum("ka,ka->k", delta, n)[:, None] * n
    y = np.linalg.norm(u, axis=1)
    u *= np.minimum(1.0, eps_v / np.maximum(y, 1e-300))[:, None]
    arm_i, arm_j = lag.arm_i.copy(), lag.arm_j.copy()
    arm_i[had], arm_j[had] = _arms(x, R, i, j, apart=u)
    turn = lag.turn
    if eps_R is not None and turn is not None and previous.turn is not None:
        _, w, _ = _pivot(R, i, j, previous.turn[at[had]])
        theta = np.clip(np.einsum("ka,ka->k", n, w), -eps_R, eps_R)
        turn = turn.copy()
        turn[had] = _turn(R, i, j, theta, n)
    return replace(lag, arm_i=arm_i, arm_j=arm_j, turn=turn)


class FrictionWork(NamedTuple):
    """The friction at one configuration."""
    energy: float             # the potential D (nan with live normal forces: none)
    gradient: np.ndarray      # (n, 6): positions, then spins
    hessian: object           # sparse (6 n, 6 n), or None
    force: np.ndarray         # (k, 3) friction force on node i's section (-dD/du)
    slip: np.ndarray          # (k,) |u|
    #: (k, 3) the rotational law's couple on node i's section (j gets
    #: -it) and (k,) its slip, the pivot about the normal (:func:`_pivot`);
    #: None without rotational friction
    couple: Optional[np.ndarray] = None
    pivot: Optional[np.ndarray] = None


def _slip(x, R, lag):
    """The pairs' contact points on both sections at ``(x, R)`` (``c_i``,
    ``c_j``, from the nodes) and their separation ``delta``: the slip
    before its projection on the tangent plane.  The kinematics of both
    :func:`friction_work` and :func:`friction_live`."""
    i, j = lag.pairs[:, 0], lag.pairs[:, 1]
    c_i = np.einsum("kab,kb->ka", R[i], lag.arm_i)
    c_j = np.einsum("kab,kb->ka", R[j], lag.arm_j)
    delta = (x[i] + c_i) - (x[j] + c_j)           # the points coincided: the slip
    return i, j, c_i, c_j, delta


def _smoothed(y, eps_v):
    """Coulomb's law smoothed below the slip ``eps_v``, at slips ``y``:
    ``f0`` (the potential per unit ``mu lambda``), ``f1 / y`` and ``c``
    with ``(f1' y - f1) / y^3 u u^T = c (u/y)(u/y)^T``."""
    small = y < eps_v
    f0 = np.where(small, -y ** 3 / (3 * eps_v ** 2) + y ** 2 / eps_v + eps_v / 3, y)
    ratio = np.where(small, 2 / eps_v - y / eps_v ** 2, 1 / np.maximum(y, 1e-300))
    c = np.where(small, -y / eps_v ** 2, -1 / np.maximum(y, eps_v))
    return f0, ratio, c


def _law(u, y, ratio, c, ml):
    """``d phi / d u`` per pair, ``phi = ml f1(|u|) u / |u|`` the friction
    force's magnitude along the slip: ``ml (f1/y I + c (u/y)(u/y)^T)``."""
    uh = u / np.maximum(y, 1e-300)[:, None]           # the slip's direction (0 at rest)
    return ml[:, None, None] * (ratio[:, None, None] * np.eye(3)
                                + c[:, None, None] * uh[:, :, None] * uh[:, None, :])


def _points_jacobian(c_i, c_j):
    """``d delta`` per pair over the positions and spins of nodes i and j
    (``(k, 3, 12)``; spatial spins turn the arms: ``dc = w x c``)."""
    k = c_i.shape[0]
    eye = np.broadcast_to(np.eye(3), (k, 3, 3))
    return np.concatenate([eye, -hat(c_i), -eye, hat(c_j)], axis=2)


def _scatter(grad, i, j, c_i, c_j, phi):
    """Adds the pairs' force ``phi`` (on the contact points) to the
    generalized force: on positions and, through the arms, spins."""
    np.add.at(grad[:, :3], i, phi)
    np.add.at(grad[:, :3], j, -phi)
    np.add.at(grad[:, 3:], i, cross(c_i, phi))
    np.add.at(grad[:, 3:], j, -cross(c_j, phi))


def _arms_turn(blk, c_i, c_j, phi):
    """Adds to the pair blocks the derivative of the spins' force
    ``c x phi`` as the spins turn the arms, ``phi`` held:
    ``d(c x phi)/dw = c phi^T - (c . phi) I`` (not symmetric)."""
    blk[:, 3:6, 3:6] += c_i[:, :, None] * phi[:, None, :] \
        - np.einsum("ka,ka->k", c_i, phi)[:, None, None] * np.eye(3)
    blk[:, 9:12, 9:12] -= c_j[:, :, None] * phi[:, None, :] \
        - np.einsum("ka,ka->k", c_j, phi)[:, None, None] * np.eye(3)


def _assemble(blk, lag, n_nodes, pattern):
    """The sparse matrix of the 12 x 12 blocks ``blk`` of ``lag``'s pairs
    (``pattern``: a :class:`NodePattern` or None)."""
    return _node_blocks(blk, lag.pairs, n_nodes, 6, 6, pattern)


def _pivot(R, i, j, turn):
    """The rotational law's kinematics of the pairs ``(i, j)`` at the
    rotations ``R``, ``turn`` their reference (:attr:`FrictionLag.turn`):
    ``Psi = R_i turn R_j^T``, the relative rotation of the two sections
    since the reference (the identity for a rigid motion of any size),
    ``w`` the axial vector of its skew part (``sin`` of its angle about
    its axis) and its trace.  The slip is the pivot ``theta = n . w``
    about the normal ``n``: the relative spin the tangential law, whose
    lever arms lie along the normal, does not see (docs/friction.md,
    F7, "pivot")."""
    if turn is None:
        raise ValueError("rotational friction needs the lag's reference rotations (turn)")
    Psi = np.einsum("kab,kbc,kdc->kad", R[i], turn, R[j])
    return Psi, vee(Psi), np.einsum("kaa->k", Psi)


def _pivot_gradient(Psi, tr, n):
    """``d theta / d a`` and ``d theta / d b`` (``theta = n . vee(Psi)``,
    ``n`` held) over the spatial spins ``a`` of section i and ``b`` of
    section j (``Psi <- exp(a) Psi exp(-b)``)."""
    return (0.5 * (tr[:, None] * n - np.einsum("kba,kb->ka", Psi, n)),
            -0.5 * (tr[:, None] * n - np.einsum("kab,kb->ka", Psi, n)))


def _pivot_hessian(blk, Psi, w, n, g_a, g_b, tau, k_theta):
    """Adds to the pair blocks ``blk`` (``(k, 12, 12)``: x_i, a, x_j, b)
    the derivative over the spins of the generalized force ``tau (g_a,
    g_b)`` of the potential ``D(theta)``, ``tau = D'``, ``k_theta = D''``:
    ``k_theta g g^T + tau dg/d(a, b)`` (``n`` held; the second part not
    symmetric, as the spins are no coordinates)."""
    nw = n[:, :, None] * w[:, None, :]
    hn = hat(n)
    t = tau[:, None, None]
    outer = k_theta[:, None, None]
    blk[:, 3:6, 3:6] += outer * g_a[:, :, None] * g_a[:, None, :] \
        + t * (-nw - 0.5 * np.swapaxes(Psi, 1, 2) @ hn)
    blk[:, 3:6, 9:12] += outer * g_a[:, :, None] * g_b[:, None, :] \
        + t * (nw + 0.5 * hat(np.einsum("kba,kb->ka", Psi, n)))
    blk[:, 9:12, 3:6] += outer * g_b[:, :, None] * g_a[:, None, :] \
        + t * (nw - 0.5 * hat(np.einsum("kab,kb->ka", Psi, n)))
    blk[:, 9:12, 9:12] += outer * g_b[:, :, None] * g_b[:, None, :] \
        + t * (-nw + 0.5 * Psi @ hn)


def friction_work(x, R, lag, mu, eps_v, hessian=True, pattern=None, mu_R=0.0, eps_R=None):
    """The dissipation potential ``D`` of :class:`FrictionLag` ``lag`` at
    ``(x, R)`` (module notes above), friction coefficient ``mu``, slip
    smoothing ``eps_v``, the normal forces and normals the lag's:
    energy, gradient and Hessian over the 6 dofs per node (positions;
    spatial spins, ``R <- exp(w) R``).  The Hessian is the exact one of
    ``D`` in the surface points' slip times their Jacobian on both sides
    (positive semi-definite); the second derivative of the rotation acting
    on the arm is left out.  ``pattern``: a :class:`NodePattern` that
    keeps the Hessian's pattern between calls (the lag's pairs).  With
    ``mu_R > 0`` (a length) the rotational law too, its slip the pivot
    about the lag's normal smoothed below ``eps_R`` (:func:`_pivot`), its
    potential ``mu_R lambda f0(|theta|)`` and its exact derivatives."""
    n_nodes = x.shape[0]
    grad = np.zeros((n_nodes, 6))
    k = lag.pairs.shape[0]
    if k == 0 or (mu == 0 and mu_R == 0):
        H = sp.csc_matrix((6 * n_nodes, 6 * n_nodes)) if hessian else None
        return FrictionWork(0.0, grad, H, np.zeros((k, 3)), np.zeros(k))
    i, j, c_i, c_j, delta = _slip(x, R, lag)
    nrm = lag.normal
    u = delta - np.einsum("ka,ka->k", delta, nrm)[:, None] * nrm
    y = np.linalg.norm(u, axis=1)
    f0, ratio, c = _smoothed(y, eps_v)
    ml = mu * lag.force
    phi = (ml * ratio)[:, None] * u                        # dD/d(delta), in the plane
    _scatter(grad, i, j, c_i, c_j, phi)
    if hessian:
        PJ = (np.eye(3) - nrm[:, :, None] * nrm[:, None, :]) @ _points_jacobian(c_i, c_j)
        # PJ^T L PJ by batched products: the three-operand einsum runs
        # unoptimized, 20 times slower (1.4 ms against 0.07 ms, 600 pairs)
        blk = np.swapaxes(PJ, 1, 2) @ (_law(u, y, ratio, c, ml) @ PJ)
        _arms_turn(blk, c_i, c_j, phi)
    energy = float(np.sum(ml * f0))
    couple = theta = None
    if mu_R > 0:
        Psi, w, tr = _pivot(R, i, j, lag.turn)
        theta = np.einsum("ka,ka->k", nrm, w)
        f0r, ratio_r, c_r = _smoothed(np.abs(theta), eps_R)
        mlr = mu_R * lag.force
        tau = mlr * ratio_r * theta                         # dD_R / d theta
        g_a, g_b = _pivot_gradient(Psi, tr, nrm)
        np.add.at(grad[:, 3:], i, tau[:, None] * g_a)
        np.add.at(grad[:, 3:], j, tau[:, None] * g_b)
        energy += float(np.sum(mlr * f0r))
        couple = -tau[:, None] * g_a
        if hessian:
            _pivot_hessian(blk, Psi, w, nrm, g_a, g_b, tau, mlr * (ratio_r + c_r))
    H = _assemble(blk, lag, n_nodes, pattern) if hessian else None
    return FrictionWork(energy, grad, H, -phi, y, couple, theta)


def friction_live(x, R, lag, barrier, mu, eps_v, jacobian=True, pattern=None, mu_R=0.0,
                  eps_R=None):
    """The friction of ``lag``'s pairs and contact points with the normal
    force and normal *live*: each pair's ``lambda = -b'(g)`` and normal
    ``(x_i - x_j) / |x_i - x_j|`` at ``(x, R)``, not the lag's.  Coulomb's
    law then holds at the state itself (``|f_T| <= mu lambda``, normal to
    the actual normal), and the friction is no potential's gradient: the
    force ``phi = mu lambda f1(|u|) u / |u|`` on the contact points, ``u``
    the separation of the two points projected on the plane normal to the
    live normal.  Its Jacobian (``jacobian``) is exact and not symmetric:
    ``phi``'s change with the slip, with the normal and with the normal
    force, and the rotation acting on the arms.  Both of a pair's forces
    act at the midpoint of its two material points (``delta`` apart), so
    that the pair exerts no net couple: the moments balance exactly
    (:func:`friction_work`, a potential's gradient, leaves the couple
    ``delta x phi``, small: ``delta``'s normal part is within the
    barrier's width).  ``energy`` is nan; a pair
    at or inside the contact distance gives an infinite force.
    ``pattern``: as :func:`friction_work`'s.  With ``mu_R > 0`` the
    rotational law too: a pure couple ``-+ mu_R lambda f1(|theta|)
    sign(theta) n`` on the two sections about the live normal, ``theta``
    the pivot about it (:func:`_pivot`; balanced, and at most ``mu_R
    lambda``: Coulomb's law for couples at the state), its Jacobian
    exact."""
    n_nodes = x.shape[0]
    grad = np.zeros((n_nodes, 6))
    k = lag.pairs.shape[0]
    if k == 0 or (mu == 0 and mu_R == 0):
        H = sp.csc_matrix((6 * n_nodes, 6 * n_nodes)) if jacobian else None
        return FrictionWork(np.nan, grad, H, np.zeros((k, 3)), np.zeros(k))
    i, j, c_i, c_j, delta = _slip(x, R, lag)
    nrm, dist, lam, dlam = pair_forces(x, lag.pairs, barrier)
    if not np.all(np.isfinite(lam)):                      # a pair at or inside D
        return FrictionWork(np.nan, np.full((n_nodes, 6), np.inf), None,
                            np.zeros((k, 3)), np.zeros(k))
    dn = np.einsum("ka,ka->k", delta, nrm)
    u = delta - dn[:, None] * nrm
    y = np.linalg.norm(u, axis=1)
    _, ratio, c = _smoothed(y, eps_v)
    ml = mu * lam
    phi = (ml * ratio)[:, None] * u
    _scatter(grad, i, j, c_i, c_j, phi)
    # both forces at one point, the material points' midpoint (they are
    # delta apart): the pair then exerts no couple, and the moments
    # balance exactly (applied at the two points, the pair would leave
    # delta x phi); on each section the moment arm moves by -delta / 2
    couple = -0.5 * cross(delta, phi)
    np.add.at(grad[:, 3:], i, couple)
    np.add.at(grad[:, 3:], j, couple)
    if jacobian:
        J = _points_jacobian(c_i, c_j)
        P = np.eye(3) - nrm[:, :, None] * nrm[:, None, :]
        # du = P d(delta) - ((n . delta) I + n delta^T) dn,  dn = P (dx_i - dx_j) / dist
        A = (dn[:, None, None] * np.eye(3) + nrm[:, :, None] * delta[:, None, :]) @ P \
            / dist[:, None, None]
        Ju = P @ J
        Ju[:, :, 0:3] -= A
        Ju[:, :, 6:9] += A
        dphi = _law(u, y, ratio, c, ml) @ Ju                 # d phi / dy, (k, 3, 12)
        # the normal force's own change: lambda(g), g = |x_i - x_j| - D
        dg = dlam[:, None] * nrm                          # d lambda / d x_i
        dphi_dlam = (mu * ratio)[:, None] * u
        dphi[:, :, 0:3] += dphi_dlam[:, :, None] * dg[:, None, :]
        dphi[:, :, 6:9] -= dphi_dlam[:, :, None] * dg[:, None, :]
        blk = np.einsum("kai,kaj->kij", J, dphi)
        _arms_turn(blk, c_i, c_j, phi)
        # the couple's change: -(d delta x phi + delta x d phi) / 2
        dcouple = 0.5 * (hat(phi) @ J - hat(delta) @ dphi)
        blk[:, 3:6, :] += dcouple
        blk[:, 9:12, :] += dcouple
    torque = theta = None
    if mu_R > 0:
        # the pivot about the live normal; tau n on i, -tau n on j
        Psi, w, tr = _pivot(R, i, j, lag.turn)
        theta = np.einsum("ka,ka->k", nrm, w)
        _, ratio_r, c_r = _smoothed(np.abs(theta), eps_R)
        tau = mu_R * lam * ratio_r * theta
        np.add.at(grad[:, 3:], i, tau[:, None] * nrm)
        np.add.at(grad[:, 3:], j, -tau[:, None] * nrm)
        torque = -tau[:, None] * nrm
        if jacobian:
            g_a, g_b = _pivot_gradient(Psi, tr, nrm)
            k_t = mu_R * lam * (ratio_r + c_r)                 # d tau / d theta
            # d theta = g_a . a + g_b . b + w . dn,  dn = P (dx_i - dx_j) / dist;
            # d tau also through lambda(g)
            dtau = np.empty((k, 12))
            dtau[:, 0:3] = (k_t / dist)[:, None] * np.einsum("kab,kb->ka", P, w) \
                + (mu_R * ratio_r * theta * dlam)[:, None] * nrm
            dtau[:, 6:9] = -dtau[:, 0:3]
            dtau[:, 3:6] = k_t[:, None] * g_a
            dtau[:, 9:12] = k_t[:, None] * g_b
            rows = nrm[:, :, None] * dtau[:, None, :]          # d(tau n), (k, 3, 12)
            rows[:, :, 0:3] += (tau / dist)[:, None, None] * P
            rows[:, :, 6:9] -= (tau / dist)[:, None, None] * P
            blk[:, 3:6, :] += rows
            blk[:, 9:12, :] -= rows
    H = _assemble(blk, lag, n_nodes, pattern) if jacobian else None
    return FrictionWork(np.nan, grad, H, -phi, y, torque, theta)


class NodeContact(NamedTuple):
    """The node pairs in contact at a state (one row per pair inside the
    barrier's width, each pair once): what a solve records."""
    pairs: np.ndarray         # (k, 2) node indices i < j
    normal: np.ndarray        # (k, 3) unit (x_i - x_j) / |x_i - x_j|
    distance: np.ndarray      # (k,) |x_i - x_j|
    force: np.ndarray         # (k,) normal point force -b'(g) > 0 pressing i and j apart
    candidates: int           # node pairs within the barrier's reach
    friction: np.ndarray      # (k, 3) friction point force on node i's section (j gets -it)
    slip: np.ndarray          # (k, 3) the slip of i's contact point relative to j's (u)
    sliding: np.ndarray       # (k,) bool: |u| >= eps_v (the law's full Coulomb force)
    #: (k, 3) the rotational law's couple on node i's section (j gets -it),
    #: about the normal; (k,) the pivot of i relative to j about the normal
    #: (:func:`_pivot`); (k,) bool: |pivot| >= eps_R.  Zero without it.
    couple: np.ndarray = None
    pivot: np.ndarray = None
    pivoting: np.ndarray = None


def node_contact(x, R, s, barrier, lag=None, mu=0.0, eps_v=None, live=True, mu_R=0.0,
                 eps_R=None):
    """:class:`NodeContact` at ``(x, R)``: the barrier's pairs and forces
    and, with ``mu > 0`` and the :class:`FrictionLag` ``lag`` the state
    was solved with, each pair's friction force and slip
    (:func:`friction_live` where ``live``, else :func:`friction_work` at
    the lag's normal forces); pairs the lag does not have carry none.
    With ``mu_R > 0`` the rotational law's couples and pivots too."""
    bw = barrier
    pr = _pairs(x, s, bw.distance + bw.width, bw)
    pf = pair_forces(x, pr, bw)
    on = pf.force > 0
    k = int(on.sum())
    friction, slip = np.zeros((k, 3)), np.zeros((k, 3))
    sliding = np.zeros(k, dtype=bool)
    couple, pivot, pivoting = np.zeros((k, 3)), np.zeros(k), np.zeros(k, dtype=bool)
    pairs = pr[on]
    if lag is not None and (mu > 0 or mu_R > 0) and lag.pairs.shape[0] and k:
        fw = (friction_live(x, R, lag, bw, mu, eps_v, jacobian=False, mu_R=mu_R, eps_R=eps_R)
              if live else friction_work(x, R, lag, mu, eps_v, hessian=False, mu_R=mu_R,
                                         eps_R=eps_R))
        at = _pair_lookup(pairs, x.shape[0], lag.pairs)
        has, src = at >= 0, at[at >= 0]
        f = fw.force[src]
        size = np.linalg.norm(f, axis=1)
        # the force is -phi, phi along the slip u: u = -f |u| / |f|
        friction[has] = f
        slip[has] = -f * (fw.slip[src] / np.maximum(size, 1e-300))[:, None]
        sliding[has] = fw.slip[src] >= eps_v
        if mu_R > 0:
            couple[has], pivot[has] = fw.couple[src], fw.pivot[src]
            pivoting[has] = np.abs(fw.pivot[src]) >= eps_R
    return NodeContact(pairs, pf.normal[on], pf.distance[on], pf.force[on], int(pr.shape[0]),
                       friction, slip, sliding, couple, pivot, pivoting)
