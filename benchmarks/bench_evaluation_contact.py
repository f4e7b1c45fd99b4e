"""Cost of one residual + tangent evaluation with contact: the plectoneme of
``bench_plectoneme.py`` (100 elements, frictionless, smooth contact curve,
crossing contact) solved by pseudo-dynamics towards 1.3 turns, as in the
profile of RESULTS_evaluation.md (2026-11-28).

The solve runs until ``--states`` evaluations with contact and crossing
pairs have been captured (every ``--every``-th of them, from the snap at
about 1.25 turns; deep copies of the :class:`~skfem_rod.problem.Problem`
before the evaluation, so each state is evaluated as the solve did); it
is then stopped.  Per state the script times

* ``evaluate``: ``Problem.evaluate(r, R, lam)`` (residual and tangent,
  contact included);
* ``contact``: its contact part alone (``Problem._contact``: search,
  Gauss-point and crossing pairs' work, on the contact curve and pulled
  back to the rod's dofs);
* ``search``: the Gauss-point contact search alone (with the problem's
  master preference and neighbour list);
* ``crossing_pairs``: the crossing pairs alone (with the held pairs);

each the median of ``--repeat`` calls after one warm-up call; it prints
the mean over the states of those medians, in ms.  The solve is
deterministic, so two source trees capture the same states: compare them
by running the script under each (``PYTHONPATH=<tree>``), interleaved on a
shared machine::

    .venv/bin/python benchmarks/bench_evaluation_contact.py [--states 16] [--repeat 15]
"""
import argparse
import copy
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import bench_plectoneme as bp  # noqa: E402

import skfem_rod  # noqa: E402
from skfem_rod import problem as problem_module  # noqa: E402
from skfem_rod.contact.crossing import crossing_pairs  # noqa: E402
from skfem_rod.contact.search import Preference, search  # noqa: E402


class _Captured(Exception):
    """Raised from the wrapped evaluate to stop the solve once enough
    states are captured."""


def capture(n_states, every):
    """``(problem copy, r, R, lam)`` at every ``every``-th evaluation with
    contact and crossing pairs of the solve, ``n_states`` of them."""
    original = problem_module.Problem.evaluate
    states, seen = [], [0]

    def evaluate(self, r, R, lam, *args, **kwargs):
        before = copy.deepcopy(self) if seen[0] else None
        ev = original(self, r, R, lam, *args, **kwargs)
        c = ev.contact
        if c is not None and c.pairs.size and c.crossing is not None and c.crossing.size:
            seen[0] += 1
            if before is not None and not args and not kwargs and seen[0] % every == 0:
                states.append((before, r.copy(), R.copy(), lam))
                if len(states) >= n_states:
                    raise _Captured
        return ev

    problem_module.Problem.evaluate = evaluate
    try:
        rod = bp.build(100, 0.0, turns=1.3, contact={"curve": "smooth"})
        rod.solve(6, dynamics=True, max_rotation_step=0.3927)
    except _Captured:
        pass
    finally:
        problem_module.Problem.evaluate = original
    return states


def contact_arguments(p, r):
    """The arguments :meth:`Problem._contact_on` gives the search and the
    crossing pairs at ``r`` (on the contact curve)."""
    from skfem_rod.problem import KEEP_MASTER
    c, m, cc = p.contact, p.multipliers, p.contact_curve
    mesh, x = (p.mesh, r) if cc is None else (cc.mesh, cc.positions(r))
    mu = c.penalty / m.penalty_scale
    reach = 2 * c.radius + (mu * m.normal).max(initial=0.0) + c.margin
    s_args = (mesh, x, p.slaves, reach, c.exclusion)
    s_kw = dict(prefer=Preference(p.last_master, KEEP_MASTER * c.tolerance * c.radius),
                neighbours=p.neighbours)
    c_args = (mesh, x, c.radius, c.exclusion)
    held = (m.held_crossing() if hasattr(m, "held_crossing")      # (older trees: a track)
            else p.crossing_track.held(m.crossing_key, m.crossing))
    c_kw = dict(threshold=c.crossing_threshold(), held=held)
    return s_args, s_kw, c_args, c_kw


def median_ms(f, repeat):
    f()
    t = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        t.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(t))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--states", type=int, default=16)
    ap.add_argument("--every", type=int, default=60)
    ap.add_argument("--repeat", type=int, default=15)
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    states = capture(a.states, a.every)
    print(f"{skfem_rod.__file__}: {len(states)} states captured in "
          f"{time.perf_counter() - t0:.1f} s", flush=True)
    out = {"evaluate": [], "contact": [], "search": [], "crossing_pairs": []}
    for p0, r, R, lam in states:
        p = copy.deepcopy(p0)
        out["evaluate"].append(median_ms(lambda: p.evaluate(r, R, lam), a.repeat))
        p = copy.deepcopy(p0)
        out["contact"].append(median_ms(lambda: p._contact(r, R, True), a.repeat))
        p = copy.deepcopy(p0)
        s_args, s_kw, c_args, c_kw = contact_arguments(p, r)
        out["search"].append(median_ms(lambda: search(*s_args, **s_kw), a.repeat))
        out["crossing_pairs"].append(median_ms(lambda: crossing_pairs(*c_args, **c_kw),
                                               a.repeat))
    print("  ".join(f"{k} {np.mean(v):.2f} ms" for k, v in out.items()), flush=True)
    return out


if __name__ == "__main__":
    main()
