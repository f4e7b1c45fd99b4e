"""Closed rods (rings): the reference is an equilibrium, objectivity,
an exact pressure solution, topology without closure, bad input, and the
twisted ring folding into three loops (demos/twisted_ring.py)."""
import json
import pathlib

import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.rotations import expm
from skfem_rod.problem import Problem

from helpers import load_demo

SEC = Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=0.8)


@pytest.mark.parametrize("turns", [0, 2])
def test_free_ring_is_unstressed_and_objective(turns):
    rod = Rod(geometry.ring(1.0, twist_turns=turns), SEC, 8)
    assert rod.mesh.n_nodes == 3 * 8                     # the end node is the start node
    assert rod.mesh.nodes[-1, 1] == rod.mesh.nodes[0, 0]
    ev = Problem(rod).evaluate(rod.r0, rod.R0, 0.0)
    res, K, iw = ev.residual, ev.tangent, ev.internal
    assert np.abs(res).max() < 1e-10 and iw.energy < 1e-20
    # a rigid motion of the whole ring: no force, no energy (objectivity)
    Q = expm(np.array([0.3, -0.5, 0.7]))
    ev = Problem(rod).evaluate(rod.r0 @ Q.T + [1.0, 2.0, 3.0], Q @ rod.R0, 0.0)
    res, K, iw = ev.residual, ev.tangent, ev.internal
    assert np.abs(res).max() < 1e-9 * 1e4 and iw.energy < 1e-18
    # six rigid modes in the kernel of the tangent of the free ring
    w = np.linalg.eigvalsh(0.5 * (K + K.T).toarray())
    assert np.sum(np.abs(w) < 1e-8 * np.abs(w).max()) == 6


def test_ring_under_uniform_pressure_converges_to_exact():
    """Dead inward load p per unit reference length (below the buckling
    pressure 3 EI / R^3): hoop force N = -p R, the ring shrinks uniformly to
    rho = R (1 - p R / EA), no bending (the curvature per unit reference
    length stays 1/R).  The P3 reference circle is not exact, so the error
    converges with the mesh (measured rates 5.6 and 4.6)."""
    R, p, EA = 2.0, 0.2, 100.0
    errors = []
    for ne in (8, 16, 32):
        rod = Rod(geometry.ring(R), Section(EA=EA, GA1=EA, GA2=EA, EI1=1.0, EI2=1.0, GJ=0.8), ne)
        rod.clamp("start")
        rod.add_distributed_force(lambda s: -p * np.stack([np.cos(s / R), np.sin(s / R),
                                                           0 * s], axis=1))
        result = rod.solve(2)
        assert result.converged
        rho = R * (1 - p * R / EA)
        centre = np.array([R - rho, 0.0, 0.0])           # the clamped point stays put
        r = result.steps[-1].r
        f = result.evaluate(np.linspace(0, rod.length, 33))
        hoop = np.einsum("ni,nij,j->n", f["n"], f["R"], [0, 0, 1.0])      # n . d3
        errors.append((np.abs(np.linalg.norm(r - centre, axis=1) - rho).max() / R,
                       np.abs(hoop + p * R).max() / (p * R)))
    e = np.array(errors)
    rates = np.log2(e[:-1] / e[1:])
    assert np.all(rates > 3.5), rates
    assert e[-1, 0] < 1e-8 and e[-1, 1] < 1e-4


def test_ring_topology_has_no_closure():
    rod = Rod(geometry.ring(1.0, twist_turns=3), SEC, 12)
    rod.clamp("start")
    top = rod.solve().topology()
    assert top.closure_twist == 0.0
    assert abs(top.twist - 3) < 1e-9 and abs(top.writhe) < 1e-9
    assert abs(top.link - (top.twist + top.writhe)) < 1e-12 and round(top.link_gauss) == 3


def test_closed_rod_bad_input():
    with pytest.raises(ValueError, match="twist_turns"):
        geometry.ring(1.0, twist_turns=0.5)
    with pytest.raises(ValueError, match="close up"):
        Rod(geometry.closed(geometry.arc(1.0, 3.0)), SEC, 8)
    with pytest.raises(ValueError, match="n_elements >= 3"):
        Rod(geometry.ring(1.0), SEC, 2)
    with pytest.raises(ValueError, match="shape"):
        geometry.closed("ring")


@pytest.mark.slow
def test_twisted_ring_folds_into_three_loops(tmp_path):
    demo = load_demo("twisted_ring")
    summary = demo.main(str(tmp_path), **demo.SMALL)
    data = json.loads((tmp_path / "results.json").read_text())
    assert data["converged"] and abs(data["turn_end"] - 2 * np.pi) < 1e-12
    # the end state is the triple-covered circle of radius R/3 (12 elements: 4e-4 R)
    assert data["triple_ring_error_over_R"] < 1e-3
    assert abs(data["B_distance_from_A_over_R"] - 2 / 3) < 1e-4
    bm = data["bending_moment_end"]
    assert abs(bm["min"] / bm["exact"] - 1) < 1e-8 and abs(bm["max"] / bm["exact"] - 1) < 1e-8
    # the fold: two limit points in the turn, unstable between them, stable elsewhere
    crit = data["critical_points"]
    assert [c["kind"] for c in crit] == ["limit", "limit"]
    # pinned figures (24 elements: 1.12958 pi and 1.12800 pi; 12 elements agree to 2e-5)
    assert abs(crit[0]["turn_over_pi"] - 1.12958) < 1e-3
    assert abs(crit[1]["turn_over_pi"] - 1.12800) < 1e-3
    index = np.array(data["path"]["index"])
    turn = np.array(data["path"]["turn"])
    assert index[0] == 0 and index[-1] == 0 and set(index) == {0, 1}
    assert np.all((turn[index == 1] > crit[1]["turn"] - 1e-9)
                  & (turn[index == 1] < crit[0]["turn"] + 1e-9))
    # the end moment about AB vanishes at the triple ring, B slid by 4R/3
    assert abs(data["path"]["end_moment_about_AB"][-1]) < 1e-6
    assert abs(data["path"]["slide_of_B"][-1] - 4 / 3) < 1e-4
    for f in [summary["plot"]] + summary["renders"]:
        assert pathlib.Path(f).stat().st_size > 1000
