#!/bin/bash
# CLI test of "not applicable": a method that cannot cull more than the frustum on a scene (the 2.5D
# methods without footprints, the occlusion methods without occluders) is named with the reason by
# `sightline methods --scene` (text and JSON) and left out of `bench` with that reason, never run as
# vfc. A model imported with its synthesised occluders keeps the occlusion methods. $1 is the
# sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"
OBJ=/usr/share/assimp/models/OBJ
[ -e "$OBJ/box.obj" ] && [ -e "$OBJ/spider.obj" ] || { echo "SKIP: assimp-testmodels is not installed"; exit 77; }

expect 0 "$SL" import "$OBJ/spider.obj" --no-occluders -o "$tmp/bare.slscene" --quiet
expect 0 "$SL" import "$OBJ/box.obj" -o "$tmp/box.slscene" --quiet

# methods --scene: an "applies" column and the reasons below the table
expect 0 "$SL" methods --scene "$tmp/bare.slscene"
has "applies" "$tmp/out"
grep -Eq '^hzb +conservative.* not applicable ' "$tmp/out" || fail "hzb is not said not applicable to a scene without occluders"
grep -Eq '^cullmap +conservative +not applicable ' "$tmp/out" || fail "cullmap is not said not applicable"
grep -Eq '^vfc +conservative +yes ' "$tmp/out" || fail "vfc does not apply"
grep -Eq '^chc +conservative-at-resolution +yes ' "$tmp/out" || fail "chc (draws its own depth) does not apply"
grep -Eq '^pvs +conservative +needs options ' "$tmp/out" || fail "pvs without a file is not 'needs options'"
has "  hzb: not applicable: the scene has no occluders" "$tmp/out"
has "sightline occluders" "$tmp/out"
has "  cullmap: not applicable: the scene has no building footprints" "$tmp/out"
expect 0 "$SL" methods --scene "$tmp/bare.slscene" --json
has '"name":"hzb","guarantee":"conservative",' "$tmp/out"
has '"applies":"not_applicable","why":"the scene has no occluders' "$tmp/out"
has '"applies":"needs_options","why":"pvs: option file=PATH is required' "$tmp/out"
expect 0 "$SL" methods lazygrid --scene "$tmp/bare.slscene"
has "  on bare: not applicable: the scene has no occluders" "$tmp/out"
# the synthesised occluders of a default import make the occlusion methods apply; the 2.5D ones still not
expect 0 "$SL" methods --scene "$tmp/box.slscene"
grep -Eq '^hzb +conservative.* yes ' "$tmp/out" || fail "hzb does not apply to a model with synthesised occluders"
grep -Eq '^dhorizon +conservative +not applicable ' "$tmp/out" || fail "dhorizon applies without footprints"
# a generated city: everything applies
expect 0 "$SL" methods --scene city:tiny
hasnt "not applicable" "$tmp/out"
expect 2 "$SL" methods --map x
has "--map needs --scene" "$tmp/err"
expect 1 "$SL" methods --scene "$tmp/missing.slscene"

# bench: the methods that do not apply are not run, with the reason; those named that apply run
expect 0 "$SL" bench "$tmp/bare.slscene" --random flyover --count 3 --allow-empty --no-plots --out "$tmp/b"
has "not running hzb on bare: not applicable: the scene has no occluders" "$tmp/err"
has "not run: cullmap (bare: not applicable: the scene has no building footprints" "$tmp/out"
grep -q '^| vfc |' "$tmp/out" || fail "vfc did not run"
grep -Eq '^\| (hzb|lazygrid|cullmap|horizon|hom|frusta) \|' "$tmp/b/summary.md" && fail "a method that does not apply ran"
expect 0 "$SL" bench "$tmp/bare.slscene" --random flyover --count 3 --allow-empty --no-plots --methods vfc,hzb:all_objects=true --out "$tmp/c" --json
has '"name":"hzb"' "$tmp/out"
hasnt 'not applicable' "$tmp/out"
expect 2 "$SL" bench "$tmp/bare.slscene" --random flyover --count 3 --allow-empty --no-plots --methods cullmap,horizon --out "$tmp/d"
has "no method to run on bare: every one named is not applicable to it" "$tmp/err"
[ ! -e "$tmp/d" ] || fail "a bench with nothing to run left an output folder"
echo "PASS"
