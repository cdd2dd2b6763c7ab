"""Training losses (Cinematic Gaussians Eq. 7–11) and the exposure-aligned warm-up loss.

Images are (H, W, 3) float tensors. Δ(a, b) = 0.8·L1 + 0.2·(1 − SSIM), the 3DGS photometric
measure. The paper's L_foc compares the outputs of a learned blur detector, which cannot be
downloaded; here the defocus map g is a local sharpness measure: the square root of the Gaussian-
weighted local energy of the image's Laplacian (large where the image has in-focus detail, ~0 in
flat or defocused regions), differentiable by construction.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

SSIM_WEIGHT = 0.2
LAMBDA_EXP = 0.25  # Eq. 8, as in the paper
LAMBDA_FOC = 1.0
GAMMA_TOE = 1e-7  # below it x^(1/γ) runs on as a straight line to 0: a finite slope at black (0.17/255 here)
SATURATED = 254.0 / 255.0  # pixel values outside (DARK, SATURATED) carry no radiance information
DARK = 1.0 / 255.0
HALF_STEP = 0.5 / 255.0  # an 8-bit pixel holds its value ± this


def _gauss_kernel(size: int, sigma: float, device, dtype) -> torch.Tensor:
    x = torch.arange(size, device=device, dtype=dtype) - (size - 1) / 2
    g = torch.exp(-x * x / (2 * sigma * sigma))
    g = g / g.sum()
    return g[:, None] * g[None, :]


def _blur(x: torch.Tensor, size: int, sigma: float) -> torch.Tensor:
    """(C, H, W) → same shape, Gaussian-filtered per channel with replicated borders."""
    k = _gauss_kernel(size, sigma, x.device, x.dtype)[None, None].repeat(x.shape[0], 1, 1, 1)
    pad = size // 2
    return F.conv2d(F.pad(x[None], (pad, pad, pad, pad), mode="replicate"), k, groups=x.shape[0])[0]


def ssim(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Mean SSIM (11×11 Gaussian window, σ = 1.5) of two (H, W, C) images in [0, 1]-ish units."""
    x, y = a.permute(2, 0, 1), b.permute(2, 0, 1)
    # the five local means in one filter call: on CPU, most of a depthwise convolution's time is per call
    mx, my, xx, yy, xy = _blur(torch.cat([x, y, x * x, y * y, x * y]), 11, 1.5).chunk(5)
    vx, vy, cxy = xx - mx * mx, yy - my * my, xy - mx * my
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    return (((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))).mean()


def delta(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Δ of Eq. 9: (1 − λ)·L1 + λ·(1 − SSIM), λ = 0.2."""
    return (1 - SSIM_WEIGHT) * (a - b).abs().mean() + SSIM_WEIGHT * (1 - ssim(a, b))


def encode(x: torch.Tensor, gamma: float) -> torch.Tensor:
    """x^(1/γ) for x ≥ 0, exact above :data:`GAMMA_TOE` and a straight line from there to 0 (a
    finite slope at black). A floor instead, max(x, ε)^(1/γ), lifts black to ε^(1/γ): on a black
    background that offset outweighs the scene in SSIM and in L_exp's mean (docs/TRAINING.md)."""
    a = 1.0 / gamma
    x = torch.clamp(x, min=0.0)
    return torch.where(x < GAMMA_TOE, x * GAMMA_TOE ** (a - 1.0), torch.clamp(x, min=GAMMA_TOE) ** a)


def tonemap(hdr: torch.Tensor, exposure: float, gamma: float) -> torch.Tensor:
    """Eq. 7: min(exposure·C, 1)^(1/γ) (through :func:`encode`)."""
    return encode(torch.clamp(hdr * exposure, max=1.0), gamma)


def sharpness(img: torch.Tensor) -> torch.Tensor:
    """(H, W, 3) → (1, H, W) defocus map g: sqrt of the local energy of the Laplacian of luma."""
    luma = img.mean(-1)[None]
    lap = torch.tensor([[0.0, 1.0, 0.0], [1.0, -4.0, 1.0], [0.0, 1.0, 0.0]], device=img.device, dtype=img.dtype)
    edge = F.conv2d(F.pad(luma[None], (1, 1, 1, 1), mode="replicate"), lap[None, None])[0]
    return torch.sqrt(_blur(edge * edge, 5, 1.0) + 1e-8)


def photo_loss(rendered: torch.Tensor, photo: torch.Tensor, use_exp: bool = True, use_foc: bool = True,
               ) -> tuple[torch.Tensor, dict[str, float]]:
    """Eq. 8: L_rec + λ_exp·L_exp + λ_foc·L_foc of a tonemapped render against its photo."""
    rec = delta(rendered, photo)
    total, parts = rec, {"rec": float(rec.detach())}
    if use_exp:  # Eq. 10: both images scaled to a medium exposure
        exp = delta(rendered / (2 * rendered.mean() + 1e-6), photo / (2 * photo.mean() + 1e-6))
        total = total + LAMBDA_EXP * exp
        parts["exp"] = float(exp.detach())
    if use_foc:  # Eq. 11 with g = local Laplacian energy
        foc = delta(sharpness(rendered).permute(1, 2, 0), sharpness(photo).permute(1, 2, 0))
        total = total + LAMBDA_FOC * foc
        parts["foc"] = float(foc.detach())
    return total, parts


def aligned_loss(hdr: torch.Tensor, photo: torch.Tensor, exposure: float, key: float, gamma: float) -> torch.Tensor:
    """Warm-up loss without tonemapping: the render against the photo brought to radiance.

    The photo is un-exposed (pixel^γ / exposure) and both sides are compared at the dataset's
    key exposure with the gamma but without the clip, so bright and dark regions weigh alike.
    A black pixel holds no radiance value but a bound: what it saw was darker than half a step
    above it, so only a render brighter than that costs (else haze over a black background
    would grow unseen); a saturated pixel bounds from below in the same way.
    """
    scale = (key / exposure) ** (1 / gamma)  # a pixel value → its radiance at the key, gamma-encoded
    pred = encode(hdr * key, gamma)
    dark, saturated = photo <= DARK, photo >= SATURATED
    diff = torch.where(dark, torch.relu(pred - (photo + HALF_STEP) * scale),
                       torch.where(saturated, torch.relu((photo - HALF_STEP) * scale - pred),
                                   (pred - photo * scale).abs()))
    return diff.mean()
