#!/usr/bin/env bash
# Set up, then run the whole test suite (GL tests on Mesa llvmpipe through EGL; viewer tests under Xvfb).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
. .venv/bin/activate
python -m pytest -q -ra "$@"
