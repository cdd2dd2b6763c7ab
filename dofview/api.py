"""dofview's Python API: load a scene, render it through a lens, save the frame.

One call renders one view, in the spirit of gsplat's ``rasterization()``::

    import dofview
    scene = dofview.load("samples/cards.ply")                 # .ply, .splat, …: dofview.io.READERS
    camera = dofview.load_cameras("samples/cards_cameras.json")[0].resized(320, 240)
    frame = dofview.render(scene, camera, dofview.Lens(focus=4.0, aperture=60.0))
    frame.rgba.shape, frame.depth.shape                        # (240, 320, 4), (240, 320)
    frame.save_exr("cards.exr")                                # linear RGBA + Z
    dofview.render_deep(scene, camera).save_deep_exr("deep.exr")  # deep samples (a pinhole)
    frame.save_png("cards.png", dofview.Tonemap(exposure=1.0))  # +1 EV

Units: positions and depths in scene units; ``Lens.aperture`` A in px·(scene unit), so the blur
radius of a point at camera depth z is R = ½·A·|1/z − 1/focus| pixels; ``Lens.focus`` is a camera
z-depth. Exposure, here (``Tonemap.exposure``) as on the command line (``--exposure``), in the viewer
and in the EXR header (``dofview:exposure``), is in EV stops: the light is scaled by 2^EV
(``Tonemap.multiplier``). A :class:`~dofview.frame.Frame` holds (H, W, 4) float32 linear RGB premultiplied by
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
from dofview.deep import DeepFrame, DeepSettings
from dofview.errors import DofviewError
from dofview.frame import Frame, RenderSettings
from dofview.lens import Lens, LensRequest
from dofview.rendering import Renderer, get_backend
from dofview.rendering.progressive import render_lens_samples
from dofview.scene import ColourSpace, GaussianScene
from dofview.tonemap import Tonemap
from dofview.tonemap.stats import Stats, StatsSmoother, frame_stats, pooled_stats


def load(path: str | Path, *, colour_space: ColourSpace | None = None,
         progress: bool | Callable[[int, int], None] = False, spz_axes: str | None = None,
         lod: int | None = None, budget: int | None = None) -> GaussianScene:
    """Read a scene file (any format in :data:`dofview.io.READERS`).

    Args:
        path: the file.
        colour_space: "srgb" (standard 3DGS, fit to display-encoded photos) or "linear" (HDR);
            overrides what the file says.
        progress: a progress bar on stderr (True) or a ``progress(done, total)`` callback.
        spz_axes: for ``.spz`` files, the axes the data is in: None follows the file (the spec's
            RUB, converted to dofview's RDF), "rdf" takes it as stored (splat-transform's files).
        lod, budget: for a streamed LOD set (``lod-meta.json`` or its folder), the level to read (0
            the finest), else the finest whose Gaussians are within ``budget`` (default
            :data:`dofview.io.lod.DEFAULT_BUDGET`).

    Raises:
        DofviewError: a missing, unreadable or malformed file, with the path and what is wrong.
    """
    from dofview.io import load_scene

    scene = load_scene(path, progress=progress, spz_axes=spz_axes, lod=lod, budget=budget)
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


def render_deep(scene: GaussianScene, camera: Camera, lens: Lens = Lens(1.0, 0.0), *,
                settings: RenderSettings = RenderSettings(), deep: DeepSettings = DeepSettings(),
                raster: str = "auto") -> DeepFrame:
    """The deep image of the view :func:`render` renders with the same arguments: each pixel's
    splats front to back as samples (see :mod:`dofview.deep`); ``image.flatten()`` is
    :func:`render`'s RGBA and ``image.save_deep_exr(path)`` writes it. With the sliced depth of
    field (the default) and an aperture, the samples are the blurred layers over their depth ranges
    (rendering/deep_sliced.py).
    """
    renderer = get_backend(raster, scene)
    try:
        image = renderer.deep(camera, lens, settings, deep)
    finally:
        renderer.release()
    image.meta = {**exr_header(camera, lens, Tonemap(), settings, scene.colour_space),
                  "dofview:deep": json.dumps(deep.to_dict())}
    return image


def exr_header(camera: Camera, lens: Lens, tm: Tonemap, settings: RenderSettings, colour_space: str,
               scene_path: str | None = None, lens_info: dict[str, object] | None = None,
               stats: Stats | None = None) -> dict[str, object]:
    """dofview's EXR header attributes for one view, each from its type's ``to_dict``: version,
    scene, ``dofview:camera`` (:meth:`Camera.to_dict`), ``dofview:lens`` (:meth:`Lens.to_dict`,
    ``aperture_at_ref_width``: the ``--aperture`` value that gives this image's strength, held at
    the camera's ``ref_width`` (:meth:`Lens.aperture_at`), and ``lens_info``, a
    :meth:`~dofview.lens.LensRequest.to_dict`: how the aperture was asked for),
    ``dofview:exposure``, ``dofview:gamma`` and ``dofview:tonemap`` (:meth:`Tonemap.to_dict`),
    ``dofview:render`` (:meth:`RenderSettings.to_dict` and the scene's colour space); JSON strings
    where structured. :func:`read_header` reads them back. Beside them, the camera as OpenEXR's
    standard attributes that compositing applications read (:func:`dofview.io.exr.camera_attributes`:
    ``worldToCamera``, ``worldToNDC`` and, with a physical lens, its focus, f-number and focal lengths)."""
    from dofview.io.exr import camera_attributes

    physical = LensRequest.from_dict(lens_info).physical if lens_info else None
    header: dict[str, object] = {"dofview:version": __version__}
    if scene_path is not None:
        header["dofview:scene"] = scene_path
    display = tm.to_dict()
    header.update({
        "dofview:camera": json.dumps(camera.to_dict()),
        "dofview:lens": json.dumps({**lens.to_dict(),
                                    "aperture_at_ref_width": lens.aperture_at(camera.width, camera.ref_width),
                                    **(lens_info or {})}),
        "dofview:exposure": display["exposure"],
        "dofview:gamma": display["gamma"],
        "dofview:tonemap": json.dumps(display["tonemap"]),
        "dofview:render": json.dumps({**settings.to_dict(), "colour_space": colour_space}),
    })
    if stats is not None:  # the statistics the PNG was tone mapped with (log2 linear radiance)
        header["dofview:tonemap_stats"] = stats.to_json()
    header.update(camera_attributes(camera, settings.near, lens.focus, physical))
    return header


def read_header(header: dict[str, object]) -> dict[str, object]:
    """The dofview entries of an EXR header (:func:`exr_header`'s, read with
    :func:`dofview.io.exr.read_exr`) as objects: ``camera``, ``lens``, ``lens_request``,
    ``tonemap``, ``settings``, ``colour_space`` for those present, and the other ``dofview:``
    entries by name as stored. Recorded objects read with their own ``from_dict``, so a header
    written before an entry was recorded (``near``) reads with that entry's default.

    Raises:
        DofviewError: a malformed entry.
    """
    out: dict[str, object] = {k[len("dofview:"):]: v for k, v in header.items() if k.startswith("dofview:")}
    try:
        if "dofview:camera" in header:
            out["camera"] = Camera.from_dict(_json_entry(header, "dofview:camera"))
        if "dofview:lens" in header:
            out["lens"] = Lens.from_dict(_json_entry(header, "dofview:lens"))
            out["lens_request"] = LensRequest.from_dict(_json_entry(header, "dofview:lens"))
        if "dofview:render" in header:
            render = _json_entry(header, "dofview:render")
            out["colour_space"] = render.pop("colour_space", "srgb")
            out["settings"] = RenderSettings.from_dict(render)
        if "dofview:tonemap" in header:
            out["tonemap"] = Tonemap.from_dict({"exposure": header.get("dofview:exposure", 0.0),
                                                "gamma": header.get("dofview:gamma", 2.2),
                                                "tonemap": _json_entry(header, "dofview:tonemap")},
                                               str(out.get("colour_space", "srgb")))
    except (KeyError, TypeError, ValueError) as e:
        raise DofviewError(f"EXR header: malformed dofview entry ({e})") from None
    return out


def _json_entry(header: dict[str, object], key: str) -> dict:
    """The JSON object of header entry ``key``; DofviewError when it is not one."""
    value = header[key]
    try:
        d = json.loads(value) if isinstance(value, (str, bytes)) else value
    except ValueError:
        d = None
    if not isinstance(d, dict):
        raise DofviewError(f"EXR header {key}: not a JSON object")
    return d


def joint_stats(renderer: Renderer, cameras: list[Camera], operator, settings: RenderSettings = RenderSettings(),
                width: int = 256) -> Stats:
    """Statistics pooled over ``cameras`` (all training views: ``--stats joint``, seed 004 §5.1.6):
    each view rendered as a pinhole ``width`` pixels wide, its log histograms summed."""
    frames = []
    for cam in cameras:
        frames.append(renderer.render(cam.resized(width, max(1, round(cam.height * width / cam.width))),
                                      Lens(1.0, 0.0), settings).rgba)
    return pooled_stats(frames, operator, renderer.scene.colour_space == "srgb")


def save_render(renderer: Renderer, camera: Camera, lens: Lens, tm: Tonemap, settings: RenderSettings,
                scene_path: str, output: Path, png: Path | None = None, half: bool = False,
                lens_info: dict[str, float | None] | None = None, header: dict[str, object] | None = None,
                stats: Stats | None = None, lens_samples: int = 0, smoother: StatsSmoother | None = None,
                dt: float = 0.0, deep: Path | None = None, deep_settings: DeepSettings = DeepSettings()) -> Frame:
    """Render a view and write it as ``dofview render`` does: a linear EXR (exposure applied, Z,
    dofview header) and optionally the PNG tone mapped on the GPU. Shared by the CLI and the
    viewer's Save.

    ``lens_info`` is how the aperture was asked for (:meth:`dofview.lens.LensRequest.to_dict`:
    the physical-lens values and the options as given); ``header`` adds attributes (a sequence's frame number).
    ``stats``: statistics for an adaptive ``tm.operator`` (joint or smoothed); default this frame's,
    from the read-back frame; with ``smoother`` (a sequence: one StatsSmoother for all its frames,
    ``dt`` the frame interval in seconds) this frame's statistics are smoothed in time first.
    The EXR stays linear whatever the operator; its header records the operator and the statistics. ``lens_samples`` > 0: the depth of field refined with that many
    sub-aperture passes (rendering.progressive; the image the viewer shows once it reached that many).
    ``deep``: also write the view's deep image there (:meth:`Renderer.deep` with ``deep_settings``,
    the same header plus ``dofview:deep``, exposure applied), checked before anything is written.
    """
    from dofview.io.png import write_png

    if deep is not None:
        if lens_samples:
            raise DofviewError("--deep cannot be refined with --lens-samples: the deep image is one pass")
    if lens_samples:
        frame = render_lens_samples(renderer, camera, lens, settings, lens_samples)
        header = {"dofview:lens_samples": lens_samples, **(header or {})}
    else:
        frame = renderer.render(camera, lens, settings)
    if tm.operator.adaptive and stats is None:
        stats = frame_stats(frame.rgba, tm.operator, renderer.scene.colour_space == "srgb")
        if smoother is not None:
            stats = smoother.update(stats, dt)
    frame.meta = {**exr_header(camera, lens, tm, settings, renderer.scene.colour_space, scene_path, lens_info,
                               stats if tm.operator.adaptive else None),
                  **(header or {})}
    frame.save_exr(output, exposure=tm.exposure, half=half)
    if png:
        write_png(png, renderer.display_image(tm, stats=stats))
    if deep is not None:
        save_deep(renderer.deep(camera, lens, settings, deep_settings), deep, frame.meta, deep_settings, tm.exposure)
    return frame


def save_deep(image: DeepFrame, path: Path, header: dict[str, object], deep_settings: DeepSettings,
              exposure: float) -> None:
    """Write a deep image with a flat render's ``header`` and ``dofview:deep`` (the
    :meth:`DeepSettings.to_dict` it was made with), exposed by ``exposure`` EV as the flat EXR."""
    image.meta = {**header, "dofview:deep": json.dumps(deep_settings.to_dict())}
    image.save_deep_exr(path, exposure=exposure)
