"""Load stepping with automatic step cutting: the loop of :meth:`Rod.solve`.

The loop, in plain sight::

    step 0: equilibrium (or check) at load factor 0, contact solved in full
    t = 0
    while t < 1:
        try the step lam(t) -> lam(t + dt):
            [secant predictor]
            augmented Lagrangian (augmented.py) around
                Newton (newton.py) from the last state, prescribed increments
                applied on the first iteration
            [snap="relax": a failed step is relaxed by the gradient flow
             (relax.py); after such a step the next ones go to the flow
             directly, Newton tried again after 1, 2, 4, 8 of them
             (NewtonBackoff); stability=True: an unstable equilibrium is
             pushed off along its unstable mode and relaxed, up to
             MAX_PUSHES times; still unstable: the step fails]
        converged: keep the step, commit it (friction slips start there),
                   let dt grow back after `need` successes in a row
                   (2; doubled, up to MAX_NEED, each time the first step
                   after a growth fails, halved each time it converges)
        failed:    halve dt; stop with the converged steps if dt < min_step

Residual, tangent and the configuration update are the
:class:`~skfem_rod.problem.Problem`'s; Newton and the Uzawa loop are shared
with continuation, stability paths and the gradient flow.
"""
import warnings

import numpy as np

from .augmented import step
from .dynamics import in_contact
from .options import Deadline, SolverOptions, make_options
from .problem import Problem, Report, clearance_ok, spin_cap
from .relax import GradientFlow
from .results import Result
from .rotations import is_rotation
from .stability import contact_stiffening, modes

__all__ = ["solve", "SolverOptions", "make_options", "ContactShortfall", "RelaxedShortfall"]

#: a cut step grows back after this many successes in a row; each time the
#: first step after a growth fails, twice as many (at most MAX_NEED), and
#: each time it converges, half as many again (at least GROW_AFTER)
GROW_AFTER = 2
MAX_NEED = 16

#: pushes off a saddle per step (snap="relax", stability=True): along the
#: unstable mode, the other way, then each twice as far.  One push was all
#: before: in the pressed figure-eight's step to load factor 0.2 the
#: relaxation off one saddle ended on another (lowest eigenvalue -7.2e-4),
#: which was recorded (benchmarks/RESULTS_figure_eight.md)
MAX_PUSHES = 4

#: a push off a saddle whose flow ends within this share of the push's
#: largest nodal move from the state pushed from came back to it.  A state
#: in contact that the flow comes back to from the last two pushes (both
#: ways along its unstable mode, at the largest push size) is kept with
#: its eigenvalue: along that mode it is a minimum of the energy the flow
#: descends, and the test's negative eigenvalue belongs to what even the
#: constrained test (stability.CONTACT_STIFFENING) reads wrongly, a gap
#: active without force, a crossing pair's frozen weight.  A true saddle's
#: flow leads away from it, farther than the push.  Measured in the
#: plectoneme at 2.375 turns (100 elements), with the penalty's tangent
#: (before the constrained test, which reads those states stable): every
#: one of the four pushes (0.5 and 1 contact radius) along modes of
#: eigenvalue -0.15 to -0.21 relaxed back to within 1.4e-4 of the state,
#: 1 % of the push, and the step was cut until the run ended there
#: (docs/stability.md; the pseudo-dynamics' rule is
#: :meth:`skfem_rod.dynamics.PseudoDynamics.came_back`)
RETURN_SHARE = 0.1


#: the most steps in a row :class:`NewtonBackoff` sends to the gradient
#: flow without trying Newton first (0: Newton is tried at every step)
MAX_SKIPS = 8


class NewtonBackoff:
    """Which steps of ``snap="relax"`` try Newton before the gradient flow.

    A step that Newton does not solve is solved again by the flow from the
    step's start, so Newton's attempt is spent.  Where Newton fails at step
    after step (a loose knot whose loops swing and slide, a plectoneme
    growing past its fold: each step a new active set), that is most of
    the time: measured in the knot's frictional cycle (``gamma_T`` = 0.2,
    benchmarks/bench_knot.py), every one of the 20 steps failed Newton
    (the generalized Newton, and with Uzawa alike), a third of the cycle's
    time, and the flows that did the steps are the same with or without
    those attempts (the same flow steps, the same forces).  So after a
    step Newton failed and the flow did, the next ``wait`` steps go to the
    flow directly, ``wait`` = 1, 2, 4, ... :data:`MAX_SKIPS` while Newton
    keeps failing when it is tried, back to 0 when it succeeds.  A step
    whose flow failed too (the step is cut) starts no wait: the shorter
    step may be Newton's.

    Scenes where Newton does its steps never meet it; a snap met once (the
    twisted rod's jump) costs at most a step or two through the flow,
    whose Levenberg-Marquardt steps end as Newton's."""

    def __init__(self):
        #: the wait after Newton's last failure, and the steps of it left
        self.wait, self.left = 0, 0

    def skip(self):
        """Whether this step goes to the flow without trying Newton."""
        if self.left:
            self.left -= 1
            return True
        return False

    def record(self, newton_failed, flow_solved):
        """After a step that tried Newton: whether Newton failed (or its
        state was rejected), and whether the flow then solved the step."""
        if not newton_failed:
            self.wait = 0
        elif flow_solved:
            self.wait = min(max(1, 2 * self.wait), MAX_SKIPS)
            self.left = self.wait


class ContactShortfall(UserWarning):
    """The augmented-Lagrangian loop stopped at ``max_uzawa`` updates short of
    its tolerances in some steps (they are kept; ``Result.log`` names them)."""


class RelaxedShortfall(UserWarning):
    """Some steps end on the gradient flow's state (``snap="relax"``):
    Newton's polish did not converge from it, so the residual there is
    above ``rtol`` of the force scale (they are kept;
    ``Step.relaxed_residual`` and ``Result.log`` give it)."""


def load_path(path):
    """Piecewise-linear load factor over pseudo-time ``t`` in [0, 1]: the
    values ``path`` are reached at equally spaced times (default 0 -> 1)."""
    try:
        p = np.asarray([0.0, 1.0] if path is None else path, dtype=float)
    except (TypeError, ValueError):
        p = np.zeros(0)
    if isinstance(path, (str, bytes)) or p.ndim != 1 or p.size < 2 \
            or not np.all(np.isfinite(p)):
        raise ValueError(f"path must be a list of >= 2 finite load factors, got {path!r}")
    if p[0] != 0.0:
        raise ValueError(f"path must start at load factor 0 (the reference), got {p[0]!r}")
    if np.any(np.diff(p) == 0):
        raise ValueError(f"consecutive path values must differ, got {p.tolist()}")
    return np.linspace(0.0, 1.0, p.size), p


def start_state(rod, start):
    """Nodal ``(r, R)`` to start from: a :class:`Result` (its last step) or
    a pair of arrays; checked."""
    if isinstance(start, Result):
        if not start.steps:
            raise ValueError("start: the Result has no converged step")
        r, R = start.steps[-1].r, start.steps[-1].R
    else:
        try:
            r, R = start
        except (TypeError, ValueError):
            raise ValueError(f"start must be a Result or a pair (r, R) of nodal positions "
                             f"and rotations, got {type(start).__name__}") from None
    r, R = np.array(r, dtype=float), np.array(R, dtype=float)
    n = rod.r0.shape[0]
    if r.shape != (n, 3) or R.shape != (n, 3, 3):
        raise ValueError(f"start: r must have shape ({n}, 3) and R ({n}, 3, 3) for this rod, "
                         f"got {r.shape} and {R.shape}")
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(R))):
        raise ValueError("start: r and R must be finite")
    if not np.all(is_rotation(R, tol=1e-8)):
        raise ValueError("start: R must hold rotation matrices (R^T R = I, det R = 1)")
    return r, R


def carry_multipliers(problem, contact):
    """The multipliers of a converged contact state, so that a solve started
    from it does not begin Uzawa again from zero: at its active slave
    points (matched by arclength) ``lambda_N = f_N``, the Uzawa update at
    that state (eq. 4.2a's); at its crossing pairs (by place,
    :func:`skfem_rod.contact.crossing.carry`) the multipliers that give the
    recorded point forces at the recorded state, ``lambda = f / w - d / mu``
    (eq. 4.2a solved for the multiplier at the nominal penalty); and, with
    friction on both sides, the friction forces (the carried multipliers of
    an accepted step, met again at zero slip; at the crossing pairs ``F =
    w F / w``).  Nothing is carried where the
    recorded slave points are not this problem's (another mesh).

    Why the two differ (measured, docs/crossing-contact.md): the crossing
    pairs' point law is stiff, and their Uzawa update ``lambda = f`` started
    the pressed figure-eight out of balance by ``d / mu``, 40 % of the
    pressing force; solved for exactly, it restarts at 1e-9 of it.  At the
    slave points the gap offsets (:func:`skfem_rod.augmented.adjust_offsets`)
    are not carried: they belong to the loop that raised them (carried, the
    tied knot of demos/knot.py failed its step 0, the loop lowering them
    and the next pass starting from a residual of 1.7), and the slave
    multipliers solved for exactly with the offsets' effect folded in took
    the knot's cycles along other paths, 1.4 and 2.3 times as long
    (benchmarks/RESULTS_knot.md)."""
    if contact is None:
        return
    m, c = problem.multipliers, problem.contact
    if contact.s.size:
        s = np.ravel(problem.slaves.s)          # flat slave index = multiplier index
        j = np.minimum(np.searchsorted(s, contact.s), s.size - 1)
        if np.abs(s[j] - contact.s).max() > 1e-12 * problem.rod.length:
            return                               # another mesh: start Uzawa from zero
        m.normal[j] = contact.force
        if contact.friction and m.tangential is not None:
            m.tangential[j] = contact.force_T
            m.rotational[j] = contact.force_R
    cr = contact.crossing
    if cr is not None and c.crossing and cr.s.size:
        d = cr.gap - cr.weight * cr.offset
        friction = cr.friction / cr.weight[:, None] if c.crossing_friction \
            else np.zeros((cr.s.size, 3))
        m.rekey_crossing(cr.key.copy(), cr.force / cr.weight - d / problem.crossing_compliance(),
                         np.zeros(cr.s.size), friction)


class LoadStepper:
    """The state of one :func:`solve`: the problem, the options, the result
    being built and the gradient flow (snap="relax")."""

    def __init__(self, rod, opts):
        self.rod, self.opts = rod, opts
        self.problem = Problem(rod)
        self.result = Result(rod)
        self.deadline = Deadline(opts.time_limit)
        self.flow = GradientFlow(self.problem, self.deadline)
        self.backoff = NewtonBackoff()

    def initial(self, r0, R0, stressed):
        """Step 0 at load factor 0: an equilibrium solve from a stressed start
        (naturally straight rod, a given start state), a check of the
        stress-free reference otherwise -- with contact solved in full either
        way (preloads may press strands together)."""
        p, opts = self.problem, self.opts
        zero = np.zeros(p.mesh.n_dofs)
        r, R, rep = step(p, r0.copy(), R0.copy(), 0.0, zero, opts)
        if not rep.converged and stressed and opts.snap == "relax":
            r, R, rep = step(p, r0.copy(), R0.copy(), 0.0, zero, opts, inner=self.flow)
        if rep.converged and opts.stability:
            rep.lowest_eigenvalue = self.lowest_mode(r, R, 0.0)[0]
        return r, R, rep

    def lowest_mode(self, r, R, lam):
        """Lowest eigenvalue and mode of the symmetrized tangent on the free
        dofs (at the problem's multipliers) and the Morse index; with
        contact, the active gaps stiffened (the constrained test,
        :data:`skfem_rod.stability.CONTACT_STIFFENING`)."""
        m = modes(self.problem, r, R, lam, 1, stiffen=contact_stiffening(self.problem))
        mode = np.concatenate([m.positions[0], m.spins[0]], axis=1).ravel()
        return float(m.values[0]), self.problem.to_basis(mode), m.negative

    def secant(self, r, R, prev, ratio):
        """Secant predictor: ``(r, R)`` moved by ``ratio`` times the increment
        from ``prev = (lam, r, R)`` to it, with supported dofs left alone (the
        prescribed increment moves them), spins capped at ``max_spin_update``
        and, with ``clearance_cap``, halved until no strand can pass through
        another (up to ``max_backtracks`` halvings, else no prediction)."""
        p, opts = self.problem, self.opts
        dy = ratio * p.increment(r, R, prev[1], prev[2])
        dy[p.fixed] = 0.0
        alpha = spin_cap(dy, opts.max_spin_update)
        for _ in range(opts.max_backtracks + 1):
            try:
                r_p, R_p = p.update(r, R, dy, alpha)
            except ValueError:                     # would leave an element chart
                alpha *= 0.5
                continue
            if not (opts.clearance_cap and p.contact is not None) \
                    or clearance_ok(self.rod, r, r_p):
                return r_p, R_p
            alpha *= 0.5
        return r, R

    def advance(self, r, R, lam, lam_new, prev):
        """The step ``lam -> lam_new`` from ``(r, R)``, with the snap and
        stability options; with ``snap="relax"`` Newton is tried first
        unless :class:`NewtonBackoff` sends the step to the flow directly.
        Returns ``(r, R, report)``."""
        p, opts = self.problem, self.opts
        flows = p.calls["flow_steps"]
        saved = p.multipliers.copy() if p.multipliers is not None else None
        presc = p.prescribed(lam_new - lam)
        relax = opts.snap == "relax"
        tried = not (relax and self.backoff.skip())
        if not tried:
            trial = (r, R, Report(False, reason=f"Newton not tried: it failed at the last step "
                                                f"it was tried (then tried at one step in "
                                                f"{self.backoff.wait + 1})"))
        else:
            r_p, R_p = r, R
            if opts.predictor == "secant" and prev is not None and lam != prev[0]:
                r_p, R_p = self.secant(r, R, prev, (lam_new - lam) / (lam - prev[0]))
            trial = step(p, r_p, R_p, lam_new, presc, opts)
        if not (relax or opts.stability):
            return trial
        r1, R1, rep = self.snap(r, R, lam_new, presc, trial, saved)
        rep.flow_steps = p.calls["flow_steps"] - flows
        if relax and tried:
            # snap marks Newton's report not converged where it rejects its state
            self.backoff.record(not trial[2].converged, rep.converged)
        return r1, R1, rep

    def snap(self, r, R, lam_new, presc, trial, saved):
        """Options ``snap="relax"`` and ``stability`` on the ``trial =
        (r1, R1, report)`` of the step from ``(r, R)`` to ``lam_new``: relax
        (gradient flow) when the Newton step failed or moved strands by more
        than half their clearance (a possible passage of one strand through
        another) or, with the stability check, when it converged to an
        unstable equilibrium (pushed off along the unstable mode first).
        ``saved``: the multipliers before the step."""
        p, opts, log = self.problem, self.opts, self.result.log
        r1, R1, rep = trial
        relax = opts.snap == "relax"
        if rep.converged and relax and not clearance_ok(self.rod, r, r1):
            rep.converged = False
            rep.reason = "strands moved by more than half their clearance (possible passage)"
            p.multipliers = saved                  # those of the rejected step are void
        if not rep.converged and relax:
            log.append(f"step to lam={lam_new:.6g} failed ({rep.reason}): relaxing "
                       "(gradient flow)")
            r1, R1, rep = step(p, r, R, lam_new, presc, opts, inner=self.flow)
            rep.relaxed = rep.converged
        if not (rep.converged and opts.stability):
            return r1, R1, rep
        low, mode, negative = self.lowest_mode(r1, R1, lam_new)
        # off a saddle (snap="relax"): pushed along its unstable mode and
        # relaxed, again (the other way, then twice as far) while the flow
        # ends on a saddle; after MAX_PUSHES the step fails rather than
        # record one, unless the state is in contact and the flow came back
        # to it from the last two (RETURN_SHARE).  With friction the test
        # (Problem.free_tangent) is only sufficient: one push, then the
        # state is kept with its eigenvalue
        # (docs/stability.md).  snap="cut" records saddles with their
        # eigenvalue: stability=True is then a diagnostic.
        pushes, limit, back = 0, (1 if p.friction else MAX_PUSHES), []
        while negative and relax and pushes < limit:
            log.append(f"step to lam={lam_new:.6g}: unstable equilibrium (lowest eigenvalue "
                       f"{low:.3e}); relaxing along the unstable mode")
            sign, size = (-1.0) ** pushes, p.push_size * 2.0 ** (pushes // 2)
            pushes += 1
            r_p, R_p = p.push(r1, R1, sign * mode, size)
            pushed, r_s = float(np.abs(r_p - r1).max()), r1
            r1, R1, rep = step(p, r_p, R_p, lam_new, None, opts,
                               inner=lambda *a, **k: self.flow(*a, descent=True, **k))
            if not rep.converged:
                break
            rep.relaxed = True
            back.append(float(np.abs(r1 - r_s).max()) / max(pushed, 1e-300))
            low, mode, negative = self.lowest_mode(r1, R1, lam_new)
        returned = (rep.converged and negative and pushes == MAX_PUSHES
                    and max(back[-2:]) <= RETURN_SHARE and in_contact(p, r1, R1, lam_new))
        if returned:
            log.append(f"step to lam={lam_new:.6g}: the flow came back from the last pushes "
                       f"both ways along the unstable mode (to {max(back[-2:]):.2g} of the "
                       f"push): kept as held by contact, the tangent's lowest eigenvalue "
                       f"{low:.3e}")
        if rep.converged and negative and pushes and not p.friction and not returned:
            rep.converged = False
            rep.reason = (f"an unstable equilibrium (lowest eigenvalue {low:.3e}) after "
                          f"{pushes} pushes off saddles along their unstable modes")
            p.multipliers = saved                  # those of the rejected step are void
        if rep.converged:
            rep.lowest_eigenvalue = low
        return r1, R1, rep

    def keep(self, lam, r, R, rep, t, callback):
        """Record a converged step and commit it."""
        self.problem.commit(r, R, rep.evaluation)
        self.result.append(lam, r, R, rep, time=t)
        if rep.uzawa_note:
            self.result.log.append(f"step to lam={lam:.6g}: {rep.uzawa_note}")
        if rep.rescued:
            self.result.log.append(f"step to lam={lam:.6g}: a Uzawa pass failed ({rep.rescued}); "
                                   "the generalized Newton solved it from the last converged pass")
        if rep.relaxed_residual is not None:
            self.result.log.append(
                f"step to lam={lam:.6g}: the gradient flow's state, Newton's polish did not "
                f"converge from it: residual {rep.relaxed_residual:.2e} of the force scale "
                f"(relax_tol={self.opts.relax_tol:g}, rtol={self.opts.rtol:g})")
        if callback is not None:
            callback(self.result, len(self.result.steps) - 1)


def first_step(rod, n_steps, times, values, opts):
    """Nominal pseudo-time step: ``1 / n_steps``, smaller where the largest
    prescribed rotation per step would exceed ``max_rotation_step``."""
    rot = max([np.linalg.norm(s.rotation_vector) for s in rod.supports.values()] + [0.0])
    slope = np.abs(np.diff(values) / np.diff(times)).max()
    nominal = 1.0 / n_steps
    if rot > 0:
        nominal = min(nominal, opts.max_rotation_step / (rot * slope))
    return nominal


def solve(rod, n_steps=1, path=None, callback=None, start=None, **kwargs):
    """Step the rod along the load path; see :meth:`Rod.solve`.
    ``callback(result, k)`` is called after each converged step ``k``;
    ``start`` (a Result or ``(r, R)``) replaces the reference as the state
    step 0 starts from (step 0 is then an equilibrium solve)."""
    rod.check_steps(n_steps)
    times, values = load_path(path)
    opts = make_options(kwargs)
    rod.check_constraints()
    S = LoadStepper(rod, opts)
    p, result = S.problem, S.result
    r0, R0 = (rod.r0, rod.R0) if start is None else start_state(rod, start)
    p.commit(r0, R0)                     # slips of step 0 are measured from the start
    if isinstance(start, Result) and p.contact is not None:
        carry_multipliers(p, start.steps[-1].contact)
    stressed = rod.natural == "straight" or start is not None
    r, R, rep = S.initial(r0, R0, stressed)
    if not rep.converged:
        where = ("reference" if not stressed else
                 "initial shape" if start is None else "given start state")
        result.finish(False, f"no equilibrium at load factor 0 from the {where}: {rep.reason}")
        return result
    S.keep(0.0, r, R, rep, 0.0, callback)
    if opts.dynamics:
        from .dynamics import follow
        result = follow(S, r, R, first_step(rod, n_steps, times, values, opts), times, values,
                        callback)
        if result.converged:
            warn_shortfall(result)
        return result
    return follow_path(S, r, R, n_steps, times, values, callback)


def follow_path(S, r, R, n_steps, times, values, callback):
    """The load steps of :func:`solve` after step 0 (the loop of the module
    doc); returns the finished result."""
    rod, opts, result = S.rod, S.opts, S.result
    lam_of = lambda t: float(np.interp(t, times, values))         # noqa: E731
    nominal = first_step(rod, n_steps, times, values, opts)
    t, dt, streak, prev = 0.0, nominal, 0, None
    # successes in a row before a cut step grows back; where the grown step
    # fails again at once (a stretch of the path that takes only shorter
    # steps: a frictional plectoneme's plies slipping), twice as many
    need, grown = GROW_AFTER, False
    while t < 1.0 - 1e-14:
        if S.deadline.passed():
            result.finish(False, f"stopped at load factor {lam_of(t):.6g} (pseudo-time "
                                 f"{t:.6g}): {S.deadline.reason()}")
            return result
        nxt = times[times > t + 1e-14][0]            # do not step over a turning point
        h = min(dt, nxt - t)
        t_new = nxt if h == nxt - t else t + h
        lam, lam_new = lam_of(t), lam_of(t_new)
        r1, R1, rep = S.advance(r, R, lam, lam_new, prev)
        if rep.converged:
            t, prev, r, R = t_new, (lam, r, R), r1, R1
            S.keep(lam_new, r, R, rep, t, callback)
            streak += 1
            if grown:                # the grown step went through
                need, grown = max(GROW_AFTER, need // 2), False
            if streak >= need and dt < nominal:
                dt, grown = min(dt * opts.grow, nominal), True
            continue
        if grown:                    # the grown step failed at once
            need = min(2 * need, MAX_NEED)
        streak, grown = 0, False
        result.log.append(f"step to lam={lam_new:.6g} (t={t_new:.6g}) failed: "
                          f"{rep.reason}; cutting the step")
        dt = 0.5 * h
        if dt < opts.min_step:
            result.finish(False, f"stopped at load factor {lam:.6g} (pseudo-time {t:.6g}): "
                                 f"the step to {lam_new:.6g} failed ({rep.reason}) and the "
                                 f"step size fell below min_step={opts.min_step:g}")
            return result
    result.finish(True, f"converged: {len(result.steps) - 1} steps to the end of the "
                        f"load path (load factor {lam_of(1.0):g})")
    warn_shortfall(result)
    return result


def warn_shortfall(result):
    """A :class:`ContactShortfall` warning naming the steps whose Uzawa loop
    stopped short of its tolerances, a :class:`RelaxedShortfall` one naming
    the steps that end on the gradient flow's state (Newton's polish did not
    converge there)."""
    relaxed = [k for k, st in enumerate(result.steps) if st.relaxed_residual is not None]
    if relaxed:
        worst = max(result.steps[k].relaxed_residual for k in relaxed)
        warnings.warn(f"{len(relaxed)} step(s) end on the gradient flow's state without a "
                      f"converged Newton polish (first: step {relaxed[0]}; residual up to "
                      f"{worst:.2e} of the force scale, above rtol; see Result.log)",
                      RelaxedShortfall, stacklevel=3)
    short = [k for k, st in enumerate(result.steps)
             if st.contact is not None and not st.contact.uzawa_converged]
    if short:
        warnings.warn(f"Uzawa did not reach its tolerance in {len(short)} step(s) (first: "
                      f"step {short[0]}, penetration "
                      f"{result.steps[short[0]].contact.penetration:.3e}; see Result.log)",
                      ContactShortfall, stacklevel=3)
