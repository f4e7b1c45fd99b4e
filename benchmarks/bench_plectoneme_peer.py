"""PyElastica beside skfem_rod on the plectoneme of issue 13.

The same rod and loads as ``benchmarks/bench_plectoneme.py`` (L = 1,
r = 0.025, E = 1e6, G = E / 1.5, 100 elements; s = 0 clamped; s = L held
on the axis, free along it, pulled by the dead tension T = 10 EI / L^2 and
turned about it), solved by PyElastica 1.0 the way its own plectoneme
example does (``examples/RodContactCase/RodSelfContact/PlectonemesCase``):
damped explicit dynamics (position Verlet, ``dt = 0.0025 L / n``,
``AnalyticalLinearDamper``), the end turned at one turn per 5 time units,
``RodSelfContact(k=1e4, nu=10)``, and its symmetry breaking (a lateral
velocity kick of 1e-4 at mid-length at every step while turning).  The
differences from the example are the issue's: the tension at the end, and
100 elements instead of 150.

It runs until the end has turned ``TURNS`` times, or for a wall-time
budget, and records, every 0.05 turn of the nominal rate: the turns
applied (the end element's rotation about the axis as measured: the
example's damper slows the prescribed spin of the end too, which turns
0.852 times the nominal rate; the nominal turns, time / 5, are kept as
``nominal``), the link (twist + writhe, closed along the end tangents as
skfem_rod's benchmarks close their rods: equal to the turns unless a
strand passes through another or around an end), the end position
``x(L)`` and the true penetration of the discrete centreline (``2 r`` minus the smallest distance between two of
its segments farther apart along the rod than skfem_rod's contact
exclusion, 3.14 r; relative to ``r``; > 0: the tubes overlap).  PyElastica's
states are those of a moving rod (its kinetic energy is reported), not
equilibria.

    pip install -e ".[bench]"                      # pyelastica (and numba)
    python benchmarks/bench_plectoneme_peer.py [--budget 400] [--elements 100]
        [--results]                                # append to RESULTS_plectoneme.md
        [--out records.json]
"""
import argparse
import datetime
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_plectoneme import AREA, E, L, RADIUS, TENSION, TURNS  # noqa: E402

#: skfem_rod's default contact exclusion of this rod (arclength)
EXCLUSION = np.pi * RADIUS
#: PyElastica's example: one turn per this many time units
TIME_PER_TURN = 5.0


def segment_distances(x, exclusion):
    """Smallest distance between the segments of the polyline ``x`` (n+1, 3)
    whose midpoints lie farther apart along it than ``exclusion`` (the
    segments' closest points, clamped to both segments), and where."""
    p, d = x[:-1], np.diff(x, axis=0)
    ds = np.linalg.norm(d, axis=1)
    s = np.concatenate([[0.0], np.cumsum(ds)])
    mid = 0.5 * (s[:-1] + s[1:])
    i, j = np.triu_indices(len(p), 1)
    keep = mid[j] - mid[i] > exclusion
    i, j = i[keep], j[keep]
    a, b, r = d[i], d[j], p[i] - p[j]
    aa, bb, ab = (a * a).sum(1), (b * b).sum(1), (a * b).sum(1)
    ar, br = (a * r).sum(1), (b * r).sum(1)
    den = aa * bb - ab * ab
    u = np.where(den > 1e-300 * aa * bb, (ab * br - bb * ar) / np.maximum(den, 1e-300), 0.0)
    u = np.clip(u, 0.0, 1.0)
    v = np.clip((ab * u + br) / bb, 0.0, 1.0)
    u = np.clip((ab * v - ar) / aa, 0.0, 1.0)
    gap = np.linalg.norm(r + a * u[:, None] - b * v[:, None], axis=1)
    k = int(np.argmin(gap))
    return float(gap[k]), (float(mid[i[k]]), float(mid[j[k]]))


def link_of(x, Q):
    """Twist + writhe of PyElastica's rod (node positions ``x`` (n+1, 3),
    element directors ``Q`` (3, 3, n), rows d1, d2, d3), closed far away
    along its end tangents as skfem_rod's benchmark closes its own
    (``skfem_rod.topology.topology``): ``d1`` at a node the normalized
    mean of its elements'.  The turns applied, unless a strand passed
    through another or around an end."""
    from skfem_rod.topology import topology
    d1e, d3e = Q[0].T, Q[2].T
    d1 = np.vstack([d1e[:1], d1e[:-1] + d1e[1:], d1e[-1:]])
    d1 /= np.linalg.norm(d1, axis=1)[:, None]
    t = topology(x, d1, t_start=d3e[0], t_end=d3e[-1])
    return float(t.twist - t.closure_twist + t.writhe)


def run(n_elements=100, budget=400.0, turns=TURNS, verbose=True):
    import elastica as ea

    class Sim(ea.BaseSystemCollection, ea.Constraints, ea.Contact, ea.Forcing,
              ea.CallBacks, ea.Damping):
        pass

    sim = Sim()
    dt = 0.0025 * L / n_elements
    density = 1.0 / (AREA * L)                       # total mass 1, as the example
    nu = 2.0 / density / AREA
    axis = np.array([1.0, 0.0, 0.0])
    rod = ea.CosseratRod.straight_rod(n_elements, np.zeros(3), axis, np.array([0.0, 0.0, 1.0]),
                                      L, RADIUS, density, youngs_modulus=E,
                                      shear_modulus=E / 1.5)
    sim.append(rod)
    sim.dampen(rod).using(ea.AnalyticalLinearDamper, damping_constant=nu, time_step=dt)
    # the end is turned until it has turned ``turns`` times (the damper
    # slows the end's prescribed spin too: it turns 0.852 times the
    # nominal rate), then the run ends
    state = dict(turning=True)
    rate = 2 * np.pi / TIME_PER_TURN
    mid = n_elements // 2

    class SlideAndTurn(ea.ConstraintBase):
        """s = 0 clamped; s = L held on the axis (y = z = 0), free along
        it, turned about it at ``rate`` while ``state["turning"]``; the
        example's lateral kick at mid-length while turning."""

        def __init__(self, x_start, x_end, Q_start, Q_end, **kw):
            super().__init__(**kw)
            self.x0, self.Q0 = np.array(x_start), np.array(Q_start)

        def constrain_values(self, system, time):
            system.position_collection[..., 0] = self.x0
            system.director_collection[..., 0] = self.Q0
            system.position_collection[1:, -1] = 0.0

        def constrain_rates(self, system, time):
            system.velocity_collection[..., 0] = 0.0
            system.omega_collection[..., 0] = 0.0
            system.velocity_collection[1:, -1] = 0.0
            # omega is in the material frame: the axis is d3 of the end element
            w = rate if state["turning"] else 0.0
            system.omega_collection[..., -1] = np.array([0.0, 0.0, w])
            if state["turning"]:
                system.velocity_collection[2, mid] -= 1e-4

    sim.constrain(rod).using(SlideAndTurn, constrained_position_idx=(0, -1),
                             constrained_director_idx=(0, -1))
    sim.add_forcing_to(rod).using(ea.EndpointForces, np.zeros(3), TENSION * axis, ramp_up_time=dt)
    sim.detect_contact_between(rod, rod).using(ea.RodSelfContact, k=1e4, nu=10)
    sim.finalize()
    stepper = ea.PositionVerlet()
    records, t, step = [], 0.0, 0
    every = max(1, int(round(0.05 * TIME_PER_TURN / dt)))          # 0.05 turn
    angle0 = np.arctan2(rod.director_collection[0, 2, -1], rod.director_collection[0, 1, -1])
    t0 = time.perf_counter()
    while state["turning"]:
        t = stepper.step(sim, t, dt)
        step += 1
        if step % every == 0:
            x = rod.position_collection.T.copy()
            gap, at = segment_distances(x, EXCLUSION)
            ke = float(rod.compute_translational_energy() + rod.compute_rotational_energy())
            wall = time.perf_counter() - t0
            finite = bool(np.all(np.isfinite(x)))
            # the end element's rotation about the axis, unwrapped (0.05
            # turn or less between records)
            d1 = rod.director_collection[0, :, -1]
            ang = np.arctan2(d1[2], d1[1]) - angle0
            end_turns = ang / (2 * np.pi)
            end_turns += np.round((records[-1]["end_turns"] if records else 0.0) - end_turns)
            rec = dict(turns=float(end_turns), nominal=t / TIME_PER_TURN, wall=wall,
                       x_end=float(x[-1, 0]), true_penetration=(2 * RADIUS - gap) / RADIUS,
                       at=at, kinetic=ke, finite=finite, end_turns=float(end_turns),
                       link=link_of(x, rod.director_collection) if finite else None)
            records.append(rec)
            if verbose:
                print(f"  {rec['turns']:6.3f} turns ({rec['nominal']:.3f} nominal)  "
                      f"x_end={rec['x_end']:.4f}  "
                      f"pen/r={rec['true_penetration']:+.3f}  KE={ke:.2e}  "
                      f"link={rec['link']:.4f}  {rec['wall']:.1f} s", flush=True)
            state["turning"] = end_turns < turns
            if not rec["finite"] or rec["wall"] > budget:
                break
    return dict(n_elements=n_elements, dt=dt, budget=budget, records=records,
                steps=step, wall=time.perf_counter() - t0)


def summary(out):
    recs = out["records"]
    pen = np.array([r["true_penetration"] for r in recs])
    return dict(turns=recs[-1]["turns"] if recs else 0.0, wall=out["wall"],
                steps=out["steps"], max_true_penetration=float(pen.max()) if pen.size else None,
                x_end=recs[-1]["x_end"] if recs else None,
                link=recs[-1]["link"] if recs else None)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--elements", type=int, default=100)
    ap.add_argument("--budget", type=float, default=400.0, help="wall-time budget (s)")
    ap.add_argument("--out", default=None, help="write the records as JSON to this file")
    ap.add_argument("--results", action="store_true",
                    help="append the table to benchmarks/RESULTS_plectoneme.md")
    a = ap.parse_args(argv)
    out = run(a.elements, a.budget)
    s = summary(out)
    print(json.dumps(s, indent=1))
    if a.out:
        tmp = Path(a.out + ".tmp")
        tmp.write_text(json.dumps(out, indent=1))
        tmp.replace(a.out)
    if a.results:
        recs = out["records"]
        # the first record at or past each quarter turn of the end
        rows = [next(r for r in recs if r["turns"] >= q - 1e-9)
                for q in np.arange(0.25, recs[-1]["turns"] + 1e-9, 0.25)] if recs else []
        lines = [f"\n## PyElastica beside skfem_rod ({datetime.date.today()})\n\n",
                 f"`python benchmarks/bench_plectoneme_peer.py "
                 f"{' '.join(argv if argv is not None else sys.argv[1:])}` (pyelastica "
                 f"{__import__('importlib.metadata').metadata.version('pyelastica')}, "
                 f"{a.elements} elements, dt = {out['dt']:.3g}, {out['steps']} steps): "
                 f"{s['turns']:.3f} turns in {s['wall']:.0f} s, largest true penetration "
                 f"{s['max_true_penetration']:.3g} r.\n\n",
                 "| turns | wall (s) | x(L) | true penetration / r | kinetic energy | link |\n",
                 "|---|---|---|---|---|---|\n"]
        lines += [f"| {r['turns']:.2f} | {r['wall']:.0f} | {r['x_end']:.4f} | "
                  f"{r['true_penetration']:+.3f} | {r['kinetic']:.2e} | "
                  f"{r['link'] if r['link'] is None else round(r['link'], 3)} |\n"
                  for r in rows]
        with open(HERE / "RESULTS_plectoneme.md", "a") as fh:
            fh.writelines(lines)


if __name__ == "__main__":
    main()
