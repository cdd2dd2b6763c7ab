"""Checkpoints and resumption: an interrupted fit resumes to the same model, checkpoints record
what made them and the held-out score, and the ETA counts only the resumed run's pace."""

import io
import json

import pytest

torch = pytest.importorskip("torch")

from dofview.cli import main  # noqa: E402
from dofview.train.dataset import load_dataset  # noqa: E402
from dofview.train.generate import Capture, generate  # noqa: E402
from dofview.train.optimise import TrainConfig, Trainer  # noqa: E402


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    from test_train import hdr_scene

    out = tmp_path_factory.mktemp("resume") / "ds"
    generate(hdr_scene(), out, Capture(views=6, held_out=2, width=32, height=24), eye=(0, 0, 0),
             target=(0, 0, 4.5), progress=False)
    return out


def test_interrupted_fit_resumes_to_the_same_model(dataset, tmp_path):
    """Stopped at step 35 (warm-up over, one densification behind, one ahead, SH bands growing),
    checkpointed, loaded into a new trainer and run on: the same parameters, bit for bit, as
    without the stop (Adam moments, both random generators and the densification statistics
    are in the checkpoint; the native rasteriser is deterministic)."""
    config = TrainConfig(iterations=60, warmup=20, initial=60, max_gaussians=200, densify_every=25, sh_degree=1)
    ds = load_dataset(dataset)
    whole = Trainer(ds, config, "cpu")
    assert whole.raster == "native"
    whole.run(progress=False)
    first = Trainer(ds, config, "cpu")
    while first.step < 35:
        first.train_step()
    first.save_checkpoint(tmp_path / "c.ckpt")
    resumed = Trainer(ds, config, "cpu")
    resumed.load_checkpoint(tmp_path / "c.ckpt")
    resumed.run(progress=False)
    assert whole.model.count != config.initial  # densification changed the count on the way
    for name, p in whole.model.params.items():
        assert torch.equal(p, resumed.model.params[name]), name
    assert whole.history.rows[-1] == resumed.history.rows[-1]  # steps 51–60: the same losses


def test_checkpoints_record_their_maker_and_held_out_score(dataset, tmp_path, capsys):
    out, log = tmp_path / "m.ply", tmp_path / "m.json"
    args = ["train", str(dataset), "-o", str(out), "--warmup", "10", "--gaussians", "40", "--checkpoint-every", "15",
            "--sh-degree", "1"]
    assert main([*args, "--iterations", "30", "--log", str(log)]) == 0
    err = capsys.readouterr().err
    data = torch.load(out.with_suffix(".ckpt"), weights_only=False)
    assert data["raster"] == "native" and data["config"]["sh_degree"] == 1 and data["step"] == 30
    scores = data["scores"]
    assert [s["step"] for s in scores] == [15, 30]
    assert all(5.0 < s["log_psnr"] < 60.0 and s["bright_ratio"] > 0 for s in scores)
    logged = json.loads(log.read_text())
    assert logged["scores"] == scores and logged["raster"] == "native"
    assert logged["variant"] == data["config"]["variant"] == "no-foc"  # L_foc is off by default
    assert f"held-out log-radiance PSNR {scores[-1]['log_psnr']:.2f} dB at step 30" in err
    assert "(native rasteriser)" in err
    # resumed with another rasteriser: said, and the scores go on from where they were
    assert main([*args, "--iterations", "45", "--resume", "--torch-raster", "sparse", "--log", str(log)]) == 0
    err = capsys.readouterr().err
    assert "was trained with the native rasteriser; going on with sparse" in err
    resumed = json.loads(log.read_text())
    assert [s["step"] for s in resumed["scores"]] == [15, 30, 45] and resumed["scores"][:2] == scores
    assert resumed["raster"] == "sparse"


def test_eta_of_a_resumed_run_counts_its_own_pace(monkeypatch):
    from dofview import progress

    now = [0.0]
    monkeypatch.setattr(progress.time, "perf_counter", lambda: now[0])
    out = io.StringIO()
    p = progress.Progress("training", 2000, stream=out, delay=0.0, resumed=1500)
    now[0] = 10.0
    p.update(1600)  # 100 steps in 10 s, 400 to go: 40 s (from step 0 it would say 2.5 s)
    assert out.getvalue() == "training: 1600/2000 (80%, 10.0s, eta 40.0s) \n"


def test_without_a_renderer_checkpoints_go_on_unscored(dataset, tmp_path, monkeypatch, capsys):
    from dofview.errors import BackendUnavailable
    from dofview.train import optimise

    def no_gl(*args, **kwargs):
        raise BackendUnavailable("no EGL display")

    monkeypatch.setattr(optimise, "evaluate", no_gl)
    out = tmp_path / "u.ply"
    assert main(["train", str(dataset), "-o", str(out), "--iterations", "20", "--warmup", "5", "--gaussians", "30",
                 "--checkpoint-every", "5"]) == 0
    err = capsys.readouterr().err
    assert err.count("no held-out scores at checkpoints: no EGL display") == 1  # said once, not at every checkpoint
    data = torch.load(out.with_suffix(".ckpt"), weights_only=False)
    assert data["step"] == 20 and data["scores"] == []
