"""Per-iteration cost of the solver core against the code before it
(issue 12: one problem object, one Newton, one augmented-Lagrangian loop),
and the Newton iterations of slender rods (position correction).

Each measurement runs in a fresh subprocess with ``PYTHONPATH`` at one of
two source trees (this checkout, and ``--old`` = a checkout of the commit
before the core), interleaved repeat by repeat so that the machine's load
hits both alike; medians and their ratio are reported.

Per iteration: one evaluation (residual + tangent, contact and friction
where on) + factorization + solve, on a stressed state (a random smooth
perturbation of the reference, seeded).  Whole solves: the README roll-up
(4 steps) and the 45-degree bend at slenderness 1e4 (4 steps).

    python benchmarks/bench_core.py --old /path/to/old/checkout [--repeats 7]
"""
import argparse
import json
import os
import shlex
import statistics
import subprocess
import sys
import textwrap
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

CHILD = textwrap.dedent(r'''
    import json, sys, time
    import numpy as np
    from skfem_rod import Rod, Section, geometry
    case, n = sys.argv[1], int(sys.argv[2])

    def evaluator(rod):
        try:
            from skfem_rod.problem import Problem
            p = Problem(rod)
            def it(r, R):
                ev = p.evaluate(r, R, 1.0)
                p.factor(ev.tangent)(-ev.residual)
            return it, p
        except ImportError:
            from skfem_rod.solver import _System
            p = _System(rod)
            def it(r, R):
                res, K, _, _ = p.evaluate(r, R, 1.0)
                p.factor(K)(-res)
            return it, p

    sec = Section.circle(E=1e7, nu=0.3, radius=0.01)
    if case in ("statics", "contact", "friction"):
        if case == "statics":
            rod = Rod(geometry.helix(0.2, 0.1, 2.0), sec, n).clamp("start")
            rod.add_force("end", [0.0, 0.0, 1.0], follower=True)
        else:
            eps = 0.01
            rod = Rod(geometry.plectoneme(0.98 * eps, 0.05, 15, loop=100 * eps, tail=200 * eps),
                      Section.circle(E=1e7, nu=0.3, radius=eps), n).clamp("start")
            rod.enable_contact(gamma_T=0.3 if case == "friction" else 0.0)
        rng = np.random.default_rng(0)
        d = 1e-3 * rng.standard_normal((rod.mesh.n_nodes, 6))
        from skfem_rod.rotations import expm
        r, R = rod.r0 + d[:, :3] * 0.01, expm(d[:, 3:]) @ rod.R0
        it, p = evaluator(rod)
        if case != "statics":
            m = getattr(p, "multipliers")
            lam = getattr(m, "normal", m)
            lam[:] = 1e-3
        it(r, R)                                   # warm caches
        ts = []
        for _ in range(5):
            t0 = time.perf_counter(); it(r, R); ts.append(time.perf_counter() - t0)
        print(json.dumps(dict(t=float(np.median(ts)))))
    else:
        if case == "rollup":
            rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), n)
            rod.clamp("start").add_moment("end", [0.0, 0.0, 2 * np.pi * rod.section.EI2])
        else:                                       # bend45 at slenderness 1e4
            L = 100.0 * np.pi / 4
            rad = L / 1e4
            E, G = 1e7, 5e6
            A, I = np.pi * rad**2, np.pi * rad**4 / 4
            s = Section(EA=E * A, GA1=G * A, GA2=G * A, EI1=E * I, EI2=E * I, GJ=G * 2 * I)
            rod = Rod(geometry.arc(100.0, np.pi / 4, start=(0.0, 0.0, 0.0)), s, n).clamp("start")
            rod.add_force("end", [0.0, 0.0, 600.0 * E * I / (1e7 / 12)])
        t0 = time.perf_counter()
        res = rod.solve(4)
        print(json.dumps(dict(t=time.perf_counter() - t0, converged=res.converged,
                              steps=len(res.steps) - 1,
                              iterations=[int(st.iterations) for st in res.steps[1:]])))
''')


def run(tree, case, n):
    env = dict(os.environ, PYTHONPATH=str(tree), MPLBACKEND="Agg")
    out = subprocess.run([sys.executable, "-c", CHILD, case, str(n)], env=env, cwd="/",
                         capture_output=True, text=True, timeout=1800)
    if out.returncode:
        raise RuntimeError(out.stderr[-2000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--old", required=True, help="checkout of the code before the core")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--cases", nargs="+", default=None,
                    help="per-iteration cases as name:elements (default: statics:100 "
                         "statics:1000 contact:200 contact:1000 friction:200 friction:1000)")
    ap.add_argument("--no-solves", action="store_true", help="skip the whole solves")
    ap.add_argument("--title", default="Solver core: per-iteration cost and Newton "
                                       "iterations, before and after")
    ap.add_argument("--out", default=None,
                    help="write the report to this file (default: print it; "
                         "benchmarks/RESULTS_core.md holds the issue-12 record)")
    a = ap.parse_args(argv)
    cases = [("statics", 100), ("statics", 1000), ("contact", 200), ("contact", 1000),
             ("friction", 200), ("friction", 1000)]
    if a.cases:
        cases = [(c.split(":")[0], int(c.split(":")[1])) for c in a.cases]
    rows = []
    for case, n in cases:
        t = {"new": [], "old": []}
        for _ in range(a.repeats):
            for which, tree in (("new", ROOT), ("old", Path(a.old))):
                t[which].append(run(tree, case, n)["t"])
        new, old = statistics.median(t["new"]), statistics.median(t["old"])
        rows.append(f"| {case} | {n} | {old * 1e3:.1f} | {new * 1e3:.1f} | {new / old:.2f} |")
        print(rows[-1], flush=True)
    solves = []
    for case, n in (() if a.no_solves else (("rollup", 16), ("bend45", 8))):
        res = {w: run(tree, case, n) for w, tree in (("old", Path(a.old)), ("new", ROOT))}
        solves.append(f"| {case} | {res['old']['steps']} | {res['old']['iterations']} | "
                      f"{res['old']['t']:.2f} | {res['new']['steps']} | "
                      f"{res['new']['iterations']} | {res['new']['t']:.2f} |")
        print(solves[-1], flush=True)
    lines = [
        f"# {a.title}",
        "",
        "Command: `python benchmarks/bench_core.py "
        + shlex.join(argv if argv is not None else sys.argv[1:])
        + "` (each figure a fresh subprocess; old and new interleaved repeat by repeat "
          "on the shared 2-core machine; medians).",
        "",
        "## One Newton iteration (evaluation + factorization + solve), ms",
        "",
        "| case | elements | before | after | after / before |",
        "|---|---|---|---|---|",
        *rows,
        "",
        "statics: helix with a follower tip force; contact: the plectoneme of "
        "bench_contact.py (multipliers 1e-3); friction: the same with gamma_T = 0.3.",
        ""]
    if solves:
        lines += [
            "## Whole solves (4 load steps requested)",
            "",
            "| case | steps before | iterations per step before | s before | steps after | "
            "iterations per step after | s after |",
            "|---|---|---|---|---|---|---|",
            *solves,
            "",
            "rollup: the README's (`Section.circle(E=1e7, nu=0.3, radius=0.01)`, 16 elements); "
            "bend45: the 45-degree bend with a solid circle of slenderness L / radius = 1e4, "
            "8 elements.",
            ""]
    text = "\n".join(lines)
    if a.out is None:
        print(text)
    else:
        Path(a.out).write_text(text)


if __name__ == "__main__":
    main()
