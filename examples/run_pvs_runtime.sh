#!/bin/bash
# CTest driver of examples/pvs_runtime.c: bake what a game would ship (a scene, a walk, the PVS of
# the cells along it) with the command, then run the example on them.
#   run_pvs_runtime.sh SIGHTLINE PVS_RUNTIME
set -eu
SL="$1"
EX="$2"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$SL" gen city --preset tiny -o "$tmp/city.slscene" --quiet >/dev/null
"$SL" path gen "$tmp/city.slscene" --kind walk --frames 90 -o "$tmp/walk.txt" >/dev/null
"$SL" pvs build "$tmp/city.slscene" --along "$tmp/walk.txt" -o "$tmp/walk.slpvs" --threads 1 --quiet >/dev/null
"$EX" "$tmp/city.slscene" "$tmp/walk.slpvs" "$tmp/walk.txt"
