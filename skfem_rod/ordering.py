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
import scipy.sparse as sp
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


class _Taken(NamedTuple):
    """The last free block :meth:`KeptOrdering.block` took: the order and
    ``K``'s pattern it was taken for and, once that pattern came again,
    the block (its pattern) and the entries of ``K.data`` it holds."""
    order: Optional[np.ndarray]
    indptr: np.ndarray
    indices: np.ndarray
    block: object = None
    take: Optional[np.ndarray] = None


def _taken(K, idx):
    """``K[idx][:, idx]`` (CSC, indices sorted) and the positions in
    ``K.data`` of its entries (``K`` canonical CSC): the block of a
    matrix whose entries are their own positions."""
    pos = sp.csc_matrix((np.arange(1, K.nnz + 1, dtype=float), K.indices, K.indptr),
                        shape=K.shape)
    P = pos[idx][:, idx].tocsc()
    P.sort_indices()
    take = P.data.astype(np.int64) - 1
    A = sp.csc_matrix((K.data[take], P.indices, P.indptr), shape=P.shape)
    A.has_sorted_indices = True
    return A, take


class KeptSum:
    """The sum of sparse matrices whose patterns recur (the tangent's
    terms: the rod's, fixed; the node barrier's and the friction's, which
    change where their pairs do).  Where every term has the pattern it
    had at the last call, the sum is one weighted ``bincount`` of the
    terms' entries into the kept union pattern (no sparse additions, no
    sorts); where one changed, scipy's sum, and the terms' patterns
    kept -- their union and the positions of their entries in it found
    only when the same patterns come again (the barrier's active pairs
    change from one iterate to the next in a slip: no work done for a
    pattern seen once).  Terms that are None are left out."""

    def __init__(self):
        self._pats = None         # the last call's terms' patterns
        self._union = None        # their union's (indices, indptr)
        self._dest = None         # the positions of their entries in it
        self.unions = 0           # positions found (tests, benchmarks)

    def __call__(self, terms):
        """``sum(terms)`` as a canonical CSC matrix (indices sorted, no
        duplicates)."""
        terms = [sp.csc_matrix(T) for T in terms if T is not None]
        if not terms:
            raise ValueError("KeptSum: no terms to sum")
        for T in terms:
            T.sum_duplicates()
        shape = terms[0].shape
        same = (self._pats is not None and len(self._pats) == len(terms) and all(
            T.shape == sh and np.array_equal(T.indptr, p) and np.array_equal(T.indices, i)
            for T, (sh, p, i) in zip(terms, self._pats)))
        if not same:
            S = terms[0]
            for T in terms[1:]:
                S = S + T
            # a new matrix (a copy only where there is one term to return)
            S = sp.csc_matrix(S, copy=len(terms) == 1)
            S.sum_duplicates()
            self._pats = [(T.shape, T.indptr.copy(), T.indices.copy()) for T in terms]
            self._union = self._dest = None
            return S
        if self._dest is None:
            # the patterns again: their union (a sum of ones: the entries
            # that are zero, which a sum of the values drops, kept) and
            # where each term's entries go in it
            U = None
            for T in terms:
                O = sp.csc_matrix((np.ones(T.nnz), T.indices, T.indptr), shape=shape)
                U = O if U is None else U + O
            U = sp.csc_matrix(U)
            U.sort_indices()
            self._union = (U.indices.copy(), U.indptr.copy())
            indices, indptr = self._union
            ukeys = _keys(indices, indptr, shape)
            self._dest = np.concatenate([np.searchsorted(ukeys, _keys(T.indices, T.indptr, shape))
                                         for T in terms])
            self.unions += 1
        indices, indptr = self._union
        data = np.bincount(self._dest, weights=np.concatenate([T.data for T in terms]),
                           minlength=indices.size)
        S = sp.csc_matrix((data, indices.copy(), indptr.copy()), shape=shape)
        S.has_sorted_indices = True
        S.has_canonical_format = True
        return S


def _keys(indices, indptr, shape):
    """The column-major keys ``col * rows + row`` of a CSC pattern's
    entries (increasing where its indices are sorted)."""
    cols = np.repeat(np.arange(shape[1], dtype=np.int64), np.diff(indptr))
    return cols * shape[0] + indices


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
        self._taken = None        # the last block's _Taken
        self.extractions = 0      # blocks taken by indexing (tests, benchmarks)

    def block(self, K):
        """The free block of ``K`` (sparse, all dofs) in the kept order.
        Where ``K`` has the last call's pattern (and the order is the
        same), the block's entries are one gather of ``K``'s (the
        pattern changes only where the contact pairs do); the gather's
        map is found when a pattern comes the second time (no work done
        for a pattern seen once: the barrier's active pairs change from
        one iterate to the next where strands slide)."""
        K = sp.csc_matrix(K)
        K.sum_duplicates()
        t = self._taken
        if (t is not None and t.order is self.order and np.array_equal(t.indptr, K.indptr)
                and np.array_equal(t.indices, K.indices)):
            if t.take is None:
                idx = self.free if self.order is None else self.free[self.order]
                A, take = _taken(K, idx)
                self._taken = t = t._replace(block=A, take=take)
                self.extractions += 1
            A = sp.csc_matrix((K.data[t.take], t.block.indices.copy(), t.block.indptr.copy()),
                              shape=t.block.shape)
            A.has_sorted_indices = True
            return Ordered(A, self.order)
        idx = self.free if self.order is None else self.free[self.order]
        A = K[idx][:, idx].tocsc()
        if self.order is not None and A.nnz > self.growth * self.nnz:
            self.order = None
            A = K[self.free][:, self.free].tocsc()
        self._taken = _Taken(self.order, K.indptr.copy(), K.indices.copy())
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
