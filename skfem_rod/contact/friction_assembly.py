r"""Nonlocal assembler of the frictional contact work: tangential and
rotational Coulomb self-friction (sec. 3.2-3.3, 4.2b-c, 6.1, 7.1).

The slips and their linearization are measured in :mod:`.slip` (exact for
finite rotations, F6), the law (ball projection, stick/slip, exact
derivatives) is :mod:`.friction`; this module evaluates the law on the
slips and assembles the residual and the consistent (non-symmetric)
tangent.

Laws (F7, docs/friction.md: the paper's split of the sliding, sec. 3.2).
With the material slip ``g`` of :mod:`.slip`, the contact frame
``(N, t, b)`` (``t`` the slave's tangent, ``b = N x t``) and the carried
multipliers ``L_T, L_R`` (pushed forward with the slave section's
incremental rotation when ``push_forward``)::

    f_T = (1/mu_T) P_B(mu_T gamma_T f_N)[t t . (g + mu_T L_T)]        axial sliding
    f_R = (1/mu_R) P_B(mu_R gamma_R f_N)[t ((b . g)/rho + mu_R t . L_R)]
                                      circumferential sliding, as a rotation about t

``f_T`` is a force per unit length along ``t``, ``f_R`` a couple per unit
length about ``t`` (``gamma_R`` a length), both acting on the master (the
slave gets the opposite).  The couple is carried by the contact points: a
force ``f_R / rho`` along ``b`` at the material points in contact, whose
moment about either section's axis is ``f_R``.  The force at the contact
point is ``F = f_T + (t . f_R / rho) b``.

Virtual work (residual = internal - external, weight ``w`` of the slave)::

    w F . [delta r(s) - delta r(s_bar) - rho (delta th_s + delta th_m) x N],

material variations, virtual spins interpolated from the nodal spins
(deviation D3): each section gets the couple ``-rho N x F``.  The tangent
is its exact derivative (through the law's ``df/dg``, ``df/df_N``, the
kinematics of :mod:`.slip`, and the moving master shape functions).

Assembly.  Each pair gives a dense 48 x 48 block over the positions and
spins of its 8 nodes, of low rank in the nodes: ``U C U^T`` with ``U``
(8 nodes x 4 modes: ``N_s``, ``N_m``, ``N'_m``, ``N'_s``) and a core ``C``
of 24 x 24 numbers per pair (the spin columns of node ``k`` carry ``T^-1(phi_k)``).
The pairs of one element pair share their 8 nodes: the columns are expanded
pair by pair, the rows by one matrix product per element pair, batched over
the element pairs with the same number of pairs; the blocks are summed into
CSC arrays by one ``bincount`` over a cached pattern (kept while the element
pairs in contact do not change, in the caller's
:class:`.assembly.PatternCache`, as in :mod:`.assembly`), into which the
normal contact tangent can be added (``K_normal``) instead of a sparse sum.
"""
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from ..rotations import hat, tangent_inv
import skfem_rod.contact.friction as law
from .assembly import PatternCache
from .slip import (DS, NC, NM, S, M, crossing_kinematics, pulled_back, pushed,
                   slip_kinematics)
from .slip import D as DM


@dataclass(frozen=True)
class FrictionParams:
    """Coefficients and compliances of the two friction laws.

    gamma_T : tangential (axial) Coulomb coefficient, dimensionless.
    gamma_R : rotational (circumferential) coefficient, a length:
        ``|f_R| <= gamma_R f_N``.
    mu_T, mu_R : compliances (eq. 4.2b-c; increments, not rates).
    rotational : what the rotational law acts on (docs/friction.md F7):
        ``"twist"`` (default): the relative rotation increment about the
        slave's tangent ``t`` (the paper's "around d_3", eq. 3.9 projected),
        a pure couple on the sections; the tangential law acts on the whole
        material slip (isotropic Coulomb), so a twist slides the surface and
        is resisted by ``(gamma_R + rho gamma_T) f_N``.
        ``"circumferential"``: the material slip is split, axial sliding to
        the tangential law, circumferential sliding (as an angle about
        ``t``) to the rotational law: no sliding is counted twice, a twist is
        resisted by ``gamma_R f_N`` alone, but lateral sliding of parallel
        strands is then rotational friction.
        ``"pivot"``: the relative rotation about the normal ``N`` (spinning
        friction of the contact patch), a pure couple; invisible to the
        tangential slip.
    push_forward : the carried multipliers ``lam_T``, ``lam_R`` are
        expressed at the last converged state and are pushed forward with
        the slave section's incremental rotation (objective for rotations
        of any size over the step); store :attr:`FrictionOutput.multiplier_T`
        / ``multiplier_R`` as the Uzawa update inside a step and
        ``force_T`` / ``force_R`` when the step is accepted.  False: the
        multipliers are used as given (the update is then ``force_*``).
    """
    gamma_T: float = 0.0
    gamma_R: float = 0.0
    mu_T: float = 1.0
    mu_R: float = 1.0
    push_forward: bool = False
    rotational: str = "twist"

    def __post_init__(self):
        if self.rotational not in ("twist", "circumferential", "pivot"):
            raise ValueError("rotational must be 'twist', 'circumferential' or 'pivot', "
                             f"got {self.rotational!r}")


@dataclass
class FrictionOutput:
    """Per active pair (``f_N > 0``) friction figures of one evaluation."""
    index: np.ndarray        # (m,) index into the Pairs of the evaluation
    slave: np.ndarray        # (m,) global slave point index
    slip_T: np.ndarray       # (m, 3) tangential slip increment (F6, F7)
    slip_R: np.ndarray       # (m, 3) rotational slip increment (F7)
    force_T: np.ndarray      # (m, 3) f_T (on the master)
    force_R: np.ndarray      # (m, 3) f_R (couple on the master)
    state_T: np.ndarray      # (m,) FrictionState
    state_R: np.ndarray      # (m,) FrictionState
    fN: np.ndarray           # (m,) normal force
    multiplier_T: np.ndarray = None   # (m, 3) Uzawa update at the last converged state
    multiplier_R: np.ndarray = None   # (m, 3)
    axis: np.ndarray = None           # (m, 3) t, the master tangent
    #: ``(dofs, values)`` ``(m, 48)``: the derivative of the friction
    #: residual with respect to each pair's normal force ``f_N`` (through
    #: the Coulomb radius), spatial basis; with ``tangent`` only.  The
    #: nonsmooth Newton (:mod:`skfem_rod.nonsmooth`) couples it to the
    #: normal multipliers (``d f_N / d lambda_N = 1`` where active).
    dresidual_dfN: tuple = None
    #: :class:`MultiplierJacobian` (with ``tangent`` and
    #: ``multiplier_jacobian``): the carried multipliers as unknowns of the
    #: generalized Newton (:mod:`skfem_rod.nonsmooth`)
    jacobian: object = None


class MultiplierJacobian(NamedTuple):
    """Derivatives of the friction multipliers' Uzawa update per active
    pair, ``c = Lam_s^T f`` (``f`` without ``push_forward``): the
    ``multiplier_T`` / ``multiplier_R`` of :class:`FrictionOutput`, and of
    the residual with respect to the carried multipliers.  Law ``X`` is
    ``T`` (tangential) or ``R`` (rotational); ``dofs`` ``(m, 48)`` are the
    spatial dofs of the pair's 8 nodes (slave element, then master).

    rows_X : ``(m, 3, 48)`` ``dc_X / dy`` (spins: spatial virtual spins).
    self_X : ``(m, 3, 3)`` ``dc_X / dlambda_X``.
    normal_X : ``(m, 3)`` ``dc_X / df_N`` (the Coulomb radius).
    cols_X : ``(m, 48, 3)`` ``dG / dlambda_X`` (``G`` the friction residual).
    """
    dofs: np.ndarray
    rows_T: np.ndarray
    rows_R: np.ndarray
    self_T: np.ndarray
    self_R: np.ndarray
    normal_T: np.ndarray
    normal_R: np.ndarray
    cols_T: np.ndarray
    cols_R: np.ndarray


class _Forces(NamedTuple):
    F: np.ndarray            # (m, 3) force at the contact point (on the master)
    fT: np.ndarray
    fR: np.ndarray
    couple: np.ndarray       # (m, 3) pure couple on the sections (on the master), or 0
    gT: np.ndarray           # (m, 3) the slips
    gR: np.ndarray
    resT: law.FrictionResult
    resR: law.FrictionResult
    DF: np.ndarray           # (m, 3, NC) or None
    Dcouple: np.ndarray      # (m, 3, NC), 0 or None
    DfT: np.ndarray = None   # (m, 3, NC): the laws' forces linearized (None without)
    DfR: np.ndarray = None


def _outer(a, c):
    return a[:, :, None] * c[:, None, :]


def _forces(kin, lam_T, lam_R, fN, dfN, p, linearize):
    """The two laws on their slips (F6, F7): the force ``F`` at the contact
    point and the couple on the sections, with their reduced
    linearizations."""
    if p.push_forward:
        LT, DLT = pushed(kin, lam_T, linearize)
        LR, DLR = pushed(kin, lam_R, linearize)
    else:
        LT, LR, DLT, DLR = lam_T, lam_R, 0.0, 0.0
    split = p.rotational == "circumferential"
    t, b, g, rho, N = kin.t, kin.b, kin.g, kin.rho, kin.N
    vT = g + p.mu_T * LT
    if split:
        AT, gT = kin.axial(vT), kin.axial(g)
        bg = np.sum(b * g, axis=1)
        axis, cR = t, bg / rho + p.mu_R * np.sum(t * LR, axis=1)
        gR = t * (bg / rho)[:, None]
    else:
        AT = vT - N * np.sum(N * vT, axis=1)[:, None]
        gT = g - N * np.sum(N * g, axis=1)[:, None]
        axis = t if p.rotational == "twist" else N
        vR = kin.rel + p.mu_R * LR
        cR = np.sum(axis * vR, axis=1)
        gR = axis * np.sum(axis * kin.rel, axis=1)[:, None]
    zero = np.zeros_like(AT)
    resT = law.friction_force(AT, zero, p.mu_T, p.gamma_T, fN)
    resR = law.friction_force(axis * cR[:, None], zero, p.mu_R, p.gamma_R, fN)
    fT, fR = resT.force, resR.force
    fRs = np.sum(axis * fR, axis=1)
    F = fT + (fRs / rho)[:, None] * b if split else fT
    couple = zero if split else fR
    if not linearize:
        return _Forces(F, fT, fR, couple, gT, gR, resT, resR, None, None)
    dot = lambda a, D: np.einsum("mc,mcj->mj", a, D)               # noqa: E731
    DfN = -dfN[:, None] * kin.NX
    Drho = kin.Drho
    DvT = kin.Dg + p.mu_T * DLT
    if split:
        DAT = np.sum(t * vT, axis=1)[:, None, None] * kin.Dt + _outer(t, dot(vT, kin.Dt)
                                                                      + dot(t, DvT))
        DcR = ((dot(g, kin.Db) + dot(b, kin.Dg)) / rho[:, None]
               - (bg / rho ** 2)[:, None] * Drho
               + p.mu_R * (dot(LR, kin.Dt) + (dot(t, DLR) if p.push_forward else 0.0)))
        Daxis = kin.Dt
    else:
        DAT = (DvT - np.sum(N * vT, axis=1)[:, None, None] * kin.DN
               - _outer(N, dot(vT, kin.DN) + dot(N, DvT)))
        Daxis = kin.Dt if p.rotational == "twist" else kin.DN
        DvR = kin.Drel + p.mu_R * DLR
        DcR = dot(vR, Daxis) + dot(axis, DvR)
    DfT = resT.dforce_dslip @ DAT + _outer(resT.dforce_dnormal, DfN)
    DAR = cR[:, None, None] * Daxis + _outer(axis, DcR)
    DfR = resR.dforce_dslip @ DAR + _outer(resR.dforce_dnormal, DfN)
    if split:
        DfRs = dot(fR, kin.Dt) + dot(t, DfR)
        DF = (DfT + _outer(b, DfRs / rho[:, None] - (fRs / rho ** 2)[:, None] * Drho)
              + (fRs / rho)[:, None, None] * kin.Db)
        return _Forces(F, fT, fR, couple, gT, gR, resT, resR, DF, 0.0, DfT, DfR)
    return _Forces(F, fT, fR, couple, gT, gR, resT, resR, DfT, DfR, DfT, DfR)


def _residual(n, kin, w, F, couple):
    """``w F . [delta x - delta y - rho (delta th_s + delta th_m) x N]``:
    on the slave nodes ``N_s (F; -rho q)``, on the master's
    ``N_m (-F; -rho q)``, ``q = N x F``."""
    dofs, loc = _local(kin, w, F, couple)
    return np.bincount(dofs.ravel(), weights=loc.ravel(), minlength=n)


def _local(kin, w, F, couple):
    """The pairs' residual entries ``(dofs, values)``, each ``(m, 8, 6)``
    (linear in ``F`` and ``couple``: :func:`_residual`)."""
    m = w.size
    wF = w[:, None] * F
    wq = (w * kin.rho)[:, None] * np.cross(kin.N, F)
    loc = np.empty((m, 8, 6))
    loc[:, :4, :3] = kin.Ns[:, :, None] * wF[:, None, :]
    loc[:, 4:, :3] = kin.Nm[:, :, None] * (-wF)[:, None, :]
    wc = w[:, None] * couple                      # + w f_R . (delta th_s - delta th_m)
    loc[:, :4, 3:] = kin.Ns[:, :, None] * (wc - wq)[:, None, :]
    loc[:, 4:, 3:] = kin.Nm[:, :, None] * (-wc - wq)[:, None, :]
    dofs = 6 * kin.nodes[:, :, None] + np.arange(6)
    return dofs, loc


def _dforces_dfN(kin, fo, p):
    """``dF / df_N`` and ``d couple / df_N`` per pair (the Coulomb radius
    ``mu gamma f_N`` of both laws; zero in stick)."""
    dT, dR = fo.resT.dforce_dnormal, fo.resR.dforce_dnormal
    if p.rotational == "circumferential":
        t = kin.t
        return dT + (np.sum(t * dR, axis=1) / kin.rho)[:, None] * kin.b, np.zeros_like(dT)
    return dT, dR


def _core(kin, w, F, DF, couple, Dcouple):
    """The reduced core ``C`` ``(m, row mode, row dof, NC)`` of the tangent:
    ``w [Vx^T DF - rho Vl^T Dq - (Vl^T q) Drho^T]`` plus the moving master
    shape functions (row mode ``N'_m`` times ``Delta xi``) and, for a
    crossing pair, the moving slave's (row mode ``N'_s`` times ``Delta
    xi_s``)."""
    m = w.size
    q = np.cross(kin.N, F)
    Dq = hat(kin.N) @ DF - hat(F) @ kin.DN
    wc = w[:, None, None]
    E1 = wc * DF
    E2 = -wc * (kin.rho[:, None, None] * Dq + _outer(q, kin.Drho))
    C = np.zeros((m, NM, 6, NC))
    C[:, 0, :3] = E1
    C[:, 1, :3] = -E1
    E3 = wc * Dcouple
    C[:, 0, 3:] = E2 + E3
    C[:, 1, 3:] = E2 - E3
    C[:, 2, :3] = -_outer(w[:, None] * F, kin.Xi)
    C[:, 2, 3:] = -_outer(w[:, None] * (kin.rho[:, None] * q + couple), kin.Xi)
    if kin.Us is not None:             # a moving slave point (crossing pairs)
        C[:, 3, :3] = _outer(w[:, None] * F, kin.Us)
        C[:, 3, 3:] = _outer(w[:, None] * (couple - kin.rho[:, None] * q), kin.Us)
    return C


def _expand(mesh, kin, ve, me, C, K_normal, cache):
    """The pairs' blocks ``U C U^T`` summed into a CSC matrix (see the
    module docstring; the pattern kept in ``cache``); ``K_normal`` added
    into its arrays."""
    n = mesh.n_dofs
    m = ve.size
    nodes = kin.nodes
    ne = mesh.nodes.shape[0]
    hs = (ve > me).astype(np.intp)                  # half of the slave's nodes
    U = np.zeros((m, 2, 4, NM))
    ar = np.arange(m)
    U[ar, hs, :, 0] = kin.Ns
    U[ar, 1 - hs, :, 1] = kin.Nm
    U[ar, 1 - hs, :, 2] = kin.dNm
    U[ar, hs, :, 3] = kin.dNs
    U = U.reshape(m, 8, NM)
    key = np.minimum(ve, me) * ne + np.maximum(ve, me)
    _, inv, count = np.unique(key, return_inverse=True, return_counts=True)
    order = np.lexsort((key, count[inv]))          # by pair count, then element pair
    U = U[order]
    C = C[order].reshape(m, NM, 6, 6, NM).transpose(0, 1, 4, 3, 2)   # (p, alpha, beta, c, a)
    Yp = np.matmul(U[:, None], C[:, :, :, :3].reshape(m, NM, NM, 18))  # (p, alpha, J, (c, a))
    Tn = tangent_inv(kin.phi)[np.where(hs[order, None],
                                       nodes[order][:, [4, 5, 6, 7, 0, 1, 2, 3]],
                                       nodes[order])]               # (p, J, c', c)
    W = (U[:, :, None, :, None]
         * np.swapaxes(Tn, 2, 3)[:, :, :, None, :]).reshape(m, 24, 3 * NM)
    Yw = np.matmul(W[:, None], C[:, :, :, 3:].reshape(m, NM, 3 * NM, 6))  # (p, alpha, (J, c), a)
    ge = key[order][np.r_[True, key[order][1:] != key[order][:-1]]]
    ng = ge.size
    vals = np.empty((2, ng, 144, 8))               # (pos/spin, g, (J, c, a), I)
    lo = g0 = 0
    for k in np.unique(count):
        g = int(np.count_nonzero(count == k))
        hi = lo + k * g
        Uk = U[lo:hi].reshape(g, k, 8, NM).transpose(0, 1, 3, 2).reshape(g, NM * k, 8)
        for part, Yk in enumerate((Yp, Yw)):
            np.matmul(Yk[lo:hi].reshape(g, NM * k, 144).transpose(0, 2, 1), Uk,
                      out=vals[part, g0:g0 + g])                    # (g, (J, c, a), I)
        lo, g0 = hi, g0 + g
    gnodes = np.concatenate([mesh.nodes[ge // ne], mesh.nodes[ge % ne]], axis=1)
    nnz, pos, indices, indptr = _pattern(mesh, ge, gnodes, cache)
    data = np.bincount(pos, weights=vals.ravel(), minlength=nnz)
    K = sp.csc_matrix((data, indices, indptr), shape=(n, n))
    if K_normal is not None:
        K_normal = sp.csc_matrix(K_normal)
        where = _normal_positions(K_normal, indices, indptr, n, cache)
        if where is None:
            K = (K + K_normal).tocsc()
        else:
            data[where] += K_normal.data
    return K


def _pattern(mesh, ge, gnodes, cache):
    """CSC structure (``nnz, pos, indices, indptr``) of the friction tangent
    of the element pairs ``ge`` (keys ``lo * n_elements + hi``, in the order
    of the blocks) with nodes ``gnodes`` ``(ng, 8)``; ``pos``: the data
    position of every entry ``(part, g, J, c, a, I)`` of the element-pair
    blocks (row dof ``6 I + a``, column ``6 J + 3 part + c``).  The last
    pattern is kept in ``cache``: the element pairs in contact seldom change
    between Newton iterations."""
    hit = cache.lookup(mesh, ge)
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
    return cache.store(mesh, ge, (nnz, pos, indices, indptr.astype(itype)))


def _normal_positions(K_normal, indices, indptr, n, cache):
    """Data positions, in the friction tangent (``indices``, ``indptr``),
    of the entries of the CSC matrix ``K_normal`` (the normal contact
    tangent of the same pairs, whose node blocks are among the friction's),
    or None if its pattern is not inside (or not canonical).  Kept with
    the pattern in ``cache`` (``merged``)."""
    c = cache.merged
    if (c is not None and c[0].shape == K_normal.indptr.shape
            and c[1].shape == K_normal.indices.shape
            and np.array_equal(c[0], K_normal.indptr) and np.array_equal(c[1], K_normal.indices)):
        return c[2]
    key_f = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr)) * n + indices
    key_n = np.repeat(np.arange(n, dtype=np.int64), np.diff(K_normal.indptr)) * n + K_normal.indices
    where = np.minimum(np.searchsorted(key_f, key_n), key_f.size - 1)
    if not (np.all(np.diff(key_n) > 0) and np.array_equal(key_f[where], key_n)):
        where = None
    cache.merged = (K_normal.indptr.copy(), K_normal.indices.copy(), where)
    return where


def friction_work(mesh, state, pairs, normal, params, tangent=True, K_normal=None,
                  cache=None, multiplier_jacobian=False):
    """Residual ``(n_dofs,)``, tangent (CSC or None) and :class:`FrictionOutput`
    of the frictional contact work of ``pairs`` (from :func:`.search.search`
    at ``state.r``).

    ``state`` (:class:`.slip.SlipState`): the current and the last
    converged nodal states and the friction multipliers ``lam_T``,
    ``lam_R`` ``(n_slaves, 3)`` carried at the latter; ``normal``
    (:class:`.law.NormalLaw`): the normal multipliers ``(n_slaves,)``,
    compliances and contact radius; ``params`` (:class:`FrictionParams`):
    the coefficients and compliances, and ``push_forward``.  Pairs with
    ``f_N = 0`` carry no friction.  ``K_normal`` (optional, CSC): a matrix
    added to the returned tangent, the normal contact tangent of the same
    pairs (from :func:`.assembly.contact_work`): its entries are added into
    the friction tangent's arrays, which hold its pattern.  ``cache``: the
    :class:`.assembly.PatternCache` of the friction tangent's pattern
    (default: none kept).  ``multiplier_jacobian`` (with ``tangent``):
    the :class:`MultiplierJacobian` in the output's ``jacobian``.
    """
    p = params
    n = mesh.n_dofs
    if K_normal is not None and K_normal.shape != (n, n):
        raise ValueError(f"K_normal must be an ({n}, {n}) matrix, got shape {K_normal.shape}")
    fN_all, dfN_all = normal.forces(pairs)
    idx = np.flatnonzero(fN_all > 0)
    if idx.size == 0:
        return _no_friction(n, idx, tangent, K_normal)
    sl, w, fN, dfN = pairs.slave[idx], pairs.weight[idx], fN_all[idx], dfN_all[idx]
    kin = slip_kinematics(mesh, state.r, state.R, state.r_n, state.R_n, pairs, idx, tangent)
    force, K, out, _ = _work(mesh, kin, w, state.lam_T[sl], state.lam_R[sl], fN, dfN, p, idx,
                             sl, tangent, multiplier_jacobian, pairs.s_elem[idx],
                             pairs.m_elem[idx], K_normal, cache)
    return force, K, out


def _work(mesh, kin, w, lam_T, lam_R, fN, dfN, p, idx, slave, tangent, multiplier_jacobian,
          ve, me, K_normal=None, cache=None):
    """The laws on the pairs' slips (:class:`.slip.Slip` ``kin``, weights
    ``w``, carried multipliers, normal forces ``fN`` and their derivatives
    ``dfN``): residual, tangent (or None), :class:`FrictionOutput` (``idx``
    and ``slave`` its indices) and the laws' :class:`_Forces`; with the
    tangent the output's ``dresidual_dfN`` and (``multiplier_jacobian``)
    ``jacobian``."""
    n = mesh.n_dofs
    fo = _forces(kin, lam_T, lam_R, fN, dfN, p, tangent)
    force = _residual(n, kin, w, fo.F, fo.couple)
    back = (lambda f: pulled_back(kin, f)) if p.push_forward else (lambda f: f)
    out = FrictionOutput(idx, slave, fo.gT, fo.gR, fo.fT, fo.fR, fo.resT.state, fo.resR.state,
                         fN, back(fo.fT), back(fo.fR), kin.t)
    if not tangent:
        return force, None, out, fo
    dofs, loc = _local(kin, w, *_dforces_dfN(kin, fo, p))
    out.dresidual_dfN = (dofs.reshape(idx.size, 48), loc.reshape(idx.size, 48))
    if multiplier_jacobian:
        out.jacobian = _multiplier_jacobian(kin, fo, p, w)
    C = _core(kin, w, fo.F, fo.DF, fo.couple, fo.Dcouple)
    K = _expand(mesh, kin, ve, me, C, K_normal, PatternCache() if cache is None else cache)
    return force, K, out, fo


def crossing_friction_work(mesh, state, cp, fN, dfN, params, tangent=True, dw=None,
                           offset=None, multiplier_jacobian=False):
    """Residual ``(n_dofs,)``, tangent (CSC or None) and
    :class:`FrictionOutput` of Coulomb friction at the crossing pairs ``cp``
    (a :class:`.crossing.CrossingPairs` at ``state.r``;
    docs/crossing-contact.md, "Friction at the crossing pairs").

    The pair ``(e, u)``, ``(f, v)`` is a slave/master pair whose two
    parameters move (:func:`.slip.crossing_kinematics`): the same material
    slip (F6), the same laws (:func:`_forces`), acting with the pair's
    weight ``w`` as a point force ``w F``: ``|w F| <= gamma_T w f_N``,
    with ``f_N`` the pair's point force before its weight.

    ``state`` (:class:`.slip.SlipState`): ``lam_T``, ``lam_R`` ``(m, 3)``
    are the pairs' carried multipliers (carried to ``cp`` by place by the
    caller); ``fN``, ``dfN`` ``(m,)``: the pairs' normal point forces (before
    the weight) and their derivative with respect to the gap; ``params``:
    the crossing pairs' :class:`FrictionParams` (compliances per unit
    point force).  ``dw`` (optional, ``(m, n_dofs)`` CSR): the weights'
    derivatives ``dw/dq`` (:func:`.crossing.crossing_work`,
    ``weight_rows``), whose terms the tangent then holds (the factor ``w``
    and the gap ``2 eps + w offset - l`` of ``f_N``, ``offset`` the pairs'
    gap offsets); without it the weights are frozen in the tangent.
    ``FrictionOutput.slave`` holds the pairs' indices in ``cp``; with the
    tangent its ``dresidual_dfN`` is the residual's derivative with respect
    to each pair's ``f_N`` (the generalized Newton's crossing columns) and,
    with ``multiplier_jacobian``, its ``jacobian`` the
    :class:`MultiplierJacobian` of the pairs' multipliers (their rows among
    the generalized Newton's unknowns)."""
    p = params
    n = mesh.n_dofs
    idx = np.flatnonzero(fN > 0)
    if idx.size == 0:
        return _no_friction(n, idx, tangent, None)
    w = np.ones(cp.size)[idx] if cp.weight is None else cp.weight[idx]
    kin = crossing_kinematics(mesh, state.r, state.R, state.r_n, state.R_n, cp, idx, tangent)
    force, K, out, fo = _work(mesh, kin, w, state.lam_T[idx], state.lam_R[idx], fN[idx],
                              dfN[idx], p, idx, idx, tangent, multiplier_jacobian, cp.e[idx],
                              cp.f[idx])
    if not tangent:
        return force, None, out
    if dw is not None:
        Wq = sp.coo_matrix(dw[idx])
        if Wq.nnz:
            # w F(f_N(2 eps + w offset - l)): the weight's derivative enters
            # through the factor and through the gap
            off = np.zeros(cp.size)[idx] if offset is None else np.asarray(offset, float)[idx]
            m = idx.size
            dofs, per_w = _local(kin, np.ones(m), fo.F, fo.couple)
            per_f = (off * dfN[idx])[:, None] * out.dresidual_dfN[1]
            vec = (per_w.reshape(m, 48) + per_f)[Wq.row]             # (nnz, 48)
            rows = dofs.reshape(m, 48)[Wq.row]
            cols = np.broadcast_to(Wq.col[:, None], rows.shape)
            K = K + sp.csc_matrix(((vec * Wq.data[:, None]).ravel(),
                                   (rows.ravel(), cols.ravel())), shape=(n, n))
    return force, K.tocsc(), out


def _expand_rows(kin, D):
    """Reduced operators ``D`` ``(m, 3, NC)`` (see :mod:`.slip`) expanded
    to the dofs of the pairs' 8 nodes: ``(m, 3, 48)``, the spin columns
    taken from ``delta phi_k`` to the spatial spins ``delta w_k`` by
    ``T^-1(phi_k)`` node by node, as :func:`_expand` does."""
    m = D.shape[0]
    U = np.zeros((m, 8, NM))
    U[:, :4, S] = kin.Ns
    U[:, 4:, M] = kin.Nm
    U[:, 4:, DM] = kin.dNm
    U[:, :4, DS] = kin.dNs
    Dr = D.reshape(m, 3, 6, NM)
    rows = np.einsum("mkb,micb->mikc", U, Dr)                 # (m, 3, 8 nodes, 6)
    Tinv = tangent_inv(kin.phi)[kin.nodes]                    # (m, 8, 3, 3)
    rows[..., 3:] = np.einsum("mikc,mkcd->mikd", rows[..., 3:], Tinv)
    return rows.reshape(m, 3, 48)


def _multiplier_jacobian(kin, fo, p, w):
    """:class:`MultiplierJacobian` of the pairs: ``c = Lam^T f`` with
    ``f = (1/mu) P_B(mu gamma f_N)[Pi (v + mu Lam lambda)]`` (``Pi`` the
    law's projection, ``Lam`` the slave section's incremental rotation with
    ``push_forward``, else the identity), so ``dc/dlambda = Lam^T (df/da)
    mu Pi Lam``, ``dc/dy = Lam^T (Df + hat(f) Dw_s)`` (``delta Lam =
    hat(delta w) Lam``) and ``dc/df_N = Lam^T df/df_N``."""
    m = w.size
    eye = np.eye(3)
    Lam = kin.Lam_s if p.push_forward else np.broadcast_to(eye, (m, 3, 3))
    LamT = np.swapaxes(Lam, 1, 2)
    split = p.rotational == "circumferential"
    t, N = kin.t, kin.N
    PT = _outer(t, t) if split else eye - _outer(N, N)
    axis = t if split or p.rotational == "twist" else N
    dfT = fo.resT.dforce_dslip @ (p.mu_T * PT @ Lam)          # df_T / dlambda_T
    dfR = fo.resR.dforce_dslip @ (p.mu_R * _outer(axis, axis) @ Lam)
    zero = np.zeros((m, 3, 3))
    if split:       # F = f_T + (t . f_R / rho) b, no couple
        dF_R = kin.b[:, :, None] * (np.einsum("mi,mik->mk", t, dfR) / kin.rho[:, None])[:, None]
        cols = ((dfT, zero), (dF_R, zero))
    else:
        cols = ((dfT, zero), (zero, dfR))
    dofs = None
    expanded = []
    for dF, dC in cols:
        per = []
        for k in range(3):
            dofs, loc = _local(kin, w, dF[:, :, k], dC[:, :, k])
            per.append(loc.reshape(m, 48))
        expanded.append(np.stack(per, axis=2))                # (m, 48, 3)

    def rows(f, Df):
        if p.push_forward:
            Df = LamT @ (Df + hat(f) @ kin.Dw_s)
        return _expand_rows(kin, Df)

    return MultiplierJacobian(
        dofs.reshape(m, 48), rows(fo.fT, fo.DfT), rows(fo.fR, fo.DfR),
        LamT @ dfT, LamT @ dfR,
        np.einsum("mji,mj->mi", Lam, fo.resT.dforce_dnormal),
        np.einsum("mji,mj->mi", Lam, fo.resR.dforce_dnormal),
        expanded[0], expanded[1])


#: the friction laws: the attribute of their multipliers
#: (:class:`~skfem_rod.problem.Multipliers`), the contact option of their
#: coefficient, and the suffix of their fields in :class:`FrictionOutput`
LAWS = (("tangential", "gamma_T", "T"), ("rotational", "gamma_R", "R"))


def multiplier_updates(out, multipliers, contact, names=None):
    """The Uzawa update ``lambda <- f`` of the friction multipliers (the
    projected multipliers of :func:`skfem_rod.contact.friction.uzawa_update`
    in the :class:`FrictionOutput` ``out``, expressed at the last converged
    state: ``multiplier_T``, ``multiplier_R``) of the laws ``names`` (all by
    default), each a full ``(n_slaves, 3)`` array, zero at the points out of
    contact; and how far they are from ``multipliers``: the largest change
    relative to the Coulomb bound ``gamma max f_N`` of the contact options
    ``contact`` (0 without points in contact or with a zero coefficient).
    Read by the Uzawa loop (the update itself) and the generalized Newton
    (its friction residual ``w (update - lambda)``)."""
    updates, moved = {}, 0.0
    for name, coef, X in LAWS:
        if names is not None and name not in names:
            continue
        old = getattr(multipliers, name)
        new = np.zeros_like(old)
        new[out.slave] = getattr(out, "multiplier_" + X)
        updates[name] = new
        gamma = getattr(contact, coef)
        if gamma > 0 and out.fN.size:
            moved = max(moved, float(np.abs(new - old).max()) / (gamma * out.fN.max()))
    return updates, moved


def crossing_updates(out, n_pairs, carried, gamma):
    """The Uzawa update ``lambda <- f`` of the crossing pairs' tangential
    friction multipliers (the :class:`FrictionOutput` ``out`` of
    :func:`crossing_friction_work`, ``multiplier_T``): ``(n_pairs, 3)``,
    zero at pairs without a normal force; and how far it is from
    ``carried`` (the multipliers the evaluation used), relative to the
    Coulomb bound ``gamma max f_N`` (0 without force or coefficient), as
    :func:`multiplier_updates` measures the slave points'."""
    new = np.zeros((n_pairs, 3))
    new[out.slave] = out.multiplier_T
    moved = 0.0
    if gamma > 0 and out.fN.size and n_pairs:
        moved = float(np.abs(new - carried).max()) / (gamma * out.fN.max())
    return new, moved


def coulomb_misfit(out, params, tolerance):
    """How far the friction forces of the :class:`FrictionOutput` ``out``
    are from Coulomb's law (eq. 3.10) where the points slip: the largest
    component of a slipping point's force across its slip, relative to the
    bound ``gamma f_N`` (the sine of the angle between force and slip: a
    force relative to the bound, as the multipliers' motion is measured),
    over both laws of ``params`` (:class:`FrictionParams`, the compliances
    of the evaluation); 0 where nothing slips.  Points whose slip is below
    ``tolerance`` times their stick range ``mu gamma f_N`` are left out:
    the slip adds less than the tolerance to their trial force
    ``lambda + g / mu``, so its direction is not theirs to follow (and a
    slip at round-off, as in a rigid step, has no direction).  The Uzawa
    loop's Coulomb test (:mod:`skfem_rod.augmented`, tolerance
    ``friction_tolerance``) and the generalized Newton's
    (:mod:`skfem_rod.nonsmooth`).

    The multipliers' motion alone does not bound the misfit: in the
    rotational-friction scene with both laws on, forces ended 4 degrees off
    slips of 0.1 to 0.7 stick ranges while the multipliers moved by less
    than the tolerance (docs/friction.md)."""
    worst = 0.0
    for _, coef, X in LAWS:
        gamma, mu = getattr(params, coef), getattr(params, "mu_" + X)
        f, g, state = (getattr(out, a + X) for a in ("force_", "slip_", "state_"))
        if gamma > 0:
            big = (state == law.SLIP) & (np.linalg.norm(g, axis=1)
                                         > tolerance * mu * gamma * out.fN)
            worst = max(worst, float(law.misalignment(f[big], g[big], gamma, out.fN[big])
                                     .max(initial=0.0)))
    return worst


def _no_friction(n, idx, tangent, K_normal):
    """What :func:`friction_work` returns when no pair carries a force."""
    z = np.zeros((0, 3))
    out = FrictionOutput(idx, idx, z, z, z, z, np.zeros(0, int), np.zeros(0, int),
                         np.zeros(0), z, z, z)
    if not tangent:
        return np.zeros(n), None, out
    return np.zeros(n), (sp.csc_matrix((n, n)) if K_normal is None else K_normal), out
