#!/bin/bash
# CLI test of the `volumetric` PVS method end to end on the tiny city: `pvs build --method
# volumetric` along a walk (the cells near its cameras), `pvs info` names the method and its
# guarantee, `pvs verify` holds cells to the region oracle (0 misses), and `bench` runs the `pvs`
# culler on the file against the point oracle (exit 1 on any miss). A bad option is a usage error.
# $1 is the sightline binary. Under sanitizers (SL_SANITIZED set) fewer frames and cells.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

if [ -n "${SL_SANITIZED:-}" ]; then N=3; C=2; else N=8; C=4; fi

expect 0 "$SL" path gen city:tiny --kind walk --frames "$N" -o "$tmp/walk.txt"
expect 0 "$SL" pvs build city:tiny --along "$tmp/walk.txt" --method volumetric:voxel=1.5 -o "$tmp/v.slpvs" --threads 2
expect 0 "$SL" pvs info "$tmp/v.slpvs"
has "method=volumetric" "$tmp/out"
has "guarantee=conservative" "$tmp/out"
expect 0 "$SL" pvs verify "$tmp/v.slpvs" --scene city:tiny --cells "$C"
has "0 missed objects" "$tmp/out"
expect 0 "$SL" bench city:tiny --path "$tmp/walk.txt" --methods pvs --method-options pvs:file="$tmp/v.slpvs" --no-plots \
    --out "$tmp/b"
[ "$(awk -F, '$10 == "pvs" && $18 == 0' "$tmp/b/frames.csv" | wc -l)" -eq "$N" ] || fail "pvs culler: rows with misses"
expect 2 "$SL" pvs build city:tiny --method volumetric:voxel=-1 -o "$tmp/bad.slpvs"
has "voxel" "$tmp/err"
echo "ok"
