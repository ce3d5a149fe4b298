#!/bin/bash
# The demo report in a real browser: headless Chromium opens report.html of a quick demo run,
# takes a screenshot (its size and that it is not blank are checked), and a check page loads the
# report in a frame to find broken images, requests that leave file://, contents links that lead
# nowhere and a page wider than a laptop's window; the browser's log must show no console error.
# Exit 77 (skipped) only when Chromium is not installed. $1 is the sightline binary.
set -u
SL="$1"
. "$(dirname "$0")/lib/common.sh"

CHROME=$(command -v chromium || command -v chromium-browser || true)
if [ -z "$CHROME" ]; then
    echo "SKIP: chromium is not installed (Debian package chromium, scripts/packages.txt)"
    exit 77
fi
if [ -n "${SL_SANITIZED:-}" ]; then FRAMES="--frames 4"; else FRAMES=""; fi
# shellcheck disable=SC2086
expect 0 "$SL" demo --preset tiny --quick $FRAMES --out "$tmp/d" --quiet
H="$tmp/d/report.html"

# self-contained: nothing fetched from the network (a plain text link would be allowed, none is used)
grep -Eqi '(src|href)="(https?:)?//' "$H" && fail "report.html references the network"
grep -Eqi 'url\((["'\'']?)(https?:)?//|@import' "$H" && fail "report.html's style fetches something"

# one browser run: headless, no GPU, no sandbox (root in CI), a throwaway profile, logs on stderr
chrome() {
    timeout 60 "$CHROME" --headless --disable-gpu --no-sandbox --hide-scrollbars --no-first-run \
        --user-data-dir="$tmp/profile" --enable-logging=stderr --v=0 "$@"
}

# 1. the screenshot
chrome --screenshot="$tmp/shot.png" --window-size=1280,4000 "file://$H" >"$tmp/out" 2>"$tmp/err" ||
    fail "chromium --screenshot failed"
[ -s "$tmp/shot.png" ] || fail "no screenshot"
is_png "$tmp/shot.png"
[ "$(png_size "$tmp/shot.png")" = "1280x4000" ] || fail "the screenshot is $(png_size "$tmp/shot.png"), not 1280x4000"
# a blank page compresses to a few kB; the report's tables, plots and images do not
bytes=$(wc -c <"$tmp/shot.png")
[ "$bytes" -gt 60000 ] || fail "the screenshot is $bytes bytes: blank?"
colors=$(png_colors "$tmp/shot.png")
[ -z "$colors" ] || [ "$colors" -ge 50 ] || fail "the screenshot has only $colors distinct colours: blank?"
cp "$tmp/err" "$tmp/log-shot"

# 2. the check page: the report in a frame (file access allowed between files), every image loaded
# (lazy ones too), every resource a file, every #link an id, no horizontal overflow at 1280 px
cat >"$tmp/check.html" <<HTML
<!DOCTYPE html><html><head><meta charset="utf-8"></head><body style="margin:0">
<iframe id="f" style="border:0" width="1280" height="2000" src="file://$H"></iframe>
<pre id="result">PENDING</pre>
<script>
"use strict";
function done(text) { document.getElementById("result").textContent = text; }
document.getElementById("f").addEventListener("load", function () {
    var d = null;
    try { d = this.contentDocument; } catch (e) { done("NOACCESS " + e); return; }
    if (!d || !d.images) { done("NOACCESS"); return; }
    var imgs = Array.prototype.slice.call(d.images), waits = imgs.map(function (i) {
        i.loading = "eager";
        return new Promise(function (resolve) {
            function settle() { resolve(i.naturalWidth > 0 ? null : i.getAttribute("src")); }
            if (i.complete) settle();
            else { i.addEventListener("load", settle); i.addEventListener("error", settle); }
        });
    });
    Promise.all(waits).then(function (bad) {
        bad = bad.filter(function (b) { return b !== null; });
        var remote = d.defaultView.performance.getEntriesByType("resource").map(function (e) { return e.name; })
            .filter(function (n) { return n.indexOf("file:") !== 0; });
        var dead = Array.prototype.slice.call(d.querySelectorAll("a[href^='#']")).map(function (a) {
            return a.getAttribute("href").slice(1); }).filter(function (id) { return !d.getElementById(id); });
        done("IMAGES " + imgs.length + " BROKEN [" + bad.join(" ") + "] REMOTE [" + remote.join(" ") +
             "] DEAD [" + dead.join(" ") + "] OVERFLOW " + (d.documentElement.scrollWidth > 1280 ? 1 : 0) + " END");
    });
});
</script></body></html>
HTML
chrome --allow-file-access-from-files --virtual-time-budget=20000 --dump-dom "file://$tmp/check.html" \
    >"$tmp/out" 2>"$tmp/err" || fail "chromium --dump-dom failed"
result=$(grep -o 'IMAGES [0-9]* BROKEN.*END\|NOACCESS[^<]*\|PENDING' "$tmp/out" | head -1)
echo "check page: $result"
case "$result" in
"IMAGES 0 "*) fail "the report shows no images" ;;
"IMAGES "*" BROKEN [] REMOTE [] DEAD [] OVERFLOW 0 END") ;;
*) fail "the check page says: ${result:-nothing}" ;;
esac
# 3. no console error, no failed load in either run's log
cat "$tmp/log-shot" >>"$tmp/err"
grep -E 'CONSOLE|Uncaught|Failed to load|ERR_FILE_NOT_FOUND' "$tmp/err" && fail "the browser logged errors"
echo "PASS"
