#!/bin/bash
# CLI test of the `virtual` PVS method (virtual occluders, docs/virtual-occluders.md):
#  - `pvs build --method virtual` bakes the tiny city's street cells along a short walk; `pvs info`
#    names the method and its conservative guarantee; `pvs verify` holds 4 cells to the region
#    oracle (exit 0: no miss);
#  - the file runs as the pvs culler in `bench` along the same walk against the exact oracle (exit 0:
#    a conservative method that missed anything would make it 1);
#  - where it does not apply it refuses (exit 1) with the reason: an OpenArena map's cluster cells,
#    and the same map with grid cells (no building footprints; skipped when the maps are not
#    installed).
# $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

expect 0 "$SL" gen city --preset tiny -o "$tmp/city.slscene"
expect 0 "$SL" path gen "$tmp/city.slscene" --kind walk --frames 40 -o "$tmp/walk.txt"
expect 0 "$SL" pvs build "$tmp/city.slscene" --along "$tmp/walk.txt" --method virtual --threads 2 \
    -o "$tmp/walk.slpvs"
expect 0 "$SL" pvs info "$tmp/walk.slpvs"
has "method=virtual" "$tmp/out"
has "guarantee=conservative" "$tmp/out"
expect 0 "$SL" pvs verify "$tmp/walk.slpvs" --scene "$tmp/city.slscene" --cells 4
expect 0 "$SL" bench "$tmp/city.slscene" --path "$tmp/walk.txt" --methods pvs \
    --method-options "pvs:file=$tmp/walk.slpvs" --out "$tmp/bench"

PK3=/usr/share/games/openarena/baseoa/pak1-maps.pk3
if [ -r "$PK3" ]; then
    expect 1 "$SL" pvs build "$PK3" --map oa_dm1 --method virtual -o "$tmp/dm1.slpvs"
    has "virtual: view cell 0 is a BSP cluster" "$tmp/err"
    has "method portal" "$tmp/err"
    expect 1 "$SL" pvs build "$PK3" --map oa_dm1 --cells grid --method virtual -o "$tmp/dm1.slpvs"
    has "no building footprints" "$tmp/err"
    [ ! -e "$tmp/dm1.slpvs" ] || fail "a refused bake left a file"
else
    echo "$PK3 not installed: the refusal on a map is skipped"
fi
echo "ok"
