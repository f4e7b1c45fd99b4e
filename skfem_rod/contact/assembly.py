r"""Nonlocal assembler: the contact virtual work of all slave/master pairs,
added into the global sparse system (eq. 4.1 third integral, sec. 6, 7.1).

For a slave point ``x = r(s)`` (slave element ``v``) and its master point
``y = r(s_bar)`` (master element ``e``, parameter ``xi``), with
``l = |x - y|``, ``N = (x - y)/l`` and the gap ``d = 2 eps - l``:

    delta l   = N . (delta x - delta y)                        (y' . N = 0)
    Delta xi  = Omega [(Delta x - Delta y) . y' + (x - y) . Delta y']   (eq. 6.5)
    Delta delta l = (delta x - delta y) . (I - N N) (Delta x - Delta y) / l
                    - Omega l a(delta) a(Delta),                (eq. 6.4c)
    a(delta)  = (delta x - delta y) . y' / l + N . delta y',
    Omega     = 1 / (|y'|^2 - (x - y) . y'')    (derivatives in xi).

The pair's work is ``w phi(d)`` (``w`` the slave's quadrature weight,
``phi`` the augmented-Lagrangian potential of :mod:`.law`), so

    residual = -w f_N delta l = w f_N N . (delta y - delta x)      (eq. 4.1)
    tangent  =  w [phi'' delta l (x) Delta l - f_N Delta delta l],

a symmetric 24 x 24 block over the position dofs of the two elements (the
paper's Sigma_1^T Gamma_N Sigma_1 of sec. 7.1).  ``Omega`` is guarded: where
the projection sits on an element end, or ``|y'|^2 - (x - y) . y''`` is not
safely positive (non-unique projection), the ``Delta xi`` term is dropped.
All pairs are evaluated at once; the blocks of the pairs of one element
pair are summed by one batched product and the node blocks written straight
into CSC arrays (:func:`_tangent`; the pattern is kept in a :class:`PatternCache`, one per
tangent and problem (:class:`ContactPatterns`), while the element pairs in
contact do not change).
"""
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from ..element import shape_functions
from .law import gap, normal_force, potential


class PatternCache:
    """The CSC pattern of a contact tangent built for the element pairs last
    in contact, kept while they do not change (they seldom change between
    Newton iterations).  ``merged``: what an assembler derived from the
    pattern (the friction assembler: where the normal tangent's entries
    sit in it), dropped with it.  Owned by the object that assembles (one
    per tangent and :class:`skfem_rod.problem.Problem`, in
    :class:`ContactPatterns`); a fresh one caches nothing across calls."""

    def __init__(self):
        self.clear()

    def clear(self):
        """Forget the pattern (the next assembly builds it again)."""
        self.nodes = self.ge = self.pattern = self.merged = None

    def lookup(self, mesh, ge):
        """The kept pattern if it was built for the same mesh and element
        pairs ``ge``, else None."""
        if (self.nodes is mesh.nodes and self.ge.shape == ge.shape
                and np.array_equal(self.ge, ge)):
            return self.pattern
        return None

    def store(self, mesh, ge, pattern):
        """Keep ``pattern``, built for ``mesh`` and element pairs ``ge``
        (what was derived from the last one goes); returns it."""
        self.clear()
        self.nodes, self.ge, self.pattern = mesh.nodes, ge.copy(), pattern
        return pattern


@dataclass
class ContactPatterns:
    """The sparse-pattern caches of one problem's contact tangents: the
    normal contact tangent's (:func:`contact_work`) and the friction
    tangent's (:func:`.friction_assembly.friction_work`)."""
    normal: PatternCache = field(default_factory=PatternCache)
    friction: PatternCache = field(default_factory=PatternCache)

    def clear(self):
        """Forget both patterns."""
        self.normal.clear()
        self.friction.clear()


@dataclass(frozen=True)
class _TangentTerms:
    """The active pairs' terms of the contact tangent (:func:`_tangent`):
    slave and master elements ``(m,)``, the operators ``P``, ``Q`` ``(m, 8)``
    of ``delta(x - y)`` and ``delta y'``, the normal ``N`` and ``u = y' / l``
    ``(m, 3)``, and the weights ``c_nn``, ``c_proj``, ``c_om`` ``(m,)``."""
    s_elem: np.ndarray
    m_elem: np.ndarray
    P: np.ndarray
    Q: np.ndarray
    N: np.ndarray
    u: np.ndarray
    c_nn: np.ndarray
    c_proj: np.ndarray
    c_om: np.ndarray

    def matrices(self):
        """``G`` ``(m, 4, 3, 3)``: ``G1, G2, G2^T, G3`` of :func:`_tangent`."""
        N, u, c_nn, c_proj, c_om = self.N, self.u, self.c_nn, self.c_proj, self.c_om
        NN = N[:, :, None] * N[:, None, :]
        G = np.empty((N.shape[0], 4, 3, 3))
        G[:, 0] = ((c_nn + c_proj)[:, None, None] * NN
                   + c_om[:, None, None] * (u[:, :, None] * u[:, None, :]))
        G[:, 0, [0, 1, 2], [0, 1, 2]] -= c_proj[:, None]
        G[:, 1] = c_om[:, None, None] * (u[:, :, None] * N[:, None, :])
        G[:, 2] = np.swapaxes(G[:, 1], 1, 2)
        G[:, 3] = c_om[:, None, None] * NN
        return G


def contact_work(mesh, r, pairs, lam, mu, radius, tangent=True, cache=None, stiffen=1.0):
    """Energy, force vector ``(n_dofs,)`` and tangent (CSC or None) of the
    contact pairs, and the per-pair normal forces ``f_N``.  ``cache``: the
    :class:`PatternCache` of the tangent's pattern (default: none kept);
    ``stiffen``: the active pairs' ``df_N / d gap`` times this in the tangent
    (the constrained stability test), the forces unchanged."""
    n = mesh.n_dofs
    m = pairs.size
    if m == 0:
        return 0.0, np.zeros(n), (sp.csc_matrix((n, n)) if tangent else None), np.zeros(0)
    w = pairs.weight
    d = gap(pairs.distance, radius)
    fN, dfN = normal_force(d, lam[pairs.slave], mu)
    energy = float(np.sum(w * potential(d, lam[pairs.slave], mu)))
    act = fN > 0
    Ns, _, _ = shape_functions(pairs.s_xi)                  # (4, m)
    Nm, dNm, d2Nm = shape_functions(pairs.m_xi)
    # operators on the 24 position dofs (8 nodes x 3): x - y and y'
    P = np.concatenate([Ns.T, -Nm.T], axis=1)               # (m, 8): delta(x - y)
    Q = np.concatenate([np.zeros((m, 4)), dNm.T], axis=1)   # (m, 8): delta y'
    Nv = pairs.normal
    b = P[:, :, None] * Nv[:, None, :]                      # delta l  (m, 8, 3)
    fe = -(w * fN)[:, None, None] * b
    nodes = np.concatenate([mesh.nodes[pairs.s_elem], mesh.nodes[pairs.m_elem]], axis=1)
    dofs = (6 * nodes[:, :, None] + np.arange(3)).reshape(m, 24)
    force = np.bincount(dofs.ravel(), weights=fe.reshape(m, 24).ravel(), minlength=n)
    K = None
    if tangent:
        keep = np.flatnonzero(act)                          # stiffness of active pairs
        P, Q, Nv, w, fa, dfa = P[keep], Q[keep], Nv[keep], w[keep], fN[keep], dfN[keep]
        dNm, d2Nm = dNm[:, keep], d2Nm[:, keep]
        r_m = r[mesh.nodes[pairs.m_elem[keep]]]             # (m, 4, 3)
        y1 = (dNm.T[:, None, :] @ r_m)[:, 0]
        y2 = (d2Nm.T[:, None, :] @ r_m)[:, 0]
        l = pairs.distance[keep]
        xy = Nv * l[:, None]
        den = np.sum(y1 * y1, axis=1) - np.sum(xy * y2, axis=1)
        use = pairs.interior[keep] & (den > 1e-8 * np.sum(y1 * y1, axis=1))
        Om = np.where(use, 1.0 / np.where(use, den, 1.0), 0.0)
        terms = _TangentTerms(pairs.s_elem[keep], pairs.m_elem[keep], P, Q, Nv,
                              y1 / l[:, None], stiffen * w * dfa, w * fa / l, w * fa * Om * l)
        K = _tangent(mesh, terms, PatternCache() if cache is None else cache)
    return energy, force, K, fN


def _tangent(mesh, terms, cache):
    r"""The pairs' 24 x 24 blocks, summed into a CSC matrix.

    With ``a(delta) = P (x) u + Q (x) N`` (``u = y' / l``), the block is
    ``w [f' b b^T - f ddl]`` = ``PP^T (x) G1 + PQ^T (x) G2 + QP^T (x) G2^T
    + QQ^T (x) G3`` with the 3 x 3 matrices
    ``G1 = c_nn NN^T - c_proj (I - NN^T) + c_om uu^T``, ``G2 = c_om u N^T``,
    ``G3 = c_om NN^T``.  The pairs of one element pair {v, e} (at most
    ``2 n_slave``: the slaves of v on e and those of e on v) share their 8
    nodes, so their blocks are summed by one batched product per element
    pair, (64 node pairs x 4 k) @ (4 k x 9).  The node blocks are then merged
    by global (column node, row node) and written straight into CSC arrays
    (no COO sort of ``m * 576`` entries; pattern kept in ``cache``)."""
    n = mesh.n_dofs
    s_elem, m_elem, P, Q = terms.s_elem, terms.m_elem, terms.P, terms.Q
    m = P.shape[0]
    if m == 0:
        return sp.csc_matrix((n, n))
    G = terms.matrices()
    # element pair {v, e}, v <= e, nodes ordered (v, e): swap the halves of
    # the operators of pairs whose slave element is the larger
    swap = s_elem > m_elem
    lo, hi = np.minimum(s_elem, m_elem), np.maximum(s_elem, m_elem)
    ne = mesh.nodes.shape[0]
    key = lo * ne + hi
    order = np.argsort(key, kind="stable")
    ks = key[order]
    new = np.r_[True, ks[1:] != ks[:-1]]
    start = np.flatnonzero(new)
    group = np.cumsum(new) - 1                              # group of sorted pair
    slot = np.arange(m) - start[group]
    ng, K = start.size, int(slot.max()) + 1
    # operators X = (P, Q) padded per group (ng, K, 2, 8), G as (ng, K, 2, 2, 9)
    X = np.zeros((ng, K, 2, 8))
    so = swap[order][:, None]
    X[group, slot, 0] = np.where(so, np.roll(P[order], 4, axis=1), P[order])
    X[group, slot, 1] = np.where(so, np.roll(Q[order], 4, axis=1), Q[order])
    Gp = np.zeros((ng, K, 2, 2, 9))
    Gp[group, slot] = G[order].reshape(m, 2, 2, 9)
    # block (I, J) = sum_{k, alpha, beta} X_{k alpha I} X_{k beta J} G_{k alpha beta}
    Y = np.einsum("gkabx,gkbj->gkaxj", Gp, X).reshape(ng, 2 * K, 72)
    blocks = X.reshape(ng, 2 * K, 8).transpose(0, 2, 1) @ Y        # (ng, I, 9, J)
    ge = ks[start]
    nnz, posraw, indices, indptr = _pattern(mesh, ge, ne, cache)
    data = np.bincount(posraw, weights=blocks.ravel(), minlength=nnz)
    return sp.csc_matrix((data, indices, indptr), shape=(n, n))


def _pattern(mesh, ge, ne, cache):
    """CSC structure of the contact stiffness of element pairs ``ge``
    (``lo * ne + hi``) and the data position of every (pair, 3 x 3
    component, node block) value.  The last pattern is kept in ``cache``
    (the element pairs in contact seldom change between Newton
    iterations)."""
    hit = cache.lookup(mesh, ge)
    if hit is not None:
        return hit
    n, nn = mesh.n_dofs, mesh.n_nodes
    ng = ge.size
    nodes = np.concatenate([mesh.nodes[ge // ne], mesh.nodes[ge % ne]], axis=1)   # (ng, 8)
    # global node-block keys, column-major: (column node, row node)
    bkey = (nodes[:, None, :] * nn + nodes[:, :, None]).ravel()         # (ng * 64,)
    ukey, inv = np.unique(bkey, return_inverse=True)
    bcol, brow = ukey // nn, ukey % nn
    # CSC: column 6 J + c holds rows 6 I + a of its blocks (I ascending)
    per_node = np.bincount(bcol, minlength=nn)
    counts = np.zeros((nn, 6), dtype=np.int64)
    counts[:, :3] = 3 * per_node[:, None]
    indptr = np.r_[0, np.cumsum(counts.ravel())]
    first_block = np.r_[0, np.cumsum(per_node)][:-1]
    base = indptr[6 * bcol] + 3 * (np.arange(ukey.size) - first_block[bcol])
    stride = 3 * per_node[bcol]
    nnz = int(indptr[-1])
    itype = np.int32 if nnz < 2**31 and n < 2**31 else np.int64
    a, cc = np.divmod(np.arange(9), 3)                       # component a * 3 + c
    b_i = inv.reshape(ng, 8, 1, 8)                          # value layout (g, I, a c, J)
    posraw = (base[b_i] + a[:, None] + cc[:, None] * stride[b_i]).ravel()
    indices = np.empty(nnz, dtype=itype)
    indices[posraw] = np.broadcast_to(6 * brow[b_i] + a[:, None], (ng, 8, 9, 8)).ravel()
    return cache.store(mesh, ge, (nnz, posraw, indices, indptr.astype(itype)))
