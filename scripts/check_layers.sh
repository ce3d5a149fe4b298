#!/usr/bin/env bash
# The layer check (docs/architecture.md): every #include in src/ points at the same layer or one
# below it, and tools/ includes only the public headers (include/sightline/) and its own. Prints
# FILE:LINE and what is wrong for each upward include, and exits 1 when there is any.
#   scripts/check_layers.sh [BUILD_DIR]
# With BUILD_DIR (a configured and built tree) it also checks the objects: every sl_ symbol a
# layer's object uses must be defined by that layer or one below it (nm), so a call upward through
# a local prototype is caught too. The build itself enforces the includes (each layer compiles
# against an include tree holding only the layers at or below it); this script says which line.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"

# low to high; keep in step with SL_LAYERS and SL_PUBLIC_* in CMakeLists.txt
layers=(core scene accel raster pvs cull embree region import truth app)
declare -A rank public
for i in "${!layers[@]}"; do rank[${layers[$i]}]=$i; done
public_of() { # the layer implementing public header $1
    case "$1" in
    core.h | geom.h | image.h | camera.h) echo core ;;
    scene.h | slscene.h | path.h | gen.h) echo scene ;;
    accel.h) echo accel ;;
    raster.h) echo raster ;;
    pvs.h | region.h) echo pvs ;;
    cull.h | urban.h) echo cull ;;
    bake.h) echo region ;;
    import.h) echo import ;;
    truth.h | bench.h) echo truth ;;
    radar.h) echo app ;;
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
# The command's internal includes still to be replaced by public API (issue 13): tolerated, but no
# new one. Remove a line when its include goes; a line no longer needed is reported too.
declare -A tolerated
while read -r f inc; do [ -n "$f" ] && tolerated["$f $inc"]=0; done <<'LIST'
tools/cli.c core/escape.h
tools/cli.c core/sl_core.h
tools/cmd_bench.c core/sl_core.h
tools/cmd_bench.c core/text_parse.h
tools/cmd_demo.c core/sl_core.h
tools/cmd_demo.c truth/plot.h
tools/cmd_export.c core/sl_core.h
tools/cmd_gen.c core/sl_core.h
tools/cmd_import.c core/escape.h
tools/cmd_import.c core/sl_core.h
tools/cmd_occlusion.c cull/occluders.h
tools/cmd_pvs.c core/sl_core.h
tools/cmd_pvs.c core/text_parse.h
tools/cmd_radar.c core/sl_core.h
tools/cmd_render.c core/sl_core.h
tools/cmd_render.c core/text_parse.h
tools/cmd_render.c truth/plot.h
tools/pvs_along.c core/sl_core.h
tools/pvs_mpi.c core/sl_core.h
LIST
for f in tools/*.[ch]; do
    while IFS=: read -r n inc; do
        if [ -n "${tolerated["$f $inc"]+x}" ]; then
            tolerated["$f $inc"]=1
            continue
        fi
        case "$inc" in
        sightline/*) [ -n "$(public_of "${inc#sightline/}")" ] ||
            report "$f:$n" "includes $inc: not a public header" ;;
        */*) report "$f:$n" "includes $inc: tools/ may include only sightline/*.h and its own headers" ;;
        *) [ -e "tools/$inc" ] || report "$f:$n" "includes \"$inc\", not a file of tools/" ;;
        esac
    done < <(includes "$f")
done
for k in "${!tolerated[@]}"; do
    [ "${tolerated[$k]}" = 1 ] || report "${k% *}" "no longer includes ${k#* }: drop it from the tolerated list in $0"
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
fi

if [ $bad -ne 0 ]; then
    echo "layer check: FAILED (the layers, low to high: ${layers[*]}; see docs/architecture.md)" >&2
    exit 1
fi
echo "layer check: ok"
