/* Reports of the benchmark harness: per-frame rows as CSV and JSON, the Markdown summary, and SVG
 * plots. The columns are documented in docs/bench.md; keep both in step. Every file is written
 * atomically, so an interrupted run never leaves half a report. */
#include "bench_internal.h"
#include "plot.h"

#include <math.h>
#include <stdarg.h>

#define RAD2DEG (180.0 / 3.14159265358979323846)

static void out(sl_atomic_file *f, const char *fmt, ...) SL_PRINTF(2, 3);
static void out(sl_atomic_file *f, const char *fmt, ...)
{
    if (f->failed)
        return;
    va_list ap;
    va_start(ap, fmt);
    if (vfprintf(f->fp, fmt, ap) < 0)
        f->failed = true;
    va_end(ap);
}

static sl_status check_benches(const sl_bench *benches, uint32_t count, const char *path, const char *fn, sl_error *err)
{
    if (!path || (count && !benches))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: benches and path must not be NULL", fn);
    for (uint32_t i = 0; i < count; i++)
        if (!benches[i])
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: bench %u is NULL", fn, i);
    return SL_OK;
}

/* ---- CSV ---- */

/* A CSV field, quoted when it holds a comma, quote or line break. */
static void csv_text(sl_atomic_file *f, const char *s)
{
    if (!strpbrk(s, ",\"\r\n")) {
        out(f, "%s", s);
        return;
    }
    out(f, "\"");
    for (; *s; s++) {
        if (*s == '"')
            out(f, "\"\"");
        else
            out(f, "%c", *s);
    }
    out(f, "\"");
}

static const char csv_header[] =
    "scene,frame,time_s,x,y,z,yaw_deg,pitch_deg,roll_deg,method,guarantee,cull_ms,cull_ms_min,"
    "objects_drawn,triangles_drawn,visible_exact,triangles_visible,missed_objects,missed_pixels,extra_objects,"
    "overestimation,objects_in_frustum,triangles_in_frustum,covered_pixels,oracle_ms,objects_tested,nodes_visited,"
    "occlusion_tests,queries,pixels_rasterized,pixel_queries,phases,missed,skipped,query_stalls,query_wait_ms";

/* The view columns, after the others, only in a file with a frame given by matrices (so that a
 * file of camera frames keeps its columns byte for byte): the view as culled, exactly. */
static const char csv_view_header[] =
    ",view,clip_depth,projection,near,far,rect_left,rect_right,rect_bottom,rect_top,forward_x,forward_y,forward_z,"
    "up_x,up_y,up_z,width,height,mirrored";

static bool frame_from_matrices(const sl_bench_frame *fr)
{
    return fr->view.source == SL_VIEW_FROM_MATRICES;
}

static bool any_from_matrices(const sl_bench *benches, uint32_t count)
{
    for (uint32_t bi = 0; bi < count; bi++)
        for (uint32_t fi = 0; fi < benches[bi]->frames.count; fi++)
            if (frame_from_matrices(&SL_AT(benches[bi]->frames, sl_bench_frame, fi)))
                return true;
    return false;
}

static void csv_view(sl_atomic_file *f, const sl_bench_frame *fr)
{
    const sl_view *v = &fr->view;
    out(f, ",%s,%s,%s,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%u,%u,%s",
        frame_from_matrices(fr) ? "matrices" : "camera", sl_clip_depth_name(v->clip_depth),
        v->projection == SL_ORTHOGRAPHIC ? "orthographic" : "perspective", v->near_plane, v->far_plane, v->rect_left,
        v->rect_right, v->rect_bottom, v->rect_top, (double)v->forward.x, (double)v->forward.y, (double)v->forward.z,
        (double)v->up.x, (double)v->up.y, (double)v->up.z, v->width, v->height,
        v->mirrored_x ? (v->mirrored_y ? "xy" : "x") : (v->mirrored_y ? "y" : ""));
}

sl_status sl_bench_write_csv(const sl_bench *benches, uint32_t count, const char *path, sl_error *err)
{
    sl_status st = check_benches(benches, count, path, "sl_bench_write_csv", err);
    if (st != SL_OK)
        return st;
    sl_atomic_file f;
    st = sl_atomic_open(count ? &benches[0]->alloc : NULL, path, &f, err);
    if (st != SL_OK)
        return st;
    const bool views = any_from_matrices(benches, count);
    out(&f, "%s%s\n", csv_header, views ? csv_view_header : "");
    for (uint32_t bi = 0; bi < count; bi++) {
        struct sl_bench_t *b = benches[bi];
        for (uint32_t fi = 0; fi < b->frames.count; fi++) {
            const sl_bench_frame *fr = &SL_AT(b->frames, sl_bench_frame, fi);
            const sl_camera *c = &fr->camera;
            if (fr->out_of_domain) {
                /* one row for the skipped frame: where it was, no method, the reason last */
                csv_text(&f, b->label);
                out(&f, ",%u,%.9g,%.9g,%.9g,%.9g,%.6g,%.6g,%.6g,,,,,,,,,,,,,,,,,,,,,,,,,out_of_domain,,", fr->source,
                    (double)fr->time, (double)c->position.x, (double)c->position.y, (double)c->position.z,
                    c->yaw * RAD2DEG, c->pitch * RAD2DEG, c->roll * RAD2DEG);
                if (views)
                    csv_view(&f, fr);
                out(&f, "\n");
                continue;
            }
            for (uint32_t mi = 0; mi < b->method_count; mi++) {
                const sl_bench_record *r = bench_rec(b, fi, mi);
                if (!r->valid)
                    continue;
                const sl_cull_metrics *m = &r->metrics;
                const sl_cull_stats *s = &r->stats;
                csv_text(&f, b->label);
                out(&f, ",%u,%.9g,%.9g,%.9g,%.9g,%.6g,%.6g,%.6g,", fr->source, (double)fr->time, (double)c->position.x,
                    (double)c->position.y, (double)c->position.z, c->yaw * RAD2DEG, c->pitch * RAD2DEG,
                    c->roll * RAD2DEG);
                csv_text(&f, b->methods[mi].name);
                out(&f, ",%s,%.6f,%.6f,%u,%llu,%u,%llu,%u,%llu,%u,%.6f,%u,%llu,%llu,%.3f,%llu,%llu,%llu,%llu,%llu,%llu,",
                    sl_cull_guarantee_name(b->methods[mi].guarantee), r->cull_ms, r->cull_ms_min, m->result_count,
                    (unsigned long long)m->triangles_rendered, m->visible_count,
                    (unsigned long long)m->triangles_visible, m->missed_count, (unsigned long long)m->missed_pixels,
                    m->extra_count, m->overestimation, fr->objects_in_frustum,
                    (unsigned long long)fr->triangles_in_frustum, (unsigned long long)fr->covered_pixels, fr->oracle_ms,
                    (unsigned long long)s->objects_tested, (unsigned long long)s->nodes_visited,
                    (unsigned long long)s->occlusion_tests, (unsigned long long)s->queries,
                    (unsigned long long)s->pixels_rasterized, (unsigned long long)s->pixel_queries);
                /* phases "name=ms;name=ms" and the first missed objects "id:pixels;id:pixels" */
                for (uint32_t p = 0; p < s->phase_count && p < SL_CULL_MAX_PHASES; p++)
                    out(&f, "%s%s=%.6f", p ? ";" : "", s->phase_names[p] ? s->phase_names[p] : "?", s->phase_ms[p]);
                out(&f, ",");
                for (uint32_t k = 0; k < r->missed_kept; k++)
                    out(&f, "%s%u:%u", k ? ";" : "", r->missed_ids[k], r->missed_pixels[k]);
                /* skipped empty, then query_stalls and query_wait_ms */
                out(&f, ",,%llu,%.6f", (unsigned long long)s->query_stalls, s->query_wait_ms);
                if (views)
                    csv_view(&f, fr);
                out(&f, "\n");
            }
        }
    }
    return sl_atomic_commit(&f, err);
}

/* ---- JSON ---- */

static void json_str(sl_atomic_file *f, const char *s)
{
    out(f, "\"");
    for (const unsigned char *p = (const unsigned char *)s; p && *p; p++) {
        if (*p == '"' || *p == '\\')
            out(f, "\\%c", *p);
        else if (*p < 0x20)
            out(f, "\\u%04x", *p);
        else
            out(f, "%c", *p);
    }
    out(f, "\"");
}

static void json_num(sl_atomic_file *f, double v)
{
    if (isfinite(v))
        out(f, "%.9g", v);
    else
        out(f, "null");
}

static void json_vec(sl_atomic_file *f, sl_vec3 v)
{
    out(f, "[");
    json_num(f, v.x);
    out(f, ",");
    json_num(f, v.y);
    out(f, ",");
    json_num(f, v.z);
    out(f, "]");
}

/* ,"view":{...}: a frame given by matrices, exactly (its "camera" is approximate) */
static void json_view(sl_atomic_file *f, const sl_view *v)
{
    out(f, ",\"view\":{\"source\":\"matrices\",\"clip_depth\":\"%s\",\"projection\":\"%s\",\"eye\":",
        sl_clip_depth_name(v->clip_depth), v->projection == SL_ORTHOGRAPHIC ? "orthographic" : "perspective");
    json_vec(f, v->eye);
    out(f, ",\"forward\":");
    json_vec(f, v->forward);
    out(f, ",\"right\":");
    json_vec(f, v->right);
    out(f, ",\"up\":");
    json_vec(f, v->up);
    out(f, ",\"near\":");
    json_num(f, v->near_plane);
    out(f, ",\"far\":");
    json_num(f, v->far_plane);
    out(f, ",\"rect\":{\"left\":");
    json_num(f, v->rect_left);
    out(f, ",\"right\":");
    json_num(f, v->rect_right);
    out(f, ",\"bottom\":");
    json_num(f, v->rect_bottom);
    out(f, ",\"top\":");
    json_num(f, v->rect_top);
    out(f, "},\"focal_x\":");
    json_num(f, v->focal_x);
    out(f, ",\"focal_y\":");
    json_num(f, v->focal_y);
    out(f, ",\"width\":%u,\"height\":%u,\"mirrored_x\":%s,\"mirrored_y\":%s,\"left_handed\":%s}", v->width,
        v->height, v->mirrored_x ? "true" : "false", v->mirrored_y ? "true" : "false",
        v->left_handed ? "true" : "false");
}

sl_status sl_bench_write_json(const sl_bench *benches, uint32_t count, const char *path, sl_error *err)
{
    sl_status st = check_benches(benches, count, path, "sl_bench_write_json", err);
    if (st != SL_OK)
        return st;
    sl_atomic_file f;
    st = sl_atomic_open(count ? &benches[0]->alloc : NULL, path, &f, err);
    if (st != SL_OK)
        return st;
    out(&f, "{\"format\":\"sightline-bench-frames\",\"version\":1,\"scenes\":[");
    for (uint32_t bi = 0; bi < count; bi++) {
        struct sl_bench_t *b = benches[bi];
        sl_scene_stats ss;
        sl_scene_get_stats(b->scene, &ss);
        out(&f, "%s\n{\"scene\":", bi ? "," : "");
        json_str(&f, b->label);
        out(&f, ",\"objects\":%u,\"triangles\":%llu,\"frames\":%zu,\"methods\":[", ss.object_count,
            (unsigned long long)ss.instanced_triangle_count, b->frames.count);
        for (uint32_t mi = 0; mi < b->method_count; mi++) {
            out(&f, "%s{\"name\":", mi ? "," : "");
            json_str(&f, b->methods[mi].name);
            out(&f, ",\"options\":");
            json_str(&f, b->methods[mi].options);
            out(&f, ",\"guarantee\":\"%s\",\"external\":%s}", sl_cull_guarantee_name(b->methods[mi].guarantee),
                b->methods[mi].culler ? "false" : "true");
        }
        /* frames skipped because the eye was outside the domain (docs/oracle.md) */
        uint32_t skipped = 0;
        out(&f, "],\"skipped_frames\":[");
        for (uint32_t fi = 0; fi < b->frames.count; fi++) {
            const sl_bench_frame *fr = &SL_AT(b->frames, sl_bench_frame, fi);
            if (!fr->out_of_domain)
                continue;
            out(&f, "%s{\"frame\":%u,\"reason\":\"out_of_domain\",\"x\":", skipped++ ? "," : "", fr->source);
            json_num(&f, fr->camera.position.x);
            out(&f, ",\"y\":");
            json_num(&f, fr->camera.position.y);
            out(&f, ",\"z\":");
            json_num(&f, fr->camera.position.z);
            out(&f, "}");
        }
        out(&f, "],\"frames_out_of_domain\":%u}", skipped);
    }
    out(&f, "],\n\"rows\":[");
    bool first = true;
    for (uint32_t bi = 0; bi < count; bi++) {
        struct sl_bench_t *b = benches[bi];
        for (uint32_t fi = 0; fi < b->frames.count; fi++) {
            const sl_bench_frame *fr = &SL_AT(b->frames, sl_bench_frame, fi);
            const sl_camera *c = &fr->camera;
            for (uint32_t mi = 0; mi < b->method_count; mi++) {
                const sl_bench_record *r = bench_rec(b, fi, mi);
                if (!r->valid)
                    continue;
                const sl_cull_metrics *m = &r->metrics;
                const sl_cull_stats *s = &r->stats;
                out(&f, "%s\n{\"scene\":", first ? "" : ",");
                first = false;
                json_str(&f, b->label);
                out(&f, ",\"frame\":%u,\"time_s\":", fr->source);
                json_num(&f, fr->time);
                out(&f, ",\"camera\":{\"x\":");
                json_num(&f, c->position.x);
                out(&f, ",\"y\":");
                json_num(&f, c->position.y);
                out(&f, ",\"z\":");
                json_num(&f, c->position.z);
                out(&f, ",\"yaw_deg\":%.6g,\"pitch_deg\":%.6g,\"roll_deg\":%.6g,\"fov_deg\":%.6g,\"width\":%u,"
                        "\"height\":%u,\"projection\":\"%s\"}",
                    c->yaw * RAD2DEG, c->pitch * RAD2DEG, c->roll * RAD2DEG, c->fov_y * RAD2DEG, c->width, c->height,
                    c->projection == SL_ORTHOGRAPHIC ? "orthographic" : "perspective");
                if (frame_from_matrices(fr))
                    json_view(&f, &fr->view);
                out(&f, ",\"method\":");
                json_str(&f, b->methods[mi].name);
                out(&f, ",\"guarantee\":\"%s\",\"cull_ms\":", sl_cull_guarantee_name(b->methods[mi].guarantee));
                json_num(&f, r->cull_ms);
                out(&f, ",\"cull_ms_min\":");
                json_num(&f, r->cull_ms_min);
                out(&f, ",\"objects_drawn\":%u,\"triangles_drawn\":%llu,\"visible_exact\":%u,\"triangles_visible\":%llu,"
                        "\"missed_objects\":%u,\"missed_pixels\":%llu,\"extra_objects\":%u,\"overestimation\":",
                    m->result_count, (unsigned long long)m->triangles_rendered, m->visible_count,
                    (unsigned long long)m->triangles_visible, m->missed_count, (unsigned long long)m->missed_pixels,
                    m->extra_count);
                json_num(&f, m->overestimation);
                out(&f, ",\"objects_in_frustum\":%u,\"triangles_in_frustum\":%llu,\"covered_pixels\":%llu,\"oracle_ms\":",
                    fr->objects_in_frustum, (unsigned long long)fr->triangles_in_frustum,
                    (unsigned long long)fr->covered_pixels);
                json_num(&f, fr->oracle_ms);
                out(&f, ",\"stats\":{\"objects_tested\":%llu,\"nodes_visited\":%llu,\"occlusion_tests\":%llu,"
                        "\"queries\":%llu,\"pixels_rasterized\":%llu,\"pixel_queries\":%llu,\"query_stalls\":%llu,"
                        "\"query_wait_ms\":%.6f}",
                    (unsigned long long)s->objects_tested, (unsigned long long)s->nodes_visited,
                    (unsigned long long)s->occlusion_tests, (unsigned long long)s->queries,
                    (unsigned long long)s->pixels_rasterized, (unsigned long long)s->pixel_queries,
                    (unsigned long long)s->query_stalls, s->query_wait_ms);
                out(&f, ",\"phases_ms\":{");
                for (uint32_t p = 0; p < s->phase_count && p < SL_CULL_MAX_PHASES; p++) {
                    out(&f, "%s", p ? "," : "");
                    json_str(&f, s->phase_names[p] ? s->phase_names[p] : "?");
                    out(&f, ":");
                    json_num(&f, s->phase_ms[p]);
                }
                out(&f, "},\"missed\":[");
                for (uint32_t k = 0; k < r->missed_kept; k++)
                    out(&f, "%s{\"id\":%u,\"pixels\":%u}", k ? "," : "", r->missed_ids[k], r->missed_pixels[k]);
                out(&f, "]}");
            }
        }
    }
    out(&f, "]}\n");
    return sl_atomic_commit(&f, err);
}

/* ---- Markdown summary ---- */

/* A count with thousands separators ("1 234 567" would be ambiguous in CSV; this is for tables). */
static const char *grouped(char *buf, size_t n, double v)
{
    char raw[64];
    snprintf(raw, sizeof raw, "%.0f", v);
    size_t len = strlen(raw), o = 0;
    for (size_t i = 0; i < len && o + 2 < n; i++) {
        buf[o++] = raw[i];
        size_t left = len - 1 - i;
        if (left && left % 3 == 0 && raw[i] != '-')
            buf[o++] = ',';
    }
    buf[o] = 0;
    return buf;
}

/* Milliseconds with 3 significant decimals below 10, else 1 decimal. */
static const char *ms_text(char *buf, size_t n, double v)
{
    snprintf(buf, n, v < 10 ? "%.3f" : "%.1f", v);
    return buf;
}

/* Below a scene's table, for the methods that issue occlusion queries (sl_cull_stats.queries): the
 * queries and the stalls (results waited for before they were ready) per frame, means over the
 * judged frames. Nothing when no method queries. */
static void query_line(struct sl_bench_t *b, FILE *fp)
{
    bool any = false;
    for (uint32_t mi = 0; mi < b->method_count; mi++) {
        uint64_t queries = 0, stalls = 0;
        double wait = 0;
        uint32_t frames = 0;
        for (uint32_t fi = 0; fi < b->frames.count; fi++) {
            const sl_bench_record *r = bench_rec(b, fi, mi);
            if (!r->valid)
                continue;
            frames++;
            queries += r->stats.queries;
            stalls += r->stats.query_stalls;
            wait += r->stats.query_wait_ms;
        }
        if (!queries)
            continue;
        fprintf(fp, "%s %s %.1f queries (%.1f stalls, %.3f ms wait)", any ? ";" : "Occlusion queries per frame (mean):",
                b->methods[mi].name, (double)queries / frames, (double)stalls / frames, wait / frames);
        any = true;
    }
    if (any)
        fprintf(fp, ".\n\n");
}

/* A ranked column's value as the summary table prints it (counts to the unit, over-estimation to
 * two decimals, times as ms_text), so that two cells that read the same tie. */
static double column_printed(const sl_bench_summary *s, int c)
{
    char t[32];
    switch (c) {
    case SL_BENCH_COL_OBJECTS: return round(s->objects_drawn_mean);
    case SL_BENCH_COL_TRIANGLES: return round(s->triangles_drawn_mean);
    case SL_BENCH_COL_OVERESTIMATION: snprintf(t, sizeof t, "%.2f", s->overestimation); break;
    case SL_BENCH_COL_MISSED_OBJECTS: return (double)s->missed_objects_total;
    case SL_BENCH_COL_MISSED_PIXELS: return (double)s->missed_pixels_total;
    case SL_BENCH_COL_MS_MEDIAN: ms_text(t, sizeof t, s->cull_ms.median); break;
    case SL_BENCH_COL_MS_P95: ms_text(t, sizeof t, s->cull_ms.p95); break;
    default: ms_text(t, sizeof t, s->cull_ms.max); break;
    }
    return strtod(t, NULL);
}

/* The drawn counts and the over-estimation are ranked among the methods that missed nothing. */
static bool column_needs_no_miss(int c)
{
    return c == SL_BENCH_COL_OBJECTS || c == SL_BENCH_COL_TRIANGLES || c == SL_BENCH_COL_OVERESTIMATION;
}

uint32_t sl_bench_best_columns(sl_bench b, uint32_t method)
{
    if (!b || method >= b->method_count)
        return 0;
    sl_bench_summary mine, s;
    if (sl_bench_summarize(b, method, &mine, NULL) != SL_OK || !mine.frames)
        return 0;
    uint32_t mask = 0;
    for (int c = 0; c < SL_BENCH_COLUMN_COUNT; c++) {
        if (column_needs_no_miss(c) && mine.missed_objects_total)
            continue;
        double v = column_printed(&mine, c);
        bool best = true, spread = false;
        for (uint32_t mi = 0; mi < b->method_count && best; mi++) {
            if (mi == method || sl_bench_summarize(b, mi, &s, NULL) != SL_OK || !s.frames ||
                (column_needs_no_miss(c) && s.missed_objects_total))
                continue;
            double o = column_printed(&s, c);
            spread |= o != v;
            best = o >= v;
        }
        if (best && spread)
            mask |= 1u << c;
    }
    return mask;
}

static void summary_md(const sl_bench *benches, uint32_t count, FILE *fp)
{
    for (uint32_t bi = 0; bi < count; bi++) {
        struct sl_bench_t *b = benches[bi];
        sl_scene_stats ss;
        sl_scene_get_stats(b->scene, &ss);
        char g1[48], g2[48], g3[48];
        size_t nf = b->frames.count, outside = 0;
        double vis = 0, tv = 0;
        double *oms = sl_alloc(&b->alloc, SL_MAX(nf, 1) * sizeof(double));
        for (size_t i = 0; i < nf; i++) {
            const sl_bench_frame *fr = &SL_AT(b->frames, sl_bench_frame, i);
            if (oms)
                oms[i] = fr->oracle_ms;
            if (fr->out_of_domain) {
                outside++;
                continue;
            }
            vis += fr->visible_count;
            tv += (double)fr->triangles_visible;
        }
        sl_series_summary os;
        memset(&os, 0, sizeof os);
        if (oms)
            sl_series_summarize(oms, nf, &b->alloc, &os, NULL);
        sl_free(&b->alloc, oms, SL_MAX(nf, 1) * sizeof(double));
        const sl_bench_frame *f0 = nf ? &SL_AT(b->frames, sl_bench_frame, 0) : NULL;
        fprintf(fp, "### %s\n\n", b->label);
        fprintf(fp, "%s objects, %s triangles; %zu frames", grouped(g1, sizeof g1, ss.object_count),
                grouped(g2, sizeof g2, (double)ss.instanced_triangle_count), nf);
        if (f0)
            fprintf(fp, " at %ux%u", f0->camera.width, f0->camera.height);
        if (outside)
            fprintf(fp, " (%zu skipped: eye outside the domain, in solid or void space)", outside);
        /* frames from an engine's matrices: what the view is (the camera columns only approximate it) */
        const sl_bench_frame *fm = NULL;
        size_t nmat = 0;
        for (size_t i = 0; i < nf; i++)
            if (frame_from_matrices(&SL_AT(b->frames, sl_bench_frame, i)) && !nmat++)
                fm = &SL_AT(b->frames, sl_bench_frame, i);
        if (fm) {
            const sl_view *v = &fm->view;
            char far_text[32];
            snprintf(far_text, sizeof far_text, isfinite(v->far_plane) ? "%.6g m" : "infinite", v->far_plane);
            fprintf(fp, "; %zu from an engine's matrices (frame %u: %s depth, %s, near %.6g m, far %s, near rectangle "
                        "x [%.6g, %.6g] y [%.6g, %.6g] m%s%s)",
                    nmat, fm->source, sl_clip_depth_name(v->clip_depth),
                    v->projection == SL_ORTHOGRAPHIC ? "orthographic" : "perspective", v->near_plane, far_text,
                    v->rect_left, v->rect_right, v->rect_bottom, v->rect_top,
                    v->mirrored_x || v->mirrored_y ? ", mirrored in " : "",
                    v->mirrored_x ? (v->mirrored_y ? "x and y" : "x") : (v->mirrored_y ? "y" : ""));
        }
        size_t judged = nf - outside;
        fprintf(fp, "; exact visible set %s objects and %s triangles per frame (mean); oracle %.1f ms median, %.1f ms "
                    "p95.\n\n",
                grouped(g1, sizeof g1, judged ? vis / (double)judged : 0),
                grouped(g3, sizeof g3, judged ? tv / (double)judged : 0), os.median, os.p95);
        fprintf(fp, "| method | guarantee | frames | objects drawn | triangles drawn | exact visible | over-estimation "
                    "| missed objects | missed pixels | cull ms median | cull ms p95 | cull ms max |\n");
        fprintf(fp, "|---|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|\n");
        for (uint32_t mi = 0; mi < b->method_count; mi++) {
            sl_bench_summary s;
            if (sl_bench_summarize(b, mi, &s, NULL) != SL_OK)
                continue;
            const bench_method *m = &b->methods[mi];
            bool violated = sl_cull_guarantee_keeps_visible(m->guarantee, true) && s.missed_objects_total;
            char t1[32], t2[32], t3[32], over[32], missed[48], mpx[32];
            uint32_t best = sl_bench_best_columns(b, mi);
#define B(col) ((best >> (col)) & 1u ? "**" : "")
            snprintf(over, sizeof over, "%.2f", s.overestimation);
            snprintf(missed, sizeof missed, "%llu", (unsigned long long)s.missed_objects_total);
            snprintf(mpx, sizeof mpx, "%llu", (unsigned long long)s.missed_pixels_total);
            fprintf(fp, "| %s | %s | %u | %s%s%s | %s%s%s | %s | %s%s%s | %s%s%s%s | %s%s%s | %s%s%s | %s%s%s | %s%s%s |\n",
                    m->name, sl_cull_guarantee_name(m->guarantee), s.frames, B(SL_BENCH_COL_OBJECTS),
                    grouped(g1, sizeof g1, s.objects_drawn_mean), B(SL_BENCH_COL_OBJECTS), B(SL_BENCH_COL_TRIANGLES),
                    grouped(g2, sizeof g2, s.triangles_drawn_mean), B(SL_BENCH_COL_TRIANGLES),
                    grouped(g3, sizeof g3, s.visible_mean), B(SL_BENCH_COL_OVERESTIMATION), over,
                    B(SL_BENCH_COL_OVERESTIMATION), violated ? "**" : B(SL_BENCH_COL_MISSED_OBJECTS), missed,
                    violated ? " VIOLATION" : "", violated ? "**" : B(SL_BENCH_COL_MISSED_OBJECTS),
                    B(SL_BENCH_COL_MISSED_PIXELS), mpx, B(SL_BENCH_COL_MISSED_PIXELS), B(SL_BENCH_COL_MS_MEDIAN),
                    ms_text(t1, sizeof t1, s.cull_ms.median), B(SL_BENCH_COL_MS_MEDIAN), B(SL_BENCH_COL_MS_P95),
                    ms_text(t2, sizeof t2, s.cull_ms.p95), B(SL_BENCH_COL_MS_P95), B(SL_BENCH_COL_MS_MAX),
                    ms_text(t3, sizeof t3, s.cull_ms.max), B(SL_BENCH_COL_MS_MAX));
#undef B
        }
        fprintf(fp, "\n");
        query_line(b, fp);
        sl_bench_recommendation rec;
        if (sl_bench_recommend(b, &rec, NULL) == SL_OK)
            fprintf(fp, "**Recommendation.** %s\n\n", rec.text);
    }
}

void sl_bench_print_summary(const sl_bench *benches, uint32_t count, FILE *fp)
{
    if (!fp || check_benches(benches, count, "", "sl_bench_print_summary", NULL) != SL_OK)
        return;
    summary_md(benches, count, fp);
}

sl_status sl_bench_write_summary(const sl_bench *benches, uint32_t count, const char *path, sl_error *err)
{
    sl_status st = check_benches(benches, count, path, "sl_bench_write_summary", err);
    if (st != SL_OK)
        return st;
    sl_atomic_file f;
    st = sl_atomic_open(count ? &benches[0]->alloc : NULL, path, &f, err);
    if (st != SL_OK)
        return st;
    out(&f, "# Sightline benchmark summary\n\n"
            "Means are per frame; missed objects and pixels are totals over the frames (a conservative method must "
            "show 0); over-estimation is the objects drawn over the exact visible objects, each summed over the frames "
            "(a ratio of sums); cull times are the per-frame medians of the repeats, summarised over the frames. "
            "Each scene ends with a recommendation: the fastest conservative method within a tightness bound and the "
            "tightest within a time bound. The best value of each ranked column is in bold (sl_bench_best_columns). "
            "Columns: docs/bench.md.\n\n");
    if (!f.failed) {
        summary_md(benches, count, f.fp);
        if (ferror(f.fp))
            f.failed = true;
    }
    return sl_atomic_commit(&f, err);
}

/* ---- plots ---- */

sl_status sl_bench_write_plots(sl_bench b, const char *prefix, sl_error *err)
{
    if (!b || !prefix)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_bench_write_plots: bench and prefix must not be NULL");
    const sl_allocator *a = &b->alloc;
    size_t nf = b->frames.count, nm = b->method_count;
    size_t cells = SL_MAX(nf, 1) * (3 * nm + 2);
    double *buf = sl_alloc(a, cells * sizeof(double));
    size_t plen = strlen(prefix) + 32;
    char *path = sl_alloc(a, plen);
    sl_plot_series *series = sl_alloc(a, (nm + 1) * sizeof *series);
    sl_status st = SL_OK;
    if (!buf || !path || !series) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for the plots", b->label);
        goto done;
    }
    /* columns: cull ms, triangles drawn, missed pixels per method; exact triangles; frame numbers */
    double *ms = buf, *tri = buf + nf * nm, *miss = buf + 2 * nf * nm, *exact = buf + 3 * nf * nm,
           *x = exact + nf;
    for (size_t fi = 0; fi < nf; fi++) {
        const sl_bench_frame *fr = &SL_AT(b->frames, sl_bench_frame, fi);
        exact[fi] = (double)fr->triangles_visible;
        x[fi] = (double)fr->source;
        for (size_t mi = 0; mi < nm; mi++) {
            const sl_bench_record *r = bench_rec(b, (uint32_t)fi, (uint32_t)mi);
            ms[mi * nf + fi] = r->valid ? r->cull_ms : NAN;
            tri[mi * nf + fi] = r->valid ? (double)r->metrics.triangles_rendered : NAN;
            miss[mi * nf + fi] = r->valid ? (double)r->metrics.missed_pixels : NAN;
        }
    }
    char title[256];
    sl_plot plot;
    memset(&plot, 0, sizeof plot);
    plot.x = nf ? x : NULL;
    plot.x_label = "frame";
    plot.series = series;

    for (size_t mi = 0; mi < nm; mi++)
        series[mi] = (sl_plot_series){b->methods[mi].name, ms + mi * nf, nf, sl_plot_color((uint32_t)mi), false,
                                      (uint32_t)mi + 1};
    snprintf(title, sizeof title, "%s: cull time per frame", b->label);
    plot.title = title;
    plot.y_label = "cull time (ms)";
    plot.series_count = (uint32_t)nm;
    plot.y_scale = SL_PLOT_AUTO;
    snprintf(path, plen, "%scull-time.svg", prefix);
    st = sl_plot_write_svg(&plot, path, a, err);
    if (st != SL_OK)
        goto done;

    for (size_t mi = 0; mi < nm; mi++)
        series[mi].y = tri + mi * nf;
    series[nm] = (sl_plot_series){"exact visible", exact, nf, 0x000000, true, 0};
    snprintf(title, sizeof title, "%s: triangles drawn per frame", b->label);
    plot.y_label = "triangles";
    plot.series_count = (uint32_t)nm + 1;
    snprintf(path, plen, "%striangles.svg", prefix);
    st = sl_plot_write_svg(&plot, path, a, err);
    if (st != SL_OK)
        goto done;

    /* only the methods that missed something: a flat line at 0 would read as a miss */
    size_t with_misses = 0;
    for (size_t mi = 0; mi < nm; mi++) {
        bool any = false;
        for (size_t fi = 0; fi < nf && !any; fi++)
            any = miss[mi * nf + fi] > 0;
        if (any) {
            series[with_misses] = series[mi];
            series[with_misses++].y = miss + mi * nf;
        }
    }
    snprintf(title, sizeof title, "%s: missed pixels per frame (methods with misses only)", b->label);
    plot.y_label = "missed pixels";
    plot.series_count = (uint32_t)with_misses;
    plot.empty_note = "no misses: no method missed a visible pixel in any frame";
    plot.y_scale = SL_PLOT_LINEAR;
    snprintf(path, plen, "%smissed-pixels.svg", prefix);
    st = sl_plot_write_svg(&plot, path, a, err);
done:
    sl_free(a, buf, cells * sizeof(double));
    sl_free(a, path, plen);
    sl_free(a, series, (nm + 1) * sizeof *series);
    return st;
}

/* ---- violations ---- */

uint64_t sl_bench_print_violations(const sl_bench *benches, uint32_t count, uint32_t max_lines, FILE *fp)
{
    if (check_benches(benches, count, "", "sl_bench_print_violations", NULL) != SL_OK)
        return 0;
    uint64_t total = 0;
    for (uint32_t bi = 0; bi < count; bi++) {
        struct sl_bench_t *b = benches[bi];
        for (uint32_t mi = 0; mi < b->method_count; mi++) {
            const bench_method *m = &b->methods[mi];
            if (!sl_cull_guarantee_keeps_visible(m->guarantee, true))
                continue;
            uint32_t lines = 0, more = 0;
            for (uint32_t fi = 0; fi < b->frames.count; fi++) {
                const sl_bench_record *r = bench_rec(b, fi, mi);
                if (!r->valid || !r->metrics.missed_count)
                    continue;
                total += r->metrics.missed_count;
                if (!fp)
                    continue;
                if (lines >= max_lines) {
                    more++;
                    continue;
                }
                lines++;
                fprintf(fp,
                        "CONSERVATIVENESS VIOLATION: scene %s, frame %u: method %s (conservative) missed %u visible "
                        "object%s (%llu pixels):",
                        b->label, SL_AT(b->frames, sl_bench_frame, fi).source, m->name, r->metrics.missed_count, r->metrics.missed_count == 1 ? "" : "s",
                        (unsigned long long)r->metrics.missed_pixels);
                for (uint32_t k = 0; k < r->missed_kept; k++)
                    fprintf(fp, "%s object %u (%u px)", k ? "," : "", r->missed_ids[k], r->missed_pixels[k]);
                if (r->metrics.missed_count > r->missed_kept)
                    fprintf(fp, ", ...");
                fprintf(fp, "\n");
            }
            if (fp && more)
                fprintf(fp, "CONSERVATIVENESS VIOLATION: scene %s: method %s missed objects in %u more frames\n",
                        b->label, m->name, more);
        }
    }
    return total;
}
