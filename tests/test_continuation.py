"""Pseudo-arclength continuation: a limit point against an independent
reference, stability along a solved path (twist buckling under tension),
the API switch and the path plot."""
import numpy as np
import pytest
from scipy.integrate import solve_bvp
from scipy.optimize import minimize_scalar

from skfem_rod import Rod, Section, geometry
from skfem_rod.continuation import PathResult, follow
from skfem_rod.problem import Problem

# shallow circular arch, pinned at both ends, central point load
ANGLE, RADIUS, EI, EA, GA, LOAD = 0.2, 100.0, 1.0, 1e4, 1e4, 1e-2


def arch(n_elements=16):
    a = ANGLE
    shape = geometry.arc(RADIUS, 2 * a, tangent=(np.cos(a), np.sin(a), 0),
                         toward=(np.sin(a), -np.cos(a), 0))
    # in-plane bending is about d2 (the arc's binormal): EI2 = EI; stiff out of plane
    rod = Rod(shape, Section(EA=EA, GA1=GA, GA2=GA, EI1=10 * EI, EI2=EI, GJ=10 * EI), n_elements)
    rod.pin("start").pin("end").fix_rotation("start", (0,))
    rod.add_force(rod.length / 2, [0.0, -LOAD, 0.0])
    return rod


def arch_limit_load_bvp():
    """Symmetric limit load of the same arch from the planar Reissner
    equations (extensible, shearable) on the half arch, solved by
    collocation (scipy solve_bvp) under crown-deflection control and
    maximized over the deflection."""
    a, R = ANGLE, RADIUS
    half, rise = R * np.sin(a), R * (1 - np.cos(a))
    s = np.linspace(0, a * R, 101)

    def rhs(s, u, p):
        th, M = u[2], u[3]
        Nx, Ny = p
        c, sn = np.cos(th), np.sin(th)
        N, Q = Nx * c + Ny * sn, -Nx * sn + Ny * c
        xp = (1 + N / EA) * c - Q / GA * sn
        yp = (1 + N / EA) * sn + Q / GA * c
        return np.vstack([xp, yp, -1 / R + M / EI, -(xp * Ny - yp * Nx)])

    def solve(yc, guess):
        bc = lambda ua, ub, p: np.array([ua[0], ua[1], ua[3], ub[0] - half,  # noqa: E731
                                         ub[1] - yc, ub[2]])
        sol = solve_bvp(rhs, bc, *guess, tol=1e-10, max_nodes=100000)
        assert sol.success, sol.message
        return sol

    u0 = np.vstack([R * (np.sin(a) - np.sin(a - s / R)), R * (np.cos(a - s / R) - np.cos(a)),
                    a - s / R, 0 * s])
    guess = (s, u0, np.zeros(2))
    for yc in np.linspace(rise, 1.1, 12):          # deflection continuation
        sol = solve(yc, guess)
        guess = (sol.x, sol.y, sol.p)
    best = minimize_scalar(lambda yc: 2 * solve(yc, guess).p[1], bounds=(0.95, 1.1),
                           method="bounded", options=dict(xatol=1e-8))
    return -best.fun / LOAD


@pytest.mark.slow
def test_arch_limit_point_passed_and_located():
    rod = arch()
    crown = rod.node(rod.length / 2)
    rise = rod.r0[crown, 1]
    res = follow(rod, lam_stop=None, max_steps=40, stability=True, n_eigen=2,
                 locate_tol=1e-7, stop=lambda r: r.steps[-1].r[crown, 1] < 0)
    assert isinstance(res, PathResult) and res.converged, res.message
    lam = res.load_factors
    k = int(np.argmax(lam))
    # the load factor rises to a maximum and comes back down past it
    assert 0 < k < len(lam) - 5 and lam[-1] < lam[k] - 0.1
    # ... while the crown keeps moving down (the snap-through branch)
    y = np.array([st.r[crown, 1] for st in res.steps])
    assert np.all(np.diff(y) < 0) and y[-1] < 0 < rise
    limits = [c for c in res.critical if c.kind == "limit"]
    assert len(limits) == 1
    ref = arch_limit_load_bvp()
    assert abs(limits[0].load_factor / ref - 1) < 1e-5      # measured 4.3e-7
    assert abs(limits[0].eigenvalue) < 1e-6 * abs(res.eigenvalues[0][0])
    # the symmetric path is followed past an asymmetric bifurcation first
    bif = [c for c in res.critical if c.kind == "bifurcation"]
    assert len(bif) == 1 and bif[0].load_factor < limits[0].load_factor
    mode = bif[0].mode_positions
    assert np.abs(mode[crown, 1]) < 1e-6 * np.abs(mode).max()  # antisymmetric mode
    # Morse index: 0 before the bifurcation, 1 between, 2 past the limit point
    assert res.index[0] == 0 and res.index.max() == 2 and res.index[-1] == 2
    # every converged point is an equilibrium on the arclength it claims
    assert np.all(np.diff(res.arclengths) > 0)


@pytest.mark.slow
def test_twist_buckling_under_tension_detected_without_imperfection():
    """Clamped rod, end on the axis under a constant dead tension, end turned
    about the axis: along the straight twisted branch (no imperfection) the
    lowest eigenvalues cross zero at Greenhill's moment (finite clamped rod:
    2 sqrt(BT) * 1.00198 for L = 50 sqrt(B/T))."""
    B = T = 1.0
    GJ, L, turn = 10.0, 50.0, 12.0
    rod = Rod(geometry.straight(L), Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=B, EI2=B, GJ=GJ), 64)
    rod.clamp("start").pin("end", (1, 2)).add_force("end", [T, 0, 0], constant=True)
    rod.prescribe_rotation("end", [turn, 0, 0])
    res = follow(rod, lam_stop=1.0, stability=True, n_eigen=2, locate_tol=1e-4)
    assert res.converged, res.message
    # the path stays straight (the solver does not need an imperfection) ...
    assert max(np.abs(st.r[:, 1:]).max() for st in res.steps) < 1e-10 * L
    # ... stable at first, unstable at the end
    assert res.index[0] == 0 and res.index[-1] > 0
    first = res.critical[0]
    assert first.kind == "bifurcation"
    end = rod.node("end")
    moment = Problem(rod).evaluate(first.r, first.R, first.load_factor).residual[6 * end + 3]
    greenhill = 2 * np.sqrt(B * T) * 1.00198
    assert abs(moment / greenhill - 1) < 0.05              # measured 2e-6
    assert abs(moment - GJ * turn * first.load_factor / L) < 1e-8   # M = GJ phi / L
    # the helical buckling mode of a round rod: a double eigenvalue
    m = res.eigenvalues[res.index > 0][0]
    assert abs(m[1] - m[0]) < 1e-6 * abs(m[0])


def test_rod_solve_arclength_switch_and_bad_input():
    rod = Rod(geometry.straight(1.0), Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=1.0), 4)
    rod.clamp("start").add_moment("end", [0, 0, np.pi])
    res = rod.solve(4, method="arclength")
    assert isinstance(res, PathResult) and res.converged
    assert res.load_factors[-1] == 1.0
    ref = rod.solve(4)
    assert np.abs(res.steps[-1].r - ref.steps[-1].r).max() < 1e-9
    with pytest.raises(ValueError, match="method"):
        rod.solve(method="riks")
    with pytest.raises(ValueError, match="path"):
        rod.solve(method="arclength", path=(0, 1, 0))
    with pytest.raises(ValueError, match="max_steps"):
        follow(rod, max_steps=0)
    with pytest.raises(ValueError, match="unknown solver option"):
        follow(rod, rtoll=1e-8)
    rod.enable_contact(radius=0.01)
    with pytest.raises(NotImplementedError, match="contact"):
        follow(rod, stability=True)


@pytest.mark.slow
def test_plot_path_marks_stability(tmp_path):
    rod = arch(8)
    crown = rod.node(rod.length / 2)
    res = follow(rod, lam_stop=None, max_steps=30, stability=True, n_eigen=2,
                 locate_tol=1e-3, stop=lambda r: r.steps[-1].r[crown, 1] < 1.3)
    y = np.array([st.r[crown, 1] for st in res.steps])
    ax = res.plot(y, filename=str(tmp_path / "path.png"))
    styles = {line.get_linestyle() for line in ax.get_lines() if len(line.get_xdata()) > 1}
    assert styles == {"-", "--"}
    import matplotlib.image as mpimg
    assert mpimg.imread(tmp_path / "path.png")[..., :3].std() > 0.05
