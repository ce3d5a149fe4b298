/* Views (include/sightline/view.h, issue 13 §1): the camera's view bit for bit; engine matrices in
 * every depth convention, handedness and image orientation giving the camera's frustum and image;
 * refusals naming the element; the far plane bounded by the world; the closed-mesh winding of the
 * normal form; and off-axis, reversed-z and infinite-far views through every conservative method
 * against the oracle with zero misses (the tiny city's street, orthographic flyover and near-wall
 * views, two OpenArena maps' near-wall views; a third of them also against a 2x MSAA-4x oracle for
 * the methods promising any resolution), with a method that ignores the off-axis shift shown to
 * miss.
 * CTest: 720 views x 15 methods and 240 x pvs in release (about 13 s); under SL_SANITIZED 64 views
 * (4 cameras of each kind in the city, 4 of one map; four engine views each) and no pvs bake. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/sl_core.h"
#include "sightline/bake.h"
#include "sightline/cull.h"
#include "sightline/gen.h"
#include "sightline/import.h"
#include "sightline/path.h"
#include "sightline/region.h"
#include "sightline/truth.h"
#include "sightline/view.h"
#include "support/box_mesh.h"
#include "support/view_matrices.h"

#include "../bench/near_wall_views.h"

#include "support/pk3_names.h"

#define OA_PK3 SL_TEST_OA_PK3

static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }

static sl_camera test_camera(int k)
{
    sl_camera c = sl_camera_default();
    c.position = (sl_vec3){3.5f + k, -2.0f, 1.7f + 0.5f * k};
    c.yaw = 0.3f + 0.9f * k;
    c.pitch = -0.2f + 0.15f * k;
    c.roll = k % 2 ? 0.4f : 0.0f;
    c.width = k % 3 == 2 ? 333 : 320;
    c.height = k % 3 == 2 ? 97 : 240;
    if (k >= 3) {
        c.projection = SL_ORTHOGRAPHIC;
        c.ortho_height = 40.0f;
        c.near_plane = 1.0f;
        c.far_plane = 900.0f;
    }
    return c;
}

/* sl_view_from_camera is the camera functions, bit for bit. */
static void test_from_camera_exact(void **state)
{
    (void)state;
    sl_error err;
    for (int k = 0; k < 6; k++) {
        sl_camera c = test_camera(k);
        sl_view v;
        assert_int_equal(sl_view_from_camera(&c, &v, &err), SL_OK);
        sl_mat4 vm = sl_camera_view(&c), pm = sl_camera_proj(&c), vp = sl_camera_view_proj(&c);
        sl_frustum fr = sl_camera_frustum(&c);
        assert_memory_equal(&v.view, &vm, sizeof vm);
        assert_memory_equal(&v.proj, &pm, sizeof pm);
        assert_memory_equal(&v.view_proj, &vp, sizeof vp);
        assert_memory_equal(&v.frustum, &fr, sizeof fr);
        sl_vec3 f, r, u;
        sl_camera_basis(&c, &f, &r, &u);
        assert_memory_equal(&v.forward, &f, sizeof f);
        assert_memory_equal(&v.right, &r, sizeof r);
        assert_memory_equal(&v.up, &u, sizeof u);
        assert_memory_equal(&v.eye, &c.position, sizeof c.position);
        assert_true(v.near_plane == c.near_plane && v.far_plane == c.far_plane);
        assert_int_equal(v.source, SL_VIEW_FROM_CAMERA);
        assert_int_equal(sl_view_validate(&v, &err), SL_OK);
        /* the depth checks are the camera's */
        for (int fmt = 0; fmt < 3; fmt++)
            assert_true(sl_view_min_near(&v, (sl_depth_format)fmt) == sl_camera_min_near(&c, (sl_depth_format)fmt));
    }
    sl_camera bad = sl_camera_default();
    bad.width = 0;
    sl_view v;
    assert_int_equal(sl_view_from_camera(&bad, &v, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "viewport"));
}

static double rel(double a, double b) { return fabs(a - b) / fmax(1.0, fmax(fabs(a), fabs(b))); }

/* Engine matrices of a camera, in every convention: the camera's frustum, planes and depth range,
 * the mirror flags, and the camera's id image from the oracle. */
static void test_from_matrices_conventions(void **state)
{
    (void)state;
    sl_error err;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    static const unsigned flag_sets[] = {0,
                                         SL_TVM_LH_Z,
                                         SL_TVM_LH_X,
                                         SL_TVM_FLIP_Y,
                                         SL_TVM_FLIP_X,
                                         SL_TVM_LH_Z | SL_TVM_FLIP_Y,
                                         SL_TVM_LH_X | SL_TVM_FLIP_X | SL_TVM_FLIP_Y,
                                         SL_TVM_INF,
                                         SL_TVM_INF | SL_TVM_LH_Z,
                                         SL_TVM_INF | SL_TVM_FLIP_Y | SL_TVM_LH_X};
    uint32_t *ref = NULL;
    for (int k = 0; k < 6; k += sanitized() ? 3 : 1) {
        sl_camera c = test_camera(k);
        c.position = (sl_vec3){-20.0f + 7 * k, 5.0f, 2.0f + 10 * (k >= 3)};
        c.width = 160, c.height = k % 3 == 2 ? 64 : 120;
        sl_frustum fr = sl_camera_frustum(&c);
        sl_mat4 cvp = sl_camera_view_proj(&c);
        sl_oracle_frame f0;
        assert_int_equal(sl_oracle_render(o, &c, &f0, &err), SL_OK);
        sl_oracle_view ov;
        assert_int_equal(sl_oracle_get_view(o, 0, &ov, &err), SL_OK);
        size_t px = (size_t)c.width * c.height;
        ref = realloc(ref, px * sizeof *ref);
        memcpy(ref, ov.ids, px * sizeof *ref);
        for (int d = 0; d < 3; d++)
            for (size_t q = 0; q < SL_COUNTOF(flag_sets); q++) {
                unsigned fl = flag_sets[q];
                bool inf = (fl & SL_TVM_INF) && c.projection == SL_PERSPECTIVE;
                if ((fl & SL_TVM_INF) && !inf)
                    continue;
                float V[16], P[16];
                sl_tvm_matrices(&c, (sl_clip_depth)d, fl, NULL, V, P);
                sl_view v;
                if (sl_view_from_matrices(V, P, (sl_clip_depth)d, c.width, c.height, &v, &err) != SL_OK)
                    fail_msg("camera %d, %s, flags %u: %s", k, sl_clip_depth_name((sl_clip_depth)d), fl, err.message);
                assert_int_equal(v.projection, c.projection);
                assert_int_equal(v.mirrored_x, (fl & SL_TVM_FLIP_X) != 0);
                assert_int_equal(v.mirrored_y, (fl & SL_TVM_FLIP_Y) != 0);
                assert_int_equal(v.left_handed, ((fl & SL_TVM_LH_Z) != 0) != ((fl & SL_TVM_LH_X) != 0));
                assert_true(rel(v.near_plane, c.near_plane) < 1e-4);
                if (inf)
                    assert_true(isinf(v.far_plane));
                else if (!(fabs(v.far_plane - c.far_plane) / c.far_plane <
                           (c.projection == SL_PERSPECTIVE ? 1e-2 : 1e-4)))
                    fail_msg("camera %d, %s, flags %u: far %.9g for %.9g", k, sl_clip_depth_name((sl_clip_depth)d), fl,
                             v.far_plane, (double)c.far_plane);
                assert_true(rel(v.eye.x, c.position.x) < 1e-5 && rel(v.eye.y, c.position.y) < 1e-5 &&
                            rel(v.eye.z, c.position.z) < 1e-5);
                for (int i = 0; i < (inf ? 5 : 6); i++) {
                    const sl_plane *a = &v.frustum.planes[i], *b = &fr.planes[i];
                    if (!(fabs(a->a - b->a) < 1e-5 && fabs(a->b - b->b) < 1e-5 && fabs(a->c - b->c) < 1e-5 &&
                          rel(a->d, b->d) < (i == 5 ? 1e-2 : 1e-5)))
                        fail_msg("camera %d, %s, flags %u: plane %d (%g %g %g %g) vs (%g %g %g %g)", k,
                                 sl_clip_depth_name((sl_clip_depth)d), fl, i, a->a, a->b, a->c, a->d, b->a, b->b, b->c,
                                 b->d);
                }
                for (int i = 0; i < 4; i++)
                    assert_true(rel(v.frustum.corners[i].x, fr.corners[i].x) < 1e-5 &&
                                rel(v.frustum.corners[i].y, fr.corners[i].y) < 1e-5 &&
                                rel(v.frustum.corners[i].z, fr.corners[i].z) < 1e-5);
                /* x, y and w rows of the world-to-clip map: the camera's (the depth row differs with
                 * an infinite far plane) */
                for (int col = 0; col < 4; col++)
                    for (int row = 0; row < 4; row++)
                        if (row != 2 || !inf)
                            assert_true(fabs(v.view_proj.m[4 * col + row] - cvp.m[4 * col + row]) <
                                        2e-3 * (1 + fabs(cvp.m[4 * col + row])));
                /* the oracle's image of the normal form is the camera's */
                sl_oracle_frame f1;
                assert_int_equal(sl_oracle_render_view(o, &v, &f1, &err), SL_OK);
                assert_int_equal(sl_oracle_get_view(o, 0, &ov, &err), SL_OK);
                size_t same = 0;
                for (size_t i = 0; i < px; i++)
                    same += ov.ids[i] == ref[i];
                if (same < px - px / 500)
                    fail_msg("camera %d, %s, flags %u: %zu of %zu pixels as the camera's", k,
                             sl_clip_depth_name((sl_clip_depth)d), fl, same, px);
            }
    }
    free(ref);
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

/* Everything that is not a rigid view and a perspective or orthographic projection is refused,
 * naming the element and the reason. */
static void test_refusals(void **state)
{
    (void)state;
    sl_error err;
    sl_camera c = test_camera(1), oc = test_camera(3);
    float V0[16], P0[16], OV[16], OP[16];
    sl_tvm_matrices(&c, SL_CLIP_DEPTH_GL, 0, NULL, V0, P0);
    sl_tvm_matrices(&oc, SL_CLIP_DEPTH_GL, 0, NULL, OV, OP);
    struct {
        bool ortho;
        int matrix, index; /* 0 view, 1 projection; -1: nothing changed */
        float value;       /* the element's new value (NAN: not finite); scale: multiply instead */
        bool scale;
        sl_clip_depth depth;
        uint32_t width;
        const char *want;
    } cases[] = {
        {false, 0, 0, 2.0f, true, SL_CLIP_DEPTH_GL, 320, "dot product"},         /* scaled */
        {false, 0, 4, 0.25f, false, SL_CLIP_DEPTH_GL, 320, "rigid"},             /* skewed */
        {false, 0, 3, 0.5f, false, SL_CLIP_DEPTH_GL, 320, "row 3, column 0"},    /* projective view */
        {false, 0, 13, NAN, false, SL_CLIP_DEPTH_GL, 320, "not finite"},
        {false, 1, 5, INFINITY, false, SL_CLIP_DEPTH_GL, 320, "row 1, column 1"},
        {false, 1, 4, 0.3f, false, SL_CLIP_DEPTH_GL, 320, "skew"},
        {false, 1, 2, 0.2f, false, SL_CLIP_DEPTH_GL, 320, "oblique"},
        {false, 1, 12, 0.5f, false, SL_CLIP_DEPTH_GL, 320, "shear"},
        {true, 1, 8, 0.5f, false, SL_CLIP_DEPTH_GL, 320, "shear"},
        {false, 1, 15, 0.5f, false, SL_CLIP_DEPTH_GL, 320, "neither perspective"},
        {false, 1, 0, 0.0f, false, SL_CLIP_DEPTH_GL, 320, "zero scale"},
        {false, 1, 0, 0.0f, true, SL_CLIP_DEPTH_GL, 320, "zero scale"},
        {false, 1, 14, -1.0f, true, SL_CLIP_DEPTH_GL, 320, "near plane"},        /* near < 0 */
        {false, -1, 0, 0, false, SL_CLIP_DEPTH_REVERSED, 320, "far plane"},      /* GL read as reversed */
        {false, 1, 10, 1.0f, false, SL_CLIP_DEPTH_GL, 320, "near plane"},        /* far = near ... */
        {true, 1, 14, 3.0f, false, SL_CLIP_DEPTH_GL, 320, "near plane"},         /* ortho near < 0 */
        {true, 1, 10, 0.0f, false, SL_CLIP_DEPTH_GL, 320, "singular"},
        {false, -1, 0, 0, false, SL_CLIP_DEPTH_GL, 0, "viewport"},
        {false, -1, 0, 0, false, (sl_clip_depth)7, 320, "depth convention"},
    };
    for (size_t i = 0; i < SL_COUNTOF(cases); i++) {
        float V[16], P[16];
        memcpy(V, cases[i].ortho ? OV : V0, sizeof V);
        memcpy(P, cases[i].ortho ? OP : P0, sizeof P);
        if (cases[i].matrix >= 0) {
            float *m = cases[i].matrix ? P : V;
            m[cases[i].index] = cases[i].scale ? m[cases[i].index] * cases[i].value : cases[i].value;
        }
        sl_view v;
        memset(&err, 0, sizeof err);
        if (sl_view_from_matrices(V, P, cases[i].depth, cases[i].width, 240, &v, &err) != SL_ERROR_INVALID_ARGUMENT)
            fail_msg("case %zu accepted", i);
        if (!strstr(err.message, cases[i].want))
            fail_msg("case %zu: '%s' does not say '%s'", i, err.message, cases[i].want);
    }
    /* within the tolerance: accepted (a float-rounded rotation) */
    float V[16];
    memcpy(V, V0, sizeof V);
    V[0] *= 1.000001f;
    sl_view v;
    assert_int_equal(sl_view_from_matrices(V, P0, SL_CLIP_DEPTH_GL, 320, 240, &v, &err), SL_OK);
    /* a view no constructor made */
    sl_view hand;
    memset(&hand, 0, sizeof hand);
    assert_int_equal(sl_view_validate(&hand, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "constructor"));
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    sl_test_add_box(s, (sl_vec3){0, 0, 0}, (sl_vec3){1, 1, 1}, SL_KIND_BUILDING, 0);
    sl_culler cu;
    assert_int_equal(sl_culler_create("vfc", s, NULL, NULL, &cu, &err), SL_OK);
    uint32_t ids[1], k;
    assert_int_equal(sl_culler_cull_view(cu, &hand, ids, 1, &k, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "constructor"));
    sl_culler_destroy(cu);
    sl_scene_destroy(s);
}

/* An infinite far plane (reversed-z, the engine case): bounded by the world with the same sets;
 * refused by a CLIP_Z depth check until bounded. */
static void test_infinite_far(void **state)
{
    (void)state;
    sl_error err;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    sl_aabb world = sl_scene_bounds(s);
    sl_camera c = sl_camera_default();
    c.width = 200, c.height = 150;
    c.position = (sl_vec3){-30, -20, 2};
    c.yaw = 0.6f;
    float V[16], P[16];
    sl_tvm_matrices(&c, SL_CLIP_DEPTH_REVERSED, SL_TVM_INF | SL_TVM_LH_Z, NULL, V, P);
    sl_view v, b, b2;
    assert_int_equal(sl_view_from_matrices(V, P, SL_CLIP_DEPTH_REVERSED, c.width, c.height, &v, &err), SL_OK);
    assert_true(isinf(v.far_plane));
    assert_true(isinf(sl_view_min_near(&v, SL_DEPTH_CLIP_Z)));
    assert_int_equal(sl_view_check_depth(&v, SL_DEPTH_CLIP_Z, "the oracle", &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "finite far plane"));
    assert_int_equal(sl_view_check_depth(&v, SL_DEPTH_INV_W, "hzb", &err), SL_OK);
    assert_int_equal(sl_view_bound_far(&v, &world, &b, &err), SL_OK);
    assert_true(isfinite(b.far_plane) && b.far_plane > b.near_plane);
    /* beyond every corner of the world box */
    for (int i = 0; i < 8; i++) {
        sl_vec3 q = {i & 1 ? world.max.x : world.min.x, i & 2 ? world.max.y : world.min.y,
                     i & 4 ? world.max.z : world.min.z};
        double dx = q.x - v.eye.x, dy = q.y - v.eye.y, dz = q.z - v.eye.z;
        assert_true(b.far_plane > sqrt(dx * dx + dy * dy + dz * dz));
    }
    assert_int_equal(sl_view_check_depth(&b, SL_DEPTH_CLIP_Z, "the oracle", &err), SL_OK);
    /* a far plane already nearer: unchanged */
    assert_int_equal(sl_view_with_far(&v, 50.0, &b2, &err), SL_OK);
    sl_view b3;
    assert_int_equal(sl_view_bound_far(&b2, &world, &b3, &err), SL_OK);
    assert_true(b3.far_plane == b2.far_plane);
    assert_memory_equal(&b2.view_proj, &b3.view_proj, sizeof b2.view_proj);
    assert_memory_equal(&b2.frustum, &b3.frustum, sizeof b2.frustum);
    assert_int_equal(sl_view_with_far(&v, 0.05, &b2, &err), SL_ERROR_INVALID_ARGUMENT);
    /* the cullers bound it themselves: the same ids as for the bounded view */
    uint32_t n = sl_scene_object_count(s), *o1 = malloc(n * sizeof *o1), *o2 = malloc(n * sizeof *o2);
    uint32_t mc = sl_cull_method_count();
    for (uint32_t m = 0; m < mc; m++) {
        sl_cull_method_desc md;
        assert_int_equal(sl_cull_method_info(m, &md, &err), SL_OK);
        sl_culler cu;
        if (sl_culler_create(md.name, s, NULL, NULL, &cu, &err) != SL_OK)
            continue; /* pvs: needs a file */
        uint32_t k1, k2;
        if (sl_culler_cull_view(cu, &v, o1, n, &k1, &err) != SL_OK)
            fail_msg("%s: %s", md.name, err.message);
        assert_int_equal(sl_culler_cull_view(cu, &b, o2, n, &k2, &err), SL_OK);
        assert_int_equal(k1, k2);
        assert_memory_equal(o1, o2, k1 * sizeof *o1);
        sl_culler_destroy(cu);
    }
    free(o1);
    free(o2);
    /* the oracle bounds it too: the bounded view's image and set */
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    sl_oracle_frame fi, fb;
    assert_int_equal(sl_oracle_render_view(o, &v, &fi, &err), SL_OK);
    size_t px = (size_t)c.width * c.height;
    uint32_t *img = malloc(px * sizeof *img), *set = malloc((fi.visible_count + 1) * sizeof *set), vc = fi.visible_count;
    sl_oracle_view ov;
    assert_int_equal(sl_oracle_get_view(o, 0, &ov, &err), SL_OK);
    memcpy(img, ov.ids, px * sizeof *img);
    memcpy(set, fi.visible, vc * sizeof *set);
    assert_true(vc > 0);
    assert_int_equal(sl_oracle_render_view(o, &b, &fb, &err), SL_OK);
    assert_int_equal(sl_oracle_get_view(o, 0, &ov, &err), SL_OK);
    assert_memory_equal(img, ov.ids, px * sizeof *img);
    assert_int_equal(fb.visible_count, vc);
    assert_memory_equal(set, fb.visible, vc * sizeof *set);
    sl_view hand;
    memset(&hand, 0, sizeof hand);
    assert_int_equal(sl_oracle_render_view(o, &hand, &fb, &err), SL_ERROR_INVALID_ARGUMENT);
    free(img);
    free(set);
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

/* The normal form keeps the winding of an unmirrored OpenGL view: a box inside a closed convex box
 * (whose back faces are skipped) stays hidden for every convention, handedness and mirror. */
static void test_closed_mesh_winding(void **state)
{
    (void)state;
    sl_error err;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, &err), SL_OK);
    uint32_t outer = sl_test_add_box(s, (sl_vec3){-2, -2, 0}, (sl_vec3){2, 2, 4}, SL_KIND_BUILDING,
                                     SL_OBJECT_CLOSED_CONVEX);
    uint32_t inner = sl_test_add_box(s, (sl_vec3){-1, -1, 1}, (sl_vec3){1, 1, 3}, SL_KIND_OTHER, 0);
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    static const unsigned flag_sets[] = {0, SL_TVM_LH_Z, SL_TVM_LH_X, SL_TVM_FLIP_X, SL_TVM_FLIP_Y,
                                         SL_TVM_FLIP_X | SL_TVM_FLIP_Y, SL_TVM_LH_Z | SL_TVM_FLIP_Y,
                                         SL_TVM_INF | SL_TVM_LH_X | SL_TVM_FLIP_X};
    for (int proj = 0; proj < 2; proj++) {
        sl_camera c = sl_camera_default();
        c.width = 64, c.height = 48;
        c.position = (sl_vec3){-12, -3, 2};
        if (proj) {
            c.projection = SL_ORTHOGRAPHIC;
            c.ortho_height = 10;
        }
        sl_camera_look_at(&c, (sl_vec3){0, 0, 2});
        for (int d = 0; d < 3; d++)
            for (size_t q = 0; q < SL_COUNTOF(flag_sets); q++) {
                if (proj && (flag_sets[q] & SL_TVM_INF))
                    continue;
                float V[16], P[16];
                sl_tvm_shape sh = {1, 0.2, 1, -0.1}; /* off-axis too */
                sl_tvm_matrices(&c, (sl_clip_depth)d, flag_sets[q], &sh, V, P);
                sl_view v;
                assert_int_equal(sl_view_from_matrices(V, P, (sl_clip_depth)d, c.width, c.height, &v, &err), SL_OK);
                sl_oracle_frame f;
                assert_int_equal(sl_oracle_render_view(o, &v, &f, &err), SL_OK);
                bool saw_outer = false, saw_inner = false;
                for (uint32_t i = 0; i < f.visible_count; i++) {
                    saw_outer |= f.visible[i] == outer;
                    saw_inner |= f.visible[i] == inner;
                }
                if (!saw_outer || saw_inner)
                    fail_msg("%s, %s, flags %u: outer %s, inner %s", proj ? "ortho" : "perspective",
                             sl_clip_depth_name((sl_clip_depth)d), flag_sets[q], saw_outer ? "seen" : "hidden",
                             saw_inner ? "seen (back faces drawn)" : "hidden");
            }
    }
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

/* ---- off-axis, reversed-z and infinite-far views against the oracle ---- */

static const struct {
    const char *name, *options;
} g_methods[] = {
    {"vfc", NULL},       {"cullmap", NULL},          {"horizon", NULL},  {"dhorizon", NULL},
    {"hzb", NULL},       {"hzb", "res=culling"},     {"lazygrid", NULL}, {"lazygrid", "res=culling"},
    {"lazygrid-z", NULL}, {"busygrid", NULL},        {"hom", NULL},      {"hom", "res=culling"},
    {"frusta", NULL},    {"frusta", "all_objects=true"}, {"cplp", NULL}, {"gl-stopwait", NULL},
    {"pvs", NULL}, /* options: the file of a bake (maps only; skipped without) */
};
#define NM SL_COUNTOF(g_methods)

/* The engine views made of one camera: a stereo eye, a tile of a 3x3 screen, reversed-z with an
 * infinite far plane in a left-handed eye space with a y-down image, [0, 1] depth with a Vulkan
 * image, all off-axis. */
#define NVARIANTS 4
static void variant(const sl_camera *c, uint32_t f, int which, float V[16], float P[16], sl_clip_depth *d)
{
    sl_tvm_shape sh = {1, 0, 1, 0};
    unsigned fl = 0;
    switch (which) {
    case 0: /* a stereo eye: the image shifted by a quarter of its width */
        sh.ox = f % 2 ? 0.25 : -0.25;
        *d = SL_CLIP_DEPTH_GL;
        break;
    case 1: { /* tile (i, j) of a 3x3 screen whose whole is the camera's image */
        int i = (int)(f % 3), j = (int)((f / 3) % 3);
        sh.kx = sh.ky = 3;
        sh.ox = 2 - 2 * i;
        sh.oy = 2 - 2 * j;
        *d = SL_CLIP_DEPTH_ZERO_ONE;
        break;
    }
    case 2: /* reversed-z, infinite far, Direct3D eye space, Vulkan image, shifted */
        sh.ox = 0.4, sh.oy = -0.3;
        fl = SL_TVM_LH_Z | SL_TVM_FLIP_Y | (c->projection == SL_PERSPECTIVE ? SL_TVM_INF : 0);
        *d = SL_CLIP_DEPTH_REVERSED;
        break;
    default: /* [0, 1] depth, mirrored x, shifted up, wider */
        sh.kx = 0.8, sh.oy = 0.5;
        fl = SL_TVM_FLIP_X | SL_TVM_LH_X;
        *d = SL_CLIP_DEPTH_ZERO_ONE;
        break;
    }
    sl_tvm_matrices(c, *d, fl, &sh, V, P);
}

typedef struct tally {
    uint64_t frames, missed_frames, missed_objects;
} tally;

/* Cull every variant of every camera with every method, judged by the oracle of the same view at
 * the culling resolution and (methods promising SL_CONSERVATIVE: any resolution) at twice it, with
 * MSAA 4x sample positions. Returns the view-method pairs with a miss. */
static uint64_t run_views(sl_scene s, const char *label, const sl_camera *cams, uint32_t nc, const char *pvs_options,
                          tally *t)
{
    sl_error err;
    sl_culler c[NM];
    bool ok[NM];
    for (size_t i = 0; i < NM; i++) {
        bool pvs = !strcmp(g_methods[i].name, "pvs");
        ok[i] = (!pvs || pvs_options) &&
                sl_culler_create(g_methods[i].name, s, pvs ? pvs_options : g_methods[i].options, NULL, &c[i], &err) ==
                    SL_OK;
        if (pvs && !pvs_options)
            continue;
        if (!ok[i])
            print_message("%s: %s not run: %s\n", label, g_methods[i].name, err.message);
        else
            assert_true(sl_cull_guarantee_keeps_visible(sl_culler_guarantee(c[i]), true));
    }
    sl_oracle o, o2;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    sl_oracle_options oo = sl_oracle_default_options();
    oo.width = 2 * cams[0].width;
    oo.height = 2 * cams[0].height;
    oo.samples = SL_ORACLE_SAMPLES_MSAA4;
    assert_int_equal(sl_oracle_create(s, &oo, NULL, &o2, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), *out = malloc((n ? n : 1) * sizeof *out), missed[4], mpx[4];
    uint64_t bad = 0;
    for (uint32_t f = 0; f < nc; f++)
        for (int w = 0; w < NVARIANTS; w++) {
            float V[16], P[16];
            sl_clip_depth d;
            variant(&cams[f], f, w, V, P, &d);
            sl_view v;
            if (sl_view_from_matrices(V, P, d, cams[f].width, cams[f].height, &v, &err) != SL_OK)
                fail_msg("%s view %u variant %d: %s", label, f, w, err.message);
            sl_oracle_frame fr, fr2;
            assert_int_equal(sl_oracle_render_view(o, &v, &fr, &err), SL_OK);
            if (fr.out_of_domain)
                continue;
            bool hi = (f + (uint32_t)w) % 3 == 0; /* a third of the views also at 2x, MSAA 4x */
            if (hi)
                assert_int_equal(sl_oracle_render_view(o2, &v, &fr2, &err), SL_OK);
            for (size_t i = 0; i < NM; i++) {
                if (!ok[i])
                    continue;
                uint32_t k;
                if (sl_culler_cull_view(c[i], &v, out, n, &k, &err) != SL_OK)
                    fail_msg("%s %s view %u variant %d: %s", label, g_methods[i].name, f, w, err.message);
                sl_cull_metrics mt;
                assert_int_equal(sl_metrics_compare(s, &fr, out, k, &mt, missed, mpx, 4, &err), SL_OK);
                if (hi && sl_culler_guarantee(c[i]) == SL_CONSERVATIVE && !mt.missed_count)
                    assert_int_equal(sl_metrics_compare(s, &fr2, out, k, &mt, missed, mpx, 4, &err), SL_OK);
                t[i].frames++;
                if (mt.missed_count) {
                    bad++;
                    t[i].missed_frames++;
                    t[i].missed_objects += mt.missed_count;
                    print_message("%s: %s%s%s view %u variant %d missed %u objects (first %u, %u pixels); eye (%.4f, "
                                  "%.4f, %.4f) yaw %.5f pitch %.5f roll %.5f\n",
                                  label, g_methods[i].name, g_methods[i].options ? " " : "",
                                  g_methods[i].options ? g_methods[i].options : "", f, w, mt.missed_count, missed[0],
                                  mpx[0], (double)cams[f].position.x, (double)cams[f].position.y,
                                  (double)cams[f].position.z, (double)cams[f].yaw, (double)cams[f].pitch,
                                  (double)cams[f].roll);
                }
            }
        }
    free(out);
    sl_oracle_destroy(o);
    sl_oracle_destroy(o2);
    for (size_t i = 0; i < NM; i++)
        if (ok[i])
            sl_culler_destroy(c[i]);
    return bad;
}

/* Near-wall cameras (bench/near_wall_views.h) of s. */
static sl_camera *near_wall_cameras(sl_scene s, uint32_t count, uint64_t seed, uint32_t w, uint32_t h)
{
    nw_table tb;
    assert_true(nw_table_build(s, &tb));
    sl_camera in = sl_camera_default(), *cams = malloc(count * sizeof *cams);
    in.width = w;
    in.height = h;
    nw_rng r = {seed};
    for (uint32_t f = 0; f < count; f++)
        assert_true(nw_view(s, &tb, &r, &in, 0.001, 0.2, &cams[f]) >= 0);
    nw_table_free(&tb);
    return cams;
}

static void test_off_axis_against_oracle(void **state)
{
    (void)state;
    sl_error err;
    tally t[NM];
    memset(t, 0, sizeof t);
    uint64_t bad = 0;
    const uint32_t W = 192, H = 144;
    {
        sl_city_options co = sl_city_defaults(SL_CITY_TINY);
        sl_scene s;
        assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
        uint32_t nv = sanitized() ? 4 : 40;
        sl_path_options po = sl_path_options_default(SL_PATH_WALK);
        po.intrinsics.width = W;
        po.intrinsics.height = H;
        sl_path p;
        assert_int_equal(sl_path_random_views(s, SL_VIEWS_STREET, nv, 77, &po, NULL, &p, &err), SL_OK);
        sl_camera *cams = malloc(3 * nv * sizeof *cams);
        for (uint32_t f = 0; f < nv; f++)
            cams[f] = sl_path_camera(p, f);
        sl_path_destroy(p);
        /* orthographic views from above (light views) */
        assert_int_equal(sl_path_random_views(s, SL_VIEWS_FLYOVER, nv, 78, &po, NULL, &p, &err), SL_OK);
        for (uint32_t f = 0; f < nv; f++) {
            cams[nv + f] = sl_path_camera(p, f);
            cams[nv + f].projection = SL_ORTHOGRAPHIC;
            cams[nv + f].ortho_height = 60.0f;
        }
        sl_path_destroy(p);
        sl_camera *nw = near_wall_cameras(s, nv, 79, W, H);
        memcpy(cams + 2 * nv, nw, nv * sizeof *cams);
        free(nw);
        bad += run_views(s, "tiny city", cams, 3 * nv, NULL, t);
        free(cams);
        sl_scene_destroy(s);
    }
    if (access(OA_PK3, R_OK) != 0) {
        print_message("maps skipped: %s is not installed (Debian package openarena-081-maps)\n", OA_PK3);
    } else {
        static const char *const maps[] = {"aggressor", "oa_dm1"};
        uint32_t per_map = sanitized() ? 4 : 30;
        for (size_t m = 0; m < (sanitized() ? 1u : SL_COUNTOF(maps)); m++) {
            sl_scene s;
            if (sl_import_q3bsp(OA_PK3, maps[m], NULL, NULL, &s, &err) != SL_OK)
                fail_msg("%s", err.message);
            sl_camera *cams = near_wall_cameras(s, per_map, 90 + m, W, H);
            /* the pvs culler of a quick portal bake (budget=2: short walks, still conservative; not
             * under the sanitizers, where the bake is slow) */
            if (sanitized()) {
                bad += run_views(s, maps[m], cams, per_map, NULL, t);
                free(cams);
                sl_scene_destroy(s);
                continue;
            }
            sl_viewcells vc;
            assert_int_equal(sl_viewcells_from_bsp(s, NULL, &vc, &err), SL_OK);
            char file[96], popts[128];
            snprintf(file, sizeof file, "/tmp/sl_test_view_%ld_%s.slpvs", (long)getpid(), maps[m]);
            sl_pvs_build_options bo;
            memset(&bo, 0, sizeof bo);
            bo.method = "portal";
            bo.method_options = "budget=2";
            bo.threads = 2;
            if (sl_pvs_build(s, vc, file, &bo, NULL, &err) != SL_OK)
                fail_msg("%s: portal bake: %s", maps[m], err.message);
            sl_viewcells_destroy(vc);
            snprintf(popts, sizeof popts, "file=%s", file);
            bad += run_views(s, maps[m], cams, per_map, popts, t);
            unlink(file);
            free(cams);
            sl_scene_destroy(s);
        }
    }
    for (size_t i = 0; i < NM; i++)
        print_message("off-axis %-10s %-18s %llu views, %llu with misses, %llu objects missed\n", g_methods[i].name,
                      g_methods[i].options ? g_methods[i].options : "", (unsigned long long)t[i].frames,
                      (unsigned long long)t[i].missed_frames, (unsigned long long)t[i].missed_objects);
    assert_int_equal(bad, 0);
}

/* The check above catches a method that ignores the off-axis shift: vfc culling with the
 * symmetric frustum of the same camera (what a method deriving its frustum from a field of view
 * would use) misses objects of the shifted view's oracle image. */
static void test_symmetric_frustum_misses(void **state)
{
    (void)state;
    sl_error err;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    sl_path_options po = sl_path_options_default(SL_PATH_WALK);
    po.intrinsics.width = 160;
    po.intrinsics.height = 120;
    sl_path p;
    uint32_t nv = 10;
    assert_int_equal(sl_path_random_views(s, SL_VIEWS_STREET, nv, 5, &po, NULL, &p, &err), SL_OK);
    sl_oracle o;
    assert_int_equal(sl_oracle_create(s, NULL, NULL, &o, &err), SL_OK);
    sl_culler c;
    assert_int_equal(sl_culler_create("vfc", s, NULL, NULL, &c, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), *out = malloc(n * sizeof *out), k;
    uint64_t missed_sym = 0, missed_true = 0;
    for (uint32_t f = 0; f < nv; f++) {
        sl_camera cam = sl_path_camera(p, f);
        float V[16], P[16], Ps[16];
        sl_tvm_shape sh = {1, 0.6, 1, 0};
        sl_tvm_matrices(&cam, SL_CLIP_DEPTH_GL, 0, &sh, V, P);
        sl_tvm_matrices(&cam, SL_CLIP_DEPTH_GL, 0, NULL, V, Ps);
        sl_view v, sym;
        assert_int_equal(sl_view_from_matrices(V, P, SL_CLIP_DEPTH_GL, cam.width, cam.height, &v, &err), SL_OK);
        assert_int_equal(sl_view_from_matrices(V, Ps, SL_CLIP_DEPTH_GL, cam.width, cam.height, &sym, &err), SL_OK);
        sl_oracle_frame fr;
        assert_int_equal(sl_oracle_render_view(o, &v, &fr, &err), SL_OK);
        sl_cull_metrics mt;
        assert_int_equal(sl_culler_cull_view(c, &sym, out, n, &k, &err), SL_OK);
        assert_int_equal(sl_metrics_compare(s, &fr, out, k, &mt, NULL, NULL, 0, &err), SL_OK);
        missed_sym += mt.missed_count;
        assert_int_equal(sl_culler_cull_view(c, &v, out, n, &k, &err), SL_OK);
        assert_int_equal(sl_metrics_compare(s, &fr, out, k, &mt, NULL, NULL, 0, &err), SL_OK);
        missed_true += mt.missed_count;
    }
    print_message("symmetric frustum for a shifted view: %llu objects missed over %u views (the view's own: %llu)\n",
                  (unsigned long long)missed_sym, nv, (unsigned long long)missed_true);
    assert_true(missed_sym > 0);
    assert_int_equal(missed_true, 0);
    free(out);
    sl_culler_destroy(c);
    sl_oracle_destroy(o);
    sl_path_destroy(p);
    sl_scene_destroy(s);
}

/* What an off-axis view derives, checked against its own matrix: the frustum's near corners land on
 * the NDC corners, the near-corner distance is the farthest of them, the focal lengths are the
 * per-axis pixel scales. */
static void test_off_axis_derived(void **state)
{
    (void)state;
    sl_error err;
    const sl_tvm_shape shapes[] = {{1, 0.5, 1, 0}, {3, 2, 3, -2}, {0.7, -0.3, 1.6, 0.9}, {1, 0, 1, 0}};
    for (int k = 0; k < 6; k++)
        for (size_t q = 0; q < SL_COUNTOF(shapes); q++)
            for (int d = 0; d < 3; d++) {
                sl_camera c = test_camera(k);
                float V[16], P[16];
                sl_tvm_matrices(&c, (sl_clip_depth)d, q % 2 ? SL_TVM_FLIP_Y | SL_TVM_LH_Z : 0, &shapes[q], V, P);
                sl_view v;
                assert_int_equal(sl_view_from_matrices(V, P, (sl_clip_depth)d, c.width, c.height, &v, &err), SL_OK);
                const double ndc[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}; /* bl br tr tl */
                double far_corner = 0;
                for (int i = 0; i < 4; i++) {
                    const sl_vec3 *p = &v.frustum.corners[i];
                    const float *m = v.view_proj.m;
                    double cl[4];
                    for (int r = 0; r < 4; r++)
                        cl[r] = m[r] * p->x + m[4 + r] * p->y + m[8 + r] * p->z + m[12 + r];
                    if (!(fabs(cl[0] / cl[3] - ndc[i][0]) < 1e-3 && fabs(cl[1] / cl[3] - ndc[i][1]) < 1e-3 &&
                          fabs(cl[2] / cl[3] + 1) < 1e-2))
                        fail_msg("camera %d shape %zu %s: near corner %d at NDC (%g, %g, %g)", k, q,
                                 sl_clip_depth_name((sl_clip_depth)d), i, cl[0] / cl[3], cl[1] / cl[3], cl[2] / cl[3]);
                    double dx = p->x - v.eye.x, dy = p->y - v.eye.y, dz = p->z - v.eye.z;
                    far_corner = fmax(far_corner, sqrt(dx * dx + dy * dy + dz * dz));
                }
                if (v.projection == SL_PERSPECTIVE)
                    assert_true(fabs(v.near_corner_dist - far_corner) < 1e-5 * (1 + far_corner));
                else
                    assert_true(v.near_corner_dist == 0);
                /* focal: pixels per metre of eye x (y) at unit depth: P00 W / 2 of the shaped image */
                double fx = shapes[q].kx * c.width / 2.0, fy = shapes[q].ky * c.height / 2.0;
                if (c.projection == SL_PERSPECTIVE) {
                    double t = 1.0 / tan(0.5 * (double)c.fov_y), a = (double)c.width / c.height;
                    fx *= t / a, fy *= t;
                } else {
                    fx *= 2.0 / (c.ortho_height * (double)c.width / c.height), fy *= 2.0 / c.ortho_height;
                }
                assert_true(fabs(v.focal_x - fx) < 1e-5 * fx && fabs(v.focal_y - fy) < 1e-5 * fy);
            }
}

/* Random engine matrices, many of them broken on purpose (entries changed by small and large
 * amounts, zeroed, not finite): sl_view_from_matrices refuses each with a message or gives a view
 * that keeps the normal form (rigid right-handed view, positive scales, OpenGL depth, 0 < near <
 * far, finite normalised planes, a finite bounded far plane and pixel rays), and the cullers take
 * every view it gives (the wrapper's own checks of the output pass). Seeded. */
static void test_random_matrices(void **state)
{
    (void)state;
    sl_error err;
    sl_city_options co = sl_city_defaults(SL_CITY_TINY);
    sl_scene s;
    assert_int_equal(sl_gen_city(&co, NULL, &s, &err), SL_OK);
    sl_culler cv, ch;
    assert_int_equal(sl_culler_create("vfc", s, NULL, NULL, &cv, &err), SL_OK);
    assert_int_equal(sl_culler_create("hzb", s, NULL, NULL, &ch, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s), *out = malloc(n * sizeof *out), k;
    nw_rng r = {20261202};
    uint32_t cases = sanitized() ? 3000 : 30000, accepted = 0, culled = 0;
    for (uint32_t i = 0; i < cases; i++) {
        sl_camera c = sl_camera_default();
        c.position = (sl_vec3){(float)(200 * nw_unit(&r) - 100), (float)(200 * nw_unit(&r) - 100),
                               (float)(30 * nw_unit(&r))};
        c.yaw = (float)(7 * nw_unit(&r)), c.pitch = (float)(3 * nw_unit(&r) - 1.5), c.roll = (float)(7 * nw_unit(&r));
        c.width = 32 + (uint32_t)(nw_next(&r) % 200), c.height = 32 + (uint32_t)(nw_next(&r) % 200);
        c.fov_y = (float)(0.1 + 2.9 * nw_unit(&r));
        if (nw_next(&r) % 4 == 0) {
            c.projection = SL_ORTHOGRAPHIC;
            c.ortho_height = (float)(1 + 100 * nw_unit(&r));
        }
        c.near_plane = (float)(0.01 + 2 * nw_unit(&r));
        c.far_plane = c.near_plane * (float)(2 + 1e4 * nw_unit(&r));
        sl_clip_depth d = (sl_clip_depth)(nw_next(&r) % 3);
        unsigned fl = (unsigned)(nw_next(&r) % 32);
        sl_tvm_shape sh = {0.2 + 3 * nw_unit(&r), 4 * nw_unit(&r) - 2, 0.2 + 3 * nw_unit(&r), 4 * nw_unit(&r) - 2};
        float V[16], P[16];
        sl_tvm_matrices(&c, d, fl, &sh, V, P);
        int breaks = (int)(nw_next(&r) % 4);
        for (int b = 0; b < breaks; b++) {
            float *m = nw_next(&r) % 2 ? V : P;
            int e = (int)(nw_next(&r) % 16);
            switch (nw_next(&r) % 6) {
            case 0: m[e] += (float)(1e-6 * (nw_unit(&r) - 0.5)); break;
            case 1: m[e] += (float)(nw_unit(&r) - 0.5); break;
            case 2: m[e] = 0; break;
            case 3: m[e] = -m[e]; break;
            case 4: m[e] = nw_next(&r) % 2 ? NAN : INFINITY; break;
            default: m[e] *= (float)(1e6 * nw_unit(&r)); break;
            }
        }
        sl_view v;
        memset(&err, 0, sizeof err);
        sl_status st = sl_view_from_matrices(V, P, d, c.width, c.height, &v, &err);
        if (st != SL_OK) {
            assert_int_equal(st, SL_ERROR_INVALID_ARGUMENT);
            assert_non_null(strstr(err.message, "sl_view_from_matrices"));
            continue;
        }
        accepted++;
        assert_true(v.near_plane > 0 && v.far_plane > v.near_plane && isfinite(v.near_plane));
        assert_true(v.proj.m[0] > 0 && v.proj.m[5] > 0);
        assert_true(v.projection == SL_ORTHOGRAPHIC ? v.proj.m[11] == 0 && v.proj.m[15] == 1
                                                    : v.proj.m[11] == -1 && v.proj.m[15] == 0);
        double det = 0;
        {
            const float *m = v.view.m;
            det = m[0] * (m[5] * m[10] - m[9] * m[6]) - m[4] * (m[1] * m[10] - m[9] * m[2]) +
                  m[8] * (m[1] * m[6] - m[5] * m[2]);
        }
        assert_true(fabs(det - 1) < 1e-4);
        assert_true(isfinite(v.eye.x) && isfinite(v.eye.y) && isfinite(v.eye.z));
        for (int q = 0; q < (isinf(v.far_plane) ? 5 : 6); q++) {
            const sl_plane *p = &v.frustum.planes[q];
            assert_true(isfinite(p->a) && isfinite(p->b) && isfinite(p->c) && isfinite(p->d));
            assert_true(fabs(sqrt((double)p->a * p->a + (double)p->b * p->b + (double)p->c * p->c) - 1) < 1e-4);
        }
        sl_view bounded;
        sl_aabb world = sl_scene_bounds(s);
        assert_int_equal(sl_view_bound_far(&v, &world, &bounded, &err), SL_OK);
        assert_true(isfinite(bounded.far_plane));
        double org[3], dir[3];
        sl_view_pixel_ray(&v, 0.5, 0.5, org, dir);
        assert_true(isfinite(org[0]) && isfinite(dir[0]) && isfinite(dir[2]));
        /* the cullers: either the depth check refuses it (naming the near plane) or they cull */
        if (i % 8 == 0) {
            for (int m = 0; m < 2; m++) {
                st = sl_culler_cull_view(m ? ch : cv, &v, out, n, &k, &err);
                if (st != SL_OK) {
                    assert_int_equal(st, SL_ERROR_INVALID_ARGUMENT);
                    assert_non_null(strstr(err.message, "near plane"));
                } else {
                    culled++;
                }
            }
        }
    }
    print_message("random matrices: %u of %u accepted, %u culls\n", accepted, cases, culled);
    assert_true(accepted > cases / 8 && accepted < cases);
    free(out);
    sl_culler_destroy(cv);
    sl_culler_destroy(ch);
    sl_scene_destroy(s);
}

/* Viewports and names. */
static void test_viewport_and_names(void **state)
{
    (void)state;
    sl_error err;
    sl_camera c = test_camera(0);
    sl_view v, w, ref;
    assert_int_equal(sl_view_from_camera(&c, &v, &err), SL_OK);
    assert_int_equal(sl_view_with_viewport(&v, 640, 200, &w, &err), SL_OK);
    c.width = 640, c.height = 200;
    assert_int_equal(sl_view_from_camera(&c, &ref, &err), SL_OK);
    assert_memory_equal(&w.view_proj, &ref.view_proj, sizeof w.view_proj);
    assert_memory_equal(&w.frustum, &ref.frustum, sizeof w.frustum);
    assert_true(w.width == 640 && w.height == 200 && w.focal_y == ref.focal_y);
    float V[16], P[16];
    sl_tvm_matrices(&c, SL_CLIP_DEPTH_GL, 0, NULL, V, P);
    assert_int_equal(sl_view_from_matrices(V, P, SL_CLIP_DEPTH_GL, 640, 200, &v, &err), SL_OK);
    assert_int_equal(sl_view_with_viewport(&v, 64, 20, &w, &err), SL_OK);
    assert_memory_equal(&w.view_proj, &v.view_proj, sizeof v.view_proj); /* matrices kept */
    assert_true(fabs(w.focal_y - v.focal_y / 10) < 1e-9 * v.focal_y);
    assert_int_equal(sl_view_with_viewport(&v, 0, 20, &w, &err), SL_ERROR_INVALID_ARGUMENT);
    for (int d = 0; d < 3; d++) {
        sl_clip_depth back;
        assert_true(sl_clip_depth_parse(sl_clip_depth_name((sl_clip_depth)d), &back));
        assert_int_equal(back, d);
    }
    assert_false(sl_clip_depth_parse("d3d", NULL));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_from_camera_exact),
        cmocka_unit_test(test_from_matrices_conventions),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_infinite_far),
        cmocka_unit_test(test_closed_mesh_winding),
        cmocka_unit_test(test_off_axis_against_oracle),
        cmocka_unit_test(test_symmetric_frustum_misses),
        cmocka_unit_test(test_off_axis_derived),
        cmocka_unit_test(test_random_matrices),
        cmocka_unit_test(test_viewport_and_names),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
