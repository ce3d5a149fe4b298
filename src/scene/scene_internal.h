/* Internal layout of sl_scene, shared by the scene layer (model, .slscene reader/writer,
 * importers, generators) and readable by higher layers that need raw arrays for speed.
 *
 * All bulk data lives in flat sl_arrays so that a .slscene section maps onto each array without
 * a copy: a loaded scene's arrays are borrowed from the file mapping (cap == 0) until changed. */
#ifndef SL_SCENE_INTERNAL_H
#define SL_SCENE_INTERNAL_H

#include "sightline/scene.h"
#include "sightline/view.h"
#include "core/sl_core.h"

/* One mesh: a range of the shared vertex array and a range of the shared index array. Indices
 * are local to the mesh (0..vertex_count-1). */
typedef struct sl_mesh_rec {
    uint64_t first_vertex;
    uint64_t first_index;       /* in uint32 indices, a multiple of 3 */
    uint32_t vertex_count;
    uint32_t triangle_count;
    sl_aabb bounds;
} sl_mesh_rec;

/* One object. transform == SL_NONE means identity. */
typedef struct sl_object_rec {
    uint32_t mesh;
    uint32_t color;
    uint32_t kind;
    uint32_t flags;
    uint32_t transform;         /* index into transforms, or SL_NONE */
    uint32_t reserved;
} sl_object_rec;

typedef struct sl_footprint_rec {
    uint32_t first_vertex;      /* into footprint_xy (pairs) */
    uint32_t vertex_count;
    float base_z, roof_z;
    uint32_t object;
    uint32_t reserved;
} sl_footprint_rec;

/* One shrunk occluder level: its footprints follow those of the levels before it in olevel_fps. */
typedef struct sl_olevel_rec {
    float eps;                  /* horizontal */
    float eps_z;                /* vertical, in [0, eps] */
    uint32_t flags;             /* SL_OCCLUDER_LEVEL_* */
    uint32_t footprint_count;
} sl_olevel_rec;

typedef struct sl_occluder_rec {
    uint32_t mesh;
    uint32_t transform;         /* index into transforms, or SL_NONE */
    uint32_t object;
    uint32_t reserved;
} sl_occluder_rec;

/* A motion record (sl_object_motion; .slscene 1.3 MOTN, 128 bytes). */
enum { SL_MOTION_REC_PATH = 1u << 0 };
typedef struct sl_motion_rec {
    uint32_t object;
    uint32_t flags;             /* SL_MOTION_REC_PATH */
    float max_speed;
    float speed, phase;
    uint32_t reserved0;
    sl_aabb region;
    float from[3], to[3];
    sl_affine base;
    uint32_t reserved[2];
} sl_motion_rec;

typedef struct sl_polygon_rec {
    uint32_t first_vertex;
    uint32_t vertex_count;
} sl_polygon_rec;

/* One material (id = position + 1). The texture path is bytes [texture_offset, +texture_length)
 * of material_text, followed there by a NUL; texture_length 0: none (and texture_offset 0). */
typedef struct sl_material_rec {
    float base_color[4];
    uint32_t alpha_mode;
    float alpha_cutoff;
    uint32_t flags;
    uint32_t texture_offset;
    uint32_t texture_length;
    uint32_t reserved;
} sl_material_rec;

typedef struct sl_meta_rec {
    char *key;
    char *value;
} sl_meta_rec;

struct sl_scene_t {
    sl_allocator alloc;

    sl_array meshes;            /* sl_mesh_rec */
    sl_array positions;         /* float, 3 per vertex */
    sl_array normals;           /* float, 3 per vertex */
    sl_array indices;           /* uint32 */

    sl_array objects;           /* sl_object_rec */
    sl_array bounds;            /* sl_aabb per object, world space */
    sl_array transforms;        /* sl_affine */

    sl_array footprints;        /* sl_footprint_rec */
    sl_array footprint_xy;      /* float pairs */
    sl_array occluders;         /* sl_occluder_rec */

    bool has_terrain;
    uint32_t terrain_nx, terrain_ny;
    float terrain_origin_x, terrain_origin_y, terrain_cell;
    sl_array terrain_heights;   /* float */

    sl_array street_polys;      /* sl_polygon_rec */
    sl_array street_xy;         /* float pairs */
    sl_array street_nodes;      /* sl_street_node */
    sl_array street_edges;      /* sl_street_edge */

    bool has_bsp;
    uint32_t bsp_cluster_count, bsp_cluster_bytes;
    sl_array bsp_planes;        /* sl_plane */
    sl_array bsp_nodes;         /* sl_bsp_node */
    sl_array bsp_leaves;        /* sl_bsp_leaf */
    sl_array bsp_leaf_objects;  /* uint32 */
    sl_array bsp_pvs;           /* uint8 */

    sl_array meta;              /* sl_meta_rec (strings always owned) */

    sl_array materials;         /* sl_material_rec, material id i at index i-1 */
    sl_array material_text;     /* char: the texture paths, each followed by a NUL, in material order */
    sl_array object_materials;  /* uint32 material id per object, or empty: every object has none */
    sl_array uvs;               /* float, 2 per vertex of positions, or empty: no mesh has UVs */
    sl_array mesh_uvs;          /* uint8 per mesh: 1 when its range of uvs is real, or empty */
    sl_array object_name_len;   /* uint32 per object: its name's length in bytes (0: none), or empty */
    sl_array object_name_text;  /* char: the names, each followed by a NUL, in object order (unnamed: nothing) */
    sl_array object_name_off;   /* uint32 per object: where its name starts in the text (derived, not stored) */
    char *base_dir;             /* folder texture paths are relative to (owned), or NULL */

    /* shrunk occluder levels (occluder_levels.c; .slscene 1.2 OLVL, OLFP, OLXY) */
    sl_array olevels;           /* sl_olevel_rec, ascending eps */
    sl_array olevel_fps;        /* sl_footprint_rec, the levels' footprints one level after another */
    sl_array olevel_xy;         /* float pairs */
    sl_array olevel_first;      /* uint32 per level: its first footprint (derived, not stored) */

    /* moving objects (motion.c; .slscene 1.3 MOTN) */
    sl_array motions;           /* sl_motion_rec, ascending object */

    /* backing file mapping of a loaded .slscene (NULL when built in memory) */
    sl_mapping mapping;
};

/* Shorthand accessors for hot loops. */
/* The view of a validated v with a finite far plane: v itself, or its sl_view_bound_far by the
 * scene's bounds (one pass over the object boxes) written to *tmp; *out points to the one to use
 * (src/scene/scene_view.c; the culler wrapper and the oracle). */
sl_status sl_scene_finite_view(sl_scene s, const sl_view *v, sl_view *tmp, const sl_view **out, sl_error *err);

static inline const sl_mesh_rec *sl_scene_meshes(const struct sl_scene_t *s) { return (const sl_mesh_rec *)s->meshes.data; }
static inline const sl_object_rec *sl_scene_objects(const struct sl_scene_t *s) { return (const sl_object_rec *)s->objects.data; }
static inline const float *sl_scene_positions(const struct sl_scene_t *s) { return (const float *)s->positions.data; }
static inline const uint32_t *sl_scene_indices(const struct sl_scene_t *s) { return (const uint32_t *)s->indices.data; }
static inline const sl_affine *sl_scene_transforms(const struct sl_scene_t *s) { return (const sl_affine *)s->transforms.data; }

/* Reason a texture path breaks the rules of sl_material, or NULL when it is fine (len bytes at p,
 * no terminator needed; the .slscene reader checks its bytes with it). */
const char *sl_texture_path_problem(const char *p, size_t len);
/* Reason a material record is invalid, or NULL (finite colour in [0,1], known alpha mode, cutoff). */
const char *sl_material_rec_problem(const sl_material_rec *m);

/* Set the scene's base folder (sl_scene_set_base_dir) to the folder holding file `path`: the part
 * before its last '/', "/" for a file in the root, "." for a bare name (the .slscene loader, the
 * assimp importer). */
sl_status sl_scene_set_base_dir_of(sl_scene scene, const char *path, sl_error *err);

/* Recompute the world bounds of one object from its mesh bounds and transform. */
void sl_scene_update_object_bounds(struct sl_scene_t *s, uint32_t object);

/* Validate every cross-reference of a scene whose arrays were filled directly (by the .slscene
 * reader): mesh ranges inside the vertex/index arrays, indices < vertex counts, finite floats,
 * object/footprint/occluder references, BSP child/leaf/cluster indices. Names the offending
 * element in err. */
sl_status sl_scene_validate(const struct sl_scene_t *s, sl_error *err);

/* Whether sl_scene_push_polygon would accept the polygon (the bakers drop what it would refuse). */
bool sl_scene_polygon_ok(const float *xy, uint32_t n);
/* Validate a polygon and append it CCW to an xy array (the footprint rules: >= 3 vertices, finite,
 * non-zero area, simple; a repeated closing vertex dropped). */
sl_status sl_scene_push_polygon(struct sl_scene_t *s, sl_array *xy_arr, const float *xy, uint32_t n, const char *what,
                                uint32_t *first, uint32_t *count, sl_error *err);
/* Occluder levels (occluder_levels.c): release; check and index the arrays a reader filled. */
void sl_scene_levels_free(struct sl_scene_t *s);
void sl_scene_motions_free(struct sl_scene_t *s);
/* Check the loaded motion records (objects, order, fields, paths inside regions). */
sl_status sl_scene_motions_load(struct sl_scene_t *s, sl_error *err);
/* The record of an object, or NULL. */
const sl_motion_rec *sl_scene_motion_rec(const struct sl_scene_t *s, uint32_t object);
sl_status sl_scene_levels_load(struct sl_scene_t *s, sl_error *err);

/* Recompute all mesh bounds and object bounds (after a load). */
void sl_scene_recompute_bounds(struct sl_scene_t *s);
/* Object names (scene_names.c): room for one more object's entry (before sl_array pushes that
 * cannot fail), its entry after an object was added, release, and the check and index of the
 * ONAM/NAMT arrays a reader filled. */
bool sl_scene_names_reserve(struct sl_scene_t *s);
void sl_scene_names_on_add(struct sl_scene_t *s);
void sl_scene_names_free(struct sl_scene_t *s);
sl_status sl_scene_names_load(struct sl_scene_t *s, sl_error *err);

/* Write the scene as .slscene to an open file descriptor (left open; written from its current
 * offset, straight through); `name` is the destination's name in messages. */
sl_status sl_scene_save_fd(sl_scene s, int fd, const char *name, sl_error *err);

#endif
