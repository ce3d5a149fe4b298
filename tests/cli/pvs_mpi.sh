#!/bin/bash
# CLI test of `sightline pvs`: help and usage errors; a bake of the tiny city with one process and
# with two MPI processes (mpiexec -n 2) gives the same bytes; a bake stopped after a few cells
# (--stop-after) and one killed with SIGKILL both resume (--resume) to the same bytes; info, query
# and verify (checksums, and zero misses against the region oracle on a few cells); a bake of the
# cells along a camera path (--along) holds only those cells, and a point far from it is in none;
# a corrupted file is refused. $1 is the sightline binary; mpiexec comes from $SL_MPIEXEC or the
# PATH. Process 0 of an MPI bake bakes too: the 2-process bake exercises both of its roles.
set -u
SL="$1"
MPIEXEC="${SL_MPIEXEC:-$(command -v mpiexec || true)}"
. "$(dirname "$0")/lib/common.sh"
# the sanitizer build: MPICH keeps allocations until exit
export ASAN_OPTIONS="${ASAN_OPTIONS:-}:detect_leaks=0"

# ---- help and usage errors ----
expect 0 "$SL" pvs --help
has "examples:" "$tmp/out"
for a in build info query verify; do
    expect 0 "$SL" pvs $a --help
    has "usage: sightline pvs $a" "$tmp/out"
    has "example" "$tmp/out"
done
expect 2 "$SL" pvs
expect 2 "$SL" pvs bogus
has "unknown action" "$tmp/err"
expect 2 "$SL" pvs build --city tiny
has "missing -o" "$tmp/err"
expect 2 "$SL" pvs build --city tiny -o "$tmp/x.slpvs" --bogus
has "unknown option --bogus" "$tmp/err"
expect 2 "$SL" pvs build --city tiny -o "$tmp/x.slpvs" --method nope
has "unknown PVS method 'nope'" "$tmp/err"
expect 2 "$SL" pvs build --city tiny -o "$tmp/x.slpvs" --options eps=-1
has "eps" "$tmp/err"
expect 2 "$SL" pvs build --city tiny -o "$tmp/x.slpvs" --cells hexagons
expect 2 "$SL" pvs query "$tmp/x.slpvs"
has "exactly one of" "$tmp/err"
expect 1 "$SL" pvs info "$tmp/missing.slpvs"
[ ! -e "$tmp/x.slpvs" ] || fail "a failed command left an output file"

# coarse cells keep the bake short (130 cells); under the sanitizers (several times slower) the
# bakes take the 17 cells within 40 m of a point (the --along section uses base itself)
base=(--city tiny --cell-size 40 --threads 1 --quiet --method sample)
common=("${base[@]}")
if [ -n "${SL_SANITIZED:-}" ]; then
    printf '# sightline-path 1\n0 0 0 1.7 0 0 0\n' >"$tmp/point.txt"
    common+=(--along "$tmp/point.txt" --radius 40)
fi

# ---- one process ----
expect 0 "$SL" pvs build "${common[@]}" -o "$tmp/one.slpvs"
has "streets cells, method sample" "$tmp/out"
[ ! -e "$tmp/one.slpvs.ckpt" ] || fail "the checkpoint was not removed after success"

# ---- two MPI processes: the same bytes ----
[ -n "$MPIEXEC" ] || fail "mpiexec not found (install mpich)"
expect 0 timeout 300 "$MPIEXEC" -n 2 "$SL" pvs build "${common[@]}" -o "$tmp/two.slpvs"
has "2 process(es)" "$tmp/out"
cmp "$tmp/one.slpvs" "$tmp/two.slpvs" || fail "2-process bake differs from the 1-process bake"

# ---- resume after --stop-after (threads and MPI) ----
expect 3 "$SL" pvs build "${common[@]}" -o "$tmp/stop.slpvs" --stop-after 7
has "stopped after 7" "$tmp/err"
[ -s "$tmp/stop.slpvs.ckpt" ] || fail "no checkpoint after --stop-after"
[ ! -e "$tmp/stop.slpvs" ] || fail "an interrupted bake left an output file"
expect 1 "$SL" pvs build "${common[@]}" -o "$tmp/stop.slpvs"
has "continue it (--resume), or delete it to bake afresh: rm -- " "$tmp/err"
expect 1 "$SL" pvs build "${common[@]}" -o "$tmp/stop.slpvs" --resume --options eps=2
has "belongs to another bake" "$tmp/err"
expect 0 timeout 300 "$MPIEXEC" -n 2 "$SL" pvs build "${common[@]}" -o "$tmp/stop.slpvs" --resume
has "(7 resumed)" "$tmp/out"
cmp "$tmp/one.slpvs" "$tmp/stop.slpvs" || fail "resumed bake differs from the uninterrupted one"
# --stop-after under MPI: the driver counts the sets it stores through the public bake session
# (sl_bake_session_baked); cells already out when it stops are kept, so a few more may be done
expect 3 timeout 300 "$MPIEXEC" -n 2 "$SL" pvs build "${common[@]}" -o "$tmp/mstop.slpvs" --stop-after 3
has "stopped after" "$tmp/err"
[ -s "$tmp/mstop.slpvs.ckpt" ] && [ ! -e "$tmp/mstop.slpvs" ] || fail "an MPI bake stopped early left no journal, or a file"
expect 0 timeout 300 "$MPIEXEC" -n 2 "$SL" pvs build "${common[@]}" -o "$tmp/mstop.slpvs" --resume
cmp "$tmp/one.slpvs" "$tmp/mstop.slpvs" || fail "resumed MPI bake differs from the uninterrupted one"

# ---- resume after SIGKILL in the middle of the bake ----
"$SL" pvs build "${common[@]}" -o "$tmp/kill.slpvs" >/dev/null 2>&1 &
pid=$!
for _ in $(seq 1 400); do
    size=$(stat -c %s "$tmp/kill.slpvs.ckpt" 2>/dev/null || echo 0)
    [ "$size" -gt 1000 ] && break
    sleep 0.02
done
kill -9 $pid 2>/dev/null
wait $pid 2>/dev/null
if [ -e "$tmp/kill.slpvs" ]; then
    echo "note: the bake finished before it could be killed; the kill case was not exercised"
else
    # a torn last record must not matter either
    truncate -s -3 "$tmp/kill.slpvs.ckpt"
    expect 0 "$SL" pvs build "${common[@]}" -o "$tmp/kill.slpvs" --resume
    has "resumed)" "$tmp/out"
    cmp "$tmp/one.slpvs" "$tmp/kill.slpvs" || fail "bake resumed after SIGKILL differs"
fi

# ---- info, query, verify ----
expect 0 "$SL" pvs info "$tmp/one.slpvs" --json
has '"method":"sample"' "$tmp/out"
has '"cells":' "$tmp/out"
expect 0 "$SL" pvs query "$tmp/one.slpvs" --cell 3 --ids
has "cell 3" "$tmp/out"
expect 1 "$SL" pvs query "$tmp/one.slpvs" --point 1e6,1e6,1 --json
has '"cell":null' "$tmp/out"
expect 1 "$SL" pvs query "$tmp/one.slpvs" --cell 99999999
expect 0 "$SL" pvs verify "$tmp/one.slpvs"
has "ok" "$tmp/out"
expect 0 "$SL" pvs verify "$tmp/one.slpvs" --city tiny --cells 3 --face-size 64 --spacing 4 --samples 4 --json
has '"misses":0' "$tmp/out"
expect 1 "$SL" pvs verify "$tmp/one.slpvs" --city small --cells 1
has "not baked for this scene" "$tmp/err"

# ---- only the cells along a path ----
cat >"$tmp/walk.txt" <<'PATH'
# sightline-path 1
0 0 0 1.7 0 0 0
1 1 0 1.7 0 0 0
PATH
expect 2 "$SL" pvs build "${base[@]}" -o "$tmp/along.slpvs" --along "$tmp/walk.txt" --radius -1
has "radius" "$tmp/err"
expect 1 "$SL" pvs build "${base[@]}" -o "$tmp/along.slpvs" --along "$tmp/missing.txt"
[ ! -e "$tmp/along.slpvs" ] || fail "a failed --along bake left an output file"
expect 0 "$SL" pvs build "${base[@]}" -o "$tmp/along.slpvs" --along "$tmp/walk.txt" --radius 30 --json
all=$("$SL" pvs info "$tmp/one.slpvs" --json | grep -o '"cells":[0-9]*' | head -1 | cut -d: -f2)
near=$(grep -o '"cells":[0-9]*' "$tmp/out" | head -1 | cut -d: -f2)
[ -n "$near" ] && [ "$near" -gt 0 ] && [ "$near" -lt "$all" ] || fail "--along kept $near of $all cells"
expect 0 "$SL" pvs query "$tmp/along.slpvs" --point 0.5,0,1.7 --json
has '"cell":[0-9]' "$tmp/out"
expect 1 "$SL" pvs query "$tmp/along.slpvs" --point 150,150,1.7 --json
has '"cell":null,"nearest_cell":' "$tmp/out"
expect 1 "$SL" pvs build "${base[@]}" -o "$tmp/far.slpvs" --along "$tmp/walk.txt" --radius 0 --eye-min 50 --eye-max 60
has "no view cell lies within" "$tmp/err"
expect 0 "$SL" pvs verify "$tmp/along.slpvs" --city tiny --cells 2 --face-size 64 --spacing 4 --samples 4 --json
has '"misses":0' "$tmp/out"

# ---- a corrupted file is refused with the offset ----
cp "$tmp/one.slpvs" "$tmp/bad.slpvs"
size=$(stat -c %s "$tmp/bad.slpvs")
printf '\xff' | dd of="$tmp/bad.slpvs" bs=1 seek=$((size - 100)) conv=notrunc 2>/dev/null
if "$SL" pvs info "$tmp/bad.slpvs" >"$tmp/out" 2>"$tmp/err"; then
    expect 1 "$SL" pvs verify "$tmp/bad.slpvs"
fi
has "offset" "$tmp/err"
echo "ok"
