/* Convex parts of an occluder mesh (res=any's inner coverage of MESH and SCENE_MESH proxies,
 * sl_occ_render_mesh_hull in occlusion/inner_coverage.c). A part is a connected set of a mesh's triangles (connected
 * through vertices at equal positions) that bounds a convex solid: every vertex of the part lies
 * on the inner side of every triangle's plane, within `dev` (the largest excess found), and every
 * edge is shared by two triangles, or the edges used once form at most SL_OCC_CPART_MAX_HOLES
 * loops, each in a plane that supports the part (a car body open underneath, a trunk open at both
 * ends): a hole's plane passes through hole_v[h][0..2], its inner side holding the part's vertices. Such a part is drawn by its silhouette like a prism; its triangles, wound
 * outward here, give the front planes. Triangles in no part are drawn one by one (`rest`). */
#ifndef SL_CULL_CONVEX_PARTS_H
#define SL_CULL_CONVEX_PARTS_H

#include "sightline/core.h"

#include <stdbool.h>
#include <stdint.h>

#define SL_OCC_CPART_MAX_VERTS 128 /* larger convex parts are left to the rest */
#define SL_OCC_CPART_MAX_TRIS 252
#define SL_OCC_CPART_MAX_HOLES 4

typedef struct sl_occ_cpart {
    uint32_t vfirst, vcount;  /* welded vertices in pos (mesh-local) */
    uint32_t tfirst, tcount;  /* triangles in tri (3 part-local vertex indices each, wound outward)
                                 and src (the mesh's triangle index of each) */
    uint32_t holes;           /* open: its holes (loops of edges used once), each in a plane through
                                 part vertices hole_v[h][0..2] (wound outward) that supports the part */
    uint32_t hole_v[SL_OCC_CPART_MAX_HOLES][3];
    double dev;               /* largest distance of a vertex outside a triangle's plane (mesh units) */
} sl_occ_cpart;

typedef struct sl_occ_cparts {
    bool built;
    size_t cap;               /* triangles the arrays were made for */
    uint32_t part_count, vert_count, tri_count, rest_count;
    sl_occ_cpart *parts;
    float *pos;
    uint32_t *tri, *src;
    uint32_t *rest;           /* triangles of the mesh in no part */
} sl_occ_cparts;

/* Find the convex parts of a mesh (positions xyz, nv vertices, nt triangles). */
sl_status sl_occ_cparts_build(const float *pos, uint32_t nv, const uint32_t *idx, uint32_t nt, const sl_allocator *a,
                              sl_occ_cparts *out);
void sl_occ_cparts_free(sl_occ_cparts *c, const sl_allocator *a);

#endif
