"""Scene statistics for the adaptive operators: robust, scale-covariant, pooled or smoothed in time.

Statistics come from log2-luminance histograms of the *covered* pixels (alpha > COVERED_ALPHA, so
a black 3DGS background never enters a log statistic), never from raw min/max:

- pass 1: STATS_BINS bins over log2 in STATS_RANGE for Y, R, G, B (32 bins per stop, so scaling
  the scene by a power of two shifts the histogram by whole bins and the statistics exactly);
  ``lo``/``hi`` are the PERCENTILES of log2 Y interpolated inside their bin, ``key`` the mean
  log2 Y (log-average luminance), ``channel_key`` the same per channel;
- pass 2 (histogram operator only): WARD_BINS bins of log2 Y between lo and hi, kept as their
  cumulative distribution (the operator builds its ceiling-limited curve from it per exposure).

``display_referred`` says what the values are: a standard (sRGB-trained) scene's are display
values, 1 = display white, and the adaptive operators leave them alone where they fit the display;
a linear HDR scene's have no unit, and the operators place them by their statistics.

The viewer builds the same histograms on the GPU (rendering/glsl/stats_histogram.comp) and reads
back only them; :func:`log_histograms` is the CPU twin with the same binning, so both give the
same statistics. :class:`StatsSmoother` is the thesis's temporal filter (seed 004 §5.2.2).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace

import numpy as np

LUMINANCE = (0.2126, 0.7152, 0.0722)  # Y of linear Rec.709 RGB
COVERED_ALPHA = 0.5
STATS_BINS = 2048
STATS_RANGE = (-32.0, 32.0)  # log2 radiance; 32 bins per stop
WARD_BINS = 4096
PERCENTILES = (1.0, 99.0)
# t0 of S_t = w·S_(t−1) + (1−w)·S, w = exp(−Δt/t0). Not the thesis's 0.15 s: along a 24-frame
# orbit (dofview.bench.tonemap_consistency) 0.5 s cut the display change the tone curve alone makes
# at 0.15 s by 59–90% on lamp.ply and 20–44% on the HDR biker (docs/BENCHMARKS.md)
SMOOTHING_T0_S = 0.5
CRUSHED_BELOW = 16  # an 8-bit pixel whose channels are all < 16 (linear < 0.0033 at γ 2.2) is crushed


@dataclass
class Stats:
    """Statistics of the covered pixels, log2 of linear radiance (unexposed).

    Attributes:
        lo, hi: the 1st and 99th percentile of log2 Y.
        key: mean log2 Y (log2 of the log-average luminance).
        channel_key: (3,) mean log2 R, G, B.
        channel_hi: (3,) 99th percentile of log2 R, G, B.
        peak: mean log2 Y of the brightest 1% (above the 99th percentile): the automatic key's top,
            which a lamp under 1% of the pixels still raises, continuously with its share.
        count: covered pixels the statistics came from (0: nothing covered; the values are 0).
        cdf: (WARD_BINS + 1,) the cumulative distribution of log2 Y over [cdf_lo, cdf_hi] at the
            bin edges (0 … 1; the histogram operator's input), or None.
        display_referred: the frame's values are display values (an sRGB-trained scene) rather
            than scene radiance of arbitrary unit (a linear HDR scene).
    """

    lo: float = 0.0
    hi: float = 0.0
    key: float = 0.0
    channel_key: tuple[float, float, float] = (0.0, 0.0, 0.0)
    channel_hi: tuple[float, float, float] = (0.0, 0.0, 0.0)
    peak: float = 0.0
    count: int = 0
    cdf: np.ndarray | None = None
    cdf_lo: float = 0.0
    cdf_hi: float = 0.0
    display_referred: bool = False

    def scalars(self) -> np.ndarray:
        return np.array([self.lo, self.hi, self.key, *self.channel_key, self.cdf_lo, self.cdf_hi, *self.channel_hi,
                         self.peak], np.float64)

    def to_json(self) -> str:
        """The EXR header form (the CDF as its value at every 256th entry)."""
        d = {"lo_log2": self.lo, "hi_log2": self.hi, "key_log2": self.key, "channel_key_log2": list(self.channel_key),
             "channel_hi_log2": list(self.channel_hi), "peak_log2": self.peak,
             "covered_pixels": self.count, "percentiles": list(PERCENTILES), "display_referred": self.display_referred}
        if self.cdf is not None:
            d.update(cdf_lo_log2=self.cdf_lo, cdf_hi_log2=self.cdf_hi,
                     cdf_every_256=[round(float(v), 6) for v in self.cdf[::256]])
        return json.dumps(d)


def covered(alpha: np.ndarray) -> np.ndarray:
    return np.asarray(alpha) > COVERED_ALPHA


def log_histograms(rgba: np.ndarray, lo: float, hi: float, bins: int, channels: int) -> np.ndarray:
    """(channels, bins) int64 histograms of log2 Y (and R, G, B when channels = 4) of the covered
    pixels of (H, W, 4) linear RGBA; bin = clamp(floor((log2 v − lo)/(hi − lo)·bins)), values ≤ 0
    in bin 0. float32 arithmetic, as the GPU pass does it."""
    rgba = np.asarray(rgba, np.float32).reshape(-1, 4)
    px = rgba[covered(rgba[:, 3])]
    w = np.asarray(LUMINANCE, np.float32)
    y = px[:, 0] * w[0] + px[:, 1] * w[1] + px[:, 2] * w[2]
    values = [y, px[:, 0], px[:, 1], px[:, 2]][:channels]
    scale = np.float32(bins / (hi - lo))
    out = np.zeros((channels, bins), np.int64)
    for c, v in enumerate(values):
        with np.errstate(divide="ignore", invalid="ignore"):
            x = (np.log2(v) - np.float32(lo)) * scale
        b = np.where(v > 0, np.clip(np.floor(np.nan_to_num(x, nan=0.0, posinf=bins, neginf=0.0)), 0, bins - 1), 0)
        out[c] = np.bincount(b.astype(np.int64), minlength=bins)
    return out


def _percentile(h: np.ndarray, p: float, lo: float, width: float) -> float:
    c = np.cumsum(h, dtype=np.float64)
    target = p / 100.0 * c[-1]
    i = int(np.searchsorted(c, target, side="left"))
    i = min(i, len(h) - 1)
    below = c[i - 1] if i > 0 else 0.0
    frac = (target - below) / h[i] if h[i] > 0 else 0.0
    return lo + (i + frac) * width


def _tail_mean(h: np.ndarray, p: float, lo: float, width: float) -> float:
    """Mean value of the counts above the p-th percentile of histogram ``h`` (bin centres; the
    percentile's bin counted by its share above it)."""
    c = np.cumsum(h, dtype=np.float64)
    above = np.clip(c - p / 100.0 * c[-1], 0.0, h)  # counts of each bin above the percentile
    centres = lo + (np.arange(len(h)) + 0.5) * width
    return float(above @ centres / above.sum()) if above.sum() > 0 else lo + (len(h) - 0.5) * width


def stats_from_histograms(hist: np.ndarray, display_referred: bool) -> Stats:
    """Pass-1 histograms (4, STATS_BINS) → :class:`Stats` (no CDF)."""
    lo, hi = STATS_RANGE
    width = (hi - lo) / STATS_BINS
    count = int(hist[0].sum())
    if count == 0:
        return Stats(display_referred=display_referred)
    centres = lo + (np.arange(STATS_BINS) + 0.5) * width
    keys = [float(h @ centres / max(h.sum(), 1)) for h in hist]
    his = [float(_percentile(h, PERCENTILES[1], lo, width)) for h in hist]
    return Stats(lo=float(_percentile(hist[0], PERCENTILES[0], lo, width)), hi=his[0], key=keys[0],
                 channel_key=(keys[1], keys[2], keys[3]), channel_hi=(his[1], his[2], his[3]), count=count,
                 peak=_tail_mean(hist[0], PERCENTILES[1], lo, width), display_referred=display_referred)


def with_cdf(stats: Stats, hist: np.ndarray, lo: float, hi: float) -> Stats:
    """``stats`` with the cumulative distribution of a pass-2 histogram over [lo, hi]."""
    c = np.concatenate([[0.0], np.cumsum(np.asarray(hist, np.float64))])
    cdf = c / c[-1] if c[-1] > 0 else np.linspace(0.0, 1.0, len(c))
    return replace(stats, cdf=cdf, cdf_lo=lo, cdf_hi=hi)


def cdf_domain(stats: Stats) -> tuple[float, float]:
    """The pass-2 range: [lo, hi], at least 1/32 stop wide (a constant frame has lo = hi)."""
    mid, half = (stats.lo + stats.hi) / 2, max((stats.hi - stats.lo) / 2, 1 / 64)
    return mid - half, mid + half


def frame_stats(linear: np.ndarray, operator, display_referred: bool = False) -> Stats:
    """Statistics of one (H, W, 4) linear RGBA frame for ``operator`` (CPU path);
    ``display_referred``: the scene is an sRGB-trained one (``scene.colour_space == "srgb"``)."""
    return pooled_stats([linear], operator, display_referred)


def pooled_stats(frames, operator, display_referred: bool = False) -> Stats:
    """Statistics pooled over several (H, W, 4) linear RGBA frames: ``--stats joint`` over all
    training views (seed 004 §5.1.6). Histograms add, so pooling is exact."""
    frames = list(frames)
    stats = stats_from_histograms(sum(log_histograms(f, *STATS_RANGE, STATS_BINS, 4) for f in frames), display_referred)
    if operator.needs_cdf:
        lo, hi = cdf_domain(stats)
        stats = with_cdf(stats, sum(log_histograms(f, lo, hi, WARD_BINS, 1)[0] for f in frames), lo, hi)
    return stats


@dataclass
class StatsSmoother:
    """Exponential smoothing of statistics in time (seed 004 §5.2.2):
    S_t = w·S_(t−1) + (1−w)·S_frame, w = exp(−Δt/t0), Δt the measured frame interval (s), so the
    response does not depend on the frame rate. The first update takes the frame's statistics;
    ``locked`` freezes the state. For a headless sequence call ``update(stats, 1 / fps)`` per frame.
    """

    t0: float = SMOOTHING_T0_S
    locked: bool = False
    state: Stats | None = field(default=None, repr=False)

    def reset(self) -> None:
        self.state = None

    def update(self, stats: Stats, dt: float) -> Stats:
        """Blend ``stats`` (this frame's) into the state after ``dt`` seconds; return the state."""
        if self.state is None or self.state.count == 0:
            self.state = stats
            return stats
        if self.locked or stats.count == 0:
            return self.state
        w = math.exp(-max(dt, 0.0) / self.t0)
        s = w * self.state.scalars() + (1.0 - w) * stats.scalars()
        cdf = stats.cdf
        if cdf is not None and self.state.cdf is not None and self.state.cdf.shape == cdf.shape:
            cdf = w * self.state.cdf + (1.0 - w) * cdf
        self.state = Stats(lo=s[0], hi=s[1], key=s[2], channel_key=(s[3], s[4], s[5]), count=stats.count, cdf=cdf,
                           cdf_lo=s[6], cdf_hi=s[7], channel_hi=(s[8], s[9], s[10]), peak=s[11],
                           display_referred=stats.display_referred)
        return self.state


def clipped_crushed(image: np.ndarray, alpha: np.ndarray) -> tuple[float, float]:
    """Fractions of covered pixels of an (H, W, 3) uint8 display image that are clipped (a channel
    at 255) and crushed (every channel below CRUSHED_BELOW)."""
    m = covered(alpha)
    n = max(int(m.sum()), 1)
    px = image[m]
    return float((px == 255).any(axis=1).sum() / n), float((px < CRUSHED_BELOW).all(axis=1).sum() / n)
