"""Tone mapping: display settings (:class:`Tonemap`: exposure, gamma, background, operator), the
colour transfers, and the operators by name in :data:`OPERATORS`.

Each operator is one module: a frozen dataclass whose numpy ``apply`` is the twin of its GLSL pass
``rendering/glsl/tonemap_<name>.glsl`` (see :mod:`dofview.tonemap.operator`). ``clip`` is Eq. 7
and the default; ``reinhard05``, ``histogram`` and ``bilateral`` adapt to scene statistics
(:mod:`dofview.tonemap.stats`); ``aces`` (OpenColorIO), ``aces-fit``, ``pbr-neutral`` and ``filmic``
are fixed display curves.
To add one: a module here, its .glsl, and one line in OPERATORS (the CLI's --tonemap choices, the
viewer's combo box and the GPU-vs-numpy tests follow).
"""

from __future__ import annotations

from dofview.tonemap.aces import Aces
from dofview.tonemap.aces_fit import AcesFit
from dofview.tonemap.base import (
    SCENE_ENCODING_GAMMA,
    Tonemap,
    decode,
    display,
    encode,
    to_uint8,
)
from dofview.tonemap.bilateral import Bilateral
from dofview.tonemap.clip import Clip
from dofview.tonemap.filmic import Filmic
from dofview.tonemap.histogram import Histogram
from dofview.tonemap.operator import Operator
from dofview.tonemap.pbr_neutral import PbrNeutral
from dofview.tonemap.reinhard05 import Reinhard05
from dofview.tonemap.stats import Stats, StatsSmoother, frame_stats, pooled_stats

OPERATORS: dict[str, type[Operator]] = {
    "clip": Clip,
    "reinhard05": Reinhard05,
    "histogram": Histogram,
    "bilateral": Bilateral,
    "aces": Aces,
    "aces-fit": AcesFit,
    "pbr-neutral": PbrNeutral,
    "filmic": Filmic,
}

__all__ = ["OPERATORS", "SCENE_ENCODING_GAMMA", "Aces", "AcesFit", "Bilateral", "Clip", "Filmic", "Histogram", "Operator",
           "PbrNeutral", "Reinhard05", "Stats", "StatsSmoother", "Tonemap", "decode", "display", "encode",
           "frame_stats", "pooled_stats", "to_uint8"]
