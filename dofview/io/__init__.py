"""Scene files, read and written by the table below: one line per format, one module per format.

Adding a format is one module with ``read_X(path, progress=None) -> GaussianScene`` (and
``write_X(scene, path)`` where the format can be written) plus one line in :data:`READERS` (and
:data:`WRITERS`). Modules are imported only when a file of theirs is opened, so ``plyfile`` and
``OpenEXR`` stay off the import path until needed.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Callable

from dofview.errors import DofviewError
from dofview.progress import Progress
from dofview.scene import GaussianScene

READERS: dict[str, str] = {
    ".ply": "dofview.io.ply:read_ply",
    ".splat": "dofview.io.splat:read_splat",
}
"""File-name ending (lower case) → ``"module:function"`` that reads it. The longest matching ending wins."""

WRITERS: dict[str, str] = {
    ".ply": "dofview.io.ply:write_ply",
    ".splat": "dofview.io.splat:write_splat",
}
"""File-name ending (lower case) → ``"module:function"`` that writes it."""


def _lookup(table: dict[str, str], path: Path, verb: str) -> Callable:
    name = path.name.lower()
    endings = sorted((e for e in table if name.endswith(e)), key=len, reverse=True)
    if not endings:
        known = ", ".join(sorted(table))
        raise DofviewError(f"{path}: cannot {verb} scene format {path.suffix or '(no extension)'!r}; "
                           f"expected one of {known}")
    module, _, func = table[endings[0]].partition(":")
    return getattr(importlib.import_module(module), func)


def load_scene(path: str | Path, progress: bool | Callable[[int, int], None] = True) -> GaussianScene:
    """Read a scene file; a progress bar shows on stderr when loading takes more than half a second.
    ``progress`` may instead be a ``progress(done, total)`` callback (the viewer's progress bar).

    Raises:
        DofviewError: a missing, unreadable or malformed file, with the path and what is wrong.
    """
    path = Path(path)
    reader = _lookup(READERS, path, "read")
    if path.is_dir():
        raise DofviewError(f"{path}: is a directory, not a scene file")
    if callable(progress):
        return reader(path, progress=progress)
    if not progress:
        return reader(path)
    with Progress(f"loading {path.name}", 1, unit=" Gaussians") as bar:
        return reader(path, progress=bar)


def save_scene(scene: GaussianScene, path: str | Path) -> None:
    """Write a scene file by extension (whole or not at all)."""
    path = Path(path)
    _lookup(WRITERS, path, "write")(scene, path)
