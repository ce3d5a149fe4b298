#!/bin/bash
# CLI test of the isolated assimp import (docs/import-export.md, "assimp runs in a child
# process"): --import-timeout stops a model that takes too long, with a clear message, no output
# and no process left; a generous limit imports; bad values are usage errors; every command that
# opens assimp files takes it. $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

# a 180,000-triangle OBJ (300 x 300 quads): assimp needs a few hundred milliseconds for it
awk 'BEGIN { n = 300
  for (i = 0; i <= n; i++) for (j = 0; j <= n; j++) print "v", i, j, (i * j) % 7
  for (i = 0; i < n; i++) for (j = 0; j < n; j++) {
    a = i * (n + 1) + j + 1; b = a + 1; c = a + n + 1; d = c + 1
    print "f", a, b, d; print "f", a, d, c } }' >"$tmp/big.obj"

# 1 ms: stopped
expect 1 "$SL" import "$tmp/big.obj" -o "$tmp/big.slscene" --import-timeout 0.001 --quiet
has "took longer than the limit of 1 ms and was stopped" "$tmp/err"
[ ! -e "$tmp/big.slscene" ] || fail "a stopped import wrote its output"
expect 1 "$SL" info "$tmp/big.obj" --import-timeout=0.001
has "limit of 1 ms" "$tmp/err"
# no importer child left running (the command reaped or killed it before exiting)
if pgrep -f "import $tmp/big.obj" >/dev/null 2>&1; then fail "an import process is still running"; fi

# a generous limit, and none: imported, the same bytes
expect 0 "$SL" import "$tmp/big.obj" -o "$tmp/a.slscene" --import-timeout 600 --quiet
expect 0 "$SL" import "$tmp/big.obj" -o "$tmp/b.slscene" --quiet
cmp -s "$tmp/a.slscene" "$tmp/b.slscene" || fail "the limit changed the imported scene"
expect 0 "$SL" info "$tmp/a.slscene" --json
has '"triangles_stored":180000' "$tmp/out"

# bad values: usage errors naming the option
for v in x 0 -1 1e10 ""; do
    expect 2 "$SL" import "$tmp/big.obj" -o "$tmp/c.slscene" --import-timeout "$v"
    has "\-\-import-timeout" "$tmp/err"
done
[ ! -e "$tmp/c.slscene" ] || fail "a usage error wrote an output"

# every command that opens assimp files documents it
for c in import info export bench render radar "path gen" "path random" "pvs build" "pvs query" "pvs verify"; do
    # shellcheck disable=SC2086
    expect 0 "$SL" $c --help
    has "\-\-import-timeout" "$tmp/out"
done
echo "import_isolate: ok"
