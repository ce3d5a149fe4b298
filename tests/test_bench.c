/* The benchmark harness on a hand-built scene whose answer is known: a wall hides one box, two
 * boxes are in plain sight, one is behind the camera. The records, metrics and summaries of vfc
 * and of external methods (an exact answer, a broken "conservative" one that drops a visible box,
 * an aggressive one) are checked against the hand count; then the writers (CSV rows, JSON, the
 * Markdown summary, plots, the top-down map with its orientation), scene specs, a generated-city
 * walk with zero misses for every registered conservative method, and the error paths. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "sightline/bench.h"
#include "sightline/gen.h"
#include "sightline/image.h"
#include "support/counting_alloc.h"
#include "support/view_matrices.h"
#include "truth/plot.h"

/* ---- the scene ---- */

static uint32_t add_mesh_object(sl_scene s, const float *pos, uint32_t nv, const uint32_t *idx, uint32_t nt)
{
    sl_error err;
    sl_mesh_desc md = {pos, NULL, nv, idx, nt, NULL};
    uint32_t mesh, obj;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, NULL, 0xffffffffu, SL_KIND_OTHER, 0, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &obj, &err), SL_OK);
    return obj;
}

/* An axis-aligned box of 12 triangles (both sides are drawn: it is not flagged closed). */
static uint32_t add_box(sl_scene s, sl_vec3 lo, sl_vec3 hi)
{
    float p[24];
    for (int i = 0; i < 8; i++) {
        p[3 * i] = (i & 1) ? hi.x : lo.x;
        p[3 * i + 1] = (i & 2) ? hi.y : lo.y;
        p[3 * i + 2] = (i & 4) ? hi.z : lo.z;
    }
    static const uint32_t idx[36] = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                     2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};
    return add_mesh_object(s, p, 8, idx, 12);
}

/* ids of the known scene */
typedef struct known {
    sl_scene scene;
    uint32_t wall, hidden, front, side, behind;
} known;

/* Camera at the origin looking along +X. The wall (x = 10, y in [-20, 2]) hides `hidden`
 * (x 20..22, y -5..-3); `front` is between the camera and the wall; `side` (x 30..32, y 8..10)
 * shows past the wall's end; `behind` (x -12..-10, y 4..6) is behind the camera, north-west. */
static known make_known(void)
{
    known k;
    assert_int_equal(sl_scene_create(NULL, &k.scene, NULL), SL_OK);
    float wp[12] = {10, -20, -5, 10, 2, -5, 10, 2, 20, 10, -20, 20};
    uint32_t wi[6] = {0, 1, 2, 0, 2, 3};
    k.wall = add_mesh_object(k.scene, wp, 4, wi, 2);
    k.hidden = add_box(k.scene, (sl_vec3){20, -5, -1}, (sl_vec3){22, -3, 1});
    k.front = add_box(k.scene, (sl_vec3){5, -4, -1}, (sl_vec3){6, -3, 0});
    k.side = add_box(k.scene, (sl_vec3){30, 8, -1}, (sl_vec3){32, 10, 1});
    k.behind = add_box(k.scene, (sl_vec3){-12, 4, -1}, (sl_vec3){-10, 6, 1});
    return k;
}

static sl_camera camera_at(float yaw)
{
    sl_camera c = sl_camera_default();
    c.position = (sl_vec3){0, 0, 0};
    c.yaw = yaw;
    c.width = 256;
    c.height = 192;
    return c;
}

static char *temp_dir(void)
{
    static char dir[64];
    snprintf(dir, sizeof dir, "/tmp/sl_test_bench_XXXXXX");
    assert_non_null(mkdtemp(dir));
    return dir;
}

static void remove_dir(const char *dir)
{
    char cmd[256];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    assert_int_equal(system(cmd), 0);
}

static char *read_text(const char *path, size_t *len)
{
    uint8_t *data;
    size_t size;
    sl_error err;
    assert_int_equal(sl_file_read_all(NULL, path, &data, &size, &err), SL_OK);
    char *text = malloc(size + 1);
    memcpy(text, data, size);
    text[size] = 0;
    sl_free(NULL, data, size);
    if (len)
        *len = size;
    return text;
}

static size_t count_lines(const char *text)
{
    size_t n = 0;
    for (; *text; text++)
        n += *text == '\n';
    return n;
}

/* ---- tests ---- */

static void test_known_scene_records(void **state)
{
    (void)state;
    known k = make_known();
    sl_test_counter counter = {0, 0, 0};
    sl_allocator alloc = sl_test_counting_allocator(&counter);
    sl_bench_method_spec specs[] = {{"vfc", NULL}};
    sl_bench_options opt = sl_bench_default_options();
    opt.repeat = 3;
    opt.label = "known";
    sl_bench b;
    sl_error err;
    assert_int_equal(sl_bench_create(k.scene, specs, 1, &opt, &alloc, &b, &err), SL_OK);
    uint32_t exact, broken, rough;
    assert_int_equal(sl_bench_add_external(b, "exact", SL_CONSERVATIVE, &exact, &err), SL_OK);
    assert_int_equal(sl_bench_add_external(b, "broken", SL_CONSERVATIVE, &broken, &err), SL_OK);
    assert_int_equal(sl_bench_add_external(b, "rough", SL_AGGRESSIVE, &rough, &err), SL_OK);
    assert_int_equal(sl_bench_method_count(b), 4);
    assert_string_equal(sl_bench_label(b), "known");
    /* the options reports show can be replaced (the command names a staged file where it ends up);
     * the counting allocator sees the old string freed */
    sl_bench_method_info shown;
    assert_int_equal(sl_bench_set_shown_options(b, rough, "file=out/rough.slpvs", &err), SL_OK);
    assert_int_equal(sl_bench_method(b, rough, &shown, &err), SL_OK);
    assert_string_equal(shown.options, "file=out/rough.slpvs");
    assert_int_equal(sl_bench_set_shown_options(b, 4, "x", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_bench_set_shown_options(b, rough, NULL, &err), SL_OK);
    assert_int_equal(sl_bench_method(b, rough, &shown, &err), SL_OK);
    assert_string_equal(shown.options, "");

    /* frame 0: looking along +X */
    sl_camera c0 = camera_at(0);
    assert_int_equal(sl_bench_run_frame(b, &c0, &err), SL_OK);
    sl_oracle_frame truth;
    assert_int_equal(sl_bench_last_truth(b, &truth, &err), SL_OK);
    assert_int_equal(truth.visible_count, 3);
    assert_int_equal(truth.visible[0], k.wall);
    assert_int_equal(truth.visible[1], k.front);
    assert_int_equal(truth.visible[2], k.side);
    uint32_t side_pixels = truth.pixels[2];
    assert_true(side_pixels > 0);

    sl_bench_frame fr;
    assert_int_equal(sl_bench_get_frame(b, 0, &fr, &err), SL_OK);
    assert_int_equal(fr.visible_count, 3);
    assert_int_equal(fr.triangles_visible, 2 + 12 + 12);
    assert_int_equal(fr.camera.width, 256);

    /* vfc keeps everything in the frustum: the visible three and the hidden box, not the one behind */
    sl_bench_record r;
    assert_int_equal(sl_bench_get_record(b, 0, 0, &r, &err), SL_OK);
    assert_true(r.valid);
    assert_int_equal(r.metrics.result_count, 4);
    assert_int_equal(r.metrics.visible_count, 3);
    assert_int_equal(r.metrics.missed_count, 0);
    assert_int_equal(r.metrics.missed_pixels, 0);
    assert_int_equal(r.metrics.extra_count, 1);
    assert_int_equal(r.metrics.triangles_rendered, 2 + 3 * 12);
    assert_int_equal(r.metrics.triangles_visible, 26);
    assert_true(fabs(r.metrics.overestimation - 4.0 / 3.0) < 1e-12);
    assert_true(r.cull_ms_min <= r.cull_ms && r.cull_ms >= 0);
    assert_int_equal(r.stats.objects_visible, 4);
    const uint32_t *ids;
    uint32_t n;
    assert_int_equal(sl_bench_last_result(b, 0, &ids, &n, &err), SL_OK);
    assert_int_equal(n, 4);
    assert_int_equal(ids[3], k.side);

    /* external methods are pending until submitted */
    assert_int_equal(sl_bench_get_record(b, 0, exact, &r, &err), SL_OK);
    assert_false(r.valid);
    assert_int_equal(sl_bench_submit(b, exact, truth.visible, truth.visible_count, 0.5, &err), SL_OK);
    uint32_t dropped[] = {k.wall, k.front}; /* drops `side`, which is visible */
    assert_int_equal(sl_bench_submit(b, broken, dropped, 2, 0.25, &err), SL_OK);
    uint32_t only_wall[] = {k.wall};
    assert_int_equal(sl_bench_submit(b, rough, only_wall, 1, 0.1, &err), SL_OK);
    assert_int_equal(sl_bench_get_record(b, 0, exact, &r, &err), SL_OK);
    assert_true(r.valid);
    assert_int_equal(r.metrics.missed_count, 0);
    assert_true(r.metrics.overestimation == 1.0);
    assert_true(r.cull_ms == 0.5);
    assert_int_equal(sl_bench_get_record(b, 0, broken, &r, &err), SL_OK);
    assert_int_equal(r.metrics.missed_count, 1);
    assert_int_equal(r.missed_kept, 1);
    assert_int_equal(r.missed_ids[0], k.side);
    assert_int_equal(r.missed_pixels[0], side_pixels);
    assert_int_equal(r.metrics.missed_pixels, side_pixels);
    assert_int_equal(sl_bench_get_record(b, 0, rough, &r, &err), SL_OK);
    assert_int_equal(r.metrics.missed_count, 2);

    /* bad submissions change nothing */
    uint32_t unsorted[] = {k.side, k.wall};
    assert_int_equal(sl_bench_submit(b, exact, unsorted, 2, 0, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "ascending"));
    uint32_t out_of_range[] = {99};
    assert_int_equal(sl_bench_submit(b, exact, out_of_range, 1, 0, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_bench_submit(b, 0, truth.visible, 1, 0, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_bench_submit(b, exact, truth.visible, 1, NAN, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_bench_get_record(b, 0, exact, &r, &err), SL_OK);
    assert_int_equal(r.metrics.missed_count, 0);
    assert_int_equal(sl_bench_add_external(b, "late", SL_AGGRESSIVE, NULL, &err), SL_ERROR_INVALID_ARGUMENT);

    /* frame 1: turned around, only the box behind is visible; "broken" is not submitted */
    sl_camera c1 = camera_at((float)M_PI);
    assert_int_equal(sl_bench_run_frame(b, &c1, &err), SL_OK);
    assert_int_equal(sl_bench_last_truth(b, &truth, &err), SL_OK);
    assert_int_equal(truth.visible_count, 1);
    assert_int_equal(truth.visible[0], k.behind);
    assert_int_equal(sl_bench_submit(b, exact, truth.visible, 1, 0.5, &err), SL_OK);
    assert_int_equal(sl_bench_submit(b, rough, NULL, 0, 0.1, &err), SL_OK);
    assert_int_equal(sl_bench_frame_count(b), 2);

    sl_bench_summary s;
    assert_int_equal(sl_bench_summarize(b, 0, &s, &err), SL_OK);
    assert_int_equal(s.frames, 2);
    assert_true(s.visible_mean == 2.0);
    assert_int_equal(s.missed_objects_total, 0);
    assert_int_equal(s.first_miss_frame, SL_NONE);
    assert_int_equal(s.cull_ms.count, 2);
    assert_int_equal(sl_bench_summarize(b, broken, &s, &err), SL_OK);
    assert_int_equal(s.frames, 1); /* only the submitted frame counts */
    assert_int_equal(s.missed_objects_total, 1);
    assert_int_equal(s.missed_pixels_total, side_pixels);
    assert_int_equal(s.frames_with_misses, 1);
    assert_int_equal(s.first_miss_frame, 0);
    assert_int_equal(s.first_miss_object, k.side);
    assert_true(s.cull_ms.median == 0.25);
    assert_int_equal(sl_bench_summarize(b, rough, &s, &err), SL_OK);
    assert_int_equal(s.missed_objects_total, 3);
    /* only conservative methods violate: the broken one's single miss */
    assert_int_equal(sl_bench_violations(b), 1);

    char *buf = NULL;
    size_t len = 0;
    FILE *mem = open_memstream(&buf, &len);
    assert_int_equal(sl_bench_print_violations(&b, 1, 10, mem), 1);
    fclose(mem);
    char expect[160];
    snprintf(expect, sizeof expect, "frame 0: method broken (conservative) missed 1 visible object (%u pixels): object %u",
             side_pixels, k.side);
    assert_non_null(strstr(buf, "CONSERVATIVENESS VIOLATION: scene known"));
    assert_non_null(strstr(buf, expect));
    assert_null(strstr(buf, "rough"));
    free(buf);

    sl_bench_destroy(b);
    assert_int_equal(counter.live, 0);
    sl_scene_destroy(k.scene);
}

/* The query counts in the reports: hoq (its own CPU backend, latency=1, so every result is waited
 * for before it is ready: a stall) beside vfc (no queries). frames.csv ends with query_stalls,
 * frames.json's stats carry it, the summary has a line of queries and stalls per frame. */
static void test_query_stalls_reported(void **state)
{
    (void)state;
    known k = make_known();
    sl_bench_method_spec specs[] = {{"vfc", NULL}, {"gl-stopwait", "latency=1,leaf_size=1"}};
    sl_bench_options opt = sl_bench_default_options();
    opt.label = "known";
    sl_bench b;
    sl_error err;
    assert_int_equal(sl_bench_create(k.scene, specs, 2, &opt, NULL, &b, &err), SL_OK);
    uint64_t queries = 0, stalls = 0;
    for (int f = 0; f < 2; f++) {
        sl_camera c = camera_at(0);
        assert_int_equal(sl_bench_run_frame(b, &c, &err), SL_OK);
        sl_bench_record r;
        assert_int_equal(sl_bench_get_record(b, (uint32_t)f, 1, &r, &err), SL_OK);
        queries += r.stats.queries;
        stalls += r.stats.query_stalls;
        assert_int_equal(r.stats.query_stalls, r.stats.queries); /* latency 1: every wait stalls */
    }
    assert_true(stalls > 0);
    char *dir = temp_dir();
    char path[256], want[128];
    snprintf(path, sizeof path, "%s/frames.csv", dir);
    assert_int_equal(sl_bench_write_csv(&b, 1, path, &err), SL_OK);
    char *text = read_text(path, NULL);
    assert_non_null(strstr(text, ",phases,missed,skipped,query_stalls,query_wait_ms\n"));
    /* each row's last field but one: 0 for vfc, the stalls for gl-stopwait; the last, its wait ms */
    uint32_t hoq_rows = 0, vfc_rows = 0;
    uint64_t csv_stalls = 0;
    for (const char *line = strchr(text, '\n') + 1; *line; line = strchr(line, '\n') + 1) {
        const char *end = strchr(line, '\n'), *wait = end;
        while (wait > line && wait[-1] != ',')
            wait--;
        const char *last = wait - 1;
        while (last > line && last[-1] != ',')
            last--;
        assert_true(wait < end); /* the wait time: a number */
        if (strstr(line, ",gl-stopwait,") && strstr(line, ",gl-stopwait,") < end) {
            hoq_rows++;
            csv_stalls += strtoull(last, NULL, 10);
            assert_true(strtod(wait, NULL) > 0); /* its backend's simulated clock waited */
        } else {
            vfc_rows++;
            assert_int_equal(strtoull(last, NULL, 10), 0);
            assert_true(last < wait - 1); /* a number, not empty */
            assert_true(strtod(wait, NULL) == 0);
        }
    }
    assert_int_equal(hoq_rows, 2);
    assert_int_equal(vfc_rows, 2);
    assert_int_equal(csv_stalls, stalls);
    free(text);
    snprintf(path, sizeof path, "%s/frames.json", dir);
    assert_int_equal(sl_bench_write_json(&b, 1, path, &err), SL_OK);
    text = read_text(path, NULL);
    sl_bench_record r0;
    assert_int_equal(sl_bench_get_record(b, 0, 1, &r0, &err), SL_OK);
    snprintf(want, sizeof want, "\"pixel_queries\":%llu,\"query_stalls\":%llu,\"query_wait_ms\":%.6f}",
             (unsigned long long)r0.stats.pixel_queries, (unsigned long long)r0.stats.query_stalls,
             r0.stats.query_wait_ms);
    assert_non_null(strstr(text, want));
    free(text);
    snprintf(path, sizeof path, "%s/summary.md", dir);
    assert_int_equal(sl_bench_write_summary(&b, 1, path, &err), SL_OK);
    text = read_text(path, NULL);
    snprintf(want, sizeof want, "Occlusion queries per frame (mean): gl-stopwait %.1f queries (%.1f stalls, ", queries / 2.0,
             stalls / 2.0);
    assert_non_null(strstr(text, want));
    const char *ql = strstr(text, "Occlusion queries per frame"), *qe = ql ? strchr(ql, '\n') : NULL;
    assert_non_null(qe);
    const char *v = strstr(ql, "vfc");
    assert_true(!v || v > qe); /* no queries, no entry */
    free(text);
    remove_dir(dir);
    sl_bench_destroy(b);
    sl_scene_destroy(k.scene);
}

static void test_reports(void **state)
{
    (void)state;
    known k = make_known();
    sl_bench_method_spec specs[] = {{"vfc", "coherence=false"}};
    sl_bench_options opt = sl_bench_default_options();
    opt.label = "known";
    opt.width = 200; /* overrides the cameras' viewport */
    opt.height = 150;
    sl_bench b;
    sl_error err;
    assert_int_equal(sl_bench_create(k.scene, specs, 1, &opt, NULL, &b, &err), SL_OK);
    sl_bench_method_info info;
    assert_int_equal(sl_bench_method(b, 0, &info, &err), SL_OK);
    assert_string_equal(info.name, "vfc");
    assert_non_null(strstr(info.options, "coherence=false"));
    assert_false(info.external);
    uint32_t broken;
    assert_int_equal(sl_bench_add_external(b, "broken", SL_CONSERVATIVE, &broken, &err), SL_OK);
    for (int f = 0; f < 3; f++) {
        sl_camera c = camera_at(f == 2 ? (float)M_PI : 0);
        assert_int_equal(sl_bench_run_frame(b, &c, &err), SL_OK);
        if (f < 2) {
            uint32_t dropped[] = {k.wall, k.front};
            assert_int_equal(sl_bench_submit(b, broken, dropped, 2, 1.0, &err), SL_OK);
        }
    }
    sl_bench_frame fr;
    assert_int_equal(sl_bench_get_frame(b, 0, &fr, &err), SL_OK);
    assert_int_equal(fr.camera.width, 200);
    assert_int_equal(fr.camera.height, 150);

    char *dir = temp_dir();
    char path[256];
    /* CSV: a header and one row per valid frame x method (3 vfc + 2 broken) */
    snprintf(path, sizeof path, "%s/frames.csv", dir);
    assert_int_equal(sl_bench_write_csv(&b, 1, path, &err), SL_OK);
    char *text = read_text(path, NULL);
    assert_int_equal(count_lines(text), 1 + 3 + 2);
    assert_true(!strncmp(text, "scene,frame,time_s,x,y,z,yaw_deg,pitch_deg,roll_deg,method,guarantee,cull_ms,", 77));
    /* camera frames: no view columns */
    assert_true(strstr(text, ",missed,skipped,query_stalls,query_wait_ms\n") == strchr(text, '\n') - 42);
    char row[128];
    snprintf(row, sizeof row, ",broken,conservative,1.000000,1.000000,2,14,3,26,1,");
    assert_non_null(strstr(text, row));
    snprintf(row, sizeof row, ",%u:", k.side); /* the missed object and its pixels, last column */
    assert_non_null(strstr(text, row));
    free(text);
    /* JSON */
    snprintf(path, sizeof path, "%s/frames.json", dir);
    assert_int_equal(sl_bench_write_json(&b, 1, path, &err), SL_OK);
    text = read_text(path, NULL);
    assert_true(!strncmp(text, "{\"format\":\"sightline-bench-frames\",\"version\":1,", 47));
    snprintf(row, sizeof row, "\"missed\":[{\"id\":%u,\"pixels\":", k.side);
    assert_non_null(strstr(text, row));
    assert_non_null(strstr(text, "\"external\":true"));
    size_t rows = 0;
    for (const char *p = text; (p = strstr(p, "\"method\":")); p++)
        rows++;
    assert_int_equal(rows, 5);
    free(text);
    /* the summary */
    snprintf(path, sizeof path, "%s/summary.md", dir);
    assert_int_equal(sl_bench_write_summary(&b, 1, path, &err), SL_OK);
    text = read_text(path, NULL);
    assert_non_null(strstr(text, "### known"));
    assert_non_null(strstr(text, "| vfc | conservative | 3 | "));
    assert_non_null(strstr(text, "| broken | conservative | 2 | "));
    assert_non_null(strstr(text, "**2 VIOLATION**"));
    /* the best cells, in bold: broken draws fewer objects but missed some, so it is not the tightest,
     * and vfc, alone among those that missed nothing, has no one to be tighter than; vfc missed
     * nothing and was faster than broken's 1 ms in every frame */
    uint32_t times = 1u << SL_BENCH_COL_MS_MEDIAN | 1u << SL_BENCH_COL_MS_P95 | 1u << SL_BENCH_COL_MS_MAX;
    assert_int_equal(sl_bench_best_columns(b, 0),
                     1u << SL_BENCH_COL_MISSED_OBJECTS | 1u << SL_BENCH_COL_MISSED_PIXELS | times);
    assert_int_equal(sl_bench_best_columns(b, broken), 0);
    assert_int_equal(sl_bench_best_columns(b, 2), 0);
    assert_int_equal(sl_bench_best_columns(NULL, 0), 0);
    assert_non_null(strstr(strstr(text, "| vfc | conservative | 3 | "), "| **0** | **0** | **"));
    assert_non_null(strstr(text, "The best value of each ranked column is in bold"));
    free(text);
    /* plots */
    snprintf(path, sizeof path, "%s/known-", dir);
    assert_int_equal(sl_bench_write_plots(b, path, &err), SL_OK);
    static const char *plots[] = {"cull-time", "triangles", "missed-pixels"};
    for (int i = 0; i < 3; i++) {
        snprintf(path, sizeof path, "%s/known-%s.svg", dir, plots[i]);
        text = read_text(path, NULL);
        assert_true(!strncmp(text, "<?xml", 5));
        assert_non_null(strstr(text, "</svg>"));
        /* the missed-pixels plot shows only the methods that missed something */
        if (i == 2) {
            assert_non_null(strstr(text, ">broken</text>"));
            assert_null(strstr(text, ">vfc</text>"));
        } else {
            assert_non_null(strstr(text, ">vfc</text>"));
        }
        if (i == 1)
            assert_non_null(strstr(text, "exact visible"));
        free(text);
    }

    /* the map from frame 0's camera: vfc keeps 3 visible, 1 hidden (orange), drops 1 (grey) */
    sl_bench_map_options mo;
    memset(&mo, 0, sizeof mo);
    mo.camera = camera_at(0);
    mo.size = 300;
    snprintf(path, sizeof path, "%s/known-map-", dir);
    sl_bench_map_counts counts[2];
    assert_int_equal(sl_bench_write_maps(b, &mo, path, counts, &err), SL_OK);
    assert_int_equal(counts[0].visible_kept, 3);
    assert_int_equal(counts[0].missed, 0);
    assert_int_equal(counts[0].extra, 1);
    assert_int_equal(counts[0].culled, 1);
    snprintf(path, sizeof path, "%s/known-map-broken.png", dir);
    assert_int_equal(access(path, F_OK), -1); /* external methods get no map */
    snprintf(path, sizeof path, "%s/known-map-vfc.png", dir);
    uint8_t *px;
    uint32_t w, h;
    assert_int_equal(sl_png_read_rgba(path, NULL, &px, &w, &h, &err), SL_OK);
    assert_int_equal(w, 300);
    /* orientation: north up, east right. The grey box (behind, x -11, y 5) lies left of and above
     * the orange one (hidden, x 21, y -4) */
    double gx = 0, gy = 0, gn = 0, ox = 0, oy = 0, on = 0;
    for (uint32_t y = 0; y < h; y++)
        for (uint32_t x = 0; x < w; x++) {
            const uint8_t *p = px + 4 * ((size_t)y * w + x);
            int r = p[0], g = p[1], bl = p[2];
            if (abs(r - g) < 6 && abs(g - bl) < 6 && r > 60 && r < 245)
                gx += x, gy += y, gn++;
            else if (r > 150 && g > 60 && bl < 60 && r > g + 40)
                ox += x, oy += y, on++;
        }
    assert_true(gn > 20 && on > 20);
    assert_true(gx / gn < ox / on);
    assert_true(gy / gn < oy / on);
    /* a thumbnail: the map averaged down, the same colours where they fill an area */
    mo.thumb_size = 301;
    snprintf(path, sizeof path, "%s/known-map-", dir);
    assert_int_equal(sl_bench_write_maps(b, &mo, path, counts, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "thumbnail size 301 is outside 16..300"));
    mo.thumb_size = 100;
    assert_int_equal(sl_bench_write_maps(b, &mo, path, counts, &err), SL_OK);
    snprintf(path, sizeof path, "%s/known-map-vfc-thumb.png", dir);
    uint8_t *tp;
    uint32_t tw, th;
    assert_int_equal(sl_png_read_rgba(path, NULL, &tp, &tw, &th, &err), SL_OK);
    assert_int_equal(tw, 100);
    assert_int_equal(th, (uint32_t)lround(h * 100.0 / w));
    /* each thumbnail pixel is the mean of the map pixels under it: 3 wide and h / th high, the
     * rows it covers in part weighted by the part */
    assert_true(h % th != 0); /* the partial rows are exercised */
    double sy = (double)h / th;
    for (uint32_t y = 0; y < th; y++)
        for (uint32_t x = 0; x < tw; x++)
            for (int c = 0; c < 3; c++) {
                double sum = 0, wsum = 0, lo = y * sy, hi = (y + 1) * sy;
                for (uint32_t yy = (uint32_t)lo; yy < h && yy < hi; yy++) {
                    double wy = fmin(yy + 1.0, hi) - fmax(yy, lo);
                    for (uint32_t dx = 0; dx < 3; dx++)
                        sum += wy * px[4 * ((size_t)yy * w + 3 * x + dx) + c], wsum += wy;
                }
                assert_true(fabs(tp[4 * ((size_t)y * tw + x) + c] - sum / wsum) <= 0.5 + 1e-6);
            }
    sl_free(NULL, tp, (size_t)tw * th * 4);
    mo.thumb_size = 0;
    snprintf(path, sizeof path, "%s/known-map-vfc-thumb.png", dir);
    unlink(path);
    snprintf(path, sizeof path, "%s/known-map-vfc.png", dir);
    sl_free(NULL, px, (size_t)w * h * 4);

    /* a map from a point sees in all directions: then everything but the hidden box is visible */
    mo.use_eye = true;
    mo.eye = (sl_vec3){0, 0, 0};
    mo.cube_size = 128;
    assert_int_equal(sl_bench_write_maps(b, &mo, path, counts, &err), SL_OK);
    assert_int_equal(counts[0].visible_kept + counts[0].missed, 4);
    assert_int_equal(counts[0].missed, 0);
    mo.size = 5;
    assert_int_equal(sl_bench_write_maps(b, &mo, path, counts, &err), SL_ERROR_INVALID_ARGUMENT);
    /* a write into a missing folder fails cleanly */
    snprintf(path, sizeof path, "%s/missing/frames.csv", dir);
    assert_int_equal(sl_bench_write_csv(&b, 1, path, &err), SL_ERROR_IO);
    remove_dir(dir);
    sl_bench_destroy(b);
    sl_scene_destroy(k.scene);
}

static void test_plot_svg(void **state)
{
    (void)state;
    char *dir = temp_dir();
    char path[256];
    sl_error err;
    /* a long series is thinned per pixel column and stays small; spikes survive */
    size_t n = 200000;
    double *y = malloc(n * sizeof *y);
    for (size_t i = 0; i < n; i++)
        y[i] = 1.0 + (double)(i % 97) * 0.01;
    y[123457] = 5000; /* one spike: the log scale turns on and the spike's value is drawn */
    y[5] = NAN;
    sl_plot_series se = {"a <method> & co", y, n, sl_plot_color(0), false, 0};
    sl_plot p;
    memset(&p, 0, sizeof p);
    p.title = "t";
    p.x_label = "frame";
    p.y_label = "ms";
    p.series = &se;
    p.series_count = 1;
    p.y_scale = SL_PLOT_AUTO;
    snprintf(path, sizeof path, "%s/long.svg", dir);
    assert_int_equal(sl_plot_write_svg(&p, path, NULL, &err), SL_OK);
    size_t len;
    char *text = read_text(path, &len);
    assert_true(len < 400000);
    assert_non_null(strstr(text, "(log scale)"));
    assert_non_null(strstr(text, "a &lt;method&gt; &amp; co"));
    free(text);
    /* no series at all: still a valid image saying so */
    p.series_count = 0;
    snprintf(path, sizeof path, "%s/empty.svg", dir);
    assert_int_equal(sl_plot_write_svg(&p, path, NULL, &err), SL_OK);
    text = read_text(path, NULL);
    assert_non_null(strstr(text, "no data"));
    free(text);
    /* a single point is drawn as a dot */
    double one = 3;
    sl_plot_series s1 = {"one", &one, 1, 0xff0000, false, 0};
    p.series = &s1;
    p.series_count = 1;
    snprintf(path, sizeof path, "%s/one.svg", dir);
    assert_int_equal(sl_plot_write_svg(&p, path, NULL, &err), SL_OK);
    text = read_text(path, NULL);
    assert_non_null(strstr(text, "<circle"));
    free(text);
    free(y);
    remove_dir(dir);
}

static bool cancel_after_two(void *user, const char *stage, uint64_t done, uint64_t total)
{
    (void)user, (void)stage, (void)total;
    return done < 2;
}

static void test_city_walk(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s;
    char label[64];
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    co.seed = 2;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    snprintf(label, sizeof label, "city-tiny-2");
    /* every registered method that runs with its default options, as the commands run them; the
     * others (a method that needs a baked file) are named with a reason */
    uint32_t total = sl_cull_method_count(), skipped_count = 0;
    sl_bench_method_spec *specs = calloc(total, sizeof *specs);
    sl_bench_skip *skipped = calloc(total, sizeof *skipped);
    uint32_t nm = sl_bench_registered_methods(specs, total, skipped, total, &skipped_count);
    assert_int_equal(nm + skipped_count, total);
    assert_true(nm >= 1);
    assert_string_equal(specs[0].name, "vfc");
    for (uint32_t i = 0; i < skipped_count; i++) {
        assert_non_null(strstr(skipped[i].reason, skipped[i].name));
        assert_int_not_equal(sl_cull_method_check_options(skipped[i].name, NULL, &err), SL_OK);
    }
    free(skipped);
    sl_bench_options opt = sl_bench_default_options();
    opt.width = 320;
    opt.height = 240;
    opt.label = label;
    sl_bench b;
    assert_int_equal(sl_bench_create(s, specs, nm, &opt, NULL, &b, &err), SL_OK);
    sl_path_options po = sl_path_options_default(SL_PATH_WALK);
    po.frames = getenv("SL_SANITIZED") ? 8 : 40;
    po.fps = 2;
    sl_path walk;
    assert_int_equal(sl_path_generate(s, &po, NULL, &walk, &err), SL_OK);
    assert_int_equal(sl_bench_run_path(b, walk, 0, UINT32_MAX, &err), SL_OK);
    assert_int_equal(sl_bench_frame_count(b), po.frames);
    sl_bench_frame fr;
    assert_int_equal(sl_bench_get_frame(b, 1, &fr, &err), SL_OK);
    assert_true(fr.time == sl_path_poses(walk)[1].time);
    assert_int_equal(sl_bench_violations(b), 0);
    for (uint32_t m = 0; m < nm; m++) {
        sl_bench_summary sum;
        assert_int_equal(sl_bench_summarize(b, m, &sum, &err), SL_OK);
        assert_int_equal(sum.frames, po.frames);
        assert_true(sum.visible_mean > 0);
        assert_true(sum.objects_drawn_mean > 0);
        /* the over-estimation is the ratio of the sums */
        assert_true(fabs(sum.overestimation - sum.objects_drawn_mean / sum.visible_mean) < 1e-9 * sum.overestimation);
    }
    /* the recommendation: the fastest eligible method within the tightness bound and the tightest
     * within the time bound, checked against every summary */
    for (int pass = 0; pass < 2; pass++) {
        sl_bench_recommendation rec;
        assert_int_equal(sl_bench_recommend(b, &rec, &err), SL_OK);
        assert_true(rec.max_overestimation == 2 && rec.max_ms == 2);
        assert_true(rec.fastest >= 0 && rec.tightest >= 0);
        sl_bench_summary fs, ts;
        assert_int_equal(sl_bench_summarize(b, (uint32_t)rec.fastest, &fs, &err), SL_OK);
        assert_int_equal(sl_bench_summarize(b, (uint32_t)rec.tightest, &ts, &err), SL_OK);
        assert_true(fs.overestimation <= 2 && ts.cull_ms.median <= 2);
        for (uint32_t m = 0; m < nm; m++) {
            sl_bench_summary sum;
            sl_bench_method_info mi;
            assert_int_equal(sl_bench_summarize(b, m, &sum, &err), SL_OK);
            assert_int_equal(sl_bench_method(b, m, &mi, &err), SL_OK);
            if (!sl_cull_guarantee_keeps_visible(mi.guarantee, true) || sum.missed_objects_total)
                continue;
            if (sum.overestimation <= 2)
                assert_true(sum.cull_ms.median >= fs.cull_ms.median);
            if (sum.cull_ms.median <= 2)
                assert_true(sum.overestimation >= ts.overestimation);
        }
        sl_bench_method_info fi;
        assert_int_equal(sl_bench_method(b, (uint32_t)rec.fastest, &fi, &err), SL_OK);
        assert_non_null(strstr(rec.text, fi.name));
    }
    /* the first frame range and the end are honoured; progress may cancel */
    sl_bench b2;
    opt.progress = (sl_progress){cancel_after_two, NULL};
    assert_int_equal(sl_bench_create(s, specs, 1, &opt, NULL, &b2, &err), SL_OK);
    assert_int_equal(sl_bench_run_path(b2, walk, po.frames - 1, 10, &err), SL_OK);
    assert_int_equal(sl_bench_frame_count(b2), 1);
    assert_int_equal(sl_bench_run_path(b2, walk, 0, 5, &err), SL_ERROR_CANCELLED);
    assert_int_equal(sl_bench_frame_count(b2), 3);
    assert_int_equal(sl_bench_run_path(b2, walk, po.frames + 1, 1, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_bench_destroy(b2);
    sl_path_destroy(walk);
    sl_bench_destroy(b);
    free(specs);
    sl_scene_destroy(s);
}

/* Frames from views (issue 13 §1): a camera's view gives the camera's frame, record for record; an
 * engine's off-axis reversed-z infinite-far view is judged like any other (no misses), its frame
 * showing the eye and orientation; the options' viewport replaces the view's. */
static void test_run_view(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    uint32_t total = sl_cull_method_count();
    sl_bench_method_spec *specs = calloc(total, sizeof *specs);
    uint32_t nm = sl_bench_registered_methods(specs, total, NULL, 0, NULL);
    sl_bench_options opt = sl_bench_default_options();
    sl_bench a, b;
    assert_int_equal(sl_bench_create(s, specs, nm, &opt, NULL, &a, &err), SL_OK);
    assert_int_equal(sl_bench_create(s, specs, nm, &opt, NULL, &b, &err), SL_OK);
    sl_path_options po = sl_path_options_default(SL_PATH_WALK);
    po.intrinsics.width = 160;
    po.intrinsics.height = 120;
    sl_path p;
    uint32_t nv = getenv("SL_SANITIZED") ? 2 : 8;
    assert_int_equal(sl_path_random_views(s, SL_VIEWS_STREET, nv, 3, &po, NULL, &p, &err), SL_OK);
    for (uint32_t f = 0; f < nv; f++) {
        sl_camera cam = sl_path_camera(p, f);
        sl_view v;
        assert_int_equal(sl_view_from_camera(&cam, &v, &err), SL_OK);
        assert_int_equal(sl_bench_run_frame(a, &cam, &err), SL_OK);
        assert_int_equal(sl_bench_run_view(b, &v, &err), SL_OK);
        for (uint32_t m = 0; m < nm; m++) {
            /* chc and chc++ start from the last frame's classification, and b culls other views in
             * between: their sets depend on that history (never a miss: the violations below) */
            if (!strcmp(specs[m].name, "chc") || !strcmp(specs[m].name, "chc++"))
                continue;
            sl_bench_record ra, rb;
            assert_int_equal(sl_bench_get_record(a, f, m, &ra, &err), SL_OK);
            assert_int_equal(sl_bench_get_record(b, 2 * f, m, &rb, &err), SL_OK); /* b: camera, engine, ... */
            assert_memory_equal(&ra.metrics, &rb.metrics, sizeof ra.metrics);
        }
        /* the engine's version of the camera, shifted off-axis, reversed-z, infinite far */
        float V[16], P[16];
        sl_tvm_shape sh = {1, 0.3, 1, -0.2};
        sl_tvm_matrices(&cam, SL_CLIP_DEPTH_REVERSED, SL_TVM_INF | SL_TVM_LH_Z | SL_TVM_FLIP_Y, &sh, V, P);
        assert_int_equal(sl_view_from_matrices(V, P, SL_CLIP_DEPTH_REVERSED, cam.width, cam.height, &v, &err), SL_OK);
        assert_int_equal(sl_bench_run_view(b, &v, &err), SL_OK);
        sl_bench_frame fr;
        assert_int_equal(sl_bench_get_frame(b, sl_bench_frame_count(b) - 1, &fr, &err), SL_OK);
        assert_true(fabsf(fr.camera.position.x - cam.position.x) < 1e-3f && fabsf(fr.camera.yaw - cam.yaw) < 1e-4f);
        assert_true(fr.visible_count > 0);
    }
    assert_int_equal(sl_bench_violations(b), 0);
    /* the reports: the camera frames' columns as before, the view of matrices exactly */
    char *dir = temp_dir();
    char path[256];
    sl_bench both[2] = {a, b};
    snprintf(path, sizeof path, "%s/frames.csv", dir);
    assert_int_equal(sl_bench_write_csv(&a, 1, path, &err), SL_OK);
    char *cams = read_text(path, NULL);
    assert_non_null(strstr(cams, ",missed,skipped,query_stalls,query_wait_ms\n"));
    assert_null(strstr(cams, "mirrored"));
    assert_int_equal(sl_bench_write_csv(both, 2, path, &err), SL_OK);
    char *mixed = read_text(path, NULL);
    assert_non_null(strstr(mixed, ",missed,skipped,query_stalls,query_wait_ms,view,clip_depth,projection,near,far,rect_left,rect_right,rect_bottom,"
                                  "rect_top,forward_x,forward_y,forward_z,up_x,up_y,up_z,width,height,mirrored\n"));
    assert_non_null(strstr(mixed, ",camera,gl,perspective,"));
    assert_non_null(strstr(mixed, ",matrices,reversed,perspective,"));
    assert_non_null(strstr(mixed, ",inf,"));  /* the infinite far plane as given */
    assert_non_null(strstr(mixed, ",160,120,y\n")); /* the y-flipped projection */
    /* the first file's rows, view columns left out, are rows of the mixed file */
    for (char *line = strchr(cams, '\n') + 1, *end; *line; line = end + 1) {
        end = strchr(line, '\n');
        *end = 0;
        assert_non_null(strstr(mixed, line));
    }
    free(cams);
    free(mixed);
    snprintf(path, sizeof path, "%s/frames.json", dir);
    assert_int_equal(sl_bench_write_json(&b, 1, path, &err), SL_OK);
    char *text = read_text(path, NULL);
    assert_non_null(strstr(text, "\"view\":{\"source\":\"matrices\",\"clip_depth\":\"reversed\",\"projection\":\"perspective\","));
    assert_non_null(strstr(text, "\"far\":null,\"rect\":{\"left\":"));
    assert_non_null(strstr(text, "\"mirrored_x\":false,\"mirrored_y\":true,\"left_handed\":true}"));
    size_t views = 0;
    for (const char *q = text; (q = strstr(q, "\"view\":{")); q++)
        views++;
    assert_int_equal(views, (size_t)nv * nm); /* the frames of matrices only, one row per method */
    free(text);
    snprintf(path, sizeof path, "%s/summary.md", dir);
    assert_int_equal(sl_bench_write_summary(&b, 1, path, &err), SL_OK);
    text = read_text(path, NULL);
    assert_non_null(strstr(text, "from an engine's matrices (frame 1: reversed depth, perspective, near "));
    assert_non_null(strstr(text, "far infinite, near rectangle x ["));
    free(text);
    remove_dir(dir);
    sl_bench_destroy(a);
    sl_bench_destroy(b);
    /* the options' viewport */
    opt.width = 64;
    opt.height = 32;
    assert_int_equal(sl_bench_create(s, specs, 1, &opt, NULL, &a, &err), SL_OK);
    sl_camera cam = sl_path_camera(p, 0);
    float V[16], P[16];
    sl_tvm_matrices(&cam, SL_CLIP_DEPTH_GL, 0, NULL, V, P);
    sl_view v;
    assert_int_equal(sl_view_from_matrices(V, P, SL_CLIP_DEPTH_GL, cam.width, cam.height, &v, &err), SL_OK);
    assert_int_equal(sl_bench_run_view(a, &v, &err), SL_OK);
    sl_bench_frame fr;
    assert_int_equal(sl_bench_get_frame(a, 0, &fr, &err), SL_OK);
    assert_int_equal(fr.camera.width, 64);
    assert_int_equal(fr.camera.height, 32);
    /* the frame's view: the one culled, at the options' viewport, the same matrices */
    assert_int_equal(fr.view.source, SL_VIEW_FROM_MATRICES);
    assert_true(fr.view.width == 64 && fr.view.height == 32);
    assert_memory_equal(&fr.view.view_proj, &v.view_proj, sizeof v.view_proj);
    assert_true(fr.view.rect_left == v.rect_left && fr.view.rect_top == v.rect_top);
    sl_view hand;
    memset(&hand, 0, sizeof hand);
    assert_int_equal(sl_bench_run_view(a, &hand, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_bench_run_view(a, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_bench_destroy(a);
    sl_path_destroy(p);
    free(specs);
    sl_scene_destroy(s);
}

static void test_errors(void **state)
{
    (void)state;
    known k = make_known();
    sl_test_counter counter = {0, 0, 0};
    sl_allocator alloc = sl_test_counting_allocator(&counter);
    sl_error err;
    sl_bench b = (sl_bench)0x1;
    sl_bench_method_spec nosuch[] = {{"vfc", NULL}, {"nosuch", NULL}};
    assert_int_equal(sl_bench_create(k.scene, nosuch, 2, NULL, &alloc, &b, &err), SL_ERROR_NOT_FOUND);
    assert_null(b);
    assert_non_null(strstr(err.message, "nosuch"));
    assert_int_equal(counter.live, 0);
    sl_bench_method_spec bad[] = {{"vfc", "leaf_size=999"}};
    assert_int_equal(sl_bench_create(k.scene, bad, 1, NULL, &alloc, &b, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "leaf_size"));
    assert_int_equal(counter.live, 0);
    sl_bench_method_spec twice[] = {{"vfc", NULL}, {"vfc", NULL}};
    assert_int_equal(sl_bench_create(k.scene, twice, 2, NULL, &alloc, &b, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "twice"));
    sl_bench_options opt = sl_bench_default_options();
    opt.repeat = 0;
    assert_int_equal(sl_bench_create(k.scene, NULL, 0, &opt, &alloc, &b, &err), SL_ERROR_INVALID_ARGUMENT);
    opt = sl_bench_default_options();
    opt.threads = 0;
    assert_int_equal(sl_bench_create(k.scene, NULL, 0, &opt, &alloc, &b, &err), SL_ERROR_INVALID_ARGUMENT);
    opt = sl_bench_default_options();
    opt.width = 10;
    assert_int_equal(sl_bench_create(k.scene, NULL, 0, &opt, &alloc, &b, &err), SL_ERROR_INVALID_ARGUMENT);

    /* a bench with external methods only; submissions need a frame */
    assert_int_equal(sl_bench_create(k.scene, NULL, 0, NULL, &alloc, &b, &err), SL_OK);
    uint32_t m;
    assert_int_equal(sl_bench_add_external(b, "x", SL_CONSERVATIVE, &m, &err), SL_OK);
    assert_int_equal(sl_bench_add_external(b, "x", SL_CONSERVATIVE, &m, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_bench_submit(b, m, NULL, 0, 0, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "no current frame"));
    sl_camera c = camera_at(0);
    c.fov_y = NAN;
    assert_int_equal(sl_bench_run_frame(b, &c, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_bench_last_truth(b, &(sl_oracle_frame){0}, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_bench_record r;
    assert_int_equal(sl_bench_get_record(b, 5, 0, &r, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_bench_summary s;
    assert_int_equal(sl_bench_summarize(b, 3, &s, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_bench_summarize(b, m, &s, &err), SL_OK); /* no frames: zeros */
    assert_int_equal(s.frames, 0);
    sl_bench_destroy(b);
    assert_int_equal(counter.live, 0);
    sl_bench_destroy(NULL);

    /* scene specs (city:PRESET[:SEED], files) are the command's: tests/cli/bench.sh */
    sl_scene_destroy(k.scene);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_known_scene_records),
        cmocka_unit_test(test_reports),
        cmocka_unit_test(test_query_stalls_reported),
        cmocka_unit_test(test_plot_svg),
        cmocka_unit_test(test_city_walk),
        cmocka_unit_test(test_run_view), cmocka_unit_test(test_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
