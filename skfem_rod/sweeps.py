"""Parameter sweeps of a scene on Dask: one labelled dataset per study.

A sweep solves one scene at many values of some of its keys.  The keys are
the scene's own, written as dotted paths (``contact.gamma_T``,
``section.E``, ``load[0].vector[2]``, ``support[1].rotation_vector[0]``);
each value is validated exactly like the key it replaces (the scene is
validated with the value put in), so a sweep accepts what the scene
accepts.  In a TOML scene::

    [sweep]
    mode = "grid"                          # or "zip": the lists side by side
    "contact.gamma_T" = [0.0, 0.1, 0.2, 0.3]
    "load[0].vector[0]" = [1.0, 2.0]

and in Python ``skfem_rod.sweep(scene, {"contact.gamma_T": [0, 0.1]})`` (this module is
:mod:`skfem_rod.sweeps`).

Execution is on dask.distributed: an in-process ``LocalCluster`` (worker
processes, one thread each) by default, or any running cluster by its
scheduler address.  Nothing is lost: each finished point is written to
``points/<key>.nc`` as it finishes (temporary file + ``os.replace``), where
``key`` is a hash of the point's whole validated scene, so a re-run skips
the points already done; a point that fails (the solve stops, or raises)
is recorded with its message and the steps it converged; a point whose
worker dies is re-run by the scheduler (up to its ``allowed-failures``).

The result is an :class:`xarray.Dataset` with one dimension per swept key
(grid) or one ``point`` dimension (zip), plus ``step`` (the load steps,
padded with NaN, or -1 for counts, past the steps a point converged),
``support`` (the ``[[support]]`` entries) and ``xyz``; it is written to
``sweep.nc`` (netCDF, h5netcdf engine).  Format and study: docs/sweep.md.

Dask, xarray and h5netcdf are the optional extra ``sweep``
(``pip install skfem_rod[sweep]``); they are imported only when a sweep
runs.
"""
import hashlib
import itertools
import json
import logging
import os
import threading
import time
from dataclasses import dataclass

import numpy as np

from .sweep_table import label, parse_key, put_path, validate_sweep

__all__ = ["sweep", "sweep_points", "run_point", "open_sweep", "local_cluster", "SweepPoint"]

log = logging.getLogger("skfem_rod.sweep")

#: version of the point files; part of every point's key
FORMAT = 1
#: files of a sweep directory
POINTS_DIR, DATASET = "points", "sweep.nc"
#: fill value of the integer step variables past a point's last step
MISSING = -1
#: samples of the centreline for twist, writhe and link (Result.topology)
TOPOLOGY_SAMPLES = 2000


def _strip(d):
    """Validated scene data back to a scene table (no None: the defaults)."""
    if isinstance(d, dict):
        return {k: _strip(v) for k, v in d.items() if v is not None}
    if isinstance(d, list):
        return [_strip(v) for v in d]
    return d




# ---------------------------------------------------------------------------
# points
# ---------------------------------------------------------------------------
@dataclass
class SweepPoint:
    """One point of a sweep.

    index : tuple of int
        Its place in the dataset (one index per key in a grid, one in zip).
    values : dict
        Swept key -> value.
    data : dict
        The point's scene table (the scene with the values put in).
    key : str
        Hash of the point's validated scene: the name of its point file.
    """
    index: tuple
    values: dict
    data: dict
    key: str


def point_key(data, centreline=False, vtu=False):
    """Stable hash of a validated scene's content (what the solve sees:
    not its title, outputs or sweep), of the skfem_rod version and of
    what the point keeps besides its figures (centreline, VTU series)."""
    import skfem_rod                    # the package's version (its __init__ defines it)
    __version__ = skfem_rod.__version__
    content = {k: v for k, v in data.items() if k not in ("title", "output", "sweep")}
    keep = {k: True for k, on in (("centreline", centreline), ("vtu", vtu)) if on}
    text = json.dumps([FORMAT, __version__, content] + ([keep] if keep else []),
                      sort_keys=True, default=float)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def _base(scene):
    """(validated data, name, source) of a Scene, scene file or scene table."""
    from .scene import Scene, load_scene
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    return scene.data, scene.name, scene.source


def sweep_points(scene, parameters=None, mode=None, centreline=False, vtu=False):
    """The points of a sweep, in dataset order.

    Parameters
    ----------
    scene : Scene, str, os.PathLike or dict
        A loaded scene, a scene file or a scene table.
    parameters : dict, optional
        Dotted key -> values (replaces the scene's ``[sweep]`` table).
    mode : {"grid", "zip"}, optional
        Default: the ``[sweep]`` table's, else ``"grid"``.
    centreline, vtu : bool
        The points keep their centreline, their VTU series (part of their
        key).

    Returns
    -------
    points : list of SweepPoint
    spec : dict
        ``{"mode", "parameters"}`` (validated values).

    Examples
    --------
    >>> pts, spec = sweep_points({
    ...     "rod": {"geometry": {"type": "straight", "length": 1.0}, "n_elements": 4},
    ...     "section": {"E": 1e7, "nu": 0.3, "radius": 0.01},
    ...     "support": [{"where": "start", "kind": "clamp"}],
    ...     "load": [{"kind": "force", "where": "end", "vector": [0.0, 0.0, -1.0]}]},
    ...     {"section.E": [1e7, 2e7], "load[0].vector[2]": [-1, -2, -3]})
    >>> len(pts), pts[5].index, pts[5].values
    (6, (1, 2), {'section.E': 20000000.0, 'load[0].vector[2]': -3.0})
    """
    from .scene import SceneError, show_value, validate_data
    data, _, _ = _base(scene)
    base = _strip({k: v for k, v in data.items() if k != "sweep"})
    if parameters is None:
        spec = data.get("sweep")
        if spec is None:
            raise SceneError(["the scene has no [sweep] table and no parameters were "
                              'given: add [sweep] with e.g. "contact.gamma_T" = [0.0, 0.1]'])
        spec = dict(spec, mode=mode or spec["mode"])
        if spec["mode"] != data["sweep"]["mode"]:     # re-check the zip lengths
            spec, problems = validate_sweep(dict(spec["parameters"], mode=spec["mode"]), base,
                                            validate=validate_data, show=show_value,
                                            error=SceneError)
            if problems:
                raise SceneError(problems)
    else:
        spec, problems = validate_sweep(dict(parameters, mode=mode or "grid"), base,
                                        validate=validate_data, show=show_value,
                                        error=SceneError)
        if problems:
            raise SceneError(problems)
    keys = list(spec["parameters"])
    values = [spec["parameters"][k] for k in keys]
    if spec["mode"] == "grid":
        combos = [(idx, [v[i] for v, i in zip(values, idx)])
                  for idx in itertools.product(*(range(len(v)) for v in values))]
    else:
        combos = [((i,), [v[i] for v in values]) for i in range(len(values[0]))]
    points = []
    for idx, vals in combos:
        d = base
        for k, v in zip(keys, vals):
            d = put_path(d, parse_key(k), v)
        points.append(SweepPoint(tuple(idx), dict(zip(keys, vals)), d,
                                 point_key(validate_data(d), centreline, vtu)))
    return points, spec


# ---------------------------------------------------------------------------
# one point (runs on a worker): plain arrays in, plain arrays out
# ---------------------------------------------------------------------------
def _step_record(result, k, sup):
    rod, st = result.rod, result.steps[k]
    s, r, R = result.nodes(k)
    force = np.full((len(sup), 3), np.nan)
    moment = np.full((len(sup), 3), np.nan)
    for j, item in enumerate(sup):
        f, m = st.reactions[rod.node(item["where"])]
        force[j], moment[j] = f, m
    end = rod.node("end")
    torque = (float(np.dot(st.reactions[end][1], R[-1][:, 2]))
              if end in st.reactions else np.nan)
    try:                                  # at most ~TOPOLOGY_SAMPLES points (writhe is O(n^2))
        t = result.topology(k, per_element=int(np.clip(
            TOPOLOGY_SAMPLES // rod.mesh.n_elements, 1, 16)))
        topo = (t.twist, t.writhe, t.link)
    except Exception:                     # noqa: BLE001  (a figure, not the solve)
        topo = (np.nan,) * 3
    c = st.contact
    return dict(
        load_factor=st.load_factor, time=st.time, tip_position=r[-1],
        reaction_force=force, reaction_moment=moment, end_torque=torque,
        twist=topo[0], writhe=topo[1], link=topo[2], energy=st.energy,
        iterations=(c.newton_total if c is not None else st.iterations),
        lowest_eigenvalue=(np.nan if st.lowest_eigenvalue is None
                           else float(st.lowest_eigenvalue)),
        active_contacts=(int(c.force.size) if c is not None else 0),
        penetration=(float(c.penetration) if c is not None else 0.0))


#: the per-step variables: name -> (extra dims, fill, long name)
STEP_VARIABLES = {
    "load_factor": ((), np.nan, "load factor"),
    "time": ((), np.nan, "pseudo-time along the load path"),
    "tip_position": (("xyz",), np.nan, "position of the end s = L"),
    "reaction_force": (("support", "xyz"), np.nan,
                       "force the support's node exerts on the rod (spatial)"),
    "reaction_moment": (("support", "xyz"), np.nan,
                        "moment the support's node exerts on the rod, about the node"),
    "end_torque": ((), np.nan, "reaction moment at the end about the end tangent d3 "
                               "(NaN when the end is not supported)"),
    "twist": ((), np.nan, "twist (turns)"),
    "writhe": ((), np.nan, "writhe (turns)"),
    "link": ((), np.nan, "link = twist + writhe (turns)"),
    "energy": ((), np.nan, "strain energy"),
    "dissipation": ((), np.nan, "friction work dissipated since step 0 (cumulative)"),
    "iterations": ((), MISSING, "Newton iterations (all Uzawa passes)"),
    "lowest_eigenvalue": ((), np.nan, "lowest eigenvalue of the symmetrized tangent "
                                      "(solver.stability = true; NaN otherwise)"),
    "active_contacts": ((), MISSING, "active contact points"),
    "penetration": ((), np.nan, "largest contact penetration"),
}


def run_point(data, name="scene", values=None, on_step=None, centreline=False, vtu=None):
    """Load and solve one point's scene table; returns its record: the
    per-step arrays of :data:`STEP_VARIABLES` (converged steps only) and
    ``converged``, ``message``, ``n_steps``, ``wall_time``, ``cpu_time``.
    Never raises: a scene the loader rejects, a solve that stops or an exception are
    recorded in ``message`` (with the steps converged before).

    ``on_step(values, result, k)``, if given, is called after each
    converged step ``k`` (on the worker).  With ``centreline``, the record
    also holds the nodal ``arclength`` and the ``centreline`` positions of
    every step.  With ``vtu`` (a directory), the converged steps are also
    written there as a VTU series (``point.pvd``).
    """
    from .scene import load_scene
    t0, c0 = time.perf_counter(), time.process_time()
    kept = {}

    def callback(result, k):
        kept["result"] = result
        if on_step is not None:
            on_step(values, result, k)

    converged, result = False, None
    try:
        scene = load_scene(data, name=name)
        result = scene.solve(callback=callback)
        converged, message = bool(result.converged), str(result.message)
        data = scene.data
    except Exception as err:              # noqa: BLE001  (recorded, the sweep goes on)
        result = kept.get("result")
        message = f"{type(err).__name__}: {err}"
    rows = []
    if result is not None and result.steps:
        sup = data.get("support", [])
        rows = [_step_record(result, k, sup) for k in range(len(result.steps))]
        diss = result.dissipated_energy()
        for row, d in zip(rows, diss):
            row["dissipation"] = float(d)
    rec = {name_: np.array([row[name_] for row in rows]) for name_ in STEP_VARIABLES}
    if vtu is not None and rows:
        try:
            result.write_series(vtu, "point")
        except OSError as err:
            message += f" (the VTU series could not be written: {err})"
    if centreline and rows:
        rec["arclength"] = result.nodes(0)[0]
        rec["centreline"] = np.array([result.nodes(k)[1] for k in range(len(rows))])
    rec.update(converged=converged, message=message, n_steps=len(rows),
               wall_time=time.perf_counter() - t0, cpu_time=time.process_time() - c0)
    return rec


# ---------------------------------------------------------------------------
# point files
# ---------------------------------------------------------------------------
def point_dataset(rec, point, n_support):
    """One point's record as an xarray Dataset (dims step, support, xyz)."""
    import xarray as xr
    n = rec["n_steps"]
    out = {}
    for name, (dims, fill, long) in STEP_VARIABLES.items():
        shape = (n,) + tuple(3 if d == "xyz" else n_support for d in dims)
        a = np.asarray(rec[name])
        a = a.reshape(shape) if a.size else np.full(shape, fill)
        if fill is MISSING:
            a = a.astype(np.int64)
        out[name] = (("step",) + dims, a, {"long_name": long})
    if "centreline" in rec:
        out["arclength"] = (("node",), rec["arclength"], {"long_name": "arclength s"})
        out["centreline"] = (("step", "node", "xyz"), rec["centreline"],
                             {"long_name": "nodal positions r(s)"})
    ds = xr.Dataset(out)
    ds["converged"] = ((), bool(rec["converged"]))
    ds["message"] = ((), str(rec["message"]))
    ds["n_steps"] = ((), int(n))
    ds["wall_time"] = ((), float(rec["wall_time"]), {"units": "s"})
    ds["cpu_time"] = ((), float(rec.get("cpu_time", np.nan)), {"units": "s"})
    ds.attrs.update(key=point.key, values=json.dumps(point.values),
                    index=json.dumps(list(point.index)), format=FORMAT)
    return ds


def write_point(ds, folder, key):
    """Write a point file atomically (temporary file, then os.replace)."""
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, key + ".nc")
    tmp = os.path.join(folder, f".{key}.{os.getpid()}.tmp")
    ds.to_netcdf(tmp, engine="h5netcdf")
    os.replace(tmp, path)
    return path


def _read_point(path):
    import xarray as xr
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        return ds.load()


def _read_points(points, folder):
    """The Datasets of the point files of ``points`` in ``folder``; a file
    that cannot be read (damaged outside the sweep) is removed, so that its
    point is solved again."""
    out = {}
    for p in points:
        path = os.path.join(folder, p.key + ".nc")
        if p.key in out or not os.path.exists(path):
            continue
        try:
            out[p.key] = _read_point(path)
        except (OSError, ValueError) as err:
            log.warning("point file %s is unreadable (%s): removed, the point is solved "
                        "again", path, err)
            os.remove(path)
    return out


def finished_keys(folder):
    """Keys of the point files in ``folder`` (temporary files ignored)."""
    if not os.path.isdir(folder):
        return set()
    return {f[:-3] for f in os.listdir(folder) if f.endswith(".nc") and not f.startswith(".")}


# ---------------------------------------------------------------------------
# the dataset
# ---------------------------------------------------------------------------
def assemble(points, spec, records, meta):
    """The sweep's Dataset from the points' Datasets ``records`` (key ->
    Dataset; a point without one is marked not run)."""
    import xarray as xr
    keys = list(spec["parameters"])
    grid = spec["mode"] == "grid"
    shape = (tuple(len(v) for v in spec["parameters"].values()) if grid
             else (len(points),))
    pdims = tuple(keys) if grid else ("point",)
    n_steps = max([int(ds["n_steps"]) for ds in records.values()] + [1])
    n_sup = max([ds.sizes.get("support", 0) for ds in records.values()] + [0])
    data = {}
    for name, (dims, fill, long) in STEP_VARIABLES.items():
        full = shape + (n_steps,) + tuple(3 if d == "xyz" else n_sup for d in dims)
        arr = np.full(full, fill, dtype=np.int64 if fill is MISSING else float)
        for p in points:
            ds = records.get(p.key)
            if ds is not None and int(ds["n_steps"]):
                v = ds[name].values
                arr[p.index][tuple(slice(0, s) for s in v.shape)] = v
        data[name] = (pdims + ("step",) + dims, arr, {"long_name": long})
    n_node = max([ds.sizes.get("node", 0) for ds in records.values()] + [0])
    if n_node:                            # centrelines (points may differ in nodes)
        s = np.full(shape + (n_node,), np.nan)
        r = np.full(shape + (n_steps, n_node, 3), np.nan)
        for p in points:
            ds = records.get(p.key)
            if ds is not None and "centreline" in ds:
                v = ds["centreline"].values
                s[p.index][:v.shape[1]] = ds["arclength"].values
                r[p.index][:v.shape[0], :v.shape[1]] = v
        data["arclength"] = (pdims + ("node",), s, {"long_name": "arclength s of the nodes"})
        data["centreline"] = (pdims + ("step", "node", "xyz"), r,
                              {"long_name": "nodal positions r(s)"})
    conv = np.zeros(shape, bool)
    msg = np.full(shape, "not run", dtype=object)
    nst = np.zeros(shape, np.int64)
    wall = np.full(shape, np.nan)
    cpu = np.full(shape, np.nan)
    pkey = np.full(shape, "", dtype=object)
    for p in points:
        pkey[p.index] = p.key
        ds = records.get(p.key)
        if ds is not None:
            conv[p.index] = bool(ds["converged"])
            msg[p.index] = str(ds["message"].values)
            nst[p.index] = int(ds["n_steps"])
            wall[p.index] = float(ds["wall_time"])
            cpu[p.index] = float(ds["cpu_time"]) if "cpu_time" in ds else np.nan
    data.update(converged=(pdims, conv, {"long_name": "the solve reached the end of its "
                                                     "load path"}),
                message=(pdims, msg.astype(str), {"long_name": "how the solve ended"}),
                n_steps=(pdims, nst, {"long_name": "converged steps (step 0 included)"}),
                wall_time=(pdims, wall, {"units": "s", "long_name": "solve wall time"}),
                cpu_time=(pdims, cpu, {"units": "s", "long_name": "solve CPU time of "
                                                                  "the worker process"}),
                point_key=(pdims, pkey.astype(str), {"long_name": "point file name"}))
    coords = {"step": np.arange(n_steps), "xyz": ["x", "y", "z"],
              "support": np.arange(n_sup)}
    for k, vals in spec["parameters"].items():
        lab = [label(v) for v in vals]
        coords[k] = (k, lab) if grid else ("point", lab)
    if not grid:
        coords["point"] = np.arange(len(points))
    ds = xr.Dataset(data, coords=coords)
    ds.attrs.update(meta)
    ds.attrs.update(mode=spec["mode"], parameters=json.dumps(keys),
                    fill=f"steps past n_steps: NaN, counts {MISSING}")
    return ds


def open_sweep(path):
    """Read a sweep dataset (``sweep.nc``, or the directory holding it)."""
    import xarray as xr
    if os.path.isdir(path):
        path = os.path.join(path, DATASET)
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        return ds.load()


# ---------------------------------------------------------------------------
# the sweep
# ---------------------------------------------------------------------------
class _Stop(threading.Event):
    """A stop request (the command line's SIGTERM handler sets it with its
    exit code): the sweep stops after the point that finishes next, even
    when the exception the handler raised was swallowed inside Dask."""
    code = 1

    def request(self, code):
        self.code = code
        self.set()


STOP = _Stop()


def sweep(scene, parameters=None, mode=None, out=None, scheduler=None, n_workers=None,
          resume=True, progress=None, on_step=None, centreline=False, vtu=False):
    """Solve a scene at every point of a parameter sweep on Dask.

    Parameters
    ----------
    scene : Scene, str, os.PathLike or dict
        A loaded scene, a scene file or a scene table.
    parameters : dict, optional
        Dotted scene key -> values, e.g. ``{"contact.gamma_T": [0, 0.1]}``
        (default: the scene's ``[sweep]`` table).
    mode : {"grid", "zip"}, optional
        Every combination (default), or the i-th values together.
    out : str, optional
        Directory of ``points/`` and ``sweep.nc`` (default: the scene's
        output directory + ``/sweep``).
    scheduler : str or distributed.Client, optional
        A running cluster (``"tcp://host:8786"``) or client; default an
        in-process ``LocalCluster`` of ``n_workers`` processes with one
        thread each.
    n_workers : int, optional
        Default: the number of CPUs, at most the points to run.
    resume : bool
        Skip the points whose file is in ``out/points`` (default).
    progress : callable, optional
        ``progress(done, total, point, record)`` after each point (also
        logged to the ``skfem_rod.sweep`` logger).
    on_step : callable, optional
        ``on_step(values, result, k)`` after each converged step, on the
        worker.
    centreline : bool
        Also keep the nodal positions of every step (``centreline``, dims
        ``step, node, xyz``, and ``arclength``); off by default (large).
    vtu : bool
        Also write each point's VTU series to ``out/points/<key>/point.pvd``
        (by the workers: on a cluster, ``out`` must be a folder they share).

    Returns
    -------
    xarray.Dataset
        Also written to ``out/sweep.nc``.

    Examples
    --------
    The shipped study (6 points, about a minute and a half on 2 workers):

    >>> from skfem_rod import examples
    >>> ds = sweep(examples.path("greenhill_sweep"), n_workers=2)   # doctest: +SKIP
    >>> ds.end_torque.isel(step=ds.n_steps - 1).values      # doctest: +SKIP
    array([1.85, 2.2 , 2.8 , 3.8 , 5.3 , 7.4 ])
    """
    from .scene import Scene, load_scene
    if not isinstance(scene, Scene):
        scene = load_scene(scene)
    if n_workers is not None and not (isinstance(n_workers, int) and n_workers >= 1):
        raise ValueError(f"n_workers must be an integer >= 1, got {n_workers!r}")
    points, spec = sweep_points(scene, parameters, mode, centreline, vtu)
    out = sweep_directory(scene, out)
    folder = os.path.join(out, POINTS_DIR)
    os.makedirs(folder, exist_ok=True)
    for f in os.listdir(folder):           # temporaries of an interrupted run
        if f.endswith(".tmp"):
            try:
                os.remove(os.path.join(folder, f))
            except OSError:
                pass
    records = _read_points(points, folder) if resume else {}   # the points done
    todo, seen = [], set()
    for p in points:
        if p.key not in records and p.key not in seen:
            todo.append(p)
            seen.add(p.key)
    n_sup = len(scene.data["support"])
    total = len(points)
    log.info("%s: %d points, %d already done, %d to run", scene.name, total,
             total - len(todo), len(todo))
    if todo:
        records.update(_run(todo, scene.name, folder, n_sup, scheduler, n_workers,
                            progress, (on_step, centreline, vtu), total - len(todo),
                            total))
        records.update(_read_points([p for p in todo if p.key not in records], folder))
    meta = dict(scene=scene.name, title=scene.title, source=str(scene.source or ""),
                scene_data=json.dumps(scene.data, default=float))
    ds = assemble(points, spec, records, meta)
    tmp = os.path.join(out, f".{DATASET}.{os.getpid()}.tmp")
    ds.to_netcdf(tmp, engine="h5netcdf")
    os.replace(tmp, os.path.join(out, DATASET))
    return ds


def sweep_directory(scene, out=None):
    """Where a sweep of ``scene`` writes: ``out``, or the scene's output
    directory + ``/sweep``."""
    return os.fspath(out) if out is not None else os.path.join(scene.output_directory(),
                                                                "sweep")


def local_cluster(n_workers):
    """The in-process cluster of a sweep: ``n_workers`` worker processes of
    one thread each, the dashboard on a free port.

    Dask's workers trim the heap at 64 KiB (``MALLOC_TRIM_THRESHOLD_``),
    which also makes glibc map every large array anew: the solver ran 1.8x
    slower on a worker than in a plain loop.  A solve holds little memory,
    so the workers keep glibc's adaptive default.

    Examples
    --------
    >>> from dask.distributed import Client           # doctest: +SKIP
    >>> with local_cluster(2) as cluster, Client(cluster) as client:   # doctest: +SKIP
    ...     ds = sweep("scene.toml", scheduler=client)
    """
    import dask
    from dask.distributed import LocalCluster
    with dask.config.set({"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_":
                          None}):
        return LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                            dashboard_address=":0")


def _run(todo, name, folder, n_sup, scheduler, n_workers, progress, options, done, total):
    """Run the points on Dask, writing each as it finishes; returns the
    Datasets of the points lost with their workers (not written: a re-run
    tries them again)."""
    from dask.distributed import Client, as_completed
    from distributed.scheduler import KilledWorker
    cluster = None
    if scheduler is None:
        cluster = local_cluster(n_workers or min(os.cpu_count() or 1, len(todo)))
        client = Client(cluster)
    elif isinstance(scheduler, str):
        client = Client(scheduler)
    else:
        client = scheduler
    lost = {}
    try:
        on_step, centreline, vtu = options
        futures = {client.submit(run_point, p.data, name, p.values, on_step, centreline,
                                 os.path.abspath(os.path.join(folder, p.key)) if vtu
                                 else None,
                                 key=f"skfem-rod-point-{p.key}", pure=False): p
                   for p in todo}
        for fut in as_completed(futures):
            p = futures[fut]
            try:
                rec = fut.result()
            except KilledWorker as err:
                rec = dict({k: [] for k in STEP_VARIABLES}, converged=False, n_steps=0,
                           wall_time=np.nan, cpu_time=np.nan,
                           message=f"the workers running this point died: {err}")
                lost[p.key] = point_dataset(rec, p, n_sup)
            else:
                write_point(point_dataset(rec, p, n_sup), folder, p.key)
            done += 1
            fut.release()
            _report(done, total, p, rec)
            if progress is not None:
                progress(done, total, p, rec)
            if STOP.is_set():       # a stop request that Dask's machinery swallowed
                raise SystemExit(STOP.code)
    finally:
        if client is not scheduler:
            client.close()
        if cluster is not None:
            cluster.close()
    return lost


def _report(done, total, point, rec):
    log.info(progress_line(done, total, point, rec))


def progress_line(done, total, point, rec):
    """One line per finished point (logged to ``skfem_rod.sweep``)."""
    vals = "  ".join(f"{k} = {label(v)}" for k, v in point.values.items())
    state = "converged" if rec["converged"] else "stopped: " + rec["message"]
    return (f"[{done:{len(str(total))}d}/{total}] {vals}  {state}  "
            f"({rec['n_steps']} steps, {rec['wall_time']:.2f} s)")
