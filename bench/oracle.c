/* bench_oracle: what the exact point oracle costs per frame on street-level views of the generated
 * cities, with view-frustum culling (vfc) timed on the same cameras for scale.
 *
 * For each preset (default: tiny, small, vienna; seed 1) the city is generated and a walk along its
 * streets is sampled every 28 m (sl_path_generate walk at 0.05 fps: eye 1.7 m above the ground,
 * looking along the street, which is the typical and the expensive street-level view). Each view
 * is rendered by the oracle at 1024x768 with 2 threads; the wall time of sl_oracle_render (median,
 * nearest-rank 95th percentile, max), the CPU time of all threads together, the exact visible set
 * and the time of one vfc cull are reported, as Markdown rows and then one machine line.
 *
 * usage: bench_oracle [--views N] [--threads T] [--width W --height H] [--seed S] [PRESET...]
 */
#include "core/sl_core.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "sightline/truth.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include "bench_common.h"

static double cpu_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec * 1e3 + (double)ts.tv_nsec * 1e-6;
}

static int fail(const char *what, const sl_error *err)
{
    fprintf(stderr, "bench_oracle: %s: %s\n", what, err->message);
    return 1;
}

int main(int argc, char **argv)
{
    uint32_t views = 15, threads = 2, width = 1024, height = 768;
    uint64_t seed = 1;
    const char *presets[8];
    int np = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (i + 1 < argc && !strcmp(a, "--views"))
            views = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (i + 1 < argc && !strcmp(a, "--threads"))
            threads = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (i + 1 < argc && !strcmp(a, "--width"))
            width = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (i + 1 < argc && !strcmp(a, "--height"))
            height = (uint32_t)strtoul(argv[++i], NULL, 10);
        else if (i + 1 < argc && !strcmp(a, "--seed"))
            seed = strtoull(argv[++i], NULL, 10);
        else if (a[0] != '-' && np < 8)
            presets[np++] = a;
        else {
            fprintf(stderr, "usage: bench_oracle [--views N] [--threads T] [--width W --height H] [--seed S] "
                            "[tiny|small|vienna ...]\n");
            return 2;
        }
    }
    if (!np) {
        presets[0] = "tiny", presets[1] = "small", presets[2] = "vienna";
        np = 3;
    }
    if (!views || !threads || !width || !height) {
        fprintf(stderr, "bench_oracle: --views, --threads, --width and --height must be positive\n");
        return 2;
    }
    char mach[320];
    bench_machine(mach, sizeof mach);
    printf("oracle cost on street-level views (walk sampled every 28 m, eye 1.7 m), %ux%u, %u threads, "
           "%u views per city, seed %llu\n",
           width, height, threads, views, (unsigned long long)seed);
    printf("machine at start: %s\n\n", mach);
    printf("| city | objects | triangles | views | oracle median | p95 | max | CPU median | visible objects (mean) | "
           "triangles in frustum (mean) | vfc median | vfc objects (mean) |\n");
    printf("|---|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|\n");
    fflush(stdout);
    sl_error err;
    for (int p = 0; p < np; p++) {
        sl_city_preset preset;
        if (sl_city_preset_from_name(presets[p], &preset, &err) != SL_OK)
            return fail(presets[p], &err);
        sl_city_options co = sl_city_defaults(preset);
        co.seed = seed;
        sl_scene s;
        double t0 = sl_now();
        if (sl_gen_city(&co, NULL, &s, &err) != SL_OK)
            return fail("gen", &err);
        double gen_s = sl_now() - t0;
        sl_scene_stats st;
        sl_scene_get_stats(s, &st);
        sl_path_options po = sl_path_options_default(SL_PATH_WALK);
        po.frames = views;
        po.fps = 0.05f; /* 1.4 m/s: 28 m between views */
        po.seed = seed;
        po.intrinsics.width = width;
        po.intrinsics.height = height;
        sl_path walk;
        if (sl_path_generate(s, &po, NULL, &walk, &err) != SL_OK)
            return fail("walk", &err);
        sl_oracle_options oo = sl_oracle_default_options();
        oo.threads = threads;
        sl_oracle o;
        sl_culler vfc;
        if (sl_oracle_create(s, &oo, NULL, &o, &err) != SL_OK)
            return fail("oracle", &err);
        if (sl_culler_create("vfc", s, NULL, NULL, &vfc, &err) != SL_OK)
            return fail("vfc", &err);
        uint32_t n = sl_scene_object_count(s);
        uint32_t *ids = malloc((n ? n : 1) * sizeof *ids);
        double *wall = malloc(views * sizeof *wall), *cpu = malloc(views * sizeof *cpu);
        double *vms = malloc(views * sizeof *vms);
        double vis = 0, tri = 0, vobj = 0;
        for (uint32_t v = 0; v < views; v++) {
            sl_camera cam = sl_path_camera(walk, v);
            sl_oracle_frame f;
            double c0 = cpu_ms();
            if (sl_oracle_render(o, &cam, &f, &err) != SL_OK)
                return fail("render", &err);
            cpu[v] = cpu_ms() - c0;
            wall[v] = f.ms;
            vis += f.visible_count;
            tri += (double)f.triangles_in_frustum;
            uint32_t k;
            if (sl_culler_cull(vfc, &cam, ids, n ? n : 1, &k, &err) != SL_OK)
                return fail("cull", &err);
            sl_cull_stats cs;
            sl_culler_stats(vfc, &cs);
            vms[v] = cs.total_ms;
            vobj += k;
        }
        sl_series_summary ws, cs, vs;
        sl_series_summarize(wall, views, NULL, &ws, NULL);
        sl_series_summarize(cpu, views, NULL, &cs, NULL);
        sl_series_summarize(vms, views, NULL, &vs, NULL);
        printf("| %s (gen %.1f s) | %u | %llu | %u | %.1f ms | %.1f ms | %.1f ms | %.1f ms | %.0f | %.0f | %.3f ms | %.0f |\n",
               presets[p], gen_s, st.object_count, (unsigned long long)st.instanced_triangle_count, views, ws.median,
               ws.p95, ws.max, cs.median, vis / views, tri / views, vs.median, vobj / views);
        fflush(stdout);
        free(ids);
        free(wall);
        free(cpu);
        free(vms);
        sl_culler_destroy(vfc);
        sl_oracle_destroy(o);
        sl_path_destroy(walk);
        sl_scene_destroy(s);
    }
    bench_machine(mach, sizeof mach);
    printf("\nmachine at end: %s\n", mach);
    return 0;
}
