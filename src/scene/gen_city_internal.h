/* Internals of the procedural city generator (gen_city*.c), shared by its parts:
 *   gen_city.c          options, presets, validation, the driver, metadata
 *   gen_city_geom.c     2D polygon helpers and the mesh builder (flat-shaded primitives)
 *   gen_city_layout.c   street lattice, cells, river, terrain, street polygons and graph
 *   gen_city_building.c lots and building meshes, footprints
 *   gen_city_ground.c   street/block/park/bank ground pieces, water, bridges
 *   gen_city_props.c    trees, lamps, cars
 *
 * Layout model. The city is a lattice of (nx+1) x (ny+1) nodes whose lines are streets; the
 * nx x ny cells between them are blocks, parks, squares or the river. Node (i,j) sits near
 * (X_i, Y_j), jittered; lines on the extent border are not streets (cells there reach the border).
 * Cell (i,j) has corners k = 0..3 at nodes (i,j), (i+1,j), (i+1,j+1), (i,j+1) (CCW) and side k runs
 * from corner k to corner k+1: side 0 = horizontal edge (i,j), 1 = vertical edge (i+1,j),
 * 2 = horizontal edge (i,j+1), 3 = vertical edge (i,j). A cell's ground quad is bounded by its
 * four side lines moved inward by half the street width (0 where the side is not a street); two
 * cells meeting across a non-street lattice edge share their corners there. Street segments and
 * intersections are built from the ground corners, lots are the ground quad moved in by a
 * setback, banks and water subdivide river cells: everything tiles the extent exactly.
 *
 * All layout arithmetic is in double; meshes are emitted in float. Every random choice draws from
 * a PCG32 stream keyed by (seed, purpose, cell or edge index), so the output never depends on the
 * order in which other parts consumed random numbers. */
#ifndef SL_GEN_CITY_INTERNAL_H
#define SL_GEN_CITY_INTERNAL_H

#include "sightline/gen.h"
#include "scene_internal.h"
#include "core/dvec3.h"

#include <math.h>

/* ---- constants (documented in docs/city-generator.md) ---- */
#define GC_SETBACK 0.5        /* gap between street polygons and façades (> every protrusion) */
#define GC_TILE 100.0         /* street ground is merged into one object per tile of this size */
#define GC_TERRAIN_CELL 8.0   /* height field spacing */
#define GC_WATER_Z (-2.0)     /* water surface below the quays */
#define GC_RECESS 0.25        /* window recess depth */
#define GC_CORNICE 0.35       /* cornice protrusion */
#define GC_LEDGE 0.15         /* string course protrusion */
#define GC_MAX_POLY 16        /* vertices of a building footprint */
#define GC_PI 3.14159265358979323846
#define GC_MEANDER_DRIFT 0.5  /* oldtown: largest phase change of the meander between neighbouring lines */

/* ---- vectors: the core kit (core/dvec3.h: sl_dvec2, sl_d2_*, sl_dvec3, sl_d3_*) ---- */

/* ---- 2D polygons (gen_city_geom.c) ---- */

/* Intersection of lines p + t*d and q + u*e; false when (nearly) parallel. */
bool gc_line_isect(sl_dvec2 p, sl_dvec2 d, sl_dvec2 q, sl_dvec2 e, sl_dvec2 *out);
/* Signed area (positive for CCW). */
double gc_area(const sl_dvec2 *p, int n);
/* True when every turn is a left turn (strictly convex CCW polygon). */
bool gc_convex(const sl_dvec2 *p, int n);
/* True when no two non-adjacent edges touch. */
bool gc_simple(const sl_dvec2 *p, int n);
/* Shortest edge length. */
double gc_min_edge(const sl_dvec2 *p, int n);
/* Move edge i (p[i] -> p[i+1]) of a CCW polygon to its left (inward) by off[i] (negative:
 * outward); vertices are the intersections of consecutive moved edges. Returns false when the
 * result is not a like polygon (an edge flipped or shrank below 5 cm, or the area vanished). */
bool gc_offset(const sl_dvec2 *p, int n, const double *off, sl_dvec2 *out);
/* Same with one offset for all edges. */
bool gc_offset_all(const sl_dvec2 *p, int n, double off, sl_dvec2 *out);
/* Largest uniform inward offset keeping a like polygon (bisection; convex polygons). */
double gc_max_inset(const sl_dvec2 *p, int n);
/* Point strictly inside a CCW convex polygon, at least `margin` from every edge. */
bool gc_inside_convex(const sl_dvec2 *p, int n, sl_dvec2 q, double margin);
/* Ear-clipping triangulation of a simple CCW polygon (n <= GC_MAX_POLY); returns the triangle
 * count (n-2) and fills tri with vertex indices. */
int gc_triangulate(const sl_dvec2 *p, int n, uint8_t tri[][3]);

/* ---- mesh builder (gen_city_geom.c) ----
 * A scratch mesh reused for every building/prop/ground piece, then copied into the scene with
 * sl_scene_add_mesh. Flat faces share their vertices; distinct faces never do (flat shading).
 * Allocation failures are sticky in `oom` and reported once at gc_mesh_commit. */
typedef struct gc_mesh {
    const sl_allocator *alloc;
    float *pos, *nrm;
    uint32_t *idx;
    uint32_t nv, nt;
    uint32_t cap_v, cap_t;
    bool oom;
} gc_mesh;

void gc_mesh_init(gc_mesh *m, const sl_allocator *a);
void gc_mesh_free(gc_mesh *m);
static inline void gc_mesh_reset(gc_mesh *m) { m->nv = m->nt = 0; }
/* Make room for nv more vertices and nt more triangles; false (and oom set) on failure. */
bool gc_mesh_reserve(gc_mesh *m, uint32_t nv, uint32_t nt);
/* Append a vertex (room must be reserved). */
static inline uint32_t gc_vert(gc_mesh *m, sl_dvec3 p, sl_dvec3 n)
{
    float *d = m->pos + 3 * (size_t)m->nv, *e = m->nrm + 3 * (size_t)m->nv;
    d[0] = (float)p.x, d[1] = (float)p.y, d[2] = (float)p.z;
    e[0] = (float)n.x, e[1] = (float)n.y, e[2] = (float)n.z;
    return m->nv++;
}
static inline void gc_tri_idx(gc_mesh *m, uint32_t a, uint32_t b, uint32_t c)
{
    uint32_t *d = m->idx + 3 * (size_t)m->nt++;
    d[0] = a, d[1] = b, d[2] = c;
}
/* Planar polygon (n <= 8, convex) with its own vertices, facing by the right-hand rule; when
 * `want` is non-zero the winding is flipped if the face would point away from it. Degenerate
 * faces are skipped. */
void gc_face(gc_mesh *m, const sl_dvec3 *p, int n, sl_dvec3 want);
/* Quad shorthand for gc_face. */
void gc_quad(gc_mesh *m, sl_dvec3 a, sl_dvec3 b, sl_dvec3 c, sl_dvec3 d, sl_dvec3 want);
void gc_tri(gc_mesh *m, sl_dvec3 a, sl_dvec3 b, sl_dvec3 c, sl_dvec3 want);
/* Horizontal cap of a simple CCW polygon at height z, facing up (or down). */
void gc_cap(gc_mesh *m, const sl_dvec2 *p, int n, double z, bool up);
/* Vertical prism over a CCW polygon between z0 and z1: the walls, plus caps when asked. */
void gc_prism(gc_mesh *m, const sl_dvec2 *p, int n, double z0, double z1, bool top, bool bottom);
/* Axis-aligned box (local prop coordinates); bottom face optional. */
void gc_box(gc_mesh *m, sl_dvec3 lo, sl_dvec3 hi, bool bottom);

/* ---- the generator's state ---- */

enum { GC_TAG_STREET = 0, GC_TAG_COURT = 1, GC_TAG_PARTY = 2, GC_TAG_BLANK = 3 };
enum { GC_CELL_BLOCK = 0, GC_CELL_TOWER, GC_CELL_PARK, GC_CELL_SQUARE, GC_CELL_RIVER, GC_CELL_PLAZA };
enum { GC_EDGE_STREET = 1u << 0, GC_EDGE_AVENUE = 1u << 1, GC_EDGE_BRIDGE = 1u << 2 };

typedef struct gc_edge {
    float width;              /* street width (0 when not a street) */
    uint32_t flags;           /* GC_EDGE_* */
} gc_edge;

typedef struct gc_cell {
    uint32_t type;            /* GC_CELL_* */
    sl_dvec2 ground[4];       /* the cell bounded by its streets' kerb lines */
} gc_cell;

typedef struct gc_court {
    sl_dvec2 q[4];            /* CCW courtyard quad */
    uint32_t cell;            /* cell index, keys the random stream */
    uint32_t pad;
} gc_court;

typedef struct gc_city {
    const sl_city_options *opt;
    const sl_allocator *alloc;
    sl_scene scene;
    sl_error *err;

    double x0, y0, x1, y1;    /* extent */
    int nx, ny;               /* cells along x and y */
    int river_row;            /* cell row of the river, -1 without */
    sl_dvec2 *node;           /* (nx+1)*(ny+1), index j*(nx+1)+i */
    gc_edge *hedge;           /* nx*(ny+1): node (i,j) -> (i+1,j), index j*nx+i */
    gc_edge *vedge;           /* (nx+1)*ny: node (i,j) -> (i,j+1), index j*(nx+1)+i */
    gc_cell *cell;            /* nx*ny, index j*nx+i */
    uint8_t *vline_avenue, *hline_avenue; /* per lattice line */

    /* terrain: samples at (x0 + i*tcell, y0 + j*tcell) */
    bool has_terrain;
    uint32_t tnx, tny;
    double tcell;
    float *theight;

    gc_mesh mesh;             /* scratch */
    sl_array courts;          /* gc_court: courtyards that may get trees (filled by gc_buildings) */

    /* instanced prop meshes (SL_NONE until made) */
    uint32_t tree_mesh[3], lamp_mesh, car_mesh[3];

    /* counts for the metadata */
    uint32_t n_blocks, n_buildings, n_towers, n_parks, n_squares, n_bridges, n_plazas;
    uint32_t n_trees, n_lamps, n_cars, n_driving;
} gc_city;

static inline sl_dvec2 gc_node(const gc_city *c, int i, int j) { return c->node[(size_t)j * (c->nx + 1) + i]; }
static inline gc_edge *gc_hedge(gc_city *c, int i, int j) { return &c->hedge[(size_t)j * c->nx + i]; }
static inline gc_edge *gc_vedge(gc_city *c, int i, int j) { return &c->vedge[(size_t)j * (c->nx + 1) + i]; }
static inline gc_cell *gc_cellp(gc_city *c, int i, int j) { return &c->cell[(size_t)j * c->nx + i]; }

/* Random stream for one purpose and one element (cell, edge, node): independent of every other. */
void gc_rng(const gc_city *c, uint32_t purpose, uint32_t a, uint32_t b, sl_rng *out);
enum {
    GC_RNG_SPACING = 1, GC_RNG_NODE, GC_RNG_LINE, GC_RNG_REMOVE, GC_RNG_CELL, GC_RNG_BLOCK, GC_RNG_BUILDING,
    GC_RNG_TREE, GC_RNG_LAMP, GC_RNG_CAR, GC_RNG_TERRAIN, GC_RNG_RIVER, GC_RNG_MEANDER, GC_RNG_DISTRICT,
    GC_RNG_TRAFFIC
};

/* The edge on side k of cell (i,j), and whether that side lies on the extent border. */
gc_edge *gc_cell_side_edge(gc_city *c, int i, int j, int k);
bool gc_cell_side_border(const gc_city *c, int i, int j, int k);
/* Line of side k of cell (i,j) moved inward by off: point p, direction d (corner k to k+1). */
void gc_side_line(const gc_city *c, int i, int j, int k, double off, sl_dvec2 *p, sl_dvec2 *d);
/* Cell quad bounded by its side lines moved inward by off[k]; false if degenerate. */
bool gc_cell_quad(const gc_city *c, int i, int j, const double off[4], sl_dvec2 out[4]);
/* Free-space quad of a street edge: out[0]->out[1] is the kerb on the right of the direction
 * a->b, out[3]->out[2] the kerb on the left. `horizontal` picks hedge(i,j) or vedge(i,j). */
void gc_edge_quad(gc_city *c, bool horizontal, int i, int j, sl_dvec2 out[4]);
/* Free-space polygon of an interior lattice node (intersection): the corners of the cells around
 * it, CCW, coincident corners merged. Returns the vertex count (0 when there is none, 3 or 4). */
int gc_node_poly(gc_city *c, int i, int j, sl_dvec2 out[4]);
/* Lower and upper bank quads and the water quad of river cell (i,j). */
bool gc_river_quads(gc_city *c, int i, int j, sl_dvec2 bank_lo[4], sl_dvec2 bank_hi[4], sl_dvec2 water[4]);

/* Terrain height at (x,y) (bilinear, as sl_scene_ground_height), 0 without terrain. */
double gc_ground(const gc_city *c, double x, double y);
/* Lowest terrain height over a simple polygon (exact for the bilinear height field). */
double gc_ground_min_poly(const gc_city *c, const sl_dvec2 *p, int n);
/* Terrain normal at (x,y). */
sl_dvec3 gc_ground_normal(const gc_city *c, double x, double y);

/* Add the scratch mesh to the scene; false on error (c->err filled). */
bool gc_commit_mesh(gc_city *c, uint32_t *mesh_id);
/* Add the scratch mesh and one object using it. */
bool gc_commit_object(gc_city *c, uint32_t kind, uint32_t flags, uint32_t color, uint32_t *object);

/* The stages (each returns SL_OK or an error already recorded in c->err). */
sl_status gc_layout(gc_city *c);
sl_status gc_terrain(gc_city *c);
sl_status gc_buildings(gc_city *c);
sl_status gc_groundwork(gc_city *c);
sl_status gc_props(gc_city *c);
sl_status gc_streets(gc_city *c);

#endif
