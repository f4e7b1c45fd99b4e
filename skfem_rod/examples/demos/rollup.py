"""Roll-up of a cantilever by an end moment
=========================================

This demo shows how to:

* build a straight rod with a section, a clamp and an end moment,
* solve the large-rotation equilibrium with load steps,
* compare with the exact solution (Simo & Vu-Quoc 1986): a moment
  ``M = phi EI / L`` bends the rod into a circle of curvature ``M / EI``;
  the end sits at ``(L sin(phi)/phi, L (1 - cos(phi))/phi)``,
* write the results (JSON summary, a VTU file per step plus a ParaView
  ``.pvd`` series) and an offscreen render of the rod as a tube whose stripe
  follows the director ``d1``,
* write the load path as an animated GIF (one frame per converged step,
  one camera for all frames: :func:`skfem_rod.render.render_animation`).

The equations are in docs/theory.md; run ``python demos/rollup.py --help``.
"""
import argparse
import os
import time

import numpy as np

from skfem_rod import Rod, Section, geometry

LENGTH = 1.0
EI = 1.0


def solve(phi=2 * np.pi, n_elements=16, n_steps=4):
    """Roll a cantilever up by the end angle ``phi``; return the result and
    the largest nodal distance to the exact circle (divided by L)."""
    section = Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=EI, EI2=EI, GJ=EI / 1.3,
                      radius=0.02 * LENGTH)
    rod = Rod(geometry.straight(LENGTH), section, n_elements)
    rod.clamp("start")
    rod.add_moment("end", [0.0, 0.0, phi * EI / LENGTH])   # about d2 = +z
    result = rod.solve(n_steps=n_steps)
    s, r, _ = result.nodes()
    k = phi / LENGTH
    exact = np.stack([np.sin(k * s) / k, (1 - np.cos(k * s)) / k, 0 * s], axis=1)
    return result, float(np.abs(r - exact).max() / LENGTH)


#: Settings for a quick run (tests, demos/gallery.py).
SMALL = dict(n_elements=8, n_steps=4, window_size=(480, 360), gif_size=(240, 180))
#: Settings of the gallery thumbnails (docs/img/gallery).
GALLERY = dict(n_elements=16, n_steps=16, window_size=(720, 540), gif_size=(480, 360))


def main(out="output/rollup", phi=2 * np.pi, n_elements=16, n_steps=8,
         window_size=(1024, 768), animate=True, gif_size=(480, 360)):
    """Solve, write ``results.json``, the VTU/PVD series, ``rollup.png``
    and (``animate=True``) ``rollup.gif`` in ``out``; return the summary."""
    os.makedirs(out, exist_ok=True)
    t0 = time.perf_counter()
    result, error = solve(phi, n_elements, n_steps)
    wall = time.perf_counter() - t0
    s, r, R = result.nodes()
    force, moment = result.reaction("start")
    summary = {
        "problem": "roll-up of a cantilever by an end moment",
        "phi": phi, "n_elements": n_elements, "converged": result.converged,
        "message": result.message, "wall_time_s": wall,
        "tip": r[-1].tolist(), "max_nodal_error_over_L": error,
        "strain_energy": result.steps[-1].energy,
        "exact_strain_energy": 0.5 * EI * (phi / LENGTH) ** 2 * LENGTH,
        "clamp_reaction_force": force.tolist(), "clamp_reaction_moment": moment.tolist(),
        "steps": [{"load_factor": st.load_factor, "iterations": st.iterations,
                   "residual_history": st.residual_history, "energy": st.energy}
                  for st in result.steps],
    }
    from skfem_rod.export import write_json
    write_json(os.path.join(out, "results.json"), summary)
    result.write_series(out, "rollup")
    png = result.render(os.path.join(out, "rollup.png"), camera="iso",
                        window_size=window_size,
                        title=f"roll-up by an end moment M = {phi / np.pi:.2g}π EI/L")
    files = [png]
    if animate:
        from skfem_rod.render import render_animation
        samples = [result.sample(8, k) for k in range(len(result.steps))]
        files.append(render_animation(
            os.path.join(out, "rollup.gif"), [(f["r"], f["R"]) for f in samples],
            result.rod.section.radius, window_size=gif_size, fps=3, camera=(0, -0.6, 1),
            titles=[f"M = {st.load_factor * phi / np.pi:.2f}π EI/L" for st in result.steps],
            reference=(samples[0]["r"], samples[0]["R"]),
            supports=[{"point": samples[0]["r"][0], "kind": "clamp"}]))
    summary["renders"] = [png]
    summary["animations"] = files[1:]
    print(f"{result.message}; max nodal error {error:.2e} L; wall {wall:.2f} s")
    print(f"wrote {out}/results.json, {out}/rollup.pvd (+ VTU per step), "
          + ", ".join(files))
    return summary


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="output/rollup", help="output directory")
    p.add_argument("--phi", type=float, default=2 * np.pi, help="end rotation (rad)")
    p.add_argument("--elements", type=int, default=16, help="number of P3 elements")
    p.add_argument("--steps", type=int, default=8, help="number of load steps")
    p.add_argument("--no-gif", action="store_true", help="skip the animated GIF")
    a = p.parse_args()
    main(a.out, a.phi, a.elements, a.steps, animate=not a.no_gif)
