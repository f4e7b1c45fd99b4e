"""Scaling of a Newton iteration with self-contact (issue 5, item 3): the
plectoneme of ``bench_contact.py`` (superhelix radius 0.98 eps, ply angle
0.05 rad, 15 turns) at 10 to 10,000 elements.  One iteration = one full
system evaluation (internal work, contact search, contact assembly;
residual and tangent) plus one factorization and solve, at the reference
configuration (every ply point in contact).  Medians of 3; peak memory
of one iteration by ``tracemalloc`` (a separate run: tracing slows numpy).

    python benchmarks/scaling_contact.py [--quick]

writes benchmarks/RESULTS_scaling_contact.md.
"""
import argparse
import datetime
import os
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_contact import plectoneme_scene                      # noqa: E402

from skfem_rod.problem import Problem                            # noqa: E402

HERE = Path(__file__).resolve().parent


def iteration(system, rod):
    system.timers.clear()
    t0 = time.perf_counter()
    ev = system.evaluate(rod.r0, rod.R0, 1.0)
    res, K = ev.residual, ev.tangent
    t1 = time.perf_counter()
    system.factor(K)(-res)
    t2 = time.perf_counter()
    tm = system.timers
    return [tm["internal_assembly"], tm["contact_search"], tm["contact_assembly"],
            t2 - t1, t2 - t0], int((ev.contact.fN > 0).sum())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    sizes = [10, 100, 1000] if a.quick else [10, 30, 100, 300, 1000, 3000, 10000]
    lines = ["| elements | dofs | active pairs | internal asm | search | contact asm "
             "| factor + solve | iteration | peak memory |",
             "|---|---|---|---|---|---|---|---|---|"]
    data = []
    for n in sizes:
        rod = plectoneme_scene(n)
        system = Problem(rod)
        iteration(system, rod)                      # warm-up (caches, imports)
        rows = []
        for _ in range(3):
            t, m = iteration(system, rod)
            rows.append(t)
        med = np.median(np.array(rows), axis=0)
        tracemalloc.start()
        iteration(system, rod)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        data.append([n, *med, peak])
        lines.append(f"| {n} | {rod.mesh.n_dofs} | {m} | " + " | ".join(
            f"{1e3 * x:.1f} ms" for x in med) + f" | {peak / 2**20:.1f} MiB |")
        print(lines[-1], flush=True)
    d = np.array(data)
    big = d[:, 0] >= 100
    names = ["internal asm", "search", "contact asm", "factor + solve", "iteration",
             "peak memory"]
    slopes = [np.polyfit(np.log(d[big, 0]), np.log(d[big, k]), 1)[0] for k in range(1, 7)]
    text = "\n".join([
        "# Scaling of a Newton iteration with self-contact (plectoneme)", "",
        f"Command: `python benchmarks/scaling_contact.py{' --quick' if a.quick else ''}`  ",
        f"Date: {datetime.datetime.now(datetime.timezone.utc).isoformat(timespec='seconds')}; "
        f"{os.cpu_count()} cores; load average {os.getloadavg()[0]:.2f}", "",
        __doc__.split("\n\n")[0].replace("\n", " "), "", *lines, "",
        f"Log-log slopes from {int(d[big, 0].min())} to {int(d[big, 0].max())} elements: "
        + ", ".join(f"{nm} {sl:.2f}" for nm, sl in zip(names, slopes)) + ".",
        f"Target (issue 5): iteration slope <= 1.15: "
        f"**{'met' if slopes[4] <= 1.15 else 'not met'}**.", ""])
    if not a.quick:
        (HERE / "RESULTS_scaling_contact.md").write_text(text)
    print(text)


if __name__ == "__main__":
    sys.exit(main())
