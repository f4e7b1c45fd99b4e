"""Cost of one Newton iteration with self-contact, split into internal
assembly, contact search, contact assembly and factorization + solve.

Scene (main table): a two-ply plectoneme (`geometry.plectoneme`) used as
the rod's stress-free reference shape, evaluated at that configuration:
contact radius eps = 1e-3, superhelix radius 0.98 eps (the plies
interpenetrate by 0.04 eps, so the pairs along the plies are active),
ply angle 0.05 rad, 15 turns, end loop of half-width 100 eps, tails of
200 eps; rod length 5575 eps.  Second table: the dense coil of the first
benchmark (helix of 10 turns, coil radius 0.1, pitch 1.92 eps: every slave
in contact with the neighbouring turns; pitch 1.9 eps was the limit of the
start overlap `Rod.enable_contact` accepts and was refused on round-off).  Timings are medians over repeats
of one full system evaluation (residual + tangent, `Problem.evaluate`) and
one factorization + solve, read from the solver's phase timers
(`Problem.timers`).  "contact asm" is the warm figure (the CSC pattern of
the contact stiffness cached from the previous evaluation, as in Newton
iterations whose contact element pairs do not change); "cold" clears that
cache before every evaluation.

    python benchmarks/bench_contact.py [--quick]

writes benchmarks/RESULTS_contact.md.
"""
import argparse
import datetime
import os
import time
from pathlib import Path

import numpy as np

from skfem_rod import Rod, Section, geometry
from skfem_rod.problem import Problem

HERE = Path(__file__).resolve().parent
EPS = 1e-3
SECTION = Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1, EI2=1, GJ=0.8, radius=EPS)


def plectoneme_scene(n_elements):
    shape = geometry.plectoneme(0.98 * EPS, 0.05, 15, loop=100 * EPS, tail=200 * EPS)
    return Rod(shape, SECTION, n_elements).clamp("start").enable_contact()


def coil_scene(n_elements):
    shape = geometry.helix(radius=0.1, pitch=1.92 * EPS, turns=10)
    return Rod(shape, SECTION, n_elements).clamp("start").enable_contact()


def measure(scene, n, repeats):
    """Medians (s): internal, search, contact asm (warm), contact asm
    (cold), factor + solve; and pairs, active pairs, candidates, dofs."""
    rod = scene(n)
    system = Problem(rod)
    rows = []
    for cold in (False, True):
        for _ in range(repeats):
            if cold:
                system.contact_patterns.normal.clear()
            system.timers.clear()
            ev = system.evaluate(rod.r0, rod.R0, 1.0)
            res, K = ev.residual, ev.tangent
            tm = dict(system.timers)
            if not cold:
                t1 = time.perf_counter()
                system.factor(K)(-res)
                ls = time.perf_counter() - t1
                rows.append([tm["internal_assembly"], tm["contact_search"],
                             tm["contact_assembly"], np.nan, ls])
            else:
                rows.append([tm["internal_assembly"], tm["contact_search"], np.nan,
                             tm["contact_assembly"], np.nan])
    pairs, fN = ev.contact.pairs, ev.contact.fN
    med = np.nanmedian(np.array(rows), axis=0)
    return med, pairs.size, int((fN > 0).sum()), pairs.n_candidates, rod.mesh.n_dofs


def table(scene, sizes, repeats, lines):
    lines += ["| elements | dofs | pairs | active | candidates | internal assembly | "
              "contact search | contact asm | contact asm (cold) | factor + solve | "
              "(search + asm) / internal | same, cold |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    data = []
    for n in sizes:
        (ia, cs, ca, cc, ls), m, act, cand, dofs = measure(scene, n, repeats)
        data.append((n, ia, cs, ca, cc, ls))
        lines.append(f"| {n} | {dofs} | {m} | {act} | {cand} | {ia * 1e3:.2f} ms | "
                     f"{cs * 1e3:.2f} ms | {ca * 1e3:.2f} ms | {cc * 1e3:.2f} ms | "
                     f"{ls * 1e3:.1f} ms | {(cs + ca) / ia:.2f} | {(cs + cc) / ia:.2f} |")
        print(lines[-1], flush=True)
    d = np.array(data)
    slopes = [np.polyfit(np.log(d[:, 0]), np.log(d[:, k]), 1)[0] for k in range(1, 6)]
    lines.append("")
    lines.append("Log-log slopes vs elements: internal assembly {:.2f}, contact search {:.2f}, "
                 "contact asm {:.2f} (cold {:.2f}), factor + solve {:.2f}.".format(*slopes))
    warm = np.all(d[:, 2] + d[:, 3] < d[:, 1])
    cold = np.all(d[:, 2] + d[:, 4] < d[:, 1])
    lines.append(f"Target (issue 3), contact search + contact assembly < internal assembly at "
                 f"every size: **{'met' if warm else 'not met'}** (warm), "
                 f"**{'met' if cold else 'not met'}** (cold).")
    lines.append("")
    return d


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
             "## Plectoneme\n"]
    table(plectoneme_scene, sizes, repeats, lines)
    lines.append("## Dense coil\n")
    table(coil_scene, sizes[:3] if not a.quick else sizes[:2], repeats, lines)
    lines.append(f"Load average at the end: {os.getloadavg()[0]:.2f}.")
    out = HERE / ("RESULTS_contact_quick.md" if a.quick else "RESULTS_contact.md")
    tmp = out.with_suffix(".tmp")
    tmp.write_text("\n".join(lines) + "\n")
    os.replace(tmp, out)
    print(f"written to {out}")


if __name__ == "__main__":
    main()
