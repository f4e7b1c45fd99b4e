r"""Squeezed loop: contact that appears and disappears along the load path
=====================================================================

A rod whose stress-free shape is an open ring (a circular arc of radius
``rho`` and angle ``2 pi - delta``) is clamped at both ends; the ends are a
chord ``2 rho sin(delta / 2)`` apart, far more than the contact distance
``2 eps``, so the clamps alone never touch.  Two equal and opposite dead
forces at the quarter points ``s = L/4`` and ``3L/4`` squeeze the loop
across its symmetry axis until the two sides touch each other in the middle
(frictionless self-contact), then the forces are released: the load path
of the load factor is ``0 -> 1 -> 0``.

This demo shows how to:

* run a load/unload path, ``rod.solve(n_steps, path=[0, 1, 0])``;
* follow contact appearing, growing, shrinking and disappearing;
* check the contact law at every converged step (penetration below the
  Uzawa tolerance, ``f_N > 0`` at the active points, which sit on the
  contact distance: complementarity);
* check path independence: the rod is elastic and the contact is
  frictionless (it derives from a potential), so at the end of the path
  the rod is back in its reference state (energy zero, positions equal to
  the start), and the loading and unloading branches coincide at equal load
  factors;
* render the squeezed loop with the contact points marked.

Run ``python demos/squeezed_loop.py --help``.
"""
import argparse
import os
import time

import numpy as np

from skfem_rod import Rod, Section, geometry

B = 1.0              # bending stiffness
GJ = B / 1.3
EA = 1e4


def build(rho=1.0, delta=0.4, radius=0.02, force=30.0, n_elements=48, penalty_factor=1.0,
          crossing=False):
    """The open ring, both ends clamped, squeezed by ``force`` (in units of
    ``B / rho^2``) at the quarter points, perpendicular to its symmetry
    axis.  ``n_elements`` must be a multiple of 4 (nodes at the quarter
    points).  ``crossing``: point pairs at the closest points of the
    strands too (docs/crossing-contact.md), which hold the touching sides
    to the tolerance between slave points."""
    if n_elements % 4:
        raise ValueError(f"n_elements must be a multiple of 4, got {n_elements}")
    angle = 2 * np.pi - delta
    section = Section(EA=EA, GA1=EA, GA2=EA, EI1=B, EI2=B, GJ=GJ, radius=radius)
    rod = Rod(geometry.arc(rho, angle), section, n_elements)
    rod.clamp("start").clamp("end")
    L = rod.length
    # the symmetry axis passes through the centre (0, rho) and the point at
    # s = L/2; the quarter points lie symmetric to it
    p1, p2 = rod.r0[rod.node(L / 4)], rod.r0[rod.node(3 * L / 4)]
    u = (p2 - p1) / np.linalg.norm(p2 - p1)
    F = force * B / rho ** 2
    rod.add_force(L / 4, F * u)
    rod.add_force(3 * L / 4, -F * u)
    rod.enable_contact(radius=radius, penalty=penalty_factor * 10 * radius ** 4 / B,
                       crossing=crossing)
    return rod


def record(result, k):
    st = result.steps[k]
    rod = result.rod
    c = st.contact
    tol = rod.contact.tolerance * rod.contact.radius
    L = rod.length
    p1, p2 = st.r[rod.node(L / 4)], st.r[rod.node(3 * L / 4)]
    return dict(step=k, time=st.time, load_factor=st.load_factor, contacts=int(c.s.size),
                penetration=float(c.penetration) / rod.contact.radius,
                min_force=float(c.force.min(initial=np.inf)) if c.s.size else 0.0,
                max_active_gap=float(np.abs(c.gap).max(initial=0.0)) / tol,
                contact_force=c.total_force, energy=st.energy,
                quarter_distance=float(np.linalg.norm(p2 - p1)),
                contact_span=(float(np.ptp(c.s)) if c.s.size else 0.0),
                uzawa=int(c.uzawa), newton=int(c.newton_total))


def solve(n_steps=16, log=None, **kwargs):
    rod = build(**kwargs)
    records = []

    def callback(result, k):
        records.append(record(result, k))
        if log is not None:
            log(records[-1])

    t0 = time.perf_counter()
    result = rod.solve(n_steps, path=[0.0, 1.0, 0.0], snap="relax", callback=callback)
    return dict(result=result, rod=rod, records=records, converged=result.converged,
                message=result.message, wall_time_s=time.perf_counter() - t0)


#: Quick settings (tests/test_demos.py).
SMALL = dict(n_steps=8, n_elements=24, window_size=(360, 360))
#: Gallery run (docs/img/gallery).
GALLERY = dict(n_steps=16, window_size=(540, 540))


def main(out="output/squeezed_loop", n_steps=16, render=True, verbose=True,
         window_size=(600, 600), **kwargs):
    os.makedirs(out, exist_ok=True)
    say = print if verbose else (lambda *a: None)

    def log(r):
        say(f"  t={r['time']:.3f} lam={r['load_factor']:.3f}: contacts {r['contacts']:3d} "
            f"contact force {r['contact_force']:8.4f}  quarter points "
            f"{r['quarter_distance']:.4f} apart  energy {r['energy']:.5f}")

    sol = solve(n_steps, log=log, **kwargs)
    res, rod = sol["result"], sol["rod"]
    first, last = res.steps[0], res.steps[-1]
    back = dict(position_change=float(np.abs(last.r - first.r).max() / rod.length),
                rotation_change=float(np.abs(last.R - first.R).max()),
                energy_end=last.energy)
    say(f"{sol['message']}; wall {sol['wall_time_s']:.1f} s; back at the start: "
        f"max |r_end - r_0| / L = {back['position_change']:.1e}, "
        f"energy {back['energy_end']:.1e}")
    from skfem_rod.export import write_json
    write_json(os.path.join(out, "results.json"),
               dict(converged=sol["converged"], message=sol["message"],
                    wall_time_s=sol["wall_time_s"], back=back, records=sol["records"]))
    pngs = []
    if render:
        peak = int(np.argmax([r["load_factor"] for r in sol["records"]]))
        for name, k in (("reference", 0), ("squeezed", peak)):
            r = sol["records"][k]
            path = os.path.join(out, f"squeezed_loop_{name}.png")
            res.render(path, step=k, radius=rod.contact.radius, camera="xy",
                       window_size=window_size,
                       title=f"{name}: load factor {r['load_factor']:.2f}, "
                             f"{r['contacts']} contact points")
            pngs.append(path)
    return dict(sol, back=back, renders=pngs)


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="output/squeezed_loop")
    p.add_argument("--steps", type=int, default=16, help="load steps over the path 0 -> 1 -> 0")
    p.add_argument("--force", type=float, default=30.0, help="squeeze force / (B / rho^2)")
    p.add_argument("--no-render", action="store_true")
    a = p.parse_args()
    main(a.out, a.steps, render=not a.no_render, force=a.force)
