"""The rod model: reference shape, section, mesh, supports and loads.

>>> import numpy as np
>>> from skfem_rod import Rod, Section, geometry
>>> rod = Rod(geometry.straight(1.0), Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=1.0), 4)
>>> rod = rod.clamp("start").add_moment("end", [0.0, 0.0, 0.5 * np.pi])
>>> result = rod.solve(n_steps=2)
>>> bool(result.converged)
True
"""
from dataclasses import dataclass, field

import numpy as np

from .assembly import reference_strains
from .geometry import Shape
from .loads import PointLoad, DistributedLoad
import skfem_rod.validation as validation
from .validation import finite_vector
from .mesh import RodMesh
from .section import Section


_vector = finite_vector


def _components(components):
    """Validated spatial axis indices (a non-empty selection of 0, 1, 2)."""
    arr = np.asarray(components) if np.ndim(components) == 1 else np.zeros((0, 0))
    # a bool is not an axis index (np.asarray([False, 0]) is an int array)
    has_bool = arr.ndim == 1 and any(isinstance(c, (bool, np.bool_)) for c in components)
    if (arr.ndim != 1 or arr.size == 0 or arr.dtype.kind not in "iu" or has_bool
            or np.any((arr < 0) | (arr > 2))):
        raise ValueError("components must be spatial axis indices 0, 1, 2 "
                         f"(x, y, z), e.g. (0, 2); got {components!r}")
    return arr.tolist()


_flag = validation.flag

#: bytes a solve needs per element: a part independent of ``n_quad`` and one
#: per 3 Gauss points (measured peak: 72 kB per element at 3 points, mesh,
#: bases, tangent and its factorization, 20,000 and 80,000 elements), for the
#: memory estimate of :class:`Rod`
_BYTES_PER_ELEMENT = (36e3, 36e3)
#: bytes kept per node and load step (positions, rotations, reactions)
_BYTES_PER_NODE_STEP = 12 * 8
#: reference-shape check: largest distance between the P3-interpolated
#: reference centreline and the given curve, relative to the smallest radius
#: of curvature, and largest angle (rad) between the interpolated and the
#: given frames
REFERENCE_POSITION_TOL = 0.1
REFERENCE_FRAME_TOL = 0.3
#: frame rotation per element (rad) the element count advised by
#: ``Rod.check_reference`` aims at (a circle needs about 3.3 for the tolerances)
REFERENCE_TURN = 2.5
#: contact compliance allowed around the default ``10 eps^4 / EI``
#: (factors): stiffer makes the tangent singular to round-off, softer lets
#: strands pass through each other
PENALTY_RANGE = (1e-12, 1e4)
#: strands of the reference may start pressed into each other by at most this
#: fraction of the contact diameter (a preload, e.g. the plies of
#: ``geometry.plectoneme(0.98 eps, ...)``); deeper is refused
INITIAL_OVERLAP_TOL = 0.05


@dataclass
class Support:
    """Kinematic constraints at one node.

    ``position`` / ``rotation``: which spatial components of the position
    increment and of the spin increment are fixed.  ``displacement`` is the
    prescribed displacement and ``rotation_vector`` the prescribed spatial
    rotation of the node at load factor 1 (both scaled by the load factor;
    ``R(lam) = exp(lam * rotation_vector) R0``).  With a ``basis`` (see
    :meth:`Rod.support_basis`) the components are along its columns.
    """
    node: int
    position: np.ndarray = field(default_factory=lambda: np.zeros(3, bool))
    rotation: np.ndarray = field(default_factory=lambda: np.zeros(3, bool))
    displacement: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotation_vector: np.ndarray = field(default_factory=lambda: np.zeros(3))
    #: node-local orthonormal basis (columns) in which ``position``,
    #: ``rotation`` and ``displacement`` are expressed; None: the spatial axes
    #: (``rotation_vector`` is always spatial)
    basis: np.ndarray = None
    #: which call holds each component (0-2 position, 3-5 rotation) and
    #: whether it prescribes a motion: ``{component: (call, prescribed)}``
    holders: dict = field(default_factory=dict)

    def hold(self, components, call, prescribed):
        """Record that ``call`` holds ``components``; ValueError (nothing
        changed) if one of them is already held and either call prescribes
        its motion -- a prescribed component is held by one support only, as
        in the scene files."""
        for c in components:
            prev = self.holders.get(c)
            if prev is not None and (prev[1] or prescribed):
                what = "position" if c < 3 else "rotation"
                raise ValueError(
                    f"{call} conflicts with {prev[0]} at node {self.node}: both hold the "
                    f"{what} component {c % 3} and one of them prescribes its motion; a "
                    "prescribed component must be held by one support only (e.g. "
                    "fix_rotation(...) + prescribe_displacement(...) instead of clamp(...) "
                    "+ prescribe_displacement(...))")
        for c in components:
            if self.holders.get(c) is None or prescribed:
                self.holders[c] = (call, prescribed)


class Rod:
    """A geometrically exact (Simo-Reissner) rod discretized with P3 elements.

    Build it from a stress-free reference shape and a section, add supports
    and loads (the methods return the rod, so calls chain), then
    :meth:`solve`.

    Parameters
    ----------
    shape : geometry.Shape
        Stress-free reference shape (:mod:`skfem_rod.geometry`).
    section : Section
        Section stiffness (:class:`skfem_rod.Section`).
    n_elements : int
        Number of cubic elements (>= 1).
    n_quad : int
        Gauss points per element for the internal work (default 3).
    natural : {"reference", "straight"}
        The rod's stress-free shape: ``"reference"`` (default) ``shape``
        itself; ``"straight"`` straight and untwisted (unit stretch, no
        shear, no curvature), so that ``shape`` is only the configuration the
        solve starts from, e.g. a knot tied in a straight rod.  The solver
        first finds the equilibrium at load factor 0 from there (with
        ``snap="relax"`` through the gradient flow when Newton alone does not
        converge).

    Examples
    --------
    A cantilever rolled into a full circle by an end moment ``2 pi EI / L``:

    >>> import numpy as np
    >>> from skfem_rod import Rod, Section, geometry
    >>> section = Section.circle(E=1e7, nu=0.3, radius=0.01)
    >>> rod = Rod(geometry.straight(1.0), section, n_elements=8)
    >>> result = (rod.clamp("start")
    ...              .add_moment("end", [0.0, 0.0, 2 * np.pi * section.EI2])
    ...              .solve(n_steps=4))
    >>> result.converged, bool(np.linalg.norm(result.position(1.0)) < 1e-4)
    (True, True)
    """

    def __init__(self, shape, section, n_elements, n_quad=3, natural="reference"):
        if not isinstance(shape, Shape):
            raise ValueError("shape must be a skfem_rod.geometry shape "
                             "(straight, arc, helix, curve, polyline), "
                             f"got {type(shape).__name__}")
        if not isinstance(section, Section):
            raise ValueError(f"section must be a skfem_rod.Section, got {type(section).__name__}")
        self.shape = shape
        self.section = section
        closed = bool(getattr(shape, "closed", False))
        validation.count("n_elements", n_elements, 1, validation.MAX_ELEMENTS)
        validation.count("n_quad", n_quad, 1, validation.MAX_QUAD)
        validation.memory_budget(
            f"a rod of n_elements={n_elements} (n_quad={n_quad})",
            n_elements * (_BYTES_PER_ELEMENT[0] + _BYTES_PER_ELEMENT[1] * n_quad / 3))
        if not (1e-150 <= shape.length <= 1e150):
            raise ValueError(f"shape length {shape.length!r} is out of the range a rod can "
                             "be computed in (1e-150 to 1e150: energies scale with powers "
                             "of the length); choose other units")
        self.mesh = RodMesh(shape.length, n_elements, n_quad, closed=closed)
        with np.errstate(all="ignore"):
            self.r0, self.R0 = shape(self.mesh.s_nodes)
        for name, a in (("positions", self.r0), ("frames", self.R0)):
            if not np.all(np.isfinite(a)):
                k = int(np.argwhere(~np.isfinite(a))[0, 0])
                raise ValueError(
                    f"shape {shape!r} gives non-finite reference {name} (NaN or inf) at "
                    f"s = {self.mesh.s_nodes[k]:g}: check its parameters (start, direction, "
                    "points, ...)")
        if np.abs(self.r0).max() > 1e150:
            raise ValueError(f"shape {shape!r} has reference positions up to "
                             f"{np.abs(self.r0).max():.3g}, beyond the range a rod can be "
                             "computed in (1e150); choose other units or move it")
        if closed:                      # the ring must close up, frame included
            ends_r, ends_R = shape(np.array([0.0, shape.length]))
            gap = np.linalg.norm(ends_r[1] - ends_r[0]) / shape.length
            turn = np.linalg.norm(ends_R[1] - ends_R[0])
            if gap > 1e-8 or turn > 1e-6:
                raise ValueError(
                    f"a closed shape must close up: |r(L) - r(0)| / L = {gap:.3g} (allowed "
                    f"1e-8) and |R(L) - R(0)| = {turn:.3g} (allowed 1e-6; the frame must "
                    "turn by whole turns about the centreline, e.g. geometry.ring(..., "
                    "twist_turns=n) with an integer n)")
        self.C = section.C
        if natural not in ("reference", "straight"):
            raise ValueError(f"natural must be 'reference' or 'straight', got {natural!r}")
        self.natural = natural
        self.check_reference()
        self.eps0 = reference_strains(self.mesh, self.r0, self.R0, self.C)
        if natural == "straight":                 # unit stretch along d3, nothing else
            self.eps0 = np.zeros_like(self.eps0)
            self.eps0[..., 2] = 1.0
        self.supports = {}
        self.point_loads = []
        self.distributed = []
        self.contact = None

    # ------------------------------------------------------------------
    @property
    def length(self):
        """Length of the rod (of its reference shape).

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> rod.length
        1.0
        """
        return self.mesh.length

    def node(self, where):
        """Global node index of ``"start"``, ``"end"`` or an arclength that
        coincides with a node.

        Parameters
        ----------
        where : {"start", "end"} or float
            An end of the rod, or the arclength of a node (nodes are at multiples
            of ``length / (3 n_elements)``).

        Returns
        -------
        int
            Node index (dofs ``6 node + c``: ``c`` 0..2 position, 3..5 spin).
            scikit-fem numbers the element ends first (node ``k`` at
            ``s = k L / n_elements``), then the interior nodes.

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> rod.node("start"), rod.node("end"), rod.node(0.25)
        (0, 4, 1)
        """
        if isinstance(where, str):
            if where not in ("start", "end"):
                raise ValueError(f"where must be 'start', 'end' or a nodal arclength, got {where!r}")
            return self.mesh.end_nodes[0 if where == "start" else 1]
        if not validation._is_real(where):            # True is not the arclength 1
            raise ValueError("where must be 'start', 'end' or a nodal arclength, "
                             f"got {where!r}")
        try:
            s = float(where)
        except (TypeError, ValueError):
            raise ValueError("where must be 'start', 'end' or a nodal arclength, "
                             f"got {where!r}") from None
        if s < 0:
            raise ValueError(f"where={where!r} is a negative arclength; where must be "
                             "'start', 'end' or the arclength (>= 0) of a node")
        d = np.abs(self.mesh.s_nodes - s)
        k = int(np.argmin(d))
        if not np.isfinite(s) or d[k] > 1e-9 * self.length:
            raise ValueError(f"where={where!r} is not a node arclength; nodes are at "
                             f"multiples of {self.length / (3 * self.mesh.n_elements):g}")
        return k

    def _support(self, where):
        n = self.node(where)
        return self.supports.setdefault(n, Support(n))

    # supports ------------------------------------------------------------
    def clamp(self, where):
        """Fix position and rotation of the node at ``where``.

        Parameters
        ----------
        where : {"start", "end"} or float
            See :meth:`node`.

        Returns
        -------
        Rod
            The rod itself (calls chain).

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> rod.clamp("start").fixed_dofs()[:6]
        array([ True,  True,  True,  True,  True,  True])
        """
        sup = self._support(where)
        sup.hold(range(6), f"clamp({where!r})", False)
        sup.position[:] = True
        sup.rotation[:] = True
        return self

    def pin(self, where, components=(0, 1, 2)):
        """Fix (components of) the position at ``where``; the rotation stays
        free.

        Parameters
        ----------
        where : {"start", "end"} or float
            See :meth:`node`.
        components : sequence of int, default (0, 1, 2)
            Spatial axes to fix (0 x, 1 y, 2 z).

        Returns
        -------
        Rod

        Examples
        --------
        A simply supported beam: pinned at one end, on a roller (y, z held) at the
        other, twist held at the first:

        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> rod = rod.pin("start").fix_rotation("start", [0]).pin("end", (1, 2))
        >>> rod.check_constraints()          # no rigid-body mode left
        """
        comps = _components(components)
        sup = self._support(where)
        sup.hold(comps, f"pin({where!r})", False)
        sup.position[comps] = True
        return self

    def fix_rotation(self, where, components=(0, 1, 2)):
        """Fix spin components (about spatial axes) of the node at ``where``.

        Parameters
        ----------
        where : {"start", "end"} or float
        components : sequence of int, default (0, 1, 2)
            Spatial axes about which the node may not turn.

        Returns
        -------
        Rod

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> n = rod.node("end")
        >>> rod.fix_rotation("end", [0]).fixed_dofs()[6 * n:6 * n + 6]
        array([False, False, False,  True, False, False])
        """
        comps = _components(components)
        sup = self._support(where)
        sup.hold([3 + c for c in comps], f"fix_rotation({where!r})", False)
        sup.rotation[comps] = True
        return self

    def prescribe_rotation(self, where, rotation_vector):
        """Prescribe the rotation of the node at ``where``:
        ``R(lam) = exp(lam * rotation_vector) R0``.

        The rotation vector is spatial, at load factor 1; e.g. ``2 pi N`` about
        the rod's axis twists the end by ``N`` turns (the paper's
        ``theta(l) = theta^l``).  All three spin components of the node are held.

        Parameters
        ----------
        where : {"start", "end"} or float
        rotation_vector : array_like (3,)
            Rotation vector (rad) reached at load factor 1.

        Returns
        -------
        Rod

        Examples
        --------
        Twist a straight rod by a quarter turn; the torque is ``GJ phi / L``:

        >>> import numpy as np
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> rod.clamp("start").pin("end").prescribe_rotation("end", [np.pi / 2, 0, 0])  # doctest: +ELLIPSIS
        <skfem_rod.model.Rod object at ...>
        >>> torque = rod.solve(2).reaction("end")[1][0]
        >>> bool(np.isclose(torque, rod.section.GJ * np.pi / 2, rtol=1e-8))
        True
        """
        rotvec = _vector("rotation_vector", rotation_vector)
        sup = self._support(where)
        sup.hold(range(3, 6), f"prescribe_rotation({where!r})", True)
        sup.rotation[:] = True
        sup.rotation_vector = rotvec
        return self

    def prescribe_displacement(self, where, displacement, components=(0, 1, 2)):
        """Prescribe displacement components of the node at ``where`` (total
        at load factor 1, scaled with the load factor).

        Parameters
        ----------
        where : {"start", "end"} or float
        displacement : array_like (3,)
            Displacement reached at load factor 1 (only ``components`` are used).
        components : sequence of int, default (0, 1, 2)
            Spatial axes prescribed.

        Returns
        -------
        Rod

        Examples
        --------
        Stretch a bar by 1 %; the end force is ``EA * 0.01``:

        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> rod = rod.clamp("start").prescribe_displacement("end", [0.01, 0, 0], components=[0])
        >>> rod = rod.fix_rotation("end")
        >>> force = rod.solve(1).reaction("end")[0]
        >>> round(float(force[0] / (rod.section.EA * 0.01)), 8)
        1.0
        """
        comps = _components(components)
        d = _vector("displacement", displacement)
        sup = self._support(where)
        sup.hold(comps, f"prescribe_displacement({where!r})", True)
        sup.position[comps] = True
        sup.displacement[comps] = d[comps]
        return self

    # loads ------------------------------------------------------------------
    def add_force(self, where, force, follower=False, constant=False):
        """End (point) force at load factor 1.

        Parameters
        ----------
        where : {"start", "end"} or float
        force : array_like (3,)
            Force at load factor 1 (scaled with the load factor).
        follower : bool, default False
            Rotate the force with the cross-section (``R R0^T F``); otherwise it
            keeps its spatial direction (dead load).
        constant : bool, default False
            A preload, applied in full at every load factor (also in the
            reference state solved at load factor 0), e.g. a tension held while an
            end turns.

        Returns
        -------
        Rod

        Examples
        --------
        A tip-loaded cantilever (small load: the Euler-Bernoulli deflection
        ``P L^3 / 3 EI`` plus the shear part ``P L / GA``):

        >>> import numpy as np
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> P = 1e-3 * rod.section.EI2
        >>> result = rod.clamp("start").add_force("end", [0.0, P, 0.0]).solve(1)
        >>> w = result.position(1.0)[1]
        >>> exact = P / (3 * rod.section.EI2) + P / rod.section.GA1
        >>> bool(abs(w / exact - 1) < 1e-3)
        True
        """
        self.point_loads.append(PointLoad(self.node(where), _vector("force", force),
                                          "force", _flag("follower", follower),
                                          _flag("constant", constant)))
        return self

    def add_moment(self, where, moment, follower=False, constant=False):
        """End (point) moment at load factor 1.

        Parameters
        ----------
        where : {"start", "end"} or float
        moment : array_like (3,)
            Moment at load factor 1.  Dead (fixed spatial axis) unless
            ``follower=True`` (``R R0^T M``).
        follower : bool, default False
        constant : bool, default False
            A preload, as in :meth:`add_force`.

        Returns
        -------
        Rod

        Examples
        --------
        >>> import numpy as np
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_moment("end", [0, 0, np.pi * rod.section.EI2]).solve(2)
        >>> np.round(result.position(1.0), 5) + 0.0    # a half circle: tip at (0, 2/pi, 0)
        array([0.     , 0.63662, 0.     ])
        """
        self.point_loads.append(PointLoad(self.node(where), _vector("moment", moment),
                                          "moment", _flag("follower", follower),
                                          _flag("constant", constant)))
        return self

    def add_distributed_force(self, force):
        """Dead force per unit reference length, at load factor 1.

        Parameters
        ----------
        force : array_like (3,) or callable
            A constant vector, or a callable ``s -> (len(s), 3)`` of the
            arclength (e.g. gravity ``rho A g``, or a load on part of the rod).

        Returns
        -------
        Rod

        Examples
        --------
        A cantilever under its own weight (small load): tip deflection
        ``q L^4 / 8 EI`` plus the shear part ``q L^2 / 2 GA``:

        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> q = 1e-3 * rod.section.EI2
        >>> result = rod.clamp("start").add_distributed_force([0.0, 0.0, -q]).solve(1)
        >>> exact = q / (8 * rod.section.EI1) + q / (2 * rod.section.GA2)
        >>> bool(abs(-result.position(1.0)[2] / exact - 1) < 1e-3)
        True
        """
        self.distributed.append(DistributedLoad(self._distributed_value("force", force),
                                                "force"))
        return self

    def add_distributed_torque(self, torque):
        """Dead torque per unit reference length (3-vector or callable
        ``s -> (len(s), 3)``), at load factor 1.

        Returns
        -------
        Rod

        Examples
        --------
        A uniform twisting torque ``t`` on a clamped rod: the end turns by
        ``t L^2 / 2 GJ``:

        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> t = 0.1 * rod.section.GJ
        >>> result = rod.clamp("start").add_distributed_torque([t, 0.0, 0.0]).solve(1)
        >>> import numpy as np
        >>> angle = np.arctan2(result.frame(1.0)[2, 0], result.frame(1.0)[1, 0])
        >>> round(float(angle), 10)
        0.05
        """
        self.distributed.append(DistributedLoad(self._distributed_value("torque", torque),
                                                "torque"))
        return self

    def _distributed_value(self, name, value):
        """A finite 3-vector, or a callable checked at the quadrature points
        (it must return finite values of shape ``(len(s), 3)``)."""
        if not callable(value):
            return _vector(name, value)
        s = self.mesh.s_quad.ravel()
        try:
            q = np.asarray(value(s), dtype=float)
        except Exception as err:
            raise ValueError(f"distributed {name} callable failed at the quadrature points "
                             f"({type(err).__name__}: {err})") from err
        if q.shape != (s.size, 3):
            raise ValueError(f"distributed {name} callable must return an array of shape "
                             f"(len(s), 3) for arclengths s; got shape {q.shape} "
                             f"for len(s) = {s.size}")
        if not np.all(np.isfinite(q)):
            raise ValueError(f"distributed {name} callable returned non-finite values "
                             "(NaN or inf)")
        return value

    def enable_contact(self, radius=None, penalty=None, exclusion=None, **options):
        """Switch self-contact on (augmented Lagrangian with Uzawa updates).

        Parameters
        ----------
        radius : float, optional
            Contact radius ``eps`` (two strands touch at centreline distance
            ``2 eps``); default: ``section.radius``.
        penalty : float, optional
            Normal penalty ``mu_N``; default ``10 eps^4 / EI``.
        exclusion : float, optional
            Arclength ``L_ex`` around a point that is never in contact with it;
            default ``pi eps``.
        **options
            ``n_slave``, ``tolerance``, ``max_uzawa``, ``margin`` and the friction
            options: see :class:`skfem_rod.contact.ContactOptions`.

        Returns
        -------
        Rod

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> rod.enable_contact().contact.radius
        0.01
        """
        from dataclasses import fields
        from .contact import ContactOptions
        if radius is not None:
            radius = validation.positive("radius", radius)
        if penalty is not None:
            penalty = validation.positive("penalty", penalty)
        if exclusion is not None:
            exclusion = validation.positive("exclusion", exclusion)
        eps = self.section.radius if radius is None else radius
        if eps is None:
            raise ValueError("contact needs a radius: give radius=... or a Section with radius")
        allowed = [f.name for f in fields(ContactOptions)
                   if f.name not in ("radius", "penalty", "exclusion")]
        unknown = sorted(set(options) - set(allowed))
        if unknown:
            raise ValueError(f"unknown contact option(s) {', '.join(map(repr, unknown))}; "
                             f"allowed: radius, penalty, exclusion, {', '.join(allowed)}")
        self._check_contact_radius(eps)          # before defaults derived from it
        EI = max(self.section.EI1, self.section.EI2)
        with np.errstate(over="ignore", under="ignore"):
            default = 10.0 * np.float64(eps) ** 4 / EI
        if not (np.isfinite(default) and default > 0):
            raise ValueError(f"radius {eps!r}: the default penalty 10 eps^4 / EI = "
                             f"{float(default)!r} is out of floating-point range; give "
                             "penalty=... or choose other units")
        default = float(default)
        contact = ContactOptions(
            radius=eps, penalty=default if penalty is None else penalty,
            exclusion=np.pi * eps if exclusion is None else exclusion, **options)
        previous, self.contact = self.contact, contact
        try:
            self.check_contact()
        except ValueError:
            self.contact = previous
            raise
        return self

    def support_basis(self, where, basis):
        """Express the supports of the node at ``where`` in a local
        orthonormal basis: the ``components`` of :meth:`pin`,
        :meth:`fix_rotation` and :meth:`prescribe_displacement` (and its
        ``displacement``) then refer to the columns of ``basis`` instead of
        the spatial axes x, y, z, so a node can be held along or about any
        direction (a roller on an inclined plane, sliding along a line,
        turning about a skew axis).  The rotation vector of
        :meth:`prescribe_rotation` stays spatial.

        Parameters
        ----------
        where : {"start", "end"} or float
        basis : array_like (3, 3)
            Orthonormal matrix whose columns are the local axes.

        Returns
        -------
        Rod

        Examples
        --------
        A cantilever whose tip slides on the plane normal to ``n = (0, 1,
        1)/sqrt(2)`` (held along ``n`` only): its tip moves in that plane.

        >>> import numpy as np
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> n = np.array([0.0, 1.0, 1.0]) / np.sqrt(2)
        >>> Q = np.column_stack([n, [0.0, 1.0, -1.0] / np.sqrt(2), [1.0, 0.0, 0.0]])
        >>> rod = rod.clamp("start").support_basis("end", Q).pin("end", [0])
        >>> res = rod.add_force("end", [0.0, 0.0, -1.0]).solve(2)
        >>> bool(abs((res.position(1.0) - [1.0, 0.0, 0.0]) @ n) < 1e-12)
        True
        """
        try:
            Q = np.asarray(basis, dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise ValueError(f"basis must be a finite 3 x 3 matrix, got {basis!r}") from None
        if Q.shape != (3, 3) or not np.all(np.isfinite(Q)):
            raise ValueError(f"basis must be a finite 3 x 3 matrix, got shape {Q.shape}")
        if not np.allclose(Q.T @ Q, np.eye(3), atol=1e-10):
            raise ValueError("basis must be orthonormal (columns of unit length, mutually "
                             f"orthogonal); Q^T Q - I has norm {np.linalg.norm(Q.T @ Q - np.eye(3)):.3g}")
        self._support(where).basis = Q
        return self

    def dof_basis(self):
        """Sparse orthogonal matrix ``T`` (CSC) with ``y_spatial = T y_local``
        over all dofs: the :meth:`support_basis` blocks at their nodes, the
        identity elsewhere; None when no node has a basis other than the identity.

        Examples
        --------
        >>> import numpy as np
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 2)
        >>> rod.dof_basis() is None
        True
        >>> Q = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
        >>> T = rod.support_basis("end", Q).dof_basis()
        >>> n = rod.node("end")
        >>> bool(np.allclose(T[6 * n:6 * n + 3, 6 * n:6 * n + 3].toarray(), Q))
        True
        """
        # an identity basis changes nothing: not formed (no work, bitwise the
        # same solve as without it)
        nodes = [(n, sup.basis) for n, sup in self.supports.items()
                 if sup.basis is not None and not np.array_equal(sup.basis, np.eye(3))]
        if not nodes:
            return None
        import scipy.sparse as sp
        n = self.mesh.n_dofs
        B = np.broadcast_to(np.eye(3), (2 * self.mesh.n_nodes, 3, 3)).copy()
        for node, Q in nodes:
            B[2 * node] = B[2 * node + 1] = Q
        nb = B.shape[0]
        return sp.bsr_matrix((B, np.arange(nb), np.arange(nb + 1)), shape=(n, n)).tocsc()

    # ------------------------------------------------------------------------
    def fixed_dofs(self):
        """Boolean mask of the constrained global dofs (``6 node + c``).

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> int(rod.clamp("start").pin("end").fixed_dofs().sum())
        9
        """
        mask = np.zeros(self.mesh.n_dofs, bool)
        for n, sup in self.supports.items():
            mask[6 * n:6 * n + 3] |= sup.position
            mask[6 * n + 3:6 * n + 6] |= sup.rotation
        return mask

    def check_constraints(self):
        """Raise ValueError if the supports leave a rigid-body mode free.

        The message names each free mode (a translation or a rotation axis).

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> rod.pin("start").check_constraints()
        Traceback (most recent call last):
        ...
        ValueError: supports leave rigid-body mode(s) unconstrained: ...
        """
        fixed = self.fixed_dofs()
        modes = np.zeros((self.mesh.n_dofs, 6))
        centre = self.r0.mean(axis=0)
        arm = (self.r0 - centre) / self.length          # scale free: any units
        names = []
        for k in range(3):
            modes[k::6, k] = 1.0
            e = np.eye(3)[k]
            modes[0::6, 3 + k] = np.cross(e, arm)[:, 0]
            modes[1::6, 3 + k] = np.cross(e, arm)[:, 1]
            modes[2::6, 3 + k] = np.cross(e, arm)[:, 2]
            modes[3 + k::6, 3 + k] = 1.0
        T = self.dof_basis()
        if T is not None:                       # modes in the supports' bases
            modes = T.T @ modes
        Mc = modes[fixed]
        if Mc.shape[0] == 0:
            free = np.eye(6)
        else:
            _, sv, Vt = np.linalg.svd(Mc, full_matrices=True)
            rank = int(np.sum(sv > 1e-10 * max(sv.max(), 1.0)))
            free = Vt[rank:]
        if free.shape[0]:
            for v in free:
                t, w = v[:3], v[3:]
                if np.linalg.norm(w) > 1e-8:
                    names.append("rotation about axis " + np.array2string(
                        w / np.linalg.norm(w), precision=3, suppress_small=True))
                else:
                    names.append("translation along " + np.array2string(
                        t / np.linalg.norm(t), precision=3, suppress_small=True))
            raise ValueError(
                "supports leave rigid-body mode(s) unconstrained: " + "; ".join(names)
                + ". Add a support (clamp, pin, fix_rotation or prescribe_*) that "
                "removes them.")
        if self.contact is not None:
            self.check_contact()

    def check_steps(self, n_steps):
        """Raise ValueError unless ``n_steps`` is an integer in ``[1,
        validation.MAX_STEPS]`` whose kept steps fit in memory (every
        converged step keeps the nodal positions and rotations).

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> rod.check_steps(10**9)
        Traceback (most recent call last):
        ...
        ValueError: n_steps must be an integer in [1, 1000000], got 1000000000
        """
        n = validation.count("n_steps", n_steps, 1, validation.MAX_STEPS)
        validation.memory_budget(
            f"keeping n_steps={n} steps of {self.mesh.n_nodes} nodes",
            (n + 1) * self.mesh.n_nodes * _BYTES_PER_NODE_STEP)
        return n

    def check_reference(self):
        """Raise ValueError if the mesh cannot represent the reference shape.

        The P3 interpolation of the nodal positions and frames is compared
        with the shape at three points per element (where the interpolation
        error of a cubic peaks): the largest distance, relative to the
        smallest radius of curvature of the shape, must stay below
        :data:`REFERENCE_POSITION_TOL` and the largest angle between the
        frames below :data:`REFERENCE_FRAME_TOL` rad.  The message gives
        the element count that meets both (the error of the cubic
        interpolation falls as ``h^4``).

        Examples
        --------
        An arc of radius 0.01 turning 16 times on 4 elements:

        >>> from skfem_rod import Rod, Section, geometry
        >>> Rod(geometry.arc(0.01, 100.0), Section.circle(E=1e7, nu=0.3, radius=1e-3), 4)
        Traceback (most recent call last):
        ...
        ValueError: the mesh cannot represent the reference shape ...
        """
        from .element import shape_functions
        from .kinematics import local_coordinates, ElementRotationError
        from .rotations import expm, logm
        mesh = self.mesh
        ne = mesh.n_elements
        xi = np.tile([1 / 6, 1 / 2, 5 / 6], ne)
        e = np.repeat(np.arange(ne), 3)
        h = np.diff(mesh.vertices)
        s = mesh.vertices[e] + xi * h[e]
        mid = s[1::3]                                   # element midpoints
        d = 1e-4 * h
        with np.errstate(all="ignore"):                 # shapes may be costly: 4 n points
            r_ex, R_ex = self.shape(s)
            R_d = self.shape(mid + d)[1]
        if not (np.all(np.isfinite(r_ex)) and np.all(np.isfinite(R_ex))
                and np.all(np.isfinite(R_d))):
            raise ValueError(f"shape {self.shape!r} gives non-finite positions or frames "
                             "between the nodes: check its parameters")
        # rotation rate of the frame (curvature and twist) and curvature at the
        # element midpoints (forward differences)
        R_mid = R_ex[1::3]
        omega = np.linalg.norm(logm(np.swapaxes(R_mid, -1, -2) @ R_d), axis=-1) / d
        kappa = np.linalg.norm(R_d[:, :, 2] - R_mid[:, :, 2], axis=-1) / d
        e_ok = np.arange(ne)
        rho = 1.0 / max(float(kappa.max(initial=0.0)), 1e-300)
        N = shape_functions(xi)[0]                                  # (4, m)
        nodes = mesh.nodes[e]
        r_h = np.einsum("Im,mIi->mi", N, self.r0[nodes])
        pos = float(np.linalg.norm(r_h - r_ex, axis=1).max()) / rho
        try:
            loc = local_coordinates(self.r0[mesh.nodes], self.R0[mesh.nodes])
            psi = np.einsum("Im,mIi->mi", N, loc.psi[e])
            R_h = loc.Rr[e] @ expm(psi)
            ang = float(np.linalg.norm(logm(np.swapaxes(R_h, -1, -2) @ R_ex), axis=-1).max())
        except ElementRotationError:
            ang = np.inf
        tol_p, tol_a = REFERENCE_POSITION_TOL, REFERENCE_FRAME_TOL
        if pos <= tol_p and ang <= tol_a:
            return
        # elements needed: the h^4 law from the measured errors, and at most
        # REFERENCE_TURN rad of frame rotation per element (beyond it the
        # errors saturate and the law says nothing)
        turn = float((omega * h[e_ok]).max(initial=0.0))
        factor = max((pos / tol_p) ** 0.25 if np.isfinite(pos) else 1.0,
                     (ang / tol_a) ** 0.25 if np.isfinite(ang) else 1.0,
                     turn / REFERENCE_TURN)
        need = int(np.ceil(1.05 * ne * factor))
        raise ValueError(
            f"the mesh cannot represent the reference shape {self.shape!r}: with "
            f"n_elements={ne} its P3 interpolation is up to {pos:.3g} times the smallest "
            f"radius of curvature ({rho:.3g}) off the given curve (allowed {tol_p:g}) and "
            f"its frames up to {ang:.3g} rad off (allowed {tol_a:g}); an element turns "
            f"the frame by up to {turn:.3g} rad. Use n_elements >= {need}")

    def _check_contact_radius(self, eps):
        closed = bool(getattr(self.mesh, "closed", False))
        span = self.length / 2 if closed else self.length
        if not 2 * eps < span:
            raise ValueError(f"contact radius {eps:g}: the contact diameter 2 eps = "
                             f"{2 * eps:g} must be smaller than the "
                             f"{'half ring' if closed else 'rod'} ({span:g})")

    def check_contact(self):
        """Raise ValueError if the contact parameters make no sense for this
        rod: an exclusion length that excludes every pair (``>=`` the
        length, half of it for a ring) or shorter than the contact diameter
        ``2 eps`` (neighbours would touch at rest), a contact diameter not
        smaller than the rod, or strands that start interpenetrated (the
        reference centreline, sampled densely, has points farther apart
        along the rod than the exclusion but closer in space than ``2 eps``;
        the message names their arclengths).  Called by
        :meth:`check_constraints` (so at the start of every solve).

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.arc(0.1, 6.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 8)
        >>> rod.enable_contact(radius=0.02)
        Traceback (most recent call last):
        ...
        ValueError: contact radius 0.02: the strands start interpenetrated: ...
        """
        c = self.contact
        if c is None:
            return
        key = (c.radius, c.exclusion, c.penalty)
        if getattr(self, "_contact_checked", None) == key:
            return
        L, eps, ex = self.length, c.radius, c.exclusion
        closed = bool(getattr(self.mesh, "closed", False))
        span = L / 2 if closed else L
        self._check_contact_radius(eps)
        if not ex < span:
            raise ValueError(f"contact exclusion {ex:g} excludes every pair of points: it "
                             f"must be smaller than the {'half ring' if closed else 'rod length'} "
                             f"{span:g}")
        if not ex >= 2 * eps * (1 - 1e-12):
            raise ValueError(f"contact exclusion {ex:g} must be at least the contact "
                             f"diameter 2 eps = {2 * eps:g} (points closer along the rod "
                             "would be in contact at rest); default pi eps")
        EI = max(self.section.EI1, self.section.EI2)
        default = 10.0 * eps ** 4 / EI
        lo, hi = PENALTY_RANGE
        if not lo * default <= c.penalty <= hi * default:
            raise ValueError(f"contact penalty {c.penalty:g} is out of range: allowed "
                             f"{lo:g} to {hi:g} times the default 10 eps^4 / EI = "
                             f"{default:.3g} (a larger compliance lets strands pass through "
                             "each other, a smaller one makes the tangent singular)")
        # initial interpenetration: dense samples of the reference centreline
        from scipy.spatial import cKDTree
        # samples of the discrete reference (the P3 interpolation of the nodes,
        # what the solver starts from), eps / 3 apart (at most 400,000): a few
        # neighbours along the strand within the query radius, so the pairs
        # stay O(samples); a penetration is seen to about 0.03 eps
        from .element import shape_functions
        mesh = self.mesh
        n = int(np.clip(np.ceil(3 * L / eps), 64, 400_000))
        s = (np.arange(n) + 0.5) * (L / n)
        e, xi = mesh.locate(s)
        N = shape_functions(xi)[0]                                  # (4, n)
        r = np.einsum("In,nIi->ni", N, self.r0[mesh.nodes[e]])
        tree = cKDTree(r)
        gap = 2 * eps * (1 - INITIAL_OVERLAP_TOL)
        pairs = tree.query_pairs(gap, output_type="ndarray")
        if len(pairs):
            ds = np.abs(s[pairs[:, 0]] - s[pairs[:, 1]])
            if closed:
                ds = np.minimum(ds, L - ds)
            pairs = pairs[ds >= ex]
        if len(pairs):
            dist = np.linalg.norm(r[pairs[:, 0]] - r[pairs[:, 1]], axis=1)
            k = int(np.argmin(dist))
            a, b = sorted((s[pairs[k, 0]], s[pairs[k, 1]]))
            raise ValueError(
                f"contact radius {eps:g}: the strands start interpenetrated: the reference "
                f"centreline at s = {a:.6g} and s = {b:.6g} is {dist[k]:.4g} apart, less "
                f"than 2 eps (1 - {INITIAL_OVERLAP_TOL:g}) = {gap:.4g} ({len(pairs)} such "
                "sample pair(s)); give a smaller radius or a shape whose strands are at "
                "least 2 eps apart")
        self._contact_checked = key

    def solve(self, n_steps=1, path=None, callback=None, start=None, progress=False,
              **options):
        """Solve the equilibrium along the load path.

        Parameters
        ----------
        n_steps : int
            Number of equal pseudo-time steps (cut automatically when
            Newton fails).
        path : sequence of float, optional
            Load factors reached at equally spaced pseudo-times, starting at
            0: ``(0, 1)`` (default) loads proportionally, ``(0, 1, 0)`` loads
            and unloads, ``(0, 1, 0.5)`` ...  All loads and prescribed
            motions are multiplied by the load factor.
        callback : callable, optional
            ``callback(result, k)`` after each converged step ``k`` (e.g. a
            progress line).
        progress : bool or {"bar", "log"}, default False
            Report the converged steps: ``True`` a tqdm bar over pseudo-time
            (a widget in notebooks; optional extra ``progress``), ``"log"``
            INFO records on the ``skfem_rod`` logger
            (:func:`skfem_rod.progress.step_reporter`).
        start : Result or (r, R), optional
            Start step 0 from this state instead of the reference: the last
            step of a Result (of a rod with the same mesh), or nodal
            positions ``(n, 3)`` and rotations ``(n, 3, 3)``.  Step 0 is then
            an equilibrium solve at load factor 0, with the contact
            multipliers of a Result's last step (the slave points' forces,
            the crossing pairs' multipliers that give their forces, and the
            friction forces when both have friction:
            :func:`skfem_rod.solver.carry_multipliers`); slips of friction
            are measured from the start.  E.g. a knot tied without friction
            and then pulled with it.
        **options
            See :class:`skfem_rod.solver.SolverOptions` (``rtol``,
            ``max_iterations``, ``line_search``, ``min_step``, ...).
            ``method="arclength"`` follows the path by pseudo-arclength
            continuation instead (through limit points; ``path`` must then
            be ``(0, lam_end)``, ``n_steps`` sets the initial load step
            ``lam_end / n_steps``; further options of
            :func:`skfem_rod.continuation.follow`, e.g. ``stability=True``).
            ``method="barrier"`` (contact on) replaces the paper's
            augmented-Lagrangian contact by a smooth barrier between the
            centreline's nodes and solves each step by Newton on the total
            energy, with tangential friction (``gamma_T``) and rotational
            friction on the pivot about each pair's normal (``gamma_R``
            with ``rotational_slip="pivot"``) at the state's own normal
            forces (:func:`skfem_rod.minimize.solve_barrier`,
            docs/contact-solve.md; dead forces only).

        Returns
        -------
        Result
            Every converged step; ``result.converged`` and
            ``result.message`` say whether and where it stopped.
            (:class:`skfem_rod.continuation.PathResult` for ``"arclength"``.)

        Examples
        --------
        Load and unload a cantilever in 2 + 2 steps; the energy returns to 0:

        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> rod = rod.clamp("start").add_force("end", [0.0, 0.05, 0.0])
        >>> result = rod.solve(4, path=[0, 1, 0])
        >>> result.load_factors
        array([0. , 0.5, 1. , 0.5, 0. ])
        >>> bool(result.energies[2] > 0 and abs(result.energies[-1]) < 1e-20)
        True
        """
        from .progress import step_reporter
        callback, close = step_reporter(progress, callback)
        try:
            return self._solve(n_steps, path, callback, start, **options)
        finally:
            close()

    def _solve(self, n_steps, path, callback, start, **options):
        method = options.pop("method", "newton")
        if method == "arclength":
            if start is not None:
                raise ValueError("start is not supported with method='arclength'")
            from .continuation import solve_arclength
            return solve_arclength(self, n_steps=n_steps, path=path, callback=callback,
                                   **options)
        if method == "barrier":
            from .minimize import solve_barrier
            return solve_barrier(self, n_steps=n_steps, path=path, callback=callback,
                                 start=start, **options)
        if method != "newton":
            raise ValueError(f"method must be 'newton', 'arclength' or 'barrier', "
                             f"got {method!r}")
        from .solver import solve
        return solve(self, n_steps=n_steps, path=path, callback=callback, start=start,
                     **options)
