"""The fill-reducing ordering kept across factorizations
(:mod:`skfem_rod.ordering`): solutions and inertia as a fresh
factorization's, the ordering renewed where the pattern grew."""
import numpy as np
import pytest
import scipy.sparse as sp

from skfem_rod.ordering import KeptOrdering

SYM = dict(diag_pivot_thresh=0.0, options=dict(SymmetricMode=True))


def _tangent(n, contacts, seed, scattered=0):
    """A symmetric rod-like matrix: a band of width 12 (the elements), the
    couplings of a hairpin's two arms in contact (node ``i`` with ``n - 1
    - i`` for ``contacts`` nodes from node 20: a contact zone that grows
    with ``contacts``) and ``scattered`` random far couplings;
    diagonally dominant.  The same values for the same seed."""
    rng = np.random.default_rng(seed)
    A = sp.lil_matrix((n, n))
    for k in range(1, 13):
        A.setdiag(rng.uniform(-1, 1, n - k), k)
    i = 20 + np.arange(contacts)
    j = n - 1 - i
    si, sj = rng.integers(0, n, (2, scattered))
    A = A.tocsr() + sp.csr_matrix((rng.uniform(-1, 1, contacts + scattered),
                                   (np.r_[i, si], np.r_[j, sj])), shape=(n, n))
    A = A + A.T
    d = np.abs(A).sum(axis=1).A1 + 1.0
    return (A + sp.diags(d)).tocsr()


def test_kept_ordering_solves_as_a_fresh_factorization_and_is_renewed_where_it_pays():
    n = 600
    free = np.ones(n, bool)
    free[[0, 1, 2, 300]] = False
    idx = np.flatnonzero(free)
    ko = KeptOrdering(free)
    rng = np.random.default_rng(3)
    for k, (contacts, scattered) in enumerate([(150, 0), (160, 0), (170, 0), (170, 300)]):
        K = _tangent(n, contacts, 0, scattered)
        blk = ko.block(K)
        lu = ko.factor(blk, **SYM)
        b = rng.standard_normal(idx.size)
        x = blk.from_block(lu.solve(blk.to_block(b)))
        Kf = K[idx][:, idx].toarray()
        assert np.abs(Kf @ x - b).max() <= 1e-12 * np.abs(b).max() * np.abs(Kf).max()
        if k == 0:
            assert blk.order is None and ko.renewals == 1
        elif k < 3:
            # the contact zone grown: the ordering kept
            assert blk.order is not None and ko.renewals == 1
    # couplings all over: the fill grew fourfold, the ordering is renewed
    # at the next factorization
    assert ko.order is None
    ko.factor(ko.block(K), **SYM)
    assert ko.renewals == 2 and ko.order is not None


def test_kept_ordering_reads_the_inertia_as_the_eigenvalues_do():
    """Sylvester: the negative pivots of the unpivoted LU in the kept
    order count the negative eigenvalues (the energy Newton's definiteness
    test and its saddle report)."""
    n = 300
    free = np.ones(n, bool)
    ko = KeptOrdering(free)
    K = _tangent(n, 100, 7, 20)
    ko.factor(ko.block(K), **SYM)                       # the ordering, from K
    ev = np.linalg.eigvalsh(K.toarray())
    for shift in (0.0, ev[3] + 1e-3, ev[40] + 1e-3):
        A = (K - shift * sp.eye(n)).tocsr()
        blk = ko.block(A)
        assert blk.order is not None
        lu = ko.factor(blk, **SYM)
        assert np.array_equal(lu.perm_r, lu.perm_c)
        assert int(np.sum(lu.U.diagonal() < 0)) == int(np.sum(ev < shift))


def test_free_given_as_indices_or_mask_is_the_same():
    n = 100
    free = np.ones(n, bool)
    free[::7] = False
    K = _tangent(n, 30, 1, 5)
    a, b = KeptOrdering(free).block(K).A, KeptOrdering(np.flatnonzero(free)).block(K).A
    assert (a != b).nnz == 0


@pytest.mark.parametrize("growth", [1.0, 2.0])
def test_growth_sets_when_the_ordering_is_renewed(growth):
    n = 400
    ko = KeptOrdering(np.ones(n, bool), growth=growth)
    ko.factor(ko.block(_tangent(n, 100, 2)), **SYM)
    ko.factor(ko.block(_tangent(n, 120, 2)), **SYM)
    # growth 1: any growth renews; 2: a contact zone a fifth longer keeps it
    assert ko.renewals == (2 if growth == 1.0 else 1)


def test_kept_sum_is_the_sum_and_keeps_its_pattern_while_the_terms_keep_theirs():
    """:class:`KeptSum` against scipy's sum: terms with their own patterns
    (a band, scattered couplings, one term left out as None); new values
    on the same patterns (the entries' positions found at the second
    call, kept at the third); a term's pattern changed (scipy's sum), and
    again (the new positions found); the result canonical (sorted, no
    duplicates)."""
    from skfem_rod.ordering import KeptSum
    n = 200
    ks = KeptSum()
    rng = np.random.default_rng(4)

    def term(seed, density):
        A = sp.random(n, n, density=density, random_state=seed, format="csc")
        A.data = rng.standard_normal(A.nnz)             # new values, same pattern
        return A
    for k, (seeds, none) in enumerate([((1, 2, 3), False), ((1, 2, 3), True),
                                       ((1, 2, 3), False), ((1, 5, 3), False),
                                       ((1, 5, 3), False)]):
        terms = [_tangent(n, 40, 0).tocsc(), term(seeds[1], 0.02), term(seeds[2], 0.05)]
        terms[0].data = rng.standard_normal(terms[0].nnz)
        if k in (0, 3):
            # entries zero at the first call (a straight rod's tangent has
            # them): a sum of the values drops them, the kept pattern not
            terms[0].data[::3] = 0.0
        if none:
            terms.insert(1, None)
        S = ks(terms)
        want = sum(T for T in terms if T is not None)
        assert abs(S - want).max() <= 1e-14 * abs(want).max()
        canon = S.copy()
        canon.has_canonical_format = False
        canon.sum_duplicates()
        assert np.array_equal(canon.indices, S.indices) and canon.nnz == S.nnz
        # a None leaves the terms as they were: the union kept
        assert ks.unions == (0, 1, 1, 1, 2)[k]
    with pytest.raises(ValueError, match="no terms"):
        ks([None])


def test_kept_block_is_taken_anew_only_where_the_pattern_or_the_order_changes():
    """The free block of a matrix with the last one's pattern is one
    gather of its entries (its map found at the pattern's second call):
    equal to the block by indexing for new values, taken by indexing for
    a new pattern and after the ordering is renewed."""
    n = 300
    free = np.ones(n, bool)
    free[[0, 5, 150]] = False
    idx = np.flatnonzero(free)
    ko = KeptOrdering(free)
    rng = np.random.default_rng(9)
    K = _tangent(n, 60, 1).tocsc()
    ko.factor(ko.block(K), **SYM)                       # the ordering, from K
    assert ko.extractions == 0
    for k, contacts in enumerate([60, 60, 60, 80, 80]):
        K = _tangent(n, contacts, 1).tocsc()
        K.data = rng.standard_normal(K.nnz)
        blk = ko.block(K)
        want = K[idx][:, idx].toarray()[np.ix_(ko.order, ko.order)]
        assert np.array_equal(blk.A.toarray(), want)
        # order renewed (indexing), the pattern again (the map), kept,
        # a new pattern (indexing), again (the map)
        assert ko.extractions == (0, 1, 1, 1, 2)[k]


def test_kept_sum_of_one_term_is_a_new_matrix():
    """The sum of a single term is that term's values in a matrix of its
    own: changing the result leaves the term as it was."""
    from skfem_rod.ordering import KeptSum
    T = _tangent(50, 10, 3).tocsc()
    before = T.toarray()
    S = KeptSum()([T, None])
    S.data[:] = 0.0
    assert np.array_equal(T.toarray(), before)
