"""Stability: lowest eigenvalues of the symmetrized tangent and critical
loads (see docs/stability.md for the derivations and measured tables).

1. Clamped-free column under a dead compressive end force: the exact
   critical load of this shearable, extensible model,
   ``P (1 - P/EA + P/GA) = pi^2 EI / (4 L^2)``, from the exact uniformly
   compressed prebuckling state; convergence rate; buckling mode.
2. Lateral-torsional buckling of a tip-loaded cantilever strip (Michell,
   Prandtl): ``P_cr = 4.0126 sqrt(EI_weak GJ) / L^2`` with the prebuckling
   (in-plane bending) state solved by Newton at each load; twist mode.
3. Unloaded clamped rods are stable: every eigenvalue positive, the
   eigenpairs agree with a dense solver, small eigen-residuals.
4. Symmetry of the tangent at equilibrium: symmetric for dead forces,
   not for follower forces and end moments (dead or follower).

Run ``pytest -s tests/test_stability.py`` to see the measured numbers.
"""
import doctest

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.special import jv

from helpers import bent_cantilever
from skfem_rod import Rod, Section, geometry, stability
from skfem_rod.problem import Problem
from skfem_rod.stability import (EquilibriumPath, critical_load, inertia,
                                 lowest_eigenvalues)

#: 2 x first zero of the Bessel function J_{-1/4} (Michell's constant)
MICHELL = 4.012599343578901


def correlation(a, b):
    return abs(a @ b) / (np.linalg.norm(a) * np.linalg.norm(b))


# ==========================================================================
# 1. Euler / Haringx column, exact prebuckling state
# ==========================================================================
EA, GA, EI, L = 100.0, 50.0, 1.0, 1.0


def column(n_elements, EI2=2.0 * EI):
    sec = Section(EA=EA, GA1=GA, GA2=GA, EI1=EI, EI2=EI2, GJ=1.0)
    rod = Rod(geometry.straight(L), sec, n_elements)
    rod.clamp("start").add_force("end", [-1.0, 0.0, 0.0])      # P = lam
    return rod


def column_state(rod):
    """Exact equilibrium at P = lam: uniform compression, R = R0."""
    return lambda lam: (rod.r0 * (1.0 - lam / EA), rod.R0)


def haringx_load():
    """Smallest root of P (1 - P/EA + P/GA) = pi^2 EI / (4 L^2)."""
    c, a = np.pi**2 * EI / (4 * L**2), 1.0 / GA - 1.0 / EA
    return (-1.0 + np.sqrt(1.0 + 4.0 * a * c)) / (2.0 * a)


def test_column_prebuckling_state_is_exact_equilibrium():
    rod = column(4)
    r, R = column_state(rod)(2.0)
    m = lowest_eigenvalues(rod, r, R, 2.0, k=2)
    assert m.residual < 1e-11          # round-off: 3e-13
    assert m.asymmetry < 1e-14 and m.negative == 0


def test_column_critical_load_haringx():
    rod = column(8)
    crit = critical_load(rod, column_state(rod), 1.0, 4.0, tol=1e-12)
    P = haringx_load()
    err = abs(crit.load_factor / P - 1)
    print(f"\ncolumn: P_cr = {crit.load_factor:.12f}, exact {P:.12f}, rel. error {err:.2e}, "
          f"{crit.evaluations} evaluations")
    assert err < 1e-8                 # the issue asks 1e-6; 8 P3 elements give 1e-9
    lo, hi = crit.bracket
    assert lo < crit.load_factor < hi and hi - lo < 1e-11 * hi
    # the extensibility/shear correction is resolved: Euler's value is 1% off
    assert abs(np.pi**2 * EI / (4 * L**2) / P - 1) > 1e-2
    # mode: bending about d1 (EI1 < EI2), spin_y = sin(pi s / 2L), w along z
    m = crit.modes
    s = rod.mesh.s_nodes
    assert abs(m.values[0]) < 1e-9
    assert correlation(m.spins[0][:, 1], np.sin(np.pi * s / (2 * L))) > 1 - 1e-12
    assert np.abs(m.spins[0][:, [0, 2]]).max() < 1e-12
    assert np.abs(m.positions[0][:, :2]).max() < 1e-12
    # the illinois variant finds the same load in fewer evaluations
    fast = critical_load(rod, column_state(rod), 1.0, 4.0, tol=1e-12, method="illinois")
    assert abs(fast.load_factor / crit.load_factor - 1) < 1e-10
    assert fast.evaluations < crit.evaluations / 2


def test_column_critical_load_converges_at_sixth_order():
    P = haringx_load()
    ns = np.array([1, 2, 4])
    errs = []
    for n in ns:
        rod = column(n)
        crit = critical_load(rod, column_state(rod), 1.0, 4.0, tol=1e-13, method="illinois")
        errs.append(abs(crit.load_factor / P - 1))
    rate = -np.polyfit(np.log(ns), np.log(errs), 1)[0]
    print("\ncolumn errors (1, 2, 4 elements):", ", ".join(f"{e:.2e}" for e in errs),
          f"rate {rate:.2f}")
    assert rate > 5.5
    assert errs[-1] < 1e-7


def test_column_double_eigenvalue_and_solved_path():
    """EI1 = EI2: both bending planes buckle at once (eigenvalue of
    multiplicity 2); the Newton path stays straight and gives the same load."""
    rod = column(6, EI2=EI)
    path = EquilibriumPath(rod, max_step=1.0)
    crit = critical_load(rod, path, 1.0, 4.0, tol=1e-10, method="illinois")
    assert abs(crit.load_factor / haringx_load() - 1) < 1e-7
    r, R = path(3.0)                          # beyond the critical load
    np.testing.assert_allclose(r, rod.r0 * (1 - 3.0 / EA), atol=1e-12)
    m = lowest_eigenvalues(rod, r, R, 3.0, k=3)
    assert m.negative == 2 and np.all(m.values[:2] < 0) and m.values[2] > 0
    assert abs(m.values[0] / m.values[1] - 1) < 1e-8


# ==========================================================================
# 2. lateral-torsional buckling of a cantilever strip
# ==========================================================================
def strip(n_elements, ratio=1e4, GJ=1.0, stiff=1e6):
    """Rod along x, d1 = y (strong axis, EI1 = ratio), d2 = z (weak); dead
    tip force -P e_z at the centroid bends it in its stiff (x, z) plane."""
    sec = Section(EA=stiff, GA1=stiff, GA2=stiff, EI1=ratio, EI2=1.0, GJ=GJ)
    rod = Rod(geometry.straight(L), sec, n_elements)
    rod.clamp("start").add_force("end", [0.0, 0.0, -1.0])
    return rod


def test_lateral_torsional_buckling_cantilever():
    rod = strip(8)
    path = EquilibriumPath(rod, max_step=1.0)
    P0 = MICHELL * np.sqrt(1.0 * 1.0) / L**2
    crit = critical_load(rod, path, 0.8 * P0, 1.3 * P0, tol=1e-8)
    err = crit.load_factor / P0 - 1
    print(f"\nLTB: P_cr L^2 / sqrt(EI_w GJ) = {crit.load_factor:.6f} (Michell {MICHELL:.6f}), "
          f"rel. diff {err:.2e}, {crit.evaluations} evaluations, "
          f"{path.newton_iterations} Newton iterations")
    assert abs(err) < 1e-3
    # what is left is the prebuckling in-plane deflection, ~1.15 EI_w / EI_s
    assert 0 < err < 2e-4
    # the prebuckling state is the in-plane bent one, an equilibrium
    lo, _ = crit.bracket
    r, R = path(lo)
    tip = r[rod.node("end")]
    assert abs(tip[1]) < 1e-12 and tip[2] < 0
    m = crit.modes
    assert m.residual < 1e-7 and m.asymmetry < 1e-14
    # mode: twist phi = sqrt(xi) J_{-1/4}(gamma xi^2 / 2L^2), xi = L - s,
    # with lateral displacement along y and no in-plane component
    xi = np.maximum(L - rod.mesh.s_nodes, 1e-12)
    phi = np.sqrt(xi) * jv(-0.25, MICHELL * xi**2 / (2 * L**2))
    assert correlation(m.spins[0][:, 0], phi) > 1 - 1e-6
    assert np.abs(m.positions[0][:, 1]).max() > 0.1
    assert np.abs(m.spins[0][:, 1]).max() < 1e-8


# ==========================================================================
# 3. unloaded rods are stable; eigenpairs
# ==========================================================================
@pytest.mark.parametrize("shape", [geometry.straight(1.0),
                                   geometry.arc(0.5, 2.0),
                                   geometry.helix(0.3, 0.2, 1.0)])
def test_unloaded_clamped_rod_is_stable(shape):
    sec = Section(EA=1e3, GA1=8e2, GA2=6e2, EI1=1.0, EI2=2.0, GJ=0.7)
    rod = Rod(shape, sec, 6)
    rod.clamp("start")
    k = 6
    m = lowest_eigenvalues(rod, rod.r0, rod.R0, 0.0, k=k)
    assert m.negative == 0 and np.all(m.values > 0)
    assert m.residual == 0.0 or m.residual < 1e-12
    # against a dense solver on the free dofs
    system = Problem(rod)
    K = system.evaluate(rod.r0, rod.R0, 0.0).tangent
    free = system.free
    Kf = K.toarray()[np.ix_(free, free)]
    Ks = 0.5 * (Kf + Kf.T)
    w = np.linalg.eigvalsh(Ks)
    assert w.min() > 0
    np.testing.assert_allclose(m.values, w[:k], rtol=1e-10)
    # eigen-residuals and orthonormality of the returned modes
    # (position, spin) per node is the dof order 6 n + c
    V = np.concatenate([m.positions, m.spins], axis=-1).reshape(k, -1)[:, free].T
    res = np.linalg.norm(Ks @ V - V * m.values, axis=0) / np.abs(w).max()
    assert res.max() < 1e-12
    np.testing.assert_allclose(V.T @ V, np.eye(k), atol=1e-10)
    # constrained dofs are zero in the modes
    n0 = rod.node("start")
    assert np.all(m.positions[:, n0] == 0) and np.all(m.spins[:, n0] == 0)


def test_shift_near_a_given_value_and_inertia():
    rod = column(4, EI2=EI)
    r, R = column_state(rod)(30.0)            # far beyond buckling: several negative
    m = lowest_eigenvalues(rod, r, R, 30.0, k=4)
    system = Problem(rod)
    K = system.evaluate(r, R, 30.0).tangent
    free = system.free
    Kf = K.toarray()[np.ix_(free, free)]
    w = np.linalg.eigvalsh(0.5 * (Kf + Kf.T))
    np.testing.assert_allclose(m.values, w[:4], rtol=1e-9, atol=1e-12)
    assert m.negative == np.sum(w < 0) >= 3
    # the k eigenvalues nearest a given shift
    near = lowest_eigenvalues(rod, r, R, 30.0, k=3, sigma=0.3)
    expect = np.sort(w[np.argsort(np.abs(w - 0.3))[:3]])
    np.testing.assert_allclose(near.values, expect, rtol=1e-9)
    # inertia at several shifts against the dense count
    Ks = sp.csc_matrix(0.5 * (Kf + Kf.T))
    for shift in (-1.0, -0.01, 0.05, 1.0, 10.0):
        assert inertia(Ks, shift) == np.sum(w < shift)


def test_bad_brackets_say_what_to_do():
    rod = column(2)
    with pytest.raises(ValueError, match="lower lam_lo"):
        critical_load(rod, column_state(rod), 3.0, 4.0)
    with pytest.raises(ValueError, match="raise lam_hi"):
        critical_load(rod, column_state(rod), 1.0, 2.0)
    with pytest.raises(ValueError, match="method"):
        critical_load(rod, column_state(rod), 1.0, 4.0, method="newton")


# ==========================================================================
# 4. symmetry of the tangent at equilibrium: conservative vs not
# ==========================================================================
def loaded_cantilever(kind, follower, vec):
    sec = Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.5, GJ=0.8)
    rod = Rod(geometry.straight(1.0), sec, 8)
    rod.clamp("start")
    getattr(rod, "add_" + kind)("end", vec, follower=follower)
    res = rod.solve(n_steps=8)
    assert res.converged, res.message
    st = res.steps[-1]
    return lowest_eigenvalues(rod, st.r, st.R, 1.0, k=2)


def test_tangent_symmetric_at_equilibrium_only_for_conservative_loads():
    f = np.array([0.0, 3.0, 1.0])
    M = np.array([0.7, 1.0, 2.0])
    dead = loaded_cantilever("force", False, f)
    print(f"\n||K-K^T||/||K|| at equilibrium: dead force {dead.asymmetry:.1e}", end="")
    assert dead.residual < 1e-8 and dead.asymmetry < 1e-14
    fol = loaded_cantilever("force", True, f)
    assert fol.residual < 1e-8
    np.testing.assert_allclose(fol.skew, 2 * np.linalg.norm(f), rtol=1e-8)
    for follower in (False, True):
        mom = loaded_cantilever("moment", follower, M)
        assert mom.residual < 1e-8
        np.testing.assert_allclose(mom.skew, np.sqrt(2) * np.linalg.norm(M), rtol=1e-8)
    print(f", follower force {fol.asymmetry:.1e} (skew {fol.skew:.3f} = 2|f|), "
          f"end moment {mom.asymmetry:.1e} (skew {mom.skew:.3f} = sqrt2 |m|)")


def test_docstrings():
    failed, attempted = doctest.testmod(stability, optionflags=doctest.ELLIPSIS)
    assert attempted > 0 and failed == 0


def _always_unstable(monkeypatch):
    """Every state reads as unstable (its lowest eigenvalue made negative,
    its mode kept)."""
    from skfem_rod import solver
    real = solver.LoadStepper.lowest_mode

    def always_unstable(self, r, R, lam):
        value, mode, _ = real(self, r, R, lam)
        return -abs(value) - 1.0, mode, 1

    monkeypatch.setattr(solver.LoadStepper, "lowest_mode", always_unstable)


def test_relax_never_records_a_saddle(monkeypatch):
    """snap="relax", stability=True: a step that lands on a saddle is pushed
    off along its unstable mode and relaxed, at most solver.MAX_PUSHES
    times; where every relaxed state is still a saddle (forced here: every
    state reads as unstable; without contact a flow that comes back is no
    reason to keep it: see the next test) the step fails with the message,
    no saddle is recorded, and the solve stops with the converged steps."""
    from skfem_rod import solver
    _always_unstable(monkeypatch)
    rod = bent_cantilever()
    res = rod.solve(1, snap="relax", stability=True, min_step=0.2)
    assert not res.converged
    assert len(res.steps) == 1                    # step 0 only: no saddle kept
    assert "unstable equilibrium" in res.message
    assert f"after {solver.MAX_PUSHES} pushes" in res.message
    pushes = [line for line in res.log if "relaxing along the unstable mode" in line]
    assert len(pushes) % solver.MAX_PUSHES == 0 and pushes


def test_a_state_in_contact_the_flow_comes_back_to_from_both_sides_is_kept(monkeypatch):
    """The pressed hairpin (tests/test_contact.py) is a stable equilibrium
    in contact; made to read as unstable, it is pushed off along its
    lowest mode four times (solver.MAX_PUSHES), and the flow comes back to
    it from the last two, both ways (solver.RETURN_SHARE): the state is
    kept with the log line and the tangent's eigenvalue, and it is the
    equilibrium found without the stability check.  Without the rule the
    step fails as a saddle.  (In the plectoneme at 2.375 turns the tangent
    of the nonsmooth contact read -0.15 to -0.21 at states every push came
    back to, and the step was cut until the run ended.)"""
    from skfem_rod import solver
    from test_contact import SEC, hairpin

    def pressed():
        eps = SEC.radius
        rod = Rod(hairpin(eps, 4 * eps), SEC, 40)
        return rod.clamp("start").add_force("end", [0, -0.6, 0]).enable_contact(tolerance=1e-6)
    plain = pressed().solve(1)          # one step: the load factor 1, in contact
    assert plain.converged and plain.steps[-1].contact.s.size > 0
    _always_unstable(monkeypatch)
    res = pressed().solve(1, snap="relax", stability=True, min_step=0.5)
    assert res.converged, res.message
    pushes = [m for m in res.log if m.startswith("step to lam=1: unstable")]
    assert len(pushes) == solver.MAX_PUSHES
    assert any(m.startswith("step to lam=1: the flow came back") for m in res.log)
    assert res.steps[1].lowest_eigenvalue < 0
    assert np.abs(res.steps[1].r - plain.steps[1].r).max() < 1e-4 * SEC.radius
    monkeypatch.setattr(solver, "RETURN_SHARE", 0.0)
    res = pressed().solve(1, snap="relax", stability=True, min_step=0.5)
    assert not res.converged and "unstable equilibrium" in res.message
