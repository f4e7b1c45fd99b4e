"""Results of a solve: every converged step, queries at any arclength,
reactions, the load path, and export/render helpers."""
from dataclasses import dataclass

import numpy as np

from .element import shape_functions
from .kinematics import local_coordinates, strains


@dataclass
class Step:
    """One converged load step."""
    load_factor: float
    r: np.ndarray                  # (n_nodes, 3) nodal positions
    R: np.ndarray                  # (n_nodes, 3, 3) nodal rotations
    iterations: int
    residual_history: list
    energy: float                  # strain energy
    reactions: dict                # node -> (force (3,), moment (3,))
    contact: object = None         # ContactState of the step (contact on only)
    time: float = 0.0              # pseudo-time along the load path
    flow_steps: int = 0            # gradient-flow steps (solve option snap="relax")
    lowest_eigenvalue: float = None  # of the symmetrized tangent (option stability;
    # with contact the active gaps stiffened: stability.CONTACT_STIFFENING)
    #: the gradient flow's state kept without a converged Newton polish: its
    #: residual relative to the force scale (above rtol)
    relaxed_residual: float = None
    #: the step's residual was accepted at its round-off floor, above rtol
    #: times the force scale (:func:`skfem_rod.problem.at_floor`): that
    #: floor relative to the force scale
    floor: float = None


@dataclass
class CrossingContact:
    """The crossing pairs that carry force at a converged step (contact
    option ``crossing``): point-to-point pairs at the local minima of the
    distance between two strands, both parameters free
    (:mod:`skfem_rod.contact.crossing`, docs/crossing-contact.md).  Their
    forces are point forces (not per unit length, unlike
    :class:`ContactState`'s), each already times its pair's weight.  With
    friction on (``gamma_T > 0`` and the contact option
    ``crossing_friction``) each pair carries a tangential Coulomb force
    ``w F``, ``|F| <= gamma_T f_N`` (docs/crossing-contact.md, "Friction at
    the crossing pairs")."""
    s: np.ndarray            # (k,) arclength of the first point
    s_bar: np.ndarray        # (k,) arclength of the second point
    force: np.ndarray        # (k,) point force w f_N pressing the strands apart
    weight: np.ndarray       # (k,) the pair's weight w: 1 at a crossing, fading to 0
                             # where the strands run parallel (line contact)
    gap: np.ndarray          # (k,) d = 2 eps + w offset - distance (positive: penetration)
    normal: np.ndarray       # (k, 3) unit vector from the second point to the first
    offset: np.ndarray       # (k,) gap offsets (augmented.adjust_offsets)
    angle: np.ndarray        # (k,) effective angle between the strands (radians)
    #: ``(k, 5)`` the places the pairs' multipliers are carried by
    #: (:func:`skfem_rod.contact.crossing.carry`): what a solve started
    #: from this step (``Rod.solve(start=...)``) starts its pairs from
    key: np.ndarray
    #: ``(k, 3)`` the friction point force ``w F`` on the second point's
    #: strand (the first point's strand gets ``-w F``; it acts at the
    #: surface points, so each section also gets the couple
    #: ``-(distance / 2) N x w F``); zeros without friction there
    friction: np.ndarray = None
    #: ``(k, 3)`` the material slip of the step (F6), first point relative
    #: to the second; zeros without friction
    slip: np.ndarray = None
    #: ``(k,)`` :class:`skfem_rod.contact.friction.FrictionState` per pair
    #: (0, open, without friction)
    state: np.ndarray = None

    def __post_init__(self):
        k = self.s.size
        if self.friction is None:
            self.friction = np.zeros((k, 3))
        if self.slip is None:
            self.slip = np.zeros((k, 3))
        if self.state is None:
            self.state = np.zeros(k, dtype=int)

    @property
    def total_force(self):
        """Sum of the point forces (each pair once)."""
        return float(np.sum(self.force))


@dataclass
class ContactState:
    """Active contact points of a converged step (one row per slave point
    with a positive normal force).  With ``Rod.solve(method="barrier")``
    one row per node pair inside the barrier's width (``s`` node i,
    ``s_bar`` node j, each pair once): ``force`` is then the pair's point
    force and ``weight`` 1, ``offset`` the barrier's contact distance less
    ``2 eps``, ``force_T`` and ``force_R`` the pair's point force and
    couple (the latter about the normal, ``slip_R`` the pivot along it), no
    Uzawa (:meth:`skfem_rod.minimize.BarrierStepper.contact_state`)."""
    s: np.ndarray            # slave arclengths
    s_bar: np.ndarray        # master arclengths
    gap: np.ndarray          # d = 2 eps + offset - distance (positive: penetration)
    force: np.ndarray        # f_N per unit length
    normal: np.ndarray       # N (master -> slave)
    weight: np.ndarray       # slave quadrature weights (ds)
    penetration: float       # largest penetration max(d, 0)
    uzawa: int               # Uzawa updates in the step
    uzawa_converged: bool
    newton_total: int        # Newton iterations over all Uzawa passes
    candidates: int          # narrow-phase candidate pairs (broad phase output)
    # friction (None when gamma_T = gamma_R = 0): per point, f on the master
    force_T: np.ndarray = None   # (m, 3) tangential friction force per unit length
    force_R: np.ndarray = None   # (m, 3) rotational friction couple per unit length
    state_T: np.ndarray = None   # (m,) FrictionState: 0 open, 1 stick, 2 slip
    state_R: np.ndarray = None
    slip_T: np.ndarray = None    # (m, 3) slip increments of the step
    slip_R: np.ndarray = None
    #: ``Rod.solve(method="barrier")`` with friction: the friction lag the
    #: state was solved with (a :class:`skfem_rod.contact.barrier.FrictionLag`:
    #: each pair's material points and the sections' reference), whose
    #: slips the next step carries -- and a solve restarted from this state
    #: (``start=result``)
    lag: object = None
    dissipation: float = 0.0     # friction work dissipated in the step (slave points and
                                 # crossing pairs)
    min_distance: float = None   # true smallest distance between strands (centrelines)
    #: per point, the gap offset it acted with (augmented.adjust_offsets):
    #: in contact at the distance 2 eps + offset, where the centrelines dip
    #: below 2 eps between slave points
    offset: np.ndarray = None
    #: :class:`CrossingContact`: the crossing pairs carrying force (contact
    #: option ``crossing``; None without it)
    crossing: CrossingContact = None

    @property
    def friction(self):
        return self.force_T is not None

    @property
    def total_force(self):
        """Sum of |f_N| ds over the slave points (both passes: twice the
        force that one stretch exerts on the other)."""
        return float(np.sum(self.force * self.weight))


class Result:
    """Converged load path of a rod, returned by :meth:`skfem_rod.Rod.solve`.

    Attributes
    ----------
    steps : list of Step
        Step 0 is the reference (load factor 0).
    converged : bool
        True when the load factor 1 was reached.
    message : str
        How the solve ended (where and why it stopped, if it did).
    log : list of str
        Step cuts and other events along the way.

    Examples
    --------
    >>> from skfem_rod import Rod, Section, geometry
    >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
    >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
    >>> result.converged, len(result.steps)
    (True, 3)
    >>> result.message
    'converged: 2 steps to the end of the load path (load factor 1)'
    >>> tip = result.position(1.0)          # at any arclength and step
    """

    def __init__(self, rod):
        self.rod = rod
        self.steps = []
        self.converged = False
        self.message = "not solved"
        self.log = []

    # building ----------------------------------------------------------
    def append(self, lam, r, R, report, time=None, contact=None):
        """Add a converged step (used by the solvers while they follow the
        load path): ``report`` is the step's :class:`skfem_rod.newton.Report`
        (its evaluation's residual is in the supports' bases, see
        ``Rod.support_basis``; reactions are stored spatial); ``contact``:
        the step's :class:`ContactState` where the solve builds it (the
        node barrier's, ``method="barrier"``), else from the evaluation.
        """
        ev = report.evaluation
        reactions = {}
        for n in self.rod.supports:
            if ev is None:
                reactions[n] = (np.zeros(3), np.zeros(3))
            else:
                res = ev.residual
                f, m = res[6 * n:6 * n + 3].copy(), res[6 * n + 3:6 * n + 6].copy()
                Q = self.rod.supports[n].basis
                if Q is not None:           # the residual is in the support's basis
                    f, m = Q @ f, Q @ m
                reactions[n] = (f, m)
        if contact is None and ev is not None and ev.contact is not None:
            contact = self._contact_state(ev.contact, report)
        self.steps.append(Step(load_factor=float(lam), r=r.copy(), R=R.copy(),
                               iterations=int(report.iterations),
                               residual_history=list(report.history),
                               energy=float(ev.internal.energy) if ev is not None else 0.0,
                               reactions=reactions, contact=contact,
                               time=float(lam if time is None else time),
                               flow_steps=int(report.flow_steps),
                               lowest_eigenvalue=report.lowest_eigenvalue,
                               relaxed_residual=report.relaxed_residual,
                               floor=report.floor))

    def _contact_state(self, ce, report):
        """:class:`ContactState` of a converged contact evaluation."""
        pairs, fN = ce.pairs, ce.fN
        act = fN > 0
        contact = ContactState(
            s=pairs.s[act], s_bar=pairs.s_bar[act],
            gap=ce.gap[act], force=fN[act], offset=ce.offset[act],
            normal=pairs.normal[act], weight=pairs.weight[act],
            penetration=float(report.penetration), uzawa=int(report.uzawa),
            uzawa_converged=bool(report.uzawa_converged),
            newton_total=int(report.newton_total or report.iterations),
            candidates=int(pairs.n_candidates), min_distance=report.min_distance)
        cp = ce.crossing
        if cp is not None:
            on = ce.crossing_fN > 0
            key = np.array(cp.key[on], dtype=float).reshape(-1, cp.key.shape[1])
            key[:, 4] = -1.0                  # no held index outside the solve
            friction, slip = np.zeros((cp.size, 3)), np.zeros((cp.size, 3))
            state = np.zeros(cp.size, dtype=int)
            cf = ce.crossing_friction
            if cf is not None:
                friction[cf.slave] = cp.weight[cf.slave, None] * cf.force_T
                slip[cf.slave], state[cf.slave] = cf.slip_T, cf.state_T
            contact.crossing = CrossingContact(
                s=cp.s[on], s_bar=cp.s_bar[on], force=ce.crossing_fN[on],
                weight=cp.weight[on], gap=ce.crossing_gap[on], normal=cp.normal[on],
                offset=ce.crossing_offset[on], angle=cp.beta[on], key=key,
                friction=friction[on], slip=slip[on], state=state[on])
        fr = ce.friction
        if fr is not None:
            w = pairs.weight[fr.index]
            contact.force_T, contact.force_R = fr.force_T, fr.force_R
            contact.state_T, contact.state_R = fr.state_T, fr.state_R
            contact.slip_T, contact.slip_R = fr.slip_T, fr.slip_R
            contact.dissipation = float(np.sum(w * (np.sum(fr.force_T * fr.slip_T, 1)
                                                    + np.sum(fr.force_R * fr.slip_R, 1))))
            if contact.crossing is not None:
                cr = contact.crossing
                contact.dissipation += float(np.sum(cr.friction * cr.slip))
        return contact

    def finish(self, converged, message):
        """Record how the solve ended (used by the solver).
        """
        self.converged = bool(converged)
        self.message = message

    def __repr__(self):
        return (f"Result(converged={self.converged}, steps={len(self.steps)}, "
                f"message={self.message!r})")

    # load path ---------------------------------------------------------
    @property
    def load_factors(self):
        """Load factor of every step, ``(n_steps,)``.

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> result.load_factors
        array([0. , 0.5, 1. ])
        """
        return np.array([s.load_factor for s in self.steps])

    @property
    def iterations(self):
        """Newton iterations of every step, ``(n_steps,)`` (0 for the
        reference state).

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> result.iterations.shape
        (3,)
        """
        return np.array([s.iterations for s in self.steps])

    @property
    def energies(self):
        """Strain energy of every step, ``(n_steps,)``.

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> bool(result.energies[0] == 0 and result.energies[2] > result.energies[1] > 0)
        True
        """
        return np.array([s.energy for s in self.steps])

    def reaction(self, where, step=-1):
        """Force and moment that the support at ``where`` exerts on the rod.

        Parameters
        ----------
        where : {"start", "end"} or float
            A supported node (see :meth:`skfem_rod.Rod.node`).
        step : int, default -1
            Step index.

        Returns
        -------
        force, moment : numpy.ndarray (3,)
            Spatial components; the moment is about the node.

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> force, moment = result.reaction("start")
        >>> np.round(force, 10) + 0.0                  # balances the tip load
        array([ 0.  , -0.01,  0.  ])
        """
        n = self.rod.node(where)
        st = self._step(step)
        if n not in st.reactions:
            held = sorted(float(self.rod.mesh.s_nodes[k]) for k in st.reactions)
            raise ValueError(f"where={where!r}: node {n} (s = {self.rod.mesh.s_nodes[n]:g}) "
                             "has no support, so no reaction; the supported nodes are at "
                             f"s = {', '.join(f'{x:g}' for x in held) or '(none)'}")
        return st.reactions[n]

    def _step(self, step):
        """The stored step ``step`` (an index, negative from the end);
        ValueError naming the valid range otherwise."""
        from .validation import step_index
        if not self.steps:
            raise ValueError("the result has no converged step")
        return self.steps[step_index(step, len(self.steps))]

    # fields --------------------------------------------------------------
    def nodes(self, step=-1):
        """Nodal arclengths, positions and rotations, ordered along the rod.

        Returns
        -------
        s : numpy.ndarray (n,)
        r : numpy.ndarray (n, 3)
        R : numpy.ndarray (n, 3, 3)
            Columns ``d1, d2, d3``.

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> s, r, R = result.nodes()
        >>> s.shape, r.shape, R.shape
        ((13,), (13, 3), (13, 3, 3))
        """
        o = self.rod.mesh.order
        st = self._step(step)
        return self.rod.mesh.s_nodes[o], st.r[o], st.R[o]

    def evaluate(self, s, step=-1):
        """Fields at arclengths ``s`` of a step.

        Returns a dict with ``r`` (n, 3), ``R`` (n, 3, 3), the strains ``v``,
        ``u`` and their reference values ``v0``, ``u0`` (material frame), and the
        spatial stress resultants ``n``, ``m`` (n, 3): force and moment that the
        part beyond ``s`` exerts on the part before it.

        Strains are those of the interpolated configuration.  The resultants are
        recovered from the Gauss points, where the strains of the displacement
        formulation are accurate (Barlow points), by the Lagrange polynomial
        through them: away from those points a stiff rod's ``EA (v3 - 1)``
        magnifies the interpolation error (a cantilever with EA = 1e6 gave
        n = (719, -231, 0) instead of (0, 5, 0) at the element ends).

        Parameters
        ----------
        s : float or array_like
            Arclengths in ``[0, length]``; for a scalar ``s`` every field
            drops its leading axis (``r`` is ``(3,)``, ``R`` is ``(3, 3)``).
        step : int, default -1

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> result.evaluate(0.5)["m"].shape
        (3,)
        >>> f = result.evaluate([0.25, 0.75])
        >>> np.round(f["n"], 8) + 0.0                  # the tip load, carried along the rod
        array([[0.  , 0.01, 0.  ],
               [0.  , 0.01, 0.  ]])
        """
        from .validation import arclengths
        mesh, rod = self.rod.mesh, self.rod
        scalar = np.ndim(s) == 0
        s = arclengths("s", s, mesh.length)
        if scalar:                                                  # scalar in, scalar out
            return {k: v[0] for k, v in self.evaluate(s, step).items()}
        st = self._step(step)
        e, xi = mesh.locate(s)
        eps, Rs, r = self._fields(e, xi[:, None], st.r, st.R)
        xg = np.asarray(mesh.sbasis.X[0], float)                   # Gauss points
        eg, Rg, _ = self._fields(e, np.broadcast_to(xg, (len(s), xg.size)), st.r, st.R)
        if getattr(rod, "natural", "reference") == "straight":     # unit stretch, nothing else
            eps0 = np.zeros_like(eps)
            eps0[..., 2] = 1.0
            eg0 = np.zeros_like(eg)
            eg0[..., 2] = 1.0
        else:
            eps0 = self._fields(e, xi[:, None], rod.r0, rod.R0)[0]
            eg0 = self._fields(e, np.broadcast_to(xg, (len(s), xg.size)), rod.r0, rod.R0)[0]
        Sg = (eg - eg0) @ rod.C.T                                   # (n, nq, 6)
        ng = np.einsum("nqij,nqj->nqi", Rg, Sg[..., :3])
        mg = np.einsum("nqij,nqj->nqi", Rg, Sg[..., 3:])
        lag = np.ones((len(s), xg.size))
        for k in range(xg.size):
            for j in range(xg.size):
                if j != k:
                    lag[:, k] *= (xi - xg[j]) / (xg[k] - xg[j])
        return dict(s=s, r=r[:, 0], R=Rs[:, 0], v=eps[:, 0, :3], u=eps[:, 0, 3:],
                    v0=eps0[:, 0, :3], u0=eps0[:, 0, 3:],
                    n=np.einsum("nq,nqi->ni", lag, ng), m=np.einsum("nq,nqi->ni", lag, mg))

    def _fields(self, e, xi, r, R):
        """Strains, rotations and positions at reference coordinates ``xi``
        ``(n, k)`` of elements ``e`` ``(n,)``."""
        mesh = self.rod.mesh
        h = (mesh.vertices[e + 1] - mesh.vertices[e])[:, None, None]
        N, dN, _ = shape_functions(xi)                            # (4, n, k)
        N, dN = np.moveaxis(N, 0, -1), np.moveaxis(dN, 0, -1) / h   # (n, k, 4)
        nodes = mesh.nodes[e]
        loc = local_coordinates(r[nodes], R[nodes])
        psi = np.einsum("nkI,nIi->nki", N, loc.psi)
        dpsi = np.einsum("nkI,nIi->nki", dN, loc.psi)
        drho = np.einsum("nkI,nIi->nki", dN, loc.rho)
        eps, Lam = strains(psi, dpsi, drho)
        return eps, loc.Rr[:, None] @ Lam, np.einsum("nkI,nIi->nki", N, r[nodes])

    def position(self, s, step=-1):
        """Positions at arclengths ``s``, ``(n, 3)`` (``(3,)`` for a scalar ``s``).

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> result.position([0.0, 1.0]).shape, result.position(1.0).shape
        ((2, 3), (3,))
        """
        return self.evaluate(s, step)["r"]

    def frame(self, s, step=-1):
        """Rotations (columns ``d1, d2, d3``) at arclengths ``s``, ``(n, 3, 3)``
        (``(3, 3)`` for a scalar ``s``).

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> R = result.frame(1.0)
        >>> bool(np.allclose(R.T @ R, np.eye(3)))
        True
        """
        return self.evaluate(s, step)["R"]

    def sample(self, per_element=8, step=-1):
        """Fields (as :meth:`evaluate`) at ``per_element`` uniform intervals
        per element, ends included: ``n_elements * per_element + 1`` points.

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> result.sample(per_element=2)["r"].shape
        (9, 3)
        """
        from .validation import count
        n = self.rod.mesh.n_elements * count("per_element", per_element, 1, 1024) + 1
        return self.evaluate(np.linspace(0, self.rod.length, n), step)

    # output ------------------------------------------------------------------
    def point_data(self, step=-1, per_element=8):
        """Sampled fields of a step and the point data written to VTU files
        (arclength, resultants ``n``, ``m``, strains ``v``, ``u``, twist strain,
        and ``contact_force`` when contact is on; ``crossing_force``, the point
        forces of the crossing pairs at the samples nearest to their two
        points, with the contact option ``crossing``).

        Returns
        -------
        fields : dict
            As :meth:`sample`.
        data : dict of numpy.ndarray

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> f, data = result.point_data()
        >>> sorted(data)
        ['arclength', 'm', 'n', 'twist', 'u', 'v']
        """
        f = self.sample(per_element, step)
        data = dict(arclength=f["s"], n=f["n"], m=f["m"], v=f["v"], u=f["u"],
                    twist=f["u"][:, 2] - f["u0"][:, 2])
        c = self._step(step).contact
        if self.rod.contact is not None:
            fc = np.zeros(len(f["s"]))
            if c is not None and c.s.size:
                k = np.abs(f["s"][None, :] - c.s[:, None]).argmin(axis=1)
                np.maximum.at(fc, k, c.force)
            data["contact_force"] = fc
            if self.rod.contact.crossing:
                # point forces of the crossing pairs, at the sample nearest
                # to each of a pair's two points
                xf = np.zeros(len(f["s"]))
                cr = None if c is None else c.crossing
                if cr is not None and cr.s.size:
                    at = np.r_[cr.s, cr.s_bar]
                    k = np.abs(f["s"][None, :] - at[:, None]).argmin(axis=1)
                    np.maximum.at(xf, k, np.r_[cr.force, cr.force])
                data["crossing_force"] = xf
        return f, data

    def write_vtu(self, path, step=-1, per_element=8):
        """Write one step as a VTU polyline with frames and resultants; with
        contact, the point data ``contact_force`` holds f_N (per unit length)
        at the sample nearest to each active contact point.

        Returns
        -------
        str
            ``path``.

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> result.write_vtu("cantilever.vtu")
        'cantilever.vtu'
        """
        from .export import write_vtu
        f, pdata = self.point_data(step, per_element)
        return write_vtu(path, f["r"], f["R"], pdata)

    def write_series(self, directory, basename="rod", per_element=8):
        """Write every step (one VTU each) plus the time series files
        ``basename.pvd`` (ParaView) and ``basename.xdmf``, atomically.

        Returns
        -------
        list of str
            The files written.

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> files = result.write_series("out", "cantilever")
        >>> sorted(f.rsplit("/", 1)[-1] for f in files)[:2]
        ['cantilever.pvd', 'cantilever.xdmf']
        """
        from .export import write_series
        steps = []
        for k, st in enumerate(self.steps):
            f, pdata = self.point_data(k, per_element)
            steps.append(dict(time=st.time, points=f["r"], frames=f["R"],
                              point_data=pdata))
        return write_series(directory, basename, steps)

    def topology(self, step=-1, per_element=16):
        """Twist, writhe and link (in turns) of the rod at a step.

        The open rod is closed far away along its end tangents (the standard
        closure for rods with held ends, :func:`skfem_rod.topology.closure`),
        which adds no writhe; ``twist`` is the twist of the rod itself (the
        closure's compensating partial turn, ``closure_twist``, removed) and
        ``link = twist + writhe``: for a rod whose ends are turned by
        ``phi`` it equals ``phi / 2 pi`` (Calugareanu-White).  ``link_gauss``
        is the Gauss linking number of the closed ribbon (an integer).
        A closed rod (ring) is its own closed curve: ``link = twist +
        writhe`` with no closure.

        Returns
        -------
        skfem_rod.topology.Topology

        Examples
        --------
        One turn of twist on a straight rod: all twist, no writhe.

        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> rod = rod.clamp("start").pin("end").prescribe_rotation("end", [2 * np.pi, 0, 0])
        >>> t = rod.solve(2).topology()
        >>> round(t.twist, 6), round(abs(t.writhe), 6), round(t.link, 6)
        (1.0, 0.0, 1.0)
        """
        from dataclasses import replace
        from .topology import topology
        f = self.sample(per_element, step)
        if getattr(self.rod.mesh, "closed", False):     # a ring: no closure
            return topology(f["r"][:-1], f["R"][:-1, :, 0], closed=True)
        t = topology(f["r"], f["R"][:, :, 0], t_start=f["R"][0][:, 2],
                     t_end=f["R"][-1][:, 2])
        tw = t.twist - t.closure_twist
        return replace(t, twist=tw, link=tw + t.writhe)

    def dissipated_energy(self):
        """Cumulative friction work dissipated along the path, one value per
        step (all zeros without friction; step 0 holds what the settling of
        preloads dissipated, if any), ``(n_steps,)``.

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 2)
        >>> rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2).dissipated_energy()
        array([0., 0., 0.])
        """
        d = [st.contact.dissipation if st.contact is not None and st.contact.friction else 0.0
             for st in self.steps]
        return np.cumsum(d)

    def contact_states(self, step=-1):
        """Friction state of the active contact points of a step, ``(m,)``:
        0 open (no friction), 1 stick, 2 slip -- a point slips if the
        tangential or the rotational law slips (the laws whose coefficient
        is positive); all 0 without friction, empty without contact.

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> result.contact_states().shape
        (0,)
        """
        c = self._step(step).contact
        if c is None:
            return np.zeros(0, int)
        if not c.friction:
            return np.zeros(c.s.size, int)
        opts = self.rod.contact
        laws = [st for g, st in ((opts.gamma_T, c.state_T), (opts.gamma_R, c.state_R)) if g > 0]
        return np.max(laws, axis=0).astype(int)

    def contact_points(self, step=-1):
        """Positions of the active contact (slave) points of a step, ``(m, 3)``
        (empty without contact).

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> result.contact_points().shape
        (0, 3)
        """
        c = self._step(step).contact
        if c is None or c.s.size == 0:
            return np.zeros((0, 3))
        return self.evaluate(c.s, step)["r"]

    def crossing_points(self, step=-1):
        """Where the crossing pairs of a step that carry force act, ``(k, 3)``:
        the midpoint of each pair's two centreline points, on the tubes'
        surfaces where they touch (empty without contact or without the
        contact option ``crossing``).  :attr:`ContactState.crossing` holds
        their forces.

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> rod = rod.clamp("start").enable_contact(crossing=True)
        >>> result = rod.add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> result.crossing_points().shape
        (0, 3)
        """
        c = self._step(step).contact
        if c is None or c.crossing is None or c.crossing.s.size == 0:
            return np.zeros((0, 3))
        x = self.evaluate(np.r_[c.crossing.s, c.crossing.s_bar], step)["r"]
        return 0.5 * (x[:c.crossing.s.size] + x[c.crossing.s.size:])

    def render(self, filename, step=-1, radius=None, per_element=8, **kwargs):
        """Offscreen PNG of the rod at a step as a tube with a stripe along
        ``d1``, with the reference shape (step 0) as a grey ghost, the
        supports and the point loads of the step, and an axes triad; active
        contact points are marked (unless ``contact_points`` is given):
        frictionless purple, or coloured by state with friction on (stick
        green, slip orange, see :func:`skfem_rod.render.contact_state_colors`),
        and the crossing pairs carrying force (:meth:`crossing_points`) in
        :data:`skfem_rod.render.CROSSING_COLOR`.
        ``color_by="moment_magnitude"`` (or any scalar field of
        :meth:`to_pyvista`: ``twist``, ``curvature``, ``contact_force`` ...)
        colours the tube by that field, with a colour bar.

        Parameters
        ----------
        filename : str or os.PathLike
        step : int, default -1
        radius : float, optional
            Tube radius; default the section's radius (else 1 % of the length).
        per_element : int, default 8
            Samples of the centreline per element.
        **kwargs
            ``color_by``, or passed to :func:`skfem_rod.render.render_rod`
            (``window_size``, ``camera``, ``title``, ``glyphs``,
            ``contact_colors``, ``reference=None`` to hide the ghost ...).

        Returns
        -------
        str
            ``filename``.

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> result.render("cantilever.png", window_size=(320, 240), title="cantilever")
        'cantilever.png'
        """
        from .render import FIELD_LABELS, render_rod
        f = self.sample(per_element, step)
        if radius is None:
            radius = self.rod.section.radius or 0.01 * self.rod.length
        given = "contact_points" in kwargs
        if not given:
            pts = self.contact_points(step)
            if len(pts):
                kwargs["contact_points"] = pts
                if (self.steps[step].contact.friction and "contact_colors" not in kwargs
                        and "contact_states" not in kwargs):
                    kwargs["contact_states"] = self.contact_states(step)
        if "crossing_points" not in kwargs and not given:
            pts = self.crossing_points(step)
            if len(pts):
                kwargs["crossing_points"] = pts
        color_by = kwargs.pop("color_by", None)
        if color_by is not None and "scalars" not in kwargs:
            kwargs["scalars"] = self._line_fields(f, step)[color_by]
            kwargs.setdefault("scalar_label", FIELD_LABELS.get(color_by, color_by))
        for key, value in self._scene_extras(step, per_element).items():
            kwargs.setdefault(key, value)
        return render_rod(filename, f["r"], f["R"], radius, **kwargs)

    # notebooks -----------------------------------------------------------
    def _line_fields(self, f, step=-1):
        """Scalar and vector fields at the samples ``f`` (from :meth:`sample`)
        of a step: the arrays of :meth:`to_pyvista`."""
        c = self.steps[step].contact
        n = len(f["s"])
        curv = np.linalg.norm(f["u"][:, :2] - f["u0"][:, :2], axis=1)
        fields = dict(arclength=f["s"], force=f["n"], moment=f["m"],
                      moment_magnitude=np.linalg.norm(f["m"], axis=1),
                      force_magnitude=np.linalg.norm(f["n"], axis=1),
                      twist=f["u"][:, 2] - f["u0"][:, 2], curvature=curv,
                      stretch=f["v"][:, 2] - f["v0"][:, 2],
                      shear=np.linalg.norm(f["v"][:, :2] - f["v0"][:, :2], axis=1),
                      strain_v=f["v"] - f["v0"], strain_u=f["u"] - f["u0"],
                      contact_force=np.zeros(n), contact_state=np.full(n, -1))
        if c is not None and c.s.size:
            k = np.abs(f["s"][None, :] - c.s[:, None]).argmin(axis=1)
            np.maximum.at(fields["contact_force"], k, c.force)
            np.maximum.at(fields["contact_state"], k, self.contact_states(step))
        return fields

    def _scene_extras(self, step=-1, per_element=8):
        """Reference ghost (step 0), supports and loads of a step, as the
        keyword arguments ``reference``, ``supports``, ``loads`` of
        :func:`skfem_rod.render.render_rod`."""
        rod, st = self.rod, self.steps[step]
        f0 = self.sample(per_element, 0)
        supports = []
        for node, sup in rod.supports.items():
            pos, rot = np.all(sup.position), np.all(sup.rotation)
            kind = ("turn" if np.any(sup.rotation_vector != 0) else
                    "move" if np.any(sup.displacement != 0) else
                    "clamp" if pos and rot else "pin" if pos else "slide")
            supports.append({"point": st.r[node], "kind": kind})
        loads = []
        for ld in getattr(rod, "point_loads", ()):
            lam = 1.0 if ld.constant else st.load_factor
            v = np.asarray(ld.vector, float) * lam
            if ld.follower:
                v = st.R[ld.node] @ np.asarray(ld.vector, float) * lam
            if np.linalg.norm(v) > 0:
                loads.append({"point": st.r[ld.node], "vector": v, "kind": ld.kind})
        moved = step not in (0, -len(self.steps))
        return {"reference": (f0["r"], f0["R"]) if moved else None,
                "supports": supports, "loads": loads}

    def to_pyvista(self, step=-1, per_element=8, radius=None, n_around=24):
        """The rod at a step as a tube (``pyvista.PolyData``) carrying the
        mechanical fields, for notebooks and ParaView.

        Point data (per tube point, from the centreline sample of its ring;
        the ``d1`` stripe arrays of :func:`skfem_rod.render.tube_mesh` too):
        ``arclength``; ``force``, ``moment`` (3-vectors: the stress
        resultants ``n``, ``m``) and their magnitudes ``force_magnitude``,
        ``moment_magnitude``; ``twist`` (``u3 - u3⁰``), ``curvature``
        (``|u₁₂ - u₁₂⁰|``), ``stretch`` (``v3 - v3⁰``), ``shear``;
        ``strain_v``, ``strain_u`` (3-vectors, material frame);
        ``contact_force`` (``f_N`` per unit length at the sample nearest to
        each active contact point, else 0) and ``contact_state`` (-1 no
        contact, else 0 open/frictionless, 1 stick, 2 slip).

        Parameters
        ----------
        step : int, default -1
        per_element : int, default 8
            Samples of the centreline per element.
        radius : float, optional
            Tube radius; default the section's radius (else 1 % of the length).
        n_around : int, default 24
            Points per ring.

        Returns
        -------
        pyvista.PolyData

        Examples
        --------
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> tube = result.to_pyvista()
        >>> tube.n_points, "moment" in tube.point_data, int(tube.point_data["contact_state"].max())
        (842, True, -1)
        >>> round(float(tube.point_data["moment_magnitude"].max()), 3)   # about P L at the clamp
        0.01
        """
        from .render import tube_point_values, tube_mesh
        f = self.sample(per_element, step)
        if radius is None:
            radius = self.rod.section.radius or 0.01 * self.rod.length
        tube = tube_mesh(f["r"], f["R"], radius, n_around=n_around)
        n = len(f["s"])
        for name, value in self._line_fields(f, step).items():
            value = np.asarray(value)
            if value.ndim == 1:
                tube.point_data[name] = tube_point_values(value, n, n_around)
            else:
                tube.point_data[name] = np.vstack(
                    [np.repeat(value, n_around, axis=0),
                     np.repeat(value[:1], n_around + 1, axis=0),
                     np.repeat(value[-1:], n_around + 1, axis=0)])
        tube.field_data["load_factor"] = np.array([self.steps[step].load_factor])
        return tube

    def plot(self, ax=None, step=-1, plane=None, reference=True, contacts=True,
             per_element=8, **kwargs):
        """Draw the centreline of a step with matplotlib.

        The reference shape (step 0) is drawn dashed grey, active contact
        points as dots (frictionless purple, stick green, slip orange: the
        colours of :mod:`skfem_rod.render`), supports as squares.

        Parameters
        ----------
        ax : matplotlib Axes, optional
            A 3D axes (``projection="3d"``) draws in 3D; a 2D axes draws the
            projection on ``plane``.  Default: a new 3D axes.
        step : int, default -1
        plane : str, optional
            ``"xy"``, ``"xz"`` or ``"yz"`` for a 2D axes (default ``"xy"``).
        reference, contacts : bool, default True
            Draw the reference shape; mark the contact points.
        per_element : int, default 8
        **kwargs
            Passed to ``ax.plot`` for the centreline.

        Returns
        -------
        matplotlib Axes

        Examples
        --------
        >>> import matplotlib
        >>> matplotlib.use("Agg")
        >>> import matplotlib.pyplot as plt
        >>> from skfem_rod import Rod, Section, geometry
        >>> rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
        >>> result = rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(2)
        >>> ax = result.plot(plt.figure().add_subplot(), plane="xy")
        >>> ax.get_xlabel(), ax.get_ylabel()
        ('x', 'y')
        """
        import matplotlib.pyplot as plt

        from .render import CONTACT_COLOR, REFERENCE_COLOR, ROD_COLOR, STATE_COLORS
        if ax is None:
            ax = plt.figure().add_subplot(projection="3d")
        three_d = hasattr(ax, "get_zlim")
        axis = {"x": 0, "y": 1, "z": 2}
        plane = plane or "xy"
        if three_d:
            cols = [0, 1, 2]
        elif len(plane) == 2 and set(plane) <= set(axis) and plane[0] != plane[1]:
            cols = [axis[c] for c in plane]
        else:
            raise ValueError(f"plane = {plane!r}; expected 'xy', 'xz' or 'yz'")

        def draw(points, **kw):
            return ax.plot(*(points[:, c] for c in cols), **kw)

        f = self.sample(per_element, step)
        shown = set(ax.get_legend_handles_labels()[1])

        def label(name):          # each legend entry once per axes
            return "_nolegend_" if name in shown else name

        if reference and step not in (0, -len(self.steps)):
            draw(self.sample(per_element, 0)["r"], color=REFERENCE_COLOR, ls="--", lw=1.2,
                 label=label("reference"))
        kw = dict(color=ROD_COLOR, lw=2.5, label=f"load factor {self.steps[step].load_factor:.3g}")
        kw.update(kwargs)
        draw(f["r"], **kw)
        st = self.steps[step]
        sup = np.array([st.r[n] for n in self.rod.supports]).reshape(-1, 3)
        if len(sup):
            draw(sup, ls="none", marker="s", ms=8, color="#555555", label=label("support"))
        if contacts:
            pts, states = self.contact_points(step), self.contact_states(step)
            if len(pts):
                friction = st.contact.friction
                colors = [STATE_COLORS[k] if friction else CONTACT_COLOR for k in states]
                ax.scatter(*(pts[:, c] for c in cols), c=colors, s=18, zorder=3,
                           label=label("contact"))
        for c, name in zip(cols, ("xlabel", "ylabel", "zlabel")):
            getattr(ax, f"set_{name}")("xyz"[c])
        if three_d:                       # equal scales: a cube around what is drawn
            pts = np.vstack([f["r"], self.sample(per_element, 0)["r"]] if reference
                            else [f["r"]])
            centre = (pts.min(axis=0) + pts.max(axis=0)) / 2
            half = np.ptp(pts, axis=0).max() / 2 or 1.0
            for c, name in zip(cols, ("xlim", "ylim", "zlim")):
                getattr(ax, f"set_{name}")(centre[c] - half, centre[c] + half)
            ax.set_box_aspect((1, 1, 1))
        else:
            ax.set_aspect("equal", adjustable="datalim")
        return ax
