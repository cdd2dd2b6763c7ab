"""Outputs are written whole or not at all: into a temporary file beside the target, then renamed.

An existing file is replaced only once the new one is complete; a failure (full disk, bad value,
interrupt) removes the temporary file and leaves the target as it was.
"""

from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from dofview.errors import DofviewError


@contextmanager
def atomic_output(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path in ``path``'s folder; on success rename it to ``path``.

    Raises:
        DofviewError: the folder is missing or not writable, or writing failed (e.g. disk full).
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise DofviewError(f"{path}: folder {folder} does not exist")
    if path.is_dir():
        raise DofviewError(f"{path}: is a directory")
    tmp_path = _new_file(folder, path, ".part", path)
    try:
        yield tmp_path
        os.chmod(tmp_path, 0o666 & ~_umask())
        os.replace(tmp_path, path)
    except OSError as e:
        tmp_path.unlink(missing_ok=True)
        raise DofviewError(f"{path}: cannot write ({e.strerror or e}); nothing was written") from None
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise


def check_writable(path: str | Path, shown: str | Path | None = None) -> None:
    """Check, before any work, that ``path`` can be written: its folder, or the nearest folder
    above it that exists (:func:`make_folder` makes the rest), is a folder this process can create
    a file in. Tried by creating and removing a file, not by permission bits, which a root process
    passes even where the file system refuses it (/sys, a read-only mount). Errors name ``shown``
    (default ``path``), e.g. the numbered pattern a frame's name came from.

    Raises:
        DofviewError: the path runs through a file, or the folder cannot be written in.
    """
    path = Path(path)
    shown = path if shown is None else shown
    folder = path.parent if str(path.parent) else Path(".")
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise DofviewError(f"{shown}: {existing} is a file, not a folder")
    _new_file(existing, path, ".probe", shown).unlink()


def check_output_file(path: str | Path, shown: str | Path | None = None) -> None:
    """:func:`check_writable`, and that ``path`` does not name a folder.

    Raises:
        DofviewError: as :func:`check_writable`, or ``path`` is a folder.
    """
    check_writable(path, shown)
    if Path(path).is_dir():
        raise DofviewError(f"{path if shown is None else shown}: is a folder, not a file name")


def _new_file(folder: Path, path: Path, suffix: str, shown: str | Path) -> Path:
    """A new empty hidden file in ``folder`` named after ``path``; a DofviewError naming ``shown``
    when the folder refuses it."""
    try:
        fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=folder)
    except OSError as e:
        raise DofviewError(f"{shown}: cannot write in {folder} ({e.strerror or e})") from None
    os.close(fd)
    return Path(name)


def make_folder(path: str | Path) -> None:
    """Make the folder of ``path`` and its missing parents (as ``mkdir -p``), once
    :func:`check_writable` has passed.

    Raises:
        DofviewError: a folder cannot be made.
    """
    folder = Path(path).parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise DofviewError(f"{path}: cannot make folder {folder} ({e.strerror or e})") from None


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
