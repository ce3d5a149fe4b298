#!/bin/bash
# CLI test of `sightline render`'s shaded kind (the OpenGL renderer, headless): the default kind
# when built with OpenGL, PNG frames of a camera and of the bench's walk, frames.csv / frames.json
# with a row per frame, --methods choosing the culler (fewer objects drawn than none), usage errors,
# --video through ffmpeg (or its clear refusal when ffmpeg is missing). Exits 77 (skipped) when the
# command was built without OpenGL or no headless GL context can be made. $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

"$SL" render --help >"$tmp/help" 2>&1
if ! grep -q '^  shaded ' "$tmp/help"; then
    echo "SKIP: sightline was built without OpenGL (no shaded kind)"
    exit 77
fi
if ! "$SL" render city:tiny --camera 0,0,1.7,0,0,0 --width 8 --height 8 --out "$tmp/probe" --quiet >"$tmp/out" 2>"$tmp/err"; then
    if grep -q "no headless GL context" "$tmp/err"; then
        echo "SKIP: $(cat "$tmp/err")"
        exit 77
    fi
    fail "probe render failed"
fi

# ---- one camera: shaded is the default, nothing else ----
expect 0 "$SL" render city:tiny --camera "0,0,1.7,45,0,0" --width 160 --height 120 --out "$tmp/one"
has "1 image of 1 frame" "$tmp/out"
is_png "$tmp/one/frame-00000-shaded.png"
[ "$(png_size "$tmp/one/frame-00000-shaded.png")" = "160x120" ] || fail "shaded frame size"
[ ! -e "$tmp/one/frame-00000-id.png" ] || fail "the oracle's id image written by default with OpenGL"
head -1 "$tmp/one/frames.csv" | grep -q '^frame,method,width,height,frame_ms,cull_ms' || fail "frames.csv header"
[ "$(wc -l <"$tmp/one/frames.csv")" -eq 2 ] || fail "frames.csv: expected one row"
python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); assert len(d["frames"])==1 and d["method"]=="none" and d["frames"][0]["objects_drawn"]>0' \
    "$tmp/one/frames.json" || fail "frames.json"
# with the oracle's kinds too
expect 0 "$SL" render city:tiny --camera "0,0,1.7,45,0,0" --width 64 --height 48 --images shaded,id --out "$tmp/both"
is_png "$tmp/both/frame-00000-shaded.png"
is_png "$tmp/both/frame-00000-id.png"

# ---- the bench's walk, culled by vfc: fewer objects drawn than without culling ----
expect 0 "$SL" render city:tiny --walk 4 --width 96 --height 64 --methods vfc --out "$tmp/walk" --quiet
for f in 0 1 2 3; do is_png "$tmp/walk/frame-0000$f-shaded.png"; done
[ "$(wc -l <"$tmp/walk/frames.csv")" -eq 5 ] || fail "frames.csv: expected 4 rows"
expect 0 "$SL" render city:tiny --walk 4 --width 96 --height 64 --frames 1:2 --out "$tmp/walk0" --quiet
culled=$(awk -F, 'NR==3 {print $10}' "$tmp/walk/frames.csv")
all=$(awk -F, 'NR==2 {print $10}' "$tmp/walk0/frames.csv")
[ "$culled" -lt "$all" ] || fail "vfc drew $culled objects, no culling $all"
grep -q '^1,vfc,96,64,' "$tmp/walk/frames.csv" || fail "frames.csv rows"
expect 0 "$SL" render city:tiny --walk 2 --width 64 --height 48 --methods "vfc:coherence=off" --depth-prepass --out "$tmp/opt" --quiet
grep -q '"options":"[^"]*coherence=false' "$tmp/opt/frames.json" || fail "method options not applied"

# ---- usage errors ----
expect 2 "$SL" render city:tiny --walk 2 --methods bogus --out "$tmp/x"
has "bogus" "$tmp/err"
expect 2 "$SL" render city:tiny --walk 2 --methods vfc,hzb --out "$tmp/x"
has "one method" "$tmp/err"
expect 2 "$SL" render city:tiny --walk 2 --methods vfc --images id --out "$tmp/x"
has "applies to the shaded kind" "$tmp/err"
expect 2 "$SL" render city:tiny --walk 2 --video "$tmp/v.avi" --out "$tmp/x"
has "FILE.mp4" "$tmp/err"
expect 2 "$SL" render city:tiny --walk 2 --context bogus --out "$tmp/x"
expect 2 "$SL" render city:tiny --walk 0 --out "$tmp/x"

# ---- video ----
if command -v ffmpeg >/dev/null 2>&1; then
    expect 0 "$SL" render city:tiny --walk 6 --width 64 --height 48 --video "$tmp/walk.mp4" --out "$tmp/vid" --quiet
    [ -s "$tmp/walk.mp4" ] || fail "no video written"
    if command -v ffprobe >/dev/null 2>&1; then
        n=$(ffprobe -v error -count_frames -select_streams v:0 -show_entries stream=nb_read_frames -of csv=p=0 "$tmp/walk.mp4")
        [ "$n" = 6 ] || fail "the video has $n frames, expected 6"
    fi
    ls "$tmp" | grep -q 'walk.mp4.tmp-' && fail "temporary video left behind"
fi
# the query cullers draw through the renderer's GL backend (queries counted per frame), gpu-hiz is
# the render layer's own method; both draw fewer objects than no culling
for m in chc gpu-hiz; do
    expect 0 "$SL" render city:tiny --walk 3 --width 96 --height 64 --methods $m --out "$tmp/q_$m" --quiet
    has "^2,$m," "$tmp/q_$m/frames.csv"
done
awk -F, 'NR > 1 && $13 > 0 { q = 1 } END { exit !q }' "$tmp/q_chc/frames.csv" || fail "chc issued no GL queries"
expect 1 "$SL" render city:tiny --walk 2 --methods gpu-hiz:bogus=1 --out "$tmp/x"
has "gpu-hiz: unknown option .bogus." "$tmp/err"
# without ffmpeg in PATH: a clear message and exit 1
PATH=/nonexistent expect 1 "$SL" render city:tiny --walk 2 --video "$tmp/none.mp4" --out "$tmp/nov"
has "ffmpeg command is not installed" "$tmp/err"
[ ! -e "$tmp/none.mp4" ] || fail "video written without ffmpeg"
echo "PASS"
