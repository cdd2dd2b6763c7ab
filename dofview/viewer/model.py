"""The viewer's model: everything it shows, without a window. :class:`~dofview.viewer.views.ViewerViews`
holds the scene, its renderer (and a LOD set's streaming) and the views; the model adds focus and
focus pulls, the lens and image settings, the frames drawn while the view moves and rests, tone-
mapping adaptation (:class:`~dofview.viewer.adaptation.ToneAdaptation`), saving and the equivalent
command line. viewer.py puts it in a window; a test drives it headless (tests/test_viewer_model.py).

:meth:`ViewerModel.update` brings the renderer's targets up to date for one frame: it advances a
focus pull, takes in chunks a LOD set streamed for the view, asks the renderer for the current
view's order (the quad backend sorts in the background and draws with the last order meanwhile),
splats again only when the camera, lens or splatting settings changed — while they keep changing,
the preview the interaction budget affords (viewer/interaction.py), once they rest the full frame —
and otherwise adds a pass of the thin lens while the view rests. Exposure, gamma, background and the
focus aid only re-run the tonemap (the view's business).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import moderngl

from dofview.api import save_render
from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.framing import UpGuess
from dofview.io.atomic import check_output_file, make_folder
from dofview.io.lod import DEFAULT_BUDGET, LodSet
from dofview.lens import Lens
from dofview.options import render_command_line
from dofview.rendering.progressive import ProgressiveLens, next_stage
from dofview.scene import GaussianScene
from dofview.tonemap import Tonemap
from dofview.tonemap.stats import Stats
from dofview.viewer.adaptation import ToneAdaptation
from dofview.viewer.focusing import ViewerLens
from dofview.viewer.interaction import LADDERS, Preview
from dofview.viewer.settings import ViewerSettings

COUNT_EVERY_S = 0.5  # how often the drawn-Gaussian counter is read back (it costs a GPU sync)


class ViewerModel(ViewerLens):
    """The viewer's state and its actions (see the module docstring). The window (viewer.py), its
    panel, mouse and keys and the script drive it through these public attributes and methods.
    Arguments as :class:`~dofview.viewer.views.ViewerViews`, and the scene to show first (a level
    of ``lod_set``)."""

    def __init__(self, ctx: moderngl.Context, image_size: Callable[[], tuple[int, int]], scene: GaussianScene,
                 scene_path: Path, settings: ViewerSettings, camera: Camera | None, cameras: list[Camera],
                 up: UpGuess | None = None, raster: str = "auto", lod_set: LodSet | None = None,
                 budget: int | None = None, lod: int | None = None) -> None:
        super().__init__(ctx, image_size, settings, cameras, raster, budget, lod)
        self.tone = ToneAdaptation()
        self.progressive: ProgressiveLens | None = None
        self.splat_draws = 0  # splatting passes shown (exposure, gamma, background, focus aid add none)
        self.preview: Preview | None = None  # how the image shown was drawn (None: not drawn yet)
        self._last_count = -math.inf
        self._shown_count = 0  # Gaussians of the scene last shown (a swap scales the pinhole frame's cost)
        self.set_scene(scene, scene_path, camera, up, lod_set)

    def _scene_shown(self, new: bool) -> None:
        if new:  # a new renderer: its refinement, adaptation and costs start afresh
            if self.progressive is not None:
                self.progressive.release()
            self.progressive = ProgressiveLens(self.renderer)  # the thin lens refined while still
            self.tone.reset()
            self.interaction.forget()
            self._last_count = -math.inf  # count the new scene's first frame
        else:  # another subset of a LOD set: the pinhole frame's cost changes with it
            self.interaction.pinhole_stale(self.scene.count / max(self._shown_count, 1))
        self._shown_count = self.scene.count
        self._drawn_key = None

    def _release_scene(self) -> None:
        self.progressive.release()
        super()._release_scene()

    def command_line(self) -> str:
        camera = self.camera()
        line = render_command_line(str(self.scene_path), camera, self.lens(camera), self.settings.tonemap(),
                                   self.settings.render, self.settings.colour_space)
        if self.lod_set is not None and self.lod is not None:
            line += f" --lod {self.lod}"
        elif self.lod_set is not None and self.budget != DEFAULT_BUDGET:
            line += f" --budget {self.budget}"
        return line

    def save(self, path: str | Path, png: bool) -> None:
        """Write the current view as EXR (and PNG beside it if ``png``), exactly as ``dofview render`` would."""
        out = Path(path).expanduser()
        self.error = ""
        try:
            if out.suffix.lower() != ".exr":
                raise DofviewError(f"{out}: output must be an .exr file")
            outputs = [out, out.with_suffix(".png")] if png else [out]
            for target in outputs:
                check_output_file(target)
            for target in outputs:  # a new folder is made, as dofview render makes it
                make_folder(target)
            camera = self.camera()
            save_render(self.renderer, camera, self.lens(camera), self.settings.tonemap(), self.settings.render,
                        str(self.scene_path), out, outputs[1] if png else None,
                        lens_info=self.settings.lens_request().to_dict(),
                        stats=self.tone.smoother.state if self.settings.tonemap().operator.adaptive else None)
        except DofviewError as e:
            self.error = str(e)
            return
        finally:
            self._drawn_key = None
        self.message = f"saved {out}" + (" and .png" if png else "")

    # ---- one frame -------------------------------------------------------------------------
    def _state_key(self, camera: Camera, lens: Lens) -> tuple:
        return (camera.view_key(), camera.width, camera.height, camera.fx, lens, self.settings.render,
                self.settings.colour_space)

    def update(self, now: float) -> bool:
        """Bring the renderer's targets up to date for this frame: take in chunks streamed for the
        view, splat if anything the splats depend on changed (a preview while it keeps changing, the
        full frame once it rests), else add a pass of the thin lens while the view rests. Returns
        whether the targets hold the same image as the last frame's (so the display may keep what
        it derived from it)."""
        if self.pull.active:
            self.settings.focus = self.pull.value(now)
        self.swap_chunks()
        camera = self.camera()
        lens = self.lens(camera)
        self.scene.colour_space = self.settings.colour_space  # the panel's choice; the renderer reads the scene's
        if self.renderer.request_order(camera):
            self._drawn_key = None  # a background sort finished: draw with its order
        state = self._state_key(camera, lens)
        moving = self.interaction.moving(state, now) or self.pull.active
        ladder = LADDERS[self.settings.render.dof]
        preview = self.interaction.choose(self.settings.render.dof, moving)
        # the targets already hold this frame, drawn as chosen or better
        drawn = (self._drawn_key is not None and self._drawn_key[0] == state
                 and ladder.index(self._drawn_key[1]) <= ladder.index(preview))
        if not drawn:
            self._draw(camera, lens, preview, now)
            self._drawn_key = (state, preview)
            # the single-pass image is kept only where refinement can follow (it copies two float targets)
            self.progressive.restart(keep_single=preview == ladder[0] and lens.aperture > 0
                                     and self.settings.lens_samples_max > 0)
        elif (self.progressive.samples and not self.busy and self.interaction.pinhole_due(now)
              and self._pinhole_view != self._view_of(camera)):
            # resting, the image kept: the budget's pinhole frame of this view timed again, shown back
            self._time_pinhole(camera)
            self._drawn_key = (state, preview)
            self.progressive.show()
            drawn = False
        elif 0 < self.progressive.samples < self.settings.lens_samples_max and not self.busy:
            # still: one more pass of the next stage, the last complete stage staying on screen;
            # the first refinement (2 passes) is drawn whole, so the second still frame shows it
            stage = next_stage(self.progressive.samples, self.settings.lens_samples_max)
            t0 = time.perf_counter()
            while self.progressive.add(camera, lens, self.settings.render, stage) != stage and stage == 2:
                pass
            self.progressive.show()
            self.ctx.finish()
            self._drew("thin-lens refinement", (time.perf_counter() - t0) * 1e3)
            drawn = False  # the targets now hold the refined image
        return drawn

    def _draw(self, camera: Camera, lens: Lens, preview: Preview, now: float) -> None:
        """Splat ``preview`` of the frame, timed (the interaction budget learns its cost)."""
        count = now - self._last_count >= COUNT_EVERY_S
        t0 = time.perf_counter()
        self.renderer.draw(*preview.view(camera, lens, self.settings.render), count=count)
        self.ctx.finish()
        self.splat_draws += 1
        ms = (time.perf_counter() - t0) * 1e3
        self._drew(str(preview), ms)
        self.interaction.record(preview, ms)
        if lens.aperture == 0 and preview.scale == 1:  # a pinhole frame: the budget's own measure
            self.interaction.record_pinhole(ms, now)
        if count:
            self._last_count = now
        self.preview = preview

    def adapt(self, tm: Tonemap, now: float, same_frame: bool = False) -> Stats | None:
        """This frame's tone-mapping statistics (:meth:`ToneAdaptation.adapt`)."""
        return self.tone.adapt(self.renderer, tm, now, self.settings.stats_lock, same_frame)

    def lock_joint_stats(self) -> None:
        """``--stats joint``: statistics pooled over every view of cameras.json, locked (no adaptation)."""
        self.tone.lock_joint(self.renderer, self.cameras, self.settings.operator(), self.settings.render)
        self.settings.stats_lock = True
        self._drawn_key = None  # the pooled renders replaced the targets

    @property
    def previewing(self) -> bool:
        """The image shown is a preview drawn while the view moved; the full frame is still to come."""
        return self.preview is not None and self.preview != LADDERS[self.settings.render.dof][0]

    @property
    def busy(self) -> bool:
        """Work in flight that will change the image: a load, a sort, chunks streaming, a focus
        pull, adaptation or the full frame after a preview."""
        return (self.loading is not None or self.renderer.sort_pending or self.pull.active or self.tone.adapting
                or self.previewing or (self.stream is not None and self.stream.pending))

    @property
    def settled(self) -> bool:
        """The image shows the current state with the order sorted for the current view."""
        return not self.busy and self._drawn_key is not None

    def report(self) -> dict:
        """The state as plain data (the script's ``report`` action writes it as JSON, with the window's)."""
        camera = self.camera()
        lens = self.lens(camera)
        tm = self.settings.tonemap()
        state = self.tone.smoother.state
        return {
            "scene": str(self.scene_path), "count": self.scene.count, "generation": self.generation,
            "camera": {**camera.to_dict(), "name": camera.name},
            "lens": lens.to_dict(),
            "tonemap": {"exposure": tm.exposure, "gamma": tm.gamma, "background": list(tm.background),
                        "operator": tm.operator.name, "params": tm.operator.params(),
                        "stats": json.loads(state.to_json()) if state is not None and tm.operator.adaptive else None,
                        "locked": self.settings.stats_lock},
            "render": self.settings.render.to_dict(),
            "colour_space": self.settings.colour_space, "focus_aid": self.settings.focus_aid,
            "focus_pull_target": self.pull.target, "pivot": self.controls.pivot.tolist(),
            "up": self.up.tolist(), "up_label": self.up_label,
            "depth_span": list(self.depth_span), "view_index": self.view_index, "views": len(self.cameras),
            "drawn": self.renderer.stats.drawn, "total": self.renderer.stats.total,
            "sort_ms": self.renderer.stats.sort_ms, "sort_requests": self.renderer.stats.sort_requests,
            "message": self.message, "error": self.error, "command": self.command_line(),
            "splat_draws": self.splat_draws, "lens_samples": self.progressive.samples,
            "preview": str(self.preview), "budget_ms": self.interaction.budget_ms,
            "lod": None if self.stream is None else {"levels": self.stream.choice.tolist(), "swaps": self.stream.swaps,
                                                     "budget": self.budget, "error": self.stream.error,
                                                     "swap_ms": self.swap_ms, "made_s": self.stream.made_s},
        }

    def with_render(self, **changes) -> None:
        """Change splatting settings (tau, k, opacity_norm, blend_linear, near)."""
        self.settings.render = replace(self.settings.render, **changes)
