#!/bin/bash
# CLI test of the messages that name the fix (issue 17 §4): an unknown option, command, culling
# method or method option suggests the nearest ones; a .pk3 without --map lists its maps and a
# wrong map name lists the close ones; `--methods NAME:key=value` is the one method grammar of
# bench; city:PRESET[:SEED] is a scene in every command that takes one. $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

# unknown options: "did you mean" after the error, from the command's own --help text
expect 2 "$SL" bench city:tiny --walk 2 --method vfc
has "unknown option --method " "$tmp/err"
has "did you mean --methods or --method-options?" "$tmp/err"
expect 2 "$SL" info city:tiny --jsno
has "did you mean --json?" "$tmp/err"
expect 2 "$SL" path gen city:tiny --frams 3 -o "$tmp/p.txt"
has "did you mean --frames?" "$tmp/err"
expect 2 "$SL" pvs build city:tiny --metod sample -o "$tmp/x.slpvs"
has "did you mean --method?" "$tmp/err"
expect 2 "$SL" render city:tiny --widht 64
has "did you mean --width?" "$tmp/err"
expect 2 "$SL" info city:tiny --zzzzzzzzzz
hasnt "did you mean" "$tmp/err"
# unknown command
expect 2 "$SL" bnech
has "unknown command 'bnech' (did you mean bench?)" "$tmp/err"
# unknown method and method option
expect 2 "$SL" bench city:tiny --walk 2 --methods hbz
has "unknown culling method 'hbz' (did you mean hzb?" "$tmp/err"
expect 2 "$SL" bench city:tiny --walk 2 --methods hzb:rse=any
has "^sightline bench: --methods: hzb: unknown option 'rse' (did you mean res?" "$tmp/err"

# one method grammar: NAME:key=value[:key=value] in --methods, the same as --method-options
expect 0 "$SL" bench city:tiny --walk 3 --methods hzb:res=culling:leaf_size=4,vfc --out "$tmp/b1" --quiet
expect 0 "$SL" bench city:tiny --walk 3 --methods hzb,vfc --method-options hzb:res=culling,leaf_size=4 --out "$tmp/b2" --quiet
# hzb's default (res=any) is conservative; res=culling makes it conservative-at-resolution
has "| hzb | conservative-at-resolution | 3 |" "$tmp/b1/summary.md"
has "| hzb | conservative-at-resolution | 3 |" "$tmp/b2/summary.md"
[ "$(grep '^| hzb' "$tmp/b1/summary.md" | cut -d'|' -f2-10)" = "$(grep '^| hzb' "$tmp/b2/summary.md" | cut -d'|' -f2-10)" ] ||
    fail "--methods hzb:res=culling and --method-options hzb:res=culling differ"
expect 0 "$SL" bench city:tiny --walk 3 --methods hzb --out "$tmp/b3" --quiet
has "| hzb | conservative | 3 |" "$tmp/b3/summary.md"
expect 2 "$SL" bench city:tiny --walk 3 --methods hzb:res=culling --method-options hzb:res=any
has "given twice" "$tmp/err"
expect 2 "$SL" bench city:tiny --walk 3 --methods hzb:
has "no options after the colon" "$tmp/err"

# pvs build --method NAME:key=value is the same as --method NAME --options key=value
expect 0 "$SL" pvs build city:tiny --method adjustable:eps=1:bins=4096 --cell-size 40 --threads 1 -o "$tmp/m1.slpvs" --quiet
expect 0 "$SL" pvs build city:tiny --method adjustable --options eps=1,bins=4096 --cell-size 40 --threads 1 -o "$tmp/m2.slpvs" --quiet
cmp -s "$tmp/m1.slpvs" "$tmp/m2.slpvs" || fail "--method adjustable:eps=1:bins=4096 and --options differ"
expect 2 "$SL" pvs build city:tiny --method adjustable:eps=1 --options bins=4 -o "$tmp/m3.slpvs"
has "not both" "$tmp/err"
expect 2 "$SL" pvs build city:tiny --method adjustable:epz=1 -o "$tmp/m3.slpvs"
has "unknown option 'epz' (did you mean eps?" "$tmp/err"

# city:PRESET[:SEED] wherever a scene is taken
expect 0 "$SL" info city:tiny --json
has '"objects":335' "$tmp/out"
expect 0 "$SL" path gen city:tiny:1 --frames 4 -o "$tmp/walk.txt"
expect 0 "$SL" export city:tiny "$tmp/t.obj"
[ -s "$tmp/t.obj" ] || fail "export city:tiny wrote nothing"
expect 1 "$SL" info city:huge
has "unknown city preset 'huge'" "$tmp/err"

# a missing file says which argument it was
expect 1 "$SL" bench city:tiny --path "$tmp/nope.txt" --methods vfc
has "^sightline bench: --path: $tmp/nope.txt: cannot open" "$tmp/err"
expect 1 "$SL" pvs build city:tiny --along "$tmp/nope.txt" -o "$tmp/x.slpvs" --quiet
has "^sightline pvs build: --along: $tmp/nope.txt: cannot open" "$tmp/err"
expect 1 "$SL" info "$tmp/nope.slscene"
has "^sightline info: scene: $tmp/nope.slscene: cannot open" "$tmp/err"

# a .pk3 without --map lists its maps; a wrong name lists the close ones
PK3=/usr/share/games/openarena/baseoa/pak1-maps.pk3
if [ -f "$PK3" ]; then
    expect 1 "$SL" info "$PK3"
    has "the archive holds [0-9]* maps (aggressor, " "$tmp/err"
    has "and [0-9]* more); name the one to import (sightline: --map NAME" "$tmp/err"
    has "list-maps" "$tmp/err"
    expect 1 "$SL" info "$PK3" --map oasag
    has "entry maps/oasag.bsp not found (did you mean oasago2?)" "$tmp/err"
    expect 1 "$SL" info "$PK3" --map zzzzzzzzzz
    has "no map of that name or close to it" "$tmp/err"
else
    echo "skipping the .pk3 checks: $PK3 is not installed (package openarena-081-maps)"
fi
# pvs build without --method takes the method that suits the scene and says which
expect 0 "$SL" pvs build city:tiny -o "$tmp/d.slpvs" --threads 1 --cell-size 40
has "method adjustable (the conservative method for scenes with building footprints" "$tmp/err"
expect 0 "$SL" pvs build city:tiny -o "$tmp/d2.slpvs" --threads 1 --cell-size 40 --json
has '"method":"adjustable"' "$tmp/out"
hasnt "method adjustable (" "$tmp/err"
# --json: progress as JSON lines on stderr, the last one complete
has '^{"progress":"baking cells","done":[0-9]*,"total":[0-9]*,"elapsed_s":' "$tmp/err"
last=$(grep '^{"progress"' "$tmp/err" | tail -1)
d=$(echo "$last" | sed 's/.*"done":\([0-9]*\).*/\1/'); t=$(echo "$last" | sed 's/.*"total":\([0-9]*\).*/\1/')
[ "$d" = "$t" ] || fail "last progress line $last is not complete"
expect 0 "$SL" pvs build city:tiny -o "$tmp/d3.slpvs" --threads 1 --cell-size 40 --json --quiet
hasnt "progress" "$tmp/err"
expect 2 "$SL" pvs build "$tmp/t.obj" -o "$tmp/e.slpvs" --cells grid
has "no conservative from-region method applies to this scene" "$tmp/err"
has "method gvs" "$tmp/err"
[ ! -e "$tmp/e.slpvs" ] || fail "a refused bake left a file"
if [ -f "$PK3" ]; then
    expect 3 "$SL" pvs build "$PK3" --map q3dm6ish -o "$tmp/q.slpvs" --threads 1 --stop-after 1
    has "method portal (the conservative method for Quake III cluster cells" "$tmp/err"
fi
echo "suggest: ok"
