#!/usr/bin/env bash
# The API reference (docs/api.md) is what scripts/apiref.sh makes of the public headers, and every
# public function (SL_API) in include/sightline/*.h has a comment. $1 (the command) is not used.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
"$root/scripts/apiref.sh" --check
# the check itself fails on an undocumented function
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$tmp/include/sightline" "$tmp/scripts" "$tmp/docs"
cp "$root/scripts/apiref.sh" "$tmp/scripts/"
printf '/* A header. */\n#include "core.h"\n\nSL_API int sl_undocumented(void);\n' > "$tmp/include/sightline/x.h"
if "$tmp/scripts/apiref.sh" -o "$tmp/docs/api.md" > /dev/null 2> "$tmp/err"; then
    echo "apiref.sh took a public function without a comment" >&2
    exit 1
fi
grep -q 'x.h:4: sl_undocumented has no comment' "$tmp/err" || { cat "$tmp/err" >&2; exit 1; }
echo "apiref: ok"
