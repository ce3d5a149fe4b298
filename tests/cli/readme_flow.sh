#!/bin/bash
# CLI test of the README's first session (issue 17): the lines between <!-- readme-flow --> and
# <!-- /readme-flow --> in README.md, run as they are (sightline -> $1) in a scratch folder, each
# exiting 0; the bench recommends the method the README then runs, the PVS bake says it chose
# portal, and the query prints a set. Skips (77) without the Debian map package.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"
readme="$(cd "$(dirname "$0")/../.." && pwd)/README.md"
[ -f /usr/share/games/openarena/baseoa/pak1-maps.pk3 ] || { echo "SKIP: openarena-081-maps is not installed"; exit 77; }
sed -n '/<!-- readme-flow -->/,/<!-- \/readme-flow -->/p' "$readme" | grep '^sightline ' > "$tmp/flow"
[ "$(wc -l < "$tmp/flow")" -ge 5 ] || fail "README has no readme-flow block"
cd "$tmp" || exit 1
n=0
while IFS= read -r line; do
    cmd=${line%%#*} # the comment after the command
    # shellcheck disable=SC2086
    expect 0 "$SL" ${cmd#sightline }
    cp "$tmp/out" "$tmp/out.$n"
    cp "$tmp/err" "$tmp/err.$n"
    n=$((n + 1))
done < "$tmp/flow"
# the bench ended with a recommendation naming the method the README runs next
has "^\\*\\*Recommendation.\\*\\*" "$tmp/out.2"
m=$(sed -n 's/.*--methods \([a-z+-]*\).*/\1/p' "$tmp/flow" | head -1)
[ -n "$m" ] || fail "the README runs no recommended method"
# (the recommendation rests on cull times: under the sanitizers, ten times slower, another method
# is the tightest within 2 ms, so the check is the release build's)
if [ -z "${SL_SANITIZED:-}" ]; then
    grep -q "\"fastest\":\"$m\"\|\"tightest\":\"$m\"" "$tmp/dm1-bench/summary.json" ||
        fail "the README runs $m, the bench recommends $(grep -o '"recommendation":{[^}]*}' "$tmp/dm1-bench/summary.json")"
fi
grep -q '"recommendation":{"max_overestimation":2,"max_ms":2,"fastest":' "$tmp/dm1-bench/summary.json" ||
    fail "no recommendation in summary.json"
has "| $m | " "$tmp/dm1-hzb/summary.md"
has "method portal (the conservative method for Quake III cluster cells" "$tmp/err.4"
has "^cell 10 (cluster" "$tmp/out.5"
echo "readme_flow: ok"
