"""Pointwise Coulomb friction law (skfem_rod.contact.friction): the ball
projection and its derivatives, the augmented-Lagrangian force in stick,
slip and open states, exact derivatives against central differences, the
rate/increment equivalence, what dissipation is guaranteed, and Uzawa
iterations on a block pressed by f_N and pulled by a spring (translational
and rotational) against the analytic Coulomb answer."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra.numpy import arrays

from skfem_rod.contact.friction import (OPEN, SLIP, STICK, FrictionState, coulomb_violation,
                                        dissipation, friction_force, misalignment,
                                        project_ball, uzawa_update)

HYP = settings(derandomize=True, deadline=None, max_examples=300)
vec = arrays(np.float64, 3, elements=st.floats(-1e3, 1e3, allow_nan=False))
positive = st.floats(1e-4, 1e4)
nonneg = st.one_of(st.just(0.0), st.floats(1e-6, 1e3))


def _random_regime(rng, m, stick):
    """Points with ``a = g + mu lam`` a known distance inside (stick) or
    outside (slip) the ball ``mu gamma fN``: ratio ``|a| / tau`` in
    [0.1, 0.9] or [1.1, 10], away from the switch."""
    mu = 10.0 ** rng.uniform(-3, 1, m)
    gamma = rng.uniform(0.05, 1.5, m)
    a = rng.normal(size=(m, 3)) * 10.0 ** rng.uniform(-2, 1, (m, 1))
    ratio = rng.uniform(0.1, 0.9, m) if stick else rng.uniform(1.1, 10.0, m)
    tau = np.linalg.norm(a, axis=1) / ratio
    fN = tau / (mu * gamma)
    g = rng.normal(size=(m, 3)) * np.linalg.norm(a, axis=1, keepdims=True)
    lam = (a - g) / mu[:, None]
    return g, lam, mu, gamma, fN


# ---------------------------------------------------------------- projection

def test_project_ball_values_and_states():
    a = np.array([[0.3, 0.4, 0.0], [3.0, 4.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0],
                  [1.0, 0.0, 0.0]])
    tau = np.array([1.0, 1.0, 1.0, 0.0, 0.0])
    p = project_ball(a, tau)
    assert np.allclose(p.value, [[0.3, 0.4, 0], [0.6, 0.8, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0]])
    assert p.inside.tolist() == [True, False, True, False, False]
    assert np.allclose(p.d_point[0], np.eye(3)) and np.allclose(p.d_radius[0], 0)
    e = np.array([0.6, 0.8, 0.0])
    assert np.allclose(p.d_point[1], 0.2 * (np.eye(3) - np.outer(e, e)))
    assert np.allclose(p.d_radius[1], e)
    # degenerate ball {0}: the map is identically 0 in a
    assert np.all(p.d_point[3:] == 0) and np.all(p.d_radius[3] == 0)
    assert np.allclose(p.d_radius[4], [1, 0, 0])          # right derivative in tau
    # on the sphere: inside (the paper's <=), value a
    q = project_ball([[0.6, 0.8, 0.0]], 1.0)
    assert q.inside[0] and np.allclose(q.value, [[0.6, 0.8, 0.0]])


def test_project_ball_broadcasts_and_rejects_bad_input():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(4, 5, 3))
    p = project_ball(a, 0.5)
    assert p.value.shape == (4, 5, 3) and p.d_point.shape == (4, 5, 3, 3)
    assert project_ball(a[0, 0], np.array([0.1, 1.0, 10.0])).value.shape == (3, 3)
    assert project_ball(a, 0.5, derivatives=False).d_point is None
    with pytest.raises(ValueError):
        project_ball(a, -1.0)
    with pytest.raises(ValueError):
        project_ball(a, np.nan)
    with pytest.raises(ValueError):
        project_ball(np.ones((4, 2)), 1.0)


@pytest.mark.parametrize("stick", [True, False])
def test_project_ball_derivatives_central_differences(stick):
    rng = np.random.default_rng(1 if stick else 2)
    m = 300
    a = rng.normal(size=(m, 3)) * 10.0 ** rng.uniform(-3, 3, (m, 1))
    na = np.linalg.norm(a, axis=1)
    tau = na / (rng.uniform(0.1, 0.9, m) if stick else rng.uniform(1.1, 10.0, m))
    p = project_ball(a, tau)
    assert np.all(p.inside == stick)
    h = 1e-6 * na
    fd = np.empty((m, 3, 3))
    for j in range(3):
        da = np.zeros((m, 3))
        da[:, j] = h
        fd[:, :, j] = (project_ball(a + da, tau).value
                       - project_ball(a - da, tau).value) / (2 * h[:, None])
    rel = np.linalg.norm(fd - p.d_point, axis=(1, 2)) / np.linalg.norm(p.d_point, axis=(1, 2))
    assert rel.max() < 1e-7
    ht = 1e-6 * tau
    fdt = (project_ball(a, tau + ht).value - project_ball(a, tau - ht).value) / (2 * ht[:, None])
    if stick:
        assert np.all(fdt == 0) and np.all(p.d_radius == 0)
    else:
        rel = np.linalg.norm(fdt - p.d_radius, axis=1) / np.linalg.norm(p.d_radius, axis=1)
        assert rel.max() < 1e-7


# ------------------------------------------------------------------- the law

@HYP
@given(g=vec, lam=vec, mu=positive, gamma=st.one_of(st.just(0.0), st.floats(1e-6, 5.0)),
       fN=nonneg)
def test_force_bounded_and_states(g, lam, mu, gamma, fN):
    f, state, dfdg, dfdn = friction_force(g, lam, mu, gamma, fN)
    bound = gamma * fN
    assert np.linalg.norm(f) <= bound * (1 + 1e-12)
    a = g + mu * lam
    na = np.linalg.norm(a)
    if fN == 0:
        assert state == OPEN and np.all(f == 0) and np.all(dfdg == 0)
    elif na <= mu * bound and bound > 0:     # gamma = 0: frictionless, SLIP
        assert state == STICK
        assert np.allclose(f, g / mu + lam, rtol=1e-12, atol=1e-12 * (na / mu + bound))
        assert np.allclose(dfdg, np.eye(3) / mu) and np.all(dfdn == 0)
    else:
        assert state == SLIP
        assert np.isclose(np.linalg.norm(f), bound, rtol=1e-12, atol=1e-300)
        # parallel to a and in the same direction
        assert np.linalg.norm(np.cross(f, a)) <= 1e-12 * bound * na
        assert f @ a >= 0
    # the Uzawa update is the projected multiplier: lambda <- f
    assert np.array_equal(uzawa_update(g, lam, mu, gamma, fN), f)
    # always: f . (g + mu lam) >= 0 (f is a nonnegative multiple of a)
    assert f @ a >= -1e-12 * np.linalg.norm(f) * na


def test_states_are_named_and_vectorized():
    assert [FrictionState(i).name for i in (0, 1, 2)] == ["OPEN", "STICK", "SLIP"]
    g = np.array([[0.1, 0, 0], [5.0, 0, 0], [5.0, 0, 0], [0.0, 0, 0], [1.0, 0, 0]])
    fN = np.array([1.0, 1.0, 0.0, 0.0, 1.0])
    gamma = np.array([0.5, 0.5, 0.5, 0.5, 0.0])            # last: frictionless contact
    res = friction_force(g, np.zeros((5, 3)), 1.0, gamma, fN)
    assert res.state.tolist() == [STICK, SLIP, OPEN, OPEN, SLIP]
    assert res.force.shape == (5, 3) and res.dforce_dslip.shape == (5, 3, 3)
    assert res.dforce_dnormal.shape == (5, 3)
    assert np.allclose(res.force, [[0.1, 0, 0], [0.5, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0]])
    # an open point with zero slip has no stiffness (the paper's F_T(0) = 1 would give 1/mu)
    assert np.all(res.dforce_dslip[2:4] == 0) and np.all(res.dforce_dnormal[3] == 0)
    # open point with a != 0: right derivative gamma e in f_N
    assert np.allclose(res.dforce_dnormal[2], [0.5, 0, 0])


def test_bad_parameters_rejected():
    g = np.zeros((2, 3))
    for mu, gamma, fN in [(0.0, 0.3, 1.0), (-1.0, 0.3, 1.0), (1.0, -0.3, 1.0),
                          (1.0, 0.3, [1.0, -1e-3]), (1.0, np.nan, 1.0)]:
        with pytest.raises(ValueError):
            friction_force(g, g, mu, gamma, fN)
    with pytest.raises(ValueError):
        friction_force(np.zeros((2, 2)), np.zeros((2, 2)), 1.0, 0.3, 1.0)


@pytest.mark.parametrize("stick", [True, False])
def test_law_derivatives_central_differences(stick):
    rng = np.random.default_rng(10 + stick)
    g, lam, mu, gamma, fN = _random_regime(rng, 400, stick)
    res = friction_force(g, lam, mu, gamma, fN)
    assert np.all(res.state == (STICK if stick else SLIP))
    h = 1e-6 * np.linalg.norm(g + mu[:, None] * lam, axis=1)
    fd = np.empty((len(fN), 3, 3))
    for j in range(3):
        dg = np.zeros_like(g)
        dg[:, j] = h
        fd[:, :, j] = (friction_force(g + dg, lam, mu, gamma, fN).force
                       - friction_force(g - dg, lam, mu, gamma, fN).force) / (2 * h[:, None])
    J = res.dforce_dslip
    rel = np.linalg.norm(fd - J, axis=(1, 2)) / np.linalg.norm(J, axis=(1, 2))
    assert rel.max() < 1e-7
    # derivative in lambda: mu df/dg
    dl = np.zeros_like(lam)
    dl[:, 1] = h / mu
    fdl = (friction_force(g, lam + dl, mu, gamma, fN).force
           - friction_force(g, lam - dl, mu, gamma, fN).force) / (2 * (h / mu)[:, None])
    assert np.allclose(fdl, mu[:, None] * J[:, :, 1], rtol=1e-7, atol=0)
    # derivative in the normal force (through the radius mu gamma fN)
    hn = 1e-6 * fN
    fdn = (friction_force(g, lam, mu, gamma, fN + hn).force
           - friction_force(g, lam, mu, gamma, fN - hn).force) / (2 * hn[:, None])
    if stick:
        assert np.all(fdn == 0) and np.all(res.dforce_dnormal == 0)
    else:
        dn = res.dforce_dnormal
        assert np.allclose(np.linalg.norm(dn, axis=1), gamma)
        rel = np.linalg.norm(fdn - dn, axis=1) / np.linalg.norm(dn, axis=1)
        assert rel.max() < 1e-7


def test_slip_tangent_is_the_exact_formula():
    """In slip ``df/dg = (gamma fN / |a|)(I - e e^T)``: symmetric, kills e."""
    rng = np.random.default_rng(3)
    g, lam, mu, gamma, fN = _random_regime(rng, 50, stick=False)
    res = friction_force(g, lam, mu, gamma, fN)
    a = g + mu[:, None] * lam
    na = np.linalg.norm(a, axis=1)
    e = a / na[:, None]
    expect = (gamma * fN / na)[:, None, None] * (np.eye(3) - e[:, :, None] * e[:, None, :])
    assert np.allclose(res.dforce_dslip, expect, rtol=1e-12, atol=0)
    assert np.allclose(np.einsum("mij,mj->mi", res.dforce_dslip, e), 0, atol=1e-12 * fN.max())
    assert np.allclose(res.dforce_dnormal, gamma[:, None] * e)


def test_rate_form_equals_increment_form():
    """Paper: rate g/dt with compliance mu_p; here: increment g with
    mu = mu_p dt.  Same force, same state, derivative scaled by dt."""
    rng = np.random.default_rng(4)
    m = 200
    g = rng.normal(size=(m, 3))
    lam = rng.normal(size=(m, 3))
    fN = rng.uniform(0.0, 3.0, m)
    fN[:10] = 0.0
    gamma, mu_p = 0.4, 0.7
    for dt in (1e-3, 0.25, 1.0, 7.0):
        rate = friction_force(g / dt, lam, mu_p, gamma, fN)
        incr = friction_force(g, lam, mu_p * dt, gamma, fN)
        assert np.allclose(rate.force, incr.force, rtol=1e-12, atol=1e-14)
        assert np.array_equal(rate.state, incr.state)
        assert np.allclose(rate.dforce_dslip / dt, incr.dforce_dslip, rtol=1e-12, atol=1e-14)
        assert np.allclose(rate.dforce_dnormal, incr.dforce_dnormal, rtol=1e-12, atol=1e-14)


# ------------------------------------------------------------- dissipation

def test_dissipation_guarantees():
    rng = np.random.default_rng(5)
    m = 500
    g = rng.normal(size=(m, 3))
    mu, gamma = 0.3, 0.6
    fN = rng.uniform(0.1, 2.0, m)
    # pure penalty (lambda = 0): f . g >= 0
    f0 = friction_force(g, np.zeros((m, 3)), mu, gamma, fN).force
    assert np.all(dissipation(f0, g) >= 0)
    # an unconverged multiplier can give f . g < 0: not guaranteed
    g_small = 1e-3 * g
    lam_bad = -0.9 * gamma * fN[:, None] * g / np.linalg.norm(g, axis=1, keepdims=True)
    fb = friction_force(g_small, lam_bad, mu, gamma, fN).force
    assert np.all(dissipation(fb, g_small) < 0)
    # the variational inequality behind the projection holds for any lambda:
    # (g + mu (lam - f)) . (t - f) <= 0 for every admissible |t| <= gamma fN
    lam = rng.normal(size=(m, 3))
    res = friction_force(g, lam, mu, gamma, fN)
    f = res.force
    for _ in range(20):
        t = rng.normal(size=(m, 3))
        t *= (gamma * fN * rng.uniform(0, 1, m) ** (1 / 3) / np.linalg.norm(t, axis=1))[:, None]
        vi = np.einsum("mi,mi->m", g + mu * (lam - f), t - f)
        assert np.all(vi <= 1e-12 * (1 + np.abs(vi)))


def test_uzawa_fixed_point_is_coulomb_with_maximal_dissipation():
    """For a fixed slip g != 0, lambda <- P_B(gamma fN)[lambda + g/mu]
    converges to lambda = gamma fN g/|g|: there f = lambda, f is parallel to
    g, f . g = gamma fN |g| >= t . g for all admissible t."""
    rng = np.random.default_rng(6)
    m = 300
    g = rng.normal(size=(m, 3)) * 10.0 ** rng.uniform(-3, 0, (m, 1))
    mu, gamma = 0.05, 0.5
    fN = rng.uniform(0.1, 2.0, m)
    lam = rng.normal(size=(m, 3)) * 0.3                 # arbitrary start
    for _ in range(20000):
        new = uzawa_update(g, lam, mu, gamma, fN)
        done = np.abs(new - lam).max() == 0.0
        lam = new
        if done:
            break
    res = friction_force(g, lam, mu, gamma, fN)
    f = res.force
    assert np.allclose(f, lam, rtol=0, atol=1e-14)      # fixed point
    assert np.all(res.state == SLIP)
    ng = np.linalg.norm(g, axis=1)
    assert np.allclose(f, (gamma * fN / ng)[:, None] * g, rtol=1e-10, atol=0)
    D = dissipation(f, g)
    assert np.all(D >= 0) and np.allclose(D, gamma * fN * ng, rtol=1e-10)
    for _ in range(20):
        t = rng.normal(size=(m, 3))
        t *= (gamma * fN / np.linalg.norm(t, axis=1))[:, None]
        assert np.all(np.einsum("mi,mi->m", t, g) <= D * (1 + 1e-12))
    excess, gap = coulomb_violation(f, g, gamma, fN)
    assert excess.max() <= 1e-14 and np.abs(gap).max() <= 1e-10 * (gamma * fN * ng).max()


# ------------------------------------------- block pulled by a spring (Uzawa)

def _block_problem(p, x0, k, mu, gamma, fN, uzawa_tol=1e-13, max_uzawa=200):
    """A block at ``x`` (tangential position, or rotation vector) pressed by
    ``fN`` on a fixed master and pulled by a spring of stiffness ``k`` whose
    end sits at ``p``.  Slip ``g = x - x0``; the friction force on the block
    is ``-f``, so equilibrium reads ``k (p - x) = f(x - x0, lambda)``.
    Newton with the exact tangent ``df/dg + k I`` and a backtracking line
    search inside (full steps can 2-cycle between two slip states of a
    point whose answer is stick: the slip tangent has no stiffness along
    ``e``), Uzawa outside."""
    m = len(p)
    lam = np.zeros((m, 3))
    x = x0.copy()
    newton_its = []
    tol = 1e-14 * (k * np.abs(p - x0).max() + gamma * np.max(fN))

    def residual(x, lam):
        res = friction_force(x - x0, lam, mu, gamma, fN)
        return res, res.force - k * (p - x)

    for uz in range(max_uzawa):
        res, R = residual(x, lam)
        for it in range(50):
            nR = np.linalg.norm(R, axis=1)
            if nR.max() <= tol:
                break
            J = res.dforce_dslip + k * np.eye(3)
            dx = -np.linalg.solve(J, R[:, :, None])[:, :, 0]
            alpha = np.ones(m)
            for _ in range(30):
                x_t = x + alpha[:, None] * dx
                res_t, R_t = residual(x_t, lam)
                bad = (np.linalg.norm(R_t, axis=1) > (1 - 1e-4 * alpha) * nR) & (nR > tol)
                if not bad.any():
                    break
                alpha[bad] *= 0.5
            x, res, R = x_t, res_t, R_t
        newton_its.append(it)
        new = uzawa_update(x - x0, lam, mu, gamma, fN)
        step = np.abs(new - lam).max()
        lam = new
        if step <= uzawa_tol * (gamma * np.max(fN)):
            break
    return x, lam, uz + 1, max(newton_its)


def _analytic(p, x0, k, gamma, fN):
    d = p - x0
    nd = np.linalg.norm(d, axis=1)
    stick = k * nd <= gamma * fN
    f = np.where(stick[:, None], k * d, (gamma * fN / nd)[:, None] * d)
    x = np.where(stick[:, None], x0, p - f / k)
    return x, f, stick


@pytest.mark.parametrize("law", ["translation", "rotation"])
def test_block_pulled_by_spring_converges_to_coulomb(law):
    rng = np.random.default_rng(7)
    m = 200
    if law == "translation":       # force per length; gamma dimensionless
        k, gamma, mu, scale = 50.0, 0.4, 2e-3, 0.05
    else:                          # couple per length; gamma_R a length (eps-like)
        eps = 0.02
        k, gamma, mu, scale = 0.05, 0.3 * eps, 2.0, 1.0
    fN = rng.uniform(0.5, 2.0, m)
    x0 = rng.normal(size=(m, 3)) * scale
    # spring end: |k d| / (gamma fN) in [0.2, 0.8] (stick) or [1.25, 5] (slip)
    ratio = np.where(np.arange(m) % 2 == 0, rng.uniform(0.2, 0.8, m), rng.uniform(1.25, 5.0, m))
    direc = rng.normal(size=(m, 3))
    direc /= np.linalg.norm(direc, axis=1, keepdims=True)
    p = x0 + (ratio * gamma * fN / k)[:, None] * direc
    x, lam, n_uzawa, n_newton = _block_problem(p, x0, k, mu, gamma, fN)
    xa, fa, stick = _analytic(p, x0, k, gamma, fN)
    assert stick.sum() == m // 2
    assert n_uzawa < 60 and n_newton <= 8
    assert np.allclose(x, xa, rtol=0, atol=1e-10 * scale)
    assert np.allclose(lam, fa, rtol=1e-10, atol=0)
    res = friction_force(x - x0, lam, mu, gamma, fN)
    assert np.array_equal(res.state == STICK, stick)
    assert np.allclose(res.force, fa, rtol=1e-10)
    g = x - x0
    # stick: no slip; slip: |f| = gamma fN and g parallel to f, positive work
    assert np.abs(g[stick]).max() <= 1e-10 * scale
    assert np.allclose(np.linalg.norm(res.force[~stick], axis=1), gamma * fN[~stick], rtol=1e-12)
    D = dissipation(res.force, g)
    ng = np.linalg.norm(g, axis=1)
    assert np.all(D[~stick] > 0)
    assert np.allclose(D[~stick], (gamma * fN * ng)[~stick], rtol=1e-9)
    excess, gap = coulomb_violation(res.force, g, gamma, fN)
    assert excess.max() <= 1e-12 * gamma * fN.max()
    assert np.abs(gap).max() <= 1e-9 * (gamma * fN * ng).max()


def test_misalignment_is_the_sine_of_the_force_to_the_slip():
    """``misalignment(f, g, gamma, fN)``: for a force on the cone
    (``|f| = gamma f_N``) at an angle ``theta`` to the slip, ``sin theta``,
    whatever the slip's length; zero along the slip, where the slip or the
    bound is zero; a force inside the cone counts by its share of the bound."""
    rng = np.random.default_rng(3)
    m = 50
    g = rng.normal(size=(m, 3)) * rng.uniform(1e-6, 1e3, size=(m, 1))
    e = g / np.linalg.norm(g, axis=1)[:, None]
    q = rng.normal(size=(m, 3))
    q -= np.sum(q * e, axis=1)[:, None] * e
    q /= np.linalg.norm(q, axis=1)[:, None]
    theta = rng.uniform(0.0, np.pi, size=m)
    gamma, fN = 0.3, rng.uniform(0.1, 10.0, size=m)
    f = (gamma * fN)[:, None] * (np.cos(theta)[:, None] * e + np.sin(theta)[:, None] * q)
    assert np.allclose(misalignment(f, g, gamma, fN), np.sin(theta), rtol=0, atol=1e-12)
    assert np.allclose(misalignment(0.5 * f, g, gamma, fN), 0.5 * np.sin(theta), atol=1e-12)
    along = (gamma * fN)[:, None] * e
    assert np.abs(misalignment(along, g, gamma, fN)).max() < 1e-12
    assert np.all(misalignment(f, np.zeros_like(g), gamma, fN) == 0)
    assert np.all(misalignment(f, g, gamma, np.zeros(m)) == 0)
    with pytest.raises(ValueError, match="shape"):
        misalignment(f[:, :2], g, gamma, fN)
