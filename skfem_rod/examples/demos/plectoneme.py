r"""A plectoneme to 10 turns: the node-barrier solve (``method="barrier"``)
=========================================================================

PyElastica's plectoneme: a rod of length ``L = 1`` and radius ``r =
0.025`` (``E = 1e6``, ``G = E / 1.5``), clamped at ``s = 0``; the end ``s =
L`` held on the axis, free to slide along it under a constant dead tension
``T = 10 EI / L^2``, and turned ``turns`` times about it.  A lateral dead
force of ``1e-2 T`` at mid-length breaks the symmetry.  Self-contact with
the contact radius ``r``, optionally with tangential Coulomb friction
``gamma_T`` between the plies.

Solved by ``rod.solve(n, method="barrier")``: every pair of centreline
nodes carries a smooth barrier energy on its distance, and each load step
is Newton on the total energy (rod + barrier + the end's tension), with
friction at the state's own normal forces (docs/contact-solve.md, "A
smooth barrier between nodes").  No multipliers, no active set, no
gradient flow.  Both ends carry handles (``handles=True``): the rod
continues beyond them as rigid straight rods along the axis, as the
surface and the bead of a magnetic-tweezers experiment hold a DNA
molecule.  Without them the plectoneme, lying across both ends at this
length and tension, swings around an end at 8-9 turns: no strand touches
another, and the link drops by 2 at each swing.

What to look for
----------------
* The straight twisted rod up to the Greenhill threshold (torque
  ``GJ 2 pi n / L``), its snap into a loop at about 1.25 turns, then the
  plectoneme: the end shortens at the hard-core plectoneme's rate per turn
  and the torque levels off at its plateau (Neukirch & Marko, PRL 106,
  138104 (2011); both drawn beside the results).
* Twist + writhe stays the turns applied (and the link of the closed-up
  curve their rounding), so no strand passed through another nor around
  an end; the true
  least distance of the centrelines (closest points of element pairs,
  both parameters free) stays at least ``2 r (1 - 1e-3)`` at every step.
* With friction, every pair's friction force is at most ``gamma_T`` times
  its normal force (Coulomb's law at the state), and the friction work of
  every step is positive.

Run ``python demos/plectoneme.py --help``.
"""
import argparse
import importlib.util
import os
import pathlib
import time

import numpy as np

from skfem_rod import Rod, Section, geometry

_here = pathlib.Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location("twisted_rod", _here / "twisted_rod.py")
tw = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(tw)

L, RADIUS, E = 1.0, 0.025, 1e6
G = E / 1.5
AREA, INERTIA = np.pi * RADIUS ** 2, np.pi * RADIUS ** 4 / 4
EI, GJ = E * INERTIA, G * 2 * INERTIA
TENSION = 10 * EI / L ** 2


def build(n_elements=100, gamma_T=0.0, turns=10.0, imperfection=1e-2):
    """The rod of the module doc, contact on (radius ``r``, ``gamma_T``)."""
    section = Section(EA=E * AREA, GA1=G * AREA, GA2=G * AREA, EI1=EI, EI2=EI, GJ=GJ,
                      radius=RADIUS)
    rod = Rod(geometry.straight(L), section, n_elements)
    rod.clamp("start")
    rod.pin("end", components=(1, 2))                 # on the axis, sliding along it
    rod.prescribe_rotation("end", [2 * np.pi * turns, 0.0, 0.0])
    rod.add_force("end", [TENSION, 0.0, 0.0], constant=True)
    s = rod.mesh.s_nodes
    mid = float(s[np.argmin(np.abs(s - L / 2))])
    rod.add_force(mid, [0.0, imperfection * TENSION, 0.0], constant=True)
    rod.enable_contact(radius=RADIUS, gamma_T=float(gamma_T))
    return rod


def theory():
    """The Greenhill threshold and the hard-core plectoneme's plateau
    torque and shortening per turn, in the scene's units."""
    lam = np.sqrt(EI / TENSION)
    scale = np.sqrt(EI * TENSION)
    m = tw.greenhill_factor(L / lam)
    th = tw.plectoneme_theory(RADIUS / lam)
    return dict(greenhill_torque=2 * scale * m,
                greenhill_turns=2 * scale * m * L / (GJ * 2 * np.pi),
                plateau_torque=th["torque"] * scale,
                shortening_per_turn=th["shortening_per_turn"] * lam)


def record(result, k, turns):
    """Figures of step ``k``: turns, end position and torque, node pairs in
    contact, true least distance over ``2 r``, link (twist + writhe),
    Coulomb's law (largest friction force over ``gamma_T`` times its
    normal force), friction work, Newton iterations."""
    st = result.steps[k]
    rod = result.rod
    end = rod.node("end")
    c = st.contact
    top = result.topology(k)
    coulomb, work = 0.0, 0.0
    if c.friction and c.s.size:
        coulomb = float(np.max(np.linalg.norm(c.force_T, axis=1)
                               / (rod.contact.gamma_T * c.force)))
        work = float(c.dissipation)
    return dict(step=k, turns=st.load_factor * turns, x_end=float(st.r[end, 0]),
                torque=float(result.reaction("end", k)[1][0]), pairs=int(c.s.size),
                # None: no two strands within reach of each other
                distance=(float(c.min_distance / (2 * RADIUS)) if np.isfinite(c.min_distance)
                          else None), link=float(top.link),
                twist_writhe=float(top.twist + top.writhe), coulomb=coulomb,
                friction_work=work, iterations=int(st.iterations))


def solve(n_elements=100, gamma_T=0.0, turns=10.0, steps_per_turn=16, log=None, **options):
    """Twist to ``turns`` in ``steps_per_turn`` steps per turn by
    ``rod.solve(method="barrier", handles=True)`` (``options``: more solve
    options);
    returns the result, the rod, the per-step records and the wall time."""
    rod = build(n_elements, gamma_T, turns)
    records = []

    def callback(result, k):
        records.append(record(result, k, turns))
        if log is not None:
            log(records[-1])

    options.setdefault("handles", True)
    t0 = time.perf_counter()
    result = rod.solve(int(round(turns * steps_per_turn)), method="barrier", callback=callback,
                       **options)
    return dict(result=result, rod=rod, records=records, converged=result.converged,
                message=result.message, wall_time_s=time.perf_counter() - t0)


def _plot(sol, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    th, recs = theory(), sol["records"]
    n = np.array([q["turns"] for q in recs])
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    ax[0].plot(n, [q["x_end"] for q in recs], "o-", ms=2.5, label="end position x(L)")
    first = next((q for q in recs if q["pairs"] > 0), None)
    if first is not None:
        nn = np.linspace(first["turns"], max(n.max(), first["turns"]), 50)
        ax[0].plot(nn, first["x_end"] - th["shortening_per_turn"] * (nn - first["turns"]),
                   "C2-.", lw=1, label="hard-core plectoneme: shortening per turn")
    ax[0].set_ylim(-0.1, 1.1)
    ax[1].plot(n, [q["torque"] for q in recs], "o-", ms=2.5, label="end torque $M_x$")
    nn = np.linspace(0, max(n.max(), 1.0), 50)
    ax[1].plot(nn, GJ * 2 * np.pi * nn / L, "k:", lw=1, label=r"straight: $GJ\,2\pi n/L$")
    ax[1].axhline(th["greenhill_torque"], color="C3", ls="--", lw=1, label="Greenhill, clamped")
    ax[1].axhline(th["plateau_torque"], color="C2", ls="-.", lw=1,
                  label="plectoneme plateau (Neukirch-Marko)")
    ax[1].set_ylim(0, 1.6 * max(max(q["torque"] for q in recs), th["plateau_torque"]))
    for a in ax:
        a.set_xlabel("turns n")
        a.legend(fontsize=7)
    rod = sol["rod"]
    fig.suptitle(f"plectoneme, {rod.mesh.n_elements} elements, gamma_T = "
                 f"{rod.contact.gamma_T:g}: rod.solve(method='barrier'), "
                 f"{sol['wall_time_s']:.0f} s")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


#: Quick settings (tests/test_demos.py): 40 elements, through the snap into a loop.
SMALL = dict(n_elements=40, turns=1.5, window_size=(480, 360))
#: Gallery run (docs/img/gallery).
GALLERY = dict(n_elements=100, turns=10.0, window_size=(720, 540))


def main(out="output/plectoneme", n_elements=100, gamma_T=0.0, turns=10.0, steps_per_turn=16,
         render=True, verbose=True, window_size=(900, 675), **options):
    os.makedirs(out, exist_ok=True)
    say = print if verbose else (lambda *a: None)

    def log(q):
        say(f"  {q['turns']:6.3f} turns: x(L) {q['x_end']:.4f}  M {q['torque']:8.4f}  "
            f"pairs {q['pairs']:4d}  d/2r {q['distance'] or np.inf:.5f}  Lk {q['link']:+.0f} "
            f"(Tw+Wr {q['twist_writhe']:+.3f})  its {q['iterations']}")

    sol = solve(n_elements, gamma_T, turns, steps_per_turn, log=log, **options)
    say(f"{sol['message']}; wall {sol['wall_time_s']:.1f} s")
    from skfem_rod.export import write_json
    write_json(os.path.join(out, "results.json"),
               dict(converged=sol["converged"], message=sol["message"],
                    wall_time_s=sol["wall_time_s"], theory=theory(), log=sol["result"].log,
                    records=sol["records"]))
    renders, plots = [], []
    if render and sol["records"]:
        plots.append(_plot(sol, os.path.join(out, "plectoneme_curves.png")))
        res, q = sol["result"], sol["records"][-1]
        path = os.path.join(out, "plectoneme.png")
        r = res.steps[-1].r
        lo, hi = r.min(axis=0), r.max(axis=0)
        c = 0.5 * (lo + hi)
        size = float(np.linalg.norm(hi - lo))
        cam = [tuple(c + 1.3 * size * np.array([0.25, -0.8, 0.5])), tuple(c), (0.0, 0.0, 1.0)]
        res.render(path, camera=cam, window_size=window_size, contact_radius=0.4 * RADIUS,
                   title=f"{q['turns']:.2f} turns, {q['pairs']} node pairs in contact "
                         f"(method='barrier')")
        renders.append(path)
    return dict(sol, renders=renders, plots=plots)


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="output/plectoneme")
    p.add_argument("--elements", type=int, default=100)
    p.add_argument("--gamma-T", type=float, default=0.0, help="Coulomb coefficient")
    p.add_argument("--turns", type=float, default=10.0)
    p.add_argument("--steps-per-turn", type=int, default=16)
    p.add_argument("--no-render", action="store_true")
    a = p.parse_args()
    main(a.out, a.elements, a.gamma_T, a.turns, a.steps_per_turn, render=not a.no_render)
