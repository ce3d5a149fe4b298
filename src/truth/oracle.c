/* The exact point oracle: which objects does a viewpoint see, and with how many pixels?
 *
 * Every object whose world box meets the view frustum is drawn triangle by triangle with the
 * reference rasterizer (raster_ref.c) into an id + reversed-depth buffer; the objects owning at
 * least one pixel form the visible set. The object boxes are only a shortcut: a box decides
 * nothing a triangle would decide differently, since each triangle is clipped and tested itself.
 *
 * Threads: the objects in the frustum are dealt to threads by a fixed rule (each to the thread
 * with the fewest triangles so far, in id order); each thread draws its objects into its own
 * full-size buffer, and the buffers are merged pixel by pixel. The depth rule (nearest wins, ties
 * to the lower id) makes the kept fragment independent of drawing order and of the split, so the
 * merged buffer is bit for bit what one thread drawing everything produces. Threads share nothing
 * writable; no atomics. Every thread transforms only its own objects' vertices, so the whole
 * pipeline (not only pixel filling) is divided.
 */
#include "sightline/truth.h"

#include "open_space.h"
#include "raster/raster_ref.h"
#include "scene/scene_internal.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>

/* An object that may cover pixels of the current view, and the thread that draws it. */
typedef struct frustum_entry {
    uint32_t object;
    uint32_t thread;
} frustum_entry;

/* A see-through object's pixels in one view (docs/oracle.md, "See-through objects"): pixels where
 * one of its fragments is at least as near as the solid surface; open: one of them passes rule 4. */
typedef struct see_through_hit {
    uint32_t object;
    uint32_t pixels;
    bool open;
} see_through_hit;

struct sl_oracle_t {
    sl_allocator alloc;
    sl_scene scene;
    sl_oracle_options opt;

    /* buffers of the last render: view_count views of width*height pixels each */
    uint32_t view_count, width, height;
    uint32_t *ids;
    float *depth;
    uint32_t *overdraw;
    size_t pixel_cap;
    sl_mat4 view_proj[SL_ORACLE_MAX_SAMPLES > 6 ? SL_ORACLE_MAX_SAMPLES : 6];
    double sample_pos[SL_ORACLE_MAX_SAMPLES > 6 ? SL_ORACLE_MAX_SAMPLES : 6][2]; /* per view: where it samples */

    sl_refrast_scratch *scratch; /* one per thread */
    /* private buffers of helper threads 1..threads-1, helper_cap pixels each */
    uint32_t *helper_ids;
    float *helper_depth;
    uint32_t *helper_overdraw;
    size_t helper_cap;

    sl_array frustum;           /* frustum_entry, ascending object ids */
    uint32_t *counts;           /* pixels per object id while counting; all zero between renders */
    size_t counts_cap;
    sl_array visible;           /* uint32 */
    sl_array visible_pixels;    /* uint32 */

    /* see-through objects: their own id + depth buffer (one view), and what they showed */
    uint32_t *st_ids;
    float *st_depth;
    size_t st_cap;
    sl_array st_hits;           /* see_through_hit, over all views of the render */
};

sl_oracle_options sl_oracle_default_options(void)
{
    sl_oracle_options o;
    memset(&o, 0, sizeof o);
    o.threads = 2;
    return o;
}

sl_status sl_oracle_create(sl_scene scene, const sl_oracle_options *options, const sl_allocator *alloc,
                           sl_oracle *out, sl_error *err)
{
    if (!scene || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_oracle_create: scene and out must not be NULL");
    *out = NULL;
    sl_oracle_options opt = options ? *options : sl_oracle_default_options();
    if (opt.threads < 1 || opt.threads > SL_ORACLE_MAX_THREADS)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_oracle_create: threads = %u is outside 1..%u",
                       opt.threads, SL_ORACLE_MAX_THREADS);
    if ((opt.width == 0) != (opt.height == 0))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "sl_oracle_create: width = %u and height = %u: give both or neither (0: camera's size)",
                       opt.width, opt.height);
    if (opt.width > SL_ORACLE_MAX_SIZE || opt.height > SL_ORACLE_MAX_SIZE ||
        (uint64_t)opt.width * opt.height > SL_ORACLE_MAX_PIXELS)
        return sl_fail(err, SL_ERROR_LIMIT, "sl_oracle_create: resolution %ux%u exceeds the limit (%u per side, %u pixels)",
                       opt.width, opt.height, SL_ORACLE_MAX_SIZE, SL_ORACLE_MAX_PIXELS);
    if ((uint32_t)opt.samples > SL_ORACLE_SAMPLES_JITTER)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_oracle_create: samples = %u is not a sample pattern (0..2)",
                       (unsigned)opt.samples);
    if (opt.samples == SL_ORACLE_SAMPLES_JITTER && opt.sample_count > SL_ORACLE_MAX_SAMPLES)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_oracle_create: sample_count = %u is outside 1..%u",
                       opt.sample_count, SL_ORACLE_MAX_SAMPLES);
    alloc = sl_alloc_or_default(alloc);
    struct sl_oracle_t *o = sl_calloc(alloc, 1, sizeof *o);
    if (!o)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_oracle_create: out of memory");
    o->alloc = *alloc;
    o->scene = scene;
    o->opt = opt;
    o->scratch = sl_calloc(alloc, opt.threads, sizeof *o->scratch);
    if (!o->scratch) {
        sl_free(alloc, o, sizeof *o);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_oracle_create: out of memory");
    }
    *out = o;
    return SL_OK;
}

static void free_pixels(struct sl_oracle_t *o)
{
    const sl_allocator *a = &o->alloc;
    size_t helpers = o->helper_cap * (o->opt.threads - 1);
    sl_free(a, o->ids, o->pixel_cap * sizeof(uint32_t));
    sl_free(a, o->depth, o->pixel_cap * sizeof(float));
    sl_free(a, o->overdraw, o->pixel_cap * sizeof(uint32_t));
    sl_free(a, o->helper_ids, helpers * sizeof(uint32_t));
    sl_free(a, o->helper_depth, helpers * sizeof(float));
    sl_free(a, o->helper_overdraw, helpers * sizeof(uint32_t));
    o->ids = NULL;
    o->depth = NULL;
    o->overdraw = NULL;
    o->helper_ids = NULL;
    o->helper_depth = NULL;
    o->helper_overdraw = NULL;
    o->pixel_cap = 0;
    o->helper_cap = 0;
}

void sl_oracle_destroy(sl_oracle o)
{
    if (!o)
        return;
    const sl_allocator *a = &o->alloc;
    free_pixels(o);
    for (uint32_t t = 0; t < o->opt.threads; t++)
        sl_refrast_scratch_free(a, &o->scratch[t]);
    sl_free(a, o->scratch, o->opt.threads * sizeof *o->scratch);
    sl_array_free(a, &o->frustum, sizeof(frustum_entry));
    sl_free(a, o->counts, o->counts_cap * sizeof(uint32_t));
    sl_array_free(a, &o->visible, sizeof(uint32_t));
    sl_array_free(a, &o->visible_pixels, sizeof(uint32_t));
    sl_free(a, o->st_ids, o->st_cap * sizeof(uint32_t));
    sl_free(a, o->st_depth, o->st_cap * sizeof(float));
    sl_array_free(a, &o->st_hits, sizeof(see_through_hit));
    sl_free(a, o, sizeof *o);
}

/* Make room for `views` views of w*h pixels, plus one view per helper thread (previous contents
 * are not kept). */
static sl_status reserve_pixels(struct sl_oracle_t *o, uint32_t views, uint32_t w, uint32_t h, sl_error *err)
{
    size_t px = (size_t)w * h, need = (size_t)views * px, helpers = (size_t)(o->opt.threads - 1) * px;
    bool need_overdraw = o->opt.count_overdraw;
    if (need <= o->pixel_cap && px <= o->helper_cap)
        return SL_OK;
    free_pixels(o);
    const sl_allocator *a = &o->alloc;
    o->ids = sl_alloc(a, need * sizeof(uint32_t));
    o->depth = sl_alloc(a, need * sizeof(float));
    o->overdraw = need_overdraw ? sl_alloc(a, need * sizeof(uint32_t)) : NULL;
    o->pixel_cap = need;
    o->helper_ids = helpers ? sl_alloc(a, helpers * sizeof(uint32_t)) : NULL;
    o->helper_depth = helpers ? sl_alloc(a, helpers * sizeof(float)) : NULL;
    o->helper_overdraw = helpers && need_overdraw ? sl_alloc(a, helpers * sizeof(uint32_t)) : NULL;
    o->helper_cap = px;
    if (!o->ids || !o->depth || (need_overdraw && !o->overdraw) ||
        (helpers && (!o->helper_ids || !o->helper_depth || (need_overdraw && !o->helper_overdraw)))) {
        free_pixels(o);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "oracle: out of memory for %u view(s) of %ux%u pixels", views, w, h);
    }
    return SL_OK;
}

/* ---- one view ---- */

typedef struct view_job {
    struct sl_oracle_t *o;
    const double *vp;
    sl_refrast_target targets[SL_ORACLE_MAX_THREADS];
} view_job;

typedef struct thread_arg {
    const view_job *job;
    uint32_t thread;
    pthread_t handle;
    bool started;
} thread_arg;

static double affine_det(const sl_affine *t)
{
    const float *m = t->m;
    return (double)m[0] * ((double)m[5] * m[10] - (double)m[6] * m[9]) -
           (double)m[1] * ((double)m[4] * m[10] - (double)m[6] * m[8]) +
           (double)m[2] * ((double)m[4] * m[9] - (double)m[5] * m[8]);
}

/* One thread: clear its buffer and draw the objects dealt to it. */
static void *run_thread(void *p)
{
    thread_arg *arg = p;
    const view_job *job = arg->job;
    struct sl_oracle_t *o = job->o;
    const struct sl_scene_t *s = o->scene;
    const sl_refrast_target *t = &job->targets[arg->thread];
    sl_refrast_scratch *scratch = &o->scratch[arg->thread];
    sl_refrast_clear(t);

    const sl_mesh_rec *meshes = sl_scene_meshes(s);
    const sl_object_rec *objects = sl_scene_objects(s);
    const sl_affine *transforms = sl_scene_transforms(s);
    const float *positions = sl_scene_positions(s);
    const uint32_t *indices = sl_scene_indices(s);
    const frustum_entry *list = o->frustum.data;
    const sl_affine identity = sl_affine_identity();
    for (size_t i = 0; i < o->frustum.count; i++) {
        const sl_object_rec *obj = &objects[list[i].object];
        if (list[i].thread != arg->thread || (obj->flags & SL_OBJECT_SEE_THROUGH))
            continue; /* see-through objects write no depth: drawn after the solids (see_through_pass) */
        const sl_mesh_rec *mesh = &meshes[obj->mesh];
        const sl_affine *xf = obj->transform == SL_NONE ? &identity : &transforms[obj->transform];
        double m[16];
        sl_refrast_compose(job->vp, xf, m);
        sl_refrast_cull cull = SL_REFRAST_CULL_NONE;
        if ((obj->flags & SL_OBJECT_CLOSED_CONVEX) && !o->opt.draw_closed_backfaces)
            /* a mirroring transform turns the mesh's front faces into back faces */
            cull = affine_det(xf) < 0 ? SL_REFRAST_CULL_FRONT : SL_REFRAST_CULL_BACK;
        sl_refrast_mesh(t, scratch, m, positions + 3 * mesh->first_vertex, mesh->vertex_count,
                        indices + mesh->first_index, mesh->triangle_count, list[i].object, cull);
    }
    return NULL;
}

static sl_status see_through_pass(struct sl_oracle_t *o, uint32_t v, const double vp[16], const sl_refrast_target *solid,
                                  sl_error *err);

/* Draw view `v` of the current render with the world-to-clip matrix vp (column-major floats),
 * sampling every pixel at (sx, sy) from its top-left corner: the clip-space x and y are moved by
 * the offset that puts the pixel centres of the moved image on those positions (applied in double
 * to the float matrix; the stored matrix rounds it). Only a view with `count` adds to the frame's
 * frustum counts (the sample passes of one camera render count once). */
static sl_status render_view(struct sl_oracle_t *o, uint32_t v, const sl_mat4 *vpf, double sx, double sy, bool count,
                             sl_oracle_frame *frame, sl_error *err)
{
    const struct sl_scene_t *s = o->scene;
    const uint32_t T = o->opt.threads;
    double vp[16];
    for (int i = 0; i < 16; i++)
        vp[i] = vpf->m[i];
    /* screen X = (x_ndc + 1) W / 2: the sample at X = px + sx lands on the centre px + 0.5 when X
     * grows by 0.5 - sx, i.e. x_ndc by 2 (0.5 - sx) / W; Y = (1 - y_ndc) H / 2 grows down */
    double tx = 2.0 * (0.5 - sx) / (double)o->width, ty = -2.0 * (0.5 - sy) / (double)o->height;
    if (tx != 0 || ty != 0)
        for (int c = 0; c < 4; c++) {
            vp[4 * c] += tx * vp[4 * c + 3];
            vp[4 * c + 1] += ty * vp[4 * c + 3];
        }
    for (int i = 0; i < 16; i++)
        o->view_proj[v].m[i] = (float)vp[i];
    o->sample_pos[v][0] = sx;
    o->sample_pos[v][1] = sy;

    /* objects that may cover a pixel, each dealt to the thread with the fewest triangles so far
     * (a fixed rule: the split depends on the scene and the view only) */
    const sl_object_rec *objects = sl_scene_objects(s);
    const sl_mesh_rec *meshes = sl_scene_meshes(s);
    const sl_aabb *bounds = sl_scene_object_bounds_array(o->scene);
    uint32_t n = sl_scene_object_count(o->scene);
    uint32_t max_vertices[SL_ORACLE_MAX_THREADS] = {0};
    uint64_t load[SL_ORACLE_MAX_THREADS] = {0};
    o->frustum.count = 0;
    for (uint32_t i = 0; i < n; i++) {
        const sl_mesh_rec *mesh = &meshes[objects[i].mesh];
        if (mesh->triangle_count == 0 || !sl_refrast_box_visible(vp, &bounds[i], o->width, o->height))
            continue;
        frustum_entry e = {i, 0};
        for (uint32_t t = 1; t < T; t++)
            if (load[t] < load[e.thread])
                e.thread = t;
        /* a vertex costs about as much as a triangle */
        load[e.thread] += (uint64_t)mesh->triangle_count + mesh->vertex_count;
        max_vertices[e.thread] = SL_MAX(max_vertices[e.thread], mesh->vertex_count);
        if (!sl_array_push(&o->alloc, &o->frustum, sizeof e, &e, 1))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "oracle: out of memory for the frustum list");
        if (count) {
            frame->objects_in_frustum++;
            frame->triangles_in_frustum += mesh->triangle_count;
        }
    }
    for (uint32_t t = 0; t < T; t++)
        if (!sl_refrast_scratch_reserve(&o->alloc, &o->scratch[t], max_vertices[t]))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "oracle: out of memory for %u transformed vertices",
                           max_vertices[t]);

    size_t px = (size_t)o->width * o->height;
    view_job job;
    memset(&job, 0, sizeof job);
    job.o = o;
    job.vp = vp;
    for (uint32_t t = 0; t < T; t++) {
        sl_refrast_target *g = &job.targets[t];
        g->width = o->width;
        g->height = o->height;
        g->guard_x = 2.0 * SL_REFRAST_GUARD_PX / o->width;
        g->guard_y = 2.0 * SL_REFRAST_GUARD_PX / o->height;
        if (t == 0) {
            g->ids = o->ids + (size_t)v * px;
            g->depth = o->depth + (size_t)v * px;
            g->overdraw = o->overdraw ? o->overdraw + (size_t)v * px : NULL;
        } else {
            g->ids = o->helper_ids + (size_t)(t - 1) * px;
            g->depth = o->helper_depth + (size_t)(t - 1) * px;
            g->overdraw = o->helper_overdraw ? o->helper_overdraw + (size_t)(t - 1) * px : NULL;
        }
    }

    thread_arg args[SL_ORACLE_MAX_THREADS];
    for (uint32_t t = 0; t < T; t++) {
        args[t].job = &job;
        args[t].thread = t;
        args[t].started = false;
    }
    for (uint32_t t = 1; t < T; t++)
        args[t].started = pthread_create(&args[t].handle, NULL, run_thread, &args[t]) == 0;
    run_thread(&args[0]);
    /* a thread that could not be started has its objects drawn here: same buffer, same result */
    for (uint32_t t = 1; t < T; t++) {
        if (args[t].started)
            pthread_join(args[t].handle, NULL);
        else
            run_thread(&args[t]);
    }
    for (uint32_t t = 1; t < T; t++)
        sl_refrast_merge(&job.targets[0], &job.targets[t], 0, o->height);
    return see_through_pass(o, v, vp, &job.targets[0], err);
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

/* ---- sight lines through solid space (maps) ---- */

/* Front-to-back walk of p0-p1 below `node`: false once the segment enters solid after open space
 * (*seen_open records open space met so far). */
static bool walk_open(const sl_bsp_view *bsp, int32_t node, const double p0[3], const double p1[3], bool *seen_open)
{
    while (node >= 0) {
        const sl_bsp_node *nd = &bsp->nodes[node];
        const sl_plane *pl = &bsp->planes[nd->plane];
        double d0 = pl->a * p0[0] + pl->b * p0[1] + pl->c * p0[2] + pl->d;
        double d1 = pl->a * p1[0] + pl->b * p1[1] + pl->c * p1[2] + pl->d;
        if ((d0 >= 0) == (d1 >= 0)) {
            node = nd->children[d0 >= 0 ? 0 : 1];
            continue;
        }
        double t = d0 / (d0 - d1), mid[3];
        for (int k = 0; k < 3; k++)
            mid[k] = p0[k] + t * (p1[k] - p0[k]);
        return walk_open(bsp, nd->children[d0 >= 0 ? 0 : 1], p0, mid, seen_open) &&
               walk_open(bsp, nd->children[d0 >= 0 ? 1 : 0], mid, p1, seen_open);
    }
    if (bsp->leaves[-(node + 1)].cluster >= 0) {
        *seen_open = true;
        return true;
    }
    return !*seen_open;
}

bool sl_bsp_sight_line_open(const sl_bsp_view *bsp, const double p0[3], const double p1[3], bool solid_start)
{
    if (!bsp->node_count)
        return true;
    bool seen_open = !solid_start;
    return walk_open(bsp, 0, p0, p1, &seen_open);
}

/* Inverse of a column-major 4x4 matrix in double (cofactors); false when singular. */
static bool invert4(const float *m, double inv[16])
{
    double a[16];
    for (int i = 0; i < 16; i++)
        a[i] = m[i];
    inv[0] = a[5] * a[10] * a[15] - a[5] * a[11] * a[14] - a[9] * a[6] * a[15] + a[9] * a[7] * a[14] +
             a[13] * a[6] * a[11] - a[13] * a[7] * a[10];
    inv[4] = -a[4] * a[10] * a[15] + a[4] * a[11] * a[14] + a[8] * a[6] * a[15] - a[8] * a[7] * a[14] -
             a[12] * a[6] * a[11] + a[12] * a[7] * a[10];
    inv[8] = a[4] * a[9] * a[15] - a[4] * a[11] * a[13] - a[8] * a[5] * a[15] + a[8] * a[7] * a[13] +
             a[12] * a[5] * a[11] - a[12] * a[7] * a[9];
    inv[12] = -a[4] * a[9] * a[14] + a[4] * a[10] * a[13] + a[8] * a[5] * a[14] - a[8] * a[6] * a[13] -
              a[12] * a[5] * a[10] + a[12] * a[6] * a[9];
    inv[1] = -a[1] * a[10] * a[15] + a[1] * a[11] * a[14] + a[9] * a[2] * a[15] - a[9] * a[3] * a[14] -
             a[13] * a[2] * a[11] + a[13] * a[3] * a[10];
    inv[5] = a[0] * a[10] * a[15] - a[0] * a[11] * a[14] - a[8] * a[2] * a[15] + a[8] * a[3] * a[14] +
             a[12] * a[2] * a[11] - a[12] * a[3] * a[10];
    inv[9] = -a[0] * a[9] * a[15] + a[0] * a[11] * a[13] + a[8] * a[1] * a[15] - a[8] * a[3] * a[13] -
             a[12] * a[1] * a[11] + a[12] * a[3] * a[9];
    inv[13] = a[0] * a[9] * a[14] - a[0] * a[10] * a[13] - a[8] * a[1] * a[14] + a[8] * a[2] * a[13] +
              a[12] * a[1] * a[10] - a[12] * a[2] * a[9];
    inv[2] = a[1] * a[6] * a[15] - a[1] * a[7] * a[14] - a[5] * a[2] * a[15] + a[5] * a[3] * a[14] +
             a[13] * a[2] * a[7] - a[13] * a[3] * a[6];
    inv[6] = -a[0] * a[6] * a[15] + a[0] * a[7] * a[14] + a[4] * a[2] * a[15] - a[4] * a[3] * a[14] -
             a[12] * a[2] * a[7] + a[12] * a[3] * a[6];
    inv[10] = a[0] * a[5] * a[15] - a[0] * a[7] * a[13] - a[4] * a[1] * a[15] + a[4] * a[3] * a[13] +
              a[12] * a[1] * a[7] - a[12] * a[3] * a[5];
    inv[14] = -a[0] * a[5] * a[14] + a[0] * a[6] * a[13] + a[4] * a[1] * a[14] - a[4] * a[2] * a[13] -
              a[12] * a[1] * a[6] + a[12] * a[2] * a[5];
    inv[3] = -a[1] * a[6] * a[11] + a[1] * a[7] * a[10] + a[5] * a[2] * a[11] - a[5] * a[3] * a[10] -
             a[9] * a[2] * a[7] + a[9] * a[3] * a[6];
    inv[7] = a[0] * a[6] * a[11] - a[0] * a[7] * a[10] - a[4] * a[2] * a[11] + a[4] * a[3] * a[10] +
             a[8] * a[2] * a[7] - a[8] * a[3] * a[6];
    inv[11] = -a[0] * a[5] * a[11] + a[0] * a[7] * a[9] + a[4] * a[1] * a[11] - a[4] * a[3] * a[9] -
              a[8] * a[1] * a[7] + a[8] * a[3] * a[5];
    inv[15] = a[0] * a[5] * a[10] - a[0] * a[6] * a[9] - a[4] * a[1] * a[10] + a[4] * a[2] * a[9] +
              a[8] * a[1] * a[6] - a[8] * a[2] * a[5];
    double det = a[0] * inv[0] + a[1] * inv[4] + a[2] * inv[8] + a[3] * inv[12];
    if (!(fabs(det) > 0) || !isfinite(det))
        return false;
    for (int i = 0; i < 16; i++)
        inv[i] /= det;
    return true;
}

/* The world point of NDC (x, y, z) through the inverse view-projection; false at infinity. */
static bool unproject(const double inv[16], double x, double y, double z, double out[3])
{
    double w = inv[3] * x + inv[7] * y + inv[11] * z + inv[15];
    if (!(fabs(w) > 0))
        return false;
    for (int k = 0; k < 3; k++)
        out[k] = (inv[k] * x + inv[4 + k] * y + inv[8 + k] * z + inv[12 + k]) / w;
    return true;
}

#define OPEN_BIT 0x80000000u

/* Rule 4 of docs/oracle.md: on a map, an object counts only when one of its pixels is seen along a
 * sight line that, from the near plane to just before the surface (2 mm or 0.01% short), never
 * enters solid space from open space. Marks OPEN_BIT in o->counts of such objects; the pixels of
 * an object are traced until one passes. */
/* Whether the sight line to pixel (x, y) at stored depth d passes rule 4 (ok: inv is valid). */
static bool pixel_open(const struct sl_oracle_t *o, const sl_bsp_view *bsp, const double inv[16], bool ok, uint32_t x,
                       uint32_t y, float d)
{
    double nx = 2.0 * (x + 0.5) / o->width - 1.0, ny = 1.0 - 2.0 * (y + 0.5) / o->height;
    double a[3], b[3];
    if (!ok || !unproject(inv, nx, ny, -1.0, a) || !unproject(inv, nx, ny, 1.0 - 2.0 * d, b))
        return true; /* cannot tell: keep it (the safe side for a judge) */
    double len2 = 0, dir[3];
    for (int k = 0; k < 3; k++) {
        dir[k] = b[k] - a[k];
        len2 += dir[k] * dir[k];
    }
    double keep = 1.0 - fmax(1e-4, 2e-3 / fmax(sqrt(len2), 1e-9));
    if (keep <= 0)
        return true;
    for (int k = 0; k < 3; k++)
        b[k] = a[k] + keep * dir[k];
    return sl_bsp_sight_line_open(bsp, a, b, true);
}

static void mark_open(struct sl_oracle_t *o, const sl_bsp_view *bsp)
{
    size_t px = (size_t)o->width * o->height;
    for (uint32_t v = 0; v < o->view_count; v++) {
        double inv[16];
        bool ok = invert4(o->view_proj[v].m, inv);
        const uint32_t *ids = o->ids + v * px;
        const float *depth = o->depth + v * px;
        for (uint32_t y = 0; y < o->height; y++)
            for (uint32_t x = 0; x < o->width; x++) {
                size_t i = (size_t)y * o->width + x;
                uint32_t id = ids[i];
                if (id == SL_NONE || (o->counts[id] & OPEN_BIT))
                    continue;
                if (pixel_open(o, bsp, inv, ok, x, y, depth[i]))
                    o->counts[id] |= OPEN_BIT;
            }
    }
}

/* Conservative pixel rectangle [x0, x1) x [y0, y1) that a box's fragments can fall in: the hull
 * of its projected corners plus a pixel, or the whole screen when a corner is not in front. */
static void box_rect(const struct sl_oracle_t *o, const double vp[16], const sl_aabb *b, uint32_t r[4])
{
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (int c = 0; c < 8; c++) {
        double p[3] = {c & 1 ? b->max.x : b->min.x, c & 2 ? b->max.y : b->min.y, c & 4 ? b->max.z : b->min.z};
        double cx = vp[0] * p[0] + vp[4] * p[1] + vp[8] * p[2] + vp[12];
        double cy = vp[1] * p[0] + vp[5] * p[1] + vp[9] * p[2] + vp[13];
        double cw = vp[3] * p[0] + vp[7] * p[1] + vp[11] * p[2] + vp[15];
        if (!(cw > 1e-9)) {
            r[0] = 0, r[1] = 0, r[2] = o->width, r[3] = o->height;
            return;
        }
        double sx = (cx / cw + 1.0) * 0.5 * o->width, sy = (1.0 - cy / cw) * 0.5 * o->height;
        lo[0] = fmin(lo[0], sx), hi[0] = fmax(hi[0], sx);
        lo[1] = fmin(lo[1], sy), hi[1] = fmax(hi[1], sy);
    }
    double lim[2] = {o->width, o->height};
    for (int k = 0; k < 2; k++) {
        double a = floor(lo[k]) - 1, z = ceil(hi[k]) + 2;
        r[k] = (uint32_t)fmin(fmax(a, 0), lim[k]);
        r[2 + k] = (uint32_t)fmin(fmax(z, 0), lim[k]);
    }
}

/* The see-through rule (docs/oracle.md): after the solids, each see-through object in the frustum
 * is drawn alone into its own buffer; it shows at every pixel where its nearest fragment is at
 * least as near as the solid depth there (ties: seen, as a decal on a wall is). It writes no depth,
 * so it hides nothing, and the order of these objects does not matter. */
static sl_status see_through_pass(struct sl_oracle_t *o, uint32_t v, const double vp[16], const sl_refrast_target *solid,
                                  sl_error *err)
{
    const struct sl_scene_t *s = o->scene;
    const sl_object_rec *objects = sl_scene_objects(s);
    const sl_mesh_rec *meshes = sl_scene_meshes(s);
    const sl_affine *transforms = sl_scene_transforms(s);
    const sl_aabb *bounds = sl_scene_object_bounds_array(o->scene);
    const frustum_entry *list = o->frustum.data;
    const sl_affine identity = sl_affine_identity();
    size_t px = (size_t)o->width * o->height;
    sl_bsp_view bsp;
    bool rule4 = !o->opt.see_through_solid && sl_scene_bsp(o->scene, &bsp) && bsp.node_count > 0;
    double inv[16];
    bool inv_ok = rule4 && invert4(o->view_proj[v].m, inv);
    for (size_t i = 0; i < o->frustum.count; i++) {
        uint32_t id = list[i].object;
        const sl_object_rec *obj = &objects[id];
        if (!(obj->flags & SL_OBJECT_SEE_THROUGH))
            continue;
        if (o->st_cap < px) {
            sl_free(&o->alloc, o->st_ids, o->st_cap * sizeof(uint32_t));
            sl_free(&o->alloc, o->st_depth, o->st_cap * sizeof(float));
            o->st_ids = sl_alloc(&o->alloc, px * sizeof(uint32_t));
            o->st_depth = sl_alloc(&o->alloc, px * sizeof(float));
            o->st_cap = px;
            if (!o->st_ids || !o->st_depth) {
                sl_free(&o->alloc, o->st_ids, px * sizeof(uint32_t));
                sl_free(&o->alloc, o->st_depth, px * sizeof(float));
                o->st_ids = NULL, o->st_depth = NULL, o->st_cap = 0;
                return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "oracle: out of memory for the see-through buffer");
            }
        }
        uint32_t r[4];
        box_rect(o, vp, &bounds[id], r);
        if (r[0] >= r[2] || r[1] >= r[3])
            continue;
        for (uint32_t y = r[1]; y < r[3]; y++)
            for (uint32_t x = r[0]; x < r[2]; x++) {
                o->st_ids[(size_t)y * o->width + x] = SL_NONE;
                o->st_depth[(size_t)y * o->width + x] = 0.0f;
            }
        sl_refrast_target t = *solid;
        t.ids = o->st_ids;
        t.depth = o->st_depth;
        t.overdraw = NULL;
        const sl_mesh_rec *mesh = &meshes[obj->mesh];
        const sl_affine *xf = obj->transform == SL_NONE ? &identity : &transforms[obj->transform];
        double m[16];
        sl_refrast_compose(vp, xf, m);
        sl_refrast_cull cull = SL_REFRAST_CULL_NONE;
        if ((obj->flags & SL_OBJECT_CLOSED_CONVEX) && !o->opt.draw_closed_backfaces)
            cull = affine_det(xf) < 0 ? SL_REFRAST_CULL_FRONT : SL_REFRAST_CULL_BACK;
        if (!sl_refrast_scratch_reserve(&o->alloc, &o->scratch[0], mesh->vertex_count))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "oracle: out of memory for %u transformed vertices",
                           mesh->vertex_count);
        sl_refrast_mesh(&t, &o->scratch[0], m, sl_scene_positions(s) + 3 * mesh->first_vertex, mesh->vertex_count,
                        sl_scene_indices(s) + mesh->first_index, mesh->triangle_count, id, cull);
        see_through_hit hit = {id, 0, !rule4};
        for (uint32_t y = r[1]; y < r[3]; y++)
            for (uint32_t x = r[0]; x < r[2]; x++) {
                size_t k = (size_t)y * o->width + x;
                if (o->st_ids[k] != id || o->st_depth[k] < solid->depth[k])
                    continue;
                hit.pixels++;
                if (!hit.open && pixel_open(o, &bsp, inv, inv_ok, x, y, o->st_depth[k]))
                    hit.open = true;
            }
        if (hit.pixels && !sl_array_push(&o->alloc, &o->st_hits, sizeof hit, &hit, 1))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "oracle: out of memory for the see-through list");
    }
    return SL_OK;
}

/* Count pixels per object over all views of the render and fill the frame's visible set. */
static sl_status count_pixels(struct sl_oracle_t *o, sl_oracle_frame *frame, sl_error *err)
{
    uint32_t n = sl_scene_object_count(o->scene);
    if (o->counts_cap < n) {
        uint32_t *c = sl_calloc(&o->alloc, n, sizeof(uint32_t));
        if (!c)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "oracle: out of memory for %u object counters", n);
        sl_free(&o->alloc, o->counts, o->counts_cap * sizeof(uint32_t));
        o->counts = c;
        o->counts_cap = n;
    }
    o->visible.count = 0;
    o->visible_pixels.count = 0;
    size_t total = (size_t)o->view_count * o->width * o->height;
    uint64_t covered = 0;
    sl_status st = SL_OK;
    for (size_t i = 0; i < total; i++) {
        uint32_t id = o->ids[i];
        if (id == SL_NONE)
            continue;
        covered++;
        if (o->counts[id]++ == 0 && st == SL_OK && !sl_array_push(&o->alloc, &o->visible, sizeof id, &id, 1))
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "oracle: out of memory for the visible set");
    }
    /* see-through objects: never in the id buffer; their pixels come from see_through_pass */
    const see_through_hit *hits = o->st_hits.data;
    for (size_t i = 0; i < o->st_hits.count && st == SL_OK; i++) {
        uint32_t id = hits[i].object;
        if ((o->counts[id] & ~OPEN_BIT) == 0 && !sl_array_push(&o->alloc, &o->visible, sizeof id, &id, 1))
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "oracle: out of memory for the visible set");
        o->counts[id] = ((o->counts[id] & ~OPEN_BIT) + hits[i].pixels) | (o->counts[id] & OPEN_BIT);
    }
    uint32_t *vis = o->visible.data;
    if (st == SL_OK) {
        if (o->visible.count > 1)
            qsort(vis, o->visible.count, sizeof(uint32_t), cmp_u32);
        if (!sl_array_reserve(&o->alloc, &o->visible_pixels, sizeof(uint32_t), o->visible.count))
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "oracle: out of memory for the visible set");
    }
    sl_bsp_view bsp;
    bool rule4 = st == SL_OK && !o->opt.see_through_solid && sl_scene_bsp(o->scene, &bsp) && bsp.node_count > 0;
    if (rule4) {
        mark_open(o, &bsp);
        for (size_t i = 0; i < o->st_hits.count; i++)
            if (hits[i].open)
                o->counts[hits[i].object] |= OPEN_BIT;
    }
    /* put every counter back to zero, whatever happened */
    if (st == SL_OK) {
        uint32_t *pix = o->visible_pixels.data;
        size_t k = 0;
        for (size_t i = 0; i < o->visible.count; i++) {
            uint32_t c = o->counts[vis[i]];
            o->counts[vis[i]] = 0;
            if (rule4 && !(c & OPEN_BIT)) {
                /* drawn, but only along sight lines through solid space */
                if (!(sl_scene_objects(o->scene)[vis[i]].flags & SL_OBJECT_SEE_THROUGH))
                    covered -= c;
                frame->hidden_by_solid++;
                continue;
            }
            vis[k] = vis[i];
            pix[k++] = c & ~OPEN_BIT;
        }
        o->visible.count = k;
        o->visible_pixels.count = k;
    } else {
        memset(o->counts, 0, o->counts_cap * sizeof(uint32_t));
        o->visible.count = 0;
        return st;
    }
    frame->visible_count = (uint32_t)o->visible.count;
    frame->visible = o->visible.data;
    frame->pixels = o->visible_pixels.data;
    frame->covered_pixels = covered;
    return SL_OK;
}

/* The sample positions of a camera render (docs/oracle.md, "Supersampling"), in pixel units from
 * the pixel's top-left corner; returns their number. */
static uint32_t sample_positions(const sl_oracle_options *opt, double pos[SL_ORACLE_MAX_SAMPLES][2])
{
    /* D3D's standard 4x pattern (sample offsets (-2,-6), (6,-2), (-6,2), (2,6) sixteenths of a
     * pixel from the centre, y down); OpenGL implementations use the same */
    static const double msaa4[4][2] = {{0.375, 0.125}, {0.875, 0.375}, {0.125, 0.625}, {0.625, 0.875}};
    if (opt->samples == SL_ORACLE_SAMPLES_MSAA4) {
        memcpy(pos, msaa4, sizeof msaa4);
        return 4;
    }
    if (opt->samples == SL_ORACLE_SAMPLES_JITTER) {
        uint32_t n = opt->sample_count ? opt->sample_count : 4;
        sl_rng r;
        sl_rng_seed(&r, opt->jitter_seed, 0x5a3b1e5ull);
        for (uint32_t i = 0; i < n; i++) {
            pos[i][0] = sl_rng_double(&r);
            pos[i][1] = sl_rng_double(&r);
        }
        return n;
    }
    pos[0][0] = pos[0][1] = 0.5;
    return 1;
}

/* Common front: size the buffers and clear the frame. */
static sl_status begin(struct sl_oracle_t *o, uint32_t views, uint32_t w, uint32_t h, sl_oracle_frame *frame,
                       sl_error *err)
{
    memset(frame, 0, sizeof *frame);
    o->view_count = 0;
    o->st_hits.count = 0;
    sl_status st = reserve_pixels(o, views, w, h, err);
    if (st != SL_OK)
        return st;
    o->view_count = views;
    o->width = w;
    o->height = h;
    frame->view_count = views;
    frame->width = w;
    frame->height = h;
    return SL_OK;
}

sl_status sl_oracle_render(sl_oracle o, const sl_camera *cam, sl_oracle_frame *out, sl_error *err)
{
    if (!o || !cam || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_oracle_render: oracle, camera and out must not be NULL");
    sl_view view;
    sl_status st = sl_view_from_camera(cam, &view, err);
    if (st != SL_OK)
        return st;
    return sl_oracle_render_view(o, &view, out, err);
}

sl_status sl_oracle_render_view(sl_oracle o, const sl_view *view_in, sl_oracle_frame *out, sl_error *err)
{
    if (!o || !view_in || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_oracle_render_view: oracle, view and out must not be NULL");
    sl_status st = sl_view_validate(view_in, err);
    if (st != SL_OK)
        return st;
    /* an infinite far plane: bounded by the scene's box (the same image: nothing lies beyond) */
    sl_view bounded;
    const sl_view *view;
    if ((st = sl_scene_finite_view(o->scene, view_in, &bounded, &view, err)) != SL_OK)
        return st;
    if ((st = sl_view_check_depth(view, SL_DEPTH_CLIP_Z, "the oracle", err)) != SL_OK) /* its depth: issue 12 §1 */
        return st;
    double t0 = sl_now();
    uint32_t w = o->opt.width ? o->opt.width : view->width, h = o->opt.height ? o->opt.height : view->height;
    if (w > SL_ORACLE_MAX_SIZE || h > SL_ORACLE_MAX_SIZE || (uint64_t)w * h > SL_ORACLE_MAX_PIXELS)
        return sl_fail(err, SL_ERROR_LIMIT, "sl_oracle_render: resolution %ux%u exceeds the limit (%u per side, %u pixels)",
                       w, h, SL_ORACLE_MAX_SIZE, SL_ORACLE_MAX_PIXELS);
    double pos[SL_ORACLE_MAX_SAMPLES][2];
    uint32_t ns = sample_positions(&o->opt, pos);
    st = begin(o, ns, w, h, out, err);
    if (st != SL_OK)
        return st;
    out->samples_per_pixel = ns;
    sl_mat4 vp = view->view_proj;
    for (uint32_t i = 0; i < ns && st == SL_OK; i++)
        st = render_view(o, i, &vp, pos[i][0], pos[i][1], i == 0, out, err);
    if (st == SL_OK)
        st = count_pixels(o, out, err);
    if (st != SL_OK) {
        o->view_count = 0;
        memset(out, 0, sizeof *out);
        return st;
    }
    out->out_of_domain = !sl_oracle_in_domain(o->scene, view->eye, &out->eye_leaf);
    out->ms = (sl_now() - t0) * 1000.0;
    return SL_OK;
}

/* forward, right, up of each cube face (see truth.h) */
static const int8_t g_cube_axes[6][3][3] = {
    {{1, 0, 0}, {0, -1, 0}, {0, 0, 1}},  /* +X */
    {{-1, 0, 0}, {0, 1, 0}, {0, 0, 1}},  /* -X */
    {{0, 1, 0}, {1, 0, 0}, {0, 0, 1}},   /* +Y */
    {{0, -1, 0}, {-1, 0, 0}, {0, 0, 1}}, /* -Y */
    {{0, 0, 1}, {0, -1, 0}, {-1, 0, 0}}, /* +Z */
    {{0, 0, -1}, {0, -1, 0}, {1, 0, 0}}, /* -Z */
};

/* World-to-clip matrix of a cube face: a 90-degree square frustum whose side planes are exactly
 * the planes x = +-w, y = +-w of signed axis permutations, so neighbouring faces share them bit
 * for bit. Column-major, OpenGL clip space. */
static sl_mat4 cube_view_proj(sl_vec3 eye, uint32_t face, float n, float f)
{
    const int8_t(*ax)[3] = g_cube_axes[face];
    const float e[3] = {eye.x, eye.y, eye.z};
    /* eye space rows: right, up, -forward; translation -R e */
    float R[3][3], T[3];
    for (int k = 0; k < 3; k++) {
        R[0][k] = ax[1][k];
        R[1][k] = ax[2][k];
        R[2][k] = -ax[0][k];
    }
    for (int r = 0; r < 3; r++)
        T[r] = -(R[r][0] * e[0] + R[r][1] * e[1] + R[r][2] * e[2]);
    float a = (f + n) / (n - f), b = 2.0f * f * n / (n - f);
    sl_mat4 m;
    memset(&m, 0, sizeof m);
    for (int col = 0; col < 3; col++) {
        m.m[col * 4 + 0] = R[0][col];
        m.m[col * 4 + 1] = R[1][col];
        m.m[col * 4 + 2] = a * R[2][col];
        m.m[col * 4 + 3] = -R[2][col];
    }
    m.m[12] = T[0];
    m.m[13] = T[1];
    m.m[14] = a * T[2] + b;
    m.m[15] = -T[2];
    return m;
}

sl_camera sl_cube_face_camera(sl_vec3 eye, sl_cube_face face, uint32_t face_size, float near_plane, float far_plane)
{
    static const float yaw_deg[6] = {0, 180, 90, 270, 0, 0}, pitch_deg[6] = {0, 0, 0, 0, 90, -90};
    const float deg = 3.14159265358979323846f / 180.0f;
    uint32_t f = (uint32_t)face < 6 ? (uint32_t)face : 0;
    sl_camera c;
    memset(&c, 0, sizeof c);
    c.position = eye;
    c.yaw = yaw_deg[f] * deg;
    c.pitch = pitch_deg[f] * deg;
    c.roll = 0;
    c.projection = SL_PERSPECTIVE;
    c.fov_y = 90.0f * deg;
    c.ortho_height = 1.0f;
    c.near_plane = near_plane;
    c.far_plane = far_plane;
    c.width = c.height = face_size;
    return c;
}

sl_status sl_oracle_render_cube(sl_oracle o, sl_vec3 eye, uint32_t face_size, float near_plane, float far_plane,
                                sl_oracle_frame *out, sl_error *err)
{
    if (!o || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_oracle_render_cube: oracle and out must not be NULL");
    if (!sl_finite3(&eye.x))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_oracle_render_cube: eye (%g, %g, %g) is not finite",
                       (double)eye.x, (double)eye.y, (double)eye.z);
    if (!(near_plane > 0) || !(far_plane > near_plane) || !isfinite(far_plane))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "sl_oracle_render_cube: near %g and far %g must satisfy 0 < near < far < inf", (double)near_plane,
                       (double)far_plane);
    if (face_size == 0 || face_size > SL_ORACLE_MAX_SIZE || (uint64_t)face_size * face_size > SL_ORACLE_MAX_PIXELS)
        return sl_fail(err, SL_ERROR_LIMIT, "sl_oracle_render_cube: face size %u is outside 1..%u (and %u pixels)",
                       face_size, SL_ORACLE_MAX_SIZE, SL_ORACLE_MAX_PIXELS);
    double t0 = sl_now();
    sl_status st = begin(o, 6, face_size, face_size, out, err);
    out->samples_per_pixel = 1;
    for (uint32_t f = 0; f < 6 && st == SL_OK; f++) {
        sl_mat4 vp = cube_view_proj(eye, f, near_plane, far_plane);
        st = render_view(o, f, &vp, 0.5, 0.5, true, out, err);
    }
    if (st == SL_OK)
        st = count_pixels(o, out, err);
    if (st != SL_OK) {
        o->view_count = 0;
        memset(out, 0, sizeof *out);
        return st;
    }
    out->out_of_domain = !sl_oracle_in_domain(o->scene, eye, &out->eye_leaf);
    out->ms = (sl_now() - t0) * 1000.0;
    return SL_OK;
}

sl_status sl_oracle_get_view(sl_oracle o, uint32_t index, sl_oracle_view *out, sl_error *err)
{
    if (!o || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_oracle_get_view: oracle and out must not be NULL");
    if (index >= o->view_count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_oracle_get_view: view %u does not exist (the last render has %u)",
                       index, o->view_count);
    size_t px = (size_t)o->width * o->height;
    out->width = o->width;
    out->height = o->height;
    out->ids = o->ids + index * px;
    out->depth = o->depth + index * px;
    out->overdraw = o->overdraw ? o->overdraw + index * px : NULL;
    out->view_proj = o->view_proj[index];
    out->sample_x = o->sample_pos[index][0];
    out->sample_y = o->sample_pos[index][1];
    return SL_OK;
}
