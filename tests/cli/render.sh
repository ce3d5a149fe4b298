#!/bin/bash
# CLI test of `sightline render`: help, usage errors (exit 2), bad files (exit 1), and images of
# the tiny city for one camera and for frames of a path: PNG signature, size, the kinds selected
# by --images and --KIND, --json listing. $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

# ---- help and usage errors ----
expect 0 "$SL" render --help
has "usage: sightline render" "$tmp/out"
has "examples:" "$tmp/out"
has "overdraw" "$tmp/out"
expect 2 "$SL" render
has "missing SCENE" "$tmp/err"
expect 2 "$SL" render city:tiny
has "missing --camera or --path" "$tmp/err"
expect 2 "$SL" render city:tiny --camera 0,0,2,0,0,0 --path x.txt
expect 2 "$SL" render city:tiny --camera 0,0,2,0,0
has "expected x,y,z,yaw,pitch,roll" "$tmp/err"
expect 2 "$SL" render city:tiny --camera 0,0,2,0,0,0,60,1
expect 2 "$SL" render city:tiny --camera 0,0,2,0,abc,0
expect 2 "$SL" render city:tiny --camera 0,0,2,0,95,0
has "pitch" "$tmp/err"
expect 2 "$SL" render city:tiny --camera 0,0,2,0,0,0 --images id,bogus
has "unknown kind 'bogus'" "$tmp/err"
expect 2 "$SL" render city:tiny --camera 0,0,2,0,0,0 --frames 0:2
expect 2 "$SL" render city:tiny --camera 0,0,2,0,0,0 --width 100
expect 2 "$SL" render city:tiny --camera 0,0,2,0,0,0 --bogus
has "unknown option --bogus" "$tmp/err"
expect 2 "$SL" render city:tiny --path x.txt --frames 5:2

# ---- bad files: exit 1 ----
expect 1 "$SL" render "$tmp/missing.obj" --camera 0,0,2,0,0,0 --out "$tmp/x"
has "missing.obj" "$tmp/err"
expect 1 "$SL" render city:tiny --path "$tmp/missing.txt" --out "$tmp/x"
has "missing.txt" "$tmp/err"
printf '# sightline-path 1\n0 0 0 2 0 0\n' >"$tmp/short.txt"
expect 1 "$SL" render city:tiny --path "$tmp/short.txt" --out "$tmp/x"
has "short.txt:2" "$tmp/err"

# ---- one camera ----
# (the oracle's kinds; with OpenGL the default is shaded: tests/cli/render_shaded.sh)
expect 0 "$SL" render city:tiny --camera "0,0,1.7,45,0,0" --width 160 --height 120 --images id,depth,overdraw --out "$tmp/one"
has "3 images of 1 frame" "$tmp/out"
for k in id depth overdraw; do
    f="$tmp/one/frame-00000-$k.png"
    is_png "$f"
    [ "$(png_size "$f")" = "160x120" ] || fail "$f is $(png_size "$f"), expected 160x120"
done
expect 0 "$SL" render city:tiny --camera "0,0,300,0,-60,0,70" --width 64 --height 48 --images id --out "$tmp/sel"
[ "$(ls "$tmp/sel" | wc -l)" -eq 1 ] || fail "--images id wrote $(ls "$tmp/sel")"
is_png "$tmp/sel/frame-00000-id.png"
expect 0 "$SL" render city:tiny --camera "0,0,300,0,-60,0" --width 64 --height 48 --depth --out "$tmp/flag"
[ "$(ls "$tmp/flag")" = "frame-00000-depth.png" ] || fail "--depth wrote $(ls "$tmp/flag")"

# ---- frames of a path ----
cat >"$tmp/p.txt" <<'EOF'
# sightline-path 1
camera fov=70 width=96 height=64
0 0 0 1.7 0 0 0
1 0 0 1.7 90 0 0
2 0 0 1.7 180 0 0
3 0 0 30 270 -45 0
EOF
expect 0 "$SL" render city:tiny --path "$tmp/p.txt" --frames 1:3 --images id,depth,overdraw --out "$tmp/path" --json
has '"images":6' "$tmp/out"
has '"frame":1' "$tmp/out"
has '"frame":2' "$tmp/out"
for f in 1 2; do for k in id depth overdraw; do is_png "$tmp/path/frame-0000$f-$k.png"; done; done
[ "$(png_size "$tmp/path/frame-00001-id.png")" = "96x64" ] || fail "path intrinsics not used"
[ ! -e "$tmp/path/frame-00000-id.png" ] || fail "frame 0 rendered outside --frames 1:3"
expect 0 "$SL" render city:tiny --path "$tmp/p.txt" --frames 3 --width 50 --height 40 --depth --out "$tmp/path1"
[ "$(png_size "$tmp/path1/frame-00003-depth.png")" = "50x40" ] || fail "--width with --path"
expect 1 "$SL" render city:tiny --path "$tmp/p.txt" --frames 7: --out "$tmp/path2"
has "beyond" "$tmp/err"
# the cull map of a viewpoint (cullmap method), written only when asked for
expect 0 "$SL" render city:tiny --camera "0,0,1.7,45,0,0" --cullmap --out "$tmp/cm"
is_png "$tmp/cm/frame-00000-cullmap.png"
[ ! -e "$tmp/cm/frame-00000-id.png" ] || fail "--cullmap alone also wrote the id image"

# an engine's matrices (issue 13 §1): the reversed-z infinite-far view of --camera 0,0,1.7,0,0,0
# draws the camera's id image; a Vulkan-style y-flipped [0,1] one too; refusals name the reason
VM=0,0,-1,0,-1,0,0,0,0,1,0,0,0,-1.7,0,1
PREV=1.299038,0,0,0,0,1.732051,0,0,0,0,0,-1,0,0,0.1,0
PVK=1.299038,0,0,0,0,-1.732051,0,0,0,0,-1.00002,-1,0,0,-0.100002,0
expect 0 "$SL" render city:tiny --camera 0,0,1.7,0,0,0 --width 160 --height 120 --images id --out "$tmp/vc"
expect 0 "$SL" render city:tiny --view-matrix $VM --proj-matrix $PREV --clip-depth reversed --width 160 --height 120 \
    --images id,depth --out "$tmp/vr"
cmp -s "$tmp/vc/frame-00000-id.png" "$tmp/vr/frame-00000-id.png" || fail "reversed-z matrices: not the camera's image"
is_png "$tmp/vr/frame-00000-depth.png"
expect 0 "$SL" render city:tiny --view-matrix $VM --proj-matrix $PVK --clip-depth zero-one --width 160 --height 120 \
    --images id --out "$tmp/vk"
cmp -s "$tmp/vc/frame-00000-id.png" "$tmp/vk/frame-00000-id.png" || fail "y-flipped [0,1] matrices: not the camera's image"
expect 0 "$SL" render --help
has "view-matrix" "$tmp/out"
has "clip-depth" "$tmp/out"
expect 2 "$SL" render city:tiny --view-matrix $VM
has "go together" "$tmp/err"
expect 2 "$SL" render city:tiny --view-matrix $VM --proj-matrix $PREV --camera 0,0,2,0,0,0
expect 2 "$SL" render city:tiny --view-matrix $VM --proj-matrix $PREV --clip-depth d3d
has "expected gl, zero-one or reversed" "$tmp/err"
expect 2 "$SL" render city:tiny --view-matrix 1,2,3 --proj-matrix $PREV
has "16 comma-separated" "$tmp/err"
expect 2 "$SL" render city:tiny --view-matrix 0,0,-1,0,-1,0,0,0,0,1,0,0,0,-1.7,0,1 --proj-matrix 1.3,0.2,0,0,0,1.7,0,0,0,0,0,-1,0,0,0.1,0 --clip-depth reversed
has "skew" "$tmp/err"
expect 2 "$SL" render city:tiny --view-matrix 2,0,-1,0,-1,0,0,0,0,1,0,0,0,-1.7,0,1 --proj-matrix $PREV --clip-depth reversed
has "rigid" "$tmp/err"
# the cull map of an engine's view (its infinite far plane bounded by the scene)
expect 0 "$SL" render city:tiny --view-matrix $VM --proj-matrix $PREV --clip-depth reversed --width 160 --height 120 \
    --cullmap --out "$tmp/vm"
is_png "$tmp/vm/frame-00000-cullmap.png"
[ ! -e "$tmp/vm/frame-00000-id.png" ] || fail "--cullmap alone also wrote the id image"
expect 2 "$SL" render city:tiny --camera 0,0,2,0,0,0 --clip-depth gl
echo "PASS"
