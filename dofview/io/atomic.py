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
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=folder)
    except OSError as e:
        raise DofviewError(f"{path}: cannot write in {folder} ({e.strerror or e})") from None
    os.close(fd)
    tmp_path = Path(tmp)
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


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
