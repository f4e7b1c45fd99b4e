"""The ``skfem-rod`` command (also ``python -m skfem_rod``).

::

    skfem-rod run SCENE.toml [--out DIR] [--quiet]   solve a scene, write its outputs
    skfem-rod check SCENE.toml                       validate a scene, solve nothing
    skfem-rod demo [NAME] [--out DIR]                run demos/NAME.py (list without NAME)

Exit codes: 0 success, 2 bad input (the message is printed, no traceback),
3 the solve stopped before the end of the load path (the converged steps
are written, and where it stopped is printed).  The scene format is in
docs/scenes.md.
"""
import argparse
import difflib
import importlib.util
import inspect
import os
import pathlib
import sys
import time

from .scene import load_scene, step_figures

OK, BAD_INPUT, SOLVE_FAILED = 0, 2, 3


def _err(msg):
    print(f"skfem-rod: {msg}", file=sys.stderr)


def progress_line(step, index):
    """One line per converged load step: load factor, Newton iterations
    (all Uzawa passes), Uzawa updates and active contact points."""
    f = step_figures(step, index)
    uzawa = f.get("uzawa_iterations", "-")
    contacts = f.get("active_contacts", "-")
    return (f"step {index:4d}  load factor {f['load_factor']:<11.6g} "
            f"Newton {f['newton_iterations']:3d}  Uzawa {uzawa:>3}  contacts {contacts:>4}")


def _files(written, directory):
    vtu = [p for p in written if p.endswith(".vtu")]
    rest = [os.path.basename(p) for p in written if not p.endswith(".vtu")]
    if vtu:
        rest.append(f"{len(vtu)} VTU file(s)")
    return f"{directory}: " + ", ".join(rest)


def _load(path):
    """The scene, or None after printing why it cannot be used."""
    try:
        return load_scene(path)
    except OSError as err:
        _err(f"cannot read {path}: {err.strerror or err}")
    except ValueError as err:
        _err(f"{path}: {err}")
    return None


def cmd_run(args):
    scene = _load(args.scene)
    if scene is None:
        return BAD_INPUT
    talk = not args.quiet
    progress = talk and sys.stdout.isatty()
    if talk:
        d = scene.data
        print(f"{scene.name}: {d['rod']['geometry']['type']} rod, "
              f"{d['rod']['n_elements']} elements, {len(d['support'])} support(s), "
              f"{len(d['load'])} load(s), contact "
              f"{'on' if (d.get('contact') or {}).get('enabled') else 'off'}", flush=True)
    t0 = time.perf_counter()
    live = (lambda res, k: print(progress_line(res.steps[k], k), flush=True)) \
        if progress else None
    result = scene.solve(callback=live)
    wall = time.perf_counter() - t0
    try:
        written = scene.write(result, out=args.out, wall_time=wall)
    except OSError as err:
        _err(f"cannot write the output: {err}")
        return BAD_INPUT
    directory = scene.output_directory(args.out)
    if not result.converged:
        _err(f"the solve stopped: {result.message}")
        if written:
            _err(f"wrote the {len(result.steps)} converged step(s) to "
                 + _files(written, directory))
        return SOLVE_FAILED
    if talk:
        print(f"{result.message} ({wall:.2f} s)")
        if written:
            print("wrote " + _files(written, directory))
    return OK


def cmd_check(args):
    scene = _load(args.scene)
    if scene is None:
        return BAD_INPUT
    print(f"{args.scene}: valid scene {scene.name!r}")
    return OK


def demos_dir():
    """The repository's demos/ folder, next to the package (a source
    checkout or an editable install; demos are not part of the wheel)."""
    return pathlib.Path(__file__).resolve().parent.parent / "demos"


def cmd_demo(args):
    folder = demos_dir()
    if not folder.is_dir():
        _err(f"no demos found (looked in {folder}): the demos live in the repository's "
             "demos/ folder and are not installed with the package; run them from a "
             "source checkout (pip install -e .) or as python demos/NAME.py")
        return BAD_INPUT
    names = sorted(p.stem for p in folder.glob("*.py") if not p.name.startswith("_"))
    if args.name is None:
        print("demos: " + ", ".join(names))
        return OK
    if args.name not in names:
        close = difflib.get_close_matches(args.name, names, n=1)
        _err(f"no demo {args.name!r}" + (f"; did you mean {close[0]!r}?" if close else ".")
             + f" Available: {', '.join(names)}")
        return BAD_INPUT
    spec = importlib.util.spec_from_file_location(f"skfem_rod_demo_{args.name}",
                                                  folder / f"{args.name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    main = getattr(module, "main", None)
    if main is None:
        _err(f"demos/{args.name}.py has no main()")
        return BAD_INPUT
    kwargs = {}
    if args.out is not None:
        if "out" not in inspect.signature(main).parameters:
            _err(f"demo {args.name!r} takes no output directory (--out)")
            return BAD_INPUT
        kwargs["out"] = args.out
    ret = main(**kwargs)
    if isinstance(ret, dict) and ret.get("converged") is False:
        return SOLVE_FAILED
    return OK


def parser():
    p = argparse.ArgumentParser(
        prog="skfem-rod",
        description="Geometrically exact rods with self-contact: solve TOML scenes "
                    "(format: docs/scenes.md) and run the demos.",
        epilog="exit codes: 0 success, 2 bad input, 3 the solve stopped early")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", required=True)
    r = sub.add_parser(
        "run", help="solve a scene and write the outputs its [output] table asks for",
        description="Validate SCENE, solve it along its load path and write what its "
                    "[output] table asks for (JSON summary, VTU series, PNG render). "
                    "A line per converged load step is printed when stdout is a "
                    "terminal. Exit codes: 0 converged, 2 invalid scene or unwritable "
                    "output, 3 the solve stopped early (the converged steps are written).")
    r.add_argument("scene", metavar="SCENE.toml", help="scene file")
    r.add_argument("--out", metavar="DIR",
                   help="output directory (replaces [output] directory; without an "
                        "[output] table, writes the JSON summary there)")
    r.add_argument("-q", "--quiet", action="store_true",
                   help="print nothing but errors")
    r.set_defaults(func=cmd_run)
    c = sub.add_parser("check", help="validate a scene without solving it",
                       description="Validate every key of SCENE and build the rod "
                                   "(boundary conditions); exit 0 if valid, 2 if not.")
    c.add_argument("scene", metavar="SCENE.toml", help="scene file")
    c.set_defaults(func=cmd_check)
    d = sub.add_parser("demo", help="run a demo from the repository's demos/ folder",
                       description="Run demos/NAME.py's main() (without NAME: list the "
                                   "demos). The demos live in the source checkout.")
    d.add_argument("name", metavar="NAME", nargs="?", help="demo name, e.g. rollup")
    d.add_argument("--out", metavar="DIR", help="output directory of the demo")
    d.set_defaults(func=cmd_demo)
    return p


def main(argv=None):
    """Run the command line ``argv`` (default ``sys.argv[1:]``); returns the
    exit code."""
    try:
        args = parser().parse_args(argv)
    except SystemExit as exc:                 # --help (0) or a usage error (2)
        return exc.code if isinstance(exc.code, int) else BAD_INPUT
    return args.func(args)


if __name__ == "__main__":
    sys.exit(main())
