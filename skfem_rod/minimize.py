r"""Load steps by Newton on the total energy, with the smooth node barrier of
:mod:`skfem_rod.contact.barrier` for contact and its lagged Coulomb friction:
the experiment of issue 13 (docs/contact-solve.md, "A smooth barrier between
nodes"; ``benchmarks/bench_plectoneme_barrier.py``).  Not the paper's
augmented-Lagrangian contact; ``Rod.solve(..., method="barrier")`` runs
it (:func:`solve_barrier`: the load path of ``solver.follow_path``, each
step by :meth:`EnergySolve.step`).

Where every load is dead (forces, no moments, no followers) and motions are
prescribed, an equilibrium is a stationary point of

    E(y) = U_rod(y) - f . (x - x_0) + sum over node pairs b(g_ij)
           [+ handles] + bend and shear barriers  [+ D(y)]

(``D`` the friction's dissipation potential at lagged normal forces; the
handles, with ``handles=True``, continue the held ends; the bend and
shear barriers keep the node polyline from kinking within the
exclusion and the sections from tilting off it: barrier module doc,
"Handles" and "Local self-contact").
One step, in plain sight::

    predictor (EnergySolve.predict): frictionless, the quadratic through
        the last two equilibria with the path's tangent dy/dlam at the
        last (K_ff dy_f = df_ext/dlam - K q, from the Hessian factorized
        there for its inertia), the secant where it runs into a contact;
        with friction the secant (the last step's increment again); cut
        by the step bound, the rest of the prescribed motion applied
    frictionless: Newton on E to rtol
    friction:
        lag the friction at the step's start (pairs, normal forces, normals;
            each pair's contact point a material point of both sections;
            the slips the pairs had there carried, carry_slip: the step
            starts with the state's friction forces)
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
                per retry, kept for the next iteration where it was
                raised (and a tenth of it where the energy solves after
                this one start their shift search), else a tenth of it
                after a shortened step and 0 after a full one: pseudo-
                transient continuation; at most live_iterations)
            done when the state is an equilibrium with its own lag (the
                live Newton takes no iteration, or the lag at the state
                has the same friction there: no pair left it and the
                pairs new to it met during the step, same_friction):
                Coulomb's law holds at the state's own normal forces
        if the live Newton fails, or the lag stalls (no static path
            through the step: the plies slip), by the step's slip= :
            "cut": the step fails (the load path's first try: it cuts the
                step, and a half step usually goes through statically);
            "damped": pseudo-time steps through the slip (_damped: the
                DAMPED_CALM steps after a failed one; each Newton on the
                energy, the friction lagged once at the last one's state,
                and a proximal term);
            "fallback": settle the lag to lag_tol instead (its solves to
                lag_rtol), solve to rtol at it and check it again
                (Coulomb to lag_tol; not used by the solve: the static
                step from _damped's flow at rest is as "cut", its live
                Newton at most DAMPED_LIVE iterations, more pseudo-time
                steps where it fails)

    a solved step has converged if the strands' true least distance
        (crossing.min_distance: closest points of element pairs) is at
        least 2 radius (1 - penetration_tol): the barrier holds the nodes,
        and the centrelines can sag between them

Newton on E (the energy; with friction, E + D at the lag):
    converged when |G_free| <= rtol * force scale, or at the residual's
        round-off floor (Problem.at_floor: an unloaded state, a stiff rod)
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
    after more than CURVATURE_AFTER shifted iterations in a row (a creep
        near a saddle): also a step along the tangent's negative lowest
        mode, taken where it lowers the energy more (_curvature_step)
"""
import logging
import warnings
from dataclasses import dataclass, field
from typing import NamedTuple, Optional

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .contact.barrier import (Barrier, Bend, FrictionLag, NodePattern, Relaxation, Shear,
                              barrier_work, bend_work, carry_slip, friction_lag, friction_live,
                              friction_work, lag_change, node_contact, node_spacing,
                              same_friction, shear_work, step_bound)
from .contact.search import NeighbourList
from .contact.crossing import min_distance
from .kinematics import ElementRotationError
from .options import EnergyOptions
from .ordering import KeptOrdering, KeptSum, Ordered
from .problem import Problem
from .rotations import vee

__all__ = ["BarrierResolution", "EnergyOptions", "EnergySolve", "StepReport", "solve_barrier"]

#: the live Newton's line search halves at most this often before it
#: shortens the update by a shift instead (pseudo-transient continuation)
LIVE_HALVINGS = 6
#: the first shift of the live Newton's tangent (times diag|K|)
LIVE_SHIFT_START = 1e-4
#: energy Newton, where the tangent has needed a shift at more than
#: CURVATURE_AFTER iterations in a row (creeping near a saddle): also try
#: a step along its lowest mode (:meth:`EnergySolve._curvature_step`):
#: the mode by CURVATURE_ITERATIONS inverse iterations, the step moving no
#: node by more than CURVATURE_LENGTH radii, taken only where its
#: quadratic model promises CURVATURE_GAIN times the Newton step's energy
#: drop (at most CURVATURE_HALVINGS halvings) and its energy is lower
NEGATIVE_CURVATURE = True
CURVATURE_AFTER = 10
CURVATURE_ITERATIONS = 8
CURVATURE_LENGTH = 1.0
CURVATURE_GAIN = 2.0
CURVATURE_HALVINGS = 4
#: the live tangent's LU keeps a diagonal pivot unless it is below this
#: share of its column's largest entry (SuperLU's diag_pivot_thresh)
LIVE_PIVOT = 0.01

logger = logging.getLogger(__name__)
#: the lag's fixed point iteration (``EnergySolve._settle``) has stalled,
#: and the step fails, when LAG_STALL lags in a row did not bring the
#: normal forces' change (relative to the largest force) below LAG_GAIN
#: times the least change before: measured on the frictional plectoneme,
#: a step whose lag stalls (changes of 0.6-1.1 of the largest force for
#: 60 lags) succeeds when cut
LAG_STALL = 8
LAG_GAIN = 0.9
#: a frictional step whose static solve failed for one of these reasons
#: (the friction found no path through the step: the plies slip) is taken
#: by pseudo-time steps (``EnergySolve._damped``): each minimizes the
#: energy plus the friction from the last one's state plus the proximal
#: term ``c/2 |x - x_k|^2 + c r^2/2 (3 - tr(R R_k^T))`` per node, ``c``
#: from DAMPED_STIFFNESS times the force scale over the radius, divided by
#: DAMPED_GROWTH after each quick step (a longer pseudo-time step) and
#: multiplied by it after a failed one; once the proximal force is below
#: DAMPED_REST of the force scale the static solve is tried from there
#: (at most DAMPED_STEPS steps)
DAMPED_SLIPS = True
#: what a frictional step does where its static solve finds no path
#: (EnergySolve.step)
SLIPS = ("cut", "damped", "fallback")
SLIP_LIVE = "the live Newton found no equilibrium with its own lag"
SLIP_FAILURES = ("the friction lag stalled", "the friction lag did not settle",
                 "no equilibrium with its own lag", SLIP_LIVE)
DAMPED_STIFFNESS = 1e3
DAMPED_GROWTH = 4.0
DAMPED_REST = 1e-3
DAMPED_STEPS = 60
#: a pseudo-time step solved in at most this many iterations lengthens the next
DAMPED_QUICK = 25
#: the live Newton of the static step tried from the flow at rest fails
#: after this many iterations (more pseudo-time steps follow; the live
#: solves that converged from there took 7-9, those that failed ran to
#: the options' 80: measured on the 100- and 200-element slips)
DAMPED_LIVE = 20
#: the steps of a load path after a failed one that may take pseudo-time
#: steps (BarrierStepper.advance)
DAMPED_CALM = 2
#: after a failed static step from the flow, the next is tried once the
#: proximal force has fallen to this share of the force at that attempt
DAMPED_RETRY = 0.1
#: the barrier's candidate pairs (a :class:`~skfem_rod.contact.search.NeighbourList`)
#: are kept while no node has moved by more than this many radii
NEAR_SKIN = 0.25


def backward_error(A, x, b):
    """The norm-wise backward error of ``x`` as a solution of ``A x = b``
    (infinity norms): ``|A x - b| / (|A| |x| + |b|)``."""
    scale = float(abs(A).sum(axis=1).max()) * float(np.abs(x).max()) + float(np.abs(b).max())
    return float(np.abs(A @ x - b).max()) / max(scale, 1e-300)


class Factor(NamedTuple):
    """The energy Newton's factorization of its shifted tangent on the free
    dofs: the LU, the unshifted free block (an
    :class:`~skfem_rod.ordering.Ordered`, in the LU's order) and ``D =
    diag|K|`` in that order."""
    lu: object
    block: Ordered
    d: np.ndarray


class Proximal(NamedTuple):
    """The anchor of a pseudo-time step (:meth:`EnergySolve._damped`):
    the energy gains ``c/2 |x - r|^2 + c length^2 / 2 (3 - tr(R_x R^T))``
    per node (``3 - tr`` is ``|theta|^2`` to second order in the
    rotation ``theta`` from the anchor)."""
    r: np.ndarray
    R: np.ndarray
    c: float                  # force per length
    length: float             # rotations weigh as displacements of this arm


def proximal_work(r, R, prox, tangent=True):
    """``(E, G, K)`` of the :class:`Proximal` term at ``(r, R)``: the
    gradient over the dofs (positions, spatial spins), the tangent (the
    gradient's derivative along the spin update ``R <- exp(w) R``: ``c
    l^2 / 2 (tr(B) I - B)``, ``B = R R_k^T``; not symmetric away from the
    anchor, as the rod's own) block diagonal, or None.  Not
    :class:`skfem_rod.problem.Viscous` (``Problem.damped``), the viscous
    term of the gradient flow and the pseudo-dynamics: that one is a
    residual with no energy beside it and a tangent exact only at the
    anchor (``c W``), and the energy Newton takes its steps by an Armijo
    search on the energy with the exact tangent."""
    n = r.shape[0]
    dx = r - prox.r
    B = R @ np.swapaxes(prox.R, 1, 2)
    tr = np.trace(B, axis1=1, axis2=2)
    cw = prox.c * prox.length ** 2
    E = 0.5 * prox.c * float(np.sum(dx * dx)) + 0.5 * cw * float(np.sum(3.0 - tr))
    G = np.hstack([prox.c * dx, cw * vee(B)]).ravel()
    K = None
    if tangent:
        blk = np.zeros((n, 6, 6))
        blk[:, :3, :3] = prox.c * np.eye(3)
        blk[:, 3:, 3:] = 0.5 * cw * (tr[:, None, None] * np.eye(3) - B)
        K = sp.bsr_matrix((blk, np.arange(n), np.arange(n + 1)), shape=(6 * n, 6 * n)).tocsc()
    return E, G, K


@dataclass
class StepReport:
    """What one step took."""
    converged: bool
    iterations: int = 0           # Newton iterations taken (all lags)
    shifts: int = 0               # factorizations refused as not positive definite
    halvings: int = 0
    retries: int = 0
    curvature_steps: int = 0      # updates along the tangent's negative lowest mode
    lags: int = 0                 # friction lags solved
    fallbacks: int = 0            # live solves that failed (then solved on the energy)
    damped: int = 0               # pseudo-time steps through a slip (friction)
    slip: str = ""                # why the static solve failed where they were taken
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
    floor: Optional[float] = None  # the last solve stopped at the residual's round-off floor
    #: frictionless: the negative eigenvalues of the energy's Hessian at the
    #: solved state (0: a minimum; more: a saddle, e.g. held by symmetry;
    #: None: not known, e.g. with friction)
    negative: Optional[int] = None
    #: frictionless: the path's tangent ``dy/dlam`` at the solved state
    #: (dof basis), the next step's predictor (None: not known)
    rate: Optional[np.ndarray] = None
    #: the out-of-balance force over the dofs where the last solve
    #: converged: the rod's, the barrier's and the friction it held (at the
    #: state's own normal forces where ``live``, at its lag's otherwise);
    #: on the supported dofs the reactions
    out_of_balance: Optional[np.ndarray] = None


def predictor(secant, euler, ratio):
    """A step's predicted increment (dof basis) from the equilibrium
    ``y_k``: with the last step's increment ``secant = y_k - y_{k-1}``
    and this step's tangent increment ``euler = dlam y'(y_k)``, the
    quadratic through ``y_{k-1}`` and ``y_k`` with the slope ``y'`` at
    ``y_k``, taken ``ratio`` times the last step's size on,

        dy = (1 + ratio) euler - ratio^2 secant;

    with one of them alone, ``euler`` or ``ratio secant``.  Measured on
    the frictionless barrier plectoneme (docs/contact-solve.md): the
    quadratic one starts Newton 4-100 times nearer than the secant."""
    if euler is None:
        return ratio * secant
    if secant is None:
        return euler
    return (1 + ratio) * euler - ratio ** 2 * secant


def _absorb(into, sub, before=False):
    """Add the counts of the :class:`StepReport` ``sub`` to ``into``, and
    its residual histories after ``into``'s (``before``: ahead of them)."""
    # (not the fallbacks: they tell what friction the last solve's state holds)
    for name in ("iterations", "shifts", "halvings", "retries", "curvature_steps", "lags"):
        setattr(into, name, getattr(into, name) + getattr(sub, name))
    if before:
        into.history[:0] = sub.history
        into.solves[:0] = sub.solves
    else:
        into.history.extend(sub.history)
        into.solves.extend(sub.solves)


class EnergySolve:
    """The rod ``rod`` (without contact of its own) with the node ``barrier``
    and, with ``mu > 0``, Coulomb friction at the node pairs (slip
    smoothing ``eps_v``, default 1e-3 of the radius ``radius``); with
    ``mu_R > 0`` (a length) rotational Coulomb friction, on the pivot about
    each pair's normal (smoothing ``eps_R``, an angle, default ``eps_v /
    radius``; :func:`~skfem_rod.contact.barrier.friction_live`);
    ``problem`` the rod's :class:`~skfem_rod.problem.Problem` where it is
    built already."""

    def __init__(self, rod, barrier: Barrier, radius, mu=0.0, eps_v=None,
                 options: Optional[EnergyOptions] = None, problem: Optional[Problem] = None,
                 mu_R=0.0, eps_R=None):
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
        for name, value in (("mu", mu), ("mu_R", mu_R)):
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a finite number >= 0, not {value!r}")
        self.rod, self.barrier, self.radius, self.mu = rod, barrier, float(radius), float(mu)
        self.mu_R = float(mu_R)
        self.eps_v = 1e-3 * self.radius if eps_v is None else float(eps_v)
        if not (np.isfinite(self.eps_v) and self.eps_v > 0):
            raise ValueError(f"eps_v must be a finite number > 0, not {eps_v!r}")
        self.eps_R = self.eps_v / self.radius if eps_R is None else float(eps_R)
        if not (np.isfinite(self.eps_R) and self.eps_R > 0):
            raise ValueError(f"eps_R must be a finite number > 0, not {eps_R!r}")
        #: friction of either law on
        self.with_friction = self.mu > 0 or self.mu_R > 0
        self.options = options or EnergyOptions()
        if problem is not None and problem.rod is not rod:
            raise ValueError("problem: it must be the Problem of rod")
        P = Problem(rod) if problem is None else problem
        if P.T is not None:
            raise ValueError("EnergySolve needs supports along the spatial axes")
        self.P, self.free, self.s, self.x0 = P, P.free, rod.mesh.s_nodes, rod.r0.copy()
        self.ordering = KeptOrdering(self.free)    # the factorizations' ordering
        # the barrier's pairs from candidates kept while no node moves by
        # more than NEAR_SKIN radii (a Verlet list, as the contact search's;
        # of node pairs: a margin of twice the skin)
        self.near = NeighbourList(skin=NEAR_SKIN * self.radius, spread=1.0)
        # the barrier's and the friction's Hessian patterns, kept while
        # their pairs recur (the friction's: the lag's, fixed for a solve)
        self.patterns = (NodePattern(), NodePattern())
        # ... and the tangent's, their sum with the rod's (and the bend's,
        # the shear's, a pseudo-time step's), kept while none changes
        self.summed = KeptSum()
        #: the anchor of a pseudo-time step while one is solved (_damped)
        self.proximal = None
        # no kink tighter than half the radius (barrier module doc, "Local
        # self-contact")
        self.bend = Bend.for_rod(self.s, self.radius, max(rod.section.EI1, rod.section.EI2),
                                 closed=barrier.period is not None)
        # ... nor a section tilted far off the centreline (a phase slip of the twist)
        self.shear = Shear.for_rod(self.s, self.radius, max(rod.section.EI1, rod.section.EI2),
                                   closed=barrier.period is not None)
        if not np.isfinite(shear_work(rod.r0, rod.R0, self.shear, hessian=False).energy):
            raise ValueError(f"rod: a section of its reference shape tilts by more than "
                             f"{self.shear.limit:.3g} rad from the chords to its neighbours; "
                             "the node barrier's solve forbids that (a finer mesh)")
        if not np.isfinite(bend_work(rod.r0, self.bend, hessian=False).energy):
            raise ValueError(f"rod: its reference shape turns by more than "
                             f"{self.bend.limit:.3g} rad at a node, a curvature above 2 / radius "
                             f"= {2 / self.radius:.3g}: a loop tighter than half the contact "
                             f"radius {self.radius:.3g}, which the node barrier forbids (its "
                             "tube would pass through itself); give a smaller contact radius")
        # the handles point away from the rod along the end tangent d3
        self.handle_sign = np.zeros(len(barrier.handles))
        for h, k in enumerate(barrier.handles):
            if self.s[k] not in (self.s.min(), self.s.max()):
                raise ValueError(f"barrier: node {k} (s = {self.s[k]:g}) is no end of the rod; "
                                 "handles continue its ends")
            if self.free[6 * k + 3:6 * k + 6].any():
                raise ValueError(f"barrier: the end at s = {self.s[k]:g} turns freely; a handle "
                                 "needs the end's rotation held (clamp, fix_rotation or "
                                 "prescribe_rotation)")
            self.handle_sign[h] = 1.0 if self.s[k] == self.s.max() else -1.0

    def _directions(self, R):
        """The handles' directions at the rotations ``R`` (None: no handles)."""
        if not self.barrier.handles:
            return None
        return self.handle_sign[:, None] * R[list(self.barrier.handles)][:, :, 2]

    def _bound(self, r, R, dy):
        """The collision bound of the update ``dy`` (dof basis) from ``(r,
        R)``: :func:`~skfem_rod.contact.barrier.step_bound` of its node
        moves, with the handles' directions at ``R``."""
        return step_bound(r, dy.reshape(-1, 6)[:, :3], self.s, self.barrier,
                          self.options.fraction, self._directions(R), self.near)

    # -- the energy ------------------------------------------------------
    def _parts(self, r, R, lam, lag, tangent, live=False):
        ev = self.P.evaluate(r, R, lam, tangent=tangent)
        bp, fp = self.patterns
        bw = barrier_work(r, self.s, self.barrier, hessian=tangent, dofs=6,
                          directions=self._directions(R), near=self.near, pattern=bp)
        fw = None
        if lag is not None:
            fw = (friction_live(r, R, lag, self.barrier, self.mu, self.eps_v, tangent, fp,
                                self.mu_R, self.eps_R)
                  if live else friction_work(r, R, lag, self.mu, self.eps_v, tangent, fp,
                                             self.mu_R, self.eps_R))
        kw = bend_work(r, self.bend, hessian=tangent, dofs=6)
        sw = shear_work(r, R, self.shear, hessian=tangent)
        f = ev.external.reshape(-1, 6)
        E = (ev.internal.energy - float(np.sum(f[:, :3] * (r - self.x0))) + bw.energy
             + kw.energy + sw.energy)
        G = (ev.residual + np.hstack([bw.gradient + kw.gradient, bw.spin_gradient]).ravel()
             + sw.gradient.ravel())
        if fw is not None:
            # live: no potential; E stays the rest's (infinite on contact)
            E, G = (E if live else E + fw.energy), G + fw.gradient.ravel()
        pw = None
        if self.proximal is not None:               # a pseudo-time step
            pw = proximal_work(r, R, self.proximal, tangent)
            E, G = E + pw[0], G + pw[1]
        K = None
        if tangent:
            K = self.summed([ev.tangent, bw.hessian, fw.hessian if fw is not None else None,
                             kw.hessian, sw.hessian, pw[2] if pw is not None else None])
        return E, G, K, ev, bw

    def energy(self, r, R, lam, lag=None):
        """``(E, G)``: the total energy (with the friction potential of
        ``lag``) and its gradient over the dofs at ``(r, R)``, load factor
        ``lam``."""
        E, G, _, _, _ = self._parts(r, R, lam, lag, False)
        return E, G

    def tangent(self, r, R, lam, lag=None):
        """The total energy's Hessian over the dofs at ``(r, R)``, load
        factor ``lam`` (with the friction potential of ``lag``): sparse,
        in the problem's dof basis, supported dofs included."""
        return self._parts(r, R, lam, lag, True)[2]

    def residual(self, r, R, lam, lag=None):
        """The out-of-balance force over the dofs at ``(r, R)``, load
        factor ``lam``, with the friction of ``lag``'s pairs at the state's
        own normal forces and normals (:func:`friction_live`): zero on the
        free dofs at a converged frictional step."""
        return self._parts(r, R, lam, lag, False, live=True)[1]

    def contact(self, r, R, rep):
        """The node pairs in contact at the state ``(r, R)`` solved by the
        step of report ``rep``, with their friction
        (:func:`~skfem_rod.contact.barrier.node_contact`)."""
        return node_contact(r, R, self.s, self.barrier, rep.friction, self.mu, self.eps_v,
                            live=rep.live, mu_R=self.mu_R, eps_R=self.eps_R)

    # -- one Newton solve at a fixed lag ---------------------------------
    def _direction(self, K, G, sigma, rep, live=False):
        """The Newton update ``dy`` on the free dofs and the shift used.
        ``live``: the tangent is not symmetric (live normal forces in the
        friction); solved by a pivoting LU, shifted by ``sigma diag|K|`` as
        given (no inertia to test).  The free block is factorized in the
        fill-reducing ordering kept across iterations
        (:class:`~skfem_rod.ordering.KeptOrdering`)."""
        o = self.options
        blk = self.ordering.block(K)
        Kf = blk.A
        d = np.abs(Kf.diagonal())
        d[d == 0] = 1.0
        b = -blk.to_block(G[self.free])
        if live:
            A = Kf if sigma == 0 else (Kf + sp.diags(sigma * d)).tocsc()
            try:
                # nearly symmetric (the energy's Hessian and the friction's
                # pairs): the symmetric ordering and diagonal pivots where
                # they are not small, a third of COLAMD's time at the
                # plectoneme's 1800 dofs; partial pivoting where the
                # solution's backward error is not small
                x = self.ordering.factor(blk._replace(A=A), diag_pivot_thresh=LIVE_PIVOT,
                                         options=dict(SymmetricMode=True)).solve(b)
                if not (np.all(np.isfinite(x)) and backward_error(A, x, b) <= 1e-12):
                    x = spla.splu(A, permc_spec="COLAMD").solve(b)
            except RuntimeError:             # exactly singular
                raise np.linalg.LinAlgError("singular tangent") from None
            if not np.all(np.isfinite(x)):
                raise np.linalg.LinAlgError("non-finite Newton update")
            dy = np.zeros_like(G)
            dy[self.free] = blk.from_block(x)
            return dy, sigma, None
        while True:
            A = Kf if sigma == 0 else (Kf + sp.diags(sigma * d)).tocsc()
            try:
                lu = self.ordering.factor(blk._replace(A=A), diag_pivot_thresh=0.0,
                                          options=dict(SymmetricMode=True))
                x = lu.solve(b)
                if np.array_equal(lu.perm_r, lu.perm_c):
                    definite = bool(np.all(lu.U.diagonal() > 0))
                else:                        # pivoted: descent is all one can tell
                    definite = float(b @ x) > 0
            except RuntimeError:             # exactly singular
                definite = False
            if definite and np.all(np.isfinite(x)):
                dy = np.zeros_like(G)
                dy[self.free] = blk.from_block(x)
                return dy, sigma, Factor(lu, blk, d)
            sigma = o.shift_start if sigma == 0 else 10 * sigma
            rep.shifts += 1
            if sigma > 1e12:
                raise np.linalg.LinAlgError("no positive definite shift below 1e12")

    def _curvature_step(self, r, R, lam, lag, E, G, dy, factor, newton_drop):
        """A step along the tangent's lowest mode where it is negative (the
        escape from a saddle that the shifted Newton creeps away from):
        the mode by inverse iteration with the shifted factorization
        (``(K + sigma D)^-1 D``, ``D = diag|K|``, whose largest eigenvalue
        is the pencil's lowest) from the Newton update ``dy``, turned
        downhill, scaled to move no node by more than ``CURVATURE_LENGTH``
        radii nor turn one by more than ``max_spin``, bounded by the
        collision bound, halved until the energy falls by the Armijo share
        of its quadratic model -- while that model promises
        ``CURVATURE_GAIN`` times the Newton step's drop ``newton_drop``.  Returns ``(r, R, E, parts)`` or None
        (no negative mode, no promising or no accepted step)."""
        o, P, free = self.options, self.P, self.free
        lu, blk, d = factor
        # from the Newton update: where the lowest mode is degenerate (a
        # round section buckles in any plane) the estimate keeps to the
        # plane the loads push towards (all in the factor's order)
        v = blk.to_block(dy[free])
        v = v / max(float(np.linalg.norm(v)), 1e-300)
        for _ in range(CURVATURE_ITERATIONS):
            v = lu.solve(d * v)
            v /= np.linalg.norm(v)
        curv = float(v @ (blk.A @ v)) / float(v @ (d * v))
        if not curv < 0:
            return None
        d, v = blk.from_block(d), blk.from_block(v)
        g = G[free]
        if float(g @ v) > 0:
            v = -v
        step = np.zeros_like(G)
        step[free] = v
        s6 = step.reshape(-1, 6)
        scale = min(CURVATURE_LENGTH * self.radius
                    / max(float(np.linalg.norm(s6[:, :3], axis=1).max()), 1e-300),
                    o.max_spin / max(float(np.linalg.norm(s6[:, 3:], axis=1).max()), 1e-300))
        step *= scale
        slope = float(g @ step[free])
        quad = curv * float(step[free] @ (d * step[free]))
        t = min(1.0, self._bound(r, R, step))
        for halving in range(CURVATURE_HALVINGS):
            if -(t * slope + 0.5 * t * t * quad) < CURVATURE_GAIN * newton_drop:
                return None
            try:
                rt, Rt = P.update(r, R, step, t)
                Et = self._parts(rt, Rt, lam, lag, False)[0]
            except ElementRotationError:
                Et = np.inf
            if np.isfinite(Et) and Et <= E + o.armijo * (t * slope + 0.5 * t * t * quad):
                parts = self._parts(rt, Rt, lam, lag, True)
                return rt, Rt, parts[0], parts
            t *= 0.5
        return None

    def _solved(self, K, R, rep):
        """At a solved frictionless state (rotations ``R``, the energy's
        Hessian ``K``): ``rep.negative``, the number of negative
        eigenvalues of ``K`` on the free dofs (Sylvester: the negative
        pivots of an LU without off-diagonal pivoting; None where the LU
        pivoted off the diagonal or the matrix is singular), and from the
        same factorization ``rep.rate``, the path's tangent ``dy/dlam``
        (dof basis): ``K_ff dy_f = df_ext/dlam - K q`` with ``q`` the
        prescribed motions' rate (None where ``K`` is singular)."""
        blk = self.ordering.block(K)
        try:
            lu = self.ordering.factor(blk, diag_pivot_thresh=0.0,
                                      options=dict(SymmetricMode=True))
        except RuntimeError:
            return
        q = self.P.prescribed(1.0)
        x = lu.solve(blk.to_block((self.P.load_rate(R) - K @ q)[self.free]))
        if np.all(np.isfinite(x)):
            rep.rate = q
            rep.rate[self.free] = blk.from_block(x)
        if np.array_equal(lu.perm_r, lu.perm_c):
            rep.negative = int(np.sum(lu.U.diagonal() < 0))

    def newton(self, r, R, lam, lag, sigma, rep, rtol=None, live=False, iterations=None):
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
        failure is for the caller to recover from.  ``iterations``: at
        most so many in this solve (the energy's solves of a step have
        ``max_iterations`` in all)."""
        o = self.options
        rtol = o.rtol if rtol is None else rtol
        limit = rep.iterations + o.live_iterations if live else o.max_iterations
        if iterations is not None:
            limit = min(limit, rep.iterations + iterations)
        start = len(rep.history)
        out = self._newton(r, R, lam, lag, sigma, rep, rtol, live, limit)
        rep.solves.append((live, rep.history[start:]))
        return out

    def _newton(self, r, R, lam, lag, sigma, rep, rtol, live, limit):
        o, P, free = self.options, self.P, self.free
        E = G = K = None
        retries, rn, trial = 0, np.inf, None
        tau = 0.0                   # live: the pseudo-time shift (0: Newton)
        shifted = 0                 # iterations in a row with a shifted tangent
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
                # converged at rtol or (no loads to measure against: an
                # unloaded state; a stiff rod) at the residual's round-off floor
                done = rn <= rtol * P.force_scale(ev)
                if not done:
                    rep.floor = P.at_floor(r, R, lam, ev, rn)
                    done = rep.floor is not None
                if done:
                    rep.out_of_balance = G
                    if lag is None:      # frictionless: the Hessian's inertia, the path's tangent
                        self._solved(K, R, rep)
                    return r, R, sigma
                if rep.iterations >= limit:
                    rep.reason = (f"no convergence in {limit} iterations "
                                  f"(residual {rn:.3e})")
                    return r, R, sigma
            try:
                dy, used, factor = self._direction(K, G, tau if live else sigma, rep, live)
            except np.linalg.LinAlgError as err:
                rep.reason = str(err)
                return r, R, sigma
            slope = float(G[free] @ dy[free])
            d6 = dy.reshape(-1, 6)
            alpha = min(1.0,
                        o.max_spin / max(float(np.linalg.norm(d6[:, 3:], axis=1).max()), 1e-300),
                        self._bound(r, R, dy))
            for halving in range(LIVE_HALVINGS if live else o.halvings):
                try:
                    rt, Rt = P.update(r, R, dy, alpha)
                    # the first trial (the full step, or as far as the bounds
                    # let it go) is taken most often: its tangent with it
                    trial = self._parts(rt, Rt, lam, lag, halving == 0, live)
                    Et, Gt = trial[:2]
                    if halving:
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
            shifted = shifted + 1 if used > 0 else 0
            if NEGATIVE_CURVATURE and not live and shifted > CURVATURE_AFTER:
                nc = self._curvature_step(r, R, lam, lag, E, G, dy, factor,
                                          E - Et if np.isfinite(Et) else np.inf)
                if nc is not None and (not np.isfinite(Et) or nc[2] < Et):
                    rt, Rt, Et, trial = nc
                    rep.curvature_steps += 1
            if live and not retries:
                # a full step taken: plain Newton again (its quadratic tail);
                # a shortened one: a tenth of the shift
                tau = 0.0 if alpha == 1.0 or tau / 10 < LIVE_SHIFT_START else tau / 10
            elif live:
                # a step that needed the shift raised keeps it for the next
                # (where the plain update found no descent it would not find
                # one the next time: half the evaluations of a creeping
                # solve, measured), and the energy solves after this one
                # start their shift search from a tenth of it, as the energy
                # Newton carries its own (both times diag|K|): the frictional
                # plectoneme in 83 s against 103 s at 100 elements, 307 s
                # against 389 s at 200 (docs/contact-solve.md)
                sigma = used / 10 if used >= o.shift_start else 0.0
            else:
                sigma = used / 10 if used >= o.shift_start else 0.0
            r, R, G, retries = rt, Rt, None, 0
            trial = trial if trial is not None and np.isfinite(trial[0]) else None
            rep.iterations += 1

    # -- one load step ---------------------------------------------------
    def step(self, r, R, lam, dlam, previous=None, sigma=0.0, ratio=1.0, slip="damped",
             rate=None, stable=False, friction=None):
        """From the equilibrium ``(r, R)`` at load factor ``lam`` to
        ``lam + dlam``, from the state :meth:`predict` gives (``previous``,
        ``ratio``, ``rate``: its arguments; ``stable``: ``(r, R)`` is a
        minimum of the energy, :attr:`StepReport.negative` 0, see
        :meth:`_frictionless`).  With friction, where the
        static solve finds no path through the step (``SLIP_FAILURES``: the
        plies slip), ``slip`` says what follows: ``"cut"`` the step fails
        there (the load path cuts it: a shorter step usually goes through
        statically); ``"damped"`` pseudo-time steps through the slip
        (:meth:`_damped`); ``"fallback"`` the lag settled to ``lag_tol``
        (Coulomb's law to that).  ``friction``: the lag ``(r, R)`` was
        solved with (:attr:`StepReport.friction` of its step), whose
        pairs' slips the step carries (:func:`carry_slip`: the friction's
        memory); None: every pair's slip starts from zero.  Returns ``(r,
        R, StepReport)``; on failure the state given back is where the
        solve stopped (not an equilibrium)."""
        if slip not in SLIPS:
            raise ValueError(f"slip={slip!r}: must be one of {', '.join(map(repr, SLIPS))}")
        if not self.with_friction:
            return self._frictionless(r, R, lam, dlam, previous, sigma, ratio, rate, stable)
        if dlam == 0 and friction is not None and friction.pairs.shape[0]:
            # no load added to a state solved with the lag `friction`: where it
            # is still an equilibrium with it, it is the step's answer (the
            # carry re-centres each pair's points, which moves where the
            # forces act: a restart would not start where it stopped)
            rep = StepReport(converged=False, sigma=sigma)
            self.newton(r, R, lam, friction, sigma, rep, live=True, iterations=0)
            if not rep.reason:
                rep.friction, rep.live, rep.lags = friction, True, 1
                return r, R, self._checked(r, rep)
        rep = StepReport(converged=False, sigma=sigma)
        r1, R1 = self.predict(r, R, dlam, previous, ratio, rate)
        lam1 = lam + dlam
        if slip == "damped" and not DAMPED_SLIPS:
            slip = "fallback"
        r2, R2, rep = self._frictional(r, R, r1, R1, lam1, sigma, rep,
                                       fallback=slip == "fallback", carried=friction)
        if rep.converged or slip != "damped" or not rep.reason.startswith(SLIP_FAILURES):
            return r2, R2, rep
        # no static path through the step (a slip): pseudo-time steps
        return self._damped(r, R, r1, R1, lam1, sigma, rep)

    def _frictionless(self, r, R, lam, dlam, previous, sigma, ratio, rate, stable):
        """The frictionless step of :meth:`step`: Newton on the energy from
        the predicted state.  Where the step starts from a minimum
        (``stable``) and the tangent's prediction (``rate``) leads Newton
        to a saddle, stability was lost within the step, and the predictor
        followed the path's branch on past it: the step is solved again
        from the secant's start, or else the plain one, from which the
        energy's descent leaves the branch for a minimum where there is one
        (docs/contact-solve.md); the report counts every solve tried, the
        one whose state it returns last."""
        rep = StepReport(converged=False, sigma=sigma)
        r1, R1 = self.predict(r, R, dlam, previous, ratio, rate)
        r2, R2, sig = self.newton(r1, R1, lam + dlam, None, sigma, rep)
        rep.lags = 1
        if rep.reason:
            return r2, R2, rep
        rep.sigma = sig
        tried, starts = [], ()
        if stable and rep.negative and rate is not None:
            starts = (None,) if previous is None else (previous, None)
        for start in starts:
            r3, R3, other = self._frictionless(r, R, lam, dlam, start, sigma, ratio, None, False)
            if other.converged and not other.negative:
                for t in reversed([rep] + tried):
                    _absorb(other, t, before=True)
                return r3, R3, other
            tried.append(other)
        for t in reversed(tried):
            _absorb(rep, t, before=True)
        return r2, R2, self._checked(r2, rep)

    def predict(self, r, R, dlam, previous=None, ratio=1.0, rate=None):
        """The state a step of ``dlam`` from the equilibrium ``(r, R)``
        starts Newton from: moved by :func:`predictor`'s increment
        (``previous``: the equilibrium before, its increment taken
        ``ratio`` times, this step's size over the last one's; ``rate``:
        the path's tangent ``dy/dlam`` at ``(r, R)``,
        :attr:`StepReport.rate` of the step that solved it), cut by the
        collision bound, then the rest of the prescribed motion applied.
        Where the quadratic predictor runs into a contact (the bound cuts
        it), the secant instead: the tangent at a state where node pairs
        slide past each other misleads (measured, docs/contact-solve.md).
        No predictor given, or one that would wrap an element's rotation:
        the prescribed motion alone."""
        P = self.P
        p = P.prescribed(dlam)
        secant = None if previous is None else P.increment(r, R, previous[0], previous[1])
        euler = None if rate is None else dlam * rate
        dy = None
        if secant is not None or euler is not None:
            dy = predictor(secant, euler, ratio)
            a = self._bound(r, R, dy)
            if a < 1 and euler is not None and secant is not None:
                dy = ratio * secant          # the quadratic runs into a contact
                a = self._bound(r, R, dy)
        if dy is not None:
            try:
                r1, R1 = P.update(r, R, dy, a)
                return P.update(r1, R1, p, 1 - a) if a < 1 else (r1, R1)
            except ElementRotationError:              # after a snap: no secant
                pass
        return P.update(r, R, p)

    def _frictional(self, r, R, r1, R1, lam1, sigma, rep, fallback=True, live_iterations=None,
                    carried=None):
        """The frictional solve of the step from the equilibrium ``(r, R)``
        to the load factor ``lam1``, from the predicted ``(r1, R1)``: the
        lag's normal forces brought to a fixed point on the energy
        (Aitken-relaxed) until they change by less than ``live_tol`` of the
        largest; then Newton at the state's own (live) normal forces, until
        the state is an equilibrium with its own lag; where that fails, the
        lag settled to ``lag_tol`` (the ``fallback``; without it the step
        fails there, ``SLIP_LIVE``); ``live_iterations``: the live
        Newton's limit (default the options'); ``carried``: the lag
        ``(r, R)`` was solved with, its slips carried
        (:func:`carry_slip`).  Returns ``(r, R, rep)``."""
        o = self.options
        lag = friction_lag(r, R, r, R, self.s, self.barrier)
        if carried is not None:
            lag = carry_slip(lag, r, R, carried, self.eps_v, self.eps_R)
        held = lag.pairs
        settled = self._settle(r, R, r1, R1, lam1, lag, held, Relaxation(r.shape[0]),
                               o.live_tol, o.near_rtol, sigma, rep)
        if settled is None:
            return r1, R1, rep
        r1, R1, lag, sigma = settled
        # pairs, normals and contact points at the state
        lag = friction_lag(r1, R1, r, R, self.s, self.barrier, lag, held)
        for _ in range(o.max_lags):
            before = rep.iterations
            # no pair in contact: no friction, the energy's own Newton (shifted
            # where not positive definite) finishes, not the live one
            live = lag.pairs.shape[0] > 0
            r1, R1, sigma = self.newton(r1, R1, lam1, lag, sigma, rep, live=live,
                                        iterations=live_iterations)
            if rep.reason:
                break
            new = friction_lag(r1, R1, r, R, self.s, self.barrier, lag, held)
            if rep.iterations == before or (live and same_friction(lag, new, held, r.shape[0])):
                # an equilibrium with its own lag, normal forces its own
                rep.sigma, rep.friction, rep.lag_change, rep.live = sigma, new, 0.0, True
                return r1, R1, self._checked(r1, rep)
            lag = new
        else:
            rep.reason = f"no equilibrium with its own lag in {o.max_lags} live solves"
        if not fallback:
            rep.reason = f"{SLIP_LIVE} ({rep.reason})"
            return r1, R1, rep
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

    def _damped(self, r, R, r1, R1, lam1, sigma, rep):
        """The frictional step from the equilibrium ``(r, R)`` to ``lam1``
        whose static solve failed (``rep``: its report, the predicted
        ``(r1, R1)``), by pseudo-time steps at ``lam1``: each minimizes the
        energy with the friction lagged once at the last step's state
        (its pairs, normal forces and normals; solved to ``lag_rtol``) and the
        :class:`Proximal` term anchored there (module constants
        ``DAMPED_*``), an implicit step of a viscous flow whose friction
        acts against each pseudo-time step's slip; once the proximal
        force has fallen below ``DAMPED_REST`` of the force scale, the
        static step from that state (friction from it, failing where its
        live Newton takes more than ``DAMPED_LIVE`` iterations) ends it,
        or where it fails more pseudo-time steps.  Returns ``(r,
        R, StepReport)`` as :meth:`step`; ``damped`` counts the
        pseudo-time steps."""
        o = self.options
        ev = self.P.evaluate(r, R, lam1, tangent=False)
        scale = self.P.force_scale(ev)
        c0 = DAMPED_STIFFNESS * scale / self.radius
        c = c0
        first = rep.reason
        rep.reason = ""
        rest = DAMPED_REST * scale        # the proximal force to try the static step at
        a_r, a_R = r, R                   # the anchor: the last step's state
        y_r, y_R = r1, R1                 # where the next solve starts
        for _ in range(DAMPED_STEPS):
            # the friction at the anchor's pairs, normal forces and normals
            # (one lag: explicit in the normal forces, implicit in the slip)
            lag = friction_lag(a_r, a_R, a_r, a_R, self.s, self.barrier)
            sub = StepReport(converged=False, sigma=sigma)
            self.proximal = Proximal(a_r, a_R, c, self.radius)
            try:
                t_r, t_R, t_sigma = self.newton(y_r, y_R, lam1, lag, sigma, sub, o.lag_rtol)
            finally:
                self.proximal = None
            sub.lags = 1
            _absorb(rep, sub)
            if sub.reason:
                c *= DAMPED_GROWTH        # a shorter pseudo-time step
                y_r, y_R = a_r, a_R
                if c > c0 * DAMPED_GROWTH ** 4:
                    break
                continue
            y_r, y_R, sigma = t_r, t_R, t_sigma
            rep.damped += 1
            # the proximal force left at the step's state (on the free dofs)
            force = float(np.linalg.norm(proximal_work(
                y_r, y_R, Proximal(a_r, a_R, c, self.radius), False)[1][self.free]))
            logger.debug("pseudo-time step %d: c %.3g, %d iterations, %d lags, proximal "
                         "force %.3g of the force scale", rep.damped, c, sub.iterations,
                         sub.lags, force / scale)
            a_r, a_R = y_r, y_R
            if sub.iterations <= DAMPED_QUICK:
                c /= DAMPED_GROWTH        # a longer one
            if force <= rest:
                # near rest: the static step from here, friction from here;
                # failing fast where its live Newton fails (more
                # pseudo-time steps then, the flow slower: docs)
                fin = StepReport(converged=False, sigma=sigma)
                r2, R2, fin = self._frictional(a_r, a_R, a_r, a_R, lam1, sigma, fin,
                                               fallback=False, live_iterations=DAMPED_LIVE)
                _absorb(fin, rep, before=True)
                fin.damped, fin.slip = rep.damped, first
                if fin.converged:
                    return r2, R2, fin
                rep = fin
                rep.reason = ""
                rest = DAMPED_RETRY * force     # not again before the flow has slowed
        rep.reason = (f"{first}; then {rep.damped} pseudo-time steps found no equilibrium "
                      f"(last proximal stiffness {c:.3g})")
        return y_r, y_R, rep

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
        least, since = np.inf, 0          # the least relative change, lags since
        for k in range(o.max_lags):
            r1, R1, sigma = self.newton(r1, R1, lam1, lag, sigma, rep,
                                        None if final else rtol)
            rep.lags += 1
            if rep.reason:
                return None
            new = friction_lag(r1, R1, r, R, self.s, self.barrier, lag, held)
            change = lag_change(lag, new, r1.shape[0])
            rep.lag_change = change
            top = new.force.max(initial=0.0)
            if change <= tol * top:
                if final or not tight:
                    return r1, R1, lag, sigma
                final, lag = True, new
                continue
            # a fixed point iteration that has stopped contracting: the
            # step is cut (by the caller) now rather than after max_lags
            rel = change / top if top > 0 else np.inf
            least, since = (rel, 0) if rel < LAG_GAIN * least else (least, since + 1)
            if since >= LAG_STALL:
                rep.reason = (f"the friction lag stalled: no lag in the last {LAG_STALL} "
                              f"changed the normal forces by less than {LAG_GAIN:g} times "
                              f"the least change before ({least:.3g} of the largest force; "
                              f"{k + 1} solves)")
                return None
            lag = relax(new, lag)
        rep.reason = f"the friction lag did not settle in {o.max_lags} solves"
        return None


# -- Rod.solve(method="barrier") ---------------------------------------

def default_force(problem):
    """The barrier's default force at half its width: the dead loads'
    total size at load factor 1 (the sum of the nodal forces' lengths: a
    point force's size, a distributed load's total), at least ``EI / L^2``
    of the stiffer bending axis.  Touching pairs then stand off by a
    fraction of the width rather than at its edge (too stiff a barrier)
    or pressed to its log wall (too soft); measured on the plectoneme,
    docs/contact-solve.md."""
    rod = problem.rod
    ev = problem.evaluate(rod.r0, rod.R0, 1.0, tangent=False)
    loads = float(np.linalg.norm(ev.external.reshape(-1, 6)[:, :3], axis=1).sum())
    EI = max(rod.section.EI1, rod.section.EI2)
    return max(loads, EI / rod.length ** 2)


class BarrierResolution(UserWarning):
    """``method="barrier"`` on a mesh whose nodes are too far apart for the
    contact radius: the nodes' offset (``contact.barrier.node_offset``,
    ``3 a^2 / (8 eps)``) exceeds the barrier's width (docs/contact-solve.md)."""


class BarrierStepper:
    """The state of one :func:`solve_barrier`: the :class:`EnergySolve`
    of the rod with its contact replaced by the node barrier, the path's
    options, the result being built and the deadline -- what
    :func:`skfem_rod.solver.follow_path` steps (``advance``, ``keep``)."""

    def __init__(self, rod, opts, energy, own):
        import copy
        from .contact.search import arclength_period
        from .options import Deadline
        from .results import Result
        c = rod.contact
        if c.gamma_R > 0 and c.rotational_slip != "pivot":
            raise ValueError(f"rotational_slip = {c.rotational_slip!r} with gamma_R = "
                             f"{c.gamma_R!r}: method='barrier' has the rotational law on the "
                             "pivot about the contact normal only; enable_contact(..., "
                             "rotational_slip='pivot') (docs/contact-solve.md)")
        bare = copy.copy(rod)
        bare.contact = None
        P = Problem(bare)
        force = default_force(P) if own.barrier_force is None else own.barrier_force
        period = arclength_period(rod.mesh)
        if own.handles and period is not None:
            raise ValueError("handles=True: a closed rod has no ends to continue")
        ends = (rod.node("start"), rod.node("end")) if own.handles else ()
        barrier = Barrier.for_nodes(rod.mesh.s_nodes, c.radius, width=own.barrier_width,
                                    force=force, exclusion=c.exclusion, period=period,
                                    handles=ends)
        sampling = barrier.distance - 2 * c.radius       # the nodes' offset (node_offset)
        if sampling > barrier.width:
            warnings.warn(
                f"method='barrier' with {rod.mesh.n_elements} elements: the node spacing "
                f"{node_spacing(sampling, c.radius):.3g} against the contact radius "
                f"{c.radius:.3g} lets crossing strands stand off by up to "
                f"{sampling / c.radius:.3g} of the radius, more than the barrier's width "
                f"({barrier.width / c.radius:.3g}), and strands sliding along each other feel "
                f"the nodes as bumps; refine the mesh to a node spacing below "
                f"{node_spacing(barrier.width, c.radius):.3g}", BarrierResolution, stacklevel=4)
        self.solve = EnergySolve(bare, barrier, c.radius, mu=c.gamma_T,
                                 eps_v=own.slip_smoothing * c.radius, options=energy,
                                 problem=P, mu_R=c.gamma_R, eps_R=own.slip_smoothing)
        self.rod, self.opts = rod, opts
        self.result = Result(rod)
        self.deadline = Deadline(opts.time_limit)
        self.sigma = 0.0               # the tangent's shift the next step starts from
        self.calm = DAMPED_CALM          # steps converged since one failed
        #: the load factor and the report of the last solved step (the
        #: path's tangent and the inertia there: the next step's predictor)
        self.solved_at, self.solved = None, None

    def initial(self, r0, R0, friction=None):
        """Step 0: the equilibrium at load factor 0 from ``(r0, R0)`` (no
        iteration where it is one); ``friction``: the lag ``(r0, R0)`` was
        solved with (:meth:`recorded_friction`), its slips carried."""
        r, R, rep = self.solve.step(r0, R0, 0.0, 0.0, sigma=self.sigma, friction=friction)
        if rep.converged:
            self.sigma, self.solved_at, self.solved = rep.sigma, 0.0, rep
        return r, R, rep

    def recorded_friction(self, contact):
        """The friction lag a converged state was solved with, from its
        record ``contact`` (a :class:`~skfem_rod.results.ContactState`), to
        carry its slips into the next step; None where there is none: no
        friction, or a record of another solve's (the augmented
        Lagrangian's slave points: its friction state does not map onto
        node pairs) or of another rod's."""
        lag = None if contact is None else contact.lag
        if not self.solve.with_friction or lag is None:
            return None
        if lag.pairs.size and lag.pairs.max() >= self.rod.mesh.s_nodes.size:
            return None
        return lag

    def advance(self, r, R, lam, lam_new, prev):
        """The step ``lam -> lam_new`` from the equilibrium ``(r, R)``
        (``prev = (lam, r, R)`` the one before: the secant predictor,
        scaled to this step's size).  Returns ``(r, R, StepReport)``."""
        previous, ratio = None, 1.0
        if self.opts.predictor == "secant" and prev is not None and lam != prev[0]:
            previous, ratio = (prev[1], prev[2]), (lam_new - lam) / (lam - prev[0])
        # the path's tangent where the last solved step left one (frictionless):
        # the predictor quadratic (a predictor on at all: "secant")
        rate, stable = None, False
        if self.opts.predictor == "secant" and self.solved_at == lam:
            rate, stable = self.solved.rate, self.solved.negative == 0
        # where the static solve finds no path through a slip: the step
        # fails at once and is cut (a half step goes through statically in
        # 10-20 iterations where the fallback's lag took 300-700 to stall,
        # measured); pseudo-time steps through it only in the DAMPED_CALM
        # steps after a failed one
        # the friction the last solved step converged with: its slips
        # carried into this step (the friction's memory, carry_slip)
        friction = self.solved.friction if self.solved_at == lam else None
        r1, R1, rep = self.solve.step(r, R, lam, lam_new - lam, previous, self.sigma, ratio,
                                      "damped" if self.calm < DAMPED_CALM else "cut", rate,
                                      stable, friction)
        if rep.converged:
            self.sigma, self.solved_at, self.solved = rep.sigma, lam_new, rep
            self.calm += 1
        else:
            self.calm = 0
        return r1, R1, rep

    def keep(self, lam, r, R, rep, t, callback):
        """Record a converged step: its reactions from the whole
        out-of-balance force (rod, barrier, friction), its contact pairs as
        a :class:`skfem_rod.results.ContactState`."""
        from dataclasses import replace
        from .problem import Report
        G = rep.out_of_balance                 # as the step's last solve evaluated it
        radius = self.solve.radius
        report = Report(True, iterations=rep.iterations, history=list(rep.history),
                        evaluation=replace(rep.evaluation, residual=G),
                        min_distance=rep.true_distance, floor=rep.floor,
                        penetration=max(0.0, 2 * radius - rep.true_distance))
        self.result.append(lam, r, R, report, time=t, contact=self.contact_state(r, R, rep))
        if rep.negative:
            self.result.log.append(
                f"step to lam={lam:.6g}: an unstable equilibrium, a saddle of the energy "
                f"({rep.negative} negative eigenvalue(s) of its Hessian; e.g. held by a "
                f"symmetry that no load breaks)")
        if rep.damped:
            self.result.log.append(
                f"step to lam={lam:.6g}: {rep.damped} pseudo-time step(s) through a slip (the "
                f"static solve found no path: {rep.slip})")
        if rep.fallbacks:
            self.result.log.append(
                f"step to lam={lam:.6g}: the Newton at the state's own normal forces failed "
                f"({rep.fallbacks}x); the step holds the friction of its lag settled to "
                f"lag_tol={self.solve.options.lag_tol:g} (Coulomb's law to that)")
        if callback is not None:
            callback(self.result, len(self.result.steps) - 1)

    def contact_state(self, r, R, rep):
        """The node pairs in contact as a :class:`ContactState`: one row
        per pair (``s`` node i, ``s_bar`` node j, the normal from j to i),
        its point force in ``force`` with ``weight`` 1, the barrier's
        contact distance in ``offset`` (``2 eps + offset``), the friction
        force on node j's section (the master's) and the slip of i
        relative to j, and the rotational law's couple on j and the pivot
        of i relative to j about the normal (``slip_R``, along it)."""
        from .contact.friction import OPEN, SLIP, STICK
        from .results import ContactState
        nc = self.solve.contact(r, R, rep)
        s, radius = self.rod.mesh.s_nodes, self.solve.radius
        k = nc.force.size
        offset = np.full(k, self.solve.barrier.distance - 2 * radius)
        st = ContactState(
            s=s[nc.pairs[:, 0]], s_bar=s[nc.pairs[:, 1]], gap=2 * radius + offset - nc.distance,
            force=nc.force, normal=nc.normal, weight=np.ones(k),
            penetration=max(0.0, 2 * radius - rep.true_distance), uzawa=0,
            uzawa_converged=True, newton_total=rep.iterations, candidates=nc.candidates,
            min_distance=rep.true_distance, offset=offset)
        S = self.solve
        if S.with_friction:
            st.force_T, st.slip_T, st.lag = -nc.friction, nc.slip, rep.friction
            st.state_T = (np.where(nc.sliding, SLIP, STICK) if S.mu > 0
                          else np.full(k, OPEN)).astype(int)
            # the rotational law's couple on the master section, the pivot of
            # the slave's relative to it about the normal
            st.force_R, st.slip_R = -nc.couple, nc.pivot[:, None] * nc.normal
            st.state_R = (np.where(nc.pivoting, SLIP, STICK) if S.mu_R > 0
                          else np.full(k, OPEN)).astype(int)
            st.dissipation = float(np.sum(st.force_T * st.slip_T)
                                   + np.sum(st.force_R * st.slip_R))
        return st


def solve_barrier(rod, n_steps=1, path=None, callback=None, start=None, **kwargs):
    """``Rod.solve(method="barrier")``: the load path of
    :func:`skfem_rod.solver.follow_path` (step cutting, the deadline), each
    step solved by :meth:`EnergySolve.step` with the rod's contact
    (radius, exclusion, ``gamma_T``) replaced by the node barrier.  Options
    (:func:`skfem_rod.options.barrier_specs`): the path's
    (:data:`skfem_rod.options.BARRIER_PATH`), the fields of
    :class:`~skfem_rod.options.EnergyOptions` and of
    :class:`~skfem_rod.options.BarrierOptions` (``barrier_force`` None:
    :func:`default_force`).  ``start``: a Result (its last step; with
    friction its pairs' slips carried into step 0,
    :meth:`BarrierStepper.recorded_friction`) or ``(r, R)`` (friction from
    zero slips).  Returns a :class:`skfem_rod.results.Result`."""
    from .options import split_barrier_options
    from .results import Result
    from .solver import follow_path, load_path, start_state
    if rod.contact is None:
        raise ValueError("method='barrier' is a contact solve: switch contact on with "
                         "rod.enable_contact(...) (its radius, exclusion and gamma_T are used)")
    rod.check_steps(n_steps)
    times, values = load_path(path)
    opts, energy, own = split_barrier_options(kwargs)
    rod.check_constraints()
    S = BarrierStepper(rod, opts, energy, own)
    r0, R0 = (rod.r0, rod.R0) if start is None else start_state(rod, start)
    r0, R0 = np.array(r0, dtype=float), np.array(R0, dtype=float)
    # restarted from a Result: its last step's friction carried (the memory)
    friction = S.recorded_friction(start.steps[-1].contact) \
        if isinstance(start, Result) else None
    r, R, rep = S.initial(r0, R0, friction)
    if not rep.converged:
        S.result.finish(False, f"no equilibrium at load factor 0: {rep.reason}")
        return S.result
    S.keep(0.0, r, R, rep, 0.0, callback)
    return follow_path(S, r, R, n_steps, times, values, callback)
