"""Depth of field that follows the image size (issue 22): ``--aperture A`` holds at the camera's
reference width and scales with --width, ``--blur R`` asks for the blur itself, and a physical lens
follows f_x. The same command rendered at W and 2W, box-filtered to W/2, agrees about as well with
depth of field as without it."""

from __future__ import annotations

import json
import re
import shlex

import numpy as np
import pytest
from conftest import psnr
from inria_folder import BURGER, ring_cameras
from test_bad_input import assert_one_line_error, run_cli

import dofview
from dofview.camera import REFERENCE_WIDTH, Camera
from dofview.cli import main
from dofview.io.cameras import save_cameras_json
from dofview.io.exr import read_exr
from dofview.lens import Lens
from dofview.options import render_command_line
from dofview.rendering import get_backend
from dofview.frame import Frame
from dofview.rendering.focus import blur_span, depth_range

W = 160  # and 2W = 320: small, llvmpipe on two cores


@pytest.fixture(scope="module")
def burger_view():
    """--eye/--target of a view of burger.ply (ring_cameras' first), and the camera itself."""
    cam = ring_cameras(BURGER, n=1, size=(W, W * 3 // 4))[0]
    eye, target = cam.centre, cam.centre + cam.forward
    return ["--eye=" + ",".join(f"{v:.9g}" for v in eye), "--target=" + ",".join(f"{v:.9g}" for v in target),
            "--fov", "50"]


@pytest.fixture(scope="module")
def renderer():
    r = get_backend("quad", dofview.load(BURGER))
    yield r
    r.release()


def render(tmp_path, width, *argv, name="out"):
    """(H, W, 4) float64 RGBA, the lens and the camera header of ``dofview render --width width argv``."""
    out = tmp_path / f"{name}_{width}.exr"
    assert main(["render", str(BURGER), "--width", str(width), "--raster", "quad", "-o", str(out), *argv]) == 0
    channels, header = read_exr(out)
    rgba = np.stack([channels[c] for c in "RGBA"], -1).astype(np.float64)
    return rgba, json.loads(header["dofview:lens"]), json.loads(header["dofview:camera"])


def header_camera(c: dict) -> Camera:
    """The camera a dofview:camera header records."""
    return Camera(c["width"], c["height"], c["fx"], c["fy"], c["cx"], c["cy"], np.array(c["R"]), np.array(c["T"]),
                  ref_width=c["ref_width"])


def box(image, f):
    """(H, W, C) → (H/f, W/f, C): the mean of each f×f block."""
    h, w = image.shape[:2]
    return image.reshape(h // f, f, w // f, f, -1).mean(axis=(1, 3))


def agreement(small, large):
    """PSNR (dB, peak 1) of a W and a 2W render, both box-filtered to W/2."""
    return psnr(box(small, 2), box(large, 4), 1.0)


@pytest.mark.parametrize("lens", [["--aperture", "200"], ["--blur", "2%"], ["--blur", "12@1.8"],
                                  ["--fnumber", "1.4", "--focal-mm", "50", "--units-per-metre", "5"]],
                         ids=["aperture", "blur-percent", "blur-at-depth", "physical"])
def test_same_command_at_twice_the_width_gives_the_same_picture(tmp_path, burger_view, renderer, lens):
    """The view sees burger.ply between depths 1.27 and 1.84; focus 1.5 blurs both sides. (Per-splat
    depth of field, whose stronger change of the picture the thresholds were set on; the strength
    that follows f_x is the same for both modes.)"""
    common = [*burger_view, "--focus", "1.5", "--dof", "splat"]
    pin_small, _, _ = render(tmp_path, W, *common, "--aperture", "0", name="pin")
    pin_large, _, _ = render(tmp_path, 2 * W, *common, "--aperture", "0", name="pin")
    dof_small, lens_small, cam_small = render(tmp_path, W, *common, *lens, name="dof")
    dof_large, lens_large, cam_large = render(tmp_path, 2 * W, *common, *lens, name="dof")
    pinhole, dof = agreement(pin_small, pin_large), agreement(dof_small, dof_large)
    # the old behaviour: the strength used at W used unchanged at 2W
    old_large = renderer.render(header_camera(cam_large), Lens(1.5, lens_small["aperture"]),
                                dofview.RenderSettings(dof="splat")).rgba
    old = agreement(dof_small, old_large.astype(np.float64))
    print(f"{lens}: pinhole pair {pinhole:.2f} dB, depth-of-field pair {dof:.2f} dB, A unscaled {old:.2f} dB; "
          f"depth of field against pinhole at W {psnr(box(dof_small, 2), box(pin_small, 2), 1.0):.2f} dB")
    assert psnr(dof_small, pin_small, 1.0) < 32.0  # the blur is there to be seen
    # A follows f_x (--blur measures the depths in view at the reference width, whatever the size)
    assert lens_large["aperture"] == pytest.approx(2 * lens_small["aperture"], rel=1e-9)
    assert dof >= pinhole - 2.0
    if "--fnumber" not in lens:  # a physical lens followed f_x before; A and --blur did not
        assert old < pinhole - 2.0  # what the test catches: a strength that does not follow the width


@pytest.fixture(scope="module")
def burger_cameras(tmp_path_factory):
    """A cameras.json of two 160×120 views of burger.ply: cameras with a size of their own."""
    path = tmp_path_factory.mktemp("cams") / "cameras.json"
    save_cameras_json(ring_cameras(BURGER, n=2, size=(W, W * 3 // 4)), path)
    return path


def test_a_cameras_json_view_at_its_own_width_gives_todays_image(tmp_path, burger_cameras, renderer):
    """--aperture A on a view at its own width is today's A, bit for bit: published figures hold."""
    rgba, lens, cam = render(tmp_path, W, "--cameras", str(burger_cameras), "--focus", "1.5", "--aperture", "200")
    view = dofview.load_cameras(burger_cameras)[0]
    assert (lens["aperture"], cam["ref_width"]) == (200.0, W) and lens["asked"] == "--aperture 200"
    today = renderer.render(view, Lens(1.5, 200.0), dofview.RenderSettings()).rgba
    np.testing.assert_array_equal(rgba, today.astype(np.float64))
    # at twice its width the strength doubles; an --eye/--target camera holds A at REFERENCE_WIDTH
    _, lens2, cam2 = render(tmp_path, 2 * W, "--cameras", str(burger_cameras), "--focus", "1.5", "--aperture", "200")
    assert (lens2["aperture"], cam2["ref_width"]) == (400.0, W)


@pytest.mark.parametrize("blur,radius_at_w", [("3", 3 * W / REFERENCE_WIDTH), ("2.5%", 0.025 * W)])
def test_blur_gives_the_largest_blur_in_view(tmp_path, burger_view, renderer, blur, radius_at_w):
    """--blur R: the strength resolved makes the largest blur over the 2nd–98th percentile depths
    of the detail a pinhole pass shows (at the reference width) R px there, R·W/800 px on this
    W-wide image."""
    _, lens, cam = render(tmp_path, W, *burger_view, "--blur", blur)
    camera = header_camera(cam)
    probe = camera.resized(REFERENCE_WIDTH, REFERENCE_WIDTH * 3 // 4)
    near, far = blur_span(renderer.render(probe, Lens(1.0, 0.0), dofview.RenderSettings()))
    assert lens["asked"] == f"--blur {blur}" and near < lens["focus"] < far  # auto focus: on the burger
    largest = Lens(lens["focus"], lens["aperture"]).coc_radius(np.array([near, far])).max()
    assert largest == pytest.approx(radius_at_w, rel=1e-6)


def _frame(depth, focus_depth, luma):
    """A pinhole Frame, fully covered, of grey ``luma`` (display-encoded, [0, 1]) at the depths given."""
    rgba = np.concatenate([np.repeat(luma[..., None], 3, -1), np.ones_like(luma)[..., None]], -1)
    return Frame(rgba.astype(np.float32), depth.astype(np.float32), True, focus_depth.astype(np.float32))


def test_blur_span_is_where_the_picture_shows_detail():
    """A subject with detail at depths 1–1.3 (left), a smooth backdrop at 200 covering half of the
    frame (right), and a strip of fine detail whose pixels mix a faint near splat with the backdrop
    (mean depth 150, focus depth 10: no single depth). --blur is measured on the subject; the depths
    in view (the sliders) still reach the backdrop; a frame without detail falls back to them."""
    h, w = 60, 80
    yy, xx = np.mgrid[:h, :w]
    depth = np.where(xx < w // 2, 1.0 + 0.3 * yy / (h - 1), 200.0)
    focus_depth = depth.copy()
    luma = np.where(xx < w // 2, 0.3 + 0.4 * ((xx // 2 + yy // 2) % 2), 0.5 + 0.1 * xx / w)
    strip = (xx >= w // 2) & (yy < 6)
    luma = np.where(strip, 0.5 + 0.3 * ((xx + yy) % 2), luma)
    depth, focus_depth = np.where(strip, 150.0, depth), np.where(strip, 10.0, focus_depth)
    frame = _frame(depth, focus_depth, luma)
    near, far = blur_span(frame)
    assert 1.0 <= near < 1.03 and 1.27 < far <= 1.3
    assert depth_range(frame)[1] == pytest.approx(200.0)
    flat = _frame(depth, depth, np.full((h, w), 0.5))
    assert blur_span(flat) == depth_range(flat)


def test_blur_percent_on_a_scan_with_a_far_shell_blurs_the_subjects_surroundings(tmp_path):
    """tests/data/tap.spz: the scan's smooth far shell (100–240 units) covers 44 % of the frame; the
    tap and its wall are at 1.0–1.4. --blur 2% used to give the shell the 2 % (invisible on it) and
    the tap's wall about a pixel: 47.6 dB from the pinhole at 200 px. Measured on the detail in view,
    the 2 % lands on the wall around the tap."""
    from PIL import Image

    tap = BURGER.with_name("tap.spz")
    images = {}
    for name, blur in (("pinhole", "0"), ("dof", "2%")):
        out = tmp_path / f"{name}.exr"
        assert main(["render", str(tap), "--width", "200", "--blur", blur, "-o", str(out),
                     "--png", str(out.with_suffix(".png"))]) == 0
        images[name] = np.asarray(Image.open(out.with_suffix(".png")), np.float64) / 255.0
        if name == "dof":
            lens = json.loads(read_exr(out)[1]["dofview:lens"])
    assert psnr(images["dof"], images["pinhole"], 1.0) < 36.0
    # 2 % of the width at the wall behind the tap (1.3–1.4 units), not at the shell
    wall = Lens(lens["focus"], lens["aperture"]).coc_radius(np.array([1.3, 1.4]))
    assert 0.6 * 0.02 * 200 < wall.min() and wall.max() < 1.3 * 0.02 * 200


def test_printed_and_recorded_aperture_pass_back_to_the_same_strength(tmp_path, capsys, burger_view):
    """--width 120 --blur 2% prints the --aperture value that gives the same image at that width
    (held at the 800 px reference width; it used to print A on the 120 px image, which --aperture
    then read at 800 px: 0.15× the blur), and the EXR header records it at full precision."""
    first, again, exact = (tmp_path / f"{n}.exr" for n in ("blur", "again", "exact"))
    rc, err = run_cli(capsys, "render", BURGER, "--width", "120", *burger_view, "-o", first, "--blur", "2%")
    assert rc == 0
    printed = re.search(r"--aperture (\S+) \(at the 800 px reference width; A = (\S+) on these 120 px\)", err)
    assert printed, err
    lens = json.loads(read_exr(first)[1]["dofview:lens"])
    assert float(printed[2]) == pytest.approx(lens["aperture"], rel=1e-3)
    assert float(printed[1]) == pytest.approx(lens["aperture_at_ref_width"], rel=1e-6)
    assert lens["aperture_at_ref_width"] == pytest.approx(lens["aperture"] * 800 / 120, rel=1e-12)
    for out, value in ((again, printed[1]), (exact, repr(lens["aperture_at_ref_width"]))):
        assert main(["render", str(BURGER), "--width", "120", *burger_view, "-o", str(out), "--aperture", value]) == 0
    assert json.loads(read_exr(again)[1]["dofview:lens"])["aperture"] == pytest.approx(lens["aperture"], rel=1e-6)
    assert json.loads(read_exr(exact)[1]["dofview:lens"])["aperture"] == lens["aperture"]


def test_blur_at_a_depth(tmp_path, burger_view):
    _, lens, _ = render(tmp_path, W, *burger_view, "--focus", "1.5", "--blur", "8@inf")
    assert Lens(1.5, lens["aperture"]).coc_radius(1e30) == pytest.approx(8 * W / REFERENCE_WIDTH, rel=1e-9)


def test_copied_command_gives_the_same_picture_at_another_width(tmp_path, burger_view, renderer):
    """The viewer's "copy as command" line: at the viewer's width the strength it drew with, at
    twice the width twice that."""
    camera = header_camera(render(tmp_path, 240, *burger_view, "--aperture", "0")[2])
    drawn = Lens(1.5, 37.0)
    line = render_command_line(str(BURGER), camera, drawn, dofview.Tonemap(), dofview.RenderSettings(), "srgb",
                               out=str(tmp_path / "again.exr"))
    argv = shlex.split(line)[1:]
    assert main(argv) == 0
    assert json.loads(read_exr(tmp_path / "again.exr")[1]["dofview:lens"])["aperture"] == pytest.approx(37.0, rel=1e-5)
    argv[argv.index("--width") + 1], argv[argv.index("--height") + 1] = "480", "360"
    assert main(argv) == 0
    assert json.loads(read_exr(tmp_path / "again.exr")[1]["dofview:lens"])["aperture"] == pytest.approx(74.0, rel=1e-5)


@pytest.mark.parametrize("argv,needle", [
    (["--blur", "-1"], "argument --blur: blur radius must be ≥ 0, got -1"),
    (["--blur", "x%"], "argument --blur: blur radius must be a number, got 'x%'"),
    # a value that starts like a negative number is --blur's value, named with what is wrong with it
    (["--blur", "-2%"], "argument --blur: blur radius must be ≥ 0, got -2%"),
    (["--blur", "-3@inf"], "argument --blur: blur radius must be ≥ 0, got -3"),
    # bounded: a quarter of the width (500 % used to exit 0 with a frame faded to black)
    (["--blur", "500%"], "argument --blur: blur radius must be at most 25% of the image width"),
    (["--blur", "25.5%@inf"], "argument --blur: blur radius must be at most 25% of the image width"),
    (["--blur", "200.5"], "--blur 200.5: 200.5 px is more than 25% of the 800 px reference width (at most 200 px"),
    (["--blur", "2@"], "argument --blur: --blur: a blur radius such as 4"),
    (["--blur", "2@0"], "argument --blur: blur depth must be > 0, got 0"),
    (["--blur", "2", "--aperture", "10"], "give the aperture one way: --aperture A, --blur R or --fnumber/--focal-mm"),
    (["--blur", "2@1.5", "--focus", "1.5"], "blur at depth 1.5: that is the focus distance"),
])
def test_bad_blur_values_are_one_line_errors(tmp_path, capsys, burger_view, argv, needle):
    out = tmp_path / "x.exr"
    rc, err = run_cli(capsys, "render", BURGER, "--width", "32", *burger_view, "-o", out, *argv)
    assert_one_line_error(rc, err, needle)
    assert not out.exists()


def test_blur_bound_is_in_the_help_and_holds_at_the_bound(tmp_path, capsys, burger_view):
    with pytest.raises(SystemExit):
        main(["render", "--help"])
    assert "R ≤ 25% of the width" in " ".join(capsys.readouterr().out.split())
    out = tmp_path / "x.exr"
    assert main(["render", str(BURGER), "--width", "32", *burger_view, "-o", str(out), "--blur", "200"]) == 0
    assert main(["render", str(BURGER), "--width", "32", *burger_view, "-o", str(out), "--blur", "25%"]) == 0


def test_strength_follows_the_width_through_resized():
    cam = ring_cameras(BURGER, n=1)[0]  # 160×120, built as cameras.json cameras are
    assert cam.ref_width == cam.width == 160 and cam.scaled_aperture(0.1) == 0.1  # its own width: A as given
    half = cam.resized(80, 60)
    assert half.ref_width == 160 and half.scaled_aperture(200.0) == 100.0
    assert half.resized(320, 240).scaled_aperture(200.0) == 400.0


def test_blur_spec_radius_and_depth():
    from dofview.errors import DofviewError
    from dofview.lens import BlurSpec, aperture_at_depth

    assert BlurSpec(4.0).radius_px(400, 800) == 2.0 and BlurSpec(1.0, percent=True).radius_px(400, 800) == 4.0
    A = aperture_at_depth(3.0, 2.0, 8.0)  # R = ½·A·|1/8 − 1/2| = 3 px
    assert Lens(2.0, A).coc_radius(8.0) == pytest.approx(3.0)
    assert Lens(2.0, aperture_at_depth(3.0, 2.0, float("inf"))).coc_radius(1e300) == pytest.approx(3.0)
    assert str(BlurSpec(2.5, True, float("inf"))) == "2.5%@inf"
    with pytest.raises(DofviewError, match="that is the focus distance"):
        aperture_at_depth(3.0, float("inf"), float("inf"))
    with pytest.raises(DofviewError, match="nothing in view"):
        BlurSpec(2.0).aperture(100, 800, 2.0, None)
