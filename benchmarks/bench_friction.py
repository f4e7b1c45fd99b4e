"""Cost of a Newton iteration with friction on and off (issue 4).

Scene: a two-ply plectoneme (``geometry.plectoneme``: plies of superhelix
radius ``0.98 eps``, so they press on each other along their whole length)
used as the reference shape of a rod clamped at one end, with self-contact
on.  One "Newton iteration" is one full system evaluation (internal work,
contact search, normal contact and, with friction, the friction work;
residual and tangent) plus one factorization and solve, at a state a
small step away from the last converged one (random nodal displacements
of 1e-3 eps and spins of 1e-3 rad, seeded), with Uzawa multipliers such
that every slave point in range carries a normal force.  Friction on:
``gamma_T = 0.3``, ``gamma_R = 0.3 eps``.  Medians over repeats; the
ratio "on / off" compares two runs made in the same process.

    python benchmarks/bench_friction.py [--quick]

writes benchmarks/RESULTS_friction.md.
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
from skfem_rod.solver import _System

HERE = Path(__file__).resolve().parent
EPS = 0.01


def scene(n_elements, friction):
    shape = geometry.plectoneme(radius=0.98 * EPS, ply_angle=0.4, turns=6)
    rod = Rod(shape, Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1, EI2=1, GJ=0.8, radius=EPS),
              n_elements)
    rod.clamp("start")
    if friction:
        rod.enable_contact(gamma_T=0.3, gamma_R=0.3 * EPS)
    else:
        rod.enable_contact()
    return rod


def measure(n, friction, repeats):
    rod = scene(n, friction)
    system = _System(rod)
    rng = np.random.default_rng(0)
    r = rod.r0 + 1e-3 * EPS * rng.normal(size=rod.r0.shape)
    R = expm(1e-3 * rng.normal(size=rod.r0.shape)) @ rod.R0
    system.multipliers[:] = 0.5 * EPS / rod.contact.penalty * 0.1
    rows = []
    for _ in range(repeats):
        system.timers.clear()
        t0 = time.perf_counter()
        res, K, _, iw = system.evaluate(r, R, 1.0)
        t1 = time.perf_counter()
        solve = system.factor(K)
        solve(-res)
        t2 = time.perf_counter()
        tm = system.timers
        rows.append([tm["internal_assembly"], tm["contact_search"], tm["contact_assembly"],
                     tm["friction_assembly"], t2 - t1, t2 - t0])
    pairs, fN, _ = iw.contact
    return np.median(np.array(rows), axis=0), int((fN > 0).sum())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small sizes, one repeat")
    a = ap.parse_args(argv)
    sizes = [100, 300] if a.quick else [100, 300, 1000, 3000, 5000]
    lines = ["| elements | active pairs | friction | internal asm | search | contact asm "
             "| friction asm | factor + solve | iteration | on / off |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    ms = lambda x: f"{1e3 * x:.1f} ms"                       # noqa: E731
    for n in sizes:
        reps = 1 if a.quick else (5 if n <= 1000 else 3)
        off, m_off = measure(n, False, reps)
        on, m_on = measure(n, True, reps)
        for tag, t, m in (("off", off, m_off), ("on", on, m_on)):
            ratio = f"{on[5] / off[5]:.2f}" if tag == "on" else ""
            lines.append(f"| {n} | {m} | {tag} | " + " | ".join(ms(x) for x in t) + f" | {ratio} |")
        print(lines[-2], lines[-1], sep="\n", flush=True)
    text = "\n".join([
        "# Friction on/off: cost of a Newton iteration", "",
        "Command: `python benchmarks/bench_friction.py`" + (" --quick" if a.quick else ""),
        f"Date: {datetime.datetime.now(datetime.timezone.utc).isoformat(timespec='seconds')}; "
        f"{os.cpu_count()} cores; load average {os.getloadavg()[0]:.2f}", "",
        __doc__.split("\n\n")[1].replace("\n", " "), "",
        *lines, "",
        "Target (issue 4): friction adds at most 50 % to a frictionless iteration "
        "(column on / off <= 1.5)."])
    if not a.quick:
        (HERE / "RESULTS_friction.md").write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    sys.exit(main())
