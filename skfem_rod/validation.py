"""Input checks shared by the package: each raises ValueError naming the
parameter, the value, and what is allowed."""
import numpy as np


def positive(name, value):
    """``value`` as a float; ValueError unless it is a finite number > 0."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}") from None
    if not (np.isfinite(v) and v > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return v


def count(name, value, minimum):
    """``value`` unless it is an integer >= ``minimum`` (bools rejected)."""
    if not (isinstance(value, (int, np.integer)) and not isinstance(value, bool)
            and value >= minimum):
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def finite_vector(name, value):
    """A finite 3-vector of numbers."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite 3-vector of numbers, "
                         f"got {value!r}") from None
    if v.shape != (3,):
        raise ValueError(f"{name} must be a 3-vector, got shape {v.shape}")
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be finite (no NaN or inf), got {v.tolist()}")
    return v
