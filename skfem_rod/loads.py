"""External loads: end (point) forces and moments, dead or follower, and
distributed forces and torques.  All are proportional to the load factor
``lam`` of the load path, except point loads marked ``constant`` (preloads:
applied in full at every load factor, including the reference state solved
at load factor 0, e.g. a tension held on while an end is twisted).

Virtual work and load stiffness (conventions of :mod:`skfem_rod.rotations`):

* dead force ``F``:            ``F . delta r``,                 no stiffness;
* follower force ``R R0^T F``: rotates with the section; stiffness
  ``d f / d w = -hat(f)`` (enters the tangent with the opposite sign);
* dead moment ``M``:           ``M . delta w`` (spatially fixed axis; not
  conservative in 3D: no load stiffness, as in Simo & Vu-Quoc 1986);
* follower moment ``R R0^T M``: stiffness ``-hat(m)``;
* distributed force ``f(s)`` per unit reference length: ``int f . delta r``
  assembled as a scikit-fem ``LinearForm`` (exact for the P3 field);
* distributed torque ``t(s)``: ``int t . delta w_h`` with ``delta w_h`` the
  P3 interpolation of the nodal spins (see docs/theory.md, deviation D3).
"""
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from skfem import LinearForm, asm

from .rotations import hat
from .validation import finite_vector  # noqa: F401  (re-exported)


@dataclass
class PointLoad:
    node: int
    vector: np.ndarray
    kind: str          # "force" or "moment"
    follower: bool = False
    constant: bool = False   # preload: factor 1 at every load factor


@dataclass
class DistributedLoad:
    value: object      # 3-vector or callable s -> (n, 3)
    kind: str          # "force" or "torque"


@LinearForm
def _distributed(v, w):
    """Work of a distributed load component: ``int q(s) v ds``."""
    return w["q"] * v


def distributed_vector(mesh, loads):
    """Assembled dead distributed load vector (per unit load factor)."""
    f = np.zeros(mesh.n_dofs)
    for ld in loads:
        if callable(ld.value):
            x = mesh.sbasis.mapping.F(mesh.sbasis.X)[0]       # (ne, nq)
            q = np.asarray(ld.value(x.ravel()), float).reshape(x.shape + (3,))
            if not np.all(np.isfinite(q)):
                raise ValueError(f"distributed {ld.kind} returned non-finite values")
        else:
            q = np.broadcast_to(ld.value, mesh.dx.shape + (3,))
        off = 0 if ld.kind == "force" else 3
        for c in range(3):          # three components, each one scalar form
            f[off + c::6] += mesh.gather(asm(_distributed, mesh.sbasis, q=q[..., c]))
    return f


def point_loads(mesh, loads, R, R0, lam):
    """Point-load vector at load factor ``lam`` and its stiffness
    ``-d f_ext / d y`` (CSC, or None when only dead loads)."""
    f = np.zeros(mesh.n_dofs)
    rows, cols, vals = [], [], []
    for ld in loads:
        n = ld.node
        vec = (1.0 if ld.constant else lam) * ld.vector
        off = 0 if ld.kind == "force" else 3
        if ld.follower:
            vec = R[n] @ R0[n].T @ vec
            # f = R R0^T F: d f = hat(dw) f = -hat(f) dw; tangent gets +hat(f)
            K = hat(vec)
            r_i, c_i = np.meshgrid(6 * n + off + np.arange(3), 6 * n + 3 + np.arange(3),
                                   indexing="ij")
            rows.append(r_i.ravel()); cols.append(c_i.ravel()); vals.append(K.ravel())
        f[6 * n + off:6 * n + off + 3] += vec
    Kext = None
    if rows:
        Kext = sp.csc_matrix((np.concatenate(vals),
                              (np.concatenate(rows), np.concatenate(cols))),
                             shape=(mesh.n_dofs, mesh.n_dofs))
    return f, Kext
