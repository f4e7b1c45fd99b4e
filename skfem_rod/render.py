r"""Render rod configurations to PNG with pyvista (works headless).

Inputs are plain numpy arrays (independent of the solver):

* ``points``  ``(n, 3)``: centreline positions, ordered along the rod;
* ``frames``  ``(n, 3, 3)``: rotation matrices whose **columns** are the
  directors ``d1, d2, d3`` (``d3`` the tangent).

The rod is drawn as a tube built from the frames themselves (not from a
Frenet frame or ``pyvista.Spline.tube``), with a coloured stripe along the
material line ``d1``: an untwisted rod shows a straight stripe, a twisted
one a helical stripe, so twist is visible in a still image.

``pyvista`` is imported inside the functions.  When no display is available
(or when ``off_screen=True`` is passed) ``pyvista.OFF_SCREEN`` is set to
``True``; VTK then renders off screen (EGL/OSMesa software fallback).  VTK may
print a harmless "bad X server connection" warning while it probes for X.
"""
from __future__ import annotations

import math
import os
import sys

import numpy as np

from .export import _atomic_path, _validate_points_frames

__all__ = ["tube_mesh", "render_rod", "ROD_COLOR", "STRIPE_COLOR", "STATE_NAMES",
           "STATE_COLORS", "contact_state_colors", "render_contact_states",
           "render_animation"]

ROD_COLOR = "#4f81bd"       # base colour of the tube (blue)
STRIPE_COLOR = "#d62728"    # material line along d1 (red)
CONTACT_COLOR = "#2ca02c"   # default colour of contact spheres (green)
GLYPH_COLOR = "#333333"     # default colour of arrows (dark grey)


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------
def _has_display():
    if sys.platform.startswith(("win", "cygwin", "darwin")):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _pyvista(off_screen=None):
    """Import pyvista; switch it off screen if asked or if there is no display."""
    import pyvista

    if off_screen or not _has_display():
        pyvista.OFF_SCREEN = True
    return pyvista


def _radii(radius, n):
    r = np.asarray(radius, dtype=float)
    if r.ndim == 0:
        r = np.full(n, float(r))
    if r.shape != (n,):
        raise ValueError(
            f"radius has shape {r.shape}; expected a scalar or an array of "
            f"shape ({n},) matching the points"
        )
    if not np.all(np.isfinite(r)) or np.any(r <= 0):
        raise ValueError(
            f"radius = {radius!r} is not allowed; radii must be finite and > 0"
        )
    return r


# --------------------------------------------------------------------------
# tube
# --------------------------------------------------------------------------
def tube_mesh(points, frames, radius, n_around=24, stripe_width=0.35, *, capped=True):
    """Surface of the rod as a tube built from its directors.

    At centreline point ``p_i`` with directors ``d1, d2`` (columns 0 and 1 of
    ``frames[i]``) a ring of ``n_around`` points is placed at::

        x_ij = p_i + r_i (cos(phi_j) d1 + sin(phi_j) d2),
        phi_j = 2 pi j / n_around,  j = 0 .. n_around - 1,

    and consecutive rings are joined by quadrilaterals (with outward
    normals); the ring is closed (``j = n_around - 1`` joins ``j = 0``).

    Point ordering: tube point ``(i, j)`` has index ``i * n_around + j``; the
    first ``n * n_around`` points are the tube.  With ``capped=True`` each
    end is closed by a fan of triangles on separate points (a copy of the end
    ring and a centre point appended after the tube points, start cap
    first), so the caps do not blur the shading of the tube.

    Point data
    ----------
    ``stripe`` (float, 1/0)
        1 on tube points with ``|phi| < stripe_width / 2``, i.e. on the
        material line along ``d1``; 0 elsewhere and on the caps.  (As point
        data interpolated over the quads, the stripe drawn from it is about
        one ring spacing ``2 pi / n_around`` wide if that exceeds
        ``stripe_width``; :func:`render_rod` draws the exact width from
        ``phi``.)
    ``phi`` (float)
        Angle of the point about the centreline from ``d1`` towards ``d2``,
        wrapped to ``(-pi, pi]``; cap points take the angle of their ring
        point, cap centres ``pi``.
    ``arclength`` (float)
        Arc length of the centreline polyline at the point's ring.
    ``cap`` (uint8)
        1 on cap points, 0 on tube points.

    Parameters
    ----------
    points : array_like, (n, 3)
    frames : array_like, (n, 3, 3)
        Columns ``d1, d2, d3``.  ``d1, d2`` are used as given (the ring is
        a circle if they are orthonormal).
    radius : float or array_like (n,)
        Tube radius, > 0.
    n_around : int, default 24
        Points per ring, >= 3.
    stripe_width : float, default 0.35
        Angular width (radians) of the stripe, in ``(0, 2 pi]``.
    capped : bool, default True
        Close both ends.

    Returns
    -------
    pyvista.PolyData
    """
    pv = _pyvista()
    points, frames = _validate_points_frames(points, frames)
    n = points.shape[0]
    r = _radii(radius, n)
    if isinstance(n_around, bool) or int(n_around) != n_around or n_around < 3:
        raise ValueError(f"n_around = {n_around!r}; expected an integer >= 3")
    m = int(n_around)
    if not (np.isfinite(stripe_width) and 0 < stripe_width <= 2 * math.pi):
        raise ValueError(
            f"stripe_width = {stripe_width!r}; expected an angle in (0, 2 pi] (radians)"
        )

    phi = 2 * np.pi * np.arange(m) / m
    phi_w = np.where(phi > np.pi, phi - 2 * np.pi, phi)        # (-pi, pi]
    d1 = frames[:, :, 0]
    d2 = frames[:, :, 1]
    ring = (np.cos(phi)[None, :, None] * d1[:, None, :]
            + np.sin(phi)[None, :, None] * d2[:, None, :])       # (n, m, 3)
    tube_pts = (points[:, None, :] + r[:, None, None] * ring).reshape(-1, 3)

    i = np.arange(n - 1)[:, None]
    j = np.arange(m)[None, :]
    jn = (j + 1) % m
    quads = np.stack(
        [i * m + j, i * m + jn, (i + 1) * m + jn, (i + 1) * m + j], axis=-1
    ).reshape(-1, 4)
    faces = [np.column_stack([np.full(len(quads), 4), quads]).ravel()]

    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    stripe = (np.abs(phi_w) < stripe_width / 2).astype(float)
    pdata = {
        "stripe": np.tile(stripe, n),
        "phi": np.tile(phi_w, n),
        "arclength": np.repeat(s, m),
        "cap": np.zeros(n * m, dtype=np.uint8),
    }
    all_pts = [tube_pts]

    if capped:
        offset = n * m
        for end, flip in ((0, True), (n - 1, False)):
            rim = tube_pts[end * m:(end + 1) * m]
            centre = offset + m
            jj = np.arange(m)
            a, b = offset + jj, offset + (jj + 1) % m
            # start cap faces -d3, end cap +d3 (outward)
            tri = np.column_stack([np.full(m, centre), b, a] if flip
                                  else [np.full(m, centre), a, b])
            faces.append(np.column_stack([np.full(m, 3), tri]).ravel())
            all_pts += [rim, points[end][None, :]]
            pdata["stripe"] = np.concatenate([pdata["stripe"], np.zeros(m + 1)])
            pdata["phi"] = np.concatenate([pdata["phi"], phi_w, [np.pi]])
            pdata["arclength"] = np.concatenate([pdata["arclength"], np.full(m + 1, s[end])])
            pdata["cap"] = np.concatenate([pdata["cap"], np.ones(m + 1, dtype=np.uint8)])
            offset += m + 1

    mesh = pv.PolyData(np.vstack(all_pts), faces=np.concatenate(faces))
    for key, val in pdata.items():
        mesh.point_data[key] = val
    mesh.field_data["n_around"] = np.array([m])
    mesh.field_data["stripe_width"] = np.array([float(stripe_width)])
    return mesh


# --------------------------------------------------------------------------
# rendering
# --------------------------------------------------------------------------
def _color_lut(pv, base, stripe, stripe_width, n_colors=512):
    """Colormap over |phi| in [0, pi]: stripe colour below stripe_width/2."""
    from matplotlib.colors import ListedColormap

    centres = (np.arange(n_colors) + 0.5) * np.pi / n_colors
    base_rgba = pv.Color(base).float_rgba
    stripe_rgba = pv.Color(stripe).float_rgba
    colors = np.where((centres < stripe_width / 2)[:, None], stripe_rgba, base_rgba)
    return ListedColormap(colors)


def _window_size(window_size):
    """``(width, height)`` in pixels, checked (integers >= 16)."""
    try:
        width, height = (int(v) for v in window_size)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"window_size = {window_size!r}; expected (width, height) in pixels"
        ) from exc
    if width < 16 or height < 16:
        raise ValueError(f"window_size = {window_size!r}; width and height must be >= 16")
    return width, height


def _as_points(name, value):
    a = np.asarray(value, dtype=float)
    if a.ndim == 1 and a.shape[0] == 3:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name} has shape {a.shape}; expected (m, 3)")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN/inf; only finite values are allowed")
    return a


def _fit_camera(pl, pts, fill):
    """Set the view angle so that ``pts`` fill ``fill`` of the window.

    Assumes the camera already looks at the scene (``reset_camera``).
    Projects the points with the camera's composite projection, pans the
    camera so that their projected bounding box is centred, and rescales the
    perspective view angle (or parallel scale) so that the box spans
    ``fill`` of the window width or height, whichever binds.
    """
    from pyvista import array_from_vtkmatrix

    cam = pl.renderer.GetActiveCamera()
    w, h = pl.window_size
    aspect = w / h
    pts = np.c_[pts, np.ones(len(pts))]

    def ndc_box():
        pl.renderer.ResetCameraClippingRange()
        mat = array_from_vtkmatrix(cam.GetCompositeProjectionTransformMatrix(aspect, -1, 1))
        hom = pts @ mat.T
        ndc = hom[:, :2] / hom[:, 3:4]
        return ndc.min(axis=0), ndc.max(axis=0)

    def half_height():
        if cam.GetParallelProjection():
            return cam.GetParallelScale()
        return cam.GetDistance() * math.tan(math.radians(cam.GetViewAngle()) / 2)

    for _ in range(3):
        # centre the projected scene (perspective makes it slightly off-centre
        # after reset_camera), then scale it to the requested fill
        lo, hi = ndc_box()
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            return
        centre = (lo + hi) / 2
        direction = np.array(cam.GetDirectionOfProjection())
        up = np.array(cam.GetViewUp())
        up = up - direction * (up @ direction)
        up /= np.linalg.norm(up)
        right = np.cross(direction, up)
        hh = half_height()
        shift = right * centre[0] * hh * aspect + up * centre[1] * hh
        cam.SetFocalPoint(*(np.array(cam.GetFocalPoint()) + shift))
        cam.SetPosition(*(np.array(cam.GetPosition()) + shift))
        lo, hi = ndc_box()
        extent = np.max((hi - lo) / 2)
        if not np.isfinite(extent) or extent <= 0:
            return
        f = fill / extent
        if cam.GetParallelProjection():
            cam.SetParallelScale(cam.GetParallelScale() / f)
        else:
            half = math.radians(cam.GetViewAngle()) / 2
            cam.SetViewAngle(math.degrees(2 * math.atan(math.tan(half) / f)))
    pl.renderer.ResetCameraClippingRange()


def render_rod(filename, points, frames, radius, *, window_size=(1024, 768),
               contact_points=None, contact_colors=None, glyphs=None, title=None,
               background="white", camera="iso", color=ROD_COLOR,
               stripe_color=STRIPE_COLOR, stripe_width=0.35, n_around=48,
               contact_radius=None, zoom=None, off_screen=None):
    """Render the rod as a striped tube and write a PNG, atomically.

    Parameters
    ----------
    filename : str or os.PathLike
        Output PNG; written via a temporary file and :func:`os.replace`.
    points, frames, radius
        As in :func:`tube_mesh`.
    window_size : (int, int)
        ``(width, height)`` in pixels; the PNG has exactly this size.
    contact_points : array_like (m, 3), optional
        Drawn as spheres of radius ``contact_radius`` (default ``1.25 *``
        the largest rod radius, so points on the centreline stay visible).
    contact_colors : optional
        One colour for all (name, hex string or RGB *tuple*), a list of
        ``m`` colours, an ``(m, 3)`` RGB array (floats in [0, 1] or ints
        0..255), or an ``(m,)`` array of scalars (coloured with viridis).
    glyphs : dict, optional
        Arrows: ``points`` (k, 3), ``vectors`` (k, 3), optional ``color``
        and ``scale`` (arrow length = ``scale * |vector|``; default: the
        longest arrow is 15 % of the rod's bounding-box diagonal).
    title : str, optional
        Text at the top of the image.
    background : colour
    camera : str or camera position
        A pyvista view (``"iso"``, ``"xy"``, ``"xz"``, ``"yz"``, ``"yx"``,
        ``"zx"``, ``"zy"``): the camera is reset onto the whole scene and then
        zoomed so that the scene fills about 90 % of the window (80 % with a
        title).  Anything else (e.g. ``[position, focal_point, view_up]``) is
        passed to ``Plotter.camera_position`` and used as is.
    color, stripe_color : colour
        Tube colour and colour of the material line along ``d1``.
    stripe_width, n_around
        As in :func:`tube_mesh`; the stripe is drawn with its exact angular
        width, independent of ``n_around``.  The default ``n_around=48`` is
        finer than :func:`tube_mesh`'s: with 24 facets the polygonal
        cross-section, rotating with the twist, makes the silhouette of a
        twisted rod visibly ripple.
    zoom : float, optional
        Instead of the automatic fit, ``reset_camera`` followed by
        ``camera.zoom(zoom)``.
    off_screen : bool, optional
        Force ``pyvista.OFF_SCREEN = True``; it is set anyway when no display
        is available.  Rendering always uses an off-screen window.

    Returns
    -------
    str
        ``filename``.
    """
    pv = _pyvista(off_screen)
    points, frames = _validate_points_frames(points, frames)
    r = _radii(radius, points.shape[0])
    width, height = _window_size(window_size)

    tube = tube_mesh(points, frames, r, n_around=n_around, stripe_width=stripe_width)
    # |phi| interpolated linearly across the quads and mapped through a
    # two-colour table gives a stripe edge exactly at |phi| = stripe_width/2.
    tube.point_data["stripe_coord"] = np.where(
        tube.point_data["cap"] == 1, np.pi, np.abs(tube.point_data["phi"])
    )
    fit_pts = [tube.points]

    pl = pv.Plotter(off_screen=True, window_size=(width, height), lighting="three lights")
    try:
        pl.set_background(background)
        try:  # smoother silhouettes; SSAA works with the OSMesa/EGL fallback
            pl.enable_anti_aliasing("ssaa")
        except Exception:  # pragma: no cover - depends on the VTK build
            pass
        pl.add_mesh(
            tube, scalars="stripe_coord", clim=(0.0, np.pi),
            cmap=_color_lut(pv, color, stripe_color, stripe_width),
            interpolate_before_map=True, show_scalar_bar=False,
            smooth_shading=True, specular=0.3, specular_power=20, ambient=0.2,
        )

        if contact_points is not None:
            cp = _as_points("contact_points", contact_points)
            if len(cp):
                rad = float(contact_radius) if contact_radius is not None else 1.25 * r.max()
                if not (np.isfinite(rad) and rad > 0):
                    raise ValueError(f"contact_radius = {contact_radius!r}; expected > 0")
                cloud = pv.PolyData(cp)
                kw = _contact_color_kwargs(pv, cloud, contact_colors, len(cp))
                spheres = cloud.glyph(
                    geom=pv.Sphere(radius=rad, theta_resolution=20, phi_resolution=20),
                    scale=False, orient=False,
                )
                pl.add_mesh(spheres, smooth_shading=True, show_scalar_bar=False,
                            ambient=0.2, **kw)
                fit_pts.append(spheres.points)

        if glyphs is not None:
            arrows = _arrow_mesh(pv, glyphs, points)
            if arrows is not None:
                pl.add_mesh(arrows, color=glyphs.get("color", GLYPH_COLOR),
                            smooth_shading=True)
                fit_pts.append(arrows.points)

        if title:
            text_color = "black" if np.mean(pv.Color(background).float_rgb) > 0.5 else "white"
            font_size = max(8, round(14 * height / 768))
            pl.add_text(str(title), position="upper_edge", font_size=font_size,
                        color=text_color)

        if isinstance(camera, str):
            pl.camera_position = camera
            pl.reset_camera()
            if zoom is None:
                pts = np.vstack(fit_pts)
                if len(pts) > 50000:
                    pts = pts[:: len(pts) // 50000 + 1]
                _fit_camera(pl, pts, 0.8 if title else 0.9)
            else:
                pl.camera.zoom(float(zoom))
        else:
            pl.camera_position = camera

        img = np.asarray(pl.screenshot(None, return_img=True))
    finally:
        pl.close()

    if img.shape[:2] != (height, width):
        raise RuntimeError(
            f"renderer produced an image of {img.shape[1]}x{img.shape[0]} pixels, "
            f"not the requested {width}x{height}"
        )
    from PIL import Image  # a dependency of pyvista and matplotlib

    with _atomic_path(filename) as tmp:
        Image.fromarray(np.ascontiguousarray(img)).save(tmp, format="PNG")
    return os.fspath(filename)


def _contact_color_kwargs(pv, cloud, colors, m):
    if colors is None:
        return {"color": CONTACT_COLOR}
    if isinstance(colors, (str, tuple)):
        return {"color": pv.Color(colors).float_rgb}
    if isinstance(colors, list) and colors and isinstance(colors[0], (str, tuple)):
        if len(colors) != m:
            raise ValueError(
                f"contact_colors has {len(colors)} colours; expected {m} (one per contact point)"
            )
        cloud.point_data["rgb"] = np.array([pv.Color(c).int_rgb for c in colors], np.uint8)
        return {"scalars": "rgb", "rgb": True}
    a = np.asarray(colors)
    if a.ndim == 1 and a.shape[0] == m and a.dtype.kind in "iuf":
        if not np.all(np.isfinite(a)):
            raise ValueError("contact_colors contains NaN/inf; only finite values are allowed")
        cloud.point_data["contact_value"] = a.astype(float)
        return {"scalars": "contact_value", "cmap": "viridis"}
    if a.shape == (m, 3) and a.dtype.kind in "iuf":
        if not np.all(np.isfinite(a)):
            raise ValueError("contact_colors contains NaN/inf; only finite values are allowed")
        rgb = a * 255 if a.dtype.kind == "f" and a.max(initial=0) <= 1 else a
        cloud.point_data["rgb"] = np.clip(np.rint(rgb), 0, 255).astype(np.uint8)
        return {"scalars": "rgb", "rgb": True}
    raise ValueError(
        f"contact_colors of shape {a.shape} is not allowed; expected a colour, "
        f"a list of {m} colours, an ({m}, 3) RGB array or ({m},) scalars"
    )


def _arrow_mesh(pv, glyphs, rod_points):
    if not isinstance(glyphs, dict) or "points" not in glyphs or "vectors" not in glyphs:
        raise ValueError(
            "glyphs must be a dict with keys 'points' and 'vectors' (each (k, 3)); "
            "optional 'color' and 'scale'"
        )
    gp = _as_points("glyphs['points']", glyphs["points"])
    gv = _as_points("glyphs['vectors']", glyphs["vectors"])
    if gp.shape != gv.shape:
        raise ValueError(
            f"glyphs['points'] has shape {gp.shape} but glyphs['vectors'] has "
            f"shape {gv.shape}; they must agree"
        )
    mags = np.linalg.norm(gv, axis=1)
    if len(gp) == 0 or mags.max() == 0:
        return None
    scale = glyphs.get("scale")
    if scale is None:
        diag = np.linalg.norm(np.ptp(np.vstack([rod_points, gp]), axis=0))
        scale = 0.15 * diag / mags.max()
    scale = float(scale)
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"glyphs['scale'] = {scale!r}; expected a finite number > 0")
    cloud = pv.PolyData(gp)
    cloud.point_data["vectors"] = gv
    cloud.point_data["magnitude"] = mags
    geom = pv.Arrow(tip_length=0.25, tip_radius=0.08, shaft_radius=0.03)
    return cloud.glyph(orient="vectors", scale="magnitude", factor=scale, geom=geom)


# --------------------------------------------------------------------------
# contact states (open / stick / slip) and animations
# --------------------------------------------------------------------------
#: Names of the contact states, indexed by the integer state of
#: :class:`skfem_rod.contact.friction.FrictionState` (0 open, 1 stick, 2 slip).
STATE_NAMES = ("open", "stick", "slip")
#: Marker colour per contact state: open grey, stick green, slip orange.
STATE_COLORS = ("#9e9e9e", "#2ca02c", "#ff7f0e")


def contact_state_colors(states):
    """RGB colours of contact markers from their integer states.

    Parameters
    ----------
    states : array_like of int, (m,)
        ``0`` open, ``1`` stick, ``2`` slip (the values of
        :class:`skfem_rod.contact.friction.FrictionState`).

    Returns
    -------
    numpy.ndarray, (m, 3), uint8
        One colour of :data:`STATE_COLORS` per marker, ready for the
        ``contact_colors`` argument of :func:`render_rod`.

    Examples
    --------
    >>> contact_state_colors([0, 1, 2]).tolist()
    [[158, 158, 158], [44, 160, 44], [255, 127, 14]]
    """
    a = np.asarray(states)
    if a.ndim != 1 or (a.size and a.dtype.kind not in "iub"):
        raise ValueError(
            f"states = {states!r}; expected a 1D array of integer contact states "
            f"(0 open, 1 stick, 2 slip)"
        )
    a = a.astype(int)
    bad = (a < 0) | (a >= len(STATE_COLORS))
    if np.any(bad):
        raise ValueError(
            f"states contains {sorted(set(a[bad].tolist()))}; allowed contact states "
            f"are 0 (open), 1 (stick) and 2 (slip)"
        )
    table = np.array([[int(c[i:i + 2], 16) for i in (1, 3, 5)] for c in STATE_COLORS],
                     dtype=np.uint8)
    return table[a]


def _legend_font(size):
    from PIL import ImageFont

    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # pragma: no cover - Pillow < 10.1
        return ImageFont.load_default()


def _draw_state_legend(img, states=None):
    """Draw the open/stick/slip legend in the lower left corner of an RGB image
    (``(h, w, 3)`` uint8); only the states present in ``states`` are listed
    (all three when ``states`` is None).  Returns a new array."""
    from PIL import Image, ImageDraw

    present = range(len(STATE_NAMES)) if states is None else sorted(set(np.asarray(states, int).tolist()))
    h = img.shape[0]
    size = max(10, round(16 * h / 768))
    font = _legend_font(size)
    im = Image.fromarray(np.ascontiguousarray(img[..., :3]))
    draw = ImageDraw.Draw(im)
    x0, y = size, h - size - (size + size // 2) * len(present)
    for k in present:
        draw.ellipse([x0, y, x0 + size, y + size], fill=STATE_COLORS[k], outline="#333333")
        draw.text((x0 + 1.5 * size, y - size // 8), STATE_NAMES[k], fill="#222222", font=font)
        y += size + size // 2
    return np.asarray(im)


def render_contact_states(filename, points, frames, radius, contact_points, states, *,
                          legend=True, **kwargs):
    """Render the rod with contact markers coloured by their state.

    The markers are the spheres of :func:`render_rod` at ``contact_points``,
    coloured open grey, stick green, slip orange (:data:`STATE_COLORS`);
    with ``legend=True`` the states present are named in the lower left
    corner.  The PNG is written atomically.

    Parameters
    ----------
    filename, points, frames, radius
        As in :func:`render_rod`.
    contact_points : array_like, (m, 3)
        Marker positions (e.g. the slave points of the contact pairs).
    states : array_like of int, (m,)
        ``0`` open, ``1`` stick, ``2`` slip.
    legend : bool, default True
        Name the states shown.
    **kwargs
        Passed on to :func:`render_rod` (``window_size``, ``title``,
        ``camera``, ``glyphs`` ...; not ``contact_colors``).

    Returns
    -------
    str
        ``filename``.

    Examples
    --------
    >>> import numpy as np
    >>> s = np.linspace(0, 1, 20)
    >>> pts = np.c_[s, 0 * s, 0 * s]
    >>> R = np.repeat([[[0, 0, 1], [0, 1, 0], [-1, 0, 0]]], 20, axis=0)  # d3 = +x
    >>> render_contact_states("states.png", pts, R, 0.02, pts[[5, 10, 15]],
    ...                       [0, 1, 2], window_size=(320, 240))  # doctest: +SKIP
    'states.png'
    """
    if "contact_colors" in kwargs:
        raise ValueError("render_contact_states colours the markers by state; "
                         "do not pass contact_colors (use render_rod for free colours)")
    cp = _as_points("contact_points", contact_points)
    colors = contact_state_colors(states)
    if len(colors) != len(cp):
        raise ValueError(
            f"states has {len(colors)} entries but contact_points has {len(cp)} points; "
            f"give one state per point"
        )
    render_rod(filename, points, frames, radius, contact_points=cp,
               contact_colors=colors, **kwargs)
    if legend and len(cp):
        from PIL import Image

        img = _draw_state_legend(np.asarray(Image.open(filename).convert("RGB")), states)
        with _atomic_path(filename) as tmp:
            Image.fromarray(img).save(tmp, format="PNG")
    return os.fspath(filename)


def render_animation(filename, configurations, radius, *, window_size=(640, 480),
                     fps=4, titles=None, camera="iso", contact_points=None,
                     contact_states=None, color=ROD_COLOR, stripe_color=STRIPE_COLOR,
                     stripe_width=0.35, n_around=32, background="white",
                     hold_last=2, off_screen=None):
    """Write an animated GIF of a sequence of rod configurations (a load path).

    Every frame is drawn like :func:`render_rod` (tube with the ``d1``
    stripe, optional contact markers) by one off-screen plotter with **one
    camera for all frames**, fitted to the union of all configurations, so
    the rod moves inside a fixed view.  The frames are assembled into a
    looping GIF with Pillow (already a dependency of pyvista and matplotlib;
    no video codec needed) and written atomically.

    Parameters
    ----------
    filename : str or os.PathLike
        Output ``.gif``.
    configurations : sequence of (points, frames)
        One ``((n, 3), (n, 3, 3))`` pair per frame, as in :func:`render_rod`
        (``n`` may change between frames).
    radius : float
        Tube radius.
    window_size : (int, int), default (640, 480)
        Frame size in pixels.
    fps : float, default 4
        Frames per second.
    titles : sequence of str, optional
        One caption per frame (e.g. the load factor).
    camera : str or array_like (3,), default "iso"
        A pyvista view (``"iso"``, ``"xy"``, ...) or a view direction (from
        the scene towards the camera, e.g. ``(0, -0.6, 1)``: from above,
        tilted); the view is then fitted to all frames.
    contact_points : sequence of array_like (m_k, 3), optional
        Contact markers per frame.
    contact_states : sequence of array_like (m_k,), optional
        Integer states per frame (0 open, 1 stick, 2 slip); without them the
        markers take the default contact colour.
    color, stripe_color, stripe_width, n_around, background
        As in :func:`render_rod`.
    hold_last : int, default 2
        Repeat the last frame this many extra times (a pause before the
        loop restarts).
    off_screen : bool, optional
        As in :func:`render_rod`.

    Returns
    -------
    str
        ``filename``.

    Examples
    --------
    A rod rolling up under a growing end moment (``result`` from
    :meth:`skfem_rod.Rod.solve`)::

        confs = [(f["r"], f["R"]) for f in (result.sample(8, k)
                                            for k in range(len(result.steps)))]
        render_animation("rollup.gif", confs, radius=0.02,
                         titles=[f"load factor {st.load_factor:.2f}"
                                 for st in result.steps])
    """
    pv = _pyvista(off_screen)
    confs = list(configurations)
    if not confs:
        raise ValueError("configurations is empty; give at least one (points, frames) pair")
    width, height = _window_size(window_size)
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps = {fps!r}; expected a number > 0")
    for name, seq in (("titles", titles), ("contact_points", contact_points),
                      ("contact_states", contact_states)):
        if seq is not None and len(seq) != len(confs):
            raise ValueError(f"{name} has {len(seq)} entries for {len(confs)} "
                             f"configurations; give one per configuration")
    if contact_states is not None and contact_points is None:
        raise ValueError("contact_states needs contact_points (one array per frame)")

    tubes, markers = [], []
    for k, (pts, frs) in enumerate(confs):
        pts, frs = _validate_points_frames(pts, frs)
        r = _radii(radius, pts.shape[0])
        tube = tube_mesh(pts, frs, r, n_around=n_around, stripe_width=stripe_width)
        tube.point_data["stripe_coord"] = np.where(
            tube.point_data["cap"] == 1, np.pi, np.abs(tube.point_data["phi"]))
        tubes.append(tube)
        cloud = None
        if contact_points is not None:
            cp = (np.zeros((0, 3)) if np.size(contact_points[k]) == 0
                  else _as_points(f"contact_points[{k}]", contact_points[k]))
            if len(cp):
                cloud = pv.PolyData(cp)
                if contact_states is not None:
                    rgb = contact_state_colors(contact_states[k])
                    if len(rgb) != len(cp):
                        raise ValueError(
                            f"contact_states[{k}] has {len(rgb)} entries but "
                            f"contact_points[{k}] has {len(cp)} points")
                    cloud.point_data["rgb"] = rgb
                cloud = cloud.glyph(geom=pv.Sphere(radius=1.25 * r.max(), theta_resolution=16,
                                                   phi_resolution=16), scale=False, orient=False)
        markers.append(cloud)

    all_pts = np.vstack([t.points for t in tubes] + [m.points for m in markers if m is not None])
    if len(all_pts) > 50000:
        all_pts = all_pts[:: len(all_pts) // 50000 + 1]
    lo, hi = all_pts.min(axis=0), all_pts.max(axis=0)
    bounds = (lo[0], hi[0], lo[1], hi[1], lo[2], hi[2])
    cmap = _color_lut(pv, color, stripe_color, stripe_width)
    text_color = "black" if np.mean(pv.Color(background).float_rgb) > 0.5 else "white"

    images = []
    pl = pv.Plotter(off_screen=True, window_size=(width, height), lighting="three lights")
    try:
        pl.set_background(background)
        try:
            pl.enable_anti_aliasing("ssaa")
        except Exception:  # pragma: no cover - depends on the VTK build
            pass
        if isinstance(camera, str):
            pl.camera_position = camera
        else:
            view = np.asarray(camera, dtype=float)
            if view.shape != (3,) or not np.all(np.isfinite(view)) or not view.any():
                raise ValueError(f"camera = {camera!r}; expected a pyvista view name "
                                 f"('iso', 'xy', ...) or a non-zero 3-vector")
            pl.view_vector(view)
        pl.reset_camera(bounds=bounds)
        _fit_camera(pl, all_pts, 0.8 if titles else 0.9)
        cam = pl.camera.copy()
        for k, tube in enumerate(tubes):
            pl.add_mesh(tube, scalars="stripe_coord", clim=(0.0, np.pi), cmap=cmap,
                        interpolate_before_map=True, show_scalar_bar=False,
                        smooth_shading=True, specular=0.3, specular_power=20,
                        ambient=0.2, name="rod", reset_camera=False)
            if markers[k] is not None:
                kw = ({"scalars": "rgb", "rgb": True} if "rgb" in markers[k].point_data
                      else {"color": CONTACT_COLOR})
                pl.add_mesh(markers[k], smooth_shading=True, show_scalar_bar=False,
                            ambient=0.2, name="contacts", reset_camera=False, **kw)
            else:
                pl.remove_actor("contacts")
            if titles:
                pl.add_text(str(titles[k]), position="upper_edge", name="title",
                            font_size=max(8, round(14 * height / 768)), color=text_color)
            pl.camera = cam.copy()
            img = np.asarray(pl.screenshot(None, return_img=True))[..., :3]
            if contact_states is not None and markers[k] is not None:
                img = _draw_state_legend(img, contact_states[k])
            images.append(np.ascontiguousarray(img))
    finally:
        pl.close()

    if images[0].shape[:2] != (height, width):
        raise RuntimeError(
            f"renderer produced frames of {images[0].shape[1]}x{images[0].shape[0]} "
            f"pixels, not the requested {width}x{height}")
    from PIL import Image

    pics = [Image.fromarray(im) for im in images]
    pics += [pics[-1]] * int(max(hold_last, 0))
    # one adaptive palette from all frames keeps the colours steady
    palette = Image.fromarray(np.vstack(images[:: max(1, len(images) // 8)])).quantize(
        colors=255, method=Image.Quantize.MEDIANCUT)
    frames_p = [p.quantize(palette=palette, dither=Image.Dither.NONE) for p in pics]
    with _atomic_path(filename) as tmp:
        frames_p[0].save(tmp, format="GIF", save_all=True, append_images=frames_p[1:],
                         duration=round(1000 / fps), loop=0, disposal=1)
    return os.fspath(filename)
