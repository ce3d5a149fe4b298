/* Cameras: basis vectors from yaw/pitch/roll, OpenGL view and projection matrices, frustum planes
 * and corners, and the box-frustum test every culler starts from. See include/sightline/camera.h
 * for the conventions.
 *
 * Everything is computed in double and rounded once to float at the end: the near plane of a
 * 0.1 m / 5000 m camera is badly conditioned in float, and the planes are built geometrically
 * from the basis (not extracted from the view-projection matrix) for the same reason. */
#include "sightline/camera.h"
#include "sightline/view.h"
#include "core/camera_internal.h"
#include "core/dvec3.h"
#include "core/sl_core.h"

#include <math.h>

/* Orthonormal camera basis in double. Roll turns up toward right about forward (right-hand rule
 * about +forward): the camera rolls clockwise as the viewer sees it, the image turns the other way. */
static void basis_d(const sl_camera *cam, sl_dvec3 *f, sl_dvec3 *r, sl_dvec3 *u)
{
    double cy = cos(cam->yaw), sy = sin(cam->yaw), cp = cos(cam->pitch), sp = sin(cam->pitch);
    double cr = cos(cam->roll), sr = sin(cam->roll);
    sl_dvec3 fw = sl_d3(cp * cy, cp * sy, sp);
    sl_dvec3 r0 = sl_d3(sy, -cy, 0);            /* forward x Z, normalised: well defined even at pitch +-90 */
    sl_dvec3 u0 = sl_d3(-sp * cy, -sp * sy, cp); /* r0 x forward */
    *f = fw;
    *r = sl_d3_add(sl_d3_scale(r0, cr), sl_d3_scale(u0, -sr));
    *u = sl_d3_add(sl_d3_scale(u0, cr), sl_d3_scale(r0, sr));
}

sl_camera sl_camera_default(void)
{
    sl_camera c;
    memset(&c, 0, sizeof c);
    c.position = (sl_vec3){0.0f, 0.0f, 1.7f};
    c.projection = SL_PERSPECTIVE;
    c.fov_y = (float)(60.0 * M_PI / 180.0);
    c.ortho_height = 100.0f;
    c.near_plane = 0.1f;
    c.far_plane = 5000.0f;
    c.width = 1024;
    c.height = 768;
    return c;
}

sl_status sl_camera_validate(const sl_camera *c, sl_error *err)
{
    if (!c)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "camera: NULL");
    if (!isfinite(c->position.x) || !isfinite(c->position.y) || !isfinite(c->position.z))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "camera: position (%g, %g, %g) is not finite", c->position.x,
                       c->position.y, c->position.z);
    if (!isfinite(c->yaw))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "camera: yaw %g is not finite", c->yaw);
    if (!isfinite(c->roll))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "camera: roll %g is not finite", c->roll);
    /* compared in float: (float)(pi/2) is slightly above pi/2 and must be accepted */
    if (!(c->pitch >= -(float)M_PI_2 && c->pitch <= (float)M_PI_2))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "camera: pitch %g is outside [-pi/2, pi/2]", c->pitch);
    if (c->projection != SL_PERSPECTIVE && c->projection != SL_ORTHOGRAPHIC)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "camera: projection %d is neither perspective nor orthographic",
                       (int)c->projection);
    if (!isfinite(c->fov_y) || (c->projection == SL_PERSPECTIVE && !(c->fov_y > 0 && c->fov_y < (float)M_PI)))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "camera: fov_y %g is outside (0, pi)", c->fov_y);
    if (!isfinite(c->ortho_height) || (c->projection == SL_ORTHOGRAPHIC && !(c->ortho_height > 0)))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "camera: ortho_height %g must be positive and finite",
                       c->ortho_height);
    if (!(c->near_plane > 0) || !isfinite(c->near_plane))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "camera: near plane %g must be positive and finite", c->near_plane);
    if (!(c->far_plane > c->near_plane) || !isfinite(c->far_plane))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "camera: far plane %g must be finite and beyond the near plane %g",
                       c->far_plane, c->near_plane);
    if (c->width == 0 || c->height == 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "camera: viewport %ux%u is empty", c->width, c->height);
    return SL_OK;
}

/* The view terms the depth checks read (view.h), without validating the camera. */
static sl_view depth_terms(const sl_camera *c)
{
    sl_view v;
    memset(&v, 0, sizeof v);
    v.eye = c->position;
    v.projection = c->projection;
    v.near_plane = c->near_plane;
    v.far_plane = c->far_plane;
    v.source = SL_VIEW_FROM_CAMERA;
    return v;
}

double sl_camera_min_near(const sl_camera *c, sl_depth_format format)
{
    if (!c)
        return 0;
    sl_view v = depth_terms(c);
    return sl_view_min_near(&v, format);
}

sl_status sl_camera_check_depth(const sl_camera *c, sl_depth_format format, const char *who, sl_error *err)
{
    if (!c)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "camera: NULL");
    sl_view v = depth_terms(c);
    return sl_view_check_depth(&v, format, who, err);
}

void sl_camera_basis(const sl_camera *cam, sl_vec3 *forward, sl_vec3 *right, sl_vec3 *up)
{
    sl_dvec3 f, r, u;
    basis_d(cam, &f, &r, &u);
    if (forward)
        *forward = sl_d3_to_vec3(f);
    if (right)
        *right = sl_d3_to_vec3(r);
    if (up)
        *up = sl_d3_to_vec3(u);
}

static sl_mat4 view_of(const sl_camera *cam, sl_dvec3 f, sl_dvec3 r, sl_dvec3 u)
{
    sl_dvec3 p = sl_d3_of(cam->position);
    sl_mat4 m;
    memset(&m, 0, sizeof m);
    /* rows of the rotation are right, up, -forward (the eye looks down -Z); column-major storage */
    m.m[0] = (float)r.x, m.m[4] = (float)r.y, m.m[8] = (float)r.z, m.m[12] = (float)-sl_d3_dot(r, p);
    m.m[1] = (float)u.x, m.m[5] = (float)u.y, m.m[9] = (float)u.z, m.m[13] = (float)-sl_d3_dot(u, p);
    m.m[2] = (float)-f.x, m.m[6] = (float)-f.y, m.m[10] = (float)-f.z, m.m[14] = (float)sl_d3_dot(f, p);
    m.m[15] = 1.0f;
    return m;
}

sl_mat4 sl_camera_view(const sl_camera *cam)
{
    sl_dvec3 f, r, u;
    basis_d(cam, &f, &r, &u);
    return view_of(cam, f, r, u);
}

static double aspect_of(const sl_camera *cam)
{
    return cam->height ? (double)cam->width / (double)cam->height : 1.0;
}

/* ty = tan(0.5 * fov_y) (perspective; unused for orthographic cameras) */
static sl_mat4 proj_of(const sl_camera *cam, double ty)
{
    sl_mat4 m;
    memset(&m, 0, sizeof m);
    double n = cam->near_plane, fa = cam->far_plane, aspect = aspect_of(cam);
    if (cam->projection == SL_ORTHOGRAPHIC) {
        double h = 0.5 * cam->ortho_height, w = h * aspect;
        m.m[0] = (float)(1.0 / w);
        m.m[5] = (float)(1.0 / h);
        m.m[10] = (float)(-2.0 / (fa - n));
        m.m[14] = (float)(-(fa + n) / (fa - n));
        m.m[15] = 1.0f;
    } else {
        double t = 1.0 / ty;
        m.m[0] = (float)(t / aspect);
        m.m[5] = (float)t;
        m.m[10] = (float)((fa + n) / (n - fa));
        m.m[11] = -1.0f;
        m.m[14] = (float)(2.0 * fa * n / (n - fa));
    }
    return m;
}

static double tan_half_fov(const sl_camera *cam)
{
    return cam->projection == SL_ORTHOGRAPHIC ? 0.0 : tan(0.5 * cam->fov_y);
}

sl_mat4 sl_camera_proj(const sl_camera *cam) { return proj_of(cam, tan_half_fov(cam)); }

/* p * v, accumulated in double */
static sl_mat4 mul_pv(sl_mat4 p, sl_mat4 v)
{
    sl_mat4 r;
    for (int c = 0; c < 4; c++)
        for (int row = 0; row < 4; row++) {
            double s = 0;
            for (int k = 0; k < 4; k++)
                s += (double)p.m[k * 4 + row] * (double)v.m[c * 4 + k];
            r.m[c * 4 + row] = (float)s;
        }
    return r;
}

sl_mat4 sl_camera_view_proj(const sl_camera *cam) { return mul_pv(sl_camera_proj(cam), sl_camera_view(cam)); }

/* Plane with inward normal n through point q, normalised. */
static sl_plane plane_through(sl_dvec3 n, sl_dvec3 q)
{
    double len = sqrt(sl_d3_dot(n, n));
    n = sl_d3_scale(n, 1.0 / len);
    return (sl_plane){(float)n.x, (float)n.y, (float)n.z, (float)-sl_d3_dot(n, q)};
}

static sl_frustum frustum_of(const sl_camera *cam, sl_dvec3 f, sl_dvec3 r, sl_dvec3 u, double ty)
{
    sl_dvec3 p = sl_d3_of(cam->position);
    double n = cam->near_plane, fa = cam->far_plane, aspect = aspect_of(cam);
    sl_frustum out;
    sl_dvec3 nc = sl_d3_add(p, sl_d3_scale(f, n)), fc = sl_d3_add(p, sl_d3_scale(f, fa));
    double nh, nw, fh, fw; /* half extents of the near and far rectangles */
    if (cam->projection == SL_ORTHOGRAPHIC) {
        double h = 0.5 * cam->ortho_height, w = h * aspect;
        nh = fh = h, nw = fw = w;
        /* side planes are parallel to forward: inward normals are +-right and +-up */
        out.planes[0] = plane_through(r, sl_d3_add(p, sl_d3_scale(r, -w)));
        out.planes[1] = plane_through(sl_d3_scale(r, -1), sl_d3_add(p, sl_d3_scale(r, w)));
        out.planes[2] = plane_through(u, sl_d3_add(p, sl_d3_scale(u, -h)));
        out.planes[3] = plane_through(sl_d3_scale(u, -1), sl_d3_add(p, sl_d3_scale(u, h)));
    } else {
        double tx = ty * aspect;
        nh = n * ty, nw = n * tx, fh = fa * ty, fw = fa * tx;
        /* each side plane passes through the eye; its inward normal is orthogonal to the edge
         * direction forward -+ t*axis, e.g. left: (right + tx*forward) . (forward - tx*right) = 0 */
        out.planes[0] = plane_through(sl_d3_add(r, sl_d3_scale(f, tx)), p);
        out.planes[1] = plane_through(sl_d3_add(sl_d3_scale(r, -1), sl_d3_scale(f, tx)), p);
        out.planes[2] = plane_through(sl_d3_add(u, sl_d3_scale(f, ty)), p);
        out.planes[3] = plane_through(sl_d3_add(sl_d3_scale(u, -1), sl_d3_scale(f, ty)), p);
    }
    out.planes[4] = plane_through(f, nc);
    out.planes[5] = plane_through(sl_d3_scale(f, -1), fc);
    const double sx[4] = {-1, 1, 1, -1}, sy[4] = {-1, -1, 1, 1}; /* bl, br, tr, tl */
    for (int i = 0; i < 4; i++) {
        out.corners[i] =
            sl_d3_to_vec3(sl_d3_add(nc, sl_d3_add(sl_d3_scale(r, sx[i] * nw), sl_d3_scale(u, sy[i] * nh))));
        out.corners[4 + i] =
            sl_d3_to_vec3(sl_d3_add(fc, sl_d3_add(sl_d3_scale(r, sx[i] * fw), sl_d3_scale(u, sy[i] * fh))));
    }
    return out;
}

sl_frustum sl_camera_frustum(const sl_camera *cam)
{
    sl_dvec3 f, r, u;
    basis_d(cam, &f, &r, &u);
    return frustum_of(cam, f, r, u, tan_half_fov(cam));
}

void sl_camera_all(const sl_camera *cam, sl_mat4 *view, sl_mat4 *proj, sl_mat4 *view_proj, sl_frustum *frustum,
                   sl_vec3 *forward, sl_vec3 *right, sl_vec3 *up, double *tan_half_fov_y)
{
    sl_dvec3 f, r, u;
    basis_d(cam, &f, &r, &u);
    double ty = tan_half_fov(cam);
    *view = view_of(cam, f, r, u);
    *proj = proj_of(cam, ty);
    *view_proj = mul_pv(*proj, *view);
    *frustum = frustum_of(cam, f, r, u, ty);
    *forward = sl_d3_to_vec3(f);
    *right = sl_d3_to_vec3(r);
    *up = sl_d3_to_vec3(u);
    *tan_half_fov_y = ty;
}

void sl_camera_look_at(sl_camera *cam, sl_vec3 target)
{
    double dx = (double)target.x - cam->position.x, dy = (double)target.y - cam->position.y,
           dz = (double)target.z - cam->position.z;
    double h = hypot(dx, dy);
    if (!(h > 0) && !(dz != 0))
        return; /* target at the eye (or not finite): no direction to look along */
    if (h > 0)
        cam->yaw = (float)atan2(dy, dx); /* straight up or down keeps the current yaw */
    float pitch = (float)atan2(dz, h);
    cam->pitch = SL_CLAMP(pitch, -(float)M_PI_2, (float)M_PI_2);
}

int sl_frustum_test_aabb(const sl_frustum *f, const sl_aabb *b)
{
    if (sl_aabb_is_empty(b))
        return 0;
    /* the shared classifier without slack (SL_MARGIN_PLANE_EXACT, core/margins.h) */
    static const float exact[6] = {SL_MARGIN_PLANE_EXACT, SL_MARGIN_PLANE_EXACT, SL_MARGIN_PLANE_EXACT,
                                   SL_MARGIN_PLANE_EXACT, SL_MARGIN_PLANE_EXACT, SL_MARGIN_PLANE_EXACT};
    int c = sl_frustum_classify_box(f->planes, exact, b, 0x3fu, true, NULL);
    return c < 0 ? 0 : c == 0 ? 2 : 1;
}
