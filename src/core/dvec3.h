/* Internal: the one kit of double-precision 3-vectors (issue 13: camera.c, gvs.c and the city
 * generator each had their own) and the ray-triangle test (the point-in-mesh parity tests of the
 * occluder shrinker and the view cells, and the tests). Header-only arithmetic, inlined: each
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

/* Does the ray o + t d, t > 0, meet the triangle (a, b, c)? Möller–Trumbore, both faces, edges and
 * vertices included (barycentric u, v >= 0, u + v <= 1); a ray whose |determinant| is below
 * det_eps (parallel to the triangle's plane, or a degenerate triangle) misses. *t_out (may be NULL)
 * receives t on a hit. src/core/dvec3.c. */
bool sl_ray_triangle(const double o[3], const double d[3], const double a[3], const double b[3], const double c[3],
                     double det_eps, double *t_out);

#endif
