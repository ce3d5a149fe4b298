#!/bin/bash
# CLI test of `sightline path`: help texts, usage errors, check/info on hand-written files (good,
# CRLF, malformed), gen on a scene without streets (an OBJ box), and gen/random on a generated
# city. $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

# ---- help and usage errors ----
expect 0 "$SL" path --help
has "# sightline-path 1" "$tmp/out"
has "examples:" "$tmp/out"
for a in gen random info check; do
    expect 0 "$SL" path $a --help
    has "usage: sightline path $a" "$tmp/out"
    has "example" "$tmp/out"
done
expect 2 "$SL" path
expect 2 "$SL" path bogus
has "unknown action" "$tmp/err"
expect 2 "$SL" path info --bogus
has "unknown option --bogus" "$tmp/err"
expect 2 "$SL" path check
expect 2 "$SL" path gen some.slscene --kind walk
has "missing -o" "$tmp/err"
expect 2 "$SL" path gen some.slscene --kind swim -o x.txt
has "not walk, drive or flyover" "$tmp/err"
expect 2 "$SL" path gen some.slscene --frames ten -o x.txt
expect 2 "$SL" path random some.slscene --frames 10 -o x.txt
expect 2 "$SL" path random some.slscene --kind walk -o x.txt

# ---- check and info on hand-written files ----
cat >"$tmp/p.txt" <<'EOF'
# sightline-path 1
camera fov=70 width=640 height=480
# t x y z yaw pitch roll
0 0 0 1.7 0 0 0
1 3 4 1.7 90 0 0

2 3 4 1.7 90 -10 0
EOF
expect 0 "$SL" path check "$tmp/p.txt"
has "ok, 3 poses" "$tmp/out"
expect 0 "$SL" path check "$tmp/p.txt" --json
has '"valid":true' "$tmp/out"
expect 0 "$SL" path info "$tmp/p.txt" --json
has '"frames":3' "$tmp/out"
has '"length_m":5' "$tmp/out"
has '"duration_s":2' "$tmp/out"
has '"fov_deg":70' "$tmp/out"
has '"width":640' "$tmp/out"
expect 0 "$SL" path info "$tmp/p.txt"
has "frames     3" "$tmp/out"
sed 's/$/\r/' "$tmp/p.txt" >"$tmp/crlf.txt"
expect 0 "$SL" path check "$tmp/crlf.txt"

printf '# sightline-path 1\n0 0 0 0 0 0\n' >"$tmp/short.txt"
expect 1 "$SL" path check "$tmp/short.txt"
has "short.txt:2: expected 7 fields" "$tmp/err"
printf '# sightline-path 1\n1 0 0 0 0 0 0\n0 0 0 0 0 0 0\n' >"$tmp/back.txt"
expect 1 "$SL" path check "$tmp/back.txt"
has "back.txt:3: time 0 is before" "$tmp/err"
printf '# sightline-path 1\n0 nan 0 0 0 0 0\n' >"$tmp/nan.txt"
expect 1 "$SL" path info "$tmp/nan.txt"
has "nan.txt:2: field 2 (x)" "$tmp/err"
: >"$tmp/empty.txt"
expect 1 "$SL" path check "$tmp/empty.txt"
has "empty.txt:1: empty file" "$tmp/err"
head -c 3000 /dev/urandom >"$tmp/garbage.txt"
expect 1 "$SL" path check "$tmp/garbage.txt"
has "garbage.txt:1:" "$tmp/err"
expect 1 "$SL" path check "$tmp/short.txt" --json
has '"valid":false' "$tmp/out"
expect 1 "$SL" path check "$tmp/missing.txt"
has "missing.txt" "$tmp/err"

# ---- a scene without streets: an OBJ tower ----
cat >"$tmp/box.obj" <<'EOF'
v 0 0 0
v 20 0 0
v 20 20 0
v 0 20 0
v 0 0 60
v 20 0 60
v 20 20 60
v 0 20 60
f 1 3 2
f 1 4 3
f 5 6 7
f 5 7 8
f 1 2 6
f 1 6 5
f 2 3 7
f 2 7 6
f 3 4 8
f 3 8 7
f 4 1 5
f 4 5 8
EOF
expect 1 "$SL" path gen "$tmp/box.obj" --kind walk -o "$tmp/w.txt"
has "scene has no street network: use flyover, or a path file" "$tmp/err"
[ ! -e "$tmp/w.txt" ] || fail "a failed gen left $tmp/w.txt behind"
expect 0 "$SL" path gen "$tmp/box.obj" --kind flyover --frames 120 -o "$tmp/fly.txt" --json
has '"frames":120' "$tmp/out"
expect 0 "$SL" path check "$tmp/fly.txt"
expect 0 "$SL" path random "$tmp/box.obj" --kind flyover --count 25 --seed 3 -o "$tmp/rf.txt"
expect 0 "$SL" path info "$tmp/rf.txt" --json
has '"frames":25' "$tmp/out"
expect 1 "$SL" path gen "$tmp/box.obj" --kind flyover -o "$tmp/no-such-dir/fly.txt"
expect 1 "$SL" path gen "$tmp/box.obj" --kind flyover --frames 0 -o "$tmp/f0.txt"
has "frames 0" "$tmp/err"
expect 1 "$SL" path gen "$tmp/missing.obj" --kind flyover -o "$tmp/f1.txt"

# ---- a generated city ----
if ! "$SL" gen city --preset tiny -o "$tmp/city.slscene" >"$tmp/out" 2>"$tmp/err"; then
    fail "sightline gen city --preset tiny failed"
fi
city="$tmp/city.slscene"
for k in walk drive flyover; do
    expect 0 "$SL" path gen "$city" --kind $k --frames 300 --seed 5 -o "$tmp/$k-a.txt"
    expect 0 "$SL" path gen "$city" --kind $k --frames 300 --seed 5 -o "$tmp/$k-b.txt"
    expect 0 "$SL" path gen "$city" --kind $k --frames 300 --seed 6 -o "$tmp/$k-c.txt"
    cmp -s "$tmp/$k-a.txt" "$tmp/$k-b.txt" || fail "$k: same seed, different files"
    cmp -s "$tmp/$k-a.txt" "$tmp/$k-c.txt" && fail "$k: different seeds, same file"
    expect 0 "$SL" path info "$tmp/$k-a.txt" --json
    has '"frames":300' "$tmp/out"
done
expect 0 "$SL" path info "$tmp/walk-a.txt" --json
near speed_mean_mps 1.4 0.01
expect 0 "$SL" path gen "$city" --kind walk --frames 60 --fps 60 --speed 2 --eye-height 1.5 --head-bob \
    --fov 90 --width 800 --height 600 --near 0.2 --far 2000 -o "$tmp/opts.txt"
expect 0 "$SL" path info "$tmp/opts.txt" --json
has '"fov_deg":90' "$tmp/out"
has '"near":0.2' "$tmp/out"
for k in street flyover; do
    expect 0 "$SL" path random "$city" --kind $k --count 50 --seed 2 -o "$tmp/r-$k.txt"
    expect 0 "$SL" path check "$tmp/r-$k.txt"
    has "ok, 50 poses" "$tmp/out"
done
echo "PASS"
