#!/bin/bash
# CLI test of the MPI chunk lease: in a 3-process bake (mpiexec -n 3) one worker process is
# stopped with SIGSTOP in the middle of the bake, alive and holding a chunk. With --lease 2 its
# cells are handed to another process after 2 s without a result, the bake completes (the file is
# written while the process is still stopped), byte-identical to a one-process bake, and the log
# says what happened; once the stopped process is continued (SIGCONT) the job ends cleanly.
# Everything is bounded in time, and nothing is left running or stopped. $1 is the sightline
# binary; mpiexec (MPICH) comes from $SL_MPIEXEC or the PATH.
set -u
SL="$1"
MPIEXEC="${SL_MPIEXEC:-$(command -v mpiexec || true)}"
. "$(dirname "$0")/lib/common.sh"
export ASAN_OPTIONS="${ASAN_OPTIONS:-}:detect_leaks=0" # MPICH keeps allocations until exit
job= victim=
cleanup() {
    [ -n "$victim" ] && kill -CONT "$victim" 2>/dev/null
    [ -n "$job" ] && kill -9 "$job" 2>/dev/null
    [ -n "$victim" ] && kill -9 "$victim" 2>/dev/null
    rm -rf "$tmp"
}
trap cleanup EXIT
[ -n "$MPIEXEC" ] || fail "mpiexec not found (install mpich)"

common=(--city tiny --cell-size 40 --threads 1 --quiet)
if [ -n "${SL_SANITIZED:-}" ]; then
    # several times slower: the cells within 40 m of a point only (a few dozen)
    printf '# sightline-path 1\n0 0 0 1.7 0 0 0\n' >"$tmp/walk.txt"
    common+=(--along "$tmp/walk.txt" --radius 40)
fi
expect 2 "$SL" pvs build "${common[@]}" -o "$tmp/x.slpvs" --lease -1
has "lease" "$tmp/err"
expect 0 "$SL" pvs build "${common[@]}" -o "$tmp/one.slpvs"

out="$tmp/lease.slpvs"
"$MPIEXEC" -n 3 "$SL" pvs build "${common[@]}" -o "$out" --lease 2 >"$tmp/job.out" 2>"$tmp/job.err" &
job=$!
# the bake is under way once the journal holds a few cells; process 0 is the lock holder
for _ in $(seq 1 3000); do
    size=$(stat -c %s "$out.ckpt" 2>/dev/null || echo 0)
    [ "$size" -gt 600 ] && break
    kill -0 $job 2>/dev/null || break
    sleep 0.01
done
[ ! -e "$out" ] || fail "the bake finished before a process could be stopped"
rank0=$(head -1 "$out.ckpt.lock" 2>/dev/null)
# the ranks are the children of hydra's proxy, the child of mpiexec
ranks=
for proxy in $(ps -o pid= --ppid $job); do ranks="$ranks $(ps -o pid= --ppid "$proxy")"; done
for p in $ranks; do
    [ "$p" != "$rank0" ] && { victim=$p; break; }
done
[ -n "$victim" ] || fail "no worker process found (ranks:$ranks, process 0: $rank0)"
kill -STOP "$victim"
# the others finish the bake, the stopped process's cells included
for _ in $(seq 1 1200); do
    [ -e "$out" ] && break
    kill -0 $job 2>/dev/null || break
    sleep 0.1
done
cp "$tmp/job.err" "$tmp/err"
[ -e "$out" ] || fail "no file 120 s after a process was stopped (the bake stalled)"
cmp "$tmp/one.slpvs" "$out" || fail "the bake with a stopped process differs from the one-process bake"
has "has sent nothing for" "$tmp/err"
has "the first result to arrive is kept" "$tmp/err"
kill -0 "$victim" 2>/dev/null || fail "the stopped process is gone"
# continue it: it reports its chunk (dropped: the cells are done), and the job ends
kill -CONT "$victim"
for _ in $(seq 1 600); do
    kill -0 $job 2>/dev/null || break
    sleep 0.1
done
kill -0 $job 2>/dev/null && fail "the job did not end within 60 s of the stopped process being continued"
wait $job
rc=$?
job= victim=
cp "$tmp/job.out" "$tmp/out"
cp "$tmp/job.err" "$tmp/err"
[ $rc -eq 0 ] || fail "the job ended with status $rc"
has "3 process(es)" "$tmp/out"
cmp "$tmp/one.slpvs" "$out" || fail "the file changed when the stopped process came back"
[ ! -e "$out.ckpt" ] && [ ! -e "$out.ckpt.lock" ] || fail "a journal or lock was left after success"
echo "ok"
