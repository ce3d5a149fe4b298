/* Shrunk occluder levels stored with the scene (Instant Visibility, Wonka's thesis ch. 6: the
 * occluders are shrunk by eps ahead of time, so that a point method run on them gives a set valid
 * for every viewpoint within eps). The bake is in src/region (sl_shrink_occluder_levels, GEOS);
 * this file holds the model: levels in ascending eps, each a list of footprint records like the
 * scene's own, in three arrays that map onto .slscene 1.2 sections (OLVL, OLFP, OLXY). */
#include "scene_internal.h"

#include <math.h>

void sl_scene_levels_free(struct sl_scene_t *s)
{
    const sl_allocator *a = &s->alloc;
    sl_array_free(a, &s->olevels, sizeof(sl_olevel_rec));
    sl_array_free(a, &s->olevel_fps, sizeof(sl_footprint_rec));
    sl_array_free(a, &s->olevel_xy, sizeof(float));
    sl_array_free(a, &s->olevel_first, sizeof(uint32_t));
}

void sl_scene_clear_occluder_levels(sl_scene s)
{
    if (s)
        sl_scene_levels_free(s);
}

uint32_t sl_scene_occluder_level_count(sl_scene s) { return s ? (uint32_t)s->olevels.count : 0; }

sl_occluder_level_view sl_scene_occluder_level(sl_scene s, uint32_t level)
{
    sl_occluder_level_view v = {0};
    if (!s || level >= s->olevels.count)
        return v;
    const sl_olevel_rec *r = &SL_AT(s->olevels, sl_olevel_rec, level);
    v.eps = r->eps;
    v.eps_z = r->eps_z;
    v.flags = r->flags;
    v.footprint_count = r->footprint_count;
    return v;
}

sl_footprint_view sl_scene_occluder_level_footprint(sl_scene s, uint32_t level, uint32_t index)
{
    sl_footprint_view v = {0};
    if (!s || level >= s->olevels.count || index >= SL_AT(s->olevels, sl_olevel_rec, level).footprint_count)
        return v;
    const sl_footprint_rec *f =
        &SL_AT(s->olevel_fps, sl_footprint_rec, (size_t)SL_AT(s->olevel_first, uint32_t, level) + index);
    v.xy = (const float *)s->olevel_xy.data + 2 * (size_t)f->first_vertex;
    v.vertex_count = f->vertex_count;
    v.base_z = f->base_z;
    v.roof_z = f->roof_z;
    v.object = f->object;
    return v;
}

/* A level's record: what is wrong with it, or NULL. */
static const char *level_problem(const sl_olevel_rec *r, const sl_olevel_rec *prev)
{
    if (!isfinite(r->eps) || !(r->eps > 0))
        return "eps must be finite and > 0";
    if (prev && !(r->eps > prev->eps))
        return "eps must be larger than the previous level's";
    if (!isfinite(r->eps_z) || !(r->eps_z >= 0) || !(r->eps_z <= r->eps))
        return "eps_z must be finite and in [0, eps]";
    if (r->flags & ~(uint32_t)SL_OCCLUDER_LEVEL_MERGED)
        return "unknown flag bits";
    return NULL;
}

sl_status sl_scene_add_occluder_level(sl_scene s, float eps, float eps_z, uint32_t flags,
                                      const sl_footprint_desc *fps, uint32_t count, sl_error *err)
{
    if (!s || (count && !fps))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_add_occluder_level: NULL argument");
    sl_olevel_rec rec = {eps, eps_z, flags, count};
    const sl_olevel_rec *prev = s->olevels.count ? &SL_AT(s->olevels, sl_olevel_rec, s->olevels.count - 1) : NULL;
    const char *why = level_problem(&rec, prev);
    if (why)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "occluder level %zu (eps %g): %s", s->olevels.count, eps, why);
    if (s->olevel_fps.count + count > UINT32_MAX - 1)
        return sl_fail(err, SL_ERROR_LIMIT, "occluder level %zu: too many footprints", s->olevels.count);
    const sl_allocator *a = &s->alloc;
    size_t fp0 = s->olevel_fps.count, xy0 = s->olevel_xy.count;
    uint32_t first = (uint32_t)fp0;
    if (!sl_array_reserve(a, &s->olevels, sizeof rec, 1) || !sl_array_reserve(a, &s->olevel_first, 4, 1) ||
        (count && !sl_array_reserve(a, &s->olevel_fps, sizeof(sl_footprint_rec), count)))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluder level %zu: out of memory", s->olevels.count);
    sl_status st = SL_OK;
    for (uint32_t i = 0; i < count && st == SL_OK; i++) {
        const sl_footprint_desc *d = &fps[i];
        char what[96];
        snprintf(what, sizeof what, "occluder level %zu: footprint %u", s->olevels.count, i);
        if (!isfinite(d->base_z) || !isfinite(d->roof_z) || !(d->roof_z > d->base_z))
            st = sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: roof height %g must exceed base height %g", what,
                         d->roof_z, d->base_z);
        else if (d->object != SL_NONE && d->object >= s->objects.count)
            st = sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: object %u does not exist", what, d->object);
        else if (d->object != SL_NONE && (sl_scene_objects(s)[d->object].flags & SL_OBJECT_SEE_THROUGH))
            st = sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: object %u is see-through: it never occludes", what,
                         d->object);
        else {
            sl_footprint_rec f = {0, 0, d->base_z, d->roof_z, d->object, 0};
            st = sl_scene_push_polygon(s, &s->olevel_xy, d->xy, d->vertex_count, what, &f.first_vertex,
                                       &f.vertex_count, err);
            if (st == SL_OK)
                sl_array_push(a, &s->olevel_fps, sizeof f, &f, 1); /* reserved above */
        }
    }
    if (st != SL_OK) { /* nothing added: drop this level's footprints again */
        s->olevel_fps.count = fp0;
        s->olevel_xy.count = xy0;
        return st;
    }
    sl_array_push(a, &s->olevels, sizeof rec, &rec, 1);
    sl_array_push(a, &s->olevel_first, 4, &first, 1);
    return SL_OK;
}

/* Signed area, summed as the .slscene reader sums the scene's footprints. */
static double ring_area(const float *xy, uint32_t n)
{
    double area = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t j = i + 1 == n ? 0 : i + 1;
        area += (double)xy[2 * i] * xy[2 * j + 1] - (double)xy[2 * j] * xy[2 * i + 1];
    }
    return 0.5 * area;
}

sl_status sl_scene_levels_load(struct sl_scene_t *s, sl_error *err)
{
    const sl_olevel_rec *lv = s->olevels.data;
    uint64_t total = 0;
    for (size_t i = 0; i < s->olevels.count; i++) {
        const char *why = level_problem(&lv[i], i ? &lv[i - 1] : NULL);
        if (why)
            return sl_fail(err, SL_ERROR_FORMAT, "occluder level %zu: %s", i, why);
        total += lv[i].footprint_count;
    }
    if (total != s->olevel_fps.count)
        return sl_fail(err, SL_ERROR_FORMAT, "occluder levels: their footprint counts add up to %llu, the section holds %zu",
                       (unsigned long long)total, s->olevel_fps.count);
    if (s->olevel_xy.count % 2)
        return sl_fail(err, SL_ERROR_FORMAT, "occluder levels: an odd number (%zu) of vertex coordinates",
                       s->olevel_xy.count);
    const float *xy = s->olevel_xy.data;
    const sl_object_rec *o = sl_scene_objects(s);
    for (size_t i = 0; i < s->olevel_fps.count; i++) {
        const sl_footprint_rec *f = &SL_AT(s->olevel_fps, sl_footprint_rec, i);
        if (f->vertex_count < 3 || (uint64_t)f->first_vertex + f->vertex_count > s->olevel_xy.count / 2)
            return sl_fail(err, SL_ERROR_FORMAT, "occluder level footprint %zu: vertex range out of bounds", i);
        if (!isfinite(f->base_z) || !isfinite(f->roof_z) || !(f->roof_z > f->base_z))
            return sl_fail(err, SL_ERROR_FORMAT, "occluder level footprint %zu: bad heights", i);
        if (f->object != SL_NONE && f->object >= s->objects.count)
            return sl_fail(err, SL_ERROR_FORMAT, "occluder level footprint %zu: object %u out of range", i, f->object);
        if (f->object != SL_NONE && (o[f->object].flags & SL_OBJECT_SEE_THROUGH))
            return sl_fail(err, SL_ERROR_FORMAT, "occluder level footprint %zu: object %u is see-through", i, f->object);
        if (f->reserved != 0)
            return sl_fail(err, SL_ERROR_FORMAT, "occluder level footprint %zu: reserved field is not zero", i);
        const float *p = xy + 2 * (size_t)f->first_vertex;
        for (uint32_t k = 0; k < 2 * f->vertex_count; k++)
            if (!isfinite(p[k]))
                return sl_fail(err, SL_ERROR_FORMAT, "occluder level footprint %zu: vertex not finite", i);
        if (!(ring_area(p, f->vertex_count) > 0))
            return sl_fail(err, SL_ERROR_FORMAT, "occluder level footprint %zu: polygon is not counter-clockwise", i);
    }
    /* the derived index: each level's first footprint */
    s->olevel_first.count = 0;
    if (s->olevels.count && !sl_array_reserve(&s->alloc, &s->olevel_first, 4, s->olevels.count))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "occluder levels: out of memory");
    uint32_t first = 0;
    for (size_t i = 0; i < s->olevels.count; i++) {
        sl_array_push(&s->alloc, &s->olevel_first, 4, &first, 1);
        first += lv[i].footprint_count;
    }
    return SL_OK;
}
