"""`dofview render` end to end on the bundled samples: EXR channels and header, PNG, lens options."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dofview.bench import synth
from dofview.cli import main
from dofview.io.exr import read_exr
from dofview.io.png import read_png
from dofview.tonemap import Tonemap, display, to_uint8

SAMPLES = Path(__file__).resolve().parent.parent / "samples"
CARDS = [str(SAMPLES / "cards.ply"), "--cameras", str(SAMPLES / "cards_cameras.json")]


def render(tmp_path, *args, name="out"):
    exr, png = tmp_path / f"{name}.exr", tmp_path / f"{name}.png"
    assert main(["render", *args, "-o", str(exr), "--png", str(png)]) == 0
    channels, header = read_exr(exr)
    return channels, header, read_png(png)


def test_exr_holds_linear_rgba_and_depth_and_png_is_its_tonemap(tmp_path):
    ch, header, png = render(tmp_path, *CARDS, "--width", "160", "--height", "120", "--focus", "4",
                             "--aperture", "60", "--exposure", "1.5")
    assert set(ch) == {"R", "G", "B", "A", "Z"}
    assert all(c.shape == (120, 160) and c.dtype == np.float32 for c in ch.values())
    rgba = np.stack([ch[c] for c in "RGBA"], axis=-1)
    assert 0.9 < ch["A"].mean() <= 1.0 and rgba.max() > 1.0  # exposed by +1.5 EV, not clipped
    z = ch["Z"][ch["A"] > 0.99]
    assert z.min() >= 1.9 and z.max() <= synth.WALL_DEPTH * 1.01
    # The PNG is Eq. 7 of the EXR (already exposed): decode → clip → gamma, on a black background.
    expected = to_uint8(display(rgba, encoded=True, tm=Tonemap(exposure=0.0, gamma=2.2)))
    assert np.abs(png.astype(int) - expected.astype(int)).max() <= 1
    cam = json.loads(header["dofview:camera"])
    lens = json.loads(header["dofview:lens"])
    # --aperture holds at the view's own width (800 px): a fifth of it on this 160 px image
    assert (cam["width"], cam["height"]) == (160, 120) and lens["focus"] == 4.0 and lens["aperture"] == 60.0 / 5
    assert header["dofview:exposure"] == 1.5  # EV, the unit of --exposure
    assert header["dofview:version"]


def test_half_output_and_view_by_name(tmp_path):
    exr = tmp_path / "h.exr"
    assert main(["render", *CARDS, "--view", "view_003", "--width", "64", "--half", "--aperture", "0",
                 "-o", str(exr)]) == 0
    ch, header = read_exr(exr)
    assert ch["R"].dtype == np.float16 and ch["Z"].dtype == np.float32
    assert ch["R"].shape == (48, 64)  # height follows the camera's aspect


def test_focus_auto_focuses_on_the_object_under_the_centre(tmp_path):
    # canonical view: the image centre looks at the wall (depth 14) between the cards
    ch, header, _ = render(tmp_path, *CARDS, "--width", "80", "--height", "60", "--aperture", "40")
    assert json.loads(header["dofview:lens"])["focus"] == pytest.approx(synth.WALL_DEPTH, rel=0.02)


def test_physical_lens_equals_its_strength(tmp_path):
    """--fnumber/--focal-mm renders exactly what --aperture A = f_x·(f/N)·d_f/(d_f − f) renders."""
    common = [*CARDS, "--width", "80", "--height", "60", "--focus", "2", "--units-per-metre", "10"]
    a, ha, _ = render(tmp_path, *common, "--fnumber", "1.4", "--focal-mm", "50", name="a")
    A = json.loads(ha["dofview:lens"])["aperture"]
    fx = json.loads(ha["dofview:camera"])["fx"]
    f = 0.05 * 10
    assert A == pytest.approx(fx * (f / 1.4) * 2 / (2 - f))
    b, hb, _ = render(tmp_path, *common, "--aperture", repr(A * 800 / 80), name="b")  # A at the view's own 800 px
    assert json.loads(hb["dofview:lens"])["aperture"] == pytest.approx(A, rel=1e-12)
    np.testing.assert_allclose(a["R"], b["R"], rtol=0, atol=1e-6)


def test_hdr_sample_needs_exposure(tmp_path):
    args = [str(SAMPLES / "lamp.ply"), "--cameras", str(SAMPLES / "lamp_cameras.json"), "--width", "80",
            "--height", "60", "--focus", "4.5", "--aperture", "200",  # A = 20 at 80 of the views' 800 px
            "--tonemap", "clip"]  # Eq. 7 (a linear scene's default is adaptive)
    ch, header, png0 = render(tmp_path, *args, name="ev0")
    _, _, png_dark = render(tmp_path, *args, "--exposure", "-7", name="evm7")
    assert json.loads(header["dofview:render"])["colour_space"] == "linear"
    assert max(ch[c].max() for c in "RGB") > 30  # the lamp's radiance survives in the EXR
    lamp = np.stack([ch[c] for c in "RGB"], -1).max(-1) > 30
    assert png0[lamp].min() == 255 and png_dark[lamp].max() < 255  # clipped at 0 EV, resolved at −7 EV


@pytest.mark.parametrize("argv,needle", [
    (["--aperture", "-1"], "aperture must be ≥ 0"),
    (["--tau", "1"], "tau must be in [0, 1)"),
    (["--view", "nope"], "no camera named 'nope'"),
    (["--fnumber", "2"], "needs both --fnumber and --focal-mm"),
    (["--blades", "6", "--dof", "splat"], "shape the aperture of --dof sliced"),
])
def test_bad_arguments_exit_2_with_one_line(tmp_path, argv, needle):
    out = tmp_path / "x.exr"
    p = subprocess.run([sys.executable, "-m", "dofview", "render", *CARDS, "-o", str(out), *argv],
                       capture_output=True, text=True)
    assert p.returncode == 2
    assert needle in p.stderr and "Traceback" not in p.stderr
    assert not out.exists() and not list(tmp_path.iterdir())
