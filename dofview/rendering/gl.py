"""OpenGL context and shader files.

Shaders live in ``dofview/rendering/glsl/``, inside the package (and so inside the wheel). ``#include "file"`` lines are expanded (``#include NAME``
takes the file named by the define NAME) and ``#define``s are inserted after ``#version``.
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

import moderngl
import numpy as np

from dofview.errors import BackendUnavailable, DofviewError

_INCLUDE = re.compile(r'^\s*#include\s+(?:"([^"]+)"|(\w+))\s*$', re.M)
GL_REQUIRED = 430  # SSBOs and atomics in the vertex stage


def shader_dir() -> Path:
    glsl = Path(__file__).resolve().parent / "glsl"
    if not (glsl / "quads.vert").is_file():
        raise DofviewError(f"dofview's shader files are missing (looked in {glsl}); reinstall dofview")
    return glsl


def load_shader(name: str, defines: dict[str, object] | None = None) -> str:
    """The text of ``glsl/name`` with includes expanded and ``defines`` set."""
    base = shader_dir()
    defines = defines or {}
    src = (base / name).read_text()
    src = _INCLUDE.sub(lambda m: (base / (m.group(1) or str(defines[m.group(2)]))).read_text(), src)
    if defines:
        head, _, rest = src.partition("\n")
        src = head + "\n" + "".join(f"#define {k} {v}\n" for k, v in defines.items()) + rest
    return src


def compute_shader(ctx: moderngl.Context, name: str, defines: dict[str, object] | None = None) -> moderngl.ComputeShader:
    """The compute shader ``glsl/name`` with ``defines`` set (see :func:`load_shader`).

    Raises:
        BackendUnavailable: this GL cannot compile it (no compute shaders, or a driver limit the
            kernel exceeds), naming the file and the compiler's first error line.
    """
    try:
        return ctx.compute_shader(load_shader(name, defines))
    except moderngl.Error as e:
        lines = [line.strip() for line in str(e).splitlines() if line.strip()] or ["unknown error"]
        why = next((line for line in lines if "error" in line.lower() and line != lines[0]), lines[0])
        raise BackendUnavailable(f"this OpenGL cannot compile {name}: {why}") from None


_MISSING_GL = (
    "cannot create a headless OpenGL {need} context through EGL ({err}). Install Mesa's EGL and "
    "software rasteriser (Debian/Ubuntu: apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1) "
    "or run scripts/setup.sh"
)


@lru_cache(maxsize=1)
def headless_context() -> moderngl.Context:
    """The process's shared headless GL context (EGL: Mesa llvmpipe without a GPU, or NVIDIA)."""
    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=GL_REQUIRED)
    except Exception as e:  # moderngl/glcontext raise plain Exceptions with library messages
        raise DofviewError(_MISSING_GL.format(need=f"{GL_REQUIRED // 100}.{GL_REQUIRED % 100 // 10}", err=str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__)) from None
    return ctx


def check_size(ctx: moderngl.Context, width: int, height: int) -> None:
    """Refuse image sizes the GL implementation cannot hold, with a clear message."""
    limit = min(ctx.info["GL_MAX_TEXTURE_SIZE"], *ctx.info["GL_MAX_VIEWPORT_DIMS"])
    if width < 1 or height < 1:
        raise DofviewError(f"image size must be at least 1×1, got {width}×{height}")
    if width > limit or height > limit:
        raise DofviewError(f"image size {width}×{height} exceeds this OpenGL's limit of {limit} pixels per side")


def float32_uniform(x: float) -> float:
    """Clamp to float32 range: a uniform of 1/d_f for a focus below 1e-38 would be inf, and 0·inf
    a NaN circle of confusion even with a pinhole."""
    return min(x, float(np.finfo(np.float32).max))


def set_uniforms(program: moderngl.Program, values: dict[str, object]) -> None:
    """Set the uniforms ``program`` uses (the compiler drops unused ones, so a shared set of values
    serves programs that read only part of it)."""
    for name, value in values.items():
        member = program.get(name, None)  # (`name in program` walks every member)
        if member is not None:
            if isinstance(value, np.generic):  # moderngl packs Python numbers: a numpy bool is none
                value = value.item()
            member.value = value
