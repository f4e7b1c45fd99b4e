"""The rod model: reference shape, section, mesh, supports and loads.

>>> from skfem_rod import Rod, Section, geometry
>>> rod = Rod(geometry.straight(1.0), Section(1e4, 1e4, 1e4, 1.0, 1.0, 1.0), 4)
>>> rod.clamp("start")
>>> rod.add_moment("end", [0.0, 0.0, 0.5 * np.pi])
>>> result = rod.solve(n_steps=2)
>>> bool(result.converged)
True
"""
from dataclasses import dataclass, field

import numpy as np

from .assembly import reference_strains
from .geometry import Shape
from .loads import PointLoad, DistributedLoad
from .validation import finite_vector
from .mesh import RodMesh
from .section import Section


_vector = finite_vector


def _components(components):
    """Validated spatial axis indices (a non-empty selection of 0, 1, 2)."""
    arr = np.atleast_1d(np.asarray(components))
    if (arr.ndim != 1 or arr.size == 0 or arr.dtype.kind not in "iu"
            or np.any((arr < 0) | (arr > 2))):
        raise ValueError("components must be spatial axis indices 0, 1, 2 "
                         f"(x, y, z), e.g. (0, 2); got {components!r}")
    return arr.tolist()


@dataclass
class Support:
    """Kinematic constraints at one node.

    ``position`` / ``rotation``: which spatial components of the position
    increment and of the spin increment are fixed.  ``displacement`` is the
    prescribed displacement and ``rotation_vector`` the prescribed spatial
    rotation of the node at load factor 1 (both scaled by the load factor;
    ``R(lam) = exp(lam * rotation_vector) R0``).
    """
    node: int
    position: np.ndarray = field(default_factory=lambda: np.zeros(3, bool))
    rotation: np.ndarray = field(default_factory=lambda: np.zeros(3, bool))
    displacement: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotation_vector: np.ndarray = field(default_factory=lambda: np.zeros(3))


class Rod:
    """A geometrically exact (Simo-Reissner) rod discretized with P3 elements.

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
    """

    def __init__(self, shape, section, n_elements, n_quad=3):
        if not isinstance(shape, Shape):
            raise ValueError("shape must be a skfem_rod.geometry shape "
                             "(straight, arc, helix, curve, polyline), "
                             f"got {type(shape).__name__}")
        if not isinstance(section, Section):
            raise ValueError(f"section must be a skfem_rod.Section, got {type(section).__name__}")
        self.shape = shape
        self.section = section
        self.mesh = RodMesh(shape.length, n_elements, n_quad)
        self.r0, self.R0 = shape(self.mesh.s_nodes)
        self.C = section.C
        self.eps0 = reference_strains(self.mesh, self.r0, self.R0, self.C)
        self.supports = {}
        self.point_loads = []
        self.distributed = []
        self.contact = None

    # ------------------------------------------------------------------
    @property
    def length(self):
        return self.mesh.length

    def node(self, where):
        """Global node index of ``"start"``, ``"end"`` or an arclength that
        coincides with a node."""
        if isinstance(where, str):
            if where not in ("start", "end"):
                raise ValueError(f"where must be 'start', 'end' or a nodal arclength, got {where!r}")
            return self.mesh.end_nodes[0 if where == "start" else 1]
        try:
            s = float(where)
        except (TypeError, ValueError):
            raise ValueError("where must be 'start', 'end' or a nodal arclength, "
                             f"got {where!r}") from None
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
        """Fix position and rotation of the node at ``where``."""
        sup = self._support(where)
        sup.position[:] = True
        sup.rotation[:] = True
        return self

    def pin(self, where, components=(0, 1, 2)):
        """Fix (components of) the position; the rotation stays free."""
        comps = _components(components)
        sup = self._support(where)
        sup.position[comps] = True
        return self

    def fix_rotation(self, where, components=(0, 1, 2)):
        """Fix spin components (spatial axes) of the node at ``where``."""
        comps = _components(components)
        sup = self._support(where)
        sup.rotation[comps] = True
        return self

    def prescribe_rotation(self, where, rotation_vector):
        """Prescribe the node rotation ``exp(lam * rotation_vector) R0``
        (spatial rotation vector at load factor 1; e.g. ``2 pi N`` about the
        axis twists by ``N`` turns, the paper's ``theta(l) = theta^l``)."""
        rotvec = _vector("rotation_vector", rotation_vector)
        sup = self._support(where)
        sup.rotation[:] = True
        sup.rotation_vector = rotvec
        return self

    def prescribe_displacement(self, where, displacement, components=(0, 1, 2)):
        """Prescribe displacement components (total at load factor 1)."""
        comps = _components(components)
        d = _vector("displacement", displacement)
        sup = self._support(where)
        sup.position[comps] = True
        sup.displacement[comps] = d[comps]
        return self

    # loads ------------------------------------------------------------------
    def add_force(self, where, force, follower=False):
        """End (point) force at load factor 1; ``follower=True`` makes it
        rotate with the cross-section."""
        self.point_loads.append(PointLoad(self.node(where), _vector("force", force),
                                          "force", bool(follower)))
        return self

    def add_moment(self, where, moment, follower=False):
        """End (point) moment at load factor 1 (dead: fixed spatial axis)."""
        self.point_loads.append(PointLoad(self.node(where), _vector("moment", moment),
                                          "moment", bool(follower)))
        return self

    def add_distributed_force(self, force):
        """Dead force per unit reference length: a 3-vector or a callable
        ``s -> (n, 3)`` (e.g. gravity ``rho A g``)."""
        self.distributed.append(DistributedLoad(self._distributed_value("force", force),
                                                "force"))
        return self

    def add_distributed_torque(self, torque):
        """Dead torque per unit reference length (3-vector or callable)."""
        self.distributed.append(DistributedLoad(self._distributed_value("torque", torque),
                                                "torque"))
        return self

    def _distributed_value(self, name, value):
        """A finite 3-vector, or a callable checked at the quadrature points
        (it must return finite values of shape ``(len(s), 3)``)."""
        if not callable(value):
            return _vector(name, value)
        s = self.mesh.s_quad.ravel()
        q = np.asarray(value(s), dtype=float)
        if q.shape != (s.size, 3):
            raise ValueError(f"distributed {name} callable must return an array of shape "
                             f"(len(s), 3) for arclengths s; got shape {q.shape} "
                             f"for len(s) = {s.size}")
        if not np.all(np.isfinite(q)):
            raise ValueError(f"distributed {name} callable returned non-finite values "
                             "(NaN or inf)")
        return value

    def enable_contact(self, radius=None, penalty=None, exclusion=None, **options):
        """Switch self-contact on (see :class:`skfem_rod.contact.ContactOptions`
        for ``n_slave``, ``tolerance``, ``max_uzawa``, ``margin``)."""
        from .contact import ContactOptions
        eps = self.section.radius if radius is None else radius
        if eps is None:
            raise ValueError("contact needs a radius: give radius=... or a Section with radius")
        if not (np.isfinite(eps) and eps > 0):
            raise ValueError(f"contact radius must be a finite number > 0, got {eps!r}")
        EI = max(self.section.EI1, self.section.EI2)
        self.contact = ContactOptions(
            radius=float(eps),
            penalty=10.0 * eps**4 / EI if penalty is None else penalty,
            exclusion=np.pi * eps if exclusion is None else exclusion, **options)
        return self

    # ------------------------------------------------------------------------
    def fixed_dofs(self):
        """Boolean mask of the constrained global dofs."""
        mask = np.zeros(self.mesh.n_dofs, bool)
        for n, sup in self.supports.items():
            mask[6 * n:6 * n + 3] |= sup.position
            mask[6 * n + 3:6 * n + 6] |= sup.rotation
        return mask

    def check_constraints(self):
        """Raise ValueError if a rigid-body mode is left unconstrained."""
        fixed = self.fixed_dofs()
        modes = np.zeros((self.mesh.n_dofs, 6))
        centre = self.r0.mean(axis=0)
        names = []
        for k in range(3):
            modes[k::6, k] = 1.0
            e = np.eye(3)[k]
            modes[0::6, 3 + k] = np.cross(e, self.r0 - centre)[:, 0]
            modes[1::6, 3 + k] = np.cross(e, self.r0 - centre)[:, 1]
            modes[2::6, 3 + k] = np.cross(e, self.r0 - centre)[:, 2]
            modes[3 + k::6, 3 + k] = 1.0
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

    def solve(self, n_steps=1, path=None, callback=None, **options):
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
        **options
            See :class:`skfem_rod.solver.SolverOptions` (``rtol``,
            ``max_iterations``, ``line_search``, ``min_step``, ...).

        Returns
        -------
        Result
            Every converged step; ``result.converged`` and
            ``result.message`` say whether and where it stopped.
        """
        from .solver import solve
        return solve(self, n_steps=n_steps, path=path, callback=callback, **options)
