r"""The discrete equilibrium problem of a rod: the one object every loop uses.

::

    state (r, R) --kinematics--> internal work (scikit-fem forms, assembly.py)
                                + loads (loads.py) + contact/friction (contact/)
                 --> Evaluation: residual G(y, lam), tangent K, f_ext, parts
                 --> Newton (newton.py) / AL loop (augmented.py)
                 --> update y (+) dy  --> state

:class:`Problem` holds what does not change during a solve (mesh, supports,
dof basis, slave points) and the solve's memory that every loop shares: the
contact and friction :class:`Multipliers` (with their adaptive penalty
factors; copied and put back as one object) and the last converged state
the friction slips are measured from (:meth:`Problem.commit`).  The loops
above it -- load stepping (solver.py), pseudo-arclength continuation
(continuation.py), stability paths (stability.py) and the gradient flow
(relax.py) -- differ only in how they drive :func:`skfem_rod.newton.newton`
and :func:`skfem_rod.augmented.augmented_lagrangian`.

Configuration update (the one place it is written): positions add, rotations
are updated by spatial spins, ``R <- expm(w) R`` (:func:`skfem_rod.rotations.rotate`);
the inverse, the increment between two states, is
:meth:`Problem.increment` (``log(R R_ref^T)`` per node).
"""
import time
from collections import defaultdict
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial import cKDTree

from .assembly import InternalWork, internal_work, shape_operator
from .loads import distributed_vector, point_loads
from .kinematics import PSI_MAX, REF_NODE, ElementRotationError
from .rotations import logm, rotate, spin_between


@dataclass
class ContactEvaluation:
    """Contact part of an :class:`Evaluation`: the slave/master pairs found,
    the normal force per pair (``f_N``, per unit length) and the contact
    energy; ``friction`` holds the friction figures
    (:class:`skfem_rod.contact.friction_assembly.FrictionOutput`) when
    friction is on."""
    pairs: object
    fN: np.ndarray
    energy: float
    friction: object = None
    crossing: object = None          # CrossingPairs (option crossing)
    crossing_fN: np.ndarray = None   # point forces of the crossing pairs
    #: the gaps the law acted on, ``d = 2 eps + offset - distance`` per
    #: slave pair (``Multipliers.offset``) and per crossing pair
    gap: np.ndarray = None
    crossing_gap: np.ndarray = None
    offset: np.ndarray = None        # per slave pair
    crossing_offset: np.ndarray = None   # per crossing pair
    #: ``(m, n)`` the crossing pairs' weight derivatives ``dw/dq`` on the
    #: contact curve's dofs (with the tangent, inside
    #: :meth:`Problem.crossing_unknowns`; :func:`crossing_work`), else None
    crossing_dw: object = None
    #: the crossing pairs' friction figures (friction and crossing contact
    #: on; :class:`skfem_rod.contact.friction_assembly.FrictionOutput`,
    #: ``slave`` = the pair's index in ``crossing``)
    crossing_friction: object = None

    def violations(self):
        """The contact tolerances' measures, ``(penetration, opened)``: the
        largest penetration and the largest open gap under force (a
        multiplier left over from a higher load pushes apart), over the
        slave pairs and the crossing pairs.  A crossing pair's penetration
        counts with its weight ``w``: below full weight the Uzawa update's
        fixed point ``lambda = w [lambda + d / mu]_+`` leaves the pair a gap,
        the share ``1 - w`` of the contact being the Gauss pairs'
        (docs/crossing-contact.md, 4); the true distance is judged after
        the loop (:func:`skfem_rod.augmented.finish`)."""
        d = self.gap
        pen = float(d.max(initial=0.0))
        opened = float(np.max(-d[self.fN > 0], initial=0.0))
        if self.crossing is not None:                # point pairs of crossing strands
            dc = self.crossing_gap
            pen = max(pen, float((self.crossing.weight * dc).max(initial=0.0)))
            opened = max(opened, float(np.max(-dc[self.crossing_fN > 0], initial=0.0)))
        return pen, opened


@dataclass
class Evaluation:
    """Residual and tangent of a :class:`Problem` at a state and load factor.

    Vectors and the tangent are in the problem's dof basis (the supports'
    local bases where given, :meth:`skfem_rod.Rod.support_basis`)."""
    residual: np.ndarray          # G = internal (+ contact) - external
    tangent: object               # CSC dG/dy, or None (tangent=False)
    external: np.ndarray          # f_ext
    internal: InternalWork        # internal work (energy, forces, tangent)
    contact: ContactEvaluation = None


@dataclass
class Multipliers:
    """Augmented-Lagrangian multipliers of contact and friction per slave
    point and the adaptive penalty factors (:mod:`skfem_rod.augmented`).

    The normal compliance at slave ``i`` is ``penalty / penalty_scale[i]``;
    the friction compliances are ``mu_T / friction_scale`` and
    ``mu_R / friction_scale``; the crossing pairs' compliance is
    ``crossing_penalty / crossing_scale``.  :meth:`copy` and assignment back to
    ``Problem.multipliers`` are the save and restore of a rejected step."""
    normal: np.ndarray
    penalty_scale: np.ndarray
    tangential: np.ndarray = None     # (n, 3) with friction on
    rotational: np.ndarray = None     # (n, 3) with friction on
    friction_scale: float = 1.0
    #: the crossing pairs' adaptive penalty factor, one for all of them
    #: (:func:`skfem_rod.augmented.adapt_crossing_penalty`)
    crossing_scale: float = 1.0
    #: crossing pairs (option ``crossing``): element-pair keys and multipliers
    crossing_key: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    crossing: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: ``(k, 2)`` the places ``(s, s_bar)`` where the held crossing pairs
    #: followed their minima at the last evaluation (None: their keys'
    #: places).  Part of the saved state: a restored copy follows from the
    #: places of the state it was saved at.  Kept beside the multipliers
    #: before, and reset to the keys' places by every restore, the places
    #: made a rejected damped step change the residual at the accepted
    #: state it fell back to: a minimum that had moved more than its carry
    #: radius since the last multiplier update was no longer followed, its
    #: force fell from 31.5 to 0.003 (the plectoneme's winding at 1.95
    #: turns with ``contact_solve="newton"``, where no Uzawa update re-keys
    #: the pairs) and the next damped step started from a residual of 36
    #: that no time step could take: dt halved to 1e-8
    crossing_places: np.ndarray = None
    #: ``(n,)`` the gap offsets of the slave points (:mod:`skfem_rod.augmented`,
    #: :func:`~skfem_rod.augmented.adjust_offsets`): slave ``i`` is in contact
    #: at the distance ``2 eps + offset[i]``, where the centrelines dip
    #: below ``2 eps`` between slave points; 0 elsewhere
    offset: np.ndarray = None
    #: the same per crossing pair, beside ``crossing`` (carried by place)
    crossing_offset: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: ``(k, 3)`` the crossing pairs' tangential friction multipliers,
    #: beside ``crossing`` (carried by place; at the last converged state,
    #: pushed forward as the slave points' are)
    crossing_friction: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    @classmethod
    def zeros(cls, n, friction):
        return cls(normal=np.zeros(n), penalty_scale=np.ones(n),
                   tangential=np.zeros((n, 3)) if friction else None,
                   rotational=np.zeros((n, 3)) if friction else None,
                   offset=np.zeros(n))

    def copy(self):
        c = lambda a: None if a is None else a.copy()        # noqa: E731
        return replace(self, normal=c(self.normal), penalty_scale=c(self.penalty_scale),
                       tangential=c(self.tangential), rotational=c(self.rotational),
                       crossing_key=c(self.crossing_key), crossing=c(self.crossing),
                       crossing_places=c(self.crossing_places), offset=c(self.offset),
                       crossing_offset=c(self.crossing_offset),
                       crossing_friction=c(self.crossing_friction))

    def held_crossing(self):
        """The ``held`` argument of
        :func:`skfem_rod.contact.crossing.crossing_pairs`: keys, multipliers
        and the places to follow the held pairs' minima from (set to the
        keys' places on the first call after new keys, so that
        :meth:`follow_crossing` can record into them)."""
        if self.crossing_places is None and self.crossing_key.ndim == 2 \
                and self.crossing_key.shape[0]:
            self.crossing_places = np.asarray(self.crossing_key, float)[:, :2].copy()
        return self.crossing_key, self.crossing, self.crossing_places

    def follow_crossing(self, pairs):
        """Record where the held pairs of ``pairs`` (a
        :class:`~skfem_rod.contact.crossing.CrossingPairs`) act or follow
        their minima: the next evaluation looks for each from there."""
        if self.crossing_places is None or pairs.size == 0:
            return
        idx = pairs.key[:, 4].astype(np.int64)
        ok = idx >= 0
        self.crossing_places[idx[ok]] = pairs.key[ok, :2]

    def crossing_offsets(self, key):
        """The gap offsets of crossing pairs with the keys ``key``, carried
        by place from the held keys (0 for new places)."""
        return self._by_place(self.crossing_offset, key)

    def crossing_frictions(self, key):
        """The friction multipliers ``(k, 3)`` of crossing pairs with the
        keys ``key``, carried by place from the held keys (0 for new
        places)."""
        return self._by_place(self.crossing_friction, key)

    def _by_place(self, values, key):
        """Per-pair ``values`` of the held keys carried by place to the keys
        ``key`` (:func:`skfem_rod.contact.crossing.carry`); zeros where they
        do not belong to the held keys (set before the keys changed)."""
        from .contact.crossing import carry
        if values.shape[0] != len(self.crossing_key):
            return np.zeros((len(key),) + values.shape[1:])
        return carry(self.crossing_key, values, key)

    def rekey_crossing(self, key, lam, offset=None, friction=None):
        """New crossing keys and multipliers (a multiplier update) with
        their gap offsets and friction multipliers (default: carried from
        the old keys by place): the held pairs follow from the new keys'
        places."""
        if offset is None:
            offset = self.crossing_offsets(key)
        if friction is None:
            friction = self.crossing_frictions(key)
        self.crossing_key, self.crossing, self.crossing_places = key, lam, None
        self.crossing_offset, self.crossing_friction = offset, friction

    def nominal_penalty(self):
        """The same multipliers at the nominal penalties (factors 1)."""
        return replace(self.copy(), penalty_scale=np.ones_like(self.penalty_scale),
                       friction_scale=1.0, crossing_scale=1.0)


class SearchMemory(NamedTuple):
    """What the contact search of one evaluation leaves for the next
    (:meth:`Problem.search_memory`): the master element of each slave
    point (``-1``: none; kept by the next search within ``KEEP_MASTER`` of
    the contact tolerance, contact/search.py) and the places where the held
    crossing pairs followed their minima (``Multipliers.crossing_places``;
    None: the held keys' own places)."""
    last_master: np.ndarray
    crossing_places: np.ndarray = None


@dataclass
class Viscous:
    """Viscous term ``c W (y (-) y_ref)`` of a proximal (gradient-flow) step
    or a damped step (:meth:`Problem.damped`); ``W`` a diagonal metric per
    dof."""
    c: float
    W: np.ndarray
    r_ref: np.ndarray
    R_ref: np.ndarray


class Problem:
    """Residual, tangent and shared state of the equilibrium of ``rod``.

    Parameters
    ----------
    rod : Rod

    Attributes
    ----------
    free, fixed : boolean masks of the dofs (supports).
    multipliers : :class:`Multipliers` or None (contact off).
    reference : ``(r, R)`` the last converged state (friction slips are
        measured from it); None without friction.
    viscous : :class:`Viscous` or None; added to the residual when set.

    Examples
    --------
    >>> from skfem_rod import Rod, Section, geometry
    >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
    >>> p = Problem(rod.clamp("start"))
    >>> ev = p.evaluate(rod.r0, rod.R0, 0.0)
    >>> float(abs(ev.residual).max()), ev.tangent.shape
    (0.0, (78, 78))
    """

    def __init__(self, rod):
        self.rod = rod
        self.mesh = rod.mesh
        self.Z = shape_operator(rod.mesh)
        self.f_dist = distributed_vector(rod.mesh, rod.distributed)
        self.fixed = rod.fixed_dofs()
        self.free = ~self.fixed
        #: dofs held in a position correction (:func:`skfem_rod.newton.newton`):
        #: every spin and the supported positions
        self.not_position = self.fixed | (np.arange(self.mesh.n_dofs) % 6 >= 3)
        #: accumulated wall time per phase (s) and call counts, for benchmarks
        self.timers = defaultdict(float)
        self.calls = defaultdict(int)
        self.viscous = None
        #: the friction output carries the multipliers' Jacobian (inside
        #: :meth:`friction_unknowns`: the generalized Newton)
        self.friction_jacobian = False
        self.crossing_jacobian = False
        #: what Problem.factor derives from the tangent's pattern, one per
        #: mask of held dofs (the supports', and the position correction's
        #: with every spin held: Newton alternates them)
        self.factor_patterns = {}
        #: dof basis of the supports (sparse orthogonal), None: spatial axes
        self.T = rod.dof_basis()
        self.contact = rod.contact
        self.friction = self.contact is not None and self.contact.friction
        self.multipliers = None
        self.reference = None
        self.contact_curve = None
        if self.contact is not None:
            from .contact.assembly import ContactPatterns
            from .contact.curve import ContactCurve
            from .contact.search import slave_points
            #: the curve the contact acts on (contact/curve.py): None, the
            #: rod's centreline; else a ContactCurve (option curve="smooth")
            self.contact_curve = ContactCurve(rod.mesh) if self.contact.curve == "smooth" \
                else None
            self.slaves = slave_points(rod.mesh, self.contact.n_slave)
            #: the sparse patterns of the contact tangents, kept between evaluations
            self.contact_patterns = ContactPatterns()
            #: the band ordering of the generalized Newton's bordered matrix
            #: (skfem_rod.nonsmooth), kept while its pattern stays
            self.bordered_pattern = FactorPattern(band=True, symmetric=False)
            #: the master element of each slave at the last evaluation (-1:
            #: none), kept by the next search within KEEP_MASTER of the
            #: contact tolerance (contact/search.py: kinks at nodes)
            self.last_master = np.full(self.slaves.s.size, -1)
            from .contact.search import NeighbourList
            #: the broad phase's pairs, kept while no node moves more than
            #: NEIGHBOUR_SKIN contact radii (contact/search.py: same answer)
            self.neighbours = NeighbourList(skin=NEIGHBOUR_SKIN * self.contact.radius)
            self.multipliers = Multipliers.zeros(self.slaves.s.size, self.friction)
            #: the normal penalty factors a step's Uzawa loop ended with,
            #: where the next step's loop starts (option penalty_memory;
            #: None: at the nominal penalty)
            self.penalty_start = None
            if self.friction:
                self.reference = (rod.r0.copy(), rod.R0.copy())

    # -- state -------------------------------------------------------------
    def search_memory(self):
        """A copy of the contact search's memory (:class:`SearchMemory`;
        None without contact).

        Every evaluation with contact on updates it: the slaves' master
        elements and the held crossing pairs' places.  So the residual at a
        state depends on the evaluation before it.  A trial that is refused
        must leave the memory as the accepted state's evaluation left it
        (:meth:`restore_search`): else the next trials from that state are
        evaluated from the refused trial's masters and places, and the
        residual jumps at the state.  Measured in the plectoneme (100
        elements, the step to 3.125 turns, a Levenberg-Marquardt flow at
        held multipliers): the residual norm was 50.4 at the flow's state
        and 14.6 a move of 1e-15 from it, the jump 25 at three dofs of one
        ply; the flow refused 20 steps in a row and failed there, and the
        proximal steps after it crawled until the time limit."""
        if self.contact is None:
            return None
        places = self.multipliers.crossing_places
        return SearchMemory(self.last_master.copy(),
                            None if places is None else places.copy())

    def restore_search(self, memory):
        """Put the contact search's memory back to ``memory`` (from
        :meth:`search_memory`; None: nothing to do)."""
        if memory is None:
            return
        self.last_master = memory.last_master.copy()
        places = memory.crossing_places
        self.multipliers.crossing_places = None if places is None else places.copy()

    def to_spatial(self, dy):
        """A dof vector (update, mode, residual) from the supports' bases to
        the spatial axes."""
        return dy if self.T is None else self.T @ dy

    def to_basis(self, dy):
        """A spatial dof vector to the supports' bases."""
        return dy if self.T is None else self.T.T @ dy

    def update(self, r, R, dy, alpha=1.0):
        """``y (+) alpha dy``: ``r + alpha dr``, ``expm(alpha dw) R`` per node
        (``dy`` in the dof basis).

        Raises :class:`~skfem_rod.kinematics.ElementRotationError` when the
        update would carry a node's rotation relative to its element's
        reference node through the edge of the element chart (angle ``pi``)
        on the way: the local rotation vector would wrap and the element
        would silently lose a full turn of twist (:func:`check_no_wrap`)."""
        d = alpha * self.to_spatial(dy).reshape(-1, 6)
        check_no_wrap(self.mesh, R, d[:, 3:])
        return r + d[:, :3], rotate(R, d[:, 3:])

    @contextmanager
    def damped(self, c, W, r_ref, R_ref):
        """The viscous term ``c W (y (-) y_ref)`` (:class:`Viscous`) on in
        the evaluations inside the ``with`` block (a proximal step of the
        gradient flow, a damped step of the pseudo-dynamics), off after."""
        self.viscous = Viscous(c, W, r_ref, R_ref)
        try:
            yield self
        finally:
            self.viscous = None

    @contextmanager
    def friction_unknowns(self):
        """Evaluations inside the ``with`` block compute the Jacobian of the
        friction multipliers' update (the generalized Newton solves for
        them, :mod:`skfem_rod.nonsmooth`); as before after."""
        before, self.friction_jacobian = self.friction_jacobian, True
        try:
            yield self
        finally:
            self.friction_jacobian = before

    def crossing_reach(self):
        """How far apart the strands may be at a crossing pair of an
        evaluation: ``2 eps + mu_c max(lambda_c) + max(offset)`` (beyond, the
        point law ``[d + mu_c lambda]_+`` gives no force at any of the
        carried multipliers and offsets) plus :data:`CROSSING_MARGIN` ``eps``.

        A pair beyond it would add nothing to the residual or the tangent,
        and its multiplier, were it carried, is back by place when it comes
        within reach (:func:`skfem_rod.contact.crossing.carry`).  (One path
        can differ: a held pair whose minimum moved beyond the reach within
        a solve is not found, and may follow another minimum within its
        carry radius, taking its multiplier there; the loop's tolerances
        judge the state either way.)  Before, the
        reach was ``3 eps`` at any multiplier: in the plectoneme's snaps 217
        element pairs on average were solved for their minima per
        evaluation, against 55 now, for the same pairs carrying force (every
        recorded state to 1.25 turns the same, bit for bit;
        benchmarks/RESULTS_plectoneme.md)."""
        c, m = self.contact, self.multipliers
        lam = float(np.max(m.crossing, initial=0.0))
        return (2.0 * c.radius + self.crossing_compliance() * lam
                + float(np.max(m.crossing_offset, initial=0.0)) + CROSSING_MARGIN * c.radius)

    def crossing_compliance(self):
        """The crossing pairs' compliance ``mu_c``: the contact option
        ``crossing_penalty`` at the multipliers' adaptive factor."""
        return self.contact.crossing_penalty / self.multipliers.crossing_scale

    @contextmanager
    def crossing_unknowns(self):
        """Evaluations inside the ``with`` block return the crossing pairs'
        weight derivatives (``ContactEvaluation.crossing_dw``: the
        generalized Newton solves for their multipliers); as before after."""
        before, self.crossing_jacobian = self.crossing_jacobian, True
        try:
            yield self
        finally:
            self.crossing_jacobian = before

    def push(self, r, R, mode, size):
        """``(r, R)`` moved along ``mode`` (dof basis; e.g. an unstable mode)
        so that the largest nodal move is ``size`` and the largest nodal
        rotation 0.1 rad; with contact, halved (at most
        :data:`PUSH_HALVINGS` times) while it would make the strands'
        true overlap larger than it was and than
        :data:`skfem_rod.contact.OVERLAP_FAIL` eps, the most a converged
        state may have.
        (A mode of a state in contact can carry strands into each other: in
        the frictional plectoneme pushes of several radii left them
        overlapping by 0.58 eps, and the damped steps from there failed at
        every step size.)"""
        m = self.to_spatial(mode).reshape(-1, 6)
        a = min(size / max(np.abs(m[:, :3]).max(), 1e-300),
                0.1 / max(np.abs(m[:, 3:]).max(), 1e-300))
        r1, R1 = self.update(r, R, mode, a)
        c = self.contact
        if c is None:
            return r1, R1
        from .contact import OVERLAP_FAIL
        from .contact.crossing import min_distance
        overlap = lambda x: 2 * c.radius - min_distance(self.mesh, x, c.radius,    # noqa: E731
                                                        c.exclusion).distance
        allowed = max(overlap(r), OVERLAP_FAIL * c.radius)
        for _ in range(PUSH_HALVINGS):
            if overlap(r1) <= allowed:
                break
            a *= 0.5
            r1, R1 = self.update(r, R, mode, a)
        return r1, R1

    @property
    def push_size(self):
        """The largest nodal move of a push off a saddle: half the contact
        radius, or 1e-3 of the rod length without contact."""
        return 0.5 * self.contact.radius if self.contact is not None else 1e-3 * self.rod.length

    def increment(self, r, R, r_ref, R_ref):
        """``y (-) y_ref`` in the dof basis: the ``dy`` with ``y = y_ref (+) dy``."""
        d = np.concatenate([r - r_ref, spin_between(R, R_ref)], axis=1).ravel()
        return self.to_basis(d)

    def commit(self, r, R, evaluation=None):
        """Record a converged state (and its ``evaluation``): the next
        step's slips are measured from it, and the friction multipliers,
        carried within a step at the last converged state (pulled back with
        the sections' incremental rotations, ``push_forward``), become the
        friction forces of the accepted state (friction on; nothing to do
        otherwise)."""
        if not self.friction:
            return
        self.reference = (r.copy(), R.copy())
        fr = None if evaluation is None or evaluation.contact is None \
            else evaluation.contact.friction
        if fr is not None:
            m = self.multipliers
            m.tangential = np.zeros_like(m.tangential)
            m.rotational = np.zeros_like(m.rotational)
            m.tangential[fr.slave] = fr.force_T
            m.rotational[fr.slave] = fr.force_R
        cf = None if evaluation is None or evaluation.contact is None \
            else evaluation.contact.crossing_friction
        if cf is not None:
            # the pairs that follow a held key take their forces to it
            m = self.multipliers
            m.crossing_friction = np.zeros((len(m.crossing_key), 3))
            held = evaluation.contact.crossing.key[cf.slave, 4].astype(np.int64)
            ok = (held >= 0) & (held < len(m.crossing_key))
            m.crossing_friction[held[ok]] = cf.force_T[ok]

    def prescribed(self, dlam):
        """Increment of the constrained dofs for a load-factor change
        ``dlam`` (prescribed motions scale with the load factor), in the dof
        basis; zero on the free dofs."""
        d = np.zeros(self.mesh.n_dofs)
        for n, sup in self.rod.supports.items():
            d[6 * n:6 * n + 3] = np.where(sup.position, dlam * sup.displacement, 0.0)
            rot = sup.rotation_vector if sup.basis is None else sup.basis.T @ sup.rotation_vector
            d[6 * n + 3:6 * n + 6] = np.where(sup.rotation, dlam * rot, 0.0)
        return d

    def load_rate(self, R):
        """``d f_ext / d lam`` at rotations ``R`` (loads are affine in the
        load factor at fixed rotations), in the dof basis."""
        rod = self.rod
        f1 = point_loads(self.mesh, rod.point_loads, R, rod.R0, 1.0)[0]
        f0 = point_loads(self.mesh, rod.point_loads, R, rod.R0, 0.0)[0]
        return self.to_basis(self.f_dist + f1 - f0)

    # -- evaluation --------------------------------------------------------
    def evaluate(self, r, R, lam, tangent=True, friction=None, frozen=False, stiffen=1.0):
        """:class:`Evaluation` at ``(r, R)`` and load factor ``lam``;
        ``friction=False`` leaves the friction work out (default: as the
        problem has it, :attr:`friction`); ``frozen``: the crossing pairs'
        tangent at frozen weights (no weight derivative,
        :func:`skfem_rod.contact.crossing.crossing_work`); ``stiffen``: the
        active gaps' stiffness (``df_N / d gap``) times this in the tangent,
        the forces unchanged (the constrained stability test,
        :meth:`free_tangent`)."""
        rod = self.rod
        t0 = time.perf_counter()
        iw = internal_work(self.mesh, r, R, rod.eps0, rod.C, tangent=tangent, Z=self.Z)
        self.timers["internal_assembly"] += time.perf_counter() - t0
        self.calls["evaluate"] += 1
        fp, Kp = point_loads(self.mesh, rod.point_loads, R, rod.R0, lam)
        f_ext = lam * self.f_dist + fp
        res = iw.force - f_ext
        K = iw.matrix
        v = self.viscous
        if tangent and v is not None:        # into the internal pattern's diagonal
            K = self.mesh.add_diagonal(K, v.c * v.W)
        if tangent and Kp is not None:
            K = K + Kp
        ce = None
        if self.contact is not None:
            ce, fc, Kc = self._contact(r, R, tangent, friction, frozen, stiffen)
            res = res + fc
            if tangent:
                K = K + Kc
        if v is not None:
            res = res + v.c * v.W * np.concatenate(
                [r - v.r_ref, spin_between(R, v.R_ref)], axis=1).ravel()
        if self.T is not None:
            T = self.T
            res, f_ext = T.T @ res, T.T @ f_ext
            if tangent:
                K = T.T @ K @ T
        if tangent:
            K = K.tocsc()
        return Evaluation(residual=res, tangent=K, external=f_ext, internal=iw, contact=ce)

    def _contact(self, r, R, tangent, friction=None, frozen=False, stiffen=1.0):
        """Search, normal contact work and (``friction``, default
        :attr:`friction`) friction work, on the contact curve (the rod's
        centreline, or the smooth curve of :attr:`contact_curve`, pulled
        back to the rod's dofs)."""
        friction = self.friction if friction is None else friction
        cc = self.contact_curve
        if cc is None:
            return self._contact_on(self.mesh, r, R, self.reference, tangent, friction, frozen,
                                    stiffen)
        ref = None if self.reference is None else (cc.positions(self.reference[0]),
                                                   cc.rotations(self.reference[1]))
        ce, force, K = self._contact_on(cc.mesh, cc.positions(r), cc.rotations(R), ref,
                                        tangent, friction, frozen, stiffen)
        return ce, cc.force(force), (cc.tangent(K) if tangent else None)

    def _contact_on(self, mesh, r, R, reference, tangent, friction, frozen=False, stiffen=1.0):
        """Contact work on the curve of ``mesh`` at nodal ``(r, R)``, with
        the friction work when ``friction`` (slips measured from
        ``reference``); ``frozen``: crossing weights held fixed in the
        tangent."""
        from .contact.assembly import contact_work
        from .contact.search import Preference, search
        c, m, tm = self.contact, self.multipliers, self.timers
        mu = c.penalty / m.penalty_scale                   # per slave
        reach = 2 * c.radius + (mu * m.normal).max(initial=0.0) + c.margin \
            + m.offset.max(initial=0.0)
        t0 = time.perf_counter()
        pairs = search(mesh, r, self.slaves, reach, c.exclusion,
                       prefer=Preference(self.last_master, KEEP_MASTER * c.tolerance * c.radius),
                       neighbours=self.neighbours)
        self.last_master = np.full_like(self.last_master, -1)
        self.last_master[pairs.slave] = pairs.m_elem
        t1 = time.perf_counter()
        mu = mu[pairs.slave]
        # the contact radius of each pair, raised by half its slave's gap
        # offset (augmented.adjust_offsets): the gap is 2 eps + offset - l
        offset = m.offset[pairs.slave]
        radius = c.radius + 0.5 * offset
        energy, force, K, fN = contact_work(mesh, r, pairs, m.normal, mu, radius,
                                            tangent, cache=self.contact_patterns.normal,
                                            stiffen=stiffen)
        t2 = time.perf_counter()
        tm["contact_search"] += t1 - t0
        tm["contact_assembly"] += t2 - t1
        fr = None
        if friction:
            from .contact.friction_assembly import friction_work
            from .contact.law import NormalLaw
            from .contact.slip import SlipState
            r_n, R_n = reference
            params = self.friction_params()
            state = SlipState(r, R, r_n, R_n, m.tangential, m.rotational)
            ff, Kf, fr = friction_work(mesh, state, pairs, NormalLaw(m.normal, mu, radius),
                                       params, tangent=tangent, K_normal=K,
                                       cache=self.contact_patterns.friction,
                                       multiplier_jacobian=self.friction_jacobian)
            force = force + ff
            if tangent:
                K = Kf                                  # includes the normal tangent
            tm["friction_assembly"] += time.perf_counter() - t2
        ce = ContactEvaluation(pairs=pairs, fN=fN, energy=energy, friction=fr,
                               gap=2.0 * radius - pairs.distance, offset=offset)
        if c.crossing:
            from .contact.crossing import carry, crossing_pairs, crossing_work
            t3 = time.perf_counter()
            cp = crossing_pairs(mesh, r, c.radius, c.exclusion, self.crossing_reach(),
                                threshold=c.crossing_threshold(),
                                held=m.held_crossing())
            m.follow_crossing(cp)
            lam = carry(m.crossing_key, m.crossing, cp.key)
            off = m.crossing_offsets(cp.key)
            # friction at the crossing pairs: the tangential law only
            # (ContactOptions.crossing_friction_params)
            cfric = bool(friction and c.crossing_friction and c.gamma_T > 0)
            rows = self.crossing_jacobian or (cfric and not frozen)
            out = crossing_work(mesh, r, cp, lam, self.crossing_compliance(), c.radius, tangent,
                                fade=not frozen, offset=off, weight_rows=tangent and rows,
                                stiffen=stiffen)
            ec, fc, Kc, fNc = out[:4]
            force = force + fc
            if tangent:
                K = K + Kc
            ce.crossing, ce.crossing_fN, ce.energy = cp, fNc, ce.energy + ec
            dw = out[4] if len(out) > 4 else None
            ce.crossing_dw = dw if self.crossing_jacobian else None
            # a fading pair's offset fades with it (crossing_work)
            ce.crossing_gap = 2.0 * c.radius + cp.weight * off - cp.distance
            ce.crossing_offset = off
            if cfric:
                ff, Kf, ce.crossing_friction = self._crossing_friction(
                    mesh, r, R, reference, cp, lam, off, tangent, None if frozen else dw)
                force = force + ff
                if tangent:
                    K = K + Kf
            tm["crossing"] += time.perf_counter() - t3
        return ce, force, K

    def _crossing_friction(self, mesh, r, R, reference, cp, lam, off, tangent, dw):
        """Friction at the crossing pairs ``cp`` (multipliers ``lam``, gap
        offsets ``off``; ``dw`` the weights' derivatives, None: frozen):
        residual, tangent and output of
        :func:`skfem_rod.contact.friction_assembly.crossing_friction_work`."""
        from .contact.friction_assembly import crossing_friction_work
        from .contact.law import gap, normal_force
        from .contact.slip import SlipState
        r_n, R_n = reference
        m = self.multipliers
        l = cp.distance if cp.length is None else cp.length
        fN, dfN = normal_force(gap(l, self.contact.radius) + cp.weight * off, lam,
                               self.crossing_compliance())
        lam_T = m.crossing_frictions(cp.key)
        state = SlipState(r, R, r_n, R_n, lam_T, np.zeros_like(lam_T))
        return crossing_friction_work(mesh, state, cp, fN, dfN, self.crossing_friction_params(),
                                      tangent, dw=dw, offset=off,
                                      multiplier_jacobian=self.friction_jacobian)

    def crossing_friction_params(self):
        """The crossing pairs' friction parameters: the tangential law at
        the compliance ``mu_T`` scaled as the normal one is (per unit point
        force: ``crossing_penalty / penalty``), at the adaptive friction
        factor, which the slave points' friction shares
        (:meth:`skfem_rod.contact.ContactOptions.crossing_friction_params`)."""
        return self.contact.crossing_friction_params(self.multipliers.friction_scale)

    def friction_params(self):
        """The :class:`~skfem_rod.contact.friction_assembly.FrictionParams`
        of the evaluations: the contact options' coefficients, the
        compliances at the multipliers' adaptive friction factor, carried
        multipliers pushed forward."""
        m = self.multipliers
        return self.contact.friction_params(push_forward=True, scale_T=m.friction_scale,
                                            scale_R=m.friction_scale)

    # -- convergence -------------------------------------------------------
    def force_scale(self, ev):
        """The force scale the residual on the free dofs is measured against:
        the largest of the external loads on the free dofs and the internal
        (and contact) forces that the supports take up (the reactions less
        any load applied on a supported dof, which the supports take up
        directly and which therefore cannot decide convergence)."""
        f_int = ev.residual + ev.external
        a = float(np.linalg.norm(ev.external[self.free]))
        b = float(np.linalg.norm(f_int[self.fixed]))
        if not (np.isfinite(a) and np.isfinite(b)):
            return np.inf if not (np.isnan(a) or np.isnan(b)) else np.nan
        return max(a, b, 1e-300)

    def residual_norm(self, ev):
        """Norm of the residual on the free dofs."""
        return float(np.linalg.norm(ev.residual[self.free]))

    def floor_estimate(self, r, ev):
        """An a-priori size of the residual's round-off floor at the
        evaluation ``ev`` (with its tangent) of positions ``r``: machine
        epsilon times the largest coordinate, the largest diagonal entry of
        the tangent on the free dofs and the square root of their number
        (a position known to a relative ``eps`` of the largest coordinate
        gives forces known to ``|K| eps |r|`` per dof).  Newton measures the
        floor (:meth:`round_off_floor`) only where the residual is within
        :data:`FLOOR_GATE` times this."""
        d = ev.tangent.diagonal()[self.free]
        return (np.finfo(float).eps * float(np.abs(r).max(initial=0.0))
                * float(np.abs(d).max(initial=0.0)) * np.sqrt(d.size))

    def round_off_floor(self, r, R, lam, ev):
        """The residual's round-off floor at ``(r, R)``, measured: the norm
        on the free dofs of the change of the residual (``ev`` at ``(r, R,
        lam)``) when every position coordinate is rounded at the precision
        of the largest one (a round trip through a shift of
        :data:`ROUND_TRIP` times it: ``(r + s) - s``).  In exact arithmetic
        the two residuals are the same state's; a residual at or below their
        difference cannot be told from zero in double precision.  Where a
        rod is long against its elements and axially stiff against its loads
        (the localized writhing case: ``L = 100``, ``EA = 1e5``, end forces
        0.4) the floor is 1e-7 of the force scale, above the default
        ``rtol``; there Newton returns its least iterate at the floor
        (:func:`skfem_rod.newton.at_floor`, ``Report.floor``) rather than
        the updates that round-off decides along a soft mode
        (docs/theory.md section 6)."""
        s = ROUND_TRIP * max(float(np.abs(r).max(initial=0.0)), self.rod.length)
        ev_t = self.evaluate((r + s) - s, R, lam, tangent=False)
        return float(np.linalg.norm((ev_t.residual - ev.residual)[self.free]))

    def at_floor(self, r, R, lam, ev, rn):
        """The residual's round-off floor at ``(r, R, lam)`` (evaluation
        ``ev``, with its tangent) if the residual norm ``rn`` is at or below
        it, else None.  The floor is measured (:meth:`round_off_floor`, one
        evaluation) only where ``rn`` is within :data:`FLOOR_GATE` times
        :meth:`floor_estimate`: elsewhere it cannot decide.  Newton's least
        iterate (:func:`skfem_rod.newton.at_floor`) and the polish's
        proximal steps (:func:`skfem_rod.relax.polish`) accept a state by
        this test."""
        if rn > FLOOR_GATE * self.floor_estimate(r, ev):
            return None
        floor = self.round_off_floor(r, R, lam, ev)
        return floor if rn <= floor else None

    # -- linear solve ------------------------------------------------------
    def factor(self, K, fixed=None):
        """Factorize ``K`` on the free dofs (constrained rows and columns
        replaced by the identity, pattern unchanged); returns ``solve(rhs)``
        (zero on the constrained dofs).  ``fixed``: another mask of held
        dofs (default: the supports').  What depends on the sparsity
        pattern alone (the held entries, the band ordering with contact)
        is kept in :attr:`factor_patterns` (one :class:`FactorPattern` per
        mask of held dofs) while the pattern stays."""
        fixed = self.fixed if fixed is None else fixed
        t0 = time.perf_counter()
        key = fixed.tobytes()
        pattern = self.factor_patterns.get(key)
        if pattern is None:
            if len(self.factor_patterns) >= 4:
                self.factor_patterns.clear()
            pattern = self.factor_patterns[key] = FactorPattern(
                fixed.copy(), band=self.contact is not None)
        A, p = pattern.prepare(K.tocsc())
        if p is None:
            lu = spla.splu(A)

            def solve(rhs):
                return lu.solve(np.where(fixed, 0.0, rhs))
        else:
            lu = spla.splu(A, permc_spec="NATURAL", diag_pivot_thresh=BAND_PIVOT_THRESHOLD)

            def solve(rhs):
                x = np.empty_like(rhs)
                x[p] = lu.solve(np.where(fixed, 0.0, rhs)[p])
                return x
        self.timers["factorization"] += time.perf_counter() - t0
        self.calls["factor"] += 1
        return solve

    def free_tangent(self, r, R, lam, stiffen=1.0):
        """Tangent on the free dofs at ``(r, R, lam)`` (CSC, constrained rows
        and columns removed) and the relative residual there: what the
        stability checks (:mod:`skfem_rod.stability`) read.

        With friction on it is the tangent of the **frictionless** problem at
        the same state and normal multipliers (the residual is the
        frictional one).  The friction tangent is not symmetric (the Coulomb
        bound follows ``f_N``), and its symmetrized part is no measure of
        stability: in the frictional plectoneme cycle
        (``demos/plectoneme_friction.py``, 16 elements) the looped states
        had lowest eigenvalues -9 to -18 with it, where the frictionless
        cycle's looped states have +1.5e-4, and every one of them was pushed
        off as a saddle.  The frictionless test is sufficient, not
        necessary: friction only dissipates, so a state stable without it is
        stable with it, but it may hold one the frictionless rod would
        leave (docs/stability.md).

        Likewise the crossing pairs' weights are held fixed in it: a fading
        pair's force is no energy's gradient, and the symmetrized part of
        its weight's derivative (the pair's force over the rise at the
        threshold, about 1e-4 eps) has eigenvalues of both signs far above
        the rod's; in the plectoneme it made a stable state a saddle with
        lowest eigenvalue -8e5 (docs/crossing-contact.md).

        ``stiffen``: the active gaps' stiffness times this, the forces
        unchanged (the constrained test of a state in contact:
        :data:`skfem_rod.stability.CONTACT_STIFFENING`)."""
        ev = self.evaluate(r, R, lam, tangent=not self.friction, frozen=True, stiffen=stiffen)
        residual = self.residual_norm(ev) / self.force_scale(ev)
        if self.friction:
            ev = self.evaluate(r, R, lam, friction=False, frozen=True, stiffen=stiffen)
        idx = np.flatnonzero(self.free)
        Kf = ev.tangent[idx][:, idx].tocsc()
        return Kf, residual


#: a slave keeps its master element while the projection there is within
#: this fraction of the contact tolerance of the closest one
KEEP_MASTER = 0.1
#: the crossing pairs are looked for up to the distance at which a pair
#: can carry force at the evaluation's multipliers and offsets, ``2 eps +
#: mu_c max(lambda_c) + max(offset)``, plus this fraction of ``eps``
#: (:meth:`Problem.crossing_reach`)
CROSSING_MARGIN = 0.25

#: nodal move, in contact radii, before the contact search's broad phase is
#: run again (:class:`skfem_rod.contact.search.NeighbourList`)
NEIGHBOUR_SKIN = 0.5

#: a position correction follows a Newton update that raised the residual
#: norm by more than this factor (:func:`position_correction`)
CORRECT_ABOVE = 10.0
#: halvings of a push off a saddle that would carry strands into each other
#: (:meth:`Problem.push`)
PUSH_HALVINGS = 10


class State(NamedTuple):
    """A configuration ``(r, R)`` at load factor ``lam``: where a Newton
    iteration stands."""
    r: np.ndarray
    R: np.ndarray
    lam: float


class Increment(NamedTuple):
    """A Newton update: ``dy`` (dof basis) and ``dl``, the load factor's
    (bordered continuation) or the normal multipliers' (generalized Newton)."""
    dy: np.ndarray
    dl: object = 0.0


#: SuperLU's threshold for keeping a diagonal pivot in the band-ordered
#: factorization (contact on, :class:`FactorPattern`): the diagonal is taken
#: unless it is below this fraction of the largest entry of its column
#: below the diagonal.  Row swaps widen the band; with SuperLU's default
#: (1.0, partial pivoting) the knot's tangents (1086 dofs, band 80) took
#: 1.79 ms per factorization, with 0.01 1.10 ms at the same backward error
#: (1e-16; benchmarks/RESULTS_evaluation.md).
BAND_PIVOT_THRESHOLD = 0.01


def spin_cap(dy, largest):
    """The fraction of the update ``dy`` (dof basis) whose largest nodal spin
    is ``largest`` (rad), at most 1: where a Newton update, a line search or
    a predictor starts."""
    spin = np.abs(dy.reshape(-1, 6)[:, 3:]).max(initial=0.0)
    return min(1.0, largest / max(spin, 1e-300))


class FactorPattern:
    """What :meth:`Problem.factor` derives from a tangent's sparsity pattern
    alone, for one mask ``fixed`` of held dofs (None: none held), kept while
    the pattern stays (Newton iterations whose contact element pairs do not
    change): the positions of the held rows and columns (their entries are
    replaced by the identity) and, with ``band``, the reverse Cuthill-McKee
    ordering (``symmetric``: of the pattern taken as symmetric) and the map
    that permutes the values.

    With contact the band ordering keeps the fill small where COLAMD does
    not: contact couples distant stretches of the rod (the turns of a coil,
    the plies of a plectoneme; coil of 1000 elements in contact: 0.5 s
    against 3.2 s per factorization).  Recomputing the ordering and the
    permuted pattern for every factorization cost more than the numerical
    factorization itself at some sizes (benchmarks/RESULTS_evaluation.md)."""

    def __init__(self, fixed=None, band=False, symmetric=True):
        self.fixed, self.band, self.symmetric = fixed, band, symmetric
        #: the pattern the rest was derived from
        self.shape = self.indptr = self.indices = None
        #: data positions of the held entries (zeroed) and of their diagonal (set to 1)
        self.zero = self.one = None
        #: the band ordering, the data map and the permuted pattern (band only)
        self.p = self.map = self.pindptr = self.pindices = None
        #: how many times the pattern work was done (benchmarks)
        self.derivations = 0

    def _same(self, K):
        return (self.indptr is not None and K.shape == self.shape
                and np.array_equal(K.indptr, self.indptr)
                and np.array_equal(K.indices, self.indices))

    def _derive(self, K):
        self.derivations += 1
        self.shape = K.shape
        self.indptr, self.indices = K.indptr.copy(), K.indices.copy()
        if self.fixed is None:
            self.zero = self.one = np.zeros(0, dtype=np.intp)
        else:
            cols = np.repeat(np.arange(K.shape[1]), np.diff(K.indptr))
            rows = K.indices
            kill = self.fixed[rows] | self.fixed[cols]
            self.zero = np.flatnonzero(kill)
            self.one = np.flatnonzero(kill & (rows == cols))
        self.p = None
        if self.band:
            from scipy.sparse.csgraph import reverse_cuthill_mckee
            p = reverse_cuthill_mckee(K.tocsr(), symmetric_mode=self.symmetric)
            # the same permutation applied to the entries' positions
            pos = sp.csc_matrix((np.arange(1, K.nnz + 1, dtype=float), K.indices, K.indptr),
                                shape=K.shape)
            Pp = pos[p][:, p].tocsc()
            Pp.sort_indices()                     # what splu would do in place
            self.p, self.map = p, Pp.data.astype(np.int64) - 1
            self.pindptr, self.pindices = Pp.indptr, Pp.indices

    def prepare(self, K):
        """``K`` (CSC) with the held rows and columns replaced by the
        identity, band-ordered with ``band``; returns ``(matrix, p)``
        (``p`` the ordering, None without ``band``)."""
        if not K.has_canonical_format:            # one entry per position
            K = K.copy()
            K.sum_duplicates()
        if not self._same(K):
            self._derive(K)
        data = K.data.copy()
        data[self.zero] = 0.0
        data[self.one] = 1.0
        # copies of the index arrays: splu may sort a matrix's indices in place
        if self.p is None:
            return sp.csc_matrix((data, self.indices.copy(), self.indptr.copy()),
                                 shape=K.shape), None
        return sp.csc_matrix((data[self.map], self.pindices.copy(), self.pindptr.copy()),
                             shape=K.shape), self.p


def start(problem, r, R, lam, prescribed):
    """What a Newton solve starts from: the prescribed increment still to
    apply (a copy; zeros for None) and the evaluation at ``(r, R, lam)``,
    or None and the reason when ``(r, R)`` leaves an element chart."""
    remaining = np.zeros(problem.mesh.n_dofs) if prescribed is None else prescribed.copy()
    try:
        return remaining, problem.evaluate(r, R, lam), ""
    except ElementRotationError as err:
        return remaining, None, str(err)


#: a Newton loop stops on a small update (``increment_tol``) only where the
#: residual did not grow more than this factor at that update
#: (:func:`settled`)
SETTLED_GROWTH = 10.0

#: positions are rounded for :meth:`Problem.round_off_floor` by a round trip
#: through a shift of this multiple of the largest coordinate: every
#: coordinate comes back rounded at the precision of numbers two to four
#: times the largest
ROUND_TRIP = 3.0
#: Newton measures the round-off floor only where the residual is within
#: this factor of :meth:`Problem.floor_estimate` (elsewhere the floor
#: cannot decide, and measuring it costs an evaluation)
FLOOR_GATE = 10.0


def settled(history, last_update, rtol_force, increment_tol):
    """Newton's convergence test on the residual norms ``history`` (the
    last one at the current iterate): the residual below ``rtol_force``
    (rtol times the force scale), or the last update below
    ``increment_tol`` with the residual not grown by more than
    :data:`SETTLED_GROWTH` at it.

    The update test is for a residual at its round-off floor.  An update
    can be small where the residual is not: in a damped step at a small
    ``dt`` the viscous term bounds the update by ``dt |G| / W``.  When such
    an update crossed a jump of the contact force (a crossing pair whose
    minimum the search lost, measured in the frictional plectoneme at 1.95
    turns: residual 1.6e-2 -> 66 at the last iterate, force 41.8 gone), the
    step was reported converged and accepted at a residual of 66, and every
    later step from there failed down to ``dt`` = 7e-9."""
    rn = history[-1]
    if rn <= rtol_force:
        return True
    if last_update > increment_tol:
        return False
    return len(history) < 2 or rn <= SETTLED_GROWTH * max(history[-2], rtol_force)


def update_size(problem, dy):
    """The size of an applied update ``dy`` (dof basis): the largest nodal
    move over the rod's length, or the largest spin (rad); Newton stops
    when it falls below ``increment_tol``."""
    upd = dy.reshape(-1, 6)
    return float(max(np.abs(upd[:, :3]).max() / problem.rod.length, np.abs(upd[:, 3:]).max()))


@dataclass
class Report:
    """What a solve of one step did: Newton's part, filled in by the outer
    loops (augmented Lagrangian, load stepping, gradient flow) with theirs."""
    converged: bool
    iterations: int = 0
    history: list = field(default_factory=list)
    reason: str = ""
    evaluation: Evaluation = None
    # augmented-Lagrangian loop (contact on)
    uzawa: int = 0
    newton_total: int = 0
    penetration: float = 0.0
    min_distance: float = None
    min_distance_at: tuple = None
    uzawa_converged: bool = True
    uzawa_note: str = ""
    #: a later Uzawa pass failed and the generalized Newton solved the step
    #: from the last converged pass (:func:`skfem_rod.augmented.step`): the
    #: failed pass's reason, else ""
    rescued: str = ""
    #: passes at adjusted gap offsets (:func:`skfem_rod.augmented.adjust_offsets`)
    offset_rounds: int = 0
    friction_moved: float = 0.0
    friction_misfit: float = 0.0     # friction_assembly.coulomb_misfit of the last pass
    # generalized Newton (skfem_rod.nonsmooth): |C| per iteration and the
    # iteration from which the multipliers were held
    complementarity: list = None
    polished_from: int = None
    step_lengths: list = None
    #: points whose contact state (normal law open/active, friction
    #: stick/slip) changed from the last iterate, per iteration (0 first)
    switches: list = None
    penalty_scale: float = 1.0
    # load stepping and gradient flow
    flow_steps: int = 0
    relaxed: bool = False
    #: the gradient flow's state was kept without a converged Newton polish:
    #: its residual relative to the force scale (above rtol), else None
    relaxed_residual: float = None
    lowest_eigenvalue: float = None
    #: the residual was accepted at its round-off floor
    #: (:meth:`Problem.round_off_floor`, above rtol times the force scale):
    #: that floor relative to the force scale, else None
    floor: float = None


class Iterate(NamedTuple):
    """A Newton iterate kept for :func:`at_floor`: its residual norm, state
    and evaluation."""
    rn: float
    r: np.ndarray
    R: np.ndarray
    lam: float
    ev: object


def at_floor(problem, best, history):
    """The :class:`Iterate` ``best`` as the converged state of a Newton
    solve that cannot go on (its residual jumped up from there, no update
    was admissible, or the iterations ran out) when its residual is at its
    round-off floor (:meth:`~skfem_rod.problem.Problem.at_floor`); else
    None.

    A residual at its floor cannot be told from zero in double precision,
    and the updates Newton computes from it are round-off amplified by the
    inverse of the softest stiffness: along a very soft mode (the loop of
    a localizing helix sliding along a long rod, lowest eigenvalue 1e-13
    of the stiffest) the residual went 0.07 -> 9e-5 -> 1e-7 -> 0.08 in a
    3-cycle, the floor there 3e-7 (the force scale 2).  A solve that
    converges to ``rtol`` never gets here, so this costs nothing where
    Newton works."""
    if best is None:
        return None
    # the floor's evaluation, at best's state rounded, is also the last one:
    # the problem's search memory (kept master elements, crossing keys) is
    # best's again, not that of the iterate the residual jumped at
    floor = problem.at_floor(best.r, best.R, best.lam, best.ev, best.rn)
    if floor is None:
        return None
    return best.r, best.R, best.lam, Report(True, iterations=len(history) - 1,
                                            history=history, evaluation=best.ev,
                                            floor=floor / problem.force_scale(best.ev))


def failed(r, R, lam, history, it, reason, ev=None):
    """The ``(r, R, lam, report)`` of a Newton solve that stopped at
    iteration ``it`` for ``reason`` (the state it stopped in)."""
    return r, R, lam, Report(False, iterations=it, history=history, reason=reason,
                             evaluation=ev)


def position_correction(problem, r, R, lam, ev):
    """One Newton step on the positions alone, rotations held: ``K_rr dr =
    -G_r``.  Returns the corrected ``(r, evaluation)``, or the given ones
    when the correction does not lower the residual.

    At fixed rotations the internal energy is quadratic in the positions
    (the strains ``v = Lambda^T rho'`` are linear in them, kinematics.py),
    so this step puts the positions where the rotations want them.  A Newton
    update of a slender rod gets the rotations nearly right but moves the
    positions along the linearized tangents: the O(theta^2) stretch it
    leaves is stiff (EA/EI ~ 1/eps^2) and raises the residual by orders of
    magnitude (a roll-up by pi/2 per step: 0.12 -> 2000), after which plain
    Newton wanders for 20 iterations.  It is applied after an update that
    raised the residual more than :data:`CORRECT_ABOVE` times: never in the
    quadratic regime, where the residual falls.
    For dead and follower loads, the only loads that depend on the
    configuration act through the rotations, so the step is exact for the
    internal work and the loads; contact enters through its tangent."""
    try:
        dr = problem.factor(ev.tangent, fixed=problem.not_position)(-ev.residual)
    except RuntimeError:
        return r, ev
    dr = problem.to_spatial(dr).reshape(-1, 6)[:, :3]
    if not np.all(np.isfinite(dr)):
        return r, ev
    r_c = r + dr
    if problem.contact is not None and not clearance_ok(problem.rod, r, r_c):
        return r, ev
    try:
        ev_c = problem.evaluate(r_c, R, lam)
    except ElementRotationError:
        return r, ev
    if problem.residual_norm(ev_c) < problem.residual_norm(ev):
        return r_c, ev_c
    return r, ev


def clearance_ok(rod, r_old, r_new):
    """True when no two non-neighbouring nodes move relative to each other by
    more than half their clearance ``|r_i - r_j| - 2 eps`` at ``r_old`` (at
    least ``eps / 2``), so that strands cannot pass through each other
    between two iterates (the contact search only sees the iterates); always
    True with contact off.  Newton (option ``clearance_cap``), the secant
    predictor and the gradient flow cap their updates with it."""
    c = rod.contact
    if c is None:
        return True
    d = r_new - r_old
    d = d - d.mean(axis=0)               # relative motion: a translation is free
    move = np.sqrt((d * d).sum(axis=1))
    floor = 0.5 * c.radius
    if 2 * move.max() <= floor:
        return True
    # two nodes approach each other by at most 2 max|d|, which exceeds half
    # their clearance only if that clearance is below 4 max|d|
    pairs = cKDTree(r_old).query_pairs(2 * c.radius + 4 * move.max(), output_type="ndarray")
    if pairs.size == 0:
        return True
    i, j = pairs[:, 0], pairs[:, 1]
    s = rod.mesh.s_nodes
    h = rod.length / rod.mesh.n_elements
    ds = np.abs(s[i] - s[j])
    if rod.mesh.closed:                  # arclength separation around the ring
        ds = np.minimum(ds, rod.length - ds)
    far = ds > max(c.exclusion, h)
    i, j = i[far], j[far]
    rel = np.linalg.norm(d[i] - d[j], axis=1)
    clear = np.linalg.norm(r_old[i] - r_old[j], axis=1) - 2 * c.radius
    return bool(np.all(rel <= np.maximum(0.5 * clear, floor)))


#: samples of the straight update path ``exp(t w) R``, t in (0, 1], checked
#: by :func:`check_no_wrap`
WRAP_SAMPLES = 10


def check_no_wrap(mesh, R, w):
    """Raise :class:`~skfem_rod.kinematics.ElementRotationError` if the spin
    update ``R <- exp(t w) R`` (``t`` from 0 to 1) takes the rotation of a
    node relative to its element's reference node beyond
    :data:`~skfem_rod.kinematics.PSI_MAX`.

    The relative angle ``theta(t)`` is continuous with slope at most
    ``|w_I| + |w_a|``; where ``theta(0) + |w_I| + |w_a|`` stays below the
    limit nothing can happen (almost always: no work); elsewhere ``theta``
    is sampled at :data:`WRAP_SAMPLES` points, which with spins capped at
    ``pi / 2`` per update (``SolverOptions.max_spin_update``) catches any
    excursion through ``pi``.  Without this check an update that jumps over
    the chart's edge lands on the other side, where the element's local
    rotation vector is short again: a prescribed twist of 20 turns ended
    with 5 in the rod, reported converged."""
    a = REF_NODE
    Rn, wn = R[mesh.nodes], w[mesh.nodes]                    # (ne, 4, ...)
    mag = np.linalg.norm(wn, axis=-1)
    if not np.any(mag):
        return
    Ra = Rn[:, a]
    theta = np.linalg.norm(logm(np.swapaxes(Ra, -1, -2)[:, None] @ Rn), axis=-1)
    e, i = np.nonzero(theta + mag + mag[:, [a]] >= PSI_MAX)
    if e.size == 0:
        return
    from .rotations import expm
    for t in np.arange(1, WRAP_SAMPLES + 1) / WRAP_SAMPLES:
        RI = expm(t * wn[e, i]) @ Rn[e, i]
        RA = expm(t * wn[e, a]) @ Rn[e, a]
        th = np.linalg.norm(logm(np.swapaxes(RA, -1, -2) @ RI), axis=-1)
        if np.any(th > PSI_MAX):
            bad = np.unique(e[th > PSI_MAX])
            raise ElementRotationError(
                f"element(s) {bad[:5].tolist()} would rotate by up to {th.max():.3f} rad "
                f"between nodes on the way to the update (allowed < {PSI_MAX:.3f} rad; "
                "through the edge of the element chart a turn of twist would be lost); "
                "refine the mesh (n_elements) or take smaller load steps")
