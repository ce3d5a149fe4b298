/* BVH build benchmark: median build time of 5 runs (one thread and all threads), node counts, depth,
 * SAH cost, a full front-to-back traversal, a refit, and the 2D grid build, for random boxes
 * (10k, 100k, 1M) and for the generated cities (tiny, small, vienna) when the generator exists.
 * Prints Markdown rows for BENCHMARKS.md.
 *
 *   bench_bvh_build [--quick] [--no-city] [--leaf N] [--bins N] [--runs N]
 *     --quick    skip the 1M boxes and the vienna city
 */
#include "sightline/accel.h"
#include "sightline/scene.h"
#include "core/sl_core.h"

#if __has_include("sightline/gen.h")
#include "sightline/gen.h"
#define HAVE_GEN 1
#else
#define HAVE_GEN 0
#endif

#include <math.h>
#include <stdio.h>
#include <time.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "bench_common.h"

typedef struct config {
    bool quick, city;
    uint32_t leaf, bins, runs;
} config;

/* CPU time of the calling thread: a single-threaded build's cost even on a busy machine. */
static double thread_cpu(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

/* City-like random boxes: constant density (one box per 400 m² of ground), 2-40 m wide, 3-60 m tall. */
static sl_aabb *random_boxes(uint32_t n, uint64_t seed)
{
    sl_aabb *b = malloc((size_t)n * sizeof *b);
    if (!b)
        return NULL;
    sl_rng r;
    sl_rng_seed(&r, seed, 1);
    float side = sqrtf((float)n) * 20.0f;
    for (uint32_t i = 0; i < n; i++) {
        float x = sl_rng_range(&r, 0, side), y = sl_rng_range(&r, 0, side), z = sl_rng_range(&r, 0, 5);
        float w = sl_rng_range(&r, 2, 40), d = sl_rng_range(&r, 2, 40), h = sl_rng_range(&r, 3, 60);
        b[i] = (sl_aabb){{x, y, z}, {x + w, y + d, z + h}};
    }
    return b;
}

static bool count_node(void *user, uint32_t node, const sl_aabb *bounds)
{
    (void)node, (void)bounds;
    (*(uint64_t *)user)++;
    return true;
}

static bool count_object(void *user, uint32_t object, const sl_aabb *bounds)
{
    (void)object, (void)bounds;
    (*((uint64_t *)user + 1))++;
    return true;
}

static void print_header(void)
{
    printf("| input | objects | build 1 thread ms | (its CPU ms) | build all threads ms | nodes | leaves | depth "
           "| SAH cost | traversal ms | refit ms | grid build ms |\n");
    printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
}

/* Measure one input; returns false on error (printed). */
static bool measure(const char *name, const sl_aabb *boxes, uint32_t n, const config *cfg)
{
    double t1[16], c1[16], tall[16], trav[16], refit[16], grid[16];
    sl_bvh_stats st = {0};
    sl_error err;
    sl_bvh keep = NULL;
    for (uint32_t r = 0; r < cfg->runs; r++) {
        for (int mode = 0; mode < 2; mode++) {
            sl_bvh_options o = {cfg->leaf, cfg->bins, mode == 0 ? 1u : 0u, NULL};
            sl_bvh bvh;
            double t0 = sl_now(), cpu0 = thread_cpu();
            if (sl_bvh_build_boxes(boxes, n, &o, &bvh, &err) != SL_OK) {
                fprintf(stderr, "bench_bvh_build: %s: %s\n", name, err.message);
                sl_bvh_destroy(keep);
                return false;
            }
            (mode == 0 ? t1 : tall)[r] = (sl_now() - t0) * 1e3;
            if (mode == 0)
                c1[r] = (thread_cpu() - cpu0) * 1e3;
            if (mode == 0 && !keep)
                keep = bvh;
            else
                sl_bvh_destroy(bvh);
        }
    }
    sl_bvh_get_stats(keep, &st);
    /* a full front-to-back traversal from the middle of the scene, eye 1.7 m above the lowest box */
    sl_aabb b = sl_bvh_bounds(keep);
    sl_vec3 eye = {0.5f * (b.min.x + b.max.x), 0.5f * (b.min.y + b.max.y), b.min.z + 1.7f};
    uint64_t counts[2] = {0, 0};
    for (uint32_t r = 0; r < cfg->runs; r++) {
        counts[0] = counts[1] = 0;
        double t0 = sl_now();
        sl_bvh_traverse(keep, eye, count_node, count_object, counts);
        trav[r] = (sl_now() - t0) * 1e3;
        if (counts[1] != n || counts[0] != st.node_count) {
            fprintf(stderr, "bench_bvh_build: %s: traversal reported %llu objects and %llu nodes\n", name,
                    (unsigned long long)counts[1], (unsigned long long)counts[0]);
            sl_bvh_destroy(keep);
            return false;
        }
        t0 = sl_now();
        if (sl_bvh_refit_boxes(keep, boxes, n, &err) != SL_OK) {
            fprintf(stderr, "bench_bvh_build: %s: %s\n", name, err.message);
            sl_bvh_destroy(keep);
            return false;
        }
        refit[r] = (sl_now() - t0) * 1e3;
        sl_grid g;
        t0 = sl_now();
        if (sl_grid_build_boxes(boxes, n, NULL, &g, &err) != SL_OK) {
            fprintf(stderr, "bench_bvh_build: %s: %s\n", name, err.message);
            sl_bvh_destroy(keep);
            return false;
        }
        grid[r] = (sl_now() - t0) * 1e3;
        sl_grid_destroy(g);
    }
    printf("| %s | %u | %.1f | %.1f | %.1f | %u | %u | %u | %.1f | %.2f | %.2f | %.1f |\n", name, n,
           bench_median(t1, cfg->runs), bench_median(c1, cfg->runs), bench_median(tall, cfg->runs), st.node_count,
           st.leaf_count, st.depth, st.sah_cost, bench_median(trav, cfg->runs), bench_median(refit, cfg->runs),
           bench_median(grid, cfg->runs));
    fflush(stdout);
    sl_bvh_destroy(keep);
    return true;
}

static int usage(FILE *f, int code)
{
    fprintf(f, "usage: bench_bvh_build [--quick] [--no-city] [--leaf N] [--bins N] [--runs N]\n"
               "  --quick     skip the 1M random boxes and the vienna city\n"
               "  --no-city   random boxes only\n"
               "  --leaf N    max leaf size (default 4)\n"
               "  --bins N    SAH bins (default 16)\n"
               "  --runs N    runs per figure, the median is printed (default 5, at most 16)\n"
               "example: bench_bvh_build --quick\n");
    return code;
}

int main(int argc, char **argv)
{
    config cfg = {false, true, 0, 0, 5};
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--quick"))
            cfg.quick = true;
        else if (!strcmp(argv[i], "--no-city"))
            cfg.city = false;
        else if ((!strcmp(argv[i], "--leaf") || !strcmp(argv[i], "--bins") || !strcmp(argv[i], "--runs")) &&
                 i + 1 < argc) {
            char *end;
            unsigned long v = strtoul(argv[i + 1], &end, 10);
            if (*end || v == 0 || v > 64)
                return usage(stderr, 2);
            if (!strcmp(argv[i], "--leaf"))
                cfg.leaf = (uint32_t)v;
            else if (!strcmp(argv[i], "--bins"))
                cfg.bins = (uint32_t)v;
            else if (v <= 16)
                cfg.runs = (uint32_t)v;
            else
                return usage(stderr, 2);
            i++;
        } else if (!strcmp(argv[i], "--help")) {
            return usage(stdout, 0);
        } else {
            return usage(stderr, 2);
        }
    }
    char cpu[256];
    bench_cpu_model(cpu, sizeof cpu);
    printf("Machine: %ld CPUs (nproc), %s. Median of %u runs; leaf size %u, %u bins.\n\n",
           sysconf(_SC_NPROCESSORS_ONLN), cpu, cfg.runs, cfg.leaf ? cfg.leaf : 4, cfg.bins ? cfg.bins : 16);
    print_header();
    const uint32_t sizes[] = {10000, 100000, 1000000};
    for (size_t k = 0; k < SL_COUNTOF(sizes); k++) {
        if (cfg.quick && sizes[k] > 100000)
            continue;
        sl_aabb *boxes = random_boxes(sizes[k], 42 + k);
        if (!boxes) {
            fprintf(stderr, "bench_bvh_build: out of memory\n");
            return 1;
        }
        char name[64];
        snprintf(name, sizeof name, "random %uk", sizes[k] / 1000);
        bool ok = measure(name, boxes, sizes[k], &cfg);
        free(boxes);
        if (!ok)
            return 1;
    }
#if HAVE_GEN
    if (cfg.city) {
        const sl_city_preset presets[] = {SL_CITY_TINY, SL_CITY_SMALL, SL_CITY_VIENNA};
        for (size_t k = 0; k < SL_COUNTOF(presets); k++) {
            if (cfg.quick && presets[k] == SL_CITY_VIENNA)
                continue;
            sl_city_options co = sl_city_defaults(presets[k]);
            sl_scene scene;
            sl_error err;
            if (sl_gen_city(&co, NULL, &scene, &err) != SL_OK) {
                fprintf(stderr, "bench_bvh_build: city %s: %s\n", sl_city_preset_name(presets[k]), err.message);
                return 1;
            }
            char name[64];
            snprintf(name, sizeof name, "city %s", sl_city_preset_name(presets[k]));
            bool ok = measure(name, sl_scene_object_bounds_array(scene), sl_scene_object_count(scene), &cfg);
            sl_scene_destroy(scene);
            if (!ok)
                return 1;
        }
    }
#else
    if (cfg.city)
        printf("\n(city rows skipped: sightline/gen.h is not available in this build)\n");
#endif
    return 0;
}
