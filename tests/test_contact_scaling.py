"""Contact search on a two-ply plectoneme (geometry.plectoneme): linear
growth of the narrow-phase work under refinement, the pruned narrow phase
against an exhaustive one, and the frictionless tangent (symmetry, finite
differences) where every element pair carries contacts from both sides."""
import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.contact.assembly import contact_work
from skfem_rod.contact.search import project, search, slave_points

EPS = 1.0                       # contact radius (lengths in units of eps)
REACH, EXCL = 3 * EPS, np.pi * EPS
SEC = Section(EA=1, GA1=1, GA2=1, EI1=1, EI2=1, GJ=1, radius=EPS)


def plect_rod(n, ply_angle=0.05, turns=4):
    """Plies at superhelix radius 0.98 eps: they interpenetrate by 0.04 eps
    along their whole length (pairs active there)."""
    shape = geometry.plectoneme(0.98 * EPS, ply_angle, turns, loop=50 * EPS, tail=100 * EPS)
    return Rod(shape, SEC, n)


def test_plectoneme_shape():
    """Arclength parametrized, C1 (tangent continuous), plies 2 * radius
    apart and nothing else closer than the contact distance."""
    shape = geometry.plectoneme(0.98, 0.3, 3, loop=8.0, tail=10.0)
    s = np.linspace(0, shape.length, 6001)
    r, R = shape(s)
    ds = s[1] - s[0]
    assert np.abs(np.linalg.norm(np.diff(r, axis=0), axis=1) / ds - 1).max() < 1e-5
    t = R[:, :, 2]
    # central difference of r against the tangent: error <= kappa^2 ds^2 / 6
    assert np.linalg.norm(np.gradient(r, ds, axis=0) - t, axis=1)[1:-1].max() < 0.1 * ds**2
    assert np.linalg.norm(np.diff(t, axis=0), axis=1).max() / ds < 0.5      # curvature < 1 / (2 eps)
    from scipy.spatial import cKDTree
    P = cKDTree(r).query_pairs(2.5, output_type="ndarray")
    P = P[np.abs(s[P[:, 0]] - s[P[:, 1]]) > np.pi]
    d = np.linalg.norm(r[P[:, 0]] - r[P[:, 1]], axis=1)
    assert 2 * 0.98 - 1e-9 <= d.min() <= 2 * 0.98 + 1e-4     # sampled: never below
    assert np.allclose(r[[0, -1], 1:], 0) and r[0, 0] < 0 < r[-1, 0]      # tails on the x axis
    with pytest.raises(ValueError, match="ply_angle"):
        geometry.plectoneme(0.98, 0.9, 3)
    with pytest.raises(ValueError, match="loop"):
        geometry.plectoneme(0.98, 0.3, 3, loop=1.0)


@pytest.mark.slow
def test_candidates_and_active_pairs_grow_linearly():
    sizes = np.array([50, 100, 200, 400, 800])
    cand, active = [], []
    for n in sizes:
        rod = plect_rod(n)
        sl = slave_points(rod.mesh, 3)
        pairs = search(rod.mesh, rod.r0, sl, REACH, EXCL)
        _, _, _, fN = contact_work(rod.mesh, rod.r0, pairs, np.zeros(sl.s.size), 1e-3, EPS,
                                   tangent=False)
        cand.append(pairs.n_candidates)
        active.append(int((fN > 0).sum()))
    cand, active = np.array(cand), np.array(active)
    slope_c = np.polyfit(np.log(sizes), np.log(cand), 1)[0]
    slope_a = np.polyfit(np.log(sizes), np.log(active), 1)[0]
    assert 0.9 <= slope_c <= 1.1, (cand, slope_c)
    assert 0.9 <= slope_a <= 1.1, (active, slope_a)
    # per slave: the element holding its closest point on the other ply, a
    # neighbour when that point is near their shared node, or (off the
    # plies) the elements straddling the exclusion boundary: at most 3
    per_slave = cand / (3 * sizes)
    assert per_slave.max() <= 3.0, per_slave
    assert (active / (3 * sizes)).min() > 0.4          # the plies are in contact


@pytest.mark.parametrize("n, noise", [(100, 0.0), (200, 0.2)])
def test_pruned_narrow_phase_equals_exhaustive(n, noise):
    """The pruned narrow phase (capsule lower bounds) finds, for every slave,
    the closest admissible point that projecting the slave on every master
    element finds."""
    rod = plect_rod(n)
    rng = np.random.default_rng(n)
    r = rod.r0 + noise * EPS * rng.normal(size=rod.r0.shape)
    sl = slave_points(rod.mesh, 3)
    pairs = search(rod.mesh, r, sl, REACH, EXCL)
    x = np.einsum("qI,eIc->eqc", sl.N, r[rod.mesh.nodes]).reshape(-1, 3)
    ns, ne = x.shape[0], rod.mesh.nodes.shape[0]
    i, j = np.repeat(np.arange(ns), ne), np.tile(np.arange(ne), ns)
    xi, _ = project(x[i], r[rod.mesh.nodes[j]])
    v = rod.mesh.vertices
    s_bar = v[j] + xi * (v[j + 1] - v[j])
    from skfem_rod.element import shape_functions
    y = np.einsum("Im,mIc->mc", shape_functions(xi)[0], r[rod.mesh.nodes[j]])
    d = np.linalg.norm(x[i] - y, axis=1)
    ok = (np.abs(s_bar - sl.s.ravel()[i]) >= EXCL) & (d < REACH) & (d > 0)
    best = np.full(ns, np.inf)
    np.minimum.at(best, i[ok], d[ok])
    found = np.isfinite(best)
    assert np.array_equal(np.flatnonzero(found), pairs.slave)
    assert np.abs(best[found] - pairs.distance).max() <= 1e-12 * EPS
    assert pairs.n_candidates < 0.05 * ns * ne            # and it projects few pairs


def test_tangent_symmetric_and_matches_finite_differences():
    """Dense contact: both plies' slaves on the same element pairs (six
    pairs per element pair, summed in one block).  Tangent symmetric to
    round-off; directional derivative of the contact force by central
    differences."""
    rod = plect_rod(60)
    rng = np.random.default_rng(3)
    r = rod.r0 + 0.02 * EPS * rng.normal(size=rod.r0.shape)
    sl = slave_points(rod.mesh, 3)
    lam = 0.01 * np.abs(rng.normal(size=sl.s.size))
    mu = 1e-2

    def work(rr, tangent):
        return contact_work(rod.mesh, rr, search(rod.mesh, rr, sl, REACH, EXCL), lam, mu, EPS,
                            tangent)

    E, f, K, fN = work(r, True)
    assert (fN > 0).sum() > 50
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()
    d = np.zeros(rod.mesh.n_dofs)
    d.reshape(-1, 6)[:, :3] = rng.normal(size=(rod.mesh.n_nodes, 3))
    shift = lambda t: r + t * d.reshape(-1, 6)[:, :3]       # noqa: E731
    h = 1e-6
    dE = (work(shift(h), False)[0] - work(shift(-h), False)[0]) / (2 * h)
    assert abs(dE - f @ d) <= 1e-6 * abs(f @ d)
    fd = (work(shift(h), False)[1] - work(shift(-h), False)[1]) / (2 * h)
    assert np.abs(fd - K @ d).max() <= 1e-6 * np.abs(fd).max()
