"""Property tests of :mod:`skfem_rod.rotations`.

All hypothesis tests are derandomized, so the run is deterministic.

Finite-difference tolerances: a central difference with step ``h`` of a
smooth function ``f`` has truncation error ``h^2/6 |f'''|`` and round-off
error ``~ eps |f| / h``.  The functions tested here have derivatives of order
one for unit directions (the coefficient functions are entire in ``x = t^2``
and bounded for large ``t``), so the tolerance is ``C (h^2 + eps/h) * scale``
with a safety constant ``C = 100`` and ``scale`` the product of the norms of
the vector arguments.
"""
from math import factorial

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from skfem_rod.rotations import (coefficients, d2tangent_form, dtangent_form,
                                 dtangent_matrix, expm, hat, is_rotation,
                                 logm, matrix_from_quat, quat_from_matrix,
                                 quat_from_rotvec, quat_multiply, tangent,
                                 tangent_inv, vee)

EPS = np.finfo(float).eps
I3 = np.eye(3)
H = 1e-6                                  # finite-difference step
FD_TOL = 100 * (H**2 + EPS / H)           # ~2.2e-8 relative

SETTINGS = settings(max_examples=150, deadline=None, derandomize=True)

# angles where the implementation switches branches, and other edge cases
SWITCH = 2.0                              # series/closed form in coefficients
SPECIAL_ANGLES = [0.0, 1e-12, 1e-8, 1e-4 - 1e-12, 1e-4 + 1e-12, 1e-3,
                  1.0 - 1e-12, 1.0 + 1e-12,          # tangent_inv switch
                  SWITCH - 1e-9, SWITCH + 1e-9, SWITCH - 1e-6, SWITCH + 1e-6,
                  np.pi - 1e-9, np.pi, np.pi + 1e-9, 5.0, 6.0]


# --------------------------------------------------------------------------
# strategies
# --------------------------------------------------------------------------

def vectors(lo=-3.0, hi=3.0):
    f = st.floats(lo, hi, allow_nan=False, allow_infinity=False)
    return st.tuples(f, f, f).map(np.array)


def unit_vectors():
    f = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)
    return (st.tuples(f, f, f).map(np.array)
            .filter(lambda v: np.linalg.norm(v) > 0.1)
            .map(lambda v: v / np.linalg.norm(v)))


def rotvecs(max_angle, special=True):
    """Rotation vectors ``t n`` with ``0 <= t <= max_angle``; mixes uniformly
    drawn angles with the special (switch / tiny / near-pi) angles."""
    angles = st.floats(0.0, max_angle, allow_nan=False)
    if special:
        sp = [a for a in SPECIAL_ANGLES if a <= max_angle]
        angles = st.one_of(angles, st.sampled_from(sp))
    return st.builds(lambda t, n: t * n, angles, unit_vectors())


def assert_close(actual, desired, tol, scale=1.0):
    err = np.abs(np.asarray(actual) - np.asarray(desired)).max()
    assert err <= tol * scale, f"error {err:.3e} > {tol * scale:.3e}"


# --------------------------------------------------------------------------
# hat / vee
# --------------------------------------------------------------------------

@SETTINGS
@given(vectors(), vectors())
def test_hat_is_cross_product_and_vee_inverts_it(a, b):
    np.testing.assert_allclose(hat(a) @ b, np.cross(a, b), rtol=0,
                               atol=1e-15 * (1 + np.abs(a).max()
                                             * np.abs(b).max()))
    np.testing.assert_array_equal(hat(a), -hat(a).T)
    np.testing.assert_array_equal(vee(hat(a)), a)


def test_vee_takes_skew_part():
    A = np.arange(9.0).reshape(3, 3)
    np.testing.assert_array_equal(vee(A), vee(0.5 * (A - A.T)))


# --------------------------------------------------------------------------
# exponential and logarithm
# --------------------------------------------------------------------------

@SETTINGS
@given(rotvecs(20.0))
def test_expm_is_rotation(psi):
    R = expm(psi)
    assert is_rotation(R, tol=1e-13)
    # the rotation axis is fixed
    np.testing.assert_allclose(R @ psi, psi, rtol=0, atol=1e-14 * (1 + 20))


def test_expm_examples():
    np.testing.assert_allclose(expm(np.array([0.0, 0.0, np.pi / 2])) @ [1, 0, 0],
                               [0, 1, 0], atol=1e-15)
    np.testing.assert_array_equal(expm(np.zeros(3)), I3)
    # 2 pi about any axis is the identity
    n = np.array([1.0, 2.0, -2.0]) / 3
    np.testing.assert_allclose(expm(2 * np.pi * n), I3, atol=1e-14)


@SETTINGS
@given(rotvecs(np.pi - 1e-6))
def test_logm_inverts_expm(psi):
    # the logarithm's derivative T^{-1}(psi) is bounded by ~ t/2 / sin(t/2)
    # stays ~ 1.6 for t < pi; round-off in R is a few eps
    np.testing.assert_allclose(logm(expm(psi)), psi, rtol=0, atol=1e-14)


@SETTINGS
@given(rotvecs(20.0))
def test_expm_inverts_logm(psi):
    R = expm(psi)
    phi = logm(R)
    assert np.linalg.norm(phi) <= np.pi * (1 + 1e-15)
    np.testing.assert_allclose(expm(phi), R, rtol=0, atol=1e-14)


@pytest.mark.parametrize("t", [0.0, 1e-300, 1e-12, 1e-9, 1e-8 - 1e-20,
                               1e-8 + 1e-20, 1e-4, np.pi - 1e-6,
                               np.pi - 1e-9, np.pi - 1e-12, np.pi])
def test_log_exp_edge_angles(t):
    rng = np.random.default_rng(12)
    for n in rng.normal(size=(20, 3)):
        n /= np.linalg.norm(n)
        R = expm(t * n)
        phi = logm(R)
        np.testing.assert_allclose(expm(phi), R, rtol=0, atol=1e-14)
        if t < np.pi - 1e-7:
            np.testing.assert_allclose(phi, t * n, rtol=0, atol=1e-15)
        else:  # near pi the axis sign is arbitrary; the angle is not
            np.testing.assert_allclose(np.linalg.norm(phi), t, rtol=1e-15,
                                       atol=1e-15)
            assert abs(abs(phi @ n) - np.linalg.norm(phi)) < 1e-7 * t


def test_logm_of_exact_half_turns():
    # exactly representable rotations by pi (diagonal and permutation-like)
    for R in [np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]),
              np.diag([-1.0, -1.0, 1.0]),
              np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])]:
        phi = logm(R)
        np.testing.assert_allclose(np.linalg.norm(phi), np.pi, rtol=1e-15)
        np.testing.assert_allclose(expm(phi), R, atol=1e-15)


def test_expm_logm_batched():
    rng = np.random.default_rng(3)
    psi = rng.normal(size=(4, 5, 3))
    R = expm(psi)
    assert R.shape == (4, 5, 3, 3)
    for i in range(4):
        for j in range(5):
            np.testing.assert_array_equal(R[i, j], expm(psi[i, j]))
    phi = logm(R)
    assert phi.shape == (4, 5, 3)
    np.testing.assert_allclose(expm(phi), R, atol=1e-14)


def test_is_rotation_rejects():
    assert is_rotation(I3)
    assert not is_rotation(np.diag([1.0, 1.0, -1.0]))           # reflection
    assert not is_rotation(1.001 * I3)                          # scaling
    S = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    assert not is_rotation(I3 + 1e-6 * S)                       # shear
    # I + eps K is orthogonal to O(eps^2) only
    assert is_rotation(I3 + 1e-6 * hat([1.0, 0.0, 0.0]))
    assert not is_rotation(I3 + 1e-4 * hat([1.0, 0.0, 0.0]))
    np.testing.assert_array_equal(
        is_rotation(np.stack([I3, -I3])), [True, False])


# --------------------------------------------------------------------------
# quaternions
# --------------------------------------------------------------------------

@SETTINGS
@given(rotvecs(20.0))
def test_quaternion_round_trip(psi):
    R = expm(psi)
    q = quat_from_matrix(R)
    assert q[0] >= 0
    np.testing.assert_allclose(np.linalg.norm(q), 1.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(matrix_from_quat(q), R, rtol=0, atol=1e-14)


@SETTINGS
@given(rotvecs(20.0), rotvecs(20.0))
def test_quat_multiply_is_matrix_product(a, b):
    p, q = quat_from_rotvec(a), quat_from_rotvec(b)
    np.testing.assert_allclose(matrix_from_quat(quat_multiply(p, q)),
                               expm(a) @ expm(b), rtol=0, atol=1e-14)
    # and from matrices
    P, Q = quat_from_matrix(expm(a)), quat_from_matrix(expm(b))
    np.testing.assert_allclose(matrix_from_quat(quat_multiply(P, Q)),
                               expm(a) @ expm(b), rtol=0, atol=1e-14)


@SETTINGS
@given(rotvecs(20.0))
def test_quat_from_rotvec_is_expm(psi):
    q = quat_from_rotvec(psi)
    np.testing.assert_allclose(np.linalg.norm(q), 1.0, rtol=0, atol=1e-15)
    np.testing.assert_allclose(matrix_from_quat(q), expm(psi), rtol=0,
                               atol=1e-14)
    # same quaternion as from the matrix, up to the sign
    qm = quat_from_matrix(expm(psi))
    s = 1.0 if q @ qm >= 0 else -1.0
    np.testing.assert_allclose(s * q, qm, rtol=0, atol=1e-14)


def test_quaternion_helpers_batched_and_identity():
    np.testing.assert_array_equal(quat_from_rotvec(np.zeros(3)), [1, 0, 0, 0])
    np.testing.assert_array_equal(quat_from_matrix(I3), [1, 0, 0, 0])
    rng = np.random.default_rng(5)
    psi = rng.normal(size=(2, 3, 3)) * 2
    q = quat_from_rotvec(psi)
    assert q.shape == (2, 3, 4)
    np.testing.assert_allclose(matrix_from_quat(q), expm(psi), atol=1e-14)
    qq = quat_multiply(q, q)
    np.testing.assert_allclose(matrix_from_quat(qq),
                               expm(psi) @ expm(psi), atol=1e-14)
    np.testing.assert_allclose(matrix_from_quat(quat_from_matrix(expm(psi))),
                               expm(psi), atol=1e-14)


# --------------------------------------------------------------------------
# tangent operator
# --------------------------------------------------------------------------

@SETTINGS
@given(rotvecs(12.0), unit_vectors())
def test_tangent_is_left_trivialized_differential(psi, d):
    R = expm(psi)
    dR = (expm(psi + H * d) - expm(psi - H * d)) / (2 * H)
    assert_close(dR @ R.T, hat(tangent(psi) @ d), FD_TOL)
    # right trivialized: R^T dR = hat(T^T d)
    assert_close(R.T @ dR, hat(tangent(psi).T @ d), FD_TOL)


@SETTINGS
@given(rotvecs(20.0))
def test_tangent_symmetries(psi):
    T = tangent(psi)
    np.testing.assert_allclose(T.T, tangent(-psi), rtol=0, atol=1e-15)
    np.testing.assert_allclose(T.T, expm(-psi) @ T, rtol=0, atol=1e-14)
    # T psi = psi (the axis direction is not changed)
    np.testing.assert_allclose(T @ psi, psi, rtol=0,
                               atol=1e-14 * (1 + np.linalg.norm(psi)))


def _tangent_inv_tol(psi):
    # round-off of T^{-1} T - I: a few ulps times |T^{-1}| |T| (both O(1)
    # here except near t = 2 pi, where |T^{-1}| ~ 1 / (2 pi - t))
    T, Ti = tangent(psi), tangent_inv(psi)
    return 20 * EPS * np.linalg.norm(Ti, 2) * np.linalg.norm(T, 2)


@SETTINGS
@given(rotvecs(2 * np.pi - 0.1), vectors())
def test_tangent_inv_is_inverse(psi, a):
    T, Ti = tangent(psi), tangent_inv(psi)
    tol = _tangent_inv_tol(psi)
    assert_close(Ti @ T, I3, tol)
    assert_close(T @ Ti, I3, tol)


@pytest.mark.parametrize("t", [1e-12, 0.5, 0.9, 1 - 1e-12, 1 + 1e-12, 1.1,
                               SWITCH - 1e-9, SWITCH + 1e-9, np.pi, 5.0,
                               2 * np.pi - 0.1])
def test_tangent_inv_across_switch(t):
    n = np.array([2.0, -1.0, 2.0]) / 3
    psi = t * n
    assert_close(tangent_inv(psi) @ tangent(psi), I3, _tangent_inv_tol(psi))


def test_tangent_batched():
    rng = np.random.default_rng(7)
    psi = rng.normal(size=(3, 4, 3))
    T, Ti = tangent(psi), tangent_inv(psi)
    assert T.shape == Ti.shape == (3, 4, 3, 3)
    np.testing.assert_array_equal(T[2, 1], tangent(psi[2, 1]))
    np.testing.assert_array_equal(Ti[2, 1], tangent_inv(psi[2, 1]))


# --------------------------------------------------------------------------
# derivatives of the tangent operator
# --------------------------------------------------------------------------

@SETTINGS
@given(rotvecs(12.0), vectors(), unit_vectors())
def test_dtangent_matrix_is_directional_derivative(psi, p, a):
    fd = (tangent(psi + H * a) @ p - tangent(psi - H * a) @ p) / (2 * H)
    assert_close(dtangent_matrix(psi, p) @ a, fd, FD_TOL,
                 1 + np.linalg.norm(p))


@SETTINGS
@given(rotvecs(12.0), vectors(), vectors(), vectors())
def test_dtangent_form(psi, h, c, d):
    Q = dtangent_form(psi, h)
    # exact identity with the directional derivative matrix
    lhs = h @ (dtangent_matrix(psi, d) @ c)
    scale = (1 + np.linalg.norm(h)) * (1 + np.linalg.norm(c)) \
        * (1 + np.linalg.norm(d))
    assert_close(d @ Q @ c, lhs, 1e-14, scale)
    # and with finite differences of T
    nc = np.linalg.norm(c)
    if nc > 0:
        e = c / nc
        fd = h @ ((tangent(psi + H * e) - tangent(psi - H * e)) @ d) / (2 * H)
        assert_close(d @ Q @ e, fd, FD_TOL, scale)


@SETTINGS
@given(rotvecs(12.0), vectors(), vectors(), unit_vectors(), unit_vectors())
def test_d2tangent_form(psi, m, p, a, b):
    Q = d2tangent_form(psi, m, p)
    scale = (1 + np.linalg.norm(m)) * (1 + np.linalg.norm(p))
    assert_close(Q, Q.T, 1e-15, scale)

    def first(x):  # a -> m . DT(x)[a] p
        return m @ (dtangent_matrix(x, p) @ a)
    fd = (first(psi + H * b) - first(psi - H * b)) / (2 * H)
    assert_close(a @ Q @ b, fd, FD_TOL, scale)


@pytest.mark.parametrize("t", [0.0, 1e-12, 1e-8, 1e-3, 0.5, SWITCH - 1e-9,
                               SWITCH + 1e-9, SWITCH - 1e-6, SWITCH + 1e-6,
                               np.pi, 5.0, 6.0, 2 * np.pi, 10.0])
def test_tangent_derivatives_at_fixed_angles(t):
    """Full matrices (all directions) at the edge-case angles."""
    rng = np.random.default_rng(int(1000 * t) % 2**31)
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    psi = t * n
    m, p = rng.normal(size=(2, 3))
    scale = (1 + np.linalg.norm(m)) * (1 + np.linalg.norm(p))
    J = dtangent_matrix(psi, p)
    Q1 = dtangent_form(psi, m)
    Q2 = d2tangent_form(psi, m, p)
    J_fd = np.empty((3, 3))
    Q2_fd = np.empty((3, 3))
    for k in range(3):
        e = I3[k]
        J_fd[:, k] = (tangent(psi + H * e) @ p
                      - tangent(psi - H * e) @ p) / (2 * H)
        Q2_fd[:, k] = (dtangent_matrix(psi + H * e, p).T @ m
                       - dtangent_matrix(psi - H * e, p).T @ m) / (2 * H)
    assert_close(J, J_fd, FD_TOL, scale)
    # h . DT[c] d = d^T Q c  <=>  Q = (J(d)^T h) as rows over d
    Q1_from_J = np.stack([dtangent_matrix(psi, I3[k]).T @ m
                          for k in range(3)])
    assert_close(Q1, Q1_from_J, 1e-14, scale)
    assert_close(Q2, Q2.T, 1e-15, scale)
    assert_close(Q2, Q2_fd, FD_TOL, scale)


def test_tangent_derivatives_batched():
    rng = np.random.default_rng(11)
    psi, m, p = rng.normal(size=(3, 2, 5, 3)) * 1.5
    J = dtangent_matrix(psi, p)
    Q1 = dtangent_form(psi, m)
    Q2 = d2tangent_form(psi, m, p)
    assert J.shape == Q1.shape == Q2.shape == (2, 5, 3, 3)
    np.testing.assert_array_equal(J[1, 3], dtangent_matrix(psi[1, 3], p[1, 3]))
    np.testing.assert_array_equal(Q1[1, 3], dtangent_form(psi[1, 3], m[1, 3]))
    np.testing.assert_array_equal(Q2[1, 3],
                                  d2tangent_form(psi[1, 3], m[1, 3], p[1, 3]))
    # broadcasting a single psi against many p
    Jb = dtangent_matrix(psi[0, 0], p)
    np.testing.assert_array_equal(Jb[1, 2], dtangent_matrix(psi[0, 0], p[1, 2]))


# --------------------------------------------------------------------------
# coefficient functions
# --------------------------------------------------------------------------

def test_coefficients_continuous_at_series_switch():
    """Series (t < 2) and closed forms (t >= 2) meet continuously.

    The two evaluation points t = 2 -+ 1e-9 differ in x = t^2 by
    dx = 8e-9, so the values themselves differ by f_x dx ~ 1e-9 |f|.  Remove
    that first-order change (using the derivative f_x, second-order remainder
    ~ f_xx dx^2 ~ 1e-17) and what is left is the jump between the branches,
    which must be at round-off level (1e-12 relative).
    """
    n = np.array([1.0, -2.0, 2.0]) / 3
    lo = np.array(coefficients((SWITCH - 1e-9) * n, order=2))
    hi = np.array(coefficients((SWITCH + 1e-9) * n, order=2))
    mid = np.array(coefficients(SWITCH * n, order=2))
    dx = (SWITCH + 1e-9)**2 - (SWITCH - 1e-9)**2
    # derivatives: alpha_x, beta_x for alpha, beta; alpha_xx, beta_xx for
    # alpha_x, beta_x.  (alpha_xx, beta_xx are compared without correction:
    # their own change over dx is ~ 1e-9 relative, checked at 1e-8.)
    deriv = np.concatenate([mid[2:6], [0.0, 0.0]])
    jump = hi - lo - deriv * dx
    np.testing.assert_array_less(np.abs(jump[:4]), 1e-12 * np.abs(mid[:4]))
    np.testing.assert_array_less(np.abs(jump[4:]), 1e-8 * np.abs(mid[4:]))


def _reference_coefficients(t):
    """alpha, beta and their first two x-derivatives (x = t^2) from their
    Taylor series summed in 50-digit arithmetic (independent of both
    branches of the implementation)."""
    mpmath = pytest.importorskip("mpmath")
    with mpmath.workdps(50):
        x = mpmath.mpf(float(t))**2
        out = []
        for shift in (2, 3):            # alpha: 1/(2k+2)!, beta: 1/(2k+3)!
            c = [mpmath.mpf(-1)**k / mpmath.factorial(2 * k + shift)
                 for k in range(120)]
            f = sum(c[k] * x**k for k in range(120))
            fx = sum(k * c[k] * x**(k - 1) for k in range(1, 120))
            fxx = sum(k * (k - 1) * c[k] * x**(k - 2) for k in range(2, 120))
            out.append((f, fx, fxx))
        (a, ax, axx), (b, bx, bxx) = out
        return np.array([float(v) for v in (a, b, ax, bx, axx, bxx)])


@pytest.mark.parametrize("t", [SWITCH - 1e-9, SWITCH + 1e-9])
def test_coefficients_branches_agree_at_same_point(t):
    """At the same point, the value returned (one branch) equals a
    high-precision reference and the closed forms evaluated here in double
    precision (the other branch below the switch), to 1e-12 relative."""
    n = np.array([0.0, 0.6, 0.8])
    got = np.array(coefficients(t * n, order=2))
    np.testing.assert_allclose(got, _reference_coefficients(t), rtol=1e-12,
                               atol=0)
    c, s = np.cos(t), np.sin(t)
    closed = np.array([
        (1 - c) / t**2, (t - s) / t**3,
        (t * s / 2 + c - 1) / t**4, (-t * c - 2 * t + 3 * s) / (2 * t**5),
        (t**2 * c - 5 * t * s - 8 * c + 8) / (4 * t**6),
        (t**2 * s + 7 * t * c + 8 * t - 15 * s) / (4 * t**7)])
    np.testing.assert_allclose(got, closed, rtol=1e-12, atol=0)


def _roundoff_envelope(t):
    """Size of the terms each branch of :func:`coefficients` sums: the
    round-off of the result is a few eps times this (relative accuracy is
    lost only where the result is much smaller, e.g. alpha at 2 pi k)."""
    if t < SWITCH:   # Taylor series in x = t^2 with absolute coefficients
        return np.array(_abs_series(t))
    c, s = abs(np.cos(t)), abs(np.sin(t))
    return np.array([
        (1 + c) / t**2, (t + s) / t**3,
        (t * s / 2 + c + 1) / t**4, (t * c + 2 * t + 3 * s) / (2 * t**5),
        (t**2 * c + 5 * t * s + 8 * c + 8) / (4 * t**6),
        (t**2 * s + 7 * t * c + 8 * t + 15 * s) / (4 * t**7)])


def _abs_series(t):
    x = t * t
    out = []
    for shift in (2, 3):
        c = [1.0 / factorial(2 * k + shift) for k in range(40)]
        out.append((sum(c[k] * x**k for k in range(40)),
                    sum(k * c[k] * x**(k - 1) for k in range(1, 40)),
                    sum(k * (k - 1) * c[k] * x**(k - 2) for k in range(2, 40))))
    (a, ax, axx), (b, bx, bxx) = out
    return a, b, ax, bx, axx, bxx


@SETTINGS
@given(st.one_of(st.floats(0.0, 20.0), st.sampled_from(SPECIAL_ANGLES)))
def test_coefficients_accuracy(t):
    got = np.array(coefficients(np.array([t, 0.0, 0.0]), order=2))
    ref = _reference_coefficients(t)
    err = np.abs(got - ref)
    tol = 50 * EPS * _roundoff_envelope(t)
    assert np.all(err <= tol), (t, err / tol)


def test_cross_and_the_series_are_the_plain_ones_bit_for_bit():
    # rotations.cross is np.cross written out (same products, same order),
    # with broadcasting; coefficients() evaluates all its series in one
    # Horner loop: each equals its own Horner evaluation exactly
    from skfem_rod import rotations as rot
    rng = np.random.default_rng(7)
    a, b = rng.standard_normal((5, 4, 3)), rng.standard_normal((4, 3))
    assert np.array_equal(rot.cross(a, b), np.cross(a, b))
    psi = rng.standard_normal((50, 3)) * rng.uniform(0.0, 3.0, (50, 1))
    x = np.einsum("...i,...i->...", psi, psi)
    small = np.sqrt(x) < rot._SERIES_T
    one_by_one = [rot._A, rot._B, rot._AX, rot._BX, rot._AXX, rot._BXX]
    for k, value in enumerate(rot.coefficients(psi, 2)):
        alone = rot._series(np.where(small, x, 0.0), one_by_one[k])
        assert np.array_equal(value[small], alone[small])
