r"""Nonlocal assembler of the frictional contact work: tangential and
rotational Coulomb self-friction (sec. 3.2, 4.2b-c, 6.1, 7.1), with the
slip kinematics measured on the material (corrections F4, F5 of
docs/friction.md).

The law itself (ball projection, stick/slip, exact derivatives) is in
:mod:`.friction`; the search and the normal part in :mod:`.search` and
:mod:`.assembly`.  This module turns a step's kinematics into slips and
assembles the residual and the consistent (non-symmetric) tangent.

Kinematics of one pair (slave point ``s`` of element ``v`` at ``xi_s``,
master point ``s_bar`` of element ``e`` at ``xi``; subscript ``n`` = the
last converged step, ``N_I`` the P3 shape functions)::

    u_s   = sum N_I(xi_s) (r_I - r_nI)          displacement of the slave point
    u_m   = sum N_J(xi)   (r_J - r_nJ)          ... of the master material point
    phi_I = log(R_I R_nI^T)                     nodal rotation increment (spatial)
    phi_s = sum N_I(xi_s) phi_I,  phi_m = sum N_J(xi) phi_J
    rho   = l / 2                               lever arm (= eps at zero gap)
    g_T   = (I - N N) [u_s - u_m - rho (phi_s + phi_m) x N]     (slip, F4)
    g_R   = phi_s - phi_m                                        (eq. 3.9, F5)

``g_T`` is the relative displacement, over the step, of the two material
points that meet at the contact point (``r(s) - rho N`` on the slave's
section, ``r(s_bar) + rho N`` on the master's: the midpoint of the
centreline segment, which is the surface point ``r -+ eps N`` of each tube
at zero gap), projected on the tangent plane: two tubes rolling on each
other do not slip, and an infinitesimal rigid motion is no slip even at a
penalty penetration (with the lever arm ``eps`` it would slip by ``d w``).  Both slips are Lagrangian (material points), so no
convective term ``s_bar-dot r'`` or ``s_bar-dot theta'`` appears.

Forces (:func:`.friction.friction_force`, ``f`` acts on the master, ``-f``
on the slave)::

    f_T = (1/mu_T) P_B(mu_T gamma_T f_N)[(I - N N)(a + mu_T lambda_T)],  g_T = (I - N N) a
    f_R = (1/mu_R) P_B(mu_R gamma_R f_N)[g_R + mu_R lambda_R]

(the multiplier is projected on the current tangent plane too, so that a
carried-over friction force never acquires a normal component).

Virtual work (residual = internal - external, weight ``w`` of the slave)::

    w f_T . [delta r(s) - delta r(s_bar) - rho (delta th_s + delta th_m) x N]
      + w f_R . (delta th_s - delta th_m),

with ``delta r(s_bar)`` the material variation (``xi`` held) and the
virtual spins at a point interpolated from the nodal spins (deviation D3).
The lever arm gives each section the couple ``-rho N x f_T``.

The tangent is the exact derivative of that residual: through ``f``
(``df/dg``, ``df/df_N`` of the law), through the normal ``N``, through the
master coordinate ``xi`` (``Delta xi`` of eq. 6.5, guarded as in
:mod:`.assembly`) and through the moving master shape functions.  Each pair
gives a dense 48 x 48 block over the positions and spins of its 8 nodes; all
pairs are evaluated at once and scattered in one COO -> CSC conversion.
"""
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..element import shape_functions
from ..rotations import hat, logm, tangent_inv
from . import friction as law
from .law import gap, normal_force


@dataclass
class FrictionOutput:
    """Per active pair (``f_N > 0``) friction figures of one evaluation."""
    index: np.ndarray        # (m,) index into the Pairs of the evaluation
    slave: np.ndarray        # (m,) global slave point index
    slip_T: np.ndarray       # (m, 3) tangential slip increment g_T
    slip_R: np.ndarray       # (m, 3) rotational slip increment g_R
    force_T: np.ndarray      # (m, 3) f_T (on the master)
    force_R: np.ndarray      # (m, 3) f_R (on the master)
    state_T: np.ndarray      # (m,) FrictionState
    state_R: np.ndarray      # (m,) FrictionState
    fN: np.ndarray           # (m,) normal force


def _pos(coef):
    """Operator ``(m, 3, 48)`` that takes ``sum_k coef_k delta r_k`` over the
    8 nodes of a pair (local dof ``6 k + c``)."""
    m = coef.shape[0]
    op = np.zeros((m, 3, 8, 6))
    for c in range(3):
        op[:, c, :, c] = coef
    return op.reshape(m, 3, 48)


def _spin(coef, mats=None):
    """Operator ``(m, 3, 48)``: ``sum_k coef_k M_k delta w_k`` (``M = I`` if
    ``mats`` is None; ``mats`` is ``(m, 8, 3, 3)``)."""
    m = coef.shape[0]
    op = np.zeros((m, 3, 8, 6))
    if mats is None:
        for c in range(3):
            op[:, c, :, 3 + c] = coef
    else:
        op[:, :, :, 3:] = np.einsum("mk,mkab->makb", coef, mats)
    return op.reshape(m, 3, 48)


def _vec(coef, v, spin=False):
    """Vector ``(m, 48)`` with ``coef_k v`` on the position (or spin) dofs
    of node ``k``."""
    m = coef.shape[0]
    out = np.zeros((m, 8, 6))
    off = 3 if spin else 0
    out[:, :, off:off + 3] = coef[:, :, None] * v[:, None, :]
    return out.reshape(m, 48)


#: pairs per chunk of the tangent blocks (18 KB each): a working set in cache
_CHUNK = 256


def _mm(A, B):
    """Batched ``A @ B``."""
    return np.matmul(A, B)


def scatter_node_blocks(nodes, blocks, n_nodes, b, layout="IaJc"):
    """Sum per-pair node blocks into a CSC matrix without a COO sort.

    ``nodes`` ``(m, k)`` global nodes of each pair, ``blocks``
    ``(m, k, b, k, b)`` (``layout="IaJc"``) or ``(m, k, k, b, b)``
    (``layout="IJac"``): block ``(I, J)`` couples the ``b`` dofs
    ``b * nodes[I] + (0..b-1)`` (rows) with those of ``nodes[J]``
    (columns); the global dof of node ``p``, component ``c`` is ``6 p + c``
    (``b = 6``: all dofs of a node).  Blocks with the same (row node,
    column node) are summed (``np.bincount``) and written straight into the
    CSC arrays, rows ascending in every column."""
    m, k = nodes.shape
    n = 6 * n_nodes
    if m == 0:
        return sp.csc_matrix((n, n))
    bkey = (nodes[:, None, :] * n_nodes + nodes[:, :, None]).ravel()   # (col node, row node)
    ukey, inv = np.unique(bkey, return_inverse=True)
    nb = ukey.size
    bcol, brow = ukey // n_nodes, ukey % n_nodes
    per_node = np.bincount(bcol, minlength=n_nodes)
    counts = np.zeros((n_nodes, 6), dtype=np.int64)
    counts[:, :b] = b * per_node[:, None]
    indptr = np.r_[0, np.cumsum(counts.ravel())]
    first = np.r_[0, np.cumsum(per_node)][:-1]
    within = b * (np.arange(nb) - first[bcol])
    ar = np.arange(b)
    pos = (indptr[6 * bcol[:, None, None] + ar[None, None, :]]
           + within[:, None, None] + ar[None, :, None])                     # (nb, row, col)
    nnz = int(indptr[-1])
    # the CSC position of every entry of every block, built in the layout of
    # ``blocks`` (no transpose of the data): column dof 6 J + c, row 6 I + a
    if layout == "IaJc":
        wb = within[inv.reshape(m, k, k)]                                   # (m, I, J)
        idx = (indptr[6 * nodes[:, None, None, :, None] + ar[None, None, None, None, :]]
               + wb[:, :, None, :, None] + ar[None, None, :, None, None])
        data = np.bincount(idx.ravel(), weights=blocks.ravel(), minlength=nnz)
    else:
        # whole blocks summed by their (row node, column node): one sparse
        # (unique block x block) product, then written at the blocks' places
        S = sp.csr_matrix((np.ones(m * k * k), (inv.ravel(), np.arange(m * k * k))),
                          shape=(nb, m * k * k))
        data = np.empty(nnz)
        data[pos.ravel()] = (S @ blocks.reshape(m * k * k, b * b)).ravel()
    indices = np.empty(nnz, dtype=np.int32 if nnz < 2**31 else np.int64)
    indices[pos.ravel()] = np.broadcast_to(6 * brow[:, None, None] + ar[None, :, None],
                                           pos.shape).ravel()
    return sp.csc_matrix((data, indices, indptr.astype(indices.dtype)), shape=(n, n))


def friction_work(mesh, r, R, r_n, R_n, pairs, lam_N, mu_N, radius, lam_T, lam_R,
                  gamma_T, gamma_R, mu_T, mu_R, tangent=True):
    """Residual ``(n_dofs,)``, tangent (CSC or None) and :class:`FrictionOutput`
    of the frictional contact work of ``pairs`` (from :func:`.search.search`
    at ``r``).

    ``r, R`` current nodal state; ``r_n, R_n`` the last converged one;
    ``lam_N`` ``(n_slaves,)``, ``lam_T``, ``lam_R`` ``(n_slaves, 3)``: the
    multipliers; ``mu_*`` the compliances, ``gamma_*`` the coefficients
    (``gamma_R`` a length).  Pairs with ``f_N = 0`` carry no friction.
    """
    n = mesh.n_dofs
    d = gap(pairs.distance, radius)
    fN_all, dfN_all = normal_force(d, lam_N[pairs.slave], mu_N)
    idx = np.flatnonzero(fN_all > 0)
    m = idx.size
    if m == 0:
        z = np.zeros((0, 3))
        out = FrictionOutput(idx, idx, z, z, z, z, np.zeros(0, int), np.zeros(0, int), np.zeros(0))
        return np.zeros(n), (sp.csc_matrix((n, n)) if tangent else None), out
    sl, ve, xs, me, xm = (pairs.slave[idx], pairs.s_elem[idx], pairs.s_xi[idx],
                          pairs.m_elem[idx], pairs.m_xi[idx])
    w, l, Nv = pairs.weight[idx], pairs.distance[idx], pairs.normal[idx]
    fN, dfN = fN_all[idx], dfN_all[idx]

    nodes = np.concatenate([mesh.nodes[ve], mesh.nodes[me]], axis=1)      # (m, 8)
    Ns = shape_functions(xs)[0].T                                        # (m, 4)
    Nm, dNm, d2Nm = (a.T for a in shape_functions(xm))
    zero = np.zeros_like(Ns)
    c_rel = np.concatenate([Ns, -Nm], axis=1)        # delta(x - y), xi held
    c_s = np.concatenate([Ns, zero], axis=1)
    c_m = np.concatenate([zero, Nm], axis=1)
    c_dm = np.concatenate([zero, dNm], axis=1)

    # nodal increments of the step
    du = r - r_n                                                         # (nn, 3)
    phi = logm(R @ np.swapaxes(R_n, 1, 2))                               # (nn, 3)
    rm, dum, phim_n = r[mesh.nodes[me]], du[mesh.nodes[me]], phi[mesh.nodes[me]]
    y1 = np.einsum("mk,mkc->mc", dNm, rm)
    y2 = np.einsum("mk,mkc->mc", d2Nm, rm)
    u_s = np.einsum("mk,mkc->mc", Ns, du[mesh.nodes[ve]])
    u_m = np.einsum("mk,mkc->mc", Nm, dum)
    u_m1 = np.einsum("mk,mkc->mc", dNm, dum)
    phi_s = np.einsum("mk,mkc->mc", Ns, phi[mesh.nodes[ve]])
    phi_m = np.einsum("mk,mkc->mc", Nm, phim_n)
    phi_m1 = np.einsum("mk,mkc->mc", dNm, phim_n)

    P = np.eye(3) - Nv[:, :, None] * Nv[:, None, :]
    phi_sum = phi_s + phi_m
    rho = 0.5 * l                      # lever arm: centreline -> contact point
    a_raw = u_s - u_m + rho[:, None] * np.cross(Nv, phi_sum)
    b = a_raw + mu_T * lam_T[sl]
    g_aug = np.einsum("mab,mb->ma", P, b)
    g_T = np.einsum("mab,mb->ma", P, a_raw)
    g_R = phi_s - phi_m

    resT = law.friction_force(g_aug, np.zeros_like(g_aug), mu_T, gamma_T, fN)
    resR = law.friction_force(g_R, lam_R[sl], mu_R, gamma_R, fN)
    fT, fR = resT.force, resR.force
    q = np.cross(Nv, fT)

    # residual: w [Vx^T f_T + Vw^T f_R - rho Vl^T (N x f_T)]
    loc = w[:, None] * (_vec(c_rel, fT) + _vec(np.concatenate([Ns, -Nm], 1), fR, spin=True)
                        - rho[:, None] * _vec(np.concatenate([Ns, Nm], 1), q, spin=True))
    dofs = (6 * nodes[:, :, None] + np.arange(6)).reshape(m, 48)
    force = np.bincount(dofs.ravel(), weights=loc.ravel(), minlength=n)
    out = FrictionOutput(idx, sl, g_T, g_R, fT, fR, resT.state, resR.state, fN)
    if not tangent:
        return force, None, out

    # linearized primitives, operators (m, 3, 48) / (m, 48)
    Xrel = _pos(c_rel)
    Y1m = _pos(c_dm)
    xy = Nv * l[:, None]
    den = np.sum(y1 * y1, axis=1) - np.sum(xy * y2, axis=1)
    use = pairs.interior[idx] & (den > 1e-8 * np.sum(y1 * y1, axis=1))
    Om = np.where(use, 1.0 / np.where(use, den, 1.0), 0.0)
    Xi = Om[:, None] * (np.einsum("mc,mcj->mj", y1, Xrel) + np.einsum("mc,mcj->mj", xy, Y1m))
    DN = _mm(P, Xrel - y1[:, :, None] * Xi[:, None, :]) / l[:, None, None]
    DfN = -dfN[:, None] * np.einsum("mc,mcj->mj", Nv, Xrel)
    Tinv = tangent_inv(phi)[nodes]                                       # (m, 8, 3, 3)
    Phis = _spin(c_s, Tinv)
    Phim = _spin(c_m, Tinv) + phi_m1[:, :, None] * Xi[:, None, :]
    Drho = 0.5 * np.einsum("mc,mcj->mj", Nv, Xrel)       # y' . N = 0
    Da = (_pos(c_s) - _pos(c_m) - u_m1[:, :, None] * Xi[:, None, :]
          + rho[:, None, None] * _mm(hat(Nv), Phis + Phim)
          - rho[:, None, None] * _mm(hat(phi_sum), DN)
          + np.cross(Nv, phi_sum)[:, :, None] * Drho[:, None, :])
    nb = np.sum(Nv * b, axis=1)
    Dg = (-nb[:, None, None] * DN - Nv[:, :, None] * np.einsum("mc,mcj->mj", b, DN)[:, None, :]
          + _mm(P, Da))
    DfT = (_mm(resT.dforce_dslip, Dg)
           + resT.dforce_dnormal[:, :, None] * DfN[:, None, :])
    DfR = (_mm(resR.dforce_dslip, Phis - Phim)
           + resR.dforce_dnormal[:, :, None] * DfN[:, None, :])
    Dq = -_mm(hat(fT), DN) + _mm(hat(Nv), DfT)

    # K_e = w [Vx^T DfT + Vw^T DfR - rho Vl^T Dq - (Vl^T q) Drho^T + moving Xi^T]
    # row (node k, dof a): the virtual operators are shape-function multiples
    # of the identity, so each term is a broadcast product (no matmul)
    c_w = np.concatenate([Ns, -Nm], axis=1)
    c_l = np.concatenate([Ns, Nm], axis=1)
    c_dm_neg = np.concatenate([zero, -dNm], axis=1)
    wc = w[:, None]
    A_T, A_R, A_q, A_l = wc * c_rel, wc * c_w, wc * rho[:, None] * c_l, wc * c_l
    # the master shape functions move with xi
    M_pos = (wc * c_dm_neg)[:, :, None] * fT[:, None, :]
    M_spin = ((wc * c_dm_neg)[:, :, None] * fR[:, None, :]
              - (wc * rho[:, None] * c_dm)[:, :, None] * q[:, None, :])
    # the slaves of one element on one master element share their 8 nodes:
    # their blocks are summed before the scatter (about 3x fewer blocks);
    # pairs sorted by (slave element, master element), blocks built chunk
    # by chunk (a working set that stays in cache), summed slot by slot
    key = ve * mesh.nodes.shape[0] + me
    order = np.argsort(key, kind="stable")
    new = np.r_[True, key[order][1:] != key[order][:-1]]
    start = np.flatnonzero(new)
    group = np.cumsum(new) - 1
    slot = np.arange(m) - start[group]
    Kg = np.zeros((start.size, 8, 8, 6, 6))             # (group, I, J, a, c)
    for a in range(0, m, _CHUNK):
        ix = order[a:a + _CHUNK]
        Ke = np.empty((ix.size, 8, 6, 48))
        Ke[:, :, :3] = (A_T[ix][:, :, None, None] * DfT[ix][:, None]
                        + M_pos[ix][..., None] * Xi[ix][:, None, None, :])
        Ke[:, :, 3:] = (A_R[ix][:, :, None, None] * DfR[ix][:, None]
                        - A_q[ix][:, :, None, None] * Dq[ix][:, None]
                        - A_l[ix][:, :, None, None] * q[ix][:, None, :, None]
                        * Drho[ix][:, None, None, :]
                        + M_spin[ix][..., None] * Xi[ix][:, None, None, :])
        Ke = np.ascontiguousarray(Ke.reshape(ix.size, 8, 6, 8, 6).transpose(0, 1, 3, 2, 4))
        g, sl = group[a:a + _CHUNK], slot[a:a + _CHUNK]
        for j in range(int(sl.max()) + 1):
            sel = sl == j
            Kg[g[sel]] += Ke[sel]
    K = scatter_node_blocks(nodes[order[start]], Kg, mesh.n_nodes, 6, layout="IJac")
    return force, K, out
