"""Friction tangent assembly (skfem_rod.contact.friction_assembly): the
cached sparsity pattern and the merged normal-contact tangent give the same
residual and matrix as a fresh assembly and as a plain sparse sum; the
pattern caches belong to the problem, not to a module."""
import numpy as np
import pytest
import scipy.sparse as sp

from skfem_rod import Rod
from skfem_rod.contact import assembly as ca
from skfem_rod.contact import friction_assembly as fa
from skfem_rod.contact.assembly import ContactPatterns, PatternCache, contact_work
from skfem_rod.contact.law import NormalLaw
from skfem_rod.contact.search import search
from skfem_rod.contact.slip import SlipState
from skfem_rod.problem import Problem

from test_friction_assembly import EPS, REGIMES, _setup


def _pairs(rod, r, sl):
    return search(rod.mesh, r, sl, reach=2 * EPS + 0.05, exclusion=np.pi * EPS)


def _work(rod, r, R, r_n, R_n, pairs, lams, params, radius=EPS, **kw):
    lam_N, lam_T, lam_R = lams
    p = fa.FrictionParams(params["gamma_T"], params["gamma_R"], params["mu_T"], params["mu_R"])
    return fa.friction_work(rod.mesh, SlipState(r, R, r_n, R_n, lam_T, lam_R), pairs,
                            NormalLaw(lam_N, params["mu_N"], radius), p, **kw)


def _close(A, B, tol=1e-14):
    A, B = sp.csc_matrix(A), sp.csc_matrix(B)
    scale = abs(A).max()
    assert scale > 0
    return abs(A - B).max() <= tol * scale


@pytest.mark.parametrize("regime", ["slip", "stick"])
@pytest.mark.parametrize("seed", [0, 3])
def test_cached_pattern_gives_the_fresh_result(seed, regime):
    rng, rod, r, R, r_n, R_n, sl, *lams = _setup(seed)
    params = REGIMES[regime]
    pairs = _pairs(rod, r, sl)
    cache = PatternCache()
    f0, K0, out0 = _work(rod, r, R, r_n, R_n, pairs, lams, params, cache=cache)
    pattern = cache.pattern
    f1, K1, out1 = _work(rod, r, R, r_n, R_n, pairs, lams, params, cache=cache)
    assert cache.pattern is pattern                       # the cache was used
    assert np.abs(f1 - f0).max() <= 1e-14 * np.abs(f0).max()
    assert _close(K0, K1)
    np.testing.assert_array_equal(out0.index, out1.index)
    # a state with other pairs in contact replaces the pattern; the result
    # is again that of a fresh assembly
    r2 = r + 0.03 * rng.normal(size=r.shape)
    pairs2 = _pairs(rod, r2, sl)
    f2, K2, _ = _work(rod, r2, R, r_n, R_n, pairs2, lams, params, cache=cache)
    assert cache.pattern is not pattern
    cache.clear()
    f3, K3, _ = _work(rod, r2, R, r_n, R_n, pairs2, lams, params, cache=cache)
    assert np.abs(f2 - f3).max() <= 1e-14 * np.abs(f3).max()
    assert _close(K3, K2)
    assert K2.nnz != K0.nnz or not np.array_equal(K2.indices, K0.indices)


@pytest.mark.parametrize("seed", [1, 2])
def test_normal_tangent_merged_equals_sparse_sum(seed):
    """``K_normal`` (the normal contact tangent of the same pairs) is added
    into the friction tangent's arrays: the same matrix as ``Kf + Kn``, on
    a cached pattern too; a matrix outside the pattern is summed."""
    rng, rod, r, R, r_n, R_n, sl, *lams = _setup(seed)
    params = REGIMES["slip"]
    pairs = _pairs(rod, r, sl)
    _, _, Kn, _ = contact_work(rod.mesh, r, pairs, lams[0], params["mu_N"], EPS)
    assert Kn.nnz > 0
    cache = PatternCache()
    f, Kf, _ = _work(rod, r, R, r_n, R_n, pairs, lams, params, cache=cache)
    want = Kf + Kn
    for _ in range(2):                                     # fresh, then cached
        f1, K1, _ = _work(rod, r, R, r_n, R_n, pairs, lams, params, K_normal=Kn, cache=cache)
        assert cache.merged[2] is not None                 # merged, not summed
        assert K1.nnz == Kf.nnz
        assert _close(want, K1)
        np.testing.assert_array_equal(f1, f)
    # outside the pattern (every diagonal entry): a plain sum
    D = sp.identity(rod.mesh.n_dofs, format="csc")
    _, K2, _ = _work(rod, r, R, r_n, R_n, pairs, lams, params, K_normal=D, cache=cache)
    assert _close(Kf + D, K2)
    # no pair carries a force (thin rods, no multipliers): the tangent is
    # K_normal itself
    lam_N, lam_T, lam_R = lams
    f4, K4, out = _work(rod, r, R, r_n, R_n, pairs, (0 * lam_N, lam_T, lam_R), params,
                        radius=0.1 * EPS, K_normal=Kn)
    assert out.index.size == 0 and K4 is Kn and not f4.any()


def test_rotational_friction_off_gives_the_same_matrix_as_zero_couples():
    """gamma_R = 0 skips the rotational-friction terms; the tangent equals
    the full assembly with a vanishing rotational law (gamma_R -> 0)."""
    rng, rod, r, R, r_n, R_n, sl, *lams = _setup(4)
    params = dict(REGIMES["slip"], gamma_R=0.0)
    pairs = _pairs(rod, r, sl)
    f0, K0, out = _work(rod, r, R, r_n, R_n, pairs, lams, params)
    assert np.all(out.force_R == 0)
    tiny = dict(params, gamma_R=1e-300)
    f1, K1, _ = _work(rod, r, R, r_n, R_n, pairs, lams, tiny)
    assert np.abs(f1 - f0).max() <= 1e-14 * np.abs(f0).max()
    assert _close(K0, K1)


def test_normal_tangent_of_wrong_shape_is_refused():
    rng, rod, r, R, r_n, R_n, sl, *lams = _setup(0)
    pairs = _pairs(rod, r, sl)
    n = rod.mesh.n_dofs
    with pytest.raises(ValueError, match=r"K_normal must be an \(%d, %d\) matrix" % (n, n)):
        _work(rod, r, R, r_n, R_n, pairs, lams, REGIMES["slip"],
              K_normal=sp.identity(n - 6, format="csc"))


def test_pattern_caches_belong_to_the_problem():
    """No module-level cache in the assemblers: every problem keeps its own
    patterns (:class:`ContactPatterns`), filled by its evaluations."""
    for mod in (ca, fa):
        assert not [n for n, v in vars(mod).items() if isinstance(v, dict)
                    and not n.startswith("__")], mod.__name__
    from test_contact import SEC, hairpin
    rod = Rod(hairpin(EPS, 0.2, leg=1.0), SEC, 16).clamp("start")
    rod.enable_contact(radius=EPS, gamma_T=0.3)
    p, q = Problem(rod), Problem(rod)
    assert isinstance(p.contact_patterns, ContactPatterns)
    assert p.contact_patterns is not q.contact_patterns
    p.multipliers.normal[:] = 0.01
    ev = p.evaluate(rod.r0, rod.R0, 0.0)
    assert ev.contact.fN.max() > 0
    assert p.contact_patterns.normal.pattern is not None
    assert p.contact_patterns.friction.pattern is not None
    assert q.contact_patterns.normal.pattern is None
    p.contact_patterns.clear()
    assert p.contact_patterns.friction.pattern is None
