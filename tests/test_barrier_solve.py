"""``Rod.solve(method="barrier")``: the node-barrier solve of
:mod:`skfem_rod.minimize` behind the rod's own solve -- the same states as
its steps taken by hand, a Result whose reactions balance the loads, whose
contact pairs obey Coulomb's law and dissipate, the load path's step
cutting, elastic reversibility, and bad input refused by name."""
import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.contact.friction import SLIP
from skfem_rod.minimize import BarrierResolution, EnergySolve, StepReport, default_force

from test_minimize import _hairpin, _steps

LOAD = np.array([0.02, -0.05, 0.0])

# the hairpin's 24 elements are coarse for the barrier (its nodes' offset
# 0.045 eps, tested below): what is tested here holds all the same
pytestmark = pytest.mark.filterwarnings("ignore::skfem_rod.minimize.BarrierResolution")


def _pressed(gamma_T):
    """The pressed hairpin of tests/test_minimize.py with the rod's own
    contact switched on (radius, exclusion, gamma_T): what method="barrier"
    reads."""
    rod, eps, barrier = _hairpin()
    rod.point_loads.clear()
    rod.add_force("end", LOAD)
    rod.enable_contact(radius=eps, gamma_T=gamma_T)
    return rod, eps, barrier


@pytest.mark.parametrize("gamma_T", [0.0, 0.3])
def test_the_solve_is_its_steps_and_its_result_balances(gamma_T):
    rod, eps, barrier = _pressed(gamma_T)
    result = rod.solve(4, method="barrier", barrier_force=1.0)
    assert result.converged, result.message
    assert np.allclose(result.load_factors, [0, 0.25, 0.5, 0.75, 1.0])
    # the same steps taken by hand with EnergySolve (same barrier, predictor)
    rod.contact, contact = None, rod.contact
    r, R, reps = _steps(EnergySolve(rod, barrier, eps, mu=gamma_T), 4, settle=True)
    rod.contact = contact
    assert np.abs(result.steps[-1].r - r).max() <= 1e-12 * rod.length
    assert [st.iterations for st in result.steps[1:]] == [q.iterations for q in reps]
    for k, st in enumerate(result.steps[1:], start=1):
        lam = st.load_factor
        # the clamp takes up the load: the barrier's and the friction's
        # forces are internal (pairwise opposite), so they cancel
        # up to what the free dofs' residual leaves: their sum is at most
        # sqrt(n) times its norm (Cauchy-Schwarz), its moments |x| times that
        f, m = result.reaction("start", k)
        left = np.sqrt(st.r.shape[0]) * st.residual_history[-1]
        assert 0 < left <= 1e-8 * 2 * np.linalg.norm(LOAD) * np.sqrt(st.r.shape[0])
        assert np.linalg.norm(f + lam * LOAD) <= left
        end = rod.node("end")
        # moments about the clamp: the load's at the end (with friction too:
        # a pair's two forces act at one point, no couple)
        arm = st.r[end] - st.r[rod.node("start")]
        reach = np.linalg.norm(st.r - st.r[rod.node("start")], axis=1).max() + 1.0
        assert np.linalg.norm(m + np.cross(arm, lam * LOAD)) <= reach * left
        c = st.contact
        assert c.s.size > 0 and np.all(c.force > 0) and np.all(c.weight == 1)
        assert c.penetration == 0.0 and c.min_distance >= 2 * eps * (1 - 1e-3)
        assert np.all(c.gap <= 0)                      # stands off in the barrier's width
        if gamma_T == 0:
            assert not c.friction
            continue
        # Coulomb at the state's own normal forces, in the tangent plane
        ft = np.linalg.norm(c.force_T, axis=1)
        assert np.all(ft <= gamma_T * c.force * (1 + 1e-12))
        assert np.abs(np.einsum("ka,ka->k", c.force_T, c.normal)).max() <= 1e-12 * ft.max()
        assert ft.max() > 0 and c.dissipation > 0
        # the friction opposes the slip: on the master along it
        slipping = np.linalg.norm(c.slip_T, axis=1) > 0
        assert np.all(np.einsum("ka,ka->k", c.force_T, c.slip_T)[slipping] > 0)
    if gamma_T > 0:
        assert not result.log
    else:
        # pressed in its plane, the free arm would roll off sideways: every
        # loaded state is a saddle held by the symmetry, and said to be
        assert [line.split(":")[0] for line in result.log] == \
            [f"step to lam={lam:g}" for lam in (0.25, 0.5, 0.75, 1.0)]
        assert all("saddle" in line for line in result.log)


def test_a_saddle_is_told_by_the_hessians_eigenvalues():
    """The inertia the solve reads off its LU's pivots is the Hessian's:
    the frictionless pressed hairpin's last state has exactly as many
    negative eigenvalues (dense, independent) as the log says (1)."""
    rod, eps, barrier = _pressed(0.0)
    rod.contact = None
    solve = EnergySolve(rod, barrier, eps)
    r, R, reps = _steps(solve, 2, settle=True)
    K = solve.tangent(r, R, 1.0)
    w = np.linalg.eigvalsh(K[solve.free][:, solve.free].toarray())
    assert reps[-1].negative == int(np.sum(w < 0)) == 1
    assert w[0] < -1e-4 * abs(w[1])            # clearly negative, not round-off
    # the reference pressed by nothing: a minimum
    r0, R0, rep0 = solve.step(rod.r0, rod.R0, 0.0, 0.0)
    assert rep0.negative == 0


def test_load_and_unload_returns_to_the_reference_without_friction():
    rod, eps, _ = _pressed(0.0)
    result = rod.solve(4, path=[0, 1, 0], method="barrier", barrier_force=1.0)
    assert result.converged, result.message
    assert result.steps[4].contact.s.size > 0
    # back at step 0's equilibrium (not the reference: the arms start
    # inside the barrier's width)
    assert np.abs(result.steps[-1].r - result.steps[0].r).max() <= 1e-8 * rod.length
    assert result.steps[-1].contact.s.size == result.steps[0].contact.s.size


def test_a_failed_step_is_cut_by_the_load_path(monkeypatch):
    """A step that fails is cut in half by the load path
    (solver.follow_path), grows back after two successes, and with
    min_step above the cut it stops saying where and why.  The two steps
    after a failed one (and only they) may take pseudo-time steps through
    a slip (``slip="damped"``); elsewhere a step that finds no static path
    fails at once, to be cut (``"cut"``)."""
    rod, eps, _ = _pressed(0.0)
    calls = []
    step = EnergySolve.step

    def capped(self, r, R, lam, dlam, previous=None, sigma=0.0, ratio=1.0, slip="damped",
               rate=None, stable=False, friction=None):
        calls.append((round(lam, 12), round(dlam, 12), previous is not None, slip))
        if dlam > 0.3:
            return r, R, StepReport(converged=False, reason="too long a step")
        return step(self, r, R, lam, dlam, previous, sigma, ratio, slip, rate, stable, friction)

    monkeypatch.setattr(EnergySolve, "step", capped)
    result = rod.solve(2, method="barrier", barrier_force=1.0)
    assert result.converged, result.message
    assert np.allclose(result.load_factors, [0, 0.25, 0.5, 0.75, 1.0])
    assert calls == [(0.0, 0.0, False, "damped"), (0.0, 0.5, False, "cut"),
                     (0.0, 0.25, False, "damped"), (0.25, 0.25, True, "damped"),
                     (0.5, 0.5, True, "cut"), (0.5, 0.25, True, "damped"),
                     (0.75, 0.25, True, "damped")]
    assert sum("too long a step" in line for line in result.log) == 2
    monkeypatch.setattr(EnergySolve, "step", step)
    four = rod.solve(4, method="barrier", barrier_force=1.0)
    assert np.abs(four.steps[-1].r - result.steps[-1].r).max() <= 1e-7 * rod.length
    monkeypatch.setattr(EnergySolve, "step", capped)
    stopped = rod.solve(2, method="barrier", barrier_force=1.0, min_step=0.3)
    assert not stopped.converged and len(stopped.steps) == 1
    assert "load factor 0" in stopped.message and "too long a step" in stopped.message


def test_a_solve_restarted_from_its_result_carries_the_friction():
    """A frictional barrier solve restarted from its Result (``start=``,
    the loads held as preloads) carries the friction of the last step
    (the lag it was solved with, kept in its ContactState): step 0 takes no
    iteration and leaves the state as it is, and the next step ends where
    the solve taken in one go does, to round-off.  Restarted from the bare
    state ``(r, R)`` the friction starts from zero: step 0 moves the arm by
    more than the slip smoothing while the stuck pairs build their forces
    up, and the end differs."""
    from dataclasses import replace

    from skfem_rod.minimize import BarrierStepper
    from skfem_rod.options import split_barrier_options

    from test_minimize import _hairpin

    rod, eps, _ = _pressed(0.3)
    whole = rod.solve(2, method="barrier", barrier_force=1.0)
    first = rod.solve(1, path=[0, 0.5], method="barrier", barrier_force=1.0)
    assert whole.converged and first.converged
    assert np.array_equal(first.steps[-1].r, whole.steps[1].r)

    def held():
        """The hairpin with the first half of the load held (constant) and
        the second half growing with the load factor."""
        again, _, _ = _hairpin()
        again.point_loads.clear()
        again.add_force("end", 0.5 * LOAD, constant=True)
        again.add_force("end", 0.5 * LOAD)
        again.enable_contact(radius=eps, gamma_T=0.3)
        return again

    rest = held().solve(1, method="barrier", barrier_force=1.0, start=first)
    assert rest.converged, rest.message
    assert rest.steps[0].iterations == 0
    assert np.array_equal(rest.steps[0].r, first.steps[-1].r)
    assert np.abs(rest.steps[-1].r - whole.steps[-1].r).max() <= 1e-10 * rod.length

    bare = held().solve(1, method="barrier", barrier_force=1.0,
                        start=(first.steps[-1].r, first.steps[-1].R))
    assert bare.converged and bare.steps[0].iterations > 0
    assert np.abs(bare.steps[0].r - first.steps[-1].r).max() > 1e-3 * eps   # eps_v
    assert np.abs(bare.steps[-1].r - whole.steps[-1].r).max() > 1e-7 * rod.length

    # a record without the lag (e.g. the augmented Lagrangian's slave
    # points) or of another rod's pairs carries nothing
    S = BarrierStepper(held(), *split_barrier_options(dict(barrier_force=1.0)))
    c = first.steps[-1].contact
    assert S.recorded_friction(c) is c.lag and c.lag.pairs.size > 0
    assert S.recorded_friction(replace(c, lag=None)) is None
    far = replace(c.lag, pairs=c.lag.pairs + first.steps[-1].r.shape[0])
    assert S.recorded_friction(replace(c, lag=far)) is None


def test_rotational_friction_resists_the_pivot_and_obeys_coulomb_for_couples():
    """The pressed hairpin pulled along and out of its plane, with the
    rotational law on (``rotational_slip="pivot"``: the relative spin of
    the sections about each pair's normal): at every step each pair's
    couple is about its normal, within gamma_R times its normal force and
    at it where the pair pivots; the couples dissipate; the pairs' forces
    and couples are internal (the clamp takes up the load); the arm bends
    less out of its plane than with the tangential law alone; restarted
    from its Result the solve ends where one taken in one go does (the
    pivots carried).  Any other rotational law is refused by name."""
    from test_minimize import _hairpin

    load = np.array([0.02, -0.05, 0.02])

    def build(gamma_R, held=None):
        rod, eps, _ = _hairpin()
        rod.point_loads.clear()
        if held is None:
            rod.add_force("end", load)
        else:                                  # that much held, the rest growing
            rod.add_force("end", held * load, constant=True)
            rod.add_force("end", (1 - held) * load)
        rod.enable_contact(radius=eps, gamma_T=0.3, gamma_R=gamma_R, rotational_slip="pivot")
        return rod

    gamma_R = 0.05
    rod = build(gamma_R)
    result = rod.solve(2, method="barrier", barrier_force=1.0)
    plain = build(0.0).solve(2, method="barrier", barrier_force=1.0)
    assert result.converged and plain.converged
    end, clamp = rod.node("end"), rod.node("start")
    pivoting = 0
    for k, st in enumerate(result.steps[1:], start=1):
        c = st.contact
        size = np.linalg.norm(c.force_R, axis=1)
        bound = gamma_R * c.force
        assert np.all(size <= bound * (1 + 1e-12))
        assert np.allclose(np.abs(np.einsum("ka,ka->k", c.force_R, c.normal)), size,
                           rtol=1e-12, atol=1e-15)
        at_bound = c.state_R == SLIP
        assert np.allclose(size[at_bound], bound[at_bound], rtol=1e-12)
        pivoting += int(at_bound.sum())
        assert np.all(np.einsum("ka,ka->k", c.force_R, c.slip_R) >= 0)
        assert c.dissipation > plain.steps[k].contact.dissipation
        # internal: the clamp's reaction balances the load, force and moment
        f, m = result.reaction("start", k)
        left = np.sqrt(st.r.shape[0]) * st.residual_history[-1]
        lam = st.load_factor
        assert np.linalg.norm(f + lam * load) <= left
        arm = st.r[end] - st.r[clamp]
        reach = np.linalg.norm(st.r - st.r[clamp], axis=1).max() + 1.0
        assert np.linalg.norm(m + np.cross(arm, lam * load)) <= reach * left
    assert pivoting > 0
    # the pivots resisted: the free arm bends out of its plane less
    lift = result.steps[-1].r[end, 2] - result.steps[0].r[end, 2]
    assert 0 < lift < plain.steps[-1].r[end, 2] - plain.steps[0].r[end, 2] - 1e-3
    # restarted from half the load with its pivots and slips carried
    first = build(gamma_R).solve(1, path=[0, 0.5], method="barrier", barrier_force=1.0)
    assert np.array_equal(first.steps[-1].r, result.steps[1].r)
    rest = build(gamma_R, held=0.5).solve(1, method="barrier", barrier_force=1.0, start=first)
    assert rest.converged and rest.steps[0].iterations == 0
    assert np.abs(rest.steps[-1].r - result.steps[-1].r).max() <= 1e-10 * rod.length
    # the barrier has the pivot law only
    other, _, _ = _hairpin()
    other.enable_contact(radius=0.05, gamma_T=0.3, gamma_R=gamma_R)     # "twist"
    with pytest.raises(ValueError, match="rotational_slip"):
        other.solve(1, method="barrier", barrier_force=1.0)


def test_an_unloaded_closed_ring_stays_put():
    """The ring's barrier is periodic by itself (no pair across the closure)."""
    rod = Rod(geometry.ring(1.0), Section.circle(E=1e4, nu=0.3, radius=0.02), 40)
    rod.clamp("start").enable_contact(gamma_T=0.3)
    result = rod.solve(2, method="barrier")
    assert result.converged, result.message
    assert all(st.contact.s.size == 0 for st in result.steps)
    assert np.abs(result.steps[-1].r - rod.r0).max() < 1e-12


def test_the_default_force_is_the_loads_or_the_bending_scale():
    rod, eps, _ = _pressed(0.0)
    from skfem_rod.problem import Problem
    rod.contact = None
    EI = rod.section.EI1
    assert default_force(Problem(rod)) == pytest.approx(max(np.linalg.norm(LOAD),
                                                            EI / rod.length ** 2))
    rod.point_loads.clear()
    assert default_force(Problem(rod)) == pytest.approx(EI / rod.length ** 2)
    rod.add_force("end", 1e3 * LOAD)
    assert default_force(Problem(rod)) == pytest.approx(1e3 * np.linalg.norm(LOAD))


def test_bad_input_is_refused_with_the_parameter_named():
    rod, eps, _ = _pressed(0.3)
    with pytest.raises(ValueError, match="'penalty_growth'.*allowed: min_step"):
        rod.solve(2, method="barrier", penalty_growth=2.0)
    for name, value in (("barrier_width", -1.0), ("barrier_force", 0.0),
                        ("slip_smoothing", np.nan), ("barrier_width", "wide")):
        with pytest.raises(ValueError, match=name):
            rod.solve(2, method="barrier", **{name: value})
    with pytest.raises(ValueError, match="rtol"):
        rod.solve(2, method="barrier", rtol=-1.0)
    with pytest.raises(ValueError, match="predictor"):
        rod.solve(2, method="barrier", predictor="cubic")
    with pytest.raises(ValueError, match="method must be"):
        rod.solve(2, method="barier")
    rod.enable_contact(radius=eps, gamma_T=0.3, gamma_R=0.01)
    with pytest.raises(ValueError, match="gamma_R"):
        rod.solve(2, method="barrier")
    rod.enable_contact(radius=eps)
    rod.add_force("end", [0.0, 0.0, 1.0], follower=True)
    with pytest.raises(ValueError, match="follower"):
        rod.solve(2, method="barrier")
    rod.point_loads.pop()
    rod.contact = None
    with pytest.raises(ValueError, match="enable_contact"):
        rod.solve(2, method="barrier")


def test_backward_error_tells_a_solution_from_a_wrong_one():
    from scipy.sparse import random as sprandom
    import scipy.sparse as sp
    from skfem_rod.minimize import backward_error
    rng = np.random.default_rng(7)
    A = (sprandom(200, 200, density=0.05, random_state=rng) + 10 * sp.eye(200)).tocsc()
    x = rng.standard_normal(200)
    b = A @ x
    assert backward_error(A, x, b) <= 1e-15
    assert backward_error(A, x * (1 + 1e-6), b) >= 1e-8


def test_the_plectoneme_demo_snaps_into_a_loop_and_keeps_its_link(tmp_path):
    """demos/plectoneme.py at its small size (40 elements, 1.5 turns): the
    straight twisted rod's torque GJ 2 pi n / L before the snap, the snap into a loop with contact at 1.25
    turns, twist + writhe the turns applied at every step (no strand
    passage), the strands' true distance at least 2 r (1 - 1e-3)."""
    from helpers import load_demo
    demo = load_demo("plectoneme")
    sol = demo.main(str(tmp_path), verbose=False, **demo.SMALL)
    assert sol["converged"], sol["message"]
    recs = sol["records"]
    assert len(recs) == 25
    for q in recs:
        assert q["twist_writhe"] == pytest.approx(q["turns"], abs=1e-6)
        assert q["distance"] is None or q["distance"] >= 1 - 1e-3
    straight = [q for q in recs if q["pairs"] == 0 and q["turns"] > 0]
    assert len(straight) == 19            # to 1.1875 turns
    # (the lateral imperfection of 1e-2 T bends the rod a little: its effect
    # on the end torque is of second order, about 1e-6 here)
    for q in straight:
        assert q["torque"] == pytest.approx(demo.GJ * 2 * np.pi * q["turns"] / demo.L,
                                            rel=1e-4)
    loop = recs[20]
    assert loop["turns"] == pytest.approx(1.25) and loop["pairs"] > 0
    assert loop["x_end"] < 0.5 * demo.L and loop["torque"] < 0.5 * recs[19]["torque"]
    assert (tmp_path / "results.json").exists() and (tmp_path / "plectoneme.png").exists()


def test_a_mesh_too_coarse_for_the_barrier_is_warned_about():
    """The nodes' offset 3 a^2 / (8 eps) (``barrier.node_offset``) against
    the barrier's width: the plectoneme's 70 elements (a = 0.19 eps, offset
    0.014 eps) are fine; the hairpin's 24 (a = 0.6 eps, 0.136 eps) are
    not."""
    from skfem_rod.minimize import BarrierResolution
    import warnings
    from helpers import load_demo
    fine = load_demo("plectoneme").build(70, turns=0.01)
    with warnings.catch_warnings():
        warnings.simplefilter("error", BarrierResolution)
        assert fine.solve(1, method="barrier").converged
    rod, eps, _ = _pressed(0.0)
    with pytest.warns(BarrierResolution, match="0.136 of the radius.*below 0.0115$"):
        rod.solve(1, method="barrier", barrier_force=1.0)


def test_a_reference_bent_tighter_than_half_the_radius_is_refused():
    """The bend barrier (barrier module doc, "Local self-contact") forbids
    a curvature above 2 / radius: a reference with one is refused by name,
    not solved from an infinite energy."""
    # two straight legs, the second turned by 30 degrees over a bend of
    # radius 0.004 at s = 0.1: a curvature of 2.5 / eps
    rho, turn, eps = 0.004, np.pi / 6, 0.01

    def r_of_s(s):
        th = np.clip((s - 0.1) / rho, 0.0, turn)
        beyond = np.clip(s - 0.1 - rho * turn, 0.0, None)
        return np.c_[np.minimum(s, 0.1) + rho * np.sin(th) + beyond * np.cos(turn),
                     rho * (1 - np.cos(th)) + beyond * np.sin(turn), 0 * s]
    rod = Rod(geometry.curve(r_of_s, 0.2 + rho * turn), Section.circle(E=1e4, nu=0.3,
                                                                      radius=0.005), 40)
    rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).enable_contact(radius=eps)
    with pytest.raises(ValueError, match="curvature above 2 / radius"):
        rod.solve(1, method="barrier")
    # with a contact radius of the bend's (a curvature of 1 / eps) it solves
    rod.enable_contact(radius=rho)
    with pytest.warns(BarrierResolution):
        assert rod.solve(1, method="barrier").converged


def test_a_step_that_fails_again_when_grown_back_waits_longer(monkeypatch):
    """Where every step longer than a tenth of the path fails, the load
    path (solver.follow_path) cuts the step to 1/16 and grows it back after
    2, then 4, then 8 successes: the grown step failing at once doubles
    the successes it waits for (``GROW_AFTER``, ``MAX_NEED``), so that a
    stretch of the path that takes only short steps is not tried with
    long ones every third step (7 such failures instead of 3 here)."""
    from skfem_rod.solver import GROW_AFTER
    rod, _, _ = _pressed(0.0)
    calls = []
    step = EnergySolve.step

    def capped(self, r, R, lam, dlam, *args, **kwargs):
        if dlam > 0.1:
            calls.append((round(dlam, 12), False))
            return r, R, StepReport(converged=False, reason="too long a step")
        calls.append((round(dlam, 12), True))
        return step(self, r, R, lam, dlam, *args, **kwargs)

    monkeypatch.setattr(EnergySolve, "step", capped)
    result = rod.solve(1, method="barrier", barrier_force=1.0)
    assert result.converged, result.message
    assert np.allclose(np.diff(result.load_factors), 1 / 16)
    outcomes = [ok for dlam, ok in calls[1:] if dlam > 0]        # after step 0
    # the first cuts: 1, 1/2, 1/4, 1/8 fail; then runs of successes between
    # the grown steps' failures
    assert outcomes[:4] == [False] * 4
    runs = [len(run) for run in "".join("s" if ok else "f"
                                       for ok in outcomes[4:]).split("f")]
    assert runs == [GROW_AFTER, 2 * GROW_AFTER, 4 * GROW_AFTER, 2]


def _saved_plectoneme(name, n_elements, gamma_T):
    """The barrier plectoneme's two states saved in ``tests/data/<name>``
    (``benchmarks/plectoneme_state.py``) and the :class:`EnergySolve` of
    its ``n_elements`` rod with handles: ``(bp, d, S, lam1, dlam)``, ``bp``
    the bench module, ``d`` the states, ``lam1`` the later one's load
    factor and ``dlam`` the step between them."""
    from pathlib import Path

    from helpers import load_bench
    from skfem_rod.minimize import BarrierStepper
    from skfem_rod.options import split_barrier_options

    bp = load_bench("bench_plectoneme")
    d = np.load(Path(__file__).with_name("data") / name)
    rod = bp.build(n_elements, gamma_T)
    S = BarrierStepper(rod, *split_barrier_options(dict(barrier_force=1.0, handles=True))).solve
    lam1 = float(d["lam1"])
    return bp, d, S, lam1, lam1 - float(d["lam0"])


def _check_plectoneme(S, bp, r, R, rep, lam):
    """The barrier plectoneme's step of report ``rep`` (``S`` its
    :class:`EnergySolve`, ``bp`` the bench module) converged at ``lam``:
    no overlap, Coulomb's law at its pairs, an equilibrium to rtol, the
    link the turns applied."""
    from skfem_rod.topology import topology

    assert rep.converged, rep.reason
    assert rep.true_distance >= 2 * bp.RADIUS * (1 - S.options.penetration_tol)
    nc = S.contact(r, R, rep)
    assert nc.force.size > 0
    # Coulomb: no friction force above mu times its pair's normal force
    excess = np.linalg.norm(nc.friction, axis=1) - S.mu * nc.force
    assert excess.max() <= 1e-9 * S.mu * nc.force.max()
    # an equilibrium: the out-of-balance force on the free dofs within rtol
    G = S.residual(r, R, lam, rep.friction) if rep.live else rep.out_of_balance
    assert np.linalg.norm(G[S.free]) <= S.options.rtol * S.P.force_scale(rep.evaluation)
    o = np.argsort(S.rod.mesh.s_nodes)
    t = topology(r[o], R[o][:, :, 0], t_start=R[o][0][:, 2], t_end=R[o][-1][:, 2])
    assert t.twist - t.closure_twist + t.writhe == pytest.approx(lam * bp.TURNS, abs=1e-6)


@pytest.mark.slow
def test_a_slip_stalls_the_static_step_and_pseudo_time_steps_go_through_it():
    """The 100-element frictional barrier plectoneme (gamma_T = 0.3,
    handles) at 7.625 turns, saved by ``benchmarks/plectoneme_state.py
    100 123 ... 0.3 handles``: its next step of 1/16 turn slips, the live
    Newton fails, and the fallback's lag does not contract (changes of
    0.2-1 of the largest normal force, lag after lag; before the stall
    test all 60 lags ran).  The static step fails naming the stall,
    well before ``max_lags`` (15 lags, 800 iterations).  Taken by pseudo-time steps through the
    slip where the live Newton fails (no fallback), the whole step
    converges: an equilibrium with Coulomb's law at its pairs, the link
    kept, no overlap.  Failed at once where the live Newton fails
    (``slip="cut"``, what the load path tries first), the step is cut in
    two halves, and each goes through statically."""
    from skfem_rod.minimize import LAG_STALL, SLIP_FAILURES, SLIP_LIVE

    bp, d, S, lam1, dlam = _saved_plectoneme("plectoneme_stall.npz", 100, 0.3)
    r, R, rep = S.step(d["r1"], d["R1"], lam1, dlam, (d["r0"], d["R0"]), slip="fallback")
    assert not rep.converged and "stalled" in rep.reason
    # the first settle, the live solves, then the fallback's lags: at most
    # LAG_STALL + a few more than the least change's lag
    assert LAG_STALL <= rep.lags < S.options.max_lags // 2
    stalled = rep.iterations

    r, R, rep = S.step(d["r1"], d["R1"], lam1, dlam, (d["r0"], d["R0"]))
    assert rep.damped > 0 and rep.slip.startswith(SLIP_FAILURES)
    _check_plectoneme(S, bp, r, R, rep, lam1 + dlam)
    # what the load path does first: the step fails where the live Newton
    # does (no fallback), in a fraction of the fallback's iterations, and
    # is cut; its two halves go through statically
    r, R, rep = S.step(d["r1"], d["R1"], lam1, dlam, (d["r0"], d["R0"]), slip="cut")
    assert not rep.converged and rep.reason.startswith(SLIP_LIVE)
    assert rep.damped == 0 and rep.fallbacks == 0 and rep.iterations < stalled / 2
    r, R, rep = S.step(d["r1"], d["R1"], lam1, dlam / 2, (d["r0"], d["R0"]), ratio=0.5,
                       slip="cut")
    _check_plectoneme(S, bp, r, R, rep, lam1 + dlam / 2)
    r, R, rep = S.step(r, R, lam1 + dlam / 2, dlam / 2, (d["r1"], d["R1"]), slip="cut")
    _check_plectoneme(S, bp, r, R, rep, lam1 + dlam)


@pytest.mark.slow
def test_pseudo_time_steps_lagged_once_go_through_a_second_slip():
    """The 100-element frictional barrier plectoneme (gamma_T = 0.3,
    handles) at 8.906 turns (a state of a run of the twenty-ninth
    session, saved by ``benchmarks/plectoneme_state.py``): its next step
    of 1/32 turn slips.  Taken with the fallback, the lag's fixed point
    stalls (more than ``LAG_STALL`` lags).  Taken by pseudo-time steps
    (each one solve with the friction lagged at its anchor), the step
    converges: an equilibrium with Coulomb's law at its pairs, the link
    kept, no overlap; and the step's first half goes through
    statically."""
    from skfem_rod.minimize import LAG_STALL, SLIP_FAILURES

    bp, d, S, lam1, dlam = _saved_plectoneme("plectoneme_lag_stall.npz", 100, 0.3)
    previous = (d["r0"], d["R0"])
    _, _, stalled = S.step(d["r1"], d["R1"], lam1, dlam, previous, slip="fallback")
    assert not stalled.converged and "stalled" in stalled.reason
    assert stalled.lags > LAG_STALL
    r, R, rep = S.step(d["r1"], d["R1"], lam1, dlam, previous)
    assert rep.damped > 0 and rep.slip.startswith(SLIP_FAILURES)
    _check_plectoneme(S, bp, r, R, rep, lam1 + dlam)
    r, R, rep = S.step(d["r1"], d["R1"], lam1, dlam / 2, previous, ratio=0.5, slip="cut")
    _check_plectoneme(S, bp, r, R, rep, lam1 + dlam / 2)


@pytest.mark.slow
def test_a_step_past_a_loss_of_stability_ends_on_a_minimum():
    """The 150-element frictionless barrier plectoneme (handles) at 5.25
    turns, saved by ``benchmarks/plectoneme_state.py 150 84
    tests/data/plectoneme_saddle.npz 0.0 handles``: a minimum, whose path
    loses its stability within the next step of 1/16 turn.  From the
    quadratic predictor (the path's tangent) Newton converges in a few
    iterations to the branch's continuation, a saddle of the energy (one
    negative eigenvalue); the step then takes the secant's start instead,
    from which the energy's descent reaches a minimum: the step ends on
    it, its report counting both solves."""
    bp, d, S, lam1, dlam = _saved_plectoneme("plectoneme_saddle.npz", 150, 0.0)
    r, R, at = S.step(d["r1"], d["R1"], lam1, 0.0)         # the saved state, re-solved
    assert at.converged and at.iterations == 0 and at.negative == 0
    # Newton from the tangent's prediction alone: a saddle
    alone = StepReport(converged=False)
    r1, R1 = S.predict(r, R, dlam, (d["r0"], d["R0"]), rate=at.rate)
    S.newton(r1, R1, lam1 + dlam, None, 0.0, alone)
    assert not alone.reason and alone.negative == 1
    # the step: a minimum, both solves counted
    r2, R2, rep = S.step(r, R, lam1, dlam, (d["r0"], d["R0"]), rate=at.rate, stable=True)
    assert rep.converged, rep.reason
    assert rep.negative == 0
    assert rep.iterations > alone.iterations and len(rep.solves) == 2
    assert rep.true_distance >= 2 * bp.RADIUS
