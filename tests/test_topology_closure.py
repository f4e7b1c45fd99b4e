"""Issue 14, item 10: the closure of rods with held ends for any end
tangents.  The closure used to fold back on itself (a cusp at its far
corners) when the end tangents are antiparallel: a planar hairpin at rest
had writhe 1 and link 1, a two-ply raised "cusp".  Now every corner of the
closure turns by 90 degrees; link = twist + writhe holds and the Gauss
linking number of the closed ribbon is an integer for any end tangents."""
import warnings

import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.topology import closure, topology


def transported(P, d_start):
    """Parallel-transported normals along the polygon ``P`` (vertex
    tangents), starting from ``d_start``."""
    t = np.gradient(P, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    d = np.empty_like(P)
    d[0] = d_start - np.dot(d_start, t[0]) * t[0]
    d[0] /= np.linalg.norm(d[0])
    for k in range(1, len(P)):
        v = d[k - 1] - np.dot(d[k - 1], t[k]) * t[k]
        d[k] = v / np.linalg.norm(v)
    return d


def hairpin_points(leg=1.0, a=0.1, n=200):
    """Planar hairpin: along +x from the origin, a half circle of radius
    ``a``, back along -x at y = 2a."""
    x = np.linspace(0.0, leg, n, endpoint=False)
    th = np.linspace(-np.pi / 2, np.pi / 2, n, endpoint=False)
    return np.vstack([np.c_[x, 0 * x, 0 * x],
                      np.c_[leg + a * np.cos(th), a + a * np.sin(th), 0 * th],
                      np.c_[x[::-1] + leg / n, 2 * a + 0 * x, 0 * x]])


def two_ply_points(turns, leg=1.0, a=0.05, n=600):
    """Two plies wound ``turns`` times about the x axis, joined by a half
    circle at x = leg; the ends leave the clamps at x = 0 along +x and -x
    (antiparallel end tangents)."""
    x = np.linspace(0.0, leg, n, endpoint=False)
    u = x / leg
    phi = 2 * np.pi * turns * u**3 * (10 - 15 * u + 6 * u * u)   # flat at both ends
    ply = np.c_[x, a * np.cos(phi), a * np.sin(phi)]
    e = np.array([0.0, np.cos(phi[-1]), np.sin(phi[-1])])
    th = np.linspace(0.0, np.pi, 40)[1:-1]
    loop = leg + a * np.sin(th)[:, None] * np.array([1.0, 0, 0]) \
        + (a * np.cos(th))[:, None] * e
    loop[:, 0] = leg + a * np.sin(th)
    back = np.c_[x, -a * np.cos(phi), -a * np.sin(phi)][::-1]
    return np.vstack([ply, loop, back])


def test_planar_hairpin_at_rest_has_no_link():
    P = hairpin_points()
    d1 = np.tile([0.0, 0.0, 1.0], (len(P), 1))             # normal to the plane
    with warnings.catch_warnings():
        warnings.simplefilter("error")                     # no mismatch warning
        top = topology(P, d1)
    assert abs(top.twist) < 1e-12 and abs(top.writhe) < 1e-12
    assert abs(top.link) < 1e-12 and abs(top.link_gauss) < 1e-9
    # the same through a Rod at rest (ends clamped: held end tangents)
    shape = geometry.polyline(P[::8])
    rod = Rod(shape, Section.circle(1e7, 0.3, 0.005), 24).clamp("start").clamp("end")
    t = rod.solve(1).topology(0)
    assert abs(t.writhe) < 1e-9 and abs(t.link) < 1e-9 and abs(t.link_gauss) < 1e-6


def test_closure_corners_never_fold_back():
    """Every vertex of the closure turns by less than 180 degrees (no
    cusp), for parallel, antiparallel and oblique end tangents."""
    rng = np.random.default_rng(3)
    for P in (hairpin_points(), two_ply_points(2.0), np.c_[np.linspace(0, 1, 50),
                                                           np.zeros(50), np.zeros(50)]):
        c = closure(P, transported(P, rng.normal(size=3)))
        e = np.diff(np.vstack([c.points, c.points[:1]]), axis=0)[len(P) - 2:]
        e /= np.linalg.norm(e, axis=1, keepdims=True)
        cos = np.sum(e[:-1] * e[1:], axis=1)
        assert cos.min() > -0.9, cos


@pytest.mark.parametrize("turns", [0.5, 1.0, 2.0, 3.25])
def test_two_ply_link_is_twist_plus_writhe(turns):
    P = two_ply_points(turns)
    d1 = transported(P, np.array([0.0, 0.0, 1.0]))
    for ends in ({}, dict(t_start=[1.0, 0, 0], t_end=[-1.0, 0, 0])):   # clamped along x
        top = topology(P, d1, **ends)                      # raised "cusp" before
        assert abs(top.link_gauss - round(top.link_gauss)) < 1e-6
        assert abs(top.twist + top.writhe - top.link_gauss) < 1e-6
        assert abs(top.link - (top.twist + top.writhe)) < 1e-12


def random_rod(rng, n=300):
    """A smooth random open rod with held ends and a random smooth normal
    field: the body lies in ``x >= 0`` and its ends point away from it (the
    setting of held ends: nothing lies beyond an end along its tangent);
    end tangents random, parallel or antiparallel (the rod turning back)."""
    s = np.linspace(0.0, 1.0, n)
    kind = int(rng.integers(4))
    back = kind >= 2                        # the rod turns back toward x = 0
    P = np.c_[np.sin(np.pi * s) if back else s, 0.3 * s if back else 0 * s, 0 * s]
    for k in range(1, 4):
        P = P + 0.1 / k * np.outer(np.sin(np.pi * k * s) ** 2, rng.normal(size=3))
    P[:, 0] = np.abs(P[:, 0])
    ts = rng.normal(size=3)
    ts[0] = abs(ts[0]) + 0.5
    ts /= np.linalg.norm(ts)
    te = rng.normal(size=3)
    te[0] = abs(te[0]) + 0.5
    te = {0: te, 1: ts, 2: -te, 3: -ts}[kind]
    te = te / np.linalg.norm(te)
    P = np.vstack([P[0] - ts * np.linspace(0.2, 0.01, 20)[:, None], P,
                   P[-1] + te * np.linspace(0.01, 0.2, 20)[:, None]])
    d1 = transported(P, rng.normal(size=3))
    t = np.gradient(P, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    ang = np.cumsum(rng.normal(scale=0.05, size=len(P)))
    b = np.cross(t, d1)
    return P, np.cos(ang)[:, None] * d1 + np.sin(ang)[:, None] * b, ts, te


def test_random_configurations_link_is_twist_plus_writhe():
    rng = np.random.default_rng(20261124)
    for _ in range(24):
        P, d1, ts, te = random_rod(rng)
        top = topology(P, d1, t_start=ts, t_end=te)
        assert abs(top.link_gauss - round(top.link_gauss)) < 1e-6
        assert abs(top.twist + top.writhe - top.link_gauss) < 1e-6
