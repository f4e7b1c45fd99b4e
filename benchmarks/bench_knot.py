"""The knot's tighten-and-loosen cycle of demos/knot.py, as issue 13 measures
it: under 60 s per run, no Uzawa or iteration limit hit, and, without
friction, the tightening and loosening branches within 1e-3 of the force.

Ties the knot once (``knot.tie``, 60 elements by default), then runs the
cycle of ``knot.solve`` from it (the end pulled by 0.2 in ``--steps`` steps
and brought back in as many) with the demo's solver options, replaced or
extended by ``--option name=value`` (JSON values, repeatable), and the
cycle's contact options by ``--contact name=value``.  Reports the
wall time of the tying and of the cycle, the gradient-flow steps, Newton
iterations and Uzawa updates of the cycle, the steps whose Uzawa loop
stopped at its limit (step, updates, penetration) and the number of steps that end on the gradient flow's state
(``RelaxedShortfall``), the largest up/down mismatch of the force over the
pairs of steps at the same load factor (the tied state excluded), relative
to the largest force, the load factors whose forces agree to 1e-4 of it,
and every force of the cycle.  ``--pretighten`` starts the cycle from the
knot after one frictionless cycle (the tied knot is another arrangement of
the loops, which the first pull leaves by a jump: docs/knot.md).

    python benchmarks/bench_knot.py [--gamma 0] [--elements 60] [--steps 10] \\
        [--option position_correction=false ...] [--contact penalty_memory=true ...] \\
        [--pretighten] [--results]

``--results`` appends the report to benchmarks/RESULTS_knot.md.
"""
import argparse
import datetime
import json
import shlex
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
from bench_statics import add_option_arguments, machine_info, parse_options  # noqa: E402
from helpers import load_demo  # noqa: E402

knot = load_demo("knot")


def run(gamma=0.0, elements=60, steps=10, pull=0.2, options=None, contact=None,
        pretighten=False):
    """Tie, then cycle; returns the figures of the module doc.  ``contact``:
    contact options of the cycle's rod (``enable_contact`` keywords; the
    knot is tied with the defaults).  ``pretighten``: the cycle starts from
    the knot after one frictionless cycle (the tied knot is another
    arrangement of the loops, which the first pull leaves by a jump;
    docs/knot.md), its time counted with the tying's."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")          # shortfalls are counted below
        t0 = time.perf_counter()
        tied = knot.tie(elements)
        if pretighten:
            tied = knot.tighten(tied, pull, elements, steps)
        t_tie = time.perf_counter() - t0
        sol = knot.solve(gamma, pull, elements, steps, start=tied, options=options,
                         **(contact or {}))
    res, rows = sol["result"], sol["rows"]
    F = np.array([w["force"] for w in rows])
    pairs = [(i, j) for i, j in knot.same_load_pairs(rows) if rows[i]["load_factor"] > 0]
    # no pair of steps (a cycle stopped before it turned back): no mismatch
    gaps = (np.array([abs(F[i] - F[j]) for i, j in pairs]) / np.abs(F).max()
            if pairs else np.zeros(0))
    mismatch = gaps.max() if gaps.size else np.nan
    steps_ = res.steps
    return dict(gamma=gamma, elements=elements, steps=steps, options=options or {},
                contact=contact or {},
                converged=bool(res.converged), message=res.message,
                tie_s=t_tie, cycle_s=sol["wall_time_s"],
                flow_steps=int(sum(st.flow_steps for st in steps_)),
                newton=int(sum(st.iterations for st in steps_)),
                uzawa=int(sum(st.contact.uzawa for st in steps_ if st.contact is not None)),
                uzawa_limit=[(k, st.contact.uzawa, float(st.contact.penetration))
                             for k, st in enumerate(steps_)
                             if st.contact is not None and not st.contact.uzawa_converged],
                relaxed_shortfall=int(sum(st.relaxed_residual is not None for st in steps_)),
                mismatch=float(mismatch),
                reversible=[round(float(rows[i]["load_factor"]), 6)
                            for (i, j), g in zip(pairs, gaps) if g <= 1e-4],
                pretighten=bool(pretighten), forces=[round(float(f), 4) for f in F])


def report(out, argv):
    cmd = "python benchmarks/bench_knot.py " + shlex.join(argv)
    return "\n".join([
        f"\n## {datetime.date.today()} `{cmd}`\n",
        f"{machine_info()}\n",
        f"{out['message']}; tying {out['tie_s']:.1f} s, cycle {out['cycle_s']:.1f} s; "
        f"{out['flow_steps']} gradient-flow steps, {out['newton']} Newton iterations, "
        f"{out['uzawa']} Uzawa updates; steps stopped at the Uzawa limit (step, updates, "
        f"penetration): {out['uzawa_limit'] or 'none'}; "
        f"{out['relaxed_shortfall']} steps on the flow's state; up/down mismatch "
        f"{100 * out['mismatch']:.2f} % of the largest force; load factors whose "
        f"forces up and down agree to 1e-4 of it: {out['reversible'] or 'none'}"
        + (" (the cycle from the knot after one frictionless cycle; its time is in "
           "the tying's)" if out["pretighten"] else "") + "\n",
        "forces: " + ", ".join(f"{f:.4f}" for f in out["forces"]) + "\n"])


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--gamma", type=float, default=0.0, help="tangential friction gamma_T")
    ap.add_argument("--elements", type=int, default=60)
    ap.add_argument("--steps", type=int, default=10, help="steps each way")
    ap.add_argument("--pretighten", action="store_true",
                    help="start the cycle from the knot after one frictionless cycle")
    ap.add_argument("--contact", action="append", default=[],
                    help="contact option name=value (JSON value) of the cycle, repeatable")
    add_option_arguments(ap, "RESULTS_knot.md")
    a = ap.parse_args(argv)
    out = run(a.gamma, a.elements, a.steps, options=parse_options(a.option),
              contact=parse_options(a.contact), pretighten=a.pretighten)
    print(json.dumps(out, indent=1, default=str))
    if a.results:
        path = HERE / "RESULTS_knot.md"
        head = "" if path.exists() else (
            "# The knot's tighten-and-loosen cycle (issue 13)\n\n"
            "Scene, options and columns: `benchmarks/bench_knot.py` docstring; "
            "discussion: docs/knot.md.  One run per entry; wall times on the shared "
            "2-core machine.\n")
        with open(path, "a") as f:
            f.write(head + report(out, argv))


if __name__ == "__main__":
    main()
