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
    # the iterations by kind of solve add up to the run's figures
    b = out["by_kind"]
    log = out["result"].dynamics
    assert sum(v["accepted"] + v["failed"] for v in b.values()) == out["solves"] == len(log.kind)
    assert sum(v["accepted_its"] + v["failed_its"] for v in b.values()) == out["newton_total"]
    assert b["damped"]["accepted"] == out["damped"]
    assert sum(v["failed"] for v in b.values()) == out["rejected"]


def test_runs_printed_side_by_side_are_plotted_from_their_logs(tmp_path, capsys):
    """``--plot-logs``: the runs a printout holds (heading and step lines as
    ``run`` prints them) are read back as records, the figure is written."""
    out = bench.run(20, 0.3, turns=10.0, budget=1.0)
    printed = capsys.readouterr().out
    log = tmp_path / "run.log"
    log.write_text("20 elements, gamma_T = 0.3\n" + printed + "  -> done\n")
    runs = bench.main(["--plot-logs", str(log), "--out", str(tmp_path)])
    assert len(runs) == 1 and (runs[0]["n_elements"], runs[0]["gamma_T"]) == (20, 0.3)
    got = [(q["turns"], q["x_end"], q["torque"], q["contacts"]) for q in runs[0]["records"]]
    want = [(round(q["turns"], 3), round(q["x_end"], 4), round(q["torque"], 4), q["contacts"])
            for q in out["records"]]
    assert got == want and len(got) > 1
    assert (tmp_path / "plectoneme.png").stat().st_size > 0


def test_a_relax_run_reports_its_recorded_steps():
    """``method="relax"`` (``snap="relax"``, ``stability=True``): no damped
    step, one solve per recorded step after step 0, its Newton iterations
    and true penetration those of the steps."""
    out = bench.run(20, 0.0, turns=10.0, budget=2.0, verbose=False, method="relax")
    res = out["result"]
    assert getattr(res, "dynamics", None) is None and out["damped"] == 0
    assert out["solves"] == len(res.steps) - 1 >= 1
    assert out["newton_total"] == sum(st.iterations for st in res.steps[1:])
    assert out["by_kind"]["static"]["accepted"] == out["solves"]


def test_an_unknown_method_is_refused():
    import pytest
    with pytest.raises(ValueError, match="method must be"):
        bench.run(20, 0.0, budget=1.0, verbose=False, method="flow")
