"""Random viewer sessions: `dofview view SCENE --script S.json` with random actions (lens and
image settings, clicks, camera drags, views, saves, the help overlay, raw mouse, wheel and key
events), each run in a virtual display (xvfb-run); a session must end with exit status 0 and no
traceback. docs/ROBUSTNESS.md, "Viewer sessions".

    python scripts/random_viewer_scripts.py [--first N] [--count N] [--scene PATH ...]

Scenes default to the bundled samples and tests/data/tap.spz. Exits 1 when a session failed; the
failing script is kept and its path printed.
"""

from __future__ import annotations

import argparse
import json
import random
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_SCENES = [ROOT / "samples" / "cards.ply", ROOT / "samples" / "lamp.ply", ROOT / "tests" / "data" / "tap.spz"]
KEYS = ["f1", "h", "r", "u", "n", "tab", "space", "w", "a", "s", "d", "q", "e", "left_arrow", "right_arrow", "escape",
        "f", "c", "page_up", "page_down", "enter", "backspace"]
SETTINGS = [("focus", [0.1, 2, 8, 1000]), ("aperture", [0, 20, 200, 5000]), ("ev", [-5, 0, 3]),
            ("focus_aid", [False, True]), ("tau", [0, 0.01]), ("blades", [0, 5]), ("dof", ["sliced", "splat"]),
            ("gamma", [1.0, 2.2, 3.0]), ("k", [0.25, 1.0])]


def actions(seed: int, out: Path) -> list[dict]:
    """A session of 10–30 random actions between two frames and a quit (viewer/script.py's vocabulary).
    A key or mouse button pressed is released after a frame, and the thin lens's stages are asked
    for with an aperture: a key held in fly mode moves the view for ever, and a pinhole has no
    stages, so the script's `still` would wait out its time on either (exit 2, rightly)."""
    rnd = random.Random(seed)
    script: list[dict] = [{"do": "frames", "n": 2}]
    for i in range(rnd.randint(10, 30)):
        after: list[dict] = []
        do = rnd.choice(["set", "set", "click", "orbit", "pan", "look", "zoom", "next", "reset", "save", "copy_command",
                         "help", "frames", "wait", "mouse_move", "mouse_button", "scroll", "key", "key", "still",
                         "report"])
        if do == "set":
            name, values = rnd.choice(SETTINGS)
            a = {"do": "set", name: rnd.choice(values)}
        elif do == "click":
            a = {"do": do, "x": rnd.randint(0, 949), "y": rnd.randint(0, 799)}
        elif do in ("orbit", "pan", "look"):
            a = {"do": do, "dx": rnd.uniform(-100, 100), "dy": rnd.uniform(-50, 50)}
        elif do == "zoom":
            a = {"do": do, "steps": rnd.choice([-2, -1, 1, 2])}
        elif do == "save":
            a = {"do": do, "path": str(out / f"view{i}.exr"), "png": rnd.random() < 0.5}
        elif do == "frames":
            a = {"do": do, "n": rnd.randint(1, 4)}
        elif do == "wait":
            a = {"do": do, "seconds": round(rnd.uniform(0.05, 0.4), 3)}
        elif do == "mouse_move":
            a = {"do": do, "x": rnd.uniform(0, 1280), "y": rnd.uniform(0, 800)}
        elif do == "mouse_button":  # a click or a drag
            button = rnd.randint(0, 2)
            a = {"do": do, "button": button, "down": True}
            after = [{"do": "mouse_move", "x": rnd.uniform(0, 1280), "y": rnd.uniform(0, 800)},
                     {"do": "frames", "n": 1}, {"do": do, "button": button, "down": False}]
        elif do == "scroll":
            a = {"do": do, "steps": rnd.choice([-1, 1])}
        elif do == "key":
            key = rnd.choice(KEYS)
            a = {"do": do, "key": key, "down": True}
            after = [{"do": "frames", "n": 1}, {"do": do, "key": key, "down": False}]
        elif do == "still":
            a = {"do": "set", "aperture": rnd.choice([20, 200])}
            after = [{"do": do, "samples": rnd.choice([2, 4])}]
        elif do == "report":
            a = {"do": do, "path": str(out / f"report{i}.json"), "settle": False}
        elif do == "help":
            a = {"do": do, "show": rnd.random() < 0.5}
        else:
            a = {"do": do}
        script += [a, *after]
    return script + [{"do": "quit"}]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--first", type=int, default=0)
    parser.add_argument("--count", type=int, default=20)
    parser.add_argument("--scene", type=Path, action="append", help="a scene to draw from (repeatable)")
    a = parser.parse_args()
    if shutil.which("xvfb-run") is None:
        print("random_viewer_scripts: xvfb-run is missing (Debian package xvfb; scripts/setup.sh installs it)")
        return 2
    scenes = a.scene or DEFAULT_SCENES
    failed = 0
    for seed in range(a.first, a.first + a.count):
        out = Path(tempfile.mkdtemp(prefix=f"viewer_session_{seed}_"))
        path = out / "script.json"
        path.write_text(json.dumps(actions(seed, out)))
        scene = random.Random(seed).choice(scenes)
        t0 = time.perf_counter()
        done = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1280x800x24", sys.executable, "-m", "dofview", "view",
                               str(scene), "--script", str(path)], capture_output=True, text=True, timeout=900)
        seconds = time.perf_counter() - t0
        if done.returncode != 0 or "Traceback" in done.stderr:
            failed += 1
            tail = "\n    ".join(done.stderr.strip().splitlines()[-6:])
            print(f"[{seed}] exit {done.returncode} after {seconds:.0f} s on {scene.name}; script kept: {path}\n    {tail}",
                  flush=True)
        else:
            print(f"[{seed}] {scene.name}: {len(json.loads(path.read_text()))} actions, {seconds:.0f} s", flush=True)
            shutil.rmtree(out, ignore_errors=True)
    print(f"{a.count} sessions: {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
