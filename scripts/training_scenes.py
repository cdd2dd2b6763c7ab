"""Write the two real-capture scenes that docs/TRAINING.md's quality runs at real size are made from.

    python scripts/training_scenes.py OUT_DIR

- ``guitar_lamp.ply``: tests/data/guitar.compressed.ply (90,854 Gaussians, read as linear radiance)
  plus a lamp: a ball of 60 opaque Gaussians beside the guitar whose radiance is 100× the guitar's
  brightest base colour, so the scene's dynamic range is a real HDR one (the guitar alone spans its
  albedos only, which an LDR fit holds nearly as well).
- ``tap_glossy.ply``: tests/data/tap.spz (132,432 Gaussians, SH degree 3, a phone scan) read as
  linear radiance with its SH bands 1–3 scaled by 10, so the colour changes strongly with the view
  (median change across the dataset's 40 views: 16 % of the colour; 7 % at ×3).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from dofview.io import load_scene  # noqa: E402
from dofview.io.ply import write_ply  # noqa: E402
from dofview.scene import SH_C0, GaussianScene  # noqa: E402

LAMP_GAUSSIANS = 60
LAMP_GAIN = 100.0  # × the guitar's brightest base colour
SH_GAIN = 10.0


def guitar_lamp() -> GaussianScene:
    guitar = load_scene(ROOT / "tests" / "data" / "guitar.compressed.ply", progress=False)
    lo, hi = guitar.robust_bounds()
    extent = hi - lo
    rng = np.random.default_rng(0)
    d = rng.normal(size=(LAMP_GAUSSIANS, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    radius = 0.04 * float(np.linalg.norm(extent))
    centre = (lo + hi) / 2 + np.array([0.45 * extent[0], -0.1 * extent[1], 0.0])
    ball = centre + radius * d * rng.uniform(0, 1, (LAMP_GAUSSIANS, 1)) ** (1 / 3)
    radiance = LAMP_GAIN * float(guitar.base_colour().max()) * np.array([1.0, 0.85, 0.65])
    n = LAMP_GAUSSIANS
    return GaussianScene(
        means=np.concatenate([guitar.means, ball]),
        quats=np.concatenate([guitar.quats, np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))]),
        scales=np.concatenate([guitar.scales, np.full((n, 3), 0.5 * radius)]),
        opacities=np.concatenate([guitar.opacities, np.full(n, 0.99)]),
        sh_dc=np.concatenate([guitar.sh_dc, np.tile((radiance - 0.5) / SH_C0, (n, 1))]),
        colour_space="linear", name="guitar_lamp")


def tap_glossy() -> GaussianScene:
    tap = load_scene(ROOT / "tests" / "data" / "tap.spz", progress=False)
    return dataclasses.replace(tap, sh_rest=tap.sh_rest * SH_GAIN, colour_space="linear", name="tap_glossy")


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out", type=Path, help="folder to write guitar_lamp.ply and tap_glossy.ply into")
    out = p.parse_args().out
    out.mkdir(parents=True, exist_ok=True)
    for name, make in (("guitar_lamp.ply", guitar_lamp), ("tap_glossy.ply", tap_glossy)):
        write_ply(make(), out / name)
        print(out / name)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
