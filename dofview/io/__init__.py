"""Scene files, read and written by the table below: one line per format, one module per format.

Adding a format is one module with ``read_X(path, progress=None) -> GaussianScene`` (and
``write_X(scene, path)`` where the format can be written) plus one line in :data:`READERS` (and
:data:`WRITERS`). Modules are imported only when a file of theirs is opened, so ``plyfile`` and
``OpenEXR`` stay off the import path until needed.
"""

from __future__ import annotations

import importlib
import inspect
from pathlib import Path
from typing import Callable

from dofview.errors import DofviewError
from dofview.progress import Progress
from dofview.scene import GaussianScene

READERS: dict[str, str] = {
    ".ply": "dofview.io.ply:read_ply",  # hands a PLY with a "chunk" element to read_compressed_ply
    ".splat": "dofview.io.splat:read_splat",
    ".spz": "dofview.io.spz:read_spz",
    ".compressed.ply": "dofview.io.compressed_ply:read_compressed_ply",
    ".sog": "dofview.io.sog:read_sog",
    "meta.json": "dofview.io.sog:read_sog",  # an unbundled SOG (or give its folder)
    "lod-meta.json": "dofview.io.lod:read_lod",  # a streamed LOD set of SOG chunks (or give its folder)
}
"""File-name ending (lower case) → ``"module:function"`` that reads it. The longest matching ending wins."""

WRITERS: dict[str, str] = {
    ".ply": "dofview.io.ply:write_ply",
    ".splat": "dofview.io.splat:write_splat",
    ".spz": "dofview.io.spz:write_spz",
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


def load_scene(path: str | Path, progress: bool | Callable[[int, int], None] = True,
               **options: object) -> GaussianScene:
    """Read a scene file; a progress bar shows on stderr when loading takes more than half a second.
    ``progress`` may instead be a ``progress(done, total)`` callback (the viewer's progress bar).

    ``options`` are keyword arguments for the readers that take them, e.g. ``spz_axes="rdf"`` for
    :func:`dofview.io.spz.read_spz`, ``lod=1`` or ``budget=2_000_000`` for a streamed LOD set
    (:func:`dofview.io.lod.read_lod`), or ``report=print`` (a one-line note on how the file was read);
    readers without such a parameter, and options given as None, are left alone.

    Raises:
        DofviewError: a missing, unreadable or malformed file, or one with no drawable Gaussian
            (:meth:`GaussianScene.nothing_to_draw`), with the path and what is wrong.
    """
    path = Path(path)
    for inside in ("lod-meta.json", "meta.json"):  # a streamed LOD set's folder, an unbundled SOG's
        if path.is_dir() and (path / inside).is_file():
            path = path / inside
    reader = _lookup(READERS, path, "read")
    if path.is_dir():
        raise DofviewError(f"{path}: is a directory, not a scene file")
    accepted = inspect.signature(reader).parameters
    kwargs = {k: v for k, v in options.items() if k in accepted and v is not None}
    if callable(progress):
        scene = reader(path, progress=progress, **kwargs)
    elif not progress:
        scene = reader(path, **kwargs)
    else:
        with Progress(f"loading {path.name}", 1, unit=" Gaussians") as bar:
            scene = reader(path, progress=bar, **kwargs)
    why = scene.nothing_to_draw()
    if why is not None:
        raise DofviewError(f"{path}: {why}")
    return scene


def save_scene(scene: GaussianScene, path: str | Path, **options: object) -> None:
    """Write a scene file by extension (whole or not at all); ``options`` go to the writers that
    take them (e.g. ``spz_axes``), as in :func:`load_scene`."""
    path = Path(path)
    writer = _lookup(WRITERS, path, "write")
    accepted = inspect.signature(writer).parameters
    writer(scene, path, **{k: v for k, v in options.items() if k in accepted and v is not None})
