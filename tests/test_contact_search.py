"""Contact search with the bounded broad phase (skfem_rod.contact.search):
the same pairs as the exhaustive search of tests/search_reference.py on the
scenes of the contact tests; a number of candidates per slave that does not
grow when the elements get much shorter than the contact radius; and the
periodic exclusion of closed rods (an unloaded ring has no contact, the
pairs of a pinched ring do not depend on where its closure point is)."""
import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.contact import search as search_mod
from skfem_rod.contact.search import search, slave_points

from search_reference import search_dense
from test_contact import SEC, hairpin
from test_contact_scaling import plect_rod


def _same_pairs(a, b):
    """Same slaves, distances, master points and normals (the master
    element may differ where the projection is a vertex shared by two
    elements: the same point)."""
    assert np.array_equal(a.slave, b.slave)
    assert np.array_equal(a.distance, b.distance)
    assert np.array_equal(a.s_bar, b.s_bar)
    assert np.abs(a.normal - b.normal).max() < 1e-12
    assert np.array_equal(a.weight, b.weight)
    diff = a.m_elem != b.m_elem
    assert np.all(np.isin(a.m_xi[diff], [0.0, 1.0])) and np.all(np.isin(b.m_xi[diff], [0.0, 1.0]))
    same = ~diff
    assert np.array_equal(a.m_xi[same], b.m_xi[same])
    assert np.array_equal(a.normal[same], b.normal[same])
    assert np.array_equal(a.interior[same], b.interior[same])
    assert a.n_candidates <= b.n_candidates


SCENES = [("hairpin", n, noise) for n in (16, 64, 256, 1000) for noise in (0.0, 0.003)] + [
    ("plectoneme", n, noise) for n in (100, 200) for noise in (0.0, 0.2)] + [
    ("helix", 400, 0.0), ("helix", 400, 0.3)]


@pytest.mark.parametrize("scene, n, noise", SCENES)
def test_search_equals_exhaustive_reference(scene, n, noise):
    rng = np.random.default_rng(n + int(100 * noise))
    if scene == "hairpin":
        eps = 0.105
        rod = Rod(hairpin(eps, 0.2, leg=1.0), SEC, n)
        reach, excl, scale = 2 * eps + 0.05, np.pi * eps, 1.0
    elif scene == "plectoneme":
        eps, rod = 1.0, plect_rod(n)
        reach, excl, scale = 3.0, np.pi, 1.0
    else:                                   # turns 2.2 eps apart, h ~ 3 eps
        eps = 0.01
        rod = Rod(geometry.helix(radius=0.1, pitch=2.2 * eps, turns=4),
                  Section(EA=1, GA1=1, GA2=1, EI1=1, EI2=1, GJ=1, radius=eps), n)
        reach, excl, scale = 3 * eps, np.pi * eps, eps
    r = rod.r0 + noise * scale * rng.normal(size=rod.r0.shape)
    sl = slave_points(rod.mesh, 3)
    new = search(rod.mesh, r, sl, reach, excl)
    assert new.size > 0
    _same_pairs(new, search_dense(rod.mesh, r, sl, reach, excl))


@pytest.mark.parametrize("length", [5000.0, 800.0])
def test_broad_phase_candidates_per_slave_bounded(length):
    """Hairpin with touching legs, contact radius 1, element size from 10
    down to 0.1 radii: the (slave, element) candidates the broad phase
    materializes stay a few per slave (the exhaustive k-d tree query grows
    as the number of elements within reach, 60 per slave at h = 0.1)."""
    import sys
    import pathlib
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks"))
    from bench_search import hairpin_mesh
    per_slave = []
    for n in (500, 2000, 8000):
        mesh, r = hairpin_mesh(length, n)
        sl = slave_points(mesh, 3)
        x = np.einsum("qI,eIc->eqc", sl.N, r[mesh.nodes]).reshape(-1, 3)
        i, j = search_mod._broad_phase(x, sl.s.ravel(), r[mesh.nodes], mesh.vertices,
                                       3.0, np.pi, None)
        per_slave.append(i.size / x.shape[0])
    assert max(per_slave) <= 4.0, per_slave


def test_hairpin_mesh_numbering_is_rodmesh():
    """The benchmark's light-weight mesh numbers nodes as RodMesh does."""
    import sys
    import pathlib
    sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "benchmarks"))
    from bench_search import hairpin_mesh
    mesh, r = hairpin_mesh(40.0, 40)
    rod = Rod(hairpin(0.99, 1.98, leg=(40.0 - np.pi * 0.99) / 2), SEC, 40)
    assert np.array_equal(mesh.nodes, rod.mesh.nodes)
    assert np.allclose(mesh.vertices, rod.mesh.vertices)
    assert np.abs(r - rod.r0).max() < 1e-9


def _pinched_ring(n, eps, shift=0):
    """A ring of radius 1 squeezed in the middle (a peanut: its two halves
    come within 1.9 eps at x = 0); its closure point is at the waist
    (``shift = 0``) or ``shift`` elements further on."""
    rod = Rod(geometry.ring(1.0), SEC, n)
    assert rod.mesh.closed
    a = 0.95 * eps
    theta = rod.mesh.s_nodes + np.pi / 2 + 2 * np.pi * shift / n      # s = 0 at the waist
    r = np.stack([np.cos(theta), np.sin(theta) * (a + (1 - a) * np.cos(theta) ** 2),
                  0 * theta], axis=1)
    return rod, r


def test_unloaded_ring_has_no_contact():
    """The exclusion is periodic: slaves beside the closure point do not
    see their neighbours across it (the non-periodic search does)."""
    eps = 0.05
    rod = Rod(geometry.ring(1.0), SEC, 64)
    sl = slave_points(rod.mesh, 3)
    reach, excl = 3 * eps, np.pi * eps
    pairs = search(rod.mesh, rod.r0, sl, reach, excl)
    assert pairs.size == 0
    near = search_dense(rod.mesh, rod.r0, sl, reach, excl)      # the old, open exclusion
    assert near.size > 0 and np.all(np.minimum(near.s, rod.length - near.s) < excl)
    # rotated and translated: still none
    from skfem_rod.rotations import expm
    Q = expm(np.array([0.4, -0.3, 1.2]))
    assert search(rod.mesh, rod.r0 @ Q.T + 3.0, sl, reach, excl).size == 0


def test_pinched_ring_pairs_do_not_depend_on_the_closure_point():
    eps, n = 0.05, 96
    out = []
    for shift in (0, 7, 48):
        rod, r = _pinched_ring(n, eps, shift)
        sl = slave_points(rod.mesh, 3)
        pairs = search(rod.mesh, r, sl, 3 * eps, np.pi * eps)
        # the waist is in contact: its upper arc, which straddles the
        # closure point when shift = 0, against the lower one (the tight
        # lobes touch themselves too; no matter: the same everywhere)
        s_top = (-2 * np.pi * shift / n) % rod.length
        top = search_mod.arc_distance(pairs.s, s_top, rod.length) < 0.2
        assert top.sum() >= 6
        assert np.all(search_mod.arc_distance(pairs.s_bar[top], s_top + np.pi, rod.length) < 0.2)
        assert np.all(search_mod.arc_distance(pairs.s, pairs.s_bar, rod.length) >= np.pi * eps)
        out.append(np.sort(pairs.distance))
    for o in out[1:]:
        assert o.size == out[0].size
        np.testing.assert_allclose(o, out[0], rtol=0, atol=1e-12)


def _kinked(alpha, h, dx):
    """Two straight master elements meeting at the origin with a kink of
    ``alpha`` (element 0 along -x, element 1 turned by ``alpha``); element 3
    a straight slave segment at height ``h`` on the concave side, its middle
    Gauss point at ``x = x0 + dx`` where ``x0 = -h tan(alpha / 2)`` is
    equally far (``h``) from both elements."""
    from skfem_rod.mesh import RodMesh
    mesh = RodMesh(4.0, 4)
    t = np.array([0.0, 1.0, 1 / 3, 2 / 3])[:, None]
    a = np.array([np.cos(alpha), np.sin(alpha), 0.0])
    x0 = -h * np.tan(alpha / 2)
    r = np.zeros((mesh.n_nodes, 3))
    r[mesh.nodes[0]] = (t - 1.0) * [1.0, 0.0, 0.0]
    r[mesh.nodes[1]] = t * a
    r[mesh.nodes[3]] = [x0 + dx - 0.5, h, 0.0] + t * [1.0, 0.0, 0.0]
    r[mesh.nodes[2, 2:]] = [[a[0] + 0.5, 1.0, 1.0], [x0 + dx - 1.0, 1.0, 1.0]]
    return mesh, r


def test_a_slave_keeps_its_master_element_at_a_kink():
    """At a node where the centreline kinks, a slave on the concave side has
    a projection on both elements, equally far when it is on the bisector:
    the closest one switches element as the slave crosses it (the normal
    jumps by the kink angle; Newton 2-cycled on it in the plectoneme).  With
    a Preference the last element is kept while its distance is within the
    tolerance of the closest, and the distance it reports is its own (at
    most the tolerance above the closest)."""
    alpha, h, tol = 0.05, 0.2, 1e-4
    slave = 3 * 3 + 1                              # middle Gauss point of element 3
    sl = slave_points(_kinked(alpha, h, 0.0)[0])

    def closest(dx, prefer=None):
        mesh, r = _kinked(alpha, h, dx)
        p = search(mesh, r, sl, reach=0.5, exclusion=0.3, prefer=prefer)
        k = np.flatnonzero(p.slave == slave)
        assert k.size == 1
        return int(p.m_elem[k[0]]), float(p.distance[k[0]])

    # without a preference: the closer element, switching at the bisector
    assert closest(-1e-7)[0] == 0 and closest(1e-7)[0] == 1
    assert abs(closest(-1e-7)[1] - h) < 1e-12
    # kept while within the tolerance: element 0 is h, element 1 is
    # h - dx sin(alpha) away
    keep = search_mod.Preference(np.zeros(sl.s.size, int), tol)
    dx = 0.5 * tol / np.sin(alpha)
    e, d = closest(dx, keep)
    assert e == 0 and abs(d - h) < 1e-12
    assert 0 < d - closest(dx)[1] <= tol
    assert closest(2.0 * tol / np.sin(alpha), keep)[0] == 1
    # the other way round too
    keep1 = search_mod.Preference(np.ones(sl.s.size, int), tol)
    assert closest(-dx, keep1)[0] == 1 and closest(-2.0 * tol / np.sin(alpha), keep1)[0] == 0


def test_a_kept_master_element_is_an_orthogonal_projection():
    """The kept master element must hold the slave's orthogonal projection
    (interior): where the closest point has crossed the node onto the next
    element, the last element's projection is clamped at its end, a hair
    farther but not orthogonal (its normal tilted by ``dx / h``).  Kept, it
    made the residual depend on the last evaluation: on the smooth contact
    curve (no kink) the plectoneme's damped Newton 2-cycled between two
    states 9e-5 apart (residual 0.032 <-> 0.044), one slave carrying 1420
    held at the end of element 12 while its closest point was 5e-4 into
    element 13; from a fresh search the same state had residual 0.008."""
    h, tol, dx = 0.2, 1e-4, 1e-3                   # dx^2 / 2h = 2.5e-6 < tol
    slave = 3 * 3 + 1
    mesh, r = _kinked(0.0, h, dx)                  # a straight master: no kink
    sl = slave_points(mesh)
    keep = search_mod.Preference(np.zeros(sl.s.size, int), tol)
    p = search(mesh, r, sl, reach=0.5, exclusion=0.3, prefer=keep)
    k = np.flatnonzero(p.slave == slave)[0]
    assert p.m_elem[k] == 1 and p.interior[k]
    assert p.m_xi[k] == pytest.approx(dx, abs=1e-12) and p.distance[k] == pytest.approx(h, abs=1e-14)
    np.testing.assert_allclose(p.normal[k], [0.0, 1.0, 0.0], atol=1e-13)


@pytest.mark.parametrize("scene", ["hairpin", "plectoneme", "helix"])
def test_neighbour_list_gives_the_search_without_it(scene):
    """A :class:`NeighbourList` keeps the broad phase's pairs while the
    nodes stay within its skin: along a random motion of the nodes (lists
    kept for a few searches and rebuilt after), every search with the list returns the
    pairs of a search without it, bit for bit (moves of 0.3 skin per
    search); a growing reach rebuilds."""
    rng = np.random.default_rng({"hairpin": 1, "plectoneme": 2, "helix": 3}[scene])
    if scene == "hairpin":
        eps = 0.105
        rod = Rod(hairpin(eps, 0.2, leg=1.0), SEC, 64)
        reach, excl = 2 * eps + 0.05, np.pi * eps
    elif scene == "plectoneme":
        eps, rod = 1.0, plect_rod(100)
        reach, excl = 3.0, np.pi
    else:
        eps = 0.01
        rod = Rod(geometry.helix(radius=0.1, pitch=2.2 * eps, turns=4),
                  Section(EA=1, GA1=1, GA2=1, EI1=1, EI2=1, GJ=1, radius=eps), 400)
        reach, excl = 3 * eps, np.pi * eps
    sl = slave_points(rod.mesh, 3)
    nl = search_mod.NeighbourList(skin=0.5 * eps)
    r = rod.r0.copy()
    drift = rng.normal(size=r.shape)              # a steady motion, and noise
    for k in range(16):
        step = drift + 0.5 * rng.normal(size=r.shape)
        r = r + 0.3 * nl.skin * step / np.linalg.norm(step, axis=1).max()
        kept = search(rod.mesh, r, sl, reach, excl, neighbours=nl)
        new = search(rod.mesh, r, sl, reach, excl)
        assert new.size > 0
        for name in ("slave", "m_elem", "m_xi", "s_bar", "distance", "normal", "interior"):
            assert np.array_equal(getattr(kept, name), getattr(new, name)), name
    assert 2 <= nl.builds <= 8               # kept for a few searches, rebuilt after
    builds = nl.builds
    search(rod.mesh, r, sl, 1.5 * reach, excl, neighbours=nl)
    assert nl.builds == builds + 1


def test_neighbour_list_does_not_hide_a_non_finite_position():
    """A NaN among the nodes makes the search raise, with the list as
    without it: the list finds its pairs anew (its move test reads a NaN
    as a move beyond the skin) instead of searching with stale pairs."""
    eps = 0.105
    rod = Rod(hairpin(eps, 0.2, leg=1.0), SEC, 64)
    sl = slave_points(rod.mesh, 3)
    reach, excl = 2 * eps + 0.05, np.pi * eps
    nl = search_mod.NeighbourList(skin=0.5 * eps)
    assert search(rod.mesh, rod.r0, sl, reach, excl, neighbours=nl).size > 0
    r = rod.r0.copy()
    r[5, 0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        search(rod.mesh, r, sl, reach, excl)
    with pytest.raises(ValueError, match="finite"):
        search(rod.mesh, r, sl, reach, excl, neighbours=nl)
