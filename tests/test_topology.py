"""Twist, writhe and linking number (:mod:`skfem_rod.topology`).

Independent references: direct quadrature of the Gauss double integral on
smooth curves (Richardson extrapolated) and on single segment pairs
(Gauss-Legendre), the torsion integral of a helix, exact twist of straight
ribbons, and the Calugareanu-White-Fuller identity ``Lk = Tw + Wr`` with
``Lk`` from the independent Gauss linking of the two edges of the ribbon.
All random input is seeded.
"""
import doctest
import warnings

import numpy as np
import pytest

from skfem_rod import topology as topo
from skfem_rod.topology import (closure, link, linking_number, topology,
                                twist, writhe)

TWO_PI = 2.0 * np.pi


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------

def torus_knot(n, p=2, q=3, endpoint=False):
    """(p, q) torus knot on the torus of radii 2 and 1, with derivative."""
    u = np.linspace(0.0, TWO_PI, n, endpoint=endpoint)
    rad = 2.0 + np.cos(q * u)
    r = np.c_[rad * np.cos(p * u), rad * np.sin(p * u), np.sin(q * u)]
    drad = -q * np.sin(q * u)
    dr = np.c_[drad * np.cos(p * u) - p * rad * np.sin(p * u),
               drad * np.sin(p * u) + p * rad * np.cos(p * u),
               q * np.cos(q * u)]
    return r, dr


def gauss_writhe_quadrature(curve, N):
    """Trapezoidal rule on an N x N periodic grid for the Gauss double
    integral (the integrand is continuous, O(|s - u|) at the diagonal);
    error O(h^2)."""
    r, dr = curve(N)
    h = TWO_PI / N
    total = 0.0
    for i0 in range(0, N, 256):
        R = r[i0:i0 + 256, None, :] - r[None, :, :]
        C = np.cross(dr[i0:i0 + 256, None, :], dr[None, :, :])
        num = np.einsum("ijk,ijk->ij", C, R)
        dist = np.linalg.norm(R, axis=2)
        with np.errstate(divide="ignore", invalid="ignore"):
            total += np.where(dist > 0, num / dist**3, 0.0).sum()
    return total * h * h / (4.0 * np.pi)


def pair_gauss_legendre(p1, p2, p3, p4, order=60):
    """Gauss integral (1/4pi) int int (dp x dq).(p - q)/|p - q|^3 over
    segments p1->p2 and p3->p4 by tensor Gauss-Legendre quadrature."""
    x, w = np.polynomial.legendre.leggauss(order)
    s, ws = 0.5 * (x + 1.0), 0.5 * w
    P = p1 + s[:, None] * (p2 - p1)
    Q = p3 + s[:, None] * (p4 - p3)
    R = P[:, None, :] - Q[None, :, :]
    num = R @ np.cross(p2 - p1, p4 - p3)
    f = num / np.linalg.norm(R, axis=2) ** 3
    return ws @ f @ ws / (4.0 * np.pi)


def random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def vertex_tangents(p, closed):
    e = np.roll(p, -1, axis=0) - p if closed else np.diff(p, axis=0)
    t = e / np.linalg.norm(e, axis=1)[:, None]
    tv = np.roll(t, 1, axis=0) + t if closed else np.vstack([t[0], t[:-1] + t[1:], t[-1]])
    return tv / np.linalg.norm(tv, axis=1)[:, None]


def transported_normals(p, closed, d0):
    """Normals at the vertices parallel transported (minimal rotations
    between consecutive vertex tangents) from ``d0`` at the first vertex;
    a sequential recurrence, fine for a test."""
    tv = vertex_tangents(p, closed)
    d = np.empty_like(p)
    d[0] = d0 - np.dot(d0, tv[0]) * tv[0]
    d[0] /= np.linalg.norm(d[0])
    for k in range(1, len(p)):
        d[k] = topo._transport(d[k - 1], tv[k - 1], tv[k])
    return d, tv


def rotate_about(v, axis, angle):
    return topo._rotate(v, axis, np.asarray(angle, dtype=float)[:, None])


def random_closed_ribbon(rng, n=300, modes=3):
    """Random smooth closed curve (a few Fourier modes) with a smooth
    closed normal field carrying a random integer number of extra turns
    and a random periodic wobble."""
    th = np.linspace(0.0, TWO_PI, n, endpoint=False)
    k = np.arange(1, modes + 1)
    A = rng.normal(size=(modes, 3)) / k[:, None]
    B = rng.normal(size=(modes, 3)) / k[:, None]
    p = np.cos(np.outer(th, k)) @ A + np.sin(np.outer(th, k)) @ B
    d, tv = transported_normals(p, True, rng.normal(size=3))
    # holonomy: angle from the normal transported once around to d[0]
    back = topo._transport(d[-1], tv[-1], tv[0])
    hol = np.arctan2(np.dot(tv[0], np.cross(back, d[0])), np.dot(back, d[0]))
    m = int(rng.integers(-3, 4))
    ang = (hol + TWO_PI * m) * th / TWO_PI + 0.8 * np.sin(2 * th + rng.uniform(0, TWO_PI))
    return p, rotate_about(d, tv, ang)


def coil(n, radius, height=1.0, turns=1.0):
    """Rod from (0,0,0) to (0,0,height) with tangent +z at both ends and a
    coil of ``turns`` turns of maximal radius ``radius`` in between."""
    s = np.linspace(0.0, 1.0, n)
    rho = radius * np.sin(np.pi * s) ** 2
    phi = TWO_PI * turns * s
    return np.c_[rho * np.cos(phi), rho * np.sin(phi), height * s]


def straight_twisted(n, turns, length=1.0):
    s = np.linspace(0.0, 1.0, n)
    pts = np.c_[0 * s, 0 * s, length * s]
    d1 = np.c_[np.cos(TWO_PI * turns * s), np.sin(TWO_PI * turns * s), 0 * s]
    return pts, d1


# --------------------------------------------------------------------------
# writhe
# --------------------------------------------------------------------------

def test_docstring_examples():
    failed, attempted = doctest.testmod(topo, verbose=False)
    assert attempted > 10 and failed == 0


def test_planar_curves_have_zero_writhe():
    rng = np.random.default_rng(0)
    th = np.linspace(0.0, TWO_PI, 400, endpoint=False)
    rad = 1.0 + 0.3 * np.cos(3 * th) + 0.2 * np.sin(5 * th + 1.0)   # simple, star shaped
    planar = np.c_[rad * np.cos(th), rad * np.sin(th), 0 * th]
    assert writhe(planar, closed=True) == 0.0                 # exactly, in z = 0
    assert writhe(planar[:300]) == 0.0                        # open arc
    for _ in range(3):                                         # any plane
        Q = random_rotation(rng)
        shifted = planar @ Q.T + rng.normal(size=3)
        assert abs(writhe(shifted, closed=True)) < 1e-12
        assert abs(writhe(shifted[:300])) < 1e-12


@pytest.mark.parametrize("p, q", [(2, 3), (2, 5), (3, 4)])
def test_torus_knot_writhe_matches_gauss_quadrature(p, q):
    """Polygon formula (exact for the polygon, O(h^2) for the curve) against
    direct quadrature of the Gauss double integral on the smooth curve,
    both Richardson extrapolated."""
    def curve(n):
        return torus_knot(n, p, q)

    w = {n: writhe(curve(n)[0], closed=True) for n in (800, 1600)}
    poly = (4 * w[1600] - w[800]) / 3
    g = {N: gauss_writhe_quadrature(curve, N) for N in (800, 1600)}
    quad = (4 * g[1600] - g[800]) / 3
    assert abs(poly - quad) < 1e-6 * max(1.0, abs(quad))
    # second-order convergence of the polygon writhe
    w400 = writhe(curve(400)[0], closed=True)
    ratio = (w400 - poly) / (w[800] - poly)
    assert 3.5 < ratio < 4.5
    if (p, q) == (2, 3):                                    # regression value
        assert abs(quad - (-3.5182392)) < 1e-6


def test_segment_pairs_against_gauss_legendre():
    """Open random polygons: writhe and open Gauss linking against
    Gauss-Legendre quadrature of every segment pair (well separated)."""
    rng = np.random.default_rng(3)
    pts = np.cumsum(rng.normal(size=(7, 3)), axis=0)
    ref = 0.0
    for i in range(6):
        for j in range(i + 2, 6):
            ref += 2 * pair_gauss_legendre(pts[i], pts[i + 1], pts[j], pts[j + 1])
    assert abs(writhe(pts) - ref) < 1e-8
    a = rng.normal(size=(4, 3))
    b = rng.normal(size=(5, 3)) + np.array([4.0, 0.0, 1.0])
    ref = sum(pair_gauss_legendre(a[i], a[i + 1], b[j], b[j + 1])
              for i in range(3) for j in range(4))
    assert abs(linking_number(a, b, closed=False) - ref) < 1e-8


def test_writhe_mirror_reversal_and_rigid_motions():
    rng = np.random.default_rng(1)
    p, _ = random_closed_ribbon(rng)
    w = writhe(p, closed=True)
    assert abs(w) > 0.05
    mirror = p * np.array([1.0, 1.0, -1.0])
    assert abs(writhe(mirror, closed=True) + w) < 1e-12
    assert abs(writhe(p[::-1], closed=True) - w) < 1e-12             # orientation
    assert abs(writhe(np.roll(p, 37, axis=0), closed=True) - w) < 1e-12
    moved = 3.7 * p @ random_rotation(rng).T + rng.normal(size=3)
    assert abs(writhe(moved, closed=True) - w) < 1e-12
    assert abs(writhe(np.vstack([p, p[:1]]), closed=True) - w) < 1e-15  # repeated end
    tre, _ = torus_knot(300)
    assert abs(writhe(tre * [-1, 1, 1], closed=True) + writhe(tre, closed=True)) < 1e-12


def test_right_handed_helix_has_positive_writhe_and_hopf_sign():
    s = np.linspace(0.0, 4 * np.pi, 200)
    helix = np.c_[np.cos(s), np.sin(s), 0.3 * s]
    assert writhe(helix) > 0 and writhe(helix * [1, -1, 1]) < 0
    u = np.linspace(0.0, TWO_PI, 64, endpoint=False)
    a = np.c_[np.cos(u), np.sin(u), 0 * u]
    b = np.c_[1 + np.cos(u), 0 * u, -np.sin(u)]       # through a's disk along +z
    assert abs(linking_number(a, b) - 1.0) < 1e-12
    assert abs(linking_number(b, a) - 1.0) < 1e-12
    assert abs(linking_number(a, b[::-1]) + 1.0) < 1e-12
    assert abs(linking_number(a, b + [5.0, 0, 0])) < 1e-12


def test_blocking_does_not_change_results(monkeypatch):
    rng = np.random.default_rng(2)
    p, d1 = random_closed_ribbon(rng, n=120)
    ref = writhe(p, closed=True), link(p, d1, closed=True), writhe(p[:80])
    for block in (1, 7, 200):
        monkeypatch.setattr(topo, "_BLOCK", block)
        got = writhe(p, closed=True), link(p, d1, closed=True), writhe(p[:80])
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12)


# --------------------------------------------------------------------------
# twist
# --------------------------------------------------------------------------

@pytest.mark.parametrize("turns", [-2, 0, 1, 3])
def test_straight_twisted_ribbon(turns):
    pts, d1 = straight_twisted(61, turns)
    assert abs(twist(pts, d1) - turns) < 1e-12
    assert writhe(pts) == 0.0
    top = topology(pts, d1)                                 # clamped ends, closure
    assert abs(top.link - turns) < 1e-12
    assert abs(top.link_gauss - turns) < 1e-9
    assert abs(top.writhe) < 1e-12 and abs(top.closure_twist) < 1e-12
    # closed version: a circle whose ribbon makes `turns` turns
    u = np.linspace(0.0, TWO_PI, 120, endpoint=False)
    circ = np.c_[np.cos(u), np.sin(u), 0 * u]
    radial, z = circ.copy(), np.array([0.0, 0.0, 1.0])
    d = np.cos(turns * u)[:, None] * radial - np.sin(turns * u)[:, None] * z
    top = topology(circ, d, closed=True)
    assert abs(top.twist - turns) < 1e-12 and abs(top.writhe) < 1e-12
    assert abs(top.link_gauss - turns) < 1e-9


def test_twist_exact_for_coarse_samples_and_tangential_components():
    """Exact for a sampled frame whenever each step is < half a turn, and
    independent of the components of d1 along the tangent."""
    rng = np.random.default_rng(4)
    steps = rng.uniform(-0.95, 0.95, size=12) * np.pi
    ang = np.r_[0.0, np.cumsum(steps)]
    s = np.arange(13.0)
    pts = np.c_[s, 0 * s, 0 * s]
    d1 = np.c_[0 * s, np.cos(ang), np.sin(ang)]
    assert abs(twist(pts, d1) - ang[-1] / TWO_PI) < 1e-12
    p, d = random_closed_ribbon(rng)
    tw = twist(p, d, closed=True)
    tilted = 2.5 * d + rng.uniform(-3, 3, size=(len(p), 1)) * vertex_tangents(p, True)
    assert abs(twist(p, tilted, closed=True) - tw) < 1e-12
    assert abs(link(p, tilted, closed=True) - link(p, d, closed=True)) < 1e-9


def test_helix_frenet_twist_converges_to_torsion_integral():
    """Frenet frame of a helix: Tw = (1/2pi) int tau ds = turns c / sqrt(R^2 + c^2),
    with second-order convergence in the sampling."""
    R, c, turns = 1.0, 0.3, 2
    exact = turns * c / np.hypot(R, c)
    err = []
    for n in (50, 100, 200, 400):
        s = np.linspace(0.0, TWO_PI * turns, n)
        pts = np.c_[R * np.cos(s), R * np.sin(s), c * s]
        normal = np.c_[-np.cos(s), -np.sin(s), 0 * s]
        err.append(twist(pts, normal) - exact)
    err = np.abs(err)
    assert err[-1] < 1e-4
    assert np.all(3.5 < err[:-1] / err[1:]) and np.all(err[:-1] / err[1:] < 4.5)


# --------------------------------------------------------------------------
# Calugareanu-White-Fuller
# --------------------------------------------------------------------------

@pytest.mark.parametrize("seed", [10, 11, 12, 13, 14])
def test_calugareanu_white_random_closed_ribbons(seed):
    rng = np.random.default_rng(seed)
    p, d1 = random_closed_ribbon(rng)
    tw, wr = twist(p, d1, closed=True), writhe(p, closed=True)
    lk = link(p, d1, closed=True)                # independent Gauss linking
    assert abs(lk - round(lk)) < 1e-6
    assert abs(tw + wr - lk) < 1e-6
    assert abs(tw + wr - round(lk)) < 1e-10      # exact for polygonal ribbons
    assert abs(link(p, d1, closed=True, eps=1e-6) - lk) < 1e-6
    top = topology(p, d1, closed=True)
    assert top.link == pytest.approx(tw + wr, abs=1e-15)
    assert top.link_gauss == pytest.approx(lk, abs=1e-12)


# --------------------------------------------------------------------------
# open rods with held ends: closure
# --------------------------------------------------------------------------

def test_closure_geometry_and_frame():
    pts, d1 = straight_twisted(41, 2.0)
    c = closure(pts, d1, extension=5.0, offset=3.0, direction=[1.0, 0.0, 0.0])
    assert c.n_rod == 41 and c.points.shape == (45, 3) and c.d1.shape == (45, 3)
    np.testing.assert_array_equal(c.points[:41], pts)
    np.testing.assert_allclose(c.points[41:], [[0, 0, 6], [3, 0, 6], [3, 0, -5], [0, 0, -5]],
                               atol=1e-14)
    np.testing.assert_allclose(np.linalg.norm(c.d1, axis=1), 1.0, atol=1e-14)
    assert abs(twist(c.points[40:], c.d1[40:]) - 0.0) < 1e-14   # closure adds no twist
    # a fractional end rotation is made up by the closure, Lk stays integer
    pts, d1 = straight_twisted(41, 2.3)
    top = topology(pts, d1)
    assert abs(twist(pts, d1) - 2.3) < 1e-12
    assert abs(top.closure_twist + 0.3) < 1e-12
    assert abs(top.link - 2.0) < 1e-12 and abs(top.link_gauss - 2.0) < 1e-9


@pytest.mark.parametrize("radius", [0.1, 0.3, 0.6])
def test_coil_with_closure_has_integer_link(radius):
    """One turn of a coil with both ends along the axis, parallel
    transported frame: Tw + Wr = Lk is an integer after the closure; the
    closure writhe does not depend on its size (same tangent indicatrix)."""
    pts = coil(200, radius)
    d1, _ = transported_normals(pts, False, np.array([1.0, 0.0, 0.0]))
    top = topology(pts, d1)
    assert abs(top.link_gauss - round(top.link_gauss)) < 1e-6
    assert abs(top.twist + top.writhe - top.link_gauss) < 1e-6
    assert abs(top.twist - (twist(pts, d1) + top.closure_twist)) < 1e-12
    for ext, off in ((10.0, 10.0), (1e3, 50.0)):
        other = topology(pts, d1, extension=ext, offset=off)
        assert abs(other.writhe - top.writhe) < 1e-9
        assert abs(other.link_gauss - top.link_gauss) < 1e-6
    # writhe of the coil is that of one right-handed loop, between 0 and 1
    assert 0.0 < top.writhe < 1.0
    # adding N full turns of twist adds N to the linking number
    tv = vertex_tangents(pts, False)
    extra = rotate_about(d1, tv, 2 * TWO_PI * np.linspace(0.0, 1.0, len(pts)))
    assert abs(topology(pts, extra).link_gauss - top.link_gauss - 2) < 1e-6


def test_clamped_rod_conserves_link_while_coiling():
    """Clamped ends (end frames fixed, here untwisted): as a straight rod is
    continuously deformed into a one-turn coil, Lk stays 0 while twist is
    converted into writhe."""
    d_end = np.array([1.0, 0.0, 0.0])
    prev, results = 0.0, []
    for radius in np.linspace(0.0, 0.6, 25):
        pts = coil(150, radius)
        d, tv = transported_normals(pts, False, d_end)
        # rotate the transported frame progressively so that d1(end) = d_end,
        # choosing the branch of the correction continuously in the radius
        delta = np.arctan2(np.dot(tv[-1], np.cross(d[-1], d_end)), np.dot(d[-1], d_end))
        delta = prev + (delta - prev + np.pi) % TWO_PI - np.pi
        prev = delta
        d1 = rotate_about(d, tv, delta * np.linspace(0.0, 1.0, len(pts)))
        # (the end tangent is that of the last segment, ~z to O(h))
        end = d_end - np.dot(d_end, tv[-1]) * tv[-1]
        np.testing.assert_allclose(d1[-1], end / np.linalg.norm(end), atol=1e-12)
        results.append(topology(pts, d1))
    lk = np.array([r.link_gauss for r in results])
    assert np.all(np.abs(lk) < 1e-6)
    wr = np.array([r.writhe for r in results])
    tw = np.array([r.twist for r in results])
    np.testing.assert_allclose(tw + wr, 0.0, atol=1e-10)
    assert wr[0] == 0.0 and wr[-1] > 0.5                  # twist went into writhe
    assert all(abs(r.closure_twist) < 1e-12 for r in results)


# --------------------------------------------------------------------------
# input checks
# --------------------------------------------------------------------------

def test_bad_input():
    pts, d1 = straight_twisted(10, 1.0)
    with pytest.raises(ValueError, match="shape"):
        writhe(pts[:, :2])
    with pytest.raises(ValueError, match="at least"):
        writhe(pts[:2], closed=True)
    with pytest.raises(ValueError, match="zero-length"):
        writhe(np.vstack([pts[:3], pts[2:]]))
    with pytest.raises(ValueError, match="finite"):
        writhe(np.vstack([pts, [np.nan, 0, 0]]))
    with pytest.raises(ValueError, match="shape of points"):
        twist(pts, d1[:-1])
    with pytest.raises(ValueError, match="parallel to the tangent"):
        twist(pts, np.tile([0.0, 0.0, 1.0], (10, 1)))
    with pytest.raises(ValueError, match="nonzero"):
        link(pts, np.zeros_like(d1))
    with pytest.raises(ValueError, match="eps"):
        link(pts, d1, eps=-1.0)
    with pytest.raises(ValueError, match="extension"):
        closure(pts, d1, extension=0.0)
    with pytest.raises(TypeError):
        topology(pts, d1, closed=True, extension=3.0)


def test_mismatch_warns_when_eps_too_large():
    """A ribbon wider than the gap between strands does not measure the
    linking number of the thin ribbon: topology() warns."""
    tre, _ = torus_knot(200)
    d1, _ = transported_normals(tre, True, np.array([0.0, 0.0, 1.0]))
    # closed smooth normal: undo the holonomy gradually
    tv = vertex_tangents(tre, True)
    back = topo._transport(d1[-1], tv[-1], tv[0])
    hol = np.arctan2(np.dot(tv[0], np.cross(back, d1[0])), np.dot(back, d1[0]))
    d1 = rotate_about(d1, tv, hol * np.arange(200) / 200)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        top = topology(tre, d1, closed=True)
    assert abs(top.link - top.link_gauss) < 1e-6
    with pytest.warns(RuntimeWarning, match="differs from the Gauss linking"):
        topology(tre, d1, closed=True, eps=3.0)


def test_result_topology_of_a_twisted_straight_rod():
    """A rod clamped at one end, pinned at the other, whose end is turned 3
    times about its axis stays straight: Tw = Lk = 3 lam, Wr = 0 along the
    load path (partial turns included); the closed ribbon links 3 times."""
    from skfem_rod import Rod, Section, geometry
    rod = Rod(geometry.straight(1.0), Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1, EI2=1, GJ=0.8), 16)
    rod.clamp("start").pin("end").prescribe_rotation("end", [2 * np.pi * 3, 0, 0])
    res = rod.solve(4)
    assert res.converged
    for k in (len(res.steps) // 2, -1):
        t = res.topology(k)
        lam = res.steps[k].load_factor
        assert abs(t.twist - 3 * lam) < 1e-9 and abs(t.writhe) < 1e-9
        assert abs(t.link - 3 * lam) < 1e-9
    assert abs(res.topology().link_gauss - 3) < 1e-6
