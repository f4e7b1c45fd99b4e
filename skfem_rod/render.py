r"""Render rod configurations to PNG with pyvista (works headless).

Inputs are plain numpy arrays (independent of the solver):

* ``points``  ``(n, 3)``: centreline positions, ordered along the rod;
* ``frames``  ``(n, 3, 3)``: rotation matrices whose **columns** are the
  directors ``d1, d2, d3`` (``d3`` the tangent).

The rod is drawn as a tube built from the frames themselves (not from a
Frenet frame or ``pyvista.Spline.tube``), with a coloured stripe along the
material line ``d1``: an untwisted rod shows a straight stripe, a twisted
one a helical stripe, so twist is visible in a still image.

Every picture uses the same visual code (:data:`STATE_COLORS`,
:data:`CONTACT_COLOR`, ...): the reference shape as a translucent grey ghost,
supports as dark grey blocks (clamps) or balls (pins), forces as black
arrows, moments as brown double arrows, an axes triad in the lower right
corner; titles, legends and colour bars are drawn with DejaVu Sans (Greek
letters and maths symbols show) in bands that never cover the rod.

``pyvista`` is imported inside the functions.  Rendering always uses an
off-screen plotter (``pyvista.Plotter(off_screen=True)``): nothing global in
pyvista is changed, so a notebook's own plotting settings stay as they are.
VTK's warnings while it probes for a display (e.g. "bad X server
connection" on a headless machine) are silenced for the duration of a
render only (:func:`quiet_vtk`).
"""
from __future__ import annotations

import contextlib
import math
import os
import sys

import numpy as np

from .export import atomic_path, validate_points_frames

__all__ = ["tube_mesh", "render_rod", "ROD_COLOR", "STRIPE_COLOR", "STATE_NAMES",
           "STATE_COLORS", "CONTACT_COLOR", "CROSSING_COLOR", "contact_state_colors",
           "render_contact_states",
           "render_animation", "quiet_vtk"]

ROD_COLOR = "#4f81bd"       # base colour of the tube (blue)
STRIPE_COLOR = "#d62728"    # material line along d1 (red)
#: Colour of frictionless contact points (purple: green and orange are the
#: stick and slip of :data:`STATE_COLORS`, one code in every picture).
CONTACT_COLOR = "#9467bd"
#: Colour of the crossing pairs' contact points (pink: the point pairs of
#: crossing strands, whatever their friction state;
#: :meth:`skfem_rod.Result.crossing_points`).
CROSSING_COLOR = "#e377c2"
GLYPH_COLOR = "#222222"     # forces (black arrows)
MOMENT_COLOR = "#8c564b"    # moments (brown double arrows)
SUPPORT_COLOR = "#555555"   # clamps (blocks) and pins (balls)
REFERENCE_COLOR = "#9a9a9a"  # the reference shape (translucent ghost)
#: Colour-bar titles of the fields of :meth:`skfem_rod.Result.to_pyvista`
#: (``Result.render(color_by=...)``).
FIELD_LABELS = {
    "moment_magnitude": "|m|", "force_magnitude": "|n|",
    "twist": "twist u\u2083 \u2212 u\u2083\u2070", "curvature": "bending |u\u2081\u2082 \u2212 u\u2081\u2082\u2070|",
    "stretch": "stretch v\u2083 \u2212 v\u2083\u2070", "shear": "shear |v\u2081\u2082|",
    "contact_force": "normal contact force", "arclength": "arclength s",
}


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------
def _has_display():
    if sys.platform.startswith(("win", "cygwin", "darwin")):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _pyvista(off_screen=None):
    """Import pyvista (nothing global is changed: every plotter of this
    module is created with ``off_screen=True``).  Its import pulls in
    ``tqdm.auto``, which warns "IProgress not found" in a notebook without
    ipywidgets; that warning is dropped."""
    import warnings

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="IProgress not found")
        import pyvista

    return pyvista


@contextlib.contextmanager
def quiet_vtk():
    """Silence VTK's warnings and errors in the ``with`` block only.

    A headless render makes VTK probe for an X display and print "bad X
    server connection" (and similar) to stderr; the global warning switch
    of ``vtkObject`` is turned off inside the block and restored after it.

    Examples
    --------
    >>> with quiet_vtk():
    ...     pass                     # build and screenshot a pyvista.Plotter here
    """
    from vtkmodules.vtkCommonCore import vtkObject

    previous = vtkObject.GetGlobalWarningDisplay()
    vtkObject.GlobalWarningDisplayOff()
    try:
        yield
    finally:
        vtkObject.SetGlobalWarningDisplay(previous)


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
    points, frames = validate_points_frames(points, frames)
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


# --------------------------------------------------------------------------
# annotations drawn on the image (title, legend, colour bar)
# --------------------------------------------------------------------------
def _font(size, bold=False):
    """DejaVu Sans (shipped with matplotlib: Greek letters and maths
    symbols) at ``size`` pixels."""
    from PIL import ImageFont

    try:
        import matplotlib

        name = "DejaVuSans-Bold.ttf" if bold else "DejaVuSans.ttf"
        return ImageFont.truetype(os.path.join(matplotlib.get_data_path(), "fonts", "ttf",
                                               name), size)
    except (ImportError, OSError):  # pragma: no cover - matplotlib is a dependency
        return _legend_font(size)


def _base_font_size(width, height):
    """Text size in pixels for an image of ``width x height``."""
    return max(11, round(17 * min(width / 640, height / 480)))


def _text_width(font, text):
    left, _, right, _ = font.getbbox(text)
    return right - left


def _title_lines(title, width, size):
    """Font size and lines of a title that fits ``width``: shrunk down to
    11 px, then wrapped at spaces."""
    title = str(title)
    for s in range(size, 10, -1):
        font = _font(s)
        if _text_width(font, title) <= 0.96 * width:
            return font, s, [title]
    s = 11
    font = _font(s)
    lines, line = [], ""
    for word in title.split():
        trial = f"{line} {word}".strip()
        if line and _text_width(font, trial) > 0.96 * width:
            lines.append(line)
            line = word
        else:
            line = trial
    lines.append(line)
    return font, s, lines


def _layout(width, height, title, colorbar):
    """Split the image into a title band (top), the 3D scene and a colour-bar
    band (right).  Returns ``(scene_w, scene_h, top, title_spec)``."""
    size = _base_font_size(width, height)
    spec = None
    top = 0
    if title:
        font, s, lines = _title_lines(title, width, round(1.15 * size))
        top = round(len(lines) * 1.3 * s + 0.6 * s)
        spec = (font, s, lines)
    right = 0
    if colorbar:
        font = _font(size)
        ticks = _colorbar_ticks(*colorbar[1])
        right = round(max(0.12 * width, 2.3 * size + max(_text_width(font, t) for t in ticks)
                          + 0.6 * size))
    return width - right, height - top, top, spec


def _colorbar_ticks(lo, hi):
    """Five tick labels from ``lo`` to ``hi``, with enough digits to differ."""
    scale = max(abs(lo), abs(hi))
    digits = 3 if scale == 0 else max(3, 2 + int(math.ceil(math.log10(scale / (hi - lo)))))
    return [f"{v:.{digits}g}" for v in np.linspace(lo, hi, 5)]


def _text_color(background):
    from pyvista import Color

    return "#000000" if np.mean(Color(background).float_rgb) > 0.5 else "#ffffff"


def _compose(scene, width, height, top, background, title_spec=None, legend=(),
             colorbar=None):
    """Paste the rendered ``scene`` (RGB array) under the title band of a
    ``width x height`` canvas and draw the title, the legend (lower left
    corner of the scene) and the colour bar (right band)."""
    from PIL import Image, ImageDraw
    from pyvista import Color

    bg = tuple(Color(background).int_rgb)
    fg = _text_color(background)
    canvas = Image.new("RGB", (width, height), bg)
    canvas.paste(Image.fromarray(np.ascontiguousarray(scene[..., :3])), (0, top))
    draw = ImageDraw.Draw(canvas)
    size = _base_font_size(width, height)
    if title_spec is not None:
        font, s, lines = title_spec
        y = round(0.3 * s)
        for line in lines:
            draw.text(((width - _text_width(font, line)) / 2, y), line, fill=fg, font=font)
            y += round(1.3 * s)
    if legend:
        ls = max(10, round(0.8 * size))
        _draw_legend(draw, legend, x0=round(0.6 * ls), y1=height - round(0.6 * ls),
                     size=ls, fg=fg, bg=bg)
    if colorbar is not None:
        _draw_colorbar(draw, colorbar, x0=scene.shape[1], top=top, width=width - scene.shape[1],
                       height=height - top, size=size, fg=fg)
    return np.asarray(canvas)


def _draw_legend(draw, entries, x0, y1, size, fg, bg):
    """Entries ``(kind, colour, label)`` stacked upwards from ``y1``; kind
    ``"dot"`` (a marker), ``"line"`` (a thick line), ``"arrow"``,
    ``"box"`` or ``"ghost"``."""
    font = _font(size)
    step = round(1.45 * size)
    w = max(_text_width(font, label) for _, _, label in entries) + round(2.4 * size)
    y0 = y1 - step * len(entries)
    draw.rectangle([x0 - size // 3, y0 - size // 3, x0 + w, y1], fill=bg,
                   outline="#cccccc")
    y = y0
    for kind, color, label in entries:
        cy = y + step / 2 - size / 6
        if kind == "dot":
            draw.ellipse([x0, cy - size / 2, x0 + size, cy + size / 2], fill=color,
                         outline="#333333")
        elif kind == "line":
            draw.line([x0 - 2, cy, x0 + size + 2, cy], fill=color, width=max(3, size // 4))
        elif kind == "ghost":
            draw.rounded_rectangle([x0 - 2, cy - size / 4, x0 + size + 2, cy + size / 4],
                                   radius=size // 4, fill="#dedede", outline=color)
        elif kind == "box":
            draw.rectangle([x0 + 1, cy - size / 2 + 1, x0 + size - 1, cy + size / 2 - 1],
                           fill=color)
        elif kind in ("arrow", "double"):
            lw = max(2, size // 6)
            draw.line([x0, cy, x0 + size, cy], fill=color, width=lw)
            h = size / 3
            draw.polygon([(x0 + size + 2, cy), (x0 + size - h, cy - h), (x0 + size - h, cy + h)],
                         fill=color)
            if kind == "double":
                draw.polygon([(x0 + size - h, cy), (x0 + size - 2 * h - 2, cy - h),
                              (x0 + size - 2 * h - 2, cy + h)], fill=color)
        draw.text((x0 + round(1.6 * size), y + (step - size) / 2 - size / 5), label, fill=fg,
                  font=font)
        y += step


def _draw_colorbar(draw, bar, x0, top, width, height, size, fg):
    """Vertical colour bar ``bar = (cmap, (lo, hi), label)`` in the band
    ``[x0, x0 + width] x [top, top + height]``."""
    import matplotlib

    cmap, (lo, hi), label = bar
    cmap = matplotlib.colormaps[cmap] if isinstance(cmap, str) else cmap
    font = _font(size)
    # the label above the bar, shrunk to fit the band
    s = size
    while s > 9 and _text_width(_font(s), label) > 0.96 * width:
        s -= 1
    lfont = _font(s)
    y_label = top + round(0.12 * height)
    draw.text((x0 + (width - _text_width(lfont, label)) / 2 - 0.02 * width, y_label), label,
              fill=fg, font=lfont)
    bx0 = x0 + round(0.6 * size)
    bw = max(8, round(0.9 * size))
    by0 = y_label + round(1.8 * size)
    by1 = top + round(0.88 * height)
    n = max(2, by1 - by0)
    for k in range(n):
        rgba = cmap(1 - k / (n - 1))
        draw.line([bx0, by0 + k, bx0 + bw, by0 + k],
                  fill=tuple(int(round(255 * c)) for c in rgba[:3]))
    draw.rectangle([bx0, by0, bx0 + bw, by0 + n], outline="#555555")
    for t, text in zip(np.linspace(0, 1, 5), _colorbar_ticks(lo, hi)):
        y = by0 + (1 - t) * n
        draw.line([bx0 + bw, y, bx0 + bw + size // 3, y], fill="#555555", width=1)
        draw.text((bx0 + bw + size // 2, y - 0.6 * size), text, fill=fg, font=font)


# --------------------------------------------------------------------------
# scene pieces: reference ghost, supports, loads
# --------------------------------------------------------------------------
def _tube_actor_kwargs():
    return dict(smooth_shading=True, specular=0.3, specular_power=20, ambient=0.2)


def _support_meshes(pv, supports, size):
    """Blocks (clamps, prescribed motions) and balls (pins) of edge/diameter
    ``size`` at the support points."""
    blocks, balls = [], []
    for sup in supports or ():
        p = _as_points("supports point", sup["point"])[0]
        kind = sup.get("kind", "clamp")
        if kind == "pin":
            balls.append(pv.Sphere(radius=size / 2, center=p, theta_resolution=20,
                                   phi_resolution=20))
        elif kind in ("clamp", "turn", "move", "slide"):
            blocks.append(pv.Cube(center=p, x_length=size, y_length=size, z_length=size))
        else:
            raise ValueError(f"support kind {kind!r}; expected 'clamp', 'pin', 'turn', "
                             f"'move' or 'slide'")
    merge = (lambda ms: None if not ms else (ms[0] if len(ms) == 1 else ms[0].merge(ms[1:])))
    return merge(blocks), merge(balls)


def _block_label(supports):
    """Legend text of the support blocks: clamps, turned or moved ends."""
    kinds = {sup.get("kind", "clamp") for sup in supports or ()}
    names = [name for kind, name in (("clamp", "clamp"), ("turn", "turned end"),
                                     ("move", "moved end"), ("slide", "guided end"))
             if kind in kinds]
    return " / ".join(names)


def _load_meshes(pv, loads, length, start_offset, centre=None):
    """Arrows of length ``length`` for ``loads`` (dicts ``point``,
    ``vector``, ``kind``): forces single, moments double headed, kept
    ``start_offset`` away from the point (outside the tube).  A force that
    points away from ``centre`` (the middle of the rod: a pull) starts at
    its point; one that points towards it (a push) ends at its point."""
    forces, moments = [], []
    loads = list(loads or ())
    if len(loads) > 4:
        # a load spread over many nodes: shorter arrows, at most 10 of them
        length = 0.4 * length
        loads = loads[::-(-len(loads) // 10)]
    for ld in loads:
        p = _as_points("loads point", ld["point"])[0]
        v = np.asarray(ld["vector"], float)
        nv = np.linalg.norm(v)
        if not np.isfinite(nv) or nv == 0:
            continue
        d = v / nv
        start = p + start_offset * d
        if (ld.get("kind", "force") != "moment" and centre is not None
                and d @ (p - centre) < 0):                     # a push: tip at the point
            start = p - (start_offset + length) * d
        if ld.get("kind", "force") == "moment":
            arrow = pv.Arrow(start=start, direction=d, scale=length, tip_length=0.22,
                             tip_radius=0.07, shaft_radius=0.025)
            second = pv.Cone(center=start + d * length * 0.67, direction=d,
                             height=0.22 * length, radius=0.07 * length, resolution=24)
            moments += [arrow, second]
        else:
            forces.append(pv.Arrow(start=start, direction=d, scale=length, tip_length=0.25,
                                   tip_radius=0.08, shaft_radius=0.03))
    merge = (lambda ms: None if not ms else (ms[0] if len(ms) == 1 else ms[0].merge(ms[1:])))
    return merge(forces), merge(moments)


def _view_vector(camera):
    """``camera`` as a view direction (a 3-vector, from the scene towards
    the camera), or None if it is a view name or a camera position."""
    if isinstance(camera, str):
        return None
    try:
        v = np.asarray(camera, dtype=float)
    except (TypeError, ValueError):
        return None
    if v.shape != (3,):
        return None
    if not np.all(np.isfinite(v)) or not v.any():
        raise ValueError(f"camera = {camera!r}; a view direction must be a finite, "
                         f"non-zero 3-vector")
    return v


def _view_up(view):
    """+z up, unless the view is along z (then +y)."""
    v = view / np.linalg.norm(view)
    return (0.0, 1.0, 0.0) if abs(v[2]) > 0.95 else (0.0, 0.0, 1.0)


def _centreline_values(name, values, n):
    a = np.asarray(values, dtype=float)
    if a.shape != (n,):
        raise ValueError(f"{name} has shape {a.shape}; expected ({n},): one value per "
                         f"centreline point")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains NaN/inf; only finite values are allowed")
    return a


def tube_point_values(values, n, m, capped=True):
    """Per-centreline-point values spread over a tube of ``tube_mesh``
    (rings, then the two caps)."""
    out = np.repeat(values, m)
    if capped:
        out = np.concatenate([out, np.full(m + 1, values[0]), np.full(m + 1, values[-1])])
    return out


def render_rod(filename, points, frames, radius, *, window_size=(1024, 768),
               contact_points=None, contact_colors=None, contact_states=None,
               crossing_points=None, glyphs=None,
               title=None, background="white", camera="iso", color=ROD_COLOR,
               stripe_color=STRIPE_COLOR, stripe_width=0.35, n_around=48,
               contact_radius=None, zoom=None, off_screen=None, reference=None,
               supports=None, loads=None, scalars=None, cmap="viridis", clim=None,
               scalar_label=None, axes=True, legend=True):
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
        Default :data:`CONTACT_COLOR` (frictionless contact).
    contact_states : array_like of int (m,), optional
        Instead of ``contact_colors``: the friction state of each point
        (0 open, 1 stick, 2 slip), coloured by :data:`STATE_COLORS` and
        named in the legend.
    crossing_points : array_like (k, 3), optional
        Contact points of crossing pairs (point forces of crossing strands,
        :meth:`skfem_rod.Result.crossing_points`), drawn as spheres of
        ``contact_radius`` in :data:`CROSSING_COLOR`.
    glyphs : dict, optional
        Arrows: ``points`` (k, 3), ``vectors`` (k, 3), optional ``color``
        and ``scale`` (arrow length = ``scale * |vector|``; default: the
        longest arrow is 15 % of the rod's bounding-box diagonal).
    title : str, optional
        Text above the scene (DejaVu Sans: Greek letters show), shrunk or
        wrapped to fit the width.
    background : colour
    camera : str, 3-vector or camera position
        A pyvista view (``"iso"``, ``"xy"``, ``"xz"``, ``"yz"``, ``"yx"``,
        ``"zx"``, ``"zy"``) or a view direction (from the scene towards the
        camera, e.g. ``(0.2, -1, 0.45)``; ``+z`` up): the camera is reset
        onto the whole scene and then zoomed so that the scene fills about
        90 % of its part of the image.  Anything else (e.g.
        ``[position, focal_point, view_up]``) is passed to
        ``Plotter.camera_position`` and used as is.
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
        Accepted for compatibility; rendering always uses an off-screen
        plotter and changes no global pyvista setting.
    reference : (points, frames), optional
        The reference shape, drawn as a translucent grey ghost.
    supports : list of dict, optional
        ``{"point": (3,), "kind": "clamp" | "pin" | "turn" | "move" | "slide"}``:
        dark grey blocks (clamps, turned or moved ends, partly guided ends)
        or balls (pins).
    loads : list of dict, optional
        ``{"point": (3,), "vector": (3,), "kind": "force" | "moment"}``:
        arrows of one length showing the direction (forces black, moments
        brown double arrows).
    scalars : array_like (n,), optional
        A field per centreline point: the tube is coloured by it through
        ``cmap`` (limits ``clim``, default its range) with a colour bar
        titled ``scalar_label``; the material line is then a thin red line.
    axes : bool, default True
        An x-y-z triad in the lower right corner.
    legend : bool, default True
        Name what is drawn (reference, supports, loads, contact markers) in
        the lower left corner.

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
    >>> render_rod("rod.png", pts, R, 0.02, window_size=(320, 240), title="κ = 0",
    ...            supports=[{"point": pts[0], "kind": "clamp"}])  # doctest: +SKIP
    'rod.png'
    """
    img = _rod_image(points, frames, radius, window_size=window_size,
                     contact_points=contact_points, contact_colors=contact_colors,
                     contact_states=contact_states, crossing_points=crossing_points,
                     glyphs=glyphs, title=title, background=background, camera=camera,
                     color=color,
                     stripe_color=stripe_color, stripe_width=stripe_width, n_around=n_around,
                     contact_radius=contact_radius, zoom=zoom, reference=reference,
                     supports=supports, loads=loads, scalars=scalars, cmap=cmap, clim=clim,
                     scalar_label=scalar_label, axes=axes, legend=legend)
    from PIL import Image  # a dependency of pyvista and matplotlib

    with atomic_path(filename) as tmp:
        Image.fromarray(np.ascontiguousarray(img)).save(tmp, format="PNG")
    return os.fspath(filename)


def _rod_image(points, frames, radius, *, window_size=(1024, 768), contact_points=None,
               contact_colors=None, contact_states=None, crossing_points=None, glyphs=None,
               title=None,
               background="white", camera="iso", color=ROD_COLOR, stripe_color=STRIPE_COLOR,
               stripe_width=0.35, n_around=48, contact_radius=None, zoom=None,
               reference=None, supports=None, loads=None, scalars=None, cmap="viridis",
               clim=None, scalar_label=None, axes=True, legend=True):
    """The picture of :func:`render_rod` as an ``(h, w, 3)`` uint8 array."""
    pv = _pyvista()
    points, frames = validate_points_frames(points, frames)
    n = points.shape[0]
    r = _radii(radius, n)
    width, height = _window_size(window_size)
    if contact_states is not None and contact_colors is not None:
        raise ValueError("give contact_colors or contact_states, not both")
    values = None if scalars is None else _centreline_values("scalars", scalars, n)
    if values is not None:
        lo, hi = (float(values.min()), float(values.max())) if clim is None else map(float, clim)
        if hi <= lo:
            hi = lo + max(abs(lo), 1.0) * 1e-6
        bar = (cmap, (lo, hi), str(scalar_label or "scalars"))
    else:
        bar = None
    sw, sh, top, title_spec = _layout(width, height, title, bar)

    tube = tube_mesh(points, frames, r, n_around=n_around, stripe_width=stripe_width)
    tube.point_data["stripe_coord"] = np.where(
        tube.point_data["cap"] == 1, np.pi, np.abs(tube.point_data["phi"]))
    fit_pts = [tube.points]
    entries = []
    size = 3.5 * r.max()                  # edge of a support block

    with quiet_vtk():
        pl = pv.Plotter(off_screen=True, window_size=(sw, sh), lighting="three lights")
        try:
            pl.set_background(background)
            try:  # smoother silhouettes; SSAA works with the OSMesa/EGL fallback
                pl.enable_anti_aliasing("ssaa")
            except Exception:  # pragma: no cover - depends on the VTK build
                pass
            if values is None:
                # |phi| interpolated linearly across the quads and mapped through a
                # two-colour table gives a stripe edge exactly at |phi| = stripe_width/2.
                pl.add_mesh(tube, scalars="stripe_coord", clim=(0.0, np.pi),
                            cmap=_color_lut(pv, color, stripe_color, stripe_width),
                            interpolate_before_map=True, show_scalar_bar=False,
                            **_tube_actor_kwargs())
            else:
                tube.point_data["field"] = tube_point_values(values, n, int(n_around))
                pl.add_mesh(tube, scalars="field", clim=bar[1], cmap=cmap,
                            show_scalar_bar=False, **_tube_actor_kwargs())
                line = pv.lines_from_points(points + 1.02 * r[:, None] * frames[:, :, 0])
                pl.add_mesh(line.tube(radius=0.15 * r.max()), color=stripe_color,
                            smooth_shading=True)
            entries.append(("line", stripe_color, "material line d\u2081"))

            if reference is not None:
                ref_pts, ref_frames = validate_points_frames(*reference)
                ghost = tube_mesh(ref_pts, ref_frames, _radii(r.max(), len(ref_pts)),
                                  n_around=24)
                pl.add_mesh(ghost, color=REFERENCE_COLOR, opacity=0.3, smooth_shading=True,
                            show_scalar_bar=False)
                fit_pts.append(ghost.points)
                entries.insert(0, ("ghost", REFERENCE_COLOR, "reference shape"))

            blocks, balls = _support_meshes(pv, supports, size)
            if blocks is not None:
                pl.add_mesh(blocks, color=SUPPORT_COLOR, ambient=0.3)
                fit_pts.append(blocks.points)
                entries.append(("box", SUPPORT_COLOR, _block_label(supports)))
            if balls is not None:
                pl.add_mesh(balls, color=SUPPORT_COLOR, smooth_shading=True, ambient=0.3)
                fit_pts.append(balls.points)
                entries.append(("dot", SUPPORT_COLOR, "pin"))

            if loads:
                diag = np.linalg.norm(np.ptp(np.vstack(fit_pts), axis=0))
                forces, moments = _load_meshes(pv, loads, 0.2 * diag, 1.5 * size / 2,
                                               centre=points.mean(axis=0))
                if forces is not None:
                    pl.add_mesh(forces, color=GLYPH_COLOR, smooth_shading=True)
                    fit_pts.append(forces.points)
                    entries.append(("arrow", GLYPH_COLOR, "force"))
                if moments is not None:
                    pl.add_mesh(moments, color=MOMENT_COLOR, smooth_shading=True)
                    fit_pts.append(moments.points)
                    entries.append(("double", MOMENT_COLOR, "moment"))

            rad = float(contact_radius) if contact_radius is not None else 1.25 * r.max()
            if (contact_points is not None or crossing_points is not None) \
                    and not (np.isfinite(rad) and rad > 0):
                raise ValueError(f"contact_radius = {contact_radius!r}; expected > 0")
            if contact_points is not None:
                cp = _as_points("contact_points", contact_points)
                if len(cp):
                    cloud = pv.PolyData(cp)
                    if contact_states is not None:
                        rgb = contact_state_colors(contact_states)
                        if len(rgb) != len(cp):
                            raise ValueError(
                                f"states has {len(rgb)} entries but contact_points has "
                                f"{len(cp)} points; give one state per point")
                        cloud.point_data["rgb"] = rgb
                        kw = {"scalars": "rgb", "rgb": True}
                        for k in sorted(set(np.asarray(contact_states, int).tolist())):
                            entries.append(("dot", STATE_COLORS[k], STATE_NAMES[k]))
                    else:
                        kw = _contact_color_kwargs(pv, cloud, contact_colors, len(cp))
                        if contact_colors is None:
                            entries.append(("dot", CONTACT_COLOR, "contact"))
                    spheres = cloud.glyph(
                        geom=pv.Sphere(radius=rad, theta_resolution=20, phi_resolution=20),
                        scale=False, orient=False)
                    pl.add_mesh(spheres, smooth_shading=True, show_scalar_bar=False,
                                ambient=0.2, **kw)
                    fit_pts.append(spheres.points)
            if crossing_points is not None:
                xp = _as_points("crossing_points", crossing_points)
                if len(xp):
                    spheres = pv.PolyData(xp).glyph(
                        geom=pv.Sphere(radius=rad, theta_resolution=20, phi_resolution=20),
                        scale=False, orient=False)
                    pl.add_mesh(spheres, color=CROSSING_COLOR, smooth_shading=True,
                                ambient=0.2)
                    fit_pts.append(spheres.points)
                    entries.append(("dot", CROSSING_COLOR, "crossing pair"))

            if glyphs is not None:
                arrows = _arrow_mesh(pv, glyphs, points)
                if arrows is not None:
                    pl.add_mesh(arrows, color=glyphs.get("color", GLYPH_COLOR),
                                smooth_shading=True)
                    fit_pts.append(arrows.points)

            if axes:
                pl.add_axes(viewport=(0.84, 0.0, 1.0, 0.2), line_width=3,
                            labels_off=False)

            view = _view_vector(camera)
            if isinstance(camera, str) or view is not None:
                if view is None:
                    pl.camera_position = camera
                else:
                    pl.view_vector(view, viewup=_view_up(view))
                pl.reset_camera()
                if zoom is None:
                    pts = np.vstack(fit_pts)
                    if len(pts) > 50000:
                        pts = pts[:: len(pts) // 50000 + 1]
                    _fit_camera(pl, pts, 0.9)
                else:
                    pl.camera.zoom(float(zoom))
            else:
                pl.camera_position = camera

            scene = np.asarray(pl.screenshot(None, return_img=True))[..., :3]
        finally:
            pl.close()

    if scene.shape[:2] != (sh, sw):
        raise RuntimeError(
            f"renderer produced an image of {scene.shape[1]}x{scene.shape[0]} pixels, "
            f"not the requested {sw}x{sh}")
    return _compose(scene, width, height, top, background, title_spec,
                    entries if legend else (), bar)


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


def _state_entries(states):
    present = sorted(set(np.asarray(states, int).tolist()))
    return [("dot", STATE_COLORS[k], STATE_NAMES[k]) for k in present]


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
        Name what is shown.
    **kwargs
        Passed on to :func:`render_rod` (``window_size``, ``title``,
        ``camera``, ``glyphs``, ``reference`` ...; not ``contact_colors``).

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
    kwargs.setdefault("axes", legend)
    return render_rod(filename, points, frames, radius, contact_points=cp,
                      contact_states=np.asarray(states, int), legend=legend, **kwargs)


def _gif_palette(images, fixed):
    """A 256-colour palette: an adaptive one for the frames plus every colour
    of ``fixed`` in several shades (so that shaded markers keep their hue
    when the frames are quantized)."""
    from PIL import Image

    from pyvista import Color

    shades = []
    for c in fixed:
        rgb = np.array(Color(c).int_rgb, float)
        for f in (0.45, 0.6, 0.75, 0.9, 1.0):
            shades.append(np.rint(rgb * f))
        for t in (0.25, 0.5):
            shades.append(np.rint(rgb + (255 - rgb) * t))
    shades = np.unique(np.clip(shades, 0, 255).astype(np.uint8), axis=0)
    n_adaptive = 256 - len(shades)
    sample = np.vstack(images[:: max(1, len(images) // 8)])
    adaptive = Image.fromarray(sample).quantize(colors=n_adaptive,
                                                method=Image.Quantize.MEDIANCUT)
    pal = np.array(adaptive.getpalette()[: 3 * n_adaptive], np.uint8).reshape(-1, 3)
    pal = np.vstack([pal, np.zeros((n_adaptive - len(pal), 3), np.uint8), shades])
    palette = Image.new("P", (1, 1))
    palette.putpalette(pal.ravel().tolist())
    return palette


def render_animation(filename, configurations, radius, *, window_size=(640, 480),
                     fps=4, titles=None, camera="iso", contact_points=None,
                     contact_states=None, crossing_points=None, contact_radius=None,
                     color=ROD_COLOR, stripe_color=STRIPE_COLOR,
                     stripe_width=0.35, n_around=32, background="white",
                     hold_last=2, off_screen=None, reference=None, supports=None,
                     axes=True, legend=True):
    """Write an animated GIF of a sequence of rod configurations (a load path).

    Every frame is drawn like :func:`render_rod` (tube with the ``d1``
    stripe, optional contact markers) by one off-screen plotter with **one
    camera for all frames**, fitted to the union of all configurations, so
    the rod moves inside a fixed view.  The frames are assembled into a
    looping GIF with Pillow (already a dependency of pyvista and matplotlib;
    no video codec needed) and written atomically.  The GIF palette holds
    the marker and stripe colours in several shades, so stick green and
    slip orange stay green and orange.

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
        One caption per frame (e.g. the load factor), above the scene.
    camera : str or array_like (3,), default "iso"
        A pyvista view (``"iso"``, ``"xy"``, ...) or a view direction (from
        the scene towards the camera, e.g. ``(0, -0.6, 1)``: from above,
        tilted); the view is then fitted to all frames.
    contact_points : sequence of array_like (m_k, 3), optional
        Contact markers per frame.
    contact_states : sequence of array_like (m_k,), optional
        Integer states per frame (0 open, 1 stick, 2 slip); without them the
        markers take the frictionless contact colour :data:`CONTACT_COLOR`.
    crossing_points : sequence of array_like (k_k, 3), optional
        The crossing pairs' places per frame
        (:meth:`skfem_rod.Result.crossing_points`), drawn in
        :data:`CROSSING_COLOR` as :func:`render_rod` draws them.
    contact_radius : float, optional
        Radius of the contact and crossing markers (default 1.25 times the
        largest tube radius of the frame).
    color, stripe_color, stripe_width, n_around, background
        As in :func:`render_rod`.
    hold_last : int, default 2
        Repeat the last frame this many extra times (a pause before the
        loop restarts).
    off_screen : bool, optional
        Accepted for compatibility (always off screen).
    reference : (points, frames), optional
        Drawn in every frame as a translucent grey ghost.
    supports : list of dict, optional
        As in :func:`render_rod` (fixed points: drawn in every frame).
    axes, legend : bool, default True
        Axes triad; legend of what is drawn.

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
    pv = _pyvista()
    confs = list(configurations)
    if not confs:
        raise ValueError("configurations is empty; give at least one (points, frames) pair")
    width, height = _window_size(window_size)
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps = {fps!r}; expected a number > 0")
    for name, seq in (("titles", titles), ("contact_points", contact_points),
                      ("contact_states", contact_states),
                      ("crossing_points", crossing_points)):
        if seq is not None and len(seq) != len(confs):
            raise ValueError(f"{name} has {len(seq)} entries for {len(confs)} "
                             f"configurations; give one per configuration")
    if contact_states is not None and contact_points is None:
        raise ValueError("contact_states needs contact_points (one array per frame)")
    if not isinstance(camera, str):
        view = np.asarray(camera, dtype=float)
        if view.shape != (3,) or not np.all(np.isfinite(view)) or not view.any():
            raise ValueError(f"camera = {camera!r}; expected a pyvista view name "
                             f"('iso', 'xy', ...) or a non-zero 3-vector")

    tubes, markers, crossings = [], [], []
    rmax = float(np.max(radius))
    if contact_radius is not None and not (np.isfinite(contact_radius) and contact_radius > 0):
        raise ValueError(f"contact_radius = {contact_radius!r}; expected > 0")
    for k, (pts, frs) in enumerate(confs):
        pts, frs = validate_points_frames(pts, frs)
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
        xs = None
        if crossing_points is not None and np.size(crossing_points[k]):
            xs = pv.PolyData(_as_points(f"crossing_points[{k}]", crossing_points[k]))
        if cloud is not None or xs is not None:          # markers in this frame
            ball = pv.Sphere(radius=1.25 * r.max() if contact_radius is None else contact_radius,
                             theta_resolution=16, phi_resolution=16)
            cloud, xs = (None if m is None else m.glyph(geom=ball, scale=False, orient=False)
                         for m in (cloud, xs))
        markers.append(cloud)
        crossings.append(xs)

    statics = []
    if reference is not None:
        ref_pts, ref_frames = validate_points_frames(*reference)
        statics.append(("ghost", tube_mesh(ref_pts, ref_frames,
                                           _radii(rmax, len(ref_pts)), n_around=24)))
    blocks, balls = _support_meshes(pv, supports, 3.5 * rmax)
    statics += [(kind, m) for kind, m in (("block", blocks), ("ball", balls)) if m is not None]

    all_pts = np.vstack([t.points for t in tubes]
                        + [m.points for m in markers + crossings if m is not None]
                        + [m.points for _, m in statics])
    if len(all_pts) > 50000:
        all_pts = all_pts[:: len(all_pts) // 50000 + 1]
    lo, hi = all_pts.min(axis=0), all_pts.max(axis=0)
    bounds = (lo[0], hi[0], lo[1], hi[1], lo[2], hi[2])
    cmap = _color_lut(pv, color, stripe_color, stripe_width)
    sw, sh, top, _ = _layout(width, height, max(titles, key=len) if titles else None, False)

    base_entries = [("line", stripe_color, "material line d\u2081")]
    for kind, _ in statics:
        base_entries.insert(0, {"ghost": ("ghost", REFERENCE_COLOR, "reference shape"),
                                "block": ("box", SUPPORT_COLOR, _block_label(supports)),
                                "ball": ("dot", SUPPORT_COLOR, "pin")}[kind])
    fixed = [background, color, stripe_color, CONTACT_COLOR, *STATE_COLORS] \
        + ([CROSSING_COLOR] if crossing_points is not None else [])

    images = []
    with quiet_vtk():
        pl = pv.Plotter(off_screen=True, window_size=(sw, sh), lighting="three lights")
        try:
            pl.set_background(background)
            try:
                pl.enable_anti_aliasing("ssaa")
            except Exception:  # pragma: no cover - depends on the VTK build
                pass
            if isinstance(camera, str):
                pl.camera_position = camera
            else:
                pl.view_vector(view)
            for kind, m in statics:
                if kind == "ghost":
                    pl.add_mesh(m, color=REFERENCE_COLOR, opacity=0.3, smooth_shading=True,
                                reset_camera=False)
                else:
                    pl.add_mesh(m, color=SUPPORT_COLOR, ambient=0.3, reset_camera=False)
            if axes:
                pl.add_axes(viewport=(0.84, 0.0, 1.0, 0.2), line_width=3)
            pl.reset_camera(bounds=bounds)
            _fit_camera(pl, all_pts, 0.9)
            cam = pl.camera.copy()
            for k, tube in enumerate(tubes):
                pl.add_mesh(tube, scalars="stripe_coord", clim=(0.0, np.pi), cmap=cmap,
                            interpolate_before_map=True, show_scalar_bar=False,
                            name="rod", reset_camera=False, **_tube_actor_kwargs())
                entries = list(base_entries)
                if markers[k] is not None:
                    if "rgb" in markers[k].point_data:
                        kw = {"scalars": "rgb", "rgb": True}
                        entries += _state_entries(contact_states[k])
                    else:
                        kw = {"color": CONTACT_COLOR}
                        entries.append(("dot", CONTACT_COLOR, "contact"))
                    pl.add_mesh(markers[k], smooth_shading=True, show_scalar_bar=False,
                                ambient=0.2, name="contacts", reset_camera=False, **kw)
                else:
                    pl.remove_actor("contacts")
                if crossings[k] is not None:
                    pl.add_mesh(crossings[k], color=CROSSING_COLOR, smooth_shading=True,
                                ambient=0.2, name="crossings", reset_camera=False)
                    entries.append(("dot", CROSSING_COLOR, "crossing pair"))
                else:
                    pl.remove_actor("crossings")
                pl.camera = cam.copy()
                scene = np.asarray(pl.screenshot(None, return_img=True))[..., :3]
                spec = _layout(width, height, titles[k], False)[3] if titles else None
                images.append(_compose(scene, width, height, top, background, spec,
                                       entries if legend else ()))
        finally:
            pl.close()

    if images[0].shape[:2] != (height, width):
        raise RuntimeError(
            f"renderer produced frames of {images[0].shape[1]}x{images[0].shape[0]} "
            f"pixels, not the requested {width}x{height}")
    from PIL import Image

    pics = [Image.fromarray(np.ascontiguousarray(im)) for im in images]
    pics += [pics[-1]] * int(max(hold_last, 0))
    palette = _gif_palette(images, fixed)
    frames_p = [p.quantize(palette=palette, dither=Image.Dither.NONE) for p in pics]
    with atomic_path(filename) as tmp:
        frames_p[0].save(tmp, format="GIF", save_all=True, append_images=frames_p[1:],
                         duration=round(1000 / fps), loop=0, disposal=1)
    return os.fspath(filename)
