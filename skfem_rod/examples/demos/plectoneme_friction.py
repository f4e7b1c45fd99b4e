r"""Plectoneme twisted up and back, with and without friction: hysteresis
======================================================================

The twisted rod under tension of ``demos/twisted_rod.py`` (clamped at
``s = 0``; the other end held on the axis, free to slide along it, under a
constant dead tension ``T`` and turned by ``n`` turns) is twisted up to
``turns`` turns, through the snap into a loop and a plectoneme, and back to
zero, along the load path ``[0, 1, 0]``.  Once with frictionless contact,
once with tangential Coulomb friction ``gamma_T`` between the plies.

What to look for
----------------
* Without friction the torque-turns curve is the same up and down while the
  rod is in the plectoneme (statics without dissipation is path
  independent for a given branch); the loops that snap in on the way up and
  out on the way down do so at different turns (the bistable window of the
  subcritical Greenhill bifurcation: hysteresis of the snap itself).
* With friction the plies resist sliding: the torque is higher on the way
  up and lower on the way down at the same number of turns, and the friction
  work dissipated per step is positive (``Result.dissipated_energy``).
* At every converged step: link = twist + writhe equals the applied turns,
  Coulomb's law holds at every contact point, the penetration is below the
  Uzawa tolerance.

Run ``python demos/plectoneme_friction.py --help``.
"""
import argparse
import importlib.util
import os
import pathlib
import time

import numpy as np

_here = pathlib.Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location("twisted_rod", _here / "twisted_rod.py")
tw = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(tw)


def solve(gamma_T, length=5.0, n_elements=24, radius=0.1, turns=4.0, n_steps=40,
          log=None):
    """Twist up to ``turns`` and back in ``2 n_steps`` steps; returns the
    result and per-step records (turns, torque, shortening, contacts, link,
    dissipation, pseudo-time)."""
    rod = tw.build(length, n_elements, radius, turns, 0.01, 0.01)
    if gamma_T > 0:
        rod.contact.gamma_T = float(gamma_T)
    records = []

    def callback(result, k):
        rec = tw.record(result, k, turns)
        st = result.steps[k]
        c = st.contact
        rec.update(time=st.time, dissipation=c.dissipation if c.friction else 0.0)
        records.append(rec)
        if log is not None:
            log(rec)

    t0 = time.perf_counter()
    result = rod.solve(2 * n_steps, path=[0, 1, 0], snap="relax", stability=True,
                       callback=callback)
    return dict(rod=rod, result=result, records=records, gamma_T=gamma_T,
                wall_time_s=time.perf_counter() - t0)


def branches(records):
    """``(turns, torque)`` arrays of the way up and of the way down."""
    t = np.array([r["time"] for r in records])
    n = np.array([r["turns"] for r in records])
    m = np.array([r["torque"] for r in records])
    up, down = t <= 0.5 + 1e-12, t >= 0.5 - 1e-12
    return (n[up], m[up]), (n[down][::-1], m[down][::-1])


def hysteresis(records, at):
    """Torque up and down at ``at`` turns (linear interpolation)."""
    (nu, mu), (nd, md) = branches(records)
    return np.interp(at, nu, mu), np.interp(at, nd, md)


#: settings of the test suite and of the gallery (demos/gallery.py)
SMALL = dict(gammas=(0.3,), n_elements=16, turns=1.5, n_steps=6, window_size=(480, 360),
             gif_size=(240, 180))
#: (the full run, the defaults of main, takes about 23 min on a loaded 2-core
#: machine; the gallery's coarser run, 3 turns in 12 steps each way on 16
#: elements, shows the same snap, plectoneme and hysteresis in about 10 min)
GALLERY = dict(gammas=(0.0, 0.3), n_elements=16, turns=3.0, n_steps=12, window_size=(720, 540),
               gif_size=(480, 360))


def main(out="output/plectoneme_friction", gammas=(0.0, 0.3), length=5.0, n_elements=24,
         radius=0.1, turns=4.0, n_steps=40, render=True, verbose=True,
         window_size=(1024, 768), animate=True, gif_size=(480, 360)):
    """Solve each friction coefficient of ``gammas``, write ``results.json``,
    the torque-turns plot, a render of the plectoneme at the top of the
    path and (``animate=True``) an animated GIF of the last run's load path,
    up and back (contact points coloured by stick / slip)."""
    os.makedirs(out, exist_ok=True)
    sols = []
    for g in gammas:
        sols.append(solve(g, length, n_elements, radius, turns, n_steps,
                          _printer(g) if verbose else None))
    summary = dict(problem="plectoneme twisted up and back, with and without friction",
                   parameters=dict(length=length, n_elements=n_elements, radius=radius,
                                   turns=turns, n_steps=n_steps, gammas=list(gammas),
                                   B=tw.B, T=tw.T, GJ=tw.GJ),
                   converged=all(s["result"].converged for s in sols),
                   runs=[dict(gamma_T=s["gamma_T"], message=s["result"].message,
                              wall_time_s=s["wall_time_s"],
                              dissipated=float(s["result"].dissipated_energy()[-1]),
                              records=s["records"]) for s in sols])
    from skfem_rod.export import write_json
    write_json(os.path.join(out, "results.json"), summary)
    summary["renders"], summary["plots"] = [], []
    if render:
        summary["plots"].append(_plot(sols, os.path.join(out, "torque_turns.png")))
        s = sols[-1]
        res = s["result"]
        top = int(np.argmax([st.load_factor for st in res.steps]))
        png = os.path.join(out, "plectoneme_friction.png")
        res.render(png, step=top, window_size=window_size, camera=tw._camera(res.steps[top].r),
                   radius=0.6 * res.rod.contact.radius, reference=None,   # the rod shortens: no ghost
                   contact_radius=0.75 * res.rod.contact.radius,
                   title=f"plectoneme with friction γ_T = {s['gamma_T']:g}, {turns:g} turns")
        summary["renders"].append(png)
        if animate:
            summary["animations"] = [_animate(s, os.path.join(out, "plectoneme_friction.gif"),
                                              gif_size)]
    return summary


def _animate(sol, path, size):
    """GIF of the load path of one run: one frame per converged step, one
    camera for all frames, contact markers coloured by their (tangential)
    stick / slip state."""
    from skfem_rod.render import render_animation
    res = sol["result"]
    configs, points, states, titles = [], [], [], []
    for k in range(len(res.steps)):
        f = res.sample(6, k)
        configs.append((f["r"], f["R"]))
        points.append(res.contact_points(k))
        states.append(res.contact_states(k))
        titles.append(f"γ_T = {sol['gamma_T']:g}: {sol['records'][k]['turns']:.2f} turns")
    return render_animation(path, configs, res.rod.contact.radius, window_size=size,
                            titles=titles, contact_points=points, contact_states=states,
                            camera=(0.2, -1.0, 0.45), fps=6,
                            supports=[{"point": configs[0][0][0], "kind": "clamp"}])


def _printer(g):
    def log(r):
        print(f"gamma_T={g:g} t={r['time']:.3f} turns={r['turns']:.2f} "
              f"torque={r['torque']:+.4f} contacts={r['contacts']} "
              f"dissipation={r['dissipation']:.2e}", flush=True)
    return log


def _plot(sols, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for s, col in zip(sols, ("k", "C3", "C0", "C2")):
        (nu, mu), (nd, md) = branches(s["records"])
        g = s["gamma_T"]
        ax.plot(nu, mu, "-", color=col, marker="o", ms=2.5, label=rf"$\gamma_T={g:g}$ up")
        ax.plot(nd, md, "--", color=col, marker="s", ms=2.5, label=rf"$\gamma_T={g:g}$ down")
    ax.set_xlabel("turns n")
    ax.set_ylabel(r"end torque $M_x/\sqrt{BT}$")
    ax.legend(fontsize=8)
    ax.set_title("twisted up and back: friction hysteresis")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default="output/plectoneme_friction")
    p.add_argument("--gammas", type=float, nargs="+", default=[0.0, 0.3])
    p.add_argument("--elements", type=int, default=24)
    p.add_argument("--turns", type=float, default=4.0)
    p.add_argument("--steps", type=int, default=40, help="steps each way")
    a = p.parse_args()
    main(a.out, tuple(a.gammas), n_elements=a.elements, turns=a.turns, n_steps=a.steps)
