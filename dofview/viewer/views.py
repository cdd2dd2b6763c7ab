"""The viewer's scene and views, without a window: the scene and its renderer (opened, replaced, a
failed load kept out, a streamed LOD set's chunks swapped as the camera moves), the training rig
and the world up, the view controls and the views they jump to. :class:`ViewerModel
<dofview.viewer.model.ViewerModel>` adds the lens, the frames and saving on top.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import moderngl
import numpy as np

from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.framing import (
    UP_AXES,
    UpGuess,
    axis_vector,
    extent,
    guess_up,
    nearest_axis,
    overview_camera,
    rig_centre,
    rig_up,
)
from dofview.io.cameras import load_cameras_json
from dofview.io.lod import DEFAULT_BUDGET, LodSet
from dofview.lens import Lens
from dofview.rendering import Renderer, get_backend
from dofview.scene import GaussianScene
from dofview.viewer.controls import ViewControls
from dofview.viewer.loader import SceneLoad
from dofview.viewer.settings import ViewerSettings
from dofview.viewer.streaming import LodStream, Swap


class ViewerViews:
    """The scene, its renderer and the views of the viewer (see the module docstring).

    Args:
        ctx: the GL context to render with (the window's, or a headless one).
        image_size: gives the (width, height) in pixels of the image the camera renders, now.
        raster: renderer backend name (:data:`dofview.rendering.BACKENDS`, or ``"auto"``).
        budget: the most Gaussians drawn from a streamed LOD set (``--budget``; default
            :data:`~dofview.io.lod.DEFAULT_BUDGET`), whose leaves' levels follow the camera
            (:meth:`swap_chunks`) unless ``lod`` names the one level to draw (``--lod``).
    """

    def __init__(self, ctx: moderngl.Context, image_size: Callable[[], tuple[int, int]], settings: ViewerSettings,
                 cameras: list[Camera], raster: str = "auto", budget: int | None = None, lod: int | None = None) -> None:
        self.ctx = ctx
        self._image_size = image_size
        self.settings = settings
        self.cameras = cameras
        self.raster = raster
        self.budget = budget or DEFAULT_BUDGET
        self.lod = lod
        self.view_index: int | None = None
        self.loading: SceneLoad | None = None
        self.message = ""  # last status line (saved file, copied command)
        self.error = ""  # last error (failed load or save), shown in red until the next action
        self.fly_speed = 1.0  # scene units per second
        self.generation = 0  # scenes shown so far
        # the overview camera (R, U, a scene opened without cameras) frames the scene for this
        # width, height (pixels) and horizontal field of view (degrees); app.py sets the window's
        self.framing = (800, 600, 50.0)
        self.renderer: Renderer | None = None
        self.stream: LodStream | None = None
        self.lod_set: LodSet | None = None
        self.swap_ms = 0.0  # the UI thread's part of the last swap of a LOD set's chunks (the upload)

    # ---- scene -------------------------------------------------------------------------------
    def set_scene(self, scene: GaussianScene, path: Path, camera: Camera | None = None, up: UpGuess | None = None,
                  lod_set: LodSet | None = None) -> None:
        """Show ``scene`` (a level of ``lod_set`` when given): upload it, start at ``camera``
        (default: view 0 of :attr:`cameras`, else a camera framing the scene from the ``up`` given
        or guessed).

        The new scene is uploaded before the old one is released, so a failed upload keeps it.
        """
        renderer = get_backend(self.raster, scene, ctx=self.ctx)
        if self.renderer is not None:
            self._release_scene()
        self.renderer = renderer
        self.scene, self.scene_path = scene, Path(path)
        self.lod_set = lod_set
        if lod_set is not None and self.lod is None:
            level, _ = lod_set.choose_level(budget=self.budget)  # the level read, as read_lod chose it
            self.stream = LodStream(lod_set, self.budget, renderer.packed, renderer.colour_scale,
                                    np.full(lod_set.leaves, level))
        self.generation += 1
        self.settings.colour_space = scene.colour_space
        if self.settings.tonemap_auto:  # --tonemap auto: each scene opens with its colour space's operator
            from dofview.tonemap import default_operator

            self.settings.tonemap_operator, self.settings.tonemap_params = default_operator(scene.colour_space), {}
        self.centre, self.radius = extent(scene)
        self.fly_speed = 0.5 * self.radius
        self.view_index = None
        if self.cameras:
            self._use_rig()
        else:
            guess = up or guess_up(scene)
            self.up_label, self.up = guess.nearest_axis, guess.vector
            self.message = f"up {guess.label} ({guess.reason}); U cycles"
        if camera is None and self.cameras:
            camera, self.view_index = self.cameras[0], 0
        self._set_controls(camera or self._overview())
        self._scene_shown(new=True)
        if self.stream is not None:  # opening: the first view's leaves now, before its first frame
            try:
                swap = self.stream.make(self.camera())
            except DofviewError as e:  # a chunk that cannot be decoded: the level read stays
                swap, self.error = None, str(e)
            if swap is not None:
                self._swap_in(swap)

    def _scene_shown(self, new: bool) -> None:
        """What follows a ``new`` scene, or another subset of the LOD set (False), in the renderer:
        the model's own state."""

    def swap_chunks(self) -> bool:
        """Take a subset of the LOD set the stream finished for the camera (at the start of a frame):
        the renderer swaps it in. Returns whether the scene drawn changed."""
        if self.stream is None:
            return False
        self.stream.request(self.camera())
        swap = self.stream.take()
        if self.stream.error and not self.error:  # a chunk that cannot be decoded: said, the scene stays
            self.error = self.stream.error
        return swap is not None and self._swap_in(swap)

    def _swap_in(self, swap: Swap) -> bool:
        t0 = time.perf_counter()
        try:
            self.renderer.swap_scene(swap.scene, swap.arrays, (swap.camera, swap.order))
        except DofviewError as e:  # more than this backend holds: the chunks drawn stay
            self.stream.close()
            self.stream, self.error = None, f"{self.scene_path}: streaming stopped ({e})"
            return False
        self.swap_ms = (time.perf_counter() - t0) * 1e3
        self.scene = swap.scene
        self._scene_shown(new=False)
        return True

    def _release_scene(self) -> None:
        if self.stream is not None:
            self.stream.close()
            self.stream = None
        self.renderer.release()

    def _use_rig(self) -> None:
        """Orbit around the point nearest to all training views' axes, with their mean up."""
        self.up = rig_up(self.cameras)
        self.up_label = nearest_axis(self.up)
        centre = rig_centre(self.cameras)
        if centre is not None:
            self.centre = centre

    def _set_controls(self, camera: Camera) -> None:
        fwd = camera.forward
        pivot = float(np.dot(self.centre - camera.centre, fwd))
        self.controls = ViewControls.from_camera(camera, pivot if pivot > 0.05 * self.radius else self.radius)
        self.controls.up = self.up.copy()

    def _overview(self) -> Camera:
        w, h, fov = self.framing
        return overview_camera(self.scene, w, h, fov, up=self.up)

    # ---- views -------------------------------------------------------------------------------
    def frame_lens(self) -> None:
        """The lens a view opens with (the model's)."""

    def reset_view(self) -> None:
        """Back to the camera that frames the whole scene, with the lens it opens with."""
        self.view_index = None
        self._set_controls(self._overview())
        self.frame_lens()

    def cycle_up(self) -> None:
        """Take the next world up of :data:`UP_AXES` and frame the scene from it (the U key)."""
        self.up_label = UP_AXES[(UP_AXES.index(self.up_label) + 1) % len(UP_AXES)]
        self.up = axis_vector(self.up_label)
        self.reset_view()
        self.message = f"up {self.up_label} (U cycles)"

    def set_view(self, index: int) -> None:
        """Jump to camera ``index`` of cameras.json (wrapping around), with the lens it opens with."""
        if not self.cameras:
            return
        self.view_index = index % len(self.cameras)
        self._set_controls(self.cameras[self.view_index])
        self.frame_lens()

    def step_view(self, delta: int) -> None:
        """Next (delta 1) or previous (-1) view; from a free camera, the first or the last."""
        if self.view_index is None:
            self.set_view(0 if delta > 0 else -1)
        else:
            self.set_view(self.view_index + delta)

    # ---- opening -----------------------------------------------------------------------------
    def open_file(self, path: str | Path) -> None:
        """Start loading a scene (in the background) or, for a .json file, a set of cameras."""
        path = Path(path).expanduser()
        self.error = ""
        if path.suffix.lower() == ".json" and not path.name.lower().endswith("meta.json"):  # SOG, LOD sets
            try:
                self.cameras = load_cameras_json(path)
            except DofviewError as e:
                self.error = str(e)
                return
            self.message = f"{len(self.cameras)} cameras from {path.name}"
            self._use_rig()
            self.set_view(0)
            return
        self.loading = SceneLoad(path, budget=self.budget)  # --lod was for the scene opened first

    def poll(self) -> None:
        """Take a finished background load (at the start of a frame)."""
        if self.loading is not None and self.loading.done:
            self._finish_load()

    def _finish_load(self) -> None:
        load, self.loading = self.loading, None
        if load.error:
            self.error = load.error  # the current scene stays
            return
        previous, self.cameras = self.cameras, load.cameras  # the old ones belonged to the previous scene
        self.lod = None  # --lod was for the scene opened first: this one streams
        try:
            self.set_scene(load.scene, load.path, lod_set=load.lod_set)
        except (DofviewError, moderngl.Error) as e:  # e.g. too large for this GPU's memory
            self.cameras = previous
            self.error = f"{load.path}: cannot show this scene ({e})"
            return
        self.message = (f"loaded {load.path.name}: {load.scene.count:,} Gaussians in {load.elapsed:.1f} s; "
                        + (load.found or self.message))
        self._loaded()

    def _loaded(self) -> None:
        """What follows a scene opened from the panel (the model's first-frame lens)."""

    # ---- the current image -------------------------------------------------------------------
    @property
    def image_size(self) -> tuple[int, int]:
        """(width, height) in pixels of the image (the window's image area left of the panel)."""
        return self._image_size()

    def camera(self) -> Camera:
        w, h = self.image_size
        name = self.cameras[self.view_index].name if self.view_index is not None else ""
        return self.controls.camera(w, h, name)

    def lens(self, camera: Camera | None = None) -> Lens:
        return self.settings.lens(camera or self.camera())

    def close(self) -> None:
        self._release_scene()
