r"""Newton-Raphson with the consistent tangent: the one Newton loop of the
package (load steps, continuation correctors, proximal steps of the
gradient flow, stability paths all call :func:`newton`).

The loop, in plain sight::

    evaluate G(y, lam), K(y, lam)
    repeat:
        converged when |G_free| <= rtol * force scale (or the update is
            below increment_tol and did not raise the residual more than
            10 times), the prescribed motions are all applied and
            (continuation) the arclength equation holds; where the residual
            jumps up from its least, no update is admissible or the
            iterations run out: the least iterate, if its residual is at
            its round-off floor (at_floor), else failure
        solve K dy = -G - K p   (p: what is left of the prescribed motion)
        continuation: the bordered system adds dlam (two back substitutions)
        safeguard: scale dy so that no spin exceeds max_spin_update; halve
            while the trial leaves an element chart, is not finite, would
            carry a strand through another (contact on), or raises the
            residual more than max_growth times
        y <- y (+) alpha dy,  lam <- lam + alpha dlam

The force scale is :meth:`skfem_rod.problem.Problem.force_scale`: loads on
the free dofs and the forces the supports take up, never a load that acts
on a supported dof (that one cannot decide convergence).
"""
from dataclasses import dataclass

import numpy as np

from .kinematics import ElementRotationError
# Report, the position correction and its threshold live in problem.py
# (the generalized Newton of nonsmooth.py uses them too); re-exported here
from .problem import CORRECT_ABOVE, Report, clearance_ok, position_correction  # noqa: F401
from .problem import Increment, State, settled, spin_cap, start, update_size
# the least iterate at its round-off floor: problem.py (the generalized
# Newton of nonsmooth.py accepts it too); re-exported here
from .problem import Iterate, at_floor  # noqa: F401
from .problem import failed as _fail


#: Newton returns its least iterate, if at the round-off floor
#: (:func:`at_floor`), once the residual rose above this multiple of it: an
#: update that round-off decided (along a very soft mode the residual
#: jumps by 1e4 and more).  Not less: at a floor that the residual
#: fluctuates about while the updates still converge (a cantilever with
#: EA = 1e8 EI/L^2: 6.5e-6 -> 1.6e-5), the least iterate is not yet the
#: solution
FLOOR_JUMP = 10.0

#: the slope search shortens an update whose energy slope at the trial is
#: above this fraction of the (negative) slope at the start, reversed
SLOPE_BACK = 0.5


@dataclass
class Border:
    r"""The extra equation of pseudo-arclength continuation,
    ``<w, Dy> + wl Dlam = target``, with ``Dy``, ``Dlam`` the increments
    accumulated since the base point (``w`` already carries the metric), and
    ``p`` the prescribed motion per unit load factor (constrained dofs)."""
    w: np.ndarray
    wl: float
    target: float
    Dy: np.ndarray
    Dl: float
    p: np.ndarray

    def residual(self):
        return float(np.dot(self.w, self.Dy) + self.wl * self.Dl - self.target)

    def update(self, problem, solve, K, R, dy):
        """The bordered update: ``dy`` plus ``dl`` times ``xq = dy/dlam``
        (a second back substitution of the same factor), ``dl`` from the
        arclength equation.  Returns an :class:`Increment`, or None when the
        bordered system is singular."""
        xq = solve(problem.load_rate(R) - K @ self.p) + self.p
        den = float(np.dot(self.w, xq) + self.wl)
        if not np.isfinite(den) or den == 0.0:
            return None
        dl = -(self.residual() + np.dot(self.w, dy)) / den
        return Increment(dy + dl * xq, dl)

    def advance(self, alpha, inc):
        """Accumulate the taken step ``alpha inc``."""
        self.Dy = self.Dy + alpha * inc.dy
        self.Dl = self.Dl + alpha * inc.dl


def safeguarded_update(problem, at, inc, opts, bound, rn, slope=None):
    """The trial ``y (+) alpha dy``, ``lam + alpha dl`` from the
    :class:`~skfem_rod.problem.State` ``at`` along the
    :class:`~skfem_rod.problem.Increment` ``inc``: ``alpha`` starts where no
    spin exceeds ``max_spin_update`` (with ``line_search``) and is halved
    (at most ``max_backtracks`` times) while the trial would leave an
    element chart, carry a strand through another (``clearance_cap`` with
    contact), or give a non-finite residual or one above ``bound``.  A
    trial that raised the residual norm ``rn`` more than
    :data:`CORRECT_ABOVE` times gets its position correction first
    (``position_correction``).  With ``slope`` (option ``slope_search``:
    frictionless contact, ``G . dy < 0`` at the start) a trial whose energy
    slope ``G_t . dy`` is above :data:`SLOPE_BACK` times ``|slope|`` has
    overshot the minimum of the energy along the update and is shortened to
    the minimum of the quadratic with the two slopes (a tenth to a half).
    Every trial is evaluated from the contact search's memory at ``at``
    (:meth:`~skfem_rod.problem.Problem.search_memory`), and where none is
    taken the memory is left as it was.
    Returns ``((r, R, evaluation) or None, alpha, why)``."""
    r, R, lam = at
    dy, dl = inc
    alpha, why = 1.0, "residual grew too much"
    if opts.line_search:
        alpha = spin_cap(dy, opts.max_spin_update)
    cap = opts.clearance_cap and problem.contact is not None
    memory = problem.search_memory()        # the state's (Problem.search_memory)
    for _ in range(opts.max_backtracks + 1):
        try:
            r_t, R_t = problem.update(r, R, dy, alpha)
            if cap and not clearance_ok(problem.rod, r, r_t):
                why = "the update would carry a strand through another"
                alpha *= 0.5
                continue
            problem.restore_search(memory)
            ev_t = problem.evaluate(r_t, R_t, lam + alpha * dl)
        except ElementRotationError as err:
            why = str(err)
            alpha *= 0.5
            continue
        rn_t = problem.residual_norm(ev_t)
        if slope is not None and np.isfinite(rn_t):
            s_t = float(np.dot(ev_t.residual[problem.free], dy[problem.free]))
            if s_t > SLOPE_BACK * abs(slope):
                problem.calls["slope_cuts"] += 1
                why = "the energy rises along the update"
                # the minimum of a quadratic with these slopes
                alpha *= min(0.5, max(0.1, -slope / (s_t - slope)))
                continue
        if np.isfinite(rn_t) and opts.position_correction and rn_t > CORRECT_ABOVE * rn:
            r_t, ev_t = position_correction(problem, r_t, R_t, lam + alpha * dl, ev_t)
            rn_t = problem.residual_norm(ev_t)
        if not np.isfinite(rn_t):
            why = "non-finite residual"
        elif rn_t <= bound:
            return (r_t, R_t, ev_t), alpha, ""
        alpha *= 0.5
    problem.restore_search(memory)
    return None, alpha, why


def newton(problem, r, R, lam, opts, prescribed=None, border=None):
    """Newton iterations at load factor ``lam`` from ``(r, R)``.

    Parameters
    ----------
    problem : :class:`skfem_rod.problem.Problem`
    r, R : nodal positions and rotations to start from.
    lam : load factor (the start value with ``border``).
    opts : :class:`skfem_rod.options.SolverOptions`.
    prescribed : increment of the constrained dofs still to apply (dof
        basis), or None.
    border : :class:`Border` (continuation), or None (``lam`` fixed).

    With contact on and ``opts.contact_solve`` ``"newton"`` or
    ``"newton_normal"`` (no ``border``) the generalized Newton of
    :mod:`skfem_rod.nonsmooth` solves for the multipliers too (the normal
    and friction ones, or the normal ones only), with the viscous term of a damped step
    (``Problem.viscous``) as with any other.

    Returns
    -------
    ``(r, R, lam, report)`` with a :class:`Report`; ``report.converged``.
    """
    if problem.contact is not None and opts.contact_solve != "uzawa" and border is None:
        from .nonsmooth import contact_newton
        return contact_newton(problem, r, R, lam, opts, prescribed)
    fixed = problem.fixed
    history, last_update = [], np.inf
    remaining, ev, why = start(problem, r, R, lam, prescribed)
    if ev is None:
        return _fail(r, R, lam, history, 0, why)
    best = None             # the iterate of least residual, motions applied: Iterate
    checked = None          # the last one at_floor turned down

    def give_up(it, reason):
        # the least iterate if it is at its round-off floor, else failure
        return (best is not checked and at_floor(problem, best, history)) or \
            _fail(r, R, lam, history, it, reason, ev)
    for it in range(opts.max_iterations + 1):
        rn = problem.residual_norm(ev)
        scale = problem.force_scale(ev)
        history.append(rn)
        if not (np.isfinite(scale) and np.all(np.isfinite(ev.residual))):
            return give_up(it, "non-finite residual or forces")
        bordered_ok = border is None or \
            abs(border.residual()) <= 1e-8 * max(abs(border.target), 1e-300)
        if settled(history, last_update, opts.rtol * scale, opts.increment_tol) \
                and not np.any(remaining) and bordered_ok:
            return r, R, lam, Report(True, iterations=it, history=history, evaluation=ev)
        if not np.any(remaining) and bordered_ok:
            if best is None or rn < best.rn:
                best = Iterate(rn, r, R, lam, ev)
            elif rn > FLOOR_JUMP * best.rn and best is not checked:
                # the residual rose from its least: if that was at its
                # round-off floor, Newton's updates are round-off amplified
                done, checked = at_floor(problem, best, history), best
                if done is not None:
                    return done
        if it == opts.max_iterations:
            break
        K = ev.tangent
        try:
            solve = problem.factor(K)
            dy = solve(-ev.residual - K @ remaining)
        except RuntimeError as err:                      # singular factor
            return _fail(r, R, lam, history, it, f"singular tangent ({err})", ev)
        dy[fixed] = remaining[fixed]
        inc = Increment(dy) if border is None else border.update(problem, solve, K, R, dy)
        if inc is None:
            return _fail(r, R, lam, history, it, "singular bordered system", ev)
        if not np.all(np.isfinite(inc.dy)):
            return _fail(r, R, lam, history, it, "non-finite Newton update", ev)
        bound = np.inf if (not opts.line_search or np.any(remaining)) \
            else opts.max_growth * max(rn, scale)
        slope = None
        if opts.slope_search and problem.contact is not None and not problem.friction \
                and border is None and not np.any(remaining):
            slope = float(np.dot(ev.residual[problem.free], inc.dy[problem.free]))
            slope = slope if slope < 0 else None           # not a descent direction
        accepted, alpha, why = safeguarded_update(problem, State(r, R, lam), inc, opts,
                                                  bound, rn, slope)
        if accepted is None:
            return give_up(it + 1,
                           f"no admissible update after {opts.max_backtracks} halvings: {why}")
        r, R, ev = accepted
        lam = lam + alpha * inc.dl
        if border is not None:
            border.advance(alpha, inc)
        last_update = update_size(problem, alpha * inc.dy)
        remaining = remaining * (1.0 - alpha)
        remaining[np.abs(remaining) < 1e-300] = 0.0
    return give_up(opts.max_iterations, f"no convergence in {opts.max_iterations} "
                                        f"iterations (residual {history[-1]:.3e})")
