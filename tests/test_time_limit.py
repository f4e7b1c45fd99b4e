"""The solve option ``time_limit``: a solve that runs out of wall time stops
where it is (load stepping, damped phase, gradient flow, continuation),
keeps every converged step and says why; without the option nothing
changes."""
import time

import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.dynamics import PseudoDynamics
from skfem_rod.relax import GradientFlow

from helpers import load_demo

demo = load_demo("twisted_rod")


def cantilever(n=8):
    rod = Rod(geometry.straight(1.0), Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0,
                                              GJ=0.8), n)
    rod.clamp("start")
    rod.add_force("end", [0.0, 3.0, 1.0])
    return rod


def twisted():
    """The contact-free twisted rod of tests/test_dynamics.py: straight up to
    Greenhill's threshold (1.67 turns), then a snap that load stepping
    cannot follow."""
    rod = demo.straight_rod(10.0, 16, turns=2.0)
    s = rod.mesh.s_nodes
    rod.add_force(float(s[np.argmin(np.abs(s - 5.0))]), [0.0, 0.01, 0.0], constant=True)
    return rod


def run_out_on_entry(monkeypatch, cls, name):
    """Make the solve's clock (``time_limit`` set) run out when ``cls.name``
    is first called (the damped step, the gradient flow), so that the stop
    is where it is meant to be whatever the machine's speed."""
    orig = getattr(cls, name)

    def wrapped(self, *args, **kwargs):
        deadline = self.S.deadline if isinstance(self, PseudoDynamics) else self.deadline
        deadline.end = -np.inf
        return orig(self, *args, **kwargs)
    monkeypatch.setattr(cls, name, wrapped)


@pytest.mark.parametrize("value", [-1.0, float("inf"), float("nan"), "10"])
def test_time_limit_is_validated(value):
    with pytest.raises(ValueError, match="time_limit must be a finite number >= 0"):
        cantilever(2).solve(1, time_limit=value)


def test_load_stepping_stops_at_the_time_limit_with_its_steps_kept():
    """Each step's callback sleeps 0.3 s and the limit is 1 s: the solve
    stops after a few of its 20 steps, not converged, says why, and the steps
    it kept are those of the unlimited solve."""
    ref = cantilever().solve(20)
    res = cantilever().solve(20, time_limit=1.0, callback=lambda result, k: time.sleep(0.3))
    assert ref.converged
    assert not res.converged
    assert "the time limit ran out (time_limit=1 s)" in res.message
    assert res.message.startswith(f"stopped at load factor {res.steps[-1].load_factor:.6g}")
    assert 2 <= len(res.steps) <= 6
    for a, b in zip(ref.steps, res.steps):
        assert a.load_factor == b.load_factor
        assert np.abs(a.r - b.r).max() < 1e-13


def test_no_time_limit_by_default():
    res = cantilever().solve(4, callback=lambda result, k: time.sleep(0.01))
    assert res.converged


def test_a_damped_phase_stops_at_the_time_limit(monkeypatch):
    """The clock runs out in the first damped step (the snap past
    Greenhill's threshold): the solve stops before the second, with the
    straight states before the snap kept (the damped state is not an
    equilibrium: not recorded)."""
    run_out_on_entry(monkeypatch, PseudoDynamics, "damped")
    rod = twisted()
    res = rod.solve(20, dynamics=True, time_limit=3600.0)
    assert not res.converged
    assert "after 1 damped steps: the time limit ran out (time_limit=3600 s)" in res.message
    lam = [st.load_factor for st in res.steps]
    assert 0.8 <= lam[-1] < 1.0 and np.all(np.diff(lam) > 0)
    assert res.dynamics.damped_steps == 1


def test_a_gradient_flow_stops_at_the_time_limit(monkeypatch):
    """The same snap by the gradient flow (snap="relax"): the flow stops at
    once and the load stepping after it, the straight states kept."""
    run_out_on_entry(monkeypatch, GradientFlow, "__call__")
    rod = twisted()
    res = rod.solve(20, snap="relax", stability=True, time_limit=3600.0)
    assert not res.converged
    assert "the time limit ran out (time_limit=3600 s)" in res.message
    assert 0.8 <= res.steps[-1].load_factor < 1.0
    assert all(st.flow_steps == 0 for st in res.steps)


def test_continuation_stops_at_the_time_limit():
    """Pseudo-arclength continuation in steps of 0.02 (about 350 to load
    factor 1) with each point's callback sleeping 0.3 s and a limit of 1 s:
    it stops after a few points and says why."""
    res = cantilever().solve(method="arclength", ds=0.02, ds_max=0.02, time_limit=1.0,
                             callback=lambda result, k: time.sleep(0.3))
    assert not res.converged
    assert "the time limit ran out (time_limit=1 s)" in res.message
    assert 2 <= len(res.steps) <= 6
