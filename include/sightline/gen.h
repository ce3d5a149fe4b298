/* Procedural scene generators. One exists: the city.
 *
 * The city is the test bed every visibility method is measured on, shaped after the procedurally
 * generated Vienna of Wonka's thesis: an irregular street lattice (jittered nodes, streets of
 * varied width, straight avenues, a few dropped segments), perimeter blocks split into lots with
 * one building per lot (convex, L- and U-shaped footprints around courtyards), some towers,
 * parks and squares, and a river with wide open banks and a few bridges so that long views exist
 * beside the mostly occluded street views. Optional smooth terrain relief. That is the style
 * `grid`; the style `oldtown` (sl_city_style below) makes a historic centre on the same machinery,
 * with curved streets, T-junctions and short sight lines.
 *
 * What goes into the scene (see docs/city-generator.md):
 *  - one BUILDING object (flag OCCLUDER) per building, its mesh in world coordinates, and its
 *    2.5D footprint (sl_scene_add_footprint, linked to the object; roof_z is the eave height so
 *    that the prism lies inside the building, and walls with window recesses are moved inward
 *    by the recess depth);
 *  - GROUND objects: street surfaces merged per 100 m tile, one per block/park/square/bank and
 *    per bridge; WATER objects, one per river cell;
 *  - instanced props: TREE, LAMP and CAR (flag DYNAMIC) objects sharing a few meshes;
 *  - the street network: free-space polygons (street segments, intersections, squares, parks,
 *    river banks) and the centre-line graph (avenue, bridge and square edges flagged);
 *  - the terrain height field when relief is on; metadata (generator, preset, seed, extent,
 *    counts).
 * Same options, same bytes: the output depends only on the options, never on timing or memory
 * addresses. */
#ifndef SIGHTLINE_GEN_H
#define SIGHTLINE_GEN_H

#include "core.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sl_city_preset {
    SL_CITY_TINY = 0,   /* 300 x 260 m, a dozen blocks, about 18k triangles: unit tests */
    SL_CITY_SMALL = 1,  /* 800 x 750 m, about 130 blocks, about 0.6M triangles */
    SL_CITY_VIENNA = 2, /* 3000 x 2700 m, about 2,000 blocks, about 8.5M triangles (the thesis' model) */
    SL_CITY_OLDTOWN = 3,       /* style oldtown over the vienna extent (3000 x 2700 m) */
    SL_CITY_OLDTOWN_SMALL = 4  /* style oldtown over the small extent (800 x 750 m): tests */
} sl_city_preset;

/* Street layout style.
 *  GRID:    the lattice as described above (straight avenues, a river, lines that only jitter);
 *           its output is pinned byte for byte by tests/test_gen_city.c.
 *  OLDTOWN: a historic centre: every lattice line meanders (a sine across the line whose phase
 *           drifts slowly from one line to the next, so streets curve and blocks vary in depth),
 *           the lattice is cut into districts, and in each district every other segment of one
 *           direction is dropped in a brick pattern (so streets of that direction end in
 *           T-junctions after one block and neighbouring blocks merge into deep ones); more
 *           squares, no avenues, no river. Sight lines along a street end after one or two
 *           blocks instead of running across the city. */
typedef enum sl_city_style {
    SL_CITY_STYLE_GRID = 0,
    SL_CITY_STYLE_OLDTOWN = 1
} sl_city_style;

/* Generator options. Start from sl_city_defaults(preset) and override fields; every field is
 * checked by sl_city_options_validate. Lengths are metres. */
typedef struct sl_city_options {
    sl_city_preset preset;          /* recorded in the metadata */
    sl_city_style style;            /* street layout (recorded in the metadata when not grid) */
    uint64_t seed;

    /* layout: the city covers [-extent_x/2, extent_x/2] x [-extent_y/2, extent_y/2] */
    float extent_x, extent_y;       /* 100 .. 20000 */
    float block_size_min;           /* street centre-line spacing of the lattice, 30 .. 500 */
    float block_size_max;           /* >= block_size_min */
    float jitter;                   /* node displacement as a fraction of the block size, 0 .. 0.25 */
    float street_width_min;         /* ordinary streets, sidewalk edge to sidewalk edge, 4 .. 60 */
    float street_width_max;
    float avenue_width;             /* avenues and river quays, >= street_width_min */
    float avenue_spacing;           /* distance between straight avenues; 0: none */
    float street_removal;           /* probability of dropping a minor street segment, 0 .. 0.5 */
    float meander;                  /* amplitude of the lines' sine meander, 0 .. 0.3 block_size_min
                                     * (0 in the grid presets) */
    float meander_wavelength;       /* its wavelength along the line, 100 .. 5000 (used when
                                     * meander > 0) */
    uint32_t district;              /* oldtown: district size in lattice cells (brick pattern
                                     * direction per district), 2 .. 64; ignored by grid */
    float park_fraction;            /* share of lattice cells that are parks (trees), 0 .. 1 */
    float square_fraction;          /* share that are paved squares, 0 .. 1 */
    float tower_fraction;           /* share that hold one tower, 0 .. 1 (sum of the three <= 1) */

    /* river: one lattice row becomes water between two quays, with open banks */
    bool river;
    float river_width;              /* water surface, 10 .. 1000 */
    float bank_width;               /* open bank on each side, 0 .. 200 */
    float bridge_spacing;           /* distance between bridges; 0: no bridges (graph splits in two) */

    /* buildings */
    float height_min, height_max;   /* ordinary buildings, eave height above the base, 4 .. 300 */
    float tower_height_min, tower_height_max;
    uint32_t detail;                /* façade and roof detail, 0 .. 4 (measured triangles per
                                     * building, averaged over the vienna preset):
                                     * 0: prism with a flat roof (11; 10 for a box);
                                     * 1: + cornice, mansard/hip/gable roofs (40);
                                     * 2: + a ledge at every floor (120);
                                     * 3: + recessed windows and doors on street façades (710);
                                     * 4: + window sills, windows on courtyard façades too
                                     *    (1,260; several thousand for big corner buildings) */

    /* props */
    float cars_per_km;              /* expected cars per km of street, 0 .. 400 */
    float traffic_speed;            /* m/s of the cars in the driving lanes, 0 .. 40 (default 11,
                                     * about 40 km/h; each car within 25% of it): each gets a motion
                                     * record with a path up and down its lane (sl_scene_animate);
                                     * parked cars get one that never moves. 0: no paths */
    float trees_per_ha;             /* in parks and courtyards, 0 .. 400 */
    float street_tree_spacing;      /* along avenues and river banks; 0: none */
    float lamp_spacing;             /* along every street, alternating sides; 0: none */

    /* terrain: a smooth height field rising from the river (or everywhere without one) */
    bool terrain;
    float relief;                   /* highest ground above the river level, 0 .. 500 */

    sl_progress progress;           /* optional; returning false cancels */
} sl_city_options;

/* Default options of a preset (seed 1). An unknown preset yields the tiny defaults. */
SL_API sl_city_options sl_city_defaults(sl_city_preset preset);

/* Preset by name: "tiny", "small", "vienna", "oldtown" or "oldtown-small". SL_ERROR_NOT_FOUND for
 * anything else. */
SL_API sl_status sl_city_preset_from_name(const char *name, sl_city_preset *out, sl_error *err);

/* Lowercase name of a preset, or "unknown". */
SL_API const char *sl_city_preset_name(sl_city_preset preset);

/* Check every option and their combinations (e.g. streets too wide for the blocks, a river that
 * does not fit); SL_ERROR_INVALID_ARGUMENT with the option's name and the allowed range. */
SL_API sl_status sl_city_options_validate(const sl_city_options *opt, sl_error *err);

/* Generate a city into a new scene (*out, created with alloc, which may be NULL). On failure
 * *out is left NULL and nothing leaks. */
SL_API sl_status sl_gen_city(const sl_city_options *opt, const sl_allocator *alloc, sl_scene *out, sl_error *err);

/* Lowercase name of a style ("grid", "oldtown"), or "unknown"; and the reverse
 * (SL_ERROR_NOT_FOUND for an unknown name). */
SL_API const char *sl_city_style_name(sl_city_style style);
SL_API sl_status sl_city_style_from_name(const char *name, sl_city_style *out, sl_error *err);

/* Figures that say whether a generated city is comparable with another (measured on the scene,
 * any style; also on a city read back from a .slscene):
 *  - extent: the "extent" metadata when present, else the scene bounds in x and y;
 *  - object_count: every object; building_count: objects of kind BUILDING;
 *  - mean_building_height: mean over BUILDING objects of their bounds' height (max z - min z);
 *  - street_area: summed area of the street polygons (free space: streets, intersections,
 *    squares, parks, river banks); street_fraction = street_area / extent area;
 *  - street_length: summed length of the street graph's edges;
 *  - sight_mean, sight_p90: straight sight lines along the streets: from the midpoint of every
 *    street graph edge, in both directions along it, the distance a ray 1.7 m above the ground
 *    travels before it meets a building footprint (or before it leaves the extent); mean and
 *    90th percentile over the rays. */
typedef struct sl_city_stats {
    double extent_x, extent_y;
    uint32_t object_count, building_count;
    double mean_building_height;
    double street_area, street_fraction;
    double street_length;
    double sight_mean, sight_p90;
    uint32_t sight_rays;
} sl_city_stats;

/* Measure a scene (see sl_city_stats). Thread safety: reads the scene only; concurrent calls on
 * one scene are safe. SL_ERROR_INVALID_ARGUMENT for NULL arguments or a scene without footprints
 * or street polygons (not a city). */
SL_API sl_status sl_city_measure(sl_scene scene, sl_city_stats *out, sl_error *err);

/* ---- random edits of a city's buildings (what `sightline pvs update` is tested and measured on) ----
 * sl_city_edit copies `scene` into a new scene (*out, created with alloc) with, for every building
 * (an object with a footprint) whose footprint box centre lies in region, one seeded draw: removed
 * (with probability remove: the object and its footprint), moved (move: shifted by up to `shift`
 * metres towards the middle of its row of touching buildings — a perimeter block's courtyard, away
 * from the street — and its height scaled about its base by a factor drawn in [1, grow]), given a
 * new building (add: appended, its footprint the building's halved about its vertex centroid, its
 * height `tower` times the building's), or kept. Everything else (meshes, materials, the other
 * objects in order, streets, terrain, metadata) is copied. Scenes with BSP data or mesh occluders
 * are refused. Same scene and options, same result. */
typedef struct sl_city_edit_options {
    float region[4];            /* X0, Y0, X1, Y1 */
    uint64_t seed;
    float remove, move, add;    /* probabilities, sum <= 1 (defaults 0.25, 0.25, 0.2) */
    float shift;                /* metres, 0..100 (default 1) */
    float grow;                 /* 1..10 (default 1: a moved building keeps its height) */
    float tower;                /* 0.1..10 (default 1: a new building as high as its host) */
} sl_city_edit_options;

typedef struct sl_city_edit_stats {
    uint32_t removed, moved, added;
} sl_city_edit_stats;

/* Defaults (region all zero: set it). */
SL_API sl_city_edit_options sl_city_edit_defaults(void);
SL_API sl_status sl_city_edit(sl_scene scene, const sl_city_edit_options *opt, const sl_allocator *alloc,
                              sl_scene *out, sl_city_edit_stats *stats, sl_error *err);

#ifdef __cplusplus
}
#endif
#endif
