"""Crossing contact: cost of the curve-to-curve search per evaluation
against the whole evaluation (:meth:`skfem_rod.problem.Problem.evaluate`
with ``crossing=True``), and of the true-distance check per converged step
(:func:`skfem_rod.contact.crossing.min_distance`).

Scenes (contact radius eps = 0.01, ``Section.circle(E=1e7, nu=0.3)``):

* ``figure-eight``: the figure-eight of tests/test_core.py (two strands
  crossing at 90 degrees, 3 eps apart), 60 and 240 elements;
* ``coil``: a helix of 6 turns, radius 0.1, pitch 2.05 eps (neighbouring
  turns 0.05 eps apart: a line contact along the whole rod, near-parallel
  strands), 100, 200 and 400 elements;
* ``crossed coil``: the same coil with every other node moved by
  +-0.3 eps across the turn (strands that cross the neighbouring turn at
  small angles between slave points), 100 and 400 elements.

Per scene ``repeat`` evaluations (tangent on) at the same state; per
evaluation the wall time of the evaluation, of the crossing part
(``Problem.timers["crossing"]``: minima, held pairs, work) and of the
Gauss-point search; medians.  The machine is shared (2 cores, 4 users):
wall times swing; ratios within one run are what to read.

    .venv/bin/python benchmarks/bench_crossing.py [--repeat 15] \
        [--out benchmarks/RESULTS_crossing.md]
"""
import argparse
import pathlib
import sys
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from skfem_rod import Rod, Section, geometry                  # noqa: E402
from skfem_rod.contact.crossing import min_distance           # noqa: E402
from skfem_rod.problem import Problem                         # noqa: E402

EPS = 0.01


def figure_eight(n):
    from test_core import _figure_eight
    shape, _ = _figure_eight(EPS, 3 * EPS)
    rod = Rod(shape, Section.circle(E=1e7, nu=0.3, radius=EPS), n)
    return rod, rod.r0


def coil(n, crossed=False):
    rod = Rod(geometry.helix(radius=0.1, pitch=2.05 * EPS, turns=6),
              Section.circle(E=1e7, nu=0.3, radius=EPS), n)
    r = rod.r0.copy()
    if crossed:
        rng = np.random.default_rng(0)
        r[::2, 2] += 0.3 * EPS * np.sign(rng.normal(size=r[::2].shape[0]))
    return rod, r


SCENES = [("figure-eight", 60, lambda: figure_eight(60)),
          ("figure-eight", 240, lambda: figure_eight(240)),
          ("coil", 100, lambda: coil(100)),
          ("coil", 200, lambda: coil(200)),
          ("coil", 400, lambda: coil(400)),
          ("crossed coil", 100, lambda: coil(100, True)),
          ("crossed coil", 400, lambda: coil(400, True))]


def measure(build, repeat):
    rod, r = build()
    rod.clamp("start")
    rod.enable_contact(crossing=True)
    p = Problem(rod)
    rows = []
    for _ in range(repeat):
        before = dict(p.timers)
        t0 = time.perf_counter()
        ev = p.evaluate(r, rod.R0, 0.0)
        total = time.perf_counter() - t0
        rows.append((total, p.timers["crossing"] - before.get("crossing", 0.0),
                     p.timers["contact_search"] - before.get("contact_search", 0.0)))
    md = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        min_distance(rod.mesh, r, EPS, rod.contact.exclusion)
        md.append(time.perf_counter() - t0)
    rows = np.array(rows)
    cp = ev.contact.crossing
    return dict(evaluate=np.median(rows[:, 0]), crossing=np.median(rows[:, 1]),
                search=np.median(rows[:, 2]), min_distance=np.median(md),
                share=np.median(rows[:, 1] / rows[:, 0]), pairs=int(cp.size),
                gauss=int(ev.contact.pairs.size))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15)
    ap.add_argument("--out", default=None)
    a = ap.parse_args(argv)
    if a.repeat < 1:
        raise ValueError(f"repeat must be >= 1, got {a.repeat}")
    lines = ["| scene | elements | evaluation (ms) | crossing (ms) | crossing / evaluation "
             "| Gauss-point search (ms) | min_distance (ms) | crossing pairs | Gauss pairs |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name, n, build in SCENES:
        m = measure(build, a.repeat)
        lines.append(f"| {name} | {n} | {1e3 * m['evaluate']:.1f} | {1e3 * m['crossing']:.1f} "
                     f"| {m['share']:.2f} | {1e3 * m['search']:.1f} "
                     f"| {1e3 * m['min_distance']:.1f} | {m['pairs']} | {m['gauss']} |")
        print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    if a.out:
        pathlib.Path(a.out).write_text(text)
    return text


if __name__ == "__main__":
    main()
