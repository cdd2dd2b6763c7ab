"""The uniforms of glsl/project.glsl (camera, lens, splatting settings), set in one place for every
program that includes it (the quad vertex shader and the compute rasteriser's kernels)."""

from __future__ import annotations

import moderngl

from dofview.camera import Camera
from dofview.frame import CUT_MODES, KERNELS, OPACITY_NORMS, RenderSettings
from dofview.lens import Lens
from dofview.rendering.gl import float32_uniform, set_uniforms


def set_projection_uniforms(program: moderngl.Program | moderngl.ComputeShader, camera: Camera, lens: Lens,
                            settings: RenderSettings) -> None:
    """Set project.glsl's uniforms that ``program`` uses (the compiler drops unused ones)."""
    values = {
        "u_R0": tuple(float(v) for v in camera.R[0]),
        "u_R1": tuple(float(v) for v in camera.R[1]),
        "u_R2": tuple(float(v) for v in camera.R[2]),
        "u_T": tuple(float(v) for v in camera.T),
        "u_eye": tuple(float(v) for v in camera.centre),
        "u_focal": (camera.fx, camera.fy),
        "u_principal": (camera.cx, camera.cy),
        "u_viewport": (float(camera.width), float(camera.height)),
        "u_frustum": camera.frustum_limits(),
        "u_near": settings.near,
        "u_tau": settings.tau,
        "u_aperture": lens.aperture,
        "u_inv_focus": float32_uniform(lens.inv_focus),
        "u_k": settings.k,
        "u_opacity_norm": OPACITY_NORMS.index(settings.opacity_norm),
        "u_blend_linear": settings.blend_linear,
        "u_cut": CUT_MODES.index(settings.cut),
        "u_kernel": KERNELS.index(settings.kernel),
    }
    set_uniforms(program, values)
