"""The ``skfem-rod`` command (also ``python -m skfem_rod``).

::

    skfem-rod run SCENE.toml [--out DIR] [--quiet]   solve a scene, write its outputs
    skfem-rod check SCENE.toml [SCENE.toml ...]      validate scenes, solve nothing
    skfem-rod example [NAME] [--copy DIR]            list, show or copy a shipped example
    skfem-rod sweep SCENE.toml [--scheduler ADDR]    solve the points of its [sweep] on Dask
    skfem-rod demo [NAME] [--out DIR]                run a shipped demo (list without NAME)
    skfem-rod --version

The examples (scenes and demo scripts) are installed with the package
(:mod:`skfem_rod.examples`).  Progress goes through :mod:`logging` (logger
``skfem_rod``): one line per load step on a terminal or with ``-v``.

Exit codes: 0 success, 2 bad input (the message is printed, no traceback),
3 the solve stopped before the end of the load path (the converged steps
are written, and where it stopped is printed), 130 interrupted (Ctrl-C)
and 143 terminated (SIGTERM), the steps converged so far written.

``run`` checks the output directory before it solves (and removes the
files an earlier run of the same basename left there), then writes every
converged step as it arrives: the ``.pvd`` lists exactly the complete VTU
files, so a run stopped at any point leaves a readable series.  The scene format is in
docs/scenes.md.
"""
import argparse
import contextlib
import importlib.util
import inspect
import logging
import os
import sys
import time
import warnings

from . import __version__, examples
from .scene import load_scene, step_figures

OK, BAD_INPUT, SOLVE_FAILED = 0, 2, 3


log = logging.getLogger("skfem_rod.cli")


def _err(msg):
    print(f"skfem-rod: {msg}", file=sys.stderr)


def _log_to_terminal(level):
    """Show the package's log records (logger ``skfem_rod``) for one
    command: below WARNING on stdout as plain lines, warnings on stderr
    (Python warnings too, e.g. an Uzawa shortfall, as one line without a
    source location).  Returns the function that undoes it."""
    pkg = logging.getLogger("skfem_rod")
    out = logging.StreamHandler(sys.stdout)
    out.addFilter(lambda record: record.levelno < logging.WARNING)
    out.setFormatter(logging.Formatter("%(message)s"))
    err = logging.StreamHandler(sys.stderr)
    err.setLevel(logging.WARNING)
    err.setFormatter(logging.Formatter("skfem-rod: %(levelname)s: %(message)s"))
    before = pkg.level, pkg.propagate
    pkg.setLevel(level)
    pkg.propagate = False
    pkg.addHandler(out)
    pkg.addHandler(err)
    showwarning = warnings.showwarning
    warnings.showwarning = lambda message, category, *where, **kw: log.warning(
        "%s", message)

    def undo():
        warnings.showwarning = showwarning
        pkg.removeHandler(out)
        pkg.removeHandler(err)
        pkg.setLevel(before[0])
        pkg.propagate = before[1]
    return undo


def _needs_render(err, alternative=""):
    """A missing optional rendering package, said with the fix."""
    _err(f"rendering needs the optional package {err.name!r}: "
         f"pip install 'skfem_rod[render]'{alternative}")
    return BAD_INPUT


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
    d = scene.data
    log.info(f"{scene.name}: {d['rod']['geometry']['type']} rod, "
             f"{d['rod']['n_elements']} elements, {len(d['support'])} support(s), "
             f"{len(d['load'])} load(s), contact "
             f"{'on' if (d.get('contact') or {}).get('enabled') else 'off'}")
    directory = scene.output_directory(args.out)
    try:        # before the solve: a directory that takes no files loses nothing
        stream = scene.open_output(args.out)
    except (OSError, ValueError) as err:
        _err(f"cannot write to the output directory {directory!r}: "
             f"{getattr(err, 'strerror', None) or err}")
        return BAD_INPUT
    t0 = time.perf_counter()
    # a line per load step: INFO on a terminal, DEBUG (shown with -v) otherwise
    step_level = logging.INFO if sys.stdout.isatty() else logging.DEBUG
    talk = log.isEnabledFor(step_level)

    def on_step(res, k):                 # each converged step: to disk, then a line
        stream.step(res, k)
        if talk:
            log.log(step_level, progress_line(res.steps[k], k))

    try:
        with _interrupts_as_keyboard_interrupt():
            result = scene.solve(callback=on_step)
            wall = time.perf_counter() - t0
            written = stream.finish(result, wall_time=wall)
    except KeyboardInterrupt as stop:
        return _interrupted(stop, stream, directory, time.perf_counter() - t0)
    except ModuleNotFoundError as err:
        return _needs_render(err, " (or set render = false in [output])")
    except MemoryError:
        _err("out of memory: the scene is too large for this machine (fewer elements "
             "or load steps)")
        return BAD_INPUT
    except OSError as err:
        _err(f"cannot write the output: {err}")
        return BAD_INPUT
    except (ValueError, TypeError, ArithmeticError) as err:
        kept = len(stream.result.steps) if stream.result is not None else 0
        _err(f"the run failed: {err}"
             + (f" ({kept} converged step(s) written to {directory})"
                if kept and stream.entries else ""))
        return SOLVE_FAILED
    if not result.converged:
        _err(f"the solve stopped: {result.message}")
        if written:
            _err(f"wrote the {len(result.steps)} converged step(s) to "
                 + _files(written, directory))
        return SOLVE_FAILED
    log.info(f"{result.message} ({wall:.2f} s)")
    if written:
        log.info("wrote " + _files(written, directory))
    else:
        log.warning("wrote nothing: the scene has no [output] table (or asks for no "
                 "file); add one, or pass --out DIR for the JSON summary, VTU "
                 "series and render")
    return OK


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the run is (like Ctrl-C) so that it stops the
    same way: the steps kept so far are written, temporary files removed."""


@contextlib.contextmanager
def _interrupts_as_keyboard_interrupt():
    """SIGTERM raises :class:`Terminated` (a KeyboardInterrupt) for the
    duration of the block; SIGINT raises KeyboardInterrupt as usual."""
    import signal

    def term(signum, frame):
        raise Terminated()
    try:
        before = signal.signal(signal.SIGTERM, term)
    except ValueError:                  # not the main thread: leave signals alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, before)


def _interrupted(stop, stream, directory, wall):
    """Ctrl-C (exit 130) or SIGTERM (exit 143): the kept steps are already
    on disk; write the JSON summary of them, say so."""
    import signal
    signum = signal.SIGTERM if isinstance(stop, Terminated) else signal.SIGINT
    what = "terminated (SIGTERM)" if signum == signal.SIGTERM else "interrupted (Ctrl-C)"
    kept = len(stream.result.steps) if stream.result is not None else 0
    try:
        with _interrupts_as_keyboard_interrupt():
            written = stream.interrupted(
                f"{what} after {kept} converged step(s)", wall_time=wall)
    except KeyboardInterrupt:           # a second signal: stop writing at once
        written = []
        stream.remove_temporary()
    except (OSError, ValueError) as err:
        _err(f"cannot write the summary: {err}")
        written = []
    _err(f"{what}: {kept} converged step(s) kept"
         + (f"; wrote {_files(written, directory)}" if written else ""))
    return 128 + signum


def cmd_check(args):
    """Every scene is checked (not only up to the first bad one); exit 2 if
    any is invalid."""
    code = OK
    for path in args.scene:
        scene = _load(path)
        if scene is None:
            code = BAD_INPUT
        else:
            print(f"{path}: valid scene {scene.name!r}")
    return code


def cmd_sweep(args):
    """Solve the scene at every point of its [sweep] table on Dask: a line
    per finished point, each point written as it finishes, the points
    already done skipped; exit 3 if a point stopped (all are recorded)."""
    import signal
    scene = _load(args.scene)
    if scene is None:
        return BAD_INPUT
    if args.workers is not None and args.workers < 1:
        _err(f"--workers {args.workers}: expected an integer >= 1")
        return BAD_INPUT
    if "sweep" not in scene.data:
        _err(f"{args.scene}: no [sweep] table: add one with the scene keys to vary, e.g. "
             '[sweep] "contact.gamma_T" = [0.0, 0.1, 0.2] (docs/sweep.md)')
        return BAD_INPUT
    os.environ.setdefault("DASK_LOGGING__DISTRIBUTED", "warning")   # Dask's own chatter
    # SIGTERM: stop like Ctrl-C, closing the workers (finished points are on disk)
    def term(*_):
        from .sweeps import STOP
        STOP.request(128 + signal.SIGTERM)
        sys.exit(128 + signal.SIGTERM)
    before = signal.signal(signal.SIGTERM, term)
    try:
        from .sweeps import sweep, sweep_directory
        ds = sweep(scene, out=args.out, scheduler=args.scheduler, n_workers=args.workers,
                   resume=not args.restart, centreline=args.centreline, vtu=args.vtu)
    except ModuleNotFoundError as err:
        _err(f"sweeps need the optional package {err.name!r}: pip install "
             "'skfem_rod[sweep]'")
        return BAD_INPUT
    except OSError as err:
        _err(f"cannot run the sweep: {err}")
        return BAD_INPUT
    finally:
        signal.signal(signal.SIGTERM, before)
    stopped = int((~ds.converged.values).sum())
    log.info(f"{ds.converged.size} points, {stopped} stopped; wrote "
             + os.path.join(sweep_directory(scene, args.out), "sweep.nc"))
    return SOLVE_FAILED if stopped else OK


def demos_dir():
    """The folder of the shipped demo scripts (``skfem_rod/examples/demos``;
    ``demos/`` in a source checkout points there)."""
    return examples.DEMOS


def cmd_example(args):
    """List the examples, print where one is installed, or copy it."""
    available = examples.names()
    if args.name is None:
        print("scenes: " + ", ".join(examples.scenes()))
        print("demos:  " + ", ".join(examples.demos()))
        print("copy one with: skfem-rod example NAME --copy DIR")
        return OK
    if args.name not in available:
        _err(examples.unknown(args.name, available))
        return BAD_INPUT
    if args.copy is None:
        for path in examples.files(args.name):
            print(path)
        return OK
    try:
        written = examples.copy(args.name, args.copy)
    except OSError as err:
        _err(f"cannot copy to {args.copy}: {err.strerror or err}")
        return BAD_INPUT
    for path in written:
        print(f"wrote {path}")
    scene = [p for p in written if p.suffix == ".toml"]
    if scene:
        print(f"run it with: skfem-rod run {scene[0]}")
    return OK


def cmd_demo(args):
    folder = demos_dir()
    if not folder.is_dir():
        _err(f"no demos found (looked in {folder}): the package's examples are missing; "
             "reinstall skfem_rod")
        return BAD_INPUT
    names = examples.demos(folder)
    if args.name is None:
        print("demos: " + ", ".join(names))
        return OK
    if args.name not in names:
        _err(examples.unknown(args.name, names).replace("example", "demo", 1))
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
    try:
        ret = main(**kwargs)
    except ModuleNotFoundError as err:
        if err.name not in ("pyvista", "vtk", "vtkmodules", "PIL"):
            raise
        return _needs_render(err)
    if isinstance(ret, dict) and ret.get("converged") is False:
        return SOLVE_FAILED
    return OK


def parser():
    p = argparse.ArgumentParser(
        prog="skfem-rod",
        description="Geometrically exact rods with self-contact: solve TOML scenes "
                    "(format: docs/scenes.md) and run the demos.",
        epilog="exit codes: 0 success, 2 bad input, 3 the solve stopped early, "
               "130 interrupted (Ctrl-C), 143 terminated (SIGTERM)")
    p.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
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
    r.add_argument("-v", "--verbose", action="store_true",
                   help="also print a line per load step when stdout is not a terminal")
    r.set_defaults(func=cmd_run)
    c = sub.add_parser("check", help="validate scenes without solving them",
                       description="Validate every key of each SCENE and build the rod "
                                   "(boundary conditions); exit 0 if all are valid, 2 "
                                   "if any is not (each one is reported).")
    c.add_argument("scene", metavar="SCENE.toml", nargs="+", help="scene file(s)")
    c.set_defaults(func=cmd_check)
    w = sub.add_parser("sweep", help="solve a scene at every point of its [sweep] table",
                       description="Solve SCENE at every point of its [sweep] table (grid "
                                   "or zip of scene keys) on Dask: an in-process "
                                   "LocalCluster, or a running cluster (--scheduler). "
                                   "Each point is written to OUT/points/ as it finishes; "
                                   "a re-run skips the points done. The dataset (one "
                                   "dimension per swept key, plus step) is OUT/sweep.nc. "
                                   "Exit codes: 0 all points converged, 2 invalid scene "
                                   "or no cluster, 3 a point stopped (it is recorded).")
    w.add_argument("scene", metavar="SCENE.toml", help="scene file with a [sweep] table")
    w.add_argument("--out", metavar="DIR",
                   help="output directory (default: the scene's output directory/sweep)")
    w.add_argument("--scheduler", metavar="ADDR",
                   help="address of a running Dask scheduler, e.g. tcp://host:8786 "
                        "(default: a local cluster)")
    w.add_argument("--workers", metavar="N", type=int,
                   help="worker processes of the local cluster (default: the CPUs)")
    w.add_argument("--centreline", action="store_true",
                   help="also keep the nodal positions of every step (larger files)")
    w.add_argument("--vtu", action="store_true",
                   help="also write each point's VTU series to OUT/points/KEY/ (on a "
                        "cluster: OUT on a file system the workers share)")
    w.add_argument("--restart", action="store_true",
                   help="recompute every point (default: skip the points in OUT/points)")
    w.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    w.set_defaults(func=cmd_sweep)
    e = sub.add_parser("example", help="list, locate or copy the shipped examples",
                       description="Without NAME: list the scenes and demos installed "
                                   "with the package. With NAME: print where its files "
                                   "are, or copy them into DIR with --copy (then e.g. "
                                   "skfem-rod run DIR/NAME.toml).")
    e.add_argument("name", metavar="NAME", nargs="?", help="example name, e.g. bend45")
    e.add_argument("--copy", metavar="DIR", help="copy the example's files into DIR")
    e.set_defaults(func=cmd_example)
    d = sub.add_parser("demo", help="run a shipped demo script",
                       description="Run the demo NAME's main() (without NAME: list the "
                                   "demos; skfem-rod example NAME --copy DIR copies its "
                                   "script).")
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
    level = (logging.ERROR if getattr(args, "quiet", False)
             else logging.DEBUG if getattr(args, "verbose", False) else logging.INFO)
    undo = _log_to_terminal(level)
    try:                                  # never a traceback: say what failed
        return args.func(args)
    except KeyboardInterrupt:
        _err("interrupted")
        return 130
    except MemoryError:
        _err("out of memory")
        return BAD_INPUT
    except (ValueError, TypeError) as err:
        _err(str(err))
        return BAD_INPUT
    except Exception as err:              # a bug: name it, no traceback
        _err(f"unexpected error ({type(err).__name__}: {err}); please report it with "
             "the scene")
        return SOLVE_FAILED
    finally:
        undo()


if __name__ == "__main__":
    sys.exit(main())
