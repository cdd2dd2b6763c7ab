"""Same commands, same pixels: render a fixed set of `dofview render` commands into a folder, or
compare two such folders pixel for pixel (a refactoring must leave every EXR channel and every PNG
unchanged).

    python scripts/pixel_identity.py run OUT          # render the set into OUT (from this checkout)
    python scripts/pixel_identity.py compare A B      # exit 1 if any EXR channel or PNG differs

The set covers both backends, the single pass at several apertures, progressive refinement
(--lens-samples), a focus-pull sequence, the physical lens, half-float output and every
tone-mapping operator. EXR headers are not compared (they carry the command's own settings, and
fields are added on purpose); the pixel data of every channel is, byte for byte.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np
import OpenEXR

CARDS = ["samples/cards.ply", "--cameras", "samples/cards_cameras.json", "--width", "160", "--height", "120"]
LAMP = ["samples/lamp.ply", "--cameras", "samples/lamp_cameras.json", "--width", "160", "--height", "120"]
OPERATORS = ["clip", "reinhard05", "histogram", "bilateral", "aces", "aces-fit", "pbr-neutral", "filmic"]

COMMANDS: dict[str, list[str]] = {
    "quad_pinhole": [*CARDS, "--raster", "quad", "--focus", "4"],
    "quad_a60": [*CARDS, "--raster", "quad", "--focus", "4", "--aperture", "60"],
    "compute_a60": [*CARDS, "--raster", "compute", "--focus", "4", "--aperture", "60"],
    "quad_physical": [*CARDS, "--raster", "quad", "--focus", "4", "--fnumber", "2", "--focal-mm", "50"],
    "quad_knobs": [*CARDS, "--raster", "quad", "--focus", "auto", "--aperture", "90", "--tau", "2/255", "--k", "0.11",
                   "--opacity-norm", "optical-depth", "--cut", "conserve"],
    "compute_disk": [*CARDS, "--raster", "compute", "--focus", "2", "--aperture", "90", "--kernel", "disk"],
    "lens_samples": [*CARDS, "--raster", "quad", "--focus", "4", "--aperture", "60", "--lens-samples", "8"],
    "lamp_half": [*LAMP, "--raster", "quad", "--focus", "auto", "--exposure", "-3", "--half", "--aperture", "40"],
    "seq_pull": [*CARDS, "--raster", "quad", "--frames", "3", "--focus", "2:8", "--aperture", "60"],
    **{f"tm_{op}": [*LAMP, "--raster", "quad", "--focus", "auto", "--aperture", "20", "--tonemap", op] for op in OPERATORS},
}


def run(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for i, (name, args) in enumerate(COMMANDS.items()):
        exr = out / (f"{name}_%04d.exr" if name.startswith("seq_") else f"{name}.exr")
        png = [] if name.startswith("seq_") else ["--png", str(out / f"{name}.png")]
        cmd = [sys.executable, "-m", "dofview", "render", args[0], "-o", str(exr), *png, *args[1:]]
        print(f"[{i + 1}/{len(COMMANDS)}] {name}", file=sys.stderr)
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


def exr_pixels(path: Path) -> dict[str, np.ndarray]:
    with OpenEXR.File(str(path)) as f:
        return {name: np.ascontiguousarray(ch.pixels) for name, ch in f.channels().items()}


def compare(a: Path, b: Path) -> int:
    names = sorted(p.name for p in a.iterdir() if p.suffix in (".exr", ".png"))
    missing = [n for n in names if not (b / n).exists()]
    bad = list(missing)
    for n in names:
        if n in missing:
            continue
        if n.endswith(".png"):
            same = (a / n).read_bytes() == (b / n).read_bytes()
        else:
            pa, pb = exr_pixels(a / n), exr_pixels(b / n)
            same = pa.keys() == pb.keys() and all(pa[c].dtype == pb[c].dtype and pa[c].tobytes() == pb[c].tobytes()
                                                  for c in pa)
        print(f"{'same' if same else 'DIFFERENT'}  {n}")
        if not same:
            bad.append(n)
    print(f"{len(names) - len(bad)} of {len(names)} files identical" + (f"; missing in {b}: {missing}" if missing else ""))
    return 1 if bad else 0


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    sub.add_parser("run").add_argument("out", type=Path)
    c = sub.add_parser("compare")
    c.add_argument("a", type=Path)
    c.add_argument("b", type=Path)
    args = p.parse_args()
    if args.cmd == "run":
        run(args.out)
        return 0
    return compare(args.a, args.b)


if __name__ == "__main__":
    sys.exit(main())
