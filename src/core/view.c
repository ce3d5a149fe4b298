/* Views: the normal form of include/sightline/view.h, from a camera (the camera functions, bit
 * for bit) or from an engine's matrices (normalised to a right-handed eye space, OpenGL depth and
 * an unmirrored image), the far plane bounded by the world, and the depth-format limits.
 *
 * Matrices are column-major: element (row i, column j) of m is m[4 * j + i]. Everything derived
 * (near and far, the near rectangle, the planes) is computed in double from the float entries and
 * rounded once. */
#include "sightline/view.h"
#include "core/camera_internal.h"
#include "core/dvec3.h"
#include "core/sl_core.h"

#include <float.h>
#include <math.h>

#define VIEW_MAGIC 0x53567731u /* "SVw1" */

#define M(m, i, j) ((m)[4 * (j) + (i)])

static const char *g_depth_names[3] = {"gl", "zero-one", "reversed"};

const char *sl_clip_depth_name(sl_clip_depth d)
{
    return (unsigned)d < 3 ? g_depth_names[d] : "unknown";
}

bool sl_clip_depth_parse(const char *text, sl_clip_depth *out)
{
    for (int i = 0; text && i < 3; i++)
        if (strcmp(text, g_depth_names[i]) == 0) {
            if (out)
                *out = (sl_clip_depth)i;
            return true;
        }
    return false;
}

/* ---- from a camera ---- */

/* The camera's values in view terms; view_proj and frustum from the camera functions. */
static void fill_from_camera(const sl_camera *cam, sl_view *v)
{
    memset(v, 0, sizeof *v);
    double t;
    sl_camera_all(cam, &v->view, &v->proj, &v->view_proj, &v->frustum, &v->forward, &v->right, &v->up, &t);
    v->projection = cam->projection;
    v->eye = cam->position;
    v->near_plane = cam->near_plane;
    v->far_plane = cam->far_plane;
    v->width = cam->width;
    v->height = cam->height;
    double a = (double)cam->width / (double)cam->height;
    if (cam->projection == SL_ORTHOGRAPHIC) {
        double h = 0.5 * cam->ortho_height, w = h * a;
        v->rect_left = -w, v->rect_right = w, v->rect_bottom = -h, v->rect_top = h;
        /* square pixels: one focal; the value the occlusion framework computed from the camera */
        v->focal_x = v->focal_y = (double)((float)cam->height / cam->ortho_height);
        v->near_corner_dist = 0;
    } else {
        double n = cam->near_plane; /* t = tan(0.5 * fov_y) */
        v->rect_left = -n * t * a, v->rect_right = n * t * a, v->rect_bottom = -n * t, v->rect_top = n * t;
        v->focal_x = v->focal_y = (double)cam->height / (2.0 * t);
        v->near_corner_dist = n * sqrt(1.0 + t * t * (1.0 + a * a));
    }
    v->source = SL_VIEW_FROM_CAMERA;
    v->clip_depth = SL_CLIP_DEPTH_GL;
    v->camera = *cam;
    v->magic = VIEW_MAGIC;
}

sl_status sl_view_from_camera(const sl_camera *cam, sl_view *out, sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_view_from_camera: out is NULL");
    sl_status st = sl_camera_validate(cam, err);
    if (st != SL_OK)
        return st;
    fill_from_camera(cam, out);
    return SL_OK;
}

/* ---- from matrices ---- */

/* Plane with inward normal n through point q, normalised (as camera.c). */
static sl_plane plane_through(sl_dvec3 n, sl_dvec3 q)
{
    double len = sqrt(sl_d3_dot(n, n));
    n = sl_d3_scale(n, 1.0 / len);
    return (sl_plane){(float)n.x, (float)n.y, (float)n.z, (float)-sl_d3_dot(n, q)};
}

/* The eye-space axes and the eye of the normal-form view matrix, in double. */
static void eye_frame(const sl_view *v, sl_dvec3 *r, sl_dvec3 *u, sl_dvec3 *f, sl_dvec3 *e)
{
    const float *V = v->view.m;
    sl_dvec3 rows[3];
    for (int i = 0; i < 3; i++)
        rows[i] = sl_d3(M(V, i, 0), M(V, i, 1), M(V, i, 2));
    sl_dvec3 t = sl_d3(M(V, 0, 3), M(V, 1, 3), M(V, 2, 3));
    /* eye = -R^T t */
    *e = sl_d3_scale(sl_d3_add(sl_d3_add(sl_d3_scale(rows[0], t.x), sl_d3_scale(rows[1], t.y)), sl_d3_scale(rows[2], t.z)),
                     -1.0);
    *r = sl_d3_unit(rows[0]);
    *u = sl_d3_unit(rows[1]);
    *f = sl_d3_scale(sl_d3_unit(rows[2]), -1.0);
}

/* Everything a matrix view derives from its normal-form view matrix, the x, y and w rows of proj,
 * near, far and the viewport: proj's depth row, view_proj, the axes, the rectangle, the focal
 * lengths, the frustum. */
static void finish_matrices(sl_view *v)
{
    float *P = v->proj.m;
    double n = v->near_plane, fa = v->far_plane;
    bool ortho = v->projection == SL_ORTHOGRAPHIC;
    if (ortho) {
        M(P, 2, 2) = (float)(-2.0 / (fa - n));
        M(P, 2, 3) = (float)(-(fa + n) / (fa - n));
    } else if (isinf(fa)) {
        M(P, 2, 2) = -1.0f;
        M(P, 2, 3) = (float)(-2.0 * n);
    } else {
        M(P, 2, 2) = (float)((fa + n) / (n - fa));
        M(P, 2, 3) = (float)(2.0 * fa * n / (n - fa));
    }
    for (int c = 0; c < 4; c++)
        for (int row = 0; row < 4; row++) {
            double s = 0;
            for (int k = 0; k < 4; k++)
                s += (double)P[k * 4 + row] * (double)v->view.m[c * 4 + k];
            v->view_proj.m[c * 4 + row] = (float)s;
        }
    sl_dvec3 r, u, f, e;
    eye_frame(v, &r, &u, &f, &e);
    v->eye = sl_d3_to_vec3(e);
    v->forward = sl_d3_to_vec3(f);
    v->right = sl_d3_to_vec3(r);
    v->up = sl_d3_to_vec3(u);
    double p00 = M(P, 0, 0), p11 = M(P, 1, 1);
    double l, rr, b, t;
    if (ortho) {
        double ox = M(P, 0, 3), oy = M(P, 1, 3);
        l = (-1.0 - ox) / p00, rr = (1.0 - ox) / p00, b = (-1.0 - oy) / p11, t = (1.0 - oy) / p11;
    } else {
        double cx = M(P, 0, 2), cy = M(P, 1, 2);
        l = n * (cx - 1.0) / p00, rr = n * (cx + 1.0) / p00, b = n * (cy - 1.0) / p11, t = n * (cy + 1.0) / p11;
    }
    v->rect_left = l, v->rect_right = rr, v->rect_bottom = b, v->rect_top = t;
    v->focal_x = p00 * v->width / 2.0;
    v->focal_y = p11 * v->height / 2.0;
    v->near_corner_dist =
        ortho ? 0 : sqrt(n * n + fmax(l * l, rr * rr) + fmax(b * b, t * t));

    sl_frustum *out = &v->frustum;
    sl_dvec3 nc = sl_d3_add(e, sl_d3_scale(f, n));
    if (ortho) {
        out->planes[0] = plane_through(r, sl_d3_add(e, sl_d3_scale(r, l)));
        out->planes[1] = plane_through(sl_d3_scale(r, -1), sl_d3_add(e, sl_d3_scale(r, rr)));
        out->planes[2] = plane_through(u, sl_d3_add(e, sl_d3_scale(u, b)));
        out->planes[3] = plane_through(sl_d3_scale(u, -1), sl_d3_add(e, sl_d3_scale(u, t)));
    } else {
        /* each side plane passes through the eye and an edge of the near rectangle: eye-space
         * inward normals (n, 0, l), (-n, 0, -r), (0, n, b), (0, -n, -t); an eye-space vector
         * (x, y, z) is x r + y u - z f in the world */
        out->planes[0] = plane_through(sl_d3_sub(sl_d3_scale(r, n), sl_d3_scale(f, l)), e);
        out->planes[1] = plane_through(sl_d3_add(sl_d3_scale(r, -n), sl_d3_scale(f, rr)), e);
        out->planes[2] = plane_through(sl_d3_sub(sl_d3_scale(u, n), sl_d3_scale(f, b)), e);
        out->planes[3] = plane_through(sl_d3_add(sl_d3_scale(u, -n), sl_d3_scale(f, t)), e);
    }
    out->planes[4] = plane_through(f, nc);
    if (isinf(fa))
        out->planes[5] = (sl_plane){0, 0, 0, 1};
    else
        out->planes[5] = plane_through(sl_d3_scale(f, -1), sl_d3_add(e, sl_d3_scale(f, fa)));
    const double xs[4] = {l, rr, rr, l}, ys[4] = {b, b, t, t}; /* bl, br, tr, tl */
    double k = ortho ? 1.0 : fa / n;
    for (int i = 0; i < 4; i++) {
        sl_dvec3 d = sl_d3_add(sl_d3_scale(r, xs[i]), sl_d3_scale(u, ys[i]));
        out->corners[i] = sl_d3_to_vec3(sl_d3_add(nc, d));
        sl_dvec3 fc = sl_d3_add(e, sl_d3_scale(f, fa));
        out->corners[4 + i] = sl_d3_to_vec3(sl_d3_add(fc, sl_d3_scale(d, k)));
    }
}

static sl_status bad(sl_error *err, const char *what, int i, int j, const char *why, double value)
{
    return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_view_from_matrices: %s matrix element (row %d, column %d) = %g: %s",
                   what, i, j, value, why);
}

sl_status sl_view_from_matrices(const float view[16], const float proj[16], sl_clip_depth depth, uint32_t width,
                                uint32_t height, sl_view *out, sl_error *err)
{
    if (!view || !proj || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_view_from_matrices: view, proj and out must not be NULL");
    if ((unsigned)depth > SL_CLIP_DEPTH_REVERSED)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_view_from_matrices: depth convention %d is unknown",
                       (int)depth);
    if (width == 0 || height == 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_view_from_matrices: viewport %ux%u is empty", width, height);
    double V[16], P[16];
    for (int i = 0; i < 16; i++) {
        V[i] = view[i];
        P[i] = proj[i];
        if (!isfinite(V[i]))
            return bad(err, "view", i % 4, i / 4, "not finite", V[i]);
        if (!isfinite(P[i]))
            return bad(err, "projection", i % 4, i / 4, "not finite", P[i]);
    }
    const double tol = SL_VIEW_ORTHO_TOL;
    /* the view matrix: rigid */
    for (int j = 0; j < 4; j++) {
        double want = j == 3 ? 1.0 : 0.0;
        if (!(fabs(M(V, 3, j) - want) <= tol))
            return bad(err, "view", 3, j, j == 3 ? "the bottom row must be (0, 0, 0, 1) (an affine transform)"
                                                 : "the bottom row must be (0, 0, 0, 1) (an affine transform)",
                       M(V, 3, j));
        M(V, 3, j) = want;
    }
    for (int a = 0; a < 3; a++)
        for (int b = a; b < 3; b++) {
            double d = M(V, a, 0) * M(V, b, 0) + M(V, a, 1) * M(V, b, 1) + M(V, a, 2) * M(V, b, 2);
            if (!(fabs(d - (a == b ? 1.0 : 0.0)) <= tol))
                return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                               "sl_view_from_matrices: view matrix rows %d and %d of the 3x3 part have dot product %g "
                               "(must be %d within %g: a rigid transform, no scale, skew, shear or singular part)",
                               a, b, d, a == b, tol);
        }
    double det = M(V, 0, 0) * (M(V, 1, 1) * M(V, 2, 2) - M(V, 1, 2) * M(V, 2, 1)) -
                 M(V, 0, 1) * (M(V, 1, 0) * M(V, 2, 2) - M(V, 1, 2) * M(V, 2, 0)) +
                 M(V, 0, 2) * (M(V, 1, 0) * M(V, 2, 1) - M(V, 1, 1) * M(V, 2, 0));
    bool left_handed = det < 0;
    /* the projection: its kind from the bottom row */
    double scale = fmax(fabs(M(P, 0, 0)), fabs(M(P, 1, 1)));
    if (!(scale > 0))
        return bad(err, "projection", 0, 0, "P00 and P11 are both zero (singular)", M(P, 0, 0));
    for (int j = 0; j < 2; j++) {
        if (!(fabs(M(P, 3, j)) <= tol))
            return bad(err, "projection", 3, j, "the bottom row must be (0, 0, +-1, 0) or (0, 0, 0, 1)", M(P, 3, j));
        M(P, 3, j) = 0;
    }
    bool ortho;
    if (fabs(M(P, 3, 3) - 1.0) <= tol && fabs(M(P, 3, 2)) <= tol) {
        ortho = true;
        M(P, 3, 2) = 0, M(P, 3, 3) = 1;
    } else if (fabs(M(P, 3, 3)) <= tol && fabs(fabs(M(P, 3, 2)) - 1.0) <= tol) {
        ortho = false;
        M(P, 3, 2) = M(P, 3, 2) < 0 ? -1.0 : 1.0, M(P, 3, 3) = 0;
    } else {
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "sl_view_from_matrices: projection matrix bottom row (%g, %g, %g, %g) is neither perspective "
                       "(0, 0, +-1, 0) nor orthographic (0, 0, 0, 1)",
                       M(P, 3, 0), M(P, 3, 1), M(P, 3, 2), M(P, 3, 3));
    }
    /* the entries that must be zero: skew, x/y-dependent depth, shear */
    static const int zeros_p[6][2] = {{0, 1}, {1, 0}, {2, 0}, {2, 1}, {0, 3}, {1, 3}};
    static const int zeros_o[6][2] = {{0, 1}, {1, 0}, {2, 0}, {2, 1}, {0, 2}, {1, 2}};
    static const char *why_p[6] = {"skew (x from y) must be 0", "skew (y from x) must be 0",
                                   "an oblique depth (depth from x) must be 0", "an oblique depth (depth from y) must be 0",
                                   "a perspective x offset not divided by depth (shear) must be 0",
                                   "a perspective y offset not divided by depth (shear) must be 0"};
    static const char *why_o[6] = {"skew (x from y) must be 0", "skew (y from x) must be 0",
                                   "an oblique depth (depth from x) must be 0", "an oblique depth (depth from y) must be 0",
                                   "an orthographic x shear along depth must be 0",
                                   "an orthographic y shear along depth must be 0"};
    for (int k = 0; k < 6; k++) {
        int i = ortho ? zeros_o[k][0] : zeros_p[k][0], j = ortho ? zeros_o[k][1] : zeros_p[k][1];
        if (!(fabs(M(P, i, j)) <= tol * scale))
            return bad(err, "projection", i, j, ortho ? why_o[k] : why_p[k], M(P, i, j));
        M(P, i, j) = 0;
    }
    if (M(P, 0, 0) == 0 || M(P, 1, 1) == 0)
        return bad(err, "projection", M(P, 0, 0) == 0 ? 0 : 1, M(P, 0, 0) == 0 ? 0 : 1, "zero scale (singular)", 0);
    /* looking down +Z of the input eye space: flip eye z (row 2 of V, column 2 of P); for an
     * orthographic view the depth's slope says which way is forward */
    bool reversed = depth == SL_CLIP_DEPTH_REVERSED;
    if (ortho && M(P, 2, 2) == 0)
        return bad(err, "projection", 2, 2, "zero depth scale (singular)", 0);
    bool flip_z = ortho ? ((M(P, 2, 2) > 0) != reversed) : M(P, 3, 2) > 0;
    if (flip_z)
        for (int j = 0; j < 4; j++) {
            M(V, 2, j) = -M(V, 2, j);
            M(P, j, 2) = -M(P, j, 2);
        }
    /* a left-handed frame now (det < 0 after the flip): flip eye x (row 0 of V, column 0 of P) */
    if ((det < 0) != flip_z)
        for (int j = 0; j < 4; j++) {
            M(V, 0, j) = -M(V, 0, j);
            M(P, j, 0) = -M(P, j, 0);
        }
    /* an image mirrored in x or y: negate clip x or y (rows 0 and 1 of P) */
    bool mx = M(P, 0, 0) < 0, my = M(P, 1, 1) < 0;
    for (int j = 0; j < 4; j++) {
        if (mx)
            M(P, 0, j) = -M(P, 0, j);
        if (my)
            M(P, 1, j) = -M(P, 1, j);
    }
    /* near and far from the depth row: NDC depth of a point at forward distance D is
     * (a D - b) / D (perspective, z_eye = -D, w = D) or -a D + b (orthographic) */
    double a = M(P, 2, 2), b = M(P, 2, 3);
    const double dn[3] = {-1, 0, 1}, df[3] = {1, 1, 0};
    double n, fa;
    if (ortho) {
        n = (b - dn[depth]) / a;
        fa = (b - df[depth]) / a;
    } else {
        /* depth(D) = -a + b / D = d  <=>  D = b / (d + a) */
        n = b / (dn[depth] + a);
        fa = df[depth] + a == 0 ? INFINITY : b / (df[depth] + a);
    }
    if (!(n > 0) || !isfinite(n))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "sl_view_from_matrices: projection matrix depth row (P22 = %g, P23 = %g) under %s depth gives a "
                       "near plane at %g: it must be positive and finite",
                       (double)proj[10], (double)proj[14], sl_clip_depth_name(depth), n);
    if (!(fa > n))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "sl_view_from_matrices: projection matrix depth row (P22 = %g, P23 = %g) under %s depth gives a "
                       "far plane at %g: it must be beyond the near plane %g",
                       (double)proj[10], (double)proj[14], sl_clip_depth_name(depth), fa, n);
    if (ortho && isinf(fa))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_view_from_matrices: an orthographic far plane must be finite");
    memset(out, 0, sizeof *out);
    for (int i = 0; i < 16; i++) {
        out->view.m[i] = (float)V[i];
        out->proj.m[i] = (float)P[i];
    }
    out->projection = ortho ? SL_ORTHOGRAPHIC : SL_PERSPECTIVE;
    out->near_plane = n;
    out->far_plane = fa;
    out->width = width;
    out->height = height;
    out->source = SL_VIEW_FROM_MATRICES;
    out->clip_depth = depth;
    out->mirrored_x = mx;
    out->mirrored_y = my;
    out->left_handed = left_handed;
    out->magic = VIEW_MAGIC;
    finish_matrices(out);
    return SL_OK;
}

/* ---- checks and copies ---- */

sl_status sl_view_validate(const sl_view *v, sl_error *err)
{
    if (!v)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "view: NULL");
    if (v->magic != VIEW_MAGIC || (v->source != SL_VIEW_FROM_CAMERA && v->source != SL_VIEW_FROM_MATRICES))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "view: not made by a constructor (sl_view_from_camera, sl_view_from_matrices)");
    return SL_OK;
}

sl_status sl_view_with_far(const sl_view *v, double far_plane, sl_view *out, sl_error *err)
{
    sl_status st = sl_view_validate(v, err);
    if (st != SL_OK)
        return st;
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_view_with_far: out is NULL");
    if (!(far_plane > v->near_plane) || isnan(far_plane) ||
        (isinf(far_plane) && v->projection == SL_ORTHOGRAPHIC))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "sl_view_with_far: far plane %g must be beyond the near plane %g (and finite for an orthographic "
                       "view)",
                       far_plane, v->near_plane);
    if (v->source == SL_VIEW_FROM_CAMERA) {
        sl_camera c = v->camera;
        c.far_plane = (float)far_plane;
        return sl_view_from_camera(&c, out, err);
    }
    sl_view w = *v;
    w.far_plane = far_plane;
    finish_matrices(&w);
    *out = w;
    return SL_OK;
}

sl_status sl_view_with_viewport(const sl_view *v, uint32_t width, uint32_t height, sl_view *out, sl_error *err)
{
    sl_status st = sl_view_validate(v, err);
    if (st != SL_OK)
        return st;
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_view_with_viewport: out is NULL");
    if (width == 0 || height == 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_view_with_viewport: viewport %ux%u is empty", width, height);
    if (v->source == SL_VIEW_FROM_CAMERA) {
        sl_camera c = v->camera;
        c.width = width;
        c.height = height;
        return sl_view_from_camera(&c, out, err);
    }
    sl_view w = *v;
    w.width = width;
    w.height = height;
    finish_matrices(&w);
    *out = w;
    return SL_OK;
}

sl_status sl_view_bound_far(const sl_view *v, const sl_aabb *world, sl_view *out, sl_error *err)
{
    sl_status st = sl_view_validate(v, err);
    if (st != SL_OK)
        return st;
    if (!world || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_view_bound_far: world and out must not be NULL");
    double reach;
    if (sl_aabb_is_empty(world)) {
        reach = 1.0;
    } else {
        double reach2 = 0;
        const float *lo = &world->min.x, *hi = &world->max.x, *e = &v->eye.x;
        for (int a = 0; a < 3; a++) {
            double d = fmax(fabs((double)lo[a] - e[a]), fabs((double)hi[a] - e[a]));
            reach2 += d * d;
        }
        reach = sqrt(reach2) * (1 + 1e-3) + 1.0;
    }
    reach = fmax(reach, 2.0 * v->near_plane);
    if (v->source == SL_VIEW_FROM_CAMERA)
        reach = fmin(reach, (double)FLT_MAX);
    if (!(isfinite(reach) && reach < v->far_plane)) {
        *out = *v;
        return SL_OK;
    }
    return sl_view_with_far(v, reach, out, err);
}

void sl_view_pixel_ray(const sl_view *v, double x, double y, double org[3], double dir[3])
{
    double xe = v->rect_left + (v->rect_right - v->rect_left) * x / (double)v->width;
    double ye = v->rect_top - (v->rect_top - v->rect_bottom) * y / (double)v->height;
    const float *r = &v->right.x, *u = &v->up.x, *f = &v->forward.x, *e = &v->eye.x;
    if (v->projection == SL_PERSPECTIVE) {
        double sx = xe / v->near_plane, sy = ye / v->near_plane;
        for (int k = 0; k < 3; k++) {
            org[k] = e[k];
            dir[k] = f[k] + sx * r[k] + sy * u[k];
        }
    } else {
        for (int k = 0; k < 3; k++) {
            org[k] = e[k] + xe * r[k] + ye * u[k];
            dir[k] = f[k];
        }
    }
}

/* ---- depth formats ---- */

double sl_view_min_near(const sl_view *v, sl_depth_format format)
{
    if (!v || format == SL_DEPTH_NONE || v->projection == SL_ORTHOGRAPHIC)
        return 0;
    double m = fabs((double)v->eye.x) + fabs((double)v->eye.y) + fabs((double)v->eye.z) + 1.0;
    double lo = m * SL_MARGIN_REL; /* the float depth's relative resolution (core/margins.h) */
    if (format == SL_DEPTH_CLIP_Z)
        lo = fmax(lo, v->far_plane / SL_CAMERA_MAX_FAR_NEAR);
    return lo;
}

sl_status sl_view_check_depth(const sl_view *v, sl_depth_format format, const char *who, sl_error *err)
{
    if (!v)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "view: NULL");
    double lo = sl_view_min_near(v, format);
    if (v->near_plane >= lo)
        return SL_OK;
    bool zfar = format == SL_DEPTH_CLIP_Z;
    return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                   "%s: near plane %g m: %s's %s needs near >= %.3g m (2^-20 of |x|+|y|+|z|+1 m at this eye%s)",
                   v->source == SL_VIEW_FROM_CAMERA ? "camera" : "view", v->near_plane, who ? who : "the renderer",
                   zfar ? "float depth (1 - z/w)/2" : "float depth 1/w", lo,
                   zfar ? (isinf(v->far_plane) ? ", and a finite far plane: bound it with sl_view_bound_far"
                                               : ", and far/near <= 16777216")
                        : "");
}
