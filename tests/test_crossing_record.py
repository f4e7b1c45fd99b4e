"""What a converged step records of its crossing pairs
(:class:`skfem_rod.results.CrossingContact`), and a solve started from a
converged contact state (``Rod.solve(start=result)``), which starts with
its crossing pairs in the balance they were recorded in.

The scene: the figure-eight of tests/test_core.py, its two strands
crossing at 90 degrees between slave points (elements 9 eps long), 3 eps
apart, pressed together at the crossing by opposite point forces: the
crossing pair alone carries the contact.
"""
import numpy as np
import pytest

from skfem_rod import Rod, Section
from skfem_rod.element import shape_functions
from skfem_rod.problem import Problem

from test_core import _figure_eight

EPS = 0.01


def pressed(force, constant=False):
    """The figure-eight pressed at its crossing by ``force`` (a preload
    with ``constant``), crossing pairs on."""
    shape, (s1, s2) = _figure_eight(EPS, 3 * EPS)
    rod = Rod(shape, Section.circle(E=1e7, nu=0.3, radius=EPS), 60)
    rod.clamp("start").clamp("end")
    sn = rod.mesh.s_nodes
    rod.add_force(float(sn[np.argmin(abs(sn - s1))]), [0.0, 0.0, -force], constant=constant)
    rod.add_force(float(sn[np.argmin(abs(sn - s2))]), [0.0, 0.0, force], constant=constant)
    return rod.enable_contact(crossing=True)


@pytest.fixture(scope="module")
def solved():
    rod = pressed(0.3)
    res = rod.solve(2)
    assert res.converged, res.message
    return rod, res


def nodal(mesh, s, vectors):
    """The point vectors ``(k, 3)`` at arclengths ``s`` as nodal forces
    (the P3 shape functions' values), ``(n_dofs,)``."""
    e, xi = mesh.locate(np.asarray(s, float))
    N = shape_functions(xi)[0].T                                  # (k, 4)
    dofs = 6 * mesh.nodes[e][:, :, None] + np.arange(3)           # (k, 4, 3)
    vals = N[:, :, None] * np.asarray(vectors)[:, None, :]
    return np.bincount(dofs.ravel(), weights=vals.ravel(), minlength=mesh.n_dofs)


def assert_balanced(rod, res, force):
    """At every converged step of ``res`` (the pressed scene at ``force``),
    the rod's internal forces less its loads, evaluated without contact,
    are balanced on the free dofs by the recorded contact forces: each
    crossing pair's point force ``f`` along its normal at its two points
    (``+f N`` at ``s``, ``-f N`` at ``s_bar``) and the slave points' line
    forces ``f_N ds`` likewise.  Returns how many steps had slave points in
    contact."""
    bare = pressed(force)
    bare.contact = None
    p = Problem(bare)
    with_slaves = 0
    for st in res.steps[1:]:
        c, cr = st.contact, st.contact.crossing
        assert cr is not None and cr.force.size + c.s.size >= 1
        assert np.all(cr.force > 0)
        f = -p.evaluate(st.r, st.R, st.load_factor, tangent=False).residual
        F = max(cr.force.max(initial=0.0), (c.force * c.weight).max(initial=0.0))
        if c.s.size:
            fw = (c.force * c.weight)[:, None] * c.normal
            f += nodal(rod.mesh, c.s, fw) - nodal(rod.mesh, c.s_bar, fw)
            with_slaves += 1
        if cr.force.size:
            # the crossing pairs carry force: without it the misfit is of
            # the order of the force (spread over an element's four nodes)
            assert np.abs(f[p.free]).max() > 0.2 * cr.force.max()
            f += nodal(rod.mesh, cr.s, cr.force[:, None] * cr.normal) \
                - nodal(rod.mesh, cr.s_bar, cr.force[:, None] * cr.normal)
        assert np.abs(f[p.free]).max() <= 1e-8 * F
    return with_slaves


def test_the_recorded_crossing_forces_are_the_forces_that_balance_the_rod(solved):
    """The recorded forces are the forces that were applied, where and in
    which direction, with their weights (:func:`assert_balanced`): a
    crossing force left out, doubled, or a sign or point swapped leaves a
    misfit of the order of the force itself (measured: 1e-9 of it)."""
    rod, res = solved
    assert assert_balanced(rod, res, 0.3) == 0          # the crossing pair alone


@pytest.mark.slow
def test_recorded_crossing_and_slave_forces_together_balance_the_rod():
    """Pressed harder (force 2, the scene of tests/test_core.py), the
    strands wrap around each other: slave points and two crossing pairs
    share the contact at the last steps, and the record balances the rod at
    every step; a solve started from the last state takes no Uzawa update
    and stays within the contact tolerance of it."""
    rod = pressed(2.0)
    res = rod.solve(4)
    assert res.converged, res.message
    assert assert_balanced(rod, res, 2.0) >= 1
    assert res.steps[-1].contact.crossing.s.size == 2
    # restarted from there (slave points and two crossing pairs): the
    # crossing pairs in balance, the slave points at their Uzawa update
    # (off by d / mu_N each: 0.5 % of the pressing force at the start), no
    # update taken, and the state moves within the contact tolerance
    again = pressed(2.0, constant=True).solve(1, start=res)
    assert again.converged, again.message
    st0, last = again.steps[0], res.steps[-1]
    assert st0.contact.uzawa == 0 and st0.residual_history[0] <= 1e-2 * 2.0
    assert np.abs(st0.r - last.r).max() <= rod.contact.tolerance * EPS
    np.testing.assert_allclose(st0.contact.crossing.force, last.contact.crossing.force,
                               rtol=2e-3)             # measured 8e-4


def test_the_recorded_crossing_pairs_are_consistent(solved):
    """Each recorded pair: its normal a unit vector from its second point to
    its first, its gap ``2 eps + w offset - |r(s) - r(s_bar)|`` within the
    contact tolerance, its weight 1 (the strands cross at about 90 degrees,
    its recorded angle), and ``Result.crossing_points`` the midpoints of its
    two points."""
    rod, res = solved
    tol = rod.contact.tolerance * EPS
    st = res.steps[-1]
    cr = st.contact.crossing
    x, y = res.evaluate(cr.s)["r"], res.evaluate(cr.s_bar)["r"]
    dist = np.linalg.norm(x - y, axis=1)
    np.testing.assert_allclose(cr.normal, (x - y) / dist[:, None], atol=1e-12)
    np.testing.assert_allclose(cr.gap, 2 * EPS + cr.weight * cr.offset - dist, atol=1e-12)
    assert np.all(np.abs(cr.gap) <= tol)
    np.testing.assert_allclose(cr.weight, 1.0)
    assert np.all(cr.angle > np.radians(80))
    np.testing.assert_allclose(res.crossing_points(), 0.5 * (x + y), atol=1e-14)
    assert cr.total_force == pytest.approx(cr.force.sum())
    assert cr.key.shape == (cr.s.size, 5) and np.all(cr.key[:, 4] == -1)


def test_a_solve_started_from_a_converged_contact_state_starts_in_balance(solved):
    """The pressed state, handed to a rod that holds the same forces as
    preloads (so that load factor 0 is that state's problem), is an
    equilibrium from the first iterate: the crossing pair (no slave point is
    in contact here) carries the multiplier that gives its recorded force
    at the recorded state (:func:`skfem_rod.solver.carry_multipliers`), so
    step 0 takes no Uzawa
    update, its residual starts at the tolerance, the state does not move
    and the crossing forces are those recorded.  Before, the crossing pairs
    were not carried (Uzawa started them from zero); carried as ``lambda =
    f`` (the Uzawa update), step 0 started from a residual of 0.12 (40 % of
    the pressing force, ``d / mu`` through the stiff point law) and took 4
    Newton iterations."""
    rod, res = solved
    again = pressed(0.3, constant=True).solve(1, start=res)
    assert again.converged, again.message
    st0, last = again.steps[0], res.steps[-1]
    assert st0.contact.uzawa == 0
    # the pressing force is 0.3: the first iterate is balanced to 1e-8 of it
    assert st0.residual_history[0] <= 1e-8 * 0.3
    assert np.abs(st0.r - last.r).max() <= 1e-10 * EPS
    np.testing.assert_allclose(st0.contact.crossing.force, last.contact.crossing.force,
                               rtol=1e-9)
    np.testing.assert_allclose(st0.contact.crossing.s, last.contact.crossing.s, atol=1e-12)


def test_the_render_marks_the_crossing_pairs(solved, tmp_path):
    """``Result.render`` draws the crossing pairs carrying force as spheres
    of :data:`~skfem_rod.render.CROSSING_COLOR` (named in the legend), where
    the slave points draw none here; asked for no crossing points, none
    (the pixels that differ between the two pictures are pink in the first
    and not in the second)."""
    pytest.importorskip("pyvista")
    import matplotlib.image as mpimg
    from skfem_rod.render import CROSSING_COLOR
    from test_export_render import near
    rod, res = solved
    kw = dict(window_size=(480, 360), contact_radius=0.03, legend=False)
    marked = mpimg.imread(res.render(tmp_path / "x.png", **kw))[..., :3]
    bare = mpimg.imread(res.render(tmp_path / "o.png", crossing_points=np.zeros((0, 3)),
                                   **kw))[..., :3]
    # the stripe shades the tube pinkish here and there: count the pink
    # pixels where the two pictures differ (a sphere about 7 pixels across)
    changed = np.abs(marked - bare).sum(axis=2) > 0.1
    assert (near(marked, CROSSING_COLOR) & changed).sum() > 50
    assert (near(bare, CROSSING_COLOR) & changed).sum() == 0


def test_the_animation_marks_the_crossing_pairs(solved, tmp_path):
    """``render.render_animation`` draws each frame's crossing pairs
    (``crossing_points``, one array per frame) in
    :data:`~skfem_rod.render.CROSSING_COLOR`: the frames of the steps with a
    pair carry pink pixels where the same animation without them has
    none (the GIF palette keeps the colour)."""
    pytest.importorskip("pyvista")
    from PIL import Image
    from skfem_rod.render import CROSSING_COLOR, ROD_COLOR, render_animation
    from test_export_render import near
    rod, res = solved
    confs = [(f["r"], f["R"]) for f in (res.sample(4, k) for k in range(len(res.steps)))]
    xs = [res.crossing_points(k) for k in range(len(res.steps))]
    assert xs[0].size == 0 and all(x.shape == (1, 3) for x in xs[1:])

    def frames(path, **kw):
        # (the d1 stripe in the tube's colour, no axes triad: their shades
        # come near pink)
        render_animation(path, confs, EPS, window_size=(480, 360), hold_last=0, legend=False,
                         contact_radius=0.03, stripe_color=ROD_COLOR, axes=False, **kw)
        im = Image.open(path)
        out = []
        for k in range(im.n_frames):
            im.seek(k)
            out.append(np.asarray(im.convert("RGB"), float) / 255.0)
        return out

    marked = frames(tmp_path / "x.gif", crossing_points=xs)
    bare = frames(tmp_path / "o.gif")
    assert len(marked) == len(bare) == len(res.steps)
    for k, (a, b) in enumerate(zip(marked, bare)):
        changed = np.abs(a - b).sum(axis=2) > 0.1
        pink = (near(a, CROSSING_COLOR) & changed).sum()
        assert (pink > 50) if xs[k].size else pink == 0, k
        assert not near(b, CROSSING_COLOR).any()
    with pytest.raises(ValueError, match="crossing_points has 1 entries"):
        render_animation(tmp_path / "y.gif", confs, EPS, crossing_points=xs[:1])


def test_the_files_carry_the_crossing_forces(solved):
    """The VTU point data ``crossing_force`` holds each pair's point force at
    the samples nearest to its two points, and the JSON summary's step
    figures the number of pairs and their total force."""
    from skfem_rod.scene import step_figures
    rod, res = solved
    cr = res.steps[-1].contact.crossing
    f, data = res.point_data()
    xf = data["crossing_force"]
    assert np.count_nonzero(xf) == 2 * cr.force.size
    np.testing.assert_allclose(np.sort(xf[xf > 0]), np.repeat(np.sort(cr.force), 2))
    near = f["s"][np.flatnonzero(xf)]
    half_spacing = np.diff(rod.mesh.vertices).max() / 16       # 8 samples per element
    assert np.abs(np.sort(near) - np.sort(np.r_[cr.s, cr.s_bar])).max() <= half_spacing + 1e-12
    row = step_figures(res.steps[-1], len(res.steps) - 1)
    assert row["crossing_pairs"] == cr.force.size
    assert row["crossing_force"] == pytest.approx(cr.total_force)


@pytest.mark.parametrize("carried", [False, True])
def test_crossing_pairs_beyond_the_reach_carry_no_force(solved, monkeypatch, carried):
    """The crossing pairs are looked for up to ``Problem.crossing_reach()``,
    the distance at which a pair can carry force at the multipliers and
    offsets of the evaluation (plus a quarter ``eps``), not ``3 eps`` at
    any multiplier: searched up to ``6 eps`` instead, the evaluation finds
    more pairs, and the residual and tangent are the same to round-off,
    at every converged state of the pressed scene, with zero multipliers and
    with those carried from the last step (``lambda = 0.3``)."""
    from skfem_rod.solver import carry_multipliers
    rod, res = solved
    p = Problem(rod)
    if carried:
        carry_multipliers(p, res.steps[-1].contact)
    assert p.crossing_reach() < 3 * EPS
    more = 0
    for st in res.steps:
        ev = p.evaluate(st.r, st.R, st.load_factor)
        with monkeypatch.context() as mp:
            mp.setattr(Problem, "crossing_reach", lambda self: 6 * EPS)
            wide = p.evaluate(st.r, st.R, st.load_factor)
        more += wide.contact.crossing.size - ev.contact.crossing.size
        scale = np.abs(wide.residual).max()
        assert np.abs(ev.residual - wide.residual).max() <= 1e-13 * scale
        assert abs(ev.tangent - wide.tangent).max() <= 1e-13 * abs(wide.tangent).max()
    assert more > 0
