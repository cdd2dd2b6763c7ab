"""Checks every scene reader makes before it reads."""

from __future__ import annotations

import os
from pathlib import Path

from dofview.errors import DofviewError


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
