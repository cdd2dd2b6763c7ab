"""Thin lens and exposure: circle of confusion, aperture strength, physical lens (Eq. 3), t/N².

The circle of confusion of a point at camera depth z is R(z) = ½·A·|1/z − 1/d_f| pixels, where
A is the aperture strength in px·(scene unit) (the poster's form). A physical thin lens with
focal length f, f-number N and focus d_f gives the same curve with A = f_x·(f/N)·d_f/(d_f − f)
(Cinematic Gaussians Eq. 3), f_x in pixels and all lengths in scene units.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from dofview.errors import DofviewError


@dataclass(frozen=True)
class Lens:
    """A thin lens at render time.

    Attributes:
        focus: focus distance d_f, camera z-depth in scene units (> 0, may be inf).
        aperture: strength A in px·(scene unit), ≥ 0; 0 is a pinhole.
    """

    focus: float = 1.0
    aperture: float = 0.0

    def __post_init__(self) -> None:
        if not (self.focus > 0) or math.isnan(self.focus):
            raise DofviewError(f"focus distance must be > 0, got {self.focus}")
        if not (self.aperture >= 0) or not math.isfinite(self.aperture):
            raise DofviewError(f"aperture must be a finite value ≥ 0, got {self.aperture}")

    @property
    def inv_focus(self) -> float:
        return 0.0 if math.isinf(self.focus) else 1.0 / self.focus

    def coc_radius(self, z) -> np.ndarray:
        """CoC radius in pixels for camera depth ``z`` (scene units, any shape)."""
        z = np.asarray(z, dtype=np.float64)
        return 0.5 * self.aperture * np.abs(1.0 / z - self.inv_focus)

    def diameter(self, fx: float) -> float:
        """Aperture diameter D in scene units for a camera with ``fx`` pixels (A = f_x·D)."""
        return self.aperture / fx

    def to_dict(self) -> dict[str, float]:
        """``{"focus": d_f, "aperture": A}`` (scene units; px·scene unit on the image drawn)."""
        return {"focus": self.focus, "aperture": self.aperture}

    @classmethod
    def from_dict(cls, d: dict[str, object]) -> "Lens":
        """The lens of :meth:`to_dict` (other entries, such as a header's :class:`LensRequest`, are ignored)."""
        try:
            return cls(float(d["focus"]), float(d["aperture"]))  # type: ignore[arg-type]
        except (KeyError, TypeError, ValueError) as e:
            raise DofviewError(f"lens record: missing or malformed entry ({e})") from None

    def aperture_at(self, width: int, ref_width: int) -> float:
        """The ``--aperture`` value of this lens on an image ``width`` wide whose strengths hold at
        ``ref_width``: the strength at ``ref_width`` that :meth:`dofview.camera.Camera.scaled_aperture`
        turns back into :attr:`aperture` bit for bit where a float does (A·ref_width/width alone
        may be off by its last bits), else the one that comes nearest, within a unit in the last
        place of A."""
        a = self.aperture
        if width != ref_width and a > 0:
            given = a * ref_width / width
            near = [given]
            up = down = given
            for _ in range(4):  # the best value is within a few ulps of the quotient
                up, down = math.nextafter(up, math.inf), math.nextafter(down, 0.0)
                near += [up, down]
            a = min(near, key=lambda c: abs(c * width / ref_width - self.aperture))
        return float(a)

    def to_args(self, width: int, ref_width: int) -> list[str]:
        """``dofview render`` arguments for this lens on an image ``width`` wide whose aperture
        strengths hold at ``ref_width``: --focus, and --aperture :meth:`aperture_at`."""
        return ["--focus", repr(float(self.focus)), "--aperture", repr(self.aperture_at(width, ref_width))]


@dataclass(frozen=True)
class PhysicalLens:
    """A physical thin lens: focal length and sensor in mm, scene scale in units per metre."""

    focal_mm: float
    fnumber: float
    sensor_mm: float = 36.0
    units_per_metre: float = 1.0

    def __post_init__(self) -> None:
        for name in ("focal_mm", "fnumber", "sensor_mm", "units_per_metre"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise DofviewError(f"{name.replace('_', '-')} must be a finite value > 0, got {v}")

    @property
    def focal_units(self) -> float:
        """Focal length in scene units."""
        return self.focal_mm * 1e-3 * self.units_per_metre

    def strength(self, fx: float, focus: float) -> float:
        """Aperture strength A (px·scene unit) for focus distance ``focus`` (scene units).

        Eq. 3 of Cinematic Gaussians: R = ½·f_x·(f/N)·d_f/(d_f − f)·|1/z − 1/d_f|. Focusing at or
        inside the focal length has no real image: that is refused, not divided by zero.
        """
        f = self.focal_units
        if math.isinf(focus):
            return fx * f / self.fnumber
        if not focus > f:
            raise DofviewError(
                f"focus distance {focus:g} must be beyond the focal length ({f:g} scene units "
                f"= {self.focal_mm:g} mm at {self.units_per_metre:g} units per metre)")
        return fx * (f / self.fnumber) * focus / (focus - f)

    def lens(self, fx: float, focus: float) -> Lens:
        return Lens(focus=focus, aperture=self.strength(fx, focus))


def aperture_for_blur(radius_px: float, focus: float, near: float, far: float) -> float:
    """Aperture strength A (px·scene unit) at which the largest blur in view has ``radius_px``.

    The largest blur is at the nearest or the farthest depth in view (``near``, ``far``: camera
    z in scene units, 0 < near ≤ far, far may be inf), for focus distance ``focus``:
    R = ½·A·|1/z − 1/d_f|. A flat view (near = far = focus) would need an infinite aperture, so
    the spread is taken as at least 10 % of 1/focus.
    """
    if not (math.isfinite(radius_px) and radius_px >= 0):
        raise DofviewError(f"blur radius must be a finite number of pixels ≥ 0, got {radius_px}")
    inv_f = 0.0 if math.isinf(focus) else 1.0 / focus
    inv_near = 1.0 / near
    inv_far = 0.0 if math.isinf(far) else 1.0 / far
    worst = max(abs(inv_near - inv_f), abs(inv_far - inv_f), 0.1 * (inv_f or inv_near))
    return 2.0 * radius_px / worst


def aperture_at_depth(radius_px: float, focus: float, depth: float) -> float:
    """Aperture strength A (px·scene unit) at which a point at camera depth ``depth`` (scene
    units, may be inf) has a blur of radius ``radius_px`` for focus distance ``focus``:
    A = 2·R / |1/depth − 1/d_f|. The focus plane itself has no blur to ask for: refused."""
    if not (math.isfinite(radius_px) and radius_px >= 0):
        raise DofviewError(f"blur radius must be a finite number of pixels ≥ 0, got {radius_px}")
    inv_d, inv_f = (0.0 if math.isinf(v) else 1.0 / v for v in (depth, focus))
    spread = abs(inv_d - inv_f)
    if spread <= 1e-9 * max(inv_d, inv_f):
        raise DofviewError(f"blur at depth {depth:g}: that is the focus distance, where nothing is blurred; "
                           "name a depth in front of or behind it")
    return 2.0 * radius_px / spread


BLUR_MAX_FRACTION = 0.25
"""The largest ``--blur`` radius, as a fraction of the image width. Beyond it a blur spreads light
past the guard band the sliced mode renders around the frame (at most an eighth of it), and the
frame darkens: samples/cards.ply at --focus 4 loses 1 % of its mean brightness at 25 %, 8 % at
50 %, 23 % at 100 %, and more than half at 500 %."""


@dataclass(frozen=True)
class BlurSpec:
    """Depth of field asked for by the blur it makes (``--blur``), not by a strength in px·scene unit.

    Attributes:
        radius: blur radius, pixels at the camera's reference width (``percent``: % of the image width).
        percent: ``radius`` is a percentage of the image width.
        depth: camera depth (scene units, may be inf) that gets this blur; None: the largest blur in
            view, at the nearest or farthest depth in view.
    """

    radius: float
    percent: bool = False
    depth: float | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.radius) and self.radius >= 0):
            raise DofviewError(f"blur radius must be a finite number ≥ 0, got {self.radius}")
        if self.percent and self.radius > 100.0 * BLUR_MAX_FRACTION:
            raise DofviewError(f"blur radius must be at most {100 * BLUR_MAX_FRACTION:g}% of the image width "
                               f"(a larger blur spreads light off the frame and darkens it), got {self}")
        if self.depth is not None and not self.depth > 0:
            raise DofviewError(f"the depth of a blur must be > 0, got {self.depth}")

    def __str__(self) -> str:
        depth = "" if self.depth is None else f"@{self.depth:g}"
        return f"{self.radius:g}{'%' if self.percent else ''}{depth}"

    def to_text(self) -> str:
        """The ``--blur`` value at full float precision (``str`` rounds to 6 digits, as headers show it)."""
        depth = "" if self.depth is None else f"@{self.depth!r}"
        return f"{float(self.radius)!r}{'%' if self.percent else ''}{depth}"

    @classmethod
    def parse(cls, text: str) -> "BlurSpec":
        """A ``--blur`` value: ``R`` (pixels at the reference width), ``R%`` (of the image width),
        each optionally ``@DEPTH`` (scene units or inf).

        Raises:
            DofviewError: not such a value, with what is wrong.
        """
        radius, sep, depth = text.partition("@")
        percent = radius.endswith("%")
        r = _parse_number(radius[:-1] if percent else radius, "blur radius", positive=False, shown=radius)
        if not sep:
            return cls(r, percent)
        if not depth:
            raise DofviewError("--blur: a blur radius such as 4 (pixels), 0.5% (of the image width) or 4@inf "
                               f"(at a depth); got {text!r}")
        d = math.inf if depth in ("inf", "infinity") else _parse_number(depth, "blur depth", positive=True)
        return cls(r, percent, d)

    def radius_px(self, width: int, ref_width: int) -> float:
        """The radius in pixels on an image ``width`` wide whose reference width is ``ref_width``.

        Raises:
            DofviewError: a radius in pixels beyond :data:`BLUR_MAX_FRACTION` of the reference width.
        """
        if self.percent:
            return self.radius / 100.0 * width
        if self.radius > BLUR_MAX_FRACTION * ref_width:
            raise DofviewError(f"--blur {self}: {self.radius:g} px is more than {100 * BLUR_MAX_FRACTION:g}% of "
                               f"the {ref_width} px reference width (at most {BLUR_MAX_FRACTION * ref_width:g} px; "
                               "a larger blur spreads light off the frame and darkens it)")
        return self.radius * width / ref_width

    def aperture(self, width: int, ref_width: int, focus: float,
                 span: tuple[float, float] | None) -> float:
        """Aperture strength A (px·scene unit) on an image ``width`` wide, for focus ``focus``;
        ``span`` = (near, far) depths in view (scene units), needed when :attr:`depth` is None."""
        radius = self.radius_px(width, ref_width)
        if self.depth is not None:
            return aperture_at_depth(radius, focus, self.depth)
        if span is None:
            raise DofviewError(f"--blur {self}: nothing in view to measure the largest blur on; "
                               "name a depth (--blur R@DEPTH) or give --aperture")
        return aperture_for_blur(radius, focus, *span)


def _parse_number(text: str, what: str, positive: bool, shown: str | None = None) -> float:
    """A finite number ≥ 0 (> 0 when ``positive``) written as ``text``; DofviewError naming ``what``
    and the value as the user wrote it (``shown``, default ``text``)."""
    shown = text if shown is None else shown
    try:
        v = float(text)
    except ValueError:
        raise DofviewError(f"{what} must be a number, got {shown!r}") from None
    if not math.isfinite(v):
        raise DofviewError(f"{what} must be finite, got {shown!r}")
    if v < 0 or (positive and v == 0):
        raise DofviewError(f"{what} must be {'>' if positive else '≥'} 0, got {shown}")
    return v


class SizedCamera(Protocol):
    """What resolving a :class:`LensRequest` reads of a :class:`dofview.camera.Camera`."""

    fx: float
    width: int
    ref_width: int

    def scaled_aperture(self, aperture: float) -> float: ...


@dataclass(frozen=True)
class LensRequest:
    """How the depth of field was asked for (the command's lens options, before a camera and a
    focus resolve them to a :class:`Lens`): a strength A at the camera's reference width
    (``--aperture``), a blur (``--blur``), or a physical lens (``--fnumber`` with ``--focal-mm``,
    on ``sensor_mm`` and ``units_per_metre``). At most one way; none is a pinhole.

    Raises:
        DofviewError: more than one way, or half a physical lens.
    """

    aperture: float | None = None
    blur: BlurSpec | None = None
    fnumber: float | None = None
    focal_mm: float | None = None
    sensor_mm: float = 36.0
    units_per_metre: float = 1.0

    def __post_init__(self) -> None:
        physical = self.fnumber is not None or self.focal_mm is not None
        if sum((physical, self.aperture is not None, self.blur is not None)) > 1:
            raise DofviewError("give the aperture one way: --aperture A, --blur R or --fnumber/--focal-mm")
        if physical and (self.fnumber is None or self.focal_mm is None):
            raise DofviewError("a physical lens needs both --fnumber and --focal-mm")

    @property
    def physical(self) -> PhysicalLens | None:
        if self.fnumber is None or self.focal_mm is None:
            return None
        return PhysicalLens(self.focal_mm, self.fnumber, self.sensor_mm, self.units_per_metre)

    @property
    def needs_span(self) -> bool:
        """Whether resolving needs the depth range in view (``--blur R`` without ``@DEPTH``)."""
        return self.blur is not None and self.blur.depth is None

    def lens(self, camera: SizedCamera, focus: float, span: tuple[float, float] | None = None) -> Lens:
        """The lens on ``camera`` at ``focus`` (scene units): --aperture A scaled from the camera's
        reference width to its width, --blur resolved on ``span`` (the (near, far) depths in view,
        scene units), or the physical lens through f_x (which scales with the width by itself)."""
        physical = self.physical
        if physical is not None:
            return physical.lens(camera.fx, focus)
        if self.blur is not None:
            return Lens(focus=focus, aperture=self.blur.aperture(camera.width, camera.ref_width, focus, span))
        return Lens(focus=focus, aperture=camera.scaled_aperture(self.aperture or 0.0))

    def asked(self) -> str:
        """The options as given, in words for the header (``--blur 1%``, ``--aperture 60``, …)."""
        if self.blur is not None:
            return f"--blur {self.blur}"
        if self.physical is not None:
            return f"--fnumber {self.fnumber:g} --focal-mm {self.focal_mm:g}"
        return f"--aperture {self.aperture or 0.0:g}"

    def to_dict(self) -> dict[str, object]:
        """What the EXR header's ``dofview:lens`` records besides the :class:`Lens`: fnumber,
        focal_mm (None unless physical), sensor_mm, units_per_metre and ``asked`` (:meth:`asked`)."""
        return {"fnumber": self.fnumber, "focal_mm": self.focal_mm, "sensor_mm": self.sensor_mm,
                "units_per_metre": self.units_per_metre, "asked": self.asked()}

    @classmethod
    def from_dict(cls, d: dict[str, object]) -> "LensRequest":
        """The request of :meth:`to_dict` (other entries, such as the :class:`Lens`'s, are ignored;
        a header without ``asked`` records a strength or a physical lens by its values).

        Raises:
            DofviewError: a malformed entry, named.
        """
        asked = str(d.get("asked", ""))
        kind, _, value = asked.partition(" ")
        blur = BlurSpec.parse(value) if kind == "--blur" else None
        aperture = _parse_number(value, "aperture", positive=False) if kind == "--aperture" else None

        def opt(name: str) -> float | None:
            v = d.get(name)
            return None if v is None else float(v)  # type: ignore[arg-type]

        return cls(aperture=aperture, blur=blur, fnumber=opt("fnumber"), focal_mm=opt("focal_mm"),
                   sensor_mm=opt("sensor_mm") or 36.0, units_per_metre=opt("units_per_metre") or 1.0)

    def to_args(self) -> list[str]:
        """``dofview render`` lens arguments that make this request (full float precision)."""
        if self.blur is not None:
            return ["--blur", self.blur.to_text()]
        if self.physical is not None:
            return ["--fnumber", repr(float(self.fnumber)), "--focal-mm", repr(float(self.focal_mm)),  # type: ignore[arg-type]
                    "--sensor-mm", repr(float(self.sensor_mm)), "--units-per-metre", repr(float(self.units_per_metre))]
        return [] if self.aperture is None else ["--aperture", repr(float(self.aperture))]


def exposure_from_ev(ev: float) -> float:
    """Linear exposure multiplier 2^EV."""
    if not math.isfinite(ev):
        raise DofviewError(f"exposure must be a finite number of stops, got {ev}")
    return float(2.0 ** ev)


def exposure_from_shutter(t: float, fnumber: float) -> float:
    """Linear exposure t/N² (Eq. 7), for exposure time ``t`` seconds and f-number ``fnumber``."""
    if not (t > 0 and math.isfinite(t) and fnumber > 0 and math.isfinite(fnumber)):
        raise DofviewError(f"exposure time and f-number must be > 0, got t={t}, N={fnumber}")
    return float(t / fnumber ** 2)


def shutter_ev(t: float, fnumber: float) -> float:
    """The exposure in EV stops of exposure time ``t`` seconds at f-number ``fnumber``: log2(t/N²)."""
    return math.log2(exposure_from_shutter(t, fnumber))


# ---- the per-Gaussian lens math, written once for numpy arrays and torch tensors alike ----------
# (only arithmetic and the array's own sqrt/exp/log, so the CPU reference and the trainer share
# it; rendering/glsl/quads.vert is its GPU twin, held equal by the GL-vs-reference tests)
LOW_PASS = 0.3  # px², the reference rasteriser's screen-space low-pass filter
ALPHA_MAX = 0.99
SUPPORT_MAX = 9.0  # dᵀΣ⁻¹d at 3σ: the support cut whatever τ


def coc(inv_z, aperture, inv_focus):
    """CoC radius in pixels, R = ½·A·|1/z − 1/d_f|, from the inverse depth 1/z (any array)."""
    return 0.5 * aperture * abs(inv_z - inv_focus)


def blur_footprint(sxx, sxy, syy, det_p, radius, k):
    """Add the low-pass and the aperture Gaussian k·R²·I to a projected covariance P Pᵀ.

    ``sxx, sxy, syy`` are the entries of P Pᵀ (px²), ``det_p`` = |p₀ × p₁|² its determinant (kept
    as a sum of squares so it never cancels), ``radius`` the CoC radius. Returns the blurred
    (sxx, sxy, syy, det) and β = sqrt(det Σ₂ / det Σ₂′), Σ₂ being the pinhole footprint with its
    low-pass. Every determinant is a sum of positives.
    """
    add = LOW_PASS + k * radius * radius
    trace = sxx + syy
    det0 = det_p + LOW_PASS * trace + LOW_PASS * LOW_PASS
    det = det_p + add * trace + add * add
    beta = (det0 / det) ** 0.5
    return sxx + add, sxy, syy + add, det, beta


def cut_splat(opacity, tau: float, mode: str, xp=np):
    """The τ cut of splats of opacity o′ (lens.glsl's cut_splat): returns (kept, opacity drawn,
    support bound r2 on dᵀΣ′⁻¹d, ≤ 9). "drop": o′ where α ≥ τ, q ≤ 2 ln(o′/τ), culled when
    o′ < τ; "conserve": o′ + τ inside q ≤ 2 ln(1 + o′/τ), which carries the untruncated mass."""
    o = opacity  # bounds by .clip (numpy arrays and torch tensors alike; xp.minimum wants two arrays in torch)
    if tau > 0 and mode == "conserve":
        return o > 0, o + tau, (2.0 * xp.log1p(o / tau)).clip(max=SUPPORT_MAX)
    kept = (o > 0) & (o.clip(max=ALPHA_MAX) >= tau)
    if tau == 0:
        return kept, o, xp.full_like(o, SUPPORT_MAX)
    return kept, o, (2.0 * xp.log(o.clip(min=1e-300) / tau)).clip(max=SUPPORT_MAX)


def normalise_opacity(opacity, beta, mode: str, xp=np):
    """Opacity o′ of a blurred Gaussian: "energy" o·β (Eq. 5), "optical-depth" 1 − (1 − o)^β, "none"."""
    if mode == "energy":
        return opacity * beta
    if mode == "optical-depth":
        return 1.0 - xp.exp(beta * xp.log(1.0 - xp.clip(opacity, 0.0, ALPHA_MAX)))
    return opacity


# ---- the disk kernel (RenderSettings.kernel "disk") ---------------------------------------------
# The thin lens convolves each splat with a uniform disk of the CoC radius, not with a Gaussian.
# The blurred footprint Σ₂′ = Σ₂ + k·R²·I keeps its ellipse (k = 1/4: the disk's second moment)
# and only its radial profile changes: in Σ₂′'s whitened units (q = dᵀΣ₂′⁻¹d, r = √q) the splat is
# a Gaussian of std σ̃ (σ̃² = s) spread over a disk of radius R̃ = 2·sqrt(1 − s), where
# s = σ²/(σ² + k·R²) and σ² = sqrt(det Σ₂) (the geometric mean of the footprint's variances).
# s = 1 is the Gaussian kernel; s → 0 is the bare disk of radius 2·sqrt(k)·R. The profile is the
# 1-D box ⊛ Gaussian used radially, F(r) = ½(erf((R̃ + r)/(√2σ̃)) + erf((R̃ − r)/(√2σ̃))): exact
# in both limits, an approximation in between and for anisotropic splats.
DISK_MIN_RATIO = 6.25e-4  # k·R²/σ² below this (disk radius < 5 % of σ) draws the Gaussian kernel
_AS = (0.254829592, -0.284496736, 1.421413741, -1.453152027, 1.061405429)  # Abramowitz-Stegun 7.1.26


def erf(x, xp=np):
    """erf to 1.5e-7 (Abramowitz and Stegun 7.1.26), with only abs/exp/where, like lens.glsl's."""
    a = abs(x)
    t = 1.0 / (1.0 + 0.3275911 * a)
    poly = t * (_AS[0] + t * (_AS[1] + t * (_AS[2] + t * (_AS[3] + t * _AS[4]))))
    y = 1.0 - poly * xp.exp(-a * a)
    return xp.where(x < 0, -y, y)


def kernel_shape(beta, det, radius, k, xp=np):
    """Shape s ∈ (0, 1] of the disk kernel from blur_footprint's β and det (det Σ₂ = β²·det):
    s = σ²/(σ² + k·R²), σ² = sqrt(det Σ₂); 1 (the Gaussian) when the disk is < 5 % of σ."""
    var = beta * det ** 0.5
    ratio = k * radius * radius / var
    return xp.where(ratio < DISK_MIN_RATIO, 1.0, 1.0 / (1.0 + ratio))


def _disk_axes(s, xp=np):
    """(σ̃, R̃, 1/(√2·σ̃)) of shape s, in whitened units."""
    sig = xp.sqrt(s)
    return sig, 2.0 * xp.sqrt(xp.maximum(1.0 - s, 0.0)), 0.7071067811865476 / sig


def disk_peak_and_area(s, xp=np):
    """(F(0), area ratio m) of the disk profile of shape s < 1: F(0) = erf(b/√2), b = R̃/σ̃, and
    m = ∫Gaussian / ∫F/F(0) over the whitened plane = F(0)/M, M = ∫₀^∞ r F(r) dr
    = ½(R̃² + σ̃²)·erf(b/√2) + σ̃·R̃·φ(b) (φ the standard normal density); m → 1 as s → 1."""
    sig, rad, inv = _disk_axes(s, xp)
    f0 = erf(rad * inv, xp)
    b = rad / sig
    mass = 0.5 * (rad * rad + s) * f0 + sig * rad * 0.3989422804014327 * xp.exp(-0.5 * b * b)
    return f0, f0 / mass


def disk_support(opacity, tau: float, s, xp=np):
    """Support bound r2 on q for a disk splat of peak opacity o′ (shape s < 1): r ≤ R̃ + 3σ̃ always,
    and with τ > 0, r ≤ R̃ + σ̃·sqrt(2 ln(o′·c/τ)) where α ≥ τ can still hold, from
    F(r) ≤ min(½, 2R̃·φ(0)/σ̃)·exp(−(r − R̃)²/(2σ̃²)) for r ≥ R̃, c = that minimum over F(0)."""
    sig, rad, _ = _disk_axes(s, xp)
    f0, _ = disk_peak_and_area(s, xp)
    n = xp.full_like(s, SUPPORT_MAX)
    if tau > 0:
        c = xp.minimum(0.5, 0.7978845608028654 * rad / sig) / f0
        n = xp.minimum(n, xp.maximum(2.0 * xp.log(xp.maximum(opacity * c, 1e-300) / tau), 0.0))
    r = rad + sig * xp.sqrt(n)
    return r * r


def disk_profile(q, s, xp=np):
    """F(√q) of shape s < 1 (unnormalised: the splat's α is o′·F/F(0), clamped and cut)."""
    _, rad, inv = _disk_axes(s, xp)
    r = xp.sqrt(q)
    return 0.5 * (erf((rad + r) * inv, xp) + erf((rad - r) * inv, xp))
