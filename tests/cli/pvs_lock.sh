#!/bin/bash
# CLI test of the bake lock: while one `pvs build` runs (held stopped with SIGSTOP, so the test
# does not depend on timing), a second bake of the same output is refused with "another bake of
# OUT is running (pid N)", plain and with --resume (which would otherwise have appended to the
# running bake's journal); the first bake then finishes as if nothing happened, and leaves no lock
# or journal behind. A failed bake (a method that cannot prepare for the scene) leaves no
# checkpoint, and the next bake of that output runs. $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"
pid=
# never leave a stopped bake behind, whatever fails
trap '[ -n "$pid" ] && { kill -CONT $pid; kill -9 $pid; } 2>/dev/null; rm -rf "$tmp"' EXIT

# the cells near a two-camera walk (4 cells): the bakes stay short, under the sanitizers too
cat >"$tmp/walk.txt" <<'PATH'
# sightline-path 1
0 0 0 1.7 0 0 0
1 1 0 1.7 0 0 0
PATH
common=(--city tiny --cell-size 60 --threads 1 --quiet --along "$tmp/walk.txt" --radius 10)
out="$tmp/a.slpvs"

# ---- a failed bake leaves nothing that blocks the next one ----
expect 1 "$SL" pvs build "${common[@]}" -o "$out" --method mappvs
has "no BSP data" "$tmp/err"
[ ! -e "$out.ckpt" ] || fail "a bake that failed in prepare left a checkpoint"
[ ! -e "$out.ckpt.lock" ] || fail "a failed bake left its lock file"

# ---- two bakes of one output ----
"$SL" pvs build "${common[@]}" -o "$out" >"$tmp/a.out" 2>"$tmp/a.err" &
pid=$!
# the lock is taken (and the holder's pid written) before the method is prepared
for _ in $(seq 1 1000); do
    [ -s "$out.ckpt.lock" ] && break
    kill -0 $pid 2>/dev/null || break
    sleep 0.01
done
kill -STOP $pid
[ -s "$out.ckpt.lock" ] || fail "no lock file while the bake runs"
expect 1 "$SL" pvs build "${common[@]}" -o "$out"
has "another bake of $out is running (pid $pid)" "$tmp/err"
hasnt "interrupted" "$tmp/err"
expect 1 "$SL" pvs build "${common[@]}" -o "$out" --resume
has "another bake of $out is running (pid $pid)" "$tmp/err"
kill -CONT $pid
for _ in $(seq 1 1200); do
    kill -0 $pid 2>/dev/null || break
    sleep 0.1
done
kill -0 $pid 2>/dev/null && fail "the first bake did not finish in 120 s"
wait $pid
rc=$?
pid=
[ $rc -eq 0 ] || { cat "$tmp/a.err"; fail "the first bake failed (status $rc) after the refused ones"; }
expect 0 "$SL" pvs verify "$out"
[ ! -e "$out.ckpt" ] || fail "the journal was left after success"
[ ! -e "$out.ckpt.lock" ] || fail "the lock file was left after success"
# and the lock is free again
expect 3 "$SL" pvs build "${common[@]}" -o "$out" --stop-after 1
echo "ok"
