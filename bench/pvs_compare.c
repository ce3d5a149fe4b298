/* Several PVS methods on the same cells, against one region oracle (BENCHMARKS.md, "From-region
 * methods, second round: extproj").
 *
 *   bench_pvs_compare [--preset tiny|small|vienna] [--cell-size M] [--methods a,b,c] [--sample N]
 *                     [--face F] [--seed S] [--no-verify] [--part K/N]
 *
 * N street cells chosen at random (the same cells as bench_pvs_bake with the same --seed and
 * --sample), each baked by every method on one thread (thread CPU time per cell: median and mean)
 * and judged by the region oracle once (face size F): per method the mean fraction culled, the
 * objects per cell, the over-estimation against the oracle and the missed objects (must be 0 for a
 * conservative method; each miss is printed). Methods take their default options. Every cell's
 * figures are printed as it is done ("CELL index cell oracle method count seconds misses ..."),
 * so that --part K/N (only the sampled cells i with i % N == K: N processes share a sample) and
 * an interrupted run still give every figure; the table covers the cells this process did. */
#include "core/sl_core.h"
#include "region/pvs_internal.h"
#include "sightline/gen.h"
#include "sightline/pvs.h"
#include "sightline/region.h"

#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include "bench_common.h"

#define MAX_METHODS 8

static double thread_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv)
{
    const char *preset = "small";
    char methods[256] = "sample,adjustable,extproj";
    float cell_size = 12;
    uint32_t sample = 200, face = 192;
    uint64_t seed = 1;
    bool verify = true;
    uint32_t part_k = 0, part_n = 1;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--preset") && v)
            preset = v, i++;
        else if (!strcmp(a, "--cell-size") && v)
            cell_size = strtof(v, NULL), i++;
        else if (!strcmp(a, "--methods") && v)
            snprintf(methods, sizeof methods, "%s", v), i++;
        else if (!strcmp(a, "--sample") && v)
            sample = (uint32_t)strtoul(v, NULL, 10), i++;
        else if (!strcmp(a, "--face") && v)
            face = (uint32_t)strtoul(v, NULL, 10), i++;
        else if (!strcmp(a, "--seed") && v)
            seed = strtoull(v, NULL, 10), i++;
        else if (!strcmp(a, "--no-verify"))
            verify = false;
        else if (!strcmp(a, "--part") && v && sscanf(v, "%u/%u", &part_k, &part_n) == 2 && part_n > 0 &&
                 part_k < part_n)
            i++;
        else {
            fprintf(stderr, "usage: %s [--preset P] [--cell-size M] [--methods a,b,c] [--sample N] [--face F] "
                            "[--seed S] [--no-verify] [--part K/N]\n",
                    argv[0]);
            return 2;
        }
    }
    const char *name[MAX_METHODS];
    uint32_t nm = 0;
    for (char *tok = strtok(methods, ","); tok && nm < MAX_METHODS; tok = strtok(NULL, ","))
        name[nm++] = tok;
    sl_error err;
    sl_city_preset p;
    if (nm == 0 || sl_city_preset_from_name(preset, &p, &err) != SL_OK) {
        fprintf(stderr, "%s\n", nm == 0 ? "no methods" : err.message);
        return 2;
    }
    char cpu[256];
    bench_cpu_model(cpu, sizeof cpu);
    printf("machine: %ld cores, %s\n", sysconf(_SC_NPROCESSORS_ONLN), cpu);
    sl_city_options co = sl_city_defaults(p);
    sl_scene scene;
    if (sl_gen_city(&co, NULL, &scene, &err) != SL_OK) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    sl_viewcell_options vo = {0};
    vo.max_edge = cell_size;
    sl_viewcells cells;
    if (sl_viewcells_from_streets(scene, &vo, &cells, &err) != SL_OK) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    uint32_t nc = sl_viewcells_count(cells), no = sl_scene_object_count(scene);
    printf("city %s: %u objects, %u footprints; %u street cells (max edge %g m); %u random cells (seed %llu)\n",
           preset, no, sl_scene_footprint_count(scene), nc, (double)cell_size, sample, (unsigned long long)seed);
    /* the same pick as bench_pvs_bake */
    if (sample > nc)
        sample = nc;
    uint32_t *pick = malloc((size_t)nc * sizeof *pick);
    for (uint32_t i = 0; i < nc; i++)
        pick[i] = i;
    sl_rng r;
    sl_rng_seed(&r, seed, 7);
    for (uint32_t i = 0; i < sample; i++) {
        uint32_t j = i + sl_rng_below(&r, nc - i), t = pick[i];
        pick[i] = pick[j];
        pick[j] = t;
    }
    sl_bake bake[MAX_METHODS];
    void *worker[MAX_METHODS];
    double *secs[MAX_METHODS], prep[MAX_METHODS], culled[MAX_METHODS] = {0};
    uint64_t kept[MAX_METHODS] = {0}, miss[MAX_METHODS] = {0};
    uint32_t *sets[MAX_METHODS], counts[MAX_METHODS];
    for (uint32_t m = 0; m < nm; m++) {
        sl_pvs_build_options bo;
        memset(&bo, 0, sizeof bo);
        bo.method = name[m];
        double p0 = sl_now();
        if (sl_bake_begin(&bake[m], scene, cells, NULL, &bo, false, &err) != SL_OK ||
            bake[m].method->worker_create(bake[m].shared, &worker[m], &err) != SL_OK) {
            fprintf(stderr, "%s: %s\n", name[m], err.message);
            return 1;
        }
        prep[m] = sl_now() - p0;
        secs[m] = malloc((size_t)sample * sizeof(double));
        sets[m] = malloc(((size_t)no + 1) * sizeof(uint32_t));
    }
    sl_region_oracle ro = NULL;
    sl_region_oracle_options oo = {0};
    oo.face_size = face;
    oo.seed = seed;
    if (verify && sl_region_oracle_create(scene, &oo, NULL, &ro, &err) != SL_OK) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    uint64_t oracle_total = 0;
    uint32_t done = 0;
    double o0 = sl_now();
    for (uint32_t i = 0; i < sample; i++) {
        if (i % part_n != part_k)
            continue;
        for (uint32_t m = 0; m < nm; m++) {
            sl_pvs_cell_result res = {sets[m], 0, 0};
            double c0 = thread_seconds();
            if (bake[m].method->cell(worker[m], pick[i], &res, &err) != SL_OK) {
                fprintf(stderr, "%s, cell %u: %s\n", name[m], pick[i], err.message);
                return 1;
            }
            secs[m][done] = thread_seconds() - c0;
            counts[m] = res.count;
            kept[m] += res.count;
            culled[m] += 1.0 - (double)res.count / no;
        }
        done++;
        uint64_t cmiss[MAX_METHODS] = {0};
        sl_region_visibility v = {0};
        if (!ro) {
            printf("CELL %u %u -", i, pick[i]);
            for (uint32_t m = 0; m < nm; m++)
                printf(" %s %u %.6f -", name[m], counts[m], secs[m][done - 1]);
            printf("\n");
            fflush(stdout);
            continue;
        }
        if (sl_region_oracle_cell(ro, cells, pick[i], &v, &err) != SL_OK) {
            fprintf(stderr, "%s\n", err.message);
            return 1;
        }
        oracle_total += v.visible_count;
        for (uint32_t m = 0; m < nm; m++)
            for (uint32_t q = 0, k = 0; q < v.visible_count; q++) {
                while (k < counts[m] && sets[m][k] < v.visible[q])
                    k++;
                if (k >= counts[m] || sets[m][k] != v.visible[q]) {
                    miss[m]++;
                    cmiss[m]++;
                    printf("MISS: %s cell %u object %u (%u pixels)\n", name[m], pick[i], v.visible[q],
                           v.max_pixels[q]);
                }
            }
        printf("CELL %u %u %u", i, pick[i], v.visible_count);
        for (uint32_t m = 0; m < nm; m++)
            printf(" %s %u %.6f %llu", name[m], counts[m], secs[m][done - 1], (unsigned long long)cmiss[m]);
        printf("\n");
        fflush(stdout);
    }
    double wall = sl_now() - o0;
    sample = done;
    printf("| method | culled (mean) | objects per cell | over the oracle | CPU s per cell (median / mean) | "
           "prepare s | misses |\n|---|---|---|---|---|---|---|\n");
    for (uint32_t m = 0; m < nm; m++) {
        double sum = 0;
        for (uint32_t i = 0; i < sample; i++)
            sum += secs[m][i];
        qsort(secs[m], sample, sizeof(double), bench_cmp_double);
        char ov[32] = "-", ms[32] = "not verified";
        if (ro) {
            snprintf(ov, sizeof ov, "%.2fx", oracle_total ? (double)kept[m] / oracle_total : 0);
            snprintf(ms, sizeof ms, "%llu", (unsigned long long)miss[m]);
        }
        printf("| %s | %.2f%% | %.1f | %s | %.4f / %.4f | %.2f | %s |\n", name[m], 100 * culled[m] / sample,
               (double)kept[m] / sample, ov, secs[m][sample / 2], sum / sample, prep[m], ms);
    }
    if (ro)
        printf("region oracle (face %u): %.1f objects per cell; %u cells in %.0f s wall in all\n", face,
               (double)oracle_total / sample, sample, wall);
    for (uint32_t m = 0; m < nm; m++) {
        bake[m].method->worker_destroy(worker[m]);
        sl_bake_end(&bake[m]);
        free(secs[m]), free(sets[m]);
    }
    if (ro)
        sl_region_oracle_destroy(ro);
    free(pick);
    sl_viewcells_destroy(cells);
    sl_scene_destroy(scene);
    return 0;
}
