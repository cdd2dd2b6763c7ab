"""The native rasteriser's build, threads and fallback (dofview/train/native.py, rasterisers.py).

Its image and gradients against the dense oracle and the GL renderer are in test_train_sparse.py
(parametrized over both sparse rasterisers)."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from conftest import random_scene  # noqa: E402

from dofview.camera import look_at  # noqa: E402
from dofview.cli import main  # noqa: E402
from dofview.errors import DofviewError  # noqa: E402
from dofview.frame import RenderSettings  # noqa: E402
from dofview.lens import Lens  # noqa: E402
from dofview.train import native  # noqa: E402
from dofview.train.rasterisers import choose_rasteriser  # noqa: E402

CPU = torch.device("cpu")


@pytest.fixture
def no_cached_library():
    """Forget the loaded libraries before and after: the test builds (or fails to) afresh."""
    native.library.cache_clear()
    yield
    native.library.cache_clear()


def test_any_thread_count_gives_the_same_bits():
    """Tiles go to threads in any order; each pair's gradient is summed alone and the pairs are
    added up in one order, so 1, 2 or 5 threads give identical images and gradients."""
    scene = random_scene(1500, colour_space="linear")
    cam = look_at((0.3, 0.1, 0.0), (0.0, 0.0, 5.0), 96, 72, 60.0)
    out = []
    for threads in (1, 2, 5):
        params = [torch.tensor(np.asarray(a), dtype=torch.float32, requires_grad=True)
                  for a in (scene.means, scene.quats, scene.scales, scene.opacities, scene.base_colour())]
        r = native.rasterise_native(*params, cam, Lens(4.0, 20.0), RenderSettings(tau=0.0, dof="splat"),
                                     threads=threads)
        (r.rgb.square().sum() + r.alpha.sum()).backward()
        out.append([r.rgb.detach(), r.alpha.detach()] + [p.grad for p in params])
    assert float(out[0][1].max()) > 0.5  # splats overlap: the walk matters
    for other in out[1:]:
        assert all(torch.equal(a, b) for a, b in zip(out[0], other))


def test_builds_once_into_the_cache(tmp_path, monkeypatch, no_cached_library):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    native.library(torch.float32)
    native.library(torch.float64)
    built = sorted(tmp_path.glob("dofview/native-*.so"))
    assert [p.name.split("-")[1] for p in built] == ["double", "float"]
    stamps = [p.stat().st_mtime_ns for p in built]
    native.library.cache_clear()
    native.library(torch.float32)  # a new process finds the built file: no second compile
    assert [p.stat().st_mtime_ns for p in built] == stamps
    assert not list(tmp_path.glob("dofview/*.so.*")) and len(list(tmp_path.glob("dofview/*"))) == 2  # no leftovers


@pytest.mark.parametrize("compiler, why", [("/nonexistent/cc", "no C compiler"), ("false", "failed on native.c")])
def test_without_a_compiler_training_falls_back_to_sparse(tmp_path, monkeypatch, capsys, no_cached_library,
                                                         compiler, why):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))  # nothing built there yet
    monkeypatch.setenv("CC", compiler)
    assert choose_rasteriser(None, CPU) == "sparse"
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("dofview: native rasteriser: ") and why in err
    with pytest.raises(DofviewError, match=why):  # asked for by name: an error, not a silent change
        choose_rasteriser("native", CPU)
    assert not list(tmp_path.rglob("*.so"))


def test_choice_by_device_and_name(capsys):
    assert choose_rasteriser(None, CPU) == "native"  # this machine has a C compiler
    assert choose_rasteriser("dense", CPU) == "dense"
    assert choose_rasteriser(None, torch.device("cuda")) == "sparse"  # a device need not exist to be named
    with pytest.raises(DofviewError, match="runs on the CPU"):
        choose_rasteriser("native", torch.device("cuda"))
    with pytest.raises(DofviewError, match="must be one of native, sparse, dense"):
        choose_rasteriser("fast", CPU)
    assert capsys.readouterr().err == ""


def test_cli_native_without_compiler_is_one_line_error(tmp_path, monkeypatch, capsys, no_cached_library):
    from test_train import Capture, generate, hdr_scene

    ds = tmp_path / "ds"
    generate(hdr_scene(), ds, Capture(views=2, held_out=0, width=32, height=24), eye=(0, 0, 0),
             target=(0, 0, 4.5), progress=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setenv("CC", "/nonexistent/cc")
    out = tmp_path / "x.ply"
    assert main(["train", str(ds), "-o", str(out), "--iterations", "2", "--torch-raster", "native"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "dofview: error: native rasteriser: no C compiler" in err
    assert not out.exists()
