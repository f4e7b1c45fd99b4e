"""Issue 14, items 8-9: the CLI around failures.  A run killed by SIGINT or
SIGTERM at a random (seeded) point leaves a readable series of the steps it
finished (every .pvd entry a complete VTU whose TimeValue is the entry's
time, times increasing, no VTU outside the .pvd, no temporary file) and
exits 130 / 143; the output directory is checked before the solve; files
of an earlier run are removed; no traceback reaches the user."""
import json
import os
import signal
import subprocess
import sys
import time
from xml.etree import ElementTree as ET

import numpy as np
import pytest

SCENE = """
[rod]
geometry = {{type = "straight", length = 1.0}}
n_elements = 8
[section]
EA = 1e4
GA1 = 1e4
GA2 = 1e4
EI1 = 1.0
EI2 = 1.0
GJ = 0.8
[[support]]
where = "start"
kind = "clamp"
[[load]]
kind = "moment"
where = "end"
vector = [0.0, 0.0, 6.0]
[solver]
n_steps = {n_steps}
[output]
directory = "{out}"
basename = "rod"
vtu = true
"""


def scene(tmp_path, n_steps, out="out"):
    path = tmp_path / f"s{n_steps}.toml"
    path.write_text(SCENE.format(n_steps=n_steps, out=tmp_path / out))
    return path


def cli(*args, **kw):
    return subprocess.run([sys.executable, "-m", "skfem_rod", *map(str, args)],
                          capture_output=True, text=True, timeout=300, **kw)


def check_series(out):
    """The series in ``out`` is readable and consistent; returns its times."""
    import meshio
    names = sorted(os.listdir(out))
    assert not [n for n in names if n.endswith(".tmp")], names        # no temporary file
    vtus = {n for n in names if n.endswith(".vtu")}
    if "rod.pvd" not in names:
        assert not vtus, names
        return []
    coll = ET.parse(out / "rod.pvd").getroot().find("Collection")
    entries = [(float(e.get("timestep")), e.get("file")) for e in coll]
    assert {f for _, f in entries} == vtus                             # no stray VTU
    times = [t for t, _ in entries]
    assert all(b > a for a, b in zip(times, times[1:]))
    for t, f in entries:
        mesh = meshio.read(out / f)
        assert float(np.ravel(mesh.field_data["TimeValue"])[0]) == t
        assert mesh.points.shape == (8 * 8 + 1, 3)
    return times


def kill_at(tmp_path, sig, delay, n_steps=400):
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "skfem_rod", "run",
                             str(scene(tmp_path, n_steps))],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t0 = time.time()
    while not (out / "rod.pvd").exists() and proc.poll() is None and time.time() - t0 < 60:
        time.sleep(0.01)                              # the first step is on disk
    time.sleep(delay)
    proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=120)
    return proc.returncode, stderr, out


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_killed_run_leaves_a_readable_series(tmp_path, sig):
    code, stderr, out = kill_at(tmp_path, sig, 0.5)
    assert code == 128 + sig, stderr
    assert "Traceback" not in stderr and "converged step(s) kept" in stderr
    times = check_series(out)
    summary = json.loads((out / "rod.json").read_text())
    assert summary["converged"] is False and len(summary["steps"]) == len(times) >= 1


@pytest.mark.slow
def test_killed_at_random_points(tmp_path):
    rng = np.random.default_rng(14)
    for k, (sig, delay) in enumerate(zip(rng.choice([signal.SIGINT, signal.SIGTERM], 8),
                                         rng.uniform(0.0, 2.0, 8))):
        d = tmp_path / f"run{k}"
        d.mkdir()
        code, stderr, out = kill_at(d, int(sig), float(delay))
        assert code in (0, 128 + int(sig)), stderr
        assert "Traceback" not in stderr
        check_series(out)


def test_stale_files_of_an_earlier_run_are_removed(tmp_path):
    assert cli("run", scene(tmp_path, 6)).returncode == 0
    (tmp_path / "out" / ".rod_0003.vtu.abcd.tmp").write_text("left by a kill -9")
    assert cli("run", scene(tmp_path, 2)).returncode == 0
    assert check_series(tmp_path / "out") == [0.0, 0.5, 1.0]
    assert sorted(os.listdir(tmp_path / "out")) == [
        "rod.json", "rod.pvd", "rod.xdmf", "rod_0000.vtu", "rod_0001.vtu", "rod_0002.vtu"]


def test_unwritable_output_is_reported_before_the_solve(tmp_path):
    (tmp_path / "file").write_text("")
    t0 = time.time()
    r = cli("run", scene(tmp_path, 10**6, out="file/sub"))      # would solve for hours
    assert r.returncode == 2 and time.time() - t0 < 60
    assert "cannot write to the output directory" in r.stderr and "Traceback" not in r.stderr


def test_check_dev_zero_and_nul_in_names(tmp_path):
    r = cli("check", "/dev/zero")
    assert r.returncode == 2 and "larger than 1 MiB" in r.stderr
    assert "Traceback" not in r.stderr
    text = scene(tmp_path, 2).read_text().replace('basename = "rod"', 'basename = "a\\u0000b"')
    (tmp_path / "nul.toml").write_text(text)
    r = cli("check", tmp_path / "nul.toml")
    assert r.returncode == 2 and "output.basename" in r.stderr and "Traceback" not in r.stderr
    text = scene(tmp_path, 2).read_text().replace(f'directory = "{tmp_path / "out"}"',
                                                   'directory = "o\\u0000ut"')
    (tmp_path / "nul2.toml").write_text(text)
    r = cli("check", tmp_path / "nul2.toml")
    assert r.returncode == 2 and "output.directory" in r.stderr and "Traceback" not in r.stderr


def test_non_finite_results_do_not_crash_the_json_writer(tmp_path, monkeypatch):
    """A result with a non-finite number (e.g. an infinite reaction): the
    run reports it (exit 3), no traceback."""
    from skfem_rod import __main__ as main_mod
    from skfem_rod.scene import Scene
    real = Scene.solve

    def solve(self, callback=None):
        res = real(self, callback)
        n = next(iter(res.steps[-1].reactions))
        res.steps[-1].reactions[n] = (np.array([-np.inf, 0, 0]), np.zeros(3))
        return res
    monkeypatch.setattr(Scene, "solve", solve)
    code = main_mod.main(["run", str(scene(tmp_path, 2))])
    assert code == 3
    assert not [n for n in os.listdir(tmp_path / "out") if n.endswith(".tmp")]
