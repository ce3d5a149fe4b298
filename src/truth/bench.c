/* The benchmark harness: every culling method on the same frames, judged against the point oracle.
 *
 * Per frame the oracle renders once (it is by far the slowest part) and every method then culls
 * the same camera; the records keep what docs/bench.md lists. Methods are reached only through
 * the registry by name (cull.h), so a method that lands in src/cull/ appears here with no change.
 * Timing is the interface's own wall time of sl_culler_cull (sl_cull_stats.total_ms), the median
 * over `repeat` calls on the same camera; the counters are those of the last call. */
#include "bench_internal.h"

#include <math.h>
#include <stdlib.h>

sl_bench_options sl_bench_default_options(void)
{
    sl_bench_options o;
    memset(&o, 0, sizeof o);
    o.threads = 2;
    o.repeat = 1;
    o.label = "scene";
    return o;
}

uint32_t sl_bench_registered_methods(sl_bench_method_spec *specs, uint32_t capacity, sl_bench_skip *skipped,
                                     uint32_t skipped_capacity, uint32_t *skipped_count)
{
    uint32_t n = 0, k = 0, count = sl_cull_method_count();
    for (uint32_t i = 0; i < count; i++) {
        sl_cull_method_desc d;
        sl_error err;
        if (sl_cull_method_info(i, &d, &err) != SL_OK)
            continue;
        if (sl_cull_method_check_options(d.name, NULL, &err) == SL_OK) {
            if (specs && n < capacity)
                specs[n++] = (sl_bench_method_spec){d.name, NULL};
            continue;
        }
        if (skipped && k < skipped_capacity) {
            skipped[k].name = d.name;
            snprintf(skipped[k].reason, sizeof skipped[k].reason, "%s", err.message);
        }
        k++;
    }
    if (skipped_count)
        *skipped_count = k;
    return n;
}

static void free_method(const sl_allocator *a, bench_method *m, uint32_t object_count)
{
    sl_culler_destroy(m->culler);
    sl_strfree(a, m->name);
    sl_strfree(a, m->options);
    sl_free(a, m->result, (size_t)SL_MAX(object_count, 1) * sizeof(uint32_t));
    memset(m, 0, sizeof *m);
}

void sl_bench_destroy(sl_bench b)
{
    if (!b)
        return;
    const sl_allocator *a = &b->alloc;
    for (uint32_t i = 0; i < b->method_count; i++)
        free_method(a, &b->methods[i], b->object_count);
    sl_oracle_destroy(b->oracle);
    sl_strfree(a, b->label);
    sl_free(a, b->triangles, (size_t)SL_MAX(b->object_count, 1) * sizeof(uint32_t));
    sl_free(a, b->times, (size_t)b->opt.repeat * sizeof(double));
    sl_array_free(a, &b->frames, sizeof(sl_bench_frame));
    sl_array_free(a, &b->records, sizeof(sl_bench_record));
    sl_free(a, b, sizeof *b);
}

/* Room for a method's per-frame result. */
static sl_status method_buffers(struct sl_bench_t *b, bench_method *m, sl_error *err)
{
    m->result = sl_alloc(&b->alloc, (size_t)SL_MAX(b->object_count, 1) * sizeof(uint32_t));
    if (!m->result)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "bench: out of memory for %u object ids", b->object_count);
    return SL_OK;
}

sl_status sl_bench_create(sl_scene scene, const sl_bench_method_spec *methods, uint32_t method_count,
                          const sl_bench_options *opt, const sl_allocator *alloc, sl_bench *out, sl_error *err)
{
    if (!scene || !out || (method_count && !methods))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_create: scene, methods and out must not be NULL");
    *out = NULL;
    sl_bench_options o = opt ? *opt : sl_bench_default_options();
    if (method_count > SL_BENCH_MAX_METHODS)
        return sl_fail(err, SL_ERROR_LIMIT, "sl_bench_create: %u methods (at most %u)", method_count,
                       SL_BENCH_MAX_METHODS);
    if (o.threads < 1 || o.threads > SL_ORACLE_MAX_THREADS)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_create: threads = %u is outside 1..%u", o.threads,
                       SL_ORACLE_MAX_THREADS);
    if (o.repeat < 1 || o.repeat > 1000)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_create: repeat = %u is outside 1..1000", o.repeat);
    if ((o.width == 0) != (o.height == 0))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "sl_bench_create: width = %u and height = %u: give both or neither", o.width, o.height);
    for (uint32_t i = 0; i < method_count; i++) {
        if (!methods[i].name)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_create: method %u has no name", i);
        for (uint32_t j = 0; j < i; j++)
            if (!strcmp(methods[i].name, methods[j].name))
                return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_create: method '%s' is listed twice",
                               methods[i].name);
    }
    alloc = sl_alloc_or_default(alloc);
    struct sl_bench_t *b = sl_calloc(alloc, 1, sizeof *b);
    if (!b)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_bench_create: out of memory");
    b->alloc = *alloc;
    b->scene = scene;
    b->opt = o;
    b->object_count = sl_scene_object_count(scene);
    b->label = sl_strdup(alloc, o.label ? o.label : "scene");
    b->opt.label = b->label;
    b->times = sl_alloc(alloc, (size_t)o.repeat * sizeof(double));
    b->triangles = sl_alloc(alloc, (size_t)SL_MAX(b->object_count, 1) * sizeof(uint32_t));
    sl_status st = SL_OK;
    if (!b->label || !b->times || !b->triangles) {
        /* destroy frees by the recorded sizes: keep them consistent with what was allocated */
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_bench_create: out of memory");
    } else {
        for (uint32_t i = 0; i < b->object_count; i++)
            b->triangles[i] = sl_scene_object(scene, i).triangle_count;
        sl_oracle_options oo = sl_oracle_default_options();
        oo.threads = o.threads;
        st = sl_oracle_create(scene, &oo, alloc, &b->oracle, err);
    }
    for (uint32_t i = 0; st == SL_OK && i < method_count; i++) {
        bench_method *m = &b->methods[i];
        b->method_count = i + 1; /* so that destroy frees what is made */
        st = sl_culler_create(methods[i].name, scene, methods[i].options, alloc, &m->culler, err);
        if (st != SL_OK)
            break;
        m->name = sl_strdup(alloc, sl_culler_method(m->culler));
        m->options = sl_strdup(alloc, sl_culler_options(m->culler));
        m->guarantee = sl_culler_guarantee(m->culler);
        if (!m->name || !m->options)
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_bench_create: out of memory");
        if (st == SL_OK)
            st = method_buffers(b, m, err);
    }
    if (st != SL_OK) {
        sl_bench_destroy(b);
        return st;
    }
    *out = b;
    return SL_OK;
}

sl_status sl_bench_add_external(sl_bench b, const char *name, sl_cull_guarantee guarantee, uint32_t *out_index,
                                sl_error *err)
{
    if (!b || !name || !name[0])
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_add_external: bench and name must be given");
    if (b->frames.count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "sl_bench_add_external: '%s' comes after the first frame; add methods before running", name);
    if (b->method_count >= SL_BENCH_MAX_METHODS)
        return sl_fail(err, SL_ERROR_LIMIT, "sl_bench_add_external: at most %u methods", SL_BENCH_MAX_METHODS);
    if (guarantee != SL_CONSERVATIVE && guarantee != SL_AGGRESSIVE && guarantee != SL_CONSERVATIVE_AT_RESOLUTION)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_add_external: '%s': unknown guarantee %d", name,
                       (int)guarantee);
    for (uint32_t i = 0; i < b->method_count; i++)
        if (!strcmp(b->methods[i].name, name))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_add_external: method '%s' already exists", name);
    bench_method *m = &b->methods[b->method_count];
    m->name = sl_strdup(&b->alloc, name);
    m->options = sl_strdup(&b->alloc, "");
    m->guarantee = guarantee;
    sl_status st = m->name && m->options ? method_buffers(b, m, err)
                                         : sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_bench_add_external: out of memory");
    if (st != SL_OK) {
        free_method(&b->alloc, m, b->object_count);
        return st;
    }
    if (out_index)
        *out_index = b->method_count;
    b->method_count++;
    return SL_OK;
}

static int cmp_double(const void *x, const void *y)
{
    double a = *(const double *)x, c = *(const double *)y;
    return (a > c) - (a < c);
}

/* Judge a method's result (in m->result) against the current truth into rec. */
static sl_status judge(struct sl_bench_t *b, bench_method *m, sl_bench_record *rec, sl_error *err)
{
    uint32_t keep_ids[SL_BENCH_MISSED_KEEP], keep_px[SL_BENCH_MISSED_KEEP];
    sl_status st = sl_metrics_compare(b->scene, &b->truth, m->result, m->result_count, &rec->metrics, keep_ids, keep_px,
                                      SL_BENCH_MISSED_KEEP, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "%s", m->name);
        return st;
    }
    rec->missed_kept = SL_MIN(rec->metrics.missed_count, SL_BENCH_MISSED_KEEP);
    memcpy(rec->missed_ids, keep_ids, rec->missed_kept * sizeof(uint32_t));
    memcpy(rec->missed_pixels, keep_px, rec->missed_kept * sizeof(uint32_t));
    rec->valid = true;
    return SL_OK;
}

/* The camera a report shows for a frame given as a view of matrices: the eye, the orientation of
 * its axes, near and far, the vertical extent (fov of the larger of |bottom|, |top|; the off-axis
 * shift is not kept). */
static sl_camera camera_of_view(const sl_view *v)
{
    if (v->source == SL_VIEW_FROM_CAMERA)
        return v->camera;
    sl_camera c;
    memset(&c, 0, sizeof c);
    c.position = v->eye;
    double fx = v->forward.x, fy = v->forward.y, fz = v->forward.z;
    double yaw = atan2(fy, fx), pitch = asin(fz > 1 ? 1 : fz < -1 ? -1 : fz);
    double cy = cos(yaw), sy = sin(yaw), cp = cos(pitch), sp = sin(pitch);
    double r0[3] = {sy, -cy, 0}, u0[3] = {-sp * cy, -sp * sy, cp}, r[3] = {v->right.x, v->right.y, v->right.z};
    double cr = r[0] * r0[0] + r[1] * r0[1] + r[2] * r0[2], sr = -(r[0] * u0[0] + r[1] * u0[1] + r[2] * u0[2]);
    c.yaw = (float)yaw;
    c.pitch = (float)pitch;
    c.roll = (float)atan2(sr, cr);
    c.projection = v->projection;
    double ext = fmax(fabs(v->rect_bottom), fabs(v->rect_top));
    c.fov_y = v->projection == SL_PERSPECTIVE ? (float)(2.0 * atan(ext / v->near_plane)) : 1.0f;
    c.ortho_height = (float)(v->rect_top - v->rect_bottom);
    c.near_plane = (float)v->near_plane;
    c.far_plane = (float)v->far_plane;
    c.width = v->width;
    c.height = v->height;
    return c;
}

static sl_status run_view(struct sl_bench_t *b, const sl_view *view, int64_t source, float time, sl_error *err);

/* A camera's frame: as its view at the bench's viewport; source < 0: the frame's own number. */
static sl_status run_camera(sl_bench b, const sl_camera *cam_in, int64_t source, float time, sl_error *err)
{
    sl_camera cam = *cam_in;
    if (b->opt.width) {
        cam.width = b->opt.width;
        cam.height = b->opt.height;
    }
    sl_view view;
    sl_status st = sl_view_from_camera(&cam, &view, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "%s: frame %u: oracle", b->label, (uint32_t)b->frames.count);
        return st;
    }
    return run_view(b, &view, source, time, err);
}

sl_status sl_bench_run_frame(sl_bench b, const sl_camera *cam_in, sl_error *err)
{
    if (!b || !cam_in)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_run_frame: bench and camera must not be NULL");
    return run_camera(b, cam_in, -1, 0, err);
}

sl_status sl_bench_run_view(sl_bench b, const sl_view *view_in, sl_error *err)
{
    if (!b || !view_in)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_run_view: bench and view must not be NULL");
    sl_view view;
    sl_status st = b->opt.width ? sl_view_with_viewport(view_in, b->opt.width, b->opt.height, &view, err)
                                : sl_view_validate(view_in, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "%s: frame %u", b->label, (uint32_t)b->frames.count);
        return st;
    }
    return run_view(b, b->opt.width ? &view : view_in, -1, 0, err);
}

static sl_status run_view(struct sl_bench_t *b, const sl_view *view, int64_t source, float time, sl_error *err)
{
    if (sl_scene_object_count(b->scene) != b->object_count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "sl_bench_run_frame: the scene has %u objects, %u when the bench was made: make a new bench",
                       sl_scene_object_count(b->scene), b->object_count);
    uint32_t fi = (uint32_t)b->frames.count;
    b->have_truth = false;
    sl_status st = sl_oracle_render_view(b->oracle, view, &b->truth, err);
    if (st != SL_OK) {
        sl_error_prefix(err, "%s: frame %u: oracle", b->label, fi);
        return st;
    }
    b->have_truth = true;
    sl_bench_frame fr;
    memset(&fr, 0, sizeof fr);
    fr.index = fi;
    fr.source = source < 0 ? fi : (uint32_t)source;
    fr.time = source < 0 ? (float)fi : time;
    fr.camera = camera_of_view(view);
    fr.view = *view;
    fr.visible_count = b->truth.visible_count;
    for (uint32_t i = 0; i < b->truth.visible_count; i++)
        fr.triangles_visible += b->triangles[b->truth.visible[i]];
    fr.covered_pixels = b->truth.covered_pixels;
    fr.objects_in_frustum = b->truth.objects_in_frustum;
    fr.triangles_in_frustum = b->truth.triangles_in_frustum;
    fr.oracle_ms = b->truth.ms;
    fr.out_of_domain = b->truth.out_of_domain;
    if (!sl_array_reserve(&b->alloc, &b->records, sizeof(sl_bench_record), b->method_count) ||
        !sl_array_reserve(&b->alloc, &b->frames, sizeof fr, 1))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for the records of frame %u", b->label, fi);
    sl_bench_record *recs = sl_array_push(&b->alloc, &b->records, sizeof(sl_bench_record), NULL, b->method_count);
    sl_array_push(&b->alloc, &b->frames, sizeof fr, &fr, 1);
    for (uint32_t mi = 0; mi < b->method_count; mi++) {
        bench_method *m = &b->methods[mi];
        m->result_count = 0;
        /* outside the domain there is no truth to judge by: the frame is counted and skipped */
        if (!m->culler || fr.out_of_domain)
            continue;
        sl_bench_record *rec = &recs[mi];
        for (uint32_t r = 0; r < b->opt.repeat; r++) {
            st = sl_culler_cull_view(m->culler, view, m->result, SL_MAX(b->object_count, 1), &m->result_count, err);
            if (st != SL_OK) {
                sl_error_prefix(err, "%s: frame %u: %s", b->label, fi, m->name);
                return st;
            }
            sl_culler_stats(m->culler, &rec->stats);
            b->times[r] = rec->stats.total_ms;
        }
        qsort(b->times, b->opt.repeat, sizeof(double), cmp_double);
        uint32_t n = b->opt.repeat;
        rec->cull_ms = n % 2 ? b->times[n / 2] : 0.5 * (b->times[n / 2 - 1] + b->times[n / 2]);
        rec->cull_ms_min = b->times[0];
        st = judge(b, m, rec, err);
        if (st != SL_OK) {
            sl_error_prefix(err, "%s: frame %u", b->label, fi);
            return st;
        }
    }
    if (b->opt.frame_done && !b->opt.frame_done(b->opt.frame_user, b, fi))
        return sl_fail(err, SL_ERROR_CANCELLED, "%s: frame %u: stopped by the frame callback", b->label, fi);
    return SL_OK;
}

sl_status sl_bench_run_path(sl_bench b, sl_path path, uint32_t first, uint32_t count, sl_error *err)
{
    if (!b || !path)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_run_path: bench and path must not be NULL");
    uint32_t n = sl_path_count(path);
    if (first > n)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_run_path: first frame %u is beyond the path's %u",
                       first, n);
    count = SL_MIN(count, n - first);
    const sl_pose *poses = sl_path_poses(path);
    snprintf(b->stage, sizeof b->stage, "%s", b->label);
    for (uint32_t i = 0; i < count; i++) {
        if (!sl_progress_report(&b->opt.progress, b->stage, i, count))
            return sl_fail(err, SL_ERROR_CANCELLED, "%s: cancelled after %u frames", b->label, i);
        sl_camera cam = sl_path_camera(path, first + i);
        sl_status st = run_camera(b, &cam, first + i, poses[first + i].time, err);
        if (st != SL_OK)
            return st;
    }
    sl_progress_report(&b->opt.progress, b->stage, count, count);
    return SL_OK;
}

sl_status sl_bench_submit(sl_bench b, uint32_t method, const uint32_t *ids, uint32_t count, double cull_ms,
                          sl_error *err)
{
    if (!b || (count && !ids))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_submit: bench and ids must not be NULL");
    if (method >= b->method_count || b->methods[method].culler)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_submit: method %u is not an external method", method);
    if (!b->frames.count || !b->have_truth)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_submit: no current frame (run a frame first)");
    if (!isfinite(cull_ms) || cull_ms < 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_submit: time %g ms is not a finite non-negative number",
                       cull_ms);
    if (count > b->object_count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_submit: %u ids for a scene of %u objects", count,
                       b->object_count);
    bench_method *m = &b->methods[method];
    uint32_t fi = (uint32_t)b->frames.count - 1;
    sl_bench_record *rec = bench_rec(b, fi, method);
    if (count)
        memcpy(m->result, ids, (size_t)count * sizeof(uint32_t));
    m->result_count = count;
    if (SL_AT(b->frames, sl_bench_frame, fi).out_of_domain) {
        /* keep it as the last result, judge nothing: the record stays invalid */
        for (uint32_t i = 0; i < count; i++)
            if (ids[i] >= b->object_count || (i && ids[i] <= ids[i - 1])) {
                m->result_count = 0;
                return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                               "sl_bench_submit: %s: entry %u (object %u) is out of range or out of order", m->name, i,
                               ids[i]);
            }
        return SL_OK;
    }
    sl_bench_record fresh;
    memset(&fresh, 0, sizeof fresh);
    fresh.cull_ms = fresh.cull_ms_min = cull_ms;
    fresh.stats.total_ms = cull_ms;
    fresh.stats.objects_visible = count;
    sl_status st = judge(b, m, &fresh, err);
    if (st != SL_OK) {
        m->result_count = 0;
        return st;
    }
    fresh.stats.triangles_visible = fresh.metrics.triangles_rendered;
    *rec = fresh;
    return SL_OK;
}

/* ---- results ---- */

sl_scene sl_bench_scene(sl_bench b) { return b ? b->scene : NULL; }
const char *sl_bench_label(sl_bench b) { return b ? b->label : ""; }
uint32_t sl_bench_method_count(sl_bench b) { return b ? b->method_count : 0; }
uint32_t sl_bench_frame_count(sl_bench b) { return b ? (uint32_t)b->frames.count : 0; }

sl_status sl_bench_method(sl_bench b, uint32_t index, sl_bench_method_info *out, sl_error *err)
{
    if (!b || !out || index >= b->method_count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_method: no method %u (the bench has %u)", index,
                       b ? b->method_count : 0);
    const bench_method *m = &b->methods[index];
    out->name = m->name;
    out->options = m->options;
    out->guarantee = m->guarantee;
    out->external = m->culler == NULL;
    return SL_OK;
}

sl_status sl_bench_set_shown_options(sl_bench b, uint32_t index, const char *options, sl_error *err)
{
    if (!b || index >= b->method_count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_set_shown_options: no method %u (the bench has %u)",
                       index, b ? b->method_count : 0);
    char *copy = sl_strdup(&b->alloc, options ? options : "");
    if (!copy)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_bench_set_shown_options: out of memory");
    bench_method *m = &b->methods[index];
    sl_strfree(&b->alloc, m->options);
    m->options = copy;
    return SL_OK;
}

sl_status sl_bench_get_frame(sl_bench b, uint32_t index, sl_bench_frame *out, sl_error *err)
{
    if (!b || !out || index >= b->frames.count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_get_frame: no frame %u (the bench has %zu)", index,
                       b ? b->frames.count : 0);
    *out = SL_AT(b->frames, sl_bench_frame, index);
    return SL_OK;
}

sl_status sl_bench_get_record(sl_bench b, uint32_t frame, uint32_t method, sl_bench_record *out, sl_error *err)
{
    if (!b || !out || frame >= b->frames.count || method >= b->method_count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_get_record: no record for frame %u, method %u", frame,
                       method);
    *out = *bench_rec(b, frame, method);
    return SL_OK;
}

sl_status sl_bench_last_result(sl_bench b, uint32_t method, const uint32_t **ids, uint32_t *count, sl_error *err)
{
    if (!b || !ids || !count || method >= b->method_count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_last_result: no method %u", method);
    *ids = b->methods[method].result;
    *count = b->methods[method].result_count;
    return SL_OK;
}

sl_status sl_bench_last_truth(sl_bench b, sl_oracle_frame *out, sl_error *err)
{
    if (!b || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_last_truth: bench and out must not be NULL");
    if (!b->have_truth)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_last_truth: no frame has been run");
    *out = b->truth;
    return SL_OK;
}

sl_status sl_bench_summarize(sl_bench b, uint32_t method, sl_bench_summary *out, sl_error *err)
{
    if (!b || !out || method >= b->method_count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_summarize: no method %u", method);
    memset(out, 0, sizeof *out);
    out->first_miss_frame = out->first_miss_object = SL_NONE;
    size_t nf = b->frames.count;
    double *ms = sl_alloc(&b->alloc, SL_MAX(nf, 1) * sizeof(double));
    if (!ms)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_bench_summarize: out of memory");
    size_t n = 0;
    for (uint32_t f = 0; f < nf; f++) {
        const sl_bench_record *r = bench_rec(b, f, method);
        if (SL_AT(b->frames, sl_bench_frame, f).out_of_domain)
            out->frames_out_of_domain++;
        if (!r->valid)
            continue;
        const sl_cull_metrics *m = &r->metrics;
        out->objects_drawn_mean += m->result_count;
        out->triangles_drawn_mean += (double)m->triangles_rendered;
        out->visible_mean += m->visible_count;
        out->triangles_visible_mean += (double)m->triangles_visible;
        out->overestimation_mean += m->overestimation;
        out->frames_empty += m->visible_count == 0;
        out->extra_mean += m->extra_count;
        out->missed_objects_total += m->missed_count;
        out->missed_pixels_total += m->missed_pixels;
        if (m->missed_count) {
            if (!out->frames_with_misses) {
                out->first_miss_frame = SL_AT(b->frames, sl_bench_frame, f).source;
                out->first_miss_object = r->missed_kept ? r->missed_ids[0] : SL_NONE;
            }
            out->frames_with_misses++;
        }
        ms[n++] = r->cull_ms;
    }
    out->frames = (uint32_t)n;
    if (n) {
        double k = (double)n;
        out->objects_drawn_mean /= k;
        out->triangles_drawn_mean /= k;
        out->visible_mean /= k;
        out->triangles_visible_mean /= k;
        out->overestimation_mean /= k;
        out->extra_mean /= k;
    }
    /* sum of |R| over sum of |V| (at least 1, as the per-frame ratio's max(|V|, 1)) */
    double sum_r = out->objects_drawn_mean * (double)n, sum_v = out->visible_mean * (double)n;
    out->overestimation = n ? sum_r / (sum_v > 1 ? sum_v : 1) : 1.0;
    sl_status st = sl_series_summarize(ms, n, &b->alloc, &out->cull_ms, err);
    sl_free(&b->alloc, ms, SL_MAX(nf, 1) * sizeof(double));
    return st;
}

uint64_t sl_bench_violations(sl_bench b)
{
    if (!b)
        return 0;
    uint64_t total = 0;
    for (uint32_t mi = 0; mi < b->method_count; mi++) {
        if (!sl_cull_guarantee_keeps_visible(b->methods[mi].guarantee, true)) /* the oracle: camera resolution */
            continue;
        for (size_t f = 0; f < b->frames.count; f++) {
            const sl_bench_record *r = bench_rec(b, (uint32_t)f, mi);
            if (r->valid)
                total += r->metrics.missed_count;
        }
    }
    return total;
}
