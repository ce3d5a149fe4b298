/* Benchmark of the online occlusion methods (hzb, hom, lazygrid, lazygrid-z, busygrid, frusta,
 * plp, cplp) beside vfc, against the point oracle.
 *
 *   bench_occlusion [--preset tiny|small|vienna] [--frames N] [--fps F] [--repeat R]
 *                   [--width W --height H] [--threads T] [--methods LIST] [--no-scaling]
 *                   [--no-memory] [--scaling-frames N]
 *
 * 1. Walkthrough (default: vienna, a street walk of 300 frames at 5 fps, seed 1, 1024x768): every
 *    method culls every frame once against the oracle (objects passed, misses), then, for the times,
 *    the whole walk on its own, every frame R times (default 3), with `threads=T` (default 2) where
 *    it has a rasterizer; per frame the fastest of the R wall times counts (the build machine is
 *    shared; culling the walk alone keeps the other methods and the oracle from evicting a method's
 *    caches between its frames, as in bench_urban), and
 *    the table gives the median and 95th percentile over the frames, the objects passed to the
 *    renderer against the exact visible set of the oracle at the same resolution (mean and ratio of
 *    means), the missed objects and pixels (zero for conservative methods), and the pixel queries.
 *    --methods takes comma-separated specs name[:key=value[:key=value...]], e.g.
 *    "hzb,hzb:exact_px=0:box_rows=0,lazygrid". The rows with shared=false show each method alone,
 *    without the shared hidden-object test that runs after its own (src/cull/occluders.h).
 * 2. Memory: live bytes of a culling context (everything it allocated, its BVH, proxies and
 *    rasterizer included) after one frame at 1920x1080 on the same scene.
 * 3. Scaling: the median cull time on a walk of --scaling-frames frames (default 100) of the tiny,
 *    small and vienna cities.
 * Output: Markdown for BENCHMARKS.md and docs/occlusion.md; exit status 1 when a conservative
 * method missed an object. */
#include "core/sl_core.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "sightline/truth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "bench_common.h"

#define MAX_METHODS 24

static const char *const g_default_methods[] = {
    "vfc", "hzb", "hzb:threads=1", "hzb:exact_px=0:box_rows=0", "hzb:far_layer=false", "hzb:all_objects=true", "hom",
    "hom:depth=zbuffer",
    "hom:threshold=0.9",
    "lazygrid", "lazygrid:threads=1", "lazygrid-z", "busygrid", "frusta", "plp", "cplp",
    /* each method alone: the shared hidden-object test (mesh_test, sample_tris) off */
    "hzb:shared=false", "lazygrid:shared=false", "lazygrid-z:shared=false", "busygrid:shared=false"};

typedef bench_method_spec method;

static void die(const char *what, const sl_error *err) { bench_die("bench_occlusion", what, err); }

static sl_scene make_city(const char *preset)
{
    sl_city_preset p;
    sl_error err;
    if (sl_city_preset_from_name(preset, &p, &err) != SL_OK)
        die(preset, &err);
    sl_city_options co = sl_city_defaults(p);
    sl_scene s;
    if (sl_gen_city(&co, NULL, &s, &err) != SL_OK)
        die("gen city", &err);
    return s;
}

static sl_path make_walk(sl_scene s, uint32_t frames, float fps, uint32_t w, uint32_t h)
{
    sl_path_options po = sl_path_options_default(SL_PATH_WALK);
    po.frames = frames;
    po.fps = fps;
    po.seed = 1;
    po.intrinsics.width = w;
    po.intrinsics.height = h;
    sl_path p;
    sl_error err;
    if (sl_path_generate(s, &po, NULL, &p, &err) != SL_OK)
        die("walk", &err);
    return p;
}

/* Cull every frame of the walk `repeat` times; times[f]: the fastest (wall clock, ms). */
static void walk_times(sl_culler c, sl_path p, uint32_t repeat, uint32_t *out, uint32_t n, double *times)
{
    uint32_t frames = sl_path_count(p);
    for (uint32_t f = 0; f < frames; f++) {
        sl_camera cam = sl_path_camera(p, f);
        double best = INFINITY;
        for (uint32_t r = 0; r < repeat; r++) {
            uint32_t k;
            sl_error err;
            if (sl_culler_cull(c, &cam, out, n, &k, &err) != SL_OK)
                die(sl_culler_method(c), &err);
            sl_cull_stats st;
            sl_culler_stats(c, &st);
            best = fmin(best, st.total_ms);
        }
        times[f] = best;
    }
}

/* Median over frames of the fastest of `repeat` culls. */
static double median_time(sl_culler c, sl_path p, uint32_t repeat, uint32_t *out, uint32_t n, double *scratch)
{
    walk_times(c, p, repeat, out, n, scratch);
    return bench_percentile(scratch, sl_path_count(p), 0.5);
}

/* Allocator that counts live bytes (for the memory table). */
typedef struct counter {
    size_t live, peak;
} counter;
static void *c_alloc(void *u, size_t size, size_t align)
{
    counter *c = u;
    void *p = NULL;
    if (posix_memalign(&p, align < sizeof(void *) ? sizeof(void *) : align, size ? size : 1) != 0)
        return NULL;
    c->live += size;
    c->peak = c->live > c->peak ? c->live : c->peak;
    return p;
}
static void c_free(void *u, void *p, size_t size)
{
    counter *c = u;
    if (p)
        c->live -= size;
    free(p);
}
static void *c_realloc(void *u, void *p, size_t old, size_t size, size_t align)
{
    void *q = c_alloc(u, size, align);
    if (!q)
        return NULL;
    if (p)
        memcpy(q, p, old < size ? old : size);
    c_free(u, p, old);
    return q;
}

int main(int argc, char **argv)
{
    const char *preset = "vienna";
    uint32_t frames = 300, repeat = 3, width = 1024, height = 768, threads = 2, scaling_frames = 100;
    float fps = 5;
    bool scaling = true, memory = true;
    const char *list = NULL;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        bool more = i + 1 < argc;
        if (!strcmp(a, "--preset") && more)
            preset = argv[++i];
        else if (!strcmp(a, "--frames") && more)
            frames = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(a, "--fps") && more)
            fps = (float)atof(argv[++i]);
        else if (!strcmp(a, "--repeat") && more)
            repeat = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(a, "--width") && more)
            width = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(a, "--height") && more)
            height = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(a, "--threads") && more)
            threads = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(a, "--methods") && more)
            list = argv[++i];
        else if (!strcmp(a, "--scaling-frames") && more)
            scaling_frames = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(a, "--no-scaling"))
            scaling = false;
        else if (!strcmp(a, "--no-memory"))
            memory = false;
        else {
            fprintf(stderr,
                    "usage: bench_occlusion [--preset tiny|small|vienna] [--frames N] [--fps F] [--repeat R]\n"
                    "       [--width W --height H] [--threads T] [--methods LIST] [--no-scaling] [--no-memory]\n"
                    "       [--scaling-frames N]\n");
            return 2;
        }
    }
    if (frames < 1 || repeat < 1 || width < 1 || height < 1 || threads < 1 || threads > 16 || !(fps > 0))
        die("bad numeric option", NULL);
    method methods[MAX_METHODS];
    uint32_t nm = bench_methods_parse("bench_occlusion", list, g_default_methods, SL_COUNTOF(g_default_methods), threads,
                                      NULL, methods, MAX_METHODS);
    sl_error err;
    printf("# bench_occlusion\n\n");
    /* ---- 1. walkthrough ---- */
    sl_scene s = make_city(preset);
    sl_path walk = make_walk(s, frames, fps, width, height);
    frames = sl_path_count(walk);
    uint32_t n = sl_scene_object_count(s);
    uint32_t *out = malloc((n ? n : 1) * sizeof *out);
    double *times = malloc((size_t)nm * frames * sizeof(double));
    double *scratch = malloc((frames > scaling_frames ? frames : scaling_frames) * sizeof(double));
    double kept[MAX_METHODS] = {0}, queries[MAX_METHODS] = {0}, missed[MAX_METHODS] = {0},
           missed_px[MAX_METHODS] = {0};
    sl_culler c[MAX_METHODS];
    for (uint32_t i = 0; i < nm; i++)
        if (sl_culler_create(methods[i].name, s, methods[i].opts, NULL, &c[i], &err) != SL_OK)
            die(methods[i].spec, &err);
    sl_oracle o;
    if (sl_oracle_create(s, NULL, NULL, &o, &err) != SL_OK)
        die("oracle", &err);
    double visible = 0;
    bool violation = false;
    const bool tty = isatty(STDERR_FILENO); /* progress on a terminal only */
    for (uint32_t f = 0; f < frames; f++) {
        sl_camera cam = sl_path_camera(walk, f);
        sl_oracle_frame fr;
        if (sl_oracle_render(o, &cam, &fr, &err) != SL_OK)
            die("oracle render", &err);
        visible += fr.visible_count;
        for (uint32_t i = 0; i < nm; i++) {
            uint32_t k = 0;
            sl_cull_stats st;
            if (sl_culler_cull(c[i], &cam, out, n, &k, &err) != SL_OK)
                die(methods[i].spec, &err);
            sl_culler_stats(c[i], &st);
            sl_cull_metrics m;
            if (sl_metrics_compare(s, &fr, out, k, &m, NULL, NULL, 0, &err) != SL_OK)
                die("metrics", &err);
            kept[i] += k;
            queries[i] += (double)st.queries;
            missed[i] += m.missed_count;
            missed_px[i] += (double)m.missed_pixels;
            if (m.missed_count && sl_cull_guarantee_keeps_visible(sl_culler_guarantee(c[i]), true)) {
                fprintf(stderr, "CONSERVATIVENESS VIOLATION: %s frame %u missed %u objects\n", methods[i].spec, f,
                        m.missed_count);
                violation = true;
            }
        }
        if (f % 25 == 0 && tty)
            fprintf(stderr, "\rwalkthrough frame %u/%u", f, frames);
    }
    if (tty)
        fprintf(stderr, "\n");
    /* timing: each method culls the whole walk on its own, `repeat` times per frame, so that the
     * other methods and the oracle do not evict its caches between frames (as in bench_urban) */
    for (uint32_t i = 0; i < nm; i++) {
        /* one untimed pass first (its times are overwritten): the first method timed after the
         * oracle pass ran up to 1.4x slower than the same method timed later in the same run */
        walk_times(c[i], walk, 1, out, n, times + (size_t)i * frames);
        walk_times(c[i], walk, repeat, out, n, times + (size_t)i * frames);
        if (tty)
            fprintf(stderr, "\rtiming %u/%u", i + 1, nm);
    }
    if (tty)
        fprintf(stderr, "\n");
    sl_scene_stats ss;
    sl_scene_get_stats(s, &ss);
    printf("## Walkthrough: %s city, street walk of %u frames at %g fps (seed 1), %ux%u, threads=%u\n\n", preset,
           frames, (double)fps, width, height, threads);
    printf("%u objects, %llu triangles; exact visible set (oracle, same resolution): %.1f objects per frame. "
           "Time: each method culls the walk on its own; per frame the fastest of %u culls (wall clock), then the "
           "median and 95th percentile over the frames.\n\n",
           ss.object_count, (unsigned long long)ss.instanced_triangle_count, visible / frames, repeat);
    printf("| method | guarantee | median ms | p95 ms | objects passed | passed / visible | missed objects | "
           "missed pixels | pixel queries |\n|---|---|---:|---:|---:|---:|---:|---:|---:|\n");
    for (uint32_t i = 0; i < nm; i++) {
        double *t = times + (size_t)i * frames;
        double med = bench_percentile(t, frames, 0.5), p95 = bench_percentile(t, frames, 0.95);
        printf("| %s | %s | %.4f | %.4f | %.1f | %.2f | %.0f | %.0f | %.0f |\n", methods[i].spec,
               sl_cull_guarantee_name(sl_culler_guarantee(c[i])), med, p95, kept[i] / frames, kept[i] / visible,
               missed[i], missed_px[i], queries[i] / frames);
    }
    printf("\n");
    sl_oracle_destroy(o);
    for (uint32_t i = 0; i < nm; i++)
        sl_culler_destroy(c[i]);
    /* ---- 2. memory at 1920x1080 ---- */
    if (memory) {
        printf("## Memory of a culling context at 1920x1080 (%s city)\n\n", preset);
        printf("Live bytes after one frame (the context's BVH or octree, occluder proxies, rasterizer and "
               "pyramids; the scene is not counted).\n\n| method | MiB |\n|---|---:|\n");
        sl_camera cam = sl_path_camera(walk, 0);
        cam.width = 1920;
        cam.height = 1080;
        for (uint32_t i = 0; i < nm; i++) {
            counter cnt = {0, 0};
            sl_allocator a = {c_alloc, c_realloc, c_free, &cnt};
            sl_culler cc;
            if (sl_culler_create(methods[i].name, s, methods[i].opts, &a, &cc, &err) != SL_OK)
                die(methods[i].spec, &err);
            uint32_t k;
            if (sl_culler_cull(cc, &cam, out, n, &k, &err) != SL_OK)
                die(methods[i].spec, &err);
            printf("| %s | %.2f |\n", methods[i].spec, (double)cnt.live / (1024.0 * 1024.0));
            sl_culler_destroy(cc);
        }
        printf("\n");
    }
    sl_path_destroy(walk);
    sl_scene_destroy(s);
    /* ---- 3. scaling ---- */
    if (scaling) {
        static const char *const presets[] = {"tiny", "small", "vienna"};
        double med[3][MAX_METHODS];
        uint32_t objs[3];
        for (int p = 0; p < 3; p++) {
            sl_scene sc = make_city(presets[p]);
            objs[p] = sl_scene_object_count(sc);
            sl_path w = make_walk(sc, scaling_frames, fps, width, height);
            uint32_t no = sl_scene_object_count(sc);
            uint32_t *o2 = malloc((no ? no : 1) * sizeof *o2);
            for (uint32_t i = 0; i < nm; i++) {
                sl_culler cc;
                if (sl_culler_create(methods[i].name, sc, methods[i].opts, NULL, &cc, &err) != SL_OK)
                    die(methods[i].spec, &err);
                med[p][i] = median_time(cc, w, repeat, o2, no, scratch);
                sl_culler_destroy(cc);
            }
            free(o2);
            sl_path_destroy(w);
            sl_scene_destroy(sc);
            fprintf(stderr, "scaling: %s done\n", presets[p]);
        }
        printf("## Cull time against scene size (median ms over a %u-frame walk, %ux%u)\n\n", scaling_frames, width,
               height);
        printf("| method | tiny (%u objects) | small (%u) | vienna (%u) |\n|---|---:|---:|---:|\n", objs[0], objs[1],
               objs[2]);
        for (uint32_t i = 0; i < nm; i++)
            printf("| %s | %.3f | %.3f | %.3f |\n", methods[i].spec, med[0][i], med[1][i], med[2][i]);
        printf("\n");
    }
    free(out);
    free(times);
    free(scratch);
    return violation ? 1 : 0;
}
