"""Image error measures for the benchmark: PSNR, SSIM (Wang et al. 2004) and log-radiance error,
and the edge width of a bokeh disc.

PSNR and SSIM compare display images (tonemapped, values in [0, 1]); the log-radiance error
compares linear HDR images, where a display image would clip the bright parts away.
"""

from __future__ import annotations

import math

import numpy as np

# Wang et al.: an 11-tap Gaussian window with σ = 1.5 px, and the stabilising constants
# C1 = (K1·L)², C2 = (K2·L)² with K1 = 0.01, K2 = 0.03 for dynamic range L.
SSIM_TAPS = 11
SSIM_SIGMA = 1.5
SSIM_K1 = 0.01
SSIM_K2 = 0.03

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 weights for linear RGB


def psnr(a: np.ndarray, b: np.ndarray, peak: float = 1.0) -> float:
    """Peak signal-to-noise ratio in dB of image ``a`` against ``b`` (same shape); inf if equal."""
    mse = float(np.mean((np.asarray(a, np.float64) - np.asarray(b, np.float64)) ** 2))
    return math.inf if mse == 0.0 else 10.0 * math.log10(peak * peak / mse)


def _gaussian_window(taps: int = SSIM_TAPS, sigma: float = SSIM_SIGMA) -> np.ndarray:
    x = np.arange(taps) - (taps - 1) / 2
    w = np.exp(-0.5 * (x / sigma) ** 2)
    return w / w.sum()


def _filter_valid(img: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Separable 'valid' filtering of the first two axes of ``img`` (H, W, …) with the 1D ``w``."""
    n = len(w)
    h, wd = img.shape[:2]
    rows = sum(w[i] * img[i:h - n + 1 + i] for i in range(n))
    return sum(w[i] * rows[:, i:wd - n + 1 + i] for i in range(n))


def ssim(a: np.ndarray, b: np.ndarray, data_range: float = 1.0) -> float:
    """Mean SSIM of ``a`` against ``b``: (H, W) or (H, W, C) images, C channels averaged.

    Local means, variances and covariance come from the 11×11 Gaussian window (σ = 1.5), over
    the positions where the window fits inside the image (Wang et al.'s 'valid' filtering).
    Images smaller than the window are compared with one window the size of the image.
    """
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    if a.shape != b.shape:
        raise ValueError(f"ssim: shapes differ, {a.shape} vs {b.shape}")
    taps = min(SSIM_TAPS, a.shape[0], a.shape[1])
    w = _gaussian_window(taps)
    c1 = (SSIM_K1 * data_range) ** 2
    c2 = (SSIM_K2 * data_range) ** 2
    mu_a, mu_b = _filter_valid(a, w), _filter_valid(b, w)
    var_a = _filter_valid(a * a, w) - mu_a * mu_a
    var_b = _filter_valid(b * b, w) - mu_b * mu_b
    cov = _filter_valid(a * b, w) - mu_a * mu_b
    s = ((2 * mu_a * mu_b + c1) * (2 * cov + c2)) / ((mu_a ** 2 + mu_b ** 2 + c1) * (var_a + var_b + c2))
    return float(s.mean())


def log_radiance_error(a: np.ndarray, b: np.ndarray, floor: float = 1e-3) -> float:
    """RMS difference in stops (log₂) between the luminances of linear RGB images ``a`` and ``b``.

    ``a``, ``b``: (H, W, ≥3) linear radiance (alpha ignored). ``floor`` (same units) is added to
    both so that near-black pixels do not dominate: differences well below it count little.
    """
    la = np.asarray(a, np.float64)[..., :3] @ LUMINANCE
    lb = np.asarray(b, np.float64)[..., :3] @ LUMINANCE
    d = np.log2(np.maximum(la, 0.0) + floor) - np.log2(np.maximum(lb, 0.0) + floor)
    return float(np.sqrt(np.mean(d * d)))


def radial_profile(img: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """The radial profile of a bokeh disc ``img`` (H, W, light ≥ 0) about its light's centroid, in
    ½ px rings out to 2·``radius`` (px, the disc's expected radius), over its mean within
    ½·radius: (ring radii px, values) of the rings that hold a pixel centre."""
    yy, xx = np.mgrid[:img.shape[0], :img.shape[1]] + 0.5
    cy, cx = (img * yy).sum() / img.sum(), (img * xx).sum() / img.sum()
    ring = np.minimum((np.hypot(yy - cy, xx - cx) / 0.5).astype(int), int(4 * radius))
    # the last ring gathers everything beyond 2·radius: left out
    sums, counts = np.bincount(ring.ravel(), img.ravel())[:-1], np.bincount(ring.ravel())[:-1]
    r = ((np.arange(len(sums)) + 0.5) * 0.5)[counts > 0]
    prof = sums[counts > 0] / counts[counts > 0]
    return r, prof / prof[r < 0.5 * radius].mean()


def edge_width(img: np.ndarray, radius: float) -> float:
    """Width px of a bokeh disc's edge (``img`` (H, W) its light, ``radius`` px its expected
    radius): where its :func:`radial_profile` falls from 90 % to 10 % (the outermost rings at
    or above each), a lens's sharp rim a few px, a blob's soft one tens."""
    r, q = radial_profile(img, radius)
    return float(r[np.nonzero(q >= 0.1)[0].max()] - r[np.nonzero(q >= 0.9)[0].max()])
