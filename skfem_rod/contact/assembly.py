r"""Nonlocal assembler: the contact virtual work of all slave/master pairs,
added into the global sparse system (eq. 4.1 third integral, sec. 6, 7.1).

For a slave point ``x = r(s)`` (slave element ``v``) and its master point
``y = r(s_bar)`` (master element ``e``, parameter ``xi``), with
``l = |x - y|``, ``N = (x - y)/l`` and the gap ``d = 2 eps - l``:

    delta l   = N . (delta x - delta y)                        (y' . N = 0)
    Delta xi  = Omega [(Delta x - Delta y) . y' + (x - y) . Delta y']   (eq. 6.5)
    Delta delta l = (delta x - delta y) . (I - N N) (Delta x - Delta y) / l
                    - Omega l a(delta) a(Delta),                (eq. 6.4c)
    a(delta)  = (delta x - delta y) . y' / l + N . delta y',
    Omega     = 1 / (|y'|^2 - (x - y) . y'')    (derivatives in xi).

The pair's work is ``w phi(d)`` (``w`` the slave's quadrature weight,
``phi`` the augmented-Lagrangian potential of :mod:`.law`), so

    residual = -w f_N delta l = w f_N N . (delta y - delta x)      (eq. 4.1)
    tangent  =  w [phi'' delta l (x) Delta l - f_N Delta delta l],

a symmetric 24 x 24 block over the position dofs of the two elements (the
paper's Sigma_1^T Gamma_N Sigma_1 of sec. 7.1).  ``Omega`` is guarded: where
the projection sits on an element end, or ``|y'|^2 - (x - y) . y''`` is not
safely positive (non-unique projection), the ``Delta xi`` term is dropped.
All pairs are evaluated at once; the blocks go to one COO -> CSC scatter.
"""
import numpy as np
import scipy.sparse as sp

from ..element import shape_functions
from .law import gap, normal_force, potential


def contact_work(mesh, r, pairs, lam, mu, radius, tangent=True):
    """Energy, force vector ``(n_dofs,)`` and tangent (CSC or None) of the
    contact pairs, and the per-pair normal forces ``f_N``."""
    n = mesh.n_dofs
    m = pairs.size
    if m == 0:
        return 0.0, np.zeros(n), (sp.csc_matrix((n, n)) if tangent else None), np.zeros(0)
    w = pairs.weight
    d = gap(pairs.distance, radius)
    fN, dfN = normal_force(d, lam[pairs.slave], mu)
    energy = float(np.sum(w * potential(d, lam[pairs.slave], mu)))
    act = fN > 0
    Ns, _, _ = shape_functions(pairs.s_xi)                  # (4, m)
    Nm, dNm, d2Nm = shape_functions(pairs.m_xi)
    # operators on the 24 position dofs (8 nodes x 3): x - y and y'
    P = np.concatenate([Ns.T, -Nm.T], axis=1)               # (m, 8): delta(x - y)
    Q = np.concatenate([np.zeros((m, 4)), dNm.T], axis=1)   # (m, 8): delta y'
    Nv = pairs.normal
    b = P[:, :, None] * Nv[:, None, :]                      # delta l  (m, 8, 3)
    fe = -(w * fN)[:, None, None] * b
    nodes = np.concatenate([mesh.nodes[pairs.s_elem], mesh.nodes[pairs.m_elem]], axis=1)
    dofs = (6 * nodes[:, :, None] + np.arange(3)).reshape(m, 24)
    force = np.bincount(dofs.ravel(), weights=fe.reshape(m, 24).ravel(), minlength=n)
    K = None
    if tangent:
        keep = np.flatnonzero(act)                          # stiffness of active pairs
        m = keep.size
        P, Q, Nv, b, w, fa, dfa, dofs = (P[keep], Q[keep], Nv[keep], b[keep], w[keep],
                                         fN[keep], dfN[keep], dofs[keep])
        dNm, d2Nm = dNm[:, keep], d2Nm[:, keep]
        r_m = r[mesh.nodes[pairs.m_elem[keep]]]             # (m, 4, 3)
        y1 = (dNm.T[:, None, :] @ r_m)[:, 0]
        y2 = (d2Nm.T[:, None, :] @ r_m)[:, 0]
        l = pairs.distance[keep]
        xy = Nv * l[:, None]
        den = np.sum(y1 * y1, axis=1) - np.sum(xy * y2, axis=1)
        use = pairs.interior[keep] & (den > 1e-8 * np.sum(y1 * y1, axis=1))
        Om = np.where(use, 1.0 / np.where(use, den, 1.0), 0.0)
        a = (P[:, :, None] * (y1 / l[:, None])[:, None, :]
             + Q[:, :, None] * Nv[:, None, :]).reshape(m, 24)
        bb = b.reshape(m, 24)
        proj = np.eye(3) - Nv[:, :, None] * Nv[:, None, :]     # (m, 3, 3)
        PP = P[:, :, None] * P[:, None, :]                      # (m, 8, 8)
        ddl = (PP[:, :, None, :, None] * proj[:, None, :, None, :]).reshape(m, 24, 24) / l[:, None, None]
        ddl -= (Om * l)[:, None, None] * a[:, :, None] * a[:, None, :]
        Ke = w[:, None, None] * (dfa[:, None, None] * bb[:, :, None] * bb[:, None, :]
                                 - fa[:, None, None] * ddl)
        rows = np.repeat(dofs, 24, axis=1).ravel()
        cols = np.tile(dofs, (1, 24)).ravel()
        K = sp.csc_matrix((Ke.ravel(), (rows, cols)), shape=(n, n))
    return energy, force, K, fN
