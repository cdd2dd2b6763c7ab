"""Views from inside the shared places, for the quality study: where a person would stand and what a
photographer would focus on.

``dofview/bench/places/<place>_<n>.json`` holds one camera each, in the Inria ``cameras.json`` form
(so ``dofview render SCENE --cameras FILE`` takes it as it is) with two more keys: ``focus``, the
camera z-depth of the subject in scene units (measured on a pinhole render at the subject's pixel),
and ``subject``, what it is, in words. The places are the scenes of ``../shared/scenes`` that are
rooms (corridor.compressed.ply, kitchen_balcony.compressed.ply, showroom/lod-meta.json; not in the
repository: only these poses are). Each has two views at eye height with a wall, a door frame or
furniture within a metre of the lens at the frame's edges: ``_1`` focused near (a door handle, a tap,
an armchair: 0.9–1.6 units), ``_2`` far (the end of the corridor, the fridge, the fireplace across the
room: 1.9–4.4 units). 320 × 240 px, f_x 230 (69° across), small enough for llvmpipe.

    from dofview.bench.places import place_views
    for camera, focus in place_views("../shared/scenes/corridor.compressed.ply"):
        frame = renderer.render(camera, Lens(focus, aperture))
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple

from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.io.cameras import load_cameras_json
from dofview.io.jsonfile import read_json

VIEWS = Path(__file__).with_name("places")
"""The folder of the view files."""


class PlaceView(NamedTuple):
    """A view from inside a place: its ``camera`` (named ``<place>_<n>``) and ``focus``, the subject's
    camera z-depth in scene units."""

    camera: Camera
    focus: float


def place_names() -> list[str]:
    """The places that have views, sorted: corridor, kitchen_balcony, showroom."""
    return sorted({p.stem.rsplit("_", 1)[0] for p in VIEWS.glob("*_*.json")})


def place_of(scene: str | Path) -> str | None:
    """The place a scene file shows, or None: the longest place name that its name starts with, its
    name being the file's up to the first dot, or the folder's for a ``lod-meta.json`` or ``meta.json``
    (``.../corridor.compressed.ply`` → corridor, ``.../showroom/lod-meta.json`` → showroom, a decoded
    level ``showroom_l1.ply`` → showroom). A bare place name is its own."""
    path = Path(scene)
    name = path.parent.name if path.name in ("lod-meta.json", "meta.json") else path.name.split(".")[0]
    matches = [p for p in place_names() if name == p or name.startswith(p + "_")]
    return max(matches, key=len) if matches else None


def place_views(scene: str | Path) -> list[PlaceView]:
    """The views of the place ``scene`` shows (a scene file or a place name, :func:`place_of`), in
    order ``_1``, ``_2``, …; empty for a scene that is no place here (an object).

    Raises:
        DofviewError: a view file that is not one camera with a positive, finite ``focus``.
    """
    place = place_of(scene)
    if place is None:
        return []
    views = []
    for path in sorted(VIEWS.glob(f"{place}_*.json"), key=lambda p: int(p.stem.rsplit("_", 1)[1])):
        cameras, entries = load_cameras_json(path), read_json(path, "place view")
        focus = entries[0].get("focus") if len(cameras) == 1 and isinstance(entries[0], dict) else None
        if not isinstance(focus, (int, float)) or not math.isfinite(focus) or focus <= 0:
            raise DofviewError(f"{path}: expected one camera with a positive \"focus\" (its subject's depth)")
        views.append(PlaceView(cameras[0], float(focus)))
    return views
