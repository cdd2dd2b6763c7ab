"""8-bit RGB(A) PNG files, written with the standard library (zlib) and read back for tests."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

from dofview.errors import DofviewError
from dofview.io.atomic import atomic_output


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def encode_png(image: np.ndarray) -> bytes:
    """(H, W, 3|4) uint8 → PNG bytes."""
    image = np.ascontiguousarray(image, dtype=np.uint8)
    if image.ndim != 3 or image.shape[2] not in (3, 4):
        raise ValueError(f"image must be (H, W, 3|4) uint8, got {image.shape}")
    h, w, c = image.shape
    raw = np.concatenate([np.zeros((h, 1), np.uint8), image.reshape(h, w * c)], axis=1).tobytes()
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2 if c == 3 else 6, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr) + _chunk(b"IDAT", zlib.compress(raw, 6)) + _chunk(b"IEND", b"")


def write_png(path: str | Path, image: np.ndarray) -> None:
    """Write a (H, W, 3|4) uint8 image as PNG (whole or not at all)."""
    data = encode_png(image)
    with atomic_output(path) as tmp:
        Path(tmp).write_bytes(data)


def read_png(path: str | Path) -> np.ndarray:
    """(H, W, 3|4) uint8 from an 8-bit RGB/RGBA PNG with unfiltered rows, as :func:`write_png` makes."""
    data = Path(path).read_bytes()
    if not data.startswith(b"\x89PNG\r\n\x1a\n"):
        raise DofviewError(f"{path}: not a PNG file")
    pos, idat, w = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, ctype, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if depth != 8 or ctype not in (2, 6) or interlace:
                raise DofviewError(f"{path}: only 8-bit RGB/RGBA non-interlaced PNGs are read")
            c = 3 if ctype == 2 else 4
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    if w is None:
        raise DofviewError(f"{path}: PNG has no header")
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(h, 1 + w * c)
    if np.any(raw[:, 0] != 0):
        raise DofviewError(f"{path}: only unfiltered PNG rows are read (as write_png makes them)")
    return raw[:, 1:].reshape(h, w, c).copy()
