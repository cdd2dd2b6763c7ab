"""Random `dofview render` command lines, or with --bench `dofview bench --quick` ones: each must
run (exit 0, its EXR or its report written) or fail in one line (`dofview: error: …`, exit 2,
nothing written); a traceback, another exit status or an output left behind by a failed command
is reported. docs/ROBUSTNESS.md, "Command lines".

    python scripts/random_render_commands.py [--bench] [--first N] [--count N] [--scene PATH ...]

Scenes default to the bundled samples and tests/data; a streamed LOD set (a folder or its
lod-meta.json) is given a coarse --lod. Exits 1 when something was reported.
"""

from __future__ import annotations

import argparse
import random
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_SCENES = [ROOT / "samples" / "cards.ply", ROOT / "samples" / "lamp.ply", ROOT / "tests" / "data" / "tap.spz",
                  ROOT / "tests" / "data" / "guitar.compressed.ply"]


def command_line(seed: int, scenes: list[Path], out: Path) -> list[str]:
    """One random command line writing into ``out``; options drawn independently, so that many
    combinations are ones dofview must refuse."""
    rnd = random.Random(seed)
    scene = rnd.choice(scenes)
    args = ["render", str(scene), "-o", str(out / "o.exr"),
            "--width", str(rnd.choice([17, 64, 97, 160])), "--height", str(rnd.choice([9, 48, 71, 120]))]
    if scene.is_dir() or scene.name == "lod-meta.json":
        args += ["--lod", str(rnd.randint(3, 6))]

    def maybe(p: float, *opts: str) -> None:
        if rnd.random() < p:
            args.extend(opts)

    maybe(0.5, "--raster", rnd.choice(["quad", "compute", "auto"]))
    maybe(0.3, "--dof", rnd.choice(["sliced", "splat"]))
    maybe(0.4, "--blur", rnd.choice(["2%", "8", "0.5", "30", "5%@3", "12@1.5", "50%"]))
    maybe(0.2, "--aperture", rnd.choice(["0", "50", "3000", "1e5"]))
    maybe(0.3, "--focus", rnd.choice(["0.2", "3", "1e4", "4"]))
    maybe(0.3, "--blades", str(rnd.choice([0, 3, 5, 6, 9])))
    maybe(0.2, "--blade-rotation", f"{rnd.uniform(-90, 400):.2f}")
    maybe(0.2, "--lens-samples", str(rnd.choice([1, 2, 4, 7])))
    maybe(0.2, "--exposure", str(rnd.choice([-8, -1, 0, 3])))
    maybe(0.2, "--tonemap", rnd.choice(["clip", "reinhard05", "histogram", "bilateral", "aces-fit", "pbr-neutral",
                                        "filmic", "auto"]))
    maybe(0.15, "--half")
    maybe(0.25, "--png", str(out / "o.png"))
    maybe(0.15, "--deep", str(out / "deep.exr"))
    maybe(0.1, "--kernel", "disk")
    maybe(0.1, "--cut", "conserve")
    maybe(0.1, "--opacity-norm", rnd.choice(["none", "energy", "optical-depth"]))
    maybe(0.1, "--tau", rnd.choice(["0", "0.01", "0.2"]))
    maybe(0.1, "--frames", str(rnd.choice([2, 3])))
    maybe(0.1, "--near", rnd.choice(["0.001", "0.5", "5"]))
    maybe(0.1, "--fnumber", rnd.choice(["1.4", "8"]))
    maybe(0.1, "--focal-mm", rnd.choice(["35", "85"]))
    maybe(0.1, "--up", rnd.choice(["+y", "-z", "x"]))
    maybe(0.1, "--fov", rnd.choice(["10", "90", "150"]))
    maybe(0.1, "--eye=0.1,0.2,-3")
    if "--frames" in args:
        args[args.index("-o") + 1] = str(out / "o_%03d.exr")
    return args


def bench_line(seed: int, scenes: list[Path], out: Path) -> list[str]:
    """One random `dofview bench --quick` command line writing into ``out``/b: the full bench's
    options and the study's (--views) drawn independently, so that many mix the two modes."""
    rnd = random.Random(seed)
    scene = rnd.choice(scenes)
    args = ["bench", str(scene), "--quick", "--out", str(out / "b"), "--frames", "1", "--counts", "500",
            "--widths", "32", "--ref-samples", "8"]
    if scene.is_dir() or scene.name == "lod-meta.json":
        args += ["--lod", str(rnd.randint(3, 6))]

    def maybe(p: float, *opts: str) -> None:
        if rnd.random() < p:
            args.extend(opts)

    maybe(0.4, "--no-plots")
    maybe(0.3, "--raster", rnd.choice(["quad", "compute", "auto"]))
    maybe(0.3, "--focus", rnd.choice(["auto", "3", "0.5,4", "1e4", "-1", "x"]))
    maybe(0.3, "--blur", rnd.choice(["4", "8,16", "2%", "5@3", "30%", "0", "-2"]))
    maybe(0.2, "--apertures", rnd.choice(["0", "50", "10,100", "1e5", "-3"]))
    maybe(0.2, "--grid-apertures", rnd.choice(["0", "20,40"]))
    maybe(0.2, "--taus", rnd.choice(["0", "0,0.01", "1", "0.5"]))
    maybe(0.2, "--ks", rnd.choice(["0.25", "0,1", "-1"]))
    maybe(0.2, "--norms", rnd.choice(["none", "energy,bogus", "optical-depth"]))
    maybe(0.2, "--acc-samples", rnd.choice(["2", "1,3", "0"]))
    maybe(0.2, "--no-scaling")
    maybe(0.2, "--width", str(rnd.choice([17, 48, 96])))
    maybe(0.2, "--height", str(rnd.choice([9, 36, 72])))
    maybe(0.15, "--exposure", rnd.choice(["-3", "2"]))
    maybe(0.15, "--tau", rnd.choice(["0", "0.02", "2"]))
    maybe(0.15, "--k", rnd.choice(["0.1", "1", "0"]))
    maybe(0.15, "--opacity-norm", rnd.choice(["none", "energy", "x"]))
    maybe(0.15, "--views", rnd.choice(["1", "2", "0"]))
    maybe(0.1, "--focus-pct", rnd.choice(["50", "10,90", "120"]))
    maybe(0.1, "--coc-px", rnd.choice(["4", "6,16", "0"]))
    maybe(0.1, "--up", rnd.choice(["+y", "z"]))
    maybe(0.1, "--fov", rnd.choice(["20", "120"]))
    maybe(0.1, "--near", rnd.choice(["0.5", "100"]))
    maybe(0.1, "--warmup", rnd.choice(["0", "2"]))
    maybe(0.1, "--count-size", rnd.choice(["64x48", "bad"]))
    maybe(0.1, "--bench-width", rnd.choice(["40", "0"]))
    return args


def check(args: list[str], out: Path) -> tuple[str | None, bool]:
    """(what is wrong or None, whether it ran)."""
    done = subprocess.run([sys.executable, "-m", "dofview", *args], capture_output=True, text=True, timeout=900)
    lines = done.stderr.strip().splitlines()
    if args[0] == "bench":
        written = [p for p in (out / "b" / "report.md", out / "b" / "study.md") if p.exists()]
        left = (out / "b").exists()
    else:
        written = list(out.glob("o*.exr"))
        left = bool(written)
    if "Traceback" in done.stderr:
        return "a traceback", False
    if done.returncode == 0:
        return (None if written else "exit 0 and no output"), True
    if done.returncode != 2:
        return f"exit status {done.returncode}", False
    if not lines or not lines[-1].startswith("dofview: error: "):
        return "an error that is not one dofview line", False
    return ("an output written by a failed command" if left else None), False


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--first", type=int, default=0)
    parser.add_argument("--count", type=int, default=200)
    parser.add_argument("--scene", type=Path, action="append", help="a scene to draw from (repeatable)")
    parser.add_argument("--bench", action="store_true", help="draw `dofview bench --quick` command lines instead")
    a = parser.parse_args()
    scenes = a.scene or DEFAULT_SCENES
    problems = rendered = 0
    for seed in range(a.first, a.first + a.count):
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp)
            args = (bench_line if a.bench else command_line)(seed, scenes, out)
            problem, ok = check(args, out)
        rendered += ok
        if problem:
            problems += 1
            print(f"[{seed}] {problem}: dofview {shlex.join(args)}", flush=True)
        if (seed - a.first + 1) % 50 == 0:
            print(f"{seed - a.first + 1}/{a.count} command lines, {rendered} ran, {problems} reported", flush=True)
    print(f"{a.count} command lines: {rendered} ran, {a.count - rendered - problems} refused in one line, "
          f"{problems} reported")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
