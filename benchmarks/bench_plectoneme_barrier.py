"""The plectoneme of ``bench_plectoneme.py`` by Newton on the total energy
(:mod:`skfem_rod.minimize`), with the smooth node barrier of
:mod:`skfem_rod.contact.barrier` and its lagged Coulomb friction in place
of the paper's augmented-Lagrangian contact: a design experiment of issue
13, not yet a solve option of ``Rod.solve``.

Usage::

    python benchmarks/bench_plectoneme_barrier.py              # 100 and 200 elements,
                                                               # gamma_T = 0 and 0.3
    python benchmarks/bench_plectoneme_barrier.py --elements 100 --gammas 0 --budget 120 --out /tmp/pb

Same rod, supports, loads and twist as ``bench_plectoneme.py`` (dead
tension, lateral imperfection, the end turned 10 times), the rod's own
contact off and the barrier (width 0.02 r, a pair's force 1.0 at half the
width) added to its energy; steps of 1/16 turn, each solved by
:meth:`skfem_rod.minimize.EnergySolve.step` (secant predictor, Newton with
the tangent shifted where it is not positive definite, steps bounded by
continuous collision detection and an Armijo line search on the energy;
with friction, the lag's normal forces brought near their fixed point on
the energy, then Newton at the state's own normal forces and normals,
until the state is an equilibrium with its own lag; a failed step tried
again in halves).

Recorded per step: turns, end position and torque, pairs inside the
barrier's width, Newton iterations, lags, live-solve fallbacks, whether
the friction is the state's own (``live``), shifts, halvings, Coulomb's
law at the converged state (:func:`coulomb_excess`), and the true penetration
of the centrelines (``skfem_rod.contact.crossing.min_distance``,
closest points of element pairs, both parameters free).  Results:
``<out>.json`` and ``<out>.png`` (extension and torque against turns
beside the reference relations of ``bench_plectoneme.py``).
"""
import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import bench_plectoneme as bp  # noqa: E402

from skfem_rod.contact.barrier import (Barrier, friction_live, friction_work,  # noqa: E402
                                       pair_forces)
from skfem_rod.minimize import EnergySolve  # noqa: E402


def run(n_elements, gamma_T=0.0, turns=bp.TURNS, step=1 / 16, budget=300.0, width=0.02,
        force=1.0, verbose=True):
    """Twist the rod to ``turns`` in steps of ``step`` turns; returns a
    dict of figures and per-step records."""
    rod = bp.build(n_elements, 0.0)
    rod.contact = None
    barrier = Barrier.for_nodes(rod.mesh.s_nodes, bp.RADIUS, width=width, force=force)
    solve = EnergySolve(rod, barrier, bp.RADIUS, mu=gamma_T)
    end = rod.node("end")
    recs = []
    t0 = time.perf_counter()

    def record(k, lam, r, R, rep):
        ev = rep.evaluation                      # the rod's, at the converged state
        reaction = (ev.residual + ev.external).reshape(-1, 6)[end]
        rec = dict(coulomb=coulomb_excess(solve, r, R, rep), turns=lam * bp.TURNS, x_end=float(r[end, 0]), torque=float(reaction[3]),
                   contacts=rep.active, iterations=rep.iterations, lags=rep.lags, fallbacks=rep.fallbacks, live=rep.live,
                   shifts=rep.shifts, halvings=rep.halvings,
                   true_penetration=float((2 * bp.RADIUS - rep.true_distance) / bp.RADIUS),
                   min_gap=float(rep.min_gap / bp.RADIUS),
                   wall=time.perf_counter() - t0)
        recs.append(rec)
        if verbose:
            print(f"  {k:3d}: {rec['turns']:6.3f} turns  x_end={rec['x_end']:.4f}  "
                  f"M={rec['torque']:.4f}  pairs={rec['contacts']:4d}  "
                  f"its={rec['iterations']:3d} (lags {rec['lags']}, fallbacks {rec['fallbacks']}, shifts {rec['shifts']}, "
                  f"halvings {rec['halvings']})  penetration={rec['true_penetration']:+.2e} r  "
                  f"{rec['wall']:.1f} s", flush=True)
    path = solve.path(int(round(turns / step)), turns / bp.TURNS, record, budget)
    _, r, R = path.states[-1]
    stop = path.stop
    its = np.array([q["iterations"] for q in recs])
    tries = path.reports                         # every step tried, failed ones too
    state = dict(r=r, R=R, order=np.argsort(rod.mesh.s_nodes))
    out = dict(n_elements=n_elements, gamma_T=gamma_T, turns=recs[-1]["turns"] if recs else 0.0,
               wall=time.perf_counter() - t0, stop=stop, records=recs,
               median_iterations=float(np.median(its)) if its.size else None,
               total_iterations=int(sum(q.iterations for q in tries)),
               failed_tries=int(sum(not q.converged for q in tries)),
               live_steps=int(sum(q["live"] for q in recs)),
               max_true_penetration=max((q["true_penetration"] for q in recs), default=None),
               max_coulomb_excess=max((q["coulomb"] for q in recs), default=None),
               width=width, force=force, step=step)
    out["_state"] = state
    if verbose:
        print(f"  -> {out['turns']:.3f} turns in {out['wall']:.1f} s, median "
              f"{out['median_iterations']} Newton iterations per step"
              + (f"; stopped: {stop}" if stop else ""), flush=True)
    return out


def coulomb_excess(solve, r, R, rep):
    """Coulomb's law at a converged frictional state: the largest excess of
    a pair's friction force (the one in equilibrium there: at the state's
    own normal forces, or, where the step fell back to the settled lag, at
    the lag's) over mu times its actual normal force there, relative to mu
    times the largest normal force (0 without friction; at most round-off
    at the state's own forces, the lag tolerance 1e-3 at the lag's)."""
    lag = rep.friction
    if lag is None or lag.pairs.shape[0] == 0:
        return 0.0
    bw = solve.barrier
    fw = (friction_live(r, R, lag, bw, solve.mu, solve.eps_v, jacobian=False) if rep.live
          else friction_work(r, R, lag, solve.mu, solve.eps_v, hessian=False))
    f = np.linalg.norm(fw.force, axis=1)
    lam = pair_forces(r, lag.pairs, bw).force
    return float(np.max(f - solve.mu * lam) / (solve.mu * max(lam.max(), 1e-300)))


def render(run_out, path):
    """The last state of a run as a striped tube (off screen), ``path``."""
    from skfem_rod.render import render_rod
    st = run_out["_state"]
    o = st["order"]
    render_rod(path, st["r"][o], st["R"][o], bp.RADIUS, off_screen=True, camera=(0.3, -1, 0.5),
               title=f"{run_out['n_elements']} elements, gamma_T = {run_out['gamma_T']:g}: "
                     f"{run_out['turns']:.3g} turns (node barrier, Newton on the energy)")
    return path


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--elements", type=int, nargs="+", default=[100, 200])
    ap.add_argument("--gammas", type=float, nargs="+", default=[0.0, 0.3],
                    help="Coulomb coefficients gamma_T")
    ap.add_argument("--turns", type=float, default=bp.TURNS)
    ap.add_argument("--step", type=float, default=1 / 16, help="turns per load step")
    ap.add_argument("--width", type=float, default=0.02, help="barrier width / radius")
    ap.add_argument("--force", type=float, default=1.0,
                    help="a node pair's force at half the width")
    ap.add_argument("--budget", type=float, default=300.0, help="wall-time budget per run (s)")
    ap.add_argument("--out", default=str(HERE / "plectoneme_barrier"))
    a = ap.parse_args(argv)
    runs = [run(n, g, a.turns, a.step, a.budget, a.width, a.force)
            for n in a.elements for g in a.gammas]
    out = Path(a.out)
    pngs = [render(q, f"{a.out}_{q['n_elements']}_{q['gamma_T']:g}.png") for q in runs]
    for q in runs:
        q.pop("_state")
    tmp = out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(dict(command=" ".join(["python"] + sys.argv), runs=runs),
                              indent=1))
    tmp.replace(out.with_suffix(".json"))
    bp.plot(runs, str(out.with_suffix(".png")),
            title="plectoneme (L = 1, r = 0.025, T = 10 EI/L$^2$): Newton on the energy "
                  "with a node barrier")
    print(f"wrote {out.with_suffix('.json')}, {out.with_suffix('.png')} and " + ", ".join(pngs))


if __name__ == "__main__":
    main()
