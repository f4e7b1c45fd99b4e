r"""Load steps by Newton on the total energy, with the smooth node barrier of
:mod:`skfem_rod.contact.barrier` for contact and its lagged Coulomb friction:
the experiment of issue 13 (docs/contact-solve.md, "A smooth barrier between
nodes"; ``benchmarks/bench_plectoneme_barrier.py``).  Not the paper's
augmented-Lagrangian contact, and not yet an option of ``Rod.solve``.

Where every load is dead (forces, no moments, no followers) and motions are
prescribed, an equilibrium is a stationary point of

    E(y) = U_rod(y) - f . (x - x_0) + sum over node pairs b(g_ij)  [+ D(y)]

(``D`` the friction's dissipation potential at lagged normal forces).
One step, in plain sight::

    predictor: the last step's increment again (secant), cut by the step
        bound; the rest of the prescribed motion applied
    frictionless: Newton on E to rtol
    friction:
        lag the friction at the step's start (pairs, normal forces, normals;
            each pair's contact point a material point of both sections)
        settle the lag's normal forces to live_tol (_settle):
            Newton on E + D to near_rtol (a globalization only: the live
            solve finishes); lag again at the state; Aitken's
            relaxation of the forces (barrier.Relaxation); until no force
            changes by more than live_tol times the largest
        repeat (at most max_lags):
            lag again at the state (new pairs slip from where they met)
            Newton with the friction at the state's own normal forces and
                normals (live: no energy; the exact non-symmetric tangent,
                a line search on the residual's norm; after LIVE_HALVINGS
                halvings the update is computed again with the tangent
                shifted by tau diag|K|, tau from LIVE_SHIFT_START times 10
                per retry, a tenth of it after an accepted step: pseudo-
                transient continuation; at most live_iterations)
            done when the state is an equilibrium with its own lag (the
                live Newton takes no iteration): Coulomb's law holds at
                the state's own normal forces
        if the live Newton fails: settle the lag to lag_tol instead (its
            solves to lag_rtol), solve to rtol at it and check it again
            (Coulomb to lag_tol)

    a solved step has converged if the strands' true least distance
        (crossing.min_distance: closest points of element pairs) is at
        least 2 radius (1 - penetration_tol): the barrier holds the nodes,
        and the centrelines can sag between them

Newton on E (the energy; with friction, E + D at the lag):
    converged when |G_free| <= rtol * force scale
    solve (K + sigma diag|K|) dy = -G, sigma the least shift (0, then
        1e-6 times 10^k) making the matrix positive definite (its inertia
        from a symmetric-mode LU's pivots); the next iteration starts from
        a tenth of it
    alpha: at most max_spin per node, at most `fraction` of the way to the
        first node-pair contact (continuous collision detection on the
        positions' straight paths)
    halve alpha until E falls by the Armijo fraction of the slope (below
        the energy's round-off: until the residual falls); after
        `halvings` halvings compute the update again with the shift raised
        a hundredfold, at most `retries` times
"""
import time
from dataclasses import dataclass, field
from typing import Optional

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .contact.barrier import (Barrier, FrictionLag, Relaxation, barrier_work, friction_lag,
                              friction_live, friction_work, lag_change, step_bound)
from .contact.crossing import min_distance
from .kinematics import ElementRotationError
from .problem import Problem

__all__ = ["EnergyOptions", "EnergySolve", "Path", "StepReport"]

#: the live Newton's line search halves at most this often before it
#: shortens the update by a shift instead (pseudo-transient continuation)
LIVE_HALVINGS = 6
#: the first shift of the live Newton's tangent (times diag|K|)
LIVE_SHIFT_START = 1e-4


@dataclass(frozen=True)
class EnergyOptions:
    """Options of :class:`EnergySolve` (names as in the module doc)."""
    rtol: float = 1e-8
    max_iterations: int = 3000
    armijo: float = 1e-4
    max_spin: float = 0.5
    fraction: float = 0.8
    shift_start: float = 1e-6
    halvings: int = 30
    retries: int = 6
    max_lags: int = 60
    lag_tol: float = 1e-3
    lag_rtol: float = 1e-5
    near_rtol: float = 0.1
    live_iterations: int = 80
    cuts: int = 3
    penetration_tol: float = 1e-3
    live_tol: float = 0.3

    def __post_init__(self):
        for name in ("rtol", "armijo", "max_spin", "fraction", "shift_start", "lag_tol",
                     "lag_rtol", "live_tol", "near_rtol", "penetration_tol"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"EnergyOptions {name} must be a finite number > 0, not {v!r}")
        if not self.fraction < 1 or not self.armijo < 1:
            raise ValueError("EnergyOptions fraction and armijo must be below 1")
        for name in ("max_iterations", "halvings", "retries", "max_lags", "live_iterations"):
            v = getattr(self, name)
            if not (isinstance(v, (int, np.integer)) and v >= 1):
                raise ValueError(f"EnergyOptions {name} must be an integer >= 1, not {v!r}")
        if not (isinstance(self.cuts, (int, np.integer)) and self.cuts >= 0):
            raise ValueError(f"EnergyOptions cuts must be an integer >= 0, not {self.cuts!r}")


@dataclass
class StepReport:
    """What one step took."""
    converged: bool
    iterations: int = 0           # Newton iterations taken (all lags)
    shifts: int = 0               # factorizations refused as not positive definite
    halvings: int = 0
    retries: int = 0
    lags: int = 0                 # friction lags solved
    fallbacks: int = 0            # live solves that failed (then solved on the energy)
    live: bool = False            # friction at the state's own normal forces (else the lag's)
    lag_change: float = 0.0       # the last lag's largest change of a normal force
    residual: float = np.inf
    active: int = 0               # node pairs inside the barrier's width
    min_gap: float = np.inf       # least node-pair gap (distance - D)
    reason: str = ""
    sigma: float = 0.0            # the shift the next step starts from
    history: list = field(default_factory=list)
    solves: list = field(default_factory=list)   # (live, residual norms) per Newton solve
    friction: Optional[FrictionLag] = None   # the lag the last solve held (friction on)
    evaluation: object = None     # the rod's Evaluation at the last iterate (no barrier)
    true_distance: float = np.nan  # the strands' true least distance at the solved state


@dataclass
class Path:
    """What :meth:`EnergySolve.path` reached."""
    states: list = field(default_factory=list)     # (load factor, r, R), converged
    reports: list = field(default_factory=list)    # StepReport per step tried
    stop: str = ""                                  # where and why it stopped; "" if done

    @property
    def converged(self):
        return not self.stop


class EnergySolve:
    """The rod ``rod`` (without contact of its own) with the node ``barrier``
    and, with ``mu > 0``, Coulomb friction at the node pairs (slip
    smoothing ``eps_v``, default 1e-3 of the radius ``radius``)."""

    def __init__(self, rod, barrier: Barrier, radius, mu=0.0, eps_v=None,
                 options: Optional[EnergyOptions] = None):
        if rod.contact is not None:
            raise ValueError("rod: the node barrier replaces the rod's own contact; build the "
                             "rod without enable_contact (rod.contact must be None)")
        for pl in rod.point_loads:
            if pl.follower or pl.kind != "force":
                raise ValueError(f"EnergySolve needs dead forces only (an energy): the point "
                                 f"load at node {pl.node} is a "
                                 f"{'follower ' if pl.follower else ''}{pl.kind}")
        for dl in rod.distributed:
            if dl.kind != "force":
                raise ValueError(f"EnergySolve needs dead forces only (an energy), not a "
                                 f"distributed {dl.kind}")
        if getattr(rod.mesh, "closed", False) and barrier.period is None:
            raise ValueError("barrier: a closed rod needs the barrier's period, "
                             "Barrier.for_nodes(..., period=rod length), or every pair "
                             "across the closure point touches")
        if not (np.isfinite(mu) and mu >= 0):
            raise ValueError(f"mu must be a finite number >= 0, not {mu!r}")
        self.rod, self.barrier, self.radius, self.mu = rod, barrier, float(radius), float(mu)
        self.eps_v = 1e-3 * self.radius if eps_v is None else float(eps_v)
        if not (np.isfinite(self.eps_v) and self.eps_v > 0):
            raise ValueError(f"eps_v must be a finite number > 0, not {eps_v!r}")
        self.options = options or EnergyOptions()
        P = Problem(rod)
        if P.T is not None:
            raise ValueError("EnergySolve needs supports along the spatial axes")
        self.P, self.free, self.s, self.x0 = P, P.free, rod.mesh.s_nodes, rod.r0.copy()

    # -- the energy ------------------------------------------------------
    def _parts(self, r, R, lam, lag, tangent, live=False):
        ev = self.P.evaluate(r, R, lam, tangent=tangent)
        bw = barrier_work(r, self.s, self.barrier, hessian=tangent, dofs=6)
        fw = None
        if lag is not None:
            fw = (friction_live(r, R, lag, self.barrier, self.mu, self.eps_v, tangent) if live
                  else friction_work(r, R, lag, self.mu, self.eps_v, tangent))
        f = ev.external.reshape(-1, 6)
        E = ev.internal.energy - float(np.sum(f[:, :3] * (r - self.x0))) + bw.energy
        G = ev.residual + np.pad(bw.gradient, ((0, 0), (0, 3))).ravel()
        if fw is not None:
            # live: no potential; E stays the rest's (infinite on contact)
            E, G = (E if live else E + fw.energy), G + fw.gradient.ravel()
        K = None
        if tangent:
            K = ev.tangent + bw.hessian + (fw.hessian if fw is not None else 0)
        return E, G, K, ev, bw

    def energy(self, r, R, lam, lag=None):
        """``(E, G)``: the total energy (with the friction potential of
        ``lag``) and its gradient over the dofs at ``(r, R)``, load factor
        ``lam``."""
        E, G, _, _, _ = self._parts(r, R, lam, lag, False)
        return E, G

    def residual(self, r, R, lam, lag=None):
        """The out-of-balance force over the dofs at ``(r, R)``, load
        factor ``lam``, with the friction of ``lag``'s pairs at the state's
        own normal forces and normals (:func:`friction_live`): zero on the
        free dofs at a converged frictional step."""
        return self._parts(r, R, lam, lag, False, live=True)[1]

    # -- one Newton solve at a fixed lag ---------------------------------
    def _direction(self, K, G, sigma, rep, live=False):
        """The Newton update ``dy`` on the free dofs and the shift used.
        ``live``: the tangent is not symmetric (live normal forces in the
        friction); solved by a pivoting LU, shifted by ``sigma diag|K|`` as
        given (no inertia to test)."""
        free, o = self.free, self.options
        Kf = K[free][:, free].tocsc()
        d = np.abs(Kf.diagonal())
        d[d == 0] = 1.0
        if live:
            A = Kf if sigma == 0 else (Kf + sp.diags(sigma * d)).tocsc()
            try:
                x = spla.splu(A, permc_spec="COLAMD").solve(-G[free])
            except RuntimeError:             # exactly singular
                raise np.linalg.LinAlgError("singular tangent") from None
            if not np.all(np.isfinite(x)):
                raise np.linalg.LinAlgError("non-finite Newton update")
            dy = np.zeros_like(G)
            dy[free] = x
            return dy, sigma
        while True:
            A = Kf if sigma == 0 else (Kf + sp.diags(sigma * d)).tocsc()
            try:
                lu = spla.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                               options=dict(SymmetricMode=True))
                x = lu.solve(-G[free])
                if np.array_equal(lu.perm_r, lu.perm_c):
                    definite = bool(np.all(lu.U.diagonal() > 0))
                else:                        # pivoted: descent is all one can tell
                    definite = float(G[free] @ x) < 0
            except RuntimeError:             # exactly singular
                definite = False
            if definite and np.all(np.isfinite(x)):
                dy = np.zeros_like(G)
                dy[free] = x
                return dy, sigma
            sigma = o.shift_start if sigma == 0 else 10 * sigma
            rep.shifts += 1
            if sigma > 1e12:
                raise np.linalg.LinAlgError("no positive definite shift below 1e12")

    def newton(self, r, R, lam, lag, sigma, rep, rtol=None, live=False):
        """Newton at the fixed ``lag`` to the relative residual ``rtol``
        (default the options'); returns ``(r, R, sigma)`` and fills ``rep``
        (``reason`` set on failure).

        On the energy (``live`` false): the shifted positive definite
        tangent, an Armijo line search on the energy.  With ``live``, the
        friction's normal forces are the state's (:func:`friction_live`,
        no energy): the exact non-symmetric tangent, an Armijo line search
        on the residual's norm, the tangent shifted where the line search
        fails (module doc), at most ``live_iterations``; this is the local
        solve of a step, from a state the energy solve brought near, and a
        failure is for the caller to recover from."""
        o = self.options
        rtol = o.rtol if rtol is None else rtol
        limit = rep.iterations + o.live_iterations if live else o.max_iterations
        start = len(rep.history)
        out = self._newton(r, R, lam, lag, sigma, rep, rtol, live, limit)
        rep.solves.append((live, rep.history[start:]))
        return out

    def _newton(self, r, R, lam, lag, sigma, rep, rtol, live, limit):
        o, P, free = self.options, self.P, self.free
        E = G = K = None
        retries, rn, trial = 0, np.inf, None
        tau = 0.0                   # live: the pseudo-time shift (0: Newton)
        while True:
            if G is None:
                # the accepted trial was evaluated with its tangent: reused
                E, G, K, ev, bw = trial or self._parts(r, R, lam, lag, True, live)
                rn = float(np.linalg.norm(G[free]))
                rep.residual, rep.active, rep.min_gap = rn, bw.active, bw.min_gap
                rep.evaluation = ev
                rep.history.append(rn)
                if not np.isfinite(rn):
                    rep.reason = "non-finite residual"
                    return r, R, sigma
                if rn <= rtol * P.force_scale(ev):
                    return r, R, sigma
                if rep.iterations >= limit:
                    rep.reason = (f"no convergence in {limit} iterations "
                                  f"(residual {rn:.3e})")
                    return r, R, sigma
            try:
                dy, used = self._direction(K, G, tau if live else sigma, rep, live)
            except np.linalg.LinAlgError as err:
                rep.reason = str(err)
                return r, R, sigma
            slope = float(G[free] @ dy[free])
            d6 = dy.reshape(-1, 6)
            alpha = min(1.0,
                        o.max_spin / max(float(np.linalg.norm(d6[:, 3:], axis=1).max()), 1e-300),
                        step_bound(r, d6[:, :3], self.s, self.barrier, o.fraction))
            for _ in range(LIVE_HALVINGS if live else o.halvings):
                try:
                    rt, Rt = P.update(r, R, dy, alpha)
                    # the full step is taken most often: its tangent with it
                    trial = self._parts(rt, Rt, lam, lag, alpha == 1.0, live)
                    Et, Gt = trial[:2]
                    if alpha != 1.0:
                        trial = None
                except ElementRotationError:
                    Et, trial = np.inf, None
                if live:
                    if np.isfinite(Et) and (float(np.linalg.norm(Gt[free])) ** 2
                                           <= (1 - 2 * o.armijo * alpha) * rn ** 2):
                        break
                elif np.isfinite(Et):
                    if Et <= E + o.armijo * alpha * slope:
                        break
                    if abs(slope) < 1e-11 * max(1.0, abs(E)) and \
                            np.linalg.norm(Gt[free]) < rn:
                        break                 # below the energy's round-off: the residual
                alpha *= 0.5
                rep.halvings += 1
            else:
                if retries == o.retries:
                    rep.reason = (f"no descent along the Newton update, shift {used:.3g} "
                                  f"(residual {rn:.3e})")
                    return r, R, sigma
                retries += 1
                rep.retries += 1
                trial = None
                if live:
                    tau = max(10 * tau, LIVE_SHIFT_START)
                else:
                    sigma = max(100 * used, 1e-3)
                continue
            if live:
                tau = tau / 10 if tau / 10 >= LIVE_SHIFT_START else 0.0
            else:
                sigma = used / 10 if used >= o.shift_start else 0.0
            r, R, G, retries = rt, Rt, None, 0
            trial = trial if trial is not None and np.isfinite(trial[0]) else None
            rep.iterations += 1

    # -- a load path -----------------------------------------------------
    def path(self, n_steps, lam_end=1.0, callback=None, budget=None):
        """From the rod's reference state (load factor 0) to ``lam_end`` in
        ``n_steps`` equal steps (:meth:`step`, each from the last with the
        secant predictor where the last step had the same size).  A step
        that fails is tried again in halves from the last equilibrium, at
        most ``options.cuts`` times halved; the path returns to the full
        step at the next full step's start.  ``callback(k, lam, r, R,
        report)`` after every converged step (``k`` counts them);
        ``budget``: wall seconds, checked before each step.  Returns
        :class:`Path`: the converged states, every step's report (failed
        tries too), and where and why it stopped (empty when it reached
        ``lam_end``)."""
        if not (isinstance(n_steps, (int, np.integer)) and n_steps >= 1):
            raise ValueError(f"n_steps must be an integer >= 1, not {n_steps!r}")
        if not np.isfinite(lam_end):
            raise ValueError(f"lam_end must be a finite number, not {lam_end!r}")
        r, R, lam = self.rod.r0.copy(), self.rod.R0.copy(), 0.0
        dlam, prev, last, sigma = lam_end / n_steps, None, None, 0.0
        out = Path(states=[(0.0, r, R)])
        t0 = time.perf_counter()
        full, depth = 0, 0                   # full steps done, halvings of this one
        while full < n_steps:
            if budget is not None and time.perf_counter() - t0 > budget:
                out.stop = f"the budget of {budget:g} s ran out at load factor {lam:.6g}"
                break
            target = (full + 1) * dlam
            d = dlam / 2 ** depth
            r1, R1, rep = self.step(r, R, lam, d, prev if last == d else None, sigma)
            out.reports.append(rep)
            if not rep.converged:
                if depth == self.options.cuts:
                    out.stop = (f"step to load factor {lam + d:.6g} (step {d:.3g}, "
                                f"halved {depth} times): {rep.reason}")
                    break
                depth += 1
                continue
            lam = lam + d
            if abs(lam - target) <= 1e-9 * abs(dlam):
                lam, full, depth = target, full + 1, 0
            prev, last, (r, R), sigma = (r, R), d, (r1, R1), rep.sigma
            out.states.append((lam, r, R))
            if callback is not None:
                callback(len(out.states) - 1, lam, r, R, rep)
        return out

    # -- one load step ---------------------------------------------------
    def step(self, r, R, lam, dlam, previous=None, sigma=0.0):
        """From the equilibrium ``(r, R)`` at load factor ``lam`` to
        ``lam + dlam`` (``previous``: the equilibrium before, for the secant
        predictor).  Returns ``(r, R, StepReport)``; on failure the state
        given back is where the solve stopped (not an equilibrium)."""
        P, o = self.P, self.options
        rep = StepReport(converged=False, sigma=sigma)
        p = P.prescribed(dlam)
        r1 = None
        if previous is not None:
            dy = P.increment(r, R, previous[0], previous[1])
            a = step_bound(r, dy.reshape(-1, 6)[:, :3], self.s, self.barrier, o.fraction)
            try:
                r1, R1 = P.update(r, R, dy, a)
                if a < 1:
                    r1, R1 = P.update(r1, R1, p, 1 - a)
            except ElementRotationError:              # after a snap: no secant
                r1 = None
        if r1 is None:
            r1, R1 = P.update(r, R, p)
        lam1 = lam + dlam
        if not self.mu:
            r1, R1, sigma = self.newton(r1, R1, lam1, None, sigma, rep)
            rep.lags = 1
            if rep.reason:
                return r1, R1, rep
            rep.sigma = sigma
            return r1, R1, self._checked(r1, rep)
        # friction: the lag's normal forces brought to a fixed point on the
        # energy (Aitken-relaxed) until they change by less than live_tol
        # of the largest; then Newton at the state's own (live) normal
        # forces, until the state is an equilibrium with its own lag
        lag = friction_lag(r, R, r, R, self.s, self.barrier)
        held = lag.pairs
        settled = self._settle(r, R, r1, R1, lam1, lag, held, Relaxation(r.shape[0]),
                               o.live_tol, o.near_rtol, sigma, rep)
        if settled is None:
            return r1, R1, rep
        r1, R1, lag, sigma = settled
        for _ in range(o.max_lags):
            # pairs, normals and contact points at the state
            lag = friction_lag(r1, R1, r, R, self.s, self.barrier, lag, held)
            before = rep.iterations
            # no pair in contact: no friction, the energy's own Newton (shifted
            # where not positive definite) finishes, not the live one
            r1, R1, sigma = self.newton(r1, R1, lam1, lag, sigma, rep,
                                        live=lag.pairs.shape[0] > 0)
            if rep.reason:
                break
            if rep.iterations == before:
                # an equilibrium with its own lag, normal forces its own
                rep.sigma, rep.friction, rep.lag_change, rep.live = sigma, lag, 0.0, True
                return r1, R1, self._checked(r1, rep)
        else:
            rep.reason = f"no equilibrium with its own lag in {o.max_lags} live solves"
        # the live solve failed: the lag settled to lag_tol instead, solved
        # to rtol there and checked again
        rep.fallbacks += 1
        rep.reason = ""
        # a fresh relaxation: the first one's last residual is of another state
        settled = self._settle(r, R, r1, R1, lam1, lag, held, Relaxation(r.shape[0]),
                               o.lag_tol, o.lag_rtol, sigma, rep, tight=True)
        if settled is None:
            return r1, R1, rep
        r1, R1, lag, sigma = settled
        rep.sigma, rep.friction = sigma, lag
        return r1, R1, self._checked(r1, rep)

    def _checked(self, r1, rep):
        """``rep`` of a solved step at the positions ``r1``, converged if
        the strands' true distance (closest points of element pairs, both
        parameters free) is at least ``2 radius (1 - penetration_tol)``."""
        md = min_distance(self.rod.mesh, r1, self.radius, self.barrier.exclusion)
        rep.true_distance = float(md.distance)
        pen = (2 * self.radius - rep.true_distance) / self.radius
        if pen > self.options.penetration_tol:
            rep.reason = (f"the strands overlap by {pen:.3g} of the radius between nodes "
                          f"(penetration_tol {self.options.penetration_tol:g})")
        else:
            rep.converged = True
        return rep

    def _settle(self, r, R, r1, R1, lam1, lag, held, relax, tol, rtol, sigma, rep,
                tight=False):
        """The lag's normal forces to a fixed point, from ``(r1, R1)`` in
        the step from ``(r, R)``: solve on the energy at the lag (to
        ``rtol``), lag again at the state, until no force changes by more
        than ``tol`` times the largest; ``tight``: then solved to rtol at
        the settled lag and checked again.  Returns ``(r1, R1, lag,
        sigma)``, or None with ``rep.reason`` set."""
        o = self.options
        final = False
        for _ in range(o.max_lags):
            r1, R1, sigma = self.newton(r1, R1, lam1, lag, sigma, rep,
                                        None if final else rtol)
            rep.lags += 1
            if rep.reason:
                return None
            new = friction_lag(r1, R1, r, R, self.s, self.barrier, lag, held)
            change = lag_change(lag, new, r1.shape[0])
            rep.lag_change = change
            if change <= tol * new.force.max(initial=0.0):
                if final or not tight:
                    return r1, R1, lag, sigma
                final, lag = True, new
                continue
            lag = relax(new, lag)
        rep.reason = f"the friction lag did not settle in {o.max_lags} solves"
        return None
