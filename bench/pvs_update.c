/* Benchmark of updating a bake after an edit (BENCHMARKS.md, "Updating a bake").
 *
 *   bench_pvs_update [--preset vienna] [--method adjustable] [--every K] [--edits N] [--threads T]
 *                    [--seed S] [--cell-size M] [--dir DIR] [--grow F] [--tower F]
 *
 * The city's street cells (max edge --cell-size), every K-th of them (the full vienna bake takes
 * about 41 CPU minutes: a regular subset spread over the whole city keeps the fractions unbiased),
 * are baked for the city; then N edits (sl_city_edit, seeds S, S+1, ...: the buildings of a
 * 100 m x 100 m square around a building drawn by the seed removed, moved and given towers), each
 * updated from the old bake (sl_pvs_update) and baked in full, the two files compared byte for
 * byte. Reported per edit and as medians: the fraction of cells re-baked, the update's process CPU
 * time (all threads: probe, method preparation, re-bake and the rest) against the full bake's,
 * and both projected to all the city's cells (the fixed costs once, the per-cell costs scaled).
 * An edit that changes the view cells (refused by the update) is skipped and counted. */
#include "core/sl_core.h"
#include "sightline/bake.h"
#include "sightline/gen.h"
#include "sightline/pvs.h"
#include "sightline/region.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include <unistd.h>
#include "bench_common.h"

static double cpu_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, uint32_t n)
{
    if (!n)
        return NAN;
    qsort(v, n, sizeof *v, cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

static bool same_files(const char *a, const char *b)
{
    uint8_t *x = NULL, *y = NULL;
    size_t nx = 0, ny = 0;
    sl_error err;
    if (sl_file_read_all(sl_default_allocator(), a, &x, &nx, &err) != SL_OK ||
        sl_file_read_all(sl_default_allocator(), b, &y, &ny, &err) != SL_OK)
        return false;
    bool same = nx == ny && memcmp(x, y, nx) == 0;
    sl_free(sl_default_allocator(), x, nx);
    sl_free(sl_default_allocator(), y, ny);
    return same;
}

int main(int argc, char **argv)
{
    const char *preset = "vienna", *method = "adjustable", *dir = "/tmp";
    uint32_t every = 40, edits = 3, threads = 2;
    uint64_t seed = 1;
    float cell_size = 12, grow = 1, tower = 1;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--preset") && v)
            preset = v, i++;
        else if (!strcmp(a, "--method") && v)
            method = v, i++;
        else if (!strcmp(a, "--every") && v)
            every = (uint32_t)strtoul(v, NULL, 10), i++;
        else if (!strcmp(a, "--edits") && v)
            edits = (uint32_t)strtoul(v, NULL, 10), i++;
        else if (!strcmp(a, "--threads") && v)
            threads = (uint32_t)strtoul(v, NULL, 10), i++;
        else if (!strcmp(a, "--seed") && v)
            seed = strtoull(v, NULL, 10), i++;
        else if (!strcmp(a, "--cell-size") && v)
            cell_size = strtof(v, NULL), i++;
        else if (!strcmp(a, "--dir") && v)
            dir = v, i++;
        else if (!strcmp(a, "--grow") && v)
            grow = strtof(v, NULL), i++;
        else if (!strcmp(a, "--tower") && v)
            tower = strtof(v, NULL), i++;
        else {
            fprintf(stderr, "usage: %s [--preset P] [--method M] [--every K] [--edits N] [--threads T] [--seed S] "
                            "[--cell-size M] [--dir DIR] [--grow F] [--tower F]\n",
                    argv[0]);
            return 2;
        }
    }
    if (every < 1 || edits < 1 || edits > 100) {
        fprintf(stderr, "--every >= 1, --edits 1..100\n");
        return 2;
    }
    setvbuf(stdout, NULL, _IOLBF, 0); /* progress in a log file as it comes */
    sl_error err;
    sl_city_preset p;
    if (sl_city_preset_from_name(preset, &p, &err) != SL_OK) {
        fprintf(stderr, "%s\n", err.message);
        return 2;
    }
    char cpu[256];
    bench_cpu_model(cpu, sizeof cpu);
    printf("machine: %ld cores, %s\n", sysconf(_SC_NPROCESSORS_ONLN), cpu);
    sl_city_options co = sl_city_defaults(p);
    sl_scene olds = NULL;
    if (sl_gen_city(&co, NULL, &olds, &err) != SL_OK) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    sl_viewcell_options vo;
    memset(&vo, 0, sizeof vo);
    vo.max_edge = cell_size;
    sl_viewcells all = NULL, cells = NULL;
    if (sl_viewcells_from_streets(olds, &vo, &all, &err) != SL_OK) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    uint32_t nall = sl_viewcells_count(all), n = 0;
    sl_viewcell *keep = malloc(((size_t)nall + 1) * sizeof *keep);
    for (uint32_t c = 0; c < nall; c += every)
        keep[n++] = sl_viewcells_data(all)[c];
    if (sl_viewcells_create(keep, n, NULL, &cells, &err) != SL_OK) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    free(keep);
    printf("%s: %u objects, %u footprints; %u street cells (max edge %g m), every %u-th baked: %u cells; method %s, "
           "%u threads\n",
           preset, sl_scene_object_count(olds), sl_scene_footprint_count(olds), nall, (double)cell_size, every, n,
           method, threads);
    char old_path[512], upd_path[512], full_path[512];
    snprintf(old_path, sizeof old_path, "%s/bench_pvs_update_old.slpvs", dir);
    snprintf(upd_path, sizeof upd_path, "%s/bench_pvs_update_upd.slpvs", dir);
    snprintf(full_path, sizeof full_path, "%s/bench_pvs_update_full.slpvs", dir);
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    bo.method = method;
    bo.threads = threads;
    bo.fresh = true;
    sl_pvs_build_stats bs;
    double c0 = cpu_seconds();
    if (sl_pvs_build(olds, cells, old_path, &bo, &bs, &err) != SL_OK) {
        fprintf(stderr, "old bake: %s\n", err.message);
        return 1;
    }
    printf("old bake: %.1f s CPU, %.1f s wall, mean culled %.3f%%\n", cpu_seconds() - c0, bs.seconds,
           100 * bs.mean_culled);
    sl_pvs old = NULL;
    if (sl_pvs_load(old_path, NULL, &old, &err) != SL_OK) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    double frac[100], ratio[100], proj[100];
    uint32_t done = 0, refused = 0, identical = 0;
    printf("edits: move up to 1 m, heights x[1, %g], new buildings x%g their host's height\n", (double)grow,
           (double)tower);
    printf("%-6s %-8s %-8s %-8s %-7s %-9s %-7s %-7s %-9s %-9s %-9s %-9s %-8s %-10s %s\n", "seed", "removed", "moved",
           "added", "zone", "affected", "by set", "probe", "cells%", "upd CPU", "probe", "prepare", "full CPU", "upd/full", "projected/full");
    for (uint64_t s = seed; done < edits && s < seed + 4 * edits; s++) {
        sl_city_edit_options eo = sl_city_edit_defaults();
        eo.seed = s;
        eo.grow = grow;
        eo.tower = tower;
        sl_rng rng;
        sl_rng_seed(&rng, s, 77);
        /* a building drawn by the seed, well inside the city */
        uint32_t nf = sl_scene_footprint_count(olds), pick = sl_rng_below(&rng, nf);
        sl_footprint_view fv = sl_scene_footprint(olds, pick);
        float cx = fv.xy[0], cy = fv.xy[1];
        eo.region[0] = cx - 50, eo.region[1] = cy - 50, eo.region[2] = cx + 50, eo.region[3] = cy + 50;
        sl_scene news = NULL;
        sl_city_edit_stats es;
        if (sl_city_edit(olds, &eo, NULL, &news, &es, &err) != SL_OK) {
            fprintf(stderr, "edit: %s\n", err.message);
            return 1;
        }
        sl_pvs_update_options uo;
        memset(&uo, 0, sizeof uo);
        uo.threads = threads;
        sl_pvs_update_stats us;
        unlink(upd_path);
        char ckpt[600];
        snprintf(ckpt, sizeof ckpt, "%s.ckpt", upd_path);
        unlink(ckpt); /* left by an interrupted run */
        double u0 = cpu_seconds();
        sl_status st = sl_pvs_update(old, olds, news, cells, upd_path, &uo, &us, &err);
        double ucpu = cpu_seconds() - u0;
        if (st == SL_ERROR_INVALID_ARGUMENT && strstr(err.message, "view cells differ")) {
            printf("%-6llu edit changes the view cells: refused (%s)\n", (unsigned long long)s, err.message);
            refused++;
            sl_scene_destroy(news);
            continue;
        }
        if (st != SL_OK) {
            fprintf(stderr, "update: %s\n", err.message);
            return 1;
        }
        double f0 = cpu_seconds();
        if (sl_pvs_build(news, cells, full_path, &bo, &bs, &err) != SL_OK) {
            fprintf(stderr, "full bake: %s\n", err.message);
            return 1;
        }
        double fcpu = cpu_seconds() - f0;
        bool same = same_files(upd_path, full_path);
        identical += same;
        /* projected to every cell of the city: fixed parts once, per-cell parts scaled */
        double scale = (double)nall / n;
        double upd_fixed = ucpu - us.probe_cpu_seconds - us.bake_cpu_seconds;
        double upd_all = upd_fixed + scale * (us.probe_cpu_seconds + us.bake_cpu_seconds);
        double full_all = us.prepare_cpu_seconds + scale * (fcpu - us.prepare_cpu_seconds);
        frac[done] = (double)us.cells_affected / us.cells;
        ratio[done] = ucpu / fcpu;
        proj[done] = upd_all / full_all;
        printf("%-6llu %-8u %-8u %-8u %-7u %-9u %-7u %-7u %-9.2f %-9.2f %-9.2f %-9.2f %-8.2f %-10.4f %.4f%s\n",
               (unsigned long long)s, es.removed, es.moved, es.added, us.zone_footprints, us.cells_affected,
               us.cells_by_set, us.cells_by_probe,
               100 * frac[done], ucpu, us.probe_cpu_seconds, us.prepare_cpu_seconds, fcpu, ratio[done], proj[done],
               same ? "" : "  FILES DIFFER");
        done++;
        sl_scene_destroy(news);
    }
    printf("%u edits (%u refused: cells changed), %u byte-identical to the full bake\n", done, refused, identical);
    printf("median: %.2f%% of the cells re-baked; update CPU / full bake CPU %.4f on these %u cells, %.4f projected to "
           "all %u cells\n",
           100 * median(frac, done), median(ratio, done), n, median(proj, done), nall);
    unlink(old_path);
    unlink(upd_path);
    unlink(full_path);
    sl_pvs_destroy(old);
    sl_viewcells_destroy(cells);
    sl_viewcells_destroy(all);
    sl_scene_destroy(olds);
    return identical == done ? 0 : 1;
}
