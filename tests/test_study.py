"""`dofview bench SCENE --views N` (bench/study.py): the real-scene study against the physical thin
lens, on a bundled sample at a tiny size."""

from __future__ import annotations

import csv
from pathlib import Path

from dofview.bench.study import pareto
from dofview.cli import main

ROOT = Path(__file__).resolve().parents[1]


def test_study_writes_the_table_plot_and_rows(tmp_path):
    out = tmp_path / "study"
    assert main(["bench", str(ROOT / "samples" / "cards.ply"), "--views", "2", "--width", "64", "--ref-samples", "8",
                 "--frames", "1", "--coc-px", "6", "--focus-pct", "50", "--out", str(out)]) == 0
    rows = list(csv.DictReader((out / "study.csv").open()))
    methods = {r["method"] for r in rows}
    assert {"pinhole", "k=1/9 (CineGS)", "k=1/4", "k=1 (Spark)", "default", "splat, conserve cut"} <= methods
    assert {r["view"] for r in rows} == {"0", "1"}
    table = (out / "study.md").read_text()
    assert "| default |" in table and "Largest blur (6 px CoC): frame time / pinhole" in table
    assert (out / "study.png").stat().st_size > 10_000

    def acc(n: int) -> float:
        return sum(float(r["psnr"]) for r in rows if r["method"] == f"accumulation {n}")

    assert acc(1) < acc(4) < acc(8)  # more lens samples, closer to the truth


def test_pareto_front():
    pts = [(1.0, 20.0), (1.5, 19.0), (2.0, 25.0), (2.0, 24.0), (4.0, 30.0)]
    assert pareto(pts) == [(1.0, 20.0), (2.0, 25.0), (4.0, 30.0)]
