"""A larger streamed LOD set made from one (for measuring at real size): the set's copies on a grid,
each copy's chunk positions moved by its offset (the means images re-encoded; the other images
linked, not copied), the copies' trees joined under one root.

    python scripts/tile_lod_set.py ../shared/scenes/showroom /tmp/tiled12m --grid 4,2 --step 24,28

Write the result outside the repository when the source has no licence (the shared places).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np


def log_transform(v: np.ndarray) -> np.ndarray:
    """SOG's position transform sign(v)·ln(|v| + 1) (dofview/io/sog.py)."""
    return np.sign(v) * np.log1p(np.abs(v))


def moved_chunk(src: Path, dst: Path, offset: np.ndarray) -> None:
    """The loose SOG ``src`` (its meta.json) with every position moved by ``offset``, into ``dst``."""
    from PIL import Image

    meta = json.loads(src.read_text())
    dst.parent.mkdir(parents=True, exist_ok=True)
    lo_name, hi_name = meta["means"]["files"]
    lo = np.asarray(Image.open(src.parent / lo_name).convert("RGBA")).copy()
    hi = np.asarray(Image.open(src.parent / hi_name).convert("RGBA")).copy()
    mins, maxs = np.array(meta["means"]["mins"]), np.array(meta["means"]["maxs"])
    stored = mins + (maxs - mins) * (lo[..., :3].astype(np.float64) + 256.0 * hi[..., :3]) / 65535.0
    v = log_transform(np.sign(stored) * np.expm1(np.abs(stored)) + offset)
    used = v.reshape(-1, 3)[:meta["count"]]
    new_min, new_max = used.min(0), used.max(0)
    span = np.where(new_max > new_min, new_max - new_min, 1.0)
    code = np.clip(np.round((v - new_min) / span * 65535.0), 0, 65535).astype(np.uint32)
    lo[..., :3], hi[..., :3] = code & 255, code >> 8
    for image, name in ((lo, lo_name), (hi, hi_name)):
        Image.fromarray(image, "RGBA").save(dst.parent / name, lossless=True, quality=0, method=0, exact=True)
    for key in ("quats", "scales", "sh0", "shN"):
        for name in meta.get(key, {}).get("files", []):
            if not (dst.parent / name).exists():
                os.symlink((src.parent / name).resolve(), dst.parent / name)
    meta["means"]["mins"], meta["means"]["maxs"] = new_min.tolist(), new_max.tolist()
    dst.write_text(json.dumps(meta))


def moved_tree(node: dict, offset: np.ndarray, first_file: int) -> dict:
    out = {"bound": {k: (np.array(node["bound"][k]) + offset).tolist() for k in ("min", "max")}}
    if "children" in node:
        out["children"] = [moved_tree(c, offset, first_file) for c in node["children"]]
    if "lods" in node:
        out["lods"] = {k: {**r, "file": r["file"] + first_file} for k, r in node["lods"].items()}
    return out


def joined(nodes: list[dict]) -> dict:
    """One binary tree over ``nodes`` (pairs joined level by level)."""
    while len(nodes) > 1:
        pairs = [nodes[i:i + 2] for i in range(0, len(nodes), 2)]
        nodes = [p[0] if len(p) == 1 else {"bound": {"min": np.minimum(p[0]["bound"]["min"], p[1]["bound"]["min"]).tolist(),
                                                     "max": np.maximum(p[0]["bound"]["max"], p[1]["bound"]["max"]).tolist()},
                                           "children": p} for p in pairs]
    return nodes[0]


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("source", type=Path, help="a streamed LOD set's folder")
    p.add_argument("out", type=Path, help="the new set's folder")
    p.add_argument("--grid", default="4,2", help="copies along x and y")
    p.add_argument("--step", default="24,28", help="offset between copies along x and y, scene units")
    args = p.parse_args()
    nx, ny = (int(v) for v in args.grid.split(","))
    sx, sy = (float(v) for v in args.step.split(","))
    meta = json.loads((args.source / "lod-meta.json").read_text())
    names, trees = [], []
    for k, offset in enumerate(np.array([i * sx, j * sy, 0.0]) for j in range(ny) for i in range(nx)):
        first = len(names)
        for name in meta["filenames"]:
            moved_chunk(args.source / name, args.out / f"t{k}" / name, offset)
            names.append(f"t{k}/{name}")
        trees.append(moved_tree(meta["tree"], offset, first))
    counts = [c * nx * ny for c in meta["counts"]]
    out = {"version": 1, "asset": {"generator": f"dofview scripts/tile_lod_set.py of {args.source.name}"},
           "count": sum(counts), "counts": counts, "lodLevels": meta["lodLevels"], "filenames": names,
           "tree": joined(trees)}
    (args.out / "lod-meta.json").write_text(json.dumps(out))
    print(f"{args.out}: {nx * ny} copies, {' / '.join(f'{c:,}' for c in counts)} Gaussians")
    return 0


if __name__ == "__main__":
    sys.exit(main())
