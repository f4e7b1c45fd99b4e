"""Newton-Raphson with the consistent tangent, load stepping with automatic
step cutting, and a backtracking safeguard.

The loop, in plain sight::

    lam = 0
    while lam < 1:
        try the step lam -> lam + dlam:
            apply the prescribed increments of the supports (first iteration)
            Newton: assemble R(y), K(y); solve K dy = -R; y <- y (+) alpha dy
        converged: keep the step (and let dlam grow back)
        failed:    halve dlam; stop with the converged steps if dlam < min_step

``y (+) dy`` is the configuration update: ``r <- r + dr``,
``R <- exp(dw) R`` at every node (spatial spins, :mod:`skfem_rod.rotations`).
"""
import difflib
import time
from collections import defaultdict
from dataclasses import dataclass, fields

import numpy as np
import scipy.sparse.linalg as spla

from .assembly import internal_work, shape_operator
from .kinematics import ElementRotationError
from .loads import distributed_vector, point_loads
from .results import Result
from .rotations import expm


@dataclass
class SolverOptions:
    """Controls of :func:`solve`.

    rtol : converged when ``|R_free| <= rtol * max(|f_ext|, |reactions|)``,
        or when the last Newton update was below ``increment_tol``
        (positions in units of the rod length, spins in radians).  The
        residual of a stiff rod stagnates at a round-off floor that grows
        with the mesh (5e-7 at 1000 elements, 1.5e-5 at 10000 for EA/EI =
        1e4) while the Newton updates keep converging quadratically to
        1e-14, so the update, not the residual, tells convergence there.
    max_iterations : Newton iterations per step before the step is cut.
    line_search : safeguard the Newton update: scale it so that no nodal
        spin exceeds ``max_spin_update``, and halve it (at most
        ``max_backtracks`` times) while the trial state leaves an element
        chart, is not finite, or raises the residual norm more than
        ``max_growth`` times.  (A residual-norm or energy-slope merit test
        vetoes good Newton steps of stiff rods: one full step from a
        straight rod raises the residual 2000x through O(theta^2) axial
        strain, and the next step converges; see docs/theory.md.)
    min_step : smallest load-factor step before the solve gives up.
    max_rotation_step : largest prescribed end rotation per step (rad).
    grow : factor by which a cut step grows back after a success.
    """
    rtol: float = 1e-10
    increment_tol: float = 1e-11
    max_iterations: int = 25
    line_search: bool = True
    max_backtracks: int = 6
    max_spin_update: float = 0.5 * np.pi
    max_growth: float = 1e6
    min_step: float = 1e-6
    max_rotation_step: float = 0.5 * np.pi
    grow: float = 2.0

    def __post_init__(self):
        for name in ("rtol", "increment_tol", "min_step", "max_rotation_step",
                     "max_spin_update", "max_growth"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
        for name in ("max_iterations", "max_backtracks"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, np.integer)) and v >= 1):
                raise ValueError(f"{name} must be an integer >= 1, got {v!r}")
        if not isinstance(self.line_search, bool):
            raise ValueError(f"line_search must be true or false, got {self.line_search!r}")
        if not (np.isfinite(self.grow) and self.grow >= 1):
            raise ValueError(f"grow must be a number >= 1, got {self.grow!r}")


def make_options(kwargs):
    names = [f.name for f in fields(SolverOptions)]
    for k in kwargs:
        if k not in names:
            close = difflib.get_close_matches(k, names, n=1)
            hint = f"; did you mean {close[0]!r}?" if close else ""
            raise ValueError(f"unknown solver option {k!r}{hint} Allowed: {', '.join(names)}")
    return SolverOptions(**kwargs)


class _System:
    """Residual and tangent of a rod at a load factor (internal work from
    :mod:`skfem_rod.assembly`, loads from :mod:`skfem_rod.loads`)."""

    def __init__(self, rod):
        self.rod = rod
        self.mesh = rod.mesh
        self.Z = shape_operator(rod.mesh)
        self.f_dist = distributed_vector(rod.mesh, rod.distributed)
        self.fixed = rod.fixed_dofs()
        self.free = ~self.fixed
        #: accumulated wall time per phase (s) and call counts, for benchmarks
        self.timers = defaultdict(float)
        self.calls = defaultdict(int)
        self.contact = rod.contact
        if self.contact is not None:
            from .contact.search import slave_points
            self.slaves = slave_points(rod.mesh, self.contact.n_slave)
            self.multipliers = np.zeros(self.slaves.s.size)
            self.pairs = None

    def contact_terms(self, r, tangent):
        """Search and contact work at positions ``r`` (contact on only)."""
        from .contact.search import search
        from .contact.assembly import contact_work
        c = self.contact
        reach = 2 * c.radius + c.penalty * self.multipliers.max(initial=0.0) + c.margin
        t0 = time.perf_counter()
        pairs = search(self.mesh, r, self.slaves, reach, c.exclusion)
        t1 = time.perf_counter()
        energy, force, K, fN = contact_work(self.mesh, r, pairs, self.multipliers,
                                            c.penalty, c.radius, tangent)
        self.timers["contact_search"] += t1 - t0
        self.timers["contact_assembly"] += time.perf_counter() - t1
        return pairs, energy, force, K, fN

    def evaluate(self, r, R, lam, tangent=True):
        rod = self.rod
        t0 = time.perf_counter()
        iw = internal_work(self.mesh, r, R, rod.eps0, rod.C, tangent=tangent, Z=self.Z)
        self.timers["internal_assembly"] += time.perf_counter() - t0
        self.calls["evaluate"] += 1
        fp, Kp = point_loads(self.mesh, rod.point_loads, R, rod.R0, lam)
        f_ext = lam * self.f_dist + fp
        res = iw.force - f_ext
        K = iw.matrix
        if tangent and Kp is not None:
            K = (K + Kp).tocsc()
        if self.contact is not None:
            pairs, ec, fc, Kc, fN = self.contact_terms(r, tangent)
            res = res + fc
            if tangent:
                K = (K + Kc).tocsc()
            iw.contact = (pairs, fN, ec)
        return res, K, f_ext, iw

    def factor(self, K):
        """Factorize ``K`` on the free dofs (constrained rows/columns
        replaced by the identity, pattern unchanged); returns a solver."""
        K = K.tocsc(copy=True)
        cols = np.repeat(np.arange(K.shape[1]), np.diff(K.indptr))
        rows = K.indices
        fixed = self.fixed
        kill = fixed[rows] | fixed[cols]
        K.data[kill] = 0.0
        K.data[kill & (rows == cols)] = 1.0
        t0 = time.perf_counter()
        if self.contact is None:
            lu = spla.splu(K)
            solve = lambda rhs: lu.solve(np.where(fixed, 0.0, rhs))      # noqa: E731
        else:
            # contact couples distant stretches of the rod (turns of a coil,
            # the plies of a plectoneme): a reverse Cuthill-McKee band
            # ordering keeps the fill small where COLAMD does not (coil of
            # 1000 elements in contact: 0.5 s against 3.2 s per factorization)
            from scipy.sparse.csgraph import reverse_cuthill_mckee
            p = reverse_cuthill_mckee(K.tocsr(), symmetric_mode=True)
            lu = spla.splu(K[p][:, p].tocsc(), permc_spec="NATURAL")

            def solve(rhs):
                x = np.empty_like(rhs)
                x[p] = lu.solve(np.where(fixed, 0.0, rhs)[p])
                return x
        self.timers["factorization"] += time.perf_counter() - t0
        self.calls["factor"] += 1
        return solve


def _prescribed_increment(rod, dlam):
    d = np.zeros(rod.mesh.n_dofs)
    for n, sup in rod.supports.items():
        d[6 * n:6 * n + 3] = np.where(sup.position, dlam * sup.displacement, 0.0)
        d[6 * n + 3:6 * n + 6] = np.where(sup.rotation, dlam * sup.rotation_vector, 0.0)
    return d


def _update(r, R, dy, alpha):
    d = alpha * dy.reshape(-1, 6)
    return r + d[:, :3], expm(d[:, 3:]) @ R


def newton(system, r, R, lam, prescribed, opts):
    """Newton iterations at load factor ``lam`` from ``(r, R)``.

    Returns ``(converged, r, R, info)`` where ``info`` has the residual
    history, the iteration count, the reason of a failure and the last
    evaluation.
    """
    free, fixed = system.free, system.fixed
    remaining = prescribed.copy()
    history = []
    last_update = np.inf
    length = system.rod.length
    try:
        res, K, f_ext, iw = system.evaluate(r, R, lam)
    except ElementRotationError as err:
        return False, r, R, dict(history=history, iterations=0, reason=str(err))
    for it in range(opts.max_iterations + 1):
        rn = float(np.linalg.norm(res[free]))
        history.append(rn)
        scale = max(np.linalg.norm(f_ext), np.linalg.norm(res[fixed]), 1e-300)
        if not np.isfinite(rn):
            return False, r, R, dict(history=history, iterations=it,
                                     reason="non-finite residual")
        if (rn <= opts.rtol * scale or last_update <= opts.increment_tol) \
                and not np.any(remaining):
            return True, r, R, dict(history=history, iterations=it, res=res, iw=iw,
                                    f_ext=f_ext, reason="")
        if it == opts.max_iterations:
            break
        rhs = -res - K @ remaining
        try:
            solve_k = system.factor(K)
            dy = solve_k(rhs)
        except RuntimeError as err:          # singular factor
            return False, r, R, dict(history=history, iterations=it,
                                     reason=f"singular tangent ({err})")
        dy[fixed] = remaining[fixed]
        if not np.all(np.isfinite(dy)):
            return False, r, R, dict(history=history, iterations=it,
                                     reason="non-finite Newton update")
        alpha, accepted, why = 1.0, None, "residual grew too much"
        if opts.line_search:
            spin = np.abs(dy.reshape(-1, 6)[:, 3:]).max()
            alpha = min(1.0, opts.max_spin_update / max(spin, 1e-300))
        for _ in range(opts.max_backtracks + 1):
            r_t, R_t = _update(r, R, dy, alpha)
            try:
                out = system.evaluate(r_t, R_t, lam)
            except ElementRotationError as err:
                why = str(err)
                alpha *= 0.5
                continue
            res_t = out[0][free]
            if not np.all(np.isfinite(res_t)):
                why = "non-finite residual"
                alpha *= 0.5
                continue
            if (not opts.line_search or np.any(remaining)
                    or np.linalg.norm(res_t) <= opts.max_growth * max(rn, scale)):
                accepted = (r_t, R_t, out)
                break
            alpha *= 0.5
        if accepted is None:
            return False, r, R, dict(history=history, iterations=it + 1,
                                     reason=f"no admissible update after {opts.max_backtracks} "
                                            f"halvings: {why}")
        r, R, (res, K, f_ext, iw) = accepted
        upd = (alpha * dy).reshape(-1, 6)
        last_update = float(max(np.abs(upd[:, :3]).max() / length, np.abs(upd[:, 3:]).max()))
        remaining = remaining * (1.0 - alpha)
        remaining[np.abs(remaining) < 1e-300] = 0.0
    return False, r, R, dict(history=history, iterations=opts.max_iterations,
                             reason=f"no convergence in {opts.max_iterations} iterations "
                                    f"(residual {history[-1]:.3e})")


def _load_path(path):
    """Piecewise-linear load factor over pseudo-time ``t`` in [0, 1]: the
    values ``path`` are reached at equally spaced times (default 0 -> 1)."""
    p = np.asarray([0.0, 1.0] if path is None else path, dtype=float)
    if p.ndim != 1 or p.size < 2 or not np.all(np.isfinite(p)):
        raise ValueError(f"path must be a list of >= 2 finite load factors, got {path!r}")
    if p[0] != 0.0:
        raise ValueError(f"path must start at load factor 0 (the reference), got {p[0]!r}")
    if np.any(np.diff(p) == 0):
        raise ValueError(f"consecutive path values must differ, got {p.tolist()}")
    times = np.linspace(0.0, 1.0, p.size)
    return times, p


def solve(rod, n_steps=1, path=None, callback=None, **kwargs):
    """Step the rod along the load path; see :meth:`Rod.solve`.
    ``callback(result, k)`` is called after each converged step ``k``."""
    if not (isinstance(n_steps, (int, np.integer)) and n_steps >= 1):
        raise ValueError(f"n_steps must be an integer >= 1, got {n_steps!r}")
    times, values = _load_path(path)
    lam_of = lambda t: float(np.interp(t, times, values))         # noqa: E731
    opts = make_options(kwargs)
    rod.check_constraints()
    system = _System(rod)
    result = Result(rod)
    r, R = rod.r0.copy(), rod.R0.copy()
    ok, r, R, info = newton(system, r, R, 0.0, np.zeros(rod.mesh.n_dofs), opts)
    if not ok:
        result.finish(False, f"the unloaded reference is not in equilibrium: {info['reason']}")
        return result
    result.append(0.0, r, R, info, time=0.0)
    if callback is not None:
        callback(result, 0)
    # the largest prescribed rotation per step bounds the pseudo-time step
    rot = max([np.linalg.norm(s.rotation_vector) for s in rod.supports.values()] + [0.0])
    slope = np.abs(np.diff(values) / np.diff(times)).max()
    nominal = 1.0 / n_steps
    if rot > 0:
        nominal = min(nominal, opts.max_rotation_step / (rot * slope))
    t, dt, streak = 0.0, nominal, 0
    while t < 1.0 - 1e-14:
        nxt = times[times > t + 1e-14][0]            # do not step over a turning point
        step = min(dt, nxt - t)
        t_new = nxt if step == nxt - t else t + step
        lam, lam_new = lam_of(t), lam_of(t_new)
        ok, r_new, R_new, info = _step(system, r, R, lam_new,
                                       _prescribed_increment(rod, lam_new - lam), opts)
        if ok:
            t = t_new
            r, R = r_new, R_new
            result.append(lam_new, r, R, info, time=t)
            if callback is not None:
                callback(result, len(result.steps) - 1)
            if info.get("uzawa_note"):
                result.log.append(f"step to lam={lam_new:.6g}: {info['uzawa_note']}")
            streak += 1
            if streak >= 2:          # grow back only after two successes in a row
                dt = min(dt * opts.grow, nominal)
        else:
            streak = 0
            result.log.append(f"step to lam={lam_new:.6g} (t={t_new:.6g}) failed: "
                              f"{info['reason']}; cutting the step")
            dt = 0.5 * step
            if dt < opts.min_step:
                result.finish(False, f"stopped at load factor {lam:.6g} (pseudo-time "
                              f"{t:.6g}): the step to {lam_new:.6g} failed "
                              f"({info['reason']}) and the step size fell below "
                              f"min_step={opts.min_step:g}")
                return result
    result.finish(True, f"converged: {len(result.steps) - 1} steps to the end of the "
                  f"load path (load factor {lam_of(1.0):g})")
    return result


def _step(system, r, R, lam, prescribed, opts):
    """One load step: Newton, wrapped in Uzawa updates of the contact
    multipliers when contact is on (until the largest penetration is below
    ``tolerance * eps`` or ``max_uzawa`` updates were made)."""
    c = system.contact
    if c is None:
        return newton(system, r, R, lam, prescribed, opts)
    from .contact.law import gap, uzawa_update
    saved = system.multipliers.copy()
    newton_its, uzawa = 0, 0
    while True:
        ok, r, R, info = newton(system, r, R, lam, prescribed, opts)
        newton_its += info["iterations"]
        if not ok:
            system.multipliers = saved
            return ok, r, R, info
        prescribed = np.zeros_like(prescribed)
        pairs, fN, _ = info["iw"].contact
        d = gap(pairs.distance, c.radius)
        pen = float(d.max(initial=0.0))
        if pen <= c.tolerance * c.radius or uzawa == c.max_uzawa:
            if pen > c.tolerance * c.radius:
                info["uzawa_note"] = (f"Uzawa stopped after {uzawa} updates with penetration "
                                      f"{pen:.3e} > tolerance {c.tolerance * c.radius:.3e}")
            info.update(uzawa=uzawa, newton_total=newton_its, penetration=pen,
                        uzawa_converged=pen <= c.tolerance * c.radius)
            return True, r, R, info
        lam_new = np.zeros_like(system.multipliers)
        lam_new[pairs.slave] = uzawa_update(d, system.multipliers[pairs.slave], c.penalty)
        system.multipliers = lam_new
        uzawa += 1
