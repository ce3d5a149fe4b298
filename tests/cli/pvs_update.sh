#!/bin/bash
# CLI test of `sightline pvs update` (docs/pvs.md, "Updating a bake") and `sightline gen edit`:
#  - the tiny city baked with adjustable on coarse cells (--cell-size 40, for time); a seeded edit
#    of the buildings of one 100 m square (gen edit: the same seed gives the same file);
#  - the update (to -o and in place) is byte-identical to a full bake of the edited scene, and says
#    how many cells it re-baked;
#  - refused with exit 1 and nothing written: a file of another scene (--old-scene not the one it
#    was baked for), an edit that changes the view cells (buildings moved over the streets), other
#    cell options than the bake's; usage errors (exit 2): a missing --scene or --old-scene.
# $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

expect 0 "$SL" pvs update --help
has "usage: sightline pvs update FILE.slpvs --old-scene OLD --scene EDITED" "$tmp/out"
has "byte-identical" "$tmp/out"
expect 0 "$SL" pvs --help
has "update FILE.slpvs --old-scene OLD --scene EDITED" "$tmp/out"
expect 0 "$SL" gen edit --help
has "region X0,Y0,X1,Y1" "$tmp/out"

expect 0 "$SL" gen city --preset tiny -o "$tmp/city.slscene" --quiet
expect 0 "$SL" pvs build "$tmp/city.slscene" --method adjustable --cell-size 40 --threads 2 --quiet -o "$tmp/old.slpvs"
expect 0 "$SL" gen edit "$tmp/city.slscene" --region -60,-60,40,40 --seed 5 -o "$tmp/edited.slscene"
has "buildings removed" "$tmp/out"
expect 0 "$SL" gen edit "$tmp/city.slscene" --region -60,-60,40,40 --seed 5 -o "$tmp/edited2.slscene" --json
has '"removed":' "$tmp/out"
cmp -s "$tmp/edited.slscene" "$tmp/edited2.slscene" || fail "gen edit: the same seed gave another file"

expect 0 "$SL" pvs update "$tmp/old.slpvs" --old-scene "$tmp/city.slscene" --scene "$tmp/edited.slscene" \
    --cell-size 40 --threads 2 --quiet -o "$tmp/updated.slpvs"
has "cells re-baked" "$tmp/out"
has "method adjustable" "$tmp/out"
expect 0 "$SL" pvs build "$tmp/edited.slscene" --method adjustable --cell-size 40 --threads 2 --quiet -o "$tmp/full.slpvs"
cmp -s "$tmp/updated.slpvs" "$tmp/full.slpvs" || fail "the update differs from the full bake"
[ ! -e "$tmp/updated.slpvs.ckpt" ] || fail "the update left its checkpoint"

# a partial bake (--along) is updated with the same --along and --radius, byte for byte the partial
# bake of the edited scene; without them the cells are the whole city's, not the file's
expect 0 "$SL" path gen "$tmp/city.slscene" --kind walk --frames 90 --fps 10 --seed 4 -o "$tmp/walk.txt"
expect 0 "$SL" pvs build "$tmp/city.slscene" --along "$tmp/walk.txt" --radius 3 --method adjustable --cell-size 40 \
    --quiet -o "$tmp/old_along.slpvs"
expect 0 "$SL" pvs update "$tmp/old_along.slpvs" --old-scene "$tmp/city.slscene" --scene "$tmp/edited.slscene" \
    --along "$tmp/walk.txt" --radius 3 --cell-size 40 --quiet --json -o "$tmp/upd_along.slpvs"
has '"cells_affected":[1-9]' "$tmp/out"
expect 0 "$SL" pvs build "$tmp/edited.slscene" --along "$tmp/walk.txt" --radius 3 --method adjustable --cell-size 40 \
    --quiet -o "$tmp/full_along.slpvs"
cmp -s "$tmp/upd_along.slpvs" "$tmp/full_along.slpvs" || fail "the update of a partial bake differs from its bake"
expect 1 "$SL" pvs update "$tmp/old_along.slpvs" --old-scene "$tmp/city.slscene" --scene "$tmp/edited.slscene" \
    --cell-size 40 --quiet -o "$tmp/bad.slpvs"
has "view cells differ" "$tmp/err"
has "the same --along and --radius" "$tmp/err"
[ ! -e "$tmp/bad.slpvs" ] || fail "a refused update wrote its output"
expect 2 "$SL" pvs update "$tmp/old_along.slpvs" --old-scene "$tmp/city.slscene" --scene "$tmp/edited.slscene" \
    --radius 3 -o "$tmp/bad.slpvs"
has "needs --along" "$tmp/err"
expect 2 "$SL" pvs update "$tmp/old_along.slpvs" --old-scene "$tmp/city.slscene" --scene "$tmp/edited.slscene" \
    --along "$tmp/walk.txt" -o "$tmp/walk.txt"
has "input" "$tmp/err"

# in place, with --json
cp "$tmp/old.slpvs" "$tmp/inplace.slpvs"
expect 0 "$SL" pvs update "$tmp/inplace.slpvs" --old-scene "$tmp/city.slscene" --scene "$tmp/edited.slscene" \
    --cell-size 40 --threads 1 --json
has '"cells_affected":' "$tmp/out"
has '"cpu_seconds":' "$tmp/out"
cmp -s "$tmp/inplace.slpvs" "$tmp/full.slpvs" || fail "the update in place differs from the full bake"

# a file of another scene: the edited scene given as the old one
expect 1 "$SL" pvs update "$tmp/old.slpvs" --old-scene "$tmp/edited.slscene" --scene "$tmp/edited.slscene" \
    --cell-size 40 -o "$tmp/bad.slpvs"
has "not the one the file was baked for" "$tmp/err"
# the advice is to give the right old scene, not to re-bake over the (good) file; the command's
# name is not said twice
has "give as the old scene the scene the file was baked for" "$tmp/err"
hasnt "bake it again" "$tmp/err"
hasnt "pvs update: pvs update" "$tmp/err"
[ ! -e "$tmp/bad.slpvs" ] || fail "a refused update wrote its output"
# buildings moved over the streets: the view cells change
expect 0 "$SL" gen edit "$tmp/city.slscene" --region -1000,-1000,1000,1000 --remove 0 --add 0 --move 1 --shift 30 \
    --seed 2 -o "$tmp/streets.slscene"
expect 1 "$SL" pvs update "$tmp/old.slpvs" --old-scene "$tmp/city.slscene" --scene "$tmp/streets.slscene" \
    --cell-size 40 -o "$tmp/bad.slpvs"
has "view cells differ" "$tmp/err"
has "pvs build" "$tmp/err"
has "^sightline pvs update: the edited scene's view cells" "$tmp/err"
[ ! -e "$tmp/bad.slpvs" ] || fail "a refused update wrote its output"
# other cell options than the bake's
expect 1 "$SL" pvs update "$tmp/old.slpvs" --old-scene "$tmp/city.slscene" --scene "$tmp/edited.slscene" \
    -o "$tmp/bad.slpvs"
has "view cells differ" "$tmp/err"
# usage errors
expect 2 "$SL" pvs update "$tmp/old.slpvs" --old-scene "$tmp/city.slscene"
has "missing --scene" "$tmp/err"
expect 2 "$SL" pvs update "$tmp/old.slpvs" --scene "$tmp/edited.slscene"
has "missing --old-scene" "$tmp/err"
echo "pvs update: ok"
