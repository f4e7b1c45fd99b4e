r"""Export rod configurations for ParaView (and anything else that reads VTK).

Inputs are plain numpy arrays, so this module is independent of the solver:

* ``points``  ``(n, 3)``: centreline positions, ordered along the rod;
* ``frames``  ``(n, 3, 3)``: rotation matrices whose **columns** are the
  directors ``d1, d2, d3`` (``d3`` the tangent; the convention of
  :mod:`skfem_rod.rotations`, ``d_i = R e_i``);
* ``point_data``: ``name -> array`` of shape ``(n,)`` or ``(n, k)``.

The rod is written as an unstructured grid of ``line`` cells joining
consecutive points (a polyline).  The directors are attached as point vectors
``d1``, ``d2``, ``d3``, so ParaView's *Glyph* filter can draw the frames.

Every file is written **atomically**: the data go to a temporary file in the
target directory, which then replaces the target with :func:`os.replace`.  A
reader (or a crash) therefore sees either the previous file or the complete
new one, never a truncated one; on error the temporary file is removed.

``meshio`` is imported inside the functions (heavy imports are lazy in this
package).
"""
from __future__ import annotations

import contextlib
import os
import tempfile
from xml.etree import ElementTree as ET

import numpy as np

__all__ = ["write_vtu", "write_series"]

_FRAME_NAMES = ("d1", "d2", "d3")


# --------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------
def _check_finite(name, a):
    if a.dtype.kind in "fc" and not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))
        idx = tuple(int(i) for i in bad[0])
        raise ValueError(
            f"{name} contains {bad.shape[0]} non-finite value(s) "
            f"(first: {name}[{', '.join(map(str, idx))}] = {a[idx]!r}); "
            "only finite numbers are allowed"
        )


def _as_real_array(name, value):
    try:
        a = np.asarray(value)
    except Exception as exc:  # ragged lists etc.
        raise ValueError(f"{name} could not be converted to an array: {exc}") from exc
    if a.dtype == bool:
        a = a.astype(np.uint8)
    if a.dtype.kind not in "iuf":
        raise ValueError(
            f"{name} has dtype {a.dtype}; only real numeric (int, unsigned, "
            "float or bool) arrays are allowed"
        )
    return a


def validate_points_frames(points, frames, *, prefix=""):
    points = _as_real_array(prefix + "points", points).astype(np.float64)
    if points.ndim != 2 or points.shape[1] != 3 or points.shape[0] < 2:
        raise ValueError(
            f"{prefix}points has shape {points.shape}; expected (n, 3) with n >= 2"
        )
    _check_finite(prefix + "points", points)
    n = points.shape[0]
    frames = _as_real_array(prefix + "frames", frames).astype(np.float64)
    if frames.shape != (n, 3, 3):
        raise ValueError(
            f"{prefix}frames has shape {frames.shape}; expected ({n}, 3, 3) "
            f"to match points of shape {points.shape} (columns are d1, d2, d3)"
        )
    _check_finite(prefix + "frames", frames)
    return points, frames


def _validate_point_data(point_data, n, *, prefix=""):
    out = {}
    if point_data is None:
        return out
    if not isinstance(point_data, dict):
        raise ValueError(
            f"{prefix}point_data is a {type(point_data).__name__}; "
            "expected a dict name -> array of shape (n,) or (n, k)"
        )
    for key, value in point_data.items():
        if not isinstance(key, str) or not key:
            raise ValueError(
                f"{prefix}point_data key {key!r} is not allowed; keys must be "
                "non-empty strings"
            )
        if key in _FRAME_NAMES:
            raise ValueError(
                f"{prefix}point_data key {key!r} is reserved for the directors "
                f"taken from frames; use another name (reserved: {_FRAME_NAMES})"
            )
        name = f"{prefix}point_data[{key!r}]"
        a = _as_real_array(name, value)
        if a.ndim not in (1, 2) or a.shape[0] != n or (a.ndim == 2 and a.shape[1] < 1):
            raise ValueError(
                f"{name} has shape {a.shape}; expected ({n},) or ({n}, k) "
                f"to match the {n} points"
            )
        _check_finite(name, a)
        out[key] = np.ascontiguousarray(a)
    return out


def _validate_field_data(field_data):
    out = {}
    if field_data is None:
        return out
    if not isinstance(field_data, dict):
        raise ValueError(
            f"field_data is a {type(field_data).__name__}; expected a dict "
            "name -> number or numeric array"
        )
    for key, value in field_data.items():
        if not isinstance(key, str) or not key:
            raise ValueError(
                f"field_data key {key!r} is not allowed; keys must be non-empty strings"
            )
        name = f"field_data[{key!r}]"
        a = _as_real_array(name, value)
        if a.ndim > 2:
            raise ValueError(
                f"{name} has shape {a.shape}; expected a scalar, (m,) or (m, k)"
            )
        if a.size == 0:
            raise ValueError(f"{name} is empty; expected at least one value")
        _check_finite(name, a)
        out[key] = np.atleast_1d(a)
    return out


# --------------------------------------------------------------------------
# atomic file writing
# --------------------------------------------------------------------------
def check_path(name, path):
    """``os.fspath(path)``; ValueError naming ``name`` if it is not a path
    or contains a NUL byte (which no file system accepts)."""
    try:
        p = os.fspath(path)
    except TypeError:
        raise ValueError(f"{name} must be a path (str or os.PathLike), got "
                         f"{type(path).__name__}") from None
    if isinstance(p, bytes):
        p = os.fsdecode(p)
    if "\0" in p:
        raise ValueError(f"{name} {p!r} contains a NUL byte, which no file name may contain")
    if not p:
        raise ValueError(f"{name} must not be empty")
    return p


def _file_mode():
    """Permission bits for a new file, ``0o666`` minus the process umask.

    ``tempfile.mkstemp`` creates files with mode 0600, which ``os.replace``
    would carry over to the final file.
    """
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return 0o666 & ~int(line.split()[1], 8)
    except OSError:
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path next to ``path``; on success move it onto ``path``.

    On any exception the temporary file is deleted and ``path`` is untouched.
    """
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(
        prefix="." + os.path.basename(path) + ".", suffix=".tmp", dir=directory
    )
    os.close(fd)
    try:
        yield tmp
        os.chmod(tmp, _file_mode())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.remove(tmp)
        raise


# --------------------------------------------------------------------------
# VTU
# --------------------------------------------------------------------------
def _vtk_type(a):
    return {
        "f": {4: "Float32", 8: "Float64"},
        "i": {1: "Int8", 2: "Int16", 4: "Int32", 8: "Int64"},
        "u": {1: "UInt8", 2: "UInt16", 4: "UInt32", 8: "UInt64"},
    }[a.dtype.kind][a.dtype.itemsize]


def _add_field_data(vtu_path, field_data):
    """Insert a ``<FieldData>`` block (ascii) into a VTU file written by meshio.

    meshio's VTU *writer* ignores ``mesh.field_data`` (its reader does not),
    so the block is added here; VTK/ParaView and ``meshio.read`` both read it.
    """
    tree = ET.parse(vtu_path)
    grid = tree.getroot().find("UnstructuredGrid")
    fd = ET.Element("FieldData")
    for name, a in field_data.items():
        vtype = _vtk_type(a)
        da = ET.SubElement(
            fd, "DataArray", type=vtype, Name=name,
            NumberOfTuples=str(a.shape[0]), format="ascii",
        )
        if a.ndim == 2:
            da.set("NumberOfComponents", str(a.shape[1]))
        fmt = repr if vtype.startswith("Float") else str
        da.text = " ".join(fmt(x) for x in a.ravel().tolist())
    grid.insert(0, fd)
    tree.write(vtu_path)


def _write_vtu_validated(path, points, frames, point_data, field_data):
    import meshio

    n = points.shape[0]
    cells = np.column_stack([np.arange(n - 1), np.arange(1, n)]).astype(np.int64)
    data = {name: np.ascontiguousarray(frames[:, :, i]) for i, name in enumerate(_FRAME_NAMES)}
    data.update(point_data)
    mesh = meshio.Mesh(points, [("line", cells)], point_data=data)
    with atomic_path(path) as tmp:
        meshio.write(tmp, mesh, file_format="vtu")
        if field_data:
            _add_field_data(tmp, field_data)
    return os.fspath(path)


def write_vtu(path, points, frames, point_data=None, field_data=None):
    """Write one rod configuration as a VTU polyline, atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Target file (conventionally ``*.vtu``); its directory must exist.
    points : array_like, (n, 3)
        Centreline points in order along the rod, ``n >= 2``.
    frames : array_like, (n, 3, 3)
        Rotation matrices; column ``i`` is director ``d_{i+1}``.  Written as
        point vectors ``d1``, ``d2``, ``d3``.
    point_data : dict, optional
        ``name -> array`` of shape ``(n,)`` or ``(n, k)``; the names ``d1``,
        ``d2``, ``d3`` are reserved.  Bool arrays are stored as ``uint8``.
    field_data : dict, optional
        ``name -> number or array`` of shape ``(m,)`` / ``(m, k)``, stored as
        VTK field data (e.g. time, load factor, energy).

    Returns
    -------
    str
        ``path``.

    Raises
    ------
    ValueError
        On wrong shapes, non-numeric or non-finite values (NaN/inf).  Nothing
        is written in that case.
    """
    path = check_path("path", path)
    points, frames = validate_points_frames(points, frames)
    point_data = _validate_point_data(point_data, points.shape[0])
    field_data = _validate_field_data(field_data)
    return _write_vtu_validated(path, points, frames, point_data, field_data)


# --------------------------------------------------------------------------
# time series
# --------------------------------------------------------------------------
_XDMF_NATIVE_COLUMNS = (1, 2, 3, 6, 9)  # shapes meshio's XDMF writer accepts


def _xdmf_point_data(data):
    """Split ``(n, k)`` arrays that XDMF has no attribute type for into scalars."""
    out = {}
    for name, a in data.items():
        if a.ndim == 1 or a.shape[1] in _XDMF_NATIVE_COLUMNS:
            out[name] = a
        else:
            for j in range(a.shape[1]):
                out[f"{name}_{j}"] = np.ascontiguousarray(a[:, j])
    return out


def _write_xdmf(path, steps):
    """XDMF (XML, no HDF5) time series; returns False if it cannot be written."""
    from meshio.xdmf import TimeSeriesWriter

    ref = steps[0]["points"]
    n = ref.shape[0]
    cells = np.column_stack([np.arange(n - 1), np.arange(1, n)]).astype(np.int64)
    try:
        with atomic_path(path) as tmp:
            # The writer's __exit__ writes the XML to ``tmp``; with
            # data_format="XML" every array is inline, no h5py involved.
            with TimeSeriesWriter(tmp, data_format="XML") as writer:
                writer.write_points_cells(ref, [("line", cells)])
                for st in steps:
                    data = {"position": st["points"], "displacement": st["points"] - ref}
                    for i, name in enumerate(_FRAME_NAMES):
                        data[name] = np.ascontiguousarray(st["frames"][:, :, i])
                    data.update(st["point_data"])
                    writer.write_data(st["time"], point_data=_xdmf_point_data(data))
    except ImportError:  # a meshio that insists on h5py: skip XDMF
        return False
    return True


def _pvd_xml(entries):
    root = ET.Element(
        "VTKFile", type="Collection", version="0.1", byte_order="LittleEndian"
    )
    coll = ET.SubElement(root, "Collection")
    for time, fname in entries:
        ET.SubElement(
            coll, "DataSet", timestep=repr(float(time)), group="", part="0", file=fname
        )
    ET.indent(root)
    return b'<?xml version="1.0"?>\n' + ET.tostring(root) + b"\n"


def write_series(directory, basename, steps, *, xdmf=True):
    """Write a time series of rod configurations for ParaView.

    Writes ``basename_0000.vtu``, ``basename_0001.vtu``, ... (one
    :func:`write_vtu` file per step, with the step's time as field data
    ``TimeValue``; more digits if there are more than 10000 steps), then ``basename.xdmf`` and finally the ParaView collection
    ``basename.pvd`` that lists every VTU with its ``timestep``.  Open the
    ``.pvd`` in ParaView to get the animation.

    Every file is written atomically (temporary file + :func:`os.replace`)
    and the ``.pvd`` is written last, so an existing ``.pvd`` only ever
    references complete files.  All steps are validated before anything is
    written; a failure while writing (e.g. disk full) can leave the VTU
    files of earlier steps behind, but no partial file and no new ``.pvd``.

    XDMF
    ----
    The XDMF file uses meshio's ``TimeSeriesWriter`` with
    ``data_format="XML"`` (all arrays inline), which does **not** need
    ``h5py``; h5py is deliberately not a dependency.  Should the installed
    meshio nevertheless require h5py (ImportError), the XDMF file is skipped
    silently and only the VTU/PVD files are written.  XDMF is also skipped if
    the number of points changes between steps or if ``xdmf=False``.

    An XDMF time series has a *single* geometry: it is the centreline of the
    first step, and every step carries point vectors ``position`` (the
    current centreline) and ``displacement`` (``position`` minus the first
    step's centreline) besides ``d1``, ``d2``, ``d3`` and the user point
    data.  In ParaView, apply *Warp By Vector* with ``displacement`` to see
    the motion.  ``(n, k)`` point data with ``k`` not in {1, 2, 3, 6, 9}
    (which XDMF has no attribute type for) is split into scalars
    ``name_0``, ``name_1``, ...

    Parameters
    ----------
    directory : str or os.PathLike
        Output directory; created if missing.
    basename : str
        File name stem, without directory separators.
    steps : sequence of dict
        Each with keys ``time`` (finite, strictly increasing), ``points``
        ``(n, 3)``, ``frames`` ``(n, 3, 3)`` and optionally ``point_data``
        (as in :func:`write_vtu`).
    xdmf : bool, default True
        Also write ``basename.xdmf`` (when possible, see above).

    Returns
    -------
    list of str
        The written paths: the VTU files in step order, then the XDMF file
        (if written), then the PVD file.

    Raises
    ------
    ValueError
        On an empty or malformed ``steps``, bad shapes, non-finite values,
        non-increasing times, or an invalid ``basename``.
    """
    if not isinstance(basename, str) or not basename or basename in (".", "..") or any(
        sep in basename for sep in ("/", "\\", os.sep, "\0")
    ):
        raise ValueError(
            f"basename {basename!r} is not allowed; expected a non-empty file "
            "name stem without directory separators"
        )
    try:
        steps = list(steps)
    except TypeError as exc:
        raise ValueError(
            f"steps is a {type(steps).__name__}; expected a list of dicts"
        ) from exc
    if not steps:
        raise ValueError("steps is empty; expected at least one step")

    checked = []
    prev_time = None
    for k, st in enumerate(steps):
        prefix = f"steps[{k}]."
        if not isinstance(st, dict):
            raise ValueError(
                f"steps[{k}] is a {type(st).__name__}; expected a dict with keys "
                "'time', 'points', 'frames' and optionally 'point_data'"
            )
        missing = [key for key in ("time", "points", "frames") if key not in st]
        if missing:
            raise ValueError(
                f"steps[{k}] lacks key(s) {missing}; required: 'time', 'points', "
                "'frames' (optional: 'point_data')"
            )
        unknown = set(st) - {"time", "points", "frames", "point_data"}
        if unknown:
            raise ValueError(
                f"steps[{k}] has unknown key(s) {sorted(unknown)}; allowed: "
                "'time', 'points', 'frames', 'point_data'"
            )
        try:
            time = float(st["time"])
        except (TypeError, ValueError) as exc:
            raise ValueError(
                f"{prefix}time = {st['time']!r} is not a number; expected a finite float"
            ) from exc
        if not np.isfinite(time):
            raise ValueError(f"{prefix}time = {time!r}; only finite times are allowed")
        if prev_time is not None and not time > prev_time:
            raise ValueError(
                f"{prefix}time = {time!r} does not exceed the previous time "
                f"{prev_time!r}; times must be strictly increasing"
            )
        prev_time = time
        points, frames = validate_points_frames(st["points"], st["frames"], prefix=prefix)
        pdata = _validate_point_data(st.get("point_data"), points.shape[0], prefix=prefix)
        checked.append(dict(time=time, points=points, frames=frames, point_data=pdata))

    directory = check_path("directory", directory)
    os.makedirs(directory, exist_ok=True)
    width = max(4, len(str(len(checked) - 1)))
    written = []
    entries = []
    for k, st in enumerate(checked):
        fname = f"{basename}_{k:0{width}d}.vtu"
        path = os.path.join(directory, fname)
        _write_vtu_validated(
            path, st["points"], st["frames"], st["point_data"],
            _validate_field_data({"TimeValue": st["time"]}),
        )
        written.append(path)
        entries.append((st["time"], fname))

    if xdmf and len({st["points"].shape[0] for st in checked}) == 1:
        path = os.path.join(directory, basename + ".xdmf")
        if _write_xdmf(path, checked):
            written.append(path)

    pvd = os.path.join(directory, basename + ".pvd")
    with atomic_path(pvd) as tmp:
        with open(tmp, "wb") as f:
            f.write(_pvd_xml(entries))
    written.append(pvd)
    return written


# --------------------------------------------------------------------------
# JSON summaries
# --------------------------------------------------------------------------
def _jsonable(x, where="results"):
    """``x`` with numpy scalars and arrays as plain numbers and lists;
    ``where``: the path of ``x`` in the results, named when a number is
    not finite."""
    if isinstance(x, dict):
        return {str(k): _jsonable(v, f"{where}.{k}") for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v, f"{where}[{i}]") for i, v in enumerate(x)]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist(), where)
    if isinstance(x, (np.floating, float)):
        v = float(x)
        if not np.isfinite(v):
            raise ValueError(f"results contain a non-finite number ({v}) at {where}; "
                             "refusing to write it")
        return v
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.bool_,)):
        return bool(x)
    return x


def write_json(path, data):
    """Write a JSON summary atomically (complete or not at all); non-finite
    numbers are refused rather than written as NaN."""
    import json
    path = check_path("path", path)
    text = json.dumps(_jsonable(data), indent=2)
    with atomic_path(path) as tmp:
        with open(tmp, "w") as f:
            f.write(text + "\n")
    return os.fspath(path)
