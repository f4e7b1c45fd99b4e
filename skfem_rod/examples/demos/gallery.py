"""Run every demo at a small size and write the gallery thumbnails
===============================================================

Every script in ``demos/`` (except this one) is imported and its
``main(out=..., **settings)`` is run headless with the small settings of
the demo: the module's ``GALLERY`` or ``SMALL`` dict, or the entry of
:data:`FALLBACK_GALLERY` / :data:`FALLBACK` below for demos that do not
define one (``SMALL`` is what the tests run; ``GALLERY``, when given, is a
larger run that reaches the state worth showing).  The renders, plots and
animations each demo returns (``summary["renders"]``, ``["plots"]``,
``["animations"]``; all PNG/GIF files in its output folder otherwise) are
shrunk to thumbnails in ``docs/img/gallery/`` for ``docs/gallery.md``,
and ``docs/img/gallery/index.json`` lists them with each demo's
wall time.

    python demos/gallery.py                    # all demos -> docs/img/gallery
    python demos/gallery.py bend45 rollup      # only these
    skfem-rod demo gallery --out /tmp/gallery  # same, via the CLI

``tests/test_demos.py`` runs each demo with the same settings
(:func:`small_settings`) and checks its images.
"""
import argparse
import importlib.util
import inspect
import json
import os
import pathlib
import shutil
import sys
import tempfile
import time

HERE = pathlib.Path(__file__).resolve().parent
#: the checkout's docs/img/gallery (demos live in skfem_rod/examples/demos/)
DOCS_IMG = HERE.parents[2] / "docs" / "img" / "gallery"
#: Small settings for demos that do not define ``SMALL`` themselves
#: (``{"name": dict(...)}``); empty: every demo defines its own.
FALLBACK = {}
#: Gallery settings (thumbnails) for demos whose small run does not reach the
#: interesting state and that define no ``GALLERY``; default: the small
#: settings.
FALLBACK_GALLERY = {}
THUMBNAIL_WIDTH = 640


def demo_names():
    """Names of the demos (``demos/*.py`` without this script and helpers
    starting with ``_``)."""
    return sorted(p.stem for p in HERE.glob("*.py")
                  if not p.name.startswith("_") and p.stem != "gallery")


def load(name):
    """Import ``demos/NAME.py`` as a module (it is not a package)."""
    path = HERE / f"{name}.py"
    if not path.is_file():
        raise ValueError(f"no demo {name!r}; demos are: {', '.join(demo_names())}")
    spec = importlib.util.spec_from_file_location(f"skfem_rod_demo_{name}", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module          # dataclasses etc. look the module up
    spec.loader.exec_module(module)
    return module


def small_settings(name, module=None):
    """Keyword arguments of a quick run of demo ``name`` (``SMALL`` of the
    module, else :data:`FALLBACK`); ``None`` if the demo has none."""
    module = module or load(name)
    small = getattr(module, "SMALL", None)
    if small is None:
        small = FALLBACK.get(name)
    return None if small is None else dict(small)


def gallery_settings(name, module=None):
    """Keyword arguments of the gallery run of demo ``name``: the module's
    ``GALLERY``, else :data:`FALLBACK_GALLERY`, else :func:`small_settings`."""
    module = module or load(name)
    settings = getattr(module, "GALLERY", None) or FALLBACK_GALLERY.get(name)
    return dict(settings) if settings is not None else small_settings(name, module)


def requested_size(module, settings):
    """Window size the demo's renders must have: ``window_size`` of the
    settings, else the default of ``main``, else render_rod's (1024, 768)."""
    if "window_size" in settings:
        return tuple(settings["window_size"])
    param = inspect.signature(module.main).parameters.get("window_size")
    if param is not None and param.default is not inspect.Parameter.empty:
        return tuple(param.default)
    return (1024, 768)


def run(name, out, gallery=False):
    """Run demo ``name`` at its small size (``gallery=True``: its gallery
    settings) into ``out``; return ``(summary, images, wall_time)`` where
    ``images`` maps a kind (``renders``, ``plots``, ``animations``) to file
    paths."""
    module = load(name)
    settings = (gallery_settings if gallery else small_settings)(name, module)
    if settings is None:
        raise ValueError(f"demo {name!r} has no small settings: define SMALL = dict(...) "
                         f"in demos/{name}.py (or add it to gallery.FALLBACK)")
    t0 = time.perf_counter()
    summary = module.main(out=os.fspath(out), **settings)
    wall = time.perf_counter() - t0
    images = {}
    if isinstance(summary, dict):
        for kind in ("renders", "plots", "animations"):
            if summary.get(kind):
                images[kind] = [os.fspath(p) for p in summary[kind]]
    if not images:
        found = sorted(pathlib.Path(out).glob("*.png")) + sorted(pathlib.Path(out).glob("*.gif"))
        images["renders"] = [os.fspath(p) for p in found]
    return summary, images, wall


def thumbnail(src, dst, width=THUMBNAIL_WIDTH):
    """Shrink a PNG to ``width`` pixels (aspect kept), or copy a GIF, to
    ``dst`` (atomically)."""
    from PIL import Image

    from skfem_rod.export import atomic_path

    dst = pathlib.Path(dst)
    dst.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(dst) as tmp:
        if str(src).endswith(".gif"):
            shutil.copyfile(src, tmp)
        else:
            im = Image.open(src).convert("RGB")
            h = round(im.height * width / im.width)
            im.resize((width, h), Image.LANCZOS).save(tmp, format="PNG", optimize=True)
    return os.fspath(dst)


def thumbnail_name(demo, path):
    """``demo_file.png``, or ``file.png`` when the file already starts with
    the demo's name."""
    base = pathlib.Path(path).name
    return base if base.startswith(demo) else f"{demo}_{base}"


def main(out=None, names=None, thumbnails=True):
    """Run the demos (all, or ``names``) at small size; write thumbnails to
    ``out`` (default ``docs/img/gallery``) and return the index."""
    out = pathlib.Path(out) if out is not None else DOCS_IMG
    names = list(names) if names else demo_names()
    index = {}
    with tempfile.TemporaryDirectory(prefix="skfem_rod_gallery_") as work:
        for name in names:
            summary, images, wall = run(name, pathlib.Path(work) / name, gallery=True)
            entry = {"wall_time_s": round(wall, 2), "converged": (
                summary.get("converged") if isinstance(summary, dict) else None)}
            for kind, files in images.items():
                entry[kind] = [pathlib.Path(thumbnail(f, out / thumbnail_name(name, f))).name
                               if thumbnails else f for f in files]
            index[name] = entry
            print(f"{name}: {wall:.1f} s, " + ", ".join(
                f"{len(v)} {k}" for k, v in images.items()))
    if thumbnails:
        from skfem_rod.export import write_json
        old = out / "index.json"
        merged = json.loads(old.read_text()) if old.is_file() else {}
        merged.update(index)                      # a partial run keeps the others
        write_json(old, dict(sorted(merged.items())))
    return index


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("names", nargs="*", help=f"demos to run (default: all: "
                                            f"{', '.join(demo_names())})")
    p.add_argument("--out", default=None, help="thumbnail folder (default docs/img/gallery)")
    a = p.parse_args()
    main(a.out, a.names)
