#!/bin/bash
# CLI test of `sightline occlusion replay`: help, usage errors (exit 2), a frame of the tiny city
# recorded by the hzb culler (`sightline bench --method-options hzb:record=...`) replayed on every
# available instruction-set path, as text and --json, and hostile copies (missing, truncated,
# wrong magic, a flipped recorded answer, random bytes) failing with exit 1 and a message, never a
# crash. $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

# ---- help and usage errors ----
expect 0 "$SL" occlusion --help
has "usage: sightline occlusion replay" "$tmp/out"
has "examples:" "$tmp/out"
has "record=" "$tmp/out"
expect 0 "$SL" occlusion replay --help
has "--isa" "$tmp/out"
expect 2 "$SL" occlusion
expect 2 "$SL" occlusion bogus
has "unknown action 'bogus' (replay; see sightline occlusion --help)" "$tmp/err"
expect 2 "$SL" occlusion replay
has "missing FILE" "$tmp/err"
expect 2 "$SL" occlusion replay a.rec b.rec
expect 2 "$SL" occlusion replay a.rec --isa mmx
has "expected scalar, sse41, avx2, avx512, auto or all" "$tmp/err"
expect 2 "$SL" occlusion replay a.rec --isa
expect 2 "$SL" occlusion replay a.rec --bogus
has "unknown option --bogus" "$tmp/err"
expect 1 "$SL" occlusion replay "$tmp/missing.rec"
has "missing.rec" "$tmp/err"

# ---- record a frame (the third cull of a short walk) and replay it ----
rec="$tmp/frame.rec"
expect 0 "$SL" bench city:tiny --walk 4 --methods hzb --method-options "hzb:record=$rec,debug_frame=2" \
    --out "$tmp/bench"
[ -s "$rec" ] || fail "no recording written"
expect 0 "$SL" occlusion replay "$rec"
has "batches" "$tmp/out"
has "scalar  ok" "$tmp/out"
# one line per available path, all with the scalar path's depth hash
hash=$(awk '$1 == "scalar" { print $NF }' "$tmp/out")
[ -n "$hash" ] || fail "no scalar depth hash"
[ "$(grep -c "ok  depth hash $hash" "$tmp/out")" -eq "$(grep -c "depth hash" "$tmp/out")" ] ||
    fail "paths disagree on the depth hash"
expect 0 "$SL" occlusion replay "$rec" --isa scalar --json
has '"ok":true' "$tmp/out"
has '"isa":"scalar"' "$tmp/out"
has '"mismatches":0' "$tmp/out"
has "\"depth_hash\":\"$hash\"" "$tmp/out"
batches=$(sed -n 's/.*"batches":\([0-9]*\).*/\1/p' "$tmp/out")
queries=$(sed -n 's/.*"queries":\([0-9]*\).*/\1/p' "$tmp/out")
[ "${batches:-0}" -gt 0 ] || fail "no batches recorded"
[ "${queries:-0}" -gt 0 ] || fail "no queries recorded"
expect 0 "$SL" occlusion replay "$rec" --isa auto

# ---- hostile copies: exit 1 with a message, no crash ----
size=$(stat -c %s "$rec")
head -c $((size / 2)) "$rec" >"$tmp/trunc.rec"
expect 1 "$SL" occlusion replay "$tmp/trunc.rec"
has "trunc.rec" "$tmp/err"
{ printf 'NOTAREC!'; tail -c +9 "$rec"; } >"$tmp/magic.rec"
expect 1 "$SL" occlusion replay "$tmp/magic.rec"
: >"$tmp/empty.rec"
expect 1 "$SL" occlusion replay "$tmp/empty.rec"
head -c 4096 /dev/urandom >"$tmp/random.rec"
expect 1 "$SL" occlusion replay "$tmp/random.rec"
# the last record of a frame is a query whose answer is its last u32, just before the 8-byte
# checksum: flip it between visible (0) and occluded (1); the checksum no longer matches, so the
# file is refused as damaged (tests/test_occ_record.c replays a resealed copy as a mismatch)
last=$(od -An -tu4 -j $((size - 12)) -N4 "$rec" | tr -d ' ')
if [ "$last" = 0 ] || [ "$last" = 1 ]; then
    cp "$rec" "$tmp/flip.rec"
    printf "\\x0$((1 - last))" | dd of="$tmp/flip.rec" bs=1 seek=$((size - 12)) conv=notrunc status=none
    expect 1 "$SL" occlusion replay "$tmp/flip.rec" --json --isa scalar
    has "checksum mismatch" "$tmp/err"
fi
echo "occlusion CLI: ok"
