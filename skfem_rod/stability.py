r"""Stability of equilibria: lowest eigenvalues of the symmetrized tangent
and the critical load factor along a family of equilibria.

Why the symmetrized tangent (Simo 1992)
---------------------------------------
The Newton tangent ``K`` of :mod:`skfem_rod.solver` is the derivative of the
residual for the update ``R <- exp(dw) R`` (spatial spins).  For a
potential ``Pi`` it is the second derivative along the curves
``exp(a w1) exp(b w2) R``, and exchanging the two spins changes the curve by
the commutator ``[hat w1, hat w2] = hat(w1 x w2)``:

    K(dy1, dy2) - K(dy2, dy1) = sum_nodes g_I . (w1_I x w2_I),

``g_I`` the rotational part of the gradient of ``Pi`` at node ``I``.  The
symmetric part ``(K + K^T) / 2`` is the covariant Hessian of ``Pi`` (the
Levi-Civita connection of the bi-invariant metric on SO(3): Simo, CMAME 96,
1992; the paper's remark at the end of its section 7).  At an equilibrium
under conservative loads the rotational gradient vanishes at every free
rotational dof, so ``K`` itself is symmetric there and equals the Hessian;
an equilibrium is stable (strict local minimum of ``Pi``) when the
symmetrized tangent restricted to the free dofs is positive definite, and
an eigenvalue crossing zero along a load path marks a bifurcation or limit
point.  Symmetrizing removes the round-off and the residual-size skew part
of the converged state, nothing else.

Dead forces are conservative.  Follower forces and moments (``R R0^T F``)
and dead moments (``M . delta w``, a spatially fixed axis) are not: ``K`` is
then not symmetric even at equilibrium (``||K - K^T||`` is of the size of
the load; measured in ``docs/stability.md``), there is no energy whose
Hessian the symmetrized tangent would be, and its eigenvalues do not decide
stability (flutter, e.g. Beck's column, needs the dynamics; divergence is a
zero eigenvalue of the full, unsymmetric ``K``).  The same holds for a node
with one or two of three spatial spin components fixed while a reaction
moment acts about the fixed axis (a non-integrable constraint on SO(3)).
:attr:`Modes.asymmetry` reports ``||K - K^T||_F / ||K||_F`` on the free
dofs so that the case is visible.

Units: the dofs are positions (length) and spins (rad), so the eigenvalues
of ``K`` mix force/length and moment units; their *signs* (the inertia)
do not depend on this scaling (Sylvester), their sizes do.

>>> import numpy as np
>>> from skfem_rod import Rod, Section, geometry
>>> rod = Rod(geometry.straight(1.0), Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=1.0), 8)
>>> rod.clamp("start").add_force("end", [-1.0, 0.0, 0.0])   # doctest: +ELLIPSIS
<skfem_rod.model.Rod object at ...>
>>> exact = lambda lam: (rod.r0 * (1 - lam / 1e4), rod.R0)   # uniform compression
>>> crit = critical_load(rod, exact, 1.0, 4.0, tol=1e-10)
>>> round(crit.load_factor, 4)          # P (1 - P/EA + P/GA) = pi^2 EI / (4 L^2)
2.4674
"""
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .newton import newton
from .options import make_options
from .problem import Problem

#: the automatic shift starts at ``-SHIFT_FLOOR * max|diag K|`` (numerical zero)
SHIFT_FLOOR = 1e-13

#: the stability test of a state in contact (the load stepping's
#: :meth:`skfem_rod.solver.LoadStepper.lowest_mode` and the pseudo-dynamics'
#: :func:`skfem_rod.dynamics.morse_index`) reads the tangent with
#: the active gaps' stiffness ``df_N / d gap`` times this, the forces
#: unchanged: the Hessian of the Lagrangian plus ``rho A^T A`` over the
#: strictly active gaps (``A`` their gradients), positive for a large
#: enough ``rho`` exactly where the Hessian is positive on the directions
#: that keep those gaps (Finsler's lemma), the second-order test of a
#: constrained minimum.  The augmented Lagrangian's own penalty is soft
#: (the Uzawa loop needs it so), and its tangent can read a stable
#: constrained equilibrium as a saddle: in the plectoneme at 2.375 turns
#: (100 elements) the lowest eigenvalue was -0.188 at the penalty, -0.104
#: at 10 times it, and 2.380e-5 at 100, 1e3, 1e4 and 1e6 times it (the
#: next ones 7.49e-3 ... 9.31e-3: converging to the constrained Hessian's)
#: (docs/stability.md)
CONTACT_STIFFENING = 1e4


def contact_stiffening(problem):
    """The ``stiffen`` factor of the stability tests of ``problem``
    (:func:`modes`, :func:`skfem_rod.dynamics.morse_index`):
    :data:`CONTACT_STIFFENING` with contact on, else 1."""
    return 1.0 if problem.contact is None else CONTACT_STIFFENING


@dataclass
class Modes:
    """Lowest eigenpairs of the symmetrized tangent at one configuration.

    Attributes
    ----------
    values : (k,) eigenvalues, ascending.
    positions, spins : (k, n_nodes, 3) the modes as nodal position and
        spatial-spin increments (node numbering of ``rod.r0``; zero at
        constrained dofs; unit Euclidean norm over the free dofs).
    negative : number of eigenvalues below ``-SHIFT_FLOOR * max|diag K|``
        (the Morse index of the equilibrium: 0 = stable).
    asymmetry : ``||K - K^T||_F / ||K||_F`` on the free dofs.
    skew : ``||K - K^T||_F`` (absolute: the relative measure is dominated by
        the stiff axial/shear entries; a follower force gives ``2 |f|``, an
        end moment, dead or follower, ``sqrt(2) |m|``).
    residual : equilibrium residual ``||R_free|| / max(|f_ext|, |reactions|)``
        (the symmetrized tangent is the Hessian only at equilibrium).
    load_factor : the load factor of the configuration.
    shift : the shift of the shift-invert Lanczos iteration.
    """
    values: np.ndarray
    positions: np.ndarray
    spins: np.ndarray
    negative: int
    asymmetry: float
    skew: float
    residual: float
    load_factor: float
    shift: float

    @property
    def lowest(self):
        return float(self.values[0])


@dataclass
class CriticalLoad:
    """Result of :func:`critical_load`.

    Attributes
    ----------
    load_factor : the critical load factor (zero of the lowest eigenvalue,
        linearly interpolated inside the final bracket).
    bracket : ``(lam_stable, lam_unstable)``, the final bracket.
    modes : :class:`Modes` at the stable end of the final bracket (its first
        mode is the buckling mode).
    history : list of ``(load_factor, lowest eigenvalue)`` per evaluation.
    """
    load_factor: float
    bracket: tuple
    modes: Modes
    history: list = field(default_factory=list)

    @property
    def evaluations(self):
        return len(self.history)


# ----------------------------------------------------------------------------
def free_tangent(problem, r, R, lam, stiffen=1.0):
    """Tangent on the free dofs at ``(r, R, lam)``: returns ``(K_free, info)``
    with ``K_free`` CSC (constrained rows and columns removed) and ``info``
    the relative equilibrium residual and the free-dof mask
    (:meth:`skfem_rod.problem.Problem.free_tangent`; ``stiffen``: the
    active gaps' stiffness times this, the constrained test)."""
    Kf, residual = problem.free_tangent(r, R, lam, stiffen)
    return Kf, dict(residual=residual, free=problem.free)


def inertia(A, shift=0.0):
    """Number of eigenvalues of the symmetric sparse ``A`` below ``shift``.

    Sylvester's law of inertia on a symmetric-mode LU (``P (A - shift I) P^T
    = L D L^T``, diagonal pivots) of SuperLU; dense Bunch-Kaufman
    ``scipy.linalg.ldl`` when SuperLU leaves the diagonal or hits a zero
    pivot.
    """
    n = A.shape[0]
    M = (A - shift * sp.identity(n, format="csc")).tocsc()
    try:
        lu = spla.splu(M, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options=dict(SymmetricMode=True))
        if np.array_equal(lu.perm_r, lu.perm_c):
            d = lu.U.diagonal()
            if np.all(np.isfinite(d)) and np.all(d != 0):
                return int(np.sum(d < 0))
    except RuntimeError:
        pass
    _, D, _ = sla.ldl(M.toarray())
    return int(np.sum(np.linalg.eigvalsh(D) < 0))       # D: 1x1 and 2x2 blocks


def _lowest_shift(Ks, floor):
    """A shift below every eigenvalue of ``Ks`` (at most 10x below the
    lowest one), and the number of eigenvalues below ``-floor``."""
    shift = -floor
    negative = inertia(Ks, shift)
    count = negative
    # Gershgorin: no eigenvalue lies below this bound
    A = abs(Ks).tocsr()
    d = Ks.diagonal()
    bound = float(np.min(d - (np.asarray(A.sum(axis=1)).ravel() - np.abs(d))))
    while count > 0:
        shift *= 10.0
        if shift <= bound:
            shift = bound - floor
            break
        count = inertia(Ks, shift)
    return shift, negative


def symmetric_eigen(Ks, k, sigma=None):
    """``k`` lowest eigenpairs of the symmetric sparse ``Ks`` (or the ``k``
    nearest ``sigma`` when given) by shift-invert Lanczos (``eigsh``).

    Returns ``(values, vectors, shift, negative)``, values ascending.
    """
    if not (isinstance(k, (int, np.integer)) and k >= 1):
        raise ValueError(f"k must be an integer >= 1, got {k!r}")
    n = Ks.shape[0]
    floor = SHIFT_FLOOR * max(float(np.abs(Ks.diagonal()).max()), 1e-300)
    shift, negative = _lowest_shift(Ks, floor)
    if sigma is not None:
        shift = float(sigma)
    if k >= n - 1:                        # ARPACK needs k < n - 1: tiny problem
        w, V = np.linalg.eigh(Ks.toarray())
        order = np.argsort(np.abs(w - shift))[:min(k, n)]
        order = order[np.argsort(w[order])]
        return w[order], V[:, order], shift, negative
    M = (Ks - shift * sp.identity(n, format="csc")).tocsc()
    if sigma is None:
        # shift below the spectrum: M is positive definite, no pivoting needed
        lu = spla.splu(M, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options=dict(SymmetricMode=True))
    else:
        lu = spla.splu(M)
    OPinv = spla.LinearOperator((n, n), matvec=lu.solve, dtype=float)
    # seeded random start: a constant vector can be orthogonal to symmetric modes
    v0 = np.random.default_rng(0).standard_normal(n)
    w, V = spla.eigsh(Ks, k=k, sigma=shift, which="LM", OPinv=OPinv, v0=v0)
    order = np.argsort(w)
    return w[order], V[:, order], shift, negative


def modes(problem, r, R, lam, k, sigma=None, stiffen=1.0):
    """:class:`Modes`: the ``k`` lowest eigenpairs (or nearest ``sigma``) of the
    symmetrized tangent of ``problem`` on the free dofs at ``(r, R, lam)``
    (``stiffen``: :meth:`skfem_rod.problem.Problem.free_tangent`)."""
    Kf, info = free_tangent(problem, r, R, lam, stiffen)
    nK = spla.norm(Kf)
    skew = float(spla.norm(Kf - Kf.T))
    asym = skew / nK if nK > 0 else 0.0
    Ks = (0.5 * (Kf + Kf.T)).tocsc()
    w, V, shift, negative = symmetric_eigen(Ks, k, sigma)
    # deterministic sign: largest component positive
    big = np.argmax(np.abs(V), axis=0)
    V = V * np.sign(V[big, np.arange(V.shape[1])])
    full = np.zeros((V.shape[1], problem.mesh.n_dofs))
    full[:, info["free"]] = V.T
    full = full.reshape(V.shape[1], -1, 6)
    return Modes(values=w, positions=full[..., :3].copy(), spins=full[..., 3:].copy(),
                 negative=negative, asymmetry=asym, skew=skew, residual=info["residual"],
                 load_factor=float(lam), shift=float(shift))


def _check_rod(rod):
    if rod.contact is not None:
        raise NotImplementedError(
            "stability with self-contact needs the converged Uzawa multipliers of "
            "the state, which a Result does not keep; switch contact off "
            "(rod.contact = None) for a contact-free state")


def lowest_eigenvalues(rod, r, R, lam, k=6, sigma=None):
    """The ``k`` lowest eigenvalues and modes of the symmetrized tangent
    ``(K + K^T) / 2`` on the free dofs at the configuration ``(r, R)`` and
    load factor ``lam``.

    Parameters
    ----------
    rod : Rod
    r, R : (n_nodes, 3), (n_nodes, 3, 3) nodal positions and rotations, e.g.
        ``result.steps[i].r`` and ``.R``; should be an equilibrium at ``lam``
        (:attr:`Modes.residual` tells).
    lam : float, load factor.
    k : number of eigenpairs.
    sigma : float, optional
        Shift of the shift-invert Lanczos iteration; the ``k`` eigenvalues
        nearest ``sigma`` are returned.  Default: a shift below the lowest
        eigenvalue, found from the inertia of ``K_sym - shift I``, so that the
        ``k`` returned are the ``k`` lowest (also when some are negative).

    Returns
    -------
    Modes

    Examples
    --------
    >>> from skfem_rod import Rod, Section, geometry
    >>> rod = Rod(geometry.straight(1.0), Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=1.0), 4)
    >>> rod.clamp("start")                      # doctest: +ELLIPSIS
    <skfem_rod.model.Rod object at ...>
    >>> m = lowest_eigenvalues(rod, rod.r0, rod.R0, 0.0, k=3)
    >>> bool(m.values[0] > 0), m.negative, m.positions.shape
    (True, 0, (3, 13, 3))
    """
    _check_rod(rod)
    r = np.asarray(r, float)
    R = np.asarray(R, float)
    return modes(Problem(rod), r, R, float(lam), k, sigma)


def critical_load(rod, state_fn, lam_lo, lam_hi, tol=1e-8, k=1, method="bisection"):
    """Critical load factor: where the lowest eigenvalue of the symmetrized
    tangent changes sign along a family of equilibria.

    Parameters
    ----------
    rod : Rod
    state_fn : callable ``lam -> (r, R)``, the equilibrium at load factor
        ``lam``: an exact fundamental state, or :class:`EquilibriumPath`
        (Newton continuation).
    lam_lo, lam_hi : a bracket: stable at ``lam_lo`` (lowest eigenvalue > 0),
        unstable at ``lam_hi`` (< 0).
    tol : stop when the bracket is narrower than ``tol * |lam|``.
    k : eigenpairs per evaluation (the lowest decides).
    method : ``"bisection"`` (halve the bracket) or ``"illinois"`` (regula
        falsi on the lowest eigenvalue with the Illinois modification;
        keeps the bracket, fewer evaluations for a smooth eigenvalue).

    Returns
    -------
    CriticalLoad
    """
    _check_rod(rod)
    if method not in ("bisection", "illinois"):
        raise ValueError(f"method must be 'bisection' or 'illinois', got {method!r}")
    if not (np.isfinite(tol) and tol > 0):
        raise ValueError(f"tol must be a finite number > 0, got {tol!r}")
    problem = Problem(rod)
    history = []

    def at(lam):
        r, R = state_fn(lam)
        m = modes(problem, np.asarray(r, float), np.asarray(R, float), lam, k, None)
        history.append((float(lam), m.lowest))
        return m

    lo, hi = float(lam_lo), float(lam_hi)
    m_lo, m_hi = at(lo), at(hi)
    if m_lo.lowest <= 0:
        raise ValueError(f"the lowest eigenvalue at lam_lo={lo:g} is {m_lo.lowest:.3e} <= 0: "
                         "the state is not stable there; lower lam_lo")
    if m_hi.lowest >= 0:
        raise ValueError(f"the lowest eigenvalue at lam_hi={hi:g} is {m_hi.lowest:.3e} >= 0: "
                         "no instability in the bracket; raise lam_hi")
    f_lo, f_hi = m_lo.lowest, m_hi.lowest
    side = 0
    while abs(hi - lo) > tol * max(abs(lo), abs(hi)):
        if method == "bisection":
            mid = 0.5 * (lo + hi)
        else:
            mid = lo + (hi - lo) * f_lo / (f_lo - f_hi)
            # keep strictly inside, and make progress of at least tol
            eps = 0.25 * tol * max(abs(lo), abs(hi))
            mid = min(max(mid, min(lo, hi) + eps), max(lo, hi) - eps)
        m = at(mid)
        if m.lowest > 0:
            lo, m_lo, f_lo = mid, m, m.lowest
            if side == -1 and method == "illinois":
                f_hi *= 0.5
            side = -1
        else:
            hi, m_hi, f_hi = mid, m, m.lowest
            if side == 1 and method == "illinois":
                f_lo *= 0.5
            side = 1
    lam_c = lo + (hi - lo) * m_lo.lowest / (m_lo.lowest - m_hi.lowest)
    return CriticalLoad(load_factor=float(lam_c), bracket=(lo, hi), modes=m_lo,
                        history=history)


class EquilibriumPath:
    """``lam -> (r, R)``: equilibria of ``rod`` by Newton continuation.

    Each call starts Newton (:func:`skfem_rod.newton.newton`) from the
    cached converged state nearest in load factor and steps toward ``lam``
    in increments of at most ``max_step`` (halved when Newton fails).
    Along a symmetric fundamental path (a perfect column, a beam bent in its
    stiff plane) the solution stays on the fundamental branch past the
    critical load: the out-of-path residual is zero to round-off.

    Parameters
    ----------
    rod : Rod
    max_step : largest load-factor increment of one Newton solve.
    **options : :class:`skfem_rod.solver.SolverOptions`.
    """

    def __init__(self, rod, max_step=0.25, **options):
        _check_rod(rod)
        rod.check_constraints()
        if not (np.isfinite(max_step) and max_step > 0):
            raise ValueError(f"max_step must be a finite number > 0, got {max_step!r}")
        self.rod = rod
        self.max_step = float(max_step)
        self.opts = make_options(options)
        self.problem = Problem(rod)
        self.states = {}
        self.newton_iterations = 0
        r, R = self._newton(rod.r0.copy(), rod.R0.copy(), 0.0, 0.0)
        self.states[0.0] = (r, R)

    def _newton(self, r, R, lam, dlam):
        r, R, _, rep = newton(self.problem, r, R, lam, self.opts,
                              prescribed=self.problem.prescribed(dlam))
        self.newton_iterations += rep.iterations
        if not rep.converged:
            raise RuntimeError(f"Newton failed at load factor {lam:g}: {rep.reason}")
        return r, R

    def __call__(self, lam):
        lam = float(lam)
        if lam in self.states:
            return self.states[lam]
        start = min(self.states, key=lambda x: abs(x - lam))
        r, R = self.states[start]
        cur, step = start, self.max_step
        while cur != lam:
            nxt = lam if abs(lam - cur) <= step else cur + np.sign(lam - cur) * step
            try:
                r_n, R_n = self._newton(r, R, nxt, nxt - cur)
            except RuntimeError:
                step *= 0.5
                if step < self.opts.min_step:
                    raise
                continue
            r, R, cur = r_n, R_n, nxt
        self.states[lam] = (r, R)
        return r, R


def _polylines(xs, y, stable, inserts):
    """Split the path into solid (stable) and dashed (unstable) polylines.

    ``inserts``: ``(k, f, x, y)`` points between steps ``k`` and ``k + 1``
    (fraction ``f``), the located critical points, where the style changes.
    A segment is stable when none of its step ends is unstable.
    """
    pts = [(float(k), xs[k], y[k], bool(stable[k])) for k in range(len(xs))]
    pts += [(k + f, xc, yc, None) for k, f, xc, yc in inserts]
    pts.sort(key=lambda p: p[0])
    lines = []
    for a, b in zip(pts[:-1], pts[1:]):
        st = all(p[3] is not False for p in (a, b))
        if lines and lines[-1][2] == st:
            lines[-1][0].append(b[1])
            lines[-1][1].append(b[2])
        else:
            lines.append(([a[1], b[1]], [a[2], b[2]], st))
    return lines


def plot_path(result, quantity=None, ax=None, filename=None, xlabel="load factor",
              ylabel=None, x=None, marker_critical=True, color="C0", **line_kw):
    """Equilibrium path with its stability: solid where stable (Morse index
    0), dashed where unstable; limit points marked with circles and
    bifurcations with squares.

    Parameters
    ----------
    result : :class:`skfem_rod.continuation.PathResult` (``stability=True``;
        without it the whole path is drawn solid and gray).
    quantity : per-step array, or callable ``(result, k) -> float``; default
        the largest nodal displacement.
    x : per-step array for the horizontal axis (default the load factor).
    ax : matplotlib axes (default: a new figure).
    filename : write the figure (PNG, atomically) when given.

    Returns
    -------
    the matplotlib axes.
    """
    import matplotlib
    if ax is None:
        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt
        _, ax = plt.subplots(figsize=(6, 4.2))
    n = len(result.steps)
    if quantity is None:
        y = np.array([np.abs(st.r - result.rod.r0).max() for st in result.steps])
        ylabel = ylabel or "largest nodal displacement"
    elif callable(quantity):
        y = np.array([float(quantity(result, k)) for k in range(n)])
    else:
        y = np.asarray(quantity, float)
    xs = result.load_factors if x is None else np.asarray(x, float)
    if y.shape != (n,) or xs.shape != (n,):
        raise ValueError(f"quantity and x must have one value per step ({n}), got shapes "
                         f"{y.shape} and {xs.shape}")
    index = getattr(result, "index", np.full(n, -1))
    crit = list(getattr(result, "critical", []))
    inserts, marks = [], []
    s_path = getattr(result, "arclengths", None)
    for c in crit:
        k = c.step
        ds = s_path[k + 1] - s_path[k]
        f = min(max((c.arclength - s_path[k]) / ds, 0.0), 1.0) if ds > 0 else 0.0
        xc = c.load_factor if x is None else xs[k] + f * (xs[k + 1] - xs[k])
        yc = y[k] + f * (y[k + 1] - y[k])          # linear in arclength
        inserts.append((k, f, xc, yc))
        marks.append((xc, yc, c.kind))
    if np.all(index < 0):
        ax.plot(xs, y, "-", color="0.4", **line_kw)
    else:
        labelled = set()
        for px, py, st in _polylines(xs, y, index == 0, inserts):
            lab = "stable" if st else "unstable"
            ax.plot(px, py, "-" if st else "--", color=color,
                    label=None if lab in labelled else lab, **line_kw)
            labelled.add(lab)
    if marker_critical:
        labelled = set()
        for xc, yc, kind in marks:
            ax.plot([xc], [yc], "o" if kind == "limit" else "s", color="C3", ms=5,
                    label=None if kind in labelled else f"{kind} point")
            labelled.add(kind)
    ax.set_xlabel(xlabel)
    if ylabel:
        ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    if filename is not None:
        from .export import atomic_path
        with atomic_path(filename) as tmp:
            ax.figure.savefig(tmp, dpi=120, bbox_inches="tight", format="png")
    return ax
