#!/bin/bash
# CLI test of Instant Visibility (docs/instant.md): `sightline occluders --instant-levels` bakes
# shrunk occluder levels into a scene (text and --json), the file is version 1.3 with them (a
# generated city's cars carry motion records, docs/motion.md) and a city without levels or cars is
# 1.1; `sightline bench` runs the `instant` culler on it with zero
# misses (stall and thread=false), reports continue as aggressive, and bad options are usage errors.
# $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

expect 0 "$SL" occluders --help
has "instant-levels" "$tmp/out"
expect 0 "$SL" occluders city:tiny --instant-levels 1.5,0.5 -o "$tmp/iv.slscene"
has "level eps 0.5 " "$tmp/out"
has "level eps 1.5 " "$tmp/out"
[ "$(od -An -tu1 -j12 -N1 "$tmp/iv.slscene" | tr -d " ")" = 3 ] || fail "a generated city with levels is not version 1.3 (levels and the cars' motion records)"
expect 0 "$SL" occluders city:tiny --instant-levels 1 --instant-vertical 0.2 --merge --json -o "$tmp/iv2.slscene"
has '"eps_z":0.2' "$tmp/out"
has '"merge":true' "$tmp/out"
expect 0 "$SL" gen city --preset tiny --cars 0 -o "$tmp/plain.slscene"
[ "$(od -An -tu1 -j12 -N1 "$tmp/plain.slscene" | tr -d ' ')" = 1 ] || fail "a scene without levels or cars is not version 1.1"
expect 0 "$SL" gen city --preset tiny -o "$tmp/cars.slscene"
[ "$(od -An -tu1 -j12 -N1 "$tmp/cars.slscene" | tr -d ' ')" = 3 ] || fail "a city with cars (motion records) is not version 1.3"
# usage errors
expect 2 "$SL" occluders city:tiny --instant-levels 0.5,x -o "$tmp/x.slscene"
has "instant-levels" "$tmp/err"
expect 2 "$SL" occluders city:tiny --instant-levels 1 --instant-vertical -1 -o "$tmp/x.slscene"
expect 1 "$SL" occluders city:tiny --instant-levels 1,1 -o "$tmp/x.slscene"
has "given twice" "$tmp/err"
[ ! -e "$tmp/x.slscene" ] || fail "a failed bake left an output"
# the culler
expect 0 "$SL" methods instant
has "late=stall|continue" "$tmp/out"
expect 0 "$SL" bench "$tmp/iv.slscene" --walk 20 --width 160 --height 120 --methods vfc,instant:thread=false:eps=1 \
    --json --out "$tmp/b"
has '"name":"instant"' "$tmp/out"
grep -o '"missed_objects":[0-9]*' "$tmp/out" | grep -vq '"missed_objects":0$' && fail "a conservative method missed objects"
expect 0 "$SL" bench "$tmp/iv.slscene" --walk 10 --width 160 --height 120 --methods instant:late=continue --json --out "$tmp/c"
has '"guarantee":"aggressive"' "$tmp/out"
expect 2 "$SL" bench "$tmp/iv.slscene" --walk 10 --methods instant:base=hzb --out "$tmp/d"
has "base" "$tmp/err"
expect 1 "$SL" bench "$tmp/iv.slscene" --walk 10 --methods instant:eps=9 --out "$tmp/e"
has "no stored occluder level" "$tmp/err"
echo "ok"
