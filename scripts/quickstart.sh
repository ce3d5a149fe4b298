#!/usr/bin/env bash
# Quick start, first command: install what is missing, build (release), run the demo, and put the
# command on the PATH: a link ~/.local/bin/sightline -> build/sightline when ~/.local/bin is on the
# PATH (never over a file that is not such a link), else the line that does it.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DSL_BUILD_TESTS=OFF >/dev/null
cmake --build build -j"$(nproc)"
bin="$PWD/build/sightline"
link_cmd() {
    local dir="$HOME/.local/bin" link="$HOME/.local/bin/sightline"
    case ":$PATH:" in
    *":$dir:"*)
        if [ -L "$link" ] || [ ! -e "$link" ]; then
            ln -sfn "$bin" "$link" && echo "sightline: $link -> $bin (on your PATH)"
            return
        fi
        echo "sightline: $link exists and is not a link; the command is $bin" ;;
    *) echo "sightline: the command is $bin; to type just 'sightline': export PATH=\"$PWD/build:\$PATH\"" ;;
    esac
}
status=0
build/sightline demo "$@" || status=$?
link_cmd
exit $status
