"""A fill-reducing ordering kept across the factorizations of a Newton
solve whose sparsity pattern drifts (the barrier's node pairs come and go).

SuperLU spends about a third of a factorization of the barrier
plectoneme's tangent (3600 dofs, 180 000 entries) on the multiple minimum
degree ordering of ``A^T + A``.  The pattern changes little from one
iterate to the next, so the ordering is computed once and reused: the
free block of the tangent is taken in that order (one fancy-index slice,
as the free block itself costs) and factorized in its natural order.  The
ordering is computed anew when the factor's fill has grown by more than
``growth`` over the fill it had where it was computed, or the matrix's
entries by more than ``growth``: a stale ordering costs fill, never
correctness.  No pivoting is changed: the caller's ``diag_pivot_thresh``
and symmetric mode act on the reordered matrix as they acted on the
original one, and the factor's row and column permutations (the identity
where no pivot left the diagonal) keep their meaning for the inertia
test (Sylvester's law reads the diagonal of ``U``).
"""
from typing import NamedTuple, Optional

import numpy as np
import scipy.sparse.linalg as spla

#: the ordering is renewed where the factor's fill (or the matrix's
#: entries) grew by more than this factor since it was computed
GROWTH = 1.25


class Ordered(NamedTuple):
    """A free block in a kept ordering: ``A = K[idx][:, idx]``, ``idx =
    free[order]`` (``order`` None: the natural one, the ordering still to
    be computed)."""
    A: object                 # CSC
    order: Optional[np.ndarray]

    def to_block(self, v):
        """``v`` (over the free dofs, in their natural order) in ``A``'s."""
        return v if self.order is None else v[self.order]

    def from_block(self, v):
        """``v`` (in ``A``'s order) over the free dofs, in their natural order."""
        if self.order is None:
            return v
        out = np.empty_like(v)
        out[self.order] = v
        return out


class KeptOrdering:
    """The free block of tangents over the dofs ``free`` (indices), in an
    ordering kept while it stays good (module doc); ``free`` a mask or
    the indices of the free dofs."""

    def __init__(self, free, growth=GROWTH):
        free = np.asarray(free)
        self.free = np.flatnonzero(free) if free.dtype == bool else free
        self.growth = float(growth)
        self.order = None         # positions into free, in elimination order
        self.fill = None          # the factor's fill where the order was computed
        self.nnz = None           # the block's entries there
        self.renewals = 0         # orderings computed

    def block(self, K):
        """The free block of ``K`` (sparse, all dofs) in the kept order."""
        idx = self.free if self.order is None else self.free[self.order]
        A = K[idx][:, idx].tocsc()
        if self.order is not None and A.nnz > self.growth * self.nnz:
            self.order = None
            return Ordered(K[self.free][:, self.free].tocsc(), None)
        return Ordered(A, self.order)

    def factor(self, blk, **options):
        """SuperLU of ``blk.A`` (an :class:`Ordered` of :meth:`block`,
        shifted or not) with the caller's pivoting ``options``: by the
        minimum degree ordering of ``A^T + A`` where no order is kept (and
        that ordering kept), in the natural order of the kept one
        otherwise (renewed next time where the fill grew)."""
        if blk.order is None:
            lu = spla.splu(blk.A, permc_spec="MMD_AT_PLUS_A", **options)
            self.order = np.argsort(lu.perm_c)
            self.fill = lu.L.nnz + lu.U.nnz
            self.nnz = blk.A.nnz
            self.renewals += 1
            return lu
        lu = spla.splu(blk.A, permc_spec="NATURAL", **options)
        if lu.L.nnz + lu.U.nnz > self.growth * self.fill:
            self.order = None
        return lu
