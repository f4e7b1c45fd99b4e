"""Frictional contact work (skfem_rod.contact.friction_assembly): the
consistent tangent against central differences of the residual in seeded
random near-contact states, stick and slip, tangential and rotational;
rolling is not slip; the slips of rigid motions vanish."""
import numpy as np
import pytest

from skfem_rod import Rod
from skfem_rod.contact import friction as law
from skfem_rod.contact.friction_assembly import FrictionParams, friction_work
from skfem_rod.contact.law import NormalLaw
from skfem_rod.contact.search import search, slave_points
from skfem_rod.contact.slip import SlipState
from skfem_rod.rotations import expm

from test_contact import SEC, hairpin

EPS = 0.105


def _setup(seed, n_el=16):
    rng = np.random.default_rng(seed)
    rod = Rod(hairpin(EPS, 0.2, leg=1.0), SEC, n_el)
    nn = rod.mesh.n_nodes
    # last converged state: reference with noise; current: a step away
    r_n = rod.r0 + 0.002 * rng.normal(size=(nn, 3))
    R_n = expm(0.3 * rng.normal(size=(nn, 3))) @ rod.R0
    r = r_n + 0.004 * rng.normal(size=(nn, 3))
    R = expm(0.05 * rng.normal(size=(nn, 3))) @ R_n
    sl = slave_points(rod.mesh, 3)
    ns = sl.s.size
    lam_N = 0.01 * np.abs(rng.normal(size=ns))
    lam_T = 0.005 * rng.normal(size=(ns, 3))
    lam_R = 0.002 * rng.normal(size=(ns, 3))
    return rng, rod, r, R, r_n, R_n, sl, lam_N, lam_T, lam_R


def _eval(rod, r, R, r_n, R_n, sl, lams, params, tangent=True):
    pairs = search(rod.mesh, r, sl, reach=2 * EPS + 0.05, exclusion=np.pi * EPS)
    lam_N, lam_T, lam_R = lams
    p = FrictionParams(params["gamma_T"], params["gamma_R"], params["mu_T"], params["mu_R"])
    return friction_work(rod.mesh, SlipState(r, R, r_n, R_n, lam_T, lam_R), pairs,
                         NormalLaw(lam_N, params["mu_N"], EPS), p, tangent)


# two regimes: mostly slipping (small coefficients) and mostly sticking
REGIMES = {
    "slip": dict(mu_N=1e-3, gamma_T=0.3, gamma_R=0.01, mu_T=1e-3, mu_R=1e-3),
    "stick": dict(mu_N=1e-3, gamma_T=5.0, gamma_R=2.0, mu_T=1e-1, mu_R=1e-1),
}


@pytest.mark.parametrize("regime", ["slip", "stick"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_friction_tangent_matches_finite_differences(seed, regime):
    rng, rod, r, R, r_n, R_n, sl, *lams = _setup(seed)
    params = REGIMES[regime]
    f, K, out = _eval(rod, r, R, r_n, R_n, sl, lams, params)
    m = out.index.size
    assert m > 20
    st_T, st_R = out.state_T, out.state_R
    want = law.SLIP if regime == "slip" else law.STICK
    # the regime is what its name says for most points, tangential and rotational
    assert (st_T == want).mean() > 0.6 and (st_R == want).mean() > 0.6
    # the law holds pointwise: |f| <= gamma f_N
    assert np.all(np.linalg.norm(out.force_T, axis=1) <= params["gamma_T"] * out.fN * (1 + 1e-12))
    assert np.all(np.linalg.norm(out.force_R, axis=1) <= params["gamma_R"] * out.fN * (1 + 1e-12))
    d = rng.normal(size=rod.mesh.n_dofs)
    d.reshape(-1, 6)[:, 3:] *= 0.3

    def shifted(t):
        dd = t * d.reshape(-1, 6)
        return r + dd[:, :3], expm(dd[:, 3:]) @ R

    h = 1e-7
    fp = _eval(rod, *shifted(h), r_n, R_n, sl, lams, params, False)[0]
    fm = _eval(rod, *shifted(-h), r_n, R_n, sl, lams, params, False)[0]
    fd = (fp - fm) / (2 * h)
    Kd = K @ d
    assert np.abs(fd - Kd).max() <= 1e-6 * np.abs(fd).max()
    # the friction tangent is not symmetric (Coulomb)
    assert abs(K - K.T).max() > 1e-3 * abs(K).max()


def test_rigid_motion_gives_no_slip():
    """A rigid rotation + translation of the whole rod over the step is no
    slip: g_T = g_R = 0 at every pair, to round-off, for a finite rotation
    (the slips trace the material points back with the exact incremental
    rotations of their sections, docs/friction.md F6)."""
    rng, rod, r, R, r_n, R_n, sl, *lams = _setup(5)
    c = np.array([0.1, 0.2, -0.3])
    for angle in (1e-3, 0.3, 1.0):
        Q = expm(angle * np.array([0.3, -0.2, 0.5]) / np.linalg.norm([0.3, -0.2, 0.5]))
        f, K, out = _eval(rod, r_n @ Q.T + c, Q @ R_n, r_n, R_n, sl, lams, REGIMES["slip"])
        assert out.index.size > 0
        assert np.abs(out.slip_R).max() < 1e-12
        assert np.abs(out.slip_T).max() < 1e-14


def test_rolling_is_not_slip():
    """Two parallel legs rolling on each other: the slave leg translates
    along the legs by ``v`` while its sections spin by ``v / rho`` about the
    normal of the plane of the legs: the material points in contact do
    not move relative to each other, so g_T = 0 while the centreline points
    did move relative to each other."""
    rng, rod, r, R, r_n, R_n, sl, *lams = _setup(0)
    # state: the reference hairpin (legs along x at y = 0 and y = 0.2)
    r_n, R_n = rod.r0.copy(), rod.R0.copy()
    s = rod.mesh.s_nodes
    upper = s > 1.0 + np.pi * 0.1                    # the free (upper) leg
    v = 1e-3
    r = r_n.copy()
    r[upper, 0] += v                                 # upper leg moves along +x
    # rolling on the lower leg (contact normal N = +y from master to slave,
    # centreline distance l = 0.2, contact point at the midpoint, lever arm
    # rho = l/2): the slave's material point r - rho N must not move:
    # v e_x + w x (-rho e_y) = 0  ->  w = -v/rho e_z
    rho = 0.1
    R = R_n.copy()
    # (over a finite step: the slave's material point now at the contact
    # was at r_n - rho Lam^T N, so the slip vanishes for a turn by
    # asin(v / rho), v / rho to first order)
    R[upper] = expm(np.array([0.0, 0.0, -np.arcsin(v / rho)])) @ R_n[upper]
    f, K, out = _eval(rod, r, R, r_n, R_n, sl, lams, REGIMES["slip"])
    s_of = out.index
    assert s_of.size > 0
    pairs = search(rod.mesh, r, sl, reach=2 * EPS + 0.05, exclusion=np.pi * EPS)
    on_upper = pairs.s[s_of] > 1.0 + np.pi * 0.1 + 0.2
    on_lower = pairs.s[s_of] < 0.8
    assert on_upper.any() and on_lower.any()
    # slave on the rolling leg, master on the still one: no tangential slip
    assert np.abs(out.slip_T[on_upper]).max() < 1e-9 * v
    # nor rotational slip: the relative rotation about z (relative bending,
    # rolling) is not a twist about the rod axis (docs/friction.md F7)
    assert np.abs(out.slip_R[on_upper]).max() < 1e-9 * v / rho
    # the centreline points did move relative to each other by v
    # and sliding instead (no spin) is slip v along x
    f, K, out = _eval(rod, r, R_n, r_n, R_n, sl, lams, REGIMES["slip"])
    pairs = search(rod.mesh, r, sl, reach=2 * EPS + 0.05, exclusion=np.pi * EPS)
    on_upper = pairs.s[out.index] > 1.0 + np.pi * 0.1 + 0.2
    assert np.allclose(out.slip_T[on_upper], [v, 0, 0], atol=1e-9 * v)


@pytest.mark.parametrize("rotational", ["twist", "circumferential", "pivot"])
@pytest.mark.parametrize("push_forward", [True, False])
@pytest.mark.parametrize("regime", ["slip", "stick"])
def test_multiplier_jacobian_matches_finite_differences(regime, push_forward, rotational):
    """The Jacobian of the friction multipliers' update ``c = Lam_s^T f``
    (``FrictionOutput.jacobian``, the rows of the generalized Newton,
    skfem_rod.nonsmooth) against central differences: ``dc/dy``,
    ``dc/dlambda`` of both laws, ``dc/df_N`` (through the normal
    multipliers), and the residual's columns ``dG/dlambda``."""
    rng, rod, r, R, r_n, R_n, sl, *lams = _setup(1)
    prm = REGIMES[regime]
    p = FrictionParams(prm["gamma_T"], prm["gamma_R"], prm["mu_T"], prm["mu_R"],
                       push_forward=push_forward, rotational=rotational)

    def run(r, R, lams, tangent=False):
        pairs = search(rod.mesh, r, sl, reach=2 * EPS + 0.05, exclusion=np.pi * EPS)
        lam_N, lam_T, lam_R = lams
        return friction_work(rod.mesh, SlipState(r, R, r_n, R_n, lam_T, lam_R), pairs,
                             NormalLaw(lam_N, prm["mu_N"], EPS), p, tangent,
                             multiplier_jacobian=tangent)

    f, K, out = run(r, R, lams, tangent=True)
    J = out.jacobian
    m = out.index.size
    assert m > 20 and J.rows_T.shape == (m, 3, 48) and J.cols_R.shape == (m, 48, 3)
    # without the option, no Jacobian is computed
    pairs = search(rod.mesh, r, sl, reach=2 * EPS + 0.05, exclusion=np.pi * EPS)
    plain = friction_work(rod.mesh, SlipState(r, R, r_n, R_n, *lams[1:]), pairs,
                          NormalLaw(lams[0], prm["mu_N"], EPS), p, True)[2]
    assert plain.jacobian is None
    h = 1e-7

    def close(fd, an, what):
        err = np.abs(fd - an).max()
        scale = max(np.abs(fd).max(), np.abs(an).max())
        # a saturated 1D law (slip about one axis) has dc/dlambda = 0: the
        # difference is round-off there
        assert err <= 1e-6 * scale or err <= 1e-9, (what, err, scale)

    # d c / d y
    d = rng.normal(size=rod.mesh.n_dofs)
    d.reshape(-1, 6)[:, 3:] *= 0.3

    def shifted(t):
        dd = t * d.reshape(-1, 6)
        return r + dd[:, :3], expm(dd[:, 3:]) @ R

    op, om = run(*shifted(h), lams)[2], run(*shifted(-h), lams)[2]
    assert np.array_equal(op.slave, out.slave) and np.array_equal(om.slave, out.slave)
    for X in ("T", "R"):
        fd = (getattr(op, "multiplier_" + X) - getattr(om, "multiplier_" + X)) / (2 * h)
        close(fd, np.einsum("mij,mj->mi", getattr(J, "rows_" + X), d[J.dofs]), "dc/dy " + X)
    # d c / d lambda and d G / d lambda, each law: c is f / mu, so the
    # round-off of f is amplified by 1 / mu (1e3 here): a larger step
    # (the error falls as 1 / h down to 1e-3, measured)
    h = 1e-4
    for k, X in ((1, "T"), (2, "R")):
        dl = 0.003 * rng.normal(size=lams[k].shape)
        lp, lm = list(lams), list(lams)
        lp[k], lm[k] = lams[k] + h * dl, lams[k] - h * dl
        fp, _, op = run(r, R, lp)
        fm, _, om = run(r, R, lm)
        for Y in ("T", "R"):
            fd = (getattr(op, "multiplier_" + Y) - getattr(om, "multiplier_" + Y)) / (2 * h)
            an = (np.einsum("mij,mj->mi", getattr(J, "self_" + Y), dl[out.slave]) if X == Y
                  else np.zeros_like(fd))
            close(fd, an, f"dc_{Y}/dlambda_{X}")
        cols = np.einsum("mak,mk->ma", getattr(J, "cols_" + X), dl[out.slave])
        an = np.bincount(J.dofs.ravel(), weights=cols.ravel(), minlength=rod.mesh.n_dofs)
        close((fp - fm) / (2 * h), an, "dG/dlambda " + X)
    # d c / d f_N, through the normal multipliers (d f_N / d lambda_N = 1)
    dn = 0.003 * rng.normal(size=lams[0].shape)
    lp, lm = list(lams), list(lams)
    lp[0], lm[0] = lams[0] + h * dn, lams[0] - h * dn
    op, om = run(r, R, lp)[2], run(r, R, lm)[2]
    for X in ("T", "R"):
        fd = (getattr(op, "multiplier_" + X) - getattr(om, "multiplier_" + X)) / (2 * h)
        close(fd, getattr(J, "normal_" + X) * dn[out.slave][:, None], "dc/df_N " + X)
