r"""Overhand (trefoil) knot pulled tight and let loose, with and without friction
==============================================================================

A rod is tied into an open overhand knot (an open trefoil).  One end is
clamped; the other end is clamped too but moved along the pulling axis ``x``
(end-to-end distance control): first away from the clamp by ``pull``
(the knot tightens), then back to where it started (the knot loosens,
pushed open by its own bending stiffness).  The load path is
``path=[0, 1, 0]``.  The pulling force ``F`` is the ``x`` reaction of the
moved end.  Self-contact is on (contact radius ``h`` = the tube radius), with
tangential Coulomb friction ``gamma_T`` (0 = frictionless) and no rotational
friction.

Reference shape
---------------
The closed trefoil ``(sin t + 2 sin 2t, cos t - 2 cos 2t, -sin 3t)`` is cut at
the apex of an outer lobe (``t = pi``), where the curve is tangent to the
line ``tau = (1, 0, 1)/sqrt 2`` and no other part of the knot comes near
that line.  The two cut ends are pushed apart across the line (by a smooth
bump along ``(1, 0, -1)/sqrt 2`` that dies out after 12 % of the knot at
each end), and straight tails are attached along ``-tau`` before the start
and ``+tau`` after the end.  The shape is rotated so that ``tau`` is ``x``
and scaled so that the strands are ``clearance`` contact radii apart at
their closest (6 by default; :func:`min_strand_distance` checks it).

What it measures
----------------
Per converged step: end-to-end distance ``d``, pulling force ``F``, the
loop radius ``R`` read off the FE shape (radius of curvature at the point
of the knot farthest from the pulling axis, the apex of the loop), the
number of contact points, stick/slip counts, penetration, dissipated
energy, link (``Result.topology``: constant unless strands pass through
each other) and the smallest distance between strands.

Frictionless statics is path-independent: the loosening branch must retrace
the tightening branch.  With friction the knot resists both ways: the force
needed to tighten exceeds the force at which it loosens, at the same ``d``
(hysteresis), increasingly so as ``gamma_T`` grows.  Audoly, Clauvelin &
Neukirch (PRL 99, 164301, 2007) give, for a knot sliding through its own
braid (tight-knot limit, ``eps = sqrt(h / R)`` small),

    F h^2 / B = eps^4 / 2  +/-  c gamma eps^3,     c = 0.492 (trefoil),

``+`` tightening, ``-`` loosening; docs/knot.md compares it with the
measured branches.

Run ``python demos/knot.py --help``.
"""
import argparse
import os
import time

import numpy as np

from skfem_rod import Rod, Section, geometry

EPS = 0.02                # tube radius h = contact radius
B = 1.0                   # bending stiffness
C_TREFOIL = 0.492         # Audoly et al. (2007): friction constant of the trefoil
_UNIT_CLEARANCE = 1.2     # closest approach of strands in the unit-size reference


def section(eps=EPS):
    """Nearly inextensible, unshearable round rod: ``EA = GA = 1e4 >> B / eps^2``."""
    return Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=B, EI2=B, GJ=B / 1.3, radius=eps)


def _smoothstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3 - 2 * x)


def knot_points(eps=EPS, clearance=6.0, tail=0.5, offset=0.7, blend=0.12, n=1500):
    """Points of the open trefoil with straight tails along ``x`` (the
    pulling axis), scaled so that strands are about ``clearance * eps``
    apart; ``tail`` is the length of each tail."""
    t = np.linspace(np.pi, 3 * np.pi, n)
    P = np.c_[np.sin(t) + 2 * np.sin(2 * t), np.cos(t) - 2 * np.cos(2 * t), -np.sin(3 * t)]
    tau = np.array([1.0, 0.0, 1.0]) / np.sqrt(2)       # tangent at the cut
    nrm = np.array([1.0, 0.0, -1.0]) / np.sqrt(2)      # across the cut, away from the knot
    u = (t - np.pi) / (2 * np.pi)
    bump = (1 - _smoothstep(u / blend)) - (1 - _smoothstep((1 - u) / blend))
    P = P + offset * bump[:, None] * nrm
    scale = clearance * eps / _UNIT_CLEARANCE
    P = (P - P[0]) * scale
    m = max(int(tail / (np.linalg.norm(P[1] - P[0]))), 2)
    v = np.linspace(0.0, tail, m + 1)[1:, None]
    P = np.r_[P[0] - tau * v[::-1], P, P[-1] + tau * v]
    Q = np.array([tau, [0.0, 1.0, 0.0], -nrm])          # rows: new x, y, z (right-handed)
    P = P @ Q.T
    return P - P[0]


def min_strand_distance(r, s, exclusion):
    """Smallest distance between points ``r`` (ordered along the rod at
    arclengths ``s``) that are more than ``exclusion`` apart along it."""
    D = np.linalg.norm(r[:, None] - r[None], axis=2)
    far = np.abs(s[:, None] - s[None]) > exclusion
    return float(D[far].min())


def shape(eps=EPS, clearance=6.0, tail=0.5):
    return geometry.polyline(knot_points(eps, clearance, tail))


def build(gamma_T=0.0, pull=1.2, n_elements=80, eps=EPS, clearance=6.0, tail=0.5,
          **contact):
    """The rod: start clamped, end clamped and moved by ``pull`` along ``x``
    at load factor 1; contact with tangential friction ``gamma_T``."""
    rod = Rod(shape(eps, clearance, tail), section(eps), n_elements)
    rod.clamp("start")
    rod.clamp("end")
    rod.prescribe_displacement("end", [pull, 0.0, 0.0])
    rod.enable_contact(radius=eps, gamma_T=gamma_T, **contact)
    return rod


def _sampled(result, k, per_element):
    """Arclengths and positions at ``per_element`` points per element."""
    s = np.linspace(0.0, result.rod.length, result.rod.mesh.n_elements * per_element + 1)
    return s, result.evaluate(s, k)["r"]


def loop_radius(result, k, per_element=16):
    """Radius of curvature at the apex of the loop: the point of the knot
    (the part between the tails) farthest from the pulling axis ``x``."""
    s, r = _sampled(result, k, per_element)
    rho = np.hypot(r[:, 1], r[:, 2])
    i = int(np.argmax(rho))
    # curvature from the sampled centreline (central differences in s)
    t = np.gradient(r, s, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    kappa = np.linalg.norm(np.gradient(t, s, axis=0), axis=1)
    j = slice(max(i - per_element // 2, 0), i + per_element // 2 + 1)
    return float(1.0 / np.mean(kappa[j]))


def record(result, k, eps):
    """The measurements of step ``k`` (a dict)."""
    st = result.steps[k]
    s, r, _ = result.nodes(k)
    F = result.reaction("end", k)[0]
    c = st.contact
    top = result.topology(k)
    row = dict(step=k, time=st.time, load_factor=st.load_factor,
               distance=float(np.linalg.norm(r[-1] - r[0])),
               force=float(F[0]), loop_radius=loop_radius(result, k),
               link=float(top.link), writhe=float(top.writhe),
               min_strand_distance=min_strand_distance(
                   *_sampled(result, k, 6)[::-1], 2.5 * np.pi * eps),
               n_contact=0, stick=0, slip=0, penetration=0.0, dissipation=0.0,
               uzawa=0, newton=st.iterations, normal_force=0.0)
    if c is not None:
        row.update(n_contact=int(c.s.size), penetration=float(c.penetration),
                   uzawa=int(c.uzawa), newton=int(c.newton_total),
                   normal_force=c.total_force / 2)
        if c.friction:
            row.update(stick=int(np.sum(c.state_T == 1)), slip=int(np.sum(c.state_T == 2)),
                       dissipation=float(c.dissipation))
    return row


def solve(gamma_T=0.0, pull=1.2, n_elements=80, n_steps=40, eps=EPS, clearance=6.0,
          tail=0.5, max_iterations=6, verbose=False, **contact):
    """Tighten (load factor 0 -> 1) and loosen (1 -> 0) in ``n_steps``
    steps each way (``2 n_steps`` in all, more if steps are cut).

    Solver choices (measured, see docs/knot.md): in the loose knot the
    tangent is nearly singular (the loops can swing and slide on the few
    contact points), and plain Newton iterates move nodes by 10 to 37 tube
    radii at a time; with 25 iterations allowed such an iterate carried one
    strand through another (the link jumped from -2.5 to +1.5 turns) and the
    knot came undone.  So Newton gets only ``max_iterations`` (6) per step,
    and a step that does not converge by then is relaxed by the gradient
    flow (``snap="relax"``), whose iterates may not move two strands towards
    each other by more than half their clearance."""
    rod = build(gamma_T, pull, n_elements, eps, clearance, tail, **contact)
    rows = []

    def cb(result, k):
        rows.append(record(result, k, eps))
        if verbose:
            w = rows[-1]
            print(f"  k={k:3d} lam={w['load_factor']:.3f} d={w['distance']:.4f} "
                  f"F={w['force']:9.4f} R/h={w['loop_radius'] / eps:6.2f} n_c={w['n_contact']:3d} "
                  f"slip={w['slip']:3d} pen/h={w['penetration'] / eps:.1e} "
                  f"dmin/h={w['min_strand_distance'] / eps:.3f} Lk={w['link']:+.3f} "
                  f"newton={w['newton']} uzawa={w['uzawa']}", flush=True)

    t0 = time.perf_counter()
    result = rod.solve(n_steps=2 * n_steps, path=[0.0, 1.0, 0.0], callback=cb, snap="relax",
                       max_iterations=max_iterations)
    wall = time.perf_counter() - t0
    return dict(rod=rod, result=result, rows=rows, wall_time_s=wall, gamma_T=gamma_T,
                eps=eps, pull=pull)


def branches(rows):
    """Split the rows into the tightening and loosening branches, each as
    arrays ``(d, F)`` sorted by ``d`` (the turning step in both)."""
    lam = np.array([w["load_factor"] for w in rows])
    t = np.array([w["time"] for w in rows])
    d = np.array([w["distance"] for w in rows])
    F = np.array([w["force"] for w in rows])
    up = t <= 0.5 + 1e-12
    down = t >= 0.5 - 1e-12
    out = []
    for m in (up, down):
        o = np.argsort(d[m])
        out.append((d[m][o], F[m][o], lam[m][o]))
    return out


def hysteresis(rows, d_at):
    """Tightening and loosening forces interpolated at end distances ``d_at``."""
    (du, Fu, _), (dd, Fd, _) = branches(rows)
    return np.interp(d_at, du, Fu), np.interp(d_at, dd, Fd)


def audoly(eps_knot, gamma, c=C_TREFOIL):
    """``F h^2 / B`` of a sliding trefoil (Audoly et al. 2007): tightening
    and loosening."""
    e = np.asarray(eps_knot)
    return 0.5 * e**4 + c * gamma * e**3, 0.5 * e**4 - c * gamma * e**3


#: settings of the test suite (a short pull: the loose knot, no contact yet)
#: and of the gallery (demos/gallery.py)
SMALL = dict(gammas=(0.0,), pull=0.1, n_elements=48, n_steps=4, window_size=(480, 360))
GALLERY = dict(gammas=(0.0, 0.2), pull=0.6, n_elements=80, n_steps=40, window_size=(720, 540))


def main(out="output/knot", gammas=(0.0, 0.1, 0.2, 0.3), pull=1.2, n_elements=80, n_steps=40,
         render=True, verbose=True, window_size=(900, 600)):
    os.makedirs(out, exist_ok=True)
    sols = []
    for g in gammas:
        if verbose:
            print(f"gamma_T = {g}")
        sol = solve(g, pull, n_elements, n_steps, verbose=verbose)
        if verbose:
            print(" ", sol["result"].message, f"({sol['wall_time_s']:.1f} s)")
        sols.append(sol)
    summary = dict(problem="overhand knot tightened and loosened (end-to-end distance control)",
                   parameters=dict(eps=EPS, B=B, pull=pull, n_elements=n_elements,
                                   n_steps=n_steps, gammas=list(gammas), c_trefoil=C_TREFOIL),
                   runs=[])
    for sol in sols:
        rows = sol["rows"]
        k_top = int(np.argmax([w["load_factor"] for w in rows]))
        top = rows[k_top]
        eps_k = np.sqrt(EPS / top["loop_radius"])
        up, down = audoly(eps_k, sol["gamma_T"])
        summary["runs"].append(dict(
            gamma_T=sol["gamma_T"], converged=sol["result"].converged,
            message=sol["result"].message, wall_time_s=sol["wall_time_s"],
            tightest=dict(distance=top["distance"], force=top["force"],
                          loop_radius=top["loop_radius"], eps_knot=float(eps_k),
                          F_h2_over_B=top["force"] * EPS**2 / B,
                          audoly_tightening=float(up), audoly_loosening=float(down)),
            max_penetration_over_h=max(w["penetration"] for w in rows) / EPS,
            min_strand_distance_over_h=min(w["min_strand_distance"] for w in rows) / EPS,
            link_range=[min(w["link"] for w in rows), max(w["link"] for w in rows)],
            dissipated=float(sum(w["dissipation"] for w in rows)),
            rows=rows))
    from skfem_rod.export import write_json
    summary["converged"] = all(r["converged"] for r in summary["runs"])
    write_json(os.path.join(out, "results.json"), summary)
    summary["renders"], summary["plots"] = [], []
    if render:
        summary["plots"].append(_plot(sols, os.path.join(out, "force_distance.png")))
        summary["renders"].append(_render(sols[-1], os.path.join(out, "knot_tight.png"),
                                          window_size))
    return summary


def _plot(sols, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.2, 4.4))
    colors = plt.cm.viridis(np.linspace(0, 0.85, len(sols)))
    for sol, col in zip(sols, colors):
        (du, Fu, _), (dd, Fd, _) = branches(sol["rows"])
        g = sol["gamma_T"]
        ax.plot(du, Fu, "-", color=col, label=rf"$\gamma_T = {g:g}$ tightening")
        ax.plot(dd, Fd, "--", color=col, label=rf"$\gamma_T = {g:g}$ loosening")
    ax.set_xlabel("end-to-end distance $d$")
    ax.set_ylabel("pulling force $F$ ($B = 1$)")
    ax.legend(fontsize=7, ncol=2)
    ax.set_title("overhand knot: tighten (solid) and loosen (dashed)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


def _render(sol, path, window_size=(900, 600)):
    import pyvista
    pyvista.OFF_SCREEN = True
    from skfem_rod.render import render_contact_states
    res = sol["result"]
    k = int(np.argmax([st.load_factor for st in res.steps]))
    f = res.sample(8, k)
    c = res.steps[k].contact
    pts = res.contact_points(k)
    states = (c.state_T if c is not None and c.friction else np.zeros(len(pts), int))
    render_contact_states(path, f["r"], f["R"], sol["eps"], pts, states,
                          window_size=window_size,
                          title=f"tight knot, gamma_T = {sol['gamma_T']:g}")
    return path
    return path


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="output/knot")
    p.add_argument("--gammas", type=float, nargs="+", default=[0.0, 0.1, 0.2, 0.3])
    p.add_argument("--pull", type=float, default=1.2)
    p.add_argument("--elements", type=int, default=80)
    p.add_argument("--steps", type=int, default=40)
    a = p.parse_args()
    main(a.out, tuple(a.gammas), a.pull, a.elements, a.steps)
