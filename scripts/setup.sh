#!/usr/bin/env bash
# Set up dofview on a fresh Debian/Ubuntu machine: system GL/EGL (Mesa) and Xvfb when missing, a C
# compiler (the trainer builds its native rasteriser with it on first use), a virtual environment
# in .venv, and dofview with its test and trainer extras.
# Safe to run again: it only installs what is missing.
set -euo pipefail
cd "$(dirname "$0")/.."

pkgs=(libegl1 libegl-mesa0 libgl1-mesa-dri libgbm1 libgl1 xvfb xauth gcc libc6-dev)
missing=()
if command -v dpkg-query >/dev/null 2>&1; then
  for p in "${pkgs[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
fi
if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "setup: installing ${missing[*]}" >&2
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  else
    echo "setup: missing system packages: ${missing[*]} (install them with: sudo apt-get install ${missing[*]})" >&2
  fi
fi

PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
. .venv/bin/activate
python -m pip install -q --upgrade pip >/dev/null 2>&1 || true

# The trainer extra needs torch. Take the CPU build pinned here first, so pip never resolves a
# CUDA build; without it the trainer's tests are skipped with a reason.
extras="dev,video,ocio,deep"  # video: imageio-ffmpeg, so the sequence tests write and read back MP4s; ocio: --tonemap aces; deep: isal
if python -c "import torch" >/dev/null 2>&1 || python -m pip install -q "torch==2.13.0" >/dev/null 2>&1; then
  extras="dev,video,ocio,deep,train"
else
  echo "setup: torch 2.13.0 (CPU) is not available here; the trainer will be skipped" >&2
fi
python -m pip install -q -e ".[${extras}]"

# PlayCanvas splat-transform (npm), the formats' own tool: the format tests make .spz,
# .compressed.ply and .sog files with it. Installed project-locally in .tools (tests look there
# first, then on PATH). 3.7.0 declares node >= 22 but its CLI and these conversions run on node 20.
SPLAT_TRANSFORM_VERSION=3.7.0
st=.tools/node_modules/.bin/splat-transform
if ! { [ -x "$st" ] && "$st" --version 2>&1 | grep -q "v${SPLAT_TRANSFORM_VERSION}"; }; then
  if ! command -v npm >/dev/null 2>&1 && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "setup: installing nodejs and npm" >&2
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends nodejs npm >/dev/null
  fi
  if command -v npm >/dev/null 2>&1; then
    echo "setup: installing @playcanvas/splat-transform@${SPLAT_TRANSFORM_VERSION} into .tools" >&2
    npm install --prefix .tools --no-audit --no-fund --loglevel=error \
      "@playcanvas/splat-transform@${SPLAT_TRANSFORM_VERSION}" >/dev/null
  else
    echo "setup: npm is missing; the format tests need splat-transform (install node and npm, then rerun)" >&2
  fi
fi
echo "setup: ready (.venv, extras: ${extras})" >&2
