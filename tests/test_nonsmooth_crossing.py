"""The crossing pairs' multipliers as unknowns of the generalized Newton
(``contact_solve="newton"`` with ``crossing=True``): the weights'
derivatives ``dw/dq`` that their complementarity rows read, and the whole
generalized Jacobian with a crossing pair, against central differences;
a pressed crossing solved with no Uzawa update and the true distance at
the tolerance."""
import numpy as np
import pytest

from skfem_rod import Rod, Section
from skfem_rod import nonsmooth
from skfem_rod.contact.crossing import crossing_pairs, crossing_work, min_distance
from skfem_rod.options import make_options
from skfem_rod.problem import Increment, Problem, State

from test_core import _figure_eight, pressed_figure_eight
from test_crossing import EPS as UNIT, _WIDE, two_strands
from test_nonsmooth import assert_jacobian


@pytest.mark.parametrize("degrees, seed", [(26.0, 0), (28.0, 1), (29.5, 2)])
def test_weight_rows_match_finite_differences(degrees, seed):
    """A fading crossing pair (weight between 0 and 1, the threshold of
    tests/test_crossing.py's fading tests): the rows ``dw/dq`` that
    ``crossing_work(..., weight_rows=True)`` returns against the central
    difference of the weight along a random direction of the positions."""
    mesh, r = two_strands(np.radians(degrees), 1.5 * UNIT, bend=0.03)
    rng = np.random.default_rng(seed)
    r = r + 1e-3 * UNIT * rng.normal(size=r.shape)
    held = (np.zeros((0, 5)), np.zeros(0))

    def pairs(rr):
        return crossing_pairs(mesh, rr, UNIT, np.pi * UNIT, threshold=_WIDE, held=held)

    cp = pairs(r)
    assert cp.size == 1 and 0.0 < cp.weight[0] < 1.0
    out = crossing_work(mesh, r, cp, np.zeros(1), 1.0, UNIT, weight_rows=True)
    assert len(out) == 5
    Wq = out[4]
    assert Wq.shape == (1, mesh.n_dofs) and Wq.nnz > 0
    d = np.zeros(mesh.n_dofs)
    d.reshape(-1, 6)[:, :3] = rng.normal(size=(mesh.n_nodes, 3))
    h = 1e-6
    wp = pairs(r + h * d.reshape(-1, 6)[:, :3]).weight
    wm = pairs(r - h * d.reshape(-1, 6)[:, :3]).weight
    fd = (wp - wm) / (2 * h)
    assert abs(fd[0]) > 1e-3                           # the weight moves along d
    assert abs(fd[0] - (Wq @ d)[0]) <= 1e-6 * abs(fd[0])
    # without the rows the output is the usual four
    assert len(crossing_work(mesh, r, cp, np.zeros(1), 1.0, UNIT)) == 4


def _pressed_figure_eight(sep=1.92):
    """The figure-eight of tests/test_core.py (strands crossing at 90
    degrees, elements 9 eps long) with its strands ``sep`` eps apart at the
    crossing: they overlap there, between the Gauss points."""
    eps = 0.01
    shape, _ = _figure_eight(eps, sep * eps)
    rod = Rod(shape, Section.circle(E=1e7, nu=0.3, radius=eps), 60)
    rod.clamp("start").clamp("end")
    rod.enable_contact(crossing=True)
    return rod, eps


def _residuals(p, pairs, r, R, x):
    """``(G, C)`` at ``(r, R)`` and the unknowns ``x`` (the crossing part
    keyed to ``pairs``)."""
    saved = p.multipliers.copy()
    nonsmooth.set_unknowns(p, x, pairs)
    try:
        ev = p.evaluate(r, R, 0.0, tangent=False)
        cs = nonsmooth.contact_blocks(p, ev, jacobian=False, crossing=True)
    finally:
        nonsmooth.restore(p.multipliers, saved)
    return cs.G, cs.C


@pytest.mark.parametrize("seed", [0, 1])
def test_generalized_jacobian_with_a_crossing_pair(seed):
    """The overlapping figure-eight with a multiplier on its crossing pair
    (active, full weight): ``[[K, dG/dlambda], [dC/dy, dC/dlambda]]``
    times a random direction of the dofs and of the multipliers (the
    crossing one included) against the central difference of ``(G, C)``;
    the crossing pair's row and column are there."""
    rng = np.random.default_rng(seed)
    rod, eps = _pressed_figure_eight()
    p = Problem(rod)
    r, R = rod.r0, rod.R0
    ev = p.evaluate(r, R, 0.0)
    cp = ev.contact.crossing
    assert cp.size == 1 and cp.weight[0] == 1.0
    p.multipliers.rekey_crossing(cp.key.copy(), np.array([0.5]))
    with p.crossing_unknowns():
        ev = p.evaluate(r, R, 0.0)
    cp = ev.contact.crossing
    cs = nonsmooth.contact_blocks(p, ev, crossing=True)
    x = nonsmooth.unknowns(p, cp)
    ns = p.multipliers.normal.size
    assert cs.C.size == x.size == ns + 1
    assert x[-1] == 0.5 and cs.active[-1]
    assert abs(cs.K_yl[:, -1]).max() > 0 and abs(cs.K_ly[-1]).max() > 0
    dy = rng.normal(size=p.mesh.n_dofs)
    dy.reshape(-1, 6)[:, 3:] *= 0.3
    dl = 0.01 * rng.normal(size=x.size)
    assert_jacobian(p, ev, cs, lambda *a: _residuals(p, cp, *a), r, R, x, dy, dl)
    # the crossing pair's own entries: its multiplier alone
    e = np.zeros_like(x)
    e[-1] = 1.0
    hl = 1e-2
    pl, mi = _residuals(p, cp, r, R, x + hl * e), _residuals(p, cp, r, R, x - hl * e)
    for k, J in enumerate((cs.K_yl @ e, cs.D @ e)):
        fd = (pl[k] - mi[k]) / (2 * hl)
        # (C's own entry is w - 1 = 0 at full weight: round-off there)
        assert np.abs(fd - J).max() <= 1e-6 * max(np.abs(fd).max(), np.abs(J).max()) + 1e-12
    assert np.abs(cs.K_yl @ e).max() > 0


def test_pressed_crossing_needs_no_uzawa_update():
    """The figure-eight pressed together by opposite point forces at its
    crossing (tests/test_core.py): with the crossing pairs' multipliers
    among the generalized Newton's unknowns every step converges with no
    Uzawa update and the true distance (closest points, both parameters
    free) within 1e-8 eps of contact; the Uzawa loop takes updates and
    leaves up to 6.5e-4 eps (within its tolerance, 1e-3 eps)."""
    eps = 0.01
    figures = {}
    for mode in ("uzawa", "newton"):
        rod = pressed_figure_eight(eps, crossing=True)
        res = rod.solve(4, path=[0, 0.1], contact_solve=mode)
        assert res.converged, res.message
        pen = [min_distance(rod.mesh, st.r, eps, rod.contact.exclusion).penetration(eps) / eps
               for st in res.steps[1:]]
        figures[mode] = (pen, [st.contact.uzawa for st in res.steps[1:]])
    pen, uzawa = figures["newton"]
    assert all(u == 0 for u in uzawa)
    assert max(abs(v) for v in pen) <= 1e-8
    pen_u, uzawa_u = figures["uzawa"]
    assert sum(uzawa_u) >= 2
    assert 1e-4 < max(pen_u) <= rod.contact.tolerance


def test_generalized_jacobian_with_a_fading_crossing_pair(monkeypatch):
    """A figure-eight flattened so that its strands cross at 42 degrees,
    with the wide threshold of tests/test_crossing.py's fading tests (on
    these curved strands, elements 7 eps long, the weight rises from 0 at
    32 to 1 at 50 degrees), its nodes moved by 1e-2 eps at random: the
    crossing pair's weight is 0.55, and its complementarity
    row carries the weight's derivative ``(f_N + w offset / mu) dw/dq``.
    The whole generalized Jacobian against central differences; without
    that term the row would not match."""
    from skfem_rod.contact import ContactOptions
    eps = 0.01
    a = np.tan(np.radians(21.0))             # crossing angle 2 atan(a) = 42 degrees
    shape, _ = _figure_eight(eps, 1.92 * eps, flatten=a)
    rod = Rod(shape, Section.circle(E=1e7, nu=0.3, radius=eps), 60)
    rod.clamp("start").clamp("end")
    rod.enable_contact(crossing=True)
    monkeypatch.setattr(ContactOptions, "crossing_threshold", lambda self: _WIDE)
    p = Problem(rod)
    # off the lemniscate's symmetry: there the probes on either side rise
    # alike, and the lowest of them (the weight reads the least rise) has
    # a kink in every direction that makes them differ
    R = rod.R0
    r = rod.r0 + 1e-2 * eps * np.random.default_rng(1).normal(size=rod.r0.shape)
    cp = p.evaluate(r, R, 0.0).contact.crossing
    assert cp.size == 1 and 0.05 < cp.weight[0] < 0.95
    p.multipliers.rekey_crossing(cp.key.copy(), np.array([0.5]))
    assert p.evaluate(r, R, 0.0).contact.crossing_dw is None      # only where asked
    with p.crossing_unknowns():                        # as in the generalized Newton
        ev = p.evaluate(r, R, 0.0)
    cp = ev.contact.crossing
    assert ev.contact.crossing_dw.nnz > 0
    cs = nonsmooth.contact_blocks(p, ev, crossing=True)
    assert cs.active[-1]
    x = nonsmooth.unknowns(p, cp)
    rng = np.random.default_rng(3)
    dy = rng.normal(size=p.mesh.n_dofs)
    dy.reshape(-1, 6)[:, 3:] *= 0.3
    h = 1e-7
    plus = _residuals(p, cp, *p.update(r, R, dy, h), x)
    minus = _residuals(p, cp, *p.update(r, R, dy, -h), x)
    fd_C = (plus[1] - minus[1]) / (2 * h)
    J_C = cs.K_ly @ dy
    assert abs(fd_C[-1]) > 0
    assert abs(fd_C[-1] - J_C[-1]) <= 1e-6 * abs(fd_C[-1])
    # the weight's term is a visible part of the row (the contact curve is
    # the centreline here, its dofs the rod's)
    term = ev.contact.crossing_fN[0] / cp.weight[0] * (ev.contact.crossing_dw @ dy)[0]
    assert abs(term) > 1e-3 * abs(fd_C[-1])


def test_the_line_search_restores_the_search_memory_with_re_keyed_crossing_pairs():
    """The generalized Newton's line search sets the trial's multipliers,
    which re-keys the crossing pairs to those of the iterate, before it
    evaluates each trial from the state's search memory
    (skfem_rod/nonsmooth.py, line_search).  Here the held keys (two) and
    the iterate's pairs (one) differ in number: the state's memory (the
    held pairs' places, two rows) must be put back before the re-keying,
    not after it (then the evaluation found two places for one key and
    failed).  Where no trial is taken, the memory is as it was."""
    rod, eps = _pressed_figure_eight()
    p = Problem(rod)
    r, R = rod.r0, rod.R0
    cp = p.evaluate(r, R, 0.0).contact.crossing
    assert cp.size == 1
    p.multipliers.rekey_crossing(np.vstack([cp.key, cp.key]), np.array([0.5, 0.5]))
    p.evaluate(r, R, 0.0)
    memory = p.search_memory()
    assert memory.crossing_places.shape == (2, 2)
    rng = np.random.default_rng(0)
    dy = 1e-3 * eps * rng.normal(size=p.mesh.n_dofs)
    dy[p.fixed] = 0.0
    dl = np.zeros_like(nonsmooth.unknowns(p, cp))
    opts = make_options({"max_backtracks": 1, "clearance_cap": False,
                         "position_correction": False})
    never = nonsmooth.Merit(last=1.0, reference=-1.0, scale=1.0, weight=1.0, first=False)
    evaluations = p.calls["evaluate"]
    out, alpha, why = nonsmooth.line_search(p, State(r, R, 0.0), Increment(dy, dl), never,
                                            opts, cp)
    assert out is None and p.calls["evaluate"] == evaluations + 2
    now = p.search_memory()
    assert np.array_equal(now.last_master, memory.last_master)
    assert np.array_equal(now.crossing_places, memory.crossing_places)
    assert len(p.multipliers.crossing_key) == 2
