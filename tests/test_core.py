"""The solver core (problem.py, newton.py, augmented.py): one problem object,
one Newton, one augmented-Lagrangian loop used by every loop.

* the house: no module of the package imports another's private names, no
  import circle;
* the configuration update and its inverse;
* arc-length continuation with friction agrees with load stepping (it had
  its own Newton and Uzawa loops without the friction update: 3.7x the
  dissipation, reported converged);
* stability paths with contact refuse with a clear error;
* convergence is decided on the free dofs: a load on a supported dof
  (taken up by the support) cannot make a solve "converge";
* a step never loses imposed turns (the element chart's edge);
* Newton on slender rods: the README roll-up at radii 0.002-0.015 and the
  45-degree bend at slenderness 1e4 in at most 8 iterations per step, no
  step cut (position correction, newton.position_correction);
* step 0 with contact and preloads runs the full augmented-Lagrangian
  solve and keeps its multipliers.
"""
import ast
import pathlib

import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.problem import Problem
from skfem_rod.rotations import is_rotation

from helpers import load_demo

PKG = pathlib.Path(__file__).resolve().parents[1] / "skfem_rod"


def _imports():
    """Per module of the package: (private names imported from another
    module of the package, the package modules it imports)."""
    private, graph = [], {}
    for f in sorted(PKG.rglob("*.py")):
        rel = f.relative_to(PKG.parent).with_suffix("")
        mod = ".".join(rel.parts).removesuffix(".__init__")
        deps = set()
        for node in ast.walk(ast.parse(f.read_text())):
            if not (isinstance(node, ast.ImportFrom) and node.level):
                continue
            parts = list(rel.parts[:-1])
            base = parts[:len(parts) - (node.level - 1)] if node.level > 1 else parts
            target = ".".join(base + ([node.module] if node.module else []))
            for a in node.names:
                if a.name.startswith("_") and not a.name.startswith("__"):
                    private.append(f"{rel}: from {target} import {a.name}")
                sub = f"{target}.{a.name}"
                deps.add(sub if (PKG.parent / sub.replace(".", "/")).with_suffix(".py").exists()
                         else target)
        graph[mod] = {d.removesuffix(".__init__") for d in deps} - {mod}
    return private, graph


def test_no_private_names_across_modules():
    private, _ = _imports()
    assert private == []


def test_no_import_circle_in_the_package():
    """Depth-first search for a cycle among the package's modules (the
    package ``__init__`` excluded: it only re-exports)."""
    _, graph = _imports()
    graph = {m: {d for d in deps if d != "skfem_rod"} for m, deps in graph.items()
             if m != "skfem_rod"}
    cycles = []
    state = {}

    def visit(m, stack):
        state[m] = 1
        for d in sorted(graph.get(m, ())):
            if state.get(d) == 1:
                cycles.append(stack[stack.index(d):] + [d])
            elif d in graph and not state.get(d):
                visit(d, stack + [d])
        state[m] = 2

    for m in sorted(graph):
        if not state.get(m):
            visit(m, [m])
    assert cycles == []


def test_update_and_increment_are_inverse_in_any_support_basis():
    rng = np.random.default_rng(3)
    rod = Rod(geometry.helix(0.2, 0.1, 1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
    Q = np.linalg.qr(rng.standard_normal((3, 3)))[0]
    Q *= np.linalg.det(Q)
    rod.clamp("start").support_basis("end", Q).pin("end", components=(0,))
    p = Problem(rod)
    dy = 0.3 * rng.standard_normal(rod.mesh.n_dofs)
    dy.reshape(-1, 6)[:, 3:] *= 0.5
    r, R = p.update(rod.r0, rod.R0, dy)
    assert np.all(is_rotation(R))
    np.testing.assert_allclose(p.increment(r, R, rod.r0, rod.R0), dy, atol=1e-12)


@pytest.mark.slow
def test_arclength_with_friction_agrees_with_load_stepping():
    """Rotational-friction scene (24 elements): the continuation runs the
    same augmented-Lagrangian loop with the friction update and measures
    slips from the last converged point, so its dissipation, transmitted
    torque and slip states agree with load stepping at load factor 1 (the
    steps differ: continuation lands at 0.25, 0.54, 0.96, 1)."""
    rf = load_demo("rotational_friction")
    rod, s_cut = rf.build(n_elements=24)
    a = rod.solve(4)
    b = rod.solve(4, method="arclength")
    assert a.converged and b.converged, (a.message, b.message)
    assert b.steps[-1].load_factor == 1.0
    ra, rb = rf.measure(a, s_cut, rf.EPS), rf.measure(b, s_cut, rf.EPS)
    da = sum(r["dissipation"] for r in ra)
    db = sum(r["dissipation"] for r in rb)
    assert da > 0 and abs(db - da) <= 1e-3 * da
    assert abs(rb[-1]["transmitted"] - ra[-1]["transmitted"]) <= 1e-3 * abs(ra[-1]["transmitted"])
    assert rb[-1]["stick"] == ra[-1]["stick"] == 0        # all sliding at the end
    # every continuation point is an Uzawa-converged contact state
    assert all(st.contact.uzawa_converged for st in b.steps[1:])


@pytest.mark.slow
def test_arclength_with_friction_on_the_plectoneme_agrees_then_refuses_the_turn_back():
    """Plectoneme-friction scene (16 elements, 1.5 turns, gamma_T = 0.3):
    up to the limit point of the twisted rod the continuation and load
    stepping give the same states; at the limit point (the loading snaps
    into a loop there) the continuation stops with the message instead of
    following the unstable branch back, where friction would dissipate along
    a process no loading performs.  Frictionless, it passes the limit point."""
    tw = load_demo("twisted_rod")

    def build(gamma_T):
        rod = tw.build(5.0, 16, 0.1, 1.5, 0.01, 0.01)
        rod.contact.gamma_T = gamma_T
        return rod

    b = build(0.3).solve(6, method="arclength", max_steps=40)
    assert not b.converged
    assert "limit point" in b.message and "snap='relax'" in b.message
    lam_b = np.array([st.load_factor for st in b.steps])
    assert np.all(np.diff(lam_b) > 0)           # nothing recorded past the turn
    assert 0.6 < lam_b[-1] < 0.75               # the limit point (0.716 turns x 1.5)
    # load stepping through the continuation's first load factors
    a = build(0.3).solve(3, path=lam_b[:4])
    assert a.converged and len(a.steps) == 4
    for k in range(1, 4):
        assert a.steps[k].load_factor == pytest.approx(lam_b[k], abs=1e-12)
        np.testing.assert_allclose(a.steps[k].r, b.steps[k].r, atol=1e-8 * 5.0)
        np.testing.assert_allclose(a.steps[k].R, b.steps[k].R, atol=1e-8)
    c = build(0.0).solve(6, method="arclength", max_steps=24)
    lam_c = np.array([st.load_factor for st in c.steps])
    assert np.any(np.diff(lam_c) < 0)           # frictionless: on along the turned path


def _hairpin_rod(n=24):
    sec = Section.circle(E=1e7, nu=0.3, radius=0.01)
    x = np.linspace(0.6, 0.0, 40, endpoint=False)
    th = np.linspace(0.0, np.pi, 30, endpoint=False)
    pts = np.concatenate([np.c_[x, 0 * x, 0 * x],
                          np.c_[-0.03 * np.sin(th), 0.03 * (1 - np.cos(th)), 0 * th],
                          np.c_[x[::-1], 0.06 + 0 * x, 0 * x]])
    return Rod(geometry.polyline(pts), sec, n)


def test_stability_paths_with_contact_refuse_with_a_clear_error():
    from skfem_rod.continuation import follow
    from skfem_rod.stability import EquilibriumPath, lowest_eigenvalues
    rod = _hairpin_rod().clamp("start").add_force("end", [0.0, -0.1, 0.0])
    rod.enable_contact()
    with pytest.raises(NotImplementedError, match="stability along a path with self-contact"):
        follow(rod, stability=True)
    with pytest.raises(NotImplementedError, match="self-contact"):
        EquilibriumPath(rod)
    with pytest.raises(NotImplementedError, match="self-contact"):
        lowest_eigenvalues(rod, rod.r0, rod.R0, 0.0)


def test_a_load_on_a_supported_dof_does_not_decide_convergence():
    """A 1e9 force on the clamp is taken up by the clamp; it must not make
    the residual of the free dofs look small (it made the solve converge in
    0 iterations with the 0.05 tip load ignored)."""
    def tip(extra):
        rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 8)
        rod.clamp("start").add_force("end", [0.0, 0.05, 0.0])
        if extra:
            rod.add_force("start", [0.0, 1e9, 0.0])
        res = rod.solve(2)
        assert res.converged, res.message
        return res.position(1.0), res
    ref, _ = tip(False)
    got, res = tip(True)
    assert np.abs(got - ref).max() < 1e-9
    assert min(st.iterations for st in res.steps[1:]) >= 2
    # the clamp's reaction carries the extra load
    assert abs(res.reaction("start")[0][1] + 1e9 + 0.05) < 1e-3


def test_non_finite_reactions_are_never_converged():
    """Two 1e308 forces on the clamp overflow to an infinite load on a held
    dof: it stored a reaction of -inf with converged=True.  Now the step
    with a non-finite force fails, and every kept step has finite
    reactions."""
    rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
    rod.clamp("start").add_force("end", [0.0, 0.01, 0.0])
    rod.add_force("start", [1e308, 1e308, 0.0])
    rod.add_force("start", [1e308, 1e308, 0.0])
    with np.errstate(over="ignore", invalid="ignore"):
        res = rod.solve(1)
    assert not res.converged and "non-finite" in res.message
    for k in range(len(res.steps)):
        f, m = res.reaction("start", k)
        assert np.all(np.isfinite(f)) and np.all(np.isfinite(m))


@pytest.mark.slow
def test_relax_never_gives_up_imposed_turns():
    """20 turns on 8 elements is more twist per element than the element
    chart holds: the solve must stop with the message, not relax into 5
    turns and call it converged (issue: end moment 1.90 instead of 7.59).
    On 48 elements it holds all 20 turns: end moment GJ 40 pi / L."""
    def twisted(n):
        return (Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), n)
                .clamp("start").pin("end").prescribe_rotation("end", [40 * np.pi, 0.0, 0.0]))
    rod = twisted(8)
    res = rod.solve(1, snap="relax", max_flow_steps=200)
    assert not res.converged
    assert "stopped at load factor" in res.message
    # every kept step holds its imposed twist: end moment GJ phi / L
    GJ = rod.section.GJ
    for k, st in enumerate(res.steps):
        M = res.reaction("end", k)[1][0]
        assert abs(abs(M) - GJ * 40 * np.pi * st.load_factor) <= 1e-6 * GJ * 40 * np.pi
    rod = twisted(48)
    res = rod.solve(1, snap="relax")
    assert res.converged, res.message
    assert abs(res.topology().twist - 20.0) < 1e-9
    assert abs(abs(res.reaction("end")[1][0]) - GJ * 40 * np.pi) < 1e-6 * GJ * 40 * np.pi


@pytest.mark.parametrize("radius", [0.002, 0.005, 0.008, 0.01, 0.015])
def test_readme_rollup_in_few_newton_iterations(radius):
    """The README's roll-up: 4 steps of pi/2 at the tip each.  Plain Newton
    took 23 iterations per step at radius 0.01 and cut steps at the other
    radii; with the position correction at most 8 (measured: 3)."""
    rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=radius), 16)
    rod.clamp("start").add_moment("end", [0.0, 0.0, 2 * np.pi * rod.section.EI2])
    res = rod.solve(n_steps=4)
    assert res.converged, res.message
    assert len(res.steps) == 5 and res.log == []               # no cut step
    assert max(st.iterations for st in res.steps) <= 8
    assert np.abs(res.position(1.0)).max() < 1e-9             # closed circle


def test_slender_45_degree_bend_in_few_newton_iterations():
    """Bathe-Bolourchi bend (arc radius 100, 45 degrees) with a solid
    circle of slenderness L / radius = 1e4, tip load scaled with EI so that
    the shape is the published one at 600: 4 steps, at most 8 iterations
    each (plain Newton: 28-36 iterations with cut steps)."""
    Rb, L = 100.0, 100.0 * np.pi / 4
    rad = L / 1e4
    E, G = 1e7, 5e6
    A, I = np.pi * rad**2, np.pi * rad**4 / 4
    sec = Section(EA=E * A, GA1=G * A, GA2=G * A, EI1=E * I, EI2=E * I, GJ=G * 2 * I)
    rod = Rod(geometry.arc(Rb, np.pi / 4, start=(0.0, 0.0, 0.0)), sec, 8).clamp("start")
    rod.add_force("end", [0.0, 0.0, 600.0 * E * I / (1e7 / 12)])
    res = rod.solve(4)
    assert res.converged, res.message
    assert len(res.steps) == 5 and res.log == []
    assert max(st.iterations for st in res.steps) <= 8
    tip = res.position(L) / Rb
    # the published tip (Simo & Vu-Quoc 1986, 8 elements): (15.79, 47.23, 53.37),
    # here with the arc starting along x (first two components swapped)
    assert np.abs(tip - [0.4723, 0.1579, 0.5337]).max() < 1.5e-3


def test_step_zero_with_contact_and_preloads_solves_contact_in_full():
    """A hairpin whose upper leg is pressed onto the lower one by a
    constant preload: step 0 (load factor 0) carries the preload, so it is a
    contact solve with Uzawa to the tolerance; the multipliers it converged
    to are kept, so the next (tiny) step needs no Uzawa update."""
    rod = _hairpin_rod(24).clamp("start").clamp("end")
    s = rod.mesh.s_nodes
    mid = float(s[np.argmin(np.abs(s - 0.85 * rod.length))])
    rod.add_force(mid, [0.0, -15.0, 0.0], constant=True)
    rod.enable_contact()
    c = rod.contact
    res = rod.solve(1, path=[0.0, 1e-9])
    assert res.converged, res.message
    st0 = res.steps[0].contact
    assert st0.uzawa >= 1 and st0.uzawa_converged
    assert st0.penetration <= c.tolerance * c.radius
    assert st0.force.size > 0
    assert res.steps[1].contact.uzawa == 0


def _docs_table(table, heading=None):
    """``(key, default cell)`` rows of docs/scenes.md's ``[table]`` table
    (the one under ``heading``); asserts that no key has two rows."""
    import re
    text = (PKG.parent / "docs" / "scenes.md").read_text()
    block = text.split(heading or f"### `[{table}]`", 1)[1].split("\n#", 1)[0]
    rows = re.findall(r"^\| `(\w+)` \| [^|]+ \| ([^|]+) \|", block, flags=re.M)
    names = [n for n, _ in rows]
    assert len(names) == len(set(names)), f"duplicate rows in [{table}]"
    return rows


def _docs_value(cell):
    """The default a docs table's cell states (None: in words)."""
    c = cell.strip().strip("`").strip()
    if c in ("true", "false"):
        return c == "true"
    if c.startswith('"'):
        return c.strip('"')
    try:
        return float(eval(c, {"pi": np.pi}))      # numbers like 1e-10, pi / 2
    except (NameError, SyntaxError):
        return None


def _check_defaults(rows, specs):
    defaults = dict(rows)
    for name, (spec, default) in specs.items():
        got = _docs_value(defaults[name])
        assert got == default or (isinstance(default, float) and np.isclose(got, default)), name


def test_docs_solver_table_matches_the_option_specs():
    """docs/scenes.md's [solver] table has one row per key of the scene's
    [solver] table with method "newton" or "arclength" (built from
    SolverOptions' specs), each with its default: the docs cannot drift from
    the one place options are checked."""
    from skfem_rod import scene
    from skfem_rod.options import option_specs
    rows = _docs_table("solver")
    assert set(n for n, _ in rows) == (set(scene.SOLVER_COMMON) | set(scene.SOLVER_METHODS[
        "newton"]) | set(scene.SOLVER_METHODS["arclength"]))
    _check_defaults(rows, option_specs())


def test_docs_barrier_table_matches_the_option_specs():
    """The table of [solver] with method = "barrier" has one row per key the
    method takes besides n_steps, path and method, with its default (the
    barrier's force, computed when absent, in words)."""
    from skfem_rod import scene
    from skfem_rod.options import barrier_specs
    rows = _docs_table("solver", '#### `[solver]` with `method = "barrier"`')
    assert set(n for n, _ in rows) == set(barrier_specs()) == set(
        scene.SOLVER_METHODS["barrier"])
    _check_defaults(rows, barrier_specs())


@pytest.mark.parametrize("curve", ["elements", "smooth"])
def test_unloaded_closed_ring_with_contact_stays_put(curve):
    """The exclusion of contact pairs is periodic on a closed rod: an
    unloaded ring gets no contact across the closure point (it got f_N =
    4.6e4 there and moved 29.6 eps, reported converged); on the smooth
    contact curve too (its tangent is shared across the closure vertex)."""
    eps = 0.02
    sec = Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=0.8, radius=eps)
    rod = Rod(geometry.ring(0.3), sec, 24)
    rod.pin(0.0).fix_rotation(0.0)
    rod.enable_contact(curve=curve)
    res = rod.solve(2)
    assert res.converged, res.message
    for st in res.steps:
        assert st.contact.force.size == 0
        assert np.abs(st.r - rod.r0).max() < 1e-12 * eps


def _figure_eight(eps, sep, flatten=1.0):
    """A figure-eight (lemniscate of Gerono, x = sin t, y = sin t cos t)
    whose two strands cross at 90 degrees at the origin, ``sep`` apart in z;
    the arclengths of the two crossing points.  ``flatten`` scales y: the
    strands cross at ``2 atan(flatten)``."""
    t = np.linspace(-np.pi / 2 + 0.4, 3 * np.pi / 2 - 0.4, 20001)
    p = np.c_[np.sin(t), flatten * np.sin(t) * np.cos(t), 0.5 * sep * np.cos(t)]
    s = np.r_[0, np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))]

    def r(q):
        q = np.clip(q, 0, s[-1])
        return np.c_[[np.interp(q, s, p[:, k]) for k in range(3)]].T
    return geometry.curve(r, s[-1], ds=1e-4), np.interp([0.0, np.pi], t, s)


def pressed_figure_eight(eps, crossing):
    """The figure-eight above, strands 3 ``eps`` apart, 60 elements (9
    ``eps`` long), both ends clamped, pressed together at the crossing by
    opposite point forces of 2 (load factor 1), contact on."""
    shape, (s1, s2) = _figure_eight(eps, 3 * eps)
    rod = Rod(shape, Section.circle(E=1e7, nu=0.3, radius=eps), 60)
    rod.clamp("start").clamp("end")
    sn = rod.mesh.s_nodes
    rod.add_force(float(sn[np.argmin(abs(sn - s1))]), [0.0, 0.0, -2.0])
    rod.add_force(float(sn[np.argmin(abs(sn - s2))]), [0.0, 0.0, 2.0])
    rod.enable_contact(crossing=crossing)
    return rod


@pytest.mark.slow
@pytest.mark.parametrize("crossing", [False, True])
def test_crossing_strands_never_converge_through_each_other(crossing):
    """Two strands of a figure-eight crossing at 90 degrees, elements 9 eps
    long, pressed together by opposite point forces: the slave points (Gauss
    points) see nothing of the crossing, which lies between them.  Every
    kept step records its true smallest distance (closest points, both
    parameters free): without crossing contact the solve stops with the
    message where the strands overlap by more than OVERLAP_FAIL, instead of
    pressing them through each other; with it the crossing pair holds them
    apart to the tolerance."""
    from skfem_rod.augmented import OVERLAP_FAIL
    from skfem_rod.contact.crossing import min_distance
    eps = 0.01
    rod = pressed_figure_eight(eps, crossing)
    tol = rod.contact.tolerance * eps
    res = rod.solve(4)
    assert len(res.steps) > 1
    for st in res.steps:
        md = min_distance(rod.mesh, st.r, eps, rod.contact.exclusion)
        # with crossing pairs the true distance is held to the tolerance;
        # without, a step whose strands overlap by more than OVERLAP_FAIL is
        # refused (the overlap grows to 0.9 eps when nothing holds it)
        assert md.penetration(eps) <= (tol if crossing else OVERLAP_FAIL * eps)
        assert st.contact.min_distance == pytest.approx(md.distance, abs=1e-12)
    if not crossing:
        assert not res.converged
        assert "overlap" in res.message and "crossing contact" in res.message
    else:
        # far beyond where the other stops and beyond 0.22, where pairs keyed
        # by element pair stalled (the minimum crossed a node and lost its
        # multiplier); it ends near 0.72.  The states past load factor 0.15
        # are saddles (the pressed strands roll off each other: next test)
        assert res.steps[-1].load_factor > 0.7


@pytest.mark.slow
def test_pressed_figure_eight_rolls_off_onto_stable_states_to_full_load():
    """The figure-eight above (benchmarks/bench_figure_eight.py), pressed by
    its point forces.  Load stepping alone follows the pressed state, which
    is a saddle from load factor 0.15 on (lowest eigenvalue of the tangent
    negative; the onset is the same at 60 and 120 elements): the two
    strands, bent into opposite tents by the forces, sit tip on tip.  With
    ``snap="relax", stability=True`` the solve leaves it along its unstable
    mode: the strands roll off each other, the pushed-down point ends far
    below the pushed-up one, and every recorded state to load factor 1 is
    stable, an equilibrium polished by Newton, with the strands touching
    and apart by their true distance to the contact tolerance."""
    from helpers import load_bench
    bench = load_bench("bench_figure_eight")
    eps = bench.EPS
    # the pressed state of plain load stepping: stable at 0.1, a saddle at 0.2
    _, res, rows, _, _ = bench.run(2, path=[0.0, 0.2], snap="cut")
    assert res.converged, res.message
    at = {round(r["lam"], 9): r for r in rows}
    assert at[0.1]["eig"] > 0 > at[0.2]["eig"]
    assert at[0.2]["height"] > 0                      # still pressed tip on tip
    # relaxed off the saddles to full load
    rod, res, rows, _, caught = bench.run(5)
    assert res.converged, res.message
    assert not caught, caught                         # no Relaxed/ContactShortfall
    tol = rod.contact.tolerance * eps
    for r in rows:
        assert r["eig"] > 0
        assert r["relaxed"] is None
        assert r["penetration"] <= tol
    assert sum(r["flow"] for r in rows) > 0
    assert rows[-1]["height"] < -100 * eps
    assert rows[-1]["distance"] <= 2 * eps * (1 + 1e-3)   # still in contact


def test_docs_contact_table_matches_the_contact_specs():
    """docs/scenes.md's [contact] table: one row per key of the scene's
    [contact] table (built from ContactOptions' specs, as the API checks
    them), no duplicates (two rows had drifted in twice), and the defaults
    of the options that have a fixed one."""
    from dataclasses import MISSING

    from skfem_rod import scene
    from skfem_rod.contact import ContactOptions
    from skfem_rod.options import option_specs
    rows = _docs_table("contact")
    assert set(n for n, _ in rows) == set(scene.CONTACT)
    defaults = dict(rows)
    for name, (spec, default) in option_specs(ContactOptions).items():
        cell = defaults[name].strip().strip("`").strip()
        if default is None or default is MISSING:
            continue                                   # derived from other values
        if spec.kind == "boolean":
            assert (cell == "true") == default, name
        elif spec.kind == "choice":
            assert cell.strip('"') == default, name
        elif name == "crossing_angle":
            assert cell == "15 degrees" and default == pytest.approx(np.radians(15.0))
        else:
            assert float(cell) == default, name
    # the scene and the API refuse the same values with the same bounds
    for name, (spec, default) in option_specs(ContactOptions).items():
        if spec.kind in ("number", "integer") and spec.lo is not None:
            bad = spec.lo - 1 if spec.kind == "integer" or not spec.lo_open else spec.lo
            args = dict(radius=0.1, penalty=1e-3, exclusion=0.3)
            args[name] = type(default)(bad) if isinstance(default, int) else float(bad)
            with pytest.raises(ValueError, match=f"contact {name} must be"):
                ContactOptions(**args)
            with pytest.raises(Exception):               # the scene validator's refusal
                scene.CONTACT[name].check(args[name])
            scene.CONTACT[name].check(default if default not in (None, MISSING) else 1.0)


def test_relaxed_state_without_polish_is_reported(monkeypatch):
    """A step that ends on the gradient flow's state because Newton's
    polish did not converge from it (a very soft mode: the localized loop of
    tests/test_writhing.py) is kept, but says so: its residual relative to
    the force scale on the Step, a Result.log line and a RelaxedShortfall
    warning; where the polish converges nothing is reported."""
    import warnings
    from skfem_rod import newton as newton_module, relax
    from skfem_rod.problem import Report
    from skfem_rod.solver import RelaxedShortfall

    plain = newton_module.newton

    def static_fails(problem, r, R, lam, opts, prescribed=None, border=None):
        out = plain(problem, r, R, lam, opts, prescribed=prescribed, border=border)
        if problem.viscous is None and lam > 0:   # a load step, not a proximal step
            out[3].converged = False
        return out

    def cantilever():
        return (Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 6)
                .clamp("start").add_force("end", [0.0, 2.0, 0.0]))

    # every load step's Newton "fails": the flow relaxes it, the polish converges
    monkeypatch.setattr(newton_module, "newton", static_fails)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RelaxedShortfall)
        res = cantilever().solve(2, snap="relax")
    assert res.converged, res.message
    assert all(st.flow_steps > 0 and st.relaxed_residual is None for st in res.steps[1:])
    # the Levenberg-Marquardt steps find no descent, so proximal steps take
    # over, and their polish fails too (Newton and its proximal steps): the
    # flow's state is kept and reported
    def polish_fails(problem, W, c, r, R, lam, opts, prescribed=None):
        out = plain(problem, r, R, lam, opts, prescribed=prescribed)
        out[3].converged = False
        return out

    def no_descent(self, r, R, lam, opts, prescribed=None):
        return r, R, lam, Report(False, reason="no descent (test)")
    monkeypatch.setattr(relax, "polish", polish_fails)
    monkeypatch.setattr(relax.GradientFlow, "linearized", no_descent)
    with pytest.warns(RelaxedShortfall, match="gradient flow's state"):
        res = cantilever().solve(2, snap="relax")
    assert res.converged, res.message
    for st in res.steps[1:]:
        assert 1e-14 < st.relaxed_residual < 1e-6       # the flow stopped near 1e-8
    assert sum("Newton's polish did not converge" in line for line in res.log) == 2
    assert res.steps[-1].flow_steps > 0
