"""Tests of the reference solutions in :mod:`skfem_rod.analytic`."""
import doctest

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from skfem_rod import analytic
from skfem_rod.analytic import (elastica_cantilever, elastica_tip_elliptic,
                                greenhill_critical_moment, rollup,
                                twist_torque)


# ---------------------------------------------------------------- roll-up
@pytest.mark.parametrize("kappa", [0.0, 1e-9, 0.3, -2.0, np.pi, 2 * np.pi])
def test_rollup_matches_direct_integration(kappa):
    L, EI = 1.0, 2.5
    s = np.linspace(0.0, L, 41)
    ref = solve_ivp(lambda t, z: [np.cos(kappa * t), np.sin(kappa * t)],
                    (0.0, L), [0.0, 0.0], t_eval=s, rtol=1e-13, atol=1e-15)
    r = rollup(L, EI, kappa * EI, s)
    assert r.kappa == pytest.approx(kappa, abs=1e-15)
    np.testing.assert_allclose(r.x, ref.y[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.y, ref.y[1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.theta, kappa * s, rtol=0, atol=1e-15)


def test_rollup_full_circle_closes():
    L, EI = 3.0, 0.7
    r = rollup(L, EI, 2 * np.pi * EI / L, np.linspace(0, L, 101))
    assert abs(r.x[-1]) < 1e-14 and abs(r.y[-1]) < 1e-14
    radius = L / (2 * np.pi)
    np.testing.assert_allclose(np.hypot(r.x, r.y - radius), radius,
                               rtol=0, atol=1e-14)


def test_rollup_rejects_arclength_outside_rod():
    with pytest.raises(ValueError):
        rollup(1.0, 1.0, 1.0, [0.0, 1.5])


# ---------------------------------------------------- elastica cantilever
def test_published_values_alpha_1():
    # Mattiasson (1981) / Bisshopp & Drucker (1945), P L^2 / EI = 1
    sol = elastica_cantilever(1.0)
    assert sol.tip_v == pytest.approx(0.3017208, abs=1e-7)
    assert sol.tip_u == pytest.approx(0.0564332, abs=1e-7)
    ell = elastica_tip_elliptic(1.0)
    assert ell["v"] == pytest.approx(0.3017208, abs=1e-7)
    assert ell["u"] == pytest.approx(0.0564332, abs=1e-7)


@pytest.mark.parametrize("alpha", [1.0, 2.0, 5.0, 10.0])
def test_bvp_matches_elliptic_integrals(alpha):
    sol = elastica_cantilever(alpha)
    ell = elastica_tip_elliptic(alpha)
    assert sol.tip_error < 1e-10
    assert sol.tip_angle == pytest.approx(ell["tip_angle"], abs=1e-8)
    assert sol.tip_v == pytest.approx(ell["v"], abs=1e-8)
    assert sol.tip_u == pytest.approx(ell["u"], abs=1e-8)


def test_solution_is_scale_consistent_and_satisfies_bcs():
    # dimensional scaling: x/L, theta depend on alpha only
    alpha, L, EI = 2.0, 3.0, 0.4
    ref = elastica_cantilever(alpha)
    sol = elastica_cantilever(alpha, EI=EI, length=L)
    assert sol.force == pytest.approx(alpha * EI / L**2)
    s = np.linspace(0.0, 1.0, 11)
    np.testing.assert_allclose(sol.x(L * s) / L, ref.x(s), rtol=0, atol=1e-11)
    np.testing.assert_allclose(sol.y(L * s) / L, ref.y(s), rtol=0, atol=1e-11)
    np.testing.assert_allclose(sol.theta(L * s), ref.theta(s),
                               rtol=0, atol=1e-11)
    assert abs(sol.x(0.0)) + abs(sol.y(0.0)) + abs(sol.theta(0.0)) < 1e-12
    assert abs(sol.m(L)) < 1e-10
    # moment balance about the clamp: m(0) = P x(L)
    assert sol.m(0.0) == pytest.approx(sol.force * sol.x(L), rel=1e-10)
    # unit tangent for the inextensible rod: arclength is preserved
    ss = np.linspace(0, L, 2001)
    arc = np.sum(np.hypot(np.diff(sol.x(ss)), np.diff(sol.y(ss))))
    assert arc == pytest.approx(L, rel=1e-6)


def test_negative_load_is_mirror_image():
    a, b = elastica_cantilever(1.5), elastica_cantilever(-1.5)
    assert b.tip_v == pytest.approx(-a.tip_v, abs=1e-12)
    assert b.tip_u == pytest.approx(a.tip_u, abs=1e-12)


@pytest.mark.parametrize("EI, L", [(1.0, 1.0), (2.0, 1.5)])
def test_small_load_linear_beam_theory(EI, L):
    # Euler-Bernoulli: v = P L^3 / (3 EI), u = (P L^2/EI)^2 L / 15
    errs = []
    for alpha in (1e-2, 1e-3):
        sol = elastica_cantilever(alpha, EI=EI, length=L)
        v_lin = sol.force * L**3 / (3 * EI)
        errs.append(abs(sol.tip_v - v_lin) / v_lin)
        assert sol.tip_u == pytest.approx(alpha**2 * L / 15, rel=1e-4)
    assert errs[1] < 1e-6
    # nonlinear correction is O(alpha^2)
    assert 80 < errs[0] / errs[1] < 120


def test_small_load_timoshenko_beam_theory():
    # shear-flexible linear theory: v = P L^3 / (3 EI) + P L / GA
    EI, L, EA, GA = 2.0, 1.5, 80.0, 50.0
    for alpha in (1e-3, 1e-4):
        sol = elastica_cantilever(alpha, EA=EA, GA=GA, EI=EI, length=L)
        P = sol.force
        v_lin = P * L**3 / (3 * EI) + P * L / GA
        assert sol.tip_v == pytest.approx(v_lin, rel=2e-6 * (alpha / 1e-3)**2)


def test_equal_axial_and_shear_stiffness_shifts_elastica():
    # EA == GA: r' = d + n / EA, i.e. the elastica plus P s / EA in y
    alpha, k = 2.0, 37.0
    ref = elastica_cantilever(alpha)
    sol = elastica_cantilever(alpha, EA=k, GA=k)
    s = np.linspace(0, 1, 9)
    np.testing.assert_allclose(sol.theta(s), ref.theta(s), rtol=0, atol=1e-11)
    np.testing.assert_allclose(sol.x(s), ref.x(s), rtol=0, atol=1e-11)
    np.testing.assert_allclose(sol.y(s), ref.y(s) + alpha * s / k,
                               rtol=0, atol=1e-11)


def _reissner_tip_by_quadrature(alpha, EA, GA, nquad=120):
    """Tip of the extensible, shearable cantilever (EI = L = 1) from the
    first integral of the moment equation, by quadrature.

    Independent of the module's formulation: with n = (0, P),
    N = P sin(th), Q = P cos(th), eps = N/EA, gamma = Q/GA,
    r' = (1 + eps) d + gamma e, and m' = -P x'.  Multiplying
    th'' = -P x'(th) by th' and using th'(1) = 0:
    th'^2 / 2 = P (G(phi0) - G(th)),  G(th) = int_0^th x'(t) dt
              = sin th + (1/EA - 1/GA) P sin^2(th) / 2.
    Substituting th = phi0 - t^2 removes the endpoint singularity.
    """
    P = alpha

    def xp(th):
        eps, gam = P * np.sin(th) / EA, P * np.cos(th) / GA
        return (1 + eps) * np.cos(th) - gam * np.sin(th)

    def yp(th):
        eps, gam = P * np.sin(th) / EA, P * np.cos(th) / GA
        return (1 + eps) * np.sin(th) + gam * np.cos(th)

    def dsdt(t, phi0):
        # G(phi0) - G(phi0 - t^2), written without cancellation
        dG = (2 * np.cos(phi0 - t**2 / 2) * np.sin(t**2 / 2)
              + 0.5 * P * (1 / EA - 1 / GA)
              * np.sin(2 * phi0 - t**2) * np.sin(t**2))
        return 2 * t / np.sqrt(2 * P * dG)        # |d th/dt| / th'

    # the integrand is analytic in t: Gauss-Legendre converges exponentially
    xi, w = np.polynomial.legendre.leggauss(nquad)

    def integral(f, phi0):
        t = 0.5 * np.sqrt(phi0) * (xi + 1)
        return 0.5 * np.sqrt(phi0) * np.sum(w * f(phi0 - t**2) * dsdt(t, phi0))

    phi0 = brentq(lambda p: integral(np.ones_like, p) - 1.0, 1e-3,
                  np.pi / 2 - 1e-9, xtol=1e-15, rtol=1e-15)
    return phi0, 1.0 - integral(xp, phi0), integral(yp, phi0)


@pytest.mark.parametrize("alpha, EA, GA", [(2.0, 5.0, 3.0), (3.0, 4.0, 10.0)])
def test_extensible_shearable_matches_quadrature(alpha, EA, GA):
    phi0, u, v = _reissner_tip_by_quadrature(alpha, EA, GA)
    # the quadrature itself is converged
    np.testing.assert_allclose(_reissner_tip_by_quadrature(alpha, EA, GA, 60),
                               (phi0, u, v), rtol=0, atol=1e-13)
    sol = elastica_cantilever(alpha, EA=EA, GA=GA)
    assert sol.tip_angle == pytest.approx(phi0, abs=1e-9)
    assert sol.tip_u == pytest.approx(u, abs=1e-9)
    assert sol.tip_v == pytest.approx(v, abs=1e-9)
    # the strains are not small here: the answer differs from the elastica
    assert abs(sol.tip_v - elastica_cantilever(alpha).tip_v) > 1e-2


def test_extensible_tends_to_inextensible_like_one_over_EA():
    alpha = 2.0
    ref = elastica_cantilever(alpha)
    scaled = []
    for lam in (1e3, 1e4, 1e5):
        sol = elastica_cantilever(alpha, EA=lam, GA=lam / 2.6)
        diff = np.array([sol.tip_u - ref.tip_u, sol.tip_v - ref.tip_v,
                         sol.tip_angle - ref.tip_angle])
        scaled.append(lam * diff)
    scaled = np.array(scaled)
    # lam * difference converges to a nonzero first-order coefficient
    assert np.all(np.abs(scaled[-1]) > 1e-2)
    np.testing.assert_allclose(scaled[1], scaled[2], rtol=2e-3)
    assert (np.max(np.abs(scaled[1] - scaled[2]))
            < 0.2 * np.max(np.abs(scaled[0] - scaled[1])))


def test_elliptic_rejects_nonpositive_load():
    with pytest.raises(ValueError):
        elastica_tip_elliptic(0.0)


# ------------------------------------------------------------ closed forms
def test_greenhill_and_twist():
    assert greenhill_critical_moment(3.0, 12.0) == pytest.approx(12.0)
    assert greenhill_critical_moment(1.0, 0.0) == 0.0
    assert twist_torque(4.0, 0.5, 2.0) == pytest.approx(1.0)


def test_docstring_examples():
    res = doctest.testmod(analytic, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert res.attempted > 0 and res.failed == 0


# -- localized writhing (the localizing helix of a clamped rod) ----------------
def test_localized_writhing_relations_and_curve():
    """PyElastica's helical buckling case (B = 1.345, C = 0.789, L = 100,
    slack 3, 27 turns): the end conditions solved for (m, tau) give the
    values its authors obtained with a different solver (vpasolve of the same
    two equations: m = 98.541496171190744, tau = 2900.993205792131), and the
    centreline of the localizing helix is consistent with them: arclength
    parametrized (length L), ends on the axis at the slack, largest tangent
    angle theta_max, and writhe 2 arccos(c) / pi turns (the rotation not
    taken up by twist, Calugareanu-White), computed here from the curve by
    the exact polygon Gauss integral of skfem_rod.topology."""
    from skfem_rod.analytic import localized_writhing
    from skfem_rod.topology import closure, writhe
    L, D, R = 100.0, 3.0, 27 * 2 * np.pi
    w = localized_writhing(1.345, 0.789, L, D, R)
    assert w.m == pytest.approx(98.541496171190744, rel=1e-12)
    assert w.tau == pytest.approx(2.900993205792131e3, rel=1e-12)
    s = np.linspace(0.0, L, 40001)
    p = w.position(s)
    seg = np.diff(p, axis=0)
    assert np.linalg.norm(seg, axis=1).sum() == pytest.approx(L, rel=1e-8)
    np.testing.assert_allclose(p[-1] - p[0], [0, 0, L - D], atol=1e-4)   # exp(-10.9) ends
    t = seg / np.linalg.norm(seg, axis=1)[:, None]
    assert np.arccos(t[:, 2].min()) == pytest.approx(w.theta_max, rel=1e-6)
    # twist share + writhe share = the applied turns
    assert w.m / (0.789 / 1.345) + 4 * np.arccos(w.c) == pytest.approx(R, rel=1e-13)
    pts = p[::20]
    d1 = np.cross(np.gradient(pts, axis=0), [1.0, 0.0, 0.0])
    d1 /= np.linalg.norm(d1, axis=1)[:, None]
    c = closure(pts, d1)
    assert writhe(c.points, closed=True) == pytest.approx(2 * np.arccos(w.c) / np.pi,
                                                          abs=2e-4)


@pytest.mark.parametrize("kw, name", [(dict(B=-1.0), "B"), (dict(shortening=0.0), "shortening"),
                                      (dict(rotation=np.inf), "rotation")])
def test_localized_writhing_refuses_bad_input(kw, name):
    from skfem_rod.analytic import localized_writhing
    args = dict(B=1.345, C=0.789, length=100.0, shortening=3.0, rotation=27 * 2 * np.pi)
    args.update(kw)
    with pytest.raises(ValueError, match=name):
        localized_writhing(**args)
