"""Branch switching (skfem_rod.continuation.switch_branch): a perfect
clamped-free column followed by arc-length continuation with stability on
stays straight, the bifurcation is located at the Euler load, and switching
along the critical mode follows the buckled (elastica) branch, whose load
rises as the inextensible elastica's ``P / P_cr = 1 + alpha^2 / 8 + ...``
(``alpha`` the tip rotation)."""
import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.continuation import follow, switch_branch

pytestmark = pytest.mark.slow    # a scene or a long run (fast tier: -m "not slow")

EI, L = 1.0, 1.0
SEC = Section(EA=1e7, GA1=1e7, GA2=1e7, EI1=EI, EI2=2 * EI, GJ=1.0, radius=0.01)
P_CR = np.pi ** 2 * EI / (4 * L ** 2)


def column():
    rod = Rod(geometry.straight(L), SEC, 8)
    rod.clamp("start").add_force("end", [-1.5 * P_CR, 0.0, 0.0])
    return rod


def test_switch_onto_the_buckled_branch():
    rod = column()
    path = follow(rod, lam_stop=1.0, stability=True, n_eigen=2, locate_tol=1e-6)
    assert path.converged, path.message
    # the straight branch: no lateral deflection at all
    assert np.abs(path.steps[-1].r[:, 1:]).max() < 1e-10
    bif = [c for c in path.critical if c.kind == "bifurcation"]
    assert bif
    point = bif[0]
    # located at the Euler load of the weak axis (EI1 = EI < EI2)
    assert point.load_factor * 1.5 == pytest.approx(1.0, rel=1e-4)
    branch = switch_branch(rod, point, lam_stop=None, max_steps=40, side=1)
    assert len(branch.steps) > 5
    tip = rod.node("end")
    alphas, ratios = [], []
    for st in branch.steps[1:]:
        t = st.R[tip][:, 2]                     # d3 at the tip (rod axis)
        alpha = np.arccos(np.clip(t[0], -1, 1))
        alphas.append(alpha)
        ratios.append(1.5 * st.load_factor)    # P / P_cr
    alphas, ratios = np.array(alphas), np.array(ratios)
    # the column left the straight state and buckled
    assert alphas.max() > 0.5
    # on the buckled branch the load rises with the tip rotation like the
    # elastica: P / P_cr - 1 = alpha^2 / 8 to leading order (measured
    # 0.12502 at alpha = 0.013, 0.12509 at 0.092; 0.1283 at 0.54, where the
    # higher-order terms show)
    small = (alphas > 0.01) & (alphas < 0.1)
    assert small.sum() >= 3
    assert np.allclose((ratios[small] - 1) / alphas[small] ** 2, 1 / 8, rtol=2e-3)
    assert np.all(np.diff(ratios) > 0)          # supercritical: the load rises
