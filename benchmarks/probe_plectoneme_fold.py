"""Where the plectoneme's path ends: static load steps past the last
equilibrium that the pseudo-dynamics recorded, halved on failure, with the
lowest eigenvalues of the tangent at every converged state.

Usage::

    python benchmarks/probe_plectoneme_fold.py                # 100 elements, frictionless
    python benchmarks/probe_plectoneme_fold.py --upto 1.9375 --step 0.005 --smallest 1e-5

The scene is ``bench_plectoneme.build`` (issue 13).  The solve follows it by
``dynamics=True`` (``max_rotation_step`` pi/8, as the bench's runs) to
``--upto`` turns; from the last recorded equilibrium, with the same
:class:`~skfem_rod.problem.Problem` (its multipliers, crossing keys and
committed state), plain load steps of ``--step`` turns (Newton inside the
augmented-Lagrangian loop, :func:`skfem_rod.augmented.step`) go on; a
failed step is halved until it is below ``--smallest`` turns.  Each
converged state is committed and gets the three lowest eigenvalues of the
symmetrized tangent at frozen multipliers and crossing weights
(:func:`skfem_rod.stability.modes`: a reading, not a stability proof with
contact).  A fold shows as steps that fail at every size beyond one load
factor while the converged states before it approach it with an
eigenvalue going to zero.

This is a probe of the solver's internals (the load stepper is reached by
wrapping ``LoadStepper.keep``), not a user scene.
"""
import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import bench_plectoneme as bp  # noqa: E402

from skfem_rod import solver as solver_module  # noqa: E402
from skfem_rod.augmented import step  # noqa: E402
from skfem_rod.stability import modes  # noqa: E402


def last_equilibrium(n_elements, gamma_T, upto):
    """Solve by pseudo-dynamics to ``upto`` turns; returns the load stepper
    and its last recorded ``(lam, r, R)``."""
    rod = bp.build(n_elements, gamma_T, contact={"curve": "smooth"})
    box = {}
    original = solver_module.LoadStepper.keep

    def keep(self, lam, r, R, rep, t, callback):
        box["S"], box["state"] = self, (lam, r, R)
        return original(self, lam, r, R, rep, t, callback)

    solver_module.LoadStepper.keep = keep
    try:
        lam_end = upto / bp.TURNS
        result = rod.solve(int(round(upto * 16)), path=[0.0, lam_end], dynamics=True,
                           max_rotation_step=np.pi / 8, max_damped_steps=400)
    finally:
        solver_module.LoadStepper.keep = original
    if not result.converged:
        raise SystemExit(f"the pseudo-dynamics did not reach {upto} turns: {result.message}")
    return box["S"], box["state"]


#: a converged state with an eigenvalue below this is on another branch (an
#: unstable one): the step is taken as failed.  The recorded states carry a
#: reading of about -2.3e-5 themselves (see RESULTS_plectoneme.md)
UNSTABLE = -1e-3


def probe(S, state, step_turns, smallest, stay_stable=True):
    """Static steps from ``state``; returns rows ``(turns asked, converged,
    Newton iterations, Uzawa updates, eigenvalues or None, kept)``; with
    ``stay_stable`` a step that converged to a state with an eigenvalue
    below :data:`UNSTABLE` is not kept (halved as a failure)."""
    p, opts = S.problem, S.opts
    lam, r, R = state
    d = step_turns / bp.TURNS
    rows = [(lam * bp.TURNS, True, 0, 0, modes(p, r, R, lam, 3).values, True)]
    while d >= smallest / bp.TURNS:
        saved = p.multipliers.copy()
        r1, R1, rep = step(p, r, R, lam + d, p.prescribed(d), opts)
        ev = modes(p, r1, R1, lam + d, 3).values if rep.converged else None
        kept = rep.converged and not (stay_stable and ev.min() < UNSTABLE)
        rows.append(((lam + d) * bp.TURNS, rep.converged, rep.newton_total, rep.uzawa, ev, kept))
        if kept:
            p.commit(r1, R1, rep.evaluation)
            lam, r, R = lam + d, r1, R1
        else:
            p.multipliers = saved
            d *= 0.5
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--elements", type=int, default=100)
    ap.add_argument("--gamma", type=float, default=0.0)
    ap.add_argument("--upto", type=float, default=1.9375, help="turns by pseudo-dynamics")
    ap.add_argument("--step", type=float, default=0.005, help="first static step (turns)")
    ap.add_argument("--smallest", type=float, default=1e-5,
                    help="stop when a failed step was halved below this (turns)")
    ap.add_argument("--any-branch", action="store_true",
                    help="keep converged states whatever their eigenvalues")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    S, state = last_equilibrium(a.elements, a.gamma, a.upto)
    t1 = time.perf_counter()
    rows = probe(S, state, a.step, a.smallest, stay_stable=not a.any_branch)
    t2 = time.perf_counter()
    print(f"{a.elements} elements, gamma_T = {a.gamma:g}: pseudo-dynamics to {a.upto} turns "
          f"{t1 - t0:.1f} s, static steps {t2 - t1:.1f} s\n")
    print("| turns | converged | kept | Newton its | Uzawa updates | three lowest eigenvalues |")
    print("|---|---|---|---|---|---|")
    for turns, ok, its, uz, ev, kept in rows:
        e = ", ".join(f"{v:.3e}" for v in ev) if ev is not None else ""
        print(f"| {turns:.6f} | {'yes' if ok else 'no'} | {'yes' if kept else 'no'} | {its} "
              f"| {uz} | {e} |")


if __name__ == "__main__":
    main()
