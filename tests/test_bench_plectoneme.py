"""benchmarks/bench_plectoneme.py's ``run`` as its users call it: the
wall-time budget is the solve's ``time_limit`` (it stops wherever the solve
is, in a damped phase too), and what the run reached is reported from the
recorded equilibria."""
import numpy as np

from helpers import load_bench

bench = load_bench("bench_plectoneme")


def test_a_run_stops_at_its_budget_and_reports_what_it_reached():
    out = bench.run(20, 0.0, turns=10.0, budget=2.0, verbose=False)
    assert out["stopped"] == "budget"
    assert "the time limit ran out (time_limit=2 s)" in out["message"]
    assert not out["result"].converged
    turns = np.array([r["turns"] for r in out["records"]])
    assert turns[0] == 0.0 and np.all(np.diff(turns) > 0)
    assert out["turns"] == turns[-1] < 10.0
    assert len(out["result"].steps) == len(out["records"])
    assert out["flow_steps"] == 0
