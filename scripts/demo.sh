#!/usr/bin/env bash
# Set up, then render the bundled sample headless: out/cards.exr (linear RGBA + Z) and out/cards.png.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
. .venv/bin/activate
mkdir -p out
dofview render samples/cards.ply --cameras samples/cards_cameras.json --view 0 \
  --focus 4 --aperture 60 -o out/cards.exr --png out/cards.png
echo "wrote out/cards.exr and out/cards.png"
