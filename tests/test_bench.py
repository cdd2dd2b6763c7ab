"""The benchmark: metrics, fragment estimate, and the structure of a --quick run's outputs.

Never wall-clock values: only the files, their columns and rows, and the errors' ordering.
"""

import csv
import math
import struct
from pathlib import Path

import numpy as np
import pytest

from dofview.bench.metrics import log_radiance_error, psnr, ssim
from dofview.cli import main

SAMPLES = Path(__file__).resolve().parent.parent / "samples"


# ---- metrics -------------------------------------------------------------------------------------------
def test_psnr_and_ssim_of_identical_images():
    img = np.random.default_rng(0).uniform(size=(20, 24, 3))
    assert psnr(img, img) == math.inf
    assert ssim(img, img) == pytest.approx(1.0, abs=1e-12)


def test_psnr_of_a_known_error():
    a = np.zeros((8, 8))
    assert psnr(a + 0.1, a) == pytest.approx(20.0)  # MSE 0.01 → 20 dB at peak 1


def test_ssim_falls_with_noise_and_ignores_nothing():
    rng = np.random.default_rng(1)
    img = np.clip(np.cumsum(rng.normal(size=(40, 40)), axis=1) * 0.05 + 0.5, 0, 1)
    scores = [ssim(np.clip(img + rng.normal(scale=s, size=img.shape), 0, 1), img) for s in (0.01, 0.05, 0.2)]
    assert 1.0 > scores[0] > scores[1] > scores[2] > 0.0
    # a uniform brightness shift keeps the structure but not the luminance term
    assert 0.5 < ssim(np.clip(img + 0.1, 0, 1), img) < 1.0
    # symmetric
    b = np.clip(img + rng.normal(scale=0.05, size=img.shape), 0, 1)
    assert ssim(img, b) == pytest.approx(ssim(b, img))


def test_ssim_window_matches_a_direct_sum():
    """The separable 'valid' filter equals the 2D Gaussian-weighted sum at one position."""
    from dofview.bench.metrics import _filter_valid, _gaussian_window

    rng = np.random.default_rng(2)
    img = rng.uniform(size=(15, 13))
    w = _gaussian_window()
    out = _filter_valid(img, w)
    assert out.shape == (5, 3)
    assert out[2, 1] == pytest.approx(float((np.outer(w, w) * img[2:13, 1:12]).sum()))


def test_log_radiance_error_counts_stops():
    a = np.full((4, 4, 3), 10.0)
    assert log_radiance_error(2 * a, a, floor=0.0) == pytest.approx(1.0)
    assert log_radiance_error(a, a) == 0.0


# ---- fragment estimate against the shader's own counter ---------------------------------------------------
def test_quad_fragment_estimate_draws_what_the_shader_draws():
    from dofview.bench.runner import quad_fragments
    from dofview.frame import RenderSettings
    from dofview.io import load_scene
    from dofview.io.cameras import load_cameras_json
    from dofview.lens import Lens
    from dofview.rendering.quad import QuadBackend

    scene = load_scene(SAMPLES / "cards.ply", progress=False)
    cam = load_cameras_json(SAMPLES / "cards_cameras.json")[0].resized(80, 60)
    r = QuadBackend(scene)
    quads = {}
    for a, tau in ((0.0, 0.0), (60.0, 0.0), (60.0, 2 / 255)):
        st = RenderSettings(tau=tau, dof="splat")
        r.draw(cam, Lens(4.0, a), st, count=True)
        drawn, quad, ellipse = quad_fragments(scene, cam, Lens(4.0, a), st)
        assert abs(drawn - r.stats.drawn) <= 0.002 * r.stats.drawn
        assert 0 < ellipse < quad
        quads[(a, tau)] = quad
    # blur grows the quads; τ > 0 tightens them again
    assert quads[(60.0, 0.0)] > quads[(60.0, 2 / 255)] and quads[(60.0, 0.0)] > quads[(0.0, 0.0)]
    r.release()


# ---- a quick run ------------------------------------------------------------------------------------------
def _rows(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", data[16:24])


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("bench") / "cards"
    # the last accumulation count equals the reference's: it must reproduce the reference exactly
    rc = main(["bench", str(SAMPLES / "cards.ply"), "--quick", "--out", str(out), "--focus", "2,auto",
               "--acc-samples", "2,4,16,64"])
    assert rc == 0
    return out


def test_quick_run_writes_every_output(quick_run):
    for name in ("timing.csv", "error.csv", "scaling.csv", "report.md"):
        assert (quick_run / name).stat().st_size > 0
    for name in ("bench_speed_error.png", "bench_ratios.png", "bench_scaling.png"):
        w, h = _png_size(quick_run / name)
        assert w > 100 and h > 100
    report = (quick_run / "report.md").read_text()
    for heading in ("## Frame time, A × τ", "## Targets", "## Error against the thin-lens reference",
                    "### Per-splat mode, k × opacity normalisation", "### Per-splat mode, τ: error added",
                    "### Per-splat mode, blend colour space", "## Scaling"):
        assert heading in report
    targets = [t for t in report.split("## Targets")[1].split("\n## ")[0].strip().splitlines()[1:] if t]
    verdicts = [t for t in targets if t.startswith("- ")]
    assert verdicts and all(any(f"**{v}**" in t for v in ("met", "missed", "undecided")) for t in verdicts)
    for item, following in zip(targets, targets[1:] + [""]):  # every target not met says why, on its next line
        if item.startswith("- ") and "**met**" not in item:
            assert following.startswith("  Why: ") and "To change: " in following, (item, following)
    assert not list(quick_run.glob(".*.part"))  # nothing half-written left behind


def test_timing_table_has_every_setting(quick_run):
    from dofview.bench.variants import QUICK

    rows = _rows(quick_run / "timing.csv")
    for col in ("wall_med_ms", "wall_p90_ms", "gpu_med_ms", "gpu_p90_ms", "sort_ms", "drawn", "quad_fragments"):
        assert col in rows[0]
    grid = {(float(r["aperture"]), float(r["tau_255"])) for r in rows if r["focus"] == rows[0]["focus"]}
    studied = {float(r["aperture"]) for r in _rows(quick_run / "error.csv")}
    assert len(studied) == len(QUICK["blur"])  # chosen from the scene, one per blur radius
    assert {(a, round(t * 255, 3)) for a in {0.0, *studied} for t in QUICK["taus"]} <= grid
    for r in rows:
        assert float(r["wall_p90_ms"]) >= float(r["wall_med_ms"]) > 0
    assert len({r["focus"] for r in rows}) == 2  # both focus distances timed


def test_errors_fall_with_accumulation_samples(quick_run):
    rows = _rows(quick_run / "error.csv")
    for focus in {r["focus"] for r in rows}:
        acc = sorted(((int(r["samples"]), float(r["psnr_physical"]), float(r["ssim_physical"]))
                      for r in rows if r["method"] == "accumulation" and r["focus"] == focus))
        assert [n for n, _, _ in acc] == [2, 4, 16, 64]
        psnrs = [p for _, p, _ in acc]
        assert psnrs[0] < psnrs[1] < psnrs[2]
        assert acc[0][2] < acc[2][2]
        assert psnrs[3] == math.inf  # 64 samples = the reference's own samples
        single = [r for r in rows if r["method"] == "single-pass" and r["focus"] == focus]
        assert single and all(0 < float(r["psnr"]) < math.inf and 0 < float(r["ssim"]) <= 1 for r in single)
        # the time of n samples is n pinhole frames
        t = {n: float(r["time_ms"]) for r in rows if r["method"] == "accumulation" and r["focus"] == focus
             for n in [int(r["samples"])]}
        assert t[4] == pytest.approx(2 * t[2], rel=1e-4)


def test_scaling_rows(quick_run):
    from dofview.bench.variants import QUICK

    rows = _rows(quick_run / "scaling.csv")
    counts = sorted({int(r["gaussians"]) for r in rows if r["kind"] == "gaussians"})
    assert counts == sorted(QUICK["counts"])
    widths = sorted({int(r["width"]) for r in rows if r["kind"] == "resolution"})
    assert widths == sorted(QUICK["widths"])
    big = [float(r["quad_fragments"]) for r in rows if r["kind"] == "resolution" and float(r["aperture"]) == 0]
    assert big[0] < big[-1]  # more pixels, more fragments


def test_hdr_scene_gets_a_log_radiance_error(tmp_path):
    out = tmp_path / "lamp"
    rc = main(["bench", str(SAMPLES / "lamp.ply"), "--quick", "--no-scaling", "--out", str(out),
               "--ks", "0.25", "--norms", "energy", "--taus", "0,2/255", "--acc-samples", "2,8"])
    assert rc == 0
    rows = _rows(out / "error.csv")
    assert all(math.isfinite(float(r["log_radiance_physical"])) for r in rows)
    assert not (out / "scaling.csv").exists()
    assert "log-rad" in (out / "report.md").read_text()


def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys):
    rc = main(["bench", str(tmp_path / "missing.ply"), "--quick", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and err.startswith("dofview: error:") and err.count("\n") == 1
    assert not (tmp_path / "o").exists()
    with pytest.raises(SystemExit) as e:
        main(["bench", str(SAMPLES / "cards.ply"), "--apertures", "ten"])
    assert e.value.code == 2
    capsys.readouterr()
    rc = main(["bench", str(SAMPLES / "cards.ply"), "--quick", "--blur", "4", "--apertures", "10", "--out",
               str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and "--blur" in err and "--apertures" in err and err.count("\n") == 1
    assert not (tmp_path / "o").exists()


# ---- apertures from the scene, progress, targets ------------------------------------------------------------
def _scaled_copy(path: Path, factor: float, out: Path) -> Path:
    """The scene at ``path`` with every length × ``factor`` (means and scales), as a PLY without cameras."""
    from dataclasses import replace

    from dofview.io import load_scene
    from dofview.io.ply import write_ply

    s = load_scene(path, progress=False)
    write_ply(replace(s, means=s.means * factor, scales=s.scales * factor), out)
    return out


def test_default_apertures_give_the_same_blur_in_pixels_whatever_the_units(tmp_path, capsys):
    """A scene 100× larger gets apertures 100× larger (A is px·scene unit) and so the same blur in px;
    fixed default apertures would blur one of them not at all."""
    tiny = ["--quick", "--no-scaling", "--width", "48", "--ref-samples", "8", "--acc-samples", "2", "--frames", "1",
            "--ks", "0.25", "--norms", "energy", "--taus", "0"]
    apertures, reports = {}, {}
    for factor in (1.0, 100.0):
        scene = _scaled_copy(SAMPLES / "cards.ply", factor, tmp_path / f"cards_x{factor:g}.ply")
        out = tmp_path / f"out_x{factor:g}"
        assert main(["bench", str(scene), *tiny, "--out", str(out)]) == 0
        apertures[factor] = sorted({float(r["aperture"]) for r in _rows(out / "error.csv")})
        reports[factor] = (out / "report.md").read_text()
    assert len(apertures[1.0]) == 1 and apertures[1.0][0] > 0
    assert apertures[100.0][0] == pytest.approx(100.0 * apertures[1.0][0], rel=1e-3)
    for text in reports.values():  # --quick's blur: 8 px, whatever the scene's unit
        assert "chosen from the scene" in text and "is 8 px" in text
    err = capsys.readouterr().err
    assert "eta " in err and "reference lens sample" in err  # progress names the step it is on
    # the full run's defaults too: 4, 8, 16 px whatever the unit
    from dofview.bench.variants import BenchConfig

    metres, cm = (BenchConfig().with_apertures(320, 3.0 * f, (2.0 * f, 14.0 * f)) for f in (1.0, 100.0))
    assert len(metres.apertures) == 3 and metres.grid_apertures == (0.0, *metres.apertures)
    assert cm.apertures == pytest.approx([100.0 * a for a in metres.apertures])


def test_progress_shows_an_eta_and_keeps_logging(monkeypatch):
    import io

    from dofview import progress

    now = [0.0]
    monkeypatch.setattr(progress.time, "perf_counter", lambda: now[0])
    out = io.StringIO()  # not a terminal: log lines
    p = progress.Progress("work", 100, stream=out, delay=0.0, heartbeat=20.0)
    now[0] = 10.0
    p.update(25, info="step")
    assert out.getvalue() == "work: 25/100 (25%, 10.0s, eta 30.0s) step\n"
    now[0] = 25.0
    p.update(26)  # same decile, 15 s later: no line yet
    now[0] = 31.0
    p.update(27)  # 21 s since the last line: a heartbeat line
    now[0] = 200.0
    p.update(50)
    lines = out.getvalue().splitlines()
    assert lines[1].startswith("work: 27/100 (27%, 31.0s, eta 1m24s)")
    assert lines[2].startswith("work: 50/100 (50%, 3m20s, eta 3m20s)") and len(lines) == 3


def _targets_result(psnr: float, psnr_physical: float, pinhole_ms: float) -> dict:
    """A bench result of one aperture (30, 6 px): the default single pass at 10 ms with these PSNRs,
    accumulation of 4 and 16 pinhole frames of ``pinhole_ms`` at 25 and 31 dB."""
    from dofview.bench.variants import BenchConfig
    from dofview.frame import RenderSettings

    base = RenderSettings()
    cfg = BenchConfig(apertures=(30.0,), grid_apertures=(0.0, 30.0), taus=(0.0, base.tau))
    cols = {"tau": base.tau, "k": base.k, "opacity_norm": base.opacity_norm, "blend_linear": base.blend_linear,
            "dof": base.dof}
    errs = [{"aperture": 30.0, "method": "single-pass", "samples": 1, **cols, "psnr": psnr,
             "psnr_physical": psnr_physical, "time_ms": 10.0}]
    errs += [{"aperture": 30.0, "method": "accumulation", "samples": n, **cols, "psnr": p, "psnr_physical": p,
              "time_ms": pinhole_ms * n} for n, p in ((4, 25.0), (16, 31.0))]
    return {"config": cfg, "base": base, "error": errs, "blur_px": {0.0: 0.0, 30.0: 6.0}}


def test_target_lines_say_met_or_missed():
    from dofview.bench.report import target_lines

    result = _targets_result(30.0, 24.0, 8.0)
    lines = target_lines(result, np.array([[1.0, 1.0], [2.5, 1.2]]), np.array([[1.0, 1.0], [3.0, 1.5]]), 10.0)
    assert len(lines) == 6
    assert "1.10×" in lines[0] and "**missed**, 1.20×" in lines[0] and "6 px" in lines[0]
    assert lines[1].startswith("  Why: its blurred splats rasterise 1.50× the pinhole's fragments")
    assert "To change: a larger τ cuts more" in lines[1] and "1.20×" in lines[1]
    assert "≤ 3×" in lines[2] and "**met**, 2.50×" in lines[2]
    assert "physical" in lines[3] and "**missed**" in lines[3] and "4 samples" in lines[3]   # 24 dB: 4 samples
    assert lines[4] == ("  Why: 4 lens samples already reach its error. To change: refine towards the lens "
                        "(--lens-samples N, as the viewer does when still), which buys accuracy with time.")
    assert "matched" in lines[5] and "**met**" in lines[5] and "16 samples, 12.8×" in lines[5]  # 30 dB: 16 at 12.8×


def test_a_target_beyond_the_counts_measured_is_undecided_and_says_what_to_measure():
    """Worth more than the 16 samples measured, which take 8× its time: 17 samples would miss the
    10× target and 32 would meet it, so the verdict is neither."""
    from dofview.bench.report import target_lines

    lines = target_lines(_targets_result(40.0, 40.0, 5.0), np.ones((2, 2)), np.ones((2, 2)), 10.0)
    assert "**undecided**" in lines[2] and "more than 16 samples, more than 8.0×" in lines[2]
    assert lines[3] == ("  Why: a default frame costs 2.00 pinhole frames, so the counts measured stop short of "
                        "the target's time. To change: measure more samples (--acc-samples 4,16,32,64).")


def _captured_figure(monkeypatch, plot, *args):
    """The matplotlib figure ``plot`` saves, drawn, and its renderer."""
    import dofview.bench.report as report

    saved = []
    monkeypatch.setattr(report, "_save", lambda fig, path: saved.append(fig))
    plot(Path("unused.png"), *args)
    fig = saved[0]
    fig.canvas.draw()
    return fig, fig.canvas.get_renderer()


def _labels(axis, renderer) -> list:
    lo, hi = sorted(axis.get_view_interval())
    return [t for t, v in zip(axis.get_ticklabels(), axis.get_ticklocs()) if t.get_text() and lo <= v <= hi]


def test_scaling_plot_labels_both_axes_of_both_panels_without_overlap(monkeypatch):
    """The figures of a default bench on cards.ply: the right panel's frame times span less than a
    decade (130–780 ms; its y axis had no label) and its pixel counts got overlapping minor labels."""
    from dofview.bench.report import plot_scaling

    rows = [{"kind": "gaussians", "gaussians": n, "width": 480, "height": 270, "aperture": a, "tau": t,
             "dof": "sliced", "wall_med_ms": ms}
            for n, times in ((10_000, (75, 1350, 1220)), (50_000, (390, 1560, 1040)), (200_000, (840, 1530, 1790)))
            for (a, t), ms in zip(((0.0, 0.0), (100.0, 0.0), (100.0, 1 / 255)), times)]
    rows += [{"kind": "resolution", "gaussians": 19129, "width": w, "height": w * 3 // 4, "aperture": a, "tau": t,
              "dof": "sliced", "wall_med_ms": ms}
             for w, times in ((160, (145, 120)), (320, (135, 280)), (640, (230, 780)))
             for (a, t), ms in zip(((0.0, 0.0), (18.8 * w / 160, 1 / 255)), times)]
    fig, renderer = _captured_figure(monkeypatch, plot_scaling, rows)
    for ax in fig.axes:
        assert len(_labels(ax.yaxis, renderer)) >= 3
        xs = _labels(ax.xaxis, renderer)
        assert len(xs) == 3
        boxes = [t.get_window_extent(renderer) for t in xs]
        assert not any(a.overlaps(b) for i, a in enumerate(boxes) for b in boxes[i + 1:])


def test_speed_error_legend_hides_no_point(monkeypatch):
    """The legend sat inside the last panel, over its points; it is below the panels now."""
    from dofview.bench.report import plot_speed_error
    from dofview.bench.variants import BenchConfig
    from dofview.frame import RenderSettings

    base = RenderSettings()
    cfg = BenchConfig(apertures=(20.0, 40.0), grid_apertures=(0.0, 20.0, 40.0))
    cols = {"opacity_norm": "energy", "blend_linear": False}
    errs = []
    for a in cfg.apertures:
        errs += [{"aperture": a, "method": "accumulation", "samples": n, "tau": 0.0, "k": 0.25, "dof": "splat",
                  **cols, "time_ms": 100.0 * n, "psnr_physical": 20.0 + 3 * n ** 0.5} for n in (2, 4, 8, 16)]
        errs += [{"aperture": a, "method": "single-pass", "samples": 1, "tau": base.tau, "k": k, "dof": "splat",
                  **cols, "time_ms": 150.0 + 50 * k, "psnr_physical": 25.0 + k} for k in cfg.ks]
        errs.append({"aperture": a, "method": "single-pass", "samples": 1, "tau": base.tau, "k": base.k,
                     "dof": base.dof, **cols, "time_ms": 1500.0, "psnr_physical": 20.5})  # bottom right
    fig, renderer = _captured_figure(monkeypatch, plot_speed_error, errs, cfg, base, {20.0: 4.0, 40.0: 8.0})
    assert all(ax.get_legend() is None for ax in fig.axes) and len(fig.legends) == 1
    legend = fig.legends[0].get_window_extent(renderer)
    assert not any(legend.overlaps(ax.get_window_extent(renderer)) for ax in fig.axes)
