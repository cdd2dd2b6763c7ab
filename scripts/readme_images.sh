#!/usr/bin/env bash
# Re-make the README's pictures with dofview itself (headless): the cards sample focused at its three
# cards, and the HDR lamp sample at two exposures. Run after scripts/setup.sh.
set -euo pipefail
# --aperture holds at the cameras' own 800 px: 200 and 250 are A = 120 and 150 on these 480 px images
cd "$(dirname "$0")/.."
. .venv/bin/activate
out=docs/images
tmp=$(mktemp -d)
mkdir -p "$out"
cards=(samples/cards.ply --cameras samples/cards_cameras.json --view 0 --width 480 --height 360 --aperture 200)
for d in 2 4 8; do
  dofview render "${cards[@]}" --focus "$d" -o "$tmp/cards_focus_$d.exr" --png "$out/cards_focus_$d.png"
done
lamp=(samples/lamp.ply --cameras samples/lamp_cameras.json --view 0 --width 480 --height 360 --focus 2.5 --aperture 250)
for ev in 0 -6; do
  dofview render "${lamp[@]}" --exposure "$ev" -o "$tmp/lamp_ev$ev.exr" --png "$out/lamp_ev$ev.png"
done
rm -r "$tmp"
