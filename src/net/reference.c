/* What the visibility server answers for a viewpoint, computed in-process (include/sightline/net.h,
 * sl_vis_reference): the method's own set (its culler), or, for a method whose sets hold over
 * regions (pvs), the set of the eye's view cell, valid for any eye in the cell and any view
 * direction — the set-reuse of issue 18 (the server answers every client in a cell from one set).
 *
 * Why the cell set is a superset of the pvs culler's answer anywhere in the cell (src/cull/pvs.c):
 * that culler frustum-culls the union of the baked sets of the cells its near-plane region's box
 * meets, where the box lies within distance r of the eye (r: the near plane's farthest corner, plus
 * the culler's rounding margin, below ours); it frustum-culls every dynamic object. For an eye in
 * cell C, that box lies inside C's bounds widened by r, so the union of the sets of the cells the
 * widened box meets, plus every dynamic object, holds everything the culler can return there. When
 * the widened box is not covered by cells (the culler would fall back to all objects somewhere), an
 * eye outside the domain, or an eye in no cell, there is no cell set and the method's own set is
 * answered. r is rounded up to 0.05 m * 2^level, so clients with similar cameras share sets. */
#include "net/net_internal.h"

#include <math.h>
#include <stdio.h>

struct sl_vis_reference_t {
    const sl_allocator *alloc;
    sl_scene scene;
    sl_culler culler;
    uint32_t object_count;
    bool regions;
    sl_pvs pvs;
    bool owns_pvs;
    sl_pvs_cursor cursor;
    sl_viewcells cells;
    uint32_t cell_count;
    uint32_t *near_cells; /* cell_count */
    uint32_t *tmp;        /* object_count */
    uint8_t *mark;        /* object_count */
    uint32_t *dynamic;    /* the dynamic objects, ascending */
    uint32_t dynamic_count;
};

sl_status net_fail(sl_error *err, sl_status st, const char *fmt, ...)
{
    if (err) {
        err->status = st;
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->message, sizeof err->message, fmt, ap);
        va_end(ap);
    }
    return st;
}

sl_status net_split_spec(const char *spec, char *name, size_t size, char *options, size_t options_size, sl_error *err)
{
    if (!spec || !*spec)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "method spec: empty (NAME[:OPTIONS], e.g. cullmap or pvs:file=X.slpvs)");
    const char *colon = strchr(spec, ':');
    size_t n = colon ? (size_t)(colon - spec) : strlen(spec);
    if (n == 0 || n >= size)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "method spec '%.200s': bad method name", spec);
    memcpy(name, spec, n);
    name[n] = 0;
    /* the house grammar NAME[:key=value[:key=value...]]: the options' colons separate them */
    const char *o = colon ? colon + 1 : "";
    size_t k = strlen(o);
    if (k >= options_size)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "method spec '%.200s...': options longer than %zu characters",
                        spec, options_size - 1);
    for (size_t i = 0; i <= k; i++)
        options[i] = o[i] == ':' ? ',' : o[i];
    return SL_OK;
}

bool net_spec_file(const char *opts, char *out, size_t size)
{
    const char *p = opts;
    while (*p) {
        while (*p == ',' || *p == ' ' || *p == '\t')
            p++;
        const char *e = p;
        while (*e && *e != ',' && *e != ' ' && *e != '\t')
            e++;
        if ((size_t)(e - p) > 5 && strncmp(p, "file=", 5) == 0 && (size_t)(e - p - 5) < size) {
            memcpy(out, p + 5, (size_t)(e - p - 5));
            out[e - p - 5] = 0;
            return true;
        }
        p = e;
    }
    return false;
}

void sl_vis_reference_destroy(sl_vis_reference r)
{
    if (!r)
        return;
    const sl_allocator *a = r->alloc;
    sl_culler_destroy(r->culler);
    sl_pvs_cursor_destroy(r->cursor);
    if (r->owns_pvs)
        sl_pvs_destroy(r->pvs);
    net_free(a, r->near_cells, (size_t)r->cell_count * sizeof(uint32_t));
    net_free(a, r->tmp, (size_t)r->object_count * sizeof(uint32_t));
    net_free(a, r->mark, r->object_count);
    net_free(a, r->dynamic, (size_t)r->object_count * sizeof(uint32_t));
    net_free(a, r, sizeof *r);
}

sl_status net_reference_create(sl_scene scene, const char *spec, bool reuse, sl_scene_accel accel, sl_pvs shared_pvs,
                               const sl_allocator *alloc, sl_vis_reference *out, sl_error *err)
{
    *out = NULL;
    if (!scene)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis reference: no scene");
    char name[64], opts[4096];
    sl_status st = net_split_spec(spec, name, sizeof name, opts, sizeof opts, err);
    if (st != SL_OK)
        return st;
    const sl_allocator *a = alloc ? alloc : sl_default_allocator();
    sl_vis_reference r = net_calloc(a, sizeof *r);
    if (!r)
        return net_fail(err, SL_ERROR_OUT_OF_MEMORY, "vis reference: out of memory");
    r->alloc = a;
    r->scene = scene;
    r->object_count = sl_scene_object_count(scene);
    sl_culler_params params = {.accel = accel};
    st = sl_culler_create_with(name, scene, opts, &params, a, &r->culler, err);
    if (st != SL_OK) {
        sl_vis_reference_destroy(r);
        return st;
    }
    size_t n = r->object_count ? r->object_count : 1;
    r->tmp = net_alloc(a, n * sizeof(uint32_t));
    r->mark = net_calloc(a, n);
    r->dynamic = net_alloc(a, n * sizeof(uint32_t));
    if (!r->tmp || !r->mark || !r->dynamic) {
        r->object_count = (uint32_t)n;
        sl_vis_reference_destroy(r);
        return net_fail(err, SL_ERROR_OUT_OF_MEMORY, "vis reference: out of memory");
    }
    for (uint32_t i = 0; i < r->object_count; i++)
        if (sl_scene_object(scene, i).flags & SL_OBJECT_DYNAMIC)
            r->dynamic[r->dynamic_count++] = i;
    if (reuse && strcmp(name, "pvs") == 0) {
        if (shared_pvs) {
            r->pvs = shared_pvs;
        } else {
            char file[4096];
            if (!net_spec_file(opts, file, sizeof file)) {
                sl_vis_reference_destroy(r);
                return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis reference: pvs needs file=PATH");
            }
            if ((st = sl_pvs_open(file, 0, a, &r->pvs, err)) != SL_OK) {
                sl_vis_reference_destroy(r);
                return st;
            }
            r->owns_pvs = true;
        }
        if ((st = sl_pvs_cursor_create(r->pvs, &r->cursor, err)) != SL_OK) {
            sl_vis_reference_destroy(r);
            return st;
        }
        r->cells = sl_pvs_cells(r->pvs);
        r->cell_count = sl_viewcells_count(r->cells);
        r->near_cells = net_alloc(a, (size_t)(r->cell_count ? r->cell_count : 1) * sizeof(uint32_t));
        if (!r->near_cells) {
            sl_vis_reference_destroy(r);
            return net_fail(err, SL_ERROR_OUT_OF_MEMORY, "vis reference: out of memory");
        }
        r->regions = true;
    }
    *out = r;
    return SL_OK;
}

sl_status sl_vis_reference_create(sl_scene scene, const char *spec, bool reuse, sl_scene_accel accel,
                                  const sl_allocator *alloc, sl_vis_reference *out, sl_error *err)
{
    return net_reference_create(scene, spec, reuse, accel, NULL, alloc, out, err);
}

bool sl_vis_reference_has_regions(sl_vis_reference r) { return r && r->regions; }
uint32_t net_reference_object_count(sl_vis_reference r) { return r->object_count; }

/* The distance from the eye to the farthest corner of the near-plane region's box. */
static double near_reach(const sl_camera *cam)
{
    double aspect = (double)cam->width / (double)cam->height;
    double hh = cam->projection == SL_PERSPECTIVE ? cam->near_plane * tan(0.5 * cam->fov_y) : 0.5 * cam->ortho_height;
    double hw = hh * aspect;
    return sqrt((double)cam->near_plane * cam->near_plane + hh * hh + hw * hw);
}

/* box +- m on every axis, m = reach plus a rounding margin above the pvs culler's */
static sl_aabb widen(sl_aabb box, double reach)
{
    float *lo = &box.min.x, *hi = &box.max.x;
    for (int k = 0; k < 3; k++) {
        double m = reach + 1e-3 + 1e-5 * (fabs((double)lo[k]) + fabs((double)hi[k]));
        lo[k] = (float)(lo[k] - m);
        hi[k] = (float)(hi[k] + m);
    }
    return box;
}

bool net_reference_region_key(sl_vis_reference r, const sl_camera *cam, uint32_t *cell, uint32_t *level)
{
    if (!r->regions || !sl_oracle_in_domain(r->scene, cam->position, NULL))
        return false;
    uint32_t c = sl_viewcells_locate(r->cells, r->scene, cam->position);
    if (c == SL_NONE)
        return false;
    double reach = near_reach(cam);
    uint32_t l = 0;
    while (l < 40 && 0.05 * ldexp(1.0, (int)l) < reach)
        l++;
    if (l >= 40)
        return false;
    /* the near-plane region of any view from here stays inside the cells: the pvs culler takes
     * baked sets (not every object) whatever the direction */
    sl_aabb box = widen((sl_aabb){cam->position, cam->position}, 0.05 * ldexp(1.0, (int)l));
    bool covered = false;
    uint32_t nc = sl_viewcells_overlap(r->cells, r->scene, &box, r->near_cells, r->cell_count, &covered);
    if (!covered || nc == 0)
        return false;
    *cell = c;
    *level = l;
    return true;
}

uint32_t sl_vis_reference_cell(sl_vis_reference r, const sl_camera *cam)
{
    uint32_t c, l;
    return r && net_reference_region_key(r, cam, &c, &l) ? c : SL_NONE;
}

sl_status net_reference_region_set(sl_vis_reference r, uint32_t cell, uint32_t level, uint32_t *ids,
                                   uint32_t capacity, uint32_t *count, bool *valid, sl_error *err)
{
    *valid = false;
    *count = 0;
    if (!r->regions || cell >= r->cell_count)
        return SL_OK;
    if (capacity < r->object_count)
        return net_fail(err, SL_ERROR_INVALID_ARGUMENT, "vis reference: capacity %u below the %u objects", capacity,
                        r->object_count);
    /* every cell the widened box of an eye in this cell can meet */
    sl_aabb box = widen(sl_viewcells_data(r->cells)[cell].bounds, 0.05 * ldexp(1.0, (int)level));
    uint32_t nc = sl_viewcells_overlap(r->cells, r->scene, &box, r->near_cells, r->cell_count, NULL);
    if (nc == 0)
        return SL_OK;
    for (uint32_t i = 0; i < nc; i++) {
        uint32_t k;
        sl_status st = sl_pvs_cursor_cell_set(r->cursor, r->near_cells[i], r->tmp, r->object_count, &k, err);
        if (st != SL_OK) {
            memset(r->mark, 0, r->object_count);
            return st;
        }
        for (uint32_t j = 0; j < k; j++)
            r->mark[r->tmp[j]] = 1;
    }
    for (uint32_t j = 0; j < r->dynamic_count; j++)
        r->mark[r->dynamic[j]] = 1;
    uint32_t m = 0;
    for (uint32_t id = 0; id < r->object_count; id++)
        if (r->mark[id]) {
            r->mark[id] = 0;
            ids[m++] = id;
        }
    *count = m;
    *valid = true;
    return SL_OK;
}

sl_status sl_vis_reference_point(sl_vis_reference r, const sl_camera *cam, uint32_t *ids, uint32_t capacity,
                                 uint32_t *count, sl_error *err)
{
    return sl_culler_cull(r->culler, cam, ids, capacity, count, err);
}

sl_status sl_vis_reference_compute(sl_vis_reference r, const sl_camera *cam, uint32_t *ids, uint32_t capacity,
                                   uint32_t *count, sl_vis_validity *validity, uint32_t *cell, sl_error *err)
{
    uint32_t c, level;
    if (net_reference_region_key(r, cam, &c, &level)) {
        bool valid;
        sl_status st = net_reference_region_set(r, c, level, ids, capacity, count, &valid, err);
        if (st != SL_OK)
            return st;
        if (valid) {
            *validity = SL_VIS_CELL;
            *cell = c;
            return SL_OK;
        }
    }
    *validity = SL_VIS_POINT;
    *cell = SL_NONE;
    return sl_vis_reference_point(r, cam, ids, capacity, count, err);
}
