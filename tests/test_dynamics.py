"""Implicit pseudo-dynamics path following (``rod.solve(..., dynamics=True)``,
skfem_rod/dynamics.py): the recorded states are static equilibria (viscous
term off), the damped phases end on the load stepper's equilibrium where
that one is unique, and a twisted rod under tension leaves the straight
branch at Greenhill's threshold by damped steps, without the gradient
flow."""
import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.dynamics import DynamicsLog, in_contact, morse_index
from skfem_rod.problem import Problem

from helpers import load_demo

demo = load_demo("twisted_rod")


def section():
    return Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=0.8)


def cantilever(n=8):
    rod = Rod(geometry.straight(1.0), section(), n)
    rod.clamp("start")
    rod.add_force("end", [0.0, 3.0, 1.0])
    return rod


def equilibrium_residual(rod, step):
    """Relative residual on the free dofs of a recorded state, evaluated by
    a fresh problem (no viscous term)."""
    p = Problem(rod)
    ev = p.evaluate(step.r, step.R, step.load_factor)
    return p.residual_norm(ev) / p.force_scale(ev)


def test_dynamics_options_are_validated():
    rod = cantilever(2)
    with pytest.raises(ValueError, match="dynamics=True and snap='relax' exclude each other"):
        rod.solve(1, dynamics=True, snap="relax")
    with pytest.raises(ValueError, match="dynamics must be true or false"):
        rod.solve(1, dynamics="yes")
    with pytest.raises(ValueError, match="dynamics_dt must be a finite number > 0"):
        rod.solve(1, dynamics=True, dynamics_dt=0.0)
    with pytest.raises(ValueError, match="dynamics_tol"):
        rod.solve(1, dynamics=True, dynamics_tol=2.0)
    with pytest.raises(ValueError, match="max_damped_steps"):
        rod.solve(1, dynamics=True, max_damped_steps=0)


def test_smooth_path_is_load_stepping():
    """Where every static step converges to a stable equilibrium the
    pseudo-dynamics is load stepping: the same states to round-off and no
    damped step."""
    ref = cantilever().solve(4)
    res = cantilever().solve(4, dynamics=True)
    assert ref.converged and res.converged, res.message
    assert isinstance(res.dynamics, DynamicsLog)
    assert res.dynamics.damped_steps == 0
    assert len(res.steps) == len(ref.steps)
    for a, b in zip(ref.steps, res.steps):
        assert np.abs(a.r - b.r).max() < 1e-13
        assert np.abs(a.R - b.R).max() < 1e-13


@pytest.mark.slow
def test_damped_phases_end_on_the_static_equilibrium():
    """Static steps that fail (Newton limited to 3 iterations) are replaced
    by damped phases; each phase ends, after the polish with the viscous
    term off, on the equilibrium of the load factor it reached, which for a
    cantilever is unique: the end state equals load stepping's to 1e-9, and
    every recorded state is an equilibrium to the solver's tolerance."""
    ref = cantilever().solve(4)
    rod = cantilever()
    res = rod.solve(1, dynamics=True, max_iterations=3)
    assert res.converged, res.message
    log = res.dynamics
    assert log.damped_steps > 0
    assert sum(log.damped_per_record) == log.damped_steps
    assert len(log.kind) == len(log.newton) == len(log.accepted)
    assert res.steps[-1].load_factor == 1.0
    assert np.abs(res.steps[-1].r - ref.steps[-1].r).max() < 1e-9
    for st in res.steps:
        assert equilibrium_residual(rod, st) < 1e-9
        assert st.flow_steps == 0                      # no gradient flow


def _refused_above(monkeypatch, cap, wait_max):
    """The cantilever's damped phase (Newton held to 3 iterations, first
    ``dt`` 1e-4, 200 damped steps at most) with every damped step at a
    ``dt`` above ``cap`` times the first refused, and the controller's
    longest wait ``wait_max`` easy steps: (accepted, refused) tries."""
    from skfem_rod import dynamics
    monkeypatch.setattr(dynamics, "EASY_WAIT_MAX", wait_max)
    damped = dynamics.PseudoDynamics.damped
    count = {"accepted": 0, "refused": 0}

    def refusing(self, r, R, t, t_new, dt, descent=None):
        out = damped(self, r, R, t, t_new, dt, descent=descent)
        if dt > cap * self.dt0:
            count["refused"] += 1
            out[2].reason = "refused by the test"
            return r, R, out[2], False, out[4]
        count["accepted"] += bool(out[3])
        return out
    monkeypatch.setattr(dynamics.PseudoDynamics, "damped", refusing)
    res = cantilever().solve(1, dynamics=True, max_iterations=3, dynamics_dt=1e-4,
                             max_damped_steps=200)
    assert not res.converged and "no equilibrium after 200 damped steps" in res.message
    return count["accepted"], count["refused"]


def test_a_refused_doubling_makes_dt_wait_longer(monkeypatch):
    """Where every doubling of ``dt`` beyond some size fails (as in the
    frictional plectoneme at rest at 1.97 turns, where Newton failed at
    twice the ``dt`` it had just managed, about once in three tries), the
    easy steps ``dt`` waits for before it doubles again double after each
    refusal at a freshly doubled ``dt``, up to ``EASY_WAIT_MAX`` = 8: a
    refused try for every 8 accepted steps, not for every 2."""
    accepted, refused = _refused_above(monkeypatch, 2.0, 8)
    assert accepted == 200 and refused <= accepted / 8 + 5
    accepted, refused = _refused_above(monkeypatch, 2.0, 2)      # the rule before
    assert accepted == 200 and refused >= accepted / 3


@pytest.fixture(scope="module")
def twisted():
    """Contact-free twisted rod under tension (L = 10 lambda, 16 elements,
    imperfection 1e-2 T at mid-length), 0.1 turn per step to 2 turns."""
    rod = demo.straight_rod(10.0, 16, turns=2.0)
    s = rod.mesh.s_nodes
    rod.add_force(float(s[np.argmin(np.abs(s - 5.0))]), [0.0, 0.01, 0.0], constant=True)
    recs = []
    res = rod.solve(20, dynamics=True,
                    callback=lambda result, k: recs.append(result.reaction("end", k)[1][0]))
    return rod, res, np.array(recs)


@pytest.mark.slow
def test_twisted_rod_leaves_the_straight_branch_at_greenhill(twisted):
    """Static steps follow the straight twisted branch (M = GJ 2 pi n / L) up
    to the clamped Greenhill threshold (1.670 turns for L = 10 lambda); the
    static step past it converges to the now unstable straight state, and
    the damped steps (pushed off along the unstable mode) take the rod into
    the buckled, stable state on the other side: the torque drops, by damped
    steps, without the gradient flow."""
    rod, res, torque = twisted
    assert res.converged, res.message
    n = np.array([st.load_factor for st in res.steps]) * 2.0
    x = np.array([st.r[rod.node("end"), 0] for st in res.steps])
    short = x[0] - x
    n_c = demo.greenhill_factor(10.0) * 2 * 10.0 / (demo.GJ * 2 * np.pi)
    assert n_c == pytest.approx(1.670, abs=1e-3)
    straight = n < n_c - 0.05
    assert np.allclose(torque[straight], demo.GJ * 2 * np.pi * n[straight] / 10.0, rtol=2e-3)
    first = int(np.argmax(short > 0.1))
    assert n[first - 1] < n_c <= n[first] + 1e-9
    assert torque[first] < torque[first - 1]             # the snap: the torque drops
    log = res.dynamics
    assert log.damped_steps > 0
    assert log.damped_per_record[first - 1] > 0          # that step was damped
    assert all(st.flow_steps == 0 for st in res.steps)


@pytest.mark.slow
def test_twisted_rod_records_stable_equilibria(twisted):
    """Every recorded state is an equilibrium with the viscous term off
    (relative residual below 1e-9) and stable (no negative eigenvalue of
    the symmetrized tangent)."""
    rod, res, _ = twisted
    p = Problem(rod)
    for st in res.steps:
        assert equilibrium_residual(rod, st) < 1e-9
        assert morse_index(p, st.r, st.R, st.load_factor) == 0


@pytest.mark.slow
@pytest.mark.parametrize("contact_solve", ["uzawa", "newton"])
def test_twisted_rod_snaps_into_a_loop_as_the_reference(contact_solve):
    """The contact scene of tests/test_twisted_rod.py (L = 10 lambda, contact
    radius 0.1 lambda, 36 elements, 0.1 turn per step) to 1.9 turns with
    pseudo-dynamics instead of the gradient flow: the rod leaves the
    straight branch at 1.7 turns (torque 1.91 sqrt(BT), as the reference
    before its snap) and snaps into a loop closed by contact at 1.8 turns
    with the torque of the reference, 0.89 sqrt(BT) (gradient flow: 1.91 ->
    0.89 at 1.8 turns), all by damped steps, no gradient-flow step.  The
    damped steps' contact solve is either the Uzawa loop or the generalized
    Newton (the normal multipliers as unknowns inside every damped step)."""
    rod = demo.build(10.0, 36, 0.1, 1.9, 0.01, 0.01)
    recs = []
    res = rod.solve(19, dynamics=True, contact_solve=contact_solve,
                    callback=lambda result, k: recs.append(demo.record(result, k, 1.9)))
    assert res.converged, res.message
    n = np.array([r["turns"] for r in recs])
    tq = np.array([r["torque"] for r in recs])
    k17, k18 = int(np.argmin(np.abs(n - 1.7))), int(np.argmin(np.abs(n - 1.8)))
    assert recs[k17]["contacts"] == 0 and recs[k18]["contacts"] > 0
    assert tq[k17] == pytest.approx(1.913, abs=0.01)
    assert tq[k18] == pytest.approx(0.89, abs=0.02)
    assert tq[k18] < 0.6 * tq[k17]
    assert all(r["flow_steps"] == 0 for r in recs)
    assert res.dynamics.damped_steps > 0
    tol = rod.contact.tolerance * rod.contact.radius
    for r, st in zip(recs, res.steps):
        assert st.contact.penetration <= tol
        assert r["link"] == pytest.approx(r["turns"], abs=1e-3)     # no strand passage


def _hairpin(eps=0.05, gap=0.2, contact=True):
    """A rod bent into a hairpin: two straight arms 1 long, ``(2 + gap)
    eps`` apart, joined by a half circle; contact radius ``eps``."""
    a = (1.0 + 0.5 * gap) * eps

    def r_of_s(s):
        th = np.clip((s - 1.0) / a, 0.0, np.pi)
        arm2 = np.clip(s - 1.0 - np.pi * a, 0.0, None)
        return np.c_[np.minimum(s, 1.0) + a * np.sin(th) - arm2, a - a * np.cos(th), 0 * s]

    rod = Rod(geometry.curve(r_of_s, 2.0 + np.pi * a), section(), 24)
    rod.clamp("start")
    if contact:
        rod.enable_contact(radius=eps)
    return rod


@pytest.mark.parametrize("contact", [True, False])
def test_a_push_off_a_saddle_does_not_carry_a_strand_into_another(contact):
    """A push along a mode that moves one arm of a hairpin onto the other
    (0.2 eps apart) by 2 eps: with contact on it is halved until the
    strands' true overlap is at most ``OVERLAP_FAIL`` = 0.1 eps, the most
    a converged state may have (to 0.25 eps: an overlap of 0.05 eps);
    without contact it is the full
    2 eps.  Pushes of several radii (sizes doubling after each push that
    did not get away) once left the frictional plectoneme's strands
    0.58 eps into each other."""
    from skfem_rod.contact.crossing import min_distance
    eps = 0.05
    rod = _hairpin(eps, contact=contact)
    p = Problem(rod)
    r, R = rod.r0, rod.R0
    mode = np.zeros((rod.r0.shape[0], 6))
    mode[r[:, 1] < 0.5 * eps, 1] = 1.0                 # the first arm, towards the second
    mode = p.to_basis(mode.ravel())
    r1, _ = p.push(r, R, mode, 2.0 * eps)
    moved = np.abs(r1 - r).max()
    if contact:
        assert moved == pytest.approx(0.25 * eps)
        md = min_distance(p.mesh, r1, eps, rod.contact.exclusion).distance
        assert md == pytest.approx(2 * eps - 0.05 * eps, rel=1e-6)
    else:
        assert moved == pytest.approx(2.0 * eps)


def _twisted_saddle(radius, gamma_T=0.0):
    """The straight rod (L = 10 lambda, 16 elements) twisted by 2 turns,
    past Greenhill's threshold: a saddle with no contact force; contact of
    ``radius`` on.  Returns the rod, its LoadStepper, a PseudoDynamics and
    the sections' rotations."""
    from skfem_rod.dynamics import PseudoDynamics
    from skfem_rod.options import SolverOptions
    from skfem_rod.rotations import expm
    from skfem_rod.solver import LoadStepper
    rod = demo.straight_rod(10.0, 16, turns=2.0)
    rod.enable_contact(radius=radius, gamma_T=gamma_T)
    S = LoadStepper(rod, SolverOptions(dynamics=True))
    dyn = PseudoDynamics(S, lambda t: t, np.array([0.0, 1.0]))
    R = np.array([expm(np.array([2 * np.pi * 2.0 * si / 10.0, 0.0, 0.0])) @ R0
                  for si, R0 in zip(rod.mesh.s_nodes, rod.R0)])
    return rod, S, dyn, R


@pytest.mark.parametrize("gamma_T", [0.3, 0.0])
def test_without_contact_a_saddle_stays_a_saddle_after_a_push(gamma_T):
    """The straight rod twisted past Greenhill's threshold is a saddle by
    the frictionless tangent the stability checks read.  With friction that
    test is only sufficient where contact is (friction may hold a state the
    frictionless rod would leave): there a state found again after one push
    in the load step is kept.  This saddle has no contact force, so friction
    cannot hold it: it stays a saddle after the push, with friction or
    without.  (Before the rule asked for contact, the frictional
    plectoneme recorded the pushed Greenhill saddle at 1.25 turns as an
    equilibrium, x_end 0.9976, no contact.)"""
    rod, S, dyn, R = _twisted_saddle(0.01, gamma_T)
    assert morse_index(S.problem, rod.r0, R, 1.0) > 0
    assert dyn.unstable_at(rod.r0, R, 1.0)
    assert not in_contact(S.problem, rod.r0, R, 1.0)
    dyn.push(rod.r0, R, 1.0)
    assert dyn.pushed_with_friction == (gamma_T > 0)
    assert dyn.unstable_at(rod.r0, R, 1.0)


def test_in_contact_sees_the_forces_of_a_pressed_hairpin():
    """``in_contact`` (the condition of the frictional and held-saddle
    rules): the hairpin's arms 0.2 eps apart carry no contact force; with
    the first arm moved 0.4 eps onto the second (0.2 eps into it) they do;
    without contact there is none."""
    eps = 0.05
    rod = _hairpin(eps)
    p = Problem(rod)
    pressed = rod.r0.copy()
    pressed[rod.r0[:, 1] < 0.5 * eps, 1] += 0.4 * eps
    assert not in_contact(p, rod.r0, rod.R0, 0.0)
    assert in_contact(p, pressed, rod.R0, 0.0)
    assert not in_contact(Problem(_hairpin(eps, contact=False)), pressed, rod.R0, 0.0)


@pytest.mark.parametrize("radius", [0.01, 1.0])
def test_a_saddle_the_flow_comes_back_to_from_a_capped_push_is_kept(radius):
    """The straight rod twisted past Greenhill's threshold, pushed along its
    unstable mode by half the contact radius: 0.005 moves the rod that far
    (radius 0.01); 0.5 is held to 0.066 by the 0.1 rad rotation limit
    (radius 1), and a larger push would move no farther.  A state at rest
    closer to the saddle than the push put it counts as having come back
    (then the saddle is held, not left) only after such a capped push; a
    smaller push is doubled instead, and a state farther away has left.
    Held or not, this saddle has no contact force: it stays a saddle."""
    rod, S, dyn, R = _twisted_saddle(radius)
    saddle = rod.r0
    assert not dyn.came_back(saddle)                     # no push yet
    r1, _ = dyn.push(saddle, R, 1.0)
    moved = np.abs(r1 - saddle).max()
    assert dyn.pushed_by == moved
    if radius == 1.0:
        assert dyn.push_capped and moved == pytest.approx(0.0665, abs=1e-3)
    else:
        assert not dyn.push_capped and moved == pytest.approx(0.5 * radius)
    assert dyn.came_back(saddle + 0.5 * (r1 - saddle)) == dyn.push_capped
    assert not dyn.came_back(saddle + 2.0 * (r1 - saddle))
    # held: kept only where contact holds it; this saddle has no contact force
    dyn.held = True
    assert dyn.unstable_at(saddle, R, 1.0)
