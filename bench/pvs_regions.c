/* Moving cars in precomputed visibility (issue 18 §2; docs/motion.md): the pvs culler with motion
 * regions (dynamic=regions) against dynamic=frustum, side by side in the same run, on a generated
 * city whose cars drive; and Instant Visibility (instant, its simulated clock with the drive's
 * frame time) on the same frames, which grows each car's box by how far it can move while a set
 * is displayed.
 *
 * The cells within --radius of a drive's cameras are baked with adjustable (so the bake stays
 * short), the cars animated at each frame (frame i at i / fps), and per frame both cullers run on
 * the same view. Reported: the bake (sets and region marks, wall seconds), the cars drawn per frame
 * by each mode, the cars the exact oracle sees (with --check: and that neither mode misses one),
 * and each mode's cull time (median over --runs runs of the per-run mean, thread CPU time of the
 * calling thread: instant's visibility thread is not in it).
 *
 *   bench_pvs_regions [--city tiny|small] [--frames N] [--speed M/S] [--runs N] [--check]
 */
#include "bench_common.h"

#include "sightline/bake.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "sightline/pvs.h"
#include "sightline/region.h"
#include "sightline/truth.h"

#include <time.h>

static double thread_cpu(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static bool has(const uint32_t *ids, uint32_t n, uint32_t id)
{
    uint32_t lo = 0, hi = n;
    while (lo < hi) {
        uint32_t m = (lo + hi) / 2;
        if (ids[m] < id)
            lo = m + 1;
        else
            hi = m;
    }
    return lo < n && ids[lo] == id;
}

int main(int argc, char **argv)
{
    const char *prog = "bench_pvs_regions", *city = "small";
    uint32_t frames = 300, runs = 5;
    float speed = 12, radius = 3;
    bool check = false;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--city") && i + 1 < argc)
            city = argv[++i];
        else if (!strcmp(argv[i], "--frames") && i + 1 < argc)
            frames = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(argv[i], "--speed") && i + 1 < argc)
            speed = (float)atof(argv[++i]);
        else if (!strcmp(argv[i], "--runs") && i + 1 < argc)
            runs = (uint32_t)atoi(argv[++i]);
        else if (!strcmp(argv[i], "--check"))
            check = true;
        else {
            fprintf(stderr, "usage: %s [--city tiny|small] [--frames N] [--speed M/S] [--runs N] [--check]\n", prog);
            return 2;
        }
    }
    if (frames == 0 || runs == 0 || !(speed > 0)) {
        fprintf(stderr, "%s: --frames, --runs and --speed must be positive\n", prog);
        return 2;
    }
    sl_error err;
    sl_city_options co = sl_city_defaults(!strcmp(city, "tiny") ? SL_CITY_TINY : SL_CITY_SMALL);
    sl_scene s;
    if (sl_gen_city(&co, NULL, &s, &err) != SL_OK)
        bench_die(prog, "city", &err);
    sl_path_options po = sl_path_options_default(SL_PATH_DRIVE);
    po.speed = speed;
    po.fps = 30;
    po.frames = frames;
    po.seed = 5;
    sl_path path;
    if (sl_path_generate(s, &po, NULL, &path, &err) != SL_OK)
        bench_die(prog, "path", &err);
    sl_viewcell_options vo = {0};
    sl_viewcells all, vc;
    if (sl_viewcells_from_streets(s, &vo, &all, &err) != SL_OK)
        bench_die(prog, "cells", &err);
    uint32_t nall = sl_viewcells_count(all), nk = 0;
    sl_viewcell *keep = malloc(((size_t)nall + 1) * sizeof *keep);
    for (uint32_t c = 0; c < nall; c++) {
        const sl_aabb *b = &sl_viewcells_data(all)[c].bounds;
        for (uint32_t i = 0; i < sl_path_count(path); i++) {
            sl_vec3 e = sl_path_camera(path, i).position;
            float dx = fmaxf(fmaxf(b->min.x - e.x, e.x - b->max.x), 0), dy = fmaxf(fmaxf(b->min.y - e.y, e.y - b->max.y), 0);
            if (dx * dx + dy * dy < radius * radius) {
                keep[nk++] = sl_viewcells_data(all)[c];
                break;
            }
        }
    }
    if (sl_viewcells_create(keep, nk, NULL, &vc, &err) != SL_OK)
        bench_die(prog, "cells", &err);
    free(keep);
    sl_viewcells_destroy(all);
    char file[128];
    snprintf(file, sizeof file, "/tmp/bench_pvs_regions_%d.slpvs", (int)getpid());
    sl_pvs_build_options bo;
    memset(&bo, 0, sizeof bo);
    bo.method = "adjustable";
    sl_pvs_build_stats bs;
    if (sl_pvs_build(s, vc, file, &bo, &bs, &err) != SL_OK)
        bench_die(prog, "bake", &err);
    enum { M = 3 };
    char opt[M][200];
    snprintf(opt[0], sizeof opt[0], "file=%s,dynamic=regions", file);
    snprintf(opt[1], sizeof opt[1], "file=%s,dynamic=frustum", file);
    snprintf(opt[2], sizeof opt[2], "t_frame=%.4f", 1000.0 / 30); /* the drive's frame time */
    const char *method[M] = {"pvs", "pvs", "instant"};
    sl_culler c[M];
    for (int m = 0; m < M; m++)
        if (sl_culler_create(method[m], s, opt[m], NULL, &c[m], &err) != SL_OK)
            bench_die(prog, "culler", &err);
    sl_oracle o = NULL;
    if (check && sl_oracle_create(s, NULL, NULL, &o, &err) != SL_OK)
        bench_die(prog, "oracle", &err);
    const uint32_t n = sl_scene_object_count(s), nf = sl_path_count(path);
    uint32_t *ids = malloc((size_t)n * sizeof *ids);
    uint64_t cars[M] = {0}, objects[M] = {0}, seen = 0, misses[M] = {0}, in_cells = 0;
    double *ms[M];
    for (int m = 0; m < M; m++)
        ms[m] = calloc(runs, sizeof(double));
    /* the oracle's sets of run 0's frames, for the second pass */
    uint32_t **vis = calloc(nf, sizeof *vis), *vis_n = calloc(nf, sizeof *vis_n);
    for (uint32_t r = 0; r < runs; r++) {
        double t[M] = {0};
        /* two passes over the frames: the pvs cullers, then instant (alone, so that its visibility
         * thread does not share the cores with the others' timing); instant restarts each run */
        for (int pass = 0; pass < 2; pass++) {
            if (pass == 1) {
                sl_culler_destroy(c[2]);
                if (sl_culler_create(method[2], s, opt[2], NULL, &c[2], &err) != SL_OK)
                    bench_die(prog, "culler", &err);
            }
            for (uint32_t i = 0; i < nf; i++) {
                if (sl_scene_animate(s, i / 30.0, &err) != SL_OK)
                    bench_die(prog, "animate", &err);
                sl_camera cam = sl_path_camera(path, i);
                if (r == 0 && pass == 0 && o) {
                    sl_oracle_frame fr = {0};
                    if (sl_oracle_render(o, &cam, &fr, &err) != SL_OK)
                        bench_die(prog, "oracle", &err);
                    vis_n[i] = fr.visible_count;
                    vis[i] = malloc(((size_t)fr.visible_count + 1) * sizeof **vis);
                    memcpy(vis[i], fr.visible, (size_t)fr.visible_count * sizeof **vis);
                    for (uint32_t v = 0; v < fr.visible_count; v++)
                        seen += (sl_scene_object(s, fr.visible[v]).flags & SL_OBJECT_DYNAMIC) != 0;
                }
                in_cells += r == 0 && pass == 0 && sl_viewcells_locate(vc, s, cam.position) != SL_NONE;
                for (int m = pass ? 2 : 0; m < (pass ? M : 2); m++) {
                    uint32_t cnt;
                    if (sl_culler_scene_changed(c[m], &err) != SL_OK)
                        bench_die(prog, "scene_changed", &err);
                    double t0 = thread_cpu();
                    if (sl_culler_cull(c[m], &cam, ids, n, &cnt, &err) != SL_OK)
                        bench_die(prog, "cull", &err);
                    t[m] += thread_cpu() - t0;
                    if (r)
                        continue;
                    objects[m] += cnt;
                    for (uint32_t q = 0; q < cnt; q++)
                        cars[m] += (sl_scene_object(s, ids[q]).flags & SL_OBJECT_DYNAMIC) != 0;
                    for (uint32_t v = 0; v < vis_n[i]; v++)
                        misses[m] += !has(ids, cnt, vis[i][v]);
                }
            }
        }
        for (int m = 0; m < M; m++)
            ms[m][r] = 1e3 * t[m] / nf;
    }
    for (uint32_t i = 0; i < nf; i++)
        free(vis[i]);
    free(vis);
    free(vis_n);
    char machine[256];
    bench_machine(machine, sizeof machine);
    printf("# %s\n", machine);
    printf("city %s, %u objects, %u with motion records; drive of %u frames at %.0f m/s, 30 fps; %u cells baked "
           "(within %.0f m of the drive), %llu frames in them\n",
           city, n, sl_scene_motion_count(s), nf, speed, nk, radius, (unsigned long long)in_cells);
    printf("bake (adjustable, %u threads): %.2f s, of which marking %u region nodes %.2f s\n", bs.threads, bs.seconds,
           bs.regions, bs.region_seconds);
    printf("| culler | cars drawn per frame | objects drawn per frame | cull ms per frame (median of %u) |%s\n", runs,
           check ? " misses |" : "");
    printf("|---|---:|---:|---:|%s\n", check ? "---:|" : "");
    const char *name[M] = {"pvs dynamic=regions", "pvs dynamic=frustum", "instant (simulated clock, t_frame 33.3 ms)"};
    for (int m = 0; m < M; m++) {
        printf("| %s | %.2f | %.2f | %.4f |", name[m], (double)cars[m] / nf, (double)objects[m] / nf,
               bench_median(ms[m], runs));
        if (check)
            printf(" %llu |", (unsigned long long)misses[m]);
        printf("\n");
    }
    if (check)
        printf("cars the oracle sees per frame: %.2f\n", (double)seen / nf);
    for (int m = 0; m < M; m++) {
        sl_culler_destroy(c[m]);
        free(ms[m]);
    }
    sl_oracle_destroy(o);
    free(ids);
    unlink(file);
    sl_path_destroy(path);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
    return check && (misses[0] || misses[1] || misses[2]) ? 1 : 0;
}
