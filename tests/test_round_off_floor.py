"""Newton at the residual's round-off floor (newton.at_floor,
Problem.round_off_floor) and the proximal polish (relax.polish).

The recorded state (tests/data/writhing_soft_mode.npz) is the gradient
flow's state at the first shortening step of the localized writhing case
(benchmarks/bench_writhing.py, rigid path, 64 elements, load factor 1/30):
a loop of the localizing helix forming in a rod of length 100 with
``EA = 1e5`` under end forces of order 1.  The loop slides along the rod at
almost no cost (lowest eigenvalue 1e-13 of the stiffest), and the
residual's round-off floor is about 1.7e-7 of the force scale, far above
``rtol`` = 1e-10."""
from pathlib import Path

import numpy as np
import pytest

from skfem_rod import newton as newton_module
from skfem_rod.newton import Iterate, at_floor, newton
from skfem_rod.options import SolverOptions
from skfem_rod.problem import Problem
from skfem_rod.relax import climbs, metric, polish

from helpers import load_bench

DATA = Path(__file__).parent / "data" / "writhing_soft_mode.npz"
bw = load_bench("bench_writhing")


@pytest.fixture(scope="module")
def soft():
    d = np.load(DATA)
    _, shorten = bw.build_rigid(64, 1e-3)
    return Problem(shorten), d["r"], d["R"], float(d["lam"])


def test_the_floor_is_the_noise_of_the_residual(soft):
    """Translating the whole state rigidly leaves the residual unchanged in
    exact arithmetic (internal work, dead loads); in floating point it
    changes by the round-off of the positions.  That change is of the size
    of the measured floor, and far above rtol times the force scale."""
    p, r, R, lam = soft
    ev = p.evaluate(r, R, lam)
    floor = p.round_off_floor(r, R, lam, ev)
    scale = p.force_scale(ev)
    assert 1e-8 < floor / scale < 1e-6
    rng = np.random.default_rng(7)
    changes = []
    for _ in range(5):
        t = rng.uniform(-50.0, 50.0, 3)
        ev_t = p.evaluate(r + t, R, lam, tangent=False)
        changes.append(np.linalg.norm((ev_t.residual - ev.residual)[p.free]))
    assert max(changes) < 4.0 * floor
    assert min(changes) > 0.05 * floor
    # the a-priori estimate that gates the measurement is of the same size
    assert 0.1 < p.floor_estimate(r, ev) / floor < 10.0


def test_newton_returns_its_least_iterate_at_the_floor(soft, monkeypatch):
    """From the flow's state Newton's updates are round-off amplified along
    the soft mode: the residual cycles between 1e-7 and 1 (25 iterations,
    failed, without the floor test).  With it the solve returns its least
    iterate once the residual rose from there, at its floor."""
    p, r, R, lam = soft
    opts = SolverOptions()
    r1, R1, _, rep = newton(p, r, R, lam, opts)
    assert rep.converged and rep.floor is not None
    ev = p.evaluate(r1, R1, lam)
    rn = p.residual_norm(ev)
    assert rn == pytest.approx(min(rep.history), rel=1e-12)
    assert rn <= rep.floor * p.force_scale(ev)
    assert rn > opts.rtol * p.force_scale(ev)             # not at rtol: at the floor
    assert max(rep.history[rep.history.index(min(rep.history)):]) > 2 * rn
    # without the floor test Newton cycles to its iteration limit
    monkeypatch.setattr(newton_module, "at_floor", lambda *a: None)
    rep = newton(p, r, R, lam, opts)[3]
    assert not rep.converged and "no convergence in 25 iterations" in rep.reason


def test_at_floor_turns_down_a_residual_above_the_floor(soft):
    p, r, R, lam = soft
    ev = p.evaluate(r, R, lam)
    rn = p.residual_norm(ev)
    floor = p.round_off_floor(r, R, lam, ev)
    assert rn > floor                                     # the flow's state itself
    assert at_floor(p, Iterate(rn, r, R, lam, ev), [rn, 1.0]) is None
    out = at_floor(p, Iterate(0.5 * floor, r, R, lam, ev), [0.5 * floor, 1.0])
    assert out is not None and out[3].converged
    assert out[3].floor == pytest.approx(floor / p.force_scale(ev))
    assert out[3].iterations == 1


def test_proximal_polish_reaches_the_floor(soft, monkeypatch):
    """Where Newton fails outright (here: held to 3 iterations), the polish
    takes proximal steps and stops when the residual without the viscous
    term is at its floor: an equilibrium, checked afresh."""
    p, r, R, lam = soft
    opts = SolverOptions(max_iterations=3)
    assert not newton(p, r, R, lam, opts)[3].converged
    W = metric(p.rod, p.fixed)
    r1, R1, _, rep = polish(p, W, 1.0, r, R, lam, opts)
    assert rep.converged, rep.reason
    ev = Problem(p.rod).evaluate(r1, R1, lam)
    rn = p.residual_norm(ev)
    assert rn <= max(opts.rtol * p.force_scale(ev), p.round_off_floor(r1, R1, lam, ev))
    assert np.abs(r1 - r).max() < 0.1                     # next to the flow's state


def test_descent_check_along_an_unstable_mode():
    """``climbs`` on the energy ``-k x^2 / 2`` (metric ``q``): backward Euler
    from ``x0`` gives ``x1 = x0 q / (q - k dt)``; a step longer than
    ``q / k`` lands on the other side of the saddle; from ``3 q / k`` on it
    lands less than half as far from it as it started (``|x1| < x0 / 2``),
    and the check calls it climbing (the trapezoid rule is exact for a
    quadratic: the energy falls by ``k (x0^2 - x1^2) / 2``, and it must fall
    by half the viscous work ``k |x1| |x1 - x0|``)."""
    k, q, x0 = 3.0, 2.0, 0.1
    free = np.array([True])
    for dt, up in [(0.1 * q / k, False), (0.9 * q / k, False), (2.9 * q / k, False),
                   (3.1 * q / k, True), (10 * q / k, True)]:
        x1 = x0 * q / (q - k * dt)
        g0, g1 = np.array([-k * x0]), np.array([-k * x1])
        assert climbs(g0, g1, np.array([x1 - x0]), free) is up, dt


def test_a_polish_beyond_the_clearance_cap_is_not_converged(soft, monkeypatch):
    """The gradient flow's polish (``clearance=True``) does not count a
    solve that moves a node beyond the clearance cap as converged, Newton's
    or a proximal step's; the pseudo-dynamics' (``clearance=False``) leaves
    that to the AL loop's true-distance check."""
    from skfem_rod import relax
    p, r, R, lam = soft
    W = metric(p.rod, p.fixed)
    opts = SolverOptions(max_iterations=3)
    monkeypatch.setattr(relax, "clearance_ok", lambda rod, r0, r1: False)
    assert polish(p, W, 1.0, r, R, lam, opts, clearance=False)[3].converged
    rep = polish(p, W, 1.0, r, R, lam, opts)[3]
    assert not rep.converged and "40 proximal steps" in rep.reason


def test_a_polish_with_contact_beyond_the_clearance_cap_is_not_converged(monkeypatch):
    """With contact (no proximal steps) Newton's converged solve that moves
    a node beyond the clearance cap is returned as not converged too."""
    from skfem_rod import Rod, Section, geometry, relax
    rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 8)
    rod.clamp("start").add_force("end", [0.0, 1e-3, 0.0])
    rod.enable_contact()
    p = Problem(rod)
    res = rod.solve(1)
    st = res.steps[-1]
    W = metric(rod, p.fixed)
    assert polish(p, W, 1.0, st.r, st.R, 1.0, SolverOptions())[3].converged
    monkeypatch.setattr(relax, "clearance_ok", lambda rod, r0, r1: False)
    rep = polish(p, W, 1.0, st.r, st.R, 1.0, SolverOptions())[3]
    assert not rep.converged and "clearance cap" in rep.reason
    assert polish(p, W, 1.0, st.r, st.R, 1.0, SolverOptions(), clearance=False)[3].converged
