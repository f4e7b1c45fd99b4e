"""Newton on the total energy with the node barrier (skfem_rod.minimize):
the energy and its gradient agree (finite differences through the rod's own
update, spins included), bad options are refused, and the twisted rod
snaps into the loop of the reference (the augmented-Lagrangian solve's
torques, tests/test_dynamics.py) without gradient flow."""
import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.contact.barrier import (Barrier, barrier_work, friction_lag, friction_live,
                                       potential)
from skfem_rod.contact.crossing import min_distance
from skfem_rod.contact.search import arclength_period
from skfem_rod.minimize import EnergyOptions, EnergySolve
from skfem_rod.topology import topology

from helpers import load_demo

demo = load_demo("twisted_rod")


def _hairpin(n=24):
    """Two straight arms joined by a half circle, the arms half the node
    barrier's width outside its contact distance; a dead force on the end.
    Returns the rod, its radius and the barrier."""
    eps = 0.05

    def build(half):
        def r_of_s(s):
            th = np.clip((s - 1.0) / half, 0.0, np.pi)
            arm2 = np.clip(s - 1.0 - np.pi * half, 0.0, None)
            return np.c_[np.minimum(s, 1.0) + half * np.sin(th) - arm2,
                         half - half * np.cos(th), 0 * s]
        rod = Rod(geometry.curve(r_of_s, 2.0 + np.pi * half),
                  Section.circle(E=1e4, nu=0.3, radius=eps), n)
        return rod, Barrier.for_nodes(rod.mesh.s_nodes, eps, width=0.02, force=1.0)

    _, barrier = build(eps)
    rod, barrier = build(0.5 * (barrier.distance + 0.5 * barrier.width))
    rod.clamp("start")
    rod.add_force("end", [0.0, -0.3, 0.1])
    return rod, eps, barrier


def test_energy_gradient_matches_finite_differences_with_contact_and_friction():
    rod, eps, barrier = _hairpin()
    solve = EnergySolve(rod, barrier, eps, mu=0.3)
    P = solve.P
    r, R = rod.r0.copy(), rod.R0.copy()
    rng = np.random.default_rng(4)
    start = rng.standard_normal(r.shape) * 1e-4
    r0 = r + start
    lag = friction_lag(r, R, r0, R, solve.s, barrier)
    assert lag.pairs.shape[0] > 0
    E, G = solve.energy(r, R, 0.5, lag)
    v = rng.standard_normal(G.size) * 1e-3
    v[~P.free] = 0.0
    h = 1e-6
    Ep, _ = solve.energy(*P.update(r, R, v, h), 0.5, lag)
    Em, _ = solve.energy(*P.update(r, R, v, -h), 0.5, lag)
    fd = (Ep - Em) / (2 * h)
    assert fd == pytest.approx(float(G @ v), rel=1e-6)


def test_bad_input_is_refused_with_the_parameter_named():
    rod, eps, barrier = _hairpin()
    with pytest.raises(ValueError, match="mu"):
        EnergySolve(rod, barrier, eps, mu=-0.1)
    with pytest.raises(ValueError, match="rtol"):
        EnergyOptions(rtol=0.0)
    with pytest.raises(ValueError, match="max_lags"):
        EnergyOptions(max_lags=0)
    rod.add_force("end", [0.0, 0.0, 1.0], follower=True)
    with pytest.raises(ValueError, match="follower"):
        EnergySolve(rod, barrier, eps)
    rod.point_loads.pop()
    rod.enable_contact(radius=eps)
    with pytest.raises(ValueError, match="enable_contact"):
        EnergySolve(rod, barrier, eps)


@pytest.mark.slow
def test_twisted_rod_snaps_into_the_reference_loop():
    """The contact scene of tests/test_dynamics.py (L = 10 lambda, radius
    0.1 lambda; 108 elements here, the node spacing a third of the radius,
    where the augmented-Lagrangian solve used 36) in steps of 0.1 turn by
    ``Rod.solve(method="barrier")``: the straight branch's torque at 1.7
    turns (1.913 sqrt(BT)), the loop closed by contact at 1.8 turns with
    the reference's torque 0.89 (within 0.02: the barrier's standoff), a
    recorded state never overlapping, link kept."""
    rod = demo.build(10.0, 108, 0.1, 1.9, 0.01, 0.01)
    order = np.argsort(rod.mesh.s_nodes)
    torque = {}

    def check(result, k):
        st = result.steps[k]
        turns = round(st.load_factor * 1.9, 6)
        torque[turns] = abs(float(result.reaction("end", k)[1][0]))
        md = min_distance(rod.mesh, st.r, 0.1, rod.contact.exclusion)
        assert md.distance >= 2 * 0.1 * (1 - 1e-3)
        assert st.contact.min_distance == pytest.approx(md.distance, rel=1e-12)
        link = topology(st.r[order], st.R[order][:, :, 0]).link
        assert link == pytest.approx(np.floor(turns + 0.5), abs=1e-6)   # no strand passage
    result = rod.solve(18, path=[0, 18 / 19], method="barrier", barrier_force=1.0,
                       callback=check)
    assert result.converged, result.message
    assert len(result.steps) == 19 and len(torque) == 19
    assert torque[1.7] == pytest.approx(1.913, abs=0.01)
    assert torque[1.8] == pytest.approx(0.89, abs=0.02)
    assert result.steps[-1].contact.s.size > 0
    assert all(st.flow_steps == 0 for st in result.steps)


def _steps(solve, n, settle=False):
    """``n`` equal steps of ``solve`` to load factor 1, each from the last
    (the predictor from the last two equilibria and, with ``settle`` or
    after the first step, the path's tangent at the last; the friction's
    slips carried from the step before), from the
    reference or, with ``settle``, from the equilibrium at load factor 0
    (as ``Rod.solve(method="barrier")``; the hairpin's arms start inside
    the barrier's width); the last state and the steps' reports."""
    r, R, prev, reps, sigma = solve.rod.r0.copy(), solve.rod.R0.copy(), None, [], 0.0
    rate, stable, friction = None, False, None
    if settle:
        r, R, rep = solve.step(r, R, 0.0, 0.0)
        assert rep.converged, rep.reason
        sigma, rate, stable, friction = rep.sigma, rep.rate, rep.negative == 0, rep.friction
    for k in range(n):
        r1, R1, rep = solve.step(r, R, k / n, 1 / n, prev, sigma, rate=rate, stable=stable,
                                 friction=friction)
        assert rep.converged, rep.reason
        prev, (r, R), sigma = (r, R), (r1, R1), rep.sigma
        rate, stable, friction = rep.rate, rep.negative == 0, rep.friction
        reps.append(rep)
    return r, R, reps


def _pressed_hairpin(mu, steps=4):
    """The hairpin's free arm pressed onto the clamped one (-y) and pulled
    along it (+x) by a dead end force growing with the load factor; returns
    the solve, the last state and the step reports."""
    rod, eps, barrier = _hairpin()
    rod.point_loads.clear()
    rod.add_force("end", [0.02, -0.05, 0.0])
    solve = EnergySolve(rod, barrier, eps, mu=mu)
    r, R, reps = _steps(solve, steps)
    return solve, rod, r, R, reps


def test_friction_holds_a_pressed_arm_and_obeys_coulomb():
    """Friction resists the pull along the arm (the end moves less along x
    with mu = 0.3 than without, and less still with mu = 1); at every
    converged step the state is an equilibrium with the friction of its
    own lag at its own normal forces and normals, every pair's friction
    force is within Coulomb's bound there, normal to the normal, and the
    solves at the live normal forces converge quadratically."""
    moved = {}
    for mu in (0.0, 0.3, 1.0):
        solve, rod, r, R, reps = _pressed_hairpin(mu)
        end = rod.node("end")
        moved[mu] = float(r[end, 0] - rod.r0[end, 0])
        assert barrier_work(r, solve.s, solve.barrier, hessian=False).active > 0
        if mu == 0:
            assert all(rep.friction is None for rep in reps)
            continue
        lag = reps[-1].friction
        assert lag.pairs.shape[0] > 0
        G = solve.residual(r, R, 1.0, lag)
        ev = solve.P.evaluate(r, R, 1.0, tangent=False)
        assert np.linalg.norm(G[solve.free]) <= solve.options.rtol * solve.P.force_scale(ev)
        # the lag at the state is the one it converged with (no new pair)
        again = friction_lag(r, R, r, R, solve.s, solve.barrier, lag)
        assert np.array_equal(again.pairs, lag.pairs)
        w = friction_live(r, R, lag, solve.barrier, mu, solve.eps_v, jacobian=False)
        i, j = lag.pairs[:, 0], lag.pairs[:, 1]
        d = r[i] - r[j]
        g = np.linalg.norm(d, axis=1) - solve.barrier.distance
        lam_now = np.where(g < solve.barrier.width, -potential(
            np.minimum(g, solve.barrier.width), solve.barrier.width,
            solve.barrier.stiffness)[1], 0.0)
        f = np.linalg.norm(w.force, axis=1)
        assert np.all(f <= mu * lam_now * (1 + 1e-12))
        n = d / np.linalg.norm(d, axis=1)[:, None]
        assert np.abs(np.einsum("ka,ka->k", w.force, n)).max() <= 1e-12 * f.max()
        # the live solves converge quadratically: relative to a solve's first
        # residual, e_{k+1} <= e_k^2 (a linear rate of 0.1 fails this below
        # e_k = 0.1), up to the residual the solve stops at
        tested = 0
        for rep in reps:
            assert rep.live
            stop = solve.options.rtol * solve.P.force_scale(rep.evaluation)
            for live, hist in rep.solves:
                if not live or len(hist) < 3:
                    continue
                h = np.array(hist)
                e = h / h[0]
                above = h[1:] > stop
                assert np.all(e[1:][above] <= e[:-1][above] ** 2), hist
                tested += int(np.sum(above & (e[:-1] < 0.1)))
        assert tested >= 2
    assert moved[0.0] > moved[0.3] > moved[1.0] >= 0.0



def test_a_step_adding_no_load_leaves_a_frictional_equilibrium_as_it_is():
    """From a converged frictional state of the pressed hairpin, a step of
    zero load with the slips of the lag it was solved with carried
    (``friction=``, :func:`carry_slip`: the friction's memory) takes no
    iteration and leaves the state as it is.  Without them every pair's
    friction starts the step from zero, and the arm moves (by more than
    the slip smoothing) while the stuck pairs build their forces up."""
    solve, rod, r, R, reps = _pressed_hairpin(0.3)
    lag = reps[-1].friction
    r2, R2, rep = solve.step(r, R, 1.0, 0.0, None, friction=lag)
    assert rep.converged and rep.iterations == 0
    assert np.array_equal(r2, r) and np.array_equal(R2, R)
    r3, _, fresh = solve.step(r, R, 1.0, 0.0, None)
    assert fresh.converged and fresh.iterations > 0
    assert np.abs(r3 - r).max() > solve.eps_v

def test_newton_given_an_iteration_limit_stops_there_naming_it():
    """A frictional Newton solve (on the energy at a lag, and the live one)
    given ``iterations`` takes at most that many and says it did not
    converge; without the limit the same solve converges in more: the
    limit the static try of a step that may slip is given."""
    from skfem_rod.minimize import StepReport

    solve, rod, r, R, reps = _pressed_hairpin(0.3)
    lag = friction_lag(r, R, r, R, solve.s, solve.barrier)
    for live in (False, True):
        free = StepReport(converged=False)
        solve.newton(r, R, 1.5, lag, 0.0, free, live=live)
        assert free.reason == "" and free.iterations >= 3
        capped = StepReport(converged=False)
        solve.newton(r, R, 1.5, lag, 0.0, capped, live=live, iterations=2)
        assert capped.iterations == 2
        assert capped.reason.startswith("no convergence in")
        assert capped.history == free.history[:3]

def test_a_step_whose_strands_overlap_between_nodes_has_not_converged():
    """With a node barrier whose contact distance is below 2 eps, the
    pressed arm's nodes settle closer than the strands' diameter: the step
    is solved, but its true distance says the strands overlap, so it has
    not converged (and the reason says by how much)."""
    rod, eps, barrier = _hairpin()
    rod.point_loads.clear()
    rod.add_force("end", [0.0, -0.05, 0.0])
    short = Barrier(distance=0.98 * 2 * eps, width=barrier.width,
                    stiffness=barrier.stiffness, exclusion=barrier.exclusion)
    r1, R1, rep = EnergySolve(rod, short, eps).step(rod.r0, rod.R0, 0.0, 1.0)
    assert not rep.converged and "overlap" in rep.reason
    assert rep.true_distance < 2 * eps * (1 - 1e-3)
    assert rep.residual <= 1e-8 * EnergySolve(rod, short, eps).P.force_scale(rep.evaluation)
    # the same press on the barrier for the radius: converged, no overlap
    r1, R1, rep = EnergySolve(rod, barrier, eps).step(rod.r0, rod.R0, 0.0, 1.0)
    assert rep.converged, rep.reason
    assert rep.true_distance >= 2 * eps * (1 - 1e-3)


def test_an_unloaded_closed_ring_stays_put():
    """A closed ring without loads, the barrier periodic: no pair across
    the closure point, no motion.  Without the period the rod is refused."""
    rod = Rod(geometry.ring(1.0), Section.circle(E=1e4, nu=0.3, radius=0.02), 40)
    period = arclength_period(rod.mesh)
    assert period == pytest.approx(2 * np.pi)
    with pytest.raises(ValueError, match="period"):
        EnergySolve(rod, Barrier.for_nodes(rod.mesh.s_nodes, 0.02), 0.02)
    barrier = Barrier.for_nodes(rod.mesh.s_nodes, 0.02, period=period)
    solve = EnergySolve(rod, barrier, 0.02, mu=0.3)
    r1, R1, rep = solve.step(rod.r0, rod.R0, 0.0, 1.0)
    assert rep.converged, rep.reason
    assert rep.active == 0
    assert np.abs(r1 - rod.r0).max() < 1e-12


def test_a_saddle_is_left_along_its_negative_curvature(monkeypatch):
    """A straight rod clamped at both ends (the end free to move along the
    axis, its rotation held), shortened by 2 % of its length, far beyond
    Euler's (4 pi^2 EI / (EA L^2) = 0.4 %), a lateral dead force 1e-4 at
    mid-length: Newton from the straight state creeps away from that
    saddle with its tangent shifted.  The step along the tangent's
    negative lowest mode leaves it sooner and ends at the same buckled
    minimum (no negative eigenvalue, the same energy and shape).  Without
    the lateral force the straight state is an equilibrium, and a saddle,
    and said to be one (its negative eigenvalues: the two planes of
    buckling of a round section, and their overtones)."""
    import skfem_rod.minimize as m

    def solved(imperfection, curvature):
        monkeypatch.setattr(m, "NEGATIVE_CURVATURE", curvature)
        rod = Rod(geometry.straight(1.0), Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0,
                                                  GJ=0.8, radius=0.01), 24)
        rod.clamp("start").fix_rotation("end").prescribe_displacement("end", [-0.02, 0, 0])
        if imperfection:
            rod.add_force(0.5, [0.0, imperfection, 0.0])
        solve = EnergySolve(rod, Barrier.for_nodes(rod.mesh.s_nodes, 0.01), 0.01)
        r, R, rep = solve.step(rod.r0, rod.R0, 0.0, 1.0)
        assert rep.converged, rep.reason
        return r, rep, solve.energy(r, R, 1.0)[0]
    r0, rep0, E0 = solved(1e-4, False)
    r1, rep1, E1 = solved(1e-4, True)
    assert rep0.curvature_steps == 0 and rep1.curvature_steps >= 1
    assert rep0.negative == rep1.negative == 0
    assert rep1.iterations < 0.7 * rep0.iterations, (rep0.iterations, rep1.iterations)
    assert E1 == pytest.approx(E0, rel=1e-9)
    assert np.abs(r1 - r0).max() <= 1e-6 and np.abs(r1[:, 1]).max() > 0.05   # buckled
    r, rep, E = solved(0.0, True)
    assert np.abs(r[:, 1:]).max() == 0.0 and rep.negative >= 2 and E > E0


def test_proximal_term_matches_finite_differences_along_the_solves_update():
    """The pseudo-time step's proximal term (:func:`proximal_work`) from
    an anchor turned and moved away by a random finite motion: its
    gradient against central differences of its energy along the solve's
    own update (positions and spatial spins, ``Problem.update``), its
    tangent column by column against differences of the gradient; zero
    energy and gradient at the anchor, tangent ``diag(c, c l^2)`` there."""
    from skfem_rod.minimize import Proximal, proximal_work
    rod, eps, barrier = _hairpin()
    solve = EnergySolve(rod, barrier, eps)
    P = solve.P
    rng = np.random.default_rng(8)
    r0, R0 = rod.r0.copy(), rod.R0.copy()
    n = r0.shape[0]
    prox = Proximal(r0, R0, 3.0, 0.2)
    E, G, K = proximal_work(r0, R0, prox)
    assert abs(E) <= 1e-15 * n and np.abs(G).max() <= 1e-15     # 3 - tr(I): round-off
    assert np.allclose(K.diagonal(), np.tile([3.0] * 3 + [3.0 * 0.04] * 3, n))
    away = rng.standard_normal(6 * n) * 0.3
    r, R = P.update(r0, R0, away)
    E, G, K = proximal_work(r, R, prox)
    h = 1e-6
    v = rng.standard_normal(6 * n)
    Ep = proximal_work(*P.update(r, R, v, h), prox, False)[0]
    Em = proximal_work(*P.update(r, R, v, -h), prox, False)[0]
    assert (Ep - Em) / (2 * h) == pytest.approx(float(G @ v), rel=1e-7)
    Kd = K.toarray()
    for j in rng.choice(6 * n, 24, replace=False):
        e = np.zeros(6 * n)
        e[j] = 1.0
        col = (proximal_work(*P.update(r, R, e, h), prox, False)[1]
               - proximal_work(*P.update(r, R, e, -h), prox, False)[1]) / (2 * h)
        assert np.abs(col - Kd[:, j]).max() <= 1e-6 * np.abs(Kd).max()


def test_quadratic_predictor_is_exact_on_a_quadratic_path():
    """``predictor`` passes through ``y_{k-1}`` and ``y_k`` with the slope
    ``y'(y_k)``: on a quadratic path it lands on the path, for any ratio of
    step sizes; with one of its two inputs it is the secant or Euler."""
    from skfem_rod.minimize import predictor
    rng = np.random.default_rng(3)
    a, b, c = rng.standard_normal((3, 12))
    y = lambda t: a + b * t + c * t ** 2
    for h0, h1 in [(0.1, 0.1), (0.1, 0.05), (0.05, 0.15)]:
        dy = predictor(y(0) - y(-h0), h1 * b, h1 / h0)
        assert np.abs(y(0) + dy - y(h1)).max() <= 1e-13
    assert np.array_equal(predictor(y(0) - y(-0.1), None, 0.5), 0.5 * (y(0) - y(-0.1)))
    assert np.array_equal(predictor(None, 0.1 * b, 0.5), 0.1 * b)


@pytest.mark.parametrize("motion", [False, True])
def test_path_tangent_matches_the_equilibria_beside_it(motion):
    """The path's tangent a solved frictionless step reports
    (``StepReport.rate``, from the energy's Hessian at the state: the
    loads' rate and the prescribed motions' through the supports) is the
    central difference of the equilibria at ``lam -+ delta`` to O(delta^2),
    with the hairpin's arms inside the barrier's width (its Hessian in
    it).  ``motion``: the clamp also turned about the arm's axis by
    0.2 lam (the prescribed part of the tangent)."""
    rod, eps, barrier = _hairpin()
    if motion:
        rod.supports.clear()
        rod.pin("start").prescribe_rotation("start", [0.2, 0.0, 0.0])
    solve = EnergySolve(rod, barrier, eps)
    r, R, rep = solve.step(rod.r0, rod.R0, 0.0, 0.5)
    assert rep.converged and rep.active > 0 and rep.rate is not None
    ends = []
    for sign in (-1, 1):
        r1, R1, q = solve.step(r, R, 0.5, sign * 1e-4)
        assert q.converged, q.reason
        ends.append((r1, R1))
    fd = solve.P.increment(*ends[1], *ends[0]) / 2e-4
    err = np.abs(rep.rate - fd).reshape(-1, 6)
    scale = np.abs(fd).reshape(-1, 6)
    assert err[:, :3].max() <= 1e-5 * scale[:, :3].max()
    assert err[:, 3:].max() <= 1e-5 * scale[:, 3:].max()
