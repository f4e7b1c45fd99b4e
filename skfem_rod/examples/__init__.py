"""Examples shipped with the package: scenes (TOML) and demo scripts.

They are installed with skfem_rod, so they work outside a source checkout::

    skfem-rod example                       # list them
    skfem-rod example bend45 --copy d       # copy scenes/bend45.toml (and demos/bend45.py) to d/
    skfem-rod run d/bend45.toml
    skfem-rod demo rollup --out out         # run demos/rollup.py's main()

In a checkout, ``scenes/`` and ``demos/`` at the top of the repository point
here.

>>> from skfem_rod import examples
>>> "bend45" in examples.scenes() and "rollup" in examples.demos()
True
>>> examples.path("bend45").name
'bend45.toml'
"""
import difflib
import importlib.util
import pathlib
import shutil

HERE = pathlib.Path(__file__).resolve().parent
SCENES = HERE / "scenes"
DEMOS = HERE / "demos"


def scenes():
    """Names of the shipped scenes (``scenes/NAME.toml``), sorted."""
    return sorted(p.stem for p in SCENES.glob("*.toml"))


#: scripts in demos/ that are tools, not demos (gallery.py writes the docs' images)
TOOLS = ("gallery",)


def demos(folder=DEMOS):
    """Names of the demo scripts in ``folder`` (default: the shipped
    ``demos/NAME.py``), sorted; helpers (``_*.py``) and :data:`TOOLS` left out."""
    return sorted(p.stem for p in pathlib.Path(folder).glob("*.py")
                  if not p.name.startswith("_") and p.stem not in TOOLS)


def names():
    """Every example name (a scene, a demo, or both)."""
    return sorted(set(scenes()) | set(demos()))


def unknown(name, available):
    """The message for a name that is not an example (with a suggestion)."""
    close = difflib.get_close_matches(name, available, n=1)
    return (f"no example {name!r}" + (f"; did you mean {close[0]!r}?" if close else ".")
            + f" Available: {', '.join(available)}")


def files(name):
    """The files of example ``name``: its scene and/or its demo script.

    Raises
    ------
    ValueError
        If ``name`` is neither a scene nor a demo.
    """
    found = [p for p in (SCENES / f"{name}.toml", DEMOS / f"{name}.py") if p.is_file()]
    if not found:
        raise ValueError(unknown(name, names()))
    return found


def path(name):
    """The installed file of example ``name``: the scene if there is one,
    else the demo script."""
    return files(name)[0]


def copy(name, directory):
    """Copy the files of example ``name`` into ``directory`` (created if
    needed); returns the new paths.  A demo that imports a sibling demo
    (``plectoneme_friction`` uses ``twisted_rod``) brings it along."""
    directory = pathlib.Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    sources = files(name)
    for src in list(sources):
        if src.suffix == ".py":
            text = src.read_text()
            sources += [DEMOS / f"{d}.py" for d in demos()
                        if d != name and f'"{d}.py"' in text]
    written = []
    for src in sources:
        dst = directory / src.name
        shutil.copyfile(src, dst)
        written.append(dst)
    return written


def load_demo(name):
    """Demo ``name`` imported as a module (call its ``main(out, ...)``).

    Raises
    ------
    ValueError
        If there is no such demo.
    """
    if name not in demos():
        raise ValueError(unknown(name, demos()).replace("example", "demo", 1))
    spec = importlib.util.spec_from_file_location(f"skfem_rod_demo_{name}",
                                                  DEMOS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
