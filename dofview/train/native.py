"""The native rasteriser: :func:`dofview.train.sparse.rasterise_sparse`'s compositing fused in C.

:func:`dofview.train.raster.project` makes the splats in torch (the lens math stays written
once, and autograd carries the gradients from the splats back to the Gaussians); ``native.c``
beside this file bins them into 16×16 tiles, composites them front to back with early stop and
walks them back to front for the backward (its header comment has the details). It is built on
first use with the system C compiler (``$CC``, else ``cc``) into the user cache folder
(``$XDG_CACHE_HOME/dofview``, else ``~/.cache/dofview``), once per source, compiler, flags and
CPU, and called through ctypes on the tensors' memory; no compiler → :class:`NativeUnavailable`.
"""

from __future__ import annotations

import ctypes
import functools
import hashlib
import os
import platform
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import NamedTuple

import torch

from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.lens import ALPHA_MAX, SUPPORT_MAX, Lens
from dofview.train.raster import TILE, Raster, project
from dofview.train.sparse import EARLY_STOP

SOURCE = Path(__file__).with_name("native.c")
# -march=native: the build is keyed by the CPU's flags, so a cached library never meets another CPU
FLAGS = ("-O3", "-march=native", "-std=c11", "-shared", "-fPIC", "-pthread")
REALS = {torch.float32: "float", torch.float64: "double"}
MAX_CHANNELS = 16  # native.c's MAX_CHANNELS


class NativeUnavailable(DofviewError):
    """The native rasteriser cannot be built or loaded here; the message says why."""


def cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "dofview"


def _cpu_flags() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            return next((line for line in f if line.startswith(("flags", "Features"))), "")
    except OSError:
        return ""


class _Kernel(NamedTuple):
    lib: ctypes.CDLL
    splats: type  # ctypes.Structure of native.c's struct Splats


@functools.cache
def library(dtype: torch.dtype) -> _Kernel:
    """The compiled ``native.c`` for ``dtype`` (float32 or float64), built on first use.

    Raises:
        NativeUnavailable: no C compiler, or it failed (the message has its first error line).
    """
    compiler = os.environ.get("CC") or "cc"
    path = shutil.which(compiler)
    if path is None:
        raise NativeUnavailable(f"native rasteriser: no C compiler {compiler!r} (set CC, or install gcc)")
    try:
        version = subprocess.run([path, "--version"], capture_output=True, text=True, timeout=60).stdout
    except (OSError, subprocess.SubprocessError) as e:
        raise NativeUnavailable(f"native rasteriser: cannot run the C compiler {path} ({e})") from None
    flags = [*FLAGS, f"-DREAL={REALS[dtype]}"]
    key = hashlib.sha256("\0".join([SOURCE.read_text(), path, version, *flags, platform.machine(),
                                    _cpu_flags()]).encode()).hexdigest()[:16]
    out = cache_dir() / f"native-{REALS[dtype]}-{key}.so"
    if not out.is_file():
        try:
            out.parent.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise NativeUnavailable(f"native rasteriser: cannot create the cache folder {out.parent} ({e})") from None
        fd, tmp = tempfile.mkstemp(suffix=".so", dir=out.parent)
        os.close(fd)
        try:
            p = subprocess.run([path, *flags, "-o", tmp, str(SOURCE), "-lm"], capture_output=True, text=True,
                               timeout=300)
            if p.returncode != 0:
                first = next((line for line in p.stderr.splitlines() if "error" in line), p.stderr.strip()[:200])
                raise NativeUnavailable(f"native rasteriser: {path} failed on {SOURCE.name}: {first}")
            os.replace(tmp, out)  # whole or not at all: another process may be building the same file
        finally:
            Path(tmp).unlink(missing_ok=True)
    try:
        lib = ctypes.CDLL(str(out))
    except OSError as e:
        raise NativeUnavailable(f"native rasteriser: cannot load {out} ({e})") from None
    lib.dv_bin_count.restype = ctypes.c_int64
    lib.dv_bin_fill.restype = None
    return _Kernel(lib, _splats_struct(ctypes.c_float if dtype == torch.float32 else ctypes.c_double))


def _splats_struct(real) -> type:
    """``struct Splats`` of native.c with ``real`` (ctypes.c_float or c_double) for REAL."""
    ptr = ctypes.c_void_p
    fields = [("count", ctypes.c_int64)] + [(n, ptr) for n in ("mean2d", "conic", "opacity", "colour", "support",
                                                               "lo", "hi")]
    fields += [(n, ctypes.c_int64) for n in ("channels", "width", "height", "tile", "threads")]
    fields += [(n, real) for n in ("tau", "alpha_max", "support_max", "early_stop")]
    fields += [("offsets", ptr), ("pairs", ptr)]
    return type("Splats", (ctypes.Structure,), {"_fields_": fields})


def default_threads() -> int:
    """The CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def _ptr(t: torch.Tensor) -> ctypes.c_void_p:
    return ctypes.c_void_p(t.data_ptr())


class _NativeComposite(torch.autograd.Function):
    """(mean2d, conic, opacity, colour) of front-to-back splats → (rgb (H·W, C), alpha (H·W,))."""

    @staticmethod
    def forward(ctx, mean2d, conic, opacity, colour, support, lo, hi, width: int, height: int, tau: float,
                threads: int):
        arrays = [t.detach().contiguous() for t in (mean2d, conic, opacity, colour, support, lo, hi)]
        if (mean2d.dtype not in REALS or any(a.device.type != "cpu" or a.dtype != mean2d.dtype for a in arrays)
                or colour.shape[1] > MAX_CHANNELS):
            raise ValueError(f"the native rasteriser takes CPU tensors, all float32 or all float64, and ≤ "
                             f"{MAX_CHANNELS} colour channels")
        lib, splats = library(mean2d.dtype)
        s = splats(len(mean2d), *(a.data_ptr() for a in arrays), colour.shape[1], width, height, TILE, threads,
                   tau, ALPHA_MAX, SUPPORT_MAX, EARLY_STOP)
        tiles = -(-width // TILE) * -(-height // TILE)
        offsets = torch.empty(tiles + 1, dtype=torch.int64)
        pairs = torch.empty(lib.dv_bin_count(ctypes.byref(s), _ptr(offsets)), dtype=torch.int32)
        s.offsets, s.pairs = offsets.data_ptr(), pairs.data_ptr()
        cursor = torch.empty(tiles, dtype=torch.int64)
        lib.dv_bin_fill(ctypes.byref(s), _ptr(pairs), _ptr(cursor))
        n = width * height
        rgb = torch.zeros(n, colour.shape[1], dtype=colour.dtype)
        final = torch.empty(n, dtype=colour.dtype)
        last = torch.empty(n, dtype=torch.int32)
        if lib.dv_forward(ctypes.byref(s), *map(_ptr, (rgb, final, last))):
            raise MemoryError("native rasteriser: out of memory or threads")
        ctx.keep = (s, arrays, offsets, pairs, final, last)  # s points into the others: they live with it
        return rgb, 1.0 - final

    @staticmethod
    def backward(ctx, grad_rgb, grad_alpha):
        s, arrays, _, _, final, last = ctx.keep
        lib = library(final.dtype).lib
        grads = [torch.zeros_like(a) for a in arrays[:4]]
        inputs = [grad_rgb.to(final.dtype).contiguous(), grad_alpha.to(final.dtype).contiguous(), final, last]
        if lib.dv_backward(ctypes.byref(s), *map(_ptr, inputs + grads)):
            raise MemoryError("native rasteriser: out of memory or threads")
        return (*grads, None, None, None, None, None, None, None)


def rasterise_native(means: torch.Tensor, quats: torch.Tensor, scales: torch.Tensor, opacities: torch.Tensor,
                     colours: torch.Tensor, camera: Camera, lens: Lens,
                     settings: RenderSettings = RenderSettings(), retain_mean2d: bool = False,
                     sh: torch.Tensor | None = None, threads: int | None = None) -> Raster:
    """:func:`dofview.train.raster.rasterise`, composited by ``native.c`` (CPU tensors, float32 or
    float64; see the module docstring).

    Args:
        means: (N, 3) scene units. quats: (N, 4) (w, x, y, z). scales: (N, 3) scene units, > 0.
        opacities: (N,) in [0, 1]. colours: (N, C) linear (or display) values, any range.
        retain_mean2d: keep the gradient of the projected means (for densification).
        sh: (N, K−1, 3) view-dependent SH coefficients, or None (see :func:`project`).
        threads: compositing threads (default: the cores this process may use); any count gives
            the same image and gradients.

    Raises:
        NativeUnavailable: the C file cannot be built here.
    """
    s = project(means, quats, scales, opacities, colours, camera, lens, settings, sh)
    if retain_mean2d and s.mean2d.requires_grad:
        s.mean2d.retain_grad()
    w, h = camera.width, camera.height
    rgb, alpha = _NativeComposite.apply(s.mean2d, s.conic, s.opacity, s.colour, s.support, s.lo, s.hi, w, h,
                                        settings.tau, threads or default_threads())
    return Raster(rgb=rgb.reshape(h, w, -1), alpha=alpha.reshape(h, w), mean2d=s.mean2d, drawn=s.drawn)
