/* The point oracle on hand-built scenes whose answer is known: a wall hides a box, a one-pixel gap
 * shows it with a countable number of pixels, the near plane cuts a ground plane where a ray cast
 * says it must, shared edges neither leak nor overlap, cube maps are seamless, threads agree. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <stdlib.h>

#include "core/sl_core.h"
#include "sightline/truth.h"
#include "support/counting_alloc.h"

/* ---- scene helpers ---- */

static uint32_t add_mesh_object(sl_scene s, const float *pos, uint32_t nv, const uint32_t *idx, uint32_t nt,
                                const sl_affine *xf, uint32_t flags)
{
    sl_error err;
    sl_mesh_desc md = {pos, NULL, nv, idx, nt, NULL};
    uint32_t mesh, obj;
    assert_int_equal(sl_scene_add_mesh(s, &md, &mesh, &err), SL_OK);
    sl_object_desc od = {mesh, xf, 0xffffffffu, SL_KIND_OTHER, flags, 0};
    assert_int_equal(sl_scene_add_object(s, &od, &obj, &err), SL_OK);
    return obj;
}

/* An axis-aligned box, 12 triangles, counter-clockwise seen from outside. */
static uint32_t add_box_xf(sl_scene s, sl_vec3 lo, sl_vec3 hi, uint32_t flags, const sl_affine *xf)
{
    float p[24];
    for (int i = 0; i < 8; i++) {
        p[3 * i] = (i & 1) ? hi.x : lo.x;
        p[3 * i + 1] = (i & 2) ? hi.y : lo.y;
        p[3 * i + 2] = (i & 4) ? hi.z : lo.z;
    }
    static const int quads[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
    uint32_t idx[36];
    float cx = 0.5f * (lo.x + hi.x), cy = 0.5f * (lo.y + hi.y), cz = 0.5f * (lo.z + hi.z);
    for (int f = 0; f < 6; f++) {
        const int *q = quads[f];
        const float *a = p + 3 * q[0], *b = p + 3 * q[1], *c = p + 3 * q[2];
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        float fc[3] = {0, 0, 0};
        for (int k = 0; k < 4; k++)
            for (int j = 0; j < 3; j++)
                fc[j] += 0.25f * p[3 * q[k] + j];
        bool outward = n[0] * (fc[0] - cx) + n[1] * (fc[1] - cy) + n[2] * (fc[2] - cz) > 0;
        uint32_t t[6] = {(uint32_t)q[0], (uint32_t)q[1], (uint32_t)q[2], (uint32_t)q[0], (uint32_t)q[2], (uint32_t)q[3]};
        if (!outward) {
            t[1] = (uint32_t)q[2], t[2] = (uint32_t)q[1], t[4] = (uint32_t)q[3], t[5] = (uint32_t)q[2];
        }
        memcpy(idx + 6 * f, t, sizeof t);
    }
    return add_mesh_object(s, p, 8, idx, 12, xf, flags);
}

static uint32_t add_box(sl_scene s, sl_vec3 lo, sl_vec3 hi, uint32_t flags)
{
    return add_box_xf(s, lo, hi, flags, NULL);
}

/* A quad of two triangles (a, b, c) and (a, c, d). */
static uint32_t add_quad(sl_scene s, sl_vec3 a, sl_vec3 b, sl_vec3 c, sl_vec3 d)
{
    float p[12] = {a.x, a.y, a.z, b.x, b.y, b.z, c.x, c.y, c.z, d.x, d.y, d.z};
    uint32_t idx[6] = {0, 1, 2, 0, 2, 3};
    return add_mesh_object(s, p, 4, idx, 2, NULL, 0);
}

/* A wall in the plane x = x0 covering y in [y0, y1], z in [z0, z1]. */
static uint32_t add_wall(sl_scene s, float x0, float y0, float y1, float z0, float z1)
{
    return add_quad(s, (sl_vec3){x0, y0, z0}, (sl_vec3){x0, y1, z0}, (sl_vec3){x0, y1, z1}, (sl_vec3){x0, y0, z1});
}

static sl_camera looking_x(sl_projection proj)
{
    sl_camera c = sl_camera_default();
    c.position = (sl_vec3){0, 0, 0};
    c.yaw = 0;
    c.pitch = 0;
    c.projection = proj;
    if (proj == SL_ORTHOGRAPHIC)
        c.ortho_height = (float)c.height; /* one metre per pixel */
    return c;
}

static uint32_t pixels_of(const sl_oracle_frame *f, uint32_t id)
{
    for (uint32_t i = 0; i < f->visible_count; i++)
        if (f->visible[i] == id)
            return f->pixels[i];
    return 0;
}

static sl_oracle make_oracle(sl_scene s, uint32_t threads)
{
    sl_oracle_options opt = sl_oracle_default_options();
    opt.threads = threads;
    opt.count_overdraw = true;
    sl_oracle o = NULL;
    sl_error err;
    assert_int_equal(sl_oracle_create(s, &opt, NULL, &o, &err), SL_OK);
    return o;
}

/* ---- tests ---- */

static void test_wall_hides_box(void **state)
{
    (void)state;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
    uint32_t wall = add_wall(s, 10, -100, 100, -100, 100);
    add_box(s, (sl_vec3){20, -1, -1}, (sl_vec3){22, 1, 1}, SL_OBJECT_CLOSED_CONVEX);
    sl_oracle o = make_oracle(s, 2);
    sl_oracle_frame f;
    sl_error err;
    sl_camera cam = looking_x(SL_PERSPECTIVE);
    assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
    assert_int_equal(f.visible_count, 1);
    assert_int_equal(f.visible[0], wall);
    assert_int_equal(f.pixels[0], cam.width * cam.height);
    assert_int_equal(f.covered_pixels, (uint64_t)cam.width * cam.height);
    assert_int_equal(f.objects_in_frustum, 2);
    assert_int_equal(f.triangles_in_frustum, 14);
    /* the wall's depth is the reversed depth of a point 10 m ahead, everywhere */
    sl_oracle_view v;
    assert_int_equal(sl_oracle_get_view(o, 0, &v, &err), SL_OK);
    double n = cam.near_plane, fa = cam.far_plane, d = 10;
    double zndc = (fa + n) / (fa - n) - 2 * fa * n / ((fa - n) * d);
    assert_true(fabs(v.depth[384 * 1024 + 512] - 0.5 * (1 - zndc)) < 1e-6);
    assert_int_equal(sl_oracle_get_view(o, 1, &v, &err), SL_ERROR_INVALID_ARGUMENT);
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

/* Perspective: a gap exactly one pixel column wide at the wall lets the box show in that column
 * for the rows whose centre ray meets the box's front face. */
static void test_gap_one_pixel_perspective(void **state)
{
    (void)state;
    sl_camera cam = looking_x(SL_PERSPECTIVE);
    const double W = cam.width, H = cam.height, t = tan(0.5 * cam.fov_y), aspect = W / H, d = 10;
    const uint32_t col = 700;
    /* world y at the wall of the screen column boundary sx (right is -y) */
#define Y_AT(sx) ((float)(-((2.0 * (sx) / W) - 1.0) * t * aspect * d))
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
    uint32_t a = add_wall(s, 10, Y_AT(col), 100, -100, 100);
    uint32_t b = add_wall(s, 10, -100, Y_AT(col + 1), -100, 100);
    uint32_t box = add_box(s, (sl_vec3){20, -10, -1}, (sl_vec3){22, 10, 1}, SL_OBJECT_CLOSED_CONVEX);
#undef Y_AT
    /* rows whose centre ray meets the front face x = 20, |z| <= 1 */
    uint32_t rows = 0;
    for (uint32_t r = 0; r < cam.height; r++) {
        double yn = 1.0 - 2.0 * (r + 0.5) / H, z = yn * t * 20.0;
        assert_true(fabs(fabs(z) - 1.0) > 1e-3); /* no centre near the box edge: the count is exact */
        rows += fabs(z) < 1.0;
    }
    assert_int_equal(rows, 66);
    sl_oracle o = make_oracle(s, 2);
    sl_oracle_frame f;
    sl_error err;
    assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
    assert_int_equal(f.visible_count, 3);
    assert_int_equal(pixels_of(&f, box), rows);
    assert_int_equal(pixels_of(&f, a), col * cam.height);
    assert_int_equal(pixels_of(&f, b), (cam.width - col - 1) * cam.height);
    /* everything the box owns lies in the gap column */
    sl_oracle_view v;
    assert_int_equal(sl_oracle_get_view(o, 0, &v, &err), SL_OK);
    for (uint32_t y = 0; y < v.height; y++)
        for (uint32_t x = 0; x < v.width; x++)
            if (v.ids[y * v.width + x] == box)
                assert_int_equal(x, col);
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

/* Orthographic, one metre per pixel: column c has its centre at y = 511.5 - c, row r at z = 383.5 - r. */
static void test_gap_orthographic(void **state)
{
    (void)state;
    struct { float g0, g1; uint32_t box_pixels; } cases[] = {
        {-89.0f, -88.0f, 20}, /* exactly one pixel wide around the centre of column 600 */
        {-88.9f, -88.1f, 20}, /* narrower, still around the centre */
        {-89.4f, -88.6f, 0},  /* narrower than a pixel and between two centres: nothing shows */
    };
    sl_camera cam = looking_x(SL_ORTHOGRAPHIC);
    for (size_t k = 0; k < SL_COUNTOF(cases); k++) {
        sl_scene s;
        assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
        add_wall(s, 10, cases[k].g1, 600, -500, 500);
        add_wall(s, 10, -600, cases[k].g0, -500, 500);
        uint32_t box = add_box(s, (sl_vec3){20, -100, -10}, (sl_vec3){22, 100, 10}, SL_OBJECT_CLOSED_CONVEX);
        sl_oracle o = make_oracle(s, 3);
        sl_oracle_frame f;
        sl_error err;
        assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
        assert_int_equal(pixels_of(&f, box), cases[k].box_pixels);
        /* the walls cover every column but the one whose centre is in the gap (if any) */
        uint64_t all = (uint64_t)cam.width * cam.height;
        assert_int_equal(f.covered_pixels, cases[k].box_pixels ? all - cam.height + cases[k].box_pixels : all);
        sl_oracle_destroy(o);
        sl_scene_destroy(s);
    }
}

static void test_box_behind_camera(void **state)
{
    (void)state;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
    add_box(s, (sl_vec3){-12, -1, -1}, (sl_vec3){-10, 1, 1}, SL_OBJECT_CLOSED_CONVEX);
    add_box(s, (sl_vec3){-2, -1, -1}, (sl_vec3){-0.2f, 1, 1}, 0);
    sl_oracle o = make_oracle(s, 2);
    sl_oracle_frame f;
    sl_error err;
    for (int p = 0; p < 2; p++) {
        sl_camera cam = looking_x(p ? SL_ORTHOGRAPHIC : SL_PERSPECTIVE);
        assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
        assert_int_equal(f.visible_count, 0);
        assert_int_equal(f.covered_pixels, 0);
        assert_int_equal(f.objects_in_frustum, 0);
        /* turned around, both are in view; the nearer one hides the other */
        cam.yaw = (float)M_PI;
        assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
        assert_int_equal(f.visible_count, 1);
        assert_int_equal(f.visible[0], 1);
    }
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

/* Is the ground quad z = zg, |x|, |y| <= 50 seen through screen point (sx, sy) in front of the near
 * plane and before the far plane? Ray cast in double. */
static bool ground_hit(const sl_camera *cam, double sx, double sy, double zg, double *depth)
{
    double t = tan(0.5 * cam->fov_y), aspect = (double)cam->width / cam->height;
    double xn = 2 * sx / cam->width - 1, yn = 1 - 2 * sy / cam->height;
    double dir[3] = {1, -xn * t * aspect, yn * t}; /* forward +x, right -y, up +z; dir.x = 1 = eye depth rate */
    if (!(dir[2] < 0))
        return false;
    double k = zg / dir[2];
    double px = k * dir[0], py = k * dir[1];
    if (depth)
        *depth = k;
    return k >= cam->near_plane && k <= cam->far_plane && fabs(px) <= 50 && fabs(py) <= 50;
}

static void test_near_plane_crossing(void **state)
{
    (void)state;
    const double zg = -0.03; /* cuts the near plane inside the frustum: the bottom rows are too near */
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
    uint32_t g = add_quad(s, (sl_vec3){-50, -50, (float)zg}, (sl_vec3){50, -50, (float)zg}, (sl_vec3){50, 50, (float)zg},
                          (sl_vec3){-50, 50, (float)zg});
    sl_camera cam = looking_x(SL_PERSPECTIVE);
    cam.width = 320;
    cam.height = 240;
    sl_oracle o = make_oracle(s, 2);
    sl_oracle_frame f;
    sl_error err;
    assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
    sl_oracle_view v;
    assert_int_equal(sl_oracle_get_view(o, 0, &v, &err), SL_OK);
    uint32_t checked = 0, near_cut = 0, drawn = 0;
    double fa = cam.far_plane, n = cam.near_plane;
    for (uint32_t y = 0; y < v.height; y++)
        for (uint32_t x = 0; x < v.width; x++) {
            /* decide only where the answer is the same a hundredth of a pixel around the centre */
            int in = 0;
            for (int k = 0; k < 4; k++)
                in += ground_hit(&cam, x + 0.5 + ((k & 1) ? 0.01 : -0.01), y + 0.5 + ((k & 2) ? 0.01 : -0.01), zg, NULL);
            if (in != 0 && in != 4)
                continue;
            checked++;
            uint32_t id = v.ids[y * v.width + x];
            assert_int_equal(id, in ? g : SL_NONE);
            double dd = -1;
            bool hit = ground_hit(&cam, x + 0.5, y + 0.5, zg, &dd);
            if (!hit && dd > 0 && dd < n && y > v.height / 2)
                near_cut++;
            if (hit) {
                drawn++;
                double zndc = (fa + n) / (fa - n) - 2 * fa * n / ((fa - n) * dd);
                /* the plane goes through the exact vertices: only the float view-projection rounds */
                double want = 0.5 * (1 - zndc);
                assert_true(fabs(v.depth[y * v.width + x] - want) < 2e-5 * want);
            }
        }
    assert_true(checked > v.width * v.height * 95 / 100);
    assert_true(near_cut > 1000); /* the near plane really cut the quad on screen */
    assert_true(drawn > 1000);
    assert_int_equal(pixels_of(&f, g), f.covered_pixels);
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

/* A jittered grid of triangles on vertices snapped to quarter pixels (so edges and vertices fall
 * exactly on pixel centres): every pixel centre inside the outline is covered exactly once. */
static void test_shared_edges_exact(void **state)
{
    (void)state;
    enum { G = 20 };
    float pos[(G + 1) * (G + 1) * 3];
    uint32_t idx[G * G * 6];
    sl_rng rng;
    sl_rng_seed(&rng, 7, 1);
    /* the outline: y, z in (-100.25, 99.75), world units are pixels */
    for (int j = 0; j <= G; j++)
        for (int i = 0; i <= G; i++) {
            float y = -100.25f + 10.0f * i, z = -100.25f + 10.0f * j;
            if (i > 0 && i < G && j > 0 && j < G) {
                y += 0.25f * (float)((int)sl_rng_below(&rng, 17) - 8);
                z += 0.25f * (float)((int)sl_rng_below(&rng, 17) - 8);
            }
            float *p = pos + 3 * (j * (G + 1) + i);
            p[0] = 10, p[1] = y, p[2] = z;
        }
    for (int j = 0; j < G; j++)
        for (int i = 0; i < G; i++) {
            uint32_t a = j * (G + 1) + i, b = a + 1, c = a + G + 2, d = a + G + 1;
            uint32_t *t = idx + 6 * (j * G + i);
            /* alternate the diagonal and the winding (the mesh is open: both sides are drawn) */
            if ((i + j) & 1) {
                uint32_t q[6] = {a, b, c, a, c, d};
                memcpy(t, q, sizeof q);
            } else {
                uint32_t q[6] = {a, d, b, b, d, c};
                memcpy(t, q, sizeof q);
            }
        }
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
    uint32_t obj = add_mesh_object(s, pos, (G + 1) * (G + 1), idx, G * G * 2, NULL, 0);
    sl_camera cam = looking_x(SL_ORTHOGRAPHIC);
    cam.width = cam.height = 256;
    cam.ortho_height = 256;
    sl_oracle o = make_oracle(s, 2);
    sl_oracle_frame f;
    sl_error err;
    assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
    assert_int_equal(pixels_of(&f, obj), 200 * 200);
    sl_oracle_view v;
    assert_int_equal(sl_oracle_get_view(o, 0, &v, &err), SL_OK);
    assert_non_null(v.overdraw);
    for (uint32_t i = 0; i < v.width * v.height; i++)
        assert_int_equal(v.overdraw[i], v.ids[i] == SL_NONE ? 0 : 1);
    /* a quad split in two: exactly its area in pixels */
    sl_scene s2;
    assert_int_equal(sl_scene_create(NULL, &s2, NULL), SL_OK);
    add_wall(s2, 5, -30, 34, -17, 23); /* 64 x 40 pixels, edges on pixel boundaries */
    sl_oracle o2 = make_oracle(s2, 1);
    assert_int_equal(sl_oracle_render(o2, &cam, &f, &err), SL_OK);
    assert_int_equal(f.covered_pixels, 64 * 40);
    assert_int_equal(sl_oracle_get_view(o2, 0, &v, &err), SL_OK);
    for (uint32_t i = 0; i < v.width * v.height; i++)
        assert_true(v.overdraw[i] <= 1);
    sl_oracle_destroy(o2);
    sl_scene_destroy(s2);
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

static void test_closed_backfaces(void **state)
{
    (void)state;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
    /* a mirrored closed box: its transform flips the winding, it must still show its front */
    sl_affine mirror = sl_affine_identity();
    mirror.m[5] = -1;
    uint32_t plain = add_box(s, (sl_vec3){20, 2, -1}, (sl_vec3){22, 4, 1}, SL_OBJECT_CLOSED_CONVEX);
    uint32_t mirrored = add_box_xf(s, (sl_vec3){20, 2, -1}, (sl_vec3){22, 4, 1}, SL_OBJECT_CLOSED_CONVEX, &mirror);
    sl_camera cam = looking_x(SL_PERSPECTIVE);
    sl_oracle_options opt = sl_oracle_default_options();
    uint32_t counts[2][2];
    for (int back = 0; back < 2; back++) {
        opt.draw_closed_backfaces = back;
        sl_oracle o;
        sl_oracle_frame f;
        sl_error err;
        assert_int_equal(sl_oracle_create(s, &opt, NULL, &o, &err), SL_OK);
        assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
        counts[back][0] = pixels_of(&f, plain);
        counts[back][1] = pixels_of(&f, mirrored);
        /* from inside a closed box only back faces face the eye */
        sl_camera inside = cam;
        inside.position = (sl_vec3){21, 3, 0};
        assert_int_equal(sl_oracle_render(o, &inside, &f, &err), SL_OK);
        assert_int_equal(pixels_of(&f, plain), back ? cam.width * cam.height : 0);
        sl_oracle_destroy(o);
    }
    assert_true(counts[0][0] > 1000);
    assert_int_equal(counts[0][0], counts[1][0]);
    assert_int_equal(counts[0][1], counts[1][1]);
    assert_int_equal(counts[0][0], counts[0][1]);
    sl_scene_destroy(s);
}

/* A random clutter of boxes and loose triangles. */
static sl_scene random_scene(uint64_t seed, uint32_t boxes, uint32_t loose)
{
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
    sl_rng r;
    sl_rng_seed(&r, seed, 3);
    for (uint32_t i = 0; i < boxes; i++) {
        sl_vec3 lo = {sl_rng_range(&r, -60, 60), sl_rng_range(&r, -60, 60), sl_rng_range(&r, -5, 5)};
        sl_vec3 hi = {lo.x + sl_rng_range(&r, 0.2f, 8), lo.y + sl_rng_range(&r, 0.2f, 8), lo.z + sl_rng_range(&r, 0.2f, 12)};
        add_box(s, lo, hi, sl_rng_below(&r, 2) ? SL_OBJECT_CLOSED_CONVEX : 0);
    }
    for (uint32_t i = 0; i < loose; i++) {
        float p[9];
        float c[3] = {sl_rng_range(&r, -60, 60), sl_rng_range(&r, -60, 60), sl_rng_range(&r, -5, 5)};
        for (int k = 0; k < 9; k++)
            p[k] = c[k % 3] + sl_rng_range(&r, -6, 6);
        uint32_t idx[3] = {0, 1, 2};
        add_mesh_object(s, p, 3, idx, 1, NULL, 0);
    }
    return s;
}

static void test_threads_identical(void **state)
{
    (void)state;
    sl_scene s = random_scene(11, 300, 300);
    sl_camera cams[3];
    for (int k = 0; k < 3; k++) {
        cams[k] = sl_camera_default();
        cams[k].width = 317; /* odd sizes: partial row blocks */
        cams[k].height = 203;
        cams[k].position = (sl_vec3){-70.0f + 20 * k, 3.0f * k, 1.5f};
        cams[k].yaw = 0.3f * k;
        cams[k].pitch = -0.1f;
    }
    cams[2].projection = SL_ORTHOGRAPHIC;
    cams[2].ortho_height = 60;
    size_t px = 317 * 203;
    uint32_t *ids = malloc(px * sizeof *ids);
    float *depth = malloc(px * sizeof *depth);
    for (int k = 0; k < 3; k++) {
        sl_oracle_frame f1;
        sl_oracle o1 = make_oracle(s, 1);
        sl_error err;
        assert_int_equal(sl_oracle_render(o1, &cams[k], &f1, &err), SL_OK);
        assert_true(f1.visible_count > 10);
        sl_oracle_view v1;
        assert_int_equal(sl_oracle_get_view(o1, 0, &v1, &err), SL_OK);
        memcpy(ids, v1.ids, px * sizeof *ids);
        memcpy(depth, v1.depth, px * sizeof *depth);
        for (uint32_t t = 2; t <= 3; t++) {
            sl_oracle o = make_oracle(s, t);
            sl_oracle_frame f;
            assert_int_equal(sl_oracle_render(o, &cams[k], &f, &err), SL_OK);
            sl_oracle_view v;
            assert_int_equal(sl_oracle_get_view(o, 0, &v, &err), SL_OK);
            assert_memory_equal(v.ids, ids, px * sizeof *ids);
            assert_memory_equal(v.depth, depth, px * sizeof *depth);
            assert_int_equal(f.visible_count, f1.visible_count);
            assert_memory_equal(f.visible, f1.visible, f.visible_count * sizeof(uint32_t));
            assert_memory_equal(f.pixels, f1.pixels, f.visible_count * sizeof(uint32_t));
            sl_oracle_destroy(o);
        }
        sl_oracle_destroy(o1);
    }
    free(ids);
    free(depth);
    sl_scene_destroy(s);
}

/* Coincident surfaces: the pixel goes to the lowest id, whatever the thread split (the objects
 * land on different threads and meet again in the merge). */
static void test_ties_to_lower_id(void **state)
{
    (void)state;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
    add_wall(s, 12, -3, 1, -2, 2);  /* id 0 */
    add_wall(s, 12, -1, 3, -1, 3);  /* id 1 overlaps 0 in the same plane */
    add_wall(s, 12, -1, 3, -1, 3);  /* id 2 duplicates 1 */
    add_wall(s, 11, 2, 2.5f, -4, 4); /* id 3 in front of both */
    sl_camera cam = looking_x(SL_PERSPECTIVE);
    cam.width = 200;
    cam.height = 150;
    uint32_t first[4] = {0};
    for (uint32_t t = 1; t <= 4; t++) {
        sl_oracle o = make_oracle(s, t);
        sl_oracle_frame f;
        sl_error err;
        assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
        assert_int_equal(pixels_of(&f, 2), 0);
        for (uint32_t id = 0; id < 4; id++) {
            assert_true(pixels_of(&f, id) > 0 || id == 2);
            if (t == 1)
                first[id] = pixels_of(&f, id);
            assert_int_equal(pixels_of(&f, id), first[id]);
        }
        sl_oracle_view v;
        assert_int_equal(sl_oracle_get_view(o, 0, &v, &err), SL_OK);
        for (uint32_t i = 0; i < v.width * v.height; i++)
            assert_true(v.ids[i] == SL_NONE || v.overdraw[i] >= 1);
        sl_oracle_destroy(o);
    }
    sl_scene_destroy(s);
}

/* The counts must agree with the id buffer, and every visible object must own its pixels. */
static void test_counts_match_buffer(void **state)
{
    (void)state;
    sl_scene s = random_scene(5, 200, 100);
    sl_oracle o = make_oracle(s, 2);
    sl_camera cam = sl_camera_default();
    cam.position = (sl_vec3){-70, 0, 2};
    sl_oracle_frame f;
    sl_error err;
    assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
    sl_oracle_view v;
    assert_int_equal(sl_oracle_get_view(o, 0, &v, &err), SL_OK);
    uint32_t n = sl_scene_object_count(s);
    uint32_t *c = calloc(n, sizeof *c);
    uint64_t covered = 0;
    for (uint32_t i = 0; i < v.width * v.height; i++)
        if (v.ids[i] != SL_NONE) {
            assert_true(v.ids[i] < n);
            assert_true(v.depth[i] > 0 && v.depth[i] <= 1);
            c[v.ids[i]]++;
            covered++;
        } else {
            assert_true(v.depth[i] == 0);
        }
    assert_int_equal(covered, f.covered_pixels);
    uint32_t k = 0;
    for (uint32_t id = 0; id < n; id++)
        if (c[id]) {
            assert_true(k < f.visible_count);
            assert_int_equal(f.visible[k], id);
            assert_int_equal(f.pixels[k], c[id]);
            k++;
        }
    assert_int_equal(k, f.visible_count);
    free(c);
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

/* Inside a box (open mesh, both sides drawn) every pixel of every face sees exactly one box face. */
static void test_cube_covers_everything(void **state)
{
    (void)state;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
    uint32_t box = add_box(s, (sl_vec3){-5, -5, -5}, (sl_vec3){5, 5, 5}, 0);
    sl_oracle o = make_oracle(s, 2);
    sl_oracle_frame f;
    sl_error err;
    const uint32_t N = 64;
    sl_vec3 eyes[2] = {{0, 0, 0}, {0.3f, -1.7f, 2.2f}};
    for (int e = 0; e < 2; e++) {
        assert_int_equal(sl_oracle_render_cube(o, eyes[e], N, 0.05f, 100, &f, &err), SL_OK);
        assert_int_equal(f.view_count, 6);
        assert_int_equal(f.visible_count, 1);
        assert_int_equal(f.visible[0], box);
        assert_int_equal(f.pixels[0], 6 * N * N);
        for (uint32_t face = 0; face < 6; face++) {
            sl_oracle_view v;
            assert_int_equal(sl_oracle_get_view(o, face, &v, &err), SL_OK);
            for (uint32_t i = 0; i < N * N; i++)
                assert_int_equal(v.overdraw[i], 1);
        }
    }
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

/* A thin pole standing on the seam between the +X and +Y faces shows on both, in the same rows,
 * touching the shared edge from both sides; no other face sees it. */
static void test_cube_seam(void **state)
{
    (void)state;
    sl_scene s;
    assert_int_equal(sl_scene_create(NULL, &s, NULL), SL_OK);
    const float r = 10.0f / sqrtf(2.0f), hw = 0.037f / sqrtf(2.0f);
    uint32_t pole = add_quad(s, (sl_vec3){r + hw, r - hw, -2.3f}, (sl_vec3){r - hw, r + hw, -2.3f},
                             (sl_vec3){r - hw, r + hw, 2.1f}, (sl_vec3){r + hw, r - hw, 2.1f});
    sl_oracle o = make_oracle(s, 2);
    sl_oracle_frame f;
    sl_error err;
    const uint32_t N = 256;
    assert_int_equal(sl_oracle_render_cube(o, (sl_vec3){0, 0, 0}, N, 0.1f, 100, &f, &err), SL_OK);
    assert_int_equal(f.visible_count, 1);
    sl_oracle_view px, py;
    assert_int_equal(sl_oracle_get_view(o, SL_CUBE_POS_X, &px, &err), SL_OK);
    assert_int_equal(sl_oracle_get_view(o, SL_CUBE_POS_Y, &py, &err), SL_OK);
    uint32_t on_x = 0, on_y = 0, rows = 0;
    for (uint32_t y = 0; y < N; y++) {
        /* +X face: +Y is on the left (column 0); +Y face: +X is on the right (column N-1) */
        bool a = px.ids[y * N + 0] == pole, b = py.ids[y * N + N - 1] == pole;
        assert_int_equal(a, b);
        rows += a;
        for (uint32_t x = 0; x < N; x++) {
            on_x += px.ids[y * N + x] == pole;
            on_y += py.ids[y * N + x] == pole;
        }
    }
    assert_true(rows > 20);
    assert_true(on_x >= rows && on_y >= rows);
    assert_int_equal(f.pixels[0], on_x + on_y);
    for (uint32_t face = 0; face < 6; face++) {
        if (face == SL_CUBE_POS_X || face == SL_CUBE_POS_Y)
            continue;
        sl_oracle_view v;
        assert_int_equal(sl_oracle_get_view(o, face, &v, &err), SL_OK);
        for (uint32_t i = 0; i < N * N; i++)
            assert_int_equal(v.ids[i], SL_NONE);
    }
    sl_oracle_destroy(o);
    sl_scene_destroy(s);
}

/* The documented face orientation: a camera built by sl_cube_face_camera sees (nearly) the same
 * image as the exact face matrix; only rounding at silhouettes may differ. */
static void test_cube_face_cameras(void **state)
{
    (void)state;
    sl_scene s = random_scene(3, 400, 0);
    sl_oracle o = make_oracle(s, 2), oc = make_oracle(s, 2);
    const uint32_t N = 96;
    sl_vec3 eye = {1.5f, -2.5f, 0.5f};
    sl_oracle_frame f, fc;
    sl_error err;
    assert_int_equal(sl_oracle_render_cube(o, eye, N, 0.1f, 500, &f, &err), SL_OK);
    for (uint32_t face = 0; face < 6; face++) {
        sl_camera cam = sl_cube_face_camera(eye, (sl_cube_face)face, N, 0.1f, 500);
        assert_int_equal(sl_oracle_render(oc, &cam, &fc, &err), SL_OK);
        sl_oracle_view a, b;
        assert_int_equal(sl_oracle_get_view(o, face, &a, &err), SL_OK);
        assert_int_equal(sl_oracle_get_view(oc, 0, &b, &err), SL_OK);
        uint32_t diff = 0, covered = 0;
        for (uint32_t i = 0; i < N * N; i++) {
            diff += a.ids[i] != b.ids[i];
            covered += a.ids[i] != SL_NONE;
        }
        assert_true(covered > N * N / 10);
        assert_true(diff <= N * N / 200);
    }
    sl_oracle_destroy(o);
    sl_oracle_destroy(oc);
    sl_scene_destroy(s);
}

static void test_errors_and_memory(void **state)
{
    (void)state;
    sl_test_counter c = {0};
    sl_allocator a = sl_test_counting_allocator(&c);
    sl_scene s = random_scene(1, 50, 10);
    sl_oracle o = NULL;
    sl_error err;
    sl_oracle_options opt = sl_oracle_default_options();
    opt.threads = 0;
    assert_int_equal(sl_oracle_create(s, &opt, &a, &o, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "threads"));
    opt.threads = 2;
    opt.width = 100;
    assert_int_equal(sl_oracle_create(s, &opt, &a, &o, &err), SL_ERROR_INVALID_ARGUMENT);
    opt.width = 20000, opt.height = 20000;
    assert_int_equal(sl_oracle_create(s, &opt, &a, &o, &err), SL_ERROR_LIMIT);
    opt.width = 160, opt.height = 120;
    opt.count_overdraw = true;
    assert_int_equal(sl_oracle_create(s, &opt, &a, &o, &err), SL_OK);
    sl_camera cam = sl_camera_default();
    cam.position = (sl_vec3){-70, 0, 2};
    sl_oracle_frame f;
    assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_OK);
    assert_int_equal(f.width, 160); /* the option overrides the camera's 1024x768 */
    cam.fov_y = NAN;
    assert_int_equal(sl_oracle_render(o, &cam, &f, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_oracle_render_cube(o, (sl_vec3){0, 0, 0}, 16, 1, 0.5f, &f, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_oracle_render_cube(o, (sl_vec3){NAN, 0, 0}, 16, 0.1f, 5, &f, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_oracle_render_cube(o, (sl_vec3){0, 0, 0}, 0, 0.1f, 5, &f, &err), SL_ERROR_LIMIT);
    assert_int_equal(sl_oracle_render_cube(o, (sl_vec3){0, 0, 0}, 32, 0.1f, 500, &f, &err), SL_OK);
    assert_true(f.visible_count > 0);
    sl_oracle_destroy(o);
    assert_true(c.calls > 0);
    assert_int_equal(c.live, 0);
    sl_scene_destroy(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_wall_hides_box),
        cmocka_unit_test(test_gap_one_pixel_perspective),
        cmocka_unit_test(test_gap_orthographic),
        cmocka_unit_test(test_box_behind_camera),
        cmocka_unit_test(test_near_plane_crossing),
        cmocka_unit_test(test_shared_edges_exact),
        cmocka_unit_test(test_closed_backfaces),
        cmocka_unit_test(test_threads_identical),
        cmocka_unit_test(test_ties_to_lower_id),
        cmocka_unit_test(test_counts_match_buffer),
        cmocka_unit_test(test_cube_covers_everything),
        cmocka_unit_test(test_cube_seam),
        cmocka_unit_test(test_cube_face_cameras),
        cmocka_unit_test(test_errors_and_memory),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
