"""Input checks shared by the package (the API and the scene loader): each
raises ValueError naming the parameter, the value, and what is allowed.

One checker per kind of value, used everywhere that kind is taken: a
number > 0 (:func:`positive`), an integer (:func:`count`), a flag
(:func:`flag`), a 3-vector (:func:`finite_vector`), an array of points
(:func:`points`), arclengths along a rod (:func:`arclengths`), a step
index (:func:`step_index`), and the sizes a run
may allocate (:func:`memory_budget`).
"""
import numbers

import numpy as np

#: largest number of elements a Rod accepts (about 1.3 GB of mesh, bases and
#: sparse tangent at 3 Gauss points); beyond it the allocation fails anyway
MAX_ELEMENTS = 2_000_000
#: largest number of Gauss points per element
MAX_QUAD = 32
#: largest number of load steps of a solve (each converged step is kept)
MAX_STEPS = 1_000_000
def _physical_memory():
    try:
        import os
        return int(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return 8 * 2**30


#: memory a model may ask for before it is refused (bytes): the machine's
#: physical memory (8 GiB where it cannot be read)
MEMORY_LIMIT = _physical_memory()


def _is_real(value):
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf":
        return True
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _show(value):
    s = repr(value)
    return s if len(s) <= 80 else s[:77] + "..."


def positive(name, value):
    """``value`` as a float; ValueError unless it is a finite number > 0
    (bools and strings are not numbers)."""
    if not _is_real(value):
        raise ValueError(f"{name} must be a finite number > 0, got {_show(value)}")
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be a finite number > 0, got {_show(value)}") from None
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {_show(value)}")
    return v


def nonnegative(name, value):
    """``value`` as a float; ValueError unless it is a finite number >= 0."""
    if not _is_real(value) or not (np.isfinite(float(value)) and float(value) >= 0):
        raise ValueError(f"{name} must be a finite number >= 0, got {_show(value)}")
    return float(value)


def count(name, value, minimum, maximum=None):
    """``value`` unless it is an integer in ``[minimum, maximum]`` (bools
    rejected)."""
    ok = (isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
          and value >= minimum)
    if ok and maximum is not None and value > maximum:
        raise ValueError(f"{name} must be an integer in [{minimum}, {maximum}], got "
                         f"{_show(value)}")
    if not ok:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {_show(value)}")
    return int(value)


def flag(name, value):
    """``value`` as a bool; ValueError unless it is True or False (no
    truthiness: ``"no"`` or ``0`` are refused)."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {_show(value)}")
    return bool(value)


def _has_bool(value):
    """True if ``value`` is (or holds, nested in lists or tuples) a bool."""
    if isinstance(value, (bool, np.bool_)):
        return True
    if isinstance(value, np.ndarray):
        return value.dtype == bool
    if isinstance(value, (list, tuple)):
        return any(_has_bool(v) for v in value)
    return False


def finite_vector(name, value, nonzero=False):
    """A finite 3-vector of numbers (not all zero with ``nonzero``; bools are
    not numbers)."""
    if isinstance(value, (str, bytes)) or _has_bool(value):
        raise ValueError(f"{name} must be a finite 3-vector of numbers, got {_show(value)}")
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be a finite 3-vector of numbers, "
                         f"got {_show(value)}") from None
    if v.shape != (3,):
        raise ValueError(f"{name} must be a 3-vector, got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be finite (no NaN or inf), got {v.tolist()}")
    if nonzero and not np.any(v):
        raise ValueError(f"{name} must be a nonzero finite 3-vector, got {v.tolist()}")
    return v


def points(name, value, minimum=1, n=None):
    """A finite ``(m, 3)`` array of numbers with ``m >= minimum`` (or
    exactly ``n`` rows when given)."""
    what = f"{n}" if n is not None else f"m >= {minimum}"
    if isinstance(value, (str, bytes)) or _has_bool(value):
        raise ValueError(f"{name} must be a finite (m, 3) array of numbers ({what}), "
                         f"got {_show(value)}")
    try:
        P = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be a finite (m, 3) array of numbers ({what}), "
                         f"got {_show(value)}") from None
    if P.ndim != 2 or P.shape[1] != 3 or (n is None and len(P) < minimum):
        raise ValueError(f"{name} must be a finite (m, 3) array of numbers ({what}), "
                         f"got shape {P.shape}")
    if n is not None and len(P) != n:
        raise ValueError(f"{name} must have one row per point ({n}), got {len(P)}")
    if not np.all(np.isfinite(P)):
        k = int(np.argwhere(~np.isfinite(P))[0, 0])
        raise ValueError(f"{name} must be finite (no NaN or inf): row {k} is "
                         f"{P[k].tolist()}")
    return P


def arclengths(name, value, length):
    """Arclengths in ``[0, length]`` as a 1-d float array (a scalar becomes
    one entry); bools and strings are not numbers."""
    if isinstance(value, (str, bytes)) or _has_bool(value):
        raise ValueError(f"{name} must be arclengths in [0, {length}] (numbers), "
                         f"got {_show(value)}")
    try:
        raw = np.asarray(value)
        if raw.dtype.kind not in "iuf":                     # strings, objects, bytes
            raise TypeError
        s = np.atleast_1d(raw.astype(float))
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{name} must be arclengths in [0, {length}] (numbers), "
                         f"got {_show(value)}") from None
    if s.ndim != 1:
        raise ValueError(f"{name} must be a number or a 1-d array of numbers, got shape "
                         f"{s.shape}")
    if np.any(~np.isfinite(s)) or np.any(s < -1e-12 * length) \
            or np.any(s > length * (1 + 1e-12)):
        raise ValueError(f"{name} must lie in [0, {length}], got {_show(value)}")
    return s


def step_index(value, n_steps, name="step"):
    """A valid index into ``n_steps`` stored steps (negative counts from
    the end), as a non-negative int."""
    if not (isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))):
        raise ValueError(f"{name} must be an integer step index, got {_show(value)}")
    if not -n_steps <= value < n_steps:
        raise ValueError(f"{name} = {value} is out of range: the result has {n_steps} "
                         f"step(s), indices {-n_steps} to {n_steps - 1}")
    return int(value) % n_steps


def memory_budget(what, n_bytes, limit=None):
    """Refuse a model that would need ``n_bytes`` of memory (an estimate)
    beyond ``limit`` (default :data:`MEMORY_LIMIT`), naming ``what``."""
    limit = MEMORY_LIMIT if limit is None else limit
    if n_bytes > limit:
        raise ValueError(f"{what} would need about {n_bytes / 2**30:.3g} GiB of memory, "
                         f"more than the limit of {limit / 2**30:.3g} GiB "
                         "(skfem_rod.validation.MEMORY_LIMIT)")
