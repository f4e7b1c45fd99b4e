"""Names that say what they do: Section stiffnesses by keyword only (the
positional order EA, GA1, GA2 differs from the matrix order GA1, GA2, EA),
and scalar-in scalar-out queries of a result."""
import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry


def test_section_stiffnesses_are_keyword_only():
    sec = Section(EA=3.0, GA1=1.0, GA2=2.0, EI1=4.0, EI2=5.0, GJ=6.0)
    assert np.array_equal(sec.C.diagonal(), [1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    with pytest.raises(TypeError, match=r"by keyword.*Section\(EA=\.\.\., GA1="):
        Section(3.0, 1.0, 2.0, 4.0, 5.0, 6.0)
    with pytest.raises(TypeError, match="1 positional"):
        Section(3.0, GA1=1.0, GA2=2.0, EI1=4.0, EI2=5.0, GJ=6.0)
    C = np.diag([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    sec = Section.from_matrix(C)
    assert (sec.EA, sec.GA1, sec.GA2, sec.EI1, sec.EI2, sec.GJ) == (3, 1, 2, 4, 5, 6)


def test_scalar_queries_return_one_point():
    rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
    res = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
    assert res.position(1.0).shape == (3,)
    assert res.frame(1.0).shape == (3, 3)
    assert res.position([1.0]).shape == (1, 3)
    assert res.position(np.float64(0.5)).shape == (3,)
    both = res.evaluate([0.3, 1.0])
    one = res.evaluate(1.0)
    for key, value in both.items():
        assert np.array_equal(one[key], value[1]), key
