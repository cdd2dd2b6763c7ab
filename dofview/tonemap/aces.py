"""``aces``: the ACES 2.0 SDR output transform (100 nits, Rec.709) through OpenColorIO.

OpenColorIO's built-in CG config (CONFIG) maps scene-linear Rec.709 ("Linear Rec.709 (sRGB)") to the
"Gamma 2.2 Rec.709 - Display" with the ACES 2.0 view. Its CPU processor is this operator's numpy
twin; its GPU shader generator writes the GLSL of the display pass (tonemap_aces.glsl includes it,
with the generator's two lookup tables as textures). The display-encoded result is decoded with
γ 2.2 to display-linear, so at dofview's default γ 2.2 the screen shows exactly OCIO's output.
A fixed curve: exposure comes only from EV. Needs the ``opencolorio`` package (the ``ocio`` extra).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from dofview.errors import DofviewError
from dofview.tonemap.operator import Operator

CONFIG = "ocio://cg-config-v5.0.0_aces-v2.1_ocio-v2.6"
SOURCE = "Linear Rec.709 (sRGB)"
DISPLAY = "Gamma 2.2 Rec.709 - Display"
VIEW = "ACES 2.0 - SDR 100 nits (Rec.709)"
DISPLAY_GAMMA = 2.2
FUNCTION = "ocio_aces"


@dataclass(frozen=True)
class GpuTable:
    """One lookup table of the generated shader: sampler name, width × height, components (1 or 3),
    (width·height·components,) float32 values, linear or nearest filtering."""

    sampler: str
    width: int
    height: int
    components: int
    values: np.ndarray
    linear: bool


@lru_cache(maxsize=1)
def _processor():
    try:
        import PyOpenColorIO as ocio
    except ImportError:
        raise DofviewError("--tonemap aces needs OpenColorIO: pip install 'dofview[ocio]' "
                           "(or use aces-fit, the fitted curve)") from None
    try:
        config = ocio.Config.CreateFromBuiltinConfig(CONFIG)
        return ocio, config.getProcessor(SOURCE, DISPLAY, VIEW, ocio.TRANSFORM_DIR_FORWARD)
    except ocio.Exception as e:
        raise DofviewError(f"--tonemap aces: OpenColorIO {ocio.__version__} lacks {CONFIG} ({e}); "
                           "install opencolorio>=2.6") from None


@lru_cache(maxsize=1)
def gpu_shader() -> tuple[str, tuple[GpuTable, ...]]:
    """(GLSL text defining ``vec4 ocio_aces(vec4)``, its lookup tables) from OCIO's generator."""
    ocio, proc = _processor()
    desc = ocio.GpuShaderDesc.CreateShaderDesc(language=ocio.GPU_LANGUAGE_GLSL_4_0, functionName=FUNCTION,
                                               resourcePrefix="ocio")
    desc.setAllowTexture1D(False)  # moderngl has no 1-D textures: tables come as N×1 2-D ones
    proc.getDefaultGPUProcessor().extractGpuShaderInfo(desc)
    tables = tuple(GpuTable(t.samplerName, t.width, t.height,
                            1 if t.channel == ocio.GpuShaderDesc.TEXTURE_RED_CHANNEL else 3,
                            np.asarray(t.getValues(), np.float32), t.interpolation != ocio.INTERP_NEAREST)
                   for t in desc.getTextures())
    if list(desc.get3DTextures()) or list(desc.getUniforms()):
        raise DofviewError("--tonemap aces: this OpenColorIO's shader needs 3-D tables or uniforms, which dofview does not bind")
    return desc.getShaderText(), tables


@dataclass(frozen=True)
class Aces(Operator):
    """ACES 2.0 SDR output transform via OpenColorIO; no parameters."""

    name = "aces"
    glsl = "tonemap_aces.glsl"

    def generated_glsl(self):
        return gpu_shader()

    def require(self) -> None:
        _processor()

    def apply(self, rgb, *, stats=None, exposure=1.0, alpha=None, depth=None) -> np.ndarray:
        _, proc = _processor()
        px = np.ascontiguousarray(np.maximum(rgb, 0.0), dtype=np.float32).reshape(-1, 3)
        proc.getDefaultCPUProcessor().applyRGB(px)
        return np.clip(np.power(np.maximum(px, 0.0), DISPLAY_GAMMA), 0.0, 1.0).reshape(np.shape(rgb))
