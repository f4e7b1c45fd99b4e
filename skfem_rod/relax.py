r"""Gradient-flow (proximal, backward-Euler pseudo-transient) continuation
through snaps.

Load stepping with Newton (:func:`skfem_rod.solver.newton`) follows an
equilibrium branch as long as there is one near the last converged state.
Past a limit point or a subcritical bifurcation (a twisted rod under
tension snapping into a loop, a shallow arch snapping through) there is
none: Newton fails at every step size.  The stable equilibrium on the other
side is reached by descending the energy ``E`` at the new load factor with
proximal steps

    y_{k+1} = argmin_y  E(y) + |y (-) y_k|_W^2 / (2 dt_k),

each solved by Newton on the augmented residual

    R(y) + c W (y (-) y_k),      c = 1 / dt_k,

(``y (-) y_k``: position difference and the spatial rotation vector
``log(R R_k^T)`` per node; the tangent gets ``+ c W``, its rotational part
approximated by the identity, which only slows Newton down far from
``y_k``).  This is backward Euler on the gradient flow ``W dy/dt = -R(y)``:
for any ``dt`` the step lowers ``E + |y - y_k|^2/2dt`` and the iterates
settle in a stable equilibrium (not on a saddle, unless started exactly on
it).  :func:`flow` runs it with

* ``W`` a lumped metric per node (:func:`metric`): arclength share of the
  node times ``B / l^2`` for positions and ``B`` for spins (``B`` the larger
  bending stiffness, ``l = L / 10``);
* ``dt`` adapted: divided by 3 when the proximal Newton fails (8
  iterations) or nodes would move too far, multiplied by 4, 2 or 1.5 after
  an easy step (<= 2, 3, 5 Newton iterations), starting from
  ``SolverOptions.relax_dt`` or twice the first step the last flow accepted; the proximal steps are solved to
  ``rtol = 1e-7`` only (the last state is polished anyway);
* a clearance cap with contact on (:func:`clearance_ok`): no two
  non-neighbouring nodes move relative to each other by more than half
  their clearance ``|r_i - r_j| - 2 eps`` (at least ``eps / 2``), so that
  two strands cannot pass through each other between two iterates (the
  contact search only sees the iterates);
* when the flow starts next to a saddle (pushed off an unstable
  equilibrium along its unstable mode), a descent check: a step is
  rejected (``dt`` divided by 3) when the energy change estimated by the
  trapezoid rule on the gradients at both ends exceeds half the viscous
  work of the step; a long step of the non-convex proximal problem can
  otherwise climb back onto the saddle (Newton converges to any stationary
  point).  It is off for the flows of failed steps: with contact the
  trapezoid estimate is poor where the active set changes, and it stalled
  the two-ply at 1.7 turns;
* convergence when the viscous force ``max |c W (y_{k+1} (-) y_k)|`` is
  below ``relax_tol`` times the force scale ``max(|f_ext|, |reactions|)``;
  the state is then polished by plain Newton (no viscous term) so that a
  relaxed step is an equilibrium to the same tolerance as any other step.

The load stepper (:func:`skfem_rod.solver.solve`, option ``snap="relax"``)
calls :func:`flow` in place of Newton inside the same Uzawa loop of the
contact multipliers when a step fails.
"""
from dataclasses import replace

import numpy as np
from scipy.spatial import cKDTree

from .rotations import logm


def metric(rod, fixed=None, length_scale=None):
    """Lumped viscous metric ``W`` (one value per dof, zero at the fixed
    dofs): nodal arclength share times ``B / l^2`` (positions) and ``B``
    (spins), ``l = length_scale`` (default ``L / 10``)."""
    mesh = rod.mesh
    ell = rod.length / 10.0 if length_scale is None else float(length_scale)
    B = max(rod.section.EI1, rod.section.EI2)
    o = mesh.order
    s = mesh.s_nodes[o]
    share = np.empty(s.size)
    gaps = np.diff(s)
    share[:] = 0.0
    share[:-1] += 0.5 * gaps
    share[1:] += 0.5 * gaps
    h = np.empty(s.size)
    h[o] = share
    w = np.empty((s.size, 6))
    w[:, :3] = (B / ell**2) * h[:, None]
    w[:, 3:] = B * h[:, None]
    w = w.ravel()
    if fixed is not None:
        w = np.where(fixed, 0.0, w)
    return w


def increment(r, R, r_ref, R_ref):
    """``y (-) y_ref``: position differences and spatial rotation vectors
    ``log(R R_ref^T)`` per node, flattened like the dofs."""
    return np.concatenate([r - r_ref, logm(R @ np.swapaxes(R_ref, 1, 2))], axis=1).ravel()


def viscous_terms(viscous, r, R):
    """Residual ``c W (y (-) y_ref)`` and tangent diagonal ``c W`` of the
    viscous term ``viscous = (c, W, (r_ref, R_ref))``."""
    c, W, (r_ref, R_ref) = viscous
    return c * W * increment(r, R, r_ref, R_ref), c * W


def clearance_ok(rod, r_old, r_new):
    """True when no two non-neighbouring nodes move relative to each other by
    more than half their clearance ``|r_i - r_j| - 2 eps`` at ``r_old`` (at
    least ``eps / 2``), so that strands cannot pass through each other
    between two iterates; always True with contact off."""
    c = rod.contact
    if c is None:
        return True
    d = r_new - r_old
    d = d - d.mean(axis=0)               # relative motion: a translation is free
    move = np.sqrt((d * d).sum(axis=1))
    floor = 0.5 * c.radius
    if 2 * move.max() <= floor:
        return True
    # two nodes approach each other by at most 2 max|d|, which exceeds half
    # their clearance only if that clearance is below 4 max|d|
    pairs = cKDTree(r_old).query_pairs(2 * c.radius + 4 * move.max(), output_type="ndarray")
    if pairs.size == 0:
        return True
    i, j = pairs[:, 0], pairs[:, 1]
    s = rod.mesh.s_nodes
    h = rod.length / rod.mesh.n_elements
    far = np.abs(s[i] - s[j]) > max(c.exclusion, h)
    i, j = i[far], j[far]
    rel = np.linalg.norm(d[i] - d[j], axis=1)
    clear = np.linalg.norm(r_old[i] - r_old[j], axis=1) - 2 * c.radius
    return bool(np.all(rel <= np.maximum(0.5 * clear, floor)))


def flow(system, r, R, lam, prescribed, opts, descent=False):
    """Proximal steps at load factor ``lam`` (contact multipliers held) from
    ``(r, R)``, the first one carrying the prescribed increment, until the
    viscous force is below ``opts.relax_tol`` times the force scale; then a
    plain Newton polish.  Same signature and return value as
    :func:`skfem_rod.solver.newton`: ``(converged, r, R, info)``; ``info``
    also has ``flow_steps`` (accepted proximal steps) and ``dt``.
    ``descent=True`` adds the descent check (used when the flow starts next
    to a saddle, pushed off along its unstable mode)."""
    from .solver import newton
    rod = system.rod
    if getattr(system, "_relax_W", None) is None:
        system._relax_W = metric(rod, system.fixed)
    W = system._relax_W
    # the proximal steps need not be solved to round-off: only the last
    # state counts, and it is polished by plain Newton
    inner = replace(opts, max_iterations=min(opts.max_iterations, 8),
                    rtol=max(opts.rtol, 1e-7), increment_tol=max(opts.increment_tol, 1e-8))
    capped = 0
    # start at twice the first step size the last flow accepted (the flows
    # of one problem meet the same stiffness), else at relax_dt
    dt = getattr(system, "_relax_dt", opts.relax_dt)
    presc = prescribed.copy()
    steps = tries = iters = 0
    fscale = None
    why = "no proximal step"
    free = system.free
    g0 = None
    if descent and not np.any(prescribed):
        g0 = system.evaluate(r, R, lam, tangent=False)[0]
    while steps < opts.max_flow_steps:
        tries += 1
        system.viscous = (1.0 / dt, W, (r, R))
        try:
            ok, r1, R1, info = newton(system, r, R, lam, presc, inner)
        finally:
            system.viscous = None
        iters += info["iterations"]
        if ok and not clearance_ok(rod, r, r1):
            ok, info["reason"] = False, "a node moved beyond the clearance cap"
            capped += 1
        if ok:
            # descent: the energy change over the step, by the trapezoid rule
            # on the gradients g0 (at y_k) and g1 = res - c W dy (at y_k+1),
            # must not exceed half the viscous work |g1 . dy|.  A too long
            # step of the non-convex proximal problem can climb back onto a
            # saddle (Newton converges to any stationary point); along an
            # unstable mode of curvature -k this rejects c W < k / 2, and the
            # slack leaves room for the non-smooth contact terms.
            dy = increment(r1, R1, r, R)
            if system.T is not None:          # residuals live in the supports' bases
                dy = system.T.T @ dy
            g1 = info["res"] - W * dy / dt
            if descent and g0 is not None:
                down = 0.5 * float(np.dot((g0 + g1)[free], dy[free]))
                if down > 0.5 * abs(float(np.dot(g1[free], dy[free]))):
                    ok, info["reason"] = False, "the proximal step climbs (energy would rise)"
        if not ok:
            why = info["reason"]
            dt /= 3.0
            if dt < opts.relax_dt * 1e-9:
                break
            continue
        steps += 1
        system.calls["flow_steps"] += 1
        g0 = g1
        vis = float(np.abs(W * dy).max() / dt)
        if steps == 1:
            system._relax_dt = 2.0 * dt
        if fscale is None:
            res = info["res"]
            fscale = max(np.linalg.norm(info["f_ext"]),
                         np.linalg.norm(res[system.fixed]), 1e-300)
        r, R, presc = r1, R1, np.zeros_like(presc)
        if info["iterations"] <= 5:
            grow = 4.0 if info["iterations"] <= 2 else 2.0 if info["iterations"] <= 3 else 1.5
            dt = min(grow * dt, 1e12 * opts.relax_dt)
        if vis <= opts.relax_tol * fscale:
            ok, r2, R2, fin = newton(system, r, R, lam, presc, opts)
            ok = ok and clearance_ok(rod, r, r2)
            if ok:
                r, R, info = r2, R2, fin
                iters += fin["iterations"]
            info = dict(info, iterations=iters, flow_steps=steps, dt=dt, capped=capped,
                        tries=tries, polished=bool(ok))
            if not ok:          # the flow's state, residual ~ relax_tol
                res, _, f_ext, iw = system.evaluate(r, R, lam)
                info.update(res=res, iw=iw, f_ext=f_ext, reason="")
            return True, r, R, info
    return False, r, R, dict(history=[], iterations=iters, flow_steps=steps, dt=dt,
                             reason=f"gradient flow stopped after {steps} steps "
                                    f"({tries} tries, dt={dt:.3g}): {why}")
