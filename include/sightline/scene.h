/* Sightline scene model.
 *
 * A scene holds
 *  - meshes: indexed triangle meshes (float positions, float normals), shared by instancing;
 *  - objects: the unit of visibility (a building, a car, a tree, a group of BSP faces): a mesh,
 *    an affine transform, a colour, a kind tag and a world-space AABB; object ids are dense
 *    indices 0..object_count-1 in insertion order;
 *  - occluders, kept apart from render geometry: 2.5D building footprints (simple CCW polygons
 *    seen from +z with base and roof height; each edge is a façade quad) and general 3D occluder
 *    meshes (a mesh plus a transform);
 *  - an optional terrain height field, an optional street network (polygons of free space plus a
 *    centre-line graph), optional BSP data from Quake III maps (nodes, leaves, clusters and the
 *    map's own cluster PVS), and string metadata.
 *
 * Units are metres, Z up. A scene is built with the sl_scene_add_* calls, or loaded from a
 * .slscene file (see slscene.h), read into memory or, on request, mapped: a mapped scene's bulk
 * arrays stay read-only in the mapping and the add calls copy what they need first. Object transforms stay writable (dynamic objects).
 *
 * Thread safety: const accessors may run concurrently from any number of threads; mutating calls
 * need exclusive access.
 */
#ifndef SIGHTLINE_SCENE_H
#define SIGHTLINE_SCENE_H

#include "core.h"
#include "geom.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sl_scene_t *sl_scene;

/* Kind tags. Values are stored in files: never renumber. */
typedef enum sl_object_kind {
    SL_KIND_OTHER = 0,
    SL_KIND_BUILDING = 1,
    SL_KIND_GROUND = 2,     /* streets, squares, parks, terrain patches */
    SL_KIND_CAR = 3,
    SL_KIND_TREE = 4,
    SL_KIND_LAMP = 5,
    SL_KIND_BSP_FACES = 6,  /* faces of a Quake III BSP leaf */
    SL_KIND_WATER = 7,
    SL_KIND_IMPORTED = 8,   /* a node of a file read through assimp */
    SL_KIND_COUNT = 9
} sl_object_kind;

/* Short lowercase name of a kind ("building"), or "unknown". */
SL_API const char *sl_object_kind_name(uint32_t kind);

/* Object flags. */
enum {
    SL_OBJECT_DYNAMIC = 1u << 0,       /* may move between frames (cars) */
    SL_OBJECT_CLOSED_CONVEX = 1u << 1, /* the mesh is a closed convex part (back-face rejection) */
    SL_OBJECT_OCCLUDER = 1u << 2,      /* solid: its own render mesh may serve as an occluder */
    SL_OBJECT_SEE_THROUGH = 1u << 3    /* alpha-tested or transparent: it can be seen but never hides
                                          anything (no depth writes in the oracle and the renderer,
                                          never an occluder; docs/oracle.md) */
};
/* See-through objects never occlude, and the scene keeps it so (every culler and baker may rely on
 * it):
 *  - sl_scene_add_object sets SL_OBJECT_SEE_THROUGH on an object whose material's alpha mode is
 *    SL_ALPHA_MASK or SL_ALPHA_BLEND, and clears SL_OBJECT_OCCLUDER on every see-through object
 *    (whatever the caller passed: an alpha-tested building stays a building, not an occluder);
 *  - sl_scene_add_footprint and sl_scene_add_occluder refuse (SL_ERROR_INVALID_ARGUMENT) a
 *    footprint or occluder mesh attached to a see-through object;
 *  - the .slscene reader refuses a file that breaks any of these (SL_ERROR_FORMAT).
 * Methods that use every object's render mesh as an occluder (an "all objects" option) skip
 * see-through objects themselves. */

/* --- materials ------------------------------------------------------------------------------ */

/* Alpha modes (the glTF 2.0 ones). Values are stored in files: never renumber. */
typedef enum sl_alpha_mode {
    SL_ALPHA_OPAQUE = 0, /* alpha ignored: the surface is solid */
    SL_ALPHA_MASK = 1,   /* alpha test: fragments with alpha < alpha_cutoff are discarded */
    SL_ALPHA_BLEND = 2   /* transparent, blended */
} sl_alpha_mode;

/* Material flags. */
enum {
    SL_MATERIAL_DOUBLE_SIDED = 1u << 0 /* draw back faces too (the oracle's face rule: docs/oracle.md) */
};

/* Material id 0 means "no material: the object's own colour". Real materials are numbered
 * 1..sl_scene_material_count() in the order they were added. SL_NONE is accepted as 0 by
 * sl_scene_add_object. */
#define SL_MATERIAL_NONE 0u
/* Longest base-colour texture path, in bytes (without the terminator). */
#define SL_TEXTURE_PATH_MAX 1024u

/* A material, as added (sl_scene_add_material copies it) and as read back (sl_scene_material). */
typedef struct sl_material {
    float base_color[4];        /* RGBA factor, each finite and in [0, 1] (glTF baseColorFactor;
                                   multiplied with the texture where there is one) */
    const char *base_color_texture; /* NULL (or "" when adding): none. Otherwise a path relative to
                                   the scene's base folder (sl_scene_base_dir): '/'-separated, no
                                   leading '/', no empty, "." or ".." component, no '\\', bytes
                                   0x20..0x7e or >= 0x80, at most SL_TEXTURE_PATH_MAX bytes.
                                   Read back, it is borrowed from the scene. */
    uint32_t alpha_mode;        /* sl_alpha_mode */
    float alpha_cutoff;         /* SL_ALPHA_MASK: in [0, 1] (glTF default 0.5); stored as given otherwise */
    uint32_t flags;             /* SL_MATERIAL_* */
} sl_material;

typedef struct sl_mesh_desc {
    const float *positions;    /* 3 floats per vertex */
    const float *normals;      /* 3 floats per vertex, or NULL: area-weighted normals are computed */
    uint32_t vertex_count;
    const uint32_t *indices;   /* 3 per triangle, each < vertex_count */
    uint32_t triangle_count;
    const float *uvs;          /* 2 floats per vertex (u, v: texture channel 0, finite), or NULL: none */
} sl_mesh_desc;

/* Read-only view of a mesh; pointers stay valid until the scene is changed or destroyed. */
typedef struct sl_mesh_view {
    const float *positions;
    const float *normals;
    uint32_t vertex_count;
    const uint32_t *indices;
    uint32_t triangle_count;
    sl_aabb bounds;            /* in mesh (local) coordinates */
    const float *uvs;          /* 2 floats per vertex, or NULL when the mesh has none */
} sl_mesh_view;

typedef struct sl_object_desc {
    uint32_t mesh;
    const sl_affine *transform; /* NULL: identity */
    uint32_t color;             /* 0xRRGGBBAA */
    uint32_t kind;              /* sl_object_kind */
    uint32_t flags;             /* SL_OBJECT_* (see-through rules above) */
    uint32_t material;          /* material id, or SL_MATERIAL_NONE (0) / SL_NONE: the colour above */
} sl_object_desc;

typedef struct sl_object_view {
    uint32_t mesh;
    uint32_t color;
    uint32_t kind;
    uint32_t flags;
    sl_affine transform;
    bool identity;              /* transform is the identity */
    sl_aabb bounds;             /* world space */
    uint32_t triangle_count;
    uint32_t material;          /* material id, or SL_MATERIAL_NONE (0) */
} sl_object_view;

typedef struct sl_footprint_desc {
    const float *xy;            /* 2 floats per vertex, simple polygon, either orientation */
    uint32_t vertex_count;      /* >= 3; a repeated closing vertex is dropped */
    float base_z, roof_z;       /* roof_z > base_z */
    uint32_t object;            /* the building object it stands for, or SL_NONE */
} sl_footprint_desc;

typedef struct sl_footprint_view {
    const float *xy;            /* CCW seen from +z */
    uint32_t vertex_count;
    float base_z, roof_z;
    uint32_t object;
} sl_footprint_view;

typedef struct sl_occluder_view {
    uint32_t mesh;
    sl_affine transform;
    uint32_t object;            /* object it belongs to, or SL_NONE */
} sl_occluder_view;

typedef struct sl_terrain_desc {
    uint32_t nx, ny;            /* samples along x and y, >= 2 each */
    float origin_x, origin_y;   /* world position of sample (0,0) */
    float cell;                 /* spacing between samples, > 0 */
    const float *heights;       /* nx*ny, row-major: heights[j*nx+i] at (origin_x+i*cell, origin_y+j*cell) */
} sl_terrain_desc;

typedef sl_terrain_desc sl_terrain_view;

/* Street network: polygons covering the free (walkable/drivable) space, and a centre-line graph. */
typedef struct sl_street_node { float x, y; } sl_street_node;
typedef struct sl_street_edge { uint32_t a, b; float width; uint32_t flags; } sl_street_edge;
enum { SL_STREET_AVENUE = 1u << 0, SL_STREET_BRIDGE = 1u << 1, SL_STREET_SQUARE = 1u << 2 };

typedef struct sl_polygon_view {
    const float *xy;
    uint32_t vertex_count;
} sl_polygon_view;

/* Quake III style BSP data. Child index c >= 0 is a node; c < 0 is leaf -(c+1). */
typedef struct sl_bsp_node { uint32_t plane; int32_t children[2]; sl_aabb bounds; } sl_bsp_node;
typedef struct sl_bsp_leaf {
    int32_t cluster;            /* -1: outside the map / opaque */
    int32_t area;
    sl_aabb bounds;
    uint32_t first_object;      /* range in the leaf-object list */
    uint32_t object_count;
} sl_bsp_leaf;

typedef struct sl_bsp_desc {
    const sl_plane *planes; uint32_t plane_count;   /* front side: a*x+b*y+c*z+d >= 0 */
    const sl_bsp_node *nodes; uint32_t node_count;
    const sl_bsp_leaf *leaves; uint32_t leaf_count;
    const uint32_t *leaf_objects; uint32_t leaf_object_count;
    uint32_t cluster_count;
    uint32_t cluster_bytes;     /* bytes per cluster row of the PVS bit matrix */
    const uint8_t *pvs;         /* cluster_count*cluster_bytes, or NULL when the map has no vis */
} sl_bsp_desc;

typedef sl_bsp_desc sl_bsp_view;

/* Summary counts. */
typedef struct sl_scene_stats {
    uint32_t mesh_count, object_count, footprint_count, occluder_count;
    uint64_t vertex_count, triangle_count;     /* stored (instanced meshes counted once) */
    uint64_t instanced_triangle_count;         /* rendered (sum over objects) */
    uint32_t street_polygon_count, street_node_count, street_edge_count;
    uint32_t objects_per_kind[SL_KIND_COUNT];
    uint64_t triangles_per_kind[SL_KIND_COUNT];
    bool has_terrain, has_bsp;
    uint32_t bsp_leaf_count, bsp_cluster_count;
    size_t memory_bytes;                       /* bytes held by the scene (mapped bytes included) */
    sl_aabb bounds;
    uint32_t material_count;                   /* materials (ids 1..material_count) */
    uint32_t see_through_count;                /* objects with SL_OBJECT_SEE_THROUGH */
    uint32_t uv_mesh_count;                    /* meshes with UVs */
} sl_scene_stats;

/* --- lifetime ------------------------------------------------------------------------------ */

/* Create an empty scene. alloc may be NULL. */
SL_API sl_status sl_scene_create(const sl_allocator *alloc, sl_scene *out, sl_error *err);
/* Release a scene and everything it owns (including a file mapping). NULL is ignored. */
SL_API void sl_scene_destroy(sl_scene scene);

/* --- building -------------------------------------------------------------------------------- */

/* Add a mesh (copied). Fails on out-of-range indices or non-finite coordinates. */
SL_API sl_status sl_scene_add_mesh(sl_scene scene, const sl_mesh_desc *desc, uint32_t *out_mesh, sl_error *err);
/* Add a material (copied, validated: finite colour and cutoff in [0, 1], a known alpha mode, a
 * valid texture path). Its id (1, 2, ...) is returned in out_material (may be NULL). */
SL_API sl_status sl_scene_add_material(sl_scene scene, const sl_material *material, uint32_t *out_material, sl_error *err);
/* Add an object instancing a mesh. Its id is returned in out_object (may be NULL). A material id
 * must exist; a mask or blend material makes the object see-through (rules above). */
SL_API sl_status sl_scene_add_object(sl_scene scene, const sl_object_desc *desc, uint32_t *out_object, sl_error *err);
/* Add a 2.5D footprint occluder. The polygon is validated (simple, finite, non-zero area) and
 * stored counter-clockwise. */
SL_API sl_status sl_scene_add_footprint(sl_scene scene, const sl_footprint_desc *desc, uint32_t *out_index, sl_error *err);
/* Add a 3D occluder mesh (closed and solid is assumed by the methods that use it). */
SL_API sl_status sl_scene_add_occluder(sl_scene scene, uint32_t mesh, const sl_affine *transform, uint32_t object, sl_error *err);
/* Set (replace) the terrain height field (copied). */
SL_API sl_status sl_scene_set_terrain(sl_scene scene, const sl_terrain_desc *desc, sl_error *err);
/* Add a polygon of free street space. */
SL_API sl_status sl_scene_add_street_polygon(sl_scene scene, const float *xy, uint32_t vertex_count, sl_error *err);
/* Set (replace) the street centre-line graph (copied). */
SL_API sl_status sl_scene_set_street_graph(sl_scene scene, const sl_street_node *nodes, uint32_t node_count,
                                           const sl_street_edge *edges, uint32_t edge_count, sl_error *err);
/* Set (replace) the BSP data (copied, validated). */
SL_API sl_status sl_scene_set_bsp(sl_scene scene, const sl_bsp_desc *desc, sl_error *err);
/* Set a metadata string (key and value copied; an existing key is replaced). */
SL_API sl_status sl_scene_set_meta(sl_scene scene, const char *key, const char *value, sl_error *err);

/* Set (replace) the folder that texture paths are relative to (copied; NULL or "" clears). The
 * importers set the model file's folder, sl_scene_load the .slscene file's folder. */
SL_API sl_status sl_scene_set_base_dir(sl_scene scene, const char *dir, sl_error *err);

/* Move an object (dynamic objects): replaces its transform and recomputes its world bounds. */
SL_API sl_status sl_scene_set_object_transform(sl_scene scene, uint32_t object, const sl_affine *transform, sl_error *err);

/* --- reading ----------------------------------------------------------------------------------- */

/* How many meshes, objects, building footprints, occluders and street polygons the scene holds. */
SL_API uint32_t sl_scene_mesh_count(sl_scene scene);
SL_API uint32_t sl_scene_object_count(sl_scene scene);
SL_API uint32_t sl_scene_footprint_count(sl_scene scene);
SL_API uint32_t sl_scene_occluder_count(sl_scene scene);
SL_API uint32_t sl_scene_street_polygon_count(sl_scene scene);

/* A read-only view of mesh `mesh` / object `object`, borrowed from the scene: valid until the
 * scene changes or is destroyed. An index beyond the count gives a zeroed view. */
SL_API sl_mesh_view sl_scene_mesh(sl_scene scene, uint32_t mesh);
SL_API sl_object_view sl_scene_object(sl_scene scene, uint32_t object);
/* World bounds of one object (cheaper than sl_scene_object). */
SL_API sl_aabb sl_scene_object_bounds(sl_scene scene, uint32_t object);
/* Contiguous array of all world bounds, object_count entries. */
SL_API const sl_aabb *sl_scene_object_bounds_array(sl_scene scene);
SL_API sl_footprint_view sl_scene_footprint(sl_scene scene, uint32_t index);
/* Does footprint `index` belong to a DYNAMIC object? A footprint stays where it was placed while
 * its object moves (sl_scene_set_object_transform does not carry it along), so no method occludes
 * with such a footprint: the online methods use the object's mesh at its current transform
 * instead, the bakers and `instant` leave it out (docs/motion.md). False for an index out of range. */
SL_API bool sl_scene_footprint_moves(sl_scene scene, uint32_t index);
/* The façade of edge `edge` of a footprint as a quad: base a, base b, roof b, roof a
 * (outward normal by the right-hand rule, i.e. CCW seen from outside). */
SL_API void sl_footprint_facade(const sl_footprint_view *fp, uint32_t edge, sl_vec3 quad[4]);
SL_API sl_occluder_view sl_scene_occluder(sl_scene scene, uint32_t index);
/* False when the scene has no terrain. */
SL_API bool sl_scene_terrain(sl_scene scene, sl_terrain_view *out);
/* Bilinear terrain height at (x,y), clamped at the border; 0 without terrain. */
SL_API float sl_scene_ground_height(sl_scene scene, float x, float y);
SL_API sl_polygon_view sl_scene_street_polygon(sl_scene scene, uint32_t index);
SL_API void sl_scene_street_graph(sl_scene scene, const sl_street_node **nodes, uint32_t *node_count,
                                  const sl_street_edge **edges, uint32_t *edge_count);
/* False when the scene has no BSP data. */
SL_API bool sl_scene_bsp(sl_scene scene, sl_bsp_view *out);
/* Leaf index containing point p, or -1 without BSP data. */
SL_API int32_t sl_scene_bsp_find_leaf(sl_scene scene, sl_vec3 p);
/* Whether eye lies in the domain of the oracles (point and region) and of the cullers' guarantee:
 * always true for a scene without BSP nodes; otherwise true when the BSP leaf holding eye
 * (sl_scene_bsp_find_leaf) has a cluster (cluster >= 0, the playable space). leaf (may be NULL)
 * receives that leaf, or -1 without BSP data. */
SL_API bool sl_oracle_in_domain(sl_scene scene, sl_vec3 eye, int32_t *leaf);
/* Metadata lookup; NULL when absent. */
SL_API const char *sl_scene_meta(sl_scene scene, const char *key);
SL_API uint32_t sl_scene_meta_count(sl_scene scene);
SL_API void sl_scene_meta_at(sl_scene scene, uint32_t i, const char **key, const char **value);

/* --- object names -----------------------------------------------------------------------------
 * An object may carry a name: the node name an importer read (assimp nodes, Quake III models), or
 * an engine's own. Names need not be unique; an object's id is what identifies it, and ids are
 * stable: the same input gives the same objects in the same order. A name is at most
 * SL_OBJECT_NAME_MAX bytes of well-formed UTF-8 without control bytes. Stored in .slscene 1.1
 * (sections ONAM, NAMT). Not thread-safe against a concurrent reader of the same scene. */
#define SL_OBJECT_NAME_MAX 1024u
/* Name object `object` ("" or NULL: no name). SL_ERROR_INVALID_ARGUMENT for a bad object or name
 * (the message says why). */
SL_API sl_status sl_scene_set_object_name(sl_scene scene, uint32_t object, const char *name, sl_error *err);
/* The object's name, "" when it has none (valid until the scene changes). Thread-safe for readers. */
SL_API const char *sl_scene_object_name(sl_scene scene, uint32_t object);
/* The first object named exactly `name`, or SL_NONE. O(objects). */
SL_API uint32_t sl_scene_find_object(sl_scene scene, const char *name);

/* Materials: ids 1..sl_scene_material_count(). sl_scene_material fills *out (its texture
 * pointer borrowed from the scene, NULL for none) and returns true; false (and a zeroed *out)
 * for SL_MATERIAL_NONE or an id beyond the count. */
SL_API uint32_t sl_scene_material_count(sl_scene scene);
SL_API bool sl_scene_material(sl_scene scene, uint32_t material, sl_material *out);
/* The material id of an object (SL_MATERIAL_NONE for none or an id beyond the count). */
SL_API uint32_t sl_scene_object_material(sl_scene scene, uint32_t object);
/* The folder texture paths are relative to, or NULL when none is known (a scene built in memory). */
SL_API const char *sl_scene_base_dir(sl_scene scene);
/* Whether `path` is acceptable as a material's base-colour texture (the rules of sl_material);
 * when not, *why (may be NULL) receives a static reason ("contains a '..' component"). */
SL_API bool sl_texture_path_check(const char *path, const char **why);
/* The file of a material's base-colour texture, for a renderer to decode: base folder + '/' + path,
 * with symbolic links resolved (realpath) and checked to stay inside the base folder (itself
 * resolved). Writes a NUL-terminated path of at most cap bytes to buf. SL_ERROR_NOT_FOUND when the
 * material does not exist or has no texture, the scene has no base folder, or the file does not
 * exist; SL_ERROR_INVALID_ARGUMENT when the resolved file lies outside the base folder (a symbolic
 * link leading out) or is not a regular file; SL_ERROR_LIMIT when cap is too small. Reads the
 * file system; safe to call concurrently. */
SL_API sl_status sl_scene_texture_path(sl_scene scene, uint32_t material, char *buf, size_t cap, sl_error *err);

/* --- shrunk occluder levels (Instant Visibility, docs/instant.md) --------------------------------
 * A scene may carry a few "levels": its footprints eroded ahead of time by a fixed eps (Wonka's
 * thesis ch. 7, baked by sl_shrink_occluder_levels in region.h, which needs GEOS), so that a
 * run-time culler (`instant`) runs a point method on occluders shrunk by eps without GEOS. A level
 * is a list of footprints (simple CCW polygons with base and roof, like sl_scene_footprint) that
 * replace the scene's footprints for that culler: each footprint lies at least eps inside the original
 * one in plan, its roof lowered and its base raised by eps_z, so that it hides from P only what the
 * originals hide from every point within eps of P horizontally and eps_z vertically. Levels are kept
 * in strictly ascending eps and stored in .slscene 1.2 (sections OLVL, OLFP, OLXY; a scene without
 * levels is written as 1.1, byte for byte as before). */
typedef struct sl_occluder_level_view {
    float eps;                  /* horizontal, metres, > 0 */
    float eps_z;                /* vertical, metres, in [0, eps] */
    uint32_t flags;             /* SL_OCCLUDER_LEVEL_* */
    uint32_t footprint_count;
} sl_occluder_level_view;
enum {
    SL_OCCLUDER_LEVEL_MERGED = 1u << 0 /* touching footprints were eroded as one block */
};
/* Add a level (the footprints are copied and validated as sl_scene_add_footprint does). eps must
 * be finite, > 0 and larger than every level's already there; eps_z in [0, eps]; flags only the
 * bits above. SL_ERROR_INVALID_ARGUMENT naming the footprint and the reason otherwise (nothing
 * added). */
SL_API sl_status sl_scene_add_occluder_level(sl_scene scene, float eps, float eps_z, uint32_t flags,
                                             const sl_footprint_desc *footprints, uint32_t count, sl_error *err);
/* Remove every level. */
SL_API void sl_scene_clear_occluder_levels(sl_scene scene);
SL_API uint32_t sl_scene_occluder_level_count(sl_scene scene);
/* Level `level` (a zeroed view beyond the count). */
SL_API sl_occluder_level_view sl_scene_occluder_level(sl_scene scene, uint32_t level);
/* Footprint `index` of a level (a zeroed view beyond the counts); borrowed like sl_scene_footprint. */
SL_API sl_footprint_view sl_scene_occluder_level_footprint(sl_scene scene, uint32_t level, uint32_t index);

/* --- moving objects (Wonka's thesis §8.5; docs/motion.md) -------------------------------------
 * A DYNAMIC object may carry a motion record: the fastest it moves and the box it never leaves.
 * With it, methods that keep a set for a while can bound where the object can be: `instant` tests
 * the object's box grown by max_speed times the time its set is displayed (clipped to the region),
 * instead of counting the object visible everywhere. The contract is the caller's: between any two
 * calls that move the object (sl_scene_set_object_transform, sl_scene_animate), no point of its box
 * moves farther than max_speed times the time between them, and its world box stays inside region.
 * A DYNAMIC object without a record may move anywhere at any speed (such objects are always in an
 * `instant` set, then frustum-tested).
 *
 * A record may hold a deterministic path, which sl_scene_animate follows (the city generator's
 * driving cars): the object shuttles between `from` and `to` at `speed`, turned half a turn about
 * the vertical axis through its box centre at each end. Its pose at parameter d (metres travelled,
 * d in [0, 2L), L = |to - from|) is path_base translated by p(d) - from, where p runs from `from` to
 * `to` for d < L and back for d >= L (then also turned about the box centre of path_base, which
 * leaves the world box as it is); d = phase + speed * t wrapped to [0, 2L). Records are stored in
 * .slscene 1.3 (section MOTN). */
typedef struct sl_object_motion {
    float max_speed;            /* m/s, finite, >= 0 (0: never moves) */
    sl_aabb region;             /* the world box the object's box never leaves (finite, min <= max) */
    bool has_path;
    sl_affine path_base;        /* the pose at `from`, heading for `to` (has_path only) */
    sl_vec3 from, to;           /* where the pose's translation runs, |to - from| > 0 */
    float speed;                /* m/s along the path, in (0, max_speed] */
    float phase;                /* metres along the path at t = 0, in [0, 2 |to - from|) */
} sl_object_motion;
/* Give a DYNAMIC object a motion record (replacing its old one), or remove it (motion NULL).
 * Checks every field as above and, with a path, that the object's box along the whole path lies in
 * region; the object's transform is not touched. SL_ERROR_INVALID_ARGUMENT naming the object and the
 * reason (an object that is not DYNAMIC, a path outside its region, ...). Not thread-safe with any
 * other call on the scene. */
SL_API sl_status sl_scene_set_object_motion(sl_scene scene, uint32_t object, const sl_object_motion *motion,
                                            sl_error *err);
/* The object's motion record, if it has one (false, *out untouched, otherwise). */
SL_API bool sl_scene_object_motion(sl_scene scene, uint32_t object, sl_object_motion *out);
/* Objects with a motion record, and how many of those have a path. */
SL_API uint32_t sl_scene_motion_count(sl_scene scene);
SL_API uint32_t sl_scene_path_count(sl_scene scene);
/* Put every object with a path at its pose at time t (seconds; any finite t, negative too):
 * sl_scene_set_object_transform for each, so cullers need sl_culler_scene_changed afterwards.
 * Deterministic: the same t gives the same transforms bit for bit. */
SL_API sl_status sl_scene_animate(sl_scene scene, double t, sl_error *err);

/* World bounds of all objects. */
SL_API sl_aabb sl_scene_bounds(sl_scene scene);
SL_API void sl_scene_get_stats(sl_scene scene, sl_scene_stats *out);

#ifdef __cplusplus
}
#endif
#endif
