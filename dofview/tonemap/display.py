"""From blended values to linear light and to display (Eq. 7): C̄ = op(2^EV·C)^(1/γ).

Colour space matters. A standard 3DGS scene was fit to sRGB photos, so its blended values are
display-encoded: they are decoded (with the scene's encoding gamma) before exposure is applied and
encoded again after, so that 0 EV with γ = 2.2 reproduces the trained image and gamma is never
applied twice. An HDR scene blends linear radiance and only gets the display gamma.

The linear image of an encoded scene is decode(C) of the blend C over black; its alpha is the
coverage. So tonemapping the EXR reproduces the PNG exactly (black background).

Between exposure and gamma sits the operator (``Tonemap.operator``, one of
:data:`dofview.tonemap.OPERATORS`); the default :class:`~dofview.tonemap.clip.Clip` is Eq. 7's
clip to [0, 1]. The GPU pass in ``rendering/glsl/tonemap.frag`` computes the same as
:func:`display`; tests hold them equal.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dofview.errors import DofviewError
from dofview.lens import exposure_from_ev
from dofview.tonemap.clip import Clip
from dofview.tonemap.operator import Operator
from dofview.tonemap.registry import AUTO, default_operator, operator_from_dict
from dofview.tonemap.stats import Stats

SCENE_ENCODING_GAMMA = 2.2  # the transfer of the photos a standard 3DGS scene was fit to
EV_LIMIT = 100.0  # |EV| beyond this: a multiplier 2^EV outside float32's normal range soon after


@dataclass(frozen=True)
class Tonemap:
    """Display settings.

    Attributes:
        exposure: exposure in EV stops, as the CLI's ``--exposure``, the viewer's slider and the EXR
            header's ``dofview:exposure``: the linear light is scaled by :attr:`multiplier` = 2^EV
            (a shutter time t at f-number N is EV = log2(t/N²)). Adaptive operators apply it after
            normalising the scene by its statistics, so 0 EV is their automatic exposure.
        gamma: display gamma γ, > 0.
        background: display-encoded background colour, each in [0, 1].
        operator: the tone curve between exposure and gamma (an entry of OPERATORS).
    """

    exposure: float = 0.0
    gamma: float = 2.2
    background: tuple[float, float, float] = (0.0, 0.0, 0.0)
    operator: Operator = field(default_factory=Clip)

    def __post_init__(self) -> None:
        if not (np.isfinite(self.exposure) and abs(self.exposure) <= EV_LIMIT):
            raise DofviewError(f"exposure must be a finite number of EV stops in [-{EV_LIMIT:g}, {EV_LIMIT:g}], "
                               f"got {self.exposure}")
        if not (np.isfinite(self.gamma) and self.gamma > 0):
            raise DofviewError(f"gamma must be finite and > 0, got {self.gamma}")

    @property
    def multiplier(self) -> float:
        """The linear factor 2^exposure that scales the light (Eq. 7's exposure)."""
        return exposure_from_ev(self.exposure)

    def to_dict(self) -> dict[str, object]:
        """The display settings as plain data: exposure (EV), gamma, background (list of 3) and
        ``tonemap``, the operator as the EXR header's ``dofview:tonemap`` records it:
        ``{"operator": name, param: value, …}``."""
        return {"exposure": self.exposure, "gamma": self.gamma, "background": list(self.background),
                "tonemap": {"operator": self.operator.name, **self.operator.params()}}

    @classmethod
    def from_dict(cls, d: dict[str, object], colour_space: str = "srgb") -> "Tonemap":
        """The settings of :meth:`to_dict`; missing entries take their defaults, and the operator
        ``auto`` (or none) is the default operator of ``colour_space``, as ``--tonemap auto``."""
        background = tuple(float(c) for c in d.get("background", (0.0, 0.0, 0.0)))  # type: ignore[union-attr]
        return cls(exposure=float(d.get("exposure", 0.0)), gamma=float(d.get("gamma", 2.2)),  # type: ignore[arg-type]
                   background=background,  # type: ignore[arg-type]
                   operator=operator_from_dict(d.get("tonemap", {"operator": AUTO}), colour_space))  # type: ignore[arg-type]

    def to_args(self, colour_space: str = "srgb") -> list[str]:
        """``dofview render`` arguments that give these settings on a scene in ``colour_space``:
        --exposure, --gamma, --background when not black, and --tonemap with every parameter
        unless the operator is ``auto``'s choice for that colour space with no parameters."""
        args = ["--exposure", repr(float(self.exposure)), "--gamma", repr(float(self.gamma))]
        if any(self.background):
            args += ["--background", ",".join(repr(float(c)) for c in self.background)]
        op, params = self.operator.name, self.operator.params()
        if op != default_operator(colour_space) or params:
            args += ["--tonemap", op, *(f"--{op}-{k.replace('_', '-')}={v!r}" for k, v in params.items())]
        return args


def decode(c: np.ndarray) -> np.ndarray:
    """Display-encoded → linear: max(C, 0)^2.2."""
    return np.power(np.maximum(c, 0.0), SCENE_ENCODING_GAMMA)


def encode(c: np.ndarray) -> np.ndarray:
    """Linear → display-encoded: max(C, 0)^(1/2.2), the inverse of :func:`decode`."""
    return np.power(np.maximum(c, 0.0), 1.0 / SCENE_ENCODING_GAMMA)


def display(linear: np.ndarray, encoded: bool, tm: Tonemap, stats: Stats | None = None,
            depth: np.ndarray | None = None) -> np.ndarray:
    """(H, W, 4) linear RGBA → (H, W, 3) float64 display values in [0, 1] (before 8-bit rounding).

    The background is composited in the blend's own space, as the scene was trained, then the
    result is exposed in linear light, tone mapped by ``tm.operator`` and gamma-encoded.
    ``stats``: the scene statistics adaptive operators need (:func:`dofview.tonemap.stats.frame_stats`;
    taken from this image when omitted, display-referred when ``encoded``: give them for the linear
    blend of an sRGB scene). ``depth``: (H, W) camera z, scene units (the bilateral
    operator's depth term; 0 = nothing drawn).
    """
    linear = np.asarray(linear, dtype=np.float64)
    bg = np.asarray(tm.background, dtype=np.float64)
    t = 1.0 - linear[..., 3:4]
    if encoded:
        lin = decode(encode(linear[..., :3]) + t * bg)
    else:
        lin = linear[..., :3] + t * decode(bg)
    lin = np.nan_to_num(lin * tm.multiplier, nan=0.0, posinf=1.0)
    op = tm.operator
    if op.adaptive and stats is None:
        from dofview.tonemap.stats import frame_stats

        stats = frame_stats(linear, op, encoded)
    mapped = op.apply(lin, stats=stats, exposure=tm.multiplier, alpha=linear[..., 3], depth=depth)
    return np.power(np.clip(mapped, 0.0, 1.0), 1.0 / tm.gamma)


def to_uint8(img: np.ndarray) -> np.ndarray:
    """[0, 1] floats → uint8, rounded to nearest."""
    return (np.clip(img, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
