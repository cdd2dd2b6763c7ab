"""OpenEXR images: linear R, G, B, A (premultiplied) and Z (camera depth) with dofview's metadata,
the camera as OpenEXR's standard attributes, and deep scanline images (per pixel, a list of samples
with R, G, B, A, Z and ZBack).

Flat images go through the OpenEXR library. Deep images are written here, straight from flat
sample arrays, following the OpenEXR 2 file layout (openexr.com, "OpenEXR File Layout": a
single-part deep scanline file, one scan line per chunk, ZIPS compression): the library's Python
binding takes a deep image only as one numpy array per pixel and channel, too slow to build for
millions of pixels; the files are read back by the library in the tests. Every file is written
through a temporary file (see atomic.py), so a failure never leaves half an image.
"""

from __future__ import annotations

import os
import struct
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import OpenEXR

from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.io.atomic import atomic_output
from dofview.lens import PhysicalLens

HALF_MAX = 65504.0
# Intel ISA-L's deflate (the optional `deep` extra): the same zlib stream, deep files written ~4× faster
try:
    from isal.isal_zlib import compress as _deflate

    ZIP_LEVEL = 1  # ISA-L levels run 0–3
except ImportError:  # pragma: no cover - depends on the installation
    from zlib import compress as _deflate

    ZIP_LEVEL = 4  # the OpenEXR library's default for ZIP(S)


def write_exr(path: str | Path, rgba: np.ndarray, depth: np.ndarray | None = None, half: bool = False,
              header: dict[str, object] | None = None) -> None:
    """Write an EXR with channels R, G, B, A (and Z when ``depth`` is given).

    Args:
        rgba: (H, W, 4) float linear RGB premultiplied by A.
        depth: (H, W) float camera z, scene units (0 where nothing was drawn); always float32.
        half: store R, G, B, A as half floats (values beyond ±65504 are clipped to it, not inf).
        header: extra attributes stored in the file's header: str, int and float values as such,
            (4, 4) float arrays as M44f and (2,) float arrays as V2f (see :func:`camera_attributes`);
            anything else as its text.
    """
    rgba = np.asarray(rgba)
    if rgba.ndim != 3 or rgba.shape[2] != 4:
        raise ValueError(f"rgba must be (H, W, 4), got {rgba.shape}")
    if half:
        colour = np.clip(np.nan_to_num(rgba, nan=0.0), -HALF_MAX, HALF_MAX).astype(np.float16)
    else:
        colour = np.nan_to_num(rgba.astype(np.float32), nan=0.0, posinf=np.finfo(np.float32).max)
    channels = {c: np.ascontiguousarray(colour[..., i]) for i, c in enumerate("RGBA")}
    if depth is not None:
        channels["Z"] = np.ascontiguousarray(np.asarray(depth, np.float32))
    hdr: dict[str, object] = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    hdr.update({k: _attribute(v) for k, v in (header or {}).items()})
    with atomic_output(path) as tmp:
        try:
            with OpenEXR.File(hdr, channels) as f:
                f.write(str(tmp))
        except RuntimeError as e:  # OpenEXR reports I/O failures (a full disk) as RuntimeError
            reason = str(e).rsplit('". ', 1)[-1].rstrip(".")  # the OS's reason, after the temp file's name
            raise DofviewError(f"{path}: cannot write EXR ({reason}); nothing was written") from None


def _attribute(value: object) -> object:
    """A header value as the OpenEXR binding stores it: str, int, float, float32 matrices and vectors."""
    if isinstance(value, np.ndarray) and value.shape in ((4, 4), (2,)):
        return np.ascontiguousarray(value, np.float32)
    if isinstance(value, (str, int, float)):
        return value
    return str(value)


def read_exr(path: str | Path) -> tuple[dict[str, np.ndarray], dict[str, object]]:
    """(channels by name as (H, W) arrays, header attributes) of an EXR file."""
    path = Path(path)
    if not path.is_file():
        raise DofviewError(f"{path}: no such EXR file")
    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            channels = {name: np.array(ch.pixels) for name, ch in f.channels().items()}
            return channels, dict(f.header())
    except Exception as e:  # OpenEXR raises plain exceptions for unreadable files
        raise DofviewError(f"{path}: not a readable EXR file ({e})") from None


def read_exr_header(path: str | Path) -> dict[str, object]:
    """The header attributes of an EXR file, flat or deep, without reading its pixels."""
    path = Path(path)
    if not path.is_file():
        raise DofviewError(f"{path}: no such EXR file")
    try:
        with OpenEXR.File(str(path), header_only=True) as f:
            return dict(f.header())
    except Exception as e:
        raise DofviewError(f"{path}: not a readable EXR file ({e})") from None


# ---- the camera as OpenEXR's standard attributes ---------------------------------------------------
def camera_attributes(camera: Camera, near: float, focus: float | None = None,
                      physical: PhysicalLens | None = None) -> dict[str, object]:
    """OpenEXR's standard optional attributes for the view (openexr.com, "Standard Attributes"):

    - ``worldToCamera`` (M44f): world → the camera space of RenderMan and OpenEXR, left-handed:
      x right, y **up** in the image, z the viewing direction (points in front have z > 0), in
      scene units. dofview's own camera is OpenCV's (y down): this is its rotation and translation
      with y negated.
    - ``worldToNDC`` (M44f): world → normalised device coordinates: x right and y down over the
      display window, (0, 0) its top-left corner and (1, 1) its bottom-right one, so pixel
      (i, j)'s centre is at ((i + ½)/W, (j + ½)/H); NDC z = 1 − near/z (0 on the near plane,
      towards 1 far away), which the standard leaves to the renderer.

    Both matrices are in OpenEXR's (Imath's) row-vector convention: a world point is the row
    [x, y, z, 1], multiplied on the left, p·M, then divided by its w (1 for worldToCamera, the
    camera z for worldToNDC). With a physical lens (``physical``), also ``focus`` (the focus
    distance in metres: ``focus`` scene units over units per metre; inf for infinity), ``aperture``
    (the f-number), ``nominalFocalLength`` (the lens's focal length that sets the depth of field,
    mm), ``pinholeFocalLength`` (the camera's, f_x × sensor width / image width, mm) and
    ``sensorOverallDimensions`` (the sensor width and the height of the same aspect as the image,
    mm). Arrays are float32, as the file stores them.
    """
    flip = np.diag([1.0, -1.0, 1.0])
    rot, trans = flip @ camera.R, flip @ camera.T  # OpenCV → RenderMan camera axes
    to_camera = np.eye(4)
    to_camera[:3, :3] = rot.T  # row vectors: p_cam = p_world · Rᵀ + T
    to_camera[3, :3] = trans
    w, h = camera.width, camera.height
    # camera (x, y up, z) row → (x·fx + cx·z)/W, (−y·fy + cy·z)/H, z − near, w = z
    project = np.array([[camera.fx / w, 0.0, 0.0, 0.0],
                        [0.0, -camera.fy / h, 0.0, 0.0],
                        [camera.cx / w, camera.cy / h, 1.0, 1.0],
                        [0.0, 0.0, -near, 0.0]])
    attrs: dict[str, object] = {"worldToCamera": to_camera.astype(np.float32),
                                "worldToNDC": (to_camera @ project).astype(np.float32)}
    if physical is not None:
        if focus is not None:
            attrs["focus"] = float(focus) / physical.units_per_metre
        attrs["aperture"] = float(physical.fnumber)
        attrs["nominalFocalLength"] = float(physical.focal_mm)
        attrs["pinholeFocalLength"] = float(camera.fx * physical.sensor_mm / w)
        attrs["sensorOverallDimensions"] = np.array([physical.sensor_mm, physical.sensor_mm * h * camera.fx
                                                     / (w * camera.fy)], np.float32)
    return attrs


# ---- deep scanline images ----------------------------------------------------------------------------
_COMPRESSION_ZIPS = 2
_FLOAT = 2  # the pixel type of a float32 channel
_DEEP_FLAG, _LONG_NAMES_FLAG = 0x800, 0x400


def write_deep_exr(path: str | Path, counts: np.ndarray, channels: dict[str, np.ndarray],
                   header: dict[str, object] | None = None) -> None:
    """Write a single-part deep scanline OpenEXR file (ZIPS: one zlib-compressed scan line a chunk).

    Args:
        counts: (H, W) integers ≥ 0, the samples of each pixel (rows top to bottom).
        channels: name → (S,) float32 per-sample values, S = counts.sum(), pixel by pixel (rows
            top to bottom, left to right) and within a pixel in the order the samples are stored
            (dofview: front to back).
        header: extra attributes, as for :func:`write_exr`.

    Raises:
        DofviewError: the file cannot be written (nothing is left behind).
        ValueError: arrays of the wrong shape.
    """
    counts = np.asarray(counts)
    if counts.ndim != 2 or (counts.size and counts.min() < 0):
        raise ValueError(f"counts must be (H, W) ≥ 0, got shape {counts.shape}")
    total = int(counts.sum())
    names = sorted(channels)  # the file stores channels in alphabetical order
    data = {n: np.ascontiguousarray(channels[n], np.float32).ravel() for n in names}
    if any(a.size != total for a in data.values()):
        raise ValueError(f"every channel must hold the {total} samples of counts")
    h, w = counts.shape
    ends = np.cumsum(counts.reshape(h, w), axis=1, dtype=np.int64)  # per row, inclusive: the pixel offset table
    row_start = np.concatenate([[0], np.cumsum(ends[:, -1] if w else np.zeros(h, np.int64))])
    attrs: list[tuple[str, str, bytes]] = [
        ("channels", "chlist", b"".join(n.encode() + b"\0" + struct.pack("<iB3xii", _FLOAT, 0, 1, 1) for n in names)
         + b"\0"),
        ("compression", "compression", bytes([_COMPRESSION_ZIPS])),
        ("dataWindow", "box2i", struct.pack("<4i", 0, 0, w - 1, h - 1)),
        ("displayWindow", "box2i", struct.pack("<4i", 0, 0, w - 1, h - 1)),
        ("lineOrder", "lineOrder", b"\0"),
        ("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
        ("screenWindowCenter", "v2f", struct.pack("<2f", 0.0, 0.0)),
        ("screenWindowWidth", "float", struct.pack("<f", 1.0)),
        ("type", "string", b"deepscanline"),
        ("version", "int", struct.pack("<i", 1)),
        ("chunkCount", "int", struct.pack("<i", h)),
        ("maxSamplesPerPixel", "int", struct.pack("<i", int(counts.max()) if counts.size else 0)),
    ]
    attrs += [(k, *_encode_attribute(k, v)) for k, v in (header or {}).items()]
    long_names = any(len(name) > 31 or len(kind) > 31 for name, kind, _ in attrs)
    head = struct.pack("<ii", 20000630, 2 | _DEEP_FLAG | (_LONG_NAMES_FLAG if long_names else 0))
    head += b"".join(name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value
                     for name, kind, value in attrs) + b"\0"

    def chunk(y: int) -> bytes:
        table = _zips(ends[y].astype("<i4").tobytes())
        lo, hi = row_start[y], row_start[y + 1]
        raw = b"".join(data[n][lo:hi].astype("<f4", copy=False).tobytes() for n in names)
        packed = _zips(raw)
        return struct.pack("<iQQQ", y, len(table), len(packed), len(raw)) + table + packed

    with ThreadPoolExecutor(os.cpu_count()) as pool:  # deflate lets go of the GIL: lines compress in parallel
        chunks = list(pool.map(chunk, range(h)))
    first = len(head) + 8 * h
    offsets = first + np.concatenate([[0], np.cumsum([len(c) for c in chunks[:-1]], dtype=np.int64)]) if h else []
    with atomic_output(path) as tmp:
        try:
            with open(tmp, "wb") as f:
                f.write(head)
                f.write(np.asarray(offsets, "<u8").tobytes())
                for c in chunks:
                    f.write(c)
        except OSError as e:
            raise DofviewError(f"{path}: cannot write EXR ({e.strerror or e}); nothing was written") from None


def _zips(raw: bytes) -> bytes:
    """One chunk's bytes as OpenEXR's ZIP compressors store them: the even bytes then the odd ones,
    each byte replaced by its difference to the one before (+128, modulo 256), as a zlib stream
    (ISA-L's where installed: docs/BENCHMARKS.md, "Deep output", measured whole writes 4× faster
    than with zlib's); the raw bytes themselves when that is no smaller (the reader tells them by
    their size)."""
    if not raw:
        return raw
    b = np.frombuffer(raw, np.uint8)
    split = np.concatenate([b[0::2], b[1::2]])
    split[1:] = np.diff(split) + np.uint8(128)  # uint8 arithmetic wraps modulo 256
    packed = _deflate(split.tobytes(), ZIP_LEVEL)
    return packed if len(packed) < len(raw) else raw


def _encode_attribute(name: str, value: object) -> tuple[str, bytes]:
    """(OpenEXR type name, value bytes) of a header value, stored as :func:`write_exr` stores it."""
    if isinstance(value, np.ndarray) and value.shape == (4, 4):
        return "m44f", np.asarray(value, "<f4").tobytes()
    if isinstance(value, np.ndarray) and value.shape == (2,):
        return "v2f", np.asarray(value, "<f4").tobytes()
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return "string", str(value).encode()
    if isinstance(value, int):
        if not -2**31 <= value < 2**31:
            raise ValueError(f"header {name}: {value} does not fit an EXR int")
        return "int", struct.pack("<i", value)
    return "float", struct.pack("<f", value)


def read_deep_exr(path: str | Path) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, object]]:
    """(counts (H, W) int64, channels by name as (S,) arrays in pixel order, header attributes)
    of a deep scanline EXR, read by the OpenEXR library (slow for large images: it hands each
    pixel over as its own array)."""
    path = Path(path)
    if not path.is_file():
        raise DofviewError(f"{path}: no such EXR file")
    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            header = dict(f.header())
            if header.get("type") != OpenEXR.deepscanline:
                raise DofviewError(f"{path}: not a deep scanline EXR")
            pixels = {name: ch.pixels for name, ch in f.channels().items()}
    except DofviewError:
        raise
    except Exception as e:
        raise DofviewError(f"{path}: not a readable EXR file ({e})") from None
    any_channel = next(iter(pixels.values()))
    counts = np.array([[0 if p is None else len(p) for p in row] for row in any_channel], np.int64)
    flat = {}
    for name, per_pixel in pixels.items():
        parts = [p for p in per_pixel.ravel() if p is not None]
        flat[name] = np.concatenate(parts) if parts else np.zeros(0, np.float32)
    return counts, flat, header
