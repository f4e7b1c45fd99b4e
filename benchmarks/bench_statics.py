"""Static benchmarks of skfem_rod: accuracy, cost per Newton iteration,
profile and memory of the assembly.

Usage::

    python benchmarks/bench_statics.py            # full run -> benchmarks/RESULTS.md
    python benchmarks/bench_statics.py --quick    # smoke run -> benchmarks/RESULTS_quick.md
    python benchmarks/bench_statics.py --output some/file.md

Sections (each printed as markdown and written to the output file):

1. Accuracy and solve cost of the roll-up (end moment, phi = 2 pi) and of
   the tip-loaded cantilever (P L^2 / EI = 2) for 2..64 elements.
2. Cost of one Newton iteration (assembly of residual + tangent, residual
   only, sparse factorization + solve) for 10..10000 elements at a deformed
   state, with the log-log slopes and the assembly/solve ratio.
3. Where the assembly spends its time: a stage-by-stage timing of
   ``internal_work`` and a cProfile of one assembly at 1000 elements.
4. Peak memory (tracemalloc) of one assembly at 10000 elements.
5. Round-off floor of the residual vs the convergence threshold of the
   Newton solver (why large meshes may never reach "converged").

The machine may be shared: every time is a median of repeats, and the
quantities that are compared (ratios) are measured interleaved in one run.
"""
import argparse
import cProfile
import datetime
import gc
import importlib.metadata
import io
import os
import platform
import pstats
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np
import scipy
import scipy.sparse.linalg as spla

from skfem_rod import Rod, Section, geometry, analytic
from skfem_rod.assembly import internal_work, shape_operator
from skfem_rod.rotations import expm
from skfem_rod.solver import _System, SolverOptions, _update

HERE = Path(__file__).resolve().parent

# problem data (brief): EA = GA = 1e4, EI = GJ = 1, L = 1
L = 1.0
EA = GA = 1e4
EI = GJ = 1.0
PHI = 2 * np.pi            # roll-up angle: M = PHI EI / L
ALPHA = 2.0                # cantilever load parameter P L^2 / EI
N_STEPS = 4                # fixed number of load steps asked from the solver


def section():
    return Section(EA=EA, GA1=GA, GA2=GA, EI1=EI, EI2=EI, GJ=GJ)


def make_rod(case, n_elements):
    rod = Rod(geometry.straight(L), section(), n_elements)
    rod.clamp("start")
    if case == "rollup":
        rod.add_moment("end", [0.0, 0.0, PHI * EI / L])
    elif case == "cantilever":
        rod.add_force("end", [0.0, ALPHA * EI / L**2, 0.0])
    else:
        raise ValueError(case)
    return rod


def rollup_state(rod):
    """Exact roll-up circle (phi = 2 pi) placed on the nodes of ``rod``:
    positions on the circle, frames rotated about +z by kappa s."""
    s = rod.mesh.s_nodes
    ref = analytic.rollup(L, EI, PHI * EI / L, s)
    r = np.stack([ref.x, ref.y, np.zeros_like(s)], axis=1)
    R = expm(np.outer(ref.theta, [0.0, 0.0, 1.0])) @ rod.R0
    return r, R


def median_time(fn, repeats):
    ts = []
    for _ in range(repeats):
        gc.collect()
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def fmt_t(t):
    if t < 1e-3:
        return f"{t * 1e6:.0f} us"
    if t < 1.0:
        return f"{t * 1e3:.2f} ms"
    return f"{t:.3f} s"


def table(header, rows):
    out = ["| " + " | ".join(header) + " |",
           "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(out)


class Report:
    def __init__(self):
        self.parts = []

    def add(self, text=""):
        print(text, flush=True)
        self.parts.append(text)

    def text(self):
        return "\n".join(self.parts) + "\n"


# ---------------------------------------------------------------------------
def machine_info():
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        affinity = len(os.sched_getaffinity(0))
    except AttributeError:
        affinity = os.cpu_count()
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=HERE,
                                capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--", "skfem_rod"],
                               cwd=HERE.parent, capture_output=True,
                               text=True).stdout.strip()
        commit += " (skfem_rod/ has uncommitted changes)" if dirty else ""
    except OSError:
        commit = "unknown"
    threads = {k: os.environ.get(k, "unset") for k in
               ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}
    return [
        ("nproc (usable / total)", f"{affinity} / {os.cpu_count()}"),
        ("CPU", cpu),
        ("load average (1, 5, 15 min) at start",
         ", ".join(f"{x:.2f}" for x in os.getloadavg())),
        ("OS", platform.platform()),
        ("python", platform.python_version()),
        ("numpy", np.__version__),
        ("scipy", scipy.__version__),
        ("scikit-fem", importlib.metadata.version("scikit-fem")),
        ("skfem_rod commit", commit or "unknown"),
        ("thread env", ", ".join(f"{k}={v}" for k, v in threads.items())),
    ]


# ---------------------------------------------------------------------------
def accuracy(rep, sizes, repeats):
    rep.add("## 1. Accuracy and cost of whole solves\n")
    rep.add(f"Roll-up: end moment M = 2 pi EI / L (phi = 2 pi, exact circle, "
            f"`analytic.rollup`). Cantilever: dead tip force P L^2/EI = {ALPHA:g} "
            f"(`analytic.elastica_cantilever` with the same EA, GA). "
            f"EA = GA = {EA:g}, EI = GJ = {EI:g}, L = {L:g}. "
            f"`rod.solve(n_steps={N_STEPS})`, default solver options. "
            f"Errors: Euclidean distance of the nodal positions to the reference, "
            f"divided by L; `order` = log2 of the ratio of the all-node error "
            f"between successive meshes. Time: wall time of `rod.solve` only "
            f"(median of {repeats} runs, rod built outside the timer). "
            f"`Newton its` = total over the load steps (step 0 = the unloaded "
            f"check, 0 iterations); `steps` = converged load steps used "
            f"(> {N_STEPS} means the solver cut steps).\n")
    cant = analytic.elastica_cantilever(ALPHA, EA=EA, GA=GA, EI=EI, length=L)
    rep.add(f"Cantilever reference: tip_u = {cant.tip_u:.15f}, "
            f"tip_v = {cant.tip_v:.15f}, its own refinement error estimate "
            f"tip_error = {cant.tip_error:.1e}.\n")
    for case in ("rollup", "cantilever"):
        rows, prev = [], None
        for n in sizes:
            times, res = [], None
            for _ in range(repeats):
                rod = make_rod(case, n)
                gc.collect()
                t = time.perf_counter()
                res = rod.solve(n_steps=N_STEPS)
                times.append(time.perf_counter() - t)
            s, r, _ = res.nodes()
            if case == "rollup":
                ref = analytic.rollup(L, EI, PHI * EI / L, s)
                x, y = ref.x, ref.y
            else:
                x, y = cant.x(s), cant.y(s)
            err = np.sqrt((r[:, 0] - x) ** 2 + (r[:, 1] - y) ** 2 + r[:, 2] ** 2) / L
            e_all, e_tip = float(err.max()), float(err[-1])
            order = "" if prev is None else f"{np.log2(prev / e_all):.2f}"
            prev = e_all
            rows.append([n, f"{e_tip:.2e}", f"{e_all:.2e}", order,
                         fmt_t(float(np.median(times))), int(res.iterations.sum()),
                         " ".join(str(i) for i in res.iterations[1:]),
                         len(res.steps) - 1, "yes" if res.converged else "NO"])
        title = ("Roll-up, phi = 2 pi" if case == "rollup"
                 else f"Tip-loaded cantilever, P L^2/EI = {ALPHA:g}")
        rep.add(f"### {title}\n")
        rep.add(table(["n_elements", "tip error / L", "max nodal error / L", "order",
                       "solve time", "Newton its", "its per step", "steps",
                       "converged"], rows))
        rep.add()


# ---------------------------------------------------------------------------
def iteration_cost(rep, sizes, repeats_for):
    rep.add("## 2. Cost of one Newton iteration\n")
    rep.add("State: the exact roll-up circle (phi = 2 pi) put on the nodes "
            "(the converged roll-up up to O(h^4); it costs no solve, so the "
            "largest meshes stay cheap to set up). "
            "(a) `internal_work(..., tangent=True)`: residual + tangent (CSC); "
            "(b) `internal_work(..., tangent=False)`: residual only; "
            "(c) `_System.factor(K)` (constraints, `scipy.sparse.linalg.splu`, "
            "COLAMD) + one solve. (a), (b), (c) are timed interleaved, "
            "medians of the repeats [minimum in brackets]; the shape operator Z is precomputed (and "
            "cached on the mesh) as in the solver. `setup` = `Rod(...)` + `_System(rod)` once (not per "
            "iteration).\n")
    rows, data, data_min = [], {}, {}
    for n in sizes:
        reps = repeats_for(n)
        t0 = time.perf_counter()
        rod = make_rod("rollup", n)
        sysm = _System(rod)
        t_setup = time.perf_counter() - t0
        r, R = rollup_state(rod)
        mesh, Z = rod.mesh, sysm.Z
        res_vec, K, _, _ = sysm.evaluate(r, R, 1.0)
        rhs = -res_vec

        def asm_full():
            return internal_work(mesh, r, R, rod.eps0, rod.C, tangent=True, Z=Z)

        def asm_res():
            return internal_work(mesh, r, R, rod.eps0, rod.C, tangent=False, Z=Z)

        def lu_solve():
            return sysm.factor(K)(rhs)

        for f in (asm_full, asm_res, lu_solve):        # warm-up
            f()
        ta, tb, tc = [], [], []
        for _ in range(reps):
            for f, ts in ((asm_full, ta), (asm_res, tb), (lu_solve, tc)):
                gc.collect()
                t = time.perf_counter()
                f()
                ts.append(time.perf_counter() - t)
        mins = tuple(float(np.min(x)) for x in (ta, tb, tc))
        ta, tb, tc = (float(np.median(x)) for x in (ta, tb, tc))
        data_min[n] = mins
        Kc = K.tocsc()
        lu = spla.splu(Kc)
        fill = (lu.L.nnz + lu.U.nnz) / Kc.nnz
        data[n] = (ta, tb, tc)
        rows.append([n, 6 * mesh.n_nodes, Kc.nnz, f"{fill:.2f}", reps,
                     f"{fmt_t(ta)} [{fmt_t(mins[0])}]", f"{fmt_t(tb)} [{fmt_t(mins[1])}]",
                     f"{fmt_t(tc)} [{fmt_t(mins[2])}]", f"{ta / tc:.2f}",
                     f"{ta / n * 1e6:.1f}", f"{tc / n * 1e6:.1f}", fmt_t(t_setup)])
        del rod, sysm, K, res_vec, rhs
    rep.add(table(["n_elements", "dofs", "nnz(K)", "nnz(L+U)/nnz(K)", "repeats",
                   "(a) assembly res+tangent", "(b) residual only",
                   "(c) factor+solve", "(a)/(c)", "(a) us/element",
                   "(c) us/element", "setup"], rows))
    rep.add()
    fit = [n for n in sizes if 100 <= n <= 10000]
    slopes = {}
    if len(fit) >= 2:
        x = np.log(fit)
        for k, name in enumerate(("(a) assembly", "(b) residual", "(c) factor+solve")):
            slopes[name] = float(np.polyfit(x, np.log([data[n][k] for n in fit]), 1)[0])
        smin = {name: float(np.polyfit(x, np.log([data_min[n][k] for n in fit]), 1)[0])
                for k, name in enumerate(slopes)}
        rep.add(f"Log-log slope of time vs n_elements (np.polyfit on n = "
                f"{fit[0]}..{fit[-1]}), from the medians: "
                + ", ".join(f"{k}: **{v:.2f}**" for k, v in slopes.items())
                + "; from the minima (less sensitive to other load on the machine): "
                + ", ".join(f"{k}: {v:.2f}" for k, v in smin.items()) + "\n")
    # targets
    lin = all(v <= 1.15 for v in slopes.values()) if slopes else None
    lines = ["**Targets**\n"]
    if lin is not None:
        lines.append(f"- Iteration cost linear in the element count (all slopes "
                     f"<= 1.15): **{'met' if lin else 'NOT met'}** (max slope "
                     f"{max(slopes.values()):.2f}).")
    if 1000 in data:
        ta, _, tc = data[1000]
        ok = ta <= 3 * tc
        lines.append(f"- Assembly <= 3x the sparse solve at 1000 elements: "
                     f"assembly {fmt_t(ta)}, factor+solve {fmt_t(tc)}, ratio "
                     f"**{ta / tc:.2f}** -> **{'met' if ok else 'NOT met'}**.")
    rep.add("\n".join(lines) + "\n")
    return data, slopes


# ---------------------------------------------------------------------------
def profile(rep, n, top=10):
    rep.add(f"### cProfile of one assembly (residual + tangent), {n} elements\n")
    rod = make_rod("rollup", n)
    r, R = rollup_state(rod)
    Z = shape_operator(rod.mesh)
    internal_work(rod.mesh, r, R, rod.eps0, rod.C, tangent=True, Z=Z)   # warm-up
    pr = cProfile.Profile()
    pr.enable()
    internal_work(rod.mesh, r, R, rod.eps0, rod.C, tangent=True, Z=Z)
    pr.disable()
    stats = pstats.Stats(pr, stream=io.StringIO())
    total = stats.total_tt
    root = str(HERE.parent)

    def name(func):
        fname, line, fn = func
        fname = fname.replace(root + os.sep, "")
        if "site-packages" in fname:
            fname = fname.split("site-packages" + os.sep, 1)[1]
        return f"`{fn}` ({fname}:{line})" if line else f"`{fn}`"

    entries = [(func, cc, nc, tt, ct) for func, (cc, nc, tt, ct, _) in stats.stats.items()]
    for key, label in ((4, "cumulative"), (3, "total (self)")):
        rows = []
        for func, cc, nc, tt, ct in sorted(entries, key=lambda e: -e[key])[:top]:
            rows.append([name(func), nc, fmt_t(tt), fmt_t(ct),
                         f"{100 * (ct if key == 4 else tt) / total:.0f}%"])
        rep.add(f"Top {top} by {label} time (profiled total {fmt_t(total)}, "
                f"cProfile overhead included):\n")
        rep.add(table(["function", "calls", "self time", "cumulative", "share"], rows))
        rep.add()


# ---------------------------------------------------------------------------
def memory(rep, n):
    rep.add(f"## 4. Peak memory of one assembly, {n} elements\n")
    rod = make_rod("rollup", n)
    r, R = rollup_state(rod)
    Z = shape_operator(rod.mesh)
    rows = []
    for tangent in (True, False):
        gc.collect()
        tracemalloc.start()
        iw = internal_work(rod.mesh, r, R, rod.eps0, rod.C, tangent=tangent, Z=Z)
        cur, peak = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        out = iw.force.nbytes
        if iw.matrix is not None:
            K = iw.matrix
            out += K.data.nbytes + K.indices.nbytes + K.indptr.nbytes
        rows.append(["residual + tangent" if tangent else "residual only",
                     f"{peak / 2**20:.1f} MiB", f"{peak / n / 1024:.1f} KiB",
                     f"{out / 2**20:.1f} MiB", f"{peak / max(out, 1):.1f}"])
        del iw
    rep.add("`tracemalloc` peak of the Python/NumPy allocations during one "
            "`internal_work` call (inputs and the precomputed Z excluded); "
            "`result size` = the returned vector + CSC matrix.\n")
    rep.add(table(["assembly", "peak", "peak per element", "result size",
                   "peak / result"], rows))
    rep.add(f"\nNot included above: the shape operator Z {Z.shape}, computed once "
            f"per mesh and kept: {Z.nbytes / 2**20:.1f} MiB "
            f"({Z.nbytes / n / 1024:.1f} KiB per element).\n")


# ---------------------------------------------------------------------------
# ---------------------------------------------------------------------------
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true",
                    help="small sizes and few repeats (smoke test)")
    ap.add_argument("--output", default=None,
                    help="markdown file (default benchmarks/RESULTS.md, "
                         "benchmarks/RESULTS_quick.md with --quick)")
    args = ap.parse_args(argv)
    out = Path(args.output) if args.output else \
        HERE / ("RESULTS_quick.md" if args.quick else "RESULTS.md")
    if args.quick:
        acc_sizes, acc_reps = [2, 4, 8, 16], 3
        it_sizes = [10, 30, 100, 300, 1000]
        reps_for = lambda n: 3                                   # noqa: E731
        prof_n, mem_n = 1000, 1000
    else:
        acc_sizes, acc_reps = [2, 4, 8, 16, 32, 64], 5
        it_sizes = [10, 30, 100, 300, 1000, 3000, 10000]
        reps_for = lambda n: 7 if n >= 10000 else 9              # noqa: E731
        prof_n, mem_n = 1000, 10000

    rep = Report()
    t_start, c_start = time.perf_counter(), time.process_time()
    cmd = " ".join([Path(sys.executable).as_posix(),
                    os.path.relpath(__file__, Path.cwd())] + sys.argv[1:])
    rep.add("# skfem_rod statics benchmarks\n")
    rep.add(f"Command: `{cmd}` (run from `{Path.cwd()}`)  ")
    rep.add(f"Date: {datetime.datetime.now().astimezone().isoformat(timespec='seconds')}"
            f"{'  (QUICK run: reduced sizes and repeats)' if args.quick else ''}\n")
    rep.add(table(["machine", ""], machine_info()))
    rep.add()
    accuracy(rep, acc_sizes, acc_reps)
    iteration_cost(rep, it_sizes, reps_for)
    rep.add("## 3. Where the assembly time goes\n")
    profile(rep, prof_n)
    memory(rep, mem_n)
    wall = time.perf_counter() - t_start
    cpu = time.process_time() - c_start
    rep.add(f"Total benchmark wall time: {wall:.0f} s; CPU time of this process "
            f"{cpu:.0f} s ({100 * cpu / wall:.0f}% of wall: well below 100% means "
            f"other processes competed for the 2 cores); load average at the end: "
            + ", ".join(f"{x:.2f}" for x in os.getloadavg()) + ".")
    out.write_text(rep.text())
    print(f"\nwritten to {out}", flush=True)


if __name__ == "__main__":
    main()
