/* Small helpers around the GEOS C API for the region layer (view cells, occluder shrinking).
 *
 * Only the reentrant GEOS functions (_r) are used, each call site with its own context handle:
 * there is no global GEOS state, so distinct threads may shrink or triangulate at the same time.
 * GEOS allocates with its own allocator (C++ new); everything that leaves these helpers is copied
 * into memory from the caller's sl_allocator. */
#ifndef SL_REGION_GEOS_UTIL_H
#define SL_REGION_GEOS_UTIL_H

#define GEOS_USE_ONLY_R_API
#include <geos_c.h>

#include "core/sl_core.h"

/* A GEOS context whose error and notice messages land in `message` (the last one). */
typedef struct sl_geos {
    GEOSContextHandle_t h;
    char message[256];
} sl_geos;

/* Start a context; false when GEOS could not create one. */
bool sl_geos_init(sl_geos *g);
void sl_geos_finish(sl_geos *g);

/* A polygon from a ring of n (x, y) float pairs (closing vertex added). NULL on failure. */
GEOSGeometry *sl_geos_polygon(sl_geos *g, const float *xy, uint32_t n);

/* A collection of n polygons (taking ownership of them; they are destroyed on failure). */
GEOSGeometry *sl_geos_collection(sl_geos *g, GEOSGeometry **polys, uint32_t n);

/* Visit every polygon of a geometry (a polygon, multipolygon or collection, recursively). */
typedef bool (*sl_geos_polygon_fn)(void *user, const GEOSGeometry *poly);
bool sl_geos_each_polygon(sl_geos *g, const GEOSGeometry *geom, sl_geos_polygon_fn fn, void *user);

/* The coordinates of a ring (closing vertex dropped) as doubles, into *xy (allocated with a,
 * 2 per vertex, *cap doubles held). Returns the vertex count, or -1 on failure. */
int sl_geos_ring_coords(sl_geos *g, const GEOSGeometry *ring, const sl_allocator *a, double **xy, size_t *cap);

#endif
