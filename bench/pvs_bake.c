/* Benchmark of PVS baking on the generated cities (BENCHMARKS.md, "From-region visibility").
 *
 *   bench_pvs_bake [--preset tiny|small|vienna|oldtown|oldtown-small] [--cell-size M] [--method NAME] [--options K=V,...]
 *                  [--sample N] [--threads T] [--verify N] [--face F] [--full OUT.slpvs] [--seed S]
 *
 * Street view cells of the city (max edge --cell-size), then either
 *  - --sample N (default 200): N cells chosen at random are baked one by one on one thread; the
 *    report gives thread CPU seconds per cell (median, mean, p95), the projected bake time on T threads
 *    (mean x cells / T), the mean fraction culled and the mean set size, and the projected file
 *    size (the sampled sets delta-coded and zstd-compressed in blocks of 32, scaled to all cells);
 *    --verify N holds the first N sampled cells to the region oracle (face size --face) and
 *    reports missed objects (must be 0 for a conservative method) and the over-estimation;
 *  - --oracle-only: no bake, the region oracle's visible fraction on the --sample cells (face --face);
 *  - --full OUT: the whole bake on T threads (sl_pvs_build), with its real time and file size.
 * The machine: `nproc` and the CPU model are printed with the results. */
#include "core/sl_core.h"
#include "region/pvs_internal.h"
#include "sightline/gen.h"
#include "sightline/bake.h"
#include "sightline/pvs.h"
#include "sightline/region.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include <unistd.h>
#include "bench_common.h"

/* CPU time of the calling thread: the machine is shared, wall time is not a fair per-cell cost. */
static double thread_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv)
{
    const char *preset = "small", *method = "sample", *options = NULL, *full = NULL;
    float cell_size = 12;
    uint32_t sample = 200, threads = 2, verify = 0, face = 256;
    bool oracle_only = false;
    uint64_t seed = 1;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--preset") && v)
            preset = v, i++;
        else if (!strcmp(a, "--cell-size") && v)
            cell_size = strtof(v, NULL), i++;
        else if (!strcmp(a, "--method") && v)
            method = v, i++;
        else if (!strcmp(a, "--options") && v)
            options = v, i++;
        else if (!strcmp(a, "--sample") && v)
            sample = (uint32_t)strtoul(v, NULL, 10), i++;
        else if (!strcmp(a, "--threads") && v)
            threads = (uint32_t)strtoul(v, NULL, 10), i++;
        else if (!strcmp(a, "--verify") && v)
            verify = (uint32_t)strtoul(v, NULL, 10), i++;
        else if (!strcmp(a, "--face") && v)
            face = (uint32_t)strtoul(v, NULL, 10), i++;
        else if (!strcmp(a, "--full") && v)
            full = v, i++;
        else if (!strcmp(a, "--seed") && v)
            seed = strtoull(v, NULL, 10), i++;
        else if (!strcmp(a, "--oracle-only"))
            oracle_only = true;
        else {
            fprintf(stderr, "usage: %s [--preset P] [--cell-size M] [--method M] [--options O] [--sample N] "
                            "[--threads T] [--verify N] [--face F] [--full OUT] [--seed S] [--oracle-only]\n",
                    argv[0]);
            return 2;
        }
    }
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
    double t0 = sl_now();
    sl_scene scene;
    if (sl_gen_city(&co, NULL, &scene, &err) != SL_OK) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    double t1 = sl_now();
    sl_viewcell_options vo = {0};
    vo.max_edge = cell_size;
    sl_viewcells cells;
    if (sl_viewcells_from_streets(scene, &vo, &cells, &err) != SL_OK) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    double t2 = sl_now();
    uint32_t nc = sl_viewcells_count(cells), no = sl_scene_object_count(scene);
    sl_viewcells_stats vs;
    sl_viewcells_get_stats(cells, &vs);
    printf("city %s: %u objects, %u footprints; generated in %.2f s\n", preset, no, sl_scene_footprint_count(scene),
           t1 - t0);
    printf("street cells (max edge %g m): %u cells over %.0f m^2 in %.2f s\n", (double)cell_size, nc, vs.area, t2 - t1);

    if (full) {
        sl_pvs_build_options bo;
        memset(&bo, 0, sizeof bo);
        bo.method = method;
        bo.method_options = options;
        bo.threads = threads;
        sl_pvs_build_stats st;
        unlink(full);
        char ck[1024];
        snprintf(ck, sizeof ck, "%s.ckpt", full);
        unlink(ck);
        if (sl_pvs_build(scene, cells, full, &bo, &st, &err) != SL_OK) {
            fprintf(stderr, "%s\n", err.message);
            return 1;
        }
        printf("full bake, %s (%s), %u threads: %.1f s wall (%.4f s per cell per thread), %.3f MB, mean culled "
               "%.4f%%, mean visible %.1f\n",
               st.method, st.options, st.threads, st.seconds, st.cell_seconds / st.cells, st.file_bytes / 1e6,
               100 * st.mean_culled, (double)st.visible_total / st.cells);
        if (st.notice[0])
            printf("notice: %s\n", st.notice);
    } else {
        /* a random sample of cells, baked one by one */
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
        if (oracle_only) {
            /* no bake: the region oracle's visible set on the sampled cells (a lower bound of the
             * exact from-region set, so 1 - its fraction bounds what any conservative method culls) */
            sl_region_oracle_options oo = {0};
            oo.face_size = face;
            oo.seed = seed;
            sl_region_oracle ro;
            if (sl_region_oracle_create(scene, &oo, NULL, &ro, &err) != SL_OK) {
                fprintf(stderr, "%s\n", err.message);
                return 1;
            }
            double o0 = sl_now(), frac = 0, fmax = 0;
            uint64_t total = 0;
            for (uint32_t i = 0; i < sample; i++) {
                sl_region_visibility v;
                if (sl_region_oracle_cell(ro, cells, pick[i], &v, &err) != SL_OK) {
                    fprintf(stderr, "%s\n", err.message);
                    return 1;
                }
                double f = (double)v.visible_count / no;
                frac += f, fmax = f > fmax ? f : fmax;
                total += v.visible_count;
            }
            printf("region oracle only on %u random cells (seed %llu, face %u, %.1f s): mean visible %.1f objects, "
                   "mean visible fraction %.4f%% (max %.4f%%), so at most %.4f%% culled on average\n",
                   sample, (unsigned long long)seed, face, sl_now() - o0, (double)total / sample, 100 * frac / sample,
                   100 * fmax, 100 * (1 - frac / sample));
            sl_region_oracle_destroy(ro);
            free(pick);
            sl_viewcells_destroy(cells);
            sl_scene_destroy(scene);
            return 0;
        }
        sl_pvs_build_options bo;
        memset(&bo, 0, sizeof bo);
        bo.method = method;
        bo.method_options = options;
        sl_bake b;
        double p0 = sl_now();
        if (sl_bake_begin(&b, scene, cells, NULL, &bo, false, &err) != SL_OK) {
            fprintf(stderr, "%s\n", err.message);
            return 1;
        }
        double prep = sl_now() - p0;
        void *w;
        if (b.method->worker_create(b.shared, &w, &err) != SL_OK) {
            fprintf(stderr, "%s\n", err.message);
            return 1;
        }
        uint32_t *ids = malloc(((size_t)no + 1) * sizeof *ids);
        double *secs = malloc((size_t)sample * sizeof *secs);
        uint64_t *off = malloc(((size_t)sample + 1) * sizeof *off);
        uint32_t *all = malloc((size_t)sample * (no + 1) * sizeof *all);
        double culled = 0;
        off[0] = 0;
        for (uint32_t i = 0; i < sample; i++) {
            sl_pvs_cell_result res = {ids, 0, 0};
            double c0 = thread_seconds();
            if (b.method->cell(w, pick[i], &res, &err) != SL_OK) {
                fprintf(stderr, "cell %u: %s\n", pick[i], err.message);
                return 1;
            }
            secs[i] = thread_seconds() - c0;
            culled += 1.0 - (double)res.count / no;
            memcpy(all + off[i], ids, res.count * sizeof *ids);
            off[i + 1] = off[i] + res.count;
        }
        /* the sampled sets as a file of `sample` cells: its size per cell, scaled */
        sl_viewcell *sub = malloc((size_t)sample * sizeof *sub);
        for (uint32_t i = 0; i < sample; i++)
            sub[i] = sl_viewcells_data(cells)[pick[i]];
        sl_viewcells subc;
        sl_viewcells_create(sub, sample, NULL, &subc, &err);
        char tmp[] = "/tmp/bench_pvs_XXXXXX";
        int fd = mkstemp(tmp);
        if (fd >= 0)
            close(fd);
        double bytes_per_cell = 0;
        if (sl_pvs_write(tmp, subc, no, 0, off, all, NULL, &err) == SL_OK) {
            sl_pvs pv;
            if (sl_pvs_load(tmp, NULL, &pv, &err) == SL_OK) {
                sl_pvs_info in;
                sl_pvs_get_info(pv, &in);
                bytes_per_cell = (double)in.file_size / sample;
                sl_pvs_destroy(pv);
            }
        }
        unlink(tmp);
        double sum = 0;
        for (uint32_t i = 0; i < sample; i++)
            sum += secs[i];
        qsort(secs, sample, sizeof *secs, bench_cmp_double);
        double mean = sum / sample;
        printf("method %s (%s): prepare %.2f s; %u random cells on 1 thread (CPU time): median %.4f s, "
               "mean %.4f s, p95 %.4f s, "
               "max %.4f s per cell\n",
               b.method->name, b.effective, prep, sample, secs[sample / 2], mean,
               secs[(uint32_t)ceil(0.95 * sample) - 1], secs[sample - 1]);
        printf("projected: whole bake of %u cells on %u threads %.1f min; file %.2f MB (%.0f bytes per cell); mean "
               "culled %.4f%%, mean visible %.1f\n",
               nc, threads, mean * nc / threads / 60, bytes_per_cell * nc / 1e6, bytes_per_cell, 100 * culled / sample,
               (double)off[sample] / sample);
        if (verify) {
            sl_region_oracle_options oo = {0};
            oo.face_size = face;
            oo.seed = seed;
            sl_region_oracle ro;
            if (sl_region_oracle_create(scene, &oo, NULL, &ro, &err) != SL_OK) {
                fprintf(stderr, "%s\n", err.message);
                return 1;
            }
            uint64_t miss = 0, ov = 0, pv = 0, added = 0, kind_pvs[SL_KIND_COUNT] = {0}, kind_or[SL_KIND_COUNT] = {0};
            double o0 = sl_now();
            if (verify > sample)
                verify = sample;
            for (uint32_t i = 0; i < verify; i++) {
                sl_region_visibility v;
                if (sl_region_oracle_cell(ro, cells, pick[i], &v, &err) != SL_OK) {
                    fprintf(stderr, "%s\n", err.message);
                    return 1;
                }
                const uint32_t *set = all + off[i];
                uint32_t n = (uint32_t)(off[i + 1] - off[i]), k = 0;
                for (uint32_t q = 0; q < v.visible_count; q++) {
                    while (k < n && set[k] < v.visible[q])
                        k++;
                    if (k >= n || set[k] != v.visible[q]) {
                        miss++;
                        printf("MISS: cell %u object %u (%u pixels)\n", pick[i], v.visible[q], v.max_pixels[q]);
                    }
                }
                for (uint32_t q = 0; q < v.visible_count; q++)
                    kind_or[sl_scene_object(scene, v.visible[q]).kind % SL_KIND_COUNT]++;
                for (uint32_t q = 0; q < n; q++)
                    kind_pvs[sl_scene_object(scene, set[q]).kind % SL_KIND_COUNT]++;
                ov += v.visible_count;
                pv += n;
                added += v.added_last_tenth;
            }
            printf("region oracle on %u cells (face %u, %.1f s): %llu missed objects; oracle %.1f, PVS %.1f objects "
                   "per cell (over-estimation %.2fx); %.2f objects first seen in the last 10%% of samples; oracle "
                   "visible fraction %.4f%%\n",
                   verify, face, sl_now() - o0, (unsigned long long)miss, (double)ov / verify, (double)pv / verify,
                   ov ? (double)pv / ov : 0, (double)added / verify, 100.0 * (double)ov / verify / no);
            /* where the over-estimation lies: objects per cell by kind, PVS against the oracle */
            printf("per kind, objects per cell (PVS / oracle):");
            for (uint32_t kd = 0; kd < SL_KIND_COUNT; kd++)
                if (kind_pvs[kd] || kind_or[kd])
                    printf(" %s %.1f / %.1f;", sl_object_kind_name(kd), (double)kind_pvs[kd] / verify,
                           (double)kind_or[kd] / verify);
            printf("\n");
            sl_region_oracle_destroy(ro);
        }
        b.method->worker_destroy(w);
        sl_bake_end(&b);
        sl_viewcells_destroy(subc);
        free(sub), free(all), free(off), free(secs), free(ids), free(pick);
    }
    sl_viewcells_destroy(cells);
    sl_scene_destroy(scene);
    return 0;
}
