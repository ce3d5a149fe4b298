#!/bin/bash
# CLI test of `sightline methods` and `sightline bench`: help texts, usage errors (exit 2), bad
# files (exit 1), and runs on the tiny city: a walk, random street and flyover views, a hand-written
# path with a frame range, two scenes at once, method options, a map from a point. Checks the
# files written (CSV rows = frames x methods, JSON, summary, SVG plots, PNG maps with the PNG
# signature) and that every conservative method misses nothing. The pvs culler runs on the PVS the
# bench bakes along the views (OUT/LABEL.slpvs) or on a file given with pvs:file=, and is named as
# not run where nothing can be baked; with --frames A:B it bakes the cells along those frames only.
# $1 is the sightline binary.
# Under sanitizers (SL_SANITIZED set) the runs use fewer frames.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

if [ -n "${SL_SANITIZED:-}" ]; then N=4; else N=12; fi

# ---- methods ----
expect 0 "$SL" methods --help
has "usage: sightline methods" "$tmp/out"
has "example" "$tmp/out"
expect 0 "$SL" methods
has "vfc (conservative)" "$tmp/out"
has "leaf_size=" "$tmp/out"
expect 0 "$SL" methods --json
has '"name":"vfc"' "$tmp/out"
has '"guarantee":"conservative"' "$tmp/out"
expect 0 "$SL" methods vfc --json
has '"name":"vfc"' "$tmp/out"
expect 2 "$SL" methods nosuch
has "unknown culling method 'nosuch'" "$tmp/err"
expect 2 "$SL" methods --bogus

# ---- bench: help and usage errors (run in an empty folder: nothing may be written) ----
mkdir "$tmp/cwd"
cd "$tmp/cwd" || fail "cd"
expect 0 "$SL" bench --help
has "usage: sightline bench" "$tmp/out"
has "examples:" "$tmp/out"
has "CONSERVATIVENESS VIOLATION" "$tmp/out"
expect 2 "$SL" bench
has "missing SCENE" "$tmp/err"
expect 2 "$SL" bench city:tiny
has "missing views" "$tmp/err"
expect 2 "$SL" bench city:tiny --walk 5 --random street
has "only one of" "$tmp/err"
expect 2 "$SL" bench city:tiny --random walk
has "not street or flyover" "$tmp/err"
expect 2 "$SL" bench city:tiny --walk 0
expect 2 "$SL" bench city:tiny --walk ten
expect 2 "$SL" bench city:tiny --walk 5 --bogus
has "unknown option --bogus" "$tmp/err"
expect 2 "$SL" bench city:tiny --walk 5 --methods vfc,nosuch
has "unknown culling method 'nosuch'" "$tmp/err"
expect 2 "$SL" bench city:tiny --walk 5 --methods vfc,vfc
expect 2 "$SL" bench city:tiny --walk 5 --method-options vfc:bogus=1
has "bogus" "$tmp/err"
expect 2 "$SL" bench city:tiny --walk 5 --method-options coherence=off
expect 2 "$SL" bench city:tiny --walk 5 --methods pvs --method-options pvs:bogus=1
has "unknown option 'bogus'" "$tmp/err"
expect 2 "$SL" bench city:tiny --walk 5 --repeat 0
expect 2 "$SL" bench city:tiny --walk 5 --frames 0:2
expect 2 "$SL" bench city:tiny --walk 5 --map-eye 1,2
expect 2 "$SL" bench city:tiny --walk 5 --width 0
[ -z "$(ls -A "$tmp/cwd")" ] || fail "a usage error wrote into the current folder"

# ---- bad files and scenes: exit 1 ----
expect 1 "$SL" bench "$tmp/missing.slscene" --walk 5 --out "$tmp/x"
has "missing.slscene" "$tmp/err"
head -c 2000 /dev/urandom >"$tmp/garbage.slscene"
expect 1 "$SL" bench "$tmp/garbage.slscene" --walk 5 --out "$tmp/x"
has "garbage.slscene" "$tmp/err"
expect 1 "$SL" bench city:huge --walk 5 --out "$tmp/x"
has "unknown city preset" "$tmp/err"
has "scene 'city:huge': unknown city preset 'huge'" "$tmp/err"
expect 1 "$SL" bench city:tiny:x1 --walk 5 --out "$tmp/x"
has "scene 'city:tiny:x1': the seed 'x1' is not a non-negative integer" "$tmp/err"
expect 1 "$SL" bench city:tiny:-1 --walk 5 --out "$tmp/x"
has "the seed '-1' is not a non-negative integer" "$tmp/err"
expect 1 "$SL" bench city:tiny --map q3dm1 --walk 5 --out "$tmp/x"
has "scene 'city:tiny': a map name only applies to .pk3 archives" "$tmp/err"
expect 1 "$SL" bench city:tiny --path "$tmp/missing.txt" --out "$tmp/x"
has "missing.txt" "$tmp/err"
printf '# sightline-path 1\n0 0 0 nan 0 0 0\n' >"$tmp/bad.txt"
expect 1 "$SL" bench city:tiny --path "$tmp/bad.txt" --out "$tmp/x"
has "bad.txt:2" "$tmp/err"
[ -z "$(ls "$tmp/x" 2>/dev/null | grep -v '^$')" ] || fail "a failed run left files in $tmp/x"

# ---- a walk on the tiny city, every method ----
expect 0 "$SL" bench city:tiny --walk $N --out "$tmp/walk"
# methods run by default: every registered one that needs no option; the others are named
M=$(grep -o '"guarantee":' "$tmp/walk/summary.json" | wc -l)
[ "$M" -ge 1 ] || fail "no methods ran"
S=$(grep -o '"reason":' "$tmp/walk/summary.json" | wc -l)
R=$("$SL" methods --json | grep -o '"name":' | wc -l)
[ $((M + S)) -eq "$R" ] || fail "$M methods ran and $S were skipped, but $R are registered"
[ "$(grep -c '^not run: ' "$tmp/out")" -eq "$S" ] || fail "skipped methods are not named on stdout"
has "### city-tiny-1" "$tmp/out"
has "| vfc | conservative | $N |" "$tmp/out"
hasnt "VIOLATION" "$tmp/err"
for f in frames.csv frames.json summary.md summary.json; do [ -s "$tmp/walk/$f" ] || fail "no $f"; done
[ "$(rows "$tmp/walk/frames.csv")" -eq $((N * M)) ] || fail "frames.csv has $(rows "$tmp/walk/frames.csv") rows, expected $((N * M))"
head -1 "$tmp/walk/frames.csv" | grep -q '^scene,frame,time_s,x,y,z,yaw_deg,pitch_deg,roll_deg,method,guarantee,cull_ms,' ||
    fail "frames.csv header"
cols=$(head -1 "$tmp/walk/frames.csv" | tr ',' '\n' | wc -l)
awk -F, -v c="$cols" 'NR > 1 && NF != c { exit 1 }' "$tmp/walk/frames.csv" || fail "a CSV row has the wrong field count"
# every conservative row has zero missed objects (column 18)
awk -F, 'NR > 1 && $11 == "conservative" && $18 != 0 { exit 1 }' "$tmp/walk/frames.csv" || fail "a conservative miss"
has '"format":"sightline-bench-frames"' "$tmp/walk/frames.json"
[ "$(grep -o '"method":' "$tmp/walk/frames.json" | wc -l)" -eq $((N * M)) ] || fail "frames.json rows"
has '"violations":0' "$tmp/walk/summary.json"
has "| vfc | conservative | $N |" "$tmp/walk/summary.md"
for p in cull-time triangles missed-pixels; do is_svg "$tmp/walk/city-tiny-1-$p.svg"; done
is_png "$tmp/walk/city-tiny-1-map-vfc.png"
# pvs ran by default on the PVS baked along the walk, with no miss (column 18)
has "baking the PVS of the street cells" "$tmp/err"
has "| pvs | conservative | $N |" "$tmp/out"
hasnt "not run: pvs" "$tmp/out"
[ "$(awk -F, '$10 == "pvs"' "$tmp/walk/frames.csv" | wc -l)" -eq "$N" ] || fail "frames.csv: no $N pvs rows"
awk -F, '$10 == "pvs" && $18 != 0 { exit 1 }' "$tmp/walk/frames.csv" || fail "pvs missed an object"
[ -s "$tmp/walk/city-tiny-1.slpvs" ] || fail "no city-tiny-1.slpvs"
[ ! -e "$tmp/walk/city-tiny-1.slpvs.ckpt" ] || fail "the PVS bake left its journal"
"$SL" pvs verify "$tmp/walk/city-tiny-1.slpvs" >/dev/null 2>&1 || fail "city-tiny-1.slpvs does not verify"

# ---- pvs: --json and other options, a given file, nothing to bake ----
expect 0 "$SL" bench city:tiny --walk 3 --methods vfc,pvs --method-options pvs:dynamic=frustum --no-plots --json \
    --out "$tmp/pj"
hasnt "baking" "$tmp/err"
has '"name":"pvs","options":"file='"$tmp"'/pj/city-tiny-1.slpvs,dynamic=frustum' "$tmp/out"
has '"violations":0' "$tmp/out"
[ "$(awk -F, '$10 == "pvs" && $18 == 0' "$tmp/pj/frames.csv" | wc -l)" -eq 3 ] || fail "pvs --json: rows"
expect 0 "$SL" bench city:tiny --walk 3 --methods pvs --method-options pvs:file="$tmp/walk/city-tiny-1.slpvs" \
    --no-plots --out "$tmp/pf"
hasnt "baking" "$tmp/err"
[ ! -e "$tmp/pf/city-tiny-1.slpvs" ] || fail "pvs:file= given, yet the bench baked"
[ "$(awk -F, '$10 == "pvs" && $18 == 0' "$tmp/pf/frames.csv" | wc -l)" -eq 3 ] || fail "pvs:file=: rows"
expect 0 "$SL" bench city:tiny --random flyover --count 2 --no-plots --quiet --out "$tmp/pn"
has "not run: pvs (city-tiny-1: no street view cell" "$tmp/out"
has '"name":"pvs","reason":"city-tiny-1: ' "$tmp/pn/summary.json"
expect 1 "$SL" bench city:tiny --random flyover --count 2 --methods vfc,pvs --no-plots --quiet --out "$tmp/pn2"
has "cannot run pvs on city-tiny-1" "$tmp/err"
expect 0 "$SL" bench city:tiny --walk 2 --no-plots --quiet --out "$tmp/a,b"
has "not run: pvs (city-tiny-1: the output folder's path holds a comma" "$tmp/out"
expect 1 "$SL" bench city:tiny --walk 2 --methods vfc,pvs --no-plots --quiet --out "$tmp/a,b"
has "comma" "$tmp/err"

# ---- JSON summary, random views, no plots, repeats, method options ----
expect 0 "$SL" bench city:tiny --random street --count $N --seed 2 --no-plots --json --repeat 3 \
    --methods vfc --method-options vfc:coherence=off,leaf_size=2 --out "$tmp/rand"
has '"violations":0' "$tmp/out"
has '"frames":'"$N" "$tmp/out"
has 'coherence=false' "$tmp/out"
has 'leaf_size=2' "$tmp/out"
[ "$(rows "$tmp/rand/frames.csv")" -eq "$N" ] || fail "random: CSV rows"
ls "$tmp/rand"/*.svg >/dev/null 2>&1 && fail "--no-plots wrote plots"
expect 0 "$SL" bench city:tiny --random flyover --count 3 --methods vfc --width 320 --height 240 \
    --map-eye 0,0,40 --map-size 200 --out "$tmp/fly" --quiet
is_png "$tmp/fly/city-tiny-1-map-vfc.png"
grep -q '"width":320' "$tmp/fly/frames.json" || fail "frames.json camera width"

# ---- a path file with a frame range; two scenes at once ----
cat >"$tmp/p.txt" <<'EOF'
# sightline-path 1
camera fov=70 width=640 height=480
0 0 0 1.7 0 0 0
1 0 0 1.7 90 0 0
2 0 0 1.7 180 0 0
3 0 0 1.7 270 -10 0
EOF
expect 0 "$SL" bench city:tiny city:tiny:2 --path "$tmp/p.txt" --frames 1:3 --methods vfc --no-plots --out "$tmp/path"
[ "$(rows "$tmp/path/frames.csv")" -eq 4 ] || fail "path: 2 frames x 2 scenes expected"
has '^city-tiny-2,' "$tmp/path/frames.csv"
has '^city-tiny-1,1,1,' "$tmp/path/frames.csv"
expect 0 "$SL" bench city:tiny --path "$tmp/p.txt" --frames 3: --methods vfc --no-plots --out "$tmp/path2"
[ "$(rows "$tmp/path2/frames.csv")" -eq 1 ] || fail "--frames 3: should run one frame"
expect 1 "$SL" bench city:tiny --path "$tmp/p.txt" --frames 9:12 --out "$tmp/path3"
has "beyond" "$tmp/err"
expect 2 "$SL" bench city:tiny --path "$tmp/p.txt" --frames 3:1

# ---- pvs with --frames: the bench bakes the cells along the frames it runs, not the whole path ----
# a 40 s walk at 1 fps (55 m) of the same generated city, run whole (0:40) and as frames 0:2; the
# cells baked are read back with `pvs info` and must match the count the bench printed on stderr
expect 0 "$SL" gen city --preset tiny -o "$tmp/city.slscene"
expect 0 "$SL" path gen "$tmp/city.slscene" --kind walk --frames 40 --fps 1 -o "$tmp/w.txt"
cells=()
for r in 0:40 0:2; do
    o="$tmp/ps${#cells[@]}"
    expect 0 "$SL" bench "$tmp/city.slscene" --path "$tmp/w.txt" --frames "$r" --methods pvs --width 64 --height 48 \
        --no-plots --out "$o"
    n=$("$SL" pvs info "$o/city.slpvs" --json | grep -o '"cells":[0-9]*' | head -1 | cut -d: -f2)
    [ -n "$n" ] || fail "--frames $r: no cell count from pvs info $o/city.slpvs"
    has "$o/city.slpvs: $n cells" "$tmp/err"
    [ "$(awk -F, '$10 == "pvs" && $18 == 0' "$o/frames.csv" | wc -l)" -eq "${r#0:}" ] ||
        fail "--frames $r: not ${r#0:} pvs rows without a miss"
    cells+=("$n")
done
[ "${cells[1]}" -gt 0 ] && [ "${cells[1]}" -lt "${cells[0]}" ] ||
    fail "--frames 0:2 baked ${cells[1]} cells, the whole path ${cells[0]}: expected fewer, but some"

# one frame from an engine's matrices (issue 13 §1): the reversed-z infinite-far, y-flipped
# Vulkan-style view of the eye at (0, 0, 1.7) looking along +X, every default method (pvs baked
# along it) judged with no violation; refusals exit 2
VM=0,0,-1,0,-1,0,0,0,0,1,0,0,0,-1.7,0,1
PREV=1.299038,0,0,0,0,-1.732051,0,0,0,0,0,-1,0,0,0.1,0
expect 0 "$SL" bench city:tiny --view-matrix $VM --proj-matrix $PREV --clip-depth reversed --width 160 --height 120 \
    --no-plots --quiet --json --out "$tmp/bv"
has '"violations":0' "$tmp/out"
has '"frames":1,' "$tmp/out"
has '"name":"pvs"' "$tmp/out"
# the reports show the view itself (docs/bench.md, "the view columns"); camera runs have none
head -1 "$tmp/bv/frames.csv" | grep -q ',skipped,query_stalls,query_wait_ms,view,clip_depth,projection,near,far,rect_left,.*,mirrored$' ||
    fail "frames.csv of a view from matrices: no view columns"
grep -q ',matrices,reversed,perspective,0.100000001,inf,' "$tmp/bv/frames.csv" || fail "frames.csv: not the view given"
grep -q '"view":{"source":"matrices","clip_depth":"reversed"' "$tmp/bv/frames.json" || fail "frames.json: no view"
grep -q "from an engine's matrices (frame 0: reversed depth, perspective, near 0.1 m, far infinite" "$tmp/bv/summary.md" ||
    fail "summary.md: the view is not described"
head -1 "$tmp/walk/frames.csv" | grep -q ',missed,skipped,query_stalls,query_wait_ms$' || fail "frames.csv of cameras: columns changed"
expect 2 "$SL" bench city:tiny --view-matrix $VM --proj-matrix $PREV --walk 5
has "only one of" "$tmp/err"
expect 2 "$SL" bench city:tiny --proj-matrix $PREV
has "go together" "$tmp/err"
expect 2 "$SL" bench city:tiny --walk 5 --clip-depth reversed
has "applies to --view-matrix" "$tmp/err"
expect 2 "$SL" bench city:tiny --view-matrix $VM --proj-matrix 1,0,0,0,0,1,0,0,0,0,0,-1,0,0,0,0 --clip-depth reversed
has "near plane" "$tmp/err"
echo "PASS"
