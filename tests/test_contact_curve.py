"""The smooth contact curve (contact/curve.py): exactness on cubics, C1 at
every vertex, O(h^4) from the centreline, residual/tangent consistency of
the contact pulled back to the rod's dofs, and no ridge in the contact
energy where a closest point passes a kinked node."""
import numpy as np
import pytest

from skfem_rod import Rod
from skfem_rod.contact.assembly import contact_work
from skfem_rod.contact.curve import ContactCurve, smoothing_map
from skfem_rod.contact.search import search, slave_points
from skfem_rod.element import shape_functions
from skfem_rod.mesh import RodMesh
from skfem_rod.problem import Problem

from test_contact import SEC, hairpin


def _graded(ne, length=2.0, seed=0):
    """Vertices of a mesh with element sizes varying by up to 3x."""
    rng = np.random.default_rng(seed)
    h = rng.uniform(1.0, 3.0, ne)
    return np.r_[0.0, np.cumsum(h)] * length / h.sum()


def _curve_values(mesh, r_curve, xi):
    """The curve of every element at ``xi`` ``(ne, len(xi), 3)``, and its
    xi-derivatives, from element node values ``r_curve`` ``(4 ne, 3)``."""
    N, dN, _ = shape_functions(xi)
    rc = r_curve.reshape(-1, 4, 3)
    return np.einsum("kx,ekc->exc", N, rc), np.einsum("kx,ekc->exc", dN, rc)


@pytest.mark.parametrize("graded", [False, True])
def test_a_cubic_centreline_is_its_own_smooth_curve(graded):
    """Where the centreline is one cubic (all elements on one polynomial of
    degree 3), both one-sided derivatives are exact, and the smooth curve
    is the centreline."""
    ne = 7
    mesh = RodMesh(2.0, ne, vertices=_graded(ne) if graded else None)
    s = mesh.s_nodes
    r = np.stack([s, 1 - 2 * s**2, 0.5 * s**3 - s], axis=1)
    cc = ContactCurve(mesh)
    assert np.abs(cc.positions(r) - r[mesh.nodes].reshape(-1, 3)).max() <= 1e-13


@pytest.mark.parametrize("closed", [False, True])
def test_the_smooth_curve_is_C1_and_continuous(closed):
    """One position and one arclength tangent at every vertex (at the
    closure vertex too on a ring), while the centreline's tangent jumps."""
    rng = np.random.default_rng(3)
    ne = 9
    mesh = RodMesh(3.0, ne, vertices=_graded(ne, 3.0, seed=1), closed=closed)
    r = rng.normal(size=(mesh.n_nodes, 3))
    cc = ContactCurve(mesh)
    y, y1 = _curve_values(mesh, cc.positions(r), np.array([0.0, 1.0]))
    h = np.diff(mesh.vertices)[:, None]
    t = y1 / h[:, :, None]                              # d/ds
    nxt = np.arange(1, ne + closed) % ne
    pos_jump = np.abs(y[nxt, 0] - y[:ne - 1 + closed, 1]).max()
    tan_jump = np.abs(t[nxt, 0] - t[:ne - 1 + closed, 1]).max()
    assert pos_jump <= 1e-12 and tan_jump <= 1e-12 * np.abs(t).max()
    # the centreline itself kinks (the check above can fail)
    _, dN, _ = shape_functions(np.array([0.0, 1.0]))
    tl = np.einsum("kx,ekc->exc", dN, r[mesh.nodes]) / h[:, :, None]
    assert np.abs(tl[nxt, 0] - tl[:ne - 1 + closed, 1]).max() > 0.1


@pytest.mark.parametrize("graded", [False, True])
def test_smooth_curve_converges_at_h4(graded):
    """On a helix, the smooth curve's largest distance from the exact curve
    (dense sampling) falls as h^4 under refinement, like the P3 centreline:
    the rate fitted over four meshes."""
    def exact(s):
        return np.stack([np.cos(2 * s), np.sin(2 * s), 0.3 * s], axis=-1)
    errs, hs = [], []
    for ne in (8, 16, 32, 64):
        v = _graded(ne, 3.0, seed=ne) if graded else None
        mesh = RodMesh(3.0, ne, vertices=v)
        xi = np.linspace(0.0, 1.0, 41)
        y, _ = _curve_values(mesh, ContactCurve(mesh).positions(exact(mesh.s_nodes)), xi)
        s = mesh.vertices[:-1, None] + np.diff(mesh.vertices)[:, None] * xi
        errs.append(np.abs(y - exact(s)).max())
        hs.append(np.diff(mesh.vertices).max())
    rate = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert rate >= 3.8, (rate, errs)


def test_smoothing_map_rows_sum_to_one():
    """A rigid translation moves every curve node by the same vector (the
    map's rows sum to one) and the map touches only the element and its
    two neighbours."""
    mesh = RodMesh(1.0, 6, vertices=_graded(6, 1.0))
    S = smoothing_map(mesh)
    assert np.allclose(np.asarray(S.sum(axis=1)).ravel(), 1.0, atol=1e-13)
    for e in range(6):
        cols = np.unique(S[4 * e:4 * e + 4].nonzero()[1])
        near = np.unique(mesh.nodes[max(e - 1, 0):e + 2])
        assert set(cols) <= set(near)


def _hairpin_problem(curve, gamma_T=0.0, crossing=False, seed=0):
    rng = np.random.default_rng(seed)
    eps = 0.105                                          # legs 0.2 apart: pressed
    rod = Rod(hairpin(eps, 0.2, leg=1.0), SEC, 24)
    rod.clamp("start")
    rod.enable_contact(radius=eps, penalty=1e-3, curve=curve, gamma_T=gamma_T,
                       gamma_R=0.01 * gamma_T, crossing=crossing)
    p = Problem(rod)
    r = rod.r0 + 0.003 * rng.normal(size=rod.r0.shape)
    p.multipliers.normal[:] = 0.01 * np.abs(rng.normal(size=p.multipliers.normal.size))
    return p, r, rod.R0, rng


@pytest.mark.parametrize("gamma_T, crossing", [(0.0, False), (0.0, True), (0.3, False)])
def test_smooth_contact_residual_and_tangent_agree(gamma_T, crossing):
    """The contact on the smooth curve pulled back to the rod's dofs: the
    tangent is the derivative of the residual (central differences along a
    random update of positions and spins), and the frictionless contact
    tangent is symmetric."""
    p, r, R, rng = _hairpin_problem("smooth", gamma_T, crossing)
    ev = p.evaluate(r, R, 0.0)
    assert (ev.contact.fN > 0).sum() > 20
    d = rng.normal(size=p.mesh.n_dofs)
    d[p.fixed] = 0.0
    if gamma_T == 0:
        d.reshape(-1, 6)[:, 3:] = 0.0

    def residual(t):
        r2, R2 = p.update(r, R, t * d)
        return p.evaluate(r2, R2, 0.0, tangent=False).residual
    h = 1e-7
    fd = (residual(h) - residual(-h)) / (2 * h)
    assert np.abs(fd - ev.tangent @ d).max() <= 1e-7 * np.abs(fd).max()
    if gamma_T == 0:
        _, _, Kc = p._contact(r, R, True)
        assert abs(Kc - Kc.T).max() <= 1e-12 * abs(Kc).max()


def _kinked_energy(curve, shifts, a=np.radians(6.0), eps=0.05):
    """Contact energy of a slave strand moved by ``shifts`` along x over a
    kinked node of a master strand, on the concave side.

    Four elements of length 1: e0, e1 the master (straight, turning up by
    ``a`` at the node x = 0 between them), e2 a link far above, e3 the
    slave strand, pressed to a gap of 0.95 (2 eps) along the bisector of
    the kink.  The slave point above the node has two projections, one
    per master element; their distances cross at ``x = -y tan(a / 2)``."""
    mesh = RodMesh(4.0, 4)
    t = np.array([0.0, 1.0, 1 / 3, 2 / 3])[:, None]
    r = np.zeros((mesh.n_nodes, 3))
    r[mesh.nodes[0]] = (t - 1.0) * [1.0, 0.0, 0.0]
    r[mesh.nodes[1]] = t * [np.cos(a), np.sin(a), 0.0]
    y0, slope = 0.95 * 2 * eps, np.tan(a / 2)
    start, end = np.array([0.5, y0 + 0.5 * slope, 0]), np.array([-0.5, y0 - 0.5 * slope, 0])
    r[mesh.nodes[3]] = start + t * (end - start)
    r[mesh.nodes[2, 2:]] = [[1.5, 2.0, 0.0], [0.8, 2.0, 0.0]]
    slaves = slave_points(mesh, 3)
    cc = ContactCurve(mesh) if curve == "smooth" else None
    lam = np.full(slaves.s.size, 1.0)
    out = []
    for x in shifts:
        rx = r.copy()
        rx[mesh.nodes[3, 1:], 0] += x
        m, rr = (cc.mesh, cc.positions(rx)) if cc else (mesh, rx)
        pairs = search(m, rr, slaves, reach=4 * eps, exclusion=0.3)
        out.append(contact_work(m, rr, pairs, lam, 1e-3, eps, tangent=False)[0])
    return np.array(out)


@pytest.mark.parametrize("curve", ["elements", "smooth"])
def test_no_ridge_where_a_closest_point_passes_a_kinked_node(curve):
    """A slave point moving over a kinked node of the master on its concave
    side: on the P3 centreline the contact energy has a ridge there (the
    smaller of two distances, one per element: its second difference grows
    like 1/h), on the smooth curve it is twice differentiable (the second
    difference converges)."""
    second = []
    for h in (4e-4, 1e-4, 2.5e-5):                        # grids of step h over the ridge
        E = _kinked_energy(curve, np.arange(-0.01, 0.005 + h / 2, h))
        second.append(np.abs(np.diff(E, 2)).max() / h**2)
    if curve == "elements":
        assert second[1] > 2 * second[0] and second[2] > 2 * second[1]   # grows as 1/h
    else:
        assert max(second) <= 1.1 * min(second), second   # smooth: converges


def test_pressed_hairpin_on_the_smooth_curve_matches_the_centreline():
    """A hairpin's free leg pressed onto the clamped one (the scene of
    test_contact): on the smooth contact curve it converges at every step
    with the contact law kept, to the centreline's answer (total contact
    force and tip within the O(h^4) difference of the two curves)."""
    eps = SEC.radius
    out = {}
    for curve in ("elements", "smooth"):
        rod = Rod(hairpin(eps, 4 * eps), SEC, 40)
        rod.clamp("start").add_force("end", [0, -0.6, 0])
        rod.enable_contact(penalty=10 * eps**4 / SEC.EI1, curve=curve)
        res = rod.solve(n_steps=6)
        assert res.converged, res.message
        for st in res.steps:
            assert st.contact.penetration <= rod.contact.tolerance * eps
            assert np.all(st.contact.force > 0)
        out[curve] = (res.steps[-1].contact.total_force, res.steps[-1].r[rod.node("end")])
    (F0, x0), (F1, x1) = out["elements"], out["smooth"]
    assert F0 > 0 and abs(F1 - F0) <= 1e-6 * F0, (F0, F1)
    assert np.linalg.norm(x1 - x0) <= 1e-5 * eps, np.linalg.norm(x1 - x0) / eps
