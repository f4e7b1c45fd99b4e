r"""Rotations: SO(3), its exponential map, tangent operators and quaternions.

Conventions (written once, here; every other module follows them)
-----------------------------------------------------------------
* A rotation ``R`` maps the **material** basis to the **spatial** one:
  the directors are its columns, ``d_i = R e_i``.  ``d_3`` is the tangent
  direction of the unstressed straight rod (shear-free), ``d_1, d_2`` span
  the cross-section.
* ``hat(a) b = a x b``;  ``vee`` is its inverse.
* ``expm(psi)`` is the rotation by ``|psi|`` about ``psi`` (Rodrigues).
* Variations and Newton increments of rotations are **spatial spins**:
  ``R <- expm(w) R``, so ``delta R R^T = hat(delta w)``.
* The tangent operator ``T(psi)`` (the differential of the exponential map,
  left trivialized) satisfies ``d expm(psi) expm(psi)^T = hat(T(psi) d psi)``;
  right trivialized, ``expm(psi)^T d expm(psi) = hat(T(psi)^T d psi)``.
  ``T = I + alpha hat(psi) + beta hat(psi)^2`` with
  ``alpha = (1 - cos t)/t^2``, ``beta = (t - sin t)/t^3``, ``t = |psi|``.
  ``T^{-1} = I - hat(psi)/2 + gamma hat(psi)^2``,
  ``gamma = (1 - (t/2) cot(t/2))/t^2``; ``T`` is singular at ``t = 2 pi k``.
* Quaternions are stored scalar-first, ``q = (w, x, y, z)``, unit norm.

All functions are batched over leading axes: vectors are ``(..., 3)``,
matrices ``(..., 3, 3)``.  The coefficient functions switch to Taylor series
for small angles, so nothing loses precision near the identity.
"""
import numpy as np

__all__ = [
    "cross", "hat", "vee", "expm", "logm", "tangent", "tangent_inv",
    "dtangent_matrix", "dtangent_form", "d2tangent_form", "coefficients",
    "quat_from_matrix", "matrix_from_quat", "quat_multiply", "quat_from_rotvec",
    "is_rotation", "rotate", "spin_between",
]

_SERIES_T = 2.0      # below this angle the coefficients use Taylor series
_NTERMS = 18


def hat(a):
    """Skew matrix of ``a`` (``hat(a) @ b == cross(a, b)``)."""
    a = np.asarray(a, dtype=float)
    H = np.zeros(a.shape[:-1] + (3, 3))
    H[..., 0, 1], H[..., 0, 2] = -a[..., 2], a[..., 1]
    H[..., 1, 0], H[..., 1, 2] = a[..., 2], -a[..., 0]
    H[..., 2, 0], H[..., 2, 1] = -a[..., 1], a[..., 0]
    return H


def cross(a, b):
    """``np.cross`` of 3-vectors along the last axis, written out: the same
    arithmetic (bit-for-bit), without ``np.cross``'s axis handling, which
    cost more than the products on the small arrays of a rod."""
    a, b = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
    c = np.empty(a.shape)
    c[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    c[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    c[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return c


def vee(A):
    """Axial vector of the skew part of ``A`` (inverse of :func:`hat`)."""
    A = np.asarray(A, dtype=float)
    return 0.5 * np.stack([A[..., 2, 1] - A[..., 1, 2],
                           A[..., 0, 2] - A[..., 2, 0],
                           A[..., 1, 0] - A[..., 0, 1]], axis=-1)


def _series(x, coef):
    """Horner evaluation of sum_k coef[k] x^k; ``coef`` of shape ``(n,)``
    or ``(n, m)`` (m series at once, results along a new last axis)."""
    coef = np.asarray(coef)
    xs = x if coef.ndim == 1 else x[..., None]
    out = np.zeros(x.shape + coef.shape[1:])
    for c in coef[::-1]:
        out = out * xs + c
    return out


def _fact(n):
    return float(np.prod(np.arange(1, n + 1, dtype=float)))


# Taylor coefficients in x = t^2 of alpha, beta and their x-derivatives
_A = np.array([(-1) ** k / _fact(2 * k + 2) for k in range(_NTERMS)])
_B = np.array([(-1) ** k / _fact(2 * k + 3) for k in range(_NTERMS)])
_AX = np.array([(k + 1) * _A[k + 1] for k in range(_NTERMS - 1)])
_BX = np.array([(k + 1) * _B[k + 1] for k in range(_NTERMS - 1)])
_AXX = np.array([(k + 1) * _AX[k + 1] for k in range(_NTERMS - 2)])
_BXX = np.array([(k + 1) * _BX[k + 1] for k in range(_NTERMS - 2)])
# the series of coefficients(psi, order) side by side (zero-padded), one
# Horner loop for all
_SERIES = {k: np.stack([np.pad(a, (0, _NTERMS - a.size)) for a in arrays], axis=1)
           for k, arrays in ((0, (_A, _B)), (1, (_A, _B, _AX, _BX)),
                             (2, (_A, _B, _AX, _BX, _AXX, _BXX)))}
# gamma(t) = (1 - (t/2) cot(t/2)) / t^2 = sum_{n>=1} |B_2n| t^(2n-2) / (2n)!
_G = np.array([abs(_b) / _fact(2 * n) for n, _b in
               zip(range(1, 16), __import__("scipy.special").special.bernoulli(30)[2::2])])


def coefficients(psi, order=0):
    """Scalar coefficient functions of ``T(psi)`` as functions of ``x = t^2``.

    Returns ``(alpha, beta)`` for ``order=0``, adds ``(alpha_x, beta_x)`` for
    ``order=1`` and ``(alpha_xx, beta_xx)`` for ``order=2``; derivatives are
    with respect to ``x = |psi|^2``.
    """
    psi = np.asarray(psi, dtype=float)
    x = np.einsum("...i,...i->...", psi, psi)
    t = np.sqrt(x)
    small = t < _SERIES_T
    xs = np.where(small, x, 0.0)
    tl = np.where(small, 1.0, t)          # safe large-angle argument
    s, c = np.sin(tl), np.cos(tl)
    series = _series(xs, _SERIES[order])             # all of them in one Horner loop
    closed = [(1 - c) / tl**2, (tl - s) / tl**3]
    if order >= 1:
        closed += [(tl * s / 2 + c - 1) / tl**4,
                   (-tl * c - 2 * tl + 3 * s) / (2 * tl**5)]
    if order >= 2:
        closed += [(tl**2 * c - 5 * tl * s - 8 * c + 8) / (4 * tl**6),
                   (tl**2 * s + 7 * tl * c + 8 * tl - 15 * s) / (4 * tl**7)]
    return tuple(np.where(small, series[..., k], f) for k, f in enumerate(closed))


def expm(psi):
    """Rotation matrix ``exp(hat(psi))`` (Rodrigues' formula).

    Examples
    --------
    >>> R = expm(np.array([0.0, 0.0, np.pi / 2]))
    >>> np.round(R @ [1.0, 0.0, 0.0], 12)
    array([0., 1., 0.])
    """
    psi = np.asarray(psi, dtype=float)
    x = np.einsum("...i,...i->...", psi, psi)
    t = np.sqrt(x)
    small = t < 1e-4
    tl = np.where(small, 1.0, t)
    a = np.where(small, 1 - x / 6 + x**2 / 120, np.sin(tl) / tl)
    b = np.where(small, 0.5 - x / 24 + x**2 / 720, (1 - np.cos(tl)) / tl**2)
    K = hat(psi)
    return np.eye(3) + a[..., None, None] * K + b[..., None, None] * (K @ K)


def quat_from_matrix(R):
    """Unit quaternion (scalar first, ``w >= 0``) of rotation matrices
    (Shepperd's method, robust for every angle).

    The entries of ``P = 4 q q^T`` are linear in ``R``: the diagonal
    ``1 + tr R``, ``1 + 2 R_ii - tr R`` and the off-diagonal sums and
    differences of ``R``'s transposed entries.  The row ``k`` of the
    largest diagonal entry is ``4 q_k q``, far from zero: normalized, it is
    ``q`` up to sign."""
    R = np.asarray(R, dtype=float)
    r00, r11, r22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = r00 + r11 + r22
    P = np.empty(R.shape[:-2] + (4, 4))
    P[..., 0, 0] = 1.0 + tr
    P[..., 1, 1] = 1.0 + 2.0 * r00 - tr
    P[..., 2, 2] = 1.0 + 2.0 * r11 - tr
    P[..., 3, 3] = 1.0 + 2.0 * r22 - tr
    P[..., 0, 1] = P[..., 1, 0] = R[..., 2, 1] - R[..., 1, 2]
    P[..., 0, 2] = P[..., 2, 0] = R[..., 0, 2] - R[..., 2, 0]
    P[..., 0, 3] = P[..., 3, 0] = R[..., 1, 0] - R[..., 0, 1]
    P[..., 1, 2] = P[..., 2, 1] = R[..., 1, 0] + R[..., 0, 1]
    P[..., 1, 3] = P[..., 3, 1] = R[..., 0, 2] + R[..., 2, 0]
    P[..., 2, 3] = P[..., 3, 2] = R[..., 2, 1] + R[..., 1, 2]
    k = np.argmax(np.diagonal(P, axis1=-2, axis2=-1), axis=-1)
    q = np.take_along_axis(P, k[..., None, None], axis=-2)[..., 0, :]
    q = q * np.where(q[..., :1] < 0, -1.0, 1.0)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def matrix_from_quat(q):
    """Rotation matrices of (not necessarily normalized) quaternions."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], axis=-2)


def quat_multiply(p, q):
    """Hamilton product ``p q`` (rotation ``q`` first, then ``p``)."""
    p, q = np.asarray(p, float), np.asarray(q, float)
    pw, pv = p[..., :1], p[..., 1:]
    qw, qv = q[..., :1], q[..., 1:]
    w = pw * qw - np.sum(pv * qv, axis=-1, keepdims=True)
    v = pw * qv + qw * pv + cross(pv, qv)
    return np.concatenate([w, v], axis=-1)


def quat_from_rotvec(psi):
    """Unit quaternion of the rotation vector ``psi``."""
    psi = np.asarray(psi, dtype=float)
    t = np.linalg.norm(psi, axis=-1, keepdims=True)
    small = t < 1e-4
    s = np.where(small, 0.5 - t**2 / 48, np.sin(t / 2) / np.where(small, 1, t))
    return np.concatenate([np.cos(t / 2), s * psi], axis=-1)


def logm(R):
    """Rotation vector of rotation matrices, with angle in ``[0, pi]``.

    Computed through the quaternion, so it is accurate near the identity
    and near ``pi`` (where the axis sign is arbitrary).
    """
    q = quat_from_matrix(R)
    w, v = q[..., 0], q[..., 1:]
    s = np.linalg.norm(v, axis=-1)
    t = 2 * np.arctan2(s, w)
    small = s < 1e-8
    f = np.where(small, 2.0 / np.where(w == 0, 1, w),
                 t / np.where(small, 1.0, s))
    return f[..., None] * v


def tangent(psi, coef=None):
    """Tangent operator ``T(psi)`` of the exponential map (see module doc).
    ``coef``: :func:`coefficients` of ``psi`` (any order) if already at
    hand (they depend on ``|psi|`` only: those of ``-psi`` serve too)."""
    al, be = coefficients(psi) if coef is None else coef[:2]
    K = hat(psi)
    return np.eye(3) + al[..., None, None] * K + be[..., None, None] * (K @ K)


def tangent_inv(psi):
    """Inverse ``T(psi)^{-1}``; valid for ``|psi| < 2 pi``."""
    psi = np.asarray(psi, dtype=float)
    x = np.einsum("...i,...i->...", psi, psi)
    t = np.sqrt(x)
    small = t < 1.0
    tl = np.where(small, 1.0, t)
    g = np.where(small, _series(np.where(small, x, 0.0), _G),
                 (1 - (tl / 2) / np.tan(tl / 2)) / tl**2)
    K = hat(psi)
    return np.eye(3) - 0.5 * K + g[..., None, None] * (K @ K)


def dtangent_matrix(psi, p, coef=None):
    """Matrix ``J`` with ``DT(psi)[a] p = J a`` (directional derivative of
    ``T`` in direction ``a``, applied to ``p``); ``coef`` as in
    :func:`tangent` (order >= 1)."""
    psi, p = np.broadcast_arrays(np.asarray(psi, float), np.asarray(p, float))
    al, be, ax, bx = coefficients(psi, 1) if coef is None else coef[:4]
    pxp = cross(psi, p)
    v = ax[..., None] * pxp + bx[..., None] * cross(psi, pxp)
    return (-al[..., None, None] * hat(p)
            - be[..., None, None] * (hat(pxp) + hat(psi) @ hat(p))
            + 2 * v[..., :, None] * psi[..., None, :])


def dtangent_form(psi, h, coef=None):
    """Matrix ``Q`` with ``h . DT(psi)[c] d = d^T Q c`` (bilinear in d, c);
    ``coef`` as in :func:`tangent` (order >= 1)."""
    psi, h = np.broadcast_arrays(np.asarray(psi, float), np.asarray(h, float))
    al, be, ax, bx = coefficients(psi, 1) if coef is None else coef[:4]
    hp = np.einsum("...i,...i->...", h, psi)
    x = np.einsum("...i,...i->...", psi, psi)
    hxp = cross(h, psi)
    v = ax[..., None] * hxp + bx[..., None] * (hp[..., None] * psi - x[..., None] * h)
    return (al[..., None, None] * hat(h)
            + be[..., None, None] * (hp[..., None, None] * np.eye(3)
                                     - h[..., :, None] * psi[..., None, :]
                                     + hat(hxp))
            + 2 * v[..., :, None] * psi[..., None, :])


def d2tangent_form(psi, m, p, coef=None):
    """Symmetric matrix ``Q`` with ``m . D^2T(psi)[a, b] p = a^T Q b``;
    ``coef`` as in :func:`tangent` (order 2)."""
    psi, m, p = np.broadcast_arrays(np.asarray(psi, float),
                                    np.asarray(m, float), np.asarray(p, float))
    al, be, ax, bx, axx, bxx = coefficients(psi, 2) if coef is None else coef
    mp = np.einsum("...i,...i->...", m, p)
    psixp = cross(psi, p)
    pp = np.einsum("...i,...i->...", psi, p)
    w1 = (ax[..., None] * cross(p, m)
          + bx[..., None] * (cross(psixp, m) + pp[..., None] * m
                             - mp[..., None] * psi))
    m_psixp = np.einsum("...i,...i->...", m, psixp)
    m_psipsixp = np.einsum("...i,...i->...", m, cross(psi, psixp))
    s1 = ax * m_psixp + bx * m_psipsixp
    s2 = axx * m_psixp + bxx * m_psipsixp
    I = np.eye(3)
    outer = lambda a, b: a[..., :, None] * b[..., None, :]
    return (be[..., None, None] * (outer(p, m) + outer(m, p) - 2 * mp[..., None, None] * I)
            + 2 * (outer(w1, psi) + outer(psi, w1))
            + 2 * s1[..., None, None] * I
            + 4 * s2[..., None, None] * outer(psi, psi))


def is_rotation(R, tol=1e-10):
    """True where ``R`` is in SO(3) to ``tol`` (orthogonal, det = +1)."""
    R = np.asarray(R, dtype=float)
    err = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(axis=(-2, -1))
    return (err < tol) & (np.abs(np.linalg.det(R) - 1) < tol)


def rotate(R, w, alpha=1.0):
    """The configuration update of rotations: ``expm(alpha w) R`` (spatial
    spins ``w``, one per rotation).  Its inverse is :func:`spin_between`."""
    return expm(alpha * np.asarray(w)) @ R


def spin_between(R, R_ref):
    """The spatial rotation vector ``w`` with ``R = expm(w) R_ref``:
    ``logm(R R_ref^T)`` (the inverse of :func:`rotate`, for ``|w| < pi``)."""
    return logm(R @ np.swapaxes(R_ref, -1, -2))
