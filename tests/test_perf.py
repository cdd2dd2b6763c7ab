"""Issue 7, performance at scale: sort correctness and precision at scale, packing error on the bundled
samples, culling, a million-Gaussian scene headless, load memory, and the perf script itself.
Structure and ratios only: no wall-clock asserts."""

import threading
from pathlib import Path

import numpy as np
import pytest
from conftest import psnr

from dofview.bench.perf import _with_hidden, measure_load_file, run
from dofview.bench.synth import benchmark_camera, random_scene
from dofview.camera import look_at
from dofview.frame import RenderSettings
from dofview.io.cameras import load_cameras_json
from dofview.io.ply import read_ply, write_ply
from dofview.lens import Lens
from dofview.rendering import base as renderer_module
from dofview.rendering.packing import gpu_arrays
from dofview.rendering.quad import QuadBackend
from dofview.rendering.depth_order import camera_depths, front_to_back

SAMPLES = Path(__file__).resolve().parent.parent / "samples"


def test_front_to_back_is_exactly_numpys_stable_order_for_a_million():
    means = random_scene(1_000_000, seed=1).means
    cam = benchmark_camera()
    z = camera_depths(means, cam)
    np.testing.assert_array_equal(front_to_back(means, cam), np.argsort(z, kind="stable"))


def test_no_popping_while_the_camera_moves_over_a_huge_depth_range():
    """Depths 1e-3…1e5 units: as the camera creeps forward, two Gaussians whose depths differ by more
    than float32 can resolve (relative 1e-6) never swap; equal ones keep their index order."""
    rng = np.random.default_rng(4)
    n = 20_000
    z = np.geomspace(1e-3, 1e5, n)
    z[1::2] = z[0::2]  # pairs of exact ties
    means = np.c_[rng.uniform(-0.3, 0.3, (n, 2)) * z[:, None], z + 0.5].astype(np.float32)
    perm = rng.permutation(n)
    means = means[perm]
    previous = None
    for step in range(8):
        cam = look_at([0.0, 0.0, 0.05 * step], [0.0, 0.0, 10.0], 64, 64, 60)
        order = front_to_back(means, cam)
        exact = cam.world_to_camera(means)[:, 2]
        ahead = exact[order]
        assert np.all(np.diff(ahead) >= -1e-6 * np.abs(ahead[1:])), "order against float64 depth"
        if previous is not None:
            rank = np.empty(n, np.int64)
            rank[previous] = np.arange(n)
            swapped = np.diff(rank[order]) < 0  # neighbours now that were the other way round before
            gap = np.abs(np.diff(ahead)) / np.abs(ahead[1:])
            assert not np.any(swapped & (gap > 1e-6))
        tie = np.diff(ahead) == 0
        assert tie.sum() >= n // 2 - 1 and np.all(np.diff(order.astype(np.int64))[tie] > 0)  # stable
        previous = order


@pytest.mark.parametrize("sample", ["cards", "lamp"])
@pytest.mark.parametrize("aperture", [0.0, 40.0])
def test_packing_error_on_the_samples(sample, aperture):
    """Packed storage against float32 storage on the bundled scenes: PSNR ≥ 50 dB (peak: the image's
    brightest value, at least 1, so the HDR lamp is measured on its own range)."""
    scene = read_ply(SAMPLES / f"{sample}.ply")
    cam = load_cameras_json(SAMPLES / f"{sample}_cameras.json")[0].resized(160, 120)
    focus = float(np.median(camera_depths(scene.means, cam)))
    lens, settings = Lens(focus, aperture), RenderSettings()
    full = QuadBackend(scene, packed=False).render(cam, lens, settings)
    packed = QuadBackend(scene, packed=True).render(cam, lens, settings)
    assert full.alpha.mean() > 0.5  # the view shows the scene
    assert psnr(packed.rgba, full.rgba, max(1.0, float(full.rgba.max()))) >= 50.0


def test_gpu_bytes_per_gaussian():
    """≤ 128 B per Gaussian at SH degree 3 (order buffer included); degree 0 carries no SH storage."""
    for degree, most in ((3, 128), (0, 36)):
        r = QuadBackend(random_scene(1000, degree=degree, seed=2))
        assert r.bytes_per_gaussian <= most
        assert (2 in r._buffers) == (degree > 0)
        r.release()


@pytest.mark.parametrize("n, degree", [(4999, 3), (2500, 0), (7, 2), (1, 1)])
@pytest.mark.parametrize("packed", [True, False])
def test_chunked_upload_writes_exactly_the_packed_arrays(monkeypatch, n, degree, packed):
    """The renderer packs and uploads in chunks (to bound host memory); the GPU buffers must hold
    byte for byte what packing the whole scene at once gives, odd counts and SH padding included."""
    monkeypatch.setattr(renderer_module, "UPLOAD_CHUNK", 1000)
    scene = random_scene(n, degree=degree, seed=n)
    r = QuadBackend(scene, packed=packed)
    for binding, a in gpu_arrays(scene, packed).items():
        assert r._buffers[binding].read() == np.ascontiguousarray(a).tobytes()
    assert set(r._buffers) == set(gpu_arrays(scene, packed))
    r.release()


def test_hidden_gaussians_are_culled_and_change_nothing():
    """Gaussians beside the frustum or behind the camera cost no quad and leave the image bit-identical."""
    visible = random_scene(3000, degree=1, seed=3)
    cam = benchmark_camera(160, 90)
    lens = Lens(6.0, 60.0)
    r = QuadBackend(visible)
    r.draw(cam, lens, count=True)
    drawn, image = r.stats.drawn, r.read().rgba
    for where in ("frustum", "behind"):
        both = _with_hidden(visible, where)
        r2 = QuadBackend(both)
        r2.draw(cam, lens, count=True)
        assert both.count == 2 * visible.count
        assert r2.stats.drawn == drawn
        np.testing.assert_array_equal(r2.read().rgba, image)
        r2.release()


def test_a_million_gaussians_render_headless():
    scene = random_scene(1_000_000, degree=3, seed=5)
    r = QuadBackend(scene)
    assert r.bytes_per_gaussian <= 128
    cam = benchmark_camera(160, 90)
    r.draw(cam, Lens(6.0, 100.0), count=True)
    frame = r.read()
    assert np.isfinite(frame.rgba).all()
    assert frame.alpha.min() > 0.9  # the random scene covers the whole view many times over
    assert 0 < r.stats.drawn <= scene.count
    r.release()


def test_load_memory_stays_within_twice_the_file_size(tmp_path):
    """Loading (read, activate, pack, upload) in a fresh process: host allocations peak ≤ 2× the file
    size; resident growth too, once the GL driver's own copy of the uploaded buffers is set aside
    (llvmpipe keeps "GPU" buffers in host memory)."""
    path = tmp_path / "big.ply"
    write_ply(random_scene(200_000, degree=3, seed=6), path)
    rep = measure_load_file(path)
    size = path.stat().st_size
    assert rep["count"] == 200_000
    assert rep["traced_peak_bytes"] <= 2 * size
    if rep["peak_rss_growth_bytes"] is not None:
        gpu = rep["gpu_bytes_per_gaussian"] * rep["count"]
        assert rep["peak_rss_growth_bytes"] - gpu <= 2 * size


def test_perf_script_measurements_hang_together():
    res = run(("memory", "fragments", "sort"), quick=True, frame_sizes=())
    per = {(m["degree"], m["packed"]): m["bytes_per_gaussian"] for m in res["memory"]["rows"]}
    assert per[(3, True)] <= 128 < per[(3, False)] and per[(0, True)] < per[(3, True)]
    rows = {(f["aperture"], f["shape"], f["tau"] > 0): f for f in res["fragments"]["rows"]}
    for a in (0.0, 100.0):
        tight, tight0, square = rows[(a, "tight", True)], rows[(a, "tight", False)], rows[(a, "3sigma", False)]
        assert 0 < tight["fragments"] < tight0["fragments"] < square["fragments"]
        for t in (tight, tight0):  # fragments that survive the α cut are a subset of those rasterised
            assert t["gl_fragments_blended"] <= 1.05 * t["fragments"]
            assert t["gl_drawn"] <= t["gaussians_kept"]
    assert rows[(100.0, "3sigma", False)]["fragments"] > rows[(0.0, "3sigma", False)]["fragments"]
    assert all(s["count"] > 0 and s["front_to_back_ms"] > 0 for s in res["sort"]["rows"])


def test_perf_measures_the_backend_it_is_given():
    """--raster reaches the renderers through get_backend: the compute backend's own per-Gaussian
    buffers (splat, tile rectangle, order, tile count) show in its memory figures."""
    from dofview.rendering.compute import PER_GAUSSIAN_BYTES

    res = {r: run(("memory",), quick=True, frame_sizes=(), raster=r)["memory"] for r in ("quad", "compute")}
    assert res["quad"]["raster"] == "quad" and res["compute"]["raster"] == "compute"
    for q, c in zip(res["quad"]["rows"], res["compute"]["rows"]):
        assert (q["degree"], q["packed"]) == (c["degree"], c["packed"])
        # quad adds a 4 B order; compute its PER_GAUSSIAN_BYTES, its offsets and the radix sort's buffers
        assert c["bytes_per_gaussian"] - q["bytes_per_gaussian"] >= PER_GAUSSIAN_BYTES - 4


def test_sorting_runs_off_the_viewers_ui_thread(monkeypatch):
    """The viewer's sort request returns while the sort itself is still running on another thread."""
    from dofview.rendering import sort_thread as sorter

    release, threads = threading.Event(), []

    def slow_sort(means, camera):
        threads.append(threading.current_thread())
        assert release.wait(10.0)
        return front_to_back(means, camera)

    monkeypatch.setattr(sorter, "front_to_back", slow_sort)
    worker = sorter.SortThread()
    try:
        means = random_scene(1000, seed=7).means
        cam = benchmark_camera(64, 36)
        worker.request(means, cam)  # returns although the sort cannot finish yet
        assert worker.pending and worker.result() is None
        release.set()
        for _ in range(1000):
            res = worker.result()
            if res is not None:
                break
            threading.Event().wait(0.01)
        assert res is not None and res.view_key == cam.view_key()
        assert threads and threads[0] is not threading.main_thread()
        np.testing.assert_array_equal(res.order, front_to_back(means, cam)[::-1])
    finally:
        release.set()
        worker.close()
