"""OpenEXR images: linear R, G, B, A (premultiplied) and Z (camera depth) with dofview's metadata.

Written through a temporary file (see atomic.py), so a failure never leaves a half-written image.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenEXR

from dofview.errors import DofviewError
from dofview.io.atomic import atomic_output

HALF_MAX = 65504.0


def write_exr(path: str | Path, rgba: np.ndarray, depth: np.ndarray | None = None, half: bool = False,
              header: dict[str, object] | None = None) -> None:
    """Write an EXR with channels R, G, B, A (and Z when ``depth`` is given).

    Args:
        rgba: (H, W, 4) float linear RGB premultiplied by A.
        depth: (H, W) float camera z, scene units (0 where nothing was drawn); always float32.
        half: store R, G, B, A as half floats (values beyond ±65504 are clipped to it, not inf).
        header: extra attributes (str, int, float) stored in the file's header.
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
    for k, v in (header or {}).items():
        hdr[k] = v if isinstance(v, (str, int)) else float(v) if isinstance(v, float) else str(v)
    with atomic_output(path) as tmp:
        try:
            with OpenEXR.File(hdr, channels) as f:
                f.write(str(tmp))
        except RuntimeError as e:  # OpenEXR reports I/O failures (a full disk) as RuntimeError
            reason = str(e).rsplit('". ', 1)[-1].rstrip(".")  # the OS's reason, after the temp file's name
            raise DofviewError(f"{path}: cannot write EXR ({reason}); nothing was written") from None


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
