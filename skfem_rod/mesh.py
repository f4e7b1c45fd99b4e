"""The discretization: a scikit-fem 1D mesh with nodal P3 bases and dof maps.

Degrees of freedom
------------------
Every P3 node ``n`` (scikit-fem's scalar dof numbering: the mesh vertices
first, then two interior nodes per element) carries six unknowns, numbered
by scikit-fem's ``ElementVector(ElementLineP3(), 6)`` as ``6 n + c``:
``c = 0, 1, 2`` position increment, ``c = 3, 4, 5`` spatial spin increment
(see :mod:`skfem_rod.rotations` for the spin convention).
"""
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from skfem import MeshLine, Basis, ElementVector
from skfem.quadrature import get_quadrature
from skfem.refdom import RefLine

from .element import ElementLineP3, ORDER_BY_POSITION
from .validation import arclengths, count


@dataclass
class RodMesh:
    """Mesh of ``[0, length]`` with P3 bases, quadrature data and dof maps.

    Parameters
    ----------
    length : float
        Rod length (> 0).
    n_elements : int
        Number of cubic elements (>= 1).
    n_quad : int
        Gauss points per element for the internal work (default 3: full
        4-point integration locks for slender rods, see docs/theory.md).
    closed : bool
        A closed rod (ring): the node at ``s = length`` is the node at
        ``s = 0`` (one position, one rotation), so the last element ends
        where the first begins.  scikit-fem's open numbering is kept for
        the bases; ``to_node`` maps it to the closed node numbers.

    Examples
    --------
    >>> m = RodMesh(2.0, 4)
    >>> m.n_nodes, m.n_dofs
    (13, 78)
    """
    length: float
    n_elements: int
    n_quad: int = 3
    vertices: np.ndarray = None
    closed: bool = False

    basis: Basis = field(init=False, repr=False)
    sbasis: Basis = field(init=False, repr=False)

    def __post_init__(self):
        if not (np.isfinite(self.length) and self.length > 0):
            raise ValueError(f"length must be a finite number > 0, got {self.length!r}")
        count("n_elements", self.n_elements, 1)
        count("n_quad", self.n_quad, 1)
        if not isinstance(self.closed, (bool, np.bool_)):
            raise ValueError(f"closed must be True or False, got {self.closed!r}")
        if self.closed and self.n_elements < 3:
            raise ValueError(f"a closed rod needs n_elements >= 3, got {self.n_elements!r}")
        if self.vertices is None:
            self.vertices = np.linspace(0.0, self.length, self.n_elements + 1)
        v = np.asarray(self.vertices, dtype=float)
        if v.shape != (self.n_elements + 1,) or np.any(np.diff(v) <= 0):
            raise ValueError("vertices must be n_elements + 1 increasing arclengths")
        self.vertices = v
        mesh = MeshLine(v)
        quad = get_quadrature(RefLine, 2 * self.n_quad - 1)
        self.sbasis = Basis(mesh, ElementLineP3(), quadrature=quad)
        self.basis = Basis(mesh, ElementVector(ElementLineP3(), 6), quadrature=quad)
        self.mesh = mesh
        sb = self.sbasis
        #: (ne, 4) global node index of each local node (scikit-fem order)
        self.nodes = sb.element_dofs.T.copy()
        #: (n_nodes,) arclength of each node
        self.s_nodes = sb.doflocs[0].copy()
        #: node indices sorted by arclength (for output along the rod)
        self.order = np.argsort(self.s_nodes, kind="stable")
        #: (ne, 24) global dof of each local dof (6 I + c), scikit-fem's map
        self.edofs = self.basis.element_dofs.T.copy()
        assert np.array_equal(self.edofs, (6 * self.nodes[:, :, None]
                                           + np.arange(6)).reshape(-1, 24))
        #: scikit-fem (open) scalar dof -> node number (identity unless closed)
        self.to_node = np.arange(self.s_nodes.size)
        if self.closed:
            self._close()
        #: quadrature: (ne, nq, 4) shape functions and arclength derivatives
        self.N = np.stack([np.asarray(sb.basis[i][0]) for i in range(4)], axis=-1)
        self.dN = np.stack([sb.basis[i][0].grad[0] for i in range(4)], axis=-1)
        self.dx = sb.dx.copy()                       # (ne, nq) weights * J
        self.s_quad = sb.mapping.F(sb.X)[0]          # (ne, nq) arclengths
        self._pattern()

    def _close(self):
        """Identify the node at ``s = length`` with the node at ``s = 0``."""
        last = int(np.argmax(self.s_nodes))
        first = int(np.argmin(self.s_nodes))
        m = np.arange(self.s_nodes.size)
        m[last] = first
        m[m > last] -= 1
        self.to_node = m
        self.nodes = m[self.nodes]
        self.s_nodes = np.delete(self.s_nodes, last)
        self.order = np.argsort(self.s_nodes, kind="stable")
        self.edofs = (6 * self.nodes[:, :, None] + np.arange(6)).reshape(-1, 24)

    def gather(self, v):
        """Sum a vector over scikit-fem's scalar dofs into node numbers."""
        return np.bincount(self.to_node, weights=v, minlength=self.n_nodes)

    # sizes ---------------------------------------------------------------
    @property
    def n_nodes(self):
        return self.s_nodes.size

    @property
    def n_dofs(self):
        return 6 * self.n_nodes

    @property
    def end_nodes(self):
        """Global node indices at s = 0 and s = length (one node if closed)."""
        if self.closed:
            return int(self.order[0]), int(self.order[0])
        return int(self.order[0]), int(self.order[-1])

    # sparse pattern -------------------------------------------------------
    def _pattern(self):
        """Precompute the CSC pattern of the element matrices and the map
        from element-matrix entries to its data array (summing duplicates)."""
        ed = self.edofs
        rows = np.repeat(ed, 24, axis=1).ravel()
        cols = np.tile(ed, (1, 24)).ravel()
        key = cols.astype(np.int64) * self.n_dofs + rows
        ukey, inv = np.unique(key, return_inverse=True)
        self._scatter = inv
        self._indices = (ukey % self.n_dofs).astype(np.int32)
        ucol = ukey // self.n_dofs
        self._indptr = np.searchsorted(ucol, np.arange(self.n_dofs + 1)).astype(np.int32)
        self._nnz = ukey.size
        #: data positions of the diagonal (every dof couples with itself)
        self._diagonal = np.searchsorted(ukey, np.arange(self.n_dofs, dtype=np.int64)
                                         * (self.n_dofs + 1))

    def assemble_matrix(self, Ke):
        """Global CSC matrix from element matrices ``(ne, 24, 24)``
        (rows: test dofs, columns: trial dofs)."""
        data = np.bincount(self._scatter, weights=Ke.ravel(), minlength=self._nnz)
        return sp.csc_matrix((data, self._indices.copy(), self._indptr.copy()),
                             shape=(self.n_dofs, self.n_dofs))

    def add_diagonal(self, K, d):
        """``K + diag(d)`` for a matrix ``K`` of :meth:`assemble_matrix`
        (its pattern holds the diagonal): a new matrix, ``K`` unchanged."""
        data = K.data.copy()
        data[self._diagonal] += d
        return sp.csc_matrix((data, K.indices.copy(), K.indptr.copy()), shape=K.shape)

    def assemble_vector(self, fe):
        """Global vector from element vectors ``(ne, 24)``."""
        return np.bincount(self.edofs.ravel(), weights=fe.ravel(),
                           minlength=self.n_dofs)

    def locate(self, s):
        """Element index and reference coordinate of arclengths ``s``."""
        s = arclengths("arclength s", s, self.length)
        e = np.clip(np.searchsorted(self.vertices, s, side="right") - 1,
                    0, self.n_elements - 1)
        xi = (s - self.vertices[e]) / (self.vertices[e + 1] - self.vertices[e])
        return e, xi

    def element_nodes_by_position(self):
        """(ne, 4) node indices ordered along each element."""
        return self.nodes[:, ORDER_BY_POSITION]
