r"""The Coulomb friction law at contact points, by the augmented Lagrangian.

Pointwise and vectorized: every argument is an array over contact points
(vectors ``(m, 3)``, scalars ``(m,)`` or plain numbers; any leading shape
that broadcasts works).  It does not know the rod: the slips are inputs, the
kinematics (eq. 3.7, 3.9) and their linearization (eq. 6.4c, 6.5, 6.7) belong
to the assembler.  One set of functions serves both laws of the paper:

=================  ==========================  ===============================
                   tangential (eq. 4.2b)       rotational (eq. 4.2c)
=================  ==========================  ===============================
slip ``g``         ``g_T``: a length           ``g_R``: an angle (rad)
force ``f``        force per unit length       couple per unit length
coefficient        ``gamma_T`` (dimensionless)  ``gamma_R``: a length
compliance ``mu``  length / (force / length)   angle / (couple / length)
=================  ==========================  ===============================

so that ``|f_T| <= gamma_T f_N`` and ``|f_R| <= gamma_R f_N`` (eq. 3.10).  A
natural pairing with the normal compliance ``mu_N`` of :mod:`.law` is
``mu_T = mu_N`` and ``mu_R = mu_N / eps^2`` (a couple ``eps f`` per rotation
``u / eps``).

Map to the paper
----------------
* :func:`project_ball`: ``P_B(tau)[a]`` of sec. 1.1, with its derivatives
  with respect to ``a`` and to the radius ``tau``.
* :func:`friction_force`: eq. 4.2b / 4.2c,
  ``f = (1/mu) P_B(mu gamma f_N)[g + mu lambda]``; the state per point
  (:data:`STICK` is the paper's ``F_T = 1`` / ``F_R = 1`` of sec. 6,
  :data:`SLIP` is ``F = 0``, :data:`OPEN` is ``f_N = 0``); the exact
  derivatives ``df/dg`` and ``df/df_N`` (eq. 6.4b / 6.6, corrected below).
* :func:`uzawa_update`: the multiplier iteration of [8] behind eq. 4.2,
  ``lambda <- f``, i.e. ``lambda <- P_B(gamma f_N)[lambda + g / mu]``.
* :func:`dissipation`: ``f . g`` (the power, or the work of a step, of
  friction); :func:`coulomb_violation` checks eq. 3.10 after a step;
  :func:`misalignment` is the force's sine to its slip, relative to the
  bound (the Uzawa loop's Coulomb test).

Slips are increments, not rates
-------------------------------
The paper writes the law with slip *rates* and backward Euler (eq. 1.1),
``g_rate = (increment) / Delta t``, hence the ``1 / (mu_T Delta t)`` of
eq. 6.4b.  Here ``g`` is the slip *increment* of the load step (from the last
converged state: ``Delta t`` times eq. 3.7 or 3.9) and ``mu`` is the paper's
``mu Delta t``, a compliance per unit slip: in stick the force grows by
``1 / mu`` per unit slip length (per unit length of rod).  The pseudo-time
step cancels: ``P_B`` is positively homogeneous,
``P_B(c tau)[c a] = c P_B(tau)[a]``, so ``(1/mu) P_B(mu gamma f_N)[g + mu lam]``
is unchanged under ``(g, mu) -> (g Delta t, mu Delta t)``: rate form with
``mu_paper`` = increment form with ``mu = mu_paper Delta t``, and the law is
rate-independent, as Coulomb's law is.  ``f . g`` is then the work dissipated
in the step (per unit length), not a power.

Signs
-----
* Slip = slave relative to master, as eq. 3.7 (``g_r = r-dot(s) -
  r-dot(s_bar) + ...``) and eq. 3.9 (``g_R = theta-dot(s) - theta-dot(s_bar)
  - ...``).
* ``f`` is the paper's ``f_T`` / ``f_R`` of eq. 3.10 / 4.2: at Coulomb
  equilibrium it points *along* the slip, ``f = gamma f_N g / |g|``.  It is
  therefore the friction force exerted **on the master**; the friction force
  **on the slave** is ``-f`` (it opposes the slave's slip).  The dissipation
  ``f . g >= 0`` (at the converged multiplier, see :func:`dissipation`).
* Weak form (residual = internal minus external work, as in
  :mod:`.assembly`, whose normal term is ``w f_N N . (delta y - delta x)``):
  friction adds ``+ w f_T . (delta r(s) - delta r(s_bar))`` and
  ``+ w f_R . (delta theta(s) - delta theta(s_bar))``, the opposite sign to
  the normal term.

Deviations from the paper
-------------------------
1. *Sign of friction in eq. 3.4 / 4.1.*  The paper adds ``f_T`` to the
   slave's balance with the same sign as ``f_N N`` (eq. 3.4:
   ``n' + f_ext + f_N N + f_T = 0``; eq. 4.1:
   ``(f_N N + f_T) . (delta r(s_bar) - delta r(s))``), i.e. as the force on
   the slave, while eq. 3.10b makes ``f_T`` point along the slave's slip:
   friction would then drive the slip (negative dissipation), and the
   stick stiffness becomes negative -- eq. 6.8 indeed carries
   ``- F_R / (mu_R Delta t) vartheta_bar . delta theta_bar``.  We keep eq.
   3.10 / 4.2 for ``f`` and put friction in the weak form with the sign
   above (force on the slave ``-f``); the stick stiffness is then
   ``+ 1 / mu`` (positive).
2. *Slip tangent (eq. 6.4b, 6.6).*  The paper's indicator ``F`` keeps only
   the stick derivative ``I / mu`` and sets the slip derivative to zero.
   The exact derivative in slip (``a = g + mu lambda``, ``e = a / |a|``) is

       df/dg   = (gamma f_N / |a|) (I - e e^T)      (symmetric, in-plane)
       df/df_N = gamma e                             (through the radius)

   The second term is the radius derivative ``d(mu gamma f_N)/d(...)`` that
   eq. 6.6 drops (it is zero in stick, so eq. 6.6 is exact there); combined
   with ``Delta f_N`` of eq. 6.4a it gives the non-symmetric friction/normal
   coupling ``gamma e (x) Delta f_N``, the usual source of non-symmetry of
   Coulomb friction (the paper attributes non-symmetry to ``K_R2`` only).
   Without both terms Newton converges at best linearly on slipping points.
3. *Open points.*  The paper's ``F(x) = 1`` for ``|x| <= mu gamma f_N``
   gives a stick stiffness ``1 / mu`` at ``f_N = 0, x = 0``, where the force
   is identically zero.  Here ``f_N = 0`` is :data:`OPEN`, with ``df/dg = 0``;
   ``df/df_N = gamma e`` is then the right derivative (``f_N`` cannot
   decrease), zero when ``a = 0``.
4. On the switch ``|a| = mu gamma f_N > 0`` the state is :data:`STICK` (the
   paper's ``<=`` in ``F``); both formulas of sec. 1.1 agree there.  "On"
   is to round-off (:data:`ON_SPHERE`, relative; the force is still
   projected onto the ball): a point that slipped in the last load step
   starts the next one with ``g = 0`` and its carried multiplier on the
   sphere, ``|mu lambda| = mu gamma f_N``, and round-off decided which
   tangent Newton's first iteration took.  The slip tangent has no
   stiffness along the slip, so where the point sticks in the new step
   the first update slid it across, the force turned to the other side
   of the ball, and Newton cycled between the two directions (measured:
   a crossing pair of the pressed figure-eight pulled sideways, the
   residual 3.5e-5 <-> 3.2e-5 for 25 iterations at every step size down
   to 6e-5 of the load; with the stick tangent first, 3-5 iterations per
   step, docs/crossing-contact.md).

The law itself does not project ``g`` on a tangent plane or on the
``d_3`` axis: eq. 3.7 / 3.9 / 4.2 use full vectors.  If the caller projects
``g`` and ``lambda`` onto a subspace, ``f`` stays in it (the ball projection
only rescales).
"""
from enum import IntEnum
from typing import NamedTuple

import numpy as np

from ..rotations import cross


#: ``|a| <= tau (1 + ON_SPHERE)`` is inside the ball (the stick state): a
#: point on the sphere to round-off sticks (module doc, deviation 4)
ON_SPHERE = 1e-9


class FrictionState(IntEnum):
    """State of a contact point (an ``int`` array of these is returned)."""
    OPEN = 0    # f_N = 0: no normal force, no friction
    STICK = 1   # |g + mu lambda| <= mu gamma f_N: f = g / mu + lambda
    SLIP = 2    # |g + mu lambda| >  mu gamma f_N: |f| = gamma f_N


OPEN, STICK, SLIP = FrictionState.OPEN, FrictionState.STICK, FrictionState.SLIP


class BallProjection(NamedTuple):
    """``P_B(tau)[a]`` and its derivatives (``None`` if not asked for)."""
    value: np.ndarray        # (..., 3)
    d_point: np.ndarray      # (..., 3, 3): dP/da
    d_radius: np.ndarray     # (..., 3):    dP/dtau
    inside: np.ndarray       # (...,) bool: |a| <= tau and tau > 0


class FrictionResult(NamedTuple):
    """Friction force, state and exact derivatives per point."""
    force: np.ndarray           # (..., 3)
    state: np.ndarray           # (...,) int: OPEN / STICK / SLIP
    dforce_dslip: np.ndarray    # (..., 3, 3): df/dg
    dforce_dnormal: np.ndarray  # (..., 3):    df/df_N


def _vectors(*arrays):
    out = [np.asarray(a, dtype=float) for a in arrays]
    for a in out:
        if a.ndim == 0 or a.shape[-1] != 3:
            raise ValueError(f"expected vectors of shape (..., 3), got shape {a.shape}")
    return out


def _nonnegative(name, x, strict=False):
    x = np.asarray(x, dtype=float)
    bad = ~(x > 0) if strict else ~(x >= 0)          # also catches NaN
    if np.any(bad):
        raise ValueError(f"{name} must be {'> 0' if strict else '>= 0'}, "
                         f"got {x[bad].ravel()[:3]}")
    return x


def project_ball(a, radius, derivatives=True):
    r"""Projection ``P_B(tau)[a]`` on the centred ball of radius ``tau >= 0``
    (sec. 1.1), batched, and its derivatives:

    * inside (``|a| <= tau``, ``tau > 0``): ``P = a``, ``dP/da = I``,
      ``dP/dtau = 0``;
    * outside: ``P = tau e``, ``dP/da = (tau / |a|) (I - e e^T)``,
      ``dP/dtau = e``, with ``e = a / |a|`` (``e = 0`` when ``a = 0``, which
      with ``tau = 0`` is the degenerate ball ``{0}``: ``P = 0``,
      ``dP/da = 0``, ``dP/dtau = 0``).

    ``a``: ``(..., 3)``; ``radius``: broadcastable to ``a.shape[:-1]``.
    """
    (a,) = _vectors(a)
    tau = _nonnegative("ball radius", radius)
    shape = np.broadcast_shapes(a.shape[:-1], tau.shape)
    a = np.broadcast_to(a, shape + (3,))
    tau = np.broadcast_to(tau, shape)
    norm = np.linalg.norm(a, axis=-1)
    # on the sphere to round-off counts as inside (module doc, 4): a point
    # that slipped in the last step starts the next one there
    inside = (norm <= tau * (1.0 + ON_SPHERE)) & (tau > 0)
    safe = np.where(norm > 0, norm, 1.0)
    e = a / safe[..., None]                         # 0 where a = 0
    value = np.where(inside[..., None], a * np.minimum(1.0, tau / safe)[..., None],
                     tau[..., None] * e)
    if not derivatives:
        return BallProjection(value, None, None, inside)
    eye = np.eye(3)
    scale = np.where(inside, 1.0, tau / safe)       # 0 where a = 0 (then tau = 0)
    outer = np.where(inside[..., None, None], 0.0, e[..., :, None] * e[..., None, :])
    d_point = scale[..., None, None] * (eye - outer)
    d_radius = np.where(inside[..., None], 0.0, e)
    return BallProjection(value, d_point, d_radius, inside)


def _augmented(g, lam, mu, gamma, fN):
    g, lam = _vectors(g, lam)
    mu = _nonnegative("friction compliance mu", mu, strict=True)
    gamma = _nonnegative("friction coefficient gamma", gamma)
    fN = _nonnegative("normal force f_N", fN)
    return g + mu[..., None] * lam, mu * gamma * fN, mu, gamma, fN


def friction_force(g, lam, mu, gamma, fN):
    r"""Coulomb friction by the augmented Lagrangian (eq. 4.2b / 4.2c):

        f = (1/mu) P_B(mu gamma f_N)[g + mu lambda].

    g : slip increment of the step, slave relative to master (eq. 3.7 or
        3.9 times ``Delta t``), ``(..., 3)``.
    lam : the multiplier ``lambda`` (last Uzawa iterate), ``(..., 3)``.
    mu : compliance (``> 0``; the paper's ``mu Delta t``).
    gamma : friction coefficient (``>= 0``; a length for the rotational law).
    fN : normal force per unit length (``>= 0``, eq. 4.2a).

    Returns :class:`FrictionResult` ``(force, state, dforce_dslip,
    dforce_dnormal)``: ``f`` (the force on the master; the slave gets
    ``-f``), the state (:data:`OPEN`, :data:`STICK`, :data:`SLIP`) and the
    exact derivatives ``df/dg = (1/mu) dP/da`` (``I / mu`` in stick,
    ``(gamma f_N / |a|)(I - e e^T)`` in slip) and
    ``df/df_N = gamma dP/dtau`` (0 in stick, ``gamma e`` in slip).
    ``df/dlambda = mu df/dg``.
    """
    a, tau, mu, gamma, fN = _augmented(g, lam, mu, gamma, fN)
    p = project_ball(a, tau)
    shape = p.inside.shape
    force = p.value / mu[..., None]
    dfdg = p.d_point / mu[..., None, None]
    dfdn = np.broadcast_to(gamma, shape)[..., None] * p.d_radius
    state = np.where(p.inside, int(STICK), int(SLIP))
    state = np.where(np.broadcast_to(fN, shape) > 0, state, int(OPEN))
    return FrictionResult(force, state, dfdg, dfdn)


def uzawa_update(g, lam, mu, gamma, fN):
    r"""Multiplier update ``lambda <- f = P_B(gamma f_N)[lambda + g / mu]``
    (the projected multiplier; always ``|lambda| <= gamma f_N``).  Its fixed
    points are the Coulomb solutions: ``g = 0`` in stick, and in slip
    ``|lambda| = gamma f_N`` with ``g = c lambda``, ``c >= 0``."""
    a, tau, mu, _, _ = _augmented(g, lam, mu, gamma, fN)
    return project_ball(a, tau, derivatives=False).value / mu[..., None]


def dissipation(f, g):
    r"""``f . g`` per point: the friction work dissipated over the step
    (``g`` an increment) per unit length, or its power (``g`` a rate).

    What is guaranteed: ``f . (g + mu lambda) >= 0`` always (``f`` is a
    non-negative multiple of ``g + mu lambda``), so ``f . g >= 0`` for the
    pure penalty (``lambda = 0``) and at the converged multiplier
    (``lambda = f``, the fixed point of :func:`uzawa_update`), where
    moreover ``f . g = gamma f_N |g|`` (maximal dissipation: ``f . g >= t . g``
    for every admissible ``|t| <= gamma f_N``).  For an arbitrary, not yet
    converged ``lambda`` it may be negative."""
    f, g = _vectors(f, g)
    return np.einsum("...i,...i->...", f, g)


def coulomb_violation(f, g, gamma, fN):
    r"""How far ``(f, g)`` is from Coulomb's law (eq. 3.10), per point:
    ``(excess, dissipation_gap)`` with ``excess = max(|f| - gamma f_N, 0)``
    (the bound) and ``dissipation_gap = gamma f_N |g| - f . g`` (``>= 0``
    when the bound holds; zero iff ``g = 0`` or ``f = gamma f_N g / |g|``).
    Both vanish (to round-off) at a converged Uzawa iterate."""
    f, g = _vectors(f, g)
    bound = np.asarray(gamma, float) * np.asarray(fN, float)
    excess = np.maximum(np.linalg.norm(f, axis=-1) - bound, 0.0)
    gap = bound * np.linalg.norm(g, axis=-1) - dissipation(f, g)
    return excess, gap


def misalignment(f, g, gamma, fN):
    r"""Per point, the component of the friction force ``f`` across the slip
    ``g``, relative to the bound ``gamma f_N``: ``|f x g| / (|g| gamma f_N)``,
    the sine of the angle between force and slip where ``|f| = gamma f_N``
    (a slipping point, eq. 3.10).  Zero where ``g = 0`` or the bound is zero
    (no direction to follow).  The Uzawa loop stops only when it is below
    ``friction_tolerance`` at the points that slip
    (:func:`skfem_rod.contact.friction_assembly.coulomb_misfit`)."""
    f, g = _vectors(f, g)
    bound = np.asarray(gamma, float) * np.asarray(fN, float)
    gn = np.linalg.norm(g, axis=-1)
    across = np.linalg.norm(cross(f, g), axis=-1)
    ok = (gn > 0) & (bound > 0)
    return np.divide(across, gn * bound, out=np.zeros(np.broadcast(across, bound).shape),
                     where=ok)
