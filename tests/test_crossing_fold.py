"""A crossing pair's minimum born or vanishing at a fold of the distance
(skfem_rod.contact.crossing: the fold reading of the weight).

The fixture is recorded from the frictional plectoneme (100 elements,
gamma_T = 0.3, smooth contact curve) at 1.95 turns: the contact curve's
positions at a converged damped state (``start``) and after the next
Newton update (``update``).  Along ``start + a (update - start)`` a
minimum of the distance between the plies is born at ``a`` = 1e-13, a
tenth of an element from a node of both strands.  Read from the second
derivatives blended across the nodes, it had ``sin^2 beta`` 7 times the
threshold's and weight 1 the moment it existed; the damped steps there
failed at every ``dt`` (docs/crossing-contact.md, section 4).  The
tangent of the fold reading is checked against central differences in
tests/test_crossing.py (``test_fold_reading_*``): here, close to the fold,
the weight moves over state changes of 1e-9 and the minimum's own solve
limits central differences to about 1e-5."""
from pathlib import Path

import numpy as np
import pytest

from skfem_rod.contact import crossing
from skfem_rod.contact.crossing import PairThreshold, crossing_pairs
from skfem_rod.contact.curve import CurveMesh

DATA = Path(__file__).with_name("data") / "plectoneme_fold.npz"
RADIUS = 0.025
EXCLUSION = np.pi * RADIUS
THRESHOLD = PairThreshold(min_angle=np.radians(15.0), n_slave=3, tolerance=1e-3)
PLACE = (0.15, 0.85)                    # the crossing's place (s, s_bar)


@pytest.fixture(scope="module")
def path():
    d = np.load(DATA)
    mesh = CurveMesh(np.arange(400).reshape(100, 4), np.linspace(0.0, 1.0, 101))
    start, update = d["start"], d["update"]
    return mesh, lambda a: start + a * (update - start)


def _at(mesh, r, held=None):
    cp = crossing_pairs(mesh, r, RADIUS, EXCLUSION, threshold=THRESHOLD, held=held)
    k = np.flatnonzero((np.abs(cp.s - PLACE[0]) < 0.01) & (np.abs(cp.s_bar - PLACE[1]) < 0.01))
    return cp, k


def _weight(mesh, r):
    cp, k = _at(mesh, r)
    return float(cp.weight[k].sum())


def _largest_step(mesh, at, a0, h):
    """The largest change of the crossing's weight between samples ``h``
    apart over ``[a0 - 5 h, a0 + 35 h]``."""
    w = [_weight(mesh, at(a)) for a in a0 + h * np.arange(-5, 36)]
    return float(np.abs(np.diff(w)).max())


def _first_weight(mesh, at):
    """Bisection for the first ``a`` in [-1e-3, 1e-3] at which the crossing
    has a pair (weight above 0)."""
    lo, hi = -1e-3, 1e-3
    assert _weight(mesh, at(lo)) == 0.0 and _weight(mesh, at(hi)) > 0.9
    for _ in range(45):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if _weight(mesh, at(mid)) > 0 else (mid, hi)
    return hi


def test_a_minimum_born_at_a_fold_fades_in(path):
    """The pair of the newborn minimum fades in: sampled ten times finer
    around the place where it first has weight, the largest change of its
    weight between samples drops more than tenfold (a weight of finite
    slope).  Read from the blended second derivatives alone, it jumps from
    no pair to weight 1 at every resolution."""
    mesh, at = path
    a0 = _first_weight(mesh, at)
    coarse, fine = _largest_step(mesh, at, a0, 1e-6), _largest_step(mesh, at, a0, 1e-7)
    assert 0.0 < fine < 0.1 * coarse
    assert _weight(mesh, at(0.0)) == 0.0          # the recorded state: born, no weight yet


def test_the_blended_reading_alone_jumps(path, monkeypatch):
    """The same path with the fold reading switched off (its share so small
    that it never wins): the pair appears with weight 1."""
    mesh, at = path
    monkeypatch.setattr(crossing, "FOLD_SHARE", 1e-300)
    a0 = _first_weight(mesh, at)
    assert abs(a0) < 1e-6
    assert _largest_step(mesh, at, a0, 1e-7) == 1.0
