#!/bin/bash
# CLI test on real models shipped by Debian (assimp-testmodels, /usr/share/assimp/models): the
# confined import (issue 12 §4) must keep loading what assimp loads. A LightWave scene names its
# objects bare ("LoadObjectLayer 1 simple_cube.lwo"): the name means the scene's folder, so the
# scene loads from any current directory (it was refused as "/tmp/simple_cube.lwo, outside the
# model's folder" when run elsewhere); a Blender 2.47 PLY has a free-text header line that assimp
# skips (our PLY pre-check refused it). A model whose reference really leaves its folder is still
# refused. Skips when the package is not installed. $1 is the sightline binary.
set -u
SL="$(cd "$(dirname "$1")" && pwd)/$(basename "$1")"
. "$(dirname "$0")/lib/common.sh"
m=/usr/share/assimp/models
if [ ! -d "$m" ]; then
    echo "SKIP: $m not installed (Debian package assimp-testmodels)"
    exit 0
fi

# a LightWave scene, run from three current directories
for dir in / "$tmp" "$m" "$m/LWS"; do
    (cd "$dir" && expect 0 "$SL" info "$m/LWS/move_x.lws") || exit 1
    has "triangles *12 stored" "$tmp/out"
done
(cd "$m" && expect 0 "$SL" info LWS/move_x.lws) || exit 1
(cd "$m/LWS" && expect 0 "$SL" info move_x.lws) || exit 1

# the scene copied beside a folder it may not leave: its object found inside, not outside
mkdir -p "$tmp/scene"
cp "$m/LWS/move_x.lws" "$tmp/scene/"
(cd "$tmp" && expect 1 "$SL" info "$tmp/scene/move_x.lws") || exit 1
cp "$m/LWS/simple_cube.lwo" "$tmp/simple_cube.lwo"
(cd "$tmp" && expect 1 "$SL" info scene/move_x.lws) || exit 1
# assimp then tries LightWave's packed-scene fallback, ../simple_cube.lwo: outside, refused
has "'../simple_cube.lwo' resolves to .*outside the model's folder" "$tmp/err"
cp "$m/LWS/simple_cube.lwo" "$tmp/scene/"
(cd / && expect 0 "$SL" info "$tmp/scene/move_x.lws") || exit 1

# a PLY whose header has a free-text line (Blender 2.47)
expect 0 "$SL" info "$m/PLY/Wuson.ply"
has "triangles *3732 stored" "$tmp/out"

# a handful of formats, each from another folder
for f in OBJ/spider.obj COB/dwarf.cob glTF/CesiumMilkTruck/CesiumMilkTruck.gltf 3DS/fels.3ds OFF/Wuson.off; do
    [ -f "$m/$f" ] || continue
    (cd / && expect 0 "$SL" info "$m/$f") || exit 1
done
echo "ok"
