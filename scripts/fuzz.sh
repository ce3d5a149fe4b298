#!/usr/bin/env bash
# Build the libFuzzer targets with clang and run each for a bounded time (default 35 s), then run
# the archive and map readers once more with the command line's limits (SL_FUZZ_CLI_LIMITS=1:
# 512 MiB entries, 64 Mi triangles) so that the large-allocation paths are fuzzed too (default
# 30 s each, SL_FUZZ_CLI_SECONDS). Ten targets x 35 s + 2 x 30 s is about 7 minutes, which keeps
# the fuzz stage of CI near its 10-minute budget with the build.
set -euo pipefail
cd "$(dirname "$0")/.."
secs=${1:-35}
cli_secs=${SL_FUZZ_CLI_SECONDS:-30}
CC=clang cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSL_FUZZ=ON -DSL_BUILD_TESTS=OFF -DSL_BUILD_BENCH=OFF >/dev/null
# only the fuzz targets: the library objects carry fuzzer instrumentation that just they link
targets=()
for src in fuzz/fuzz_*.c; do targets+=(--target "$(basename "$src" .c)"); done
cmake --build build-fuzz -j"$(nproc)" "${targets[@]}"
# fuzz_mmap writes each input to a file: keep those in memory where possible
if [ -z "${TMPDIR:-}" ] && [ -d /dev/shm ] && [ -w /dev/shm ]; then export TMPDIR=/dev/shm; fi
run() { # run NAME SECONDS CORPUS [libFuzzer flags...]
  local name=$1 s=$2 corpus=$3
  shift 3
  local f=build-fuzz/$name seeds=fuzz/seeds/${name#fuzz_}
  mkdir -p "$corpus"
  if [ -d "$seeds" ]; then
    "$f" -max_total_time="$s" "$@" "$corpus" "$seeds" 2>&1 | tail -n 3
  else
    "$f" -max_total_time="$s" "$@" "$corpus" 2>&1 | tail -n 3
  fi
}
for f in build-fuzz/fuzz_*; do
  [ -x "$f" ] || continue
  name=$(basename "$f")
  echo "== $name (${secs}s)"
  run "$name" "$secs" "build-fuzz/corpus/$name" -rss_limit_mb=2048 -max_len=1048576
done
# The CLI's limits: an entry may inflate to 512 MiB (allocated once it passes the size check) and a
# map may ask for up to 64 Mi triangles (about 1.5 GB of output), so a single allocation may reach
# 2 GiB and the process, with ASan's overhead, several; 8 GiB of RSS leaves room on a 24 GiB machine.
# Inputs up to 4 MiB, so that a .bsp can be large enough for the file-size bound to allow big outputs.
for name in fuzz_pk3 fuzz_q3bsp; do
  [ -x "build-fuzz/$name" ] || continue
  echo "== $name with the CLI's limits (${cli_secs}s)"
  SL_FUZZ_CLI_LIMITS=1 run "$name" "$cli_secs" "build-fuzz/corpus/$name-cli" \
    -rss_limit_mb=8192 -malloc_limit_mb=2048 -max_len=4194304 -timeout=120
done
