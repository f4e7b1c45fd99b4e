r"""The 45-degree bend under an out-of-plane tip force
===================================================

The classic test of Bathe & Bolourchi (1979), repeated by Simo & Vu-Quoc
(1986) and most papers on geometrically exact rods since: a curved
cantilever (an arc of radius 100 subtending 45 degrees, unit square
section) is clamped at one end and loaded at the other by a dead force
perpendicular to its plane.  The force grows to ``P = 600``; the rod bends
and twists far out of its plane.

This demo shows how to:

* build a curved rod from :func:`skfem_rod.geometry.arc` and a section
  given by its six stiffnesses,
* clamp it, load it by a tip force and solve with load steps,
* read the tip position at intermediate load factors (every converged
  step is kept in the :class:`skfem_rod.Result`),
* compare with an independent reference: the tip positions of a shooting
  solution of the Simo-Reissner equations (docs/verification.md, section 3),
  and with the published values,
* write a JSON summary, a render of the deformed rod with the tip force
  drawn as an arrow, and a plot of the tip coordinates against the load.

The same problem as a scene file is ``scenes/bend45.toml``
(``skfem-rod run scenes/bend45.toml``).

Setup
-----
Arc of radius ``R = 100`` in the x-y plane, from the origin with tangent
``+y`` curving toward ``+x`` (centre ``(100, 0, 0)``, free end at
``(29.29, 70.71, 0)``).  ``E = 1e7``, ``G = 5e6``, ``A = 1``,
``I = 1/12``, ``J = 1/6``, shear area ``A``.  Dead tip force ``(0, 0, P)``.

Reference tip positions (shooting on the rod equations, DOP853 with
rtol 1e-12; docs/verification.md):

======  ============  ============  ============
P       x             y             z
======  ============  ============  ============
300     22.24478095   58.77912249   40.19189167
450     18.50817893   52.23855801   48.50292734
600     15.68480053   47.15043857   53.47485879
======  ============  ============  ============

Published at ``P = 600``: Simo & Vu-Quoc (15.79, 47.23, 53.37), Bathe &
Bolourchi (15.9, 47.2, 53.4), both with 8 elements of lower order.  The
tip is a vertex of the P3 mesh, where the error falls like ``h^4``: about
9e-7 with 8 elements.

Run ``python demos/bend45.py --help``.
"""
import argparse
import os
import time

import numpy as np

from skfem_rod import Rod, Section, geometry

RADIUS = 100.0
P_MAX = 600.0
E, G, A, I, J = 1e7, 5e6, 1.0, 1.0 / 12, 1.0 / 6
#: Tip positions of the shooting solution (docs/verification.md, section 3).
REFERENCE = {
    300.0: (22.24478095, 58.77912249, 40.19189167),
    450.0: (18.50817893, 52.23855801, 48.50292734),
    600.0: (15.68480053, 47.15043857, 53.47485879),
}
PUBLISHED = {
    "Simo & Vu-Quoc (1986)": (15.79, 47.23, 53.37),
    "Bathe & Bolourchi (1979)": (15.9, 47.2, 53.4),
}
#: Settings for a quick run (tests, demos/gallery.py).
SMALL = dict(n_elements=4, n_steps=4, window_size=(480, 360))
#: Settings of the gallery thumbnails (docs/img/gallery).
GALLERY = dict(n_elements=8, n_steps=12, window_size=(720, 540))


def build(n_elements=8):
    """The clamped 45-degree arc with the tip force ``(0, 0, 600)`` at load
    factor 1."""
    shape = geometry.arc(RADIUS, np.pi / 4, start=(0.0, 0.0, 0.0),
                         tangent=(0.0, 1.0, 0.0), toward=(1.0, 0.0, 0.0))
    section = Section(EA=E * A, GA1=G * A, GA2=G * A, EI1=E * I, EI2=E * I, GJ=G * J,
                      radius=0.5)
    rod = Rod(shape, section, n_elements)
    rod.clamp("start")
    rod.add_force("end", [0.0, 0.0, P_MAX])
    return rod


def tip_history(result):
    """Load ``P`` and tip position of every converged step."""
    P = np.array([st.load_factor * P_MAX for st in result.steps])
    tips = np.array([st.r[result.rod.node("end")] for st in result.steps])
    return P, tips


def compare(P, tips):
    """Distance of the tip to the reference at every reference load reached
    by a step (``{P: error}``)."""
    out = {}
    for load, ref in REFERENCE.items():
        k = np.flatnonzero(np.isclose(P, load, rtol=0, atol=1e-9 * P_MAX))
        if k.size:
            out[load] = float(np.linalg.norm(tips[k[0]] - np.asarray(ref)))
    return out


def plot(filename, P, tips, window_size=(640, 480)):
    """Tip coordinates against the load, with the reference points."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from skfem_rod.export import atomic_path

    dpi = 100
    fig, ax = plt.subplots(figsize=(window_size[0] / dpi, window_size[1] / dpi), dpi=dpi)
    for c, name in enumerate("xyz"):
        ax.plot(P, tips[:, c], "-o", color=f"C{c}", ms=3, label=f"tip {name} (this code)")
    for c in range(3):
        ax.plot(list(REFERENCE), [v[c] for v in REFERENCE.values()], "s",
                mfc="none", color="k", ms=8, label="shooting reference" if c == 0 else None)
    for (name, v), m in zip(PUBLISHED.items(), ("^", "v")):
        ax.plot([P_MAX] * 3, v, m, color="grey", ms=6, label=name)
    ax.set_xlabel("tip force P")
    ax.set_ylabel("tip coordinate")
    ax.set_title("45-degree bend: tip position")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="center left")
    fig.tight_layout()
    with atomic_path(filename) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi)
    plt.close(fig)
    return filename


def main(out="output/bend45", n_elements=8, n_steps=12, window_size=(1024, 768),
         render=True):
    """Solve, compare with the reference, write ``results.json``,
    ``bend45.png`` (render) and ``bend45_tip.png`` (plot) in ``out``.

    ``n_steps`` should be a multiple of 4 for the comparison at P = 300 and
    450 (load factors 1/2 and 3/4); P = 600 is always compared.
    """
    from skfem_rod.export import write_json

    os.makedirs(out, exist_ok=True)
    t0 = time.perf_counter()
    rod = build(n_elements)
    result = rod.solve(n_steps=n_steps)
    wall = time.perf_counter() - t0
    P, tips = tip_history(result)
    errors = compare(P, tips)
    summary = {
        "problem": "45-degree bend (Bathe & Bolourchi 1979) under a dead tip force",
        "n_elements": n_elements, "n_steps": n_steps,
        "converged": result.converged, "message": result.message, "wall_time_s": wall,
        "tip": tips[-1].tolist(), "reference_tip": list(REFERENCE[P_MAX]),
        "tip_error": errors.get(P_MAX), "tip_errors": {f"{k:g}": v for k, v in errors.items()},
        "published": {k: list(v) for k, v in PUBLISHED.items()},
        "clamp_reaction_force": result.reaction("start")[0].tolist(),
        "steps": [{"load": float(p), "tip": t.tolist(), "iterations": st.iterations}
                  for p, t, st in zip(P, tips, result.steps)],
    }
    files = [os.path.join(out, "results.json")]
    summary["renders"], summary["plots"] = [], []
    if render:
        tip = tips[-1]
        summary["renders"].append(result.render(
            os.path.join(out, "bend45.png"), radius=1.5, camera="iso",
            window_size=window_size, title=f"45-degree bend, P = {P[-1]:g}",
            glyphs={"points": [tip], "vectors": [[0.0, 0.0, P[-1]]]}))
        summary["plots"].append(plot(os.path.join(out, "bend45_tip.png"), P, tips,
                                     window_size))
    write_json(files[0], summary)
    summary["files"] = files + summary["renders"] + summary["plots"]
    err = summary["tip_error"]
    print(f"{result.message}; tip {np.round(tips[-1], 5).tolist()}, "
          f"|tip - reference| = {err:.2e}; wall {wall:.2f} s" if err is not None
          else result.message)
    print("wrote " + ", ".join(summary["files"]))
    return summary


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="output/bend45", help="output directory")
    p.add_argument("--elements", type=int, default=8, help="number of P3 elements")
    p.add_argument("--steps", type=int, default=12, help="number of load steps")
    a = p.parse_args()
    main(a.out, a.elements, a.steps)
