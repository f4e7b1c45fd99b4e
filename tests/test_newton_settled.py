"""Newton's convergence test (``problem.settled``): a small update settles
a step only where the residual did not jump at it."""
from skfem_rod.problem import SETTLED_GROWTH, settled


def test_a_small_update_across_a_jump_of_the_residual_is_not_convergence():
    """The history of an accepted damped step of the frictional plectoneme
    (1.95 turns): the last update was below ``increment_tol``, but it
    crossed the place where a crossing pair's minimum was lost and the
    residual went from 1.6e-2 to 66.  Not converged; at a residual floor
    (the residual wandering by a factor 3 below the update tolerance) it
    is; below ``rtol`` it always is."""
    jump = [1.7e-2, 2.8e-2, 1.6e-2, 66.0]
    assert not settled(jump, 1e-12, 2.2e-7, 1e-9)
    assert settled([1.0, 1e-3, 3e-9, 9e-9], 1e-12, 1e-9, 1e-9)
    assert settled([1.0, 1e-3, 3e-9, 3e-9 * SETTLED_GROWTH], 1e-12, 1e-9, 1e-9)
    assert not settled([1.0, 1e-3, 3e-9, 3.1e-9 * SETTLED_GROWTH], 1e-12, 1e-9, 1e-9)
    assert settled(jump[:-1] + [1e-7], 1e-3, 2.2e-7, 1e-9)       # below rtol
    assert not settled([1.0, 0.5], 1e-3, 1e-9, 1e-9)               # still moving
