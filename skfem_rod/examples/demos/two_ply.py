r"""Two-ply: a rod folded back on itself and twisted
==================================================

A rod is folded into a hairpin: two straight legs of length ``l`` at
``y = +a`` and ``y = -a`` joined by a half circle of radius ``a``.  Both
ends are clamped side by side at ``x = 0`` (``2 a`` apart, more than the
contact distance ``2 eps``: the clamps alone never touch).  The apex of the
fold (mid-length, on the ``x`` axis) is held on the axis, pulled along it by
a constant dead force ``T`` and turned about it by ``N`` turns.  The legs
wind around each other into a two-ply (frictionless self-contact between
the plies), as a rope or a rubber band twisted while folded.

This demo shows how to:

* build a folded reference shape with :func:`skfem_rod.geometry.curve`;
* prescribe the rotation of an interior node (the apex) and hold a force on
  it from the start (``add_force(..., constant=True)``);
* solve with self-contact, relaxing (``snap="relax"``) the steps where
  Newton finds no nearby equilibrium;
* measure the two-ply: the winding of the vector joining the legs (ply
  turns), the ply angle and pitch where the plies touch, the number of
  contact points, the torque at the apex, and check ``Tw + Wr`` (it stays
  at its initial value 0: both ends are held, the rod never passes through
  itself);
* render the plies with the contact points marked.

Geometry of the ply: where the plies touch, the vector ``d(x)`` from one
leg to the other at the same abscissa has length ``2 R`` (``R = eps``, the
superhelix radius) and turns at the rate ``k = d psi / dx``; the ply angle
between a ply's tangent and the axis is ``theta = arctan(R k)`` and the
pitch (axial length of one ply turn) ``2 pi / k``.  Between the clamp
(``d`` along ``y``) and the apex (``d`` turned with the apex) ``d`` turns
by ``N`` full turns, so the ply turns equal the applied turns.

Run ``python demos/two_ply.py --help``.
"""
import argparse
import os
import time

import numpy as np

from skfem_rod import Rod, Section, geometry

B = 1.0              # bending stiffness
GJ = B / 1.3         # torsional stiffness (circle, nu = 0.3)
EA = 1e4             # axial and shear stiffness


def hairpin(leg, a):
    """Folded reference shape: legs of length ``leg`` at ``y = +-a`` joined by
    a half circle of radius ``a`` (apex at ``(leg + a, 0, 0)``), planar in
    ``z = 0``, ``d1`` along ``z``."""
    L = 2 * leg + np.pi * a

    def r(s):
        s = np.asarray(s, float)
        phi = np.clip((s - leg) / a, 0.0, np.pi)
        x = np.where(s <= leg, s, np.where(s >= leg + np.pi * a, leg - (s - leg - np.pi * a),
                                           leg + a * np.sin(phi)))
        y = np.where(s <= leg, a, np.where(s >= leg + np.pi * a, -a, a * np.cos(phi)))
        return np.stack([x, y, np.zeros_like(x)], axis=1)

    return geometry.curve(r, L, d1_of_s=lambda s: np.tile([0.0, 0.0, 1.0], (len(s), 1)),
                          ds=1e-6 * a)


def build(leg=1.0, radius=0.02, separation=4.0, tension=10.0, turns=3.0, n_elements=48,
          penalty_factor=0.1):
    """The folded rod: clamps ``separation * radius`` apart, apex pulled by
    ``tension`` and turned by ``turns``; contact of radius ``radius``
    (compliance ``penalty_factor`` times the library default)."""
    if n_elements % 2:
        raise ValueError(f"n_elements must be even (the apex is a vertex), got {n_elements}")
    a = 0.5 * separation * radius
    section = Section(EA=EA, GA1=EA, GA2=EA, EI1=B, EI2=B, GJ=GJ, radius=radius)
    rod = Rod(hairpin(leg, a), section, n_elements)
    rod.clamp("start").clamp("end")
    apex = rod.length / 2
    rod.pin(apex, components=(1, 2))
    rod.prescribe_rotation(apex, [2 * np.pi * turns, 0.0, 0.0])
    rod.add_force(apex, [tension, 0.0, 0.0], constant=True)
    rod.enable_contact(radius=radius, penalty=penalty_factor * 10 * radius ** 4 / B)
    return rod


def ply_geometry(result, k, samples=400):
    """Ply measures at step ``k``: the vector ``d`` joining the legs at equal
    arclength from the clamps to the fold (which turns with the apex), its
    total winding (turns, from the clamps to the fold), and the ply
    angle / pitch over the stretch where the plies touch."""
    rod = result.rod
    L = rod.length
    a = 0.5 * np.linalg.norm(rod.r0[rod.node("end")] - rod.r0[rod.node("start")])
    leg = 0.5 * (L - np.pi * a)                      # end of the straight legs
    s = np.linspace(0.0, leg, samples)
    p1 = result.position(s, k)
    p2 = result.position(L - s, k)
    d = p2 - p1
    psi = np.unwrap(np.arctan2(d[:, 2], d[:, 1]))
    x = 0.5 * (p1[:, 0] + p2[:, 0])
    dist = np.linalg.norm(d, axis=1)
    eps = rod.contact.radius
    touch = np.abs(dist - 2 * eps) < 0.05 * eps
    out = dict(ply_turns=float((psi[-1] - psi[0]) / (2 * np.pi)),
               touching_length=float(np.sum(np.diff(x)[touch[1:]])))
    if touch.sum() >= 10:
        idx = np.flatnonzero(touch)
        i0, i1 = idx[len(idx) // 4], idx[3 * len(idx) // 4]
        kk = (psi[i1] - psi[i0]) / (x[i1] - x[i0])
        out.update(ply_rate=float(kk), pitch=float(2 * np.pi / abs(kk)),
                   ply_angle_deg=float(np.degrees(np.arctan(eps * abs(kk)))),
                   ply_radius=float(0.5 * dist[i0:i1 + 1].mean()))
    return out


def topology(result, k, per_element=16):
    """Twist, writhe and link of the rod closed by a planar rectangle behind
    the clamps: both ends point along ``-x`` (anti-parallel end tangents, so
    the library's end-tangent closure does not apply).  The clamps keep
    ``d1 = e_z``, which is also the (parallel) normal on the closure, so the
    closure adds no twist; ``link_gauss`` is the Gauss linking number of
    the closed ribbon (an integer, 0 for the planar reference)."""
    from skfem_rod.topology import topology as topo
    f = result.sample(per_element, k)
    p, d1 = f["r"], f["R"][:, :, 0]
    far = result.rod.length
    back = np.array([[p[-1, 0] - far, p[-1, 1], p[-1, 2]], [p[0, 0] - far, p[0, 1], p[0, 2]]])
    return topo(np.vstack([p, back]), np.vstack([d1, np.tile(d1[0], (2, 1))]), closed=True)


def record(result, k, turns):
    st = result.steps[k]
    rod = result.rod
    apex = rod.length / 2
    force, moment = result.reaction(apex, k)
    c = st.contact
    top = topology(result, k)
    tol = rod.contact.tolerance * rod.contact.radius
    rec = dict(step=k, turns=st.load_factor * turns, torque=float(moment[0]),
               apex_x=float(st.r[rod.node(apex), 0]), contacts=int(c.s.size),
               penetration=float(c.penetration) / rod.contact.radius,
               min_force=float(c.force.min(initial=np.inf)) if c.s.size else 0.0,
               max_active_gap=float(np.abs(c.gap).max(initial=0.0)) / tol,
               contact_force=c.total_force, flow_steps=int(st.flow_steps),
               twist=top.twist, writhe=top.writhe, link=top.link, link_gauss=top.link_gauss,
               clamp_torque=float(result.reaction("start", k)[1][0]
                                  + result.reaction("end", k)[1][0]))
    rec.update(ply_geometry(result, k))
    return rec


def solve(turns=2.0, n_steps=20, log=None, **kwargs):
    rod = build(turns=turns, **kwargs)
    records = []

    def callback(result, k):
        records.append(record(result, k, turns))
        if log is not None:
            log(records[-1])

    t0 = time.perf_counter()
    result = rod.solve(n_steps, snap="relax", callback=callback)
    return dict(result=result, rod=rod, records=records, converged=result.converged,
                message=result.message, wall_time_s=time.perf_counter() - t0)


#: Quick settings (tests/test_demos.py): a quarter turn, before contact.
SMALL = dict(turns=0.25, n_steps=2, n_elements=16, leg=0.6, window_size=(480, 240))
#: Gallery run (docs/img/gallery).
GALLERY = dict(turns=2.0, n_steps=20, window_size=(720, 360))


def main(out="output/two_ply", turns=2.0, n_steps=20, render=True, verbose=True,
         window_size=(900, 450), **kwargs):
    os.makedirs(out, exist_ok=True)
    say = print if verbose else (lambda *a: None)

    def log(r):
        say(f"  {r['turns']:5.2f} turns: torque {r['torque']:+.4f}  ply turns "
            f"{r['ply_turns']:+.3f}  contacts {r['contacts']:3d}  ply angle "
            f"{r.get('ply_angle_deg', float('nan')):5.1f} deg  Tw+Wr {r['link']:+.1e}")

    sol = solve(turns, n_steps, log=log, **kwargs)
    say(f"{sol['message']}; wall {sol['wall_time_s']:.1f} s")
    from skfem_rod.export import write_json
    write_json(os.path.join(out, "results.json"),
               dict(converged=sol["converged"], message=sol["message"],
                    wall_time_s=sol["wall_time_s"], records=sol["records"]))
    pngs = []
    if render:
        res, rod = sol["result"], sol["rod"]
        r = sol["records"][-1]
        path = os.path.join(out, "two_ply.png")
        lo, hi = res.steps[-1].r.min(axis=0), res.steps[-1].r.max(axis=0)
        c = 0.5 * (lo + hi)
        size = float(np.linalg.norm(hi - lo))
        cam = [tuple(c + size * np.array([0.15, -0.9, 0.45])), tuple(c), (0.0, 0.0, 1.0)]
        # tubes at half the contact radius, so that the contact points (on
        # the centrelines) show between the plies
        res.render(path, radius=0.5 * rod.contact.radius, camera=cam, window_size=window_size,
                   contact_radius=0.7 * rod.contact.radius,
                   title=f"two-ply: {r['turns']:.1f} turns, {r['contacts']} contact points, "
                         f"ply angle {r.get('ply_angle_deg', float('nan')):.1f}° "
                         "(tubes at half the contact radius)")
        pngs.append(path)
    return dict(sol, renders=pngs)


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="output/two_ply")
    p.add_argument("--turns", type=float, default=2.0, help="apex rotation in turns")
    p.add_argument("--steps", type=int, default=20, help="load steps")
    p.add_argument("--no-render", action="store_true")
    a = p.parse_args()
    main(a.out, a.turns, a.steps, render=not a.no_render)
