"""Regenerate the bundled samples from dofview's own procedural generator (dofview/synth.py).

    python samples/generate.py            # writes samples/*.ply and samples/*_cameras.json

cards.ply: sRGB, SH degree 0, three textured cards at depths 2, 4 and 8 before a wall at 14.
lamp.ply: linear HDR, SH degree 3, a room with a lamp bulb ≥ 100× brighter than any wall.
"""

from pathlib import Path

from dofview.bench import synth
from dofview.io import save_scene
from dofview.io.cameras import save_cameras_json

HERE = Path(__file__).resolve().parent


def main() -> None:
    for name, scene, cameras in (("cards", synth.cards_scene(), synth.cards_cameras()),
                                 ("lamp", synth.lamp_scene(), synth.lamp_cameras())):
        save_scene(scene, HERE / f"{name}.ply")
        save_cameras_json(cameras, HERE / f"{name}_cameras.json")
        print(f"{name}.ply: {scene.count} Gaussians, SH degree {scene.sh_degree}, {scene.colour_space}")


if __name__ == "__main__":
    main()
