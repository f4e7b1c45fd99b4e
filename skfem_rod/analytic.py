r"""Reference solutions used to verify the finite-element rod solver.

Conventions
-----------
* Planar problems live in the x-y plane.  The rod is clamped at ``s = 0``
  with its tangent along ``+x``; ``s`` is the arclength of the *reference*
  (unstressed, straight) configuration, ``0 <= s <= L``.
* ``theta(s)`` is the angle of the cross-section (the director ``d_3`` of
  :mod:`skfem_rod.rotations`, here ``d = (cos theta, sin theta)``) measured
  counter-clockwise from ``+x``, i.e. a rotation about ``+z``.
* Internal force ``n(s)`` and moment ``m(s)`` are those exerted by the part
  ``s' > s`` on the part ``s' < s``.  Without distributed loads
  ``n' = 0`` and ``m' + (r' x n)_z = 0``.  Bending: ``m = EI theta'``.
* Material-frame strains of the Reissner rod: with section tangent
  ``d = (cos theta, sin theta)`` and normal ``e = (-sin theta, cos theta)``,
  axial force ``N = n . d``, shear force ``Q = n . e``, axial strain
  ``eps = N / EA``, shear strain ``gamma = Q / GA`` and
  ``r' = (1 + eps) d + gamma e``.  ``EA = GA = None`` means inextensible
  and unshearable (``eps = gamma = 0``).
* Tip displacements: ``u = L - x(L)`` (shortening along the axis, positive
  when the tip moves towards the clamp) and ``v = y(L)``.

Only NumPy and SciPy are used.
"""
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_bvp
from scipy.optimize import brentq
from scipy.special import ellipeinc, ellipkinc

__all__ = [
    "Rollup", "rollup",
    "CantileverSolution", "elastica_cantilever", "elastica_tip_elliptic",
    "greenhill_critical_moment", "greenhill_factor", "twist_torque", "clamped_rod_shooting",
    "LocalizedWrithing", "localized_writhing",
]


# --------------------------------------------------------------------------
# pure bending: the roll-up of a cantilever into a circle
# --------------------------------------------------------------------------
@dataclass
class Rollup:
    """Exact roll-up configuration (see :func:`rollup`)."""

    kappa: float
    s: np.ndarray
    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray


def rollup(length, EI, moment, s):
    r"""Straight cantilever bent into a circular arc by an end moment.

    The rod is clamped at ``s = 0`` along ``+x``; the moment ``moment``
    about ``+z`` acts at ``s = length``.  The bending moment is constant,
    so the curvature is ``kappa = moment / EI`` and

    .. math::
        x = \sin(\kappa s)/\kappa,\quad
        y = (1 - \cos(\kappa s))/\kappa,\quad
        \theta = \kappa s.

    The axial and shear forces vanish, so extensibility and shear
    flexibility do not change the result.  The formulas are evaluated in a
    form (``np.sinc``) that is exact also for ``kappa -> 0``.

    Parameters
    ----------
    length : float
        Rod length ``L`` (only used to check that ``s`` lies in ``[0, L]``).
    EI : float
        Bending stiffness.
    moment : float
        End moment about ``+z``; ``moment = 2 pi EI / L`` closes a full
        circle.
    s : array_like
        Reference arclengths at which to evaluate.

    Returns
    -------
    Rollup
        Dataclass with ``kappa`` and arrays ``s, x, y, theta``.

    Examples
    --------
    >>> r = rollup(1.0, 2.0, 2 * np.pi, [0.0, 1.0])  # half circle, r = 1/pi
    >>> np.round([r.x[-1], r.y[-1], r.theta[-1]], 8) + 0.0
    array([0.        , 0.63661977, 3.14159265])
    """
    s = np.asarray(s, dtype=float)
    if np.any(s < 0) or np.any(s > length * (1 + 1e-14)):
        raise ValueError("arclengths must lie in [0, length]")
    kappa = float(moment) / float(EI)
    a = kappa * s
    x = s * np.sinc(a / np.pi)                       # sin(a)/kappa
    y = 0.5 * kappa * s**2 * np.sinc(a / (2 * np.pi))**2   # (1 - cos a)/kappa
    return Rollup(kappa=kappa, s=s, x=x, y=y, theta=a)


# --------------------------------------------------------------------------
# tip-loaded cantilever (elastica / planar Reissner rod)
# --------------------------------------------------------------------------
@dataclass
class CantileverSolution:
    """Solution of :func:`elastica_cantilever`.

    ``x(s)``, ``y(s)``, ``theta(s)``, ``m(s)`` evaluate the collocation
    solution (a C1 cubic spline, 4th-order accurate) at any arclength.
    ``tip_error`` is the change of the tip values ``(u, v, theta(L))`` under
    one uniform mesh refinement; it bounds the discretization error.
    """

    load_parameter: float
    length: float
    EI: float
    EA: float | None
    GA: float | None
    force: float
    nodes: np.ndarray
    tip_error: float
    _sol: object = field(repr=False)

    def _eval(self, s, i):
        return self._sol(np.asarray(s, dtype=float))[i]

    def x(self, s):
        """Horizontal position at arclength(s) ``s``."""
        return self._eval(s, 0)

    def y(self, s):
        """Vertical position at arclength(s) ``s``."""
        return self._eval(s, 1)

    def theta(self, s):
        """Section angle at arclength(s) ``s``."""
        return self._eval(s, 2)

    def m(self, s):
        """Bending moment ``EI theta'`` at arclength(s) ``s``."""
        return self._eval(s, 3)

    @property
    def tip_u(self):
        """Axial shortening ``L - x(L)``."""
        return self.length - float(self.x(self.length))

    @property
    def tip_v(self):
        """Transverse tip displacement ``y(L)``."""
        return float(self.y(self.length))

    @property
    def tip_angle(self):
        """Tip rotation ``theta(L)``."""
        return float(self.theta(self.length))


def _cantilever_system(P, EI, cA, cG):
    """Right-hand side, boundary conditions and Jacobians.

    State ``z = (x, y, theta, m)``; ``cA = 1/EA``, ``cG = 1/GA`` (0 for
    rigid).  With ``n = (0, P)``: ``N = P sin(theta)``, ``Q = P cos(theta)``.
    """
    c = P * (cA - cG)

    def fun(s, z):
        th, m = z[2], z[3]
        sn, cs = np.sin(th), np.cos(th)
        xp = cs + c * sn * cs
        yp = sn + P * (cA * sn**2 + cG * cs**2)
        return np.vstack([xp, yp, m / EI, -P * xp])

    def fun_jac(s, z):
        th = z[2]
        dxp = -np.sin(th) + c * np.cos(2 * th)
        dyp = np.cos(th) + c * np.sin(2 * th)
        J = np.zeros((4, 4, th.size))
        J[0, 2] = dxp
        J[1, 2] = dyp
        J[2, 3] = 1.0 / EI
        J[3, 2] = -P * dxp
        return J

    def bc(za, zb):
        return np.array([za[0], za[1], za[2], zb[3]])

    Ja = np.zeros((4, 4))
    Ja[0, 0] = Ja[1, 1] = Ja[2, 2] = 1.0
    Jb = np.zeros((4, 4))
    Jb[3, 3] = 1.0

    def bc_jac(za, zb):
        return Ja, Jb

    return fun, bc, fun_jac, bc_jac


def _solve(P, EI, cA, cG, s, z, tol, max_nodes):
    fun, bc, fun_jac, bc_jac = _cantilever_system(P, EI, cA, cG)
    res = solve_bvp(fun, bc, s, z, fun_jac=fun_jac, bc_jac=bc_jac, tol=tol,
                    bc_tol=tol, max_nodes=max_nodes)
    if res.status != 0:
        raise RuntimeError(f"solve_bvp failed (P = {P}): {res.message}")
    return res


def elastica_cantilever(load_parameter, n=401, EA=None, GA=None, EI=1.0,
                        length=1.0, tol=1e-10, max_step=1.0):
    r"""Planar cantilever under a dead tip force, solved to high accuracy.

    Clamped at ``s = 0`` along ``+x``; a fixed-direction force
    ``P = load_parameter * EI / L**2`` in ``+y`` acts at ``s = L``.  The
    internal force is constant, ``n = (0, P)``, and the boundary-value
    problem (see the module docstring for the conventions) is

    .. math::
        x' &= (1 + \varepsilon)\cos\theta - \gamma\sin\theta, &
        y' &= (1 + \varepsilon)\sin\theta + \gamma\cos\theta, \\
        EI\,\theta' &= m, & m' &= -P\,x',

    with ``eps = P sin(theta)/EA``, ``gamma = P cos(theta)/GA`` and
    ``x(0) = y(0) = theta(0) = 0``, ``m(L) = 0``.  With ``EA = GA = None``
    this is the classical inextensible elastica ``EI theta'' = -P cos theta``.
    With ``EA == GA`` the strain ``eps d + gamma e = n / EA`` is a constant
    vector, so the shape is the elastica shifted by ``P s / EA`` in ``y``.

    It is solved with :func:`scipy.integrate.solve_bvp` (analytic
    Jacobians), by continuation in the load from the linear beam solution
    in steps of at most ``max_step`` in ``load_parameter``.  The final solve
    is repeated on a uniformly refined mesh; the change of the tip values is
    stored as ``tip_error``.

    Parameters
    ----------
    load_parameter : float
        ``alpha = P L**2 / EI`` (negative values load in ``-y``).
    n : int
        Number of nodes of the initial uniform mesh (``solve_bvp`` may add
        more to reach ``tol``).
    EA, GA : float or None
        Axial and shear stiffness; ``None`` means rigid.
    EI, length : float
        Bending stiffness and rod length.
    tol : float
        Tolerance of the final ``solve_bvp`` (residual and boundary
        conditions).  The default gives tip values accurate to about
        1e-14; much smaller values hit the round-off floor of the
        residual estimate and exhaust the node budget.
    max_step : float
        Largest increment of ``load_parameter`` per continuation step.

    Returns
    -------
    CantileverSolution

    Examples
    --------
    >>> sol = elastica_cantilever(1.0)
    >>> round(sol.tip_v, 7), round(sol.tip_u, 7)
    (0.3017208, 0.0564332)
    >>> float(sol.y(0.5)) < sol.tip_v
    True
    """
    alpha = float(load_parameter)
    L, EI = float(length), float(EI)
    cA = 0.0 if EA is None else 1.0 / float(EA)
    cG = 0.0 if GA is None else 1.0 / float(GA)
    max_nodes = 200 * n + 10000

    # linear (Euler-Bernoulli) solution for the first continuation step
    nsteps = max(1, int(np.ceil(abs(alpha) / max_step)))
    alphas = alpha * np.arange(1, nsteps + 1) / nsteps
    P0 = alphas[0] * EI / L**2
    s = np.linspace(0.0, L, n)
    z = np.vstack([s,
                   P0 / EI * (L * s**2 / 2 - s**3 / 6),
                   P0 / EI * (L * s - s**2 / 2),
                   P0 * (L - s)])
    for i, a in enumerate(alphas):
        P = a * EI / L**2
        final = i == nsteps - 1
        res = _solve(P, EI, cA, cG, s, z, tol if final else 1e-6, max_nodes)
        s, z = res.x, res.y

    # convergence check: uniform refinement of the converged mesh
    s2 = np.sort(np.concatenate([s, 0.5 * (s[1:] + s[:-1])]))
    res2 = _solve(P, EI, cA, cG, s2, res.sol(s2), tol, 2 * max_nodes)

    def tip(r):
        zL = r.sol(L)
        return np.array([L - zL[0], zL[1], zL[2]])

    tip_error = float(np.max(np.abs(tip(res2) - tip(res))))
    return CantileverSolution(load_parameter=alpha, length=L, EI=EI, EA=EA,
                              GA=GA, force=P, nodes=res2.x,
                              tip_error=tip_error, _sol=res2.sol)


def elastica_tip_elliptic(load_parameter):
    r"""Tip of the inextensible cantilever elastica from elliptic integrals.

    Independent closed-form route (Bisshopp & Drucker 1945) used to check
    :func:`elastica_cantilever`.  For unit length and ``alpha = P L^2/EI``
    the first integral of ``theta'' = -alpha cos(theta)`` with
    ``theta'(1) = 0`` is ``theta'^2 = 2 alpha (sin phi0 - sin theta)``,
    ``phi0 = theta(1)``.  The substitution
    ``1 + sin(theta) = 2 k^2 sin^2(psi)``, ``k = sin(pi/4 + phi0/2)``, gives

    .. math::
        \sqrt{\alpha} = F(k) - F(\psi_1, k), \qquad
        \sin\psi_1 = 1/(\sqrt{2}\,k),

    which is solved for ``phi0``.  Then
    ``v/L = 1 - 2 (E(k) - E(psi1, k)) / sqrt(alpha)`` and, from
    ``m(0) = P x(L)``, ``1 - u/L = sqrt(2 sin(phi0) / alpha)``.

    Parameters
    ----------
    load_parameter : float
        ``alpha = P L**2 / EI > 0``.

    Returns
    -------
    dict
        ``{"tip_angle": phi0, "u": u/L, "v": v/L}``.

    Examples
    --------
    >>> t = elastica_tip_elliptic(1.0)
    >>> round(t["v"], 7), round(t["u"], 7)
    (0.3017208, 0.0564332)
    """
    alpha = float(load_parameter)
    if alpha <= 0:
        raise ValueError("load_parameter must be positive")

    def parts(phi0):
        m = np.sin(np.pi / 4 + phi0 / 2) ** 2          # parameter m = k^2
        psi1 = np.arcsin(np.sqrt(0.5 / m))
        return m, psi1

    def residual(phi0):
        m, psi1 = parts(phi0)
        return ellipkinc(np.pi / 2, m) - ellipkinc(psi1, m) - np.sqrt(alpha)

    # residual(0) = -sqrt(alpha) < 0 and residual -> +inf as phi0 -> pi/2
    phi0 = brentq(residual, 0.0, np.pi / 2 * (1 - 1e-15), xtol=1e-15,
                  rtol=4 * np.finfo(float).eps, maxiter=500)
    m, psi1 = parts(phi0)
    dE = ellipeinc(np.pi / 2, m) - ellipeinc(psi1, m)
    v = 1.0 - 2.0 * dE / np.sqrt(alpha)
    u = 1.0 - np.sqrt(2.0 * np.sin(phi0) / alpha)
    return {"tip_angle": float(phi0), "u": float(u), "v": float(v)}


# --------------------------------------------------------------------------
# small closed-form results
# --------------------------------------------------------------------------
def greenhill_critical_moment(B, T):
    """Greenhill's critical twisting moment ``2 sqrt(B T)``.

    A long rod with bending stiffness ``B`` under tension ``T`` buckles
    into a helix when the axial twisting moment exceeds this value.

    Examples
    --------
    >>> float(greenhill_critical_moment(2.0, 8.0))
    8.0
    """
    return 2.0 * np.sqrt(B * T)


def greenhill_factor(length):
    """Clamped-length factor ``m = M_c / 2 sqrt(B T)`` of Greenhill's threshold.

    A rod clamped at both ends (one end free to slide along the axis),
    ``length`` long in units of ``lambda = sqrt(B/T)``, loses the straight
    twisted equilibrium at ``M_c = 2 sqrt(B T) m``; ``m`` is the first root
    of the clamped-clamped condition (derived in docs/twisted_rod.md).
    ``m -> 1`` for a long rod and ``m L -> 4.49`` (Euler's clamped value,
    tension free) for a short one.

    Examples
    --------
    >>> round(greenhill_factor(50.0), 6)
    1.001978
    """
    Lt = float(length)
    if not np.isfinite(Lt) or Lt <= 0:
        raise ValueError(f"greenhill_factor: length must be a positive finite number, got {length!r}")

    def f(b):
        return 2 * (np.cos(b * Lt) - np.cos(np.sqrt(b * b + 1) * Lt)) - Lt * np.sin(b * Lt) / b

    bs = np.linspace(1e-9, 20.0 / Lt, 200001)
    fv = f(bs)
    i = np.flatnonzero(np.sign(fv[:-1]) != np.sign(fv[1:]))[0]
    b = brentq(f, bs[i], bs[i + 1], xtol=1e-15)
    return float(np.sqrt(b * b + 1))


def twist_torque(GJ, angle, length):
    """Torque ``GJ * angle / length`` of a straight rod twisted by ``angle``.

    Examples
    --------
    >>> twist_torque(3.0, np.pi, 2.0) == 1.5 * np.pi
    True
    """
    return GJ * angle / length


# --------------------------------------------------------------------------
# localized writhing of a clamped rod (the localizing helix)
# --------------------------------------------------------------------------
@dataclass
class LocalizedWrithing:
    """The localized writhing solution of :func:`localized_writhing`.

    Attributes
    ----------
    moment, tension : the end twisting moment ``M`` and the end tension
        ``T`` (forces and moments, not the dimensionless ``m, tau``).
    m, tau : ``M L / B`` and ``T L^2 / B``.
    c : ``m / (2 sqrt(tau)) = cos(theta_max / 2)``.
    theta_max : largest angle between the tangent and the axis (rad).
    position : callable ``s -> (n, 3)`` centreline of the localizing
        helix, ``0 <= s <= L``, axis along ``+z`` from the origin (the
        infinite-rod solution; at the ends it is straight to the relative
        accuracy ``exp(-pi sqrt(4 t - m_z^2) / 2)``, 2e-5 for the case of
        PyElastica's example).
    """
    moment: float
    tension: float
    m: float
    tau: float
    c: float
    theta_max: float
    position: object = field(repr=False)


def localized_writhing(B, C, length, shortening, rotation):
    r"""Localized writhing of a straight rod clamped at both ends, its ends
    brought together by ``shortening`` along the axis and turned relative
    to each other by ``rotation`` (rad) about it; inextensible, unshearable,
    isotropic bending stiffness ``B``, torsional stiffness ``C``.

    The equilibrium is the localizing helix of the infinite rod (van der
    Heijden, Neukirch, Goss & Thompson, Int. J. Mech. Sci. 45 (2003)
    161-196, their (27) and (52)); the end conditions give, with ``m = M
    L / B``, ``tau = T L^2 / B``, ``gamma = C / B`` (van der Heijden,
    Champneys & Thompson, "Writhing instabilities of twisted rods: from
    infinite to finite length", 2001, (13)-(15)),

    .. math::

        \frac{D}{L} = \sqrt{\frac{16}{\tau}\Big(1 - \frac{m^2}{4\tau}\Big)},
        \qquad R = \frac{m}{\gamma} + 4 \arccos\frac{m}{2\sqrt{\tau}},
        \qquad \cos\theta_{max} = \frac{m^2}{2\tau} - 1,

    the rotation absorbed by twist ``m / gamma = M L / C`` and by writhe
    ``4 arccos(...)``.  These are the relations PyElastica's helical
    buckling example is checked against (Gazzola et al., R. Soc. open sci.
    2018, 3.4.1).

    Examples
    --------
    >>> w = localized_writhing(1.345, 0.789, 100.0, 3.0, 27 * 2 * np.pi)
    >>> round(w.m, 4), round(w.tau, 2), round(w.theta_max, 4)
    (98.5415, 2900.99, 0.8317)
    """
    B, C, L, D, Rot = (float(v) for v in (B, C, length, shortening, rotation))
    for name, v in (("B", B), ("C", C), ("length", L), ("shortening", D),
                    ("rotation", Rot)):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
    gamma = C / B
    d = D / L
    # with c = m / (2 sqrt(tau)) = cos(theta_max / 2): tau = 16 (1 - c^2) / d^2
    # and m = 8 c sqrt(1 - c^2) / d, so R(c) = m / gamma + 4 arccos(c) is one
    # equation in c; on 1/sqrt(2) < c < 1 (theta_max < 90 degrees) it falls
    # monotonically from 4 / (gamma d) + pi to 0: one root there.
    def rotation_of(c):
        return 8.0 * c * np.sqrt(1.0 - c * c) / (gamma * d) + 4.0 * np.arccos(c)

    lo, hi = 1.0 / np.sqrt(2.0), 1.0
    if not Rot < rotation_of(lo):
        raise ValueError(f"rotation={Rot!r} is beyond the localized writhing branch for "
                         f"shortening={D!r} (at most 4 B L / (C D) + pi = "
                         f"{rotation_of(lo):.6g} rad)")
    c = brentq(lambda c: rotation_of(c) - Rot, lo, hi, xtol=1e-15, rtol=1e-15)
    tau = 16.0 * (1.0 - c * c) / d ** 2
    m = 8.0 * c * np.sqrt(1.0 - c * c) / d
    m, tau, c = float(m), float(tau), float(c)
    M, T = m * B / L, tau * B / L ** 2
    theta_max = float(np.arccos(np.clip(m * m / (2.0 * tau) - 1.0, -1.0, 1.0)))
    t = tau / (4.0 * np.pi ** 2)
    mz = m / (2.0 * np.pi)
    root = np.sqrt(4.0 * t - mz * mz)

    def position(s):
        u = np.asarray(s, dtype=float) / L - 0.5          # -1/2 .. 1/2
        a = root / (2.0 * np.pi * t)
        x = a * np.sin(mz * np.pi * u) / np.cosh(np.pi * u * root)
        y = -a * np.cos(mz * np.pi * u) / np.cosh(np.pi * u * root)
        z = u - a * np.tanh(np.pi * u * root)
        z0 = -0.5 + a * np.tanh(0.5 * np.pi * root)           # z at s = 0
        return np.stack([x, y, z - z0], axis=-1) * L

    return LocalizedWrithing(moment=M, tension=T, m=m, tau=tau, c=c, theta_max=theta_max,
                             position=position)


# --------------------------------------------------------------------------
# a clamped 3D rod with a dead tip force: shooting on the rod equations
# --------------------------------------------------------------------------
def clamped_rod_shooting(C, v0, u0, R0, length, forces, rtol=1e-12):
    r"""Tips of a clamped Simo-Reissner rod under dead tip forces, by
    shooting on the 3D rod equations (independent of the finite elements):

        r' = R v,   R' = R hat(u),   n = F,   m' = -r' x n,
        (v, u) = (v0, u0) + C^-1 (R^T n, R^T m),

    with ``r(0) = 0``, ``R(0) = R0`` and the unknown ``m(0)`` found from
    ``m(L) = 0`` (DOP853 at ``rtol``; Newton with continuation through the
    forces in the given order, so list them increasing).

    Parameters
    ----------
    C : (6, 6) section stiffness, order ``(v1, v2, v3, u1, u2, u3)``.
    v0, u0 : (3,) constant reference strains (``u0 = e2 / radius`` for an arc
        whose ``d1`` points to its centre).
    R0 : (3, 3) frame at ``s = 0``.
    length : arclength.
    forces : sequence of (3,) dead tip forces.

    Returns
    -------
    list of (3,) tip positions, one per force.

    Examples
    --------
    A straight cantilever along ``d3 = +x`` under a small tip force: the tip
    deflects by ``F L^3 / 3 EI + F L / GA`` (to first order in ``F``).

    >>> import numpy as np
    >>> C = np.diag([1e6, 1e6, 1e6, 1.0, 1.0, 1.0])
    >>> R0 = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    >>> tip = clamped_rod_shooting(C, [0, 0, 1], [0, 0, 0], R0, 1.0, [[0, 1e-3, 0]])[0]
    >>> bool(abs(tip[1] / (1e-3 / 3 + 1e-9) - 1) < 1e-6)       # linear theory
    True
    """
    from scipy.integrate import solve_ivp
    from scipy.optimize import fsolve
    Ci = np.linalg.inv(np.asarray(C, float))
    eps0 = np.r_[np.asarray(v0, float), np.asarray(u0, float)]
    R0 = np.asarray(R0, float)

    def rhs(s, y, F):
        R, m = y[3:12].reshape(3, 3), y[12:]
        e = eps0 + Ci @ np.r_[R.T @ F, R.T @ m]
        v, u = e[:3], e[3:]
        uhat = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
        rp = R @ v
        return np.r_[rp, (R @ uhat).ravel(), -np.cross(rp, F)]

    def shoot(m0, F):
        sol = solve_ivp(rhs, (0.0, length), np.r_[0, 0, 0, R0.ravel(), m0],
                        args=(F,), method="DOP853", rtol=rtol, atol=rtol * 1e-2)
        return sol.y[:, -1]

    tips, m0 = [], np.zeros(3)
    for F in forces:
        F = np.asarray(F, float)
        m0 = fsolve(lambda m: shoot(m, F)[12:], m0, xtol=1e-13)
        yL = shoot(m0, F)
        scale = max(np.linalg.norm(F) * length, 1e-300)
        if not np.linalg.norm(yL[12:]) < 1e-6 * scale:
            raise RuntimeError(f"shooting did not reach m(L) = 0 for F = {F.tolist()}: "
                               f"|m(L)| = {np.linalg.norm(yL[12:]):.3e}")
        tips.append(yL[:3])
    return tips
