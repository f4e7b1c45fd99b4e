"""Supports (prescribed displacement, pins) and curved reference shapes
(helix, polyline) against exact small-load and geometric results."""
import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry

SEC = Section(EA=1e4, GA1=2e3, GA2=2e3, EI1=1.0, EI2=1.0, GJ=0.8)


def test_prescribed_axial_displacement_gives_exact_axial_force():
    """A straight rod stretched by a prescribed end displacement: uniform
    strain, N = EA delta / L exactly (no linearization involved)."""
    L, delta = 2.0, 0.01
    rod = Rod(geometry.straight(L), SEC, 4)
    rod.clamp("start").prescribe_displacement("end", [delta, 0, 0]).fix_rotation("end")
    res = rod.solve(n_steps=1)
    assert res.converged, res.message
    force, moment = res.reaction("end")
    assert force[0] == pytest.approx(SEC.EA * delta / L, rel=1e-12)   # support pulls outward
    assert np.abs(force[1:]).max() < 1e-10 and np.abs(moment).max() < 1e-10
    n = res.evaluate(np.linspace(0, L, 9))["n"]
    np.testing.assert_allclose(n[:, 0], SEC.EA * delta / L, rtol=1e-12)


@pytest.mark.parametrize("w", [1e-4, 1e-5])
def test_guided_transverse_displacement_matches_timoshenko(w):
    """Clamped start, end moved sideways by w with its rotation held:
    F = 12 EI w / (L^3 (1 + 12 EI / (GA L^2))) to O(w^2)."""
    L = 1.0
    rod = Rod(geometry.straight(L), SEC, 4)
    rod.clamp("start").prescribe_displacement("end", [0, w, 0]).fix_rotation("end")
    res = rod.solve(n_steps=1)
    F = res.reaction("end")[0][1]          # the support pushes the end along +y
    exact = 12 * SEC.EI2 * w / (L**3 * (1 + 12 * SEC.EI2 / (SEC.GA1 * L**2)))
    assert F == pytest.approx(exact, rel=50 * w)


def test_pinned_beam_midspan_load():
    """Simply supported (pins, rotations free, axial end free, twist held at
    one end): midspan deflection P L^3/(48 EI) + P L/(4 GA) for small P."""
    L, P = 1.0, 1e-4
    rod = Rod(geometry.straight(L), SEC, 4)
    rod.pin("start").fix_rotation("start", components=(0,))
    rod.pin("end", components=(1, 2))
    rod.add_force(L / 2, [0, -P, 0])
    res = rod.solve(n_steps=1)
    assert res.converged, res.message
    w = -res.position(L / 2)[1]
    exact = P * L**3 / (48 * SEC.EI2) + P * L / (4 * SEC.GA1)
    assert w == pytest.approx(exact, rel=1e-3)
    assert res.reaction("start")[0][1] == pytest.approx(P / 2, rel=1e-6)


def test_helix_reference_is_stress_free_with_its_curvature_and_torsion():
    Rc, pitch = 0.3, 0.2
    c = pitch / (2 * np.pi)
    kappa, tau = Rc / (Rc**2 + c**2), c / (Rc**2 + c**2)
    rod = Rod(geometry.helix(Rc, pitch, 1.5), SEC, 12)
    rod.clamp("start")
    res = rod.solve(n_steps=1)
    assert res.converged and res.iterations[-1] <= 1          # nothing to do
    np.testing.assert_allclose(res.steps[-1].r, rod.r0, atol=1e-13)
    f = res.evaluate(np.linspace(0, rod.length, 25), step=0)
    # d1 toward the axis (principal normal), d2 binormal: u0 = (0, kappa, tau)
    # constant curvature: the objective interpolation is exact (psi linear)
    np.testing.assert_allclose(f["u0"], [[0, kappa, tau]] * 25, atol=1e-12 * kappa)
    # the P3 interpolated centreline (taken as stress free) departs from the
    # arclength parametrization by the interpolation error, O(h^3) in r'
    err = []
    for n in (12, 24, 48):
        rr = Rod(geometry.helix(Rc, pitch, 1.5), SEC, n)
        rr.clamp("start")
        f = rr.solve(n_steps=1).evaluate(np.linspace(0, rr.length, 101), step=0)
        err.append(np.abs(f["v0"] - [0, 0, 1]).max())
    rates = np.log2(np.array(err[:-1]) / np.array(err[1:]))
    assert err[0] < 1e-2 and np.all(rates > 2.8), (err, rates)


def test_polyline_reference_passes_through_its_points_and_is_stress_free():
    t = np.linspace(0, np.pi, 9)
    pts = np.stack([np.cos(t), np.sin(t), 0.1 * t], axis=1)
    shape = geometry.polyline(pts)
    r0, R0 = shape(np.array([0.0, shape.length]))
    np.testing.assert_allclose(r0, pts[[0, -1]], atol=1e-9)
    np.testing.assert_allclose(np.einsum("nji,njk->nik", R0, R0), [np.eye(3)] * 2, atol=1e-12)
    rod = Rod(shape, SEC, 10)
    rod.clamp("start")
    res = rod.solve(n_steps=1)
    assert res.converged and res.iterations[-1] <= 1
    np.testing.assert_allclose(res.steps[-1].r, rod.r0, atol=1e-13)
