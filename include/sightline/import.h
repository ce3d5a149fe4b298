/* Sightline importers and exporters.
 *
 * Any format assimp reads (OBJ, glTF 2.0/GLB, PLY, FBX, COLLADA, 3DS, ...) becomes a scene whose
 * objects are the file's nodes (one object per node with meshes; instanced meshes stay shared).
 * Quake III maps (IBSP version 46) are read from a .bsp file or from inside a .pk3 (zip) archive.
 *
 * Conventions: every importer produces metres, Z up. assimp files are taken as Y-up (glTF's rule,
 * and what most tools write) and rotated to Z-up unless up_axis says otherwise; unit_scale
 * multiplies coordinates. Quake III units are converted at 1/32 m per unit (a standing player,
 * 56 units tall, is 1.75 m), and Quake III is already Z-up.
 */
#ifndef SIGHTLINE_IMPORT_H
#define SIGHTLINE_IMPORT_H

#include "core.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sl_up_axis { SL_UP_Y = 0, SL_UP_Z = 1 } sl_up_axis;

typedef struct sl_import_options {
    float unit_scale;           /* metres per file unit; 0 means 1 (assimp) or 1/32 (Quake III) */
    sl_up_axis up_axis;         /* assimp files only; default SL_UP_Y */
    uint32_t split_triangles;   /* 0: one object per node; else split meshes larger than this into
                                   spatially compact objects of about this many triangles */
    uint32_t bezier_level;      /* Quake III patch tessellation level per bezier (0 means 8) */
    sl_progress progress;
    /* assimp files: what the references inside a model (glTF buffers and images, OBJ material
     * libraries, any file assimp opens besides the model) may resolve to. By default only files
     * inside the model's own folder (after symlinks and '..'); each entry here allows one more
     * folder (everything below it) or, when it names a file, that file. A reference resolving
     * anywhere else fails the import, naming the reference and the folder. The list and its
     * strings are borrowed for the call only: the importer copies what it needs (canonical
     * paths) through its allocator and frees them before returning. */
    const char *const *allow_external;
    uint32_t allow_external_count;
    /* assimp files: the largest file assimp may open (the model or a reference); 0 means 4 GiB.
     * Only regular files are opened (never a FIFO or a device), read-only. */
    uint64_t max_file_bytes;
    /* assimp files: where assimp runs. By default (false) in a child process (fork()): assimp 5.2
     * reads out of bounds, crashes and loops on some malformed files (PLY and STL among them,
     * found by fuzzing), which in this process could corrupt its memory or kill it. The child
     * imports, writes the scene as .slscene into an anonymous memory file and exits; this process
     * reads that back with the validating .slscene reader. A child that crashes, is killed or
     * exits without a result fails the import with SL_ERROR_FORMAT naming the signal or status;
     * progress and cancellation reach `progress` as in this process. The child's allocations
     * go through `alloc` in the child's copy of this process. true: assimp runs in this process
     * (debugging; or where fork() is not allowed). */
    bool in_process;
    /* isolated assimp import only: kill the child after this many milliseconds and fail with
     * SL_ERROR_LIMIT (0: no limit) */
    uint32_t timeout_ms;
} sl_import_options;

/* Default options (all zero). */
SL_API sl_import_options sl_import_defaults(void);

/* Import any file assimp reads into a new scene. Every file assimp opens goes through a
 * read-only IO system confined as opt->allow_external says; assimp's messages are passed on with
 * control bytes and non-UTF-8 bytes escaped and cut short, never with raw file content. assimp
 * runs in a child process unless opt->in_process (see there). Thread safety: may be called from
 * several threads at once with distinct outputs; the isolated import forks, so a caller whose
 * other threads hold locks the child needs (other than malloc's, which glibc resets) should
 * import in process. */
SL_API sl_status sl_import_assimp(const char *path, const sl_import_options *opt, const sl_allocator *alloc,
                                  sl_scene *out, sl_error *err);

/* Import a Quake III map. `path` is a .bsp file, or a .pk3 archive with `map` naming the entry
 * ("maps/oa_dm1.bsp" or just "oa_dm1"); map is ignored for a .bsp file. */
SL_API sl_status sl_import_q3bsp(const char *path, const char *map, const sl_import_options *opt,
                                 const sl_allocator *alloc, sl_scene *out, sl_error *err);

/* Import a Quake III map already in memory (the bytes of a .bsp). `name` is used in messages. */
SL_API sl_status sl_import_q3bsp_memory(const void *data, size_t size, const char *name, const sl_import_options *opt,
                                        const sl_allocator *alloc, sl_scene *out, sl_error *err);

/* List the .bsp entries of a .pk3 archive: calls fn for each entry name ("maps/x.bsp"). */
SL_API sl_status sl_pk3_list_maps(const char *pk3_path, void (*fn)(void *user, const char *entry), void *user,
                                  sl_error *err);

/* Export a scene through assimp. `format` is an assimp export id ("obj", "gltf2", "glb2", "ply",
 * "collada", "stl", ...) or NULL to choose from the file extension. Written atomically. Output is
 * Y-up for glTF (its rule) and Z-up otherwise unless the options say SL_UP_Y. */
SL_API sl_status sl_export_assimp(sl_scene scene, const char *path, const char *format, sl_up_axis up_axis,
                                  sl_error *err);

/* --- cities from GIS data (docs/gis-import.md) ---------------------------------------------- */

/* Options of sl_import_gis. All zero (sl_gis_defaults) reads every layer with the default names. */
typedef struct sl_gis_options {
    /* Attribute names, comma-separated, tried in order; NULL: the defaults. A name is looked up as
     * a field of the feature and, for OpenStreetMap data, among its other_tags. */
    const char *height_fields;  /* total height in metres; NULL: "height,building:height,measuredHeight,HEIGHT,Height" */
    const char *levels_fields;  /* storeys; NULL: "building:levels,levels,storeys" */
    float default_height;       /* metres for a building with no usable height (a counted warning); 0: 10 */
    float level_height;         /* metres per storey (levels × this); 0: 3 */
    /* The source CRS, any text OGR's OSRSetFromUserInput takes ("EPSG:25832", a WKT or PROJ
     * string), replacing what the file declares; NULL: the file's own. */
    const char *crs;
    /* true: the coordinates are metres in a local frame, whatever CRS the file declares (or when
     * it declares none); they are only moved so that the data is centred on the origin. */
    bool metric;
    const char *layers;         /* comma-separated layer names to read; NULL: every layer */
    bool no_streets;            /* true: lines are not read as streets */
    bool no_ground;             /* true: no ground tiles */
    /* metres from the centre of the data (the median of the features' centres) beyond which a
     * feature is dropped as a counted warning; 0: 50 000 */
    float max_extent;
    /* polygons smaller than this (m^2, after cleaning) are dropped as a counted warning; 0: 1 */
    float min_area;
    uint32_t max_features;      /* more features than this fail with SL_ERROR_LIMIT; 0: 10 000 000 */
    sl_progress progress;
} sl_gis_options;

/* What sl_import_gis read, made, repaired and dropped. Every count of a warning has an example in
 * first_warning (the first one met, naming the layer and feature). */
typedef struct sl_gis_stats {
    uint32_t layers, features;        /* layers read, features met in them */
    uint32_t buildings, building_parts; /* building objects made; polygons (after cleaning) in them */
    uint32_t footprints;              /* 2.5D footprints added (a polygon with holes is cut in pieces) */
    uint32_t streets, street_segments, street_nodes; /* street lines, their segments, graph nodes */
    uint32_t ground_tiles;
    uint32_t other;                   /* features that are neither (points, untagged lines, land use) */
    /* warnings */
    uint32_t default_height;          /* buildings given the default height (no height, no levels) */
    uint32_t bad_height;              /* height or levels present but unusable (text, negative, NaN, > 2 km) */
    uint32_t unclosed_rings;          /* rings that did not end where they began (closed here) */
    uint32_t repaired;                /* polygons that were not valid (self-intersections, ...) and were made valid */
    uint32_t dropped_invalid;         /* features dropped: NaN/infinite coordinates, too few points, no area */
    uint32_t dropped_far;             /* features dropped: beyond max_extent */
    uint32_t dropped_small;           /* polygons dropped: smaller than min_area */
    uint32_t dropped_transform;       /* features dropped: the reprojection failed for them */
    char first_warning[256];
    char driver[32];                  /* the GDAL driver that read the file ("GeoJSON") */
    char crs[128];                    /* the source CRS's name, or "metric (local)" */
    double origin_lon, origin_lat;    /* centre of the local frame (NaN in metric mode) */
    double seconds;                   /* wall time */
} sl_gis_stats;

/* Default options (all zero). */
SL_API sl_gis_options sl_gis_defaults(void);

/* Whether `path` names a file sl_import_gis takes by its extension (.geojson, .json, .shp, .osm,
 * .pbf, .gml; case-insensitive). */
SL_API bool sl_gis_path(const char *path);

/* Import a city from GIS data through GDAL's OGR (GeoJSON, ESRI Shapefile, OpenStreetMap XML and
 * PBF, GML/CityGML; the driver is chosen by the extension and only that driver may open it).
 * Polygons become buildings: reprojected to a local metric frame (a transverse Mercator centred on
 * the data, x east, y north, metres, z up), cleaned with GEOS (made valid, duplicate points
 * dropped, holes kept), extruded from min_height to the height (height attribute, levels ×
 * level_height, the z range of 3D geometry, or the default), one SL_KIND_BUILDING object each with
 * its mesh (flat roof; a roof:height gives a sloped band to a flat top) and its 2.5D footprints
 * inside it. Lines tagged highway (every line of a layer without such a field) become street
 * polygons (each segment buffered by its width) and the street graph; flat ground tiles cover the
 * data. Bad input fails with a message naming the file, the layer and the feature, or is a
 * counted warning in stats (may be NULL). Deterministic. alloc may be NULL.
 * Thread safety: may be called from several threads at once with distinct outputs (GDAL's error
 * handler is set per thread). */
SL_API sl_status sl_import_gis(const char *path, const sl_gis_options *opt, const sl_allocator *alloc, sl_scene *out,
                               sl_gis_stats *stats, sl_error *err);

/* --- occluder synthesis (docs/occluder-synthesis.md) ------------------------------------------ */

/* Options of sl_synth_occluders. All zero (sl_synth_defaults) chooses every value from the scene. */
typedef struct sl_synth_options {
    float voxel;                   /* voxel edge in metres; 0: per object, the smaller of its longest
                                      side / 48 and its shortest side / 6 (at least 1e-5 of the
                                      scene's diagonal), coarsened until max_voxels holds */
    float min_box;                 /* smallest edge of a box kept, metres; 0: two voxels */
    float weld;                    /* vertices closer than this (same cell of a grid this fine)
                                      become one; 0: 1e-6 of the scene's diagonal */
    uint32_t max_boxes_per_object; /* 0: 16 (the largest boxes are kept) */
    uint32_t max_boxes;            /* per scene; 0: 65536 (the largest boxes are kept) */
    uint32_t max_voxels;           /* per object; 0: 2^21 */
    bool no_expand;                /* true: boxes stay on the voxel grid (no growing towards the surface) */
} sl_synth_options;

/* What sl_synth_occluders did. */
typedef struct sl_synth_stats {
    uint32_t considered;          /* objects looked at (not see-through, native or dynamic) */
    uint32_t closed, open;        /* of those: closed and consistently oriented after welding (or
                                     closed but for holes in its base plane), or not */
    uint32_t base_open;           /* of the closed: open only in the plane of their lowest z */
    uint32_t partial;             /* of the closed: with open parts left out (their other connected
                                     components are closed: the boxes lie inside those) */
    uint32_t see_through;         /* skipped: SL_OBJECT_SEE_THROUGH (never an occluder) */
    uint32_t native;              /* skipped: has a footprint, an occluder mesh or SL_OBJECT_OCCLUDER */
    uint32_t dynamic;             /* skipped: SL_OBJECT_DYNAMIC (a box would not follow it) */
    uint32_t objects_with_boxes;  /* closed objects that received at least one box */
    uint32_t boxes;               /* boxes added (12 triangles each) */
    uint32_t occluder_meshes;     /* occluder meshes added: one per object that got boxes */
    uint32_t dropped_by_budget;   /* boxes left out by max_boxes */
    uint64_t voxels, solid_voxels; /* over all closed objects */
    double closed_volume;         /* m^3 enclosed by the closed objects */
    double covered_volume;        /* m^3 of the added boxes on the voxel grid (a lower bound of what
                                     they cover: growing towards the surface adds more) */
    double volume_fraction;       /* covered_volume / closed_volume */
    double seconds, cpu_seconds;  /* wall time; CPU time of the calling thread */
    uint32_t t_junctions;         /* triangles split where another vertex lay on their open edge
                                     (a T-junction), before the closedness test. Appended */
} sl_synth_stats;

/* Default options (all zero: everything chosen from the scene). */
SL_API sl_synth_options sl_synth_defaults(void);

/* Synthesise conservative 3D occluders for the objects of `scene` that can carry them: for each
 * static object that is not see-through and has no occluder of its own (footprint, occluder mesh,
 * SL_OBJECT_OCCLUDER), whose mesh is closed and consistently oriented once welded and
 * once loose parts are peeled off (triangles with an edge no other triangle has, round after
 * round: a ledge glued on along a wall's edge); its closed connected components, if it has open
 * ones too; holes in the plane of its lowest z are
 * allowed: a building without a floor), boxes lying strictly inside the solid they enclose are added as one occluder mesh of the object
 * (sl_scene_add_mesh + sl_scene_add_occluder: the boxes, 12 triangles each, closed, wound
 * outward, in world coordinates). Open meshes get nothing. The occlusion methods use an
 * occluder mesh with an object as that object's occluder, while the eye is outside the object's
 * box. Deterministic: the same scene and
 * options add the same boxes in the same order. Sets the metadata key "occluders.synthesised" to
 * the number of boxes when any were added. Running it again adds nothing (every object that got
 * boxes now has occluders of its own). stats may be NULL; alloc may be NULL (the default).
 * Thread safety: mutates the scene (exclusive access). */
SL_API sl_status sl_synth_occluders(sl_scene scene, const sl_synth_options *opt, const sl_allocator *alloc,
                                    sl_synth_stats *stats, sl_error *err);

#ifdef __cplusplus
}
#endif
#endif
