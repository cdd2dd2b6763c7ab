"""Inria 3DGS ``.ply`` files: read into a :class:`GaussianScene`, write back in the same format.

A 3DGS PLY has one ``vertex`` element with float properties x, y, z; optional nx, ny, nz;
f_dc_0..2; f_rest_0..M−1 with M ∈ {0, 9, 24, 45} (SH degree 0–3, channel-major); opacity (logit);
scale_0..2 (log); rot_0..3 (w, x, y, z, not normalised). Other properties are ignored.

Binary bodies are mapped, not read whole, and checked against the header's vertex count before
anything is allocated. ASCII files go through plyfile. dofview records the scene's colour space as
a header comment ``dofview colour_space linear|srgb``; files without it are standard (sRGB).
"""

from __future__ import annotations

import mmap
import re
from pathlib import Path
from typing import Callable

import numpy as np

from dofview.errors import DofviewError
from dofview.io._common import report_dropped
from dofview.io._packed import LOG_SCALE_LIMIT
from dofview.io.ply_header import Element, read_header
from dofview.scene import COLOUR_SPACES, GaussianScene

REQUIRED = ("x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
            "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3")
REST_COUNTS = {0: 0, 9: 1, 24: 2, 45: 3}  # f_rest values → SH degree
_COLOUR_COMMENT = re.compile(r"^dofview colour_space (\w+)$")
_DROP_PAGES = hasattr(mmap, "MADV_DONTNEED")  # POSIX; Windows' mmap has no madvise
CHUNK = 1 << 18  # Gaussians activated per step (bounds temporaries, drives the progress bar)


def _check_vertex(path: Path, elements: list[Element]) -> Element:
    vertex = next((e for e in elements if e.name == "vertex"), None)
    if vertex is None:
        raise DofviewError(f"{path}: PLY file has no 'vertex' element, so no Gaussians")
    types = dict(vertex.props)
    missing = [p for p in REQUIRED if p not in types]
    if missing:
        hint = ""
        if {"x", "y", "z"} <= types.keys() and ({"red", "green", "blue"} & types.keys() or "f_dc_0" not in types):
            hint = " — this looks like a plain point cloud, not a trained 3D Gaussian Splatting scene"
        raise DofviewError(f"{path}: missing Gaussian properties {', '.join(missing)}{hint}")
    rest = sorted(int(p[7:]) for p in types if re.fullmatch(r"f_rest_\d+", p))
    if len(rest) not in REST_COUNTS or rest != list(range(len(rest))):
        raise DofviewError(f"{path}: {len(rest)} f_rest_* properties is no SH degree "
                           f"(expected 0, 9, 24 or 45 numbered from f_rest_0)")
    wanted = list(REQUIRED) + [f"f_rest_{i}" for i in rest]
    bad = [f"{p} ({'list' if types[p] is None else types[p]})" for p in wanted if types[p] not in ("f4", "f8")]
    if bad:
        raise DofviewError(f"{path}: Gaussian properties must be float or double, got {', '.join(bad)}")
    return vertex


def _check_body_size(path: Path, fmt: str, elements: list[Element], vertex: Element, body: int) -> None:
    """Refuse a body too short for the header's counts before anything is allocated (exact for
    binary files without lists, a lower bound otherwise)."""
    need = sum(e.min_body_bytes(fmt) for e in elements) - (fmt == "ascii")  # last newline optional
    if need > body:
        raise DofviewError(
            f"{path}: file is cut short: the header announces {vertex.count} Gaussians "
            f"(at least {need} bytes) but only {body} bytes follow it")


def _binary_columns(path: Path, fmt: str, elements: list[Element], vertex: Element,
                    header_len: int) -> np.ndarray | None:
    """The vertex rows as a read-only structured memmap, or None when the layout needs plyfile."""
    order = "<" if fmt == "binary_little_endian" else ">"
    offset = header_len
    for e in elements:
        if any(t is None for _, t in e.props):
            return None  # list properties before/in the vertex element: sizes are per row
        dtype = np.dtype([(n, order + t) for n, t in e.props])
        if e is vertex:
            if e.count == 0:
                return np.zeros(0, dtype)
            return np.memmap(path, dtype=dtype, mode="r", offset=offset, shape=(e.count,))
        offset += dtype.itemsize * e.count
    return None


def _plyfile_rows(path: Path) -> np.ndarray:
    import plyfile

    try:
        data = plyfile.PlyData.read(str(path))
        return data["vertex"].data
    except (plyfile.PlyParseError, ValueError, IndexError, KeyError, EOFError) as e:
        raise DofviewError(f"{path}: cannot parse PLY body ({str(e).splitlines()[0] if str(e) else type(e).__name__})") from None


def read_ply(path: str | Path, progress: Callable[[int, int], None] | None = None) -> GaussianScene:
    """Read a 3DGS ``.ply`` into an activated :class:`GaussianScene` (float32 arrays).

    Opacity goes through a sigmoid, scales through exp (both clamped so that no value overflows),
    quaternions are normalised (a zero one becomes the identity). An opacity logit of +inf is a
    fully opaque Gaussian and −inf a fully transparent one (splat-transform writes the logit of an
    8-bit opacity of 255 as +inf); Gaussians with a NaN in any property, or an infinite position,
    colour, scale or rotation, are dropped with one :class:`DofviewWarning` that counts them (all
    of them: a DofviewError).
    ``progress(done, total)`` is called as Gaussians are activated.

    Raises:
        DofviewError: the file is missing, unreadable, not a 3DGS PLY, or cut short.
    """
    path = Path(path)
    size, fmt, elements, comments, header_len = read_header(path)
    if any(e.name == "chunk" for e in elements):  # a PlayCanvas compressed PLY, whatever its name
        from dofview.io.compressed_ply import read_compressed_ply

        return read_compressed_ply(path, progress)
    vertex = _check_vertex(path, elements)
    _check_body_size(path, fmt, elements, vertex, size - header_len)
    rows = None
    if fmt != "ascii":
        rows = _binary_columns(path, fmt, elements, vertex, header_len)
    if rows is None:
        rows = _plyfile_rows(path)
    colour_space = "srgb"
    for c in comments:
        m = _COLOUR_COMMENT.match(c)
        if m and m.group(1) in COLOUR_SPACES:
            colour_space = m.group(1)
    return _activate(path, rows, colour_space, progress)


def _activate(path: Path, rows: np.ndarray, colour_space: str,
              progress: Callable[[int, int], None] | None) -> GaussianScene:
    n = rows.shape[0]
    n_rest = sum(1 for name in rows.dtype.names if name.startswith("f_rest_"))
    degree = REST_COUNTS[n_rest]
    k1 = n_rest // 3
    means = np.empty((n, 3), np.float32)
    sh_dc = np.empty((n, 3), np.float32)
    scales = np.empty((n, 3), np.float32)
    quats = np.empty((n, 4), np.float32)
    logits = np.empty(n, np.float32)
    rest = np.empty((n, k1, 3), np.float32) if degree else None
    finite = np.ones(n, bool)
    for s in range(0, n, CHUNK):
        e = min(s + CHUNK, n)
        r = rows[s:e]
        for i, a in enumerate("xyz"):
            means[s:e, i] = r[a]
        for i in range(3):
            sh_dc[s:e, i] = r[f"f_dc_{i}"]
            scales[s:e, i] = r[f"scale_{i}"]
        for i in range(4):
            quats[s:e, i] = r[f"rot_{i}"]
        logits[s:e] = r["opacity"]
        if rest is not None:
            for c in range(3):  # channel-major in the file: f_rest[c·(K−1) + j] is (j, c)
                for j in range(k1):
                    rest[s:e, j, c] = r[f"f_rest_{c * k1 + j}"]
        ok = (np.isfinite(means[s:e]).all(1) & np.isfinite(sh_dc[s:e]).all(1) & np.isfinite(scales[s:e]).all(1)
              & np.isfinite(quats[s:e]).all(1) & ~np.isnan(logits[s:e]))  # ±inf: sigmoid's limits 1 and 0
        if rest is not None:
            ok &= np.isfinite(rest[s:e]).all((1, 2))
        finite[s:e] = ok
        if _DROP_PAGES and isinstance(rows.base, mmap.mmap):  # drop the pages read from our resident
            rows.base.madvise(mmap.MADV_DONTNEED)  # set (issue 7: load peak ≤ 2× file); page cache keeps them
        if progress:
            progress(e, n)
    np.exp(np.clip(scales, -LOG_SCALE_LIMIT, LOG_SCALE_LIMIT, out=scales), out=scales)
    opacities = (1.0 / (1.0 + np.exp(-np.clip(logits, -LOG_SCALE_LIMIT, LOG_SCALE_LIMIT)))).astype(np.float32)
    opacities[np.isneginf(logits)] = 0.0  # exactly transparent (the clip alone leaves 1.6e-38)
    norm = np.linalg.norm(quats.astype(np.float64), axis=1)
    good_q = norm > 1e-30
    quats[good_q] = (quats[good_q] / norm[good_q, None]).astype(np.float32)
    quats[~good_q] = (1.0, 0.0, 0.0, 0.0)
    report_dropped(path, finite)
    if not finite.all():
        keep = finite
        means, quats, scales, opacities, sh_dc = means[keep], quats[keep], scales[keep], opacities[keep], sh_dc[keep]
        rest = None if rest is None else rest[keep]
    return GaussianScene(means=means, quats=quats, scales=scales, opacities=opacities, sh_dc=sh_dc,
                         sh_rest=rest, colour_space=colour_space, name=path.stem)


def ply_dtype(degree: int) -> np.dtype:
    """The little-endian float32 vertex layout the reference 3DGS code writes for ``degree``."""
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
    names += [f"f_rest_{i}" for i in range(3 * ((degree + 1) ** 2 - 1))]
    names += ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    return np.dtype([(n, "<f4") for n in names])


def scene_rows(scene: GaussianScene) -> np.ndarray:
    """(N,) structured float32 rows of ``scene`` in the stored (pre-activation) form."""
    dtype = ply_dtype(scene.sh_degree)
    rows = np.zeros(scene.count, dtype)
    for i, a in enumerate("xyz"):
        rows[a] = scene.means[:, i]
    for i in range(3):
        rows[f"f_dc_{i}"] = scene.sh_dc[:, i]
        rows[f"scale_{i}"] = np.log(np.maximum(scene.scales[:, i].astype(np.float64), 1e-38))
    if scene.sh_rest is not None:
        k1 = scene.sh_rest.shape[1]
        for c in range(3):
            for j in range(k1):
                rows[f"f_rest_{c * k1 + j}"] = scene.sh_rest[:, j, c]
    o = np.clip(scene.opacities.astype(np.float64), 1e-12, 1.0 - 1e-7)
    rows["opacity"] = np.log(o) - np.log1p(-o)
    for i in range(4):
        rows[f"rot_{i}"] = scene.quats[:, i]
    return rows


def write_ply(scene: GaussianScene, path: str | Path) -> None:
    """Write ``scene`` as a binary little-endian 3DGS ``.ply`` (whole or not at all)."""
    from dofview.io.atomic import atomic_output

    rows = scene_rows(scene)
    header = ["ply", "format binary_little_endian 1.0", f"comment dofview colour_space {scene.colour_space}",
              f"element vertex {scene.count}"]
    header += [f"property float {n}" for n in rows.dtype.names]
    header.append("end_header")
    with atomic_output(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(("\n".join(header) + "\n").encode("ascii"))
            f.write(rows.tobytes())
