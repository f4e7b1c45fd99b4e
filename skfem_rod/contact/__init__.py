"""Self-contact: search (:mod:`.search`), normal law (:mod:`.law`), the
nonlocal assembler (:mod:`.assembly`), and Coulomb self-friction: the law
(:mod:`.friction`), the slip kinematics (:mod:`.slip`) and the assembler
(:mod:`.friction_assembly`).  :class:`ContactOptions` holds the
parameters; ``Rod.enable_contact`` switches contact on (off by default, and
then no contact code runs)."""
from dataclasses import MISSING, dataclass, field, fields

import numpy as np

from ..options import Spec


def _field(default, kind, doc, **kw):
    """A field of :class:`ContactOptions` with its :class:`Spec` (the one
    place the option is checked; the scene's ``[contact]`` keys and their
    docs are built from it)."""
    return field(default=default, metadata={"spec": Spec(kind, doc, **kw)})


#: a state on the way (a damped step of the pseudo-dynamics, a push off a
#: saddle) whose strands overlap by more than this fraction of the contact
#: radius between slave points (away from the rod's ends) is rejected: a
#: strand passing through another (a crossing between slave points: 0.9 eps
#: measured) is caught.  An equilibrium that is recorded must hold the
#: true distance to the contact tolerance (``augmented.finish``; the gap
#: offsets of ``augmented.adjust_offsets`` close what the slave points
#: miss), and this is also the most its gap offsets may reach.
OVERLAP_FAIL = 0.1

#: options derived from others when not given (None): name -> how
_DERIVED = ("margin", "mu_T", "mu_R", "crossing_penalty", "crossing_sampling")


@dataclass
class ContactOptions:
    """Parameters of the self-contact (all lengths in the rod's units).

    radius : contact radius ``eps`` (the paper's; default: section radius).
    penalty : compliance ``mu_N`` of eq. 4.2a (force = penetration / mu_N per
        unit length); default ``10 eps^4 / EI``: a contact stiffness of a
        tenth of the bending stiffness at the scale of the radius.  Stiffer
        penalties made Newton chatter when contact switches on (a hairpin
        closing on itself needed 14 steps with cuts at ``0.1 eps^4/EI``, 6
        without at ``10 eps^4/EI``, same contact force to 4 digits); Uzawa
        recovers the accuracy.
    exclusion : excluded arclength ``I_s`` around a slave; default
        ``pi eps`` (see :mod:`.search`).
    n_slave : slave (Gauss) points per element (default 3, the paper's).
    tolerance : Uzawa stops when the largest penetration is below
        ``tolerance * eps`` (default 1e-3).
    max_uzawa : largest number of Uzawa updates per load step.
    margin : extra search reach beyond ``2 eps`` (default ``eps``).
    gamma_T : tangential Coulomb coefficient (dimensionless, eq. 3.10a-b)
        of the axial sliding; default 0.
    gamma_R : rotational Coulomb coefficient, a length (eq. 3.10c-d), of the
        circumferential sliding (around the rod's axis, docs/friction.md F7):
        ``|f_R| <= gamma_R f_N``; default 0.  With ``gamma_T = gamma_R = 0``
        (the default) no friction code runs.
    mu_T : tangential compliance (slip increment per unit friction force
        per unit length, eq. 4.2b); default ``penalty``.
    mu_R : rotational compliance (rotation increment per unit couple per
        unit length, eq. 4.2c); default ``penalty / eps**2``.
    friction_tolerance : Uzawa also iterates until every friction
        multiplier moved by less than ``friction_tolerance * gamma f_N``
        (largest over the points) and the force of every slipping point is
        within ``friction_tolerance * gamma f_N`` of its slip's direction
        (``friction_assembly.coulomb_misfit``); default 1e-3.
    penalty_growth : adaptive penalty of the Uzawa loop (the method of
        multipliers' penalty update, ``augmented.adapt_penalty``): at a point
        still short of its tolerance whose violation did not drop by a factor
        4 over an update, the penalty stiffness ``1 / mu_N`` is multiplied by
        ``penalty_growth`` for the rest of the load step (the next step
        starts from there, or at the nominal penalty without
        ``penalty_memory``); the crossing pairs' one factor likewise
        (``augmented.adapt_crossing_penalty``); default 4; 1 keeps the
        penalty fixed.
        The converged answer is the same to the tolerances; only the number
        of updates changes.
    max_penalty_scale : cap of that growth, as a multiple of the nominal
        penalty stiffness; default 1000.
    penalty_memory : a step's Uzawa loop starts at the normal penalty
        factors (per slave point) the last step's loop ended with, instead
        of the nominal penalty; a first pass that fails with them is solved
        again at the nominal one.  Default False.  Where a load path meets
        the same contacts step after step it saves Uzawa passes: the
        frictionless knot cycle, whose penalty grew to 16-64 times in
        nearly every step, took 0.6 of the time with it.  Where contacts
        change or slide it costs: the frictional knot (``gamma_T = 0.2``)
        took 1.7 times longer, the plectoneme's snap three times as many
        damped steps (docs/knot.md).  Measured again on 2026-11-30
        (benchmarks/RESULTS_plectoneme.md): past the plectoneme's fold,
        where the penalty reaches its cap in every step and the nominal
        one at the next step's start lets the contact sink by 0.09-0.18
        eps, it carries the 200-element winding to 3.06 turns in 112 s
        (without it: 1.875 turns in 900 s); the knot's cycles took 24.5 s
        without friction (11.7-19 s without the option: no longer the
        saving above) and 213 s with ``gamma_T = 0.2`` (52.6 s), so it
        stays off.  The converged state is the nominal
        penalty's to the tolerances either way (the reported state, the
        stability checks and the next step's predictor see the nominal
        penalty).
    rotational_slip : what the rotational law acts on
        (:class:`.friction_assembly.FrictionParams`, docs/friction.md F7):
        ``"twist"`` (default), ``"circumferential"`` or ``"pivot"``.
    curve : the curve the contact acts on (:mod:`.curve`): ``"elements"``
        (default), the rod's P3 centreline, C0 at the nodes; ``"smooth"``, a
        C1 cubic through the nodes (tangents at the vertices from the two
        elements beside them), O(h^4) from the centreline: the contact
        normal and distance have no kinks where a closest point passes a
        node.
    crossing : add point-to-point contact pairs at the closest points of
        crossing strands (:mod:`.crossing`); default False.
    crossing_penalty : compliance of the crossing pairs' point law (length
        per unit force); default ``penalty / radius``.
    crossing_friction : with ``gamma_T > 0``, tangential Coulomb friction at
        the crossing pairs too (:func:`.friction_assembly.crossing_friction_work`);
        default True.  The rotational law stays with the Gauss slave points.
    crossing_angle : cap of the angle at which a strict minimum of the
        strand distance gets a crossing pair of full weight (radians,
        default 15 degrees): ``min(crossing_angle, beta_h)``, ``beta_h``
        the angle below which the Gauss slave points alone hold the
        minimum (:func:`.crossing.sampled_angle`), measured at the sampling
        scale; flatter minima fade out (docs/crossing-contact.md).
    offsets : the gap offsets (:func:`skfem_rod.augmented.adjust_offsets`)
        a recorded step starts from: ``"carried"`` (default) the last
        step's, lowered only where the strands stand open by more than the
        tolerance, so they remember the path (0.1 of the tolerance in
        positions in the squeezed loop, 3.2 % of the force in the knot's
        cycle); ``"state"`` from 0, raised where the state's strands dip
        between the points that carry the contact, so they are the
        state's and a frictionless path comes back through the same states,
        at the price of the offset rounds of every step
        (docs/crossing-contact.md, "Gap offsets").
    crossing_sampling : the tolerance (times eps) in ``beta_h``: a minimum
        the Gauss slave points sample to ``SAMPLING_SHARE`` of it stays with
        them (default: ``tolerance``).  Above ``tolerance`` the slave
        points' sag at such minima is held by the gap offsets
        (:func:`skfem_rod.augmented.adjust_offsets`), and the true distance
        is still checked against ``tolerance``.
    """
    radius: float = _field(MISSING, "number", "contact radius eps (default: section radius)",
                           lo=0.0)
    penalty: float = _field(MISSING, "number", "compliance mu_N (default 10 eps^4 / EI)",
                            lo=0.0)
    exclusion: float = _field(MISSING, "number", "excluded arclength (default pi eps)", lo=0.0)
    n_slave: int = _field(3, "integer", "slave points per element", lo=1, hi=20)
    tolerance: float = _field(1e-3, "number", "Uzawa tolerance (times eps)", lo=0.0)
    max_uzawa: int = _field(30, "integer", "Uzawa updates per step", lo=1, hi=10_000)
    margin: float = _field(None, "number", "extra search reach (default eps)", lo=0.0,
                           lo_open=False)
    gamma_T: float = _field(0.0, "number", "tangential Coulomb coefficient (0: no friction)",
                            lo=0.0, lo_open=False)
    gamma_R: float = _field(0.0, "number", "rotational Coulomb coefficient, a length (0: none)",
                            lo=0.0, lo_open=False)
    mu_T: float = _field(None, "number", "tangential friction compliance (default: penalty)",
                         lo=0.0)
    mu_R: float = _field(None, "number", "rotational friction compliance (default: penalty "
                                         "/ eps^2)", lo=0.0)
    friction_tolerance: float = _field(1e-3, "number", "Uzawa tolerance of the friction "
                                                       "multipliers and of the forces' "
                                                       "alignment with the slip (times "
                                                       "gamma f_N)", lo=0.0)
    penalty_growth: float = _field(4.0, "number", "adaptive Uzawa penalty: growth factor where "
                                                  "the violation stalls (1: fixed penalty)",
                                   lo=1.0, lo_open=False)
    max_penalty_scale: float = _field(1e3, "number", "cap of the adaptive penalty (times the "
                                                     "nominal one)", lo=1.0, lo_open=False)
    penalty_memory: bool = _field(False, "boolean", "a step's Uzawa loop starts at the normal "
                                                    "penalty factors the last step ended with")
    rotational_slip: str = _field("twist", "choice", "what the rotational friction law acts on",
                                  choices=("twist", "circumferential", "pivot"))
    curve: str = _field("elements", "choice", "the curve the contact acts on: the P3 "
                                             "centreline (C0 at nodes) or a C1 cubic through "
                                             "its nodes", choices=("elements", "smooth"))
    crossing: bool = _field(False, "boolean", "point-to-point pairs at the closest points of "
                                              "crossing strands")
    crossing_penalty: float = _field(None, "number", "compliance of the crossing pairs "
                                                     "(default penalty / eps)", lo=0.0)
    crossing_friction: bool = _field(True, "boolean", "Coulomb friction (gamma_T) at the "
                                                      "crossing pairs too")
    crossing_angle: float = _field(float(np.radians(15.0)), "number",
                                   "cap of the angle at which a distance minimum gets a "
                                   "crossing pair of full weight (rad, below pi/2; the "
                                   "Gauss-sampling bound beta_h lowers it)", lo=0.0,
                                   hi=float(np.pi / 2))
    offsets: str = _field("carried", "choice", "the gap offsets a step starts from: the "
                                               "last step's or 0 (raised to the state's)",
                          choices=("state", "carried"))
    crossing_sampling: float = _field(None, "number", "the sampling tolerance (times eps) "
                                                      "that sets beta_h: minima the Gauss "
                                                      "slave points sample to it stay with "
                                                      "them (default: tolerance)", lo=0.0)

    @property
    def friction(self):
        """True when a friction coefficient is positive."""
        return self.gamma_T > 0 or self.gamma_R > 0

    def __post_init__(self):
        # the given values first (the derived defaults are computed from them)
        for f in fields(self):
            v = getattr(self, f.name)
            if not (v is None and f.name in _DERIVED):
                f.metadata["spec"].check(f"contact {f.name}", v)
        derived = dict(margin=self.radius, mu_T=self.penalty,
                       mu_R=self.penalty / self.radius ** 2,
                       crossing_penalty=self.penalty / self.radius,
                       crossing_sampling=self.tolerance)
        for f in fields(self):
            if f.name in _DERIVED and getattr(self, f.name) is None:
                setattr(self, f.name, derived[f.name])
                f.metadata["spec"].check(f"contact {f.name}", getattr(self, f.name))
        if self.crossing_angle >= np.pi / 2:
            raise ValueError("contact crossing_angle must be below pi/2 (strands at a right "
                             f"angle always cross), got {self.crossing_angle!r}")

    def friction_params(self, push_forward=True, scale_T=1.0, scale_R=1.0):
        """The :class:`.friction_assembly.FrictionParams` of these options
        (``scale_*`` divide the compliances: the adaptive penalty factors)."""
        from .friction_assembly import FrictionParams
        return FrictionParams(self.gamma_T, self.gamma_R, self.mu_T / scale_T,
                              self.mu_R / scale_R, push_forward, self.rotational_slip)

    def crossing_friction_params(self, scale=1.0):
        """The :class:`.friction_assembly.FrictionParams` of the crossing
        pairs (docs/crossing-contact.md, "Friction at the crossing pairs"):
        the tangential law, its compliance per unit point force
        ``mu_T crossing_penalty / penalty`` (as the normal law's), divided
        by ``scale`` (the adaptive penalty factors), on the whole slip in the
        tangent plane whatever ``rotational_slip`` says (its split hands
        the circumferential sliding to the rotational law); no rotational
        law at a point pair."""
        from .friction_assembly import FrictionParams
        mu = self.mu_T * self.crossing_penalty / self.penalty / scale
        return FrictionParams(self.gamma_T, 0.0, mu, 1.0, True, "twist")

    def crossing_threshold(self):
        """The :class:`.crossing.PairThreshold` of these options: which
        minima of the strand distance get a crossing pair."""
        from .crossing import PairThreshold
        return PairThreshold(self.crossing_angle, self.n_slave, self.crossing_sampling)
