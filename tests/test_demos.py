"""Demos are importable, run headless, and write what they promise."""
import json

import numpy as np
import pytest

from helpers import load_demo as load


def test_rollup_demo_writes_results_render_and_series(tmp_path):
    demo = load("rollup")
    summary = demo.main(str(tmp_path), phi=2 * np.pi, n_elements=8, n_steps=2, animate=False)
    assert summary["converged"]
    data = json.loads((tmp_path / "results.json").read_text())
    # one full loop: the tip comes back to the clamp (8 elements: 1.2e-5 L)
    assert np.linalg.norm(data["tip"]) < 2e-5
    assert data["max_nodal_error_over_L"] < 2e-5
    assert abs(data["strain_energy"] / data["exact_strain_energy"] - 1) < 1e-6
    assert len(list(tmp_path.glob("rollup_*.vtu"))) == 3          # lam = 0, 0.5, 1
    assert (tmp_path / "rollup.pvd").exists()
    import matplotlib.image as mpimg
    img = mpimg.imread(tmp_path / "rollup.png")
    assert img.shape[:2] == (768, 1024)
    assert img[..., :3].std() > 0.05                              # not blank
    red = (img[..., 0] > 0.7) & (img[..., 1] < 0.4) & (img[..., 2] < 0.4)
    assert red.sum() > 100                                        # the d1 stripe


# --------------------------------------------------------------------------
# every demo, headless, at its small size (the settings of demos/gallery.py)
# --------------------------------------------------------------------------
gallery = load("gallery")


def image(path):
    """RGB array in [0, 1] of a PNG, or of every frame of a GIF."""
    from PIL import Image, ImageSequence

    im = Image.open(path)
    frames = [np.asarray(f.convert("RGB"), dtype=float) / 255 for f in ImageSequence.Iterator(im)]
    return frames if path.endswith(".gif") else frames[0]


def assert_not_blank(img, what):
    """A picture, not a flat background: the colours vary and more than 1 %
    of the pixels differ from the most common (background) colour."""
    assert img[..., :3].std() > 0.03, f"{what} is blank"
    flat = img.reshape(-1, img.shape[-1])
    values, counts = np.unique(np.round(flat * 255).astype(int), axis=0, return_counts=True)
    background = values[counts.argmax()]
    foreground = np.abs(np.round(flat * 255) - background).max(axis=1) > 30
    assert foreground.mean() > 0.01, f"{what}: only {foreground.mean():.2%} of the pixels drawn"


@pytest.mark.slow
@pytest.mark.parametrize("name", gallery.demo_names())
def test_demo_runs_headless_at_small_size(name, tmp_path):
    module = gallery.load(name)
    settings = gallery.small_settings(name, module)
    assert settings is not None, f"demos/{name}.py needs SMALL settings (or gallery.FALLBACK)"
    summary, images, _ = gallery.run(name, tmp_path)
    if isinstance(summary, dict) and "converged" in summary:
        assert summary["converged"], summary.get("message")
    assert (tmp_path / "results.json").exists()
    json.loads((tmp_path / "results.json").read_text())
    width, height = gallery.requested_size(module, settings)
    renders = images.get("renders", [])
    assert renders, f"demo {name} wrote no render"
    for path in renders:
        img = image(path)
        assert img.shape[:2] == (height, width), f"{path}: {img.shape[1]}x{img.shape[0]}"
        assert_not_blank(img, path)
    for path in images.get("plots", []):
        assert_not_blank(image(path), path)
    for path in images.get("animations", []):
        frames = image(path)
        assert len(frames) >= 2, f"{path} has {len(frames)} frame(s)"
        if "gif_size" in settings:
            assert frames[0].shape[:2] == tuple(settings["gif_size"])[::-1]
        for k, f in enumerate(frames):
            assert_not_blank(f, f"{path} frame {k}")
        # some frame differs from the first (a load cycle ends where it began)
        assert max(np.abs(f - frames[0]).max() for f in frames) > 0.5, \
            "the animation does not move"


def test_bend45_tip_matches_the_shooting_reference(tmp_path):
    demo = load("bend45")
    summary = demo.main(str(tmp_path), n_elements=8, n_steps=4, render=False)
    assert summary["converged"]
    # P = 300, 450, 600 reached at load factors 1/2, 3/4, 1 (docs/verification.md:
    # 8 elements, 6.3e-7, 7.7e-7, 8.9e-7)
    errors = summary["tip_errors"]
    assert sorted(errors) == ["300", "450", "600"]
    for load_, err in errors.items():
        assert err < 2e-6, (load_, err)
    assert np.allclose(summary["tip"], demo.REFERENCE[600.0], atol=2e-6)
    # the published 8-element values are within their own discretization error
    assert np.abs(np.array(summary["tip"]) - demo.PUBLISHED["Simo & Vu-Quoc (1986)"]).max() < 0.12
    # the clamp holds the load: reaction = -P e_z
    assert np.allclose(summary["clamp_reaction_force"], [0, 0, -600.0], atol=1e-6)
    data = json.loads((tmp_path / "results.json").read_text())
    assert data["tip_errors"] == errors


@pytest.mark.slow
def test_gallery_writes_thumbnails_and_index(tmp_path):
    index = gallery.main(out=tmp_path, names=["bend45"])
    assert set(index) == {"bend45"}
    files = index["bend45"]["renders"] + index["bend45"]["plots"]
    assert files == ["bend45.png", "bend45_tip.png"]
    for f in files:
        img = image(str(tmp_path / f))
        assert img.shape[1] == gallery.THUMBNAIL_WIDTH
        assert_not_blank(img, f)
    assert json.loads((tmp_path / "index.json").read_text()) == index


# --------------------------------------------------------------------------
# animation writer and contact-state markers (skfem_rod.render)
# --------------------------------------------------------------------------
def straight_rod(n=20, angle=0.0):
    """A unit rod along x, bent in the x-y plane by ``angle`` (an arc)."""
    s = np.linspace(0.0, 1.0, n)
    if angle == 0:
        r = np.c_[s, 0 * s, 0 * s]
        t = np.tile([1.0, 0, 0], (n, 1))
    else:
        k = angle
        r = np.c_[np.sin(k * s) / k, (1 - np.cos(k * s)) / k, 0 * s]
        t = np.c_[np.cos(k * s), np.sin(k * s), 0 * s]
    d2 = np.tile([0.0, 0, 1], (n, 1))
    d1 = np.cross(d2, t)
    return r, np.stack([d1, d2, t], axis=-1)


def test_render_animation_writes_a_looping_gif_of_the_requested_size(tmp_path):
    from skfem_rod.render import render_animation

    confs = [straight_rod(angle=a) for a in np.linspace(0, np.pi, 4)]
    path = render_animation(tmp_path / "bend.gif", confs, 0.03, window_size=(200, 150),
                            titles=[f"frame {k}" for k in range(4)], hold_last=0)
    frames = image(str(path))
    assert len(frames) == 4
    for f in frames:
        assert f.shape == (150, 200, 3)
        assert_not_blank(f, "frame")
    # a fixed camera: the clamped end (start of the rod) stays where it was
    # while the rest moves
    assert np.abs(frames[0] - frames[-1]).max() > 0.5
    from PIL import Image
    assert Image.open(path).info.get("loop") == 0
    assert not list(tmp_path.glob(".*.tmp"))              # written atomically


def test_render_animation_rejects_bad_input(tmp_path):
    from skfem_rod.render import render_animation

    confs = [straight_rod()] * 2
    with pytest.raises(ValueError, match="configurations is empty"):
        render_animation(tmp_path / "a.gif", [], 0.03)
    with pytest.raises(ValueError, match="titles has 1 entries for 2 configurations"):
        render_animation(tmp_path / "a.gif", confs, 0.03, titles=["x"])
    with pytest.raises(ValueError, match="fps"):
        render_animation(tmp_path / "a.gif", confs, 0.03, fps=0)
    with pytest.raises(ValueError, match="camera"):
        render_animation(tmp_path / "a.gif", confs, 0.03, camera=(0, 0))
    assert not (tmp_path / "a.gif").exists()


def test_contact_state_colors_and_messages():
    from skfem_rod.contact.friction import OPEN, SLIP, STICK
    from skfem_rod.render import STATE_COLORS, contact_state_colors

    rgb = contact_state_colors(np.array([SLIP, OPEN, STICK]))
    hexes = ["#%02x%02x%02x" % tuple(c) for c in rgb]
    assert hexes == [STATE_COLORS[2], STATE_COLORS[0], STATE_COLORS[1]]
    assert contact_state_colors([]).shape == (0, 3)
    with pytest.raises(ValueError, match=r"states contains \[3\]; allowed contact states"):
        contact_state_colors([0, 3])
    with pytest.raises(ValueError, match="integer contact states"):
        contact_state_colors([0.5])


def test_render_contact_states_colours_each_marker_by_its_state(tmp_path):
    from skfem_rod.render import STATE_COLORS, render_contact_states

    r, R = straight_rod(n=30)
    states = [0, 1, 2]
    png = render_contact_states(tmp_path / "states.png", r, R, 0.02, r[[5, 15, 25]], states,
                                window_size=(400, 300), camera="xy", legend=False)
    img = np.round(image(png) * 255)
    assert img.shape[:2] == (300, 400)

    def pixels_near(hex_color, tol=40):
        c = np.array([int(hex_color[i:i + 2], 16) for i in (1, 3, 5)])
        return int((np.abs(img - c).max(axis=-1) < tol).sum())

    # each state's colour shows up on its sphere (shading darkens some pixels)
    for k in states:
        assert pixels_near(STATE_COLORS[k]) > 30, STATE_COLORS[k]
    # left to right along x: open, stick, slip
    cols = [np.flatnonzero((np.abs(img - np.array([int(STATE_COLORS[k][i:i + 2], 16)
                                                    for i in (1, 3, 5)])).max(-1) < 40)
                           .any(axis=0)).mean() for k in states]
    assert cols[0] < cols[1] < cols[2]
    with pytest.raises(ValueError, match="one state per point"):
        render_contact_states(tmp_path / "x.png", r, R, 0.02, r[[5, 15]], states)


def test_twisted_rod_reports_no_snap_when_the_torque_only_rises():
    """The SMALL run of the twisted rod stays on the straight branch (the
    torque rises linearly): no snap is reported."""
    demo = load("twisted_rod")
    rising = [dict(turns=0.2 * k, torque=0.5 * k, shortening=0.0, contacts=0) for k in range(4)]
    ana = demo.analyse(rising, 5.0, 0.1)
    assert ana["snapped"] is False
    assert ana["snap_turns_before"] is None and ana["torque_after_snap"] is None
    snapping = rising + [dict(turns=0.8, torque=0.9, shortening=0.3, contacts=0)]
    ana = demo.analyse(snapping, 5.0, 0.1)
    assert ana["snapped"] and ana["snap_turns_after"] == pytest.approx(0.8)
    assert ana["torque_before_snap"] == pytest.approx(1.5)
    assert [name for name, _ in demo.stages(rising)] == ["straight"]


def test_crossing_friction_demo_slips_then_sticks_within_coulomb(tmp_path):
    """demos/crossing_friction.py: the crossing slips at its first contact
    and sticks at every later step; Coulomb's law at every step to the
    loop's tolerance; the results file holds the records."""
    demo = load("crossing_friction")
    summary = demo.main(str(tmp_path), render=False, verbose=False)
    assert summary["converged"], summary["message"]
    states = [r["state"] for r in summary["records"] if r["pairs"]]
    assert states[0] == "slip" and set(states[1:]) == {"stick"} and len(states) >= 3
    c = summary["coulomb"]
    assert c["bound_excess"] <= 1e-9 and c["misalignment"] <= c["tolerance"]
    saved = json.loads((tmp_path / "results.json").read_text())
    assert [r["state"] for r in saved["records"] if r["pairs"]] == states
