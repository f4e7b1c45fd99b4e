"""Coulomb friction at the crossing pairs
(:func:`skfem_rod.contact.friction_assembly.crossing_friction_work`): the
consistent tangent against central differences of the residual, with both
closest-point parameters moving, a parameter held on a node, and a fading
pair's weight; a rigid motion of any size gives no slip.

Scenes: the two strands of tests/test_crossing.py (elements 10 eps long,
crossing between Gauss points), a random last converged state a step
away, random carried multipliers, in a regime where the pair slips and in
one where it sticks."""
import dataclasses

import numpy as np
import pytest

from skfem_rod.contact import friction as law
from skfem_rod.contact.crossing import PairThreshold, carry, crossing_pairs, crossing_work
from skfem_rod.contact.friction_assembly import FrictionParams, crossing_friction_work
from skfem_rod.contact.law import gap, normal_force
from skfem_rod.contact.slip import SlipState
from skfem_rod.element import shape_functions
from skfem_rod.problem import Problem
from skfem_rod.rotations import expm

from test_core import _figure_eight
from test_crossing import EPS, on_a_node, two_strands
from test_crossing_record import EPS as EPS8, nodal, pressed

#: the fading scenes' threshold (as tests/test_crossing.py): 25-30 degree
#: crossings fade
WIDE = PairThreshold(min_angle=np.pi / 3, n_slave=3, tolerance=1.0)
REGIMES = {                      # mu_N, gamma_T, gamma_R, mu_T, mu_R
    "slip": (0.1, 0.3, 0.05, 0.05, 0.05),
    "stick": (0.1, 5.0, 5.0, 50.0, 50.0),
}


class Scene:
    """A crossing scene with a last converged state and carried
    multipliers; :meth:`work` evaluates the crossing pairs' normal and
    friction work at a state, the held pairs fixed (as within a solve)."""

    def __init__(self, mesh, r, seed, regime, threshold=PairThreshold(), offset=0.0):
        rng = np.random.default_rng(seed)
        self.mesh, self.threshold, self.offset = mesh, threshold, offset
        nn = mesh.n_nodes
        self.r = r + 1e-3 * EPS * rng.normal(size=r.shape)
        self.R = expm(0.4 * rng.normal(size=(nn, 3)))
        self.r_n = self.r - 0.2 * EPS * rng.normal(size=(nn, 3))
        self.R_n = expm(0.05 * rng.normal(size=(nn, 3))).transpose(0, 2, 1) @ self.R
        mu_N, gT, gR, mu_T, mu_R = REGIMES[regime]
        self.mu_N = mu_N
        self.params = FrictionParams(gT, gR, mu_T, mu_R, push_forward=True)
        cp = self.pairs(self.r)
        self.held = (cp.key, 0.2 * np.ones(cp.size))
        self.lam_T = 0.05 * rng.normal(size=(cp.size, 3))
        self.lam_R = 0.05 * rng.normal(size=(cp.size, 3))

    def pairs(self, r, held=None):
        return crossing_pairs(self.mesh, r, EPS, np.pi * EPS, threshold=self.threshold,
                              held=held)

    def work(self, r, R, tangent=True):
        cp = self.pairs(r, self.held)
        lam = carry(self.held[0], self.held[1], cp.key)
        off = np.full(cp.size, self.offset)
        out = crossing_work(self.mesh, r, cp, lam, self.mu_N, EPS, tangent, offset=off,
                            weight_rows=tangent)
        l = cp.distance if cp.length is None else cp.length
        fN, dfN = normal_force(gap(l, EPS) + cp.weight * off, lam, self.mu_N)
        state = SlipState(r, R, self.r_n, self.R_n,
                          carry(self.held[0], self.lam_T, cp.key),
                          carry(self.held[0], self.lam_R, cp.key))
        f, K, fo = crossing_friction_work(self.mesh, state, cp, fN, dfN, self.params, tangent,
                                          dw=out[4] if tangent else None, offset=off)
        return cp, fN, f, K, fo

    def fd_check(self, seed=0, h=1e-6):
        """The friction tangent against central differences of its residual
        along a random direction of positions and spins."""
        cp, fN, f, K, fo = self.work(self.r, self.R)
        d = np.random.default_rng(seed).normal(size=self.mesh.n_dofs)
        d.reshape(-1, 6)[:, 3:] *= 0.1

        def shifted(t):
            dd = t * d.reshape(-1, 6)
            return self.r + dd[:, :3], expm(dd[:, 3:]) @ self.R

        fp = self.work(*shifted(h), tangent=False)[2]
        fm = self.work(*shifted(-h), tangent=False)[2]
        fd = (fp - fm) / (2 * h)
        assert np.abs(fd).max() > 0
        assert np.abs(fd - K @ d).max() <= 1e-6 * np.abs(fd).max()
        return cp, fN, f, fo


@pytest.mark.parametrize("regime", ["slip", "stick"])
@pytest.mark.parametrize("degrees, seed", [(90.0, 0), (60.0, 1), (35.0, 2)])
def test_crossing_friction_tangent(degrees, seed, regime):
    """Full-weight crossings at 35-90 degrees (both parameters free):
    the tangent, with the motion of both closest points, the moving shape
    functions of both strands and the normal force's derivative through
    the Coulomb radius, against central differences; the law holds at the
    pair (``|F| <= gamma f_N``, in the regime named)."""
    mesh, r = two_strands(np.radians(degrees), 1.6 * EPS, bend=0.05)
    sc = Scene(mesh, r, seed, regime)
    cp, fN, f, fo = sc.fd_check(seed)
    assert cp.size == 1 and cp.weight[0] == 1.0 and fN[0] > 0
    assert cp.u_free[0] and cp.v_free[0]
    want = law.SLIP if regime == "slip" else law.STICK
    assert fo.state_T[0] == want
    gT = sc.params.gamma_T
    assert np.linalg.norm(fo.force_T[0]) <= gT * fN[0] * (1 + 1e-12)
    if regime == "slip":
        assert np.linalg.norm(fo.force_T[0]) == pytest.approx(gT * fN[0], rel=1e-12)
    # the tangential force lies in the tangent plane of the contact
    assert abs(fo.force_T[0] @ cp.normal[0]) <= 1e-12 * np.linalg.norm(fo.force_T[0])


@pytest.mark.parametrize("regime", ["slip", "stick"])
def test_crossing_friction_tangent_on_a_node(regime):
    """A minimum held on a node of the C0 centreline (``u`` held, ``v``
    free): the held parameter does not move."""
    mesh, r = on_a_node()
    sc = Scene(mesh, r, 3, regime)
    cp = sc.fd_check(3)[0]
    assert cp.size == 1 and not cp.u_free[0] and cp.v_free[0]


@pytest.mark.parametrize("degrees, seed", [(26.0, 0), (29.5, 2)])
def test_fading_crossing_friction_tangent(degrees, seed):
    """A fading pair (weight between 0 and 1) with a gap offset: the
    weight's derivative (through the factor ``w`` and the gap ``2 eps + w
    offset - l`` of its normal force) is in the tangent."""
    mesh, r = two_strands(np.radians(degrees), 1.5 * EPS, bend=0.03)
    sc = Scene(mesh, r, seed, "slip", threshold=WIDE, offset=0.3 * EPS)
    cp = sc.fd_check(seed)[0]
    assert cp.size == 1 and 0.0 < cp.weight[0] < 1.0


def test_a_rigid_motion_gives_no_slip():
    """The pair's material slip (F6) over a step that moves the whole
    crossing rigidly by a rotation of 0.5 rad and a translation: zero to
    round-off, and the carried multipliers come out rotated with it."""
    mesh, r = two_strands(np.radians(70.0), 1.6 * EPS, bend=0.05)
    sc = Scene(mesh, r, 4, "slip")
    Q = expm(np.array([0.3, -0.2, 0.35]) / np.linalg.norm([0.3, -0.2, 0.35]) * 0.5)
    sc.r_n, sc.R_n = sc.r.copy(), sc.R.copy()
    r1 = sc.r @ Q.T + [0.3, -1.0, 2.0]
    R1 = Q @ sc.R
    cp, fN, _, _, fo = sc.work(r1, R1, tangent=False)
    assert cp.size == 1 and fN[0] > 0
    assert np.abs(fo.slip_T).max() <= 1e-12 * EPS
    # the carried multiplier, pushed forward, is the rotated one: in stick
    # the force is that multiplier, rotated
    sc.params = dataclasses.replace(sc.params, gamma_T=1e3)
    fo = sc.work(r1, R1, tangent=False)[4]
    np.testing.assert_allclose(fo.force_T[0], Q @ sc.lam_T[0] - (Q @ sc.lam_T[0] @ cp.normal[0])
                               * cp.normal[0], atol=1e-12)


# -- a scene: the pressed figure-eight pulled sideways -------------------------


def sideways(gamma, pull, crossing_friction=True, constant=False):
    """The figure-eight of tests/test_crossing_record.py (strands crossing
    at 90 degrees between slave points, 3 eps apart, both ends clamped),
    pressed together at the crossing by opposite point forces 0.3 and
    pulled apart along x there by opposite forces ``pull`` (preloads with
    ``constant``): the crossing pair alone carries the contact; friction
    ``gamma``."""
    rod = pressed(0.3, constant)
    _, (s1, s2) = _figure_eight(EPS8, 3 * EPS8)
    sn = rod.mesh.s_nodes
    a, b = (float(sn[np.argmin(abs(sn - s))]) for s in (s1, s2))
    rod.add_force(a, [pull, 0.0, 0.0], constant=constant)
    rod.add_force(b, [-pull, 0.0, 0.0], constant=constant)
    return rod.enable_contact(crossing=True, gamma_T=gamma, crossing_friction=crossing_friction)


def nodal_spin(mesh, s, couples):
    """Point couples ``(k, 3)`` at arclengths ``s`` on the spin dofs."""
    out = nodal(mesh, s, couples).reshape(-1, 6)
    return np.concatenate([np.zeros_like(out[:, :3]), out[:, :3]], axis=1).ravel()


def at(mesh, r, s):
    """The centreline ``r`` (nodal) at arclengths ``s``."""
    e, xi = mesh.locate(np.asarray(s, float))
    return np.einsum("ik,ikc->ic", shape_functions(xi)[0].T, r[mesh.nodes[e]])


def assert_crossing_coulomb_and_balance(rod, res, gamma, pull):
    """At every converged step: Coulomb's law at each crossing pair (the
    bound; the force along the slip where it slips; the slip within the
    loop's tolerance of zero where it sticks; no negative dissipation), and
    the rod balanced by the recorded normal and friction forces alone (the
    friction acts at the surface points: a couple ``(l/2) N x w F`` on
    each section).  Returns the pairs' states per step."""
    bare = sideways(gamma, pull)
    bare.contact = None
    p = Problem(bare)
    c = rod.contact
    mu = c.crossing_friction_params().mu_T
    states = []
    for st in res.steps[1:]:
        cr = st.contact.crossing
        assert st.contact.s.size == 0 and cr.s.size == 1       # the crossing pair alone
        fN = cr.force / cr.weight                              # before the weight
        F = cr.friction / cr.weight[:, None]
        bound = gamma * fN
        nF = np.linalg.norm(F, axis=1)
        assert np.all(nF <= bound * (1 + 1e-9))
        slip = cr.state == law.SLIP
        np.testing.assert_allclose(nF[slip], bound[slip], rtol=1e-9)
        if np.any(slip):
            assert law.misalignment(F[slip], cr.slip[slip], gamma, fN[slip]).max() \
                <= c.friction_tolerance
        # in stick F - lambda = g / mu, and the loop stops once every
        # component of F - lambda is within friction_tolerance gamma f_N
        # (one pair: its own f_N), so |g| <= sqrt(3) tol mu gamma f_N
        stick = cr.state == law.STICK
        assert np.all(np.linalg.norm(cr.slip[stick], axis=1)
                      <= np.sqrt(3) * c.friction_tolerance * mu * bound[stick])
        assert np.all(np.sum(cr.friction[slip] * cr.slip[slip], axis=1) > 0)
        assert np.all(np.abs(np.sum(cr.friction * cr.normal, axis=1)) <= 1e-12 * bound)
        states.append(cr.state.copy())
        # the balance
        ev = p.evaluate(st.r, st.R, st.load_factor, tangent=False)
        f = -ev.residual
        fn = cr.force[:, None] * cr.normal
        f += nodal(rod.mesh, cr.s, fn) - nodal(rod.mesh, cr.s_bar, fn)
        arm = 0.5 * (2 * c.radius + cr.weight * cr.offset - cr.gap)
        couple = arm[:, None] * np.cross(cr.normal, cr.friction)
        f += nodal(rod.mesh, cr.s_bar, cr.friction) - nodal(rod.mesh, cr.s, cr.friction)
        f += nodal_spin(rod.mesh, cr.s, couple) + nodal_spin(rod.mesh, cr.s_bar, couple)
        scale = max(cr.force.max(), np.abs(ev.external).max())   # contact or loads
        if np.any(np.linalg.norm(cr.friction, axis=1) > 1e-3 * scale):
            # without the friction forces the misfit is of their order
            g = f - nodal(rod.mesh, cr.s_bar, cr.friction) + nodal(rod.mesh, cr.s, cr.friction)
            assert np.abs(g[p.free]).max() > 0.1 * np.linalg.norm(cr.friction, axis=1).max()
        # to 1e-8 of the forces, or to the residual the step converged to
        # (at the first contact the loads are 2e-3 and the residual stops
        # at its round-off floor, 3.7e-10)
        assert np.linalg.norm(f[p.free]) <= 1e-8 * scale + 2 * st.residual_history[-1]
    return states


PULL = 0.02


def solved(gamma):
    rod = sideways(gamma, PULL)
    res = rod.solve(2)
    assert res.converged, res.message
    return rod, res


def relative(rod, res):
    """Displacement of the first point's material point relative to the
    second's over the last step (both in contact), at the last step's
    pair."""
    cr = res.steps[-1].contact.crossing
    r0, r1 = res.steps[-2].r, res.steps[-1].r
    return ((at(rod.mesh, r1, cr.s) - at(rod.mesh, r0, cr.s))
            - (at(rod.mesh, r1, cr.s_bar) - at(rod.mesh, r0, cr.s_bar)))[0]


def test_a_crossing_pulled_sideways_slips_then_sticks():
    """gamma_T = 0.1: at the first contact (load factor 1/128) the pull is
    more than friction holds and the pair slips, at ``|F| = gamma_T f_N``
    along its slip; pressed harder, it sticks at every later step (its slip
    within the loop's tolerance of zero, ``|F|`` at 0.7 of the bound).
    Coulomb's law and the balance of the recorded forces at every step;
    each step converges in at most 5 Newton iterations and one Uzawa
    update (with the round-off sphere counted as stick: Newton cycled at
    every step size before, docs/crossing-contact.md)."""
    rod, res = solved(0.1)
    states = assert_crossing_coulomb_and_balance(rod, res, 0.1, PULL)
    assert states[0][0] == law.SLIP
    assert all(s[0] == law.STICK for s in states[1:]) and len(states) >= 3
    assert max(len(st.residual_history) for st in res.steps[1:]) <= 6
    assert max(st.contact.uzawa for st in res.steps[1:]) <= 2


def test_a_restart_carries_the_crossing_pairs_friction():
    """A solve started from the last state of the sticking run
    (``Rod.solve(start=result)``, the loads held as preloads) carries the
    pair's friction force with its normal multiplier: its step 0 starts in
    balance (residual below 1e-6 of the pressing force), takes no Uzawa
    update, and keeps the recorded forces; carried at zero (a restart
    that drops them) the loop finds the same force again."""
    rod, res = solved(0.1)
    last = res.steps[-1].contact.crossing
    assert np.linalg.norm(last.friction) > 0.01 * last.force[0]
    again = sideways(0.1, PULL, constant=True).solve(1, start=res)
    assert again.converged, again.message
    st0 = again.steps[0]
    assert st0.contact.uzawa == 0
    assert st0.residual_history[0] <= 1e-6 * 0.3
    np.testing.assert_allclose(st0.contact.crossing.friction, last.friction, rtol=1e-6,
                               atol=1e-9)
    # carried at zero, the friction force is found again, by the loop:
    # its first pass sticks at the slip that makes the force, the update
    # knocks the trial force out of the ball, the next pass fails and the
    # generalized Newton rescues it from the multipliers the first pass
    # converged with (augmented.step; from the updated ones it slid the
    # pair by the clearance cap and step 0 failed)
    last.friction = np.zeros_like(last.friction)
    off = sideways(0.1, PULL, constant=True).solve(1, start=res)
    assert off.converged, off.message
    st0 = off.steps[0]
    assert st0.contact.uzawa >= 1 and st0.contact.crossing.state[0] == law.STICK
    np.testing.assert_allclose(st0.contact.crossing.friction, again.steps[0].contact.crossing
                               .friction, rtol=1e-3)


def test_the_scene_summary_holds_the_crossing_friction():
    """A scene's JSON summary (``scene.summary``) holds the last step's
    crossing pairs with their friction forces and states."""
    from types import SimpleNamespace
    from skfem_rod.scene import summary
    rod, res = solved(1.0)
    clamps = [dict(where="start"), dict(where="end")]
    out = summary(SimpleNamespace(name="x", source=None, title="", data=dict(support=clamps)),
                  res)
    x = out["end_state"]["contact"]["crossing"]
    cr = res.steps[-1].contact.crossing
    np.testing.assert_array_equal(x["friction"], cr.friction)
    assert np.linalg.norm(cr.friction) > 0 and list(x["state"]) == [law.STICK]


@pytest.mark.slow
def test_a_crossing_slides_where_friction_cannot_hold_it():
    """gamma_T = 0.05: the crossing slides at every step at the Coulomb
    bound along its slip (dissipating), Coulomb's law and the balance at
    every step; over the last step the two strands' material points in
    contact move apart by a tenth of a radius and more, where with
    gamma_T = 1 they move together (the pair sticks at every step)."""
    rod, res = solved(0.05)
    states = assert_crossing_coulomb_and_balance(rod, res, 0.05, PULL)
    assert all(s[0] == law.SLIP for s in states)
    assert all(st.contact.dissipation > 0 for st in res.steps[1:])
    held_rod, held = solved(1.0)
    assert all(s[0] == law.STICK for s in assert_crossing_coulomb_and_balance(
        held_rod, held, 1.0, PULL))
    slid, stuck = relative(rod, res), relative(held_rod, held)
    assert np.linalg.norm(slid) > 0.1 * EPS8
    assert np.linalg.norm(stuck) < 0.01 * np.linalg.norm(slid)


# -- the generalized Newton: the crossing pairs' friction multipliers ----------

def flattened_eight(monkeypatch):
    """The figure-eight of test_nonsmooth_crossing's fading test: flattened
    so that its strands cross at 42 degrees (1.92 eps apart, 60 elements,
    both ends clamped), with the wide threshold: its crossing pair fades
    (weight 0.55 at the states used here)."""
    from skfem_rod import Rod, Section
    from skfem_rod.contact import ContactOptions
    eps = 0.01
    shape, _ = _figure_eight(eps, 1.92 * eps, flatten=np.tan(np.radians(21.0)))
    rod = Rod(shape, Section.circle(E=1e7, nu=0.3, radius=eps), 60)
    rod.clamp("start").clamp("end")
    monkeypatch.setattr(ContactOptions, "crossing_threshold", lambda self: WIDE)
    return rod


def step_away(p, r, R, eps, rng):
    """The problem ``p`` at ``(r, R)`` with one crossing pair: a random last
    converged state a step away and carried multipliers on the pair
    (normal 0.5, a gap offset of 0.1 eps, which a fading pair's f_N reads
    through its weight, and a friction multiplier)."""
    p.reference = (r - 0.05 * eps * rng.normal(size=r.shape),
                   expm(0.02 * rng.normal(size=(r.shape[0], 3))).transpose(0, 2, 1) @ R)
    cp = p.evaluate(r, R, 0.0).contact.crossing
    assert cp.size == 1
    p.multipliers.rekey_crossing(cp.key.copy(), np.array([0.5]), offset=np.array([0.1 * eps]),
                                 friction=np.array([[0.2, -0.1, 0.05]]))


@pytest.mark.parametrize("gamma, want, fading", [(0.1, law.SLIP, False),
                                                 (5.0, law.STICK, False),
                                                 (0.1, law.SLIP, True)])
def test_generalized_jacobian_with_crossing_friction(gamma, want, fading, monkeypatch):
    """The overlapping figure-eight of tests/test_nonsmooth_crossing.py
    with friction, a last converged state a step away and carried
    multipliers: the crossing pair's friction multipliers are unknowns of
    the generalized Newton (3 rows ``C = c - lambda`` after its normal
    one).  The whole generalized Jacobian against central differences of
    ``(G, C)``, and the friction rows' own blocks (``dC/dy``,
    ``dC/dlambda``, ``dG/dlambda``, and in slip ``dC/dlambda_c`` through
    the Coulomb radius) each against their own differences."""
    from skfem_rod import nonsmooth
    from test_nonsmooth import assert_jacobian
    from test_nonsmooth_crossing import _pressed_figure_eight, _residuals
    rng = np.random.default_rng(5)
    rod, eps = _pressed_figure_eight()
    if fading:
        rod = flattened_eight(monkeypatch)
    rod.enable_contact(crossing=True, gamma_T=gamma)
    p = Problem(rod)
    r, R = rod.r0, rod.R0
    if fading:
        r = r + 1e-2 * eps * np.random.default_rng(1).normal(size=r.shape)
    step_away(p, r, R, eps, rng)
    with p.crossing_unknowns(), p.friction_unknowns():
        ev = p.evaluate(r, R, 0.0)
        cs = nonsmooth.contact_blocks(p, ev, crossing=True)
        x = nonsmooth.unknowns(p, ev.contact.crossing)
        cp = ev.contact.crossing
        ns = p.multipliers.normal.size
        cf = ev.contact.crossing_friction
        assert cf.state_T[0] == want
        assert (0.05 < cp.weight[0] < 0.95) if fading else cp.weight[0] == 1.0
        assert (ev.contact.crossing_dw.nnz > 0) == fading
        assert x.size == cs.C.size == 4 * ns + 1 + 3       # normal, tangential, crossing
        assert np.all(cs.active[-3:])
        dy = rng.normal(size=p.mesh.n_dofs)
        dy.reshape(-1, 6)[:, 3:] *= 0.3
        dl = 0.01 * rng.normal(size=x.size)
        assert_jacobian(p, ev, cs, lambda *a: _residuals(p, cp, *a), r, R, x, dy, dl)
        # the friction rows and columns alone
        h = 1e-7
        e_c = np.zeros_like(x)
        e_c[-4] = 1.0                       # the pair's normal multiplier
        for part, d_y, d_l in (("dC/dy", dy, np.zeros_like(x)),
                               ("dC/dlambda", np.zeros_like(dy), np.r_[np.zeros(x.size - 3),
                                                                       [1.0, -0.5, 0.3]]),
                               ("dC/dlambda_c", np.zeros_like(dy), e_c)):
            if part == "dC/dlambda_c" and want == law.STICK:
                continue                    # c does not depend on f_N in stick
            plus = _residuals(p, cp, *p.update(r, R, d_y, h), x + h * d_l)
            minus = _residuals(p, cp, *p.update(r, R, d_y, -h), x - h * d_l)
            fd = [(a - b) / (2 * h) for a, b in zip(plus, minus)]
            J = (ev.tangent @ d_y + cs.K_yl @ d_l, cs.K_ly @ d_y + cs.D @ d_l)
            assert np.abs(fd[1][-3:]).max() > 0, part
            assert np.abs(fd[1][-3:] - J[1][-3:]).max() <= 1e-6 * np.abs(fd[1][-3:]).max(), part
            assert np.abs(fd[0] - J[0]).max() <= 1e-6 * np.abs(fd[0]).max(), part


@pytest.mark.parametrize("curve, fading", [("elements", False), ("smooth", False),
                                           ("smooth", True)])
def test_the_problems_tangent_with_crossing_friction(curve, fading, monkeypatch):
    """``Problem.evaluate`` with friction at the crossing pairs (the
    overlapping figure-eight of test_nonsmooth_crossing, on the P3
    centreline or the smooth contact curve, whose dofs map to the rod's;
    ``fading``: the flattened eight at 42 degrees, weight 0.55, with a gap
    offset), a last converged state a step away and carried multipliers:
    the whole tangent against central differences of the residual."""
    from test_nonsmooth_crossing import _pressed_figure_eight
    rng = np.random.default_rng(7)
    rod, eps = _pressed_figure_eight()
    if fading:
        rod = flattened_eight(monkeypatch)
    rod.enable_contact(crossing=True, gamma_T=0.1, curve=curve)
    p = Problem(rod)
    r = rod.r0 + 1e-2 * eps * rng.normal(size=rod.r0.shape)
    R = rod.R0
    step_away(p, r, R, eps, rng)
    ev = p.evaluate(r, R, 0.0)
    cf = ev.contact.crossing_friction
    assert cf.index.size == 1 and cf.state_T[0] == law.SLIP
    assert (0.05 < ev.contact.crossing.weight[0] < 0.95) if fading else \
        ev.contact.crossing.weight[0] == 1.0
    d = rng.normal(size=p.mesh.n_dofs)
    d.reshape(-1, 6)[:, 3:] *= 0.3
    h = 1e-7
    fp = p.evaluate(*p.update(r, R, d, h), 0.0, tangent=False).residual
    fm = p.evaluate(*p.update(r, R, d, -h), 0.0, tangent=False).residual
    fd = (fp - fm) / (2 * h)
    assert np.abs(fd - ev.tangent @ d).max() <= 1e-6 * np.abs(fd).max()
    # the friction's part is visible in it
    p.contact = dataclasses.replace(p.contact, crossing_friction=False)
    K0 = p.evaluate(r, R, 0.0).tangent
    assert np.abs((ev.tangent - K0) @ d).max() > 1e-4 * np.abs(fd).max()


def test_no_crossing_friction_work_without_gamma_T():
    """With the rotational law alone (``gamma_R > 0``, ``gamma_T = 0``) or
    ``crossing_friction=False`` the crossing pairs carry no friction: the
    evaluation has no crossing friction output (the friction work is not
    evaluated there)."""
    from test_nonsmooth_crossing import _pressed_figure_eight
    for kw in (dict(gamma_T=0.0, gamma_R=1e-3), dict(gamma_T=0.1, crossing_friction=False)):
        rod, eps = _pressed_figure_eight()
        rod.enable_contact(crossing=True, **kw)
        p = Problem(rod)
        p.reference = (rod.r0, rod.R0)
        ce = p.evaluate(rod.r0, rod.R0, 0.0).contact
        assert ce.crossing.size == 1 and ce.crossing_fN[0] > 0
        assert ce.crossing_friction is None and ce.crossing_dw is None
