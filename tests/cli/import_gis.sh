#!/bin/bash
# CLI test of the GIS import (docs/gis-import.md): `sightline import` of a GeoJSON city of 4 x 4
# blocks and of an OpenStreetMap XML snippet, both written here; the imported city is a normal
# scene: info, a walk, `pvs build --method adjustable`, `bench` with every method against the
# oracle (no conservative method misses an object), `demo --scene` straight from the GeoJSON; the
# same file gives the same .slscene; bad input fails with a message naming the file, or a counted
# warning, and leaves no output. $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

# ---- help and usage errors ----
expect 0 "$SL" import --help
has "GIS options:" "$tmp/out"
has "--crs SRS" "$tmp/out"
has "docs/gis-import.md" "$tmp/out"
echo "o 0 0 0" >"$tmp/box.obj"
expect 2 "$SL" import "$tmp/box.obj" --metric -o "$tmp/x.slscene"
has "apply to GIS files only" "$tmp/err"
echo "{}" >"$tmp/u.geojson"
expect 2 "$SL" import "$tmp/u.geojson" --up z -o "$tmp/x.slscene"
has "do not apply to GIS files" "$tmp/err"

# ---- a city of 4 x 4 blocks: 4 buildings each (every fourth without a height), streets ----
awk -v B=4 'function lon(x) { return 16.37 + x / 74260.0 } function lat(y) { return 48.21 + y / 111200.0 }
BEGIN {
    P = 72; S = 26; n = 0
    printf "{\"type\":\"FeatureCollection\",\"features\":[\n"
    for (j = 0; j < B; j++) for (i = 0; i < B; i++) for (b = 0; b < 4; b++) {
        x = i * P + 8 + (b % 2) * (S + 4); y = j * P + 8 + int(b / 2) * (S + 4)
        k = (i + j + b) % 4
        if (k == 0) props = "\"building\":\"yes\""
        else if (k == 1) props = sprintf("\"building\":\"yes\",\"building:levels\":%d", 2 + (i + b) % 5)
        else props = sprintf("\"building\":\"yes\",\"height\":%d", 9 + 4 * ((i * 7 + j * 3 + b) % 6))
        printf "{\"type\":\"Feature\",\"properties\":{%s},\"geometry\":{\"type\":\"Polygon\",\"coordinates\":[[", props
        printf "[%.9f,%.9f],[%.9f,%.9f],[%.9f,%.9f],[%.9f,%.9f],[%.9f,%.9f]", lon(x), lat(y), lon(x + S), lat(y), lon(x + S), lat(y + S), lon(x), lat(y + S), lon(x), lat(y)
        printf "]]}},\n"
    }
    for (d = 0; d < 2; d++) for (k = 0; k <= B; k++) {
        printf "{\"type\":\"Feature\",\"properties\":{\"highway\":\"residential\"},\"geometry\":{\"type\":\"LineString\",\"coordinates\":["
        for (m = 0; m <= B; m++) { x = d ? m * P : k * P; y = d ? k * P : m * P; printf "%s[%.9f,%.9f]", m ? "," : "", lon(x), lat(y) }
        printf "]}}%s\n", (d == 1 && k == B) ? "" : ","
    }
    printf "]}\n"
}' >"$tmp/city.geojson"

expect 0 "$SL" import "$tmp/city.geojson" -o "$tmp/city.slscene"
has "format         GeoJSON" "$tmp/out"
has "buildings      64 " "$tmp/out"
has "WGS 84 -> tmerc" "$tmp/out"
has "streets        10 (40 segments, 25 graph nodes)" "$tmp/out"
has "warning: 16 GIS problems: 16 default heights" "$tmp/err"
has "no height or levels: 10 m used" "$tmp/err"
expect 0 "$SL" import "$tmp/city.geojson" -o "$tmp/city2.slscene" --json --default-height 15 --level-height 3.5
has '"importer":"gis"' "$tmp/out"
has '"buildings":64' "$tmp/out"
has '"default_height":16' "$tmp/out"
# the same input and options: the same bytes
expect 0 "$SL" import "$tmp/city.geojson" -o "$tmp/city3.slscene" --quiet
cmp -s "$tmp/city.slscene" "$tmp/city3.slscene" || fail "two imports of the same file differ"
cmp -s "$tmp/city.slscene" "$tmp/city2.slscene" && fail "--default-height changed nothing"

expect 0 "$SL" info "$tmp/city.slscene"
has "footprint" "$tmp/out"

# ---- the imported city is a scene like a generated one ----
expect 0 "$SL" path gen "$tmp/city.slscene" --kind walk --frames 120 -o "$tmp/walk.txt"
expect 0 "$SL" pvs build "$tmp/city.slscene" --method adjustable -o "$tmp/city.slpvs" --quiet
[ -s "$tmp/city.slpvs" ] || fail "no .slpvs"
expect 0 "$SL" bench "$tmp/city.slscene" --path "$tmp/walk.txt" --frames 0:60 --out "$tmp/bench" --quiet
has '"violations":0' "$tmp/bench/summary.json"
for m in vfc cullmap horizon dhorizon hzb lazygrid busygrid pvs; do
    grep -q "\"name\":\"$m\"" "$tmp/bench/summary.json" || fail "bench did not run $m"
done
# the conservative methods miss nothing (the oracle judges every frame)
if grep -o '"guarantee":"conservative"[^}]*"missed_objects":[1-9]' "$tmp/bench/summary.json" | head -1 | grep -q .; then
    fail "a conservative method missed objects on the imported city"
fi
# occlusion culls something on it: hzb keeps fewer objects than the frustum
vfc=$(grep -o '"name":"vfc"[^}]*"objects_drawn_mean":[0-9.]*' "$tmp/bench/summary.json" | head -1 | sed 's/.*://')
hzb=$(grep -o '"name":"hzb"[^}]*"objects_drawn_mean":[0-9.]*' "$tmp/bench/summary.json" | head -1 | sed 's/.*://')
awk -v a="$hzb" -v b="$vfc" 'BEGIN { exit !(a < b) }' || fail "hzb keeps $hzb objects, vfc $vfc: no occlusion on the imported city"
# the demo straight from the GIS file (sl_scene_open takes it by its extension)
expect 0 "$SL" demo --scene "$tmp/city.geojson" --quick --frames 20 --out "$tmp/demo" --quiet
[ -s "$tmp/demo/report.html" ] || fail "no demo report"
has "the scene city" "$tmp/demo/report.md"

# ---- OpenStreetMap XML ----
cat >"$tmp/block.osm" <<'EOF'
<?xml version='1.0' encoding='UTF-8'?>
<osm version='0.6' generator='import_gis.sh'>
  <node id='1' lat='48.2100' lon='16.3700'/> <node id='2' lat='48.2100' lon='16.3704'/>
  <node id='3' lat='48.2103' lon='16.3704'/> <node id='4' lat='48.2103' lon='16.3700'/>
  <node id='10' lat='48.2098' lon='16.3695'/> <node id='11' lat='48.2098' lon='16.3707'/>
  <node id='13' lat='48.2106' lon='16.3707'/>
  <way id='100'><nd ref='1'/><nd ref='2'/><nd ref='3'/><nd ref='4'/><nd ref='1'/>
    <tag k='building' v='yes'/><tag k='building:levels' v='6'/></way>
  <way id='102'><nd ref='10'/><nd ref='11'/><nd ref='13'/><tag k='highway' v='residential'/></way>
</osm>
EOF
expect 0 "$SL" import "$tmp/block.osm" -o "$tmp/block.slscene" --json
has '"format":"OSM"' "$tmp/out"
has '"buildings":1' "$tmp/out"
has '"streets":1' "$tmp/out"
grep -q '"bounds_max":\[[^]]*,18\]' "$tmp/out" || fail "6 levels are not 18 m"

# ---- bad input: a clear error naming the file, no output ----
printf 'not json\n' >"$tmp/bad.geojson"
expect 1 "$SL" import "$tmp/bad.geojson" -o "$tmp/bad.slscene"
has "bad.geojson: GDAL's GeoJSON driver cannot read it" "$tmp/err"
[ -e "$tmp/bad.slscene" ] && fail "a failed import left its output"
printf '{"type":"FeatureCollection","features":[]}\n' >"$tmp/empty.geojson"
expect 1 "$SL" import "$tmp/empty.geojson" -o "$tmp/bad.slscene"
has "empty.geojson: no buildings" "$tmp/err"
# projected coordinates in a GeoJSON (WGS 84 by its rule): an error saying so; --metric or --crs
printf '{"type":"FeatureCollection","features":[{"type":"Feature","properties":{"height":8},"geometry":{"type":"Polygon","coordinates":[[[601000,5340000],[601020,5340000],[601020,5340020],[601000,5340020],[601000,5340000]]]}}]}\n' >"$tmp/utm.geojson"
expect 1 "$SL" import "$tmp/utm.geojson" -o "$tmp/bad.slscene"
has "look projected" "$tmp/err"
expect 0 "$SL" import "$tmp/utm.geojson" --metric -o "$tmp/utm.slscene" --json
has '"crs":"metric (local)"' "$tmp/out"
expect 0 "$SL" import "$tmp/utm.geojson" --crs EPSG:32633 -o "$tmp/utm2.slscene" --json
has 'UTM zone 33N' "$tmp/out"
expect 1 "$SL" import "$tmp/utm.geojson" --crs EPSG:999999 -o "$tmp/bad.slscene"
has "CRS 'EPSG:999999' not understood" "$tmp/err"
expect 1 "$SL" import "$tmp/city.geojson" --layers roads -o "$tmp/bad.slscene"
has "no layer 'roads'" "$tmp/err"
expect 1 "$SL" import "$tmp/nothere.shp" -o "$tmp/bad.slscene"
has "nothere.shp" "$tmp/err"
[ -e "$tmp/bad.slscene" ] && fail "a failed import left its output"
echo "import_gis: ok"
