/* Internal: the one vector kit (issue 13: camera.c, gvs.c, the city generator and the near-wall
 * views each had their own): double-precision 3-vectors, 2-vectors (the city generator's plan
 * geometry), the float sl_vec3 difference, cross product and length of mesh triangles (the
 * near-wall views), and the ray-triangle test (the point-in-mesh parity tests of the occluder
 * shrinker and the view cells, and the tests). Header-only arithmetic, inlined: each
 * function is the textbook expression in the order written, so code moved onto it computes the same
 * bits as before. */
#ifndef SL_CORE_DVEC3_H
#define SL_CORE_DVEC3_H

#include "sightline/geom.h"

#include <math.h>
#include <stdbool.h>

typedef struct sl_dvec3 {
    double x, y, z;
} sl_dvec3;

static inline sl_dvec3 sl_d3(double x, double y, double z) { return (sl_dvec3){x, y, z}; }
static inline sl_dvec3 sl_d3_add(sl_dvec3 a, sl_dvec3 b) { return sl_d3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline sl_dvec3 sl_d3_sub(sl_dvec3 a, sl_dvec3 b) { return sl_d3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline sl_dvec3 sl_d3_scale(sl_dvec3 a, double s) { return sl_d3(a.x * s, a.y * s, a.z * s); }
static inline double sl_d3_dot(sl_dvec3 a, sl_dvec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline sl_dvec3 sl_d3_cross(sl_dvec3 a, sl_dvec3 b)
{
    return sl_d3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline double sl_d3_len(sl_dvec3 a) { return sqrt(sl_d3_dot(a, a)); }
/* a / |a|; a vector shorter than 1e-300 gives the zero vector (never NaN). */
static inline sl_dvec3 sl_d3_unit(sl_dvec3 a)
{
    double l = sl_d3_len(a);
    return l > 1e-300 ? sl_d3_scale(a, 1.0 / l) : sl_d3(0, 0, 0);
}
static inline sl_dvec3 sl_d3_of(sl_vec3 v) { return sl_d3(v.x, v.y, v.z); }
static inline sl_dvec3 sl_d3_of_array(const double *p) { return sl_d3(p[0], p[1], p[2]); }
/* Rounded to float. */
static inline sl_vec3 sl_d3_to_vec3(sl_dvec3 v) { return (sl_vec3){(float)v.x, (float)v.y, (float)v.z}; }

/* ---- 2-vectors in double (plan geometry) ---- */
typedef struct sl_dvec2 {
    double x, y;
} sl_dvec2;

static inline sl_dvec2 sl_d2(double x, double y) { return (sl_dvec2){x, y}; }
static inline sl_dvec2 sl_d2_add(sl_dvec2 a, sl_dvec2 b) { return sl_d2(a.x + b.x, a.y + b.y); }
static inline sl_dvec2 sl_d2_sub(sl_dvec2 a, sl_dvec2 b) { return sl_d2(a.x - b.x, a.y - b.y); }
static inline sl_dvec2 sl_d2_scale(sl_dvec2 a, double s) { return sl_d2(a.x * s, a.y * s); }
static inline double sl_d2_dot(sl_dvec2 a, sl_dvec2 b) { return a.x * b.x + a.y * b.y; }
/* z of the 3D cross product: > 0 when b turns counter-clockwise from a. */
static inline double sl_d2_cross(sl_dvec2 a, sl_dvec2 b) { return a.x * b.y - a.y * b.x; }
static inline double sl_d2_len(sl_dvec2 a) { return sqrt(a.x * a.x + a.y * a.y); }
static inline sl_dvec2 sl_d2_lerp(sl_dvec2 a, sl_dvec2 b, double t)
{
    return sl_d2(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t);
}
/* a / |a|; the zero vector gives the zero vector. */
static inline sl_dvec2 sl_d2_unit(sl_dvec2 a)
{
    double l = sl_d2_len(a);
    return l > 0 ? sl_d2_scale(a, 1.0 / l) : sl_d2(0, 0);
}
/* The left normal of a direction (inward for a counter-clockwise polygon's edge). */
static inline sl_dvec2 sl_d2_left(sl_dvec2 d) { return sl_d2(-d.y, d.x); }
/* (p, z) */
static inline sl_dvec3 sl_d3_of_d2(sl_dvec2 p, double z) { return sl_d3(p.x, p.y, z); }

/* ---- float 3-vectors (sl_vec3), in float as a mesh's coordinates are ---- */
static inline sl_vec3 sl_v3_sub(sl_vec3 a, sl_vec3 b) { return (sl_vec3){a.x - b.x, a.y - b.y, a.z - b.z}; }
static inline sl_vec3 sl_v3_cross(sl_vec3 a, sl_vec3 b)
{
    return (sl_vec3){a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
/* |a| computed in double. */
static inline double sl_v3_len(sl_vec3 a) { return sqrt((double)a.x * a.x + (double)a.y * a.y + (double)a.z * a.z); }

/* Does the ray o + t d, t > 0, meet the triangle (a, b, c)? Möller–Trumbore, both faces, edges and
 * vertices included (barycentric u, v >= 0, u + v <= 1); a ray whose |determinant| is below
 * det_eps (parallel to the triangle's plane, or a degenerate triangle) misses. *t_out (may be NULL)
 * receives t on a hit. src/core/dvec3.c. */
bool sl_ray_triangle(const double o[3], const double d[3], const double a[3], const double b[3], const double c[3],
                     double det_eps, double *t_out);

#endif
