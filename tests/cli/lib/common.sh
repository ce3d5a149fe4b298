# shellcheck shell=bash
# Shared helpers of the command-line tests in tests/cli/ (bash). Every test script starts with
#
#     set -u
#     SL="$1"
#     . "$(dirname "$0")/lib/common.sh"
#
# and then runs the sightline binary "$SL" through `expect` and checks its output with `has` and
# the other helpers below. The file lives in tests/cli/lib/ on purpose: CMakeLists.txt registers
# every tests/cli/*.sh (a non-recursive glob) as a CTest test, and this file is not a test.
#
# Sourcing it creates the scratch folder $tmp, removed when the script exits (an EXIT trap: a script
# that sets its own EXIT trap must remove $tmp itself). The last command run by `expect` leaves its
# stdout in $tmp/out and its stderr in $tmp/err; `fail` shows both, so that a failing check in the
# CTest log comes with what the command said.

tmp=$(mktemp -d) || { echo "FAIL: mktemp -d"; exit 1; }
trap 'rm -rf "$tmp"' EXIT

# fail MESSAGE...: print "FAIL: MESSAGE" and the start of the last command's stdout and stderr
# (4000 bytes of each, enough to see the error without flooding the log), then exit 1.
fail() {
    echo "FAIL: $*"
    echo "--- stdout"; head -c 4000 "$tmp/out" 2>/dev/null
    echo "--- stderr"; head -c 4000 "$tmp/err" 2>/dev/null
    exit 1
}

# expect STATUS COMMAND...: run COMMAND with stdout in $tmp/out and stderr in $tmp/err, and fail
# unless it exits with STATUS (0 ok, 1 failure, 2 usage error for sightline).
expect() {
    local want=$1
    shift
    "$@" >"$tmp/out" 2>"$tmp/err"
    local rc=$?
    [ "$rc" -eq "$want" ] || fail "exit status $rc, expected $want: $*"
}

# has PATTERN FILE / hasnt PATTERN FILE: the grep (basic regular expression) PATTERN is / is not
# in FILE. The "--" lets a pattern start with a dash (an option name).
has() { grep -q -- "$1" "$2" || fail "'$1' not in $2"; }
hasnt() { ! grep -q -- "$1" "$2" || fail "'$1' unexpectedly in $2"; }

# rows CSV: the data rows of a CSV file (its lines less the header).
rows() { echo $(($(wc -l <"$1") - 1)); }

# is_png FILE: FILE starts with the 8-byte PNG signature. is_svg FILE: an XML file with </svg>.
is_png() { [ "$(head -c 8 "$1" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ] || fail "$1 is not a PNG"; }
is_svg() { head -c 5 "$1" | grep -q '<?xml' && grep -q '</svg>' "$1" || fail "$1 is not an SVG"; }

# png_size FILE: prints "WIDTHxHEIGHT" from the IHDR chunk (big-endian u32s at offsets 16 and 20).
png_size() {
    local w h
    w=$(od -An -tu1 -j16 -N4 "$1" | awk '{ print $1 * 16777216 + $2 * 65536 + $3 * 256 + $4 }')
    h=$(od -An -tu1 -j20 -N4 "$1" | awk '{ print $1 * 16777216 + $2 * 65536 + $3 * 256 + $4 }')
    echo "${w}x${h}"
}

# near KEY VALUE TOLERANCE: the first JSON number "KEY":... in $tmp/out is within TOLERANCE of VALUE.
near() {
    local v
    v=$(grep -o "\"$1\":[^,}]*" "$tmp/out" | head -1 | cut -d: -f2)
    [ -n "$v" ] || fail "no $1 in the JSON output"
    awk -v v="$v" -v w="$2" -v t="$3" 'BEGIN { d = v - w; if (d < 0) d = -d; exit !(d <= t) }' ||
        fail "$1 is $v, expected $2 +- $3"
}

# png_colors FILE: the number of distinct RGB colours of FILE scaled to 200 pixels wide (nearest
# neighbour), decoded by ffmpeg; prints nothing when ffmpeg is missing.
png_colors() {
    command -v ffmpeg >/dev/null 2>&1 || return 0
    ffmpeg -loglevel error -i "$1" -vf scale=200:-1:flags=neighbor -f rawvideo -pix_fmt rgb24 - 2>/dev/null |
        od -An -v -tx1 -w3 | sort -u | wc -l
}

# png_dark FILE CROP: how many pixels of the ffmpeg crop CROP (w:h:x:y, expressions of iw and ih)
# of FILE are near black (grey level below 40); prints nothing when ffmpeg is missing.
png_dark() {
    command -v ffmpeg >/dev/null 2>&1 || return 0
    ffmpeg -loglevel error -i "$1" -vf "crop=$2,format=gray" -f rawvideo -pix_fmt gray - 2>/dev/null |
        od -An -v -tu1 -w1 | awk '$1 < 40 { n++ } END { print n + 0 }'
}
