"""Scenes (TOML) and the ``skfem-rod`` command: the example scenes load,
solve and write what they ask for; each class of malformed scene gives a
message naming the key, the value and what is allowed; random malformed
scenes raise only ValueError (exit code 2 through the CLI, no file
written); exit codes 0 / 2 / 3."""
import copy
import json
import math
import pathlib
import re
import tempfile
from dataclasses import fields

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings, strategies as st

from skfem_rod import Rod
from skfem_rod import __main__ as cli
from skfem_rod import scene as scene_mod
from skfem_rod.contact import ContactOptions
from skfem_rod.scene import SceneError, load_scene
from skfem_rod.solver import SolverOptions

try:
    import tomllib
except ModuleNotFoundError:                      # Python 3.10
    import tomli as tomllib

ROOT = pathlib.Path(__file__).resolve().parents[1]
#: every key of the [solver] table, of any method
SOLVER_KEYS = set(scene_mod.SOLVER_COMMON).union(*scene_mod.SOLVER_METHODS.values())
SCENES = ROOT / "scenes"
SMALL = {  # (n_elements, n_steps) at which each example still converges quickly
    "rollup": (8, 2), "cantilever": (8, 2), "bend45": (8, 12), "hairpin_contact": (12, 4)}


def read(name):
    with open(SCENES / f"{name}.toml", "rb") as f:
        return tomllib.load(f)


def small(name, out):
    d = read(name)
    d["rod"]["n_elements"], d["solver"]["n_steps"] = SMALL[name]
    d["output"].update(directory=str(out), window_size=[160, 120])
    return d


# a compact valid scene touching every table (mutated by the property tests)
BASE = {
    "title": "base",
    "rod": {"geometry": {"type": "straight", "length": 1.0}, "n_elements": 2},
    "section": {"EA": 100.0, "GA1": 100.0, "GA2": 100.0, "EI1": 1.0, "EI2": 1.0,
                "GJ": 1.0, "radius": 0.02},
    "support": [{"where": "start", "kind": "pin"},
                {"where": "start", "kind": "fix_rotation", "components": [0, 1, 2]}],
    "load": [{"kind": "force", "where": "end", "vector": [0.0, 0.1, 0.0]},
             {"kind": "distributed_torque", "vector": [0.0, 0.0, 0.1]}],
    "contact": {"enabled": False, "tolerance": 1e-3},
    "solver": {"n_steps": 1, "max_iterations": 20},
    "output": {"json": True, "vtu": False, "render": False},
}


# valid variants: the other shapes, sections, supports and loads, contact on
VARIANTS = [
    {"rod": {"geometry": {"type": "helix", "radius": 0.1, "pitch": 0.05, "turns": 1.5},
             "n_elements": 3, "n_quad": 3},
     "section": {"E": 1e7, "nu": 0.3, "radius": 0.01, "shear_coefficient": 0.9},
     "support": [{"where": "start", "kind": "clamp"},
                 {"where": "end", "kind": "prescribe_rotation", "rotation_vector": [0, 0, 1.0]},
                 {"where": "end", "kind": "prescribe_displacement",
                  "displacement": [0, 0, 0.01], "components": [2]}],
     "load": [{"kind": "moment", "where": "end", "vector": [0, 0.1, 0], "follower": True},
              {"kind": "distributed_force", "vector": [0, 0, -0.1]}],
     "contact": {"enabled": True, "penalty": 1e-3, "exclusion": 0.05, "n_slave": 3,
                 "margin": 0.01, "max_uzawa": 5},
     "solver": {"n_steps": 2, "path": [0, 1, 0.5], "rtol": 1e-8, "grow": 1.5,
                "line_search": False},
     "output": {"render": True, "window_size": [100, 100], "zoom": 1.2, "per_element": 2}},
    {"rod": {"geometry": {"type": "polyline", "points": [[0, 0, 0], [1, 0, 0], [1, 1, 0]],
                          "d1": [[0, 0, 1]] * 3}, "n_elements": 3},
     "section": {"matrix": [[10.0 * (i == j) + 0.5 * (abs(i - j) == 1) for j in range(6)]
                            for i in range(6)], "radius": 0.05},
     "support": [{"where": 0.0, "kind": "pin"}, {"where": "start", "kind": "fix_rotation"}],
     "load": [{"kind": "force", "where": "end", "vector": [0, 0.1, 0]}]},
    {"rod": {"geometry": {"type": "arc", "radius": 2.0, "angle": 1.0, "tangent": [0, 1, 0],
                          "toward": [1, 0, 0]}, "n_elements": 2},
     "section": {"type": "stiffness", "EA": 1.0, "GA1": 1.0, "GA2": 1.0, "EI1": 1.0,
                 "EI2": 1.0, "GJ": 1.0},
     "support": [{"where": "start", "kind": "clamp"}],
     "load": [{"kind": "distributed_torque", "vector": [0, 0.1, 0]}]},
]


def with_(d, path, value):
    """Copy of ``d`` with the item at ``path`` (keys/indices) replaced, or
    deleted if ``value`` is DELETE."""
    d = copy.deepcopy(d)
    c = d
    for k in path[:-1]:
        c = c[k]
    if value is DELETE:
        del c[path[-1]]
    else:
        c[path[-1]] = value
    return d


DELETE = object()


def problem(d):
    with pytest.raises(SceneError) as info:
        load_scene(d)
    assert isinstance(info.value, ValueError)
    return str(info.value)


# ---------------------------------------------------------------------------
# example scenes
# ---------------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(SMALL))
def test_example_scene_loads_runs_and_writes_what_it_asks(name, tmp_path):
    scene = load_scene(SCENES / f"{name}.toml")             # the file as shipped
    assert scene.name == name and scene.output["json"] and scene.output["vtu"]
    scene = load_scene(small(name, tmp_path), name=name)
    result = scene.run()
    assert result.converged, result.message
    n = len(result.steps)
    assert len(list(tmp_path.glob(f"{name}_*.vtu"))) == n
    assert (tmp_path / f"{name}.pvd").exists() and (tmp_path / f"{name}.png").exists()
    assert not list(tmp_path.glob(".*.tmp"))                 # no temporary left over
    data = json.loads((tmp_path / f"{name}.json").read_text())
    assert data["converged"] and data["message"] == result.message
    assert [s["load_factor"] for s in data["steps"]] == list(result.load_factors)
    assert data["input"]["rod"]["n_elements"] == SMALL[name][0]
    np.testing.assert_allclose(data["end_state"]["end"], result.nodes()[1][-1])
    assert set(data["files"]) == {p.name for p in tmp_path.iterdir()}


@pytest.mark.slow
def test_bend45_scene_reproduces_the_verified_tip():
    """docs/verification.md, 45-degree bend, 8 elements, P = 600."""
    result = load_scene(SCENES / "bend45.toml").solve()
    assert result.converged
    tip = result.nodes()[1][-1]
    np.testing.assert_allclose(tip, [15.68479966, 47.15043872, 53.47485879], atol=2e-8)


@pytest.mark.slow
def test_rollup_scene_closes_the_circle_and_hairpin_touches(tmp_path):
    roll = load_scene(small("rollup", tmp_path), name="rollup").solve()
    assert np.linalg.norm(roll.nodes()[1][-1]) < 1e-4        # tip back at the clamp
    hp = load_scene(small("hairpin_contact", tmp_path)).solve()
    c = hp.steps[-1].contact
    assert hp.converged and c.force.size > 0 and c.penetration <= 1e-3 * 0.02
    assert hp.steps[0].contact.force.size == 0


def test_no_output_table_writes_nothing_and_out_writes_the_summary(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    d = with_(BASE, ["output"], DELETE)
    scene = load_scene(d)
    scene.run()
    assert list(tmp_path.iterdir()) == []
    scene.run(out=tmp_path / "o")
    assert sorted(p.name for p in (tmp_path / "o").iterdir()) == ["scene.json"]


def test_build_gives_a_fresh_rod_and_load_unload_path_writes_a_series(tmp_path):
    d = with_(BASE, ["solver", "path"], [0, 1, 0])
    d["solver"]["n_steps"] = 2
    d["output"].update(vtu=True, directory=str(tmp_path), basename="lu")
    scene = load_scene(d)
    a, b = scene.build(), scene.build()
    assert isinstance(a, Rod) and a is not b
    result = scene.run()
    assert result.converged and result.load_factors[-1] == 0.0
    # the series time is the pseudo-time (the load factor goes up and down)
    assert len(list(tmp_path.glob("lu_*.vtu"))) == len(result.steps)
    times = re.findall(r'timestep="([^"]+)"', (tmp_path / "lu.pvd").read_text())
    assert np.all(np.diff([float(t) for t in times]) > 0)


def test_schema_covers_the_solver_and_contact_options_and_the_docs():
    assert {f.name for f in fields(SolverOptions)} <= set(scene_mod.SOLVER_METHODS["newton"])
    assert {f.name for f in fields(ContactOptions)} <= set(scene_mod.CONTACT)
    docs = (ROOT / "docs" / "scenes.md").read_text()
    keys = set(scene_mod.TOP) | set(scene_mod.ROD) | set(SOLVER_KEYS) \
        | set(scene_mod.CONTACT) | set(scene_mod.OUTPUT) \
        | set(scene_mod.SUPPORT_COMMON) | set(scene_mod.LOAD_COMMON)
    for group in (scene_mod.GEOMETRY, scene_mod.SECTIONS, scene_mod.SUPPORTS, scene_mod.LOADS):
        keys |= set(group)
        for spec in group.values():
            keys |= set(spec)
    missing = sorted(k for k in keys if f"`{k}`" not in docs and f'`"{k}"`' not in docs)
    assert not missing, f"keys not documented in docs/scenes.md: {missing}"


# ---------------------------------------------------------------------------
# one test per class of malformed scene
# ---------------------------------------------------------------------------
def test_missing_key():
    msg = problem(with_(BASE, ["rod", "n_elements"], DELETE))
    assert msg.startswith("rod.n_elements is missing: expected an integer in [1, 100000]")
    msg = problem(with_(BASE, ["support", 0, "where"], DELETE))
    assert msg.startswith("support[0].where is missing: expected")
    assert "rod is missing" in problem(with_(BASE, ["rod"], DELETE))


def test_wrong_type():
    msg = problem(with_(BASE, ["rod", "n_elements"], "four"))
    assert msg == 'rod.n_elements = "four": expected an integer in [1, 100000]'
    msg = problem(with_(BASE, ["load", 0, "vector"], [1.0, 2.0]))
    assert msg == "load[0].vector = [1.0, 2.0]: expected an array of 3 finite numbers [x, y, z]"
    msg = problem(with_(BASE, ["load", 0, "follower"], 1))
    assert msg == "load[0].follower = 1: expected true or false"
    assert "expected a table" in problem(with_(BASE, ["solver"], 3))
    assert "got a single table" in problem(with_(BASE, ["support"], BASE["support"][0]))
    assert problem([1, 2]).startswith("a scene must be a table")


def test_out_of_range():
    msg = problem(with_(BASE, ["section", "EA"], -1.0))
    assert msg == "section.EA = -1.0: expected a finite number > 0"
    d = with_(BASE, ["section"], {"E": 1e7, "nu": 0.5, "radius": 0.01})
    assert problem(d) == "section.nu = 0.5: expected a number in (-1, 0.5)"
    msg = problem(with_(BASE, ["support", 0, "where"], 2.5))
    assert msg == "support[0].where = 2.5: expected an arclength in [0, 1] (the rod length)"
    msg = problem(with_(BASE, ["load", 0, "where"], 0.3))   # not a node
    assert msg.startswith("load[0].where: where=0.3 is not a node arclength")
    msg = problem(with_(BASE, ["solver", "path"], [1, 0]))
    assert msg.startswith("solver.path = [1, 0]: expected an array of >= 2 finite load")
    assert msg.endswith("(it must start at 0)")


def test_unknown_key_with_suggestion():
    msg = problem(with_(BASE, ["solver", "max_iteration"], 3))
    assert msg.startswith('solver.max_iteration is not a known key; did you mean '
                          '"max_iterations"? Allowed in [solver] (method = "newton"): '
                          'n_steps, path, method, rtol')
    # a key of another solve method: say which methods have it
    msg = problem(with_(BASE, ["solver", "barrier_width"], 0.05))
    assert 'solver.barrier_width is not a known key here (only for method = "barrier")' in msg
    msg = problem(with_(BASE, ["solver", "max_steps"], 10))
    assert 'solver.max_steps is not a known key here (only for method = "arclength")' in msg
    msg = problem(with_(BASE, ["supports"], []))
    assert msg.startswith('supports is not a known key; did you mean "support"?')
    # a key of another kind of support: say which kinds have it
    msg = problem(with_(BASE, ["support", 0, "rotation_vector"], [0, 0, 1]))
    assert 'support[0].rotation_vector is not a known key here (only for kind = ' \
           '"prescribe_rotation")' in msg
    assert 'Allowed in [[support]] (kind = "pin"): kind, where, components' in msg
    msg = problem(with_(BASE, ["support", 0, "kind"], "clmap"))
    assert msg.endswith('(did you mean "clamp"?)')
    # several problems are reported together
    d = with_(with_(BASE, ["rod", "n_elements"], DELETE), ["output", "camera"], "top")
    d["rod"]["n_element"] = 2
    err = pytest.raises(SceneError, load_scene, d).value
    assert len(err.problems) == 3 and str(err).startswith("3 problems in the scene:")


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_nan_and_inf(bad):
    msg = problem(with_(BASE, ["rod", "geometry", "length"], bad))
    text = {1: "inf", -1: "-inf"}.get(np.sign(bad), "nan") if not math.isnan(bad) else "nan"
    assert msg == (f"rod.geometry.length = {text}: expected a finite number > 0 "
                   "(NaN and inf are not allowed)")
    msg = problem(with_(BASE, ["load", 1, "vector"], [0.0, bad, 0.0]))
    assert msg.startswith(f"load[1].vector = [0.0, {text}, 0.0]: expected an array of 3 "
                          "finite numbers")


def test_nan_in_a_toml_file(tmp_path):
    text = (SCENES / "rollup.toml").read_text().replace("length = 1.0", "length = nan")
    (tmp_path / "s.toml").write_text(text)
    assert problem_file(tmp_path / "s.toml").startswith("rod.geometry.length = nan")


def problem_file(path):
    with pytest.raises(ValueError) as info:
        load_scene(path)
    return str(info.value)


def test_inconsistent_boundary_conditions():
    # no support: the Rod's own rigid-body check
    msg = problem(with_(BASE, ["support"], []))
    assert msg.startswith("support: supports leave rigid-body mode(s) unconstrained: "
                          "translation along")
    # a pin alone leaves the rotations free
    msg = problem(with_(BASE, ["support"], BASE["support"][:1]))
    assert "rotation about axis" in msg and "Add a support" in msg
    # a prescribed motion on a component another support holds
    d = copy.deepcopy(BASE)
    d["support"].append({"where": "start", "kind": "prescribe_displacement",
                         "displacement": [0.1, 0.0, 0.0], "components": [0]})
    msg = problem(d)
    assert msg.startswith("support[2]: prescribe_displacement('start') conflicts with "
                          "pin('start') at node 0: both hold the position component 0")
    # contact needs a radius
    d = with_(with_(BASE, ["section", "radius"], DELETE), ["contact", "enabled"], True)
    assert problem(d).startswith("contact.radius is missing")
    # a straight rod whose d1 is its tangent has no frame
    d = with_(BASE, ["rod", "geometry", "d1"], [2.0, 0.0, 0.0])
    assert problem(d).startswith("rod.geometry.d1 = [2.0, 0.0, 0.0]: expected a vector "
                                 "not parallel to direction")


def test_invalid_toml_and_missing_file(tmp_path):
    (tmp_path / "bad.toml").write_text("[rod\nn_elements = 2\n")
    assert problem_file(tmp_path / "bad.toml").startswith("invalid TOML:")
    with pytest.raises(FileNotFoundError):
        load_scene(tmp_path / "none.toml")


# ---------------------------------------------------------------------------
# property: random malformed scenes give ValueError only, and nothing written
# ---------------------------------------------------------------------------
WORDS = ["start", "end", "clamp", "pin", "force", "moment", "straight", "arc", "helix",
         "polyline", "circle", "matrix", "stiffness", "iso", "", "x"]
KEYS = sorted(set(scene_mod.TOP) | set(scene_mod.ROD) | set(SOLVER_KEYS)
              | set(scene_mod.OUTPUT) | set(scene_mod.CONTACT)
              | {"type", "kind", "where", "vector", "length", "radius", "points",
                 "components", "E", "nu", "EA", "matrix"})
SCALARS = st.one_of(
    st.booleans(), st.integers(-3, 30), st.sampled_from([10**12, -2**63, 2**63 - 1]),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=6),
    st.sampled_from(WORDS))
VALUES = st.recursive(
    SCALARS, lambda inner: st.lists(inner, max_size=7)
    | st.dictionaries(st.sampled_from(KEYS) | st.text(max_size=5), inner, max_size=4),
    max_leaves=24)


def _slots(d, path=()):
    """Every (path) in ``d`` that can be replaced, deleted or added to."""
    yield path
    items = d.items() if isinstance(d, dict) else enumerate(d) if isinstance(d, list) else ()
    for k, v in items:
        yield from _slots(v, path + (k,))


@st.composite
def malformed(draw, values=VALUES):
    """A valid scene with 1 to 3 random replacements, deletions, additions."""
    d = copy.deepcopy(draw(st.sampled_from([BASE] + VARIANTS)))
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(list(_slots(d))))
        op = draw(st.sampled_from(["replace", "delete", "add"]))
        target = d
        for k in path[:-1]:
            target = target[k]
        if op == "add" or not path:
            node = target[path[-1]] if path else d
            if isinstance(node, dict):
                node[draw(st.sampled_from(KEYS) | st.text(max_size=5))] = draw(values)
            elif isinstance(node, list):
                node.append(draw(values))
        elif op == "delete":
            del target[path[-1]]
        else:
            target[path[-1]] = draw(values)
    return d


NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True), st.integers(-10, 10),
    st.sampled_from([0, 1e-300, 1e300, -1e300, 5e-324, 1e154, 2**63 - 1, -2**63]))


@st.composite
def renumbered(draw):
    """A valid scene with 1 to 3 of its numbers replaced by any number
    (these reach the build: extreme but finite values, overflow)."""
    d = copy.deepcopy(draw(st.sampled_from([BASE] + VARIANTS)))
    for _ in range(draw(st.integers(1, 3))):
        slots = [p for p in _slots(d) if p and type(_at(d, p)) in (int, float)]
        path = draw(st.sampled_from(slots))
        _at(d, path[:-1])[path[-1]] = draw(NUMBERS)
    return d


def _at(d, path):
    for k in path:
        d = d[k]
    return d


def _toml(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v)
                else repr(v))
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_toml(x) for x in v) + "]"
    return "{" + ", ".join(f"{json.dumps(k)} = {_toml(x)}" for k, x in v.items()) + "}"


def to_toml(d):
    return "\n".join(f"{json.dumps(k)} = {_toml(v)}" for k, v in d.items()) + "\n"


def test_toml_writer_round_trips_the_base_scene():
    assert tomllib.loads(to_toml(BASE)) == BASE


def test_variants_are_valid():
    for d in VARIANTS:
        load_scene(d)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")     # degenerate shapes: NaN frames
@pytest.mark.filterwarnings("ignore:An ill-conditioned matrix")
@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(malformed(VALUES | st.none()), renumbered(),
                 st.dictionaries(st.sampled_from(KEYS) | st.text(max_size=4),
                                 VALUES | st.none(), max_size=6),
                 VALUES.filter(lambda v: not isinstance(v, str))))    # a str is a path
@pytest.mark.slow
def test_load_scene_raises_only_value_error(d):
    try:
        scene = load_scene(d)
    except ValueError as err:
        assert str(err)                                   # a message, always
        return
    assert scene.data["rod"]["n_elements"] >= 1


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@pytest.mark.filterwarnings("ignore:An ill-conditioned matrix")
@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(malformed() | renumbered())
def test_cli_exits_2_on_malformed_scenes_and_writes_nothing(d):
    try:
        load_scene(d)
        event("valid")
        return                                            # valid: nothing to check here
    except ValueError:
        event("invalid")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = pathlib.Path(tmp)
        path = tmp / "scene.toml"
        path.write_text(to_toml(d), encoding="utf-8", errors="surrogatepass")
        out = tmp / "out"
        assert cli.main(["run", str(path), "--out", str(out), "--quiet"]) == 2
        assert not out.exists()


# ---------------------------------------------------------------------------
# the command line
# ---------------------------------------------------------------------------
def write_scene(tmp_path, d, name="s"):
    path = tmp_path / f"{name}.toml"
    path.write_text(to_toml(d))
    return path


def test_cli_run_success_writes_and_reports(tmp_path, capsys):
    path = write_scene(tmp_path, BASE)
    assert cli.main(["run", str(path), "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "converged" in out and "s.json" in out and "step " not in out   # not a tty
    assert json.loads((tmp_path / "o" / "s.json").read_text())["converged"]
    assert cli.main(["run", str(path), "--out", str(tmp_path / "q"), "--quiet"]) == 0
    assert capsys.readouterr() == ("", "")
    assert cli.main(["check", str(path)]) == 0


@pytest.mark.slow
def test_cli_progress_lines_only_on_a_terminal(tmp_path, capsys, monkeypatch):
    d = with_(read("hairpin_contact"), ["output"], DELETE)
    d["rod"]["n_elements"], d["solver"]["n_steps"] = SMALL["hairpin_contact"]
    path = write_scene(tmp_path, d)
    monkeypatch.setattr(cli.sys.stdout, "isatty", lambda: True)
    assert cli.main(["run", str(path)]) == 0
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("step")]
    assert len(lines) == SMALL["hairpin_contact"][1] + 1
    assert re.fullmatch(r"step +4 +load factor 1 +Newton +\d+ +Uzawa +\d+ +contacts +[1-9]\d*",
                        lines[-1])
    assert cli.main(["run", str(path), "--quiet"]) == 0
    assert capsys.readouterr().out == ""
    assert not (tmp_path / "output").exists()


def test_cli_bad_input_exits_2_without_traceback(tmp_path, capsys):
    path = write_scene(tmp_path, with_(BASE, ["rod", "n_elements"], 0))
    assert cli.main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "rod.n_elements = 0: expected an integer in [1, 100000]" in err
    assert "Traceback" not in err and not (tmp_path / "o").exists()
    assert cli.main(["run", str(tmp_path / "missing.toml")]) == 2
    assert "cannot read" in capsys.readouterr().err
    assert cli.main(["check", str(path)]) == 2
    assert cli.main(["frobnicate"]) == 2                   # argparse usage error
    assert cli.main([]) == 2


def test_cli_solve_failure_exits_3_and_writes_the_converged_steps(tmp_path, capsys):
    d = copy.deepcopy(BASE)
    d["load"][0]["vector"] = [0.0, 5.0, 0.0]
    d["solver"].update(max_iterations=1, min_step=0.5)
    d["output"]["vtu"] = True
    path = write_scene(tmp_path, d)
    assert cli.main(["run", str(path), "--out", str(tmp_path / "o")]) == 3
    err = capsys.readouterr().err
    assert "the solve stopped: stopped at load factor 0" in err
    assert "min_step=0.5" in err and "wrote the 1 converged step(s)" in err
    data = json.loads((tmp_path / "o" / "s.json").read_text())
    assert not data["converged"] and len(data["steps"]) == 1
    assert data["end_state"]["load_factor"] == 0.0
    assert (tmp_path / "o" / "s.pvd").exists()


def test_cli_help(capsys):
    assert cli.main(["--help"]) == 0
    out = capsys.readouterr().out
    assert "run" in out and "demo" in out and "exit codes" in out
    for cmd in ("run", "check", "demo"):
        assert cli.main([cmd, "--help"]) == 0
        assert f"usage: skfem-rod {cmd}" in capsys.readouterr().out


def test_cli_demo(tmp_path, capsys, monkeypatch):
    assert "rollup" in (cli.main(["demo"]), capsys.readouterr().out)[1]
    assert cli.main(["demo", "rolup"]) == 2
    assert "did you mean 'rollup'?" in capsys.readouterr().err
    # the plumbing, on a quick stand-in demo folder
    (tmp_path / "quick.py").write_text(
        "def main(out='x'):\n    print('ran', out)\n    return {'converged': out != 'fail'}\n")
    monkeypatch.setattr(cli, "demos_dir", lambda: tmp_path)
    assert cli.main(["demo", "quick", "--out", "here"]) == 0
    assert "ran here" in capsys.readouterr().out
    assert cli.main(["demo", "quick", "--out", "fail"]) == 3
    monkeypatch.setattr(cli, "demos_dir", lambda: tmp_path / "absent")
    assert cli.main(["demo", "quick"]) == 2
    assert "examples are missing" in capsys.readouterr().err


# ---------------------------------------------------------------------------
# [solver] method = "barrier"
# ---------------------------------------------------------------------------
@pytest.mark.filterwarnings("ignore::skfem_rod.minimize.BarrierResolution")
def test_a_barrier_scene_is_the_rods_barrier_solve(tmp_path, capsys):
    """A scene with method = "barrier" solves as Rod.solve(method="barrier")
    with its options (the barrier's rtol, not SolverOptions'), and the CLI
    writes its steps with their contact."""
    d = with_(read("hairpin_contact"), ["output"], {"json": True})
    d["rod"]["n_elements"] = SMALL["hairpin_contact"][0]
    d["solver"] = {"n_steps": 4, "method": "barrier", "rtol": 1e-10, "barrier_width": 0.05}
    path = write_scene(tmp_path, d)
    got = load_scene(path).solve()
    assert got.converged, got.message
    rod = load_scene(path).build()
    want = rod.solve(4, method="barrier", rtol=1e-10, barrier_width=0.05)
    assert [s.iterations for s in got.steps] == [s.iterations for s in want.steps]
    assert np.allclose(got.steps[-1].r, want.steps[-1].r, rtol=0, atol=1e-14)
    assert got.steps[-1].contact.force.size > 0
    assert cli.main(["run", str(path), "--out", str(tmp_path / "o")]) == 0
    data = json.loads((tmp_path / "o" / "s.json").read_text())
    assert data["converged"] and data["input"]["solver"]["method"] == "barrier"
    assert data["steps"][-1]["active_contacts"] == got.steps[-1].contact.force.size


def test_a_barrier_scene_needs_contact_dead_forces_and_its_own_keys(tmp_path, capsys):
    base = with_(BASE, ["solver"], {"method": "barrier"})
    base["load"].pop()                                   # the distributed torque
    msg = problem(base)
    assert 'solver.method = "barrier" is a contact solve: add a [contact] table' in msg
    on = with_(base, ["contact"], {"enabled": True, "gamma_R": 0.1})
    assert 'contact.gamma_R = 0.1 with contact.rotational_slip = "twist": solver.method = ' \
        '"barrier" has the rotational law on the pivot' in problem(on)
    on["contact"]["rotational_slip"] = "pivot"       # the barrier's rotational law
    assert load_scene(on).data["contact"]["rotational_slip"] == "pivot"
    on["contact"]["gamma_R"] = 0.0
    on["load"].append({"kind": "moment", "where": "end", "vector": [0, 0, 1.0]})
    assert 'load[1] is a moment: solver.method = "barrier" minimizes an energy' in problem(on)
    on["load"][1] = {"kind": "force", "where": "end", "vector": [0, 0, 1.0], "follower": True}
    assert "load[1] is a follower force" in problem(on)
    on["load"].pop()
    load_scene_data = scene_mod.validate_data(on)             # now valid
    assert load_scene_data["solver"]["predictor"] == "secant"
    assert load_scene_data["solver"]["rtol"] == 1e-8         # EnergyOptions' default
    assert problem(with_(on, ["solver", "barrier_width"], -1.0)).startswith(
        "solver.barrier_width = -1.0: expected a finite number > 0")
    assert 'only for method = "newton" or "arclength"' in problem(
        with_(on, ["solver", "line_search"], False))
    path = write_scene(tmp_path, with_(on, ["contact", "enabled"], False))
    assert cli.main(["check", str(path)]) == 2
    assert 'is a contact solve' in capsys.readouterr().err
