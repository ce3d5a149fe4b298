/* sl_scene_open: one entry point for every scene source, dispatched by file extension, so that
 * the CLI, the viewer and the benchmarks accept .slscene, Quake III maps, GIS files and assimp formats
 * alike.
 * The extension decides (not the content): a file named .obj that holds something else fails in
 * assimp with assimp's message, which names the real problem better than a guess would. */
#include "scene/scene_internal.h"
#include "sightline/import.h"
#include "sightline/slscene.h"

#include <strings.h>

/* The extension of the last path component including its dot (".slscene"), or "" when none. */
static const char *path_extension(const char *path)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    const char *dot = strrchr(base, '.');
    return dot && dot != base ? dot : "";
}

sl_status sl_scene_open(const char *path, const char *map, const sl_allocator *alloc, sl_scene *out, sl_error *err)
{
    return sl_scene_open_with(path, map, NULL, alloc, out, err);
}

sl_status sl_scene_open_with(const char *path, const char *map, const sl_import_options *opt, const sl_allocator *alloc,
                             sl_scene *out, sl_error *err)
{
    if (!path || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_open: NULL argument");
    *out = NULL;
    const char *ext = path_extension(path);
    if (strcasecmp(ext, ".pk3") == 0)
        return sl_import_q3bsp(path, map, opt, alloc, out, err);
    if (strcasecmp(ext, ".bsp") == 0) /* the map name only selects an entry inside a .pk3 */
        return sl_import_q3bsp(path, NULL, opt, alloc, out, err);
    /* a map name with any other file is a caller mistake worth reporting, not ignoring */
    if (map)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: a map name (\"%s\") only applies to .pk3 archives", path, map);
    if (strcasecmp(ext, ".slscene") == 0)
        return sl_scene_load(path, NULL, alloc, out, err);
    if (sl_gis_path(path)) /* GeoJSON, Shapefile, OpenStreetMap, GML: the GIS importer's defaults */
        return sl_import_gis(path, NULL, alloc, out, NULL, err);
    return sl_import_assimp(path, opt, alloc, out, err);
}
