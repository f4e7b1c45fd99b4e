"""Plectoneme by implicit pseudo-dynamics: PyElastica's plectoneme set-up
twisted to 10 turns with ``rod.solve(..., dynamics=True)``.

Usage::

    python benchmarks/bench_plectoneme.py                 # 100 and 200 elements,
                                                          # gamma_T = 0 and 0.3
                                                          # -> RESULTS_plectoneme.md,
                                                          #    plectoneme.png
    python benchmarks/bench_plectoneme.py --elements 100 --gammas 0 --budget 120

Scene (issue 13): L = 1, radius r = 0.025, E = 1e6, G = E / 1.5 (PyElastica's
Poisson ratio 0.5, so explicit stiffnesses: EA = E pi r^2, GA = G pi r^2,
EI = E pi r^4 / 4, GJ = G pi r^4 / 2); s = 0 clamped; s = L pinned in y and
z, free along x, under a constant dead tension T = 10 EI / L^2 along +x, and
turned about x by 10 turns (load factor 1); self-contact of radius r
(default penalty, tolerance 1e-3 r) with crossing contact on
(``crossing=True``: without it the plies that cross in the loop press at
points between slave points, the projection of a slave on the tight master
curve is ill-conditioned -- a move of 1.7e-5 shifts s_bar by 4e-4 and the
residual by 2 -- and Newton 2-cycles at any dt); a constant lateral dead force 1e-2 T at
mid-length breaks the symmetry (PyElastica's rod buckles from round-off).
The end rotation is stepped by pi/2 per load step (``max_rotation_step``):
40 nominal steps.

Each run has a wall-time ``budget`` (the solve option ``time_limit``: it
stops wherever it is, in a damped phase too); what it reached is reported.

Reference relations plotted beside the results (docs/pseudo-dynamics.md):
the straight twisted rod ``M = GJ 2 pi n / L``; the clamped Greenhill
threshold (``skfem_rod.analytic.greenhill_factor``); the hard-core
plectoneme plateau torque and end shortening per turn of Neukirch & Marko,
PRL 106, 138104 (2011) with superhelix radius ``R = r`` (two plies in
contact): ``T = B sin^4 t (1 + 2 cos^2 t) / (2 R^2 cos 2t)`` fixes the ply
angle ``t``, then ``M_p = 2 B sin^3 t cos t / (R cos 2t)`` and
``d(shortening)/dn = 4 pi R / sin 2t``.
"""
import argparse
import datetime
import json
import os
import re
import sys
import time
from pathlib import Path

import numpy as np

from skfem_rod import Rod, Section, geometry

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))
from helpers import load_demo  # noqa: E402

tw = load_demo("twisted_rod")

L, RADIUS, E = 1.0, 0.025, 1e6
G = E / 1.5
AREA, INERTIA = np.pi * RADIUS ** 2, np.pi * RADIUS ** 4 / 4
EI, GJ = E * INERTIA, G * 2 * INERTIA
TENSION = 10 * EI / L ** 2
TURNS = 10.0


def section():
    return Section(EA=E * AREA, GA1=G * AREA, GA2=G * AREA, EI1=EI, EI2=EI, GJ=GJ,
                   radius=RADIUS)


def build(n_elements, gamma_T=0.0, turns=TURNS, imperfection=1e-2, contact=None):
    """The rod of the module doc (``contact``: more contact options, e.g.
    ``{"curve": "smooth"}``)."""
    rod = Rod(geometry.straight(L), section(), n_elements)
    rod.clamp("start")
    rod.pin("end", components=(1, 2))
    rod.prescribe_rotation("end", [2 * np.pi * turns, 0.0, 0.0])
    rod.add_force("end", [TENSION, 0.0, 0.0], constant=True)
    s = rod.mesh.s_nodes
    rod.add_force(float(s[np.argmin(np.abs(s - L / 2))]), [0.0, imperfection * TENSION, 0.0],
                  constant=True)
    rod.enable_contact(**{"radius": RADIUS, "gamma_T": float(gamma_T), "crossing": True,
                          **(contact or {})})
    return rod


def theory():
    """Greenhill threshold and plectoneme relations in the scene's units."""
    lam = np.sqrt(EI / TENSION)                      # lambda = sqrt(B / T)
    scale = np.sqrt(EI * TENSION)                    # moments in sqrt(BT)
    m = tw.greenhill_factor(L / lam)
    th = tw.plectoneme_theory(RADIUS / lam)          # B = T = 1 units
    return dict(lam=lam, greenhill_torque=2 * scale * m,
                greenhill_turns=2 * scale * m * L / (GJ * 2 * np.pi),
                theta=th["theta"], plateau_torque=th["torque"] * scale,
                shortening_per_turn=th["shortening_per_turn"] * lam)


def run(n_elements, gamma_T, turns=TURNS, budget=300.0, verbose=True, max_damped=400,
        contact=None, method="dynamics", **options):
    """Solve one case (``contact``: more contact options, ``options``: more
    solver options); returns a dict of figures (and the result).
    ``method``: ``"dynamics"`` (``dynamics=True``) or ``"relax"``
    (``snap="relax"``, ``stability=True``: the gradient flow, by
    Levenberg-Marquardt steps with contact on, pushed off saddles).  With
    ``"relax"`` the figures per solve are those of the recorded steps
    (:func:`steps_log`), and ``damped`` is 0."""
    if method not in ("dynamics", "relax"):
        raise ValueError(f"method must be 'dynamics' or 'relax', not {method!r}")
    rod = build(n_elements, gamma_T, turns, contact=contact)
    n_steps = int(np.ceil(turns * 4))
    recs = []
    t0 = time.perf_counter()

    def callback(result, k):
        st = result.steps[k]
        c = st.contact
        recs.append(dict(turns=st.load_factor * turns, x_end=float(st.r[rod.node("end"), 0]),
                         torque=float(result.reaction("end", k)[1][0]),
                         contacts=int(c.s.size), penetration=float(c.penetration) / RADIUS,
                         crossing=0 if c.crossing is None else int(c.crossing.s.size),
                         crossing_force=0.0 if c.crossing is None
                         else c.crossing.total_force,
                         true_penetration=(2 * RADIUS - c.min_distance) / RADIUS
                         if c.min_distance is not None else None,
                         wall=time.perf_counter() - t0))
        if verbose:
            r = recs[-1]
            dyn = getattr(result, "dynamics", None)
            print(f"  {k:3d}: {r['turns']:6.3f} turns  x_end={r['x_end']:.4f}  "
                  f"M={r['torque']:.4f}  contacts={r['contacts']:3d}  "
                  f"crossing={r['crossing']:2d} ({r['crossing_force']:6.2f})  "
                  f"damped={dyn.damped_steps if dyn else 0:4d}  {r['wall']:.1f} s", flush=True)

    how = dict(dynamics=True, max_damped_steps=max_damped) if method == "dynamics" \
        else dict(snap="relax", stability=True)
    result = rod.solve(n_steps, callback=callback, time_limit=budget, **how, **options)
    message = result.message
    stopped = "budget" if "the time limit ran out" in message else ""
    wall = time.perf_counter() - t0
    d = result.dynamics if method == "dynamics" else steps_log(result)
    newton = np.array(d.newton) if d.newton else np.zeros(1)
    acc = np.array(d.accepted, dtype=bool) if d.accepted else np.zeros(1, bool)
    true_pen = [r["true_penetration"] for r in recs if r["true_penetration"] is not None]
    return dict(n_elements=n_elements, gamma_T=gamma_T, turns=recs[-1]["turns"],
                wall=wall, message=message, stopped=stopped, records=recs,
                solves=len(d.kind), newton_total=int(newton.sum()),
                newton_median=float(np.median(newton)),
                newton_median_accepted=float(np.median(newton[acc])) if acc.any() else None,
                damped=d.damped_steps, rejected=int((~acc).sum()),
                flow_steps=int(sum(st.flow_steps for st in result.steps)),
                by_kind=by_kind(d),
                max_penetration_recorded=max(true_pen, default=float("-inf")),
                max_penetration_all=d.max_penetration,
                max_uzawa_penetration=max(r["penetration"] for r in recs),
                result=result)


def steps_log(result):
    """A :class:`~skfem_rod.dynamics.DynamicsLog` of a run without dynamics:
    one accepted "static" solve per recorded step after step 0 (its Newton
    iterations, the flow's linear solves included) with its true
    penetration, no damped step."""
    from skfem_rod.dynamics import DynamicsLog
    log = DynamicsLog()
    for st in result.steps[1:]:
        log.kind.append("static")
        log.newton.append(int(st.iterations))
        log.accepted.append(True)
        if st.contact is not None and st.contact.min_distance is not None:
            log.penetration.append((2 * RADIUS - st.contact.min_distance) / RADIUS)
    return log


def by_kind(log):
    """Newton iterations of a run's solves (:class:`~skfem_rod.dynamics.DynamicsLog`
    ``log``) by kind ("static", "damped", "polish") and outcome: ``{kind:
    dict(accepted, accepted_its, median_its, failed, failed_its)}``, the
    median over the accepted solves of that kind."""
    kind, its = np.array(log.kind), np.array(log.newton, dtype=int)
    ok = np.array(log.accepted, dtype=bool)
    out = {}
    for k in ("static", "damped", "polish"):
        a, f = (kind == k) & ok, (kind == k) & ~ok
        out[k] = dict(accepted=int(a.sum()), accepted_its=int(its[a].sum()),
                      median_its=float(np.median(its[a])) if a.any() else 0.0,
                      failed=int(f.sum()), failed_its=int(its[f].sum()))
    return out


def plot(runs, path, title=None):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    th = theory()
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    nmax = max(max(r["records"][-1]["turns"] for r in runs), 1.0)
    nn = np.linspace(0, nmax, 100)
    steps = {r.get("step") for r in runs}
    for k, r in enumerate(runs):
        n = np.array([q["turns"] for q in r["records"]])
        lab = f"{r['n_elements']} el., $\\gamma_T$={r['gamma_T']:g}"
        if len(steps) > 1:                  # runs of several step sizes
            lab += f", step {r['step']:.4g}"
        ax[0].plot(n, [q["x_end"] for q in r["records"]], "o-", ms=3, color=f"C{k}", label=lab)
        ax[1].plot(n, [q["torque"] for q in r["records"]], "o-", ms=3, color=f"C{k}", label=lab)
    ax[1].plot(nn, GJ * 2 * np.pi * nn / L, "k:", lw=1, label=r"straight: $GJ\,2\pi n/L$")
    ax[1].axhline(th["greenhill_torque"], color="C3", ls="--", lw=1,
                  label="Greenhill, clamped")
    ax[1].axhline(th["plateau_torque"], color="C2", ls="-.", lw=1,
                  label="plectoneme plateau (Neukirch-Marko)")
    # extension: straight until the snap, then the plectoneme slope from the
    # first state with contact of the first run
    r0 = runs[0]["records"]
    j = next((i for i, q in enumerate(r0) if q["contacts"] > 0), None)
    x_straight = L * (1 + TENSION / (E * AREA))
    ax[0].axhline(x_straight, color="k", ls=":", lw=1, label="straight: $L(1+T/EA)$")
    if j is not None:
        n0, x0 = r0[j]["turns"], r0[j]["x_end"]
        m = nn >= n0
        ax[0].plot(nn[m], x0 - th["shortening_per_turn"] * (nn[m] - n0), "C2-.", lw=1,
                   label=r"plectoneme: $-4\pi a/\sin 2\theta$ per turn")
    ax[0].set_ylim(-0.1, 1.1)
    ax[0].set_xlabel("turns n")
    ax[0].set_ylabel("end position $x(L)$ (extension)")
    ax[1].set_xlabel("turns n")
    ax[1].set_ylabel("end torque $M_x$")
    for a in ax:
        a.legend(fontsize=7)
    fig.suptitle(title or "plectoneme (L = 1, r = 0.025, T = 10 EI/L$^2$) by implicit "
                 "pseudo-dynamics")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def report(runs, path, command, png):
    th = theory()
    lines = [
        "# Plectoneme by implicit pseudo-dynamics (issue 13)", "",
        f"Generated by `{command}` on {datetime.date.today()} (2 shared cores; other",
        "engineers' jobs ran at the same time, so wall times are upper bounds).", "",
        "Scene: benchmarks/bench_plectoneme.py docstring (PyElastica's plectoneme: L = 1,",
        "r = 0.025, E = 1e6, G = E/1.5, T = 10 EI/L^2, 10 turns in 40 nominal steps).",
        f"Greenhill (clamped, L/lambda = {L / th['lam']:.3f}): {th['greenhill_turns']:.3f} turns, "
        f"M = {th['greenhill_torque']:.4f}; hard-core plectoneme: ply angle "
        f"{np.degrees(th['theta']):.2f} deg, plateau torque {th['plateau_torque']:.4f}, "
        f"shortening {th['shortening_per_turn']:.4f} per turn.", "",
        "| elements | gamma_T | turns reached | wall (s) | solves | Newton its (total) | "
        "median its/solve | damped steps | rejected solves | gradient-flow steps | "
        "max true penetration / r (recorded) | (all damped states) | how it ended |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in runs:
        lines.append(
            f"| {r['n_elements']} | {r['gamma_T']:g} | {r['turns']:.3f} | {r['wall']:.1f} | "
            f"{r['solves']} | {r['newton_total']} | {r['newton_median']:.0f} | {r['damped']} | "
            f"{r['rejected']} | {r['flow_steps']} | {r['max_penetration_recorded']:.2e} | "
            f"{r['max_penetration_all']:.2e} | {r['message'][:160]} |")
    lines += ["", "Where the Newton iterations went, by solve (accepted: solves, iterations, "
              "median per solve; failed: solves, iterations):", "",
              "| elements | gamma_T | static steps | damped steps | polishes | failed static | "
              "failed damped | failed polishes |", "|---|---|---|---|---|---|---|---|"]
    for r in runs:
        b = r["by_kind"]
        cells = [f"{b[k]['accepted']} / {b[k]['accepted_its']} / {b[k]['median_its']:.0f}"
                 for k in ("static", "damped", "polish")]
        cells += [f"{b[k]['failed']} / {b[k]['failed_its']}" for k in ("static", "damped", "polish")]
        lines.append(f"| {r['n_elements']} | {r['gamma_T']:g} | " + " | ".join(cells) + " |")
    lines += ["", f"![extension and torque against turns]({os.path.basename(png)})", ""]
    Path(path).write_text("\n".join(lines) + "\n")


#: a step line of a run's printout (``run``): turns, x_end, torque, contacts
_STEP = re.compile(r"^\s+\d+:\s+([-\d.]+) turns\s+x_end=([-\d.]+)\s+M=([-\d.]+)\s+"
                   r"contacts=\s*(\d+)")
#: the heading line of a run's printout
_HEAD = re.compile(r"^(\d+) elements, gamma_T = ([-\d.eE+]+)")


def runs_from_logs(paths):
    """The records of the runs printed to the files ``paths`` (this script's
    output): one run per heading line, its step lines as records."""
    runs = []
    for path in paths:
        for line in Path(path).read_text().splitlines():
            head, step = _HEAD.match(line), _STEP.match(line)
            if head:
                runs.append(dict(n_elements=int(head[1]), gamma_T=float(head[2]), records=[]))
            elif step and runs:
                runs[-1]["records"].append(dict(turns=float(step[1]), x_end=float(step[2]),
                                                torque=float(step[3]), contacts=int(step[4])))
    return [r for r in runs if r["records"]]


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--elements", type=int, nargs="+", default=[100, 200])
    p.add_argument("--gammas", type=float, nargs="+", default=[0.0, 0.3])
    p.add_argument("--turns", type=float, default=TURNS)
    p.add_argument("--budget", type=float, default=300.0, help="wall-time budget per run (s)")
    p.add_argument("--method", choices=("dynamics", "relax"), default="dynamics",
                   help="dynamics=True, or snap='relax' with stability=True (the gradient "
                        "flow by Levenberg-Marquardt steps)")
    p.add_argument("--max-damped", type=int, default=400,
                   help="damped steps per damped phase before a run gives up")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="another solver option (value as JSON), e.g. contact_solve=\"newton\"")
    p.add_argument("--contact", action="append", default=[], metavar="KEY=VALUE",
                   help="another contact option (value as JSON), e.g. curve=\"smooth\"")
    p.add_argument("--out", default=str(HERE))
    p.add_argument("--plot-logs", nargs="+", metavar="LOG",
                   help="no runs: plot the runs printed to these files (this script's "
                        "output, e.g. runs made side by side) to OUT/plectoneme.png")
    a = p.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)            # before the runs, not after the first
    if a.plot_logs:
        runs = runs_from_logs(a.plot_logs)
        if not runs:
            p.error(f"no run found in {a.plot_logs}")
        print(plot(runs, os.path.join(a.out, "plectoneme.png")))
        return runs
    options, contact = {}, {}
    for target, given in ((options, a.option), (contact, a.contact)):
        for kv in given:
            k, _, v = kv.partition("=")
            target[k] = json.loads(v)
    runs = []
    for n in a.elements:
        for g in a.gammas:
            print(f"{n} elements, gamma_T = {g:g}", flush=True)
            r = run(n, g, a.turns, a.budget, max_damped=a.max_damped, contact=contact,
                    method=a.method, **options)
            print(f"  -> {r['turns']:.3f} turns in {r['wall']:.1f} s: {r['message']}", flush=True)
            runs.append(r)
            # written after every run: a long run does not lose the others
            png = plot(runs, os.path.join(a.out, "plectoneme.png"))
            command = "python benchmarks/bench_plectoneme.py " + " ".join(argv or sys.argv[1:])
            report(runs, os.path.join(a.out, "RESULTS_plectoneme.md"), command.strip(), png)
    return runs


if __name__ == "__main__":
    main()
