"""Sweep benchmark: a 16-point sweep on 2 local Dask workers against a
plain serial loop, and the overhead per point of the Dask path.

Three ways to solve the same 16 points (a 4 x 4 grid of tip load and
Young's modulus of a 24-element cantilever in 8 load steps, about a second
a point):

* ``loop``: ``skfem_rod.sweeps.run_point`` in a plain loop, in this
  process (no Dask, no files);
* ``dask-1``: :func:`skfem_rod.sweep` on a LocalCluster of 1 worker
  (cluster start-up, worker imports, scheduling, one point file each and
  the dataset included);
* ``dask-2``: the same on 2 workers.

Speed-up = loop / dask-2; overhead per point = (dask-1 - loop) / points,
and the part of it that is the cluster's start-up and shutdown (an empty
LocalCluster of 1 worker, timed alone).  Each is the median of
``--repeat`` runs (the machine is shared; medians are less noisy).

    python benchmarks/bench_sweep.py [--repeat 3] [--points 16] [--out benchmarks]

writes ``RESULTS_sweep.md`` (with the command, machine and numbers).
"""
import argparse
import os
import platform
import shutil
import statistics
import sys
import tempfile
import time

os.environ.setdefault("DASK_LOGGING__DISTRIBUTED", "warning")

from skfem_rod.scene import load_scene                      # noqa: E402
from skfem_rod.sweeps import local_cluster, run_point, sweep, sweep_points  # noqa: E402

SCENE = {
    "rod": {"geometry": {"type": "straight", "length": 1.0}, "n_elements": 24},
    "section": {"E": 1e7, "nu": 0.3, "radius": 0.01},
    "support": [{"where": "start", "kind": "clamp"}],
    "load": [{"kind": "force", "where": "end", "vector": [0.0, 0.0, -0.1]}],
    "solver": {"n_steps": 8},
}


def grid(points):
    n = int(round(points ** 0.5))
    assert n * n == points, "--points must be a square"
    return {"section.E": [1e7 * (1 + 0.25 * i) for i in range(n)],
            "load[0].vector[2]": [-0.04 * (1 + j) for j in range(n)]}


def time_dask(scene, params, n_workers):
    """Wall time of the sweep, and the sum of its points' solve times (on
    the workers)."""
    out = tempfile.mkdtemp(prefix="bench_sweep_")
    try:
        t0 = time.perf_counter()
        ds = sweep(scene, params, out=out, n_workers=n_workers, resume=False)
        wall = time.perf_counter() - t0
    finally:
        shutil.rmtree(out, ignore_errors=True)
    assert bool(ds.converged.all())
    return wall, float(ds.wall_time.sum()), float(ds.cpu_time.sum())


def time_loop_solves(scene, params):
    pts, _ = sweep_points(scene, params)
    t0 = time.perf_counter()
    recs = [run_point(p.data, "bench", p.values) for p in pts]
    wall = time.perf_counter() - t0
    assert all(r["converged"] for r in recs)
    return wall, sum(r["wall_time"] for r in recs), sum(r["cpu_time"] for r in recs)


def time_cluster():
    from dask.distributed import Client
    t0 = time.perf_counter()
    with local_cluster(1) as cluster, Client(cluster):
        pass
    return time.perf_counter() - t0


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--points", type=int, default=16)
    ap.add_argument("--out", default=os.path.dirname(os.path.abspath(__file__)))
    args = ap.parse_args(argv)
    scene = load_scene(SCENE, name="bench")
    params = grid(args.points)
    time_loop_solves(scene, {k: v[:1] for k, v in params.items()})   # warm the imports
    runs = {"loop": [], "dask-1": [], "dask-2": [], "cluster": []}
    solves = {"loop": [], "dask-1": [], "dask-2": []}      # sum of the points' solve times
    cpus = {"loop": [], "dask-1": [], "dask-2": []}        # and of their CPU times
    for r in range(args.repeat):
        for name, f in (("loop", lambda: time_loop_solves(scene, params)),
                        ("dask-2", lambda: time_dask(scene, params, 2)),
                        ("dask-1", lambda: time_dask(scene, params, 1))):
            wall, solve, cpu = f()
            runs[name].append(wall)
            solves[name].append(solve)
            cpus[name].append(cpu)
        runs["cluster"].append(time_cluster())
        print(f"repeat {r + 1}: " + ", ".join(f"{k} {v[-1]:.2f} s" for k, v in runs.items()),
              flush=True)
    med = {k: statistics.median(v) for k, v in runs.items()}
    med_solve = {k: statistics.median(v) for k, v in solves.items()}
    med_cpu = {k: statistics.median(v) for k, v in cpus.items()}
    n = args.points
    speedup = med["loop"] / med["dask-2"]
    overhead = (med["dask-1"] - med["loop"]) / n
    per_point = (med["dask-1"] - med["loop"] - med["cluster"]) / n
    try:
        load = os.getloadavg()
    except OSError:
        load = (float("nan"),) * 3
    cmd = "python benchmarks/bench_sweep.py" + (" " + " ".join(argv if argv is not None
                                                              else sys.argv[1:])).rstrip()
    lines = [
        "# Sweep benchmark (Dask)",
        "",
        f"Command: `{cmd}`  ",
        f"Machine: {platform.machine()}, {os.cpu_count()} CPUs, Python "
        f"{platform.python_version()}, load average at the end {load[0]:.1f} "
        "(shared by other jobs: numbers are medians of the repeats)",
        "",
        f"{n} points (a {int(n ** 0.5)} x {int(n ** 0.5)} grid of tip load and E of a "
        "24-element cantilever, 8 load steps each); medians of "
        f"{args.repeat} repeats (s):",
        "",
        "| run | median (s) | runs (s) | points' solve times, summed (median, s) "
        "| their CPU times, summed (median, s) |",
        "| --- | ---: | --- | ---: | ---: |",
    ]
    what = {"loop": "plain loop of run_point (serial, no Dask)",
            "dask-1": "skfem_rod.sweep, LocalCluster of 1 worker",
            "dask-2": "skfem_rod.sweep, LocalCluster of 2 workers",
            "cluster": "start and close an empty LocalCluster (1 worker)"}
    for k in runs:
        lines.append(f"| {what[k]} | {med[k]:.2f} | "
                     + ", ".join(f"{v:.2f}" for v in runs[k])
                     + (f" | {med_solve[k]:.2f} | {med_cpu[k]:.2f} |" if k in med_solve
                        else " | | |"))
    lines += [
        "",
        f"- speed-up of 2 workers over the serial loop: **{speedup:.2f}x** "
        f"({med['loop'] / n:.2f} s per point serially)",
        f"- overhead of the Dask path per point (dask-1 - loop) / {n}: "
        f"**{overhead:.2f} s**, of which the cluster start-up and shutdown is "
        f"{med['cluster'] / n:.2f} s; the rest, {per_point:.3f} s per point, is "
        "scheduling, worker imports, the point files and the dataset",
        f"- the points' own solve times, summed: loop {med_solve['loop']:.2f} s, "
        f"1 worker {med_solve['dask-1']:.2f} s, 2 workers {med_solve['dask-2']:.2f} s; "
        "the share of a core a solving process got (CPU / wall time): "
        + ", ".join(f"{k} {med_cpu[k] / med_solve[k]:.2f}" for k in med_solve)
        + " (the machine is shared with other jobs: with less than two free cores, "
        "two workers cannot halve the time)",
        "",
    ]
    path = os.path.join(args.out, "RESULTS_sweep.md")
    with open(path, "w") as f:
        f.write("\n".join(lines))
    print("\n".join(lines))
    return dict(median=med, speedup=speedup, overhead=overhead)


if __name__ == "__main__":
    main()
