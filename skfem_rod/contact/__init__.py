"""Self-contact: search (:mod:`.search`), normal law (:mod:`.law`) and the
nonlocal assembler (:mod:`.assembly`).  :class:`ContactOptions` holds the
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
    """
    radius: float
    penalty: float
    exclusion: float
    n_slave: int = 3
    tolerance: float = 1e-3
    max_uzawa: int = 30
    margin: float = None

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
