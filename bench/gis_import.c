/* Benchmark: how long sl_import_gis takes on a generated GeoJSON city (docs/gis-import.md).
 *
 * The file is written here, seeded: a lattice of blocks near 16.37 E, 48.21 N (WGS 84), each block
 * holding a ring of buildings along its edges (rectangles turned a little, every fifth an L, every
 * seventh with a courtyard), heights as "height", "building:levels" or none (the default), and
 * the streets between the blocks as lines through the crossings. It is imported --runs times
 * (after one warm-up); the median wall time and thread CPU time are reported with what was made.
 * --scene PATH keeps the last import as a .slscene (for `sightline bench` on it).
 *
 *   bench_gis_import [--buildings N] [--seed S] [--runs R] [--geojson PATH] [--scene PATH]
 */
#include "bench_common.h"
#include "sightline/import.h"
#include "sightline/scene.h"
#include "sightline/slscene.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static void die(const char *what)
{
    fprintf(stderr, "bench_gis_import: %s\n", what);
    exit(1);
}

static double now(clockid_t c)
{
    struct timespec ts;
    clock_gettime(c, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double lon_of(double x) { return 16.37 + x / 74260.0; }
static double lat_of(double y) { return 48.21 + y / 111200.0; }

static void ring(FILE *f, const double *xy, int n)
{
    fprintf(f, "[");
    for (int i = 0; i <= n; i++)
        fprintf(f, "%s[%.8f,%.8f]", i ? "," : "", lon_of(xy[2 * (i % n)]), lat_of(xy[2 * (i % n) + 1]));
    fprintf(f, "]");
}

/* Write about n buildings; returns how many were written. */
static int write_city(const char *path, int n, uint64_t seed)
{
    FILE *f = fopen(path, "w");
    if (!f)
        die("cannot write the GeoJSON file");
    sl_rng r;
    sl_rng_seed(&r, seed, 11);
    int per_block = 12, blocks = (int)ceil(sqrt((double)n / per_block));
    double pitch = 84, block = 70;
    fprintf(f, "{\"type\":\"FeatureCollection\",\"features\":[\n");
    int written = 0;
    for (int j = 0; j < blocks && written < n; j++)
        for (int i = 0; i < blocks && written < n; i++) {
            double bx = i * pitch + 7, by = j * pitch + 7;
            /* 12 lots around the block's edge: 4 a side, 17.5 m wide, 20 m deep */
            for (int k = 0; k < per_block && written < n; k++) {
                int side = k / 3, pos = k % 3;
                double w = block / 3 - 1.5, d = 20 + 6 * sl_rng_double(&r);
                double cx, cy, ux, uy; /* lot centre and its along-the-street direction */
                double t = (pos + 0.5) * block / 3;
                switch (side) {
                case 0: cx = bx + t, cy = by + d / 2, ux = 1, uy = 0; break;
                case 1: cx = bx + block - d / 2, cy = by + t, ux = 0, uy = 1; break;
                case 2: cx = bx + block - t, cy = by + block - d / 2, ux = -1, uy = 0; break;
                default: cx = bx + d / 2, cy = by + block - t, ux = 0, uy = -1; break;
                }
                double a = (sl_rng_double(&r) - 0.5) * 0.08, ca = cos(a), sa = sin(a);
                double vx = ux * ca - uy * sa, vy = ux * sa + uy * ca, nx = -vy, ny = vx;
                double hw = w / 2, hd = d / 2 - 0.5;
                char props[96];
                int kind = written % 4;
                if (kind == 0)
                    snprintf(props, sizeof props, "\"building\":\"yes\"");
                else if (kind == 1)
                    snprintf(props, sizeof props, "\"building\":\"yes\",\"building:levels\":%u", 2 + sl_rng_below(&r, 7));
                else
                    snprintf(props, sizeof props, "\"building\":\"yes\",\"height\":\"%.1f\"", 8 + 30 * sl_rng_double(&r));
                fprintf(f, "{\"type\":\"Feature\",\"properties\":{%s},\"geometry\":{\"type\":\"Polygon\",\"coordinates\":[",
                        props);
                double p[12];
                int np = 4;
                double cs[4][2] = {{-hw, -hd}, {hw, -hd}, {hw, hd}, {-hw, hd}};
                if (written % 5 == 4) { /* an L: a notch out of one corner */
                    double l[6][2] = {{-hw, -hd}, {hw, -hd}, {hw, 0}, {0, 0}, {0, hd}, {-hw, hd}};
                    for (int q = 0; q < 6; q++)
                        p[2 * q] = cx + l[q][0] * vx + l[q][1] * nx, p[2 * q + 1] = cy + l[q][0] * vy + l[q][1] * ny;
                    np = 6;
                } else {
                    for (int q = 0; q < 4; q++)
                        p[2 * q] = cx + cs[q][0] * vx + cs[q][1] * nx, p[2 * q + 1] = cy + cs[q][0] * vy + cs[q][1] * ny;
                }
                ring(f, p, np);
                if (written % 7 == 6 && np == 4) { /* a courtyard */
                    double h[8], s = 0.3;
                    for (int q = 0; q < 4; q++)
                        h[2 * q] = cx + s * cs[3 - q][0] * vx + s * cs[3 - q][1] * nx,
                                  h[2 * q + 1] = cy + s * cs[3 - q][0] * vy + s * cs[3 - q][1] * ny;
                    fprintf(f, ",");
                    ring(f, h, 4);
                }
                fprintf(f, "]}},\n");
                written++;
            }
        }
    for (int d = 0; d < 2; d++)
        for (int k = 0; k <= blocks; k++) {
            fprintf(f, "{\"type\":\"Feature\",\"properties\":{\"highway\":\"%s\"},\"geometry\":{\"type\":\"LineString\","
                       "\"coordinates\":[", k % 4 == 0 ? "primary" : "residential");
            for (int m = 0; m <= blocks; m++) {
                double x = d ? m * pitch : k * pitch, y = d ? k * pitch : m * pitch;
                fprintf(f, "%s[%.8f,%.8f]", m ? "," : "", lon_of(x), lat_of(y));
            }
            fprintf(f, "]}}%s\n", d == 1 && k == blocks ? "" : ",");
        }
    fprintf(f, "]}\n");
    if (fclose(f) != 0)
        die("cannot write the GeoJSON file");
    return written;
}

int main(int argc, char **argv)
{
    int n = 4000, runs = 5;
    uint64_t seed = 1;
    const char *geojson = "/tmp/sl_bench_gis.geojson", *scene_out = NULL;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--buildings") && v)
            n = atoi(v), i++;
        else if (!strcmp(a, "--runs") && v)
            runs = atoi(v), i++;
        else if (!strcmp(a, "--seed") && v)
            seed = strtoull(v, NULL, 10), i++;
        else if (!strcmp(a, "--geojson") && v)
            geojson = v, i++;
        else if (!strcmp(a, "--scene") && v)
            scene_out = v, i++;
        else {
            fprintf(stderr, "usage: bench_gis_import [--buildings N] [--seed S] [--runs R] [--geojson PATH] [--scene PATH]\n");
            return strcmp(a, "--help") ? 2 : 0;
        }
    }
    if (n < 1 || n > 1000000 || runs < 1 || runs > 100)
        die("--buildings 1..1000000, --runs 1..100");
    int written = write_city(geojson, n, seed);
    double *wall = calloc((size_t)runs, sizeof(double)), *cpu = calloc((size_t)runs, sizeof(double));
    if (!wall || !cpu)
        die("out of memory");
    sl_gis_stats st;
    sl_scene s = NULL;
    sl_error err;
    for (int k = -1; k < runs; k++) {
        double w0 = now(CLOCK_MONOTONIC), c0 = now(CLOCK_THREAD_CPUTIME_ID);
        if (sl_import_gis(geojson, NULL, NULL, &s, &st, &err) != SL_OK)
            die(err.message);
        double w1 = now(CLOCK_MONOTONIC), c1 = now(CLOCK_THREAD_CPUTIME_ID);
        if (k >= 0)
            wall[k] = w1 - w0, cpu[k] = c1 - c0;
        if (k + 1 < runs)
            sl_scene_destroy(s);
    }
    qsort(wall, (size_t)runs, sizeof(double), bench_cmp_double);
    qsort(cpu, (size_t)runs, sizeof(double), bench_cmp_double);
    sl_scene_stats ss;
    sl_scene_get_stats(s, &ss);
    char machine[320];
    bench_machine(machine, sizeof machine);
    FILE *gf = fopen(geojson, "rb");
    long bytes = 0;
    if (gf && fseek(gf, 0, SEEK_END) == 0)
        bytes = ftell(gf);
    if (gf)
        fclose(gf);
    printf("# bench_gis_import: %s (%.1f MiB GeoJSON, seed %llu), %d runs after a warm-up; %s\n\n", geojson,
           (double)bytes / 1048576.0, (unsigned long long)seed, runs, machine);
    printf("| footprints written | buildings | footprints | polygons | street segments | graph nodes | triangles | "
           "default heights | repaired | import s (median wall) | import s (median thread CPU) | buildings/s |\n");
    printf("|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|--:|\n");
    printf("| %d | %u | %u | %u | %u | %u | %llu | %u | %u | %.3f | %.3f | %.0f |\n", written, st.buildings, st.footprints,
           st.building_parts, st.street_segments, st.street_nodes, (unsigned long long)ss.triangle_count, st.default_height,
           st.repaired, wall[runs / 2], cpu[runs / 2], st.buildings / wall[runs / 2]);
    if (scene_out) {
        if (sl_scene_save(s, scene_out, &err) != SL_OK)
            die(err.message);
        printf("\nscene saved to %s (%u objects)\n", scene_out, ss.object_count);
    }
    sl_scene_destroy(s);
    free(wall);
    free(cpu);
    return 0;
}
