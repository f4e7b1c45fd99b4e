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


def _strip_code(html):
    """The HTML without <pre>, <code> and <script> elements (where a dollar
    sign is just a character)."""
    for tag in ("pre", "code", "script", "style"):
        html = re.sub(rf"<{tag}\b.*?</{tag}>", "", html, flags=re.S)
    return html


@pytest.mark.slow
def test_docs_build_strict_without_warnings(tmp_path):
    """The site builds strictly (any warning fails), runs the notebook, and
    its pages carry typeset maths (KaTeX), no raw ``$...$`` and no heading
    ids that start with a digit (invalid CSS selectors)."""
    pytest.importorskip("mkdocs", reason="the docs extra is not installed")
    pytest.importorskip("mkdocstrings_handlers.python")
    pytest.importorskip("material", reason="mkdocs-material is not installed")
    pytest.importorskip("mkdocs_jupyter", reason="mkdocs-jupyter is not installed")
    site = tmp_path / "site"
    proc = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(site)],
        cwd=ROOT, capture_output=True, text=True, timeout=600,
        env={**os.environ, "NO_MKDOCS_2_WARNING": "1", "SKFEM_ROD_DOCS_EXECUTE": "true"})
    log = proc.stdout + proc.stderr
    warnings = [line for line in log.splitlines() if re.match(r"\s*(WARNING|ERROR)\b", line)]
    assert proc.returncode == 0, log
    assert warnings == [], "\n".join(warnings)
    # every page of the nav was written, and the API reference has content
    for page in ("quickstart", "scenes", "theory", "teaching", "verification",
                 "gallery", "api", "paraview", "notebooks/rollup"):
        assert (site / page / "index.html").exists(), page
    assert (site / "index.html").exists()
    api = (site / "api" / "index.html").read_text()
    for name in ("skfem_rod.Rod", "Rod.solve", "Section.circle", "Result.render",
                 "render_animation", "internal_force", "friction_force", "to_pyvista"):
        assert name.split(".")[-1] in api, name

    pages = sorted(site.rglob("index.html"))
    assert len(pages) >= 15
    for page in pages:
        html = page.read_text()
        where = page.relative_to(site)
        # the maths script (a local KaTeX copy: works offline) on every page
        assert "assets/katex/katex.min.js" in html, where
        assert "javascripts/katex.js" in html, where
        # heading ids are valid CSS selectors
        bad = re.findall(r'<h[1-6][^>]*\bid="(\d[^"]*)"', html)
        assert bad == [], f"{where}: heading ids starting with a digit: {bad}"
        if "notebooks" in where.parts:
            continue        # Jupyter markdown keeps $...$; KaTeX typesets it in the browser
        text = _strip_code(html)
        raw = re.findall(r"(?<![\\\w])\$[^$\s<][^$<]*?\$", text)
        assert raw == [], f"{where}: raw $...$ not turned into maths: {raw[:3]}"
    # the pages whose formulas were pseudo-code now carry typeset maths
    for page in ("theory", "teaching", "friction", "verification"):
        html = (site / page / "index.html").read_text()
        assert html.count('class="arithmatex"') > 20, page
    # the paper is cited in full
    theory = " ".join((site / "theory" / "index.html").read_text().split())
    assert "Rotational self-friction problem of elastic rods" in theory
    assert "Latrach" in theory and "Chamekh" in theory
    # no development notes in the user docs
    for page in pages:
        html = page.read_text()
        for note in ("shared/seed", "as they land", "/work/", "git archive"):
            assert note not in html, f"{page.relative_to(site)}: {note!r}"
    # the notebook ran top to bottom in the build, and can be downloaded
    nb = (site / "notebooks" / "rollup" / "index.html").read_text()
    assert "largest distance to the exact arc" in nb          # printed output of a cell
    assert nb.count("data:image/png;base64") >= 2               # the plot and the render
    assert "Traceback" not in nb
    assert "application/vnd.jupyter.stderr" not in _strip_code(nb)   # no warning printed
    assert (site / "notebooks" / "rollup" / "rollup.ipynb").exists()


def test_every_page_is_in_the_nav():
    import yaml

    class Loader(yaml.SafeLoader):
        """Reads mkdocs.yml with its tags (!ENV, !!python/name) as plain values."""

    Loader.add_multi_constructor("!", lambda loader, suffix, node: None)
    Loader.add_multi_constructor("tag:yaml.org,2002:python/",
                                 lambda loader, suffix, node: None)
    cfg = yaml.load((ROOT / "mkdocs.yml").read_text(), Loader=Loader)

    def pages(nav):
        for item in nav:
            for value in item.values():
                yield from (pages(value) if isinstance(value, list) else [value])

    in_nav = set(pages(cfg["nav"]))
    on_disk = {p.name for p in DOCS.glob("*.md")} | {
        p.relative_to(DOCS).as_posix() for p in DOCS.glob("notebooks/*.ipynb")}
    assert on_disk - in_nav == set(), "pages missing from mkdocs.yml nav"
    assert in_nav - on_disk == set(), "nav entries without a page"


def python_blocks(page):
    text = (DOCS / page).read_text()
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


@pytest.mark.parametrize("page", ["quickstart.md", "teaching.md", "paraview.md"])
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


@pytest.mark.slow
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


def control_characters(text):
    """``(line, character)`` of every C0 control character in ``text``
    but the newline (a TeX escape written through a Python string becomes
    one: ``\\v``arepsilon, ``\\t``o, ``\\a``pprox), which the strict build
    renders without a warning."""
    return [(text.count("\n", 0, m.start()) + 1, repr(m.group()))
            for m in re.finditer(r"[\x00-\x09\x0b-\x1f\x7f]", text)]


def test_pages_hold_no_control_characters():
    """The documentation, the README and the benchmark results are plain
    text: no tab, no vertical tab, no bell (a script once wrote
    ``$\\varepsilon$`` into docs/contact-solve.md as a vertical tab and
    ``arepsilon``)."""
    assert control_characters("$s \x07pprox 0.15$, $10^{-3}\x0barepsilon$") == \
        [(1, repr("\x07")), (1, repr("\x0b"))]
    pages = sorted(DOCS.rglob("*.md")) + [ROOT / "README.md"] + \
        sorted((ROOT / "benchmarks").glob("*.md"))
    bad = {str(p.relative_to(ROOT)): control_characters(p.read_text()) for p in pages}
    assert {k: v for k, v in bad.items() if v} == {}
