"""Scenes: a rod problem described in a TOML file, validated on load.

A scene names the reference shape, the section, the supports, the loads,
contact, the solver controls and the outputs; ``docs/scenes.md`` is the
reference of every key.  :func:`load_scene` checks **every** key before
anything is built or written: unknown keys (with the closest valid name),
wrong types, values out of range, NaN and inf are reported with the key's
table path (``support[1].where``), the value and what is allowed, all
problems at once; then the rod is built, which reports the boundary
conditions the :class:`~skfem_rod.Rod` itself rejects (a rigid-body mode
left free, an arclength that is not a node) and two supports that would
prescribe the same component of one node.

>>> scene = load_scene({
...     "rod": {"geometry": {"type": "straight", "length": 1.0}, "n_elements": 4},
...     "section": {"EA": 1e4, "GA1": 1e4, "GA2": 1e4, "EI1": 1.0, "EI2": 1.0, "GJ": 0.8},
...     "support": [{"where": "start", "kind": "clamp"}],
...     "load": [{"kind": "moment", "where": "end", "vector": [0.0, 0.0, 1.0]}],
...     "solver": {"n_steps": 2}})
>>> scene.solve().converged
True
>>> load_scene({"rod": {"n_element": 4}})         # doctest: +ELLIPSIS
Traceback (most recent call last):
...
skfem_rod.scene.SceneError: 4 problems in the scene:
  - rod.n_element is not a known key; did you mean "n_elements"? ...
"""
import contextlib
import difflib
import json
import math
import numbers
import os
import pathlib
import time
from dataclasses import MISSING, dataclass

import numpy as np

__all__ = ["Scene", "SceneError", "load_scene", "read_toml"]

#: sanity limits of what a scene may ask for (beyond them: the Python API)
MAX_ELEMENTS = 100_000
MAX_QUAD = 10
MAX_POINTS = 10_000
#: largest scene file read
MAX_FILE_BYTES = 2**20
CAMERAS = ("iso", "xy", "xz", "yz", "yx", "zx", "zy")


class SceneError(ValueError):
    """Invalid scene: ``problems`` lists one message per problem."""

    def __init__(self, problems):
        self.problems = list(problems)
        if len(self.problems) == 1:
            msg = self.problems[0]
        else:
            msg = (f"{len(self.problems)} problems in the scene:\n"
                   + "\n".join("  - " + p for p in self.problems))
        super().__init__(msg)


# ---------------------------------------------------------------------------
# value checks: each returns the normalized value or raises _Bad
# ---------------------------------------------------------------------------
class _Bad(Exception):
    def __init__(self, note=""):
        self.note = note


def show_value(v, limit=80):
    """A value as it would read in TOML (shortened)."""
    if isinstance(v, np.ndarray) and v.ndim == 0:
        v = v.item()
    if isinstance(v, (bool, np.bool_)):
        s = "true" if v else "false"
    elif isinstance(v, str):
        s = json.dumps(v)
    elif isinstance(v, numbers.Real):
        f = float(v) if not isinstance(v, numbers.Integral) else None
        s = (str(int(v)) if f is None else "nan" if math.isnan(f)
             else ("inf" if f > 0 else "-inf") if math.isinf(f) else repr(f))
    elif isinstance(v, (list, tuple, np.ndarray)):
        s = "[" + ", ".join(show_value(x, limit) for x in list(v)[:8]) \
            + (", ..." if len(v) > 8 else "") + "]"
    elif isinstance(v, dict):
        s = "{" + ", ".join(f"{k} = {show_value(x, limit)}" for k, x in list(v.items())[:4]) \
            + (", ..." if len(v) > 4 else "") + "}"
    else:
        s = f"{v!r} ({type(v).__name__})"
    return s if len(s) <= limit else s[:limit - 3] + "..."


def _real(v):
    """``v`` as a float (NaN/inf kept) or _Bad if it is not a real number."""
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real):
        raise _Bad()
    try:
        return float(v)
    except (OverflowError, ValueError, TypeError):
        raise _Bad() from None


def _finite(v):
    x = _real(v)
    if not math.isfinite(x):
        raise _Bad("NaN and inf are not allowed")
    return x


def _fmt(x):
    return f"{x:g}"


class Number:
    def __init__(self, lo=None, hi=None, lo_open=True, hi_open=True):
        self.lo, self.hi, self.lo_open, self.hi_open = lo, hi, lo_open, hi_open
        if lo is not None and hi is not None:
            self.expected = (f"a number in {'(' if lo_open else '['}{_fmt(lo)}, "
                             f"{_fmt(hi)}{')' if hi_open else ']'}")
        elif lo is not None:
            self.expected = f"a finite number {'>' if lo_open else '>='} {_fmt(lo)}"
        else:
            self.expected = "a finite number"

    def __call__(self, v):
        x = _finite(v)
        if self.lo is not None and (x < self.lo or (self.lo_open and x == self.lo)):
            raise _Bad()
        if self.hi is not None and (x > self.hi or (self.hi_open and x == self.hi)):
            raise _Bad()
        return x


class Integer:
    def __init__(self, lo, hi=None):
        self.lo, self.hi = lo, hi
        self.expected = (f"an integer in [{lo}, {hi}]" if hi is not None
                         else f"an integer >= {lo}")

    def __call__(self, v):
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Integral):
            raise _Bad()
        if v < self.lo or (self.hi is not None and v > self.hi):
            raise _Bad()
        return int(v)


class Boolean:
    expected = "true or false"

    def __call__(self, v):
        if not isinstance(v, (bool, np.bool_)):
            raise _Bad()
        return bool(v)


class Choice:
    def __init__(self, *options):
        self.options = options
        self.expected = "one of " + ", ".join(json.dumps(o) for o in options)

    def __call__(self, v):
        if isinstance(v, str) and v in self.options:
            return v
        if isinstance(v, str):
            close = difflib.get_close_matches(v, self.options, n=1)
            raise _Bad(f'did you mean "{close[0]}"?' if close else "")
        raise _Bad()


class Text:
    expected = "a non-empty string"

    def __call__(self, v):
        if not (isinstance(v, str) and v.strip()):
            raise _Bad()
        return v


class Basename:
    expected = "a file name stem (a non-empty string without /, \\ or NUL)"

    def __call__(self, v):
        if not (isinstance(v, str) and v.strip()) or v in (".", "..") \
                or any(c in v for c in "/\\\0" + os.sep):
            raise _Bad()
        return v


class Directory:
    expected = "a directory path (a non-empty string without NUL)"

    def __call__(self, v):
        if not (isinstance(v, str) and v.strip()) or "\0" in v:
            raise _Bad()
        return v


def _seq(v):
    if isinstance(v, np.ndarray):
        if v.ndim == 0:
            raise _Bad()
        return list(v)
    if not isinstance(v, (list, tuple)):
        raise _Bad()
    return list(v)


class Vector:
    def __init__(self, nonzero=False):
        self.nonzero = nonzero
        self.expected = ("an array of 3 finite numbers, not all zero" if nonzero
                         else "an array of 3 finite numbers [x, y, z]")

    def __call__(self, v):
        items = _seq(v)
        if len(items) != 3:
            raise _Bad()
        out = [_finite(x) for x in items]
        if self.nonzero and not any(out):
            raise _Bad()
        return out


class Points:
    def __init__(self, minimum=2, what="points"):
        self.minimum = minimum
        self.expected = (f"an array of {minimum} to {MAX_POINTS} {what} "
                         "[x, y, z] of finite numbers")

    def __call__(self, v):
        items = _seq(v)
        if not self.minimum <= len(items) <= MAX_POINTS:
            raise _Bad(f"got {len(items)}")
        out = []
        for k, p in enumerate(items):
            try:
                out.append(Vector()(p))
            except _Bad as bad:
                raise _Bad(f"item {k} = {show_value(p)} is not [x, y, z]"
                           + (f" ({bad.note})" if bad.note else "")) from None
        return out


class Matrix6:
    expected = "a 6 x 6 array (6 rows of 6 finite numbers)"

    def __call__(self, v):
        rows = _seq(v)
        if len(rows) != 6:
            raise _Bad()
        out = []
        for row in rows:
            row = _seq(row)
            if len(row) != 6:
                raise _Bad()
            out.append([_finite(x) for x in row])
        return out


#: tolerance of the support ``axes``: largest |cos| between two normalized
#: axes, and largest difference of the axes of two supports at one node
AXES_TOL = 1e-6


class Axes:
    """Three local axes of a support (rows), as ``Rod.support_basis`` takes
    them as the columns of ``Q``: each non-zero (normalized here), mutually
    orthogonal to :data:`AXES_TOL` and right-handed; returned as the rows
    of the nearest rotation (exactly orthonormal)."""
    expected = (f"3 axes [[x, y, z], [x, y, z], [x, y, z]] of finite numbers, not zero "
                f"(normalized on load), mutually orthogonal (|cos| <= {AXES_TOL:g}) and "
                f"right-handed (axes[0] x axes[1] = axes[2]): the rows of a rotation matrix")

    def __call__(self, v):
        items = _seq(v)
        if len(items) != 3:
            raise _Bad(f"got {len(items)} item{'s' if len(items) != 1 else ''}, not 3 axes")
        rows = []
        for k, a in enumerate(items):
            try:
                rows.append(Vector(nonzero=True)(a))
            except _Bad as bad:
                raise _Bad(f"axes[{k}] = {show_value(a)} is not a non-zero [x, y, z]"
                           + (f"; {bad.note}" if bad.note else "")) from None
        A = np.array(rows)
        A /= np.abs(A).max(axis=1, keepdims=True)      # no overflow in the norm
        A /= np.linalg.norm(A, axis=1, keepdims=True)
        for i, j in ((0, 1), (0, 2), (1, 2)):
            cos = float(A[i] @ A[j])
            if abs(cos) > AXES_TOL:
                raise _Bad(f"axes[{i}] and axes[{j}] are not orthogonal: cos = {cos:.3g}, "
                           f"tolerance {AXES_TOL:g}")
        det = float(np.linalg.det(A))
        if det < 0:
            raise _Bad(f"left-handed: axes[0] x axes[1] . axes[2] = {det:.6g}; reverse "
                       "one axis (e.g. axes[2] -> -axes[2])")
        u, _, vt = np.linalg.svd(A)                   # nearest rotation (polar factor)
        return (u @ vt).tolist()


class Where:
    expected = '"start", "end" or an arclength >= 0 at a node'

    def __call__(self, v):
        if isinstance(v, str):
            return Choice("start", "end")(v)
        x = _finite(v)
        if x < 0:
            raise _Bad()
        return x


class Components:
    expected = "a non-empty array of distinct axis indices 0, 1, 2 (x, y, z)"

    def __call__(self, v):
        items = [v] if isinstance(v, numbers.Integral) and not isinstance(v, bool) else _seq(v)
        out = [Integer(0, 2)(c) for c in items]
        if not out or len(set(out)) != len(out):
            raise _Bad()
        return sorted(out)


class LoadPath:
    expected = ("an array of >= 2 finite load factors starting at 0, "
                "consecutive values different, e.g. [0, 1, 0]")

    def __call__(self, v):
        items = _seq(v)
        if not 2 <= len(items) <= MAX_POINTS:
            raise _Bad()
        out = [_finite(x) for x in items]
        if out[0] != 0:
            raise _Bad("it must start at 0")
        if any(a == b for a, b in zip(out, out[1:])):
            raise _Bad("consecutive values must differ")
        return out


class WindowSize:
    expected = "[width, height] in pixels, integers in [16, 8192]"

    def __call__(self, v):
        items = _seq(v)
        if len(items) != 2:
            raise _Bad()
        return [Integer(16, 8192)(x) for x in items]


# ---------------------------------------------------------------------------
# the schema
# ---------------------------------------------------------------------------
_REQUIRED = object()


@dataclass(frozen=True)
class Key:
    check: object
    default: object = _REQUIRED
    doc: str = ""


POSITIVE = Number(0)
VECTOR = Vector()

GEOMETRY = {
    "straight": {
        "length": Key(POSITIVE, doc="rod length"),
        "start": Key(VECTOR, [0.0, 0.0, 0.0], "position of s = 0"),
        "direction": Key(Vector(nonzero=True), [1.0, 0.0, 0.0], "tangent d3"),
        "d1": Key(Vector(nonzero=True), None,
                  "first director (not parallel to direction); default: z x direction"),
    },
    "arc": {
        "radius": Key(POSITIVE, doc="arc radius"),
        "angle": Key(POSITIVE, doc="subtended angle (rad)"),
        "start": Key(VECTOR, [0.0, 0.0, 0.0], "position of s = 0"),
        "tangent": Key(Vector(nonzero=True), [1.0, 0.0, 0.0], "tangent at s = 0"),
        "toward": Key(Vector(nonzero=True), [0.0, 1.0, 0.0],
                      "direction the arc curves toward (not parallel to tangent)"),
    },
    "helix": {
        "radius": Key(POSITIVE, doc="helix radius (about +z)"),
        "pitch": Key(POSITIVE, doc="rise per turn"),
        "turns": Key(POSITIVE, doc="number of turns"),
        "axis_start": Key(VECTOR, [0.0, 0.0, 0.0], "point of the axis at s = 0"),
    },
    "polyline": {
        "points": Key(Points(), doc="points a cubic spline passes through"),
        "d1": Key(Points(what="directors"), None,
                  "first director at each point (as many as points)"),
    },
}

SECTIONS = {
    "stiffness": {
        **{n: Key(POSITIVE, doc=d) for n, d in (
            ("EA", "axial stiffness"), ("GA1", "shear stiffness along d1"),
            ("GA2", "shear stiffness along d2"), ("EI1", "bending stiffness about d1"),
            ("EI2", "bending stiffness about d2"), ("GJ", "torsional stiffness"))},
        "radius": Key(POSITIVE, None, "radius (contact, rendering)"),
    },
    "circle": {
        "E": Key(POSITIVE, doc="Young's modulus"),
        "nu": Key(Number(-1, 0.5), doc="Poisson's ratio"),
        "radius": Key(POSITIVE, doc="radius of the solid circle"),
        "shear_coefficient": Key(POSITIVE, None, "default: Cowper's 6(1+nu)/(7+6nu)"),
    },
    "matrix": {
        "matrix": Key(Matrix6(), doc="symmetric positive-definite 6 x 6 stiffness, "
                      "strain order (v1, v2, v3, u1, u2, u3)"),
        "radius": Key(POSITIVE, None, "radius (contact, rendering)"),
    },
}

_AXES = Key(Axes(), None, "local axes the components (and displacement) refer to "
                         "(Rod.support_basis); default: x, y, z")
SUPPORTS = {
    "clamp": {},
    "pin": {"components": Key(Components(), [0, 1, 2], "position components held"),
            "axes": _AXES},
    "fix_rotation": {"components": Key(Components(), [0, 1, 2], "spin components held"),
                     "axes": _AXES},
    "prescribe_rotation": {
        "rotation_vector": Key(VECTOR, doc="spatial rotation vector at load factor 1")},
    "prescribe_displacement": {
        "displacement": Key(VECTOR, doc="displacement at load factor 1"),
        "components": Key(Components(), [0, 1, 2], "components prescribed"),
        "axes": _AXES},
}
SUPPORT_COMMON = {
    "kind": Key(Choice(*SUPPORTS), doc="kind of support"),
    "where": Key(Where(), doc="node of the support"),
}

LOADS = {
    "force": {"where": Key(Where(), doc="node loaded"),
              "follower": Key(Boolean(), False, "rotates with the section")},
    "moment": {"where": Key(Where(), doc="node loaded"),
               "follower": Key(Boolean(), False, "rotates with the section")},
    "distributed_force": {},
    "distributed_torque": {},
}
LOAD_COMMON = {
    "kind": Key(Choice(*LOADS), doc="kind of load"),
    "vector": Key(VECTOR, doc="value at load factor 1 (per unit length if distributed)"),
}

def _checker(spec):
    """The scene's validator of an option :class:`~skfem_rod.options.Spec`
    (:class:`~skfem_rod.options.SolverOptions`,
    :class:`~skfem_rod.contact.ContactOptions`)."""
    if spec.kind == "number":
        return Number(spec.lo, spec.hi, lo_open=spec.lo_open, hi_open=False)
    if spec.kind == "integer":
        return Integer(spec.lo, spec.hi)
    if spec.kind == "boolean":
        return Boolean()
    return Choice(*spec.choices)


def _contact_keys():
    from .contact import ContactOptions
    from .options import option_specs
    keys = {"enabled": Key(Boolean(), True, "switch self-contact on")}
    keys.update({n: Key(_checker(spec), None if default is MISSING else default, spec.doc)
                 for n, (spec, default) in option_specs(ContactOptions).items()})
    return keys


CONTACT = _contact_keys()


def _solver_keys():
    """The [solver] table: the keys of every method, and each method's own
    (from the option specs of :mod:`skfem_rod.options`)."""
    from .options import barrier_specs, option_specs
    common = {"n_steps": Key(Integer(1, 1_000_000), 1, "equal pseudo-time steps"),
              "path": Key(LoadPath(), [0.0, 1.0], "load factors at equal pseudo-times"),
              "method": Key(Choice(*METHODS), "newton",
                            "load stepping; pseudo-arclength continuation (through limit "
                            "points; path must be [0, lam_end], n_steps sets the first "
                            "step); or the node barrier's energy Newton (contact on)")}

    def keys(specs):
        return {n: Key(_checker(spec), default, spec.doc)
                for n, (spec, default) in specs.items()}
    newton = keys(option_specs())
    arclength = {**newton, "max_steps": Key(Integer(1, 1_000_000), 200,
                                            "arclength: most continuation steps")}
    return common, {"newton": newton, "arclength": arclength, "barrier": keys(barrier_specs())}


#: the solve methods of the [solver] table (``Rod.solve(method=...)``)
METHODS = ("newton", "arclength", "barrier")
SOLVER_COMMON, SOLVER_METHODS = _solver_keys()

OUTPUT = {
    "directory": Key(Directory(), None, "output directory (default output/<scene name>)"),
    "basename": Key(Basename(), None, "file name stem (default: the scene name)"),
    "json": Key(Boolean(), True, "JSON summary <basename>.json"),
    "vtu": Key(Boolean(), False, "VTU per step + <basename>.pvd/.xdmf"),
    "render": Key(Boolean(), False, "PNG of the last converged step"),
    "per_element": Key(Integer(1, 64), 8, "samples per element (VTU, render)"),
    "camera": Key(Choice(*CAMERAS), "iso", "render view"),
    "window_size": Key(WindowSize(), [1024, 768], "render size (pixels)"),
    "title": Key(Text(), None, "render title (default: the scene title)"),
    "zoom": Key(POSITIVE, None, "camera zoom instead of the automatic fit"),
}

ROD = {
    "geometry": Key(None, doc="reference shape: [rod.geometry]"),
    "n_elements": Key(Integer(1, MAX_ELEMENTS), doc="number of cubic elements"),
    "n_quad": Key(Integer(1, MAX_QUAD), 3, "Gauss points per element"),
}

TOP = ("title", "rod", "section", "support", "load", "contact", "solver", "output",
       "sweep")


# ---------------------------------------------------------------------------
# the validator
# ---------------------------------------------------------------------------
class _Checker:
    def __init__(self):
        self.problems = []

    def bad(self, msg):
        self.problems.append(msg)

    def value(self, path, v, check):
        try:
            return check(v), True
        except _Bad as bad:
            note = f" ({bad.note})" if bad.note else ""
            self.bad(f"{path} = {show_value(v)}: expected {check.expected}{note}")
            return None, False

    def table(self, path, v, what):
        if isinstance(v, dict):
            return True
        self.bad(f"{path} = {show_value(v)}: expected a table ({what})")
        return False

    def keys(self, path, table, allowed, label, others=None, tag=None):
        """Report keys of ``table`` not in ``allowed``, with the closest valid
        name (and the variants ``others`` of a typed table that have it)."""
        for k in table:
            if k in allowed:
                continue
            ks = str(k)
            close = difflib.get_close_matches(ks, [str(a) for a in allowed], n=1)
            owners = [o for o, keys in (others or {}).items() if k in keys]
            msg = f"{path}.{ks}" if path else ks
            msg += " is not a known key"
            if owners:
                msg += f" here (only for {tag} = " + " or ".join(
                    json.dumps(o) for o in owners) + ")"
            msg += f'; did you mean "{close[0]}"?' if close else "."
            self.bad(f"{msg} Allowed in {label}: {', '.join(allowed)}")

    def fill(self, path, table, spec):
        """Check the keys of ``spec`` present in ``table`` and fill defaults."""
        out = {}
        for name, key in spec.items():
            if key.check is None:
                continue
            if name not in table:
                if key.default is _REQUIRED:
                    self.bad(f"{path}.{name} is missing: expected {key.check.expected}"
                             + (f" ({key.doc})" if key.doc else ""))
                else:
                    out[name] = key.default
                continue
            val, ok = self.value(f"{path}.{name}", table[name], key.check)
            if ok:
                out[name] = val
        return out

    def typed(self, path, table, tag, variants, common, label, default_tag=None):
        """A table whose keys depend on the variant named by ``table[tag]``
        (or ``default_tag`` when absent)."""
        if tag in table:
            name = self.value(f"{path}.{tag}", table[tag], common[tag].check)[0]
        else:
            name = default_tag
            if name is None:
                self.bad(f"{path}.{tag} is missing: expected {common[tag].check.expected}"
                         + (f" ({common[tag].doc})" if common[tag].doc else ""))
        if name is None:                      # unknown variant: check what we can
            self.keys(path, table, list(common) + sorted(
                {k for v in variants.values() for k in v}), label)
            return None
        spec = {**common, **variants[name]}
        others = {o: keys for o, keys in variants.items() if o != name}
        self.keys(path, table, list(spec), f"{label} ({tag} = {json.dumps(name)})",
                  others, tag)
        out = self.fill(path, table, {k: v for k, v in spec.items() if k != tag})
        out[tag] = name
        return out


def _section_kind(table, checker):
    """The section's type, inferred from its keys when not given; None (and
    a problem reported) when the keys of several types are mixed."""
    if "type" in table:
        return None
    own = {kind: set(spec) - {"radius"} for kind, spec in SECTIONS.items()}
    present = {kind: sorted(own[kind] & set(table)) for kind in own}
    present = {kind: keys for kind, keys in present.items() if keys}
    if len(present) > 1:
        checker.bad("section mixes the keys of " + " and of ".join(
            f'a {json.dumps(kind)} section ({", ".join(keys)})'
            for kind, keys in present.items())
            + "; give the keys of one type only")
        return None
    return next(iter(present), "stiffness")


def _check_barrier(c, out):
    """What ``method = "barrier"`` needs of the rest of a scene: contact on
    (rotational friction only on the pivot about the normal), and dead
    forces (an energy)."""
    cont = out.get("contact")
    if not (cont and cont.get("enabled")):
        c.bad('solver.method = "barrier" is a contact solve: add a [contact] table with '
              "enabled = true (its radius, exclusion and gamma_T are used)")
    elif (cont.get("gamma_R") or 0) > 0 and cont.get("rotational_slip", "twist") != "pivot":
        c.bad(f'contact.gamma_R = {show_value(cont["gamma_R"])} with contact.rotational_slip = '
              f'{show_value(cont.get("rotational_slip", "twist"))}: solver.method = "barrier" '
              'has the rotational law on the pivot about the contact normal only: set '
              'rotational_slip = "pivot" (or method = "newton")')
    for k, load in enumerate(out.get("load") or []):
        if load is None:
            continue
        if load["kind"] in ("moment", "distributed_torque") or load.get("follower"):
            what = "a follower force" if load["kind"] == "force" else f'a {load["kind"]}'
            c.bad(f'load[{k}] is {what}: solver.method = "barrier" minimizes an energy and '
                  "takes dead forces only (prescribe rotations by a support instead)")


def validate_data(data):
    c = _Checker()
    if not isinstance(data, dict):
        raise SceneError([f"a scene must be a table of tables ([rod], [section], ...), "
                          f"got {show_value(data)}"])
    c.keys("", data, list(TOP), "the top level")
    out = {}
    if "title" in data:
        out["title"] = c.value("title", data["title"], Text())[0]

    # [rod] -----------------------------------------------------------------
    rod = data.get("rod")
    if rod is None:
        c.bad("rod is missing: expected a table [rod] with geometry and n_elements")
    elif c.table("rod", rod, "[rod] with geometry, n_elements, n_quad"):
        c.keys("rod", rod, list(ROD), "[rod]")
        out["rod"] = c.fill("rod", rod, ROD)
        g = rod.get("geometry")
        if g is None:
            c.bad("rod.geometry is missing: expected a table [rod.geometry] with a type "
                  '("straight", "arc", "helix" or "polyline") and its parameters')
        elif c.table("rod.geometry", g, "[rod.geometry] with a type and its parameters"):
            out["rod"]["geometry"] = c.typed(
                "rod.geometry", g, "type", GEOMETRY,
                {"type": Key(Choice(*GEOMETRY), doc="shape")}, "[rod.geometry]")

    # [section] ---------------------------------------------------------------
    sec = data.get("section")
    if sec is None:
        c.bad("section is missing: expected a table [section] (stiffnesses EA, GA1, GA2, "
              "EI1, EI2, GJ; or circle E, nu, radius; or matrix)")
    elif c.table("section", sec, "[section]"):
        kind = _section_kind(sec, c)
        if kind is not None or "type" in sec:
            common = {"type": Key(Choice(*SECTIONS), kind, "kind of section")}
            out["section"] = c.typed("section", sec, "type", SECTIONS, common,
                                     "[section]", default_tag=kind)

    # [[support]], [[load]] -------------------------------------------------
    for name, variants, common in (("support", SUPPORTS, SUPPORT_COMMON),
                                   ("load", LOADS, LOAD_COMMON)):
        items = data.get(name, [])
        if isinstance(items, dict):
            c.bad(f"{name} = {show_value(items)}: expected an array of tables "
                  f"([[{name}]] entries, one per {name}), got a single table")
            continue
        if not isinstance(items, (list, tuple)):
            c.bad(f"{name} = {show_value(items)}: expected an array of tables ([[{name}]])")
            continue
        out[name] = []
        for k, item in enumerate(items):
            path = f"{name}[{k}]"
            if c.table(path, item, f"a [[{name}]] entry"):
                out[name].append(c.typed(path, item, "kind", variants, common,
                                         f"[[{name}]]"))

    # [contact], [solver], [output] -----------------------------------------
    for name, spec in (("contact", CONTACT), ("output", OUTPUT)):
        if name in data and c.table(name, data[name], f"[{name}]"):
            c.keys(name, data[name], list(spec), f"[{name}]")
            out[name] = c.fill(name, data[name], spec)
    if "solver" in data and c.table("solver", data["solver"], "[solver]"):
        out["solver"] = c.typed("solver", data["solver"], "method", SOLVER_METHODS,
                                SOLVER_COMMON, "[solver]", default_tag="newton")
    sv = out.get("solver") or {}
    out.setdefault("solver", {k: key.default for k, key in
                              {**SOLVER_COMMON, **SOLVER_METHODS["newton"]}.items()})
    if sv.get("method") == "arclength" and len(sv.get("path") or []) != 2:
        c.bad(f"solver.path: with method = \"arclength\" the path must be [0, lam_end] "
              f"(the continuation turns back by itself), got {sv.get('path')!r}")
    if sv.get("method") == "barrier":
        _check_barrier(c, out)
    if "sweep" in data:        # each swept value validated as the key it replaces
        from .sweep_table import validate_sweep
        out["sweep"], problems = validate_sweep(
            data["sweep"], {k: v for k, v in data.items() if k != "sweep"}, c.problems,
            validate=validate_data, show=show_value, error=SceneError)
        c.problems += problems

    if c.problems:
        raise SceneError(c.problems)
    out.setdefault("support", [])
    out.setdefault("load", [])
    return out


# ---------------------------------------------------------------------------
# building
# ---------------------------------------------------------------------------
def _wrapped(path, err, keys=()):
    """Prefix an API error message with the table path (and the key it names)."""
    msg = str(err)
    first = msg.split(" ", 1)[0].rstrip(":=")
    if first.startswith("where="):
        first = "where"
    return f"{path}.{first}: {msg}" if first in keys else f"{path}: {msg}"


def _call(path, keys, f, *args, **kwargs):
    try:
        return f(*args, **kwargs)
    except ValueError as err:
        raise SceneError([_wrapped(path, err, keys)]) from None
    except ArithmeticError as err:     # e.g. Section.circle(radius=1e300) overflows
        raise SceneError([f"{path}: these values are out of floating-point range "
                          f"({type(err).__name__}: {err})"]) from None


def _shape(g):
    import skfem_rod.geometry as geometry
    kw = {k: v for k, v in g.items() if k != "type" and v is not None}
    if g["type"] == "straight" and g["d1"] is not None:
        t, d1 = (np.asarray(v) / np.abs(v).max() for v in (g["direction"], g["d1"]))
        if np.linalg.norm(np.cross(t, d1)) < 1e-8 * np.linalg.norm(t) * np.linalg.norm(d1):
            raise SceneError([f"rod.geometry.d1 = {show_value(g['d1'])}: expected a vector "
                              f"not parallel to direction = {show_value(g['direction'])}"])
    return _call("rod.geometry", list(kw), getattr(geometry, g["type"]), **kw)


def _section(s):
    from .section import Section
    kw = {k: v for k, v in s.items() if k != "type" and v is not None}
    if s["type"] == "circle":
        f = Section.circle
    elif s["type"] == "matrix":
        f = Section.from_matrix
        kw["C"] = kw.pop("matrix")
        for k in range(6):
            if not kw["C"][k][k] > 0:
                raise SceneError([f"section.matrix: diagonal entry [{k}][{k}] = "
                                  f"{show_value(kw['C'][k][k])}: expected > 0 (the stiffness "
                                  "must be positive definite)"])
    else:
        f = Section
    return _call("section", list(kw) + ["matrix"], f, **kw)


def _same_basis(bases, node, axes, who):
    """The supports of one node share one basis (``Rod.support_basis`` is
    per node): ``axes`` of support ``who`` must equal those of the supports
    of ``node`` seen before (None: the spatial axes)."""
    prev = bases.setdefault(node, (who, axes))
    a, b = (np.eye(3) if x is None else np.asarray(x) for x in (axes, prev[1]))
    if np.abs(a - b).max() > AXES_TOL:
        def say(x):
            return ("no axes (x, y, z)" if x is None
                    else f"axes = {show_value(np.round(np.asarray(x), 9).tolist(), 120)}")
        raise SceneError([
            f"{who} has {say(axes)} but {prev[0]} at the same node {node} has "
            f"{say(prev[1])}: the pin, fix_rotation and prescribe_displacement supports "
            "of one node share one basis; give them the same axes (or none)"])


def _build(d):
    from .model import Rod
    shape = _shape(d["rod"]["geometry"])
    section = _section(d["section"])
    rod = _call("rod", ["n_elements", "n_quad"], Rod, shape, section,
                d["rod"]["n_elements"], d["rod"]["n_quad"])
    if not (np.all(np.isfinite(rod.r0)) and np.all(np.isfinite(rod.R0))
            and np.all(np.isfinite(rod.eps0))):
        raise SceneError(["rod.geometry: the reference shape has non-finite positions, "
                          "frames or strains (NaN/inf): check its parameters"])

    def node(path, where):
        if not isinstance(where, str) and where > rod.length * (1 + 1e-12):
            raise SceneError([f"{path}.where = {show_value(where)}: expected an arclength in "
                              f"[0, {rod.length:g}] (the rod length)"])
        return _call(path, ["where"], rod.node, where)

    bases = {}
    for k, sup in enumerate(d["support"]):      # conflicts: Rod's own check (Support.hold)
        path, kind = f"support[{k}]", sup["kind"]
        n = node(path, sup["where"])
        who = f"{path} ({kind} at {show_value(sup['where'])})"
        args = {k: v for k, v in sup.items() if k not in ("kind", "where", "axes")}
        if "axes" in sup:                  # pin, fix_rotation, prescribe_displacement
            _same_basis(bases, n, sup["axes"], who)
            if sup["axes"] is not None:
                _call(path, ["axes"], rod.support_basis, sup["where"],
                      np.array(sup["axes"]).T)
        _call(path, list(args), getattr(rod, kind), sup["where"], **args)
    for k, load in enumerate(d["load"]):
        path, kind = f"load[{k}]", load["kind"]
        if kind in ("force", "moment"):
            node(path, load["where"])
            f = rod.add_force if kind == "force" else rod.add_moment
            _call(path, ["vector"], f, load["where"], load["vector"], load["follower"])
        else:
            f = getattr(rod, "add_" + kind)
            _call(path, ["vector"], f, load["vector"])
    cont = d.get("contact")
    if cont is not None and cont["enabled"]:
        kw = {k: v for k, v in cont.items() if k != "enabled" and v is not None}
        if "radius" not in kw and rod.section.radius is None:
            raise SceneError(["contact.radius is missing: contact needs a radius; give "
                              "contact.radius or section.radius"])
        _call("contact", list(kw), rod.enable_contact, **kw)
    _call("support", [], rod.check_constraints)
    return rod


def _solver_options(d):
    """The [solver] table's keyword arguments of ``Rod.solve`` besides
    ``n_steps`` and ``path`` (a key left at None takes the solve's
    default: the barrier's force)."""
    return {k: v for k, v in d["solver"].items()
            if k not in ("n_steps", "path") and v is not None}


# ---------------------------------------------------------------------------
# the scene
# ---------------------------------------------------------------------------
class Scene:
    """A validated scene (made by :func:`load_scene`).

    Attributes
    ----------
    data : dict
        The scene with every default filled in (echoed in the JSON summary).
    name : str
        The scene file's stem (or the ``name`` given to :func:`load_scene`).
    source : str or None
        The scene file.
    """

    def __init__(self, data, name="scene", source=None, _rod=None):
        self.data = data
        self.name = name
        self.source = source
        self._rod = _rod

    def __repr__(self):
        return f"Scene({self.name!r}, source={self.source!r})"

    @property
    def title(self):
        return self.data.get("title") or self.name

    @property
    def output(self):
        """The [output] table (defaults filled in), or None if absent."""
        return self.data.get("output")

    def build(self):
        """A new :class:`~skfem_rod.Rod` with the scene's shape, section,
        supports, loads and contact."""
        return _build(self.data)

    def solve(self, callback=None):
        """Build and solve; returns the :class:`~skfem_rod.Result` (no files)."""
        rod, self._rod = (self._rod or self.build()), None
        s = self.data["solver"]
        return rod.solve(s["n_steps"], path=s["path"], callback=callback,
                         **_solver_options(self.data))

    def run(self, out=None):
        """Solve and write what [output] asks for (into ``out`` if given);
        returns the :class:`~skfem_rod.Result`.  Without an [output] table
        and without ``out`` nothing is written."""
        t0 = time.perf_counter()
        result = self.solve()
        self.write(result, out=out, wall_time=time.perf_counter() - t0)
        return result

    def output_directory(self, out=None):
        o = self.output or {}
        return os.fspath(out) if out is not None else (
            o.get("directory") or os.path.join("output", self.name))

    def open_output(self, out=None):
        """An :class:`OutputStream` for a run: the output directory checked
        and cleared of an earlier run's files now, before the solve (OSError
        or ValueError if it cannot be used)."""
        return OutputStream(self, out)

    def write(self, result, out=None, wall_time=None):
        """Write the outputs of ``result`` ([output], or its defaults when
        ``out`` is given without an [output] table); returns the paths.  A
        stopped solve writes its converged steps."""
        o = self.output
        if o is None:
            if out is None:
                return []
            o = {k: key.default for k, key in OUTPUT.items()}
        directory = self.output_directory(out)
        base = o["basename"] or self.name
        written = []
        if not (o["json"] or o["vtu"] or o["render"]):
            return written
        os.makedirs(directory, exist_ok=True)
        if result.steps and o["vtu"]:
            written += result.write_series(directory, base, o["per_element"])
        if result.steps and o["render"]:
            kw = dict(camera=o["camera"], window_size=tuple(o["window_size"]),
                      title=o["title"] or self.title, per_element=o["per_element"])
            if o["zoom"] is not None:
                kw["zoom"] = o["zoom"]
            written.append(result.render(os.path.join(directory, base + ".png"), **kw))
        if o["json"]:
            from .export import write_json
            path = os.path.join(directory, base + ".json")
            data = summary(self, result, wall_time)
            data["files"] = [os.path.basename(p) for p in written + [path]]
            written.append(write_json(path, data))
        return written


class OutputStream:
    """The outputs of a run, written while it solves: the output directory
    is checked (created, writable) before the solve and cleared of the files
    of an earlier run of the same basename; with ``vtu`` on, every converged
    step is written as it arrives (:meth:`step`, the solver's
    ``callback(result, k)``) and the ``.pvd`` rewritten to list exactly the
    steps written so far, so a run interrupted at any point leaves a
    readable series of the steps it finished.  :meth:`finish` writes the
    rest (:meth:`Scene.write`).  Every file is written atomically.

    Made by :meth:`Scene.open_output`.
    """

    def __init__(self, scene, out=None):
        self.scene, self.out = scene, out
        self.result = None                 # the result being built (last callback)
        o = scene.output
        if o is None and out is not None:
            o = {k: key.default for k, key in OUTPUT.items()}
        self.options = o
        self.active = bool(o) and bool(o["json"] or o["vtu"] or o["render"])
        self.directory = scene.output_directory(out)
        self.base = (o or {}).get("basename") or scene.name
        self.entries = []                  # (time, file name) of the VTUs written
        if self.active:
            self._prepare()

    def _stale(self, name):
        import re
        b = re.escape(self.base)
        return bool(re.fullmatch(rf"{b}_\d+\.vtu|{b}\.(pvd|xdmf|json|png)"
                                 rf"|\.{b}(_\d+\.vtu|\.(pvd|xdmf|json|png))\..*\.tmp", name))

    def _prepare(self):
        """Create the directory, check that it takes files, remove the
        files of an earlier run (OSError if any of it fails)."""
        import tempfile
        from .export import check_path
        d = check_path("output directory", self.directory)
        os.makedirs(d, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".skfem-rod-probe.", dir=d)
        os.close(fd)
        os.remove(probe)
        for name in os.listdir(d):
            if self._stale(name):
                os.remove(os.path.join(d, name))

    def step(self, result, k):
        """Write step ``k`` of ``result`` (the solver's callback)."""
        self.result = result
        if not (self.active and self.options["vtu"]):
            return
        from .export import write_vtu
        st = result.steps[k]
        f, pdata = result.point_data(k, self.options["per_element"])
        name = f"{self.base}_{k:04d}.vtu"
        write_vtu(os.path.join(self.directory, name), f["r"], f["R"], pdata,
                  field_data={"TimeValue": st.time})
        self.entries = [e for e in self.entries if e[1] != name] + [(st.time, name)]
        self._write_pvd()

    def _write_pvd(self):
        from xml.etree import ElementTree as ET
        root = ET.Element("VTKFile", type="Collection", version="0.1",
                          byte_order="LittleEndian")
        coll = ET.SubElement(root, "Collection")
        for t, name in self.entries:
            ET.SubElement(coll, "DataSet", timestep=repr(float(t)), group="", part="0",
                          file=name)
        ET.indent(root)
        _atomic_write(os.path.join(self.directory, self.base + ".pvd"),
                      b'<?xml version="1.0"?>\n' + ET.tostring(root) + b"\n")

    def finish(self, result, wall_time=None):
        """Write the complete outputs of ``result`` (:meth:`Scene.write`)
        and remove streamed files the final series does not list."""
        if not self.active:
            return []
        written = self.scene.write(result, out=self.out, wall_time=wall_time)
        keep = {os.path.basename(p) for p in written}
        for _, name in self.entries:
            if name not in keep:
                with contextlib.suppress(OSError):
                    os.remove(os.path.join(self.directory, name))
        return written

    def interrupted(self, message, wall_time=None):
        """After an interrupt: the JSON summary of the steps kept so far
        (the VTU series is already on disk); returns the paths written."""
        if not self.active or self.result is None:
            return []
        self.result.finish(False, message)
        if self.options["vtu"]:            # steps kept but not yet on disk
            done = {name for _, name in self.entries}
            for k in range(len(self.result.steps)):
                if f"{self.base}_{k:04d}.vtu" not in done:
                    self.step(self.result, k)
        written = [os.path.join(self.directory, name) for _, name in self.entries]
        if self.entries:                   # a VTU may have landed after the last .pvd
            self._write_pvd()
            written.append(os.path.join(self.directory, self.base + ".pvd"))
        if self.options["json"]:
            from .export import write_json
            path = os.path.join(self.directory, self.base + ".json")
            data = summary(self.scene, self.result, wall_time)
            data["files"] = [os.path.basename(p) for p in written + [path]]
            written.append(write_json(path, data))
        self.remove_temporary()
        return written

    def remove_temporary(self):
        """Remove this run's temporary files (a signal that lands inside an
        atomic write's own clean-up can leave one)."""
        import re
        b = re.escape(self.base)
        with contextlib.suppress(OSError):
            for name in os.listdir(self.directory):
                if re.fullmatch(rf"\.{b}(_\d+\.vtu|\.(pvd|xdmf|json|png))\..*\.tmp", name):
                    with contextlib.suppress(OSError):
                        os.remove(os.path.join(self.directory, name))


def _atomic_write(path, data):
    """Write bytes to ``path`` atomically (a temporary file in the same
    directory, then ``os.replace``; the temporary file is removed on any
    exception, an interrupt included)."""
    import tempfile
    d = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp",
                               dir=d)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(tmp, 0o666 & ~mask)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.remove(tmp)
        raise


def step_figures(step, index):
    """Per-step figures (for the JSON summary and the progress lines)."""
    row = dict(step=index, time=step.time, load_factor=step.load_factor,
               newton_iterations=step.iterations,
               residual=step.residual_history[-1] if step.residual_history else 0.0,
               residual_history=step.residual_history,
               strain_energy=step.energy)
    c = step.contact
    if c is not None:
        row.update(newton_iterations=c.newton_total, uzawa_iterations=c.uzawa,
                   active_contacts=int(c.force.size), penetration=c.penetration,
                   contact_force=c.total_force, uzawa_converged=c.uzawa_converged)
        if c.crossing is not None:
            row.update(crossing_pairs=int(c.crossing.force.size),
                       crossing_force=c.crossing.total_force)
    return row


def summary(scene, result, wall_time=None):
    """The JSON summary: input, how the solve ended, the end state and the
    per-step figures."""
    rod = result.rod
    out = dict(scene=scene.name, source=scene.source, title=scene.title,
               converged=result.converged, message=result.message, log=list(result.log),
               wall_time_s=wall_time, length=rod.length,
               n_elements=rod.mesh.n_elements, n_nodes=rod.mesh.n_nodes,
               input=scene.data,
               steps=[step_figures(st, k) for k, st in enumerate(result.steps)],
               end_state=None)
    if result.steps:
        st = result.steps[-1]
        s, r, R = result.nodes()
        reactions = []
        for n, (force, moment) in st.reactions.items():
            held = [f"support[{k}]" for k, sup in enumerate(scene.data["support"])
                    if rod.node(sup["where"]) == n]
            reactions.append(dict(node=n, s=float(rod.mesh.s_nodes[n]), supports=held,
                                  force=force, moment=moment))
        out["end_state"] = dict(
            step=len(result.steps) - 1, load_factor=st.load_factor, time=st.time,
            strain_energy=st.energy, start=r[0], end=r[-1], reactions=reactions,
            s=s, r=r, d1=R[:, :, 0], d2=R[:, :, 1], d3=R[:, :, 2])
        if st.contact is not None:
            c = st.contact
            out["end_state"]["contact"] = dict(
                s=c.s, s_bar=c.s_bar, force=c.force, gap=c.gap,
                points=result.contact_points(), total_force=c.total_force,
                penetration=c.penetration)
            if c.crossing is not None:
                x = c.crossing
                out["end_state"]["contact"]["crossing"] = dict(
                    s=x.s, s_bar=x.s_bar, force=x.force, weight=x.weight, gap=x.gap,
                    points=result.crossing_points(), total_force=x.total_force)
                if c.friction:
                    out["end_state"]["contact"]["crossing"].update(friction=x.friction,
                                                                   state=x.state)
    return out


# ---------------------------------------------------------------------------
def read_toml(path):
    """The table of a TOML file; TOML syntax errors become SceneError (a
    ValueError), an unreadable file OSError."""
    try:
        import tomllib
    except ModuleNotFoundError:                  # Python 3.10
        import tomli as tomllib
    with open(path, "rb") as f:
        raw = f.read(MAX_FILE_BYTES + 1)          # /dev/zero must not fill the memory
    if len(raw) > MAX_FILE_BYTES:
        raise SceneError([f"the file is larger than {MAX_FILE_BYTES // 2**20} MiB, the "
                          "largest scene read (a scene is a short text file)"])
    try:
        return tomllib.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as err:
        raise SceneError([f"not a UTF-8 text file ({err})"]) from None
    except tomllib.TOMLDecodeError as err:
        raise SceneError([f"invalid TOML: {err}"]) from None


def load_scene(source, name=None):
    """Read and validate a scene; returns a :class:`Scene`.

    Parameters
    ----------
    source : str, os.PathLike or dict
        A TOML file, or its table as a dict.
    name : str, optional
        Scene name (default: the file's stem, or ``"scene"``); the default
        output directory is ``output/<name>`` and files are ``<name>.*``.

    Raises
    ------
    SceneError (a ValueError)
        Listing every invalid, missing or unknown key with its table path,
        its value and what is allowed; or, once the keys are valid, the
        first problem found while building the rod (boundary conditions).
    OSError
        When the file cannot be read.
    """
    src = None
    if isinstance(source, (str, os.PathLike)):
        src = os.fspath(source)
        data = read_toml(src)
        name = name or pathlib.Path(src).stem
    else:
        data = source
    d = validate_data(data)
    rod = _build(d)
    return Scene(d, name=name or "scene", source=src, _rod=rod)
