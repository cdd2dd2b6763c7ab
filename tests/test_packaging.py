"""A non-editable install works: the wheel carries every shader file the renderer loads, and the
trainer's C source."""

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.slow
def test_wheel_ships_the_shaders(tmp_path):
    p = subprocess.run([sys.executable, "-m", "pip", "wheel", str(ROOT), "--no-deps", "-q", "-w", str(tmp_path)],
                       capture_output=True, text=True)
    if p.returncode != 0 and "No matching distribution found for hatchling" in p.stderr:
        pytest.skip("the build backend (hatchling) cannot be fetched here")
    assert p.returncode == 0, p.stderr[-2000:]
    wheel = next(tmp_path.glob("dofview-*.whl"))
    names = set(zipfile.ZipFile(wheel).namelist())
    shaders = sorted(f.name for f in (ROOT / "dofview" / "rendering" / "glsl").iterdir() if f.is_file())
    assert shaders and all(f"dofview/rendering/glsl/{s}" in names for s in shaders)
    assert "dofview/rendering/quad.py" in names
    assert "dofview/train/native.c" in names  # the trainer's native rasteriser is built from it on first use
    # the package only: the tests' scene files (tests/data, ~10 MB) and the samples stay out
    assert not [n for n in names if n.startswith(("tests/", "samples/")) or n.endswith((".ply", ".spz"))]
