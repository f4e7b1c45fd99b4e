"""Frictionless self-contact: consistency of residual, tangent and energy,
symmetry, the augmented-Lagrangian law on a scene, broad-phase scaling, and
that a scene without contact runs no contact code."""
import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.contact import search as search_mod
from skfem_rod.contact.assembly import contact_work
from skfem_rod.contact.search import slave_points, search


def hairpin(eps, spacing, leg=0.5):
    """Two parallel legs ``spacing`` apart (centre to centre) joined by a
    half circle: the free leg can be pressed onto the clamped one."""
    Rb = spacing / 2

    def r_of_s(s):
        s = np.asarray(s, float)
        out = np.zeros((len(s), 3))
        a = s < leg
        out[a, 0] = leg - s[a]
        b = (s >= leg) & (s < leg + np.pi * Rb)
        th = (s[b] - leg) / Rb
        out[b, 0], out[b, 1] = -Rb * np.sin(th), Rb - Rb * np.cos(th)
        c = s >= leg + np.pi * Rb
        out[c, 0], out[c, 1] = s[c] - leg - np.pi * Rb, 2 * Rb
        return out
    return geometry.curve(r_of_s, 2 * leg + np.pi * Rb)


SEC = Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=0.8, radius=0.02)


def _work(rod, r, sl, lam, mu, eps, tangent=True):
    pairs = search(rod.mesh, r, sl, reach=2 * eps + 0.05, exclusion=np.pi * eps)
    return pairs, contact_work(rod.mesh, r, pairs, lam, mu, eps, tangent)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_contact_residual_tangent_energy_consistent(seed):
    rng = np.random.default_rng(seed)
    eps = 0.105                       # legs 0.2 apart: penetration ~0.01
    rod = Rod(hairpin(eps, 0.2, leg=1.0), SEC, 24)
    r = rod.r0 + 0.003 * rng.normal(size=rod.r0.shape)
    sl = slave_points(rod.mesh, 3)
    lam = 0.01 * np.abs(rng.normal(size=sl.s.size))
    mu = 1e-3
    pairs, (E, f, K, fN) = _work(rod, r, sl, lam, mu, eps)
    assert (fN > 0).sum() > 20 and (~pairs.interior).any()   # interior and vertex pairs
    d = np.zeros(rod.mesh.n_dofs)
    d.reshape(-1, 6)[:, :3] = rng.normal(size=(rod.mesh.n_nodes, 3))
    shift = lambda t: r + t * d.reshape(-1, 6)[:, :3]
    h = 1e-7
    dE = (_work(rod, shift(h), sl, lam, mu, eps, False)[1][0]
          - _work(rod, shift(-h), sl, lam, mu, eps, False)[1][0]) / (2 * h)
    assert abs(dE - f @ d) <= 1e-6 * abs(f @ d)
    # near-degenerate projections make the residual sharply curved: the
    # central difference converges as h^2 (3e-3, 3e-5, 3e-7 at 1e-6, 1e-7,
    # 1e-8 for seed 2), so take h small
    h = 1e-8
    fd = (_work(rod, shift(h), sl, lam, mu, eps, False)[1][1]
          - _work(rod, shift(-h), sl, lam, mu, eps, False)[1][1]) / (2 * h)
    assert np.abs(fd - K @ d).max() <= 1e-6 * np.abs(fd).max()
    # frictionless contact tangent: symmetric to round-off
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()


def _pressed_hairpin(penalty_factor):
    eps = SEC.radius
    rod = Rod(hairpin(eps, 4 * eps), SEC, 40)
    rod.clamp("start").add_force("end", [0, -0.6, 0])
    rod.enable_contact(penalty=penalty_factor * eps**4 / SEC.EI1)
    return rod, rod.solve(n_steps=6)


def test_hairpin_pressed_closed_keeps_contact_law():
    """A hairpin whose free leg is pressed onto the clamped one: contact
    appears on the way; at every converged step the penetration is below
    the Uzawa tolerance, f_N >= 0 and f_N d = 0 (complementarity), and the
    augmented-Lagrangian answer does not depend on the penalty."""
    eps = SEC.radius
    rod, res = _pressed_hairpin(10.0)
    assert res.converged, res.message
    tol = rod.contact.tolerance * eps
    n_active = []
    for st in res.steps:
        c = st.contact
        assert c.penetration <= tol
        assert np.all(c.force > 0)
        assert np.all(np.abs(c.gap) <= tol)          # active points sit on contact
        n_active.append(c.force.size)
    assert n_active[0] == 0 and n_active[-1] > 0     # contact appears on the way
    stiff_rod, stiff = _pressed_hairpin(1000.0)
    assert stiff.converged, stiff.message
    F_soft = res.steps[-1].contact.total_force
    F_stiff = stiff.steps[-1].contact.total_force
    assert F_soft == pytest.approx(F_stiff, rel=1e-2)
    tip = res.steps[-1].r[rod.node("end")]
    assert np.linalg.norm(tip - stiff.steps[-1].r[rod.node("end")]) <= 10 * tol


def test_contact_off_runs_no_contact_code(monkeypatch):
    def forbidden(*a, **k):
        raise AssertionError("contact code ran with contact off")
    monkeypatch.setattr(search_mod, "search", forbidden)
    monkeypatch.setattr(search_mod, "slave_points", forbidden)
    rod = Rod(hairpin(SEC.radius, 4 * SEC.radius), SEC, 20)
    rod.clamp("start").add_force("end", [0, -0.1, 0])
    assert rod.solve(n_steps=2).converged


def test_broad_phase_candidates_grow_linearly():
    """A coil with nearly touching turns (contact candidates between turns):
    the narrow-phase candidate count grows linearly, 50 to 800 elements."""
    """Twisted two-ply-like coil: candidate pairs per element stay constant
    under refinement (50 to 800 elements)."""
    counts = []
    sizes = [50, 100, 200, 400, 800]
    eps = 0.01
    eps = 0.001            # turns 2.2 eps apart: L / eps ~ 6300, h >~ eps
    shape = geometry.helix(radius=0.1, pitch=2.2 * eps, turns=10)
    for n in sizes:
        rod = Rod(shape, Section(EA=1, GA1=1, GA2=1, EI1=1, EI2=1, GJ=1, radius=eps), n)
        sl = slave_points(rod.mesh, 3)
        pairs = search(rod.mesh, rod.r0, sl, reach=3 * eps, exclusion=np.pi * eps)
        counts.append(pairs.n_candidates)
    slope = np.polyfit(np.log(sizes), np.log(counts), 1)[0]
    assert 0.85 <= slope <= 1.15, (counts, slope)


def test_contact_appears_and_disappears_along_a_load_unload_path():
    """Press the hairpin closed and release it (path 0 -> 1 -> 0): contact
    appears on loading, disappears on unloading, and the rod returns to its
    reference shape (elastic, frictionless: no hysteresis)."""
    eps = SEC.radius
    rod = Rod(hairpin(eps, 4 * eps), SEC, 40)
    rod.clamp("start").add_force("end", [0, -0.6, 0]).enable_contact()
    res = rod.solve(n_steps=12, path=[0, 1, 0])
    assert res.converged, res.message
    active = np.array([st.contact.force.size for st in res.steps])
    lam = np.array([st.load_factor for st in res.steps])
    assert active[0] == 0 and active[-1] == 0
    assert active[np.argmax(lam)] > 0
    on = np.flatnonzero(active > 0)
    # contact is active in one contiguous stretch around the peak load
    assert np.all(np.diff(on) == 1)
    np.testing.assert_allclose(res.steps[-1].r, rod.r0, atol=1e-9)
    # loading and unloading pass through the same states (no dissipation)
    k_up = np.flatnonzero((np.array([st.time for st in res.steps]) < 0.5) & (lam > 0.4))[0]
    k_dn = [k for k in range(len(lam)) if res.steps[k].time > 0.5
            and abs(lam[k] - lam[k_up]) < 1e-12]
    if k_dn:
        np.testing.assert_allclose(res.steps[k_dn[0]].r, res.steps[k_up].r, atol=1e-6)


def test_uzawa_shortfall_is_reported_as_a_warning():
    """A solve whose Uzawa loop stops at max_uzawa before the penetration
    tolerance keeps its steps but says so: a ContactShortfall warning and a
    line per step in Result.log."""
    from skfem_rod.solver import ContactShortfall
    eps = SEC.radius
    rod = Rod(hairpin(eps, 4 * eps), SEC, 40)
    rod.clamp("start").add_force("end", [0, -0.6, 0])
    rod.enable_contact(penalty=10 * eps**4 / SEC.EI1, tolerance=1e-9, max_uzawa=1)
    with pytest.warns(ContactShortfall, match="Uzawa did not reach its tolerance"):
        res = rod.solve(n_steps=6)
    assert res.converged
    bad = [st for st in res.steps if st.contact is not None and not st.contact.uzawa_converged]
    assert bad
    assert sum("Uzawa stopped after 1 updates" in line for line in res.log) == len(bad)
