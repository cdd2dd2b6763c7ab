"""Structure-from-motion points: COLMAP ``points3D.txt`` / ``points3D.bin`` and .ply point files.

The layouts are COLMAP's documented ones (colmap.github.io/format.html), read here by hand:

- text: ``#`` comments, then one point a line: ``POINT3D_ID X Y Z R G B ERROR`` followed by its
  track, pairs of ``IMAGE_ID POINT2D_IDX`` (ignored here);
- binary, little-endian: uint64 point count, then per point uint64 id, 3 × float64 position,
  3 × uint8 colour, float64 error, uint64 track length and that many (int32 image id, int32
  point index) pairs.

A .ply points file (nerfstudio's ``sparse_pc.ply``) is a ``vertex`` element with x, y, z and,
optionally, red, green, blue (uint8). Anything else is refused with the file named.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dofview.errors import DofviewError

_POINT = struct.Struct("<Q3d3BdQ")  # id, xyz, rgb, error, track length
_TRACK_PAIR = 8  # int32 image id + int32 point index


@dataclass(frozen=True)
class PointCloud:
    """Points of a reconstruction, in the dataset's world frame.

    Attributes:
        positions: (P, 3) float64, scene units.
        colours: (P, 3) float32 8-bit display values / 255 as the file stores them, or None.
        path: the file they were read from.
    """

    positions: np.ndarray
    colours: np.ndarray | None
    path: Path


def _checked(path: Path, positions: np.ndarray, colours: np.ndarray | None) -> PointCloud:
    if len(positions) == 0:
        raise DofviewError(f"{path}: no points in the file")
    if not np.all(np.isfinite(positions)):
        raise DofviewError(f"{path}: point positions must be finite")
    return PointCloud(positions.astype(np.float64), None if colours is None else colours.astype(np.float32) / 255.0,
                      path)


def read_colmap_text(path: Path) -> PointCloud:
    """A COLMAP ``points3D.txt`` (see the module docstring)."""
    positions, colours = [], []
    try:
        lines = path.read_text(encoding="utf-8", errors="strict").splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise DofviewError(f"{path}: cannot read COLMAP points ({e})") from None
    for n, line in enumerate(lines, 1):
        fields = line.split()
        if not fields or fields[0].startswith("#"):
            continue
        try:
            if len(fields) < 8 or len(fields) % 2:
                raise ValueError(f"{len(fields)} fields")
            x, y, z = (float(v) for v in fields[1:4])
            rgb = [int(v) for v in fields[4:7]]
            float(fields[7])
            if not all(0 <= c <= 255 for c in rgb):
                raise ValueError("colour outside 0..255")
        except ValueError as e:
            raise DofviewError(f"{path}: line {n} is not 'POINT3D_ID X Y Z R G B ERROR TRACK…' ({e})") from None
        positions.append((x, y, z))
        colours.append(rgb)
    return _checked(path, np.array(positions, np.float64).reshape(-1, 3), np.array(colours, np.uint8).reshape(-1, 3))


def read_colmap_binary(path: Path) -> PointCloud:
    """A COLMAP ``points3D.bin`` (see the module docstring)."""
    try:
        data = path.read_bytes()
    except OSError as e:
        raise DofviewError(f"{path}: cannot read COLMAP points ({e})") from None
    if len(data) < 8:
        raise DofviewError(f"{path}: too short for a COLMAP points3D.bin ({len(data)} bytes)")
    count = struct.unpack_from("<Q", data)[0]
    if count > (len(data) - 8) // _POINT.size:
        raise DofviewError(f"{path}: says {count} points but holds {len(data)} bytes: cut short or not points3D.bin")
    positions, colours = np.empty((count, 3)), np.empty((count, 3), np.uint8)
    at = 8
    for i in range(count):
        if at + _POINT.size > len(data):
            raise DofviewError(f"{path}: cut short at point {i} of {count}")
        _, x, y, z, r, g, b, _, track = _POINT.unpack_from(data, at)
        positions[i], colours[i] = (x, y, z), (r, g, b)
        at += _POINT.size + track * _TRACK_PAIR
    if at != len(data):
        raise DofviewError(f"{path}: {len(data) - at:+d} bytes after {count} points: cut short or not points3D.bin")
    return _checked(path, positions, colours)


def read_points_ply(path: Path) -> PointCloud:
    """A .ply of points: a ``vertex`` element with x, y, z and optional red, green, blue."""
    import plyfile

    try:
        vertex = plyfile.PlyData.read(str(path))["vertex"]
        positions = np.stack([np.asarray(vertex[k], np.float64) for k in "xyz"], 1)
    except (OSError, ValueError, KeyError, IndexError, plyfile.PlyParseError) as e:
        raise DofviewError(f"{path}: not a .ply of points with x, y, z ({e})") from None
    names = {p.name for p in vertex.properties}
    colours = None
    if {"red", "green", "blue"} <= names:
        colours = np.stack([np.asarray(vertex[k]) for k in ("red", "green", "blue")], 1)
        if colours.dtype != np.uint8:
            raise DofviewError(f"{path}: red, green, blue must be uint8, not {colours.dtype}")
    return _checked(path, positions, colours)


def read_points(path: Path) -> PointCloud:
    """Points from ``path`` by its name: ``*.txt`` COLMAP text, ``*.bin`` COLMAP binary, ``*.ply``."""
    readers = {".txt": read_colmap_text, ".bin": read_colmap_binary, ".ply": read_points_ply}
    reader = readers.get(path.suffix.lower())
    if reader is None:
        raise DofviewError(f"{path}: a points file is COLMAP points3D.txt / points3D.bin or a .ply")
    if not path.is_file():
        raise DofviewError(f"{path}: points file does not exist")
    return reader(path)


def write_colmap_text(path: Path, positions: np.ndarray, colours: np.ndarray) -> None:
    """``positions`` (P, 3) scene units and ``colours`` (P, 3) uint8 as a COLMAP points3D.txt with
    empty tracks (ids from 1, error 0)."""
    lines = ["# 3D point list with one line of data per point:",
             "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)",
             f"# Number of points: {len(positions)}, mean track length: 0"]
    lines += [f"{i} {x!r} {y!r} {z!r} {r} {g} {b} 0" for i, ((x, y, z), (r, g, b))
              in enumerate(zip(positions.tolist(), colours.tolist()), 1)]
    path.write_text("\n".join(lines) + "\n")


def nearest_distance(positions: np.ndarray, k: int = 3) -> np.ndarray:
    """(P,) root mean square distance of each point to its ``k`` nearest others (P ≥ 2), the
    reference 3DGS start's scale; a point alone in its place gets the median of the others."""
    import torch

    pts = torch.tensor(positions, dtype=torch.float64)
    k = min(k, len(pts) - 1)
    out = torch.empty(len(pts), dtype=torch.float64)
    for start in range(0, len(pts), 2048):  # (2048, P) distances at a time
        d = torch.cdist(pts[start:start + 2048], pts)
        d[torch.arange(len(d)), torch.arange(start, start + len(d))] = math.inf
        out[start:start + 2048] = d.topk(k, largest=False).values.square().mean(1).sqrt()
    out = out.numpy()
    positive = out[out > 0]
    return np.where(out > 0, out, np.median(positive) if len(positive) else 1.0)
