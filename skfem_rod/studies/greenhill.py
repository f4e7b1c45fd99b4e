r"""Greenhill's twist-buckling threshold against tension: a sweep study
===================================================================

This study shows how to:

* run a shipped sweep scene (``scenes/greenhill_sweep.toml``: a zipped
  ``[sweep]`` of the end tension and the end turn) on Dask with
  :func:`skfem_rod.sweep`, and read its dataset (one ``point`` dimension,
  plus ``step``);
* find, per point, where the lowest eigenvalue of the tangent
  (``lowest_eigenvalue``, solver option ``stability``) changes sign along
  the path: the torque ``M_c`` and tension ``T_c`` at the loss of
  stability;
* compare ``M_c`` with Greenhill's threshold of the clamped rod.

A straight rod of length ``L`` and bending stiffness ``B`` is clamped at
one end; the other end stays on the axis, is pulled by ``T`` and turned
by ``phi``, both growing with the load factor.  The straight twisted rod is
an equilibrium for every load; it loses stability when (Greenhill; the
clamped-length factor ``m`` is the first root of the clamped-clamped
condition, :func:`skfem_rod.analytic.greenhill_factor`,
derived in docs/twisted_rod.md)

    M_c = 2 sqrt(B T) m(L sqrt(T / B)),      m -> 1 for a long rod.

Run ``python -m skfem_rod.studies.greenhill`` (``--help``); it writes the
dataset, ``thresholds.json`` and ``greenhill_sweep.png`` (docs/sweep.md).
"""
import argparse
import json
import os

import numpy as np

from .. import examples
from ..analytic import greenhill_factor

#: the shipped scene of the study
SCENE = examples.SCENES / "greenhill_sweep.toml"
#: the study at a small size (docs build, tests): coarser mesh and path, 3 tensions
SMALL = dict(n_elements=16, n_steps=12, points=[0, 2, 4])


def scene_table(n_elements=None, n_steps=None, points=None):
    """The study's scene table, optionally coarser or with fewer points."""
    from ..scene import read_toml
    d = read_toml(SCENE)
    if n_elements is not None:
        d["rod"]["n_elements"] = n_elements
    if n_steps is not None:
        d["solver"]["n_steps"] = n_steps
    if points is not None:
        d["sweep"] = {k: (v if k == "mode" else [v[i] for i in points])
                      for k, v in d["sweep"].items()}
    return d


def thresholds(ds):
    """Where each point loses stability: the first sign change of the
    lowest eigenvalue along the path, interpolated linearly in the load
    factor between the last positive and the first negative step.

    Returns a list of dicts (one per point): tension ``T0`` and turn
    ``phi`` at load factor 1, critical load factor, ``T_c``, ``M_c``,
    Greenhill's ``2 sqrt(B T_c)``, the clamped value (times ``m``) and
    ``M_c`` relative to it.
    """
    data = json.loads(ds.attrs["scene_data"])
    B = data["section"]["EI1"]
    L = data["rod"]["geometry"]["length"]
    rows = []
    for i in range(ds.sizes["point"]):
        p = ds.isel(point=i)
        n = int(p.n_steps)
        lam, ev = p.load_factor.values[:n], p.lowest_eigenvalue.values[:n]
        torque = p.end_torque.values[:n]
        T0 = float(p["load[0].vector[0]"])
        row = dict(T0=T0, phi=float(p["support[2].rotation_vector[0]"]),
                   converged=bool(p.converged))
        neg = np.flatnonzero(ev < 0)
        if neg.size and neg[0] > 0:
            k = neg[0]
            w = ev[k - 1] / (ev[k - 1] - ev[k])
            lc = lam[k - 1] + w * (lam[k] - lam[k - 1])
            Mc = torque[k - 1] + w * (torque[k] - torque[k - 1])
            Tc = T0 * lc
            inf = 2 * np.sqrt(B * Tc)
            m = greenhill_factor(L * np.sqrt(Tc / B))
            row.update(load_factor=float(lc), T_c=float(Tc), M_c=float(Mc),
                       L_over_lambda=float(L * np.sqrt(Tc / B)), greenhill=float(inf),
                       greenhill_clamped=float(inf * m), m=float(m),
                       ratio=float(Mc / inf), error=float(Mc / (inf * m) - 1))
        rows.append(row)
    return rows


def plot(ds, rows, path):
    """The family of curves (lowest eigenvalue against the torque in units
    of 2 sqrt(B T), one curve per tension) and the thresholds against
    Greenhill's clamped-rod curve; written to ``path``."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    data = json.loads(ds.attrs["scene_data"])
    B = data["section"]["EI1"]
    L = data["rod"]["geometry"]["length"]
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4.3))
    colors = plt.cm.viridis(np.linspace(0, 0.9, ds.sizes["point"]))
    top = 1.0
    for i, (row, c) in enumerate(zip(rows, colors)):
        p = ds.isel(point=i)
        n = int(p.n_steps)
        lam = p.load_factor.values[1:n]
        T = row["T0"] * lam
        x = p.end_torque.values[1:n] / (2 * np.sqrt(B * T))
        ev = p.lowest_eigenvalue.values[1:n] / p.lowest_eigenvalue.values[0]
        a.plot(x, ev, "o-", ms=3, color=c, label=f"T = {row['T0']:g} at load 1")
        top = max(top, float(np.nanmax(ev)))
        if "ratio" in row:
            a.plot(row["ratio"], 0, "x", color=c, ms=9, mew=2)
            a.axvline(row["m"], color=c, lw=0.8, ls=":")
    a.axhline(0, color="k", lw=0.8)
    a.set_ylim(-3, 1.15 * top)           # past the threshold the curves dive: clipped
    a.set_xlabel(r"end torque $M / 2\sqrt{BT}$")
    a.set_ylabel("lowest eigenvalue / its value at rest")
    a.set_title("along each path (x: sign change; dotted: clamped Greenhill)",
                fontsize=10)
    a.legend(fontsize=8)
    ell = np.linspace(2.5, max(r.get("L_over_lambda", 10) for r in rows) * 1.15, 120)
    b.plot(ell, [greenhill_factor(x) for x in ell], "k-",
           label=r"clamped rod: $m(L/\lambda)$")
    b.axhline(1, color="k", ls="--", lw=1, label=r"infinite rod: $M_c = 2\sqrt{BT}$")
    for row, c in zip(rows, colors):
        if "ratio" in row:
            b.plot(row["L_over_lambda"], row["ratio"], "o", color=c, ms=7)
    b.plot([], [], "o", color="gray", label="sweep (sign change of the eigenvalue)")
    b.set_xlabel(r"$L/\lambda = L\sqrt{T_c/B}$")
    b.set_ylabel(r"critical torque $M_c / 2\sqrt{BT_c}$")
    b.set_title(f"Greenhill threshold against tension (L = {L:g}, "
                f"{data['rod']['n_elements']} elements)", fontsize=10)
    b.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(out="output/greenhill_sweep", n_workers=2, scheduler=None, small=False,
         figure=True):
    """Run the sweep (resuming what ``out`` holds), find the thresholds,
    write ``thresholds.json`` and the figure; returns the thresholds."""
    from ..sweeps import sweep
    d = scene_table(**SMALL) if small else scene_table()
    from ..scene import load_scene
    ds = sweep(load_scene(d, name="greenhill_sweep"), out=out, n_workers=n_workers,
               scheduler=scheduler)
    rows = thresholds(ds)
    with open(os.path.join(out, "thresholds.json"), "w") as f:
        json.dump(rows, f, indent=1)
    if figure:
        plot(ds, rows, os.path.join(out, "greenhill_sweep.png"))
    return rows


if __name__ == "__main__":
    import logging
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="output/greenhill_sweep")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--scheduler", help="a running Dask scheduler, tcp://host:8786")
    ap.add_argument("--small", action="store_true", help="the small size (3 points)")
    args = ap.parse_args()
    logging.basicConfig(format="%(message)s")
    logging.getLogger("skfem_rod.sweep").setLevel(logging.INFO)
    os.environ.setdefault("DASK_LOGGING__DISTRIBUTED", "warning")
    for r in main(args.out, args.workers, args.scheduler, args.small):
        if "M_c" in r:
            print(f"T0 = {r['T0']:5g}: T_c = {r['T_c']:.4f}  M_c = {r['M_c']:.4f}  "
                  f"M_c / 2 sqrt(B T_c) = {r['ratio']:.4f}  clamped Greenhill m = "
                  f"{r['m']:.4f}  error {r['error']:+.2e}")
        else:
            print(f"T0 = {r['T0']:5g}: no sign change along the path")
