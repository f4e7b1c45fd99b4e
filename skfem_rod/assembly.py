"""Assembly of the internal work: element arrays vectorized over elements
and quadrature points, scattered into one sparse matrix.

The integrand is the one of :mod:`skfem_rod.forms` (the scikit-fem forms that
define the internal work); this module evaluates it for all 24 x 24 element
couplings at once instead of scikit-fem's loop over basis-function pairs,
which is ~40x faster for this 6-field element (see benchmarks/RESULTS.md).
``tests/test_forms.py`` checks that both give the same vector and matrix.

Local dof order ``x = 6 I + 3 t + c``: node ``I`` (scikit-fem order), type
``t`` (0: ``rho``, 1: ``psi``), component ``c``.  The kernels are batched
``matmul`` over (element, point) pairs: ``g = sum_q dx Z^T A^T S``,
``H = sum_q dx Z^T (A^T C A + G) Z``, then ``f = B^T g``,
``K = B^T H B + G_chart`` (see :mod:`skfem_rod.kinematics`).
"""
from dataclasses import dataclass

import numpy as np

from .kinematics import (local_coordinates, interpolate, point_state, chart,
                         chart_curvature)


def shape_operator(mesh):
    """``(ne, nq, 9, 24)`` map from local element dofs ``x`` to the point
    fields ``z = (rho', psi, psi')``: ``z = Z x`` (cached on the mesh)."""
    Z = getattr(mesh, "_shape_operator", None)
    if Z is None:
        ne, nq = mesh.dx.shape
        z = np.zeros((ne, nq, 3, 4, 2))
        z[:, :, 0, :, 0] = mesh.dN      # rho' from rho_I
        z[:, :, 1, :, 1] = mesh.N       # psi  from psi_I
        z[:, :, 2, :, 1] = mesh.dN      # psi' from psi_I
        # kinds (k) x nodes/types (m), times the 3 x 3 identity per component
        Z = np.einsum("eqkm,cd->eqkcmd", z.reshape(ne, nq, 3, 8),
                      np.eye(3)).reshape(ne, nq, 9, 24)
        mesh._shape_operator = Z
    return Z


@dataclass
class InternalWork:
    """Internal force vector, tangent and energy of one configuration."""
    force: np.ndarray        # (n_dofs,) internal virtual work per dof
    matrix: object           # scipy CSC tangent, or None
    energy: float            # strain energy
    max_local_rotation: float


def reference_strains(mesh, r0, R0, C):
    """Strains of the (discrete) stress-free configuration at quadrature
    points, ``(ne, nq, 6)``: the interpolated reference is exactly unstressed."""
    loc = local_coordinates(r0[mesh.nodes], R0[mesh.nodes])
    psi, dpsi, drho = interpolate(loc, mesh.N, mesh.dN)
    return point_state(psi, dpsi, drho, 0.0, C, second=False).eps


def internal_work(mesh, r, R, eps0, C, tangent=True, Z=None):
    """Assemble the internal work at nodal positions ``r`` ``(n_nodes, 3)``
    and rotations ``R`` ``(n_nodes, 3, 3)``.

    Returns :class:`InternalWork`.  The tangent is the consistent
    linearization for the multiplicative spin update ``R <- exp(w) R``.
    """
    if Z is None:
        Z = shape_operator(mesh)
    loc = local_coordinates(r[mesh.nodes], R[mesh.nodes])
    psi, dpsi, drho = interpolate(loc, mesh.N, mesh.dN)
    ps = point_state(psi, dpsi, drho, eps0, C, second=tangent)
    ne, nq = mesh.dx.shape
    dx = mesh.dx[..., None, None]
    Zs = Z.reshape(ne, nq * 9, 24)                             # points stacked
    # gradient in local dofs: g = sum_q dx Z^T A^T S
    AtS = (dx * (np.swapaxes(ps.A, -1, -2) @ ps.S[..., None])).reshape(ne, nq * 9, 1)
    g = (np.swapaxes(Zs, 1, 2) @ AtS)[..., 0]                  # (ne, 24)
    ch = chart(loc)
    B = ch.B
    fe = (np.swapaxes(B, 1, 2) @ g[..., None])[..., 0]
    energy = float(np.sum(mesh.dx * ps.W))
    K = None
    if tangent:
        K9 = np.swapaxes(ps.A, -1, -2) @ (C @ ps.A) + ps.G      # (ne, nq, 9, 9)
        H = np.swapaxes(Zs, 1, 2) @ (dx * (K9 @ Z)).reshape(ne, nq * 9, 24)
        Ke = np.swapaxes(B, 1, 2) @ H @ B + chart_curvature(loc, ch, g)
        K = mesh.assemble_matrix(Ke)
    return InternalWork(force=mesh.assemble_vector(fe), matrix=K, energy=energy,
                        max_local_rotation=float(np.linalg.norm(loc.psi, axis=-1).max()))
