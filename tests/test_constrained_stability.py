"""The constrained stability test of states in contact
(``stability.CONTACT_STIFFENING``): the tangent with the active gaps'
stiffness ``df_N / d gap`` scaled by ``F``, the forces unchanged, is the
tangent plus ``(F - 1) sum_a w_a f_N'_a g_a g_a^T`` over the active pairs
(``g_a`` the gap gradient), for the slave-point pairs and the crossing
pairs alike; so it is the Hessian of the Lagrangian plus ``rho A^T A``, and
its lowest eigenvalue rises with ``F`` to that of the Hessian on the
directions that keep the active gaps."""
import numpy as np
import pytest

from skfem_rod.contact.assembly import contact_work
from skfem_rod.contact.crossing import crossing_pairs, crossing_work, gap_gradients
from skfem_rod.contact.law import gap, normal_force
from skfem_rod.contact.search import search, slave_points
from skfem_rod.element import shape_functions

from test_crossing import EPS, crossing_scene


def _gram(n, dofs, rows, coef):
    """``sum_a coef_a rows_a rows_a^T`` as a dense ``(n, n)`` matrix."""
    G = np.zeros((n, n))
    for d, g, c in zip(dofs, rows, coef):
        G[np.ix_(d, d)] += c * np.outer(g, g)
    return G


@pytest.mark.parametrize("degrees", [90.0, 35.0])
def test_stiffening_adds_the_active_gaps_penalty_only(degrees):
    mesh, r = crossing_scene(np.radians(degrees), 2.0 * EPS)     # overlap 0.5 eps
    n = mesh.n_dofs
    mu = 0.3
    # slave-point pairs
    pairs = search(mesh, r, slave_points(mesh, 3), 3 * EPS, np.pi * EPS)
    lam = np.zeros(slave_points(mesh, 3).s.size)
    e1, f1, K1, fN1 = contact_work(mesh, r, pairs, lam, mu, EPS)
    eF, fF, KF, fNF = contact_work(mesh, r, pairs, lam, mu, EPS, stiffen=50.0)
    assert (fN1 > 0).sum() >= 2
    assert eF == e1 and np.array_equal(fF, f1) and np.array_equal(fNF, fN1)
    _, dfN = normal_force(gap(pairs.distance, EPS), lam[pairs.slave], mu)
    Ns = shape_functions(pairs.s_xi)[0].T
    Nm = shape_functions(pairs.m_xi)[0].T
    P = np.concatenate([Ns, -Nm], axis=1)
    rows = (P[:, :, None] * pairs.normal[:, None, :]).reshape(-1, 24)
    nodes = np.concatenate([mesh.nodes[pairs.s_elem], mesh.nodes[pairs.m_elem]], axis=1)
    dofs = (6 * nodes[:, :, None] + np.arange(3)).reshape(-1, 24)
    act = np.flatnonzero(fN1 > 0)
    expect = _gram(n, dofs[act], rows[act], 49.0 * pairs.weight[act] * dfN[act])
    D = (KF - K1).toarray()
    np.testing.assert_allclose(D, expect, atol=1e-9 * np.abs(expect).max())
    assert np.linalg.eigvalsh(0.5 * (D + D.T)).min() > -1e-9 * np.abs(D).max()
    # crossing pairs
    cp = crossing_pairs(mesh, r, EPS, np.pi * EPS)
    assert cp.size >= 1
    lc = np.zeros(cp.size)
    e1, f1, K1, w1 = crossing_work(mesh, r, cp, lc, mu, EPS, fade=False)
    eF, fF, KF, wF = crossing_work(mesh, r, cp, lc, mu, EPS, fade=False, stiffen=50.0)
    assert eF == e1 and np.array_equal(fF, f1) and np.array_equal(wF, w1)
    d = gap(cp.distance if cp.length is None else cp.length, EPS)
    fN, dfN = normal_force(d, lc, mu)
    w = np.ones(cp.size) if cp.weight is None else cp.weight
    cdofs, lq = gap_gradients(mesh, cp)
    expect = _gram(n, cdofs, lq, 49.0 * w * dfN)
    D = (KF - K1).toarray()
    np.testing.assert_allclose(D, expect, atol=1e-9 * np.abs(expect).max())


def test_the_load_stepping_reads_the_constrained_test_with_contact_only(monkeypatch):
    """``stability=True``: the load stepping's test (``solver.modes``) is
    asked for the stiffened tangent when contact is on, the plain one
    without; the pressed hairpin's recorded state (in contact) reads
    stable by it."""
    from skfem_rod import Rod, Section, geometry, solver
    from skfem_rod.stability import CONTACT_STIFFENING
    from test_contact import SEC, hairpin
    seen = []
    real = solver.modes

    def spy(*a, **k):
        seen.append(k.get("stiffen", 1.0))
        return real(*a, **k)
    monkeypatch.setattr(solver, "modes", spy)
    eps = SEC.radius
    rod = Rod(hairpin(eps, 4 * eps), SEC, 40).clamp("start").add_force("end", [0, -0.6, 0])
    res = rod.enable_contact(tolerance=1e-6).solve(1, stability=True)
    assert res.converged and res.steps[-1].contact.s.size > 0
    assert res.steps[-1].lowest_eigenvalue > 0
    assert seen and set(seen) == {CONTACT_STIFFENING}
    seen.clear()
    rod = Rod(geometry.straight(1.0), Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0,
                                              GJ=0.8), 4)
    rod.clamp("start").add_force("end", [0.0, 1.0, 0.0]).solve(1, stability=True)
    assert seen and set(seen) == {1.0}
