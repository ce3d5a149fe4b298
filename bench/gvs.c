/* bench_gvs: guided visibility sampling (GVS) per view cell against plain random sampling (RAND)
 * with the same number of rays, on the small generated city (street cells) and on OpenArena maps
 * (their BSP clusters as cells): seconds per cell, rays, PVS size, and the pixel error of the
 * seed's evaluation (Wonka, Wimmer et al. 2006, section 5.4: false pixels at 1000x1000 between a
 * render of the whole scene and a render of the PVS only, from random views inside the cell).
 *
 * For every cell:
 *  1. GVS with the paper's defaults (eps 5e-5, at most 50 new triangles per 1M rays, 10M rays at
 *     most): wall time (one thread), rays by kind, triangles and objects found;
 *  2. RAND with exactly GVS's ray count (same Halton generator, no ABS, no RS);
 *  3. V views at random points inside the cell at least 0.15 m from any geometry, looking in
 *     random directions (uniform over the sphere), 1000x1000, 60 degree vertical field of view,
 *     near 0.05 m:
 *     - triangle error (the paper's metric): an Embree id render of the whole scene; a pixel is
 *       false when the triangle it shows is not in the PVS (drawing the PVS alone would show
 *       something else there, and every other pixel stays the same);
 *     - object error (Sightline's metric, per-object PVS): the point oracle's exact object-id
 *       render (truth.h) and sl_metrics_compare's missed pixels.
 *     Average and maximum over the views, then averaged over the cells of a scene (as the paper).
 *
 * usage: bench_gvs [--city PRESET|none] [--city-cells N] [--pk3 PATH] [--maps A,B,...|none]
 *                  [--clusters N] [--views N] [--size PX] [--max-rays N] [--window N]
 *                  [--min-new N] [--seed S] [--no-oracle]
 * Prints one line per cell, then Markdown rows per scene. */
#include "core/sl_core.h"
#include "region/gvs_internal.h"
#include "sightline/gen.h"
#include "sightline/import.h"
#include "sightline/region.h"
#include "sightline/truth.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "bench_common.h"

typedef struct args {
    const char *city;
    uint32_t city_cells;
    const char *pk3;
    const char *maps;
    uint32_t clusters;
    uint32_t views;
    uint32_t size;
    uint64_t max_rays, window, min_new;
    uint64_t seed;
    bool oracle;
} args;

/* One sampler's figures for one cell. */
typedef struct run {
    double seconds;
    uint64_t rays, random_rays, border_rays, reverse_rays;
    uint64_t origin_rejects;
    uint32_t triangles, objects, stop;
    double tri_err_avg, obj_err_avg, oracle_err_avg; /* false pixels per view */
    uint64_t tri_err_max, obj_err_max, oracle_err_max;
} run;

/* Sums over the cells of a scene. */
typedef struct totals {
    uint32_t cells;
    run sum[2];
    uint32_t converged;
} totals;

static int usage(int code)
{
    fprintf(code ? stderr : stdout,
            "usage: bench_gvs [--city tiny|small|vienna|none] [--city-cells N] [--pk3 PATH] [--maps A,B,...|none]\n"
            "                 [--clusters N] [--views N] [--size PX] [--max-rays N] [--window N] [--min-new N]\n"
            "                 [--seed S] [--no-oracle]\n"
            "defaults: --city small --city-cells 6 --pk3 /usr/share/games/openarena/baseoa/pak1-maps.pk3\n"
            "          --maps oa_dm1,oa_dm4,oa_rpg3dm2 --clusters 4 --views 10 --size 1000\n"
            "          --max-rays 10000000 --window 1000000 --min-new 50 --seed 1\n");
    return code;
}

static bool parse_u64(const char *s, uint64_t *out)
{
    char *end;
    unsigned long long v = strtoull(s, &end, 10);
    if (!*s || *end || s[0] == '-')
        return false;
    *out = v;
    return true;
}

static void bits_set(uint64_t *b, const uint32_t *ids, uint32_t n, bool on)
{
    for (uint32_t i = 0; i < n; i++) {
        if (on)
            b[ids[i] >> 6] |= 1ull << (ids[i] & 63);
        else
            b[ids[i] >> 6] &= ~(1ull << (ids[i] & 63));
    }
}

static bool bit(const uint64_t *b, uint32_t id) { return (b[id >> 6] >> (id & 63)) & 1u; }

typedef struct ctx {
    const args *a;
    sl_scene scene;
    sl_viewcells cells;
    sl_es *es;
    sl_oracle oracle;
    sl_gvs gvs, rnd;
    uint64_t *tri_bits[2], *obj_bits[2];
    uint32_t *ids;              /* size*size triangle ids */
    double diag;
} ctx;

/* No geometry within 0.15 m of the eye (26 directions: the cube's faces, edges and corners):
 * closer than the near plane (0.05 m) a wall would be clipped away and the view would look
 * through it into the void behind, which no from-region method is meant to cover. */
static bool clear_of_geometry(const ctx *c, sl_vec3 p)
{
    sl_es_ray rays[26];
    sl_es_hit hits[26];
    int n = 0;
    for (int x = -1; x <= 1; x++)
        for (int y = -1; y <= 1; y++)
            for (int z = -1; z <= 1; z++) {
                if (!x && !y && !z)
                    continue;
                float l = sqrtf((float)(x * x + y * y + z * z));
                sl_es_ray r = {{p.x, p.y, p.z}, 0.0f, {x / l, y / l, z / l}, 0.15f};
                rays[n++] = r;
            }
    sl_es_trace(c->es, rays, hits, 26);
    for (int i = 0; i < 26; i++)
        if (hits[i].triangle != SL_NONE)
            return false;
    return true;
}

/* Pixel errors of both samplers' sets over the cell's views. */
static int evaluate(ctx *c, uint32_t cell, const sl_gvs_result res[2], run out[2])
{
    sl_error err;
    const args *a = c->a;
    sl_rng rng;
    sl_rng_seed(&rng, a->seed, 0x51ed ^ ((uint64_t)cell << 8));
    sl_cull_metrics m;
    uint32_t nviews = 0;
    for (uint32_t v = 0; v < a->views; v++) {
        double u[4 * 64];
        sl_camera cam = sl_camera_default();
        bool placed = false;
        for (int attempt = 0; attempt < 16 && !placed; attempt++) {
            for (int i = 0; i < 4 * 64; i++)
                u[i] = sl_rng_double(&rng);
            placed = sl_gvs_cell_point(c->gvs, c->cells, cell, u, 64, &cam.position) && clear_of_geometry(c, cam.position);
        }
        if (!placed)
            continue;
        cam.yaw = (float)(2 * M_PI * sl_rng_double(&rng));
        cam.pitch = (float)asin(2 * sl_rng_double(&rng) - 1);
        cam.width = cam.height = a->size;
        cam.fov_y = (float)(60.0 * M_PI / 180.0);
        cam.near_plane = 0.05f;
        cam.far_plane = (float)(2.0 * c->diag + 10.0);
        if (sl_es_render_ids(c->es, &cam, c->ids, &err) != SL_OK) {
            fprintf(stderr, "bench_gvs: render: %s\n", err.message);
            return 1;
        }
        uint64_t tri_err[2] = {0, 0}, obj_err[2] = {0, 0};
        const uint64_t np = (uint64_t)a->size * a->size;
        for (uint64_t p = 0; p < np; p++) {
            uint32_t t = c->ids[p];
            if (t == SL_NONE)
                continue;
            uint32_t o = sl_es_triangle_object(c->es, t);
            for (int k = 0; k < 2; k++) {
                tri_err[k] += !bit(c->tri_bits[k], t);
                obj_err[k] += !bit(c->obj_bits[k], o);
            }
        }
        uint64_t orc_err[2] = {0, 0};
        if (c->oracle) {
            sl_oracle_frame f;
            if (sl_oracle_render(c->oracle, &cam, &f, &err) != SL_OK) {
                fprintf(stderr, "bench_gvs: oracle: %s\n", err.message);
                return 1;
            }
            for (int k = 0; k < 2; k++) {
                if (sl_metrics_compare(c->scene, &f, res[k].objects, res[k].object_count, &m, NULL, NULL, 0, &err) !=
                    SL_OK) {
                    fprintf(stderr, "bench_gvs: metrics: %s\n", err.message);
                    return 1;
                }
                orc_err[k] = m.missed_pixels;
            }
        }
        for (int k = 0; k < 2; k++) {
            out[k].tri_err_avg += (double)tri_err[k];
            out[k].obj_err_avg += (double)obj_err[k];
            out[k].oracle_err_avg += (double)orc_err[k];
            out[k].tri_err_max = SL_MAX(out[k].tri_err_max, tri_err[k]);
            out[k].obj_err_max = SL_MAX(out[k].obj_err_max, obj_err[k]);
            out[k].oracle_err_max = SL_MAX(out[k].oracle_err_max, orc_err[k]);
        }
        nviews++;
    }
    for (int k = 0; k < 2 && nviews; k++) {
        out[k].tri_err_avg /= nviews;
        out[k].obj_err_avg /= nviews;
        out[k].oracle_err_avg /= nviews;
    }
    return 0;
}

static void add_run(run *s, const run *r)
{
    s->seconds += r->seconds;
    s->rays += r->rays;
    s->random_rays += r->random_rays;
    s->border_rays += r->border_rays;
    s->reverse_rays += r->reverse_rays;
    s->triangles += r->triangles;
    s->objects += r->objects;
    s->tri_err_avg += r->tri_err_avg;
    s->obj_err_avg += r->obj_err_avg;
    s->oracle_err_avg += r->oracle_err_avg;
    s->tri_err_max += r->tri_err_max;
    s->obj_err_max += r->obj_err_max;
    s->oracle_err_max += r->oracle_err_max;
}

static void fill_run(run *r, const sl_gvs_result *res)
{
    memset(r, 0, sizeof *r);
    r->seconds = res->stats.seconds;
    r->rays = res->stats.rays;
    r->random_rays = res->stats.random_rays;
    r->border_rays = res->stats.border_rays;
    r->reverse_rays = res->stats.reverse_rays;
    r->origin_rejects = res->stats.origin_rejects;
    r->triangles = res->triangle_count;
    r->objects = res->object_count;
    r->stop = res->stats.stop;
}

/* Run both samplers on the chosen cells of one scene. */
static int bench_scene(const args *a, const char *name, sl_scene scene, sl_viewcells cells, const uint32_t *pick,
                       uint32_t npick, totals *tot)
{
    sl_error err;
    ctx c;
    memset(&c, 0, sizeof c);
    c.a = a;
    c.scene = scene;
    c.cells = cells;
    double t0 = sl_now();
    if (sl_es_create(scene, NULL, NULL, &c.es, &err) != SL_OK) {
        fprintf(stderr, "bench_gvs: %s: %s\n", name, err.message);
        return 1;
    }
    sl_es_stats es;
    sl_es_get_stats(c.es, &es);
    sl_aabb b = sl_es_bounds(c.es);
    c.diag = sqrt(((double)b.max.x - b.min.x) * ((double)b.max.x - b.min.x) +
                  ((double)b.max.y - b.min.y) * ((double)b.max.y - b.min.y) +
                  ((double)b.max.z - b.min.z) * ((double)b.max.z - b.min.z));
    printf("## %s: %u objects, %u triangles, %u cells (%u sampled); Embree build %.2f s\n", name, es.object_count,
           es.triangle_count, sl_viewcells_count(cells), npick, sl_now() - t0);
    sl_gvs_options go = sl_gvs_defaults();
    go.max_rays = a->max_rays;
    go.window = a->window;
    go.min_new = a->min_new;
    go.seed = a->seed;
    sl_gvs_options ro = go;
    ro.sampler = SL_GVS_RANDOM;
    int rc = 1;
    size_t words = ((size_t)es.triangle_count + 63) / 64 + 1, owords = ((size_t)es.object_count + 63) / 64 + 1;
    for (int k = 0; k < 2; k++) {
        c.tri_bits[k] = calloc(words, sizeof(uint64_t));
        c.obj_bits[k] = calloc(owords, sizeof(uint64_t));
    }
    c.ids = malloc((size_t)a->size * a->size * sizeof(uint32_t));
    uint32_t *tcopy = NULL, *ocopy = NULL;
    if (!c.ids || !c.tri_bits[0] || !c.tri_bits[1] || !c.obj_bits[0] || !c.obj_bits[1])
        goto done;
    if (sl_gvs_create(c.es, scene, &go, NULL, &c.gvs, &err) != SL_OK) {
        fprintf(stderr, "bench_gvs: %s\n", err.message);
        goto done;
    }
    if (a->oracle) {
        sl_oracle_options oo = sl_oracle_default_options();
        oo.threads = 2;
        if (sl_oracle_create(scene, &oo, NULL, &c.oracle, &err) != SL_OK) {
            fprintf(stderr, "bench_gvs: %s\n", err.message);
            goto done;
        }
    }
    tcopy = malloc(((size_t)es.triangle_count + 1) * sizeof(uint32_t));
    ocopy = malloc(((size_t)es.object_count + 1) * sizeof(uint32_t));
    if (!tcopy || !ocopy)
        goto done;
    printf("| cell | GVS s | rays (rnd/abs/rs) | origin rejects | tris | objs | stop | RAND tris | objs | tri err GVS avg/max | RAND "
           "avg/max | obj err (oracle) GVS avg/max | RAND avg/max |\n");
    for (uint32_t i = 0; i < npick; i++) {
        uint32_t cell = pick[i];
        sl_gvs_result res[2];
        if (sl_gvs_cell(c.gvs, cells, cell, &res[0], &err) != SL_OK) {
            fprintf(stderr, "bench_gvs: %s cell %u: %s\n", name, cell, err.message);
            goto done;
        }
        /* keep GVS's answer while RAND runs (the sampler's arrays are reused) */
        memcpy(tcopy, res[0].triangles, (size_t)res[0].triangle_count * sizeof(uint32_t));
        memcpy(ocopy, res[0].objects, (size_t)res[0].object_count * sizeof(uint32_t));
        res[0].triangles = tcopy;
        res[0].objects = ocopy;
        run r[2];
        fill_run(&r[0], &res[0]);
        ro.max_rays = res[0].stats.rays;
        ro.window = ro.max_rays + 1; /* exactly GVS's ray count: no early stop */
        sl_gvs_destroy(c.rnd);
        c.rnd = NULL;
        if (sl_gvs_create(c.es, scene, &ro, NULL, &c.rnd, &err) != SL_OK ||
            sl_gvs_cell(c.rnd, cells, cell, &res[1], &err) != SL_OK) {
            fprintf(stderr, "bench_gvs: %s cell %u (random): %s\n", name, cell, err.message);
            goto done;
        }
        fill_run(&r[1], &res[1]);
        for (int k = 0; k < 2; k++) {
            bits_set(c.tri_bits[k], res[k].triangles, res[k].triangle_count, true);
            bits_set(c.obj_bits[k], res[k].objects, res[k].object_count, true);
        }
        if (evaluate(&c, cell, res, r))
            goto done;
        for (int k = 0; k < 2; k++) {
            bits_set(c.tri_bits[k], res[k].triangles, res[k].triangle_count, false);
            bits_set(c.obj_bits[k], res[k].objects, res[k].object_count, false);
        }
        printf("| %u | %.2f | %.2fM (%.2f/%.2f/%.2f) | %.2fM | %u | %u | %s | %u | %u | %.1f / %llu | %.1f / %llu | %.1f / %llu "
               "| %.1f / %llu |\n",
               cell, r[0].seconds, r[0].rays / 1e6, r[0].random_rays / 1e6, r[0].border_rays / 1e6,
               r[0].reverse_rays / 1e6, r[0].origin_rejects / 1e6, r[0].triangles, r[0].objects,
               r[0].stop == SL_GVS_STOP_CONVERGED ? "conv" : r[0].stop == SL_GVS_STOP_MAX_RAYS ? "max" : "none",
               r[1].triangles, r[1].objects, r[0].tri_err_avg, (unsigned long long)r[0].tri_err_max,
               r[1].tri_err_avg, (unsigned long long)r[1].tri_err_max, r[0].oracle_err_avg,
               (unsigned long long)r[0].oracle_err_max, r[1].oracle_err_avg, (unsigned long long)r[1].oracle_err_max);
        fflush(stdout);
        tot->cells++;
        tot->converged += r[0].stop == SL_GVS_STOP_CONVERGED;
        for (int k = 0; k < 2; k++)
            add_run(&tot->sum[k], &r[k]);
    }
    rc = 0;
    {
        uint32_t n = tot->cells ? tot->cells : 1;
        const run *g = &tot->sum[0], *r = &tot->sum[1];
        printf("\nsummary %s: %u cells, %u converged; GVS %.2f s/cell, %.2fM rays/cell (%.2f Mrays/s), PVS %.2f%% of "
               "triangles, %.1f objects; RAND same rays %.2f s/cell, PVS %.2f%%\n",
               name, tot->cells, tot->converged, g->seconds / n, g->rays / 1e6 / n,
               g->seconds > 0 ? g->rays / 1e6 / g->seconds : 0, 100.0 * g->triangles / n / fmax(1, es.triangle_count),
               (double)g->objects / n, r->seconds / n, 100.0 * r->triangles / n / fmax(1, es.triangle_count));
        printf("| scene | cells | GVS s/cell | Mrays/cell | Mrays/s | PVS tris | tri err avg / max (GVS) | (RAND) | obj "
               "err oracle avg / max (GVS) | (RAND) | ratio avg RAND/GVS (tri, obj) |\n");
        printf("| %s | %u | %.2f | %.2f | %.2f | %.2f%% | %.1f / %.0f | %.1f / %.0f | %.1f / %.0f | %.1f / %.0f | %.1f, %.1f "
               "|\n\n",
               name, tot->cells, g->seconds / n, g->rays / 1e6 / n, g->seconds > 0 ? g->rays / 1e6 / g->seconds : 0,
               100.0 * g->triangles / n / fmax(1, es.triangle_count), g->tri_err_avg / n, (double)g->tri_err_max / n,
               r->tri_err_avg / n, (double)r->tri_err_max / n, g->oracle_err_avg / n, (double)g->oracle_err_max / n,
               r->oracle_err_avg / n, (double)r->oracle_err_max / n,
               g->tri_err_avg > 0 ? r->tri_err_avg / g->tri_err_avg : 0,
               g->oracle_err_avg > 0 ? r->oracle_err_avg / g->oracle_err_avg : 0);
    }
done:
    free(tcopy);
    free(ocopy);
    for (int k = 0; k < 2; k++) {
        free(c.tri_bits[k]);
        free(c.obj_bits[k]);
    }
    free(c.ids);
    sl_gvs_destroy(c.gvs);
    sl_gvs_destroy(c.rnd);
    sl_oracle_destroy(c.oracle);
    sl_es_destroy(c.es);
    return rc;
}

/* n distinct cells out of count, deterministic. */
static uint32_t pick_cells(uint64_t seed, uint32_t count, uint32_t n, uint32_t *out)
{
    if (n > count)
        n = count;
    sl_rng r;
    sl_rng_seed(&r, seed, 77);
    uint32_t k = 0;
    while (k < n) {
        uint32_t c = sl_rng_below(&r, count);
        bool dup = false;
        for (uint32_t i = 0; i < k; i++)
            dup |= out[i] == c;
        if (!dup)
            out[k++] = c;
    }
    return n;
}

int main(int argc, char **argv)
{
    args a = {"small", 6, "/usr/share/games/openarena/baseoa/pak1-maps.pk3", "oa_dm1,oa_dm4,oa_rpg3dm2", 4, 10,
              1000, 10000000, 1000000, 50, 1, true};
    for (int i = 1; i < argc; i++) {
        const char *o = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        uint64_t x = 0;
        if (!strcmp(o, "--help") || !strcmp(o, "-h"))
            return usage(0);
        if (!strcmp(o, "--no-oracle")) {
            a.oracle = false;
            continue;
        }
        if (!v)
            return usage(2);
        i++;
        if (!strcmp(o, "--city"))
            a.city = v;
        else if (!strcmp(o, "--pk3"))
            a.pk3 = v;
        else if (!strcmp(o, "--maps"))
            a.maps = v;
        else if (!parse_u64(v, &x))
            return usage(2);
        else if (!strcmp(o, "--city-cells"))
            a.city_cells = (uint32_t)x;
        else if (!strcmp(o, "--clusters"))
            a.clusters = (uint32_t)x;
        else if (!strcmp(o, "--views"))
            a.views = (uint32_t)x;
        else if (!strcmp(o, "--size") && x >= 16 && x <= 4096)
            a.size = (uint32_t)x;
        else if (!strcmp(o, "--max-rays") && x >= 1)
            a.max_rays = x;
        else if (!strcmp(o, "--window") && x >= 1)
            a.window = x;
        else if (!strcmp(o, "--min-new"))
            a.min_new = x;
        else if (!strcmp(o, "--seed"))
            a.seed = x;
        else
            return usage(2);
    }
    char mach[256];
    bench_machine(mach, sizeof mach);
    printf("# bench_gvs: %s\n# eps 5e-5, stop at <= %llu new triangles per %llu rays or %llu rays; RAND = same rays; "
           "%u views of %ux%u, 60 deg fov\n\n",
           mach, (unsigned long long)a.min_new, (unsigned long long)a.window, (unsigned long long)a.max_rays, a.views,
           a.size, a.size);
    sl_error err;
    int rc = 0;
    if (strcmp(a.city, "none") != 0) {
        sl_city_preset preset;
        if (sl_city_preset_from_name(a.city, &preset, &err) != SL_OK) {
            fprintf(stderr, "bench_gvs: %s\n", err.message);
            return 2;
        }
        sl_city_options co = sl_city_defaults(preset);
        sl_scene s;
        sl_viewcells vc;
        if (sl_gen_city(&co, NULL, &s, &err) != SL_OK) {
            fprintf(stderr, "bench_gvs: city: %s\n", err.message);
            return 1;
        }
        if (sl_viewcells_from_streets(s, NULL, &vc, &err) != SL_OK) {
            fprintf(stderr, "bench_gvs: street cells: %s\n", err.message);
            sl_scene_destroy(s);
            return 1;
        }
        uint32_t *pick = malloc((a.city_cells + 1) * sizeof *pick);
        uint32_t n = pick ? pick_cells(a.seed, sl_viewcells_count(vc), a.city_cells, pick) : 0;
        char name[64];
        snprintf(name, sizeof name, "city %s", a.city);
        totals t;
        memset(&t, 0, sizeof t);
        rc |= bench_scene(&a, name, s, vc, pick, n, &t);
        free(pick);
        sl_viewcells_destroy(vc);
        sl_scene_destroy(s);
    }
    if (strcmp(a.maps, "none") != 0) {
        char list[1024];
        snprintf(list, sizeof list, "%s", a.maps);
        for (char *save = NULL, *m = strtok_r(list, ",", &save); m; m = strtok_r(NULL, ",", &save)) {
            sl_scene s;
            sl_viewcells vc;
            if (sl_import_q3bsp(a.pk3, m, NULL, NULL, &s, &err) != SL_OK) {
                fprintf(stderr, "bench_gvs: %s: %s\n", m, err.message);
                rc = 1;
                continue;
            }
            if (sl_viewcells_from_bsp(s, NULL, &vc, &err) != SL_OK) {
                fprintf(stderr, "bench_gvs: %s clusters: %s\n", m, err.message);
                sl_scene_destroy(s);
                rc = 1;
                continue;
            }
            uint32_t *pick = malloc((a.clusters + 1) * sizeof *pick);
            uint32_t n = pick ? pick_cells(a.seed, sl_viewcells_count(vc), a.clusters, pick) : 0;
            totals t;
            memset(&t, 0, sizeof t);
            rc |= bench_scene(&a, m, s, vc, pick, n, &t);
            free(pick);
            sl_viewcells_destroy(vc);
            sl_scene_destroy(s);
        }
    }
    bench_machine(mach, sizeof mach);
    printf("# at the end: %s\n", mach);
    return rc;
}
