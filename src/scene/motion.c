/* Moving objects: per DYNAMIC object a motion record (the fastest it moves, the box it never
 * leaves, and optionally a deterministic path that sl_scene_animate follows). Wonka's thesis §8.5:
 * moving occludees are tested where they can be — by their current box online, by their box grown
 * by the distance they can cover while a set is displayed for Instant Visibility, by the region they
 * move in for a precomputed PVS. The records are kept in ascending object order in one array that
 * maps onto the .slscene 1.3 section MOTN (docs/motion.md). */
#include "scene_internal.h"

#include <math.h>

void sl_scene_motions_free(struct sl_scene_t *s) { sl_array_free(&s->alloc, &s->motions, sizeof(sl_motion_rec)); }

static const sl_motion_rec *recs(const struct sl_scene_t *s) { return (const sl_motion_rec *)s->motions.data; }

/* Index of the first record whose object is >= object. */
static size_t lower(const struct sl_scene_t *s, uint32_t object)
{
    size_t lo = 0, hi = s->motions.count;
    const sl_motion_rec *r = recs(s);
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (r[mid].object < object)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

const sl_motion_rec *sl_scene_motion_rec(const struct sl_scene_t *s, uint32_t object)
{
    size_t i = lower(s, object);
    return i < s->motions.count && recs(s)[i].object == object ? &recs(s)[i] : NULL;
}

static bool finite_n(const float *v, int n)
{
    for (int i = 0; i < n; i++)
        if (!isfinite(v[i]))
            return false;
    return true;
}

static bool box_ok(const sl_aabb *b)
{
    return finite_n(&b->min.x, 3) && finite_n(&b->max.x, 3) && b->min.x <= b->max.x && b->min.y <= b->max.y &&
           b->min.z <= b->max.z;
}

static bool box_inside(const sl_aabb *in, const sl_aabb *out)
{
    return in->min.x >= out->min.x && in->min.y >= out->min.y && in->min.z >= out->min.z && in->max.x <= out->max.x &&
           in->max.y <= out->max.y && in->max.z <= out->max.z;
}

static double path_length(const sl_motion_rec *r)
{
    double dx = (double)r->to[0] - r->from[0], dy = (double)r->to[1] - r->from[1], dz = (double)r->to[2] - r->from[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

/* The pose at path parameter d (metres, any finite value: wrapped to [0, 2L)). */
static sl_affine pose_at(const sl_motion_rec *r, const sl_aabb *mesh_box, double d)
{
    double L = path_length(r);
    double w = fmod(d, 2 * L);
    if (w < 0)
        w += 2 * L;
    bool back = w >= L;
    double u = back ? (2 * L - w) / L : w / L;
    sl_affine t = r->base;
    if (back) {
        /* half a turn about the vertical axis through the base pose's box centre: x' = 2c - x */
        sl_aabb b = sl_aabb_transform(mesh_box, &r->base);
        double cx = 0.5 * ((double)b.min.x + b.max.x), cy = 0.5 * ((double)b.min.y + b.max.y);
        for (int j = 0; j < 3; j++) {
            t.m[0 * 4 + j] = -t.m[0 * 4 + j];
            t.m[1 * 4 + j] = -t.m[1 * 4 + j];
        }
        t.m[3] = (float)(2 * cx - r->base.m[3]);
        t.m[7] = (float)(2 * cy - r->base.m[7]);
    }
    for (int i = 0; i < 3; i++)
        t.m[i * 4 + 3] = (float)((double)t.m[i * 4 + 3] + u * ((double)r->to[i] - r->from[i]));
    return t;
}

/* What is wrong with a record of an object whose mesh has box mesh_box, or NULL. */
static const char *rec_problem(const sl_motion_rec *r, const sl_aabb *mesh_box)
{
    if (!isfinite(r->max_speed) || !(r->max_speed >= 0))
        return "max_speed must be finite and >= 0";
    if (!box_ok(&r->region))
        return "region must be a finite box with min <= max";
    if (r->flags & ~(uint32_t)SL_MOTION_REC_PATH)
        return "unknown flag bits";
    if (r->reserved0 || r->reserved[0] || r->reserved[1])
        return "reserved fields must be zero";
    if (!(r->flags & SL_MOTION_REC_PATH)) {
        if (r->speed != 0 || r->phase != 0 || !finite_n(r->from, 3) || !finite_n(r->to, 3) || !finite_n(r->base.m, 12))
            return "a record without a path has zero speed and phase and finite path fields";
        return NULL;
    }
    if (!finite_n(r->from, 3) || !finite_n(r->to, 3) || !finite_n(r->base.m, 12))
        return "path fields must be finite";
    double L = path_length(r);
    if (!(L > 0) || !isfinite(L))
        return "the path's ends must differ";
    if (!isfinite(r->speed) || !(r->speed > 0) || !(r->speed <= r->max_speed))
        return "path speed must be in (0, max_speed]";
    if (!isfinite(r->phase) || !(r->phase >= 0) || !((double)r->phase < 2 * L))
        return "phase must be in [0, 2 * path length)";
    if (sl_aabb_is_empty(mesh_box))
        return "an object with an empty mesh has no path";
    /* the box along the path: the hull of the boxes at both ends (the path is straight), turned
     * poses included (their world box is the same up to rounding, checked too) */
    double ds[4] = {0, path_length(r), 2 * path_length(r) - 1e-9 * path_length(r), path_length(r) * 1.5};
    for (int k = 0; k < 4; k++) {
        sl_affine t = pose_at(r, mesh_box, ds[k]);
        sl_aabb b = sl_aabb_transform(mesh_box, &t);
        if (!box_inside(&b, &r->region))
            return "the object's box along its path leaves its region";
    }
    return NULL;
}

static sl_motion_rec to_rec(uint32_t object, const sl_object_motion *m)
{
    sl_motion_rec r;
    memset(&r, 0, sizeof r);
    r.object = object;
    r.max_speed = m->max_speed;
    r.region = m->region;
    if (m->has_path) {
        r.flags = SL_MOTION_REC_PATH;
        r.speed = m->speed;
        r.phase = m->phase;
        r.from[0] = m->from.x, r.from[1] = m->from.y, r.from[2] = m->from.z;
        r.to[0] = m->to.x, r.to[1] = m->to.y, r.to[2] = m->to.z;
        r.base = m->path_base;
    } else {
        r.base = sl_affine_identity();
    }
    return r;
}

static sl_aabb mesh_box_of(const struct sl_scene_t *s, uint32_t object)
{
    return sl_scene_meshes(s)[sl_scene_objects(s)[object].mesh].bounds;
}

sl_status sl_scene_set_object_motion(sl_scene s, uint32_t object, const sl_object_motion *m, sl_error *err)
{
    if (!s || object >= s->objects.count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_set_object_motion: bad object %u", object);
    const sl_allocator *a = &s->alloc;
    if (!sl_array_own(a, &s->motions, sizeof(sl_motion_rec)))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_set_object_motion: out of memory");
    size_t i = lower(s, object);
    bool here = i < s->motions.count && recs(s)[i].object == object;
    if (!m) {
        if (here) {
            sl_motion_rec *r = (sl_motion_rec *)s->motions.data;
            memmove(r + i, r + i + 1, (s->motions.count - i - 1) * sizeof *r);
            s->motions.count--;
        }
        return SL_OK;
    }
    if (!(sl_scene_objects(s)[object].flags & SL_OBJECT_DYNAMIC))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "object %u: a motion record needs a DYNAMIC object", object);
    sl_motion_rec r = to_rec(object, m);
    sl_aabb mb = mesh_box_of(s, object);
    const char *why = rec_problem(&r, &mb);
    if (why)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "object %u: motion: %s", object, why);
    if (here) {
        ((sl_motion_rec *)s->motions.data)[i] = r;
        return SL_OK;
    }
    if (!sl_array_reserve(a, &s->motions, sizeof r, 1))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_scene_set_object_motion: out of memory");
    sl_array_push(a, &s->motions, sizeof r, NULL, 1);
    sl_motion_rec *d = (sl_motion_rec *)s->motions.data;
    memmove(d + i + 1, d + i, (s->motions.count - 1 - i) * sizeof *d);
    d[i] = r;
    return SL_OK;
}

bool sl_scene_object_motion(sl_scene s, uint32_t object, sl_object_motion *out)
{
    if (!s || !out)
        return false;
    const sl_motion_rec *r = sl_scene_motion_rec(s, object);
    if (!r)
        return false;
    memset(out, 0, sizeof *out);
    out->max_speed = r->max_speed;
    out->region = r->region;
    out->has_path = (r->flags & SL_MOTION_REC_PATH) != 0;
    if (out->has_path) {
        out->path_base = r->base;
        out->from = (sl_vec3){r->from[0], r->from[1], r->from[2]};
        out->to = (sl_vec3){r->to[0], r->to[1], r->to[2]};
        out->speed = r->speed;
        out->phase = r->phase;
    }
    return true;
}

uint32_t sl_scene_motion_count(sl_scene s) { return s ? (uint32_t)s->motions.count : 0; }

uint32_t sl_scene_path_count(sl_scene s)
{
    uint32_t n = 0;
    for (size_t i = 0; s && i < s->motions.count; i++)
        n += (recs(s)[i].flags & SL_MOTION_REC_PATH) != 0;
    return n;
}

sl_status sl_scene_animate(sl_scene s, double t, sl_error *err)
{
    if (!s)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_animate: NULL scene");
    if (!isfinite(t))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_animate: time %g is not finite", t);
    for (size_t i = 0; i < s->motions.count; i++) {
        const sl_motion_rec *r = &recs(s)[i];
        if (!(r->flags & SL_MOTION_REC_PATH))
            continue;
        sl_aabb mb = mesh_box_of(s, r->object);
        sl_affine pose = pose_at(r, &mb, (double)r->phase + (double)r->speed * t);
        sl_status st = sl_scene_set_object_transform(s, r->object, &pose, err);
        if (st != SL_OK)
            return st;
    }
    return SL_OK;
}

sl_status sl_scene_motions_load(struct sl_scene_t *s, sl_error *err)
{
    const sl_motion_rec *r = recs(s);
    for (size_t i = 0; i < s->motions.count; i++) {
        if (r[i].object >= s->objects.count)
            return sl_fail(err, SL_ERROR_FORMAT, "motion record %zu: object %u out of range (%zu objects)", i,
                           r[i].object, s->objects.count);
        if (i && r[i].object <= r[i - 1].object)
            return sl_fail(err, SL_ERROR_FORMAT, "motion record %zu: objects not strictly ascending", i);
        if (!(sl_scene_objects(s)[r[i].object].flags & SL_OBJECT_DYNAMIC))
            return sl_fail(err, SL_ERROR_FORMAT, "motion record %zu: object %u is not DYNAMIC", i, r[i].object);
        sl_aabb mb = mesh_box_of(s, r[i].object);
        const char *why = rec_problem(&r[i], &mb);
        if (why)
            return sl_fail(err, SL_ERROR_FORMAT, "motion record %zu (object %u): %s", i, r[i].object, why);
    }
    return SL_OK;
}
