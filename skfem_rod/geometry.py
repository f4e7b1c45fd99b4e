"""Stress-free reference shapes of the rod.

A shape gives, for arclengths ``s`` ``(n,)``, the reference positions
``r0(s)`` ``(n, 3)`` and frames ``R0(s)`` ``(n, 3, 3)`` whose columns are
``d1, d2, d3`` with ``d3`` the unit tangent.  The finite-element reference
is the P3 interpolation of these nodal values (objective interpolation of
the frames), which is taken as exactly stress free.

Shapes: :func:`straight`, :func:`arc`, :func:`helix`, :func:`curve` (any
arclength-parametrized curve with an optional ``d1`` field), and
:func:`polyline` (points through which a cubic spline is fitted).  Where no
``d1`` is given the frame is parallel transported (rotation minimizing)
from the first node.
"""
import numpy as np

from .rotations import expm
from .validation import positive


def _unit(v, name):
    v = np.asarray(v, dtype=float)
    n = np.linalg.norm(v)
    if v.shape != (3,) or not np.isfinite(n) or n == 0:
        raise ValueError(f"{name} must be a nonzero finite 3-vector, got {v!r}")
    return v / n


def frames_from(t, d1):
    """Frames with columns (d1, d2, d3) from tangents ``t`` and ``d1``
    guesses (orthogonalized against ``t``)."""
    t = t / np.linalg.norm(t, axis=-1, keepdims=True)
    d1 = d1 - np.sum(d1 * t, axis=-1, keepdims=True) * t
    n1 = np.linalg.norm(d1, axis=-1, keepdims=True)
    if np.any(~(n1 > 1e-12)):
        raise ValueError("d1 must not be parallel to the tangent (it is orthogonalized "
                         "against it to build the frame)")
    d1 = d1 / n1
    d2 = np.cross(t, d1)
    return np.stack([d1, d2, t], axis=-1)


def _perpendicular(t):
    a = np.array([0.0, 0.0, 1.0]) if abs(t[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    return np.cross(a, t) / np.linalg.norm(np.cross(a, t))


def parallel_transport(s, t, d1_start=None):
    """Rotation-minimizing frames along tangents ``t`` at arclengths ``s``."""
    order = np.argsort(s, kind="stable")
    ts = t[order] / np.linalg.norm(t[order], axis=-1, keepdims=True)
    d1 = np.empty_like(ts)
    d1[0] = _perpendicular(ts[0]) if d1_start is None else d1_start
    for k in range(1, len(ts)):          # sequential by nature; setup only
        ax = np.cross(ts[k - 1], ts[k])
        sn, cs = np.linalg.norm(ax), np.dot(ts[k - 1], ts[k])
        ang = np.arctan2(sn, cs)
        rot = expm(ax / sn * ang) if sn > 1e-14 else np.eye(3)
        d1[k] = rot @ d1[k - 1]
    out = np.empty((len(s), 3, 3))
    out[order] = frames_from(ts, d1)
    return out


class Shape:
    """A reference shape: callable ``shape(s) -> (r0, R0)`` with a length."""

    def __init__(self, length, func, name="shape"):
        self.length = positive("length", length)
        self._func = func
        self.name = name

    def __call__(self, s):
        r0, R0 = self._func(np.asarray(s, dtype=float))
        return np.asarray(r0, float), np.asarray(R0, float)

    def __repr__(self):
        return f"Shape({self.name}, length={self.length})"


def straight(length, start=(0.0, 0.0, 0.0), direction=(1.0, 0.0, 0.0), d1=None):
    """Straight rod from ``start`` along ``direction``; ``d1`` defaults to a
    vector perpendicular to it (``+y`` for a rod along ``+x``).

    Examples
    --------
    >>> r0, R0 = straight(2.0)(np.array([0.0, 1.0]))
    >>> r0[1], R0[1][:, 2]
    (array([1., 0., 0.]), array([1., 0., 0.]))
    """
    t = _unit(direction, "direction")
    d1v = _perpendicular(t) if d1 is None else _unit(d1, "d1")
    if d1 is None and abs(t[2]) < 0.9:
        d1v = np.cross(np.array([0.0, 0.0, 1.0]), t)
        d1v /= np.linalg.norm(d1v)
    start = np.asarray(start, float)
    R = frames_from(t[None], d1v[None])[0]

    def f(s):
        return start + s[:, None] * t, np.broadcast_to(R, (len(s), 3, 3)).copy()
    return Shape(length, f, "straight")


def arc(radius, angle, start=(0.0, 0.0, 0.0), tangent=(1.0, 0.0, 0.0),
        toward=(0.0, 1.0, 0.0)):
    """Circular arc of ``radius`` subtending ``angle`` (rad), starting at
    ``start`` with unit ``tangent`` and curving toward ``toward``.
    ``d1`` is the inward normal (toward the centre), ``d2 = d3 x d1``."""
    radius = positive("radius", radius)
    angle = positive("angle", angle)
    t0 = _unit(tangent, "tangent")
    n0 = np.asarray(toward, float) - np.dot(toward, t0) * t0
    n0 = _unit(n0, "toward (component normal to tangent)")
    start = np.asarray(start, float)

    def f(s):
        a = s / radius
        r = start + radius * (np.sin(a)[:, None] * t0 + (1 - np.cos(a))[:, None] * n0)
        t = np.cos(a)[:, None] * t0 + np.sin(a)[:, None] * n0
        d1 = -np.sin(a)[:, None] * t0 + np.cos(a)[:, None] * n0
        return r, frames_from(t, d1)
    return Shape(radius * angle, f, "arc")


def helix(radius, pitch, turns, axis_start=(0.0, 0.0, 0.0)):
    """Helix about ``+z`` of ``radius``, rise ``pitch`` per turn, ``turns``
    turns, starting at ``(radius, 0, 0)`` (+ ``axis_start``); ``d1`` is the
    principal normal (toward the axis)."""
    radius = positive("radius", radius)
    pitch = positive("pitch", pitch)
    turns = positive("turns", turns)
    c = pitch / (2 * np.pi)
    k = np.hypot(radius, c)
    length = 2 * np.pi * turns * k
    o = np.asarray(axis_start, float)

    def f(s):
        p = s / k
        r = o + np.stack([radius * np.cos(p), radius * np.sin(p), c * p], axis=1)
        t = np.stack([-radius * np.sin(p), radius * np.cos(p), c + 0 * p], axis=1) / k
        d1 = np.stack([-np.cos(p), -np.sin(p), 0 * p], axis=1)
        return r, frames_from(t, d1)
    return Shape(length, f, "helix")


def curve(r_of_s, length, d1_of_s=None, ds=None):
    """Any curve parametrized by arclength: ``r_of_s(s) -> (n, 3)`` for
    ``s`` ``(n,)``; tangents by central differences of step ``ds``.
    ``d1_of_s`` gives the first director (else parallel transport)."""
    if not callable(r_of_s):
        raise ValueError("r_of_s must be a callable s -> (n, 3) positions")
    length = positive("length", length)
    h = 1e-5 * length if ds is None else positive("ds", ds)

    def f(s):
        r = np.asarray(r_of_s(s), float)
        if r.shape != (len(s), 3) or not np.all(np.isfinite(r)):
            raise ValueError("r_of_s(s) must return finite positions of shape (len(s), 3)")
        t = (np.asarray(r_of_s(s + h)) - np.asarray(r_of_s(s - h))) / (2 * h)
        if d1_of_s is None:
            return r, parallel_transport(s, t)
        return r, frames_from(t, np.asarray(d1_of_s(s), float))
    return Shape(length, f, "curve")


def polyline(points, d1=None):
    """Reference through ``points`` ``(m, 3)``: a cubic spline in arclength
    (chord-length parametrized, then re-parametrized by arclength).
    ``d1`` ``(m, 3)`` optional directors at the points (else parallel
    transport)."""
    from scipy.interpolate import CubicSpline
    P = np.asarray(points, float)
    if P.ndim != 2 or P.shape[1] != 3 or len(P) < 2 or not np.all(np.isfinite(P)):
        raise ValueError("points must be a finite (m, 3) array with m >= 2")
    chord = np.r_[0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]
    if np.any(np.diff(chord) <= 0):
        raise ValueError("points must be distinct consecutive points")
    spl = CubicSpline(chord, P)
    u = np.linspace(0, chord[-1], 200 * len(P))
    sp_u = np.r_[0, np.cumsum(np.linalg.norm(np.diff(spl(u), axis=0), axis=1))]
    length = sp_u[-1]
    d1spl = None if d1 is None else CubicSpline(chord, np.asarray(d1, float))

    def r_of_s(s):
        return spl(np.interp(s, sp_u, u))

    d1f = None if d1spl is None else (lambda s: d1spl(np.interp(s, sp_u, u)))
    return curve(r_of_s, length, d1f)
