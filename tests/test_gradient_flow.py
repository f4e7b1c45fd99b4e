"""The gradient flow's Levenberg-Marquardt steps (skfem_rod/relax.py,
``GradientFlow.linearized``): each taken step lowers the true energy, the
end is Newton's equilibrium reached with Newton's quadratic convergence,
and the prescribed increment is applied on the way."""
import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry, relax
from skfem_rod.options import make_options
from skfem_rod.problem import Increment, Problem, State

EI = np.pi * 0.01 ** 4 / 4 * 1e7


def released_arc(force):
    """A naturally straight cantilever started as a half circle (a stressed
    start far from its equilibrium), a dead force at the free end: a
    conservative problem whose energy is the strain energy less the dead
    load's work."""
    rod = Rod(geometry.arc(1.0 / np.pi, np.pi), Section.circle(E=1e7, nu=0.3, radius=0.01), 8,
              natural="straight")
    rod.clamp("start").add_force("end", force)
    return rod


def energy(problem, rod, r, R, force):
    ev = problem.evaluate(r, R, 1.0, tangent=False)
    return ev.internal.energy - float(np.dot(force, r[rod.node("end")]))


def recorded_flow(monkeypatch, rod, opts, prescribed=None):
    """Run ``linearized`` from the rod's start at load factor 1, recording
    the state every step starts from (a refused step starts the next try
    from the same state)."""
    problem = Problem(rod)
    flow = relax.GradientFlow(problem)
    starts = []
    plain = relax.safeguarded_update

    def record(problem_, at, inc, *args, **kw):
        starts.append((at.r.copy(), at.R.copy()))
        return plain(problem_, at, inc, *args, **kw)
    monkeypatch.setattr(relax, "safeguarded_update", record)
    out = flow.linearized(rod.r0.copy(), rod.R0.copy(), 1.0, opts, prescribed=prescribed)
    return problem, out, starts


def test_every_step_lowers_the_true_energy(monkeypatch):
    """From a half circle released under a dead end force the steps lower
    the energy (strain energy less the load's work, computed here, not the
    trapezoid estimate the steps are judged by) at every taken step, some
    steps are refused on the way, and the end is an equilibrium to rtol."""
    force = np.array([0.0, -0.5 * EI, 0.0])
    rod = released_arc(force)
    opts = make_options({})
    problem, (r, R, lam, rep), starts = recorded_flow(monkeypatch, rod, opts)
    assert rep.converged, rep.reason
    E = np.array([energy(problem, rod, *s, force) for s in starts]
                 + [energy(problem, rod, r, R, force)])
    taken = np.diff(E)
    assert np.all(taken <= 1e-12 * np.abs(E).max()), taken.max()
    assert np.sum(taken < 0) == rep.flow_steps >= 5
    assert len(starts) > rep.flow_steps          # refused steps were retried
    # converged to rtol, or to the residual's round-off floor (the package's
    # acceptance, Problem.at_floor: the bent start's internal forces are
    # large)
    ev = problem.evaluate(r, R, 1.0)
    assert problem.residual_norm(ev) <= max(opts.rtol, rep.floor or 0.0) \
        * problem.force_scale(ev)


def test_the_end_is_newtons_equilibrium_with_quadratic_convergence(monkeypatch):
    """Where plain Newton converges too (a moderate dead load on a straight
    cantilever), the steps end in the same equilibrium (to 1e-10 of the
    length), and the last residuals fall quadratically, with the viscosity driven
    to zero by the good model and the falling residual."""
    from skfem_rod.newton import newton
    force = np.array([0.0, 2.0, 0.5])
    rod = (Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 8)
           .clamp("start").add_force("end", force))
    opts = make_options({})
    problem, (r, R, lam, rep), _ = recorded_flow(monkeypatch, rod, opts)
    assert rep.converged, rep.reason
    r_n, R_n, _, rep_n = newton(Problem(rod), rod.r0.copy(), rod.R0.copy(), 1.0, opts)
    assert rep_n.converged
    assert np.abs(r - r_n).max() < 1e-10
    assert np.abs(R - R_n).max() < 1e-9
    h = np.array(rep.history)
    scale = problem.force_scale(rep.evaluation)
    # the order of convergence over the last three residuals between 1e-1
    # and 1e-8 of the force scale (below, round-off takes over): 2 for
    # Newton's, 1 where a viscosity that stays would slow it
    tail = h[(h < 1e-1 * scale) & (h > 1e-8 * scale)][-3:]
    assert tail.size == 3, h
    order = np.log(tail[2] / tail[1]) / np.log(tail[1] / tail[0])
    assert order > 1.8, (order, h)


def test_the_prescribed_increment_is_applied(monkeypatch):
    """A prescribed end rotation (a quarter turn, as a load step with the
    default ``max_rotation_step`` may carry) is carried by the first steps
    and applied in full at convergence."""
    rod = (Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 8)
           .clamp("start").prescribe_rotation("end", [0.0, 0.0, 0.5 * np.pi]))
    problem = Problem(rod)
    flow = relax.GradientFlow(problem)
    opts = make_options({})
    presc = problem.prescribed(1.0)
    r, R, lam, rep = flow.linearized(rod.r0.copy(), rod.R0.copy(), 1.0, opts, prescribed=presc)
    assert rep.converged, rep.reason
    # the end's rotation is the prescribed pi / 2 about z: the rod bent into a
    # quarter circle of radius L / (pi / 2) (to the P3 mesh's error)
    end = rod.node("end")
    Q = R[end] @ rod.R0[end].T
    assert np.abs(Q - [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]).max() < 1e-12
    rho = 1.0 / (0.5 * np.pi)
    assert r[end] == pytest.approx([rho, rho, 0.0], abs=1e-6)


@pytest.mark.parametrize("contact, how, expected", [
    (True, "auto", ["linearized"]), (False, "auto", ["proximal"]),
    (False, "linearized", ["linearized"]), (True, "proximal", ["proximal"]),
    (True, "linearized", ["linearized", "proximal"])])
def test_the_option_picks_the_steps(monkeypatch, contact, how, expected):
    """``flow_steps``: "auto" takes the Levenberg-Marquardt steps with contact
    on and proximal steps without; where the former find no descent the
    latter take over from the flow's start."""
    from skfem_rod.problem import Report
    calls = []

    def fake(name, ok):
        def run(self, r, R, lam, opts, prescribed=None, descent=False):
            calls.append(name)
            return r, R, lam, Report(ok, reason="" if ok else "no descent (test)")
        return run
    # the linearized steps fail in the last case only
    monkeypatch.setattr(relax.GradientFlow, "linearized",
                        fake("linearized", expected == ["linearized"]))
    monkeypatch.setattr(relax.GradientFlow, "proximal", fake("proximal", True))
    rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
    rod.clamp("start")
    if contact:
        rod.enable_contact(radius=0.01)
    flow = relax.GradientFlow(Problem(rod))
    out = flow(rod.r0, rod.R0, 1.0, make_options({"flow_steps": how}))
    assert calls == expected and out[3].converged


def stall_trace(n, fall, residual):
    """Per-iteration cumulative energy falls and least residual norms so
    far of a flow that fell by ``fall(k)`` at iteration ``k`` with residual
    ``residual(k)``."""
    drops = np.cumsum([-fall(k) for k in range(n)])
    return list(drops), list(np.minimum.accumulate([residual(k) for k in range(n)]))


def test_a_flow_stuck_at_a_jump_of_the_residual_is_stalled():
    """The trace measured in the plectoneme's step from 2.3125 turns: after
    200 iterations that lowered the energy by 0.1 in all, every other trial
    refused (no fall) and every other taken with a fall of 1e-19 at the
    same residual 3.829e-3: stalled once a whole window has gone by so."""
    n = 200 + relax.STALL_WINDOW + 1
    drops, least = stall_trace(
        n, lambda k: 5e-4 if k < 200 else (1e-19 if k % 2 else 0.0),
        lambda k: 1.0 / (1 + k) if k < 200 else 3.829e-3)
    assert not relax.stalled(drops[:-2], least[:-2])
    assert relax.stalled(drops, least)


@pytest.mark.parametrize("case", ["crawl", "residual falls", "short"])
def test_a_flow_that_progresses_is_not_stalled(case):
    """A flow crawling down a corrugated valley (the knot's and the
    plectoneme's: the energy falling 1e-5 per step out of a fall of order
    1, the residual hovering at 0.1-6), one whose energy no longer falls
    visibly but whose residual reaches a new least (Newton's end), and one
    shorter than the window are not stalled."""
    rng = np.random.default_rng(7)
    n = 3 * relax.STALL_WINDOW
    if case == "crawl":
        drops, least = stall_trace(n, lambda k: 1e-5 * (k % 3 != 0),
                                     lambda k: 0.1 + 6 * rng.random())
        drops = [d - 1.0 for d in drops]           # the fall before the crawl
    elif case == "residual falls":
        drops, least = stall_trace(n, lambda k: 1e-3 if k < 10 else 0.0,
                                     lambda k: 10.0 ** (-k / 10))
    else:
        drops, least = stall_trace(relax.STALL_WINDOW, lambda k: 0.0, lambda k: 1.0)
    assert not relax.stalled(drops, least)


def test_a_frictional_flow_sliding_at_its_least_residual_is_stalled():
    """The trace measured in the knot's frictional cycle (gamma_T = 0.2,
    crossing pairs on the smooth curve, tied with them): 250 iterations
    lowering the residual to 2.227e-5 and the estimate by 3.3e-6, then
    7e-11 per iteration at residuals above that least (a sliding mode:
    the slipping points' fixed-size forces do work without end).  The
    energy rule never ends it; with friction it has stalled once
    FRICTION_STALL_WINDOW iterations found no lower residual, and not
    before.  A frictional flow that reaches a new least residual now and
    then (every 400 iterations) is not stalled."""
    rng = np.random.default_rng(3)
    w = relax.FRICTION_STALL_WINDOW
    n = 250 + w + 1
    drops, least = stall_trace(
        n, lambda k: 3.3e-6 / 250 if k < 250 else 7e-11,
        lambda k: 2.227e-5 * 10.0 ** ((249 - k) / 50) if k < 250
        else 2.227e-5 * (1.01 + rng.random()))
    assert not relax.stalled(drops, least)                    # the energy rule
    assert not relax.stalled(drops[:-2], least[:-2], friction=True)
    assert relax.stalled(drops, least, friction=True)
    drops, least = stall_trace(4 * w, lambda k: 1e-6,
                               lambda k: 1.0 / (1 + k // 400) + rng.random() * 1e-3)
    assert not relax.stalled(drops, least, friction=True)


def test_a_frictional_flow_that_slides_fails_without_proximal_steps(monkeypatch):
    """With friction a stalled flow is a sliding mode at the held friction
    multipliers, along which the proximal steps crawl on as well (measured
    in the knot, above): the flow fails at once, so that the step is cut.
    Routing only (monkeypatched flows)."""
    from skfem_rod.problem import Report
    rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
    rod.clamp("start").enable_contact(radius=0.01, gamma_T=0.2)
    flow = relax.GradientFlow(Problem(rod))
    calls = []

    def proximal(self, r, R, lam, opts, prescribed=None, descent=False):
        calls.append("proximal")
        return r, R, lam, Report(True)

    def linearized(self, r, R, lam, opts, prescribed=None):
        self.stalled = True
        return r + 0.01, R, lam, Report(False, reason="stalled (test)")
    monkeypatch.setattr(relax.GradientFlow, "proximal", proximal)
    monkeypatch.setattr(relax.GradientFlow, "linearized", linearized)
    out = flow(rod.r0, rod.R0, 1.0, make_options({}))
    assert not out[3].converged and calls == []
    assert np.array_equal(out[0], rod.r0)                   # the start, as a failed solve


def test_a_stalled_flow_is_taken_on_from_its_own_state(monkeypatch):
    """Where the Levenberg-Marquardt steps stall, the proximal steps start
    from the flow's state (lower, its prescribed increment applied), with
    no increment left; where they found no descent, from the start again
    with the increment."""
    from skfem_rod.problem import Report
    rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
    rod.clamp("start").enable_contact(radius=0.01)
    flow = relax.GradientFlow(Problem(rod))
    moved = rod.r0 + 0.01
    presc = np.ones(rod.r0.size)
    calls = []

    def proximal(self, r, R, lam, opts, prescribed=None, descent=False):
        calls.append((r.copy(), prescribed))
        return r, R, lam, Report(True)
    monkeypatch.setattr(relax.GradientFlow, "proximal", proximal)
    for stall in (True, False):
        def linearized(self, r, R, lam, opts, prescribed=None, stall=stall):
            self.stalled = stall
            return moved, R, lam, Report(False, reason="test")
        monkeypatch.setattr(relax.GradientFlow, "linearized", linearized)
        flow(rod.r0, rod.R0, 1.0, make_options({}), prescribed=presc)
    (r_stall, p_stall), (r_fail, p_fail) = calls
    assert np.array_equal(r_stall, moved) and p_stall is None
    assert np.array_equal(r_fail, rod.r0) and p_fail is presc


def _crawling_flow(monkeypatch, max_flow_steps):
    """The released arc's flow with every Newton update scaled to 1e-16 of
    itself: each taken step moves the state by round-off (as where a
    crossing pair comes and goes with moves of 1e-18), the energy's
    estimated fall of each step is 1e-16 of a real one's, so over any
    window it is the same share of the flow's whole fall."""
    force = np.array([0.0, -0.5 * EI, 0.0])
    rod = released_arc(force)
    problem = Problem(rod)
    flow = relax.GradientFlow(problem)
    factor = problem.factor

    def crawl(K, fixed=None):
        solve = factor(K, fixed)
        return lambda rhs: 1e-16 * solve(rhs)
    monkeypatch.setattr(problem, "factor", crawl)
    opts = make_options({"max_flow_steps": max_flow_steps})
    return flow, flow.linearized(rod.r0.copy(), rod.R0.copy(), 1.0, opts)


def test_a_flow_whose_steps_move_by_round_off_has_stalled(monkeypatch):
    """Its last STALL_WINDOW steps each moved the state by at most
    STILL_MOVE: stalled (the proximal steps take over from its state),
    where the energy rule (its fall the same share in every window) never
    ends it: with STILL_MOVE = 0 it runs to max_flow_steps."""
    flow, (r, R, lam, rep) = _crawling_flow(monkeypatch, 400)
    assert not rep.converged and flow.stalled
    assert "moved the state by at most" in rep.reason
    assert rep.flow_steps == relax.STALL_WINDOW
    monkeypatch.setattr(relax, "STILL_MOVE", 0.0)
    flow, (r, R, lam, rep) = _crawling_flow(monkeypatch, 400)
    assert not rep.converged and not flow.stalled
    assert rep.flow_steps == 400 and "400 steps" in rep.reason


def _pressed_hairpin_flow(monkeypatch):
    """The Levenberg-Marquardt flow of a hairpin whose free leg a dead end
    force presses onto the clamped one (contact with crossing pairs),
    recording for every trial the state it starts from and the contact
    search's memory before and after it."""
    from test_contact import SEC, hairpin
    eps = 0.02
    rod = Rod(hairpin(eps, 0.2, leg=1.0), SEC, 16)
    rod.clamp("start").add_force("end", [0.0, -5.0, 0.0]).enable_contact(radius=eps,
                                                                          crossing=True)
    problem = Problem(rod)
    flow = relax.GradientFlow(problem)
    plain = relax.safeguarded_update
    trials = []

    def record(problem_, at, inc, *args, **kw):
        before = problem_.search_memory()
        out = plain(problem_, at, inc, *args, **kw)
        trials.append((at.r.copy(), before, problem_.search_memory()))
        return out
    monkeypatch.setattr(relax, "safeguarded_update", record)
    out = flow.linearized(rod.r0.copy(), rod.R0.copy(), 1.0, make_options({}))
    return problem, out, trials


def _same_memory(a, b):
    places = (a.crossing_places is None and b.crossing_places is None) or (
        a.crossing_places is not None and b.crossing_places is not None
        and np.array_equal(a.crossing_places, b.crossing_places))
    return np.array_equal(a.last_master, b.last_master) and places


def test_a_refused_step_leaves_the_search_memory_as_the_state_left_it(monkeypatch):
    """The contact search remembers each slave's master element and the
    held crossing pairs' places from one evaluation to the next.  A refused
    step's trial changes that memory; the next try from the same state must
    start from the state's memory again, or the residual at the state is
    the refused trial's search's (the plectoneme's flow refused 20 steps at
    a residual of 50.4 that was 14.6 a move of 1e-15 away).  Negative
    control: without the restore, tries start from the refused trials'
    memory."""
    problem, (r, R, lam, rep), trials = _pressed_hairpin_flow(monkeypatch)
    assert rep.converged, rep.reason
    retries = [i for i in range(1, len(trials)) if np.array_equal(trials[i][0], trials[i - 1][0])]
    changed = [i for i in retries if not _same_memory(trials[i - 1][1], trials[i - 1][2])]
    assert changed, "no refused trial changed the memory: the test would not see the restore"
    assert all(_same_memory(trials[i][1], trials[i - 1][1]) for i in retries)

    monkeypatch.setattr(Problem, "restore_search", lambda self, memory: None)
    problem, (r, R, lam, rep), trials = _pressed_hairpin_flow(monkeypatch)
    retries = [i for i in range(1, len(trials)) if np.array_equal(trials[i][0], trials[i - 1][0])]
    assert not all(_same_memory(trials[i][1], trials[i - 1][1]) for i in retries)


def _refused_back_to_the_start(problem, r, R, start, line_search):
    """From the pressed state ``(r, R)`` (in contact) back towards the open
    ``start``: the memory at the state, and the update of ``line_search``
    ``(problem, at, inc, opts) -> (trial, alpha, why)`` with trials at 1
    and 1/2, both refused."""
    problem.evaluate(r, R, 1.0)
    memory = problem.search_memory()
    inc = np.zeros(problem.mesh.n_dofs)
    inc.reshape(-1, 6)[:, :3] = start - r
    inc = problem.to_basis(inc)
    evaluations = problem.calls["evaluate"]
    opts = make_options({"max_backtracks": 1, "clearance_cap": False,
                         "position_correction": False})
    out, alpha, why = line_search(problem, State(r, R, 1.0), inc, opts)
    assert out is None and problem.calls["evaluate"] == evaluations + 2
    return memory, inc


def _plain(problem, at, inc, opts):
    from skfem_rod.newton import safeguarded_update
    return safeguarded_update(problem, at, Increment(inc, 0.0), opts, -1.0, 1.0)


def _generalized(problem, at, inc, opts):
    from skfem_rod import nonsmooth
    dl = np.zeros_like(nonsmooth.unknowns(problem))
    never = nonsmooth.Merit(last=1.0, reference=-1.0, scale=1.0, weight=1.0, first=False)
    return nonsmooth.line_search(problem, at, Increment(inc, dl), never, opts)


@pytest.mark.parametrize("line_search", [_plain, _generalized], ids=["newton", "nonsmooth"])
def test_a_line_search_that_takes_no_trial_leaves_the_search_memory(monkeypatch, line_search):
    """Every trial of one update is evaluated from the memory at its start,
    and where none is taken (every residual above the bound, or no merit
    below the reference) the memory is as it was; evaluated directly, the
    last trial changes it.  Plain Newton's safeguard
    (``newton.safeguarded_update``) and the generalized Newton's merit line
    search (``nonsmooth.line_search``)."""
    problem, (r, R, lam, rep), trials = _pressed_hairpin_flow(monkeypatch)
    memory, inc = _refused_back_to_the_start(problem, r, R, trials[0][0], line_search)
    assert _same_memory(problem.search_memory(), memory)
    problem.evaluate(*problem.update(r, R, inc, 0.5), 1.0)
    assert not _same_memory(problem.search_memory(), memory)
