"""Checks every scene reader makes before it reads."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from dofview.errors import DofviewError, DofviewWarning


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


def report_dropped(path: Path, ok: np.ndarray, what: str = "NaN or infinite values") -> None:
    """Warn once (a :class:`DofviewWarning`) about the Gaussians a reader drops, ``~ok`` of ``ok``
    (N,) bool, for having ``what``; a file whose every Gaussian is dropped has nothing to draw.

    Raises:
        DofviewError: every Gaussian of a non-empty file is dropped.
    """
    n, bad = ok.size, ok.size - int(np.count_nonzero(ok))
    if n and bad == n:
        raise DofviewError(f"{path}: no drawable Gaussian: all {n:,} have {what}")
    if bad:
        warnings.warn(f"{path}: dropped {bad} of {n} Gaussians with {what}", DofviewWarning, stacklevel=4)
