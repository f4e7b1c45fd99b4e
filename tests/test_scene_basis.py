"""Supports in local axes in scene files (``axes`` of a [[support]], the
scene form of ``Rod.support_basis``): a scene reproduces the Python-API
solution (the inclined-roller example and skew 3-D bases), the roller only
pushes along the incline's normal, and every malformed ``axes`` gives a
message naming the key, the value and what is allowed."""
import copy
import math
import pathlib

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from skfem_rod import Rod, Section, geometry
from skfem_rod.rotations import expm
from skfem_rod.scene import AXES_TOL, SceneError, load_scene

try:
    import tomllib
except ModuleNotFoundError:                      # Python 3.10
    import tomli as tomllib

ROOT = pathlib.Path(__file__).resolve().parents[1]
SEC = dict(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=0.8)
SECTION = Section(**SEC)


def _same(res_a, res_b, tol=1e-10):
    """Largest difference of positions and frames over every step."""
    assert len(res_a.steps) == len(res_b.steps)
    return max(max(np.abs(a.r - b.r).max(), np.abs(a.R - b.R).max())
               for a, b in zip(res_a.steps, res_b.steps))


# ---------------------------------------------------------------------------
# the example scene: a beam on a pin and a roller on a 30-degree incline
# ---------------------------------------------------------------------------
def test_inclined_roller_scene_reproduces_the_python_api_and_rolls_on_the_incline():
    path = ROOT / "scenes" / "inclined_roller.toml"
    scene = load_scene(path)
    with open(path, "rb") as f:
        raw = tomllib.load(f)
    res_s = scene.solve()
    assert res_s.converged

    a = math.radians(30.0)
    t = np.array([math.cos(a), math.sin(a), 0.0])       # along the incline
    n = np.array([-math.sin(a), math.cos(a), 0.0])      # normal to it
    Q = np.column_stack([t, n, [0.0, 0.0, 1.0]])
    w = raw["load"][0]["vector"]
    rod = Rod(geometry.straight(1.0), SECTION, raw["rod"]["n_elements"])
    rod.pin("start").fix_rotation("start", [0])
    rod.support_basis("end", Q).pin("end", [1, 2])
    rod.add_distributed_force(w)
    res_p = rod.solve(raw["solver"]["n_steps"])
    assert res_p.converged
    assert _same(res_s, res_p) < 1e-10

    # the physics of a roller on an incline: the end stays on the incline's
    # line through (1, 0, 0), and slid down it (the beam sags and shortens
    # its chord); the roller pushes along n only; the supports carry w L
    end = res_s.steps[-1].r[rod.node("end")]
    assert abs((end - [1.0, 0.0, 0.0]) @ n) < 1e-12 and abs(end[2]) < 1e-12
    assert (end - [1.0, 0.0, 0.0]) @ t < -0.05
    f_end, _ = res_s.reaction("end")
    f_start, _ = res_s.reaction("start")
    assert abs(f_end @ t) < 1e-8 * np.linalg.norm(w)
    assert f_end @ n > 0
    assert np.abs(f_end + f_start + np.asarray(w) * 1.0).max() < 1e-8 * np.linalg.norm(w)
    # the roller's thrust is horizontal too: the start pin takes it back
    assert f_start[0] > 0.1 * np.linalg.norm(w)


# ---------------------------------------------------------------------------
# skew 3-D bases: axes are the columns of Q, normalized on load
# ---------------------------------------------------------------------------
def _skew_scene(axes):
    return {
        "rod": {"geometry": {"type": "straight", "length": 1.0}, "n_elements": 4},
        "section": dict(SEC),
        "support": [
            {"where": "start", "kind": "clamp"},
            {"where": "end", "kind": "pin", "components": [2], "axes": axes},
            {"where": "end", "kind": "fix_rotation", "components": [1], "axes": axes},
            {"where": "end", "kind": "prescribe_displacement", "components": [0],
             "displacement": [0.05, 0.0, 0.0], "axes": axes}],
        "load": [{"kind": "force", "where": "end", "vector": [0.3, 1.5, -1.0]},
                 {"kind": "moment", "where": "end", "vector": [0.4, 0.0, 0.2]}],
        "solver": {"n_steps": 2}}


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_skew_axes_scene_reproduces_the_python_api(seed):
    rng = np.random.default_rng(seed)
    Q = expm(rng.normal(size=3) * 1.5)
    # axes given unnormalized (each scaled by its own factor): same basis
    axes = (Q.T * rng.uniform(0.1, 10.0, size=(3, 1))).tolist()
    res_s = load_scene(_skew_scene(axes)).solve()
    rod = Rod(geometry.straight(1.0), SECTION, 4).clamp("start")
    rod.support_basis("end", Q).pin("end", [2]).fix_rotation("end", [1])
    rod.prescribe_displacement("end", [0.05, 0.0, 0.0], components=[0])
    rod.add_force("end", [0.3, 1.5, -1.0]).add_moment("end", [0.4, 0.0, 0.2])
    res_p = rod.solve(2)
    assert res_s.converged and res_p.converged
    assert _same(res_s, res_p) < 1e-10
    # and the constraints hold along the skew axes
    e = res_s.steps[-1].r[rod.node("end")] - [1.0, 0.0, 0.0]
    assert abs(e @ Q[:, 2]) < 1e-12 and abs(e @ Q[:, 0] - 0.05) < 1e-12
    # the transposed matrix (rows taken as columns) is a different problem
    if np.abs(Q - Q.T).max() > 0.1:
        res_t = load_scene(_skew_scene(Q.tolist())).solve()
        assert _same(res_s, res_t) > 1e-3


def test_identity_axes_are_the_spatial_axes():
    d = _skew_scene(np.eye(3).tolist())
    plain = copy.deepcopy(d)
    for sup in plain["support"]:
        sup.pop("axes", None)
    assert _same(load_scene(d).solve(), load_scene(plain).solve()) < 1e-10


# ---------------------------------------------------------------------------
# malformed axes: key, value and what is allowed
# ---------------------------------------------------------------------------
EXPECTED = ("expected 3 axes [[x, y, z], [x, y, z], [x, y, z]] of finite numbers, not zero "
            f"(normalized on load), mutually orthogonal (|cos| <= {AXES_TOL:g}) and "
            "right-handed (axes[0] x axes[1] = axes[2]): the rows of a rotation matrix")
OK = [[0.0, 1.0, 1.0], [0.0, 1.0, -1.0], [-1.0, 0.0, 0.0]]       # right-handed, unnormalized


def _roller(axes):
    return {
        "rod": {"geometry": {"type": "straight", "length": 1.0}, "n_elements": 2},
        "section": dict(SEC),
        "support": [{"where": "start", "kind": "clamp"},
                    {"where": "end", "kind": "pin", "components": [0], "axes": axes}],
        "load": [{"kind": "force", "where": "end", "vector": [0.0, 0.0, -1.0]}]}


def problem(d):
    with pytest.raises(SceneError) as info:
        load_scene(d)
    assert isinstance(info.value, ValueError) and len(info.value.problems) == 1
    return str(info.value)


@pytest.mark.parametrize("value, shown, note", [
    ([[1, 0, 0], [0, 1, 0]], "[[1, 0, 0], [0, 1, 0]]", "got 2 items, not 3 axes"),
    ([1, 0, 0, 0, 1, 0, 0, 0, 1], "[1, 0, 0, 0, 1, 0, 0, 0, ...]", "got 9 items, not 3 axes"),
    ([[1, 0], [0, 1], [0, 0]], "[[1, 0], [0, 1], [0, 0]]",
     "axes[0] = [1, 0] is not a non-zero [x, y, z]"),
    ("x", '"x"', None),
    ([[1, 0, 0], [0, math.nan, 0], [0, 0, 1]], "[[1, 0, 0], [0, nan, 0], [0, 0, 1]]",
     "axes[1] = [0, nan, 0] is not a non-zero [x, y, z]; NaN and inf are not allowed"),
    ([[1, 0, 0], [0, 1, 0], [0, 0, -math.inf]], "[[1, 0, 0], [0, 1, 0], [0, 0, -inf]]",
     "axes[2] = [0, 0, -inf] is not a non-zero [x, y, z]; NaN and inf are not allowed"),
    ([[0, 0, 0], [0, 1, 0], [0, 0, 1]], "[[0, 0, 0], [0, 1, 0], [0, 0, 1]]",
     "axes[0] = [0, 0, 0] is not a non-zero [x, y, z]"),
    ([[1, 0, 0], [0.001, 1, 0], [0, 0, 1]], "[[1, 0, 0], [0.001, 1, 0], [0, 0, 1]]",
     "axes[0] and axes[1] are not orthogonal: cos = 0.001, tolerance 1e-06"),
    ([[1, 0, 0], [0, 1, 0], [1, 0, 1]], "[[1, 0, 0], [0, 1, 0], [1, 0, 1]]",
     "axes[0] and axes[2] are not orthogonal: cos = 0.707, tolerance 1e-06"),
    ([[1, 0, 0], [0, 1, 0], [0, 0, -1]], "[[1, 0, 0], [0, 1, 0], [0, 0, -1]]",
     "left-handed: axes[0] x axes[1] . axes[2] = -1; reverse one axis"),
    ([[1, 0, 0], [0, 0, 1], [0, 1, 0]], "[[1, 0, 0], [0, 0, 1], [0, 1, 0]]",
     "left-handed"),
    ([[True, 0, 0], [0, 1, 0], [0, 0, 1]], "[[true, 0, 0], [0, 1, 0], [0, 0, 1]]",
     "axes[0] = [true, 0, 0] is not a non-zero [x, y, z]"),
])
def test_malformed_axes_name_the_key_the_value_and_what_is_allowed(value, shown, note):
    msg = problem(_roller(value))
    assert msg.startswith(f"support[1].axes = {shown}: {EXPECTED}"), msg
    if note is not None:
        assert f"({note}" in msg, msg


def test_axes_are_checked_where_they_mean_something():
    # not on a clamp or a prescribed rotation: their components are all held
    d = _roller(OK)
    d["support"][0]["axes"] = OK
    msg = problem(d)
    assert msg.startswith('support[0].axes is not a known key here (only for kind = "pin" or '
                          '"fix_rotation" or "prescribe_displacement")')
    # the supports of one node share one basis
    d = _roller(OK)
    d["support"].append({"where": "end", "kind": "fix_rotation", "components": [0]})
    msg = problem(d)
    assert msg.startswith('support[2] (fix_rotation at "end") has no axes (x, y, z) but '
                          'support[1] (pin at "end") at the same node')
    assert msg.endswith("share one basis; give them the same axes (or none)")
    d["support"][2]["axes"] = [[0, 1, 1], [0, -1, 1], [1, 0, 0]]      # another basis
    assert "has axes = [[0.0, 0.707106781, 0.707106781]" in problem(d)
    d["support"][2]["axes"] = [[0, 2, 2], [0, 3, -3], [-1, 0, 0]]     # the same, scaled
    load_scene(d)
    # within the tolerance the axes are accepted and made exactly orthonormal
    tilt = 0.5 * AXES_TOL
    scene = load_scene(_roller([[1, tilt, 0], [0, 1, 0], [0, 0, 1]]))
    A = np.array(scene.data["support"][1]["axes"])
    assert np.abs(A @ A.T - np.eye(3)).max() < 1e-15 and abs(np.linalg.det(A) - 1) < 1e-15
    assert np.abs(A[0] - [1, tilt, 0]).max() < AXES_TOL
    assert problem(_roller([[1, 3 * AXES_TOL, 0], [0, 1, 0], [0, 0, 1]])).startswith(
        "support[1].axes = ")


ROWS = st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                          st.integers(-3, 3), st.booleans(), st.text(max_size=2)),
                min_size=0, max_size=4)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(st.lists(ROWS, min_size=0, max_size=4),
                 st.builds(lambda v, s: (expm(np.array(v)).T * np.array(s)[:, None]).tolist(),
                           st.lists(st.floats(-4, 4), min_size=3, max_size=3),
                           st.lists(st.floats(1e-3, 1e3), min_size=3, max_size=3))))
@pytest.mark.slow
def test_any_axes_value_gives_a_basis_or_a_message_naming_the_key(axes):
    """Random values: a SceneError naming support[1].axes, or a rotation
    whose columns are the normalized axes (and the rod holds it)."""
    try:
        scene = load_scene(_roller(axes))
    except SceneError as err:
        assert str(err).startswith("support[1].axes = "), str(err)
        assert EXPECTED in str(err)
        return
    A = np.array(scene.data["support"][1]["axes"])
    given_ = np.array(axes, dtype=float)
    given_ /= np.abs(given_).max(axis=1, keepdims=True)      # no overflow in the norm
    given_ /= np.linalg.norm(given_, axis=1, keepdims=True)
    assert np.abs(A - given_).max() < 10 * AXES_TOL
    assert np.abs(A @ A.T - np.eye(3)).max() < 1e-12 and np.linalg.det(A) > 0
    rod = scene.build()
    assert np.array_equal(rod.supports[rod.node("end")].basis, A.T)
