/* Sightline view cells and the region oracle: the "from where" of from-region visibility.
 *
 * A view cell is a region the viewer may stand in; a PVS (pvs.h) stores, per cell, every object
 * visible from anywhere in it. Three cell shapes exist:
 *  - PRISM: a triangle in the XY plane (counter-clockwise) times an eye-height interval
 *    [z_min, z_max] — the cells of a city, from a constrained triangulation of the free street
 *    space refined to a maximum edge length (Wonka's thesis, section 5.3);
 *  - BOX: an axis-aligned box — the regular-grid fallback and the adaptive subdivision of a
 *    navigable volume;
 *  - CLUSTER: the BSP leaves of one Quake III cluster (the map's own cells, so that a PVS compares
 *    with the map's built-in one); its bounds are the union of the leaf boxes, and a point belongs
 *    to it when the scene's BSP puts the point in a leaf of that cluster.
 * Cells of one set do not overlap (up to shared boundaries); a point on a shared boundary belongs
 * to the cell the lookup finds first (deterministic). Cells are numbered 0..count-1 in a
 * deterministic order: the same scene and options always give the same cells, bit for bit.
 *
 * Lookup: sl_viewcells_locate walks a balanced bounding-box tree over the cells (logarithmic in
 * the cell count for disjoint cells), or the scene's BSP tree for clusters.
 *
 * The region oracle estimates the set of objects visible from a whole cell by dense sampling:
 * points on the cell's boundary (vertices, edges at a chosen spacing, random points on the faces)
 * and random points inside it, each rendered as a cube map by the point oracle (truth.h). The set
 * it returns is a LOWER BOUND of the exact from-region visible set: an object seen only from
 * between the samples, or only through a gap thinner than a cube-map pixel, is missed. It reports
 * its convergence (how many objects the last 10% of the samples added) so that a reader can
 * judge how close the bound is. Conservative PVS methods must contain every object it finds.
 */
#ifndef SIGHTLINE_REGION_H
#define SIGHTLINE_REGION_H

#include "core.h"
#include "geom.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sl_viewcells_t *sl_viewcells;

/* Cell shapes. Values are stored in .slpvs files: never renumber. */
typedef enum sl_viewcell_shape {
    SL_CELL_PRISM = 0,
    SL_CELL_BOX = 1,
    SL_CELL_CLUSTER = 2
} sl_viewcell_shape;

/* One view cell (64 bytes). */
typedef struct sl_viewcell {
    uint32_t shape;             /* sl_viewcell_shape */
    int32_t cluster;            /* CLUSTER: the BSP cluster; -1 otherwise */
    sl_vec2 tri[3];             /* PRISM: the triangle, counter-clockwise; zero otherwise */
    float z_min, z_max;         /* PRISM and BOX: lowest and highest eye position (absolute z) */
    sl_aabb bounds;             /* the cell's box (PRISM: triangle x [z_min, z_max]) */
} sl_viewcell;

/* Options of the cell generators; a zero-initialised struct gives the defaults. */
typedef struct sl_viewcell_options {
    float max_edge;             /* streets: longest triangle edge in metres (default 12); grid:
                                   the square cell's side (default 8); adaptive: the largest
                                   cell extent (default 16) */
    float min_edge;             /* adaptive: cells are not split below this extent (default 2) */
    float eye_min, eye_max;     /* eye heights above the ground (defaults 1.0 and 2.0 m); cells
                                   reach from the lowest ground under them + eye_min to the
                                   highest ground + eye_max */
    uint32_t max_cells;         /* refuse to make more cells than this (default 4,000,000) */
    const sl_allocator *alloc;  /* NULL: the default allocator */
    sl_progress progress;
} sl_viewcell_options;

/* Cells over the street network: the union of the scene's street polygons (free space) minus the
 * building footprints, triangulated with GEOS's constrained Delaunay triangulation after its
 * boundary is densified to max_edge, then triangles are split at their longest edge until no edge
 * exceeds max_edge. SL_ERROR_UNSUPPORTED on a scene without street polygons. */
SL_API sl_status sl_viewcells_from_streets(sl_scene scene, const sl_viewcell_options *opt, sl_viewcells *out,
                                           sl_error *err);
/* Regular-grid fallback: square cells of side max_edge over the street polygons' bounds (or the
 * scene's bounds without streets), kept when they meet the free space (any cell without streets). */
SL_API sl_status sl_viewcells_grid(sl_scene scene, const sl_viewcell_options *opt, sl_viewcells *out, sl_error *err);
/* One CLUSTER cell per Quake III cluster that has at least one leaf. SL_ERROR_UNSUPPORTED without
 * BSP data. Cell i is not cluster i when clusters are empty: use the cells' `cluster` field. */
SL_API sl_status sl_viewcells_from_bsp(sl_scene scene, const sl_viewcell_options *opt, sl_viewcells *out,
                                       sl_error *err);
/* Adaptive subdivision of a navigable volume: `volume` (a box), or, when volume is NULL, the
 * inside of the closed mesh of scene object `object` (its world box, keeping the cells whose
 * centre is inside the mesh by ray parity). A box is split in two across its longest axis while it
 * is larger than max_edge, or while it is larger than min_edge and meets another object's bounds.
 * BOX cells, in depth-first order. */
SL_API sl_status sl_viewcells_adaptive(sl_scene scene, const sl_aabb *volume, uint32_t object,
                                       const sl_viewcell_options *opt, sl_viewcells *out, sl_error *err);
/* Cells from explicit records (validated: known shape, finite coordinates, CCW non-degenerate
 * triangles, z_min <= z_max, bounds consistent with the shape). alloc may be NULL. */
SL_API sl_status sl_viewcells_create(const sl_viewcell *cells, uint32_t count, const sl_allocator *alloc,
                                     sl_viewcells *out, sl_error *err);
/* Release cells. NULL is ignored. */
SL_API void sl_viewcells_destroy(sl_viewcells cells);

/* Number of cells. */
SL_API uint32_t sl_viewcells_count(sl_viewcells cells);
/* The cells as one array of sl_viewcells_count records (valid until destroy). */
SL_API const sl_viewcell *sl_viewcells_data(sl_viewcells cells);
/* The cell containing point p, or SL_NONE. CLUSTER cells need the scene they were made from (its
 * BSP decides); other shapes ignore `scene` (may be NULL). Allocation-free; safe from any number
 * of threads at once. */
SL_API uint32_t sl_viewcells_locate(sl_viewcells cells, sl_scene scene, sl_vec3 p);
/* The cells meeting box `box` (closed), ascending and without repeats, into out (at most capacity;
 * returns how many were written). *covered (may be NULL) tells whether those cells cover the whole
 * box: CLUSTER cells when every BSP leaf the box meets (through the scene's BSP tree) belongs to a
 * cell — none is solid or void (a leaf without a cluster); PRISM and BOX cells when the volumes of
 * the box's intersections with the cells add up to the box's (up to 1e-6 of it; cells do not
 * overlap). False too when the cells do not fit in out. Allocation-free; safe from any number of
 * threads at once. The pvs culler calls it with the box of its camera's near-plane region. */
SL_API uint32_t sl_viewcells_overlap(sl_viewcells cells, sl_scene scene, const sl_aabb *box, uint32_t *out,
                                     uint32_t capacity, bool *covered);
/* The cell nearest to point p and its distance in metres (0 inside): PRISM cells by the exact
 * distance to the prism (triangle x [z_min, z_max]), BOX and CLUSTER cells by the distance to
 * their box (a cluster's box may hold space outside the cluster). SL_NONE (and *distance
 * INFINITY) for no cells or a point that is not finite. Ties go to the lower cell number.
 * distance may be NULL. Allocation-free, O(cells); safe from any number of threads at once. */
SL_API uint32_t sl_viewcells_nearest(sl_viewcells cells, sl_vec3 p, double *distance);
/* True when point p lies in cell `cell` (closed; CLUSTER cells need the scene). */
SL_API bool sl_viewcell_contains(sl_viewcells cells, sl_scene scene, uint32_t cell, sl_vec3 p);
/* Fingerprint (XXH3-64) of the cell records: equal cells, equal key. */
SL_API uint64_t sl_viewcells_key(sl_viewcells cells);
/* Total area (PRISM, BOX: XY area) and counts, for reports. */
typedef struct sl_viewcells_stats {
    uint32_t count, prisms, boxes, clusters;
    double area;                /* XY area of prisms and boxes, m^2 */
    double min_edge, max_edge;  /* shortest and longest prism edge / box side */
    double min_angle_deg;       /* smallest triangle angle of the prisms */
} sl_viewcells_stats;
SL_API void sl_viewcells_get_stats(sl_viewcells cells, sl_viewcells_stats *out);

/* ---- occluder shrinking (Wonka's thesis, chapter 7) ----------------------------------------------
 * An occluder eroded by eps hides, from a point V, only what the original hides from every point
 * within eps of V (Theorem 3); with the eroded neighbourhood a horizontal disk (Lemma 6, the
 * "cylinder" for ground-bound viewers whose occlusion is computed from the highest eye point) the
 * heights stay and only the footprint shrinks. Occluders thinner than 2 eps vanish; they are
 * reported. */

typedef enum sl_shrink_mode {
    SL_SHRINK_CYLINDER = 0,     /* horizontal disk: footprint eroded, base and roof kept */
    SL_SHRINK_BALL = 1          /* ball: footprint eroded, roof lowered and base raised by eps */
} sl_shrink_mode;

typedef struct sl_shrunk_t *sl_shrunk;

/* One piece of a shrunk footprint (a footprint may fall into several pieces). */
typedef struct sl_shrunk_polygon {
    const float *xy;            /* 2 floats per vertex: the outer ring (counter-clockwise), then the
                                   holes (clockwise; a merged group may enclose a courtyard) */
    uint32_t vertex_count;      /* of all rings */
    uint32_t ring_count;        /* 1 + holes */
    const uint32_t *rings;      /* vertices per ring; rings[0] is the outer ring */
    float base_z, roof_z;
    uint32_t footprint;         /* the (lowest, highest-roofed) scene footprint it comes from */
    uint32_t object;            /* that footprint's object when it stands alone, else SL_NONE */
} sl_shrunk_polygon;

typedef struct sl_shrink_stats {
    uint32_t footprints;        /* input footprints */
    uint32_t kept;              /* footprints with at least one piece left */
    uint32_t vanished;          /* footprints with nothing left (thinner than 2 eps, or roof gone) */
    uint32_t split;             /* footprints that fell into two or more pieces */
    uint32_t pieces;            /* output polygons */
    double seconds;
} sl_shrink_stats;

/* Erode the footprints of a scene by eps >= 0 with GEOS (a negative buffer with round joins whose
 * radius is enlarged so that the arcs' chords stay at least eps from the boundary, plus a margin
 * for float rounding): every point of a piece is at least eps from the occluder's outside.
 * merge false: each footprint alone. merge true: footprints that touch or overlap form one 2.5D
 * occluder (a height field), eroded level by level — for every distinct roof height h of a group,
 * the union of the members at least h high is eroded and becomes pieces of height h (base: the
 * highest base of those members) — so that a row of buildings sharing walls shrinks as one block
 * and no gap opens between them (the "connected occluders" of thesis figure 5.2a). A footprint is
 * reported vanished when no piece at its own height overlaps it. alloc may be NULL. */
SL_API sl_status sl_shrink_footprints(sl_scene scene, float eps, sl_shrink_mode mode, bool merge,
                                      const sl_allocator *alloc, sl_shrunk *out, sl_error *err);
SL_API void sl_shrunk_destroy(sl_shrunk shrunk);
SL_API uint32_t sl_shrunk_count(sl_shrunk shrunk);
SL_API sl_shrunk_polygon sl_shrunk_get(sl_shrunk shrunk, uint32_t index);
/* Footprints that vanished, ascending; returns their number. */
SL_API uint32_t sl_shrunk_vanished(sl_shrunk shrunk, const uint32_t **footprints);
SL_API void sl_shrunk_get_stats(sl_shrunk shrunk, sl_shrink_stats *out);

/* Shrunk occluder levels stored with the scene (Instant Visibility, docs/instant.md): for each eps
 * (1..SL_OCCLUDER_LEVELS_MAX distinct values in (0, 10000] m, any order) the footprints eroded in
 * plan by sl_shrink_footprints(eps, SL_SHRINK_CYLINDER, merge) become a level of the scene
 * (sl_scene_add_occluder_level, scene.h): each piece's outer ring, its roof lowered and its base
 * raised by eps_z = min(vertical, eps) (vertical < 0: eps, the ball). The level then hides from P
 * only what the originals hide from every point within eps of P in plan and eps_z in height (the
 * proof of Theorem 3 with the displacement split in its horizontal and vertical parts). A merged
 * piece's courtyard walls are not used, and pieces the polygon rules refuse or that lose their
 * height are dropped: all conservative. Replaces the scene's levels; on failure the scene has
 * none. Full library only (GEOS). stats may be NULL. */
#define SL_OCCLUDER_LEVELS_MAX 16u
typedef struct sl_occluder_levels_stats {
    uint32_t levels;
    float eps[SL_OCCLUDER_LEVELS_MAX];            /* ascending */
    float eps_z[SL_OCCLUDER_LEVELS_MAX];          /* the vertical tolerance of each */
    uint32_t footprints[SL_OCCLUDER_LEVELS_MAX];  /* footprints of each level */
    uint32_t vanished[SL_OCCLUDER_LEVELS_MAX];    /* scene footprints with nothing left */
    uint32_t pieces_dropped[SL_OCCLUDER_LEVELS_MAX];
    uint32_t holes_dropped[SL_OCCLUDER_LEVELS_MAX];
    double seconds;
} sl_occluder_levels_stats;
SL_API sl_status sl_shrink_occluder_levels(sl_scene scene, const float *eps, uint32_t count, float vertical,
                                           bool merge, const sl_allocator *alloc, sl_occluder_levels_stats *stats,
                                           sl_error *err);

/* 2.5D: erode a height field (nx*ny samples, row-major, spacing `cell`, read as bilinear) by eps:
 * out (nx*ny) is a bilinear field nowhere above the eroded one — with CYLINDER the minimum over the
 * horizontal eps-disk, with BALL that minimum lowered by eps. out may not alias heights. */
SL_API sl_status sl_shrink_heightfield(const float *heights, uint32_t nx, uint32_t ny, float cell, float eps,
                                       sl_shrink_mode mode, float *out, sl_error *err);

/* 3D: erode a closed triangle mesh by eps on a voxel grid of `voxel` metres. A voxel counts as
 * solid when its corners are inside the mesh and no triangle crosses it; it is kept when every
 * voxel closer than eps to it is solid. The kept voxels are returned as boxes (runs along x merged),
 * *boxes allocated with alloc (free with sl_free-compatible size *count * sizeof(sl_aabb); use
 * sl_shrink_boxes_free). */
SL_API sl_status sl_shrink_mesh_voxels(const float *positions, uint32_t vertex_count, const uint32_t *indices,
                                       uint32_t triangle_count, float voxel, float eps, const sl_allocator *alloc,
                                       sl_aabb **boxes, uint32_t *count, sl_error *err);
/* Release boxes from sl_shrink_mesh_voxels. */
SL_API void sl_shrink_boxes_free(const sl_allocator *alloc, sl_aabb *boxes, uint32_t count);

/* ---- the region oracle ------------------------------------------------------------------------ */

typedef struct sl_region_oracle_t *sl_region_oracle;

/* Sampling density of the region oracle; a zero-initialised struct gives the defaults. */
typedef struct sl_region_oracle_options {
    uint32_t face_size;         /* cube-map face resolution in pixels (default 256) */
    float edge_spacing;         /* points along every cell edge at most this far apart, metres
                                   (default 1.0); the cell's vertices are always sampled */
    uint32_t face_samples;      /* random points on the boundary faces (default 24) */
    uint32_t interior_samples;  /* random points inside the cell (default 24) */
    uint32_t max_samples;       /* cap on the points per cell, 1..65536 (default 4096); the edge
                                   spacing is widened to fit */
    float near_plane;           /* cube-map near distance (default 0.05 m) */
    float far_plane;            /* far distance; 0: twice the scene's diagonal */
    uint32_t threads;           /* rendering threads of the point oracle (default 2) */
    uint64_t seed;              /* random points: a function of (seed, cell) only */
} sl_region_oracle_options;

/* What the oracle found for one cell (or point set). Arrays belong to the oracle and stay valid
 * until its next query. */
typedef struct sl_region_visibility {
    uint32_t sample_count;      /* cube maps rendered */
    uint32_t visible_count;     /* objects seen from at least one sample */
    const uint32_t *visible;    /* their ids, ascending */
    const uint32_t *max_pixels; /* per visible object: its largest pixel count over the samples */
    const uint32_t *first_sample;/* per visible object: the first sample (in rendering order) that saw it */
    uint32_t added_last_tenth;  /* objects first seen in the last 10% of the samples (convergence:
                                   0 suggests the density suffices; it never proves it) */
    double ms;                  /* wall time */
    uint32_t samples_out_of_domain; /* sample points outside the domain (a BSP leaf without a
                                   cluster, sl_oracle_in_domain): skipped, not rendered */
    bool out_of_domain;         /* every sample was outside the domain: the region is, and its (empty)
                                   set judges nothing (docs/oracle.md, "One set of rules") */
} sl_region_visibility;

/* Create a region oracle over a scene (which must outlive it). opt and alloc may be NULL. */
SL_API sl_status sl_region_oracle_create(sl_scene scene, const sl_region_oracle_options *opt,
                                         const sl_allocator *alloc, sl_region_oracle *out, sl_error *err);
/* Release it. NULL is ignored. */
SL_API void sl_region_oracle_destroy(sl_region_oracle oracle);
/* The points the oracle samples for a cell, in rendering order (a random interleaving of the
 * boundary and interior points, so that the last 10% is a fair subset). *points stays valid until
 * the next call; CLUSTER cells need the scene's BSP. */
SL_API sl_status sl_region_oracle_points(sl_region_oracle oracle, sl_viewcells cells, uint32_t cell,
                                         const sl_vec3 **points, uint32_t *count, sl_error *err);
/* Objects visible from anywhere in the cell (a lower bound, see above). */
SL_API sl_status sl_region_oracle_cell(sl_region_oracle oracle, sl_viewcells cells, uint32_t cell,
                                       sl_region_visibility *out, sl_error *err);
/* Objects visible from any of the given points (for regions that are not cells: an eps-disk). */
SL_API sl_status sl_region_oracle_points_visible(sl_region_oracle oracle, const sl_vec3 *points, uint32_t count,
                                                 sl_region_visibility *out, sl_error *err);

#ifdef __cplusplus
}
#endif
#endif
