#!/bin/bash
# CLI test of the option parsing every subcommand shares (cli_common_option and cli_action in
# tools/cli.c): for each command and action, --help (or -h) prints its usage and ends the parse
# (what follows is not read: exit 0 even with a bad option after it), an unknown option is a usage
# error, and a second SCENE/FILE where the command takes one is refused; -o and --output and
# --output=F are the same; output folders are made with their parents. $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

cmds=("gen city" "import" "info" "export" "bench" "render" "view" "radar" "methods" "demo" "path gen" "path random"
      "path info" "path check" "pvs build" "pvs info" "pvs query" "pvs verify" "occlusion replay")
for c in "${cmds[@]}"; do
    # shellcheck disable=SC2086
    expect 0 "$SL" $c --help --no-such-option
    has "usage: sightline $c" "$tmp/out"
    [ ! -s "$tmp/err" ] || fail "$c --help read on past --help"
    # shellcheck disable=SC2086
    expect 0 "$SL" $c -h
    has "usage: sightline $c" "$tmp/out"
    # shellcheck disable=SC2086
    expect 2 "$SL" $c --no-such-option
    has "unknown option --no-such-option" "$tmp/err"
done
# one positional argument only
for c in "import" "info" "render" "view" "path info" "path check" "pvs info" "pvs query" "pvs verify" "pvs build"; do
    # shellcheck disable=SC2086
    expect 2 "$SL" $c a.slscene b.slscene
    has "unexpected argument 'b.slscene'" "$tmp/err"
done
# actions
for c in path pvs occlusion; do
    expect 2 "$SL" $c
    expect 0 "$SL" $c --help
    expect 2 "$SL" $c bogus
    has "unknown action 'bogus' (.* or \|unknown action 'bogus' (replay" "$tmp/err"
done
# -o FILE, --output FILE, --output=FILE
for form in "-o $tmp/a.slscene" "--output $tmp/b.slscene" "--output=$tmp/c.slscene"; do
    # shellcheck disable=SC2086
    expect 0 "$SL" gen city --preset tiny --detail 0 --quiet $form
done
cmp -s "$tmp/a.slscene" "$tmp/b.slscene" && cmp -s "$tmp/a.slscene" "$tmp/c.slscene" || fail "-o, --output differ"
expect 0 "$SL" info "$tmp/a.slscene" --json
has '"objects"' "$tmp/out"
expect 2 "$SL" gen city -o
has "needs a value" "$tmp/err"
# output folders (cli_outdir_begin and its one mkdir -p, make_parents in tools/cli.c): missing
# parents are made, an existing folder is reused, a file in the way is refused by name
cam="0,0,300,30,-45,0,70"
expect 0 "$SL" render city:tiny --camera "$cam" --width 64 --height 48 --images id --out "$tmp/o/a/b" --quiet
[ -s "$tmp/o/a/b/frame-00000-id.png" ] || fail "render did not make the missing folders"
expect 0 "$SL" render city:tiny --camera "$cam" --width 64 --height 48 --images id --out "$tmp/o/a/b" --quiet
: >"$tmp/o/file"
expect 1 "$SL" render city:tiny --camera "$cam" --width 64 --height 48 --out "$tmp/o/file" --quiet
has "exists and is not a folder" "$tmp/err"
expect 1 "$SL" render city:tiny --camera "$cam" --width 64 --height 48 --out "$tmp/o/file/sub" --quiet
has "Not a directory" "$tmp/err"
[ -f "$tmp/o/file" ] || fail "the file in the way was touched"
echo "options: ok"
