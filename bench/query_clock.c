/* bench_query_clock: the query cullers (gl-stopwait, chc, chc++) against drawing the frustum set
 * (vfc) and the exact visible set, on the CPU reference backend's simulated clock (backend.h,
 * docs/query-culling.md): per frame, the simulated GPU time of the draws and queries (busy), the
 * simulated wait for query results, their sum (the frame's simulated time, frame pacing left out),
 * queries and stalls. Deterministic: the same figures on any machine. vfc's and the exact set are
 * drawn the way a renderer with multi-draw-indirect would draw them, one call per frame.
 *
 *   bench_query_clock [--preset tiny|small|vienna] [--seed S] [--frames N] [--fps F]
 *                     [--width W --height H] [--methods SPEC,...] [--no-exact]
 *
 * SPEC is name[:key=value[:key=value...]] (options separated by colons, as in the other bench
 * programs: chc:assume_visible=3:zpass=true). */
#include "bench_common.h"

#include "sightline/backend.h"
#include "sightline/gen.h"
#include "sightline/path.h"
#include "sightline/truth.h"

typedef struct row {
    const char *label;
    double busy, wait;   /* ns, summed over frames */
    uint64_t queries, stalls, drawn;
} row;

static void add_clock(row *r, sl_draw_backend_cpu cpu, const sl_draw_backend_cpu_stats *before)
{
    sl_draw_backend_cpu_stats st;
    sl_draw_backend_cpu_get_stats(cpu, &st);
    r->busy += st.busy_ns - before->busy_ns;
    r->wait += st.wait_ns - before->wait_ns;
}

/* Draw a set in one call, as a renderer would, on a clocked backend. */
static void draw_set(const char *prog, sl_draw_backend_cpu cpu, const sl_camera *cam, const uint32_t *ids, uint32_t n,
                     row *r)
{
    sl_draw_backend be = sl_draw_backend_cpu_table(cpu);
    sl_draw_backend_cpu_stats before;
    sl_draw_backend_cpu_get_stats(cpu, &before);
    sl_mat4 vp = sl_camera_view_proj(cam);
    sl_error err;
    if (be.begin_frame(be.user, vp.m, cam->width, cam->height, &err) != SL_OK ||
        be.draw_objects(be.user, ids, n, &err) != SL_OK || be.end_frame(be.user, &err) != SL_OK)
        bench_die(prog, "draw", &err);
    add_clock(r, cpu, &before);
    r->drawn += n;
}

int main(int argc, char **argv)
{
    const char *prog = "bench_query_clock", *preset = "small", *methods = "gl-stopwait,chc,chc++";
    uint32_t frames = 100, width = 1280, height = 720;
    uint64_t seed = 1;
    float fps = 30;
    bool exact = true;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--no-exact")) {
            exact = false;
            continue;
        }
        if (!v) {
            fprintf(stderr, "%s: %s needs a value (see the comment at the top of bench/query_clock.c)\n", prog, a);
            return 2;
        }
        i++;
        if (!strcmp(a, "--preset"))
            preset = v;
        else if (!strcmp(a, "--seed"))
            seed = strtoull(v, NULL, 10);
        else if (!strcmp(a, "--frames"))
            frames = (uint32_t)strtoul(v, NULL, 10);
        else if (!strcmp(a, "--fps"))
            fps = strtof(v, NULL);
        else if (!strcmp(a, "--width"))
            width = (uint32_t)strtoul(v, NULL, 10);
        else if (!strcmp(a, "--height"))
            height = (uint32_t)strtoul(v, NULL, 10);
        else if (!strcmp(a, "--methods"))
            methods = v;
        else {
            fprintf(stderr, "%s: unknown option %s\n", prog, a);
            return 2;
        }
    }
    sl_error err;
    sl_city_preset cp;
    if (sl_city_preset_from_name(preset, &cp, &err) != SL_OK)
        bench_die(prog, "--preset", &err);
    sl_city_options co = sl_city_defaults(cp);
    co.seed = seed;
    sl_scene s;
    if (sl_gen_city(&co, NULL, &s, &err) != SL_OK)
        bench_die(prog, "city", &err);
    sl_path_options po = sl_path_options_default(SL_PATH_WALK);
    po.frames = frames;
    po.fps = fps;
    po.seed = seed;
    po.intrinsics.width = width;
    po.intrinsics.height = height;
    sl_path walk;
    if (sl_path_generate(s, &po, NULL, &walk, &err) != SL_OK)
        bench_die(prog, "walk", &err);
    uint32_t n = sl_scene_object_count(s), *ids = malloc((size_t)n * sizeof *ids);
    sl_draw_backend_cpu_options clock = sl_draw_backend_cpu_clock_default();

    enum { MAXM = 16 };
    row rows[MAXM + 2];
    memset(rows, 0, sizeof rows);
    sl_culler cullers[MAXM];
    sl_draw_backend_cpu cpus[MAXM + 2];
    char names[1024];
    snprintf(names, sizeof names, "%s", methods);
    uint32_t nm = 0;
    for (char *save = NULL, *tok = strtok_r(names, ",", &save); tok && nm < MAXM; tok = strtok_r(NULL, ",", &save)) {
        char *opts = strchr(tok, ':');
        if (opts) {
            *opts++ = 0;
            for (char *c = opts; *c; c++)
                if (*c == ':')
                    *c = ','; /* name:key=value:key=value (the list itself is comma-separated) */
        }
        if (sl_draw_backend_cpu_create(s, &clock, NULL, &cpus[nm], &err) != SL_OK)
            bench_die(prog, "backend", &err);
        sl_draw_backend t = sl_draw_backend_cpu_table(cpus[nm]);
        sl_culler_params pa = {&t, NULL};
        if (sl_culler_create_with(tok, s, opts, &pa, NULL, &cullers[nm], &err) != SL_OK)
            bench_die(prog, tok, &err);
        static char labels[MAXM][160];
        snprintf(labels[nm], sizeof labels[nm], "%s%s%s", tok, opts ? " " : "", opts ? opts : "");
        rows[nm].label = labels[nm];
        nm++;
    }
    sl_culler vfc;
    if (sl_culler_create("vfc", s, NULL, NULL, &vfc, &err) != SL_OK)
        bench_die(prog, "vfc", &err);
    uint32_t iv = nm, ie = nm + 1;
    rows[iv].label = "vfc (its set in one draw call)";
    rows[ie].label = "exact visible set (one draw call)";
    for (uint32_t k = iv; k <= ie; k++)
        if (sl_draw_backend_cpu_create(s, &clock, NULL, &cpus[k], &err) != SL_OK)
            bench_die(prog, "backend", &err);
    sl_oracle o = NULL;
    if (exact && sl_oracle_create(s, NULL, NULL, &o, &err) != SL_OK)
        bench_die(prog, "oracle", &err);
    for (uint32_t f = 0; f < sl_path_count(walk); f++) {
        sl_camera cam = sl_path_camera(walk, f);
        for (uint32_t m = 0; m < nm; m++) {
            sl_draw_backend_cpu_stats before;
            sl_draw_backend_cpu_get_stats(cpus[m], &before);
            uint32_t k;
            if (sl_culler_cull(cullers[m], &cam, ids, n, &k, &err) != SL_OK)
                bench_die(prog, rows[m].label, &err);
            add_clock(&rows[m], cpus[m], &before);
            sl_cull_stats st;
            sl_culler_stats(cullers[m], &st);
            rows[m].queries += st.queries;
            rows[m].stalls += st.query_stalls;
            rows[m].drawn += k;
        }
        uint32_t k;
        if (sl_culler_cull(vfc, &cam, ids, n, &k, &err) != SL_OK)
            bench_die(prog, "vfc", &err);
        draw_set(prog, cpus[iv], &cam, ids, k, &rows[iv]);
        if (o) {
            sl_oracle_frame fr;
            if (sl_oracle_render(o, &cam, &fr, &err) != SL_OK)
                bench_die(prog, "oracle", &err);
            draw_set(prog, cpus[ie], &cam, fr.visible, fr.visible_count, &rows[ie]);
        }
    }
    char machine[256];
    bench_machine(machine, sizeof machine);
    double fc = (double)sl_path_count(walk);
    printf("city %s seed %llu, walk of %u frames at %.0f fps, %ux%u; clock: %.0f ns a call, %.1f ns a triangle, "
           "%.2f ns a fragment, %.0f us query latency (figures are simulated, machine-independent; %s)\n\n",
           preset, (unsigned long long)seed, frames, (double)fps, width, height, clock.ns_per_call,
           clock.ns_per_triangle, clock.ns_per_fragment, clock.query_latency_ns / 1000, machine);
    printf("| method | objects drawn / frame | queries / frame | stalls / frame | busy ms / frame | wait ms / frame "
           "| simulated frame ms | vs exact set |\n|---|--:|--:|--:|--:|--:|--:|--:|\n");
    double exact_ms = o ? (rows[ie].busy + rows[ie].wait) / fc * 1e-6 : 0;
    for (uint32_t m = 0; m <= ie; m++) {
        if (m == ie && !o)
            break;
        const row *r = &rows[m];
        double t = (r->busy + r->wait) / fc * 1e-6;
        printf("| %s | %.1f | %.1f | %.1f | %.3f | %.3f | %.3f | ", r->label, (double)r->drawn / fc,
               (double)r->queries / fc, (double)r->stalls / fc, r->busy / fc * 1e-6, r->wait / fc * 1e-6, t);
        if (o && exact_ms > 0)
            printf("%.2fx |\n", t / exact_ms);
        else
            printf("- |\n");
    }
    for (uint32_t m = 0; m < nm; m++)
        sl_culler_destroy(cullers[m]);
    for (uint32_t m = 0; m < nm; m++)
        sl_draw_backend_cpu_destroy(cpus[m]);
    sl_draw_backend_cpu_destroy(cpus[iv]);
    sl_draw_backend_cpu_destroy(cpus[ie]);
    sl_culler_destroy(vfc);
    sl_oracle_destroy(o);
    sl_path_destroy(walk);
    sl_scene_destroy(s);
    free(ids);
    return 0;
}
