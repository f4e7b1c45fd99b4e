"""Nodal cubic Lagrange element on a line, for scikit-fem.

scikit-fem's ``ElementLinePp(3)`` is hierarchical (integrated Legendre
polynomials): its degrees of freedom are not nodal values.  Rod kinematics
needs nodal values that *are* positions and rotations, so this module defines
the nodal element with nodes at the reference coordinates 0, 1/3, 2/3, 1.

Local degree-of-freedom order (scikit-fem's convention for line elements):
vertex 0 (xi = 0), vertex 1 (xi = 1), then the two interior nodes
(xi = 1/3, xi = 2/3).  :data:`NODE_XI` lists them and :data:`ORDER_BY_POSITION`
gives the local indices sorted by position along the element.

The same shape functions are exported as plain NumPy functions
(:func:`shape_functions`) for code that evaluates the interpolation at
arbitrary points outside scikit-fem's quadrature, e.g. the contact search.
"""
import numpy as np
from skfem.element.element_h1 import ElementH1
from skfem.refdom import RefLine

#: reference coordinates of the local nodes, in scikit-fem's dof order
NODE_XI = np.array([0.0, 1.0, 1.0 / 3.0, 2.0 / 3.0])
#: local node indices sorted by position along the element
ORDER_BY_POSITION = np.array([0, 2, 3, 1])


def shape_functions(xi):
    """Values, first and second derivatives of the four cubic Lagrange
    shape functions at reference coordinates ``xi`` (any shape).

    Returns arrays of shape ``(4,) + xi.shape`` in the local dof order
    (nodes at 0, 1, 1/3, 2/3); derivatives are with respect to ``xi``.

    Examples
    --------
    >>> N, dN, d2N = shape_functions(np.array([0.0, 0.5]))
    >>> N.sum(axis=0)
    array([1., 1.])
    """
    x = np.asarray(xi, dtype=float)
    a, b = 1.0 / 3.0, 2.0 / 3.0
    N = np.array([
        -4.5 * (x - a) * (x - b) * (x - 1.0),
        4.5 * x * (x - a) * (x - b),
        13.5 * x * (x - b) * (x - 1.0),
        -13.5 * x * (x - a) * (x - 1.0),
    ])
    dN = np.array([
        -4.5 * (3 * x**2 - 2 * (a + b + 1.0) * x + (a * b + a + b)),
        4.5 * (3 * x**2 - 2 * (a + b) * x + a * b),
        13.5 * (3 * x**2 - 2 * (b + 1.0) * x + b),
        -13.5 * (3 * x**2 - 2 * (a + 1.0) * x + a),
    ])
    d2N = np.array([
        -4.5 * (6 * x - 2 * (a + b + 1.0)),
        4.5 * (6 * x - 2 * (a + b)),
        13.5 * (6 * x - 2 * (b + 1.0)),
        -13.5 * (6 * x - 2 * (a + 1.0)),
    ])
    return N, dN, d2N


class ElementLineP3(ElementH1):
    """Nodal cubic Lagrange element (nodes at 0, 1/3, 2/3, 1).

    Examples
    --------
    >>> from skfem import MeshLine, Basis
    >>> basis = Basis(MeshLine(np.linspace(0, 1, 5)), ElementLineP3())
    >>> basis.N   # 5 vertices + 2 interior nodes in each of 4 elements
    13
    """

    nodal_dofs = 1
    interior_dofs = 2
    maxdeg = 3
    dofnames = ['u', 'u', 'u']
    doflocs = NODE_XI[:, None].copy()
    refdom = RefLine

    def lbasis(self, X, i):
        if not 0 <= i < 4:
            self._index_error()
        N, dN, _ = shape_functions(X[0])
        return N[i], np.array([dN[i]])
