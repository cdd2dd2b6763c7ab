"""The scene files the tests read (tests/data, described in tests/data/README.md) and Inria-style run
folders built from them with cameras the test chooses."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dofview.camera import Camera, look_at
from dofview.framing import robust_box
from dofview.io import load_scene
from dofview.io.cameras import save_cameras_json

SCENES = Path(__file__).resolve().parent / "data"  # the repository's own copies: tests read nothing beside it
TWO_PLANES = SCENES / "two_planes.ply"
BURGER = SCENES / "burger.ply"


def ring_cameras(scene_path: Path, n: int = 6, size: tuple[int, int] = (160, 120), fov: float = 50.0) -> list[Camera]:
    """``n`` cameras on a ring around the scene's robust box, 25° above its horizon (world up −y),
    looking at its middle from 2.5× its half-diagonal."""
    lo, hi = robust_box(load_scene(scene_path, progress=False))
    centre, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2
    cams = []
    for i in range(n):
        a = 2 * np.pi * i / n
        d = np.array([np.sin(a) * np.cos(0.44), -np.sin(0.44), np.cos(a) * np.cos(0.44)])
        cam = look_at(centre - 2.5 * radius * d, centre, *size, fov)
        cams.append(Camera(cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy, cam.R, cam.T, name=f"DSC_{i:04d}"))
    return cams


def make_run_folder(root: Path, iterations: dict[int, Path], cameras: list[Camera] | None) -> Path:
    """``root`` holding cameras.json, cfg_args and point_cloud/iteration_N/point_cloud.ply (links
    to the given scene files), as the Inria trainer leaves them."""
    root.mkdir(parents=True)
    for it, scene in iterations.items():
        folder = root / "point_cloud" / f"iteration_{it}"
        folder.mkdir(parents=True)
        (folder / "point_cloud.ply").symlink_to(scene)
    if cameras is not None:
        save_cameras_json(cameras, root / "cameras.json")
    (root / "cfg_args").write_text("Namespace(sh_degree=3, source_path='/data/scene', model_path='output/x', "
                                   "images='images', resolution=-1, white_background=False, eval=False)")
    return root
