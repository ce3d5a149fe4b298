/* Near-wall sweep (issue 12 §1): every conservative method against the point oracle on views
 * whose eye is 0.001-0.2 m in front of a surface (bench/near_wall_views.h), on every map of
 * OpenArena's pak1-maps.pk3 (and, with --city, the small city too).
 *
 *   bench_near_wall [--pk3 PATH] [--views N] [--width W --height H] [--maps N] [--city]
 *                   [--model FILE]... [--seed S] [--methods LIST]
 *
 * --model FILE adds a model (any file sl_scene_open reads: .slscene, assimp formats) as one more
 * scene, its meshes split into objects of at most --split N triangles (default 500, 0: one object
 * per node) so that parts of it can hide others; --maps 0 leaves the pk3 out.
 *
 * Defaults: 100 views per map at 320x240, seed 1, the methods of tests/test_near_wall.c (every
 * conservative one but pvs, frusta and hzb also with all_objects=true); --methods takes
 * comma-separated specs name[:key=value...]. Per method: views, views with a miss, objects
 * missed, the median and 95th percentile cull time (sl_cull_stats.total_ms, one run per view).
 * Prints the command line, the date, the machine (nproc, CPU model, load) first; Markdown table.
 * Exit status 1 when a conservative method missed an object. */
#include "core/sl_core.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/import.h"
#include "sightline/slscene.h"
#include "sightline/truth.h"

#include "near_wall_views.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include "bench_common.h"

#define MAX_METHODS 24
#define MAX_MAPS 256

static const char *const g_default[] = {"vfc",    "cullmap",    "horizon",  "dhorizon", "hzb",
                                        "hzb:all_objects=true",    "lazygrid", "lazygrid-z",
                                        "busygrid", "hom", "frusta", "frusta:all_objects=true", "cplp"};

typedef struct method {
    char spec[200], name[64], opts[200];
    uint64_t views, bad_views, missed;
    double *ms;
    size_t ms_count, ms_cap;
} method;

typedef struct maps {
    char names[MAX_MAPS][96];
    int count;
} maps;

static void collect(void *user, const char *entry)
{
    maps *l = user;
    if (l->count < MAX_MAPS)
        snprintf(l->names[l->count++], sizeof l->names[0], "%s", entry);
}

static void die(const char *what, const sl_error *err)
{
    fprintf(stderr, "bench_near_wall: %s%s%s\n", what, err ? ": " : "", err ? err->message : "");
    exit(2);
}

static void parse_method(const char *spec, method *m)
{
    memset(m, 0, sizeof *m);
    snprintf(m->spec, sizeof m->spec, "%s", spec);
    const char *colon = strchr(spec, ':');
    size_t nl = colon ? (size_t)(colon - spec) : strlen(spec);
    snprintf(m->name, sizeof m->name, "%.*s", (int)nl, spec);
    if (colon) {
        snprintf(m->opts, sizeof m->opts, "%s", colon + 1);
        for (char *c = m->opts; *c; c++)
            if (*c == ':')
                *c = ',';
    }
}

/* Cull `views` near-wall views of s with every method against the oracle. */
static void run_scene(sl_scene s, const char *label, uint32_t views, uint64_t seed, uint32_t w, uint32_t h,
                      method *ms, uint32_t nm)
{
    sl_error err;
    sl_culler c[MAX_METHODS];
    for (uint32_t i = 0; i < nm; i++)
        if (sl_culler_create(ms[i].name, s, ms[i].opts[0] ? ms[i].opts : NULL, NULL, &c[i], &err) != SL_OK)
            c[i] = NULL;
    nw_table tb;
    if (!nw_table_build(s, &tb))
        die("no triangles", NULL);
    fprintf(stderr, "%s: %u objects, %u triangles\n", label, sl_scene_object_count(s), tb.count);
    sl_oracle o;
    if (sl_oracle_create(s, NULL, NULL, &o, &err) != SL_OK)
        die("oracle", &err);
    uint32_t n = sl_scene_object_count(s);
    uint32_t *out = malloc((n ? n : 1) * sizeof *out), missed[4], mpx[4];
    sl_camera in = sl_camera_default();
    in.width = w;
    in.height = h;
    nw_rng r = {seed};
    for (uint32_t f = 0; f < views; f++) {
        sl_camera cam;
        double d = nw_view(s, &tb, &r, &in, 0.001, 0.2, &cam);
        if (d < 0)
            break;
        sl_oracle_frame fr;
        if (sl_oracle_render(o, &cam, &fr, &err) != SL_OK)
            die("oracle render", &err);
        for (uint32_t i = 0; i < nm; i++) {
            if (!c[i])
                continue;
            uint32_t k;
            if (sl_culler_cull(c[i], &cam, out, n, &k, &err) != SL_OK)
                die(ms[i].spec, &err);
            sl_cull_stats st;
            sl_culler_stats(c[i], &st);
            sl_cull_metrics mt;
            if (sl_metrics_compare(s, &fr, out, k, &mt, missed, mpx, 4, &err) != SL_OK)
                die("metrics", &err);
            method *m = &ms[i];
            m->views++;
            if (mt.missed_count) {
                m->bad_views++;
                m->missed += mt.missed_count;
                fprintf(stderr, "%s: %s view %u missed %u (first %u, %u px), eye %.3f m from the surface at (%.4f, %.4f, "
                        "%.4f) yaw %.5f pitch %.5f roll %.5f\n", label, m->spec, f, mt.missed_count, missed[0], mpx[0], d,
                        (double)cam.position.x, (double)cam.position.y, (double)cam.position.z, (double)cam.yaw,
                        (double)cam.pitch, (double)cam.roll);
            }
            if (m->ms_count == m->ms_cap) {
                m->ms_cap = m->ms_cap ? 2 * m->ms_cap : 1024;
                m->ms = realloc(m->ms, m->ms_cap * sizeof *m->ms);
                if (!m->ms)
                    die("out of memory", NULL);
            }
            m->ms[m->ms_count++] = st.total_ms;
        }
    }
    free(out);
    sl_oracle_destroy(o);
    nw_table_free(&tb);
    for (uint32_t i = 0; i < nm; i++)
        sl_culler_destroy(c[i]);
}

int main(int argc, char **argv)
{
    const char *pk3 = "/usr/share/games/openarena/baseoa/pak1-maps.pk3", *list = NULL;
    uint32_t views = 100, w = 320, h = 240;
    int max_maps = MAX_MAPS;
    uint64_t seed = 1;
    bool city = false;
    const char *models[16];
    int model_count = 0;
    uint32_t split = 500;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--pk3") && v)
            pk3 = v, i++;
        else if (!strcmp(a, "--views") && v)
            views = (uint32_t)strtoul(v, NULL, 10), i++;
        else if (!strcmp(a, "--width") && v)
            w = (uint32_t)strtoul(v, NULL, 10), i++;
        else if (!strcmp(a, "--height") && v)
            h = (uint32_t)strtoul(v, NULL, 10), i++;
        else if (!strcmp(a, "--maps") && v)
            max_maps = atoi(v), i++;
        else if (!strcmp(a, "--seed") && v)
            seed = strtoull(v, NULL, 10), i++;
        else if (!strcmp(a, "--methods") && v)
            list = v, i++;
        else if (!strcmp(a, "--city"))
            city = true;
        else if (!strcmp(a, "--model") && v && model_count < 16)
            models[model_count++] = v, i++;
        else if (!strcmp(a, "--split") && v)
            split = (uint32_t)strtoul(v, NULL, 10), i++;
        else {
            fprintf(stderr,
                    "usage: %s [--pk3 PATH] [--views N] [--width W --height H] [--maps N] [--city] [--model FILE]... [--split N] "
                    "[--seed S] [--methods LIST]\n",
                    argv[0]);
            return 2;
        }
    }
    if (!views || !w || !h || w > 4096 || h > 4096)
        die("--views, --width and --height must be positive (sizes at most 4096)", NULL);
    method *ms = calloc(MAX_METHODS, sizeof *ms);
    uint32_t nm = 0;
    if (list) {
        char buf[2048];
        snprintf(buf, sizeof buf, "%s", list);
        for (char *tok = strtok(buf, ","); tok && nm < MAX_METHODS; tok = strtok(NULL, ","))
            parse_method(tok, &ms[nm++]);
    } else {
        for (size_t i = 0; i < sizeof g_default / sizeof *g_default; i++)
            parse_method(g_default[i], &ms[nm++]);
    }
    printf("# Near-wall sweep\n\ncommand:");
    for (int i = 0; i < argc; i++)
        printf(" %s", argv[i]);
    char date[64], mach[320];
    time_t now = time(NULL);
    strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", gmtime(&now));
    bench_machine(mach, sizeof mach);
    printf("\ndate: %s\nmachine: %s\nviews: eye 0.001-0.2 m in front of a random surface point, looking towards "
           "it; %u per scene at %ux%u, near 0.1 m, seed %llu\n\n",
           date, mach, views, w, h, (unsigned long long)seed);
    fflush(stdout);
    double t0 = sl_now();
    maps *mp = calloc(1, sizeof *mp);
    sl_error err;
    int scenes = 0;
    if (max_maps <= 0) {
        /* no maps */
    } else if (access(pk3, R_OK) == 0) {
        if (sl_pk3_list_maps(pk3, collect, mp, &err) != SL_OK)
            die(pk3, &err);
        for (int i = 0; i < mp->count && i < max_maps; i++) {
            sl_scene s;
            if (sl_import_q3bsp(pk3, mp->names[i], NULL, NULL, &s, &err) != SL_OK) {
                fprintf(stderr, "%s: skipped: %s\n", mp->names[i], err.message);
                continue;
            }
            run_scene(s, mp->names[i], views, seed + 1000 * (uint64_t)i, w, h, ms, nm);
            sl_scene_destroy(s);
            scenes++;
        }
    } else {
        fprintf(stderr, "bench_near_wall: %s is not readable (Debian package openarena-081-maps)\n", pk3);
    }
    if (city) {
        sl_city_options co = sl_city_defaults(SL_CITY_SMALL);
        sl_scene s;
        if (sl_gen_city(&co, NULL, &s, &err) != SL_OK)
            die("city", &err);
        run_scene(s, "small city", views, seed + 77, w, h, ms, nm);
        sl_scene_destroy(s);
        scenes++;
    }
    for (int i = 0; i < model_count; i++) {
        sl_scene s;
        sl_import_options io = sl_import_defaults();
        io.split_triangles = split;
        if (sl_scene_open_with(models[i], NULL, &io, NULL, &s, &err) != SL_OK) {
            fprintf(stderr, "%s: skipped: %s\n", models[i], err.message);
            continue;
        }
        run_scene(s, models[i], views, seed + 5000 + (uint64_t)i, w, h, ms, nm);
        sl_scene_destroy(s);
        scenes++;
    }
    int map_scenes = scenes - (city ? 1 : 0) - model_count;
    printf("%d scenes (%d maps%s, %d models), %.0f s\n\n", scenes, map_scenes < 0 ? 0 : map_scenes,
           city ? ", the small city" : "", model_count, (sl_now() - t0));
    printf("| method | views | views with a miss | objects missed | median ms | p95 ms |\n");
    printf("|---|---:|---:|---:|---:|---:|\n");
    int status = 0;
    for (uint32_t i = 0; i < nm; i++) {
        method *m = &ms[i];
        double med = bench_percentile(m->ms, m->ms_count, 0.5), p95 = bench_percentile(m->ms, m->ms_count, 0.95);
        printf("| %s | %llu | %llu | %llu | %.3f | %.3f |\n", m->spec, (unsigned long long)m->views,
               (unsigned long long)m->bad_views, (unsigned long long)m->missed, med, p95);
        if (m->missed)
            status = 1;
        free(m->ms);
    }
    free(ms);
    free(mp);
    return status;
}
