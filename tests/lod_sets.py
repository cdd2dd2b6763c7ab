"""Streamed LOD sets (lod-meta.json + SOG chunks) made for the tests by splat-transform, the tool that
publishes them, from scenes the tests choose; each set is made once per test process."""

from __future__ import annotations

import subprocess
import tempfile
from functools import cache
from pathlib import Path

import numpy as np
from conftest import random_scene

from dofview.bench.formats import splat_transform
from dofview.io import load_scene
from dofview.io.ply import write_ply
from dofview.scene import GaussianScene

ROOT = Path(__file__).resolve().parents[1]
CARDS = ROOT / "samples" / "cards.ply"


def make_lod_set(folder: Path, levels: list[GaussianScene], environment: GaussianScene | None = None,
                 chunk_k: int = 1, extent: float = 1.0) -> Path:
    """``splat-transform L0.ply -l 0 L1.ply -l 1 … [env.ply -l -1] folder/lod-meta.json`` with leaves
    of about ``chunk_k`` thousand Gaussians or ``extent`` scene units; returns the lod-meta.json."""
    tool = splat_transform()
    assert tool, "splat-transform is not installed: run scripts/setup.sh"
    folder.mkdir(parents=True, exist_ok=True)
    args = [tool, "-q", "-w", "-g", "cpu"]
    for i, scene in enumerate(levels):
        write_ply(scene, folder / f"level{i}.ply")
        args += [str(folder / f"level{i}.ply"), "-l", str(i)]
    if environment is not None:
        write_ply(environment, folder / "env.ply")
        args += [str(folder / "env.ply"), "-l", "-1"]
    out = folder / "set" / "lod-meta.json"
    args += ["--lod-chunk-count", str(chunk_k), "--lod-chunk-extent", str(extent), str(out)]
    done = subprocess.run(args, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-1000:]
    return out


@cache
def cards_set() -> Path:
    """samples/cards.ply (19,129 Gaussians, SH 0) as level 0 and every other Gaussian of it as
    level 1, in leaves of about 4096 Gaussians (all levels counted) (levels' PLYs beside the set: level0.ply, level1.ply)."""
    cards = load_scene(CARDS, progress=False)
    return make_lod_set(Path(tempfile.mkdtemp(prefix="lod_cards_")), [cards, cards.subset(slice(0, None, 2))], chunk_k=4)


@cache
def sh_set() -> Path:
    """A random SH degree 1 scene of 3000 Gaussians as level 0, its every third Gaussian as level 1,
    and an environment of 200 SH-degree-0 Gaussians far behind it."""
    scene = random_scene(n=3000, degree=1, seed=11)
    env = random_scene(n=200, degree=0, seed=12)
    env.means = env.means * np.float32(4.0) + np.float32([0, 0, 30])
    return make_lod_set(Path(tempfile.mkdtemp(prefix="lod_sh_")), [scene, scene.subset(slice(0, None, 3))], env)
