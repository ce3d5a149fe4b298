#!/usr/bin/env bash
# The layer check (docs/architecture.md): every #include in src/ points at the same layer or one
# below it, and tools/ includes only the public headers (include/sightline/) and its own. Prints
# FILE:LINE and what is wrong for each upward include, and exits 1 when there is any.
#   scripts/check_layers.sh [BUILD_DIR]
# With BUILD_DIR (a configured and built tree) it also checks the objects: every sl_ symbol a
# layer's object uses must be defined by that layer or one below it (nm), so a call upward through
# a local prototype is caught too; and every sl_ symbol the command's objects use must be public
# (exported by libsightline.so) or the command's own. The build itself enforces the includes (each
# layer compiles against an include tree holding only the layers at or below it, the command
# against include/ and tools/); this script says which line.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"

# low to high; keep in step with SL_LAYERS and SL_PUBLIC_* in CMakeLists.txt
layers=(core scene accel raster pvs cull embree region import truth app net render)
# net (src/net, libsightline_net, optional) and render (src/render, libsightline_render, optional)
# are not part of libsightline; nothing includes either
declare -A rank public
for i in "${!layers[@]}"; do rank[${layers[$i]}]=$i; done
public_of() { # the layer implementing public header $1
    case "$1" in
    core.h | geom.h | image.h | camera.h | view.h) echo core ;;
    scene.h | slscene.h | path.h | gen.h) echo scene ;;
    accel.h) echo accel ;;
    raster.h) echo raster ;;
    pvs.h | region.h) echo pvs ;;
    cull.h | urban.h | backend.h) echo cull ;;
    bake.h) echo region ;;
    import.h) echo import ;;
    truth.h | bench.h) echo truth ;;
    radar.h) echo app ;;
    net.h) echo net ;;
    render.h) echo render ;;
    *) echo "" ;;
    esac
}

# LINE:NAME for each #include "NAME" of file $1
includes() {
    grep -n -E '^[[:space:]]*#[[:space:]]*include[[:space:]]*"' "$1" | sed -E 's/^([0-9]+):[^"]*"([^"]+)".*/\1:\2/' || true
}

bad=0
report() { echo "$1: $2" >&2; bad=1; }

# ---- src/: includes point down ----
for dir in src/*/; do
    layer=$(basename "$dir")
    if [ -z "${rank[$layer]+x}" ]; then
        report "$dir" "folder is not a layer (add it to scripts/check_layers.sh and CMakeLists.txt)"
        continue
    fi
    me=${rank[$layer]}
    while IFS= read -r f; do
        while IFS=: read -r n inc; do
            case "$inc" in
            ../* | */../*) report "$f:$n" "relative include \"$inc\": name the layer (\"layer/file.h\")" ;;
            sightline/*)
                h=${inc#sightline/}
                to=$(public_of "$h")
                if [ -z "$to" ]; then
                    report "$f:$n" "public header $inc has no layer in scripts/check_layers.sh"
                elif [ "${rank[$to]}" -gt "$me" ]; then
                    report "$f:$n" "includes $inc (layer $to) from layer $layer: upward"
                fi ;;
            */*)
                to=${inc%%/*}
                if [ -z "${rank[$to]+x}" ]; then
                    report "$f:$n" "includes $inc: $to is not a layer"
                elif [ "${rank[$to]}" -gt "$me" ]; then
                    report "$f:$n" "includes $inc (layer $to) from layer $layer: upward"
                fi ;;
            *) [ -e "$(dirname "$f")/$inc" ] || report "$f:$n" "includes \"$inc\", not a file of $(dirname "$f")/" ;;
            esac
        done < <(includes "$f")
    done < <(find "$dir" -name '*.[ch]' | sort)
done

# ---- tools/: public headers and its own only ----
for f in tools/*.[ch]; do
    while IFS=: read -r n inc; do
        case "$inc" in
        sightline/*) [ -n "$(public_of "${inc#sightline/}")" ] ||
            report "$f:$n" "includes $inc: not a public header" ;;
        */*) report "$f:$n" "includes $inc: tools/ may include only sightline/*.h and its own headers" ;;
        *) [ -e "tools/$inc" ] || report "$f:$n" "includes \"$inc\", not a file of tools/" ;;
        esac
    done < <(includes "$f")
done

# ---- objects: symbols point down ----
if [ $# -ge 1 ]; then
    build=$1
    objects() { [ -d "$build/CMakeFiles/sl_layer_$1.dir" ] && find "$build/CMakeFiles/sl_layer_$1.dir" -name '*.o' | sort; }
    declare -A owner
    for layer in "${layers[@]}"; do
        while IFS= read -r o; do
            while read -r sym; do owner[$sym]=$layer; done < <(nm --defined-only -g "$o" | awk '$3 ~ /^sl_/ { print $3 }')
        done < <(objects "$layer")
    done
    [ ${#owner[@]} -gt 0 ] || { echo "$build: no layer objects (build the library first)" >&2; exit 2; }
    for layer in "${layers[@]}"; do
        me=${rank[$layer]}
        while IFS= read -r o; do
            src=${o#"$build"/CMakeFiles/sl_layer_"$layer".dir/}
            src=${src%.o}
            while read -r sym; do
                to=${owner[$sym]:-}
                [ -n "$to" ] || continue
                [ "${rank[$to]}" -le "$me" ] || report "$src" "calls $sym (layer $to) from layer $layer: upward"
            done < <(nm -u "$o" | awk '$2 ~ /^sl_/ { print $2 }')
        done < <(objects "$layer")
    done
    # the command calls the public API only: every sl_ symbol its objects use is exported by
    # libsightline.so (SL_API) or defined in tools/ itself (an internal function reached through a
    # local prototype is caught here)
    tool_objects=$(find "$build/CMakeFiles/sightline_cli.dir/tools" -name '*.o' 2>/dev/null | sort)
    lib=$build/libsightline.so
    if [ -n "$tool_objects" ] && [ -e "$lib" ]; then
        declare -A exported
        while read -r sym; do exported[$sym]=1; done < <(
            nm -D --defined-only "$lib" | awk '$3 ~ /^sl_/ { print $3 }'
            [ ! -e "$build/libsightline_render.so" ] ||
                nm -D --defined-only "$build/libsightline_render.so" | awk '$3 ~ /^sl_/ { print $3 }'
            [ ! -e "$build/libsightline_net.so" ] ||
                nm -D --defined-only "$build/libsightline_net.so" | awk '$3 ~ /^sl_/ { print $3 }'
            for o in $tool_objects; do nm --defined-only -g "$o" | awk '$3 ~ /^sl_/ { print $3 }'; done)
        for o in $tool_objects; do
            while read -r sym; do
                [ -n "${exported[$sym]+x}" ] ||
                    report "tools/$(basename "${o%.o}")" "calls $sym, which is not public API (no SL_API in include/sightline/)"
            done < <(nm -u "$o" | awk '$2 ~ /^sl_/ { print $2 }')
        done
    fi
fi

if [ $bad -ne 0 ]; then
    echo "layer check: FAILED (the layers, low to high: ${layers[*]}; see docs/architecture.md)" >&2
    exit 1
fi
echo "layer check: ok"
