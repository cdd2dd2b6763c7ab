"""Every command's optional dependencies (the extras of pyproject.toml), as after a plain
``pip install .``: each command that needs one says so in one line naming the extra to install,
exit 2, before its work starts and with nothing written; the commands that do not need it run.

Absence is simulated in a subprocess by blocking the import (``sys.modules[name] = None`` makes
``import name`` raise ModuleNotFoundError), which is what a missing package does to dofview's code.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CARDS = ROOT / "samples" / "cards.ply"
EXTRAS = {"matplotlib": "bench", "imageio_ffmpeg": "video", "PyOpenColorIO": "ocio", "torch": "train"}
RUN = ("import sys\n"
       "for name in sys.argv[1].split(','):\n"
       "    sys.modules[name] = None\n"
       "from dofview.cli import main\n"
       "sys.exit(main(sys.argv[2:]))\n")


def without(modules: list[str], *argv, cwd: Path) -> subprocess.CompletedProcess:
    """``dofview ARGV`` in a process where ``modules`` cannot be imported."""
    return subprocess.run([sys.executable, "-c", RUN, ",".join(modules), *map(str, argv)], cwd=cwd,
                          capture_output=True, text=True, timeout=600)


def assert_needs(p: subprocess.CompletedProcess, extra: str, *needles: str) -> None:
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and "Traceback" not in p.stderr, p.stderr
    assert lines[0].startswith("dofview: error: ") and f"pip install 'dofview[{extra}]'" in lines[0], lines[0]
    for needle in needles:
        assert needle in lines[0], lines[0]


def test_a_plain_install_renders_and_lists_every_command(tmp_path):
    """None of the extras: render (EXR and PNG) and every command's --help still work."""
    p = without(list(EXTRAS), "render", CARDS, "-o", "out/x.exr", "--png", "out/x.png", "--width", "48", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "out" / "x.exr").is_file() and (tmp_path / "out" / "x.png").is_file()
    for command in ("render", "view", "bench", "train", "make-dataset", "train-eval"):
        p = without(list(EXTRAS), command, "--help", cwd=tmp_path)
        assert p.returncode == 0 and "usage: dofview " + command in p.stdout, (command, p.stderr)


def test_bench_without_matplotlib_says_so_before_measuring(tmp_path):
    """It used to measure for minutes, write its CSVs and report, then end in a traceback at the
    plots, with exit status 0. The study (--views) draws a plot too."""
    for extra_args in ([], ["--views", "1"]):
        p = without(["matplotlib"], "bench", CARDS, "--quick", "--out", "bench", *extra_args, cwd=tmp_path)
        assert_needs(p, "bench", "dofview bench's plots needs matplotlib", "--no-plots")
        assert not (tmp_path / "bench").exists()


def test_bench_without_matplotlib_and_no_plots_writes_the_tables(tmp_path):
    p = without(["matplotlib"], "bench", CARDS, "--quick", "--no-scaling", "--no-plots", "--out", "bench", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    assert sorted(f.name for f in (tmp_path / "bench").iterdir()) == ["error.csv", "report.md", "timing.csv"]


def test_render_video_without_imageio_ffmpeg(tmp_path):
    p = without(["imageio_ffmpeg"], "render", CARDS, "-o", "f_%04d.exr", "--frames", "2", "--focus", "2:8",
                "--width", "32", "--video", "pull.mp4", cwd=tmp_path)
    assert_needs(p, "video", "pull.mp4", "imageio-ffmpeg")
    assert list(tmp_path.iterdir()) == []


def test_render_aces_without_opencolorio_writes_nothing(tmp_path):
    """It used to write the EXR and then fail at the PNG."""
    p = without(["PyOpenColorIO"], "render", CARDS, "-o", "x.exr", "--png", "x.png", "--tonemap", "aces",
                "--width", "32", cwd=tmp_path)
    assert_needs(p, "ocio", "--tonemap aces needs OpenColorIO")
    assert list(tmp_path.iterdir()) == []


def test_train_without_torch(tmp_path):
    p = without(["torch"], "train", tmp_path / "dataset", "-o", "x.ply", cwd=tmp_path)
    assert_needs(p, "train", "dofview train needs torch")


def test_train_plot_without_matplotlib_says_so_before_training(tmp_path):
    """--plot used to be drawn, and fail, after the whole training run."""
    pytest.importorskip("torch")
    p = without(["matplotlib"], "train", tmp_path / "no-dataset", "-o", "x.ply", "--plot", "loss.png", cwd=tmp_path)
    assert_needs(p, "bench", "--plot loss.png needs matplotlib")
