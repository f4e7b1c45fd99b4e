"""Coulomb self-friction in solved scenes: the rotational-friction scene
saturates at gamma_R F_N (demos/rotational_friction.py), Coulomb's law
holds at every converged step (bound, alignment in slip, dissipation >= 0),
and friction off means friction absent (no friction code runs, results equal
the frictionless solver's)."""
import numpy as np
import pytest

from skfem_rod.contact import friction_assembly

from helpers import coulomb_checks, load_demo


rf = load_demo("rotational_friction")


@pytest.fixture(scope="module")
def rotational():
    return rf.solve(n_elements=32, n_steps=8, phi=0.06)


@pytest.mark.slow
def test_rotational_friction_saturates_at_gamma_R_FN(rotational):
    """The torque transmitted through the contact stretch, measured from
    the equilibrium (end couple minus the twisting moment at the cut),
    rises with the end rotation and saturates at gamma_R F_N within 2 %
    (measured: 0.06 %)."""
    assert rotational["result"].converged, rotational["result"].message
    rows = rotational["rows"]
    T = np.array([r["transmitted"] for r in rows])
    bound = np.array([r["bound"] for r in rows])
    # the stretch is pressed: F_N carries most of P = 2 (the ramp the rest)
    FN = np.array([r["FN"] for r in rows])
    assert np.all((FN[1:] > 0.75 * 2.0) & (FN[1:] < 2.0))
    # rises, then stays on the bound once every point slips
    assert 0 < T[1] < T[2]
    saturated = [k for k, r in enumerate(rows) if r["stick"] == 0 and r["slip"] > 0]
    assert len(saturated) >= 5
    for k in saturated:
        assert T[k] == pytest.approx(bound[k], rel=0.02)
    assert np.abs(T[saturated] / bound[saturated] - 1).max() < 2e-3
    # never above the bound by more than the saturated tolerance
    assert np.all(T[1:] <= bound[1:] * 1.02)
    # only rotational friction acts: the tangential forces are zero
    for st in rotational["result"].steps[1:]:
        assert np.all(st.contact.force_T == 0)


@pytest.mark.slow
def test_rotational_scene_obeys_coulomb_at_every_step(rotational):
    res = rotational["result"]
    coulomb_checks(res, 0.0, rf.EPS)
    for st in res.steps[1:]:
        assert st.contact.penetration <= 1e-3 * rf.EPS


def test_friction_off_runs_no_friction_code_and_equals_frictionless(monkeypatch):
    """gamma_T = gamma_R = 0 is contact without friction: the friction
    assembler is never called (patched to fail) and the result equals the
    result of a rod with friction options left at their defaults, to 1e-12
    (they are the same code path)."""
    def boom(*a, **k):
        raise AssertionError("friction code ran with gamma_T = gamma_R = 0")
    monkeypatch.setattr(friction_assembly, "friction_work", boom)
    rod, _ = rf.build(gamma_R=0.0, n_elements=16, phi=0.03)
    rod.contact.mu_R = 123.0             # friction parameters are ignored
    res = rod.solve(n_steps=2)
    assert res.converged
    rod2, _ = rf.build(gamma_R=0.0, n_elements=16, phi=0.03)
    res2 = rod2.solve(n_steps=2)
    for a, b in zip(res.steps, res2.steps):
        assert np.abs(a.r - b.r).max() <= 1e-12
        assert np.abs(a.R - b.R).max() <= 1e-12
    assert res.steps[-1].contact.force_T is None


@pytest.mark.slow
def test_dissipated_energy_and_stick_slip_render(rotational, tmp_path):
    """The cumulative friction work never decreases along the path, and the
    render colours the contact markers by state (all slip: orange)."""
    res = rotational["result"]
    D = res.dissipated_energy()
    assert D.shape == (len(res.steps),)
    assert np.all(np.diff(D) >= 0) and D[-1] > 0
    import matplotlib.image as mpimg
    path = res.render(str(tmp_path / "rf.png"), window_size=(400, 300))
    img = mpimg.imread(path)[..., :3]
    orange = (img[..., 0] > 0.85) & (np.abs(img[..., 1] - 0.5) < 0.12) & (img[..., 2] < 0.25)
    green = (img[..., 1] > 0.5) & (img[..., 0] < 0.3) & (img[..., 2] < 0.3)
    assert orange.sum() > 50          # slipping points
    assert green.sum() == 0           # no sticking point at the last step


pf = load_demo("plectoneme_friction")


@pytest.fixture(scope="module")
def plectoneme_cycle():
    """The twisted rod with gamma_T = 0.3 at the demo's small size: snap into
    a loop at 1 turn, up to 1.5 turns and back to 0 (about a minute)."""
    return pf.solve(0.3, n_elements=16, turns=1.5, n_steps=6)


@pytest.mark.slow
def test_plectoneme_cycle_with_friction(plectoneme_cycle):
    res, rec = plectoneme_cycle["result"], plectoneme_cycle["records"]
    assert res.converged, res.message
    eps = res.rod.contact.radius
    # link = twist + writhe = applied turns at every step (no strand passage)
    for r in rec:
        assert r["link"] == pytest.approx(r["turns"], abs=1e-9)
    # Coulomb's law at every converged step, and dissipation >= 0
    coulomb_checks(res, 0.3, 0.0)
    D = res.dissipated_energy()
    assert np.all(np.diff(D) >= 0) and D[-1] > 0
    for st in res.steps:
        if st.contact.uzawa_converged:
            assert st.contact.penetration <= 1e-3 * eps
    # the snap and its hysteresis: straight at 0.75 turn (torque 2 pi C n / L)
    # and nearly so at 1 turn on the way up (clamped Greenhill: 0.99 turn),
    # still in the loop at 1 turn on the way down
    (nu, mu), (nd, md) = pf.branches(rec)
    k = np.argmin(np.abs(nu - 0.75))
    # (the lateral imperfection force 0.01 T bends it slightly: 8.6e-6)
    assert mu[k] == pytest.approx(2 * np.pi * pf.tw.GJ * 0.75 / 5.0, rel=1e-4)
    k_up, k_dn = np.argmin(np.abs(nu - 1.0)), np.argmin(np.abs(nd - 1.0))
    assert mu[k_up] > 0.95 * 2 * np.pi * pf.tw.GJ * 1.0 / 5.0
    assert md[k_dn] < 0.5 * mu[k_up]
    # back at zero turns: the straight rod again, no torque
    assert abs(rec[-1]["torque"]) < 1e-8 and rec[-1]["contacts"] == 0
    # the stability checks read the frictionless tangent (Problem.free_tangent):
    # the looped states' lowest eigenvalues are of the frictionless loop's
    # size (+1.5e-4 there), not the -9 to -18 of the symmetrized friction
    # tangent, which had every looped state pushed off as a saddle
    # A state the frictionless tangent calls a saddle is pushed off once and,
    # with friction, kept with its eigenvalue when the flow comes back to
    # it (solver.LoadStepper.snap, docs/stability.md): the log says so.  Since
    # the recorded states hold the true distance (gap offsets; before, they
    # overlapped by 0.025-0.073 eps between slave points) the top of the
    # cycle, 1.5 turns, is such a state (-0.162 measured); the other looped
    # states measure -9e-5 to +4e-5.
    looped = [(k, st) for k, st in enumerate(res.steps) if st.contact.force.size]
    assert looped
    for k, st in looped:
        lam = st.load_factor
        flagged = any(line.startswith(f"step to lam={lam:.6g}: unstable equilibrium")
                      for line in res.log)
        assert st.lowest_eigenvalue > (-1.0 if flagged else -1e-3), (k, lam)
    assert sum(st.lowest_eigenvalue < -1e-3 for _, st in looped) <= 1


@pytest.mark.slow
@pytest.mark.parametrize("gamma_T", [0.0, 0.3])
def test_uzawa_mode_newton_solves_converge_fast_without_cycles(monkeypatch, gamma_T):
    """Every Newton solve of the rotational-friction scene in the default
    (Uzawa) contact solve, rotational friction alone and with tangential
    friction too: no residual history 2-cycles; from the largest residual
    of a solve to the round-off floor (1e-8 here; about 1e-9 for this stiff
    rod) at most 6 iterations, with a superlinear step among them
    (``log(r_{k+1}/s) / log(r_k/s) >= 1.5``, ``s`` the largest residual: 2
    for a quadratic step) or a drop by 1e3.  (Coulomb's law on the
    rotational scene: the tests above; with both laws on, the tangential
    force is aligned with the slip only to the Uzawa friction tolerance:
    docs/friction.md.)"""
    from skfem_rod import newton as newton_module
    from helpers import spy_reports, two_cycles
    floor = 1e-8
    seen = spy_reports(monkeypatch, newton_module, "newton")
    rod, _ = rf.build(rf.EPS, 2.0, 0.06, 32)
    rod.enable_contact(gamma_R=rf.EPS, gamma_T=gamma_T)
    res = rod.solve(8)
    assert res.converged, res.message
    checked = 0
    for rep in seen:
        h = np.asarray(rep.history)
        if not rep.converged or h.size < 2:
            continue
        assert not two_cycles(h, floor), h
        top = int(np.argmax(h))
        below = np.flatnonzero(h[top:] <= floor)
        assert below.size, h
        k = top + below[0]
        assert k - top <= 6, h
        if k - top >= 2:
            x = np.log(h[top:k + 1] / h[top])
            q = [x[j] / x[j - 1] for j in range(2, x.size)]
            drops = h[top + 1:k + 1] / h[top:k]
            assert max(q, default=0.0) >= 1.5 or drops.min() <= 1e-3, h
        checked += 1
    assert checked >= 8


@pytest.mark.slow
def test_both_laws_slipping_forces_follow_the_slip_to_the_tolerance():
    """Coulomb's law at every converged step of the rotational-friction
    scene with both laws on (gamma_T = 0.3, gamma_R = eps), default
    friction tolerance: at every point that slips by more than the
    tolerance times its stick range ``mu gamma f_N`` (nominal compliance),
    the friction force's component across the slip is at most
    ``friction_tolerance`` of the bound.  Before the Uzawa loop checked it
    (it stopped on the multipliers' motion alone) forces ended up to 4
    degrees off slips of 0.1-0.7 stick ranges (sine 7e-2)."""
    rod, _ = rf.build(rf.EPS, 2.0, 0.06, 32)
    rod.enable_contact(gamma_R=rf.EPS, gamma_T=0.3)
    res = rod.solve(8)
    assert res.converged, res.message
    c0 = rod.contact
    tol = c0.friction_tolerance
    checked = 0
    for st in res.steps[1:]:
        c = st.contact
        assert c.uzawa_converged
        for gamma, mu, f, g, state in ((0.3, c0.mu_T, c.force_T, c.slip_T, c.state_T),
                                       (rf.EPS, c0.mu_R, c.force_R, c.slip_R, c.state_R)):
            bound = gamma * c.force
            gn = np.linalg.norm(g, axis=1)
            slip = (state == 2) & (gn > tol * mu * bound)
            if not slip.any():
                continue
            across = np.linalg.norm(np.cross(f[slip], g[slip]), axis=1) / gn[slip]
            assert np.all(across <= tol * bound[slip]), (across / bound[slip]).max()
            # on the cone, and dissipating
            assert np.allclose(np.linalg.norm(f[slip], axis=1), bound[slip], rtol=1e-12)
            assert np.all(np.sum(f[slip] * g[slip], axis=1) > 0)
            checked += int(slip.sum())
    assert checked >= 100
