"""From scene, camera and lens to a frame: the GPU backends behind one interface
(:class:`~dofview.rendering.base.Renderer`), the sort, the CPU reference renderer and the
thin-lens accumulation that is the ground truth for depth of field. The GLSL is in ``glsl/``.

:data:`BACKENDS` is the one place a backend is named; :func:`get_backend` builds one.
"""

from __future__ import annotations

import importlib

import moderngl

from dofview.errors import BackendUnavailable, DofviewError
from dofview.rendering.base import Renderer
from dofview.rendering.gl import headless_context
from dofview.scene import GaussianScene

BACKENDS: dict[str, str] = {
    "quad": "dofview.rendering.quad:QuadBackend",
    "compute": "dofview.rendering.compute:ComputeBackend",
}
"""Backend name → ``"module:class"``; ``"auto"`` picks among them (see :func:`get_backend`)."""

AUTO_ORDER: tuple[str, ...] = ("quad", "compute")
"""The order ``"auto"`` tries backends in: the first that this GL can run. Quad first, as measured
on Mesa llvmpipe (docs/BENCHMARKS.md "Compute backend", 1200×675, sort every frame): compute/quad
frame time 1.20× / 1.37× on the cards sample and 1.03× / 1.11× on burger.ply at A = 0 / 100, but
0.95× / 0.93× on the lamp sample and 0.77× / 0.80× at 1M Gaussians: quad wins the small scenes
rendered here and is the reference. Not yet measured on a GPU (scripts/gpu_bench.sh), where the
order may change."""


def backend_class(name: str) -> type[Renderer]:
    if name not in BACKENDS:
        raise DofviewError(f"unknown renderer backend {name!r}; expected one of {', '.join(['auto', *BACKENDS])}")
    module, _, cls = BACKENDS[name].partition(":")
    return getattr(importlib.import_module(module), cls)


def get_backend(name: str, scene: GaussianScene, ctx: moderngl.Context | None = None, **kw) -> Renderer:
    """A renderer for ``scene`` on backend ``name`` (a key of :data:`BACKENDS`, or ``"auto"``: the
    first of :data:`AUTO_ORDER` whose :meth:`~Renderer.require` probe passes on this GL; the scene
    is uploaded only to the backend that takes it).

    Raises:
        BackendUnavailable: the named backend cannot run on this GL.
        DofviewError: an unknown name.
    """
    if name != "auto":
        return backend_class(name)(scene, ctx=ctx, **kw)
    ctx = ctx or headless_context()
    reasons = []
    for cand in AUTO_ORDER:
        cls = backend_class(cand)
        try:
            cls.require(ctx, scene.count)
            return cls(scene, ctx=ctx, **kw)
        except BackendUnavailable as e:  # from the probe, or a shader this GL cannot compile
            reasons.append(f"{cand}: {e}")
    raise BackendUnavailable("no renderer backend runs here (" + "; ".join(reasons) + ")")


__all__ = ["BACKENDS", "AUTO_ORDER", "BackendUnavailable", "Renderer", "backend_class", "get_backend"]
