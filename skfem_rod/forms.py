r"""The internal work of the rod as scikit-fem forms.

Read this module next to docs/theory.md.  In the co-rotated coordinates of
an element (:mod:`skfem_rod.kinematics`), the fields are P3 interpolations
of the local nodal values ``x = (rho_I, psi_I)``: a discontinuous P3 field
of six components.  With the generalized strain variables
``z = (rho', psi, psi')`` the paper's internal virtual work (eq. 4.1,
first integral) and its linearization (sec. 6) are

    delta W_int = int_0^l (A^T S) . delta z  ds,
    Delta delta W_int = int_0^l delta z . (A^T C A + G) Delta z  ds,

where ``S = (N, M)`` are the material stress resultants (eq. 3.5),
``A = d eps / d z`` and ``G = S . d^2 eps / d z^2`` (the geometric
stiffness); all three come from :func:`skfem_rod.kinematics.point_state`,
the one kinematics helper, and enter the forms through ``w``.

The forms are exactly what the fast assembler (:mod:`skfem_rod.assembly`)
evaluates, vectorized over all 24 x 24 element couplings at once;
``tests/test_forms.py`` checks that both give the same residual and tangent.
The last step, from local to global dofs (positions and spatial spins), is
the element chart ``B`` of :func:`skfem_rod.kinematics.chart`.
"""
import numpy as np
from skfem import BilinearForm, LinearForm, Basis, ElementDG, ElementVector, asm

from .element import ElementLineP3
from .kinematics import local_coordinates, point_state, chart, chart_curvature


def strain_variables(phi):
    """``z = (rho', psi, psi')`` of a six-component field ``(rho, psi)``:
    an array ``(9, ne, nq)``."""
    return np.concatenate([phi.grad[0:3, 0], np.asarray(phi)[3:6], phi.grad[3:6, 0]])


@LinearForm
def internal_force(v, w):
    """``int (A^T S) . delta z ds`` (``w.AtS``: ``(9, ne, nq)``)."""
    return np.einsum("i...,i...->...", w["AtS"], strain_variables(v))


@BilinearForm
def internal_stiffness(u, v, w):
    """``int delta z . (A^T C A + G) Delta z ds`` (``w.K9``: ``(9, 9, ne, nq)``)."""
    return np.einsum("i...,ij...,j...->...", strain_variables(v), w["K9"],
                     strain_variables(u))


def local_basis(mesh):
    """Discontinuous six-component P3 basis of the local coordinates."""
    return Basis(mesh.mesh, ElementDG(ElementVector(ElementLineP3(), 6)),
                 quadrature=(mesh.basis.X, mesh.basis.W))


def assemble_with_forms(mesh, r, R, eps0, C):
    """Internal force vector and tangent of a configuration assembled with
    scikit-fem's ``asm`` and the forms above (slow; for teaching and for
    checking :func:`skfem_rod.assembly.internal_work`).

    Returns ``(force, matrix)`` in global dofs.
    """
    dg = local_basis(mesh)
    ne = mesh.n_elements
    loc = local_coordinates(r[mesh.nodes], R[mesh.nodes])
    x = np.concatenate([loc.rho, loc.psi], axis=-1).reshape(ne, 24)
    xdg = np.zeros(dg.N)
    xdg[dg.element_dofs.T] = x
    field = dg.interpolate(xdg)
    mv = lambda a: np.moveaxis(a, 0, -1)
    ps = point_state(mv(np.asarray(field)[3:6]), mv(field.grad[3:6, 0]),
                     mv(field.grad[0:3, 0]), eps0, C)
    AtS = np.einsum("eqai,eqa->ieq", ps.A, ps.S)
    K9 = np.moveaxis(np.einsum("eqai,ab,eqbj->eqij", ps.A, C, ps.A) + ps.G, (2, 3), (0, 1))
    g = asm(internal_force, dg, AtS=AtS)[dg.element_dofs.T]             # (ne, 24)
    H = asm(internal_stiffness, dg, K9=K9).toarray()
    idx = dg.element_dofs.T
    He = H[idx[:, :, None], idx[:, None, :]]                              # (ne, 24, 24)
    ch = chart(loc)
    B = ch.B
    fe = np.einsum("eji,ej->ei", B, g)
    Ke = np.swapaxes(B, 1, 2) @ He @ B + chart_curvature(loc, ch, g)
    return mesh.assemble_vector(fe), mesh.assemble_matrix(Ke)
