/* Metrics: a culling result judged against the oracle, and summaries of measurement series.
 *
 * Missed pixels are the pixels the oracle gives to objects the culler dropped: drawing only the
 * culler's set changes exactly those pixels (every other pixel shows an object that is kept and
 * was already the nearest), so this is also the image error of the GVS paper (Wimmer 2007, ch. 5)
 * when the "result" is a PVS and the frame a view from inside its cell. */
#include "sightline/truth.h"

#include "scene/scene_internal.h"

#include <math.h>
#include <stdlib.h>

static uint64_t object_triangles(const struct sl_scene_t *s, uint32_t id)
{
    const sl_object_rec *o = &sl_scene_objects(s)[id];
    return sl_scene_meshes(s)[o->mesh].triangle_count;
}

sl_status sl_metrics_compare(sl_scene scene, const sl_oracle_frame *truth, const uint32_t *result,
                             uint32_t result_count, sl_cull_metrics *out, uint32_t *missed_ids, uint32_t *missed_pixels,
                             uint32_t missed_capacity, sl_error *err)
{
    if (!scene || !truth || !out || (result_count && !result))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_metrics_compare: scene, truth, out and result must not be NULL");
    if (missed_capacity && (!missed_ids || !missed_pixels))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "sl_metrics_compare: missed_capacity is %u but missed_ids or missed_pixels is NULL", missed_capacity);
    if (truth->visible_count && (!truth->visible || !truth->pixels))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_metrics_compare: the oracle frame has no visible set");
    const struct sl_scene_t *s = scene;
    uint32_t n = sl_scene_object_count(scene);
    memset(out, 0, sizeof *out);
    for (uint32_t i = 0; i < result_count; i++) {
        if (result[i] >= n)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                           "sl_metrics_compare: result[%u] = %u is not an object id (the scene has %u objects)", i,
                           result[i], n);
        if (i > 0 && result[i] <= result[i - 1])
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                           "sl_metrics_compare: result is not strictly ascending at index %u (%u after %u)", i,
                           result[i], result[i - 1]);
    }
    for (uint32_t i = 0; i < truth->visible_count; i++)
        if (truth->visible[i] >= n || (i > 0 && truth->visible[i] <= truth->visible[i - 1]))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                           "sl_metrics_compare: oracle frame entry %u (object %u) is out of range or out of order: "
                           "was it rendered from another scene?", i, truth->visible[i]);

    /* merge the two ascending lists */
    uint32_t i = 0, j = 0;
    while (i < truth->visible_count || j < result_count) {
        uint32_t v = i < truth->visible_count ? truth->visible[i] : UINT32_MAX;
        uint32_t r = j < result_count ? result[j] : UINT32_MAX;
        if (v == r) {
            i++, j++;
        } else if (v < r) {
            if (out->missed_count < missed_capacity) {
                missed_ids[out->missed_count] = v;
                missed_pixels[out->missed_count] = truth->pixels[i];
            }
            out->missed_count++;
            out->missed_pixels += truth->pixels[i];
            i++;
        } else {
            out->extra_count++;
            j++;
        }
    }
    out->visible_count = truth->visible_count;
    out->result_count = result_count;
    out->overestimation = (double)result_count / (double)(truth->visible_count ? truth->visible_count : 1);
    for (uint32_t k = 0; k < result_count; k++)
        out->triangles_rendered += object_triangles(s, result[k]);
    for (uint32_t k = 0; k < truth->visible_count; k++)
        out->triangles_visible += object_triangles(s, truth->visible[k]);
    return SL_OK;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

sl_status sl_series_summarize(const double *values, size_t n, const sl_allocator *alloc, sl_series_summary *out,
                              sl_error *err)
{
    if (!out || (n && !values))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_series_summarize: out and values must not be NULL");
    memset(out, 0, sizeof *out);
    if (n == 0)
        return SL_OK;
    for (size_t i = 0; i < n; i++)
        if (!isfinite(values[i]))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_series_summarize: value %zu (%g) is not finite", i,
                           values[i]);
    size_t bytes;
    if (!sl_mul_size(n, sizeof(double), &bytes))
        return sl_fail(err, SL_ERROR_LIMIT, "sl_series_summarize: %zu values are too many", n);
    double *v = sl_alloc(alloc, bytes);
    if (!v)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_series_summarize: out of memory for %zu values", n);
    memcpy(v, values, bytes);
    qsort(v, n, sizeof(double), cmp_double);
    double sum = 0;
    for (size_t i = 0; i < n; i++)
        sum += v[i];
    out->count = n;
    out->min = v[0];
    out->max = v[n - 1];
    out->mean = sum / (double)n;
    out->median = n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
    /* nearest rank: the smallest value with at least 95% of the values at or below it */
    size_t rank = n / 100 * 95 + (n % 100 * 95 + 99) / 100; /* ceil(0.95 n) in integers */
    out->p95 = v[(rank ? rank : 1) - 1];
    sl_free(alloc, v, bytes);
    return SL_OK;
}
