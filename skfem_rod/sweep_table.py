"""The ``[sweep]`` table of a scene: dotted keys into the scene and their
values, checked by the scene format's own validator (given by the caller:
this module imports neither the scene format nor the sweep runner, which
both use it)."""
import copy
import json
import math
import numbers
import re

import numpy as np

MODES = ("grid", "zip")
#: most points of one sweep
MAX_POINTS = 100_000

_TOKEN = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)((?:\[\d+\])*)")


# ---------------------------------------------------------------------------
# keys: "load[0].vector[2]" -> ["load", 0, "vector", 2]
# ---------------------------------------------------------------------------
def parse_key(key):
    """The path of a dotted key as a list of names and indices, or None."""
    out = []
    for part in str(key).split("."):
        m = _TOKEN.fullmatch(part)
        if m is None:
            return None
        out.append(m.group(1))
        out += [int(i) for i in re.findall(r"\[(\d+)\]", m.group(2))]
    return out


def get_path(data, path):
    for p in path:
        data = data[p]
    return data


def put_path(data, path, value):
    """A deep copy of ``data`` with ``value`` at ``path``; raises KeyError
    (a table or entry on the way is missing) or IndexError."""
    data = copy.deepcopy(data)
    parent = get_path(data, path[:-1])
    last = path[-1]
    if isinstance(last, int):
        if not isinstance(parent, list):
            raise KeyError(f"{show_path(path[:-1])} is not an array")
        parent[last] = value              # IndexError past its end
    else:
        if not isinstance(parent, dict):
            raise KeyError(f"{show_path(path[:-1])} is not a table")
        parent[last] = value
    return data


def show_path(path):
    s = ""
    for p in path:
        s += f"[{p}]" if isinstance(p, int) else (("." if s else "") + p)
    return s


def flatten(table, prefix=""):
    """Nested tables (TOML's unquoted ``contact.gamma_T = ...``) as dotted
    keys; the reserved ``mode`` stays."""
    out = {}
    for k, v in table.items():
        name = f"{prefix}.{k}" if prefix else str(k)
        if isinstance(v, dict) and not (prefix == "" and k == "mode"):
            out.update(flatten(v, name))
        else:
            if name in out:
                raise ValueError(name)
            out[name] = v
    return out


def validate_sweep(table, base, known=(), *, validate, show, error):
    """Check a ``[sweep]`` table against the scene ``base`` (a scene table
    without ``sweep``); returns ``(sweep, problems)``, ``sweep`` being
    ``{"mode": ..., "parameters": {key: [values]}}`` with every value
    normalized as its key is.  Each value is validated by validating
    ``base`` with the value put in: the problems it adds to ``known``
    (those of ``base`` itself) are the value's.  ``validate`` (a scene
    table -> validated data, raising ``error`` with ``.problems``) and
    ``show`` (a value in a message) are the scene format's own.
    """
    problems = []
    if not isinstance(table, dict):
        return None, [f"sweep = {show(table)}: expected a table [sweep] of dotted scene "
                      'keys and their values, e.g. "contact.gamma_T" = [0.0, 0.1]']
    try:
        flat = flatten(table)
    except ValueError as err:
        return None, [f'sweep."{err}" is given twice (as a dotted key and a nested table)']
    mode = flat.pop("mode", "grid")
    if mode not in MODES:
        problems.append(f"sweep.mode = {show(mode)}: expected one of "
                        + ", ".join(json.dumps(m) for m in MODES))
    if not flat:
        problems.append('sweep has no parameters: expected dotted scene keys with arrays '
                        'of values, e.g. "contact.gamma_T" = [0.0, 0.1]')
    known = set(known)
    params = {}
    for key, values in flat.items():
        where = f'sweep."{key}"'
        path = parse_key(key)
        if path is None or len(path) < 2:
            problems.append(f"{where} is not a scene key: expected a dotted path into the "
                            'scene such as "contact.gamma_T", "section.E" or '
                            '"load[0].vector[2]"')
            continue
        if isinstance(values, np.ndarray):
            values = values.tolist()
        if not isinstance(values, (list, tuple)) or not values:
            problems.append(f"{where} = {show(values)}: expected a non-empty array of "
                            "values of " + show_path(path))
            continue
        out, ok = [], True
        for i, v in enumerate(values):
            try:
                new = validate(put_path(base, path, v))
            except (KeyError, IndexError, TypeError) as err:
                problems.append(f"{where}: the scene has no {show_path(path)} to sweep "
                                f"({err.args[0] if err.args else 'missing'}); sweep a key "
                                "of a table or entry the scene has")
                ok = False
                break
            except error as err:
                mine = [p for p in err.problems if p not in known]
                problems += [f"{where}[{i}]: {p}" for p in mine]
                ok = ok and not mine
                continue
            out.append(get_path(new, path))
        if not ok:
            continue
        labels = [label(v) for v in out]
        if mode != "zip" and len(set(labels)) != len(labels):
            problems.append(f"{where} = {show(values)}: the values of a grid axis must "
                            "differ")
            continue
        params[key] = out
    if mode == "zip" and len({len(v) for v in params.values()}) > 1:
        problems.append("sweep: with mode = \"zip\" every key needs as many values ("
                        + ", ".join(f'"{k}": {len(v)}' for k, v in params.items()) + ")")
    n = count_points(params, mode)
    if n > MAX_POINTS:
        problems.append(f"sweep: {n} points, more than {MAX_POINTS}; split the study")
    return dict(mode=mode, parameters=params), problems


def count_points(params, mode):
    if not params:
        return 0
    return len(next(iter(params.values()))) if mode == "zip" \
        else math.prod(len(v) for v in params.values())


def label(v):
    """A coordinate label: the value itself if it is a scalar, else JSON."""
    if isinstance(v, (bool, str, numbers.Real)):
        return v
    return json.dumps(v)
