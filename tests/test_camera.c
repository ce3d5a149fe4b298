/* Cameras: matrices against hand-computed values and against cglm, frustum planes against
 * projection, corners on planes, roll, orthographic planes, box classification against brute-force
 * point sampling, validation. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <cmocka.h>

#include <cglm/cglm.h>
#include <math.h>
#include <string.h>

#include "sightline/camera.h"
#include "core/sl_core.h"

static double plane_dist(const sl_plane *p, sl_vec3 v) { return (double)p->a * v.x + (double)p->b * v.y + (double)p->c * v.z + p->d; }

/* Clip coordinates of a world point (double accumulation over the float matrix). */
static void to_clip(const sl_mat4 *m, sl_vec3 p, double c[4])
{
    for (int r = 0; r < 4; r++)
        c[r] = (double)m->m[0 * 4 + r] * p.x + (double)m->m[1 * 4 + r] * p.y + (double)m->m[2 * 4 + r] * p.z + m->m[3 * 4 + r];
}

static void assert_mat_near(const sl_mat4 *m, const double expect[16], double tol)
{
    for (int i = 0; i < 16; i++) {
        if (fabs(m->m[i] - expect[i]) > tol)
            fail_msg("element %d (col %d row %d): %.9g, expected %.9g", i, i / 4, i % 4, (double)m->m[i], expect[i]);
    }
}

static sl_camera cam_at(float x, float y, float z, double yaw_deg, double pitch_deg, double roll_deg)
{
    sl_camera c = sl_camera_default();
    c.position = (sl_vec3){x, y, z};
    c.yaw = (float)(yaw_deg * M_PI / 180), c.pitch = (float)(pitch_deg * M_PI / 180), c.roll = (float)(roll_deg * M_PI / 180);
    return c;
}

/* A random camera of either projection, with a moderate near/far ratio so that float clip
 * coordinates are accurate enough to compare with the planes. */
static sl_camera random_camera(sl_rng *r, sl_projection proj)
{
    sl_camera c = sl_camera_default();
    c.position = (sl_vec3){sl_rng_range(r, -50, 50), sl_rng_range(r, -50, 50), sl_rng_range(r, 0, 30)};
    c.yaw = sl_rng_range(r, (float)-M_PI, (float)M_PI);
    c.pitch = sl_rng_range(r, -1.5f, 1.5f);
    c.roll = sl_rng_range(r, -0.5f, 0.5f);
    c.projection = proj;
    c.fov_y = sl_rng_range(r, 0.3f, 2.0f);
    c.ortho_height = sl_rng_range(r, 10, 80);
    c.near_plane = sl_rng_range(r, 0.2f, 2.0f);
    c.far_plane = sl_rng_range(r, 60, 150);
    c.width = 320 + sl_rng_below(r, 1600);
    c.height = 240 + sl_rng_below(r, 900);
    return c;
}

static void test_default_and_basis(void **state)
{
    (void)state;
    sl_camera c = sl_camera_default();
    assert_int_equal(sl_camera_validate(&c, NULL), SL_OK);
    assert_float_equal(c.position.z, 1.7f, 0);
    assert_float_equal(c.fov_y, (float)(M_PI / 3), 1e-7);
    sl_rng r;
    sl_rng_seed(&r, 7, 1);
    for (int i = 0; i < 200; i++) {
        sl_camera k = random_camera(&r, SL_PERSPECTIVE);
        sl_vec3 f, rt, u;
        sl_camera_basis(&k, &f, &rt, &u);
        /* forward formula of camera.h */
        assert_float_equal(f.x, cosf(k.pitch) * cosf(k.yaw), 1e-5);
        assert_float_equal(f.y, cosf(k.pitch) * sinf(k.yaw), 1e-5);
        assert_float_equal(f.z, sinf(k.pitch), 1e-5);
        /* orthonormal and right-handed: right x up = -forward (eye looks down -Z) */
        assert_float_equal(f.x * rt.x + f.y * rt.y + f.z * rt.z, 0, 1e-5);
        assert_float_equal(f.x * u.x + f.y * u.y + f.z * u.z, 0, 1e-5);
        assert_float_equal(rt.x * u.x + rt.y * u.y + rt.z * u.z, 0, 1e-5);
        assert_float_equal(rt.y * u.z - rt.z * u.y, -f.x, 1e-5);
        assert_float_equal(rt.z * u.x - rt.x * u.z, -f.y, 1e-5);
        assert_float_equal(rt.x * u.y - rt.y * u.x, -f.z, 1e-5);
    }
    /* with no roll, up has a positive z below the poles, and right is horizontal */
    sl_camera k = cam_at(0, 0, 0, 33, 40, 0);
    sl_vec3 f, rt, u;
    sl_camera_basis(&k, &f, &rt, &u);
    assert_true(u.z > 0);
    assert_float_equal(rt.z, 0, 1e-7);
}

static void test_known_view_matrices(void **state)
{
    (void)state;
    /* default camera at (0,0,1.7) looking along +X: right = -Y, up = +Z, back = -X */
    sl_camera c = sl_camera_default();
    sl_mat4 v = sl_camera_view(&c);
    const double v0[16] = {0, 0, -1, 0, -1, 0, 0, 0, 0, 1, 0, 0, 0, -1.7, 0, 1};
    assert_mat_near(&v, v0, 1e-6);
    double e[4];
    to_clip(&v, (sl_vec3){10, 2, 1.7f}, e); /* 10 m ahead, 2 m to the left */
    assert_float_equal(e[0], -2, 1e-5);
    assert_float_equal(e[1], 0, 1e-5);
    assert_float_equal(e[2], -10, 1e-5);

    /* at (1,2,3) looking along +Y: right = +X, up = +Z, back = -Y */
    c = cam_at(1, 2, 3, 90, 0, 0);
    v = sl_camera_view(&c);
    const double v1[16] = {1, 0, 0, 0, 0, 0, -1, 0, 0, 1, 0, 0, -1, -3, 2, 1};
    assert_mat_near(&v, v1, 1e-6);

    /* looking straight down with yaw 0: right = -Y, image up = +X */
    c = cam_at(0, 0, 10, 0, -90, 0);
    c.pitch = -(float)M_PI_2;
    assert_int_equal(sl_camera_validate(&c, NULL), SL_OK);
    v = sl_camera_view(&c);
    const double v2[16] = {0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 1, 0, 0, 0, -10, 1};
    assert_mat_near(&v, v2, 1e-6);

    /* yaw 180 and roll 90 at the origin: forward -X; unrolled right +Y and up +Z; the roll turns
     * up onto the old right (+Y) and right onto the old down (-Z) */
    c = cam_at(0, 0, 0, 180, 0, 90);
    v = sl_camera_view(&c);
    const double v3[16] = {0, 0, 1, 0, 0, 1, 0, 0, -1, 0, 0, 0, 0, 0, 0, 1};
    assert_mat_near(&v, v3, 1e-6);
}

static void test_known_projection_matrices(void **state)
{
    (void)state;
    sl_camera c = sl_camera_default();
    c.fov_y = (float)(M_PI / 2), c.width = 200, c.height = 100, c.near_plane = 1, c.far_plane = 3;
    sl_mat4 p = sl_camera_proj(&c);
    /* f = 1/tan(45) = 1; aspect 2; (f+n)/(n-f) = -2; 2fn/(n-f) = -3 */
    const double p0[16] = {0.5, 0, 0, 0, 0, 1, 0, 0, 0, 0, -2, -1, 0, 0, -3, 0};
    assert_mat_near(&p, p0, 1e-6);
    /* eye z = -near maps to NDC -1, -far to +1 */
    double cl[4];
    to_clip(&p, (sl_vec3){0, 0, -1}, cl);
    assert_float_equal(cl[2] / cl[3], -1, 1e-6);
    to_clip(&p, (sl_vec3){0, 0, -3}, cl);
    assert_float_equal(cl[2] / cl[3], 1, 1e-6);

    c.projection = SL_ORTHOGRAPHIC;
    c.ortho_height = 10, c.width = 100, c.height = 100, c.near_plane = 1, c.far_plane = 11;
    p = sl_camera_proj(&c);
    const double p1[16] = {0.2, 0, 0, 0, 0, 0.2, 0, 0, 0, 0, -0.2, 0, 0, 0, -1.2, 1};
    assert_mat_near(&p, p1, 1e-6);
}

/* Independent check: the same matrices from cglm's look-at, perspective and ortho. */
static void test_against_cglm(void **state)
{
    (void)state;
    sl_rng r;
    sl_rng_seed(&r, 11, 2);
    for (int i = 0; i < 100; i++) {
        sl_camera c = random_camera(&r, i & 1 ? SL_ORTHOGRAPHIC : SL_PERSPECTIVE);
        c.pitch = SL_CLAMP(c.pitch, -1.2f, 1.2f); /* look-at with world up degenerates at the poles */
        c.roll = 0;
        sl_vec3 f;
        sl_camera_basis(&c, &f, NULL, NULL);
        vec3 eye = {c.position.x, c.position.y, c.position.z};
        vec3 ctr = {eye[0] + f.x, eye[1] + f.y, eye[2] + f.z}, up = {0, 0, 1};
        mat4 gv, gp;
        glm_lookat(eye, ctr, up, gv);
        float aspect = (float)c.width / (float)c.height;
        if (c.projection == SL_PERSPECTIVE)
            glm_perspective(c.fov_y, aspect, c.near_plane, c.far_plane, gp);
        else
            glm_ortho(-0.5f * c.ortho_height * aspect, 0.5f * c.ortho_height * aspect, -0.5f * c.ortho_height,
                      0.5f * c.ortho_height, c.near_plane, c.far_plane, gp);
        sl_mat4 v = sl_camera_view(&c), p = sl_camera_proj(&c);
        for (int col = 0; col < 4; col++)
            for (int row = 0; row < 4; row++) {
                double tv = 1e-4 * (col == 3 ? 60 : 1), tp = 1e-4 * fmax(1, fabs(gp[col][row]));
                if (fabs(v.m[col * 4 + row] - gv[col][row]) > tv)
                    fail_msg("camera %d view [%d][%d]: %g vs cglm %g", i, col, row, (double)v.m[col * 4 + row],
                             (double)gv[col][row]);
                if (fabs(p.m[col * 4 + row] - gp[col][row]) > tp)
                    fail_msg("camera %d proj [%d][%d]: %g vs cglm %g", i, col, row, (double)p.m[col * 4 + row],
                             (double)gp[col][row]);
            }
    }
}

/* Every random point: inside the clip volume exactly when inside all six planes (points within a
 * small margin of a plane are skipped: float rounding may put them either side). */
static void test_planes_agree_with_projection(void **state)
{
    (void)state;
    sl_rng r;
    sl_rng_seed(&r, 3, 3);
    int inside = 0, outside = 0;
    for (int i = 0; i < 200; i++) {
        sl_camera c = random_camera(&r, i & 1 ? SL_ORTHOGRAPHIC : SL_PERSPECTIVE);
        assert_int_equal(sl_camera_validate(&c, NULL), SL_OK);
        sl_frustum fr = sl_camera_frustum(&c);
        sl_mat4 vp = sl_camera_view_proj(&c);
        for (int k = 0; k < 6; k++) /* normalised */
            assert_float_equal(fr.planes[k].a * fr.planes[k].a + fr.planes[k].b * fr.planes[k].b +
                                   fr.planes[k].c * fr.planes[k].c, 1, 1e-5);
        for (int j = 0; j < 500; j++) {
            sl_vec3 p = {c.position.x + sl_rng_range(&r, -160, 160), c.position.y + sl_rng_range(&r, -160, 160),
                         c.position.z + sl_rng_range(&r, -160, 160)};
            bool in_planes = true, near_plane = false;
            for (int k = 0; k < 6; k++) {
                double d = plane_dist(&fr.planes[k], p);
                in_planes &= d >= 0;
                near_plane |= fabs(d) < 0.02;
            }
            if (near_plane)
                continue;
            double cl[4];
            to_clip(&vp, p, cl);
            bool in_clip = cl[3] > 0 && fabs(cl[0]) <= cl[3] && fabs(cl[1]) <= cl[3] && fabs(cl[2]) <= cl[3];
            if (in_clip != in_planes)
                fail_msg("camera %d point %d (%g %g %g): clip says %d, planes say %d", i, j, (double)p.x, (double)p.y,
                         (double)p.z, in_clip, in_planes);
            in_planes ? inside++ : outside++;
        }
    }
    assert_true(inside > 1000);
    assert_true(outside > 1000);
}

static void test_corners_on_planes(void **state)
{
    (void)state;
    /* corner i lies on these planes (left 0, right 1, bottom 2, top 3, near 4, far 5) */
    static const int on[8][3] = {{0, 2, 4}, {1, 2, 4}, {1, 3, 4}, {0, 3, 4}, {0, 2, 5}, {1, 2, 5}, {1, 3, 5}, {0, 3, 5}};
    sl_rng r;
    sl_rng_seed(&r, 5, 5);
    for (int i = 0; i < 200; i++) {
        sl_camera c = random_camera(&r, i & 1 ? SL_ORTHOGRAPHIC : SL_PERSPECTIVE);
        if (i % 10 == 0)
            c.far_plane = 5000, c.near_plane = 0.1f; /* the default range too */
        sl_frustum fr = sl_camera_frustum(&c);
        for (int k = 0; k < 8; k++) {
            sl_vec3 q = fr.corners[k];
            double scale = fmax(1.0, fabs(q.x) + fabs(q.y) + fabs(q.z)), tol = 2e-6 * scale;
            for (int pl = 0; pl < 6; pl++) {
                double d = plane_dist(&fr.planes[pl], q);
                bool must = pl == on[k][0] || pl == on[k][1] || pl == on[k][2];
                if (must ? fabs(d) > tol : d < -tol)
                    fail_msg("camera %d corner %d plane %d: distance %g", i, k, pl, d);
            }
        }
        /* corner order: near bl, br, tr, tl seen by the viewer */
        sl_vec3 rt, u;
        sl_camera_basis(&c, NULL, &rt, &u);
        sl_vec3 a = fr.corners[0], b = fr.corners[1], t = fr.corners[3];
        assert_true((b.x - a.x) * rt.x + (b.y - a.y) * rt.y + (b.z - a.z) * rt.z > 0);
        assert_true((t.x - a.x) * u.x + (t.y - a.y) * u.y + (t.z - a.z) * u.z > 0);
    }
}

static void test_orthographic_planes_parallel(void **state)
{
    (void)state;
    sl_rng r;
    sl_rng_seed(&r, 9, 9);
    for (int i = 0; i < 50; i++) {
        sl_camera c = random_camera(&r, SL_ORTHOGRAPHIC);
        sl_frustum fr = sl_camera_frustum(&c);
        sl_vec3 f;
        sl_camera_basis(&c, &f, NULL, NULL);
        for (int k = 0; k < 6; k += 2) {
            const sl_plane *p = &fr.planes[k], *q = &fr.planes[k + 1];
            assert_float_equal(p->a, -q->a, 1e-6);
            assert_float_equal(p->b, -q->b, 1e-6);
            assert_float_equal(p->c, -q->c, 1e-6);
            /* the gap between a pair: width, height, far - near */
            double gap = (double)p->d + q->d;
            double expect = k == 0 ? c.ortho_height * c.width / (double)c.height
                            : k == 2 ? c.ortho_height : (double)c.far_plane - c.near_plane;
            assert_float_equal(gap, expect, 1e-3 * expect + 1e-3);
        }
        for (int k = 0; k < 4; k++) /* side planes are parallel to the view direction */
            assert_float_equal(fr.planes[k].a * f.x + fr.planes[k].b * f.y + fr.planes[k].c * f.z, 0, 1e-6);
        /* near and far rectangles are the same size */
        for (int k = 0; k < 4; k++) {
            double dn = hypot(fr.corners[k].x - fr.corners[(k + 1) % 4].x, fr.corners[k].y - fr.corners[(k + 1) % 4].y);
            double df = hypot(fr.corners[4 + k].x - fr.corners[4 + (k + 1) % 4].x,
                              fr.corners[4 + k].y - fr.corners[4 + (k + 1) % 4].y);
            assert_float_equal(dn, df, 1e-3);
        }
    }
}

static void test_roll_rotates_image(void **state)
{
    (void)state;
    /* a point straight above the view axis (in the unrolled image) */
    for (int roll_deg = -150; roll_deg <= 180; roll_deg += 30) {
        sl_camera c0 = cam_at(5, -3, 2, 40, 10, 0), c = c0;
        c.width = c.height = 500;
        c.roll = (float)(roll_deg * M_PI / 180);
        sl_vec3 f, u;
        sl_camera_basis(&c0, &f, NULL, &u);
        sl_vec3 p = {c0.position.x + 10 * f.x + 2 * u.x, c0.position.y + 10 * f.y + 2 * u.y, c0.position.z + 10 * f.z + 2 * u.z};
        sl_mat4 vp = sl_camera_view_proj(&c);
        double cl[4];
        to_clip(&vp, p, cl);
        double x = cl[0] / cl[3], y = cl[1] / cl[3];
        /* positive roll turns the camera clockwise: the image turns counter-clockwise by roll */
        double angle = atan2(y, x) * 180 / M_PI, expect = 90 + roll_deg;
        double diff = remainder(angle - expect, 360);
        if (fabs(diff) > 1e-3)
            fail_msg("roll %d: point at image angle %g, expected %g", roll_deg, angle, expect);
    }
    /* and in world terms: positive roll tilts up toward right */
    sl_camera c = cam_at(0, 0, 0, 0, 0, 20);
    sl_vec3 rt, u;
    sl_camera_basis(&c, NULL, &rt, &u);
    assert_true(u.y < 0); /* right of a +X-looking camera is -Y */
    assert_true(rt.z < 0);
}

static int classify_samples(const sl_frustum *f, const sl_aabb *b, int *in, int *out)
{
    const int n = 7;
    *in = *out = 0;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++)
            for (int k = 0; k < n; k++) {
                sl_vec3 p = {b->min.x + (b->max.x - b->min.x) * (float)i / (n - 1), b->min.y + (b->max.y - b->min.y) * (float)j / (n - 1),
                             b->min.z + (b->max.z - b->min.z) * (float)k / (n - 1)};
                bool inside = true;
                for (int pl = 0; pl < 6; pl++)
                    inside &= plane_dist(&f->planes[pl], p) >= 0;
                inside ? (*in)++ : (*out)++;
            }
    return n * n * n;
}

static void test_aabb_classification(void **state)
{
    (void)state;
    sl_rng r;
    sl_rng_seed(&r, 21, 4);
    int count[3] = {0, 0, 0};
    for (int i = 0; i < 3000; i++) {
        sl_camera c = random_camera(&r, i & 1 ? SL_ORTHOGRAPHIC : SL_PERSPECTIVE);
        sl_frustum f = sl_camera_frustum(&c);
        sl_vec3 ctr = {c.position.x + sl_rng_range(&r, -120, 120), c.position.y + sl_rng_range(&r, -120, 120),
                       c.position.z + sl_rng_range(&r, -120, 120)};
        if (i % 3 == 0) { /* bias a third of the boxes toward the view axis */
            sl_vec3 fw;
            sl_camera_basis(&c, &fw, NULL, NULL);
            float t = sl_rng_range(&r, 0, 100);
            ctr = (sl_vec3){c.position.x + t * fw.x, c.position.y + t * fw.y, c.position.z + t * fw.z};
        }
        sl_vec3 h = {sl_rng_range(&r, 0.1f, 30), sl_rng_range(&r, 0.1f, 30), sl_rng_range(&r, 0.1f, 30)};
        sl_aabb b = {{ctr.x - h.x, ctr.y - h.y, ctr.z - h.z}, {ctr.x + h.x, ctr.y + h.y, ctr.z + h.z}};
        int in, out;
        classify_samples(&f, &b, &in, &out);
        int cls = sl_frustum_test_aabb(&f, &b);
        assert_in_range(cls, 0, 2);
        count[cls]++;
        if (cls == 0 && in)
            fail_msg("box %d: classified outside but %d sample points are inside", i, in);
        if (cls == 2 && out)
            fail_msg("box %d: classified inside but %d sample points are outside", i, out);
        if (in && out && cls != 1)
            fail_msg("box %d: straddles the frustum (%d in, %d out) but classified %d", i, in, out, cls);
        if (!out && cls != 2) /* all corners inside a convex volume: the box is inside */
            fail_msg("box %d: every sample inside but classified %d", i, cls);
    }
    assert_true(count[0] > 100 && count[1] > 100 && count[2] > 100);
    /* an empty box is outside */
    sl_camera c = sl_camera_default();
    sl_frustum f = sl_camera_frustum(&c);
    sl_aabb e = sl_aabb_empty();
    assert_int_equal(sl_frustum_test_aabb(&f, &e), 0);
}

static void expect_invalid(sl_camera c, const char *word)
{
    sl_error err;
    memset(&err, 0, sizeof err);
    assert_int_equal(sl_camera_validate(&c, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(err.status, SL_ERROR_INVALID_ARGUMENT);
    if (!strstr(err.message, word))
        fail_msg("message '%s' does not name '%s'", err.message, word);
}

static void test_validate(void **state)
{
    (void)state;
    sl_camera d = sl_camera_default(), c;
    c = d, c.position.x = NAN, expect_invalid(c, "position");
    c = d, c.position.z = INFINITY, expect_invalid(c, "position");
    c = d, c.yaw = NAN, expect_invalid(c, "yaw");
    c = d, c.roll = -INFINITY, expect_invalid(c, "roll");
    c = d, c.pitch = NAN, expect_invalid(c, "pitch");
    c = d, c.pitch = 1.6f, expect_invalid(c, "pitch");
    c = d, c.pitch = -1.6f, expect_invalid(c, "pitch");
    c = d, c.fov_y = NAN, expect_invalid(c, "fov");
    c = d, c.fov_y = 0, expect_invalid(c, "fov");
    c = d, c.fov_y = (float)M_PI, expect_invalid(c, "fov");
    c = d, c.near_plane = 0, expect_invalid(c, "near");
    c = d, c.near_plane = NAN, expect_invalid(c, "near");
    c = d, c.far_plane = c.near_plane, expect_invalid(c, "far");
    c = d, c.far_plane = INFINITY, expect_invalid(c, "far");
    c = d, c.width = 0, expect_invalid(c, "viewport");
    c = d, c.height = 0, expect_invalid(c, "viewport");
    c = d, c.projection = (sl_projection)7, expect_invalid(c, "projection");
    c = d, c.projection = SL_ORTHOGRAPHIC, c.ortho_height = 0, expect_invalid(c, "ortho_height");
    c = d, c.projection = SL_ORTHOGRAPHIC, c.ortho_height = NAN, expect_invalid(c, "ortho_height");
    c = d, c.ortho_height = NAN, expect_invalid(c, "ortho_height"); /* non-finite even when unused */
    /* the float nearest pi/2 is slightly above it and still valid */
    c = d, c.pitch = (float)M_PI_2;
    assert_int_equal(sl_camera_validate(&c, NULL), SL_OK);
    c.pitch = -(float)M_PI_2;
    assert_int_equal(sl_camera_validate(&c, NULL), SL_OK);
    c = d, c.projection = SL_ORTHOGRAPHIC, c.fov_y = 4; /* fov unused by orthographic cameras */
    assert_int_equal(sl_camera_validate(&c, NULL), SL_OK);
    assert_int_equal(sl_camera_validate(NULL, NULL), SL_ERROR_INVALID_ARGUMENT);
}

static void test_look_at(void **state)
{
    (void)state;
    sl_rng r;
    sl_rng_seed(&r, 1, 8);
    for (int i = 0; i < 100; i++) {
        sl_camera c = random_camera(&r, SL_PERSPECTIVE);
        float roll = c.roll;
        sl_vec3 t = {sl_rng_range(&r, -100, 100), sl_rng_range(&r, -100, 100), sl_rng_range(&r, -100, 100)};
        sl_camera_look_at(&c, t);
        assert_int_equal(sl_camera_validate(&c, NULL), SL_OK);
        sl_vec3 f;
        sl_camera_basis(&c, &f, NULL, NULL);
        double dx = t.x - c.position.x, dy = t.y - c.position.y, dz = t.z - c.position.z, l = sqrt(dx * dx + dy * dy + dz * dz);
        assert_float_equal((f.x * dx + f.y * dy + f.z * dz) / l, 1, 1e-5);
        assert_float_equal(c.roll, roll, 0);
        /* the target projects to the image centre */
        sl_mat4 vp = sl_camera_view_proj(&c);
        double cl[4];
        to_clip(&vp, t, cl);
        assert_float_equal(cl[0] / cl[3], 0, 1e-3);
        assert_float_equal(cl[1] / cl[3], 0, 1e-3);
    }
    /* straight down keeps the yaw; looking at the eye itself changes nothing */
    sl_camera c = cam_at(0, 0, 10, 70, 0, 0);
    sl_camera_look_at(&c, (sl_vec3){0, 0, 0});
    assert_float_equal(c.yaw, (float)(70 * M_PI / 180), 1e-6);
    assert_float_equal(c.pitch, -(float)M_PI_2, 1e-6);
    sl_camera before = c;
    sl_camera_look_at(&c, c.position);
    assert_memory_equal(&before, &c, sizeof c);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_default_and_basis),
        cmocka_unit_test(test_known_view_matrices),
        cmocka_unit_test(test_known_projection_matrices),
        cmocka_unit_test(test_against_cglm),
        cmocka_unit_test(test_planes_agree_with_projection),
        cmocka_unit_test(test_corners_on_planes),
        cmocka_unit_test(test_orthographic_planes_parallel),
        cmocka_unit_test(test_roll_rotates_image),
        cmocka_unit_test(test_aabb_classification),
        cmocka_unit_test(test_validate),
        cmocka_unit_test(test_look_at),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
