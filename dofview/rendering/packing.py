"""GPU storage layouts of a scene: full float32, or packed to ≤ 128 bytes per Gaussian at SH degree 3.

Packed layout, per Gaussian (read by rendering/glsl/fetch_packed.glsl):
- ``core``: 8 uint32 words = 32 B: mean xyz (float32 bits), scale xyz and base colour rgb as
  halves (3 words), the rotation as its smallest three components in snorm16 with the index of
  the dropped one (2 bits), and opacity in 14 bits.
- ``sh``: the SH-rest coefficients as halves, (K−1)·3 per Gaussian, tightly packed (absent at
  degree 0).
Colours (base and SH rest) are stored divided by :func:`colour_scale`, so HDR radiance beyond the
half range survives.
The full layout (rendering/glsl/fetch_full.glsl) keeps everything float32, for measuring what packing
costs in image error.
"""

from __future__ import annotations

import numpy as np

from dofview.scene import SH_C0, GaussianScene

HALF_MAX = 65504.0
SQRT2 = np.sqrt(2.0)


def _half_bits(x: np.ndarray) -> np.ndarray:
    """float → uint32 holding IEEE half bits, saturating instead of overflowing to inf."""
    h = np.clip(x, -HALF_MAX, HALF_MAX).astype(np.float16)
    return h.view(np.uint16).astype(np.uint32)


def _snorm16(x: np.ndarray) -> np.ndarray:
    return (np.round(np.clip(x, -1.0, 1.0) * 32767.0).astype(np.int32) & 0xFFFF).astype(np.uint32)


def base_colour_offset(scene: GaussianScene) -> np.ndarray:
    """(N, 3) float32 SH_C0·dc + 0.5: the colour before view terms and the clamp at 0."""
    return (SH_C0 * scene.sh_dc + 0.5).astype(np.float32)


def colour_scale(scene: GaussianScene) -> float:
    """The power of two the packed colour coefficients are divided by so that they fit in halves:
    1 unless one exceeds 65504 (HDR radiance up to float32 range); the shader multiplies it back."""
    peak = float(np.abs(base_colour_offset(scene)).max(initial=0.0))
    if scene.sh_rest is not None and scene.count:
        peak = max(peak, float(scene.sh_rest.max()), -float(scene.sh_rest.min()))  # no |x| temporary
    return 1.0 if peak <= HALF_MAX else float(2.0 ** np.ceil(np.log2(peak / HALF_MAX)))


def pack_core(scene: GaussianScene, scale: float | None = None) -> np.ndarray:
    """(N, 8) uint32 packed core attributes (see module docstring); ``scale``: the colour scale when
    packing part of a scene (default: this scene's :func:`colour_scale`)."""
    n = scene.count
    out = np.zeros((n, 8), np.uint32)
    out[:, :3] = scene.means.view(np.uint32)
    s = _half_bits(scene.scales)
    c = _half_bits(base_colour_offset(scene) / np.float32(colour_scale(scene) if scale is None else scale))
    out[:, 3] = s[:, 0] | (s[:, 1] << 16)
    out[:, 4] = s[:, 2] | (c[:, 0] << 16)
    out[:, 5] = c[:, 1] | (c[:, 2] << 16)
    q = scene.unit_quats()
    largest = np.argmax(np.abs(q), axis=1)
    sign = np.where(q[np.arange(n), largest] < 0, -1.0, 1.0)[:, None]
    q = q * sign  # q and −q are one rotation: make the dropped component positive
    keep = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])[largest]
    rest = np.take_along_axis(q, keep, axis=1) * SQRT2  # |component| ≤ 1/√2 when not the largest
    r = _snorm16(rest)
    opacity = np.round(np.clip(scene.opacities, 0.0, 1.0) * 16383.0).astype(np.uint32)
    out[:, 6] = r[:, 0] | (r[:, 1] << 16)
    out[:, 7] = r[:, 2] | (largest.astype(np.uint32) << 16) | (opacity << 18)
    return out


def pack_sh(scene: GaussianScene, scale: float | None = None) -> np.ndarray | None:
    """uint32 words holding the SH-rest coefficients as halves, or None at degree 0."""
    if scene.sh_rest is None:
        return None
    h = np.empty(scene.sh_rest.size, np.float16)  # clipped straight into halves: no float32 temporary
    scale = colour_scale(scene) if scale is None else scale
    rest = scene.sh_rest.ravel() if scale == 1.0 else scene.sh_rest.ravel() / np.float32(scale)
    np.clip(rest, -HALF_MAX, HALF_MAX, out=h, casting="unsafe")
    if h.size % 2:
        h = np.append(h, np.float16(0))
    return h.view(np.uint32)


def full_core(scene: GaussianScene) -> np.ndarray:
    """(N, 14) float32: mean xyz, opacity, unit quaternion wxyz, scale xyz, base colour rgb, pad."""
    out = np.zeros((scene.count, 14), np.float32)
    out[:, :3] = scene.means
    out[:, 3] = scene.opacities
    out[:, 4:8] = scene.unit_quats()
    out[:, 8:11] = scene.scales
    out[:, 11:14] = base_colour_offset(scene)
    return out


def gpu_arrays(scene: GaussianScene, packed: bool = True, scale: float | None = None) -> dict[int, np.ndarray]:
    """The storage buffers a scene needs, by shader binding (0 core, 2 SH rest); ``scale`` as in
    :func:`pack_core`."""
    bufs = {0: pack_core(scene, scale) if packed else full_core(scene)}
    if scene.sh_rest is not None:
        bufs[2] = pack_sh(scene, scale) if packed else scene.sh_rest.reshape(scene.count, -1)
    return bufs
