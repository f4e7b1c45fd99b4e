"""Verification of the rod solver against exact, independent and published
solutions (see docs/verification.md for the measured tables).

1. Roll-up of a straight cantilever by an end moment (exact circle).
2. Tip-loaded planar cantilever against the extensible, shearable Reissner
   elastica of :func:`skfem_rod.analytic.elastica_cantilever`, and the stiff
   rod against the published inextensible tip values.
3. 45-degree bend (Bathe & Bolourchi 1979; Simo & Vu-Quoc 1986) against an
   independent shooting solution of the same 3D rod equations and against
   the published 8-element tips.
4. Convergence rates in field norms (L2 and H1 of the position, L2 of the
   rotation) on the roll-up and the cantilever.
5. Slenderness sweep: no locking with the default 3-point integration,
   locking with full 4-point integration.

Run ``pytest -s tests/test_verification.py`` to see the measured numbers.
"""
import numpy as np
import pytest

from skfem_rod import Rod, Section, analytic, geometry

L = 1.0
EI = 1.0
STIFF = 1e4 * EI / L**2          # EA = GA for the roll-up and cantilever


def rod_section(EA=STIFF, GA=STIFF, EI=EI, GJ=1.0):
    return Section(EA=EA, GA1=GA, GA2=GA, EI1=EI, EI2=EI, GJ=GJ)


def rotation_angle(Q):
    """Angle (rad) of rotation matrices ``Q`` (n, 3, 3), accurate also for
    small angles (atan2 of the axial vector and the trace)."""
    w = 0.5 * np.stack([Q[:, 2, 1] - Q[:, 1, 2], Q[:, 0, 2] - Q[:, 2, 0],
                        Q[:, 1, 0] - Q[:, 0, 1]], axis=1)
    c = 0.5 * (np.trace(Q, axis1=1, axis2=2) - 1.0)
    return np.arctan2(np.linalg.norm(w, axis=1), c)


def rot_z(a):
    a = np.asarray(a, float)
    c, s = np.cos(a), np.sin(a)
    Q = np.zeros(a.shape + (3, 3))
    Q[..., 0, 0], Q[..., 0, 1], Q[..., 1, 0], Q[..., 1, 1] = c, -s, s, c
    Q[..., 2, 2] = 1.0
    return Q


def gauss_points(rod, n=10):
    """Arclengths and weights of an n-point Gauss rule on every element."""
    x, w = np.polynomial.legendre.leggauss(n)
    v = rod.mesh.vertices
    h = np.diff(v)[:, None]
    return (v[:-1, None] + h * (x + 1) / 2).ravel(), (h * w / 2).ravel()


# ==========================================================================
# 1. roll-up by an end moment
# ==========================================================================
def solve_rollup(phi, n_elements, section=None):
    rod = Rod(geometry.straight(L), section or rod_section(), n_elements)
    rod.clamp("start")
    rod.add_moment("end", [0.0, 0.0, phi * EI / L])
    res = rod.solve(n_steps=max(1, int(np.ceil(phi / (np.pi / 2)))), rtol=1e-10)
    assert res.converged, res.message
    return rod, res


def rollup_errors(phi, n_elements):
    rod, res = solve_rollup(phi, n_elements)
    s, r, R = res.nodes()
    ex = analytic.rollup(L, EI, phi * EI / L, s)
    err = np.linalg.norm(r - np.c_[ex.x, ex.y, np.zeros_like(s)], axis=1) / L
    # exact frames: the reference frame rotated by kappa s about +z
    ang = rotation_angle(np.einsum("nji,njk->nik", R, rot_z(ex.theta) @ rod.R0[0]))
    # every third node is an element vertex (P3: vertex, 2 interior, vertex)
    np.testing.assert_allclose(s[::3], rod.mesh.vertices, atol=1e-14)
    return dict(tip=err[-1], vertices=err[::3].max(), all=err.max(), angle=ang.max())


ROLLUP_PHIS = [0.5 * np.pi, np.pi, 1.5 * np.pi, 2 * np.pi, 4 * np.pi]


@pytest.mark.parametrize("phi", ROLLUP_PHIS, ids=["pi/2", "pi", "3pi/2", "2pi", "4pi"])
def test_rollup_16_elements(phi):
    e = rollup_errors(phi, 16)
    print(f"\nroll-up phi={phi / np.pi:g}pi, 16 el.: tip {e['tip']:.2e}  vertices "
          f"{e['vertices']:.2e}  all nodes {e['all']:.2e}  frame angle {e['angle']:.2e}")
    assert e["tip"] < 1e-6
    assert e["vertices"] < 1e-6              # superconvergent at the vertices
    assert e["angle"] < 1e-8                 # nodal frames are exp(kappa s e3) R0
    if phi <= 2 * np.pi + 1e-12:
        assert e["all"] < 1e-6               # element-interior P3 nodes too
    else:
        # 4 pi with 16 elements: interior nodes are at the P3 interpolation
        # error (measured 6.3e-6); refined below
        assert e["all"] < 1e-5


def test_rollup_4pi_32_elements():
    e = rollup_errors(4 * np.pi, 32)
    print(f"\nroll-up phi=4pi, 32 el.: tip {e['tip']:.2e}  vertices {e['vertices']:.2e}  "
          f"all nodes {e['all']:.2e}  frame angle {e['angle']:.2e}")
    assert e["all"] < 1e-6
    assert e["angle"] < 1e-8


# ==========================================================================
# 2. tip-loaded cantilever
# ==========================================================================
def solve_cantilever(alpha, n_elements, section, n_quad=3, n_steps=None, **options):
    rod = Rod(geometry.straight(L), section, n_elements, n_quad=n_quad)
    rod.clamp("start")
    rod.add_force("end", [0.0, alpha * section.EI1 / L**2, 0.0])
    res = rod.solve(n_steps=n_steps or max(1, int(np.ceil(alpha))), rtol=1e-10, **options)
    assert res.converged, res.message
    return rod, res


@pytest.mark.parametrize("alpha", [1.0, 2.0, 5.0])
def test_cantilever_against_reissner_elastica(alpha):
    """Same model on both sides: EA = 1e4, GA = 4e3 (EA != GA so that the
    coupling of stretch and shear in the reference ODE is exercised)."""
    EA, GA = 1e4, 4e3
    ref = analytic.elastica_cantilever(alpha, EA=EA, GA=GA, EI=EI, length=L)
    assert ref.tip_error < 1e-12
    rod, res = solve_cantilever(alpha, 16, rod_section(EA=EA, GA=GA))
    s, r, R = res.nodes()
    err = np.linalg.norm(r - np.c_[ref.x(s), ref.y(s), np.zeros_like(s)], axis=1) / L
    theta = np.arctan2(R[:, 1, 2], R[:, 0, 2])          # angle of d3 about +z
    print(f"\ncantilever PL^2/EI={alpha:g}, 16 el.: tip {err[-1]:.2e}  all nodes "
          f"{err.max():.2e}  angle {np.abs(theta - ref.theta(s)).max():.2e}  "
          f"(u, v)/L = ({L - r[-1, 0]:.8f}, {r[-1, 1]:.8f})")
    assert err[-1] < 1e-6
    assert err.max() < 1e-6
    assert np.abs(theta - ref.theta(s)).max() < 1e-6
    assert np.abs(r[:, 2]).max() < 1e-12


# The published inextensible values (Bisshopp & Drucker 1945, 7 digits).
PUBLISHED_ELASTICA_1 = dict(v=0.3017208, u=0.0564332)


def test_stiff_cantilever_against_published_inextensible_values():
    """EA = GA = 1e8 EI/L^2 is inextensible to ~P/EA = 1e-8.  (Before the
    solver's convergence test required a negligible last update, its
    round-off floor stopped 5.6e-4 L off with 16 elements and one step.)"""
    for n_elements, n_steps in ((8, 1), (8, 4), (16, 1), (16, 4)):
        rod, res = solve_cantilever(1.0, n_elements, rod_section(EA=1e8, GA=1e8),
                                    n_steps=n_steps)
        tip_solver = res.steps[-1].r[rod.node("end")]
        tip = tip_solver
        u, v = L - tip[0], tip[1]
        print(f"\nstiff cantilever, {n_elements} el., {n_steps} steps: u/L = {u:.8f}  "
              f"v/L = {v:.8f} (published {PUBLISHED_ELASTICA_1['u']}, "
              f"{PUBLISHED_ELASTICA_1['v']}); solver stop: u/L = {L - tip_solver[0]:.8f}"
              f"  v/L = {tip_solver[1]:.8f}")
        assert abs(v - PUBLISHED_ELASTICA_1["v"]) < 1e-6
        assert abs(u - PUBLISHED_ELASTICA_1["u"]) < 1e-6
    # the published digits are the elliptic-integral solution
    t = analytic.elastica_tip_elliptic(1.0)
    assert round(t["v"], 7) == PUBLISHED_ELASTICA_1["v"]
    assert round(t["u"], 7) == PUBLISHED_ELASTICA_1["u"]


def test_stiff_cantilever_default_options_converge_to_the_solution():
    rod, res = solve_cantilever(1.0, 16, rod_section(EA=1e8, GA=1e8), n_steps=1)
    tip = res.nodes()[1][-1]
    assert abs(tip[1] - PUBLISHED_ELASTICA_1["v"]) < 1e-6
    assert abs(L - tip[0] - PUBLISHED_ELASTICA_1["u"]) < 1e-6


# ==========================================================================
# 3. 45-degree bend
# ==========================================================================
BEND_RADIUS = 100.0
BEND_SECTION = dict(EA=1e7, GA1=5e6, GA2=5e6, EI1=1e7 / 12, EI2=1e7 / 12, GJ=5e6 / 6)
BEND_LOADS = (300.0, 450.0, 600.0)
BEND_ELEMENTS = (8, 16, 32, 64)
# published tip positions at P = 600, 8 elements
SIMO_VU_QUOC = np.array([15.79, 47.23, 53.37])
BATHE_BOLOURCHI = np.array([15.9, 47.2, 53.4])


def bend_shape():
    # start at the origin, tangent +y, curving toward +x: centre (100, 0, 0)
    return geometry.arc(BEND_RADIUS, np.pi / 4, start=(0.0, 0.0, 0.0),
                        tangent=(0.0, 1.0, 0.0), toward=(1.0, 0.0, 0.0))


def bend_shooting(loads=BEND_LOADS):
    """Independent reference: shooting on the 3D Simo-Reissner equations

    ``r' = R v``, ``R' = R hat(u)``, ``m' = -r' x n``, ``n = F`` (dead tip
    force, no distributed load), ``(v, u) = (v0, u0) + C^-1 (R^T n, R^T m)``,
    with ``r(0) = 0``, ``R(0) = R0(0)`` and the unknown ``m(0)`` found from
    ``m(L) = 0`` (continuation in the load).  The reference strains of the
    arc are ``v0 = e3`` and ``u0 = e2 / radius`` (``d1`` points to the
    centre, ``d3' = d1 / radius``).  Solved by
    :func:`skfem_rod.analytic.clamped_rod_shooting` (no finite elements);
    only the frame at s = 0 is taken from :func:`geometry.arc`."""
    shape = bend_shape()
    C = np.diag([BEND_SECTION[k] for k in ("GA1", "GA2", "EA", "EI1", "EI2", "GJ")])
    R00 = shape(np.array([0.0]))[1][0]
    P = sorted(set((150.0,) + tuple(loads)))
    tips = analytic.clamped_rod_shooting(C, [0, 0, 1], [0, 1 / BEND_RADIUS, 0], R00,
                                         shape.length, [[0.0, 0.0, p] for p in P])
    return dict(zip(P, tips))


def solve_bend(n_elements, n_steps=12):
    """Solve to P = 600 in ``n_steps`` steps; returns ``(rod, result, tips,
    raw)`` with the tip at each load of BEND_LOADS (``tips`` and ``raw``
    are the same since the solver converges to the discrete solution)."""
    rod = Rod(bend_shape(), Section(**BEND_SECTION), n_elements)
    rod.clamp("start")
    rod.add_force("end", [0.0, 0.0, max(BEND_LOADS)])
    res = rod.solve(n_steps=n_steps, rtol=1e-10)
    assert res.converged, res.message
    tips, raw = {}, {}
    for P in BEND_LOADS:
        lam = P / max(BEND_LOADS)
        k = int(np.argmin([abs(st.load_factor - lam) for st in res.steps]))
        assert abs(res.steps[k].load_factor - lam) < 1e-9
        raw[P] = res.steps[k].r[rod.node("end")]
        tips[P] = raw[P]
    return rod, res, tips, raw


@pytest.fixture(scope="module")
def bend():
    fe = {n: solve_bend(n) for n in BEND_ELEMENTS}
    return fe, bend_shooting()


@pytest.mark.slow
def test_bend_reference_state(bend):
    fe, _ = bend
    rod, res = fe[8][:2]
    r0, R0 = rod.r0[rod.mesh.order], rod.R0[rod.mesh.order]
    np.testing.assert_allclose(r0[-1], [100 * (1 - np.sqrt(0.5)), 100 * np.sqrt(0.5), 0],
                               atol=1e-12)
    np.testing.assert_allclose(R0[0][:, 2], [0, 1, 0], atol=1e-15)
    # the package's reference curvature is the one the shooting solution assumes
    f = res.evaluate(np.linspace(0, rod.length, 7), step=0)
    np.testing.assert_allclose(f["u0"], [[0, 1 / BEND_RADIUS, 0]] * 7, atol=1e-12)
    # the FE reference is the P3 interpolation of the arc, taken as stress
    # free: its shear/stretch v0 differs from e3 by the interpolation error
    # (8.8e-6 with 8 elements), which vanishes under refinement
    np.testing.assert_allclose(f["v0"], [[0, 0, 1]] * 7, atol=2e-5)


@pytest.mark.slow
def test_bend_against_shooting_solution(bend):
    fe, ref = bend
    print()
    for P in BEND_LOADS:
        print(f"45-degree bend P={P:g}: shooting {np.array2string(ref[P], precision=8)}")
        for n in BEND_ELEMENTS:
            tip = fe[n][2][P]
            err = np.linalg.norm(tip - ref[P])
            print(f"   {n:3d} el. {np.array2string(tip, precision=8)}  |FE - shooting| "
                  f"{err:.2e}")
            # measured 8.9e-7 (8 el.), 6.3e-8, 4.1e-9, 2.6e-10 at P = 600
            assert err < 2e-6 * (8 / n) ** 4


@pytest.mark.slow
def test_bend_converges_under_refinement(bend):
    fe, ref = bend
    tips = np.array([fe[n][2][600.0] for n in BEND_ELEMENTS])
    d = np.linalg.norm(np.diff(tips, axis=0), axis=1)
    rates = np.log2(d[:-1] / d[1:])
    print(f"\n45-degree bend P=600: successive tip differences {d}, rates {rates}")
    assert np.all(np.diff(d) < 0)
    # the tip (an element vertex) converges like h^(p+1) = h^4 for cubics
    assert np.all((rates > 3.5) & (rates < 4.5))


@pytest.mark.slow
def test_bend_against_published_tips(bend):
    """Published 8-element tips at P = 600: Simo & Vu-Quoc (1986)
    (15.79, 47.23, 53.37), Bathe & Bolourchi (1979) (15.9, 47.2, 53.4).

    Measured with 8 elements (within 9e-7 of the converged solution):
    (15.6848, 47.1504, 53.4749).  The band "published spread widened by
    0.05 per coordinate (their 2-3 significant figures)",
    [15.74, 15.95] x [47.15, 47.28] x [53.32, 53.45], does NOT contain it:
    x is 0.055 below and z 0.025 above the band (y is inside).  The
    converged solution of this continuum problem is pinned down
    independently by the shooting solution (agreement 3e-10 at 64
    elements), so the offset is in the published numbers, most likely the
    discretization error of their low-order 8-element meshes (they differ
    from each other by 0.11 in x).  Asserted here is therefore only a
    consistency check: every coordinate within 0.25 (0.4 % of the tip
    displacement of 60) of each published tip.  Measured sensitivities:
    EI x 1.1 moves the tip by (0.87, 1.56, -1.47) and GJ x 2 by
    (0.28, 0.75, -0.37), so such setup errors would fail it; J = 0.141
    instead of 1/6 (-0.12, -0.25, 0.13) would only just."""
    fe, _ = bend
    tip8 = fe[8][2][600.0]
    for name, pub in (("Simo & Vu-Quoc", SIMO_VU_QUOC), ("Bathe & Bolourchi", BATHE_BOLOURCHI)):
        print(f"\n{name}: published {pub}, FE 8 el. {np.round(tip8, 4)}, "
              f"difference {np.round(tip8 - pub, 3)}")
        assert np.all(np.abs(tip8 - pub) < 0.25)
    lo = np.minimum(SIMO_VU_QUOC, BATHE_BOLOURCHI) - 0.05
    hi = np.maximum(SIMO_VU_QUOC, BATHE_BOLOURCHI) + 0.05
    inside = (tip8 >= lo) & (tip8 <= hi)
    print(f"inside the widened published band (x, y, z): {inside}")


# ==========================================================================
# 4. convergence rates in field norms
# ==========================================================================
CONVERGENCE_ELEMENTS = (2, 4, 8, 16, 32)


def rollup_field_errors(n_elements, phi=2 * np.pi):
    """L2 of the position error, H1 seminorm (error of r' = R v against the
    exact tangent) and L2 of the rotation angle of R_h^T R_exact."""
    rod, res = solve_rollup(phi, n_elements)
    s, w = gauss_points(rod)
    f = res.evaluate(s)
    ex = analytic.rollup(L, EI, phi * EI / L, s)
    r_ex = np.c_[ex.x, ex.y, np.zeros_like(s)]
    t_ex = np.c_[np.cos(ex.theta), np.sin(ex.theta), np.zeros_like(s)]
    rp = np.einsum("nij,nj->ni", f["R"], f["v"])
    ang = rotation_angle(np.einsum("nji,njk->nik", f["R"], rot_z(ex.theta) @ rod.R0[0]))
    return (np.sqrt(w @ np.sum((f["r"] - r_ex) ** 2, axis=1)),
            np.sqrt(w @ np.sum((rp - t_ex) ** 2, axis=1)),
            np.sqrt(w @ ang**2))


def cantilever_field_errors(n_elements, alpha=5.0, EA=1e4, GA=1e4):
    """L2 of the position and of the section-angle error on the cantilever
    (whose rotation field, unlike the roll-up's, is not reproduced exactly)."""
    ref = analytic.elastica_cantilever(alpha, EA=EA, GA=GA, EI=EI, length=L)
    rod, res = solve_cantilever(alpha, n_elements, rod_section(EA=EA, GA=GA))
    s, w = gauss_points(rod)
    f = res.evaluate(s)
    theta = np.arctan2(f["R"][:, 1, 2], f["R"][:, 0, 2])
    return (np.sqrt(w @ ((f["r"][:, 0] - ref.x(s)) ** 2 + (f["r"][:, 1] - ref.y(s)) ** 2)),
            np.sqrt(w @ (theta - ref.theta(s)) ** 2))


def fitted_rate(n_elements, err):
    h = L / np.asarray(n_elements, float)
    return np.polyfit(np.log(h), np.log(err), 1)[0]


def test_rollup_convergence_rates():
    E = np.array([rollup_field_errors(n) for n in CONVERGENCE_ELEMENTS])
    l2, h1 = fitted_rate(CONVERGENCE_ELEMENTS, E[:, 0]), fitted_rate(CONVERGENCE_ELEMENTS, E[:, 1])
    print("\nroll-up 2pi: n_el, L2(r), H1(r), L2(rotation)")
    for n, e in zip(CONVERGENCE_ELEMENTS, E):
        print(f"   {n:3d}  {e[0]:.3e}  {e[1]:.3e}  {e[2]:.1e}")
    print(f"   fitted rates: L2 {l2:.3f}  H1 {h1:.3f}")
    assert 3.7 < l2 < 4.3
    assert 3.7 < np.log2(E[-2, 0] / E[-1, 0]) < 4.3
    assert 2.7 < h1 < 3.3
    # the rotation field of a circle is reproduced exactly by the objective
    # interpolation (constant curvature): its error is at the solver's
    # tolerance for every mesh, so it has no rate
    assert E[:, 2].max() < 1e-8


def test_cantilever_rotation_convergence_rate():
    n_el = (2, 4, 8, 16)
    E = np.array([cantilever_field_errors(n) for n in n_el])
    l2r, l2t = fitted_rate(n_el, E[:, 0]), fitted_rate(n_el, E[:, 1])
    print("\ncantilever PL^2/EI=5: n_el, L2(r), L2(theta)")
    for n, e in zip(n_el, E):
        print(f"   {n:3d}  {e[0]:.3e}  {e[1]:.3e}")
    print(f"   fitted rates: L2(r) {l2r:.3f}  L2(theta) {l2t:.3f}")
    assert 3.5 < l2r < 4.3
    assert 3.5 < l2t < 4.3
    assert np.log2(E[-2, 1] / E[-1, 1]) > 3.8


# ==========================================================================
# 5. slenderness sweep (locking)
# ==========================================================================
SLENDERNESS = (10.0, 100.0, 1e3, 1e4)


def slender_tip_error(ratio, n_quad, alpha=2.0, n_elements=8):
    sec = Section.circle(E=1e7, nu=0.3, radius=L / ratio)
    ref = analytic.elastica_cantilever(alpha, EA=sec.EA, GA=sec.GA1, EI=sec.EI1, length=L)
    rod, res = solve_cantilever(alpha, n_elements, sec, n_quad=n_quad, n_steps=2)
    tip = res.nodes()[1][-1]
    return np.hypot(tip[0] - ref.x(L), tip[1] - ref.y(L)) / L


@pytest.fixture(scope="module")
def slenderness():
    return {(ratio, nq): slender_tip_error(ratio, nq) for ratio in SLENDERNESS for nq in (3, 4)}


@pytest.mark.slow
def test_slenderness_no_locking(slenderness):
    print("\nL/radius   tip error 3-point   tip error 4-point")
    for ratio in SLENDERNESS:
        print(f"{ratio:8g}   {slenderness[ratio, 3]:.2e}            {slenderness[ratio, 4]:.2e}")
    for ratio in SLENDERNESS:
        assert slenderness[ratio, 3] < 1e-6


@pytest.mark.slow
def test_full_integration_locks(slenderness):
    # measured: 3.6e-7, 3.5e-5, 9.9e-4, 1.6e-3 with 4 points against
    # 1.0e-9 at every ratio with 3 points
    assert slenderness[1e4, 4] > 10 * slenderness[1e4, 3]
    assert slenderness[1e3, 4] > 1e-4 and slenderness[1e4, 4] > 1e-4
