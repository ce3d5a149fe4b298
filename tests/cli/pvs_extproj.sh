#!/bin/bash
# CLI test of the extproj PVS method (extended projections): `pvs build --method extproj` bakes the
# cells along a walk of the tiny city, the file records the method and verifies against the region
# oracle with zero misses, and the `pvs` culler runs on it along the walk with no missed object;
# Quake III cluster cells are refused with the reason (when openarena's maps are installed).
# $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

expect 0 "$SL" gen city --preset tiny -o "$tmp/tiny.slscene"
expect 0 "$SL" path gen "$tmp/tiny.slscene" --kind walk -o "$tmp/walk.txt"
expect 0 "$SL" pvs build "$tmp/tiny.slscene" --along "$tmp/walk.txt" --method extproj --threads 2 -o "$tmp/w.slpvs"
expect 0 "$SL" pvs info "$tmp/w.slpvs"
has "method=extproj" "$tmp/out"
has "guarantee=conservative" "$tmp/out"
expect 0 "$SL" pvs verify "$tmp/w.slpvs" --scene "$tmp/tiny.slscene" --cells 8
has "0 missed objects" "$tmp/out"
# the same bytes from a second bake on one thread
expect 0 "$SL" pvs build "$tmp/tiny.slscene" --along "$tmp/walk.txt" --method extproj --threads 1 -o "$tmp/w1.slpvs"
cmp -s "$tmp/w.slpvs" "$tmp/w1.slpvs" || fail "extproj bakes differ between 2 threads and 1"
# the pvs culler on the file, along the walk: no missed object
expect 0 "$SL" bench "$tmp/tiny.slscene" --path "$tmp/walk.txt" --methods pvs \
    --method-options pvs:file="$tmp/w.slpvs" --no-plots --out "$tmp/b"
has "| pvs | conservative |" "$tmp/out"
awk -F, '$10 == "pvs" && $18 != 0 { exit 1 }' "$tmp/b/frames.csv" || fail "pvs on the extproj file missed an object"
# an option out of range
expect 2 "$SL" pvs build "$tmp/tiny.slscene" --along "$tmp/walk.txt" --method extproj --options dirs=6 \
    -o "$tmp/x.slpvs"
has "dirs must be 4 or 8" "$tmp/err"

PK3=/usr/share/games/openarena/baseoa/pak1-maps.pk3
if [ -r "$PK3" ]; then
    expect 1 "$SL" pvs build "$PK3" --map q3dm6ish --method extproj --threads 1 -o "$tmp/q.slpvs"
    has "extproj: view cell 0 is a BSP cluster" "$tmp/err"
    [ ! -e "$tmp/q.slpvs" ] || fail "a refused bake left a file"
fi
echo "ok"
