#!/usr/bin/env bash
# Build the libFuzzer targets with clang and run each for a bounded time (default 60 s).
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-60}
CC=clang cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSL_FUZZ=ON -DSL_BUILD_TESTS=OFF -DSL_BUILD_BENCH=OFF >/dev/null
# only the fuzz targets: the library objects carry fuzzer instrumentation that just they link
targets=()
for src in fuzz/fuzz_*.c; do targets+=(--target "$(basename "$src" .c)"); done
cmake --build build-fuzz -j"$(nproc)" "${targets[@]}"
for f in build-fuzz/fuzz_*; do
  [ -x "$f" ] || continue
  name=$(basename "$f")
  corpus=build-fuzz/corpus/$name
  mkdir -p "$corpus"
  seeds=fuzz/seeds/${name#fuzz_}
  echo "== $name (${secs}s)"
  if [ -d "$seeds" ]; then
    "$f" -max_total_time="$secs" -rss_limit_mb=2048 -max_len=1048576 "$corpus" "$seeds" 2>&1 | tail -n 3
  else
    "$f" -max_total_time="$secs" -rss_limit_mb=2048 -max_len=1048576 "$corpus" 2>&1 | tail -n 3
  fi
done
