#!/bin/bash
# CLI test of the motion regions in a bake (docs/motion.md): the tiny city's cars have motion
# records, so `pvs build` (along a short drive) stores a region hierarchy, .slpvs 1.2, says so in
# its summary and --json, and `pvs info` shows it; --no-regions writes 1.1 without them; the same
# bake on 1 and 2 threads gives the same bytes; `bench` with the pvs culler runs with the default
# dynamic=auto and with dynamic=regions, and refuses dynamic=regions on the file without regions.
# `pvs query` shows a cell's marks; a .slpvs given as the scene is refused as what it is; a default
# bake names its method also with --quiet; a path whose cameras lie far from every cell is warned of.
# $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

expect 0 "$SL" pvs build --help
has "--no-regions" "$tmp/out"
expect 0 "$SL" path gen city:tiny --kind drive --frames 30 --fps 10 --seed 3 -o "$tmp/drive.txt"
expect 0 "$SL" pvs build city:tiny --along "$tmp/drive.txt" --method adjustable --threads 2 --quiet -o "$tmp/r2.slpvs"
has "motion regions: [0-9]* nodes, marked for every cell" "$tmp/out"
expect 0 "$SL" pvs build city:tiny --along "$tmp/drive.txt" --method adjustable --threads 1 --quiet --json -o "$tmp/r1.slpvs"
has '"regions":[1-9][0-9]*' "$tmp/out"
cmp -s "$tmp/r1.slpvs" "$tmp/r2.slpvs" || fail "the regions differ between 1 and 2 threads"
expect 0 "$SL" pvs info "$tmp/r1.slpvs"
has ".slpvs 1.2" "$tmp/out"
has "motion regions (where dynamic objects can be): [0-9]* nodes over [1-9][0-9]* regions, [0-9.]* nodes marked visible per cell on average; [0-9.]* [KMG]*i*B in memory once open" "$tmp/out"
has "^  regions=[0-9]*" "$tmp/out"
expect 0 "$SL" pvs info "$tmp/r1.slpvs" --json
has '"regions":[1-9]' "$tmp/out"
has '"region_leaves":[1-9]' "$tmp/out"
has '"region_memory_bytes":[1-9]' "$tmp/out"
# pvs query shows the cell's marks: as many marked nodes as the ids listed
expect 0 "$SL" pvs query "$tmp/r1.slpvs" --cell 0 --ids
has "motion regions: [0-9]* of [1-9][0-9]* nodes marked visible, [0-9]* of [1-9][0-9]* regions" "$tmp/out"
expect 0 "$SL" pvs query "$tmp/r1.slpvs" --cell 0 --ids --json
has '"regions_marked":[0-9]' "$tmp/out"
has '"region_leaves_marked":[0-9]' "$tmp/out"
marked=$(sed -n 's/.*"regions_marked":\([0-9]*\).*/\1/p' "$tmp/out")
listed=$(sed -n 's/.*"region_ids":\[\([0-9,]*\)\].*/\1/p' "$tmp/out" | tr ',' '\n' | grep -c .)
[ "$marked" = "$listed" ] || fail "regions_marked $marked but $listed region ids listed"
# a .slpvs given as the scene is named for what it is, not handed to assimp
expect 1 "$SL" pvs query "$tmp/r1.slpvs" --cell 0 --scene "$tmp/r1.slpvs"
has "this is a PVS (.slpvs), not a scene" "$tmp/err"
hasnt "assimp" "$tmp/err"
# a default bake says which method it chose, also with --quiet
expect 0 "$SL" pvs build city:tiny --along "$tmp/drive.txt" --threads 2 --quiet -o "$tmp/d.slpvs"
has "method adjustable (the conservative method" "$tmp/err"
# a path of which some cameras lie far from every cell is warned of before the bake
awk '/^#|^camera/ {print; next} NR % 2 == 0 {$4 = $4 + 60} {print}' "$tmp/drive.txt" > "$tmp/high.txt"
expect 0 "$SL" pvs build city:tiny --along "$tmp/high.txt" --method adjustable --quiet -o "$tmp/h.slpvs"
has "WARNING: [1-9][0-9]* of the 30 cameras of .*high.txt are farther than 2 m from every view cell" "$tmp/err"
expect 0 "$SL" pvs build city:tiny --along "$tmp/drive.txt" --method adjustable --quiet -o "$tmp/h.slpvs"
hasnt "WARNING" "$tmp/err"
expect 0 "$SL" pvs build city:tiny --along "$tmp/drive.txt" --method adjustable --no-regions --quiet -o "$tmp/plain.slpvs"
hasnt "motion regions" "$tmp/out"
expect 0 "$SL" pvs info "$tmp/plain.slpvs"
has ".slpvs 1.1" "$tmp/out"
has "motion regions: none" "$tmp/out"

expect 0 "$SL" bench city:tiny --path "$tmp/drive.txt" --methods "pvs:file=$tmp/r1.slpvs" --quiet
expect 0 "$SL" bench city:tiny --path "$tmp/drive.txt" --methods "pvs:file=$tmp/r1.slpvs:dynamic=regions" --quiet
expect 1 "$SL" bench city:tiny --path "$tmp/drive.txt" --methods "pvs:file=$tmp/plain.slpvs:dynamic=regions" --quiet
has "no motion regions" "$tmp/err"
echo "pvs regions: ok"
