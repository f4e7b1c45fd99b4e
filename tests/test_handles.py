"""The node barrier's handles (:mod:`skfem_rod.contact.barrier`, module
doc "Handles"): rigid straight continuations of a rod beyond its held
ends, so that no strand passes around an end and the link of held ends is
kept.  Their energy's gradient, Hessian and moments against finite
differences, their continuous collision detection, and their cap being
the end node's own barrier."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from skfem_rod.contact.barrier import Barrier, barrier_work, handle_pairs, step_bound

D, WIDTH = 0.05, 0.01


def _rod(seed=5):
    """Nodes of a rod: 21 along the x axis from 0 to 1 (s = x; the ends
    carry the handles, along -x and +x), then 12 far along the rod placed
    beside the end handle's side, within the barrier's width, and 3 beside
    the end node's cap on the rod's side."""
    rng = np.random.default_rng(seed)
    axis = np.column_stack([np.linspace(0, 1, 21), np.zeros(21), np.zeros(21)])
    side_x = np.linspace(1.12, 1.5, 12)
    ang = rng.uniform(0, 2 * np.pi, 12)
    rad = D + rng.uniform(0.2, 0.8, 12) * WIDTH
    side = np.column_stack([side_x, rad * np.cos(ang), rad * np.sin(ang)])
    cap_dir = np.array([[-0.05, 1.0, 0.2], [-0.1, -0.2, 1.0], [-0.02, 0.6, -0.8]])
    cap_dir /= np.linalg.norm(cap_dir, axis=1)[:, None]
    cap = axis[-1] + (D + np.array([0.3, 0.5, 0.7])[:, None] * WIDTH) * cap_dir
    x = np.vstack([axis, side, cap])
    s = np.r_[axis[:, 0], 3.0 + 0.05 * np.arange(15)]
    # node 0 starts the rod and node 20 ends it (the largest s is elsewhere:
    # only the handles' nodes matter here)
    return x, s, (0, 20), np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])


def _barrier(handles=(0, 20)):
    return Barrier(distance=D, width=WIDTH, stiffness=50.0, exclusion=0.3, handles=handles)


def test_handle_pairs_are_the_distances_to_the_capped_half_lines():
    x, s, ends, e = _rod()
    hp = handle_pairs(x, s, _barrier(), e, D + WIDTH)
    # the 12 beside the side and the 3 beside the cap, all against node 20
    assert sorted(hp.pairs[:, 0]) == list(range(21, 36))
    assert np.all(hp.pairs[:, 1] == 20)
    dist = np.linalg.norm(hp.q, axis=1)
    side = hp.pairs[:, 0] < 33
    assert np.allclose(dist[side], np.hypot(x[hp.pairs[side, 0], 1], x[hp.pairs[side, 0], 2]))
    assert np.all(hp.along[side] > 0) and np.all(hp.along[~side] == 0)
    assert np.allclose(dist[~side], np.linalg.norm(x[hp.pairs[~side, 0]] - x[20], axis=1))
    # the rod's own nodes are within the exclusion or behind the start
    # handle's end: none against it
    assert not np.any(hp.pairs[:, 1] == 0)


def test_handle_energy_gradient_hessian_and_moments_match_finite_differences():
    x, s, ends, e = _rod()
    bw = _barrier()
    w0 = barrier_work(x, s, bw, dofs=3, directions=e)
    assert np.isfinite(w0.energy) and w0.active == 15
    H = w0.hessian.toarray()
    assert np.allclose(H, H.T)
    rng = np.random.default_rng(11)
    v = rng.standard_normal(x.shape)
    h = 1e-7

    def work(y, dirs=e, hessian=False):
        return barrier_work(y, s, bw, hessian=hessian, dofs=3, directions=dirs)
    slope = float(np.sum(w0.gradient * v))
    fd = (work(x + h * v).energy - work(x - h * v).energy) / (2 * h)
    assert abs(fd - slope) <= 1e-6 * max(abs(slope), 1.0)
    fd_g = ((work(x + h * v).gradient - work(x - h * v).gradient) / (2 * h)).ravel()
    Hv = H @ v.ravel()
    assert np.linalg.norm(fd_g - Hv) <= 1e-5 * np.linalg.norm(Hv)
    # the moment on the end: the handle turned by a small spin about any axis
    for axis in np.eye(3)[1:]:
        turn = [Rotation.from_rotvec(sign * h * axis).as_matrix() for sign in (1, -1)]
        ep, em = (work(x, np.vstack([e[0], q @ e[1]])).energy for q in turn)
        assert (ep - em) / (2 * h) == pytest.approx(float(w0.spin_gradient[20] @ axis),
                                                    rel=1e-6, abs=1e-9)
    # the spin about the handle's own axis moves nothing
    assert w0.spin_gradient[20] @ e[1] == pytest.approx(0.0, abs=1e-12)
    assert not np.any(w0.spin_gradient[:20]) and not np.any(w0.spin_gradient[21:])


def test_a_nodes_cap_contact_is_the_node_pairs_barrier_moved_to_the_handle():
    """Beside the cap only (the side nodes removed), the handle's energy
    and forces are those of the node pairs with the end node without
    handles."""
    x, s, ends, e = _rod()
    keep = np.r_[0:21, 33:36]
    x, s = x[keep], s[keep]
    with_ = barrier_work(x, s, _barrier(), dofs=3, directions=e)
    without = barrier_work(x, s, _barrier(handles=()), dofs=3)
    assert with_.active == without.active == 3
    assert with_.energy == pytest.approx(without.energy, rel=1e-14)
    assert np.allclose(with_.gradient, without.gradient, rtol=0, atol=1e-12)
    assert np.allclose(with_.hessian.toarray(), without.hessian.toarray(), atol=1e-9)
    assert not np.any(with_.spin_gradient)


def test_step_bound_stops_a_node_at_the_handle_not_behind_the_end():
    x = np.array([[0.0, 0, 0], [0.5, 0, 0], [1.0, 0, 0], [1.3, 0.2, 0.0]])
    s = np.array([0.0, 0.5, 1.0, 3.0])
    e = np.array([[-1.0, 0, 0], [1.0, 0, 0]])
    bw = Barrier(distance=D, width=WIDTH, stiffness=50.0, exclusion=0.3, handles=(0, 2))
    dx = np.zeros_like(x)
    # across the handle's side, 1.3 beyond the end: stopped at distance D
    dx[3] = [0.0, -0.4, 0.0]
    a = step_bound(x, dx, s, bw, fraction=1.0, directions=e)
    assert a == pytest.approx((0.2 - D) / 0.4, rel=1e-12)
    assert step_bound(x, dx, s, bw, fraction=0.8, directions=e) == pytest.approx(0.8 * a)
    # without handles nothing stops it (node 3 passes 0.3 from node 2)
    assert step_bound(x, dx, s, Barrier(distance=D, width=WIDTH, stiffness=50.0,
                                        exclusion=0.3), fraction=1.0) == 1.0
    # across the axis behind the end (0.3 before it): the handle's infinite
    # cylinder would stop it there, the capped handle does not
    x[3] = [0.7, 0.2, 0.0]
    assert step_bound(x, dx, s, bw, fraction=1.0, directions=e) == 1.0
    # into the cap from behind, along the axis: stopped at the end node's sphere
    x[3], dx[3] = [1.0, 0.2, 0.0], [0.0, -0.4, 0.0]
    assert step_bound(x, dx, s, bw, fraction=1.0, directions=e) == pytest.approx(
        (0.2 - D) / 0.4, rel=1e-12)
    x[3], dx[3] = [0.9, 0.0, 0.2], [0.2, 0.0, -0.4]
    a = step_bound(x, dx, s, bw, fraction=1.0, directions=e)
    y = x[3] + a * dx[3] - x[2]
    assert 0 < a < 1 and np.linalg.norm(y - max(y[0], 0) * np.array([1, 0, 0])) \
        == pytest.approx(D, rel=1e-9)


def test_random_moves_never_cross_a_handle():
    rng = np.random.default_rng(2)
    x, s, ends, e = _rod()
    bw = _barrier()
    for _ in range(200):
        dx = rng.normal(scale=0.05, size=x.shape)
        a = step_bound(x, dx, s, bw, fraction=0.9, directions=e)
        for t in np.linspace(0, a, 9):
            assert np.isfinite(barrier_work(x + t * dx, s, bw, hessian=False,
                                            directions=e).energy)


def test_handles_belong_to_open_rods():
    with pytest.raises(ValueError, match="closed rod"):
        Barrier(distance=D, width=WIDTH, stiffness=1.0, exclusion=0.1, period=1.0,
                handles=(0,))
    x, s, ends, e = _rod()
    with pytest.raises(ValueError, match="directions"):
        barrier_work(x, s, _barrier())
    with pytest.raises(ValueError, match="directions"):
        step_bound(x, np.zeros_like(x), s, _barrier())


@pytest.mark.filterwarnings("ignore::skfem_rod.minimize.BarrierResolution")
def test_handles_need_both_ends_rotations_held():
    """A handle turns with its end: an end free to turn about any axis is
    refused by name (the end at s = L of the clamped hairpin; then with
    one component of its rotation held, then all three: accepted)."""
    from skfem_rod.minimize import BarrierStepper
    from skfem_rod.options import split_barrier_options

    from test_barrier_solve import _pressed

    rod, _, _ = _pressed(0.0)
    opts = split_barrier_options(dict(handles=True))
    L = rod.length
    with pytest.raises(ValueError, match=f"end at s = {L:g} turns freely"):
        BarrierStepper(rod, *opts)
    rod.fix_rotation("end", components=(0, 1))
    with pytest.raises(ValueError, match="turns freely"):
        BarrierStepper(rod, *opts)
    rod.fix_rotation("end")
    assert BarrierStepper(rod, *opts).solve.barrier.handles



@pytest.mark.slow
@pytest.mark.parametrize("handles", [False, True])
def test_handles_keep_the_link_where_the_plectoneme_swings_around_an_end(handles):
    """The 100-element barrier plectoneme at 8.625 turns (saved by
    ``benchmarks/plectoneme_state.py 100 138``): its next step, a snap,
    swings the plectoneme around an end without handles -- no strand
    touches another, the link drops by 2 or more -- and keeps the link with
    them
    (the step taken as the solve takes it: secant predictor from the step
    before)."""
    from pathlib import Path

    from helpers import load_bench
    from skfem_rod.minimize import BarrierStepper
    from skfem_rod.options import split_barrier_options
    from skfem_rod.topology import topology

    bp = load_bench("bench_plectoneme")
    d = np.load(Path(__file__).with_name("data") / "plectoneme_swing.npz")
    rod = bp.build(100, 0.0)
    stepper = BarrierStepper(rod, *split_barrier_options(dict(barrier_force=1.0,
                                                              handles=handles)))
    lam1 = float(d["lam1"])
    dlam = lam1 - float(d["lam0"])
    r, R, rep = stepper.solve.step(d["r1"], d["R1"], lam1, dlam, (d["r0"], d["R0"]))
    assert rep.converged, rep.reason
    o = np.argsort(rod.mesh.s_nodes)
    t = topology(r[o], R[o][:, :, 0], t_start=R[o][0][:, 2], t_end=R[o][-1][:, 2])
    link = t.twist - t.closure_twist + t.writhe
    turns = (lam1 + dlam) * bp.TURNS
    assert rep.true_distance >= 2 * bp.RADIUS
    if handles:
        assert link == pytest.approx(turns, abs=1e-6)
    else:
        # swung around an end, once or more (by 2 each time; how often
        # depends on the snap's path: 2 on the code that saved the state,
        # 6 with the shear barrier)
        lost = turns - link
        assert lost >= 2 - 1e-6 and lost == pytest.approx(2 * round(lost / 2), abs=1e-6)


@pytest.mark.slow
def test_the_shear_barrier_keeps_the_twist_from_slipping_in_the_frictional_plectoneme():
    """The 100-element frictional barrier plectoneme (gamma_T = 0.3,
    handles) at 7.656 turns, saved by ``benchmarks/plectoneme_state.py 100
    123 ... 0.3 handles`` on the code before the shear barrier (50354c9):
    its next step, taken without the shear barrier, turned sections 119
    degrees off the centreline near the clamp and lost a turn of twist
    twice (the link by 2); with it the step converges, the link kept."""
    from pathlib import Path

    from helpers import load_bench
    from dataclasses import replace

    from skfem_rod.contact.barrier import SAMPLING
    from skfem_rod.minimize import BarrierStepper
    from skfem_rod.options import split_barrier_options

    bp = load_bench("bench_plectoneme")
    d = np.load(Path(__file__).with_name("data") / "plectoneme_slip.npz")
    rod = bp.build(100, 0.3)
    stepper = BarrierStepper(rod, *split_barrier_options(dict(barrier_force=1.0, handles=True)))
    # the state was saved with the contact distance of then, 2 eps + a^2 /
    # (8 eps) (before the sag of bent strands was allowed for:
    # barrier.SAMPLING): some of its node pairs are closer than today's
    S = stepper.solve
    S.barrier = replace(S.barrier, distance=2 * bp.RADIUS + (S.barrier.distance - 2 * bp.RADIUS)
                        / SAMPLING)
    lam1 = float(d["lam1"])
    assert _link(rod, d["r1"], d["R1"]) == pytest.approx(lam1 * bp.TURNS, abs=1e-6)
    # the step the path takes next: 1/160, twice the last (a cut step);
    # the secant scaled to it
    dlam = 1 / 160
    ratio = dlam / (lam1 - float(d["lam0"]))
    r, R, rep = stepper.solve.step(d["r1"], d["R1"], lam1, dlam, (d["r0"], d["R0"]), 0.0, ratio)
    assert rep.converged, rep.reason
    assert _link(rod, r, R) == pytest.approx((lam1 + dlam) * bp.TURNS, abs=1e-6)
    # no section tilted off the chords to its neighbours beyond the limit
    o = np.argsort(rod.mesh.s_nodes)
    c = np.diff(r[o], axis=0)
    c /= np.linalg.norm(c, axis=1)[:, None]
    d3 = R[o][:, :, 2]
    tilt = np.arccos(np.clip(np.r_[np.einsum("ij,ij->i", d3[:-1], c),
                                   np.einsum("ij,ij->i", d3[1:], c)], -1, 1))
    assert tilt.max() < stepper.solve.shear.limit


def _link(rod, r, R):
    """Twist + writhe of the nodes' ribbon, closed along the end tangents."""
    from skfem_rod.topology import topology
    o = np.argsort(rod.mesh.s_nodes)
    t = topology(r[o], R[o][:, :, 0], t_start=R[o][0][:, 2], t_end=R[o][-1][:, 2])
    return t.twist - t.closure_twist + t.writhe
