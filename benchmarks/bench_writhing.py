"""Localized writhing of a clamped rod (PyElastica's helical buckling case,
Gazzola et al., R. Soc. open sci. 2018, 3.4.1), against the localizing
helix (:func:`skfem_rod.analytic.localized_writhing`).

Set-up: ``L = 100``, isotropic bending stiffness ``B = 1.345``, torsional
stiffness ``C = 0.789``, ``EA = GA = 1e5``; both ends clamped; the end
``s = L`` moves toward the start by the slack ``D = 3`` and turns by 27
turns about the axis, both in proportion to the load factor.  A perfect rod
stays on the (unstable) straight branch, so a small transverse dead force
at mid-length (``--imperfection`` times ``B / L^2``, constant) picks the
buckled branch.

Two load paths to the same end conditions (``--path``):

* ``proportional`` (PyElastica's): slack and turns together.  The straight
  rod is compressed 5e5 times past Euler's load long before the twist
  matters, and the path wanders through compressed, contorted states.
* ``rigid`` (default; the protocol of the experiments on localized
  writhing, Thompson & Champneys 1996): first twist the rod by the 27
  turns while its end is held a little beyond the rest length (end
  tension ``T0`` = 1.5 times the Greenhill tension ``M^2 / 4B`` of the
  turns, 0.4995 for 27 turns, so the straight twisted rod is stable: plain
  load steps),
  then bring the end in by the slack plus that stretch with the end
  rotation held (a second rod started from the first's state,
  ``Rod.solve(start=...)``).  Under this rigid loading the localizing
  branch grows out of the Greenhill point stably (tension rising from
  0.333 to 0.390 as the end comes in); only its first step leaves the
  unstable straight state (pushed off along its unstable mode by
  ``stability=True``).  The equilibrium at the end is that of the same
  boundary conditions.

At load factor 1 the solution is compared with the relations of the
localizing helix: the end tension ``T = tau B / L^2``, the end twisting
moment ``M = m B / L``, the largest tangent angle ``theta_max`` and the
share of the 27 turns taken up by twist (``m / gamma / 2 pi``) and by
writhe (``2 arccos(c) / pi``).  The analytic solution is that of the
inextensible, unshearable infinite rod; for this case it is straight at
the ends to 2e-5, and ``EA = 1e5`` stretches the rod by 4e-6 under ``T``.

    python benchmarks/bench_writhing.py [--elements 128] [--steps 30]
        [--path rigid|proportional] [--imperfection 1e-3]
        [--option snap='"relax"' ...] [--results]

prints the figures and the solver's counts (steps, Newton iterations, cut
steps, damped or flow steps, wall time); with ``--results`` appends them to
benchmarks/RESULTS_writhing.md with the command line.
"""
import argparse
import datetime
import json
import sys
import time
from pathlib import Path

import numpy as np

from skfem_rod import Rod, Section, geometry
from skfem_rod.analytic import localized_writhing

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from bench_statics import add_option_arguments, machine_info, parse_options  # noqa: E402

L, B, C, EA = 100.0, 1.345, 0.789, 1e5
SLACK, TURNS = 3.0, 27.0


def build(n_elements=128, imperfection=1e-3, slack=SLACK, turns=TURNS):
    """The clamped rod of the case, along ``+x``; the end turns about ``+x``
    and moves by ``-slack`` along it; a constant transverse dead force
    ``imperfection * B / L^2`` along ``+y`` at mid-length."""
    sec = Section(EA=EA, GA1=EA, GA2=EA, EI1=B, EI2=B, GJ=C, radius=0.35)
    rod = Rod(geometry.straight(L), sec, n_elements)
    rod.clamp("start")
    rod.prescribe_displacement("end", [-slack, 0.0, 0.0])
    rod.prescribe_rotation("end", [2 * np.pi * turns, 0.0, 0.0])
    if imperfection:
        rod.add_force(L / 2, [0.0, imperfection * B / L ** 2, 0.0], constant=True)
    return rod


#: end tension of the twisting stage of the rigid path, in Greenhill
#: tensions M^2 / 4B of the straight twisted rod (0.333 for 27 turns): the
#: straight rod is stable there (the clamped rod's threshold is higher still)
TWIST_TENSION = 1.5


def twist_tension(turns=TURNS):
    """End tension of the twisting stage: ``TWIST_TENSION`` times the
    Greenhill tension ``M^2 / 4B``, ``M = C 2 pi turns / L`` (0.4995 for 27
    turns)."""
    M = C * 2 * np.pi * turns / L
    return TWIST_TENSION * M * M / (4 * B)


def build_rigid(n_elements=128, imperfection=1e-3, slack=SLACK, turns=TURNS):
    """The two rods of the rigid path: ``twist`` (the end held at the stretch
    ``T L / EA``, ``T`` = :func:`twist_tension`, and turned by ``turns``) and
    ``shorten`` (the end rotation held, the end moved in by ``slack`` plus
    that stretch)."""
    stretch = twist_tension(turns) * L / EA
    return (build(n_elements, imperfection, slack=-stretch, turns=turns),
            build(n_elements, imperfection, slack=slack + stretch, turns=0.0))


def solve_rigid(n_elements, n_steps, imperfection, options, slack=SLACK, turns=TURNS):
    """The rigid path: twist in ``max_rotation_step`` steps (plain Newton),
    then shorten in ``n_steps`` steps with ``options``.  Returns the two
    results."""
    twist, shorten = build_rigid(n_elements, imperfection, slack, turns)
    first = twist.solve(1)
    if not first.converged:
        return first, None
    return first, shorten.solve(n_steps, start=first, **options)


def measure(result, step=-1, per_element=16):
    """End tension and twisting moment, largest tangent angle to the axis,
    twist and writhe (turns) of ``result.steps[step]``."""
    force, moment = result.reaction("end", step)
    f = result.sample(per_element, step)
    t = np.einsum("nij,nj->ni", f["R"], f["v"])          # r' = R v
    t = t / np.linalg.norm(t, axis=1)[:, None]
    top = result.topology(step, per_element=per_element)
    return dict(tension=float(force[0]), moment=float(moment[0]),
                theta_max=float(np.arccos(np.clip(t[:, 0], -1.0, 1.0)).max()),
                twist=float(top.twist), writhe=float(top.writhe), link=float(top.link))


def reference(slack=SLACK, turns=TURNS):
    w = localized_writhing(B, C, L, slack, 2 * np.pi * turns)
    gamma = C / B
    return dict(tension=w.tension, moment=w.moment, theta_max=w.theta_max,
                twist=w.m / gamma / (2 * np.pi), writhe=2 * np.arccos(w.c) / np.pi,
                link=turns)


def run(n_elements, n_steps, imperfection, options, path="rigid"):
    """Solve the case on ``path``; returns the last stage's result and the
    figures.  On the rigid path ``load_factor`` is the shortening stage's (0
    when the twisting stage failed)."""
    t0 = time.perf_counter()
    if path == "rigid":
        stages = [r for r in solve_rigid(n_elements, n_steps, imperfection, options)
                  if r is not None]
        converged = len(stages) == 2 and stages[-1].converged
    else:
        stages = [build(n_elements, imperfection).solve(n_steps, **options)]
        converged = stages[0].converged
    wall = time.perf_counter() - t0
    res = stages[-1]
    steps = [st for r in stages for st in r.steps]
    relaxed = [st.relaxed_residual for st in steps if st.relaxed_residual is not None]
    last = res.steps[-1].load_factor if res.steps and (path != "rigid" or len(stages) == 2) \
        else 0.0
    out = dict(elements=n_elements, steps=n_steps, path=path, options=options,
               imperfection=imperfection, converged=bool(converged),
               message=" / ".join(r.message for r in stages), wall_s=wall,
               load_factor=float(last), recorded_steps=len(steps),
               newton=int(sum(st.iterations for st in steps)),
               flow_steps=int(sum(st.flow_steps for st in steps)),
               relaxed_steps=len(relaxed), relaxed_residual_max=max(relaxed, default=None))
    if converged:
        out["fe"] = measure(res)
        out["ref"] = reference()
        out["rel_error"] = {k: abs(out["fe"][k] - out["ref"][k]) / abs(out["ref"][k])
                            for k in out["ref"]}
    return res, out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--elements", type=int, default=128)
    ap.add_argument("--steps", type=int, default=30,
                    help="load steps (of the shortening stage on the rigid path; the "
                         "proportional path needs at least 108 for 27 turns with "
                         "max_rotation_step pi/2)")
    ap.add_argument("--path", choices=("rigid", "proportional"), default="rigid")
    ap.add_argument("--imperfection", type=float, default=1e-3)
    add_option_arguments(ap, "RESULTS_writhing.md")
    a = ap.parse_args(argv)
    options = parse_options(a.option)
    res, out = run(a.elements, a.steps, a.imperfection, options, a.path)
    print(json.dumps({k: v for k, v in out.items()}, indent=1, default=str))
    if a.results:
        lines = [f"\n## {datetime.date.today()} `python benchmarks/bench_writhing.py "
                 + " ".join(argv if argv is not None else sys.argv[1:]) + "`\n",
                 f"{machine_info()}\n",
                 f"converged: {out['converged']} ({out['message']}); load factor "
                 f"{out['load_factor']:.4g}; {out['recorded_steps']} steps, "
                 f"{out['newton']} Newton iterations, {out['flow_steps']} gradient-flow "
                 f"steps, {out['wall_s']:.1f} s; {out['relaxed_steps']} steps end on the "
                 f"gradient flow's state (residual up to {out['relaxed_residual_max']} of the "
                 f"force scale)\n"]
        if out["converged"]:
            lines.append("\n| quantity | FE | localizing helix | rel. error |\n|---|---|---|---|\n")
            for k in out["ref"]:
                lines.append(f"| {k} | {out['fe'][k]:.6g} | {out['ref'][k]:.6g} | "
                             f"{out['rel_error'][k]:.2e} |\n")
        with open(HERE / "RESULTS_writhing.md", "a") as fh:
            fh.writelines(lines)


if __name__ == "__main__":
    main()
