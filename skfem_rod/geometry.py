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

>>> import numpy as np
>>> from skfem_rod import geometry
>>> r0, R0 = geometry.straight(1.0)(np.array([0.0, 0.5, 1.0]))
>>> R0[0]                       # columns d1 = +y, d2 = +z, d3 = +x
array([[0., 0., 1.],
       [1., 0., 0.],
       [0., 1., 0.]])
"""
import numpy as np

from .rotations import expm
from .validation import positive, finite_vector, points as _points


def _unit(v, name):
    v = finite_vector(name, v, nonzero=True)
    v = v / np.abs(v).max()                     # no overflow in the norm
    return v / np.linalg.norm(v)


def frames_from(t, d1):
    """Frames with columns (d1, d2, d3) from tangents ``t`` and ``d1``
    guesses (orthogonalized against ``t``).

    Examples
    --------
    >>> R = frames_from(np.array([[0.0, 0, 2]]), np.array([[1.0, 0, 1]]))
    >>> R[0]
    array([[1., 0., 0.],
           [0., 1., 0.],
           [0., 0., 1.]])
    """
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
    """Rotation-minimizing frames along tangents ``t`` at arclengths ``s``.

    Examples
    --------
    Along a planar circle the transported ``d1`` stays normal to the plane:

    >>> s = np.linspace(0, np.pi, 50)
    >>> t = np.c_[np.cos(s), np.sin(s), 0 * s]
    >>> R = parallel_transport(s, t, d1_start=np.array([0.0, 0.0, 1.0]))
    >>> bool(np.allclose(R[:, :, 0], [0, 0, 1]))
    True
    """
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
    """A reference shape: callable ``shape(s) -> (r0, R0)`` with a length.

    Examples
    --------
    >>> shape = Shape(2.0, lambda s: (np.c_[s, 0 * s, 0 * s], np.repeat(
    ...     [[[0.0, 0, 1], [1, 0, 0], [0, 1, 0]]], len(s), axis=0)), "my line")
    >>> r0, R0 = shape(np.array([0.0, 2.0]))
    >>> r0[1], shape
    (array([2., 0., 0.]), Shape(my line, length=2.0))
    """

    def __init__(self, length, func, name="shape"):
        self.length = positive("length", length)
        self._func = func
        self.name = name
        self.closed = False          # see closed() and ring()

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
    start = finite_vector("start", start)
    R = frames_from(t[None], d1v[None])[0]

    def f(s):
        return start + s[:, None] * t, np.broadcast_to(R, (len(s), 3, 3)).copy()
    return Shape(length, f, "straight")


def arc(radius, angle, start=(0.0, 0.0, 0.0), tangent=(1.0, 0.0, 0.0),
        toward=(0.0, 1.0, 0.0)):
    """Circular arc of ``radius`` subtending ``angle`` (rad), starting at
    ``start`` with unit ``tangent`` and curving toward ``toward``.
    ``d1`` is the inward normal (toward the centre), ``d2 = d3 x d1``.

    Examples
    --------
    A quarter circle of radius 2 from the origin along ``+x``, bending toward
    ``+y``:

    >>> shape = arc(2.0, np.pi / 2)
    >>> r0, R0 = shape(np.array([shape.length]))
    >>> np.round(r0[0], 12) + 0.0, np.round(R0[0][:, 2], 12) + 0.0   # end point, tangent
    (array([2., 2., 0.]), array([0., 1., 0.]))
    """
    radius = positive("radius", radius)
    angle = positive("angle", angle)
    t0 = _unit(tangent, "tangent")
    n0 = _unit(toward, "toward")
    n0 = n0 - np.dot(n0, t0) * t0
    if np.linalg.norm(n0) < 1e-12:
        raise ValueError(f"toward must not be parallel to tangent, got toward = "
                         f"{np.asarray(toward).tolist()} and tangent = "
                         f"{np.asarray(tangent).tolist()}")
    n0 = n0 / np.linalg.norm(n0)
    start = finite_vector("start", start)

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
    principal normal (toward the axis).

    Examples
    --------
    >>> shape = helix(radius=1.0, pitch=0.5, turns=2)
    >>> r0, _ = shape(np.array([0.0, shape.length]))
    >>> np.round(r0, 12) + 0.0
    array([[1., 0., 0.],
           [1., 0., 1.]])
    """
    radius = positive("radius", radius)
    pitch = positive("pitch", pitch)
    turns = positive("turns", turns)
    c = pitch / (2 * np.pi)
    k = np.hypot(radius, c)
    length = 2 * np.pi * turns * k
    o = finite_vector("axis_start", axis_start)

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
    ``d1_of_s`` gives the first director (else parallel transport).

    Examples
    --------
    A parabola-like arch, given by arclength (here a circle of radius 1):

    >>> shape = curve(lambda s: np.c_[np.sin(s), 1 - np.cos(s), 0 * s], length=np.pi)
    >>> r0, R0 = shape(np.array([np.pi / 2]))
    >>> np.round(r0[0], 8), np.round(R0[0][:, 2], 6) + 0.0
    (array([1., 1., 0.]), array([0., 1., 0.]))
    """
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
        d1 = np.asarray(d1_of_s(s), float)
        if d1.shape != (len(s), 3) or not np.all(np.isfinite(d1)):
            raise ValueError(f"d1_of_s(s) must return finite directors of shape "
                             f"(len(s), 3) = ({len(s)}, 3), got shape {d1.shape}")
        return r, frames_from(t, d1)
    if d1_of_s is not None and not callable(d1_of_s):
        raise ValueError(f"d1_of_s must be a callable s -> (n, 3) directors, got "
                         f"{type(d1_of_s).__name__}")
    return Shape(length, f, "curve")


def polyline(points, d1=None):
    """Reference through ``points`` ``(m, 3)``: a cubic spline in arclength
    (chord-length parametrized, then re-parametrized by arclength).
    ``d1`` ``(m, 3)`` optional directors at the points (else parallel
    transport).

    Examples
    --------
    >>> shape = polyline([[0, 0, 0], [1, 1, 0], [2, 0, 0]])
    >>> r0, _ = shape(np.array([0.0, shape.length]))
    >>> np.round(r0, 8) + 0.0
    array([[0., 0., 0.],
           [2., 0., 0.]])
    """
    from scipy.interpolate import CubicSpline
    P = _points("points", points, minimum=2)
    D = None if d1 is None else _points("d1", d1, n=len(P))
    chord = np.r_[0, np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))]
    gaps = np.diff(chord)
    if np.any(~(gaps > 1e-9 * chord[-1])):
        k = int(np.argmin(gaps))
        raise ValueError(f"points must be distinct consecutive points: points {k} and "
                         f"{k + 1} are {gaps[k]:.3g} apart, less than 1e-9 of the polyline's "
                         f"length {chord[-1]:.3g}")
    spl = CubicSpline(chord, P)
    u = np.linspace(0, chord[-1], 200 * len(P))
    sp_u = np.r_[0, np.cumsum(np.linalg.norm(np.diff(spl(u), axis=0), axis=1))]
    length = sp_u[-1]
    d1spl = None if D is None else CubicSpline(chord, D)

    def r_of_s(s):
        return spl(np.interp(s, sp_u, u))

    d1f = None if d1spl is None else (lambda s: d1spl(np.interp(s, sp_u, u)))
    return curve(r_of_s, length, d1f)


# closed rods -----------------------------------------------------------------
def closed(shape):
    """Mark ``shape`` as closed: the rod built on it is a ring whose node at
    ``s = length`` is its node at ``s = 0``.  The shape must close up,
    position and frame (checked by :class:`~skfem_rod.Rod`).

    Examples
    --------
    A full circle built with :func:`arc`, closed into a ring:

    >>> shape = closed(arc(1.0, 2 * np.pi))
    >>> shape.closed, round(shape.length, 6)
    (True, 6.283185)
    """
    if not isinstance(shape, Shape):
        raise ValueError(f"shape must be a skfem_rod.geometry shape, got {type(shape).__name__}")
    out = Shape(shape.length, shape._func, shape.name)
    out.closed = True
    return out


def ring(radius, center=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0), start=(1.0, 0.0, 0.0),
         twist_turns=0):
    """Closed circular rod (a ring) of ``radius`` about ``center``, in the
    plane normal to ``normal``, starting at ``center + radius * start``
    (``start`` projected on the plane) and running counterclockwise about
    ``normal``.  ``d1`` is the inward normal, turned about the tangent by
    ``twist_turns`` whole turns along the ring (an intrinsic twist
    ``2 pi twist_turns / length``; whole turns so that the frame closes).

    Examples
    --------
    >>> shape = ring(1.0)
    >>> shape.closed, round(shape.length, 6)
    (True, 6.283185)
    """
    radius = positive("radius", radius)
    if isinstance(twist_turns, bool) or not isinstance(twist_turns, (int, np.integer)):
        raise ValueError(f"twist_turns must be an integer (whole turns close the frame), "
                         f"got {twist_turns!r}")
    nz = _unit(normal, "normal")
    e1 = _unit(start, "start")
    e1 = e1 - np.dot(e1, nz) * nz
    if np.linalg.norm(e1) < 1e-12:
        raise ValueError(f"start must not be parallel to normal, got start = "
                         f"{np.asarray(start).tolist()}")
    e1 = e1 / np.linalg.norm(e1)
    e2 = np.cross(nz, e1)
    c = finite_vector("center", center)
    length = 2 * np.pi * radius
    n_tw = int(twist_turns)

    def f(s):
        a = s / radius
        ca, sa = np.cos(a)[:, None], np.sin(a)[:, None]
        r = c + radius * (ca * e1 + sa * e2)
        t = -sa * e1 + ca * e2
        inward = -(ca * e1 + sa * e2)
        b = np.cross(t, inward)
        ph = (2 * np.pi * n_tw * s / length)[:, None]
        d1 = np.cos(ph) * inward + np.sin(ph) * b
        return r, frames_from(t, d1)
    out = Shape(length, f, "ring")
    out.closed = True
    return out


def plectoneme(radius, ply_angle, turns, loop=None, tail=None):
    """Two-ply plectoneme: two plies wound around each other, closed by an
    end loop, with straight tails to the rod ends (parallel-transported
    frames).

    The plies are the double helix ``+-radius (cos phi, sin phi)`` about the
    ``+z`` axis, ``phi`` advancing by ``tan(ply_angle) / radius`` per unit
    height, so each ply makes the angle ``ply_angle`` with the axis and the
    two are ``2 radius`` apart at equal height (their closest approach for
    ``ply_angle < pi/4``): ``radius`` slightly below the contact radius makes
    them touch along their whole length.  The plies wind by ``turns`` full
    turns between the end loop (a planar tear drop of half-width ``loop``,
    apex up) and the base, where they stop winding, run parallel for a
    length ``loop`` and bend away from each other into straight tails along
    ``-x`` (start) and ``+x`` (end) of length ``tail``, on the line
    ``y = z = 0``.

    Construction: a curve ``c(u)``, ``u in [-U, U]``, with ``x, y`` odd and
    ``z`` even in ``u`` (the two-fold symmetry of a plectoneme about its
    axis), built from smooth functions and quintic smoothsteps (``C^2`` in
    ``u``, nonzero speed), reparametrized by arclength with Gauss quadrature
    and Newton to round-off: ``C^2`` in ``s``.  Defaults: ``loop = 8
    radius``, ``tail = 20 radius``.

    Examples
    --------
    >>> shape = plectoneme(radius=0.1, ply_angle=0.5, turns=2)
    >>> r0, _ = shape(np.array([0.0, shape.length]))
    >>> np.round(r0[:, 1:], 8) + 0.0              # both ends on the line y = z = 0
    array([[0., 0.],
           [0., 0.]])
    """
    a = positive("radius", radius)
    th = positive("ply_angle", ply_angle)
    if not th < np.pi / 4:
        raise ValueError(f"ply_angle must be in (0, pi/4) rad (plies closest at equal "
                         f"height), got {ply_angle!r}")
    turns = positive("turns", turns)
    W = 8.0 * a if loop is None else positive("loop", loop)
    if not W > 2 * a:
        raise ValueError(f"loop must exceed 2 * radius = {2 * a!r}, got {loop!r}")
    tail = 20.0 * a if tail is None else tail
    if isinstance(tail, bool) or not (isinstance(tail, (int, float, np.floating))
                                      and np.isfinite(tail) and tail >= 0):
        raise ValueError(f"tail must be a finite number >= 0, got {tail!r}")
    k, c = np.tan(th) / a, np.cos(th)        # ply phase per height; unit speed on the plies
    ell = 1.25 * W                           # loop length scale
    b = 0.5 * ell                            # apex rounding
    # u -> rho = sqrt(u^2 + b^2) - b (even, ~|u|); along rho: loop, plies
    # start winding on [rho_l, rho_l + Dl], stop on [rho_p, rho_p + Dp], then
    # turn into the tails on [rho_b, rho_b + D]
    rho_l, Dl, Dp, D = 1.5 * ell, 2.5 * ell, W, 3.0 * W
    rho_p = rho_l + 0.5 * (Dl - Dp) + turns * 2 * np.pi * a / np.sin(th)
    rho_b = rho_p + Dp
    rho_end = rho_b + D + tail

    def step(rho, r0, d):                    # quintic smoothstep, its integral, derivative
        t = np.clip((rho - r0) / d, 0.0, 1.0)
        return (t**3 * (10 - 15 * t + 6 * t * t),
                d * (t**6 - 3 * t**5 + 2.5 * t**4) + np.maximum(rho - r0 - d, 0.0),
                30 * t * t * (1 - t) ** 2 / d)

    def parts(u):
        q = np.sqrt(u * u + b * b)
        rho, drho = q - b, u / q
        (Sl, Gl, dSl), (Sp, Gp, _), (St, Gt, _) = (step(rho, rho_l, Dl), step(rho, rho_p, Dp),
                                                   step(rho, rho_b, D))
        # ply offset A (odd in u): exactly +-a once the plies wind, plus the
        # loop's bulge, switched off as the winding starts
        v = np.clip(u / ell, -1.0, 1.0)
        x = u / ell
        bump = np.exp(0.5 * (1 - x * x))
        A = a * (15 * v - 10 * v**3 + 3 * v**5) / 8 + (W - a) * x * bump * (1 - Sl)
        dA = (a * 15 * (1 - v * v) ** 2 / 8 + (W - a) * (1 - x * x) * bump * (1 - Sl)) / ell \
            - (W - a) * x * bump * dSl * drho
        z = -c * (rho - Gt)
        dz = -c * (1 - St) * drho
        phase = -k * c * (Gl - Gp)
        dphase = -k * c * (Sl - Sp) * drho
        e = np.exp(1j * (phase + phi0))
        w = A * e + np.sign(u) * Gt
        dw = (dA + 1j * dphase * A) * e + St * np.abs(drho)
        return (np.stack([w.real, w.imag, z - z_end], -1),
                np.stack([dw.real, dw.imag, dz], -1))

    z_end = -c * (rho_end - step(rho_end, rho_b, D)[1])
    phi0 = k * c * (step(rho_end, rho_l, Dl)[1] - step(rho_end, rho_p, Dp)[1])
    U = np.sqrt((rho_end + b) ** 2 - b * b)
    gx, gw = np.polynomial.legendre.leggauss(8)
    ut = np.linspace(-U, U, 20001)
    hu = ut[1] - ut[0]

    def speed(u):
        return np.linalg.norm(parts(u)[1], axis=-1)

    st = np.r_[0.0, np.cumsum(speed(ut[:-1, None] + 0.5 * hu * (gx + 1)) @ (0.5 * hu * gw))]
    length = st[-1]

    def u_of_s(s):
        u = np.interp(s, st, ut)
        kk = np.clip(np.searchsorted(ut, u) - 1, 0, len(ut) - 2)
        for _ in range(3):                   # Newton on s(u) = s
            hh = u - ut[kk]
            s_u = st[kk] + speed(ut[kk, None] + 0.5 * hh[:, None] * (gx + 1)) @ gw * 0.5 * hh
            u = u - (s_u - s) / speed(u)
        return u

    def f(s):
        r, dr = parts(u_of_s(np.clip(s, 0.0, length)))
        return r, parallel_transport(s, dr)
    return Shape(length, f, "plectoneme")
