"""The smooth node barrier of skfem_rod.contact.barrier: the scalar
barrier's smoothness, finite-difference checks of the pair energy's
gradient and Hessian, the exclusion, and the step bound (continuous
collision detection) exact on straight paths."""
import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from skfem_rod.contact.barrier import (Barrier, FrictionLag, Relaxation, barrier_work,
                                       carry_slip, friction_lag, friction_live, friction_work,
                                       node_pairs,
                                       pair_forces, potential, step_bound)


def test_potential_derivatives_and_c2_at_the_width():
    w, k = 0.3, 2.0
    g = np.linspace(0.01, 0.29, 15)
    h = 1e-6
    b, b1, b2 = potential(g, w, k)
    bp, b1p, _ = potential(g + h, w, k)
    bm, b1m, _ = potential(g - h, w, k)
    assert np.allclose((bp - bm) / (2 * h), b1, rtol=1e-7, atol=1e-9)
    assert np.allclose((b1p - b1m) / (2 * h), b2, rtol=1e-6, atol=1e-7)
    # C2 at the width: b, b', b'' all vanish there
    assert np.allclose(potential(np.array([w]), w, k), 0.0, atol=1e-14)
    # repulsive and convex inside, unbounded at contact
    assert np.all(b > 0) and np.all(b1 < 0) and np.all(b2 > 0)
    tiny = np.array([1e-12, 1e-60, 1e-150])
    bt = potential(tiny, w, k)[0]
    assert np.all(np.diff(bt) > 0)
    assert np.allclose(bt / np.log(w / tiny), k * w ** 2, rtol=1e-10)   # ~ k w^2 ln(w / g)


def _strands(seed=3):
    """Two crossing polylines (nodes 0.01 apart in arclength), the second
    lifted so that some node pairs sit inside the barrier's width."""
    rng = np.random.default_rng(seed)
    t = np.linspace(-0.1, 0.1, 21)
    a = np.stack([t, np.zeros_like(t), np.zeros_like(t)], axis=1)
    b = np.stack([0.3 * t, t, np.full_like(t, 0.05)], axis=1)
    x = np.concatenate([a, b]) + 1e-4 * rng.standard_normal((42, 3))
    s = np.concatenate([t + 0.1, t + 1.1])        # the strands are far apart along the rod
    return x, s


def test_gradient_and_hessian_match_finite_differences():
    x, s = _strands()
    bw = Barrier(distance=0.05 - 2e-3, width=0.01, stiffness=50.0, exclusion=0.05)
    w0 = barrier_work(x, s, bw, dofs=3)
    assert w0.active > 0 and np.isfinite(w0.energy) and 0 < w0.min_gap < bw.width
    H = w0.hessian.toarray()
    assert np.allclose(H, H.T)
    rng = np.random.default_rng(7)
    v = rng.standard_normal(x.shape)
    h = 1e-7
    ep = barrier_work(x + h * v, s, bw, hessian=False).energy
    em = barrier_work(x - h * v, s, bw, hessian=False).energy
    slope = float(np.sum(w0.gradient * v))
    assert abs((ep - em) / (2 * h) - slope) <= 1e-6 * max(abs(slope), 1.0)
    gp = barrier_work(x + h * v, s, bw, hessian=False).gradient
    gm = barrier_work(x - h * v, s, bw, hessian=False).gradient
    fd = ((gp - gm) / (2 * h)).ravel()
    Hv = H @ v.ravel()
    assert np.linalg.norm(fd - Hv) <= 1e-5 * np.linalg.norm(Hv)


def test_hessian_layout_with_six_dofs_per_node():
    x, s = _strands()
    bw = Barrier(distance=0.048, width=0.01, stiffness=50.0, exclusion=0.05)
    H3 = barrier_work(x, s, bw, dofs=3).hessian.toarray()
    H6 = barrier_work(x, s, bw, dofs=6).hessian.toarray()
    pos = (np.arange(6 * len(x)) % 6) < 3
    assert np.allclose(H6[np.ix_(pos, pos)], H3)
    assert not np.any(H6[~pos]) and not np.any(H6[:, ~pos])


def test_pairs_closer_than_the_exclusion_never_touch():
    # a hairpin: nodes along a tight U are close in space, some also in arclength
    th = np.linspace(0, np.pi, 40)
    x = np.stack([0.03 * np.cos(th), 0.03 * np.sin(th), np.zeros_like(th)], axis=1)
    s = 0.03 * th
    pr = node_pairs(x, s, 0.07, exclusion=0.05)
    assert pr.size > 0
    assert np.all(np.abs(s[pr[:, 0]] - s[pr[:, 1]]) >= 0.05)
    assert node_pairs(x, s, 0.07, exclusion=1.0).shape == (0, 2)


@pytest.mark.parametrize("spread", [None, 1.0])
def test_the_kept_pair_list_finds_every_pair_the_tree_finds(spread):
    """The barrier's pairs from the contact search's kept candidates
    (:class:`~skfem_rod.contact.search.NeighbourList`, the ``near`` of
    :func:`barrier_work` and :func:`step_bound`) against a fresh k-d tree
    over a random walk of a coiled rod's nodes (steps of a small share of
    the skin, some long ones that force a rebuild; reaches of the barrier
    and of step bounds): the same pairs at every call, and the
    candidates found anew far less often than asked for; with the
    margin of the contact search's curve points (``spread`` None) and
    the node pairs' own, twice the skin (``spread`` 1, the solve's)."""
    from skfem_rod.contact.barrier import _near_pairs, _pairs
    from skfem_rod.contact.search import NeighbourList
    rng = np.random.default_rng(11)
    t = np.linspace(0, 6 * np.pi, 300)
    x = np.c_[np.cos(t), np.sin(t), 0.05 * t]              # pitch 0.31: coils in reach
    s = t * np.sqrt(1 + 0.05 ** 2)
    bw = Barrier(distance=0.3, width=0.01, stiffness=1.0, exclusion=0.5)
    near = NeighbourList(skin=0.05) if spread is None else NeighbourList(skin=0.05,
                                                                         spread=spread)
    calls = found = 0
    for k in range(200):
        big = k % 50 == 49
        x = x + rng.standard_normal(x.shape) * (0.2 if big else 0.002)
        for reach in (bw.distance + bw.width, bw.distance + rng.uniform(0, 0.01)):
            got, want = _near_pairs(x, s, reach, bw, near), _pairs(x, s, reach, bw)
            calls += 1
            found += want.shape[0] > 0
            assert set(map(tuple, got)) == set(map(tuple, want))
    assert found > calls / 2                   # pairs to find at most calls
    assert 4 <= near.builds < calls / 4


def test_the_kept_pair_list_of_nodes_finds_a_pair_closing_in_by_almost_the_skin():
    """Node pairs with the margin twice the skin (``spread`` 1): two nodes
    that close in on each other straight, each by just under the skin in
    small steps, from just beyond the reach plus the margin the list was
    found with, are in reach at the end and found by the kept list (no
    rebuild) -- the margin is exactly what no node moving by less than the
    skin can cross; a shorter one (1.9 skins) misses the pair."""
    from skfem_rod.contact.barrier import _near_pairs, _pairs
    from skfem_rod.contact.search import NeighbourList
    bw = Barrier(distance=0.3, width=0.01, stiffness=1.0, exclusion=0.5)
    skin, reach = 0.05, 0.31
    for spread, kept in ((1.0, True), (0.95, False)):
        near = NeighbourList(skin=skin, spread=spread)
        gap = reach + 1.99 * skin
        x = np.array([[0.0, 0, 0], [gap, 0, 0], [5.0, 0, 0]])
        s = np.array([0.0, 1.0, 2.0])
        assert _near_pairs(x, s, reach, bw, near).shape == (0, 2)
        for _ in range(10):
            x = x + np.array([[0.0999 * skin, 0, 0], [-0.0999 * skin, 0, 0], [0, 0, 0]])
            got = _near_pairs(x, s, reach, bw, near)
        assert near.builds == 1
        assert _pairs(x, s, reach, bw).shape == (1, 2)
        assert (got.shape == (1, 2)) is kept


def test_a_kept_node_pattern_gives_the_matrix_a_fresh_one_gives():
    """:class:`NodePattern` against the entry-by-entry sparse sum of the
    blocks: new blocks on the kept node list (no new pattern), a new list
    (a new pattern), pairs repeated and a node twice in one tuple; the
    indices sorted, no duplicates, as the solve's sparse sums expect."""
    import scipy.sparse as sp
    from skfem_rod.contact.barrier import NodePattern, _blocks
    rng = np.random.default_rng(5)
    pat = NodePattern()
    n, dofs, m = 40, 6, 6
    lists = [rng.integers(0, n, (60, 2)), None, rng.integers(0, n, (70, 2))]
    lists[1] = lists[0]
    lists[2][:5] = lists[2][5:10]                       # pairs repeated
    lists[2][10, 1] = lists[2][10, 0]                   # a node twice
    for k, nodes in enumerate(lists):
        blk = rng.standard_normal((nodes.shape[0], 2 * m, 2 * m))
        H = pat.matrix(blk, nodes, n, dofs, m)
        dof = (nodes[:, :, None] * dofs + np.arange(m)).reshape(nodes.shape[0], -1)
        want = _blocks(blk, dof, n * dofs)
        assert abs(H - want).max() <= 1e-13 * abs(want).max()
        canon = sp.csc_matrix((H.data.copy(), H.indices.copy(), H.indptr.copy()),
                              shape=H.shape)
        canon.has_canonical_format = False
        canon.sum_duplicates()                          # sorts, sums duplicates
        assert np.array_equal(canon.indices, H.indices) and canon.nnz == H.nnz
        assert pat.builds == (1, 1, 2)[k]


def test_overlapping_nodes_have_infinite_energy():
    x, s = _strands()
    bw = Barrier(distance=0.2, width=0.01, stiffness=1.0, exclusion=0.05)
    w = barrier_work(x, s, bw)
    assert w.energy == np.inf and w.min_gap < 0
    # the pairs' normal forces: infinite at or inside D, 0 beyond the width,
    # -b'(g) between (the barrier's gradient along the pair's normal)
    pr = node_pairs(x, s, 1.0, bw.exclusion)
    mid = Barrier(distance=0.1, width=0.01, stiffness=1.0, exclusion=0.05)
    pf = pair_forces(x, pr, mid)
    g = pf.distance - mid.distance
    assert np.all(pf.force[g <= 0] == np.inf) and (g <= 0).any()
    assert np.all(pf.force[g >= mid.width] == 0) and (g >= mid.width).any()
    wide = Barrier(distance=0.05, width=0.2, stiffness=1.0, exclusion=0.05)
    pf = pair_forces(x, pr, wide)
    g = pf.distance - wide.distance
    on = (g > 0) & (g < wide.width)
    assert on.sum() >= 3
    assert np.allclose(pf.force[on], -potential(g[on], wide.width, wide.stiffness)[1])
    assert np.allclose(np.linalg.norm(pf.normal, axis=1), 1.0)


def test_step_bound_is_the_first_contact_on_straight_paths():
    bw = Barrier(distance=0.05, width=0.001, stiffness=1.0, exclusion=0.5)
    x = np.array([[0.0, 0.0, 0.0], [0.2, 0.03, 0.0]])
    s = np.array([0.0, 1.0])
    dx = np.array([[0.0, 0.0, 0.0], [-0.4, 0.0, 0.0]])
    # |(0.2 - 0.4 t, 0.03)| = 0.05 first at 0.4 t = 0.2 - 0.04, t = 0.4
    assert step_bound(x, dx, s, bw, fraction=1.0) == pytest.approx(0.4, rel=1e-12)
    assert step_bound(x, dx, s, bw, fraction=0.8) == pytest.approx(0.32, rel=1e-12)
    # moving apart, or passing wide, is not bounded
    assert step_bound(x, -dx, s, bw) == 1.0
    x2 = x + np.array([[0.0, 0.0, 0.0], [0.0, 0.1, 0.0]])
    assert step_bound(x2, dx, s, bw) == 1.0


def test_step_bound_keeps_random_moves_outside_contact():
    rng = np.random.default_rng(11)
    x, s = _strands()
    bw = Barrier(distance=0.045, width=0.002, stiffness=1.0, exclusion=0.05)
    assert barrier_work(x, s, bw, hessian=False).min_gap > 0
    for _ in range(20):
        dx = 0.05 * rng.standard_normal(x.shape)
        a = step_bound(x, dx, s, bw, fraction=0.8)
        assert 0 < a <= 1
        for t in np.linspace(0, a, 9):
            assert barrier_work(x + t * dx, s, bw, hessian=False).min_gap > 0


def _touching_arcs(a, radius, distance, curvature, angle):
    """Two circular arcs of curvature ``curvature``, bulging towards each
    other, crossing at ``angle`` with each strand's nodes (``a`` apart)
    half a spacing from the crossing, moved apart until their closest node
    pair is ``distance`` apart; returns the true least distance of the
    arcs (their apexes' distance)."""
    u = a * (np.arange(-3, 3) + 0.5)                     # the nodes' arclengths
    t = np.linspace(-3 * a, 3 * a, 4001)

    def arc(u, sign, phi):
        # apex at 0, bulging along +z (sign +1) or -z, along direction phi
        R = 1 / curvature if curvature else np.inf
        along = R * np.sin(u / R) if curvature else u
        drop = R * (1 - np.cos(u / R)) if curvature else 0 * u
        return np.c_[along * np.cos(phi), along * np.sin(phi), -sign * drop]

    A, B = arc(u, 1, 0.0), arc(u, -1, angle)
    node = np.linalg.norm(A[:, None] - B[None], axis=2).min()   # at apex distance 0
    h = distance - node                  # lifts the node distance to D (to first order)
    for _ in range(50):                  # exactly: the apex distance h with nodes at D
        node = np.linalg.norm(A[:, None] - (B + [0, 0, h])[None], axis=2).min()
        h += distance - node
    At, Bt = arc(t, 1, 0.0), arc(t, -1, angle) + [0, 0, h]
    # the densely sampled arcs' least distance by a k-d tree (the 4001^2
    # distance matrix took a gigabyte)
    return min(float(cKDTree(At).query(Bt)[0].min()), h)


@pytest.mark.parametrize("angle", [np.pi / 2, np.pi / 6, 0.0])
@pytest.mark.parametrize("bent", [False, True])
def test_for_nodes_keeps_strands_apart_between_their_nodes(angle, bent):
    """D keeps the centrelines 2 eps apart where the node pairs touch:
    strands crossing at any angle with both strands' nodes half a spacing
    from the crossing, straight or bent towards each other at the largest
    curvature of a tube that does not overlap itself (``TUBE_CURVATURE /
    eps``; the sag between nodes).  Measured on densely sampled arcs; the
    terms of fourth order in ``a / eps`` that the formula leaves out are in
    its favour (the tightest case, bent strands crossing at right angles,
    keeps 0.2 % of the offset: 2 % less offset fails it)."""
    from skfem_rod.contact.barrier import TUBE_CURVATURE
    s = np.random.default_rng(5).permutation(np.linspace(0, 1, 301))     # any order
    radius = 0.025
    bw = Barrier.for_nodes(s, radius=radius, width=0.02, force=1.0)
    a = 1 / 300
    curvature = TUBE_CURVATURE / radius if bent else 0.0
    true = _touching_arcs(a, radius, bw.distance, curvature, angle)
    assert true >= 2 * radius
    # and not by far: D exceeds 2 eps by the formula's offset only
    assert bw.distance - 2 * radius <= 3 * a ** 2 / (8 * radius) * (1 + 1e-12)


def test_for_nodes_sets_the_barrier_from_its_options():
    s = np.random.default_rng(5).permutation(np.linspace(0, 1, 301))     # any order
    bw = Barrier.for_nodes(s, radius=0.025, width=0.02, force=1.0)
    assert bw.width == pytest.approx(5e-4)
    assert -potential(np.array([bw.width / 2]), bw.width, bw.stiffness)[1][0] == \
        pytest.approx(1.0, rel=1e-12)
    assert bw.exclusion == pytest.approx(np.pi * 0.025)
    with pytest.raises(ValueError, match="width"):
        Barrier.for_nodes(s, radius=0.025, width=-1.0)
    with pytest.raises(ValueError, match="radius"):
        Barrier.for_nodes(s, radius=float("nan"))


# -- friction at the node pairs ------------------------------------------------

def _rotations(n, seed):
    return Rotation.random(n, random_state=seed).as_matrix()


def _spin(R, w):
    return Rotation.from_rotvec(w).as_matrix() @ R


def _friction_case(seed=3):
    x, s = _strands(seed)
    bw = Barrier(distance=0.05 - 2e-3, width=0.01, stiffness=50.0, exclusion=0.05)
    R0 = _rotations(len(x), seed)
    rng = np.random.default_rng(seed + 1)
    x0 = x - 3e-3 * rng.standard_normal(x.shape)          # the step's start
    R = np.stack([_spin(R0[k], 0.05 * rng.standard_normal(3)) for k in range(len(x))])
    lag = friction_lag(x, R, x0, R0, s, bw)
    return x, R, lag


def test_friction_gradient_matches_finite_differences_in_positions_and_spins():
    x, R, lag = _friction_case()
    assert lag.pairs.shape[0] > 0 and np.all(lag.force > 0)
    for eps_v in (1e-2, 1e-4):               # mostly sticking / mostly slipping
        w = friction_work(x, R, lag, mu=0.3, eps_v=eps_v)
        rng = np.random.default_rng(9)
        v = rng.standard_normal((len(x), 6))
        h = 1e-7

        def energy(t):
            Rt = np.stack([_spin(R[k], t * v[k, 3:]) for k in range(len(x))])
            return friction_work(x + t * v[:, :3], Rt, lag, 0.3, eps_v, hessian=False).energy
        fd = (energy(h) - energy(-h)) / (2 * h)
        slope = float(np.sum(w.gradient * v))
        assert abs(fd - slope) <= 1e-6 * max(abs(slope), 1e-3)
        # the Hessian is exact in positions and spins (the arms turning with
        # the sections included, which is not symmetric); its positions'
        # block is symmetric and positive semi-definite
        def gradient(t):
            Rt = np.stack([_spin(R[k], t * v[k, 3:]) for k in range(len(x))])
            return friction_work(x + t * v[:, :3], Rt, lag, 0.3, eps_v, hessian=False).gradient
        fdH = ((gradient(h) - gradient(-h)) / (2 * h)).ravel()
        Hv = w.hessian @ v.ravel()
        assert np.linalg.norm(fdH - Hv) <= 1e-6 * np.linalg.norm(Hv)
        H = w.hessian.toarray()
        pos = (np.arange(H.shape[0]) % 6) < 3
        Hp = H[np.ix_(pos, pos)]
        assert np.allclose(Hp, Hp.T)
        assert np.linalg.eigvalsh(Hp).min() > -1e-9 * np.abs(Hp).max()


def test_live_friction_jacobian_matches_finite_differences_in_positions_and_spins():
    """With the normal forces live (each pair's force from its own gap),
    the friction force equals the lagged one where the lag was taken, and
    its (non-symmetric) Jacobian is the exact derivative of the force in
    positions and spins, the normal forces' change and the arms' rotation
    included."""
    x, R, lag = _friction_case()
    bw = Barrier(distance=0.05 - 2e-3, width=0.01, stiffness=50.0, exclusion=0.05)
    i, j = lag.pairs[:, 0], lag.pairs[:, 1]
    # the contact points on both sections (the lag's arms) and their separation
    c_i = np.einsum("kab,kb->ka", R[i], lag.arm_i)
    c_j = np.einsum("kab,kb->ka", R[j], lag.arm_j)
    delta = x[i] + c_i - x[j] - c_j
    for eps_v in (1e-2, 1e-4):               # mostly sticking / mostly slipping
        w = friction_live(x, R, lag, bw, mu=0.3, eps_v=eps_v)
        lagged = friction_work(x, R, lag, 0.3, eps_v)
        # where the lag was taken the forces are the lag's; the live friction
        # applies both of a pair's forces at the midpoint of its two points
        assert np.allclose(w.force, lagged.force, rtol=1e-12, atol=1e-14)
        assert np.allclose(w.gradient[:, :3], lagged.gradient[:, :3], rtol=1e-12, atol=1e-14)
        shift = np.zeros((len(x), 3))
        arm = np.cross(-0.5 * delta, -w.force)              # the arm moved by -delta / 2
        np.add.at(shift, i, arm)
        np.add.at(shift, j, arm)
        assert np.allclose(w.gradient[:, 3:], lagged.gradient[:, 3:] + shift,
                           rtol=1e-12, atol=1e-14)
        assert np.abs(shift).max() > 1e-3 * np.abs(lagged.gradient[:, 3:]).max()
        # so the pairs' forces and moments balance exactly (about any point);
        # the lagged potential's leave the couples delta x phi
        f, m = w.gradient[:, :3], w.gradient[:, 3:]
        scale = np.abs(f).max() * np.abs(x).max()
        assert np.abs(f.sum(axis=0)).max() <= 1e-14 * np.abs(f).max() * len(x)
        assert np.abs((np.cross(x, f) + m).sum(axis=0)).max() <= 1e-13 * scale
        fl, ml_ = lagged.gradient[:, :3], lagged.gradient[:, 3:]
        assert np.abs((np.cross(x, fl) + ml_).sum(axis=0)).max() > 1e-6 * scale
        rng = np.random.default_rng(11)
        v = rng.standard_normal((len(x), 6))
        h = 1e-7

        def force(t):
            Rt = np.stack([_spin(R[k], t * v[k, 3:]) for k in range(len(x))])
            return friction_live(x + t * v[:, :3], Rt, lag, bw, 0.3, eps_v,
                                 jacobian=False).gradient
        fd = ((force(h) - force(-h)) / (2 * h)).ravel()
        Jv = w.hessian @ v.ravel()
        assert np.linalg.norm(fd - Jv) <= 1e-6 * np.linalg.norm(Jv)
        # the normal forces' change makes it non-symmetric
        H = w.hessian.toarray()
        assert np.abs(H - H.T).max() > 1e-3 * np.abs(H).max()


def test_friction_forces_obey_coulomb():
    """Each pair's force is at most mu lambda, along -slip, and equal to it
    where the pair slips by eps_v or more."""
    x, R, lag = _friction_case(5)
    mu = 0.3
    eps_v = float(np.median(friction_work(x, R, lag, mu, 1.0).slip))   # half stick, half slip
    w = friction_work(x, R, lag, mu, eps_v)
    f = np.linalg.norm(w.force, axis=1)
    bound = mu * lag.force
    assert np.all(f <= bound * (1 + 1e-12))
    slipping = w.slip >= eps_v
    assert slipping.any() and (~slipping).any()
    assert np.allclose(f[slipping], bound[slipping], rtol=1e-12)
    # along -slip, in the plane normal to the lagged normal
    assert np.allclose(np.einsum("ka,ka->k", w.force, lag.normal), 0.0, atol=1e-12 * bound.max())


def test_a_rigid_motion_of_the_step_gives_no_slip():
    """Translate and rotate the whole configuration rigidly from the step's
    start: the surface points move together, no slip, no friction."""
    x0, s = _strands(2)
    bw = Barrier(distance=0.05 - 2e-3, width=0.01, stiffness=50.0, exclusion=0.05)
    R0 = _rotations(len(x0), 2)
    Q = _spin(np.eye(3), np.array([0.3, -0.4, 0.2]))           # 0.54 rad
    x = x0 @ Q.T + np.array([0.1, -0.2, 0.05])
    R = np.einsum("ab,kbc->kac", Q, R0)
    lag = friction_lag(x, R, x0, R0, s, bw)
    w = friction_work(x, R, lag, mu=0.3, eps_v=1e-4)
    assert lag.pairs.shape[0] > 0
    assert w.slip.max() < 1e-14
    live = friction_live(x, R, lag, bw, mu=0.3, eps_v=1e-4)
    assert live.slip.max() < 1e-14
    assert np.abs(live.gradient).max() < 1e-12 * np.abs(lag.force).max()


def test_carried_slips_start_the_step_with_the_friction_the_state_had():
    """The slips of the lag a state was solved with, carried into a step
    from that state: each pair's slip there, its part in the plane normal
    to the new lag's normal, cut to eps_v (the force is the same: the law
    is flat beyond); the friction at the step's start is then the state's
    own, pair by pair (without the carry it is zero), and it moves with a
    rigid motion of the step as the slips turn with the sections."""
    x, R, lag = _friction_case(5)
    mu = 0.3
    had = friction_work(x, R, lag, mu, 1.0)
    eps_v = float(np.median(had.slip))                # half stick, half slip
    bw = Barrier(distance=0.05 - 2e-3, width=0.01, stiffness=50.0, exclusion=0.05)
    _, s = _strands(5)
    start = friction_lag(x, R, x, R, s, bw)           # a new step from (x, R)
    assert friction_work(x, R, start, mu, eps_v).slip.max() < 1e-15
    carried = carry_slip(start, x, R, lag, eps_v)
    assert np.array_equal(carried.pairs, start.pairs)
    assert np.array_equal(carried.force, start.force)
    at = {tuple(p): k for k, p in enumerate(lag.pairs)}
    k = np.array([at[tuple(p)] for p in carried.pairs])   # every pair is lag's
    # the slip at the start: the old one's tangential part, cut to eps_v
    i, j = carried.pairs[:, 0], carried.pairs[:, 1]
    old = (x[i] + np.einsum("kab,kb->ka", R[i], lag.arm_i[k])) \
        - (x[j] + np.einsum("kab,kb->ka", R[j], lag.arm_j[k]))
    n = start.normal
    ut = old - np.einsum("ka,ka->k", old, n)[:, None] * n
    y = np.linalg.norm(ut, axis=1)
    want = ut * np.minimum(1.0, eps_v / y)[:, None]
    new = (x[i] + np.einsum("kab,kb->ka", R[i], carried.arm_i)) \
        - (x[j] + np.einsum("kab,kb->ka", R[j], carried.arm_j))
    assert np.abs(new - want).max() <= 1e-12 * np.abs(x).max()
    assert (y > eps_v).any() and (y < eps_v).any()
    # the friction force is the state's, at the start's normals and forces
    # (here the same state: the old lag's normals were the step's start's)
    w = friction_work(x, R, carried, mu, eps_v)
    w_old = friction_work(x, R, FrictionLag(lag.pairs[k], n, carried.force, lag.arm_i[k],
                                            lag.arm_j[k]), mu, eps_v)
    assert np.allclose(w.force, w_old.force, rtol=0, atol=1e-12 * mu * carried.force.max())
    assert np.linalg.norm(w.force, axis=1).max() > 0.5 * mu * carried.force.max()
    # a rigid motion moves both material points alike: the carried slip
    # turns with it, its size kept
    Q = _spin(np.eye(3), np.array([0.4, -0.3, 0.5]))
    xq, Rq = x @ Q.T + 0.1, np.einsum("ab,kbc->kac", Q, R)
    moved = (xq[i] + np.einsum("kab,kb->ka", Rq[i], carried.arm_i)) \
        - (xq[j] + np.einsum("kab,kb->ka", Rq[j], carried.arm_j))
    assert np.abs(moved - new @ Q.T).max() <= 1e-12 * np.abs(x).max()
    # a pair the old lag does not have starts from zero slip
    fewer = FrictionLag(lag.pairs[1:], lag.normal[1:], lag.force[1:], lag.arm_i[1:],
                        lag.arm_j[1:])
    part = carry_slip(start, x, R, fewer, eps_v)
    first = np.flatnonzero((start.pairs == lag.pairs[0]).all(axis=1))
    assert np.array_equal(part.arm_i[first], start.arm_i[first])
    assert np.array_equal(part.arm_j[first], start.arm_j[first])

# -- the rotational law: the pivot about the normal ----------------------------

@pytest.mark.parametrize("mu", [0.0, 0.3])
def test_rotational_friction_derivatives_match_finite_differences(mu):
    """The rotational law (the pivot about the normal, alone or with the
    tangential law): the lagged potential's gradient and Hessian, and the
    live couple's Jacobian (the normal and the normal force live), are the
    exact derivatives in positions and spins, sticking and slipping; the
    live pair's two couples balance."""
    x, R, lag = _friction_case()
    bw = Barrier(distance=0.05 - 2e-3, width=0.01, stiffness=50.0, exclusion=0.05)
    mu_R = 0.01
    pivot = np.abs(friction_work(x, R, lag, mu, 1e-3, mu_R=mu_R, eps_R=1.0).pivot)
    assert np.median(pivot) > 1e-2                 # the sections turned within the step
    for eps_R in (1.0, 1e-3):                      # every pair sticking / most slipping
        w = friction_work(x, R, lag, mu, 1e-3, mu_R=mu_R, eps_R=eps_R)
        live = friction_live(x, R, lag, bw, mu, 1e-3, mu_R=mu_R, eps_R=eps_R)
        rng = np.random.default_rng(9)
        v = rng.standard_normal((len(x), 6))
        h = 1e-7

        def at(t, live_=False):
            Rt = np.stack([_spin(R[k], t * v[k, 3:]) for k in range(len(x))])
            if live_:
                return friction_live(x + t * v[:, :3], Rt, lag, bw, mu, 1e-3, jacobian=False,
                                     mu_R=mu_R, eps_R=eps_R)
            return friction_work(x + t * v[:, :3], Rt, lag, mu, 1e-3, hessian=False,
                                 mu_R=mu_R, eps_R=eps_R)
        plus, minus = at(h), at(-h)
        slope = float(np.sum(w.gradient * v))
        assert abs((plus.energy - minus.energy) / (2 * h) - slope) <= 1e-6 * abs(slope)
        Hv = w.hessian @ v.ravel()
        fd = ((plus.gradient - minus.gradient) / (2 * h)).ravel()
        assert np.linalg.norm(fd - Hv) <= 1e-6 * np.linalg.norm(Hv)
        Jv = live.hessian @ v.ravel()
        fd = ((at(h, True).gradient - at(-h, True).gradient) / (2 * h)).ravel()
        assert np.linalg.norm(fd - Jv) <= 1e-6 * np.linalg.norm(Jv)
        f, m = live.gradient[:, :3], live.gradient[:, 3:]
        scale = np.abs(m).max() + np.abs(f).max() * np.abs(x).max()
        assert np.abs((np.cross(x, f) + m).sum(axis=0)).max() <= 1e-13 * scale
        # without the rotational law the spins' force differs
        plain = friction_live(x, R, lag, bw, mu, 1e-3)
        assert np.abs(live.gradient[:, 3:] - plain.gradient[:, 3:]).max() > 0.1 * mu_R


def test_rotational_friction_obeys_coulomb_for_couples():
    """The live couple on each pair is about the live normal, against the
    pivot, at most mu_R lambda and equal to it where the pair pivots by
    eps_R or more."""
    x, R, lag = _friction_case(5)
    bw = Barrier(distance=0.05 - 2e-3, width=0.01, stiffness=50.0, exclusion=0.05)
    mu_R = 0.02
    theta = friction_work(x, R, lag, 0.3, 1e-3, mu_R=mu_R, eps_R=1.0).pivot
    eps_R = float(np.median(np.abs(theta)))        # half stick, half slip
    w = friction_live(x, R, lag, bw, 0.3, 1e-3, mu_R=mu_R, eps_R=eps_R)
    lam = pair_forces(x, lag.pairs, bw).force
    nrm = pair_forces(x, lag.pairs, bw).normal
    size = np.linalg.norm(w.couple, axis=1)
    assert np.all(size <= mu_R * lam * (1 + 1e-12))
    pivoting = np.abs(w.pivot) >= eps_R
    assert pivoting.any() and (~pivoting).any()
    assert np.allclose(size[pivoting], mu_R * lam[pivoting], rtol=1e-12)
    along = np.einsum("ka,ka->k", w.couple, nrm)
    assert np.allclose(np.abs(along), size, rtol=1e-12)             # about the normal
    assert np.all(along * w.pivot <= 0)                              # against the pivot
    assert np.all(along[w.pivot != 0] * w.pivot[w.pivot != 0] < 0)


def test_a_rigid_motion_gives_no_pivot_and_turns_a_carried_one():
    """A rigid rotation of 0.5 rad of the whole configuration over a step
    gives no pivot and no couple, to round-off; the pivots carried into a
    step (cut to eps_R) and their couples are the same after a rigid
    rotation, the couples turned with it; a record of the pivots gives
    them back."""
    x0, s = _strands(2)
    bw = Barrier(distance=0.05 - 2e-3, width=0.01, stiffness=50.0, exclusion=0.05)
    R0 = _rotations(len(x0), 2)
    Q = _spin(np.eye(3), 0.5 * np.array([0.6, -0.8, 0.0]))     # 0.5 rad
    x = x0 @ Q.T + np.array([0.1, -0.2, 0.05])
    R = np.einsum("ab,kbc->kac", Q, R0)
    lag = friction_lag(x, R, x0, R0, s, bw)
    live = friction_live(x, R, lag, bw, 0.0, 1e-4, mu_R=0.01, eps_R=1e-4)
    assert lag.pairs.shape[0] > 0
    assert np.abs(live.pivot).max() < 1e-14
    assert np.abs(live.gradient).max() < 1e-12 * np.abs(lag.force).max()
    # the pivots of a step, carried into the next from its state
    x1, R, old = _friction_case(5)
    _, s1 = _strands(5)
    had = friction_live(x1, R, old, bw, 0.3, 1e-3, mu_R=0.01, eps_R=1.0)
    eps_R = float(np.median(np.abs(had.pivot)))
    start = friction_lag(x1, R, x1, R, s1, bw)
    carried = carry_slip(start, x1, R, old, 1e-3, eps_R)
    now = friction_live(x1, R, carried, bw, 0.3, 1e-3, mu_R=0.01, eps_R=eps_R)
    at = {tuple(p): k for k, p in enumerate(old.pairs)}
    k = np.array([at[tuple(p)] for p in carried.pairs])
    want = np.clip(had.pivot[k], -eps_R, eps_R)
    assert np.abs(now.pivot - want).max() <= 1e-12
    assert (np.abs(had.pivot[k]) > eps_R).any() and (np.abs(had.pivot[k]) < eps_R).any()
    xq, Rq = x1 @ Q.T + 0.1, np.einsum("ab,kbc->kac", Q, R)
    turned = friction_live(xq, Rq, carried, bw, 0.3, 1e-3, mu_R=0.01, eps_R=eps_R)
    assert np.abs(turned.pivot - now.pivot).max() <= 1e-12
    assert np.abs(turned.couple - now.couple @ Q.T).max() <= 1e-12 * np.abs(now.couple).max()


def test_the_lag_keeps_each_pairs_history():
    """Pairs in contact at the step's start slip from there (the two
    material points coincided at the start's midpoint); a pair that met
    during the step has no slip where it met; a later lag keeps the points
    of the pairs an earlier lag had."""
    x0, s = _strands(4)
    bw = Barrier(distance=0.05 - 2e-3, width=0.01, stiffness=50.0, exclusion=0.05)
    R0 = _rotations(len(x0), 4)
    rng = np.random.default_rng(5)
    x = x0 + 2e-3 * rng.standard_normal(x0.shape)
    R = np.stack([_spin(R0[k], 0.05 * rng.standard_normal(3)) for k in range(len(x0))])
    start = friction_lag(x0, R0, x0, R0, s, bw)
    now = friction_lag(x, R, x0, R0, s, bw)             # every pair from the start
    assert start.pairs.shape[0] > 3 and now.pairs.shape[0] > 3
    # the points coincide at the start: the slip is their separation now
    i, j = now.pairs[:, 0], now.pairs[:, 1]
    p_i0 = x0[i] + np.einsum("kab,kb->ka", R0[i], now.arm_i)
    p_j0 = x0[j] + np.einsum("kab,kb->ka", R0[j], now.arm_j)
    assert np.allclose(p_i0, 0.5 * (x0[i] + x0[j]), atol=1e-15)
    assert np.allclose(p_i0, p_j0, atol=1e-15)
    # with half the start's pairs held, the others slip from where they are now
    held = start.pairs[::2]
    met = friction_lag(x, R, x0, R0, s, bw, held=held)
    is_held = (met.pairs[:, None, :] == held[None, :, :]).all(axis=2).any(axis=1)
    assert is_held.any() and (~is_held).any()
    w = friction_work(x, R, met, mu=0.3, eps_v=1e-4)
    assert w.slip[~is_held].max() < 1e-15
    assert np.allclose(w.slip[is_held], friction_work(x, R, now, 0.3, 1e-4).slip[is_held],
                       rtol=1e-12)
    # a later lag of the step keeps the points of the pairs it has
    x2 = x + 1e-3 * rng.standard_normal(x.shape)
    later = friction_lag(x2, R, x0, R0, s, bw, met, held)
    at = {tuple(p): k for k, p in enumerate(met.pairs)}
    both = [(k, at[tuple(p)]) for k, p in enumerate(later.pairs) if tuple(p) in at]
    assert len(both) > 3
    a, b = np.array(both).T
    assert np.array_equal(later.arm_i[a], met.arm_i[b])
    assert np.array_equal(later.arm_j[a], met.arm_j[b])


def test_aitken_relaxation_settles_a_creeping_and_an_alternating_fixed_point():
    """On the linear fixed-point map lambda -> c + M lambda of normal forces
    (eigenvalues 0.93 and -0.93: a lag that creeps and one that
    alternates), Aitken's relaxation reaches the fixed point to 1e-10 in
    under a quarter of the lags the plain iteration needs (over 250)."""
    n = 6
    pairs = np.c_[np.arange(n), np.arange(n) + 10]
    rng = np.random.default_rng(2)
    Q = np.linalg.qr(rng.standard_normal((n, n)))[0]
    for ev in (0.93, -0.93):
        M = Q @ np.diag(ev * np.linspace(0.2, 1.0, n)) @ Q.T
        c = 5.0 + rng.random(n)
        fixed = np.linalg.solve(np.eye(n) - M, c)

        def lag_of(force):
            z = np.zeros((n, 3))
            return FrictionLag(pairs, z, force, z, z)
        relax = Relaxation(20)
        lag = lag_of(np.zeros(n))
        for k in range(100):
            new = lag_of(c + M @ lag.force)              # the state's forces
            if np.abs(new.force - lag.force).max() <= 1e-10 * fixed.max():
                break
            lag = relax(new, lag)
        assert k < 60
        assert np.allclose(lag.force, fixed, rtol=1e-9)
        plain = np.zeros(n)
        for m in range(2000):
            nxt = c + M @ plain
            if np.abs(nxt - plain).max() <= 1e-10 * fixed.max():
                break
            plain = nxt
        assert m > 250


def test_crossing_strands_keep_their_distance_where_the_nodes_miss_the_crossing():
    """Two straight strands crossing at right angles, nodes half a spacing
    from the crossing on both: at the node barrier's contact distance the
    centrelines are 2 eps apart plus what D keeps for the sag of bent
    strands (``2 TUBE_CURVATURE a^2 / (8 eps)``)."""
    from skfem_rod.contact.barrier import TUBE_CURVATURE
    eps, a = 0.025, 0.01
    D = Barrier.for_nodes(np.arange(0, 1.0 + a / 2, a), eps).distance
    t = (np.arange(-10, 10) + 0.5) * a
    d = np.sqrt(D ** 2 - 2 * (a / 2) ** 2)          # the nearest nodes exactly D apart
    x = np.concatenate([np.c_[t, 0 * t, 0 * t], np.c_[0 * t, t, d + 0 * t]])
    s = np.concatenate([t + 1.0, t + 3.0])
    pr = node_pairs(x, s, 1.0, exclusion=0.5)
    dist = np.linalg.norm(x[pr[:, 0]] - x[pr[:, 1]], axis=1)
    assert dist.min() == pytest.approx(D, rel=1e-12)
    # to second order in a / eps (0.4 here: the next order is 1.2 % of it)
    assert d - 2 * eps == pytest.approx(2 * TUBE_CURVATURE * a ** 2 / (8 * eps), rel=0.02)
    assert d >= 2 * eps


# -- the bend barrier (module doc, "Local self-contact") ----------------------
def _bent_polyline(seed=3, n=12, turn=(0.45, 0.6)):
    rng = np.random.default_rng(seed)
    th = np.cumsum(rng.uniform(*turn, n))
    x = 0.1 * np.column_stack([np.cumsum(np.cos(th)), np.cumsum(np.sin(th)),
                               0.1 * rng.standard_normal(n)])
    return x, np.linspace(0.0, 1.0, n), rng


@pytest.mark.parametrize("closed", [False, True])
def test_bend_barrier_gradient_and_hessian_match_finite_differences(closed):
    from skfem_rod.contact.barrier import Bend, bend_work
    x, s, rng = _bent_polyline()
    if closed:                 # a ring: 12 nodes on a perturbed circle, 0.52 rad a node
        th = 2 * np.pi * np.arange(12) / 12
        x = 0.1 * np.column_stack([np.cos(th), np.sin(th), 0 * th])
        x += 0.003 * rng.standard_normal(x.shape)
        s = th / (2 * np.pi)
    bend = Bend(np.argsort(s), closed, limit=0.9 if closed else 0.75, width=0.3 if closed else 0.2,
                stiffness=3.0)
    w = bend_work(x, bend)
    assert np.isfinite(w.energy) and w.active > 0
    H = w.hessian.toarray()
    assert np.allclose(H, H.T, atol=1e-10 * np.abs(H).max())
    v = rng.standard_normal(x.shape)
    h = 1e-6
    ep, em = (bend_work(x + t * v, bend, hessian=False) for t in (h, -h))
    slope = float(np.sum(w.gradient * v))
    assert abs((ep.energy - em.energy) / (2 * h) - slope) <= 1e-6 * abs(slope)
    Hv = H @ v.ravel()
    fd = ((ep.gradient - em.gradient) / (2 * h)).ravel()
    assert np.linalg.norm(fd - Hv) <= 1e-5 * np.linalg.norm(Hv)
    # internal: no net force, no net moment
    assert np.allclose(w.gradient.sum(axis=0), 0, atol=1e-10 * np.abs(w.gradient).max())
    assert np.allclose(np.cross(x, w.gradient).sum(axis=0), 0,
                       atol=1e-10 * np.abs(w.gradient).max())


def test_bend_barrier_acts_only_beyond_its_onset_and_forbids_the_limit():
    from skfem_rod.contact.barrier import Bend, bend_work
    eps, EI, n = 0.025, 0.3, 61
    s = np.linspace(0.0, 0.3, n)
    bend = Bend.for_rod(s, eps, EI)
    a = s[1] - s[0]
    assert bend.limit == pytest.approx(2.0 * a / eps)

    def arc(rho):              # nodes on a circle of radius rho, chord a
        phi = 2 * np.arcsin(a / (2 * rho)) * np.arange(n)
        return np.column_stack([rho * np.sin(phi), rho * (1 - np.cos(phi)), 0 * phi])
    # a circle of radius 1/1.4 eps: inside the onset, nothing
    w = bend_work(arc(eps / 1.4), bend)
    assert w.energy == 0.0 and w.active == 0 and not np.any(w.gradient)
    # of radius eps / 1.8: the barrier resists the bending (its moment
    # tightening the circle is positive), of radius eps / 2.05 infinite
    w = bend_work(arc(eps / 1.8), bend)
    assert np.isfinite(w.energy) and w.energy > 0 and w.active == n - 2
    assert bend_work(arc(eps / 2.05), bend).energy == np.inf
    # at half the width a node resists with the moment EI * 2 / eps
    phi = np.arccos(np.cos(bend.limit) + bend.width / 2)
    from skfem_rod.contact.barrier import potential
    _, b1, _ = potential(np.array([bend.width / 2]), bend.width, bend.stiffness)
    assert -b1[0] * np.sin(phi) == pytest.approx(EI * 2.0 / eps * np.sin(phi)
                                                  / np.sin(bend.limit))


def _tilted_frames(x, rng, tilt=(0.3, 0.5)):
    """Frames whose d3 is turned off the centreline's local direction by
    ``tilt`` radians."""
    n = x.shape[0]
    R = np.empty((n, 3, 3))
    for k in range(n):
        t = x[min(k + 1, n - 1)] - x[max(k - 1, 0)]
        t /= np.linalg.norm(t)
        a = np.cross(t, [0, 0, 1.0])
        a /= np.linalg.norm(a)
        d3 = Rotation.from_rotvec(rng.uniform(*tilt) * a).as_matrix() @ t
        d1 = np.cross([0, 1.0, 0], d3)
        d1 /= np.linalg.norm(d1)
        R[k] = np.column_stack([d1, np.cross(d3, d1), d3])
    return R


def test_shear_barrier_gradient_and_tangent_match_finite_differences():
    """In positions and spatial spins (R <- exp(w) R): the tangent is the
    derivative of the gradient along the update, position and spin rows
    and columns each."""
    from skfem_rod.contact.barrier import Shear, shear_work
    rng = np.random.default_rng(4)
    s = np.linspace(0, 1, 10)
    x = np.column_stack([s, 0.05 * np.sin(3 * s), 0.02 * np.cos(2 * s)])
    R = _tilted_frames(x, rng)
    shear = Shear(np.argsort(s), False, limit=0.7, width=0.3, stiffness=2.0)
    w = shear_work(x, R, shear)
    assert np.isfinite(w.energy) and w.active > 10
    v = rng.standard_normal((10, 6))
    h = 1e-6

    def moved(t, u):
        turn = Rotation.from_rotvec(t * u[:, 3:]).as_matrix()
        return x + t * u[:, :3], np.einsum("kab,kbc->kac", turn, R)
    ep, em = (shear_work(*moved(t, v), shear, hessian=False) for t in (h, -h))
    slope = float(np.sum(w.gradient * v))
    assert abs((ep.energy - em.energy) / (2 * h) - slope) <= 1e-6 * abs(slope)
    for part in (np.r_[1, 1, 1, 0, 0, 0], np.r_[0, 0, 0, 1, 1, 1]):
        u = v * part
        gp, gm = (shear_work(*moved(t, u), shear, hessian=False).gradient for t in (h, -h))
        Hv = w.hessian @ u.ravel()
        assert np.linalg.norm((gp - gm).ravel() / (2 * h) - Hv) <= 1e-6 * np.linalg.norm(Hv)


def test_shear_barrier_is_off_for_sections_along_the_centreline_and_forbids_the_limit():
    from skfem_rod.contact.barrier import Shear, shear_work
    rng = np.random.default_rng(5)
    s = np.linspace(0, 1, 21)
    x = np.column_stack([s, 0.1 * np.sin(2 * s), 0 * s])
    shear = Shear.for_rod(s, 0.05, 1.0)
    assert shear.limit == pytest.approx(0.05 / 0.05 + 0.5)
    # sections along the centreline (the reference's): nothing
    assert shear_work(x, _tilted_frames(x, rng, (0.0, 1e-9)), shear).energy == 0.0
    # tilted into the barrier: a finite energy; beyond the limit: infinite
    assert 0 < shear_work(x, _tilted_frames(x, rng, (1.35, 1.4)), shear).energy < np.inf
    assert shear_work(x, _tilted_frames(x, rng, (1.6, 1.7)), shear).energy == np.inf
