/* The bake of the shrunk occluder levels stored with a scene (Instant Visibility: Wonka's thesis
 * ch. 6, "generate occluders and shrink them by eps" ahead of time; the shrinking is ch. 7,
 * src/region/shrink.c). For each eps the scene's footprints are eroded with GEOS and every piece
 * becomes a footprint of the level: its outer ring, its base and roof. A merged piece around a
 * courtyard keeps its outer ring only: each façade of that ring is solid from its top edge down to
 * its base (the piece lies at least eps inside the union of the members at least that high), which
 * is all a 2.5D method asks of an occluder edge; the courtyard's own walls are not used (dropping an
 * occluder is conservative). A piece the scene's polygon rules refuse (a float-rounded sliver that
 * touches itself) is dropped for the same reason, and counted. */
#include "sightline/region.h"

#include "scene/scene_internal.h"

#include <math.h>
#include <stdlib.h>

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

sl_status sl_shrink_occluder_levels(sl_scene scene, const float *eps, uint32_t count, float vertical, bool merge,
                                    const sl_allocator *alloc, sl_occluder_levels_stats *stats, sl_error *err)
{
    if (!scene || (count && !eps))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_shrink_occluder_levels: NULL argument");
    if (count == 0 || count > SL_OCCLUDER_LEVELS_MAX)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "occluder levels: %u levels, expected 1..%u", count,
                       SL_OCCLUDER_LEVELS_MAX);
    if (!(vertical < 1e4f)) /* NaN too */
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "occluder levels: vertical tolerance %g is not below 10000 m",
                       (double)vertical);
    alloc = sl_alloc_or_default(alloc);
    float sorted[SL_OCCLUDER_LEVELS_MAX];
    memcpy(sorted, eps, count * sizeof(float));
    qsort(sorted, count, sizeof(float), cmp_float);
    for (uint32_t i = 0; i < count; i++) {
        if (!isfinite(sorted[i]) || !(sorted[i] > 0) || sorted[i] > 1e4f)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "occluder levels: eps %g is outside (0, 10000] m",
                           (double)sorted[i]);
        if (i && sorted[i] == sorted[i - 1])
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "occluder levels: eps %g given twice", (double)sorted[i]);
    }
    sl_occluder_levels_stats local;
    if (!stats)
        stats = &local;
    memset(stats, 0, sizeof *stats);
    stats->levels = count;
    sl_scene_clear_occluder_levels(scene);
    sl_status st = SL_OK;
    for (uint32_t l = 0; l < count && st == SL_OK; l++) {
        sl_shrunk sh = NULL;
        st = sl_shrink_footprints(scene, sorted[l], SL_SHRINK_CYLINDER, merge, alloc, &sh, err);
        const float ez = vertical < 0 || vertical > sorted[l] ? sorted[l] : vertical;
        if (st != SL_OK)
            break;
        uint32_t n = sl_shrunk_count(sh);
        sl_footprint_desc *fps = sl_alloc(alloc, (n ? n : 1) * sizeof *fps);
        if (!fps) {
            sl_shrunk_destroy(sh);
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluder levels: out of memory for %u pieces", n);
            break;
        }
        uint32_t k = 0;
        for (uint32_t i = 0; i < n; i++) {
            sl_shrunk_polygon p = sl_shrunk_get(sh, i);
            uint32_t nv = p.ring_count ? p.rings[0] : 0;
            stats->holes_dropped[l] += p.ring_count > 1 ? p.ring_count - 1 : 0;
            float base = p.base_z + ez, roof = p.roof_z - ez;
            if (!(roof > base) || !sl_scene_polygon_ok(p.xy, nv)) {
                stats->pieces_dropped[l]++;
                continue;
            }
            fps[k++] = (sl_footprint_desc){.xy = p.xy, .vertex_count = nv, .base_z = base, .roof_z = roof,
                                           .object = p.object};
        }
        sl_shrink_stats ss;
        sl_shrunk_get_stats(sh, &ss);
        stats->eps[l] = sorted[l];
        stats->footprints[l] = k;
        stats->vanished[l] = ss.vanished;
        stats->seconds += ss.seconds;
        stats->eps_z[l] = ez;
        st = sl_scene_add_occluder_level(scene, sorted[l], ez, merge ? SL_OCCLUDER_LEVEL_MERGED : 0, fps, k,
                                         err);
        sl_free(alloc, fps, (n ? n : 1) * sizeof *fps);
        sl_shrunk_destroy(sh);
    }
    if (st != SL_OK)
        sl_scene_clear_occluder_levels(scene);
    return st;
}
