/* Benchmark of the procedural city generator: for each preset, the median generation time of
 * N runs, the scene's counts and the peak resident memory, as Markdown table rows for
 * BENCHMARKS.md.
 *
 *   bench_gen_city [--preset tiny|small|vienna] [--runs N] [--vienna-runs N] [--seed S]
 *                  [--detail D] [--terrain]
 *
 * Presets run in increasing size. Peak memory is VmHWM from /proc/self/status, reset before each
 * preset through /proc/self/clear_refs when the kernel allows it (else it is the running peak,
 * which is still the figure of the largest preset so far). */
#include "sightline/gen.h"
#include "core/sl_core.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "bench_common.h"

static uint64_t peak_rss_kib(void)
{
    FILE *f = fopen("/proc/self/status", "r");
    if (!f)
        return 0;
    char line[256];
    uint64_t kb = 0;
    while (fgets(line, sizeof line, f))
        if (!strncmp(line, "VmHWM:", 6))
            kb = strtoull(line + 6, NULL, 10);
    fclose(f);
    return kb;
}

static bool reset_peak_rss(void)
{
    FILE *f = fopen("/proc/self/clear_refs", "w");
    if (!f)
        return false;
    bool ok = fputs("5", f) >= 0;
    return fclose(f) == 0 && ok;
}

static void usage(FILE *out)
{
    fprintf(out, "usage: bench_gen_city [--preset tiny|small|vienna] [--runs N] [--vienna-runs N] [--seed S]\n"
                 "                      [--detail D] [--terrain]\n"
                 "Median generation time, counts and peak memory of the city presets (all three by default;\n"
                 "--runs defaults to 3, --vienna-runs to --runs).\n");
}

int main(int argc, char **argv)
{
    int only = -1, runs = 3, vienna_runs = -1, detail = -1;
    uint64_t seed = 1;
    bool terrain = false;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            usage(stdout);
            return 0;
        } else if (!strcmp(a, "--preset") && v) {
            sl_city_preset p;
            sl_error err;
            if (sl_city_preset_from_name(v, &p, &err) != SL_OK) {
                fprintf(stderr, "bench_gen_city: %s\n", err.message);
                return 2;
            }
            only = (int)p, i++;
        } else if (!strcmp(a, "--runs") && v) {
            runs = atoi(v), i++;
        } else if (!strcmp(a, "--vienna-runs") && v) {
            vienna_runs = atoi(v), i++;
        } else if (!strcmp(a, "--seed") && v) {
            seed = strtoull(v, NULL, 10), i++;
        } else if (!strcmp(a, "--detail") && v) {
            detail = atoi(v), i++;
        } else if (!strcmp(a, "--terrain")) {
            terrain = true;
        } else {
            usage(stderr);
            return 2;
        }
    }
    if (runs < 1 || runs > 100) {
        fprintf(stderr, "bench_gen_city: --runs must be 1..100\n");
        return 2;
    }
    if (vienna_runs < 0)
        vienna_runs = runs;

    char cpu[256];
    bench_cpu_model(cpu, sizeof cpu);
    printf("machine: %ld cores (nproc), %s\n\n", sysconf(_SC_NPROCESSORS_ONLN), cpu);
    printf("| preset | seed | detail | terrain | runs | median s | min s | triangles | objects | buildings | blocks | "
           "footprints | street polygons | peak RSS MiB |\n");
    printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (int p = 0; p < 3; p++) {
        if (only >= 0 && p != only)
            continue;
        sl_city_options o = sl_city_defaults((sl_city_preset)p);
        o.seed = seed;
        if (detail >= 0)
            o.detail = (uint32_t)detail;
        if (terrain)
            o.terrain = true;
        int n = p == SL_CITY_VIENNA ? vienna_runs : runs;
        if (n < 1)
            continue;
        bool reset = reset_peak_rss();
        double times[100];
        sl_scene_stats stats;
        memset(&stats, 0, sizeof stats);
        const char *blocks = "?", *buildings = "?";
        char bbuf[32] = "?", hbuf[32] = "?";
        for (int r = 0; r < n; r++) {
            sl_scene scene = NULL;
            sl_error err;
            double t0 = sl_now();
            if (sl_gen_city(&o, NULL, &scene, &err) != SL_OK) {
                fprintf(stderr, "bench_gen_city: %s: %s\n", sl_city_preset_name((sl_city_preset)p), err.message);
                return 1;
            }
            times[r] = sl_now() - t0;
            if (r == n - 1) {
                sl_scene_get_stats(scene, &stats);
                blocks = sl_scene_meta(scene, "city.blocks");
                buildings = sl_scene_meta(scene, "city.buildings");
                snprintf(bbuf, sizeof bbuf, "%s", blocks ? blocks : "?");
                snprintf(hbuf, sizeof hbuf, "%s", buildings ? buildings : "?");
            }
            sl_scene_destroy(scene);
        }
        qsort(times, (size_t)n, sizeof times[0], bench_cmp_double);
        double median = n % 2 ? times[n / 2] : 0.5 * (times[n / 2 - 1] + times[n / 2]);
        printf("| %s | %llu | %u | %s | %d | %.3f | %.3f | %llu | %u | %s | %s | %u | %u | %.0f%s |\n",
               sl_city_preset_name((sl_city_preset)p), (unsigned long long)seed, o.detail, o.terrain ? "on" : "off", n,
               median, times[0], (unsigned long long)stats.instanced_triangle_count, stats.object_count, hbuf, bbuf,
               stats.footprint_count, stats.street_polygon_count, (double)peak_rss_kib() / 1024.0,
               reset ? "" : " (running peak)");
        fflush(stdout);
    }
    return 0;
}
