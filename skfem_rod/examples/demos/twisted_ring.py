r"""Twisted ring: folding a ring into three loops (Goto et al. 1992)
================================================================

A ring of radius ``R`` (a thin strip: easy bending in the ring plane, stiff
bending out of it, like a band-saw blade) is clamped at a point ``A``.  At
the opposite point ``B`` the cross-section is turned about the diameter
``AB`` by an angle ``Theta``; ``B`` may slide along ``AB`` and is otherwise
held.  Turning ``B`` twists and bends the ring out of its plane, the path
folds (the turning angle passes a maximum, a *limit point*, and the ring
snaps under angle control), and at ``Theta = 2 pi`` the ring lies in its
plane again, wound three times around a circle of radius ``R / 3``.

Why ``2 pi`` at one end: in the triple-covered circle the tangent at ``B``
(half the length, 1.5 loops from ``A``) is opposite to the one at ``A``,
as in the flat ring, so ``B``'s cross-section is back in its initial
orientation, which a turn about ``AB`` reaches at ``0`` or ``2 pi``.  A
rigid rotation by ``-Theta / 2`` about ``AB`` maps the problem onto the
symmetric one of Goto et al. (both points turned by ``Theta / 2`` in
opposite senses): an end rotation of ``pi`` at each end.

This demo shows how to:

* build a closed rod (``geometry.ring``: the node at ``s = L`` is the node
  at ``s = 0``);
* hold a point, turn another and let it slide along a line (``clamp``,
  ``pin`` of two components, ``prescribe_rotation``);
* follow the equilibrium path through its limit points by pseudo-arclength
  continuation (``skfem_rod.continuation.follow``) with the lowest
  eigenvalues of the symmetrized tangent at each point, the limit points
  located by bisection;
* plot the path with its stability (solid stable, dashed unstable) and
  render the folded ring;
* check the end state against the exact triple-covered circle: every node
  at ``R / 3`` from the centre ``A + (R/3) n_A`` (``n_A`` the inward normal
  at ``A``), ``B`` slid to ``2R/3`` from ``A``, the bending moment
  ``EI2 (3 - 1) / R`` uniform.

Self-contact is off: in the exact end state the three loops coincide (a
centreline counted three times), which contact would prevent; the strands
pass through each other on the way.  Stability with contact is not supported
(``follow(..., stability=True)`` raises with contact on).

Run ``python demos/twisted_ring.py --help``.
"""
import argparse
import os
import time

import numpy as np

from skfem_rod import Rod, Section, geometry
from skfem_rod.continuation import follow

RADIUS = 1.0
#: thin strip: in-plane bending EI2 (about d2, the ring's normal) easy,
#: out-of-plane EI1 (about d1, the radius) stiff, GJ = 2 EI2 / (1 + nu)
SECTION = dict(EA=1e4, GA1=1e4, GA2=1e4, EI1=100.0, EI2=1.0, GJ=1.0 / 0.65,
               radius=0.02)


def build(n_elements=24, turn=2 * np.pi, section=None):
    """The ring clamped at ``A = (R, 0, 0)``, turned by ``turn`` (at load
    factor 1) about ``x`` at ``B = (-R, 0, 0)``, free to slide along ``x``."""
    rod = Rod(geometry.ring(RADIUS), Section(**(section or SECTION)), n_elements)
    half = rod.length / 2
    rod.clamp("start")
    rod.pin(half, (1, 2))
    rod.prescribe_rotation(half, [turn, 0.0, 0.0])
    return rod


def solve(n_elements=24, turn=2 * np.pi, max_steps=300, ds_max=None, stability=True):
    """Follow the path from the flat ring to ``Theta = turn``; returns the
    rod and the :class:`~skfem_rod.continuation.PathResult`."""
    rod = build(n_elements, turn)
    result = follow(rod, lam_stop=1.0, load_step=0.02, ds_max=ds_max, max_steps=max_steps,
                    target_iterations=5, stability=stability, n_eigen=2, locate=True,
                    locate_tol=1e-4)
    return rod, result


def triple_ring_error(rod, r):
    """Largest distance of the nodes from the circle of radius R/3 through
    ``A`` tangent to the ring there, in units of R."""
    centre = np.array([RADIUS - RADIUS / 3, 0.0, 0.0])
    d = np.linalg.norm(r[:, :2] - centre[:2], axis=1) - RADIUS / 3
    return float(max(np.abs(d).max(), np.abs(r[:, 2]).max()) / RADIUS)


#: Settings for a quick run (tests).
SMALL = dict(n_elements=12, window_size=(480, 360))


def main(out="output/twisted_ring", n_elements=24, turn=2 * np.pi, max_steps=300,
         window_size=(1024, 768)):
    """Trace the path, write ``results.json``, ``twisted_ring_path.png`` (end
    moment and slide of ``B`` against the turn, solid stable / dashed
    unstable) and renders of the fold and the end state; return the
    summary."""
    os.makedirs(out, exist_ok=True)
    t0 = time.perf_counter()
    rod, result = solve(n_elements, turn, max_steps)
    wall = time.perf_counter() - t0
    B = rod.node(rod.length / 2)
    A = rod.node("start")
    theta = result.load_factors * turn
    moment = np.array([st.reactions[B][1][0] for st in result.steps])
    slide = np.array([st.r[B, 0] - rod.r0[B, 0] for st in result.steps])
    r_end = result.steps[-1].r
    crit = [dict(kind=c.kind, turn=c.load_factor * turn, turn_over_pi=c.load_factor * turn
                 / np.pi, eigenvalue=c.eigenvalue) for c in result.critical]
    ev = result.eigenvalues
    # bending moment along the ring at the end: uniform EI2 (3 - 1) / R
    f = result.evaluate(np.linspace(0, rod.length, 8 * n_elements + 1))
    m_bend = np.linalg.norm(f["m"], axis=1)
    summary = {
        "problem": "twisted ring (Goto et al. 1992): clamp at A, turn about AB at B",
        "n_elements": n_elements, "section": SECTION, "radius": RADIUS,
        "converged": result.converged, "message": result.message, "wall_time_s": wall,
        "steps": len(result.steps) - 1,
        "newton_iterations": int(result.iterations.sum()),
        "turn_end": float(theta[-1]),
        "triple_ring_error_over_R": triple_ring_error(rod, r_end),
        "B_distance_from_A_over_R": float(np.linalg.norm(r_end[B] - r_end[A]) / RADIUS),
        "bending_moment_end": {"min": float(m_bend.min()), "max": float(m_bend.max()),
                               "exact": SECTION["EI2"] * 2 / RADIUS},
        "critical_points": crit,
        "max_turn_before_fold": float(theta[: np.argmax(result.index > 0)].max())
        if np.any(result.index > 0) else None,
        "path": {"turn": theta.tolist(), "end_moment_about_AB": moment.tolist(),
                 "slide_of_B": slide.tolist(), "index": result.index.tolist(),
                 "lowest_eigenvalues": ev[:, 0].tolist() if ev.size else []},
    }
    from skfem_rod.export import write_json
    write_json(os.path.join(out, "results.json"), summary)
    # plot: end moment and slide against the turn, stability marked
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    result.plot(moment, ax=axes[0], x=theta / np.pi, xlabel="turn of B  Theta / pi",
                ylabel="moment about AB at B  (EI2 / R)")
    result.plot(slide, ax=axes[1], x=theta / np.pi, xlabel="turn of B  Theta / pi",
                ylabel="slide of B along AB  (R)")
    axes[1].axhline(2 * RADIUS - 2 * RADIUS / 3, color="0.5", lw=0.8, ls=":")
    fig.suptitle("twisted ring: equilibrium path (solid stable, dashed unstable)")
    from skfem_rod.export import atomic_path
    plot = os.path.join(out, "twisted_ring_path.png")
    with atomic_path(plot) as tmp:
        fig.savefig(tmp, dpi=110, bbox_inches="tight", format="png")
    plt.close(fig)
    renders = []
    k_fold = int(np.argmax(result.index > 0)) if np.any(result.index > 0) else len(theta) // 2
    for name, k in (("fold", k_fold), ("end", -1)):
        png = os.path.join(out, f"twisted_ring_{name}.png")
        result.render(png, step=k, camera="iso", window_size=window_size,
                      title=f"twisted ring, Θ = {theta[k] / np.pi:.3f}π")
        renders.append(png)
    summary["plot"] = plot
    summary["renders"] = renders
    print(f"{result.message}; {summary['steps']} steps, wall {wall:.1f} s; triple-ring "
          f"error {summary['triple_ring_error_over_R']:.2e} R; critical points: "
          + ", ".join(f"{c['kind']} at {c['turn_over_pi']:.4f} pi" for c in crit))
    print(f"wrote {out}/results.json, {plot}, " + ", ".join(renders))
    return summary


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="output/twisted_ring", help="output directory")
    p.add_argument("--elements", type=int, default=24, help="number of P3 elements")
    p.add_argument("--turn", type=float, default=2 * np.pi, help="final turn of B (rad)")
    p.add_argument("--max-steps", type=int, default=300, help="continuation steps")
    a = p.parse_args()
    main(a.out, a.elements, a.turn, a.max_steps)
