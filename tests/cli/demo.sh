#!/bin/bash
# CLI test of `sightline demo`: help, usage errors, and a quick run on the tiny city: the report
# (HTML and Markdown) exists, every image it references exists, the per-frame files are there, the
# pvs culler ran on the PVS the demo baked along the walk (walk.slpvs), and no conservative method
# missed anything. $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

if [ -n "${SL_SANITIZED:-}" ]; then FRAMES="--frames 6"; else FRAMES=""; fi

expect 0 "$SL" demo --help
has "usage: sightline demo" "$tmp/out"
has "examples:" "$tmp/out"
expect 2 "$SL" demo --bogus
has "unknown option --bogus" "$tmp/err"
expect 2 "$SL" demo --preset huge
has "not tiny, small, vienna, oldtown or oldtown-small" "$tmp/err"
expect 2 "$SL" demo --frames 0
expect 2 "$SL" demo extra-argument

# shellcheck disable=SC2086
expect 0 "$SL" demo --preset tiny --quick $FRAMES --out "$tmp/d" --quiet
has "Report: $tmp/d/report.html" "$tmp/out"
has "city-tiny-1-walk" "$tmp/out"
for f in report.html report.md frames.csv frames.json summary.md walk.txt walk.slpvs; do
    [ -s "$tmp/d/$f" ] || fail "no $f"
done
has "Every conservative method kept every visible object" "$tmp/d/report.md"
has "<h2 id=\"methods\">The methods</h2>" "$tmp/d/report.html"
# the recommendation comes before the results, in the report and on stdout
has "<h2 id=\"recommendation\">Recommendation</h2>" "$tmp/d/report.html"
awk '/<h2 id="recommendation">/ { r = NR } /<h2 id="results">/ { s = NR } END { exit !(r && s && r < s) }' "$tmp/d/report.html" ||
    fail "the recommendation is not before the results"
has "Fastest within 2× the exact visible set: \|No conservative method passed" "$tmp/d/report.html"
has "Recommendation" "$tmp/out"
has "vfc" "$tmp/d/report.html"
has "| pvs | conservative |" "$tmp/d/summary.md"
has "pvs runs on walk.slpvs" "$tmp/d/report.md"
grep -q "Not run: pvs" "$tmp/d/report.md" && fail "the report still names pvs as not run"
[ ! -e "$tmp/d/walk.slpvs.ckpt" ] || fail "the PVS bake left its journal"
"$SL" pvs verify "$tmp/d/walk.slpvs" >/dev/null 2>&1 || fail "walk.slpvs does not verify"
# every image the reports reference exists next to them
refs=$(grep -o 'src="[^"]*"' "$tmp/d/report.html" | sed 's/^src="//; s/"$//')
[ -n "$refs" ] || fail "report.html references no images"
for r in $refs; do
    [ -s "$tmp/d/$r" ] || fail "report.html references missing $r"
    case "$r" in *.png) is_png "$tmp/d/$r" ;; esac
done
for r in $(grep -o '](\([^)]*\))' "$tmp/d/report.md" | sed 's/^](//; s/)$//'); do
    case "$r" in
    \#*) sed -n 's/^## //p' "$tmp/d/report.md" | tr 'A-Z ' 'a-z-' | tr -cd 'a-z0-9\n-' | grep -qx -- "${r#\#}" ||
        fail "report.md's contents link to no section $r" ;;
    *) [ -s "$tmp/d/$r" ] || fail "report.md references missing $r" ;;
    esac
done
is_png "$tmp/d/frame-id.png"
# the shaded frames (with the OpenGL renderer): the view and the view from above, or why not
has "The frame, shaded" "$tmp/d/report.md"
if "$SL" render --help 2>/dev/null | grep -q '^  shaded '; then
    if [ -e "$tmp/d/frame-shaded.png" ]; then
        is_png "$tmp/d/frame-shaded.png"
        is_png "$tmp/d/frame-above.png"
    else
        has "No shaded frames: no headless GL context" "$tmp/d/report.md"
    fi
else
    has "built without the OpenGL renderer" "$tmp/d/report.md"
fi
"$SL" path check "$tmp/d/walk.txt" >/dev/null 2>&1 || fail "walk.txt is not a valid path file"

# the report's structure (report.html)
H="$tmp/d/report.html"
# a table of contents whose every link (#id) names an element of the page, nine sections or more
toc=$(grep -o 'href="#[^"]*"' "$H" | sed 's/^href="#//; s/"$//' | sort -u)
[ "$(echo "$toc" | wc -l)" -ge 9 ] || fail "the contents list fewer than 9 sections"
for id in $toc; do grep -q "id=\"$id\"" "$H" || fail "the contents link #$id leads nowhere"; done
has '<nav class="toc"' "$H"
# the summary, the recommendation and the contents come before every other section
awk '/id="summary"/ { a = NR } /<h2 id="recommendation">/ { b = NR } /<nav class="toc"/ { c = NR }
     /<h2 id="results">/ { d = NR } END { exit !(a && a < b && b < c && c < d) }' "$H" ||
    fail "summary, recommendation, contents, results are not in that order"
# the best value of the ranked columns highlighted (a legend says what), a star on the picks
[ "$(grep -o 'class="best"' "$H" | wc -l)" -ge 4 ] || fail "fewer than 4 highlighted best cells"
has 'best in its column' "$H"
# and in report.md, in bold
[ "$(grep -o '| \*\*[0-9][0-9.,]*\*\* ' "$tmp/d/report.md" | wc -l)" -ge 4 ] || fail "fewer than 4 bold best cells in report.md"
has "The best value of each ranked column is in bold" "$tmp/d/report.md"
has 'fastest pick' "$H"
# over-estimation defined as the ratio of sums it is
has 'a ratio of sums' "$H"
# the options folded
has '<details><summary>options</summary><code>' "$H"
# nothing wider than the page: a width limit, wide tables scroll in their box
has 'max-width:1100px' "$H"
has '<div class="scroll"><table>' "$H"
# plots: a legend of every method, each with its own colour and dash pattern (and a marker)
svg="$tmp/d/city-tiny-1-walk-cull-time.svg"
is_svg "$svg"
legend=$(grep 'stroke-width="2.2"' "$svg" | sed 's/x1="[^"]*" y1="[^"]*" x2="[^"]*" y2="[^"]*"//' | sort -u | wc -l)
entries=$(grep -c 'stroke-width="2.2"' "$svg")
[ "$entries" -ge 13 ] || fail "the cull-time plot's legend has $entries entries"
[ "$legend" -eq "$entries" ] || fail "two methods share a colour and dash pattern in the cull-time plot"
grep -q '<path d="M' "$svg" || fail "the plot draws no markers"
# the missed-pixels plot: no method line when nothing was missed, and it says so
has 'no misses' "$tmp/d/city-tiny-1-walk-missed-pixels.svg"
hasnt '>vfc</text>' "$tmp/d/city-tiny-1-walk-missed-pixels.svg"
# the maps: a grid of thumbnails linking to the full images, with a colour key
has '<div class="grid maps">' "$H"
has 'id="map-key"' "$H"
[ "$(sed -n '/id="map-key"/p' "$H" | grep -o 'class="sw"' | wc -l)" -ge 5 ] || fail "the map key has fewer than 5 colours"
maps=$(find "$tmp/d" -maxdepth 1 -name '*-map-*.png' ! -name '*-thumb.png' | wc -l)
thumbs=$(grep -o '<a href="[^"]*-map-[^"]*\.png"><img loading="lazy" src="[^"]*-thumb\.png"' "$H" | wc -l)
[ "$thumbs" -eq "$maps" ] || fail "$thumbs map thumbnails for $maps maps"
# real thumbnails: 340 pixels along the longer side, beside each full map
for m in $(find "$tmp/d" -maxdepth 1 -name '*-map-*.png' ! -name '*-thumb.png'); do
    t="${m%.png}-thumb.png"
    is_png "$t"
    IFS=x read -r tw th <<<"$(png_size "$t")"
    [ "$tw" -eq 340 ] || [ "$th" -eq 340 ] || fail "$t is ${tw}x$th, not 340 along its longer side"
done
# every map has its scale bar (black on white, lower left: a corner otherwise without black) and the
# eye's frustum (its blue wedge) drawn in
for m in "$tmp/d"/city-tiny-1-walk-map-vfc.png "$tmp/d"/city-tiny-1-flyover-map-hzb.png; do
    dark=$(png_dark "$m" 'iw/3:ih/8:0:ih*7/8')
    [ -z "$dark" ] || [ "$dark" -ge 100 ] || fail "no scale bar in the lower left of $m ($dark dark pixels)"
done
has 'scale in metres' "$H"
has 'its view frustum' "$H"
# self-contained: no http(s) resources
grep -Eq '(src|href)="(https?:)?//' "$H" && fail "report.html loads something from the network"

# shellcheck disable=SC2086
expect 0 "$SL" demo --preset tiny --quick --frames 3 --out "$tmp/j" --json
has '"violations":0' "$tmp/out"
has '"pvs_cells":' "$tmp/out"
has '"report":' "$tmp/out"
# an output folder the pvs culler cannot name (a comma): pvs is reported as not run
expect 0 "$SL" demo --preset tiny --quick --frames 2 --out "$tmp/a,b" --quiet
has "Not run: pvs" "$tmp/a,b/report.md"
# --methods: only the listed methods run, with their options; pvs without file= gets the walk's PVS
expect 0 "$SL" demo --preset tiny --quick --frames 3 --methods vfc,hzb:res=culling,pvs --out "$tmp/m" --quiet
has "| hzb | conservative-at-resolution |" "$tmp/m/summary.md"
has "| vfc | conservative |" "$tmp/m/summary.md"
has "| pvs | conservative |" "$tmp/m/summary.md"
[ "$(grep -cE '^\| [a-z+-]+ \| (conservative|aggressive)' "$tmp/m/summary.md")" -eq 6 ] || fail "--methods ran other methods than the three listed"
hasnt "| cullmap |" "$tmp/m/summary.md"
grep -q "res=culling" "$tmp/m/report.html" || fail "the report does not show hzb's option"
expect 0 "$SL" demo --preset tiny --quick --frames 2 --methods lazygrid --out "$tmp/m1" --quiet
[ ! -e "$tmp/m1/walk.slpvs" ] || fail "a PVS was baked although pvs was not listed"
expect 2 "$SL" demo --preset tiny --quick --methods vfc,hzbb --out "$tmp/m2"
has "did you mean hzb" "$tmp/err"
[ ! -e "$tmp/m2" ] || fail "a bad --methods left an output folder"
expect 2 "$SL" demo --preset tiny --quick --methods hzb:bogus=1 --out "$tmp/m3"
has "unknown option 'bogus'" "$tmp/err"
expect 2 "$SL" demo --preset tiny --quick --methods pvs:bogus=1 --out "$tmp/m4"
has "pvs: unknown option 'bogus'" "$tmp/err"
[ ! -e "$tmp/m4" ] || fail "a bad pvs option left an output folder"
expect 2 "$SL" demo --preset tiny --quick --methods vfc,vfc --out "$tmp/m5"
has "listed twice" "$tmp/err"
echo "PASS"
