/* Occluder synthesis (sl_synth_occluders, import.h; docs/occluder-synthesis.md): every box lies
 * inside its mesh (corners and a grid of points by an independent ray-parity point-in-mesh test,
 * no mesh vertex inside a box), a closed cube is mostly covered, open, badly oriented and
 * see-through objects get nothing, the result is deterministic, and hzb and lazygrid with the
 * synthesised occluders miss nothing against the oracle on a box house seen from outside and
 * inside (tests/test_synth_scenes.c runs the IFC house and the re-imported city). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "sightline/cull.h"
#include "sightline/import.h"
#include "sightline/scene.h"
#include "sightline/truth.h"
#include "support/box_mesh.h"
#include "support/counting_alloc.h"
#include "support/synth_check.h"

/* ---- shapes ---- */

static uint32_t add_mesh_object(sl_scene s, const float *p, uint32_t nv, const uint32_t *idx, uint32_t nt,
                                const sl_affine *xf, uint32_t material)
{
    sl_error err;
    sl_mesh_desc md = {p, NULL, nv, idx, nt, NULL};
    uint32_t mesh, obj;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, xf, 0xffffffffu, SL_KIND_IMPORTED, 0, material};
    assert_int_equal(sl_scene_add_object(s, &od, &obj, &err), SL_OK);
    return obj;
}

/* A prism over a polygon star-shaped from its vertex 0 (CCW seen from +z), z in [z0, z1]. */
static uint32_t add_prism(sl_scene s, const float *xy, uint32_t n, float z0, float z1, const sl_affine *xf)
{
    float p[2 * 3 * 16];
    uint32_t idx[3 * 64], nt = 0;
    for (uint32_t i = 0; i < n; i++) {
        p[3 * i] = xy[2 * i], p[3 * i + 1] = xy[2 * i + 1], p[3 * i + 2] = z0;
        p[3 * (n + i)] = xy[2 * i], p[3 * (n + i) + 1] = xy[2 * i + 1], p[3 * (n + i) + 2] = z1;
    }
    for (uint32_t i = 1; i + 1 < n; i++) {
        uint32_t b[3] = {0, i + 1, i}, t[3] = {n, n + i, n + i + 1}; /* bottom faces down, top up */
        memcpy(&idx[3 * nt++], b, sizeof b);
        memcpy(&idx[3 * nt++], t, sizeof t);
    }
    for (uint32_t i = 0; i < n; i++) {
        uint32_t j = (i + 1) % n;
        uint32_t q1[3] = {i, j, n + j}, q2[3] = {i, n + j, n + i};
        memcpy(&idx[3 * nt++], q1, sizeof q1);
        memcpy(&idx[3 * nt++], q2, sizeof q2);
    }
    return add_mesh_object(s, p, 2 * n, idx, nt, xf, 0);
}

/* A UV sphere with its seam and pole vertices repeated (as exporters split them for UVs): closed
 * only once welded. */
static uint32_t add_sphere(sl_scene s, float cx, float cy, float cz, float r, const sl_affine *xf)
{
    enum { NU = 18, NV = 10 };
    static float p[3 * (NU + 1) * (NV + 1)];
    static uint32_t idx[6 * NU * NV];
    uint32_t nt = 0;
    for (uint32_t v = 0; v <= NV; v++)
        for (uint32_t u = 0; u <= NU; u++) {
            double th = M_PI * v / NV, ph = 2 * M_PI * (u % NU) / NU;
            float *q = &p[3 * (v * (NU + 1) + u)];
            q[0] = cx + r * (float)(sin(th) * cos(ph));
            q[1] = cy + r * (float)(sin(th) * sin(ph));
            q[2] = cz + r * (float)cos(th);
            if (v == 0 || v == NV)
                q[0] = cx, q[1] = cy; /* the poles exactly */
        }
    for (uint32_t v = 0; v < NV; v++)
        for (uint32_t u = 0; u < NU; u++) {
            uint32_t a = v * (NU + 1) + u, b = a + 1, c = a + NU + 1, d = c + 1;
            if (v > 0) {
                uint32_t t[3] = {a, c, b};
                memcpy(&idx[3 * nt++], t, sizeof t);
            }
            if (v + 1 < NV) {
                uint32_t t[3] = {b, c, d};
                memcpy(&idx[3 * nt++], t, sizeof t);
            }
        }
    return add_mesh_object(s, p, (NU + 1) * (NV + 1), idx, nt, xf, 0);
}

static sl_affine rot_z(float deg, float tx, float ty, float tz)
{
    float c = cosf(deg * (float)M_PI / 180), s = sinf(deg * (float)M_PI / 180);
    sl_affine a = {{c, -s, 0, tx, s, c, 0, ty, 0, 0, 1, tz}};
    return a;
}

static sl_scene new_scene(void)
{
    sl_scene s;
    sl_error err;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    return s;
}

static sl_synth_stats synth(sl_scene s, const sl_synth_options *o)
{
    sl_synth_stats st;
    sl_error err;
    if (sl_synth_occluders(s, o, NULL, &st, &err) != SL_OK)
        fail_msg("synthesis: %s", err.message);
    return st;
}

/* ---- tests ---- */

static void test_cube(void **state)
{
    (void)state;
    sl_scene s = new_scene();
    uint32_t o = sl_test_add_box(s, (sl_vec3){0, 0, 0}, (sl_vec3){10, 8, 6}, SL_KIND_IMPORTED, 0);
    sl_synth_stats st = synth(s, NULL);
    assert_int_equal(st.considered, 1);
    assert_int_equal(st.closed, 1);
    assert_true(st.boxes >= 1);
    assert_int_equal(st.occluder_meshes, 1);
    assert_int_equal(sl_scene_occluder_count(s), 1);
    assert_int_equal(sl_scene_occluder(s, 0).object, o);
    assert_true(fabs(st.closed_volume - 480.0) < 1e-3);
    sl_synth_check c = sl_synth_check_object(s, o, 5);
    print_message("cube: %u boxes, voxel fraction %.3f, box volume %.1f of 480 m^3\n", st.boxes, st.volume_fraction,
                  c.box_volume);
    assert_int_equal(c.outside_points, 0);
    assert_int_equal(c.vertices_inside, 0);
    assert_true(c.box_volume > 0.95 * 480.0); /* grown towards the faces: nearly all of it */
    assert_true(c.box_volume < 480.0);
    assert_true(st.volume_fraction > 0.6);
    /* a second run adds nothing: the cube has occluders of its own now */
    sl_synth_stats again = synth(s, NULL);
    assert_int_equal(again.boxes, 0);
    assert_int_equal(again.native, 1);
    sl_scene_destroy(s);
}

/* A cube whose +x face is four quads (an exporter's bays) while the faces around it are single
 * quads: the four midpoints of that face's edges lie inside the neighbours' edges (T-junctions),
 * so the shell reads as open until they are split. Then it is closed and its boxes lie inside it
 * (the checker splits T-junctions its own way). */
static void test_t_junctions(void **state)
{
    (void)state;
    static const float p[] = {
        0, 0, 0, 10, 0, 0, 0, 10, 0, 10, 10, 0, 0, 0, 10, 10, 0, 10, 0, 10, 10, 10, 10, 10, /* 0..7: x, y, z bits */
        10, 5, 0, 10, 10, 5, 10, 5, 10, 10, 0, 5, 10, 5, 5,                                   /* 8..12 on x = 10 */
    };
    /* quads as corner lists; each is made counter-clockwise seen from outside below */
    static const uint32_t quads[][4] = {
        {0, 2, 6, 4}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 6, 7, 5}, /* -x, -y, +y, -z, +z */
        {1, 8, 12, 11}, {8, 3, 9, 12}, {12, 9, 7, 10}, {11, 12, 10, 5},       /* +x in four */
    };
    uint32_t idx[9 * 6], nt = 0;
    for (size_t q = 0; q < 9; q++) {
        const float *a = p + 3 * quads[q][0], *b = p + 3 * quads[q][1], *c = p + 3 * quads[q][2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        double out = n[0] * (a[0] + c[0] - 10) + n[1] * (a[1] + c[1] - 10) + n[2] * (a[2] + c[2] - 10);
        uint32_t k[4] = {quads[q][0], quads[q][1], quads[q][2], quads[q][3]};
        if (out < 0)
            k[1] = quads[q][3], k[3] = quads[q][1];
        uint32_t tri[6] = {k[0], k[1], k[2], k[0], k[2], k[3]};
        memcpy(idx + 3 * nt, tri, sizeof tri);
        nt += 2;
    }
    sl_scene s = new_scene();
    uint32_t o = add_mesh_object(s, p, 13, idx, nt, NULL, 0);
    sl_synth_stats st = synth(s, NULL);
    print_message("T-junctions: %u triangles split, closed %u, %u boxes\n", st.t_junctions, st.closed, st.boxes);
    assert_int_equal(st.t_junctions, 4); /* the four neighbour faces' triangles on the shared edges */
    assert_int_equal(st.closed, 1);
    assert_int_equal(st.open, 0);
    assert_int_equal(st.partial, 0);
    assert_true(st.boxes >= 1);
    assert_true(fabs(st.closed_volume - 1000.0) < 1e-3);
    sl_synth_check c = sl_synth_check_object(s, o, 5);
    assert_int_equal(c.outside_points, 0);
    assert_int_equal(c.vertices_inside, 0);
    assert_true(c.box_volume > 0.9 * 1000.0);
    sl_scene_destroy(s);
    /* a vertex near an edge but off it by more than the tolerance is no T-junction: the shell stays
     * open (a crack) and gets nothing */
    float q[sizeof p / sizeof p[0]];
    memcpy(q, p, sizeof q);
    q[3 * 10] = 10.01f; /* the midpoint of the top edge of x = 10, 1 cm out (the bottom one may stay open: a base) */
    s = new_scene();
    add_mesh_object(s, q, 13, idx, nt, NULL, 0);
    st = synth(s, NULL);
    assert_int_equal(st.closed, 0);
    assert_int_equal(st.boxes, 0);
    sl_scene_destroy(s);
}

/* Non-convex and curved shapes, moved and rotated: every box inside. */
static void test_inside_shapes(void **state)
{
    (void)state;
    sl_scene s = new_scene();
    static const float L[] = {4, 4, 4, 10, 0, 10, 0, 0, 10, 0, 10, 4}; /* star-shaped from (4, 4) */
    sl_affine r1 = rot_z(30, 20, 5, 0), r2 = rot_z(-17, -30, 10, 2);
    uint32_t ol = add_prism(s, L, 6, 0, 7, NULL);
    uint32_t olr = add_prism(s, L, 6, 1, 4, &r1);
    uint32_t os = add_sphere(s, 0, 0, 5, 4, &r2);
    uint32_t os2 = add_sphere(s, 40, 40, 3, 2.5f, NULL);
    /* a gable house: the pentagon (0,0) (8,0) (8,5) (4,8) (0,5) in x-z, 12 m along y */
    static const float gable[] = {0, 0, 8, 0, 8, 5, 4, 8, 0, 5};
    sl_affine swap = {{1, 0, 0, 60, 0, 0, 1, 0, 0, 1, 0, 0}}; /* (x, y, z) -> (x, z, y): a mirror */
    uint32_t og = add_prism(s, gable, 5, 0, 12, &swap);
    sl_synth_options opt = sl_synth_defaults();
    sl_synth_stats st = synth(s, &opt);
    assert_int_equal(st.closed, 5);
    assert_int_equal(st.objects_with_boxes, 5);
    const uint32_t objs[] = {ol, olr, os, os2, og};
    const char *names[] = {"L prism", "rotated L prism", "rotated sphere", "sphere", "mirrored gable house"};
    for (int i = 0; i < 5; i++) {
        sl_synth_check c = sl_synth_check_object(s, objs[i], 6);
        print_message("%-22s %u boxes, %llu points checked, box volume %.2f of %.2f m^3\n", names[i], c.boxes,
                      (unsigned long long)c.points, c.box_volume, c.mesh_volume);
        assert_true(c.boxes >= 1);
        assert_int_equal(c.outside_points, 0);
        assert_int_equal(c.vertices_inside, 0);
        assert_true(c.box_volume > 0.2 * c.mesh_volume); /* a sphere in 16 boxes: about a quarter */
    }
    sl_scene_destroy(s);
}

static void test_open_and_see_through(void **state)
{
    (void)state;
    sl_scene s = new_scene();
    sl_error err;
    float p[24];
    sl_test_box_vertices((sl_vec3){0, 0, 0}, (sl_vec3){5, 5, 5}, p);
    /* open: a face missing */
    add_mesh_object(s, p, 8, sl_test_box_indices, 10, NULL, 0);
    /* closed but one triangle flipped: not consistently oriented */
    uint32_t flipped[36];
    memcpy(flipped, sl_test_box_indices, sizeof flipped);
    uint32_t t = flipped[1];
    flipped[1] = flipped[2], flipped[2] = t;
    add_mesh_object(s, p, 8, flipped, 12, NULL, 0);
    /* two cubes sharing an edge (four faces on it): not a closed surface around either */
    float p2[48];
    memcpy(p2, p, sizeof p);
    sl_test_box_vertices((sl_vec3){5, 5, 0}, (sl_vec3){10, 10, 5}, p2 + 24);
    uint32_t two[72];
    for (int i = 0; i < 36; i++)
        two[i] = sl_test_box_indices[i], two[36 + i] = 8 + sl_test_box_indices[i];
    add_mesh_object(s, p2, 16, two, 24, NULL, 0);
    /* a closed cube with a loose fin (a triangle on one of its edges): the fin is peeled off, the
     * cube gets its box */
    uint32_t extra[39];
    memcpy(extra, sl_test_box_indices, sizeof sl_test_box_indices);
    extra[36] = 0, extra[37] = 1, extra[38] = 7;
    uint32_t fin = add_mesh_object(s, p, 8, extra, 13, NULL, 0);
    /* see-through: a blended material */
    sl_material m = {{1, 1, 1, 0.5f}, NULL, SL_ALPHA_BLEND, 0.5f, 0};
    uint32_t mat;
    assert_int_equal(sl_scene_add_material(s, &m, &mat, &err), SL_OK);
    add_mesh_object(s, p, 8, sl_test_box_indices, 12, NULL, mat);
    /* dynamic */
    sl_test_add_box(s, (sl_vec3){10, 0, 0}, (sl_vec3){15, 5, 5}, SL_KIND_CAR, SL_OBJECT_DYNAMIC);
    /* its own occluder already (flagged) */
    sl_test_add_box(s, (sl_vec3){20, 0, 0}, (sl_vec3){25, 5, 5}, SL_KIND_BUILDING, SL_OBJECT_OCCLUDER);
    sl_synth_stats st = synth(s, NULL);
    assert_int_equal(st.considered, 4);
    assert_int_equal(st.open, 3);
    assert_int_equal(st.closed, 1);
    assert_int_equal(st.partial, 1);
    assert_int_equal(st.see_through, 1);
    assert_int_equal(st.dynamic, 1);
    assert_int_equal(st.native, 1);
    assert_int_equal(st.boxes, 1);
    assert_int_equal(sl_scene_occluder_count(s), 1);
    assert_int_equal(sl_scene_occluder(s, 0).object, fin);
    assert_string_equal(sl_scene_meta(s, "occluders.synthesised"), "1");
    sl_synth_check c = sl_synth_check_object(s, fin, 4);
    assert_int_equal(c.outside_points, 0);
    sl_scene_destroy(s);
}

static sl_scene det_scene(void)
{
    sl_scene s = new_scene();
    static const float L[] = {4, 4, 4, 10, 0, 10, 0, 0, 10, 0, 10, 4};
    sl_affine r = rot_z(11, 3, 4, 0);
    add_prism(s, L, 6, 0, 5, &r);
    add_sphere(s, 30, 0, 4, 3, NULL);
    sl_test_add_box(s, (sl_vec3){-20, 0, 0}, (sl_vec3){-10, 3, 9}, SL_KIND_IMPORTED, 0);
    return s;
}

static void test_deterministic(void **state)
{
    (void)state;
    sl_scene a = det_scene(), b = det_scene();
    sl_synth_stats sa = synth(a, NULL), sb = synth(b, NULL);
    assert_int_equal(sa.boxes, sb.boxes);
    assert_true(sa.boxes > 3);
    assert_int_equal(sl_scene_occluder_count(a), sl_scene_occluder_count(b));
    for (uint32_t i = 0; i < sl_scene_occluder_count(a); i++) {
        sl_occluder_view va = sl_scene_occluder(a, i), vb = sl_scene_occluder(b, i);
        assert_int_equal(va.object, vb.object);
        sl_mesh_view ma = sl_scene_mesh(a, va.mesh), mb = sl_scene_mesh(b, vb.mesh);
        assert_int_equal(ma.vertex_count, mb.vertex_count);
        assert_int_equal(ma.triangle_count, mb.triangle_count);
        assert_memory_equal(ma.positions, mb.positions, 3 * sizeof(float) * ma.vertex_count);
        assert_memory_equal(ma.indices, mb.indices, 3 * sizeof(uint32_t) * ma.triangle_count);
    }
    sl_scene_destroy(a);
    sl_scene_destroy(b);
}

/* Options: budgets, a coarse voxel, no growing. */
static void test_options(void **state)
{
    (void)state;
    sl_scene s = det_scene();
    sl_synth_options o = sl_synth_defaults();
    o.max_boxes_per_object = 2;
    o.max_boxes = 3;
    o.no_expand = true;
    sl_synth_stats st = synth(s, &o);
    assert_int_equal(st.boxes, 3);
    assert_true(st.dropped_by_budget >= 1);
    for (uint32_t i = 0; i < sl_scene_object_count(s); i++) {
        sl_synth_check c = sl_synth_check_object(s, i, 4);
        assert_true(c.boxes <= 2);
        assert_int_equal(c.outside_points, 0);
    }
    sl_scene_destroy(s);
    sl_error err;
    s = det_scene();
    o = sl_synth_defaults();
    o.voxel = -1;
    assert_int_equal(sl_synth_occluders(s, &o, NULL, NULL, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_scene_destroy(s);
}

/* A box house (a closed 10 x 10 x 6 m cube, two-sided like every imported mesh) with furniture
 * inside and houses around: hzb and lazygrid with the synthesised boxes miss nothing, from outside
 * (the house hides what is behind it) and from inside (the eye in the house sees the furniture,
 * which lies inside the house's solid: the house's boxes are not used then). */
static void test_box_house_views(void **state)
{
    (void)state;
    sl_scene s = new_scene();
    sl_test_add_box(s, (sl_vec3){0, 0, 0}, (sl_vec3){10, 10, 6}, SL_KIND_IMPORTED, 0);
    sl_test_add_box(s, (sl_vec3){2, 2, 0}, (sl_vec3){3, 3, 1}, SL_KIND_IMPORTED, 0);
    sl_test_add_box(s, (sl_vec3){6, 7, 0}, (sl_vec3){8, 8, 2}, SL_KIND_IMPORTED, 0);
    for (int i = 0; i < 8; i++) {
        float x = -30 + 9.0f * i;
        sl_test_add_box(s, (sl_vec3){x, 18, 0}, (sl_vec3){x + 4, 21, 3 + (float)(i % 3)}, SL_KIND_IMPORTED, 0);
        sl_test_add_box(s, (sl_vec3){x, -14, 0}, (sl_vec3){x + 3, -11, 2 + (float)(i % 4)}, SL_KIND_IMPORTED, 0);
    }
    sl_synth_stats st = synth(s, NULL);
    assert_true(st.boxes >= 3);
    sl_camera cams[48];
    uint32_t nc = 0;
    sl_rng rng;
    sl_rng_seed(&rng, 7, 1);
    for (uint32_t i = 0; i < 48; i++) {
        sl_camera c = sl_camera_default();
        c.width = 160, c.height = 120;
        if (i < 32) { /* around, looking at the house */
            float a = 2 * (float)M_PI * sl_rng_float(&rng), d = 12 + 20 * sl_rng_float(&rng);
            c.position = (sl_vec3){5 + d * cosf(a), 5 + d * sinf(a), 1 + 8 * sl_rng_float(&rng)};
            c.yaw = atan2f(5 - c.position.y, 5 - c.position.x) + 0.4f * (sl_rng_float(&rng) - 0.5f);
            c.pitch = -0.2f * sl_rng_float(&rng);
        } else { /* inside */
            c.position = (sl_vec3){1 + 8 * sl_rng_float(&rng), 1 + 8 * sl_rng_float(&rng), 1.5f + 3 * sl_rng_float(&rng)};
            c.yaw = 2 * (float)M_PI * sl_rng_float(&rng);
            c.pitch = 0.3f * (sl_rng_float(&rng) - 0.5f);
        }
        cams[nc++] = c;
    }
    sl_synth_views r[3];
    const char *methods[3] = {"vfc", "hzb", "lazygrid"};
    for (int m = 0; m < 3; m++) {
        r[m] = sl_synth_run_views(s, methods[m], NULL, cams, nc);
        print_message("box house %-9s kept %llu / visible %llu (%.2fx), missed %llu\n", methods[m],
                      (unsigned long long)r[m].kept, (unsigned long long)r[m].visible, r[m].overestimation,
                      (unsigned long long)r[m].missed);
        assert_int_equal(r[m].missed, 0);
    }
    assert_true(r[1].kept < r[0].kept); /* the house's boxes hide something */
    sl_scene_destroy(s);
}

/* A house without a floor (its mesh open in the plane of its lowest z) gets boxes (the surface
 * closed by a cap there encloses them); they are used only for eyes above that plane: from below
 * the eye sees into the house through the missing floor (the furniture inside), and from above it
 * the house hides what is behind it. */
static void test_floorless_views(void **state)
{
    (void)state;
    sl_scene s = new_scene();
    float p[24];
    sl_test_box_vertices((sl_vec3){0, 0, 0}, (sl_vec3){10, 10, 6}, p);
    uint32_t floorless[30]; /* every face but -z (triangles 8 and 9 of sl_test_box_indices) */
    memcpy(floorless, sl_test_box_indices, 24 * sizeof(uint32_t));
    memcpy(floorless + 24, sl_test_box_indices + 30, 6 * sizeof(uint32_t));
    uint32_t house = add_mesh_object(s, p, 8, floorless, 10, NULL, 0);
    sl_test_add_box(s, (sl_vec3){4, 4, 2}, (sl_vec3){6, 6, 3}, SL_KIND_IMPORTED, 0); /* a lamp inside */
    sl_test_add_box(s, (sl_vec3){4, 30, 0}, (sl_vec3){6, 32, 3}, SL_KIND_IMPORTED, 0); /* behind, seen from -y */
    sl_synth_stats st = synth(s, NULL);
    assert_int_equal(st.base_open, 1);
    assert_true(st.boxes >= 1);
    sl_synth_check c = sl_synth_check_object(s, house, 5);
    assert_int_equal(c.outside_points, 0);
    assert_true(c.box_volume > 0.9 * 600);
    sl_camera cams[16];
    for (uint32_t i = 0; i < 16; i++) {
        sl_camera cam = sl_camera_default();
        cam.width = 160, cam.height = 120;
        if (i < 8) { /* below the missing floor, looking up into the house */
            cam.position = (sl_vec3){2 + (float)i, 5, -2.0f - 0.3f * (float)i};
            cam.yaw = 0.3f * (float)i;
            cam.pitch = 1.2f;
        } else { /* on the far side, level with the lamp */
            cam.position = (sl_vec3){(float)i - 7, -25, 0.2f * (float)i};
            cam.yaw = (float)M_PI / 2;
            cam.pitch = 0;
        }
        cams[i] = cam;
    }
    sl_synth_views v = sl_synth_run_views(s, "vfc", NULL, cams, 16);
    const char *methods[2] = {"hzb", "lazygrid"};
    for (int m = 0; m < 2; m++) {
        sl_synth_views r = sl_synth_run_views(s, methods[m], NULL, cams, 16);
        print_message("floorless house %-9s kept %llu / visible %llu (vfc %llu), missed %llu\n", methods[m],
                      (unsigned long long)r.kept, (unsigned long long)r.visible, (unsigned long long)v.kept,
                      (unsigned long long)r.missed);
        assert_int_equal(r.missed, 0);
        assert_true(r.kept < v.kept); /* from the far side the house hides what is behind it */
    }
    sl_scene_destroy(s);
}

/* An L-shaped closed house with one box (budget 1: in one arm) and a table inside that arm: an eye
 * in the other arm is inside the house but outside the box; it sees the table, which the box
 * would hide. The boxes of an object are not used while the eye is inside the object's box. */
static void test_eye_inside_object(void **state)
{
    (void)state;
    sl_scene s = new_scene();
    static const float L[] = {10, 10, 10, 40, 0, 40, 0, 0, 40, 0, 40, 10}; /* arms along x and y */
    add_prism(s, L, 6, 0, 5, NULL);
    sl_test_add_box(s, (sl_vec3){12, 1, 0}, (sl_vec3){14, 3, 1}, SL_KIND_IMPORTED, 0); /* table, x arm */
    sl_synth_options o = sl_synth_defaults();
    o.max_boxes_per_object = 1;
    sl_synth_stats st = synth(s, &o);
    assert_int_equal(st.boxes, 2); /* one in the house, one in the table */
    sl_camera cams[8];
    for (uint32_t i = 0; i < 8; i++) {
        sl_camera c = sl_camera_default();
        c.width = 160, c.height = 120;
        c.position = (sl_vec3){1 + 0.3f * (float)i, 12 + 0.5f * (float)i, 1.5f}; /* in the y arm */
        c.yaw = atan2f(2 - c.position.y, 13 - c.position.x);
        cams[i] = c;
    }
    sl_synth_views v = sl_synth_run_views(s, "vfc", NULL, cams, 8);
    assert_int_equal(v.visible, 16); /* the house and the table, every frame */
    for (int m = 0; m < 2; m++) {
        sl_synth_views r = sl_synth_run_views(s, m ? "lazygrid" : "hzb", NULL, cams, 8);
        assert_int_equal(r.missed, 0);
    }
    sl_scene_destroy(s);
}

/* Every byte the synthesis takes from the caller's allocator comes back (sizes included: the
 * counting allocator checks each free against its allocation). */
static void test_allocator(void **state)
{
    (void)state;
    sl_scene s = det_scene();
    sl_test_add_box(s, (sl_vec3){50, 0, 0}, (sl_vec3){60, 10, 5}, SL_KIND_IMPORTED, 0);
    float p[24];
    sl_test_box_vertices((sl_vec3){70, 0, 0}, (sl_vec3){75, 5, 5}, p);
    uint32_t extra[39]; /* a cube with a fin: the peel */
    memcpy(extra, sl_test_box_indices, sizeof sl_test_box_indices);
    extra[36] = 0, extra[37] = 1, extra[38] = 7;
    add_mesh_object(s, p, 8, extra, 13, NULL, 0);
    sl_test_counter cnt = {0, 0, 0};
    sl_allocator a = sl_test_counting_allocator(&cnt);
    sl_synth_stats st;
    sl_error err;
    assert_int_equal(sl_synth_occluders(s, NULL, &a, &st, &err), SL_OK);
    assert_true(st.boxes > 3);
    assert_true(cnt.calls > 10);
    assert_int_equal(cnt.live, 0);
    sl_scene_destroy(s);
}

/* An object moved after the synthesis (sl_scene_set_object_transform, told to the culler) leaves
 * its boxes behind: the cullers stop using them, so nothing the boxes cover is lost. */
static void test_moved_object(void **state)
{
    (void)state;
    sl_scene s = new_scene();
    uint32_t wall = sl_test_add_box(s, (sl_vec3){-10, 10, 0}, (sl_vec3){10, 12, 8}, SL_KIND_IMPORTED, 0);
    sl_test_add_box(s, (sl_vec3){-1, 20, 0}, (sl_vec3){1, 22, 2}, SL_KIND_IMPORTED, 0); /* behind the wall */
    sl_synth_stats st = synth(s, NULL);
    assert_true(st.boxes >= 2);
    sl_camera cam = sl_camera_default();
    cam.width = 160, cam.height = 120;
    cam.position = (sl_vec3){0, 0, 1.5f};
    cam.yaw = (float)M_PI / 2;
    sl_error err;
    for (int m = 0; m < 2; m++) {
        sl_culler c;
        assert_int_equal(sl_culler_create(m ? "lazygrid" : "hzb", s, NULL, NULL, &c, &err), SL_OK);
        uint32_t out[4], k;
        assert_int_equal(sl_culler_cull(c, &cam, out, 4, &k, &err), SL_OK);
        assert_int_equal(k, 1); /* the wall hides the box behind it */
        sl_affine aside = {{1, 0, 0, 14, 0, 1, 0, 0, 0, 0, 1, 0}}; /* the wall slides 14 m along x */
        assert_int_equal(sl_scene_set_object_transform(s, wall, &aside, &err), SL_OK);
        assert_int_equal(sl_culler_scene_changed(c, &err), SL_OK);
        assert_int_equal(sl_culler_cull(c, &cam, out, 4, &k, &err), SL_OK);
        assert_int_equal(k, 2); /* the wall, still in view, and the box behind, seen now */
        sl_affine id = sl_affine_identity();
        assert_int_equal(sl_scene_set_object_transform(s, wall, &id, &err), SL_OK);
        sl_culler_destroy(c);
    }
    sl_scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cube),
        cmocka_unit_test(test_t_junctions),
        cmocka_unit_test(test_inside_shapes),
        cmocka_unit_test(test_open_and_see_through),
        cmocka_unit_test(test_deterministic),
        cmocka_unit_test(test_options),
        cmocka_unit_test(test_box_house_views),
        cmocka_unit_test(test_floorless_views),
        cmocka_unit_test(test_eye_inside_object),
        cmocka_unit_test(test_allocator),
        cmocka_unit_test(test_moved_object),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
