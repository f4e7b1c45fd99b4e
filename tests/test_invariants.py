"""Invariants of the discrete rod: consistency of residual and tangent,
quadratic Newton convergence, exact solutions for large rotations,
objectivity, path independence and distributed loads.

Conventions (``skfem_rod.rotations``): ``R`` maps the material to the spatial
basis, Newton increments are spatial spins, ``R <- expm(w) R``; nodal dof
``6 n + c`` (``c`` 0..2 position, 3..5 spin).

Finite differences: central differences along a configuration path
``y(h) = y (+) h d`` (``r + h dr``, ``expm(h dw) R``), whose truncation error is
``O(h^2)`` and round-off error ``O(eps / h)``; with ``h = 1e-5`` (positions
scaled by the element length) both are ~1e-10 relative, far below the 1e-6
tolerance.
"""
import dataclasses
import time

import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.assembly import internal_work
from skfem_rod.rotations import expm, is_rotation, logm
from skfem_rod.newton import newton
from skfem_rod.options import SolverOptions
from skfem_rod.problem import Problem


def _update(r, R, d, h):
    """The configuration update ``y (+) h d`` (spatial dofs)."""
    from skfem_rod.rotations import rotate
    d = h * d.reshape(-1, 6)
    return r + d[:, :3], rotate(R, d[:, 3:])

# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------

H = 1e-5                 # finite-difference step (spins; positions times h_el)
FD_TOL = 1e-6            # relative tolerance of the finite-difference checks


def diagonal_section():
    # deliberately distinct entries, moderate ratios (the FD checks compare
    # every coupling, the slender stiffness ratios are exercised below)
    return Section(EA=40.0, GA1=17.0, GA2=23.0, EI1=1.3, EI2=0.7, GJ=0.9)


def full_section(seed=7):
    """A full symmetric positive-definite 6x6 stiffness: the diagonal one
    coupled by a random symmetric matrix (eigenvalues checked > 0)."""
    rng = np.random.default_rng(seed)
    d = np.sqrt(np.diag(diagonal_section().C))
    A = rng.uniform(-0.4, 0.4, (6, 6))
    Cn = np.eye(6) + 0.5 * (A + A.T)
    C = d[:, None] * Cn * d[None, :]
    assert np.linalg.eigvalsh(C).min() > 0
    assert np.count_nonzero(np.abs(C - np.diag(np.diag(C))) > 1e-3) == 30
    return Section.from_matrix(C)


SHAPES = {
    "straight": lambda: geometry.straight(2.0),
    "arc": lambda: geometry.arc(1.0, 2.5, tangent=(0.0, 1.0, 0.3),
                                toward=(1.0, 0.0, 0.0)),
    "helix": lambda: geometry.helix(0.5, 0.4, 1.25),
}
SECTIONS = {"diagonal": diagonal_section, "full6x6": full_section}


def random_state(rod, rng, amp=1.0):
    """A large, smooth deformation of the reference plus random nodal noise:
    rotations of order ``amp`` rad (relative rotations within an element stay
    well inside the local chart), stretch and shear of a few percent."""
    s = rod.mesh.s_nodes / rod.length
    L = rod.length
    a = rng.standard_normal((3, 3))
    smooth_w = amp * (np.sin(np.pi * s)[:, None] * a[0]
                      + np.cos(2.0 * s)[:, None] * a[1] * 0.5 + s[:, None] * a[2])
    smooth_r = 0.2 * L * (np.sin(1.3 * s)[:, None] * rng.standard_normal(3)
                          + s[:, None] ** 2 * rng.standard_normal(3))
    h_el = L / rod.mesh.n_elements
    n = rod.mesh.n_nodes
    r = rod.r0 + smooth_r + 0.02 * h_el * rng.standard_normal((n, 3))
    R = expm(0.1 * rng.standard_normal((n, 3))) @ expm(smooth_w) @ rod.R0
    return r, R


def random_direction(rod, rng):
    """Unit-scaled direction: positions in units of the element length."""
    h_el = rod.length / rod.mesh.n_elements
    d = rng.standard_normal((rod.mesh.n_nodes, 6))
    d[:, :3] *= h_el
    return d.ravel()


def iw(rod, r, R, tangent=False):
    return internal_work(rod.mesh, r, R, rod.eps0, rod.C, tangent=tangent)


def rotation_distance(R1, R2):
    """Largest angle (rad) of ``R1^T R2`` over the nodes."""
    return float(np.linalg.norm(logm(np.swapaxes(R1, -1, -2) @ R2), axis=-1).max())


E_BEND, G_BEND = 1e7, 5e6
BEND_SECTION = Section(EA=E_BEND, GA1=G_BEND, GA2=G_BEND, EI1=E_BEND / 12,
                       EI2=E_BEND / 12, GJ=G_BEND / 6)


def bend45(n_elements=8, load=600.0):
    """Bathe-Bolourchi 45-degree bend: arc of radius 100 in the xy plane,
    clamped at the start, tip force out of plane (z)."""
    rod = Rod(geometry.arc(100.0, np.pi / 4), BEND_SECTION, n_elements)
    rod.clamp("start").add_force("end", [0.0, 0.0, load])
    return rod


_BEND_CACHE = {}


def bend45_solved(n_steps, **options):
    key = (n_steps, tuple(sorted(options.items())))
    if key not in _BEND_CACHE:
        rod = bend45()
        _BEND_CACHE[key] = (rod, rod.solve(n_steps, **options))
    return _BEND_CACHE[key]


# --------------------------------------------------------------------------
# 1. residual and tangent against finite differences
# --------------------------------------------------------------------------

@pytest.mark.parametrize("section", sorted(SECTIONS))
@pytest.mark.parametrize("shape", sorted(SHAPES))
def test_residual_and_tangent_match_finite_differences(shape, section):
    rng = np.random.default_rng([sorted(SHAPES).index(shape),
                                 sorted(SECTIONS).index(section)])
    rod = Rod(SHAPES[shape](), SECTIONS[section](), 4)
    for trial in range(2):
        r, R = random_state(rod, rng, amp=1.0 + trial)
        w = iw(rod, r, R, tangent=True)
        assert w.energy > 0 and w.max_local_rotation < 2.5
        fnorm = np.linalg.norm(w.force)
        for _ in range(3):
            d = random_direction(rod, rng)
            Ep = iw(rod, *_update(r, R, d, H)).energy
            Em = iw(rod, *_update(r, R, d, -H)).energy
            dE = (Ep - Em) / (2 * H)
            # residual = gradient of the energy w.r.t. the spin-update chart
            assert abs(dE - w.force @ d) <= FD_TOL * fnorm * np.linalg.norm(d)
            fp = iw(rod, *_update(r, R, d, H)).force
            fm = iw(rod, *_update(r, R, d, -H)).force
            Kd = w.matrix @ d
            df = (fp - fm) / (2 * H)
            assert np.linalg.norm(df - Kd) <= FD_TOL * np.linalg.norm(Kd)


def test_system_tangent_with_follower_loads_matches_finite_differences():
    """Residual of :class:`Problem` (internal work minus dead, follower and
    distributed loads) against its tangent, follower load stiffness included."""
    rng = np.random.default_rng(11)
    rod = Rod(SHAPES["helix"](), full_section(3), 4)
    L = rod.length
    node_s = rod.length / 2                     # a vertex of the mesh
    rod.clamp("start")
    rod.add_force("end", [0.3, -0.5, 0.8], follower=True)
    rod.add_moment("end", [0.2, 0.4, -0.1], follower=True)
    rod.add_moment(node_s, [-0.3, 0.1, 0.25], follower=True)
    rod.add_force(node_s, [0.1, 0.2, -0.3], follower=True)
    rod.add_force("end", [0.05, 0.0, 0.1])                  # dead
    rod.add_moment(node_s, [0.0, 0.07, 0.0])                # dead
    rod.add_distributed_force([0.0, 0.0, -0.2])
    rod.add_distributed_torque(lambda s: np.outer(np.sin(s / L), [0.1, 0.0, 0.05]))
    system = Problem(rod)
    lam = 0.7
    r, R = random_state(rod, rng, amp=1.5)
    K = system.evaluate(r, R, lam).tangent
    # the follower loads depend on the configuration: the load stiffness is
    # really exercised (the tangent differs from the internal one)
    K_int = iw(rod, r, R, tangent=True).matrix
    assert abs(K - K_int).max() > 1e-2
    for _ in range(4):
        d = random_direction(rod, rng)
        rp = system.evaluate(*_update(r, R, d, H), lam, tangent=False).residual
        rm = system.evaluate(*_update(r, R, d, -H), lam, tangent=False).residual
        Kd = K @ d
        assert np.linalg.norm((rp - rm) / (2 * H) - Kd) <= FD_TOL * np.linalg.norm(Kd)
        # the load part alone (its own scale is much smaller)
        fp = system.evaluate(*_update(r, R, d, H), lam, tangent=False).external
        fm = system.evaluate(*_update(r, R, d, -H), lam, tangent=False).external
        Kl = (K - K_int) @ d
        assert np.linalg.norm(-(fp - fm) / (2 * H) - Kl) <= FD_TOL * np.linalg.norm(Kl)


# --------------------------------------------------------------------------
# 2. quadratic convergence
# --------------------------------------------------------------------------

def _extended_history(system, step_from, step_to, n_dofs):
    """Newton history of one load step continued to the round-off plateau
    (same iterates as the solver, which stops earlier; plain Newton)."""
    opts = SolverOptions(rtol=1e-16, increment_tol=1e-300, max_iterations=30,
                         position_correction=False)
    _, _, _, rep = newton(system, step_from.r, step_from.R, step_to.load_factor, opts)
    return np.array(rep.history)


def test_newton_converges_quadratically_on_45_degree_bend():
    """Residual histories of the 45-degree bend (3 load steps).

    The Euclidean residual norm is dominated by the axial/shear stiffness
    (EA L^2 / EI ~ 7e4) and is far from monotone before the asymptotic
    regime, so ``q`` is taken at the last contraction whose iterates all lie
    above 100x the round-off plateau (the plateau is measured by continuing
    the same Newton iteration with vanishing tolerances).

    The rate is the consistent tangent's, so it is measured on plain Newton
    (``position_correction=False``): the default position correction
    (newton.position_correction, tested in tests/test_core.py) brings these
    steps to the round-off plateau one or two iterations earlier, leaving
    fewer than three iterates above it to measure a rate on.  The default
    options' asymptotic order is measured free of that by
    test_newton_error_is_quadratic_in_the_perturbation."""
    rod, res = bend45_solved(3, position_correction=False)
    assert res.converged, res.message
    system = Problem(rod)
    qs = []
    for k in range(1, len(res.steps)):
        h = _extended_history(system, res.steps[k - 1], res.steps[k], rod.mesh.n_dofs)
        solver_h = np.array(res.steps[k].residual_history)
        np.testing.assert_allclose(h[:len(solver_h)], solver_h, rtol=1e-6)
        floor = np.median(h[-8:])
        assert floor < 1e-8 * 600.0 * 100                  # a true plateau
        j = int(np.flatnonzero(h > 100 * floor).max())
        q = np.log(h[j] / h[j - 1]) / np.log(h[j - 1] / h[j - 2])
        qs.append(q)
        assert h[j] < h[j - 1] < h[j - 2]
    print("45-degree bend, 3 steps: q =", np.round(qs, 2))
    assert min(qs) >= 1.8, qs


def test_newton_error_is_quadratic_in_the_perturbation():
    """Asymptotic order, free of the residual-norm mixing: start Newton from
    the converged bend perturbed by ``delta`` along a smooth (compliant)
    direction; the first Newton residual scales as the square of the initial
    residual: ``log(r1(d1)/r1(d2)) / log(r0(d1)/r0(d2)) ~ 2``."""
    rod, res = bend45_solved(3)
    system = Problem(rod)
    st = res.steps[-1]
    K = system.evaluate(st.r, st.R, 1.0).tangent
    rng = np.random.default_rng(5)
    d = system.factor(K)(rng.standard_normal(rod.mesh.n_dofs))
    d /= np.abs(d.reshape(-1, 6)[:, 3:]).max()            # largest spin = 1 rad
    opts = SolverOptions(rtol=1e-16, increment_tol=1e-300, max_iterations=1,
                         line_search=False)
    r0, r1 = [], []
    for delta in (1e-5, 1e-6):
        r, R = _update(st.r, st.R, d, delta)
        _, _, _, rep = newton(system, r, R, 1.0, opts)
        r0.append(rep.history[0])
        r1.append(rep.history[1])
    p = np.log(r1[0] / r1[1]) / np.log(r0[0] / r0[1])
    print("order from perturbations: p = %.3f (r0 %s, r1 %s)" % (p, r0, r1))
    assert min(r1) > 30 * 3e-7              # above the round-off plateau (~3e-7)
    assert 1.9 <= p <= 2.1


# --------------------------------------------------------------------------
# 3. exact large-rotation solutions
# --------------------------------------------------------------------------

def test_twenty_turns_of_twist():
    """Straight rod clamped at the start, end pinned and turned 20 times
    about its axis: pure torsion, torque GJ phi / L, stays straight."""
    L, turns, ne = 1.0, 20, 32
    sec = Section.circle(E=1e7, nu=0.3, radius=0.01)
    rod = Rod(geometry.straight(L), sec, ne)
    phi = 2 * np.pi * turns
    rod.clamp("start").pin("end").prescribe_rotation("end", [phi, 0.0, 0.0])
    t0 = time.perf_counter()
    res = rod.solve(1)
    elapsed = time.perf_counter() - t0
    assert res.converged, res.message
    n_steps = len(res.steps) - 1
    iters = sum(st.iterations for st in res.steps)
    print(f"20 turns: {n_steps} steps, {iters} Newton iterations, {elapsed:.2f} s")
    # the solver limits the prescribed rotation per step (default pi/2)
    assert n_steps >= int(np.ceil(phi / SolverOptions().max_rotation_step))
    T = sec.GJ * phi / L
    F_end, M_end = res.reaction("end")
    F_start, M_start = res.reaction("start")
    err = abs(M_end[0] - T) / T
    print(f"20 turns: end torque {M_end[0]!r}, GJ phi / L = {T!r}, rel. error {err:.2e}")
    assert err < 1e-10
    assert abs(M_start[0] + T) < 1e-10 * T
    assert np.abs(np.r_[M_end[1:], M_start[1:]]).max() < 1e-10 * T
    assert np.abs(np.r_[F_end, F_start]).max() < 1e-10 * T / L
    s, r, R = res.nodes()
    assert np.abs(r - rod.r0[rod.mesh.order]).max() < 1e-12 * L        # straight
    assert np.all(is_rotation(R, tol=1e-12))
    for st in res.steps:
        assert np.all(is_rotation(st.R, tol=1e-12))
    exact = expm(np.outer(phi * s / L, [1.0, 0.0, 0.0])) @ rod.R0[rod.mesh.order]
    assert np.abs(R - exact).max() < 1e-10
    ev = res.evaluate(np.linspace(0, L, 11))
    np.testing.assert_allclose(ev["u"][:, 2], phi / L, rtol=1e-10)
    np.testing.assert_allclose(ev["m"][:, 0], T, rtol=1e-10)


def test_cantilever_rolled_up_twice():
    """End moment 4 pi EI / L rolls the cantilever into a double circle of
    radius L / (4 pi): the tip returns to the clamp."""
    L, ne = 1.0, 32
    sec = Section.circle(E=1e7, nu=0.3, radius=0.02)
    rod = Rod(geometry.straight(L), sec, ne)
    M = 4 * np.pi * sec.EI2 / L
    rod.clamp("start").add_moment("end", [0.0, 0.0, M])
    t0 = time.perf_counter()
    res = rod.solve(16)
    elapsed = time.perf_counter() - t0
    assert res.converged, res.message
    print(f"roll-up: {len(res.steps) - 1} steps, "
          f"{sum(st.iterations for st in res.steps)} iterations, {elapsed:.2f} s")
    for st in res.steps:
        assert np.all(is_rotation(st.R, tol=1e-12))
    s, r, R = res.nodes()
    assert np.linalg.norm(r[-1] - r[0]) < 1e-6 * L
    # the whole shape: circle of radius rho, frames rotated by s / rho about z
    rho = L / (4 * np.pi)
    th = s / rho
    circle = np.stack([rho * np.sin(th), rho * (1 - np.cos(th)), 0 * th], axis=1)
    assert np.abs(r - circle).max() < 1e-5 * L
    exact = expm(np.outer(th, [0.0, 0.0, 1.0])) @ rod.R0[rod.mesh.order]
    assert rotation_distance(exact, R) < 1e-6
    # the reaction balances the moment
    F, Mr = res.reaction("start")
    np.testing.assert_allclose(Mr, [0.0, 0.0, -M], atol=1e-9 * M)


# --------------------------------------------------------------------------
# 4. objectivity
# --------------------------------------------------------------------------

Q_ROTVEC = 2.9 * np.array([0.48, -0.6, 0.64]) / np.linalg.norm([0.48, -0.6, 0.64])


def _rigid(r, R, Q, c, origin=0.0):
    return (r - origin) @ Q.T + origin + c, Q @ R


_HELIX_CACHE = {}


def helix_follower_solved(rotated):
    """A helix clamped at the start under an end follower force and moment
    (load parameters F L^2 / EI ~ 4, M L / EI ~ 0.6); ``rotated``: the clamp
    is turned by the rigid rotation ``expm(Q_ROTVEC)`` along the path."""
    if rotated not in _HELIX_CACHE:
        rod = Rod(geometry.helix(0.4, 0.5, 0.75), Section.circle(1e4, 0.3, 0.1), 6)
        if rotated:             # a clamp turned by Q: held position, prescribed rotation
            rod.pin("start").prescribe_rotation("start", Q_ROTVEC)
        else:
            rod.clamp("start")
        rod.add_force("end", [0.0, -0.75, 0.4], follower=True)
        rod.add_moment("end", [0.15, 0.0, -0.2], follower=True)
        _HELIX_CACHE[rotated] = (rod, rod.solve(4))
    return _HELIX_CACHE[rotated]


def test_objectivity_of_a_deformed_state():
    """A rigid motion (large rotation Q, translation c) of a converged 3D
    state and of a random one: energy and material strains unchanged, spatial
    resultants, internal forces and tangent rotate with Q."""
    rod, res = helix_follower_solved(False)
    assert res.converged, res.message
    Q = expm(Q_ROTVEC)
    c = rod.length * np.array([0.4, -0.6, 0.3])
    st = res.steps[-1]
    rng = np.random.default_rng(2)
    states = {"converged": (st.r, st.R), "random": random_state(rod, rng, 1.0)}
    errors = {}
    for name, (r, R) in states.items():
        rq, Rq = _rigid(r, R, Q, c)
        a, b = iw(rod, r, R, tangent=True), iw(rod, rq, Rq, tangent=True)
        errors[name + " energy"] = abs(a.energy - b.energy) / a.energy
        fa, fb = a.force.reshape(-1, 2, 3), b.force.reshape(-1, 2, 3)
        errors[name + " force"] = np.linalg.norm(fb - fa @ Q.T) / np.linalg.norm(fa)
        # the tangent rotates too: K' = T K T^T with T = blockdiag(Q)
        T = np.kron(np.eye(2 * rod.mesh.n_nodes), Q)
        Ka, Kb = a.matrix.toarray(), b.matrix.toarray()
        errors[name + " tangent"] = np.abs(Kb - T @ Ka @ T.T).max() / np.abs(Ka).max()
    # fields through Result.evaluate
    moved = dataclasses.replace(st, r=_rigid(st.r, st.R, Q, c)[0], R=Q @ st.R)
    res.steps.append(moved)
    try:
        s = np.linspace(0, rod.length, 17)
        fa, fb = res.evaluate(s, step=-2), res.evaluate(s, step=-1)
    finally:
        res.steps.pop()
    for key in ("v", "u"):
        errors["strain " + key] = np.abs(fb[key] - fa[key]).max() / np.abs(fa[key]).max()
    for key in ("n", "m"):
        errors["resultant " + key] = (np.abs(fb[key] - fa[key] @ Q.T).max()
                                      / np.abs(fa[key]).max())
    errors["position"] = np.abs(fb["r"] - (fa["r"] @ Q.T + c)).max() / rod.length
    errors["frame"] = np.abs(fb["R"] - Q @ fa["R"]).max()
    print("objectivity (a):", {k: f"{v:.1e}" for k, v in errors.items()})
    assert max(errors.values()) < 1e-10, errors


def test_objectivity_through_the_solver():
    """Same rod and follower loads, once with the clamp fixed and once with
    the clamp turned by a large rigid rotation Q (prescribe_rotation): the
    second equilibrium is the first rotated by Q about the clamp."""
    rod1, res1 = helix_follower_solved(False)
    rod2, res2 = helix_follower_solved(True)
    assert res1.converged, res1.message
    assert res2.converged, res2.message
    Q = expm(Q_ROTVEC)
    origin = rod1.r0[rod1.mesh.end_nodes[0]]
    r1, R1 = res1.steps[-1].r, res1.steps[-1].R
    r2, R2 = res2.steps[-1].r, res2.steps[-1].R
    # the loads really deform the rod (not a rigid motion of the reference)
    assert np.abs(r1 - rod1.r0).max() > 0.1 * rod1.length
    rq, Rq = _rigid(r1, R1, Q, 0.0, origin)
    dr = np.abs(r2 - rq).max() / rod1.length
    dR = rotation_distance(Rq, R2)
    F1, M1 = res1.reaction("start")
    F2, M2 = res2.reaction("start")
    dF = (np.linalg.norm(F2 - Q @ F1) + np.linalg.norm(M2 - Q @ M1)) / (
        np.linalg.norm(F1) + np.linalg.norm(M1))
    print(f"objectivity (b): positions {dr:.1e}, rotations {dR:.1e} rad, "
          f"reactions {dF:.1e}, steps {len(res1.steps) - 1} / {len(res2.steps) - 1}")
    assert dr < 1e-8 and dR < 1e-8 and dF < 1e-8


# --------------------------------------------------------------------------
# 5. path independence
# --------------------------------------------------------------------------

def _difference(res_a, res_b, rod):
    a, b = res_a.steps[-1], res_b.steps[-1]
    return (np.abs(a.r - b.r).max() / rod.length, rotation_distance(a.R, b.R))


def test_path_independence_8_vs_10_steps():
    rod, res8 = bend45_solved(8)
    _, res10 = bend45_solved(10)
    assert res8.converged and res10.converged
    dr, dR = _difference(res8, res10, rod)
    print(f"path independence 8 vs 10 steps: {dr:.1e} L, {dR:.1e} rad")
    assert dr < 1e-8 and dR < 1e-8
    # the published tip position (Simo & Vu-Quoc 1986: 47.2, 15.9, 53.4)
    np.testing.assert_allclose(res8.nodes()[1][-1], [47.2, 15.7, 53.5], atol=0.1)


def test_path_independence_3_vs_7_steps_and_single_step():
    """Different load paths (3 and 7 equal steps; one requested step, which
    the solver cuts) end at the same equilibrium, with default options.  (An
    earlier residual-floor convergence test accepted the single-step state
    ~1e-8 away from the equilibrium; the update-size test does not.)"""
    rod, res3 = bend45_solved(3)
    _, res7 = bend45_solved(7)
    _, res1 = bend45_solved(1)
    assert res3.converged and res7.converged and res1.converged
    d37 = _difference(res3, res7, rod)
    d13 = _difference(res1, res3, rod)
    print(f"path independence 3 vs 7: {d37[0]:.1e} L, {d37[1]:.1e} rad; "
          f"1 (cut into {len(res1.steps) - 1}) vs 3: {d13[0]:.1e} L, {d13[1]:.1e} rad")
    assert max(d37) < 1e-8 and max(d13) < 1e-8


# --------------------------------------------------------------------------
# 6. distributed loads
# --------------------------------------------------------------------------

def test_uniform_distributed_force_matches_linear_beam_theory():
    """Cantilever under a small transverse uniform force q (gravity-like):
    w(L) = q L^4 / (8 EI) + q L^2 / (2 GA) (the shear term of the Timoshenko
    beam); the relative error is the geometric nonlinearity, which vanishes
    with the load (w is odd in q: error ~ q^2)."""
    L = 1.0
    sec = Section.circle(E=1e7, nu=0.3, radius=0.01)
    errs = []
    for q in (1e-3, 1e-4):
        rod = Rod(geometry.straight(L), sec, 8)
        rod.clamp("start").add_distributed_force([0.0, 0.0, -q])
        res = rod.solve(1)
        assert res.converged, res.message
        w = -res.nodes()[1][-1][2]
        w_lin = q * L**4 / (8 * sec.EI2) + q * L**2 / (2 * sec.GA2)
        errs.append(abs(w - w_lin) / w_lin)
        F, M = res.reaction("start")
        np.testing.assert_allclose(F, [0.0, 0.0, q * L], rtol=1e-8, atol=1e-8 * q * L)
    print("distributed force: load parameter qL^3/EI =",
          [f"{q * L**3 / sec.EI2:.1e}" for q in (1e-3, 1e-4)],
          "relative errors", [f"{e:.2e}" for e in errs])
    assert errs[0] < 1e-4
    assert errs[1] < errs[0] / 30                 # ~ q^2: 100x smaller


def test_uniform_distributed_torque_gives_quadratic_twist():
    """Straight rod clamped at the start under a uniform torque t about its
    axis: phi(s) = t (L s - s^2 / 2) / GJ, exactly (quadratic field), here
    with a large end twist of 1.375 turns."""
    L, ne = 2.0, 16
    sec = Section(EA=100.0, GA1=80.0, GA2=80.0, EI1=1.0, EI2=1.0, GJ=0.8)
    phi_end = 2.75 * np.pi
    t = 2 * sec.GJ * phi_end / L**2
    rod = Rod(geometry.straight(L), sec, ne)
    rod.clamp("start").add_distributed_torque([t, 0.0, 0.0])
    res = rod.solve(1)
    assert res.converged, res.message
    s, r, R = res.nodes()
    phi = t * (L * s - s**2 / 2) / sec.GJ
    exact = expm(np.outer(phi, [1.0, 0.0, 0.0])) @ rod.R0[rod.mesh.order]
    err = np.abs(R - exact).max()
    angle_end = np.arctan2(R[-1][2, 0], R[-1][1, 0]) % (2 * np.pi) + 2 * np.pi   # d1
    print(f"distributed torque: end twist {angle_end!r} vs t L^2 / (2 GJ) = "
          f"{phi_end!r}; max frame error {err:.1e}")
    assert abs(angle_end - phi_end) < 1e-10 * phi_end
    assert err < 1e-10
    assert np.abs(r - rod.r0[rod.mesh.order]).max() < 1e-12 * L
    ev = res.evaluate(np.linspace(0, L, 9))
    np.testing.assert_allclose(ev["u"][:, 2], t * (L - ev["s"]) / sec.GJ,
                               rtol=1e-10, atol=1e-10 * t * L / sec.GJ)
    F, M = res.reaction("start")
    np.testing.assert_allclose(M, [-t * L, 0.0, 0.0], atol=1e-10 * t * L)
