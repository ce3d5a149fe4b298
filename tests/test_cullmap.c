/* The cull map: the conservative shadow rasterizer of src/raster/cullmap_raster.c checked cell by
 * cell against exact geometry (coverage, heights, floors, seams without cracks), and the cullmap
 * culler on hand-built scenes (a wall in front of a box, the orthographic fallback, moved objects,
 * options) and its PNG output. The zero-miss runs against the oracle on generated cities are in
 * test_urban_oracle.c. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "raster/cullmap_raster.h"
#include "sightline/cull.h"
#include "sightline/image.h"
#include "sightline/truth.h"
#include "sightline/urban.h"
#include "support/counting_alloc.h"

/* ---- the rasterizer against exact geometry ---- */

#define MAP_N 64
#define MAP_CELL 1.0
#define MAP_MIN (-32.0)

typedef struct test_map {
    float z[MAP_N * MAP_N];
    float floor[MAP_N * MAP_N];
    sl_cullmap_part part[MAP_N * MAP_N];
    int32_t x0[MAP_N], x1[MAP_N];
    sl_cullmap_grid g;
    sl_cullmap_clip clip;
} test_map;

static void map_init(test_map *m, bool with_floor)
{
    for (int i = 0; i < MAP_N * MAP_N; i++) {
        m->z[i] = -INFINITY;
        m->floor[i] = 0.0f;
    }
    for (int j = 0; j < MAP_N; j++)
        m->x0[j] = 0, m->x1[j] = MAP_N - 1;
    memset(&m->g, 0, sizeof m->g);
    m->g.nx = m->g.ny = MAP_N;
    m->g.min_x = m->g.min_y = MAP_MIN;
    m->g.cell = MAP_CELL;
    m->g.margin = 1e-6;
    m->g.z = m->z;
    m->g.floor = with_floor ? m->floor : NULL;
    m->g.useful_min = -INFINITY;
    m->clip = (sl_cullmap_clip){0, MAP_N - 1, 0, MAP_N - 1, m->x0, m->x1};
}

static double cross2(double ax, double ay, double bx, double by) { return ax * by - ay * bx; }

/* Is X in the shadow wedge of e seen from eye (between the rays, behind the edge)? */
static bool in_wedge(const double eye[3], const sl_shadow_edge *e, double x, double y)
{
    double ax = e->ax - eye[0], ay = e->ay - eye[1], bx = e->bx - eye[0], by = e->by - eye[1];
    double px = x - eye[0], py = y - eye[1];
    if (cross2(ax, ay, px, py) > 1e-9 || cross2(bx, by, px, py) < -1e-9)
        return false;
    /* behind: on the far side of the edge line from the eye */
    double dx = e->bx - e->ax, dy = e->by - e->ay;
    double se = cross2(dx, dy, eye[0] - e->ax, eye[1] - e->ay), sx = cross2(dx, dy, x - e->ax, y - e->ay);
    return se * sx <= 1e-9 * fabs(se);
}

/* Height of the plane through the eye and the edge at height z (z at both ends) at (x, y). */
static double plane_at(const double eye[3], const sl_shadow_edge *e, double za, double zb, double x, double y)
{
    double ax = e->ax - eye[0], ay = e->ay - eye[1], az = za - eye[2];
    double bx = e->bx - eye[0], by = e->by - eye[1], bz = zb - eye[2];
    double nx = ay * bz - az * by, ny = az * bx - ax * bz, nz = ax * by - ay * bx;
    return eye[2] - (nx * (x - eye[0]) + ny * (y - eye[1])) / nz;
}

/* Check every written cell: each of its sample points lies in some wedge of the chain, with the
 * cell's value at most that wedge's top plane there and its floor above the bottom plane. Returns
 * the number of written cells. */
static int check_cells(const test_map *m, const double eye[3], const sl_shadow_edge *chain, int n, sl_rng *r)
{
    int written = 0;
    for (int j = 0; j < MAP_N; j++)
        for (int i = 0; i < MAP_N; i++) {
            float v = m->z[j * MAP_N + i];
            if (v == -INFINITY)
                continue;
            written++;
            for (int s = 0; s < 45; s++) {
                double fx, fy;
                if (s < 25)
                    fx = (s % 5) / 4.0, fy = (s / 5) / 4.0;
                else
                    fx = sl_rng_double(r), fy = sl_rng_double(r);
                double x = m->g.min_x + (i + fx) * m->g.cell, y = m->g.min_y + (j + fy) * m->g.cell;
                bool covered = false;
                for (int k = 0; k < n && !covered; k++) {
                    if (!in_wedge(eye, &chain[k], x, y))
                        continue;
                    double top = plane_at(eye, &chain[k], chain[k].az, chain[k].bz, x, y);
                    double bot = plane_at(eye, &chain[k], chain[k].base, chain[k].base, x, y);
                    double fl = m->g.floor ? (double)m->floor[j * MAP_N + i] : INFINITY;
                    covered = (double)v <= top + 1e-6 && bot <= fl + 1e-6;
                }
                if (!covered) {
                    fprintf(stderr, "cell (%d,%d) value %g: point (%g,%g) not in any shadow below it\n", i, j,
                            (double)v, x, y);
                    fail();
                }
            }
        }
    return written;
}

static void test_raster_single_edges(void **state)
{
    (void)state;
    sl_rng r;
    sl_rng_seed(&r, 11, 1);
    test_map *m = malloc(sizeof *m);
    int total = 0;
    for (int t = 0; t < 300; t++) {
        bool with_floor = t % 2;
        map_init(m, with_floor);
        for (int c = 0; c < MAP_N * MAP_N; c++)
            m->floor[c] = sl_rng_range(&r, -3, 2);
        double eye[3] = {sl_rng_range(&r, -30, 30), sl_rng_range(&r, -30, 30), sl_rng_range(&r, 0, 25)};
        sl_shadow_edge e;
        e.ax = sl_rng_range(&r, -30, 30), e.ay = sl_rng_range(&r, -30, 30);
        double ang = sl_rng_range(&r, 0, 6.283f), len = sl_rng_range(&r, 0.2f, 20);
        e.bx = e.ax + len * cos(ang), e.by = e.ay + len * sin(ang);
        e.base = sl_rng_range(&r, -1, 3);
        e.az = e.base + sl_rng_range(&r, 0.5f, 30);
        e.bz = t % 3 == 0 ? e.az + sl_rng_range(&r, -3, 3) : e.az; /* some sloped tops */
        /* orient with the eye in front (clockwise seen from the eye) */
        if (cross2(e.ax - eye[0], e.ay - eye[1], e.bx - eye[0], e.by - eye[1]) > 0) {
            double tx = e.ax, ty = e.ay, tz = e.az;
            e.ax = e.bx, e.ay = e.by, e.az = e.bz;
            e.bx = tx, e.by = ty, e.bz = tz;
        }
        uint64_t w = sl_cullmap_raster_wedge(&m->g, eye, &e, 1, 0, &m->clip);
        int cells = check_cells(m, eye, &e, 1, &r);
        assert_int_equal((int)w, cells);
        total += cells;
    }
    assert_true(total > 5000); /* the shadows do cover cells */
    /* an edge that does not face the eye yields nothing */
    map_init(m, false);
    double eye[3] = {0, 0, 2};
    sl_shadow_edge back = {5, -3, 10, 5, 3, 10, 0}; /* counter-clockwise seen from the eye */
    assert_int_equal(sl_cullmap_raster_wedge(&m->g, eye, &back, 1, 0, &m->clip), 0);
    free(m);
}

/* A convex polygon (CCW), its front-facing run from the eye as a chain, oriented. */
static int front_chain(const double (*p)[2], int n, const double eye[3], double h, sl_shadow_edge *out)
{
    int start = -1;
    bool front[16];
    for (int k = 0; k < n; k++) {
        const double *a = p[k], *b = p[(k + 1) % n];
        front[k] = cross2(a[0] - eye[0], a[1] - eye[1], b[0] - eye[0], b[1] - eye[1]) < 0;
    }
    for (int k = 0; k < n; k++)
        if (front[k] && !front[(k + n - 1) % n])
            start = k;
    if (start < 0)
        return 0;
    int m = 0;
    for (int k = start; front[k % n] && m < n; k++, m++) {
        const double *a = p[k % n], *b = p[(k + 1) % n];
        out[m] = (sl_shadow_edge){a[0], a[1], h, b[0], b[1], h, 0.0};
    }
    return m;
}

/* Separate occluders whose shadows overlap: cells straddling their silhouette rays are covered by
 * the two together (partial coverage), and every written cell is still sound. */
static void test_raster_partial(void **state)
{
    (void)state;
    sl_rng r;
    sl_rng_seed(&r, 13, 1);
    test_map *m = malloc(sizeof *m);
    int fused = 0;
    for (int t = 0; t < 200; t++) {
        map_init(m, t % 2 == 0);
        for (int c = 0; c < MAP_N * MAP_N; c++)
            m->floor[c] = sl_rng_range(&r, -1, 1);
        memset(m->part, 0, sizeof m->part);
        m->g.part = m->part;
        m->g.stamp = 1;
        double eye[3] = {sl_rng_range(&r, -28, -20), sl_rng_range(&r, -10, 10), sl_rng_range(&r, 0.5f, 5)};
        /* three walls facing the eye at different depths, their ends overlapping in azimuth */
        sl_shadow_edge e[3];
        double ang = sl_rng_range(&r, -0.4f, 0.4f);
        for (int k = 0; k < 3; k++) {
            double d = 10 + 8 * k + sl_rng_range(&r, 0, 4), h = sl_rng_range(&r, 8, 25);
            double a0 = ang + (k - 1) * 0.25 - sl_rng_range(&r, 0.12f, 0.2f), a1 = ang + (k - 1) * 0.25 + sl_rng_range(&r, 0.12f, 0.2f);
            /* counter-clockwise first point, then clockwise: a -> b turns clockwise seen from the eye */
            e[k] = (sl_shadow_edge){eye[0] + d * cos(a1), eye[1] + d * sin(a1), h, eye[0] + d * cos(a0), eye[1] + d * sin(a0), h,
                                    sl_rng_range(&r, -0.5f, 0.5f)};
        }
        for (int k = 0; k < 3; k++)
            sl_cullmap_raster_wedge(&m->g, eye, &e[k], 1, 0, &m->clip);
        check_cells(m, eye, e, 3, &r);
        /* count the cells written although no single shadow holds them */
        for (int j = 0; j < MAP_N; j++)
            for (int i = 0; i < MAP_N; i++) {
                if (m->z[j * MAP_N + i] == -INFINITY)
                    continue;
                double x = MAP_MIN + (i + 0.5) * MAP_CELL, y = MAP_MIN + (j + 0.5) * MAP_CELL;
                bool single = false;
                for (int k = 0; k < 3 && !single; k++) {
                    bool all = true;
                    for (int q = 0; q < 4 && all; q++)
                        all = in_wedge(eye, &e[k], x + ((q & 1) ? 0.5 : -0.5), y + ((q & 2) ? 0.5 : -0.5));
                    single = all;
                }
                fused += !single;
            }
    }
    assert_true(fused > 100);
    free(m);
}

/* The unsaturated-cell bits agree with the map: on the clip, a cell's row bit is set exactly when
 * its value is below its top, and each band's count and bit of a column say how many of its cells
 * there are unsaturated. */
static void check_bits(const test_map *m, const float *top)
{
    const sl_cullmap_grid *g = &m->g;
    for (int j = 0; j < MAP_N; j++)
        for (int i = 0; i < MAP_N; i++) {
            bool un = m->z[j * MAP_N + i] < top[j * MAP_N + i];
            assert_int_equal((int)((g->row_bits[j * g->words] >> i) & 1), (int)un);
        }
    for (int b = 0; b < MAP_N / 8; b++)
        for (int i = 0; i < MAP_N; i++) {
            int n = 0;
            for (int j = 8 * b; j < 8 * b + 8; j++)
                n += m->z[j * MAP_N + i] < top[j * MAP_N + i];
            assert_int_equal((int)g->band_count[b * MAP_N + i], n);
            assert_int_equal((int)((g->band_bits[b * g->words] >> i) & 1), n > 0);
        }
}

/* Everything at once, with cells as wide as the shadows: silhouette chains of convex buildings
 * (seams), separate walls (partial coverage), floors, saturation against random cell tops and
 * the block skipping, half the time with the unsaturated-cell bits (then only the unsaturated
 * cells are visited); every written cell must stay sound, and the bits true. */
static void test_raster_mixed(void **state)
{
    (void)state;
    sl_rng r;
    sl_rng_seed(&r, 14, 1);
    test_map *m = malloc(sizeof *m);
    static float top[MAP_N * MAP_N];
    static uint16_t unsat[(MAP_N / 8) * (MAP_N / 8) + 1];
    static uint64_t row_bits[MAP_N], band_bits[MAP_N / 8];
    static uint8_t band_count[(MAP_N / 8) * MAP_N];
    int written = 0, written_bits = 0;
    for (int t = 0; t < 600; t++) {
        map_init(m, t % 3 != 0);
        for (int c = 0; c < MAP_N * MAP_N; c++) {
            m->floor[c] = sl_rng_range(&r, -1, 1);
            top[c] = t % 2 ? sl_rng_range(&r, 0, 40) : INFINITY;
        }
        memset(m->part, 0, sizeof m->part);
        memset(unsat, 0, sizeof unsat);
        m->g.part = m->part;
        m->g.stamp = 1;
        m->g.top = top;
        m->g.unsat = unsat;
        m->g.block_shift = 3;
        m->g.bnx = MAP_N / 8;
        const bool bits = t % 4 >= 2;
        if (bits) {
            memset(row_bits, 0, sizeof row_bits);
            memset(band_bits, 0, sizeof band_bits);
            memset(band_count, 0, sizeof band_count);
            m->g.row_bits = row_bits;
            m->g.band_bits = band_bits;
            m->g.band_count = band_count;
            m->g.words = 1;
        }
        /* cells as wide as the shadows: 2 to 5 m cells over the same 64 x 64 map */
        m->g.cell = 2.0 + (t % 4);
        m->g.min_x = m->g.min_y = -32.0 * m->g.cell;
        sl_cullmap_clear(&m->g, &m->clip);
        double eye[3] = {sl_rng_range(&r, -28, -18), sl_rng_range(&r, -12, 12), sl_rng_range(&r, 0.5f, 30)};
        sl_shadow_edge all[40];
        int na = 0;
        for (int b = 0; b < 5; b++) {
            /* a small convex building: its front chain, drawn with seams */
            int n = 4 + (int)sl_rng_below(&r, 4);
            double cx = sl_rng_range(&r, -10, 20), cy = sl_rng_range(&r, -20, 20), rad = sl_rng_range(&r, 0.8f, 4);
            double p[16][2], a0 = sl_rng_range(&r, 0, 6.28f);
            for (int k = 0; k < n; k++) {
                double a = a0 + 6.2831853 * k / n;
                p[k][0] = cx + rad * cos(a), p[k][1] = cy + rad * sin(a);
            }
            double h = sl_rng_range(&r, 5, 30);
            sl_shadow_edge chain[16];
            int nc = front_chain((const double(*)[2])p, n, eye, h, chain);
            for (int k = 0; k < nc; k++) {
                int lo = k - SL_CULLMAP_MAX_SEAM < 0 ? 0 : k - SL_CULLMAP_MAX_SEAM;
                int hi = k + SL_CULLMAP_MAX_SEAM >= nc ? nc - 1 : k + SL_CULLMAP_MAX_SEAM;
                sl_cullmap_raster_wedge(&m->g, eye, chain + lo, (uint32_t)(hi - lo + 1), (uint32_t)(k - lo), &m->clip);
            }
            for (int k = 0; k < nc && na < 40; k++)
                all[na++] = chain[k];
        }
        for (int w = 0; w < 6 && na < 40; w++) {
            /* separate walls facing the eye */
            double d = sl_rng_range(&r, 6, 40), a = sl_rng_range(&r, -0.6f, 0.6f), half = sl_rng_range(&r, 0.05f, 0.3f);
            double h = sl_rng_range(&r, 3, 30);
            sl_shadow_edge e = {eye[0] + d * cos(a + half), eye[1] + d * sin(a + half), h,
                                eye[0] + d * cos(a - half), eye[1] + d * sin(a - half), h, 0.0};
            sl_cullmap_raster_wedge(&m->g, eye, &e, 1, 0, &m->clip);
            all[na++] = e;
        }
        int w = check_cells(m, eye, all, na, &r);
        written += w;
        if (bits) {
            written_bits += w;
            check_bits(m, top);
        }
    }
    assert_true(written > 3000);
    assert_true(written_bits > 1000);
    free(m);
}

static void test_raster_seams(void **state)
{
    (void)state;
    sl_rng r;
    sl_rng_seed(&r, 12, 1);
    test_map *m = malloc(sizeof *m);
    int cracks_checked = 0;
    for (int t = 0; t < 150; t++) {
        map_init(m, false);
        /* a convex polygon around a centre, edges of a few cells */
        int n = 4 + (int)sl_rng_below(&r, 5);
        double cx = sl_rng_range(&r, -10, 10), cy = sl_rng_range(&r, -10, 10), rad = sl_rng_range(&r, 3, 8);
        double p[16][2], a0 = sl_rng_range(&r, 0, 6.28f);
        for (int k = 0; k < n; k++) {
            double a = a0 + 6.2831853 * k / n;
            p[k][0] = cx + rad * cos(a), p[k][1] = cy + rad * sin(a);
        }
        double ang = sl_rng_range(&r, 0, 6.28f), dist = rad + sl_rng_range(&r, 6, 14);
        double eye[3] = {cx + dist * cos(ang), cy + dist * sin(ang), sl_rng_range(&r, 0.5f, 8)};
        double h = 12 + sl_rng_range(&r, 0, 10);
        sl_shadow_edge chain[16];
        int nc = front_chain((const double(*)[2])p, n, eye, h, chain);
        assert_true(nc >= 1);
        for (int k = 0; k < nc; k++) {
            /* the window: at most SL_CULLMAP_MAX_SEAM on each side */
            int lo = k - SL_CULLMAP_MAX_SEAM < 0 ? 0 : k - SL_CULLMAP_MAX_SEAM;
            int hi = k + SL_CULLMAP_MAX_SEAM >= nc ? nc - 1 : k + SL_CULLMAP_MAX_SEAM;
            sl_cullmap_raster_wedge(&m->g, eye, chain + lo, (uint32_t)(hi - lo + 1), (uint32_t)(k - lo), &m->clip);
        }
        check_cells(m, eye, chain, nc, &r);
        /* no cracks: every cell whose points all lie in the union of the shadows is written */
        for (int j = 0; j < MAP_N; j++)
            for (int i = 0; i < MAP_N; i++) {
                double x0 = MAP_MIN + i * MAP_CELL, y0 = MAP_MIN + j * MAP_CELL;
                if (hypot(x0 + 0.5 - eye[0], y0 + 0.5 - eye[1]) < 4)
                    continue;
                bool all = true;
                for (int s = 0; s < 81 && all; s++) {
                    double x = x0 - 1e-3 + (s % 9) / 8.0 * (MAP_CELL + 2e-3), y = y0 - 1e-3 + (s / 9) / 8.0 * (MAP_CELL + 2e-3);
                    bool in = false;
                    for (int k = 0; k < nc && !in; k++)
                        in = in_wedge(eye, &chain[k], x, y);
                    all = in;
                }
                if (all) {
                    cracks_checked++;
                    if (m->z[j * MAP_N + i] == -INFINITY) {
                        fprintf(stderr, "trial %d: cell (%d,%d) lies in the shadows but was not written\n", t, i, j);
                        fail();
                    }
                }
            }
    }
    assert_true(cracks_checked > 10000);
    free(m);
}

/* ---- the culler on hand-built scenes ---- */

static uint32_t add_box(sl_scene s, sl_vec3 lo, sl_vec3 hi, uint32_t kind)
{
    float p[24];
    for (int i = 0; i < 8; i++) {
        p[3 * i] = (i & 1) ? hi.x : lo.x;
        p[3 * i + 1] = (i & 2) ? hi.y : lo.y;
        p[3 * i + 2] = (i & 4) ? hi.z : lo.z;
    }
    static const uint32_t idx[36] = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                     2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};
    sl_error err;
    sl_mesh_desc md = {p, NULL, 8, idx, 12, NULL};
    uint32_t mesh, obj;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, NULL, 0xffffffffu, kind, kind == SL_KIND_BUILDING ? SL_OBJECT_OCCLUDER : 0, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &obj, &err), SL_OK);
    return obj;
}

/* A building: a box mesh and its footprint (the same rectangle). */
static uint32_t add_building(sl_scene s, float x0, float y0, float x1, float y1, float h)
{
    uint32_t obj = add_box(s, (sl_vec3){x0, y0, 0}, (sl_vec3){x1, y1, h}, SL_KIND_BUILDING);
    float xy[8] = {x0, y0, x1, y0, x1, y1, x0, y1};
    sl_footprint_desc fd = {xy, 4, 0.0f, h, obj};
    sl_error err;
    assert_int_equal(sl_scene_add_footprint(s, &fd, NULL, &err), SL_OK);
    return obj;
}

static bool has(const uint32_t *ids, uint32_t n, uint32_t id)
{
    for (uint32_t i = 0; i < n; i++)
        if (ids[i] == id)
            return true;
    return false;
}

static void test_wall_hides_box(void **state)
{
    (void)state;
    sl_test_counter ctr = {0};
    sl_allocator a = sl_test_counting_allocator(&ctr);
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(&a, &s, &err), SL_OK);
    uint32_t ground = add_box(s, (sl_vec3){-100, -100, -0.1f}, (sl_vec3){100, 100, 0}, SL_KIND_GROUND);
    uint32_t wall = add_building(s, 20, -30, 26, 30, 15);
    uint32_t hidden = add_box(s, (sl_vec3){40, -2, 0}, (sl_vec3){44, 2, 8}, SL_KIND_CAR);
    uint32_t tall = add_box(s, (sl_vec3){60, -2, 0}, (sl_vec3){64, 2, 60}, SL_KIND_OTHER); /* above the wall */
    uint32_t beside = add_box(s, (sl_vec3){40, 70, 0}, (sl_vec3){44, 74, 3}, SL_KIND_CAR);  /* past the end */
    sl_camera cam = sl_camera_default();
    cam.position = (sl_vec3){0, 0, 1.7f};
    cam.yaw = 0.5f;
    cam.width = 320, cam.height = 240;
    sl_oracle oracle;
    assert_int_equal(sl_oracle_create(s, NULL, &a, &oracle, &err), SL_OK);
    sl_oracle_frame fr;
    assert_int_equal(sl_oracle_render(oracle, &cam, &fr, &err), SL_OK);
    const char *methods[] = {"cullmap", "cullmap", "horizon", "dhorizon"};
    const char *opts[] = {"", "cell=2,radius=100", "", "cell=4"};
    for (int m = 0; m < 4; m++) {
        sl_culler c;
        assert_int_equal(sl_culler_create(methods[m], s, opts[m], &a, &c, &err), SL_OK);
        uint32_t ids[8], n;
        for (int rep = 0; rep < 2; rep++) { /* twice: dhorizon's second frame reuses the first */
            assert_int_equal(sl_culler_cull(c, &cam, ids, 8, &n, &err), SL_OK);
            for (uint32_t k = 0; k < fr.visible_count; k++)
                assert_true(has(ids, n, fr.visible[k]));
            assert_true(has(ids, n, wall));
            assert_true(has(ids, n, ground));
            assert_true(has(ids, n, tall));
            assert_true(has(ids, n, beside));
            assert_false(has(ids, n, hidden));
        }
        sl_culler_destroy(c);
    }
    sl_oracle_destroy(oracle);
    sl_scene_destroy(s);
    assert_int_equal(ctr.live, 0);
}

static void test_moving_and_orthographic(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_building(s, 20, -30, 26, 30, 15);
    uint32_t car = add_box(s, (sl_vec3){40, -2, 0}, (sl_vec3){44, 2, 1.5f}, SL_KIND_CAR);
    sl_camera cam = sl_camera_default();
    cam.position = (sl_vec3){0, 0, 1.7f};
    cam.yaw = 0.6f;
    const char *methods[] = {"cullmap", "horizon", "dhorizon"};
    for (int m = 0; m < 3; m++) {
        sl_culler c;
        assert_int_equal(sl_culler_create(methods[m], s, NULL, NULL, &c, &err), SL_OK);
        uint32_t ids[4], n;
        assert_int_equal(sl_culler_cull(c, &cam, ids, 4, &n, &err), SL_OK);
        assert_false(has(ids, n, car));
        /* the car drives out from behind the wall */
        sl_affine t = sl_affine_identity();
        t.m[7] = 80.0f;
        assert_int_equal(sl_scene_set_object_transform(s, car, &t, &err), SL_OK);
        assert_int_equal(sl_culler_scene_changed(c, &err), SL_OK);
        assert_int_equal(sl_culler_cull(c, &cam, ids, 4, &n, &err), SL_OK);
        assert_true(has(ids, n, car));
        /* and back */
        t.m[7] = 0.0f;
        assert_int_equal(sl_scene_set_object_transform(s, car, &t, &err), SL_OK);
        assert_int_equal(sl_culler_scene_changed(c, &err), SL_OK);
        assert_int_equal(sl_culler_cull(c, &cam, ids, 4, &n, &err), SL_OK);
        assert_false(has(ids, n, car));
        /* an orthographic camera has no eye point: frustum culling only, so the car is kept */
        sl_camera o = cam;
        o.projection = SL_ORTHOGRAPHIC;
        o.ortho_height = 40;
        assert_int_equal(sl_culler_cull(c, &o, ids, 4, &n, &err), SL_OK);
        assert_true(has(ids, n, car));
        sl_culler_destroy(c);
    }
    sl_scene_destroy(s);
}

static void test_options(void **state)
{
    (void)state;
    sl_error err;
    assert_int_equal(sl_cull_method_check_options("cullmap", "cell=4,radius=500", &err), SL_OK);
    assert_int_equal(sl_cull_method_check_options("cullmap", "cell=0.1", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "cell"));
    assert_int_equal(sl_cull_method_check_options("cullmap", "bins=4096", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "radius"));
    assert_int_equal(sl_cull_method_check_options("horizon", "bins=4096,cell=2", &err), SL_OK);
    assert_int_equal(sl_cull_method_check_options("horizon", "bins=12", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_cull_method_check_options("dhorizon", "max_move=2,max_turn=10,parallax=on", &err), SL_OK);
    assert_int_equal(sl_cull_method_check_options("dhorizon", "max_turn=400", &err), SL_ERROR_INVALID_ARGUMENT);
    uint32_t i;
    sl_cull_method_desc d;
    const char *names[] = {"cullmap", "horizon", "dhorizon"};
    for (int k = 0; k < 3; k++) {
        assert_int_equal(sl_cull_method_find(names[k], &i, &err), SL_OK);
        assert_int_equal(sl_cull_method_info(i, &d, &err), SL_OK);
        assert_int_equal(d.guarantee, SL_CONSERVATIVE);
        assert_non_null(strstr(d.options_help, "cell="));
    }
    /* dhorizon without the parallax bound is the thesis' plain test: aggressive */
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_building(s, 0, 0, 10, 10, 10);
    sl_culler c;
    assert_int_equal(sl_culler_create("dhorizon", s, "parallax=false", NULL, &c, &err), SL_OK);
    assert_int_equal(sl_culler_guarantee(c), SL_AGGRESSIVE);
    sl_culler_destroy(c);
    sl_scene_destroy(s);
}

/* The small town of the image tests: ground, two buildings and a car. */
static sl_scene png_scene(void)
{
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    add_box(s, (sl_vec3){-100, -100, -0.1f}, (sl_vec3){100, 100, 0}, SL_KIND_GROUND);
    add_building(s, 20, -30, 26, 30, 15);
    add_building(s, -40, 20, -10, 30, 25);
    add_box(s, (sl_vec3){40, -2, 0}, (sl_vec3){44, 2, 1.5f}, SL_KIND_CAR);
    return s;
}

static void test_render_png(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s = png_scene();
    sl_camera cam = sl_camera_default();
    cam.position = (sl_vec3){0, 0, 1.7f};
    char path[512];
    snprintf(path, sizeof path, "%s/test_cullmap_%ld.png", SL_BINARY_DIR, (long)getpid());
    assert_int_equal(sl_cullmap_render_png(s, &cam, "cell=2", path, &err), SL_OK);
    uint8_t *px;
    uint32_t w, h;
    assert_int_equal(sl_png_read_rgba(path, NULL, &px, &w, &h, &err), SL_OK);
    assert_int_equal(w, 100 * 10); /* 200 m at 2 m cells, 10 pixels per cell */
    assert_true(h >= 900);
    /* the eye's pixel is red */
    bool red = false;
    for (size_t k = 0; k < (size_t)w * h; k++)
        red |= px[4 * k] == 0xFF && px[4 * k + 1] == 0x20 && px[4 * k + 2] == 0x20;
    assert_true(red);
    sl_free(NULL, px, (size_t)w * h * 4);
    unlink(path);
    /* bad options and a bad path fail cleanly, without a file */
    assert_int_equal(sl_cullmap_render_png(s, &cam, "radius=-1", path, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_not_equal(sl_cullmap_render_png(s, &cam, NULL, "/nonexistent-dir/x.png", &err), SL_OK);
    assert_int_equal(access(path, F_OK), -1);
    sl_scene_destroy(s);
}

/* Read a PNG written to path (RGBA) and remove the file. */
static uint8_t *read_png(const char *path, uint32_t *w, uint32_t *h)
{
    sl_error err;
    uint8_t *px;
    assert_int_equal(sl_png_read_rgba(path, NULL, &px, w, h, &err), SL_OK);
    unlink(path);
    return px;
}

/* The view forms of the images (issue 13 §1): the cull map and the depth image of a view from a
 * camera are byte for byte those of the camera; the cull map of the camera's own matrices differs
 * from it in a few pixels at most (float rounding of the frustum's plan), an off-axis view's in
 * many (its plan turns aside); an infinite far plane is bounded by the scene; the depth image
 * refuses one. */
static void test_render_png_view(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s = png_scene();
    sl_camera cam = sl_camera_default();
    cam.position = (sl_vec3){0, 0, 1.7f};
    cam.yaw = 0.3f;
    cam.width = 320;
    cam.height = 240;
    cam.far_plane = 150;
    char path[512];
    snprintf(path, sizeof path, "%s/test_cullmap_view_%ld.png", SL_BINARY_DIR, (long)getpid());
    uint32_t w0, h0, w, h;
    assert_int_equal(sl_cullmap_render_png(s, &cam, "cell=2", path, &err), SL_OK);
    uint8_t *ref = read_png(path, &w0, &h0);
    const size_t n = (size_t)w0 * h0;
    /* the view of the camera: the same bytes */
    sl_view v;
    assert_int_equal(sl_view_from_camera(&cam, &v, &err), SL_OK);
    assert_int_equal(sl_cullmap_render_png_view(s, &v, "cell=2", path, &err), SL_OK);
    uint8_t *px = read_png(path, &w, &h);
    assert_true(w == w0 && h == h0);
    assert_memory_equal(px, ref, n * 4);
    sl_free(NULL, px, n * 4);
    /* the camera's matrices, given as an engine's */
    sl_mat4 V = sl_camera_view(&cam), P = sl_camera_proj(&cam);
    sl_view vm;
    assert_int_equal(sl_view_from_matrices(V.m, P.m, SL_CLIP_DEPTH_GL, 320, 240, &vm, &err), SL_OK);
    assert_int_equal(sl_cullmap_render_png_view(s, &vm, "cell=2", path, &err), SL_OK);
    px = read_png(path, &w, &h);
    assert_true(w == w0 && h == h0);
    size_t diff_same = 0;
    for (size_t k = 0; k < n; k++)
        diff_same += memcmp(px + 4 * k, ref + 4 * k, 4) != 0;
    sl_free(NULL, px, n * 4);
    /* off-axis: the near rectangle shifted by half its width (P02 = 1: column-major m[8]) */
    float Po[16];
    memcpy(Po, P.m, sizeof Po);
    Po[8] = 1.0f;
    sl_view vo;
    assert_int_equal(sl_view_from_matrices(V.m, Po, SL_CLIP_DEPTH_GL, 320, 240, &vo, &err), SL_OK);
    assert_true(vo.rect_left != -vo.rect_right);
    assert_int_equal(sl_cullmap_render_png_view(s, &vo, "cell=2", path, &err), SL_OK);
    px = read_png(path, &w, &h);
    size_t diff_off = 0;
    for (size_t k = 0; k < n; k++)
        diff_off += memcmp(px + 4 * k, ref + 4 * k, 4) != 0;
    sl_free(NULL, px, n * 4);
    print_message("cull map of the camera's matrices: %zu pixels differ; off-axis: %zu (of %zu)\n", diff_same, diff_off, n);
    assert_true(diff_same * 200 < n);
    assert_true(diff_off > 20 * (diff_same + 1));
    /* an infinite far plane: bounded by the scene */
    sl_view vi;
    assert_int_equal(sl_view_with_far(&vm, INFINITY, &vi, &err), SL_OK);
    assert_int_equal(sl_cullmap_render_png_view(s, &vi, "cell=2", path, &err), SL_OK);
    sl_free(NULL, read_png(path, &w, &h), (size_t)w * h * 4);
    /* a view no constructor made is refused */
    sl_view bad = vm;
    bad.magic = 0;
    assert_int_equal(sl_cullmap_render_png_view(s, &bad, NULL, path, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(access(path, F_OK), -1);

    /* the depth image: the view of the camera writes the camera's bytes */
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    sl_oracle_frame fr;
    assert_int_equal(sl_oracle_render(o, &cam, &fr, &err), SL_OK);
    sl_oracle_view ov;
    assert_int_equal(sl_oracle_get_view(o, 0, &ov, &err), SL_OK);
    assert_int_equal(sl_image_write_depth(&ov, &cam, path, NULL, &err), SL_OK);
    uint8_t *dref = read_png(path, &w0, &h0);
    assert_int_equal(sl_image_write_depth_view(&ov, &v, path, NULL, &err), SL_OK);
    px = read_png(path, &w, &h);
    assert_true(w == w0 && h == h0);
    assert_memory_equal(px, dref, (size_t)w * h * 4);
    sl_free(NULL, px, (size_t)w * h * 4);
    /* a view's own near and far: the same image at twice the far plane differs */
    sl_view v2;
    assert_int_equal(sl_view_with_far(&v, 300, &v2, &err), SL_OK);
    assert_int_equal(sl_image_write_depth_view(&ov, &v2, path, NULL, &err), SL_OK);
    px = read_png(path, &w, &h);
    assert_true(memcmp(px, dref, (size_t)w * h * 4) != 0);
    sl_free(NULL, px, (size_t)w * h * 4);
    sl_free(NULL, dref, (size_t)w0 * h0 * 4);
    assert_int_equal(sl_image_write_depth_view(&ov, &vi, path, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "sl_view_bound_far"));
    assert_int_equal(sl_image_write_depth_view(&ov, NULL, path, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(access(path, F_OK), -1);
    sl_oracle_destroy(o);
    sl_free(NULL, ref, n * 4);
    sl_scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_raster_single_edges),
        cmocka_unit_test(test_raster_seams),
        cmocka_unit_test(test_raster_partial),
        cmocka_unit_test(test_raster_mixed),
        cmocka_unit_test(test_wall_hides_box),
        cmocka_unit_test(test_moving_and_orthographic),
        cmocka_unit_test(test_options),
        cmocka_unit_test(test_render_png),
        cmocka_unit_test(test_render_png_view),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
