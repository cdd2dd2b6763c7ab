"""dofview: a camera lens (focus, aperture, exposure) for trained 3D Gaussian Splatting scenes.

The Python API (see :mod:`dofview.api`): ``load``, ``load_cameras``, ``render``, ``render_deep``,
``read_header``, and the types ``Camera``, ``Lens``, ``PhysicalLens``, ``LensRequest``, ``BlurSpec``,
``RenderSettings``, ``Frame``, ``DeepFrame``, ``DeepSettings``, ``Tonemap``, ``GaussianScene`` (the camera, lens, request, settings
and tone mapping as data: their ``to_dict``/``from_dict``, and ``to_args`` for ``dofview render``). They are imported on first use, so ``import dofview.io.ply`` stays light.
"""

__version__ = "0.1.0"

_EXPORTS = {
    "load": "dofview.api", "load_cameras": "dofview.api", "render": "dofview.api", "render_deep": "dofview.api",
    "read_header": "dofview.api", "DeepFrame": "dofview.deep", "DeepSettings": "dofview.deep",
    "Camera": "dofview.camera", "look_at": "dofview.camera",
    "Lens": "dofview.lens", "PhysicalLens": "dofview.lens", "LensRequest": "dofview.lens", "BlurSpec": "dofview.lens",
    "Frame": "dofview.frame", "RenderSettings": "dofview.frame",
    "Tonemap": "dofview.tonemap", "GaussianScene": "dofview.scene",
    "DofviewError": "dofview.errors",
}
__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str):
    if name in _EXPORTS:
        import importlib

        value = getattr(importlib.import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'dofview' has no attribute {name!r}")
