"""Core types serialised once: Camera, Lens, LensRequest (BlurSpec), RenderSettings and Tonemap each
have one to_dict/from_dict and one command-line form (to_args), used by the EXR header, the
viewer's copy-as-command, --resume and the bench. Round trips: dict → object → dict, command line
→ objects, and command line → render equal to the render of the objects through the API."""

from __future__ import annotations

import argparse
import json
import math
import shlex
from dataclasses import fields, replace
from pathlib import Path

import numpy as np
import pytest

from dofview.api import exr_header, read_header, save_render
from dofview.camera import REFERENCE_WIDTH, Camera, look_at
from dofview.cli import main
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.io.cameras import load_cameras_json
from dofview.io.exr import read_exr, write_exr
from dofview.io.png import read_png
from dofview.lens import BlurSpec, Lens, LensRequest
from dofview.options import add_lens_args, add_view_args, render_command_line
from dofview.request import lens_request_from_args, settings_from_args, tonemap_from_args
from dofview.sequence import stale_setting
from dofview.tonemap import OPERATORS, Tonemap, default_operator

SAMPLES = Path(__file__).resolve().parent.parent / "samples"
CARDS = SAMPLES / "cards.ply"

# every RenderSettings field away from its default (the disk kernel needs the drop cut: two sets)
SETTINGS = [RenderSettings(tau=2 / 255, k=0.11, opacity_norm="optical-depth", blend_linear=True, near=0.05,
                           cut="conserve", kernel="gaussian"),
            RenderSettings(tau=0.0, k=1.0, opacity_norm="none", near=0.2, cut="drop", kernel="disk")]


def _non_default(cls):
    """An operator of ``cls`` with each parameter moved from its default, within its range."""
    values = {}
    for f in fields(cls):
        lo, hi = cls.ranges.get(f.name, (f.default, f.default + 1.0))
        v = f.default + 0.25 * (hi - lo) if f.default + 0.25 * (hi - lo) <= hi else (lo + f.default) / 2
        values[f.name] = type(f.default)(round(v)) if isinstance(f.default, int) else v
    return cls(**values)


TONEMAPS = [Tonemap(exposure=-1.25, gamma=2.4, background=(0.1, 0.2, 0.3), operator=_non_default(cls))
            for cls in OPERATORS.values()]


def _json(d: dict) -> dict:
    """``d`` through JSON text, as the EXR header stores it."""
    return json.loads(json.dumps(d))


def _camera() -> Camera:
    """An --eye/--target camera on the cards sample, as `dofview render` makes one (reference width 800)."""
    view = load_cameras_json(SAMPLES / "cards_cameras.json")[0]
    cam = look_at(view.centre, view.centre + 4.0 * view.forward, 64, 48, 50.0, -view.R[1])
    return replace(cam, ref_width=REFERENCE_WIDTH)


# ---- dict → object → dict -------------------------------------------------------------------------
@pytest.mark.parametrize("camera", [_camera(), load_cameras_json(SAMPLES / "cards_cameras.json")[2].resized(70, 50)],
                         ids=["look-at", "cameras.json"])
def test_camera_dict_round_trip(camera):
    d = _json(camera.to_dict())
    again = Camera.from_dict(d)
    assert again.to_dict() == d
    assert np.array_equal(again.R, camera.R) and np.array_equal(again.T, camera.T)
    assert (again.width, again.height, again.fx, again.fy, again.cx, again.cy, again.ref_width) == \
        (camera.width, camera.height, camera.fx, camera.fy, camera.cx, camera.cy, camera.ref_width)


def test_camera_from_a_header_without_ref_width_holds_at_its_own_width():
    d = _camera().to_dict()
    del d["ref_width"]
    assert Camera.from_dict(d).ref_width == 64
    del d["fx"]
    with pytest.raises(DofviewError, match="camera record"):
        Camera.from_dict(d)


@pytest.mark.parametrize("lens", [Lens(4.0, 12.5), Lens(math.inf, 80.0), Lens(0.3, 0.0)], ids=["finite", "inf", "pinhole"])
def test_lens_dict_round_trip(lens):
    d = _json(lens.to_dict())
    assert Lens.from_dict(d) == lens and Lens.from_dict(d).to_dict() == d


REQUESTS = [LensRequest(), LensRequest(aperture=60.0), LensRequest(blur=BlurSpec(2.5, percent=True)),
            LensRequest(blur=BlurSpec(6.0, depth=math.inf)), LensRequest(blur=BlurSpec(12.0, depth=1.8)),
            LensRequest(fnumber=1.4, focal_mm=85.0, sensor_mm=24.0, units_per_metre=3.5)]
REQUEST_IDS = ["none", "aperture", "blur-percent", "blur-inf", "blur-depth", "physical"]


@pytest.mark.parametrize("request_", REQUESTS, ids=REQUEST_IDS)
def test_lens_request_dict_round_trip(request_):
    d = _json(request_.to_dict())
    again = LensRequest.from_dict(d)
    assert again.to_dict() == d
    # the header's lens entry holds the Lens and the request side by side; each reads its own part
    both = _json({**Lens(2.0, 9.0).to_dict(), **d})
    assert LensRequest.from_dict(both).to_dict() == d and Lens.from_dict(both) == Lens(2.0, 9.0)


def test_lens_request_refuses_two_ways_and_half_a_physical_lens():
    with pytest.raises(DofviewError, match="give the aperture one way"):
        LensRequest(aperture=1.0, blur=BlurSpec(2.0))
    with pytest.raises(DofviewError, match="needs both --fnumber and --focal-mm"):
        LensRequest(fnumber=2.0)


@pytest.mark.parametrize("spec", [BlurSpec(4.0), BlurSpec(0.5, True), BlurSpec(1 / 3, False, math.inf),
                                  BlurSpec(2.0, True, 1.7)])
def test_blur_spec_text_round_trip(spec):
    assert BlurSpec.parse(spec.to_text()) == spec
    assert str(BlurSpec.parse(str(spec))) == str(spec)  # the header's rounded form reads back to itself


@pytest.mark.parametrize("settings", [RenderSettings(), *SETTINGS], ids=["default", "conserve", "disk"])
def test_render_settings_dict_round_trip(settings):
    d = _json(settings.to_dict())
    assert set(d) == {f.name for f in fields(RenderSettings)}
    assert RenderSettings.from_dict(d) == settings and RenderSettings.from_dict(d).to_dict() == d


def test_render_settings_from_an_older_header_and_a_wrong_one():
    d = SETTINGS[0].to_dict()
    del d["near"]  # headers before near was recorded
    assert RenderSettings.from_dict(d) == replace(SETTINGS[0], near=RenderSettings.near)
    with pytest.raises(DofviewError, match="unknown entry 'colour_space'"):
        RenderSettings.from_dict({**d, "colour_space": "srgb"})


@pytest.mark.parametrize("tm", TONEMAPS, ids=list(OPERATORS))
def test_tonemap_dict_round_trip_for_every_operator(tm):
    assert tm.operator.params() != type(tm.operator)().params() or not tm.operator.params()
    d = _json(tm.to_dict())
    again = Tonemap.from_dict(d)
    assert again == tm and again.to_dict() == d


@pytest.mark.parametrize("colour_space", ["srgb", "linear"])
def test_tonemap_auto_is_the_colour_spaces_default(colour_space):
    tm = Tonemap.from_dict({"tonemap": {"operator": "auto"}}, colour_space)
    assert tm.operator.name == default_operator(colour_space) and tm == Tonemap.from_dict({}, colour_space)
    with pytest.raises(DofviewError, match="no parameter 'nope'"):
        Tonemap.from_dict({"tonemap": {"operator": "reinhard05", "nope": 1.0}})


def test_exr_header_reads_back_as_the_objects():
    camera, lens, tm, settings = _camera(), Lens(math.inf, 33.0), TONEMAPS[1], SETTINGS[0]
    request = REQUESTS[3]
    header = exr_header(camera, lens, tm, settings, "linear", "scene.ply", request.to_dict())
    back = read_header(header)
    assert back["camera"].to_dict() == camera.to_dict() and back["lens"] == lens
    assert back["lens_request"] == request and back["settings"] == settings and back["colour_space"] == "linear"
    assert back["tonemap"] == replace(tm, background=(0.0, 0.0, 0.0))  # the background is the PNG's, not recorded


def test_resume_reads_an_older_header_without_near_as_the_default(tmp_path):
    """--resume compares the objects read back: a frame written before ``near`` was recorded
    agrees with a command at the default near plane, and not with one at another."""
    camera, lens, tm = _camera(), Lens(4.0, 10.0), Tonemap()
    expected = exr_header(camera, lens, tm, RenderSettings(), "srgb", str(tmp_path / "s.ply"), REQUESTS[1].to_dict())
    old = dict(expected)
    render = json.loads(old["dofview:render"])
    del render["near"]
    old["dofview:render"] = json.dumps(render)
    exr = tmp_path / "f.exr"
    write_exr(exr, np.zeros((2, 2, 4), np.float32), np.zeros((2, 2), np.float32), header=old)
    assert stale_setting(exr, expected, 0) is None
    other = exr_header(camera, lens, tm, RenderSettings(near=0.5), "srgb", str(tmp_path / "s.ply"),
                       REQUESTS[1].to_dict())
    assert stale_setting(exr, other, 0) == "render"
    moved = exr_header(replace(camera, cx=camera.cx + 1), lens, tm, RenderSettings(), "srgb",
                       str(tmp_path / "s.ply"), REQUESTS[1].to_dict())
    assert stale_setting(exr, moved, 0) == "camera"


def test_resume_renders_a_frame_with_a_malformed_header_again(tmp_path):
    expected = exr_header(_camera(), Lens(4.0, 10.0), Tonemap(), RenderSettings(), "srgb", str(tmp_path / "s.ply"))
    exr = tmp_path / "f.exr"
    write_exr(exr, np.zeros((2, 2, 4), np.float32), np.zeros((2, 2), np.float32),
              header={**expected, "dofview:render": json.dumps({"tau": "x"})})
    assert stale_setting(exr, expected, 0) == "header"


# ---- command line → objects -----------------------------------------------------------------------
def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_view_args(parser)
    add_lens_args(parser)
    return parser.parse_args(argv)


@pytest.mark.parametrize("settings", SETTINGS, ids=["conserve", "disk"])
def test_render_settings_command_line_gives_them_back(settings):
    assert settings_from_args(_parse(settings.to_args())) == settings


@pytest.mark.parametrize("tm", TONEMAPS, ids=list(OPERATORS))
@pytest.mark.parametrize("colour_space", ["srgb", "linear"])
def test_tonemap_command_line_gives_it_back(tm, colour_space):
    assert tonemap_from_args(_parse(tm.to_args(colour_space)), colour_space) == tm
    plain = Tonemap(operator=OPERATORS[default_operator(colour_space)]())
    assert tonemap_from_args(_parse(plain.to_args(colour_space)), colour_space) == plain


@pytest.mark.parametrize("request_", REQUESTS, ids=REQUEST_IDS)
def test_lens_request_command_line_gives_it_back(request_):
    assert lens_request_from_args(_parse(request_.to_args())) == request_


@pytest.mark.parametrize("width", [64, 333, 1920])
@pytest.mark.parametrize("aperture", [60.0, 1 / 3, 123.456789])
def test_lens_command_line_scales_back_to_the_same_strength(width, aperture):
    """--aperture is given at the reference width; what the command resolves on the image is A,
    to its last bit where a float at the reference width scales to it (not every A has one)."""
    cam = replace(_camera().resized(width, width * 3 // 4), ref_width=REFERENCE_WIDTH)
    args = _parse(Lens(2.0, aperture).to_args(cam.width, REFERENCE_WIDTH))
    got = lens_request_from_args(args).lens(cam, float(args.focus))
    assert got.focus == 2.0 and abs(got.aperture - aperture) <= math.ulp(aperture)
    if aperture == 60.0:
        assert got.aperture == aperture


def test_camera_command_line_gives_the_same_view():
    from dofview.api import load
    from dofview.request import OpenedScene, camera_from_args

    cam = _camera()
    opened = OpenedScene(load(CARDS), CARDS, None)
    again = camera_from_args(_parse([*cam.to_args(4.0), "--focus", "4"]), opened)
    assert (again.width, again.height, again.ref_width) == (cam.width, cam.height, cam.ref_width)
    assert np.allclose(again.R, cam.R, atol=1e-15) and np.allclose(again.T, cam.T, atol=1e-14)
    assert again.fx == pytest.approx(cam.fx, rel=1e-15) and (again.cx, again.cy) == (cam.cx, cam.cy)


# ---- command line → render ------------------------------------------------------------------------
@pytest.mark.parametrize("raster", ["quad", "compute"])
@pytest.mark.parametrize("case", [0, 1], ids=["conserve+reinhard05", "disk+bilateral"])
def test_command_line_renders_what_the_objects_render(tmp_path, raster, case):
    """render_command_line of objects, run as `dofview render`, writes the pixels save_render
    writes for the same objects: EXR channels and PNG exactly equal."""
    from dofview.api import load
    from dofview.rendering import get_backend

    scene = load(CARDS)
    camera, lens = _camera(), Lens(3.5, 7.25)
    tm = (TONEMAPS[1], TONEMAPS[3])[case]
    settings = SETTINGS[case]
    renderer = get_backend(raster, scene)
    try:
        save_render(renderer, camera, lens, tm, settings, str(CARDS), tmp_path / "api.exr", tmp_path / "api.png")
    finally:
        renderer.release()
    line = render_command_line(str(CARDS), camera, lens, tm, settings, scene.colour_space,
                               out=str(tmp_path / "cli.exr"))
    argv = shlex.split(line)
    assert argv[:2] == ["dofview", "render"]
    assert main([*argv[1:], "--png", str(tmp_path / "cli.png"), "--raster", raster]) == 0
    (a, ha), (b, hb) = read_exr(tmp_path / "api.exr"), read_exr(tmp_path / "cli.exr")
    assert set(a) == set(b) == {"R", "G", "B", "A", "Z"}
    for c in a:
        assert np.array_equal(a[c], b[c]), c
    assert a["A"].max() > 0.5  # the view shows the cards
    assert np.array_equal(read_png(tmp_path / "api.png"), read_png(tmp_path / "cli.png"))
    assert read_header(hb)["settings"] == settings and read_header(hb)["lens"] == lens
