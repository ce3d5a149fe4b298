/* Software occlusion rasterizer: fill rule against an exact reference, conservative depth,
 * watertight shared edges, slivers, huge and near-plane-crossing triangles, bad input, queries,
 * orthographic projection, SIMD paths bit-equal to the scalar reference, thread counts equal. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include <math.h>
#include <pthread.h>
#include <stdlib.h>

#include "core/sl_core.h"
#include "raster/raster_internal.h"
#include "sightline/raster.h"
#include "support/counting_alloc.h"

static bool sanitized(void) { return getenv("SL_SANITIZED") != NULL; }

static const float IDENTITY[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};

/* OpenGL perspective (column-major), aspect = width/height. */
static void perspective(float m[16], double fovy, double aspect, double n, double f)
{
    memset(m, 0, sizeof(float) * 16);
    double t = 1.0 / tan(0.5 * fovy);
    m[0] = (float)(t / aspect);
    m[5] = (float)t;
    m[10] = (float)((f + n) / (n - f));
    m[11] = -1.0f;
    m[14] = (float)(2.0 * f * n / (n - f));
}

/* OpenGL orthographic box [-hw,hw] x [-hh,hh] x [-n,-f] in eye space. */
static void orthographic(float m[16], double hw, double hh, double n, double f)
{
    memset(m, 0, sizeof(float) * 16);
    m[0] = (float)(1.0 / hw);
    m[5] = (float)(1.0 / hh);
    m[10] = (float)(-2.0 / (f - n));
    m[14] = (float)(-(f + n) / (f - n));
    m[15] = 1.0f;
}

static sl_raster *make(uint32_t w, uint32_t h, sl_raster_isa isa, sl_raster_depth depth, uint32_t threads)
{
    sl_raster_options o = sl_raster_default_options(w, h);
    o.isa = isa;
    o.depth = depth;
    o.threads = threads;
    sl_raster *r = NULL;
    sl_error err;
    assert_int_equal(sl_raster_create(&o, NULL, &r, &err), SL_OK);
    return r;
}

static void render(sl_raster *r, const float *v, uint32_t nv, const uint32_t *ix, uint32_t nt, const float *m,
                   sl_raster_backface bf)
{
    sl_error err;
    assert_int_equal(sl_raster_render_triangles(r, v, nv, ix, nt, 12, m, bf, &err), SL_OK);
}

static float *depth_image(const sl_raster *r)
{
    uint32_t w, h;
    sl_raster_get_size(r, &w, &h, NULL, NULL);
    float *img = malloc(sizeof(float) * w * h);
    assert_non_null(img);
    assert_int_equal(sl_raster_read_depth(r, img, (size_t)w * h, NULL), SL_OK);
    return img;
}

/* Raw buffers of two contexts are identical (mask words and both depths, bit for bit), once the
 * rows the lazy clear left empty are written. */
static void assert_same_buffer(sl_raster *a, sl_raster *b)
{
    sl_rt_settle(a);
    sl_rt_settle(b);
    const sl_rt_target *ta = sl_rt_target_of(a), *tb = sl_rt_target_of(b);
    size_t tiles = (size_t)ta->tiles_x * (size_t)ta->tiles_y;
    assert_int_equal(tiles, (size_t)tb->tiles_x * (size_t)tb->tiles_y);
    assert_memory_equal(ta->mask, tb->mask, tiles * SL_RT_SUBTILES * sizeof(uint32_t));
    assert_memory_equal(ta->depth, tb->depth, tiles * sizeof(sl_rt_tile_depth));
}

/* ---- the exact reference ---- */

/* Snapped triangle as the rasterizer sees it (w = 1 vertices: no clipping involved). */
typedef struct ref_tri {
    int32_t X[3], Y[3];
    float d[3];
} ref_tri;

static bool ref_setup(const sl_raster *r, const float *m, const float p[9], ref_tri *t)
{
    const sl_rt_view *v = sl_rt_view_of(r);
    for (int i = 0; i < 3; i++) {
        float c[4];
        sl_rt_transform(m, p + 3 * i, c);
        if (!sl_rt_snap(v, c, &t->X[i], &t->Y[i], &t->d[i]))
            return false;
    }
    return true;
}

/* Centre of pixel (i, j) inside the snapped triangle by the top-left rule, in exact integers. */
static bool ref_covers(const ref_tri *t, int i, int j)
{
    int64_t X[3] = {t->X[0], t->X[1], t->X[2]}, Y[3] = {t->Y[0], t->Y[1], t->Y[2]};
    int64_t area = (X[1] - X[0]) * (Y[2] - Y[0]) - (X[2] - X[0]) * (Y[1] - Y[0]);
    if (area == 0)
        return false;
    if (area < 0) {
        int64_t tx = X[1], ty = Y[1];
        X[1] = X[2], Y[1] = Y[2], X[2] = tx, Y[2] = ty;
    }
    int64_t px = 256 * (int64_t)i + 128, py = 256 * (int64_t)j + 128;
    for (int e = 0; e < 3; e++) {
        int a = e, b = (e + 1) % 3;
        int64_t dX = X[b] - X[a], dY = Y[b] - Y[a];
        int64_t E = dX * (py - Y[a]) - dY * (px - X[a]);
        bool top_left = dY < 0 || (dY == 0 && dX > 0);
        if (E < 0 || (E == 0 && !top_left))
            return false;
    }
    return true;
}

/* Depth of the plane through the snapped vertices at the centre of pixel (i, j). */
static double ref_depth(const ref_tri *t, int i, int j)
{
    double x[3], y[3];
    for (int k = 0; k < 3; k++)
        x[k] = t->X[k] / 256.0, y[k] = t->Y[k] / 256.0;
    double ex1 = x[1] - x[0], ey1 = y[1] - y[0], ex2 = x[2] - x[0], ey2 = y[2] - y[0];
    double dd1 = (double)t->d[1] - t->d[0], dd2 = (double)t->d[2] - t->d[0];
    double det = ex1 * ey2 - ex2 * ey1;
    double a = (dd1 * ey2 - dd2 * ey1) / det, b = (ex1 * dd2 - ex2 * dd1) / det;
    return t->d[0] + a * (i + 0.5 - x[0]) + b * (j + 0.5 - y[0]);
}

/* A random triangle in NDC [-1.4, 1.4]^2 (w = 1, z in [-0.9, 0.9]); kind picks grid-aligned
 * vertices (edges through pixel centres), slivers or free positions. */
static void random_tri(sl_rng *rng, int W, int H, int kind, float p[9])
{
    for (int i = 0; i < 3; i++) {
        float px, py;
        if (kind == 0) {
            /* multiples of half a pixel: exact in NDC, hits the tie rule */
            px = (float)((int)sl_rng_below(rng, (uint32_t)(3 * W)) - W) * 0.5f + (float)W / 4;
            py = (float)((int)sl_rng_below(rng, (uint32_t)(3 * H)) - H) * 0.5f + (float)H / 4;
        } else {
            px = sl_rng_range(rng, -0.2f * W, 1.2f * W);
            py = sl_rng_range(rng, -0.2f * H, 1.2f * H);
        }
        p[3 * i + 0] = px / (0.5f * W) - 1.0f;
        p[3 * i + 1] = 1.0f - py / (0.5f * H);
        p[3 * i + 2] = sl_rng_range(rng, -0.9f, 0.9f);
    }
    if (kind == 2) {
        /* a sliver: the third vertex almost on the line of the first two */
        float t = sl_rng_range(rng, -0.5f, 1.5f), eps = sl_rng_range(rng, -0.004f, 0.004f);
        p[6] = p[0] + t * (p[3] - p[0]) + eps;
        p[7] = p[1] + t * (p[4] - p[1]) - eps;
    }
}

static sl_raster_isa isa_list[4];
static int isa_count;

static void collect_isas(void)
{
    isa_count = 0;
    const sl_raster_isa all[] = {SL_RASTER_ISA_SCALAR, SL_RASTER_ISA_SSE41, SL_RASTER_ISA_AVX2, SL_RASTER_ISA_AVX512};
    for (size_t i = 0; i < SL_COUNTOF(all); i++)
        if (sl_raster_isa_available(all[i]))
            isa_list[isa_count++] = all[i];
}

/* ---- tests ---- */

/* One triangle at a time on a cleared buffer: covered pixels are exactly the reference's, and
 * the depth is never nearer than the true depth at the pixel centre. */
static void test_fill_rule_exact(void **state)
{
    (void)state;
    const int W = 96, H = 64;
    int rounds = sanitized() ? 60 : 400;
    sl_rng rng;
    sl_rng_seed(&rng, 1, 2);
    for (int ii = 0; ii < isa_count; ii++) {
        sl_raster *r = make(W, H, isa_list[ii], SL_RASTER_DEPTH_LINEAR_Z, 1);
        for (int n = 0; n < rounds; n++) {
            float p[9];
            random_tri(&rng, W, H, n % 3, p);
            uint32_t ix[3] = {0, 1, 2};
            ref_tri t;
            assert_true(ref_setup(r, IDENTITY, p, &t));
            sl_raster_clear(r);
            render(r, p, 3, ix, 1, IDENTITY, SL_RASTER_CULL_NONE);
            float *img = depth_image(r);
            for (int j = 0; j < H; j++)
                for (int i = 0; i < W; i++) {
                    bool cov = ref_covers(&t, i, j);
                    float b = img[j * W + i];
                    if (cov != (b > 0.0f))
                        fail_msg("isa %s triangle %d pixel (%d,%d): reference %d, buffer %g",
                                 sl_raster_isa_name(isa_list[ii]), n, i, j, cov, (double)b);
                    /* the reference's own double rounding: 1e-12 */
                    if (cov && (double)b > ref_depth(&t, i, j) + 1e-12)
                        fail_msg("pixel (%d,%d): depth %.17g nearer than true %.17g (d %g %g %g)", i, j, (double)b,
                                 ref_depth(&t, i, j), t.d[0], t.d[1], t.d[2]);
                }
            free(img);
        }
        sl_raster_destroy(r);
    }
}

/* Many triangles: no pixel claims coverage no triangle has, and no depth is nearer than the
 * nearest triangle covering the pixel. */
static void test_soup_conservative(void **state)
{
    (void)state;
    const int W = 128, H = 72;
    int count = sanitized() ? 150 : 1500;
    sl_rng rng;
    sl_rng_seed(&rng, 7, 3);
    float *v = malloc(sizeof(float) * 9 * (size_t)count);
    uint32_t *ix = malloc(sizeof(uint32_t) * 3 * (size_t)count);
    double *truth = malloc(sizeof(double) * W * H);
    assert_true(v && ix && truth);
    for (int n = 0; n < count; n++) {
        random_tri(&rng, W, H, n % 3, v + 9 * n);
        for (int k = 0; k < 3; k++)
            ix[3 * n + k] = (uint32_t)(3 * n + k);
    }
    sl_raster *r = make(W, H, SL_RASTER_ISA_AUTO, SL_RASTER_DEPTH_LINEAR_Z, 1);
    for (int i = 0; i < W * H; i++)
        truth[i] = 0.0;
    for (int n = 0; n < count; n++) {
        ref_tri t;
        assert_true(ref_setup(r, IDENTITY, v + 9 * n, &t));
        for (int j = 0; j < H; j++)
            for (int i = 0; i < W; i++)
                if (ref_covers(&t, i, j))
                    truth[j * W + i] = fmax(truth[j * W + i], ref_depth(&t, i, j));
    }
    render(r, v, (uint32_t)(3 * count), ix, (uint32_t)count, IDENTITY, SL_RASTER_CULL_NONE);
    float *img = depth_image(r);
    size_t covered = 0, truly = 0;
    for (int i = 0; i < W * H; i++) {
        assert_true((double)img[i] <= truth[i] + 1e-12);
        covered += img[i] > 0.0f;
        truly += truth[i] > 0.0;
    }
    /* and it is not trivially conservative: most covered pixels hold a depth */
    assert_true(covered >= truly * 9 / 10);
    free(img);
    free(truth);
    free(v);
    free(ix);
    sl_raster_destroy(r);
}

/* A quad of two triangles sharing a diagonal through pixel centres covers its region without a
 * crack: a box behind it is occluded, one in front is visible. */
static void test_shared_edge_watertight(void **state)
{
    (void)state;
    const int W = 128, H = 64;
    for (int ii = 0; ii < isa_count; ii++) {
        sl_raster *r = make(W, H, isa_list[ii], SL_RASTER_DEPTH_LINEAR_Z, 1);
        /* pixel corners (8.5, 4.5) .. (100.5, 60.5): every diagonal crossing is at a centre */
        float x0 = 8.5f / 64 - 1, x1 = 100.5f / 64 - 1, y0 = 1 - 4.5f / 32, y1 = 1 - 60.5f / 32;
        float quad[12] = {x0, y0, 0.2f, x1, y0, 0.2f, x1, y1, 0.2f, x0, y1, 0.2f};
        uint32_t ix[6] = {0, 1, 2, 0, 2, 3};
        render(r, quad, 4, ix, 2, IDENTITY, SL_RASTER_CULL_NONE);
        float *img = depth_image(r);
        /* centres on the left/top edges (column 8, row 4) belong to the quad, those on the
         * right/bottom edges (column 100, row 60) do not; the diagonal leaves no crack */
        for (int j = 0; j < H; j++)
            for (int i = 0; i < W; i++) {
                bool inside = i >= 8 && i <= 99 && j >= 4 && j <= 59;
                if (inside != (img[j * W + i] > 0.0f))
                    fail_msg("%s: pixel (%d,%d) expected %d", sl_raster_isa_name(isa_list[ii]), i, j, inside);
            }
        free(img);
        float dq = 0.5f - 0.5f * 0.2f; /* the quad's depth */
        assert_int_equal(sl_raster_test_rect(r, 8, 4, 100, 60, dq - 0.01f), SL_RASTER_OCCLUDED);
        assert_int_equal(sl_raster_test_rect(r, 8, 4, 100, 60, dq + 0.01f), SL_RASTER_VISIBLE);
        assert_int_equal(sl_raster_test_rect(r, 8, 4, 101, 60, dq - 0.01f), SL_RASTER_VISIBLE);
        assert_int_equal(sl_raster_test_rect(r, 7, 4, 100, 60, dq - 0.01f), SL_RASTER_VISIBLE);
        /* a box behind the quad, projected to the same pixels, is hidden */
        float bmin[3] = {x0, y1, 0.5f}, bmax[3] = {x1, y0, 0.6f};
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, IDENTITY), SL_RASTER_VISIBLE); /* touches col 100 */
        float imin[3] = {x0 + 0.02f, y1 + 0.04f, 0.5f}, imax[3] = {x1 - 0.04f, y0 - 0.04f, 0.6f};
        assert_int_equal(sl_raster_test_aabb(r, imin, imax, IDENTITY), SL_RASTER_OCCLUDED);
        sl_raster_destroy(r);
    }
}

/* Adjacent triangles of a fan meeting at one vertex: each pixel covered exactly once. */
static void test_no_double_coverage(void **state)
{
    (void)state;
    const int W = 64, H = 64;
    sl_raster *r = make(W, H, SL_RASTER_ISA_SCALAR, SL_RASTER_DEPTH_LINEAR_Z, 1);
    sl_rng rng;
    sl_rng_seed(&rng, 11, 1);
    for (int round = 0; round < 20; round++) {
        /* a fan around a centre (grid-aligned to hit ties) */
        int n = 3 + (int)sl_rng_below(&rng, 8);
        float pts[3 * 12];
        float cx = 32.0f + (float)sl_rng_below(&rng, 8) * 0.5f, cy = 32.0f - (float)sl_rng_below(&rng, 8) * 0.5f;
        for (int k = 0; k < n; k++) {
            double ang = 2 * M_PI * k / n + 0.1 * round;
            float px = roundf((float)(cx + 40 * cos(ang)) * 2) / 2, py = roundf((float)(cy + 40 * sin(ang)) * 2) / 2;
            pts[3 * k] = px / 32 - 1, pts[3 * k + 1] = 1 - py / 32, pts[3 * k + 2] = 0;
        }
        float c[3] = {cx / 32 - 1, 1 - cy / 32, 0};
        int cover[64 * 64] = {0};
        for (int k = 0; k < n; k++) {
            float tri[9] = {c[0], c[1], c[2]};
            memcpy(tri + 3, pts + 3 * k, sizeof(float) * 3);
            memcpy(tri + 6, pts + 3 * ((k + 1) % n), sizeof(float) * 3);
            uint32_t ix[3] = {0, 1, 2};
            sl_raster_clear(r);
            render(r, tri, 3, ix, 1, IDENTITY, SL_RASTER_CULL_NONE);
            float *img = depth_image(r);
            for (int i = 0; i < W * H; i++)
                cover[i] += img[i] > 0.0f;
            free(img);
        }
        for (int i = 0; i < W * H; i++)
            assert_true(cover[i] <= 1);
        /* pixels well inside the fan's hull are covered once */
        for (int j = 28; j < 36; j++)
            for (int i = 28; i < 36; i++)
                assert_int_equal(cover[j * W + i], 1);
    }
    sl_raster_destroy(r);
}

/* Triangles far bigger than the screen (guard-band clipping) cover everything, conservatively. */
static void test_huge_triangles(void **state)
{
    (void)state;
    const int W = 160, H = 90;
    for (int ii = 0; ii < isa_count; ii++) {
        sl_raster *r = make(W, H, isa_list[ii], SL_RASTER_DEPTH_LINEAR_Z, 1);
        float tri[9] = {-1e4f, -1e4f, 0.5f, 3e4f, -1e4f, 0.5f, -1e4f, 3e4f, 0.5f};
        uint32_t ix[3] = {0, 1, 2};
        render(r, tri, 3, ix, 1, IDENTITY, SL_RASTER_CULL_NONE);
        sl_raster_stats st;
        sl_raster_get_stats(r, &st);
        assert_int_equal(st.clipped, 1);
        float *img = depth_image(r);
        for (int i = 0; i < W * H; i++) {
            assert_true(img[i] > 0.0f);
            assert_true(img[i] <= 0.25f); /* the true depth is 0.5 - 0.5*0.5 = 0.25 */
            assert_true(img[i] > 0.2499f);
        }
        free(img);
        assert_int_equal(sl_raster_test_rect(r, 0, 0, W, H, 0.2f), SL_RASTER_OCCLUDED);
        /* a huge tilted triangle: depth still never nearer than the plane */
        sl_raster_clear(r);
        float tilt[9] = {-5e3f, -5e3f, -0.9f, 5e3f, -5e3f, 0.9f, 0.0f, 5e3f, 0.0f};
        render(r, tilt, 3, ix, 1, IDENTITY, SL_RASTER_CULL_NONE);
        img = depth_image(r);
        /* z(x, y) of the plane through the three points, in NDC */
        double ax = (0.9 - -0.9) / 1e4, ay = (0.0 - 0.0 - ax * 5e3) / 1e4;
        for (int j = 0; j < H; j++)
            for (int i = 0; i < W; i++) {
                double nx = (i + 0.5) / (W / 2.0) - 1, ny = 1 - (j + 0.5) / (H / 2.0);
                double z = -0.9 + ax * (nx + 5e3) + ay * (ny + 5e3);
                double d = 0.5 - 0.5 * z;
                assert_true(img[j * W + i] > 0.0f);
                assert_true((double)img[j * W + i] <= d + 1e-6);
            }
        free(img);
        sl_raster_destroy(r);
    }
}

/* Perspective triangles crossing the near plane: clipped, every covered pixel is really covered
 * by the part in front of the near plane, at a depth no nearer than the true one. */
static void test_near_plane_crossing(void **state)
{
    (void)state;
    const int W = 128, H = 96;
    const double N = 0.5, F = 100, fovy = 1.2, aspect = (double)W / H;
    float P[16];
    perspective(P, fovy, aspect, N, F);
    sl_rng rng;
    sl_rng_seed(&rng, 5, 5);
    int rounds = sanitized() ? 20 : 120;
    for (int ii = 0; ii < isa_count; ii++) {
        sl_raster *r = make(W, H, isa_list[ii], SL_RASTER_DEPTH_INV_W, 1);
        int clipped = 0, covered_total = 0;
        for (int n = 0; n < rounds; n++) {
            /* eye space: one vertex behind the camera or between it and the near plane */
            double p[3][3];
            for (int k = 0; k < 3; k++) {
                double z = k == 0 ? sl_rng_range(&rng, -0.4f, 3.0f) : sl_rng_range(&rng, -20.0f, -1.0f);
                p[k][0] = sl_rng_range(&rng, -1, 1) * fabs(z) + sl_rng_range(&rng, -1, 1);
                p[k][1] = sl_rng_range(&rng, -1, 1) * fabs(z) + sl_rng_range(&rng, -1, 1);
                p[k][2] = z;
            }
            float v[9];
            for (int k = 0; k < 9; k++)
                v[k] = (float)p[k / 3][k % 3];
            uint32_t ix[3] = {0, 1, 2};
            sl_raster_clear(r);
            render(r, v, 3, ix, 1, P, SL_RASTER_CULL_NONE);
            sl_raster_stats st;
            sl_raster_get_stats(r, &st);
            clipped += (int)st.clipped;
            float *img = depth_image(r);
            double e1[3], e2[3], nrm[3];
            for (int k = 0; k < 3; k++)
                e1[k] = p[1][k] - p[0][k], e2[k] = p[2][k] - p[0][k];
            nrm[0] = e1[1] * e2[2] - e1[2] * e2[1];
            nrm[1] = e1[2] * e2[0] - e1[0] * e2[2];
            nrm[2] = e1[0] * e2[1] - e1[1] * e2[0];
            double tx = tan(0.5 * fovy) * aspect, ty = tan(0.5 * fovy);
            /* the part beyond the near plane (z <= -N), projected to the screen, in double */
            double poly[8][2];
            int np = 0;
            for (int k = 0; k < 3; k++) {
                const double *a = p[k], *bb = p[(k + 1) % 3];
                double da = -N - a[2], db = -N - bb[2];
                double q[3];
                if (da >= 0) {
                    poly[np][0] = (a[0] / -a[2] / tx + 1) * W / 2, poly[np][1] = (1 - a[1] / -a[2] / ty) * H / 2;
                    np++;
                }
                if ((da >= 0) != (db >= 0)) {
                    double s = da / (da - db);
                    for (int c = 0; c < 3; c++)
                        q[c] = a[c] + s * (bb[c] - a[c]);
                    poly[np][0] = (q[0] / N / tx + 1) * W / 2, poly[np][1] = (1 - q[1] / N / ty) * H / 2;
                    np++;
                }
            }
            double area = 0;
            for (int k = 0; k < np; k++)
                area += poly[k][0] * poly[(k + 1) % np][1] - poly[(k + 1) % np][0] * poly[k][1];
            for (int j = 0; j < H; j++)
                for (int i = 0; i < W; i++) {
                    float b = img[j * W + i];
                    if (!(b > 0.0f))
                        continue;
                    /* inside the projected polygon, up to the 1/256-pixel snap (checked at 1/50) */
                    double cx = i + 0.5, cy = j + 0.5;
                    for (int k = 0; k < np; k++) {
                        const double *a = poly[k], *bb = poly[(k + 1) % np];
                        double ex = bb[0] - a[0], ey = bb[1] - a[1];
                        double side = (ex * (cy - a[1]) - ey * (cx - a[0])) * (area > 0 ? 1 : -1);
                        if (side / sqrt(ex * ex + ey * ey) < -0.02)
                            fail_msg("%s round %d: pixel (%d,%d) covered, %g px outside the visible triangle",
                                     sl_raster_isa_name(isa_list[ii]), n, i, j, side / sqrt(ex * ex + ey * ey));
                    }
                    /* depth: 1/w where the pixel's ray meets the triangle's plane */
                    double dir[3] = {(cx / (W / 2.0) - 1) * tx, (1 - cy / (H / 2.0)) * ty, -1};
                    double den = nrm[0] * dir[0] + nrm[1] * dir[1] + nrm[2] * dir[2];
                    double s = (nrm[0] * p[0][0] + nrm[1] * p[0][1] + nrm[2] * p[0][2]) / den;
                    double true_d = 1.0 / s;
                    if ((double)b > true_d * (1 + 1e-5))
                        fail_msg("pixel (%d,%d): depth %g nearer than true %g", i, j, (double)b, true_d);
                    covered_total++;
                }
            free(img);
        }
        assert_true(clipped > rounds / 2);
        assert_true(covered_total > 20 * rounds);
        sl_raster_destroy(r);
    }
}

/* NaN/Inf vertices, bad indices and zero-area triangles are skipped and counted; bad arguments
 * fail without touching the buffer. */
static void test_bad_input(void **state)
{
    (void)state;
    sl_raster *r = make(64, 64, SL_RASTER_ISA_AUTO, SL_RASTER_DEPTH_LINEAR_Z, 1);
    float v[] = {-0.5f, -0.5f, 0, 0.5f, -0.5f, 0, 0, 0.5f, 0, NAN, 0, 0, INFINITY, 1, 0, 0.1f, 0.1f, 0, 0.2f, 0.2f, 0};
    uint32_t ix[] = {0, 1, 3, 0, 4, 2, 0, 1, 9, 0, 5, 6, 0, 0, 1, 3, 3, 3};
    render(r, v, 7, ix, 6, IDENTITY, SL_RASTER_CULL_NONE);
    sl_raster_stats st;
    sl_raster_get_stats(r, &st);
    assert_int_equal(st.triangles_submitted, 6);
    assert_int_equal(st.rejected_nonfinite, 3);
    assert_int_equal(st.rejected_index, 1);
    assert_int_equal(st.degenerate, 2);
    assert_int_equal(st.triangles_rasterized, 0);
    float *img = depth_image(r);
    for (int i = 0; i < 64 * 64; i++)
        assert_true(img[i] == 0.0f);
    free(img);
    sl_error err;
    float badm[16];
    memcpy(badm, IDENTITY, sizeof badm);
    badm[5] = NAN;
    assert_int_equal(sl_raster_render_triangles(r, v, 7, ix, 1, 12, badm, SL_RASTER_CULL_NONE, &err),
                     SL_ERROR_INVALID_ARGUMENT);
    assert_non_null(strstr(err.message, "matrix element 5"));
    assert_int_equal(sl_raster_render_triangles(r, v, 7, ix, 1, 8, IDENTITY, SL_RASTER_CULL_NONE, &err),
                     SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_raster_render_triangles(r, v, 7, ix, 1, 14, IDENTITY, SL_RASTER_CULL_NONE, &err),
                     SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_raster_render_triangles(r, NULL, 7, ix, 1, 12, IDENTITY, SL_RASTER_CULL_NONE, &err),
                     SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_raster_render_triangles(r, v, 7, ix, 1, 12, IDENTITY, (sl_raster_backface)7, &err),
                     SL_ERROR_INVALID_ARGUMENT);
    assert_int_equal(sl_raster_render_triangles(r, NULL, 0, NULL, 0, 12, IDENTITY, SL_RASTER_CULL_NONE, &err), SL_OK);
    img = depth_image(r);
    for (int i = 0; i < 64 * 64; i++)
        assert_true(img[i] == 0.0f);
    free(img);
    /* coordinates near the float limit: clipping must not blow up (rejected or clipped) */
    float big[] = {3e38f, 3e38f, 0, -3e38f, 3e38f, 0, 0, -3e38f, 0};
    uint32_t ix3[] = {0, 1, 2};
    render(r, big, 3, ix3, 1, IDENTITY, SL_RASTER_CULL_NONE);
    sl_raster_get_stats(r, &st);
    assert_int_equal(st.triangles_submitted, 7);
    img = depth_image(r);
    for (int i = 0; i < 64 * 64; i++)
        assert_true(img[i] == 0.0f || img[i] <= 0.5f);
    free(img);
    /* bad options */
    sl_raster_options o = sl_raster_default_options(0, 10);
    sl_raster *x = NULL;
    assert_int_equal(sl_raster_create(&o, NULL, &x, &err), SL_ERROR_INVALID_ARGUMENT);
    o = sl_raster_default_options(10000, 10);
    assert_int_equal(sl_raster_create(&o, NULL, &x, &err), SL_ERROR_INVALID_ARGUMENT);
    o = sl_raster_default_options(64, 64);
    o.near_w = -1;
    assert_int_equal(sl_raster_create(&o, NULL, &x, &err), SL_ERROR_INVALID_ARGUMENT);
    o = sl_raster_default_options(64, 64);
    o.bins_x = 3; /* 64 pixels are 2 tiles wide */
    assert_int_equal(sl_raster_create(&o, NULL, &x, &err), SL_ERROR_INVALID_ARGUMENT);
    assert_null(x);
    sl_raster_destroy(r);
}

/* Back-face modes follow OpenGL's winding in NDC. */
static void test_backface(void **state)
{
    (void)state;
    sl_raster *r = make(64, 64, SL_RASTER_ISA_AUTO, SL_RASTER_DEPTH_LINEAR_Z, 1);
    float ccw[9] = {-0.5f, -0.5f, 0, 0.5f, -0.5f, 0, 0, 0.5f, 0}; /* counter-clockwise in NDC */
    uint32_t ix[3] = {0, 1, 2}, rev[3] = {0, 2, 1};
    render(r, ccw, 3, ix, 1, IDENTITY, SL_RASTER_CULL_CCW);
    assert_int_equal(sl_raster_test_rect(r, 30, 30, 34, 34, 0.4f), SL_RASTER_VISIBLE);
    render(r, ccw, 3, ix, 1, IDENTITY, SL_RASTER_CULL_CW);
    assert_int_equal(sl_raster_test_rect(r, 30, 30, 34, 34, 0.4f), SL_RASTER_OCCLUDED);
    sl_raster_clear(r);
    render(r, ccw, 3, rev, 1, IDENTITY, SL_RASTER_CULL_CW);
    assert_int_equal(sl_raster_test_rect(r, 30, 30, 34, 34, 0.4f), SL_RASTER_VISIBLE);
    render(r, ccw, 3, rev, 1, IDENTITY, SL_RASTER_CULL_NONE);
    assert_int_equal(sl_raster_test_rect(r, 30, 30, 34, 34, 0.4f), SL_RASTER_OCCLUDED);
    sl_raster_stats st;
    sl_raster_get_stats(r, &st);
    assert_int_equal(st.culled_backface, 1);
    sl_raster_destroy(r);
}

/* A wall in a perspective view and boxes around it. */
static void test_queries_perspective(void **state)
{
    (void)state;
    const int W = 320, H = 180;
    float P[16];
    perspective(P, 1.0, (double)W / H, 0.1, 1000);
    for (int ii = 0; ii < isa_count; ii++) {
        sl_raster *r = make(W, H, isa_list[ii], SL_RASTER_DEPTH_INV_W, 1);
        /* wall: x in [-10, 10], y in [-6, 6] at z = -10 (covers the middle of the view) */
        float wall[12] = {-5, -3, -10, 5, -3, -10, 5, 3, -10, -5, 3, -10};
        uint32_t ix[6] = {0, 1, 2, 0, 2, 3};
        render(r, wall, 4, ix, 2, P, SL_RASTER_CULL_NONE);
        float bmin[3], bmax[3];
#define BOX(a, b, c, d, e, f) (bmin[0] = a, bmin[1] = b, bmin[2] = c, bmax[0] = d, bmax[1] = e, bmax[2] = f)
        BOX(-1, -1, -30, 1, 1, -20); /* behind the wall */
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, P), SL_RASTER_OCCLUDED);
        BOX(-1, -1, -9, 1, 1, -8); /* in front */
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, P), SL_RASTER_VISIBLE);
        BOX(-1, -1, -10.5f, 1, 1, -9.5f); /* through the wall */
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, P), SL_RASTER_VISIBLE);
        BOX(4, -1, -30, 14, 1, -20); /* partly behind, partly beside */
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, P), SL_RASTER_VISIBLE);
        BOX(-1, -1, 2, 1, 1, 4); /* behind the camera */
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, P), SL_RASTER_OUTSIDE);
        BOX(-1, -1, -1, 1, 1, 1); /* around the camera */
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, P), SL_RASTER_VISIBLE);
        BOX(-1, -1, -2000, 1, 1, -1500); /* beyond the far plane */
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, P), SL_RASTER_OUTSIDE);
        BOX(500, -1, -30, 510, 1, -20); /* beside the frustum */
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, P), SL_RASTER_OUTSIDE);
        BOX(NAN, -1, -30, 1, 1, -20);
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, P), SL_RASTER_VISIBLE);
        /* meshes: a small quad behind the wall, the same in front, one beside */
        float q[12] = {-1, -1, -20, 1, -1, -20, 1, 1, -20, -1, 1, -20};
        assert_int_equal(sl_raster_test_triangles(r, q, 4, ix, 2, 12, P, SL_RASTER_CULL_NONE), SL_RASTER_OCCLUDED);
        for (int k = 0; k < 4; k++)
            q[3 * k + 2] = -5;
        assert_int_equal(sl_raster_test_triangles(r, q, 4, ix, 2, 12, P, SL_RASTER_CULL_NONE), SL_RASTER_VISIBLE);
        float side[12] = {100, -1, -20, 102, -1, -20, 102, 1, -20, 100, 1, -20};
        assert_int_equal(sl_raster_test_triangles(r, side, 4, ix, 2, 12, P, SL_RASTER_CULL_NONE), SL_RASTER_OUTSIDE);
        /* a mesh crossing the near plane: the part beyond it, in front of the wall, is visible */
        float cross[9] = {-1, -1, 1, 1, -1, -5, 0, 1, -5};
        uint32_t i3[3] = {0, 1, 2};
        assert_int_equal(sl_raster_test_triangles(r, cross, 3, i3, 1, 12, P, SL_RASTER_CULL_NONE), SL_RASTER_VISIBLE);
        /* a sliver mesh behind the wall (degenerate after snapping) is still tested */
        float sliver[9] = {0, 0, -20, 0.0001f, 0, -20, 0, 0.00001f, -20};
        assert_int_equal(sl_raster_test_triangles(r, sliver, 3, i3, 1, 12, P, SL_RASTER_CULL_NONE),
                         SL_RASTER_OCCLUDED);
        sliver[2] = sliver[5] = sliver[8] = -2;
        assert_int_equal(sl_raster_test_triangles(r, sliver, 3, i3, 1, 12, P, SL_RASTER_CULL_NONE),
                         SL_RASTER_VISIBLE);
        uint32_t badix[3] = {0, 1, 7};
        assert_int_equal(sl_raster_test_triangles(r, q, 4, badix, 1, 12, P, SL_RASTER_CULL_NONE), SL_RASTER_VISIBLE);
        /* rectangles */
        assert_int_equal(sl_raster_test_rect(r, -10, -10, -1, -1, 0.01f), SL_RASTER_OUTSIDE);
        assert_int_equal(sl_raster_test_rect(r, 150, 80, 160, 90, NAN), SL_RASTER_VISIBLE);
        assert_int_equal(sl_raster_test_rect(r, 150, 80, 160, 90, -1.0f), SL_RASTER_OUTSIDE);
        assert_int_equal(sl_raster_test_rect(r, 150, 80, 160, 90, 0.05f), SL_RASTER_OCCLUDED);
        assert_int_equal(sl_raster_test_rect(r, 150, 80, 160, 90, 0.2f), SL_RASTER_VISIBLE);
        assert_int_equal(sl_raster_test_rect(r, 0, 0, 5, 5, 0.0001f), SL_RASTER_VISIBLE); /* empty corner */
        sl_raster_destroy(r);
    }
}

/* A full-screen occluder hides everything behind it (tightness). */
static void test_full_screen_tight(void **state)
{
    (void)state;
    const int W = 1920 / 4, H = 1080 / 4;
    float P[16];
    perspective(P, 1.0, (double)W / H, 0.1, 1000);
    sl_raster *r = make(W, H, SL_RASTER_ISA_AUTO, SL_RASTER_DEPTH_INV_W, 1);
    float wall[12] = {-100, -60, -10, 100, -60, -10, 100, 60, -10, -100, 60, -10};
    uint32_t ix[6] = {0, 1, 2, 0, 2, 3};
    render(r, wall, 4, ix, 2, P, SL_RASTER_CULL_NONE);
    assert_int_equal(sl_raster_test_rect(r, 0, 0, W, H, 1.0f / 10.01f), SL_RASTER_OCCLUDED);
    sl_rng rng;
    sl_rng_seed(&rng, 3, 3);
    for (int n = 0; n < 200; n++) {
        float bmin[3] = {sl_rng_range(&rng, -8, 8), sl_rng_range(&rng, -4, 4), sl_rng_range(&rng, -200, -10.05f)};
        float bmax[3] = {bmin[0] + sl_rng_range(&rng, 0, 3), bmin[1] + sl_rng_range(&rng, 0, 3), -10.02f};
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, P), SL_RASTER_OCCLUDED);
    }
    sl_raster_tile_info ti;
    assert_int_equal(sl_raster_get_tile_info(r, 3, 3, &ti, NULL), SL_OK);
    assert_int_equal(ti.covered_pixels, 256);
    assert_int_equal(ti.full_subtiles, 8);
    uint32_t tx, ty;
    sl_raster_get_size(r, NULL, NULL, &tx, &ty);
    float *sub = malloc(sizeof(float) * tx * 4 * ty * 2);
    assert_non_null(sub);
    assert_int_equal(sl_raster_read_subtile_depth(r, sub, (size_t)tx * 4 * ty * 2, NULL), SL_OK);
    for (size_t i = 0; i < (size_t)tx * 4 * ty * 2; i++)
        assert_true(sub[i] > 0.0999f && sub[i] <= 0.1f);
    free(sub);
    sl_raster_destroy(r);
}

/* Orthographic projection (LINEAR_Z depth): walls and boxes; geometry behind the camera is
 * clipped by the near plane and occludes nothing. */
static void test_orthographic(void **state)
{
    (void)state;
    const int W = 200, H = 100;
    float O[16];
    orthographic(O, 20, 10, 1, 101);
    for (int ii = 0; ii < isa_count; ii++) {
        sl_raster *r = make(W, H, isa_list[ii], SL_RASTER_DEPTH_LINEAR_Z, 1);
        float wall[12] = {-5, -5, -50, 5, -5, -50, 5, 5, -50, -5, 5, -50};
        uint32_t ix[6] = {0, 1, 2, 0, 2, 3};
        render(r, wall, 4, ix, 2, O, SL_RASTER_CULL_NONE);
        float bmin[3] = {-2, -2, -80}, bmax[3] = {2, 2, -60};
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, O), SL_RASTER_OCCLUDED);
        bmin[2] = -40, bmax[2] = -30;
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, O), SL_RASTER_VISIBLE);
        bmin[0] = 4, bmax[0] = 8, bmin[2] = -80, bmax[2] = -60;
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, O), SL_RASTER_VISIBLE);
        /* orthographic depth is linear: the wall sits at d = 1 - (50 - 1)/100 */
        float *img = depth_image(r);
        float d = img[50 * W + 100];
        assert_true(d <= 0.51f && d > 0.5099f);
        free(img);
        /* a wall behind the camera and one crossing the near plane */
        sl_raster_clear(r);
        float behind[12] = {-15, -8, 5, 15, -8, 5, 15, 8, 5, -15, 8, 5};
        render(r, behind, 4, ix, 2, O, SL_RASTER_CULL_NONE);
        float crossing[12] = {-15, -8, 5, 15, -8, 5, 15, 8, -20, -15, 8, -20};
        render(r, crossing, 4, ix, 2, O, SL_RASTER_CULL_NONE);
        /* the crossing wall occludes only what lies behind its part beyond the near plane */
        bmin[0] = -2, bmax[0] = 2, bmin[1] = -2, bmax[1] = 2, bmin[2] = -90, bmax[2] = -80;
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, O), SL_RASTER_OCCLUDED);
        bmin[1] = -9.5f, bmax[1] = -9, bmin[2] = -3, bmax[2] = -2;
        assert_int_equal(sl_raster_test_aabb(r, bmin, bmax, O), SL_RASTER_VISIBLE);
        sl_raster_stats st;
        sl_raster_get_stats(r, &st);
        assert_int_equal(st.culled_outside, 2);
        assert_int_equal(st.clipped, 2);
        sl_raster_destroy(r);
    }
}

/* A random scene with clipping, huge, sliver and tie cases in a perspective view. */
static void random_scene(sl_rng *rng, int count, float **pv, uint32_t **pix, uint32_t *nv)
{
    float *v = malloc(sizeof(float) * 9 * (size_t)count);
    uint32_t *ix = malloc(sizeof(uint32_t) * 3 * (size_t)count);
    assert_true(v && ix);
    for (int n = 0; n < count; n++) {
        int kind = (int)sl_rng_below(rng, 10);
        /* back to front on average, so that merges of every kind happen */
        float zc = -60.0f + 55.0f * (float)n / (float)count + sl_rng_range(rng, -5, 5);
        float size = kind < 6 ? sl_rng_range(rng, 0.05f, 3) : (kind < 8 ? sl_rng_range(rng, 5, 80) : 400);
        float cx = sl_rng_range(rng, -1, 1) * -zc * 0.8f, cy = sl_rng_range(rng, -1, 1) * -zc * 0.5f;
        for (int k = 0; k < 3; k++) {
            v[9 * n + 3 * k + 0] = cx + sl_rng_range(rng, -size, size);
            v[9 * n + 3 * k + 1] = cy + sl_rng_range(rng, -size, size);
            v[9 * n + 3 * k + 2] = kind == 9 && k == 0 ? sl_rng_range(rng, -1, 5) : zc + sl_rng_range(rng, -2, 2);
        }
        if (kind == 5) { /* sliver */
            float t = sl_rng_range(rng, 0, 1);
            for (int c = 0; c < 3; c++)
                v[9 * n + 6 + c] = v[9 * n + c] + t * (v[9 * n + 3 + c] - v[9 * n + c]) + sl_rng_range(rng, -1e-3f, 1e-3f);
        }
        for (int k = 0; k < 3; k++)
            ix[3 * n + k] = (uint32_t)(3 * n + k);
    }
    *pv = v, *pix = ix, *nv = (uint32_t)(3 * count);
}

/* Every instruction-set path leaves the same bits in the buffer and answers queries the same. */
static void test_isa_bit_identical(void **state)
{
    (void)state;
    const int W = 256, H = 144;
    int count = sanitized() ? 400 : 4000;
    float P[16];
    perspective(P, 1.1, (double)W / H, 0.3, 500);
    sl_rng rng;
    sl_rng_seed(&rng, 42, 9);
    float *v;
    uint32_t *ix, nv;
    random_scene(&rng, count, &v, &ix, &nv);
    for (int cov = 0; cov < 2; cov++) {
        sl_raster *ref = NULL;
        for (int ii = 0; ii < isa_count; ii++) {
            sl_raster_options o = sl_raster_default_options(W, H);
            o.isa = isa_list[ii];
            o.coverage = cov ? SL_RASTER_COVERAGE_INNER : SL_RASTER_COVERAGE_CENTER;
            sl_raster *r;
            assert_int_equal(sl_raster_create(&o, NULL, &r, NULL), SL_OK);
            assert_int_equal(sl_raster_get_isa(r), isa_list[ii]);
            for (int part = 0; part < 4; part++)
                render(r, v + 9 * (count / 4) * part, nv - 9 * (uint32_t)(count / 4) * (uint32_t)part / 3, ix,
                       (uint32_t)(count / 4), P, SL_RASTER_CULL_NONE);
            if (!ref) {
                ref = r;
                continue;
            }
            assert_same_buffer(ref, r);
            /* queries: random rectangles, boxes and small meshes */
            sl_rng q;
            sl_rng_seed(&q, 77, 1);
            for (int n = 0; n < 300; n++) {
                int32_t x0 = (int32_t)sl_rng_below(&q, W + 20) - 10, y0 = (int32_t)sl_rng_below(&q, H + 20) - 10;
                int32_t x1 = x0 + (int32_t)sl_rng_below(&q, 120), y1 = y0 + (int32_t)sl_rng_below(&q, 60);
                float d = sl_rng_range(&q, 0, 0.2f);
                assert_int_equal(sl_raster_test_rect(ref, x0, y0, x1, y1, d), sl_raster_test_rect(r, x0, y0, x1, y1, d));
                float bmin[3] = {sl_rng_range(&q, -30, 30), sl_rng_range(&q, -20, 20), sl_rng_range(&q, -80, -1)};
                float bmax[3] = {bmin[0] + sl_rng_range(&q, 0, 5), bmin[1] + sl_rng_range(&q, 0, 5),
                                 bmin[2] + sl_rng_range(&q, 0, 5)};
                assert_int_equal(sl_raster_test_aabb(ref, bmin, bmax, P), sl_raster_test_aabb(r, bmin, bmax, P));
                const float *tri = v + 9 * sl_rng_below(&q, (uint32_t)count);
                float moved[9];
                for (int k = 0; k < 9; k++)
                    moved[k] = tri[k] * (k % 3 == 2 ? 1.3f : 1.0f);
                uint32_t i3[3] = {0, 1, 2};
                assert_int_equal(sl_raster_test_triangles(ref, moved, 3, i3, 1, 12, P, SL_RASTER_CULL_NONE),
                                 sl_raster_test_triangles(r, moved, 3, i3, 1, 12, P, SL_RASTER_CULL_NONE));
            }
            sl_raster_destroy(r);
        }
        sl_raster_destroy(ref);
    }
    free(v);
    free(ix);
}

/* Hostile geometry: magnitudes from 1e-30 to 1e30, w near zero or negative, random matrices.
 * Nothing may crash, every path must agree, and every depth stays finite and non-negative. */
static void test_extreme_inputs(void **state)
{
    (void)state;
    const int W = 96, H = 64;
    int count = sanitized() ? 300 : 3000;
    sl_rng rng;
    sl_rng_seed(&rng, 666, 6);
    float *v = malloc(sizeof(float) * 9 * (size_t)count);
    uint32_t *ix = malloc(sizeof(uint32_t) * 3 * (size_t)count);
    assert_true(v && ix);
    for (int n = 0; n < 9 * count; n++) {
        float mag = powf(10.0f, sl_rng_range(&rng, -30, 30));
        v[n] = sl_rng_below(&rng, 4) == 0 ? sl_rng_range(&rng, -2, 2) : mag * sl_rng_range(&rng, -1, 1);
    }
    for (int n = 0; n < 3 * count; n++)
        ix[n] = (uint32_t)n;
    float m[4][16];
    for (int k = 0; k < 4; k++)
        for (int e = 0; e < 16; e++)
            m[k][e] = sl_rng_range(&rng, -2, 2) * (sl_rng_below(&rng, 3) == 0 ? 1e-6f : 1.0f);
    sl_raster *ref = NULL;
    for (int ii = 0; ii < isa_count; ii++) {
        for (int depth = 0; depth < 2; depth++) {
            sl_raster *r = make(W, H, isa_list[ii], (sl_raster_depth)depth, 1);
            for (int k = 0; k < 4; k++)
                render(r, v, (uint32_t)(3 * count), ix, (uint32_t)count, m[k], SL_RASTER_CULL_NONE);
            float *img = depth_image(r);
            for (int i = 0; i < W * H; i++)
                assert_true(isfinite(img[i]) && img[i] >= 0.0f);
            free(img);
            sl_raster_stats st;
            sl_raster_get_stats(r, &st);
            /* the input reaches every branch: rendered, clipped, rejected, outside */
            assert_true(st.triangles_rasterized > 0 && st.clipped > 0 && st.culled_outside > 0);
            if (depth == 1) {
                sl_raster_destroy(r);
                continue;
            }
            if (!ref)
                ref = r;
            else {
                assert_same_buffer(ref, r);
                sl_raster_destroy(r);
            }
        }
    }
    sl_raster_destroy(ref);
    free(v);
    free(ix);
}

/* INNER coverage: every covered pixel square lies inside the unsnapped triangle. */
static void test_inner_coverage(void **state)
{
    (void)state;
    const int W = 96, H = 64;
    sl_raster_options o = sl_raster_default_options(W, H);
    o.coverage = SL_RASTER_COVERAGE_INNER;
    o.depth = SL_RASTER_DEPTH_LINEAR_Z;
    sl_raster *r;
    assert_int_equal(sl_raster_create(&o, NULL, &r, NULL), SL_OK);
    sl_rng rng;
    sl_rng_seed(&rng, 9, 9);
    int rounds = sanitized() ? 50 : 300, any = 0;
    for (int n = 0; n < rounds; n++) {
        float p[9];
        random_tri(&rng, W, H, 1, p);
        uint32_t ix[3] = {0, 1, 2};
        sl_raster_clear(r);
        render(r, p, 3, ix, 1, IDENTITY, SL_RASTER_CULL_NONE);
        double sx[3], sy[3];
        for (int k = 0; k < 3; k++)
            sx[k] = ((double)p[3 * k] + 1) * W / 2, sy[k] = (1 - (double)p[3 * k + 1]) * H / 2;
        double area = (sx[1] - sx[0]) * (sy[2] - sy[0]) - (sx[2] - sx[0]) * (sy[1] - sy[0]);
        float *img = depth_image(r);
        for (int j = 0; j < H; j++)
            for (int i = 0; i < W; i++) {
                if (!(img[j * W + i] > 0.0f))
                    continue;
                any++;
                for (int cnr = 0; cnr < 4; cnr++) {
                    double px = i + (cnr & 1), py = j + (cnr >> 1);
                    for (int e = 0; e < 3; e++) {
                        int a = e, b = (e + 1) % 3;
                        double E = (sx[b] - sx[a]) * (py - sy[a]) - (sy[b] - sy[a]) * (px - sx[a]);
                        assert_true(E * area >= 0);
                    }
                }
            }
        free(img);
    }
    assert_true(any > 1000);
    sl_raster_destroy(r);
}

/* Multi-threaded rendering (pool and caller-driven bins) equals single-threaded, bit for bit. */
typedef struct bin_worker {
    sl_raster *r;
    uint32_t first, step;
    _Atomic int *done;
} bin_worker;

static void *bin_worker_main(void *p)
{
    bin_worker *w = p;
    uint32_t n = sl_raster_bin_count(w->r);
    /* render whatever is published until the front end says it is done, then a final pass */
    while (!atomic_load(w->done))
        for (uint32_t b = w->first; b < n; b += w->step)
            sl_raster_render_bin(w->r, b);
    for (uint32_t b = w->first; b < n; b += w->step)
        sl_raster_render_bin(w->r, b);
    return NULL;
}

static void test_threads_identical(void **state)
{
    (void)state;
    const int W = 320, H = 184;
    int count = sanitized() ? 1200 : 20000; /* > 16384: the pool bins in two chunks */
    float P[16];
    perspective(P, 1.1, (double)W / H, 0.3, 500);
    sl_rng rng;
    sl_rng_seed(&rng, 4242, 1);
    float *v;
    uint32_t *ix, nv;
    random_scene(&rng, count, &v, &ix, &nv);
    sl_raster *ref = make(W, H, SL_RASTER_ISA_SCALAR, SL_RASTER_DEPTH_INV_W, 1);
    render(ref, v, nv, ix, (uint32_t)count, P, SL_RASTER_CULL_CW);
    sl_raster_stats sref;
    sl_raster_get_stats(ref, &sref);
    const uint32_t threads[] = {1, 2, 4};
    for (size_t t = 0; t < SL_COUNTOF(threads); t++) {
        sl_raster_options o = sl_raster_default_options(W, H);
        o.threads = threads[t];
        o.bins_x = 3, o.bins_y = 5;
        sl_raster *r;
        assert_int_equal(sl_raster_create(&o, NULL, &r, NULL), SL_OK);
        render(r, v, nv, ix, (uint32_t)count, P, SL_RASTER_CULL_CW);
        assert_same_buffer(ref, r);
        sl_raster_stats st;
        sl_raster_get_stats(r, &st);
        assert_int_equal(st.triangles_rasterized, sref.triangles_rasterized);
        assert_int_equal(st.culled_backface, sref.culled_backface);
        /* the caller-driven bins: one front end, two renderers running at the same time */
        sl_raster_clear(r);
        _Atomic int done = 0;
        bin_worker w[2] = {{r, 0, 2, &done}, {r, 1, 2, &done}};
        pthread_t th[2];
        for (int k = 0; k < 2; k++)
            assert_int_equal(pthread_create(&th[k], NULL, bin_worker_main, &w[k]), 0);
        uint32_t chunk = (uint32_t)count / 7 + 1;
        for (uint32_t first = 0; first < (uint32_t)count; first += chunk) {
            uint32_t n = SL_MIN(chunk, (uint32_t)count - first);
            assert_int_equal(sl_raster_bin_triangles(r, v, nv, ix + 3 * first, n, 12, P, SL_RASTER_CULL_CW, NULL),
                             SL_OK);
        }
        atomic_store(&done, 1);
        for (int k = 0; k < 2; k++)
            pthread_join(th[k], NULL);
        sl_raster_flush(r); /* nothing left: a no-op beyond recycling */
        assert_same_buffer(ref, r);
        sl_raster_get_stats(r, &st);
        assert_true(st.bin_references >= st.triangles_rasterized);
        sl_raster_destroy(r);
    }
    sl_raster_destroy(ref);
    free(v);
    free(ix);
}

/* Binned triangles reach the buffer in order even when a direct render follows without flush. */
static void test_bins_then_direct(void **state)
{
    (void)state;
    sl_raster *a = make(128, 64, SL_RASTER_ISA_AUTO, SL_RASTER_DEPTH_LINEAR_Z, 1);
    sl_raster *b = make(128, 64, SL_RASTER_ISA_AUTO, SL_RASTER_DEPTH_LINEAR_Z, 1);
    sl_rng rng;
    sl_rng_seed(&rng, 8, 8);
    float v[9 * 60];
    uint32_t ix[3 * 60];
    for (int n = 0; n < 60; n++) {
        random_tri(&rng, 128, 64, n % 3, v + 9 * n);
        for (int k = 0; k < 3; k++)
            ix[3 * n + k] = (uint32_t)(3 * n + k);
    }
    render(a, v, 180, ix, 60, IDENTITY, SL_RASTER_CULL_NONE);
    assert_int_equal(sl_raster_bin_triangles(b, v, 180, ix, 30, 12, IDENTITY, SL_RASTER_CULL_NONE, NULL), SL_OK);
    render(b, v, 180, ix + 90, 30, IDENTITY, SL_RASTER_CULL_NONE);
    assert_same_buffer(a, b);
    /* an out-of-range bin renders nothing */
    assert_int_equal(sl_raster_render_bin(b, 1000), 0);
    sl_raster_destroy(a);
    sl_raster_destroy(b);
}

/* Sizes that are not multiples of the tile, the allocator, memory and begin_frame. */
static void test_odd_size_and_allocator(void **state)
{
    (void)state;
    sl_test_counter c = {0};
    sl_allocator al = sl_test_counting_allocator(&c);
    sl_raster_options o = sl_raster_default_options(37, 13);
    o.threads = 2;
    sl_raster *r;
    assert_int_equal(sl_raster_create(&o, &al, &r, NULL), SL_OK);
    uint32_t tx, ty;
    sl_raster_get_size(r, NULL, NULL, &tx, &ty);
    assert_int_equal(tx, 2);
    assert_int_equal(ty, 2);
    assert_true(sl_raster_memory(r) >= 4 * 96);
    float wall[12] = {-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0};
    uint32_t ix[6] = {0, 1, 2, 0, 2, 3};
    render(r, wall, 4, ix, 2, IDENTITY, SL_RASTER_CULL_NONE); /* INV_W: depth 1 */
    assert_int_equal(sl_raster_test_rect(r, 0, 0, 37, 13, 0.99f), SL_RASTER_OCCLUDED);
    assert_int_equal(sl_raster_test_rect(r, 30, 10, 100, 100, 0.99f), SL_RASTER_OCCLUDED);
    assert_int_equal(sl_raster_test_rect(r, 37, 0, 40, 13, 0.99f), SL_RASTER_OUTSIDE);
    assert_int_equal(sl_raster_begin_frame(r, SL_RASTER_DEPTH_LINEAR_Z, NULL), SL_OK);
    assert_int_equal(sl_raster_test_rect(r, 0, 0, 37, 13, 0.01f), SL_RASTER_VISIBLE);
    render(r, wall, 4, ix, 2, IDENTITY, SL_RASTER_CULL_NONE); /* LINEAR_Z: depth 0.5 */
    float *img = depth_image(r);
    for (int i = 0; i < 37 * 13; i++)
        assert_true(img[i] > 0.49f && img[i] <= 0.5f);
    free(img);
    float pt[4] = {0, 0, 0, 1}, x, y, d;
    assert_true(sl_raster_project(r, pt, &x, &y, &d));
    assert_true(x == 18.5f && y == 6.5f && d == 0.5f);
    pt[3] = 0;
    assert_false(sl_raster_project(r, pt, &x, &y, &d));
    assert_int_equal(sl_raster_begin_frame(r, (sl_raster_depth)9, NULL), SL_ERROR_INVALID_ARGUMENT);
    sl_raster_destroy(r);
    assert_int_equal(c.live, 0);
    assert_string_equal(sl_raster_isa_name(SL_RASTER_ISA_AVX2), "avx2");
    assert_true(sl_raster_isa_available(SL_RASTER_ISA_SCALAR));
}

/* ---- the batched SIMD paths against the scalar reference, through the internal kernels ---- */

static const sl_rt_kernels *kernels_of(sl_raster_isa isa)
{
    switch (isa) {
#if defined(SL_RT_X86)
    case SL_RASTER_ISA_SSE41: return &sl_rt_kernels_sse41;
    case SL_RASTER_ISA_AVX2: return &sl_rt_kernels_avx2;
    case SL_RASTER_ISA_AVX512: return &sl_rt_kernels_avx512;
#endif
    default: return &sl_rt_kernels_scalar;
    }
}

/* Triangles for the front end: random sizes from sub-pixel to huge, with bad indices, NaN and
 * infinite vertices, degenerate ones, near-plane crossings and guard-band clipping. */
static void hostile_batch(sl_rng *rng, uint32_t count, uint32_t stride_floats, float *v, uint32_t nv, uint32_t *ix)
{
    for (uint32_t i = 0; i < nv; i++) {
        float *p = v + (size_t)i * stride_floats;
        float z = -sl_rng_range(rng, 0.2f, 60.0f);
        float r = sl_rng_below(rng, 4) == 0 ? sl_rng_range(rng, 0, 500) : sl_rng_range(rng, 0, 3);
        p[0] = sl_rng_range(rng, -1, 1) * -z * 0.7f + sl_rng_range(rng, -r, r);
        p[1] = sl_rng_range(rng, -1, 1) * -z * 0.5f + sl_rng_range(rng, -r, r);
        p[2] = z;
        uint32_t kind = sl_rng_below(rng, 40);
        if (kind == 0)
            p[sl_rng_below(rng, 3)] = NAN;
        else if (kind == 1)
            p[sl_rng_below(rng, 3)] = INFINITY;
        else if (kind == 2)
            p[2] = sl_rng_range(rng, -1, 3); /* near or behind the camera */
        for (uint32_t k = 3; k < stride_floats; k++)
            p[k] = 12345.0f; /* padding must not be read as a coordinate */
    }
    for (uint32_t t = 0; t < count; t++) {
        uint32_t base = sl_rng_below(rng, nv > 2 ? nv - 2 : 1);
        for (int k = 0; k < 3; k++)
            ix[3 * t + k] = base + (uint32_t)k;
        uint32_t kind = sl_rng_below(rng, 30);
        if (kind == 0)
            ix[3 * t + sl_rng_below(rng, 3)] = nv + sl_rng_below(rng, 5); /* out of range */
        else if (kind == 1)
            ix[3 * t + 2] = ix[3 * t]; /* degenerate */
        else if (kind == 2)
            ix[3 * t + 1] = 0xFFFFFFFFu;
    }
}

/* Every path's front end gives the same prims and counts as the scalar one, batch tails included. */
static void test_front_end_paths(void **state)
{
    (void)state;
    sl_rng rng;
    sl_rng_seed(&rng, 2024, 11);
    float P[16];
    perspective(P, 1.2, 16.0 / 9.0, 0.5, 400);
    const uint32_t strides[] = {3, 4, 7};
    int rounds = sanitized() ? 40 : 200;
    for (int round = 0; round < rounds; round++) {
        uint32_t sf = strides[round % 3], nv = 3 + sl_rng_below(&rng, 120), count = sl_rng_below(&rng, 70);
        float *v = malloc(sizeof(float) * sf * nv);
        uint32_t *ix = malloc(sizeof(uint32_t) * 3 * (count + 1));
        assert_true(v && ix);
        hostile_batch(&rng, count, sf, v, nv, ix);
        sl_rt_view view;
        sl_rt_view_init(&view, 160 + sl_rng_below(&rng, 200), 90 + sl_rng_below(&rng, 100), 1e-5f,
                        (sl_raster_depth)(round & 1));
        sl_rt_batch b = {v, round % 17 == 5 ? 0 : nv, ix, count, sf * 4, P, (sl_raster_backface)(round % 3)};
        int mode = round % 4 == 3 ? SL_RT_INNER : SL_RT_CENTER;
        sl_rt_prim ref[512], got[512];
        sl_rt_counters cref, cgot;
        memset(&cref, 0, sizeof cref);
        uint32_t nref = 0;
        for (uint32_t t = 0; t < count;)
            nref += sl_rt_front_prims(&view, mode, &b, &t, count, &cref, ref + nref, 512 - nref);
        for (int ii = 1; ii < isa_count; ii++) {
            const sl_rt_kernels *k = kernels_of(isa_list[ii]);
            memset(&cgot, 0, sizeof cgot);
            memset(got, 0xA5, sizeof got);
            uint32_t ngot = 0;
            for (uint32_t t = 0; t < count;)
                ngot += k->front(&view, mode, &b, &t, count, &cgot, got + ngot, 512 - ngot);
            assert_int_equal(ngot, nref);
            for (uint32_t i = 0; i < nref; i++)
                if (memcmp(&got[i], &ref[i], offsetof(sl_rt_prim, area) - 4) != 0 || got[i].area != ref[i].area)
                    fail_msg("%s round %d: prim %u differs", sl_raster_isa_name(isa_list[ii]), round, i);
            assert_memory_equal(&cgot, &cref, sizeof cref);
        }
        free(v);
        free(ix);
    }
}

/* A target of w x h pixels owned by the test. */
typedef struct test_target {
    sl_rt_target t;
    size_t tiles;
    uint8_t *empty; /* no row lazily cleared */
} test_target;

static void target_init(test_target *tt, int32_t w, int32_t h)
{
    tt->t.tiles_x = (w + SL_RT_TILE_W - 1) / SL_RT_TILE_W;
    tt->t.tiles_y = (h + SL_RT_TILE_H - 1) / SL_RT_TILE_H;
    tt->t.width = w, tt->t.height = h;
    tt->tiles = (size_t)tt->t.tiles_x * (size_t)tt->t.tiles_y;
    tt->empty = calloc((size_t)tt->t.tiles_y, 1);
    assert_non_null(tt->empty);
    tt->t.row_empty = tt->empty;
    tt->t.empty_rows = 0;
    /* aligned_alloc wants a multiple of the alignment: an even number of tiles */
    size_t even = (tt->tiles + 1) & ~(size_t)1;
    tt->t.mask = aligned_alloc(64, even * SL_RT_SUBTILES * sizeof(uint32_t));
    tt->t.depth = aligned_alloc(64, even * sizeof(sl_rt_tile_depth));
    assert_true(tt->t.mask && tt->t.depth);
    memset(tt->t.mask, 0, tt->tiles * SL_RT_SUBTILES * sizeof(uint32_t));
    memset(tt->t.depth, 0, tt->tiles * sizeof(sl_rt_tile_depth));
}

static void target_copy(test_target *dst, const test_target *src)
{
    memcpy(dst->t.mask, src->t.mask, src->tiles * SL_RT_SUBTILES * sizeof(uint32_t));
    memcpy(dst->t.depth, src->t.depth, src->tiles * sizeof(sl_rt_tile_depth));
}

static void target_free(test_target *tt)
{
    free(tt->t.mask);
    free(tt->t.depth);
    free(tt->empty);
}

/* Snapped prims (w = 1, given pixel corners) for the setup paths: sizes from one pixel to beyond
 * the small-triangle limit, axis-aligned edges (top and bottom ties), tile- and screen-edge
 * positions, in a random depth order. */
static uint32_t setup_prims(sl_rng *rng, const sl_rt_view *view, int mode, sl_rt_prim *out, uint32_t cap)
{
    uint32_t n = 0;
    while (n < cap) {
        float sz;
        uint32_t kind = sl_rng_below(rng, 8);
        if (kind < 3)
            sz = sl_rng_range(rng, 0.5f, 12);
        else if (kind < 5)
            sz = sl_rng_range(rng, 12, 80);
        else if (kind < 7)
            sz = sl_rng_range(rng, 80, 180); /* around the small-path limit */
        else
            sz = sl_rng_range(rng, 180, 700);
        float cx = sl_rng_range(rng, -40, (float)view->width + 40),
              cy = sl_rng_range(rng, -40, (float)view->height + 40);
        float px[3], py[3];
        for (int k = 0; k < 3; k++) {
            px[k] = cx + sl_rng_range(rng, -sz, sz);
            py[k] = cy + sl_rng_range(rng, -sz, sz);
        }
        uint32_t shape = sl_rng_below(rng, 6);
        if (shape == 0) {
            py[1] = py[0]; /* a horizontal edge */
        } else if (shape == 1) {
            px[2] = px[1]; /* a vertical edge */
            py[1] = py[0];
        } else if (shape == 2) {
            /* corners on half pixels: edges through pixel centres */
            for (int k = 0; k < 3; k++)
                px[k] = roundf(px[k] * 2) / 2, py[k] = roundf(py[k] * 2) / 2;
        } else if (shape == 3) {
            /* a long sliver */
            px[2] = px[0] + (px[1] - px[0]) * 0.5f + 0.3f;
            py[2] = py[0] + (py[1] - py[0]) * 0.5f;
        }
        int32_t X[3], Y[3];
        float d[3];
        for (int k = 0; k < 3; k++) {
            X[k] = (int32_t)lrintf(px[k] * 256), Y[k] = (int32_t)lrintf(py[k] * 256);
            d[k] = sl_rng_range(rng, 0.05f, 1.0f);
        }
        if (sl_rt_prepare(view, X, Y, d, mode, false, SL_RASTER_CULL_NONE, &out[n]) == 1)
            n++;
    }
    return n;
}

/* The batched setup and the small-triangle kernels merge exactly what the reference setup and the
 * scalar kernel merge: whole screen and bin by bin, over a buffer already holding partial and full
 * subtiles of every kind. */
static void test_batched_render_paths(void **state)
{
    (void)state;
    sl_rng rng;
    sl_rng_seed(&rng, 77, 5);
    const int32_t sizes[][2] = {{300, 200}, {129, 67}, {64, 40}};
    int rounds = sanitized() ? 2 : 6;
    for (size_t si = 0; si < SL_COUNTOF(sizes); si++)
        for (int mode = SL_RT_CENTER; mode <= SL_RT_INNER; mode++)
            for (int round = 0; round < rounds; round++) {
                sl_rt_view view;
                sl_rt_view_init(&view, (uint32_t)sizes[si][0], (uint32_t)sizes[si][1], 1e-5f, SL_RASTER_DEPTH_LINEAR_Z);
                enum { N = 300 };
                sl_rt_prim pre[N], prims[N];
                setup_prims(&rng, &view, mode, pre, N);
                uint32_t n = setup_prims(&rng, &view, mode, prims, N);
                test_target base, ref, got;
                target_init(&base, sizes[si][0], sizes[si][1]);
                target_init(&ref, sizes[si][0], sizes[si][1]);
                target_init(&got, sizes[si][0], sizes[si][1]);
                int32_t tx = base.t.tiles_x, ty = base.t.tiles_y;
                sl_rt_kernels_scalar.render(&base.t, mode, pre, N, 0, tx, 0, ty);
                target_copy(&ref, &base);
                sl_rt_kernels_scalar.render(&ref.t, mode, prims, n, 0, tx, 0, ty);
                for (int ii = 1; ii < isa_count; ii++) {
                    const sl_rt_kernels *k = kernels_of(isa_list[ii]);
                    /* the whole screen, in uneven chunks of prims */
                    target_copy(&got, &base);
                    for (uint32_t i = 0; i < n;) {
                        uint32_t c = 1 + sl_rng_below(&rng, 20);
                        c = c < n - i ? c : n - i;
                        k->render(&got.t, mode, prims + i, c, 0, tx, 0, ty);
                        i += c;
                    }
                    assert_memory_equal(got.t.mask, ref.t.mask, ref.tiles * SL_RT_SUBTILES * sizeof(uint32_t));
                    assert_memory_equal(got.t.depth, ref.t.depth, ref.tiles * sizeof(sl_rt_tile_depth));
                    /* bin by bin: 3 x 2 rectangles of tiles, odd widths included */
                    target_copy(&got, &base);
                    int32_t bx[4] = {0, tx / 3 + 1, 2 * tx / 3 + 1, tx}, by[3] = {0, ty / 2 + 1, ty};
                    for (int a = 0; a < 3; a++)
                        for (int c = 0; c < 2; c++)
                            if (bx[a] < bx[a + 1] && by[c] < by[c + 1])
                                k->render(&got.t, mode, prims, n, bx[a], bx[a + 1], by[c], by[c + 1]);
                    assert_memory_equal(got.t.mask, ref.t.mask, ref.tiles * SL_RT_SUBTILES * sizeof(uint32_t));
                    assert_memory_equal(got.t.depth, ref.t.depth, ref.tiles * sizeof(sl_rt_tile_depth));
                }
                target_free(&base);
                target_free(&ref);
                target_free(&got);
            }
}

/* Small and mid-size triangles at many positions: every path covers exactly the reference pixels
 * (the small path's float thresholds are exact), up to and beyond the small-path size limit. */
static void test_fill_rule_sizes(void **state)
{
    (void)state;
    const int W = 320, H = 200;
    int rounds = sanitized() ? 30 : 150;
    sl_rng rng;
    sl_rng_seed(&rng, 31, 7);
    for (int ii = 0; ii < isa_count; ii++) {
        sl_raster *r = make(W, H, isa_list[ii], SL_RASTER_DEPTH_LINEAR_Z, 1);
        for (int n = 0; n < rounds; n++) {
            float sz = n % 3 == 0 ? sl_rng_range(&rng, 1, 15)
                                  : (n % 3 == 1 ? sl_rng_range(&rng, 15, 90) : sl_rng_range(&rng, 90, 160));
            float cx = sl_rng_range(&rng, 0, W), cy = sl_rng_range(&rng, 0, H), p[9];
            for (int k = 0; k < 3; k++) {
                float px = cx + sl_rng_range(&rng, -sz, sz), py = cy + sl_rng_range(&rng, -sz, sz);
                if (n % 5 == 0)
                    px = roundf(px * 2) / 2, py = roundf(py * 2) / 2; /* ties */
                p[3 * k] = px / (0.5f * W) - 1.0f;
                p[3 * k + 1] = 1.0f - py / (0.5f * H);
                p[3 * k + 2] = sl_rng_range(&rng, -0.9f, 0.9f);
            }
            if (n % 7 == 0)
                p[4] = p[1]; /* a horizontal edge */
            uint32_t ix[3] = {0, 1, 2};
            ref_tri t;
            assert_true(ref_setup(r, IDENTITY, p, &t));
            sl_raster_clear(r);
            render(r, p, 3, ix, 1, IDENTITY, SL_RASTER_CULL_NONE);
            float *img = depth_image(r);
            for (int j = 0; j < H; j++)
                for (int i = 0; i < W; i++) {
                    bool cov = ref_covers(&t, i, j);
                    float b = img[j * W + i];
                    if (cov != (b > 0.0f))
                        fail_msg("isa %s triangle %d (size %g) pixel (%d,%d): reference %d, buffer %g",
                                 sl_raster_isa_name(isa_list[ii]), n, (double)sz, i, j, cov, (double)b);
                    if (cov && (double)b > ref_depth(&t, i, j) + 1e-12)
                        fail_msg("pixel (%d,%d): depth %.17g nearer than true %.17g", i, j, (double)b,
                                 ref_depth(&t, i, j));
                }
            free(img);
        }
        sl_raster_destroy(r);
    }
}

/* A subtile partly covered by a far occluder and then wholly by a nearer one takes the nearer
 * depth over its whole area (the old layer lies inside the new coverage). */
static void test_merge_covering_layer(void **state)
{
    (void)state;
    for (int ii = 0; ii < isa_count; ii++) {
        sl_raster *r = make(64, 32, isa_list[ii], SL_RASTER_DEPTH_LINEAR_Z, 1);
        /* far: the left half of the screen at depth 0.5 (z = 0); near: all of it at depth 0.6 */
        float far[12] = {-1, -1, 0, 0.0f, -1, 0, 0.0f, 1, 0, -1, 1, 0};
        float near[12] = {-1, -1, -0.2f, 1, -1, -0.2f, 1, 1, -0.2f, -1, 1, -0.2f};
        float part[9] = {-1, 1, 0, -0.9f, 1, 0, -1, 0.8f, 0}; /* a corner of the first subtile */
        uint32_t ix[6] = {0, 1, 2, 0, 2, 3};
        render(r, far, 4, ix, 2, IDENTITY, SL_RASTER_CULL_NONE);
        render(r, part, 3, ix, 1, IDENTITY, SL_RASTER_CULL_NONE);
        render(r, near, 4, ix, 2, IDENTITY, SL_RASTER_CULL_NONE);
        float sub[8 * 8];
        assert_int_equal(sl_raster_read_subtile_depth(r, sub, 64, NULL), SL_OK);
        for (int i = 0; i < 8 * 4; i++)
            if (!(sub[i] > 0.599f && sub[i] <= 0.6f))
                fail_msg("%s: subtile %d holds %g, not the near layer", sl_raster_isa_name(isa_list[ii]), i,
                         (double)sub[i]);
        assert_int_equal(sl_raster_test_rect(r, 0, 0, 64, 32, 0.58f), SL_RASTER_OCCLUDED);
        sl_raster_destroy(r);
    }
}

/* The widest screen (SL_RT_MAX_DIM = 8192 pixels, 256 tile columns): triangles as wide as the
 * screen and wider (clipped), starting at every kind of tile column, through the general kernels
 * whose per-column depth array holds 256 + 8 entries. Every path must agree with scalar, directly
 * and through the bins, and (under ASan) no kernel may write or point past that array. Issue 12:
 * the AVX2/AVX-512 kernels formed the pointer zcol - tx0 before the array whenever tx0 > 0. */
static void test_widest_screen(void **state)
{
    (void)state;
    const uint32_t W = 8192, H = 24;
    const int count = sanitized() ? 60 : 200;
    sl_rng rng;
    sl_rng_seed(&rng, 12, 8192);
    float *v = malloc(sizeof(float) * 9 * (size_t)count);
    uint32_t *ix = malloc(sizeof(uint32_t) * 3 * (size_t)count);
    assert_non_null(v);
    assert_non_null(ix);
    for (int t = 0; t < count; t++) {
        /* one vertex far left or right, the others anywhere: spans of up to the whole width */
        for (int k = 0; k < 3; k++) {
            float *p = v + 9 * t + 3 * k;
            p[0] = k == 0 ? (t % 2 ? -1.3f : 1.3f) : sl_rng_range(&rng, -1.2f, 1.2f);
            p[1] = sl_rng_range(&rng, -2.0f, 2.0f);
            p[2] = sl_rng_range(&rng, 0.05f, 0.95f);
        }
    }
    /* a triangle covering the whole screen first, one from tile column 1 to the right edge */
    const float cover[18] = {-3, -3, 0.9f, 3, -3, 0.9f, 0, 3, 0.9f, -0.99f, -1, 0.5f, 1.5f, -1, 0.5f, 1.5f, 1, 0.5f};
    for (uint32_t i = 0; i < 3 * (uint32_t)count; i++)
        ix[i] = i;
    for (uint32_t threads = 1; threads <= 2; threads++) {
        sl_raster *ref = NULL;
        for (int ii = 0; ii < isa_count; ii++) {
            sl_raster *r = make(W, H, isa_list[ii], SL_RASTER_DEPTH_LINEAR_Z, threads);
            render(r, cover, 6, ix, 2, IDENTITY, SL_RASTER_CULL_NONE);
            render(r, v, 3 * (uint32_t)count, ix, (uint32_t)count, IDENTITY, SL_RASTER_CULL_NONE);
            if (!ref) {
                ref = r;
                continue;
            }
            assert_same_buffer(ref, r);
            sl_raster_destroy(r);
        }
        sl_raster_destroy(ref);
    }
    free(v);
    free(ix);
}

/* Triangles in the pixel rows [ya, yb] of a W x H screen (NDC, w = 1). */
static void band_tris(sl_rng *rng, int W, int H, float ya, float yb, int count, float *v, uint32_t *ix)
{
    for (int n = 0; n < count; n++) {
        for (int i = 0; i < 3; i++) {
            float px = sl_rng_range(rng, -10.0f, (float)W + 10.0f), py = sl_rng_range(rng, ya, yb);
            v[9 * n + 3 * i + 0] = px / (0.5f * (float)W) - 1.0f;
            v[9 * n + 3 * i + 1] = 1.0f - py / (0.5f * (float)H);
            v[9 * n + 3 * i + 2] = sl_rng_range(rng, -0.9f, 0.9f);
        }
        for (int k = 0; k < 3; k++)
            ix[3 * n + k] = (uint32_t)(3 * n + k);
    }
}

/* The lazy clear: after a full buffer is cleared and a band of rows redrawn (directly, binned or
 * by the pool), every read (depth images, subtile depths, tile info, rect, box and mesh queries,
 * the rect test at a negative depth) and then the raw buffer equal those of a context that only
 * drew the band and had every row written. */
static void test_lazy_clear(void **state)
{
    (void)state;
    const int W = 200, H = 136; /* 7 x 17 tiles */
    enum { FULL = 600, BAND = 700 };
    float *fv = malloc(sizeof(float) * 9 * FULL), *bv = malloc(sizeof(float) * 9 * BAND);
    uint32_t *fix = malloc(sizeof(uint32_t) * 3 * FULL), *bix = malloc(sizeof(uint32_t) * 3 * BAND);
    assert_true(fv && bv && fix && bix);
    sl_rng rng;
    sl_rng_seed(&rng, 14, 2);
    for (int n = 0; n < FULL; n++) {
        random_tri(&rng, W, H, n % 3, fv + 9 * n);
        for (int k = 0; k < 3; k++)
            fix[3 * n + k] = (uint32_t)(3 * n + k);
    }
    band_tris(&rng, W, H, 20.0f, 61.0f, BAND, bv, bix);
    float *ia = malloc(sizeof(float) * W * H), *ib = malloc(sizeof(float) * W * H);
    float *sa = malloc(sizeof(float) * W * H), *sb = malloc(sizeof(float) * W * H);
    assert_true(ia && ib && sa && sb);
    for (int ii = 0; ii < isa_count; ii++)
        for (int how = 0; how < 3; how++) { /* direct, bin_triangles + flush, the pool */
            uint32_t threads = how == 2 ? 2 : 1;
            sl_raster *a = make(W, H, isa_list[ii], SL_RASTER_DEPTH_LINEAR_Z, threads);
            sl_raster *b = make(W, H, isa_list[ii], SL_RASTER_DEPTH_LINEAR_Z, threads);
            render(a, fv, 3 * FULL, fix, FULL, IDENTITY, SL_RASTER_CULL_NONE);
            sl_rt_settle(a);
            sl_raster_clear(a); /* a's memory holds the full soup; its rows are marked empty */
            sl_rt_settle(b);
            for (sl_raster *r = a; r; r = r == a ? b : NULL) {
                if (how == 1) {
                    assert_int_equal(sl_raster_bin_triangles(r, bv, 3 * BAND, bix, BAND, 12, IDENTITY,
                                                             SL_RASTER_CULL_NONE, NULL),
                                     SL_OK);
                    sl_raster_flush(r);
                } else {
                    render(r, bv, 3 * BAND, bix, BAND, IDENTITY, SL_RASTER_CULL_NONE);
                }
            }
            if (how == 0) /* direct rendering wrote only the rows the band reaches (2..7) */
                assert_true(sl_rt_target_of(a)->row_empty[H / 8 - 1] && !sl_rt_target_of(a)->row_empty[4] &&
                            sl_rt_target_of(a)->empty_rows == 17 - 6);
            sl_rt_settle(b);
            assert_int_equal(sl_raster_read_depth(a, ia, (size_t)W * H, NULL), SL_OK);
            assert_int_equal(sl_raster_read_depth(b, ib, (size_t)W * H, NULL), SL_OK);
            assert_memory_equal(ia, ib, sizeof(float) * W * H);
            assert_int_equal(sl_raster_read_subtile_depth(a, sa, (size_t)W * H, NULL), SL_OK);
            assert_int_equal(sl_raster_read_subtile_depth(b, sb, (size_t)W * H, NULL), SL_OK);
            assert_memory_equal(sa, sb, sizeof(float) * 28 * 34);
            for (uint32_t ty = 0; ty < 17; ty++)
                for (uint32_t tx = 0; tx < 7; tx++) {
                    sl_raster_tile_info ta, tb;
                    assert_int_equal(sl_raster_get_tile_info(a, tx, ty, &ta, NULL), SL_OK);
                    assert_int_equal(sl_raster_get_tile_info(b, tx, ty, &tb, NULL), SL_OK);
                    assert_memory_equal(&ta, &tb, sizeof ta);
                }
            const sl_rt_kernels *k = kernels_of(isa_list[ii]);
            sl_rng q;
            sl_rng_seed(&q, 5, (uint64_t)ii);
            unsigned occluded = 0;
            for (int n = 0; n < 400; n++) {
                /* up to 3 tiles wide (the small-rectangle shortcut) and up to the whole width */
                int32_t x0 = (int32_t)sl_rng_below(&q, W), y0 = (int32_t)sl_rng_below(&q, 80);
                int32_t x1 = x0 + 1 + (int32_t)sl_rng_below(&q, n % 2 ? 40 : W);
                int32_t y1 = y0 + 1 + (int32_t)sl_rng_below(&q, 70);
                float d = sl_rng_range(&q, 0.0f, 0.6f);
                sl_raster_result r = sl_raster_test_rect(b, x0, y0, x1, y1, d);
                occluded += r == SL_RASTER_OCCLUDED;
                assert_int_equal(sl_raster_test_rect(a, x0, y0, x1, y1, d), r);
                int32_t cx1 = sl_rt_mini(x1, W), cy1 = sl_rt_mini(y1, H);
                /* b has no empty row: its answer (the small-rectangle shortcut, the path's kernel)
                 * is the scalar kernel's */
                assert_int_equal(r == SL_RASTER_OCCLUDED,
                                 sl_rt_kernels_scalar.rect_occluded(sl_rt_target_of(b), x0, y0, cx1, cy1, d));
                assert_int_equal(sl_rt_rect_occluded(k, sl_rt_target_of(a), x0, y0, cx1, cy1, -0.25f),
                                 sl_rt_rect_occluded(k, sl_rt_target_of(b), x0, y0, cx1, cy1, -0.25f));
                float tri[9];
                band_tris(&q, W, H, (float)y0, (float)y1, 1, tri, (uint32_t[3]){0});
                uint32_t i3[3] = {0, 1, 2};
                assert_int_equal(sl_raster_test_triangles(a, tri, 3, i3, 1, 12, IDENTITY, SL_RASTER_CULL_NONE),
                                 sl_raster_test_triangles(b, tri, 3, i3, 1, 12, IDENTITY, SL_RASTER_CULL_NONE));
            }
            assert_true(occluded > 10 && occluded < 390); /* both answers occur */
            assert_same_buffer(a, b);
            sl_raster_destroy(a);
            sl_raster_destroy(b);
        }
    free(ia);
    free(ib);
    free(sa);
    free(sb);
    free(fv);
    free(bv);
    free(fix);
    free(bix);
}

/* The box query on SIMD registers answers as the corner-by-corner reference: random boxes (inside,
 * outside, crossing the near plane, huge, degenerate) under perspective, orthographic and random
 * matrices, over a buffer holding a scene, in both depth modes. */
static void test_aabb_simd(void **state)
{
    (void)state;
    const int W = 160, H = 96;
    sl_rng rng;
    sl_rng_seed(&rng, 21, 4);
    float *v;
    uint32_t *ix, nv;
    int count = 600;
    random_scene(&rng, count, &v, &ix, &nv);
    unsigned seen[3] = {0, 0, 0};
    for (int mode = 0; mode < 2; mode++) {
        sl_raster_depth dm = mode ? SL_RASTER_DEPTH_LINEAR_Z : SL_RASTER_DEPTH_INV_W;
        sl_raster *r = make(W, H, SL_RASTER_ISA_AUTO, dm, 1);
        float P[16];
        if (mode)
            orthographic(P, 30, 20, 0.5, 120);
        else
            perspective(P, 1.1, (double)W / H, 0.3, 500);
        render(r, v, nv, ix, (uint32_t)count, P, SL_RASTER_CULL_NONE);
        for (int n = 0; n < 4000; n++) {
            float M[16];
            memcpy(M, P, sizeof M);
            if (n % 7 == 6)
                for (int k = 0; k < 16; k++)
                    M[k] = sl_rng_range(&rng, -2, 2) * (n % 21 == 20 ? 1e19f : 1.0f);
            float scale = n % 5 == 4 ? 1e6f : 1.0f;
            float bmin[3] = {sl_rng_range(&rng, -40, 40) * scale, sl_rng_range(&rng, -30, 30) * scale,
                             sl_rng_range(&rng, -150, 5) * scale};
            float bmax[3];
            for (int k = 0; k < 3; k++)
                bmax[k] = bmin[k] + (n % 11 == 3 ? 0.0f : sl_rng_range(&rng, 0, 12));
            sl_raster_result got = sl_raster_test_aabb(r, bmin, bmax, M);
            assert_int_equal(got, sl_rt_test_aabb_scalar(r, bmin, bmax, M));
            seen[got]++;
        }
        sl_raster_destroy(r);
    }
    /* every answer occurs */
    assert_true(seen[SL_RASTER_VISIBLE] > 100 && seen[SL_RASTER_OCCLUDED] > 100 && seen[SL_RASTER_OUTSIDE] > 100);
    free(v);
    free(ix);
}

int main(void)
{
    collect_isas();
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fill_rule_exact),      cmocka_unit_test(test_soup_conservative),
        cmocka_unit_test(test_shared_edge_watertight), cmocka_unit_test(test_no_double_coverage),
        cmocka_unit_test(test_huge_triangles),        cmocka_unit_test(test_near_plane_crossing),
        cmocka_unit_test(test_bad_input),             cmocka_unit_test(test_backface),
        cmocka_unit_test(test_queries_perspective),   cmocka_unit_test(test_full_screen_tight),
        cmocka_unit_test(test_orthographic),          cmocka_unit_test(test_isa_bit_identical),
        cmocka_unit_test(test_inner_coverage),        cmocka_unit_test(test_threads_identical),
        cmocka_unit_test(test_bins_then_direct),      cmocka_unit_test(test_odd_size_and_allocator),
        cmocka_unit_test(test_extreme_inputs),        cmocka_unit_test(test_front_end_paths),
        cmocka_unit_test(test_batched_render_paths),  cmocka_unit_test(test_fill_rule_sizes),
        cmocka_unit_test(test_merge_covering_layer),  cmocka_unit_test(test_widest_screen),
        cmocka_unit_test(test_lazy_clear),            cmocka_unit_test(test_aabb_simd),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
