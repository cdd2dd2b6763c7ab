"""``dofview bench SCENE``: the command line of the benchmark (see :mod:`dofview.bench.runner`).

Writes timing.csv, error.csv, scaling.csv, report.md and PNG plots into ``--out``.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Callable, Sequence

from dofview.bench.runner import run_bench
from dofview.bench.variants import QUICK, BenchConfig
from dofview.camera import Camera
from dofview.errors import DofviewError, require_extra
from dofview.io.atomic import check_writable
from dofview.frame import OPACITY_NORMS, RenderSettings
from dofview.io.cameras import load_cameras_json, select_camera
from dofview.options import add_scene_args, add_view_args, blur_value, focus_value, number, tau_value
from dofview.request import OpenedScene, camera_from_args, open_scene
from dofview.tonemap import Tonemap


def _auto_cameras(scene_path: Path) -> Path | None:
    """``NAME_cameras.json`` beside ``NAME.ply``, as the bundled samples have, if present."""
    p = scene_path.with_name(scene_path.stem + "_cameras.json")
    return p if p.is_file() else None


def bench_cameras(args: argparse.Namespace, opened: OpenedScene) -> list[Camera]:
    """The bench's cameras: one per ``--view`` entry (comma-separated) of the cameras file."""
    views = [v.strip() for v in str(args.view).split(",") if v.strip()]
    if opened.cameras is None:
        return [camera_from_args(args, opened, default_size=(args.bench_width, args.bench_width * 3 // 4))]
    cams = load_cameras_json(opened.cameras)
    out = []
    for v in views:
        cam = select_camera(cams, v, str(opened.cameras))
        w = args.width or args.bench_width
        h = args.height or max(1, round(cam.height * w / cam.width))
        out.append(cam.resized(w, h))
    return out


# ---- command line ------------------------------------------------------------------------------------
def _list_of(parse: Callable[[str], object], what: str) -> Callable[[str], tuple]:
    def parse_list(text: str) -> tuple:
        items = [t.strip() for t in text.split(",") if t.strip()]
        if not items:
            raise argparse.ArgumentTypeError(f"expected a comma-separated list of {what}, got {text!r}")
        return tuple(parse(t) for t in items)
    return parse_list


def _fraction(text: str) -> float:
    """A value ≥ 0 written as a number or a fraction such as 1/9."""
    num, _, den = text.partition("/")
    value = number(0, None, hi_open=False, what="k")(num)
    return value / number(0, None, lo_open=True, what="denominator")(den) if den else value


_aperture = number(0, None, hi_open=False, what="aperture")


_positive_int = number(1, None, integer=True, what="count")


def _size(text: str) -> tuple[int, int]:
    w, _, h = text.lower().partition("x")
    return _positive_int(w), _positive_int(h)


FOCUS_PCT, COC_PX = (30.0, 70.0), (6.0, 16.0)  # the study's defaults (--focus-pct, --coc-px)
# options only the full bench reads: the study of --views makes its own views, lenses and settings
_BENCH_ONLY = ("focus", "blur", "apertures", "grid_apertures", "taus", "ks", "norms", "acc_samples", "warmup",
               "counts", "count_size", "widths", "no_scaling", "cameras", "eye", "target", "fov", "up")
_BENCH_ONLY_DEFAULTS = {"tau": RenderSettings.tau, "k": RenderSettings.k, "opacity_norm": RenderSettings.opacity_norm,
                        "near": RenderSettings.near, "view": "0"}
_STUDY_ONLY = {"focus_pct": FOCUS_PCT, "coc_px": COC_PX}


def add_parser(sub) -> None:
    """Register ``dofview bench``."""
    p = sub.add_parser("bench", help="frame time against error of depth of field (CSV, Markdown, PNG plots)",
                       description="Frame time against error of single-pass depth of field." + " Writes timing.csv, error.csv, scaling.csv, "
                                   "report.md and PNG plots into --out.")
    add_scene_args(p)
    add_view_args(p)
    p.add_argument("--out", type=Path, help="output folder (default bench_SCENE)")
    p.add_argument("--quick", action="store_true", help="a tiny run of seconds (tests): 96 px wide, 64-sample reference")
    g = p.add_argument_group("what to measure (comma-separated lists)")
    d = BenchConfig()
    g.add_argument("--focus", type=_list_of(focus_value, "focus distances"), help="focus distances or 'auto' (default auto)")
    g.add_argument("--blur", type=_list_of(blur_value, "blur radii"), metavar="R[%][@DEPTH],…",
                   help="the study's apertures by the blur they make on the bench's image: the largest blur over "
                        "every covered depth (2nd–98th percentile depths of the first view's pinhole pass; render's "
                        "--blur measures only where the picture shows detail) has "
                        f"radius R px, or R%% of the width (≤ 25%%); R@DEPTH: at that camera depth (default "
                        f"{','.join(map(str, d.blur))})")
    g.add_argument("--apertures", type=_list_of(_aperture, "apertures"), help="apertures A for the error study, "
                   "px·scene unit, instead of --blur")
    g.add_argument("--grid-apertures", type=_list_of(_aperture, "apertures"), help="apertures of the A×τ table "
                   "(default 0 and the study's)")
    g.add_argument("--taus", type=_list_of(tau_value, "τ values"), help="τ values (default 0,1/255,2/255,3/255)")
    g.add_argument("--ks", type=_list_of(_fraction, "k values"), help="aperture covariance scales k (default 1/9,1/4,1)")
    g.add_argument("--norms", type=_list_of(_norm, "opacity normalisations"), help=f"opacity normalisations (default {','.join(OPACITY_NORMS)})")
    g.add_argument("--ref-samples", type=_positive_int, help=f"lens samples of the reference (default {d.ref_samples})")
    g.add_argument("--acc-samples", type=_list_of(_positive_int, "sample counts"), help=f"accumulation sample counts compared (default {_csv(d.acc_samples)})")
    g.add_argument("--frames", type=_positive_int, help=f"timed frames per setting (default {d.frames})")
    g.add_argument("--warmup", type=_positive_int, default=None, help=f"warm-up rounds (default {d.warmup})")
    g.add_argument("--counts", type=_list_of(_positive_int, "Gaussian counts"), help=f"random-scene sizes for scaling (default {_csv(d.counts)})")
    g.add_argument("--count-size", type=_size, help="image size for the Gaussian-count scaling, WxH (default {}x{})".format(*d.count_size))
    g.add_argument("--widths", type=_list_of(_positive_int, "widths"), help=f"image widths for resolution scaling (default {_csv(d.widths)})")
    g.add_argument("--no-scaling", action="store_true", help="skip the scaling measurements")
    g.add_argument("--no-plots", action="store_true", help="write the CSVs and the Markdown report only (the PNG "
                   "plots need matplotlib: pip install 'dofview[bench]')")
    g.add_argument("--bench-width", type=_positive_int, default=320, help="image width when --width is not given (default 320)")
    g.add_argument("--exposure", type=number(-60, 60, hi_open=False, what="exposure"), default=0.0,
                   help="display exposure in EV stops for PSNR/SSIM (default 0)")
    g.add_argument("--tau", type=tau_value, default=RenderSettings.tau, help="base τ (default: the code's default)")
    g.add_argument("--k", type=_fraction, default=RenderSettings.k, help="base k (default: the code's default)")
    g.add_argument("--opacity-norm", type=_norm, default=RenderSettings.opacity_norm, help="base normalisation (default: the code's)")
    g = p.add_argument_group("real scenes without cameras (dofview.bench.study: against the physical thin lens)")
    g.add_argument("--views", type=_positive_int, help="instead of the full bench: N look-at views around the scene's "
                   "robust bounds, the issue-14 table (anchors, default, accumulation) and a speed-error plot")
    g.add_argument("--focus-pct", type=_list_of(number(0, 100, what="percentile"), "percentiles"), default=FOCUS_PCT,
                   help="with --views: focus at these percentiles of the pinhole depth (default 30,70)")
    g.add_argument("--coc-px", type=_list_of(number(0, None, lo_open=True, what="CoC"), "radii"), default=COC_PX,
                   help="with --views: apertures whose largest CoC in view (5th-95th depth percentile) has these radii in px (default 6,16)")
    p.set_defaults(run=run)


def _check_mode_options(args: argparse.Namespace) -> None:
    """Refuse an option the chosen mode would drop without a word (the full bench, or the study of
    ``--views``)."""
    def given(dest: str, default: object = None) -> bool:
        value = getattr(args, dest)
        return value is not None and value is not False and value != default

    def option(dest: str) -> str:
        return "--" + dest.replace("_", "-")

    if args.views:
        ignored = [option(d) for d in _BENCH_ONLY if given(d)]
        ignored += [option(d) for d, default in _BENCH_ONLY_DEFAULTS.items() if given(d, default)]
        if ignored:
            raise DofviewError(f"{', '.join(ignored)}: not read with --views, whose study makes its own views, lenses "
                               "and settings (it takes --focus-pct, --coc-px, --ref-samples, --frames, --exposure, "
                               "the image size and --raster)")
    else:
        wrong = [option(d) for d, default in _STUDY_ONLY.items() if given(d, default)]
        if wrong:
            raise DofviewError(f"{', '.join(wrong)}: read only by the study of --views N")


def _csv(values) -> str:
    return ",".join(f"{v:g}" for v in values)


def _norm(text: str) -> str:
    if text not in OPACITY_NORMS:
        raise argparse.ArgumentTypeError(f"opacity normalisation must be one of {', '.join(OPACITY_NORMS)}, got {text!r}")
    return text


def config_from_args(args: argparse.Namespace) -> BenchConfig:
    cfg = BenchConfig(**QUICK) if args.quick else BenchConfig()
    if args.blur and args.apertures:
        raise DofviewError("give the study's apertures either as --blur R or as --apertures A, not both")
    given = {"focus": args.focus, "blur": args.blur, "apertures": args.apertures, "grid_apertures": args.grid_apertures,
             "taus": args.taus, "ks": args.ks, "norms": args.norms, "ref_samples": args.ref_samples,
             "acc_samples": args.acc_samples, "frames": args.frames, "warmup": args.warmup, "counts": args.counts,
             "count_size": args.count_size, "widths": args.widths, "raster": args.raster}
    return replace(cfg, **{k: v for k, v in given.items() if v is not None})


def run(args: argparse.Namespace) -> int:
    from dofview.bench.report import write_outputs
    if args.quick and args.width is None and args.height is None:
        args.bench_width = 96
    _check_mode_options(args)
    cfg = config_from_args(args)
    base = RenderSettings(tau=args.tau, k=args.k, opacity_norm=args.opacity_norm, near=args.near)
    tm = Tonemap(exposure=args.exposure)
    out = args.out or Path(f"{'study' if args.views else 'bench'}_{args.scene.stem}")
    if out.exists() and not out.is_dir():
        raise DofviewError(f"{out}: exists and is not a folder")
    check_writable(out / "report.md")  # minutes of measuring must not end in a refusal to write
    if not args.no_plots:
        require_extra("matplotlib", "bench", "dofview bench's plots", "or --no-plots: the CSVs and the report alone")
    opened = open_scene(args, cameras=_auto_cameras(args.scene))
    scene = opened.scene
    command = "dofview bench " + " ".join(_bench_argv(args))
    if args.views:  # real scenes without cameras: the study against the physical thin lens
        from dofview.bench.study import run_cli

        opened.say_notes()
        return run_cli(args, scene, out, command)
    cameras = bench_cameras(args, opened)
    opened.say_notes()
    t0 = time.perf_counter()
    result = run_bench(scene, cameras, cfg, base, tm, scaling=not args.no_scaling)
    out.mkdir(parents=True, exist_ok=True)
    files = write_outputs(out, result, command, time.perf_counter() - t0, plots=not args.no_plots)
    print(f"{out}: " + ", ".join(p.name for p in files), file=sys.stderr)
    return 0


def _bench_argv(args: argparse.Namespace) -> list[str]:
    """The arguments this run was given, for the report (the scene alone when called from Python)."""
    argv = sys.argv[1:]
    if "bench" in argv:
        return argv[argv.index("bench") + 1:]
    return argv if sys.argv[0].endswith("bench.py") else [str(args.scene), "…"]


def main(argv: Sequence[str] | None = None) -> int:
    from dofview.cli import main as cli_main

    return cli_main(["bench", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
