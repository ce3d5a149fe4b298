#!/bin/bash
# CLI test of the motion regions in a bake (docs/motion.md): the tiny city's cars have motion
# records, so `pvs build` (along a short drive) stores a region hierarchy, .slpvs 1.2, says so in
# its summary and --json, and `pvs info` shows it; --no-regions writes 1.1 without them; the same
# bake on 1 and 2 threads gives the same bytes; `bench` with the pvs culler runs with the default
# dynamic=auto and with dynamic=regions, and refuses dynamic=regions on the file without regions.
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
has "motion regions: [0-9]* nodes, [0-9.]* marked per cell" "$tmp/out"
has "^  regions=[0-9]*" "$tmp/out"
expect 0 "$SL" pvs info "$tmp/r1.slpvs" --json
has '"regions":[1-9]' "$tmp/out"
expect 0 "$SL" pvs build city:tiny --along "$tmp/drive.txt" --method adjustable --no-regions --quiet -o "$tmp/plain.slpvs"
hasnt "motion regions" "$tmp/out"
expect 0 "$SL" pvs info "$tmp/plain.slpvs"
has ".slpvs 1.1" "$tmp/out"
hasnt "motion regions" "$tmp/out"

expect 0 "$SL" bench city:tiny --path "$tmp/drive.txt" --methods "pvs:file=$tmp/r1.slpvs" --quiet
expect 0 "$SL" bench city:tiny --path "$tmp/drive.txt" --methods "pvs:file=$tmp/r1.slpvs:dynamic=regions" --quiet
expect 1 "$SL" bench city:tiny --path "$tmp/drive.txt" --methods "pvs:file=$tmp/plain.slpvs:dynamic=regions" --quiet
has "no motion regions" "$tmp/err"
echo "pvs regions: ok"
