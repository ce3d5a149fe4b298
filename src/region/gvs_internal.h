/* Guided visibility sampling (GVS) as a library function, for the `gvs` PVS method (gvs.c), the
 * tests and bench/gvs.c.
 *
 * P. Wonka, M. Wimmer, K. Zhou, S. Maierhofer, G. Hesina, A. Reshetov, "Guided Visibility
 * Sampling", ACM TOG 25(3), SIGGRAPH 2006 (chapter 5 of Wimmer's habilitation, 2007).
 *
 * Given a view cell, GVS finds the triangles that rays leaving the cell hit first: an AGGRESSIVE
 * set (every triangle it reports is visible from the cell, up to float rounding; some visible ones
 * may be missed). It casts Halton random rays from the cell, and every ray that finds a new
 * triangle seeds adaptive border sampling (ABS) around that triangle from the same origin; ABS
 * rays that run into a closer triangle trigger reverse sampling (RS), which moves the origin
 * across the cell so that the new ray passes just beside the occluder. It stops when a window of
 * rays finds too few new triangles, or at a ray budget. The same code run with ABS and RS off is
 * the plain random-sampling baseline (RAND in the paper). docs/gvs.md has the details and the
 * choices the paper leaves open.
 *
 * A sampler (sl_gvs) is one thread's working memory over a shared, read-only Embree scene; its
 * results for a cell depend on the scene, the cells, the options and the cell index only (not on
 * the thread, the order of cells or earlier calls). */
#ifndef SL_REGION_GVS_INTERNAL_H
#define SL_REGION_GVS_INTERNAL_H

#include "sightline/region.h"

#include "embree/embree_scene.h"

typedef enum sl_gvs_sampler {
    SL_GVS_GUIDED = 0,          /* random rays + ABS + RS (the paper's GVS) */
    SL_GVS_RANDOM = 1           /* random rays only (the paper's RAND baseline) */
} sl_gvs_sampler;

typedef enum sl_gvs_origins {
    SL_GVS_ORIGINS_AUTO = 0,    /* boundary for prism and box cells, volume for clusters */
    SL_GVS_ORIGINS_BOUNDARY = 1,/* on the cell's faces, directions over the outward hemisphere
                                   (the paper's generator); prism and box cells only */
    SL_GVS_ORIGINS_VOLUME = 2   /* inside the cell, directions over the whole sphere */
} sl_gvs_origins;

typedef enum sl_gvs_stop {
    SL_GVS_STOP_CONVERGED = 0,  /* a window of rays found at most min_new new triangles */
    SL_GVS_STOP_MAX_RAYS = 1,   /* the ray budget ran out */
    SL_GVS_STOP_NO_RAYS = 2     /* the cell yields no ray origin (an empty cluster) */
} sl_gvs_stop;

/* Options; start from sl_gvs_defaults(). */
typedef struct sl_gvs_options {
    uint32_t sampler;           /* sl_gvs_sampler */
    uint32_t origins;           /* sl_gvs_origins */
    double eps;                 /* relative enlargement (angle, radians) of ABS polygons and the
                                   smallest angle between two ABS rays; eps * scene diagonal is the
                                   world distance below which two hits count as adjacent (5e-5) */
    double rs_delta;            /* RS fires when a ray hits closer than the original triangle's
                                   plane by more than rs_delta * that plane's distance (0.01) */
    uint64_t window;            /* rays per termination window (1,000,000) */
    uint64_t min_new;           /* stop when a window finds at most this many new triangles (50) */
    uint64_t max_rays;          /* hard budget (10,000,000) */
    uint64_t initial;           /* random rays cast before ABS starts (the paper's progressive
                                   variant); 0: ABS follows every new triangle at once (0) */
    uint32_t batch;             /* random rays traced per call (64) */
    uint32_t max_depth;         /* deepest ABS edge subdivision (32) */
    bool auto_visible;          /* prism and box cells: triangles meeting the cell are visible by
                                   definition (true) */
    bool log_curve;             /* record (rays, triangles) at every window end (true) */
    uint64_t seed;              /* rotates the Halton sequence; with the cell index (0) */
} sl_gvs_options;

/* The defaults above. */
sl_gvs_options sl_gvs_defaults(void);
/* Check options: SL_ERROR_INVALID_ARGUMENT naming the field. */
sl_status sl_gvs_options_check(const sl_gvs_options *o, sl_error *err);

typedef struct sl_gvs_stats {
    uint64_t rays;              /* all rays cast */
    uint64_t random_rays, border_rays, reverse_rays;
    uint64_t reverse_tries;     /* discontinuities found by ABS */
    uint64_t reverse_missed;    /* ... whose mutated ray did not meet the cell (discarded) */
    uint64_t origin_rejects;    /* volume origins outside a cluster, drawn again */
    uint32_t triangles;         /* found (auto-visible ones included) */
    uint32_t auto_visible;      /* triangles meeting the cell */
    uint32_t objects;
    uint32_t stop;              /* sl_gvs_stop */
    double seconds;
} sl_gvs_stats;

/* One cell's answer. Arrays belong to the sampler and stay valid until its next call. */
typedef struct sl_gvs_result {
    const uint32_t *triangles;  /* global triangle ids (embree_scene.h), ascending */
    uint32_t triangle_count;
    const uint32_t *objects;    /* object ids, ascending: the objects owning a found triangle */
    uint32_t object_count;
    const uint64_t *curve;      /* pairs (rays, triangles found) at each window end */
    uint32_t curve_count;       /* pairs */
    sl_gvs_stats stats;
} sl_gvs_result;

typedef struct sl_gvs_t *sl_gvs;

/* A sampler over an Embree scene of `scene` (both must outlive it). alloc may be NULL. */
sl_status sl_gvs_create(const sl_es *es, sl_scene scene, const sl_gvs_options *opt, const sl_allocator *alloc,
                        sl_gvs *out, sl_error *err);
/* Release it. NULL is ignored. */
void sl_gvs_destroy(sl_gvs g);
/* Sample cell `cell`. CLUSTER cells need the scene's BSP (the sampler's scene). */
sl_status sl_gvs_cell(sl_gvs g, sl_viewcells cells, uint32_t cell, sl_gvs_result *out, sl_error *err);

/* A uniformly random point inside cell `cell` from two uniform numbers in [0,1) per try (u has
 * 4 * tries entries); for error evaluation views. False when no try landed inside (clusters). */
bool sl_gvs_cell_point(sl_gvs g, sl_viewcells cells, uint32_t cell, const double *u, uint32_t tries, sl_vec3 *out);

/* The 9-vertex enlarged polygon t' of triangle tri (3 vertices, 9 doubles) seen from o (section
 * 5.3.2), written as 9 points (27 doubles) in order around the triangle; for tests. */
void sl_gvs_enlarge(const double o[3], const double *tri, double eps, double *out);

#endif
