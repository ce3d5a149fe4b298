/* Camera paths: generators on hand-built street graphs (determinism, staying in the street, eye
 * height, no U-turns, speed, flyover altitude), random viewpoints, the text format (bit-identical
 * round trip, malformed files with file:line errors, CRLF), interpolation and statistics. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "sightline/path.h"
#include "sightline/scene.h"
#include "core/sl_core.h"

#define DEG (M_PI / 180.0)

static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }

/* An n x n grid of streets, `spacing` apart; the middle row is an avenue twice as wide. Optional
 * sloped terrain under it. No dead ends: every node has degree >= 2. */
static sl_scene grid_scene(int n, float spacing, float width, bool terrain)
{
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
    sl_street_node nodes[64];
    sl_street_edge edges[128];
    uint32_t ne = 0;
    assert_true(n * n <= 64);
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            nodes[j * n + i] = (sl_street_node){i * spacing, j * spacing};
            float w = j == n / 2 ? 2 * width : width;
            if (i + 1 < n)
                edges[ne++] = (sl_street_edge){(uint32_t)(j * n + i), (uint32_t)(j * n + i + 1), w, 0};
            if (j + 1 < n)
                edges[ne++] = (sl_street_edge){(uint32_t)(j * n + i), (uint32_t)((j + 1) * n + i), width, 0};
        }
    sl_error err;
    assert_int_equal(sl_scene_set_street_graph(s, nodes, (uint32_t)(n * n), edges, ne, &err), SL_OK);
    /* street polygons: each edge's rectangle, extended by half its width past both nodes so that
     * the rectangles cover the intersections */
    for (uint32_t e = 0; e < ne; e++) {
        const sl_street_node *a = &nodes[edges[e].a], *b = &nodes[edges[e].b];
        float h = 0.5f * edges[e].width, dx = (b->x - a->x) / spacing, dy = (b->y - a->y) / spacing;
        float xy[8] = {a->x - h * dx + h * dy, a->y - h * dy - h * dx, b->x + h * dx + h * dy, b->y + h * dy - h * dx,
                       b->x + h * dx - h * dy, b->y + h * dy + h * dx, a->x - h * dx - h * dy, a->y - h * dy + h * dx};
        assert_int_equal(sl_scene_add_street_polygon(s, xy, 4, &err), SL_OK);
    }
    if (terrain) {
        enum { T = 40 };
        static float h[T * T];
        float cell = (n * spacing + 100) / (T - 1);
        for (int j = 0; j < T; j++)
            for (int i = 0; i < T; i++)
                h[j * T + i] = 0.02f * i * cell + 3.0f * sinf(j * cell / 40.0f);
        sl_terrain_desc td = {T, T, -50, -50, cell, h};
        assert_int_equal(sl_scene_set_terrain(s, &td, &err), SL_OK);
    }
    return s;
}

/* Add a box object (a tower) to a scene. */
static void add_box(sl_scene s, float x0, float y0, float z0, float x1, float y1, float z1)
{
    const float p[24] = {x0, y0, z0, x1, y0, z0, x1, y1, z0, x0, y1, z0, x0, y0, z1, x1, y0, z1, x1, y1, z1, x0, y1, z1};
    const uint32_t idx[36] = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4, 1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7};
    sl_mesh_desc md = {p, NULL, 8, idx, 12, NULL};
    uint32_t mesh;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, NULL), SL_OK);
    sl_object_desc od = {mesh, NULL, 0xffffffffu, SL_KIND_BUILDING, 0, 0};
    assert_int_equal(sl_scene_add_object(s, &od, NULL, NULL), SL_OK);
}

static double seg_dist(double px, double py, const sl_street_node *a, const sl_street_node *b, double *cx, double *cy)
{
    double dx = (double)b->x - a->x, dy = (double)b->y - a->y, l2 = dx * dx + dy * dy;
    double t = l2 > 0 ? ((px - a->x) * dx + (py - a->y) * dy) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    *cx = a->x + t * dx, *cy = a->y + t * dy;
    return hypot(px - *cx, py - *cy);
}

/* Inside one of the scene's street polygons (even-odd rule)? */
static bool in_street_polygon(sl_scene s, double x, double y)
{
    for (uint32_t i = 0; i < sl_scene_street_polygon_count(s); i++) {
        sl_polygon_view p = sl_scene_street_polygon(s, i);
        bool in = false;
        for (uint32_t a = 0, b = p.vertex_count - 1; a < p.vertex_count; b = a++) {
            double xa = p.xy[2 * a], ya = p.xy[2 * a + 1], xb = p.xy[2 * b], yb = p.xy[2 * b + 1];
            if ((ya > y) != (yb > y) && x < (xb - xa) * (y - ya) / (yb - ya) + xa)
                in = !in;
        }
        if (in)
            return true;
    }
    return false;
}

/* Smallest (distance to centre line - frac * width) over all edges: <= 0 when the point is within
 * frac * width of some centre line. Also returns the nearest centre-line point and its width. */
static double street_excess(sl_scene s, double x, double y, double frac, double *cx, double *cy, double *width)
{
    const sl_street_node *nodes;
    const sl_street_edge *edges;
    uint32_t nn, ne;
    sl_scene_street_graph(s, &nodes, &nn, &edges, &ne);
    double best = INFINITY, bd = INFINITY;
    for (uint32_t e = 0; e < ne; e++) {
        double qx, qy, d = seg_dist(x, y, &nodes[edges[e].a], &nodes[edges[e].b], &qx, &qy);
        best = fmin(best, d - frac * edges[e].width);
        if (d < bd) {
            bd = d;
            if (cx)
                *cx = qx, *cy = qy, *width = edges[e].width;
        }
    }
    return best;
}

static sl_path gen(sl_scene s, sl_path_kind kind, uint32_t frames, uint64_t seed)
{
    sl_path_options o = sl_path_options_default(kind);
    o.frames = frames;
    o.seed = seed;
    sl_path p;
    sl_error err;
    sl_status st = sl_path_generate(s, &o, NULL, &p, &err);
    if (st != SL_OK)
        fail_msg("generate: %s", err.message);
    assert_int_equal(sl_path_count(p), frames);
    return p;
}

static bool same_poses(sl_path a, sl_path b)
{
    return sl_path_count(a) == sl_path_count(b) &&
           memcmp(sl_path_poses(a), sl_path_poses(b), sl_path_count(a) * sizeof(sl_pose)) == 0;
}

static void test_determinism(void **state)
{
    (void)state;
    sl_scene s = grid_scene(4, 80, 12, true);
    add_box(s, 10, 10, 0, 60, 60, 45);
    for (int k = 0; k < 3; k++) {
        sl_path a = gen(s, (sl_path_kind)k, 300, 42), b = gen(s, (sl_path_kind)k, 300, 42), c = gen(s, (sl_path_kind)k, 300, 43);
        assert_true(same_poses(a, b));
        assert_false(same_poses(a, c));
        sl_path_destroy(a), sl_path_destroy(b), sl_path_destroy(c);
    }
    /* random views too */
    for (int k = 0; k < 2; k++) {
        sl_path a, b, c;
        assert_int_equal(sl_path_random_views(s, (sl_view_kind)k, 50, 7, NULL, NULL, &a, NULL), SL_OK);
        assert_int_equal(sl_path_random_views(s, (sl_view_kind)k, 50, 7, NULL, NULL, &b, NULL), SL_OK);
        assert_int_equal(sl_path_random_views(s, (sl_view_kind)k, 50, 8, NULL, NULL, &c, NULL), SL_OK);
        assert_true(same_poses(a, b));
        assert_false(same_poses(a, c));
        sl_path_destroy(a), sl_path_destroy(b), sl_path_destroy(c);
    }
    sl_scene_destroy(s);
}

/* Walk and drive: inside the street, at eye height above the ground, on the right side at the
 * lane offset on straight stretches, constant speed, smooth heading, no reversal. */
static void check_street_path(sl_scene s, sl_path_kind kind, uint64_t seed, uint32_t frames)
{
    sl_path_options o = sl_path_options_default(kind);
    o.frames = frames;
    o.seed = seed;
    sl_path p;
    sl_error err;
    if (sl_path_generate(s, &o, NULL, &p, &err) != SL_OK)
        fail_msg("generate: %s", err.message);
    const sl_pose *q = sl_path_poses(p);
    double step = o.speed / o.fps, walked = 0, total_turn = 0;
    uint32_t at_lane = 0;
    for (uint32_t i = 0; i < frames; i++) {
        assert_float_equal(q[i].time, (float)(i / (double)o.fps), 0);
        double cx, cy, w;
        /* inside the street: within half the width of some centre line */
        double ex = street_excess(s, q[i].position.x, q[i].position.y, 0.5, &cx, &cy, &w);
        if (ex > 1e-4)
            fail_msg("seed %llu frame %u: (%g, %g) is %g m outside the street", (unsigned long long)seed, i,
                     (double)q[i].position.x, (double)q[i].position.y, ex);
        if (!in_street_polygon(s, q[i].position.x, q[i].position.y))
            fail_msg("seed %llu frame %u: (%g, %g) is outside every street polygon", (unsigned long long)seed, i,
                     (double)q[i].position.x, (double)q[i].position.y);
        float ground = sl_scene_ground_height(s, q[i].position.x, q[i].position.y);
        assert_float_equal(q[i].position.z, ground + o.eye_height, 1e-4);
        assert_float_equal(q[i].pitch, 0, 0);
        assert_float_equal(q[i].roll, 0, 0);
        /* right of the heading by lane_offset * width, away from corners */
        double rx = sin(q[i].yaw), ry = -cos(q[i].yaw), lat = (q[i].position.x - cx) * rx + (q[i].position.y - cy) * ry;
        if (fabs(lat - o.lane_offset * w) < 1e-3)
            at_lane++;
        if (i == 0)
            continue;
        double d = hypot((double)q[i].position.x - q[i - 1].position.x, (double)q[i].position.y - q[i - 1].position.y);
        if (d > step * 1.005 || d < step * 0.99)
            fail_msg("frame %u: moved %g m, expected %g", i, d, step);
        walked += d;
        double dyaw = remainder((double)q[i].yaw - q[i - 1].yaw, 2 * M_PI);
        if (fabs(dyaw) > (kind == SL_PATH_WALK ? 1 : 6) * DEG)
            fail_msg("frame %u: heading jumps by %g degrees", i, dyaw / DEG);
        total_turn += fabs(dyaw);
    }
    assert_float_equal(walked / ((frames - 1) / o.fps), o.speed, 0.01 * o.speed);
    assert_true(at_lane > frames / 2);
    assert_true(total_turn > 80 * DEG); /* the route did take turns */
    /* no U-turn: the heading never reverses within a short stretch (blocks are 80 m) */
    uint32_t window = (uint32_t)(25.0 / step);
    for (uint32_t i = 0; i + window < frames; i++) {
        double acc = 0;
        for (uint32_t k = i + 1; k <= i + window; k++)
            acc += remainder((double)q[k].yaw - q[k - 1].yaw, 2 * M_PI);
        if (fabs(acc) > 150 * DEG)
            fail_msg("frames %u..%u: heading turns %g degrees (a U-turn)", i, i + window, acc / DEG);
    }
    sl_path_destroy(p);
}

static void test_walk(void **state)
{
    (void)state;
    sl_scene s = grid_scene(4, 80, 12, true);
    int seeds = sanitized() ? 2 : 6;
    for (int seed = 1; seed <= seeds; seed++)
        check_street_path(s, SL_PATH_WALK, (uint64_t)seed, 6000);
    sl_scene_destroy(s);
}

static void test_drive(void **state)
{
    (void)state;
    sl_scene s = grid_scene(4, 80, 12, false);
    int seeds = sanitized() ? 2 : 6;
    for (int seed = 1; seed <= seeds; seed++)
        check_street_path(s, SL_PATH_DRIVE, (uint64_t)seed, 900);
    sl_scene_destroy(s);
}

/* An irregular network: jittered nodes, diagonals, widths from 3 to 30 m, short edges, dead ends,
 * acute junctions. Whatever the corner, the eye stays inside the streets and moves at the set
 * speed; a chord is never longer than the arc it spans. */
static void test_irregular_network(void **state)
{
    (void)state;
    sl_rng r;
    sl_rng_seed(&r, 2024, 0);
    int rounds = sanitized() ? 3 : 12;
    for (int round = 0; round < rounds; round++) {
        sl_street_node nodes[36];
        sl_street_edge edges[128];
        uint32_t ne = 0;
        for (int j = 0; j < 6; j++)
            for (int i = 0; i < 6; i++)
                nodes[j * 6 + i] = (sl_street_node){i * 50 + sl_rng_range(&r, -15, 15), j * 50 + sl_rng_range(&r, -15, 15)};
        nodes[7] = (sl_street_node){nodes[6].x + 2.0f, nodes[6].y + 1.0f}; /* a 2 m edge */
        for (int j = 0; j < 6; j++)
            for (int i = 0; i < 6; i++) {
                uint32_t v = (uint32_t)(j * 6 + i);
                if (i + 1 < 6 && sl_rng_float(&r) < 0.8f)
                    edges[ne++] = (sl_street_edge){v, v + 1, sl_rng_range(&r, 3, 30), 0};
                if (j + 1 < 6 && sl_rng_float(&r) < 0.8f)
                    edges[ne++] = (sl_street_edge){v, v + 6, sl_rng_range(&r, 3, 30), 0};
                if (i + 1 < 6 && j + 1 < 6 && sl_rng_float(&r) < 0.3f)
                    edges[ne++] = (sl_street_edge){v, v + 7, sl_rng_range(&r, 3, 30), 0};
            }
        sl_scene s;
        assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
        assert_int_equal(sl_scene_set_street_graph(s, nodes, 36, edges, ne, NULL), SL_OK);
        for (int k = 0; k < 2; k++) {
            sl_path_options o = sl_path_options_default((sl_path_kind)k);
            o.frames = k ? 1500 : 4000;
            o.seed = (uint64_t)round;
            sl_path p;
            sl_error err;
            if (sl_path_generate(s, &o, NULL, &p, &err) != SL_OK)
                fail_msg("round %d: %s", round, err.message);
            const sl_pose *q = sl_path_poses(p);
            double step = o.speed / o.fps, walked = 0;
            for (uint32_t i = 0; i < o.frames; i++) {
                double ex = street_excess(s, q[i].position.x, q[i].position.y, 0.5, NULL, NULL, NULL);
                if (ex > 1e-4)
                    fail_msg("round %d kind %d frame %u: (%g, %g) is %g m outside the street", round, k, i,
                             (double)q[i].position.x, (double)q[i].position.y, ex);
                if (i) {
                    double d = hypot((double)q[i].position.x - q[i - 1].position.x,
                                     (double)q[i].position.y - q[i - 1].position.y);
                    if (d > step * 1.005)
                        fail_msg("round %d kind %d frame %u: moved %g, step %g at (%g, %g)", round, k, i, d, step, (double)q[i].position.x, (double)q[i].position.y);
                    walked += d;
                }
            }
            assert_float_equal(walked / ((o.frames - 1) / o.fps), o.speed, 0.02 * o.speed);
            sl_path_destroy(p);
        }
        sl_scene_destroy(s);
    }
}

/* A single street: both ends are dead ends, so the walker must turn back, and stays inside. */
static void test_dead_end(void **state)
{
    (void)state;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
    sl_street_node nodes[2] = {{0, 0}, {30, 0}};
    sl_street_edge e = {0, 1, 8, 0};
    assert_int_equal(sl_scene_set_street_graph(s, nodes, 2, &e, 1, NULL), SL_OK);
    sl_path p = gen(s, SL_PATH_WALK, 3000, 3); /* 140 m on a 30 m street */
    const sl_pose *q = sl_path_poses(p);
    double min_x = INFINITY, max_x = -INFINITY;
    for (uint32_t i = 0; i < 3000; i++) {
        assert_true(street_excess(s, q[i].position.x, q[i].position.y, 0.5, NULL, NULL, NULL) <= 1e-4);
        min_x = fmin(min_x, q[i].position.x), max_x = fmax(max_x, q[i].position.x);
    }
    assert_true(min_x < 2 && max_x > 28); /* reached both ends (turning 1.6 m short of them) */
    sl_path_destroy(p);
    sl_scene_destroy(s);
}

static void test_flyover(void **state)
{
    (void)state;
    /* objects only, no streets, no terrain */
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
    add_box(s, -200, -100, 0, -150, -50, 120);
    add_box(s, 300, 200, 0, 340, 260, 80);
    sl_aabb b = sl_scene_bounds(s);
    sl_path_options o = sl_path_options_default(SL_PATH_FLYOVER);
    o.frames = 900;
    sl_path p;
    sl_error err;
    assert_int_equal(sl_path_generate(s, &o, NULL, &p, &err), SL_OK);
    const sl_pose *q = sl_path_poses(p);
    double cx = 0.5 * (b.min.x + b.max.x), cy = 0.5 * (b.min.y + b.max.y), step = 0;
    for (uint32_t i = 0; i < o.frames; i++) {
        assert_true(q[i].position.z > b.max.z + 40);
        assert_true(q[i].position.x > b.min.x && q[i].position.x < b.max.x);
        assert_true(q[i].position.y > b.min.y && q[i].position.y < b.max.y);
        assert_float_equal(q[i].pitch, (float)(-30 * DEG), 1e-6);
        /* looks toward the centre of the loop */
        double dir = atan2(cy - q[i].position.y, cx - q[i].position.x);
        assert_float_equal(remainder(q[i].yaw - dir, 2 * M_PI), 0, 1e-4);
        if (i) {
            double d = hypot((double)q[i].position.x - q[i - 1].position.x, (double)q[i].position.y - q[i - 1].position.y);
            if (i == 1)
                step = d;
            assert_float_equal(d, step, 1e-3 * step); /* constant speed */
        }
    }
    /* the default speed closes the loop: the last frame is one step before the first */
    const sl_pose *l = &q[o.frames - 1];
    assert_float_equal(hypot((double)l->position.x - q[0].position.x, (double)l->position.y - q[0].position.y), step,
                       0.01 * step);
    sl_path_destroy(p);

    /* a given altitude is measured from the scene's lowest point */
    o.altitude = 500;
    assert_int_equal(sl_path_generate(s, &o, NULL, &p, &err), SL_OK);
    assert_float_equal(sl_path_poses(p)[0].position.z, b.min.z + 500, 1e-3);
    sl_path_destroy(p);

    /* an empty scene has nothing to fly over */
    sl_scene e;
    assert_int_equal(sl_scene_create(NULL, &e, NULL), SL_OK);
    o = sl_path_options_default(SL_PATH_FLYOVER);
    assert_int_equal(sl_path_generate(e, &o, NULL, &p, &err), SL_ERROR_UNSUPPORTED);
    assert_non_null(strstr(err.message, "empty"));
    assert_null(p);
    sl_scene_destroy(e);
    sl_scene_destroy(s);
}

static void test_no_streets(void **state)
{
    (void)state;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
    add_box(s, 0, 0, 0, 10, 10, 10);
    sl_path p = NULL;
    sl_error err;
    for (int k = 0; k < 2; k++) {
        sl_path_options o = sl_path_options_default((sl_path_kind)k);
        assert_int_equal(sl_path_generate(s, &o, NULL, &p, &err), SL_ERROR_UNSUPPORTED);
        assert_string_equal(err.message, "scene has no street network: use flyover, or a path file");
        assert_null(p);
    }
    assert_int_equal(sl_path_random_views(s, SL_VIEWS_STREET, 5, 1, NULL, NULL, &p, &err), SL_ERROR_UNSUPPORTED);
    assert_non_null(strstr(err.message, "no street network"));
    /* Quake III spawn points (player origins) stand in for streets in random street views; the eye
     * is Quake III's view height, 26 units, above them: 26 * 0.5 = 13 m at this scene's unit scale */
    assert_int_equal(sl_scene_set_meta(s, "q3.spawns", "1 2 3; 4 5 6;7.5 -8 9;", NULL), SL_OK);
    assert_int_equal(sl_scene_set_meta(s, "q3.unit_scale", "0.5", NULL), SL_OK);
    assert_int_equal(sl_path_random_views(s, SL_VIEWS_STREET, 30, 1, NULL, NULL, &p, &err), SL_OK);
    const float spawns[3][3] = {{1, 2, 3 + 13.0f}, {4, 5, 6 + 13.0f}, {7.5f, -8, 9 + 13.0f}};
    int used[3] = {0, 0, 0};
    for (uint32_t i = 0; i < 30; i++) {
        const sl_pose *q = &sl_path_poses(p)[i];
        int k = 0;
        while (k < 3 && memcmp(&q->position, spawns[k], sizeof spawns[k]))
            k++;
        assert_true(k < 3);
        used[k]++;
        assert_float_equal(q->time, (float)i, 0);
    }
    assert_true(used[0] && used[1] && used[2]);
    sl_path_destroy(p);
    assert_int_equal(sl_scene_set_meta(s, "q3.spawns", "1 2 x", NULL), SL_OK);
    assert_int_equal(sl_path_random_views(s, SL_VIEWS_STREET, 5, 1, NULL, NULL, &p, &err), SL_ERROR_FORMAT);
    assert_non_null(strstr(err.message, "q3.spawns"));
    assert_int_equal(sl_scene_set_meta(s, "q3.spawns", "1 2 3 4", NULL), SL_OK);
    assert_int_equal(sl_path_random_views(s, SL_VIEWS_STREET, 5, 1, NULL, NULL, &p, &err), SL_ERROR_FORMAT);
    /* bad options are rejected before any work */
    sl_scene g = grid_scene(3, 50, 10, false);
    sl_path_options o = sl_path_options_default(SL_PATH_WALK);
    o.frames = 0;
    assert_int_equal(sl_path_generate(g, &o, NULL, &p, &err), SL_ERROR_INVALID_ARGUMENT);
    o = sl_path_options_default(SL_PATH_WALK), o.fps = NAN;
    assert_int_equal(sl_path_generate(g, &o, NULL, &p, &err), SL_ERROR_INVALID_ARGUMENT);
    o = sl_path_options_default(SL_PATH_DRIVE), o.speed = 0;
    assert_int_equal(sl_path_generate(g, &o, NULL, &p, &err), SL_ERROR_INVALID_ARGUMENT);
    o = sl_path_options_default(SL_PATH_WALK), o.lane_offset = 0.6f;
    assert_int_equal(sl_path_generate(g, &o, NULL, &p, &err), SL_ERROR_INVALID_ARGUMENT);
    o = sl_path_options_default(SL_PATH_WALK), o.intrinsics.near_plane = -1;
    assert_int_equal(sl_path_generate(g, &o, NULL, &p, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "near"));
    sl_scene_destroy(g);
    sl_scene_destroy(s);
}

static void test_random_views(void **state)
{
    (void)state;
    sl_scene s = grid_scene(4, 80, 12, true);
    add_box(s, 10, 10, 0, 60, 60, 45);
    sl_path p;
    sl_error err;
    assert_int_equal(sl_path_random_views(s, SL_VIEWS_STREET, 500, 3, NULL, NULL, &p, &err), SL_OK);
    const sl_pose *q = sl_path_poses(p);
    double yaw_lo = 0, yaw_hi = 0;
    for (uint32_t i = 0; i < 500; i++) {
        assert_true(street_excess(s, q[i].position.x, q[i].position.y, 0.4, NULL, NULL, NULL) <= 1e-3);
        assert_true(in_street_polygon(s, q[i].position.x, q[i].position.y));
        assert_float_equal(q[i].position.z, sl_scene_ground_height(s, q[i].position.x, q[i].position.y) + 1.7f, 1e-4);
        assert_float_equal(q[i].pitch, 0, 0);
        assert_float_equal(q[i].time, (float)i, 0);
        yaw_lo = fmin(yaw_lo, q[i].yaw), yaw_hi = fmax(yaw_hi, q[i].yaw);
    }
    assert_true(yaw_lo < -2.5 && yaw_hi > 2.5); /* yaws spread over the circle */
    sl_path_destroy(p);

    assert_int_equal(sl_path_random_views(s, SL_VIEWS_FLYOVER, 500, 3, NULL, NULL, &p, &err), SL_OK);
    q = sl_path_poses(p);
    sl_aabb b = sl_scene_bounds(s);
    for (uint32_t i = 0; i < 500; i++) {
        assert_true(q[i].position.z > b.max.z);
        /* the extent covers the terrain too: x and y in [-50, 370] */
        assert_true(q[i].position.x >= -50 && q[i].position.x <= 370.1f);
        assert_true(q[i].position.y >= -50 && q[i].position.y <= 370.1f);
        assert_true(q[i].pitch <= 0 && q[i].pitch >= (float)(-45 * DEG - 1e-6) && q[i].pitch <= (float)(-15 * DEG + 1e-6));
    }
    sl_path_destroy(p);
    assert_int_equal(sl_path_random_views(s, SL_VIEWS_FLYOVER, 0, 3, NULL, NULL, &p, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_scene_destroy(s);
}

/* ---- files ---- */

static char tmp_name[256];

static const char *tmp_file(const char *tag)
{
    snprintf(tmp_name, sizeof tmp_name, "test_path_%s_%ld.txt", tag, (long)getpid());
    return tmp_name;
}

static void test_round_trip(void **state)
{
    (void)state;
    sl_scene s = grid_scene(4, 80, 12, true);
    sl_path_options o = sl_path_options_default(SL_PATH_WALK);
    o.head_bob = true;
    o.frames = 500;
    o.intrinsics.projection = SL_ORTHOGRAPHIC;
    o.intrinsics.ortho_height = 37.3f;
    o.intrinsics.fov_y = 1.2345678f;
    o.intrinsics.near_plane = 0.0123f;
    o.intrinsics.far_plane = 987.6f;
    o.intrinsics.width = 333, o.intrinsics.height = 77;
    sl_path p;
    assert_int_equal(sl_path_generate(s, &o, NULL, &p, NULL), SL_OK);
    /* extreme values too: tiny, huge, negative zero, the pitch limits, random bits */
    sl_rng r;
    sl_rng_seed(&r, 99, 0);
    const sl_pose *last = &sl_path_poses(p)[sl_path_count(p) - 1];
    sl_pose x = {last->time, {-0.0f, 1e-30f, 3e38f}, (float)-M_PI, (float)M_PI_2, 1e-20f};
    assert_int_equal(sl_path_append(p, &x, NULL), SL_OK);
    x.pitch = -(float)M_PI_2, x.time = nextafterf(x.time, INFINITY);
    assert_int_equal(sl_path_append(p, &x, NULL), SL_OK);
    for (int i = 0; i < 2000; i++) {
        sl_pose y;
        uint32_t bits[7];
        for (int k = 0; k < 7; k++)
            bits[k] = sl_rng_u32(&r);
        memcpy(&y, bits, sizeof y);
        y.time = x.time + (float)i;
        if (!isfinite(y.position.x) || !isfinite(y.position.y) || !isfinite(y.position.z))
            continue;
        y.yaw = fmodf(y.yaw, 1e6f), y.roll = fmodf(y.roll, 1e6f);
        if (!isfinite(y.yaw))
            y.yaw = 0;
        if (!isfinite(y.roll))
            y.roll = 0;
        y.pitch = sl_rng_range(&r, -(float)M_PI_2, (float)M_PI_2);
        assert_int_equal(sl_path_append(p, &y, NULL), SL_OK);
    }
    const char *f = tmp_file("rt");
    sl_error err;
    assert_int_equal(sl_path_save(p, f, &err), SL_OK);
    sl_path back;
    if (sl_path_load(f, NULL, &back, &err) != SL_OK)
        fail_msg("reload: %s", err.message);
    assert_true(same_poses(p, back));
    sl_camera a = sl_path_intrinsics(p), b = sl_path_intrinsics(back);
    assert_memory_equal(&a, &b, sizeof a);
    /* and the file is stable: saving the reloaded path gives the same bytes */
    char f2[300];
    snprintf(f2, sizeof f2, "%s.2", f);
    assert_int_equal(sl_path_save(back, f2, &err), SL_OK);
    uint8_t *d1, *d2;
    size_t n1, n2;
    assert_int_equal(sl_file_read_all(NULL, f, &d1, &n1, NULL), SL_OK);
    assert_int_equal(sl_file_read_all(NULL, f2, &d2, &n2, NULL), SL_OK);
    assert_int_equal(n1, n2);
    assert_memory_equal(d1, d2, n1);
    assert_true(n1 > 20 && !memcmp(d1, "# sightline-path 1\ncamera fov=", 30));
    free(d1), free(d2);
    remove(f), remove(f2);
    sl_path_destroy(back);
    sl_path_destroy(p);
    /* a write into a missing directory fails cleanly and leaves nothing */
    sl_path e;
    assert_int_equal(sl_path_create(NULL, NULL, &e, NULL), SL_OK);
    assert_int_equal(sl_path_save(e, "no-such-dir/x.txt", &err), SL_ERROR_IO);
    sl_path_destroy(e);
    sl_scene_destroy(s);
}

static void expect_bad(const char *text, size_t len, sl_status status, const char *where, const char *what)
{
    sl_path p = (sl_path)1;
    sl_error err;
    memset(&err, 0, sizeof err);
    sl_status st = sl_path_parse(text, len, "bad.txt", NULL, &p, &err);
    if (st != status)
        fail_msg("status %d (%s), expected %d for input '%.60s'", st, err.message, status, text);
    assert_null(p);
    if (strncmp(err.message, where, strlen(where)) || !strstr(err.message, what))
        fail_msg("message '%s' does not start with '%s' and name '%s'", err.message, where, what);
}

#define BAD(text, where, what) expect_bad(text, sizeof(text) - 1, SL_ERROR_FORMAT, where, what)
#define HDR "# sightline-path 1\n"

static void test_malformed(void **state)
{
    (void)state;
    BAD("", "bad.txt:1: ", "empty");
    BAD("hello\n", "bad.txt:1: ", "not a sightline path");
    BAD("0 0 0 0 0 0 0\n", "bad.txt:1: ", "not a sightline path");
    expect_bad("# sightline-path 2\n", 19, SL_ERROR_UNSUPPORTED, "bad.txt:1: ", "version");
    BAD(HDR "0 1 2 3 4 5\n", "bad.txt:2: ", "expected 7 fields");
    BAD(HDR "0 1 2 3 4 5 6 7\n", "bad.txt:2: ", "found 8");
    BAD(HDR "\n# c\n0 nan 2 3 4 5 6\n", "bad.txt:4: ", "field 2 (x)");
    BAD(HDR "0 1 2 3 inf 5 6\n", "bad.txt:2: ", "field 5 (yaw)");
    BAD(HDR "0 1 2 3e39 0 0 0\n", "bad.txt:2: ", "field 4 (z)");
    BAD(HDR "0 1 2 3 4 5 6x\n", "bad.txt:2: ", "field 7 (roll)");
    BAD(HDR "0 1 2 3 4 5 --\n", "bad.txt:2: ", "not a finite number");
    BAD(HDR "0 1 2 3 4 91 0\n", "bad.txt:2: ", "pitch");
    BAD(HDR "1 0 0 0 0 0 0\n0.5 0 0 0 0 0 0\n", "bad.txt:3: ", "before the previous");
    BAD(HDR "0 0 0 0 0 0 0\n0 0 0\r0 0 0 0\n", "bad.txt:3: ", "carriage return");
    BAD(HDR "camera fov=200\n", "bad.txt:2: ", "fov");
    BAD(HDR "camera fov=60 fov=70\n", "bad.txt:2: ", "twice");
    BAD(HDR "camera colour=red\n", "bad.txt:2: ", "unknown camera setting");
    BAD(HDR "camera near\n", "bad.txt:2: ", "key=value");
    BAD(HDR "camera width=0\n", "bad.txt:2: ", "width");
    BAD(HDR "camera height=-5\n", "bad.txt:2: ", "height");
    BAD(HDR "camera width=99999999999999999999\n", "bad.txt:2: ", "width");
    BAD(HDR "camera near=0\n", "bad.txt:2: ", "near");
    BAD(HDR "camera near=1 far=0.5\n", "bad.txt:2: ", "far");
    BAD(HDR "camera projection=fisheye\n", "bad.txt:2: ", "projection");
    BAD(HDR "camera projection=orthographic ortho_height=0\n", "bad.txt:2: ", "ortho_height");
    BAD(HDR "0 0 0 0 0 0 0\ncamera fov=60\n", "bad.txt:3: ", "before the poses");
    BAD(HDR "camera\ncamera\n", "bad.txt:3: ", "second camera line");
    BAD(HDR "\x01\x02\xff\xfe garbage\n", "bad.txt:2: ", "expected 7 fields");
    expect_bad(HDR "0 0 0\0 0 0 0 0\n", sizeof(HDR "0 0 0\0 0 0 0 0\n") - 1, SL_ERROR_FORMAT, "bad.txt:2: ", "NUL");
    /* a huge line */
    size_t n = 100000;
    char *big = malloc(n + 64);
    assert_non_null(big);
    strcpy(big, HDR "0 0 0 0 0 0 0\n");
    size_t h = strlen(big);
    memset(big + h, '1', n);
    big[h + n] = '\n';
    expect_bad(big, h + n + 1, SL_ERROR_FORMAT, "bad.txt:3: ", "longer than");
    free(big);
    /* a missing file */
    sl_path p;
    sl_error err;
    assert_int_equal(sl_path_load("does-not-exist.txt", NULL, &p, &err), SL_ERROR_NOT_FOUND);
    assert_non_null(strstr(err.message, "does-not-exist.txt"));
}

static void test_accepted_forms(void **state)
{
    (void)state;
    /* CRLF line endings, comments, blank lines, tabs, trailing spaces, a last line without a
     * newline and no camera line are all accepted */
    const char lf[] = "# sightline-path 1\n# comment\n\n  \t\n0 1 2 3 90 -10 5\n  0.5\t1.5 2 3 -90 0 0  \n1 2 2 3 0 0 0";
    const char crlf[] = "# sightline-path 1\r\n# comment\r\n\r\n  \t\r\n0 1 2 3 90 -10 5\r\n  0.5\t1.5 2 3 -90 0 0  \r\n1 2 2 3 0 0 0\r\n";
    sl_path a, b, c;
    sl_error err;
    if (sl_path_parse(lf, sizeof lf - 1, "lf.txt", NULL, &a, &err) != SL_OK)
        fail_msg("%s", err.message);
    if (sl_path_parse(crlf, sizeof crlf - 1, "crlf.txt", NULL, &b, &err) != SL_OK)
        fail_msg("%s", err.message);
    assert_int_equal(sl_path_count(a), 3);
    assert_true(same_poses(a, b));
    const sl_pose *q = sl_path_poses(a);
    assert_float_equal(q[0].yaw, (float)(M_PI / 2), 0);
    assert_float_equal(q[0].pitch, (float)(-10 * DEG), 0);
    assert_float_equal(q[1].position.x, 1.5f, 0);
    sl_camera d = sl_camera_default(), i = sl_path_intrinsics(a);
    assert_float_equal(i.fov_y, d.fov_y, 0);
    assert_int_equal(i.width, d.width);
    sl_path_destroy(a), sl_path_destroy(b);
    /* a header-only file is an empty path; a camera line sets the intrinsics */
    const char cam[] = "# sightline-path 1\ncamera projection=orthographic ortho_height=250 width=64 height=48 near=1 far=900\n";
    assert_int_equal(sl_path_parse(cam, sizeof cam - 1, "cam.txt", NULL, &c, &err), SL_OK);
    assert_int_equal(sl_path_count(c), 0);
    i = sl_path_intrinsics(c);
    assert_int_equal(i.projection, SL_ORTHOGRAPHIC);
    assert_float_equal(i.ortho_height, 250, 0);
    assert_int_equal(i.width, 64);
    assert_float_equal(i.far_plane, 900, 0);
    sl_camera out;
    assert_int_equal(sl_path_sample(c, 0, &out, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_path_destroy(c);
}

static void test_sample(void **state)
{
    (void)state;
    sl_path p;
    assert_int_equal(sl_path_create(NULL, NULL, &p, NULL), SL_OK);
    const sl_pose poses[] = {
        {0.0f, {0, 0, 0}, (float)(170 * DEG), 0, 0},
        {1.0f, {10, 20, -4}, (float)(-170 * DEG), (float)(20 * DEG), (float)(10 * DEG)},
        {1.0f, {11, 21, -3}, 0.5f, 0, 0}, /* equal time: the later pose wins */
        {3.0f, {11, 21, 5}, 0.5f, (float)(-40 * DEG), 0},
    };
    for (size_t i = 0; i < SL_COUNTOF(poses); i++)
        assert_int_equal(sl_path_append(p, &poses[i], NULL), SL_OK);
    sl_camera c;
    sl_error err;
    /* at pose times: the poses exactly */
    const size_t at[] = {0, 2, 3};
    for (size_t k = 0; k < 3; k++) {
        const sl_pose *q = &poses[at[k]];
        assert_int_equal(sl_path_sample(p, q->time, &c, &err), SL_OK);
        assert_memory_equal(&c.position, &q->position, sizeof c.position);
        assert_memory_equal(&c.yaw, &q->yaw, sizeof(float));
        assert_memory_equal(&c.pitch, &q->pitch, sizeof(float));
        assert_memory_equal(&c.roll, &q->roll, sizeof(float));
    }
    /* halfway between the first two: linear position, yaw across +-180 the short way */
    assert_int_equal(sl_path_sample(p, 0.5, &c, &err), SL_OK);
    assert_float_equal(c.position.x, 5, 1e-5);
    assert_float_equal(c.position.y, 10, 1e-5);
    assert_float_equal(c.position.z, -2, 1e-5);
    assert_float_equal(fabs(remainder(c.yaw, 2 * M_PI)), M_PI, 1e-5);
    assert_float_equal(c.pitch, 10 * DEG, 1e-6);
    assert_float_equal(c.roll, 5 * DEG, 1e-6);
    assert_int_equal(sl_camera_validate(&c, NULL), SL_OK);
    /* a quarter between the last two */
    assert_int_equal(sl_path_sample(p, 1.5, &c, &err), SL_OK);
    assert_float_equal(c.position.z, -1, 1e-5);
    assert_float_equal(c.pitch, -10 * DEG, 1e-6);
    /* clamped outside the range */
    assert_int_equal(sl_path_sample(p, -5, &c, &err), SL_OK);
    assert_float_equal(c.position.x, 0, 0);
    assert_int_equal(sl_path_sample(p, 1e9, &c, &err), SL_OK);
    assert_float_equal(c.position.z, 5, 0);
    assert_int_equal(sl_path_sample(p, NAN, &c, &err), SL_ERROR_INVALID_ARGUMENT);
    /* the path camera carries the intrinsics */
    sl_camera k = sl_path_camera(p, 3);
    assert_float_equal(k.fov_y, sl_camera_default().fov_y, 0);
    assert_float_equal(k.position.z, 5, 0);

    /* stats */
    sl_path_stats st;
    sl_path_get_stats(p, &st);
    assert_int_equal(st.frames, 4);
    assert_float_equal(st.duration, 3, 0);
    double l1 = sqrt(100 + 400 + 16), l2 = sqrt(3.0), l3 = 8;
    assert_float_equal(st.length, l1 + l2 + l3, 1e-5);
    assert_float_equal(st.speed_max, l1, 1e-5);
    assert_float_equal(st.speed_min, 4, 1e-5);
    /* the move between the two poses at 1 s is a jump: in the length, not in the mean speed (which
     * then could exceed the max: two poses 1.5 m apart at one time, 1 m at 1 m/s gave mean 2.5) */
    assert_int_equal(st.jumps, 1);
    assert_float_equal(st.speed_mean, (l1 + l3) / 3, 1e-5);
    assert_true(st.speed_mean <= st.speed_max);
    assert_float_equal(st.bounds.min.z, -4, 0);
    assert_float_equal(st.bounds.max.y, 21, 0);

    /* append validation */
    sl_pose bad = poses[3];
    bad.time = 2.5f;
    assert_int_equal(sl_path_append(p, &bad, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "before"));
    bad = poses[3], bad.position.y = NAN;
    assert_int_equal(sl_path_append(p, &bad, &err), SL_ERROR_INVALID_ARGUMENT);
    bad = poses[3], bad.pitch = 2;
    assert_int_equal(sl_path_append(p, &bad, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_path_count(p), 4);
    sl_path_destroy(p);

    /* replay a generated walk at another frame rate: samples stay between their neighbours */
    sl_scene s = grid_scene(3, 60, 10, false);
    sl_path w = gen(s, SL_PATH_WALK, 300, 9);
    const sl_pose *q = sl_path_poses(w);
    for (uint32_t i = 0; i + 1 < 300; i++) {
        double t = ((double)q[i].time + q[i + 1].time) / 2;
        assert_int_equal(sl_path_sample(w, t, &c, &err), SL_OK);
        assert_true(c.position.x >= fminf(q[i].position.x, q[i + 1].position.x) - 1e-4f);
        assert_true(c.position.x <= fmaxf(q[i].position.x, q[i + 1].position.x) + 1e-4f);
    }
    sl_path_destroy(w);
    sl_scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_determinism),
        cmocka_unit_test(test_walk),
        cmocka_unit_test(test_drive),
        cmocka_unit_test(test_irregular_network),
        cmocka_unit_test(test_dead_end),
        cmocka_unit_test(test_flyover),
        cmocka_unit_test(test_no_streets),
        cmocka_unit_test(test_random_views),
        cmocka_unit_test(test_round_trip),
        cmocka_unit_test(test_malformed),
        cmocka_unit_test(test_accepted_forms),
        cmocka_unit_test(test_sample),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
