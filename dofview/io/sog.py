"""PlayCanvas SOG ("spatially ordered Gaussians", the layout of PlayCanvas splat-transform's
write-sog and read-sog): a ``meta.json`` and lossless WebP images, either bundled in one zip file
(``.sog``) or loose in a folder (open the folder or its ``meta.json``). Gaussian i is pixel i of
every per-Gaussian image, in row-major order. Data is in PLY axes, as dofview's.

Version 2 (``"version": 2``; the current one):

- ``means``: two RGB images, the low and high bytes of 16-bit x, y, z, each a fraction of
  ``mins…maxs`` of ``sign(v)·ln(|v| + 1)`` (a log transform that spends bits near the origin);
- ``quats``: RGBA: three components of the unit quaternion (w, x, y, z) other than the largest, as
  ``(q·√2·0.5 + 0.5)·255``, in index order, and A = 252 + the index of the dropped largest
  (made positive);
- ``scales``: RGB indices into a 256-entry ``codebook`` of log scales;
- ``sh0``: RGB indices into a 256-entry ``codebook`` of SH DC terms, A = opacity·255;
- ``shN`` (optional): a palette of ``count`` SH vectors (``bands`` 1–3): ``shN_labels`` holds a
  16-bit palette index per Gaussian (R low byte, G high byte); ``shN_centroids`` holds palette
  entry p's coefficient j at pixel (x = (p mod 64)·K + j, y = p div 64) for K coefficients per
  channel, its R, G, B indexing a 256-entry ``codebook``.

Version 1 (no ``version`` key) differs in its dequantisation: ``means.shape[0]`` is the count,
scales and sh0 (with the opacity logit as a fourth channel) are per-channel ``mins…maxs`` ranges
of 8-bit values, and shN is one scalar ``mins…maxs`` range; the palette layout is the same.
"""

from __future__ import annotations

import io
import json
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from dofview.errors import SceneFormatError
from dofview.io._common import input_size
from dofview.io._packed import (
    LOG_SCALE_LIMIT,
    quats_from_smallest_three,
    scene_from_arrays,
)
from dofview.scene import GaussianScene

META = "meta.json"
MAX_META = 64 << 20  # bytes: meta.json holds only codebooks (a few kB)
SH_COUNTS = {1: 3, 2: 8, 3: 15}
PALETTE_ROW = 64  # palette entries per row of shN_centroids
SPARE_PIXELS = 1 << 16  # images are padded to multiples of 4 pixels; anything far larger is corrupt


class _Files:
    """The files of one SOG: members of a zip, or files beside meta.json."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.zip: zipfile.ZipFile | None = None
        if path.is_dir():
            self.folder = path
        elif path.name.lower() == META:
            self.folder = path.parent
        else:
            input_size(path)
            try:
                self.zip = zipfile.ZipFile(path)
            except (zipfile.BadZipFile, OSError, ValueError, EOFError) as e:
                raise SceneFormatError(f"{path}: not a SOG bundle (not a readable zip file: {e})") from None

    def read(self, name: str, limit: int) -> bytes:
        """The bytes of ``name``, refused when larger than ``limit``."""
        if not isinstance(name, str) or not name or Path(name).is_absolute() or ".." in Path(name).parts:
            raise SceneFormatError(f"{self.path}: bad file name {name!r} in meta.json")
        try:
            if self.zip is not None:
                info = self.zip.getinfo(name)
                if info.file_size > limit:
                    raise SceneFormatError(f"{self.path}: {name} is {info.file_size} bytes, too large for a SOG member")
                return self.zip.read(info)
            member = self.folder / name
            if member.stat().st_size > limit:
                raise SceneFormatError(f"{self.path}: {name} is too large for a SOG file")
            return member.read_bytes()
        except KeyError:
            raise SceneFormatError(f"{self.path}: SOG bundle has no {name}") from None
        except FileNotFoundError:
            raise SceneFormatError(f"{self.path}: SOG file {self.folder / name} is missing") from None
        except (zipfile.BadZipFile, OSError, ValueError, EOFError, RuntimeError) as e:
            raise SceneFormatError(f"{self.path}: cannot read {name} from the SOG ({e})") from None

    def close(self) -> None:
        if self.zip is not None:
            self.zip.close()


def _field(path: Path, meta: dict, *keys: str, kind=dict):
    """meta[k0][k1]…, checked to exist and be of ``kind``."""
    v = meta
    for k in keys:
        if not isinstance(v, dict) or k not in v:
            raise SceneFormatError(f"{path}: meta.json has no {'.'.join(keys)}")
        v = v[k]
    if kind is float:
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
    elif kind is int:
        ok = isinstance(v, int) and not isinstance(v, bool)
    else:
        ok = isinstance(v, kind)
    if not ok:
        raise SceneFormatError(f"{path}: meta.json {'.'.join(keys)} is not {kind.__name__}")
    return v


def _numbers(path: Path, meta: dict, *keys: str, length: int | None = None) -> np.ndarray:
    v = _field(path, meta, *keys, kind=list)
    if (length is not None and len(v) != length) or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
        want = f"{length} numbers" if length is not None else "numbers"
        raise SceneFormatError(f"{path}: meta.json {'.'.join(keys)} must be a list of {want}")
    return np.asarray(v, np.float64)


def _image(files: _Files, meta: dict, key: str, index: int, min_pixels: int, max_pixels: int) -> np.ndarray:
    """(H, W, 4) uint8 RGBA pixels of ``meta[key].files[index]``, size checked before decoding."""
    from PIL import Image

    names = _field(files.path, meta, key, "files", kind=list)
    if len(names) <= index:
        raise SceneFormatError(f"{files.path}: meta.json {key}.files lists {len(names)} files, needs {index + 1}")
    name = names[index]
    data = files.read(name, max(4 * max_pixels, 1 << 20) + (1 << 20))
    try:
        with Image.open(io.BytesIO(data), formats=["WEBP"]) as im:
            w, h = im.size
            if w * h < min_pixels or w * h > max_pixels:
                raise SceneFormatError(f"{files.path}: {name} is {w}×{h} pixels; the SOG needs "
                                       f"{min_pixels}{'' if max_pixels == min_pixels else f'…{max_pixels}'}")
            return np.asarray(im.convert("RGBA"))
    except SceneFormatError:
        raise
    except (OSError, ValueError, SyntaxError, Image.DecompressionBombError) as e:
        raise SceneFormatError(f"{files.path}: {name} is not a readable WebP image ({e})") from None


def _pixels(files: _Files, meta: dict, key: str, index: int, count: int) -> np.ndarray:
    """(count, 4) uint8: the first ``count`` pixels of a per-Gaussian image, row-major."""
    return _image(files, meta, key, index, count, 2 * count + SPARE_PIXELS).reshape(-1, 4)[:count]


def _codebook(path: Path, meta: dict, key: str) -> np.ndarray:
    book = _numbers(path, meta, key, "codebook")
    if not 1 <= len(book) <= 256:
        raise SceneFormatError(f"{path}: meta.json {key}.codebook has {len(book)} entries (expected 1–256)")
    return np.concatenate([book, np.full(256 - len(book), np.nan)])  # a stray index decodes to NaN: dropped


def _inverse_log(v: np.ndarray) -> np.ndarray:
    return np.sign(v) * np.expm1(np.abs(v))


def _quats(q: np.ndarray) -> np.ndarray:
    tag = q[:, 3].astype(np.int64) - 252
    others = (q[:, :3].astype(np.float64) / 255.0 * 2.0 - 1.0) / np.sqrt(2.0)
    quats = quats_from_smallest_three(np.clip(tag, 0, 3), others)
    quats[(tag < 0) | (tag > 3)] = (1.0, 0.0, 0.0, 0.0)  # not a smallest-three tag: identity, as splat-transform
    return quats


def _sh_rest(files: _Files, meta: dict, count: int, version: int) -> np.ndarray | None:
    if "shN" not in meta:
        return None
    path = files.path
    labels_px = _pixels(files, meta, "shN", 1, count)
    labels = labels_px[:, 0].astype(np.int64) | (labels_px[:, 1].astype(np.int64) << 8)
    if version == 2:
        bands = _field(path, meta, "shN", "bands", kind=int)
        if bands not in SH_COUNTS:
            raise SceneFormatError(f"{path}: meta.json shN.bands is {bands} (expected 1–3)")
        k = SH_COUNTS[bands]
        palette = _field(path, meta, "shN", "count", kind=int)
        if not 1 <= palette <= 1 << 16:
            raise SceneFormatError(f"{path}: meta.json shN.count is {palette} (expected 1–65536)")
        cen = _image(files, meta, "shN", 0, 1, PALETTE_ROW * k * -(-palette // PALETTE_ROW))
        book = _codebook(path, meta, "shN")
        decode = book.__getitem__
    else:
        lo, hi = _field(path, meta, "shN", "mins", kind=float), _field(path, meta, "shN", "maxs", kind=float)
        cen = _image(files, meta, "shN", 0, 1, PALETTE_ROW * SH_COUNTS[3] * 1024)
        k = cen.shape[1] // PALETTE_ROW

        def decode(b: np.ndarray) -> np.ndarray:
            return lo + (hi - lo) * (b / 255.0)
    if cen.shape[1] != PALETTE_ROW * k or k not in SH_COUNTS.values():
        raise SceneFormatError(f"{path}: shN centroids image is {cen.shape[1]} pixels wide; "
                               f"expected {PALETTE_ROW} palette entries × 3, 8 or 15 coefficients")
    entries = cen.shape[0] * PALETTE_ROW
    if labels.max(initial=0) >= entries:
        raise SceneFormatError(f"{path}: shN labels point past the {entries} palette entries")
    # entry p, coefficient j sits at row p // 64, column (p % 64)·k + j: flat pixel p·k + j
    pix = labels[:, None] * k + np.arange(k)[None, :]
    return decode(cen.reshape(-1, 4)[pix, :3].astype(np.int64))  # R, G, B are the channels


def _open_meta(path: Path) -> tuple[_Files, dict]:
    files = _Files(path)
    try:
        text = files.read(META, MAX_META)
        meta = json.loads(text)
    except (UnicodeDecodeError, ValueError, RecursionError) as e:
        files.close()
        raise SceneFormatError(f"{path}: meta.json is not valid JSON ({e})") from None
    except SceneFormatError:
        files.close()
        raise
    if not isinstance(meta, dict):
        files.close()
        raise SceneFormatError(f"{path}: meta.json is not a JSON object")
    return files, meta


@dataclass
class SogArrays:
    """A SOG's Gaussians decoded, before any is dropped (shapes as :func:`scene_from_arrays` takes
    them): means (N, 3), quats (N, 4) w x y z, log-scales (N, 3), opacities (N,), SH DC (N, 3),
    SH rest (N, K−1, 3) or None, and the scene's name."""

    means: np.ndarray
    quats: np.ndarray
    log_scales: np.ndarray
    opacities: np.ndarray
    sh_dc: np.ndarray
    sh_rest: np.ndarray | None
    name: str

    @property
    def count(self) -> int:
        return int(self.means.shape[0])


def sog_header(path: str | Path) -> tuple[int, int]:
    """(Gaussians, SH degree) of a SOG from its meta.json alone (no image is decoded; a loose SOG's
    images must exist): what a streamed LOD set checks its chunks against. A version 1 SOG with an
    SH palette says no degree without its image: 3 is given (the most it can hold).

    Raises:
        SceneFormatError: as :func:`read_sog` for a missing file or a malformed meta.json.
    """
    path = Path(path)
    if not path.exists():
        raise SceneFormatError(f"{path}: no such file")
    files, meta = _open_meta(path)
    files.close()
    version, count = _version_count(path, meta)
    if files.zip is None:  # a loose SOG: its images are files beside meta.json
        for key in ("means", "quats", "scales", "sh0", *(("shN",) if "shN" in meta else ())):
            for name in _field(path, meta, key, "files", kind=list):
                if not isinstance(name, str) or not (files.folder / name).is_file():
                    raise SceneFormatError(f"{path}: SOG file {files.folder / str(name)} is missing")
    degree = 0 if "shN" not in meta else _field(path, meta, "shN", "bands", kind=int) if version == 2 else 3
    if degree not in (0, *SH_COUNTS):
        raise SceneFormatError(f"{path}: meta.json shN.bands is {degree} (expected 1–3)")
    return count, degree


def _version_count(path: Path, meta: dict) -> tuple[int, int]:
    """(SOG version, Gaussians) that meta.json gives, both checked."""
    version = meta.get("version", 1)
    if version not in (1, 2):
        raise SceneFormatError(f"{path}: unsupported SOG version {version!r} (dofview reads 1 and 2)")
    if version == 2:
        count = _field(path, meta, "count", kind=int)
    else:
        shape = _field(path, meta, "means", "shape", kind=list)
        count = shape[0] if shape and isinstance(shape[0], int) and not isinstance(shape[0], bool) else -1
    if count <= 0:
        raise SceneFormatError(f"{path}: meta.json gives {count} Gaussians")
    return version, count


def decode_sog(path: str | Path) -> SogArrays:
    """Every Gaussian of a SOG bundle, folder or meta.json, decoded (none dropped: see
    :func:`read_sog`). Versions 2 and 1.

    Raises:
        SceneFormatError: a missing member, a malformed meta.json, an unreadable or wrongly sized
            image.
    """
    path = Path(path)
    if not path.exists():
        raise SceneFormatError(f"{path}: no such file")
    files, meta = _open_meta(path)
    try:
        version, count = _version_count(path, meta)
        lo = _pixels(files, meta, "means", 0, count)[:, :3].astype(np.float64)
        hi = _pixels(files, meta, "means", 1, count)[:, :3].astype(np.float64)
        mins, maxs = _numbers(path, meta, "means", "mins", length=3), _numbers(path, meta, "means", "maxs", length=3)
        span = np.where(maxs - mins == 0.0, 1.0, maxs - mins)
        means = _inverse_log(mins + span * ((lo + 256.0 * hi) / 65535.0))
        quats = _quats(_pixels(files, meta, "quats", 0, count))
        s = _pixels(files, meta, "scales", 0, count)[:, :3]
        c = _pixels(files, meta, "sh0", 0, count)
        if version == 2:
            log_scales = _codebook(path, meta, "scales")[s]
            sh_dc = _codebook(path, meta, "sh0")[c[:, :3]]
            opacities = c[:, 3] / 255.0
        else:
            smin, smax = _numbers(path, meta, "scales", "mins", length=3), _numbers(path, meta, "scales", "maxs", length=3)
            log_scales = smin + (smax - smin) * (s / 255.0)
            cmin, cmax = _numbers(path, meta, "sh0", "mins", length=4), _numbers(path, meta, "sh0", "maxs", length=4)
            v = cmin + (cmax - cmin) * (c / 255.0)
            sh_dc, opacities = v[:, :3], 1.0 / (1.0 + np.exp(-np.clip(v[:, 3], -LOG_SCALE_LIMIT, LOG_SCALE_LIMIT)))
        sh_rest = _sh_rest(files, meta, count, version)
    finally:
        files.close()
    name = (path.parent if path.name.lower() == META else path).name.split(".")[0]
    return SogArrays(means, quats, log_scales, opacities, sh_dc, sh_rest, name)


def read_sog(path: str | Path, progress: Callable[[int, int], None] | None = None) -> GaussianScene:
    """Read a SOG bundle (``.sog`` zip), a folder holding ``meta.json``, or that ``meta.json``,
    into an sRGB :class:`GaussianScene` (:func:`decode_sog`; Gaussians with a non-finite value
    dropped with a warning). Versions 2 and 1.

    Raises:
        SceneFormatError: a missing member, a malformed meta.json, an unreadable or wrongly sized
            image.
    """
    path = Path(path)
    a = decode_sog(path)
    if progress:
        progress(a.count, a.count)
    return scene_from_arrays(path, a.means, a.quats, a.log_scales, a.opacities, a.sh_dc, a.sh_rest, name=a.name)
