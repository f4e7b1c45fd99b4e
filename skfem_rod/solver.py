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
from .relax import clearance_ok
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
    predictor : start of each step's Newton iterations: ``"none"`` (default)
        the last converged state; ``"secant"`` the last converged state
        moved along the secant of the last two (scaled to the new load
        increment; supported dofs stay where the load path puts them).  On a
        smooth path the secant start saves most iterations and keeps Newton
        in the basin of the equilibrium it follows (a loose knot, whose
        loops swing freely, diverges from the plain start).
    clearance_cap : with contact on (default true), halve a Newton update
        (and the secant predictor) while it moves two non-neighbouring nodes
        relative to each other by more than half their clearance
        (:func:`skfem_rod.relax.clearance_ok`), so that no iterate can carry
        a strand through another.  Without it, the first update of a step
        that brings strands into contact (no contact stiffness in the
        tangent yet) can put one strand on the far side of another, and the
        solve converges there: a hairpin leg pressed by a large force ends
        up through the other leg (``tests/test_predictor_cap.py``).
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
    predictor: str = "none"
    clearance_cap: bool = True

    def __post_init__(self):
        if self.snap not in ("cut", "relax"):
            raise ValueError(f"snap must be 'cut' or 'relax', got {self.snap!r}")
        if self.predictor not in ("none", "secant"):
            raise ValueError(f"predictor must be 'none' or 'secant', got {self.predictor!r}")
        if not isinstance(self.clearance_cap, bool):
            raise ValueError(f"clearance_cap must be true or false, got {self.clearance_cap!r}")
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
            #: per-slave penalty factor of the adaptive Uzawa loop (``_step``):
            #: the normal compliance at slave ``i`` is ``penalty / scale[i]``
            self.penalty_scale = np.ones(self.slaves.s.size)
            #: the same for the friction compliances ``mu_T``, ``mu_R`` (one
            #: factor for all points)
            self.friction_scale = 1.0
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
        mu = c.penalty / self.penalty_scale              # per slave (adaptive Uzawa)
        reach = 2 * c.radius + (mu * self.multipliers).max(initial=0.0) + c.margin
        t0 = time.perf_counter()
        pairs = search(self.mesh, r, self.slaves, reach, c.exclusion)
        t1 = time.perf_counter()
        mu = mu[pairs.slave]
        energy, force, K, fN = contact_work(self.mesh, r, pairs, self.multipliers,
                                            mu, c.radius, tangent)
        t2 = time.perf_counter()
        self.timers["contact_search"] += t1 - t0
        self.timers["contact_assembly"] += t2 - t1
        if self.friction:
            from .contact.friction_assembly import friction_work
            r_n, R_n = self.converged_state
            ff, Kf, out = friction_work(self.mesh, r, R, r_n, R_n, pairs, self.multipliers,
                                        mu, c.radius, self.lam_T, self.lam_R,
                                        c.gamma_T, c.gamma_R, c.mu_T / self.friction_scale,
                                        c.mu_R / self.friction_scale, tangent,
                                        K_normal=K)       # Kf includes K
            force = force + ff
            if tangent:
                K = Kf
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
        """Copy of the contact multipliers (normal, and friction when on) and
        of the adaptive penalty factors (last item); None without contact."""
        if self.contact is None:
            return None
        scales = (self.penalty_scale.copy(), self.friction_scale)
        if self.friction:
            return self.multipliers.copy(), self.lam_T.copy(), self.lam_R.copy(), scales
        return self.multipliers.copy(), scales

    def restore_multipliers(self, saved):
        """Undo the multiplier (and penalty factor) updates since
        :meth:`save_multipliers`."""
        if saved is None:
            return
        self.multipliers = saved[0].copy()
        if self.friction:
            self.lam_T, self.lam_R = saved[1].copy(), saved[2].copy()
        self.penalty_scale, self.friction_scale = saved[-1][0].copy(), saved[-1][1]

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
        cap = opts.clearance_cap and system.contact is not None
        for _ in range(opts.max_backtracks + 1):
            r_t, R_t = system.update(r, R, dy, alpha)
            if cap and not clearance_ok(system.rod, r, r_t):
                why = "the update would carry a strand through another"
                alpha *= 0.5
                continue
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


def _start_state(rod, start):
    """Nodal ``(r, R)`` to start from: a :class:`Result` (its last step) or
    a pair of arrays; checked."""
    if isinstance(start, Result):
        if not start.steps:
            raise ValueError("start: the Result has no converged step")
        r, R = start.steps[-1].r, start.steps[-1].R
    else:
        try:
            r, R = start
        except (TypeError, ValueError):
            raise ValueError(f"start must be a Result or a pair (r, R) of nodal positions "
                             f"and rotations, got {type(start).__name__}") from None
    r, R = np.array(r, dtype=float), np.array(R, dtype=float)
    n = rod.r0.shape[0]
    if r.shape != (n, 3) or R.shape != (n, 3, 3):
        raise ValueError(f"start: r must have shape ({n}, 3) and R ({n}, 3, 3) for this rod, "
                         f"got {r.shape} and {R.shape}")
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(R))):
        raise ValueError("start: r and R must be finite")
    from .rotations import is_rotation
    if not np.all(is_rotation(R, tol=1e-8)):
        raise ValueError("start: R must hold rotation matrices (R^T R = I, det R = 1)")
    return r, R


def _carry_multipliers(system, contact):
    """Normal multipliers of a converged contact state (``lambda = f_N`` at
    its active slave points, matched by arclength), so that a solve started
    from it does not begin Uzawa again from zero."""
    if contact is None or contact.s.size == 0:
        return
    s = np.ravel(system.slaves.s)          # flat slave index = multiplier index
    j = np.minimum(np.searchsorted(s, contact.s), s.size - 1)
    if np.abs(s[j] - contact.s).max() > 1e-12 * system.rod.length:
        return                           # another mesh: start Uzawa from zero
    system.multipliers[j] = contact.force


def solve(rod, n_steps=1, path=None, callback=None, start=None, **kwargs):
    """Step the rod along the load path; see :meth:`Rod.solve`.
    ``callback(result, k)`` is called after each converged step ``k``;
    ``start`` (a Result or ``(r, R)``) replaces the reference as the state
    step 0 starts from (step 0 is then an equilibrium solve)."""
    if not (isinstance(n_steps, (int, np.integer)) and n_steps >= 1):
        raise ValueError(f"n_steps must be an integer >= 1, got {n_steps!r}")
    times, values = _load_path(path)
    lam_of = lambda t: float(np.interp(t, times, values))         # noqa: E731
    opts = make_options(kwargs)
    rod.check_constraints()
    system = _System(rod)
    result = Result(rod)
    if start is None:
        r0, R0 = rod.r0, rod.R0
    else:
        r0, R0 = _start_state(rod, start)
    r, R = r0.copy(), R0.copy()
    if system.friction:                  # slips of step 0 are measured from the start
        system.converged_state = (r0.copy(), R0.copy())
    if isinstance(start, Result) and system.contact is not None:
        _carry_multipliers(system, start.steps[-1].contact)
    zero = np.zeros(rod.mesh.n_dofs)
    stressed = getattr(rod, "natural", "reference") == "straight" or start is not None
    if stressed:            # a stressed start: an equilibrium solve, with Uzawa
        ok, r, R, info = _step(system, r, R, 0.0, zero, opts)
    else:                   # the stress-free reference: a check (no multipliers)
        ok, r, R, info = newton(system, r, R, 0.0, zero, opts)
    if not ok and stressed and opts.snap == "relax":
        from .relax import flow
        ok, r, R, info = _step(system, r0.copy(), R0.copy(), 0.0, zero, opts, inner=flow)
    if not ok:
        where = ("reference" if not stressed else
                 "initial shape" if start is None else "given start state")
        result.finish(False, f"no equilibrium at load factor 0 from the {where}: "
                             f"{info['reason']}")
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
    prev = None                  # (load factor, r, R) of the step before the last
    while t < 1.0 - 1e-14:
        nxt = times[times > t + 1e-14][0]            # do not step over a turning point
        step = min(dt, nxt - t)
        t_new = nxt if step == nxt - t else t + step
        lam, lam_new = lam_of(t), lam_of(t_new)
        flows = system.calls["flow_steps"]
        mult = system.save_multipliers()
        r_p, R_p = r, R
        if opts.predictor == "secant" and prev is not None and lam != prev[0]:
            r_p, R_p = _secant(system, r, R, prev, (lam_new - lam) / (lam - prev[0]), opts)
        ok, r_new, R_new, info = _step(system, r_p, R_p, lam_new,
                                       _prescribed_increment(rod, lam_new - lam), opts)
        if opts.snap == "relax" or opts.stability:
            ok, r_new, R_new, info = _snap(system, r, R, lam, lam_new, ok, r_new, R_new,
                                           info, opts, result, mult)
            info["flow_steps"] = system.calls["flow_steps"] - flows
        if ok:
            t = t_new
            prev = (lam, r, R)
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


def _secant(system, r, R, prev, ratio, opts):
    """Secant predictor: ``(r, R)`` moved by ``ratio`` times the increment
    from ``prev = (lam, r, R)`` to it, with supported dofs left alone (the
    prescribed increment moves them), spins capped at
    ``opts.max_spin_update`` and, with ``opts.clearance_cap``, halved until
    no strand can pass through another (up to ``opts.max_backtracks``
    halvings, else no prediction)."""
    from .rotations import logm
    _, r0, R0 = prev
    d = np.empty((r.shape[0], 6))
    d[:, :3] = r - r0
    d[:, 3:] = logm(R @ np.swapaxes(R0, 1, 2))
    d *= ratio
    dy = d.ravel()
    if system.T is not None:
        dy = system.T.T @ dy
    dy[system.fixed] = 0.0
    spin = np.abs(dy.reshape(-1, 6)[:, 3:]).max(initial=0.0)
    alpha = min(1.0, opts.max_spin_update / max(spin, 1e-300))
    for _ in range(opts.max_backtracks + 1):
        r_p, R_p = system.update(r, R, dy, alpha)
        if not (opts.clearance_cap and system.contact is not None) \
                or clearance_ok(system.rod, r, r_p):
            return r_p, R_p
        alpha *= 0.5
    return r, R


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
    largest open gap where a force acts, are below ``tolerance * eps``, and
    with friction the friction multipliers moved by less than
    ``friction_tolerance * gamma f_N``, or ``max_uzawa`` updates were made).

    The penalty adapts as in the method of multipliers (:func:`_adapt_penalty`):
    where a point's violation did not drop by a factor 4 over an update, its
    penalty stiffness grows by ``penalty_growth`` for the rest of the step
    (each step starts at the nominal penalty).  The converged answer is that
    of the fixed penalty to the tolerances; only the path to it changes.
    """
    inner = newton if inner is None else inner
    c = system.contact
    if c is None:
        return inner(system, r, R, lam, prescribed, opts)
    from .contact.law import gap, uzawa_update
    saved = system.save_multipliers()
    newton_its, uzawa = 0, 0
    last = np.full(system.multipliers.size, np.inf)     # violations of the last pass
    last_moved = np.inf
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
            scale = float(system.penalty_scale.max(initial=1.0))
            if not done:
                info["uzawa_note"] = (
                    f"Uzawa stopped after {uzawa} updates with penetration {pen:.3e} "
                    f"and open gap under force {opened:.3e} "
                    f"(tolerance {c.tolerance * c.radius:.3e})"
                    + (f" and friction multipliers moving by {info['friction_moved']:.3e} "
                       f"gamma f_N (tolerance {c.friction_tolerance:g})"
                       if system.friction else "")
                    + (f"; penalty raised up to {scale:.3g} times" if scale > 1 else ""))
            # back to the nominal penalty: at the converged multipliers the
            # state is an equilibrium for any penalty (to the tolerances), and
            # the stability check and the next step see the nominal tangent
            system.penalty_scale = np.ones_like(system.penalty_scale)
            system.friction_scale = 1.0
            info.update(uzawa=uzawa, newton_total=newton_its, penetration=pen,
                        uzawa_converged=done, penalty_scale=scale)
            return True, r, R, info
        mu = c.penalty / system.penalty_scale[pairs.slave]
        lam_new = np.zeros_like(system.multipliers)
        lam_new[pairs.slave] = uzawa_update(d, system.multipliers[pairs.slave], mu)
        if c.penalty_growth > 1:
            if system.friction:
                last_moved = _adapt_friction_penalty(system, fN, lam_new, moved, last_moved)
            last = _adapt_penalty(system, pairs, d, fN, lam_new, last)
        system.multipliers = lam_new
        if system.friction:
            system.lam_T, system.lam_R = lam_T, lam_R
        uzawa += 1


#: the adaptive penalty raises the penalty at a point whose violation did
#: not drop below this fraction of the last one (Bertsekas' 0.25)
PENALTY_DROP = 0.25


def _adapt_penalty(system, pairs, d, fN, lam_new, last):
    """The penalty update of the method of multipliers (Bertsekas,
    *Constrained Optimization and Lagrange Multiplier Methods*, 1982,
    sec. 2.2; Nocedal & Wright, *Numerical Optimization*, framework 17.3),
    per slave point, after the Uzawa update ``lambda -> lam_new``.

    Uzawa converges linearly, by the factor ``k / (k + 1/mu)`` per update
    where the structure's stiffness ``k`` against the point's gap is large
    compared with the penalty stiffness ``1/mu`` (a line contact whose force
    redistributes between neighbouring points: factors 0.97-0.99 measured
    in the plectoneme, docs/friction.md).  The violation of a point is
    ``|d|`` where it penetrates or carries a force across an open gap; a
    point still short of its tolerance -- ``|d| > tolerance eps``, or, with
    friction, a multiplier change above ``friction_tolerance max f_N`` (the
    friction bound ``gamma f_N`` moves with it) -- whose violation did not
    drop below :data:`PENALTY_DROP` times the last one gets its penalty
    stiffness multiplied by ``penalty_growth``, up to ``max_penalty_scale``
    times the nominal one.  Returns the violations (``inf`` where no
    contact), the ``last`` of the next call."""
    c = system.contact
    n = system.multipliers.size
    act = (d > 0) | (fN > 0)
    viol = np.full(n, np.inf)
    viol[pairs.slave[act]] = np.abs(d[act])
    short = np.isfinite(viol) & (viol > c.tolerance * c.radius)
    if system.friction and fN.size:
        short |= np.isfinite(viol) & (np.abs(lam_new - system.multipliers)
                                      > c.friction_tolerance * fN.max())
    grow = short & (viol > PENALTY_DROP * last)
    system.penalty_scale = np.where(
        grow, np.minimum(system.penalty_scale * c.penalty_growth, c.max_penalty_scale),
        system.penalty_scale)
    return viol


def _adapt_friction_penalty(system, fN, lam_new, moved, last):
    """The same rule for the friction compliances, with one factor for all
    points (the friction assembler takes scalar ``mu_T``, ``mu_R``): the
    friction stiffness grows by ``penalty_growth`` when the friction
    multipliers still move by more than ``friction_tolerance`` (relative to
    ``gamma max f_N``), their movement did not drop below
    :data:`PENALTY_DROP` times the last, and it is friction's own: more than
    twice what the change of the Coulomb bound ``gamma f_N`` explains (the
    normal multipliers' change relative to ``max f_N``; that part is left to
    the normal penalty).  Sticking points converge by the factor
    ``k / (k + 1/mu)`` per update, as the normal ones (0.998 measured in the
    rotational-friction scene with a soft normal penalty).  Returns the
    movement, the ``last`` of the next call."""
    c = system.contact
    normal = (float(np.abs(lam_new - system.multipliers).max(initial=0.0)) / fN.max()
              if fN.size else 0.0)
    if moved > c.friction_tolerance and moved > PENALTY_DROP * last and moved > 2 * normal:
        system.friction_scale = min(system.friction_scale * c.penalty_growth,
                                    c.max_penalty_scale)
    return moved


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
