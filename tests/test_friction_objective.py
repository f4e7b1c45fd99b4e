"""Friction slips exact for finite rotations and the rotational law on the
circumferential sliding (skfem_rod.contact.slip, friction_assembly;
docs/friction.md F6, F7): a rigid step of 0.5 rad gives zero slip, the same
stick/slip states and rotated forces; the tangent with pushed-forward
multipliers and large step rotations matches finite differences; gamma_R
gives no couple against relative bending, and twist is resisted by
gamma_R f_N whether or not tangential friction is on; and a whole load
step that moves a pressed frictional contact rigidly by 0.5 rad converges
to the rigidly moved state with zero slip and turned forces."""
import numpy as np
import pytest

from skfem_rod import Rod, Section
from skfem_rod.contact import friction as law
from skfem_rod.contact.friction_assembly import FrictionParams, friction_work
from skfem_rod.contact.law import NormalLaw
from skfem_rod.contact.search import search, slave_points
from skfem_rod.contact.slip import SlipState
from skfem_rod.rotations import expm

from test_contact import SEC, hairpin  # noqa: F401
from test_friction_assembly import EPS, _setup


def _work(rod, r, R, r_n, R_n, sl, lams, p, mu_N=1e-3, tangent=True):
    pairs = search(rod.mesh, r, sl, reach=2 * EPS + 0.05, exclusion=np.pi * EPS)
    lam_N, lam_T, lam_R = lams
    return friction_work(rod.mesh, SlipState(r, R, r_n, R_n, lam_T, lam_R), pairs,
                         NormalLaw(lam_N, mu_N, EPS), p, tangent=tangent)


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


@pytest.mark.parametrize("rotational", ["twist", "circumferential", "pivot"])
@pytest.mark.parametrize("seed", [0, 1])
def test_rigid_step_of_half_a_radian(seed, rotational):
    """From a deformed contact state with carried multipliers (some inside
    their Coulomb ball: stick, some beyond: slip), a rigid rotation by 0.5
    rad plus a translation over the step: slips zero to round-off, the same
    states and normal forces, friction forces and couples rotated with the
    motion; the multipliers' update pulled back to the last converged state
    is the force of the step without motion."""
    rng, rod, r, R, r_n, R_n, sl, lam_N, lam_T, lam_R = _setup(seed)
    lam_T = 3.0 * rng.normal(size=lam_T.shape)     # the balls: gamma f_N ~ 3 and 0.1
    lam_R = 0.1 * rng.normal(size=lam_R.shape)
    p = FrictionParams(gamma_T=0.3, gamma_R=0.01, mu_T=1e-3, mu_R=1e-3, push_forward=True,
                       rotational=rotational)
    lams = (lam_N, lam_T, lam_R)
    f0, K0, o0 = _work(rod, r_n, R_n, r_n, R_n, sl, lams, p)
    assert np.abs(o0.slip_T).max() == 0 and np.abs(o0.slip_R).max() == 0
    for st in (o0.state_T, o0.state_R):
        assert (st == law.STICK).sum() >= 5 and (st == law.SLIP).sum() >= 5
    Q = expm(0.5 * _unit(rng.normal(size=3)))
    c = rng.normal(size=3)
    f1, K1, o1 = _work(rod, r_n @ Q.T + c, Q @ R_n, r_n, R_n, sl, lams, p)
    assert np.array_equal(o1.slave, o0.slave)
    assert np.abs(o1.slip_T).max() < 1e-14 and np.abs(o1.slip_R).max() < 1e-12
    assert np.array_equal(o1.state_T, o0.state_T) and np.array_equal(o1.state_R, o0.state_R)
    np.testing.assert_allclose(o1.fN, o0.fN, rtol=1e-10)
    scale_T, scale_R = np.abs(o0.force_T).max(), np.abs(o0.force_R).max()
    assert np.abs(o1.force_T - o0.force_T @ Q.T).max() < 1e-10 * scale_T
    # a stick force is its multiplier plus slip / mu_R: the slip's own
    # round-off (1.3e-14 for the circumferential law at seed 1, below the
    # 1e-12 asserted above) shows in it divided by the compliance
    # (1.28e-11 measured, 1e-10 scale_R = 1.27e-11)
    assert np.abs(o1.force_R - o0.force_R @ Q.T).max() < \
        1e-10 * scale_R + np.abs(o1.slip_R).max() / p.mu_R
    assert np.abs(o1.multiplier_T - o0.force_T).max() < 1e-10 * scale_T
    # the residual is the rotated one: forces and couples rotate with Q
    g0, g1 = f0.reshape(-1, 6), f1.reshape(-1, 6)
    assert np.abs(g1[:, :3] - g0[:, :3] @ Q.T).max() < 1e-9 * np.abs(g0).max()
    assert np.abs(g1[:, 3:] - g0[:, 3:] @ Q.T).max() < 1e-9 * np.abs(g0).max()
    # without the push-forward the carried forces do not turn: the same
    # step is read as slip where the points stick
    q = FrictionParams(gamma_T=0.3, gamma_R=0.01, mu_T=1e-3, mu_R=1e-3, push_forward=False)
    o2 = _work(rod, r_n @ Q.T + c, Q @ R_n, r_n, R_n, sl, lams, q, tangent=False)[2]
    assert np.abs(o2.force_T - o0.force_T @ Q.T).max() > 0.1 * scale_T


@pytest.mark.parametrize("rotational", ["twist", "circumferential", "pivot"])
@pytest.mark.parametrize("push", [True, False])
@pytest.mark.parametrize("regime", ["slip", "stick"])
@pytest.mark.parametrize("seed", [3, 4])
def test_tangent_with_large_step_rotations(seed, regime, push, rotational):
    """Sections turned by up to 0.5 rad over the step (not small): the
    tangent is the exact derivative of the residual (central differences)."""
    rng, rod, r, R, r_n, R_n, sl, lam_N, lam_T, lam_R = _setup(seed)
    R = expm(0.5 * _unit(rng.normal(size=3)) + 0.05 * rng.normal(size=(len(R), 3))) @ R_n
    p = (FrictionParams(0.1, 0.003, 1e-3, 1e-3, push, rotational) if regime == "slip"
         else FrictionParams(5.0, 2.0, 1e-1, 1e-1, push, rotational))
    lams = (lam_N, lam_T, lam_R)
    f, K, out = _work(rod, r, R, r_n, R_n, sl, lams, p)
    want = law.SLIP if regime == "slip" else law.STICK
    assert out.index.size > 20
    assert (out.state_T == want).mean() > 0.5 and (out.state_R == want).mean() > 0.4
    d = rng.normal(size=rod.mesh.n_dofs)
    d.reshape(-1, 6)[:, 3:] *= 0.3

    def shifted(t):
        dd = t * d.reshape(-1, 6)
        return r + dd[:, :3], expm(dd[:, 3:]) @ R

    h = 1e-7
    fd = (_work(rod, *shifted(h), r_n, R_n, sl, lams, p, tangent=False)[0]
          - _work(rod, *shifted(-h), r_n, R_n, sl, lams, p, tangent=False)[0]) / (2 * h)
    assert np.abs(fd - K @ d).max() <= 1e-6 * np.abs(fd).max()


def _legs(n=24):
    """The hairpin of the contact tests (legs along x, 0.2 apart, contact
    radius 0.105: pressed by 0.01) and the nodes of the upper leg beyond
    x = 0.3 (its sections are turned; near the bend N is not y)."""
    rod = Rod(hairpin(EPS, 0.2, leg=1.0), SEC, n)
    s = rod.mesh.s_nodes
    upper = s > 1.0 + np.pi * 0.1 + 0.3 - 1e-12
    return rod, upper


def _twist(rod, upper, axis, angle):
    R = rod.R0.copy()
    R[upper] = expm(angle * np.asarray(axis, float)) @ rod.R0[upper]
    return R


@pytest.mark.parametrize("rotational", ["twist", "circumferential"])
@pytest.mark.parametrize("axis", [[0, 0, 1.0], [0, 1.0, 0]])
def test_gamma_R_gives_no_couple_against_relative_bending(axis, rotational):
    """The upper leg's sections turned about z (relative bending in the
    plane of the legs) or about the normal y, centrelines held: with
    gamma_R alone no friction at all (the sliding it causes is axial, or
    none); the old law on the whole relative rotation gave couples of
    about gamma_R f_N."""
    rod, upper = _legs()
    sl = slave_points(rod.mesh, 3)
    ns = sl.s.size
    lams = (0.05 * np.ones(ns), np.zeros((ns, 3)), np.zeros((ns, 3)))
    R = _twist(rod, upper, axis, 0.05)
    p = FrictionParams(gamma_T=0.0, gamma_R=EPS, mu_T=1e-3, mu_R=1e-3 / EPS**2,
                       rotational=rotational)
    f, K, out = _work(rod, rod.r0, R, rod.r0, rod.R0, sl, lams, p)
    assert out.index.size > 20 and out.fN.min() > 0
    assert np.abs(out.force_R).max() < 1e-12 * EPS * out.fN.max()
    assert np.abs(out.slip_R).max() < 1e-12
    assert np.abs(f).max() < 1e-12 * out.fN.max()
    # while the full relative rotation (the earlier g_R) is 0.05 rad there


def test_twist_is_resisted_by_gamma_R_fN_only():
    """rotational="circumferential".  The upper leg's sections twisted about the legs' axis x by 0.05 rad
    (its centreline held), well past the stick range: every pair between
    the legs slips rotationally with |f_R| = gamma_R f_N and no axial force,
    the twisting couple on the upper leg is sum w gamma_R f_N, and it is
    the same with tangential friction on (gamma_T = 0.3): twist is not
    counted twice (the earlier slips gave (gamma_R + eps gamma_T) f_N)."""
    rod, upper = _legs()
    sl = slave_points(rod.mesh, 3)
    ns = sl.s.size
    lams = (0.05 * np.ones(ns), np.zeros((ns, 3)), np.zeros((ns, 3)))
    R = _twist(rod, upper, [1.0, 0, 0], 0.05)
    res = {}
    for gamma_T in (0.0, 0.3):
        p = FrictionParams(gamma_T=gamma_T, gamma_R=EPS, mu_T=1e-4, mu_R=1e-4 / EPS**2,
                           rotational="circumferential")
        f, K, out = _work(rod, rod.r0, R, rod.r0, rod.R0, sl, lams, p)
        res[gamma_T] = f, out
    (f0, o0), (f1, o1) = res[0.0], res[0.3]
    np.testing.assert_allclose(f1, f0, rtol=0, atol=1e-12 * np.abs(f0).max())
    assert np.abs(o1.force_T).max() < 1e-12 * o1.fN.max()
    # pairs whose two sections turned relative to each other by the full
    # 0.05 rad: rotational slip 0.05 rad about x, saturated
    full = np.abs(np.linalg.norm(o0.slip_R, axis=1) - 0.05) < 1e-3
    assert full.sum() > 10
    assert np.all(o0.state_R[full] == law.SLIP)
    np.testing.assert_allclose(np.abs(o0.force_R[full, 0]), EPS * o0.fN[full], rtol=1e-12)
    # the couple about x that each pair puts on both sections: gamma_R f_N
    # (the force f_R / rho along b at the contact point, lever arm rho)
    pairs = search(rod.mesh, rod.r0, sl, reach=2 * EPS + 0.05, exclusion=np.pi * EPS)
    w = pairs.weight[o0.index]
    Mx = f0.reshape(-1, 6)[:, 3].sum()
    assert Mx == pytest.approx(2 * np.sum(w * o0.force_R[:, 0]), rel=1e-10)
    assert abs(Mx) > 0.9 * 2 * np.sum(w[full] * EPS * o0.fN[full])


def test_twist_mode_pure_couple_and_pivot():
    """rotational="twist": a twist of the upper leg's sections saturates at
    |f_R| = gamma_R f_N as a pure couple about the axis (the rotational
    scene's physics); with gamma_T on, the tangential law resists the
    surface sliding of the twist too.  rotational="pivot": a twist gives no
    rotational slip, a turn about the normal saturates at gamma_R f_N and
    gives no tangential slip."""
    rod, upper = _legs()
    sl = slave_points(rod.mesh, 3)
    ns = sl.s.size
    lams = (0.05 * np.ones(ns), np.zeros((ns, 3)), np.zeros((ns, 3)))
    R = _twist(rod, upper, [1.0, 0, 0], 0.05)
    p = FrictionParams(gamma_T=0.0, gamma_R=EPS, mu_T=1e-4, mu_R=1e-4 / EPS**2)
    f, K, out = _work(rod, rod.r0, R, rod.r0, rod.R0, sl, lams, p)
    full = np.abs(np.linalg.norm(out.slip_R, axis=1) - 0.05) < 1e-9
    assert full.sum() > 10 and np.all(out.state_R[full] == law.SLIP)
    np.testing.assert_allclose(np.abs(out.force_R[full, 0]), EPS * out.fN[full], rtol=1e-12)
    assert np.abs(out.force_T).max() == 0
    q = FrictionParams(gamma_T=0.0, gamma_R=EPS, mu_T=1e-4, mu_R=1e-4 / EPS**2,
                       rotational="pivot")
    out = _work(rod, rod.r0, R, rod.r0, rod.R0, sl, lams, q, tangent=False)[2]
    assert np.abs(out.slip_R).max() < 1e-12
    Rp = _twist(rod, upper, [0, 1.0, 0], 0.05)                  # about N = y
    out = _work(rod, rod.r0, Rp, rod.r0, rod.R0, sl, lams, q, tangent=False)[2]
    full = np.abs(np.linalg.norm(out.slip_R, axis=1) - 0.05) < 1e-9
    assert full.sum() > 10
    np.testing.assert_allclose(np.abs(out.force_R[full, 1]), EPS * out.fN[full], rtol=1e-12)
    assert np.abs(out.slip_T[full]).max() < 1e-14


def _pressed_hairpin(Q, c, theta, eps=0.02):
    """A hairpin (legs 2.1 eps apart) whose two ends are held and, over
    load step 1, moved rigidly by ``x -> Q x + c`` (``Q = exp(theta)``);
    two constant follower forces press the free stretch of one leg onto the
    other and drag it along, so that at step 0 the legs touch with
    tangential and rotational friction at work."""
    sec = Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=0.8, radius=eps)
    rod = Rod(hairpin(eps, 2.1 * eps, leg=0.5), sec, 16)
    for e in ("start", "end"):
        x0 = rod.r0[rod.node(e)]
        rod.prescribe_displacement(e, Q @ x0 + c - x0)
        rod.prescribe_rotation(e, theta)
    L = rod.length
    rod.add_force(L * 36 / 48, [1.5, -10.0, 0.0], follower=True, constant=True)
    rod.add_force(L * 41 / 48, [2.5, -10.0, 0.5], follower=True, constant=True)
    rod.enable_contact(radius=eps, gamma_T=0.3, gamma_R=0.2 * eps)
    return rod


def test_rigid_load_step_of_half_a_radian_in_a_solve():
    """Issue 13's rigid step at the level of a solve: a pressed, frictional
    contact state (step 0: every tangential point slipping, on its Coulomb
    cone) moved rigidly by 0.5 rad and a translation in one load step.  The
    step converges to the rigidly moved state; the slips of the step are
    zero to round-off; normal forces are unchanged and friction forces and
    couples turn with the motion; the points that slipped stay on their
    cone (|f_T| = gamma_T f_N), the others keep their state.  Without the
    push-forward of the carried multipliers the same step is read as slip
    and the friction forces do not turn."""
    rng = np.random.default_rng(7)
    theta = 0.5 * _unit(rng.normal(size=3))
    Q, c = expm(theta), 0.1 * rng.normal(size=3)
    opts = dict(max_iterations=100, min_step=0.99)     # one step, never cut
    res = _pressed_hairpin(Q, c, theta).solve(1, **opts)
    assert res.converged and len(res.steps) == 2, res.message
    s0, s1 = res.steps
    c0, c1 = s0.contact, s1.contact
    assert c0.s.size >= 3 and np.array_equal(c1.s, c0.s)
    assert np.any(c0.state_T == law.SLIP) and np.any(c0.state_R == law.STICK)
    # the rigidly moved state, to the Newton tolerance
    assert np.abs(s1.r - (s0.r @ Q.T + c)).max() < 1e-9
    assert np.abs(s1.R - Q @ s0.R).max() < 1e-9
    # zero slip (step 0 slipped by 0.25 eps)
    eps = 0.02
    assert np.abs(c0.slip_T).max() > 0.1 * eps
    assert np.abs(c1.slip_T).max() < 1e-9 * eps
    assert np.abs(c1.slip_R).max() < 1e-9
    # forces: normal unchanged, friction turned with Q
    assert np.abs(c1.force - c0.force).max() < 1e-6 * c0.force.max()
    fT, fR = np.abs(c0.force_T).max(), np.abs(c0.force_R).max()
    assert np.abs(c1.force_T - c0.force_T @ Q.T).max() < 1e-6 * fT
    assert np.abs(c1.force_R - c0.force_R @ Q.T).max() < 1e-6 * fR
    # states: on the cone where they slipped (a zero slip leaves a force on
    # the cone, read as stick or slip at the Newton tolerance), unchanged
    # elsewhere
    on_cone = c0.state_T == law.SLIP
    ratio = np.linalg.norm(c1.force_T, axis=1) / (0.3 * c1.force)
    assert np.abs(ratio[on_cone] - 1).max() < 1e-5
    assert np.array_equal(c1.state_T[~on_cone], c0.state_T[~on_cone])
    assert np.array_equal(c1.state_R[c0.state_R == law.STICK], c0.state_R[c0.state_R == law.STICK])


def test_rigid_load_step_without_push_forward_reads_slip(monkeypatch):
    """The check of the test above can fail: with the carried multipliers
    not pushed forward (the friction forces of the last step kept in their
    old directions) the same rigid step is not the rigidly moved state for
    the Uzawa loop: measured, Newton does not even converge (residual 0.1
    after 100 iterations); if it did, the friction forces would not have
    turned.  (The Uzawa loop alone: its rescue by the generalized Newton,
    ``augmented.step``, solves for the friction multipliers and finds the
    fixed point whatever they start from: the rotated forces to 8e-4.)"""
    import functools
    from skfem_rod import augmented, solver
    from skfem_rod.contact import ContactOptions
    orig = ContactOptions.friction_params
    monkeypatch.setattr(ContactOptions, "friction_params",
                        lambda self, push_forward=True, **k: orig(self, False, **k))
    monkeypatch.setattr(solver, "step", functools.partial(augmented.step, rescue=False))
    rng = np.random.default_rng(7)
    theta = 0.5 * _unit(rng.normal(size=3))
    Q, c = expm(theta), 0.1 * rng.normal(size=3)
    res = _pressed_hairpin(Q, c, theta).solve(1, max_iterations=100, min_step=0.99)
    assert res.steps[0].contact.s.size >= 3
    if res.converged:
        c0, c1 = res.steps[0].contact, res.steps[1].contact
        assert np.abs(c1.force_T - c0.force_T @ Q.T).max() > 0.1 * np.abs(c0.force_T).max()
    else:
        assert len(res.steps) == 1 and "no convergence" in res.message


def test_evaluation_without_the_friction_work():
    """``Problem.evaluate(..., friction=False)`` (the stability checks'
    tangent) is the evaluation of the same contact without friction: equal
    to a frictionless problem's at the same state and normal multipliers,
    and different from the frictional one where the contact slips."""
    from dataclasses import replace

    from skfem_rod.problem import Problem
    rng = np.random.default_rng(3)
    theta = np.zeros(3)
    rod = _pressed_hairpin(np.eye(3), np.zeros(3), theta)
    st = rod.solve(1).steps[0]                  # step 0: pressed, slipping
    assert st.contact.s.size >= 3 and np.any(st.contact.state_T == law.SLIP)
    frictional = Problem(rod)
    plain_rod = _pressed_hairpin(np.eye(3), np.zeros(3), theta)
    plain_rod.contact = replace(plain_rod.contact, gamma_T=0.0, gamma_R=0.0)
    plain = Problem(plain_rod)
    lam_N = rng.uniform(0.5, 1.5, frictional.multipliers.normal.size)
    frictional.multipliers.normal = lam_N.copy()
    plain.multipliers.normal = lam_N.copy()
    r, R = st.r, st.R
    a = frictional.evaluate(r, R, 0.0, friction=False)
    b = plain.evaluate(r, R, 0.0)
    full = frictional.evaluate(r, R, 0.0)
    assert a.contact.friction is None
    np.testing.assert_array_equal(a.residual, b.residual)
    assert abs(a.tangent - b.tangent).max() == 0.0
    assert full.contact.friction is not None
    assert np.abs(full.residual - a.residual).max() > 1e-6     # the friction work (7.7e-3)
    assert frictional.friction            # the problem itself is unchanged
