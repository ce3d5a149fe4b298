/* sl_scene_open: one entry point for every scene source, dispatched by file extension, so that
 * the CLI, the viewer and the benchmarks accept .slscene, Quake III maps, GIS files and assimp formats
 * alike.
 * The extension decides (not the content): a file named .obj that holds something else fails in
 * assimp with assimp's message, which names the real problem better than a guess would. One
 * exception: Sightline's own files that are not scenes (a PVS, a bake journal, an occlusion
 * recording, a camera path) are told by their first bytes and refused with what they are, not
 * handed to assimp, whose message ("no suitable reader") would not say. */
#include "scene/scene_internal.h"
#include "sightline/import.h"
#include "sightline/slscene.h"

#include <fcntl.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

/* The extension of the last path component including its dot (".slscene"), or "" when none. */
static const char *path_extension(const char *path)
{
    const char *base = strrchr(path, '/');
    base = base ? base + 1 : path;
    const char *dot = strrchr(base, '.');
    return dot && dot != base ? dot : "";
}

/* Sightline's non-scene files, by their first bytes: what the file is, or NULL. A file that
 * cannot be read is left to the importer, which reports that. */
static const char *own_non_scene(const char *path)
{
    static const struct {
        const char *head;
        size_t len;
        const char *what;
    } kinds[] = {
        {"SLPVS\0\0\0", 8, "a PVS (.slpvs), not a scene: give the scene it was baked for (sightline pvs info shows "
                             "its scene key)"},
        {"SLPVSCKP", 8, "a PVS bake's checkpoint journal, not a scene"},
        {"SLOCCREC", 8, "an occlusion recording (an occlusion method's record=FILE output), not a scene"},
        {"# sightline-path", 16, "a camera path (sightline path), not a scene"},
    };
    /* only a regular file is opened (a FIFO's writer or a device would notice an open); then
     * non-blocking and checked again, in case it was replaced in between */
    struct stat sb;
    if (stat(path, &sb) != 0 || !S_ISREG(sb.st_mode))
        return NULL;
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0)
        return NULL;
    char head[16];
    ssize_t got = fstat(fd, &sb) == 0 && S_ISREG(sb.st_mode) ? read(fd, head, sizeof head) : -1;
    close(fd);
    size_t n = got > 0 ? (size_t)got : 0;
    for (size_t k = 0; k < sizeof kinds / sizeof *kinds; k++)
        if (n >= kinds[k].len && !memcmp(head, kinds[k].head, kinds[k].len))
            return kinds[k].what;
    return NULL;
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
    const char *what = own_non_scene(path);
    if (what)
        return sl_fail(err, SL_ERROR_FORMAT, "%s: this is %s", path, what);
    return sl_import_assimp(path, opt, alloc, out, err);
}
