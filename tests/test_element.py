"""Tests of the nodal cubic Lagrange line element :mod:`skfem_rod.element`."""
import numpy as np
import pytest
from skfem import (Basis, BilinearForm, ElementLinePp, Functional, LinearForm,
                   MeshLine, asm, condense, solve)
from skfem.helpers import dot, grad

from skfem_rod.element import (NODE_XI, ORDER_BY_POSITION, ElementLineP3,
                               shape_functions)

XI = np.linspace(-0.25, 1.25, 301)   # includes points outside [0, 1]
EPS = np.finfo(float).eps


# --------------------------------------------------------------------------
# shape functions on the reference element
# --------------------------------------------------------------------------

def test_node_tables():
    np.testing.assert_array_equal(NODE_XI, [0.0, 1.0, 1 / 3, 2 / 3])
    assert np.all(np.diff(NODE_XI[ORDER_BY_POSITION]) > 0)
    np.testing.assert_array_equal(ElementLineP3.doflocs[:, 0], NODE_XI)


def test_partition_of_unity():
    N, dN, d2N = shape_functions(XI)
    assert N.shape == dN.shape == d2N.shape == (4,) + XI.shape
    # the shape functions have coefficients of size ~14, so a few ulps of that
    np.testing.assert_allclose(N.sum(axis=0), 1.0, rtol=0, atol=1e-13)
    np.testing.assert_allclose(dN.sum(axis=0), 0.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(d2N.sum(axis=0), 0.0, rtol=0, atol=1e-12)


def test_shape_functions_keep_input_shape():
    xi = np.random.default_rng(0).random((3, 5, 2))
    N, dN, d2N = shape_functions(xi)
    assert N.shape == dN.shape == d2N.shape == (4, 3, 5, 2)
    N0, dN0, d2N0 = shape_functions(xi[1, 2, 1])
    np.testing.assert_allclose(N[:, 1, 2, 1], N0, rtol=0, atol=0)
    np.testing.assert_allclose(dN[:, 1, 2, 1], dN0, rtol=0, atol=0)
    np.testing.assert_allclose(d2N[:, 1, 2, 1], d2N0, rtol=0, atol=0)


def test_kronecker_property():
    N, _, _ = shape_functions(NODE_XI)
    np.testing.assert_allclose(N, np.eye(4), rtol=0, atol=1e-14)


@pytest.mark.parametrize("h", [1e-4, 1e-5])
def test_derivatives_against_central_differences(h):
    xi = np.linspace(-0.1, 1.1, 97)
    N, dN, d2N = shape_functions(xi)
    Np, dNp, _ = shape_functions(xi + h)
    Nm, dNm, _ = shape_functions(xi - h)
    # central difference of a cubic: truncation h^2/6 |N'''| (N''' = +-27 or
    # +-81) plus round-off ~ eps |N| / h; dN' has truncation 0 (dN quadratic)
    tol1 = 81 / 6 * h**2 + 10 * 14 * EPS / h
    tol2 = 10 * 20 * EPS / h
    np.testing.assert_allclose((Np - Nm) / (2 * h), dN, rtol=0, atol=tol1)
    np.testing.assert_allclose((dNp - dNm) / (2 * h), d2N, rtol=0, atol=tol2)


def test_third_derivative_is_constant():
    # d2N is affine: its slope computed from two far-apart points is exact
    _, _, a = shape_functions(np.array(0.0))
    _, _, b = shape_functions(np.array(1.0))
    # N_i''' = 27 * (sign) * (+-1 or 3) : the leading coefficients are
    # -4.5, 4.5, 13.5, -13.5 times 6
    np.testing.assert_allclose(b - a, 6 * np.array([-4.5, 4.5, 13.5, -13.5]),
                               rtol=1e-14, atol=0)


def test_lbasis_matches_shape_functions():
    e = ElementLineP3()
    X = XI[None, :]
    N, dN, _ = shape_functions(XI)
    for i in range(4):
        phi, dphi = e.lbasis(X, i)
        np.testing.assert_array_equal(phi, N[i])
        np.testing.assert_array_equal(dphi[0], dN[i])
    with pytest.raises(ValueError):
        e.lbasis(X, 4)


# --------------------------------------------------------------------------
# the element inside scikit-fem
# --------------------------------------------------------------------------

def _mesh(n, seed=None):
    x = np.linspace(0.0, 1.0, n + 1)
    if seed is not None:  # perturb interior vertices: non-uniform mesh
        rng = np.random.default_rng(seed)
        x[1:-1] += (rng.random(n - 1) - 0.5) * 0.4 / n
    return MeshLine(x)


def test_dof_count_and_locations():
    n = 4
    basis = Basis(_mesh(n), ElementLineP3())
    assert basis.N == 3 * n + 1
    # vertex dofs first, then two interior dofs per element at 1/3 and 2/3
    x = basis.doflocs[0]
    np.testing.assert_allclose(x[:n + 1], np.linspace(0, 1, n + 1), atol=1e-15)
    interior = x[n + 1:].reshape(n, 2)
    left = np.linspace(0, 1, n + 1)[:-1]
    np.testing.assert_allclose(interior[:, 0], left + 1 / (3 * n), atol=1e-15)
    np.testing.assert_allclose(interior[:, 1], left + 2 / (3 * n), atol=1e-15)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_exact_interpolation_of_cubics(seed):
    rng = np.random.default_rng(seed)
    c = rng.normal(size=4)                 # c0 + c1 x + c2 x^2 + c3 x^3
    f = lambda x: c[0] + c[1] * x + c[2] * x**2 + c[3] * x**3
    df = lambda x: c[1] + 2 * c[2] * x + 3 * c[3] * x**2
    basis = Basis(_mesh(7, seed=seed), ElementLineP3(), intorder=6)

    # nodal interpolation via doflocs
    u = f(basis.doflocs[0])
    uh = basis.interpolate(u)
    xq = np.array(basis.global_coordinates())[0]
    scale = np.abs(c).sum()
    np.testing.assert_allclose(np.array(uh), f(xq), rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(uh.grad[0], df(xq), rtol=0,
                               atol=1e-12 * scale)

    # L2 projection reproduces the same nodal values (cubic is in the space)
    up = basis.project(lambda x: f(x[0]))
    np.testing.assert_allclose(up, u, rtol=0, atol=1e-12 * scale)

    # and the interpolation at arbitrary points through shape_functions
    xi = rng.random(50)
    e = rng.integers(0, basis.mesh.nelements, size=50)
    x0 = basis.mesh.p[0, basis.mesh.t[0, e]]
    x1 = basis.mesh.p[0, basis.mesh.t[1, e]]
    N, dN, d2N = shape_functions(xi)
    ue = u[basis.element_dofs[:, e]]              # (4, npoints)
    L = x1 - x0
    np.testing.assert_allclose((N * ue).sum(0), f(x0 + xi * L), rtol=0,
                               atol=1e-13 * scale)
    np.testing.assert_allclose((dN * ue).sum(0) / L, df(x0 + xi * L), rtol=0,
                               atol=1e-11 * scale)
    np.testing.assert_allclose((d2N * ue).sum(0) / L**2,
                               2 * c[2] + 6 * c[3] * (x0 + xi * L), rtol=0,
                               atol=1e-9 * scale)


# --------------------------------------------------------------------------
# 1D Poisson convergence
# --------------------------------------------------------------------------

def u_exact(x):
    return np.sin(np.pi * x) * np.exp(x)


def du_exact(x):
    return np.exp(x) * (np.pi * np.cos(np.pi * x) + np.sin(np.pi * x))


def f_rhs(x):  # f = -u''
    return -np.exp(x) * (2 * np.pi * np.cos(np.pi * x)
                         + (1 - np.pi**2) * np.sin(np.pi * x))


@BilinearForm
def laplace(u, v, w):
    return dot(grad(u), grad(v))


@LinearForm
def load(v, w):
    return f_rhs(w.x[0]) * v


@Functional
def l2_error(w):
    return (w['uh'] - u_exact(w.x[0]))**2


@Functional
def h1_error(w):
    return (grad(w['uh'])[0] - du_exact(w.x[0]))**2


@Functional
def l2_diff(w):
    return (w['a'] - w['b'])**2


def _solve_poisson(mesh, element, intorder=10):
    basis = Basis(mesh, element, intorder=intorder)
    A = asm(laplace, basis)
    b = asm(load, basis)
    u = solve(*condense(A, b, D=basis.get_dofs()))
    return basis, u


NS = [4, 8, 16, 32, 64]


@pytest.fixture(scope="module")
def poisson_p3():
    return [_solve_poisson(MeshLine(np.linspace(0, 1, n + 1)), ElementLineP3())
            for n in NS]


def test_poisson_convergence_rates(poisson_p3):
    h = 1.0 / np.array(NS)
    eL2, eH1 = [], []
    for basis, u in poisson_p3:
        uh = basis.interpolate(u)
        eL2.append(np.sqrt(l2_error.assemble(basis, uh=uh)))
        eH1.append(np.sqrt(h1_error.assemble(basis, uh=uh)))
    rL2 = np.polyfit(np.log(h), np.log(eL2), 1)[0]
    rH1 = np.polyfit(np.log(h), np.log(eH1), 1)[0]
    assert abs(rL2 - 4.0) < 0.15, (rL2, eL2)
    assert abs(rH1 - 3.0) < 0.15, (rH1, eH1)
    # sanity: the finest errors are small but well above round-off
    assert 1e-12 < eL2[-1] < 1e-6
    assert 1e-10 < eH1[-1] < 1e-4


def test_poisson_nodal_values_superconvergent(poisson_p3):
    # in 1D the Galerkin solution is exact at the mesh vertices (the Green's
    # function lies in the space) up to quadrature error of the load and the
    # round-off of the solve, which grows like cond(A) ~ n^2
    for (basis, u), n in zip(poisson_p3, NS):
        xv = basis.mesh.p[0]
        np.testing.assert_allclose(u[:n + 1], u_exact(xv), rtol=0,
                                   atol=1e-14 * n**2)


@pytest.mark.parametrize("n", [4, 16])
def test_hierarchical_p3_gives_same_solution(n):
    mesh = MeshLine(np.linspace(0, 1, n + 1))
    basis, u = _solve_poisson(mesh, ElementLineP3())
    basis_h, u_h = _solve_poisson(mesh, ElementLinePp(3))
    # same quadrature points (same mesh, same intorder): compare the
    # discrete functions directly
    np.testing.assert_allclose(basis.X, basis_h.X, rtol=0, atol=0)
    diff = np.sqrt(l2_diff.assemble(basis, a=basis.interpolate(u),
                                    b=basis_h.interpolate(u_h)))
    assert diff < 1e-10, diff
