/* Benchmark: how long a warm .slscene load takes (mmap + checksums + validation), the target
 * being under one second for an 8M-triangle scene.
 *
 * The scene is built through the public API: a grid of tessellated boxes of random size, each
 * its own mesh (so every triangle is stored), a tenth of them also instanced with a transform,
 * every box with its 2.5D footprint. It is saved once, then loaded several times per mode
 * (mapped or read, checksums verified or skipped) after one warm-up load; the median is
 * reported with the peak resident memory of that mode. The validation pass alone and the raw
 * XXH3 rate over the file are timed too, so that a slow load can be attributed.
 *
 * With --city PRESET the scene is the procedural city instead (sl_gen_city, e.g. "vienna", about
 * 8M triangles with instanced props, footprints, streets and metadata).
 *
 *   bench_slscene_load [--triangles N] [--subdiv N] [--city PRESET] [--runs N] [--out PATH] [--keep]
 */
#include "scene/scene_internal.h"
#include "sightline/gen.h"
#include "sightline/slscene.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

typedef struct bench_opts {
    uint64_t triangles;
    uint32_t subdiv;
    int runs;
    const char *out;
    const char *city; /* preset name, or NULL for the box grid */
    bool keep;
} bench_opts;

static void usage(FILE *f)
{
    fprintf(f, "usage: bench_slscene_load [--triangles N] [--subdiv N] [--city PRESET] [--runs N] [--out PATH]\n"
               "                          [--keep]\n\n"
               "Build a scene of about N stored triangles (default 8000000) made of boxes whose faces are\n"
               "split into subdiv x subdiv quads (default 5: 300 triangles per box), save it as .slscene\n"
               "and time warm loads (median of --runs, default 5) mapped and read, with and without\n"
               "checksums. --city PRESET (tiny, small, vienna) uses the procedural city instead of\n"
               "the boxes. --out sets the file (default /tmp/sl_bench_slscene.slscene), removed at the\n"
               "end unless --keep.\n\n"
               "examples:\n"
               "  bench_slscene_load --triangles 8000000 --runs 5\n"
               "  bench_slscene_load --city vienna\n");
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Peak resident set since the last reset, in MiB (VmHWM). */
static double peak_rss_mib(void)
{
    FILE *f = fopen("/proc/self/status", "r");
    char line[256];
    double kib = -1;
    while (f && fgets(line, sizeof line, f))
        if (strncmp(line, "VmHWM:", 6) == 0)
            kib = strtod(line + 6, NULL);
    if (f)
        fclose(f);
    return kib / 1024.0;
}

/* Reset the peak RSS counter (Linux >= 4.0); false when unsupported. */
static bool reset_peak_rss(void)
{
    FILE *f = fopen("/proc/self/clear_refs", "w");
    if (!f)
        return false;
    bool ok = fputs("5", f) >= 0;
    return fclose(f) == 0 && ok;
}

/* A box [0,sx]x[0,sy]x[0,sz] whose every face is split into n x n quads, face normals. */
static void box_mesh(uint32_t n, float sx, float sy, float sz, float *pos, float *nrm, uint32_t *idx)
{
    /* per face: origin, two edge vectors (u, v) with u x v the outward normal */
    const float faces[6][9] = {
        {0, 0, 0, 0, 1, 0, 1, 0, 0},  /* z = 0, normal -z */
        {0, 0, 1, 1, 0, 0, 0, 1, 0},  /* z = 1, +z */
        {0, 0, 0, 1, 0, 0, 0, 0, 1},  /* y = 0, -y */
        {0, 1, 0, 0, 0, 1, 1, 0, 0},  /* y = 1, +y */
        {0, 0, 0, 0, 0, 1, 0, 1, 0},  /* x = 0, -x */
        {1, 0, 0, 0, 1, 0, 0, 0, 1},  /* x = 1, +x */
    };
    const float scale[3] = {sx, sy, sz};
    uint32_t v = 0, t = 0, side = n + 1;
    for (int f = 0; f < 6; f++) {
        const float *o = faces[f], *u = faces[f] + 3, *w = faces[f] + 6;
        float nn[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        uint32_t base = v;
        for (uint32_t j = 0; j <= n; j++)
            for (uint32_t i = 0; i <= n; i++, v++)
                for (int k = 0; k < 3; k++) {
                    pos[3 * v + k] = (o[k] + u[k] * (float)i / (float)n + w[k] * (float)j / (float)n) * scale[k];
                    nrm[3 * v + k] = nn[k];
                }
        for (uint32_t j = 0; j < n; j++)
            for (uint32_t i = 0; i < n; i++) {
                uint32_t a = base + j * side + i, b = a + 1, c = a + side + 1, d = a + side;
                uint32_t tri[6] = {a, b, c, a, c, d};
                memcpy(idx + 3 * t, tri, sizeof tri);
                t += 2;
            }
    }
}

static sl_status build_scene(const bench_opts *o, sl_scene *out, sl_error *err)
{
    uint32_t n = o->subdiv, tris = 12 * n * n, verts = 6 * (n + 1) * (n + 1);
    uint64_t boxes = (o->triangles + tris - 1) / tris;
    float *pos = malloc(sizeof(float) * 3 * verts), *nrm = malloc(sizeof(float) * 3 * verts);
    uint32_t *idx = malloc(sizeof(uint32_t) * 3 * tris);
    sl_scene s = NULL;
    sl_status st = pos && nrm && idx ? sl_scene_create(NULL, &s, err) : sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "out of memory");
    sl_rng rng;
    sl_rng_seed(&rng, 2024, 7);
    uint32_t grid = 1;
    while ((uint64_t)grid * grid < boxes)
        grid++;
    for (uint64_t b = 0; b < boxes && st == SL_OK; b++) {
        float sx = sl_rng_range(&rng, 8, 30), sy = sl_rng_range(&rng, 8, 30), sz = sl_rng_range(&rng, 6, 60);
        box_mesh(n, sx, sy, sz, pos, nrm, idx);
        /* mesh in world coordinates, like the city generator's buildings */
        float x0 = (float)(b % grid) * 40.0f, y0 = (float)(b / grid) * 40.0f;
        for (uint32_t v = 0; v < verts; v++)
            pos[3 * v] += x0, pos[3 * v + 1] += y0;
        sl_mesh_desc md = {pos, nrm, verts, idx, tris, NULL};
        uint32_t mesh, obj;
        if ((st = sl_scene_add_mesh(s, &md, &mesh, err)) != SL_OK)
            break;
        sl_object_desc od = {mesh, NULL, 0x999999ffu, SL_KIND_BUILDING, SL_OBJECT_OCCLUDER | SL_OBJECT_CLOSED_CONVEX, 0};
        if ((st = sl_scene_add_object(s, &od, &obj, err)) != SL_OK)
            break;
        float fp[8] = {x0, y0, x0 + sx, y0, x0 + sx, y0 + sy, x0, y0 + sy};
        sl_footprint_desc fd = {fp, 4, 0, sz, obj};
        if ((st = sl_scene_add_footprint(s, &fd, NULL, err)) != SL_OK)
            break;
        if (b % 10 == 0) { /* an instanced, movable copy next to it */
            sl_affine t = sl_affine_identity();
            t.m[3] = 32, t.m[7] = 32;
            sl_object_desc cd = {mesh, &t, 0x3030c0ffu, SL_KIND_CAR, SL_OBJECT_DYNAMIC, 0};
            st = sl_scene_add_object(s, &cd, NULL, err);
        }
    }
    if (st == SL_OK)
        st = sl_scene_set_meta(s, "generator", "bench_slscene_load", err);
    free(pos);
    free(nrm);
    free(idx);
    if (st != SL_OK) {
        sl_scene_destroy(s);
        return st;
    }
    *out = s;
    return SL_OK;
}

typedef struct mode {
    const char *name;
    bool no_mmap, skip;
} mode;

int main(int argc, char **argv)
{
    bench_opts o = {8000000, 5, 5, "/tmp/sl_bench_slscene.slscene", NULL, false};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        char *end = NULL;
        if (!strcmp(a, "--help")) {
            usage(stdout);
            return 0;
        } else if (!strcmp(a, "--keep")) {
            o.keep = true;
        } else if (!strcmp(a, "--triangles") && v) {
            o.triangles = strtoull(v, &end, 10), i++;
        } else if (!strcmp(a, "--subdiv") && v) {
            o.subdiv = (uint32_t)strtoul(v, &end, 10), i++;
        } else if (!strcmp(a, "--runs") && v) {
            o.runs = (int)strtol(v, &end, 10), i++;
        } else if (!strcmp(a, "--city") && v) {
            o.city = v, i++;
        } else if (!strcmp(a, "--out") && v) {
            o.out = v, i++;
        } else {
            fprintf(stderr, "bench_slscene_load: unknown or incomplete option '%s'\n", a);
            usage(stderr);
            return 2;
        }
        if (end && *end) {
            fprintf(stderr, "bench_slscene_load: bad number '%s' for %s\n", v, a);
            return 2;
        }
    }
    if (o.triangles == 0 || o.subdiv == 0 || o.subdiv > 100 || o.runs < 1 || o.runs > 101) {
        fprintf(stderr, "bench_slscene_load: --triangles > 0, --subdiv 1..100, --runs 1..101\n");
        return 2;
    }
    sl_error err;
    double t0 = sl_now();
    sl_scene s;
    sl_status bs;
    if (o.city) {
        sl_city_preset preset;
        bs = sl_city_preset_from_name(o.city, &preset, &err);
        if (bs == SL_OK) {
            sl_city_options co = sl_city_defaults(preset);
            bs = sl_gen_city(&co, NULL, &s, &err);
        }
    } else {
        bs = build_scene(&o, &s, &err);
    }
    if (bs != SL_OK) {
        fprintf(stderr, "bench_slscene_load: build failed: %s\n", err.message);
        return 1;
    }
    double t_build = sl_now() - t0;
    sl_scene_stats st;
    sl_scene_get_stats(s, &st);
    t0 = sl_now();
    if (sl_scene_save(s, o.out, &err) != SL_OK) {
        fprintf(stderr, "bench_slscene_load: %s\n", err.message);
        sl_scene_destroy(s);
        return 1;
    }
    double t_save = sl_now() - t0;
    sl_scene_destroy(s);
    struct stat sb;
    stat(o.out, &sb);
    printf("scene: %u objects, %u meshes, %u footprints, %llu stored triangles, %llu vertices\n", st.object_count,
           st.mesh_count, st.footprint_count, (unsigned long long)st.triangle_count,
           (unsigned long long)st.vertex_count);
    printf("file:  %s, %.1f MiB (built in %.2f s, saved in %.2f s incl. fsync)\n", o.out,
           (double)sb.st_size / (1024.0 * 1024.0), t_build, t_save);

    /* raw checksum rate over the mapped file, for scale */
    sl_mapping map;
    if (sl_file_map(o.out, &map, &err) == SL_OK) {
        volatile uint64_t sink = sl_hash64(map.data, map.size, 0); /* faults the pages in */
        t0 = sl_now();
        sink ^= sl_hash64(map.data, map.size, 0);
        double th = sl_now() - t0;
        (void)sink;
        printf("xxh3:  %.1f GB/s over the mapped file (%.1f ms)\n", (double)map.size / th / 1e9, th * 1e3);
        sl_file_unmap(&map);
    }

    static const mode modes[] = {
        {"mmap, checksums", false, false},
        {"mmap, no checksums", false, true},
        {"read, checksums", true, false},
        {"read, no checksums", true, true},
    };
    double *times = malloc(sizeof(double) * (size_t)o.runs);
    bool rss_ok = true;
    int status = 0;
    printf("\n%-22s %10s %10s %10s %14s\n", "load mode", "median ms", "min ms", "max ms", "peak RSS MiB");
    for (size_t m = 0; m < SL_COUNTOF(modes) && status == 0; m++) {
        sl_load_options opt;
        memset(&opt, 0, sizeof opt);
        opt.map = !modes[m].no_mmap;
        opt.skip_checksums = modes[m].skip;
        rss_ok &= reset_peak_rss();
        for (int r = -1; r < o.runs; r++) { /* run -1 warms the page cache and the allocator */
            sl_scene l;
            t0 = sl_now();
            if (sl_scene_load(o.out, &opt, NULL, &l, &err) != SL_OK) {
                fprintf(stderr, "bench_slscene_load: load failed: %s\n", err.message);
                status = 1;
                break;
            }
            double t = sl_now() - t0;
            if (r >= 0)
                times[r] = t;
            if (r == o.runs - 1 && m == 0) {
                /* the share of sl_scene_validate alone, on the last mapped scene */
                double tv = sl_now();
                sl_status vs = sl_scene_validate(l, &err);
                tv = sl_now() - tv;
                printf("%-22s %10.1f   (sl_scene_validate alone, status %d)\n", "  validate pass", tv * 1e3, vs);
            }
            sl_scene_destroy(l);
        }
        if (status)
            break;
        qsort(times, (size_t)o.runs, sizeof *times, cmp_double);
        printf("%-22s %10.1f %10.1f %10.1f %14.0f\n", modes[m].name, times[o.runs / 2] * 1e3, times[0] * 1e3,
               times[o.runs - 1] * 1e3, peak_rss_mib());
    }
    if (!rss_ok)
        printf("(peak RSS could not be reset: values are the process peak)\n");
    free(times);
    if (!o.keep)
        unlink(o.out);
    return status;
}
