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
        adapt the penalty where a violation did not drop (Bertsekas)
        next pass: inner solve from the last converged state
    the next step's loop starts at the normal penalty reached (penalty_memory);
        a first pass failing with it is solved again at the nominal one
    a later pass failing (rescue given): the generalized Newton from the
        last converged pass, at the nominal penalty (:func:`step`)
    failed inner solve: multipliers restored, failure returned

The penalty adapts as in the method of multipliers (:func:`adapt_penalty`):
where a point's violation did not drop by a factor 4 over an update, its
penalty stiffness grows by ``penalty_growth`` for the rest of the step;
with the option ``penalty_memory`` the next step starts from there, else
every step starts at the nominal penalty.  The converged answer is that
of the fixed penalty to the tolerances; only the path to it changes.
"""
import numpy as np

from .contact.friction_assembly import coulomb_misfit, multiplier_updates
from .contact import OVERLAP_FAIL
from .contact.law import gap, uzawa_update

#: the adaptive penalty raises the penalty at a point whose violation did
#: not drop below this fraction of the last one (Bertsekas' 0.25)
PENALTY_DROP = 0.25


def augmented_lagrangian(problem, solve_pass, rescue=None):
    """Uzawa updates of the contact (and friction) multipliers of
    ``problem`` around ``solve_pass``.

    Parameters
    ----------
    problem : :class:`skfem_rod.problem.Problem`
    solve_pass : callable ``previous -> (r, R, lam, report)``: the inner
        solve at the current multipliers; ``previous`` is None on the first
        pass, else the ``(r, R, lam)`` the last pass converged to.
    rescue : callable ``previous -> (r, R, lam, report)``, optional: solves
        from the last converged pass when a later pass fails (the
        multipliers as the failed pass left them, the penalty back at the
        nominal one); the loop goes on from its state.  Once per loop.

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
    carried = carry_penalty(problem)
    total, uzawa = 0, 0
    last = np.full(problem.multipliers.normal.size, np.inf)   # last violation in contact
    last_moved = np.inf
    previous = None
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
            r, R, lam, rep = rescue(previous)
            total += rep.iterations
            rescue = None
            if rep.converged:
                rep.rescued = why
        if not rep.converged:
            problem.multipliers = saved
            rep.newton_total = total
            return r, R, lam, rep
        previous = (r, R, lam)
        ce = rep.evaluation.contact
        pen, opened, d, dc = violations(problem, ce)
        done = pen <= c.tolerance * c.radius and opened <= c.tolerance * c.radius
        m = problem.multipliers
        if problem.friction:
            updates, moved = multiplier_updates(ce.friction, m, c)
            rep.friction_moved = moved
            rep.friction_misfit = coulomb_misfit(ce.friction, problem.friction_params(),
                                                 c.friction_tolerance)
            done = done and max(moved, rep.friction_misfit) <= c.friction_tolerance
        if done or uzawa == c.max_uzawa:
            rep.uzawa, rep.newton_total, rep.penetration = uzawa, total, pen
            rep.uzawa_converged = done
            finish(problem, r, rep, opened, saved)
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
            m.rekey_crossing(ce.crossing.key,
                             ce.crossing.weight * uzawa_update(dc, old, c.crossing_penalty))
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


def violations(problem, ce):
    """The contact tolerances' measures at the contact evaluation ``ce``:
    the largest penetration and the largest open gap under force (a
    multiplier left over from a higher load pushes apart), over the slave
    pairs and the crossing pairs.  Returns ``(penetration, opened, d, dc)``
    with the gaps ``d`` of the slave pairs and ``dc`` of the crossing pairs
    (None without)."""
    c = problem.contact
    d = gap(ce.pairs.distance, c.radius)
    pen = float(d.max(initial=0.0))
    opened = float(np.max(-d[ce.fN > 0], initial=0.0))
    dc = None
    if ce.crossing is not None:                  # point pairs of crossing strands
        dc = gap(ce.crossing.distance, c.radius)
        pen = max(pen, float(dc.max(initial=0.0)))
        opened = max(opened, float(np.max(-dc[ce.crossing_fN > 0], initial=0.0)))
    return pen, opened, d, dc


def finish(problem, r, rep, opened, saved):
    """The end of the loop at the state ``r`` (the report ``rep`` holds the
    loop's figures): the note when Uzawa stopped short, the multipliers
    back to the nominal penalty, the true distance between strands; a true
    overlap beyond :data:`OVERLAP_FAIL` fails the step (multipliers put
    back to ``saved``), one beyond the tolerance is noted."""
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
    # back to the nominal penalty: at the converged multipliers the state is
    # an equilibrium for any penalty (to the tolerances), and the stability
    # check and the next step see the nominal tangent
    if c.penalty_memory:
        problem.penalty_start = m.penalty_scale.copy()
    problem.multipliers = m.nominal_penalty()
    rep.penalty_scale = scale
    true_distance(problem, r, rep)
    over = true_overlap(problem, rep)
    if over > OVERLAP_FAIL * c.radius and not at_an_end(problem, rep):
        fail_overlap(problem, rep)
        problem.multipliers = saved
    elif over > tol:
        s, s_bar = rep.min_distance_at
        where = "an end of the rod overlaps" if at_an_end(problem, rep) else \
            "the strands overlap between slave points"
        rep.uzawa_note = (rep.uzawa_note + "; " if rep.uzawa_note else "") + (
            f"{where} by {over / c.radius:.3g} eps (s = {s:.6g}, {s_bar:.6g}; "
            f"tolerance {c.tolerance:g} eps)")


def step(problem, r, R, lam, prescribed, opts, inner=None, rescue=True):
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
    (``rescued``)."""
    use = rescue and inner is None and problem.contact is not None \
        and opts.contact_solve == "uzawa"
    if inner is None:
        from .newton import newton
        inner = lambda *a, **k: newton(problem, *a, **k)          # noqa: E731

    def solve_pass(previous):
        if previous is None:
            return inner(r, R, lam, opts, prescribed=prescribed)
        return inner(previous[0], previous[1], lam, opts)

    def generalized(previous):
        from dataclasses import replace
        return inner(previous[0], previous[1], lam, replace(opts, contact_solve="newton"))

    r1, R1, _, rep = augmented_lagrangian(problem, solve_pass, generalized if use else None)
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


def fail_overlap(problem, rep):
    """A state whose strands overlap by more than :data:`OVERLAP_FAIL` eps
    is not converged: the report says where and what to do."""
    c = problem.contact
    s, s_bar = rep.min_distance_at
    rep.converged = False
    rep.reason = (f"the strands overlap by {true_overlap(problem, rep) / c.radius:.3g} eps "
                  f"between slave points (s = {s:.6g} and {s_bar:.6g}; at most "
                  f"{OVERLAP_FAIL:g} eps): "
                  + ("refine the mesh or raise n_slave" if c.crossing else
                     "switch on crossing contact (enable_contact(crossing=True)), refine "
                     "the mesh or raise n_slave"))


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
        grow, np.minimum(m.penalty_scale * c.penalty_growth, c.max_penalty_scale),
        m.penalty_scale)
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
    normal = (float(np.abs(new - m.normal).max(initial=0.0)) / fN.max() if fN.size else 0.0)
    if moved > c.friction_tolerance and moved > PENALTY_DROP * last and moved > 2 * normal:
        m.friction_scale = min(m.friction_scale * c.penalty_growth, c.max_penalty_scale)
    return moved
