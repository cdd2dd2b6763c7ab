"""The ImGui layer: the side panel (lens, image, camera, status, files), the help overlay and
the loading bar. Widgets write straight into the viewer model's settings; actions call its methods
(:class:`PanelHost`: the model's public attributes and the window's fields)."""

from __future__ import annotations

import math
import shutil
from dataclasses import replace
from typing import TYPE_CHECKING, Protocol

import numpy as np
from imgui_bundle import imgui

from dofview.frame import BLADES_MAX, DOF_MODES, OPACITY_NORMS
from dofview.io import READERS
from dofview.scene import COLOUR_SPACES
from dofview.viewer.input import HELP
from dofview.viewer.settings import MAX_COC_PX
from dofview.viewer.timing import FrameTimes

if TYPE_CHECKING:
    from dofview.viewer.model import ViewerModel


class _Window(Protocol):
    @property
    def window_size(self) -> tuple[int, int]: ...


class PanelHost(Protocol):
    """What the panel reads and writes: the viewer model's public attributes and methods, and the
    window's fields it edits (viewer.py's Viewer implements it; the panel never imports it)."""

    model: ViewerModel
    window: _Window
    show_help: bool
    fly_mode: bool
    save_path: str
    save_png: bool
    open_path: str
    dialog: object | None
    times: FrameTimes
    panel_layout: dict[str, float | list[float]]

    def save(self) -> None: ...
    def copy_command(self) -> str: ...


PANEL_WIDTH = 330  # window units; the image fills the rest of the window
ERROR_COLOUR = imgui.ImVec4(1.0, 0.4, 0.35, 1.0)
# portable_file_dialogs drives one of these programs on Linux; without one, paths are typed in
DIALOG_PROGRAMS = ("zenity", "kdialog", "matedialog", "qarma")
# the default ImGui font covers Latin-1 only: UI strings stay within it
# no_nav_inputs: Tab is the viewer's fly-mode key, so ImGui's Tab (jump to the next field, where
# W A S D would then be typed) is off
_FIXED = (imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
          | imgui.WindowFlags_.no_nav_inputs)
MESSAGE_LINES = 3  # the status message's fixed area, so a message never moves the widgets below it
# a slider's handle is narrower than a digit and half transparent, so the value stays readable
GRAB_PX = 4.0
GRAB_COLOUR = imgui.ImVec4(0.26, 0.59, 0.98, 0.5)
GRAB_ACTIVE_COLOUR = imgui.ImVec4(0.26, 0.59, 0.98, 0.7)


_CLAMP = imgui.SliderFlags_.always_clamp  # Ctrl+click typing stays in range too (no zero f-number)


def _slider(label: str, value: float, lo: float, hi: float, fmt: str = "%.3f") -> tuple[bool, float]:
    return imgui.slider_float(label, value, lo, hi, fmt, _CLAMP)


def _log_slider(label: str, value: float, lo: float, hi: float, fmt: str = "%.4g") -> tuple[bool, float]:
    return imgui.slider_float(label, value, lo, hi, fmt, _CLAMP | imgui.SliderFlags_.logarithmic)


def _tip(text: str) -> None:
    """A tooltip on the last widget (also when it is disabled): the technical name and option."""
    imgui.set_item_tooltip(text)


def _mark(v: "PanelHost", name: str) -> None:
    """Remember where the last widget was drawn (window units) for the report: the tests check
    that the layout holds still and fits."""
    lo, hi = imgui.get_item_rect_min(), imgui.get_item_rect_max()
    v.panel_layout[name] = [lo.x, lo.y, hi.x, hi.y]


def _note(text: str, colour: imgui.ImVec4 | None = None) -> None:
    """Greyed (or coloured) text wrapped to the panel."""
    imgui.push_text_wrap_pos(0.0)
    if colour is None:
        imgui.text_disabled(text)
    else:
        imgui.text_colored(colour, text)
    imgui.pop_text_wrap_pos()


def _lens(v: "PanelHost") -> None:
    s = v.model.settings
    lo, hi = v.model.focus_range  # from the depths in view
    changed, focus = _log_slider("focus", s.focus, lo, hi)
    _mark(v, "focus")
    _tip("distance in focus, scene units (--focus); Ctrl+click to type")
    entered, typed = imgui.input_float("focus (type)", s.focus, 0.0, 0.0, "%.5g", imgui.InputTextFlags_.enter_returns_true)
    if changed or (entered and math.isfinite(typed) and typed > 0):
        v.model.set_focus(focus if changed else typed, smooth=False)
    _, s.dof_enabled = imgui.checkbox("depth of field", s.dof_enabled)
    imgui.same_line()
    _, s.physical = imgui.checkbox("physical lens", s.physical)
    if s.physical:
        _, s.fnumber = _log_slider("f-number N", s.fnumber, 0.7, 64.0, "f/%.2g")
        _, s.focal_mm = _log_slider("focal length mm", s.focal_mm, 4.0, 800.0, "%.3g mm")
        _, s.sensor_mm = _log_slider("sensor width mm", s.sensor_mm, 2.0, 100.0, "%.3g mm")
        _, s.units_per_metre = _log_slider("units per metre", s.units_per_metre, 1e-3, 1e3)
        imgui.text_disabled(f"aperture strength A = {v.model.lens().aperture:.4g}")
    else:
        top = max(v.model.aperture_for_blur(MAX_COC_PX), s.aperture)  # the largest blur in view reaches 30 px
        _, s.aperture = _log_slider("aperture A", s.aperture, 0.0, top)
        _tip("aperture strength A, px x scene unit (--aperture):\nblur radius R = A/2 * |1/z - 1/focus| px")
    _aperture_shape(v)
    _, s.smooth_focus = imgui.checkbox("smooth focus pull", s.smooth_focus)
    _tip("click-to-focus eases over 0.15 s instead of jumping")
    imgui.same_line()
    _, s.focus_aid = imgui.checkbox("focus aid", s.focus_aid)
    _tip("tint the sharp band: blur radius below one pixel (G)")


DOF_LABELS = {"sliced": "depth layers", "splat": "per splat"}


def _aperture_shape(v: "PanelHost") -> None:
    """How the blur is made (--dof) and, for depth layers, the aperture's blades."""
    s = v.model.settings
    rs = s.render
    labels = [DOF_LABELS[m] for m in DOF_MODES]
    changed_mode, mode = imgui.combo("blur method", DOF_MODES.index(rs.dof), labels)
    _tip("--dof: depth layers blend the scene as a pinhole in slices of equal blur and blur each\n"
         "with the aperture, as a lens does (the default); per splat blurs each splat on its own,\n"
         "the published single pass (its settings: Splatting)")
    imgui.begin_disabled(rs.dof != "sliced")
    changed_blades, blades = imgui.slider_int("aperture blades", rs.blades, 0, BLADES_MAX)
    _tip("--blades: 0 a round aperture, 3 and more a polygon (bokeh shapes);\n"
         "in front of the focus plane a lens shows it turned half a turn")
    changed_rot, rotation = _slider("blade rotation", rs.blade_rotation, 0.0, 360.0, "%.0f deg")
    _tip("--blade-rotation: the polygon's first corner, degrees from image right")
    imgui.end_disabled()
    if changed_mode or changed_blades or changed_rot:
        blades = 0 if blades < 3 else blades  # 1 and 2 blades make no aperture
        s.render = replace(rs, dof=DOF_MODES[mode], blades=blades, blade_rotation=rotation)


def _splatting(v: "PanelHost") -> None:
    """How splats are cut and blurred: the renderer's settings, in user words (names in tooltips)."""
    s = v.model.settings
    rs = s.render
    changed_tau, tau = _slider("min. opacity", rs.tau * 255.0, 0.0, 16.0, "%.2f/255")
    _tip("tau, minimum alpha (--tau): contributions fainter than this are skipped\n"
         "(lower: more exact, higher: faster)")
    imgui.begin_disabled(rs.dof != "splat")  # the per-splat blur's own knobs
    changed_k, k = _slider("blur spread", rs.k, 0.0, 1.0)
    _tip("k, aperture covariance scale (--k): a blurred splat's covariance grows by k * R^2\n"
         "(0.25: as wide as the thin lens's circle of confusion)")
    changed_norm, norm = imgui.combo("blur brightness", OPACITY_NORMS.index(rs.opacity_norm), list(OPACITY_NORMS))
    _tip("opacity normalisation (--opacity-norm): how a splat's opacity falls as the blur spreads it\n"
         "(energy: its light is kept; none: opacity unchanged, blurred splats brighten)")
    imgui.end_disabled()
    changed_lin, lin = imgui.checkbox("blend in linear light", rs.blend_linear)
    _tip("--blend-linear: decode sRGB-encoded colours to linear light before blending")
    imgui.begin_disabled(rs.kernel == "disk" or rs.dof != "splat")  # the disk kernel: the drop cut only
    changed_cut, conserve = imgui.checkbox("keep the light of faint edges", rs.cut == "conserve")
    _tip("--cut conserve: the min. opacity cut keeps each splat's whole light\n"
         "(off: --cut drop, faint edges are dropped)")
    imgui.end_disabled()
    if changed_tau or changed_k or changed_norm or changed_lin or changed_cut:
        s.render = replace(rs, tau=tau / 255.0, k=k, opacity_norm=OPACITY_NORMS[norm], blend_linear=lin,
                           cut="conserve" if conserve else "drop")


def _image(v: "PanelHost") -> None:
    s = v.model.settings
    _, s.ev = _slider("exposure EV", s.ev, -10.0, 10.0, "%+.2f")
    _, s.gamma = _slider("gamma", s.gamma, 0.5, 4.0, "%.2f")
    changed, cs = imgui.combo("colour space", COLOUR_SPACES.index(s.colour_space),
                              ["sRGB-encoded", "linear HDR"])
    if changed:
        s.colour_space = COLOUR_SPACES[cs]
    imgui.begin_disabled(not s.physical)
    _, s.exposure_follows_aperture = imgui.checkbox("aperture changes exposure (t/N²)", s.exposure_follows_aperture)
    _tip("exposure 2^EV * t/N²: stopping down darkens the image as a real lens does"
         + ("" if s.physical else "\n(needs the physical lens)"))
    if s.exposure_follows_aperture:
        _, s.shutter_s = _log_slider("shutter t s", s.shutter_s, 1e-4, 30.0)
    imgui.end_disabled()
    changed, bg = imgui.color_edit3("background", list(s.background))
    if changed:
        s.background = tuple(float(c) for c in bg)
    _tonemap(v)


def _tonemap(v: "PanelHost") -> None:
    """Operator combo box, its parameters as sliders, and the statistics lock."""
    from dataclasses import fields

    from dofview.tonemap import OPERATORS

    s = v.model.settings
    names = list(OPERATORS)
    changed, i = imgui.combo("tone mapping", names.index(s.tonemap_operator), names)
    if changed:
        s.tonemap_operator, s.tonemap_params, s.tonemap_auto = names[i], {}, False
    op = s.operator()
    for f in fields(op):
        lo, hi = op.ranges[f.name]
        value = getattr(op, f.name)
        if f.type == "int":
            moved, new = imgui.slider_int(f.name, int(value), int(lo), int(hi))
        else:
            moved, new = _slider(f.name, float(value), lo, hi, "%.3g")
        if moved:
            s.tonemap_params = {**s.tonemap_params, f.name: new}
    if op.adaptive:
        _, s.stats_lock = imgui.checkbox("lock adaptation", s.stats_lock)
        st = v.model.tone.smoother.state
        if st is not None:
            imgui.text_disabled(f"key 2^{st.key:+.2f}, 1-99%: 2^{st.lo:+.2f}..2^{st.hi:+.2f}")


def _camera(v: "PanelHost") -> None:
    if imgui.button("reset (R)"):
        v.model.reset_view()
    imgui.same_line()
    _, v.fly_mode = imgui.checkbox("fly mode (Tab)", v.fly_mode)
    if v.model.cameras:
        if imgui.button("< prev"):
            v.model.step_view(-1)
        imgui.same_line()
        if imgui.button("next >"):
            v.model.step_view(1)
        imgui.same_line()
        names = [c.name or str(i) for i, c in enumerate(v.model.cameras)]
        idx = v.model.view_index if v.model.view_index is not None else -1
        imgui.set_next_item_width(-1)
        changed, idx = imgui.combo("##view", idx, names)
        if changed:
            v.model.set_view(idx)
    else:
        imgui.text_disabled("no cameras.json (--cameras or drop one)")


def _status(v: "PanelHost") -> None:
    """A fixed number of lines whatever the state, so the widgets below never move."""
    st = v.model.renderer.stats
    ft = np.array(v.times.periods or [0.0], np.float32)
    imgui.text(v.times.status(st.sort_ms))
    _tip("frame: the last frame, start to start (its work, the swap, the wait for input);\n"
         "splat: the splatting pass drawn in it (0: the image was kept);\n"
         "last sort: the quad backend's last depth sort, on its own thread beside the frames\n"
         "(the compute backend sorts on the GPU within the splatting pass)")
    imgui.plot_lines("##frametimes", ft, overlay_text=f"max {ft.max():.0f} ms", scale_min=0.0,
                     graph_size=imgui.ImVec2(-1, 40))
    imgui.text(f"Gaussians drawn {st.drawn:,} of {st.total:,}")
    n = v.model.progressive.samples
    if v.model.previewing:  # the view moves: the preview the interaction budget affords
        imgui.text(f"moving: {v.model.preview} (budget {v.model.interaction.budget_ms:.0f} ms)")
    else:
        imgui.text(f"thin lens: {n} sub-aperture passes" if n > 1 else "thin lens: single pass")
    stream = v.model.stream
    if stream is not None:  # a streamed LOD set: how many leaves each level draws
        levels = np.bincount(stream.choice + 1, minlength=v.model.lod_set.levels + 1)
        drops = f", {levels[0]} left out" if levels[0] else ""
        imgui.text_disabled(f"LOD leaves by level {'/'.join(map(str, levels[1:]))}{drops}; "
                            f"budget {v.model.budget / 1e6:.3g}M")
    cam = v.model.camera()
    imgui.text_disabled(f"{cam.width}×{cam.height} px, fov {cam.fov_x_deg:.1f}°, {v.model.scene_path.name}")


def _files(v: "PanelHost") -> None:
    imgui.set_next_item_width(-70)
    _, v.save_path = imgui.input_text("##save", v.save_path)
    imgui.same_line()
    if imgui.button("save"):
        v.save()
    _, v.save_png = imgui.checkbox("with PNG", v.save_png)
    imgui.same_line()
    if imgui.button("copy as command"):
        v.copy_command()
    _mark(v, "copy as command")
    imgui.set_next_item_width(-70)
    entered, v.open_path = imgui.input_text_with_hint("##open", "scene to open (or drop a file)", v.open_path,
                                                      imgui.InputTextFlags_.enter_returns_true)
    imgui.same_line()
    if (imgui.button("open") or entered) and v.open_path:
        v.model.open_file(v.open_path)
    if any(shutil.which(p) for p in DIALOG_PROGRAMS):  # without one, paths are typed or dropped
        if imgui.button("browse...") and v.dialog is None:
            from imgui_bundle import portable_file_dialogs as pfd

            v.dialog = pfd.open_file("Open a scene", str(v.model.scene_path.parent),
                                     ["Scenes", " ".join("*" + e for e in READERS), "Cameras", "*.json"])
    if v.dialog is not None and v.dialog.ready(0):
        chosen = v.dialog.result()
        v.dialog = None
        if chosen:
            v.model.open_file(chosen[0])


def _messages(v: "PanelHost") -> None:
    """Loading bar, error or message in an area of :data:`MESSAGE_LINES` lines: a longer text is
    cut there (whole in its tooltip), a shorter one leaves the rest empty."""
    size = imgui.ImVec2(0, MESSAGE_LINES * imgui.get_text_line_height_with_spacing())
    imgui.begin_child("##messages", size, 0, imgui.WindowFlags_.no_scrollbar | imgui.WindowFlags_.no_nav_inputs)
    if v.model.loading is not None:
        imgui.text(f"loading {v.model.loading.path.name} ({v.model.loading.elapsed:.1f} s)")
        imgui.progress_bar(v.model.loading.fraction)
    text = v.model.error or v.model.message
    if text:
        _note(text, ERROR_COLOUR if v.model.error else None)
    imgui.end_child()
    if text:
        _tip(text)


def _help(v: "PanelHost") -> None:
    imgui.set_next_window_pos(imgui.ImVec2(12, 12), imgui.Cond_.always)
    imgui.set_next_window_bg_alpha(0.9)
    expanded, still_open = imgui.begin("Help (F1 / H)", True, imgui.WindowFlags_.always_auto_resize | _FIXED)
    if expanded and imgui.begin_table("keys", 2):
        for key, what in HELP:
            imgui.table_next_row()
            imgui.table_next_column()
            imgui.text(key)
            imgui.table_next_column()
            imgui.text_disabled(what)
        imgui.end_table()
    imgui.end()
    v.show_help = bool(still_open)


def draw_ui(v: "PanelHost") -> None:
    """The whole ImGui layer for this frame."""
    w, h = v.window.window_size
    imgui.set_next_window_pos(imgui.ImVec2(w - PANEL_WIDTH, 0), imgui.Cond_.always)
    imgui.set_next_window_size(imgui.ImVec2(PANEL_WIDTH, h), imgui.Cond_.always)
    imgui.begin("dofview", None, _FIXED | imgui.WindowFlags_.no_title_bar)
    imgui.push_style_var(imgui.StyleVar_.grab_min_size, GRAB_PX)
    imgui.push_style_color(imgui.Col_.slider_grab, GRAB_COLOUR)
    imgui.push_style_color(imgui.Col_.slider_grab_active, GRAB_ACTIVE_COLOUR)
    imgui.push_item_width(-120)
    _messages(v)
    if imgui.collapsing_header("Lens", imgui.TreeNodeFlags_.default_open):
        _lens(v)
    if imgui.collapsing_header("Splatting"):  # closed: the panel fits an 800-pixel-high window
        _splatting(v)
    if imgui.collapsing_header("Image", imgui.TreeNodeFlags_.default_open):
        _image(v)
    if imgui.collapsing_header("Camera", imgui.TreeNodeFlags_.default_open):
        _camera(v)
    if imgui.collapsing_header("Status", imgui.TreeNodeFlags_.default_open):
        _status(v)
    if imgui.collapsing_header("Files", imgui.TreeNodeFlags_.default_open):
        _files(v)
    imgui.text_disabled("F1 or H: keys and mouse")
    _mark(v, "last")
    v.panel_layout.update(height=imgui.get_window_height(), grab_px=imgui.get_style().grab_min_size,
                          digit_px=imgui.calc_text_size("0").x)
    imgui.pop_item_width()
    imgui.pop_style_color(2)
    imgui.pop_style_var()
    imgui.end()
    if v.show_help:
        _help(v)
