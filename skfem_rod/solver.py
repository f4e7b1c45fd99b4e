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
import scipy.sparse as sp
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
    snap : what to do when a load step fails: ``"cut"`` (default) halves
        the step until ``min_step``; ``"relax"`` first tries the gradient
        flow (proximal continuation, :mod:`skfem_rod.relax`) at the step's
        load factor, which crosses a snap (no nearby equilibrium) into the
        stable equilibrium on the other side, and cuts only if that fails.
    stability : compute the lowest eigenvalue of the symmetrized tangent at
        every converged step (``Step.lowest_eigenvalue``); with
        ``snap="relax"`` a step that converged to an unstable equilibrium is
        pushed off it along the unstable mode and relaxed.
    relax_tol : the gradient flow stops when the viscous force is below
        ``relax_tol`` times the force scale (then Newton polishes).
    relax_dt : first pseudo-time step of the flow (metric of
        :func:`skfem_rod.relax.metric`).
    max_flow_steps : accepted proximal steps per flow before giving up.
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
    snap: str = "cut"
    stability: bool = False
    relax_tol: float = 1e-8
    relax_dt: float = 1.0
    max_flow_steps: int = 20000

    def __post_init__(self):
        if self.snap not in ("cut", "relax"):
            raise ValueError(f"snap must be 'cut' or 'relax', got {self.snap!r}")
        if not isinstance(self.stability, bool):
            raise ValueError(f"stability must be true or false, got {self.stability!r}")
        for name in ("rtol", "increment_tol", "min_step", "max_rotation_step",
                     "max_spin_update", "max_growth", "relax_tol", "relax_dt"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {v!r}")
        for name in ("max_iterations", "max_backtracks", "max_flow_steps"):
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
        #: optional viscous term ``(c, W, (r_ref, R_ref))`` of a proximal
        #: step (:mod:`skfem_rod.relax`); None outside the gradient flow
        self.viscous = None
        self.friction = False
        #: dof basis of the supports (``Rod.support_basis``): residual,
        #: tangent and Newton updates live in it; None: the spatial axes
        self.T = rod.dof_basis()
        if self.contact is not None:
            from .contact.search import slave_points
            self.slaves = slave_points(rod.mesh, self.contact.n_slave)
            self.multipliers = np.zeros(self.slaves.s.size)
            self.pairs = None
            #: friction (gamma_T or gamma_R > 0 only): multipliers per slave
            #: and the last converged state the slips are measured from
            self.friction = self.contact.friction
            if self.friction:
                self.lam_T = np.zeros((self.slaves.s.size, 3))
                self.lam_R = np.zeros((self.slaves.s.size, 3))
                self.converged_state = (rod.r0.copy(), rod.R0.copy())

    def contact_terms(self, r, tangent, R=None):
        """Search and contact work at positions ``r`` (contact on only); with
        friction on, the friction work at ``(r, R)`` is added and its
        per-pair figures are kept in ``self.friction_output``."""
        from .contact.search import search
        from .contact.assembly import contact_work
        c = self.contact
        reach = 2 * c.radius + c.penalty * self.multipliers.max(initial=0.0) + c.margin
        t0 = time.perf_counter()
        pairs = search(self.mesh, r, self.slaves, reach, c.exclusion)
        t1 = time.perf_counter()
        energy, force, K, fN = contact_work(self.mesh, r, pairs, self.multipliers,
                                            c.penalty, c.radius, tangent)
        t2 = time.perf_counter()
        self.timers["contact_search"] += t1 - t0
        self.timers["contact_assembly"] += t2 - t1
        if self.friction:
            from .contact.friction_assembly import friction_work
            r_n, R_n = self.converged_state
            ff, Kf, out = friction_work(self.mesh, r, R, r_n, R_n, pairs, self.multipliers,
                                        c.penalty, c.radius, self.lam_T, self.lam_R,
                                        c.gamma_T, c.gamma_R, c.mu_T, c.mu_R, tangent)
            force = force + ff
            if tangent:
                K = K + Kf
            self.friction_output = out
            self.timers["friction_assembly"] += time.perf_counter() - t2
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
            pairs, ec, fc, Kc, fN = self.contact_terms(r, tangent, R)
            res = res + fc
            if tangent:
                K = (K + Kc).tocsc()
            iw.contact = (pairs, fN, ec)
            if self.friction:
                iw.friction = self.friction_output
        if self.viscous is not None:
            from .relax import viscous_terms
            fv, kv = viscous_terms(self.viscous, r, R)
            res = res + fv
            if tangent:
                K = (K + sp.diags(kv)).tocsc()
        if self.T is not None:              # to the supports' local bases
            T = self.T
            res, f_ext = T.T @ res, T.T @ f_ext
            if tangent:
                K = (T.T @ K @ T).tocsc()
        return res, K, f_ext, iw

    def save_multipliers(self):
        """Copy of the contact multipliers (normal, and friction when on);
        None without contact."""
        if self.contact is None:
            return None
        if self.friction:
            return self.multipliers.copy(), self.lam_T.copy(), self.lam_R.copy()
        return (self.multipliers.copy(),)

    def restore_multipliers(self, saved):
        """Undo the multiplier updates since :meth:`save_multipliers`."""
        if saved is None:
            return
        self.multipliers = saved[0].copy()
        if self.friction:
            self.lam_T, self.lam_R = saved[1].copy(), saved[2].copy()

    def to_spatial(self, dy):
        """A dof vector (update, mode, residual) from the supports' local
        bases to the spatial axes."""
        return dy if self.T is None else self.T @ dy

    def update(self, r, R, dy, alpha):
        """``y (+) alpha dy`` with ``dy`` in the system's dof basis."""
        return _update(r, R, self.to_spatial(dy), alpha)

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
        rot = sup.rotation_vector if sup.basis is None else sup.basis.T @ sup.rotation_vector
        d[6 * n + 3:6 * n + 6] = np.where(sup.rotation, dlam * rot, 0.0)
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
            r_t, R_t = system.update(r, R, dy, alpha)
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
    if opts.stability:
        info["lowest_eigenvalue"] = _lowest_mode(system, r, R, 0.0)[0]
    if system.friction:
        system.converged_state = (r.copy(), R.copy())
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
        flows = system.calls["flow_steps"]
        mult = system.save_multipliers()
        ok, r_new, R_new, info = _step(system, r, R, lam_new,
                                       _prescribed_increment(rod, lam_new - lam), opts)
        if opts.snap == "relax" or opts.stability:
            ok, r_new, R_new, info = _snap(system, r, R, lam, lam_new, ok, r_new, R_new,
                                           info, opts, result, mult)
            info["flow_steps"] = system.calls["flow_steps"] - flows
        if ok:
            t = t_new
            r, R = r_new, R_new
            if system.contact is not None and system.friction:
                system.converged_state = (r.copy(), R.copy())
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
    short = [k for k, st in enumerate(result.steps)
             if st.contact is not None and not st.contact.uzawa_converged]
    note = ""
    if short:
        note = (f"; warning: Uzawa did not reach its tolerance in {len(short)} step(s) "
                f"(first: step {short[0]}, penetration "
                f"{result.steps[short[0]].contact.penetration:.3e}; see Result.log)")
    result.finish(True, f"converged: {len(result.steps) - 1} steps to the end of the "
                  f"load path (load factor {lam_of(1.0):g})" + note)
    return result


def _lowest_mode(system, r, R, lam):
    """Lowest eigenvalue and mode of the symmetrized tangent on the free dofs
    (with the contact multipliers of the system) and the Morse index."""
    from .stability import free_tangent, symmetric_eigen
    Kf, _ = free_tangent(system, r, R, lam)
    w, V, _, negative = symmetric_eigen((0.5 * (Kf + Kf.T)).tocsc(), 1)
    mode = np.zeros(system.mesh.n_dofs)
    mode[system.free] = V[:, 0]
    return float(w[0]), mode, negative


def _snap(system, r, R, lam, lam_new, ok, r_new, R_new, info, opts, result, mult):
    """Options ``snap="relax"`` and ``stability``: after the Newton step
    ``lam -> lam_new``, relax (gradient flow, :mod:`skfem_rod.relax`) when it
    failed, when it moved strands by more than half their clearance (a
    possible passage of one strand through another, see
    :func:`skfem_rod.relax.clearance_ok`) or, with the stability check, when
    it converged to an unstable equilibrium (pushed off along the unstable
    mode first)."""
    from .relax import clearance_ok, flow
    relax = opts.snap == "relax"
    if ok and relax and not clearance_ok(system.rod, r, r_new):
        # Newton may jump a strand through another (the contact search only
        # sees the iterates): redo the step with the capped gradient flow
        ok, info = False, dict(info, reason="strands moved by more than half their "
                                            "clearance (possible passage)")
        system.restore_multipliers(mult)   # those of the rejected step are void
    if not ok and relax:
        result.log.append(f"step to lam={lam_new:.6g} failed ({info['reason']}): "
                          "relaxing (gradient flow)")
        ok, r_new, R_new, info = _step(system, r, R, lam_new,
                                       _prescribed_increment(system.rod, lam_new - lam),
                                       opts, inner=flow)
        info["relaxed"] = ok
    if ok and opts.stability:
        low, mode, negative = _lowest_mode(system, r_new, R_new, lam_new)
        if negative and relax:
            result.log.append(f"step to lam={lam_new:.6g}: unstable equilibrium (lowest "
                              f"eigenvalue {low:.3e}); relaxing along the unstable mode")
            m = mode.reshape(-1, 6)
            size = (0.5 * system.contact.radius if system.contact is not None
                    else 1e-3 * system.rod.length)
            # largest nodal move ``size``, largest nodal rotation 0.1 rad
            a = min(size / max(np.abs(m[:, :3]).max(), 1e-300),
                    0.1 / max(np.abs(m[:, 3:]).max(), 1e-300))
            r_p, R_p = system.update(r_new, R_new, mode, a)
            ok, r_new, R_new, info = _step(system, r_p, R_p, lam_new,
                                           np.zeros(system.mesh.n_dofs), opts,
                                           inner=lambda *a: flow(*a, descent=True))
            info["relaxed"] = ok
            if ok:
                low = _lowest_mode(system, r_new, R_new, lam_new)[0]
        if ok:
            info["lowest_eigenvalue"] = low
    return ok, r_new, R_new, info


def _step(system, r, R, lam, prescribed, opts, inner=None):
    """One load step: Newton (or ``inner``, e.g. the gradient flow of
    :func:`skfem_rod.relax.flow`), wrapped in Uzawa updates of the contact
    multipliers when contact is on (until the largest penetration, and the
    largest open gap where a force acts, are below ``tolerance * eps``, or
    ``max_uzawa`` updates were made)."""
    inner = newton if inner is None else inner
    c = system.contact
    if c is None:
        return inner(system, r, R, lam, prescribed, opts)
    from .contact.law import gap, uzawa_update
    saved = system.save_multipliers()
    newton_its, uzawa = 0, 0
    while True:
        ok, r, R, info = inner(system, r, R, lam, prescribed, opts)
        newton_its += info["iterations"]
        if not ok:
            system.restore_multipliers(saved)
            return ok, r, R, info
        prescribed = np.zeros_like(prescribed)
        pairs, fN, _ = info["iw"].contact
        d = gap(pairs.distance, c.radius)
        pen = float(d.max(initial=0.0))
        # complementarity too: no force where the gap is open beyond the
        # tolerance (a multiplier left over from a higher load pushes apart)
        opened = float(np.max(-d[fN > 0], initial=0.0))
        done = pen <= c.tolerance * c.radius and opened <= c.tolerance * c.radius
        if system.friction:
            moved, lam_T, lam_R = _friction_uzawa(system, info["iw"].friction)
            info["friction_moved"] = moved
            done = done and moved <= c.friction_tolerance
        if done or uzawa == c.max_uzawa:
            if not done:
                info["uzawa_note"] = (
                    f"Uzawa stopped after {uzawa} updates with penetration {pen:.3e} "
                    f"and open gap under force {opened:.3e} "
                    f"(tolerance {c.tolerance * c.radius:.3e})"
                    + (f" and friction multipliers moving by {info['friction_moved']:.3e} "
                       f"gamma f_N (tolerance {c.friction_tolerance:g})"
                       if system.friction else ""))
            info.update(uzawa=uzawa, newton_total=newton_its, penetration=pen,
                        uzawa_converged=done)
            return True, r, R, info
        lam_new = np.zeros_like(system.multipliers)
        lam_new[pairs.slave] = uzawa_update(d, system.multipliers[pairs.slave], c.penalty)
        system.multipliers = lam_new
        if system.friction:
            system.lam_T, system.lam_R = lam_T, lam_R
        uzawa += 1


def _friction_uzawa(system, out):
    """Friction multipliers after an Uzawa update, ``lambda <- f`` (the
    projected multiplier of :func:`skfem_rod.contact.friction.uzawa_update`,
    computed by the assembler at the converged iterate), and how far they
    moved relative to the Coulomb bound ``gamma f_N`` (largest over the
    points; 0 without active points)."""
    c = system.contact
    lam_T = np.zeros_like(system.lam_T)
    lam_R = np.zeros_like(system.lam_R)
    lam_T[out.slave] = out.force_T
    lam_R[out.slave] = out.force_R
    moved = 0.0
    for gamma, new, old in ((c.gamma_T, lam_T, system.lam_T), (c.gamma_R, lam_R, system.lam_R)):
        if gamma > 0 and out.fN.size:
            bound = gamma * out.fN.max()
            moved = max(moved, float(np.abs(new - old).max()) / bound)
    return moved, lam_T, lam_R
