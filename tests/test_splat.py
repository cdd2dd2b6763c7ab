""".splat (antimatter15) files: round trip through GaussianScene within the format's 8-bit precision,
and clear errors for files that are not .splat."""

import numpy as np
import pytest
from conftest import random_scene

from dofview.errors import DofviewError
from dofview.io import load_scene, save_scene
from dofview.io.splat import SPLAT_DTYPE, read_splat, write_splat


def test_round_trip_within_8_bit_precision(tmp_path):
    scene = random_scene(n=5000, seed=11)
    scene.sh_dc[:, :] = (np.random.default_rng(0).uniform(0, 1, (5000, 3)) - 0.5) / 0.28209479177387814
    path = tmp_path / "s.splat"
    save_scene(scene, path)
    assert path.stat().st_size == 32 * scene.count == SPLAT_DTYPE.itemsize * scene.count
    back = load_scene(path, progress=False)
    assert back.count == scene.count and back.sh_rest is None and back.colour_space == "srgb"
    np.testing.assert_array_equal(back.means, scene.means)  # float32 in the file: exact
    np.testing.assert_array_equal(back.scales, scene.scales)
    np.testing.assert_allclose(back.opacities, scene.opacities, atol=0.5 / 255 + 1e-6)
    np.testing.assert_allclose(back.base_colour(), scene.base_colour(), atol=0.5 / 255 + 1e-6)
    q, q0 = back.unit_quats(), scene.unit_quats()
    err = np.minimum(np.abs(q - q0).max(1), np.abs(q + q0).max(1))  # q and −q are one rotation
    # each component is stored as round(q·128 + 128) clipped to 255: ≤ 1/128 off before renormalising
    assert err.max() <= 2.0 / 128


def test_saving_again_does_not_drift(tmp_path):
    """Read and write again: every field but the rotation is byte-identical; the rotation, renormalised
    on reading, moves by at most one 8-bit step."""
    a, b = tmp_path / "a.splat", tmp_path / "b.splat"
    write_splat(random_scene(n=800, seed=12), a)
    write_splat(read_splat(a), b)
    ra, rb = np.fromfile(a, SPLAT_DTYPE), np.fromfile(b, SPLAT_DTYPE)
    for field in ("position", "scale", "rgba"):
        np.testing.assert_array_equal(ra[field], rb[field])
    assert np.abs(ra["rot"].astype(int) - rb["rot"].astype(int)).max() <= 1


def test_view_dependent_colour_is_dropped(tmp_path):
    scene = random_scene(n=300, degree=3, seed=13)
    write_splat(scene, tmp_path / "d3.splat")
    back = read_splat(tmp_path / "d3.splat")
    assert back.sh_degree == 0
    np.testing.assert_allclose(back.base_colour(), np.clip(scene.base_colour(), 0, 1), atol=0.5 / 255 + 1e-6)


@pytest.mark.parametrize("content, message", [(b"", "empty"), (b"x" * 33, "not a whole number")])
def test_bad_files_name_the_file_and_the_problem(tmp_path, content, message):
    path = tmp_path / "bad.splat"
    path.write_bytes(content)
    with pytest.raises(DofviewError, match=message) as e:
        read_splat(path)
    assert str(path) in str(e.value)


def test_missing_file(tmp_path):
    with pytest.raises(DofviewError, match="no such file"):
        load_scene(tmp_path / "absent.splat", progress=False)
