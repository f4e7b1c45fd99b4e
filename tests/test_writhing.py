"""Localized writhing of a clamped rod (PyElastica's helical buckling case)
reached by the rigid-loading path of benchmarks/bench_writhing.py: the
rod is twisted by 27 turns under a small end stretch (straight and stable),
then its end is brought in by the slack with the end rotation held.  The
equilibrium at the end is compared with the localizing helix of the
infinite rod (:func:`skfem_rod.analytic.localized_writhing`)."""

import warnings

import numpy as np
import pytest
from scipy.optimize import minimize_scalar

from skfem_rod.analytic import localized_writhing
from skfem_rod.problem import Problem
from skfem_rod.solver import RelaxedShortfall

from helpers import load_bench

# the case and its rigid path as the benchmark builds them
bw = load_bench("bench_writhing")
L, B, C, SLACK, TURNS = bw.L, bw.B, bw.C, bw.SLACK, bw.TURNS


@pytest.fixture(scope="module", params=["relax", "dynamics"])
def writhed(request):
    """The rigid path's shortening stage by the gradient flow
    (``snap="relax"``) or by pseudo-dynamics (``dynamics=True``, no
    gradient-flow step).  The loop slides along the rod at almost no cost
    and the residual's round-off floor is a few 1e-7 of the force scale (1.7e-7
    at 64 elements, 4.8e-7 at 128): every
    recorded step is an equilibrium to that floor (Newton's least iterate
    there, or the proximal polish), none is the flow's state kept short of
    it (no RelaxedShortfall)."""
    options = dict(snap="relax") if request.param == "relax" else dict(dynamics=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RelaxedShortfall)
        twisted, result = bw.solve_rigid(96, 15, 1e-3, dict(stability=True, **options))
    assert twisted.converged, twisted.message
    assert result.converged, result.message
    flow = sum(st.flow_steps for st in result.steps)
    assert (flow > 0) if request.param == "relax" else (flow == 0)
    if request.param == "dynamics":
        # the first damped phase leaves the compressed straight rod (21
        # unstable modes) with its steps checked for descent: 72 damped
        # steps; held at the saddle's dt bound it took 397
        assert result.dynamics.damped_per_record[0] < 150
    return twisted, result


def helix_angle(ref, s, h=1e-4):
    """Angle between the tangent of the localizing helix and its axis at ``s``."""
    t = (ref.position(s + h) - ref.position(s - h)) / (2 * h)
    return np.arccos(np.clip(t[:, 2] / np.linalg.norm(t, axis=1), -1.0, 1.0))


def tangents(result, step=-1):
    f = result.sample(16, step)
    t = np.einsum("nij,nj->ni", f["R"], f["v"])
    return f["s"], t / np.linalg.norm(t, axis=1)[:, None]


@pytest.mark.slow
def test_twisting_stage_stays_straight_and_stable(writhed):
    twisted, _ = writhed
    st = twisted.steps[-1]
    force, moment = twisted.reaction("end")
    # straight twisted rod: M = C 2 pi n / L, T = EA stretch / L
    assert moment[0] == pytest.approx(C * 2 * np.pi * TURNS / L, rel=1e-9)
    assert force[0] == pytest.approx(bw.twist_tension(TURNS), rel=1e-6)
    assert bw.twist_tension(TURNS) > (moment[0] ** 2 / (4 * B))     # above Greenhill
    assert np.abs(st.r[:, 1:]).max() < 1e-5 * L


@pytest.mark.slow
def test_localized_writhing_meets_the_localizing_helix(writhed):
    _, result = writhed
    ref = localized_writhing(B, C, L, SLACK, 2 * np.pi * TURNS)
    force, moment = result.reaction("end")
    assert force[0] == pytest.approx(ref.tension, rel=1e-3)
    assert moment[0] == pytest.approx(ref.moment, rel=1e-3)
    s, t = tangents(result)
    theta = np.arccos(np.clip(t[:, 0], -1.0, 1.0))
    assert theta.max() == pytest.approx(ref.theta_max, rel=1e-3)
    # the whole profile theta(s) is the localizing helix's, whose loop the
    # imperfection holds near mid-length (it slides along the rod at almost
    # no cost: the shift is fitted)
    shift = minimize_scalar(lambda d: np.abs(theta - helix_angle(ref, s - d)).max(),
                            bounds=(-5.0, 5.0), method="bounded", options={"xatol": 1e-8})
    assert abs(shift.x) < 1.0
    assert shift.fun < 2e-3 * ref.theta_max
    # rotation absorbed by twist and by writhe; link = twist + writhe = 27
    top = result.topology(-1, per_element=16)
    gamma = C / B
    assert top.twist == pytest.approx(ref.m / gamma / (2 * np.pi), rel=1e-3)
    assert top.writhe == pytest.approx(2 * np.arccos(ref.c) / np.pi, rel=1e-3)
    assert top.link == pytest.approx(TURNS, abs=1e-6)
    assert top.twist + top.writhe == pytest.approx(top.link, abs=1e-6)


@pytest.mark.slow
def test_rigid_loading_path_is_stable_with_rising_tension(writhed):
    # under rigid loading the localizing branch grows out of the Greenhill
    # point with the tension rising (0.333 -> 0.390) and the writhe growing
    _, result = writhed
    T = np.array([result.reaction("end", k)[0][0] for k in range(1, len(result.steps))])
    W = np.array([result.topology(k, per_element=8).writhe for k in range(1, len(result.steps))])
    assert np.all(np.diff(T) > 0)
    assert np.all(np.diff(W) > 0)
    M0 = C * 2 * np.pi * TURNS / L
    assert T[0] == pytest.approx(M0 ** 2 / (4 * B), rel=0.02)
    # stable at every recorded step (the straight state it left had -22;
    # the sliding mode of the loop along the rod is soft: +-1e-8)
    low = np.array([st.lowest_eigenvalue for st in result.steps[1:]])
    assert np.all(low > -1e-6)
    # every step is an equilibrium, to rtol or to the residual's round-off
    # floor, evaluated afresh
    _, shorten = bw.build_rigid(96, 1e-3)
    p = Problem(shorten)
    for st in result.steps[1:]:
        assert st.relaxed_residual is None
        ev = p.evaluate(st.r, st.R, st.load_factor)
        rn, scale = p.residual_norm(ev), p.force_scale(ev)
        assert rn <= max(1e-10 * scale, p.round_off_floor(st.r, st.R, st.load_factor, ev))
        assert rn < 1e-6 * scale
        # a step accepted above rtol says so, with its floor
        assert (rn <= 1e-10 * scale) or (st.floor is not None and rn <= st.floor * scale)
