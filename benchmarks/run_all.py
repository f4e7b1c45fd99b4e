"""Run every skfem_rod benchmark and write benchmarks/RESULTS.md.

Usage (from the repository root)::

    python benchmarks/run_all.py                 # everything (~30 min on 2 cores)
    python benchmarks/run_all.py --quick         # smoke run -> benchmarks/RESULTS_quick_all.md
    python benchmarks/run_all.py --skip peer     # reuse the last RESULTS_peer.md

Each benchmark runs as its own subprocess (a fresh interpreter, so one
cannot warm caches or leak memory into the next) and writes its own report;
this script then collects them, in this order, into RESULTS.md:

=========  ======================  =========================================
part       script                  its report (and plots)
=========  ======================  =========================================
statics    bench_statics.py        RESULTS_statics.md, work_precision.png,
                                   scaling.png
stress     stress.py               RESULTS_stress.md
contact    bench_contact.py        RESULTS_contact.md (and its PNGs, if any)
friction   bench_friction.py       RESULTS_friction.md
scaling_contact scaling_contact.py RESULTS_scaling_contact.md (plectoneme, 10-10000 elements)
peer       bench_peer.py           RESULTS_peer.md, peer.png; needs the
                                   optional ``bench`` extra (pyelastica)
=========  ======================  =========================================

A part whose script or optional dependency is missing is reported as
skipped (with the reason); a part that fails is reported with the tail of
its output, and the other parts still run.  ``--skip`` reuses the part's
last report if there is one (its date is in it).
"""
import argparse
import datetime
import importlib.util
import os
import re
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

PARTS = {
    # name: (script, full args, quick args, full report, quick report, needs)
    "statics": ("bench_statics.py", [], ["--quick"], "RESULTS_statics.md",
                "RESULTS_quick.md", None),
    "stress": ("stress.py", [], ["--quick"], "RESULTS_stress.md",
               "RESULTS_stress_quick.md", None),
    "contact": ("bench_contact.py", [], ["--quick"], "RESULTS_contact.md",
                "RESULTS_contact_quick.md", None),
    "scaling_contact": ("scaling_contact.py", [], ["--quick"], "RESULTS_scaling_contact.md",
                        "{tmp}/RESULTS_scaling_contact_quick.md", None),   # --quick: no file
    "friction": ("bench_friction.py", [], ["--quick"], "RESULTS_friction.md",
                 "{tmp}/RESULTS_friction_quick.md", None),     # --quick writes no file
    "peer": ("bench_peer.py", [], ["--quick", "--output", "{tmp}/RESULTS_peer_quick.md",
                                   "--plot", "{tmp}/peer_quick.png"],
             "RESULTS_peer.md", "{tmp}/RESULTS_peer_quick.md", "elastica"),
}
TITLES = {"statics": "Statics: work-precision, cost and memory per Newton iteration",
          "stress": "Numerical stability stress tests",
          "contact": "Contact: cost per Newton iteration",
          "scaling_contact": "Contact: scaling of a Newton iteration, 10 to 10,000 elements",
          "friction": "Friction: cost per Newton iteration, friction on and off",
          "peer": "Peer comparison: PyElastica"}


#: what the headline section quotes from each part's report: ("line", regex)
#: quotes every matching line (with the heading it sits under), ("table",
#: regex) the first table after the first matching line
HEADLINES = {
    "statics": [("table", r"^#+ Tip error 1e-8"), ("line", r"^Log-log slope of time"),
                ("line", r"^- Iteration cost linear")],
    "stress": [("line", r"^\d+ solves, ")],
    "contact": [("line", r"^Log-log slopes"), ("line", r"^Target")],
    "scaling_contact": [("line", r"^Log-log slopes"), ("line", r"^Target")],
    "friction": [("line", r"[Tt]arget")],
    "peer": [("table", r"^#+ Summary")],
}


def headlines(name, text):
    out, lines, heading = [], text.splitlines(), ""
    for kind, pattern in HEADLINES.get(name, []):
        rx = re.compile(pattern)
        heading = ""
        for k, line in enumerate(lines):
            if line.startswith("#"):
                heading = line.lstrip("#").strip()
            if not rx.search(line):
                continue
            if kind == "line":
                out.append(f"- *{heading}*: {line.lstrip('- ')}" if heading else f"- {line}")
                continue
            rows = []
            for row in lines[k + 1:]:
                if row.startswith("|"):
                    rows.append(row)
                elif rows:
                    break
            if rows:
                out += ["", *rows, ""]
            break
    return out


def demote(text):
    """Shift markdown headings one level down (the part's title becomes ##)."""
    out, fence = [], False
    for line in text.splitlines():
        if line.startswith("```"):
            fence = not fence
        if not fence and re.match(r"#{1,5} ", line):
            line = "#" + line
        out.append(line)
    return "\n".join(out)


def run_part(name, quick, tmp):
    script, full, qargs, report, qreport, needs = PARTS[name]
    path = HERE / script
    report = Path(str(qreport if quick else report).format(tmp=tmp))
    if not report.is_absolute():
        report = HERE / report
    if not path.exists():
        return dict(status="skipped", why=f"{script} not found", report=None)
    if needs and importlib.util.find_spec(needs) is None:
        return dict(status="skipped", report=report if report.exists() else None,
                    why=f"optional dependency `{needs}` not installed "
                        f"(`pip install -e \".[bench]\"`)")
    args = [a.format(tmp=tmp) for a in (qargs if quick else full)]
    cmd = [sys.executable, str(path)] + args
    print(f"\n=== {name}: {' '.join(cmd)}", flush=True)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    print(proc.stdout[-2000:], proc.stderr[-2000:], sep="\n", flush=True)
    info = dict(wall=wall, returncode=proc.returncode, report=report,
                tail=(proc.stdout + proc.stderr)[-1500:])
    if proc.returncode != 0 and not (name == "stress" and proc.returncode == 1
                                     and report.exists()):
        info["status"] = "failed"
    else:
        info["status"] = "ran"
    return info


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smoke run of every part")
    ap.add_argument("--skip", default="", help="comma-separated parts not to run "
                    f"(reuse their last report): {', '.join(PARTS)}")
    ap.add_argument("--only", default="", help="comma-separated parts to run "
                    "(the others are reused)")
    ap.add_argument("--output", type=Path, default=None)
    args = ap.parse_args(argv)
    skip = {s for s in args.skip.split(",") if s}
    if args.only:
        skip |= set(PARTS) - {s for s in args.only.split(",") if s}
    bad = skip - set(PARTS)
    if bad:
        raise SystemExit(f"--skip/--only: unknown part(s) {sorted(bad)}; allowed: "
                         f"{', '.join(PARTS)}")
    import tempfile
    tmp = tempfile.mkdtemp(prefix="skfem_rod_bench_") if args.quick else str(HERE)
    out = args.output or HERE / ("RESULTS_quick_all.md" if args.quick else "RESULTS.md")
    t0 = time.perf_counter()
    results = {}
    for name in PARTS:
        if name in skip:
            script, _, _, report, qreport, _ = PARTS[name]
            rep = Path(str(qreport if args.quick else report).format(tmp=tmp))
            rep = rep if rep.is_absolute() else HERE / rep
            results[name] = dict(status="reused" if rep.exists() else "skipped",
                                 report=rep if rep.exists() else None,
                                 why="not run in this invocation (--skip / --only)")
        else:
            results[name] = run_part(name, args.quick, tmp)
    wall = time.perf_counter() - t0

    cmd = "python benchmarks/run_all.py" + "".join(f" {a}" for a in (argv or sys.argv[1:]))
    lines = ["# skfem_rod benchmarks\n",
             f"Regenerated by one command: `{cmd}` (from the repository root).  ",
             f"Date: {datetime.datetime.now().astimezone().isoformat(timespec='seconds')}; "
             f"{os.cpu_count()} cores; load average at the end "
             + ", ".join(f"{x:.2f}" for x in os.getloadavg())
             + f"; total wall time {wall / 60:.1f} min"
             + ("  (QUICK run)" if args.quick else "") + ".\n",
             "Every part is a separate script run as a subprocess; its own report "
             "is included below (headings shifted one level). Element order: "
             "**P3 only** (the only element skfem_rod has).\n",
             "| part | script | status | wall time | report |",
             "|---|---|---|---|---|"]
    for name, r in results.items():
        status = r["status"] + (f" ({r['why']})" if r.get("why") else "")
        if r["status"] == "failed":
            status += f", exit code {r['returncode']}"
        rep = r.get("report")
        lines.append(f"| {name} | `{PARTS[name][0]}` | {status} | "
                     f"{r['wall']:.0f} s |" if "wall" in r else
                     f"| {name} | `{PARTS[name][0]}` | {status} | - |")
        lines[-1] += f" {Path(rep).name if rep else '-'} |"
    lines.append("")
    lines.append("## Headlines (quoted from the parts below)\n")
    for name, r in results.items():
        rep = r.get("report")
        if rep is None or not Path(rep).exists() or r["status"] == "failed":
            continue
        quoted = headlines(name, Path(rep).read_text())
        if quoted:
            lines.append(f"**{TITLES[name]}**")
            lines += quoted
            lines.append("")
    for k, (name, r) in enumerate(results.items(), 1):
        lines.append(f"# Part {k}. {TITLES[name]}\n")
        rep = r.get("report")
        if r["status"] == "failed":
            lines.append(f"**The run failed** (exit code {r['returncode']}); end of its "
                         f"output:\n\n```\n{r['tail']}\n```\n")
        if r["status"] == "reused":
            lines.append(f"*Not run in this invocation: the last report, "
                         f"`{Path(rep).name}`, is included as it was (its date is "
                         f"in it).*\n")
        if r["status"] == "skipped":
            lines.append(f"*Skipped: {r.get('why')}.*\n")
        if rep is not None and Path(rep).exists() and r["status"] != "failed":
            lines.append(demote(Path(rep).read_text()))
            lines.append("")
    text = "\n".join(lines) + "\n"
    tmpf = out.with_name(out.name + ".tmp")
    tmpf.write_text(text)
    os.replace(tmpf, out)
    print(f"\nwritten to {out}", flush=True)
    return 0 if all(r["status"] != "failed" for r in results.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
