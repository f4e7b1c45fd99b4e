"""Cost of a Newton iteration with friction on and off (issue 4).

Scene: a two-ply plectoneme (``geometry.plectoneme``: plies of superhelix
radius ``0.98 eps``, so they press on each other along their whole length)
used as the reference shape of a rod clamped at one end, with self-contact
on.  One "Newton iteration" is one full system evaluation (internal work,
contact search, normal contact and, with friction, the friction work;
residual and tangent) plus one factorization and solve, at a state a
small step away from the last converged one (random nodal displacements
of 1e-3 eps and spins of 1e-3 rad, seeded), with Uzawa multipliers such
that every slave point in range carries a normal force.  Three cases on
the same rod and state: friction off; tangential friction only
(``gamma_T = 0.3``, ``gamma_R = 0``); tangential and rotational friction
(``gamma_T = 0.3``, ``gamma_R = 0.3 eps``).  The cases are measured in
turn, repeat after repeat (the first case rotating), in one process (so
that a change of the load of a shared machine hits all of them alike);
medians over the repeats (30 up to 300 elements, 15 at 1000, 7 above).
The ratio "on / off" compares the medians of the same run.  The contact
and friction assemblers keep the sparsity pattern of the last set of
element pairs in contact (it seldom changes between Newton iterations);
the medians are of such iterations, and the column "friction asm, new
pattern" gives the friction assembly with that pattern rebuilt (the first
iteration after the contact set changed; median of 3).

    python benchmarks/bench_friction.py [--quick]

writes benchmarks/RESULTS_friction.md (not with --quick).
"""
import argparse
import datetime
import os
import sys
import time
from pathlib import Path

import numpy as np

from skfem_rod import Rod, Section, geometry
from skfem_rod.rotations import expm
from skfem_rod.problem import Problem

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_statics import machine_info  # noqa: E402

EPS = 0.01
CASES = {"off": dict(),
         "on (T)": dict(gamma_T=0.3, gamma_R=0.0),
         "on (T+R)": dict(gamma_T=0.3, gamma_R=0.3 * EPS)}


def scene(n_elements):
    shape = geometry.plectoneme(radius=0.98 * EPS, ply_angle=0.4, turns=6)
    rod = Rod(shape, Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1, EI2=1, GJ=0.8, radius=EPS),
              n_elements)
    rod.clamp("start")
    return rod


def systems(rod):
    """One system per case, all on ``rod`` (one mesh; each system keeps
    its own pattern caches, ``Problem.contact_patterns``)."""
    out = {}
    for name, options in CASES.items():
        rod.enable_contact(**options)
        out[name] = Problem(rod)
        out[name].multipliers.normal[:] = 0.5 * EPS / rod.contact.penalty * 0.1
    return out


def iteration(system, r, R):
    system.timers.clear()
    t0 = time.perf_counter()
    ev = system.evaluate(r, R, 1.0)
    res, K = ev.residual, ev.tangent
    t1 = time.perf_counter()
    solve = system.factor(K)
    solve(-res)
    t2 = time.perf_counter()
    tm = system.timers
    row = [tm["internal_assembly"], tm["contact_search"], tm["contact_assembly"],
           tm["friction_assembly"], t2 - t1, t2 - t0]
    return row, ev


def measure(n, repeats):
    """Medians per case ``(6,)``, active pairs, cold friction assembly time."""
    rod = scene(n)
    sy = systems(rod)
    rng = np.random.default_rng(0)
    r = rod.r0 + 1e-3 * EPS * rng.normal(size=rod.r0.shape)
    R = expm(1e-3 * rng.normal(size=rod.r0.shape)) @ rod.R0
    for s in sy.values():                         # warm-up
        _, ev = iteration(s, r, R)
    cold = {name: [] for name in sy if name != "off"}     # friction pattern rebuilt
    for _ in range(3):
        for name in cold:
            sy[name].contact_patterns.friction.clear()
            cold[name].append(iteration(sy[name], r, R)[0][3])
    cold = {name: np.median(v) for name, v in cold.items()}
    rows = {name: [] for name in sy}
    names = list(sy)
    for k in range(repeats):                      # in turn, the first case rotating
        for name in names[k % 3:] + names[:k % 3]:
            rows[name].append(iteration(sy[name], r, R)[0])
    fN = ev.contact.fN
    return ({k: np.median(np.array(v), axis=0) for k, v in rows.items()},
            int((fN > 0).sum()), cold)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sizes, 3 repeats, no file written")
    a = ap.parse_args(argv)
    sizes = [100, 300] if a.quick else [100, 300, 1000, 3000, 5000]
    info = machine_info()
    lines = ["| elements | active pairs | friction | internal asm | search | contact asm "
             "| friction asm | factor + solve | iteration | on / off "
             "| friction asm, new pattern |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    ms = lambda x: f"{1e3 * x:.1f} ms"                       # noqa: E731
    ratios = {k: [] for k in CASES if k != "off"}
    for n in sizes:
        reps = 3 if a.quick else (30 if n <= 300 else 15 if n <= 1000 else 7)
        med, pairs, cold = measure(n, reps)
        for name, t in med.items():
            ratio = f"{t[5] / med['off'][5]:.2f}" if name != "off" else ""
            if name != "off":
                ratios[name].append(t[5] / med["off"][5])
            lines.append(f"| {n} | {pairs} | {name} | " + " | ".join(ms(x) for x in t)
                         + f" | {ratio} | {ms(cold[name]) if name != 'off' else ''} |")
            print(lines[-1], flush=True)
    worst = max(max(v) for v in ratios.values())
    verdict = ("**Target met**" if worst <= 1.5 else "**Target not met**") + \
        f" (largest on / off ratio {worst:.2f}): " + "; ".join(
            f"{k}: " + ", ".join(f"{x:.2f}" for x in v) for k, v in ratios.items()) + \
        f" at {', '.join(str(n) for n in sizes)} elements."
    text = "\n".join([
        "# Friction on/off: cost of a Newton iteration", "",
        "Command: `python benchmarks/bench_friction.py" + (" --quick" if a.quick else "") + "`",
        f"Date: {datetime.datetime.now(datetime.timezone.utc).isoformat(timespec='seconds')}", "",
        "| machine | |", "|---|---|", *(f"| {k} | {v} |" for k, v in info), "",
        " ".join(__doc__.split("\n\n")[1].split()), "",
        *lines, "",
        "Target (issue 4): friction adds at most 50 % to a frictionless iteration "
        "(column on / off <= 1.5).", "", verdict])
    if not a.quick:
        out = HERE / "RESULTS_friction.md"
        tmp = out.with_name(out.name + ".tmp")
        tmp.write_text(text + "\n")
        os.replace(tmp, out)
    print(text)


if __name__ == "__main__":
    sys.exit(main())
