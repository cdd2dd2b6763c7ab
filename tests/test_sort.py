import numpy as np

from dofview.camera import look_at
from dofview.rendering.depth_order import (
    argsort_keys,
    camera_depths,
    depth_keys,
    front_to_back,
)


def test_radix_order_equals_numpy_stable_sort_with_ties():
    rng = np.random.default_rng(0)
    keys = rng.integers(0, 2**32, 200_000, dtype=np.uint64).astype(np.uint32)
    keys[::7] = keys[3]  # many exact ties
    np.testing.assert_array_equal(argsort_keys(keys), np.argsort(keys, kind="stable"))


def test_keys_keep_float_order_across_huge_depth_ranges():
    """Depths from 1e-3 to 1e5 units, negative ones too, and neighbours one float32 ulp apart."""
    z = np.concatenate([np.geomspace(1e-3, 1e5, 5000), -np.geomspace(1e-3, 1e5, 100), [0.0]]).astype(np.float32)
    z = np.concatenate([z, np.nextafter(z, np.float32(np.inf))])
    rng = np.random.default_rng(1)
    z = z[rng.permutation(z.size)]
    order = argsort_keys(depth_keys(z))
    assert np.all(np.diff(z[order]) >= 0)
    np.testing.assert_array_equal(z[order], np.sort(z))


def test_front_to_back_is_stable_for_equal_depths_and_repeatable():
    """Many Gaussians on one depth plane: the order is by index (no flicker between frames)."""
    n = 10_000
    rng = np.random.default_rng(2)
    means = np.c_[rng.uniform(-1, 1, (n, 2)), np.full(n, 5.0)].astype(np.float32)
    cam = look_at([0, 0, 0], [0, 0, 1], 64, 64, 60)
    order = front_to_back(means, cam)
    np.testing.assert_array_equal(order, np.arange(n))
    np.testing.assert_array_equal(front_to_back(means, cam), order)


def test_front_to_back_orders_by_camera_depth():
    rng = np.random.default_rng(3)
    means = rng.uniform(-10, 10, (5000, 3)).astype(np.float32)
    cam = look_at([0.5, -2, -30], [1, 0, 0], 64, 64, 60)
    z = camera_depths(means, cam)
    order = front_to_back(means, cam)
    assert np.all(np.diff(z[order]) >= 0)
    exact = cam.world_to_camera(means)[:, 2]
    assert np.all(np.diff(exact[order]) >= -1e-5 * np.abs(exact).max())
