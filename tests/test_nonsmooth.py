"""The generalized Newton on the Alart-Curnier augmented Lagrangian
(skfem_rod.nonsmooth, ``contact_solve="newton"``): its generalized
Jacobian against central differences on every branch (open, active;
friction in stick and in slip, tangential and rotational), the same
converged state as Uzawa on a frictionless load/unload path, quadratic
convergence and no 2-cycles on the converged steps, Coulomb's law at every
converged step with friction."""
import numpy as np
import pytest

from skfem_rod import Rod
from skfem_rod import nonsmooth
from skfem_rod.contact import friction as law
from skfem_rod.problem import Problem
from skfem_rod.rotations import expm

from helpers import coulomb_checks, spy_reports, two_cycles
from test_contact import SEC, hairpin

EPS = 0.105


def _problem(seed, friction, curve="elements"):
    """A hairpin of thick strands (eps = 0.105, legs 0.2 apart) in a seeded
    random state near contact, with multipliers that leave some slave
    points open and some active, friction (``friction`` = "stick" or
    "slip" coefficients, or None) measured from a nearby reference."""
    rng = np.random.default_rng(seed)
    rod = Rod(hairpin(EPS, 0.2, leg=1.0), SEC, 16)
    rod.clamp("start")
    kw = {}
    if friction == "slip":
        kw = dict(gamma_T=0.3, gamma_R=0.01, mu_T=1e-3, mu_R=1e-3)
    elif friction == "stick":
        kw = dict(gamma_T=5.0, gamma_R=2.0, mu_T=1e-1, mu_R=1e-1)
    rod.enable_contact(radius=EPS, penalty=1e-3, curve=curve, **kw)
    p = Problem(rod)
    nn = rod.mesh.n_nodes
    r_n = rod.r0 + 0.002 * rng.normal(size=(nn, 3))
    R_n = expm(0.3 * rng.normal(size=(nn, 3))) @ rod.R0
    r = r_n + 0.004 * rng.normal(size=(nn, 3))
    R = expm(0.05 * rng.normal(size=(nn, 3))) @ R_n
    m = p.multipliers
    ns = m.normal.size
    m.normal = 0.01 * np.abs(rng.normal(size=ns))
    if friction:
        p.reference = (r_n, R_n)
        m.tangential = 0.005 * rng.normal(size=(ns, 3))
        m.rotational = 0.002 * rng.normal(size=(ns, 3))
    return rng, p, r, R


def _residuals(p, r, R, lam):
    """``(G, C)`` at ``(r, R)`` and the multiplier unknowns ``lam``
    (normal, then friction: ``nonsmooth.unknowns``)."""
    saved = nonsmooth.unknowns(p)
    nonsmooth.set_unknowns(p, lam)
    try:
        ev = p.evaluate(r, R, 0.0, tangent=False)
        cs = nonsmooth.contact_blocks(p, ev, jacobian=False)
    finally:
        nonsmooth.set_unknowns(p, saved)
    return cs.G, cs.C


@pytest.mark.parametrize("curve", ["elements", "smooth"])
@pytest.mark.parametrize("friction", [None, "stick", "slip"])
@pytest.mark.parametrize("seed", [0, 1])
def test_generalized_jacobian_matches_finite_differences(seed, friction, curve):
    """``[[K, dG/dlambda], [dC/dy, dC/dlambda]]`` times a random direction
    equals the central difference of ``(G, C)`` (away from the kinks: the
    generalized Jacobian is the classical one on each branch), on the
    centreline and on the smooth contact curve (whose dofs map to the
    rod's)."""
    rng, p, r, R = _problem(seed, friction, curve)
    with p.friction_unknowns():         # contact_solve="newton"
        _check_jacobian(rng, p, r, R, friction)


def assert_jacobian(p, ev, cs, residuals, r, R, lam, dy, dl, h=1e-7):
    """The exact generalized Jacobian (no regularization of the active
    rows) times ``(dy, dl)`` against the central difference of ``(G, C) =
    residuals(r, R, lam)`` at ``(r, R, lam)``; returns the difference of
    ``C``."""
    plus = residuals(*p.update(r, R, dy, h), lam + h * dl)
    minus = residuals(*p.update(r, R, dy, -h), lam - h * dl)
    fd_G = (plus[0] - minus[0]) / (2 * h)
    fd_C = (plus[1] - minus[1]) / (2 * h)
    J_G = ev.tangent @ dy + cs.K_yl @ dl
    J_C = cs.K_ly @ dy + cs.D @ dl
    assert np.abs(fd_G - J_G).max() <= 1e-6 * np.abs(fd_G).max()
    assert np.abs(fd_C - J_C).max() <= 1e-6 * np.abs(fd_C).max()
    return fd_C


def _check_jacobian(rng, p, r, R, friction):
    ev = p.evaluate(r, R, 0.0)
    cs = nonsmooth.contact_blocks(p, ev)
    ns = p.multipliers.normal.size
    lam = nonsmooth.unknowns(p)
    # the normal multipliers, then 3 per slave point for each friction law
    assert cs.C.size == lam.size == ns * (7 if friction else 1)
    # both branches of the normal law are present
    assert 5 < cs.active[:ns].sum() < ns - 5
    if friction:
        fr = ev.contact.friction
        want = law.SLIP if friction == "slip" else law.STICK
        for state in (fr.state_T, fr.state_R):
            assert (state == want).mean() > 0.5
        # the friction rows of the points in contact join the system
        assert cs.active[ns:].sum() == 6 * fr.slave.size > 0
    dy = rng.normal(size=p.mesh.n_dofs)
    dy.reshape(-1, 6)[:, 3:] *= 0.3
    dl = 0.01 * rng.normal(size=lam.size)
    dl[ns:] *= 0.3
    fd_C = assert_jacobian(p, ev, cs, lambda *a: _residuals(p, *a), r, R, lam, dy, dl)
    # each block on its own: the normal multipliers, the friction
    # multipliers (a wrong block would not hide behind another).  G and C
    # are piecewise linear in the normal multipliers (the radius of the
    # Coulomb ball too) and smooth in the friction ones (to 1e-14 at
    # these steps, measured): steps large enough
    # to keep the round-off of G's internal forces out
    parts = [(slice(0, ns), 1e-2)]
    if friction:        # tangential, then rotational
        parts += [(slice(ns, 4 * ns), 1e-2), (slice(4 * ns, None), 1e-2)]
    for part, hl in parts:
        e = np.zeros_like(dl)
        e[part] = dl[part]
        pl, mi = _residuals(p, r, R, lam + hl * e), _residuals(p, r, R, lam - hl * e)
        for k, J in enumerate((cs.K_yl @ e, cs.D @ e)):
            fd = (pl[k] - mi[k]) / (2 * hl)
            # (G does not depend on a rotational multiplier that slips:
            # the couple of a saturated 1D law is gamma_R f_N)
            assert np.abs(fd - J).max() <= 1e-6 * max(np.abs(fd).max(), np.abs(J).max(),
                                                      1e-12)
    if friction:
        # without the friction multipliers' rows the difference would not
        # match: their Jacobian is not the identity's
        assert np.abs(cs.K_ly[ns:] @ dy).max() > 1e-3 * np.abs(fd_C[ns:]).max()


def _pressed(mode, n_steps=12, tolerance=1e-7):
    eps = SEC.radius
    rod = Rod(hairpin(eps, 4 * eps), SEC, 40)
    rod.clamp("start").add_force("end", [0, -0.6, 0]).enable_contact(tolerance=tolerance)
    return rod, rod.solve(n_steps=n_steps, path=[0, 1, 0], contact_solve=mode)


@pytest.fixture(scope="module")
def pressed():
    return {mode: _pressed(mode) for mode in ("uzawa", "newton")}


def test_same_converged_state_as_uzawa(pressed):
    """Frictionless load/unload path of the pressed hairpin, both solves
    held to a gap tolerance of 1e-7 eps: the generalized Newton converges
    at every step to the state Uzawa converges to, within 1e-8 eps
    (measured: 9e-9 eps; at the default tolerance 1e-3 eps the two differ by
    2.5e-3 eps at the free end, each within its tolerance of the exact
    contact, the lever arm amplifying)."""
    rod, uz = pressed["uzawa"]
    _, nw = pressed["newton"]
    assert uz.converged and nw.converged, (uz.message, nw.message)
    assert len(uz.steps) == len(nw.steps)
    eps = rod.contact.radius
    tol = rod.contact.tolerance * eps
    for a, b in zip(uz.steps, nw.steps):
        assert a.load_factor == b.load_factor
        assert b.contact.penetration <= tol
        assert np.abs(a.r - b.r).max() <= 1e-8 * eps
        fa, fb = a.contact.total_force, b.contact.total_force
        assert abs(fa - fb) <= 1e-6 * max(abs(fa), 1e-12) + 1e-12
    # back to the start (frictionless, elastic), as with Uzawa
    np.testing.assert_allclose(nw.steps[-1].r, rod.r0, atol=1e-9)


def _histories(rod, mode, monkeypatch, **solve):
    """The merit histories of every generalized-Newton solve of a run."""
    seen = spy_reports(monkeypatch, nonsmooth, "contact_newton")
    res = rod.solve(contact_solve=mode, **solve)
    return res, seen


def _check_quadratic(reports, floor):
    """Converged solves: no residual history 2-cycles; from the iterate
    after the last shortened step (the line search's
    global phase ends there) and the last change of the contact states
    (semi-smooth Newton is Newton once they are settled) to the round-off ``floor`` (absolute) at most 6
    iterations (a linear rate of 0.1 needs 8 for 8 decades); and a
    superlinear step among them: ``log(r_{k+1}/s) / log(r_k/s) >= 1.5``
    with ``s`` the largest residual of the solve (or, from ``s`` itself, a
    drop by 1e3)
    (2 for a quadratic step; the round-off floor truncates the last one).
    Returns the number of solves checked (those that took a step).

    (The residual of a stiff rod is not strictly quadratic in every step:
    plain Newton without contact shows the same, e.g. 0.1, 3.9e-5, 2.1e-5,
    1.5e-9 in the hairpin's first step, the update, not the residual,
    converging quadratically; see SolverOptions.rtol.)"""
    n = 0
    for rep in reports:
        if not rep.converged:
            continue
        h = np.asarray(rep.history)
        assert not two_cycles(h, floor), h
        # (the first entry is the start, before a step's prescribed motion:
        # the last step's equilibrium, at the floor when no Uzawa pass
        # follows; the floor that counts is the one the solve reaches)
        below = np.flatnonzero(h[1:] <= floor) + 1
        k = below[0] if below.size else h.size - 1
        # the local phase: from the last shortened step on (before it the
        # line search globalizes, the active set settles)
        short = [j + 1 for j, a in enumerate(rep.step_lengths[:k]) if a < 1]
        # ... and the iterate at which the contact states last changed
        # (normal law, stick/slip: the semi-smooth Newton's active set),
        # when the friction multipliers are unknowns too
        short += [j for j, n in enumerate(rep.switches[:k + 1]) if n]
        top = max(short, default=0)
        if k == top:
            continue
        s = h.max()
        assert k - top <= 6, h
        x = np.log(np.maximum(h[top:k + 1], 1e-300) / s)
        q = [x[j] / x[j - 1] for j in range(1, x.size) if x[j - 1] < 0]
        drops = h[top + 1:k + 1] / h[top:k]
        if k - top >= 2:                 # (one step into the floor says nothing)
            assert max(q, default=0.0) >= 1.5 or drops.min() <= 1e-3, h
        n += 1
    return n


def test_quadratic_convergence_and_no_cycles(pressed, monkeypatch):
    rod = Rod(hairpin(SEC.radius, 4 * SEC.radius), SEC, 40)
    rod.clamp("start").add_force("end", [0, -0.6, 0]).enable_contact()
    res, reps = _histories(rod, "newton", monkeypatch, n_steps=12, path=[0, 1, 0])
    assert res.converged, res.message
    assert _check_quadratic(reps, 1e-8) >= 10
    # contact on and off along the path: no Uzawa update was needed
    assert all(st.contact.uzawa == 0 for st in res.steps)


@pytest.mark.slow
def test_rotational_friction_scene_obeys_coulomb_and_converges_fast(monkeypatch):
    """The rotational-friction scene (tests/test_friction_scenes.py) with
    the generalized Newton: converged, Coulomb's law at every step, the
    penetration within tolerance, and every Newton solve converges
    superlinearly without cycling."""
    from helpers import load_demo
    rf = load_demo("rotational_friction")
    rod, _ = rf.build(rf.EPS, 2.0, 0.06, 32)
    res, reps = _histories(rod, "newton", monkeypatch, n_steps=8)
    assert res.converged, res.message
    coulomb_checks(res, 0.0, rf.EPS)
    for st in res.steps[1:]:
        assert st.contact.penetration <= 1e-3 * rf.EPS
        # the friction multipliers converge inside the Newton solve: no
        # Uzawa update (14 over the 8 steps with them updated between
        # solves, contact_solve="newton_normal")
        assert st.contact.uzawa == 0
    assert _check_quadratic(reps, 1e-8) >= 5
    # the same states as with the friction multipliers updated between
    # the solves, to the friction tolerance: 3e-9 measured, eps = 0.02
    rod, _ = rf.build(rf.EPS, 2.0, 0.06, 32)
    other = rod.solve(n_steps=8, contact_solve="newton_normal")
    assert other.converged
    assert sum(st.contact.uzawa for st in other.steps[1:]) > 0
    for a, b in zip(res.steps, other.steps):
        assert np.abs(a.r - b.r).max() <= 1e-6 * rf.EPS


@pytest.mark.slow
def test_monotone_line_search_stops_the_stick_slip_two_cycle(monkeypatch):
    """The rotational-friction scene 2-cycled at a stick/slip switch with a
    non-monotone line search (Armijo against the largest merit of the last
    4 iterates: 8.6e-3 <-> 4.3e-3 for 6 iterations, each return a hair
    below the memory's maximum), in the variant that polished from
    ``|G| <= 1e-6`` and had no escapes (the cycle is checked there); with
    the monotone test (the default, ``MEMORY = 1``) no solve of the same
    variant cycles, and it converges."""
    from helpers import load_demo
    rf = load_demo("rotational_friction")
    found = {}
    for memory in (4, 1):
        monkeypatch.setattr(nonsmooth, "MEMORY", memory)
        monkeypatch.setattr(nonsmooth, "POLISH_BELOW", 1e-6)
        monkeypatch.setattr(nonsmooth, "ESCAPES", 0)
        rod, _ = rf.build(rf.EPS, 2.0, 0.06, 32)
        # the friction multipliers updated between the solves (the variant
        # in which the cycle was found; with them as unknowns the scene
        # does not cycle with either test)
        res, reps = _histories(rod, "newton_normal", monkeypatch, n_steps=8)
        assert res.converged, res.message
        found[memory] = sum(bool(two_cycles(r.history, 1e-8)) for r in reps)
        monkeypatch.undo()
    assert found[4] >= 1
    assert found[1] == 0


@pytest.mark.parametrize("mode", ["newton", "newton_normal"])
def test_a_failed_solve_leaves_the_multipliers_as_it_found_them(mode):
    """A generalized Newton solve that fails (here: one iteration allowed
    from a state far from equilibrium) puts every multiplier back; the
    gradient flow falls back on its own state at those multipliers (the
    frictional plectoneme cycle kept a flow state with a residual of 0.28
    of the force scale, evaluated at the failed solve's multipliers)."""
    from dataclasses import fields
    from skfem_rod.options import make_options
    rng, p, r, R = _problem(0, "slip")
    before = p.multipliers.copy()
    opts = make_options({"contact_solve": mode, "max_iterations": 1})
    *_, rep = nonsmooth.contact_newton(p, r, R, 0.0, opts)
    assert not rep.converged
    for f in fields(before):
        a, b = getattr(p.multipliers, f.name), getattr(before, f.name)
        assert np.array_equal(a, b), f.name
    # ... while its iteration did move them (the inner loop, without the
    # restore, leaves them changed: the test can see a change)
    with p.friction_unknowns():
        *_, rep = nonsmooth._contact_newton(p, r, R, 0.0, opts)
    assert not rep.converged
    assert not np.array_equal(p.multipliers.normal, before.normal)


def test_the_generalized_newton_accepts_its_least_iterate_at_the_round_off_floor(monkeypatch):
    """Held to an ``rtol`` no residual reaches (1e-30) and an update
    tolerance no update meets, every generalized Newton solve of the
    rotational-friction scene ends at its round-off floor.  It returns its
    least polished iterate there (``floor`` recorded), the state the
    default tolerances reach; without the floor test the same solves run
    to the iteration limit and fail (measured in the frictional knot: a
    step whose |G| stood at 3.2e-9 with every contact tolerance met went
    to the gradient flow)."""
    from helpers import load_demo
    rf = load_demo("rotational_friction")
    strict = dict(n_steps=2, contact_solve="newton", rtol=1e-30, increment_tol=1e-300)
    rod, _ = rf.build(rf.EPS, 2.0, 0.06, 32)
    ref = rod.solve(n_steps=2, contact_solve="newton")
    assert ref.converged, ref.message
    rod, _ = rf.build(rf.EPS, 2.0, 0.06, 32)
    res = rod.solve(**strict)
    assert res.converged, res.message
    for a, b in zip(ref.steps[1:], res.steps[1:]):
        assert b.floor is not None and 0 < b.floor < 1e-8
        assert b.contact.penetration <= 1e-3 * rf.EPS
        assert np.abs(a.r - b.r).max() <= 1e-6 * rf.EPS
    coulomb_checks(res, 0.0, rf.EPS)
    monkeypatch.setattr(nonsmooth, "at_floor", lambda *a: None)
    rod, _ = rf.build(rf.EPS, 2.0, 0.06, 32)
    res = rod.solve(**strict)
    assert not res.converged
    assert "no convergence in 25 iterations" in " ".join(res.log) + res.message
