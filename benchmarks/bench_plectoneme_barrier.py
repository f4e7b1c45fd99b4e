"""The plectoneme of ``bench_plectoneme.py`` by ``rod.solve(method="barrier")``
(:func:`skfem_rod.minimize.solve_barrier`): the smooth node barrier of
:mod:`skfem_rod.contact.barrier` and its Coulomb friction in place of the
paper's augmented-Lagrangian contact, each step by Newton on the total
energy (docs/contact-solve.md, "A smooth barrier between nodes").

Usage::

    python benchmarks/bench_plectoneme_barrier.py              # 100 and 200 elements,
                                                               # gamma_T = 0 and 0.3
    python benchmarks/bench_plectoneme_barrier.py --elements 100 --gammas 0 --budget 120 --out /tmp/pb
    python benchmarks/bench_plectoneme_barrier.py --elements 100 --gammas 0.3 --step 0.0625 0.05 0.041667

Several step sizes (``--step``) give one run each: with friction each
takes its own path through the slips (which pair sticks and when a ply
slips depends on the history), and a run's cost is its path's; the
summary gives the median wall time over them per set-up
(``summary`` in the JSON).

Same rod, supports, loads, twist and contact (radius, ``gamma_T``) as
``bench_plectoneme.py`` (dead tension, lateral imperfection, the end
turned 10 times); the barrier of width 0.02 r, a pair's force 1.0 at half
the width (``--force 0``: the solve's default, the load scale); steps of
1/16 turn, each solved by :meth:`skfem_rod.minimize.EnergySolve.step`
(secant predictor, Newton with the tangent shifted where it is not
positive definite, steps bounded by continuous collision detection and an
Armijo line search on the energy; with friction, the lag's normal forces
brought near their fixed point on the energy, then Newton at the state's
own normal forces and normals, until the state is an equilibrium with its
own lag); a failed step is cut by the load path (``solver.follow_path``).

Recorded per step, from the returned ``Result``: turns, end position and
torque, the node pairs in contact, Newton iterations, Coulomb's law at
the converged state from the recorded contact forces
(:func:`coulomb_excess`) and the true penetration of the centrelines
(``ContactState.min_distance``: closest points of element pairs, both
parameters free), the link (twist + writhe, after the solve); per run the
failed tries, the friction's fallbacks and pseudo-time steps through
slips (``Result.log``) and how far the
link fell from the turns applied.  The ends carry handles (``handles=True``:
rigid continuations along the axis, so that no strand passes around an
end); ``--no-handles`` runs PyElastica's set-up as it is, where the
plectoneme swings around an end at 8-9 turns and the link drops by 2 or 4.
Results: ``<out>.json`` and ``<out>.png`` (extension
and torque against turns beside the reference relations of
``bench_plectoneme.py``).
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


def run(n_elements, gamma_T=0.0, turns=bp.TURNS, step=1 / 16, budget=300.0, width=0.02,
        force=1.0, verbose=True, handles=True):
    """Twist the rod to ``turns`` in steps of ``step`` turns by
    ``rod.solve(method="barrier")``; returns a dict of figures and per-step
    records (``force`` None: the solve's default barrier force;
    ``handles``: the ends continued by rigid handles, so that the link
    stays the turns applied).  Each step's link (twist + writhe) is
    computed after the solve, outside the timed run."""
    rod = bp.build(n_elements, gamma_T)
    end = rod.node("end")
    recs = []
    t0 = time.perf_counter()

    def record(result, k):
        if k == 0:
            return
        st = result.steps[k]
        c = st.contact
        rec = dict(coulomb=coulomb_excess(c, gamma_T), turns=st.load_factor * bp.TURNS,
                   x_end=float(st.r[end, 0]), torque=float(result.reaction("end", k)[1][0]),
                   contacts=int(c.s.size), iterations=st.iterations,
                   true_penetration=float((2 * bp.RADIUS - c.min_distance) / bp.RADIUS),
                   wall=time.perf_counter() - t0)
        recs.append(rec)
        if verbose:
            print(f"  {k:3d}: {rec['turns']:6.3f} turns  x_end={rec['x_end']:.4f}  "
                  f"M={rec['torque']:.4f}  pairs={rec['contacts']:4d}  "
                  f"its={rec['iterations']:3d}  penetration={rec['true_penetration']:+.2e} r  "
                  f"coulomb={rec['coulomb']:.1e}  {rec['wall']:.1f} s", flush=True)
    options = dict(barrier_width=width, time_limit=budget, handles=handles)
    if force is not None:
        options["barrier_force"] = force
    result = rod.solve(int(round(turns / step)), path=[0, turns / bp.TURNS], callback=record,
                       method="barrier", **options)
    wall = time.perf_counter() - t0
    for k, q in enumerate(recs, start=1):
        q["link"] = float(result.topology(k, per_element=4).link)
    last = result.steps[-1]
    its = np.array([q["iterations"] for q in recs])
    state = dict(r=last.r, R=last.R, order=np.argsort(rod.mesh.s_nodes))
    out = dict(n_elements=n_elements, gamma_T=gamma_T, turns=recs[-1]["turns"] if recs else 0.0,
               wall=wall, stop="" if result.converged else result.message,
               handles=handles,
               # the largest departure of the link from the turns applied:
               # 0 unless a strand passed around an end (no handles)
               link_lost=max((abs(q["link"] - q["turns"]) for q in recs), default=0.0),
               records=recs, median_iterations=float(np.median(its)) if its.size else None,
               total_iterations=int(its.sum()),
               failed_tries=sum("cutting the step" in line for line in result.log),
               fallbacks=sum("settled to lag_tol" in line for line in result.log),
               damped_steps=sum(int(line.split(": ")[1].split()[0]) for line in result.log
                                if "pseudo-time step(s) through a slip" in line),
               log=list(result.log),
               max_true_penetration=max((q["true_penetration"] for q in recs), default=None),
               max_coulomb_excess=max((q["coulomb"] for q in recs), default=None),
               width=width, force=force, step=step)
    out["_state"] = state
    if verbose:
        print(f"  -> {out['turns']:.3f} turns (link {recs[-1]['link'] if recs else 0:.3f}) in "
              f"{out['wall']:.1f} s, median "
              f"{out['median_iterations']} Newton iterations per step, "
              f"{out['failed_tries']} failed tries, {out['fallbacks']} fallbacks, "
              f"{out['damped_steps']} pseudo-time steps"
              + (f"; stopped: {out['stop']}" if out["stop"] else ""), flush=True)
    return out


def coulomb_excess(contact, gamma_T):
    """Coulomb's law at a converged frictional state, from what the
    result records (:class:`skfem_rod.results.ContactState`): the largest
    excess of a pair's friction force over ``gamma_T`` times its normal
    force, relative to ``gamma_T`` times the largest normal force (0
    without friction; at most round-off where the step converged at its
    own normal forces, the lag tolerance 1e-3 where it fell back to the
    settled lag)."""
    if not contact.friction or contact.s.size == 0:
        return 0.0
    f = np.linalg.norm(contact.force_T, axis=1)
    return float(np.max(f - gamma_T * contact.force) / (gamma_T * contact.force.max()))


def render(run_out, path):
    """The last state of a run as a striped tube (off screen), ``path``."""
    from skfem_rod.render import render_rod
    st = run_out["_state"]
    o = st["order"]
    render_rod(path, st["r"][o], st["R"][o], bp.RADIUS, off_screen=True, camera=(0.3, -1, 0.5),
               title=f"{run_out['n_elements']} elements, gamma_T = {run_out['gamma_T']:g}: "
                     f"{run_out['turns']:.3g} turns, link {run_out['records'][-1]['link']:.3g} "
                     f"(node barrier)")
    return path


def summarize(runs):
    """Per set-up (elements, gamma_T): how many of its runs (one per step
    size) reached the turns asked, and the median, least and largest wall
    time over them (a list of dicts)."""
    rows = []
    for key in dict.fromkeys((q["n_elements"], q["gamma_T"]) for q in runs):
        qs = [q for q in runs if (q["n_elements"], q["gamma_T"]) == key]
        walls = [q["wall"] for q in qs]
        rows.append(dict(n_elements=key[0], gamma_T=key[1], runs=len(qs),
                         reached=sum(not q["stop"] for q in qs), steps=[q["step"] for q in qs],
                         median_wall=float(np.median(walls)), min_wall=float(min(walls)),
                         max_wall=float(max(walls))))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--elements", type=int, nargs="+", default=[100, 200])
    ap.add_argument("--gammas", type=float, nargs="+", default=[0.0, 0.3],
                    help="Coulomb coefficients gamma_T")
    ap.add_argument("--turns", type=float, default=bp.TURNS)
    ap.add_argument("--step", type=float, nargs="+", default=[1 / 16],
                    help="turns per load step; several: one run each, and the median wall "
                         "time over them per set-up")
    ap.add_argument("--width", type=float, default=0.02, help="barrier width / radius")
    ap.add_argument("--force", type=float, default=1.0,
                    help="a node pair's force at half the width (0: the solve's default)")
    ap.add_argument("--budget", type=float, default=300.0, help="wall-time budget per run (s)")
    ap.add_argument("--no-handles", action="store_true",
                    help="no handles at the ends: a strand may pass around an end, and the "
                         "link drop below the turns applied")
    ap.add_argument("--out", default=str(HERE / "plectoneme_barrier"))
    a = ap.parse_args(argv)
    runs = [run(n, g, a.turns, h, a.budget, a.width, a.force or None,
                handles=not a.no_handles)
            for n in a.elements for g in a.gammas for h in a.step]
    out = Path(a.out)
    tag = (lambda q: f"_step{q['step']:.4g}") if len(a.step) > 1 else (lambda q: "")
    pngs = [render(q, f"{a.out}_{q['n_elements']}_{q['gamma_T']:g}{tag(q)}.png") for q in runs]
    for q in runs:
        q.pop("_state")
    summary = summarize(runs)
    for row in summary:
        print(f"{row['n_elements']} elements, gamma_T = {row['gamma_T']:g}: "
              f"{row['reached']} of {row['runs']} run(s) reached {a.turns:g} turns; wall "
              f"median {row['median_wall']:.1f} s (min {row['min_wall']:.1f}, max "
              f"{row['max_wall']:.1f}) over the step sizes {row['steps']}")
    tmp = out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(dict(command=" ".join(["python"] + sys.argv), runs=runs,
                                   summary=summary), indent=1))
    tmp.replace(out.with_suffix(".json"))
    bp.plot(runs, str(out.with_suffix(".png")),
            title="plectoneme (L = 1, r = 0.025, T = 10 EI/L$^2$): Newton on the energy "
                  "with a node barrier")
    print(f"wrote {out.with_suffix('.json')}, {out.with_suffix('.png')} and " + ", ".join(pngs))


if __name__ == "__main__":
    main()
