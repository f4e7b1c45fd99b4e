"""Two-ply (demos/two_ply.py): a hairpin clamped at both ends (2 a = 4 eps
apart) whose apex is pulled along the axis and turned by one turn winds
into a two-ply with its plies in contact.  Pinned figures were measured
with the demo (32 elements, legs 0.8, 8 steps; docs/contact-scenes.md);
about 20-60 s."""

import numpy as np
import pytest

from helpers import load_demo as load

pytestmark = pytest.mark.slow    # a scene or a long run (fast tier: -m "not slow")


demo = load("two_ply")


@pytest.fixture(scope="module")
def ply():
    return demo.solve(turns=1.0, n_steps=8, n_elements=32, leg=0.8)


def test_two_ply_pinned_figures(ply):
    assert ply["converged"], ply["message"]
    rec = ply["records"]
    last = rec[-1]
    # the plies wind once around each other between the clamps and the fold
    # (the fold itself carries the missing 3 %)
    for r in rec:
        assert r["ply_turns"] == pytest.approx(r["turns"], abs=0.035)
    assert last["ply_turns"] == pytest.approx(0.9687, abs=2e-3)
    # contact appears at 0.375 turns and spreads along the plies
    n = [r["contacts"] for r in rec]
    assert n[:3] == [0, 0, 0] and all(k > 0 for k in n[3:])
    assert 12 <= last["contacts"] <= 20                     # measured 16
    # where the plies touch their axes are 2 eps apart (superhelix radius
    # eps); ply angle 10.8 deg, pitch 0.658
    eps = ply["rod"].contact.radius
    assert last["ply_radius"] == pytest.approx(eps, rel=2e-3)
    assert last["ply_angle_deg"] == pytest.approx(10.82, abs=0.05)
    assert last["pitch"] == pytest.approx(0.658, abs=0.005)
    # torque at the apex (measured 11.817) grows with the turns
    assert last["torque"] == pytest.approx(11.817, rel=2e-3)
    assert np.all(np.diff([r["torque"] for r in rec]) > 0)


def test_two_ply_contact_law_and_equilibrium(ply):
    res, rod = ply["result"], ply["rod"]
    tol = rod.contact.tolerance * rod.contact.radius
    for st in res.steps:
        c = st.contact
        assert c.penetration <= tol
        assert np.all(c.force > 0)
        assert np.all(np.abs(c.gap) <= tol)               # complementarity
        # global balance of moments: the contact forces are internal, the
        # apex force acts along the axis, so the support reactions balance
        total = sum(np.cross(st.r[n], F) + M for n, (F, M) in st.reactions.items())
        torque = abs(res.reaction(rod.length / 2, res.steps.index(st))[1][0])
        assert np.linalg.norm(total) <= 1e-8 * max(torque, 1.0)


def test_two_ply_link_is_twist_plus_writhe(ply):
    """Both ends are held and the rod never passes through itself: the
    closed ribbon keeps its linking number 0 and Tw + Wr = 0 at every step,
    while twist and writhe themselves change."""
    rec = ply["records"]
    for r in rec:
        assert abs(r["link_gauss"]) < 1e-9
        assert abs(r["link"]) < 1e-3
    assert abs(rec[-1]["writhe"]) > 0.1
