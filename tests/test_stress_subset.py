"""Fast subset of the stability stress tests (benchmarks/stress.py, the
ranges of docs/ranges.md): the ends of every documented range converge to
the right answer, and a case outside a range fails with a clear message and
keeps its converged steps.

The cases are the ones of benchmarks/stress.py (imported from there), at
the ends of the documented ranges:

* contact compliance 1e-4 and 1e2 times the default (hairpin scene);
* slenderness L / radius 10 and 1e4 in 1 load step; 100 load steps;
* roll-up in 1 load step, and with 1000 elements;
* 20 turns of twist at the documented largest twist per element;
* outside: 20 turns on 16 elements (more twist per element than the
  element chart allows).
"""

import numpy as np
import pytest

from helpers import load_bench

pytestmark = pytest.mark.slow    # a scene or a long run (fast tier: -m "not slow")

stress = load_bench("stress")


def run(case):
    row = stress.run_case(case)
    return row, row["result"]


@pytest.mark.parametrize("factor", [1e-4, 1e2])
def test_penalty_extremes_converge_to_the_same_contact(factor):
    row, res = run(stress.hairpin(factor))
    assert res.converged, res.message
    # Uzawa reaches its penetration tolerance (1e-3 eps) at every step
    assert row["uzawa_all_converged"] and row["penetration"] <= 1e-3
    # and the answer does not depend on the penalty beyond the Uzawa
    # tolerance: the default penalty leaves a penetration up to 1e-3 eps =
    # 2e-5, which the lever of the free leg carries to the tip (measured
    # tip differences 3.9e-5 L at 1e-4 x, 6.8e-6 L at 1e2 x the default)
    assert row["check"] < 1e-4


@pytest.mark.parametrize("ratio", [10.0, 1e4])
def test_slenderness_ends_in_one_load_step(ratio):
    row, res = run(stress.cantilever(ratio, 8, 1))
    assert res.converged, res.message
    # 8 P3 elements: measured ~1e-9 at every slenderness (no locking)
    assert row["check"] < 1e-7


def test_slender_cantilever_in_100_load_steps():
    row, res = run(stress.cantilever(1e4, 8, 100))
    assert res.converged, res.message
    assert row["steps"] == 100 and row["cuts"] == 0
    assert row["check"] < 1e-7


@pytest.mark.parametrize("n_elements, n_steps", [(8, 1), (1000, 4)])
def test_rollup_load_steps_and_elements(n_elements, n_steps):
    row, res = run(stress.rollup(n_elements, n_steps))
    assert res.converged, res.message
    assert row["steps"] == n_steps and row["cuts"] == 0
    # P3: max nodal error ~ 3e-3 (8 / n)^4 ... down to round-off
    assert row["check"] < max(2e-5 * (8 / n_elements) ** 4, 1e-9)
    # the tangent stays well posed: condition grows like n^2 EA / EI, finite
    assert np.isfinite(row["cond"])


def test_twenty_turns_of_twist_at_the_documented_limit():
    """0.625 turns (3.93 rad) per element, the documented largest: the end
    moment is GJ phi / L to round-off and the rod stays straight."""
    row, res = run(stress.twist(20.0, 32))
    assert res.converged, res.message
    assert row["check"] < 1e-10
    r = res.nodes()[1]
    assert np.abs(r[:, 1:]).max() < 1e-10


def test_outside_the_range_fails_clearly_and_keeps_the_converged_steps():
    """20 turns on 16 elements: 7.9 rad per element at the end, beyond the
    element chart (relative node rotations < PSI_MAX).  The solve stops with
    converged=False, says where and why, and keeps every converged step."""
    row, res = run(stress.twist(20.0, 16, outside=True))
    assert not res.converged
    lam = res.steps[-1].load_factor
    assert 0.3 < lam < 1.0 and len(res.steps) > 10
    assert f"stopped at load factor {lam:.6g}" in res.message
    assert "rotate by up to" in res.message and "refine the mesh" in res.message
    # the kept steps are genuine equilibria: the exact torque at their twist
    assert row["check"] < 1e-10
