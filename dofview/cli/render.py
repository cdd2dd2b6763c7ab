"""``dofview render``: one view of a scene, headless, to a linear EXR (+ PNG)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from dofview.api import save_render
from dofview.camera import Camera
from dofview.cli.job import RenderJob, job_from_args
from dofview.cli.sequence import add_sequence_args, focus_and_span, run_sequence
from dofview.deep import DEFAULT_CAP, DEFAULT_TOLERANCE
from dofview.lens import Lens
from dofview.options import add_lens_args, add_scene_args, add_view_args, number


def add_parser(sub) -> None:
    p = sub.add_parser("render", help="render a scene headless to a linear HDR EXR (+ PNG)",
                       description="Render a trained 3DGS scene with depth of field to an EXR holding linear "
                                   "R, G, B, A (premultiplied) and Z (camera depth), and optionally a PNG.")
    add_scene_args(p)
    p.add_argument("-o", "--output", type=Path, required=True, help="output EXR path")
    p.add_argument("--png", type=Path, help="also write the tonemapped image as PNG")
    p.add_argument("--half", action="store_true", help="store R, G, B, A as half floats (Z stays float32)")
    add_view_args(p)
    add_lens_args(p, focus_pull=True)
    p.add_argument("--lens-samples", type=number(1, None, integer=True, what="lens samples"), default=0,
                   help="refine the depth of field with N passes, each from its own point of the lens disk "
                        "blurred by that 1/N share of the aperture, averaged (1: the single pass; the image the "
                        "viewer shows once its refinement reached N; the exact thin lens as N grows)")
    add_deep_args(p)
    add_sequence_args(p)
    p.set_defaults(run=run_render)


def add_deep_args(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("deep output (for compositing: docs/COMPOSITING.md)")
    g.add_argument("--deep", type=Path, metavar="OUT.exr",
                   help="also write an OpenEXR deep image: per pixel, the splats front to back as samples with R, G, "
                        "B, A (linear, premultiplied), Z and ZBack (camera depth); flattened, it is the -o image. "
                        "With the sliced depth of field, the blurred layers are the samples; numbered like -o in a sequence")
    g.add_argument("--deep-tolerance", type=number(0, None, lo_open=True, what="--deep-tolerance"),
                   metavar="REL",
                   help=f"merge a pixel's splats into one sample while their depth is within this fraction of the "
                        f"sample's front (default {DEFAULT_TOLERANCE:g})")
    g.add_argument("--deep-cap", type=number(1, None, integer=True, what="--deep-cap"), metavar="N",
                   help=f"most samples per pixel; the last takes all behind it (default {DEFAULT_CAP})")


def run_render(args: argparse.Namespace) -> int:
    """``dofview render``: the arguments as a :class:`RenderJob`, then one image or a sequence."""
    job = job_from_args(args)
    return run_sequence(job) if job.sequence else render_image(job)


def render_image(job: RenderJob) -> int:
    """Render ``job``'s one view to its EXR (+ PNG)."""
    from dofview.rendering import get_backend

    camera, scene_path, out = job.path[0], job.opened.path, job.outputs
    renderer = get_backend(job.raster, job.opened.scene)
    focus, span = focus_and_span(renderer, camera, job.settings, scene_path, job.focus, job.lens.needs_span,
                                 job.tonemap)
    lens = job.lens.lens(camera, focus, span)
    save_render(renderer, camera, lens, job.tonemap, job.settings, str(scene_path), out.exr, out.png, half=out.half,
                lens_info=job.lens.to_dict(), stats=job.stats(renderer), lens_samples=job.lens_samples,
                deep=out.deep, deep_settings=job.deep)
    job.opened.say_notes()
    print(f"{out.exr}: {camera.width}×{camera.height}, focus {lens.focus:.4g}, {aperture_words(camera, lens)}, "
          f"exposure {job.tonemap.exposure:+.4g} EV" + (f"; {out.png}" if out.png else "")
          + (f"; {out.deep}" if out.deep else ""), file=sys.stderr)
    return 0


def aperture_words(camera: Camera, lens: Lens) -> str:
    """The strength as a value to pass back: ``--aperture`` at the camera's reference width (what
    the same command takes at any --width), with A on this image when that is another width."""
    given = f"--aperture {lens.aperture_at(camera.width, camera.ref_width):.7g} (at the {camera.ref_width} px reference width"
    if camera.width == camera.ref_width:
        return given + ")"
    return given + f"; A = {lens.aperture:.4g} on these {camera.width} px)"
