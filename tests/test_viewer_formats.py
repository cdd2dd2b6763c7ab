"""The viewer opens the distribution formats (issue 13) as it opens a .ply: one scripted session
under Xvfb opens a .spz given on the command line (with --spz-axes), then a .compressed.ply, a
SOG folder's meta.json and a cut .spz, reporting after each."""

import json
import os
from pathlib import Path

from conftest import random_scene
from inria_folder import SCENES as DATA
from test_viewer import display, run_viewer  # noqa: F401  (display is a fixture)

from dofview.bench.formats import convert, splat_transform
from dofview.io.ply import write_ply


def test_viewer_opens_each_format(display, tmp_path):  # noqa: F811
    assert splat_transform(), "splat-transform is not installed: run scripts/setup.sh"
    ply = tmp_path / "small.ply"
    write_ply(random_scene(n=2000, degree=1, seed=6), ply)
    (tmp_path / "sog").mkdir()
    meta = convert(ply, tmp_path / "sog" / "meta.json")
    cut = tmp_path / "cut.spz"
    cut.write_bytes(Path(DATA, "biker.spz").read_bytes()[:100_000])
    script = [{"do": "report", "path": tmp_path / "spz.json"}]
    for name, path in (("compressed", f"{DATA}/guitar.compressed.ply"), ("sog", meta), ("cut", cut)):
        script += [{"do": "open", "path": path}, {"do": "report", "path": tmp_path / f"{name}.json"}]
    (tmp_path / "script.json").write_text(json.dumps(script + [{"do": "quit"}], default=str))
    res = run_viewer([f"{DATA}/biker.spz", "--spz-axes", "rub", "--width", "320", "--height", "240",
                      "--script", tmp_path / "script.json"], {**os.environ, "DISPLAY": display})
    assert res.returncode == 0, res.stderr
    assert "biker.spz: SPZ v4, data read as RUB (--spz-axes)" in res.stderr
    r = {name: json.loads((tmp_path / f"{name}.json").read_text()) for name in ("spz", "compressed", "sog", "cut")}
    assert r["spz"]["count"] == 152_746 and r["spz"]["error"] == "" and r["spz"]["drawn"] > 0
    assert r["compressed"]["count"] == 90_854 and r["compressed"]["error"] == ""
    assert r["sog"]["count"] == 2000 and r["sog"]["error"] == "" and r["sog"]["scene"].endswith("meta.json")
    assert "cut.spz" in r["cut"]["error"] and r["cut"]["count"] == 2000  # the SOG scene stays
