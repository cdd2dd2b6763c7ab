"""The trainer's differentiable rasterisers by ``--torch-raster`` name, and the default choice.

All three draw the same forward model (:func:`dofview.train.raster.project`'s splats):
``native`` composites in C (``native.c``, CPU only, built on first use), ``sparse`` in plain
torch per pixel fragment (any device), ``dense`` per tile through autograd (the test oracle).
"""

from __future__ import annotations

import sys
from typing import Callable

import torch

from dofview.errors import DofviewError
from dofview.train.native import NativeUnavailable, library, rasterise_native
from dofview.train.raster import rasterise
from dofview.train.sparse import rasterise_sparse

RASTERISERS: dict[str, Callable] = {"native": rasterise_native, "sparse": rasterise_sparse, "dense": rasterise}


def choose_rasteriser(name: str | None, device: torch.device) -> str:
    """The rasteriser to train with: ``name``, or by default native on the CPU when its C file
    builds here (else sparse, with a one-line notice on stderr) and sparse on other devices.

    Raises:
        DofviewError: an unknown name, or native asked for where it cannot run.
    """
    if name is not None and name not in RASTERISERS:
        raise DofviewError(f"--torch-raster must be one of {', '.join(RASTERISERS)}, got {name!r}")
    if name not in (None, "native"):
        return name
    if device.type != "cpu":
        if name == "native":
            raise DofviewError(f"--torch-raster native runs on the CPU, not on {device.type}: use sparse")
        return "sparse"
    try:
        library(torch.float32)
    except NativeUnavailable as e:
        if name == "native":
            raise
        print(f"dofview: {e}; training with the torch sparse rasteriser (slower)", file=sys.stderr)
        return "sparse"
    return "native"
