"""Squeezed loop (demos/squeezed_loop.py): an open ring clamped at both ends
is squeezed at its quarter points until its sides touch, then released
(load path 0 -> 1 -> 0): contact appears and disappears, the contact law
holds at every converged step, and the frictionless, elastic rod comes back
exactly to its reference state (10-60 s).  With crossing contact on
(20-90 s) the point pairs at the closest points of the touching sides hold
the true overlap between slave points to the tolerance
(docs/crossing-contact.md); point-to-curve pairs at Gauss points alone
left 0.012 eps and now hold it with gap offsets."""

import numpy as np
import pytest

from helpers import load_demo as load

pytestmark = pytest.mark.slow    # a scene or a long run (fast tier: -m "not slow")


demo = load("squeezed_loop")


@pytest.fixture(scope="module")
def squeezed():
    return demo.solve(n_steps=16, force=20.0)


@pytest.fixture(scope="module")
def squeezed_crossing():
    return demo.solve(n_steps=16, force=20.0, crossing=True)


def test_contact_appears_and_disappears(squeezed):
    assert squeezed["converged"], squeezed["message"]
    rec = squeezed["records"]
    n = np.array([r["contacts"] for r in rec])
    lam = np.array([r["load_factor"] for r in rec])
    assert lam.max() == 1.0 and lam[-1] == 0.0
    on = np.flatnonzero(n > 0)
    # zero, then positive on one unbroken stretch around the peak, then zero
    assert n[0] == 0 and n[-1] == 0 and on.size >= 3
    assert np.array_equal(on, np.arange(on[0], on[-1] + 1))
    assert lam[on[0]] < 1.0 and lam[on[-1]] < 1.0 and np.argmax(lam) in on
    # the quarter points approach while loading up to contact, and recede
    # while unloading after it
    d = np.array([r["quarter_distance"] for r in rec])
    assert np.all(np.diff(d[:on[0] + 1]) < 0) and np.all(np.diff(d[on[-1]:]) > 0)
    eps = squeezed["rod"].contact.radius
    assert np.all(d[on] < 2.1 * eps) and np.all(d[n == 0] > 4 * eps)


def test_contact_law_at_every_step(squeezed):
    rod = squeezed["rod"]
    tol = rod.contact.tolerance * rod.contact.radius
    for st in squeezed["result"].steps:
        c = st.contact
        assert c.penetration <= tol                       # no penetration beyond tolerance
        assert np.all(c.force > 0)                        # f_N >= 0 (active: > 0)
        assert np.all(np.abs(c.gap) <= tol)               # complementarity: on contact
        assert c.uzawa_converged


def test_back_to_the_start(squeezed):
    """Frictionless and elastic: path independent.  At the end of 0 -> 1 -> 0
    the rod is in its reference state; the peak strain energy is 9.5."""
    res, rod = squeezed["result"], squeezed["rod"]
    first, last = res.steps[0], res.steps[-1]
    assert max(s.energy for s in res.steps) > 9.0
    assert last.energy < 1e-12
    assert np.abs(last.r - first.r).max() < 1e-10 * rod.length
    assert np.abs(last.R - first.R).max() < 1e-10
    # loading and unloading pass through the same states: to round-off
    # without contact, to within the contact tolerance (10 x the Uzawa
    # tolerance on positions, 1e-3 on the contact force) in contact
    rec = squeezed["records"]
    tol = rod.contact.tolerance * rod.contact.radius
    for i, r in enumerate(rec):
        j = len(rec) - 1 - i
        assert r["load_factor"] == rec[j]["load_factor"]
        dr = np.abs(res.steps[i].r - res.steps[j].r).max()
        if r["contacts"] == 0 and rec[j]["contacts"] == 0:
            assert dr < 1e-9 * rod.length
        else:
            assert r["contacts"] == rec[j]["contacts"]
            assert dr < 10 * tol
            assert r["contact_force"] == pytest.approx(rec[j]["contact_force"], rel=1e-3)


def test_true_overlap_within_the_tolerance(squeezed, squeezed_crossing):
    """The true smallest distance between the sides (closest points, both
    parameters free, recorded per step) never falls below 2 eps by more than
    the contact tolerance, with crossing contact (the point pairs act at the
    closest points) and with Gauss-point pairs alone: there the touching
    convex sides dip between slave points, by 0.012 eps measured before the
    gap offsets (augmented.adjust_offsets), and the slave points hold the
    contact at 2 eps + offset (offsets up to 0.0215 eps measured)."""
    def overlap(sol):
        eps = sol["rod"].contact.radius
        return np.array([(2 * eps - st.contact.min_distance) / eps
                         for st in sol["result"].steps])
    tol = squeezed["rod"].contact.tolerance
    eps = squeezed["rod"].contact.radius
    assert squeezed_crossing["converged"], squeezed_crossing["message"]
    for sol in (squeezed_crossing, squeezed):
        over = overlap(sol)
        assert over.max() <= tol, over
        assert over.max() > -0.1                 # the sides do touch
    offsets = [st.contact.offset.max(initial=0.0) for st in squeezed["result"].steps]
    assert max(offsets) > 5 * tol * eps          # the dip the slave points hold


def test_back_to_the_start_with_crossing_contact(squeezed_crossing):
    """Point pairs derive from a potential too: the path 0 -> 1 -> 0 ends in
    the reference state, and loading and unloading pass through the same
    states to within 10 x the Uzawa tolerance on positions."""
    res, rod = squeezed_crossing["result"], squeezed_crossing["rod"]
    first, last = res.steps[0], res.steps[-1]
    assert last.energy < 1e-12
    assert np.abs(last.r - first.r).max() < 1e-10 * rod.length
    tol = rod.contact.tolerance * rod.contact.radius
    lam = [st.load_factor for st in res.steps]
    for i in range(len(lam)):
        j = len(lam) - 1 - i
        assert lam[i] == lam[j]
        assert np.abs(res.steps[i].r - res.steps[j].r).max() < 10 * tol
