"""Niantic ``.spz`` files (github.com/nianticlabs/spz, README and load-spz.cc): read versions 2–4,
write version 4.

Version 4 is a 32-byte little-endian header (magic "NGSP", version, point count, SH degree,
fractional bits, flags, stream count, table-of-contents offset, 12 reserved bytes), optional
extension records up to the table of contents, then one (compressed size, uncompressed size) u64
pair per stream and that many independent zstd streams. Versions 2–3 are a single gzip stream: a
16-byte header (the first 16 bytes above, the last byte reserved) followed by the same attribute
blocks back to back, then extension records. The attribute blocks, in order, per Gaussian:

- positions: 3 × 24-bit signed fixed point, ``fractionalBits`` fractional bits (9 B);
- alphas: opacity × 255 (1 B);
- colours: the SH DC term as ``dc·0.15·255 + 127.5`` (3 B; 0.15, not SH_C0, leaves head room);
- scales: natural-log standard deviation as ``(log s + 10)·16`` (3 B);
- rotations: version 2 stores x, y, z as ``q·127.5 + 127.5`` with w ≥ 0 implied (3 B); versions
  3+ the "smallest three" of (x, y, z, w): 2 bits for the index of the dropped largest component
  (made positive), then per other component a sign bit and 9 magnitude bits of ``|q|·√2``, the
  first component in the highest bits (4 B, a little-endian u32);
- SH: degree-1..4 coefficients as ``v·128 + 128``, coefficient-major with the colour channel
  fastest (the same order as dofview's ``sh_rest``). Degree 4 is dropped with a warning.

Extension records are (u32 type, u32 byte length, payload). The one that changes what the data
means is ``SPZ_ADOBE_coordinate_system`` (0xADBE0003, a u32 naming the axes the data is stored in);
others are skipped by length.

Axes: the spec stores data in RUB (x right, y up, z back, as OpenGL/three.js) unless that record
says otherwise; dofview (and PLY) uses RDF (x right, y down, z forward). Reading RUB data negates y
and z, which is the 180° rotation about x: positions (x, −y, −z), quaternions (w, x, −y, −z), and
each SH coefficient times the parity of its basis polynomial in y and z (see :data:`SH_PARITY`).
Some tools (PlayCanvas splat-transform) write ``.spz`` in PLY axes as they are, so the reader takes
``spz_axes="rdf"`` to read such a file unchanged.
"""

from __future__ import annotations

import struct
import warnings
import zlib
from pathlib import Path
from typing import Callable

import numpy as np

from dofview.errors import DofviewWarning, SceneFormatError
from dofview.io._common import input_size
from dofview.io._packed import (
    LOG_SCALE_LIMIT,
    quats_from_smallest_three,
    scene_from_arrays,
)
from dofview.scene import GaussianScene

MAGIC = 0x5053474E  # "NGSP" little endian
LATEST_VERSION = 4
HEADER_V4 = struct.Struct("<IIIBBBBI12x")  # 32 bytes
HEADER_LEGACY = struct.Struct("<IIIBBBx")  # 16 bytes
TOC_ENTRY = struct.Struct("<QQ")
EXTENSION = struct.Struct("<II")
FLAG_ANTIALIASED = 0x1
FLAG_EXTENSIONS = 0x2
EXT_COORDINATE_SYSTEM = 0xADBE0003
COLOUR_SCALE = 0.15
FRACTIONAL_BITS = 12  # what the reference writer uses: ~0.25 mm steps if a unit is a metre
MAX_RATIO = 1024  # uncompressed/compressed bound the reference reader uses to refuse lying counts
MAX_EXTENSION_BYTES = 1 << 20  # extension records after a legacy stream's attributes (a few bytes in practice)
SH_COUNTS = {0: 0, 1: 3, 2: 8, 3: 15, 4: 24}  # coefficients per channel beyond DC, by degree
SH1_BITS, SH_REST_BITS = 5, 4  # the reference writer's default SH precision (degree 1, degrees 2+)
ZSTD_LEVEL = 12
AXES = ("rub", "rdf")
"""Choices for ``spz_axes``: the axes the file's data is taken to be in ("rub" = the SPZ spec)."""

# The 16 systems of SPZ_ADOBE_coordinate_system, by value. Values 9–16 are the "rotated" family
# (y and z swapped by a 90° turn about x), which needs an SH rotation dofview does not do.
SYSTEMS = ("ldb", "rdb", "lub", "rub", "ldf", "rdf", "luf", "ruf",
           "lfd", "rfd", "lfu", "rfu", "lbd", "rbd", "lbu", "rbu")

# Parity (in x, y, z) of each real SH basis polynomial, degrees 1–3 in the 3DGS order: under a
# sign flip diag(sx, sy, sz) of the directions, coefficient k changes by sx^px·sy^py·sz^pz.
SH_PARITY = np.array([
    (0, 1, 0), (0, 0, 1), (1, 0, 0),                                   # y, z, x
    (1, 1, 0), (0, 1, 1), (0, 0, 0), (1, 0, 1), (0, 0, 0),             # xy, yz, 3z²−1, xz, x²−y²
    (0, 1, 0), (1, 1, 1), (0, 1, 0), (0, 0, 1), (1, 0, 0), (0, 0, 1), (1, 0, 0),
    # y(3x²−y²), xyz, y(4z²−x²−y²), z(2z²−3x²−3y²), x(4z²−x²−y²), z(x²−y²), x(x²−3y²)
])


def axis_signs(system: str) -> np.ndarray:
    """(3,) float64 ±1: the per-axis signs taking data stored in ``system`` (e.g. "rub") to RDF."""
    return np.array([1.0 if system[0] == "r" else -1.0, 1.0 if system[1] == "d" else -1.0,
                     1.0 if system[2] == "f" else -1.0])


def flip_axes(means: np.ndarray, quats_wxyz: np.ndarray, sh_rest: np.ndarray | None,
              signs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Apply the axis sign flip ``signs`` (3,) to positions (N, 3), rotations (N, 4) w, x, y, z and
    SH (N, K−1, 3); the flip is its own inverse. New arrays are returned."""
    sx, sy, sz = signs
    means = means * signs
    quats = quats_wxyz * np.array([1.0, sy * sz, sx * sz, sx * sy])  # the rotation S·R·S
    if sh_rest is not None:
        k = sh_rest.shape[1]
        sh_rest = sh_rest * np.prod(np.where(SH_PARITY[:k] == 1, signs, 1.0), axis=1)[None, :, None]
    return means, quats, sh_rest


# ---- reading ------------------------------------------------------------------------------------
def _read_file(path: Path) -> bytes:
    input_size(path)
    try:
        return path.read_bytes()
    except OSError as e:
        raise SceneFormatError(f"{path}: cannot read ({e.strerror or e})") from None


def _block_sizes(n: int, degree: int, version: int) -> list[int]:
    """Bytes of the six attribute blocks: positions, alphas, colours, scales, rotations, SH."""
    return [9 * n, n, 3 * n, 3 * n, (3 if version == 2 else 4) * n, 3 * SH_COUNTS[degree] * n]


def _check_header(path: Path, version: int, n: int, degree: int, frac: int, limit: int, size: int) -> None:
    """Refuse an unsupported header, or a count more than ``limit`` Gaussians (what ``size`` bytes
    of data can hold), before anything is allocated."""
    if version == 1:
        raise SceneFormatError(f"{path}: SPZ version 1 (float16 positions, never released) is not supported")
    if not 2 <= version <= LATEST_VERSION:
        raise SceneFormatError(f"{path}: unsupported SPZ version {version} (dofview reads 2–{LATEST_VERSION})")
    if degree not in SH_COUNTS:
        raise SceneFormatError(f"{path}: SPZ header gives SH degree {degree} (must be 0–4)")
    if frac > 23:
        raise SceneFormatError(f"{path}: SPZ header gives {frac} fractional bits for 24-bit positions")
    if n == 0:
        raise SceneFormatError(f"{path}: SPZ file holds no Gaussians")
    if n > limit:
        raise SceneFormatError(f"{path}: SPZ header announces {n} Gaussians, more than its {size} bytes of "
                               "data can hold (file cut short or corrupt)")


def _extensions(path: Path, data: bytes) -> dict[int, bytes]:
    """Extension records (type → payload) from a byte run that holds only whole records."""
    found, at = {}, 0
    while at < len(data):
        if at + EXTENSION.size > len(data):
            raise SceneFormatError(f"{path}: SPZ extension record cut short")
        kind, length = EXTENSION.unpack_from(data, at)
        at += EXTENSION.size
        if length > len(data) - at:
            raise SceneFormatError(f"{path}: SPZ extension record 0x{kind:08X} runs past its zone")
        found[kind] = data[at:at + length]
        at += length
    return found


def _zstd_stream(path: Path, chunk: bytes, expected: int, index: int) -> bytes:
    import zstandard

    try:
        # read at most one byte more than announced, so a stream that expands further is caught
        # without ever holding more than the (already size-checked) announced amount
        with zstandard.ZstdDecompressor().stream_reader(chunk) as reader:
            out = reader.read(expected + 1)
            while len(out) <= expected:
                more = reader.read(expected + 1 - len(out))
                if not more:
                    break
                out += more
    except zstandard.ZstdError as e:
        raise SceneFormatError(f"{path}: SPZ stream {index} is not valid zstd data ({e})") from None
    if len(out) != expected:
        raise SceneFormatError(f"{path}: SPZ stream {index} holds {'more' if len(out) > expected else len(out)} "
                               f"bytes where the header needs {expected}")
    return out


def _parse_v4(path: Path, data: bytes) -> tuple[int, int, int, int, int, list[bytes], dict[int, bytes]]:
    if len(data) < HEADER_V4.size:
        raise SceneFormatError(f"{path}: SPZ file cut short ({len(data)} bytes, the header alone is 32)")
    _, version, n, degree, frac, flags, streams, toc = HEADER_V4.unpack_from(data)
    _check_header(path, version, n, degree, frac, len(data) * MAX_RATIO // 9, len(data))
    if version < 4:
        raise SceneFormatError(f"{path}: SPZ version {version} must be gzip-compressed, not a plain NGSP file")
    sizes = [s for s in _block_sizes(n, degree, version) if s]
    if streams != len(sizes):
        raise SceneFormatError(f"{path}: SPZ header gives {streams} streams; SH degree {degree} needs {len(sizes)}")
    data_start = toc + streams * TOC_ENTRY.size
    if toc < HEADER_V4.size or data_start > len(data):
        raise SceneFormatError(f"{path}: SPZ table of contents at byte {toc} lies outside the file "
                               f"({len(data)} bytes; file cut short or corrupt)")
    extensions = _extensions(path, data[HEADER_V4.size:toc]) if flags & FLAG_EXTENSIONS else {}
    entries = [TOC_ENTRY.unpack_from(data, toc + i * TOC_ENTRY.size) for i in range(streams)]
    at, blocks = data_start, []
    for i, ((packed, unpacked), want) in enumerate(zip(entries, sizes)):
        if unpacked != want:
            raise SceneFormatError(f"{path}: SPZ stream {i} is {unpacked} bytes unpacked; "
                                   f"{n} Gaussians need {want}")
        if packed > len(data) - at:
            raise SceneFormatError(f"{path}: SPZ stream {i} runs past the end of the file (file cut short)")
        blocks.append(_zstd_stream(path, data[at:at + packed], want, i))
        at += packed
    if at != len(data):
        raise SceneFormatError(f"{path}: {len(data) - at} bytes follow the last SPZ stream (corrupt file)")
    if not SH_COUNTS[degree]:
        blocks.append(b"")
    return version, n, degree, frac, flags, blocks, extensions


def _gunzip(path: Path, data: bytes) -> bytes:
    """The legacy stream, inflated no further than its header allows (attribute blocks plus
    :data:`MAX_EXTENSION_BYTES`), so a lying header or a deflate bomb is refused, not allocated."""
    d = zlib.decompressobj(zlib.MAX_WBITS | 16)  # gzip framing, trailer CRC checked at the end
    try:
        raw = d.decompress(data, HEADER_LEGACY.size)
        while len(raw) < HEADER_LEGACY.size and d.unconsumed_tail and not d.eof:
            raw += d.decompress(d.unconsumed_tail, HEADER_LEGACY.size - len(raw))
        if len(raw) < HEADER_LEGACY.size:
            raise SceneFormatError(f"{path}: SPZ stream cut short ({len(raw)} bytes, the header alone is 16)")
        magic, version, n, degree, _, _ = HEADER_LEGACY.unpack(raw)
        if magic != MAGIC:
            raise SceneFormatError(f"{path}: gzip data is not an SPZ stream (no 'NGSP' header)")
        # deflate expands at most 1032:1: a count beyond that is refused before inflating further
        limit = len(data) * 1032 // 9
        if n > limit:
            raise SceneFormatError(f"{path}: SPZ header announces {n} Gaussians, more than its {len(data)} "
                                   "compressed bytes can hold (file cut short or corrupt)")
        cap = sum(_block_sizes(n, degree if degree in SH_COUNTS else 0, version)) + MAX_EXTENSION_BYTES
        raw += d.decompress(d.unconsumed_tail, cap)
    except zlib.error as e:
        raise SceneFormatError(f"{path}: SPZ gzip stream is corrupt ({e})") from None
    if not d.eof:
        what = "holds more than its header announces" if d.unconsumed_tail else "is cut short"
        raise SceneFormatError(f"{path}: SPZ gzip stream {what}")
    return raw


def _parse_legacy(path: Path, data: bytes) -> tuple[int, int, int, int, int, list[bytes], dict[int, bytes]]:
    raw = _gunzip(path, data)
    _, version, n, degree, frac, flags = HEADER_LEGACY.unpack_from(raw)
    if version >= 4:
        raise SceneFormatError(f"{path}: SPZ version {version} must not be gzip-compressed")
    _check_header(path, version, n, degree, frac, len(raw) // 9, len(raw))
    at, blocks = HEADER_LEGACY.size, []
    for size in _block_sizes(n, degree, version):
        if at + size > len(raw):
            raise SceneFormatError(f"{path}: SPZ stream cut short: {n} Gaussians need more than its {len(raw)} bytes")
        blocks.append(raw[at:at + size])
        at += size
    extensions = _extensions(path, raw[at:]) if flags & FLAG_EXTENSIONS else {}
    return version, n, degree, frac, flags, blocks, extensions


def _stored_axes(path: Path, extensions: dict[int, bytes]) -> tuple[str, str]:
    """(system, why) the data is stored in according to the file."""
    record = extensions.get(EXT_COORDINATE_SYSTEM)
    if record is None:
        return "rub", "the SPZ spec's default"
    if len(record) != 4 or not 1 <= struct.unpack("<I", record)[0] <= len(SYSTEMS):
        raise SceneFormatError(f"{path}: SPZ coordinate-system record is malformed")
    system = SYSTEMS[struct.unpack("<I", record)[0] - 1]
    if system not in SYSTEMS[:8]:
        raise SceneFormatError(f"{path}: SPZ data stored in the rotated axes {system.upper()} is not supported "
                               "(dofview reads the axis-flip systems LDB…RUF)")
    return system, "the file's coordinate-system record"


def read_spz(path: str | Path, progress: Callable[[int, int], None] | None = None, *,
             spz_axes: str | None = None, report: Callable[[str], None] | None = None) -> GaussianScene:
    """Read a ``.spz`` file (versions 2–4) into an sRGB :class:`GaussianScene` in dofview's axes.

    Args:
        spz_axes: the axes the data is in: None follows the file (RUB per the spec, or what its
            coordinate-system record says), "rub" forces the spec's, "rdf" takes the data as it is
            stored (files written in PLY axes, e.g. by splat-transform).
        report: called with one line saying which axes were used (the CLI prints it).

    Raises:
        SceneFormatError: the file is cut short, corrupt, or of an unsupported version.
    """
    path = Path(path)
    if spz_axes is not None and spz_axes not in AXES:
        raise SceneFormatError(f"{path}: spz_axes must be one of {', '.join(AXES)}, got {spz_axes!r}")
    data = _read_file(path)
    if data[:4] == struct.pack("<I", MAGIC):
        version, n, degree, frac, flags, blocks, extensions = _parse_v4(path, data)
    elif data[:2] == b"\x1f\x8b":
        version, n, degree, frac, flags, blocks, extensions = _parse_legacy(path, data)
    else:
        raise SceneFormatError(f"{path}: not an SPZ file (neither 'NGSP' nor gzip data at the start)")
    del data
    pos, alpha, colour, scale, rot, sh = blocks

    p = np.frombuffer(pos, np.uint8).reshape(n, 3, 3).astype(np.int32)
    fixed = p[..., 0] | (p[..., 1] << 8) | (p[..., 2] << 16)
    fixed = np.where(fixed & 0x800000, fixed - (1 << 24), fixed)
    means = fixed.astype(np.float64) / (1 << frac)
    opacities = np.frombuffer(alpha, np.uint8).astype(np.float64) / 255.0
    sh_dc = (np.frombuffer(colour, np.uint8).reshape(n, 3) / 255.0 - 0.5) / COLOUR_SCALE
    log_scales = np.frombuffer(scale, np.uint8).reshape(n, 3) / 16.0 - 10.0
    if version == 2:
        xyz = np.frombuffer(rot, np.uint8).reshape(n, 3) / 127.5 - 1.0
        w = np.sqrt(np.maximum(0.0, 1.0 - np.sum(xyz * xyz, axis=1)))
        quats = np.column_stack([w, xyz])
    else:
        code = np.frombuffer(rot, "<u4").astype(np.int64)
        others = np.empty((n, 3))
        for i in range(3):  # the last stored component sits in the lowest bits
            field = code >> (10 * (2 - i))
            others[:, i] = (field & 0x1FF) / 511.0 * np.sqrt(0.5) * np.where(field & 0x200, -1.0, 1.0)
        xyzw = quats_from_smallest_three((code >> 30) & 3, others)
        quats = xyzw[:, [3, 0, 1, 2]]
    sh_rest = None
    if degree:
        k = SH_COUNTS[degree]
        sh_rest = (np.frombuffer(sh, np.uint8).reshape(n, k, 3).astype(np.float64) - 128.0) / 128.0
        if degree == 4:
            warnings.warn(f"{path}: SH degree 4 is not supported; its degree-4 terms are dropped",
                          DofviewWarning, stacklevel=2)
            sh_rest = sh_rest[:, :SH_COUNTS[3]]
    if flags & FLAG_ANTIALIASED:
        warnings.warn(f"{path}: trained with antialiasing (mip-splatting); dofview renders it without the "
                      "antialiasing filter, so fine detail may look slightly sharper or more aliased",
                      DofviewWarning, stacklevel=2)

    stored, why = _stored_axes(path, extensions)
    if spz_axes is not None:
        stored, why = spz_axes, "--spz-axes"
    if stored != "rdf":
        means, quats, sh_rest = flip_axes(means, quats, sh_rest, axis_signs(stored))
    if report:
        turned = "taken as stored" if stored == "rdf" else "turned into dofview's RDF"
        other = "rdf" if stored != "rdf" else "rub"
        report(f"{path.name}: SPZ v{version}, data read as {stored.upper()} ({why}), {turned}; "
               f"--spz-axes {other} reads it the other way")
    if progress:
        progress(n, n)
    return scene_from_arrays(path, means, quats, log_scales, opacities, sh_dc, sh_rest)


# ---- writing ------------------------------------------------------------------------------------
def _quantise_sh(v: np.ndarray, bits: int) -> np.ndarray:
    """8-bit codes ``v·128 + 128`` rounded to buckets of 2^(8−bits) (the reference writer's default
    precision; zeros stay exact)."""
    bucket = 1 << (8 - bits)
    q = np.round(v * 128.0) + 128.0
    q = np.floor((q + bucket // 2) / bucket) * bucket
    return np.clip(q, 0, 255).astype(np.uint8)


def pack_spz(scene: GaussianScene, spz_axes: str = "rub") -> bytes:
    """The bytes of a version-4 ``.spz`` holding ``scene``, its data stored in ``spz_axes`` ("rub"
    per the spec; "rdf" stores dofview's axes unchanged, as splat-transform does).

    Positions use up to 12 fractional bits, fewer when the scene is too large for 24-bit fixed
    point at 12 (the header records the count, so every reader follows). Log-scales outside
    [−10, 5.9] and SH terms outside [−1, 1) are clamped by the format.
    """
    import zstandard

    if spz_axes not in AXES:
        raise ValueError(f"spz_axes must be one of {AXES}, got {spz_axes!r}")
    n = scene.count
    means, quats, sh_rest = scene.means.astype(np.float64), scene.unit_quats(), scene.sh_rest
    if spz_axes != "rdf":
        means, quats, sh_rest = flip_axes(means, quats, None if sh_rest is None else sh_rest.astype(np.float64),
                                          axis_signs(spz_axes))
    extent = float(np.max(np.abs(means))) if n else 0.0
    frac = FRACTIONAL_BITS
    while frac > 0 and extent * (1 << frac) >= (1 << 23) - 1:
        frac -= 1
    if extent * (1 << frac) >= (1 << 23) - 1:
        raise ValueError(f"scene extends to {extent:g} units: beyond the range of SPZ's 24-bit positions")
    fixed = np.round(means * (1 << frac)).astype(np.int64) & 0xFFFFFF
    pos = np.stack([fixed & 0xFF, (fixed >> 8) & 0xFF, fixed >> 16], axis=-1).astype(np.uint8)
    alphas = np.round(np.clip(scene.opacities, 0.0, 1.0) * 255.0).astype(np.uint8)
    colours = np.clip(np.round(scene.sh_dc * (COLOUR_SCALE * 255.0) + 127.5), 0, 255).astype(np.uint8)
    logs = np.log(np.maximum(scene.scales.astype(np.float64), np.exp(-LOG_SCALE_LIMIT)))
    scales = np.clip(np.round((logs + 10.0) * 16.0), 0, 255).astype(np.uint8)

    xyzw = quats[:, [1, 2, 3, 0]]
    largest = np.argmax(np.abs(xyzw), axis=1)
    xyzw = xyzw * np.where(xyzw[np.arange(n), largest] < 0, -1.0, 1.0)[:, None]
    code = largest.astype(np.uint32)
    for i in range(4):
        keep = largest != i
        v = xyzw[:, i]
        mag = np.minimum(np.floor(511.0 * np.abs(v) / np.sqrt(0.5) + 0.5), 511).astype(np.uint32)
        field = ((v < 0).astype(np.uint32) << np.uint32(9)) | mag
        code = np.where(keep, (code << np.uint32(10)) | field, code)
    rotations = code.astype("<u4")

    blocks = [pos.tobytes(), alphas.tobytes(), colours.tobytes(), scales.tobytes(), rotations.tobytes()]
    if sh_rest is not None:
        sh = np.empty(sh_rest.shape, np.uint8)
        sh[:, :3] = _quantise_sh(sh_rest[:, :3], SH1_BITS)
        sh[:, 3:] = _quantise_sh(sh_rest[:, 3:], SH_REST_BITS)
        blocks.append(sh.tobytes())
    compressor = zstandard.ZstdCompressor(level=ZSTD_LEVEL)
    packed = [compressor.compress(b) for b in blocks]
    header = HEADER_V4.pack(MAGIC, LATEST_VERSION, n, scene.sh_degree, frac, 0, len(blocks), HEADER_V4.size)
    toc = b"".join(TOC_ENTRY.pack(len(c), len(b)) for c, b in zip(packed, blocks))
    return header + toc + b"".join(packed)


def write_spz(scene: GaussianScene, path: str | Path, *, spz_axes: str = "rub") -> None:
    """Write ``scene`` as a version-4 ``.spz`` (whole or not at all); see :func:`pack_spz`."""
    from dofview.io.atomic import atomic_output

    if scene.count == 0:
        raise SceneFormatError(f"{path}: SPZ cannot hold an empty scene")
    try:
        data = pack_spz(scene, spz_axes)
    except ValueError as e:
        raise SceneFormatError(f"{path}: {e}") from None
    with atomic_output(path) as tmp:
        Path(tmp).write_bytes(data)
