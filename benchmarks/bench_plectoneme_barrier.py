"""The plectoneme of ``bench_plectoneme.py`` by Newton on the total energy,
with the smooth node barrier of :mod:`skfem_rod.contact.barrier` in place
of the paper's augmented-Lagrangian contact: a design experiment of issue
13 (frictionless only; not yet a solve option of the library).

Usage::

    python benchmarks/bench_plectoneme_barrier.py                  # 100 and 200 elements
    python benchmarks/bench_plectoneme_barrier.py --elements 100 --budget 120 --out /tmp/pb

Same rod, supports, loads and twist as ``bench_plectoneme.py`` (dead
tension, lateral imperfection, the end turned 10 times), contact off in the
rod and the barrier added to its energy.  All loads are dead and the twist
is prescribed, so the equilibria are the stationary points of

    E(y) = U_rod(y) - f . (x - x_0) + sum over node pairs b(g_ij)

and each load step (1/16 turn) minimizes it by Newton:

* **predictor**: the last step's increment again (secant), cut by the step
  bound so that no node pair closes; the rest of the prescribed rotation
  applied at the end;
* **direction**: ``(K + sigma diag|K|) dy = -G`` on the free dofs, with
  ``sigma`` 0 where ``K`` is positive definite and else raised by 10 from
  1e-6 until it is (the inertia read off the pivots of a symmetric-mode LU
  without row pivoting); the next iteration starts from a tenth of the
  last shift;
* **step**: at most 0.5 rad of spin per node and at most 0.8 of the way to
  the first node-pair contact (:func:`~skfem_rod.contact.barrier.step_bound`),
  halved until the energy falls by the Armijo fraction 1e-4 of the slope
  (after 30 halvings the update is computed again with the shift raised a
  hundredfold, at most 6 times in a row);
  where the slope is below the energy's round-off (``|G . dy| < 1e-11
  |E|``) the residual norm decides instead;
* **converged**: the residual on the free dofs below ``rtol = 1e-8`` of
  the force scale (``Problem.force_scale``), as every Newton of the
  package.

Recorded per step: turns, end position and torque, active pairs, Newton
iterations, shifts, halvings, and the true penetration of the centrelines
(``skfem_rod.contact.crossing.min_distance``, closest points of element
pairs, both parameters free).  Results: ``<out>.json`` and ``<out>.png``
(extension and torque against turns beside the reference relations of
``bench_plectoneme.py``).
"""
import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import bench_plectoneme as bp  # noqa: E402

from skfem_rod.contact.barrier import Barrier, barrier_work, step_bound  # noqa: E402
from skfem_rod.contact.crossing import min_distance  # noqa: E402
from skfem_rod.kinematics import ElementRotationError  # noqa: E402
from skfem_rod.problem import Problem  # noqa: E402

ARMIJO = 1e-4
MAX_SPIN = 0.5
FRACTION = 0.8
SHIFT_START = 1e-6
#: halvings of one update before it is computed again with a larger shift
HALVINGS = 30
#: such recomputations in a row before the step fails
RETRIES = 6


class Scene:
    """The rod without its own contact, the barrier, the energy."""

    def __init__(self, n_elements, width=0.02, force=1.0):
        rod = bp.build(n_elements, 0.0)
        rod.contact = None
        self.rod, self.P = rod, Problem(rod)
        if self.P.T is not None:
            raise ValueError("the supports' dof basis is not the spatial axes")
        self.s = rod.mesh.s_nodes
        self.barrier = Barrier.for_nodes(self.s, bp.RADIUS, width=width, force=force)
        self.x0 = rod.r0.copy()
        self.free = self.P.free

    def energy(self, r, R, lam):
        ev = self.P.evaluate(r, R, lam, tangent=False)
        f = ev.external.reshape(-1, 6)
        bw = barrier_work(r, self.s, self.barrier, hessian=False)
        return ev.internal.energy - float(np.sum(f[:, :3] * (r - self.x0))) + bw.energy, ev, bw

    def gradient(self, ev, bw):
        return ev.residual + np.pad(bw.gradient, ((0, 0), (0, 3))).ravel()


def shifted_direction(K, G, free, sigma):
    """``dy`` from ``(K + sigma diag|K|) dy = -G`` (free dofs) with the
    least shift ``sigma`` (from the one given, times 10) that makes the
    matrix positive definite; returns ``(dy, sigma, shifts)``."""
    Kf = K[free][:, free].tocsc()
    d = np.abs(Kf.diagonal())
    d[d == 0] = 1.0
    shifts = 0
    while True:
        A = Kf if sigma == 0 else (Kf + sp.diags(sigma * d)).tocsc()
        try:
            lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options=dict(SymmetricMode=True))
            x = lu.solve(-G[free])
            if np.array_equal(lu.perm_r, lu.perm_c):
                definite = bool(np.all(lu.U.diagonal() > 0))
            else:                                  # pivoted: descent is all one can tell
                definite = float(G[free] @ x) < 0
        except RuntimeError:                       # exactly singular
            definite = False
        if definite and np.all(np.isfinite(x)):
            dy = np.zeros_like(G)
            dy[free] = x
            return dy, sigma, shifts
        sigma = SHIFT_START if sigma == 0 else 10 * sigma
        shifts += 1
        if sigma > 1e12:
            raise RuntimeError("no positive definite shift below 1e12")


def minimize(sc, r, R, lam, max_iterations, rtol=1e-8, sigma=0.0):
    """Newton on the energy at load factor ``lam`` from ``(r, R)``; returns
    ``(r, R, info)``, ``info["failed"]`` the reason where it stopped.  An
    update along which no step lowers the energy is computed again with
    the shift raised a hundredfold (at least to 1e-3), at most
    :data:`RETRIES` times in a row."""
    P, free = sc.P, sc.free
    info = dict(iterations=0, shifts=0, halvings=0, retries=0)
    ev, retries, rn = None, 0, np.inf
    while info["iterations"] <= max_iterations:
        if ev is None:
            ev = P.evaluate(r, R, lam)
            bw = barrier_work(r, sc.s, sc.barrier, dofs=6)
            G = sc.gradient(ev, bw)
            rn = float(np.linalg.norm(G[free]))
            info.update(residual=rn, active=bw.active, min_gap=bw.min_gap)
            if rn <= rtol * P.force_scale(ev):
                info["sigma"] = sigma
                return r, R, info
            if info["iterations"] == max_iterations:
                break
            E = ev.internal.energy + bw.energy \
                - float(np.sum(ev.external.reshape(-1, 6)[:, :3] * (r - sc.x0)))
            K = (ev.tangent + bw.hessian).tocsc()
        dy, used, k = shifted_direction(K, G, free, sigma)
        info["shifts"] += k
        slope = float(G[free] @ dy[free])
        d6 = dy.reshape(-1, 6)
        alpha = min(1.0, MAX_SPIN / max(float(np.linalg.norm(d6[:, 3:], axis=1).max()), 1e-300),
                    step_bound(r, d6[:, :3], sc.s, sc.barrier, FRACTION))
        for _ in range(HALVINGS):
            try:
                rt, Rt = P.update(r, R, dy, alpha)
                Et, evt, bwt = sc.energy(rt, Rt, lam)
            except ElementRotationError:
                Et = np.inf
            if np.isfinite(Et):
                if Et <= E + ARMIJO * alpha * slope:
                    break
                if abs(slope) < 1e-11 * max(1.0, abs(E)):
                    # the energy's change is below its round-off: the residual decides
                    if np.linalg.norm(sc.gradient(evt, bwt)[free]) < rn:
                        break
            alpha *= 0.5
            info["halvings"] += 1
        else:
            if retries == RETRIES:
                info["failed"] = (f"no descent along the Newton update, shift {used:.3g} "
                                  f"(residual {rn:.3e})")
                return r, R, info
            retries += 1
            info["retries"] += 1
            sigma = max(100 * used, 1e-3)
            continue
        sigma = used / 10 if used >= SHIFT_START else 0.0
        r, R, ev, retries = rt, Rt, None, 0
        info["iterations"] += 1
    info["failed"] = f"no convergence in {max_iterations} iterations (residual {rn:.3e})"
    return r, R, info


def run(n_elements, turns=bp.TURNS, step=1 / 16, budget=300.0, width=0.02, force=1.0,
        max_iterations=3000, verbose=True):
    """Twist the rod to ``turns`` in steps of ``step`` turns; returns a
    dict of figures and per-step records."""
    sc = Scene(n_elements, width, force)
    P, rod = sc.P, sc.rod
    end = rod.node("end")
    r, R, lam = rod.r0.copy(), rod.R0.copy(), 0.0
    n_steps = int(round(turns / step))
    dlam = step / bp.TURNS
    prev, recs, stop, sigma = None, [], "", 0.0
    t0 = time.perf_counter()
    for k in range(1, n_steps + 1):
        if time.perf_counter() - t0 > budget:
            stop = f"the budget of {budget:g} s ran out"
            break
        p = P.prescribed(dlam)
        r1 = None
        if prev is not None:                           # secant predictor
            dy = P.increment(r, R, prev[0], prev[1])
            a = step_bound(r, dy.reshape(-1, 6)[:, :3], sc.s, sc.barrier, FRACTION)
            try:
                r1, R1 = P.update(r, R, dy, a)
                if a < 1:
                    r1, R1 = P.update(r1, R1, p, 1 - a)
            except ElementRotationError:               # after a snap: no secant
                r1 = None
        if r1 is None:
            r1, R1 = P.update(r, R, p)
        r1, R1, info = minimize(sc, r1, R1, lam + dlam, max_iterations, sigma=sigma)
        if "failed" in info:
            stop = f"step {k} ({(lam + dlam) * bp.TURNS:.4g} turns): {info['failed']}"
            break
        prev, (r, R), lam, sigma = (r, R), (r1, R1), lam + dlam, info["sigma"]
        ev = P.evaluate(r, R, lam, tangent=False)
        reaction = (ev.residual + ev.external).reshape(-1, 6)[end]
        md = min_distance(rod.mesh, r, bp.RADIUS, sc.barrier.exclusion)
        rec = dict(turns=lam * bp.TURNS, x_end=float(r[end, 0]), torque=float(reaction[3]),
                   contacts=info["active"], iterations=info["iterations"],
                   shifts=info["shifts"], halvings=info["halvings"],
                   true_penetration=float((2 * bp.RADIUS - md.distance) / bp.RADIUS),
                   min_gap=float(info["min_gap"] / bp.RADIUS),
                   wall=time.perf_counter() - t0)
        recs.append(rec)
        if verbose:
            print(f"  {k:3d}: {rec['turns']:6.3f} turns  x_end={rec['x_end']:.4f}  "
                  f"M={rec['torque']:.4f}  pairs={rec['contacts']:4d}  "
                  f"its={rec['iterations']:3d} (shifts {rec['shifts']}, halvings "
                  f"{rec['halvings']})  penetration={rec['true_penetration']:+.2e} r  "
                  f"{rec['wall']:.1f} s", flush=True)
    its = np.array([q["iterations"] for q in recs])
    out = dict(n_elements=n_elements, gamma_T=0.0, turns=recs[-1]["turns"] if recs else 0.0,
               wall=time.perf_counter() - t0, stop=stop, records=recs,
               median_iterations=float(np.median(its)) if its.size else None,
               total_iterations=int(its.sum()),
               max_true_penetration=max((q["true_penetration"] for q in recs), default=None),
               width=width, force=force, step=step)
    if verbose:
        print(f"  -> {out['turns']:.3f} turns in {out['wall']:.1f} s, median "
              f"{out['median_iterations']} Newton iterations per step"
              + (f"; stopped: {stop}" if stop else ""), flush=True)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--elements", type=int, nargs="+", default=[100, 200])
    ap.add_argument("--turns", type=float, default=bp.TURNS)
    ap.add_argument("--step", type=float, default=1 / 16, help="turns per load step")
    ap.add_argument("--width", type=float, default=0.02, help="barrier width / radius")
    ap.add_argument("--force", type=float, default=1.0,
                    help="a node pair's force at half the width")
    ap.add_argument("--budget", type=float, default=300.0, help="wall-time budget per run (s)")
    ap.add_argument("--out", default=str(HERE / "plectoneme_barrier"))
    a = ap.parse_args(argv)
    runs = [run(n, a.turns, a.step, a.budget, a.width, a.force) for n in a.elements]
    out = Path(a.out)
    tmp = out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(dict(command=" ".join(["python"] + sys.argv), runs=runs),
                              indent=1))
    tmp.replace(out.with_suffix(".json"))
    bp.plot(runs, str(out.with_suffix(".png")),
            title="plectoneme (L = 1, r = 0.025, T = 10 EI/L$^2$): Newton on the energy "
                  "with a node barrier")
    print(f"wrote {out.with_suffix('.json')} and {out.with_suffix('.png')}")


if __name__ == "__main__":
    main()
