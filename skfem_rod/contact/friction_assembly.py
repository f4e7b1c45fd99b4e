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
:mod:`.assembly`) and through the moving master shape functions.

Assembly.  Each pair gives a dense 48 x 48 block over the positions and
spins of its 8 nodes, but of low rank in the nodes: its rows and columns
are shape-function weights (``N_s`` on the slave's nodes, ``N_m`` and
``N'_m`` on the master's: three "modes") times 6 dofs, and the spin
columns of node ``k`` carry ``T^-1(phi_k)``.  So the block is
``U C U^T`` with ``U`` (8 nodes x 3 modes) and a core ``C`` of 18 x 18
numbers per pair; every linearized quantity is computed on the reduced
columns (3 x 18 per pair instead of 3 x 48).  The pairs of one element pair
share their 8 nodes: the columns are expanded pair by pair (with
``T^-1``), the rows by one matrix product per element pair, batched over
the element pairs with the same number of pairs; the element-pair blocks
are summed into the CSC arrays by one ``bincount`` over a cached pattern
(kept while the element pairs in contact do not change, as in
:mod:`.assembly`), into which the normal contact tangent can be added
(``K_normal``) instead of a sparse sum.
"""
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..element import shape_functions
from ..rotations import hat, logm, tangent_inv
from . import friction as law
from .law import gap, normal_force
from .assembly import cached_pattern


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


# Reduced operators.  Every linearized quantity of a pair (a row of its
# tangent) is a combination of the nodal variations of its 8 nodes with
# shape-function weights of three kinds ("modes"): N_s on the slave's
# nodes, N_m and N'_m (the moving master point) on the master's.  It is
# kept as a (3, 18) matrix: column ``3 c + beta`` for the dof ``c`` (0-2
# position, 3-5 spin) and the mode ``beta`` (0: N_s, 1: N_m, 2: N'_m).  The
# spins enter through ``T^-1(phi_k) delta w_k``, node by node: that factor
# is applied when the columns are expanded to the nodes.
_S, _M, _D = 0, 1, 2


def _mode(*parts):
    op = np.zeros((3, 18))
    for beta, dof, sign in parts:
        op[np.arange(3), 3 * (dof + np.arange(3)) + beta] = sign
    return op


_XREL = _mode((_S, 0, 1.0), (_M, 0, -1.0))    # delta(x - y), xi held
_PHIS = _mode((_S, 3, 1.0))                   # spin variation at the slave point
_PHIM = _mode((_M, 3, 1.0))                   # ... at the master point, xi held


def _mm(A, B):
    """Batched ``A @ B``."""
    return np.matmul(A, B)


_PATTERN_CACHE = {}


def _pattern(mesh, ge, gnodes):
    """CSC structure (``nnz, pos, indices, indptr``) of the friction tangent
    of the element pairs ``ge`` (keys ``lo * n_elements + hi``, in the order
    of the blocks) with nodes ``gnodes`` ``(ng, 8)``; ``pos``: the data
    position of every entry ``(part, g, J, c, a, I)`` of the element-pair
    blocks (row dof ``6 I + a``, column ``6 J + 3 part + c``).  The last
    pattern is cached: the element pairs in contact seldom change between
    Newton iterations."""
    c = _PATTERN_CACHE
    hit = cached_pattern(c, mesh, ge)
    if hit is not None:
        return hit
    nn, n = mesh.n_nodes, mesh.n_dofs
    ng = ge.size
    bkey = (gnodes[:, :, None] * nn + gnodes[:, None, :]).ravel()   # (g, J, I): col, row node
    ukey, inv = np.unique(bkey, return_inverse=True)
    bcol, brow = np.divmod(ukey, nn)
    # CSC: the 6 columns of node J hold the rows 6 I + a of its blocks,
    # I ascending; every column of a node has the same rows
    per_node = np.bincount(bcol, minlength=nn)
    indptr = np.r_[0, np.cumsum(np.repeat(6 * per_node, 6))]
    first = np.r_[0, np.cumsum(per_node)][:-1]
    within = 6 * (np.arange(ukey.size) - first[bcol])
    nnz = int(indptr[-1])
    itype = np.int32 if nnz < 2**31 and n < 2**31 else np.int64
    col = indptr[:-1][6 * gnodes[:, :, None] + np.arange(6)]             # (g, J, part c)
    col = col.reshape(ng, 8, 2, 3).transpose(2, 0, 1, 3)[..., None, None]
    pos = ((col + np.arange(6)[:, None])
           + within[inv].reshape(ng, 8, 8)[:, :, None, None, :]).ravel()
    # column 6 J + c: rows 6 brow + a of the blocks first[J]... of node J
    rows = (6 * brow[:, None] + np.arange(6)).ravel()
    shift = 6 * first[np.arange(6 * nn) // 6] - indptr[:-1]
    indices = rows[np.arange(nnz) + np.repeat(shift, np.diff(indptr))].astype(itype)
    out = (nnz, pos, indices, indptr.astype(itype))
    c.clear()
    c.update(nodes=mesh.nodes, ge=ge.copy(), out=out)
    return out


def _normal_positions(K_normal, indices, indptr, n):
    """Data positions, in the friction tangent (``indices``, ``indptr``),
    of the entries of the CSC matrix ``K_normal`` (the normal contact
    tangent of the same pairs, whose node blocks are among the friction's),
    or None if its pattern is not inside (or not canonical).  Cached with
    the pattern."""
    c = _PATTERN_CACHE.get("normal")
    if (c is not None and c[0].shape == K_normal.indptr.shape
            and c[1].shape == K_normal.indices.shape
            and np.array_equal(c[0], K_normal.indptr) and np.array_equal(c[1], K_normal.indices)):
        return c[2]
    key_f = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr)) * n + indices
    key_n = np.repeat(np.arange(n, dtype=np.int64), np.diff(K_normal.indptr)) * n + K_normal.indices
    where = np.minimum(np.searchsorted(key_f, key_n), key_f.size - 1)
    if not (np.all(np.diff(key_n) > 0) and np.array_equal(key_f[where], key_n)):
        where = None
    _PATTERN_CACHE["normal"] = (K_normal.indptr.copy(), K_normal.indices.copy(), where)
    return where


def friction_work(mesh, r, R, r_n, R_n, pairs, lam_N, mu_N, radius, lam_T, lam_R,
                  gamma_T, gamma_R, mu_T, mu_R, tangent=True, K_normal=None):
    """Residual ``(n_dofs,)``, tangent (CSC or None) and :class:`FrictionOutput`
    of the frictional contact work of ``pairs`` (from :func:`.search.search`
    at ``r``).

    ``r, R`` current nodal state; ``r_n, R_n`` the last converged one;
    ``lam_N`` ``(n_slaves,)``, ``lam_T``, ``lam_R`` ``(n_slaves, 3)``: the
    multipliers; ``mu_*`` the compliances, ``gamma_*`` the coefficients
    (``gamma_R`` a length).  Pairs with ``f_N = 0`` carry no friction.
    ``K_normal`` (optional, CSC): a matrix added to the returned tangent,
    the normal contact tangent of the same pairs (from
    :func:`.assembly.contact_work`): its entries are added into the
    friction tangent's arrays, which hold its pattern, instead of a sparse
    sum.
    """
    n = mesh.n_dofs
    if K_normal is not None and K_normal.shape != (n, n):
        raise ValueError(f"K_normal must be an ({n}, {n}) matrix, got shape {K_normal.shape}")
    d = gap(pairs.distance, radius)
    fN_all, dfN_all = normal_force(d, lam_N[pairs.slave], mu_N)
    idx = np.flatnonzero(fN_all > 0)
    m = idx.size
    if m == 0:
        z = np.zeros((0, 3))
        out = FrictionOutput(idx, idx, z, z, z, z, np.zeros(0, int), np.zeros(0, int), np.zeros(0))
        if not tangent:
            return np.zeros(n), None, out
        return np.zeros(n), (sp.csc_matrix((n, n)) if K_normal is None else K_normal), out
    sl, ve, xs, me, xm = (pairs.slave[idx], pairs.s_elem[idx], pairs.s_xi[idx],
                          pairs.m_elem[idx], pairs.m_xi[idx])
    w, l, Nv = pairs.weight[idx], pairs.distance[idx], pairs.normal[idx]
    fN, dfN = fN_all[idx], dfN_all[idx]

    nodes = np.concatenate([mesh.nodes[ve], mesh.nodes[me]], axis=1)      # (m, 8)
    Ns = shape_functions(xs)[0].T                                        # (m, 4)
    Nm, dNm, d2Nm = (a.T for a in shape_functions(xm))

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
    Nxphi = np.cross(Nv, phi_sum)
    a_raw = u_s - u_m + rho[:, None] * Nxphi
    b = a_raw + mu_T * lam_T[sl]
    g_aug = np.einsum("mab,mb->ma", P, b)
    g_T = np.einsum("mab,mb->ma", P, a_raw)
    g_R = phi_s - phi_m

    resT = law.friction_force(g_aug, np.zeros_like(g_aug), mu_T, gamma_T, fN)
    resR = law.friction_force(g_R, lam_R[sl], mu_R, gamma_R, fN)
    fT, fR = resT.force, resR.force
    q = np.cross(Nv, fT)

    # residual: w [Vx^T f_T + Vw^T f_R - rho Vl^T (N x f_T)]: on the slave
    # nodes N_s (f_T; f_R - rho q), on the master nodes -N_m (f_T; f_R + rho q)
    wv = w[:, None]
    loc = np.empty((m, 8, 6))
    loc[:, :4, :3] = Ns[:, :, None] * (wv * fT)[:, None, :]
    loc[:, 4:, :3] = Nm[:, :, None] * (-wv * fT)[:, None, :]
    loc[:, :4, 3:] = Ns[:, :, None] * (wv * (fR - rho[:, None] * q))[:, None, :]
    loc[:, 4:, 3:] = Nm[:, :, None] * (-wv * (fR + rho[:, None] * q))[:, None, :]
    dofs = 6 * nodes[:, :, None] + np.arange(6)
    force = np.bincount(dofs.ravel(), weights=loc.ravel(), minlength=n)
    out = FrictionOutput(idx, sl, g_T, g_R, fT, fR, resT.state, resR.state, fN)
    if not tangent:
        return force, None, out

    # linearized primitives on the reduced columns: (m, 3, 18) / (m, 18)
    xy = Nv * l[:, None]
    den = np.sum(y1 * y1, axis=1) - np.sum(xy * y2, axis=1)
    use = pairs.interior[idx] & (den > 1e-8 * np.sum(y1 * y1, axis=1))
    Om = np.where(use, 1.0 / np.where(use, den, 1.0), 0.0)
    Xi = np.zeros((m, 6, 3))                        # Delta xi (eq. 6.5)
    Xi[:, :3, _S] = Om[:, None] * y1
    Xi[:, :3, _M] = -Xi[:, :3, _S]
    Xi[:, :3, _D] = Om[:, None] * xy
    Xi = Xi.reshape(m, 18)
    DN = _mm(P, _XREL - y1[:, :, None] * Xi[:, None, :]) / l[:, None, None]
    NX = Nv @ _XREL                                 # N . delta(x - y)
    DfN = -dfN[:, None] * NX
    Phim = _PHIM + phi_m1[:, :, None] * Xi[:, None, :]
    Drho = 0.5 * NX                                 # y' . N = 0
    Nh = hat(Nv)
    Da = (_XREL - u_m1[:, :, None] * Xi[:, None, :]
          + rho[:, None, None] * _mm(Nh, _PHIS + Phim)
          - rho[:, None, None] * _mm(hat(phi_sum), DN)
          + Nxphi[:, :, None] * Drho[:, None, :])
    nb = np.sum(Nv * b, axis=1)
    Dg = (-nb[:, None, None] * DN - Nv[:, :, None] * np.einsum("mc,mcj->mj", b, DN)[:, None, :]
          + _mm(P, Da))
    DfT = (_mm(resT.dforce_dslip, Dg)
           + resT.dforce_dnormal[:, :, None] * DfN[:, None, :])
    Dq = _mm(Nh, DfT) - _mm(hat(fT), DN)

    # K_e = w [Vx^T DfT + Vw^T DfR - rho Vl^T Dq - (Vl^T q) Drho^T + moving Xi^T]:
    # rows by mode too (N_s, N_m, N'_m: the master shape functions move with
    # xi); C (m, row mode alpha, row dof a, reduced column (c, beta))
    wc = w[:, None, None]
    E1 = wc * DfT
    E2 = -wc * (rho[:, None, None] * Dq + q[:, :, None] * Drho[:, None, :])
    C = np.empty((m, 3, 6, 18))
    C[:, 0, :3] = E1
    C[:, 1, :3] = -E1
    C[:, 0, 3:] = E2
    C[:, 1, 3:] = E2
    if gamma_R > 0:                                 # rotational friction
        E3 = wc * (_mm(resR.dforce_dslip, _PHIS - Phim)
                   + resR.dforce_dnormal[:, :, None] * DfN[:, None, :])
        C[:, 0, 3:] += E3
        C[:, 1, 3:] -= E3
    C[:, 2, :3] = -(wv * fT)[:, :, None] * Xi[:, None, :]
    C[:, 2, 3:] = -(wv * (fR + rho[:, None] * q))[:, :, None] * Xi[:, None, :]

    # the pairs of one element pair {v, e} share their 8 nodes, ordered
    # (lower element, higher element); U (m, 8, 3): the weight of each mode
    # at each of these nodes.  The block of a pair is
    # K[(I a), (J c)] = sum U[I, alpha] C[alpha, a, c, beta] U[J, beta]
    # (spin columns: times T^-1 of node J): columns expanded pair by pair
    # (Y, 864 numbers a pair), rows summed over the pairs of an element pair
    # by one product per element pair, element pairs with the same number of
    # pairs batched together
    ne = mesh.nodes.shape[0]
    hs = (ve > me).astype(np.intp)                  # half of the slave's nodes
    U = np.zeros((m, 2, 4, 3))
    ar = np.arange(m)
    U[ar, hs, :, _S] = Ns
    U[ar, 1 - hs, :, _M] = Nm
    U[ar, 1 - hs, :, _D] = dNm
    U = U.reshape(m, 8, 3)
    key = np.minimum(ve, me) * ne + np.maximum(ve, me)
    _, inv, count = np.unique(key, return_inverse=True, return_counts=True)
    order = np.lexsort((key, count[inv]))          # by pair count, then element pair
    U = U[order]
    C = C[order].reshape(m, 3, 6, 6, 3).transpose(0, 1, 4, 3, 2)     # (p, alpha, beta, c, a)
    Yp = _mm(U[:, None], C[:, :, :, :3].reshape(m, 3, 3, 18))       # (p, alpha, J, (c, a))
    Tn = tangent_inv(phi)[np.where(hs[order, None], nodes[order][:, [4, 5, 6, 7, 0, 1, 2, 3]],
                                   nodes[order])]                   # (p, J, c', c)
    W = (U[:, :, None, :, None] * np.swapaxes(Tn, 2, 3)[:, :, :, None, :]).reshape(m, 24, 9)
    Yw = _mm(W[:, None], C[:, :, :, 3:].reshape(m, 3, 9, 6))         # (p, alpha, (J, c), a)
    ge = key[order][np.r_[True, key[order][1:] != key[order][:-1]]]
    ng = ge.size
    vals = np.empty((2, ng, 144, 8))               # (pos/spin, g, (J, c, a), I)
    lo = g0 = 0
    for k in np.unique(count):
        g = int(np.count_nonzero(count == k))
        hi = lo + k * g
        Uk = U[lo:hi].reshape(g, k, 8, 3).transpose(0, 1, 3, 2).reshape(g, 3 * k, 8)
        for part, Yk in enumerate((Yp, Yw)):
            np.matmul(Yk[lo:hi].reshape(g, 3 * k, 144).transpose(0, 2, 1), Uk,
                      out=vals[part, g0:g0 + g])                    # (g, (J, c, a), I)
        lo, g0 = hi, g0 + g
    gnodes = np.concatenate([mesh.nodes[ge // ne], mesh.nodes[ge % ne]], axis=1)
    nnz, pos, indices, indptr = _pattern(mesh, ge, gnodes)
    data = np.bincount(pos, weights=vals.ravel(), minlength=nnz)
    K = sp.csc_matrix((data, indices, indptr), shape=(n, n))
    if K_normal is not None:
        K_normal = sp.csc_matrix(K_normal)
        where = _normal_positions(K_normal, indices, indptr, n)
        if where is None:
            K = (K + K_normal).tocsc()
        else:
            data[where] += K_normal.data
    return force, K, out
