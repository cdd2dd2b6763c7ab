#!/usr/bin/env bash
# Issues 12, 23 and 28's GPU measurements in one prepared run, for a session lent an NVIDIA GPU (the
# figures on llvmpipe are in docs/BENCHMARKS.md "Compute backend" and "Sliced depth of field"; the
# GPU tables there stay open until this has run). Measures, at 1200×675, 1M and 6M random Gaussians
# (bench.synth.random_scene, SH 0), A ∈ {0, 50, 100}, for each depth-of-field mode (sliced, the
# default, and per-splat): whole frames during an orbit (every frame sorts: the quad backend on the
# CPU plus an upload, the compute backend on the GPU) → median / p90 / p99 ms, the CPU time issuing
# a frame, the sliced mode's layers and FPS per backend, the renderer's GPU bytes, and the peak GPU
# memory seen by nvidia-smi; then the compute backend's tile / pixels-per-thread variants at 1M
# (per-splat); then the viewer's frame time while the focus slider is dragged, at each size
# (scripts/viewer_budget.py --drag focus); then the sliced frame's pass profile on the repository's
# scene stand-ins (python -m dofview.bench.sliced_study passes). Everything goes to $OUT (default
# ./gpu_bench_out) as JSON, PNG and logs. Run from the repository root: OUT=/some/dir scripts/gpu_bench.sh
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-gpu_bench_out}
SIZES=${SIZES:-1000000,6000000}   # issue 28's sizes; overridable for a dry run on a small machine
FRAMES=${FRAMES:-30}
mkdir -p "$OUT"
if [ -f .venv/bin/activate ]; then . .venv/bin/activate; fi
export PYTHONUNBUFFERED=1

nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$OUT/gpu.csv" 2>&1 || true
python -c "from dofview.rendering.gl import headless_context as h; c = h(); print(c.info['GL_RENDERER']); print(c.info['GL_VERSION'])" \
  > "$OUT/gl.txt" 2>&1

# Peak GPU memory: nvidia-smi sampled every 100 ms while the benchmarks run.
(while true; do nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits 2>/dev/null || true; sleep 0.1; done) \
  > "$OUT/memory_used_mib.txt" &
MONITOR=$!
trap 'kill $MONITOR 2>/dev/null || true' EXIT

for dof in sliced splat; do
  python -m dofview.bench.backends --sizes "$SIZES" --apertures 0,50,100 --frames "$FRAMES" --width 1200 --height 675 \
    --no-samples --dof "$dof" --json "$OUT/backends_$dof.json" --plot "$OUT/backends_$dof.png" > "$OUT/backends_$dof.log" 2>&1
done

for variant in 16,1 16,2 8,1 32,2; do
  python -m dofview.bench.backends --sizes "${SIZES%%,*}" --apertures 0,100 --frames "$FRAMES" --width 1200 --height 675 \
    --no-samples --dof splat --compute-tile "$variant" --json "$OUT/compute_tile_${variant/,/x}.json" \
    > "$OUT/compute_tile_${variant/,/x}.log" 2>&1 || echo "variant $variant failed (see its log)" >> "$OUT/errors.txt"
done

# The viewer while the focus slider is dragged (issue 28): its model headless, the interaction
# budget choosing previews, each frame's time and host time, then the still frame.
for n in ${SIZES//,/ }; do
  python scripts/viewer_budget.py "random:$n" --drag focus --width 1200 --height 675 --steps 24 \
    --json "$OUT/viewer_focus_$n.json" > "$OUT/viewer_focus_$n.log" 2>&1 \
    || echo "viewer focus drag at $n failed (see its log)" >> "$OUT/errors.txt"
done

# Where the sliced frame's time goes on this GPU (issue 28; llvmpipe's figure is in
# docs/BENCHMARKS.md "Where the sliced frame's time goes"): each kind of pass timed between GL waits,
# on the repository's scene stand-ins, both backends, A = 100 and 16 px.
python -m dofview.bench.sliced_study passes tests/data/two_planes.ply tests/data/burger.ply tests/data/tap.spz \
  --width 1200 --height 675 --reps 5 --figure "$OUT/sliced_passes.png" > "$OUT/sliced_passes.tsv" 2> "$OUT/sliced_passes.log" \
  || echo "the pass profile failed (see its log)" >> "$OUT/errors.txt"

kill $MONITOR 2>/dev/null || true
python - "$OUT" <<'PY'
import json, sys
from pathlib import Path
out = Path(sys.argv[1])
used = [int(x) for x in (out / "memory_used_mib.txt").read_text().split() if x.isdigit()]
summary = {"peak_gpu_memory_used_mib": max(used) if used else None, "gl": (out / "gl.txt").read_text().split("\n")[:2],
           "rows": []}
for f in sorted(out.glob("viewer_focus_*.json")):
    summary.setdefault("viewer_focus_drag", []).extend(json.loads(f.read_text()))
for f in sorted(out.glob("*.json")):
    if f.name == "summary.json" or f.name.startswith("viewer_focus_"):
        continue
    for r in json.loads(f.read_text())["rows"]:
        summary["rows"].append({"file": f.name, **{k: r.get(k) for k in ("scene", "backend", "dof", "aperture", "median_ms",
                                                                       "p90_ms", "p99_ms", "host_ms", "layers", "fps", "ratio",
                                                                       "gpu_bytes", "pairs")}})
(out / "summary.json").write_text(json.dumps(summary, indent=1))
for r in summary["rows"]:
    print(f"{r['file']:28s} {r['scene']:12s} {r['backend']:8s} {r['dof']:7s} A={r['aperture']:5g} {r['median_ms']:8.2f} ms "
          f"p99 {r['p99_ms']:8.2f} ms host {r['host_ms']:7.2f} ms {r['layers']:3d} layers {r['fps']:7.1f} FPS "
          f"×{r['ratio']:.2f}")
for r in summary.get("viewer_focus_drag", []):
    print(f"viewer, focus dragged: {r['scene']:16s} {r['median']:8.2f} ms a frame (slowest {r['max']:.2f}), host "
          f"{r['host']:.2f} ms, previews {r['previews']}; still frame {r['still']:.2f} ms, {r['layers']} layers; "
          f"pinhole {r['pinhole']:.2f} ms")
print("peak GPU memory used (MiB):", summary["peak_gpu_memory_used_mib"])
PY
