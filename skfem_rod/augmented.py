r"""The augmented-Lagrangian loop of contact and friction (the paper's Uzawa
iteration, sec. 4 and 6): the one outer loop around any inner solve --
Newton at a load step, a continuation corrector, the gradient flow.

In plain sight::

    multipliers saved
    pass 0: inner solve at fixed multipliers
    repeat:
        penetration  = max d          (d = 2 eps - distance, slave points)
        open gap under force, friction multipliers' movement
        done when all three are below their tolerances, or max_uzawa passes
        lambda_N <- [lambda_N + d / mu_N]_+ ;  lambda_T, lambda_R <- f_T, f_R
        adapt the penalty where a violation did not drop (Bertsekas; per
            slave point, one factor for friction, one for the crossing pairs)
        next pass: inner solve from the last converged state
    the next step's loop starts at the normal penalty reached (penalty_memory);
        a first pass failing with it is solved again at the nominal one
    a later pass failing (rescue given, once): again from the last
        converged pass at the nominal penalty, by the generalized Newton
        (load steps) or by the inner solve itself (:func:`step`)
    failed inner solve: multipliers restored, failure returned; a state
        on the way (strict=False, the damped steps) keeps the last
        converged pass after an update instead, as at max_uzawa
    at the end: where a penalty factor was raised, lambda_N (crossing
        lambda) <- the force the last pass applied (eq. 4.2a's update
        there), then the factors back to 1 (:func:`fold_forces`)

The penalty adapts as in the method of multipliers (:func:`adapt_penalty`):
where a point's violation did not drop by a factor 4 over an update, its
penalty stiffness grows by ``penalty_growth`` for the rest of the step;
with the option ``penalty_memory`` the next step starts from there, else
every step starts at the nominal penalty.  The converged answer is that
of the fixed penalty to the tolerances; only the path to it changes.
"""
import numpy as np

from .contact.friction_assembly import coulomb_misfit, crossing_updates, multiplier_updates
from .contact import OVERLAP_FAIL
from .contact.law import uzawa_update

#: the adaptive penalty raises the penalty at a point whose violation did
#: not drop below this fraction of the last one (Bertsekas' 0.25)
PENALTY_DROP = 0.25


#: offset rounds per loop (:func:`adjust_offsets`): passes at raised gap
#: offsets after the contact tolerances hold at the slave points while the
#: centrelines overlap by more than the tolerance between them
OFFSET_ROUNDS = 5
#: a pass that fails after an adjustment is tried again from the last
#: converged pass with half the change, at most this many times
OFFSET_HALVINGS = 2


def augmented_lagrangian(problem, solve_pass, rescue=None, strict=True):
    """Uzawa updates of the contact (and friction) multipliers of
    ``problem`` around ``solve_pass``.

    Parameters
    ----------
    problem : :class:`skfem_rod.problem.Problem`
    solve_pass : callable ``previous -> (r, R, lam, report)``: the inner
        solve at the current multipliers; ``previous`` is None on the first
        pass, else the ``(r, R, lam)`` the last pass converged to.
    rescue : callable ``(previous, kept) -> (r, R, lam, report)``,
        optional: solves from the last converged pass when a later pass
        fails (the multipliers as the failed pass left them, the penalty
        back at the nominal one; ``kept`` the multipliers that pass
        converged with); the loop goes on from its state.  Once per loop.
    strict : the state is an equilibrium to record (load steps, the
        polish, the gradient flow): where the contact tolerances hold at
        the slave points but the centrelines overlap by more than the
        tolerance between them, the gap offsets are raised
        (:func:`adjust_offsets`, at most :data:`OFFSET_ROUNDS` times) and the
        loop goes on; a true overlap beyond the tolerance at the end fails
        the step.  False (the damped steps of the pseudo-dynamics, states
        on the way): only an overlap beyond :data:`OVERLAP_FAIL` fails,
        and a later pass that fails (after the rescue) leaves the last
        converged pass after an update as the answer, as ``max_uzawa``
        would.

    Returns
    -------
    ``(r, R, lam, report)`` of the last pass, with the loop's figures in the
    report (``uzawa``, ``newton_total``, ``penetration``,
    ``uzawa_converged``, ``uzawa_note``, ``penalty_scale``).  On a failed
    inner solve the multipliers are put back as they were.
    """
    c = problem.contact
    if c is None:
        return solve_pass(None)
    saved = problem.multipliers.copy()
    if strict and c.offsets == "state":
        # the gap offsets of an equilibrium to record are the state's: they
        # start from 0 at every step and are raised where its strands dip
        # (a carried offset is lowered only where the strands stand open by
        # more than the tolerance, so it remembers the path; contact option
        # offsets)
        m = problem.multipliers
        m.offset = np.zeros_like(m.offset)
        m.crossing_offset = np.zeros_like(m.crossing_offset)
    carried = carry_penalty(problem)
    total, uzawa = 0, 0
    last = np.full(problem.multipliers.normal.size, np.inf)   # last violation in contact
    last_moved = last_crossing = np.inf
    previous = None
    rounds, lift, fallback, halvings, stood_open = 0, None, None, 0, 0.0
    rescued = ""                   # the reason of the pass the rescue solved again
    passed = None                  # the last converged pass (not strict: kept on failure)
    while True:
        r, R, lam, rep = solve_pass(previous)
        total += rep.iterations
        if not rep.converged and carried and previous is None:
            # the carried penalty is a warm start, not part of the problem:
            # a first pass that fails with it (a stiff contact under a large
            # prescribed motion) is solved again at the nominal penalty
            problem.multipliers, carried = saved.copy(), False
            continue
        if not rep.converged and rescue is not None and previous is not None:
            # the multipliers converge too slowly for the pass's Newton: the
            # penalty grown where Uzawa stalled (double-sided contact along
            # plies: see rescue in step) made it diverge
            problem.multipliers = problem.multipliers.nominal_penalty()
            why = rep.reason
            r, R, lam, rep = rescue(previous, passed_with)
            total += rep.iterations
            rescue = None
            if rep.converged:
                rescued = why
        if not rep.converged and fallback is not None and halvings < OFFSET_HALVINGS:
            # a pass after the offsets were adjusted failed: again from the
            # last pass that held the contact tolerances, half the change
            halvings += 1
            kept, target = fallback[4], problem.multipliers
            problem.multipliers = kept.copy()
            problem.multipliers.offset = 0.5 * (kept.offset + target.offset)
            if kept.crossing_offset.size == target.crossing_offset.size:
                problem.multipliers.crossing_offset = 0.5 * (kept.crossing_offset
                                                             + target.crossing_offset)
            continue
        if not rep.converged and fallback is not None:
            # still failing: the last pass that held the contact tolerances
            # is the answer if its true distance holds too (finish judges
            # it); where a point stood open under force, the report says so
            r, R, lam, rep, problem.multipliers, pen, opened = fallback
            rep.newton_total, rep.offset_rounds, rep.rescued = total, rounds - 1, rescued
            if stood_open:
                rep.uzawa_note = (f"points carried force with gap offsets where the "
                                  f"strands stood {stood_open / c.radius:.3g} eps apart "
                                  f"(the offsets could not be lowered)")
            finish(problem, r, rep, opened, saved, strict)
            return r, R, lam, rep
        if not rep.converged and passed is not None and not strict:
            # a state on the way (a damped step): the last converged pass
            # is kept, at the multipliers it converged with, as a loop
            # stopped at max_uzawa would be -- if it took an update in: a
            # step ending on its first pass ends where it started when the
            # load is held (seen at the plectoneme's 2.125 turns with a
            # variant that also stopped stalled loops, not kept: damped
            # steps at dt = 8, each the same state, each polish failing)
            why = rep.reason
            r, R, lam, rep, problem.multipliers, pen, opened = passed
            rep.newton_total, rep.uzawa_converged, rep.rescued = total, False, rescued
            finish(problem, r, rep, opened, saved, strict)
            rep.uzawa_note = "; ".join(filter(None, (
                f"a later Uzawa pass failed ({why}); the last converged pass is kept",
                rep.uzawa_note)))
            return r, R, lam, rep
        if not rep.converged:
            problem.multipliers = saved
            rep.newton_total = total
            return r, R, lam, rep
        previous, passed_with = (r, R, lam), problem.multipliers.copy()
        ce = rep.evaluation.contact
        pen, opened = ce.violations()
        d, dc = ce.gap, ce.crossing_gap
        done = pen <= c.tolerance * c.radius and opened <= c.tolerance * c.radius
        m = problem.multipliers
        crossing_friction = None               # the crossing pairs' friction update
        if problem.friction:
            updates, moved = multiplier_updates(ce.friction, m, c)
            rep.friction_misfit = coulomb_misfit(ce.friction, problem.friction_params(),
                                                 c.friction_tolerance)
            cf = ce.crossing_friction
            if cf is not None:
                crossing_friction, cmoved = crossing_updates(
                    cf, ce.crossing.size, m.crossing_frictions(ce.crossing.key), c.gamma_T)
                moved = max(moved, cmoved)
                rep.friction_misfit = max(rep.friction_misfit, coulomb_misfit(
                    cf, problem.crossing_friction_params(), c.friction_tolerance))
            rep.friction_moved = moved
            done = done and max(moved, rep.friction_misfit) <= c.friction_tolerance
        if done and strict and rounds < OFFSET_ROUNDS and needs_offsets(problem, r, rep):
            kept = problem.multipliers.copy()
            lift = adjust_offsets(problem, r, ce, lift)
            if lift is not None:
                rounds += 1              # a pass at the adjusted offsets
                rep.uzawa, rep.penetration, rep.uzawa_converged = uzawa, pen, True
                fallback, halvings = (r, R, lam, rep, kept, pen, opened), 0
                stood_open = lift[3]
                continue
        if not strict:
            rep.uzawa, rep.penetration = uzawa, pen
            if uzawa:                # a pass that took an update in (else no progress)
                passed = (r, R, lam, rep, m.copy(), pen, opened)
        if done or uzawa == c.max_uzawa:
            rep.uzawa, rep.newton_total, rep.penetration = uzawa, total, pen
            rep.uzawa_converged, rep.offset_rounds, rep.rescued = done, rounds, rescued
            finish(problem, r, rep, opened, saved, strict)
            return r, R, lam, rep
        mu = c.penalty / m.penalty_scale[ce.pairs.slave]
        new = np.zeros_like(m.normal)
        new[ce.pairs.slave] = uzawa_update(d, m.normal[ce.pairs.slave], mu)
        if c.penalty_growth > 1:
            if problem.friction:
                last_moved = adapt_friction_penalty(problem, ce.fN, new, moved, last_moved)
            last = adapt_penalty(problem, ce.pairs, d, ce.fN, new, last)
        m.normal = new
        if problem.friction:
            m.tangential, m.rotational = updates["tangential"], updates["rotational"]
        if ce.crossing is not None:
            old = carry_crossing(m, ce.crossing)
            # the force each pair applied: a fading pair gives its
            # multiplier up with its weight (docs/crossing-contact.md, 4)
            m.rekey_crossing(ce.crossing.key, ce.crossing.weight * uzawa_update(
                dc, old, problem.crossing_compliance()), friction=crossing_friction)
            if c.penalty_growth > 1:
                last_crossing = adapt_crossing_penalty(problem, ce, dc, last_crossing)
        uzawa += 1


def carry_penalty(problem):
    """Start the loop at the normal penalty factors the last step's loop
    ended with (contact option ``penalty_memory``); True if any is above
    the nominal one."""
    start = problem.penalty_start
    if not problem.contact.penalty_memory or start is None:
        return False
    problem.multipliers.penalty_scale = start.copy()
    return bool(start.max(initial=1.0) > 1.0)


def needs_offsets(problem, r, rep):
    """Whether :func:`adjust_offsets` has anything to look at: the true
    distance at ``r`` (recorded in ``rep``, :func:`true_distance`) overlaps
    by more than the tolerance, or some offset acts."""
    m = problem.multipliers
    over = true_distance(problem, r, rep)
    return bool(over > problem.contact.tolerance * problem.contact.radius
                or m.offset.max(initial=0.0) > 0 or m.crossing_offset.max(initial=0.0) > 0)


def adjust_offsets(problem, r, ce, last=None):
    """Adjust the gap offsets where the centrelines at ``r`` (contact
    evaluation ``ce``) overlap by more than the contact tolerance between
    the points that carry the contact, or stand open by more than it where
    an offset holds them apart.  Returns None when nothing was to be done,
    else ``(overlap, change, opened, gap)``: the deepest overlap before,
    the largest change, whether a point stood open and by how much.  Passed
    back as ``last`` at the next round, they give the lift a raise achieved
    (the dip rises by less than the points around it where they are not on
    it), and the raises are scaled by its inverse (at most 4).

    The slave points (and the crossing pairs' points) sample the strands:
    along a curved line contact, at a crossing between slave points, or
    where the contact curve (option ``curve="smooth"``) departs from the
    centreline under a point force, the true distance dips below the
    distance the law holds at those points.  The local minima of the strand
    distance (closest points of element pairs, both parameters free,
    :func:`skfem_rod.contact.crossing.overlaps`) within reach give each
    slave point the deepest overlap ``p`` of a minimum within an element
    length of it (on either strand), and each held crossing pair that of a
    minimum at its two places; its offset moves by ``p`` less half the
    tolerance, within ``[0, OVERLAP_FAIL eps]`` (a point with no minimum
    near it keeps its offset; :func:`finish` clears those that carry no
    force).  The points then hold the contact at
    ``2 eps + offset`` (``Multipliers.offset``, ``.crossing_offset``), which
    lifts the dip by about as much.  Minima at an end of an open rod are
    left (the slave set leaves the end caps without contact,
    :func:`at_an_end`)."""
    from .contact.crossing import overlaps
    from .contact.search import arc_distance, arclength_period
    c, m, mesh = problem.contact, problem.multipliers, problem.mesh
    tol = c.tolerance * c.radius
    cap = OVERLAP_FAIL * c.radius
    s, s_bar, p = overlaps(mesh, r, c.radius, c.exclusion, -cap - tol)
    if not mesh.closed:
        L = problem.rod.length
        inside = np.minimum(np.minimum(s, L - s), np.minimum(s_bar, L - s_bar)) > 1e-9 * L
        s, s_bar, p = s[inside], s_bar[inside], p[inside]
    vt, period = mesh.vertices, arclength_period(mesh)
    e = np.clip(np.searchsorted(vt, s, side="right") - 1, 0, vt.size - 2)
    h = (vt[e + 1] - vt[e])[:, None]                       # (k, 1)

    def close(x, y):                      # (minima, points): within h
        return arc_distance(x[None, :], y[:, None], period) <= h

    def deepest(hit):
        return np.max(np.where(hit, p[:, None], -np.inf), axis=0, initial=-np.inf)

    # slave points: the deepest minimum near each; which carry force
    xs = problem.slaves.s.ravel()
    p_s = deepest(close(xs, s) | close(xs, s_bar))
    carrying = np.zeros(m.offset.size, bool)
    carrying[ce.pairs.slave[ce.fN > 0]] = True
    # held crossing pairs: a minimum at both of their places
    key = np.asarray(m.crossing_key, float)
    pairs = key.ndim == 2 and key.shape[0] > 0 and m.crossing_offset.size == key.shape[0]
    if pairs:
        a, b = key[:, 0], key[:, 1]
        p_c = deepest((close(a, s) & close(b, s_bar)) | (close(b, s) & close(a, s_bar)))
    deep = p.size > 0 and p.max() > tol
    holding = carrying & (m.offset > 0) & np.isfinite(p_s)
    open_gap = max(float(np.max(-p_s[holding], initial=0.0)), 0.0)
    opened = np.any(holding & (p_s < -tol)) or \
        (pairs and np.any((m.crossing > 0) & (m.crossing_offset > 0) & np.isfinite(p_c)
                          & (p_c < -tol)))
    if not (deep or opened):
        return None
    gain = 1.0
    if last is not None and deep:
        gain = 1.0 / float(np.clip((last[0] - p.max()) / max(last[1], 1e-300), 0.25, 1.0))

    def moved(off, q):
        step = np.where(np.isfinite(q), q - 0.5 * tol, 0.0)
        return np.clip(off + np.where(step > 0, gain * step, step), 0.0, cap)
    new = moved(m.offset, p_s)
    change = float(np.max(np.abs(new - m.offset), initial=0.0))
    m.offset = new
    if pairs:
        new = moved(m.crossing_offset, p_c)
        change = max(change, float(np.max(np.abs(new - m.crossing_offset), initial=0.0)))
        m.crossing_offset = new
    if change <= 1e-3 * tol:
        return None
    return float(p.max(initial=-np.inf)), change, bool(opened), open_gap


def finish(problem, r, rep, opened, saved, strict=True):
    """The end of the loop at the state ``r`` (the report ``rep`` holds the
    loop's figures): the note when Uzawa stopped short, the multipliers
    set to the forces applied where the penalty was raised
    (:func:`fold_forces`) and back to the nominal penalty, the true
    distance between strands.  A true overlap beyond the tolerance
    (``strict``; else beyond :data:`OVERLAP_FAIL`) away from the rod's
    ends fails the step (multipliers put back to ``saved``); one at an end
    is noted.  The gap offsets of the points that carry no force go back
    to 0."""
    c, m = problem.contact, problem.multipliers
    tol = c.tolerance * c.radius
    scale = float(m.penalty_scale.max(initial=1.0))
    if not rep.uzawa_converged:
        rep.uzawa_note = (
            f"Uzawa stopped after {rep.uzawa} updates with penetration {rep.penetration:.3e} "
            f"and open gap under force {opened:.3e} (tolerance {tol:.3e})"
            + (f" and friction multipliers moving by {rep.friction_moved:.3e} "
               f"gamma f_N, Coulomb misfit {rep.friction_misfit:.3e} "
               f"(tolerance {c.friction_tolerance:g})"
               if problem.friction else "")
            + (f"; penalty raised up to {scale:.3g} times" if scale > 1 else ""))
    # back to the nominal penalty, the multipliers the forces applied: the
    # state is then an equilibrium for any penalty (to d / mu), and the
    # stability check and the next step see the nominal tangent
    if c.penalty_memory:
        problem.penalty_start = m.penalty_scale.copy()
    fold_forces(m, rep.evaluation)
    problem.multipliers = m.nominal_penalty()
    rep.penalty_scale = scale
    if rep.min_distance is None:           # else measured at r by needs_offsets
        true_distance(problem, r, rep)
    over = true_overlap(problem, rep)
    if over > (tol if strict else OVERLAP_FAIL * c.radius) and not at_an_end(problem, rep):
        fail_overlap(problem, rep, tol if strict else OVERLAP_FAIL * c.radius)
        problem.multipliers = saved
        return
    m = problem.multipliers
    ce = rep.evaluation.contact if rep.evaluation is not None else None
    if ce is not None:
        carrying = np.zeros(m.offset.size, bool)
        carrying[ce.pairs.slave[ce.fN > 0]] = True
        m.offset[~carrying] = 0.0
    if m.crossing_offset.size == m.crossing.size:
        m.crossing_offset[m.crossing <= 0] = 0.0
    if over > tol:
        s, s_bar = rep.min_distance_at
        where = "an end of the rod overlaps" if at_an_end(problem, rep) else \
            "the strands overlap between slave points"
        rep.uzawa_note = (rep.uzawa_note + "; " if rep.uzawa_note else "") + (
            f"{where} by {over / c.radius:.3g} eps (s = {s:.6g}, {s_bar:.6g}; "
            f"tolerance {c.tolerance:g} eps)")


def fold_forces(m, ev):
    """Where the penalty factors of ``m`` are raised (slave points, the
    crossing pairs' factor), set the normal multipliers to the forces
    applied at the evaluation ``ev`` (the last pass's): eq. (4.2a)'s
    update at the converged state, taken before the factors go back to 1.

    The loop stops on the gaps, and a pass that converged at a penalty
    raised ``s`` times (:func:`adapt_penalty`) applied ``[lambda + s d /
    mu]_+``; kept as they were, its multipliers met the nominal penalty with
    a force lower by about ``(s - 1) d / mu`` at every penetrating point.
    The next solve then started from that out-of-balance at the state just
    converged: measured in the plectoneme's winding at 2.0 turns (factors
    256 to 1e3), residuals of 11-36 at the first iterate of every polish
    and damped step, where the state had converged to 1e-8; the polishes
    failed in 12 iterations three times in a row, each a damped phase
    going on at rest.  With the forces kept, the next solve starts off by
    ``d / mu`` at most, as after any update at the nominal penalty.  At a
    factor of 1 nothing jumps, and the multipliers stay those the last pass
    converged with.  Folding there too changed the paths of three scene
    tests (the twisted rod's second snap at 2.6 turns instead of 2.0, two
    friction scenes' Newton histories).  The friction multipliers are
    left: their loop stops only when they have stopped moving
    (``friction_tolerance``), so they already are the forces applied."""
    ce = None if ev is None else ev.contact
    if ce is None:
        return
    raised = m.penalty_scale[ce.pairs.slave] > 1.0
    m.normal[ce.pairs.slave[raised]] = ce.fN[raised]
    if ce.crossing is not None and m.crossing_scale > 1.0:
        m.rekey_crossing(ce.crossing.key, ce.crossing_fN.copy())


def step(problem, r, R, lam, prescribed, opts, inner=None, rescue=True, strict=True):
    """One solve at load factor ``lam`` from ``(r, R)``: this module's
    augmented-Lagrangian loop (contact on) around ``inner`` (default the one
    Newton, :func:`skfem_rod.newton.newton`; e.g. a
    :class:`~skfem_rod.relax.GradientFlow` or a damped Newton of
    :mod:`skfem_rod.dynamics`), the prescribed increment applied by the
    first pass.  Returns ``(r, R, report)``.  Used by load stepping and the
    pseudo-dynamics alike.

    With Uzawa (``contact_solve="uzawa"``), the default inner Newton and
    ``rescue``, a pass after the first that fails is solved again by the
    generalized Newton (:mod:`skfem_rod.nonsmooth`) from the last converged
    pass (load steps, step 0, the polish of the pseudo-dynamics; not the
    gradient flow's or the damped steps' inner solves).
    Both strands' Gauss points are slaves, so along plies in contact every
    contact is imposed twice with slightly different gaps: Uzawa then
    converges slowly (measured in the plectoneme at 1.69 turns: the
    penetration fell 4.4e-4 -> 1.4e-4 -> 9.8e-5 -> 7.5e-5 -> 5.5e-5 against
    a tolerance of 2.5e-5), the adaptive penalty grows by 4 per such update,
    and at 256 times the nominal penalty the pass's Newton diverged
    (residual 8.6 -> 113 -> 663, the active set 6 -> 9 -> 0 -> 26).  From
    the last converged pass the generalized Newton solved it in 12
    iterations to a penetration of 3.3e-7.  The report says so
    (``rescued``).  Around another ``inner`` (the damped steps, the
    gradient flow), or with the generalized Newton as the contact solve,
    such a pass runs again by ``inner`` itself from the last converged
    pass at the nominal penalty: in the plectoneme's winding at 1.95 turns
    a damped pass diverged (residual 46 -> 39 -> 69 -> 2054) after the
    crossing pairs' penalty had grown to 16 times the nominal one, and at
    the nominal penalty it converged in 5 iterations."""
    use = rescue and inner is None and problem.contact is not None \
        and opts.contact_solve == "uzawa"
    if inner is None:
        from .newton import newton
        inner = lambda *a, **k: newton(problem, *a, **k)          # noqa: E731

    def solve_pass(previous):
        if previous is None:
            return inner(r, R, lam, opts, prescribed=prescribed)
        return inner(previous[0], previous[1], lam, opts)

    def generalized(previous, kept):
        # the friction multipliers are the generalized Newton's unknowns:
        # they start from those the last pass converged with, with which
        # its state is in balance.  The update knocks a sticking point's
        # trial force out of the Coulomb ball (lambda + g / mu, with the
        # pass's slip g), and from there the generalized Newton's first
        # update took the slip branch: a crossing pair restarted without
        # its friction force (tests/test_crossing_friction.py) slid by the
        # clearance cap and the step failed
        from dataclasses import replace
        m = problem.multipliers
        if problem.friction:
            m.tangential, m.rotational = kept.tangential.copy(), kept.rotational.copy()
            m.crossing_friction = kept.crossing_frictions(m.crossing_key)
        return inner(previous[0], previous[1], lam, replace(opts, contact_solve="newton"))

    def plain(previous, kept):
        return solve_pass(previous)

    again = generalized if use else (plain if rescue else None)
    r1, R1, _, rep = augmented_lagrangian(problem, solve_pass, again, strict)
    return r1, R1, rep


def carry_crossing(m, cp):
    """The crossing multipliers of the pairs ``cp`` (0 for new element pairs)."""
    from .contact.crossing import carry
    return carry(m.crossing_key, m.crossing, cp.key)


def true_distance(problem, r, rep):
    """The true smallest distance between non-neighbouring strands at the
    state ``r`` (closest points of element pairs, both parameters free:
    :func:`skfem_rod.contact.crossing.min_distance`), recorded in the
    report (``min_distance``, and where); returns the true penetration
    ``2 eps - distance``.  Slave points sample the rod at Gauss points
    only: crossing strands can overlap between them, and along a curved
    line contact the penetration peaks between them."""
    from .contact.crossing import min_distance
    c = problem.contact
    md = min_distance(problem.mesh, r, c.radius, c.exclusion)
    rep.min_distance = float(md.distance)
    rep.min_distance_at = (float(md.s), float(md.s_bar))
    return md.penetration(c.radius)


def at_an_end(problem, rep):
    """True when the closest approach of the report involves an end of an
    open rod: the paper's slave set (Gauss points) leaves the end caps
    without contact, so an overlap there is reported (Result.log) but does
    not fail the step."""
    mesh = problem.mesh
    if mesh.closed or rep.min_distance_at is None:
        return False
    L = problem.rod.length
    return any(min(abs(s), abs(L - s)) <= 1e-9 * L for s in rep.min_distance_at)


def true_overlap(problem, rep):
    """``2 eps - min_distance`` of the report (``-inf`` without strands in reach)."""
    return 2.0 * problem.contact.radius - rep.min_distance


def fail_overlap(problem, rep, allowed):
    """A state whose strands overlap by more than ``allowed`` (the contact
    tolerance, or :data:`OVERLAP_FAIL` eps on the way) is not converged:
    the report says where and what to do."""
    c = problem.contact
    s, s_bar = rep.min_distance_at
    rep.converged = False
    where = (f"the strands overlap by {true_overlap(problem, rep) / c.radius:.3g} eps "
             f"between slave points (s = {s:.6g} and {s_bar:.6g}; at most "
             f"{allowed / c.radius:.3g} eps; gap offsets raised in {rep.offset_rounds} rounds)")
    if not rep.uzawa_converged:
        # the offsets are raised only once the slave points hold the
        # tolerances: the loop's own shortfall is the cause to report
        # (measured: the knot tied with 12 slave points per element stopped
        # at max_uzawa = 60 with the slave points at 4.5 times the
        # tolerance, and the message blamed the sampling)
        rep.reason = (f"{where}, because the Uzawa loop stopped short and the gap offsets are "
                      f"raised only once the slave points hold the tolerance: "
                      f"{rep.uzawa_note}: raise max_uzawa (now {c.max_uzawa}) or the "
                      "contact tolerance")
        return
    rep.reason = (f"{where}: "
                  + ("refine the mesh or raise n_slave" if c.crossing else
                     "switch on crossing contact (enable_contact(crossing=True)), refine "
                     "the mesh or raise n_slave"))


def grown(scale, c):
    """A penalty factor (or an array of them) grown by the contact options'
    ``penalty_growth``, at most ``max_penalty_scale``: the one growth of
    :func:`adapt_penalty`, :func:`adapt_crossing_penalty` and
    :func:`adapt_friction_penalty`."""
    return np.minimum(scale * c.penalty_growth, c.max_penalty_scale)


def adapt_penalty(problem, pairs, d, fN, new, last):
    """The penalty update of the method of multipliers (Bertsekas,
    *Constrained Optimization and Lagrange Multiplier Methods*, 1982,
    sec. 2.2; Nocedal & Wright, *Numerical Optimization*, framework 17.3),
    per slave point, after the Uzawa update ``lambda_N -> new``.

    Uzawa converges linearly, by the factor ``k / (k + 1/mu)`` per update
    where the structure's stiffness ``k`` against the point's gap is large
    compared with the penalty stiffness ``1/mu`` (a line contact whose force
    redistributes between neighbouring points: factors 0.97-0.99 measured
    in the plectoneme, docs/friction.md).  The violation of a point is
    ``|d|`` where it penetrates or carries a force across an open gap; a
    point still short of its tolerance -- ``|d| > tolerance eps``, or, with
    friction, a multiplier change above ``friction_tolerance max f_N`` (the
    friction bound ``gamma f_N`` moves with it) -- whose violation did not
    drop below :data:`PENALTY_DROP` times the last one gets its penalty
    stiffness multiplied by ``penalty_growth``, up to ``max_penalty_scale``
    times the nominal one.  The last violation of a point is the one of
    the last pass *in which it was in contact*: in a 2-cycle of the Uzawa
    passes two points take turns to carry a contact (each pass's inner
    solve lands in the other of two nearby equilibria), each point is out
    of contact every other pass, and a memory of one pass (``inf`` while
    out) never raised their penalty: the knot's step 11 (demos/knot.py)
    alternated penetrations 2.16e-4 and 2.33e-4 for 60 updates at a
    penalty scale of 16.  Returns the violations (``inf`` where a point
    was never in contact in this step), the ``last`` of the next call."""
    c, m = problem.contact, problem.multipliers
    act = (d > 0) | (fN > 0)
    now = np.zeros(m.normal.size, bool)
    now[pairs.slave[act]] = True
    viol = last.copy()
    viol[pairs.slave[act]] = np.abs(d[act])
    short = now & (viol > c.tolerance * c.radius)
    if problem.friction and fN.size:
        short |= now & (np.abs(new - m.normal) > c.friction_tolerance * fN.max())
    grow = short & (viol > PENALTY_DROP * last)
    m.penalty_scale = np.where(
        grow, grown(m.penalty_scale, c),
        m.penalty_scale)
    return viol


def adapt_crossing_penalty(problem, ce, dc, last):
    """The same rule for the crossing pairs (gaps ``dc`` at the contact
    evaluation ``ce``), with one factor for all of them
    (``Multipliers.crossing_scale``): it grows by ``penalty_growth`` when the
    largest violation of the pairs -- a penetration, or an open gap under
    force -- is above the tolerance and did not drop below
    :data:`PENALTY_DROP` times the last one.  A crossing pair carries the
    force of a whole crossing against the Gauss points beside it, and at
    the fixed nominal penalty its multiplier crawled: in the plectoneme's
    step to 1.75 turns (100 elements) the pair's penetration fell from
    4.2e-5 to 3.6e-5 in 20 updates against a tolerance of 2.5e-5 while the
    slave points had long held theirs, and the step ran out of updates.
    Returns the violation, the ``last`` of the next call."""
    c, m = problem.contact, problem.multipliers
    act = (dc > 0) | (ce.crossing_fN > 0)
    viol = float(np.max(np.abs(dc[act]), initial=0.0))
    if viol > c.tolerance * c.radius and viol > PENALTY_DROP * last:
        m.crossing_scale = grown(m.crossing_scale, c)
    return viol


def adapt_friction_penalty(problem, fN, new, moved, last):
    """The same rule for the friction compliances, with one factor for all
    points: the friction stiffness grows by ``penalty_growth`` when the
    friction multipliers still move by more than ``friction_tolerance``
    (relative to ``gamma max f_N``), their movement did not drop below
    :data:`PENALTY_DROP` times the last, and it is friction's own: more than
    twice what the change of the Coulomb bound ``gamma f_N`` explains (the
    normal multipliers' change relative to ``max f_N``; that part is left to
    the normal penalty).  Returns the movement, the ``last`` of the next
    call."""
    c, m = problem.contact, problem.multipliers
    top = float(fN.max(initial=0.0))
    if top <= 0.0:                # no normal force: no bound to measure the movement by
        return moved
    normal = float(np.abs(new - m.normal).max(initial=0.0)) / top
    if moved > c.friction_tolerance and moved > PENALTY_DROP * last and moved > 2 * normal:
        m.friction_scale = grown(m.friction_scale, c)
    return moved
