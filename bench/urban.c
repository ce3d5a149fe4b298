/* Benchmark and long correctness run of the urban 2.5D cullers (cullmap, horizon, dhorizon) against
 * vfc and the point oracle, on the generated cities.
 *
 *   bench_urban [--preset tiny|small|vienna] [--seed S] [--views N] [--frames N] [--runs R]
 *               [--fast SPEED] [--check-walk] [--methods LIST] [--opts METHOD:OPTIONS]...
 *
 * 1. Zero-miss check: N random street-level views (sl_path_random_views, eye 1.7 m, random yaw;
 *    every fourth view pitched and rolled at random, 6 degrees of freedom) rendered by the oracle
 *    at 1024x768; every method must keep every object the oracle sees. The methods are run in
 *    random order per view, dhorizon included (its frames are then unrelated jumps: the guard).
 * 2. Walkthrough: a street walk of F frames (sl_path_generate, 1.4 m/s, 30 fps) replayed R times;
 *    per method the median over the runs of the per-run median cull time per frame (one thread),
 *    the mean triangles passed to the renderer and their ratio to vfc; the dhorizon/horizon time
 *    ratio is measured in the same run. --check-walk also checks every walk frame with the oracle.
 * 3. Fast movement (dhorizon): a drive at SPEED m/s (default 30, i.e. 1 m per frame at 30 fps, and
 *    then 10x that), every frame checked by the oracle.
 * Output: Markdown, for BENCHMARKS.md; exit status 1 when any conservative method missed an object. */
#include "core/sl_core.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "sightline/truth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "bench_common.h"

#define MAX_METHODS 8

typedef struct method {
    const char *name;
    const char *opts;
    sl_culler c;
    uint64_t misses, missed_pixels, views;
    double over_sum;
} method;

static void die(const char *what, const sl_error *err)
{
    fprintf(stderr, "bench_urban: %s: %s\n", what, err ? err->message : "");
    exit(2);
}

/* CPU time of this thread in ms: on a loaded machine closer to the work than wall time. */
static double cpu_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

/* Cull one camera with a method and judge it against the oracle frame. */
static void judge(method *m, sl_scene scene, const sl_camera *cam, const sl_oracle_frame *fr, uint32_t *ids,
                  uint32_t cap, const char *where)
{
    sl_error err;
    uint32_t n;
    if (sl_culler_cull(m->c, cam, ids, cap, &n, &err) != SL_OK)
        die(m->name, &err);
    sl_cull_metrics mt;
    uint32_t missed[8], mpx[8];
    if (sl_metrics_compare(scene, fr, ids, n, &mt, missed, mpx, 8, &err) != SL_OK)
        die("metrics", &err);
    m->views++;
    m->over_sum += mt.overestimation;
    if (mt.missed_count) {
        m->misses += mt.missed_count;
        m->missed_pixels += mt.missed_pixels;
        fprintf(stderr, "MISS %s %s: %u objects (%llu px), first %u (%u px), eye (%.3f %.3f %.3f) yaw %.4f pitch %.4f roll %.4f\n",
                m->name, where, mt.missed_count, (unsigned long long)mt.missed_pixels, missed[0], mpx[0],
                (double)cam->position.x, (double)cam->position.y, (double)cam->position.z, (double)cam->yaw,
                (double)cam->pitch, (double)cam->roll);
    }
}

int main(int argc, char **argv)
{
    const char *preset = "small";
    uint64_t seed = 1;
    uint32_t views = 200, frames = 600, runs = 5;
    float fast = 30;
    bool check_walk = false;
    const char *method_list = "cullmap,horizon,dhorizon";
    const char *extra_opts[MAX_METHODS] = {0};
    int n_extra = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--preset") && v)
            preset = v, i++;
        else if (!strcmp(a, "--seed") && v)
            seed = strtoull(v, NULL, 10), i++;
        else if (!strcmp(a, "--views") && v)
            views = (uint32_t)strtoul(v, NULL, 10), i++;
        else if (!strcmp(a, "--frames") && v)
            frames = (uint32_t)strtoul(v, NULL, 10), i++;
        else if (!strcmp(a, "--runs") && v)
            runs = (uint32_t)strtoul(v, NULL, 10), i++;
        else if (!strcmp(a, "--fast") && v)
            fast = strtof(v, NULL), i++;
        else if (!strcmp(a, "--methods") && v)
            method_list = v, i++;
        else if (!strcmp(a, "--opts") && v && n_extra < MAX_METHODS)
            extra_opts[n_extra++] = v, i++;
        else if (!strcmp(a, "--check-walk"))
            check_walk = true;
        else {
            fprintf(stderr, "usage: bench_urban [--preset tiny|small|vienna] [--seed S] [--views N] [--frames N] "
                            "[--runs R] [--fast SPEED] [--check-walk] [--methods a,b] [--opts method:options]\n");
            return 2;
        }
    }
    sl_error err;
    sl_city_preset p;
    if (sl_city_preset_from_name(preset, &p, &err) != SL_OK)
        die("preset", &err);
    sl_city_options co = sl_city_defaults(p);
    co.seed = seed;
    sl_scene scene;
    double t0 = sl_now();
    if (sl_gen_city(&co, NULL, &scene, &err) != SL_OK)
        die("gen", &err);
    sl_scene_stats ss;
    sl_scene_get_stats(scene, &ss);
    printf("## urban cullers: %s city (seed %llu): %u objects, %.2fM triangles, %u footprints (generated in %.1f s)\n\n",
           preset, (unsigned long long)seed, ss.object_count, ss.instanced_triangle_count / 1e6, ss.footprint_count,
           sl_now() - t0);

    /* the methods, vfc first */
    method ms[MAX_METHODS];
    int nm = 0;
    char list[256];
    snprintf(list, sizeof list, "vfc,%s", method_list);
    for (char *tok = strtok(list, ","); tok && nm < MAX_METHODS; tok = strtok(NULL, ",")) {
        memset(&ms[nm], 0, sizeof ms[nm]);
        ms[nm].name = tok;
        ms[nm].opts = "";
        for (int k = 0; k < n_extra; k++) {
            size_t l = strlen(tok);
            if (!strncmp(extra_opts[k], tok, l) && extra_opts[k][l] == ':')
                ms[nm].opts = extra_opts[k] + l + 1;
        }
        double tc = sl_now();
        if (sl_culler_create(tok, scene, ms[nm].opts, NULL, &ms[nm].c, &err) != SL_OK)
            die(tok, &err);
        printf("- %s (%s): created in %.1f ms\n", tok, sl_culler_options(ms[nm].c), (sl_now() - tc) * 1e3);
        nm++;
    }
    printf("\n");
    uint32_t cap = ss.object_count ? ss.object_count : 1;
    uint32_t *ids = malloc((size_t)cap * sizeof *ids);
    sl_oracle oracle;
    if (sl_oracle_create(scene, NULL, NULL, &oracle, &err) != SL_OK)
        die("oracle", &err);
    sl_oracle_frame fr;
    sl_rng rng;
    sl_rng_seed(&rng, seed, 77);
    int failed = 0;

    /* 1. random street views, 6 DoF on every fourth */
    if (views) {
        sl_path path;
        if (sl_path_random_views(scene, SL_VIEWS_STREET, views, seed, NULL, NULL, &path, &err) != SL_OK)
            die("views", &err);
        double to = 0;
        for (uint32_t v = 0; v < views; v++) {
            sl_camera cam = sl_path_camera(path, v);
            if (v % 4 == 3) {
                cam.pitch = sl_rng_range(&rng, -1.2f, 1.2f);
                cam.roll = sl_rng_range(&rng, -3.1f, 3.1f);
            }
            double tr = sl_now();
            if (sl_oracle_render(oracle, &cam, &fr, &err) != SL_OK)
                die("oracle", &err);
            to += sl_now() - tr;
            char where[64];
            snprintf(where, sizeof where, "view %u", v);
            uint32_t start = sl_rng_below(&rng, (uint32_t)nm);
            for (int k = 0; k < nm; k++)
                judge(&ms[(start + (uint32_t)k) % (uint32_t)nm], scene, &cam, &fr, ids, cap, where);
        }
        sl_path_destroy(path);
        printf("### zero-miss check: %u random street views (1024x768, every 4th pitched and rolled), oracle %.1f s\n\n",
               views, to);
        printf("| method | views | missed objects | missed pixels | mean kept / visible |\n|---|---|---|---|---|\n");
        for (int k = 0; k < nm; k++) {
            printf("| %s | %llu | %llu | %llu | %.2f |\n", ms[k].name, (unsigned long long)ms[k].views,
                   (unsigned long long)ms[k].misses, (unsigned long long)ms[k].missed_pixels,
                   ms[k].views ? ms[k].over_sum / ms[k].views : 0);
            if (ms[k].misses && sl_cull_guarantee_keeps_visible(sl_culler_guarantee(ms[k].c), true))
                failed = 1;
            ms[k].misses = ms[k].missed_pixels = ms[k].views = 0;
            ms[k].over_sum = 0;
        }
        printf("\n");
    }

    /* 2. the walkthrough */
    if (frames) {
        sl_path_options po = sl_path_options_default(SL_PATH_WALK);
        po.frames = frames;
        po.seed = seed;
        sl_path walk;
        if (sl_path_generate(scene, &po, NULL, &walk, &err) != SL_OK)
            die("walk", &err);
        double *times = malloc(sizeof(double) * frames * MAX_METHODS);
        double *ctimes = malloc(sizeof(double) * frames * MAX_METHODS);
        double *run_median = malloc(sizeof(double) * runs * MAX_METHODS);
        double *run_cmedian = malloc(sizeof(double) * runs * MAX_METHODS);
        double tris[MAX_METHODS] = {0}, objs[MAX_METHODS] = {0};
        double ratio_runs[64];
        uint32_t nratio = 0;
        for (uint32_t r = 0; r < runs; r++) {
            /* Each method culls the whole walk on its own, as it would beside a renderer: interleaving
             * the methods frame by frame made them evict each other's grids and trees from the caches
             * and charged that to every method. The runs still alternate the methods. */
            for (int k = 0; k < nm; k++) {
                for (uint32_t f = 0; f < frames; f++) {
                    sl_camera cam = sl_path_camera(walk, f);
                    uint32_t n;
                    double c0 = cpu_ms();
                    if (sl_culler_cull(ms[k].c, &cam, ids, cap, &n, &err) != SL_OK)
                        die(ms[k].name, &err);
                    ctimes[k * frames + f] = cpu_ms() - c0;
                    sl_cull_stats st;
                    sl_culler_stats(ms[k].c, &st);
                    times[k * frames + f] = st.total_ms;
                    if (r == 0) {
                        tris[k] += (double)st.triangles_visible;
                        objs[k] += n;
                    }
                }
            }
            for (int k = 0; k < nm; k++) {
                run_median[k * runs + r] = bench_median(times + (size_t)k * frames, frames);
                run_cmedian[k * runs + r] = bench_median(ctimes + (size_t)k * frames, frames);
            }
            int h = -1, d = -1;
            for (int k = 0; k < nm; k++) {
                if (!strcmp(ms[k].name, "horizon"))
                    h = k;
                if (!strcmp(ms[k].name, "dhorizon"))
                    d = k;
            }
            if (h >= 0 && d >= 0 && nratio < 64)
                ratio_runs[nratio++] = run_cmedian[h * runs + r] / fmax(run_cmedian[d * runs + r], 1e-9);
        }
        sl_path_stats ps;
        sl_path_get_stats(walk, &ps);
        printf("### walkthrough: %u frames, %.0f m at %.1f m/s, %u runs (median of the per-run medians)\n\n", frames,
               ps.length, ps.speed_mean, runs);
        printf("| method | cull ms/frame, CPU (median) | wall (median) | objects/frame | triangles/frame | "
               "triangles vs vfc |\n|---|---|---|---|---|---|\n");
        for (int k = 0; k < nm; k++) {
            double med = bench_median(run_median + (size_t)k * runs, runs);
            double cmed = bench_median(run_cmedian + (size_t)k * runs, runs);
            printf("| %s | %.3f | %.3f | %.0f | %.0f | %.1fx fewer |\n", ms[k].name, cmed, med, objs[k] / frames,
                   tris[k] / frames, tris[0] / fmax(tris[k], 1));
        }
        if (nratio)
            printf("\ndhorizon vs horizon, same runs: horizon CPU time / dhorizon CPU time = %.2f (median of %u runs)\n",
                   bench_median(ratio_runs, nratio), nratio);
        printf("\n");
        if (check_walk) {
            for (int k = 0; k < nm; k++)
                ms[k].misses = ms[k].views = 0;
            for (uint32_t f = 0; f < frames; f++) {
                sl_camera cam = sl_path_camera(walk, f);
                if (sl_oracle_render(oracle, &cam, &fr, &err) != SL_OK)
                    die("oracle", &err);
                char where[64];
                snprintf(where, sizeof where, "walk frame %u", f);
                for (int k = 0; k < nm; k++)
                    judge(&ms[k], scene, &cam, &fr, ids, cap, where);
            }
            printf("walk checked against the oracle:");
            for (int k = 0; k < nm; k++) {
                printf(" %s %llu misses;", ms[k].name, (unsigned long long)ms[k].misses);
                if (ms[k].misses && sl_cull_guarantee_keeps_visible(sl_culler_guarantee(ms[k].c), true))
                    failed = 1;
            }
            printf("\n\n");
        }
        free(times);
        free(ctimes);
        free(run_median);
        free(run_cmedian);
        sl_path_destroy(walk);
    }

    /* 3. fast movement for dhorizon (and the others), every frame checked; two more dhorizons: one
     * without the guard (every frame incremental, so the parallax bound does all the work) and the
     * thesis' plain test (parallax=false, aggressive: its misses are reported, not failed) */
    if (fast > 0 && nm + 2 <= MAX_METHODS) {
        static const char *const extra[2][2] = {{"dhorizon", "max_move=10000,max_turn=180,refresh=0"},
                                                {"dhorizon", "max_move=10000,max_turn=180,refresh=0,parallax=false"}};
        for (int q = 0; q < 2; q++) {
            memset(&ms[nm], 0, sizeof ms[nm]);
            ms[nm].name = q ? "dhorizon-plain" : "dhorizon-noguard";
            ms[nm].opts = extra[q][1];
            if (sl_culler_create(extra[q][0], scene, extra[q][1], NULL, &ms[nm].c, &err) != SL_OK)
                die(extra[q][0], &err);
            nm++;
        }
    }
    if (fast > 0) {
        for (int pass = 0; pass < 2; pass++) {
            float speed = pass == 0 ? fast : 10 * fast;
            sl_path_options po = sl_path_options_default(SL_PATH_DRIVE);
            po.frames = pass == 0 ? 300 : 120;
            po.speed = speed;
            po.seed = seed + 1 + (uint64_t)pass;
            sl_path drive;
            if (sl_path_generate(scene, &po, NULL, &drive, &err) != SL_OK)
                die("drive", &err);
            for (int k = 0; k < nm; k++)
                ms[k].misses = ms[k].views = 0;
            for (uint32_t f = 0; f < po.frames; f++) {
                sl_camera cam = sl_path_camera(drive, f);
                if (sl_oracle_render(oracle, &cam, &fr, &err) != SL_OK)
                    die("oracle", &err);
                char where[64];
                snprintf(where, sizeof where, "drive %.0f m/s frame %u", (double)speed, f);
                for (int k = 0; k < nm; k++)
                    judge(&ms[k], scene, &cam, &fr, ids, cap, where);
            }
            printf("fast drive, %.0f m/s (%.2f m per frame), %u frames checked:", (double)speed, speed / 30.0,
                   po.frames);
            for (int k = 0; k < nm; k++) {
                printf(" %s %llu misses;", ms[k].name, (unsigned long long)ms[k].misses);
                if (ms[k].misses && sl_cull_guarantee_keeps_visible(sl_culler_guarantee(ms[k].c), true))
                    failed = 1;
            }
            printf("\n");
            sl_path_destroy(drive);
        }
        printf("\n");
    }
    for (int k = 0; k < nm; k++)
        sl_culler_destroy(ms[k].c);
    sl_oracle_destroy(oracle);
    free(ids);
    sl_scene_destroy(scene);
    return failed;
}
