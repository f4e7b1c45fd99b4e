"""Progress of a solve: ``progress=True`` (a tqdm bar over pseudo-time, or
log records without tqdm), ``progress="log"``; the user's callback still
runs."""
import logging
import sys

import pytest

from skfem_rod import Rod, Section, geometry


def cantilever():
    rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
    return rod.clamp("start").add_force("end", [0.0, 0.01, 0.0])


def test_progress_log_records_every_step_and_keeps_the_callback(caplog):
    seen = []
    with caplog.at_level(logging.INFO, logger="skfem_rod"):
        res = cantilever().solve(3, progress="log", callback=lambda r, k: seen.append(k))
    lines = [r.getMessage() for r in caplog.records if r.name == "skfem_rod.progress"]
    assert seen == [0, 1, 2, 3] and len(lines) == 4
    assert lines[-1].startswith("step 3: load factor 1, Newton")
    assert res.converged


def test_progress_bar_without_tqdm_falls_back_to_the_log(caplog, monkeypatch):
    monkeypatch.setitem(sys.modules, "tqdm.auto", None)          # import fails
    with caplog.at_level(logging.INFO, logger="skfem_rod"):
        cantilever().solve(2, progress=True)
    text = caplog.text
    assert "tqdm is not installed" in text and "step 2: load factor 1" in text


def test_progress_bar_reaches_the_end_of_the_path(capsys):
    pytest.importorskip("tqdm")
    cantilever().solve(4, path=[0, 1, 0], progress=True)
    err = capsys.readouterr().err
    assert "100%" in err and "load factor 0, Newton" in err


def test_progress_rejects_unknown_values():
    with pytest.raises(ValueError, match="progress must be"):
        cantilever().solve(1, progress="yes")
