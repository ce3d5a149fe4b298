#!/bin/bash
# CLI test of import determinism (issue 12, §3b): importing one file by three spellings of its
# path (plain, ./, absolute, and from another directory) gives byte-identical .slscene files; the
# scene records the base name and the XXH3-64 of the bytes read ("source", "source.xxh3"), never
# the path as typed. An OBJ (assimp), a Quake III .bsp and the same map inside a .pk3 (when the
# OpenArena data is installed). Also: a .slpvs cut short is refused with the file, the offset and
# "truncated: expected N bytes, file has M". $1 is the sightline binary.
set -u
SL="$(cd "$(dirname "$1")" && pwd)/$(basename "$1")"
. "$(dirname "$0")/lib/common.sh"
data="$(cd "$(dirname "$0")/../data" && pwd)"

# same_bytes OUT...: every file has the bytes of the first
same_bytes() {
    local first=$1
    shift
    for f in "$@"; do
        cmp -s "$first" "$f" || fail "$f differs from $first"
    done
}

# import_three DIR FILE [ARGS...]: import DIR/FILE as FILE, ./FILE and DIR/FILE (absolute) from
# DIR, and as DIR/FILE from elsewhere, into $tmp/o1..o4.slscene
import_three() {
    local dir=$1 file=$2
    shift 2
    (cd "$dir" && expect 0 "$SL" import "$file" "$@" --quiet -o "$tmp/o1.slscene") || exit 1
    (cd "$dir" && expect 0 "$SL" import "./$file" "$@" --quiet -o "$tmp/o2.slscene") || exit 1
    (cd "$dir" && expect 0 "$SL" import "$dir/$file" "$@" --quiet -o "$tmp/o3.slscene") || exit 1
    (cd / && expect 0 "$SL" import "$dir//$file" "$@" --quiet -o "$tmp/o4.slscene") || exit 1
    same_bytes "$tmp/o1.slscene" "$tmp/o2.slscene" "$tmp/o3.slscene" "$tmp/o4.slscene"
}

# hash_of FILE: XXH3-64 of FILE as 16 hex digits (xxhsum -H3 when installed)
hash_of() { command -v xxhsum >/dev/null && xxhsum -H3 "$1" | grep -o '[0-9a-f]\{16\}' | head -1; }

# ---- an OBJ through assimp ----
mkdir -p "$tmp/obj"
cp "$data/groups.obj" "$data/groups.mtl" "$tmp/obj/"
import_three "$tmp/obj" groups.obj
has "groups.obj" "$tmp/o1.slscene"
hasnt "$tmp" "$tmp/o1.slscene"
h=$(hash_of "$tmp/obj/groups.obj")
if [ -n "$h" ]; then has "$h" "$tmp/o1.slscene"; fi

# ---- a Quake III map, alone and in its archive ----
pk3=/usr/share/games/openarena/baseoa/pak1-maps.pk3
if [ -r "$pk3" ] && command -v unzip >/dev/null; then
    mkdir -p "$tmp/q3"
    unzip -p "$pk3" maps/oa_dm1.bsp >"$tmp/q3/oa_dm1.bsp" || fail "cannot extract oa_dm1.bsp"
    import_three "$tmp/q3" oa_dm1.bsp
    has "oa_dm1.bsp" "$tmp/o1.slscene"
    hasnt "$tmp" "$tmp/o1.slscene"
    h=$(hash_of "$tmp/q3/oa_dm1.bsp")
    if [ -n "$h" ]; then has "$h" "$tmp/o1.slscene"; fi
    cp "$pk3" "$tmp/q3/maps.pk3"
    import_three "$tmp/q3" maps.pk3 --map oa_dm1
    has "maps.pk3:maps/oa_dm1.bsp" "$tmp/o1.slscene"
    hasnt "$tmp" "$tmp/o1.slscene"
else
    echo "note: $pk3 or unzip missing: Quake III imports not checked"
fi

# ---- a truncated .slpvs ----
cp "$(dirname "$0")/../../fuzz/seeds/slpvs/tiny_grid_adjustable.slpvs" "$tmp/t.slpvs" || fail "no seed .slpvs"
expect 0 "$SL" pvs info "$tmp/t.slpvs"
size=$(stat -c %s "$tmp/t.slpvs")
head -c 1000 "$tmp/t.slpvs" >"$tmp/cut.slpvs"
expect 1 "$SL" pvs info "$tmp/cut.slpvs"
has "$tmp/cut.slpvs: offset 40: truncated: expected $size bytes, file has 1000" "$tmp/err"
expect 1 "$SL" pvs verify "$tmp/cut.slpvs"
has "truncated: expected $size bytes, file has 1000" "$tmp/err"
: >"$tmp/empty.slpvs"
expect 1 "$SL" pvs info "$tmp/empty.slpvs"
has "offset 0: truncated" "$tmp/err"

echo "ok"
