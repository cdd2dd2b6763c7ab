"""Renderer.swap_scene: a renderer that swaps its scene (the viewer's streamed LOD chunks) draws
what a renderer made for the new scene draws, on every backend, in both depth-of-field modes,
with the storage arrays and the order made beforehand or not."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_scene

from dofview.camera import look_at
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering import get_backend
from dofview.rendering.depth_order import front_to_back
from dofview.rendering.packing import gpu_arrays

CAMERA = look_at((0.3, -0.2, 0.0), (0.0, 0.0, 5.0), 64, 48, 50.0)
LENS = Lens(5.0, 60.0)


@pytest.mark.parametrize("dof", ["sliced", "splat"])
@pytest.mark.parametrize("prepared", [False, True])
def test_swapped_scene_draws_as_a_fresh_renderer(backend, dof, prepared):
    small, large = random_scene(n=400, degree=1, seed=5), random_scene(n=1500, degree=1, seed=6)
    settings = RenderSettings(dof=dof)
    r = backend(small)
    try:
        r.render(CAMERA, LENS, settings)
        for scene in (large, small):  # grows its buffers, then draws fewer than they hold
            if prepared:
                r.swap_scene(scene, gpu_arrays(scene, r.packed, r.colour_scale), (CAMERA, front_to_back(scene.means, CAMERA)))
            else:
                r.swap_scene(scene)
            got = r.render(CAMERA, LENS, settings)
            fresh = backend(scene)
            want = fresh.render(CAMERA, LENS, settings)
            fresh.release()
            assert r.stats.total == scene.count and r.scene is scene
            assert np.array_equal(got.rgba, want.rgba) and np.array_equal(got.depth, want.depth)
    finally:
        r.release()


def test_swap_keeps_the_sh_degree():
    r = get_backend("quad", random_scene(n=50, degree=1))
    try:
        with pytest.raises(ValueError, match="SH degree"):
            r.swap_scene(random_scene(n=50, degree=0))
    finally:
        r.release()


def test_quad_background_sort_of_the_old_scene_is_never_taken():
    """A view asked for just before a swap is sorted from the old means; the swap lets that sort go,
    so the order drawn is always one of the new scene."""
    old, new = random_scene(n=3000, seed=7), random_scene(n=200, seed=8)
    r = get_backend("quad", old)
    try:
        r.request_order(CAMERA)  # the first request sorts here
        moved = look_at((0.5, 0.0, 0.0), (0.0, 0.0, 5.0), 64, 48, 50.0)
        r.request_order(moved)  # now sorting the old scene in the background
        r.swap_scene(new, order=(CAMERA, front_to_back(new.means, CAMERA)))
        assert r.front_to_back().size == new.count
        r.request_order(moved)  # sorted in the background for the new scene
        while r.sort_pending:
            r.request_order(moved)
        assert np.array_equal(r.front_to_back(), front_to_back(new.means, moved))
    finally:
        r.release()
