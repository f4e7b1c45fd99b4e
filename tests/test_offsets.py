"""Gap offsets (skfem_rod.augmented.adjust_offsets): a recorded equilibrium
holds the true distance between strands to the contact tolerance, also
where the centrelines dip below 2 eps between the slave points.

Scene: the squeezed loop of demos/squeezed_loop.py at the demo's small
size (24 elements, 12.5 eps long: the touching convex sides meet between
slave points), without crossing pairs, loaded 0 -> 1 -> 0 (about 7 s)."""
import numpy as np
import pytest

from helpers import load_demo
from skfem_rod import augmented
from skfem_rod.problem import Multipliers

demo = load_demo("squeezed_loop")


@pytest.fixture(scope="module")
def squeezed():
    return demo.solve(n_steps=8, n_elements=24)


def overlap(step, eps):
    return (2 * eps - step.contact.min_distance) / eps


def test_true_distance_within_the_tolerance_at_every_step(squeezed):
    """Measured: true overlaps 3.2e-4 to 6.2e-4 eps at the steps in contact,
    with offsets up to 0.1 eps (the cap): without them the slave points
    left the sides overlapping by up to 0.1 eps (below)."""
    res = squeezed["result"]
    assert res.converged, res.message
    c = res.rod.contact
    tol = c.tolerance
    touching = [st for st in res.steps if st.contact.s.size]
    assert len(touching) >= 3
    for st in touching:
        # overlapping by no more than the tolerance, and not standing open
        # where the offsets hold the strands apart either
        assert -tol <= overlap(st, c.radius) <= tol
        # the offsets did the work, within their cap
        off = st.contact.offset
        assert off.max() > 5 * tol * c.radius
        assert off.max() <= augmented.OVERLAP_FAIL * c.radius * (1 + 1e-12)
        # the law holds at the offset gaps: complementarity at the points
        assert np.all(st.contact.force > 0)
        assert np.all(np.abs(st.contact.gap) <= tol * c.radius)
    for st in res.steps:
        if not st.contact.s.size:
            assert st.contact.offset.size == 0


def test_offsets_follow_the_state_not_the_path(squeezed):
    """The offsets are set by the state (the dip between slave points), so
    the frictionless, elastic path 0 -> 1 -> 0 still passes through the same
    states up and down (to 10 x the Uzawa tolerance on positions, as the
    squeezed loop's own test) and ends where it started."""
    res, rod = squeezed["result"], squeezed["rod"]
    tol = rod.contact.tolerance * rod.contact.radius
    n = len(res.steps)
    for i in range(n):
        j = n - 1 - i
        assert res.steps[i].load_factor == res.steps[j].load_factor
        assert np.abs(res.steps[i].r - res.steps[j].r).max() < 10 * tol
    assert np.abs(res.steps[-1].r - res.steps[0].r).max() < 1e-10 * rod.length


def test_offsets_from_zero_at_every_step_are_the_states():
    """With the contact option ``offsets="state"`` every recorded step
    raises its offsets from 0, so they are a function of the state: the
    squeezed loop's path 0 -> 1 -> 0 passes through the same states up and
    down to 1e-3 of the Uzawa tolerance on positions (measured 8.5e-7 of
    it; carried offsets, the default, are lowered only where the strands
    stand open by more than the tolerance and remember the path: 0.10 of
    it, the offset 0.100 eps at the top against 0.090 from 0)."""
    rod = demo.build(n_elements=24)
    c = rod.contact
    rod.enable_contact(radius=c.radius, penalty=c.penalty, offsets="state")
    res = rod.solve(8, path=[0.0, 1.0, 0.0], snap="relax")
    assert res.converged, res.message
    tol = c.tolerance * c.radius
    n = len(res.steps)
    assert max(st.contact.offset.max(initial=0.0) for st in res.steps) > 5 * tol
    for i in range(n):
        j = n - 1 - i
        assert res.steps[i].load_factor == res.steps[j].load_factor
        assert np.abs(res.steps[i].r - res.steps[j].r).max() < 1e-3 * tol


def test_without_offsets_the_step_is_not_converged(monkeypatch):
    """Negative control: with no offset rounds the slave points alone leave
    the sides overlapping beyond the tolerance, and the solve stops there
    with the place and what to do, instead of recording the state."""
    monkeypatch.setattr(augmented, "OFFSET_ROUNDS", 0)
    out = demo.solve(n_steps=8, n_elements=24)
    res = out["result"]
    assert not res.converged
    assert "overlap" in res.message and "between slave points" in res.message
    assert "crossing" in res.message
    eps = res.rod.contact.radius
    tol = res.rod.contact.tolerance
    for st in res.steps:                       # what was recorded is right
        if st.contact.min_distance is not None and np.isfinite(st.contact.min_distance):
            assert overlap(st, eps) <= tol


def test_offsets_are_saved_and_carried_with_the_multipliers():
    m = Multipliers.zeros(4, friction=False)
    m.offset[:] = [0.0, 1e-3, 2e-3, 0.0]
    key = np.array([[0.1, 0.6, 0.05, 0.0, -1.0], [0.3, 0.9, 0.05, 0.0, -1.0]])
    m.rekey_crossing(key, np.array([1.0, 2.0]), np.array([4e-3, 5e-3]))
    saved = m.copy()
    m.offset[1] = 9.0
    m.crossing_offset[0] = 9.0
    assert saved.offset[1] == 1e-3 and saved.crossing_offset[0] == 4e-3
    # new keys by place: a pair within its carry radius of an old one takes
    # its offset, a new place starts at 0
    new = np.array([[0.31, 0.89, 0.05, 0.0, -1.0], [0.5, 0.2, 0.05, 0.0, -1.0]])
    saved.rekey_crossing(new, np.array([0.5, 0.0]))
    assert saved.crossing_offset.tolist() == [5e-3, 0.0]
    assert saved.nominal_penalty().offset.tolist() == saved.offset.tolist()


@pytest.mark.parametrize("uzawa_converged", [True, False])
def test_an_overlap_after_a_short_uzawa_loop_names_the_loop(uzawa_converged):
    """An overlap between slave points fails the step.  Where the Uzawa
    loop stopped short, the offsets were never raised (they are raised
    only once the slave points hold the tolerance), so the message names
    the loop and its figures and asks for more updates, not a finer
    sampling (measured: the knot tied with 12 slave points per element
    stopped at max_uzawa = 60, and the message asked to raise n_slave)."""
    from skfem_rod import Rod, Section, geometry
    from skfem_rod.problem import Problem, Report
    rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
    rod.clamp("start").enable_contact(radius=0.01, max_uzawa=7)
    problem = Problem(rod)
    rep = Report(True, uzawa_converged=uzawa_converged, uzawa=7,
                 uzawa_note="Uzawa stopped after 7 updates with penetration 1e-05",
                 min_distance=2 * 0.01 - 3e-5, min_distance_at=(0.25, 0.75))
    augmented.fail_overlap(problem, rep, 1e-3 * 0.01)
    assert not rep.converged
    assert "overlap by 0.003 eps between slave points (s = 0.25 and 0.75" in rep.reason
    if uzawa_converged:
        assert "raise n_slave" in rep.reason and "max_uzawa" not in rep.reason
    else:
        assert "Uzawa loop stopped short" in rep.reason
        assert "Uzawa stopped after 7 updates with penetration 1e-05" in rep.reason
        assert "raise max_uzawa (now 7)" in rep.reason and "n_slave" not in rep.reason
