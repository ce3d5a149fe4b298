#!/bin/bash
# CLI test of `sightline pvs query` on a Quake III PVS (openarena's pak1-maps.pk3, skipped when it
# is not installed): a mappvs bake of q3dm6ish (bsp cluster cells) is queried
#  - by --point without --scene: refused (exit 2), asking for --scene, since only the map's BSP
#    tree can tell which cluster holds a point (it used to say "no view cell holds ...");
#  - by --point with --scene: the cell is found; a point in the map's void says it lies outside
#    the domain;
#  - with --scene naming another map: refused (exit 1) against the file's scene key;
#  - by --cell beyond the last cell, 4294967295 included: refused (exit 1) naming the valid range
#    (4294967295 used to answer for a point (0,0,0)).
# $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

PK3=/usr/share/games/openarena/baseoa/pak1-maps.pk3
if [ ! -r "$PK3" ]; then
    echo "$PK3 not installed: skipped"
    exit 0
fi

expect 0 "$SL" pvs query --help
has "--scene SCENE" "$tmp/out"
has "required with --point for Quake III cluster cells" "$tmp/out"

expect 0 "$SL" pvs build "$PK3" --map q3dm6ish --method mappvs --threads 1 -o "$tmp/q.slpvs"
cells=$("$SL" pvs info "$tmp/q.slpvs" --json | grep -o '"cells":[0-9]*' | head -1 | cut -d: -f2)
[ -n "$cells" ] && [ "$cells" -gt 10 ] || fail "pvs info: no cell count ($cells)"

# a point in cluster cell 3 of q3dm6ish (its box is 9..18, 13..16, 7..8)
P=13.5,14.5,7.5
expect 2 "$SL" pvs query "$tmp/q.slpvs" --point "$P"
has "holds Quake III cluster cells" "$tmp/err"
has "needs the map's BSP tree" "$tmp/err"
has "--scene" "$tmp/err"
hasnt "no view cell holds" "$tmp/out"
expect 0 "$SL" pvs query "$tmp/q.slpvs" --point "$P" --scene "$PK3" --map q3dm6ish
has "^cell 3 (cluster" "$tmp/out"
expect 0 "$SL" pvs query "$tmp/q.slpvs" --point "$P" --scene "$PK3" --map q3dm6ish --json
has '"cell":3' "$tmp/out"
# a point in no cell: the nearest cell and its distance, a non-zero exit (also --json)
expect 1 "$SL" pvs query "$tmp/q.slpvs" --point 0,0,-1000 --scene "$PK3" --map q3dm6ish
has "no view cell holds (0, 0, -1000)" "$tmp/err"
has "outside the domain" "$tmp/err"
has "the nearest is cell [0-9]*, [0-9.]* m away" "$tmp/err"
expect 1 "$SL" pvs query "$tmp/q.slpvs" --point 0,0,-1000 --scene "$PK3" --map q3dm6ish --json
has '"cell":null,"nearest_cell":[0-9]*,"nearest_distance":' "$tmp/out"
# --cell needs no scene
expect 0 "$SL" pvs query "$tmp/q.slpvs" --cell 3
has "^cell 3 (cluster" "$tmp/out"

# another map is not the scene the file was baked for
expect 1 "$SL" pvs query "$tmp/q.slpvs" --cell 3 --scene "$PK3" --map oa_ctf2
has "was not baked for the scene" "$tmp/err"
has "oa_ctf2" "$tmp/err"
hasnt "^cell 3" "$tmp/out"
expect 1 "$SL" pvs query "$tmp/q.slpvs" --point "$P" --scene "$PK3" --map oa_ctf2
has "was not baked for the scene" "$tmp/err"

# cell numbers beyond the last one
last=$((cells - 1))
for c in "$cells" 4294967295; do
    expect 1 "$SL" pvs query "$tmp/q.slpvs" --cell "$c"
    has "cell $c is out of range" "$tmp/err"
    has "numbered 0..$last" "$tmp/err"
    hasnt "no view cell holds" "$tmp/out"
    expect 1 "$SL" pvs query "$tmp/q.slpvs" --cell "$c" --json
    hasnt '"cell"' "$tmp/out"
done
expect 0 "$SL" pvs query "$tmp/q.slpvs" --cell "$last" --json
has "\"cell\":$last" "$tmp/out"
# street cells: a point 100 m beside the city names the nearest cell; its distance is exact
expect 0 "$SL" pvs build city:tiny -o "$tmp/t.slpvs" --method adjustable --cell-size 40 --threads 1 --quiet
expect 1 "$SL" pvs query "$tmp/t.slpvs" --point 0,0,500 --json
has '"nearest_cell":' "$tmp/out"
d=$(sed -n 's/.*"nearest_distance":\([0-9.e+]*\).*/\1/p' "$tmp/out")
awk -v d="$d" 'BEGIN { exit !(d > 490 && d < 500) }' || fail "nearest distance $d for a point 500 m up (cells reach about 2 m)"
echo "ok"
