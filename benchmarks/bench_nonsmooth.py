"""The contact solve: Uzawa (the paper's iteration, ``contact_solve="uzawa"``)
against the generalized Newton on the Alart-Curnier augmented Lagrangian
(:mod:`skfem_rod.nonsmooth`) with the normal and friction multipliers as
unknowns (``contact_solve="newton"``) and with the normal ones only, the
friction ones updated by Uzawa between solves (``"newton_normal"``), on the
contact and friction scenes of the test suite and the demos.

Scenes (each solved in the three modes, the modes in turn, reversed repeat
after repeat, in one process so that a change of the machine's load hits
all):

* ``hairpin``: the pressed hairpin of tests/test_contact.py (40 elements,
  frictionless), pressed closed and released in 12 steps (path 0 -> 1 -> 0),
  at the default gap tolerance (1e-3 eps) and at 1e-7 eps;
* ``squeezed loop``: demos/squeezed_loop.py (48 elements, frictionless,
  16 steps 0 -> 1 -> 0, ``snap="relax"``);
* ``rotational friction``: demos/rotational_friction.py at the test size
  (32 elements, 8 steps, gamma_R = eps);
* ``plectoneme cycle``: demos/plectoneme_friction.py at the test size
  (16 elements, gamma_T = 0.3, 1.5 turns up and back in 12 steps,
  ``snap="relax"``, ``stability=True``).

Per scene and mode: converged, accepted steps, Newton iterations (all
inner solves: load steps, Uzawa passes, gradient-flow steps), median Newton
iterations per step, Uzawa updates (total, and steps that hit
``max_uzawa``), failed inner solves, residual histories with a 2-cycle
(values alternating with period 2 within 5 %, more than 20 % apart, above
1e-8; in the generalized Newton / in the plain Newton of the gradient flow,
which has a viscous term and is the same in both modes), largest
penetration (units of eps), wall
time (median over the repeats).  Ratios "newton / uzawa" and
"newton_normal / uzawa" are of medians of the same run.

    python benchmarks/bench_nonsmooth.py [--quick]

writes benchmarks/RESULTS_nonsmooth.md (not with --quick: hairpins only).
"""
import argparse
import datetime
import os
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))

import skfem_rod.dynamics as dynamics_mod    # noqa: E402
import skfem_rod.newton as newton_mod        # noqa: E402
import skfem_rod.relax as relax_mod          # noqa: E402
import skfem_rod.solver as solver_mod        # noqa: E402
from skfem_rod import Rod                    # noqa: E402
from skfem_rod.options import make_options   # noqa: E402

MODES = ("uzawa", "newton_normal", "newton")


def two_cycles(h, floor=1e-8):
    h = np.asarray(h)
    return [k for k in range(3, h.size)
            if h[k] > floor and abs(h[k] / h[k - 2] - 1) < 0.05
            and abs(h[k - 1] / h[k - 3] - 1) < 0.05 and abs(h[k] / h[k - 1] - 1) > 0.2]


class Spy:
    """Every inner Newton solve's report (load steps, Uzawa passes, flow),
    with whether the solve had the gradient flow's viscous term."""

    def __init__(self):
        self.reports = []
        self.viscous = []
        self._orig = {}

    def __enter__(self):
        # load steps and Uzawa passes (augmented.step imports newton at the
        # call), the gradient flow, the damped steps
        for mod in (newton_mod, relax_mod, dynamics_mod):
            orig = mod.newton
            self._orig[mod] = orig

            def spy(problem, *a, _orig=orig, **k):
                viscous = problem.viscous is not None
                out = _orig(problem, *a, **k)
                self.reports.append(out[3])
                self.viscous.append(viscous)
                return out
            mod.newton = spy
        return self

    def __exit__(self, *exc):
        for mod, orig in self._orig.items():
            mod.newton = orig


def with_mode(mode, run):
    """Run ``run()`` with every solve of it in contact-solve ``mode``."""
    orig = solver_mod.make_options
    solver_mod.make_options = lambda kw: make_options({**kw, "contact_solve": mode})
    try:
        with Spy() as spy:
            t0 = time.perf_counter()
            res = run()
            wall = time.perf_counter() - t0
    finally:
        solver_mod.make_options = orig
    return res, wall, spy.reports, spy.viscous


def hairpin(tolerance):
    from test_contact import SEC, hairpin as shape

    def run():
        eps = SEC.radius
        rod = Rod(shape(eps, 4 * eps), SEC, 40)
        rod.clamp("start").add_force("end", [0, -0.6, 0]).enable_contact(tolerance=tolerance)
        return rod.solve(n_steps=12, path=[0, 1, 0])
    return run


def squeezed():
    from helpers import load_demo
    d = load_demo("squeezed_loop")
    return lambda: d.solve()["result"]


def rotational():
    from helpers import load_demo
    rf = load_demo("rotational_friction")
    return lambda: rf.solve(n_elements=32, n_steps=8, phi=0.06)["result"]


def plectoneme():
    from helpers import load_demo
    pf = load_demo("plectoneme_friction")
    return lambda: pf.solve(0.3, n_elements=16, turns=1.5, n_steps=6)["result"]


def figures(res, wall, reports, viscous):
    steps = res.steps[1:]
    c = [st.contact for st in steps if st.contact is not None]
    eps = res.rod.contact.radius
    per_step = [x.newton_total for x in c]
    return dict(
        converged=bool(res.converged), steps=len(steps),
        newton=int(sum(r.iterations for r in reports)),
        median_step=float(np.median(per_step)) if per_step else 0.0,
        uzawa=int(sum(x.uzawa for x in c)),
        uzawa_limit=int(sum(not x.uzawa_converged for x in c)),
        failed=int(sum(not r.converged for r in reports)),
        cycles=int(sum(bool(two_cycles(r.history)) for r, v in zip(reports, viscous) if not v)),
        cycles_flow=int(sum(bool(two_cycles(r.history)) for r, v in zip(reports, viscous) if v)),
        penetration=float(max((x.penetration for x in c), default=0.0)) / eps,
        wall=wall)


def measure(name, make, repeats):
    run = make()
    rows = {m: [] for m in MODES}
    for k in range(repeats):
        order = MODES if k % 2 == 0 else MODES[::-1]
        for mode in order:
            rows[mode].append(figures(*with_mode(mode, run)))
            print(f"  {name} {mode}: {rows[mode][-1]}", flush=True)
    out = {}
    for mode in MODES:
        f = dict(rows[mode][0])
        f["wall"] = float(np.median([r["wall"] for r in rows[mode]]))
        out[mode] = f
    return out


def table(results):
    head = ("| scene | solve | converged | steps | Newton its | median its/step | "
            "Uzawa updates | steps at max_uzawa | failed solves | 2-cycling solves (flow) | "
            "penetration / eps | time (s) |\n" + "|---" * 12 + "|\n")
    lines = []
    for name, r in results.items():
        for mode in MODES:
            f = r[mode]
            lines.append(f"| {name} | {mode} | {'yes' if f['converged'] else 'NO'} | "
                         f"{f['steps']} | {f['newton']} | {f['median_step']:g} | {f['uzawa']} | "
                         f"{f['uzawa_limit']} | {f['failed']} | {f['cycles']} ({f['cycles_flow']}) | "
                         f"{f['penetration']:.1e} | {f['wall']:.2f} |")
    ratios = ["", "| scene | Newton its newton/uzawa | time newton/uzawa | "
                  "Newton its newton_normal/uzawa | time newton_normal/uzawa |",
              "|---|---|---|---|---|"]
    for name, r in results.items():
        u, n, nn = r["uzawa"], r["newton"], r["newton_normal"]
        ratios.append(f"| {name} | {n['newton'] / max(u['newton'], 1):.2f} | "
                      f"{n['wall'] / u['wall']:.2f} | "
                      f"{nn['newton'] / max(u['newton'], 1):.2f} | "
                      f"{nn['wall'] / u['wall']:.2f} |")
    return head + "\n".join(lines) + "\n" + "\n".join(ratios) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="hairpins only, no file written")
    args = ap.parse_args()
    scenes = [("hairpin, tol 1e-3 eps", lambda: hairpin(1e-3), 5),
              ("hairpin, tol 1e-7 eps", lambda: hairpin(1e-7), 5)]
    if not args.quick:
        scenes += [("rotational friction", rotational, 3),
                   ("squeezed loop", squeezed, 1),
                   ("plectoneme cycle, gamma_T 0.3", plectoneme, 1)]
    results = {}
    t0 = time.perf_counter()
    for name, make, repeats in scenes:
        results[name] = measure(name, make, repeats)
    text = table(results)
    print(text)
    if args.quick:
        return
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    md = (f"# Contact solve: Uzawa against the generalized Newton\n\n"
          f"Written by `python benchmarks/bench_nonsmooth.py` on "
          f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC "
          f"(load average {load:.1f} on a shared 2-core machine; whole run "
          f"{time.perf_counter() - t0:.0f} s).  Scenes and columns: the script's "
          f"docstring; discussion: docs/contact-solve.md.  Times are medians over "
          f"the repeats (hairpins 5, rotational friction 3, the others 1), the "
          f"modes alternating.\n\n" + text)
    (HERE / "RESULTS_nonsmooth.md").write_text(md)


if __name__ == "__main__":
    main()
