r"""A smooth barrier between the centreline's nodes: the contact model of the
energy-minimizing experiment of issue 13 (``benchmarks/bench_plectoneme_barrier.py``,
docs/contact-solve.md "A smooth barrier between nodes").

Not the paper's model.  The paper (sec. 3-4) imposes ``d >= 2 eps`` at slave
Gauss points projected on the master curve, by an augmented Lagrangian.
Here every pair of centreline nodes ``i, j`` (the P3 nodes, which lie on
the curve, a third of an element apart) at least ``exclusion`` apart in
arclength carries the barrier energy of Li et al. (IPC, ACM TOG 39, 2020,
eq. 6) on its gap ``g = |x_i - x_j| - D``:

    b(g) = -kappa (g - g_hat)^2 ln(g / g_hat)   for 0 < g < g_hat,  0 beyond,

which is C2 at ``g_hat`` (``b = b' = b'' = 0`` there) and infinite at
``g = 0``: a configuration with a node pair closer than ``D`` has infinite
energy, and a line search that keeps the energy finite (with
:func:`step_bound` along each update) never lets a strand through another.
The total energy stays smooth, so Newton on it sees no active-set switch,
no projection jump and no multiplier update.

*Contact distance.*  The nodes sample the curve at spacing ``a``; between
two parallel strands at distance ``2 eps`` the nearest nodes are farther
apart by up to ``a^2 / (16 eps)`` (nodes half a spacing out of step).  The
node spheres touch at ``D = 2 eps + a^2 / (16 eps)`` (:meth:`Barrier.for_nodes`):
the centrelines then keep ``2 eps`` where the nodes are out of step and
stand off by that much where they are in step (1.1e-3 eps at 100 elements
of the plectoneme, 2.8e-4 eps at 200).

*Width and stiffness.*  ``g_hat`` (default 0.02 eps) bounds how far apart
touching strands stand; ``kappa`` is set so that a pair at ``g_hat / 2``
pushes with ``force`` (``|b'(g_hat/2)| = (ln 2 + 1/2) kappa g_hat``).

Everything is vectorized over pairs (``scipy.spatial.cKDTree.query_pairs``
for the pairs within reach).
"""
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

#: ``|b'(g_hat / 2)| / (kappa g_hat)``: the force of a pair at half the width
HALF_WIDTH_FORCE = np.log(2.0) + 0.5


@dataclass(frozen=True)
class Barrier:
    """The barrier's parameters (lengths in the rod's units)."""
    distance: float      # D: where the node spheres touch
    width: float         # g_hat: the barrier acts for 0 < g < g_hat
    stiffness: float     # kappa
    exclusion: float     # node pairs closer than this in arclength never touch

    def __post_init__(self):
        for name in ("distance", "width", "stiffness"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"Barrier {name} must be a finite number > 0, not {v!r}")
        if not (np.isfinite(self.exclusion) and self.exclusion >= 0):
            raise ValueError(f"Barrier exclusion must be a finite number >= 0, "
                             f"not {self.exclusion!r}")

    @classmethod
    def for_nodes(cls, s, radius, width=0.02, force=1.0, exclusion=None):
        """The barrier for nodes at arclengths ``s`` (any order) of a rod of
        contact radius ``radius``: ``D = 2 radius + a^2 / (16 radius)``
        with ``a`` the largest node spacing, ``g_hat = width radius``, the
        stiffness from ``force`` (module doc), ``exclusion`` default
        ``pi radius`` (:mod:`.search`)."""
        if not (np.isfinite(radius) and radius > 0):
            raise ValueError(f"radius must be a finite number > 0, not {radius!r}")
        if not (np.isfinite(width) and 0 < width):
            raise ValueError(f"width must be a finite number > 0 (times the radius), "
                             f"not {width!r}")
        if not (np.isfinite(force) and force > 0):
            raise ValueError(f"force must be a finite number > 0, not {force!r}")
        a = float(np.diff(np.sort(np.asarray(s, float))).max(initial=0.0))
        ghat = width * radius
        return cls(distance=2 * radius + a ** 2 / (16 * radius), width=ghat,
                   stiffness=force / (HALF_WIDTH_FORCE * ghat),
                   exclusion=np.pi * radius if exclusion is None else float(exclusion))


def potential(g, width, stiffness):
    """``b, b', b''`` of the barrier at gaps ``0 < g < width`` (arrays)."""
    g = np.asarray(g, float)
    lg = np.log(g / width)
    gm = g - width
    b = -stiffness * gm ** 2 * lg
    b1 = -stiffness * (2 * gm * lg + gm ** 2 / g)
    b2 = -stiffness * (2 * lg + 4 * gm / g - gm ** 2 / g ** 2)
    return b, b1, b2


def node_pairs(x, s, reach, exclusion):
    """Pairs ``(k, 2)`` of nodes (positions ``x``, arclengths ``s``) closer
    than ``reach`` in space and at least ``exclusion`` apart in arclength."""
    from scipy.spatial import cKDTree
    pr = cKDTree(x).query_pairs(reach, output_type="ndarray")
    if pr.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    return pr[np.abs(s[pr[:, 0]] - s[pr[:, 1]]) >= exclusion]


class BarrierWork(NamedTuple):
    """The barrier at one configuration."""
    energy: float             # inf where a pair is at or inside D
    gradient: np.ndarray      # (n, 3) dE/dx per node
    hessian: object           # sparse (n * dofs, n * dofs), or None
    active: int               # pairs with 0 < g < g_hat
    min_gap: float            # least gap g of the pairs in reach (inf: none)


def barrier_work(x, s, barrier, hessian=True, dofs=3, psd=False):
    """Energy, gradient and (``hessian``) Hessian of the barrier at node
    positions ``x`` (``(n, 3)``), arclengths ``s``.  The Hessian is laid
    out with ``dofs`` unknowns per node, the position first (6: a rod's
    positions and spins).  ``psd``: each pair's block keeps its
    normal part ``b'' n n^T`` only (positive semi-definite; the exact
    block adds ``b'/|d| (I - n n^T)``, negative)."""
    x = np.asarray(x, float)
    n = x.shape[0]
    bw = barrier
    pr = node_pairs(x, s, bw.distance + bw.width, bw.exclusion)
    grad = np.zeros((n, 3))
    empty = sp.csc_matrix((n * dofs, n * dofs)) if hessian else None
    if pr.shape[0] == 0:
        return BarrierWork(0.0, grad, empty, 0, np.inf)
    d = x[pr[:, 0]] - x[pr[:, 1]]
    dist = np.linalg.norm(d, axis=1)
    g = dist - bw.distance
    gmin = float(g.min())
    if gmin <= 0:
        return BarrierWork(np.inf, grad, empty, int(np.sum(g < bw.width)), gmin)
    act = g < bw.width
    pr, d, dist, g = pr[act], d[act], dist[act], g[act]
    b, b1, b2 = potential(g, bw.width, bw.stiffness)
    nv = d / dist[:, None]
    f = b1[:, None] * nv
    np.add.at(grad, pr[:, 0], f)
    np.add.at(grad, pr[:, 1], -f)
    H = None
    if hessian:
        nn = nv[:, :, None] * nv[:, None, :]
        blk = b2[:, None, None] * nn
        if not psd:
            blk = blk + (b1 / dist)[:, None, None] * (np.eye(3) - nn)
        I = pr[:, 0, None] * dofs + np.arange(3)
        J = pr[:, 1, None] * dofs + np.arange(3)
        v = blk.reshape(-1, 9)
        rows = [np.repeat(A, 3, axis=1).ravel() for A in (I, J, I, J)]
        cols = [np.tile(B, (1, 3)).ravel() for B in (I, J, J, I)]
        vals = [v.ravel(), v.ravel(), -v.ravel(), -v.ravel()]
        H = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(n * dofs, n * dofs)).tocsc()
    return BarrierWork(float(b.sum()), grad, H, int(act.sum()), gmin)


def step_bound(x, dx, s, barrier, fraction=0.8):
    """The largest ``alpha`` in ``(0, 1]`` such that moving the nodes along
    ``x + t dx`` for ``t <= alpha / fraction`` keeps every node pair (at
    least ``exclusion`` apart in arclength) farther apart than ``D``:
    ``fraction`` times the first root of ``|d + t e|^2 = D^2`` over the
    pairs that can reach it (continuous collision detection, exact for the
    straight paths of the positions)."""
    x, dx = np.asarray(x, float), np.asarray(dx, float)
    bw = barrier
    m = float(np.linalg.norm(dx, axis=1).max(initial=0.0))
    pr = node_pairs(x, s, bw.distance + bw.width + 2 * m, bw.exclusion)
    if pr.shape[0] == 0:
        return 1.0
    d0 = x[pr[:, 0]] - x[pr[:, 1]]
    e = dx[pr[:, 0]] - dx[pr[:, 1]]
    A = np.einsum("ij,ij->i", e, e)
    B = 2 * np.einsum("ij,ij->i", d0, e)
    C = np.einsum("ij,ij->i", d0, d0) - bw.distance ** 2
    disc = B ** 2 - 4 * A * C
    hit = (A > 0) & (disc >= 0) & (B < 0)
    t = np.full(A.shape, np.inf)
    # the smaller root, in the cancellation-free form 2C / (-B + sqrt(disc))
    t[hit] = 2 * C[hit] / (-B[hit] + np.sqrt(disc[hit]))
    t[t < 0] = np.inf
    return float(min(1.0, fraction * t.min(initial=np.inf)))
