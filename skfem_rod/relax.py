r"""Gradient-flow (proximal, backward-Euler pseudo-transient) continuation
through snaps.

Load stepping with Newton (:func:`skfem_rod.newton.newton`) follows an
equilibrium branch as long as there is one near the last converged state.
Past a limit point or a subcritical bifurcation (a twisted rod under
tension snapping into a loop, a shallow arch snapping through) there is
none: Newton fails at every step size.  The stable equilibrium on the other
side is reached by descending the energy ``E`` at the new load factor with
proximal steps

    y_{k+1} = argmin_y  E(y) + |y (-) y_k|_W^2 / (2 dt_k),

each solved by Newton on the augmented residual

    R(y) + c W (y (-) y_k),      c = 1 / dt_k,

(``y (-) y_k``: position difference and the spatial rotation vector
``log(R R_k^T)`` per node; the tangent gets ``+ c W``, its rotational part
approximated by the identity, which only slows Newton down far from
``y_k``).  This is backward Euler on the gradient flow ``W dy/dt = -R(y)``:
for any ``dt`` the step lowers ``E + |y - y_k|^2/2dt`` and the iterates
settle in a stable equilibrium (not on a saddle, unless started exactly on
it).

A flow (:class:`GradientFlow`) takes **Levenberg-Marquardt steps** first
(:meth:`GradientFlow.linearized`): one Newton iteration of the proximal
problem per step, ``(K + c W) dy = -R``, taken when the energy falls (the
change estimated by the trapezoid rule on the gradients at both ends, the
viscosity ``c`` adapted to the ratio of that change to the quadratic
model's), refused and retried at a larger ``c`` when it rises.  This is the
linearly implicit member of the family (pseudo-transient continuation with
an energy test, or Newton with a shifted Hessian): a small ``c`` makes
it Newton, with quadratic convergence to the static equilibrium, and a
large one a short step down ``-W^{-1} R``.  It costs one linear solve per
step where a proximal step costs a Newton solve.  Where it finds no descent
at any viscosity (the residual jumps along the step: a contact pair
switching), the flow starts again from its start with the proximal steps
solved by Newton, as follows (:meth:`GradientFlow.proximal`), with

* ``W`` a lumped metric per node (:func:`metric`): arclength share of the
  node times ``B / l^2`` for positions and ``B`` for spins (``B`` the larger
  bending stiffness, ``l = L / 10``);
* ``dt`` adapted: divided by 3 when the proximal Newton fails (8
  iterations) or nodes would move too far, multiplied by 4, 2 or 1.5 after
  an easy step (<= 2, 3, 5 Newton iterations), starting from
  ``SolverOptions.relax_dt`` or twice the first step the last flow accepted; the proximal steps are solved to
  ``rtol = 1e-7`` only (the last state is polished anyway);
* a clearance cap with contact on (:func:`clearance_ok`): no two
  non-neighbouring nodes move relative to each other by more than half
  their clearance ``|r_i - r_j| - 2 eps`` (at least ``eps / 2``), so that
  two strands cannot pass through each other between two iterates (the
  contact search only sees the iterates);
* when the flow starts next to a saddle (pushed off an unstable
  equilibrium along its unstable mode), a descent check: a step is
  rejected (``dt`` divided by 3) when the energy change estimated by the
  trapezoid rule on the gradients at both ends exceeds half the viscous
  work of the step; a long step of the non-convex proximal problem can
  otherwise climb back onto the saddle (Newton converges to any stationary
  point).  It is off for the flows of failed steps: with contact the
  trapezoid estimate is poor where the active set changes, and it stalled
  the two-ply at 1.7 turns;
* convergence when the viscous force ``max |c W (y_{k+1} (-) y_k)|`` is
  below ``relax_tol`` times the force scale ``max(|f_ext|, |reactions|)``;
  the state is then polished (:func:`polish`: Newton, and without contact
  proximal steps where Newton fails, the residual checked with the viscous
  term off) so that a relaxed step is an equilibrium to the same tolerance
  as any other step: ``rtol``, or the residual's round-off floor where
  that is above it (the loop of a localizing helix sliding along a long
  rod: :func:`skfem_rod.newton.at_floor`).  Where the polish does not
  converge the flow's state is kept, its residual on
  ``Step.relaxed_residual``, a ``Result.log`` line and a
  :class:`~skfem_rod.solver.RelaxedShortfall` warning.

The load stepper (:func:`skfem_rod.solver.solve`, option ``snap="relax"``)
calls a :class:`GradientFlow` in place of Newton inside the same
augmented-Lagrangian loop (:mod:`skfem_rod.augmented`) when a step fails.
"""
from dataclasses import replace
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from .newton import Report, newton, safeguarded_update
from .problem import Increment, State, clearance_ok, update_size

__all__ = ["GradientFlow", "metric", "polish", "climbs", "static_residual", "clearance_ok"]


def metric(rod, fixed=None, length_scale=None):
    """Lumped viscous metric ``W`` (one value per dof, zero at the fixed
    dofs): nodal arclength share times ``B / l^2`` (positions) and ``B``
    (spins), ``l = length_scale`` (default ``L / 10``)."""
    mesh = rod.mesh
    ell = rod.length / 10.0 if length_scale is None else float(length_scale)
    B = max(rod.section.EI1, rod.section.EI2)
    o = mesh.order
    s = mesh.s_nodes[o]
    share = np.zeros(s.size)
    gaps = np.diff(s)
    share[:-1] += 0.5 * gaps
    share[1:] += 0.5 * gaps
    h = np.empty(s.size)
    h[o] = share
    w = np.empty((s.size, 6))
    w[:, :3] = (B / ell**2) * h[:, None]
    w[:, 3:] = B * h[:, None]
    w = w.ravel()
    if fixed is not None:
        w = np.where(fixed, 0.0, w)
    return w


def climbs(g0, g1, dy, free):
    """Whether a proximal or damped step ``dy`` at a held load climbs: the
    energy change estimated by the trapezoid rule on the static residuals
    (the energy's gradients) ``g0`` at its start and ``g1`` at its end is
    above half its viscous work ``|g1 . dy|``.  The descent check of the
    gradient flow next to a saddle, and of the damped steps next to one
    without contact (:meth:`skfem_rod.dynamics.PseudoDynamics.capped`): a
    long implicit step of the non-convex problem can converge back onto
    the saddle (Newton finds any stationary point).  Along an unstable mode
    of curvature ``-k`` and metric ``q`` it rejects ``dt > 3 q / k`` from
    next to the saddle (tests/test_round_off_floor.py); the slack leaves
    room for the non-smooth contact terms."""
    down = 0.5 * float(np.dot((g0 + g1)[free], dy[free]))
    return down > 0.5 * abs(float(np.dot(g1[free], dy[free])))


def static_residual(problem, W, ev, dy, dt):
    """The residual of the evaluation ``ev`` of a proximal or damped step
    ``dy`` (viscosity ``1 / dt``) without its viscous term: the energy's
    gradient at the step's end."""
    return ev.residual - problem.to_basis(W * problem.to_spatial(dy)) / dt


#: refused Levenberg-Marquardt steps in a row before :meth:`GradientFlow.linearized` gives up
MAX_REFUSALS = 20

#: a Levenberg-Marquardt flow stops when its last STALL_WINDOW iterations
#: lowered the energy by at most STALL_SHARE of its whole fall and did not
#: lower the residual norm below its least before them (:func:`stalled`)
STALL_WINDOW = 50
STALL_SHARE = 1e-12
#: with friction on: iterations without a new least residual norm after
#: which a flow has stalled, whatever its energy estimate
FRICTION_STALL_WINDOW = 500
#: a Levenberg-Marquardt flow whose last STALL_WINDOW taken steps each
#: moved the state by at most this (``update_size``: the largest nodal
#: move over the rod's length, or spin) has stalled: the residual jumps at
#: the state itself.  Measured in the plectoneme (200 elements, the step
#: to 1.8125 turns, an Uzawa pass): a crossing pair came and went with
#: moves of 1e-18, the residual 15.46 <-> 31.25 between trials, every
#: taken step's estimated energy change at round-off but its sum over 50
#: steps above STALL_SHARE of the flow's small fall, and the flow ran for
#: 2183 steps (95 s) until the time limit
STILL_MOVE = 1e-14


def stalled(drops, least, friction=False):
    """Whether a Levenberg-Marquardt flow made no progress in its last
    :data:`STALL_WINDOW` iterations: ``drops`` the energy's fall so far
    (the sum of the taken steps' estimated changes, negative) and
    ``least`` the least residual norm so far, both per iteration (running
    values: the test costs the same at any iteration).

    Where the residual jumps at the state itself, no step length descends
    and none fails either: measured in the plectoneme's step from 2.3125
    turns (100 elements), a new minimum of weight 0 took a crossing pair's
    held multiplier at every other trial: the residual 3.8e-3 <-> 40 between
    trials at a viscosity of 1e15, the taken steps lowering the energy by
    1e-19 each, 4000 iterations until the time limit and never 20
    refusals in a row.  Such a flow is over; the proximal steps take over
    from its state (:meth:`GradientFlow.__call__`).

    With ``friction`` the estimate is no energy's: at held multipliers a
    slipping point's force has the fixed size ``gamma f_N`` along its trial
    slip, and its work falls without end along a sliding mode.  Measured in
    the knot's frictional cycle (``gamma_T`` = 0.2, crossing pairs on the
    smooth curve, tied with them): a flow lowered the residual to 2.2e-5 in
    250 iterations, then the estimate by 7e-11 per iteration (5e-3 of its
    fall every 250) at that residual, for more than 8 minutes; the proximal
    steps taking over from its state crawled on likewise.  So with friction
    a flow has stalled when its residual norm has not reached a new least
    in :data:`FRICTION_STALL_WINDOW` iterations, and it fails (the step is
    cut: :meth:`GradientFlow.__call__`)."""
    if friction:
        n = FRICTION_STALL_WINDOW
        return len(least) > n and least[-1] >= least[-n - 1]
    if len(drops) <= STALL_WINDOW:
        return False
    fall = drops[-STALL_WINDOW - 1] - drops[-1]
    return fall <= STALL_SHARE * abs(drops[-1]) and least[-1] >= least[-STALL_WINDOW - 1]


#: the viscosity a refused Levenberg-Marquardt step raises from is at least
#: this over ``relax_dt`` (a model that was good at a tiny viscosity)
LM_C_LOW = 1e-6

#: proximal steps of a polish (:func:`polish`) before it gives up
POLISH_STEPS = 40


def polish(problem, W, c, r, R, lam, opts, prescribed=None, clearance=True):
    """The equilibrium at ``lam`` next to a flow's or a damped phase's
    state ``(r, R)``: plain Newton, and where that does not converge,
    proximal steps (viscosity ``c W`` about the last iterate, ``c``
    divided by 4 after each converged step and multiplied by 4 after a
    failed one, starting from ``c``: a proximal step contracts the
    residual along a mode of stiffness ``k`` by ``c w / (k + c w)``) until the
    residual without the viscous term is within ``rtol`` times the force
    scale or its round-off floor (:meth:`~skfem_rod.problem.Problem.round_off_floor`).
    Same signature and return value as :func:`~skfem_rod.newton.newton`
    after ``W`` and ``c`` (``prescribed`` goes to the first solve); the
    report counts every Newton iteration.  ``clearance``: a solve that
    moves a node beyond the clearance cap (:func:`clearance_ok`) does not
    count as converged (the gradient flow's polish; the pseudo-dynamics'
    lets plies in contact slide and leaves a passage to the AL loop's
    true-distance check).

    Along a very soft mode (the loop of a localizing helix sliding along a
    long rod: lowest eigenvalue 1e-13 of the stiffest) Newton's update
    amplifies the residual's round-off by the inverse of that eigenvalue
    and the iterates cycle (residual 0.07 -> 9e-5 -> 1e-7 -> 0.08); the
    proximal term bounds the update along the mode, and the static residual
    is what decides, so a polished state is an equilibrium to the same test
    as any load step's.

    With contact there are no proximal steps (Newton's result is
    returned): a polish that fails there meets a change of the active set,
    not a soft mode, and in the frictional plectoneme the proximal steps
    took 1.5 times the time to 1.25 turns on the same path."""
    rod = problem.rod

    def cleared(r0, r1):
        return not clearance or clearance_ok(rod, r0, r1)
    r1, R1, lam1, rep = newton(problem, r, R, lam, opts, prescribed=prescribed)
    if rep.converged and not cleared(r, r1):
        rep.converged, rep.reason = False, "a node moved beyond the clearance cap"
    if rep.converged or (prescribed is not None and np.any(prescribed)) \
            or problem.contact is not None:
        return r1, R1, lam1, rep
    total, history, why = rep.iterations, list(rep.history), rep.reason
    inner = replace(opts, max_iterations=min(opts.max_iterations, 12))
    for _ in range(POLISH_STEPS):
        with problem.damped(c, W, r, R):
            r1, R1, _, step = newton(problem, r, R, lam, inner)
        total += step.iterations
        if not (step.converged and cleared(r, r1)):
            c *= 4.0
            continue
        r, R = r1, R1
        ev = problem.evaluate(r, R, lam)
        rn, scale = problem.residual_norm(ev), problem.force_scale(ev)
        history.append(rn)
        floor = problem.at_floor(r, R, lam, ev, rn) if rn > opts.rtol * scale else None
        if rn <= opts.rtol * scale or floor is not None:
            return r, R, lam, Report(True, iterations=total, history=history, evaluation=ev,
                                     floor=None if floor is None else floor / scale)
        c *= 0.25
    return r, R, lam, Report(False, iterations=total, history=history,
                             reason=f"the polish did not converge: Newton ({why}), then "
                                    f"{POLISH_STEPS} proximal steps")


class GradientFlow:
    """The gradient flow on a :class:`~skfem_rod.problem.Problem` (module
    doc): Levenberg-Marquardt steps or proximal steps (option
    ``flow_steps``).  It keeps the metric ``W`` and what worked last: the
    flows of one problem meet the same stiffness, so a proximal flow starts
    at twice the first step size the last one accepted, and a
    Levenberg-Marquardt run at the viscosity the last one ended with (else
    both at ``SolverOptions.relax_dt``)."""

    def __init__(self, problem, deadline=None):
        self.problem = problem
        #: the solve's :class:`~skfem_rod.options.Deadline` (a flow stops when it passed)
        self.deadline = deadline
        self.W = metric(problem.rod, problem.fixed)
        self.dt = None
        #: the viscosity the last Levenberg-Marquardt run ended with
        self.c = None
        #: the last Levenberg-Marquardt run stopped without progress, its
        #: prescribed increment applied (:func:`stalled`)
        self.stalled = False

    @cached_property
    def D(self):
        """``W`` as a sparse diagonal in the dof basis: the Levenberg-Marquardt
        shift, built at the first flow that takes those steps."""
        T = self.problem.T
        W = sp.diags(self.W)
        return (W if T is None else T.T @ W @ T).tocsc()

    def __call__(self, r, R, lam, opts, prescribed=None, descent=False):
        """The stable equilibrium at load factor ``lam`` (contact multipliers
        held) reached from ``(r, R)`` down the energy, the prescribed
        increment applied on the way, by the steps of the option
        ``flow_steps``: Levenberg-Marquardt steps (:meth:`linearized`; with
        contact on, by default), and where those find no descent, proximal
        steps solved by Newton (:meth:`proximal`) from ``(r, R)`` again
        (from the flow's own state, lower, where it stalled:
        :func:`stalled`; with friction on, a stalled flow fails instead, a
        sliding mode at the held multipliers, and the step is cut); or
        proximal steps alone (without contact, by default).
        Same signature and return value as :func:`skfem_rod.newton.newton`;
        the report also has ``flow_steps`` (both kinds counted).
        ``descent``: the proximal steps' descent check (a flow started
        next to a saddle, pushed off along its unstable mode; the
        Levenberg-Marquardt steps descend by construction)."""
        how = opts.flow_steps
        if how == "auto":
            how = "linearized" if self.problem.contact is not None else "proximal"
        if how == "proximal":
            return self.proximal(r, R, lam, opts, prescribed, descent)
        r1, R1, lam1, rep = self.linearized(r, R, lam, opts, prescribed)
        if rep.converged or (self.deadline is not None and self.deadline.passed()):
            return r1, R1, lam1, rep
        if self.stalled and self.problem.friction:
            return r, R, lam, rep    # sliding at the held multipliers: the step is cut
        self.problem.calls["flow_fallbacks"] += 1
        if self.stalled:             # on from its state: lower, the increment applied
            r1, R1, lam1, out = self.proximal(r1, R1, lam, opts, None, descent)
        else:
            r1, R1, lam1, out = self.proximal(r, R, lam, opts, prescribed, descent)
        out.iterations += rep.iterations
        out.flow_steps += rep.flow_steps
        if not out.converged:
            out.reason = f"{rep.reason}; then {out.reason}"
        return r1, R1, lam1, out

    def linearized(self, r, R, lam, opts, prescribed=None):
        """Levenberg-Marquardt on the energy at load factor ``lam``: each
        step one Newton iteration of the proximal problem about the current
        iterate, ``(K + c W) dy = -G`` (``c = 1 / dt``, the prescribed
        increment carried by the first steps), the viscosity adapted to
        how well the quadratic model predicted the energy change, which is
        estimated by the trapezoid rule on the gradients ``G`` at both ends
        of the step (exact for a quadratic energy; the frictionless rod and
        contact at held multipliers are conservative):

        * a step that lowers the energy is taken, and ``c`` is multiplied
          by ``max(1/3, 1 - (2 rho - 1)^3)`` (``rho`` the ratio of the
          energy change to the model's; Nielsen's rule), or by the ratio
          of the new residual norm to the old where that is smaller (as
          pseudo-transient continuation's switched evolution relaxation
          does): a good model drives ``c`` to zero and the steps to
          Newton's, and with ``c`` falling as the residual does the
          convergence at the end is Newton's quadratic one;
        * a step that raises it is refused, and ``c`` grows by ``nu``
          (2, doubled at each refusal in a row): the step shortens and
          turns towards ``-W^{-1} G``, along which a small enough step
          descends; the contact search's memory goes back to the state's
          (:meth:`~skfem_rod.problem.Problem.search_memory`: otherwise the
          residual at the state is the refused trial's search's and jumps);
        * a step that would leave an element chart or carry a strand
          through another (the clearance cap, always on here) is halved
          first (:func:`skfem_rod.newton.safeguarded_update`, no position
          correction: it would move the state off the step the model
          predicted).

        Converged when the residual is within ``rtol`` times the force
        scale or at its round-off floor, with the prescribed increment
        applied: the static equilibrium itself, no polish needed.  Fails
        after :data:`MAX_REFUSALS` refusals in a row (the energy's gradient
        jumps along the step, e.g. a contact pair switching, so that no
        step length descends by the estimate), after :data:`STALL_WINDOW`
        iterations without progress (:func:`stalled`: the residual jumps at
        the state itself; with friction on, :data:`FRICTION_STALL_WINDOW`
        iterations without a lower residual: a sliding mode), after
        :data:`STALL_WINDOW` taken steps in a row that each moved the state
        by at most :data:`STILL_MOVE` (the same jump, where the flow's whole
        fall was too small for the energy test), or
        ``max_flow_steps`` steps.  One linear solve
        per step, where a proximal step costs a Newton solve: the knot's
        cycle took a fifth of the time (docs/knot.md)."""
        problem = self.problem
        free, fixed = problem.free, problem.fixed
        safe = replace(opts, clearance_cap=True, position_correction=False)
        c = 1.0 / opts.relax_dt if self.c is None else self.c
        c_low = LM_C_LOW / opts.relax_dt
        remaining = np.zeros(problem.mesh.n_dofs) if prescribed is None else prescribed.copy()
        ev = problem.evaluate(r, R, lam)
        memory = problem.search_memory()      # the state's: a refused trial puts it back
        history, its, steps, nu, refused = [], 0, 0, 2.0, 0
        # the energy's fall and the least residual norm so far, per iteration
        drop, drops, least = 0.0, [], []
        still = 0               # taken steps in a row that moved the state by round-off
        self.stalled = False
        why = f"{opts.max_flow_steps} steps"
        while steps < opts.max_flow_steps:
            if self.deadline is not None and self.deadline.passed():
                why = self.deadline.reason()
                break
            G = ev.residual
            rn, scale = problem.residual_norm(ev), problem.force_scale(ev)
            history.append(rn)
            if not (np.isfinite(scale) and np.all(np.isfinite(G))):
                why = "non-finite residual or forces"
                break
            moving = bool(np.any(remaining))
            if not moving:
                floor = None if rn <= opts.rtol * scale else problem.at_floor(r, R, lam, ev, rn)
                if rn <= opts.rtol * scale or floor is not None:
                    self.c = c
                    return r, R, lam, Report(True, iterations=its, history=history,
                                             evaluation=ev, flow_steps=steps,
                                             floor=None if floor is None else floor / scale)
            drops.append(drop)
            least.append(min(rn, least[-1]) if least else rn)
            if not moving and stalled(drops, least, problem.friction):
                self.stalled = True
                why = (f"no lower residual in {FRICTION_STALL_WINDOW} steps (friction on: "
                       "a sliding mode at the held friction multipliers)"
                       if problem.friction else
                       f"no progress in {STALL_WINDOW} steps (the energy's fall below "
                       f"{STALL_SHARE:g} of the flow's, the residual not lower)")
                break
            if not moving and still >= STALL_WINDOW:
                self.stalled = True
                why = (f"its last {STALL_WINDOW} steps moved the state by at most "
                       f"{STILL_MOVE:g} of the rod's length (the residual jumps at the state)")
                break
            K = ev.tangent
            A = K + c * self.D
            try:
                solve = problem.factor(A)
                dy = solve(-G - A @ remaining if moving else -G)
            except RuntimeError as err:                  # singular factor
                why = f"singular tangent ({err})"
                break
            its += 1
            dy[fixed] = remaining[fixed]
            trial, alpha, why_not = safeguarded_update(problem, State(r, R, lam), Increment(dy),
                                                       safe, np.inf, rn)
            if trial is not None and moving:
                # the prescribed motion: taken as far as the safeguards allow
                r, R, ev = trial
                memory = problem.search_memory()
                remaining = remaining * (1.0 - alpha)
                remaining[np.abs(remaining) < 1e-300] = 0.0
                continue
            ok = trial is not None
            if ok:
                d = alpha * dy
                G1 = trial[2].residual
                change = 0.5 * float(np.dot((G + G1)[free], d[free]))
                model = float(np.dot(G[free], d[free])) + 0.5 * float(np.dot(d, K @ d))
                rn_t = problem.residual_norm(trial[2])
                ok = change < 0.0 or (rn_t <= 0.5 * rn
                                      and change <= 1e-12 * scale * np.linalg.norm(d))
            if ok:
                r, R, ev = trial
                memory = problem.search_memory()
                drop += change
                steps += 1
                still = still + 1 if update_size(problem, d) <= STILL_MOVE else 0
                problem.calls["flow_steps"] += 1
                refused, nu = 0, 2.0
                if alpha == 1.0:                         # else the safeguards set the length
                    rho = change / model if model < 0.0 else 1.0
                    c *= min(max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), rn_t / rn)
                continue
            problem.restore_search(memory)
            refused += 1
            if refused > MAX_REFUSALS:
                why = (f"no descent after {MAX_REFUSALS} refusals in a row "
                       f"({why_not or 'the energy rose'})")
                break
            c, nu = max(c, c_low) * nu, 2.0 * nu
        return r, R, lam, Report(False, iterations=its, history=history,
                                 reason=f"Levenberg-Marquardt stopped: {why}",
                                 flow_steps=steps)

    def proximal(self, r, R, lam, opts, prescribed=None, descent=False):
        """Proximal steps at load factor ``lam`` (contact multipliers held)
        from ``(r, R)``, the first one carrying the prescribed increment,
        each solved by Newton, until the viscous force is below
        ``opts.relax_tol`` times the force scale; then a plain Newton
        polish.  Same signature and return value as
        :func:`skfem_rod.newton.newton`; the report also has
        ``flow_steps``.  ``descent=True`` adds the descent check (a flow
        started next to a saddle, pushed off along its unstable mode)."""
        problem, W = self.problem, self.W
        rod = problem.rod
        # the proximal steps need not be solved to round-off: only the last
        # state counts, and it is polished by Newton; they are plain Newton
        # at the held multipliers (contact_solve "uzawa": a rejected step
        # must leave the multipliers as they were)
        inner = replace(opts, max_iterations=min(opts.max_iterations, 8),
                        rtol=max(opts.rtol, 1e-7), increment_tol=max(opts.increment_tol, 1e-8),
                        contact_solve="uzawa")
        dt = opts.relax_dt if self.dt is None else self.dt
        presc = None if prescribed is None else prescribed.copy()
        steps = tries = iters = 0
        fscale = None
        why = "no proximal step"
        free = problem.free
        g0 = None
        if descent and (presc is None or not np.any(presc)):
            g0 = problem.evaluate(r, R, lam, tangent=False).residual
        while steps < opts.max_flow_steps:
            if self.deadline is not None and self.deadline.passed():
                why = self.deadline.reason()
                break
            tries += 1
            with problem.damped(1.0 / dt, W, r, R):
                r1, R1, _, rep = newton(problem, r, R, lam, inner, prescribed=presc)
            iters += rep.iterations
            ok = rep.converged
            if ok and not clearance_ok(rod, r, r1):
                ok, rep.reason = False, "a node moved beyond the clearance cap"
            if ok:
                # descent next to a saddle: a too long step of the non-convex
                # proximal problem can climb back onto it (:func:`climbs`)
                dy = problem.increment(r1, R1, r, R)
                g1 = static_residual(problem, W, rep.evaluation, dy, dt)
                if descent and g0 is not None and climbs(g0, g1, dy, free):
                    ok, rep.reason = False, "the proximal step climbs (energy would rise)"
            if not ok:
                why = rep.reason
                dt /= 3.0
                if dt < opts.relax_dt * 1e-9:
                    break
                continue
            steps += 1
            problem.calls["flow_steps"] += 1
            g0 = g1
            vis = float(np.abs(W * problem.to_spatial(dy)).max() / dt)
            if steps == 1:
                self.dt = 2.0 * dt
            if fscale is None:
                fscale = problem.force_scale(rep.evaluation)
            r, R, presc = r1, R1, None
            if rep.iterations <= 5:
                grow = 4.0 if rep.iterations <= 2 else 2.0 if rep.iterations <= 3 else 1.5
                dt = min(grow * dt, 1e12 * opts.relax_dt)
            if vis <= opts.relax_tol * fscale:
                r2, R2, _, fin = polish(problem, W, 1.0 / dt, r, R, lam, opts)
                iters += fin.iterations
                if fin.converged:
                    r, R, rep = r2, R2, fin
                else:
                    # the flow's state, kept with its residual (above rtol:
                    # a very soft mode, along which Newton's basin is tiny):
                    # the step says so (Report.relaxed_residual, Result.log,
                    # RelaxedShortfall)
                    problem.calls["unpolished"] += 1
                    ev = problem.evaluate(r, R, lam)
                    rep = Report(True, history=rep.history, evaluation=ev,
                                 relaxed_residual=problem.residual_norm(ev)
                                 / problem.force_scale(ev))
                rep.iterations, rep.flow_steps = iters, steps
                return r, R, lam, rep
        return r, R, lam, Report(False, iterations=iters, flow_steps=steps,
                                 reason=f"gradient flow stopped after {steps} steps "
                                        f"({tries} tries, dt={dt:.3g}): {why}")
