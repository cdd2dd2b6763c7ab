"""What the README and docs promise a newcomer: the README's shell lines run, as written, in a fresh
empty folder; the files they name that the repository does not have are put there from bundled data
(``biker.spz`` from tests/data, ``output/bicycle`` a run folder of samples/cards.ply with its
training views at 160×120, to keep 48 frames cheap); the lines that cannot run here are skipped
one by one with the reason. A new shell line in the README fails this test until it is run or
given a reason. And the docs state the ranges the code enforces."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from inria_folder import SCENES, make_run_folder

from dofview.io.cameras import load_cameras_json

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "samples"
NOT_RUN = {  # a line's start → why it is not run here
    "dofview view ": "opens a window: tests/test_viewer*.py drive the viewer under Xvfb",
    "bash scripts/demo.sh": "installs system packages and a virtual environment (scripts/setup.sh)",
    "bash scripts/test.sh": "runs the whole test suite, this test included",
    "deadlinecommand ": "Deadline's job submitter, not part of dofview",
}
FILLED_IN = {"#FRAME_START#": "0", "#FRAME_END#": "1"}  # OpenCue's per-task frame range: one chunk of 2 frames


def shell_lines(markdown: str) -> list[str]:
    """The commands of the ```sh blocks: continuation lines joined, comments dropped."""
    lines = []
    for block in re.findall(r"^```sh\n(.*?)^```", markdown, flags=re.S | re.M):
        for line in block.replace("\\\n", " ").splitlines():
            line = re.sub(r"(^|\s)#(\s.*)?$", "", line).strip()  # a comment; OpenCue's #FRAME_START# stays
            if line:
                lines.append(" ".join(line.split()))
    return lines


@pytest.fixture(scope="module")
def readme_lines() -> list[str]:
    return shell_lines((ROOT / "README.md").read_text())


def test_every_readme_shell_line_is_run_or_skipped_with_a_reason(readme_lines):
    assert readme_lines, "README.md has no ```sh blocks"
    unknown = [line for line in readme_lines
               if not line.startswith("dofview ") and not any(line.startswith(k) for k in NOT_RUN)]
    assert unknown == []


def test_readme_shell_lines_run_in_an_empty_folder(tmp_path, readme_lines):
    """It used to fail at the README's first render: 'dofview: error: out/biker.exr: folder out does
    not exist'."""
    pytest.importorskip("imageio_ffmpeg", reason="the README's --video lines need the video extra")
    (tmp_path / "biker.spz").symlink_to(SCENES / "biker.spz")
    views = [c.resized(160, 120) for c in load_cameras_json(SAMPLES / "cards_cameras.json")]
    make_run_folder(tmp_path / "output" / "bicycle", {30000: SAMPLES / "cards.ply"}, views)
    ran = []
    for line in readme_lines:
        if any(line.startswith(k) for k in NOT_RUN):
            print(f"not run: {line}  ({next(v for k, v in NOT_RUN.items() if line.startswith(k))})")
            continue
        for mark, value in FILLED_IN.items():
            line = line.replace(mark, value)
        argv = shlex.split(line)
        p = subprocess.run([sys.executable, "-m", "dofview", *argv[1:]], cwd=tmp_path, capture_output=True,
                           text=True, timeout=900)
        assert p.returncode == 0, f"{line}\n{p.stderr}"
        ran.append(line)
    assert len(ran) >= 4
    out = tmp_path / "out"
    assert (out / "biker.exr").is_file() and (out / "biker.png").is_file()
    assert sorted(p.name for p in out.glob("pull_*.exr")) == [f"pull_{i:04d}.exr" for i in range(48)]
    assert (out / "pull_0047.png").is_file() and (out / "pull.mp4").stat().st_size > 0
    assert (out / "path_0000.exr").is_file() and (out / "path_0001.exr").is_file()


def test_docs_state_the_blade_counts_the_code_takes(capsys):
    """docs/VIEWER.md said 3–16 blades while `--blades 2` said 3…64."""
    from dofview.cli import main

    assert main(["render", str(SAMPLES / "cards.ply"), "-o", "x.exr", "--blades", "2"]) == 2
    error = capsys.readouterr().err
    top = int(re.search(r"0 \(a disk\) or 3…(\d+)", error)[1])
    viewer_doc = (ROOT / "docs" / "VIEWER.md").read_text()
    assert re.search(r"`--blades`: 0 round, 3–(\d+) a polygon", viewer_doc)[1] == str(top)
    with pytest.raises(SystemExit):
        main(["render", "--help"])
    assert f"3…{top} a regular polygon" in " ".join(capsys.readouterr().out.split())
