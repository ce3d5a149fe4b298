#!/bin/bash
# CLI test of occluder synthesis (docs/occluder-synthesis.md): `sightline import` synthesises boxes
# inside closed meshes by default (--no-occluders turns it off), `sightline occluders` does it for
# an existing scene (text and --json statistics), a second run adds nothing, bad options are usage
# errors. $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

# a closed cube (8 m) and an open quad (a wall without thickness) as OBJ
cat >"$tmp/m.obj" <<'OBJ'
o cube
v 0 0 0
v 8 0 0
v 0 8 0
v 8 8 0
v 0 0 8
v 8 0 8
v 0 8 8
v 8 8 8
f 1 3 4 2
f 5 6 8 7
f 1 2 6 5
f 3 7 8 4
f 1 5 7 3
f 2 4 8 6
o wall
v 20 0 0
v 30 0 0
v 30 0 5
v 20 0 5
f 9 10 11 12
OBJ
expect 0 "$SL" import "$tmp/m.obj" --up z -o "$tmp/a.slscene" --json
has '"boxes":1' "$tmp/out"
has '"closed":1' "$tmp/out"
has '"open":1' "$tmp/out"
expect 0 "$SL" import "$tmp/m.obj" --up z -o "$tmp/b.slscene"
has "occluders *1 boxes in 1 meshes for 1 of 1 closed objects (1 open" "$tmp/out"
expect 0 "$SL" import "$tmp/m.obj" --up z -o "$tmp/c.slscene" --no-occluders
has "none synthesised" "$tmp/out"
expect 0 "$SL" info "$tmp/c.slscene" --json
has '"occluder_meshes":0' "$tmp/out"
# the same boxes from `occluders` on the scene imported without them (byte for byte)
expect 0 "$SL" occluders "$tmp/c.slscene" -o "$tmp/d.slscene" --json
has '"occluders_after":1' "$tmp/out"
has '"volume_fraction"' "$tmp/out"
cmp -s "$tmp/a.slscene" "$tmp/d.slscene" || fail "import and occluders made different scenes"
# a second run adds nothing (the cube has its own occluder now)
expect 0 "$SL" occluders "$tmp/d.slscene" -o "$tmp/e.slscene"
has "occluder meshes 1 before, 1 after" "$tmp/out"
# options
expect 0 "$SL" occluders "$tmp/c.slscene" -o "$tmp/f.slscene" --voxel 0.5 --per-object 4 --no-expand --json
has '"boxes":1' "$tmp/out"
expect 2 "$SL" occluders "$tmp/c.slscene" -o "$tmp/g.slscene" --voxel -1
has "must be positive" "$tmp/err"
expect 2 "$SL" occluders "$tmp/c.slscene"
has "missing -o" "$tmp/err"
expect 2 "$SL" occluders "$tmp/c.slscene" -o "$tmp/c.slscene"
expect 0 "$SL" occluders --help
has "strictly inside" "$tmp/out"
echo "PASS"
