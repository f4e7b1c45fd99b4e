r"""Rod kinematics: the one helper that residual, tangent and energy share.

Objective interpolation (Crisfield & Jelenic 1999)
--------------------------------------------------
Each element has four nodes with positions ``r_I`` and rotations ``R_I``.
The element's reference rotation is the rotation of one of its nodes,
``R_r = R_a`` with ``a`` = :data:`REF_NODE` (the node at xi = 1/3).  In the
co-rotated *local coordinates*

    rho_I = R_r^T r_I,        psi_I = log(R_r^T R_I)      (|psi_I| < pi)

the element is interpolated with the cubic Lagrange functions ``N_I``:

    rho(s) = sum N_I rho_I,   psi(s) = sum N_I psi_I,   R(s) = R_r exp(psi(s)).

Everything depends only on the current nodal values, so the discrete energy
is objective (a rigid rotation of all nodes changes nothing) and path
independent (no history), for any number of turns: only the rotation *within*
one element must stay below ``pi`` (:data:`PSI_MAX` guards it).

Exact strains (no small-angle simplification, cf. the paper's eq. 2.3)
---------------------------------------------------------------------
With ``Lambda = exp(psi)`` and ``T`` the tangent operator (see
:mod:`skfem_rod.rotations`), the material strains are

    v = R^T r' = Lambda^T rho',         u = axial(R^T R') = T(psi)^T psi'.

Collect ``z = (rho', psi, psi')`` (9 numbers at a point) and the strains
``eps = (v, u)`` (6 numbers).  This module gives, at quadrature points,

* ``A = d eps / d z`` (6 x 9),
* ``G = S . d^2 eps / d z^2`` (9 x 9), the geometric term, for the stress
  resultants ``S = (N, M) = C (eps - eps0)`` (material frame),

so that the energy density ``W = 1/2 (eps - eps0) . C (eps - eps0)`` has
gradient ``A^T S`` and Hessian ``A^T C A + G`` with respect to ``z``.
Spatial resultants are ``n = R N``, ``m = R M`` (the paper's eq. 3.5).
"""
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .rotations import (coefficients, cross, hat, expm, logm, tangent, tangent_inv,
                        dtangent_matrix, dtangent_form, d2tangent_form)

#: local index (scikit-fem dof order 0, 1, 1/3, 2/3) of the reference node
REF_NODE = 2
#: the element's other nodes (their spins enter the chart through psi_I)
NOT_REF = np.array([I for I in range(4) if I != REF_NODE])
#: largest admitted rotation of a node relative to its element's reference
PSI_MAX = 0.95 * np.pi


class ElementRotationError(ValueError):
    """An element rotates too much between its nodes for the local chart."""


@dataclass
class LocalCoordinates:
    """Co-rotated nodal coordinates of every element (arrays over elements)."""
    Rr: np.ndarray     # (ne, 3, 3) reference rotation R_r
    rho: np.ndarray    # (ne, 4, 3) local positions  R_r^T r_I
    psi: np.ndarray    # (ne, 4, 3) local rotation vectors log(R_r^T R_I)


def local_coordinates(r_el, R_el):
    """Local coordinates of elements from nodal positions ``(ne, 4, 3)`` and
    rotations ``(ne, 4, 3, 3)``.

    Raises :class:`ElementRotationError` if a node is rotated by more than
    :data:`PSI_MAX` relative to its element's reference node.
    """
    Rr = R_el[:, REF_NODE]
    RrT = np.swapaxes(Rr, -1, -2)
    psi = logm(RrT[:, None] @ R_el)
    rho = np.einsum("eij,eIj->eIi", RrT, r_el)
    ang = np.linalg.norm(psi, axis=-1).max(axis=1)
    bad = np.flatnonzero(ang > PSI_MAX)
    if bad.size:
        raise ElementRotationError(
            f"element(s) {bad[:5].tolist()} rotate by up to "
            f"{ang[bad].max():.3f} rad between nodes (allowed < {PSI_MAX:.3f} "
            "rad); refine the mesh (n_elements) or take smaller load steps")
    return LocalCoordinates(Rr=Rr, rho=rho, psi=psi)


def interpolate(loc, N, dN):
    """Fields at points: ``psi``, ``psi'``, ``rho'`` of shape ``(ne, nq, 3)``.

    ``N`` and ``dN`` are ``(ne, nq, 4)`` shape functions and their arclength
    derivatives at the points.
    """
    psi = np.einsum("eqI,eIi->eqi", N, loc.psi)
    dpsi = np.einsum("eqI,eIi->eqi", dN, loc.psi)
    drho = np.einsum("eqI,eIi->eqi", dN, loc.rho)
    return psi, dpsi, drho


def strains(psi, dpsi, drho):
    """Material strains ``eps = (v, u)`` (``(..., 6)``) and ``Lambda``."""
    eps, Lam, _ = _strains(psi, dpsi, drho, None)
    return eps, Lam


def _strains(psi, dpsi, drho, coef):
    """:func:`strains` and ``T(psi)^T``, from the :func:`coefficients` of
    ``psi`` when given."""
    Lam = expm(psi)
    Tt = np.swapaxes(tangent(psi, coef), -1, -2)
    v = np.einsum("...ji,...j->...i", Lam, drho)
    u = np.einsum("...ij,...j->...i", Tt, dpsi)
    return np.concatenate([v, u], axis=-1), Lam, Tt


@dataclass
class PointState:
    """Everything the weak form needs at a set of points."""
    eps: np.ndarray    # (..., 6) strains (v, u)
    S: np.ndarray      # (..., 6) material resultants (N, M) = C (eps - eps0)
    W: np.ndarray      # (...)   energy density
    A: np.ndarray      # (..., 6, 9) d eps / d z
    G: np.ndarray      # (..., 9, 9) S . d^2 eps / d z^2
    Lam: np.ndarray    # (..., 3, 3) local rotation exp(psi)


def point_state(psi, dpsi, drho, eps0, C, second=True):
    """Strains, resultants, energy density, ``A`` and (optionally) ``G``.

    This is the single kinematics helper: the residual uses ``A^T S``, the
    tangent ``A^T C A + G``, the energy ``W``.  ``C`` is the ``6 x 6``
    section stiffness (order ``v1, v2, v3, u1, u2, u3``).
    """
    # T(psi) and its derivatives at -psi share these (they depend on |psi|)
    coef = coefficients(psi, 2 if second else 1)
    eps, Lam, Tt = _strains(psi, dpsi, drho, coef)
    de = eps - eps0
    S = de @ C.T
    W = 0.5 * np.einsum("...i,...i->...", de, S)
    v = eps[..., :3]
    shape = psi.shape[:-1]
    A = np.zeros(shape + (6, 9))
    A[..., :3, 0:3] = np.swapaxes(Lam, -1, -2)
    A[..., :3, 3:6] = hat(v) @ Tt
    # u = T(-psi) psi'  =>  du/dpsi a = -DT(-psi)[a] psi'
    A[..., 3:, 3:6] = -dtangent_matrix(-psi, dpsi, coef)
    A[..., 3:, 6:9] = Tt
    G = None
    if second:
        Nm, Mm = S[..., :3], S[..., 3:]
        G = np.zeros(shape + (9, 9))
        # N . d2v: mixed (rho', psi) and (psi, psi)
        G_rp = -Lam @ hat(Nm) @ Tt
        G[..., 0:3, 3:6] = G_rp
        G[..., 3:6, 0:3] = np.swapaxes(G_rp, -1, -2)
        G_pp = (np.swapaxes(Tt, -1, -2) @ hat(Nm) @ hat(v) @ Tt
                - dtangent_form(-psi, cross(Nm, v), coef))
        # M . d2u: (psi, psi) and (psi', psi)
        G_pp = G_pp + d2tangent_form(-psi, Mm, dpsi, coef)
        G[..., 3:6, 3:6] = G_pp          # symmetric (checked in tests)
        Q = -dtangent_form(-psi, Mm, coef)    # rows psi', cols psi
        G[..., 6:9, 3:6] = Q
        G[..., 3:6, 6:9] = np.swapaxes(Q, -1, -2)
    return PointState(eps=eps, S=S, W=W, A=A, G=G, Lam=Lam)


class Chart(NamedTuple):
    """The element chart of :func:`chart`: ``B`` ``(ne, 24, 24)``, the
    matrices ``P_I = T(psi_I)^{-1} R_r^T`` and ``T(psi_I)^{-1}`` itself
    ``(ne, 4, 3, 3)`` (:func:`chart_curvature` reads both)."""
    B: np.ndarray
    P: np.ndarray
    Tinv: np.ndarray


def chart(loc):
    """Map from element dofs ``y = (r_I, w_I)`` (spatial positions and
    spins) to local dofs ``x = (rho_I, psi_I)``: ``delta x = B delta y``.

    Returns a :class:`Chart`: ``B`` in the local dof order ``6 I + c``
    (``c`` = 0..2 position / local position, 3..5 spin / psi), ``P`` and
    ``Tinv``.
    """
    ne = loc.Rr.shape[0]
    a = REF_NODE
    RrT = np.swapaxes(loc.Rr, -1, -2)
    Tinv = tangent_inv(loc.psi)
    P = Tinv @ RrT[:, None]
    B = np.zeros((ne, 24, 24))
    for I in range(4):                       # 4 nodes: a fixed, tiny loop
        B[:, 6 * I:6 * I + 3, 6 * I:6 * I + 3] = RrT
        B[:, 6 * I:6 * I + 3, 6 * a + 3:6 * a + 6] += hat(loc.rho[:, I]) @ RrT
        if I != a:
            B[:, 6 * I + 3:6 * I + 6, 6 * I + 3:6 * I + 6] = P[:, I]
            B[:, 6 * I + 3:6 * I + 6, 6 * a + 3:6 * a + 6] = -P[:, I]
    return Chart(B, P, Tinv)


def chart_curvature(loc, ch, g):
    """Second-order term of the chart: ``G[i, j] = g . d(B_row)/dy_j`` for the
    multiplicative update, with ``g`` the element gradient in local dofs
    ``(ne, 24)`` and ``ch`` the :class:`Chart` of ``loc``.  Returns
    ``(ne, 24, 24)`` (rows: test, cols: increment).

    Per node ``I`` (all four at once; ``a`` the reference node, spins
    ``w_a``), with ``G_I = R_r g_rho,I``:
    ``[rho_I, w_a] -= hat(G_I)``, ``[w_a, rho_I] += hat(G_I)``, ``[w_a, w_a]
    += R_r hat(g_rho,I) hat(rho_I) R_r^T - hat(R_r (g_rho,I x rho_I))``;
    and for ``I != a``, with ``h_I = T_I^{-T} g_psi,I``, ``H_I = R_r h_I``
    and ``M_I = -P_I^T Q(psi_I, h_I) P_I`` (:func:`dtangent_form`):
    ``[w_I, w_I] += M_I``, ``[w_I, w_a] -= M_I + hat(H_I)``, ``[w_a, w_I] -=
    M_I``, ``[w_a, w_a] += M_I + hat(H_I)``.
    """
    ne = loc.Rr.shape[0]
    a = REF_NODE
    Rr = loc.Rr
    RrT = np.swapaxes(Rr, -1, -2)
    Gc = np.zeros((ne, 24, 24))
    G5 = Gc.reshape(ne, 4, 6, 4, 6)                 # [e, I, row, J, col]: a view
    g6 = g.reshape(ne, 4, 6)
    g_rho = g6[:, :, :3]
    rho = loc.rho
    # the position rows and columns, every node
    HG = hat(np.einsum("eij,eIj->eIi", Rr, g_rho))   # (ne, 4, 3, 3)
    G5[:, :, :3, a, 3:] -= HG
    G5[:, a, 3:, :, :3] += np.swapaxes(HG, 1, 2)
    waa = (Rr @ np.einsum("eIij,eIjk->eik", hat(g_rho), hat(rho)) @ RrT
           - hat(np.einsum("eij,ej->ei", Rr, cross(g_rho, rho).sum(axis=1))))
    # the spin rows and columns, the nodes other than a
    o = NOT_REF
    h = np.einsum("eIji,eIj->eIi", ch.Tinv[:, o], g6[:, o, 3:])
    HH = hat(np.einsum("eij,eIj->eIi", Rr, h))
    coef = coefficients(loc.psi[:, o], 1)
    PI = ch.P[:, o]
    M = -np.swapaxes(PI, -1, -2) @ dtangent_form(loc.psi[:, o], h, coef) @ PI
    G5[:, o, 3:, o, 3:] += np.swapaxes(M, 0, 1)     # two index arrays: their axis first
    G5[:, :, :, a][:, o, 3:, 3:] -= M + HH          # column node a: a view first
    Ga = G5[:, a]                                   # [e, row, J, col]: a view
    Ga[:, 3:, o, 3:] -= np.swapaxes(M, 1, 2)
    Ga[:, 3:, a, 3:] += waa + (M + HH).sum(axis=1)
    return Gc
