"""Scene files by extension: ``.ply`` (Inria 3DGS) and ``.splat`` (antimatter15), read and written."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

from .errors import DofviewError
from .progress import Progress
from .scene import GaussianScene

FORMATS = (".ply", ".splat")


def _format(path: Path) -> str:
    ext = path.suffix.lower()
    if ext not in FORMATS:
        raise DofviewError(f"{path}: unknown scene format {ext or '(no extension)'!r}; expected .ply or .splat")
    return ext


def input_size(path: Path) -> int:
    """The size in bytes of a scene file that exists, is readable and is not empty.

    Raises:
        DofviewError: the path is missing, a directory, unreadable or empty.
    """
    try:
        size = os.stat(path).st_size
        with open(path, "rb"):
            pass
    except IsADirectoryError:
        raise DofviewError(f"{path}: is a directory, not a scene file") from None
    except FileNotFoundError:
        raise DofviewError(f"{path}: no such file") from None
    except OSError as e:
        raise DofviewError(f"{path}: cannot read ({e.strerror or e})") from None
    if size == 0:
        raise DofviewError(f"{path}: file is empty")
    return size


def load_scene(path: str | Path, progress: bool | Callable[[int, int], None] = True) -> GaussianScene:
    """Read a scene file; a progress bar shows on stderr when loading takes more than half a second.
    ``progress`` may instead be a ``progress(done, total)`` callback (the viewer's progress bar).

    Raises:
        DofviewError: a missing, unreadable or malformed file, with the path and what is wrong.
    """
    path = Path(path)
    ext = _format(path)
    if path.is_dir():
        raise DofviewError(f"{path}: is a directory, not a scene file")
    from .ply import read_ply
    from .splat import read_splat

    reader = read_ply if ext == ".ply" else read_splat
    if callable(progress):
        return reader(path, progress=progress)
    if not progress:
        return reader(path)
    with Progress(f"loading {path.name}", 1, unit=" Gaussians") as bar:
        return reader(path, progress=bar)


def save_scene(scene: GaussianScene, path: str | Path) -> None:
    """Write a scene file by extension (whole or not at all)."""
    path = Path(path)
    from .ply import write_ply
    from .splat import write_splat

    (write_ply if _format(path) == ".ply" else write_splat)(scene, path)
