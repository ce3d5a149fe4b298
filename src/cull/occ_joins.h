/* Joins: convex prisms across the walls where two occluder prisms meet (res=any's silhouette rule,
 * docs/occlusion.md "Joins").
 *
 * res=any draws each convex piece of a prism by its convex silhouette eroded by the pixel footprint
 * (render_prism_hull in occluders.c). Where two pieces meet — two buildings of a block along their
 * party wall, or two convex pieces of one non-convex footprint along the diagonal between them —
 * both silhouettes are eroded at the shared wall, and a crack of one to two pixels is left in the
 * buffer through which everything behind the block stays visible.
 *
 * A join is a box standing across such a shared wall: a rectangle in plan, centred on the shared
 * segment, reaching w metres into each side, from the higher of the two bases to the lower of the
 * two roofs, every face kept `inset` inside (sl_occ_joins_build). It is drawn as one more convex
 * piece of its owner's prism, by the same eroded silhouette rule, so its own silhouette is eroded
 * too; but its silhouette straddles the projection of the shared wall, and the crack lies well
 * inside it wherever w is more than a pixel or two on screen.
 *
 * Why a join is safe at any resolution: it is an ordinary occluder proxy. Each half of the
 * rectangle is checked to lie inside the footprint polygon on its side (no footprint edge but the
 * shared one meets it, and its centre is inside), its height range lies inside both footprints'
 * ranges, and every footprint lies inside its building's solid (sl_scene_add_footprint). So the
 * join lies inside the union of the two buildings: a ray from the eye that reaches a point of the
 * join has entered one of the two solids through its surface before, at a nearer depth, and
 * whatever lies behind that point is hidden by the surface. The silhouette rule then writes, for a
 * pixel square inside its eroded hull, a depth no nearer than the join's surface at any sample
 * position of the square (hull_draw's argument, unchanged), so the pixel's depth is no nearer than
 * the buildings' surfaces there at any resolution or sample position. Nothing is left uneroded. A
 * join across a party wall is used only while its partner's prism is usable (enabled: the
 * partner has not moved off its footprint; the eye outside the partner's boxes and the near plane
 * clear of them, sl_occ_usable), and only while the eye keeps out of the join's own box.
 *
 * Not used by res=culling (built only with screen_margin), nor by the methods that read the
 * prisms' faces (frusta, hom's and cplp's face lists are unchanged). */
#ifndef SL_CULL_OCC_JOINS_H
#define SL_CULL_OCC_JOINS_H

#include "sightline/core.h"
#include "sightline/geom.h"

#include <stdbool.h>
#include <stdint.h>

struct sl_occ_set;
struct sl_occ_view;

typedef struct sl_occ_join {
    uint32_t partner;   /* the prism proxy on the other side (the owner itself inside one building) */
    float top[4][3];    /* the rectangle at the join's top, counter-clockwise seen from +z (world) */
    float z0;           /* its base */
    sl_aabb box;
} sl_occ_join;

typedef struct sl_occ_joins {
    uint32_t proxy_count;
    uint32_t *first;    /* proxy_count + 1 entries: proxy p owns joins [first[p], first[p + 1]) */
    uint32_t count;
    sl_occ_join *joins;
    uint32_t across, inside; /* joins across party walls, inside one footprint (statistics) */
} sl_occ_joins;

/* Find the joins of a proxy set's prisms: across every wall segment two footprints share exactly
 * (antiparallel edges on one line, overlapping), and across every edge two convex roof pieces of
 * one prism share. `inset` metres (at least 0.01) kept inside on every side. *out is NULL when
 * there is none. */
sl_status sl_occ_joins_build(const struct sl_occ_set *s, double inset, const sl_allocator *a, sl_occ_joins **out,
                             sl_error *err);
void sl_occ_joins_destroy(sl_occ_joins *j, const sl_allocator *a);

/* May join j of prism proxy `owner` be drawn in this view (see above)? The owner's own usability
 * is the caller's (it is drawing the owner). */
bool sl_occ_join_usable(const struct sl_occ_set *s, uint32_t owner, const sl_occ_join *j,
                        const struct sl_occ_view *v);

#endif
