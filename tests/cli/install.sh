#!/bin/bash
# `cmake --install` puts headers, libraries, the command, the CMake package and the pkg-config file
# in a prefix; a consumer program builds against the installed library both ways and runs.
# Runs in the build directory; $1 is the sightline binary (unused beyond a sanity check).
set -euo pipefail
if [ -n "${SL_SANITIZED:-}" ]; then
    echo "SKIP: consumer builds are not sanitizer-instrumented"
    exit 0
fi
build=$(pwd)
. "$(dirname "$0")/lib/common.sh"
cmake --install "$build" --prefix "$tmp/prefix" >/dev/null
for f in include/sightline/scene.h include/sightline/cull.h bin/sightline share/doc/sightline/README.md; do
    [ -e "$tmp/prefix/$f" ] || fail "$f not installed"
done
libdir=$(ls -d "$tmp"/prefix/lib*/ | head -n 1)
[ -e "$libdir/libsightline.so" ] && [ -e "$libdir/libsightline.a" ] || fail "libraries missing"
"$tmp/prefix/bin/sightline" --version >/dev/null

cat > "$tmp/consumer.c" <<'C'
#include <sightline/scene.h>
#include <stdio.h>
int main(void)
{
    sl_scene s;
    sl_error err;
    if (sl_scene_create(NULL, &s, &err) != SL_OK)
        return 1;
    const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t i[3] = {0, 1, 2};
    sl_mesh_desc m = {p, NULL, 3, i, 1};
    uint32_t mesh;
    if (sl_scene_add_mesh(s, &m, &mesh, &err) != SL_OK)
        return 1;
    printf("sightline %s, %u mesh\n", sl_version_string(), sl_scene_mesh_count(s));
    sl_scene_destroy(s);
    return 0;
}
C
# pkg-config, shared library
export PKG_CONFIG_PATH="$libdir/pkgconfig"
cc -std=gnu11 -Wall -Werror "$tmp/consumer.c" -o "$tmp/consumer_pc" $(pkg-config --cflags --libs sightline)
LD_LIBRARY_PATH="$libdir" "$tmp/consumer_pc" | grep -q "1 mesh"

# CMake package, shared and static
mkdir -p "$tmp/cm"
cat > "$tmp/cm/CMakeLists.txt" <<'CM'
cmake_minimum_required(VERSION 3.25)
project(consumer C)
find_package(sightline REQUIRED)
add_executable(consumer_shared ../consumer.c)
target_link_libraries(consumer_shared PRIVATE sightline::sightline)
add_executable(consumer_static ../consumer.c)
target_link_libraries(consumer_static PRIVATE sightline::sightline_static)
CM
cmake -S "$tmp/cm" -B "$tmp/cm/build" -DCMAKE_PREFIX_PATH="$tmp/prefix" >/dev/null
cmake --build "$tmp/cm/build" >/dev/null
LD_LIBRARY_PATH="$libdir" "$tmp/cm/build/consumer_shared" | grep -q "1 mesh"
"$tmp/cm/build/consumer_static" | grep -q "1 mesh"
echo "install: ok"
