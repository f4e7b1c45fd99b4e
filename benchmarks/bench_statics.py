"""Static benchmarks of skfem_rod: accuracy, cost per Newton iteration,
profile and memory of the assembly.

Usage::

    python benchmarks/bench_statics.py            # full run -> benchmarks/RESULTS_statics.md
                                                  #   + work_precision.png, scaling.png
    python benchmarks/run_all.py                  # every benchmark -> benchmarks/RESULTS.md
    python benchmarks/bench_statics.py --quick    # smoke run -> benchmarks/RESULTS_quick.md
    python benchmarks/bench_statics.py --output some/file.md

Sections (each printed as markdown and written to the output file):

1. Accuracy and solve cost (work-precision) of the roll-up (end moment,
   phi = 2 pi), the tip-loaded cantilever (P L^2 / EI = 2) and the
   45-degree bend for 2..64 P3 elements (the only element order), and the
   time to reach tip error 1e-8.
2. Cost and peak memory of one Newton iteration (assembly of residual +
   tangent, residual only, sparse factorization + solve) for 10..10000
   elements at a deformed state, with the log-log slopes and the
   assembly/solve ratio.
3. Where the assembly spends its time: a stage-by-stage timing of
   ``internal_work`` and a cProfile of one assembly at 1000 elements.
4. Peak memory (tracemalloc) of one assembly at 10000 elements.

The machine may be shared: every time is a median of repeats, and the
quantities that are compared (ratios) are measured interleaved in one run.
"""
import argparse
import cProfile
import datetime
import gc
import importlib.metadata
import io
import json
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
from skfem_rod.problem import Problem

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
    if case == "bend":
        rod = Rod(bend_shape(), Section(**BEND_SECTION), n_elements)
        rod.clamp("start")
        rod.add_force("end", [0.0, 0.0, BEND_LOAD])
        return rod
    rod = Rod(geometry.straight(L), section(), n_elements)
    rod.clamp("start")
    if case == "rollup":
        rod.add_moment("end", [0.0, 0.0, PHI * EI / L])
    elif case == "cantilever":
        rod.add_force("end", [0.0, ALPHA * EI / L**2, 0.0])
    else:
        raise ValueError(case)
    return rod


# 45-degree bend (Bathe & Bolourchi 1979; Simo & Vu-Quoc 1986): arc of
# radius 100, angle pi/4, clamped, dead tip force 600 out of its plane; the
# same data as tests/test_verification.py and scenes/bend45.toml
BEND_RADIUS = 100.0
BEND_SECTION = dict(EA=1e7, GA1=5e6, GA2=5e6, EI1=1e7 / 12, EI2=1e7 / 12, GJ=5e6 / 6)
BEND_LOAD = 600.0


def bend_shape():
    return geometry.arc(BEND_RADIUS, np.pi / 4, start=(0.0, 0.0, 0.0),
                        tangent=(0.0, 1.0, 0.0), toward=(1.0, 0.0, 0.0))


def bend_reference(rtol=1e-12):
    """Tip of the 45-degree bend at P = 600 by shooting on the 3D
    Simo-Reissner equations (:func:`skfem_rod.analytic.clamped_rod_shooting`,
    the reference of tests/test_verification.py):
    ``r' = R v``, ``R' = R hat(u)``, ``m' = -r' x n``, ``n = F`` (dead tip
    force), ``(v, u) = (e3, e2 / radius) + C^-1 (R^T n, R^T m)``; the
    unknown ``m(0)`` solves ``m(L) = 0`` (continuation over 150, 300, 450,
    600).  Only the frame at s = 0 is taken from the package."""
    shape = bend_shape()
    C = np.diag([BEND_SECTION[k] for k in ("GA1", "GA2", "EA", "EI1", "EI2", "GJ")])
    R00 = shape(np.array([0.0]))[1][0]
    tips = analytic.clamped_rod_shooting(
        C, [0, 0, 1], [0, 1 / BEND_RADIUS, 0], R00, shape.length,
        [[0.0, 0.0, P] for P in (150.0, 300.0, 450.0, BEND_LOAD)], rtol=rtol)
    return tips[-1], shape.length


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
def add_option_arguments(ap, results):
    """The benchmarks' ``--option name=value`` (repeatable; read by
    :func:`parse_options`) and ``--results`` (append to ``results``)."""
    ap.add_argument("--option", action="append", default=[],
                    help="solver option name=value (JSON value), repeatable")
    ap.add_argument("--results", action="store_true", help=f"append to benchmarks/{results}")


def parse_options(pairs):
    """Solver options from ``name=value`` strings (JSON values), as the
    benchmarks' repeatable ``--option`` gives them."""
    options = {}
    for kv in pairs:
        k, _, v = kv.partition("=")
        options[k] = json.loads(v)
    return options


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
CASE_TITLES = {"rollup": "Roll-up, phi = 2 pi",
               "cantilever": f"Tip-loaded cantilever, P L^2/EI = {ALPHA:g}",
               "bend": f"45-degree bend, P = {BEND_LOAD:g}"}


def accuracy(rep, sizes, repeats):
    """Error against wall time under mesh refinement; returns
    ``{case: [(n, tip_error, max_error, t_solve, t_build_solve), ...]}``."""
    rep.add("## 1. Accuracy and cost of whole solves (work-precision)\n")
    rep.add("**Element order: P3 only.** skfem_rod has nodal cubic (P3) elements "
            "only (no P1/P2 variant exists), so the work-precision curves are "
            "under mesh refinement at fixed order 3.\n")
    rep.add(f"Roll-up: end moment M = 2 pi EI / L (phi = 2 pi, exact circle, "
            f"`analytic.rollup`). Cantilever: dead tip force P L^2/EI = {ALPHA:g} "
            f"(`analytic.elastica_cantilever` with the same EA, GA). "
            f"EA = GA = {EA:g}, EI = GJ = {EI:g}, L = {L:g}. "
            f"45-degree bend: arc of radius {BEND_RADIUS:g}, clamped, dead tip "
            f"force {BEND_LOAD:g} out of plane (Bathe & Bolourchi 1979); reference "
            f"tip from an independent shooting solution of the 3D rod equations "
            f"(`scipy.integrate.solve_ivp`, DOP853, rtol 1e-12; as in "
            f"tests/test_verification.py), errors divided by the arc length. "
            f"`rod.solve(n_steps={N_STEPS})`, default solver options. "
            f"Errors: Euclidean distance of the nodal positions to the reference, "
            f"divided by L (bend: tip only); `order` = log2 of the error ratio "
            f"between successive meshes (all-node error; bend: tip). "
            f"Time: `solve` = wall time of `rod.solve` only, `build+solve` = "
            f"`Rod(...)`, supports, loads and `rod.solve` (median of {repeats} "
            f"runs each). `Newton its` = total over the load steps; `steps` = "
            f"converged load steps used (> {N_STEPS} means the solver cut steps).\n")
    cant = analytic.elastica_cantilever(ALPHA, EA=EA, GA=GA, EI=EI, length=L)
    t0 = time.perf_counter()
    bend_tip, bend_len = bend_reference()
    t_ref = time.perf_counter() - t0
    bend_tip_loose, _ = bend_reference(rtol=1e-10)
    rep.add(f"Cantilever reference: tip_u = {cant.tip_u:.15f}, "
            f"tip_v = {cant.tip_v:.15f}, its own refinement error estimate "
            f"tip_error = {cant.tip_error:.1e}. Bend reference tip: "
            f"({bend_tip[0]:.10f}, {bend_tip[1]:.10f}, {bend_tip[2]:.10f}) "
            f"({t_ref:.1f} s); change against rtol 1e-10: "
            f"{np.linalg.norm(bend_tip - bend_tip_loose) / bend_len:.1e} of the arc "
            f"length.\n")
    data = {}
    for case in ("rollup", "cantilever", "bend"):
        rows, prev, data[case] = [], None, []
        for n in sizes:
            times, tbs, res = [], [], None
            for _ in range(repeats):
                gc.collect()
                t = time.perf_counter()
                rod = make_rod(case, n)
                t1 = time.perf_counter()
                res = rod.solve(n_steps=N_STEPS)
                t2 = time.perf_counter()
                times.append(t2 - t1)
                tbs.append(t2 - t)
            s, r, _ = res.nodes()
            if case == "bend":
                err = np.array([np.linalg.norm(r[-1] - bend_tip) / bend_len])
            else:
                if case == "rollup":
                    ref = analytic.rollup(L, EI, PHI * EI / L, s)
                    x, y = ref.x, ref.y
                else:
                    x, y = cant.x(s), cant.y(s)
                err = np.sqrt((r[:, 0] - x) ** 2 + (r[:, 1] - y) ** 2 + r[:, 2] ** 2) / L
            e_all, e_tip = float(err.max()), float(err[-1])
            order = "" if prev is None else f"{np.log2(prev / e_all):.2f}"
            prev = e_all
            ts, tb = float(np.median(times)), float(np.median(tbs))
            data[case].append((n, e_tip, e_all, ts, tb))
            rows.append([n, f"{e_tip:.2e}", "" if case == "bend" else f"{e_all:.2e}",
                         order, fmt_t(ts), fmt_t(tb), int(res.iterations.sum()),
                         " ".join(str(i) for i in res.iterations[1:]),
                         len(res.steps) - 1, "yes" if res.converged else "NO"])
        rep.add(f"### {CASE_TITLES[case]}\n")
        rep.add(table(["n_elements", "tip error / L", "max nodal error / L", "order",
                       "solve", "build+solve", "Newton its", "its per step", "steps",
                       "converged"], rows))
        rep.add()
    rep.add("### Tip error 1e-8: how long does it take?\n")
    rep.add("The coarsest mesh of the sweep above whose tip error is at most 1e-8 "
            "(and, stricter, whose largest nodal error is), with its measured "
            "median wall time (same runs as the tables).\n")
    rows = []
    for case in ("rollup", "cantilever", "bend"):
        for k, label in ((1, "tip error"), (2, "max nodal error")):
            if case == "bend" and k == 2:
                continue
            hit = [d for d in data[case] if d[k] <= 1e-8]
            if hit:
                n, et, ea, ts, tb = hit[0]
                rows.append([CASE_TITLES[case], label, n, f"{(et, ea)[k - 1]:.1e}",
                             fmt_t(ts), fmt_t(tb),
                             "**yes**" if tb < 1.0 else "**NO**"])
            else:
                rows.append([CASE_TITLES[case], label, "not reached", "", "", "", "**NO**"])
    rep.add(table(["problem", "criterion", "coarsest n_elements", "error",
                   "solve", "build+solve", "under 1 s"], rows))
    rep.add()
    return data


def plot_work_precision(data, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.4), sharey=True)
    marks = {"rollup": "o", "cantilever": "s", "bend": "^"}
    for case, rows in data.items():
        a = np.array(rows, dtype=float)
        ax[0].loglog(a[:, 4], np.maximum(a[:, 1], 1e-16), marks[case] + "-",
                     label=CASE_TITLES[case] + " (tip)")
        if case != "bend":
            ax[0].loglog(a[:, 4], a[:, 2], marks[case] + "--", mfc="none",
                         label=CASE_TITLES[case] + " (max nodal)")
        ax[1].loglog(a[:, 0], np.maximum(a[:, 1], 1e-16), marks[case] + "-",
                     label=CASE_TITLES[case] + " (tip)")
        if case != "bend":
            ax[1].loglog(a[:, 0], a[:, 2], marks[case] + "--", mfc="none")
    n = np.array([4.0, 64.0])
    ax[1].loglog(n, 1e-5 * (n / 4) ** -4, "k:", label="slope -4")
    for a_ in ax:
        a_.axhline(1e-8, color="gray", lw=0.8)
        a_.grid(True, which="major", alpha=0.3)
    ax[0].axvline(1.0, color="gray", lw=0.8)
    ax[0].set_xlabel("wall time, build + solve (s), median of repeats")
    ax[0].set_ylabel("error / L")
    ax[0].set_title("work-precision (P3 elements, mesh refinement)")
    ax[1].set_xlabel("n_elements")
    ax[1].set_title("error under refinement")
    sizes = sorted({int(r[0]) for rows in data.values() for r in rows})
    ax[1].set_xticks(sizes)
    ax[1].set_xticklabels([str(k) for k in sizes])
    ax[1].minorticks_off()
    ax[0].legend(fontsize=7, loc="lower left")
    ax[1].legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------------------
def iteration_cost(rep, sizes, repeats_for):
    rep.add("## 2. Cost of one Newton iteration\n")
    rep.add("State: the exact roll-up circle (phi = 2 pi) put on the nodes "
            "(the converged roll-up up to O(h^4); it costs no solve, so the "
            "largest meshes stay cheap to set up). "
            "(a) `internal_work(..., tangent=True)`: residual + tangent (CSC); "
            "(b) `internal_work(..., tangent=False)`: residual only; "
            "(c) `Problem.factor(K)` (constraints, `scipy.sparse.linalg.splu`, "
            "COLAMD) + one solve. (a), (b), (c) are timed interleaved, "
            "medians of the repeats [minimum in brackets]; the shape operator Z is precomputed (and "
            "cached on the mesh) as in the solver. `setup` = `Rod(...)` + `Problem(rod)` once (not per "
            "iteration).\n")
    rows, data, data_min = [], {}, {}
    for n in sizes:
        reps = repeats_for(n)
        t0 = time.perf_counter()
        rod = make_rod("rollup", n)
        sysm = Problem(rod)
        t_setup = time.perf_counter() - t0
        r, R = rollup_state(rod)
        mesh, Z = rod.mesh, sysm.Z
        ev = sysm.evaluate(r, R, 1.0)
        res_vec, K = ev.residual, ev.tangent
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
        lu_bytes = 12 * (lu.L.nnz + lu.U.nnz)    # float64 value + int32 index
        del lu
        # peak memory of one Newton iteration (separate run: tracemalloc
        # slows the code down): system evaluation + factorization + solve
        gc.collect()
        tracemalloc.start()
        out = sysm.evaluate(r, R, 1.0)
        sysm.factor(out.tangent)(-out.residual)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        del out
        mem = peak + lu_bytes
        data[n] = (ta, tb, tc, mem)
        rows.append([n, 6 * mesh.n_nodes, Kc.nnz, f"{fill:.2f}", reps,
                     f"{fmt_t(ta)} [{fmt_t(mins[0])}]", f"{fmt_t(tb)} [{fmt_t(mins[1])}]",
                     f"{fmt_t(tc)} [{fmt_t(mins[2])}]", f"{ta / tc:.2f}",
                     f"{ta / n * 1e6:.1f}", f"{tc / n * 1e6:.1f}",
                     f"{mem / 2**20:.1f} MiB", f"{mem / n / 1024:.1f} KiB",
                     fmt_t(t_setup)])
        del rod, sysm, K, res_vec, rhs
    rep.add(table(["n_elements", "dofs", "nnz(K)", "nnz(L+U)/nnz(K)", "repeats",
                   "(a) assembly res+tangent", "(b) residual only",
                   "(c) factor+solve", "(a)/(c)", "(a) us/element",
                   "(c) us/element", "peak memory / iteration", "per element",
                   "setup"], rows))
    rep.add("\n`peak memory / iteration` = `tracemalloc` peak of one "
            "`Problem.evaluate` (residual + tangent + loads) followed by "
            "`Problem.factor` and one solve (all NumPy/SciPy arrays), plus the "
            "SuperLU factor storage, which tracemalloc does not see, counted as "
            "12 bytes per nonzero of L + U. Inputs (state, cached shape operator) "
            "are not included.\n")
    fit = [n for n in sizes if 100 <= n <= 10000]
    slopes = {}
    if len(fit) >= 2:
        x = np.log(fit)
        for k, name in enumerate(("(a) assembly", "(b) residual", "(c) factor+solve")):
            slopes[name] = float(np.polyfit(x, np.log([data[n][k] for n in fit]), 1)[0])
        smin = {name: float(np.polyfit(x, np.log([data_min[n][k] for n in fit]), 1)[0])
                for k, name in enumerate(slopes)}
        slopes["(a)+(c) one iteration"] = float(np.polyfit(
            x, np.log([data[n][0] + data[n][2] for n in fit]), 1)[0])
        smin["(a)+(c) one iteration"] = float(np.polyfit(
            x, np.log([data_min[n][0] + data_min[n][2] for n in fit]), 1)[0])
        mem_slope = float(np.polyfit(x, np.log([data[n][3] for n in fit]), 1)[0])
        rep.add(f"Log-log slope of time vs n_elements (np.polyfit on n = "
                f"{fit[0]}..{fit[-1]}), from the medians: "
                + ", ".join(f"{k}: **{v:.2f}**" for k, v in slopes.items())
                + "; from the minima (less sensitive to other load on the machine): "
                + ", ".join(f"{k}: {v:.2f}" for k, v in smin.items())
                + f". Peak memory per iteration: slope **{mem_slope:.2f}**.\n")
        a, b = fit[-2], fit[-1]
        loc = {name: np.log(data_min[b][k] / data_min[a][k]) / np.log(b / a)
               for k, name in ((0, "(a)"), (1, "(b)"), (2, "(c)"))}
        loc["(a)+(c)"] = np.log((data_min[b][0] + data_min[b][2])
                                / (data_min[a][0] + data_min[a][2])) / np.log(b / a)
        rep.add(f"Local slope between the two largest meshes ({a} -> {b} elements, "
                f"from the minima): " + ", ".join(f"{k} {v:.2f}" for k, v in loc.items())
                + " (a local slope above the fitted one is the price of memory "
                "traffic on the largest meshes: see the peak memory per iteration).\n")
    # targets
    lin = all(v <= 1.15 for v in slopes.values()) if slopes else None
    lines = ["**Targets**\n"]
    if lin is not None:
        lines.append(f"- Iteration cost linear in the element count (all slopes "
                     f"<= 1.15): **{'met' if lin else 'NOT met'}** (max slope "
                     f"{max(slopes.values()):.2f}).")
    if 1000 in data:
        ta, _, tc, _ = data[1000]
        ok = ta <= 3 * tc
        lines.append(f"- Assembly <= 3x the sparse solve at 1000 elements: "
                     f"assembly {fmt_t(ta)}, factor+solve {fmt_t(tc)}, ratio "
                     f"**{ta / tc:.2f}** -> **{'met' if ok else 'NOT met'}**.")
    rep.add("\n".join(lines) + "\n")
    return data, slopes


def plot_scaling(data, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    n = np.array(sorted(data), dtype=float)
    a = np.array([data[k] for k in sorted(data)])
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    ax[0].loglog(n, a[:, 0], "o-", label="(a) internal assembly, residual + tangent")
    ax[0].loglog(n, a[:, 1], "s-", label="(b) residual only")
    ax[0].loglog(n, a[:, 2], "^-", label="(c) linear solve (factor + solve)")
    ax[0].loglog(n, a[:, 0] + a[:, 2], "k.-", label="(a) + (c): one Newton iteration")
    ref = (a[:, 0] + a[:, 2])[n == 100]
    if ref.size:
        ax[0].loglog(n, ref[0] * n / 100, "k:", label="slope 1 (through n = 100)")
    ax[0].set_xlabel("n_elements")
    ax[0].set_ylabel("time (s), median")
    ax[0].set_title("cost of one Newton iteration, no contact")
    ax[1].loglog(n, a[:, 3] / 2**20, "o-", label="peak memory of one iteration")
    ax[1].loglog(n, a[:, 3][n == 100][0] / 2**20 * n / 100 if (n == 100).any()
                 else a[:, 3] / 2**20, "k:", label="slope 1")
    ax[1].set_xlabel("n_elements")
    ax[1].set_ylabel("MiB")
    ax[1].set_title("peak memory per iteration")
    for a_ in ax:
        a_.grid(True, alpha=0.3)
        a_.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


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
                    help="markdown file (default benchmarks/RESULTS_statics.md, "
                         "benchmarks/RESULTS_quick.md with --quick)")
    args = ap.parse_args(argv)
    out = Path(args.output) if args.output else \
        HERE / ("RESULTS_quick.md" if args.quick else "RESULTS_statics.md")
    tag = "_quick" if args.quick else ""
    png_wp = out.parent / f"work_precision{tag}.png"
    png_sc = out.parent / f"scaling{tag}.png"
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
    acc = accuracy(rep, acc_sizes, acc_reps)
    plot_work_precision(acc, png_wp)
    rep.add(f"![work-precision]({png_wp.name})\n")
    it_data, _ = iteration_cost(rep, it_sizes, reps_for)
    plot_scaling(it_data, png_sc)
    rep.add(f"![scaling]({png_sc.name})\n")
    rep.add("## 3. Where the assembly time goes\n")
    profile(rep, prof_n)
    memory(rep, mem_n)
    wall = time.perf_counter() - t_start
    cpu = time.process_time() - c_start
    rep.add(f"Total benchmark wall time: {wall:.0f} s; CPU time of this process "
            f"{cpu:.0f} s ({100 * cpu / wall:.0f}% of wall: well below 100% means "
            f"other processes competed for the 2 cores); load average at the end: "
            + ", ".join(f"{x:.2f}" for x in os.getloadavg()) + ".")
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(rep.text())
    os.replace(tmp, out)
    print(f"\nwritten to {out}, {png_wp.name}, {png_sc.name}", flush=True)


if __name__ == "__main__":
    main()
