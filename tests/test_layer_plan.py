"""The sliced mode's plan made on the GPU (rendering/layer_plan.py) against its numpy twin
(slices.measure_layers, slices.screen_boxes, slices.frame_plan): the same edges, slots, CoC
ranges, boxes and frame plan, bit for bit but for the boxes (float32 arithmetic that may round
differently: within a pixel), on the test scenes, both backends, and on hard cases: empty slices,
everything behind the near plane, one Gaussian, focus at infinity, huge-CoC layers, an earlier
view's order, too many slices."""

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from dofview.bench.sliced_study import indoor_scene
from dofview.camera import Camera, look_at
from dofview.errors import DofviewError
from dofview.frame import RenderSettings
from dofview.io import load_scene
from dofview.lens import Lens, aperture_for_blur
from dofview.rendering import get_backend
from dofview.rendering.depth_order import camera_depths, depth_keys, front_to_back
from dofview.rendering.layer_plan import MAX_EDGES, GpuLayerPlan, coc_of_key, coc_threshold
from dofview.rendering.reference import render_reference
from dofview.rendering.slices import (
    NO_BOX,
    SLICE_RULE,
    LayerStats,
    frame_plan,
    layer_reach,
    measure_layers,
    plan_frame,
    screen_boxes,
)
from dofview.scene import GaussianScene

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
SETTINGS = RenderSettings()


def numpy_stats(scene, order, cam, lens, rule=SLICE_RULE, settings=SETTINGS, current=True, size=1.0) -> LayerStats:
    stats = measure_layers(camera_depths(scene.means, cam)[order], lens, settings.near, rule,
                           max(cam.width, cam.height) / size, current)
    return replace(stats, boxes=screen_boxes(scene, order, cam, lens, settings, stats.bounds, rule))


def assert_same(got: LayerStats, want: LayerStats) -> None:
    np.testing.assert_array_equal(got.edges, want.edges)
    np.testing.assert_array_equal(got.bounds, want.bounds)
    np.testing.assert_array_equal(got.lo, want.lo)
    np.testing.assert_array_equal(got.hi, want.hi)
    empty = want.bounds[2:want.k + 2] == want.bounds[1:want.k + 1]
    assert np.all(got.boxes[empty] == NO_BOX)
    assert np.abs(got.boxes[~empty] - want.boxes[~empty]).max(initial=0) <= 1


def gpu_stats(r, cam, lens, rule=SLICE_RULE, settings=SETTINGS, size=1.0) -> LayerStats:
    planner = GpuLayerPlan(r)
    try:
        return planner.measure(cam, lens, settings, rule, size)
    finally:
        planner.release()


def view(scene, blur: float, width: int = 160, height: int = 120, near_pct: float = 5.0):
    """Looking at ``scene`` from its bounding box's −z side, focused at the median depth, the
    largest blur between the ``near_pct`` and 95th depth percentiles ``blur`` px."""
    lo, hi = np.percentile(scene.means, [2, 98], axis=0)
    centre = 0.5 * (lo + hi)
    cam = look_at(tuple(centre - np.array([0.0, 0.0, 1.6 * float(np.max(hi - lo))])), tuple(centre), width, height, 50.0)
    z = camera_depths(scene.means, cam)
    z = z[z > 0.01]
    focus = float(np.median(z))
    return cam, Lens(focus, aperture_for_blur(blur, focus, float(np.percentile(z, near_pct)), float(np.percentile(z, 95))))


@pytest.mark.parametrize("backend", ["quad", "compute"])
@pytest.mark.parametrize("name", ["two_planes.ply", "burger.ply", "guitar.compressed.ply", "biker.spz", "tap.spz"])
def test_gpu_plan_is_the_numpy_plan_on_the_test_scenes(backend, name):
    scene = load_scene(DATA / name, progress=False)
    r = get_backend(backend, scene)
    try:
        for blur, near_pct in ((16.0, 5.0), (60.0, 0.5)):  # the second: the nearest splats blurred by hundreds of px
            cam, lens = view(scene, blur, near_pct=near_pct)
            r.sort(cam)
            order = r.front_to_back()
            np.testing.assert_array_equal(order, front_to_back(scene.means, cam))  # the two sorts agree
            got, want = gpu_stats(r, cam, lens), numpy_stats(scene, order, cam, lens)
            assert want.k >= 8 and len(np.unique(want.edges)) == len(want.edges)
            assert not np.array_equal(want.edges, measure_layers(camera_depths(scene.means, cam)[order], lens, 0.01,
                                                                 replace(SLICE_RULE, snap=0.0), 160).edges)  # snapped
            assert_same(got, want)
            size = 0.5  # a lens cell's kernel: the huge-CoC threshold in px of its own blur
            got, want = gpu_stats(r, cam, lens, size=size), numpy_stats(scene, order, cam, lens, size=size)
            assert_same(got, want)
            assert frame_plan(got, cam, SLICE_RULE, size) == frame_plan(want, cam, SLICE_RULE, size)
            got, want = gpu_stats(r, cam, lens), numpy_stats(scene, order, cam, lens)
            assert frame_plan(got, cam, SLICE_RULE) == plan_frame(scene, order, cam, lens, SETTINGS, SLICE_RULE)
    finally:
        r.release()


def _points(z, xy=None, scale=0.01) -> GaussianScene:
    """Gaussians at camera depths ``z`` of :data:`CAM` (an identity camera), spread on screen by ``xy``."""
    z = np.asarray(z, np.float32)
    n = len(z)
    xy = np.zeros((n, 2)) if xy is None else xy
    return GaussianScene(means=np.c_[xy * z[:, None], z].astype(np.float32), quats=np.tile([1.0, 0, 0, 0], (n, 1)),
                         scales=np.full((n, 3), scale), opacities=np.full(n, 0.5), sh_dc=np.zeros((n, 3)))


CAM = Camera(96, 64, 80.0, 80.0, 48.0, 32.0, np.eye(3), np.zeros(3))


def _both(scene, lens, rule=SLICE_RULE, settings=SETTINGS, cam=CAM) -> tuple[LayerStats, LayerStats]:
    out = []
    for backend in ("quad", "compute"):
        r = get_backend(backend, scene)
        try:
            r.sort(cam)
            out.append(gpu_stats(r, cam, lens, rule, settings))
        finally:
            r.release()
    want = numpy_stats(scene, front_to_back(scene.means, cam), cam, lens, rule, settings)
    for got in out:
        assert_same(got, want)
    return out[0], want


def test_hard_cases():
    rng = np.random.default_rng(2)
    lens = Lens(2.0, 40.0)
    # two clusters far apart in depth: the slices between them are empty (and skipped)
    z = np.r_[rng.uniform(0.3, 0.32, 200), rng.uniform(30.0, 31.0, 200)]
    got, want = _both(_points(z, rng.uniform(-0.5, 0.5, (400, 2))), lens)
    assert np.sum(np.diff(want.bounds) == 0) >= 5
    # everything behind the near plane: nothing planned (and nothing drawn)
    got, want = _both(_points(rng.uniform(-2.0, 0.005, 100)), lens)
    assert got.k == 0 and want.k == 0
    # one Gaussian, also at the near plane's edge
    for z in ([2.5], [0.01000001], [float(np.nextafter(np.float32(0.01), np.float32(1)))]):
        got, want = _both(_points(z), lens)
        assert want.k >= 1 and want.bounds[-1] == 1
    # focus at infinity: every CoC in front of it
    got, want = _both(_points(rng.uniform(0.5, 80.0, 300), rng.uniform(-0.5, 0.5, (300, 2))), Lens(np.inf, 40.0))
    assert np.all(want.edges[:-1] > 0)
    # huge-CoC front and back layers drawn per splat (beyond SliceRule.huge: 30 px of the 96 px frame), and culled ones
    z = np.r_[rng.uniform(-1.0, 0.01, 20), rng.uniform(0.02, 0.05, 30), rng.uniform(0.5, 100.0, 300)]
    lens = Lens(0.5, 40.0)  # c = 20·(1/z − 2): 960 px at 0.02, below −30 beyond z = 2
    got, want = _both(_points(z, rng.uniform(-0.5, 0.5, (350, 2))), lens, replace(SLICE_RULE, huge=30.0 / 96))
    assert want.bounds[1] - want.bounds[0] == 30 and want.bounds[-1] - want.bounds[-2] > 0  # front and back
    # ties: many Gaussians at one depth, on an edge's snap window
    got, want = _both(_points(np.repeat([1.0, 1.01, 1.03, 1.2], 50), rng.uniform(-0.5, 0.5, (200, 2))), Lens(1.1, 200.0))


def test_an_earlier_views_order_is_planned_as_numpy_plans_it():
    """The quad backend draws with the last order while the viewer's background sort runs: the GPU
    plans that nearly sorted order as measure_layers does (running slots, edges not snapped)."""
    scene = load_scene(DATA / "tap.spz", progress=False)
    cam, lens = view(scene, 16.0)
    a = np.radians(4.0)  # the camera turned about its y axis (a move along z alone keeps the order)
    turn = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    moved = replace(cam, R=turn @ cam.R, T=turn @ cam.T)
    r = get_backend("quad", scene)
    try:
        r.sort(cam)
        assert r.draw_order(cam).sorted and not r.draw_order(moved).sorted
        got = gpu_stats(r, moved, lens)
    finally:
        r.release()
    order = front_to_back(scene.means, cam)
    depth = camera_depths(scene.means, moved)[order]
    assert np.any(np.diff(depth) < 0)  # (not sorted for the moved camera)
    want = numpy_stats(scene, order, moved, lens, current=False)
    assert_same(got, want)
    assert want.k >= 8


def test_too_many_slices_is_a_clear_error():
    scene = _points(np.linspace(0.5, 50.0, 100))
    r = get_backend("quad", scene)
    try:
        r.sort(CAM)
        with pytest.raises(DofviewError, match=f"more than {MAX_EDGES} slices"):
            gpu_stats(r, CAM, Lens(2.0, 400.0), replace(SLICE_RULE, growth=1.0, huge=math.inf, width=0.5))
    finally:
        r.release()


def test_threshold_keys_split_the_depths_where_the_coc_crosses():
    lens = Lens(3.0, 57.0)
    for e in (-9.5, -0.5, 0.0, 0.5, 7.25, 1e4):
        key = coc_threshold(e, lens)
        assert coc_of_key(key, lens) <= e < coc_of_key(key - 1, lens)
    key = int(depth_keys(np.array([3.0], np.float32))[0])  # c = 0 exactly at the focus
    assert coc_threshold(0.0, lens) == key and coc_threshold(0.0, lens, strict=True) == key + 1


def test_the_planning_benchmark_times_both_plans_and_checks_they_agree(capsys):
    from dofview.bench.planning import main, tiled

    assert main(["--sizes", "3000", "--reps", "1", "--width", "96", "--height", "54"]) == 0
    rows = [row.split("\t") for row in capsys.readouterr().out.strip().splitlines()]
    assert len(rows) == 3 and all(len(row) == 8 and float(row[7]) > 0 for row in rows[1:])  # quad, compute
    scene = load_scene(DATA / "burger.ply", progress=False)
    n = scene.count
    big = tiled(scene, 2 * n + 5)
    assert big.count == 2 * n + 5 and np.array_equal(big.means[:n], scene.means)
    np.testing.assert_array_equal(big.means[n:2 * n, 1:], scene.means[:, 1:])
    assert np.all(big.means[n:2 * n, 0] > scene.means[:, 0])  # the copies side by side


def test_the_backends_benchmark_reports_each_frames_host_time_and_layers():
    """bench.backends (scripts/gpu_bench.sh's measure) gives, beside the frame time, the calling
    thread's CPU time issuing the frame (on a GPU, a sliced frame whose host time nears its frame
    time is bound by the CPU's O(layers) work) and the sliced mode's layers: one at A = 0."""
    from dofview.bench import synth
    from dofview.bench.backends import measure

    rows = measure("random", synth.random_scene(2000, seed=1), synth.benchmark_camera(64, 48), 6.0, (0.0, 100.0), 1)
    assert [(r["backend"], r["aperture"]) for r in rows] == [("quad", 0.0), ("compute", 0.0), ("quad", 100.0),
                                                             ("compute", 100.0)]
    assert all(r["host_ms"] > 0 and r["median_ms"] > 0 for r in rows)
    assert [r["layers"] for r in rows[:2]] == [1, 1] and all(r["layers"] > 1 for r in rows[2:])


def test_a_layers_box_is_where_its_splats_draw():
    """In a room with splats at the lens (sliced_study.indoor_scene: leaves 0.12–0.45 units away,
    floaters), a layer's window (what every pass after its blend works on) holds every pixel its
    splats draw within its reach of the frame; for the layers at the lens, whose splats are many
    pixels wide, within 4 px of those pixels' box, and empty where they draw nothing there. A box
    of whole footprints, or of σ bounded by the largest scale, covers the frame for a splat at the
    lens that draws in a corner of it or nowhere: such layers did five full-resolution passes over
    the whole image for nothing."""
    scene, cam = indoor_scene()
    cam = cam.resized(120, 90)
    z = camera_depths(scene.means, cam)
    focus = float(np.percentile(z[z > 0.05], 70))
    lens = Lens(focus, aperture_for_blur(8.0, focus, float(np.percentile(z, 20)), float(np.percentile(z, 95))))
    order = front_to_back(scene.means, cam)
    plan = plan_frame(scene, order, cam, lens, SETTINGS, SLICE_RULE)
    guarded = cam.guarded(plan.guard)
    pinhole = (Lens(lens.focus, 0.0), replace(SETTINGS, dof="splat"))
    near = [0, 0]  # layers at the lens: empty windows, tight ones
    for layer, (x0, y0, x1, y1) in zip(plan.layers, plan.windows):
        if layer.lensed:
            continue  # drawn with the lens over the whole guarded image
        band = min(plan.guard, layer_reach(layer))
        lo, hx, hy = plan.guard - band, plan.guard + cam.width + band, plan.guard + cam.height + band
        alpha = render_reference(scene.subset(order[layer.first:layer.end]), guarded, *pinhole).alpha
        ys, xs = np.nonzero(alpha[lo:hy, lo:hx] > 0)
        at_lens = float(np.median(z[order[layer.first:layer.end]])) < 0.5
        if not len(xs):
            if at_lens:
                assert x1 <= x0 or y1 <= y0, (layer, (x0, y0, x1, y1))
                near[0] += 1
            continue
        dx0, dy0, dx1, dy1 = xs.min() + lo, ys.min() + lo, xs.max() + lo + 1, ys.max() + lo + 1
        assert x0 <= dx0 and y0 <= dy0 and x1 >= dx1 and y1 >= dy1, (layer, (x0, y0, x1, y1), (dx0, dy0, dx1, dy1))
        if at_lens:
            assert x0 >= dx0 - 4 and y0 >= dy0 - 4 and x1 <= dx1 + 4 and y1 <= dy1 + 4, (layer, (x0, y0, x1, y1),
                                                                                           (dx0, dy0, dx1, dy1))
            near[1] += 1
    assert near[0] + near[1] >= 4 and near[1] >= 2, near
