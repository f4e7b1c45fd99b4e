"""Friction at the crossing pairs: the pulled figure-eight solved with
sliding and sticking crossings by both contact solves, and the cost of
the crossing pairs' friction in one evaluation.

Scene (tests/test_crossing_friction.py, ``sideways``): the figure-eight of
tests/test_core.py (strands crossing at 90 degrees between slave points, 3
eps apart, 60 elements of 9 eps, both ends clamped), pressed together at
the crossing by opposite point forces 0.3 and pulled apart along x there
by opposite forces 0.02; the crossing pair alone carries the contact;
``gamma_T`` 0.05 (the pair slides), 0.1 (slips at the first contact, then
sticks), 1 (sticks); 2 load steps requested.

Per run: steps taken, Newton iterations per step (median / max, of the
recorded last pass), Uzawa updates per step (max), the pair's states over
the steps, ``|F| / (gamma_T f_N)`` at the last step, the material points'
relative displacement over the last step, wall time.  The evaluation
cost: medians of ``repeat`` evaluations (tangent on) at the last state of
the ``gamma_T = 0.1`` run with and without friction at the crossing pair
(contact option ``crossing_friction``), and their ratio.

    .venv/bin/python benchmarks/bench_crossing_friction.py [--repeat 7] \
        [--out benchmarks/RESULTS_crossing_friction.md]
"""
import argparse
import dataclasses
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))

from skfem_rod.problem import Problem                                 # noqa: E402
from test_crossing_friction import PULL, relative, sideways           # noqa: E402
from bench_statics import machine_info                                # noqa: E402


def run(gamma, solve):
    rod = sideways(gamma, PULL)
    t0 = time.perf_counter()
    res = rod.solve(2, contact_solve=solve)
    wall = time.perf_counter() - t0
    steps = res.steps[1:]
    its = [len(st.residual_history) - 1 for st in steps]
    cr = res.steps[-1].contact.crossing if res.converged else None
    states = "".join("OSX"[int(st.contact.crossing.state[0])]          # FrictionState
                     if st.contact.crossing.s.size else "." for st in steps)
    return dict(gamma=gamma, solve=solve, converged=res.converged, message=res.message,
                steps=len(steps), its_median=float(np.median(its)) if its else None,
                its_max=max(its) if its else None,
                uzawa_max=max(st.contact.uzawa for st in steps) if steps else None,
                states=states,
                bound=(float(np.linalg.norm(cr.friction[0]) / (gamma * cr.force[0]))
                       if cr is not None else None),
                apart=float(np.linalg.norm(relative(rod, res))) if cr is not None else None,
                wall=wall, rod=rod, result=res)


def evaluation_cost(run01, repeat):
    rod, res = run01["rod"], run01["result"]
    st, before = res.steps[-1], res.steps[-2]
    out = {}
    for on in (False, True):
        p = Problem(rod)
        p.contact = dataclasses.replace(p.contact, crossing_friction=on)
        p.reference = (before.r, before.R)
        cp = p.evaluate(st.r, st.R, st.load_factor).contact.crossing
        p.multipliers.rekey_crossing(cp.key.copy(), st.contact.crossing.force.copy(),
                                     friction=st.contact.crossing.friction.copy())
        ts, tc = [], []
        for _ in range(repeat):
            p.timers["crossing"] = 0.0
            t0 = time.perf_counter()
            p.evaluate(st.r, st.R, st.load_factor)
            ts.append(time.perf_counter() - t0)
            tc.append(p.timers["crossing"])
        out[on] = (float(np.median(ts)), float(np.median(tc)))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--out", default=None, help="write the report (markdown) here")
    a = ap.parse_args(argv)
    rows = [run(g, s) for s in ("uzawa", "newton") for g in (0.05, 0.1, 1.0)]
    cost = evaluation_cost(next(r for r in rows if r["gamma"] == 0.1
                                and r["solve"] == "uzawa"), a.repeat)
    lines = ["# Friction at the crossing pairs", "",
             f"`python benchmarks/bench_crossing_friction.py --repeat {a.repeat}` "
             f"({time.strftime('%Y-%m-%d')}); scene and columns: the script's docstring.", "",
             "| machine | |", "|---|---|"]
    lines += [f"| {k} | {v} |" for k, v in machine_info()]
    lines += ["", "States per step: S stick, X slip, O open, . no pair.", "",
              "| `contact_solve` | `gamma_T` | converged | steps | Newton its per step "
              "(median / max) | Uzawa updates per step (max) | states | last step: "
              "`|F|` / bound | material points apart over the last step | wall (s) |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        fmt = (lambda x, f: "-" if x is None else format(x, f))             # noqa: E731
        lines.append(f"| {r['solve']} | {r['gamma']:g} | {r['converged']} | {r['steps']} | "
                     f"{fmt(r['its_median'], 'g')} / {fmt(r['its_max'], 'd')} | "
                     f"{fmt(r['uzawa_max'], 'd')} | {r['states']} | {fmt(r['bound'], '.3f')} "
                     f"| {fmt(r['apart'], '.2e')} | {r['wall']:.1f} |")
    (t0, c0), (t1, c1) = cost[False], cost[True]
    lines += ["", f"Evaluation (tangent on) at the last state of the `gamma_T` = 0.1 run, "
              f"medians of {a.repeat}: without friction at the crossing pair {1e3 * t0:.2f} ms "
              f"(crossing part {1e3 * c0:.2f} ms), with it {1e3 * t1:.2f} ms (crossing part "
              f"{1e3 * c1:.2f} ms): ratio {t1 / t0:.2f}."]
    text = "\n".join(lines) + "\n"
    print(text)
    if a.out:
        from skfem_rod.export import atomic_path
        with atomic_path(a.out) as tmp:
            pathlib.Path(tmp).write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
