/* Guided visibility sampling (src/region/gvs.c): Halton sequences; the enlarged polygon t' lies
 * just outside its triangle from any viewpoint; a hand-built scene (a wall with a small hole, an
 * object seen only through the hole, objects hidden behind the wall, a box sealed inside another)
 * where GVS finds what the hole shows and never what nothing shows; reverse sampling fires; the
 * random baseline at the same ray budget finds less; the termination rule and the progressive
 * variant; per-object results; agreement with the region oracle on city street cells;
 * triangles meeting the cell; BSP cluster cells; determinism (repeat, cell order, Embree threads);
 * the `gvs` PVS method through the registry; bad options; every byte returned. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>

#include "core/dvec3.h"
#include "core/sl_core.h"
#include "region/gvs_internal.h"
#include "region/halton.h"
#include "sightline/gen.h"
#include "sightline/bake.h"
#include "sightline/pvs.h"
#include "support/counting_alloc.h"

static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }

static uint32_t add_mesh_object(sl_scene s, const float *pos, uint32_t nv, const uint32_t *idx, uint32_t nt)
{
    sl_error err;
    sl_mesh_desc md = {pos, NULL, nv, idx, nt, NULL};
    uint32_t mesh, obj;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, NULL, 0xffffffffu, SL_KIND_OTHER, 0, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &obj, &err), SL_OK);
    return obj;
}

/* A closed box, faces counter-clockwise seen from outside. */
static uint32_t add_box(sl_scene s, sl_vec3 lo, sl_vec3 hi)
{
    float p[24];
    for (int i = 0; i < 8; i++) {
        p[3 * i] = (i & 1) ? hi.x : lo.x;
        p[3 * i + 1] = (i & 2) ? hi.y : lo.y;
        p[3 * i + 2] = (i & 4) ? hi.z : lo.z;
    }
    static const uint32_t idx[36] = {0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5, 0, 1, 5, 0, 5, 4,
                                     2, 6, 7, 2, 7, 3, 0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6};
    return add_mesh_object(s, p, 8, idx, 12);
}

/* A wall in the plane x = x0 over y in [-10, 10], z in [0, 10], with a square hole of side 2h
 * centred at (y, z) = (0, 1.5): eight rectangles (16 triangles), one object. */
static uint32_t add_holed_wall(sl_scene s, float x0, float h)
{
    const float y[4] = {-10, -h, h, 10}, z[4] = {0, 1.5f - h, 1.5f + h, 10};
    float p[16 * 3];
    for (int j = 0; j < 4; j++)
        for (int i = 0; i < 4; i++) {
            p[3 * (4 * j + i)] = x0;
            p[3 * (4 * j + i) + 1] = y[i];
            p[3 * (4 * j + i) + 2] = z[j];
        }
    /* the grid's 3x3 quads minus the centre one */
    uint32_t idx[8 * 6], n = 0;
    for (int j = 0; j < 3; j++)
        for (int i = 0; i < 3; i++) {
            if (i == 1 && j == 1)
                continue;
            uint32_t a = (uint32_t)(4 * j + i), b = a + 1, c = a + 5, d = a + 4;
            uint32_t q[6] = {a, b, c, a, c, d};
            memcpy(idx + n, q, sizeof q);
            n += 6;
        }
    return add_mesh_object(s, p, 16, idx, n / 3);
}

static sl_viewcell box_cell(sl_vec3 lo, sl_vec3 hi)
{
    sl_viewcell c;
    memset(&c, 0, sizeof c);
    c.shape = SL_CELL_BOX;
    c.cluster = -1;
    c.z_min = lo.z;
    c.z_max = hi.z;
    c.bounds = (sl_aabb){lo, hi};
    return c;
}

static sl_viewcell prism_cell(float ax, float ay, float bx, float by, float cx, float cy, float z0, float z1)
{
    sl_viewcell c;
    memset(&c, 0, sizeof c);
    c.shape = SL_CELL_PRISM;
    c.cluster = -1;
    c.tri[0] = (sl_vec2){ax, ay};
    c.tri[1] = (sl_vec2){bx, by};
    c.tri[2] = (sl_vec2){cx, cy};
    c.z_min = z0;
    c.z_max = z1;
    c.bounds = (sl_aabb){{fminf(ax, fminf(bx, cx)), fminf(ay, fminf(by, cy)), z0},
                         {fmaxf(ax, fmaxf(bx, cx)), fmaxf(ay, fmaxf(by, cy)), z1}};
    return c;
}

static bool has(const uint32_t *ids, uint32_t n, uint32_t id)
{
    for (uint32_t i = 0; i < n; i++)
        if (ids[i] == id)
            return true;
    return false;
}

/* ---- Halton ---- */

static void test_halton(void **state)
{
    (void)state;
    assert_true(sl_radical_inverse(2, 1) == 0.5);
    assert_true(sl_radical_inverse(2, 2) == 0.25);
    assert_true(sl_radical_inverse(2, 3) == 0.75);
    assert_true(fabs(sl_radical_inverse(3, 1) - 1.0 / 3) < 1e-15);
    assert_true(fabs(sl_radical_inverse(3, 2) - 2.0 / 3) < 1e-15);
    assert_true(fabs(sl_radical_inverse(3, 3) - 1.0 / 9) < 1e-15);
    assert_true(sl_radical_inverse(2, 0) == 0.0);
    assert_int_equal(sl_halton_prime(0), 2);
    assert_int_equal(sl_halton_prime(4), 11);
    /* plain: the radical inverses from index 1; rotated: shifted mod 1, stratified all the same */
    sl_halton h, r1, r2;
    sl_halton_init(&h, 3, false, 0, 0);
    sl_halton_init(&r1, 3, true, 9, 4);
    sl_halton_init(&r2, 3, true, 9, 5);
    double x[3], y[3], z[3];
    int bins[8] = {0};
    bool differ = false;
    for (uint64_t i = 1; i <= 4096; i++) {
        sl_halton_next(&h, x);
        sl_halton_next(&r1, y);
        sl_halton_next(&r2, z);
        assert_true(x[0] == sl_radical_inverse(2, i) && x[2] == sl_radical_inverse(5, i));
        for (int k = 0; k < 3; k++) {
            assert_true(y[k] >= 0 && y[k] < 1);
            double d = fmod(y[k] - x[k] + 2.0, 1.0);
            assert_true(fabs(d - r1.shift[k]) < 1e-9 || fabs(d - r1.shift[k]) > 1 - 1e-9);
        }
        differ |= y[0] != z[0];
        bins[(int)(y[0] * 8)]++;
    }
    assert_true(differ);
    for (int b = 0; b < 8; b++)
        assert_int_equal(bins[b], 512); /* base 2 is perfectly stratified over 2^k points */
}

/* ---- the enlarged polygon ---- */

/* Does the ray from o toward p meet triangle t (both sides)? */
static bool ray_hits(const double *o, const double *p, const double *tri)
{
    double d[3] = {p[0] - o[0], p[1] - o[1], p[2] - o[2]};
    return sl_ray_triangle(o, d, tri, tri + 3, tri + 6, 1e-300, NULL); /* src/core/dvec3.c */
}

/* From random viewpoints (front and back side) and for random triangles (slivers included), every
 * vertex of t' is seen just beside the triangle: the ray misses it, at an angle of about eps. */
static void test_enlarge_outside(void **state)
{
    (void)state;
    sl_rng r;
    sl_rng_seed(&r, 21, 0);
    const double eps = 5e-5;
    for (int it = 0; it < 20000; it++) {
        double t[3][3], o[3];
        for (int k = 0; k < 3; k++)
            for (int c = 0; c < 3; c++)
                t[k][c] = sl_rng_double(&r) * 10 - 5;
        if (it % 4 == 0) /* a sliver: the third vertex close to the first edge */
            for (int c = 0; c < 3; c++)
                t[2][c] = 0.5 * (t[0][c] + t[1][c]) + 1e-3 * (sl_rng_double(&r) - 0.5);
        for (int c = 0; c < 3; c++)
            o[c] = sl_rng_double(&r) * 60 - 30;
        double ring[9][3];
        sl_gvs_enlarge(o, &t[0][0], eps, &ring[0][0]);
        for (int k = 0; k < 9; k++) {
            const double *pi = t[k / 3];
            double dv = sqrt((pi[0] - o[0]) * (pi[0] - o[0]) + (pi[1] - o[1]) * (pi[1] - o[1]) +
                             (pi[2] - o[2]) * (pi[2] - o[2]));
            double off = sqrt((ring[k][0] - pi[0]) * (ring[k][0] - pi[0]) + (ring[k][1] - pi[1]) * (ring[k][1] - pi[1]) +
                              (ring[k][2] - pi[2]) * (ring[k][2] - pi[2]));
            /* eps * |p_i - o| off its corner, perpendicular to the ray to the corner */
            assert_true(fabs(off - eps * dv) <= 1e-9 * dv || off == 0);
            double dot = (ring[k][0] - pi[0]) * (pi[0] - o[0]) + (ring[k][1] - pi[1]) * (pi[1] - o[1]) +
                         (ring[k][2] - pi[2]) * (pi[2] - o[2]);
            assert_true(fabs(dot) <= 1e-9 * dv * dv);
            /* outside the triangle as seen from o (slivers seen edge-on may touch: skip those) */
            if (it % 4 != 0)
                assert_false(ray_hits(o, ring[k], &t[0][0]));
        }
    }
}

/* ---- the hand-built scene ---- */

typedef struct hole_scene {
    sl_scene s;
    sl_viewcells vc;
    uint32_t wall, through, hidden, hidden_low, shell, sealed, open;
} hole_scene;

/* Cell 0: a box in front of a wall with a 2 cm hole; cell 1: a prism off to the side. */
static void make_hole_scene(hole_scene *h, const sl_allocator *a)
{
    sl_error err;
    assert_int_equal(sl_scene_create(a, &h->s, &err), SL_OK);
    h->wall = add_holed_wall(h->s, 10, 0.01f);
    h->through = add_box(h->s, (sl_vec3){15, -0.5f, 1}, (sl_vec3){16, 0.5f, 2});   /* seen through the hole */
    h->hidden = add_box(h->s, (sl_vec3){15, 4, 1}, (sl_vec3){16, 5, 2});           /* behind the wall */
    h->hidden_low = add_box(h->s, (sl_vec3){14, -3, 0.1f}, (sl_vec3){14.5f, -2, 0.5f});
    h->shell = add_box(h->s, (sl_vec3){4, 3, 0}, (sl_vec3){6, 5, 2});              /* in the open */
    h->sealed = add_box(h->s, (sl_vec3){4.5f, 3.5f, 0.5f}, (sl_vec3){5.5f, 4.5f, 1.5f}); /* inside shell */
    h->open = add_box(h->s, (sl_vec3){4, -6, 0}, (sl_vec3){5, -5, 1});
    sl_viewcell cells[2] = {box_cell((sl_vec3){0, -0.5f, 1}, (sl_vec3){1, 0.5f, 2}),
                            prism_cell(0, -4, 2, -4, 1, -2, 1, 2)};
    assert_int_equal(sl_viewcells_create(cells, 2, a, &h->vc, &err), SL_OK);
}

static void free_hole_scene(hole_scene *h)
{
    sl_viewcells_destroy(h->vc);
    sl_scene_destroy(h->s);
}

static void test_hole_scene(void **state)
{
    (void)state;
    sl_test_counter cnt = {0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_error err;
    hole_scene h;
    make_hole_scene(&h, &a);
    sl_es *es;
    assert_int_equal(sl_es_create(h.s, NULL, &a, &es, &err), SL_OK);
    sl_gvs_options o = sl_gvs_defaults();
    o.window = 20000;
    o.min_new = 0;
    o.max_rays = 400000;
    sl_gvs g;
    assert_int_equal(sl_gvs_create(es, h.s, &o, &a, &g, &err), SL_OK);
    sl_gvs_result r;
    assert_int_equal(sl_gvs_cell(g, h.vc, 0, &r, &err), SL_OK);
    assert_true(has(r.objects, r.object_count, h.wall));
    assert_true(has(r.objects, r.object_count, h.through));
    assert_true(has(r.objects, r.object_count, h.shell));
    assert_true(has(r.objects, r.object_count, h.open));
    assert_false(has(r.objects, r.object_count, h.hidden));
    assert_false(has(r.objects, r.object_count, h.hidden_low));
    assert_false(has(r.objects, r.object_count, h.sealed));
    /* every wall triangle is seen; the strategies all ran */
    for (uint32_t t = sl_es_object_first_triangle(es, h.wall); t < sl_es_object_first_triangle(es, h.wall + 1); t++)
        assert_true(has(r.triangles, r.triangle_count, t));
    assert_true(r.stats.border_rays > 0);
    assert_true(r.stats.reverse_tries > 0);
    assert_true(r.stats.reverse_rays > 0);
    assert_int_equal(r.stats.rays, r.stats.random_rays + r.stats.border_rays + r.stats.reverse_rays);
    assert_int_equal(r.stats.triangles, r.triangle_count);
    assert_int_equal(r.stats.objects, r.object_count);
    assert_int_equal(r.stats.auto_visible, 0);
    assert_int_equal(r.stats.stop, SL_GVS_STOP_CONVERGED);

    /* triangles ascending and unique; objects ascending, exactly the owners of the triangles */
    for (uint32_t i = 1; i < r.triangle_count; i++)
        assert_true(r.triangles[i - 1] < r.triangles[i]);
    for (uint32_t i = 1; i < r.object_count; i++)
        assert_true(r.objects[i - 1] < r.objects[i]);
    for (uint32_t i = 0; i < r.triangle_count; i++)
        assert_true(has(r.objects, r.object_count, sl_es_triangle_object(es, r.triangles[i])));
    for (uint32_t i = 0; i < r.object_count; i++) {
        bool owns = false;
        for (uint32_t k = 0; k < r.triangle_count && !owns; k++)
            owns = sl_es_triangle_object(es, r.triangles[k]) == r.objects[i];
        assert_true(owns);
    }

    /* cell 1 (a prism beside the wall's left end): the far boxes are hidden there too */
    assert_int_equal(sl_gvs_cell(g, h.vc, 1, &r, &err), SL_OK);
    assert_true(has(r.objects, r.object_count, h.wall));
    assert_true(has(r.objects, r.object_count, h.open));
    assert_false(has(r.objects, r.object_count, h.sealed));
    assert_false(has(r.objects, r.object_count, h.hidden));
    sl_gvs_destroy(g);
    sl_es_destroy(es);
    free_hole_scene(&h);
    assert_int_equal(cnt.live, 0);
}

/* The random baseline casts exactly its budget, nothing else, and finds no more than GVS with the
 * same number of rays; here it misses what only the hole shows. */
static void test_random_baseline(void **state)
{
    (void)state;
    sl_error err;
    hole_scene h;
    make_hole_scene(&h, NULL);
    sl_es *es;
    assert_int_equal(sl_es_create(h.s, NULL, NULL, &es, &err), SL_OK);
    sl_gvs_options o = sl_gvs_defaults();
    o.window = 20000;
    o.min_new = 0;
    o.max_rays = 400000;
    sl_gvs g;
    assert_int_equal(sl_gvs_create(es, h.s, &o, NULL, &g, &err), SL_OK);
    sl_gvs_result r;
    assert_int_equal(sl_gvs_cell(g, h.vc, 0, &r, &err), SL_OK);
    uint64_t rays = r.stats.rays;
    uint32_t gvs_tris = r.triangle_count;
    sl_gvs_destroy(g);

    o.sampler = SL_GVS_RANDOM;
    o.max_rays = rays;
    o.window = rays + 1; /* equal rays: no early stop */
    assert_int_equal(sl_gvs_create(es, h.s, &o, NULL, &g, &err), SL_OK);
    assert_int_equal(sl_gvs_cell(g, h.vc, 0, &r, &err), SL_OK);
    assert_int_equal(r.stats.rays, rays);
    assert_int_equal(r.stats.random_rays, rays);
    assert_int_equal(r.stats.border_rays, 0);
    assert_int_equal(r.stats.reverse_rays, 0);
    assert_int_equal(r.stats.stop, SL_GVS_STOP_MAX_RAYS);
    assert_true(r.triangle_count < gvs_tris);
    assert_false(has(r.objects, r.object_count, h.through));
    assert_false(has(r.objects, r.object_count, h.hidden));
    assert_false(has(r.objects, r.object_count, h.sealed));
    sl_gvs_destroy(g);
    sl_es_destroy(es);
    free_hole_scene(&h);
}

/* Termination: the window rule (the last window found at most min_new per window of rays), the
 * budget, and the convergence curve that records them. */
static void test_termination(void **state)
{
    (void)state;
    sl_error err;
    hole_scene h;
    make_hole_scene(&h, NULL);
    sl_es *es;
    assert_int_equal(sl_es_create(h.s, NULL, NULL, &es, &err), SL_OK);
    sl_gvs_options o = sl_gvs_defaults();
    o.window = 5000;
    o.min_new = 2;
    sl_gvs g;
    assert_int_equal(sl_gvs_create(es, h.s, &o, NULL, &g, &err), SL_OK);
    sl_gvs_result r;
    assert_int_equal(sl_gvs_cell(g, h.vc, 0, &r, &err), SL_OK);
    assert_int_equal(r.stats.stop, SL_GVS_STOP_CONVERGED);
    assert_true(r.curve_count >= 2);
    /* points: window ends then the final state; rays and triangles never decrease */
    for (uint32_t i = 1; i < r.curve_count; i++) {
        assert_true(r.curve[2 * i] >= r.curve[2 * i - 2]);
        assert_true(r.curve[2 * i + 1] >= r.curve[2 * i - 1]);
    }
    uint64_t last_rays = r.curve[2 * (r.curve_count - 1)], last_tris = r.curve[2 * (r.curve_count - 1) + 1];
    assert_int_equal(last_rays, r.stats.rays);
    assert_int_equal(last_tris, r.triangle_count);
    /* the stopping window: at most min_new new triangles, scaled to its length */
    uint64_t prev_rays = r.curve_count >= 3 ? r.curve[2 * (r.curve_count - 3)] : 0;
    uint64_t prev_tris = r.curve_count >= 3 ? r.curve[2 * (r.curve_count - 3) + 1] : r.stats.auto_visible;
    uint64_t elapsed = r.curve[2 * (r.curve_count - 2)] - prev_rays;
    uint64_t fresh = r.curve[2 * (r.curve_count - 2) + 1] - prev_tris;
    assert_true(elapsed >= o.window);
    assert_true(fresh * o.window <= o.min_new * elapsed);
    /* every earlier window found more */
    for (uint32_t i = 0; i + 2 < r.curve_count; i++) {
        uint64_t r0 = i ? r.curve[2 * i - 2] : 0, t0 = i ? r.curve[2 * i - 1] : r.stats.auto_visible;
        assert_true((r.curve[2 * i + 1] - t0) * o.window > o.min_new * (r.curve[2 * i] - r0));
    }
    sl_gvs_destroy(g);

    /* the budget: stops at max_rays (GVS may finish the ABS level it is in) */
    o.max_rays = 3000;
    o.window = 1000000;
    assert_int_equal(sl_gvs_create(es, h.s, &o, NULL, &g, &err), SL_OK);
    assert_int_equal(sl_gvs_cell(g, h.vc, 0, &r, &err), SL_OK);
    assert_int_equal(r.stats.stop, SL_GVS_STOP_MAX_RAYS);
    assert_true(r.stats.rays >= 3000 && r.stats.rays < 3000 + 2000);
    assert_int_equal(r.curve_count, 1);
    sl_gvs_destroy(g);

    /* the progressive variant: ABS waits for `initial` random rays */
    o.max_rays = 20000;
    o.initial = 20000;
    assert_int_equal(sl_gvs_create(es, h.s, &o, NULL, &g, &err), SL_OK);
    assert_int_equal(sl_gvs_cell(g, h.vc, 0, &r, &err), SL_OK);
    assert_int_equal(r.stats.border_rays, 0);
    assert_int_equal(r.stats.random_rays, 20000);
    sl_gvs_destroy(g);
    o.max_rays = 60000;
    o.initial = 10000;
    assert_int_equal(sl_gvs_create(es, h.s, &o, NULL, &g, &err), SL_OK);
    assert_int_equal(sl_gvs_cell(g, h.vc, 0, &r, &err), SL_OK);
    assert_true(r.stats.border_rays > 0);
    assert_true(r.stats.random_rays >= 10000);
    sl_gvs_destroy(g);
    sl_es_destroy(es);
    free_hole_scene(&h);
}

/* Triangles meeting the cell are visible by definition; a pole through the cell is found even
 * though no ray leaving the cell's boundary outward may hit the part inside. */
static void test_auto_visible(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t pole = add_box(s, (sl_vec3){0.4f, 0.4f, -5}, (sl_vec3){0.6f, 0.6f, 5});
    uint32_t far = add_box(s, (sl_vec3){30, 30, 0}, (sl_vec3){31, 31, 1});
    sl_viewcell c = box_cell((sl_vec3){0, 0, 1}, (sl_vec3){1, 1, 2});
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_create(&c, 1, NULL, &vc, &err), SL_OK);
    sl_es *es;
    assert_int_equal(sl_es_create(s, NULL, NULL, &es, &err), SL_OK);
    sl_gvs_options o = sl_gvs_defaults();
    o.max_rays = 1; /* one random ray: the pole's side walls come from the cell test alone */
    sl_gvs g;
    assert_int_equal(sl_gvs_create(es, s, &o, NULL, &g, &err), SL_OK);
    sl_gvs_result r;
    assert_int_equal(sl_gvs_cell(g, vc, 0, &r, &err), SL_OK);
    assert_int_equal(r.stats.auto_visible, 8); /* the 4 side faces cross the cell; caps are outside */
    assert_true(has(r.objects, r.object_count, pole));
    assert_false(has(r.objects, r.object_count, far));
    sl_gvs_destroy(g);
    o.auto_visible = false;
    assert_int_equal(sl_gvs_create(es, s, &o, NULL, &g, &err), SL_OK);
    assert_int_equal(sl_gvs_cell(g, vc, 0, &r, &err), SL_OK);
    assert_int_equal(r.stats.auto_visible, 0);
    sl_gvs_destroy(g);
    sl_es_destroy(es);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

static bool same_result(const sl_gvs_result *a, const uint32_t *tris, uint32_t n)
{
    return a->triangle_count == n && memcmp(a->triangles, tris, (size_t)n * sizeof *tris) == 0;
}

/* The same cell gives the same triangles whatever came before, whatever Embree's thread count,
 * and with volume origins too; another seed gives another (valid) sample. */
static void test_determinism(void **state)
{
    (void)state;
    sl_error err;
    hole_scene h;
    make_hole_scene(&h, NULL);
    sl_es *e1, *e2;
    sl_es_options eo = {0};
    eo.threads = 1;
    assert_int_equal(sl_es_create(h.s, &eo, NULL, &e1, &err), SL_OK);
    eo.threads = 2;
    assert_int_equal(sl_es_create(h.s, &eo, NULL, &e2, &err), SL_OK);
    for (uint32_t origins = SL_GVS_ORIGINS_BOUNDARY; origins <= SL_GVS_ORIGINS_VOLUME; origins++) {
        sl_gvs_options o = sl_gvs_defaults();
        o.window = 10000;
        o.min_new = 1;
        o.max_rays = 200000;
        o.origins = origins;
        sl_gvs g1, g2;
        assert_int_equal(sl_gvs_create(e1, h.s, &o, NULL, &g1, &err), SL_OK);
        assert_int_equal(sl_gvs_create(e2, h.s, &o, NULL, &g2, &err), SL_OK);
        sl_gvs_result r;
        uint32_t *c0 = NULL, *c1 = NULL, n0 = 0, n1 = 0;
        uint64_t rays0 = 0;
        /* g1: cell 0 then 1; g2: cell 1 then 0, then 0 again */
        assert_int_equal(sl_gvs_cell(g1, h.vc, 0, &r, &err), SL_OK);
        n0 = r.triangle_count;
        rays0 = r.stats.rays;
        c0 = malloc((n0 + 1) * sizeof *c0);
        memcpy(c0, r.triangles, n0 * sizeof *c0);
        assert_int_equal(sl_gvs_cell(g1, h.vc, 1, &r, &err), SL_OK);
        n1 = r.triangle_count;
        c1 = malloc((n1 + 1) * sizeof *c1);
        memcpy(c1, r.triangles, n1 * sizeof *c1);
        assert_int_equal(sl_gvs_cell(g2, h.vc, 1, &r, &err), SL_OK);
        assert_true(same_result(&r, c1, n1));
        assert_int_equal(sl_gvs_cell(g2, h.vc, 0, &r, &err), SL_OK);
        assert_true(same_result(&r, c0, n0));
        assert_int_equal(r.stats.rays, rays0);
        assert_int_equal(sl_gvs_cell(g2, h.vc, 0, &r, &err), SL_OK);
        assert_true(same_result(&r, c0, n0));
        sl_gvs_destroy(g1);
        sl_gvs_destroy(g2);
        /* another seed: another Halton rotation, other rays */
        o.seed = 99;
        assert_int_equal(sl_gvs_create(e1, h.s, &o, NULL, &g1, &err), SL_OK);
        assert_int_equal(sl_gvs_cell(g1, h.vc, 0, &r, &err), SL_OK);
        assert_true(r.stats.rays != rays0 || !same_result(&r, c0, n0));
        sl_gvs_destroy(g1);
        free(c0);
        free(c1);
    }
    sl_es_destroy(e1);
    sl_es_destroy(e2);
    free_hole_scene(&h);
}

/* BSP clusters: origins in the cluster's leaves (the BSP decides), directions over the sphere;
 * boundary origins are refused. */
static void test_clusters(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    /* a wall at x = 0 splits the two clusters' halves except for a gap above z = 3 */
    float wp[12] = {0, -4, -4, 0, 4, -4, 0, 4, 3, 0, -4, 3};
    uint32_t wi[6] = {0, 1, 2, 0, 2, 3};
    uint32_t wall = add_mesh_object(s, wp, 4, wi, 2);
    uint32_t left = add_box(s, (sl_vec3){-3, -1, -3}, (sl_vec3){-2, 1, -2});
    uint32_t right = add_box(s, (sl_vec3){2, -1, -3}, (sl_vec3){3, 1, -2});
    sl_plane planes[1] = {{1, 0, 0, 0}};
    sl_bsp_node nodes[1] = {{0, {-1, -2}, {{-4, -4, -4}, {4, 4, 4}}}};
    sl_bsp_leaf leaves[2] = {{0, 0, {{0, -4, -4}, {4, 4, 4}}, 0, 1}, {1, 0, {{-4, -4, -4}, {0, 4, 4}}, 1, 1}};
    uint32_t lo[2] = {right, left};
    uint8_t pvs[2] = {0x3, 0x3};
    sl_bsp_desc bd = {planes, 1, nodes, 1, leaves, 2, lo, 2, 2, 1, pvs};
    assert_int_equal(sl_scene_set_bsp(s, &bd, &err), SL_OK);
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_from_bsp(s, NULL, &vc, &err), SL_OK);
    uint32_t cell_right = sl_viewcells_data(vc)[0].cluster == 0 ? 0 : 1;
    sl_es *es;
    assert_int_equal(sl_es_create(s, NULL, NULL, &es, &err), SL_OK);
    sl_gvs_options o = sl_gvs_defaults();
    o.window = 20000;
    o.min_new = 0;
    o.max_rays = 300000;
    sl_gvs g;
    assert_int_equal(sl_gvs_create(es, s, &o, NULL, &g, &err), SL_OK);
    sl_gvs_result r;
    assert_int_equal(sl_gvs_cell(g, vc, cell_right, &r, &err), SL_OK);
    assert_true(has(r.objects, r.object_count, wall));
    assert_true(has(r.objects, r.object_count, right));
    /* the left box stands low behind the wall, but the right cluster reaches above the wall's
     * top: from (0+, y, 3.9) the box's top at z = -2 is in sight over the wall */
    assert_true(has(r.objects, r.object_count, left));
    assert_true(r.stats.random_rays > 0);
    /* volume points: only the right half is the right cluster */
    double u[4 * 8];
    for (int i = 0; i < 32; i++)
        u[i] = (i * 0.618034) - floor(i * 0.618034);
    sl_vec3 p;
    assert_true(sl_gvs_cell_point(g, vc, cell_right, u, 8, &p));
    assert_true(sl_viewcells_locate(vc, s, p) == cell_right);
    sl_gvs_destroy(g);
    o.origins = SL_GVS_ORIGINS_BOUNDARY;
    assert_int_equal(sl_gvs_create(es, s, &o, NULL, &g, &err), SL_OK);
    assert_int_equal(sl_gvs_cell(g, vc, cell_right, &r, &err), SL_ERROR_UNSUPPORTED);
    assert_non_null(strstr(err.message, "cluster"));
    sl_gvs_destroy(g);
    sl_es_destroy(es);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

/* The `gvs` PVS method: registered, its options checked, its per-cell sets equal the library's. */
static void test_pvs_method(void **state)
{
    (void)state;
    sl_error err;
    bool found = false;
    for (uint32_t i = 0; i < sl_pvs_method_count(); i++) {
        sl_pvs_method_desc d;
        assert_int_equal(sl_pvs_method_info(i, &d, &err), SL_OK);
        if (strcmp(d.name, "gvs") == 0) {
            found = true;
            assert_int_equal(d.guarantee, SL_AGGRESSIVE);
            assert_non_null(strstr(d.options_help, "max_rays"));
        }
    }
    assert_true(found);
    assert_int_equal(sl_pvs_method_check_options("gvs", "eps=1e-4,window=1000,sampler=random", &err), SL_OK);
    assert_int_equal(sl_pvs_method_check_options("gvs", "eps=0", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_pvs_method_check_options("gvs", "sampler=fast", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_pvs_method_check_options("gvs", "rays=5", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "rays"));

    hole_scene h;
    make_hole_scene(&h, NULL);
    uint32_t ids[16], n = 0;
    assert_int_equal(sl_pvs_bake_cell(h.s, h.vc, 0, "gvs", "window=20000,min_new=0,max_rays=400000", ids, 16, &n, &err),
                     SL_OK);
    sl_es *es;
    assert_int_equal(sl_es_create(h.s, NULL, NULL, &es, &err), SL_OK);
    sl_gvs_options o = sl_gvs_defaults();
    o.window = 20000;
    o.min_new = 0;
    o.max_rays = 400000;
    sl_gvs g;
    assert_int_equal(sl_gvs_create(es, h.s, &o, NULL, &g, &err), SL_OK);
    sl_gvs_result r;
    assert_int_equal(sl_gvs_cell(g, h.vc, 0, &r, &err), SL_OK);
    assert_int_equal(n, r.object_count);
    assert_memory_equal(ids, r.objects, n * sizeof *ids);
    assert_true(has(ids, n, h.through));
    sl_gvs_destroy(g);
    sl_es_destroy(es);
    free_hole_scene(&h);
}

/* On street cells of the tiny city, GVS's objects cover what the region oracle (cube maps from
 * hundreds of points of the cell) sees, and GVS finds more triangles than random sampling with the
 * same rays. Both are samplings: an object one finds and the other misses is printed. */
static void test_city_cells(void **state)
{
    (void)state;
    sl_error err;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    sl_viewcells vc;
    assert_int_equal(sl_viewcells_from_streets(s, NULL, &vc, &err), SL_OK);
    sl_es *es;
    assert_int_equal(sl_es_create(s, NULL, NULL, &es, &err), SL_OK);
    sl_gvs_options o = sl_gvs_defaults();
    o.window = 200000;
    o.min_new = 10;
    o.max_rays = sanitized() ? 600000 : 3000000;
    sl_gvs g, rnd;
    assert_int_equal(sl_gvs_create(es, s, &o, NULL, &g, &err), SL_OK);
    sl_region_oracle_options ro = {0};
    ro.face_size = sanitized() ? 96 : 192;
    ro.edge_spacing = 1.0f;
    ro.face_samples = 16;
    ro.interior_samples = 16;
    ro.max_samples = sanitized() ? 24 : 96;
    sl_region_oracle orc;
    assert_int_equal(sl_region_oracle_create(s, &ro, NULL, &orc, &err), SL_OK);
    const uint32_t cells[2] = {7, sl_viewcells_count(vc) / 2};
    for (int k = 0; k < 2; k++) {
        sl_gvs_result r;
        assert_int_equal(sl_gvs_cell(g, vc, cells[k], &r, &err), SL_OK);
        sl_region_visibility v;
        assert_int_equal(sl_region_oracle_cell(orc, vc, cells[k], &v, &err), SL_OK);
        uint32_t common = 0;
        for (uint32_t i = 0; i < v.visible_count; i++) {
            if (has(r.objects, r.object_count, v.visible[i]))
                common++;
            else
                print_message("cell %u: GVS misses object %u (oracle: at most %u pixels of a %u^2 face)\n", cells[k],
                              v.visible[i], v.max_pixels[i], ro.face_size);
        }
        print_message("cell %u: GVS %u objects / %u triangles in %llu rays, region oracle %u objects, common %u\n",
                      cells[k], r.object_count, r.triangle_count, (unsigned long long)r.stats.rays, v.visible_count,
                      common);
        assert_true(v.visible_count > 0);
        assert_true(common * 100 >= v.visible_count * 95);
        uint32_t gvs_tris = r.triangle_count;
        sl_gvs_options ro2 = o;
        ro2.sampler = SL_GVS_RANDOM;
        ro2.max_rays = r.stats.rays;
        ro2.window = r.stats.rays + 1;
        assert_int_equal(sl_gvs_create(es, s, &ro2, NULL, &rnd, &err), SL_OK);
        assert_int_equal(sl_gvs_cell(rnd, vc, cells[k], &r, &err), SL_OK);
        assert_true(r.triangle_count < gvs_tris);
        sl_gvs_destroy(rnd);
    }
    sl_region_oracle_destroy(orc);
    sl_gvs_destroy(g);
    sl_es_destroy(es);
    sl_viewcells_destroy(vc);
    sl_scene_destroy(s);
}

static void test_bad_arguments(void **state)
{
    (void)state;
    sl_error err;
    hole_scene h;
    make_hole_scene(&h, NULL);
    sl_es *es;
    assert_int_equal(sl_es_create(h.s, NULL, NULL, &es, &err), SL_OK);
    sl_gvs g = NULL;
    sl_gvs_options o = sl_gvs_defaults();
    o.eps = 0;
    assert_int_equal(sl_gvs_create(es, h.s, &o, NULL, &g, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "eps"));
    o = sl_gvs_defaults();
    o.eps = NAN;
    assert_int_equal(sl_gvs_create(es, h.s, &o, NULL, &g, &err), SL_ERROR_INVALID_ARGUMENT);
    o = sl_gvs_defaults();
    o.window = 0;
    assert_int_equal(sl_gvs_create(es, h.s, &o, NULL, &g, &err), SL_ERROR_INVALID_ARGUMENT);
    o = sl_gvs_defaults();
    o.sampler = 7;
    assert_int_equal(sl_gvs_create(es, h.s, &o, NULL, &g, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_gvs_create(NULL, h.s, NULL, NULL, &g, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_null(g);
    /* an Embree scene of another scene */
    sl_scene other;
    assert_int_equal(sl_scene_create(NULL, &other, &err), SL_OK);
    assert_int_equal(sl_gvs_create(es, other, NULL, NULL, &g, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_scene_destroy(other);
    assert_int_equal(sl_gvs_create(es, h.s, NULL, NULL, &g, &err), SL_OK);
    sl_gvs_result r;
    assert_int_equal(sl_gvs_cell(g, h.vc, 2, &r, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "cell 2"));
    assert_int_equal(sl_gvs_cell(g, NULL, 0, &r, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_gvs_destroy(g);
    sl_gvs_destroy(NULL);
    sl_es_destroy(es);
    free_hole_scene(&h);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_halton),        cmocka_unit_test(test_enlarge_outside),
        cmocka_unit_test(test_hole_scene),    cmocka_unit_test(test_random_baseline),
        cmocka_unit_test(test_termination),   cmocka_unit_test(test_auto_visible),
        cmocka_unit_test(test_determinism),   cmocka_unit_test(test_clusters),
        cmocka_unit_test(test_pvs_method),    cmocka_unit_test(test_city_cells),
        cmocka_unit_test(test_bad_arguments),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
