r"""Compiled per-pair loops of the contact searches (numba).

The closest-point iterations of the searches are small (a 2 x 2 or 1 x 1
Newton per pair, ten or so iterations each) and independent from pair to
pair.  Vectorized over the pairs with numpy, each iteration costs some
forty array operations whatever the number of pairs still iterating, and
the tail of slowly converging pairs (flat valleys between wrapped
strands) keeps the loop going for all: measured in the frictional knot's
cycle, 2.0 ms per call of the crossing search's Newton, a fifth of the
cycle's time.  Here each pair runs its own loop, compiled: 0.05 ms per
call on the same calls, with the same results to the last bit (the same
operations in the same order: ``tests/test_crossing_batched.py`` holds
them to a reference written with numpy).

Each kernel is the scalar form of an algorithm documented where it is
used; this module holds no other logic:

* :func:`closest_points_newton`: the safeguarded, projected Newton on
  ``|X(u) - Y(v)|^2 / 2`` of :func:`skfem_rod.contact.crossing.local_minima`;
* :func:`projection_newton`: the projection of a point on an element
  curve of :func:`skfem_rod.contact.search.project` (the slave points'
  master points).

numba is imported with this module, which the searches import at their
first call (heavy imports lazy); the kernels are compiled at their first
call and cached on disk (``cache=True``).
"""
import numba
import numpy as np

__all__ = ["closest_points_newton", "projection_newton"]


@numba.njit(cache=True)
def _cubic(c0, c1, c2, c3, t):
    """``c0 + c1 t + c2 t^2 + c3 t^3`` by the Horner scheme of
    :func:`skfem_rod.contact.search.curve_position` (the same round-off)."""
    return ((c3 * t + c2) * t + c1) * t + c0


@numba.njit(cache=True)
def _point(C, side, k, t, P, P1, P2):
    """Position and first and second derivatives at ``t`` of curve ``side``
    of pair ``k`` (monomial coefficients ``C`` ``(4, 3, 2, m)``), into
    ``P``, ``P1``, ``P2``: the Horner scheme of
    :func:`skfem_rod.contact.search.curve_point`."""
    for c in range(3):
        c0, c1, c2, c3 = C[0, c, side, k], C[1, c, side, k], C[2, c, side, k], C[3, c, side, k]
        P[c] = _cubic(c0, c1, c2, c3, t)
        P1[c] = (3.0 * c3 * t + 2.0 * c2) * t + c1
        P2[c] = 6.0 * c3 * t + 2.0 * c2


@numba.njit(cache=True)
def _gap2(C, k, u, v):
    """``|X(u) - Y(v)|^2`` of pair ``k``."""
    s = 0.0
    for c in range(3):
        x = _cubic(C[0, c, 0, k], C[1, c, 0, k], C[2, c, 0, k], C[3, c, 0, k], u)
        y = _cubic(C[0, c, 1, k], C[1, c, 1, k], C[2, c, 1, k], C[3, c, 1, k], v)
        s += (x - y) * (x - y)
    return s


@numba.njit(cache=True)
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@numba.njit(cache=True)
def _clip01(t):
    # np.clip's: NaN stays NaN
    return 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)


@numba.njit(cache=True)
def _step(u, v, gu, gv, huu, hvv, huv):
    """The update ``(du, dv)`` (to subtract) of one iteration at ``(u, v)``
    with gradient ``(gu, gv)`` and Hessian ``(huu, hvv, huv)``, and whether
    each parameter is free: a parameter on a bound with the gradient
    pushing outward stays; Newton where the quadratic model has a minimum,
    else a safe step in each parameter alone; both free without a minimum
    (a saddle or a flat valley): Newton on the Hessian shifted to positive
    definite, at most a quarter element long."""
    fu = not (((u <= 0) and (gu > 0)) or ((u >= 1) and (gu < 0)))
    fv = not (((v <= 0) and (gv > 0)) or ((v >= 1) and (gv < 0)))
    det = huu * hvv - huv * huv
    both = fu and fv and (huu > 0) and (det > 1e-14 * (huu * hvv + 1e-300))
    if both:
        du = (hvv * gu - huv * gv) / det
        dv = (huu * gv - huv * gu) / det
    else:
        du = gu / huu if huu > 1e-14 else 0.1 * np.sign(gu)
        dv = gv / hvv if hvv > 1e-14 else 0.1 * np.sign(gv)
    shift = fu and fv and not both
    if shift:
        lmin = 0.5 * (huu + hvv) - np.sqrt(0.25 * (huu - hvv) ** 2 + huv * huv)
        mu = max(0.0, -lmin) + 1e-9 * abs(huu + hvv) + 1e-300
        su, sv = huu + mu, hvv + mu
        sdet = su * sv - huv * huv
        du = (sv * gu - huv * gv) / sdet
        dv = (su * gv - huv * gu) / sdet
    if not fu:
        du = 0.0
    if not fv:
        dv = 0.0
    if shift:
        big = max(max(abs(du), abs(dv)) / 0.25, 1.0)
        du, dv = du / big, dv / big
    return du, dv, fu, fv


@numba.njit(cache=True)
def closest_points_newton(C, u, v, iterations):
    """Projected, safeguarded Newton on ``|X(u) - Y(v)|^2 / 2`` per pair,
    from ``(u, v)``: the curves' monomial coefficients ``C`` ``(4, 3, 2,
    m)`` (both curves of a pair side by side).  Each iteration: the update
    of :func:`_step`, backtracked (the full step, then 11 halvings, each
    clipped to [0, 1]) until the squared distance does not increase (stay
    put if it always does); a pair stops when its projected gradient is at
    round-off or its parameters move by less than 1e-12.  Returns ``(u,
    v, distance)``."""
    m = u.size
    uo, vo, d = u.copy(), v.copy(), np.empty(m)
    X, X1, X2 = np.empty(3), np.empty(3), np.empty(3)
    Y, Y1, Y2 = np.empty(3), np.empty(3), np.empty(3)
    D = np.empty(3)
    for k in range(m):
        ua, va = uo[k], vo[k]
        for _ in range(iterations):
            _point(C, 0, k, ua, X, X1, X2)
            _point(C, 1, k, va, Y, Y1, Y2)
            for c in range(3):
                D[c] = X[c] - Y[c]
            gu, gv = _dot(D, X1), -_dot(D, Y1)
            huu, hvv, huv = _dot(X1, X1) + _dot(D, X2), _dot(Y1, Y1) - _dot(D, Y2), -_dot(X1, Y1)
            du, dv, fu, fv = _step(ua, va, gu, gv, huu, hvv, huv)
            DD = _dot(D, D)
            f0 = DD * (1 + 1e-15) + 1e-300
            nu, nv, scale = ua, va, 1.0
            for h in range(12):
                if h == 0:
                    tu, tv = _clip01(ua - du), _clip01(va - dv)
                else:
                    scale *= 0.5
                    tu, tv = _clip01(ua - scale * du), _clip01(va - scale * dv)
                if _gap2(C, k, tu, tv) <= f0:
                    nu, nv = tu, tv
                    break
            tol = 1e-13 * np.sqrt(DD * (_dot(X1, X1) + _dot(Y1, Y1))) + 1e-300
            stationary = abs(gu if fu else 0.0) <= tol and abs(gv if fv else 0.0) <= tol
            moved = (abs(nu - ua) >= 1e-12 or abs(nv - va) >= 1e-12) and not stationary
            ua, va = nu, nv
            if not moved:
                break
        uo[k], vo[k], d[k] = ua, va, np.sqrt(_gap2(C, k, ua, va))
    return uo, vo, d


@numba.njit(cache=True)
def projection_newton(x, E, xi, iterations):
    """Newton on ``|y(xi) - x|^2 / 2`` per point, from ``xi``: the points
    ``x`` ``(3, m)``, the curves' monomial coefficients with those of their
    derivatives ``E`` ``(7, 3, m)`` (``C0..C3``, ``3 C3``, ``2 C2``,
    ``6 C3``).  Newton where the distance is locally convex, a gradient
    step of a quarter element else, clipped to [0, 1]; a point stops when
    its parameter moves by at most 1e-15.  Returns ``xi``."""
    out = xi.copy()
    for k in range(out.size):
        t = out[k]
        for _ in range(iterations):
            n1 = f = gy2 = 0.0
            for c in range(3):
                y = _cubic(E[0, c, k], E[1, c, k], E[2, c, k], E[3, c, k], t)
                y1 = (E[4, c, k] * t + E[5, c, k]) * t + E[1, c, k]
                y2 = E[6, c, k] * t + E[5, c, k]
                g = y - x[c, k]
                n1 += y1 * y1
                f += g * y1
                gy2 += g * y2
            fp = n1 + gy2
            step = f / fp if fp > 1e-12 * n1 else 0.25 * np.sign(f)
            new = _clip01(t - step)
            moved = abs(new - t) > 1e-15
            t = new
            if not moved:
                break
        out[k] = t
    return out
