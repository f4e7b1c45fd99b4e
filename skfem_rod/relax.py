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
it).  :func:`flow` runs it with

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

import numpy as np

from .newton import Report, newton
from .problem import clearance_ok

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
    """Proximal steps of the gradient flow on a :class:`~skfem_rod.problem.Problem`
    (module doc).  It keeps the metric ``W`` and the step size that worked
    last: the flows of one problem meet the same stiffness, so each flow
    starts at twice the first step size the last one accepted (else at
    ``SolverOptions.relax_dt``)."""

    def __init__(self, problem, deadline=None):
        self.problem = problem
        #: the solve's :class:`~skfem_rod.options.Deadline` (a flow stops when it passed)
        self.deadline = deadline
        self.W = metric(problem.rod, problem.fixed)
        self.dt = None

    def __call__(self, r, R, lam, opts, prescribed=None, descent=False):
        """Proximal steps at load factor ``lam`` (contact multipliers held)
        from ``(r, R)``, the first one carrying the prescribed increment,
        until the viscous force is below ``opts.relax_tol`` times the force
        scale; then a plain Newton polish.  Same signature and return value
        as :func:`skfem_rod.newton.newton`; the report also has
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
