"""The shipped examples and the command-line plumbing around them:
``skfem-rod example``, ``check`` on several files, ``--version``, the note
when a scene writes nothing, progress through ``logging``; and (slow) a
real non-editable install in a fresh virtual environment, used outside the
checkout."""
import json
import os
import pathlib
import re
import shutil
import subprocess
import sys
import sysconfig

import pytest

import skfem_rod
from skfem_rod import __main__ as cli
from skfem_rod import examples

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_examples_are_the_checkout_folders():
    # demos/ and scenes/ of the checkout are the shipped ones
    assert (ROOT / "scenes").resolve() == examples.SCENES
    assert (ROOT / "demos").resolve() == examples.DEMOS
    assert {"bend45", "rollup", "hairpin_contact"} <= set(examples.scenes())
    assert {"bend45", "rollup", "knot"} <= set(examples.demos())
    assert "gallery" not in examples.demos()           # a docs tool, not a demo
    with pytest.raises(ValueError, match="did you mean 'rollup'"):
        examples.files("rolup")


def test_the_library_imports_no_demo():
    # importing a demo module sets skfem_rod.examples.demos to that
    # subpackage and hides the function examples.demos (the CI failed on it
    # when a study imported demos/twisted_rod.py inside a function): no
    # library module may import a demo, at the top or inside a function
    import ast
    top = pathlib.Path(skfem_rod.__file__).parent
    found = []
    for f in sorted(top.rglob("*.py")):
        if "examples" in f.relative_to(top).parts[:-1]:
            continue
        for node in ast.walk(ast.parse(f.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [f"{node.module}"] + [f"{node.module}.{a.name}" for a in node.names]
                     if isinstance(node, ast.ImportFrom) and node.module else [])
            if any(re.search(r"(^|\.)examples\.demos(\.|$)", n) for n in names):
                found.append(f"{f.relative_to(top)}:{node.lineno}")
    assert not found, f"library modules importing a demo: {found}"
    # and a fresh interpreter that imports every library module keeps the function
    code = ("import importlib, pathlib, skfem_rod\n"
            "top = pathlib.Path(skfem_rod.__file__).parent\n"
            "for f in sorted(top.rglob('*.py')):\n"
            "    parts = f.relative_to(top.parent).with_suffix('').parts\n"
            "    if 'examples' in parts[:-1] or parts[-1] == '__main__':\n"
            "        continue\n"
            "    importlib.import_module('.'.join(p for p in parts if p != '__init__'))\n"
            "from skfem_rod import examples\n"
            "assert callable(examples.demos), examples.demos\n")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)

def test_example_list_show_copy(tmp_path, capsys):
    assert cli.main(["example"]) == 0
    out = capsys.readouterr().out
    assert "bend45" in out and "hairpin_contact" in out and "twisted_rod" in out
    assert cli.main(["example", "bend45"]) == 0
    assert "bend45.toml" in capsys.readouterr().out
    assert cli.main(["example", "bend45", "--copy", str(tmp_path / "d")]) == 0
    assert "skfem-rod run" in capsys.readouterr().out
    assert (tmp_path / "d" / "bend45.toml").read_bytes() == (ROOT / "scenes" / "bend45.toml").read_bytes()
    assert (tmp_path / "d" / "bend45.py").exists()
    # a demo importing a sibling brings it along
    assert cli.main(["example", "plectoneme_friction", "--copy", str(tmp_path / "p")]) == 0
    assert sorted(p.name for p in (tmp_path / "p").iterdir()) == [
        "plectoneme_friction.py", "twisted_rod.py"]
    assert cli.main(["example", "bend4"]) == 2
    assert "did you mean 'bend45'?" in capsys.readouterr().err


def test_check_several_files_reports_each(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("title = 1\n")
    good = [str(ROOT / "scenes" / f"{n}.toml") for n in ("rollup", "bend45")]
    assert cli.main(["check", *good]) == 0
    assert capsys.readouterr().out.count("valid scene") == 2
    assert cli.main(["check", good[0], str(bad), good[1]]) == 2
    cap = capsys.readouterr()
    assert cap.out.count("valid scene") == 2 and "bad.toml" in cap.err


def test_version(capsys):
    assert cli.main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"skfem-rod {skfem_rod.__version__}"


def test_run_without_output_says_it_wrote_nothing(tmp_path, capsys, monkeypatch):
    text = (ROOT / "scenes" / "cantilever.toml").read_text()
    text = text[:text.index("[output]")].replace("n_elements = 16", "n_elements = 4")
    (tmp_path / "c.toml").write_text(text)
    monkeypatch.chdir(tmp_path)
    assert cli.main(["run", "c.toml"]) == 0
    cap = capsys.readouterr()
    assert "converged" in cap.out and "wrote nothing" in cap.err and "[output]" in cap.err
    assert sorted(os.listdir(tmp_path)) == ["c.toml"]
    # -v shows the per-step lines off a terminal; the handlers are removed after
    assert cli.main(["run", "c.toml", "-v", "--out", "o"]) == 0
    assert "step    1  load factor" in capsys.readouterr().out
    assert not [h for h in __import__("logging").getLogger("skfem_rod").handlers]


def test_warnings_are_one_line_on_stderr_and_quiet_hides_them(tmp_path, capsys, monkeypatch):
    import warnings

    calls = []

    def check(args):                       # a new text each call (warnings show once)
        calls.append(args)
        warnings.warn(f"Uzawa did not reach its tolerance at step {len(calls) + 2}",
                      RuntimeWarning)
        return 0
    monkeypatch.setattr(cli, "cmd_check", check)
    scene = str(ROOT / "scenes" / "rollup.toml")
    assert cli.main(["check", scene]) == 0
    err = capsys.readouterr().err
    assert err == "skfem-rod: WARNING: Uzawa did not reach its tolerance at step 3\n"
    monkeypatch.setattr(cli, "cmd_run", check)
    assert cli.main(["run", scene, "--quiet"]) == 0                  # errors only
    assert capsys.readouterr() == ("", "")
    assert warnings.showwarning.__module__ == "warnings"            # restored


def test_missing_render_extra_is_named_with_the_fix(tmp_path, capsys, monkeypatch):
    (tmp_path / "pic.py").write_text("def main(out='x'):\n    import pyvista\n")
    monkeypatch.setattr(cli, "demos_dir", lambda: tmp_path)
    monkeypatch.setitem(sys.modules, "pyvista", None)                # not installed
    assert cli.main(["demo", "pic"]) == 2
    err = capsys.readouterr().err
    assert "'pyvista'" in err and "pip install 'skfem_rod[render]'" in err
    assert "Traceback" not in err


# ---------------------------------------------------------------------------
# a real non-editable install in a fresh virtual environment, outside the
# checkout (the dependencies come from this environment's site-packages)
# ---------------------------------------------------------------------------
@pytest.mark.slow
def test_fresh_non_editable_install_runs_the_shipped_examples(tmp_path):
    # the package's files only (what a clean checkout has), built by pip
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(ROOT / name, src / name)
    shutil.copytree(ROOT / "skfem_rod", src / "skfem_rod",
                    ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    py, pip = venv / "bin" / "python", venv / "bin" / "pip"
    # this environment's packages (numpy, scikit-fem, pyvista, ...) underneath,
    # without its skfem_rod (.pth files of an added path are not processed, so
    # an editable install there stays inactive)
    site = pathlib.Path(subprocess.check_output(
        [py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        text=True).strip())
    (site / "base_env.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env.update(MPLBACKEND="Agg", PIP_DISABLE_PIP_VERSION_CHECK="1")
    # a plain, non-editable install; the dependencies are already there
    subprocess.run([pip, "install", "-q", "--no-deps", str(src)], check=True, env=env,
                   cwd=tmp_path)
    shutil.rmtree(src)                                   # nothing left to fall back on
    work = tmp_path / "user"
    work.mkdir()

    def run(*args):
        return subprocess.run([str(venv / "bin" / "skfem-rod"), *args], cwd=work, env=env,
                              capture_output=True, text=True, timeout=900)

    where = subprocess.check_output([py, "-c", "import skfem_rod; print(skfem_rod.__file__)"],
                                    cwd=work, env=env, text=True).strip()
    assert where.startswith(str(site)), where          # the installed copy, not the checkout
    r = run("--version")
    assert r.returncode == 0 and skfem_rod.__version__ in r.stdout
    r = run("example", "bend45", "--copy", "d")
    assert r.returncode == 0, r.stderr
    r = run("run", "d/bend45.toml")
    assert r.returncode == 0, r.stderr
    assert json.loads((work / "output" / "bend45" / "bend45.json").read_text())["converged"]
    r = run("demo")
    assert r.returncode == 0 and "rollup" in r.stdout, r.stderr
    r = run("demo", "rollup")
    assert r.returncode == 0, r.stderr
    assert (work / "output" / "rollup" / "results.json").exists()
    assert (work / "output" / "rollup" / "rollup.png").exists()
    r = run("demo", "bend45", "--out", "b")
    assert r.returncode == 0, r.stderr
    assert (work / "b" / "results.json").exists() and (work / "b" / "bend45.png").exists()
    assert "bad X server" not in r.stderr
