/* GEOS helpers for the region layer: one context per call site, messages captured per context. */
#include "geos_util.h"

/* GEOS hands the formatted text and our user pointer to this handler. */
static void on_message_r(const char *message, void *user)
{
    sl_geos *g = user;
    snprintf(g->message, sizeof g->message, "%s", message ? message : "(no message)");
}

bool sl_geos_init(sl_geos *g)
{
    g->message[0] = 0;
    g->h = GEOS_init_r();
    if (!g->h)
        return false;
    GEOSContext_setErrorMessageHandler_r(g->h, on_message_r, g);
    GEOSContext_setNoticeMessageHandler_r(g->h, NULL, NULL);
    return true;
}

void sl_geos_finish(sl_geos *g)
{
    if (g->h)
        GEOS_finish_r(g->h);
    g->h = NULL;
}

GEOSGeometry *sl_geos_polygon(sl_geos *g, const float *xy, uint32_t n)
{
    if (n < 3)
        return NULL;
    GEOSCoordSequence *cs = GEOSCoordSeq_create_r(g->h, n + 1, 2);
    if (!cs)
        return NULL;
    for (uint32_t i = 0; i <= n; i++) {
        uint32_t k = i % n;
        if (!GEOSCoordSeq_setXY_r(g->h, cs, i, xy[2 * k], xy[2 * k + 1])) {
            GEOSCoordSeq_destroy_r(g->h, cs);
            return NULL;
        }
    }
    GEOSGeometry *ring = GEOSGeom_createLinearRing_r(g->h, cs); /* takes cs */
    if (!ring)
        return NULL;
    return GEOSGeom_createPolygon_r(g->h, ring, NULL, 0); /* takes ring */
}

GEOSGeometry *sl_geos_collection(sl_geos *g, GEOSGeometry **polys, uint32_t n)
{
    GEOSGeometry *c = GEOSGeom_createCollection_r(g->h, GEOS_MULTIPOLYGON, polys, n);
    if (!c)
        for (uint32_t i = 0; i < n; i++)
            GEOSGeom_destroy_r(g->h, polys[i]);
    return c;
}

bool sl_geos_each_polygon(sl_geos *g, const GEOSGeometry *geom, sl_geos_polygon_fn fn, void *user)
{
    int type = GEOSGeomTypeId_r(g->h, geom);
    if (type == GEOS_POLYGON)
        return GEOSisEmpty_r(g->h, geom) ? true : fn(user, geom);
    if (type == GEOS_MULTIPOLYGON || type == GEOS_GEOMETRYCOLLECTION) {
        int n = GEOSGetNumGeometries_r(g->h, geom);
        for (int i = 0; i < n; i++) {
            const GEOSGeometry *part = GEOSGetGeometryN_r(g->h, geom, i);
            if (part && !sl_geos_each_polygon(g, part, fn, user))
                return false;
        }
        return n >= 0;
    }
    return true; /* points and lines carry no area */
}

int sl_geos_ring_coords(sl_geos *g, const GEOSGeometry *ring, const sl_allocator *a, double **xy, size_t *cap)
{
    const GEOSCoordSequence *cs = GEOSGeom_getCoordSeq_r(g->h, ring);
    unsigned int n = 0;
    if (!cs || !GEOSCoordSeq_getSize_r(g->h, cs, &n) || n < 4 || n > (1u << 28))
        return -1;
    size_t need = 2 * (size_t)n;
    if (*cap < need) {
        double *p = sl_realloc(a, *xy, *cap * sizeof(double), need * sizeof(double));
        if (!p)
            return -1;
        *xy = p;
        *cap = need;
    }
    for (unsigned int i = 0; i < n; i++)
        if (!GEOSCoordSeq_getXY_r(g->h, cs, i, &(*xy)[2 * i], &(*xy)[2 * i + 1]))
            return -1;
    return (int)n - 1; /* the closing vertex repeats the first */
}
