"""Tone mapping: display settings (:class:`Tonemap`: exposure, gamma, background, operator), the
colour transfers, and the operators by name in :data:`OPERATORS`.

Each operator is one module: a frozen dataclass whose numpy ``apply`` is the twin of its GLSL pass
``rendering/glsl/tonemap_<name>.glsl`` (see :mod:`dofview.tonemap.operator`). ``clip`` is Eq. 7
and the default for sRGB-trained scenes (``--tonemap auto``: :func:`default_operator`);
``reinhard05``, ``histogram`` and ``bilateral`` adapt to scene statistics
(:mod:`dofview.tonemap.stats`), compressing only what the display cannot show; ``aces`` (OpenColorIO), ``aces-fit``, ``pbr-neutral`` and ``filmic``
are fixed display curves.
To add one: a module here, its .glsl, and one line in OPERATORS (the CLI's --tonemap choices, the
viewer's combo box and the GPU-vs-numpy tests follow).
"""

from __future__ import annotations

from dofview.tonemap.aces import Aces
from dofview.tonemap.aces_fit import AcesFit
from dofview.tonemap.display import (
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
from dofview.tonemap.registry import AUTO, LINEAR_DEFAULT, OPERATORS, default_operator, operator_from_dict
from dofview.tonemap.reinhard05 import Reinhard05
from dofview.tonemap.stats import Stats, StatsSmoother, frame_stats, pooled_stats

__all__ = ["AUTO", "LINEAR_DEFAULT", "OPERATORS", "SCENE_ENCODING_GAMMA", "Aces", "AcesFit", "Bilateral", "Clip", "Filmic", "Histogram", "Operator",
           "PbrNeutral", "Reinhard05", "Stats", "StatsSmoother", "Tonemap", "decode", "display", "encode",
           "default_operator", "frame_stats", "operator_from_dict", "pooled_stats", "to_uint8"]
