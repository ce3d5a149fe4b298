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
    sl_mesh_desc m = {p, NULL, 3, i, 1, NULL};
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
# without LD_LIBRARY_PATH, as README says: the library's folder as the program's run path
cc -std=gnu11 -Wall -Werror "$tmp/consumer.c" -o "$tmp/consumer_rp" $(pkg-config --cflags --libs sightline) \
    -Wl,-rpath,"$(pkg-config --variable=libdir sightline)"
env -u LD_LIBRARY_PATH "$tmp/consumer_rp" | grep -q "1 mesh" || fail "a program linked with -Wl,-rpath does not run"
# pkg-config --static gives a link line that builds against the static library
cc -std=gnu11 -Wall -Werror "$tmp/consumer.c" -o "$tmp/consumer_st" $(pkg-config --cflags sightline) \
    "$libdir/libsightline.a" $(pkg-config --static --libs-only-other --libs-only-l sightline | sed 's/-lsightline//')
env -u LD_LIBRARY_PATH "$tmp/consumer_st" | grep -q "1 mesh" || fail "pkg-config --static does not link"

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
# CMake gives the program the imported library's folder as its build run path: no LD_LIBRARY_PATH
env -u LD_LIBRARY_PATH "$tmp/cm/build/consumer_shared" | grep -q "1 mesh" || fail "the CMake consumer needs LD_LIBRARY_PATH"
"$tmp/cm/build/consumer_static" | grep -q "1 mesh"
# the run-time library (libsightline_runtime, sightline-runtime.pc, CMake package
# sightline_runtime): none of the bake-time dependencies in its link line or the consumer's
for f in "$libdir/libsightline_runtime.so" "$libdir/libsightline_runtime.a" "$libdir/pkgconfig/sightline-runtime.pc" \
    "$libdir/cmake/sightline_runtime/sightline_runtimeConfig.cmake" "$tmp/prefix/include/sightline/bake.h"; do
    [ -e "$f" ] || fail "$f not installed"
done
bake_deps='embree|geos|assimp|libzip|gomp|omp|tbb|mpi'
readelf -d "$libdir/libsightline_runtime.so" > "$tmp/needed"
grep -q 'NEEDED' "$tmp/needed" || fail "readelf shows no NEEDED entries for libsightline_runtime.so"
if grep 'NEEDED' "$tmp/needed" | grep -Eiq "$bake_deps"; then
    cat "$tmp/needed"; fail "libsightline_runtime.so needs a bake-time library"
fi
if pkg-config --libs --static sightline-runtime | grep -Eiq "$bake_deps"; then
    fail "sightline-runtime.pc names a bake-time library: $(pkg-config --libs --static sightline-runtime)"
fi
"$tmp/prefix/bin/sightline" gen city --preset tiny --seed 3 --quiet -o "$tmp/tiny.slscene" >/dev/null
cat > "$tmp/runtime.c" <<'C'
#include <sightline/cull.h>
#include <sightline/slscene.h>
#include <stdio.h>
#include <stdlib.h>
/* load a .slscene, cull one view with each of two methods, print the counts */
int main(int argc, char **argv)
{
    sl_scene s;
    sl_error err;
    if (argc < 2 || sl_scene_load(argv[1], NULL, NULL, &s, &err) != SL_OK)
        return 1;
    uint32_t n = sl_scene_object_count(s);
    uint32_t *ids = malloc((n ? n : 1) * sizeof *ids);
    sl_camera cam = sl_camera_default();
    sl_aabb b = sl_scene_bounds(s);
    cam.position = (sl_vec3){(b.min.x + b.max.x) / 2, (b.min.y + b.max.y) / 2, b.min.z + 1.7f};
    const char *methods[2] = {"vfc", "hzb"};
    for (int m = 0; m < 2; m++) {
        sl_culler c;
        uint32_t count = 0;
        if (sl_culler_create(methods[m], s, NULL, NULL, &c, &err) != SL_OK ||
            sl_culler_cull(c, &cam, ids, n, &count, &err) != SL_OK) {
            fprintf(stderr, "%s: %s\n", methods[m], err.message);
            return 1;
        }
        printf("%s %u of %u\n", methods[m], count, n);
        sl_culler_destroy(c);
    }
    free(ids);
    sl_scene_destroy(s);
    return 0;
}
C
cc -std=gnu11 -Wall -Werror "$tmp/runtime.c" -o "$tmp/runtime_pc" $(pkg-config --cflags --libs sightline-runtime)
LD_LIBRARY_PATH="$libdir" ldd "$tmp/runtime_pc" > "$tmp/ldd"
grep -q 'libsightline_runtime' "$tmp/ldd" || fail "the consumer does not load libsightline_runtime"
if grep -Eiq "$bake_deps|libsightline\.so" "$tmp/ldd"; then
    cat "$tmp/ldd"; fail "the run-time consumer loads a bake-time library"
fi
LD_LIBRARY_PATH="$libdir" "$tmp/runtime_pc" "$tmp/tiny.slscene" > "$tmp/out" || fail "run-time consumer failed"
grep -Eq '^vfc [1-9][0-9]* of [1-9]' "$tmp/out" && grep -Eq '^hzb [0-9]+ of [1-9]' "$tmp/out" ||
    fail "run-time consumer printed no culled view"
# static, through the CMake package
mkdir -p "$tmp/rt"
cat > "$tmp/rt/CMakeLists.txt" <<'CM'
cmake_minimum_required(VERSION 3.25)
project(runtime_consumer C)
find_package(sightline_runtime REQUIRED)
add_executable(runtime_static ../runtime.c)
target_link_libraries(runtime_static PRIVATE sightline::sightline_runtime_static)
CM
cmake -S "$tmp/rt" -B "$tmp/rt/build" -DCMAKE_PREFIX_PATH="$tmp/prefix" >/dev/null
cmake --build "$tmp/rt/build" >/dev/null
"$tmp/rt/build/runtime_static" "$tmp/tiny.slscene" | grep -Eq '^vfc [1-9]' || fail "static run-time consumer failed"
# the OpenGL renderer (when built): libsightline_render, sightline-render.pc and the CMake package
# sightline_render; the consumer draws one frame headless where a GL context can be made
if [ -e "$build/libsightline_render.so" ]; then
    for f in "$libdir/libsightline_render.so" "$libdir/libsightline_render.a" "$libdir/pkgconfig/sightline-render.pc" \
        "$libdir/cmake/sightline_render/sightline_renderConfig.cmake" "$tmp/prefix/include/sightline/render.h"; do
        [ -e "$f" ] || fail "$f not installed"
    done
    cat > "$tmp/render.c" <<'C'
#include <sightline/render.h>
#include <sightline/slscene.h>
#include <stdio.h>
/* load a .slscene, draw one culled frame headless, print what was drawn; exit 3: no GL context */
int main(int argc, char **argv)
{
    sl_scene s;
    sl_error err;
    if (argc < 2 || sl_scene_load(argv[1], NULL, NULL, &s, &err) != SL_OK)
        return 1;
    if (sl_renderer_probe(SL_GL_CONTEXT_AUTO, &err) != SL_OK) {
        printf("no GL: %s\n", err.message);
        return 3;
    }
    sl_renderer_options o;
    sl_renderer_options_default(&o);
    o.width = 160;
    o.height = 120;
    sl_renderer r;
    sl_culler c;
    if (sl_renderer_create(s, &o, NULL, &r, &err) != SL_OK || sl_culler_create("vfc", s, NULL, NULL, &c, &err) != SL_OK) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    sl_camera cam = sl_camera_default();
    sl_aabb b = sl_scene_bounds(s);
    cam.position = (sl_vec3){(b.min.x + b.max.x) / 2, (b.min.y + b.max.y) / 2, b.min.z + 1.7f};
    cam.width = 160;
    cam.height = 120;
    sl_view v;
    sl_render_frame_stats st;
    if (sl_view_from_camera(&cam, &v, &err) != SL_OK ||
        sl_renderer_frame(r, c, &v, SL_RENDER_SHADED, NULL, NULL, &st, &err) != SL_OK) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    printf("drew %u objects\n", st.objects_drawn);
    sl_culler_destroy(c);
    sl_renderer_destroy(r);
    sl_scene_destroy(s);
    return 0;
}
C
    cc -std=gnu11 -Wall -Werror "$tmp/render.c" -o "$tmp/render_pc" $(pkg-config --cflags --libs sightline-render)
    pkg-config --libs sightline-render | grep -q -- '-lsightline_render' || fail "sightline-render.pc gives no -lsightline_render"
    mkdir -p "$tmp/rd"
    cat > "$tmp/rd/CMakeLists.txt" <<'CM'
cmake_minimum_required(VERSION 3.25)
project(render_consumer C)
find_package(sightline_render REQUIRED)
add_executable(render_shared ../render.c)
target_link_libraries(render_shared PRIVATE sightline::sightline_render)
add_executable(render_static ../render.c)
target_link_libraries(render_static PRIVATE sightline::sightline_render_static)
CM
    cmake -S "$tmp/rd" -B "$tmp/rd/build" -DCMAKE_PREFIX_PATH="$tmp/prefix" >/dev/null
    cmake --build "$tmp/rd/build" >/dev/null
    for p in "$tmp/render_pc" "$tmp/rd/build/render_shared" "$tmp/rd/build/render_static"; do
        rc=0
        LD_LIBRARY_PATH="$libdir" "$p" "$tmp/tiny.slscene" > "$tmp/out" || rc=$?
        if [ "$rc" -eq 3 ]; then
            echo "renderer consumer $p: $(cat "$tmp/out") (built and linked; not drawn)"
        else
            [ "$rc" -eq 0 ] && grep -Eq '^drew [1-9][0-9]* objects' "$tmp/out" || fail "renderer consumer $p failed ($rc)"
        fi
    done
fi
echo "install: ok"
