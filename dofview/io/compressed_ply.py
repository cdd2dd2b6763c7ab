"""PlayCanvas/SuperSplat ``.compressed.ply`` (the layout of PlayCanvas splat-transform's
write-compressed-ply and compressed-chunk, and the engine's loader): a binary little-endian PLY with

- ``element chunk``: per 256 Gaussians, float bounds min_x…max_z, min_scale_x…max_scale_z (log
  scales) and optionally min_r…max_b (base colour, SH_C0·dc + 0.5);
- ``element vertex``: four uint per Gaussian: packed_position and packed_scale (11-10-11 bits of
  x, y, z from the high bits, each a fraction of the chunk's min…max), packed_rotation (2 bits for
  the index of the dropped largest component of (w, x, y, z), made positive, then three 10-bit
  fields of ``q·√2/2 + 0.5`` for the others in index order), packed_color (8-8-8-8 of r, g, b as
  fractions of the chunk's colour range, or plain [0, 1] colour without one, and opacity);
- optionally ``element sh``: uchar f_rest_0… (9, 24 or 45, channel-major like a 3DGS .ply), each
  ``(v/8 + 0.5)·256`` truncated; 0 and 255 decode to the ends of the range.

Data is in PLY axes, as dofview's. Files from the same tool are usually sorted in Morton order, so
Gaussian i here is not Gaussian i of the .ply it came from.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from dofview.errors import DofviewError, SceneFormatError
from dofview.io._packed import quats_from_smallest_three, scene_from_arrays, unorm
from dofview.io.ply_header import read_header
from dofview.scene import SH_C0, GaussianScene

CHUNK = 256
CHUNK_BOUNDS = ("min_x", "min_y", "min_z", "max_x", "max_y", "max_z",
                "min_scale_x", "min_scale_y", "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z")
CHUNK_COLOURS = ("min_r", "min_g", "min_b", "max_r", "max_g", "max_b")
VERTEX = ("packed_position", "packed_rotation", "packed_scale", "packed_color")
SH_RANGE = 8.0  # stored SH values span [−4, 4]


def _layout(path: Path, fmt: str, elements) -> dict[str, tuple[object, np.dtype]]:
    """name → (element, structured dtype) for chunk, vertex and sh, checked against the layout."""
    if fmt != "binary_little_endian":
        raise SceneFormatError(f"{path}: compressed PLY must be binary_little_endian, not {fmt}")
    by_name = {e.name: e for e in elements}
    extra = [e.name for e in elements if e.name not in ("chunk", "vertex", "sh")]
    if extra or len(by_name) != len(elements):
        raise SceneFormatError(f"{path}: compressed PLY has unexpected elements "
                               f"{', '.join(extra) or 'repeated'} (expected chunk, vertex and optional sh)")
    if "vertex" not in by_name:
        raise SceneFormatError(f"{path}: compressed PLY has no 'vertex' element")
    wanted = {"chunk": ("f4", CHUNK_BOUNDS), "vertex": ("u4", VERTEX)}
    chunk_props = [name for name, _ in by_name["chunk"].props]
    if chunk_props not in (list(CHUNK_BOUNDS), list(CHUNK_BOUNDS + CHUNK_COLOURS)):
        raise SceneFormatError(f"{path}: compressed PLY chunk properties are {', '.join(chunk_props)}; expected "
                               f"{', '.join(CHUNK_BOUNDS)} and optionally {', '.join(CHUNK_COLOURS)}")
    wanted["chunk"] = ("f4", tuple(chunk_props))
    if "sh" in by_name:
        k = len(by_name["sh"].props)
        if k not in (9, 24, 45):
            raise SceneFormatError(f"{path}: compressed PLY sh element has {k} properties (expected 9, 24 or 45)")
        wanted["sh"] = ("u1", tuple(f"f_rest_{i}" for i in range(k)))
    layout = {}
    for name, (kind, props) in wanted.items():
        e = by_name[name]
        got = tuple(p for p, _ in e.props)
        types = {t for _, t in e.props}
        if got != props or types != {kind}:
            raise SceneFormatError(f"{path}: compressed PLY {name} element must hold {kind} properties "
                                   f"{', '.join(props)}; got {', '.join(p + ' (' + (t or 'list') + ')' for p, t in e.props)}")
        layout[name] = (e, np.dtype([(p, "<" + kind) for p in props]))
    n, chunks = by_name["vertex"].count, by_name["chunk"].count
    if chunks != -(-n // CHUNK):
        raise SceneFormatError(f"{path}: compressed PLY has {chunks} chunks for {n} Gaussians "
                               f"(expected {-(-n // CHUNK)}, one per {CHUNK})")
    if "sh" in by_name and by_name["sh"].count != n:
        raise SceneFormatError(f"{path}: compressed PLY has {by_name['sh'].count} SH rows for {n} Gaussians")
    if n == 0:
        raise SceneFormatError(f"{path}: compressed PLY holds no Gaussians")
    return layout


def read_compressed_ply(path: str | Path, progress: Callable[[int, int], None] | None = None) -> GaussianScene:
    """Read a PlayCanvas compressed PLY into an sRGB :class:`GaussianScene`.

    Raises:
        SceneFormatError: not a compressed PLY, cut short, or with an unexpected layout.
    """
    path = Path(path)
    try:
        size, fmt, elements, _, header_len = read_header(path)
    except DofviewError as e:
        raise SceneFormatError(str(e)) from None
    layout = _layout(path, fmt, elements)
    need = sum(e.count * dtype.itemsize for e, dtype in layout.values())
    if need > size - header_len:
        raise SceneFormatError(f"{path}: file is cut short: the header announces {layout['vertex'][0].count} "
                               f"Gaussians ({need} bytes) but only {size - header_len} bytes follow it")
    arrays, offset = {}, header_len
    for e in elements:  # in file order
        dtype = layout[e.name][1]
        arrays[e.name] = np.fromfile(path, dtype, count=e.count, offset=offset)
        offset += e.count * dtype.itemsize
    chunk, vertex = arrays["chunk"], arrays["vertex"]
    n = vertex.shape[0]
    c = np.arange(n) // CHUNK

    def lerp(packed: np.ndarray, shift: int, bits: int, lo: str, hi: str) -> np.ndarray:
        lo_v, hi_v = chunk[lo][c].astype(np.float64), chunk[hi][c].astype(np.float64)
        return lo_v + (hi_v - lo_v) * unorm(packed, shift, bits)

    def xyz(packed: np.ndarray, lo: str, hi: str, suffix: str = "") -> np.ndarray:
        return np.column_stack([lerp(packed, shift, bits, f"{lo}{suffix}{a}", f"{hi}{suffix}{a}")
                                for a, (shift, bits) in zip("xyz", ((21, 11), (11, 10), (0, 11)))])

    means = xyz(vertex["packed_position"], "min_", "max_")
    log_scales = xyz(vertex["packed_scale"], "min_", "max_", "scale_")
    col = vertex["packed_color"]
    if "min_r" in chunk.dtype.names:
        rgb = np.column_stack([lerp(col, shift, 8, f"min_{ch}", f"max_{ch}") for ch, shift in zip("rgb", (24, 16, 8))])
    else:
        rgb = np.column_stack([unorm(col, shift, 8) for shift in (24, 16, 8)])
    opacities = unorm(col, 0, 8)
    rot = vertex["packed_rotation"]
    others = np.column_stack([(unorm(rot, shift, 10) - 0.5) * np.sqrt(2.0) for shift in (20, 10, 0)])
    quats = quats_from_smallest_three((rot >> 30).astype(np.int64), others)
    sh_rest = None
    if "sh" in arrays:
        raw = np.stack([arrays["sh"][name] for name in arrays["sh"].dtype.names], axis=1).astype(np.float64)
        t = np.where(raw == 0, 0.0, np.where(raw == 255, 1.0, (raw + 0.5) / 256.0))
        k1 = raw.shape[1] // 3
        sh_rest = ((t - 0.5) * SH_RANGE).reshape(n, 3, k1).transpose(0, 2, 1)  # channel-major → (N, K−1, 3)
    if progress:
        progress(n, n)
    return scene_from_arrays(path, means, quats, log_scales, opacities, (rgb - 0.5) / SH_C0, sh_rest)
