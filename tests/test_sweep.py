"""Parameter sweeps (:mod:`skfem_rod.sweeps`, ``skfem-rod sweep``): the
[sweep] table is validated like the keys it sweeps; a 2 x 3 grid on a
LocalCluster of 2 workers gives one dataset whose values equal single
runs; a sweep killed half-way (SIGTERM) resumes without recomputing the
finished points; a failing point is recorded with its message and steps;
a point whose worker dies is re-run."""
import copy
import os
import pathlib
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from skfem_rod import sweeps
from skfem_rod.scene import SceneError, load_scene

try:
    import tomllib
except ModuleNotFoundError:                      # Python 3.10
    import tomli as tomllib

pytest.importorskip("dask.distributed")
pytest.importorskip("xarray")
pytest.importorskip("h5netcdf")

ROOT = pathlib.Path(__file__).resolve().parents[1]

# a small cantilever (4 elements, PL^2/EI up to 1.9): about a second a point
SCENE = """
title = "small cantilever"
[rod]
n_elements = 4
[rod.geometry]
type = "straight"
length = 1.0
[section]
E = 1e7
nu = 0.3
radius = 0.01
[[support]]
where = "start"
kind = "clamp"
[[load]]
kind = "force"
where = "end"
vector = [0.0, 0.0, -0.1]
[solver]
n_steps = 2
min_step = 0.2
"""
GRID = """
[sweep]
"section.E" = [1e7, 2e7]
"load[0].vector[2]" = [-0.05, -0.1, -0.15]
"""
E_VALUES, P_VALUES = [1e7, 2e7], [-0.05, -0.1, -0.15]


def write(tmp_path, text, name="cant"):
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def cli(*args, cwd):
    """``skfem-rod ARGS`` in a subprocess running this checkout."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT)] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    return [sys.executable, "-m", "skfem_rod", *args], dict(cwd=cwd, env=env)


def run_cli(*args, cwd):
    cmd, kw = cli(*args, cwd=cwd)
    return subprocess.run(cmd, capture_output=True, text=True, timeout=600, **kw)


def single(E, P):
    """The point (E, P) solved alone, in this process."""
    d = tomllib.loads(SCENE)
    d["section"]["E"] = E
    d["load"][0]["vector"][2] = P
    return load_scene(d).solve()


# ---------------------------------------------------------------------------
# the [sweep] table (no cluster)
# ---------------------------------------------------------------------------
def test_swept_values_are_validated_like_their_keys():
    base = tomllib.loads(SCENE)

    def problems(table):
        with pytest.raises(SceneError) as err:
            load_scene(dict(copy.deepcopy(base), sweep=table))
        return err.value.problems

    # the scene's own message for the value, under the sweep key and index
    (p,) = problems({"section.nu": [0.3, 0.7]})
    assert p.startswith('sweep."section.nu"[1]: section.nu = 0.7: expected a number in (-1, 0.5)')
    (p,) = problems({"section.EE": [1.0]})
    assert 'section.EE is not a known key; did you mean "E"?' in p
    (p,) = problems({"contact.gamma_T": [0.1]})
    assert "the scene has no contact.gamma_T to sweep" in p
    (p,) = problems({"load[3].vector[0]": [1.0]})
    assert 'sweep."load[3].vector[0]"' in p
    (p,) = problems({"mode": "zip", "section.E": [1.0, 2.0], "section.nu": [0.1]})
    assert 'every key needs as many values ("section.E": 2, "section.nu": 1)' in p
    (p,) = problems({"mode": "spiral", "section.E": [1.0]})
    assert p.startswith('sweep.mode = "spiral"')
    (p,) = problems({"section.E": [1.0, 1]})
    assert "must differ" in p
    assert "no parameters" in problems({})[0]
    # a problem of the scene itself is reported once, not once per value
    bad = dict(copy.deepcopy(base), sweep={"section.E": [1.0, 2.0]})
    bad["solver"]["n_steps"] = 0
    with pytest.raises(SceneError) as err:
        load_scene(bad)
    assert len(err.value.problems) == 1 and "solver.n_steps" in err.value.problems[0]


def test_sweep_table_forms_and_point_keys(tmp_path):
    # quoted dotted keys and nested tables are the same sweep; values normalized
    a = load_scene(write(tmp_path, SCENE + GRID, "a"))
    nested = SCENE + '[sweep]\nsection.E = [10000000, 2e7]\n"load[0].vector[2]" = ' \
                     '[-0.05, -0.1, -0.15]\n'
    b = load_scene(write(tmp_path, nested, "b"))
    assert a.data["sweep"] == b.data["sweep"]
    assert b.data["sweep"]["parameters"]["section.E"] == [1e7, 2e7]
    pa, spec = sweeps.sweep_points(a)
    pb, _ = sweeps.sweep_points(b)
    assert spec["mode"] == "grid" and len(pa) == 6
    assert [p.index for p in pa] == [(i, j) for i in range(2) for j in range(3)]
    # the key is the point's scene content: not its title, outputs or formatting
    assert [p.key for p in pa] == [p.key for p in pb]
    c = load_scene(write(tmp_path, SCENE.replace('"small cantilever"', '"other"')
                         + GRID + '[output]\njson = false\n', "c"))
    assert [p.key for p in sweeps.sweep_points(c)[0]] == [p.key for p in pa]
    d = load_scene(write(tmp_path, SCENE.replace("n_steps = 2", "n_steps = 3") + GRID, "d"))
    assert not {p.key for p in sweeps.sweep_points(d)[0]} & {p.key for p in pa}
    # zip: the i-th values together, one point dimension
    pz, spec = sweeps.sweep_points(a, {"section.E": [1e7, 2e7], "section.nu": [0.2, 0.3]},
                                   mode="zip")
    assert [p.values for p in pz] == [{"section.E": 1e7, "section.nu": 0.2},
                                      {"section.E": 2e7, "section.nu": 0.3}]


def test_importing_the_package_imports_no_dask():
    code = ("import sys, skfem_rod; f = skfem_rod.sweep; "
            "import skfem_rod.scene; "
            "print(callable(f), any(m.split('.')[0] in ('dask', 'distributed', 'xarray') "
            "for m in sys.modules))")
    cmd, kw = cli(cwd=ROOT)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, **kw).stdout
    assert out.split() == ["True", "False"]


# ---------------------------------------------------------------------------
# on a cluster
# ---------------------------------------------------------------------------
@pytest.mark.slow
def test_cli_grid_on_two_workers_equals_single_runs(tmp_path):
    write(tmp_path, SCENE + GRID)
    r = run_cli("sweep", "cant.toml", "--out", "out", "--workers", "2", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "6 points, 0 already done, 6 to run" in r.stdout
    assert r.stdout.count(" converged  (") == 6          # a line per finished point
    ds = sweeps.open_sweep(tmp_path / "out")
    assert dict(ds.converged.sizes) == {"section.E": 2, "load[0].vector[2]": 3}
    assert ds.tip_position.dims == ("section.E", "load[0].vector[2]", "step", "xyz")
    assert ds.reaction_force.dims[-2:] == ("support", "xyz")
    assert ds["section.E"].values.tolist() == E_VALUES
    assert ds["load[0].vector[2]"].values.tolist() == P_VALUES
    assert bool(ds.converged.all()) and len(list((tmp_path / "out/points").glob("*.nc"))) == 6
    for E in E_VALUES:
        for P in P_VALUES:
            res = single(E, P)
            pt = ds.sel({"section.E": E, "load[0].vector[2]": P})
            n = len(res.steps)
            assert int(pt.n_steps) == n and str(pt.message.values) == res.message
            tip = np.array([res.nodes(k)[1][-1] for k in range(n)])
            np.testing.assert_allclose(pt.tip_position.values[:n], tip, rtol=1e-9, atol=1e-12)
            np.testing.assert_allclose(pt.energy.values[:n], res.energies, rtol=1e-9)
            np.testing.assert_allclose(pt.load_factor.values[:n], res.load_factors)
            np.testing.assert_array_equal(pt.iterations.values[:n], res.iterations)
            np.testing.assert_allclose(pt.reaction_force.values[n - 1, 0],
                                       res.reaction("start")[0], rtol=1e-9, atol=1e-12)
            assert np.all(np.isnan(pt.energy.values[n:]))         # padding
            assert np.all(pt.iterations.values[n:] == sweeps.MISSING)
    # the start reaction balances the tip load at the end of the path
    last = ds.isel(step=ds.n_steps - 1)
    np.testing.assert_allclose(last.reaction_force.sel(xyz="z", support=0),
                               -ds["load[0].vector[2]"].broadcast_like(ds.n_steps), rtol=1e-8)


@pytest.mark.slow
def test_sweep_killed_half_way_resumes(tmp_path):
    write(tmp_path, SCENE + GRID)
    points = tmp_path / "out" / "points"
    cmd, kw = cli("sweep", "cant.toml", "--out", "out", "--workers", "1", cwd=tmp_path)
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            **kw)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None \
            and len(sweeps.finished_keys(points)) < 2:
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + signal.SIGTERM, (out, err)
    done = {p: (p.stat().st_mtime_ns, p.stat().st_ino) for p in points.glob("*.nc")}
    assert 2 <= len(done) < 6 and not (tmp_path / "out/sweep.nc").exists()

    r = run_cli("sweep", "cant.toml", "--out", "out", "--workers", "1", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert f"6 points, {len(done)} already done, {6 - len(done)} to run" in r.stdout
    assert r.stdout.count(" converged  (") == 6 - len(done)
    for p, stamp in done.items():                      # not recomputed, not rewritten
        assert (p.stat().st_mtime_ns, p.stat().st_ino) == stamp
    assert not [f for f in os.listdir(points) if f.endswith(".tmp")]
    ds = sweeps.open_sweep(tmp_path / "out")
    assert bool(ds.converged.all()) and bool((ds.n_steps >= 3).all())
    assert not (ds.message == "not run").any()
    res = single(2e7, -0.15)
    np.testing.assert_allclose(
        ds.tip_position.sel({"section.E": 2e7, "load[0].vector[2]": -0.15}).values[
            len(res.steps) - 1], res.nodes()[1][-1], rtol=1e-9)


@pytest.fixture(scope="module")
def client():
    from dask.distributed import Client
    with sweeps.local_cluster(2) as cluster, Client(cluster) as c:
        yield c


@pytest.mark.slow
def test_failing_points_are_recorded_and_the_others_complete(tmp_path, client):
    scene = load_scene(write(tmp_path, SCENE))
    # zip: one Newton iteration per step cannot converge (the solve stops at
    # min_step); a support off the nodes fails to build; the middle one is fine
    ds = sweeps.sweep(scene, {"solver.max_iterations": [1, 25, 25],
                              "support[0].where": ["start", "start", 0.3]},
                      mode="zip", out=tmp_path / "out", scheduler=client)
    assert ds.converged.dims == ("point",)
    assert ds.converged.values.tolist() == [False, True, False]
    msg = ds.message.values
    assert "stopped" in msg[0] or "min_step" in msg[0] or "fail" in msg[0], msg[0]
    assert int(ds.n_steps[0]) >= 1 and float(ds.load_factor[0, 0]) == 0.0  # steps kept
    assert "SceneError" in msg[2] and "support[0]" in msg[2] and int(ds.n_steps[2]) == 0
    assert msg[1].startswith("converged") and int(ds.n_steps[1]) >= 3
    assert ds["support[0].where"].values.tolist() == ["start", "start", "0.3"] \
        or ds["support[0].where"].values.tolist()[2] in (0.3, "0.3")
    # failed points are finished points: a re-run does not repeat them
    seen = []
    again = sweeps.sweep(scene, {"solver.max_iterations": [1, 25, 25],
                                 "support[0].where": ["start", "start", 0.3]},
                         mode="zip", out=tmp_path / "out", scheduler=client,
                         progress=lambda *a: seen.append(a))
    assert not seen and again.message.values.tolist() == msg.tolist()
    # a point file damaged outside the sweep is solved again
    damaged = tmp_path / "out" / "points" / f"{again.point_key.values[1]}.nc"
    damaged.write_bytes(b"not a netCDF file")
    third = sweeps.sweep(scene, {"solver.max_iterations": [1, 25, 25],
                                 "support[0].where": ["start", "start", 0.3]},
                         mode="zip", out=tmp_path / "out", scheduler=client,
                         progress=lambda *a: seen.append(a))
    assert len(seen) == 1 and seen[0][2].key == damaged.stem
    assert third.converged.values.tolist() == [False, True, False]
    np.testing.assert_array_equal(third.energy.values[1], again.energy.values[1])


@pytest.mark.slow
def test_point_whose_worker_dies_is_rerun(tmp_path, client):
    marker = tmp_path / "killed-once"

    def die_once(values, result, k):          # runs on the worker
        if values["load[0].vector[2]"] == -0.1 and k == 1 and not marker.exists():
            marker.write_text(str(os.getpid()))
            os._exit(1)

    scene = load_scene(write(tmp_path, SCENE))
    ds = sweeps.sweep(scene, {"load[0].vector[2]": [-0.05, -0.1]}, out=tmp_path / "out",
                      scheduler=client, on_step=die_once, centreline=True, vtu=True)
    assert marker.exists()
    assert bool(ds.converged.all())
    res = single(1e7, -0.1)
    pt = ds.sel({"load[0].vector[2]": -0.1})
    n = len(res.steps)
    np.testing.assert_allclose(pt.energy.values[:n], res.energies, rtol=1e-9)
    # the centreline, kept on request: nodes along s, its end is the tip
    assert pt.centreline.dims == ("step", "node", "xyz") and pt.sizes["node"] == 13
    np.testing.assert_allclose(pt.arclength, np.linspace(0, 1, 13), atol=1e-12)
    np.testing.assert_allclose(pt.centreline.values[:n, -1], pt.tip_position.values[:n])
    np.testing.assert_allclose(pt.centreline.values[n - 1], res.nodes()[1], rtol=1e-9,
                               atol=1e-12)
    # and the VTU series, kept on request, one file per converged step
    series = tmp_path / "out" / "points" / str(pt.point_key.values)
    assert (series / "point.pvd").exists() and len(list(series.glob("*.vtu"))) == n


def test_cli_sweep_refuses_bad_input(tmp_path, capsys):
    from skfem_rod import __main__ as cli
    write(tmp_path, SCENE)
    assert cli.main(["sweep", str(tmp_path / "cant.toml")]) == cli.BAD_INPUT
    assert "no [sweep] table" in capsys.readouterr().err
    write(tmp_path, SCENE + GRID, "grid")
    assert cli.main(["sweep", str(tmp_path / "grid.toml"), "--workers", "0"]) == cli.BAD_INPUT
    write(tmp_path, SCENE + '[sweep]\n"section.nu" = [0.3, 0.7]\n', "bad")
    assert cli.main(["sweep", str(tmp_path / "bad.toml")]) == cli.BAD_INPUT
    assert 'sweep."section.nu"[1]' in capsys.readouterr().err
    assert not (tmp_path / "output").exists()


def test_shipped_study_scene_is_a_zipped_sweep():
    from skfem_rod.studies import greenhill
    scene = load_scene(greenhill.SCENE)
    spec = scene.data["sweep"]
    assert spec["mode"] == "zip" and len(spec["parameters"]["load[0].vector[0]"]) == 6
    assert scene.data["solver"]["stability"]


@pytest.mark.slow
def test_greenhill_study_at_small_size(tmp_path):
    """The docs' study at its small size: the sign change of the lowest
    eigenvalue is Greenhill's clamped-rod threshold (16 elements: 4e-3)."""
    from skfem_rod.studies import greenhill
    rows = greenhill.main(out=str(tmp_path), n_workers=2, small=True)
    assert [r["T0"] for r in rows] == [0.25, 1.0, 4.0]
    for r in rows:
        assert 0.4 < r["load_factor"] < 0.8 and abs(r["error"]) < 1e-2, r
    assert (tmp_path / "greenhill_sweep.png").stat().st_size > 10_000
    assert (tmp_path / "sweep.nc").exists() and (tmp_path / "thresholds.json").exists()
