"""Assembly of the internal work: element arrays vectorized over elements
and quadrature points, scattered into one sparse matrix.

The integrand is the one of :mod:`skfem_rod.forms` (the scikit-fem forms that
define the internal work); this module evaluates it for all 24 x 24 element
couplings at once instead of scikit-fem's loop over basis-function pairs,
which is ~40x faster for this 6-field element (see benchmarks/RESULTS.md).
``tests/test_forms.py`` checks that both give the same vector and matrix.

Local dof order ``x = 6 I + 3 t + c``: node ``I`` (scikit-fem order), type
``t`` (0: ``rho``, 1: ``psi``), component ``c``.
"""
from dataclasses import dataclass

import numpy as np

from .kinematics import (local_coordinates, interpolate, point_state, chart,
                         chart_curvature)


def shape_operator(mesh):
    """``(ne, nq, 3, 8)`` map from local nodal values (node ``I``, type ``t``)
    to the point fields ``z = (rho', psi, psi')``, per component."""
    ne, nq = mesh.dx.shape
    Z = np.zeros((ne, nq, 3, 4, 2))
    Z[:, :, 0, :, 0] = mesh.dN      # rho' from rho_I
    Z[:, :, 1, :, 1] = mesh.N       # psi  from psi_I
    Z[:, :, 2, :, 1] = mesh.dN      # psi' from psi_I
    return Z.reshape(ne, nq, 3, 8)


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
    dx = mesh.dx
    # gradient in local dofs: g = sum_q dx Z^T A^T S
    AtS = np.einsum("eqai,eqa->eqi", ps.A, ps.S).reshape(ne, nq, 3, 3)
    g = np.einsum("eq,eqkm,eqkc->emc", dx, Z, AtS).reshape(ne, 24)
    B, P = chart(loc)
    fe = np.einsum("eji,ej->ei", B, g)
    energy = float(np.sum(dx * ps.W))
    K = None
    if tangent:
        K9 = np.einsum("eqai,ab,eqbj->eqij", ps.A, C, ps.A) + ps.G
        K9 = (K9 * dx[..., None, None]).reshape(ne, nq, 3, 3, 3, 3)
        H = np.einsum("eqkm,eqkcld,eqln->emcnd", Z, K9, Z,
                      optimize=True).reshape(ne, 24, 24)
        Ke = np.swapaxes(B, 1, 2) @ H @ B + chart_curvature(loc, P, g)
        K = mesh.assemble_matrix(Ke)
    return InternalWork(force=mesh.assemble_vector(fe), matrix=K, energy=energy,
                        max_local_rotation=float(np.linalg.norm(loc.psi, axis=-1).max()))


def roundoff_force_scale(mesh, r, R, eps0, C, Z=None):
    """Norm of the nodal forces that a unit error in every strain component
    would produce: machine epsilon times this is the round-off floor of the
    assembled residual (stiff axial and shear terms set it, not the loads)."""
    if Z is None:
        Z = shape_operator(mesh)
    loc = local_coordinates(r[mesh.nodes], R[mesh.nodes])
    psi, dpsi, drho = interpolate(loc, mesh.N, mesh.dN)
    ps = point_state(psi, dpsi, drho, eps0, C, second=False)
    ne, nq = mesh.dx.shape
    unit = np.abs(C).sum(axis=1)
    AtS = np.einsum("eqai,a->eqi", np.abs(ps.A), unit).reshape(ne, nq, 3, 3)
    g = np.einsum("eq,eqkm,eqkc->emc", mesh.dx, np.abs(Z), AtS).reshape(ne, 24)
    B, _ = chart(loc)
    return float(np.linalg.norm(mesh.assemble_vector(np.einsum("eji,ej->ei", np.abs(B), g))))
