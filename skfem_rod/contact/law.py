r"""The normal contact law: gap, augmented-Lagrangian force, Uzawa update.

Gap (eq. 3.2; positive = penetration):   ``d = 2 eps - |r(s) - r(s_bar)|``.
Normal (sec. 3.1), from master to slave: ``N = (r(s) - r(s_bar)) / |...|``.
Force per unit length (eq. 4.2a), with the compliance ``mu_N`` (the paper's
penalty parameter: stiffness ``1 / mu_N``) and the multiplier ``lambda_N``:

    f_N = [d + mu_N lambda_N]_+ / mu_N .

It derives from the potential ``phi(d) = [d + mu_N lambda_N]_+^2 / (2 mu_N)``
per unit length, so the frictionless contact tangent is symmetric.
Uzawa's update between Newton solves is ``lambda_N <- f_N``; it drives the
penetration to zero without raising the penalty.

Every contact is seen from both sides (each side's Gauss points are slaves
too), so the two slave passes share the contact force: at convergence each
carries about half of it.
"""
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class NormalLaw:
    """The normal law of an evaluation: the multipliers ``lambda_N``
    ``(n_slaves,)``, the compliances ``mu_N`` (a number, or one per pair of
    the :class:`.search.Pairs` it is applied to: the adaptive penalty) and
    the contact radius ``eps``."""
    multiplier: np.ndarray
    compliance: object
    radius: float

    def forces(self, pairs):
        """``f_N`` and ``d f_N / d d`` per pair of ``pairs``
        (:func:`normal_force` at the pairs' gaps and slaves' multipliers)."""
        return normal_force(gap(pairs.distance, self.radius), self.multiplier[pairs.slave],
                            self.compliance)


def gap(distance, radius):
    """Gap ``d = 2 eps - distance`` (positive when the rods interpenetrate)."""
    return 2.0 * radius - distance


def normal_force(d, lam, mu):
    """``f_N = [d + mu lambda]_+ / mu`` (eq. 4.2a) and its derivative
    ``H(d + mu lambda) / mu`` with respect to the gap."""
    x = d + mu * lam
    active = x > 0
    return np.where(active, x / mu, 0.0), np.where(active, 1.0 / mu, 0.0)


def potential(d, lam, mu):
    """``phi = [d + mu lambda]_+^2 / (2 mu)``: ``phi'(d) = f_N``."""
    x = np.maximum(d + mu * lam, 0.0)
    return x * x / (2.0 * mu)


def uzawa_update(d, lam, mu):
    """Multiplier update ``lambda <- [lambda + d / mu]_+``."""
    return np.maximum(lam + d / mu, 0.0)
