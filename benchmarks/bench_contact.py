"""Cost of one Newton iteration with self-contact, split into internal
assembly, contact search, contact assembly and linear solve.

Scene: a coil (helix of 10 turns, coil radius 0.1) whose turns overlap by
10% of the contact distance, so every slave point is in contact: a dense
contact case (every point has a master on the neighbouring turns).
Timings are medians over repeats of one full system evaluation (residual +
tangent) and one factorization + solve, read from the solver's phase
timers (`_System.timers`).

    python benchmarks/bench_contact.py [--quick]

writes benchmarks/RESULTS_contact.md.
"""
import argparse
import datetime
import os
import sys
import time
from pathlib import Path

import numpy as np

from skfem_rod import Rod, Section, geometry
from skfem_rod.solver import _System

HERE = Path(__file__).resolve().parent
EPS = 0.001


def scene(n_elements):
    shape = geometry.helix(radius=0.1, pitch=1.9 * EPS, turns=10)
    rod = Rod(shape, Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1, EI2=1, GJ=0.8, radius=EPS),
              n_elements)
    rod.clamp("start").enable_contact()
    return rod


def measure(n, repeats):
    rod = scene(n)
    system = _System(rod)
    system.multipliers[:] = 0.0
    rows = []
    for _ in range(repeats):
        system.timers.clear()
        t0 = time.perf_counter()
        res, K, _, iw = system.evaluate(rod.r0, rod.R0, 1.0)
        t1 = time.perf_counter()
        solve = system.factor(K)
        dy = solve(-res)
        t2 = time.perf_counter()
        tm = dict(system.timers)
        rows.append([tm["internal_assembly"], tm["contact_search"], tm["contact_assembly"],
                     t2 - t1, t1 - t0])
    pairs = iw.contact[0]
    return np.median(np.array(rows), axis=0), pairs.size, pairs.n_candidates, rod.mesh.n_dofs


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    sizes = [100, 300, 1000] if a.quick else [100, 300, 1000, 3000, 5000]
    repeats = 3 if a.quick else 7
    lines = ["# skfem_rod contact benchmarks\n",
             f"Command: `python benchmarks/bench_contact.py{' --quick' if a.quick else ''}`  ",
             f"Date: {datetime.datetime.now().astimezone().isoformat(timespec='seconds')}; "
             f"{os.cpu_count()} cores; load average {os.getloadavg()[0]:.2f}\n",
             __doc__.split("\n\n")[1].replace("\n", " ") + "\n",
             "| elements | dofs | contact pairs | candidates | internal assembly | contact search "
             "| contact assembly | factor + solve | (search + contact asm) / internal |",
             "|---|---|---|---|---|---|---|---|---|"]
    data = []
    for n in sizes:
        (ia, cs, ca, ls, _), m, cand, dofs = measure(n, repeats)
        data.append((n, ia, cs, ca, ls))
        lines.append(f"| {n} | {dofs} | {m} | {cand} | {ia * 1e3:.2f} ms | {cs * 1e3:.2f} ms | "
                     f"{ca * 1e3:.2f} ms | {ls * 1e3:.2f} ms | {(cs + ca) / ia:.2f} |")
        print(lines[-1], flush=True)
    d = np.array(data)
    slopes = [np.polyfit(np.log(d[:, 0]), np.log(d[:, k]), 1)[0] for k in range(1, 5)]
    lines.append("")
    lines.append("Log-log slopes vs elements: internal assembly {:.2f}, contact search {:.2f}, "
                 "contact assembly {:.2f}, factor + solve {:.2f}.".format(*slopes))
    ok = np.all((d[:, 2] + d[:, 3]) < d[:, 1])
    lines.append(f"Target (issue 3): contact search + contact assembly < internal assembly at "
                 f"every size: **{'met' if ok else 'not met'}**.")
    out = HERE / ("RESULTS_contact_quick.md" if a.quick else "RESULTS_contact.md")
    out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines[-2:]))
    print(f"written to {out}")


if __name__ == "__main__":
    main()
