r"""Implicit pseudo-dynamics path following through snaps (solve option
``dynamics=True``).

Load stepping (:mod:`skfem_rod.solver`) follows a branch of equilibria as
long as Newton finds one near the last converged state.  Past a fold or a
subcritical bifurcation (a twisted rod under tension snapping into a loop,
the loop winding into a plectoneme) there is none nearby.  Implicit rod
codes (DisMech, ElasticKnots) cross these snaps by integrating damped
dynamics with backward Euler and an adaptive time step; the static solution
is the rest state.  Here the damped step is the proximal step of
:mod:`skfem_rod.relax`: with the lumped metric ``W``
(:func:`skfem_rod.relax.metric`) and a pseudo-time step ``dt``, backward
Euler on ``W dy/dtau = -G(y, lam(tau))`` gives, per step,

    G(y_{n+1}, lam_{n+1}) + (1/dt) W (y_{n+1} (-) y_n) = 0,

solved by the one Newton (:func:`skfem_rod.newton.newton`, the viscous term
through ``Problem.viscous``) inside the one augmented-Lagrangian loop
(:func:`skfem_rod.augmented.augmented_lagrangian`): contact and friction are
enforced, and the true strand distance checked, at every pseudo-time step,
not only at the end of a relaxation.  Friction slips are those of the step
(each accepted step is committed), as backward Euler on the paper's eq. 1.1
requires.

The loop, in plain sight::

    static step lam -> lam_new (dt = infinity: plain load step, Newton + AL)
    converged, stable (Morse index 0) and no strand passage: record it
    converged to an unstable equilibrium: push it off along its unstable
        mode and start the damped phase there, at lam_new
    failed: damped phase from the last equilibrium, load ramped to lam_new:
        repeat:
            h = nominal step * min(1, max(dt / (LOAD_RAMP dt_0), q)), held at
                lam_new; q doubles after each step at rest (its viscous
                force at most QUASI of its out-of-balance) while the load
                still ramps, else 0
            implicit Euler step with viscosity 1/dt (Newton + AL: contact
                enforced and true distance checked at every step)
            failed or strand passage: dt /= 2 (stop below DT_FLOOR dt_0)
            accepted: commit (friction slips start there); dt *= 2 after two
                steps in a row with <= EASY Newton iterations per AL pass, or
                after STALL accepted steps in a row at one dt
            at lam_new, viscous force |W dy| / dt <= dynamics_tol * force
                scale, and away from the last saddle:
                polish: Newton + AL with the viscous term off; converged,
                near (POLISH_REACH) and stable: record it, back to static
                steps; unstable: push off along the mode, go on

Every recorded state is therefore a static equilibrium to the solver's
``rtol`` (the viscous force is zero there, not small); the damped states in
between are not recorded (their figures are in :class:`DynamicsLog`).
The static step is the ``dt = infinity`` member of the family: on a stable
stretch of the path the solve is load stepping, and the work of the
dynamics is spent only where there is no nearby equilibrium.
"""
from dataclasses import dataclass, field, replace

import numpy as np

from .augmented import step as al_step
from .newton import newton
from .problem import clearance_ok
from .relax import climbs, metric, polish, static_residual

__all__ = ["DynamicsLog", "PseudoDynamics", "follow"]

#: the load moves by the nominal step per damped step once ``dt`` reaches
#: ``LOAD_RAMP`` times the first damped step; below, in proportion to dt
LOAD_RAMP = 64.0
#: grow dt after an implicit step that took at most this many Newton iterations
EASY = 4
#: grow dt also after this many accepted steps in a row at one dt: steps that
#: converge every time but never within EASY iterations (each starting from a
#: large static out-of-balance, 17.7 -> 13.2 -> 2.5 -> 1.8e-2 -> 2e-6 -> 0)
#: held the plectoneme's dt at 7.6e-6 for 300 steps, the load frozen
STALL = 8
#: after a failure at a freshly doubled dt, the easy steps dt waits for
#: before it doubles again double, up to this many (STALL's count: a dt
#: doubles after that many accepted steps anyway); a success at a doubled
#: dt sets them back to two.  In the frictional plectoneme at rest at 1.97
#: turns Newton failed at twice the dt it had just managed, about one try
#: in three, for 200 steps
EASY_WAIT_MAX = 8
#: the damped phase gives up when dt falls below this fraction of its first value
DT_FLOOR = 1e-8
#: after a push off a saddle, no polish until the flow is this many push
#: sizes away from it
SADDLE_DISTANCE = 4.0
#: a push whose largest nodal move is below this fraction of the size asked
#: for was held short (rotation limit, contact): :meth:`PseudoDynamics.came_back`
CAPPED = 0.99
#: dt grows to at most this multiple of its first value
DT_CEIL = 1e8
#: a damped step is at rest (a load step) when the viscous force it ends
#: with is at most this fraction of the largest out-of-balance of its Newton
#: iterations (over all its Uzawa passes): backward Euler leaves
#: ``(W / dt) / (K + W / dt)`` of it, so dt is ten times the relaxation time
#: ``W / K`` or more
QUASI = 0.1
#: Newton iterations of one damped step (it is cheaper to halve dt than to iterate)
DAMPED_ITERATIONS = 10
#: Newton iterations of a polish
POLISH_ITERATIONS = 12
#: a polish that moves a node farther than this fraction of the rod length
#: is a jump, not a polish: rejected
POLISH_REACH = 0.1


@dataclass
class DynamicsLog:
    """What the pseudo-dynamics did, for benchmarks and tests
    (``Result.dynamics``): one entry per implicit solve (static steps, damped
    steps and polishes), and per recorded equilibrium the damped steps that
    led to it."""
    #: kind of each solve: "static", "damped" or "polish"
    kind: list = field(default_factory=list)
    #: Newton iterations of each solve (all Uzawa passes)
    newton: list = field(default_factory=list)
    #: converged (accepted) or not
    accepted: list = field(default_factory=list)
    #: true penetration (2 eps - true distance, <= 0: clear) of each accepted
    #: solve with contact, relative to the contact radius
    penetration: list = field(default_factory=list)
    #: pseudo-time t of the load path at each accepted solve
    time: list = field(default_factory=list)
    #: viscous force of each accepted damped step relative to the force scale
    viscous: list = field(default_factory=list)
    #: pseudo-time step of each accepted damped step
    dt: list = field(default_factory=list)
    #: damped steps before each recorded equilibrium (0: a static step)
    damped_per_record: list = field(default_factory=list)

    def add(self, kind, rep, accepted, t=None, problem=None):
        self.kind.append(kind)
        self.newton.append(int(rep.newton_total or rep.iterations))
        self.accepted.append(bool(accepted))
        if accepted:
            self.time.append(t)
            if problem is not None and problem.contact is not None \
                    and rep.min_distance is not None:
                eps = problem.contact.radius
                self.penetration.append((2 * eps - rep.min_distance) / eps)

    @property
    def damped_steps(self):
        """Accepted damped (implicit Euler) steps."""
        return int(sum(a for k, a in zip(self.kind, self.accepted) if k == "damped"))

    @property
    def max_penetration(self):
        """Largest true penetration over every accepted solve, relative to the
        contact radius (``-inf`` without contact)."""
        return float(max(self.penetration, default=-np.inf))


#: a symmetrized tangent with an eigenvalue below -STABLE_FLOOR times its
#: largest diagonal entry is unstable (round-off and the bifurcation point
#: itself are not)
STABLE_FLOOR = 1e-10


def morse_index(problem, r, R, lam):
    """Number of negative eigenvalues of the symmetrized tangent on the free
    dofs at ``(r, R, lam)`` (Sylvester's inertia of one symmetric LU,
    :func:`skfem_rod.stability.inertia`): 0 at a stable equilibrium.  A
    static Newton step can converge to an unstable equilibrium (the twisted
    rod past its fold goes back to the straight branch); the damped steps
    cannot rest there.  With contact, the constrained test
    (:data:`skfem_rod.stability.CONTACT_STIFFENING`), as the load
    stepping's."""
    from .stability import contact_stiffening, inertia
    Kf = problem.free_tangent(r, R, lam, contact_stiffening(problem))[0]
    Ks = (0.5 * (Kf + Kf.T)).tocsc()
    floor = STABLE_FLOOR * max(float(np.abs(Ks.diagonal()).max(initial=0.0)), 1e-300)
    return inertia(Ks, -floor)


def in_contact(problem, r, R, lam):
    """Whether any contact pair (Gauss or crossing) carries a force at
    ``(r, R, lam)``."""
    if problem.contact is None:
        return False
    c = problem.evaluate(r, R, lam, tangent=False).contact
    return bool(np.any(c.fN > 0) or (c.crossing_fN is not None and np.any(c.crossing_fN > 0)))


def viscous_inner(problem, W, c, r_ref, R_ref):
    """The inner solve of one implicit Euler step: :func:`~skfem_rod.newton.newton`
    with the viscous term ``c W (y (-) y_ref)`` switched on (same signature)."""

    def inner(r, R, lam, opts, prescribed=None):
        with problem.damped(c, W, r_ref, R_ref):
            return newton(problem, r, R, lam, opts, prescribed=prescribed)
    return inner


class PseudoDynamics:
    """The damped phases of one solve (module doc): the metric, the step
    size that worked last, the log.  ``stepper`` is the
    :class:`~skfem_rod.solver.LoadStepper` of the solve."""

    def __init__(self, stepper, lam_of, times):
        self.S = stepper
        self.problem = stepper.problem
        self.opts = stepper.opts
        self.lam_of, self.times = lam_of, times
        self.W = metric(stepper.rod, self.problem.fixed)
        self.dt0 = self.opts.dynamics_dt
        self.dt = None
        self.unstable = False
        self.saddle = None
        self.away_from = None
        self.dt_saddle = np.inf
        self.pushes = 0
        #: static residual at the end of the last accepted damped step that
        #: was checked for descent (:meth:`damped`), else None
        self.gradient = None
        #: a push off a saddle with friction on in this load step (the
        #: frictionless test is then only sufficient: :meth:`unstable_at`)
        self.pushed_with_friction = False
        #: the largest nodal move of the last push (from ``away_from[0]``),
        #: and whether the rotation limit or the contact halvings held it
        #: short of the size asked for (a larger push would move no farther)
        self.pushed_by, self.push_capped = 0.0, False
        #: the flow came back, at rest, toward a saddle it was pushed off in
        #: this load step: the saddle is held (by contact), not left
        #: (:meth:`came_back`)
        self.held = False
        self.log = DynamicsLog()
        self.inner_opts = replace(self.opts,
                                  max_iterations=min(self.opts.max_iterations, DAMPED_ITERATIONS),
                                  rtol=max(self.opts.rtol, 1e-8),
                                  increment_tol=max(self.opts.increment_tol, 1e-9))
        # a polish starts next to its equilibrium: it converges fast or not at all
        self.polish_opts = replace(self.opts, max_iterations=min(self.opts.max_iterations,
                                                                 POLISH_ITERATIONS))

    def save(self):
        m = self.problem.multipliers
        return None if m is None else m.copy()

    def restore(self, saved):
        if saved is not None:
            self.problem.multipliers = saved

    def damped(self, r, R, t, t_new, dt, descent=None):
        """One implicit Euler step ``t -> t_new`` with viscosity ``1 / dt``
        from ``(r, R)``.  Returns ``(r, R, report, ok, peak)``, ``peak`` the
        largest residual norm of the Newton iterations of all its Uzawa
        passes (the out-of-balance the step met: the report holds the last
        pass's only); a rejected step leaves the multipliers as they were.
        ``descent``: the static residual at ``(r, R)`` (the energy's
        gradient, load held): the step is also rejected where it climbs
        (:func:`~skfem_rod.relax.climbs`); the accepted step's static residual is then
        :attr:`gradient`."""
        p = self.problem
        lam, lam_new = self.lam_of(t), self.lam_of(t_new)
        saved = self.save()
        viscous = viscous_inner(p, self.W, 1.0 / dt, r, R)
        peaks = []

        def inner(r0, R0, lam0, opts, prescribed=None):
            out = viscous(r0, R0, lam0, opts, prescribed=prescribed)
            peaks.append(max(out[3].history, default=0.0))
            return out
        presc = p.prescribed(lam_new - lam)
        if self.opts.dynamics_uzawa:
            r1, R1, rep = al_step(p, r, R, lam_new, presc, self.inner_opts, inner=inner,
                                  strict=False)
        else:
            # the multipliers of the last converged AL solve are held, the
            # penalty takes up new contact; the true distance is recorded
            r1, R1, _, rep = inner(r, R, lam_new, self.inner_opts, prescribed=presc)
            if rep.converged and p.contact is not None:
                from .augmented import true_distance
                rep.penetration = true_distance(p, r1, rep)
        ok = rep.converged and clearance_ok(p.rod, r, r1)
        if rep.converged and not ok:
            rep.reason = "strands moved by more than half their clearance (possible passage)"
        self.gradient = None
        if ok and descent is not None:
            dy = p.increment(r1, R1, r, R)
            g1 = static_residual(p, self.W, rep.evaluation, dy, dt)
            if climbs(descent, g1, dy, p.free):
                ok, rep.reason = False, "the damped step climbs (the energy would rise)"
            else:
                self.gradient = g1
        if not ok:
            self.restore(saved)
        self.log.add("damped", rep, ok, t_new, p)
        return r1, R1, rep, ok, max(peaks, default=0.0)

    def polish(self, r, R, t, dt):
        """Newton + AL with the viscous term off at ``lam(t)`` from a damped
        state (the last damped step's ``dt``): the equilibrium that is
        recorded.  Each AL pass is :func:`skfem_rod.relax.polish`: Newton,
        and where it does not converge without contact (a very soft mode),
        proximal steps from viscosity ``1 / dt`` down.  Returns ``(r, R, report)`` or None."""
        p, rod = self.problem, self.problem.rod
        saved = self.save()

        def inner(r0, R0, lam0, opts, prescribed=None):
            return polish(p, self.W, 1.0 / dt, r0, R0, lam0, opts, prescribed,
                          clearance=False)
        r1, R1, rep = al_step(p, r, R, self.lam_of(t), None, self.polish_opts, inner=inner)
        # no clearance cap here: plies in contact slide along each other in
        # a polish; a passage is caught by the AL loop's true-distance check
        ok = rep.converged and np.abs(r1 - r).max() <= POLISH_REACH * rod.length
        self.unstable = ok and self.unstable_at(r1, R1, t)
        ok = ok and not self.unstable
        self.log.add("polish", rep, ok, t, p)
        self.saddle = (r1, R1) if self.unstable else None
        if not ok:
            self.restore(saved)
            return None
        return r1, R1, rep

    def viscous_force(self, r1, R1, r, R, dt, ev):
        """``|W (y1 (-) y) / dt|`` on the free dofs relative to the force scale
        of the evaluation ``ev`` (the norms of Newton's convergence test)."""
        p = self.problem
        dy = p.to_spatial(p.increment(r1, R1, r, R))
        f = p.to_basis(self.W * dy / dt)[p.free]
        return float(np.linalg.norm(f)) / p.force_scale(ev)

    def push(self, r, R, lam):
        """The unstable equilibrium ``(r, R)`` moved along its unstable mode
        (largest nodal move half the contact radius, or 1e-3 L without
        contact; largest nodal rotation 0.1 rad): where the damped steps
        start when a step or a polish found a saddle (a damped flow started
        on it would stay there)."""
        p = self.problem
        low, mode_b, _ = self.S.lowest_mode(r, R, lam)
        mode = p.to_spatial(mode_b).reshape(-1, 6)
        # the proximal problem is convex along the mode while 1/dt exceeds
        # |low| / (v.W v): longer implicit steps could converge back onto the
        # saddle (Newton finds any stationary point), so dt stays below half
        # that bound until the flow is away from it
        v = mode.ravel() / max(np.linalg.norm(mode), 1e-300)
        q = float(np.dot(self.W * v, v))
        self.dt_saddle = 0.5 * q / abs(low) if low < 0 else np.inf
        size = p.push_size * 2.0 ** min(self.pushes, 10)   # a push that did not get away
        self.pushes += 1
        self.pushed_with_friction = self.pushed_with_friction or bool(p.friction)
        # no polish until the flow is well away from the saddle (Newton would
        # converge back onto it)
        self.away_from = (r, SADDLE_DISTANCE * size)
        r1, R1 = p.push(r, R, mode_b, size)
        self.pushed_by = float(np.abs(r1 - r).max())
        self.push_capped = self.pushed_by < CAPPED * size
        return r1, R1

    def came_back(self, r):
        """Whether the flow, at rest at ``r`` next to the saddle it was
        pushed off, is closer to it than the push put it although the push
        was as large as a push can be (:attr:`push_capped`).  A push that
        comes back is doubled (a push too small, or in a direction a larger
        one gets past); once the rotation limit or the contact holds the
        push, doubling moves no farther, and a state the flow comes back to
        from there is held in the direction the linearized test calls
        unstable (that test reads the tangent with the inactive gaps left
        out and the crossing weights frozen: a mode that closes a gap looks
        unstable although contact stops it).  Such a saddle is kept, as
        friction's (:meth:`unstable_at`).  Pushed again instead, the
        frictionless plectoneme past 2.19 turns came back 14 times, sizes
        doubling to 2^10 half radii, and made no progress
        (docs/pseudo-dynamics.md)."""
        if self.away_from is None or not self.push_capped:
            return False
        return float(np.abs(r - self.away_from[0]).max()) < self.pushed_by

    def unstable_at(self, r, R, t):
        """Whether the equilibrium ``(r, R)`` at ``lam(t)`` is a saddle to
        push off (Morse index of the frictionless tangent above 0).  With
        friction that test is sufficient, not necessary: friction may hold
        a state the frictionless rod would leave (docs/stability.md).  As in
        the load stepping's relaxation (:mod:`skfem_rod.solver`), such a
        state is pushed off once per load step; found again after that
        push, it is kept.  Pushed again and again with sizes doubling (up to
        2^10 half radii), the frictional plectoneme's damped steps were
        started from strands pushed into each other by 0.58 eps, and no
        step size brought Newton to converge from there (the stop at 1.94
        turns, docs/pseudo-dynamics.md).  This rule and the held saddle's
        (:meth:`came_back`) need contact at the state: without it the
        frictionless test is exact (friction acts through the contact
        forces), and at the twisted rod's Greenhill saddle, before any
        contact, the frictional rule recorded the pushed saddle as an
        equilibrium."""
        p, lam = self.problem, self.lam_of(t)
        if (self.held or (p.friction and self.pushed_with_friction)) and in_contact(p, r, R, lam):
            return False
        return morse_index(p, r, R, lam) > 0

    def recorded(self, steps):
        """An equilibrium is recorded after ``steps`` damped steps: the
        rules of one load step start afresh (friction's one push, a held
        saddle and its ``dt`` bound)."""
        self.pushed_with_friction = self.held = False
        self.dt_saddle = np.inf
        self.log.damped_per_record.append(steps)

    def capped(self, dt):
        """``dt`` within the bound that keeps a damped step next to the last
        saddle convex along its unstable mode (:meth:`push`).  Without
        contact the bound is not applied: there the damped steps next to a
        saddle are checked for descent instead (:func:`~skfem_rod.relax.climbs`, as the
        gradient flow's), which bounds ``dt`` by the curvature along the
        way rather than by the saddle's.  Held at the saddle's bound, the
        localized writhing case's first damped phase (the compressed
        straight rod, 21 unstable modes, coarsening into one loop) took
        836 damped steps; with contact the check is poor where the active
        set changes (:mod:`skfem_rod.relax`), and the bound stays."""
        return dt if self.problem.contact is None else min(dt, self.dt_saddle)

    def near_saddle(self, r):
        """True while ``r`` is within the distance of the last saddle that
        the flow must leave before a polish."""
        if self.away_from is None:
            return False
        if np.abs(r - self.away_from[0]).max() > self.away_from[1]:
            self.away_from, self.dt_saddle, self.pushes = None, np.inf, 0
            return False
        return True

    def run(self, r, R, t, t_target, h_nominal):
        """A damped phase from ``(r, R)`` at ``t`` (the equilibrium where the
        static step to ``t_target`` failed, or a pushed saddle at
        ``t = t_target``) to the first stable equilibrium at ``t_target``.
        The load follows the pseudo-time up to ``t_target`` and is held
        there.  Returns ``(r, R, t, report, damped_steps)``, or ``(None,
        why)`` when it gives up."""
        opts, p = self.opts, self.problem
        dt = self.dt0 if self.dt is None else self.dt
        steps = tries = easy = at_dt = 0
        wait, grew = 2, False                # easy steps before dt doubles; dt just doubled
        quasi = 0.0                          # load fraction of the quasi-static ramp
        first = True
        why = "no damped step"
        next_polish = np.inf                 # viscous force that allows a polish
        g = None                             # static residual at (r, R), when known
        while steps < opts.max_damped_steps:
            if self.S.deadline.passed():
                return None, (f"at pseudo-time {t:.6g} after {steps} damped steps: "
                              f"{self.S.deadline.reason()}")
            tries += 1
            h = h_nominal * min(1.0, max(dt / (LOAD_RAMP * self.dt0), quasi))
            t_new = t_target if t + h >= t_target - 1e-14 else t + h
            descent = None
            if self.away_from is not None and p.contact is None and t >= t_target - 1e-14:
                # next to a saddle without contact: the descent check
                # stands in for the saddle's dt bound (:meth:`capped`)
                if g is None:
                    g = p.evaluate(r, R, self.lam_of(t), tangent=False).residual
                descent = g
            r1, R1, rep, ok, peak = self.damped(r, R, t, t_new, dt, descent=descent)
            if not ok:
                why = rep.reason
                easy = at_dt = 0
                if grew:                         # the doubled dt failed: wait longer
                    wait = min(2 * wait, EASY_WAIT_MAX)
                grew = False
                dt *= 0.5
                quasi *= 0.5
                if dt < DT_FLOOR * self.dt0:
                    return None, (f"the damped steps stopped at pseudo-time {t:.6g} "
                                  f"(dt = {dt:.3g} after {steps} steps, {tries} tries): {why}")
                continue
            ev = rep.evaluation
            vis = self.viscous_force(r1, R1, r, R, dt, ev)
            self.log.viscous.append(vis)
            self.log.dt.append(dt)
            steps += 1
            p.calls["damped_steps"] += 1
            if first:
                self.dt = 2.0 * dt               # the next phase starts there
            first = False
            p.commit(r1, R1, ev)                 # friction slips of the next step start here
            r, R, t, g = r1, R1, t_new, self.gradient
            # Newton iterations per pass of the AL loop: Uzawa passes are the
            # contact's work, not a sign that the step is too long
            its = (rep.newton_total or rep.iterations) / (rep.uzawa + 1)
            easy = easy + 1 if its <= EASY else 0
            at_dt += 1
            if grew:                             # the doubled dt worked
                wait, grew = 2, False
            if easy >= wait or at_dt >= STALL:   # enough easy steps, or a stalled dt
                dt = min(2.0 * dt, DT_CEIL * self.dt0)
                at_dt, grew = 0, True
            # at rest while the load still ramps: the steps are load steps
            # (the viscous force a small part of the out-of-balance that
            # Newton met: QUASI), and the load moves by a
            # share of the nominal step that doubles with each such step
            # instead of one tied to dt.  Tied to dt, a ramp whose dt Newton
            # held at 0.03-0.06 of the first moved the load by 5e-6 per step
            # (the plectoneme at 1.94 turns: 400 steps at rest, 9 % of the
            # way to the next load step)
            if t < t_target - 1e-14 and vis * p.force_scale(ev) <= QUASI * peak:
                quasi = min(1.0, max(2.0 * quasi, dt / (LOAD_RAMP * self.dt0)))
            else:
                quasi = 0.0
            near = self.near_saddle(r)
            dt = self.capped(dt)
            if near and vis <= opts.dynamics_tol and t >= t_target - 1e-14:
                if self.unstable_at(r, R, t):
                    if not self.came_back(r):
                        # at rest next to the saddle (the push was too small): again
                        r, R = self.push(r, R, self.lam_of(t))
                        dt, g = self.capped(dt), None
                        continue
                    self.held = True
                    self.S.result.log.append(
                        f"the flow came back to the saddle it was pushed off at t={t:.6g} "
                        f"(at rest {np.abs(r - self.away_from[0]).max():.3g} from it, pushed "
                        f"{self.pushed_by:.3g}): kept as held by contact")
                near = False                     # at rest in a stable state nearby
                self.away_from, self.pushes = None, 0
                if not self.held:
                    self.dt_saddle = np.inf
                # held: dt stays below the saddle's bound, so each damped step
                # stays convex along the mode contact holds (longer steps
                # went along it into the contact: Newton residuals 20-110)
            if t >= t_target - 1e-14 and vis <= min(opts.dynamics_tol, next_polish) \
                    and not near:
                done = self.polish(r, R, t, dt)
                if done is not None:
                    r2, R2, rep2 = done
                    return r2, R2, t, rep2, steps
                next_polish = 0.1 * vis          # try again once it moved on
                if self.unstable:                # it found a saddle: leave it
                    r, R = self.push(self.saddle[0], self.saddle[1], self.lam_of(t))
                    next_polish, dt, g = np.inf, self.capped(dt), None
        return None, (f"no equilibrium after {steps} damped steps (max_damped_steps="
                      f"{opts.max_damped_steps}) from pseudo-time {t:.6g}")


def follow(S, r, R, nominal, times, values, callback):
    """The load steps after step 0 with pseudo-dynamics where a static step
    fails (module doc); the loop of :func:`skfem_rod.solver.follow_path`
    with the damped phase in place of the step cut.  Returns the finished
    result, with the :class:`DynamicsLog` as ``result.dynamics``;
    ``nominal`` is the nominal pseudo-time step
    (:func:`skfem_rod.solver.first_step`)."""
    rod, opts, result, p = S.rod, S.opts, S.result, S.problem
    lam_of = lambda t: float(np.interp(t, times, values))         # noqa: E731
    dyn = PseudoDynamics(S, lam_of, times)
    result.dynamics = dyn.log
    t, h, streak, prev = 0.0, nominal, 0, None
    while t < 1.0 - 1e-14:
        if S.deadline.passed():
            result.finish(False, f"stopped at load factor {lam_of(t):.6g} (pseudo-time "
                                 f"{t:.6g}): {S.deadline.reason()}")
            return result
        nxt = times[times > t + 1e-14][0]
        hh = min(h, nxt - t)
        t_new = nxt if hh == nxt - t else t + hh
        lam, lam_new = lam_of(t), lam_of(t_new)
        saved = dyn.save()
        r1, R1, rep = S.advance(r, R, lam, lam_new, prev)
        ok = rep.converged and clearance_ok(rod, r, r1)
        saddle = ok and dyn.unstable_at(r1, R1, t_new)
        if saddle:
            ok, rep.reason = False, "it converged to an unstable equilibrium"
        dyn.log.add("static", rep, ok, t_new, p)
        if ok:
            t, prev, r, R = t_new, (lam, r, R), r1, R1
            dyn.recorded(0)
            keep(S, lam_new, r, R, rep, t, callback)
            streak += 1
            if streak >= 2:
                h = min(h * opts.grow, nominal)
            continue
        result.log.append(f"static step to lam={lam_new:.6g} (t={t_new:.6g}) failed "
                          f"({rep.reason or 'strands moved by more than half their clearance'}"
                          f"): damped steps (pseudo-dynamics)")
        if saddle:          # start from the saddle, pushed along its unstable mode
            r_s, R_s = dyn.push(r1, R1, lam_new)
            out = dyn.run(r_s, R_s, t_new, t_new, nominal)
        else:
            dyn.restore(saved)
            out = dyn.run(r, R, t, t_new, nominal)
        if out[0] is None:
            result.finish(False, f"stopped at load factor {lam:.6g} (pseudo-time {t:.6g}): "
                                 f"{out[1]}")
            return result
        r, R, t, rep, steps = out
        dyn.recorded(steps)
        result.log.append(f"{steps} damped steps to an equilibrium at lam={lam_of(t):.6g} "
                          f"(t={t:.6g})")
        keep(S, lam_of(t), r, R, rep, t, callback)
        prev, streak, h = None, 0, nominal
    result.finish(True, f"converged: {len(result.steps) - 1} steps to the end of the "
                        f"load path (load factor {lam_of(1.0):g}); {dyn.log.damped_steps} "
                        f"damped steps")
    return result


def keep(S, lam, r, R, rep, t, callback):
    """Record an equilibrium (with its lowest eigenvalue under ``stability``)."""
    if S.opts.stability and rep.lowest_eigenvalue is None:
        rep.lowest_eigenvalue = S.lowest_mode(r, R, lam)[0]
    S.keep(lam, r, R, rep, t, callback)
