"""Adaptive penalty of the Uzawa loop (the method of multipliers' penalty
update, ``augmented.adapt_penalty``): fewer updates, the same converged answer
to the tolerances, bad options refused, and the penalty factors saved and
restored with the multipliers of a rejected step."""
import numpy as np
import pytest

from helpers import load_demo
from skfem_rod import Rod
from skfem_rod.problem import Problem
from test_contact import SEC, hairpin


def _pressed(compliance=1e4, **contact):
    """The pressed hairpin of test_contact (30 elements, end pushed down),
    contact on with the penalty compliance ``compliance eps^4 / EI``
    (1e4: 1000 times the library default, on which fixed-penalty Uzawa
    converges by a factor close to 1 per update on its line contact) and
    the contact options ``contact``."""
    eps = SEC.radius
    rod = Rod(hairpin(eps, 4 * eps), SEC, 30)
    rod.clamp("start").add_force("end", [0, -0.6, 0])
    rod.enable_contact(penalty=compliance * eps**4 / SEC.EI1, **contact)
    return rod


def _hairpin(growth, memory=False):
    """The soft hairpin (:func:`_pressed`) solved in 4 steps."""
    rod = _pressed(penalty_growth=growth, max_uzawa=60, penalty_memory=memory)
    return rod, rod.solve(n_steps=4)


@pytest.mark.slow
def test_adaptive_penalty_needs_fewer_updates_for_the_same_answer():
    eps = SEC.radius
    rod, fixed = _hairpin(1.0)
    _, adaptive = _hairpin(4.0)
    assert fixed.converged and adaptive.converged, (fixed.message, adaptive.message)
    tol = rod.contact.tolerance * eps
    n_fixed = sum(st.contact.uzawa for st in fixed.steps)
    n_adaptive = sum(st.contact.uzawa for st in adaptive.steps)
    for res in (fixed, adaptive):
        for st in res.steps:
            c = st.contact
            assert c.uzawa_converged
            assert c.penetration <= tol
            assert np.all(np.abs(c.gap) <= tol)        # active points sit on contact
    assert n_fixed >= 20                               # the slow case it is about
    assert n_adaptive <= n_fixed / 2
    # the converged answer does not depend on the path: both satisfy the
    # contact law to tol, so the configurations agree to a few tol
    a, b = fixed.steps[-1], adaptive.steps[-1]
    assert np.abs(a.r - b.r).max() <= 5 * tol
    assert a.contact.total_force == pytest.approx(b.contact.total_force, rel=1e-2)


@pytest.mark.slow
def test_penalty_memory_same_answer_fewer_updates():
    """The steps after the first start at the penalty the last step's loop
    reached (``penalty_memory``): fewer Uzawa updates in those steps, the
    same converged answer to the tolerances, every step within them."""
    eps = SEC.radius
    rod, nominal = _hairpin(4.0, memory=False)
    _, carried = _hairpin(4.0, memory=True)
    assert nominal.converged and carried.converged, (nominal.message, carried.message)
    tol = rod.contact.tolerance * eps
    for res in (nominal, carried):
        for st in res.steps[1:]:
            assert st.contact.uzawa_converged and st.contact.penetration <= tol
            assert np.all(np.abs(st.contact.gap) <= tol)
    # the first step with contact starts from the nominal penalty either way
    first = next(k for k, st in enumerate(nominal.steps) if st.contact.uzawa > 0)
    assert carried.steps[first].contact.uzawa == nominal.steps[first].contact.uzawa
    later = [sum(st.contact.uzawa for st in res.steps[first + 1:]) for res in (nominal, carried)]
    assert later[1] < later[0], later
    a, b = nominal.steps[-1], carried.steps[-1]
    assert np.abs(a.r - b.r).max() <= 5 * tol
    assert a.contact.total_force == pytest.approx(b.contact.total_force, rel=1e-2)


@pytest.mark.slow
def test_adaptive_penalty_with_friction_same_coulomb_answer():
    """The rotational-friction scene (16 elements, two steps): fewer Uzawa
    updates with the adaptive penalty, both within the tolerances, and the
    same configuration and normal force to the friction tolerance."""
    from helpers import coulomb_checks
    rf = load_demo("rotational_friction")
    out = {}
    for growth in (1.0, 4.0):
        rod, _ = rf.build(gamma_R=rf.EPS, n_elements=16, phi=0.03)
        rod.contact.penalty_growth = growth
        res = rod.solve(n_steps=2)
        assert res.converged and all(st.contact.uzawa_converged for st in res.steps), \
            res.log
        coulomb_checks(res, 0.0, rf.EPS)
        out[growth] = res
    n_fixed = sum(st.contact.uzawa for st in out[1.0].steps)
    n_adaptive = sum(st.contact.uzawa for st in out[4.0].steps)
    assert n_adaptive < n_fixed
    a, b = out[1.0].steps[-1], out[4.0].steps[-1]
    assert np.abs(a.r - b.r).max() <= 1e-3 * rf.EPS
    assert a.contact.total_force == pytest.approx(b.contact.total_force,
                                                  rel=rod.contact.friction_tolerance)


@pytest.mark.parametrize("name,value", [("penalty_growth", 0.5), ("penalty_growth", np.nan),
                                        ("max_penalty_scale", 0.9), ("penalty_growth", True)])
def test_bad_adaptive_penalty_options(name, value):
    rod = Rod(hairpin(SEC.radius, 4 * SEC.radius), SEC, 8)
    with pytest.raises(ValueError, match=name):
        rod.enable_contact(**{name: value})


@pytest.mark.parametrize("friction", [False, True])
def test_penalty_factors_saved_and_restored_with_the_multipliers(friction):
    rod = Rod(hairpin(SEC.radius, 4 * SEC.radius), SEC, 8)
    rod.enable_contact(gamma_T=0.3 if friction else 0.0)
    problem = Problem(rod)
    saved = problem.multipliers.copy()
    m = problem.multipliers
    m.normal += 1.0
    m.penalty_scale *= 16.0
    m.friction_scale = 64.0
    problem.multipliers = saved
    assert np.all(problem.multipliers.normal == 0.0)
    assert np.all(problem.multipliers.penalty_scale == 1.0)
    assert problem.multipliers.friction_scale == 1.0


def test_penalty_grows_where_two_points_take_turns_to_carry_a_contact():
    """An Uzawa 2-cycle: two slave points take turns to carry a contact,
    each out of contact every other pass with the same penetration when in.
    Each point's violation is compared with the one of the last pass in
    which it was in contact, so both penalties grow by ``penalty_growth``
    on their second turn; a point whose violation fell by more than
    PENALTY_DROP, and one within the tolerance, keep theirs."""
    from types import SimpleNamespace

    from skfem_rod.augmented import PENALTY_DROP, adapt_penalty
    eps = SEC.radius
    rod = Rod(hairpin(eps, 4 * eps), SEC, 8)
    rod.enable_contact()
    problem = Problem(rod)
    c, m = problem.contact, problem.multipliers
    tol = c.tolerance * eps
    v = 50 * tol                                   # a penetration well above the tolerance
    a, b, drop, fine = 3, 7, 11, 12                # slave points
    passes = [                                     # (slaves in contact, their gaps d)
        ([a, drop, fine], [v, v, 0.5 * tol]),
        ([b], [v]),
        ([a, drop, fine], [v, 0.5 * PENALTY_DROP * v, 0.5 * tol]),
        ([b], [v])]
    last = np.full(m.normal.size, np.inf)
    scales = []
    for slaves, d in passes:
        d = np.array(d)
        pairs = SimpleNamespace(slave=np.array(slaves))
        last = adapt_penalty(problem, pairs, d, np.zeros(d.size), m.normal.copy(), last)
        scales.append(m.penalty_scale.copy())
    g = c.penalty_growth
    assert np.all(scales[1] == 1.0)                # first turns: nothing to compare with
    assert scales[2][a] == g and scales[2][b] == 1.0
    assert scales[3][a] == g and scales[3][b] == g
    assert scales[3][drop] == 1.0 and scales[3][fine] == 1.0
    untouched = np.setdiff1d(np.arange(m.normal.size), [a, b])
    assert np.all(scales[3][untouched] == 1.0)


@pytest.mark.parametrize("memory", [False, True])
def test_a_first_pass_failing_at_the_carried_penalty_runs_again_at_the_nominal_one(memory):
    """The loop of a step whose last step raised the penalty of some
    points, around an inner solve that fails at any raised penalty: with
    ``penalty_memory`` the first pass runs at the carried factors, fails and
    runs again at the nominal ones (converged); without, it runs once at
    the nominal ones.  A failure at the nominal penalty is the step's
    failure, with the multipliers as they were."""
    from skfem_rod.augmented import augmented_lagrangian
    from skfem_rod.problem import Report
    rod = Rod(hairpin(SEC.radius, 4 * SEC.radius), SEC, 8)    # legs apart: no contact
    rod.enable_contact(penalty_memory=memory)
    problem = Problem(rod)
    n = problem.multipliers.normal.size
    problem.penalty_start = np.where(np.arange(n) % 3 == 0, 16.0, 1.0)
    seen = []

    def solve_pass(previous, fails_at_nominal=False):
        scale = float(problem.multipliers.penalty_scale.max())
        seen.append(scale)
        if scale > 1.0 or fails_at_nominal:
            return rod.r0, rod.R0, 0.0, Report(False, iterations=3, reason="too stiff")
        return rod.r0, rod.R0, 0.0, Report(True, iterations=2,
                                           evaluation=problem.evaluate(rod.r0, rod.R0, 0.0))

    *_, rep = augmented_lagrangian(problem, solve_pass)
    assert rep.converged and rep.uzawa_converged
    assert seen == ([16.0, 1.0] if memory else [1.0])
    assert rep.newton_total == (5 if memory else 2)
    assert np.all(problem.multipliers.penalty_scale == 1.0)
    seen.clear()
    saved = problem.multipliers.copy()
    *_, rep = augmented_lagrangian(problem, lambda prev: solve_pass(prev, True))
    assert not rep.converged and rep.reason == "too stiff"
    assert np.array_equal(problem.multipliers.penalty_scale, saved.penalty_scale)
    assert np.array_equal(problem.multipliers.normal, saved.normal)


def test_a_failing_later_pass_is_solved_by_the_generalized_newton(monkeypatch):
    """A Uzawa pass after the first that fails (here every one, on purpose:
    in the plectoneme such a pass diverged at 256 times the nominal
    penalty) is solved again by the generalized Newton from the last
    converged pass (``augmented.step``): the steps converge, the log says
    which, every contact tolerance holds at every step, and the states are
    those plain Uzawa converges to, within the tolerances."""
    from skfem_rod import newton as newton_mod
    from skfem_rod.problem import failed
    eps = SEC.radius

    def pressed():
        return _pressed(1e2)

    rod = pressed()
    plain = rod.solve(n_steps=4)
    assert plain.converged, plain.message
    assert any(st.contact.uzawa > 0 for st in plain.steps)     # later passes exist
    real = newton_mod.newton

    def later_uzawa_passes_fail(problem, r, R, lam, opts, prescribed=None, border=None):
        if prescribed is None and border is None and opts.contact_solve == "uzawa":
            return failed(r, R, lam, [], 0, "made to fail")
        return real(problem, r, R, lam, opts, prescribed=prescribed, border=border)
    monkeypatch.setattr(newton_mod, "newton", later_uzawa_passes_fail)
    rod2 = pressed()
    res = rod2.solve(n_steps=4)
    assert res.converged, res.message
    rescued = [m for m in res.log if "the generalized Newton solved it" in m]
    assert rescued and all("made to fail" in m for m in rescued)
    tol = rod2.contact.tolerance * eps
    for a, b in zip(plain.steps, res.steps):
        c = b.contact
        assert c.penetration <= tol and np.all(np.abs(c.gap) <= tol)
        assert np.all(c.force >= 0)
        assert np.abs(a.r - b.r).max() <= 5 * tol


def test_crossing_penalty_grows_where_the_crossing_pairs_crawl():
    """The crossing pairs' one factor (``Multipliers.crossing_scale``): it
    grows by ``penalty_growth`` when their largest violation (a penetration
    or an open gap under force) is above the tolerance and fell by less than
    PENALTY_DROP since the last update; not when it fell faster, not within
    the tolerance, never above ``max_penalty_scale``; the nominal penalty and
    a restored copy put it back."""
    from types import SimpleNamespace

    from skfem_rod.augmented import PENALTY_DROP, adapt_crossing_penalty
    rod = Rod(hairpin(SEC.radius, 4 * SEC.radius), SEC, 8)
    rod.enable_contact(crossing=True)
    problem = Problem(rod)
    c, m = problem.contact, problem.multipliers
    tol = c.tolerance * c.radius
    g = c.penalty_growth

    def update(dc, fN, last):
        ce = SimpleNamespace(crossing_fN=np.asarray(fN, float))
        return adapt_crossing_penalty(problem, ce, np.asarray(dc, float), last)

    saved = m.copy()
    last = update([50 * tol, -1.0], [1.0, 0.0], np.inf)     # first: nothing to compare
    assert m.crossing_scale == 1.0 and last == 50 * tol
    last = update([45 * tol, -1.0], [1.0, 0.0], last)       # crawls: grows
    assert m.crossing_scale == g
    last = update([-40 * tol], [2.0], last)                 # open under force, crawls
    assert m.crossing_scale == g * g and last == 40 * tol
    last = update([0.5 * PENALTY_DROP * last], [2.0], last)  # fell fast: kept
    assert m.crossing_scale == g * g
    last = update([0.5 * tol, -3 * tol], [1.0, 0.0], last)  # within tol (the open
    assert m.crossing_scale == g * g                        # one carries no force)
    for _ in range(20):
        last = update([50 * tol], [1.0], 50 * tol)
    assert m.crossing_scale == c.max_penalty_scale
    assert m.nominal_penalty().crossing_scale == 1.0
    problem.multipliers = saved
    assert problem.multipliers.crossing_scale == 1.0


@pytest.mark.parametrize("rescue", [True, False])
def test_a_later_pass_failing_at_a_raised_penalty_runs_again_at_the_nominal_one(rescue):
    """A loop around another inner solve (the damped steps, the gradient
    flow): a pass after the first that fails at a raised penalty (here on
    purpose, the first time; in the plectoneme's winding at 1.95 turns a
    damped pass diverged at 16 times the crossing pairs' nominal penalty)
    runs again from the last converged pass at the nominal penalty.  The
    step converges to the state plain Uzawa reaches, within the
    tolerances, and the report says so (``rescued``); without ``rescue``
    the step fails with the pass's reason and the multipliers as they
    were."""
    from skfem_rod.augmented import step
    from skfem_rod.newton import newton
    from skfem_rod.options import make_options
    from skfem_rod.problem import failed
    eps = SEC.radius

    def pressed():
        rod = _pressed(max_uzawa=60)
        return rod, Problem(rod)

    opts = make_options({})
    rod, problem = pressed()
    r_plain, _, plain = step(problem, rod.r0, rod.R0, 1.0, None, opts)
    assert plain.converged and plain.uzawa_converged and plain.penalty_scale > 1
    rod, problem = pressed()
    fails = []

    def inner(r, R, lam, opts, prescribed=None):
        if problem.multipliers.penalty_scale.max() > 1 and not fails:
            fails.append(lam)
            return failed(r, R, lam, [], 0, "made to fail")
        return newton(problem, r, R, lam, opts, prescribed=prescribed)

    saved = problem.multipliers.copy()
    r1, _, rep = step(problem, rod.r0, rod.R0, 1.0, None, opts, inner=inner, rescue=rescue)
    assert fails                                   # a pass at a raised penalty was made to fail
    if not rescue:
        assert not rep.converged and rep.reason == "made to fail"
        assert np.array_equal(problem.multipliers.normal, saved.normal)
        return
    assert rep.converged and rep.uzawa_converged and rep.rescued == "made to fail"
    tol = problem.contact.tolerance * eps
    assert rep.penetration <= tol
    assert np.abs(r1 - r_plain).max() <= 5 * tol


@pytest.mark.parametrize("strict", [False, True])
def test_a_state_on_the_way_keeps_the_last_converged_pass(strict):
    """A loop that records no equilibrium (``strict=False``: the damped
    steps of the pseudo-dynamics) keeps the last converged pass when a
    later pass fails, rescue included, as it keeps the state of a loop
    stopped at ``max_uzawa``: converged, not ``uzawa_converged``, a note,
    the state and multipliers that pass converged with.  Only a pass after
    an update counts (the first pass ends where the step started, at the
    load held).  A strict loop (an equilibrium to record) fails instead,
    its multipliers put back."""
    from skfem_rod.augmented import step
    from skfem_rod.newton import newton
    from skfem_rod.options import make_options
    from skfem_rod.problem import failed
    eps = SEC.radius
    rod = _pressed(max_uzawa=60)
    problem = Problem(rod)
    opts = make_options({})
    first = []                          # the passes that converged

    def inner(r, R, lam, opts, prescribed=None):
        if len(first) == fail_from:
            return failed(r, R, lam, [], 0, "made to fail")
        out = newton(problem, r, R, lam, opts, prescribed=prescribed)
        first.append((out[0].copy(), problem.multipliers.copy()))
        return out

    saved = problem.multipliers.copy()
    fail_from = 1                       # every pass after the first fails
    r1, _, rep = step(problem, rod.r0, rod.R0, 1.0, None, opts, inner=inner, strict=strict)
    assert len(first) == 1
    assert not rep.converged and rep.reason == "made to fail"
    assert np.array_equal(problem.multipliers.normal, saved.normal)
    first.clear()
    fail_from = 2                       # the pass after the first update converges
    r1, _, rep = step(problem, rod.r0, rod.R0, 1.0, None, opts, inner=inner, strict=strict)
    assert len(first) == 2
    if strict:
        assert not rep.converged and rep.reason == "made to fail"
        assert np.array_equal(problem.multipliers.normal, saved.normal)
        return
    assert rep.converged and not rep.uzawa_converged
    assert "the last converged pass is kept" in rep.uzawa_note and "made to fail" in rep.uzawa_note
    assert rep.penetration > rod.contact.tolerance * eps     # the pass the loop stopped at
    assert rep.uzawa == 1
    assert np.array_equal(r1, first[1][0])
    # no penalty factor was raised on the way (one update): the multipliers
    # are those that pass converged with (the fold where a factor was
    # raised: the next test)
    assert np.all(first[1][1].penalty_scale == 1.0)
    assert np.array_equal(problem.multipliers.normal, first[1][1].normal)


def test_the_next_solve_starts_in_balance_after_a_raised_penalty():
    """A loop that converged at a raised penalty leaves as multipliers the
    forces its last pass applied (``augmented.fold_forces``), so the state
    it converged to is in balance at the nominal penalty up to ``d / mu``
    at each point: the out-of-balance the next solve starts from (a polish,
    the next damped step) is far below the one the multipliers that pass
    converged with would leave, about ``(s - 1) d / mu``."""
    from skfem_rod.augmented import step
    from skfem_rod.newton import newton
    from skfem_rod.options import make_options
    rod = _pressed(penalty_growth=4.0, max_uzawa=60)
    problem = Problem(rod)
    passes = []

    def inner(r, R, lam, opts, prescribed=None):
        passes.append(problem.multipliers.copy())
        return newton(problem, r, R, lam, opts, prescribed=prescribed)

    r1, R1, rep = step(problem, rod.r0, rod.R0, 1.0, None, make_options({}), inner=inner)
    assert rep.converged and rep.uzawa_converged and rep.penalty_scale >= 16
    # the forces applied where the factor was raised, the last pass's
    # multipliers elsewhere
    ce, last = rep.evaluation.contact, passes[-1]
    raised = np.zeros(last.normal.size, bool)
    raised[ce.pairs.slave[last.penalty_scale[ce.pairs.slave] > 1]] = True
    applied = np.zeros(last.normal.size)
    applied[ce.pairs.slave] = ce.fN
    assert raised.any()
    assert np.array_equal(problem.multipliers.normal[raised], applied[raised])
    assert np.array_equal(problem.multipliers.normal[~raised], last.normal[~raised])
    scale = problem.force_scale(rep.evaluation)
    start = problem.residual_norm(problem.evaluate(r1, R1, 1.0)) / scale
    problem.multipliers = passes[-1].nominal_penalty()
    unfolded = problem.residual_norm(problem.evaluate(r1, R1, 1.0)) / scale
    assert start <= 0.05 * unfolded, (start, unfolded)


def test_friction_penalty_rule_with_no_normal_force():
    """Every contact point open (``f_N`` all 0) while the friction
    multipliers still moved: the friction penalty rule has no Coulomb bound
    to measure the movement by, leaves the factor alone and raises no
    warning (it divided 0 by 0 before: measured in the frictional
    plectoneme)."""
    import warnings

    from skfem_rod.augmented import adapt_friction_penalty

    rod = Rod(hairpin(SEC.radius, 4 * SEC.radius), SEC, 8)
    rod.enable_contact(gamma_T=0.3)
    problem = Problem(rod)
    n = problem.multipliers.normal.size
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        moved = adapt_friction_penalty(problem, np.zeros(3), np.zeros(n), 0.5, 1.0)
    assert moved == 0.5 and problem.multipliers.friction_scale == 1.0
