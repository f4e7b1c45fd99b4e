"""The scikit-fem forms of the internal work and the fast vectorized
assembler evaluate the same residual and tangent."""
import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.assembly import internal_work
from skfem_rod.forms import assemble_with_forms
from skfem_rod.rotations import expm


@pytest.mark.parametrize("shape", [geometry.straight(2.0), geometry.helix(0.5, 0.3, 1.0)],
                         ids=["straight", "helix"])
def test_forms_equal_fast_assembly(shape):
    rng = np.random.default_rng(7)
    sec = Section(EA=50.0, GA1=20.0, GA2=30.0, EI1=1.0, EI2=1.5, GJ=0.8)
    rod = Rod(shape, sec, 3)
    r = rod.r0 + 0.05 * rng.normal(size=rod.r0.shape)
    R = expm(0.4 * rng.normal(size=(rod.mesh.n_nodes, 3))) @ rod.R0
    fast = internal_work(rod.mesh, r, R, rod.eps0, rod.C)
    f, K = assemble_with_forms(rod.mesh, r, R, rod.eps0, rod.C)
    assert np.linalg.norm(fast.force) > 1.0          # a genuinely loaded state
    np.testing.assert_allclose(f, fast.force, rtol=0, atol=1e-12 * np.abs(f).max())
    dK = (K - fast.matrix).toarray()
    assert np.abs(dK).max() <= 1e-12 * np.abs(K.toarray()).max()
