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
            d._list_tiles(box, d._marks)
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


def _frames_marked_and_every_tile(monkeypatch, backend, scene, cam, lens, settings, rule=None):
    """The sliced frames of ``settings`` (a list) drawn as they are and with every tile marked
    wherever the mode lists tiles (a layer's blend's marks and a run's), and the share of each
    listing's box that its marks held."""
    from dofview.rendering import sliced

    original = sliced.SlicedDof._list_tiles
    shares = []

    def every_tile(self, box, marks):
        self.ctx.memory_barrier()
        marks.buffer.write(np.ones(marks.buffer.size // 4, np.uint32).tobytes())
        original(self, box, marks)

    def counted(self, box, marks):
        original(self, box, marks)
        listed = int(np.frombuffer(self._tile_commands.read(), np.uint32)[7])
        tiles = (-(-box[2] // sliced.TILE) - box[0] // sliced.TILE) * (-(-box[3] // sliced.TILE) - box[1] // sliced.TILE)
        shares.append((marks is self._run_marks, listed / tiles))

    frames = {}
    for name, listing in (("marked", counted), ("every", every_tile)):
        monkeypatch.setattr(sliced.SlicedDof, "_list_tiles", listing)
        r = get_backend(backend, scene)
        r.slice_rule = rule
        try:
            frames[name] = [r.render(cam, lens, each) for each in settings]
        finally:
            r.release()
    return frames["marked"], frames["every"], shares


@pytest.mark.parametrize("backend", ["quad", "compute"])
def test_passes_in_the_marked_tiles_change_no_bit(backend, monkeypatch):
    """The sliced frame with its passes at full resolution in the tiles the layers marked and its
    runs upsampled in the tiles their gathers marked is the frame with every tile of each window
    marked, bit for bit (the disk and 6 blades, colour and depth); and the marks did leave tiles
    out. Without highlights, whose additive blend follows the GPU's order."""
    from dataclasses import replace

    from dofview.io import load_scene
    from dofview.rendering.slices import SLICE_RULE
    from test_sliced_gl import TWO_PLANES, _view

    scene = load_scene(TWO_PLANES, progress=False)
    cam, lens = _view(scene, 16.0)
    settings = [RenderSettings(dof="sliced", blades=blades) for blades in (0, 6)]
    marked, every, shares = _frames_marked_and_every_tile(monkeypatch, backend, scene, cam, lens, settings,
                                                          replace(SLICE_RULE, sprites=0.0))
    for a, b in zip(marked, every):
        np.testing.assert_array_equal(a.rgba, b.rgba)
        np.testing.assert_array_equal(a.depth, b.depth)
    layers = [share for run, share in shares if not run]
    runs = [share for run, share in shares if run]
    assert len(layers) > 10 and min(layers) < 0.5 and max(layers) <= 1.0
    assert len(runs) > 3 and max(runs) <= 1.0  # (these runs fill their boxes: the next test's do not)


@pytest.mark.parametrize("backend", ["quad", "compute"])
@pytest.mark.parametrize("scene_name", ["lights", "corners"])
def test_runs_with_sprites_are_upsampled_where_their_sprites_are(backend, scene_name, monkeypatch):
    """Bright points drawn as full-resolution sprites (runs of one layer): before a wall, and two
    alone near opposite corners of the frame, whose run's box is most of it and whose level keeps
    none of their light (only the sprites mark where they are: slice_sprite.vert). The frame with
    the runs upsampled in the tiles their gathers and sprites marked is the one with every tile
    marked (to the sprites' additive blend, whose order is the GPU's); the corners' run marks under
    four fifths of its box."""
    from test_highlights import _lights_before_a_wall

    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), 400, 296, 60.0)
    if scene_name == "lights":
        scene = _lights_before_a_wall("linear")
    else:
        # at the centres of 8 × 8 blocks (the layer's level is 1/8), each within its block: all of
        # its light leaves for sprites and the level keeps none, so only the sprites mark their tiles
        pixels = np.array([[84.0, 68.0], [316.0, 228.0]])
        z = 3.0
        means = np.column_stack([(pixels[:, 0] - cam.cx) / cam.fx * z, (pixels[:, 1] - cam.cy) / cam.fy * z, [z, z]])
        scene = GaussianScene(means=means, quats=[[1, 0, 0, 0]] * 2, scales=[[0.002] * 3] * 2, opacities=[0.95] * 2,
                              sh_dc=[(200.0, 150.0, 100.0)] * 2, colour_space="linear")
    lens = Lens(1.2, 60.0)
    marked, every, shares = _frames_marked_and_every_tile(monkeypatch, backend, scene, cam, lens,
                                                          [RenderSettings()])
    peak = every[0].rgba[..., :3].max()
    assert peak > 0.0 and np.abs(marked[0].rgba - every[0].rgba).max() <= 1e-6 * peak
    runs = [share for run, share in shares if run]
    assert runs and (scene_name == "lights" or min(runs) < 0.8)
