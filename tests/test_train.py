"""The optional trainer (dofview/train): forward model vs the GL renderer, datasets, HDR training."""

import json
import re
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from conftest import psnr, random_scene  # noqa: E402

from dofview.camera import look_at  # noqa: E402
from dofview.errors import DofviewError  # noqa: E402
from dofview.frame import RenderSettings  # noqa: E402
from dofview.io import load_scene  # noqa: E402
from dofview.io.exr import read_exr  # noqa: E402
from dofview.io.ply import write_ply  # noqa: E402
from dofview.io.png import read_png, write_png  # noqa: E402
from dofview.lens import Lens  # noqa: E402
from dofview.cli import main  # noqa: E402
from dofview.rendering.quad import QuadBackend  # noqa: E402
from dofview.rendering.reference import sh_colour  # noqa: E402
from dofview.scene import SH_C0, GaussianScene  # noqa: E402
from dofview.train.dataset import load_dataset  # noqa: E402
from dofview.train.evaluate import evaluate  # noqa: E402
from dofview.train.exif import read_exif  # noqa: E402
from dofview.train.generate import Capture, generate  # noqa: E402
from dofview.train.raster import rasterise  # noqa: E402

LAMP = (1.2, -0.8, 4.5)
LAMP_RADIANCE = (120.0, 100.0, 80.0)


def hdr_scene(seed: int = 0) -> GaussianScene:
    """A small linear-HDR scene: a checkered wall at depth 6, a striped card at depth 3, and a
    lamp ball at depth 4.5 whose radiance (≥ 80) is ≥ 200× the brightest diffuse colour (0.4)."""
    rng = np.random.default_rng(seed)
    groups = []

    def card(cx, cy, z, w, h, step, colour):
        x, y = np.meshgrid(np.arange(-w / 2 + step / 2, w / 2, step), np.arange(-h / 2 + step / 2, h / 2, step))
        x, y = x.ravel(), y.ravel()
        pts = np.stack([x + cx, y + cy, np.full(x.size, z)], 1)
        groups.append((pts, np.tile([0.6 * step, 0.6 * step, 0.006 * step], (x.size, 1)), colour(x, y),
                       np.full(x.size, 0.97)))

    card(0, 0, 6.0, 9.0, 7.0, 0.3, lambda x, y: np.where(
        ((np.floor(x / 0.8) + np.floor(y / 0.8)) % 2 == 0)[:, None], [0.3, 0.25, 0.2], [0.08, 0.1, 0.12]))
    card(-0.6, 0.3, 3.0, 1.2, 1.2, 0.1, lambda x, y: np.where(
        (np.floor(x / 0.25) % 2 == 0)[:, None], [0.4, 0.1, 0.05], [0.05, 0.2, 0.4]))
    d = rng.normal(size=(60, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ball = np.asarray(LAMP) + 0.2 * d * rng.uniform(0, 1, (60, 1)) ** (1 / 3)
    groups.append((ball, np.full((60, 3), 0.1), np.tile(LAMP_RADIANCE, (60, 1)), np.full(60, 0.99)))
    means, scales, colours, opacities = (np.concatenate(g) for g in zip(*groups))
    return GaussianScene(means=means, quats=np.tile([1.0, 0, 0, 0], (len(means), 1)), scales=scales,
                         opacities=opacities, sh_dc=(colours - 0.5) / SH_C0, colour_space="linear", name="hdr")


@pytest.mark.parametrize("settings", [RenderSettings(dof="splat"), RenderSettings(tau=0.0, dof="splat"), RenderSettings(k=1 / 9, opacity_norm="optical-depth", dof="splat")])
def test_forward_render_matches_gl(settings):
    scene = random_scene(400, colour_space="linear")
    cam = look_at((0.3, 0.1, 0.0), (0.0, 0.0, 5.0), 64, 48, 60.0)
    lens = Lens(focus=4.0, aperture=20.0)
    gl = QuadBackend(scene).render(cam, lens, settings)
    f = lambda a: torch.tensor(np.asarray(a, np.float32))  # noqa: E731
    colours = sh_colour(scene, cam.centre, np.arange(scene.count))
    r = rasterise(f(scene.means), f(scene.quats), f(scene.scales), f(scene.opacities), f(colours), cam, lens, settings)
    peak = max(float(gl.rgba.max()), 1.0)
    assert psnr(r.rgb.numpy(), gl.rgba[..., :3], peak) >= 40.0
    assert psnr(r.alpha.numpy(), gl.alpha) >= 40.0


def test_forward_render_has_gradients():
    scene = random_scene(50, colour_space="linear")
    cam = look_at((0.0, 0.0, 0.0), (0.0, 0.0, 5.0), 32, 24, 60.0)
    params = [torch.tensor(np.asarray(a, np.float32), requires_grad=True)
              for a in (scene.means, scene.quats, scene.scales, scene.opacities, scene.base_colour())]
    r = rasterise(*params, cam, Lens(4.0, 10.0), RenderSettings(tau=0.0, dof="splat"))
    r.rgb.sum().backward()
    for p in params:
        assert torch.isfinite(p.grad).all() and p.grad.abs().sum() > 0


def _dataset(tmp_path_factory, capture: Capture):
    out = tmp_path_factory.mktemp("ds") / "photos"
    generate(hdr_scene(), out, capture, eye=(0, 0, 0), target=(0, 0, 4.5), progress=False)
    return out


@pytest.fixture(scope="module")
def small_dataset(tmp_path_factory):
    return _dataset(tmp_path_factory, Capture(views=4, held_out=1, width=32, height=24))


def test_generated_dataset_round_trips(small_dataset):
    doc = json.loads((small_dataset / "transforms.json").read_text())
    ds = load_dataset(small_dataset)
    assert len(ds.shots) == 4 and len(ds.held_out) == 1
    train = [f for f in doc["frames"] if f.get("split") != "test"]
    for frame, shot in zip(train, ds.shots):
        img = read_png(shot.path)
        assert img.shape == (24, 32, 3) and img.dtype == np.uint8
        assert shot.exposure_time == frame["exposure_time"] and shot.focus == frame["focus_distance"]
        exif = read_exif(shot.path)
        assert exif["exposure_time"] == pytest.approx(frame["exposure_time"], rel=1e-6)
        assert exif["f_number"] == pytest.approx(frame["f_number"], rel=1e-6)
        assert exif["focal_length_mm"] == pytest.approx(frame["focal_length_mm"], rel=1e-6)
        assert exif["subject_distance_m"] * doc["units_per_metre"] == pytest.approx(frame["focus_distance"], rel=1e-6)
        c2w = np.asarray(frame["transform_matrix"])
        assert np.allclose(shot.camera.centre, c2w[:3, 3]) and np.allclose(shot.camera.R, c2w[:3, :3].T)
    channels, _ = read_exr(ds.held_out[0].hdr_path)
    assert channels["R"].shape == (24, 32) and channels["R"].max() >= 80.0  # the lamp, un-clipped


def test_settings_fall_back_to_exif_and_missing_ones_are_named(small_dataset, tmp_path):
    doc = json.loads((small_dataset / "transforms.json").read_text())
    full = load_dataset(small_dataset)
    for frame in doc["frames"]:
        for k in ("exposure_time", "f_number", "focus_distance", "focal_length_mm"):
            frame.pop(k, None)
    exif_only = small_dataset / "exif_only.json"
    exif_only.write_text(json.dumps(doc))
    from_exif = load_dataset(exif_only)
    for a, b in zip(full.shots, from_exif.shots):
        assert b.exposure_time == pytest.approx(a.exposure_time, rel=1e-6)
        assert b.f_number == pytest.approx(a.f_number, rel=1e-6)
        assert b.focus == pytest.approx(a.focus, rel=1e-6)
    # a photo without EXIF and without settings in the JSON is named in the error
    bare = small_dataset / "images" / "bare.png"
    write_png(bare, read_png(full.shots[0].path))
    doc["frames"][1]["file_path"] = "images/bare.png"
    exif_only.write_text(json.dumps(doc))
    with pytest.raises(DofviewError, match=r"images/bare\.png \(exposure_time, f_number, focus_distance"):
        load_dataset(exif_only)


def test_train_without_torch_is_a_one_line_error(small_dataset, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "torch", None)
    assert main(["train", str(small_dataset), "-o", str(tmp_path / "x.ply")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "pip install 'dofview[train]'" in err
    assert not (tmp_path / "x.ply").exists()


@pytest.mark.parametrize("outputs, message", [
    (["-o", "{file}/x.ply"], r"x\.ply: .*is a file, not a folder"),
    (["-o", "{tmp}/x.ply", "--log", "{file}/log.json"], r"log\.json: .*is a file, not a folder"),
    (["-o", "{tmp}/x.ply", "--checkpoint", "{tmp}"], r": is a folder, not a file name"),
    (["-o", "{tmp}/x.ply", "--plot", "{tmp}/history.jpg"], r"--plot must name a \.png file"),
    (["-o", "{tmp}/x.ply", "--checkpoint", "{tmp}/x.ply"], r"--checkpoint must name another file than -o"),
    (["-o", "{tmp}/x.ply", "--log", "{tmp}/x.ckpt"], r"--log must name another file than --checkpoint"),
])
def test_train_refuses_an_output_it_could_not_write_before_any_step(small_dataset, tmp_path, monkeypatch, capsys,
                                                                    outputs, message):
    """A training run must not end, minutes or hours later, in a refusal to write its model."""
    from dofview.train.optimise import Trainer

    monkeypatch.setattr(Trainer, "run", lambda *a, **k: pytest.fail("trained before the outputs were checked"))
    (tmp_path / "afile").write_text("")
    args = [a.format(file=tmp_path / "afile", tmp=tmp_path) for a in outputs]
    assert main(["train", str(small_dataset), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and re.search(message, err), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]


def test_make_dataset_makes_its_folder_and_refuses_one_it_cannot_write(tmp_path, capsys):
    """A new folder is made as render makes one; a name under a file, or in a place the file system
    refuses even to root (/sys), is one line before anything is rendered (the latter was a
    PermissionError traceback, the former said the file "does not exist")."""
    scene = tmp_path / "s.ply"
    write_ply(hdr_scene(), scene)
    (tmp_path / "afile").write_text("")
    small = ["--views", "2", "--held-out", "1", "--width", "16", "--height", "12", "--eye", "0,0,0", "--target", "0,0,4.5"]
    assert main(["make-dataset", str(scene), "-o", str(tmp_path / "new" / "ds"), *small]) == 0
    assert load_dataset(tmp_path / "new" / "ds").shots
    capsys.readouterr()
    places = [tmp_path / "afile" / "ds"]
    try:
        tempfile.NamedTemporaryFile(dir="/sys").close()
    except OSError:
        places.append(Path("/sys/ds"))
    for place in places:
        assert main(["make-dataset", str(scene), "-o", str(place), *small]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and err.startswith(f"dofview: error: {place}: "), err
    assert not Path("/sys/.ds.partial").exists()


def test_train_makes_the_folders_of_its_outputs(small_dataset, tmp_path):
    ply, log = tmp_path / "new" / "model" / "x.ply", tmp_path / "logs" / "log.json"
    assert main(["train", str(small_dataset), "-o", str(ply), "--iterations", "2", "--warmup", "1",
                 "--gaussians", "20", "--log", str(log)]) == 0
    assert load_scene(ply, progress=False).count > 0 and json.loads(log.read_text())["history"]


def test_train_eval_refuses_an_unwritable_json_before_evaluating(small_dataset, tmp_path, monkeypatch, capsys):
    import dofview.train.evaluate

    monkeypatch.setattr(dofview.train.evaluate, "evaluate", lambda *a, **k: pytest.fail("evaluated first"))
    (tmp_path / "afile").write_text("")
    scene = tmp_path / "s.ply"
    write_ply(random_scene(20, seed=1), scene)
    assert main(["train-eval", str(small_dataset), str(scene), "--json", str(tmp_path / "afile" / "s.json")]) == 2
    assert "afile is a file, not a folder" in capsys.readouterr().err


@pytest.fixture(scope="module")
def hdr_dataset(tmp_path_factory):
    return _dataset(tmp_path_factory, Capture(views=30, held_out=8, width=64, height=48))


@pytest.fixture(scope="module")
def trained(hdr_dataset, tmp_path_factory):
    """(a) the full model and (d) a plain LDR fit, trained through ``dofview train``."""
    out = tmp_path_factory.mktemp("trained")
    common = ["--iterations", "600", "--warmup", "200", "--max-gaussians", "800"]
    assert main(["train", str(hdr_dataset), "-o", str(out / "full.ply"), *common, "--checkpoint-every", "300",
                 "--log", str(out / "log.json"), "--plot", str(out / "history.png")]) == 0
    assert main(["train", str(hdr_dataset), "-o", str(out / "ldr.ply"), "--variant", "ldr", *common,
                 "--checkpoint-every", "0"]) == 0
    return out


@pytest.mark.slow
def test_hdr_training_beats_plain_ldr_fit_and_recovers_the_lamp(hdr_dataset, trained):
    """Held-out all-in-focus HDR views: log-radiance PSNR and the lamp's radiance."""
    ds = load_dataset(hdr_dataset)
    full, ldr = load_scene(trained / "full.ply", progress=False), load_scene(trained / "ldr.ply", progress=False)
    assert full.colour_space == "linear" and ldr.colour_space == "srgb"
    a, d = evaluate(full, ds), evaluate(ldr, ds)
    assert a.mean_log_psnr >= d.mean_log_psnr + 3.0
    assert len(a.bright_ratio) == len(ds.held_out)  # every held-out view sees the lamp
    assert abs(a.mean_bright_ratio - 1.0) <= 0.2
    history = json.loads((trained / "log.json").read_text())["history"]
    assert history[-1]["step"] == 600 and {"warm-up", "full"} <= {r["stage"] for r in history}
    assert max(r["gaussians"] for r in history) > history[0]["gaussians"]  # densification grew it
    assert (trained / "full.ckpt").is_file()
    assert (trained / "history.png").read_bytes().startswith(b"\x89PNG")


@pytest.mark.slow
def test_trained_scene_refocuses_and_reexposes_in_render(trained, tmp_path):
    ply = trained / "full.ply"
    view = ["--width", "64", "--height", "48", "--eye", "0,0,0", "--target", "0,0,4.5", "--fov", "39.6"]
    images = {}
    # --aperture 375 at the --eye/--target reference width of 800 px: A = 30 on this 64 px image
    for name, extra in {"near": ["--focus", "3", "--aperture", "375"], "far": ["--focus", "6", "--aperture", "375"],
                        "near_dark": ["--focus", "3", "--aperture", "375", "--exposure", "-3"]}.items():
        assert main(["render", str(ply), "-o", str(tmp_path / f"{name}.exr"), *view, *extra]) == 0
        ch, header = read_exr(tmp_path / f"{name}.exr")
        images[name] = np.stack([ch[c] for c in "RGB"], -1)
        assert "linear" in header["dofview:render"]
    # re-exposure scales the linear output exactly; refocusing changes the image
    assert np.allclose(images["near_dark"], images["near"] / 8, rtol=1e-5, atol=1e-7)
    assert not np.allclose(images["near"], images["far"], rtol=0.05, atol=1e-3)


def test_checkpoint_resumes_where_it_stopped(small_dataset, tmp_path):
    ply, first, second = tmp_path / "r.ply", tmp_path / "a.json", tmp_path / "b.json"
    args = ["train", str(small_dataset), "-o", str(ply), "--warmup", "10", "--gaussians", "50", "--checkpoint-every", "20"]
    assert main([*args, "--iterations", "20", "--log", str(first)]) == 0
    assert (tmp_path / "r.ckpt").is_file()
    assert main([*args, "--iterations", "30", "--resume", "--log", str(second)]) == 0
    a, b = (json.loads(p.read_text())["history"] for p in (first, second))
    assert [r["step"] for r in b] == [20, 30] and b[0] == a[0]
    assert load_scene(ply, progress=False).colour_space == "linear"
