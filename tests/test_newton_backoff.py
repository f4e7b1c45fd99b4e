"""snap="relax": after a step that Newton failed and the gradient flow
solved, the next steps go to the flow directly, Newton tried again after
1, 2, 4, ... solver.MAX_SKIPS of them (solver.NewtonBackoff)."""
import numpy as np

from helpers import bent_cantilever
from skfem_rod import solver
from skfem_rod.problem import Report


def schedule(backoff, outcomes, n):
    """The steps (of ``n``) at which Newton is tried; ``outcomes(k)`` gives
    ``(newton_failed, flow_solved)`` of a tried step ``k``."""
    tried = []
    for k in range(n):
        if backoff.skip():
            continue
        tried.append(k)
        backoff.record(*outcomes(k))
    return tried


def test_the_wait_doubles_while_newton_fails_up_to_max_skips():
    assert solver.MAX_SKIPS == 8
    got = schedule(solver.NewtonBackoff(), lambda k: (True, True), 40)
    # waits 1, 2, 4, 8, 8, 8 between the tries
    assert got == [0, 2, 5, 10, 19, 28, 37]


def test_a_newton_success_ends_the_wait_and_a_failed_flow_starts_none():
    b = solver.NewtonBackoff()
    # fails twice (waits 1, 2), then succeeds at step 5: tried at every step after
    got = schedule(b, lambda k: (k < 5, True), 10)
    assert got == [0, 2, 5, 6, 7, 8, 9]
    # the flow failed too (the step is cut): the shorter step tries Newton
    b = solver.NewtonBackoff()
    assert schedule(b, lambda k: (True, False), 5) == [0, 1, 2, 3, 4]
    assert b.wait == 0


def _cantilever():
    return bent_cantilever((0.0, 2.0, 0.5))


def _failing_newton(monkeypatch, tries):
    """Newton's attempts at the load steps after step 0 fail at once
    (counted in ``tries``); the gradient flow's solves are left alone."""
    real = solver.step

    def step(problem, r, R, lam, prescribed, opts, inner=None, **kw):
        if inner is None and lam > 0:
            tries.append(lam)
            return r, R, Report(False, reason="forced")
        return real(problem, r, R, lam, prescribed, opts, inner=inner, **kw)
    monkeypatch.setattr(solver, "step", step)


def test_steps_newton_fails_go_to_the_flow_with_the_same_states(monkeypatch):
    """Newton made to fail at every step of a bent cantilever (12 steps):
    the flow solves each step, Newton is tried at steps 1, 3, 6 and 11 only,
    and every state is the one of the run that tries Newton at every step
    (``MAX_SKIPS = 0``), bit for bit: a step sent to the flow starts where
    a step whose Newton failed does."""
    tries = []
    _failing_newton(monkeypatch, tries)
    res = _cantilever().solve(12, snap="relax")
    assert res.converged and len(res.steps) == 13
    assert np.allclose(tries, np.array([1, 3, 6, 11]) / 12)
    assert sum("Newton not tried" in line for line in res.log) == 8
    every = []
    monkeypatch.setattr(solver, "MAX_SKIPS", 0)
    _failing_newton(monkeypatch, every)
    ref = _cantilever().solve(12, snap="relax")
    assert len(every) == 12
    for a, b in zip(res.steps, ref.steps):
        np.testing.assert_array_equal(a.r, b.r)
        np.testing.assert_array_equal(a.R, b.R)
    assert all(st.flow_steps > 0 for st in res.steps[1:])


def test_newton_is_tried_at_every_step_it_solves(monkeypatch):
    tries = []
    real = solver.step

    def step(problem, r, R, lam, prescribed, opts, inner=None, **kw):
        if inner is None:
            tries.append(lam)
        return real(problem, r, R, lam, prescribed, opts, inner=inner, **kw)
    monkeypatch.setattr(solver, "step", step)
    res = _cantilever().solve(6, snap="relax")
    assert res.converged and len(tries) == 7          # step 0 and the six steps
    assert not any("Newton not tried" in line for line in res.log)
    assert all(st.flow_steps == 0 for st in res.steps)
