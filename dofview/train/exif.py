"""The few EXIF tags a training photo needs: exposure time, f-number, focal length, focus distance.

Read from JPEG (APP1 "Exif") and PNG (``eXIf`` chunk) files, written into PNG ``eXIf`` chunks.
Only the TIFF structure those tags need is handled: IFD0 → Exif sub-IFD, RATIONAL values, either
byte order. Tags (Exif 2.3): ExposureTime 0x829A (s), FNumber 0x829D, FocalLength 0x920A (mm),
SubjectDistance 0x9206 (m, used as the focus distance).
"""

from __future__ import annotations

import struct
from fractions import Fraction
from pathlib import Path

import numpy as np

from dofview.errors import DofviewError
from dofview.io.atomic import atomic_output
from dofview.io.png import _chunk, encode_png

TAGS = {"exposure_time": 0x829A, "f_number": 0x829D, "focal_length_mm": 0x920A, "subject_distance_m": 0x9206}
_EXIF_IFD = 0x8769
_RATIONAL = 5


def _rational(value: float) -> tuple[int, int]:
    f = Fraction(value).limit_denominator(1_000_000)
    while f.numerator >= 2 ** 32:  # keep both terms in 32 bits, losing precision only then
        f = Fraction(round(f.numerator / 2), max(f.denominator // 2, 1))
    return f.numerator, f.denominator


def encode_exif(values: dict[str, float]) -> bytes:
    """TIFF-structured EXIF bytes (big-endian) holding ``values`` keyed as in :data:`TAGS`."""
    entries = sorted((TAGS[k], _rational(v)) for k, v in values.items())
    ifd0_at = 8
    exif_at = ifd0_at + 2 + 12 + 4
    data_at = exif_at + 2 + 12 * len(entries) + 4
    out = b"MM\x00\x2a" + struct.pack(">I", ifd0_at)
    out += struct.pack(">H", 1) + struct.pack(">HHII", _EXIF_IFD, 4, 1, exif_at) + struct.pack(">I", 0)
    out += struct.pack(">H", len(entries))
    for i, (tag, _) in enumerate(entries):
        out += struct.pack(">HHII", tag, _RATIONAL, 1, data_at + 8 * i)
    out += struct.pack(">I", 0)
    for _, (num, den) in entries:
        out += struct.pack(">II", num, den)
    return out


def write_png_exif(path: str | Path, image: np.ndarray, values: dict[str, float]) -> None:
    """Write a (H, W, 3|4) uint8 PNG carrying ``values`` in an ``eXIf`` chunk (whole or not at all)."""
    png = encode_png(image)
    iend = len(png) - 12  # the IEND chunk is the last 12 bytes
    data = png[:iend] + _chunk(b"eXIf", encode_exif(values)) + png[iend:]
    with atomic_output(path) as tmp:
        Path(tmp).write_bytes(data)


def _tiff_blob(path: Path, data: bytes) -> bytes | None:
    """The TIFF-structured EXIF bytes of a PNG or JPEG file, or None when it has none."""
    if data.startswith(b"\x89PNG\r\n\x1a\n"):
        pos = 8
        while pos + 8 <= len(data):
            n, kind = struct.unpack(">I4s", data[pos:pos + 8])
            if kind == b"eXIf":
                return data[pos + 8:pos + 8 + n]
            pos += 12 + n
        return None
    if data.startswith(b"\xff\xd8"):
        pos = 2
        while pos + 4 <= len(data) and data[pos] == 0xFF:
            marker, n = data[pos + 1], struct.unpack(">H", data[pos + 2:pos + 4])[0]
            if marker == 0xE1 and data[pos + 4:pos + 10] == b"Exif\x00\x00":
                return data[pos + 10:pos + 2 + n]
            if marker == 0xDA:  # start of scan: no metadata after this
                return None
            pos += 2 + n
        return None
    raise DofviewError(f"{path}: not a PNG or JPEG file")


def read_exif(path: str | Path) -> dict[str, float]:
    """The :data:`TAGS` present in the file's EXIF (missing tags are simply absent)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as e:
        raise DofviewError(f"{path}: cannot read ({e.strerror or e})") from None
    blob = _tiff_blob(path, data)
    if blob is None:
        return {}
    try:
        return _parse_tiff(blob)
    except (struct.error, IndexError, ZeroDivisionError) as e:
        raise DofviewError(f"{path}: malformed EXIF block ({e})") from None


def _parse_tiff(blob: bytes) -> dict[str, float]:
    order = {b"II": "<", b"MM": ">"}.get(blob[:2])
    if order is None:
        raise struct.error("bad byte-order mark")

    def ifd(offset: int) -> dict[int, tuple[int, int, int]]:
        n = struct.unpack(order + "H", blob[offset:offset + 2])[0]
        entries = {}
        for i in range(n):
            tag, kind, count, value = struct.unpack(order + "HHII", blob[offset + 2 + 12 * i:offset + 14 + 12 * i])
            entries[tag] = (kind, count, value)
        return entries

    top = ifd(struct.unpack(order + "I", blob[4:8])[0])
    entries = dict(top)
    if _EXIF_IFD in top:
        entries.update(ifd(top[_EXIF_IFD][2]))
    out = {}
    for name, tag in TAGS.items():
        if tag in entries and entries[tag][0] == _RATIONAL:
            num, den = struct.unpack(order + "II", blob[entries[tag][2]:entries[tag][2] + 8])
            if den:
                out[name] = num / den
    return out
