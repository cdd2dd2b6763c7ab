"""Where a layer's passes at full resolution run (rendering/sliced.py): each backend's blend of a
range marks the tiles it may write (tile_marks.TileMarks, quads.vert and tiles_window.comp), and
slice_tiles.comp lists the marked tiles of a window as runs and tiles, clearing the marks. Marks
must be conservative (a tile left unmarked is never read again by the layer's passes), and they
are worth having only if they leave most of an elongated splat's bounding box unmarked."""

import math

import numpy as np
import pytest
from conftest import random_scene

from dofview.camera import look_at
from dofview.frame import RenderSettings
from dofview.lens import Lens
from dofview.rendering import BACKENDS, get_backend
from dofview.rendering.compute import ComputeBackend
from dofview.rendering.tile_marks import TileMarks
from dofview.scene import GaussianScene

CAM = look_at([0.2, -0.1, 0.0], [0.0, 0.0, 5.0], 200, 150, 60)
SIZE = 16


def _marked(backend: str, scene: GaussianScene, lens: Lens, ranges, box=None):
    """For each range [first, end) blended alone into a cleared target: the (rows, columns) tiles
    holding a pixel it wrote (GL rows) and the marks it left."""
    # a compute tile of 32 px marks four tiles of the marks, one of 8 px (llvmpipe's) a quarter of one
    r = ComputeBackend(scene, tile=32, pix=2) if backend == "compute_32" else get_backend(backend, scene)
    try:
        r.sort(CAM)
        r.prepare_splats(CAM, lens, RenderSettings(dof="splat"))
        textures = [r.ctx.texture((CAM.width, CAM.height), 4, dtype="f4") for _ in range(2)]
        target = r.ctx.framebuffer(color_attachments=textures)
        rows, columns = -(-CAM.height // SIZE), -(-CAM.width // SIZE)
        out = []
        for first, end in ranges:
            marks = TileMarks(r.ctx.buffer(data=np.zeros(rows * columns, np.uint32).tobytes()), SIZE, columns)
            target.clear(0.0, 0.0, 0.0, 0.0)
            r.splat_range(first, end, target, box, marks)
            r.ctx.memory_barrier()
            written = np.zeros((rows * SIZE, columns * SIZE), bool)
            for t in textures:
                pixels = np.frombuffer(t.read(), np.float32).reshape(CAM.height, CAM.width, 4)
                written[:CAM.height, :CAM.width] |= np.any(pixels != 0.0, axis=-1)
            tiles = written.reshape(rows, SIZE, columns, SIZE).any(axis=(1, 3))
            out.append((tiles, np.frombuffer(marks.buffer.read(), np.uint32).reshape(rows, columns)))
            marks.buffer.release()
        target.release()
        for t in textures:
            t.release()
        return out
    finally:
        r.release()


@pytest.mark.parametrize("backend", [*BACKENDS, "compute_32"])
@pytest.mark.parametrize("aperture", [0.0, 60.0])
def test_a_range_marks_every_tile_it_writes_and_only_within_its_box(backend, aperture):
    """Every tile holding a pixel the range wrote is marked (with the lens too: the per-splat
    layers at the lens are drawn so); marks are 0 or 1, none beyond the box's tiles, and a part of
    the order leaves tiles unmarked."""
    scene = random_scene(seed=3)
    n = scene.count
    box = (40, 30, 150, 110)  # image pixels, rows from the top
    cases = _marked(backend, scene, Lens(5.0, aperture), [(0, n), (n // 3, n // 3 + 12), (n // 2, n // 2)])
    cases += _marked(backend, scene, Lens(5.0, aperture), [(0, n)], box)
    (whole, whole_marks), (part, part_marks), (empty, empty_marks), (boxed, boxed_marks) = cases
    for tiles, marks in cases:
        assert set(np.unique(marks)) <= {0, 1}
        assert np.all(marks[tiles] == 1)  # conservative: no written tile unmarked
    assert whole.any() and part.any() and not empty.any() and not empty_marks.any()
    assert part_marks.sum() < 0.6 * part_marks.size  # a part of the order: most tiles unmarked
    rows, columns = boxed_marks.shape
    inside = np.zeros_like(boxed_marks, bool)  # the box's tiles, GL rows
    inside[(CAM.height - box[3]) // SIZE:-(-(CAM.height - box[1]) // SIZE), box[0] // SIZE:-(-box[2] // SIZE)] = True
    assert boxed.any() and not boxed_marks[~inside].any() and boxed_marks[inside].any()


def test_the_quad_backend_marks_along_an_elongated_splat_not_its_bounding_box():
    """A long thin splat across the image's diagonal: the tiles it wrote are all marked, and
    fewer than half of its bounding box's tiles are (quads.vert's rows of the quad)."""
    angle = math.atan2(CAM.height, CAM.width) / 2.0  # half of it: the quaternion turns by twice
    scene = GaussianScene(means=[[0.0, 0.0, 5.0]], quats=[[math.cos(angle), 0.0, 0.0, math.sin(angle)]],
                          scales=[[1.2, 0.01, 0.01]], opacities=[0.9], sh_dc=[(1.0, 0.5, 0.2)],
                          colour_space="linear")
    ((tiles, marks),) = _marked("quad", scene, Lens(5.0, 0.0), [(0, 1)])
    ys, xs = np.nonzero(tiles)
    bounding = (ys.max() - ys.min() + 1) * (xs.max() - xs.min() + 1)
    assert bounding > 40 and np.all(marks[tiles] == 1)
    assert marks.sum() < 0.5 * bounding and marks.sum() <= 3 * tiles.sum()


def test_the_listing_gives_runs_and_tiles_of_the_marks_and_clears_them():
    """slice_tiles.comp over a window: each row's maximal runs of marked tiles and every marked
    tile (for the draws and the dispatch over them), with the indirect commands, against numpy; the
    window's marks are cleared and those beyond it kept."""
    scene = random_scene(seed=1)
    r = get_backend("quad", scene)
    try:
        r.render(CAM, Lens(5.0, 60.0), RenderSettings(dof="sliced"))
        d = r._sliced
        columns = d._marks.columns
        rows = d._marks.buffer.size // 4 // columns
        rng = np.random.default_rng(4)
        for share in (0.0, 0.3, 0.8):
            marks = (rng.uniform(size=(rows, columns)) < share).astype(np.uint32)
            d._marks.buffer.write(marks.tobytes())
            box = (8, 20, 8 + 9 * SIZE + 5, 20 + 6 * SIZE)  # GL pixels: the tiles 0..9 × 1..7
            d._list_tiles(box)
            tx0, ty0, tx1, ty1 = box[0] // SIZE, box[1] // SIZE, -(-box[2] // SIZE), -(-box[3] // SIZE)
            want_runs, want_tiles = set(), set()
            for y in range(ty0, ty1):
                x = tx0
                while x < tx1:
                    if marks[y, x]:
                        x0 = x
                        while x < tx1 and marks[y, x]:
                            want_tiles.add((x, y))
                            x += 1
                        want_runs.add((x0, y, x))
                    else:
                        x += 1
            commands = np.frombuffer(d._tile_commands.read(), np.uint32)
            n_runs, n_tiles = int(commands[1]), int(commands[7])
            assert tuple(commands[[0, 2, 3]]) == (4, 0, 0) and n_runs == len(want_runs) and n_tiles == len(want_tiles)
            assert tuple(commands[4:7]) == ((n_tiles, 1, 1) if n_tiles else (0, 0, 1))
            runs = np.frombuffer(d._tile_runs.read(), np.uint32).reshape(-1, 4)[:n_runs]
            tiles = np.frombuffer(d._tile_list.read(), np.uint32).reshape(-1, 2)[:n_tiles]
            assert {tuple(int(v) for v in run[:3]) for run in runs} == want_runs
            assert {tuple(int(v) for v in t) for t in tiles} == want_tiles and len(tiles) == n_tiles
            left = np.frombuffer(d._marks.buffer.read(), np.uint32).reshape(rows, columns)
            window = np.zeros((rows, columns), bool)
            window[ty0:ty1, tx0:tx1] = True
            assert not left[window].any() and np.array_equal(left[~window], marks[~window])
            assert share == 0.0 or n_tiles > 0
    finally:
        r.release()


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_passes_in_the_marked_tiles_change_no_bit(backend, monkeypatch):
    """The sliced frame with its passes at full resolution in the tiles the layers marked is the
    frame with every tile of each window marked, bit for bit (the disk and 6 blades, colour and
    depth); and the marks did leave tiles out. Without highlights, whose additive blend follows
    the GPU's order."""
    from dataclasses import replace

    from dofview.io import load_scene
    from dofview.rendering import sliced
    from dofview.rendering.slices import SLICE_RULE
    from test_sliced_gl import TWO_PLANES, _view

    scene = load_scene(TWO_PLANES, progress=False)
    cam, lens = _view(scene, 16.0)
    shares = []
    original = sliced.SlicedDof._list_tiles

    def every_tile(self, box):
        self._marks.buffer.write(np.ones(self._marks.buffer.size // 4, np.uint32).tobytes())
        original(self, box)

    def counted(self, box):
        original(self, box)
        listed = int(np.frombuffer(self._tile_commands.read(), np.uint32)[7])
        tiles = (-(-box[2] // sliced.TILE) - box[0] // sliced.TILE) * (-(-box[3] // sliced.TILE) - box[1] // sliced.TILE)
        shares.append(listed / tiles)

    frames = {}
    for name, listing in (("marked", counted), ("every", every_tile)):
        monkeypatch.setattr(sliced.SlicedDof, "_list_tiles", listing)
        r = get_backend(backend, scene)
        r.slice_rule = replace(SLICE_RULE, sprites=0.0)
        try:
            frames[name] = [r.render(cam, lens, RenderSettings(dof="sliced", blades=blades)) for blades in (0, 6)]
        finally:
            r.release()
    for marked, every in zip(frames["marked"], frames["every"]):
        np.testing.assert_array_equal(marked.rgba, every.rgba)
        np.testing.assert_array_equal(marked.depth, every.depth)
    assert len(shares) > 10 and min(shares) < 0.5 and max(shares) <= 1.0
