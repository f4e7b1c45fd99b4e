"""Options of the solvers, validated in one place.

:class:`SolverOptions` holds every control of Newton (:mod:`skfem_rod.newton`),
load stepping (:mod:`skfem_rod.solver`), the gradient flow
(:mod:`skfem_rod.relax`) and continuation (:mod:`skfem_rod.continuation`);
:func:`make_options` builds it from keyword arguments with a clear error for
unknown names.  ``Rod.solve(method="barrier")`` takes some of them and
:class:`EnergyOptions` and :class:`BarrierOptions` instead
(:func:`split_barrier_options`).  The contact options are
:class:`skfem_rod.contact.ContactOptions`.
"""
import difflib
import numbers
import time
from dataclasses import dataclass, field, fields

import numpy as np


@dataclass(frozen=True)
class Spec:
    """What a field accepts (the one place an option is checked): ``kind``
    is ``"number"`` (finite, bounded by ``lo``/``hi``, open or closed),
    ``"integer"`` (``lo`` to ``hi``), ``"boolean"`` or ``"choice"``
    (``choices``); ``doc`` is the one-line meaning for tables."""
    kind: str
    doc: str
    lo: float = None
    hi: float = None
    lo_open: bool = True
    choices: tuple = ()
    hi_open: bool = False

    def allowed(self):
        """The allowed values in words (error messages, docs tables)."""
        if self.kind == "boolean":
            return "true or false"
        if self.kind == "choice":
            q = [repr(c) for c in self.choices]
            return ", ".join(q[:-1]) + " or " + q[-1] if len(q) > 1 else q[0]
        if self.kind == "integer":
            return (f"an integer in [{self.lo}, {self.hi}]" if self.hi is not None
                    else f"an integer >= {self.lo}")
        op = ">" if self.lo_open else ">="
        words = "a finite number" + (f" {op} {self.lo:g}" if self.lo is not None else "")
        return words + (f" and {'<' if self.hi_open else '<='} {self.hi:.17g}"
                        if self.hi is not None else "")

    def check(self, name, v):
        """``v`` if it is allowed, else ValueError naming ``name``, the
        value and what is allowed (no coercion: ``True`` is no number)."""
        ok = True
        if self.kind == "boolean":
            ok = isinstance(v, (bool, np.bool_))
        elif self.kind == "choice":
            ok = isinstance(v, str) and v in self.choices
        elif self.kind == "integer":
            ok = (isinstance(v, numbers.Integral) and not isinstance(v, (bool, np.bool_))
                  and v >= self.lo and (self.hi is None or v <= self.hi))
        else:
            ok = (isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_))
                  and np.isfinite(v)
                  and (self.lo is None or v > self.lo or (not self.lo_open and v == self.lo))
                  and (self.hi is None or v < self.hi or (not self.hi_open and v == self.hi)))
        if not ok:
            raise ValueError(f"{name} must be {self.allowed()}, got {v!r}")
        return v


def _opt(default, kind, doc, **kw):
    return field(default=default, metadata={"spec": Spec(kind, doc, **kw)})


def _pos(default, doc):
    return _opt(default, "number", doc, lo=0.0)


@dataclass
class SolverOptions:
    """Controls of :func:`solve`.

    rtol : converged when ``|R_free| <= rtol * max(|f_ext|, |reactions|)``,
        or when the last Newton update was below ``increment_tol``
        (positions in units of the rod length, spins in radians).  The
        residual of a stiff rod stagnates at a round-off floor that grows
        with the mesh (5e-7 at 1000 elements, 1.5e-5 at 10000 for EA/EI =
        1e4) while the Newton updates keep converging quadratically to
        1e-14, so the update, not the residual, tells convergence there.
    max_iterations : Newton iterations per step before the step is cut.
    line_search : safeguard the Newton update: scale it so that no nodal
        spin exceeds ``max_spin_update``, and halve it (at most
        ``max_backtracks`` times) while the trial state leaves an element
        chart, is not finite, or raises the residual norm more than
        ``max_growth`` times.  (A residual-norm or energy-slope merit test
        vetoes good Newton steps of stiff rods: one full step from a
        straight rod raises the residual 2000x through O(theta^2) axial
        strain, and the next step converges; see docs/theory.md.)
    min_step : smallest load-factor step before the solve gives up.
    max_rotation_step : largest prescribed end rotation per step (rad).
    grow : factor by which a cut step grows back after two successes in a
        row (twice as many each time the grown step failed at once, up to
        16; half as many again each time it went through).
    snap : what to do when a load step fails: ``"cut"`` (default) halves
        the step until ``min_step``; ``"relax"`` first tries the gradient
        flow (proximal continuation, :mod:`skfem_rod.relax`) at the step's
        load factor, which crosses a snap (no nearby equilibrium) into the
        stable equilibrium on the other side, and cuts only if that fails.
    stability : compute the lowest eigenvalue of the symmetrized tangent at
        every converged step (``Step.lowest_eigenvalue``); with
        ``snap="relax"`` a step that converged to an unstable equilibrium is
        pushed off it along the unstable mode and relaxed.
    relax_tol : the gradient flow stops when the viscous force is below
        ``relax_tol`` times the force scale (then Newton polishes).
    relax_dt : first pseudo-time step of the flow (metric of
        :func:`skfem_rod.relax.metric`).
    max_flow_steps : accepted proximal steps per flow before giving up.
    flow_steps : how the gradient flow steps (:class:`skfem_rod.relax.GradientFlow`):
        ``"linearized"`` Levenberg-Marquardt steps, one linear solve each,
        taken where the energy falls (the proximal steps below where they
        find no descent); ``"proximal"`` proximal problems solved by Newton;
        ``"auto"`` (default) the first with contact on, the second without.
        Measured (docs/theory.md): with contact the linearized steps took
        the knot's cycle 4-5 times faster and the twisted rod's snaps 2
        times; without contact the proximal ones took the localized
        writhing 8 times faster (its loop forms by large rotations, which
        the linear model follows only in short steps).
    predictor : start of each step's Newton iterations: ``"none"`` (default)
        the last converged state; ``"secant"`` the last converged state
        moved along the secant of the last two (scaled to the new load
        increment; supported dofs stay where the load path puts them).  On a
        smooth path the secant start saves most iterations and keeps Newton
        in the basin of the equilibrium it follows (a loose knot, whose
        loops swing freely, diverges from the plain start).
    clearance_cap : with contact on (default true), halve a Newton update
        (and the secant predictor) while it moves two non-neighbouring nodes
        relative to each other by more than half their clearance
        (:func:`skfem_rod.relax.clearance_ok`), so that no iterate can carry
        a strand through another.  Without it, the first update of a step
        that brings strands into contact (no contact stiffness in the
        tangent yet) can put one strand on the far side of another, and the
        solve converges there: a hairpin leg pressed by a large force ends
        up through the other leg (``tests/test_predictor_cap.py``).
    dynamics : follow the path by implicit pseudo-dynamics where a load
        step fails (:mod:`skfem_rod.dynamics`): backward-Euler steps with
        the lumped viscous metric of :func:`skfem_rod.relax.metric`, an
        adaptive pseudo-time step (doubled after an easy Newton solve,
        halved after a failed one) and the load advanced with the
        pseudo-time, contact enforced at every step; the state is recorded
        once the viscous force is below ``dynamics_tol`` and Newton with the
        viscous term off has polished it into an equilibrium.  Excludes
        ``snap="relax"``.
    dynamics_dt : first pseudo-time step of a damped phase (units of the
        metric: ``1`` damps a position dof by ``B / (L/10)^2`` per unit
        length and unit velocity).
    dynamics_tol : viscous force (relative to the force scale) below which a
        damped state is polished into an equilibrium.
    dynamics_uzawa : run the augmented-Lagrangian loop to its tolerances in
        every damped step (default true: the penetration is within the
        contact tolerance at every pseudo-time step; false: a damped step is
        one Newton solve with the multipliers of the last converged state
        held and the penalty taking up new contact, measured 0.1-0.4 eps of
        penetration in the plectoneme; the recorded states are solved in
        full either way).
    max_damped_steps : accepted damped steps per damped phase before the
        solve gives up.
    time_limit : wall-clock seconds the solve may take (default 0: no
        limit).  Checked before every load step, damped step, gradient-flow
        step and continuation step; when it has run out the solve stops
        there (``converged`` false) with every converged step kept and the
        message saying so.
    position_correction : after a Newton update that raised the residual,
        one Newton step on the positions alone with the rotations held
        (default true; :func:`skfem_rod.newton.position_correction`): the
        roll-up of a slender rod by pi/2 per step takes 3-4 iterations per
        step instead of 23.
    slope_search : with frictionless contact (default false), shorten a
        Newton update whose energy slope ``G . dy`` at the trial turned
        positive beyond half the start slope: the update overshot the
        minimum of the energy along it (docs/theory.md).
    contact_solve : with contact on, ``"uzawa"`` (the paper's iteration:
        multipliers updated after each converged Newton solve,
        :mod:`skfem_rod.augmented`), ``"newton"`` (generalized Newton on
        the Alart-Curnier augmented Lagrangian, the normal and friction
        multipliers unknowns beside the dofs, merit line search:
        :mod:`skfem_rod.nonsmooth`, docs/contact-solve.md) or
        ``"newton_normal"`` (the same with the normal multipliers only; the
        friction multipliers updated between Newton solves by Uzawa).
    """
    rtol: float = _pos(1e-10, "residual tolerance on the free dofs (relative to the loads "
                              "on them and the forces the supports take up)")
    increment_tol: float = _pos(1e-11, "converged when the last Newton update is below it "
                                       "(positions relative to the rod length, spins in "
                                       "radians)")
    max_iterations: int = _opt(25, "integer", "Newton iterations per step before the step "
                                              "is cut", lo=1, hi=10_000)
    line_search: bool = _opt(True, "boolean", "safeguard the Newton update (spin limit, "
                                              "backtracking)")
    max_backtracks: int = _opt(6, "integer", "halvings of a Newton update", lo=1, hi=100)
    max_spin_update: float = _pos(0.5 * np.pi, "largest nodal spin of one Newton update (rad)")
    max_growth: float = _pos(1e6, "largest accepted growth of the residual norm in one "
                                  "update")
    min_step: float = _pos(1e-6, "smallest pseudo-time step before the solve stops")
    max_rotation_step: float = _pos(0.5 * np.pi, "largest prescribed rotation per step (rad)")
    grow: float = _opt(2.0, "number", "growth factor of a cut step after two successes "
                       "in a row (twice as many after a grown step failed)",
                       lo=1.0, lo_open=False)
    snap: str = _opt("cut", "choice", "when a step fails: cut it, or first relax by a "
                                      "gradient flow through the snap (skfem_rod.relax)",
                     choices=("cut", "relax"))
    stability: bool = _opt(False, "boolean", "lowest eigenvalue of the symmetrized tangent "
                                             "at every converged step")
    relax_tol: float = _pos(1e-8, "gradient flow stops when the viscous force is below this "
                                  "times the force scale")
    relax_dt: float = _pos(1.0, "first pseudo-time step of the gradient flow")
    max_flow_steps: int = _opt(20000, "integer", "proximal steps per flow before giving up",
                               lo=1, hi=10_000_000)
    flow_steps: str = _opt("auto", "choice", "gradient flow's steps: Levenberg-Marquardt "
                                             "(linearized), proximal problems solved by "
                                             "Newton, or auto (linearized with contact)",
                           choices=("auto", "linearized", "proximal"))
    predictor: str = _opt("none", "choice", "start of each step's Newton iterations: the last "
                                            "converged state, or that state moved along the "
                                            "secant of the last two",
                          choices=("none", "secant"))
    clearance_cap: bool = _opt(True, "boolean", "with contact: halve a Newton update while it "
                                                "would move two non-neighbouring nodes toward "
                                                "each other by more than half their clearance "
                                                "(no strand carried through another)")
    position_correction: bool = _opt(True, "boolean", "after a Newton update that raised the "
                                                      "residual 10x, one Newton step on the "
                                                      "positions with the rotations held")
    slope_search: bool = _opt(False, "boolean", "with frictionless contact: shorten a Newton "
                                                "update that overshoots the minimum of the "
                                                "energy along it (the slope G . dy turned "
                                                "positive)")
    contact_solve: str = _opt("uzawa", "choice", "contact solve: Uzawa updates of the "
                                                 "multipliers between Newton solves (the "
                                                 "paper), a generalized Newton on the "
                                                 "normal and friction multipliers too "
                                                 "(skfem_rod.nonsmooth), or on the normal "
                                                 "ones only (friction by Uzawa)",
                              choices=("uzawa", "newton", "newton_normal"))
    dynamics: bool = _opt(False, "boolean", "where a load step fails, implicit "
                                            "pseudo-dynamics (damped backward-Euler steps, "
                                            "adaptive pseudo-time step) to the next "
                                            "equilibrium (skfem_rod.dynamics)")
    dynamics_dt: float = _pos(1.0, "first pseudo-time step of a damped phase "
                                   "(skfem_rod.dynamics)")
    dynamics_tol: float = _opt(1e-3, "number", "viscous force (relative to the force scale) "
                                               "below which a damped state is polished into an "
                                               "equilibrium", lo=0.0, hi=1.0)
    dynamics_uzawa: bool = _opt(True, "boolean", "run the Uzawa loop to its tolerances in "
                                                 "every damped step (false: only in the static "
                                                 "steps and polishes; damped steps hold the "
                                                 "multipliers, the penalty takes up new "
                                                 "contact)")
    max_damped_steps: int = _opt(5000, "integer", "damped steps per damped phase before "
                                                  "giving up", lo=1, hi=10_000_000)
    time_limit: float = _opt(0.0, "number", "wall-clock seconds the solve may take (0: no "
                                            "limit); it stops with every converged step "
                                            "kept", lo=0.0, lo_open=False)

    def __post_init__(self):
        for f in fields(self):
            f.metadata["spec"].check(f.name, getattr(self, f.name))
        if self.dynamics and self.snap == "relax":
            raise ValueError("dynamics=True and snap='relax' exclude each other: the "
                             "pseudo-dynamics crosses the snaps itself (use snap='cut')")


@dataclass(frozen=True)
class EnergyOptions:
    """Controls of the energy Newton of ``Rod.solve(method="barrier")``
    (:class:`skfem_rod.minimize.EnergySolve`; the names as in the module
    doc of :mod:`skfem_rod.minimize`)."""
    rtol: float = _pos(1e-8, "residual tolerance of a step (relative to the force scale)")
    max_iterations: int = _opt(3000, "integer", "Newton iterations per step (all friction "
                                                "lags) before the step is cut",
                               lo=1, hi=10_000_000)
    armijo: float = _opt(1e-4, "number", "Armijo fraction of the slope a line search's "
                                         "energy must fall by", lo=0.0, hi=1.0, hi_open=True)
    max_spin: float = _pos(0.5, "largest nodal spin of one Newton update (rad)")
    fraction: float = _opt(0.8, "number", "largest share of the way to the first node-pair "
                                          "contact an update may go", lo=0.0, hi=1.0,
                           hi_open=True)
    shift_start: float = _pos(1e-6, "first shift of a tangent that is not positive definite "
                                    "(times the tangent's diagonal)")
    halvings: int = _opt(30, "integer", "line-search halvings before the shift is raised",
                         lo=1, hi=1000)
    retries: int = _opt(6, "integer", "raises of the shift (100x) per iteration", lo=1,
                        hi=100)
    max_lags: int = _opt(60, "integer", "friction: lags of the normal forces per step",
                         lo=1, hi=100_000)
    lag_tol: float = _pos(1e-3, "friction: the fallback's lag settled when no normal force "
                                "changes by more than this times the largest")
    lag_rtol: float = _pos(1e-5, "friction: residual tolerance of the fallback's solves")
    near_rtol: float = _pos(0.1, "friction: residual tolerance of the solves that settle "
                                 "the lag before the live Newton")
    live_iterations: int = _opt(80, "integer", "friction: live Newton iterations per lag",
                                lo=1, hi=10_000_000)
    penetration_tol: float = _pos(1e-3, "a step converges only where the strands' true "
                                        "least distance is at least 2 radius (1 - this)")
    live_tol: float = _pos(0.3, "friction: the lag settled for the live Newton when no "
                                "normal force changes by more than this times the largest")

    def __post_init__(self):
        for f in fields(self):
            f.metadata["spec"].check(f.name, getattr(self, f.name))


@dataclass(frozen=True)
class BarrierOptions:
    """The node barrier's own options (``Rod.solve(method="barrier")``,
    :mod:`skfem_rod.contact.barrier`)."""
    barrier_width: float = _pos(0.02, "width of the barrier (times the contact radius)")
    barrier_force: float = _opt(None, "number", "a pair's force at half the width (default: "
                                                "the dead loads' total, at least EI/L^2)",
                                lo=0.0)
    slip_smoothing: float = _pos(1e-3, "slip below which the friction force is smoothed "
                                       "(times the radius)")
    handles: bool = _opt(False, "boolean", "continue both ends by rigid straight handles "
                                           "along their tangents, so that no strand passes "
                                           "around an end (the link of held ends is kept)")

    def __post_init__(self):
        for f in fields(self):
            v = getattr(self, f.name)
            if not (v is None and f.name == "barrier_force"):      # None: the default
                f.metadata["spec"].check(f.name, v)


#: the load path's options (:class:`SolverOptions`) that
#: ``Rod.solve(method="barrier")`` takes; its predictor defaults to the secant
#: (made quadratic with the path's tangent where that is known: frictionless,
#: :func:`skfem_rod.minimize.predictor`)
BARRIER_PATH = ("min_step", "grow", "max_rotation_step", "time_limit", "predictor")


def barrier_specs():
    """``{name: (Spec, default)}`` of every option of
    ``Rod.solve(method="barrier")``: :data:`BARRIER_PATH`, then
    :class:`EnergyOptions`, then :class:`BarrierOptions`."""
    path = {n: option_specs()[n] for n in BARRIER_PATH}
    path["predictor"] = (path["predictor"][0], "secant")
    return {**path, **option_specs(EnergyOptions), **option_specs(BarrierOptions)}


def split_barrier_options(kwargs):
    """The options of ``Rod.solve(method="barrier", **kwargs)``, checked
    and split: ``(SolverOptions of the path, EnergyOptions,
    BarrierOptions)``.  An unknown name is an error listing the allowed
    ones."""
    specs = barrier_specs()
    unknown = sorted(set(kwargs) - set(specs))
    if unknown:
        close = difflib.get_close_matches(unknown[0], list(specs), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ValueError(f"unknown option(s) {', '.join(map(repr, unknown))} of "
                         f"method='barrier'{hint}; allowed: {', '.join(specs)}")

    def part(names):
        return {k: kwargs.get(k, specs[k][1]) for k in names}
    return (make_options(part(BARRIER_PATH)),
            EnergyOptions(**part(f.name for f in fields(EnergyOptions))),
            BarrierOptions(**part(f.name for f in fields(BarrierOptions))))


class Deadline:
    """The wall clock of ``SolverOptions.time_limit`` from the start of a
    solve: :meth:`passed` is checked by the solver loops before each step."""

    def __init__(self, time_limit):
        self.limit = float(time_limit)
        self.end = time.monotonic() + self.limit if self.limit > 0 else np.inf

    def passed(self):
        """True once the time limit has run out (never without one)."""
        return time.monotonic() > self.end

    def reason(self):
        return f"the time limit ran out (time_limit={self.limit:g} s)"


def option_specs(cls=None):
    """``{name: (Spec, default)}`` of the fields of ``cls`` (default
    :class:`SolverOptions`; :class:`EnergyOptions`, :class:`BarrierOptions`):
    what the scene format and the docs tables are built from."""
    cls = SolverOptions if cls is None else cls
    return {f.name: (f.metadata["spec"], f.default) for f in fields(cls)}


def make_options(kwargs):
    """:class:`SolverOptions` from keyword arguments; an unknown name is an
    error with the closest allowed one."""
    names = [f.name for f in fields(SolverOptions)]
    for k in kwargs:
        if k not in names:
            close = difflib.get_close_matches(k, names, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise ValueError(f"unknown solver option {k!r}{hint} Allowed: {', '.join(names)}")
    return SolverOptions(**kwargs)
