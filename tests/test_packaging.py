"""Packaging facts that drift silently: one version (the package's, read
by the build and repeated in CITATION.cff and CHANGELOG.md), the SPDX
license with its file, and the optional extras (the core imports neither
pyvista nor Pillow nor tqdm)."""
import pathlib
import re
import subprocess
import sys

import skfem_rod

try:
    import tomllib
except ModuleNotFoundError:                      # Python 3.10
    import tomli as tomllib

ROOT = pathlib.Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_one_version_everywhere():
    project = PYPROJECT["project"]
    assert "version" not in project and "version" in project["dynamic"]
    attr = PYPROJECT["tool"]["setuptools"]["dynamic"]["version"]["attr"]
    assert attr == "skfem_rod.__version__"
    assert re.fullmatch(r"\d+\.\d+\.\d+(\.dev\d+)?", skfem_rod.__version__)
    cff = (ROOT / "CITATION.cff").read_text()
    assert re.search(rf"^version: {re.escape(skfem_rod.__version__)}$", cff, re.M)
    changelog = (ROOT / "CHANGELOG.md").read_text()
    assert f"## [{skfem_rod.__version__}]" in changelog or "## [Unreleased]" in changelog


def test_license_is_an_spdx_expression_with_its_file():
    project = PYPROJECT["project"]
    assert project["license"] == "BSD-3-Clause"
    for name in project["license-files"]:
        text = (ROOT / name).read_text()
        assert "Redistribution and use in source and binary forms" in text
        assert "skfem_rod developers" in text


def test_citation_names_the_paper():
    cff = (ROOT / "CITATION.cff").read_text()
    assert 'title: "Rotational self-friction problem of elastic rods"' in cff
    assert "family-names: Latrach" in cff and "family-names: Chamekh" in cff


def test_core_runs_without_the_optional_extras():
    code = (
        "import sys\n"
        "for m in ('pyvista', 'vtk', 'vtkmodules', 'PIL', 'tqdm'): sys.modules[m] = None\n"
        "import skfem_rod.__main__, skfem_rod.scene, skfem_rod.export, skfem_rod.examples\n"
        "from skfem_rod import Rod, Section, geometry\n"
        "rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 2)\n"
        "res = rod.clamp('start').add_force('end', [0.0, 0.01, 0.0]).solve(1)\n"
        "assert res.converged\n")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)
    extras = PYPROJECT["project"]["optional-dependencies"]
    deps = " ".join(PYPROJECT["project"]["dependencies"]).lower()
    assert "pyvista" not in deps and "pillow" not in deps
    assert any(d.startswith("pyvista") for d in extras["render"])
    assert any(d.startswith("pillow") for d in extras["render"])
