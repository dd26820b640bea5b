#!/usr/bin/env bash
# atoll's CPU traversal benchmark and the same triangles and rays through
# Embree, side by side. Usage: scripts/bench-cpu.sh [TRIANGLES] [extra bench args...]
# Needs Python 3 with numpy and embreex: installed into .venv here if missing.
set -euo pipefail
cd "$(dirname "$0")/.."
triangles="${1:-2000000}"
shift || true
out="${ATOLL_BENCH_DIR:-/tmp/atoll-bench}"
python="${PYTHON:-.venv/bin/python}"
if ! "$python" -c 'import embreex, numpy' 2>/dev/null; then
    python3 -m venv .venv
    .venv/bin/pip install --quiet embreex numpy
    python=.venv/bin/python
fi
CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-target}" cargo run --release -p atoll-bvh --example bench -- \
    --triangles "$triangles" --threads 1,0 --export "$out" "$@"
"$python" scripts/bench-embree.py "$out"
