#!/bin/bash
# CLI test of the one thread limit (SL_MAX_THREADS, held against the OpenMP runtime's
# omp_get_thread_limit()): `pvs build`, `render` and `bench` refuse a thread count above it with a
# message naming the limit (exit 2) instead of crashing inside the OpenMP runtime (pvs build
# --threads 100000 died with SIGSEGV), refuse 0 where 0 is no default, and take the limit itself.
# OMP_THREAD_LIMIT lowers the limit. $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

out="$tmp/x.slpvs"
expect 2 timeout 60 "$SL" pvs build --city tiny -o "$out" --threads 100000 --quiet
has "100000 threads, at most 256 (SL_MAX_THREADS)" "$tmp/err"
expect 2 "$SL" pvs build --city tiny -o "$out" --threads 257 --quiet
has "at most 256" "$tmp/err"
[ ! -e "$out" ] && [ ! -e "$out.ckpt" ] || fail "a refused bake left a file"
expect 2 timeout 60 "$SL" render city:tiny --camera 0,0,2,0,0,0 --threads 100000
has "at most 256 (SL_MAX_THREADS)" "$tmp/err"
expect 2 "$SL" render city:tiny --camera 0,0,2,0,0,0 --threads 0
has "at least 1" "$tmp/err"
expect 2 timeout 60 "$SL" bench city:tiny --walk 2 --threads 100000
has "at most 256 (SL_MAX_THREADS)" "$tmp/err"
# the runtime's own limit, when lower, is the one named
OMP_THREAD_LIMIT=3 expect 2 "$SL" pvs build --city tiny -o "$out" --threads 4 --quiet
has "at most 3 (the OpenMP runtime's thread limit" "$tmp/err"
# the limit itself is accepted: a bake of the 2 cells near a camera with --threads 256 runs
# (threads beyond the cells idle)
cat >"$tmp/walk.txt" <<'PATH'
# sightline-path 1
0 0 0 1.7 0 0 0
PATH
expect 0 timeout 120 "$SL" pvs build --city tiny --cell-size 60 -o "$out" --threads 256 --quiet --json \
    --along "$tmp/walk.txt" --radius 0
has '"threads":256' "$tmp/out"
echo "ok"
