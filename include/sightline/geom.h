/* Sightline geometry value types shared by every header: vectors, boxes, matrices, planes.
 * Matrices are 4x4, column-major (OpenGL/cglm layout): m[col*4+row]. Affine object transforms
 * are 3x4 row-major: world = T[0..3]·(x,y,z,1), T[4..7]·..., T[8..11]·... */
#ifndef SIGHTLINE_GEOM_H
#define SIGHTLINE_GEOM_H

#include "core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sl_vec2 { float x, y; } sl_vec2;
typedef struct sl_vec3 { float x, y, z; } sl_vec3;
typedef struct sl_vec4 { float x, y, z, w; } sl_vec4;

/* Axis-aligned box; empty when min > max on any axis. */
typedef struct sl_aabb { sl_vec3 min, max; } sl_aabb;

/* Plane a*x + b*y + c*z + d >= 0 on the inside. */
typedef struct sl_plane { float a, b, c, d; } sl_plane;

typedef struct sl_mat4 { float m[16]; } sl_mat4;

/* 3x4 row-major affine transform. */
typedef struct sl_affine { float m[12]; } sl_affine;

/* An empty box (min = +inf, max = -inf), ready to grow. */
SL_API sl_aabb sl_aabb_empty(void);
/* Grow box b to contain point p. */
SL_API void sl_aabb_grow(sl_aabb *b, sl_vec3 p);
/* Grow box b to contain box o. */
SL_API void sl_aabb_merge(sl_aabb *b, const sl_aabb *o);
/* True when b contains no point. */
SL_API bool sl_aabb_is_empty(const sl_aabb *b);
/* Box of the 8 transformed corners of b. */
SL_API sl_aabb sl_aabb_transform(const sl_aabb *b, const sl_affine *t);

/* The identity 3x4 transform. */
SL_API sl_affine sl_affine_identity(void);
/* Apply an affine transform to a point. */
SL_API sl_vec3 sl_affine_point(const sl_affine *t, sl_vec3 p);

#ifdef __cplusplus
}
#endif
#endif
