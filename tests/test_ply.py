"""Reading and writing Inria 3DGS .ply files (binary both endians and ASCII, SH degree 0–3)."""

import numpy as np
import plyfile
import pytest
from conftest import random_scene
from numpy.lib.recfunctions import repack_fields

from dofview.errors import DofviewError
from dofview.io.ply import read_ply, scene_rows, write_ply
from dofview.scene import GaussianScene


def assert_same_scene(a: GaussianScene, b: GaussianScene) -> None:
    assert a.count == b.count and a.sh_degree == b.sh_degree and a.colour_space == b.colour_space
    np.testing.assert_array_equal(a.means, b.means)
    np.testing.assert_array_equal(a.sh_dc, b.sh_dc)
    np.testing.assert_allclose(a.scales, b.scales, rtol=1e-6)
    np.testing.assert_allclose(a.opacities, b.opacities, atol=2e-7)
    np.testing.assert_allclose(a.quats, b.unit_quats(), atol=1e-6)
    if a.sh_rest is not None:
        np.testing.assert_array_equal(a.sh_rest, b.sh_rest)


@pytest.mark.parametrize("degree", [0, 1, 2, 3])
@pytest.mark.parametrize("colour_space", ["srgb", "linear"])
def test_round_trip(tmp_path, degree, colour_space):
    scene = random_scene(n=300, degree=degree, seed=degree, colour_space=colour_space)
    path = tmp_path / "s.ply"
    write_ply(scene, path)
    back = read_ply(path)
    assert_same_scene(back, scene)
    assert back.sh_rest is None if degree == 0 else back.sh_rest.shape == (300, (degree + 1) ** 2 - 1, 3)


def _plyfile_write(scene, path, text=False, byte_order="<", extra=()):
    """Write through plyfile (an independent writer), optionally with extra properties."""
    rows = scene_rows(scene)
    dtype = rows.dtype.descr + [(name, "f4") for name in extra]
    out = np.zeros(rows.shape, dtype)
    for name in rows.dtype.names:
        out[name] = rows[name]
    for i, name in enumerate(extra):
        out[name] = i + 1.5
    el = plyfile.PlyElement.describe(out, "vertex")
    plyfile.PlyData([el], text=text, byte_order=byte_order).write(str(path))


@pytest.mark.parametrize("text,byte_order", [(True, "="), (False, "<"), (False, ">")])
def test_reads_ascii_and_both_endians(tmp_path, text, byte_order):
    scene = random_scene(n=50, degree=3, seed=4)
    path = tmp_path / "s.ply"
    _plyfile_write(scene, path, text=text, byte_order=byte_order, extra=("confidence", "filter_3D"))
    back = read_ply(path)
    np.testing.assert_allclose(back.means, scene.means, rtol=1e-6)  # ASCII prints ~8 digits
    np.testing.assert_allclose(back.sh_rest, scene.sh_rest, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(back.scales, scene.scales, rtol=1e-5)
    assert back.colour_space == "srgb"  # no dofview comment: a standard file


def test_f_rest_is_channel_major(tmp_path):
    """Inria stores f_rest reshaped (N, 3, K−1): the first K−1 values are all red coefficients."""
    scene = random_scene(n=1, degree=1)
    rows = scene_rows(scene)
    for j in range(3):
        for c in range(3):
            rows[f"f_rest_{c * 3 + j}"] = 10 * c + j
    path = tmp_path / "s.ply"
    plyfile.PlyData([plyfile.PlyElement.describe(rows, "vertex")]).write(str(path))
    rest = read_ply(path).sh_rest[0]
    np.testing.assert_array_equal(rest, [[0, 10, 20], [1, 11, 21], [2, 12, 22]])


def test_activation(tmp_path):
    scene = random_scene(n=3)
    rows = scene_rows(scene)
    rows["opacity"] = [0.0, 2.0, -1e4]
    rows["scale_0"] = [0.0, np.log(0.25), -3.0]
    for i, q in enumerate([(2, 0, 0, 0), (0, 0, 0, 0), (1, 1, 1, 1)]):
        for k in range(4):
            rows[f"rot_{k}"][i] = q[k]
    path = tmp_path / "s.ply"
    plyfile.PlyData([plyfile.PlyElement.describe(rows, "vertex")]).write(str(path))
    s = read_ply(path)
    np.testing.assert_allclose(s.opacities, [0.5, 1 / (1 + np.exp(-2.0)), 0.0], atol=1e-7)
    np.testing.assert_allclose(s.scales[:, 0], [1.0, 0.25, np.exp(-3.0)], rtol=1e-6)
    np.testing.assert_allclose(s.quats, [[1, 0, 0, 0], [1, 0, 0, 0], [0.5, 0.5, 0.5, 0.5]], atol=1e-7)


def test_plain_point_cloud_is_refused_with_the_missing_properties(tmp_path):
    pts = np.zeros(4, [("x", "f4"), ("y", "f4"), ("z", "f4"), ("red", "u1"), ("green", "u1"), ("blue", "u1")])
    path = tmp_path / "cloud.ply"
    plyfile.PlyData([plyfile.PlyElement.describe(pts, "vertex")]).write(str(path))
    with pytest.raises(DofviewError) as e:
        read_ply(path)
    msg = str(e.value)
    assert str(path) in msg and "f_dc_0" in msg and "rot_3" in msg and "point cloud" in msg


def test_sh_count_that_is_no_degree(tmp_path):
    rows = scene_rows(random_scene(n=2, degree=1))
    keep = [n for n in rows.dtype.names if n != "f_rest_8"]
    path = tmp_path / "s.ply"
    plyfile.PlyData([plyfile.PlyElement.describe(repack_fields(rows[keep]), "vertex")]).write(str(path))
    with pytest.raises(DofviewError, match="8 f_rest_\\* properties is no SH degree"):
        read_ply(path)
