"""Contact search: time and peak memory against the element count.

Hairpin (two legs 1.98 eps apart joined by a half circle: the legs touch
along their whole length), contact radius eps = 1, reach 3 eps, exclusion
pi eps, three slave points per element.  Two rod lengths so that the
element size spans 0.1 to 10 contact radii:

* ``long``:  length 5000 eps, 500..8000 elements, h = 10 .. 0.625 eps;
* ``short``: length  800 eps, 500..8000 elements, h = 1.6 .. 0.1 eps.

Every (scene, n) runs in its own subprocess: the search is timed (best of
``repeat``; CPU time of the process, ``time.process_time``, for the fit:
the machine is shared and wall times swing by factors of 2-5 under load)
and its peak memory is ``ru_maxrss`` after the searches minus
``ru_maxrss`` before them (imports and the rod's arrays; the searches'
own allocations only).  Log-log slopes of time and memory against n are
fitted per scene.  ``--reference`` also runs the search as it was before
the bounded broad phase (tests/search_reference.py) where it fits in
memory.

    .venv/bin/python benchmarks/bench_search.py [--reference] [--out benchmarks/RESULTS_search.md]
"""
import argparse
import json
import pathlib
import subprocess
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
SIZES = [500, 1000, 2000, 4000, 8000]
SCENES = {"long": 5000.0, "short": 800.0}
EPS = 1.0


def hairpin_mesh(length, n, spacing=1.98 * EPS):
    """A mesh-like object (the arrays the search reads, numbered as
    :class:`skfem_rod.mesh.RodMesh` numbers them) and nodal positions of the
    hairpin of total ``length`` on ``n`` uniform cubic elements."""
    from types import SimpleNamespace
    Rb = spacing / 2
    leg = (length - np.pi * Rb) / 2
    v = np.linspace(0.0, length, n + 1)
    nodes = np.stack([np.arange(n), np.arange(1, n + 1),
                      n + 1 + 2 * np.arange(n), n + 2 + 2 * np.arange(n)], axis=1)
    s = np.empty(3 * n + 1)
    s[:n + 1] = v
    s[n + 1::2] = v[:-1] + (v[1:] - v[:-1]) / 3
    s[n + 2::2] = v[:-1] + 2 * (v[1:] - v[:-1]) / 3
    r = np.zeros((s.size, 3))
    a = s < leg
    r[a, 0] = leg - s[a]
    b = (s >= leg) & (s < leg + np.pi * Rb)
    th = (s[b] - leg) / Rb
    r[b, 0], r[b, 1] = -Rb * np.sin(th), Rb - Rb * np.cos(th)
    c = s >= leg + np.pi * Rb
    r[c, 0], r[c, 1] = s[c] - leg - np.pi * Rb, 2 * Rb
    return SimpleNamespace(vertices=v, nodes=nodes, closed=False), r


def _child(scene, n, reference, repeat):
    import resource
    import time
    sys.path.insert(0, str(ROOT / "tests"))
    from skfem_rod.contact.search import search, slave_points
    fn = search
    if reference:
        from search_reference import search_dense as fn
    mesh, r = hairpin_mesh(SCENES[scene], n)
    sl = slave_points(mesh, 3)
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    times, cpu = [], []
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        pairs = fn(mesh, r, sl, 3 * EPS, np.pi * EPS)
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(json.dumps(dict(scene=scene, n=n, h=SCENES[scene] / n, time=min(times), cpu=min(cpu),
                          rss_base_kib=base, rss_peak_kib=peak, search_kib=peak - base,
                          pairs=int(pairs.size), candidates=int(pairs.n_candidates))))


def run(scene, n, reference=False, repeat=3):
    out = subprocess.run([sys.executable, __file__, "--child", scene, str(n),
                          "--repeat", str(repeat)] + (["--reference"] if reference else []),
                         capture_output=True, text=True, check=True, cwd=ROOT)
    return json.loads(out.stdout.strip().splitlines()[-1])


def slope(x, y):
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--child", nargs=2)
    ap.add_argument("--reference", action="store_true")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--out")
    a = ap.parse_args()
    if a.child:
        _child(a.child[0], int(a.child[1]), a.reference, a.repeat)
        return
    lines = ["| scene | n | h / eps | pairs | projections | CPU time [ms] | wall time [ms] "
             "| search peak RSS [MiB] |"
             + (" reference CPU time [ms] | reference peak RSS [MiB] |" if a.reference else ""),
             "|---|---|---|---|---|---|---|---|" + ("---|---|" if a.reference else "")]
    slopes = {}
    for scene in SCENES:
        rows = [run(scene, n, repeat=a.repeat) for n in SIZES]
        refs = ([run(scene, n, True, 1) if n * SCENES["long"] / SCENES[scene] >= 2000 or n <= 2000
                 else None for n in SIZES] if a.reference else [None] * len(SIZES))
        for row, ref in zip(rows, refs):
            line = (f"| {scene} | {row['n']} | {row['h']:.3g} | {row['pairs']} | "
                    f"{row['candidates']} | {1e3 * row['cpu']:.1f} | {1e3 * row['time']:.1f} | "
                    f"{row['search_kib'] / 1024:.1f} |")
            if a.reference:
                line += (f" {1e3 * ref['cpu']:.1f} | {ref['search_kib'] / 1024:.1f} |"
                         if ref else " - | - |")
            lines.append(line)
            print(line, flush=True)
        n = np.array([row["n"] for row in rows])
        slopes[scene] = (slope(n, [row["cpu"] for row in rows]),
                         slope(n, [max(row["search_kib"], 1) for row in rows]))
    lines.append("")
    for scene, (st, sm) in slopes.items():
        lines.append(f"- {scene}: CPU-time slope {st:.2f}, peak-memory slope {sm:.2f}")
        print(lines[-1])
    if a.out:
        pathlib.Path(a.out).write_text("\n".join(lines) + "\n")
    return slopes


if __name__ == "__main__":
    main()
