"""The tone-mapping operators by name (:data:`OPERATORS`: the CLI's --tonemap choices, the viewer's
combo box), the ``auto`` choice, and an operator from its recorded form (:func:`operator_from_dict`).

Kept below :mod:`dofview.tonemap.display` so that :class:`~dofview.tonemap.Tonemap` can read an
operator back by name without importing the package that imports it.
"""

from __future__ import annotations

from dataclasses import fields

from dofview.errors import DofviewError
from dofview.tonemap.aces import Aces
from dofview.tonemap.aces_fit import AcesFit
from dofview.tonemap.bilateral import Bilateral
from dofview.tonemap.clip import Clip
from dofview.tonemap.filmic import Filmic
from dofview.tonemap.histogram import Histogram
from dofview.tonemap.operator import Operator
from dofview.tonemap.pbr_neutral import PbrNeutral
from dofview.tonemap.reinhard05 import Reinhard05

AUTO = "auto"  # --tonemap's default: the operator follows the scene's colour space (default_operator)
LINEAR_DEFAULT = "reinhard05"  # a linear HDR scene's: the most consistent along an orbit (docs/BENCHMARKS.md)

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


def default_operator(colour_space: str) -> str:
    """The operator ``--tonemap auto`` picks: ``clip`` for an sRGB-trained scene (shown exactly as
    trained), :data:`LINEAR_DEFAULT` for a linear HDR one, whose range clip would cut."""
    return "clip" if colour_space == "srgb" else LINEAR_DEFAULT


def operator_from_dict(d: dict[str, object], colour_space: str = "srgb") -> Operator:
    """The operator of :meth:`Operator.to_dict` (``{"operator": name, param: value, …}``; missing
    parameters take their defaults); the name ``auto`` is :func:`default_operator` of ``colour_space``.

    Raises:
        DofviewError: an unknown operator or parameter, named.
    """
    name = str(d.get("operator", AUTO))
    name = default_operator(colour_space) if name == AUTO else name
    if name not in OPERATORS:
        raise DofviewError(f"tone mapping: unknown operator {name!r} (one of {', '.join(OPERATORS)})")
    cls = OPERATORS[name]
    names = {f.name: f for f in fields(cls)}
    unknown = [k for k in d if k != "operator" and k not in names]
    if unknown:
        raise DofviewError(f"tone mapping: {name} has no parameter {unknown[0]!r}")
    return cls(**{k: (int(v) if names[k].type == "int" else float(v)) for k, v in d.items() if k != "operator"})
