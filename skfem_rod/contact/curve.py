r"""The curve the contact acts on: the rod's P3 centreline, or a C1 cubic
through its nodes (option ``curve = "smooth"``).

*Why.*  The cubic Lagrange centreline is C0 at the element ends: its
tangent turns there by a small angle (O(h^3) of the curvature's third
derivative).  A slave point on the concave side of such a node has a
closest-point distance with a ridge (the smaller of two smooth functions,
one per element), and where a crossing's closest point passes a node the
contact normal jumps by the kink angle.  Newton's quadratic model is then
wrong across the ridge: measured in the plectoneme's damped steps, the
update from either of two states leads to the other (residual 0.711 <->
0.830 for ever, tangent right to 1e-7; benchmarks/RESULTS_plectoneme.md).

*The smooth curve.*  On element ``e`` (vertices ``s_e``, ``s_{e+1}``,
length ``h_e``) the contact curve is the cubic Hermite interpolant of the
end nodes ``p0, p1`` with the arclength tangents ``m0, m1`` at the
vertices:

    y(xi) = H00(xi) p0 + H01(xi) p1 + h_e (H10(xi) m0 + H11(xi) m1),

where the tangent at a vertex shared by elements ``a`` (before) and ``b``
(after) is the weighted mean of the two one-sided derivatives of the
Lagrange cubics,

    m = w_a r_a'(1) / h_a + w_b r_b'(0) / h_b,
    w_a = h_b^3 / (h_a^3 + h_b^3),  w_b = h_a^3 / (h_a^3 + h_b^3).

The one-sided derivatives of a cubic interpolant err by ``+c h_a^3 r''''``
and ``-c h_b^3 r''''`` at the two sides of a node (c = 1/108), so these
weights cancel the leading error: ``m`` is O(h^4) accurate, and the curve
differs from the Lagrange centreline by O(h^4), the interpolation order
of the rod itself.  At the ends of an open rod the element's own
derivative is taken; on a closed rod the last and first elements share the
closure vertex.  Where the centreline is one cubic across a node (a
polynomial of degree 3 or less), both curves are the same.  The curve is
C1 in the arclength: one tangent at every vertex.

*How it enters.*  The smooth cubic of an element is represented, exactly,
by its values at the element's four Lagrange points (``xi = 0, 1, 1/3,
2/3``): "curve nodes", four per element and not shared.  They are a fixed
linear map ``S`` of the rod's nodal positions (``r_c = S r``; a curve node
depends on the nodes of its element and of the two beside it), and the
sections' rotations are carried to the curve nodes unchanged (the rotation
of the rod node at the same place).  Search, normal contact, friction and
crossing pairs run unchanged on the curve mesh (:class:`CurveMesh`: four
own nodes per element, the rod's vertices), and their force and tangent are
pulled back to the rod's dofs with the dof map ``T``: ``f = T^T f_c``,
``K = T^T K_c T`` (exact: the map is linear).

The true-distance check after a step (``augmented.true_distance``) keeps
measuring the rod's own centreline.
"""
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..element import shape_functions

#: the curves the contact can act on
CURVES = ("elements", "smooth")

#: local order of the Lagrange points (scikit-fem's): xi = 0, 1, 1/3, 2/3
_XI = np.array([0.0, 1.0, 1.0 / 3.0, 2.0 / 3.0])


@dataclass(frozen=True)
class CurveMesh:
    """The mesh of the contact curve: element ``e`` has its own four nodes
    ``4 e + k`` (local order of :data:`_XI`) and spans the rod's vertices
    ``vertices[e]``, ``vertices[e + 1]``; ``closed`` as the rod's."""
    nodes: np.ndarray
    vertices: np.ndarray
    closed: bool = False

    @property
    def n_nodes(self):
        return self.nodes.size

    @property
    def n_dofs(self):
        return 6 * self.n_nodes


def _hermite(xi):
    """Cubic Hermite basis ``(H00, H01, H10, H11)`` at ``xi``: values at 0
    and 1, xi-derivatives at 0 and 1."""
    x = np.asarray(xi, float)
    return np.stack([2 * x**3 - 3 * x**2 + 1, -2 * x**3 + 3 * x**2,
                     x**3 - 2 * x**2 + x, x**3 - x**2])


def smoothing_map(mesh):
    """The sparse ``(4 ne, n_nodes)`` map ``S`` of the rod's nodal positions
    to the smooth curve's nodes (module docstring)."""
    nodes, v = mesh.nodes, mesh.vertices
    ne = nodes.shape[0]
    h = np.diff(v)
    _, dN, _ = shape_functions(np.array([0.0, 1.0]))       # (4, 2): d/dxi at 0 and 1
    D0, D1 = dN[:, 0], dN[:, 1]
    e = np.arange(ne)
    prev, nxt = e - 1, e + 1
    if mesh.closed:
        prev, nxt = np.mod(prev, ne), np.mod(nxt, ne)
    has_prev, has_next = prev >= 0, nxt < ne
    prev, nxt = np.where(has_prev, prev, e), np.where(has_next, nxt, e)
    # tangents m0 (left vertex), m1 (right vertex) over the 12-node stencil
    # (nodes of prev, e, next), coefficients (ne, 12)
    z = np.zeros((ne, 4))

    def mean(ha, hb, has, alone):
        # weights of the one-sided derivatives before (a) and after (b) the
        # vertex; ``alone``: the weight of a at an end of an open rod
        wa = np.where(has, hb**3 / (ha**3 + hb**3), alone)
        return D1[None, :] * (wa / ha)[:, None], D0[None, :] * ((1.0 - wa) / hb)[:, None]

    a, b = mean(h[prev], h, has_prev, 0.0)
    m0 = np.concatenate([a, b, z], axis=1)
    a, b = mean(h, h[nxt], has_next, 1.0)
    m1 = np.concatenate([z, a, b], axis=1)
    H = _hermite(_XI)                                      # (4 basis, 4 points)
    p0 = np.zeros(12)
    p0[4] = 1.0
    p1 = np.zeros(12)
    p1[5] = 1.0
    coef = (H[0][None, :, None] * p0 + H[1][None, :, None] * p1
            + h[:, None, None] * (H[2][None, :, None] * m0[:, None, :]
                                  + H[3][None, :, None] * m1[:, None, :]))   # (ne, 4, 12)
    cols = np.concatenate([nodes[prev], nodes, nodes[nxt]], axis=1)       # (ne, 12)
    rows = np.broadcast_to((4 * e[:, None] + np.arange(4))[:, :, None], coef.shape)
    cols = np.broadcast_to(cols[:, None, :], coef.shape)
    S = sp.coo_matrix((coef.ravel(), (rows.ravel(), cols.ravel())),
                      shape=(4 * ne, mesh.n_nodes)).tocsr()      # sums duplicates
    S.eliminate_zeros()
    return S


class ContactCurve:
    """The smooth contact curve of a rod mesh: its :class:`CurveMesh`, the
    position map ``S`` and the dof map ``T`` (module docstring).

    Examples
    --------
    >>> from skfem_rod.mesh import RodMesh
    >>> mesh = RodMesh(1.0, 4)
    >>> s = mesh.s_nodes
    >>> r = np.stack([s, s**2, s**3], axis=1)      # a cubic: both curves agree
    >>> cc = ContactCurve(mesh)
    >>> bool(np.allclose(cc.positions(r), r[mesh.nodes].reshape(-1, 3)))
    True
    """

    def __init__(self, mesh):
        ne = mesh.nodes.shape[0]
        self.mesh = CurveMesh(nodes=np.arange(4 * ne).reshape(ne, 4),
                              vertices=mesh.vertices, closed=bool(mesh.closed))
        #: the rod node at each curve node (rotations are carried unchanged)
        self.select = mesh.nodes.ravel()
        self.S = smoothing_map(mesh)
        S = self.S.tocoo()
        n_c = 4 * ne
        rows = np.concatenate([6 * S.row[:, None] + np.arange(3),
                               6 * np.arange(n_c)[:, None] + 3 + np.arange(3)]).ravel()
        cols = np.concatenate([6 * S.col[:, None] + np.arange(3),
                               6 * self.select[:, None] + 3 + np.arange(3)]).ravel()
        vals = np.concatenate([np.repeat(S.data, 3), np.ones(3 * n_c)])
        #: dof map, curve dofs (6 per curve node) from rod dofs
        self.T = sp.csc_matrix((vals, (rows, cols)), shape=(6 * n_c, mesh.n_dofs))
        #: its transpose; both CSC: the pull-back of a tangent is two CSC
        #: products (0.84 ms against 1.17 ms through CSR for the pressed
        #: hairpin's 39456 entries)
        self.TT = self.T.T.tocsc()

    def positions(self, r):
        """Curve-node positions ``(4 ne, 3)`` of rod nodal positions ``r``."""
        return self.S @ r

    def rotations(self, R):
        """Curve-node rotations ``(4 ne, 3, 3)``: those of the rod nodes."""
        return R[self.select]

    def force(self, f):
        """A force vector on the curve's dofs pulled back to the rod's."""
        return self.TT @ f

    def tangent(self, K):
        """A tangent on the curve's dofs pulled back to the rod's (CSC)."""
        return self.TT @ K.tocsc() @ self.T
