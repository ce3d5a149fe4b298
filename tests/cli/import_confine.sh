#!/bin/bash
# CLI test of issue 12 §4: an assimp model's references stay inside its folder unless
# --allow-external allows more (import, info, export, and the help of every command that opens
# scenes), refusals never echo file content, and --list-maps escapes entry names. $1 is the
# sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"
data="$(cd "$(dirname "$0")/../data" && pwd)"
model="$data/confine/model"
secret="$data/confine/secret"

# nothing of the secret files in what the command said
no_secret() {
    for f in "$tmp/out" "$tmp/err"; do
        hasnt "SECRET" "$f"
        hasnt "root:x" "$f"
        if grep -q $'\x1b' "$f"; then fail "an escape byte in $f"; fi
    done
}

# ---- refused: '../' buffer and material library, for import, info and export ----
for m in up_buffer.gltf up_mtllib.obj; do
    expect 1 "$SL" import "$model/$m" -o "$tmp/x.slscene" --quiet
    has "outside the model's folder $model/" "$tmp/err"
    has "refused" "$tmp/err"
    has "\-\-allow-external" "$tmp/err"
    no_secret
    [ ! -e "$tmp/x.slscene" ] || fail "import wrote $tmp/x.slscene"
    expect 1 "$SL" info "$model/$m"
    has "outside the model's folder" "$tmp/err"
    no_secret
    expect 1 "$SL" export "$model/$m" "$tmp/x.obj" --quiet
    has "outside the model's folder" "$tmp/err"
    no_secret
    [ ! -e "$tmp/x.obj" ] || fail "export wrote $tmp/x.obj"
done
expect 1 "$SL" import "$model/up_buffer.gltf" -o "$tmp/x.slscene" --quiet
has "reference '../secret/tri.bin' resolves to $secret/tri.bin" "$tmp/err"

# a symlink escaping the folder, made here
mkdir "$tmp/m"
cp "$model/inside.gltf" "$tmp/m/inside.gltf"
ln -s "$secret/tri.bin" "$tmp/m/tri.bin"
expect 1 "$SL" info "$tmp/m/inside.gltf" --json
has "resolves to $secret/tri.bin" "$tmp/err"
hasnt '"objects"' "$tmp/out"

# ---- allowed ----
expect 0 "$SL" import "$model/up_buffer.gltf" -o "$tmp/x.slscene" --quiet --allow-external "$secret"
expect 0 "$SL" info "$tmp/x.slscene" --json
has '"bounds_max":\[7,0,7\]' "$tmp/out"
expect 0 "$SL" info "$model/up_mtllib.obj" --allow-external "$secret/secret.mtl"
expect 0 "$SL" info "$tmp/m/inside.gltf" --allow-external="$secret" --allow-external "$data"
expect 1 "$SL" info "$model/inside.gltf" --allow-external /no/such/folder
has "/no/such/folder" "$tmp/err"
expect 0 "$SL" export "$model/up_buffer.gltf" "$tmp/x.obj" --quiet --allow-external "$secret"
expect 2 "$SL" info "$model/inside.gltf" --allow-external
has "needs a value" "$tmp/err"
# inside the folder needs nothing
expect 0 "$SL" import "$model/inside.obj" -o "$tmp/y.slscene" --quiet
expect 0 "$SL" info "$model/inside.gltf"

# the other commands that open scenes refuse and allow the same way
expect 1 "$SL" path gen "$model/up_buffer.gltf" -o "$tmp/p.txt" --kind flyover --quiet
has "outside the model's folder" "$tmp/err"
expect 0 "$SL" path gen "$model/up_buffer.gltf" -o "$tmp/p.txt" --kind flyover --quiet --allow-external "$secret"
expect 1 "$SL" pvs build "$model/up_buffer.gltf" -o "$tmp/p.slpvs" --quiet
has "outside the model's folder" "$tmp/err"
expect 1 "$SL" radar "$model/up_mtllib.obj"
has "outside the model's folder" "$tmp/err"
no_secret

# every command whose scene argument can be an assimp file takes the option
for c in import info export bench render radar "path gen" "path random" "pvs build" "pvs query" "pvs verify"; do
    expect 0 "$SL" $c --help
    has "\-\-allow-external PATH" "$tmp/out"
done

# ---- --list-maps escapes entry names (tests/data/odd-names.pk3, made with libzip) ----
expect 0 "$SL" import "$data/odd-names.pk3" --list-maps
[ "$(wc -l <"$tmp/out")" -eq 6 ] || fail "expected 6 lines"
has 'maps/cr\\x0dret\\x09tab\.bsp' "$tmp/out"
has 'maps/new\\x0aline\.bsp' "$tmp/out"
has 'maps/c1\\xc2\\x9b\.bsp' "$tmp/out"
has 'maps/back\\\\slash\.bsp' "$tmp/out"
has 'maps/café\.bsp' "$tmp/out"
if grep -q $'\r' "$tmp/out" || grep -q $'\xc2\x9b' "$tmp/out"; then fail "raw control bytes in the listing"; fi
expect 0 "$SL" import "$data/odd-names.pk3" --list-maps --json
has '"maps/new\\u000aline\.bsp"' "$tmp/out"
has '"maps/c1\\u009b\.bsp"' "$tmp/out"
has '"count":6' "$tmp/out"
if command -v python3 >/dev/null; then
    python3 -c 'import json, sys; d = json.load(open(sys.argv[1])); assert len(d["maps"]) == 6' "$tmp/out" ||
        fail "--list-maps --json is not valid JSON"
fi
# ... and so do the messages that name an entry (the map reader's, against "archive:entry")
expect 1 "$SL" import "$data/odd-names.pk3" --map $'maps/new\nline.bsp' -o "$tmp/x.slscene"
has 'odd-names.pk3:maps/new\\x0aline\.bsp: offset 0' "$tmp/err"
[ "$(wc -l <"$tmp/err")" -eq 1 ] || fail "a raw newline in the message"
expect 1 "$SL" import "$data/odd-names.pk3" --map $'maps/c1\xc2\x9b.bsp' -o "$tmp/x.slscene"
has 'odd-names.pk3:maps/c1\\xc2\\x9b\.bsp: offset 0' "$tmp/err"
if grep -q $'\xc2\x9b' "$tmp/err"; then fail "a raw C1 control in the message"; fi
echo "ok"
