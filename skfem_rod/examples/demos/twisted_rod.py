r"""Twisted rod under tension: Greenhill buckling, loop and plectoneme
==================================================================

A straight rod is clamped at ``s = 0``.  Its other end is held on the axis
(``y = z = 0``), free to slide along ``x`` under a constant dead tension
``T``, and its cross-section is turned about the axis by ``n`` turns.  The
rod first stays straight and twisted, then buckles (Greenhill), snaps into
a loop that closes on itself, and winds into a plectoneme whose two plies
press on each other (frictionless self-contact).

This demo shows how to (public API only):

* check the twist-buckling threshold against Greenhill's condition with
  :func:`skfem_rod.stability.critical_load`: the sign change of the lowest
  eigenvalue of the symmetrized tangent along the exact straight twisted
  branch;
* hold a load constant while a prescribed end rotation grows
  (``rod.add_force(..., constant=True)``: a preload, on in the reference
  state already);
* follow the equilibrium path through the snap-through at the buckling
  threshold with ``rod.solve(..., snap="relax", stability=True)``: a step
  that finds no nearby equilibrium is relaxed by a gradient flow
  (:mod:`skfem_rod.relax`) into the stable equilibrium on the other side,
  inside the usual Uzawa loop of the contact multipliers;
* check that the link ``Lk = Tw + Wr`` of the rod stays equal to the
  imposed number of turns (no strand passage; ``Result.topology``);
* record, per step, the end torque, the end shortening, the number of
  contact points, the largest penetration and the Newton / flow work;
* write a JSON summary, offscreen renders of the stages (straight,
  buckled, loop, plectoneme) and plots of torque and shortening against
  the number of turns.

Units: bending stiffness ``B = 1`` and tension ``T = 1``, so lengths are in
units of ``lambda = sqrt(B/T)`` and moments in units of ``sqrt(B T)``.

Equations
---------
Straight twisted rod (an exact equilibrium for every twist ``phi = 2 pi n``):

    M = GJ phi / L,        x_end = L (1 + T / EA).

Linearized about it, the lateral deflection ``w = y + i z`` obeys
``B w'''' - i M w''' - T w'' = 0`` (Greenhill).  Infinite rod: buckling at
``M_c = 2 sqrt(B T)``.  Clamped ends at distance ``L`` (``w = w' = 0`` at
both ends): with ``alpha = M / 2B`` and ``beta^2 = alpha^2 - T/B`` the
4 x 4 determinant vanishes when

    2 beta (cos(beta L) - cos(alpha L)) = (T/B) L sin(beta L)

(derived in docs/twisted_rod.md); its first root gives
``M_c(L) = 2 sqrt(B T) m(L/lambda)`` with ``m(50) = 1.00198``,
``m(10) = 1.0492``, ``m(5) = 1.2464``.

Under a dead tension the bifurcation is subcritical: past it there is no
nearby equilibrium and the rod snaps.  Plain load stepping stops there
(``Rod.solve`` reports the failed step); with ``snap="relax"`` the failed
step is solved by the proximal (backward-Euler gradient-flow) iteration of
:mod:`skfem_rod.relax`,

    y_{k+1} = argmin_y  E(y) + |y - y_k|_W^2 / (2 dt),

whose steps follow the steepest descent of the energy ``E`` and settle in
a stable equilibrium; ``dt`` adapts so that Newton converges and no node
moves by more than half the clearance between strands (no tunnelling).

Plectoneme (two plies in contact, superhelix radius ``R = a``, the contact
radius; ply angle ``theta`` to the axis; zero temperature, hard core: the
two-phase construction of Neukirch & Marko, PRL 106, 138104 (2011)):

    T = B sin^4(theta) (1 + 2 cos^2(theta)) / (2 R^2 cos(2 theta)),
    M_p = 2 B sin^3(theta) cos(theta) / (R cos(2 theta)),
    d(shortening)/d(turns) = 4 pi R / sin(2 theta).

Run ``python demos/twisted_rod.py --help``.
"""
import argparse
import os
import time

import numpy as np
from scipy.optimize import brentq

from skfem_rod import Rod, Section, geometry
from skfem_rod.analytic import greenhill_factor
from skfem_rod.rotations import expm
from skfem_rod.stability import critical_load

B = 1.0                 # bending stiffness
T = 1.0                 # end tension
GJ = 2.0 * B           # torsional stiffness: C/B = 2 as for DNA (C ~ 100 nm, A ~ 50 nm)
EA = 1e4                # axial and shear stiffness (nearly inextensible rod)


def section(radius):
    return Section(EA=EA, GA1=EA, GA2=EA, EI1=B, EI2=B, GJ=GJ, radius=radius)


# ---------------------------------------------------------------------------
# 1. Greenhill: the buckling threshold
# ---------------------------------------------------------------------------
def straight_rod(length, n_elements, radius=0.01, turns=1.0):
    """Clamp at the start; end on the axis, free along x, end rotation
    ``2 pi turns`` about x (at load factor 1); constant dead tension T
    (a preload: on at every load factor)."""
    rod = Rod(geometry.straight(length), section(radius), n_elements)
    rod.clamp("start")
    rod.pin("end", components=(1, 2))
    rod.prescribe_rotation("end", [2 * np.pi * turns, 0.0, 0.0])
    rod.add_force("end", [T, 0.0, 0.0], constant=True)
    return rod


def critical_twist(length=50.0, n_elements=64):
    """Twist at which the straight twisted rod loses stability.

    Along the straight branch ``r = (1 + T/EA) s e_x``,
    ``R = exp(phi s/L e_x) R0`` (exact for the P3 / objective
    interpolation), the lowest eigenvalue of the symmetrized tangent on the
    free dofs is bisected to zero (:func:`skfem_rod.stability.critical_load`;
    the load factor scales the end rotation, here one turn per unit).
    Returns the FE critical twist and moment next to Greenhill's
    infinite-rod and clamped finite-rod values.
    """
    rod = straight_rod(length, n_elements, turns=1.0)
    s = rod.mesh.s_nodes

    def state(lam):
        r = np.zeros((s.size, 3))
        r[:, 0] = (1 + T / EA) * s
        R = expm(np.outer(2 * np.pi * lam * s / length, [1.0, 0.0, 0.0])) @ rod.R0
        return r, R

    t0 = time.perf_counter()
    m = greenhill_factor(length)
    n_inf = 2 * np.sqrt(B * T) * length / GJ / (2 * np.pi)   # turns of M = 2 sqrt(BT)
    crit = critical_load(rod, state, 0.9 * n_inf, 1.1 * m * n_inf, tol=1e-10,
                         method="illinois")
    Mc = GJ * 2 * np.pi * crit.load_factor / length
    return dict(length=length, n_elements=n_elements,
                critical_turns=crit.load_factor, critical_moment=Mc,
                greenhill_infinite=2 * np.sqrt(B * T), greenhill_clamped=2 * np.sqrt(B * T) * m,
                error_vs_infinite=Mc / (2 * np.sqrt(B * T)) - 1,
                error_vs_clamped=Mc / (2 * np.sqrt(B * T) * m) - 1,
                evaluations=crit.evaluations, wall_time_s=time.perf_counter() - t0)


# ---------------------------------------------------------------------------
# 2. The plectoneme relations
# ---------------------------------------------------------------------------
def plectoneme_theory(radius):
    """Ply angle, torque and shortening per turn of a hard-core plectoneme of
    superhelix radius ``radius`` (zero temperature; module docstring)."""
    R = float(radius)

    def tension(th):
        return B * np.sin(th) ** 4 * (1 + 2 * np.cos(th) ** 2) / (2 * R * R * np.cos(2 * th)) - T

    th = brentq(tension, 1e-9, np.pi / 4 - 1e-12, xtol=1e-15)
    return dict(theta=th,
                torque=2 * B * np.sin(th) ** 3 * np.cos(th) / (R * np.cos(2 * th)),
                shortening_per_turn=4 * np.pi * R / np.sin(2 * th))


# ---------------------------------------------------------------------------
# 3. The experiment
# ---------------------------------------------------------------------------
def build(length, n_elements, radius, turns, imperfection, penalty_factor=0.01,
          crossing=False):
    """The rod: ``straight_rod`` with contact of radius ``radius`` and a
    small constant lateral dead force ``imperfection * T`` (along y) at
    mid-length.  The contact compliance is ``penalty_factor`` times the
    library default ``10 eps^4 / B`` (see docs/twisted_rod.md: Uzawa does
    not settle at crossing contacts with the default).  ``crossing``: point
    pairs at the closest points of crossing strands too
    (docs/crossing-contact.md): with elements several radii long the loop's
    crossing falls between slave points."""
    rod = straight_rod(length, n_elements, radius, turns)
    s = rod.mesh.s_nodes
    rod.add_force(float(s[np.argmin(np.abs(s - length / 2))]), [0.0, imperfection * T, 0.0],
                  constant=True)
    rod.enable_contact(radius=radius, penalty=penalty_factor * 10 * radius ** 4 / B,
                       tolerance=1e-3, max_uzawa=30, crossing=crossing)
    return rod


def record(result, k, turns):
    """Figures of step ``k``: turns, end torque and shortening, contact,
    topology (twist, writhe, link in turns), solver work."""
    st = result.steps[k]
    rod = result.rod
    _, moment = result.reaction("end", k)
    x0 = result.steps[0].r[rod.node("end"), 0]
    c = st.contact
    top = result.topology(k)
    tol = rod.contact.tolerance * rod.contact.radius
    return dict(step=k, turns=st.load_factor * turns, torque=float(moment[0]),
                shortening=float(x0 - st.r[rod.node("end"), 0]),
                contacts=int(c.s.size), penetration=float(c.penetration) / rod.contact.radius,
                min_force=float(c.force.min(initial=np.inf)) if c.s.size else 0.0,
                max_active_gap=float(np.abs(c.gap).max(initial=0.0)) / tol,
                contact_force=c.total_force, newton=int(c.newton_total), uzawa=int(c.uzawa),
                flow_steps=int(st.flow_steps),
                stability=(None if st.lowest_eigenvalue is None else float(st.lowest_eigenvalue)),
                energy=st.energy, twist=top.twist, writhe=top.writhe, link=top.link)


def solve(length=8.0, n_elements=48, radius=0.05, turns=6.0, n_steps=60,
          imperfection=0.01, penalty_factor=0.01, log=None, crossing=False, **options):
    """Twist the tensioned rod by ``turns`` turns in ``n_steps`` equal
    increments (``rod.solve(n_steps, snap="relax", stability=True)``;
    ``crossing``: see :func:`build`).

    Returns a dict with the result, the per-step figures (``records``) and
    the wall time."""
    rod = build(length, n_elements, radius, turns, imperfection, penalty_factor, crossing)
    records = []

    def callback(result, k):
        records.append(record(result, k, turns))
        if log is not None:
            log(records[-1])

    t0 = time.perf_counter()
    result = rod.solve(n_steps, snap="relax", stability=True, callback=callback,
                       **options)
    wall = time.perf_counter() - t0
    return dict(result=result, rod=rod, records=records,
                wall_time_s=wall, message=result.message, converged=result.converged,
                parameters=dict(length=length, n_elements=n_elements, radius=radius,
                                turns=turns, n_steps=n_steps, imperfection=imperfection,
                                B=B, T=T, GJ=GJ, EA=EA, penalty=rod.contact.penalty))


#: Smallest torque drop (relative to the torque before it) reported as a snap.
SNAP_DROP = 0.05


def analyse(records, length, radius, plateau_from=None):
    """Snap and plateau figures from the per-step records.

    The snap is the largest torque drop, if the torque drops at all (by more
    than ``SNAP_DROP`` of the torque before it); a path on which the torque
    only rises has no snap (``snapped`` False, the ``snap_*`` entries None).
    The plateau is taken over the steps at or after ``plateau_from`` turns
    (default: one turn after the snap): mean torque, its largest relative
    deviation, and the slope of the end shortening per turn (least
    squares)."""
    tq = np.array([r["torque"] for r in records])
    n = np.array([r["turns"] for r in records])
    sh = np.array([r["shortening"] for r in records])
    drop = np.diff(tq)
    jump = int(np.argmin(drop)) + 1 if drop.size else None   # the snap: torque drops
    if jump is not None and not drop[jump - 1] < -SNAP_DROP * abs(tq[jump - 1]):
        jump = None                                           # the torque only rises
    th = plectoneme_theory(radius)
    m = greenhill_factor(length)
    snap = (dict(snap_turns_before=None, snap_turns_after=None, torque_before_snap=None,
                 torque_after_snap=None, shortening_after_snap=None) if jump is None else
            dict(snap_turns_before=float(n[jump - 1]), snap_turns_after=float(n[jump]),
                 torque_before_snap=float(tq[jump - 1]), torque_after_snap=float(tq[jump]),
                 shortening_after_snap=float(sh[jump])))
    out = dict(snapped=jump is not None, **snap,
               greenhill_clamped_turns=2 * np.sqrt(B * T) * m * length / GJ / (2 * np.pi),
               greenhill_clamped_torque=2 * np.sqrt(B * T) * m,
               plectoneme_theta=th["theta"], plectoneme_torque=th["torque"],
               plectoneme_shortening_per_turn=th["shortening_per_turn"])
    if jump is None and plateau_from is None:
        return out
    start = n[jump] + 1.0 if plateau_from is None else plateau_from
    tail = n >= start - 1e-9
    if tail.sum() >= 3:
        out.update(plateau_from=float(start), plateau_steps=int(tail.sum()),
                   plateau_torque=float(tq[tail].mean()),
                   plateau_deviation=float(np.abs(tq[tail] / tq[tail].mean() - 1).max()),
                   plateau_shortening_per_turn=float(np.polyfit(n[tail], sh[tail], 1)[0]))
    return out


def stages(records):
    """Steps to render: straight (half-way to the snap), buckled (last step
    before the snap), loop (first step with contact), plectoneme (last);
    those that the run did not reach are left out."""
    tq = np.array([r["torque"] for r in records])
    drop = np.diff(tq)
    last = len(records) - 1
    jump = int(np.argmin(drop)) + 1 if drop.size else 0
    if drop.size and drop[jump - 1] < -SNAP_DROP * abs(tq[jump - 1]):
        out = [("straight", max(1, jump // 2)), ("buckled", jump - 1)]
    else:
        out = [("straight", last)]
    loop = next((k for k, r in enumerate(records) if r["contacts"] > 0), None)
    if loop is not None:
        out.append(("loop", loop))
        if loop < last:
            out.append(("plectoneme", last))
    return out


#: Quick settings (tests/test_demos.py): the straight branch only.
SMALL = dict(length=5.0, n_elements=12, radius=0.1, turns=0.6, n_steps=3, greenhill_length=10.0,
             greenhill_elements=16, window_size=(480, 360))
#: Gallery run (docs/img/gallery): the test size of tests/test_twisted_rod.py to 3.5 turns.
GALLERY = dict(length=10.0, n_elements=36, radius=0.1, turns=3.5, n_steps=35,
               greenhill_length=10.0, greenhill_elements=16, window_size=(720, 540))


def main(out="output/twisted_rod", length=16.0, n_elements=54, radius=0.1, turns=6.5,
         n_steps=65, imperfection=0.01, greenhill_length=50.0, greenhill_elements=64,
         render=True, verbose=True, window_size=(800, 600)):
    os.makedirs(out, exist_ok=True)
    say = print if verbose else (lambda *a: None)
    gh = critical_twist(greenhill_length, greenhill_elements)
    say(f"Greenhill, L = {greenhill_length:g} lambda, {greenhill_elements} elements: FE "
        f"M_c = {gh['critical_moment']:.6f} sqrt(BT) at {gh['critical_turns']:.4f} turns; "
        f"2 sqrt(BT) (infinite rod): {gh['error_vs_infinite']:+.2e}, "
        f"clamped finite rod: {gh['error_vs_clamped']:+.2e}")
    t0 = time.perf_counter()

    def log(rec):
        if verbose:
            say(f"  step {rec['step']:4d}: {rec['turns']:6.3f} turns  torque={rec['torque']:+.4f} "
                f"shortening={rec['shortening']:.4f}  contacts={rec['contacts']:3d} "
                f"flow steps={rec['flow_steps']:4d} newton={rec['newton']:4d} "
                f"uzawa={rec['uzawa']:2d}  Lk-n={rec['link'] - rec['turns']:+.1e} "
                f"({time.perf_counter() - t0:.0f} s)")

    sol = solve(length, n_elements, radius, turns, n_steps, imperfection, log=log)
    rec = sol["records"]
    ana = analyse(rec, length, radius)
    say(f"{sol['message']}; wall {sol['wall_time_s']:.1f} s")
    if ana["snapped"]:
        say(f"snap between {ana['snap_turns_before']:.3f} and {ana['snap_turns_after']:.3f} "
            f"turns (clamped Greenhill: {ana['greenhill_clamped_turns']:.3f}); torque "
            f"{ana['torque_before_snap']:.3f} -> {ana['torque_after_snap']:.3f} sqrt(BT)")
    else:
        say(f"no snap up to {rec[-1]['turns']:.3f} turns: the torque only rises (clamped "
            f"Greenhill: {ana['greenhill_clamped_turns']:.3f} turns)")
    if "plateau_torque" in ana:
        say(f"plateau from {ana['plateau_from']:.2f} turns ({ana['plateau_steps']} steps): "
            f"torque {ana['plateau_torque']:.4f} (max deviation {ana['plateau_deviation']:.1e}), "
            f"shortening {ana['plateau_shortening_per_turn']:.3f} per turn; hard-core "
            f"two-ply theory: {ana['plectoneme_torque']:.4f}, "
            f"{ana['plectoneme_shortening_per_turn']:.3f} per turn")
    summary = dict(problem="clamped rod under constant end tension twisted by n turns",
                   parameters=sol["parameters"], greenhill=gh, analysis=ana,
                   converged=sol["converged"], message=sol["message"],
                   wall_time_s=sol["wall_time_s"], records=rec)
    from skfem_rod.export import write_json
    write_json(os.path.join(out, "results.json"), summary)
    plot = _plot(rec, ana, length, os.path.join(out, "torque_shortening.png"))
    pngs = []
    if render:
        pngs = _render(sol, out, window_size)
    say(f"wrote {out}/results.json, {out}/torque_shortening.png" +
        "".join(f", {p}" for p in pngs))
    summary["renders"] = pngs
    summary["plots"] = [plot]
    return summary


def _plot(rec, ana, length, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    n = np.array([r["turns"] for r in rec])
    fig, ax = plt.subplots(1, 3 if "writhe" in rec[0] else 2, figsize=(14, 4.2))
    ax[0].plot(n, [r["torque"] for r in rec], "o-", ms=3, label="FE (end reaction)")
    nn = np.linspace(0, n.max(), 50)
    ax[0].plot(nn, GJ * 2 * np.pi * nn / length, "k:", lw=1, label=r"straight: $GJ\,2\pi n/L$")
    ax[0].axhline(ana["greenhill_clamped_torque"], color="C3", ls="--", lw=1,
                  label=f"Greenhill, clamped, L={length:g}")
    ax[0].axhline(ana["plectoneme_torque"], color="C2", ls="-.", lw=1,
                  label="plectoneme (hard core)")
    ax[0].set_xlabel("turns n")
    ax[0].set_ylabel(r"end torque $M_x / \sqrt{BT}$")
    ax[0].legend(fontsize=8)
    ax[1].plot(n, [r["shortening"] for r in rec], "o-", ms=3, label="FE")
    j = np.searchsorted(n, ana["snap_turns_after"]) if ana["snapped"] else n.size
    if j < n.size:
        s0 = rec[j]["shortening"]
        ax[1].plot(nn[nn >= n[j]], s0 + ana["plectoneme_shortening_per_turn"] * (nn[nn >= n[j]] - n[j]),
                   "C2-.", lw=1, label=r"slope $4\pi a/\sin 2\theta$")
    ax[1].set_xlabel("turns n")
    ax[1].set_ylabel(r"end shortening $/\lambda$")
    ax[1].legend(fontsize=8)
    if len(ax) > 2:
        ax[2].plot(n, [r["twist"] for r in rec], "o-", ms=3, label="Tw")
        ax[2].plot(n, [r["writhe"] for r in rec], "s-", ms=3, label="Wr")
        ax[2].plot(n, [r["link"] for r in rec], "k--", lw=1, label="Lk = Tw + Wr")
        ax[2].set_xlabel("turns n")
        ax[2].set_ylabel("turns")
        ax[2].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _camera(points=None, direction=(0.2, -1.0, 0.45)):
    """An oblique view direction (from the scene towards the camera; the
    render fits the view to the scene) that sees the rod's axis (x) from
    the side, so that neither tail hides behind a loop."""
    return tuple(direction)


def _render(sol, out, window_size=(800, 600)):
    res, rod = sol["result"], sol["rod"]
    radius = rod.contact.radius
    pngs = []
    for name, k in stages(sol["records"]):
        path = os.path.join(out, f"twisted_rod_{name}.png")
        rec = sol["records"][k]
        # tubes at 0.6 of the contact radius, so that the contact points
        # (on the centrelines) show between the plies
        res.render(path, step=k, radius=0.6 * radius, camera=_camera(res.steps[k].r),
                   window_size=window_size, contact_radius=0.75 * radius,
                   title=f"{name}: {rec['turns']:.2f} turns, torque {rec['torque']:.3f} √(BT), "
                         f"{rec['contacts']} contact points")
        pngs.append(path)
    return pngs


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="output/twisted_rod", help="output directory")
    p.add_argument("--length", type=float, default=16.0, help="rod length / lambda")
    p.add_argument("--elements", type=int, default=54, help="number of P3 elements")
    p.add_argument("--radius", type=float, default=0.1, help="contact radius / lambda")
    p.add_argument("--turns", type=float, default=6.5, help="end rotation in turns")
    p.add_argument("--steps", type=int, default=65, help="number of twist increments")
    p.add_argument("--imperfection", type=float, default=0.01,
                   help="lateral force at mid-length / T")
    p.add_argument("--no-render", action="store_true", help="skip the PNG renders")
    a = p.parse_args()
    main(a.out, a.length, a.elements, a.radius, a.turns, a.steps, a.imperfection,
         render=not a.no_render)
