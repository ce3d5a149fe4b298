/* The 2D scene grid: cell lists and maximum heights against brute force, the point-to-cell mapping at
 * cell boundaries, the terrain lower bound, the DDA segment walk against a fine sampling of the
 * segment, dynamic updates against a rebuild, relayouts, and rejected input. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "accel/grid_internal.h"
#include "sightline/accel.h"
#include "sightline/scene.h"
#include "support/counting_alloc.h"

static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }

static sl_aabb *random_boxes(uint32_t n, uint64_t seed, float extent, float max_edge)
{
    sl_aabb *b = malloc((n ? n : 1) * sizeof *b);
    sl_rng r;
    sl_rng_seed(&r, seed, 5);
    for (uint32_t i = 0; i < n; i++) {
        float x = sl_rng_range(&r, 0, extent), y = sl_rng_range(&r, 0, extent), z = sl_rng_range(&r, 0, 10);
        /* a few large objects covering many cells */
        float e = i % 97 == 0 ? extent / 5 : max_edge;
        float w = sl_rng_range(&r, 0, e), h = sl_rng_range(&r, 0, e), t = sl_rng_range(&r, 0, 60);
        b[i] = (sl_aabb){{x, y, z}, {x + w, y + h, z + t}};
    }
    return b;
}

/* Does the closed interval [lo, hi] overlap cell k of n (half-open, the last one closed), or is it
 * too close to a cell line to tell in float? Returns 1 yes, 0 no, -1 ambiguous. */
static int interval_overlaps(double lo, double hi, double origin, double cell, uint32_t k, uint32_t n)
{
    double c0 = origin + k * cell, c1 = origin + (k + 1) * cell;
    double eps = 1e-4 * (fabs(origin) + n * cell);
    if (fabs(lo - c1) < eps || fabs(hi - c0) < eps)
        return -1;
    bool before_end = k + 1 == n ? lo <= c1 : lo < c1;
    return before_end && hi >= c0;
}

/* Compare every cell against brute force: unambiguous overlaps must be listed, unambiguous
 * non-overlaps must not; lists ascending; max height the max of the listed tops; entry count. */
static void check_grid(sl_grid g, const sl_aabb *boxes, uint32_t n)
{
    sl_grid_info info;
    sl_grid_get_info(g, &info);
    assert_int_equal(info.object_count, n);
    uint64_t entries = 0;
    uint8_t *listed = calloc(n ? n : 1, 1);
    for (uint32_t cy = 0; cy < info.ny; cy++) {
        for (uint32_t cx = 0; cx < info.nx; cx++) {
            const uint32_t *ids;
            uint32_t cnt = sl_grid_cell_objects(g, cx, cy, &ids);
            entries += cnt;
            float top = -INFINITY;
            for (uint32_t k = 0; k < cnt; k++) {
                assert_true(ids[k] < n);
                if (k)
                    assert_true(ids[k - 1] < ids[k]);
                listed[ids[k]] = 1;
                top = fmaxf(top, boxes[ids[k]].max.z);
            }
            assert_true(sl_grid_cell_max_height(g, cx, cy) == top);
            /* brute force */
            uint32_t k = 0;
            for (uint32_t i = 0; i < n; i++) {
                int ox = interval_overlaps(boxes[i].min.x, boxes[i].max.x, info.min_x, info.cell_size, cx, info.nx);
                int oy = interval_overlaps(boxes[i].min.y, boxes[i].max.y, info.min_y, info.cell_size, cy, info.ny);
                while (k < cnt && ids[k] < i)
                    k++;
                bool in_list = k < cnt && ids[k] == i;
                if (ox == 1 && oy == 1)
                    assert_true(in_list);
                else if (ox == 0 || oy == 0)
                    assert_false(in_list);
            }
        }
    }
    assert_int_equal(entries, info.entry_count);
    free(listed);
}

static void test_cells_brute_force(void **state)
{
    (void)state;
    sl_test_counter c = {0};
    sl_allocator a = sl_test_counting_allocator(&c);
    const float cells[] = {0.0f, 3.0f, 17.5f, 250.0f};
    for (size_t k = 0; k < SL_COUNTOF(cells); k++) {
        uint32_t n = 1500;
        sl_aabb *boxes = random_boxes(n, 10 + k, 500, 30);
        sl_grid_options o = {cells[k], NULL, &a};
        sl_grid g;
        sl_error err;
        assert_int_equal(sl_grid_build_boxes(boxes, n, &o, &g, &err), SL_OK);
        sl_grid_info info;
        sl_grid_get_info(g, &info);
        if (cells[k] > 0)
            assert_true(info.cell_size == cells[k]);
        /* the grid covers the objects' bounds */
        float x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
        for (uint32_t i = 0; i < n; i++) {
            x0 = fminf(x0, boxes[i].min.x), y0 = fminf(y0, boxes[i].min.y);
            x1 = fmaxf(x1, boxes[i].max.x), y1 = fmaxf(y1, boxes[i].max.y);
        }
        assert_true(info.min_x == x0 && info.min_y == y0 && info.max_x >= x1 && info.max_y >= y1);
        assert_true(info.nx * info.cell_size >= x1 - x0);
        /* every object lies in the grid, hence is listed at least once */
        check_grid(g, boxes, n);
        for (uint32_t i = 0; i < n; i++) {
            uint32_t cx, cy;
            assert_true(sl_grid_cell_at(g, boxes[i].min.x, boxes[i].min.y, &cx, &cy));
            const uint32_t *ids;
            uint32_t cnt = sl_grid_cell_objects(g, cx, cy, &ids);
            bool found = false;
            for (uint32_t j = 0; j < cnt; j++)
                found |= ids[j] == i;
            assert_true(found);
        }
        if (cells[k] == 0.0f) /* automatic: a handful of objects per cell */
            assert_true(info.nx * info.ny > n / 16 && info.nx * info.ny < n);
        assert_true(info.memory_bytes > info.entry_count * sizeof(uint32_t));
        sl_grid_destroy(g);
        free(boxes);
    }
    assert_int_equal(c.live, 0);
}

/* An explicit extent clips objects; cells out of range answer empty. */
static void test_extent_and_mapping(void **state)
{
    (void)state;
    sl_aabb ext = {{0, 0, 0}, {10, 10, 0}};
    sl_aabb boxes[] = {
        {{2.5f, 2.5f, 0}, {3.0f, 3.5f, 7}},   /* cells (2..3, 2..3): touches x = 3 exactly */
        {{-5, -5, 0}, {-1, -1, 9}},           /* outside */
        {{9.5f, 9.5f, 1}, {20, 20, 4}},       /* clipped to the last cell */
        {{-3, 4.2f, 0}, {0, 4.4f, 2}},        /* touches the near edge x = 0: cell (0, 4) */
        {{10, 0, 0}, {11, 0, 3}},             /* touches the far edge: cell (9, 0) */
    };
    sl_grid_options o = {1.0f, &ext, NULL};
    sl_grid g;
    sl_error err;
    assert_int_equal(sl_grid_build_boxes(boxes, 5, &o, &g, &err), SL_OK);
    sl_grid_info info;
    sl_grid_get_info(g, &info);
    assert_int_equal(info.nx, 10);
    assert_int_equal(info.ny, 10);
    assert_true(info.max_x == 10.0f && info.max_y == 10.0f);
    check_grid(g, boxes, 5);
    const uint32_t *ids;
    assert_int_equal(sl_grid_cell_objects(g, 3, 3, &ids), 1);
    assert_int_equal(ids[0], 0);
    assert_int_equal(sl_grid_cell_objects(g, 3, 2, &ids), 1);
    assert_int_equal(sl_grid_cell_objects(g, 4, 3, &ids), 0);
    assert_int_equal(sl_grid_cell_objects(g, 9, 9, &ids), 1);
    assert_int_equal(ids[0], 2);
    assert_true(sl_grid_cell_max_height(g, 9, 9) == 4.0f);
    assert_int_equal(sl_grid_cell_objects(g, 0, 4, &ids), 1);
    assert_int_equal(ids[0], 3);
    assert_int_equal(sl_grid_cell_objects(g, 9, 0, &ids), 1);
    assert_int_equal(ids[0], 4);
    assert_true(sl_grid_cell_max_height(g, 5, 5) == -INFINITY);
    assert_true(sl_grid_cell_ground_min(g, 5, 5) == 0.0f);
    assert_int_equal(info.entry_count, 4 + 1 + 1 + 1);
    /* out of range cells */
    assert_int_equal(sl_grid_cell_objects(g, 10, 0, &ids), 0);
    assert_null(ids);
    assert_true(sl_grid_cell_max_height(g, 0, 10) == -INFINITY);
    /* the point mapping at boundaries: cells are half-open, the far edges belong to the last cells */
    uint32_t cx, cy;
    assert_true(sl_grid_cell_at(g, 3.0f, 0.0f, &cx, &cy) && cx == 3 && cy == 0);
    assert_true(sl_grid_cell_at(g, 2.9999f, 9.9999f, &cx, &cy) && cx == 2 && cy == 9);
    assert_true(sl_grid_cell_at(g, 10.0f, 10.0f, &cx, &cy) && cx == 9 && cy == 9);
    assert_false(sl_grid_cell_at(g, 10.01f, 5.0f, &cx, &cy));
    assert_true(cx == 9 && cy == 5);
    assert_false(sl_grid_cell_at(g, -0.01f, -3.0f, &cx, &cy));
    assert_true(cx == 0 && cy == 0);
    assert_false(sl_grid_cell_at(g, NAN, 1.0f, &cx, &cy));
    sl_grid_destroy(g);

    /* the far edge with a cell size that is not a power of two: a zero-size object on the corner of
       the objects' bounds is inside and listed in the last cell */
    const float cells[] = {7.3f, 0.1f, 3.0f, 1.7f};
    for (size_t k = 0; k < SL_COUNTOF(cells); k++) {
        float e = cells[k] * 10;
        sl_aabb corner[2] = {{{0, 0, 0}, {0.05f, 0.05f, 1}}, {{e, e, 0}, {e, e, 2}}};
        sl_grid_options oc = {cells[k], NULL, NULL};
        assert_int_equal(sl_grid_build_boxes(corner, 2, &oc, &g, &err), SL_OK);
        sl_grid_get_info(g, &info);
        assert_true(sl_grid_cell_at(g, e, e, &cx, &cy));
        assert_true(cx == info.nx - 1 && cy == info.ny - 1);
        assert_int_equal(sl_grid_cell_objects(g, cx, cy, &ids), 1);
        assert_int_equal(ids[0], 1);
        assert_int_equal(info.entry_count, 2);
        sl_grid_destroy(g);
    }
}

static void test_terrain_ground(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    /* a 33 x 21 height field with 2.5 m spacing: bumps and a pit */
    enum { TNX = 33, TNY = 21 };
    float h[TNX * TNY];
    for (int j = 0; j < TNY; j++)
        for (int i = 0; i < TNX; i++)
            h[j * TNX + i] = 3.0f * sinf(0.7f * (float)i) * cosf(0.45f * (float)j) + (i == 20 && j == 7 ? -12.0f : 0.0f);
    sl_terrain_desc td = {TNX, TNY, -10, 5, 2.5f, h};
    assert_int_equal(sl_scene_set_terrain(s, &td, &err), SL_OK);
    /* one object to give the scene bounds; the extent covers more than the terrain (clamping) */
    static const float pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    static const uint32_t idx[] = {0, 1, 2, 0, 1, 3, 0, 2, 3, 1, 2, 3};
    sl_mesh_desc md = {pos, NULL, 4, idx, 4, NULL};
    uint32_t mesh;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, NULL, 0, SL_KIND_BUILDING, 0, 0};
    assert_int_equal(sl_scene_add_object(s, &od, NULL, &err), SL_OK);
    sl_aabb ext = {{-20, -5, 0}, {80, 70, 0}};
    const float cells[] = {0.7f, 2.5f, 6.0f, 30.0f};
    for (size_t k = 0; k < SL_COUNTOF(cells); k++) {
        sl_grid_options o = {cells[k], &ext, NULL};
        sl_grid g;
        assert_int_equal(sl_grid_build(s, &o, &g, &err), SL_OK);
        sl_grid_info info;
        sl_grid_get_info(g, &info);
        sl_rng r;
        sl_rng_seed(&r, k, 1);
        float lowest = INFINITY;
        for (int i = 0; i < TNX * TNY; i++)
            lowest = fminf(lowest, h[i]);
        bool tight_somewhere = false;
        for (uint32_t cy = 0; cy < info.ny; cy++)
            for (uint32_t cx = 0; cx < info.nx; cx++) {
                float gm = sl_grid_cell_ground_min(g, cx, cy);
                assert_true(gm >= lowest);
                /* a lower bound of the surface everywhere in the cell */
                float smin = INFINITY;
                for (int t = 0; t < 24; t++) {
                    float x = info.min_x + ((float)cx + sl_rng_float(&r)) * info.cell_size;
                    float y = info.min_y + ((float)cy + sl_rng_float(&r)) * info.cell_size;
                    float z = sl_scene_ground_height(s, x, y);
                    assert_true(gm <= z + 1e-4f);
                    smin = fminf(smin, z);
                }
                /* and not far below it: within the terrain's steepest change over a cell and a quad */
                assert_true(smin - gm <= 3.0f * (info.cell_size + 2.5f) + 12.0f);
                tight_somewhere |= smin - gm < 0.5f;
            }
        assert_true(tight_somewhere);
        /* the pit is seen by the cell that contains it */
        uint32_t px, py;
        assert_true(sl_grid_cell_at(g, -10 + 20 * 2.5f, 5 + 7 * 2.5f, &px, &py));
        assert_true(sl_grid_cell_ground_min(g, px, py) <= -12.0f + 3.0f);
        sl_grid_destroy(g);
    }
    sl_scene_destroy(s);
}

/* ---- segment walk ---- */

typedef struct walk {
    uint32_t cx[4096], cy[4096];
    float t0[4096], t1[4096];
    uint32_t n;
    uint32_t stop_after;
} walk;

static bool walk_cell(void *user, uint32_t cx, uint32_t cy, float t0, float t1)
{
    walk *w = user;
    assert_true(w->n < 4096);
    w->cx[w->n] = cx, w->cy[w->n] = cy, w->t0[w->n] = t0, w->t1[w->n] = t1;
    w->n++;
    return w->n < w->stop_after;
}

/* Distance from the segment to a cell rectangle is (almost) zero: the walk only lists cells the
 * segment touches. Checked by clipping the segment to the cell grown by tol. */
static bool segment_touches(double ax, double ay, double bx, double by, double x0, double y0, double x1, double y1,
                            double tol)
{
    x0 -= tol, y0 -= tol, x1 += tol, y1 += tol;
    double t0 = 0, t1 = 1, d[2] = {bx - ax, by - ay}, p0[2] = {ax, ay}, lo[2] = {x0, y0}, hi[2] = {x1, y1};
    for (int k = 0; k < 2; k++) {
        if (d[k] == 0) {
            if (p0[k] < lo[k] || p0[k] > hi[k])
                return false;
            continue;
        }
        double ta = (lo[k] - p0[k]) / d[k], tb = (hi[k] - p0[k]) / d[k];
        if (ta > tb) {
            double t = ta;
            ta = tb, tb = t;
        }
        t0 = fmax(t0, ta), t1 = fmin(t1, tb);
    }
    return t0 <= t1;
}

static void check_walk(sl_grid g, sl_vec2 a, sl_vec2 b)
{
    static walk w;
    w.n = 0;
    w.stop_after = UINT32_MAX;
    uint32_t got = sl_grid_walk_segment(g, a, b, walk_cell, &w);
    assert_int_equal(got, w.n);
    sl_grid_info info;
    sl_grid_get_info(g, &info);
    /* no cell twice; consecutive cells are 8-neighbours; t_enter nondecreasing */
    for (uint32_t k = 0; k < w.n; k++) {
        assert_true(w.cx[k] < info.nx && w.cy[k] < info.ny);
        assert_true(w.t0[k] <= w.t1[k]);
        assert_true(w.t0[k] >= 0.0f && w.t1[k] <= 1.0f);
        for (uint32_t j = 0; j < k; j++)
            assert_false(w.cx[j] == w.cx[k] && w.cy[j] == w.cy[k]);
        if (k) {
            int dx = abs((int)w.cx[k] - (int)w.cx[k - 1]), dy = abs((int)w.cy[k] - (int)w.cy[k - 1]);
            assert_true(dx + dy == 1 || (dx == 1 && dy == 1));
            assert_true(w.t0[k] >= w.t0[k - 1]);
        }
        double x0 = info.min_x + (double)w.cx[k] * info.cell_size, y0 = info.min_y + (double)w.cy[k] * info.cell_size;
        double tol = 1e-5 * (fabs(info.min_x) + fabs(info.min_y) + (info.nx + info.ny) * info.cell_size);
        assert_true(segment_touches(a.x, a.y, b.x, b.y, x0, y0, x0 + info.cell_size, y0 + info.cell_size, tol));
    }
    /* every cell a fine sampling of the segment (points rounded to float) lands in is visited, in order */
    const int S = 20000;
    uint32_t last = 0;
    uint32_t inside_samples = 0;
    for (int s = 0; s <= S; s++) {
        double t = (double)s / S;
        float x = (float)(a.x + t * ((double)b.x - a.x)), y = (float)(a.y + t * ((double)b.y - a.y));
        uint32_t cx, cy;
        if (!sl_grid_cell_at(g, x, y, &cx, &cy))
            continue;
        inside_samples++;
        /* searching from the previous sample's cell onwards checks membership and order at once */
        uint32_t k = last;
        while (k < w.n && !(w.cx[k] == cx && w.cy[k] == cy))
            k++;
        assert_true(k < w.n);
        last = k;
    }
    if (inside_samples == 0 && w.n > 0) /* a segment grazing the grid between samples: tiny */
        assert_true(w.n <= 4);
}

static void test_segment_walk(void **state)
{
    (void)state;
    sl_aabb ext = {{-100, 50, 0}, {400, 350, 0}};
    const float cells[] = {1.0f, 7.3f, 25.0f, 100.0f};
    sl_aabb dummy = {{0, 100, 0}, {1, 101, 1}};
    for (size_t k = 0; k < SL_COUNTOF(cells); k++) {
        sl_grid_options o = {cells[k], &ext, NULL};
        sl_grid g;
        assert_int_equal(sl_grid_build_boxes(&dummy, 1, &o, &g, NULL), SL_OK);
        sl_rng r;
        sl_rng_seed(&r, 77, k);
        float maxlen = cells[k] * 60;
        for (int t = 0; t < 300; t++) {
            sl_vec2 a = {sl_rng_range(&r, -200, 500), sl_rng_range(&r, -50, 450)};
            float ang = sl_rng_range(&r, 0, 6.2831853f), len = sl_rng_range(&r, 0, maxlen);
            sl_vec2 b = {a.x + len * cosf(ang), a.y + len * sinf(ang)};
            if (t % 10 == 1)
                b.x = a.x; /* vertical */
            if (t % 10 == 2)
                b.y = a.y; /* horizontal */
            check_walk(g, a, b);
            check_walk(g, b, a);
        }
        /* exact diagonals through cell corners, segments on cell lines, degenerate ones */
        float c = cells[k];
        check_walk(g, (sl_vec2){-100, 50}, (sl_vec2){-100 + 20 * c, 50 + 20 * c});
        check_walk(g, (sl_vec2){-100 + 3 * c, 50 + 2 * c}, (sl_vec2){-100 + 9 * c, 50 + 5 * c});
        check_walk(g, (sl_vec2){-100 + 2 * c, 50}, (sl_vec2){-100 + 2 * c, 50 + 7.5f * c});
        check_walk(g, (sl_vec2){-100 + 2 * c, 50 + c}, (sl_vec2){-100 + 9.5f * c, 50 + c});
        check_walk(g, (sl_vec2){0, 100}, (sl_vec2){0, 100});
        check_walk(g, (sl_vec2){400, 350}, (sl_vec2){-100, 50});
        sl_grid_destroy(g);
    }
    /* explicit expectations on a unit grid */
    sl_aabb e10 = {{0, 0, 0}, {10, 10, 0}};
    sl_grid_options o = {1.0f, &e10, NULL};
    sl_grid g;
    assert_int_equal(sl_grid_build_boxes(&dummy, 1, &o, &g, NULL), SL_OK);
    static walk w;
    w.n = 0, w.stop_after = UINT32_MAX;
    assert_int_equal(sl_grid_walk_segment(g, (sl_vec2){0.5f, 0.5f}, (sl_vec2){3.5f, 0.5f}, walk_cell, &w), 4);
    for (uint32_t k = 0; k < 4; k++)
        assert_true(w.cx[k] == k && w.cy[k] == 0);
    assert_true(w.t0[0] == 0.0f && fabsf(w.t1[0] - 1.0f / 6.0f) < 1e-4f && w.t1[3] == 1.0f);
    /* through a corner exactly: all four cells around it, the start cell first, the end cell last */
    w.n = 0;
    assert_int_equal(sl_grid_walk_segment(g, (sl_vec2){0.5f, 0.5f}, (sl_vec2){1.5f, 1.5f}, walk_cell, &w), 4);
    assert_true(w.cx[0] == 0 && w.cy[0] == 0 && w.cx[3] == 1 && w.cy[3] == 1);
    /* fully outside, clipped at both ends, non-finite */
    w.n = 0;
    assert_int_equal(sl_grid_walk_segment(g, (sl_vec2){-5, -5}, (sl_vec2){-1, 20}, walk_cell, &w), 0);
    assert_int_equal(sl_grid_walk_segment(g, (sl_vec2){-5, 2.5f}, (sl_vec2){15, 2.5f}, walk_cell, &w), 10);
    assert_true(fabsf(w.t0[0] - 0.25f) < 1e-5f && fabsf(w.t1[9] - 0.75f) < 1e-5f);
    /* along a cell line: both rows beside it, column by column */
    w.n = 0;
    assert_int_equal(sl_grid_walk_segment(g, (sl_vec2){0.5f, 3.0f}, (sl_vec2){2.5f, 3.0f}, walk_cell, &w), 6);
    for (uint32_t k = 0; k < 6; k++)
        assert_true(w.cx[k] == k / 2 && w.cy[k] == 2 + k % 2);
    assert_int_equal(sl_grid_walk_segment(g, (sl_vec2){NAN, 0}, (sl_vec2){1, 1}, walk_cell, &w), 0);
    /* the callback stops the walk */
    w.n = 0, w.stop_after = 3;
    assert_int_equal(sl_grid_walk_segment(g, (sl_vec2){0.5f, 0.5f}, (sl_vec2){9.5f, 0.5f}, walk_cell, &w), 3);
    sl_grid_destroy(g);
}

/* ---- dynamic updates ---- */

static void snapshot(sl_grid g, uint32_t **out_ids, uint32_t *out_n, float **out_max)
{
    sl_grid_info info;
    sl_grid_get_info(g, &info);
    uint32_t total = (uint32_t)info.entry_count + info.nx * info.ny, p = 0;
    uint32_t *ids = malloc((total ? total : 1) * sizeof *ids);
    float *mx = malloc((size_t)info.nx * info.ny * sizeof *mx);
    for (uint32_t cy = 0; cy < info.ny; cy++)
        for (uint32_t cx = 0; cx < info.nx; cx++) {
            const uint32_t *l;
            uint32_t cnt = sl_grid_cell_objects(g, cx, cy, &l);
            ids[p++] = cnt;
            memcpy(ids + p, l, cnt * sizeof *l);
            p += cnt;
            mx[cy * info.nx + cx] = sl_grid_cell_max_height(g, cx, cy);
        }
    *out_ids = ids, *out_n = p, *out_max = mx;
}

/* Two grids list the same objects per cell, with the same heights. */
static void assert_same_cells(sl_grid a, sl_grid b)
{
    uint32_t *ia, *ib, na, nb;
    float *ma, *mb;
    snapshot(a, &ia, &na, &ma);
    snapshot(b, &ib, &nb, &mb);
    sl_grid_info info;
    sl_grid_get_info(a, &info);
    assert_int_equal(na, nb);
    assert_memory_equal(ia, ib, na * sizeof *ia);
    assert_memory_equal(ma, mb, (size_t)info.nx * info.ny * sizeof *ma);
    sl_grid_info ib_info;
    sl_grid_get_info(b, &ib_info);
    assert_int_equal(info.entry_count, ib_info.entry_count);
    free(ia), free(ib), free(ma), free(mb);
}

static void test_dynamic_update(void **state)
{
    (void)state;
    sl_test_counter c = {0};
    sl_allocator a = sl_test_counting_allocator(&c);
    uint32_t n = sanitized() ? 800 : 3000;
    sl_aabb *boxes = random_boxes(n, 91, 400, 12);
    sl_aabb ext = {{0, 0, 0}, {400, 400, 0}};
    sl_grid_options o = {8.0f, &ext, &a};
    sl_grid g;
    sl_error err;
    assert_int_equal(sl_grid_build_boxes(boxes, n, &o, &g, &err), SL_OK);
    sl_rng r;
    sl_rng_seed(&r, 91, 3);
    uint32_t *ids = malloc(n * sizeof *ids);
    sl_aabb *nb = malloc(n * sizeof *nb);
    for (int round = 0; round < 30; round++) {
        /* move a batch of objects: small steps (cars), jumps, out of the extent and back, and in a
           few rounds everything into one cell (forces relayouts) */
        uint32_t m = 1 + sl_rng_below(&r, round % 7 == 0 ? n : 64);
        uint32_t start = sl_rng_below(&r, n);
        for (uint32_t k = 0; k < m; k++) {
            uint32_t id = (start + k * 7919u) % n;
            ids[k] = id;
            sl_aabb b = boxes[id];
            float dx, dy;
            switch ((round + k) % 4) {
            case 0: dx = sl_rng_range(&r, -5, 5), dy = sl_rng_range(&r, -5, 5); break;
            case 1: dx = sl_rng_range(&r, -200, 200), dy = sl_rng_range(&r, -200, 200); break;
            case 2: dx = round % 2 ? 1000.0f : -1000.0f, dy = 0; break;
            default: dx = 100.5f - b.min.x, dy = 100.5f - b.min.y; break;
            }
            b.min.x += dx, b.max.x += dx, b.min.y += dy, b.max.y += dy;
            b.max.z += sl_rng_range(&r, 0, 5);
            nb[k] = b;
        }
        /* a batch of distinct ids (7919 is prime and n is not a multiple of it) */
        assert_int_equal(sl_grid_update_boxes(g, ids, nb, m, &err), SL_OK);
        for (uint32_t k = 0; k < m; k++)
            boxes[ids[k]] = nb[k];
        sl_grid fresh;
        assert_int_equal(sl_grid_build_boxes(boxes, n, &o, &fresh, &err), SL_OK);
        assert_same_cells(g, fresh);
        sl_grid_destroy(fresh);
    }
    check_grid(g, boxes, n);
    /* the crowded rounds overflowed cells: the arrays were re-laid out with slack */
    assert_true(g->start[g->ncells] > g->entries);

    /* rejected batches leave the grid unchanged */
    uint32_t *before, nbefore;
    float *mbefore;
    snapshot(g, &before, &nbefore, &mbefore);
    uint32_t dup[3] = {5, 9, 5};
    sl_aabb three[3] = {boxes[5], boxes[9], boxes[5]};
    assert_int_equal(sl_grid_update_boxes(g, dup, three, 3, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "object 5 appears twice"));
    uint32_t bad_id[2] = {3, n};
    assert_int_equal(sl_grid_update_boxes(g, bad_id, three, 2, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "out of range"));
    uint32_t two[2] = {3, 4};
    sl_aabb nan_box[2] = {boxes[3], boxes[4]};
    nan_box[1].max.y = NAN;
    assert_int_equal(sl_grid_update_boxes(g, two, nan_box, 2, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "object 4"));
    uint32_t *after, nafter;
    float *mafter;
    snapshot(g, &after, &nafter, &mafter);
    assert_int_equal(nbefore, nafter);
    assert_memory_equal(before, after, nbefore * sizeof *before);
    free(before), free(after), free(mbefore), free(mafter);
    /* the scratch state was cleared: the same ids are accepted now */
    assert_int_equal(sl_grid_update_boxes(g, two, three, 2, &err), SL_OK);
    boxes[3] = three[0], boxes[4] = three[1];
    check_grid(g, boxes, n);
    free(ids);
    free(nb);
    sl_grid_destroy(g);
    free(boxes);
    assert_int_equal(c.live, 0);
}

/* Updates through the scene: cars moved with sl_scene_set_object_transform. */
static void test_scene_update(void **state)
{
    (void)state;
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    static const float pos[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
    static const uint32_t idx[] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4,
                                   1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7};
    sl_mesh_desc md = {pos, NULL, 8, idx, 12, NULL};
    uint32_t mesh;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_rng r;
    sl_rng_seed(&r, 5, 5);
    uint32_t n = 400;
    for (uint32_t i = 0; i < n; i++) {
        bool car = i % 4 == 0;
        float sx = car ? 4.0f : sl_rng_range(&r, 5, 30), sz = car ? 1.5f : sl_rng_range(&r, 5, 60);
        sl_affine t = {{sx, 0, 0, sl_rng_range(&r, 0, 500), 0, sx, 0, sl_rng_range(&r, 0, 500), 0, 0, sz, 0}};
        sl_object_desc od = {mesh, &t, 0, car ? SL_KIND_CAR : SL_KIND_BUILDING, car ? SL_OBJECT_DYNAMIC : 0u, 0};
        assert_int_equal(sl_scene_add_object(s, &od, NULL, &err), SL_OK);
    }
    sl_aabb ext = {{0, 0, 0}, {540, 540, 0}};
    sl_grid_options o = {20.0f, &ext, NULL};
    sl_grid g;
    assert_int_equal(sl_grid_build(s, &o, &g, &err), SL_OK);
    check_grid(g, sl_scene_object_bounds_array(s), n);
    uint32_t cars[100], nc = 0;
    for (int frame = 0; frame < 20; frame++) {
        nc = 0;
        for (uint32_t i = 0; i < n; i += 4) {
            sl_object_view v = sl_scene_object(s, i);
            sl_affine t = v.transform;
            t.m[3] = fmodf(t.m[3] + 13.0f, 500.0f);
            assert_int_equal(sl_scene_set_object_transform(s, i, &t, &err), SL_OK);
            cars[nc++] = i;
        }
        assert_int_equal(sl_grid_update_objects(g, s, cars, nc, &err), SL_OK);
        sl_grid fresh;
        assert_int_equal(sl_grid_build(s, &o, &fresh, &err), SL_OK);
        assert_same_cells(g, fresh);
        sl_grid_destroy(fresh);
    }
    uint32_t bad = n;
    assert_int_equal(sl_grid_update_objects(g, s, &bad, 1, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_grid_destroy(g);
    sl_scene_destroy(s);
}

static void test_rejects(void **state)
{
    (void)state;
    sl_aabb boxes[3] = {{{0, 0, 0}, {1, 1, 1}}, {{2, 2, 0}, {3, 3, 1}}, {{4, 4, 0}, {5, 5, 1}}};
    sl_grid g = NULL;
    sl_error err;
    boxes[1].min.x = NAN;
    assert_int_equal(sl_grid_build_boxes(boxes, 3, NULL, &g, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "object 1"));
    assert_null(g);
    boxes[1].min.x = 2;
    boxes[2].min.z = 3;
    assert_int_equal(sl_grid_build_boxes(boxes, 3, NULL, &g, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "object 2: bounds are inverted on axis z"));
    boxes[2].min.z = 0;
    sl_grid_options o = {-1.0f, NULL, NULL};
    assert_int_equal(sl_grid_build_boxes(boxes, 3, &o, &g, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "cell_size"));
    o.cell_size = NAN;
    assert_int_equal(sl_grid_build_boxes(boxes, 3, &o, &g, &err), SL_ERROR_INVALID_ARGUMENT);
    o.cell_size = 1e-4f; /* 50000^2 cells */
    assert_int_equal(sl_grid_build_boxes(boxes, 3, &o, &g, &err), SL_ERROR_LIMIT);
    assert_non_null(strstr(err.message, "cells"));
    sl_aabb bad_ext = {{5, 0, 0}, {1, 1, 0}};
    o = (sl_grid_options){1.0f, &bad_ext, NULL};
    assert_int_equal(sl_grid_build_boxes(boxes, 3, &o, &g, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "extent"));
    /* boxes at the ends of the float range still map to the right cells ... */
    sl_aabb huge[2] = {{{-3e38f, 0, 0}, {-3e38f, 1, 1}}, {{3e38f, 0, 0}, {3e38f, 1, 1}}};
    assert_int_equal(sl_grid_build_boxes(huge, 2, NULL, &g, &err), SL_OK);
    sl_grid_info hi;
    sl_grid_get_info(g, &hi);
    const uint32_t *hids;
    assert_int_equal(sl_grid_cell_objects(g, 0, 0, &hids), 1);
    assert_int_equal(hids[0], 0);
    assert_int_equal(sl_grid_cell_objects(g, hi.nx - 1, 0, &hids), 1);
    assert_int_equal(hids[0], 1);
    sl_grid_destroy(g);
    /* ... but a grid whose far edge would overflow float is refused */
    sl_aabb wide = {{-3.4e38f, 0, 0}, {3.4e38f, 1, 0}};
    o = (sl_grid_options){1e38f, &wide, NULL};
    assert_int_equal(sl_grid_build_boxes(huge, 2, &o, &g, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "too large"));
    assert_int_equal(sl_grid_build_boxes(NULL, 3, NULL, &g, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_grid_build(NULL, NULL, &g, &err), SL_ERROR_INVALID_ARGUMENT);
    /* no objects: a single cell, empty */
    assert_int_equal(sl_grid_build_boxes(NULL, 0, NULL, &g, &err), SL_OK);
    sl_grid_info info;
    sl_grid_get_info(g, &info);
    assert_int_equal(info.nx * info.ny, 1);
    assert_int_equal(info.entry_count, 0);
    assert_int_equal(sl_grid_update_boxes(g, NULL, NULL, 0, &err), SL_OK);
    sl_grid_destroy(g);
    sl_grid_destroy(NULL);
    sl_grid_get_info(NULL, &info);
    assert_int_equal(info.nx, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cells_brute_force), cmocka_unit_test(test_extent_and_mapping),
        cmocka_unit_test(test_terrain_ground),    cmocka_unit_test(test_segment_walk),
        cmocka_unit_test(test_dynamic_update),    cmocka_unit_test(test_scene_update),
        cmocka_unit_test(test_rejects),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
