r"""Path following: pseudo-arclength continuation in the load factor, with
stability along the path, critical points located by bisection and branch
switching.

The unknowns are the configuration ``y`` (positions ``r`` and rotations
``R``, updated multiplicatively ``R <- exp(dw) R``) and the load factor
``lam``.  Loads scale with ``lam`` (except preloads, ``constant=True``) and
so do the prescribed motions of the supports: a constrained dof is not an
unknown but the function ``lam * p`` of the load factor (``p`` the
prescribed displacement / rotation vector), so a change ``dlam`` moves it by
``dlam * p``.  On the free dofs, with ``q = d f_ext / d lam`` (exact: the
loads are affine in ``lam`` at fixed rotations),

    K_ff dy_f + (K_fc p_c - q_f) dlam = -G_f(y, lam).

The extra equation is the pseudo-arclength constraint (Keller): with the
unit tangent ``t = (t_y, t_lam)`` at the last converged point and the
increments ``(Dy, Dlam)`` accumulated since then,

    <t_y, Dy>_D + psi^2 t_lam Dlam = ds,

in the scaled inner product ``<u, v>_D = sum u_pos . v_pos / L^2 + u_spin .
v_spin`` (positions in rod lengths, spins in radians) and ``psi`` the weight
of the load factor (default: the size of the initial tangent ``|dy/dlam|_D``,
so load and displacement count equally at the start).  Eliminating ``dy``
with two back substitutions of one factorization of ``K_ff`` gives ``dlam``
(the bordered system), so limit points in load (``t_lam = 0``) and in
displacement pass without special treatment; the predictor is the tangent,
oriented along the previous one, and ``ds`` adapts to reach
``target_iterations`` Newton iterations per step.

Stability: at each converged point, the lowest eigenvalues of the
symmetrized tangent on the free dofs (:func:`skfem_rod.stability.lowest_eigenvalues`)
and the Morse index (number of negative ones).  Where the index changes
between two points, the critical point is located by bisection in
arclength (each trial a corrector solve from the earlier point) on the sign
of the eigenvalue that crosses, refined by regula falsi; it is a *limit
point* when ``t_lam`` changes sign there and a *bifurcation* otherwise.
:func:`switch_branch` starts a new path from a bifurcation along its
critical mode.  The eigenvalues decide stability only for conservative
loads (dead forces; see :mod:`skfem_rod.stability`), and not with contact
(the multipliers of the state are not part of the tangent's potential):
``stability=True`` with contact raises.
"""
from dataclasses import dataclass, field, fields
from typing import NamedTuple

import numpy as np

from .augmented import augmented_lagrangian
from .kinematics import ElementRotationError
from .newton import Border, Report, newton
from .options import Deadline, make_options
from .problem import Increment, Problem, State, spin_cap
from .results import Result
from .stability import modes
from .validation import count, positive


@dataclass
class CriticalPoint:
    """A limit or bifurcation point located on a path.

    Attributes
    ----------
    kind : ``"limit"`` (the load factor turns back) or ``"bifurcation"``.
    load_factor : load factor at the point.
    step : the point lies between ``steps[step]`` and ``steps[step + 1]``.
    arclength : path arclength at the point.
    r, R : the configuration at the (stable side of the) final bracket.
    mode_positions, mode_spins : (n_nodes, 3) critical mode (eigenvector of
        the eigenvalue that crosses zero), zero at constrained dofs.
    eigenvalue : that eigenvalue at ``r, R`` (near zero).
    bracket : ``(s_lo, s_hi)`` arclength bracket of the final bisection.
    tangent : (n_dofs + 1,) path tangent ``(t_y, t_lam)`` at the bracket start.
    """
    kind: str
    load_factor: float
    step: int
    arclength: float
    r: np.ndarray
    R: np.ndarray
    mode_positions: np.ndarray
    mode_spins: np.ndarray
    eigenvalue: float
    bracket: tuple
    tangent: np.ndarray = field(repr=False, default=None)
    load_scale: float = None


class PathResult(Result):
    """A :class:`~skfem_rod.results.Result` of :func:`follow`, with per step

    * ``arclengths``: path arclength (scaled norm, see the module doc);
    * ``eigenvalues``: ``(n_steps, k)`` lowest eigenvalues of the
      symmetrized tangent (``stability=True``), else empty;
    * ``index``: the Morse index (negative eigenvalues; 0 = stable), -1
      when not computed;
    * ``stable``: ``index == 0``;
    * ``critical``: the located :class:`CriticalPoint` s.

    :meth:`plot` draws the path, solid where stable, dashed where not.
    """

    def __init__(self, rod):
        super().__init__(rod)
        self._s, self._eig, self._index, self._tlam = [], [], [], []
        self.critical = []
        self.tangents = []
        self.load_scale = None

    @property
    def arclengths(self):
        return np.array(self._s)

    @property
    def eigenvalues(self):
        if not self._eig or self._eig[0] is None:
            return np.zeros((len(self.steps), 0))
        return np.array(self._eig)

    @property
    def index(self):
        return np.array(self._index, dtype=int)

    @property
    def stable(self):
        return self.index == 0

    def plot(self, quantity=None, ax=None, filename=None, xlabel="load factor",
             ylabel=None, marker_critical=True, **line_kw):
        """Plot ``quantity`` (per-step array or callable ``(result, k)``;
        default: the largest nodal displacement) against the load factor;
        see :func:`skfem_rod.stability.plot_path`."""
        from .stability import plot_path
        return plot_path(self, quantity=quantity, ax=ax, filename=filename, xlabel=xlabel,
                         ylabel=ylabel, marker_critical=marker_critical, **line_kw)


# ----------------------------------------------------------------------------
class Follower:
    """Pseudo-arclength corrector and path state of :func:`follow` on a
    :class:`~skfem_rod.problem.Problem`: the bordered Newton
    (:func:`skfem_rod.newton.newton` with a :class:`~skfem_rod.newton.Border`)
    inside the augmented-Lagrangian loop, as every other loop."""

    def __init__(self, rod, opts, load_scale):
        self.rod = rod
        self.opts = opts
        self.problem = Problem(rod)
        #: the wall clock of ``time_limit``, from the start of the path
        self.deadline = Deadline(opts.time_limit)
        # prescribed motion per unit load factor, on the constrained dofs only
        self.pfix = self.problem.prescribed(1.0)
        self.pfix[self.problem.free] = 0.0
        d = np.ones((rod.mesh.n_nodes, 6))
        d[:, :3] = 1.0 / rod.length
        self.D2 = (d ** 2).ravel()                # weights of the scaled inner product
        self.psi2 = None if load_scale is None else float(load_scale) ** 2

    def dot(self, u, v, ul, vl):
        return float(np.dot(self.D2 * u, v) + self.psi2 * ul * vl)

    def tangent(self, r, R, lam, K=None, orient=None):
        """Unit tangent ``(t_y, t_lam)`` at a converged point, oriented so
        that ``<t, orient> > 0`` (default: increasing load factor)."""
        p = self.problem
        if K is None:
            K = p.evaluate(r, R, lam).tangent
        solve = p.factor(K)
        v = solve(p.load_rate(R) - K @ self.pfix) + self.pfix       # dy / dlam
        if self.psi2 is None:
            nv = float(np.sqrt(np.dot(self.D2 * v, v)))
            self.psi2 = nv ** 2 if nv > 0 else 1.0
        nrm = np.sqrt(self.dot(v, v, 1.0, 1.0))
        ty, tl = v / nrm, 1.0 / nrm
        if orient is not None and self.dot(ty, orient[0], tl, orient[1]) < 0:
            ty, tl = -ty, -tl
        return ty, tl

    def correct(self, base, arc, pred):
        """Newton on ``G(y, lam) = 0`` and the :class:`Arclength` equation
        ``arc`` (``w`` already weighted) from the base point ``base`` (a
        :class:`~skfem_rod.problem.State`) moved by the predictor ``pred``
        (an :class:`~skfem_rod.problem.Increment`).  Returns ``(r, R, lam,
        report)``."""
        p = self.problem
        r, R, lam = base
        try:
            r1, R1 = p.update(r, R, pred.dy, 1.0)
        except ElementRotationError as err:
            return r, R, lam, Report(False, reason=str(err))
        border = Border(w=arc.w, wl=arc.wl, target=arc.target, Dy=pred.dy.copy(),
                        Dl=float(pred.dl), p=self.pfix)
        return newton(p, r1, R1, lam + pred.dl, self.opts, border=border)

    def step(self, base, arc, pred):
        """:meth:`correct` inside the augmented-Lagrangian loop (contact on):
        every pass re-solves from the base point with the last converged
        increment as its predictor.  A converged step is committed (the
        friction slips of the next step are measured from it)."""
        p = self.problem

        def solve_pass(previous):
            if previous is None:
                return self.correct(base, arc, pred)
            r1, R1, lam1 = previous
            return self.correct(base, arc, Increment(p.increment(r1, R1, base.r, base.R),
                                                     lam1 - base.lam))

        return augmented_lagrangian(p, solve_pass)

    def modes(self, r, R, lam, k):
        return modes(self.problem, r, R, lam, k)

    def corrector(self, p, h):
        """:meth:`step` along the tangent of the point ``p`` by arclength ``h``."""
        return self.step(State(p.r, p.R, p.lam), Arclength(self.D2 * p.ty, self.psi2 * p.tl, h),
                         Increment(h * p.ty, h * p.tl))

    def advance(self, p, ds, lam_stop):
        """One continuation step from the point ``p``: tangent predictor
        (spins bounded by ``max_rotation_step``), corrector, and, when the
        step crosses ``lam_stop``, a corrector placed on it (``Dlam``
        fixed).  Returns ``(h, new point or None, report, landed)``."""
        h = ds * spin_cap(ds * p.ty, self.opts.max_rotation_step)
        r1, R1, lam1, info = self.corrector(p, h)
        land = False
        if info.converged and lam_stop is not None and \
                (p.lam - lam_stop) * (lam1 - lam_stop) < 0:
            frac = (lam_stop - p.lam) / (lam1 - p.lam)
            r1, R1, lam1, info = self.step(State(p.r, p.R, p.lam),
                                           Arclength(np.zeros_like(p.ty), 1.0, lam_stop - p.lam),
                                           Increment(frac * h * p.ty, frac * h * p.tl))
            land = info.converged
            h = frac * h
        if not info.converged:
            return h, None, info, False
        ty1, tl1 = self.tangent(r1, R1, lam1, K=info.evaluation.tangent, orient=(p.ty, p.tl))
        return h, Point(r1, R1, lam1, ty1, tl1), info, land

    def record(self, result, p, info, s):
        """Append the converged point ``p`` at path arclength ``s`` (with its
        eigenvalues when ``stability``) and commit it."""
        self.problem.commit(p.r, p.R, info.evaluation)
        result.append(p.lam, p.r, p.R, info, time=s)
        result._s.append(s)
        result._tlam.append(p.tl)
        result.tangents.append((p.ty, p.tl))
        if self.stability:
            m = self.modes(p.r, p.R, p.lam, self.n_eigen)
            result._eig.append(m.values)
            result._index.append(m.negative)
            result._modes_last = m
        else:
            result._eig.append(None)
            result._index.append(-1)
        if self.callback is not None:
            self.callback(result, len(result.steps) - 1)


class Arclength(NamedTuple):
    """The corrector's extra equation ``<w, Dy> + wl Dlam = target``
    (``w`` already carries the metric)."""
    w: np.ndarray
    wl: float
    target: float


class Point(NamedTuple):
    """A converged point of the path with its unit tangent."""
    r: np.ndarray
    R: np.ndarray
    lam: float
    ty: np.ndarray
    tl: float


@dataclass(frozen=True)
class PathOptions:
    """The step control of :func:`follow` (validated on construction).

    ds : initial arclength step; None: the step of a load increment of
        ``load_step`` along the initial tangent.
    load_step : the initial load increment when ``ds`` is not given.
    max_steps : converged steps before stopping.
    target_iterations : Newton iterations per step aimed at by the step
        control ``ds <- ds * clip(sqrt(target / iterations), 0.5, 2)``;
        a failed step is halved.
    ds_max, ds_min : bounds of ``ds`` (None: ``20 ds``, ``1e-6 ds``).
    load_scale : the weight ``psi`` of the load factor in the arclength
        (None: the size of the initial tangent, see module doc).
    stability : compute the ``n_eigen`` lowest eigenvalues of the
        symmetrized tangent and the Morse index at every point.
    locate : with ``stability``, locate each change of the index by
        bisection (:class:`CriticalPoint`) to a relative arclength bracket
        of ``locate_tol``.
    """
    ds: float | None = None
    load_step: float = 0.1
    max_steps: int = 200
    target_iterations: int = 4
    ds_max: float | None = None
    ds_min: float | None = None
    load_scale: float | None = None
    stability: bool = False
    n_eigen: int = 3
    locate: bool = True
    locate_tol: float = 1e-6

    def __post_init__(self):
        for name in ("max_steps", "target_iterations", "n_eigen"):
            count(name, getattr(self, name), 1)
        for name in ("ds", "ds_max", "ds_min", "load_scale"):
            if getattr(self, name) is not None:
                positive(name, getattr(self, name))
        positive("load_step", self.load_step)
        positive("locate_tol", self.locate_tol)
        for name in ("stability", "locate"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be True or False, got {getattr(self, name)!r}")

    @classmethod
    def split(cls, options):
        """``(PathOptions, SolverOptions)`` from the keyword arguments of
        :func:`follow` (unknown names go to, and are checked by,
        :func:`skfem_rod.options.make_options`)."""
        names = {f.name for f in fields(cls)}
        mine = {k: v for k, v in options.items() if k in names}
        rest = {k: v for k, v in options.items() if k not in names}
        return cls(**mine), make_options(rest)

    def steps(self, tl):
        """``(ds, ds_min, ds_max)`` given the initial tangent's load
        component ``tl``."""
        ds = self.ds
        if ds is None:            # a load increment of load_step along the initial tangent
            ds = self.load_step / abs(tl) if abs(tl) > 1e-12 else self.load_step
        ds_max = 20.0 * ds if self.ds_max is None else self.ds_max
        ds_min = 1e-6 * ds if self.ds_min is None else self.ds_min
        return ds, ds_min, ds_max


def follow(rod, lam_stop=1.0, *, start=None, stop=None, callback=None, **options):
    r"""Follow the equilibrium path of ``rod`` in the load factor by
    pseudo-arclength continuation (module doc).

    Parameters
    ----------
    rod : Rod
    lam_stop : float
        The path ends where it reaches this load factor (the last point is
        placed on it exactly), or after ``max_steps``; ``None``: no load
        limit.
    start : ``(r, R, lam, t_y, t_lam)`` to start from a converged state and
        a tangent (see :func:`switch_branch`); default: the reference
        state at load factor 0 and its tangent toward increasing load.
    stop : callable ``(result) -> bool``, ends the path when true.
    callback : callable ``(result, k)`` after each converged point.
    **options : the step control, :class:`PathOptions` (``ds``,
        ``load_step``, ``max_steps``, ``target_iterations``, ``ds_max``,
        ``ds_min``, ``load_scale``, ``stability``, ``n_eigen``, ``locate``,
        ``locate_tol``), and :class:`skfem_rod.options.SolverOptions`.

    Returns
    -------
    PathResult
    """
    po, opts = PathOptions.split(options)
    if lam_stop is not None and not np.isfinite(lam_stop):
        raise ValueError(f"lam_stop must be a finite number or None, got {lam_stop!r}")
    if po.stability and rod.contact is not None:
        raise NotImplementedError(
            "stability along a path with self-contact is not supported: the eigenvalues "
            "of the tangent with the augmented-Lagrangian contact terms at fixed "
            "multipliers do not decide stability; follow the path with stability=False")
    if stop is not None and not callable(stop):
        raise ValueError("stop must be a callable (result) -> bool")
    rod.check_constraints()
    F = Follower(rod, opts, po.load_scale)
    F.stability, F.n_eigen, F.callback = po.stability, po.n_eigen, callback
    result = PathResult(rod)
    first = _first_point(F, start, lam_stop)
    if isinstance(first, str):
        result.finish(False, first)
        return result
    r, R, lam, ty, tl, info = first
    result.load_scale = float(np.sqrt(F.psi2))
    point = Point(r, R, lam, ty, tl)
    F.record(result, point, info, 0.0)
    _march(F, result, point, po, lam_stop, stop)
    return result


#: friction is path dependent: past a limit point the path goes on along
#: an unstable branch with the load turning back, a process that no quasi-
#: static loading performs (it snaps there), so its dissipation is not the
#: friction of any loading; load stepping with snap="relax" goes through.
_FRICTION_TURNS_BACK = (
    "stopped at the limit point near load factor {lam:.6g}: with friction the "
    "continuation does not follow the path back along the unstable branch (friction "
    "dissipation depends on the process, and the loading snaps here); use load stepping "
    "(method='load', snap='relax') to go through the snap")


def _march(F, result, point, po, lam_stop, stop):
    """The continuation loop of :func:`follow` from the recorded ``point``:
    advance, halve ``ds`` on a failure, record, locate index changes, adapt
    ``ds``; ends ``result`` with its message."""
    ds, ds_min, ds_max = po.steps(point.tl)
    s_path, k = 0.0, 0
    while k < po.max_steps:
        if F.deadline.passed():
            result.finish(False, f"stopped at load factor {point.lam:.6g} after {k} steps: "
                                 f"{F.deadline.reason()}")
            return
        h, new, info, land = F.advance(point, ds, lam_stop)
        if not info.converged:
            ds = 0.5 * h
            result.log.append(f"step from lam={point.lam:.6g} (ds={h:.3g}) failed: "
                              f"{info.reason}; halving ds")
            if ds < ds_min:
                result.finish(False, f"stopped at load factor {point.lam:.6g}: step failed "
                                     f"({info.reason}) and ds fell below ds_min={ds_min:g}")
                return
            continue
        if F.problem.friction and new.tl * point.tl < 0:
            result.finish(False, _FRICTION_TURNS_BACK.format(lam=point.lam))
            return
        s_path += h
        k += 1
        F.record(result, new, info, s_path)
        if po.stability and po.locate and result._index[-1] != result._index[-2]:
            cp = _locate(F, result, point, h, po.locate_tol)
            if cp is not None:
                result.critical.append(cp)
        point = new
        its = max(info.iterations, 1)
        ds = float(np.clip(h * np.clip(np.sqrt(po.target_iterations / its), 0.5, 2.0),
                           ds_min, ds_max))
        if land:
            result.finish(True, f"reached load factor {lam_stop:g} after {k} steps "
                                f"(arclength {s_path:.4g})")
            return
        if stop is not None and stop(result):
            result.finish(True, f"stopped by the stop condition after {k} steps at load "
                                f"factor {point.lam:.6g}")
            return
    result.finish(lam_stop is None, f"{po.max_steps} steps done at load factor "
                                    f"{point.lam:.6g} (arclength {s_path:.4g})")


def _first_point(F, start, lam_stop):
    """The path's first point and tangent: the reference at load factor 0
    (an equilibrium check, contact solved in full) with the tangent toward
    ``lam_stop``, or ``start = (r, R, lam, t_y, t_lam)``.  Returns ``(r, R,
    lam, t_y, t_lam, report)`` or the message of a failure."""
    p, rod = F.problem, F.rod
    if start is None:
        zero = np.zeros(rod.mesh.n_dofs)
        r, R, _, rep = augmented_lagrangian(
            p, lambda prev: newton(p, *(prev[:2] if prev else (rod.r0.copy(), rod.R0.copy())),
                                   0.0, F.opts, prescribed=zero))
        if not rep.converged:
            return f"the unloaded reference is not in equilibrium: {rep.reason}"
        ty, tl = F.tangent(r, R, 0.0)
        if lam_stop is not None and lam_stop < 0:
            ty, tl = -ty, -tl
        return r, R, 0.0, ty, tl, rep
    r, R, lam, ty, tl = start
    r, R, lam = np.asarray(r, float).copy(), np.asarray(R, float).copy(), float(lam)
    ty, tl = np.asarray(ty, float), float(tl)
    if F.psi2 is None:
        F.tangent(r, R, lam)             # sets psi from the local load tangent
    nrm = np.sqrt(F.dot(ty, ty, tl, tl))
    return r, R, lam, ty / nrm, tl / nrm, Report(True, evaluation=p.evaluate(r, R, lam))


def _locate(F, result, p, h, tol):
    """Bisection in arclength for the change of the Morse index between the
    last two points of ``result`` (``p`` the earlier one, ``h`` the step);
    regula falsi on the crossing eigenvalue for the final estimate."""
    n_eigen = F.n_eigen
    ia, ib = result._index[-2], result._index[-1]
    j = min(ia, ib)                   # the eigenvalue that crosses zero
    if j >= n_eigen:
        j = None                      # not among the computed: bisection on the index only
        fa = fb = 0.0
    else:
        fa, fb = result._eig[-2][j], result._eig[-1][j]
    fa0 = fa
    lo, hi = 0.0, h
    state_lo = (p.r, p.R, p.lam)
    n_eval = 0
    while hi - lo > tol * max(h, 1e-300) and n_eval < 60:
        mid = 0.5 * (lo + hi)
        r1, R1, lam1, info = F.corrector(p, mid)
        if not info.converged:
            break
        m = F.modes(r1, R1, lam1, n_eigen)
        n_eval += 1
        # A side: the crossing eigenvalue keeps its sign (its sign resolves the
        # crossing below the inertia's numerical-zero floor); else the index
        same = (np.sign(m.values[j]) == np.sign(fa0)) if j is not None else m.negative == ia
        if same:
            lo, state_lo = mid, (r1, R1, lam1)
            fa = m.values[j] if j is not None else 0.0
        else:
            hi = mid
            fb = m.values[j] if j is not None else 0.0
    # regula falsi inside the bracket for the crossing arclength
    s_c = lo + (hi - lo) * fa / (fa - fb) if fa * fb < 0 else 0.5 * (lo + hi)
    rc, Rc, lamc, info = F.corrector(p, s_c)
    if not info.converged:
        rc, Rc, lamc = state_lo
    m = modes(F.problem, rc, Rc, lamc, 1, 0.0)        # the eigenpair nearest zero
    jj = 0
    tl_prev, tl_next = result._tlam[-2], result._tlam[-1]
    kind = "limit" if tl_prev * tl_next < 0 else "bifurcation"
    return CriticalPoint(kind=kind, load_factor=float(lamc), step=len(result.steps) - 2,
                         arclength=float(result._s[-2] + s_c), r=rc, R=Rc,
                         mode_positions=m.positions[jj], mode_spins=m.spins[jj],
                         eigenvalue=float(m.values[jj]),
                         bracket=(float(result._s[-2] + lo), float(result._s[-2] + hi)),
                         tangent=np.concatenate([p.ty, [p.tl]]),
                         load_scale=float(np.sqrt(F.psi2)))


def switch_branch(rod, point, ds=None, lam_stop=None, side=1, **kwargs):
    """Follow the branch that crosses the path at the bifurcation ``point``
    (:class:`CriticalPoint`): start from the point with the critical mode
    as the tangent (``side = +1`` or ``-1`` picks its sign), the load factor
    free.  Other arguments as in :func:`follow`; ``ds`` defaults to a step
    of 1e-2 in the scaled norm."""
    if side not in (1, -1):
        raise ValueError(f"side must be +1 or -1, got {side!r}")
    if not isinstance(point, CriticalPoint):
        raise ValueError("point must be a CriticalPoint of a PathResult (result.critical)")
    mode = np.concatenate([point.mode_positions, point.mode_spins], axis=1).ravel()
    kwargs["ds"] = 1e-2 if ds is None else ds
    kwargs.setdefault("load_scale", point.load_scale)
    return follow(rod, lam_stop=lam_stop,
                  start=(point.r, point.R, point.load_factor, side * mode, 0.0), **kwargs)


def solve_arclength(rod, n_steps=1, path=None, callback=None, **options):
    """:meth:`Rod.solve` with ``method="arclength"``: :func:`follow` from
    load factor 0 to ``path[-1]`` (default 1), first load step
    ``path[-1] / n_steps``."""
    rod.check_steps(n_steps)
    if path is None:
        lam_end = 1.0
    else:
        p = np.asarray(path, dtype=float)
        if p.shape != (2,) or p[0] != 0.0 or not np.isfinite(p[1]) or p[1] == 0.0:
            raise ValueError("with method='arclength' path must be (0, lam_end) with a finite "
                             f"lam_end != 0 (the continuation turns back by itself), got {path!r}")
        lam_end = float(p[1])
    options.setdefault("load_step", abs(lam_end) / n_steps)
    return follow(rod, lam_stop=lam_end, callback=callback, **options)
