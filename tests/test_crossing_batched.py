"""The batched kernels of the contact search and the crossing pairs against
the one-call-at-a-time code they replaced (kept here as references): the
probes of :func:`crossing._weigh` and the three elements of
:func:`crossing._near` in one projection, the safeguarded Newton of
:func:`crossing._newton` on both curves at once, the grid's lowest starts
(:func:`crossing._lowest_rows`), the point projection
:func:`search._project`, and the search's candidate order with a neighbour
list.  The answers must be the same to the last bit (the same floating
point operations per point), on seeded random scenes with many minima:
noisy two-ply plectonemes (open rods, crossings and wrapped plies) and a
noisy pinched ring (closed rod, periodic arclength)."""
import numpy as np
import pytest

from skfem_rod import Rod, Section, geometry
from skfem_rod.contact import crossing as X
from skfem_rod.contact import search as S
from skfem_rod.contact.search import (arc_distance, arclength_period, curve_point,
                                      monomial_coefficients, project, search, slave_points)
from skfem_rod.element import shape_functions

EPS = 1.0
SEC = Section(EA=1, GA1=1, GA2=1, EI1=1, EI2=1, GJ=1, radius=EPS)


def scene(kind, seed, noise=0.3):
    """A rod and nodal positions with seeded noise of ``noise`` eps:
    ``"plectoneme"`` (open, plies crossing at 0.4 rad) or ``"ring"``
    (closed, pinched at two waists)."""
    rng = np.random.default_rng(seed)
    if kind == "plectoneme":
        rod = Rod(geometry.plectoneme(0.98 * EPS, 0.4, 3, loop=20 * EPS, tail=20 * EPS), SEC, 60)
        r = rod.r0.copy()
    else:
        rod = Rod(geometry.ring(10.0 * EPS), SEC, 48)
        assert rod.mesh.closed
        th = rod.mesh.s_nodes / (10.0 * EPS)
        r = 10.0 * EPS * np.stack([np.cos(th), np.sin(th) * (0.1 + 0.9 * np.cos(2 * th) ** 2),
                                   0.05 * np.sin(3 * th)], axis=1)
    return rod.mesh, r + noise * EPS * rng.standard_normal(r.shape)


# -- references: the code before the batching --------------------------------

def near_reference(mesh, r, x, sx, f, exclusion):
    """:func:`crossing._near` with one projection per offset."""
    ne, vt = mesh.nodes.shape[0], mesh.vertices
    period = arclength_period(mesh)
    closed = period is not None
    best = None
    for o in (0, -1, 1):
        fb = f + o
        ok = np.ones(f.size, bool) if closed else (fb >= 0) & (fb < ne)
        fb = np.mod(fb, ne) if closed else np.where(ok, fb, f)
        eta, _ = project(x, r[mesh.nodes[fb]])
        Nb = shape_functions(eta)[0].T
        D = x - np.einsum("kI,kIc->kc", Nb, r[mesh.nodes[fb]])
        ok &= arc_distance(sx, vt[fb] + eta * (vt[fb + 1] - vt[fb]), period) >= exclusion
        d = np.where(ok, np.sqrt(np.sum(D * D, axis=1)), np.inf)
        if best is None:
            best = [d, D, fb, Nb]
        else:
            lower = d < best[0]
            best = [np.where(lower, d, best[0]), np.where(lower[:, None], D, best[1]),
                    np.where(lower, fb, best[2]), np.where(lower[:, None], Nb, best[3])]
    return best


def weigh_reference(mesh, r, mn, radius, threshold, exclusion):
    """:func:`crossing._weigh` probe by probe (two sides, two signs)."""
    m = mn["e"].size
    vt = mesh.vertices
    e, f = mn["e"], mn["f"]
    he, hf = vt[e + 1] - vt[e], vt[f + 1] - vt[f]
    hmin = np.minimum(he, hf)
    delta = X.slave_half_gap(threshold.n_slave) * hmin
    c2 = (delta * np.sin(threshold.angle(hmin, radius))) ** 2
    l = mn["distance"]
    R = np.sqrt(l * l + c2) - l
    dR = l / np.sqrt(l * l + c2) - 1.0
    sb2 = np.sin(threshold.angle(hmin, radius)) ** 2
    w_beta, slope_beta = X._smoothstep(mn["weigh_sin2"] / sb2)
    todo = np.flatnonzero(w_beta > 0)
    rise = np.full(m, np.inf)
    dofs, dq, dp = np.zeros((m, 24), np.int64), np.zeros((m, 24)), np.zeros((m, 2))
    for side in (0, 1):
        s0, B, h = (mn["s"], f, he) if side == 0 else (mn["s_bar"], e, hf)
        for sign in (-1.0, 1.0):
            ep, Np, x, x1, moving, sp_ = X._curve_at(mesh, r, s0[todo] + sign * delta[todo])
            d, D, fb, Nb = near_reference(mesh, r, x, sp_, B[todo], exclusion)
            nrm = D / np.where(np.isfinite(d), d, 1.0)[:, None]
            lower = d - l[todo] < rise[todo]
            if not lower.any():
                continue
            c = np.where(moving, X._dot(nrm.T, x1.T) * h[todo] / (vt[ep + 1] - vt[ep]), 0.0)
            a = np.concatenate([Np, -Nb], axis=1) if side == 0 else np.concatenate([-Nb, Np], 1)
            nodes = (np.concatenate([mesh.nodes[ep], mesh.nodes[fb]], axis=1) if side == 0
                     else np.concatenate([mesh.nodes[fb], mesh.nodes[ep]], axis=1))
            j = np.flatnonzero(lower)
            k = todo[j]
            rise[k] = d[j] - l[k]
            dq[k] = (a[j, :, None] * nrm[j, None, :]).reshape(j.size, 24)
            dofs[k] = (6 * nodes[j, :, None] + np.arange(3)).reshape(j.size, 24)
            dp[k] = 0.0
            dp[k, side] = c[j]
    w_rise, slope = X._smoothstep(rise / R)
    mn["weight"] = w_rise * w_beta
    mn["weight_slope"] = w_beta * slope / R
    finite = np.where(np.isfinite(rise), rise, 0.0)
    mn["weight_slope_l"] = -w_beta * slope * finite * dR / (R * R)
    mn["weight_slope_beta"] = w_rise * slope_beta / sb2
    mn["probe_dofs"], mn["probe_dq"], mn["probe_dp"] = dofs, dq, dp


def newton_reference(C1, C2, u, v, iterations, shifted):
    """:func:`crossing._newton` on each curve apart (``shifted[0]`` counts
    the iterations that took a shifted, saddle step)."""
    u, v = u.copy(), v.copy()
    act = np.arange(u.size)
    dot = X._dot
    for _ in range(iterations):
        c1, c2, ua, va = C1[:, :, act], C2[:, :, act], u[act], v[act]
        Xp, X1, X2 = curve_point(c1, ua)
        Yp, Y1, Y2 = curve_point(c2, va)
        D = Xp - Yp
        gu, gv = dot(D, X1), -dot(D, Y1)
        huu, hvv, huv = X._hessian(D, X1, X2, Y1, Y2)
        fu = ~(((ua <= 0) & (gu > 0)) | ((ua >= 1) & (gu < 0)))
        fv = ~(((va <= 0) & (gv > 0)) | ((va >= 1) & (gv < 0)))
        det = huu * hvv - huv * huv
        both = fu & fv & (huu > 0) & (det > 1e-14 * (huu * hvv + 1e-300))
        safe = lambda h, g: np.where(h > 1e-14, g / np.where(h > 1e-14, h, 1.0),   # noqa: E731
                                     0.1 * np.sign(g))
        shift = fu & fv & ~both
        shifted[0] += bool(shift.any())
        lmin = 0.5 * (huu + hvv) - np.sqrt(0.25 * (huu - hvv) ** 2 + huv * huv)
        mu = np.where(shift, np.maximum(0.0, -lmin) + 1e-9 * np.abs(huu + hvv) + 1e-300, 0.0)
        su, sv = huu + mu, hvv + mu
        sdet = np.where(shift, su * sv - huv * huv, 1.0)
        du = np.where(both, (hvv * gu - huv * gv) / np.where(both, det, 1.0),
                      np.where(shift, (sv * gu - huv * gv) / sdet, safe(huu, gu)))
        dv = np.where(both, (huu * gv - huv * gu) / np.where(both, det, 1.0),
                      np.where(shift, (su * gv - huv * gu) / sdet, safe(hvv, gv)))
        du, dv = np.where(fu, du, 0.0), np.where(fv, dv, 0.0)
        big = np.where(shift, np.maximum(np.abs(du), np.abs(dv)) / 0.25, 1.0)
        du, dv = du / np.maximum(big, 1.0), dv / np.maximum(big, 1.0)
        f0 = dot(D, D) * (1 + 1e-15) + 1e-300
        nu, nv = ua.copy(), va.copy()
        todo = np.arange(act.size)
        step = 1.0
        for _ in range(12):
            tu = np.clip(ua[todo] - step * du[todo], 0.0, 1.0)
            tv = np.clip(va[todo] - step * dv[todo], 0.0, 1.0)
            Dn = curve_point(c1[:, :, todo], tu)[0] - curve_point(c2[:, :, todo], tv)[0]
            ok = dot(Dn, Dn) <= f0[todo]
            nu[todo[ok]], nv[todo[ok]] = tu[ok], tv[ok]
            todo = todo[~ok]
            if todo.size == 0:
                break
            step *= 0.5
        tol = 1e-13 * np.sqrt(dot(D, D) * (dot(X1, X1) + dot(Y1, Y1))) + 1e-300
        stationary = (np.abs(np.where(fu, gu, 0.0)) <= tol) & (np.abs(np.where(fv, gv, 0.0)) <= tol)
        moved = ((np.abs(nu - ua) >= 1e-12) | (np.abs(nv - va) >= 1e-12)) & ~stationary
        u[act], v[act] = nu, nv
        act = act[moved]
        if act.size == 0:
            break
    D = curve_point(C1, u)[0] - curve_point(C2, v)[0]
    return u, v, np.sqrt(dot(D, D))


def project_reference(x, C, iterations=12):
    """:func:`search._project` with :func:`curve_point` at every iteration."""
    m = x.shape[1]
    d = np.einsum("tp,pcm->tcm", S._SAMPLE_POWERS, C) - x
    xi = S._SAMPLES[np.argmin(np.einsum("tcm,tcm->tm", d, d), axis=0)]
    todo = np.arange(m)
    Ct, xt, xit = C, x, xi.copy()
    for _ in range(iterations):
        y, y1, y2 = curve_point(Ct, xit)
        g = y - xt
        n1 = np.sum(y1 * y1, axis=0)
        f = np.sum(g * y1, axis=0)
        fp = n1 + np.sum(g * y2, axis=0)
        step = np.where(fp > 1e-12 * n1, f / np.where(fp == 0, 1, fp), 0.25 * np.sign(f))
        new = np.clip(xit - step, 0.0, 1.0)
        moved = np.abs(new - xit) > 1e-15
        xi[todo] = new
        if not moved.all():
            todo, Ct, xt, xit = todo[moved], Ct[:, :, moved], xt[:, moved], new[moved]
            if todo.size == 0:
                break
        else:
            xit = new
    y, y1, _ = curve_point(C, xi)
    g = y - x
    f = np.abs(np.sum(g * y1, axis=0))
    scale = np.sqrt(np.sum(y1 * y1, axis=0)) * np.sqrt(np.sum(g * g, axis=0))
    interior = (xi > 0.0) & (xi < 1.0) & (f <= 1e-9 * (scale + 1e-300))
    return xi, interior, y


# -- the tests ----------------------------------------------------------------

def assert_same(a, b, name=""):
    """Bit for bit (NaN where NaN)."""
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype == b.dtype, name
    assert np.array_equal(a, b, equal_nan=a.dtype.kind == "f"), name


@pytest.mark.parametrize("kind", ["plectoneme", "ring"])
@pytest.mark.parametrize("seed", [0, 1])
def test_near_batched_matches_one_element_at_a_time(kind, seed):
    """Random points near the curve, each against the elements around a
    random one (the rod's first and last included), with exclusions that
    leave all, some or none of the three admissible."""
    mesh, r = scene(kind, seed)
    rng = np.random.default_rng(100 + seed)
    ne = mesh.nodes.shape[0]
    k = 200
    f = np.r_[0, ne - 1, rng.integers(0, ne, k - 2)]
    s = mesh.vertices[f] + rng.random(k) * np.diff(mesh.vertices)[f]
    sx = s + rng.choice([-1.0, 1.0], k) * rng.uniform(0.0, 6.0, k) * EPS
    x = X._curve_at(mesh, r, s)[2] + 2.0 * EPS * rng.standard_normal((k, 3))
    for exclusion in (0.0, np.pi * EPS, 4.0 * EPS, 1e3 * EPS):
        got = X._near(mesh, r, x, sx, f, exclusion)
        want = near_reference(mesh, r, x, sx, f, exclusion)
        for name, a, b in zip(("d", "D", "fb", "Nb"), got, want):
            assert_same(a, b, name)
        if exclusion == 4.0 * EPS:
            inf = np.isinf(got[0])
            assert 0 < inf.sum() < k                  # both cases met


@pytest.mark.parametrize("kind", ["plectoneme", "ring"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_weigh_batched_matches_probe_by_probe(kind, seed):
    """The weights, slopes and lowest probes of every minimum of a noisy
    scene (many minima, weights in the fade and out of it)."""
    mesh, r = scene(kind, seed)
    radius, exclusion = EPS, np.pi * EPS
    mn = X._minima(mesh, r, radius, exclusion, 3 * radius)
    X._describe(mesh, mn)
    ref = dict(mn)
    threshold = X.PairThreshold()
    X._weigh(mesh, r, mn, radius, threshold, exclusion)
    weigh_reference(mesh, r, ref, radius, threshold, exclusion)
    assert mn["e"].size >= 10
    assert (mn["weight"] > 0).any()
    assert set(mn) == set(ref)
    for name in mn:
        assert_same(mn[name], ref[name], name)


@pytest.mark.parametrize("seed", [0, 1])
def test_newton_on_both_curves_matches_each_apart(seed):
    """Element pairs of a noisy plectoneme (crossings, wrapped plies with
    saddle steps) from random starts and from the grid's: the same
    parameters and distances."""
    mesh, r = scene("plectoneme", seed)
    e, f, _, r_el = X._element_pairs(mesh, r, 3 * EPS, np.pi * EPS)
    C = monomial_coefficients(r_el).transpose(1, 2, 0)
    rng = np.random.default_rng(200 + seed)
    u0, v0 = rng.random(e.size), rng.random(e.size)
    u0[::7], v0[::5] = 0.0, 1.0                        # starts on the bounds too
    shifted = [0]
    for it in (3, 40):
        got = X._newton(C[:, :, e], C[:, :, f], u0, v0, it)
        want = newton_reference(C[:, :, e], C[:, :, f], u0, v0, it, shifted)
        for name, a, b in zip("uvd", got, want):
            assert_same(a, b, name)
    assert shifted[0] > 0                              # the saddle branch ran


def test_lowest_rows_is_the_head_of_the_stable_sort():
    """Ties (by row), and a column with inf and NaN (the sort's order)."""
    rng = np.random.default_rng(3)
    rank = np.round(rng.random((49, 300)), 1)
    for n in (1, 3, 5):
        assert_same(X._lowest_rows(rank, n), np.argsort(rank, axis=0, kind="stable")[:n])
    rank[[4, 9, 20], 7] = np.inf
    rank[[2, 30], 8] = np.nan
    assert_same(X._lowest_rows(rank, 3), np.argsort(rank, axis=0, kind="stable")[:3])


@pytest.mark.parametrize("seed", [0, 1])
def test_project_matches_reference(seed):
    """Points near and far from the element curves of a noisy scene
    (non-convex distance: the gradient steps), projected on random
    elements."""
    mesh, r = scene("plectoneme", seed, noise=0.8)
    rng = np.random.default_rng(300 + seed)
    C = np.ascontiguousarray(monomial_coefficients(r[mesh.nodes]).transpose(1, 2, 0))
    j = rng.integers(0, C.shape[2], 500)
    x = r[rng.integers(0, r.shape[0], 500)].T + 3.0 * rng.standard_normal((3, 500))
    x = np.ascontiguousarray(x)
    got = S._project(x, np.ascontiguousarray(C[:, :, j]))
    want = project_reference(x, np.ascontiguousarray(C[:, :, j]))
    for name, a, b in zip(("xi", "interior", "y"), got, want):
        assert_same(a, b, name)
    assert 0 < got[1].sum() < 500                      # interior and clamped


def test_search_with_a_shuffled_neighbour_list():
    """Kept pairs in any order give the answer of a fresh search (the
    candidates are put in their order again when they are not in it)."""
    mesh, r = scene("plectoneme", 0, noise=0.1)
    sl = slave_points(mesh, 3)
    reach, excl = 3.0 * EPS, np.pi * EPS
    fresh = search(mesh, r, sl, reach, excl)
    nl = S.NeighbourList(skin=0.5 * EPS)
    search(mesh, r, sl, reach, excl, neighbours=nl)
    assert np.all(np.diff(nl.i * mesh.nodes.shape[0] + nl.j) > 0)   # kept sorted
    order = np.random.default_rng(4).permutation(nl.i.size)
    nl.i, nl.j = nl.i[order], nl.j[order]
    kept = search(mesh, r, sl, reach, excl, neighbours=nl)
    assert fresh.size > 0 and nl.builds == 1
    for name in ("slave", "m_elem", "m_xi", "s_bar", "distance", "normal", "interior",
                 "n_candidates"):
        assert_same(getattr(kept, name), getattr(fresh, name), name)


def test_first_lowest_is_the_running_minimum():
    """:func:`crossing._first_lowest` against the loop it replaced in
    :func:`crossing._near` (a row replaces the best only where strictly
    lower): ties keep the earlier row, a NaN in row 0 stays, a NaN in a
    later row never wins, all inf keeps row 0."""
    rng = np.random.default_rng(5)
    d = np.round(rng.random((3, 400)), 1)
    d[rng.random(d.shape) < 0.2] = np.inf
    d[rng.random(d.shape) < 0.1] = np.nan
    d[:, :3] = [[np.inf, np.nan, 0.5], [np.inf, 0.1, np.nan], [np.inf, 0.2, 0.5]]
    best, row = d[0].copy(), np.zeros(d.shape[1], np.int64)
    for k in (1, 2):
        lower = d[k] < best
        best, row = np.where(lower, d[k], best), np.where(lower, k, row)
    assert_same(X._first_lowest(d), row)
    assert list(row[:3]) == [0, 0, 0]
