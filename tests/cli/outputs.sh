#!/bin/bash
# CLI test of where outputs go (issue 12, §3): an output that is a FIFO, /dev/null, /dev/stdout or
# a symbolic link is written through or behind the link, never replaced by a regular file; an
# output that is one of the inputs is refused by every command that writes; a FIFO given as an
# input is refused at once (bounded by `timeout`, as it blocked open(2) for ever); stale
# temporaries of killed writers are removed by the next write; a bench that fails midway leaves
# the previous run's folder exactly as it was, and `--out .` keeps the user's other files.
# $1 is the sightline binary. /dev/null is only written to once a FIFO of our own has survived.
set -u
SL="$1"
case "$SL" in /*) ;; *) SL="$PWD/$SL" ;; esac # the test changes folder
. "$(dirname "$0")/lib/common.sh"

devnull_ok() { [ -c /dev/null ] || { echo "FAIL: /dev/null is no longer a character device"; exit 1; }; }

expect 0 "$SL" gen city --preset tiny -o "$tmp/city.slscene" --quiet
expect 0 "$SL" path gen "$tmp/city.slscene" --kind walk --frames 4 -o "$tmp/walk.txt" --quiet

# ---- a FIFO as an output: written through, still a FIFO ----
mkfifo "$tmp/out.fifo"
timeout 10 cat "$tmp/out.fifo" >"$tmp/from_fifo" &
reader=$!
expect 0 timeout 10 "$SL" path gen "$tmp/city.slscene" --kind walk --frames 4 -o "$tmp/out.fifo" --quiet
wait "$reader" || fail "the FIFO's reader failed"
[ -p "$tmp/out.fifo" ] || fail "the FIFO output was replaced by a regular file"
cmp -s "$tmp/from_fifo" "$tmp/walk.txt" || fail "the FIFO's reader did not get the path file"
ls "$tmp" | grep -q '\.tmp\.' && fail "a temporary was left beside the FIFO"

# ---- only now: /dev/null and /dev/stdout stay what they are ----
devnull_ok
expect 0 "$SL" path gen "$tmp/city.slscene" --kind walk --frames 4 -o /dev/null --quiet
devnull_ok
expect 0 "$SL" gen city --preset tiny -o /dev/null --quiet
devnull_ok
# stdout a pipe: the path file comes through it
"$SL" path gen "$tmp/city.slscene" --kind walk --frames 4 -o /dev/stdout --quiet 2>"$tmp/err" | cat >"$tmp/piped"
grep -q "# sightline-path 1" "$tmp/piped" || fail "-o /dev/stdout did not write to the pipe"
[ -L /dev/stdout ] || [ -e /dev/stdout ] || fail "/dev/stdout is gone"
# stdout a file: written through the descriptor (no rename, the file stays the one opened)
: >"$tmp/redirected"
ino=$(stat -c %i "$tmp/redirected")
"$SL" path gen "$tmp/city.slscene" --kind walk --frames 4 -o /dev/stdout --quiet >"$tmp/redirected" 2>"$tmp/err" ||
    fail "-o /dev/stdout into a file failed"
[ "$(stat -c %i "$tmp/redirected")" = "$ino" ] || fail "-o /dev/stdout replaced the redirected file"
head -1 "$tmp/redirected" | grep -q "# sightline-path 1" || fail "-o /dev/stdout did not write the path file"
devnull_ok

# ---- symbolic links: the link stays, its target gets the file ----
mkdir "$tmp/real"
echo old >"$tmp/real/target.txt"
ln -s real/target.txt "$tmp/link.txt"
expect 0 "$SL" path gen "$tmp/city.slscene" --kind walk --frames 4 -o "$tmp/link.txt" --quiet
[ -L "$tmp/link.txt" ] || fail "the symbolic link was replaced by a regular file"
cmp -s "$tmp/real/target.txt" "$tmp/walk.txt" || fail "the link's target did not get the path file"
ls "$tmp/real" | grep -q '\.tmp\.' && fail "a temporary was left beside the target"
ln -s real/new.slscene "$tmp/dangling.slscene"
expect 0 "$SL" gen city --preset tiny -o "$tmp/dangling.slscene" --quiet
[ -L "$tmp/dangling.slscene" ] || fail "the dangling link was replaced"
cmp -s "$tmp/real/new.slscene" "$tmp/city.slscene" || fail "the dangling link's target was not created"
# a directory is refused, by name, before any work (a pvs bake leaves no checkpoint beside it)
mkdir "$tmp/adir"
expect 2 "$SL" path gen "$tmp/city.slscene" --kind walk --frames 4 -o "$tmp/adir" --quiet
has "adir: cannot write: it is a directory" "$tmp/err"
[ -d "$tmp/adir" ] || fail "the directory output was touched"
expect 2 "$SL" pvs build "$tmp/city.slscene" -o "$tmp/adir" --quiet
has "adir: cannot write: it is a directory" "$tmp/err"
[ -e "$tmp/adir.ckpt" ] && fail "a checkpoint was left beside the directory output"
expect 2 "$SL" pvs build "$tmp/city.slscene" -o "$tmp/nodir/" --quiet
has "nodir/: cannot write: it names a directory" "$tmp/err"

# ---- an output that is an input: refused, whatever its spelling ----
cp "$tmp/city.slscene" "$tmp/keep.slscene"
ln -s city.slscene "$tmp/city-link.slscene"
ln "$tmp/city.slscene" "$tmp/city-hard.slscene"
for out in "$tmp/city.slscene" "$tmp/./city.slscene" "$tmp/city-link.slscene" "$tmp/city-hard.slscene"; do
    expect 2 "$SL" pvs build "$tmp/city.slscene" -o "$out" --quiet
    has "is the input file" "$tmp/err"
    expect 2 "$SL" path gen "$tmp/city.slscene" --kind walk --frames 4 -o "$out" --quiet
    has "is the input file" "$tmp/err"
    expect 2 "$SL" path random "$tmp/city.slscene" --count 3 -o "$out" --quiet
    has "is the input file" "$tmp/err"
    expect 2 "$SL" export "$tmp/city.slscene" "$out" --format obj
    has "is the input file" "$tmp/err"
    expect 2 "$SL" import "$tmp/city.slscene" -o "$out"
    expect 2 "$SL" radar "$tmp/city.slscene" -o "$out" --quiet
    has "is the input file" "$tmp/err"
done
(cd "$tmp" && expect 2 "$SL" path gen city.slscene --kind walk --frames 4 -o ./city.slscene --quiet) || exit 1
has "is the input file" "$tmp/err"
cmp -s "$tmp/city.slscene" "$tmp/keep.slscene" || fail "the input scene was changed"
expect 2 "$SL" pvs build "$tmp/city.slscene" --along "$tmp/walk.txt" -o "$tmp/walk.txt" --quiet
has "the output .*walk.txt is the input file" "$tmp/err"
expect 2 "$SL" pvs build "$tmp/city.slscene" -o "$tmp/x.slpvs" --checkpoint "$tmp/city.slscene" --quiet
has "is the input file" "$tmp/err"
cmp -s "$tmp/city.slscene" "$tmp/keep.slscene" || fail "the input scene was changed"

# ---- a FIFO as an input: refused at once, never waited on ----
mkfifo "$tmp/in.slscene" "$tmp/in.txt" "$tmp/in.slpvs" "$tmp/in.bsp" "$tmp/in.obj"
expect 1 timeout 10 "$SL" info "$tmp/in.slscene"
has "not a regular file" "$tmp/err"
expect 1 timeout 10 "$SL" path info "$tmp/in.txt"
has "not a regular file" "$tmp/err"
expect 1 timeout 10 "$SL" pvs info "$tmp/in.slpvs"
has "not a regular file" "$tmp/err"
expect 1 timeout 10 "$SL" info "$tmp/in.bsp"
has "not a regular file" "$tmp/err"
expect 1 timeout 10 "$SL" info "$tmp/in.obj"
has "not a regular file" "$tmp/err"
expect 1 timeout 10 "$SL" bench city:tiny --path "$tmp/in.txt" --methods vfc --no-plots --quiet --out "$tmp/b-fifo"
has "not a regular file" "$tmp/err"

# ---- stale temporaries of a killed writer go with the next write of that output ----
sleep 0 &
dead=$!
wait "$dead"
stale="$tmp/walk2.txt.tmp.$dead.0123456789abcdef"
other="$tmp/other.txt.tmp.$dead.0123456789abcdef"
alive="$tmp/walk2.txt.tmp.$$.0123456789abcdef"
echo partial >"$stale"
echo partial >"$other"
echo partial >"$alive"
expect 0 "$SL" path gen "$tmp/city.slscene" --kind walk --frames 4 -o "$tmp/walk2.txt" --quiet
[ -e "$stale" ] && fail "the stale temporary of a dead writer is still there"
[ -e "$other" ] || fail "the temporary of another output was removed"
[ -e "$alive" ] || fail "the temporary of a live process was removed"
rm -f "$other" "$alive"
# the same for a bake: an interrupted one, a temporary of its output left by a killed writer, and
# a successful --resume
expect 3 "$SL" pvs build "$tmp/city.slscene" --along "$tmp/walk.txt" --radius 1 --stop-after 1 -o "$tmp/w.slpvs" --quiet
stale="$tmp/w.slpvs.tmp.$dead.00000000deadbeef"
echo partial >"$stale"
expect 0 "$SL" pvs build "$tmp/city.slscene" --along "$tmp/walk.txt" --radius 1 --resume -o "$tmp/w.slpvs" --quiet
[ -s "$tmp/w.slpvs" ] || fail "the resumed bake wrote no file"
[ -e "$stale" ] && fail "a successful --resume left the stale temporary of its output"

# ---- a bench that fails midway leaves the previous run's folder exactly as it was ----
snapshot() { (cd "$1" && ls -A | sort && find . -type f | sort | xargs md5sum) >"$2"; }
B=(--walk 3 --methods vfc --map-size 64 --quiet)
expect 0 "$SL" bench city:tiny "${B[@]}" --out "$tmp/b"
echo "mine" >"$tmp/b/notes.txt"
snapshot "$tmp/b" "$tmp/b.before"
grep -q "city-tiny-1-cull-time.svg" "$tmp/b.before" || fail "the first bench wrote no plots"
# the first scene's plots are written, then the second scene fails to open
expect 1 "$SL" bench city:tiny "$tmp/missing.slscene" --walk 5 --methods vfc --map-size 64 --quiet --out "$tmp/b"
has "missing.slscene" "$tmp/err"
snapshot "$tmp/b" "$tmp/b.after"
cmp -s "$tmp/b.before" "$tmp/b.after" || { diff "$tmp/b.before" "$tmp/b.after"; fail "the failed bench changed the previous run's folder"; }
# a run that succeeds replaces the files it writes and nothing else
expect 0 "$SL" bench city:tiny --walk 5 --methods vfc --map-size 64 --quiet --out "$tmp/b/"
[ "$(cat "$tmp/b/notes.txt")" = mine ] || fail "the bench touched a file it did not write"
[ "$(rows "$tmp/b/frames.csv")" -eq 5 ] || fail "the second bench's tables did not replace the first's"
ls -A "$tmp/b" | grep -q sightline-run && fail "the run's temporary folder was left in the output folder"
# a failing run into a folder that does not exist leaves no folder
expect 1 "$SL" bench city:tiny "$tmp/missing.slscene" "${B[@]}" --out "$tmp/never/made"
[ -e "$tmp/never/made" ] && fail "a failed bench created its output folder"
ls "$tmp/never" | grep -q . && fail "a failed bench left a temporary folder beside its output folder"
# --out . keeps the user's other files, fails without a trace, and replaces only its own files
mkdir "$tmp/here"
echo "keep" >"$tmp/here/notes.txt"
echo "old table" >"$tmp/here/frames.csv"
mkdir "$tmp/here/data"
echo "keep too" >"$tmp/here/data/x.txt"
snapshot "$tmp/here" "$tmp/here.before"
(cd "$tmp/here" && expect 1 "$SL" bench city:tiny missing.slscene "${B[@]}" --out .) || exit 1
snapshot "$tmp/here" "$tmp/here.after"
cmp -s "$tmp/here.before" "$tmp/here.after" || fail "a failed bench --out . changed the folder"
(cd "$tmp/here" && expect 0 "$SL" bench city:tiny "${B[@]}" --out .) || exit 1
[ "$(cat "$tmp/here/notes.txt")" = keep ] && [ "$(cat "$tmp/here/data/x.txt")" = "keep too" ] ||
    fail "bench --out . touched the user's files"
[ "$(rows "$tmp/here/frames.csv")" -eq 3 ] || fail "bench --out . did not write its tables"
ls -A "$tmp/here" | grep -q sightline-run && fail "bench --out . left its temporary folder"
# the stage of a killed bench is removed by the next run into the same folder
mkdir "$tmp/here/.sightline-run.tmp.$dead.0123456789abcdef"
echo partial >"$tmp/here/.sightline-run.tmp.$dead.0123456789abcdef/frames.csv"
(cd "$tmp/here" && expect 0 "$SL" bench city:tiny "${B[@]}" --no-plots --out .) || exit 1
[ -e "$tmp/here/.sightline-run.tmp.$dead.0123456789abcdef" ] && fail "the stage of a killed bench is still there"
[ "$(cat "$tmp/here/notes.txt")" = keep ] || fail "bench --out . touched the user's files"

# ---- render and demo: a run that cannot finish moves nothing into the folder ----
# (a folder named like one of the run's files cannot be replaced: before, every file written up to
# that one replaced the previous run's)
mkdir -p "$tmp/r/frame-00001-id.png"
echo "old frame" >"$tmp/r/frame-00000-id.png"
snapshot "$tmp/r" "$tmp/r.before"
expect 1 "$SL" render city:tiny --path "$tmp/walk.txt" --frames 0:2 --width 32 --height 24 --images id --out "$tmp/r"
snapshot "$tmp/r" "$tmp/r.after"
cmp -s "$tmp/r.before" "$tmp/r.after" || fail "a failed render changed the previous run's folder"
has "frame-00001-id.png: it is a folder" "$tmp/err"
rmdir "$tmp/r/frame-00001-id.png"
expect 0 "$SL" render city:tiny --path "$tmp/walk.txt" --frames 0:2 --width 32 --height 24 --images id --json --out "$tmp/r"
is_png "$tmp/r/frame-00000-id.png"
is_png "$tmp/r/frame-00001-id.png"
has "\"$tmp/r/frame-00001-id.png\"" "$tmp/out"
hasnt "sightline-run" "$tmp/out"
# an input named like one of the run's files is not replaced either
mkdir "$tmp/r2"
cp "$tmp/walk.txt" "$tmp/r2/frame-00000-id.png"
expect 1 "$SL" render city:tiny --path "$tmp/r2/frame-00000-id.png" --frames 0:1 --width 32 --height 24 --images id --out "$tmp/r2"
cmp -s "$tmp/walk.txt" "$tmp/r2/frame-00000-id.png" || fail "render replaced its input path file"
has "is the input file" "$tmp/err"
mkdir -p "$tmp/d/report.md"
echo "old table" >"$tmp/d/frames.csv"
snapshot "$tmp/d" "$tmp/d.before"
expect 1 "$SL" demo --preset tiny --quick --frames 2 --out "$tmp/d" --quiet
snapshot "$tmp/d" "$tmp/d.after"
cmp -s "$tmp/d.before" "$tmp/d.after" || fail "a failed demo changed the previous run's folder"
has "report.md: it is a folder" "$tmp/err"
ls -A "$tmp/d" | grep -q sightline-run && fail "the demo left its temporary folder"
devnull_ok
echo "outputs: ok"
