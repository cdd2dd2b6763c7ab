"""The sliced mode's plan of a frame, made on the GPU: the twin of slices.plan_frame with no
per-Gaussian work on the CPU and no read-back of the draw order.

The signed CoC c = ½·A·(1/z − 1/d_f) falls as the depth grows, so a layer is a contiguous range of
the depth order and every comparison of a Gaussian's c with a value is one of its depth key (the
uint32 the order was sorted by, glsl/sort_key.glsl) with that value's threshold key
(:func:`key_threshold`). The kernels (glsl/plan_*.comp) read the draw order where the backend keeps
it (:meth:`Renderer.draw_order`) and make each Gaussian's key again from its mean, bit for bit the
sort's (project.glsl: camera_depth; depth_order.camera_depths is the CPU's twin):

1. plan_lattice.comp, one invocation: the live Gaussians' CoC range from the first live and the
   last key of a sorted order (binary search), and the lattice of slice edges over it
   (slices.slice_edges, in double precision op for op);
2. plan_snap.comp, one workgroup per edge, dispatched indirectly (the GPU knows how many): each
   inner edge moved into the widest gap between the CoCs near it (slices.snap_edges; the gaps are
   differences of consecutive sorted keys' CoCs), and each edge's threshold key;
3. plan_bounds.comp: each slot's first place, a binary search of the keys against its threshold,
   and each slice's smallest and largest live keys on either side of focus (its ends', and those
   either side of the focus's threshold: |c| is monotonic in the key there, so the CPU turns them
   into the slice's CoC range exactly);
4. plan_stats.comp, one thread per :data:`STATS_ITEMS` places of the slices: each slice's screen
   box (slices.screen_boxes: its Gaussians' footprints, each cut to the widest guard band), reduced
   per thread, per workgroup in shared memory, and added to the plan with a few atomics.

An order sorted for an earlier view (the quad backend's background sort, while the viewer moves)
is nearly sorted: plan_extent.comp finds its key range with atomics instead, plan_slots.comp and
plan_scan.comp give every place the farthest slot of those before it (as slices.measure_layers
does), plan_stats.comp reduces the keys too, and its edges are not snapped.

The CPU then reads back one fixed record of O(MAX_EDGES) numbers (:data:`PLAN_BYTES`: edges,
slot bounds, keys, boxes) and makes the frame's layers, levels, guard band and windows from it in
O(layers) (slices.frame_plan), the same code as numpy's plan. What the CPU must know it cannot
learn otherwise: each layer's level (from its smallest and largest CoC, data), the guard band (from
the boxes: it sizes the targets and the guarded camera) and which layers are empty; a frame whose
levels and guard band followed from the lens alone could be drawn without it (docs/BENCHMARKS.md,
"The sliced mode's plan on the GPU").
"""

from __future__ import annotations

import math
import struct
from dataclasses import replace

import moderngl
import numpy as np

from dofview.camera import Camera
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering.gl import compute_shader
from dofview.rendering.gpu_sort import groups
from dofview.rendering.slices import LayerStats, SliceRule, guard_cap
from dofview.rendering.uniforms import set_projection_uniforms

MAX_EDGES = 256
"""Most slices a frame's plan holds (the default rule: growth 1.15 up to the frame's larger side in
px of the kernel's blur, ~75 slices a side for a 16384 px frame refined with 256 lens cells; a rule
without a huge-CoC threshold on CoCs beyond ~10⁷ px asks for more and gets a clear error)."""
STATS_ITEMS = 16
"""Places one thread of glsl/plan_stats.comp reduces (ITEMS there)."""
NO_KEY = 0xFF800001
"""A key beyond every positive depth's (+inf is 0xFF800000): no Gaussian reaches it."""

_E = MAX_EDGES + 1
# glsl/plan_common.glsl's Plan block (std430): byte offsets of its members
_LATTICE, _CUTS, _HEADER = 0, 8 * _E, 16 * _E
_THRESH = _HEADER + 32  # after k, overflow, first_live, min_key, max_key, snap_groups[3]
_BOUNDS = _THRESH + 4 * _E
_KEYS = _BOUNDS + 4 * (_E + 2)
_BOXES = _KEYS + 16 * MAX_EDGES
PLAN_BYTES = _BOXES + 16 * MAX_EDGES
"""Bytes of the plan's record, written before and read back after each frame's plan (14.4 KB)."""
_SNAP_GROUPS = _HEADER + 20


def _initial_record() -> bytes:
    """The plan record before a frame's kernels: empty ranges of keys and boxes to reduce into."""
    out = bytearray(PLAN_BYTES)
    np.frombuffer(out, np.uint32, 8, _HEADER)[:] = [0, 0, 0, 0xFFFFFFFF, 0, 0, 1, 1]
    np.frombuffer(out, np.uint32, 4 * MAX_EDGES, _KEYS)[:] = np.tile(np.array([0xFFFFFFFF, 0], np.uint32), 2 * MAX_EDGES)
    np.frombuffer(out, np.int32, 4 * MAX_EDGES, _BOXES)[:] = np.tile(np.array([2**31 - 1, 2**31 - 1, -2**31, -2**31],
                                                                               np.int32), MAX_EDGES)
    return bytes(out)


_INITIAL = _initial_record()


def depth_of_key(key: np.ndarray | int) -> np.ndarray:
    """(…) float64 the positive camera depths of depth keys ``key`` (glsl/sort_key.glsl; ≥ 0x80000000)."""
    return (np.asarray(key, np.uint32) & np.uint32(0x7FFFFFFF)).view(np.float32).astype(np.float64)


def coc_of_key(key: np.ndarray | int, lens: Lens) -> np.ndarray:
    """(…) float64 the signed CoC px of depth keys ``key``, as slices.signed_coc computes it from
    the float32 depth (glsl/plan_common.glsl: coc_of_key); +inf at depth 0."""
    with np.errstate(divide="ignore"):
        return 0.5 * lens.aperture * (1.0 / depth_of_key(key) - lens.inv_focus)


def key_threshold(holds) -> int:
    """The first depth key of a positive depth for which ``holds(z)`` (z the key's float32 depth
    as a Python float, scene units), a predicate that once true stays true as the depth grows;
    :data:`NO_KEY` if none (glsl/plan_common.glsl: coc_threshold is the GPU's)."""
    lo, hi = 0x80000000, NO_KEY
    while lo < hi:
        mid = (lo + hi) // 2
        if holds(_F32.unpack(_U32.pack(mid & 0x7FFFFFFF))[0]):
            hi = mid
        else:
            lo = mid + 1
    return lo


_U32, _F32 = struct.Struct("<I"), struct.Struct("<f")


def coc_threshold(e: float, lens: Lens, strict: bool = False) -> int:
    """The first depth key whose c ≤ ``e`` px (c < e when ``strict``), c as slices.signed_coc
    computes it (+inf at depth 0)."""
    half, inv = 0.5 * lens.aperture, lens.inv_focus

    def coc(z: float) -> float:
        return half * (1.0 / z - inv) if z > 0.0 else math.inf

    if strict:
        return key_threshold(lambda z: coc(z) < e)
    return key_threshold(lambda z: coc(z) <= e)


class GpuLayerPlan:
    """The GPU plan of one renderer's sliced frames (made by its first sliced draw with an aperture).

    GPU memory: the plan's record; an earlier view's order adds 4 B per Gaussian (its running
    slots) the first time one is planned.
    """

    def __init__(self, renderer) -> None:
        self.r = renderer
        ctx = self.ctx = renderer.ctx
        self._defines = {**renderer.shader_defines, "MAX_EDGES": f"{MAX_EDGES}u"}
        self._kernels: dict[str, moderngl.ComputeShader] = {}
        for name in ("plan_lattice", "plan_snap", "plan_bounds", "plan_stats"):
            self._kernel(name)
        self._record = ctx.buffer(reserve=PLAN_BYTES)
        self._running: moderngl.Buffer | None = None  # an earlier view's running slots
        self._maxima: list[moderngl.Buffer] = []  # their block maxima, level by level
        self.stats: LayerStats | None = None
        """What the last plan measured (the tests compare it with numpy's)."""

    def _kernel(self, name: str) -> moderngl.ComputeShader:
        if name not in self._kernels:
            self._kernels[name] = compute_shader(self.ctx, f"{name}.comp", self._defines)
        return self._kernels[name]

    @property
    def gpu_bytes(self) -> int:
        """Bytes of its buffers as now allocated."""
        own = [self._record, *self._maxima] + ([self._running] if self._running is not None else [])
        return sum(b.size for b in own)

    def measure(self, camera: Camera, lens: Lens, settings: RenderSettings, rule: SliceRule,
                size: float = 1.0) -> LayerStats:
        """The :class:`~dofview.rendering.slices.LayerStats` of the renderer's scene in its draw order
        for ``camera`` and ``lens`` (A > 0), ``settings.near`` and ``rule``, for a kernel of ``size``
        (the frame in px of its blur sets SliceRule.huge: slices.measure_layers), with boxes: what
        slices.measure_layers and slices.screen_boxes give for that order (the order sorted for
        ``camera`` or, in the viewer, for an earlier view). One read-back of :data:`PLAN_BYTES`.

        Raises:
            DofviewError: ``rule`` cuts the view into more than :data:`MAX_EDGES` slices.
        """
        r, ctx = self.r, self.ctx
        n = r.scene.count
        order = r.draw_order(camera)
        huge = rule.huge * max(camera.width, camera.height) / size
        cap = float(guard_cap(rule, camera.width, camera.height))
        pinhole = Lens(lens.focus, 0.0)  # the boxes: the footprints as a layer's pinhole blend draws them
        values = {
            "u_n": n, "u_back_to_front": order.back_to_front, "u_sorted": order.sorted,
            "u_half_a": 0.5 * lens.aperture, "u_inv_f": lens.inv_focus,
            "u_key_near": key_threshold(lambda z: z > settings.near),
            "u_key_front": coc_threshold(huge, lens),
            "u_key_back": coc_threshold(-huge, lens, strict=True),
            "u_key_focus": coc_threshold(0.0, lens, strict=True),
            "u_width": rule.width, "u_growth": rule.growth, "u_huge": huge, "u_snap": rule.snap,
            "u_clip": (-cap, -cap, camera.width + cap, camera.height + cap),
        }
        names = ["plan_lattice", "plan_snap", "plan_bounds", "plan_stats"]
        if not order.sorted:
            names += ["plan_extent", "plan_slots"]
        for name in names:
            kernel = self._kernel(name)
            set_projection_uniforms(kernel, camera, pinhole, replace(settings, dof="splat"))
            for key, value in values.items():
                if key in kernel:
                    kernel[key].value = value
        self._record.write(_INITIAL)

        def run(name: str, *size: int) -> None:
            """Kernel ``name`` over ``size`` workgroups (none: as many as the record says, indirectly)."""
            r.bind_scene()
            order.buffer.bind_to_storage_buffer(3)
            self._record.bind_to_storage_buffer(4)
            if self._running is not None:
                self._running.bind_to_storage_buffer(6)
            if size:
                self._kernels[name].run(*size)
            else:
                self._kernels[name].run_indirect(self._record, _SNAP_GROUPS)
            ctx.memory_barrier()

        spread = groups(-(-n // 256))
        if not order.sorted:
            run("plan_extent", *spread)
        run("plan_lattice", 1)
        run("plan_snap")  # one workgroup per edge of the lattice
        if not order.sorted:
            self._running_slots(n, run, spread)
        run("plan_bounds", 1)
        run("plan_stats", *groups(-(-n // (256 * STATS_ITEMS))))
        self.stats = _decode(self._record.read(), lens)
        return self.stats

    def _running_slots(self, n: int, run, spread: tuple[int, int]) -> None:
        """Each place's farthest slot of those before it (+ 2), in the running-slot buffer."""
        if self._running is None or self._running.size < 4 * max(n, 1):
            if self._running is not None:
                self._running.release()
            self._running = self.ctx.buffer(reserve=4 * max(n, 1))
        run("plan_slots", *spread)
        self._running_max(self._running, n, 0)

    def _running_max(self, data: moderngl.Buffer, n: int, level: int) -> None:
        blocks = -(-n // 1024)
        if level == len(self._maxima):
            self._maxima.append(self.ctx.buffer(reserve=4 * max(blocks, 1)))
        elif self._maxima[level].size < 4 * blocks:
            self._maxima[level].release()
            self._maxima[level] = self.ctx.buffer(reserve=4 * blocks)
        scan, apply = self._kernel("plan_scan"), self._kernel("plan_scan_apply")

        def pass_(kernel: moderngl.ComputeShader) -> None:
            data.bind_to_storage_buffer(0)
            self._maxima[level].bind_to_storage_buffer(1)
            kernel["u_n"].value = n
            kernel.run(*groups(blocks))
            self.ctx.memory_barrier()

        pass_(scan)
        if blocks > 1:
            self._running_max(self._maxima[level], blocks, level + 1)
            pass_(apply)

    def release(self) -> None:
        for obj in (*self._kernels.values(), self._record, self._running, *self._maxima):
            if obj is not None:
                obj.release()


def _decode(record: bytes, lens: Lens) -> LayerStats:
    """The :class:`LayerStats` of a plan record read back (O(MAX_EDGES))."""
    k, overflow = (int(x) for x in np.frombuffer(record, np.uint32, 2, _HEADER))
    if overflow:
        raise DofviewError(f"the slicing rule cuts this view into more than {MAX_EDGES} slices")
    if k == 0:
        return LayerStats(np.zeros(0), np.zeros(0, np.int64), np.zeros(0), np.zeros(0), np.zeros((0, 4), np.int64))
    edges = np.frombuffer(record, np.float64, k + 1, _CUTS).copy()
    bounds = np.frombuffer(record, np.uint32, k + 3, _BOUNDS).astype(np.int64)
    keys = np.frombuffer(record, np.uint32, 4 * k, _KEYS).reshape(k, 4)
    boxes = np.frombuffer(record, np.int32, 4 * k, _BOXES).reshape(k, 4).astype(np.int64)
    # |c| per side, at its key range's ends: in front of focus c falls as the key grows, behind
    # it |c| grows with the key
    with np.errstate(divide="ignore", invalid="ignore"):
        front, back = keys[:, 0] <= keys[:, 1], keys[:, 2] <= keys[:, 3]
        c = coc_of_key(np.where(keys == 0xFFFFFFFF, 0x80000001, np.maximum(keys, 0x80000000)), lens)
    far = np.where(front, c[:, 1], np.inf), np.where(back, -c[:, 2], np.inf)
    near = np.where(front, c[:, 0], -np.inf), np.where(back, -c[:, 3], -np.inf)
    lo, hi = np.minimum(*far), np.maximum(*near)
    some = front | back
    return LayerStats(edges, bounds, np.where(some, lo, np.nan), np.where(some, hi, np.nan), boxes)


__all__ = ["GpuLayerPlan", "MAX_EDGES", "PLAN_BYTES", "coc_threshold", "key_threshold"]
