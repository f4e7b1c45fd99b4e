"""Self-contact: search (:mod:`.search`), normal law (:mod:`.law`), the
nonlocal assembler (:mod:`.assembly`), and Coulomb self-friction: the law
(:mod:`.friction`), the slip kinematics (:mod:`.slip`) and the assembler
(:mod:`.friction_assembly`).  :class:`ContactOptions` holds the
parameters; ``Rod.enable_contact`` switches contact on (off by default, and
then no contact code runs)."""
from dataclasses import dataclass

import numpy as np


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
        (largest over the points); default 1e-3.
    penalty_growth : adaptive penalty of the Uzawa loop (the method of
        multipliers' penalty update, ``solver._adapt_penalty``): at a point
        still short of its tolerance whose violation did not drop by a factor
        4 over an update, the penalty stiffness ``1 / mu_N`` is multiplied by
        ``penalty_growth`` for the rest of the load step (every step starts
        at the nominal penalty); default 4; 1 keeps the penalty fixed.
        The converged answer is the same to the tolerances; only the number
        of updates changes.
    max_penalty_scale : cap of that growth, as a multiple of the nominal
        penalty stiffness; default 1000.
    rotational_slip : what the rotational law acts on
        (:class:`.friction_assembly.FrictionParams`, docs/friction.md F7):
        ``"twist"`` (default), ``"circumferential"`` or ``"pivot"``.
    crossing : add point-to-point contact pairs at the closest points of
        crossing strands (:mod:`.crossing`); default False.
    crossing_penalty : compliance of the crossing pairs' point law (length
        per unit force); default ``penalty / radius``.
    crossing_angle : crossing pairs only where the strands' tangents make
        more than this angle (radians); default 15 degrees.
    """
    radius: float
    penalty: float
    exclusion: float
    n_slave: int = 3
    tolerance: float = 1e-3
    max_uzawa: int = 30
    margin: float = None
    gamma_T: float = 0.0
    gamma_R: float = 0.0
    mu_T: float = None
    mu_R: float = None
    friction_tolerance: float = 1e-3
    penalty_growth: float = 4.0
    max_penalty_scale: float = 1e3
    rotational_slip: str = "twist"
    crossing: bool = False
    crossing_penalty: float = None
    crossing_angle: float = float(np.radians(15.0))

    @property
    def friction(self):
        """True when a friction coefficient is positive."""
        return self.gamma_T > 0 or self.gamma_R > 0

    def __post_init__(self):
        for name in ("radius", "penalty", "exclusion", "tolerance"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float, np.floating))
                                           and np.isfinite(v) and v > 0):
                raise ValueError(f"contact {name} must be a finite number > 0, got {v!r}")
        for name in ("n_slave", "max_uzawa"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, np.integer)) and v >= 1):
                raise ValueError(f"contact {name} must be an integer >= 1, got {v!r}")
        if self.margin is None:
            self.margin = self.radius
        if not (np.isfinite(self.margin) and self.margin >= 0):
            raise ValueError(f"contact margin must be a finite number >= 0, got {self.margin!r}")
        for name in ("gamma_T", "gamma_R"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float, np.floating))
                                           and np.isfinite(v) and v >= 0):
                raise ValueError(f"contact {name} must be a finite number >= 0, got {v!r}")
        if self.mu_T is None:
            self.mu_T = self.penalty
        if self.mu_R is None:
            self.mu_R = self.penalty / self.radius ** 2
        for name in ("penalty_growth", "max_penalty_scale"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float, np.floating))
                                           and np.isfinite(v) and v >= 1):
                raise ValueError(f"contact {name} must be a finite number >= 1, got {v!r}")
        for name in ("mu_T", "mu_R", "friction_tolerance"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float, np.floating))
                                           and np.isfinite(v) and v > 0):
                raise ValueError(f"contact {name} must be a finite number > 0, got {v!r}")
        if self.rotational_slip not in ("twist", "circumferential", "pivot"):
            raise ValueError("contact rotational_slip must be 'twist', 'circumferential' or "
                             f"'pivot', got {self.rotational_slip!r}")
        if not isinstance(self.crossing, (bool, np.bool_)):
            raise ValueError(f"contact crossing must be True or False, got {self.crossing!r}")
        if self.crossing_penalty is None:
            self.crossing_penalty = self.penalty / self.radius
        for name in ("crossing_penalty", "crossing_angle"):
            v = getattr(self, name)
            if isinstance(v, bool) or not (isinstance(v, (int, float, np.floating))
                                           and np.isfinite(v) and v > 0):
                raise ValueError(f"contact {name} must be a finite number > 0, got {v!r}")
        if self.crossing_angle >= np.pi / 2:
            raise ValueError(f"contact crossing_angle must be below pi/2, got {self.crossing_angle!r}")

    def friction_params(self, push_forward=True, scale_T=1.0, scale_R=1.0):
        """The :class:`.friction_assembly.FrictionParams` of these options
        (``scale_*`` divide the compliances: the adaptive penalty factors)."""
        from .friction_assembly import FrictionParams
        return FrictionParams(self.gamma_T, self.gamma_R, self.mu_T / scale_T,
                              self.mu_R / scale_R, push_forward, self.rotational_slip)
