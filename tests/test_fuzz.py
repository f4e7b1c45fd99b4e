"""Issue 14: a hypothesis fuzz over the public API and the scene format.

Every call gets, argument by argument, either a valid value or anything
(NaN, inf, huge and tiny numbers, bools, strings, None, lists of the wrong
length, arrays).  What must hold, for every example:

* no raw traceback: a call either succeeds or raises ValueError / TypeError;
* an argument that is not valid is refused (no silent coercion: ``"no"`` is
  not a bool, ``True`` is not a number, ``2.0`` is not a count), with a
  message that names the parameter;
* no silent NaN: a solve that says converged has finite positions,
  rotations, energies and reactions.

Seeded (``derandomize=True``): 2,000 examples in the slow tier, 100 in the
fast one.
"""
import math
import numbers

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from skfem_rod import Rod, Section, geometry
from skfem_rod.scene import load_scene

ANYTHING = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-10**13, 10**13),
    st.booleans(), st.none(), st.text(max_size=4),
    st.sampled_from([1e-300, 1e300, -0.0, 0, 1, 2.0, "1", "0.01", b"x", np.nan, [np.nan, 0, 0],
                     [1.0, 2.0], [0, 0, 0], [[1, 2, 3]], np.float64(0.5), np.array(1.0),
                     np.array([1.0, 2.0, 3.0]), "start", "end", 0.5, (0, 2), [3], (0.5,)]),
    st.lists(st.floats(-1e3, 1e3), min_size=0, max_size=4),
    st.lists(st.one_of(st.booleans(), st.integers(-3, 3)), min_size=3, max_size=3),
)


def is_real(v):
    """A real number (a 0-d numeric array is one too); bools are not."""
    if isinstance(v, np.ndarray) and v.ndim == 0 and v.dtype.kind in "iuf":
        return True
    return isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_))


def positive(v):
    return is_real(v) and math.isfinite(float(v)) and float(v) > 0


def vector(v, nonzero=False):
    if isinstance(v, (str, bytes)) or (isinstance(v, (list, tuple))
                                       and any(isinstance(x, (bool, np.bool_)) for x in v)):
        return False
    try:
        a = np.asarray(v)
    except Exception:
        return False
    if a.shape != (3,) or a.dtype.kind not in "iuf":
        return False
    return bool(np.all(np.isfinite(a))) and (not nonzero or bool(np.any(a)))


def flag(v):
    return isinstance(v, (bool, np.bool_))


def count(v, lo, hi):
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool) and lo <= v <= hi


POS = (st.floats(0.05, 20.0), positive)
VEC = (st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3), vector)
VECNZ = (st.lists(st.floats(0.1, 2.0), min_size=3, max_size=3), lambda v: vector(v, True))
BOOL = (st.booleans(), flag)


class Bad(AssertionError):
    pass


def call(data, fn, name_of_call, too_long=None, **specs):
    """Draw each argument valid or anything, call ``fn``; check the outcome.
    Returns (ok, value).  ``too_long(kwargs)`` marks valid arguments whose
    call would take minutes (a solve of 10^5 steps): not called."""
    kwargs, invalid = {}, []
    for name, (valid, pred) in specs.items():
        v = data.draw(st.one_of(valid, ANYTHING) if data.draw(st.booleans()) else valid,
                      label=f"{name_of_call}.{name}")
        kwargs[name] = v
        if not pred(v):
            invalid.append(name)
    if not invalid and too_long is not None and too_long(kwargs):
        return False, None
    try:
        with np.errstate(all="ignore"):
            out = fn(**kwargs)
    except (ValueError, TypeError) as err:
        msg = str(err)
        if invalid and not any(n in msg for n in invalid + ["where", "shape", "section"]):
            raise Bad(f"{name_of_call}({kwargs}) refused {invalid} without naming "
                      f"it: {msg}") from None
        return False, None
    except Exception as err:                                   # a raw traceback
        raise Bad(f"{name_of_call}({kwargs}) raised {type(err).__name__}: {err}") from err
    if invalid:
        raise Bad(f"{name_of_call}({kwargs}) accepted invalid {invalid} (silent coercion)")
    return True, out


def where(v):
    """Valid as a type: an end, or a finite arclength >= 0 (whether it is a
    node is the rod's business: a ValueError then)."""
    return (isinstance(v, str) and v in ("start", "end")) or (
        is_real(v) and math.isfinite(float(v)) and float(v) >= 0)


WHERE = (st.sampled_from(["start", "end", 0.0]), where)
COMPONENTS = (st.sampled_from([(0,), (1, 2), (0, 1, 2)]),
              lambda v: isinstance(v, tuple) and len(v) > 0
              and all(count(c, 0, 2) for c in v))


def api_example(data):
    kind = data.draw(st.sampled_from(["straight", "arc", "helix", "polyline"]))
    if kind == "straight":
        ok, shape = call(data, geometry.straight, "straight",
                         length=(st.one_of(st.just(1.0), POS[0]), positive), start=VEC,
                         direction=VECNZ)
    elif kind == "arc":
        ok, shape = call(data, geometry.arc, "arc", radius=POS,
                         angle=(st.floats(0.1, 3.0), positive), start=VEC)
    elif kind == "helix":
        ok, shape = call(data, geometry.helix, "helix", radius=POS, pitch=POS,
                         turns=(st.floats(0.1, 1.5), positive), axis_start=VEC)
    else:
        pts = st.lists(st.lists(st.floats(-3, 3), min_size=3, max_size=3), min_size=2,
                       max_size=5)
        ok, shape = call(data, geometry.polyline, "polyline",
                         points=(pts, lambda v: isinstance(v, list) and len(v) >= 2
                                 and all(vector(p) for p in v)))
    if not ok:
        return
    if data.draw(st.booleans()):
        ok, section = call(data, Section.circle, "circle", E=(st.floats(1e2, 1e8), positive),
                           nu=(st.floats(-0.9, 0.49), lambda v: is_real(v) and -1 < v < 0.5),
                           radius=(st.floats(1e-3, 0.1), positive))
    else:
        ok, section = call(data, Section, "Section", **{n: POS for n in
                                                         ("EA", "GA1", "GA2", "EI1",
                                                          "EI2", "GJ")})
    if not ok:
        return
    ok, rod = call(data, lambda n_elements: Rod(shape, section, n_elements), "Rod",
                   n_elements=(st.integers(1, 6), lambda v: count(v, 1, 2_000_000)))
    if not ok:
        return
    for _ in range(data.draw(st.integers(1, 4))):
        what = data.draw(st.sampled_from(["clamp", "pin", "fix_rotation", "prescribe_rotation",
                                          "prescribe_displacement", "add_force",
                                          "add_moment", "add_distributed_force",
                                          "enable_contact"]))
        if what == "clamp":
            call(data, rod.clamp, what, where=WHERE)
        elif what in ("pin", "fix_rotation"):
            call(data, getattr(rod, what), what, where=WHERE, components=COMPONENTS)
        elif what == "prescribe_rotation":
            call(data, rod.prescribe_rotation, what, where=WHERE, rotation_vector=VEC)
        elif what == "prescribe_displacement":
            call(data, rod.prescribe_displacement, what, where=WHERE, displacement=VEC,
                 components=COMPONENTS)
        elif what in ("add_force", "add_moment"):
            name = what.split("_")[1]
            call(data, getattr(rod, what), what, where=WHERE,
                 **{name: (st.lists(st.floats(-1e-2, 1e-2), min_size=3, max_size=3),
                           vector)}, follower=BOOL, constant=BOOL)
        elif what == "add_distributed_force":
            call(data, rod.add_distributed_force, what, force=VEC)
        else:
            call(data, rod.enable_contact, what,
                 radius=(st.one_of(st.none(), st.floats(1e-3, 0.05)),
                         lambda v: v is None or positive(v)),
                 penalty=(st.none(), lambda v: v is None or positive(v)),
                 exclusion=(st.none(), lambda v: v is None or positive(v)))
    try:
        rod.check_constraints()
    except ValueError:
        return
    if rod.contact is not None and rod.mesh.n_elements > 3:
        return                                                  # keep examples fast
    ok, res = call(data, lambda n_steps: rod.solve(n_steps, min_step=0.1,
                                                   max_iterations=30),
                   "solve", too_long=lambda kw: kw["n_steps"] > 10,
                   n_steps=(st.integers(1, 2), lambda v: count(v, 1, 10**6)))
    if not ok:
        return
    if res.converged:                                          # no silent NaN
        for stp in res.steps:
            assert np.all(np.isfinite(stp.r)) and np.all(np.isfinite(stp.R)), "NaN state"
            assert np.isfinite(stp.energy), "NaN energy"
            for f, m in stp.reactions.values():
                assert np.all(np.isfinite(f)) and np.all(np.isfinite(m)), "NaN reaction"
    call(data, res.position, "position",
         s=(st.floats(0.0, 1.0).map(lambda x: x * rod.length),
            lambda v: is_real(v) and 0 <= v <= rod.length),
         step=(st.integers(-len(res.steps), len(res.steps) - 1),
               lambda v: count(v, -len(res.steps), len(res.steps) - 1)))
    call(data, res.reaction, "reaction", where=(st.just("start"), lambda v: False)) \
        if False else None


BASE = {
    "rod": {"geometry": {"type": "straight", "length": 1.0}, "n_elements": 4},
    "section": {"EA": 1e4, "GA1": 1e4, "GA2": 1e4, "EI1": 1.0, "EI2": 1.0, "GJ": 0.8,
                "radius": 0.01},
    "support": [{"where": "start", "kind": "clamp"}],
    "load": [{"kind": "force", "where": "end", "vector": [0.0, 0.01, 0.0],
              "follower": False}],
    "contact": {"enabled": False, "radius": 0.01},
    "solver": {"n_steps": 2},
    "output": {"basename": "rod", "json": False},
}
SCENE_KEYS = {   # key path -> validity of a value there
    ("rod", "n_elements"): lambda v: count(v, 1, 100_000),
    ("rod", "geometry", "length"): positive,
    ("rod", "geometry", "start"): vector,
    ("section", "EA"): positive, ("section", "GJ"): positive,
    ("section", "radius"): positive,
    ("support", 0, "where"): where,
    ("load", 0, "vector"): vector,
    ("load", 0, "follower"): flag,
    ("load", 0, "where"): where,
    ("contact", "enabled"): flag,
    ("contact", "radius"): positive,
    ("solver", "n_steps"): lambda v: count(v, 1, 1_000_000),
    ("output", "basename"): lambda v: isinstance(v, str) and v.strip() != ""
    and v not in (".", "..") and not any(c in v for c in "/\\\0"),
    ("output", "json"): flag,
}


def scene_example(data):
    import copy
    d = copy.deepcopy(BASE)
    keys = data.draw(st.lists(st.sampled_from(sorted(SCENE_KEYS, key=str)), min_size=1,
                              max_size=3, unique=True))
    invalid = []
    for path in keys:
        v = data.draw(ANYTHING, label=str(path))
        t = d
        for k in path[:-1]:
            t = t[k]
        t[path[-1]] = v
        if not SCENE_KEYS[path](v):
            invalid.append(".".join(str(k) for k in path).replace(".0.", "[0]."))
    invalid = [n.replace("support.0", "support[0]").replace("load.0", "load[0]")
               for n in invalid]
    try:
        with np.errstate(all="ignore"):
            scene = load_scene(d)
    except ValueError as err:
        msg = str(err)
        named = [n for n in invalid if n in msg]
        if invalid and not named:               # (the build stops at its first problem)
            raise Bad(f"scene with invalid {invalid}: the message names none: "
                      f"{msg}") from None
        return
    except Exception as err:
        raise Bad(f"load_scene raised {type(err).__name__}: {err}") from err
    if invalid:
        raise Bad(f"scene accepted invalid {invalid} (silent coercion): {d}")
    assert scene.data["rod"]["n_elements"] == d["rod"]["n_elements"]


SLOW = settings(derandomize=True, max_examples=2000, deadline=None,
                suppress_health_check=list(HealthCheck))
FAST = settings(derandomize=True, max_examples=100, deadline=None,
                suppress_health_check=list(HealthCheck))


@pytest.mark.slow
@SLOW
@given(st.data())
def test_fuzz_api(data):
    api_example(data)


@FAST
@given(st.data())
def test_fuzz_api_fast(data):
    api_example(data)


@pytest.mark.slow
@SLOW
@given(st.data())
def test_fuzz_scene(data):
    scene_example(data)


@FAST
@given(st.data())
def test_fuzz_scene_fast(data):
    scene_example(data)
