"""The GPU prefix sum and radix sort (rendering/gpu_sort.py) against numpy, the oracle: random,
all-equal, few-valued (stability), ±0, negative and huge-range depths, 1M keys, short key widths."""

import numpy as np
import pytest

from dofview.camera import Camera
from dofview.rendering.compute import ComputeBackend
from dofview.rendering.gl import headless_context
from dofview.rendering.gpu_sort import BLOCK, GpuRadixSort, GpuScan
from dofview.rendering.depth_order import argsort_keys
from dofview.scene import GaussianScene


@pytest.fixture(scope="module")
def sorter():
    s = GpuRadixSort(headless_context())
    yield s
    s.release()


@pytest.mark.parametrize("n", [1, 2, 5, BLOCK - 1, BLOCK, BLOCK + 1, 100_000])
def test_random_keys_match_numpy(sorter, n):
    keys = np.random.default_rng(n).integers(0, 2**32, n, dtype=np.uint32)
    np.testing.assert_array_equal(sorter.argsort(keys), argsort_keys(keys))


def test_one_million_keys(sorter):
    keys = np.random.default_rng(1).integers(0, 2**32, 1 << 20, dtype=np.uint32)
    order = sorter.argsort(keys)
    np.testing.assert_array_equal(order, argsort_keys(keys))
    assert np.all(np.diff(keys[order].astype(np.int64)) >= 0)


def test_all_equal_keys_keep_their_order(sorter):
    for value in (0, 0x80000000, 0xFFFFFFFF):
        keys = np.full(10_000, value, np.uint32)
        np.testing.assert_array_equal(sorter.argsort(keys), np.arange(10_000))


def test_few_distinct_keys_sort_stably(sorter):
    """Many ties in every byte (and the same digit across blocks): equal keys keep index order."""
    rng = np.random.default_rng(3)
    keys = (rng.integers(0, 5, 50_000).astype(np.uint32) << 24) | rng.integers(0, 3, 50_000).astype(np.uint32)
    np.testing.assert_array_equal(sorter.argsort(keys), np.argsort(keys, kind="stable"))


@pytest.mark.parametrize("bits", [1, 7, 12, 16])
def test_short_keys_take_fewer_passes(sorter, bits):
    """Tile keys have few bits: an odd number of 8-bit passes leaves the result in the scratch pair."""
    ctx = sorter.ctx
    n = 30_000
    keys = np.random.default_rng(bits).integers(0, 1 << bits, n, dtype=np.uint32)
    bufs = [ctx.buffer(keys), ctx.buffer(np.arange(n, dtype=np.uint32)), ctx.buffer(reserve=4 * n), ctx.buffer(reserve=4 * n)]
    out_keys, out_vals = sorter.sort(*bufs[:2], n, bits, *bufs[2:])
    assert (out_keys is bufs[0]) == (-(-bits // 8) % 2 == 0)
    order = np.frombuffer(out_vals.read(), np.uint32)
    np.testing.assert_array_equal(order, np.argsort(keys, kind="stable"))
    np.testing.assert_array_equal(np.frombuffer(out_keys.read(), np.uint32), keys[order])
    for b in bufs:
        b.release()


@pytest.mark.parametrize("n", [1, 1023, 1024, 1025, 300_000, 1_100_000])
def test_scan_matches_cumsum(n):
    """Exclusive prefix sum; 1.1M values take three levels of block totals."""
    ctx = headless_context()
    values = np.random.default_rng(n).integers(0, 50, n, dtype=np.uint32)
    buf = ctx.buffer(values)
    scan = GpuScan(ctx)
    scan.run(buf, n)
    expect = np.concatenate([[0], np.cumsum(values, dtype=np.uint64)[:-1]]).astype(np.uint32)
    np.testing.assert_array_equal(np.frombuffer(buf.read(), np.uint32), expect)
    scan.release()
    buf.release()


def _depth_order(z: np.ndarray) -> np.ndarray:
    """The compute backend's GPU depth order of Gaussians at camera depths ``z`` (means on the
    optical axis of an identity camera, so the GPU's depth is exactly z)."""
    n = z.size
    scene = GaussianScene(means=np.stack([np.zeros(n), np.zeros(n), z], 1).astype(np.float32),
                          quats=np.tile([1.0, 0, 0, 0], (n, 1)), scales=np.full((n, 3), 0.01),
                          opacities=np.full(n, 0.5), sh_dc=np.zeros((n, 3)))
    cam = Camera(64, 48, 50.0, 50.0, 32.0, 24.0, np.eye(3), np.zeros(3))
    r = ComputeBackend(scene)
    r.sort(cam)
    order = r.front_to_back()
    r.release()
    return order


def test_depth_keys_order_negative_zero_and_huge_ranges():
    """Keys made on the GPU from float depths: negatives before positives, larger magnitudes of
    negatives first, -0 and +0 equal (index order), 1e-38…1e38 and ±inf in place."""
    z = np.array([3.0, -0.0, 0.0, -2.0, 1e-38, -1e38, 1e38, np.inf, -np.inf, 0.0, -0.0, 5e-45, 2.0, -2.0,
                  1e-30, 1e30, 7.0, 7.0], np.float32)
    np.testing.assert_array_equal(_depth_order(z), np.argsort(z, kind="stable"))


def test_depth_keys_random_wide_range():
    rng = np.random.default_rng(9)
    z = (rng.choice([-1.0, 1.0], 200_000) * 10.0 ** rng.uniform(-30, 30, 200_000)).astype(np.float32)
    z[::1000] = 0.0
    z[1::1000] = -0.0
    z[2::97] = z[5]  # ties across blocks
    np.testing.assert_array_equal(_depth_order(z), np.argsort(z, kind="stable"))
