"""Numerical stability stress tests of the skfem_rod solver.

Usage::

    python benchmarks/stress.py            # full sweep -> benchmarks/RESULTS_stress.md
    python benchmarks/stress.py --quick    # a few cases -> benchmarks/RESULTS_stress_quick.md
    python benchmarks/run_all.py           # every benchmark -> benchmarks/RESULTS.md

Sweeps (the parameter ranges documented in docs/ranges.md):

* contact penalty (compliance ``mu_N``) over 6 decades, 1e-3 to 1e3 times
  the default ``10 eps^4 / EI``, on the hairpin pressed closed
  (scenes/hairpin_contact.toml), 40 and 160 elements;
* slenderness L / radius 10 to 1e4 (tip-loaded cantilever, solid circle,
  P L^2 / EI = 2) crossed with load steps 1 to 100 and 8 to 2000 elements;
* load steps 1 to 100 on the roll-up (phi = 2 pi), 8 to 2000 elements;
* twist up to 20 turns: a straight rod, clamped at s = 0, pinned at s = L
  and twisted there by ``prescribe_rotation`` (end torque GJ phi / L
  exactly, the rod stays straight);
* element counts 8 to 2000 (in the sweeps above);
* friction coefficients 0 to 1 (tangential Coulomb coefficient gamma_T on
  the hairpin) when the solver has friction (``gamma_T`` in
  ``ContactOptions`` and ``skfem_rod.contact.friction_assembly``);
  otherwise placeholder rows saying "not yet available".

For every case: converged or not, load steps (and step cuts), Newton
iterations, Uzawa updates, largest penetration, a condition estimate of
the last factorized tangent on the free dofs (exact 1-norm condition
number up to 1500 free dofs, ``onenormest(K^-1) * |K|_1`` above), a
physics check against an exact or independent reference, and the wall
time.  One case outside the documented range (20 turns on 16 elements,
more twist per element than the element chart allows) is run on purpose
to show how a solve fails: a clear message and the converged steps kept.

The case builders are imported by tests/test_stress_subset.py.
"""
import argparse
import datetime
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse.linalg as spla

from skfem_rod import Rod, Section, analytic, geometry
from skfem_rod import problem as problem_mod

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
HAIRPIN = ROOT / "scenes" / "hairpin_contact.toml"

L = 1.0
ALPHA = 2.0                        # cantilever P L^2 / EI
ROLL_SECTION = dict(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=1.0)
TWIST_SECTION = dict(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=0.8)
DENSE_LIMIT = 1500                 # exact condition number up to this many free dofs


# ---------------------------------------------------------------------------
# cases
# ---------------------------------------------------------------------------
@dataclass
class Case:
    group: str
    label: str
    build: object                  # () -> (rod, solve kwargs)
    check: object = None           # (rod, result) -> (value, description)
    outside: bool = False          # outside the documented range on purpose
    info: dict = field(default_factory=dict)


_refs = {}


def cantilever_section(ratio):
    return Section.circle(E=1e7, nu=0.3, radius=L / ratio)


def cantilever_reference(ratio):
    if ratio not in _refs:
        sec = cantilever_section(ratio)
        _refs[ratio] = analytic.elastica_cantilever(ALPHA, EA=sec.EA, GA=sec.GA1,
                                                    EI=sec.EI1, length=L)
    return _refs[ratio]


def cantilever(ratio, n_elements, n_steps):
    """Tip-loaded cantilever of slenderness L / radius = ``ratio``."""
    def build():
        sec = cantilever_section(ratio)
        rod = Rod(geometry.straight(L), sec, n_elements)
        rod.clamp("start").add_force("end", [0.0, ALPHA * sec.EI1 / L**2, 0.0])
        return rod, dict(n_steps=n_steps)

    def check(rod, res):
        ref = cantilever_reference(ratio)
        tip = res.nodes()[1][-1]
        return (float(np.linalg.norm(tip - [ref.x(L), ref.y(L), 0.0]) / L),
                "tip error / L vs Reissner elastica")
    return Case("slenderness x load steps x elements (cantilever)",
                f"L/r = {ratio:g}, {n_elements} el., {n_steps} steps", build, check,
                info=dict(ratio=ratio, n_elements=n_elements, n_steps=n_steps))


def rollup(n_elements, n_steps):
    """Roll-up into a full circle by the end moment 2 pi EI / L."""
    def build():
        rod = Rod(geometry.straight(L), Section(**ROLL_SECTION), n_elements)
        rod.clamp("start").add_moment("end", [0.0, 0.0, 2 * np.pi / L])
        return rod, dict(n_steps=n_steps)

    def check(rod, res):
        s, r, _ = res.nodes()
        ref = analytic.rollup(L, 1.0, 2 * np.pi / L, s)
        err = np.sqrt((r[:, 0] - ref.x) ** 2 + (r[:, 1] - ref.y) ** 2 + r[:, 2] ** 2)
        return float(err.max() / L), "max nodal error / L vs exact circle"
    return Case("load steps x elements (roll-up)",
                f"{n_elements} el., {n_steps} steps", build, check,
                info=dict(n_elements=n_elements, n_steps=n_steps))


def twist(turns, n_elements, outside=False):
    """Straight rod clamped at s = 0, pinned and twisted by ``turns`` at s = L."""
    def build():
        rod = Rod(geometry.straight(L), Section(**TWIST_SECTION), n_elements)
        rod.clamp("start").pin("end")
        rod.prescribe_rotation("end", [2 * np.pi * turns, 0.0, 0.0])
        return rod, dict(n_steps=1)

    def check(rod, res):
        phi = 2 * np.pi * turns * res.steps[-1].load_factor
        exact = analytic.twist_torque(TWIST_SECTION["GJ"], phi, L)
        m = res.reaction("end")[1]
        return (float(np.linalg.norm(m - [exact, 0, 0]) / exact),
                "|end moment - GJ phi / L| / (GJ phi / L) at the last step")
    per = 2 * np.pi * turns / n_elements
    return Case("twist (straight rod, prescribed end rotation)",
                f"{turns:g} turns, {n_elements} el. ({per:.2f} rad/el.)", build, check,
                outside=outside,
                info=dict(turns=turns, n_elements=n_elements, rad_per_element=per))


def hairpin_data(factor=1.0, n_elements=None):
    """The hairpin scene's table with the contact compliance ``factor``
    times the default ``10 eps^4 / EI`` (and optionally another mesh)."""
    from skfem_rod import scene as scene_mod
    d = scene_mod.read_toml(HAIRPIN)
    d.pop("output", None)
    sec = d["section"]
    eps = sec["radius"]
    d["contact"] = dict(d["contact"], penalty=factor * 10 * eps**4 / max(sec["EI1"], sec["EI2"]))
    if n_elements is not None:
        d["rod"] = dict(d["rod"], n_elements=n_elements)
    return d


def scene_solve_kwargs(sc):
    """The arguments ``Scene.solve`` gives ``rod.solve``."""
    from skfem_rod import scene as scene_mod
    s = sc.data["solver"]
    return dict(n_steps=s["n_steps"], path=s["path"], **scene_mod._solver_options(sc.data))


_hairpin_ref = {}


def hairpin_tip(n_elements):
    """Tip of the hairpin at the default penalty (the penalty-independent
    answer Uzawa should reproduce)."""
    from skfem_rod import scene as scene_mod
    if n_elements not in _hairpin_ref:
        sc = scene_mod.load_scene(hairpin_data(1.0, n_elements))
        res = sc.solve()
        assert res.converged, res.message
        _hairpin_ref[n_elements] = res.nodes()[1][-1]
    return _hairpin_ref[n_elements]


def hairpin(factor, n_elements=40, outside=False):
    def build():
        from skfem_rod import scene as scene_mod
        sc = scene_mod.load_scene(hairpin_data(factor, n_elements))
        return sc.build(), scene_solve_kwargs(sc)

    def check(rod, res):
        tip = res.nodes()[1][-1]
        return (float(np.linalg.norm(tip - hairpin_tip(n_elements)) / rod.length),
                "|tip - tip at the default penalty| / L")
    return Case("contact penalty (hairpin pressed closed)",
                f"mu_N = {factor:g} x default, {n_elements} el.", build, check,
                outside=outside, info=dict(factor=factor, n_elements=n_elements))


def hairpin_friction(gamma_T, n_elements=40):
    """The hairpin with the tangential Coulomb coefficient ``gamma_T``
    (default penalty); checked against the frictionless tip (the load
    presses the legs together, so friction should change little)."""
    def build():
        import dataclasses
        from skfem_rod import scene as scene_mod
        sc = scene_mod.load_scene(hairpin_data(1.0, n_elements))
        rod = sc.build()
        rod.contact = dataclasses.replace(rod.contact, gamma_T=float(gamma_T))
        return rod, scene_solve_kwargs(sc)

    def check(rod, res):
        tip = res.nodes()[1][-1]
        return (float(np.linalg.norm(tip - hairpin_tip(n_elements)) / rod.length),
                "|tip - frictionless tip| / L")
    return Case("friction coefficients (hairpin pressed closed)",
                f"gamma_T = {gamma_T:g}, {n_elements} el.", build, check,
                info=dict(gamma_T=gamma_T, n_elements=n_elements))


# ---------------------------------------------------------------------------
# measurement
# ---------------------------------------------------------------------------
class TangentProbe:
    """Records the last tangent the solver factorizes (and its fixed dofs)
    by wrapping ``Problem.factor`` for the duration of a ``with`` block
    (the factorizations of the full tangent, not those of a position
    correction)."""

    def __enter__(self):
        self.K, self.fixed, self.count = None, None, 0
        self._orig = problem_mod.Problem.factor
        probe = self

        def factor(problem, K, fixed=None):
            if fixed is None:
                probe.K, probe.fixed = K, problem.fixed
                probe.count += 1
            return probe._orig(problem, K, fixed)
        problem_mod.Problem.factor = factor
        return self

    def __exit__(self, *exc):
        problem_mod.Problem.factor = self._orig
        return False


def condition_estimate(K, fixed):
    """1-norm condition number of ``K`` on the free dofs: exact (dense) up
    to DENSE_LIMIT free dofs, ``onenormest(K^-1) * |K|_1`` above.
    Returns ``(value, method)``."""
    free = np.flatnonzero(~fixed)
    Kf = K.tocsc()[free][:, free].tocsc()
    if free.size <= DENSE_LIMIT:
        with np.errstate(all="ignore"):
            return float(np.linalg.cond(Kf.toarray(), 1)), "exact"
    try:
        lu = spla.splu(Kf)
    except RuntimeError:
        return float("inf"), "singular"
    op = spla.LinearOperator(Kf.shape, matvec=lu.solve, dtype=float,
                             rmatvec=lambda x: lu.solve(x, trans="T"))
    return float(spla.onenormest(op) * spla.norm(Kf, 1)), "onenormest"


def run_case(case):
    rod, kw = case.build()
    with TangentProbe() as probe:
        t0 = time.perf_counter()
        res = rod.solve(**kw)
        wall = time.perf_counter() - t0
    steps = res.steps[1:]
    cs = [st.contact for st in steps if st.contact is not None]
    newton = [c.newton_total if st.contact is not None else st.iterations
              for st, c in zip(steps, [st.contact for st in steps])]
    row = dict(case=case, result=res, converged=bool(res.converged), wall=wall,
               steps=len(steps), cuts=sum("cutting the step" in m for m in res.log),
               newton_total=int(sum(newton)), newton_max=int(max(newton, default=0)),
               factorizations=probe.count, message=res.message,
               lam=res.steps[-1].load_factor if res.steps else float("nan"))
    if cs:
        eps = rod.contact.radius
        row.update(uzawa_total=int(sum(c.uzawa for c in cs)),
                   uzawa_max=int(max(c.uzawa for c in cs)),
                   penetration=float(max(c.penetration for c in cs)) / eps,
                   uzawa_all_converged=all(c.uzawa_converged for c in cs))
    if probe.K is not None:
        row["cond"], row["cond_method"] = condition_estimate(probe.K, probe.fixed)
    if case.check is not None and len(res.steps) > 1:
        row["check"], row["check_what"] = case.check(rod, res)
    return row


GROUPS = ("penalty", "slenderness", "rollup", "twist", "friction")


def cases(quick=False, groups=GROUPS):
    out = _cases(quick)
    key = {"contact penalty": "penalty", "slenderness": "slenderness",
           "load steps x elements (roll-up)": "rollup", "twist": "twist",
           "friction": "friction"}
    return [c for c in out if any(c.group.startswith(k) and v in groups
                                  for k, v in key.items())]


def _cases(quick=False):
    out = []
    if quick:
        out += [hairpin(f) for f in (1e-4, 1.0, 1e2)]
        out += [cantilever(r, 8, s) for r in (10.0, 1e4) for s in (1, 100)]
        out += [rollup(n, s) for n, s in ((8, 1), (8, 100), (2000, 4))]
        out += [twist(t, 32) for t in (1.0, 20.0)]
        out += [twist(20.0, 16, outside=True)]
        return out
    out += [hairpin(10.0 ** k) for k in range(-4, 3)]
    out += [hairpin(10.0 ** k, 160) for k in (-4, 0, 2)]
    out += [hairpin(1e3, 40, outside=True), hairpin(1e3, 160, outside=True)]
    for n in (8, 125):
        out += [cantilever(r, n, s) for r in (10.0, 100.0, 1e3, 1e4) for s in (1, 10, 100)]
    out += [cantilever(r, 2000, s) for r in (10.0, 100.0, 1e3, 1e4) for s in (1, 10)]
    out += [rollup(8, s) for s in (1, 2, 5, 10, 20, 50, 100)]
    out += [rollup(n, s) for n in (32, 125, 500) for s in (1, 10, 100)]
    out += [rollup(2000, s) for s in (1, 10)]
    out += [twist(t, n) for n in (32, 125) for t in (0.5, 1.0, 2.0, 5.0, 10.0, 20.0)]
    out += [twist(20.0, 2000)]
    out += [twist(20.0, 16, outside=True)]
    out += [hairpin_friction(g) for g in (0.0, 0.1, 0.3, 1.0)]
    return out


# ---------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------
def _table(header, rows):
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(out)


def _short(msg, n=170):
    msg = msg.replace("|", "/")
    return msg if len(msg) <= n else msg[:n - 3] + "..."


def report(rows, wall, quick):
    lines = ["# skfem_rod stability stress tests\n",
             f"Command: `python benchmarks/stress.py{' --quick' if quick else ''}` "
             f"(run from `{ROOT}`)  ",
             f"Date: {datetime.datetime.now().astimezone().isoformat(timespec='seconds')}"
             f"{'  (QUICK run: a few cases)' if quick else ''}\n",
             "Every case is one `rod.solve` with default solver options. Columns: "
             "`steps` = converged load steps (step cuts in brackets); `Newton` = "
             "total Newton iterations (largest per step; with contact over all "
             "Uzawa passes); `Uzawa` = total multiplier updates (largest per "
             "step); `pen/eps` = largest penetration over the steps divided by "
             "the contact radius (Uzawa's tolerance is 1e-3); `cond` = 1-norm "
             "condition number of the last factorized tangent on the free dofs "
             "(exact up to 1500 free dofs, `scipy.sparse.linalg.onenormest` of "
             "K^-1 times |K|_1 above, marked ~); `check` = a physics check "
             "against an exact or independent reference (named per group). "
             "Ranges and limits: docs/ranges.md.\n"]
    groups = []
    for r in rows:
        if r["case"].group not in groups:
            groups.append(r["case"].group)
    n_fail_unexpected = 0
    for g in groups:
        sub = [r for r in rows if r["case"].group == g]
        what = next((r.get("check_what") for r in sub if r.get("check_what")), "")
        lines.append(f"## {g}\n")
        lines.append(f"check: {what}\n")
        trows = []
        for r in sub:
            c = r["case"]
            ok = r["converged"] and r.get("uzawa_all_converged", True)
            if not ok and not c.outside:
                n_fail_unexpected += 1
            status = "yes" if r["converged"] else "**NO**"
            if r["converged"] and not r.get("uzawa_all_converged", True):
                status = "yes, **Uzawa tolerance missed**"
            if c.outside:
                status += " (outside the range)"
            cond = r.get("cond")
            cond_s = "" if cond is None else (
                f"{'~' if r['cond_method'] == 'onenormest' else ''}{cond:.1e}")
            uz = f"{r['uzawa_total']} ({r['uzawa_max']})" if "uzawa_total" in r else "-"
            pen = f"{r['penetration']:.1e}" if "penetration" in r else "-"
            chk = f"{r['check']:.1e}" if "check" in r else ""
            note = "" if r["converged"] and not r["cuts"] else _short(r["message"])
            if r["converged"] and r["cuts"]:
                note = f"{r['cuts']} step cut(s), then converged"
            uz_notes = [m for m in r["result"].log if "Uzawa stopped" in m]
            if uz_notes:
                note = (f"{len(uz_notes)} step(s) in `Result.log`: "
                        + _short(uz_notes[-1], 140))
            trows.append([c.label, status, f"{r['steps']} ({r['cuts']})",
                          f"{r['newton_total']} ({r['newton_max']})", uz, pen, cond_s,
                          chk, f"{r['wall']:.2f} s", note])
        lines.append(_table(["case", "converged", "steps (cuts)", "Newton (max/step)",
                             "Uzawa (max/step)", "pen/eps", "cond", "check", "time",
                             "note"], trows))
        lines.append("")
    if not any(r["case"].group.startswith("friction") for r in rows):
        lines += ["## friction coefficients 0 to 1\n",
                  "Not run in this invocation.\n"]
    conv = sum(r["converged"] for r in rows)
    outside = sum(r["case"].outside for r in rows)
    lines.append("## Summary\n")
    lines.append(f"{len(rows)} solves, {conv} converged; {outside} run outside the "
                 f"documented range on purpose; **{n_fail_unexpected} unexpected "
                 f"failure(s)** inside the documented ranges (not converged, or "
                 f"Uzawa tolerance missed).")
    for r in rows:
        if r["case"].outside:
            res = r["result"]
            lines.append(
                f"\nOutside the range ({r['case'].label}): converged = "
                f"{res.converged}, {len(res.steps) - 1} converged steps kept (last "
                f"load factor {r['lam']:.4g}), `Result.message`: \"{res.message}\"")
            uz = [m for m in res.log if "Uzawa stopped" in m]
            if uz:
                lines.append(f"{len(uz)} step(s) accepted with the Uzawa tolerance missed "
                             f"(largest penetration {r['penetration']:.1e} eps); "
                             f"`Result.message` does not say so, `Result.log` and "
                             f"`Step.contact.uzawa_converged` do, e.g. \"{uz[-1]}\"")
    conds = [r["cond"] for r in rows if r.get("cond") is not None and np.isfinite(r["cond"])]
    if conds:
        lines.append(f"\nCondition estimates span {min(conds):.1e} to {max(conds):.1e}.")
    lines.append(f"\nTotal wall time {wall:.0f} s; load average at the end "
                 + ", ".join(f"{x:.2f}" for x in os.getloadavg()) + ".")
    return "\n".join(lines) + "\n", n_fail_unexpected


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a few cases only")
    ap.add_argument("--output", type=Path, default=None)
    ap.add_argument("--groups", default=",".join(GROUPS),
                    help=f"comma-separated subset of {', '.join(GROUPS)}")
    args = ap.parse_args(argv)
    groups = [g for g in args.groups.split(",") if g]
    if set(groups) - set(GROUPS):
        raise SystemExit(f"--groups: unknown {sorted(set(groups) - set(GROUPS))}; "
                         f"allowed: {', '.join(GROUPS)}")
    out = args.output or HERE / ("RESULTS_stress_quick.md" if args.quick
                                 else "RESULTS_stress.md")
    t0 = time.perf_counter()
    rows = []
    for case in cases(args.quick, groups):
        r = run_case(case)
        rows.append(r)
        print(f"{case.group[:28]:28s} {case.label:42s} conv={r['converged']!s:5s} "
              f"steps={r['steps']:3d} newton={r['newton_total']:4d} "
              f"cond={r.get('cond', float('nan')):.1e} check={r.get('check', float('nan')):.1e} "
              f"{r['wall']:.2f}s", flush=True)
    text, bad = report(rows, time.perf_counter() - t0, args.quick)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, out)
    print(f"\nwritten to {out}; unexpected failures: {bad}", flush=True)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
