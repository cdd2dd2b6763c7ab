"""One unit for "exposure": EV stops in the Python API (Tonemap.exposure), on the command line
(--exposure, --shutter), in the viewer and in the EXR header (dofview:exposure)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dofview.cli import build_parser, main
from dofview.errors import DofviewError
from dofview.io.exr import read_exr
from dofview.request import tonemap_from_args
from dofview.tonemap import Tonemap, display

CARDS = Path(__file__).resolve().parents[1] / "samples" / "cards.ply"


def test_one_ev_doubles_the_light():
    assert Tonemap(exposure=0).multiplier == 1.0
    assert Tonemap(exposure=1).multiplier == 2 * Tonemap(exposure=0).multiplier
    assert Tonemap(exposure=-2).multiplier == 0.25
    rgba = np.random.default_rng(0).uniform(0.0, 0.4, size=(6, 5, 4))
    twice = rgba * np.array([2.0, 2.0, 2.0, 1.0])
    assert np.array_equal(display(rgba, False, Tonemap(exposure=1)), display(twice, False, Tonemap()))
    with pytest.raises(DofviewError, match="EV stops"):
        Tonemap(exposure=float("nan"))


def test_cli_exposure_is_the_api_exposure():
    parse = build_parser().parse_args
    args = parse(["render", str(CARDS), "-o", "x.exr", "--exposure", "1"])
    assert tonemap_from_args(args) == Tonemap(exposure=1.0)
    # --shutter t at f-number N: EV = log2(t/N²); 1/8 s at f/1 is −3 EV
    args = parse(["render", str(CARDS), "-o", "x.exr", "--shutter", "0.125", "--fnumber", "1", "--focal-mm", "50"])
    assert tonemap_from_args(args).exposure == pytest.approx(-3.0)


def test_exr_header_records_the_ev_and_the_pixels_are_exposed_by_it(tmp_path):
    common = ["render", str(CARDS), "--width", "48", "--height", "36", "--focus", "4"]
    channels = {}
    for ev in ("0", "1"):
        assert main([*common, "--exposure", ev, "-o", str(tmp_path / f"ev{ev}.exr")]) == 0
        channels[ev], header = read_exr(tmp_path / f"ev{ev}.exr")
        assert header["dofview:exposure"] == float(ev)
    for c in "RGB":
        assert np.array_equal(channels["1"][c], 2 * channels["0"][c])
    assert np.array_equal(channels["1"]["A"], channels["0"]["A"])
