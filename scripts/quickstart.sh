#!/usr/bin/env bash
# Quick start, first command: install what is missing, build (release), run the demo.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DSL_BUILD_TESTS=OFF >/dev/null
cmake --build build -j"$(nproc)"
exec build/sightline demo "$@"
