"""The documentation builds without a single warning, its Python examples
run, and the docstring examples of the public API are right."""
import doctest
import os
import pathlib
import re
import subprocess
import sys

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def test_docs_build_strict_without_warnings(tmp_path):
    pytest.importorskip("mkdocs", reason="the docs extra is not installed")
    pytest.importorskip("mkdocstrings_handlers.python")
    site = tmp_path / "site"
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    log = proc.stdout + proc.stderr
    warnings = [line for line in log.splitlines() if re.match(r"\s*(WARNING|ERROR)\b", line)]
    assert proc.returncode == 0, log
    assert warnings == [], "\n".join(warnings)
    # every page of the nav was written, and the API reference has content
    for page in ("quickstart", "scenes", "theory", "teaching", "verification",
                 "gallery", "api"):
        assert (site / page / "index.html").exists(), page
    assert (site / "index.html").exists()
    api = (site / "api" / "index.html").read_text()
    for name in ("skfem_rod.Rod", "Rod.solve", "Section.circle", "Result.render",
                 "render_animation", "internal_force", "friction_force"):
        assert name.split(".")[-1] in api, name


def test_every_page_is_in_the_nav():
    import yaml

    cfg = yaml.safe_load((ROOT / "mkdocs.yml").read_text().replace("!!python", "#"))

    def pages(nav):
        for item in nav:
            for value in item.values():
                yield from (pages(value) if isinstance(value, list) else [value])

    in_nav = set(pages(cfg["nav"]))
    on_disk = {p.name for p in DOCS.glob("*.md")}
    assert on_disk - in_nav == set(), "pages missing from mkdocs.yml nav"
    assert in_nav - on_disk == set(), "nav entries without a page"


def python_blocks(page):
    text = (DOCS / page).read_text()
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


@pytest.mark.parametrize("page", ["quickstart.md", "teaching.md"])
def test_page_examples_run(page, tmp_path, monkeypatch):
    """The Python blocks of the page, run in order in one namespace (they
    contain their own asserts)."""
    blocks = python_blocks(page)
    assert blocks, f"no python example in {page}"
    monkeypatch.chdir(tmp_path)
    import matplotlib
    matplotlib.use("Agg")
    ns = {"__name__": f"docs_{page}"}
    for code in blocks:
        exec(compile(code, f"docs/{page}", "exec"), ns)


#: builders used by the solver, not part of the user-facing API
INTERNAL = {"skfem_rod.Result.append", "skfem_rod.Result.finish"}


def public_api_objects():
    import skfem_rod
    from skfem_rod import geometry, render

    objs = []
    for name in skfem_rod.__all__:
        obj = getattr(skfem_rod, name)
        objs.append((f"skfem_rod.{name}", obj))
        if isinstance(obj, type):
            for attr, member in vars(obj).items():
                if not attr.startswith("_") and (callable(member) or isinstance(
                        member, (classmethod, staticmethod, property))):
                    objs.append((f"skfem_rod.{name}.{attr}", getattr(obj, attr)))
    for mod in (geometry,):
        for attr in dir(mod):
            f = getattr(mod, attr)
            if (callable(f) and not attr.startswith("_")
                    and getattr(f, "__module__", None) == mod.__name__):
                objs.append((f"{mod.__name__}.{attr}", f))
    for attr in ("contact_state_colors", "render_contact_states", "render_animation"):
        objs.append((f"skfem_rod.render.{attr}", getattr(render, attr)))
    return objs


def test_public_api_has_numpydoc_docstrings_with_examples():
    missing = []
    for name, obj in public_api_objects():
        if name in INTERNAL:
            continue
        doc = obj.__doc__ if not isinstance(obj, property) else obj.fget.__doc__
        if not doc or "Examples\n" not in doc and ">>>" not in doc:
            missing.append(name)
    assert missing == [], "public objects without an example in the docstring"


def test_public_api_docstring_examples_pass(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    import matplotlib
    matplotlib.use("Agg")
    finder = doctest.DocTestFinder(recurse=False)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    n = 0
    for name, obj in public_api_objects():
        target = obj.fget if isinstance(obj, property) else obj
        for test in finder.find(target, name, extraglobs={"np": np}):
            n += len(test.examples)
            runner.run(test)
    assert n > 20
    assert runner.failures == 0, "docstring examples failed (see the output above)"
