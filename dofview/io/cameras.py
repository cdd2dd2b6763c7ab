"""Inria ``cameras.json``: the training views a 3DGS run leaves beside its point cloud."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.io.atomic import atomic_output
from dofview.io.jsonfile import read_json


def load_cameras_json(path: str | Path) -> list[Camera]:
    """Read an Inria ``cameras.json``: a list of {id, img_name, width, height, position (camera
    centre, world), rotation (3×3 camera → world), fx, fy}."""
    path = Path(path)
    entries = read_json(path, "cameras file")
    if not isinstance(entries, list) or not entries:
        raise DofviewError(f"{path}: expected a non-empty JSON list of cameras")
    cams = []
    for i, e in enumerate(entries):
        try:
            c2w = np.asarray(e["rotation"], dtype=np.float64).reshape(3, 3)
            pos = np.asarray(e["position"], dtype=np.float64).reshape(3)
            w, h = int(e["width"]), int(e["height"])
            fx, fy = float(e["fx"]), float(e["fy"])
        except (KeyError, TypeError, ValueError) as err:
            raise DofviewError(f"{path}: camera {i} is malformed ({err!r})") from None
        if not (np.all(np.isfinite(c2w)) and np.all(np.isfinite(pos)) and w > 0 and h > 0 and fx > 0 and fy > 0):
            raise DofviewError(f"{path}: camera {i} has non-finite or non-positive values")
        R = c2w.T
        cams.append(Camera(w, h, fx, fy, w / 2, h / 2, R, -R @ pos, name=str(e.get("img_name", i))))
    return cams


def save_cameras_json(cameras: list[Camera], path: str | Path) -> None:
    """Write cameras in the Inria ``cameras.json`` format (principal point assumed centred)."""
    out = []
    for i, c in enumerate(cameras):
        out.append({
            "id": i, "img_name": c.name or f"view_{i:03d}", "width": c.width, "height": c.height,
            "position": c.centre.tolist(), "rotation": c.R.T.tolist(), "fx": c.fx, "fy": c.fy,
        })
    with atomic_output(path) as tmp:  # whole or not at all, as every writer here
        tmp.write_text(json.dumps(out, indent=1))


def select_camera(cameras: list[Camera], view: str, source: str = "cameras.json") -> Camera:
    """Pick a camera by index (``"3"``) or image name (``"DSC_0042"``)."""
    names = [c.name for c in cameras]
    if view in names:
        return cameras[names.index(view)]
    try:
        idx = int(view)
    except ValueError:
        shown = ", ".join(names[:5]) + (", …" if len(names) > 5 else "")
        raise DofviewError(f"{source}: no camera named {view!r} (names: {shown})") from None
    if not 0 <= idx < len(cameras):
        raise DofviewError(f"{source}: view index {idx} out of range (0…{len(cameras) - 1})")
    return cameras[idx]
