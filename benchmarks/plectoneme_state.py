"""Save two consecutive converged states of the barrier plectoneme (the
set-up of ``bench_plectoneme_barrier.py``, steps of 1/16 turn; by default
frictionless and without handles) for a test to take the next step from.

Usage::

    python benchmarks/plectoneme_state.py 100 138 tests/data/plectoneme_swing.npz
    python benchmarks/plectoneme_state.py 100 122 tests/data/plectoneme_slip.npz 0.3 handles

writes ``lam0, r0, R0`` (step ``k - 1``) and ``lam1, r1, R1`` (step ``k``)
of the ``n``-element rod; ``tests/test_handles.py`` takes step ``k + 1``
from them, where the plectoneme swings around an end without handles.
"""
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_plectoneme as bp  # noqa: E402


class _Stop(Exception):
    pass


def states(n_elements, k, gamma_T=0.0, handles=False):
    """``((lam, r, R) of step k - 1, of step k)``."""
    rod = bp.build(n_elements, gamma_T)
    kept = {}

    def keep(result, j):
        st = result.steps[j]
        kept[j] = (st.load_factor, st.r.copy(), st.R.copy())
        if j >= k:
            raise _Stop
    try:
        rod.solve(160, path=[0, 1.0], method="barrier", barrier_width=0.02, barrier_force=1.0,
                  callback=keep, handles=handles)
    except _Stop:
        pass
    return kept[k - 1], kept[k]


def main(argv=None):
    args = argv or sys.argv[1:]
    n, k, path = args[:3]
    gamma_T = float(args[3]) if len(args) > 3 else 0.0
    (lam0, r0, R0), (lam1, r1, R1) = states(int(n), int(k), gamma_T, "handles" in args[4:])
    tmp = Path(path).with_suffix(".tmp.npz")
    np.savez_compressed(tmp, lam0=lam0, r0=r0, R0=R0, lam1=lam1, r1=r1, R1=R1)
    tmp.replace(path)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
