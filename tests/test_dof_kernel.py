"""The mass-conserving τ cut on burger.ply (tests/data: a stand-in, made by tests/data/make_scenes.py,
for a trained scene whose repository has no licence, with the original's faint splats): against the
physical thin lens (linear-light accumulation) it beats the anchors' formulation there, as on the
original, the one real scene of five where it does (docs/BENCHMARKS.md, so it is an option, not the
default), and the GL renderer matches the CPU reference on the scene with the default and with the
conserving cut."""

from __future__ import annotations

import argparse
import math
import warnings
from dataclasses import replace

import numpy as np
import pytest
from conftest import assert_matches_reference
from inria_folder import BURGER

from dofview.bench.metrics import psnr
from dofview.bench.study import study_cases, study_views
from dofview.bench.variants import make_references
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.io import load_scene
from dofview.lens import disk_peak_and_area, disk_profile, disk_support, erf
from dofview.rendering import backend_class
from dofview.rendering.quad import QuadBackend
from dofview.rendering.reference import render_reference
from dofview.tonemap import Tonemap, display


@pytest.fixture(scope="module")
def burger():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_scene(BURGER, progress=False)


ANCHOR = RenderSettings(tau=1 / 255, k=1 / 4, opacity_norm="energy", cut="drop", dof="splat")  # the anchors' formulation


def _scores_against_the_thin_lens(scene, variants: dict[str, RenderSettings]) -> dict[str, float]:
    """PSNR (dB, display images) against the physical thin lens (64 lens samples) on one study case,
    120×90, focus at the 50th depth percentile, CoC up to 12 px: each of ``variants`` and
    "best anchor", the best of k = 1/9, 1/4, 1 in the anchors' formulation."""
    r = QuadBackend(scene)
    cam = study_views(scene, 1, 120, 90)[0]
    case = study_cases(r, [cam], focus_pcts=(50.0,), cocs=(12.0,))[0]
    truth = make_references(r, cam, case.lens, RenderSettings(), 64, False, lambda: None).physical

    def score(st: RenderSettings) -> float:
        f = r.render(cam, case.lens, st)
        return psnr(display(f.rgba, f.encoded, Tonemap()), display(truth.rgba, truth.encoded, Tonemap()))

    out = {name: score(st) for name, st in variants.items()}
    out["best anchor"] = max(score(replace(ANCHOR, k=k)) for k in (1 / 9, 1 / 4, 1.0))
    r.release()
    return out


def test_conserving_cut_beats_the_anchor_kernels_on_burger(burger):
    """CoC up to 12 px at 120×90, truth from 64 lens samples. Measured here 1.28 dB above the best of
    k = 1/9, 1/4, 1 with the anchors' α ≥ 1/255 cut (20.68 against 19.40 dB; the original burger:
    1.3 dB here, 1.35 dB in docs/BENCHMARKS.md); asserted with a 0.4 dB margin."""
    scores = _scores_against_the_thin_lens(burger, {"conserve": replace(ANCHOR, cut="conserve")})
    assert scores["conserve"] >= scores["best anchor"] + 0.4


@pytest.mark.parametrize("cut", ["drop", "conserve"])
def test_gl_matches_the_cpu_reference_on_burger(burger, cut):
    """≥ 45 dB (assert_matches_reference). Hundreds of splats overlap each pixel of this small image,
    so 4 % (drop) and 11 % (conserve) of pixels have one within 1e-5 of a cut (the original burger:
    10 % and 15 %): those leave the depth check only."""
    r = QuadBackend(burger, packed=False)
    cam = study_views(burger, 1, 48, 36)[0]
    case = study_cases(r, [cam], focus_pcts=(50.0,), cocs=(6.0,))[0]
    settings = RenderSettings(cut=cut, dof="splat")
    gl = r.render(cam, case.lens, settings)
    r.release()
    assert_matches_reference(gl, render_reference(burger, cam, case.lens, settings, margins=True),
                             max_near_cut=0.25)


def test_disk_kernel_beats_the_anchor_kernels_on_burger(burger):
    """The disk kernel (RenderSettings.kernel "disk") against the physical thin lens, CoC up to 12 px
    at 120×90, truth from 64 lens samples: measured here 20.67 dB against 19.40 dB for the best of
    k = 1/9, 1/4, 1 (+1.27 dB; the original burger: +1.58 dB here, +0.71 dB over the 8 study cases
    in docs/BENCHMARKS.md). Asserted with a 0.5 dB margin. It is not the default: it does not win
    on every real scene (the same section), which the last line holds."""
    scores = _scores_against_the_thin_lens(burger, {"disk": replace(ANCHOR, kernel="disk")})
    assert scores["disk"] >= scores["best anchor"] + 0.75
    assert RenderSettings().kernel == "gaussian"


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_disk_kernel_matches_the_cpu_reference_on_burger(burger, backend):
    """≥ 45 dB on both GPU backends, as the Gaussian kernel above (same image, same margins)."""
    r = backend_class(backend)(burger, packed=False)
    cam = study_views(burger, 1, 48, 36)[0]
    case = study_cases(QuadBackend(burger), [cam], focus_pcts=(50.0,), cocs=(6.0,))[0]
    settings = RenderSettings(kernel="disk", dof="splat")
    gl = r.render(cam, case.lens, settings)
    r.release()
    assert_matches_reference(gl, render_reference(burger, cam, case.lens, settings, margins=True),
                             max_near_cut=0.25)


def test_disk_profile_model():
    """lens.py's disk kernel: erf to 1.5e-7; the closed-form area ratio against a numerical integral;
    the Gaussian as s → 1 and a flat disk of whitened radius 2 as s → 0; the τ-tight support holds
    every α ≥ τ inside it."""
    assert np.abs(erf(np.linspace(-5, 5, 2001)) - np.vectorize(math.erf)(np.linspace(-5, 5, 2001))).max() < 1.5e-7
    r = np.linspace(0.0, 12.0, 120001)
    for s in (0.02, 0.3, 0.9, 0.999):
        s = np.float64(s)
        f0, area = disk_peak_and_area(s)
        prof = disk_profile(r * r, s)
        assert area == pytest.approx(f0 / np.trapezoid(r * prof, r), rel=1e-5)  # erf_as: 1.5e-7 of F(0) ≥ 0.05
        for o, tau in ((0.95, 1 / 255), (0.03, 1 / 255), (0.5, 0.0)):
            inside = r[o * prof / f0 >= tau]
            bound = min(math.sqrt(disk_support(np.float64(o), tau, s)), 2 * math.sqrt(1 - s) + 3 * math.sqrt(s))
            assert math.sqrt(disk_support(np.float64(o), tau, s)) >= min(inside.max(), bound) - 1e-9
    near_gauss = np.float64(1 - 1e-6)
    np.testing.assert_allclose(disk_profile(r * r, near_gauss) / disk_peak_and_area(near_gauss)[0],
                               np.exp(-0.5 * r * r), atol=1e-4)
    flat = disk_profile(r * r, np.float64(1e-8)) / disk_peak_and_area(np.float64(1e-8))[0]
    assert flat[r < 1.99].min() > 0.999 and flat[r > 2.01].max() < 1e-3
    assert disk_peak_and_area(np.float64(1e-8))[1] == pytest.approx(0.5, rel=1e-3)  # π·2² against 2π


def test_disk_kernel_setting_and_option():
    """``--kernel disk`` reaches RenderSettings; the disk kernel refuses the conserving cut."""
    from dofview.options import add_lens_args, add_view_args
    from dofview.request import settings_from_args

    parser = argparse.ArgumentParser()
    add_view_args(parser)
    add_lens_args(parser)
    assert settings_from_args(parser.parse_args(["--kernel", "disk"])).kernel == "disk"
    assert settings_from_args(parser.parse_args([])).kernel == "gaussian"
    with pytest.raises(DofviewError, match="drop cut only"):
        RenderSettings(kernel="disk", cut="conserve")
