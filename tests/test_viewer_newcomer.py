"""What a first-time user of the viewer met (issue 22): Tab, the lens after R/U/N, the panel's layout.

Real windows under Xvfb (the display fixture of test_viewer.py), keys fed through ImGui's input
queue as glfw's callbacks feed them; each session is compared with a fresh open of the same view.
"""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from test_viewer import CARDS_CAMERAS, CARDS_PLY, ROOT, WINDOW, display, run_viewer  # noqa: F401 (fixture)

BIKER = ROOT / "tests" / "data" / "biker.spz"
CARDS = [CARDS_PLY, "--cameras", CARDS_CAMERAS, "--width", WINDOW[0], "--height", WINDOW[1]]


def key(name: str) -> list[dict]:
    """Press and release ``name`` (an ImGui key), then let two frames handle it."""
    return [{"do": "key", "key": name, "down": True}, {"do": "key", "key": name, "down": False},
            {"do": "frames", "n": 2}]


def session(display: str, tmp_path, name: str, args: list, script: list[dict]) -> dict[str, dict]:
    """Run ``script`` (its reports named ``{"report": NAME}``) on ``dofview view ARGS``; the reports by name."""
    out = tmp_path / name
    out.mkdir()
    actions = [{"do": "report", "path": out / f"{a['report']}.json"} if "report" in a else a for a in script]
    path = out / "script.json"
    path.write_text(json.dumps([*actions, {"do": "quit"}], default=str))
    res = run_viewer([*args, "--script", path], {**os.environ, "DISPLAY": display})
    assert res.returncode == 0, res.stderr
    return {p.stem: json.loads(p.read_text()) for p in out.glob("*.json") if p.stem != "script"}


def centre(report: dict) -> np.ndarray:
    c = report["camera"]
    return -np.array(c["R"]).T @ np.array(c["T"])


def assert_same_view_and_lens(got: dict, fresh: dict) -> None:
    """``got`` shows the view a fresh open shows, with the lens it opens with."""
    for k in ("width", "height", "fx"):
        assert got["camera"][k] == pytest.approx(fresh["camera"][k])
    assert np.allclose(got["camera"]["R"], fresh["camera"]["R"], atol=1e-6)
    assert np.allclose(got["camera"]["T"], fresh["camera"]["T"], atol=1e-5)
    assert got["lens"]["focus"] == pytest.approx(fresh["lens"]["focus"], rel=1e-4)
    assert got["lens"]["aperture"] == pytest.approx(fresh["lens"]["aperture"], rel=1e-3)


def largest_blur_px(report: dict) -> float:
    """Blur radius (pixels) at the nearest and farthest depth in view: R = A/2·|1/z − 1/focus|."""
    near, far = report["depth_span"]
    lens = report["lens"]
    return lens["aperture"] / 2 * max(abs(1 / z - 1 / lens["focus"]) for z in (near, far))


@pytest.fixture(scope="module")
def biker(display, tmp_path_factory):
    """biker.spz at the default 1280×800 window: lens and view moved, then R and U; and a fresh
    open with the up U leads to. The messages change on the way (the panel must hold still)."""
    tmp = tmp_path_factory.mktemp("biker")
    moved = [{"do": "set", "focus": 2.0, "aperture": 400.0}, {"do": "orbit", "dx": 150, "dy": 40},
             {"do": "zoom", "steps": 2}]
    script = ([{"do": "still", "samples": 2}, {"report": "start"}, {"do": "set", "dof_enabled": False}, {"report": "no_dof"},
               {"do": "set", "dof_enabled": True}, *moved, {"report": "moved"}]
              + key("r") + [{"report": "reset"}, {"do": "copy_command"}, {"report": "copied"},
                            {"do": "open", "path": tmp / "missing.ply"}, {"report": "error"}]
              + key("u") + [{"report": "up"}])
    runs = session(display, tmp, "keys", [BIKER], script)
    runs["fresh_up"] = session(display, tmp, "fresh", [BIKER, "--up", runs["up"]["up_label"]],
                               [{"do": "frames", "n": 2}, {"report": "start"}])["start"]
    return runs


def test_reset_restores_the_view_and_lens_it_opened_with(biker):
    assert biker["moved"]["lens"] == {"focus": 2.0, "aperture": 400.0}
    assert_same_view_and_lens(biker["reset"], biker["start"])


def test_up_gives_what_a_fresh_open_with_that_up_gives(biker):
    """Issue 22: after U the biker was a ~165 px blur with 6,407 of 152,746 Gaussians drawn."""
    up = biker["up"]
    assert up["up_label"] != biker["start"]["up_label"]
    assert_same_view_and_lens(up, biker["fresh_up"])
    assert largest_blur_px(up) == pytest.approx(0.5, rel=1e-3)  # the first-frame rule, on this view's depths
    assert up["drawn"] > 0.9 * up["total"]


def test_panel_fits_an_800_pixel_window(biker):
    for name in ("start", "up"):
        panel = biker[name]["panel"]
        assert panel["height"] == 800
        assert panel["last"][3] <= panel["height"]  # the last widget's bottom edge is inside the window


def test_messages_do_not_move_the_widgets(biker):
    """A 3-line message, none, a short one, a red error; thin-lens samples or none: every widget stays put."""
    names = ("start", "no_dof", "copied", "error")
    assert len({biker[n]["error"] or biker[n]["message"] for n in ("start", "copied", "error")}) == 3
    assert "missing.ply" in biker["error"]["error"]
    assert biker["no_dof"]["lens_samples"] == 0 < biker["start"]["lens_samples"]
    for widget in ("focus", "copy as command", "last"):
        assert len({tuple(biker[n]["panel"][widget]) for n in names}) == 1, widget


def test_next_view_gives_what_a_fresh_open_of_that_view_gives(display, tmp_path):
    moved = [{"do": "frames", "n": 2}, {"do": "set", "focus": 3.0, "aperture": 50.0}]
    runs = session(display, tmp_path, "next", CARDS, moved + key("n") + [{"report": "next"}])
    fresh = session(display, tmp_path, "fresh", [*CARDS, "--view", "view_001"],
                    [{"do": "frames", "n": 2}, {"report": "start"}])
    assert runs["next"]["camera"]["name"] == fresh["start"]["camera"]["name"] == "view_001"
    assert_same_view_and_lens(runs["next"], fresh["start"])
    assert largest_blur_px(runs["next"]) == pytest.approx(0.5, rel=1e-3)


def test_tab_flies_without_giving_a_text_field_the_keys(display, tmp_path):
    """Issue 22: Tab also focused the panel's first field, so W was typed there and nothing moved
    (it worked only after a click on the image). Here nothing is clicked first."""
    hold_w = [{"do": "key", "key": "w", "down": True}, {"do": "wait", "seconds": 0.3},
              {"do": "key", "key": "w", "down": False}, {"do": "frames", "n": 2}]
    r = session(display, tmp_path, "tab", CARDS, [{"do": "frames", "n": 2}, {"report": "start"}]
                + key("tab") + [{"report": "tab"}] + hold_w + [{"report": "flown"}])
    assert not r["start"]["fly_mode"] and r["tab"]["fly_mode"]
    step = centre(r["flown"]) - centre(r["start"])
    forward = np.array(r["start"]["camera"]["R"])[2]
    assert np.dot(step, forward) > 0.1 and np.linalg.norm(np.cross(step, forward)) < 1e-6
    for name in ("tab", "flown"):
        assert not r[name]["keyboard_captured"] and not r[name]["ui_active"]  # no field is being edited
    assert r["flown"]["lens"] == r["start"]["lens"]


def test_slider_handles_leave_the_digits_readable(biker):
    """A handle narrower than a digit, and the value's text over it at WCAG AA contrast (4.5:1)."""
    from imgui_bundle import imgui

    from dofview.viewer.panel import GRAB_COLOUR

    def luminance(rgb) -> float:
        lin = [c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4 for c in rgb]
        return 0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2]

    imgui.create_context()
    try:
        style = imgui.get_style()
        text, frame = (style.color_(c) for c in (imgui.Col_.text, imgui.Col_.frame_bg))
    finally:
        imgui.destroy_context()
    assert frame.w == 1.0
    a = GRAB_COLOUR.w  # the handle is drawn over the slider's frame, the text over both
    grab = (GRAB_COLOUR.x, GRAB_COLOUR.y, GRAB_COLOUR.z)
    handle = [a * g + (1 - a) * f for g, f in zip(grab, (frame.x, frame.y, frame.z))]
    contrast = (luminance((text.x, text.y, text.z)) + 0.05) / (luminance(handle) + 0.05)
    assert contrast >= 4.5
    panel = biker["start"]["panel"]
    assert panel["grab_px"] < panel["digit_px"]  # as drawn in the window
