"""benchmarks/bench_plectoneme_barrier.py as its users call it: several
step sizes give one run each (with friction each its own path through the
slips), their figures, renders and the median wall time per set-up."""
import json

import numpy as np
import pytest

from helpers import load_bench

bench = load_bench("bench_plectoneme_barrier")


@pytest.mark.filterwarnings("ignore::skfem_rod.minimize.BarrierResolution")
def test_several_step_sizes_give_a_run_each_and_their_median_wall(tmp_path, capsys):
    out = tmp_path / "pb"
    bench.main(["--elements", "20", "--gammas", "0", "--turns", "0.25",
                "--step", "0.125", "0.0625", "--budget", "60", "--out", str(out)])
    data = json.loads((tmp_path / "pb.json").read_text())
    runs = data["runs"]
    assert [q["step"] for q in runs] == [0.125, 0.0625]
    for q in runs:
        # every turn applied, the link the turns (twist + writhe of the rod)
        assert q["stop"] == "" and q["turns"] == pytest.approx(0.25)
        assert [r["turns"] for r in q["records"]][-1] == pytest.approx(0.25)
        assert q["records"][-1]["link"] == pytest.approx(0.25, abs=1e-9)
        assert len(q["records"]) == round(0.25 / q["step"])      # the steps after step 0
    (row,) = data["summary"]
    walls = [q["wall"] for q in runs]
    assert (row["n_elements"], row["gamma_T"], row["runs"], row["reached"]) == (20, 0.0, 2, 2)
    assert row["steps"] == [0.125, 0.0625]
    assert row["median_wall"] == pytest.approx(np.median(walls))
    assert (row["min_wall"], row["max_wall"]) == (min(walls), max(walls))
    assert "2 of 2 run(s) reached 0.25 turns" in capsys.readouterr().out
    for name in ("pb.png", "pb_20_0_step0.125.png", "pb_20_0_step0.0625.png"):
        assert (tmp_path / name).stat().st_size > 0
