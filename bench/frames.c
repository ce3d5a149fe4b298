/* bench_frames: what culling saves in frame time, on the OpenGL renderer (issue 15 §4).
 *
 *   bench_frames [--preset tiny|small|vienna] [--frames N] [--every K] [--fps F] [--seed S]
 *                [--size WxH] [--methods LIST] [--pvs FILE] [--context auto|surfaceless|device]
 *                [--no-oracle] [--warmup N] [--csv FILE] [--instant-levels E1,E2,...]
 *
 * The bench's walk of a generated city (sl_path_generate, SL_PATH_WALK, fps F (30), seed S (1)),
 * N frames (default 1000) of which every K-th is rendered (default 1), at WxH (1280x720) on one
 * renderer (render.h; headless EGL: llvmpipe without a GPU, the EGL device platform on one). For
 * each frame every configuration renders in turn, the starting one rotated frame by frame so that
 * none always runs first: a configuration is a culler (`sightline bench`'s method grammar,
 * name[:key=value...]; query cullers drive the renderer's GL backend; gpu-hiz is the render layer's
 * own), `none` (every object drawn, no culling) or `oracle-set` (exactly the oracle's visible set of
 * the frame, computed beforehand at the same resolution, drawn with no culling cost: the limit a
 * culler can reach). Each culler keeps its own state across the walk (temporal coherence).
 *
 * Frame time: wall time from the start of culling to glFinish (sl_renderer_frame), measured here
 * around the call; its phases (cull, draw, wait on queries) from sl_render_frame_stats. Printed per
 * configuration: mean, median, p95 and max frame ms, mean cull/draw/wait ms, queries, objects and
 * triangles drawn per frame, the ratio of vfc's mean frame time to its own (speed-up), the ratio of
 * its mean to oracle-set's, and misses: objects the oracle sees in a frame that the configuration
 * did not draw (a conservative culler must have none; a configuration declared aggressive reports
 * them). --csv writes one row per frame and configuration. --instant-levels bakes the city's shrunk
 * occluder levels (sl_shrink_occluder_levels, eps_z 0.5 m) for the `instant` culler, which then also
 * reports its updates: visibility ms and set size per update, stalls, frames at risk. */
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "sightline/region.h"
#include "sightline/render.h"
#include "sightline/truth.h"
#include "sightline/view.h"

#include "bench_common.h"

#include <time.h>

#define PROG "bench_frames"
#define MAX_CONFIGS 24

typedef enum cfg_kind { CFG_CULLER, CFG_NONE, CFG_ORACLE } cfg_kind;

typedef struct config {
    char spec[256], name[64], opts[320];
    cfg_kind kind;
    sl_culler culler;
    sl_cull_guarantee guarantee;
    bool conservative;
    bool gl_driven; /* draws through the renderer (query cullers, gpu-hiz): judged by GL's own image */
    double *frame_ms;
    double sum_frame, sum_cull, sum_draw, sum_wait, sum_queries, sum_objects, sum_triangles;
    uint64_t misses, miss_frames;
    uint64_t gl_misses, gl_miss_frames; /* of those, objects GL's own unculled image shows */
    uint32_t frames;
} config;

static double now_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}

static bool is_render_method(const char *name)
{
    for (uint32_t i = 0; i < sl_render_method_count(); i++)
        if (!strcmp(sl_render_method(i)->name, name))
            return true;
    return false;
}

static const char *const g_defaults[] = {"none",        "vfc", "hzb", "cullmap", "dhorizon", "gl-stopwait",
                                         "chc",         "chc++", "gpu-hiz", "oracle-set"};

static void parse_config(const char *spec, config *c)
{
    memset(c, 0, sizeof *c);
    snprintf(c->spec, sizeof c->spec, "%s", spec);
    if (!strcmp(spec, "none") || !strcmp(spec, "oracle-set")) {
        c->kind = !strcmp(spec, "none") ? CFG_NONE : CFG_ORACLE;
        snprintf(c->name, sizeof c->name, "%s", spec);
        return;
    }
    const char *colon = strchr(spec, ':');
    size_t nl = colon ? (size_t)(colon - spec) : strlen(spec);
    snprintf(c->name, sizeof c->name, "%.*s", (int)nl, spec);
    snprintf(c->opts, sizeof c->opts, "%s", colon ? colon + 1 : "");
    for (char *p = c->opts; *p; p++)
        if (*p == ':')
            *p = ',';
    c->kind = CFG_CULLER;
    sl_error err;
    if (!is_render_method(c->name) && sl_cull_method_check_options(c->name, c->opts, &err) != SL_OK)
        bench_die(PROG, spec, &err);
}

/* objects of want[0..nw) (ascending) missing from have[0..nh) (ascending); of them, those marked in
 * `shown` (may be NULL) into *shown_missing */
static uint32_t count_missing(const uint32_t *want, uint32_t nw, const uint32_t *have, uint32_t nh,
                              const uint8_t *shown, uint32_t *shown_missing)
{
    uint32_t miss = 0, j = 0;
    *shown_missing = 0;
    for (uint32_t i = 0; i < nw; i++) {
        while (j < nh && have[j] < want[i])
            j++;
        if (j == nh || have[j] != want[i]) {
            miss++;
            *shown_missing += shown && shown[want[i]];
        }
    }
    return miss;
}

static void usage(void)
{
    fprintf(stderr, "usage: " PROG " [--preset tiny|small|vienna] [--frames N] [--every K] [--fps F] [--seed S]\n"
                    "       [--size WxH] [--methods LIST] [--pvs FILE] [--context auto|surfaceless|device]\n"
                    "       [--no-oracle] [--warmup N] [--csv FILE] [--instant-levels E1,E2,...]\n"
                    "LIST: comma-separated name[:key=value...] (the cull methods, gpu-hiz, none, oracle-set);\n"
                    "default: none,vfc,hzb,cullmap,dhorizon,[pvs with --pvs],gl-stopwait,chc,chc++,gpu-hiz,oracle-set\n");
    exit(2);
}

int main(int argc, char **argv)
{
    const char *preset = "vienna", *list = NULL, *pvs = NULL, *csv_path = NULL, *context = "auto", *levels = NULL;
    uint32_t frames = 1000, every = 1, width = 1280, height = 720, warmup = 3;
    uint64_t seed = 1;
    float fps = 30;
    bool oracle_on = true;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        bool more = i + 1 < argc;
        if (!strcmp(a, "--preset") && more)
            preset = argv[++i];
        else if (!strcmp(a, "--frames") && more)
            frames = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(a, "--every") && more)
            every = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(a, "--fps") && more)
            fps = strtof(argv[++i], NULL);
        else if (!strcmp(a, "--seed") && more)
            seed = strtoull(argv[++i], NULL, 10);
        else if (!strcmp(a, "--size") && more) {
            if (sscanf(argv[++i], "%ux%u", &width, &height) != 2)
                usage();
        } else if (!strcmp(a, "--methods") && more)
            list = argv[++i];
        else if (!strcmp(a, "--pvs") && more)
            pvs = argv[++i];
        else if (!strcmp(a, "--context") && more)
            context = argv[++i];
        else if (!strcmp(a, "--no-oracle"))
            oracle_on = false;
        else if (!strcmp(a, "--warmup") && more)
            warmup = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (!strcmp(a, "--csv") && more)
            csv_path = argv[++i];
        else if (!strcmp(a, "--instant-levels") && more)
            levels = argv[++i];
        else
            usage();
    }
    if (!frames || !every || !width || !height || width > 16384 || height > 16384 || !(fps > 0))
        usage();
    sl_gl_context_kind ck;
    if (!strcmp(context, "auto"))
        ck = SL_GL_CONTEXT_AUTO;
    else if (!strcmp(context, "surfaceless"))
        ck = SL_GL_CONTEXT_SURFACELESS;
    else if (!strcmp(context, "device"))
        ck = SL_GL_CONTEXT_DEVICE;
    else
        usage();

    /* configurations */
    static config cfg[MAX_CONFIGS];
    uint32_t nc = 0;
    if (list) {
        char buf[2048];
        snprintf(buf, sizeof buf, "%s", list);
        for (char *t = strtok(buf, ","); t; t = strtok(NULL, ",")) {
            if (nc == MAX_CONFIGS) {
                fprintf(stderr, PROG ": at most %d configurations\n", MAX_CONFIGS);
                return 2;
            }
            parse_config(t, &cfg[nc++]);
        }
    } else {
        for (size_t i = 0; i < sizeof g_defaults / sizeof g_defaults[0]; i++) {
            if (!strcmp(g_defaults[i], "gl-stopwait") && pvs) {
                char spec[300];
                snprintf(spec, sizeof spec, "pvs:file=%s", pvs);
                parse_config(spec, &cfg[nc++]);
            }
            parse_config(g_defaults[i], &cfg[nc++]);
        }
    }
    for (uint32_t i = 0; i < nc; i++)
        if (cfg[i].kind == CFG_ORACLE && !oracle_on) {
            fprintf(stderr, PROG ": oracle-set needs the oracle (drop --no-oracle)\n");
            return 2;
        }

    sl_error err;
    sl_city_preset p;
    if (sl_city_preset_from_name(preset, &p, &err) != SL_OK)
        bench_die(PROG, preset, &err);
    sl_city_options co = sl_city_defaults(p);
    sl_scene scene;
    double t_gen = now_ms();
    if (sl_gen_city(&co, NULL, &scene, &err) != SL_OK)
        bench_die(PROG, "gen city", &err);
    t_gen = now_ms() - t_gen;
    double t_levels = 0;
    if (levels) {
        float eps[SL_OCCLUDER_LEVELS_MAX];
        uint32_t ne = 1;
        for (const char *q = levels; *q; q++)
            ne += *q == ',';
        if (ne > SL_OCCLUDER_LEVELS_MAX || !sl_parse_floats(levels, eps, (int)ne))
            usage();
        t_levels = now_ms();
        if (sl_shrink_occluder_levels(scene, eps, ne, 0.5f, false, NULL, NULL, &err) != SL_OK)
            bench_die(PROG, "occluder levels", &err);
        t_levels = now_ms() - t_levels;
    }
    sl_path_options po = sl_path_options_default(SL_PATH_WALK);
    po.frames = frames;
    po.fps = fps;
    po.seed = seed;
    po.intrinsics.width = width;
    po.intrinsics.height = height;
    sl_path path;
    if (sl_path_generate(scene, &po, NULL, &path, &err) != SL_OK)
        bench_die(PROG, "walk", &err);

    sl_renderer_options ro;
    sl_renderer_options_default(&ro);
    ro.width = width;
    ro.height = height;
    ro.context = ck;
    ro.debug = false; /* synchronous debug output slows the driver; errors are still checked */
    sl_renderer r;
    double t_up = now_ms();
    if (sl_renderer_create(scene, &ro, NULL, &r, &err) != SL_OK)
        bench_die(PROG, "renderer", &err);
    t_up = now_ms() - t_up;
    sl_renderer_info info;
    sl_renderer_get_info(r, &info);

    uint32_t n_obj = sl_scene_object_count(scene), n_frames = (frames + every - 1) / every;
    for (uint32_t i = 0; i < nc; i++) {
        cfg[i].frame_ms = calloc(n_frames, sizeof(double));
        if (!cfg[i].frame_ms) {
            fprintf(stderr, PROG ": out of memory\n");
            return 2;
        }
        if (cfg[i].kind != CFG_CULLER) {
            cfg[i].guarantee = cfg[i].kind == CFG_NONE ? SL_CONSERVATIVE : SL_CONSERVATIVE_AT_RESOLUTION;
            cfg[i].conservative = true;
            continue;
        }
        if (sl_renderer_create_culler(r, cfg[i].name, cfg[i].opts, &cfg[i].culler, &err) != SL_OK)
            bench_die(PROG, cfg[i].spec, &err);
        cfg[i].guarantee = sl_culler_guarantee(cfg[i].culler);
        cfg[i].gl_driven = sl_cull_method_draws(cfg[i].name) || is_render_method(cfg[i].name);
        cfg[i].conservative = cfg[i].guarantee != SL_AGGRESSIVE;
    }

    sl_oracle oracle = NULL;
    if (oracle_on) {
        sl_oracle_options oo = sl_oracle_default_options();
        oo.width = width;
        oo.height = height;
        if (sl_oracle_create(scene, &oo, NULL, &oracle, &err) != SL_OK)
            bench_die(PROG, "oracle", &err);
    }
    uint32_t *ids = malloc((n_obj ? n_obj : 1) * sizeof *ids), *truth = malloc((n_obj ? n_obj : 1) * sizeof *truth);
    /* GL's own unculled image, made (untimed) for a frame where some culler misses an object the
     * oracle sees: the objects it shows, to tell a culling error from a rasterisation difference */
    uint32_t *all = malloc((n_obj ? n_obj : 1) * sizeof *all), *gl_ids = malloc((size_t)width * height * sizeof *gl_ids);
    uint8_t *gl_shown = calloc(n_obj ? n_obj : 1, 1);
    for (uint32_t i = 0; all && i < n_obj; i++)
        all[i] = i;
    if (!ids || !truth || !all || !gl_ids || !gl_shown) {
        fprintf(stderr, PROG ": out of memory\n");
        return 2;
    }
    FILE *csv = NULL;
    if (csv_path) {
        csv = fopen(csv_path, "w");
        if (!csv) {
            perror(csv_path);
            return 2;
        }
        fprintf(csv, "frame,config,frame_ms,cull_ms,draw_ms,wait_ms,finish_ms,gpu_draw_ms,gpu_query_ms,objects_drawn,"
                     "triangles_drawn,queries,query_stalls,oracle_visible,misses,gl_shown_misses\n");
    }

    char machine[400];
    bench_machine(machine, sizeof machine);
    bool tty = isatty(2);
    double t_start = now_ms(), t_oracle = 0;
    /* warm-up: the first frames once per configuration, not recorded (shader compiles, first uploads) */
    for (uint32_t w = 0; w < warmup && w < frames; w++) {
        sl_camera cam = sl_path_camera(path, w * every < frames ? w * every : 0);
        sl_view v;
        if (sl_view_from_camera(&cam, &v, &err) != SL_OK)
            bench_die(PROG, "view", &err);
        for (uint32_t i = 0; i < nc; i++)
            if (cfg[i].kind != CFG_ORACLE &&
                sl_renderer_frame(r, cfg[i].culler, &v, SL_RENDER_SHADED, ids, NULL, NULL, &err) != SL_OK)
                bench_die(PROG, cfg[i].spec, &err);
    }
    /* the culler state after warm-up frames is that of an earlier part of the walk: reset by
     * starting the recorded walk at its first frame; coherence recovers within a frame or two */
    for (uint32_t k = 0; k < n_frames; k++) {
        uint32_t f = k * every;
        sl_camera cam = sl_path_camera(path, f);
        sl_view v;
        if (sl_view_from_camera(&cam, &v, &err) != SL_OK)
            bench_die(PROG, "view", &err);
        uint32_t nt = 0;
        bool judge = false, have_gl = false;
        if (oracle) {
            double t0 = now_ms();
            sl_oracle_frame of;
            if (sl_oracle_render_view(oracle, &v, &of, &err) != SL_OK)
                bench_die(PROG, "oracle render", &err);
            t_oracle += now_ms() - t0;
            nt = of.visible_count;
            memcpy(truth, of.visible, nt * sizeof *truth);
            judge = !of.out_of_domain;
        }
        for (uint32_t j = 0; j < nc; j++) {
            config *c = &cfg[(j + k) % nc];
            sl_render_frame_stats st;
            memset(&st, 0, sizeof st);
            uint32_t count = 0;
            double t0 = now_ms();
            sl_status s;
            if (c->kind == CFG_ORACLE) {
                s = sl_renderer_draw(r, &v, truth, nt, SL_RENDER_SHADED, &st, &err);
                memcpy(ids, truth, nt * sizeof *ids);
                count = nt;
            } else
                s = sl_renderer_frame(r, c->culler, &v, SL_RENDER_SHADED, ids, &count, &st, &err);
            double ms = now_ms() - t0;
            if (s != SL_OK)
                bench_die(PROG, c->spec, &err);
            uint32_t gl_miss = 0, miss = judge ? count_missing(truth, nt, ids, count, NULL, &gl_miss) : 0;
            if (miss) {
                /* the ids of this configuration's frame are kept; GL's unculled image is made once */
                if (!have_gl) {
                    double t1 = now_ms();
                    if (sl_renderer_draw(r, &v, all, n_obj, SL_RENDER_IDS, NULL, &err) != SL_OK ||
                        sl_renderer_read_ids(r, gl_ids, &err) != SL_OK)
                        bench_die(PROG, "unculled id image", &err);
                    memset(gl_shown, 0, n_obj);
                    for (size_t px = 0; px < (size_t)width * height; px++)
                        if (gl_ids[px] < n_obj)
                            gl_shown[gl_ids[px]] = 1;
                    have_gl = true;
                    t_oracle += now_ms() - t1;
                }
                count_missing(truth, nt, ids, count, gl_shown, &gl_miss);
            }
            c->gl_misses += gl_miss;
            c->gl_miss_frames += gl_miss > 0;
            c->frame_ms[c->frames++] = ms;
            c->sum_frame += ms;
            c->sum_cull += st.cull_ms;
            c->sum_draw += st.draw_ms;
            c->sum_wait += st.wait_ms;
            c->sum_queries += (double)st.queries;
            c->sum_objects += st.objects_drawn;
            c->sum_triangles += (double)st.triangles_drawn;
            c->misses += miss;
            c->miss_frames += miss > 0;
            if (csv)
                fprintf(csv, "%u,%s,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%u,%llu,%llu,%llu,%u,%u,%u\n", f, c->spec, ms,
                        st.cull_ms, st.draw_ms, st.wait_ms, st.finish_ms, st.gpu_draw_ms, st.gpu_query_ms,
                        st.objects_drawn, (unsigned long long)st.triangles_drawn, (unsigned long long)st.queries,
                        (unsigned long long)st.query_stalls, nt, miss, gl_miss);
        }
        if (tty) {
            double el = (now_ms() - t_start) / 1e3;
            fprintf(stderr, "\r" PROG ": frame %u/%u, %.0f s elapsed, ETA %.0f s   ", k + 1, n_frames, el,
                    el / (k + 1) * (n_frames - k - 1));
        }
    }
    if (tty)
        fprintf(stderr, "\n");
    if (csv && fclose(csv) != 0) {
        perror(csv_path);
        return 2;
    }

    /* the table */
    double vfc_mean = 0, oracle_mean = 0;
    for (uint32_t i = 0; i < nc; i++) {
        if (!strcmp(cfg[i].spec, "vfc"))
            vfc_mean = cfg[i].sum_frame / cfg[i].frames;
        if (cfg[i].kind == CFG_ORACLE)
            oracle_mean = cfg[i].sum_frame / cfg[i].frames;
    }
    printf("# " PROG ": %s city (%u objects), walk of %u frames at %g fps (seed %llu), every %u -> %u frames, "
           "%ux%u\n",
           preset, n_obj, frames, fps, (unsigned long long)seed, every, n_frames, width, height);
    printf("# GL: %s | %s | %s (%s context%s)\n", info.vendor, info.renderer, info.version,
           info.context == SL_GL_CONTEXT_DEVICE ? "EGL device" : info.context == SL_GL_CONTEXT_SURFACELESS
                                                                    ? "EGL surfaceless"
                                                                    : "current",
           info.reversed_z ? ", reversed-z float depth" : "");
    printf("# machine: %s\n", machine);
    printf("# set-up: city %.0f ms, upload %.0f ms; oracle %.0f ms (untimed); configurations rotate per frame\n",
           t_gen, t_up, t_oracle);
    if (levels)
        printf("# instant occluder levels %s baked in %.0f ms (GEOS, untimed)\n", levels, t_levels);
    printf("%-24s %-10s %9s %9s %9s %9s %8s %8s %8s %8s %9s %11s %8s %8s %9s %9s\n", "config", "guarantee",
           "mean_ms", "median", "p95", "max", "cull", "draw", "wait", "queries", "objects", "triangles", "vs_vfc",
           "vs_orac", "misses", "gl_shown");
    for (uint32_t i = 0; i < nc; i++) {
        config *c = &cfg[i];
        double mean = c->sum_frame / c->frames, fr = c->frames;
        double med = bench_median(c->frame_ms, c->frames), p95 = bench_percentile(c->frame_ms, c->frames, 0.95),
               mx = bench_percentile(c->frame_ms, c->frames, 1.0);
        const char *g = c->kind == CFG_NONE     ? "-"
                        : c->kind == CFG_ORACLE ? "limit"
                        : c->guarantee == SL_CONSERVATIVE ? "cons"
                        : c->guarantee == SL_CONSERVATIVE_AT_RESOLUTION ? "cons@res"
                                                                        : "aggr";
        char miss[48], glm[48];
        if (!oracle) {
            snprintf(miss, sizeof miss, "-");
            snprintf(glm, sizeof glm, "-");
        } else {
            bool cpu_bad = c->conservative && !c->gl_driven && c->misses, gl_bad = c->conservative && c->gl_misses;
            snprintf(miss, sizeof miss, "%llu/%llu%s", (unsigned long long)c->misses, (unsigned long long)c->miss_frames,
                     cpu_bad ? "!" : "");
            snprintf(glm, sizeof glm, "%llu/%llu%s", (unsigned long long)c->gl_misses,
                     (unsigned long long)c->gl_miss_frames, gl_bad ? "!" : "");
        }
        printf("%-24s %-10s %9.2f %9.2f %9.2f %9.2f %8.2f %8.2f %8.2f %8.1f %9.1f %11.0f %8.2f %8.2f %9s %9s\n",
               c->spec, g, mean, med, p95, mx, c->sum_cull / fr, c->sum_draw / fr, c->sum_wait / fr,
               c->sum_queries / fr, c->sum_objects / fr, c->sum_triangles / fr, vfc_mean > 0 ? vfc_mean / mean : 0,
               oracle_mean > 0 ? mean / oracle_mean : 0, miss, glm);
    }
    printf("# vs_vfc: vfc's mean frame time / this one's (speed-up); vs_orac: this mean / oracle-set's (1 = the "
           "limit); misses: objects/frames the CPU oracle saw at this resolution and the configuration did not draw; "
           "gl_shown: of those, the ones GL's own unculled image shows. '!': a conservative CPU culler missed an object "
           "the oracle sees, or a culler drawing through the renderer (query cullers, gpu-hiz: their guarantee is "
           "for the renderer's image) dropped one GL would draw; a miss GL does not show is a difference between "
           "the oracle's rasteriser and GL's (8 subpixel bits on llvmpipe, float depth ties), not a culling error\n");
    for (uint32_t i = 0; i < nc; i++) {
        sl_instant_stats is;
        if (cfg[i].kind != CFG_CULLER || sl_instant_get_stats(cfg[i].culler, &is, NULL) != SL_OK)
            continue;
        double u = is.adopted ? (double)is.adopted : 1;
        printf("# %s: %llu updates adopted over %llu frames: visibility %.2f ms per update (wall, in its thread), "
               "%.1f objects per update (%.1f KiB as 32-bit ids), eps %g m at the end, %llu stalls (%.1f ms), "
               "%llu frames at risk, %llu updates short of a level\n",
               cfg[i].spec, (unsigned long long)is.adopted, (unsigned long long)is.frames, is.vis_ms_total / u,
               (double)is.set_size_total / u, 4.0 * (double)is.set_size_total / u / 1024.0, (double)is.eps_displayed,
               (unsigned long long)is.stalls, is.stall_ms, (unsigned long long)is.frames_at_risk,
               (unsigned long long)is.eps_short);
    }
    int bad = 0;
    for (uint32_t i = 0; i < nc; i++)
        if (cfg[i].conservative && (cfg[i].gl_misses || (!cfg[i].gl_driven && cfg[i].misses)))
            bad = 1;
    for (uint32_t i = 0; i < nc; i++) {
        sl_culler_destroy(cfg[i].culler);
        free(cfg[i].frame_ms);
    }
    free(ids);
    free(truth);
    free(all);
    free(gl_ids);
    free(gl_shown);
    sl_oracle_destroy(oracle);
    sl_renderer_destroy(r);
    sl_path_destroy(path);
    sl_scene_destroy(scene);
    return bad;
}
