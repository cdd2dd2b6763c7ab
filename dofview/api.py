"""dofview's Python API: load a scene, render it through a lens, save the frame.

One call renders one view, in the spirit of gsplat's ``rasterization()``::

    import dofview
    scene = dofview.load("samples/cards.ply")                 # .ply, .splat, …: dofview.io.READERS
    camera = dofview.load_cameras("samples/cards_cameras.json")[0].resized(320, 240)
    frame = dofview.render(scene, camera, dofview.Lens(focus=4.0, aperture=60.0))
    frame.rgba.shape, frame.depth.shape                        # (240, 320, 4), (240, 320)
    frame.save_exr("cards.exr")                                # linear RGBA + Z
    frame.save_png("cards.png", dofview.Tonemap(exposure=2.0))

Units: positions and depths in scene units; ``Lens.aperture`` A in px·(scene unit), so the blur
radius of a point at camera depth z is R = ½·A·|1/z − 1/focus| pixels; ``Lens.focus`` is a camera
z-depth. A :class:`~dofview.frame.Frame` holds (H, W, 4) float32 linear RGB premultiplied by
coverage A, and (H, W) float32 depth Z (α-weighted camera z, 0 where nothing was drawn).

:func:`render` uploads the scene each call; to render many views of one scene, keep a renderer:
``r = dofview.rendering.get_backend("auto", scene)`` then ``r.render(camera, lens, settings)``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Callable

from dofview import __version__
from dofview.camera import Camera
from dofview.frame import Frame, RenderSettings
from dofview.lens import Lens
from dofview.rendering import Renderer, get_backend
from dofview.scene import ColourSpace, GaussianScene
from dofview.tonemap import Tonemap


def load(path: str | Path, *, colour_space: ColourSpace | None = None,
         progress: bool | Callable[[int, int], None] = False) -> GaussianScene:
    """Read a scene file (any format in :data:`dofview.io.READERS`).

    Args:
        path: the file.
        colour_space: "srgb" (standard 3DGS, fit to display-encoded photos) or "linear" (HDR);
            overrides what the file says.
        progress: a progress bar on stderr (True) or a ``progress(done, total)`` callback.

    Raises:
        DofviewError: a missing, unreadable or malformed file, with the path and what is wrong.
    """
    from dofview.io import load_scene

    scene = load_scene(path, progress=progress)
    if colour_space is not None:
        scene.colour_space = colour_space
    return scene


def load_cameras(path: str | Path) -> list[Camera]:
    """The training views of an Inria ``cameras.json``, in file order."""
    from dofview.io.cameras import load_cameras_json

    return load_cameras_json(path)


def render(scene: GaussianScene, camera: Camera, lens: Lens = Lens(1.0, 0.0), *,
           settings: RenderSettings = RenderSettings(), raster: str = "auto") -> Frame:
    """Render one view of ``scene`` through ``lens`` (default: a pinhole).

    Args:
        scene: N Gaussians (means (N, 3) float32 scene units, …; see :class:`GaussianScene`).
        camera: pinhole camera, OpenCV axes (x right, y down, z forward); its width × height is
            the image size.
        lens: focus (camera z, scene units) and aperture strength A (px·scene unit).
        settings: splatting settings (τ, k, opacity normalisation, near plane).
        raster: a backend of :data:`dofview.rendering.BACKENDS`, or "auto".

    Returns:
        A :class:`Frame`: ``rgba`` (H, W, 4) float32 linear premultiplied, ``depth`` (H, W) float32
        camera z; ``meta`` records the camera, lens and settings for :meth:`Frame.save_exr`.
    """
    renderer = get_backend(raster, scene)
    try:
        frame = renderer.render(camera, lens, settings)
    finally:
        renderer.release()
    frame.meta = exr_header(camera, lens, Tonemap(), settings, scene.colour_space)
    return frame


def exr_header(camera: Camera, lens: Lens, tm: Tonemap, settings: RenderSettings, colour_space: str,
               scene_path: str | None = None, lens_info: dict[str, float | None] | None = None) -> dict[str, object]:
    """dofview's EXR header attributes for one view: version, scene, camera, lens, exposure,
    gamma and splatting settings (JSON strings where structured)."""
    header: dict[str, object] = {"dofview:version": __version__}
    if scene_path is not None:
        header["dofview:scene"] = scene_path
    header.update({
        "dofview:camera": json.dumps({"width": camera.width, "height": camera.height, "fx": camera.fx, "fy": camera.fy,
                                      "cx": camera.cx, "cy": camera.cy, "R": camera.R.tolist(), "T": camera.T.tolist()}),
        "dofview:lens": json.dumps({"focus": lens.focus, "aperture": lens.aperture, **(lens_info or {})}),
        "dofview:exposure": tm.exposure,
        "dofview:gamma": tm.gamma,
        "dofview:render": json.dumps({"tau": settings.tau, "k": settings.k, "opacity_norm": settings.opacity_norm,
                                      "blend_linear": settings.blend_linear, "colour_space": colour_space}),
    })
    return header


def save_render(renderer: Renderer, camera: Camera, lens: Lens, tm: Tonemap, settings: RenderSettings,
                scene_path: str, output: Path, png: Path | None = None, half: bool = False,
                lens_info: dict[str, float | None] | None = None) -> Frame:
    """Render a view and write it as ``dofview render`` does: a linear EXR (exposure applied, Z,
    dofview header) and optionally the PNG tone mapped on the GPU. Shared by the CLI and the
    viewer's Save.

    ``lens_info`` holds the physical-lens values for the header (fnumber, focal_mm, sensor_mm,
    units_per_metre; None where not used).
    """
    from dofview.io.png import write_png

    frame = renderer.render(camera, lens, settings)
    frame.meta = exr_header(camera, lens, tm, settings, renderer.scene.colour_space, scene_path, lens_info)
    frame.save_exr(output, exposure=tm.exposure, half=half)
    if png:
        write_png(png, renderer.display_image(tm))
    return frame
