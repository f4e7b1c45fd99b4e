"""The pressed figure-eight of tests/test_core.py to load factor 1.

Two strands of a figure-eight (lemniscate of Gerono, both ends clamped,
contact radius eps = 0.01, ``Section.circle(E=1e7, nu=0.3)``) cross at 90
degrees 3 eps apart, between slave points (elements 9 eps long), and are
pressed together by opposite point forces of 2 N at the crossing.
Crossing contact (``crossing=True``) holds them apart.  Plain load stepping
stops near load factor 0.72, where the tangent turns indefinite
(docs/crossing-contact.md).  Here the solve runs with ``snap="relax",
stability=True``: a failed step is relaxed by the gradient flow, and an
unstable equilibrium is pushed off along its unstable mode and relaxed.

Per recorded step: the gradient-flow steps, Newton iterations, the lowest
eigenvalue of the symmetrized tangent on the free dofs, the true smallest
distance between the strands (closest points, both parameters free), and
the height of the downward-pushed load point above the upward-pushed one.
Renders the start, the step where the strands have slid off each other,
and the end.

    .venv/bin/python benchmarks/bench_figure_eight.py [--steps 10] \
        [--elements 60] [--out benchmarks/RESULTS_figure_eight.md] [--png DIR]
"""
import argparse
import pathlib
import sys
import time
import warnings

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from skfem_rod import Rod, Section                            # noqa: E402
from skfem_rod.contact.crossing import min_distance           # noqa: E402

EPS = 0.01
FORCE = 2.0


def build(n_elements=60):
    """The rod, and the node indices of the downward and upward load."""
    from test_core import _figure_eight
    shape, (s1, s2) = _figure_eight(EPS, 3 * EPS)
    rod = Rod(shape, Section.circle(E=1e7, nu=0.3, radius=EPS), n_elements)
    rod.clamp("start").clamp("end")
    sn = rod.mesh.s_nodes
    down, up = int(np.argmin(abs(sn - s1))), int(np.argmin(abs(sn - s2)))
    rod.add_force(float(sn[down]), [0.0, 0.0, -FORCE])
    rod.add_force(float(sn[up]), [0.0, 0.0, FORCE])
    rod.enable_contact(crossing=True)
    return rod, down, up


def run(n_steps=10, n_elements=60, **options):
    """Solve with ``snap="relax", stability=True`` (overridable by
    ``options``); returns ``(rod, result, rows, seconds, warnings)``."""
    rod, down, up = build(n_elements)
    kw = dict(snap="relax", stability=True)
    kw.update(options)
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = rod.solve(n_steps, **kw)
    seconds = time.perf_counter() - t0
    rows = []
    for st in res.steps:
        md = min_distance(rod.mesh, st.r, EPS, rod.contact.exclusion)
        rows.append(dict(lam=st.load_factor, flow=st.flow_steps, newton=st.iterations,
                         eig=st.lowest_eigenvalue, distance=md.distance,
                         penetration=md.penetration(EPS),
                         height=float(st.r[down, 2] - st.r[up, 2]),
                         relaxed=st.relaxed_residual))
    return rod, res, rows, seconds, [str(w.message) for w in caught]


def table(rows):
    lines = ["| load factor | flow steps | Newton iterations | lowest eigenvalue "
             "| true distance / 2 eps - 1 | height of the pushed-down point (eps) |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        eig = "" if r["eig"] is None else f"{r['eig']:.2e}"
        lines.append(f"| {r['lam']:.2f} | {r['flow']} | {r['newton']} | {eig} "
                     f"| {r['distance'] / (2 * EPS) - 1:.1e} | {r['height'] / EPS:.1f} |")
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=10)
    ap.add_argument("--elements", type=int, default=60)
    ap.add_argument("--out", default=None)
    ap.add_argument("--png", default=None, help="directory for the renders")
    a = ap.parse_args(argv)
    if a.steps < 1 or a.elements < 6:
        raise ValueError(f"steps must be >= 1 and elements >= 6, got {a.steps}, {a.elements}")
    rod, res, rows, seconds, caught = run(a.steps, a.elements)
    cmd = ("benchmarks/bench_figure_eight.py " + " ".join(argv if argv is not None
                                                          else sys.argv[1:])).strip()
    lines = [f"`{cmd}` ({time.strftime('%Y-%m-%d')}, 2-core shared machine, one run)", "",
             f"{res.message}; {seconds:.1f} s; gradient-flow steps "
             f"{sum(r['flow'] for r in rows)}; warnings: {caught or 'none'}", ""]
    lines += table(rows)
    lines += ["", "Pushes off saddles (`Result.log`):", ""]
    lines += [f"* {line}" for line in res.log if "unstable" in line] or ["* none"]
    text = "\n".join(lines) + "\n"
    print(text)
    if a.out:
        path = pathlib.Path(a.out)
        tmp = path.with_suffix(".tmp")
        tmp.write_text(text)
        tmp.replace(path)
    if a.png:
        import pyvista
        pyvista.OFF_SCREEN = True
        out = pathlib.Path(a.png)
        out.mkdir(parents=True, exist_ok=True)
        slid = next((k for k, r in enumerate(rows) if r["height"] < 0), len(rows) - 1)
        for k in sorted({0, slid, len(rows) - 1}):
            res.render(out / f"figure_eight_{k:02d}.png", step=k, camera="iso",
                       title=f"pressed figure-eight, load factor {rows[k]['lam']:.2f}")
    return text


if __name__ == "__main__":
    main()
