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
fi
# a scene without materials says nothing about them
expect 0 "$SL" info "$(dirname "$0")/../data/scene_v1_0.slscene"
hasnt "materials" "$tmp/out"
echo "PASS"
