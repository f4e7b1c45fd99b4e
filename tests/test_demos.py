"""Demos are importable, run headless, and write what they promise."""
import importlib.util
import json
import pathlib

import numpy as np
import pytest

DEMOS = pathlib.Path(__file__).resolve().parents[1] / "demos"


def load(name):
    spec = importlib.util.spec_from_file_location(name, DEMOS / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_rollup_demo_writes_results_render_and_series(tmp_path):
    demo = load("rollup")
    summary = demo.main(str(tmp_path), phi=2 * np.pi, n_elements=8, n_steps=2)
    assert summary["converged"]
    data = json.loads((tmp_path / "results.json").read_text())
    # one full loop: the tip comes back to the clamp (8 elements: 1.2e-5 L)
    assert np.linalg.norm(data["tip"]) < 2e-5
    assert data["max_nodal_error_over_L"] < 2e-5
    assert abs(data["strain_energy"] / data["exact_strain_energy"] - 1) < 1e-6
    assert len(list(tmp_path.glob("rollup_*.vtu"))) == 3          # lam = 0, 0.5, 1
    assert (tmp_path / "rollup.pvd").exists()
    import matplotlib.image as mpimg
    img = mpimg.imread(tmp_path / "rollup.png")
    assert img.shape[:2] == (768, 1024)
    assert img[..., :3].std() > 0.05                              # not blank
    red = (img[..., 0] > 0.7) & (img[..., 1] < 0.4) & (img[..., 2] < 0.4)
    assert red.sum() > 100                                        # the d1 stripe
