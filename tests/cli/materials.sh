#!/bin/bash
# CLI test of materials (issue 15 §1, docs/import-export.md "Materials"): `sightline import` of
# tests/data/material/materials.gltf (its buffer copied from assimp-testmodels) reports the
# materials, see-through objects and meshes with UVs, warns on stderr about the texture that leaves
# the model's folder and the embedded one, and `sightline info` of the .slscene shows the same
# counts. Skips when assimp's test models are not installed. $1 is the sightline binary.
set -u
SL="$(cd "$(dirname "$1")" && pwd)/$(basename "$1")"
. "$(dirname "$0")/lib/common.sh"
bin=/usr/share/assimp/models/glTF2/BoxTextured-glTF/BoxTextured0.bin
if [ ! -f "$bin" ]; then
    echo "SKIP: $bin not installed (Debian package assimp-testmodels)"
    exit 0
fi
data="$(dirname "$0")/../data/material"
mkdir -p "$tmp/model/tex"
cp "$data/materials.gltf" "$bin" "$tmp/model/" || fail "copy"

expect 0 "$SL" import "$tmp/model/materials.gltf" -o "$tmp/model/m.slscene"
has "materials *4 (2 see-through objects, 4 meshes with UVs)" "$tmp/out"
has "warning: textures not kept: 1 outside the model's folder or invalid, 1 embedded" "$tmp/err"
has "\.\./outside.png" "$tmp/err"
expect 0 "$SL" import "$tmp/model/materials.gltf" -o "$tmp/model/m.slscene" --json
has '"materials":4' "$tmp/out"
has '"see_through_objects":2' "$tmp/out"
expect 0 "$SL" info "$tmp/model/m.slscene"
has "materials *4 (2 see-through objects, 4 meshes with UVs)" "$tmp/out"
expect 0 "$SL" info "$tmp/model/m.slscene" --json
has '"meshes_with_uvs":4' "$tmp/out"
# the node names come through, listed with the ids (text and JSON), kept by the .slscene
HOUSE=/usr/share/assimp/models/IFC/AC14-FZK-Haus.ifc
if [ -f "$HOUSE" ]; then
    expect 0 "$SL" import "$HOUSE" -o "$tmp/haus.slscene" --quiet
    expect 0 "$SL" info "$tmp/haus.slscene" --objects
    has "^id  *kind  *triangles  *flags  *bounds (m)  *name" "$tmp/out"
    has "^1  *imported .*IfcWallStandardCase_Wand-Ext-ERDG-1" "$tmp/out"
    [ "$(grep -c '^[0-9]' "$tmp/out")" -eq "$("$SL" info "$tmp/haus.slscene" --json | sed 's/.*"objects":\([0-9]*\).*/\1/')" ] ||
        fail "info --objects does not list every object"
    expect 0 "$SL" info "$tmp/haus.slscene" --objects --json
    has '"objects":\[{"id":0,"name":"IfcSite_' "$tmp/out"
    expect 0 "$SL" info "$HOUSE" --objects --json
    cp "$tmp/out" "$tmp/direct.json"
    expect 0 "$SL" info "$tmp/haus.slscene" --objects --json
    diff <(sed 's/"file":"[^"]*"//' "$tmp/direct.json") <(sed 's/"file":"[^"]*"//' "$tmp/out") >/dev/null ||
        fail "the saved scene lists other objects than the model itself (ids not stable)"
    # every frame's sets with the names (bench --sets csv|json)
    expect 0 "$SL" bench "$tmp/haus.slscene" --random flyover --count 3 --methods vfc,hzb --sets csv --no-plots \
        --quiet --out "$tmp/bs"
    head -1 "$tmp/bs/sets.csv" | grep -qx 'scene,frame,source,by,object,name' || fail "sets.csv header"
    has '^haus,0,0,oracle,[0-9]*,"Ifc' "$tmp/bs/sets.csv"
    has '^haus,[0-9],[0-9],hzb,[0-9]*,"' "$tmp/bs/sets.csv"
    # conservative: every object of a frame's oracle rows is in the same frame's hzb rows
    awk -F, 'NR > 1 { k = $2 "," $5; if ($4 == "oracle") o[k] = 1; if ($4 == "hzb") h[k] = 1 }
             END { for (k in o) if (!(k in h)) { print "missing " k; bad = 1 } exit bad }' "$tmp/bs/sets.csv" ||
        fail "sets.csv: hzb misses an object of the oracle's set"
    expect 0 "$SL" bench "$tmp/haus.slscene" --random flyover --count 2 --methods vfc --sets json --no-plots --quiet \
        --out "$tmp/bj"
    has '^{"scene":"haus","frame":0,"source":0,"by":"oracle","objects":\[{"id":[0-9]*,"name":"Ifc' "$tmp/bj/sets.json"
    tail -1 "$tmp/bj/sets.json" | grep -qx ']}' || fail "sets.json is not closed"
    expect 2 "$SL" bench "$tmp/haus.slscene" --random flyover --count 2 --sets xml
    has "expected csv or json" "$tmp/err"
fi
# a scene without materials says nothing about them
expect 0 "$SL" info "$(dirname "$0")/../data/scene_v1_0.slscene"
hasnt "materials" "$tmp/out"
echo "PASS"
