"""Skip what a scene does not need: each test shows that some work is NOT
done (a patched function that must not be called, a call counter, or the
modules loaded in a fresh interpreter).

* contact off: no contact search, no contact assembly, no slave points;
* contact on, friction coefficients zero: no friction code;
* no rendering and no file output unless asked; pyvista and meshio are not
  imported by ``import skfem_rod`` nor by a solve, and a solve works when
  they cannot be imported at all;
* the sparsity pattern, the shape operator, the dof maps, the quadrature
  data and the reference strains are computed once per rod/solve, not per
  Newton iteration or load step;
* the broad phase returns no pair farther apart than its reach (and misses
  none closer).
"""
import inspect
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import scipy.sparse as sp
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod import assembly as assembly_mod
from skfem_rod import mesh as mesh_mod
from skfem_rod import model as model_mod
from skfem_rod import problem as problem_mod
from skfem_rod.contact import assembly as contact_assembly_mod
from skfem_rod.contact import friction as friction_mod
from skfem_rod.contact import search as search_mod

ROOT = Path(__file__).resolve().parents[1]
SEC = Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=0.8, radius=0.02)


def forbid(monkeypatch, module, names=None, why="must not run"):
    """Replace the public functions of ``module`` (or ``names``) by ones
    that raise; returns the names patched."""
    if names is None:
        names = [n for n, f in vars(module).items()
                 if inspect.isfunction(f) and f.__module__ == module.__name__
                 and not n.startswith("__")]

    def make(name):
        def forbidden(*args, **kwargs):
            raise AssertionError(f"{module.__name__}.{name} {why}")
        return forbidden
    for n in names:
        monkeypatch.setattr(module, n, make(n))
    return names


def rollup_rod(n_elements=8):
    rod = Rod(geometry.straight(1.0), SEC, n_elements)
    rod.clamp("start").add_moment("end", [0.0, 0.0, np.pi])
    return rod


def hairpin_scene():
    """scenes/hairpin_contact.toml: the free leg of a hairpin pressed onto the
    clamped one, frictionless self-contact (active at the end)."""
    from skfem_rod import scene as scene_mod
    return scene_mod.load_scene(str(ROOT / "scenes" / "hairpin_contact.toml"))


# ---------------------------------------------------------------------------
def test_contact_off_no_search_no_contact_assembly(monkeypatch):
    forbid(monkeypatch, search_mod, ["search", "slave_points", "project"],
           "ran with contact off")
    forbid(monkeypatch, contact_assembly_mod, ["contact_work"], "ran with contact off")
    rod = rollup_rod()
    res = rod.solve(n_steps=2)
    assert res.converged, res.message
    # and the phase timers of the system never saw contact work
    system = problem_mod.Problem(rod)
    system.evaluate(rod.r0, rod.R0, 1.0)
    assert not any(k.startswith("contact") for k in system.timers)
    assert all(st.contact is None for st in res.steps)


def test_contact_on_without_friction_runs_no_friction_code(monkeypatch):
    """The contract: frictionless contact never calls the friction law (nor
    its assembler, where it exists), so it costs nothing extra."""
    patched = forbid(monkeypatch, friction_mod, why="ran with zero friction coefficients")
    assert {"friction_force", "project_ball", "uzawa_update"} <= set(patched)
    try:
        from skfem_rod.contact import friction_assembly
    except ImportError:
        friction_assembly = None
    if friction_assembly is not None:
        forbid(monkeypatch, friction_assembly, why="ran with zero friction coefficients")
    calls = {"contact_work": 0}
    real = contact_assembly_mod.contact_work

    def counting(*args, **kwargs):
        calls["contact_work"] += 1
        return real(*args, **kwargs)
    monkeypatch.setattr(contact_assembly_mod, "contact_work", counting)
    sc = hairpin_scene()
    assert sc.data["contact"]["enabled"]
    res = sc.solve()
    assert res.converged, res.message
    # contact really was active (the friction code had something to do)
    assert res.steps[-1].contact.force.size > 0
    assert calls["contact_work"] > 0


def test_solve_writes_no_files_and_renders_nothing(monkeypatch, tmp_path):
    from skfem_rod import export as export_mod
    from skfem_rod import render as render_mod
    from skfem_rod import scene as scene_mod
    forbid(monkeypatch, export_mod, why="was called by a solve (no output asked)")
    forbid(monkeypatch, render_mod, why="was called by a solve (no render asked)")
    # neither pyvista nor meshio can be imported: a solve must not need them
    monkeypatch.setitem(sys.modules, "pyvista", None)
    monkeypatch.setitem(sys.modules, "meshio", None)
    monkeypatch.chdir(tmp_path)
    res = rollup_rod().solve(n_steps=2)
    assert res.converged, res.message
    # a scene's solve() writes nothing either (run() writes what [output] asks)
    sc = scene_mod.load_scene(str(ROOT / "scenes" / "rollup.toml"))
    assert sc.output is not None and sc.output["vtu"]       # output is configured ...
    assert sc.solve().converged                              # ... but solve() ignores it
    assert list(tmp_path.iterdir()) == []


def test_pyvista_and_meshio_not_imported_by_import_or_solve():
    code = textwrap.dedent("""
        import sys
        import skfem_rod
        from skfem_rod import Rod, Section, geometry
        heavy = ("pyvista", "meshio", "vtk", "matplotlib")
        print("import:", [m for m in heavy if m in sys.modules])
        rod = Rod(geometry.straight(1.0), Section(EA=1e4, GA1=1e4, GA2=1e4, EI1=1.0, EI2=1.0, GJ=1.0), 4)
        rod.clamp("start").add_moment("end", [0.0, 0.0, 3.0])
        assert rod.solve(n_steps=2).converged
        print("solve:", [m for m in heavy if m in sys.modules])
    """)
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=env, cwd=ROOT, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "import: []" in out.stdout and "solve: []" in out.stdout, out.stdout


def _counters(monkeypatch):
    """Count the set-up work: shape operator computations, sparsity pattern
    builds, mesh/quadrature/dof-map builds, reference strains, fixed-dof
    masks, and the Newton evaluations (iterations) for comparison."""
    n = dict(shape_operator=0, pattern=0, mesh=0, reference_strains=0, fixed_dofs=0,
             evaluate=0)
    real_shape = assembly_mod.shape_operator

    def shape_operator(mesh):
        if getattr(mesh, "_shape_operator", None) is None:
            n["shape_operator"] += 1            # a real computation, not a cache hit
        return real_shape(mesh)
    monkeypatch.setattr(assembly_mod, "shape_operator", shape_operator)
    monkeypatch.setattr(problem_mod, "shape_operator", shape_operator)

    def wrap(owner, name, key):
        real = getattr(owner, name)

        def counted(*args, **kwargs):
            n[key] += 1
            return real(*args, **kwargs)
        monkeypatch.setattr(owner, name, counted)
    wrap(mesh_mod.RodMesh, "_pattern", "pattern")
    wrap(mesh_mod.RodMesh, "__post_init__", "mesh")
    wrap(model_mod, "reference_strains", "reference_strains")
    wrap(model_mod.Rod, "fixed_dofs", "fixed_dofs")
    wrap(problem_mod.Problem, "evaluate", "evaluate")
    return n


@pytest.mark.parametrize("n_steps", [2, 8])
def test_set_up_work_is_done_once_per_solve_not_per_iteration(monkeypatch, n_steps):
    n = _counters(monkeypatch)
    rod = rollup_rod(6)
    built = dict(n)
    # building the rod: one mesh (with its quadrature data and dof maps),
    # one pattern, one reference-strain evaluation; no shape operator yet
    assert built["mesh"] == 1 and built["pattern"] == 1 and built["reference_strains"] == 1
    res = rod.solve(n_steps=n_steps)
    assert res.converged, res.message
    during = {k: n[k] - built[k] for k in n}
    iterations = int(res.iterations.sum())
    assert iterations >= n_steps and during["evaluate"] > iterations
    # many evaluations, but the set-up work happened once (or not at all)
    assert during["shape_operator"] == 1
    assert during["pattern"] == 0 and during["mesh"] == 0
    assert during["reference_strains"] == 0
    assert during["fixed_dofs"] <= 2          # check_constraints + Problem, once each
    # a second solve of the same rod reuses the cached shape operator
    before = n["shape_operator"]
    assert rod.solve(n_steps=1).converged
    assert n["shape_operator"] == before


def test_matrix_assembly_reuses_the_pattern_arrays():
    """Per iteration only the values are scattered: the CSC index arrays of
    the tangent are the precomputed ones (copied, never rebuilt)."""
    rod = rollup_rod(5)
    m = rod.mesh
    K = assembly_mod.internal_work(m, rod.r0, rod.R0, rod.eps0, rod.C).matrix
    assert np.array_equal(K.indices, m._indices) and np.array_equal(K.indptr, m._indptr)
    assert K.nnz == m._nnz


def test_diagonal_added_into_the_assembled_pattern():
    """``RodMesh.add_diagonal`` (the viscous term of proximal and damped
    steps) equals ``K + diag(d)`` entry for entry, keeps the assembled
    pattern and leaves ``K`` as it was."""
    rod = rollup_rod(5)
    m = rod.mesh
    K = assembly_mod.internal_work(m, rod.r0, rod.R0, rod.eps0, rod.C).matrix
    before = K.toarray()
    d = np.random.default_rng(4).uniform(1.0, 2.0, m.n_dofs)
    A = m.add_diagonal(K, d)
    np.testing.assert_array_equal(A.toarray(), before + np.diag(d))
    assert np.array_equal(A.indices, m._indices) and np.array_equal(A.indptr, m._indptr)
    np.testing.assert_array_equal(K.toarray(), before)


@pytest.mark.parametrize("contact", [False, True])
def test_factor_derives_the_pattern_work_once_per_pattern(monkeypatch, contact):
    """``Problem.factor`` keeps what depends on the tangent's sparsity
    pattern and the held dofs alone (held entries, the band ordering with
    contact) while they stay, derives it again when either changes, and
    solves exactly the reduced system every time (against a dense solve of
    the free block, with patterns and masks alternating)."""
    from skfem_rod import problem as problem_mod
    rod = rollup_rod(6)
    if contact:
        rod.enable_contact(radius=0.005)
    system = problem_mod.Problem(rod)
    derived = []
    orig = problem_mod.FactorPattern._derive
    monkeypatch.setattr(problem_mod.FactorPattern, "_derive",
                        lambda self, K: (derived.append(1), orig(self, K)))
    ev = system.evaluate(rod.r0, rod.R0, 0.0)
    n = rod.mesh.n_dofs
    K1 = ev.tangent.tocsc()
    # another pattern: the first and last free nodes coupled (as a new contact pair)
    a, b = 6 * 1, n - 6
    C = sp.coo_matrix(([1.0, 1.0, -1.0, -1.0], ([a, b, a, b], [a, b, b, a])), shape=(n, n))
    K2 = (K1 + 1e3 * C).tocsc()
    fixed2 = system.fixed.copy()
    fixed2[6 * 2:6 * 2 + 3] = True
    rng = np.random.default_rng(3)
    calls = [(K1, None), (K1, None), (K2, None), (K2, None), (K1, fixed2), (K1, None),
             (K1, fixed2), (K1, None)]
    for K, fixed in calls:
        held = system.fixed if fixed is None else fixed
        rhs = rng.standard_normal(n)
        x = system.factor(K, fixed)(rhs)
        f = ~held
        # the reduced system solved to round-off: its backward error (the
        # normwise residual, independent of the conditioning: the 6-element
        # roll-up's free block has a condition number of 1.3e7, so the
        # entries of the solution itself agree with a dense solve to 1e-9 on
        # one machine and to 3e-9 on another; backward errors measured: 4e-17
        # and below)
        Kf = K.toarray()[np.ix_(f, f)]
        norm = lambda a: np.linalg.norm(a, np.inf)                   # noqa: E731
        backward = norm(Kf @ x[f] - rhs[f]) / (norm(Kf) * norm(x[f]) + norm(rhs[f]))
        assert backward < 1e-14, backward
        assert not np.any(x[held])
        K.data[:] = K.data * (1.0 + 1e-3 * rng.standard_normal(K.nnz))   # new values
    # derived at the 1st, 3rd (pattern), 5th (another mask: its own) and 6th
    # (back to the supports' mask, which last saw K2) calls only: masks that
    # alternate (Newton and its position correction) keep theirs
    assert len(derived) == 4


@pytest.mark.parametrize("diagonal", [0.0, 1e-9])
def test_band_factor_pivots_off_a_vanishing_diagonal(diagonal):
    """The band-ordered factorization (contact on) keeps diagonal pivots
    only above ``BAND_PIVOT_THRESHOLD`` of their column: an indefinite
    tangent whose diagonal vanishes at a free dof in the band order (a
    saddle-point block, as a contact pair on a soft mode gives) is still
    solved to round-off (without pivoting the block's two unknowns, a
    well-conditioned 2x2 system, lose half their digits or more)."""
    from skfem_rod import problem as problem_mod
    rod = rollup_rod(6)
    rod.enable_contact(radius=0.005)
    system = problem_mod.Problem(rod)
    K = system.evaluate(rod.r0, rod.R0, 0.0).tangent.tolil()
    free = np.flatnonzero(system.free)
    a, b = free[0], free[1]                  # x and y of the first free node
    scale = abs(K[a, a])
    # the 2x2 block [[d, s], [s, d]] with d ~ 0, cut from the rest: whichever
    # of a, b comes first in the band order meets the pivot d (stable only
    # with a row swap)
    for i in (a, b):
        K[i, :] = 0.0
        K[:, i] = 0.0
    K[a, a] = K[b, b] = diagonal * scale
    K[a, b] = K[b, a] = scale
    K = K.tocsc()
    rng = np.random.default_rng(5)
    rhs = rng.standard_normal(K.shape[0])
    x = system.factor(K)(rhs)
    assert np.all(np.isfinite(x))
    block = scale * np.array([[diagonal, 1.0], [1.0, diagonal]])    # cond ~ 1
    np.testing.assert_allclose(x[[a, b]], np.linalg.solve(block, rhs[[a, b]]), rtol=1e-12)
    f = system.free
    A = K.toarray()[np.ix_(f, f)]
    np.testing.assert_allclose(A @ x[f], rhs[f], atol=1e-9 * np.abs(rhs).max())


@pytest.mark.parametrize("seed", [0, 1])
def test_broad_phase_returns_only_pairs_within_reach(seed):
    """A randomly (smoothly) perturbed coil: every returned pair is closer than the
    reach, and no slave whose (densely sampled) closest admissible master
    point is clearly within reach is missed."""
    rng = np.random.default_rng(seed)
    eps = 0.01
    rod = Rod(geometry.helix(radius=0.1, pitch=2.5 * eps, turns=3),
              Section(EA=1, GA1=1, GA2=1, EI1=1, EI2=1, GJ=1, radius=eps), 60)
    # a smooth random perturbation (random phases and directions) of the coil
    s = rod.mesh.s_nodes[:, None]
    k = 2 * np.pi * rng.uniform(2.0, 5.0, 3) / rod.length
    r = rod.r0 + 0.3 * eps * np.sin(k * s + rng.uniform(0, 2 * np.pi, 3))
    sl = search_mod.slave_points(rod.mesh, 3)
    exclusion = np.pi * eps
    # brute force: dense samples of the centreline
    s_dense = np.linspace(0.0, rod.length, 12001)
    e, xi = rod.mesh.locate(s_dense)
    from skfem_rod.element import shape_functions
    Nd = shape_functions(xi)[0]                                   # (4, m)
    y = np.einsum("Im,mIc->mc", Nd, r[rod.mesh.nodes[e]])
    x = np.einsum("qI,eIc->eqc", sl.N, r[rod.mesh.nodes]).reshape(-1, 3)
    s_sl = sl.s.ravel()
    dist = np.linalg.norm(x[:, None, :] - y[None, :, :], axis=2)
    dist[np.abs(s_dense[None, :] - s_sl[:, None]) < exclusion] = np.inf
    closest = dist.min(axis=1)
    v = rod.mesh.vertices
    admissible = int(np.sum((v[None, :-1] <= s_sl[:, None] - exclusion)
                            | (v[None, 1:] >= s_sl[:, None] + exclusion)))
    previous = 0
    for reach in (2.8 * eps, 4 * eps, 6 * eps):
        pairs = search_mod.search(rod.mesh, r, sl, reach, exclusion)
        assert pairs.size > 0
        assert np.all(pairs.distance < reach)
        assert np.all(np.abs(pairs.s_bar - pairs.s) >= exclusion - 1e-12)
        # the projection is at least as close as the dense sampling finds
        assert np.all(pairs.distance <= closest[pairs.slave] + 1e-9)
        # none missed: slaves clearly within reach are all found
        must = np.flatnonzero(closest < 0.98 * reach)
        assert set(must.tolist()) <= set(pairs.slave.tolist())
        # the broad phase prunes: fewer candidates than the admissible
        # slave/element pairs, and not more for a smaller reach
        assert pairs.n_candidates < 0.5 * admissible
        assert pairs.n_candidates >= previous
        previous = pairs.n_candidates
