"""The display pass's cost per tone-mapping operator, as ratios to clip in one run (a Markdown table
for docs/BENCHMARKS.md): samples/lamp.ply, view 0 at --width × --height, the median of --repeats
passes each (ctx.finish() after each), plus the GPU statistics (histograms + their 32 KB read-back).

    python scripts/tonemap_timing.py --width 720 --height 480
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def main() -> int:
    from dofview.io import load_scene
    from dofview.io.cameras import load_cameras_json
    from dofview.lens import Lens
    from dofview.rendering import get_backend
    from dofview.tonemap import OPERATORS, Tonemap
    from dofview.tonemap.stats import frame_stats

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--width", type=int, default=720)
    p.add_argument("--height", type=int, default=480)
    p.add_argument("--repeats", type=int, default=9)
    args = p.parse_args()
    r = get_backend("quad", load_scene(ROOT / "samples" / "lamp.ply"))
    cam = load_cameras_json(ROOT / "samples" / "lamp_cameras.json")[0].resized(args.width, args.height)
    frame = r.render(cam, Lens(3.0, 0.0))
    w, h = args.width, args.height

    def median_ms(fn) -> float:
        fn()  # compile, allocate
        times = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            fn()
            r.ctx.finish()
            times.append(time.perf_counter() - t0)
        return 1e3 * float(np.median(times))

    rows = []
    for name, cls in OPERATORS.items():
        op = cls()
        stats = frame_stats(frame.rgba, op) if op.adaptive else None
        tm = Tonemap(operator=op)
        rows.append((name, median_ms(lambda tm=tm, stats=stats: r.tonemap_to(r.display_fbo, (0, 0, w, h), tm, stats=stats))))
        if op.adaptive:
            rows.append((f"{name}: GPU statistics", median_ms(lambda op=op: r.frame_stats(op))))
    clip = rows[0][1]
    print(f"| pass ({w}×{h}) | ms | × clip |\n|---|---|---|")
    for name, ms in rows:
        print(f"| {name} | {ms:.2f} | {ms / clip:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
