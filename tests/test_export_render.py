"""Tests for skfem_rod.export (meshio VTU/PVD/XDMF) and skfem_rod.render (pyvista)."""
import os
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

try:
    import skfem_rod  # noqa: F401
except ImportError:  # running from a checkout without installing
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from skfem_rod.export import write_series, write_vtu  # noqa: E402

meshio = pytest.importorskip("meshio")


def twisted_rod(n=41, turns=1.0, length=1.0):
    """Straight rod along z, frames rotated about the tangent by 2 pi turns s."""
    s = np.linspace(0.0, 1.0, n)
    th = 2 * np.pi * turns * s
    points = np.c_[np.zeros(n), np.zeros(n), length * s]
    c, sn = np.cos(th), np.sin(th)
    frames = np.zeros((n, 3, 3))
    frames[:, 0, 0], frames[:, 1, 0] = c, sn      # d1
    frames[:, 0, 1], frames[:, 1, 1] = -sn, c     # d2
    frames[:, 2, 2] = 1.0                         # d3 = e_z
    return points, frames


def curved_rod(n=30):
    """Helix centreline with a twisted, non-trivial orthonormal frame."""
    a = np.linspace(0, 2.0, n)
    points = np.c_[np.cos(a), np.sin(a), 0.4 * a]
    t = np.c_[-np.sin(a), np.cos(a), 0.4 * np.ones(n)]
    t /= np.linalg.norm(t, axis=1)[:, None]
    nrm = np.c_[-np.cos(a), -np.sin(a), np.zeros(n)]
    b = np.cross(t, nrm)
    tw = 3.0 * a
    d1 = np.cos(tw)[:, None] * nrm + np.sin(tw)[:, None] * b
    d2 = np.cross(t, d1)
    return points, np.stack([d1, d2, t], axis=-1)


def leftovers(directory):
    return sorted(os.listdir(directory))


# --------------------------------------------------------------------------
# export
# --------------------------------------------------------------------------
def test_write_vtu_round_trip(tmp_path):
    points, frames = curved_rod()
    n = len(points)
    pdata = {
        "arclength": np.linspace(0, 2, n),
        "moment": np.random.default_rng(0).normal(size=(n, 3)),
        "strains": np.arange(n * 6, dtype=float).reshape(n, 6),
        "node": np.arange(n),
    }
    path = tmp_path / "rod.vtu"
    out = write_vtu(path, points, frames, pdata, field_data={"time": 0.25, "load": [1.0, 2.0]})
    assert out == os.fspath(path)
    assert leftovers(tmp_path) == ["rod.vtu"]  # no temporary file left

    mesh = meshio.read(path)
    np.testing.assert_allclose(mesh.points, points, rtol=0, atol=1e-14)
    assert [c.type for c in mesh.cells] == ["line"]
    np.testing.assert_array_equal(mesh.cells[0].data, np.c_[np.arange(n - 1), np.arange(1, n)])
    for i, name in enumerate(["d1", "d2", "d3"]):
        np.testing.assert_allclose(mesh.point_data[name], frames[:, :, i], rtol=0, atol=1e-14)
    for name, val in pdata.items():
        np.testing.assert_allclose(mesh.point_data[name], val, rtol=0, atol=1e-14)
    np.testing.assert_allclose(mesh.field_data["time"], [0.25])
    np.testing.assert_allclose(mesh.field_data["load"], [1.0, 2.0])


def test_write_series_pvd_and_xdmf(tmp_path):
    points, frames = twisted_rod(n=11)
    times = [0.0, 0.125, 0.5, 1.0]
    steps = [
        {"time": t, "points": points + [t, 0, 0], "frames": frames,
         "point_data": {"tension": np.full(len(points), t)}}
        for t in times
    ]
    steps[1].pop("point_data")  # optional key
    paths = write_series(tmp_path / "out", "rod", steps)

    vtus = [f"rod_{k:04d}.vtu" for k in range(len(times))]
    assert [os.path.basename(p) for p in paths] == vtus + ["rod.xdmf", "rod.pvd"]
    assert leftovers(tmp_path / "out") == sorted(vtus + ["rod.pvd", "rod.xdmf"])
    for p in paths:
        assert os.path.getsize(p) > 0

    root = ET.parse(tmp_path / "out" / "rod.pvd").getroot()
    assert root.tag == "VTKFile" and root.get("type") == "Collection"
    datasets = root.findall("./Collection/DataSet")
    assert len(datasets) == len(times)
    assert [float(d.get("timestep")) for d in datasets] == times
    assert [d.get("file") for d in datasets] == vtus

    for k, t in enumerate(times):
        mesh = meshio.read(tmp_path / "out" / vtus[k])
        np.testing.assert_allclose(mesh.points, steps[k]["points"])
        np.testing.assert_allclose(mesh.point_data["d1"], frames[:, :, 0], atol=1e-14)
        np.testing.assert_allclose(mesh.field_data["TimeValue"], [t])
        assert ("tension" in mesh.point_data) == (k != 1)

    from meshio.xdmf import TimeSeriesReader

    with TimeSeriesReader(tmp_path / "out" / "rod.xdmf") as reader:
        ref, _ = reader.read_points_cells()
        assert reader.num_steps == len(times)
        for k, t in enumerate(times):
            tk, pd, _ = reader.read_data(k)
            assert tk == pytest.approx(t)
            np.testing.assert_allclose(pd["position"], steps[k]["points"])
            np.testing.assert_allclose(ref + pd["displacement"], steps[k]["points"])
            np.testing.assert_allclose(pd["d2"], frames[:, :, 1], atol=1e-14)


@pytest.mark.parametrize(
    "mutate, match",
    [
        (lambda p, f: (np.where(np.arange(len(p))[:, None] == 3, np.nan, p), f), r"points.*non-finite"),
        (lambda p, f: (p, np.where(np.arange(len(f))[:, None, None] == 2, np.inf, f)), r"frames.*non-finite"),
        (lambda p, f: (p, f[:-1]), r"frames has shape \(10, 3, 3\).*expected \(11, 3, 3\)"),
        (lambda p, f: (p[:, :2], f), r"points has shape \(11, 2\)"),
    ],
)
def test_write_vtu_bad_input(tmp_path, mutate, match):
    points, frames = twisted_rod(n=11)
    points, frames = mutate(points, frames)
    target = tmp_path / "bad.vtu"
    with pytest.raises(ValueError, match=match):
        write_vtu(target, points, frames)
    assert leftovers(tmp_path) == []


def test_write_vtu_bad_point_data_keeps_old_file(tmp_path):
    points, frames = twisted_rod(n=11)
    target = tmp_path / "rod.vtu"
    write_vtu(target, points, frames)
    before = target.read_bytes()
    with pytest.raises(ValueError, match=r"point_data\['x'\] has shape \(10,\)"):
        write_vtu(target, points, frames, {"x": np.zeros(10)})
    with pytest.raises(ValueError, match=r"point_data\['y'\].*non-finite"):
        write_vtu(target, points, frames, {"y": np.r_[np.zeros(10), np.nan]})
    with pytest.raises(ValueError, match="reserved"):
        write_vtu(target, points, frames, {"d1": np.zeros((11, 3))})
    assert target.read_bytes() == before
    assert leftovers(tmp_path) == ["rod.vtu"]


def test_write_vtu_failure_while_writing_is_atomic(tmp_path, monkeypatch):
    points, frames = twisted_rod(n=11)
    target = tmp_path / "rod.vtu"
    write_vtu(target, points, frames)
    before = target.read_bytes()

    def broken_write(path, *args, **kwargs):
        with open(path, "w") as f:
            f.write("<VTKFile partial")
        raise OSError("disk full")

    monkeypatch.setattr(meshio, "write", broken_write)
    with pytest.raises(OSError, match="disk full"):
        write_vtu(target, points + 1, frames)
    with pytest.raises(OSError, match="disk full"):
        write_vtu(tmp_path / "new.vtu", points, frames)
    assert target.read_bytes() == before
    assert leftovers(tmp_path) == ["rod.vtu"]


def test_write_series_bad_input_writes_nothing(tmp_path):
    points, frames = twisted_rod(n=11)
    bad = points.copy()
    bad[5, 1] = np.nan
    steps = [
        {"time": 0.0, "points": points, "frames": frames},
        {"time": 1.0, "points": bad, "frames": frames},
    ]
    with pytest.raises(ValueError, match=r"steps\[1\]\.points.*non-finite"):
        write_series(tmp_path, "rod", steps)
    steps[1]["points"] = points
    steps[1]["time"] = 0.0
    with pytest.raises(ValueError, match="strictly increasing"):
        write_series(tmp_path, "rod", steps)
    assert leftovers(tmp_path) == []


# --------------------------------------------------------------------------
# render
# --------------------------------------------------------------------------
def test_tube_mesh_geometry():
    pytest.importorskip("pyvista")
    from skfem_rod.render import tube_mesh

    points, frames = curved_rod(n=25)
    n, m, radius, width = len(points), 16, 0.07, 0.5
    tube = tube_mesh(points, frames, radius, n_around=m, stripe_width=width)
    x = np.asarray(tube.points[: n * m]).reshape(n, m, 3)
    rel = x - points[:, None, :]
    d1, d2, d3 = frames[:, None, :, 0], frames[:, None, :, 1], frames[:, None, :, 2]

    # every ring point lies on the circle of the given radius in the d1-d2 plane
    np.testing.assert_allclose(np.linalg.norm(rel, axis=-1), radius, rtol=1e-12)
    np.testing.assert_allclose(np.sum(rel * d3, axis=-1), 0, atol=1e-12)
    # ... at the angle phi measured from d1 towards d2
    phi = np.asarray(tube.point_data["phi"][: n * m]).reshape(n, m)
    np.testing.assert_allclose(np.sum(rel * d1, -1), radius * np.cos(phi), atol=1e-12)
    np.testing.assert_allclose(np.sum(rel * d2, -1), radius * np.sin(phi), atol=1e-12)

    # the stripe is the material line along d1: stripe points point along d1
    stripe = np.asarray(tube.point_data["stripe"][: n * m]).reshape(n, m)
    assert set(np.unique(stripe)) == {0.0, 1.0}
    cos_d1 = np.sum(rel * d1, axis=-1) / radius
    assert np.all(cos_d1[stripe == 1] > np.cos(width / 2))
    assert np.all(cos_d1[stripe == 0] <= np.cos(width / 2) + 1e-12)
    assert np.all(stripe[:, 0] == 1)  # phi = 0 is on every ring
    # so the stripe runs along p_i + r d1_i, which twists with the frame
    np.testing.assert_allclose(x[:, 0], points + radius * frames[:, :, 0], atol=1e-12)

    # closed surface: quads around, caps at both ends with outward normals
    assert tube.n_points == n * m + 2 * (m + 1)
    assert tube.n_cells == (n - 1) * m + 2 * m
    normals = tube.compute_normals(cell_normals=True, point_normals=False,
                                   consistent_normals=False).cell_data["Normals"]
    centres = tube.cell_centers().points
    quad_n, quad_c = normals[: (n - 1) * m], centres[: (n - 1) * m]
    seg = np.repeat(np.arange(n - 1), m)
    mid = 0.5 * (points[seg] + points[seg + 1])
    assert np.all(np.sum(quad_n * (quad_c - mid), axis=1) > 0)  # outward
    assert np.sum(normals[(n - 1) * m] * frames[0, :, 2]) < -0.99
    assert np.sum(normals[-1] * frames[-1, :, 2]) > 0.99

    open_tube = tube_mesh(points, frames, radius, n_around=m, capped=False)
    assert open_tube.n_points == n * m and open_tube.n_cells == (n - 1) * m

    with pytest.raises(ValueError, match="radius"):
        tube_mesh(points, frames, -1.0)
    with pytest.raises(ValueError, match="n_around"):
        tube_mesh(points, frames, 0.1, n_around=2)


def near(image, hexcolor):
    """Pixels of ``image`` (floats in [0, 1]) of the hue ``hexcolor`` up to
    shading (the normalised colour directions compared)."""
    flat = image.reshape(-1, 3)
    rgb = np.array([int(hexcolor[i:i + 2], 16) for i in (1, 3, 5)]) / 255.0
    unit = rgb / np.linalg.norm(rgb)
    norm = np.linalg.norm(flat, axis=1)
    cos = np.sum(flat * unit, axis=1) / np.maximum(norm, 1e-9)
    return ((cos > 0.995) & (norm > 0.2)).reshape(image.shape[:2])


def test_render_rod_twisted_png(tmp_path):
    pytest.importorskip("pyvista")
    import matplotlib.image as mpimg

    from skfem_rod.render import ROD_COLOR, STRIPE_COLOR, render_rod

    points, frames = twisted_rod(n=81, turns=1.0)
    size = (480, 360)
    target = tmp_path / "rod.png"
    out = render_rod(target, points, frames, 0.05, window_size=size, title="twist",
                     contact_points=points[[20, 60]], glyphs={"points": points[:1],
                                                              "vectors": [[0.2, 0, 0]]},
                     off_screen=True)
    assert out == os.fspath(target)
    assert leftovers(tmp_path) == ["rod.png"]

    img = mpimg.imread(target)[..., :3]  # floats in [0, 1]
    assert img.shape[:2] == (size[1], size[0])
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 10  # not all one colour

    stripe = near(img, STRIPE_COLOR)
    tube = near(img, ROD_COLOR)
    assert stripe.sum() > 100, "stripe colour not found in the image"
    assert tube.sum() > 10 * stripe.sum()
    # the background stays background around the framed rod (not clipped)
    border = np.r_[img[0, :], img[-1, :], img[:, 0], img[:, -1]]
    assert np.all(border > 0.9)

    # an untwisted rod shows its stripe along the whole length, the twisted
    # one only where the helix is on the visible side
    straight = tmp_path / "straight.png"
    render_rod(straight, points, np.tile(np.eye(3), (len(points), 1, 1)), 0.05,
               window_size=size, off_screen=True)
    rows_straight = np.unique(np.nonzero(near(mpimg.imread(straight)[..., :3], STRIPE_COLOR))[0])
    rows_twisted = np.unique(np.nonzero(stripe)[0])
    assert len(rows_straight) > 1.3 * len(rows_twisted)


# --------------------------------------------------------------------------
# notebook-friendly rendering: no global side effects, no VTK noise
# --------------------------------------------------------------------------
def test_render_is_quiet_and_leaves_pyvista_settings_alone(tmp_path):
    """A render in a fresh interpreter prints nothing from VTK on stderr
    ("bad X server connection" on a headless machine) and does not switch
    pyvista.OFF_SCREEN globally."""
    pytest.importorskip("pyvista")
    import subprocess

    code = (
        "import numpy as np, pyvista\n"
        "from skfem_rod.render import render_rod, render_animation\n"
        "s = np.linspace(0, 1, 20); p = np.c_[s, 0 * s, 0 * s]\n"
        "R = np.repeat(np.eye(3)[None][:, :, [1, 2, 0]], 20, axis=0)\n"
        "render_rod('a.png', p, R, 0.02, window_size=(160, 120), title='γ')\n"
        "render_animation('a.gif', [(p, R), (p, R)], 0.02, window_size=(160, 120))\n"
        "print('OFF_SCREEN', pyvista.OFF_SCREEN)\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120, env=env)
    assert proc.returncode == 0, proc.stderr
    assert "OFF_SCREEN False" in proc.stdout
    assert "bad X server" not in proc.stderr
    assert "vtk" not in proc.stderr.lower(), proc.stderr


def _cantilever(n_steps=2):
    from skfem_rod import Rod, Section, geometry

    rod = Rod(geometry.straight(1.0), Section.circle(E=1e7, nu=0.3, radius=0.01), 4)
    return rod.clamp("start").add_force("end", [0.0, 0.01, 0.0]).solve(n_steps)


def test_to_pyvista_carries_the_mechanical_fields():
    pytest.importorskip("pyvista")
    result = _cantilever()
    tube = result.to_pyvista(n_around=12)
    f = result.sample(8)
    n = len(f["s"])
    assert tube.n_points == n * 12 + 2 * 13
    for name in ("moment", "force", "moment_magnitude", "twist", "curvature", "stretch",
                 "strain_v", "strain_u", "contact_force", "contact_state", "arclength"):
        assert name in tube.point_data, name
    assert tube.point_data["moment"].shape == (tube.n_points, 3)
    # ring i carries sample i: the clamp moment P L, the tip moment 0
    m = tube.point_data["moment_magnitude"]
    assert m[0] == pytest.approx(np.linalg.norm(f["m"][0]))
    assert m[(n - 1) * 12] == pytest.approx(np.linalg.norm(f["m"][-1]), abs=1e-12)
    assert m.max() == pytest.approx(0.01, rel=2e-3)          # P times the lever arm
    assert np.all(tube.point_data["contact_state"] == -1)     # no contact
    assert tube.field_data["load_factor"][0] == 1.0


def test_result_plot_draws_the_centreline_and_reference():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    result = _cantilever()
    ax = result.plot(plt.figure().add_subplot(), plane="xy")
    lines = ax.get_lines()
    assert [ln.get_label() for ln in lines][:2] == ["reference", "load factor 1"]
    tip = result.position([1.0])[0]
    assert np.allclose(lines[1].get_xydata()[-1], tip[:2])
    ax3 = result.plot()                                   # a new 3D axes
    assert hasattr(ax3, "get_zlim")
    with pytest.raises(ValueError, match="plane"):
        result.plot(plt.figure().add_subplot(), plane="xx")
    plt.close("all")


def test_result_render_colours_by_a_field_with_supports_and_loads(tmp_path):
    pytest.importorskip("pyvista")
    result = _cantilever()
    extras = result._scene_extras()
    assert [s["kind"] for s in extras["supports"]] == ["clamp"]
    assert [ld["kind"] for ld in extras["loads"]] == ["force"]
    assert extras["reference"] is not None
    png = result.render(tmp_path / "c.png", window_size=(480, 360), color_by="moment_magnitude",
                        title="cantilever: |m| from P L to 0, γ = 0")
    from PIL import Image

    img = np.asarray(Image.open(png).convert("RGB")).astype(int)
    assert img.shape == (360, 480, 3)
    # the viridis colour bar in the right band: its darkest (purple) and
    # brightest (yellow) ends are there
    band = img[:, -int(0.25 * 480):]
    assert ((band[..., 0] > 200) & (band[..., 1] > 200) & (band[..., 2] < 80)).sum() > 20
    assert ((band[..., 0] < 90) & (band[..., 1] < 30) & (band[..., 2] > 60)).sum() > 20


def test_gif_keeps_the_stick_and_slip_colours(tmp_path):
    """The GIF palette holds the contact-state colours: green (stick) and
    orange (slip) markers stay green and orange in every frame."""
    pytest.importorskip("pyvista")
    from PIL import Image, ImageSequence

    from skfem_rod.render import STATE_COLORS, render_animation

    s = np.linspace(0, 1, 40)
    confs, cps = [], []
    for k in range(3):
        a = 0.5 + k
        p = np.c_[np.sin(a * s) / a, (1 - np.cos(a * s)) / a, 0 * s]
        t = np.c_[np.cos(a * s), np.sin(a * s), 0 * s]
        d2 = np.tile([0.0, 0, 1], (40, 1))
        confs.append((p, np.stack([np.cross(d2, t), d2, t], axis=-1)))
        cps.append(p[[10, 20, 30]])
    path = render_animation(tmp_path / "states.gif", confs, 0.03, window_size=(320, 240),
                            contact_points=cps, contact_states=[[1, 2, 1]] * 3,
                            titles=["γ_T = 0.2"] * 3, camera="xy", legend=False)
    frames = [np.asarray(f.convert("RGB")).astype(int)
              for f in ImageSequence.Iterator(Image.open(path))]
    for k in (1, 2):
        c = np.array([int(STATE_COLORS[k][i:i + 2], 16) for i in (1, 3, 5)])
        for f in frames:
            assert (np.abs(f - c).max(axis=-1) <= 12).sum() > 20, STATE_COLORS[k]


def test_long_titles_with_symbols_fit_a_480_pixel_image(tmp_path):
    """Titles are drawn with a font that has Greek letters, shrunk (then
    wrapped) to the width: nothing is clipped at the image edges."""
    pytest.importorskip("pyvista")
    from PIL import Image

    from skfem_rod.render import _title_lines, render_rod

    title = "plectoneme with friction γ_T = 0.3, 2π turns, torque 0.623 √(BT), 26 contact points"
    font, size, lines = _title_lines(title, 480, 20)
    assert font.getbbox("γπ√")[2] > 0
    assert len(lines) <= 2
    points, frames = twisted_rod(n=41, turns=0.5)
    png = render_rod(tmp_path / "t.png", points, frames, 0.05, window_size=(480, 360),
                     title=title, legend=False, axes=False)
    img = np.asarray(Image.open(png).convert("L")).astype(int)
    band = img[: img.shape[0] // 8]
    dark = np.nonzero(band < 128)
    assert dark[0].size > 200                                   # the title is drawn
    assert dark[1].min() > 2 and dark[1].max() < 477            # and not clipped


def test_json_writer_names_where_a_number_is_not_finite(tmp_path):
    """A non-finite number is refused with its place in the results (the
    knot demo's summary of four runs failed with only "(inf)"), and no
    file is written."""
    from skfem_rod.export import write_json
    path = tmp_path / "results.json"
    data = {"runs": [{"force": [1.0, 2.0]}, {"force": [3.0, float("inf")]}]}
    with pytest.raises(ValueError, match=r"inf\) at results\.runs\[1\]\.force\[1\]"):
        write_json(path, data)
    assert not path.exists() and not list(tmp_path.iterdir())
