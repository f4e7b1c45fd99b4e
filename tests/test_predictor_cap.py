"""Two Newton safeguards of :func:`skfem_rod.solver.solve`: the secant
predictor (same equilibria, fewer iterations on a smooth path) and the
clearance cap (no iterate carries a strand through another)."""
import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.solver import SolverOptions

from test_contact import SEC, hairpin


def _rollup(**options):
    sec = Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=0.8)
    rod = Rod(geometry.straight(1.0), sec, 6).clamp("start")
    rod.add_moment("end", [0.0, 0.0, 2 * np.pi], follower=False)
    return rod.solve(n_steps=8, **options)


def test_secant_predictor_reaches_the_same_equilibria_in_fewer_iterations():
    """Rolling a cantilever into a circle in 8 steps: the secant start
    (the last step's motion, scaled) gives every step's equilibrium to
    1e-10 and saves Newton iterations from the third step on (the first
    step has no secant).  The saving is the predictor's own, measured with
    plain Newton updates (``position_correction=False``): with the default
    position correction both starts need 1-2 iterations per step here."""
    plain = _rollup(position_correction=False)
    secant = _rollup(predictor="secant", position_correction=False)
    default = _rollup(predictor="secant")
    assert default.converged
    for a, b in zip(plain.steps, default.steps):
        assert np.abs(a.r - b.r).max() <= 1e-10
    assert plain.converged and secant.converged
    for a, b in zip(plain.steps, secant.steps):
        assert np.abs(a.r - b.r).max() <= 1e-10
    its_plain = sum(st.iterations for st in plain.steps[2:])
    its_secant = sum(st.iterations for st in secant.steps[2:])
    assert its_secant < its_plain


def _pressed(F, **options):
    eps = SEC.radius
    rod = Rod(hairpin(eps, 4 * eps), SEC, 40)
    rod.clamp("start").add_force("end", [0.0, -F, 0.0])
    rod.enable_contact()
    res = rod.solve(n_steps=2, **options)
    return res, res.steps[-1].r[rod.node("end")][1] / eps, \
        [st.r[rod.node("end")][1] / eps for st in res.steps]


@pytest.mark.slow
def test_clearance_cap_keeps_a_pressed_leg_on_the_other_side():
    """A hairpin whose free leg (4 eps from the clamped one) is pressed by
    a large force in two steps: the first Newton update, with no contact in
    the tangent yet, moves the leg far beyond the other one.  Uncapped, the
    solve converges to the leg *through* the clamped leg (tip at y < 0);
    with the clearance cap (the default) every iterate moves the legs
    toward each other by at most half their clearance and the leg comes to
    rest on the other one (tip at y = 2 eps to the Uzawa tolerance).
    Uncapped, the passage is still never reported: the full first step is
    not accepted (its Newton solve either converges with the leg through
    the other and is refused by the true-distance check, an overlap of
    2 eps between slave points, or does not converge: measured since the
    search keeps master elements at kinks), it is cut, and every recorded
    step has the leg on the right side (it ended at y < 0 before the
    true-distance check existed)."""
    res, y, ys = _pressed(3.0, clearance_cap=False)
    assert any("step to lam=0.5 (t=0.5) failed" in line
               or "the strands overlap by 2 eps" in line for line in res.log)
    assert min(ys) > 1.9                      # the tip rests on the other leg
    assert res.converged and y == pytest.approx(2.0, abs=0.03)
    res, y, _ = _pressed(3.0)
    assert not any("failed" in line or "between slave points" in line for line in res.log)
    assert res.converged, res.message
    assert y == pytest.approx(2.0, abs=0.03)
    assert res.steps[-1].contact.penetration <= 1e-3 * SEC.radius


def test_options_are_checked():
    with pytest.raises(ValueError, match="predictor must be 'none' or 'secant'"):
        SolverOptions(predictor="linear")
    with pytest.raises(ValueError, match="clearance_cap must be true or false"):
        SolverOptions(clearance_cap=1)


def test_naturally_straight_rod_started_bent_relaxes_to_straight():
    """``natural="straight"``: the shape is only the start.  A cantilever
    started as a quarter circle, unloaded, must come back straight along its
    clamped tangent at step 0 (the equilibrium solve at load factor 0), with
    zero stress resultants; a rod whose natural shape is the arc stays put."""
    sec = Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=0.8)
    arc = geometry.arc(2 / np.pi, np.pi / 2)                 # length 1, tangent x at s = 0
    rod = Rod(arc, sec, 8, natural="straight").clamp("start")
    res = rod.solve(1)
    assert res.converged, res.message
    s = np.linspace(0.0, 1.0, 11)
    f = res.evaluate(s, 0)
    assert np.abs(f["r"] - np.c_[s, 0 * s, 0 * s]).max() <= 1e-9
    assert np.abs(f["m"]).max() <= 1e-8 and np.abs(f["n"]).max() <= 1e-8
    curved = Rod(arc, sec, 8).clamp("start").solve(1)
    assert np.abs(curved.steps[0].r - curved.rod.r0).max() == 0.0
    with pytest.raises(ValueError, match="natural must be 'reference' or 'straight'"):
        Rod(arc, sec, 8, natural="curved")


def test_solve_from_a_given_start_state():
    """``start=``: a cantilever loaded in two steps, then solved again from
    the loaded state with the load held (path 0 -> 0.5 of a doubled load):
    step 0 is an equilibrium solve that stays where the start was (it is
    in equilibrium under the constant preload); bad start values are
    refused with the parameter named."""
    sec = Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=0.8)
    rod = Rod(geometry.straight(1.0), sec, 6).clamp("start")
    rod.add_force("end", [0.0, 2.0, 0.0])
    first = rod.solve(2)
    held = Rod(geometry.straight(1.0), sec, 6).clamp("start")
    held.add_force("end", [0.0, 2.0, 0.0], constant=True)
    second = held.solve(1, start=first)
    assert second.converged, second.message
    assert np.abs(second.steps[0].r - first.steps[-1].r).max() <= 1e-10
    again = held.solve(1, start=(first.steps[-1].r, first.steps[-1].R))
    assert np.abs(again.steps[-1].r - second.steps[-1].r).max() == 0.0
    with pytest.raises(ValueError, match=r"start: r must have shape \(19, 3\)"):
        held.solve(1, start=(first.steps[-1].r[:-1], first.steps[-1].R[:-1]))
    with pytest.raises(ValueError, match="start must be a Result or a pair"):
        held.solve(1, start=3.0)
    with pytest.raises(ValueError, match="start: R must hold rotation matrices"):
        held.solve(1, start=(first.steps[-1].r, 2 * first.steps[-1].R))


def test_start_from_a_result_carries_the_contact_multipliers():
    """A pressed hairpin solved again from its converged Result: the normal
    multipliers come with it (lambda = f_N at the active slave points), so
    step 0 needs no Uzawa update and stays within the contact tolerance of
    the start; from bare ``(r, R)`` Uzawa starts again from zero."""
    eps = SEC.radius
    rod = Rod(hairpin(eps, 4 * eps), SEC, 40)
    rod.clamp("start").add_force("end", [0.0, -0.6, 0.0], constant=True)
    rod.enable_contact()
    first = rod.solve(2)
    again = rod.solve(1, start=first)
    assert again.converged and again.steps[0].contact.uzawa == 0
    assert np.abs(again.steps[0].r - first.steps[-1].r).max() <= 1e-3 * eps
    bare = rod.solve(1, start=(first.steps[-1].r, first.steps[-1].R))
    assert bare.steps[0].contact.uzawa >= 1


def test_clearance_check_sees_every_pair_that_can_close_too_far():
    """``relax.clearance_ok`` on the hairpin (legs 4 eps apart, clearance
    2 eps): both legs moved toward each other by 0.6 eps close the gap by
    1.2 eps, more than half the clearance, so the move is refused; by 0.4
    eps each (0.8 eps) it is allowed; a rigid translation by 10 eps is
    allowed (no relative motion)."""
    from skfem_rod.relax import clearance_ok
    eps = SEC.radius
    rod = Rod(hairpin(eps, 4 * eps), SEC, 40).enable_contact()
    r0 = rod.r0
    side = np.where(r0[:, 1] > 2 * eps, -1.0, 1.0)          # free leg down, other leg up
    legs = np.abs(r0[:, 1] - 2 * eps) > 1.9 * eps
    bump = np.where(legs, np.sin(np.pi * np.clip(r0[:, 0], 0, 0.5) / 0.5) ** 2, 0.0)
    for step, ok in ((0.6, False), (0.4, True)):           # smooth: no shear along a leg
        r1 = r0.copy()
        r1[:, 1] += step * eps * side * bump
        assert clearance_ok(rod, r0, r1) is ok
    assert clearance_ok(rod, r0, r0 + [10 * eps, 0.0, 0.0])


def test_slope_search_shortens_overshooting_updates_not_the_answer(monkeypatch):
    """Option ``slope_search`` (frictionless contact): a Newton update whose
    energy slope ``G . dy`` at the trial has turned positive beyond half the
    slope at the start overshot the minimum of the energy along it, and is
    shortened.  On the pressed hairpin the contact iterations overshoot (a
    leg lands deep in the other and the penalty throws it back): the search
    cuts them, and the solve reaches the same equilibrium as without (1e-8
    of the radius)."""
    from skfem_rod import problem as problem_mod
    cuts = []
    orig = problem_mod.Problem.__init__

    def init(self, rod):
        orig(self, rod)
        cuts.append(self.calls)
    monkeypatch.setattr(problem_mod.Problem, "__init__", init)
    plain, y0, _ = _pressed(3.0)
    assert cuts[-1]["slope_cuts"] == 0
    res, y1, _ = _pressed(3.0, slope_search=True)
    assert cuts[-1]["slope_cuts"] > 0
    assert plain.converged and res.converged, res.message
    for a, b in zip(plain.steps, res.steps):
        assert a.load_factor == b.load_factor
        assert np.abs(a.r - b.r).max() <= 1e-8 * SEC.radius
    # validated as every option
    with pytest.raises(ValueError, match="slope_search must be true or false"):
        SolverOptions(slope_search="yes")
