r"""Generalized (semi-smooth) Newton on the Alart-Curnier augmented
Lagrangian of normal contact: the normal multipliers are unknowns beside
the rod's dofs and move at every Newton iteration, with the generalized
Jacobian of the projection ``[.]_+``.  Selected by
``SolverOptions.contact_solve = "newton"``; the paper's Uzawa loop
(:mod:`skfem_rod.augmented`) is ``"uzawa"`` and stays around this solve:
it updates the friction multipliers between Newton solves (Uzawa, the
paper's eq. 4.2b-c) and takes over if a solve ends short of the contact
tolerances.  docs/contact-solve.md has the derivation and the measurements.

Unknowns ``(y, lambda_N)``, ``lambda_N`` one per slave point (a force per
unit length), and with crossing contact one point force per crossing pair
of the current evaluation (``C_c = w f_N - lambda_c``, the fixed point of
the Uzawa update of a pair of weight ``w``; docs/contact-solve.md, "The
crossing pairs among the unknowns") and, with friction at the crossing
pairs, their three friction multipliers each (``C = c - lambda_T``;
docs/crossing-contact.md, "Friction at the crossing pairs").  Residuals
(``w`` the slave's weight, ``f_N`` the augmented-Lagrangian force of eq.
4.2a, ``f_N = [d + mu lambda_N]_+ / mu``)::

    G(y, lambda)   = internal - external + contact(f_N) + friction(f_N)
    C_i(y, lambda) = w_i (f_N,i - lambda_i)

``C_i = 0`` is the Alart-Curnier complementarity function: where
``d + mu lambda > 0`` (active) it is ``w d / mu`` (the gap closes), elsewhere
``-w lambda`` (no force).  Its generalized Jacobian::

    active:   dC/dy = -(w / mu) dl (dl: derivative of the distance), dC/dlambda = 0
    inactive: dC/dy = 0,                                              dC/dlambda = -w
    dG/dlambda = -w dl (+ the friction's d/df_N through the Coulomb radius) where active

and ``dG/dy`` is the penalty tangent at the current multipliers
(:mod:`skfem_rod.contact.assembly`): one sparse system of size
``n_dofs + n_slaves`` per iteration.  Every contact is seen from both
sides (both strands' Gauss points are slaves), so the active rows are
nearly dependent and the exact Jacobian is singular: the active rows get
``dC/dlambda = -REGULARIZATION w`` (the residual stays exact).

In plain sight::

    evaluate G, C and the generalized Jacobian at (y, lambda)
    repeat:
        converged when |G_free| <= rtol * force scale (or the update is
            below increment_tol) and the contact tolerances hold (the
            penetration and the open gap under force, as the Uzawa loop's)
        polish: once the tolerances hold and |G_free| <= POLISH_BELOW *
            force scale, the multipliers are held and Newton finishes on G
        solve [[K, dG/dl], [dC/dy, dC/dl]] (dy, dl) = -(G, C)
        line search on the merit |(G_free, C)| (|G_free| when polishing):
            alpha = 1 (spin cap), halved until Armijo's decrease holds; in
            the first two iterations the largest trial below max_growth
            times the merit (plain Newton's safeguard); at most ESCAPES
            times a solve the same against the merit (a kink of C)
        y <- y (+) alpha dy,  lambda <- lambda + alpha dl
"""
import time
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .contact.friction_assembly import LAWS, coulomb_misfit, multiplier_updates
from .kinematics import ElementRotationError
from .problem import CORRECT_ABOVE, Increment, Iterate, Report, State, at_floor
from .problem import clearance_ok
from .problem import position_correction, settled, spin_cap, start, update_size
from .problem import failed as _fail

#: Armijo's sufficient decrease of the merit |(G, C)| per unit step
ARMIJO = 1e-4
#: the active rows' ``dC/dlambda`` is ``-REGULARIZATION w`` instead of 0:
#: both slave passes see a contact (each side's Gauss points are slaves),
#: so the active constraints are nearly dependent (50 active rows of rank
#: about 25 in the rotational-friction scene) and the exact generalized
#: Jacobian is singular; the residual stays exact, so the converged state
#: is the exact one, the rate in the multipliers is linear with about this
#: factor
REGULARIZATION = 1e-3
#: the multipliers are held (Newton polishes at them) once the contact
#: tolerances hold and ``|G_free|`` is below this times the force scale
POLISH_BELOW = 1e-4
#: steps a solve may take against the merit (see contact_newton)
ESCAPES = 2
#: iterates whose largest merit the line search compares with (1: monotone)
MEMORY = 1


@dataclass
class ContactState:
    """Residuals and the generalized Jacobian's contact blocks at an
    evaluation (:func:`contact_blocks`; the blocks None without the
    Jacobian).  The multiplier unknowns are one vector (:func:`unknowns`):
    the normal ones, then the friction ones of each law in
    :func:`friction_laws` (3 per slave point), then (``crossing``) one per
    crossing pair of the evaluation; ``active`` marks those that
    join the linear system (the normal multipliers where the law is active,
    the friction multipliers of the points in contact), the others are
    condensed (``-w dlambda = -C``).  ``D`` is the exact ``dC/dlambda``,
    ``D_reg`` the one solved with (the active rows regularized)."""
    G: np.ndarray
    C: np.ndarray
    K_ly: object
    K_yl: object
    D: object
    D_reg: object
    active: np.ndarray
    penetration: float
    opened: float
    merit: float
    #: how far the friction multipliers are from their update, relative to
    #: the Coulomb bound (the Uzawa loop's ``friction_moved``; 0 without)
    friction_moved: float = 0.0
    #: the slipping points' forces across their slips, relative to the
    #: bound (the Uzawa loop's ``coulomb_misfit``; 0 without, and at the
    #: line search's trials, evaluated without the Jacobian)
    friction_misfit: float = 0.0


class Merit(NamedTuple):
    """What the line search compares a trial's merit with: the last
    iterate's ``last``, the ``reference`` of Armijo's test, the force
    ``scale``, the ``weight`` of ``C`` in the merit (0 when polishing) and
    ``first`` (the step's first iterations: plain Newton's safeguard)."""
    last: float
    reference: float
    scale: float
    weight: float
    first: bool


def friction_laws(problem):
    """The friction laws whose multipliers are unknowns: inside
    ``Problem.friction_unknowns`` (``contact_solve="newton"``), those with
    a coefficient above zero, as ``(attribute, output suffix)``; none with
    ``"newton_normal"`` (the Uzawa loop updates them between solves)."""
    if not (problem.friction and problem.friction_jacobian):
        return ()
    c = problem.contact
    return tuple((name, X) for name, coef, X in LAWS if getattr(c, coef) > 0)


def crossing_friction_unknowns(problem):
    """True when the crossing pairs' friction multipliers are unknowns:
    the tangential law's multipliers are (:func:`friction_laws`) and the
    crossing pairs carry it (contact option ``crossing_friction``)."""
    return bool(problem.contact.crossing_friction) and any(
        name == "tangential" for name, _ in friction_laws(problem))


def unknowns(problem, pairs=None):
    """The multiplier unknowns as one vector: normal, then friction, then
    (``pairs``: the crossing pairs of the current evaluation) the crossing
    pairs' multipliers, carried by place to those pairs, then their
    friction multipliers (3 per pair, :func:`crossing_friction_unknowns`)."""
    m = problem.multipliers
    parts = [m.normal] + [getattr(m, name).ravel() for name, _ in friction_laws(problem)]
    if pairs is not None:
        from .contact.crossing import carry
        parts.append(carry(m.crossing_key, m.crossing, pairs.key))
        if crossing_friction_unknowns(problem):
            parts.append(m.crossing_frictions(pairs.key).ravel())
    return np.concatenate(parts)


def set_unknowns(problem, x, pairs=None):
    """The multipliers of ``problem`` from the vector ``x`` of
    :func:`unknowns` (the crossing multipliers keyed to ``pairs``)."""
    m = problem.multipliers
    ns = m.normal.size
    m.normal = x[:ns].copy()
    laws = friction_laws(problem)
    for k, (name, _) in enumerate(laws):
        setattr(m, name, x[ns + 3 * ns * k:ns + 3 * ns * (k + 1)].reshape(ns, 3).copy())
    if pairs is not None:
        start_c = ns + 3 * ns * len(laws)
        k = pairs.size
        friction = x[start_c + k:start_c + 4 * k].reshape(k, 3).copy() \
            if crossing_friction_unknowns(problem) else None
        m.rekey_crossing(pairs.key.copy(), x[start_c:start_c + k].copy(),
                         offset=m.crossing_offsets(pairs.key), friction=friction)


def contact_blocks(problem, ev, jacobian=True, weight=1.0, crossing=False):
    """The complementarity residual ``C`` and the blocks ``dC/dy``,
    ``dG/dlambda`` (in the dof basis), ``dC/dlambda`` at the evaluation
    ``ev`` of ``problem`` (multipliers: ``problem.multipliers``, ordered as
    :func:`unknowns`, with the crossing pairs of ``ev`` when ``crossing``);
    the merit is ``|(G_free, weight C)|`` (weight 0 when polishing).  The
    penetration and open gap include the crossing pairs' with
    ``crossing``.

    Friction (docs/contact-solve.md): ``C_X = w (c_X - lambda_X)`` per slave
    point, ``c_X`` the Uzawa update of the law's multiplier (the force
    pulled back to the last converged state, ``multiplier_T`` /
    ``multiplier_R`` of the friction output); ``-w lambda_X`` at points
    without a normal force."""
    c, m = problem.contact, problem.multipliers
    laws = friction_laws(problem)
    ns = m.normal.size
    # the pairs live on the contact curve (the rod's centreline, or the
    # smooth curve of contact/curve.py, whose dofs map to the rod's)
    cc = problem.contact_curve
    cmesh = problem.mesh if cc is None else cc.mesh
    n = cmesh.n_dofs
    w_all = problem.slaves.w.ravel()
    ce = ev.contact
    pairs = ce.pairs
    lam = m.normal
    fN = np.zeros(ns)
    fN[pairs.slave] = ce.fN
    Cs = [w_all * (fN - lam)]
    fr = ce.friction
    moved = 0.0
    if laws:
        updates, moved = multiplier_updates(fr, m, c, [name for name, _ in laws])
        for name, _ in laws:
            Cs.append((w_all[:, None] * (updates[name] - getattr(m, name))).ravel())
    cp = ce.crossing if crossing else None
    cf = None                              # crossing friction among the unknowns
    if cp is not None:
        from .contact.crossing import carry
        lam_c = carry(m.crossing_key, m.crossing, cp.key)
        Cs.append(ce.crossing_fN - lam_c)
        if crossing_friction_unknowns(problem):
            # C = c - lambda per pair (a point force, as the normal rows),
            # c the Uzawa update of the pair's multiplier (0 without force)
            from .contact.friction_assembly import crossing_updates
            cf = ce.crossing_friction
            lam_cf = m.crossing_frictions(cp.key)
            upd, cmoved = crossing_updates(cf, cp.size, lam_cf, c.gamma_T)
            moved = max(moved, cmoved)
            Cs.append((upd - lam_cf).ravel())
    C = np.concatenate(Cs)
    # the Uzawa loop's Coulomb test: at a point whose slip is just above
    # its tolerance the force's direction is sensitive to the multiplier
    # (a multiplier 4e-5 gamma f_N off its update turned forces by 0.03
    # rad in the knot), so the polish waits for it too (read at the
    # iterates, not at the line search's trials)
    misfit = (coulomb_misfit(fr, problem.friction_params(), c.friction_tolerance)
              if laws and jacobian else 0.0)
    if cf is not None and jacobian:
        misfit = max(misfit, coulomb_misfit(cf, problem.crossing_friction_params(),
                                            c.friction_tolerance))
    # the contact tolerances' measures, as the Uzawa loop reads them
    pen, opened = ce.violations()
    d, dc = ce.gap, ce.crossing_gap
    mu = c.penalty / m.penalty_scale[pairs.slave]
    act = (d + mu * lam[pairs.slave]) > 0
    active = np.zeros(C.size, bool)
    active[pairs.slave[act]] = True
    fslaves = fr.slave if laws else np.zeros(0, int)
    for k in range(len(laws)):
        active[(ns + 3 * ns * k + 3 * fslaves[:, None] + np.arange(3)).ravel()] = True
    nf = ns + 3 * ns * len(laws)                 # where the crossing block starts
    if cp is not None:
        mu_c = problem.crossing_compliance()
        act_c = (dc + mu_c * lam_c) > 0
        active[nf + np.flatnonzero(act_c)] = True
    G = ev.residual
    # C in units of G's tolerance: w tol / mu per point (the gap tolerance
    # of the Uzawa loop as a force) against rtol times the force scale
    Cw = weight * C
    merit = float(np.sqrt(problem.residual_norm(ev) ** 2 + np.dot(Cw, Cw)))
    if not jacobian:
        return ContactState(G, C, None, None, None, None, active, pen, opened, merit, moved,
                            misfit)
    # dl = delta l over the 24 position dofs of the pair (assembly.py)
    from .element import shape_functions
    k = np.flatnonzero(act)
    Ns, _, _ = shape_functions(pairs.s_xi[k])
    Nm, _, _ = shape_functions(pairs.m_xi[k])
    P = np.concatenate([Ns.T, -Nm.T], axis=1)                       # (a, 8)
    b = (P[:, :, None] * pairs.normal[k][:, None, :]).reshape(k.size, 24)
    nodes = np.concatenate([cmesh.nodes[pairs.s_elem[k]],
                            cmesh.nodes[pairs.m_elem[k]]], axis=1)
    dofs = (6 * nodes[:, :, None] + np.arange(3)).reshape(k.size, 24)
    sl = pairs.slave[k]
    w = pairs.weight[k]
    nl = C.size
    cols = np.repeat(sl, 24)
    yl = [((-w[:, None] * b).ravel(), dofs.ravel(), cols)]
    ly = [((-(w / mu[k])[:, None] * b).ravel(), cols, dofs.ravel())]
    # dC/dlambda: -w where the normal law is inactive (0 where active),
    # -w I for the friction multipliers of points out of contact
    diag = np.where(active[:ns], 0.0, -w_all)
    diags = [diag] + [np.repeat(-w_all, 3)] * len(laws)
    # the part of dC/dlambda the active rows are regularized with
    # (-REGULARIZATION w times the update's own derivative dc/dlambda)
    reg = [(np.where(active[:ns], -REGULARIZATION * w_all, 0.0), np.arange(ns), np.arange(ns))]
    cross_dd = []                               # the crossing friction's dC/dlambda
    if cp is not None:
        # C_c = w f_N - lambda, f_N = [d + mu lambda]_+ / mu, d = 2 eps +
        # w offset - l: active, dC/dlambda = w - 1 and dC/dy = -(w / mu)
        # dl + (f_N + w offset / mu) dw/dq, dG/dlambda = -w dl; inactive,
        # dC/dlambda = -1
        from .contact.crossing import gap_gradients
        wc = cp.weight
        diags.append(np.where(act_c, wc - 1.0, -1.0))
        rows_c = nf + np.arange(cp.size)
        reg.append((np.where(act_c, -REGULARIZATION, 0.0), rows_c, rows_c))
        kc = np.flatnonzero(act_c)
        if kc.size:
            cdofs, dl_c = gap_gradients(cmesh, cp)
            cdofs, dl_c = cdofs[kc], dl_c[kc]
            ccols = np.repeat(rows_c[kc], 24)
            yl.append(((-wc[kc, None] * dl_c).ravel(), cdofs.ravel(), ccols))
            ly.append(((-(wc[kc] / mu_c)[:, None] * dl_c).ravel(), ccols, cdofs.ravel()))
            if ce.crossing_dw is not None and ce.crossing_dw.nnz:
                # the weight's own derivative (a fading pair): d(w f_N)/dw
                # = f_N + w f_N' offset along dw/dq
                off_c = ce.crossing_offset
                coef = np.zeros(cp.size)
                coef[kc] = ce.crossing_fN[kc] / wc[kc] + wc[kc] * off_c[kc] / mu_c
                Wq = ce.crossing_dw.tocoo()
                ly.append((coef[Wq.row] * Wq.data, nf + Wq.row, Wq.col))
        xf = ce.crossing_friction
        if xf is not None and xf.dresidual_dfN is not None and xf.index.size:
            # friction at the crossing pairs, through the Coulomb radius:
            # df_N/dlambda_c = 1 at its pairs (f_N > 0: active)
            fd, fv = xf.dresidual_dfN
            yl.append((fv.ravel(), fd.ravel(), np.repeat(rows_c[xf.slave], 48)))
        if cf is not None:
            _crossing_friction_blocks(cf, cp, ce, rows_c, nf + cp.size, act_c, mu_c,
                                      active, diags, cross_dd, reg, yl, ly)
    dd = [(np.concatenate(diags), np.arange(nl), np.arange(nl))] + cross_dd
    if fr is not None and fr.dresidual_dfN is not None and fr.index.size:
        # friction pairs are the pairs with f_N > 0 (all active)
        fd, fv = fr.dresidual_dfN
        yl.append((fv.ravel(), fd.ravel(), np.repeat(fr.slave, 48)))
    if laws and fr.index.size:
        J = fr.jacobian
        if J is None:
            raise RuntimeError("the friction output has no multiplier Jacobian: evaluate "
                               "inside Problem.friction_unknowns()")
        wf = w_all[fr.slave]
        ar3 = np.arange(3)
        for kk, (name, X) in enumerate(laws):
            base = ns + 3 * ns * kk + 3 * fr.slave                  # (mf,)
            lrow = base[:, None] + ar3                              # (mf, 3)
            rows_X = wf[:, None, None] * getattr(J, "rows_" + X)    # (mf, 3, 48)
            ly.append((rows_X.ravel(), np.repeat(lrow.ravel(), 48),
                       np.tile(J.dofs, (1, 3)).ravel()))
            cols_X = getattr(J, "cols_" + X)                        # (mf, 48, 3)
            yl.append((cols_X.ravel(), np.repeat(J.dofs.ravel(), 3),
                       np.tile(lrow, (1, 48)).ravel()))
            own = wf[:, None, None] * getattr(J, "self_" + X)       # (mf, 3, 3)
            # dC/dlambda = w (dc/dlambda - I): the -w I is in dd already
            dd.append((own.ravel(), np.repeat(lrow, 3, axis=1).ravel(),
                       np.tile(lrow, (1, 3)).ravel()))
            reg.append(((-REGULARIZATION * own).ravel(), np.repeat(lrow, 3, axis=1).ravel(),
                        np.tile(lrow, (1, 3)).ravel()))
            # through the Coulomb radius: dc/df_N, df_N/dlambda_N = 1 (active)
            dd.append(((wf[:, None] * getattr(J, "normal_" + X)).ravel(), lrow.ravel(),
                       np.repeat(fr.slave, 3)))

    def coo(parts, shape):
        v, i, j = (np.concatenate(a) for a in zip(*parts))
        return sp.coo_matrix((v, (i, j)), shape=shape)

    K_yl = coo(yl, (n, nl)).tocsc()
    K_ly = coo(ly, (nl, n)).tocsr()
    D = coo(dd, (nl, nl)).tocsr()
    D_reg = (D + coo(reg, (nl, nl))).tocsr()
    if cc is not None:
        K_yl, K_ly = (cc.TT @ K_yl).tocsc(), (K_ly @ cc.T).tocsr()
    if problem.T is not None:
        K_yl = problem.T.T @ K_yl
        K_ly = K_ly @ problem.T
    return ContactState(G, C, K_ly, K_yl, D, D_reg, active, pen, opened, merit, moved,
                        misfit)


def _crossing_friction_blocks(cf, cp, ce, rows_c, start, act_c, mu_c, active, diags, dd, reg,
                              yl, ly):
    """The crossing pairs' friction rows ``C = c - lambda`` (3 per pair,
    from ``start``) in the generalized Jacobian's parts (appended in
    place): ``dC/dlambda = dc/dlambda - I`` (``-I`` alone at pairs without
    force, condensed), ``dC/dy`` (the kinematics' and, for a fading pair,
    the offset's share of ``f_N`` through the weight), ``dC/dlambda_c =
    dc/df_N`` where the normal law is active, and ``dG/dlambda``."""
    diags.append(np.full(3 * cp.size, -1.0))
    if cf.index.size == 0:
        return
    J = cf.jacobian
    if J is None:
        raise RuntimeError("the crossing friction output has no multiplier Jacobian: "
                           "evaluate inside Problem.friction_unknowns()")
    k = cf.slave                                               # pairs with f_N > 0
    lrow = start + 3 * k[:, None] + np.arange(3)               # (mf, 3)
    active[lrow.ravel()] = True
    ly.append((J.rows_T.ravel(), np.repeat(lrow.ravel(), 48), np.tile(J.dofs, (1, 3)).ravel()))
    yl.append((J.cols_T.ravel(), np.repeat(J.dofs.ravel(), 3), np.tile(lrow, (1, 48)).ravel()))
    own = J.self_T
    dd.append((own.ravel(), np.repeat(lrow, 3, axis=1).ravel(), np.tile(lrow, (1, 3)).ravel()))
    reg.append(((-REGULARIZATION * own).ravel(), np.repeat(lrow, 3, axis=1).ravel(),
                np.tile(lrow, (1, 3)).ravel()))
    on = act_c[k]
    dd.append((J.normal_T[on].ravel(), lrow[on].ravel(), np.repeat(rows_c[k[on]], 3)))
    if ce.crossing_dw is not None and ce.crossing_dw.nnz:
        # f_N(2 eps + w offset - l): dc/df_N f_N' offset dw/dq
        coef = np.zeros((cp.size, 3))
        coef[k[on]] = J.normal_T[on] * (ce.crossing_offset[k[on]] / mu_c)[:, None]
        Wq = ce.crossing_dw.tocoo()
        for a in range(3):
            ly.append((coef[Wq.row, a] * Wq.data, start + 3 * Wq.row + a, Wq.col))


def contact_states(problem, ev, cs):
    """Per slave point, its state at the evaluation ``ev``: the normal law
    active or not, and the state (open / stick / slip) of each friction
    law; one integer row per slave (what :attr:`Report.switches` counts)."""
    ns = problem.multipliers.normal.size
    cols = [cs.active[:ns].astype(int)]
    fr = ev.contact.friction
    if fr is not None:
        for st in (fr.state_T, fr.state_R):
            full = np.zeros(ns, int)
            full[fr.slave] = st
            cols.append(full)
    return np.stack(cols, axis=1)


def solve_step(problem, ev, cs, remaining, fixed_multipliers=False):
    """The generalized Newton update ``(dy, dlambda)`` (``dy`` takes the
    prescribed ``remaining`` on the supported dofs); ``dlambda = 0`` and
    plain Newton on ``G`` with ``fixed_multipliers``."""
    n = problem.mesh.n_dofs
    if fixed_multipliers:
        dy = problem.factor(ev.tangent)(-cs.G - ev.tangent @ remaining)
        dy[problem.fixed] = remaining[problem.fixed]
        return dy, np.zeros_like(cs.C)
    fixed = problem.fixed
    K = ev.tangent.tocsc(copy=True)
    cols = np.repeat(np.arange(n), np.diff(K.indptr))
    rows = K.indices
    kill = fixed[rows] | fixed[cols]
    K.data[kill] = 0.0
    K.data[kill & (rows == cols)] = 1.0
    # the inactive rows are -w dlambda = -C alone (no dy, no column in G,
    # no coupling): dlambda = -lambda there; the active multipliers join
    # the system
    act = np.flatnonzero(cs.active)
    out = ~cs.active
    dl = np.zeros_like(cs.C)
    dl[out] = -cs.C[out] / cs.D.diagonal()[out]
    free = sp.diags(np.where(fixed, 0.0, 1.0))
    K_ly_act = cs.K_ly.tocsr()[act]
    K_yl = free @ cs.K_yl.tocsc()[:, act]
    K_ly = K_ly_act @ free
    A = sp.bmat([[K, K_yl], [K_ly, cs.D_reg[act][:, act]]], format="csc")
    rhs_y = -cs.G - ev.tangent @ remaining
    rhs_y[fixed] = 0.0
    rhs_l = -cs.C[act] - K_ly_act @ remaining
    t0 = time.perf_counter()
    # the band ordering of Problem.factor (contact couples distant stretches
    # of the rod), kept while the pattern stays; SuperLU's partial pivoting
    # takes the zero diagonal of the active rows
    Ap, p = problem.bordered_pattern.prepare(A)
    lu = spla.splu(Ap, permc_spec="NATURAL")
    problem.timers["factorization"] += time.perf_counter() - t0
    problem.calls["factor"] += 1
    x = np.empty(A.shape[0])
    x[p] = lu.solve(np.concatenate([rhs_y, rhs_l])[p])
    dy = x[:n]
    dy[fixed] = remaining[fixed]
    dl[act] = x[n:]
    return dy, dl


def contact_newton(problem, r, R, lam, opts, prescribed=None):
    """See :func:`_contact_newton`; with ``contact_solve="newton"`` the
    friction multipliers are unknowns too (the evaluations inside
    ``Problem.friction_unknowns`` carry their Jacobian).  A solve that
    fails puts the multipliers back as they were."""
    saved = problem.multipliers.copy()
    with problem.crossing_unknowns():
        if opts.contact_solve == "newton_normal":
            out = _contact_newton(problem, r, R, lam, opts, prescribed)
        else:
            with problem.friction_unknowns():
                out = _contact_newton(problem, r, R, lam, opts, prescribed)
    if not out[3].converged:
        # a failed solve leaves the multipliers as it found them (the
        # gradient flow falls back on its own state at those)
        restore(problem.multipliers, saved)
    return out


def restore(m, saved):
    """Put the multipliers ``m`` back to the copy ``saved``, in place
    (callers hold ``m``); ``saved`` stays untouched (an evaluation
    updates the crossing places in place)."""
    fresh = saved.copy()
    for f in fields(m):
        setattr(m, f.name, getattr(fresh, f.name))


def _contact_newton(problem, r, R, lam, opts, prescribed=None):
    """Generalized Newton on ``(y, lambda_N)`` at load factor ``lam`` from
    ``(r, R)`` and the multipliers in ``problem.multipliers`` (updated in
    place).  Same call and return as :func:`skfem_rod.newton.newton`
    (without continuation); ``report.history`` holds ``|G_free|`` per
    iteration (as plain Newton's), ``report.complementarity`` ``|C|`` and
    ``report.polished_from`` the iteration from which the multipliers were
    held (the contact tolerances met; None if never), ``report.step_lengths``
    the line search's ``alpha`` per iteration."""
    c, m = problem.contact, problem.multipliers
    # the crossing pairs' multipliers are unknowns too (crossing contact on)
    crossing = bool(c.crossing)
    history, complementarity, alphas, merits, switches = [], [], [], [], []
    states = None
    tol = c.tolerance * c.radius
    last_update, polish, polished_from, escapes = np.inf, False, None, 0
    remaining, ev, why = start(problem, r, R, lam, prescribed)
    if ev is None:
        return _fail(r, R, lam, history, 0, why)
    # the polish's iterate of least |G_free| (the multipliers held there, so
    # they are its own): accepted at its round-off floor when the solve
    # cannot go on, as plain Newton's (problem.at_floor)
    best = None

    def give_up(it, reason):
        return at_floor(problem, best, history) or _fail(r, R, lam, history, it, reason, ev)
    for it in range(opts.max_iterations + 1):
        scale = problem.force_scale(ev)
        if not (np.isfinite(scale) and np.all(np.isfinite(ev.residual))):
            return _fail(r, R, lam, history, it, "non-finite residual or forces", ev)
        cs = contact_blocks(problem, ev, weight=0.0 if polish else 1.0, crossing=crossing)
        pairs = ev.contact.crossing if crossing else None
        rn = problem.residual_norm(ev)
        history.append(rn)
        complementarity.append(float(np.linalg.norm(cs.C)))
        now = contact_states(problem, ev, cs)
        switches.append(0 if states is None else int(np.any(now != states, axis=1).sum()))
        states = now
        merits.append(cs.merit)
        tolerances = (cs.penetration <= tol and cs.opened <= tol
                      and max(cs.friction_moved, cs.friction_misfit) <= c.friction_tolerance)
        if not np.any(remaining) and (tolerances or polish) and \
                settled(history, last_update, opts.rtol * scale, opts.increment_tol):
            return r, R, lam, Report(True, iterations=it, history=history, evaluation=ev,
                                     complementarity=complementarity,
                                     polished_from=polished_from, step_lengths=alphas,
                                     switches=switches)
        if it == opts.max_iterations:
            break
        # the contact tolerances hold: the multipliers are kept, Newton
        # polishes the equilibrium at them (the Uzawa loop's last pass)
        polish = polish or (tolerances and not np.any(remaining)
                            and rn <= POLISH_BELOW * scale)
        if polish and polished_from is None:
            polished_from, merits = it, [rn]
        if polish and not np.any(remaining) and (best is None or rn < best.rn):
            best = Iterate(rn, r, R, lam, ev)
        try:
            dy, dl = solve_step(problem, ev, cs, remaining, polish)
        except RuntimeError as err:
            return _fail(r, R, lam, history, it, f"singular generalized Jacobian ({err})", ev)
        if not (np.all(np.isfinite(dy)) and np.all(np.isfinite(dl))):
            return _fail(r, R, lam, history, it, "non-finite Newton update", ev)
        merit = Merit(merits[-1], max(merits[-MEMORY:]), scale, 0.0 if polish else 1.0,
                      it < 2 or bool(np.any(remaining)))
        at, inc = State(r, R, lam), Increment(dy, dl)
        accepted, alpha, why = line_search(problem, at, inc, merit, opts, pairs)
        if accepted is None and escapes < ESCAPES:
            # a kink of C between the iterate and every trial (a contact
            # that must open seen from its active branch): take the largest
            # admissible trial, at most ESCAPES times a solve (so no cycle)
            accepted, alpha, why = line_search(problem, at, inc, merit._replace(first=True),
                                               opts, pairs)
            escapes += 1
        if accepted is None and tolerances and not polish and not np.any(remaining):
            # the merit cannot fall below the mismatch of the two slave
            # passes' gaps: hold the multipliers, polish G
            polish = True
            continue
        if accepted is None:
            return give_up(it + 1,
                           f"no admissible update after {opts.max_backtracks} halvings: {why}")
        r, R, ev, x = accepted
        set_unknowns(problem, x, pairs)
        if ev.tangent is None:
            ev = problem.evaluate(r, R, lam)
        alphas.append(alpha)
        # the multipliers' update as the gap it moves (their compliance),
        # in rod lengths: per unit length at the slave points, a point
        # force at the crossing pairs
        compliance = np.full(dl.size, c.penalty)
        if pairs is not None and pairs.size:
            start_c = m.normal.size * (1 + 3 * len(friction_laws(problem)))
            compliance[start_c:start_c + pairs.size] = problem.crossing_compliance()
            compliance[start_c + pairs.size:] = problem.crossing_friction_params().mu_T
        gaps = np.abs(alpha * dl) * compliance
        last_update = max(update_size(problem, alpha * dy),
                          float(gaps.max(initial=0.0)) / problem.rod.length)
        remaining = remaining * (1.0 - alpha)
        remaining[np.abs(remaining) < 1e-300] = 0.0
    return give_up(opts.max_iterations, f"no convergence in {opts.max_iterations} iterations "
                                        f"(merit {history[-1]:.3e})")


def line_search(problem, at, inc, merit, opts, pairs=None):
    """Backtracking on the merit ``|(G_free, weight C)|`` from the
    :class:`~skfem_rod.problem.State` ``at`` along the
    :class:`~skfem_rod.problem.Increment` ``inc`` (``dl``: the normal
    multipliers' update), compared with the :class:`Merit` ``merit``;
    returns ``((r, R, evaluation, lambda_N) or None, alpha, why)``.

    Armijo's test against ``reference``, the largest merit of the last
    :data:`MEMORY` iterates (``MEMORY = 1``: monotone; a memory of 4, the
    non-monotone test of Grippo, Lampariello & Lucidi 1986, let the
    rotational-friction scene 2-cycle 8.6e-3 <-> 4.3e-3 for 6 iterations at
    a stick/slip switch, each return a hair below the memory's maximum).
    A trial above :data:`CORRECT_ABOVE` times ``last`` (the last merit) gets
    plain Newton's position correction first.  When no halving passes:
    ``first`` (the step's first iterations, the prescribed motion being
    applied) takes the largest trial whose merit is below ``max_growth``
    times the reference (plain Newton's safeguard: a stiff rod's first
    update can raise the residual, and the next one converges); otherwise
    the lowest trial below the reference, else none.

    Every trial is evaluated from the contact search's memory at ``at``
    (:meth:`~skfem_rod.problem.Problem.search_memory`, as in plain
    Newton's :func:`~skfem_rod.newton.safeguarded_update`); the memory is
    left as the returned trial's evaluation left it, or as it was where
    none is returned.
    """
    lam0 = unknowns(problem, pairs)
    saved = problem.multipliers.copy()
    memory = problem.search_memory()
    r, R, lam = at
    dy, dl = inc
    reference, weight = merit.reference, merit.weight
    alpha, why = 1.0, "the merit did not fall"
    if opts.line_search:
        alpha = spin_cap(dy, opts.max_spin_update)
    alpha0 = alpha
    bound = opts.max_growth * max(reference, merit.scale)
    best = None
    cap = opts.clearance_cap
    for _ in range(opts.max_backtracks + 1):
        lam_t = lam0 + alpha * dl
        try:
            r_t, R_t = problem.update(r, R, dy, alpha)
            if cap and not clearance_ok(problem.rod, r, r_t):
                why = "the update would carry a strand through another"
                alpha *= 0.5
                continue
            # the state's memory first: with crossing pairs, set_unknowns
            # re-keys them, and the re-keyed pairs follow from their keys
            problem.restore_search(memory)
            set_unknowns(problem, lam_t, pairs)
            # the first trial is usually taken: its tangent is the next
            # iteration's; halved trials get theirs once taken
            ev_t = problem.evaluate(r_t, R_t, lam, tangent=alpha == alpha0)
            mt = contact_blocks(problem, ev_t, jacobian=False, weight=weight,
                                crossing=pairs is not None).merit
            if np.isfinite(mt) and opts.position_correction and mt > CORRECT_ABOVE * merit.last:
                # as plain Newton (skfem_rod.problem.position_correction)
                if ev_t.tangent is None:
                    ev_t = problem.evaluate(r_t, R_t, lam)
                r_t, ev_t = position_correction(problem, r_t, R_t, lam, ev_t)
                mt = contact_blocks(problem, ev_t, jacobian=False, weight=weight,
                                    crossing=pairs is not None).merit
        except ElementRotationError as err:
            why = str(err)
            alpha *= 0.5
            continue
        finally:
            restore(problem.multipliers, saved)
        if not np.isfinite(mt):
            why = "non-finite residual"
        else:
            trial = ((r_t, R_t, ev_t, lam_t), alpha, "")
            if not opts.line_search or mt <= (1 - ARMIJO * alpha) * reference:
                return trial
            if merit.first and mt <= bound:
                return trial
            if mt < reference and (best is None or mt < best[0]):
                best = (mt, trial, problem.search_memory())
        alpha *= 0.5
    if best is not None:
        problem.restore_search(best[2])
        return best[1]
    problem.restore_search(memory)
    return None, alpha, why
