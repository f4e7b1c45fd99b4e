r"""Slip kinematics of a contact pair over a load step, exact for finite
rotations, and its linearization (docs/friction.md, F4-F7).

The friction law (:mod:`.friction`) takes slips; the assembler
(:mod:`.friction_assembly`) turns forces into residual and tangent.  This
module measures what the law needs, per pair (slave point ``s`` of element
``v`` at ``xi_s``, master point ``s_bar`` of element ``e`` at ``xi``, found
by the projection at the current iterate; subscript ``n`` = the last
converged step, ``N_I`` the P3 shape functions)::

    x, y  = r(s), r(s_bar);   l = |x - y|;   N = (x - y) / l;   rho = l / 2
    u_s   = sum N_I(xi_s) (r_I - r_nI),   u_m = sum N_J(xi) (r_J - r_nJ)
    phi_I = log(R_I R_nI^T)               nodal rotation increment (spatial)
    Lam_s = exp(sum N_I(xi_s) phi_I),     Lam_m = exp(sum N_J(xi) phi_J)
    g     = u_s - u_m - rho (2 N - Lam_s^T N - Lam_m^T N)          (F6)

``g`` is the displacement over the step of the slave's material point
``x - rho N`` relative to the master's ``y + rho N`` (the two points that
meet at the middle of the centreline segment), both traced back to the last
converged state exactly with the incremental rotations of their sections:
the slave's point was at ``r_n(s) - rho Lam_s^T N``.  A rigid motion of any
size over the step gives ``g = 0`` to round-off (``Lam_s = Lam_m = Q``,
``u_s - u_m = (Q - I) l Q^T N``).  To first order in the rotations it is
the earlier ``u_s - u_m - rho (phi_s + phi_m) x N``.

The contact frame: ``N``; ``t`` the slave's unit tangent in the tangent
plane (``(I - N N) r'(s)`` normalized; the director ``d_3`` of a
shear-free rod, of the slave: the master's tangent jumps where the
projection sits on a vertex of the C0 curve); ``b = N x t``.  The laws split ``g`` (F7): the axial
slip ``t (t . g)`` (tangential law, ``gamma_T``) and the circumferential slip
as a rotation about ``t``, ``t (b . g) / rho`` (rotational law, ``gamma_R``).

Crossing pairs (:func:`crossing_kinematics`, :mod:`.crossing`): point
``u`` of element ``e`` stands in the slave's place and ``v`` of ``f`` in
the master's, and both parameters move with the closest-point conditions
(``Delta xi_s``, the ``Us`` of :class:`Slip`, beside ``Delta xi``); the
slip is the same F6 of the two material points now in contact.

Carried multipliers live at the slave's material point and are pushed
forward with its section's incremental rotation, ``Lam_s lambda``
(:func:`pushed`).

Linearization.  Every linearized quantity is a ``(3, 24)`` (or ``(24,)``)
"reduced" operator on the nodal variations of the pair's 8 nodes, with
shape-function weights of four kinds ("modes": ``N_s`` and ``N'_s`` on the
slave's nodes, ``N_m`` and ``N'_m`` on the master's): column
``NM c + beta`` for the dof ``c`` (0-2 position, 3-5 spin) and mode
``beta``.  The spin columns
stand for ``delta phi_k = T^{-1}(phi_k) delta w_k``; the assembler applies
``T^{-1}`` node by node when it expands the columns.  ``Delta xi`` is eq.
6.5 (guarded as in :mod:`.assembly`), the spin of ``Lam`` is
``T(phi_p) Delta phi_p`` (:mod:`skfem_rod.rotations`).
"""
from dataclasses import dataclass

import numpy as np

from ..element import shape_functions
from ..rotations import expm, hat, logm, tangent as tangent_op

#: modes: N_s (slave), N_m (master), N'_m (moving master), N'_s (slave tangent)
S, M, D, DS = 0, 1, 2, 3
NM = 4
NC = 6 * NM                #: reduced columns


def mode(*parts):
    """A reduced operator ``(3, NC)``: ``parts`` = ``(beta, dof, sign)``."""
    op = np.zeros((3, NC))
    for beta, dof, sign in parts:
        op[np.arange(3), NM * (dof + np.arange(3)) + beta] = sign
    return op


XREL = mode((S, 0, 1.0), (M, 0, -1.0))    # delta(x - y), xi held
PHIS = mode((S, 3, 1.0))                  # delta phi at the slave point
PHIM = mode((M, 3, 1.0))                  # ... at the master point, xi held
X1 = mode((DS, 0, 1.0))                   # delta r'(xi_s) at the slave point


@dataclass
class Slip:
    """Kinematics of the pairs (``m``) of one evaluation; the ``D*``
    linearizations are None when not asked for."""
    nodes: np.ndarray     # (m, 8) slave element nodes, then master element nodes
    Ns: np.ndarray        # (m, 4) shape functions at the slave point
    Nm: np.ndarray        # (m, 4) ... at the master point
    dNm: np.ndarray       # (m, 4) their xi derivatives
    dNs: np.ndarray       # (m, 4) xi derivatives at the slave point
    phi: np.ndarray       # (n_nodes, 3) nodal rotation increments of the step
    N: np.ndarray         # (m, 3) normal, master to slave
    l: np.ndarray         # (m,) centreline distance
    rho: np.ndarray       # (m,) lever arm l / 2
    t: np.ndarray         # (m, 3) slave tangent in the tangent plane
    b: np.ndarray         # (m, 3) N x t
    g: np.ndarray         # (m, 3) material slip (F6)
    Lam_s: np.ndarray     # (m, 3, 3) incremental rotation of the slave section
    rel: np.ndarray       # (m, 3) phi_s - phi_m: relative rotation increment (eq. 3.9, F5)
    Xi: np.ndarray = None     # (m, NC) Delta xi
    Us: np.ndarray = None     # (m, NC) Delta xi_s (crossing pairs), None: held
    NX: np.ndarray = None     # (m, NC) N . delta(x - y)
    DN: np.ndarray = None     # (m, 3, NC)
    Dg: np.ndarray = None     # (m, 3, NC)
    Dt: np.ndarray = None     # (m, 3, NC)
    Db: np.ndarray = None     # (m, 3, NC)
    Dw_s: np.ndarray = None   # (m, 3, NC) spin of Lam_s
    Drel: np.ndarray = None   # (m, 3, NC)

    @property
    def Drho(self):
        return 0.5 * self.NX

    def axial(self, v):
        """``t (t . v)`` per pair."""
        return self.t * np.sum(self.t * v, axis=1)[:, None]


@dataclass(frozen=True)
class SlipState:
    """What the slips of an evaluation are measured from: the current nodal
    state ``(r, R)``, the last converged one ``(r_n, R_n)`` and the friction
    multipliers carried at the latter, ``lam_T``, ``lam_R``
    ``(n_slaves, 3)`` (pushed forward with the slave section's incremental
    rotation when :attr:`.friction_assembly.FrictionParams.push_forward`,
    :func:`pushed`)."""
    r: np.ndarray
    R: np.ndarray
    r_n: np.ndarray
    R_n: np.ndarray
    lam_T: np.ndarray
    lam_R: np.ndarray


def _at(N, values, nodes):
    return np.einsum("mk,mkc->mc", N, values[nodes])


def slip_kinematics(mesh, r, R, r_n, R_n, pairs, idx, linearize=True):
    """:class:`Slip` of the pairs ``idx`` of ``pairs`` (from
    :func:`.search.search` at ``r``) over the step from ``(r_n, R_n)`` to
    ``(r, R)``: the slave's parameter is held (a material point), the
    master's moves with the projection (eq. 6.5)."""
    return _kinematics(mesh, r, R, r_n, R_n, pairs.s_elem[idx], pairs.m_elem[idx],
                       pairs.s_xi[idx], pairs.m_xi[idx], pairs.distance[idx],
                       pairs.normal[idx], linearize, interior=pairs.interior[idx])


def crossing_kinematics(mesh, r, R, r_n, R_n, cp, idx, linearize=True):
    """:class:`Slip` of the crossing pairs ``idx`` of ``cp`` (a
    :class:`.crossing.CrossingPairs` at ``r``): point ``u`` of element
    ``e`` in the slave's place, point ``v`` of ``f`` in the master's.  Both
    parameters are free: they move with the closest-point conditions
    ``F_u = F_v = 0`` of ``F = |X(u) - Y(v)|^2 / 2``, ``Delta (u, v) =
    -F_pp^-1 F_pq delta q`` (a parameter held on a node does not move), as
    in :func:`.crossing.crossing_work`.  The slip is the same material
    slip (F6) of the two material points now in contact."""
    l = cp.distance if cp.length is None else cp.length
    free = [np.ones(cp.size, bool) if a is None else np.asarray(a, bool)
            for a in (cp.u_free, cp.v_free)]
    return _kinematics(mesh, r, R, r_n, R_n, cp.e[idx], cp.f[idx], cp.u[idx], cp.v[idx],
                       l[idx], cp.normal[idx], linearize,
                       free=(free[0][idx], free[1][idx]))


def _kinematics(mesh, r, R, r_n, R_n, ve, me, xi_s, xi_m, l, N, linearize, interior=None,
                free=None):
    """:class:`Slip` of the point pairs ``(ve, xi_s)``, ``(me, xi_m)``.
    ``interior``: the master parameter moves by eq. 6.5 where True, the
    slave's is held (:func:`slip_kinematics`); ``free = (u_free, v_free)``:
    both move with the closest-point conditions (:func:`crossing_kinematics`)."""
    nodes = np.concatenate([mesh.nodes[ve], mesh.nodes[me]], axis=1)
    Ns, dNs, d2Ns = (a.T for a in shape_functions(xi_s))
    Nm, dNm, d2Nm = (a.T for a in shape_functions(xi_m))
    sn, mn = mesh.nodes[ve], mesh.nodes[me]
    du = r - r_n
    phi = logm(R @ np.swapaxes(R_n, 1, 2))
    phi_s, phi_m = _at(Ns, phi, sn), _at(Nm, phi, mn)
    Lam_s, Lam_m = expm(phi_s), expm(phi_m)
    a_s = np.einsum("mji,mj->mi", Lam_s, N)              # Lam_s^T N
    a_m = np.einsum("mji,mj->mi", Lam_m, N)
    rho = 0.5 * l
    arm = 2.0 * N - a_s - a_m
    g = _at(Ns, du, sn) - _at(Nm, du, mn) - rho[:, None] * arm
    y1, y2 = _at(dNm, r, mn), _at(d2Nm, r, mn)
    x1 = _at(dNs, r, sn)
    v = x1 - N * np.sum(N * x1, axis=1)[:, None]
    nv = np.maximum(np.linalg.norm(v, axis=1), 1e-300)
    t = v / nv[:, None]
    b = np.cross(N, t)
    out = Slip(nodes, Ns, Nm, dNm, dNs, phi, N, l, rho, t, b, g, Lam_s, phi_s - phi_m)
    if not linearize:
        return out
    m = ve.size
    xy = N * l[:, None]
    outer = lambda a, c: a[:, :, None] * c[:, None, :]     # noqa: E731
    if free is None:
        den = np.sum(y1 * y1, axis=1) - np.sum(xy * y2, axis=1)
        use = interior & (den > 1e-8 * np.sum(y1 * y1, axis=1))
        Om = np.where(use, 1.0 / np.where(use, den, 1.0), 0.0)
        Xi = np.zeros((m, 6, NM))                         # Delta xi (eq. 6.5)
        Xi[:, :3, S] = Om[:, None] * y1
        Xi[:, :3, M] = -Xi[:, :3, S]
        Xi[:, :3, D] = Om[:, None] * xy
        Xi, Us = Xi.reshape(m, NC), None
    else:
        x2 = _at(d2Ns, r, sn)
        Fpq = np.zeros((m, 2, 6, NM))                     # delta F_u, delta F_v
        Fpq[:, 0, :3, S], Fpq[:, 0, :3, M], Fpq[:, 0, :3, DS] = x1, -x1, xy
        Fpq[:, 1, :3, S], Fpq[:, 1, :3, M], Fpq[:, 1, :3, D] = -y1, y1, -xy
        Fpq = Fpq.reshape(m, 2, NC)
        Fpp = np.empty((m, 2, 2))
        Fpp[:, 0, 0] = np.sum(x1 * x1, axis=1) + np.sum(xy * x2, axis=1)
        Fpp[:, 1, 1] = np.sum(y1 * y1, axis=1) - np.sum(xy * y2, axis=1)
        Fpp[:, 0, 1] = Fpp[:, 1, 0] = -np.sum(x1 * y1, axis=1)
        for k, f in enumerate(free):       # a parameter held on a node does not move
            held = ~f
            Fpq[held, k] = 0.0
            Fpp[held, k, :] = 0.0
            Fpp[held, :, k] = 0.0
            Fpp[held, k, k] = 1.0
        P = -np.linalg.solve(Fpp, Fpq)                    # Delta (u, v)
        Us, Xi = P[:, 0], P[:, 1]
    P = np.eye(3) - outer(N, N)
    XR = XREL - outer(y1, Xi)                             # delta (x - y)
    Phis, X1s = PHIS, X1
    if Us is not None:
        XR = XR + outer(x1, Us)
        Phis = PHIS + outer(_at(dNs, phi, sn), Us)
        X1s = X1 + outer(x2, Us)
    DN = P @ XR / l[:, None, None]
    NX = N @ XREL                           # x' . N = y' . N = 0 where a parameter moves
    Dw_s = tangent_op(phi_s) @ Phis
    Phim = PHIM + outer(_at(dNm, phi, mn), Xi)
    Dw_m = tangent_op(phi_m) @ Phim
    Nh = hat(N)
    Da_s = np.swapaxes(Lam_s, 1, 2) @ (Nh @ Dw_s + DN)
    Da_m = np.swapaxes(Lam_m, 1, 2) @ (Nh @ Dw_m + DN)
    Dg = (XREL - outer(_at(dNm, du, mn), Xi) - outer(arm, 0.5 * NX)
          - rho[:, None, None] * (2.0 * DN - Da_s - Da_m))
    if Us is not None:
        Dg = Dg + outer(_at(dNs, du, sn), Us)
    Dv = (P @ X1s - outer(N, np.einsum("mc,mcj->mj", x1, DN))
          - np.sum(N * x1, axis=1)[:, None, None] * DN)
    Dt = (np.eye(3) - outer(t, t)) @ Dv / nv[:, None, None]
    Db = -hat(t) @ DN + Nh @ Dt
    out.Xi, out.NX, out.DN, out.Dg, out.Dt, out.Db, out.Dw_s = Xi, NX, DN, Dg, Dt, Db, Dw_s
    out.Us = Us
    out.Drel = Phis - Phim
    return out


def pushed(slip, lam, linearize=True):
    """Carried multipliers ``lam`` ``(m, 3)`` (expressed at the last converged
    state) pushed forward with the slave section's incremental rotation:
    ``Lam_s lam`` and its linearization ``-hat(Lam_s lam) Dw_s``."""
    L = np.einsum("mij,mj->mi", slip.Lam_s, lam)
    if not linearize:
        return L, None
    return L, -hat(L) @ slip.Dw_s


def pulled_back(slip, f):
    """``Lam_s^T f``: a force of the current state expressed at the last
    converged one (the inverse of :func:`pushed`)."""
    return np.einsum("mji,mj->mi", slip.Lam_s, f)
