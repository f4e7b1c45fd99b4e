"""Supports in any direction (Rod.support_basis): a rotated problem with
supports along skew axes gives the rotated solution of the axis-aligned one
(positions, frames, reactions), with load stepping and with arc-length
continuation; bad bases are rejected with a clear message."""
import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.rotations import expm

SEC = Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=2.0, GJ=0.8, radius=0.01)
Q0 = expm(np.array([0.4, -0.7, 1.1]))        # a skew rotation


def _problem(Q, method="newton"):
    """Cantilever along Q e_x (frames rotated by Q), clamped at the start;
    the end slides on the plane normal to Q e_z (held along it) and its
    rotation about Q e_y is held; axial, transverse and twisting loads at
    the end."""
    rod = Rod(geometry.straight(1.0, direction=Q[:, 0], d1=Q[:, 1]), SEC, 8)
    rod.clamp("start")
    rod.support_basis("end", Q).pin("end", [2]).fix_rotation("end", [1])
    rod.add_force("end", Q @ [0.3, 0.8, 0.5])
    rod.add_moment("end", Q @ [0.2, 0.0, 0.0])
    kw = dict(method="arclength") if method == "arclength" else {}
    return rod, rod.solve(4, **kw)


@pytest.mark.parametrize("method", ["newton", "arclength"])
def test_rotated_supports_give_the_rotated_solution(method):
    rod_a, res_a = _problem(np.eye(3), method)
    rod_b, res_b = _problem(Q0, method)
    assert res_a.converged and res_b.converged
    ra, rb = res_a.steps[-1].r, res_b.steps[-1].r
    # the axis-aligned solution is not trivial: the end moved and turned
    assert np.abs(ra[rod_a.node("end")] - [1, 0, 0]).max() > 0.1
    assert np.abs(rb - ra @ Q0.T).max() < 1e-10
    Ra, Rb = res_a.steps[-1].R, res_b.steps[-1].R
    assert np.abs(Rb - Q0 @ Ra).max() < 1e-10
    # the end stays on the plane normal to Q0 e_z (held along it)
    e = rb[rod_b.node("end")]
    assert abs(e @ Q0[:, 2]) < 1e-12
    for where in ("start", "end"):
        fa, ma = res_a.reaction(where)
        fb, mb = res_b.reaction(where)
        assert np.abs(fb - Q0 @ fa).max() < 1e-8
        assert np.abs(mb - Q0 @ ma).max() < 1e-8


def test_skew_prescribed_rotation_and_displacement():
    """Prescribed motions in a skew basis: the end of a straight rod along
    Q0 e_x is moved by 0.01 along Q0 e_x (stretch) and turned by 0.3 rad about
    it: end force EA * 0.01 along the axis, end moment GJ 0.3 about it."""
    rod = Rod(geometry.straight(1.0, direction=Q0[:, 0], d1=Q0[:, 1]), SEC, 4)
    rod.clamp("start")
    rod.support_basis("end", Q0).prescribe_displacement("end", [0.01, 0.0, 0.0])
    rod.prescribe_rotation("end", 0.3 * Q0[:, 0])
    res = rod.solve(2)
    assert res.converged
    f, m = res.reaction("end")
    assert np.allclose(f, SEC.EA * 0.01 / (1.0) * Q0[:, 0], rtol=0, atol=1e-3 * SEC.EA * 0.01)
    assert np.allclose(m, SEC.GJ * 0.3 * Q0[:, 0], atol=1e-9)
    end = res.steps[-1].r[rod.node("end")]
    assert np.allclose(end, 1.01 * Q0[:, 0], atol=1e-12)


def test_rigid_mode_check_uses_the_basis():
    """Held only along a skew axis at both ends, a straight rod along that
    axis still rotates freely: the check names the free modes."""
    n = Q0[:, 0]
    rod = Rod(geometry.straight(1.0, direction=n), SEC, 2)
    rod.support_basis("start", Q0).pin("start").fix_rotation("start", [0])
    rod.support_basis("end", Q0).pin("end", [1, 2])
    rod.check_constraints()                         # fully held: no error
    rod2 = Rod(geometry.straight(1.0, direction=n), SEC, 2)
    rod2.support_basis("start", Q0).pin("start")
    rod2.support_basis("end", Q0).pin("end", [1, 2])
    with pytest.raises(ValueError, match="rotation about axis"):
        rod2.check_constraints()


@pytest.mark.parametrize("basis, match", [
    (np.eye(2), "3 x 3"),
    (np.full((3, 3), np.nan), "finite"),
    (2 * np.eye(3), "orthonormal"),
])
def test_bad_basis_is_rejected(basis, match):
    rod = Rod(geometry.straight(1.0), SEC, 2)
    with pytest.raises(ValueError, match=match):
        rod.support_basis("end", basis)
