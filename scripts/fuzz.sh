#!/usr/bin/env bash
# Build the libFuzzer targets with clang and run each for a bounded time (default 35 s), then run
# the archive and map readers once more with the command line's limits (SL_FUZZ_CLI_LIMITS=1:
# 512 MiB entries, 64 Mi triangles) so that the large-allocation paths are fuzzed too (default
# 30 s each, SL_FUZZ_CLI_SECONDS). The targets run SL_FUZZ_JOBS at a time (default: one per core),
# each for its full time on its own core, and their reports are printed in target order: twelve
# targets x 35 s + 2 x 30 s take about 4 minutes on two cores.
# Any finding (crash, sanitizer report including UBSan, leak, OOM, timeout) fails the script after
# the remaining targets have run; the finding's report is printed, its full log is kept in
# build-fuzz/logs/ and the input in build-fuzz/artifacts/. A clean target prints libFuzzer's last
# three lines. Each target runs with -seed=1 (SL_FUZZ_SEED overrides; 0: random) and -timeout=60.
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
# Every finding stops its fuzzer and fails this script: UBSan recovers by default (the targets are
# built without -fno-sanitize-recover), so without halt_on_error its reports scroll past in a run
# that ends "Done". Leaks inside assimp itself are suppressed as in the test suite (tests/lsan.supp);
# options the caller sets come after ours and win.
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1${UBSAN_OPTIONS:+:$UBSAN_OPTIONS}"
export ASAN_OPTIONS="detect_leaks=1:print_summary=1${ASAN_OPTIONS:+:$ASAN_OPTIONS}"
export LSAN_OPTIONS="suppressions=$PWD/tests/lsan.supp:print_suppressions=0${LSAN_OPTIONS:+:$LSAN_OPTIONS}"
logs=build-fuzz/logs artifacts=build-fuzz/artifacts
mkdir -p "$logs" "$artifacts"
failed=()
# the sanitizer's or libFuzzer's report of a finding: from its first line to the end of the log
report() { # report LOG
  local at
  local first='runtime error:|^==[0-9]+== ?(ERROR|WARNING)|^ERROR: libFuzzer|Sanitizer:DEADLYSIGNAL|^SUMMARY: '
  at=$(grep -n -m1 -E "$first" "$1" | cut -d: -f1 || true)
  if [ -n "$at" ]; then
    tail -n +"$at" "$1" | head -n 200
  else
    tail -n 60 "$1"
  fi
}
run() { # run NAME SECONDS CORPUS LABEL [libFuzzer flags...]
  local name=$1 s=$2 corpus=$3 label=$4
  shift 4
  local f=build-fuzz/$name seeds=fuzz/seeds/${name#fuzz_} log=$logs/$label.log rc=0
  local dirs=("$corpus")
  [ -d "$seeds" ] && dirs+=("$seeds")
  mkdir -p "$corpus"
  # -timeout: one input that runs 60 s is a hang and a finding (libFuzzer's default waits 20 minutes);
  # -seed: the same run every time (SL_FUZZ_SEED=0 lets libFuzzer pick one, for exploring)
  "$f" -max_total_time="$s" -timeout=60 -seed="${SL_FUZZ_SEED:-1}" -artifact_prefix="$artifacts/$label-" "$@" \
    "${dirs[@]}" >"$log" 2>&1 || rc=$?
  if [ "$rc" -eq 0 ] && ! grep -q -E 'runtime error:|^==[0-9]+==ERROR' "$log"; then
    tail -n 3 "$log"
    return 0
  fi
  local unit
  unit=$(sed -n 's/.*Test unit written to \(.*\)$/\1/p' "$log" | tail -n 1)
  echo "!! $label: FINDING (exit $rc); full log $log"
  report "$log"
  local env="UBSAN_OPTIONS=$UBSAN_OPTIONS${SL_FUZZ_CLI_LIMITS:+ SL_FUZZ_CLI_LIMITS=1}"
  echo "!! reproduce: $env $f ${unit:-$artifacts/$label-*}"
  touch "$logs/$label.failed"
}
jobs_max=${SL_FUZZ_JOBS:-$(nproc)}
order=()
start() { # start LABEL HEADER run-arguments...: run in the background, its report in LABEL.out
  local label=$1 header=$2
  shift 2
  while [ "$(jobs -rp | wc -l)" -ge "$jobs_max" ]; do wait -n || true; done
  rm -f "$logs/$label.failed"
  order+=("$label")
  { echo "$header"; run "$@"; } >"$logs/$label.out" 2>&1 &
}
finish() { # wait for every target, print the reports in order
  wait
  local label
  for label in "${order[@]}"; do
    cat "$logs/$label.out"
    [ -e "$logs/$label.failed" ] && failed+=("$label")
  done
  order=()
}
for f in build-fuzz/fuzz_*; do
  [ -x "$f" ] || continue
  name=$(basename "$f")
  start "$name" "== $name (${secs}s)" "$name" "$secs" "build-fuzz/corpus/$name" "$name" -rss_limit_mb=2048 \
    -max_len=1048576
done
finish
# The CLI's limits: an entry may inflate to 512 MiB (allocated once it passes the size check) and a
# map may ask for up to 64 Mi triangles (about 1.5 GB of output), so a single allocation may reach
# 2 GiB and the process, with ASan's overhead, several; 8 GiB of RSS leaves room on a 24 GiB machine.
# Inputs up to 4 MiB, so that a .bsp can be large enough for the file-size bound to allow big outputs.
for name in fuzz_pk3 fuzz_q3bsp; do
  [ -x "build-fuzz/$name" ] || continue
  SL_FUZZ_CLI_LIMITS=1 start "$name-cli" "== $name with the CLI's limits (${cli_secs}s)" "$name" "$cli_secs" \
    "build-fuzz/corpus/$name-cli" "$name-cli" -rss_limit_mb=8192 -malloc_limit_mb=2048 -max_len=4194304 -timeout=120
done
finish
if [ "${#failed[@]}" -gt 0 ]; then
  echo "fuzzing FAILED: findings in ${failed[*]} (each reported above with the command that reproduces it)" >&2
  exit 1
fi
echo "fuzzing: no findings"
