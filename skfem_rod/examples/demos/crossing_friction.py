r"""Crossing strands with friction: a crossing pressed and pulled sideways
=======================================================================

A rod bent into a figure-eight (the lemniscate of Gerono) has two strands
that cross at 90 degrees, ``3 eps`` apart, with both ends clamped.  Two
opposite dead forces ``press`` at the crossing push the strands together,
and two opposite forces ``pull`` along ``x`` pull them apart sideways.
The elements are 9 contact radii long, so the crossing falls between the
Gauss slave points: a *crossing pair* (the closest points of the two
strands, both parameters free; docs/crossing-contact.md) carries the
contact, with tangential Coulomb friction ``gamma_T`` (the same law as the
slave points': the material slip of the two surface points in contact,
the force ``|F| <= gamma_T f_N``).

Where friction holds the pull (``gamma_T`` large enough) the crossing
*sticks*: the strands' material points in contact move together; where it
cannot, the crossing *slides* along the strands at ``|F| = gamma_T f_N``.
With ``gamma_T = 0.1`` and the default loads the first contact slides
(the strands touch while the pull already exceeds what the small normal
force holds), and every later step sticks.

This demo shows how to:

* switch on crossing contact with friction,
  ``rod.enable_contact(crossing=True, gamma_T=...)``;
* read a converged step's crossing pairs
  (``step.contact.crossing``: :class:`skfem_rod.results.CrossingContact`,
  point forces ``force``, friction forces ``friction``, states ``state``,
  slips ``slip``);
* check Coulomb's law at the crossing at every step (the bound, and the
  force along the slip where it slides);
* render the crossing with its pair marked (``Result.render`` draws the
  crossing pairs in pink).

Run ``python demos/crossing_friction.py --help``.
"""
import argparse
import os
import time

import numpy as np

from skfem_rod import Rod, Section, geometry
from skfem_rod.contact.friction import FrictionState, misalignment

EPS = 0.01           # tube radius = contact radius


def figure_eight(sep):
    """The lemniscate ``(sin t, sin t cos t, (sep / 2) cos t)``: strands
    crossing at 90 degrees at the origin, ``sep`` apart in ``z``; the
    curve and the arclengths of its two crossing points."""
    t = np.linspace(-np.pi / 2 + 0.4, 3 * np.pi / 2 - 0.4, 20001)
    p = np.c_[np.sin(t), np.sin(t) * np.cos(t), 0.5 * sep * np.cos(t)]
    s = np.r_[0, np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))]

    def r(q):
        q = np.clip(q, 0, s[-1])
        return np.c_[[np.interp(q, s, p[:, k]) for k in range(3)]].T
    return geometry.curve(r, s[-1], ds=1e-4), np.interp([0.0, np.pi], t, s)


def build(gamma_T=0.1, press=0.3, pull=0.02, n_elements=60):
    """The clamped figure-eight (``Section.circle(E=1e7, nu=0.3,
    radius=EPS)``), pressed and pulled at the crossing (load factor 1),
    crossing contact with friction ``gamma_T``."""
    shape, (s1, s2) = figure_eight(3 * EPS)
    rod = Rod(shape, Section.circle(E=1e7, nu=0.3, radius=EPS), n_elements)
    rod.clamp("start").clamp("end")
    sn = rod.mesh.s_nodes
    a, b = (float(sn[np.argmin(abs(sn - s))]) for s in (s1, s2))
    rod.add_force(a, [pull, 0.0, -press])
    rod.add_force(b, [-pull, 0.0, press])
    return rod.enable_contact(crossing=True, gamma_T=gamma_T)


def record(step, gamma_T):
    """The crossing's figures at a converged step: normal and friction
    point forces, ``|F| / (gamma_T f_N)``, state, slip length."""
    cr = step.contact.crossing
    if cr is None or cr.s.size == 0:
        return dict(load_factor=step.load_factor, pairs=0)
    fN = float(cr.force[0])
    F = float(np.linalg.norm(cr.friction[0]))
    return dict(load_factor=step.load_factor, pairs=int(cr.s.size), normal_force=fN,
                friction_force=F, share_of_bound=F / (gamma_T * fN) if gamma_T > 0 else 0.0,
                state=FrictionState(int(cr.state[0])).name.lower(),
                slip=float(np.linalg.norm(cr.slip[0])), s=float(cr.s[0]),
                s_bar=float(cr.s_bar[0]))


def coulomb_check(res, gamma_T, tolerance):
    """The largest violation of Coulomb's law over the converged steps'
    crossing pairs: ``|F| / (gamma_T f_N) - 1`` (the bound), and where a
    pair slides the sine of the angle between its force and its slip
    relative to the bound (``misalignment``)."""
    over = align = 0.0
    for st in res.steps[1:]:
        cr = st.contact.crossing
        if cr is None or cr.s.size == 0 or gamma_T <= 0:
            continue
        fN, F = cr.force / cr.weight, cr.friction / cr.weight[:, None]
        over = max(over, float(np.max(np.linalg.norm(F, axis=1) / (gamma_T * fN) - 1.0)))
        slip = cr.state == FrictionState.SLIP
        big = slip & (np.linalg.norm(cr.slip, axis=1) > 0)
        if big.any():
            align = max(align, float(misalignment(F[big], cr.slip[big], gamma_T,
                                                  fN[big]).max()))
    return dict(bound_excess=over, misalignment=align, tolerance=tolerance)


#: Quick settings (tests/test_demos.py).
SMALL = dict(window_size=(360, 270))


def main(out="output/crossing_friction", gamma_T=0.1, press=0.3, pull=0.02, n_steps=2,
         n_elements=60, render=True, verbose=True, window_size=(640, 480)):
    os.makedirs(out, exist_ok=True)
    say = print if verbose else (lambda *a: None)
    rod = build(gamma_T, press, pull, n_elements)
    t0 = time.perf_counter()
    res = rod.solve(n_steps)
    wall = time.perf_counter() - t0
    records = [record(st, gamma_T) for st in res.steps]
    for r in records:
        if r["pairs"]:
            say(f"  load factor {r['load_factor']:.4f}: crossing f_N = {r['normal_force']:.4f}, "
                f"|F| = {r['friction_force']:.4f} ({r['share_of_bound']:.2f} of the bound), "
                f"{r['state']}, slip {r['slip']:.2e}")
    check = coulomb_check(res, gamma_T, rod.contact.friction_tolerance)
    say(f"{res.message}; wall {wall:.1f} s; Coulomb: bound exceeded by "
        f"{check['bound_excess']:.1e}, misalignment {check['misalignment']:.1e}")
    from skfem_rod.export import write_json
    write_json(os.path.join(out, "results.json"),
               dict(converged=res.converged, message=res.message, wall_time_s=wall,
                    parameters=dict(gamma_T=gamma_T, press=press, pull=pull, n_steps=n_steps,
                                    n_elements=n_elements, eps=EPS),
                    coulomb=check, records=records))
    pngs = []
    if render and res.converged:
        path = os.path.join(out, "crossing_friction.png")
        last = records[-1]
        res.render(path, step=-1, window_size=window_size, camera=(0.3, -1.0, 0.8),
                   contact_radius=2.5 * EPS,
                   title=f"γ_T = {gamma_T:g}: the crossing {last.get('state', 'open')}s "
                         f"(|F| = {last.get('share_of_bound', 0.0):.2f} of the bound)")
        pngs.append(path)
    return dict(converged=res.converged, message=res.message, wall_time_s=wall,
                records=records, coulomb=check, renders=pngs, result=res, rod=rod)


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="output/crossing_friction")
    p.add_argument("--gamma", type=float, default=0.1, help="tangential Coulomb coefficient")
    p.add_argument("--press", type=float, default=0.3, help="pressing force at the crossing")
    p.add_argument("--pull", type=float, default=0.02, help="sideways pull at the crossing")
    p.add_argument("--steps", type=int, default=2, help="load steps to load factor 1")
    p.add_argument("--no-render", action="store_true")
    a = p.parse_args()
    main(a.out, a.gamma, a.press, a.pull, a.steps, render=not a.no_render)
