r"""Rotational self-friction: the torque two pressed stretches can transmit
=========================================================================

A rod is bent into a hairpin whose upper leg comes down onto the lower leg
and lies on it over a stretch ``ell`` (the "contact stretch").  The lower
leg is clamped at both of its ends; the upper leg's end is held on its axis
(free to move across it towards the lower leg), pressed onto the lower leg
by dead forces of total ``P`` spread over the contact stretch, and turned
about its axis by an angle ``phi`` that grows with the load factor.  The
tangential friction coefficient is zero, the rotational one ``gamma_R`` (a
length): only rotational friction (eq. 3.10c-d, 4.2c) acts.

What must happen (derivation in docs/friction.md)
-------------------------------------------------
Cut the upper leg at an arclength ``s_j`` between the ramp and the contact
stretch.  The part beyond the cut carries the end reaction couple ``M``,
the twisting moment ``m_x(s_j)`` of the rod at the cut, the contact
normal forces (through the axis: no moment about it), and the rotational
friction couples ``-f_R`` (slave side) and ``+f_R`` (master side) per unit
length.  With no tangential friction, its moment balance about the axis is

    M_x - m_x(s_j) = T,     T = - int (couples of rotational friction) ds,

so the torque transmitted by friction, ``T``, is measured from the
equilibrium (reaction and internal moment), not from the friction law.
Coulomb's law (3.10c-d) bounds every couple by ``gamma_R f_N``; when all
the points of the stretch slip (``|phi|`` large enough), each reaches the
bound and points against the relative spin (about the axis), so

    T -> gamma_R F_N,          F_N = int f_N ds  (both passes),

and ``F_N = P`` when the pressing forces are carried by the contact alone
(the demo measures both).  Before saturation the stretch sticks near the
cut and slips near the turned end; ``T`` grows with ``phi``.

Run ``python demos/rotational_friction.py --help``.
"""
import argparse
import os
import time

import numpy as np

from skfem_rod import Rod, Section, geometry

EPS = 0.02                      # tube radius = contact radius


def section():
    return Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=0.8, radius=EPS)


def shape(eps=EPS, leg=1.0, ramp=(0.15, 0.45), clearance=-1e-4):
    """Hairpin: lower leg on the x axis (x from ``leg`` to 0), a half circle
    of radius ``2 eps``, upper leg at height ``4 eps`` that ramps down
    (cosine) to ``2 eps (1 + clearance)`` (a touch: the contact is active
    from the start, so the first Newton iterate feels it) between ``x = ramp[0]`` and
    ``ramp[1]`` and lies flat over the lower leg to ``x = leg``."""
    x_low = np.linspace(leg, 0.0, 400, endpoint=False)
    th = np.linspace(0.0, np.pi, 120, endpoint=False)
    x_up = np.linspace(0.0, leg, 600)
    a, b = ramp
    h_hi, h_lo = 4 * eps, 2 * eps * (1 + clearance)
    t = np.clip((x_up - a) / (b - a), 0, 1)
    y_up = h_hi + (h_lo - h_hi) * 0.5 * (1 - np.cos(np.pi * t))
    pts = np.concatenate([
        np.c_[x_low, 0 * x_low, 0 * x_low],
        np.c_[-2 * eps * np.sin(th), 2 * eps * (1 - np.cos(th)), 0 * th],
        np.c_[x_up, y_up, 0 * x_up]])
    return geometry.polyline(pts)


def build(gamma_R=EPS, P=2.0, phi=0.06, n_elements=48, ramp=(0.15, 0.45)):
    """The rod, its supports and loads; returns ``(rod, s_cut)``."""
    rod = Rod(shape(ramp=ramp), section(), n_elements)
    s = rod.mesh.s_nodes
    x = rod.r0[:, 0]
    upper = s > rod.length / 2
    rod.clamp("start")
    # the lower leg's other end: the node nearest to x = 0 on the lower leg
    lower_end = np.flatnonzero(~upper)[np.argmin(np.abs(x[~upper]))]
    rod.clamp(float(s[lower_end]))
    rod.pin("end", components=(0, 2))
    rod.prescribe_rotation("end", [phi, 0.0, 0.0])
    press = np.flatnonzero(upper & (x > ramp[1] + 0.05) & (s < rod.length - 1e-9))
    for k in press:
        rod.add_force(float(s[k]), [0.0, -P / press.size, 0.0], constant=True)
    rod.enable_contact(gamma_R=gamma_R)
    # cut between the ramp and the contact stretch
    s_cut = float(s[upper][np.argmin(np.abs(x[upper] - (ramp[1] + 0.02)))])
    return rod, s_cut


def measure(result, s_cut, gamma_R):
    """Per step: turn angle fraction, end couple, twisting moment at the
    cut, transmitted torque, F_N, gamma_R F_N, slip/stick counts."""
    rows = []
    for k, st in enumerate(result.steps):
        c = st.contact
        M = result.reaction("end", k)[1][0]
        m_cut = result.evaluate([s_cut], k)["m"][0, 0]
        beyond = (c.s > s_cut) | (c.s_bar > s_cut)
        FN = float(np.sum(c.weight[beyond] * c.force[beyond]))
        rows.append(dict(load_factor=st.load_factor, end_couple=float(M),
                         cut_moment=float(m_cut), transmitted=float(M - m_cut),
                         FN=FN, bound=gamma_R * FN,
                         slip=int(np.sum(c.state_R == 2)), stick=int(np.sum(c.state_R == 1)),
                         penetration=float(c.penetration), dissipation=c.dissipation,
                         uzawa=c.uzawa, newton=c.newton_total))
    return rows


def solve(gamma_R=EPS, P=2.0, phi=0.06, n_elements=48, n_steps=12):
    rod, s_cut = build(gamma_R, P, phi, n_elements)
    t0 = time.perf_counter()
    result = rod.solve(n_steps=n_steps)
    wall = time.perf_counter() - t0
    return dict(rod=rod, result=result, s_cut=s_cut, rows=measure(result, s_cut, gamma_R),
                wall_time_s=wall)


#: settings of the test suite and of the gallery (demos/gallery.py)
SMALL = dict(n_elements=24, n_steps=4, window_size=(480, 360))
GALLERY = dict(n_elements=48, n_steps=12, window_size=(720, 540))


def main(out="output/rotational_friction", gamma_R=EPS, P=2.0, phi=0.06, n_elements=48,
         n_steps=12, render=True, verbose=True, window_size=(1024, 768)):
    """Solve, print the table, write ``results.json``, the torque plot and
    a render of the last step (contact points coloured by stick / slip);
    returns the summary dict."""
    os.makedirs(out, exist_ok=True)
    sol = solve(gamma_R, P, phi, n_elements, n_steps)
    rows, result = sol["rows"], sol["result"]
    if verbose:
        print(result.message, f"({sol['wall_time_s']:.1f} s)")
        for r in rows:
            print(f"lam={r['load_factor']:.3f} T={r['transmitted']:+.5f} "
                  f"gamma_R F_N={r['bound']:.5f} F_N={r['FN']:.4f} slip={r['slip']} "
                  f"stick={r['stick']} pen/eps={r['penetration'] / EPS:.1e}")
    last = rows[-1]
    summary = dict(problem="rotational friction between two pressed stretches",
                   parameters=dict(gamma_R=gamma_R, P=P, phi=phi, n_elements=n_elements,
                                   n_steps=n_steps, eps=EPS),
                   converged=result.converged, message=result.message,
                   saturation_ratio=last["transmitted"] / last["bound"] if last["bound"] else None,
                   wall_time_s=sol["wall_time_s"], rows=rows)
    from skfem_rod.export import write_json
    write_json(os.path.join(out, "results.json"), summary)
    summary["renders"], summary["plots"] = [], []
    if render:
        summary["plots"].append(_plot(rows, phi, os.path.join(out, "torque.png")))
        png = os.path.join(out, "rotational_friction.png")
        result.render(png, window_size=window_size,
                      title=f"rotational friction: T / (γ_R F_N) = "
                            f"{summary['saturation_ratio']:.4f}")
        summary["renders"].append(png)
    return summary


def _plot(rows, phi, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    lam = np.array([r["load_factor"] for r in rows])
    fig, ax = plt.subplots(figsize=(5.5, 4))
    ax.plot(lam * phi, [r["transmitted"] for r in rows], "o-", label="transmitted torque $T$")
    ax.plot(lam * phi, [r["bound"] for r in rows], "k--", label=r"$\gamma_R F_N$")
    ax.set_xlabel(r"end rotation $\varphi$ (rad)")
    ax.set_ylabel("torque")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="output/rotational_friction")
    p.add_argument("--gamma-r", type=float, default=EPS)
    p.add_argument("--force", type=float, default=2.0)
    p.add_argument("--phi", type=float, default=0.06)
    p.add_argument("--elements", type=int, default=48)
    p.add_argument("--steps", type=int, default=12)
    a = p.parse_args()
    main(a.out, a.gamma_r, a.force, a.phi, a.elements, a.steps)
