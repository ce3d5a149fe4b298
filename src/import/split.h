/* Splitting a triangle soup into spatially compact pieces (internal to the library).
 *
 * Used by the assimp importer for --split; written for any indexed triangle soup, so that the
 * city generator or the Quake III importer can cut their large meshes the same way.
 *
 * The cut is a recursive partition of triangle centroids: a set of n triangles that is larger
 * than `target` is to become k = ceil(n / target) pieces; it is cut across the longest axis of its
 * centroid bounds at the (floor(k/2) / k)-quantile, and each side recurses with its share of k.
 * Every piece therefore holds at most `target` triangles and all pieces are within one triangle of
 * n / k. Centroid ties are broken by triangle index, so the result depends only on the input. */
#ifndef SL_SCENE_SPLIT_H
#define SL_SCENE_SPLIT_H

#include "core/sl_core.h"

/* One piece: a range of the result's vertex and triangle arrays. */
typedef struct sl_split_piece {
    uint32_t first_vertex;      /* into positions/normals (vertex units) */
    uint32_t vertex_count;
    uint32_t first_triangle;    /* into indices (triangle units) and source_triangle */
    uint32_t triangle_count;
    sl_aabb bounds;             /* of the piece's vertices */
} sl_split_piece;

/* The pieces, each with only the vertices it uses. Indices are local to their piece
 * (0..vertex_count-1). Within a piece, triangles keep their input order and vertices appear in
 * order of first use. A vertex used by several pieces is copied into each. */
typedef struct sl_split_result {
    sl_split_piece *pieces;
    uint32_t piece_count;
    uint32_t vertex_count;      /* total over all pieces */
    uint32_t triangle_count;    /* equals the input triangle count */
    float *positions;           /* 3 per vertex */
    float *normals;             /* 3 per vertex, or NULL when the input had none */
    uint32_t *indices;          /* 3 per triangle, local to the piece */
    uint32_t *source_triangle;  /* input triangle index of each output triangle */
} sl_split_result;

/* Split a triangle soup (pos: 3 floats per vertex, nrm: 3 floats per vertex or NULL, idx: 3 per
 * triangle, each < nv) into pieces of at most `target` triangles (target >= 1). Fails on an
 * out-of-range index, a non-finite position or when the output would exceed 2^32-1 vertices.
 * A soup of at most `target` triangles comes back as one piece (compacted). Free with
 * sl_split_free. */
sl_status sl_split_mesh(const float *pos, const float *nrm, uint32_t nv, const uint32_t *idx, uint32_t nt, uint32_t target,
                        const sl_allocator *a, sl_split_result *out, sl_error *err);

/* Release the arrays of a result (safe on a zeroed or partially filled result). */
void sl_split_free(const sl_allocator *a, sl_split_result *r);

#endif
