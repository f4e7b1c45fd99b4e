"""The overhand-knot scene (demos/knot.py): the reference is a knot whose
strands are well apart, the knot is kept (no strand passage) while it is
pulled and let go, frictionless pulling is reversible, friction makes the
tightening force exceed the loosening force at the same end distance
(hysteresis), and Coulomb's law holds at every converged step."""

import os

import numpy as np
import pytest

from helpers import coulomb_checks, load_demo


knot = load_demo("knot")

# small size: 48 elements, pulled by 0.42 (21 tube radii) in 6 steps and back
SMALL = dict(pull=0.42, n_elements=48, n_steps=6)
GAMMA = 0.3


def test_reference_is_an_open_knot_with_strands_well_apart():
    """The reference shape: strands at least 6 tube radii apart (away from
    the exclusion zone) and both tails along the pulling axis x."""
    rod = knot.build(0.0, **{k: SMALL[k] for k in ("pull", "n_elements")})
    s = np.linspace(0, rod.length, 1201)
    r, R = rod.shape(s)
    d = knot.min_strand_distance(r, s, 2.5 * np.pi * knot.EPS)
    assert d >= 5.9 * knot.EPS
    t0, t1 = R[0][:, 2], R[-1][:, 2]
    assert t0 == pytest.approx([1, 0, 0], abs=1e-6) and t1 == pytest.approx([1, 0, 0], abs=1e-6)


# The solved scene is slow: in the contact phase of the loose knot Newton
# rarely converges within the 6 iterations the demo allows, and most steps
# go through the gradient flow (5 to 20 s a step on this machine; 48
# elements, 6 steps each way: > 2 min per friction coefficient).  Until the
# solver converges on this scene (docs/knot.md, "Status"), the scene tests
# run only on request.
scene = pytest.mark.skipif(os.environ.get("SKFEM_ROD_KNOT_SCENE") != "1",
                           reason="knot scene: minutes per run; set SKFEM_ROD_KNOT_SCENE=1")


@pytest.fixture(scope="module")
def runs():
    return {g: knot.solve(g, **SMALL) for g in (0.0, GAMMA)}


def _same_lam_pairs(rows):
    """Index pairs (tightening, loosening) of steps at the same load factor."""
    lam = np.array([w["load_factor"] for w in rows])
    t = np.array([w["time"] for w in rows])
    pairs = []
    for i in np.flatnonzero(t < 0.5 - 1e-12):
        j = np.flatnonzero((t > 0.5 + 1e-12) & np.isclose(lam, lam[i], atol=1e-12))
        if j.size:
            pairs.append((i, j[0]))
    return pairs


@scene
def test_knot_is_kept_and_contact_is_resolved(runs):
    """Along the whole path: converged, the link of the rod unchanged (a
    strand passing through another changes it by 2), strands never closer
    than 2 eps minus 5 % (the crossing point of two strands may fall between
    slave points, see docs/knot.md), penetration at the slave points within
    the Uzawa tolerance 1e-3 eps, and contact reached while pulled."""
    for g, sol in runs.items():
        res, rows = sol["result"], sol["rows"]
        assert res.converged, res.message
        link = np.array([w["link"] for w in rows])
        assert np.ptp(link) < 0.05
        assert min(w["min_strand_distance"] for w in rows) > 1.9 * knot.EPS
        assert max(w["penetration"] for w in rows) <= 1e-3 * knot.EPS
        assert max(w["n_contact"] for w in rows) > 0


@scene
def test_frictionless_pulling_is_reversible(runs):
    """Frictionless statics is path independent: at the same end distance
    the loosening force equals the tightening force (to 1e-3 relative,
    the equilibrium and Uzawa tolerances)."""
    rows = runs[0.0]["rows"]
    pairs = _same_lam_pairs(rows)
    assert len(pairs) >= 5
    for i, j in pairs:
        assert rows[j]["distance"] == pytest.approx(rows[i]["distance"], rel=1e-9)
        assert rows[j]["force"] == pytest.approx(rows[i]["force"], rel=1e-3, abs=1e-6)


@scene
def test_friction_makes_tightening_force_exceed_loosening_force(runs):
    """With gamma_T > 0, at every end distance where the knot is in contact
    on both branches the tightening force exceeds the loosening force; the
    ratio (1 without friction) grows with gamma_T."""
    ratios = {}
    for g, sol in runs.items():
        rows = sol["rows"]
        rs = [rows[i]["force"] / rows[j]["force"] for i, j in _same_lam_pairs(rows)
              if rows[i]["n_contact"] and rows[j]["n_contact"]]
        assert rs, f"no contact on both branches for gamma_T={g}"
        ratios[g] = max(rs)
    assert ratios[0.0] == pytest.approx(1.0, abs=1e-3)
    assert ratios[GAMMA] > 1.02
    assert ratios[GAMMA] > ratios[0.0]


@scene
def test_knot_obeys_coulomb_at_every_step(runs):
    res = runs[GAMMA]["result"]
    coulomb_checks(res, GAMMA, 0.0)
    assert sum(w["dissipation"] for w in runs[GAMMA]["rows"]) > 0
