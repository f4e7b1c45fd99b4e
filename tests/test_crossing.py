"""Curve-to-curve contact of crossing strands (skfem_rod.contact.crossing):
the true minimum distance against dense sampling, detection of crossings
that the Gauss-point pairs miss, the point-to-point contact work against
finite differences (energy -> force -> tangent), and two strands crossing
at 90 and 30 degrees pressed together, elements 10 contact radii long,
driven to a true penetration below 1e-3 radius by Newton + Uzawa."""
import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.spatial import cKDTree

from skfem_rod import Rod, Section, geometry
from skfem_rod.contact import crossing, law
from skfem_rod.contact.crossing import (ACROSS, OWN, TWIN, PairThreshold, carry, closest_points,
                                        crossing_pairs, crossing_work, local_minima, min_distance,
                                        sampled_angle)
from skfem_rod.contact.search import (monomial_coefficients, arc_distance, curve_point, search,
                                      slave_points)
from skfem_rod.element import shape_functions
from skfem_rod.mesh import RodMesh

EPS = 1.0
H = 10.0 * EPS                    # element size


def two_strands(angle, z0, u_cross=0.3, bend=0.0, rising_link=False):
    """Three elements of length H: strand A (element 0) along x, a link
    (element 1) leaving A's end downward and away from B and coming onto B's
    start from above, strand B (element 2) at ``angle`` to A in a plane
    ``z0`` above it; they cross at ``u_cross`` of both strands (between two
    Gauss points).  ``bend`` bows both strands.  ``rising_link``: the link
    rises straight from A's end instead, past B's far end (within ``2 eps``
    of it at small angles)."""
    mesh = RodMesh(3 * H, 3)
    r = np.zeros((mesh.n_nodes, 3))
    d = np.array([np.cos(angle), np.sin(angle), 0.0])
    u = np.array([0.0, 1.0, 1 / 3, 2 / 3])
    bow = bend * H * u * (1 - u)
    A = np.outer((u - u_cross) * H, [1.0, 0, 0]) + np.outer(bow, [0, 1.0, 0])
    B = np.outer((u - u_cross) * H, d) + [0, 0, z0] - np.outer(bow, [0, 0, 0.3])
    r[mesh.nodes[0]] = A
    r[mesh.nodes[2]] = B
    lift = [[0, 0, 3 * H], [0, 0, 3 * H]] if rising_link else \
        [[0, -3 * H, -3 * H], [0, -3 * H, 3 * H]]          # interior nodes u = 1/3, 2/3
    link = A[1] + np.outer(u, B[0] - A[1]) + np.r_[np.zeros((2, 3)), lift]
    r[mesh.nodes[1, 2:]] = link[2:]
    return mesh, r


def _dense_min(mesh, r, exclusion, scale, n=401):
    """Minimum distance over admissible pairs of dense samples."""
    xi = np.linspace(0, 1, n)
    N = shape_functions(xi)[0]                                  # (4, n)
    P = np.einsum("kn,ekc->enc", N, r[mesh.nodes]).reshape(-1, 3)
    v = mesh.vertices
    s = (v[:-1, None] + np.diff(v)[:, None] * xi).ravel()
    period = mesh.length if mesh.closed else None
    tree = cKDTree(P)
    best = np.inf
    for radius in scale * np.array([1.0, 3.0, 10.0, 100.0]):
        pairs = tree.query_pairs(radius, output_type="ndarray")
        if pairs.size:
            ok = arc_distance(s[pairs[:, 0]], s[pairs[:, 1]], period) >= exclusion
            if ok.any():
                d = np.linalg.norm(P[pairs[ok, 0]] - P[pairs[ok, 1]], axis=1)
                return d.min()
    return best


@pytest.mark.parametrize("angle, bend, z0", [(np.pi / 2, 0.0, 1.3), (np.pi / 6, 0.05, 0.7),
                                             (0.3, 0.1, 1.9)])
def test_min_distance_against_dense_sampling(angle, bend, z0):
    mesh, r = two_strands(angle, z0, bend=bend)
    md = min_distance(mesh, r, EPS, np.pi * EPS)
    dense = _dense_min(mesh, r, np.pi * EPS, EPS)
    assert md.distance <= dense + 1e-12
    assert dense - md.distance < 1e-4 * EPS                # samples H / 400 apart
    assert md.elements == (0, 2)


def test_min_distance_on_a_helix_and_a_ring():
    """Helix turns 2.2 eps apart (elements about 3 eps): the distance of
    neighbouring turns; a ring: nothing within reach (periodic exclusion)."""
    eps = 0.01
    rod = Rod(geometry.helix(radius=0.1, pitch=2.2 * eps, turns=3),
              Section(EA=1, GA1=1, GA2=1, EI1=1, EI2=1, GJ=1, radius=eps), 40)
    rng = np.random.default_rng(0)
    r = rod.r0 + 0.1 * eps * rng.normal(size=rod.r0.shape)
    md = min_distance(rod.mesh, r, eps, np.pi * eps)
    dense = _dense_min(rod.mesh, r, np.pi * eps, eps, n=201)
    assert md.distance <= dense + 1e-14 and dense - md.distance < 1e-4 * eps
    ring = Rod(geometry.ring(1.0), Section(EA=1, GA1=1, GA2=1, EI1=1, EI2=1, GJ=1), 16)
    assert np.isinf(min_distance(ring.mesh, ring.r0, 0.05, np.pi * 0.05).distance)


def test_closest_points_are_stationary_and_global():
    """Vectorized closest points of random pairs of curved elements (chords
    of length 1 in random directions, nodes off the chord by up to 0.1):
    never farther than the best point of a fine grid."""
    rng = np.random.default_rng(1)
    m = 100
    u = np.array([0.0, 1.0, 1 / 3, 2 / 3])[None, :, None]

    def elements(shift):
        a = rng.normal(size=(m, 1, 3)) + shift
        d = rng.normal(size=(m, 1, 3))
        d /= np.linalg.norm(d, axis=2, keepdims=True)
        return a + u * d + 0.1 * rng.normal(size=(m, 4, 3))

    C1 = monomial_coefficients(elements(0.0)).transpose(1, 2, 0)
    C2 = monomial_coefficients(elements(0.5)).transpose(1, 2, 0)
    u, v, d = closest_points(C1, C2)
    t = np.linspace(0, 1, 101)
    V = np.vander(t, 4, increasing=True)                        # (n, 4)
    P1 = np.einsum("np,pcm->mnc", V, C1)
    P2 = np.einsum("np,pcm->mnc", V, C2)
    grid = np.sqrt(((P1[:, :, None] - P2[:, None]) ** 2).sum(-1)).min(axis=(1, 2))
    assert np.all(d <= grid + 1e-12)



@pytest.mark.parametrize("angle", [np.pi / 2, np.pi / 6])
def test_crossing_between_gauss_points_is_detected(angle):
    """Strands overlapping by 0.8 eps at a crossing 0.2 H from the middle
    Gauss point: the Gauss-point pairs see nothing at 90 degrees and about
    half the overlap at 30, the crossing pair sees the overlap."""
    mesh, r = two_strands(angle, 1.2 * EPS)
    sl = slave_points(mesh, 3)
    pairs = search(mesh, r, sl, 3 * EPS, np.pi * EPS)
    seen = np.max(law.gap(pairs.distance, EPS), initial=-np.inf)
    assert seen < (0.0 if angle > 1.5 else 0.5 * EPS), seen
    cp = crossing_pairs(mesh, r, EPS, np.pi * EPS)
    assert cp.size == 1 and (cp.e[0], cp.f[0]) == (0, 2)
    assert cp.distance[0] == pytest.approx(1.2 * EPS, rel=1e-12)
    assert cp.u[0] == pytest.approx(0.3, rel=1e-10) and cp.v[0] == pytest.approx(0.3, rel=1e-10)
    assert np.allclose(cp.normal[0], [0, 0, -1.0])
    # 5 degrees: a pair (the Gauss points would miss 0.005 eps at elements
    # 10 eps long); 0.5 degrees: the minimum is flat enough for the
    # Gauss-point pairs alone (sampled_angle: 0.93 degrees at 10 eps)
    mesh, r = two_strands(np.radians(5.0), 1.2 * EPS)
    cp = crossing_pairs(mesh, r, EPS, np.pi * EPS)
    assert cp.size == 1 and cp.beta[0] == pytest.approx(np.radians(5.0), rel=1e-9)
    assert np.degrees(sampled_angle(H, EPS)) == pytest.approx(0.935, abs=1e-3)
    mesh, r = two_strands(np.radians(0.5), 1.2 * EPS)
    assert crossing_pairs(mesh, r, EPS, np.pi * EPS).size == 0


def test_every_minimum_of_an_element_pair_is_found():
    """A link rising straight from A's end (``two_strands`` with
    ``rising_link``) passes B's far end at 5 degrees: the distance between
    elements 1 and 2 has a local minimum there besides their shared node (distance 0,
    excluded).  The closest point per element pair saw the node only and hid
    the minimum (an overlap of 1.4 eps; the fixture had it in every test at
    small angles); every distinct minimum of an element pair is kept now.
    Checked against dense sampling of both elements."""
    mesh, r = two_strands(np.radians(5.0), 1.2 * EPS, rising_link=True)
    C = monomial_coefficients(r[mesh.nodes]).transpose(1, 2, 0)
    xi = np.linspace(0.0, 1.0, 2001)
    X = curve_point(np.repeat(C[:, :, [1]], xi.size, 2), xi)[0].T
    Y = curve_point(np.repeat(C[:, :, [2]], xi.size, 2), xi)[0].T
    D = np.linalg.norm(X[:, None] - Y[None], axis=2)
    D[(xi[:, None] > 0.5) & (xi[None] < 0.5)] = np.inf          # away from the shared node
    i, j = np.unravel_index(np.argmin(D), D.shape)
    assert 0 < i < xi.size - 1 and 0 < j < xi.size - 1
    around = D[i - 1:i + 2, j - 1:j + 2].ravel()
    assert np.all(np.isfinite(around)) and np.sum(around <= D[i, j]) == 1   # a strict local minimum
    cp = crossing_pairs(mesh, r, EPS, np.pi * EPS)
    link = np.flatnonzero((cp.e == 1) & (cp.f == 2))
    assert link.size == 1
    k = link[0]
    assert abs(cp.u[k] - xi[i]) < 1e-3 and abs(cp.v[k] - xi[j]) < 1e-3
    assert D[i, j] - 1e-3 <= cp.distance[k] <= D[i, j]      # samples 1/2000 element apart


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_crossing_work_energy_force_tangent(seed):
    rng = np.random.default_rng(seed)
    mesh, r = two_strands([np.pi / 2, np.pi / 6, 1.0][seed], 1.5 * EPS, bend=0.05)
    r = r + 0.05 * EPS * rng.normal(size=r.shape)
    lam, mu = 0.3, 0.1

    def work(rr, tangent=True):
        cp = crossing_pairs(mesh, rr, EPS, np.pi * EPS)
        return cp, crossing_work(mesh, rr, cp, np.full(cp.size, lam), mu, EPS, tangent)

    cp, (E, f, K, fN) = work(r)
    assert cp.size == 1 and fN[0] > 0
    d = np.zeros(mesh.n_dofs)
    d.reshape(-1, 6)[:, :3] = rng.normal(size=(mesh.n_nodes, 3))
    shift = lambda t: r + t * d.reshape(-1, 6)[:, :3]          # noqa: E731
    h = 1e-6
    (_, (Ep, fp, _, _)), (_, (Em, fm, _, _)) = work(shift(h), False), work(shift(-h), False)
    assert abs((Ep - Em) / (2 * h) - f @ d) <= 1e-7 * abs(f @ d)
    assert np.abs((fp - fm) / (2 * h) - K @ d).max() <= 1e-6 * np.abs(K @ d).max()
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()          # from an energy
    # positions only: no spin dofs touched
    assert np.abs(f.reshape(-1, 6)[:, 3:]).max() == 0


@pytest.mark.parametrize("angle", [np.pi / 2, np.pi / 6])
def test_pressed_crossing_converges_to_no_penetration(angle):
    """Springs (stiffness k per position dof) hold every node at a state in
    which the strands overlap by 0.5 eps at the crossing; Newton at fixed
    multipliers on spring + crossing contact, Uzawa on the multipliers:
    the true penetration (min_distance) falls below 1e-3 eps."""
    mesh, r_ref = two_strands(angle, 1.5 * EPS)
    k, mu = 1.0, 1.0                    # contact as stiff as the springs
    pos = (6 * np.arange(mesh.n_nodes)[:, None] + np.arange(3)).ravel()
    r = r_ref.copy()
    key, lam = np.zeros(0, np.int64), np.zeros(0)
    history = []
    for _ in range(30):
        for it in range(30):
            cp = crossing_pairs(mesh, r, EPS, np.pi * EPS)
            lam_c = carry(key, lam, cp.key)
            _, f, K, fN = crossing_work(mesh, r, cp, lam_c, mu, EPS)
            res = k * (r - r_ref).ravel() + f[pos]
            if np.abs(res).max() < 1e-12:
                break
            Kp = K[pos][:, pos] + k * np.eye(pos.size)
            r = r - np.linalg.solve(Kp.toarray() if hasattr(Kp, "toarray") else Kp,
                                    res).reshape(-1, 3)
        assert it < 29
        md = min_distance(mesh, r, EPS, np.pi * EPS)
        history.append(md.penetration(EPS))
        if md.penetration(EPS) <= 1e-3 * EPS:
            break
        key, lam = cp.key, law.uzawa_update(law.gap(cp.distance, EPS), lam_c, mu)
    assert history[0] > 0.1 * EPS                       # the penalty alone lets it in
    assert history[-1] <= 1e-3 * EPS, history
    # the contact force balances the springs: about k times the overlap
    # shared by the nodes of the two strands
    assert fN.sum() > 0


def test_min_distance_on_a_closed_rod_does_not_depend_on_the_closure_point():
    """The pinched ring of tests/test_contact_search.py with its closure
    point at the waist or elsewhere: the same closest approach."""
    from test_contact_search import _pinched_ring
    out = []
    for shift in (0, 7, 48):
        rod, r = _pinched_ring(96, 0.05, shift)
        md = min_distance(rod.mesh, r, 0.05, np.pi * 0.05)
        assert arc_distance(md.s, md.s_bar, rod.length) >= np.pi * 0.05
        out.append(md.distance)
    assert np.ptp(out) < 1e-12 and out[0] < 2 * 0.05


# -- all angles, all element sizes --------------------------------------------

def crossing_scene(angle, h, span=80.0 * EPS, z0=1.5 * EPS, at=0.37):
    """Strand A along x and strand B at ``angle`` to it in the plane
    ``z0`` above, both ``span`` long in elements ``h`` long, crossing at
    ``at`` of an element from their middle nodes (between Gauss points);
    one long link element loops high above from A's end to B's start."""
    n = int(round(span / h))
    link = 10 * span
    v = np.r_[np.arange(n + 1) * h, n * h + link + np.arange(n + 1) * h]
    mesh = RodMesh(v[-1], 2 * n + 1, vertices=v)
    r = np.zeros((mesh.n_nodes, 3))
    t = np.array([0.0, 1.0, 1 / 3, 2 / 3])
    c = (n // 2 + at) * h
    d = np.array([np.cos(angle), np.sin(angle), 0.0])
    for e in range(n):
        s = (e + t) * h - c
        r[mesh.nodes[e]] = np.outer(s, [1.0, 0, 0])
        r[mesh.nodes[n + 1 + e]] = np.outer(s, d) + [0, 0, z0]
    a, b = r[mesh.nodes[n - 1, 1]], r[mesh.nodes[n + 1, 0]]
    r[mesh.nodes[n, 2:]] = [a + [0, 0, 3 * span], b + [0, 0, 3 * span]]
    return mesh, r


def press(angle, h, k=1.0, mu_gp=1.0, mu_cp=0.2, tol=1e-3, max_uzawa=40):
    """The strands of :func:`crossing_scene` overlap by 0.5 eps; each moves
    as a rigid body (a translation) held by a spring of stiffness ``k`` to
    that place (so they stay straight: the geometry of the crossing is
    exact at any element size).  The contact of the package -- Gauss-point
    pairs (:mod:`.search`, :mod:`.assembly`) and crossing pairs with their
    held multipliers -- pushes them apart: Newton (backtracking on the
    residual) at fixed multipliers, Uzawa updates until every pair's gap is
    within ``tol`` eps.  Returns per Uzawa pass (Newton iterations, true
    penetration / eps, crossing pairs)."""
    from skfem_rod.contact.assembly import contact_work
    mesh, r_ref = crossing_scene(angle, h)
    n = (mesh.nodes.shape[0] - 1) // 2
    sl = slave_points(mesh, 3)
    pos = (6 * np.arange(mesh.n_nodes)[:, None] + np.arange(3)).ravel()
    # positions = r_ref + P @ (T_A, T_B): the strands' translations
    body = np.full(mesh.n_nodes, -1)
    body[np.unique(mesh.nodes[:n])] = 0
    body[np.unique(mesh.nodes[n + 1:])] = 1
    rows = (3 * np.flatnonzero(body >= 0)[:, None] + np.arange(3)).ravel()
    cols = (3 * np.repeat(body[body >= 0], 3).reshape(-1, 3) + np.arange(3)).ravel()
    P = sp.csc_matrix((np.ones(rows.size), (rows, cols)), shape=(pos.size, 6))
    T = np.zeros(6)
    lam_gp = np.zeros(sl.s.size)
    key, lam = np.zeros((0, 5)), np.zeros(0)

    def evaluate(T):
        r = r_ref + (P @ T).reshape(-1, 3)
        pairs = search(mesh, r, sl, 3 * EPS, np.pi * EPS)
        _, fg, Kg, _ = contact_work(mesh, r, pairs, lam_gp, mu_gp, EPS)
        cp = crossing_pairs(mesh, r, EPS, np.pi * EPS, held=(key, lam))
        lc = carry(key, lam, cp.key)
        _, fc, Kc, _ = crossing_work(mesh, r, cp, lc, mu_cp, EPS)
        res = k * T + P.T @ (fg + fc)[pos]
        K = (P.T @ (Kg + Kc).tocsc()[pos][:, pos] @ P).toarray() + k * np.eye(6)
        return res, K, pairs, cp, lc, r

    out = []
    for _ in range(max_uzawa):
        res, K, pairs, cp, lc, r = evaluate(T)
        for it in range(40):
            if np.abs(res).max() < 1e-10:
                break
            dT = np.linalg.solve(K, res)
            a = 1.0
            for _ in range(30):          # the penalty law is only piecewise smooth
                new = evaluate(T - a * dT)
                if np.linalg.norm(new[0]) < np.linalg.norm(res):
                    break
                a *= 0.5
            T = T - a * dT
            res, K, pairs, cp, lc, r = new
        dg, dc = law.gap(pairs.distance, EPS), law.gap(cp.distance, EPS)
        out.append((it, min_distance(mesh, r, EPS, np.pi * EPS).penetration(EPS) / EPS,
                    cp.size))
        if max(dg.max(initial=0.0), dc.max(initial=0.0)) <= tol * EPS:
            break
        new_gp = np.zeros_like(lam_gp)
        new_gp[pairs.slave] = law.uzawa_update(dg, lam_gp[pairs.slave], mu_gp)
        lam_gp = new_gp
        key, lam = cp.key, cp.weight * law.uzawa_update(dc, lc, mu_cp)   # as augmented.py
    return out


def test_pressed_crossing_fast():
    """90 degrees, elements 5 eps: the overlap of 0.5 eps is pushed out to
    a true penetration below 1e-3 eps."""
    out = press(np.pi / 2, 5.0 * EPS)
    assert out[0][1] > 0.01                   # the penalty alone lets it in
    assert out[-1][1] <= 1e-3, out
    assert all(o[0] < 39 for o in out)        # every Newton solve converged


@pytest.mark.slow
@pytest.mark.parametrize("h", [1.0, 5.0, 20.0])
@pytest.mark.parametrize("degrees", [90, 45, 20, 10, 5])
def test_pressed_crossing_any_angle_any_element_size(degrees, h):
    """Crossing strands at 90 to 5 degrees, elements 1 to 20 eps long:
    the true penetration (closest points, both parameters free) ends below
    1e-3 eps, every Newton solve converging."""
    out = press(np.radians(degrees), h * EPS)
    assert out[-1][1] <= 1e-3, out
    assert all(o[0] < 39 for o in out)


# -- the new terms against finite differences ---------------------------------

def _fd_check(mesh, r, held, seed=0, mu=0.1, threshold=PairThreshold(), offset=0.0):
    """Energy -> force -> tangent of the crossing pairs at ``r`` with the
    held set ``held`` fixed (as within one Newton solve), central
    differences along a random direction of the positions.  Pairs at full
    weight derive from an energy (symmetric tangent); a fading pair's
    force does not (its weight's derivative: docs/crossing-contact.md).
    ``offset``: every pair's gap offset (held within a solve)."""
    rng = np.random.default_rng(seed)

    def work(rr, tangent=True):
        cp = crossing_pairs(mesh, rr, EPS, np.pi * EPS, threshold=threshold, held=held)
        lam = carry(held[0], held[1], cp.key)
        return cp, crossing_work(mesh, rr, cp, lam, mu, EPS, tangent,
                                 offset=np.full(cp.size, offset))

    cp, (E, f, K, fN) = work(r)
    d = np.zeros(mesh.n_dofs)
    d.reshape(-1, 6)[:, :3] = rng.normal(size=(mesh.n_nodes, 3))
    shift = lambda t: r + t * d.reshape(-1, 6)[:, :3]          # noqa: E731
    h = 1e-6
    (cpp, (Ep, fp, _, _)), (cpm, (Em, fm, _, _)) = work(shift(h), False), work(shift(-h), False)
    assert cpp.size == cpm.size == cp.size
    assert np.abs((fp - fm) / (2 * h) - K @ d).max() <= 1e-6 * np.abs(K @ d).max()
    if np.all(cp.weight == 1.0):
        assert abs((Ep - Em) / (2 * h) - f @ d) <= 1e-7 * abs(f @ d)
        assert abs(K - K.T).max() <= 1e-12 * abs(K).max()
    return cp, fN


def test_near_parallel_strands_get_no_pair_even_when_held():
    """Near-parallel strands (0.5 degrees: a line contact, the Gauss
    points' job): the distance hardly rises at the probes, the minimum's
    weight is 0 and it gets no pair, loaded key or not."""
    mesh, r = two_strands(np.radians(0.5), 1.5 * EPS)
    assert crossing_pairs(mesh, r, EPS, np.pi * EPS).size == 0
    md = min_distance(mesh, r, EPS, np.pi * EPS)
    held = (np.array([[md.s, md.s_bar, H, 0.0, -1.0]]), np.array([0.4]))
    assert crossing_pairs(mesh, r, EPS, np.pi * EPS, held=held).size == 0


#: the threshold of the fading tests: ``beta_h`` = 31 degrees at elements
#: of 10 eps (tolerance 1), so that 25-30 degree crossings fade
_WIDE = PairThreshold(min_angle=np.pi / 3, n_slave=3, tolerance=1.0)


@pytest.mark.parametrize("degrees, seed", [(26.0, 0), (28.0, 1), (29.5, 2)])
def test_fading_pair_force_tangent(degrees, seed):
    """A crossing just below the threshold angle acts with a weight between
    0 and 1; its tangent, with the weight's derivative through the lowest
    probe (its own dofs and the minimum's motion), against central
    differences of the force.  The weight makes the force no energy's
    gradient: the tangent is not symmetric there."""
    mesh, r = two_strands(np.radians(degrees), 1.5 * EPS, bend=0.03)
    r = r + 1e-3 * EPS * np.random.default_rng(seed).normal(size=r.shape)
    cp, fN = _fd_check(mesh, r, (np.zeros((0, 5)), np.zeros(0)), seed=seed, mu=1.0,
                       threshold=_WIDE)
    assert cp.size == 1 and 0.0 < cp.weight[0] < 1.0 and fN[0] > 0
    K = crossing_work(mesh, r, cp, np.zeros(1), 1.0, EPS)[2]
    assert abs(K - K.T).max() > 1e-6 * abs(K).max()
    # the frozen-weight tangent the stability checks read (fade=False): the
    # weight times the tangent of the same pair at full weight, symmetric
    Kf = crossing_work(mesh, r, cp, np.zeros(1), 1.0, EPS, fade=False)[2]
    full = dataclasses.replace(cp, weight=np.ones(1), slope=None)
    K1 = crossing_work(mesh, r, full, np.zeros(1), 1.0, EPS)[2]
    assert abs(Kf - cp.weight[0] * K1).max() <= 1e-12 * abs(K1).max()
    assert abs(Kf - Kf.T).max() <= 1e-12 * abs(Kf).max()


@pytest.mark.parametrize("degrees, seed", [(26.0, 0), (29.5, 2)])
def test_a_fading_pairs_offset_fades_with_it(degrees, seed):
    """A fading pair holds the distance ``2 eps + w offset``: its gap
    offset (raised where the centrelines dipped between the points that
    held a crossing) fades with its weight, as its share of the gap does.
    Before, a pair at weight 0.06 in the plectoneme's winding kept an
    offset of 1.8e-3 eps that only it could hold: its gap stood at twice
    the tolerance through 30 Uzawa updates at every damped step.  The
    tangent, with the offset's derivative through the weight, against
    central differences; at full weight the whole offset acts."""
    mesh, r = two_strands(np.radians(degrees), 1.5 * EPS, bend=0.03)
    r = r + 1e-3 * EPS * np.random.default_rng(seed).normal(size=r.shape)
    off = 0.4 * EPS
    cp, fN = _fd_check(mesh, r, (np.zeros((0, 5)), np.zeros(0)), seed=seed, mu=1.0,
                       threshold=_WIDE, offset=off)
    w = cp.weight[0]
    assert cp.size == 1 and 0.0 < w < 1.0
    l = cp.distance[0] if cp.length is None else cp.length[0]
    assert fN[0] == pytest.approx(w * max(2 * EPS + w * off - l, 0.0), rel=1e-12)
    full = dataclasses.replace(cp, weight=np.ones(1), slope=None)
    f1 = crossing_work(mesh, r, full, np.zeros(1), 1.0, EPS, tangent=False,
                       offset=np.full(1, off))[3]
    assert f1[0] == pytest.approx(2 * EPS + off - l, rel=1e-12)


def test_the_weight_rises_continuously_with_the_angle():
    """From 20 to 35 degrees in steps of 0.05 degree: the weight is 0 below
    0.65 of the threshold's sine (the rise at the probes is below half the
    threshold's there), 1 above the threshold, monotone, and never jumps
    (the largest step change is what its slope allows)."""
    angles = np.radians(np.arange(20.0, 35.0, 0.05))
    w = np.array([crossing_pairs(*two_strands(a, 1.5 * EPS), EPS, np.pi * EPS,
                                 threshold=_WIDE).weight.tolist() or [0.0] for a in angles])[:, 0]
    beta = _WIDE.angle(H, EPS)
    assert np.all(w[np.sin(angles) < 0.65 * np.sin(beta)] == 0.0)
    assert np.all(w[angles > beta] == 1.0)
    assert np.all(np.diff(w) >= -1e-12)
    assert np.abs(np.diff(w)).max() < 0.05


def test_a_crossing_sliding_over_a_node_keeps_its_force_continuous():
    """Strand B slides along strand A across A's middle node (a 40-degree
    crossing in the fade zone of the wide threshold): the minimum changes
    its element pair there, and the pair's weight and force do not jump
    (the probes sit at fixed arclengths from the minimum, whatever element
    holds it).  Weighed by the Gauss points of the minimum's own elements,
    the weight jumped from 0.59 to 0.998 in the plectoneme."""
    mesh = RodMesh(4 * H, 4)
    u = np.array([0.0, 1.0, 1 / 3, 2 / 3])
    thr = PairThreshold(min_angle=np.radians(30.0), n_slave=3, tolerance=1.0)

    def state(x0):
        r = np.zeros((mesh.n_nodes, 3))
        r[mesh.nodes[0]] = np.outer(u - 1, [H, 0, 0])
        r[mesh.nodes[1]] = np.outer(u, [H, 0, 0])
        d = np.array([np.cos(0.45), np.sin(0.45), 0.0])
        r[mesh.nodes[3]] = np.outer((u - 0.5) * H, d) + [x0, 0, 1.9 * EPS]
        r[mesh.nodes[2, 2:]] = [[H, -H, 3 * H], [0, -H, 3 * H]]
        return r

    xs = np.linspace(-0.02, 0.02, 81) * H
    F, W, E = [], [], []
    for x0 in xs:
        r = state(x0)
        cp = crossing_pairs(mesh, r, EPS, np.pi * EPS, threshold=thr)
        assert cp.size == 1
        F.append(crossing_work(mesh, r, cp, np.zeros(1), 1.0, EPS, tangent=False)[1])
        W.append(cp.weight[0])
        E.append(cp.e[0])
    F, W = np.array(F), np.array(W)
    assert set(E) == {0, 1}                            # it crossed the node
    assert 0.0 < W.min() and W.max() < 1.0             # in the fade zone throughout
    step = np.abs(np.diff(F, axis=0)).max()
    assert step < 0.02 * np.abs(F).max()
    assert np.abs(np.diff(W)).max() < 0.02


def on_a_node():
    """Strand A bent at a node (a V pointing at strand B, crossing above the
    node at 90 degrees), four elements of length H."""
    mesh = RodMesh(4 * H, 4)
    r = np.zeros((mesh.n_nodes, 3))
    u = np.array([0.0, 1.0, 1 / 3, 2 / 3])
    r[mesh.nodes[0]] = np.outer(u - 1, [H, 0, 0]) + np.outer(u, [0, 0, 0.5 * EPS])
    r[mesh.nodes[1]] = np.outer(u, [H, 0, 0]) + np.outer(1 - u, [0, 0, 0.5 * EPS])
    r[mesh.nodes[3]] = np.outer(u - 0.4, [0, H, 0]) + [0, 0, 2.2 * EPS]
    r[mesh.nodes[2, 2:]] = [[H, 0, 3 * H], [0, -H, 3 * H]]
    return mesh, r


def test_minimum_on_a_node_energy_force_tangent():
    """Strand A bent at a node (:func:`on_a_node`): the minimum sits on the
    node (the kink of the C0 centreline holds it), found once, with u held
    and v free."""
    mesh, r = on_a_node()
    cp = crossing_pairs(mesh, r, EPS, np.pi * EPS)
    assert cp.size == 1 and not cp.u_free[0] and cp.v_free[0]
    assert cp.s[0] == pytest.approx(H) and cp.distance[0] == pytest.approx(1.7 * EPS)
    held = (cp.key, np.array([0.3]))
    _fd_check(mesh, r + 1e-3 * EPS * np.random.default_rng(2).normal(size=r.shape), held)


def test_carry_by_place():
    """A minimum keeps its multiplier when it moves to another element
    pair (within the carry radius), one old pair feeds one new pair, the
    held index wins."""
    old = np.array([[1.0, 5.0, 0.5, 0.1, -1], [3.0, 7.0, 0.5, 0.1, -1]])
    lam = np.array([2.0, 3.0])
    new = np.array([[1.2, 5.1, 0.5, 0.1, -1], [1.3, 5.0, 0.5, 0.1, -1],
                    [9.0, 9.0, 0.5, 0.1, -1], [0.0, 0.0, 0.5, 0.1, 1]])
    assert carry(old, lam, new).tolist() == [2.0, 0.0, 0.0, 3.0]
    assert carry(np.zeros(0), np.zeros(0), new).tolist() == [0.0] * 4


def test_held_pairs_without_any_minimum_in_reach():
    """Strands far apart: a loaded held pair finds nothing within reach and
    goes (no pair, no error)."""
    mesh, r = two_strands(np.pi / 2, 10 * EPS)
    held = (np.array([[3.0, 23.0, H, 1.0, -1.0]]), np.array([0.5]))
    assert crossing_pairs(mesh, r, EPS, np.pi * EPS, held=held).size == 0


@pytest.mark.parametrize("kwargs, name", [(dict(h=0.0), "h"), (dict(radius=-1.0), "radius"),
                                          (dict(tolerance=0.0), "tolerance"),
                                          (dict(n_slave=0), "n_slave")])
def test_sampled_angle_bad_input(kwargs, name):
    args = dict(h=1.0, radius=0.1, n_slave=3, tolerance=1e-3)
    args.update(kwargs)
    with pytest.raises(ValueError, match=name):
        sampled_angle(**args)


def test_the_sampling_tolerance_sets_beta_h_apart_from_the_uzawa_tolerance():
    """``crossing_sampling`` (default: the Uzawa tolerance) is the
    tolerance in ``beta_h``: the Gauss points' sag at a minimum of angle
    ``beta`` is ``(t sin beta)^2 / (4 eps)``, so a sampling tolerance 100
    times the Uzawa one raises ``sin beta_h`` tenfold.  In the knot's braid
    (60 elements, ``h`` = 3.24 eps) the wrapped strands' 1.6 degrees then lie
    below ``beta_h`` (2.9 degrees; they stay with the Gauss points) where
    the Uzawa tolerance 1e-5 alone put them above it (0.29 degrees)."""
    from skfem_rod.contact import ContactOptions
    eps, h = 0.02, 3.24 * 0.02
    base = dict(radius=eps, penalty=1e-9, exclusion=np.pi * eps, tolerance=1e-5)
    plain, wide = ContactOptions(**base), ContactOptions(**base, crossing_sampling=1e-3)
    assert plain.crossing_sampling == plain.tolerance == 1e-5
    a0, a1 = plain.crossing_threshold().angle(h, eps), wide.crossing_threshold().angle(h, eps)
    assert np.sin(a1) == pytest.approx(10.0 * np.sin(a0), rel=1e-12)
    assert np.degrees(a0) < 1.6 < np.degrees(a1) < 15.0
    # the cap still caps
    capped = ContactOptions(**base, crossing_sampling=1.0, crossing_angle=np.radians(5.0))
    assert capped.crossing_threshold().angle(h, eps) == pytest.approx(np.radians(5.0))


def _over_a_kink(alpha=0.05, d=0.19, dx=0.0):
    """Strand A: two straight elements meeting at the origin with a kink of
    ``alpha`` (element 0 along -x, element 1 turned by ``alpha``); strand B
    (element 3) a straight element along z through ``(x0 + dx, d, 0)`` on the
    concave side, ``x0 = -d tan(alpha / 2)`` on the bisector: B crosses A
    at a right angle with one closest point on each of A's elements, a hair
    apart and (``dx = 0``) equally far."""
    from skfem_rod.mesh import RodMesh
    mesh = RodMesh(4.0, 4)
    t = np.array([0.0, 1.0, 1 / 3, 2 / 3])[:, None]
    a = np.array([np.cos(alpha), np.sin(alpha), 0.0])
    x0 = -d * np.tan(alpha / 2) + dx
    r = np.zeros((mesh.n_nodes, 3))
    r[mesh.nodes[0]] = (t - 1.0) * [1.0, 0.0, 0.0]
    r[mesh.nodes[1]] = t * a
    r[mesh.nodes[3]] = [x0, d, -0.5] + t * [0.0, 0.0, 1.0]
    r[mesh.nodes[2, 2:]] = [[3.0, 3.0, 3.0], [3.0, 3.0, -3.0]]
    return mesh, r


def test_twin_minima_at_a_kink_are_one_crossing():
    """A strand crossing another over a kink of its C0 centreline has a
    closest point on each of the two elements at the node, a hair apart:
    two strict local minima of the strand distance, one crossing.  They are
    one pair (two pairs put the contact force in twice, and a held pair
    following one twin or the other from one Newton iterate to the next
    made the plectoneme's damped steps 2-cycle): the closer one, or, with a
    held pair there, the one nearest its place."""
    from skfem_rod.contact import crossing as cx
    mesh, r = _over_a_kink()
    assert cx.crossing_pairs(mesh, r, 0.1, 0.3).size == 1
    # both twins are there: closest points of (0, 3) and (1, 3), interior,
    # equally far
    C = cx.monomial_coefficients(r[mesh.nodes]).transpose(1, 2, 0)
    u, v, dist = cx.closest_points(C[:, :, [0, 1]], C[:, :, [3, 3]])
    assert 0 < u[0] < 1 and 0 < u[1] < 1 and abs(dist[0] - dist[1]) < 1e-12
    for dx, closer in ((1e-6, 1), (-1e-6, 0)):         # the closer twin
        mesh, r = _over_a_kink(dx=dx)
        cp = cx.crossing_pairs(mesh, r, 0.1, 0.3)
        assert cp.size == 1 and cp.e[0] == closer, (dx, cp.e)
    # a held pair at one twin keeps that twin, even when the other is closer
    mesh, r = _over_a_kink(dx=1e-6)
    s0 = cx.crossing_pairs(mesh, r, 0.1, 0.3)
    key0 = np.array([[0.9953, 3.5, 1.0, 1.5, -1.0]])       # at the twin on element 0
    cp = cx.crossing_pairs(mesh, r, 0.1, 0.3, held=(key0, np.array([1.0])))
    assert s0.e[0] == 1 and cp.size == 1 and cp.e[0] == 0


def test_a_held_pair_follows_its_minimum_from_the_followed_place():
    """A minimum that moved beyond its key's carry radius within a solve
    is still followed from the place recorded at the last evaluation
    (``Multipliers.crossing_places``): its pair is the held one (the key's
    index); from the key alone it is a new pair, which :func:`carry` feeds
    by place (the old key lies within the new pair's carry radius).  The
    places are part of the saved multipliers: a copy (the save before a
    step that may be rejected) follows from the places of the state it was
    taken at, not from the keys'; new keys (a multiplier update) follow
    from their own places."""
    from skfem_rod.problem import Multipliers
    mesh, r = two_strands(np.pi / 3, 1.5 * EPS)
    md = min_distance(mesh, r, EPS, np.pi * EPS)
    beta = crossing_pairs(mesh, r, EPS, np.pi * EPS).beta[0]
    key = np.array([[md.s - 0.15 * H, md.s_bar + 0.15 * H, 0.1 * H, beta, -1.0]])
    lam = np.array([0.4])
    apart = crossing_pairs(mesh, r, EPS, np.pi * EPS, held=(key, lam))
    assert apart.size == 1 and apart.key[0, 4] == -1
    assert carry(key, lam, apart.key)[0] == 0.4
    m = Multipliers.zeros(3, False)
    m.rekey_crossing(key, lam)
    assert m.held_crossing()[2][0] == pytest.approx(key[0, :2])   # from the key's place
    m.crossing_places[:] = [md.s - 0.05 * H, md.s_bar + 0.05 * H]  # the last evaluation's place
    cp = crossing_pairs(mesh, r, EPS, np.pi * EPS, held=m.held_crossing())
    assert cp.size == 1 and cp.key[0, 4] == 0 and carry(key, lam, cp.key)[0] == 0.4
    m.follow_crossing(cp)
    assert m.crossing_places[0] == pytest.approx([md.s, md.s_bar], abs=1e-9)
    saved = m.copy()
    m.follow_crossing(apart)                  # no held pair in it: places kept
    assert m.crossing_places[0] == pytest.approx([md.s, md.s_bar], abs=1e-9)
    assert saved.held_crossing()[2][0] == pytest.approx([md.s, md.s_bar], abs=1e-9)
    again = crossing_pairs(mesh, r, EPS, np.pi * EPS, held=saved.held_crossing())
    assert again.key[0, 4] == 0 and carry(key, lam, again.key)[0] == 0.4
    m.rekey_crossing(key.copy(), lam)                              # new keys
    assert m.held_crossing()[2][0, 0] == key[0, 0]


def _double_helix(n=12, a=1.05, pitch=12.0, link=3):
    """One turn of two plies of a double helix (``n`` elements each, radius
    ``a``, contact radius 1: the plies 2.1 apart) joined by a link far
    above.  The strands are wrapped around each other: their distance is
    flat along the plies (effective angle 0); on the P3 centreline it
    ripples by 5e-5, with minima inside the elements and on the nodes (the
    kinks of the C0 curve)."""
    ne = 2 * n + link
    mesh = RodMesh(float(ne), ne)
    r = np.zeros((mesh.n_nodes, 3))
    t = np.array([0.0, 1.0, 1 / 3, 2 / 3])
    ply = lambda th, ph: np.c_[a * np.cos(th + ph), a * np.sin(th + ph),     # noqa: E731
                               pitch * th / (2 * np.pi)]
    for e in range(n):
        r[mesh.nodes[e]] = ply((e + t) / n * 2 * np.pi, 0.0)
        r[mesh.nodes[n + link + e]] = ply((1 - (e + t) / n) * 2 * np.pi, np.pi)
    top1, top2 = r[mesh.nodes[n - 1, 1]], r[mesh.nodes[n + link, 0]]
    for k in range(link):
        x = (k + t) / link
        r[mesh.nodes[n + k]] = (top1 + np.outer(x, top2 - top1)
                                + np.outer(np.sin(np.pi * x), [0, 0, 8.0]))
    return mesh, r


def test_minima_on_nodes_of_wrapped_strands_are_flat():
    """Two plies of a double helix: minima of their distance sit on the
    nodes, strict only by the tiny kinks of the C0 centreline.  They are
    flat minima (a line contact: the Gauss pairs' job), not crossings: their
    angle is the smooth one of the element pair's curves.  Counted as
    crossings (a node held = strict, 90 degrees) they got point pairs, and
    in the knot the minimum of two wrapped strands hopped from one strand's
    node to the other's between Newton iterates 1.8e-7 apart; the pair
    following it made Newton 2-cycle for ever.  The sharp node minimum of
    a V over a crossing strand keeps its pair
    (test_minimum_on_a_node_energy_force_tangent)."""
    mesh, r = _double_helix()
    md = min_distance(mesh, r, 1.0, 3 * np.pi)
    assert 2.0 < md.distance < 2.1                    # in reach
    assert crossing_pairs(mesh, r, 1.0, 3 * np.pi).size == 0


#: two elements of the knot's braid (demos/knot.py, tied, 60 elements:
#: elements 7 and 52), wrapped around each other: their distance has a
#: long valley with a saddle (det F_pp < 0) that falls slowly to the
#: minimum on the end of element 52
_BRAID_PAIR = np.array([
    [[0.4383078142852699, 0.06846308524858849, 0.08024898293245153],
     [0.5012055477531275, 0.08003353234408717, 0.0903022211680185],
     [0.45912654812729076, 0.0726710350493037, 0.0841034231340897],
     [0.4800921438554178, 0.07655621871757715, 0.0874649862142422]],
    [[0.4987944516862057, 0.08003353290892834, 0.04969778210249928],
     [0.5616921852098259, 0.06846308577503958, 0.05975101994833514],
     [0.5199078555991292, 0.07655621919289576, 0.05253501682122558],
     [0.540873451332821, 0.07267103567964446, 0.05589658004352981]]])


@pytest.mark.parametrize("u0, v0", [(0.94042, 0.05695), (0.97, 0.03), (0.9, 0.1)])
def test_closest_points_run_down_a_saddle_valley(u0, v0):
    """From points in the valley, the projected Newton of the closest
    points reaches the minimum (on the end of the second element) within 8
    iterations.  Where the 2 x 2 Hessian has no minimum the step is Newton's
    on the Hessian shifted to positive definite, at most a quarter element
    long; before, coordinate steps crept along the valley by 1e-3 per
    iteration, were up to 0.06 element away after 4000 iterations, and kept
    every call of the knot's crossing search at the 40-iteration limit."""
    from skfem_rod.contact.crossing import _newton
    from skfem_rod.contact.search import curve_point
    C = monomial_coefficients(_BRAID_PAIR).transpose(1, 2, 0)
    C1, C2 = C[:, :, [0]], C[:, :, [1]]
    u, v, d = _newton(C1, C2, np.array([u0]), np.array([v0]), 8)
    # no point of a dense sampling of both elements is closer
    t = np.linspace(0.0, 1.0, 801)
    P = curve_point(np.repeat(C1, t.size, axis=2), t)[0]
    Q = curve_point(np.repeat(C2, t.size, axis=2), t)[0]
    dense = np.sqrt(((P.T[:, None] - Q.T[None]) ** 2).sum(axis=2))
    assert d[0] <= dense.min() + 1e-15
    # and along the bound v = 0, sampled finely, nothing closer either, and
    # the best sample next to it
    t = np.linspace(0.0, 1.0, 100001)
    edge = np.linalg.norm(curve_point(np.repeat(C1, t.size, axis=2), t)[0]
                          - curve_point(C2, np.zeros(1))[0], axis=0)
    assert d[0] <= edge.min() + 1e-15 and edge.min() - d[0] < 1e-12
    # the minimum of the projected problem: on the bound v = 0 with the
    # distance growing into the element, stationary in u
    X, X1, _ = (a[:, 0] for a in curve_point(C1, u))
    Y, Y1, _ = (a[:, 0] for a in curve_point(C2, v))
    D = X - Y
    scale = np.sqrt(D @ D * (X1 @ X1 + Y1 @ Y1))
    assert v[0] == 0.0 and 0.0 < u[0] < 1.0
    assert -(D @ Y1) > 0 and abs(D @ X1) <= 1e-12 * scale


def test_a_minimum_flat_at_its_place_gets_no_pair_however_steep_its_probes():
    """Strand B runs parallel to strand A and leaves it as ``|x|^3`` on
    either side of a node: the distance rises steeply at the probes (above
    the threshold's rise) but the minimum (on B's node) is flat, local
    effective angle 0: its place is ill-conditioned (it moves by
    ``delta / sin^2 beta``), so the local factor of the weight is 0 and
    there is no pair.  The same B leaving A as ``|x|`` (a V, a sharp node
    minimum) gets one of full weight."""
    mesh = RodMesh(5 * H, 5)
    u = np.array([0.0, 1.0, 1 / 3, 2 / 3])

    def build(power, c):
        r = np.zeros((mesh.n_nodes, 3))
        r[mesh.nodes[0]] = np.outer((u - 1) * H, [1, 0, 0])
        r[mesh.nodes[1]] = np.outer(u * H, [1, 0, 0])
        x3 = (1 - u) * H                                      # element 3: x from H to 0
        x4 = -u * H                                           # element 4: x from 0 to -H
        for e, x in ((3, x3), (4, x4)):
            r[mesh.nodes[e]] = np.c_[x, np.zeros(4), 1.9 * EPS + c * np.abs(x / H) ** power * H]
        r[mesh.nodes[2, 2:]] = [[H, 0, 5 * H], [H, 0, 5 * H + 1]]
        return r

    flat = crossing_pairs(mesh, build(3, 0.05), EPS, np.pi * EPS)
    assert flat.size == 0
    md = min_distance(mesh, build(3, 0.05), EPS, np.pi * EPS)
    assert md.distance == pytest.approx(1.9 * EPS)                 # in contact, on the node
    sharp = crossing_pairs(mesh, build(1, 0.05), EPS, np.pi * EPS)
    assert sharp.size == 1 and sharp.weight[0] == 1.0


def _arcs(s, k):
    """A curve along x from the origin bending towards +z, curvature
    ``k[0]`` for ``s < 0`` and ``k[1]`` for ``s > 0`` (C1 at 0, its
    curvature jumps there)."""
    kk = np.where(s < 0, k[0], k[1])
    return np.c_[np.sin(kk * s) / kk, 0 * s, (1 - np.cos(kk * s)) / kk]


def _curvature_jumps(x0, alpha=np.radians(40.0), z0=1.9 * EPS):
    """Strand A (elements 0, 1) and strand B (elements 3, 4), each two arcs
    whose curvature jumps at their middle node (A: 0.02 -> 0.1, B: 0.02 ->
    0.06 per eps), bent towards each other and crossing at ``alpha`` just
    above the two nodes, B shifted by ``x0`` along A.  The curvature term
    ``D . X''`` of the distance's Hessian is 0.19 of ``|X'|^2`` on one side
    of A's node and 0.04 on the other."""
    mesh = RodMesh(5 * H, 5)
    u = np.array([0.0, 1.0, 1 / 3, 2 / 3])
    r = np.zeros((mesh.n_nodes, 3))
    c, s = np.cos(alpha), np.sin(alpha)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    for e, lo in ((0, -H), (1, 0.0)):
        r[mesh.nodes[e]] = _arcs(lo + u * H, (0.02, 0.1))
    for e, lo in ((3, -H), (4, 0.0)):
        r[mesh.nodes[e]] = (_arcs(lo + u * H, (0.02, 0.06)) * [1, 1, -1]) @ rot.T + [x0, 0, z0]
    a, b = r[mesh.nodes[1][1]], r[mesh.nodes[3][0]]
    r[mesh.nodes[2]] = [a, b, a + [0, -3 * H, -3 * H], b + [0, -3 * H, 3 * H]]
    return mesh, r


def test_the_weight_is_continuous_where_the_curvature_jumps_at_a_node():
    """The crossing of two strands whose curvature jumps at a node slides
    across both nodes (the minimum changes both its elements).  Read from
    each element's own curve, the minimum's effective angle jumps there
    (37.2 against 28.7 degrees at A's node, the local factor of the
    weight 1 against 0.82; measured in the plectoneme at 200 elements, 26
    against 5.7 degrees, and Newton went back and forth); with the second
    derivatives blended across the node it does not, nor do the weight
    and the force."""
    thr = PairThreshold(min_angle=np.pi / 3, n_slave=3, tolerance=1.0)
    mesh, r = _curvature_jumps(0.0)
    cp = crossing_pairs(mesh, r, EPS, np.pi * EPS, threshold=thr)
    assert cp.size == 1 and cp.distance[0] == pytest.approx(1.9 * EPS)
    C = monomial_coefficients(r[mesh.nodes]).transpose(1, 2, 0)
    Y, Y1, Y2 = (a[:, 0] for a in curve_point(C[:, :, [3]], np.array([1.0])))
    own = []
    for e, u0 in ((0, 1.0), (1, 0.0)):                 # A's node, read from either side
        X, X1, X2 = (a[:, 0] for a in curve_point(C[:, :, [e]], np.array([u0])))
        D = X - Y
        huu, hvv, huv = X1 @ X1 + D @ X2, Y1 @ Y1 - D @ Y2, -X1 @ Y1
        own.append(np.degrees(np.arcsin(np.sqrt(1 - huv ** 2 / (huu * hvv)))))
    assert abs(own[0] - own[1]) > 5.0, own
    assert min(own) < np.degrees(cp.beta[0]) < max(own)

    xs = np.linspace(-0.05, 0.05, 101) * H
    F, W, B, E = [], [], [], set()
    for x0 in xs:
        mesh, r = _curvature_jumps(x0)
        cp = crossing_pairs(mesh, r, EPS, np.pi * EPS, threshold=thr)
        assert cp.size == 1
        F.append(crossing_work(mesh, r, cp, np.zeros(1), 1.0, EPS, tangent=False)[1])
        W.append(cp.weight[0])
        B.append(np.degrees(cp.beta[0]))
        E.add((int(cp.e[0]), int(cp.f[0])))
    F, W = np.array(F), np.array(W)
    assert {(0, 3), (1, 4)} <= E                       # it crossed both nodes
    assert 0.0 < W.min() and W.max() < 1.0             # in the fade zone throughout
    assert np.abs(np.diff(B)).max() < 0.2              # degrees, per 1e-3 H
    assert np.abs(np.diff(W)).max() < 0.05
    assert np.abs(np.diff(F, axis=0)).max() < 0.05 * np.abs(F).max()


@pytest.mark.parametrize("x0, seed", [(-0.012 * H, 0), (0.003 * H, 1), (0.02 * H, 2)])
def test_blended_local_factor_force_tangent(x0, seed):
    """Near nodes where the curvature jumps the local factor of the weight
    reads the second derivatives of the elements beside the pair's: the
    tangent carries their derivative (dofs of elements 0-4 for a pair of
    elements 0-1 and 3-4), checked against central differences of the
    force."""
    thr = PairThreshold(min_angle=np.pi / 3, n_slave=3, tolerance=1.0)
    mesh, r = _curvature_jumps(x0)
    r = r + 1e-4 * EPS * np.random.default_rng(seed).normal(size=r.shape)
    cp, fN = _fd_check(mesh, r, (np.zeros((0, 5)), np.zeros(0)), seed=seed, mu=1.0,
                       threshold=thr)
    assert cp.size == 1 and 0.0 < cp.weight[0] < 1.0 and fN[0] > 0
    assert min(cp.u[0], 1 - cp.u[0]) < 0.25 and min(cp.v[0], 1 - cp.v[0]) < 0.25


@pytest.mark.parametrize("x0, reading", [(-0.015 * H, (ACROSS, ACROSS)),
                                         (0.005 * H, (OWN, ACROSS)), (0.02 * H, (OWN, OWN))])
def test_fold_reading_force_tangent_at_a_node(monkeypatch, x0, reading):
    """The weight's fold reading (crossing._fold_reading) near and on the
    nodes: with its share raised to 0.9, the readings of the elements' own
    second derivatives and of the neighbours' across the nodes (plus the
    node's share ``1 - g``) win here.  Their derivative is in the tangent:
    central differences of the force."""
    monkeypatch.setattr(crossing, "FOLD_SHARE", 0.9)
    thr = PairThreshold(min_angle=np.pi / 3, n_slave=3, tolerance=1.0)
    mesh, r = _curvature_jumps(x0)
    r = r + 1e-4 * EPS * np.random.default_rng(3).normal(size=r.shape)
    cp, fN = _fd_check(mesh, r, (np.zeros((0, 5)), np.zeros(0)), mu=1.0, threshold=thr)
    assert cp.size == 1 and 0.0 < cp.weight[0] < 1.0 and fN[0] > 0
    assert tuple(cp.slope.reading[0]) == reading and cp.slope.beta[0] != 0.0


def test_fold_reading_of_a_minimum_held_on_a_kink(monkeypatch):
    """A minimum held on the kink of the C0 centreline (the V of
    ``test_minimum_on_a_node_energy_force_tangent``, its first element
    bent towards strand B, B crossing at 45 degrees) reads both elements'
    second derivatives at the node: with the fold reading's share raised to
    0.9 the bent element's wins, ``(ACROSS, OWN)`` from the element pair of
    the second one, which represents the minimum (found from both).
    Central differences of the force."""
    monkeypatch.setattr(crossing, "FOLD_SHARE", 0.9)
    thr = PairThreshold(min_angle=np.pi / 3, n_slave=3, tolerance=1.0)
    mesh = RodMesh(4 * H, 4)
    r = np.zeros((mesh.n_nodes, 3))
    u = np.array([0.0, 1.0, 1 / 3, 2 / 3])
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    r[mesh.nodes[0]] = (np.outer(u - 1, [H, 0, 0]) + np.outer(u, [0, 0, 0.5 * EPS])
                        + np.outer(10.0 * EPS * u * (u - 1), [0, 0, 1.0]))
    r[mesh.nodes[1]] = np.outer(u, [H, 0, 0]) + np.outer(1 - u, [0, 0, 0.5 * EPS])
    r[mesh.nodes[3]] = np.outer((u - 0.4) * H, d) + [0, 0, 2.2 * EPS]
    r[mesh.nodes[2, 2:]] = [[H, 0, 3 * H], [0, -H, 3 * H]]
    r = r + 1e-3 * EPS * np.random.default_rng(4).normal(size=r.shape)
    cp = crossing_pairs(mesh, r, EPS, np.pi * EPS, threshold=thr)
    assert cp.size == 1 and (cp.e[0], cp.u[0]) == (1, 0.0) and cp.v_free[0]
    cp, fN = _fd_check(mesh, r, (cp.key, np.array([0.3])), threshold=thr)
    assert cp.size == 1 and 0.0 < cp.weight[0] < 1.0 and fN[0] > 0
    assert tuple(cp.slope.reading[0]) == (ACROSS, OWN) and cp.slope.beta[0] != 0.0


def test_the_fold_reading_is_continuous_across_a_node(monkeypatch):
    """With the fold reading's share raised to 0.9 it weighs the crossing
    sliding across both nodes of ``_curvature_jumps`` (readings of either
    element, across the node and on it): the weight stays continuous,
    sampled every 1e-4 element."""
    monkeypatch.setattr(crossing, "FOLD_SHARE", 0.9)
    thr = PairThreshold(min_angle=np.pi / 3, n_slave=3, tolerance=1.0)
    W, R = [], set()
    for x0 in np.linspace(-0.05, 0.05, 1001) * H:
        mesh, r = _curvature_jumps(x0)
        cp = crossing_pairs(mesh, r, EPS, np.pi * EPS, threshold=thr)
        assert cp.size == 1
        W.append(cp.weight[0])
        R.add(tuple(cp.slope.reading[0]))
    assert {(ACROSS, ACROSS), (OWN, OWN), (ACROSS, OWN)} <= R
    assert np.abs(np.diff(W)).max() < 0.01


#: the monomial coefficients (rows: 1, t, t^2, t^3) of the smooth contact
#: curve on elements 15 and 84 of the 100-element plectoneme with friction
#: (gamma_T = 0.3, 1.96 turns), in a Newton iterate of a damped step
_KINK_C1 = np.array([[1.2879838198720606e-01, 6.1224663721364064e-02, -2.4373951809689900e-02],
                     [6.2694147953666485e-03, 7.7889723566547178e-03, 4.2986669212200651e-04],
                     [-2.4485817973546320e-04, 1.3908573652796075e-04, 7.7892244202773520e-04],
                     [1.8302492885355348e-05, -1.2480689091522168e-05, -2.1739538713403533e-04]])
_KINK_C2 = np.array([[1.2000509191022833e-01, 6.8498303008478603e-02, 2.4693876987989603e-02],
                     [5.8331522463069968e-03, -8.0511309412563264e-03, 1.2047540552053461e-03],
                     [1.9107752041053194e-04, 1.0418773026948935e-04, -1.0964746903575906e-04],
                     [1.9066381935869958e-05, 1.5983768060570669e-05, -2.4345052370163336e-04]])


def test_a_result_on_a_node_does_not_shadow_an_interior_minimum():
    """An element pair with a strict interior minimum 0.044 from a node
    and, 0.05 away in both parameters, a closer point held on that node
    (recorded in the plectoneme: the node point is no minimum of the whole
    strands, a point of the neighbour element is closer still).  Both are
    returned: the interior one is a stationary point with a positive
    definite Hessian (central differences of the two cubics).
    Before, the node result shadowed it as a twin once both parameters
    came within 0.05, the crossing pair it carried (force 19.6) vanished
    between Newton iterates 1e-5 apart, and the damped steps stopped."""
    C1, C2 = _KINK_C1[:, :, None], _KINK_C2[:, :, None]
    k, u, v, d = local_minima(C1, C2)
    powers = lambda t: np.array([np.ones_like(t), t, t * t, t ** 3])           # noqa: E731
    X = lambda t: np.einsum("k...,kc->...c", powers(t), _KINK_C1)            # noqa: E731
    Y = lambda t: np.einsum("k...,kc->...c", powers(t), _KINK_C2)            # noqa: E731
    # the interior result is a strict local minimum, checked independently
    # by central differences of the squared distance of the two cubics
    inner = np.flatnonzero((u > 0) & (u < 1) & (v > 0) & (v < 1))
    assert inner.size == 1 and 0.0 < u[inner[0]] < 0.05
    q = np.array([u[inner[0]], v[inner[0]]])
    Fq = lambda z: float(np.sum((X(np.array(z[0])) - Y(np.array(z[1]))) ** 2))   # noqa: E731
    h, e = 1e-5, np.eye(2) * 1e-5
    grad = np.array([(Fq(q + e[a]) - Fq(q - e[a])) / (2 * h) for a in range(2)])
    hess = np.array([[(Fq(q + e[a] + e[b]) - Fq(q + e[a] - e[b]) - Fq(q - e[a] + e[b])
                       + Fq(q - e[a] - e[b])) / (4 * h * h) for b in range(2)] for a in range(2)])
    lo, hi = np.linalg.eigvalsh(hess)
    assert np.abs(grad).max() <= 1e-6 * lo and lo > 1e-3 * hi
    found = inner
    node = u == 0.0
    assert node.sum() == 1 and d[node][0] < d[found][0]        # the closer node result
    assert abs(u[node][0] - q[0]) < TWIN and abs(v[node][0] - q[1]) < TWIN
