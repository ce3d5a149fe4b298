/* The native scene file, .slscene: writer and reader. The byte layout, the versioning rules and
 * the checks done on load are documented in docs/slscene-format.md; keep the two in step.
 *
 * Shape of the file: a 64-byte header, a table of 48-byte section entries, then one section per
 * sl_array of struct sl_scene_t (plus three small parsed sections: terrain header, BSP header,
 * metadata). Every section starts on a 64-byte boundary and carries its own XXH3-64 checksum, so
 * the reader can map the file and point the scene's arrays straight into the mapping.
 *
 * Invariants the reader establishes before a scene leaves this file:
 *  - every byte it reads lies inside the file (offsets, sizes and counts are overflow-checked);
 *  - checksums match (unless the caller skipped them), required sections exist, known sections
 *    have the element size this version expects;
 *  - sl_scene_validate() passed (cross references, finite floats), mesh bounds are finite and
 *    contain their vertices, polygons are counter-clockwise, metadata keys are unique;
 *  - object records, transforms and world bounds are owned copies (dynamic objects move), world
 *    bounds recomputed from the mesh bounds and transforms (they are derived data).
 * The writer is deterministic: record padding (the `reserved` fields) is written as zero, the
 * gaps between sections are zero and the section order is fixed. */
#include "scene_internal.h"
#include "core/bytes.h"
#include "core/container.h"
#include "sightline/slscene.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the .slscene reader maps little-endian records directly; a big-endian host needs byte swapping here"
#endif

#define SLS_MAJOR 1u
#define SLS_MINOR 3u /* 1.1: materials, object materials, UVs; 1.2: shrunk occluder levels; 1.3: motion records
                      (1.0 files still load) */
#define SLS_MINOR_NO_MOTION 2u /* a scene without motion records is written as 1.2 (or 1.1), as before */
#define SLS_MINOR_NO_LEVELS 1u /* a scene without occluder levels is written as 1.1, byte for byte as before */
#define SLS_HEADER_SIZE 64u
#define SLS_ENTRY_SIZE 48u
#define SLS_ALIGN 64u
#define SLS_MAX_SECTIONS 4096u /* far more than any version will define; bounds hostile tables */
#define SLS_HASH_SEED 0u
#define SLS_TERRAIN_MAX_SAMPLES (1u << 30) /* the same limit sl_scene_set_terrain enforces */

static const uint8_t k_magic[8] = {'S', 'L', 'S', 'C', 'E', 'N', 'E', 0};

enum { SLS_FLAG_TERRAIN = 1u << 0, SLS_FLAG_BSP = 1u << 1 };

/* Header field offsets (all little-endian). */
enum {
    H_MAGIC = 0,
    H_MAJOR = 8,
    H_MINOR = 12,
    H_FLAGS = 16,
    H_HEADER_SIZE = 20,
    H_SECTION_COUNT = 24,
    H_ENTRY_SIZE = 28,
    H_TABLE_OFFSET = 32,
    H_FILE_SIZE = 40,
    H_TABLE_HASH = 48,
    H_HEADER_HASH = 56
};
/* Section entry field offsets. */
enum { E_TAG = 0, E_ELEM = 4, E_COUNT = 8, E_OFFSET = 16, E_SIZE = 24, E_HASH = 32, E_RESERVED = 40 };

/* Records written raw must have exactly the layout the format documents: no implicit padding. */
#define SLS_LAYOUT(T, size) _Static_assert(sizeof(T) == (size), #T " has the documented size")
#define SLS_FIELD(T, f, off) _Static_assert(offsetof(T, f) == (off), #T "." #f " at its documented offset")
SLS_LAYOUT(sl_vec3, 12);
SLS_LAYOUT(sl_aabb, 24);
SLS_LAYOUT(sl_affine, 48);
SLS_LAYOUT(sl_plane, 16);
SLS_LAYOUT(sl_mesh_rec, 48);
SLS_FIELD(sl_mesh_rec, first_index, 8);
SLS_FIELD(sl_mesh_rec, vertex_count, 16);
SLS_FIELD(sl_mesh_rec, triangle_count, 20);
SLS_FIELD(sl_mesh_rec, bounds, 24);
SLS_LAYOUT(sl_object_rec, 24);
SLS_FIELD(sl_object_rec, transform, 16);
SLS_FIELD(sl_object_rec, reserved, 20);
SLS_LAYOUT(sl_footprint_rec, 24);
SLS_FIELD(sl_footprint_rec, base_z, 8);
SLS_FIELD(sl_footprint_rec, object, 16);
SLS_FIELD(sl_footprint_rec, reserved, 20);
SLS_LAYOUT(sl_motion_rec, 128);
SLS_FIELD(sl_motion_rec, max_speed, 8);
SLS_FIELD(sl_motion_rec, region, 24);
SLS_FIELD(sl_motion_rec, from, 48);
SLS_FIELD(sl_motion_rec, base, 72);
SLS_FIELD(sl_motion_rec, reserved, 120);
SLS_LAYOUT(sl_olevel_rec, 16);
SLS_FIELD(sl_olevel_rec, eps_z, 4);
SLS_FIELD(sl_olevel_rec, flags, 8);
SLS_FIELD(sl_olevel_rec, footprint_count, 12);
SLS_LAYOUT(sl_occluder_rec, 16);
SLS_FIELD(sl_occluder_rec, object, 8);
SLS_FIELD(sl_occluder_rec, reserved, 12);
SLS_LAYOUT(sl_material_rec, 40);
SLS_FIELD(sl_material_rec, alpha_mode, 16);
SLS_FIELD(sl_material_rec, alpha_cutoff, 20);
SLS_FIELD(sl_material_rec, flags, 24);
SLS_FIELD(sl_material_rec, texture_offset, 28);
SLS_FIELD(sl_material_rec, texture_length, 32);
SLS_FIELD(sl_material_rec, reserved, 36);
SLS_LAYOUT(sl_polygon_rec, 8);
SLS_LAYOUT(sl_street_node, 8);
SLS_LAYOUT(sl_street_edge, 16);
SLS_FIELD(sl_street_edge, width, 8);
SLS_FIELD(sl_street_edge, flags, 12);
SLS_LAYOUT(sl_bsp_node, 36);
SLS_FIELD(sl_bsp_node, children, 4);
SLS_FIELD(sl_bsp_node, bounds, 12);
SLS_LAYOUT(sl_bsp_leaf, 40);
SLS_FIELD(sl_bsp_leaf, bounds, 8);
SLS_FIELD(sl_bsp_leaf, first_object, 32);
SLS_FIELD(sl_bsp_leaf, object_count, 36);

/* The two small header records, written field by field. */
#define SLS_TERRAIN_REC 24u /* nx, ny, origin_x, origin_y, cell, reserved */
#define SLS_BSP_REC 16u     /* cluster_count, cluster_bytes, reserved x2 */

/* How a section maps onto the scene. */
typedef enum sec_kind {
    K_ARRAY,    /* an sl_array, borrowed from a mapping when possible */
    K_WRITABLE, /* an sl_array that is always an owned copy (objects move) */
    K_TERRAIN,  /* the terrain header record */
    K_BSP,      /* the BSP header record */
    K_META      /* length-prefixed key/value strings */
} sec_kind;

/* When a section must be present. */
typedef enum sec_need {
    N_REQUIRED, /* always */
    N_OPTIONAL, /* absent means empty */
    N_TERRAIN,  /* present exactly when the header has the terrain flag */
    N_BSP_HEAD, /* present exactly when the header has the BSP flag */
    N_BSP,      /* optional, and only with the BSP flag */
    N_LEVELS    /* the occluder levels: all three present (OLVL with at least one level) or none */
} sec_need;

typedef struct sec_def {
    char tag[5];
    uint32_t elem;    /* element size in bytes */
    size_t array;     /* offsetof the sl_array in struct sl_scene_t (array kinds) */
    sec_kind kind;
    sec_need need;
    uint64_t max_count; /* ids are uint32: counts beyond this cannot be referenced */
    const char *what;
    uint32_t since_minor; /* first minor version (of major 1) that has this section */
} sec_def;

#define ARR(f) offsetof(struct sl_scene_t, f)
#define ID_MAX ((uint64_t)UINT32_MAX - 1)
#define XY_MAX (2 * (uint64_t)UINT32_MAX) /* polygon first_vertex is uint32, 2 floats per vertex */
#define NOLIMIT UINT64_MAX

/* Every section this version knows, in the order the writer emits them. Tags are stored in files:
 * never reuse one with a different meaning. */
static const sec_def k_defs[] = {
    {"MESH", sizeof(sl_mesh_rec), ARR(meshes), K_ARRAY, N_REQUIRED, ID_MAX, "meshes", 0},
    {"VPOS", sizeof(float), ARR(positions), K_ARRAY, N_REQUIRED, NOLIMIT, "vertex positions", 0},
    {"VNRM", sizeof(float), ARR(normals), K_ARRAY, N_REQUIRED, NOLIMIT, "vertex normals", 0},
    {"VIDX", sizeof(uint32_t), ARR(indices), K_ARRAY, N_REQUIRED, NOLIMIT, "triangle indices", 0},
    {"OBJS", sizeof(sl_object_rec), ARR(objects), K_WRITABLE, N_REQUIRED, ID_MAX, "objects", 0},
    {"OBND", sizeof(sl_aabb), ARR(bounds), K_WRITABLE, N_REQUIRED, ID_MAX, "object bounds", 0},
    {"XFRM", sizeof(sl_affine), ARR(transforms), K_WRITABLE, N_REQUIRED, ID_MAX, "transforms", 0},
    {"FOOT", sizeof(sl_footprint_rec), ARR(footprints), K_ARRAY, N_OPTIONAL, ID_MAX, "footprints", 0},
    {"FPXY", sizeof(float), ARR(footprint_xy), K_ARRAY, N_OPTIONAL, XY_MAX, "footprint vertices", 0},
    {"OCCL", sizeof(sl_occluder_rec), ARR(occluders), K_ARRAY, N_OPTIONAL, ID_MAX, "occluders", 0},
    {"TERH", SLS_TERRAIN_REC, 0, K_TERRAIN, N_TERRAIN, 1, "terrain header", 0},
    {"TERZ", sizeof(float), ARR(terrain_heights), K_ARRAY, N_TERRAIN, SLS_TERRAIN_MAX_SAMPLES, "terrain heights", 0},
    {"SPOL", sizeof(sl_polygon_rec), ARR(street_polys), K_ARRAY, N_OPTIONAL, ID_MAX, "street polygons", 0},
    {"SPXY", sizeof(float), ARR(street_xy), K_ARRAY, N_OPTIONAL, XY_MAX, "street polygon vertices", 0},
    {"SNOD", sizeof(sl_street_node), ARR(street_nodes), K_ARRAY, N_OPTIONAL, ID_MAX, "street nodes", 0},
    {"SEDG", sizeof(sl_street_edge), ARR(street_edges), K_ARRAY, N_OPTIONAL, ID_MAX, "street edges", 0},
    {"BSPH", SLS_BSP_REC, 0, K_BSP, N_BSP_HEAD, 1, "bsp header", 0},
    {"BPLN", sizeof(sl_plane), ARR(bsp_planes), K_ARRAY, N_BSP, ID_MAX, "bsp planes", 0},
    /* child indices are int32: nodes >= 0, leaves -(c+1) */
    {"BNOD", sizeof(sl_bsp_node), ARR(bsp_nodes), K_ARRAY, N_BSP, INT32_MAX, "bsp nodes", 0},
    {"BLEF", sizeof(sl_bsp_leaf), ARR(bsp_leaves), K_ARRAY, N_BSP, (uint64_t)INT32_MAX + 1, "bsp leaves", 0},
    {"BLOB", sizeof(uint32_t), ARR(bsp_leaf_objects), K_ARRAY, N_BSP, ID_MAX, "bsp leaf objects", 0},
    {"BPVS", 1, ARR(bsp_pvs), K_ARRAY, N_BSP, (uint64_t)UINT32_MAX * UINT32_MAX, "bsp cluster pvs", 0},
    {"META", 1, 0, K_META, N_OPTIONAL, NOLIMIT, "metadata", 0},
    /* 1.1 */
    {"MATL", sizeof(sl_material_rec), ARR(materials), K_ARRAY, N_OPTIONAL, ID_MAX - 1, "materials", 1},
    {"MTEX", 1, ARR(material_text), K_ARRAY, N_OPTIONAL, UINT32_MAX, "material texture paths", 1},
    {"OMAT", sizeof(uint32_t), ARR(object_materials), K_ARRAY, N_OPTIONAL, ID_MAX, "object materials", 1},
    {"VUV0", sizeof(float), ARR(uvs), K_ARRAY, N_OPTIONAL, NOLIMIT, "vertex uvs", 1},
    {"MUVS", 1, ARR(mesh_uvs), K_ARRAY, N_OPTIONAL, ID_MAX, "mesh uv flags", 1},
    {"ONAM", sizeof(uint32_t), ARR(object_name_len), K_ARRAY, N_OPTIONAL, ID_MAX, "object name lengths", 1},
    {"NAMT", 1, ARR(object_name_text), K_ARRAY, N_OPTIONAL, UINT32_MAX, "object names", 1},
    /* 1.2, written only when the scene has occluder levels */
    {"OLVL", sizeof(sl_olevel_rec), ARR(olevels), K_ARRAY, N_LEVELS, 4096, "occluder levels", 2},
    {"OLFP", sizeof(sl_footprint_rec), ARR(olevel_fps), K_ARRAY, N_LEVELS, ID_MAX, "occluder level footprints", 2},
    {"OLXY", sizeof(float), ARR(olevel_xy), K_ARRAY, N_LEVELS, XY_MAX, "occluder level footprint vertices", 2},
    /* 1.3, written only when the scene has motion records */
    {"MOTN", sizeof(sl_motion_rec), ARR(motions), K_ARRAY, N_OPTIONAL, ID_MAX, "motion records", 3},
};
#define SLS_NDEFS SL_COUNTOF(k_defs)


static sl_array *scene_array(struct sl_scene_t *s, const sec_def *d) { return (sl_array *)((char *)s + d->array); }
static const sl_array *scene_array_c(const struct sl_scene_t *s, const sec_def *d)
{
    return (const sl_array *)((const char *)s + d->array);
}

/* ============================================================================================
 * Writer
 * ============================================================================================ */

typedef struct out_sec {
    const sec_def *def;
    const void *data;
    uint64_t count, size;
    void *owned; /* staging copy (zeroed padding, serialized records), freed after writing */
    size_t owned_size;
} out_sec;

/* Copy records whose `reserved` word sits at byte `reserved_at` with that word zeroed, so that
 * whatever a loaded file carried there never reaches the output. */
static void *stage_zeroed(const sl_allocator *a, const sl_array *arr, size_t elem, size_t reserved_at, size_t *bytes)
{
    *bytes = arr->count * elem;
    if (!arr->count)
        return NULL;
    uint8_t *p = sl_alloc(a, *bytes);
    if (!p)
        return NULL;
    memcpy(p, arr->data, *bytes);
    for (size_t i = 0; i < arr->count; i++)
        memset(p + i * elem + reserved_at, 0, sizeof(uint32_t));
    return p;
}

/* Metadata: u32 entry count, then per entry u32 key length, key bytes, u32 value length, value
 * bytes (no terminators, no padding). */
static void *serialize_meta(const struct sl_scene_t *s, size_t *bytes)
{
    size_t n = 4;
    for (size_t i = 0; i < s->meta.count; i++) {
        const sl_meta_rec *m = &SL_AT(s->meta, sl_meta_rec, i);
        n += 8 + strlen(m->key) + strlen(m->value);
    }
    uint8_t *p = sl_alloc(&s->alloc, n);
    if (!p)
        return NULL;
    size_t k = 0;
    wr32(p, (uint32_t)s->meta.count);
    k += 4;
    for (size_t i = 0; i < s->meta.count; i++) {
        const sl_meta_rec *m = &SL_AT(s->meta, sl_meta_rec, i);
        uint32_t kl = (uint32_t)strlen(m->key), vl = (uint32_t)strlen(m->value);
        wr32(p + k, kl);
        memcpy(p + k + 4, m->key, kl);
        k += 4 + kl;
        wr32(p + k, vl);
        memcpy(p + k + 4, m->value, vl);
        k += 4 + vl;
    }
    *bytes = n;
    return p;
}

static void free_out(const sl_allocator *a, out_sec *secs, size_t n)
{
    for (size_t i = 0; i < n; i++)
        sl_free(a, secs[i].owned, secs[i].owned_size);
}

/* Write the scene to `path` through the atomic writer, or, when fd >= 0, to that open file
 * descriptor (not closed; `path` is then only its name in messages). */
static sl_status save_to(sl_scene s, const char *path, int fd, sl_error *err)
{
    const sl_allocator *a = &s->alloc;
    if (s->meta.count > UINT32_MAX)
        return sl_fail(err, SL_ERROR_LIMIT, "%s: too many metadata entries", path);
    for (size_t i = 0; i < s->meta.count; i++) {
        const sl_meta_rec *m = &SL_AT(s->meta, sl_meta_rec, i);
        if (strlen(m->key) > UINT32_MAX || strlen(m->value) > UINT32_MAX)
            return sl_fail(err, SL_ERROR_LIMIT, "%s: metadata entry %zu is longer than 4 GiB", path, i);
    }
    out_sec secs[SLS_NDEFS];
    size_t n = 0;
    memset(secs, 0, sizeof secs);
    uint32_t flags = (s->has_terrain ? SLS_FLAG_TERRAIN : 0) | (s->has_bsp ? SLS_FLAG_BSP : 0);
    sl_status st = SL_OK;
    for (size_t i = 0; i < SLS_NDEFS && st == SL_OK; i++) {
        const sec_def *d = &k_defs[i];
        if ((d->need == N_TERRAIN && !s->has_terrain) || ((d->need == N_BSP || d->need == N_BSP_HEAD) && !s->has_bsp) ||
            (d->need == N_LEVELS && !s->olevels.count) || (d->array == ARR(motions) && !s->motions.count))
            continue;
        out_sec *o = &secs[n++];
        o->def = d;
        if (d->kind == K_ARRAY || d->kind == K_WRITABLE) {
            const sl_array *arr = scene_array_c(s, d);
            o->count = arr->count;
            o->size = (uint64_t)arr->count * d->elem;
            o->data = arr->data;
            size_t reserved_at = SIZE_MAX;
            if (d->array == ARR(objects))
                reserved_at = offsetof(sl_object_rec, reserved);
            else if (d->array == ARR(footprints))
                reserved_at = offsetof(sl_footprint_rec, reserved);
            else if (d->array == ARR(occluders))
                reserved_at = offsetof(sl_occluder_rec, reserved);
            if (reserved_at != SIZE_MAX && arr->count) {
                o->owned = stage_zeroed(a, arr, d->elem, reserved_at, &o->owned_size);
                o->data = o->owned;
                if (!o->owned)
                    st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory staging %s", path, d->what);
            }
        } else if (d->kind == K_TERRAIN || d->kind == K_BSP) {
            o->owned_size = d->elem;
            uint8_t *p = sl_calloc(a, 1, d->elem);
            o->owned = p;
            o->data = p;
            o->count = 1;
            o->size = d->elem;
            if (!p) {
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
            } else if (d->kind == K_TERRAIN) {
                wr32(p + 0, s->terrain_nx);
                wr32(p + 4, s->terrain_ny);
                memcpy(p + 8, &s->terrain_origin_x, 4);
                memcpy(p + 12, &s->terrain_origin_y, 4);
                memcpy(p + 16, &s->terrain_cell, 4);
            } else {
                wr32(p + 0, s->bsp_cluster_count);
                wr32(p + 4, s->bsp_cluster_bytes);
            }
        } else {
            o->owned = serialize_meta(s, &o->owned_size);
            o->data = o->owned;
            o->count = o->size = o->owned_size;
            if (!o->owned)
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory serializing metadata", path);
        }
    }
    if (st != SL_OK) {
        free_out(a, secs, n);
        return st;
    }

    /* header, table, then the sections in table order, each on a 64-byte boundary (container.h) */
    sl_container_section cs[SLS_NDEFS];
    for (size_t i = 0; i < n; i++) {
        memcpy(cs[i].tag, secs[i].def->tag, 4);
        cs[i].elem = secs[i].def->elem;
        cs[i].count = secs[i].count;
        cs[i].data = secs[i].data;
        cs[i].size = secs[i].size;
    }
    uint32_t minor = s->motions.count ? SLS_MINOR : s->olevels.count ? SLS_MINOR_NO_MOTION : SLS_MINOR_NO_LEVELS;
    st = sl_container_write(a, path, fd, k_magic, SLS_MAJOR, minor, flags, SLS_HASH_SEED, cs, n, err);
    free_out(a, secs, n);
    return st;
}

sl_status sl_scene_save(sl_scene s, const char *path, sl_error *err)
{
    if (!s || !path)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_save: NULL argument");
    return save_to(s, path, -1, err);
}

sl_status sl_scene_save_fd(sl_scene s, int fd, const char *name, sl_error *err)
{
    if (!s || fd < 0 || !name)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_save_fd: bad argument");
    return save_to(s, name, fd, err);
}

/* ============================================================================================
 * Reader
 * ============================================================================================ */

typedef struct sls_entry {
    char tag[5];        /* printable copy for messages */
    uint8_t raw_tag[4];
    uint32_t elem;
    uint64_t count, offset, size, hash;
    const sec_def *def; /* NULL: unknown section of a newer minor version, skipped */
} sls_entry;

typedef struct reader {
    const char *name;
    const uint8_t *base;  /* the whole file in memory (mapping or caller's bytes); NULL with pread */
    int fd;               /* pread source when base is NULL */
    uint64_t size;        /* actual file size */
    bool borrow;          /* arrays may point into base (a mapping the scene will own) */
    bool verify;          /* check section checksums */
    const sl_allocator *a;
    const sl_progress *progress;
    sl_error *err;
    uint32_t minor, flags;
    uint64_t done, total; /* bytes of sections processed, for progress */
} reader;

static sl_status bad_at(reader *r, uint64_t offset, const char *fmt, ...) SL_PRINTF(3, 4);
static sl_status bad_at(reader *r, uint64_t offset, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    sl_status st = sl_container_vfail_at(r->err, r->name, offset, fmt, ap);
    va_end(ap);
    return st;
}

static sl_status bad_sec(reader *r, const sls_entry *e, const char *fmt, ...) SL_PRINTF(3, 4);
static sl_status bad_sec(reader *r, const sls_entry *e, const char *fmt, ...)
{
    char why[384];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(why, sizeof why, fmt, ap);
    va_end(ap);
    return sl_fail(r->err, SL_ERROR_FORMAT, "%s: section '%s': %s", r->name, e->tag, why);
}

/* Read `size` bytes at `offset` (bounds already checked against the file size). */
static sl_status read_at(reader *r, uint64_t offset, void *dst, uint64_t size)
{
    if (r->base) {
        memcpy(dst, r->base + offset, (size_t)size);
        return SL_OK;
    }
    uint8_t *p = dst;
    while (size) {
        size_t chunk = size > (1u << 30) ? (1u << 30) : (size_t)size;
        ssize_t got = pread(r->fd, p, chunk, (off_t)offset);
        if (got < 0 && errno == EINTR)
            continue;
        if (got < 0)
            return sl_fail(r->err, SL_ERROR_IO, "%s: offset %llu: read failed: %s", r->name,
                           (unsigned long long)offset, strerror(errno));
        if (got == 0) /* the file shrank under us */
            return bad_at(r, offset, "unexpected end of file");
        p += got, offset += (uint64_t)got, size -= (uint64_t)got;
    }
    return SL_OK;
}

static sl_status check_hash(reader *r, const sls_entry *e, const void *data)
{
    if (r->verify) {
        uint64_t h = sl_hash64(data, (size_t)e->size, SLS_HASH_SEED);
        if (h != e->hash)
            return sl_fail(r->err, SL_ERROR_FORMAT,
                           "%s: section '%s' at offset %llu: checksum mismatch (stored %016llx, computed %016llx)",
                           r->name, e->tag, (unsigned long long)e->offset, (unsigned long long)e->hash,
                           (unsigned long long)h);
    }
    r->done += e->size;
    if (!sl_progress_report(r->progress, r->base ? "verifying scene" : "reading scene", r->done, r->total))
        return sl_fail(r->err, SL_ERROR_CANCELLED, "%s: cancelled", r->name);
    return SL_OK;
}

/* Bytes of a small section: a pointer into base, or a temporary copy in *tmp (caller frees). */
static sl_status small_section(reader *r, const sls_entry *e, const uint8_t **out, uint8_t **tmp)
{
    *tmp = NULL;
    if (r->base) {
        *out = r->base + e->offset;
    } else {
        *tmp = sl_alloc(r->a, e->size ? (size_t)e->size : 1);
        if (!*tmp)
            return sl_fail(r->err, SL_ERROR_OUT_OF_MEMORY, "%s: section '%s': out of memory", r->name, e->tag);
        sl_status st = read_at(r, e->offset, *tmp, e->size);
        if (st != SL_OK)
            return st;
        *out = *tmp;
    }
    return check_hash(r, e, *out);
}

/* Attach one array section to the scene: borrowed from the mapping, or an owned copy. The array
 * is attached before its checksum is checked so that a failure frees it with the scene. */
static sl_status load_array(reader *r, struct sl_scene_t *s, const sls_entry *e)
{
    sl_array *arr = scene_array(s, e->def);
    if (e->count == 0)
        return check_hash(r, e, NULL);
    if (r->base && r->borrow && e->def->kind == K_ARRAY) {
        arr->data = (void *)(r->base + e->offset);
        arr->count = (size_t)e->count;
        arr->cap = 0; /* borrowed: growing it copies first */
        return check_hash(r, e, arr->data);
    }
    void *p = sl_alloc(r->a, (size_t)e->size);
    if (!p)
        return sl_fail(r->err, SL_ERROR_OUT_OF_MEMORY, "%s: section '%s': cannot allocate %llu bytes", r->name, e->tag,
                       (unsigned long long)e->size);
    arr->data = p;
    arr->count = arr->cap = (size_t)e->count;
    sl_status st = read_at(r, e->offset, p, e->size);
    return st != SL_OK ? st : check_hash(r, e, p);
}

static sl_status load_terrain(reader *r, struct sl_scene_t *s, const sls_entry *e)
{
    const uint8_t *p;
    uint8_t *tmp;
    sl_status st = small_section(r, e, &p, &tmp);
    if (st == SL_OK) {
        s->has_terrain = true;
        s->terrain_nx = rd32(p);
        s->terrain_ny = rd32(p + 4);
        memcpy(&s->terrain_origin_x, p + 8, 4);
        memcpy(&s->terrain_origin_y, p + 12, 4);
        memcpy(&s->terrain_cell, p + 16, 4);
        /* dimensions and finiteness are checked by sl_scene_validate against the heights */
    }
    sl_free(r->a, tmp, (size_t)e->size ? (size_t)e->size : 1);
    return st;
}

static sl_status load_bsp_header(reader *r, struct sl_scene_t *s, const sls_entry *e)
{
    const uint8_t *p;
    uint8_t *tmp;
    sl_status st = small_section(r, e, &p, &tmp);
    if (st == SL_OK) {
        s->has_bsp = true;
        s->bsp_cluster_count = rd32(p);
        s->bsp_cluster_bytes = rd32(p + 4);
    }
    sl_free(r->a, tmp, (size_t)e->size ? (size_t)e->size : 1);
    return st;
}

static int cmp_key(const void *x, const void *y) { return strcmp(*(const char *const *)x, *(const char *const *)y); }

static sl_status parse_meta(reader *r, struct sl_scene_t *s, const sls_entry *e, const uint8_t *p)
{
    uint64_t size = e->size, k = 4;
    if (size < 4)
        return bad_sec(r, e, "%llu bytes, too short for the entry count", (unsigned long long)size);
    uint32_t count = rd32(p);
    if ((uint64_t)count * 8 > size - 4)
        return bad_sec(r, e, "%u entries cannot fit in %llu bytes", count, (unsigned long long)size);
    if (count && !sl_array_reserve(r->a, &s->meta, sizeof(sl_meta_rec), count))
        return sl_fail(r->err, SL_ERROR_OUT_OF_MEMORY, "%s: metadata: out of memory", r->name);
    for (uint32_t i = 0; i < count; i++) {
        const uint8_t *str[2];
        uint32_t len[2];
        for (int j = 0; j < 2; j++) {
            if (size - k < 4)
                return bad_sec(r, e, "entry %u: length field at byte %llu runs past the end", i, (unsigned long long)k);
            len[j] = rd32(p + k);
            k += 4;
            if (len[j] > size - k)
                return bad_sec(r, e, "entry %u: %s of %u bytes at byte %llu runs past the end", i, j ? "value" : "key",
                               len[j], (unsigned long long)k);
            str[j] = p + k;
            if (memchr(str[j], 0, len[j]))
                return bad_sec(r, e, "entry %u: %s contains a NUL byte", i, j ? "value" : "key");
            k += len[j];
        }
        if (len[0] == 0)
            return bad_sec(r, e, "entry %u: empty key", i);
        sl_meta_rec rec = {sl_alloc(r->a, (size_t)len[0] + 1), sl_alloc(r->a, (size_t)len[1] + 1)};
        if (!rec.key || !rec.value) {
            sl_free(r->a, rec.key, (size_t)len[0] + 1);
            sl_free(r->a, rec.value, (size_t)len[1] + 1);
            return sl_fail(r->err, SL_ERROR_OUT_OF_MEMORY, "%s: metadata: out of memory", r->name);
        }
        memcpy(rec.key, str[0], len[0]);
        rec.key[len[0]] = 0;
        memcpy(rec.value, str[1], len[1]);
        rec.value[len[1]] = 0;
        sl_array_push(r->a, &s->meta, sizeof rec, &rec, 1); /* room reserved above */
    }
    if (k != size)
        return bad_sec(r, e, "%llu trailing bytes after the last entry", (unsigned long long)(size - k));
    if (count > 1) {
        /* keys are unique (sl_scene_set_meta replaces): sort a copy to find duplicates in n log n */
        const char **keys = sl_alloc(r->a, (size_t)count * sizeof *keys);
        if (!keys)
            return sl_fail(r->err, SL_ERROR_OUT_OF_MEMORY, "%s: metadata: out of memory", r->name);
        for (uint32_t i = 0; i < count; i++)
            keys[i] = SL_AT(s->meta, sl_meta_rec, i).key;
        qsort(keys, count, sizeof *keys, cmp_key);
        sl_status st = SL_OK;
        for (uint32_t i = 1; i < count && st == SL_OK; i++)
            if (strcmp(keys[i - 1], keys[i]) == 0)
                st = bad_sec(r, e, "duplicate key \"%.64s\"", keys[i]);
        sl_free(r->a, keys, (size_t)count * sizeof *keys);
        return st;
    }
    return SL_OK;
}

static sl_status load_meta(reader *r, struct sl_scene_t *s, const sls_entry *e)
{
    const uint8_t *p;
    uint8_t *tmp;
    sl_status st = small_section(r, e, &p, &tmp);
    if (st == SL_OK)
        st = parse_meta(r, s, e, p);
    sl_free(r->a, tmp, (size_t)e->size ? (size_t)e->size : 1);
    return st;
}

/* Signed area of a stored polygon (positive when CCW), summed in the same order as the scene's
 * own check when the polygon was added, so that what sl_scene_add_* accepted always reloads. */
static double ring_area(const float *xy, uint32_t n)
{
    double area = 0;
    for (uint32_t i = 0; i < n; i++) {
        uint32_t j = i + 1 == n ? 0 : i + 1;
        area += (double)xy[2 * i] * xy[2 * j + 1] - (double)xy[2 * j] * xy[2 * i + 1];
    }
    return 0.5 * area;
}

/* Checks sl_scene_validate leaves to the loader: stored mesh bounds, polygon orientation, street
 * widths, terrain size, BSP vis size. Runs after sl_scene_validate, so every range is in bounds. */
static sl_status check_semantics(reader *r, struct sl_scene_t *s)
{
    const sl_mesh_rec *m = sl_scene_meshes(s);
    const float *pos = sl_scene_positions(s);
    for (size_t i = 0; i < s->meshes.count; i++) {
        const sl_aabb *b = &m[i].bounds;
        const float *bmin = &b->min.x, *bmax = &b->max.x;
        if (m[i].vertex_count == 0) {
            /* an empty mesh keeps the empty box; anything but NaN is harmless */
            for (int k = 0; k < 3; k++)
                if (isnan(bmin[k]) || isnan(bmax[k]))
                    return sl_fail(r->err, SL_ERROR_FORMAT, "%s: mesh %zu: bounds are NaN", r->name, i);
            continue;
        }
        if (!sl_finite3(bmin) || !sl_finite3(bmax))
            return sl_fail(r->err, SL_ERROR_FORMAT, "%s: mesh %zu: bounds are not finite", r->name, i);
        /* min/max are exact, so the stored box (computed the same way) contains the vertices */
        const float *v = pos + 3 * m[i].first_vertex;
        float lo0 = bmin[0], lo1 = bmin[1], lo2 = bmin[2], hi0 = bmax[0], hi1 = bmax[1], hi2 = bmax[2];
        float mn0 = v[0], mn1 = v[1], mn2 = v[2], mx0 = v[0], mx1 = v[1], mx2 = v[2];
        for (uint32_t k = 1; k < m[i].vertex_count; k++) {
            const float *q = v + 3 * (size_t)k;
            mn0 = q[0] < mn0 ? q[0] : mn0, mx0 = q[0] > mx0 ? q[0] : mx0;
            mn1 = q[1] < mn1 ? q[1] : mn1, mx1 = q[1] > mx1 ? q[1] : mx1;
            mn2 = q[2] < mn2 ? q[2] : mn2, mx2 = q[2] > mx2 ? q[2] : mx2;
        }
        if (!(lo0 <= mn0 && lo1 <= mn1 && lo2 <= mn2 && hi0 >= mx0 && hi1 >= mx1 && hi2 >= mx2))
            return sl_fail(r->err, SL_ERROR_FORMAT, "%s: mesh %zu: stored bounds do not contain its vertices", r->name,
                           i);
    }
    /* world bounds are derived data: recompute them rather than trust the stored copy */
    sl_scene_recompute_bounds(s);
    const sl_aabb *ob = (const sl_aabb *)s->bounds.data;
    const sl_object_rec *o = sl_scene_objects(s);
    for (size_t i = 0; i < s->objects.count; i++) {
        const float *lo = &ob[i].min.x, *hi = &ob[i].max.x;
        bool ok = m[o[i].mesh].vertex_count ? sl_finite3(lo) && sl_finite3(hi)
                                            : !(isnan(lo[0]) || isnan(lo[1]) || isnan(lo[2]) || isnan(hi[0]) ||
                                                isnan(hi[1]) || isnan(hi[2]));
        if (!ok) /* huge but finite mesh bounds times a transform can overflow */
            return sl_fail(r->err, SL_ERROR_FORMAT, "%s: object %zu: world bounds are not finite", r->name, i);
    }
    const float *fxy = (const float *)s->footprint_xy.data;
    for (size_t i = 0; i < s->footprints.count; i++) {
        const sl_footprint_rec *f = &SL_AT(s->footprints, sl_footprint_rec, i);
        if (!(ring_area(fxy + 2 * (size_t)f->first_vertex, f->vertex_count) > 0))
            return sl_fail(r->err, SL_ERROR_FORMAT, "%s: footprint %zu: polygon is not counter-clockwise", r->name, i);
    }
    const float *sxy = (const float *)s->street_xy.data;
    for (size_t i = 0; i < s->street_polys.count; i++) {
        const sl_polygon_rec *p = &SL_AT(s->street_polys, sl_polygon_rec, i);
        if (!(ring_area(sxy + 2 * (size_t)p->first_vertex, p->vertex_count) > 0))
            return sl_fail(r->err, SL_ERROR_FORMAT, "%s: street polygon %zu: polygon is not counter-clockwise", r->name,
                           i);
    }
    const sl_street_edge *se = (const sl_street_edge *)s->street_edges.data;
    for (size_t i = 0; i < s->street_edges.count; i++)
        if (!(se[i].width >= 0))
            return sl_fail(r->err, SL_ERROR_FORMAT, "%s: street edge %zu: negative width", r->name, i);
    if (s->has_bsp && s->bsp_pvs.count != (uint64_t)s->bsp_cluster_count * s->bsp_cluster_bytes)
        return sl_fail(r->err, SL_ERROR_FORMAT, "%s: bsp vis: %zu bytes, expected %u clusters x %u bytes", r->name,
                       s->bsp_pvs.count, s->bsp_cluster_count, s->bsp_cluster_bytes);
    return SL_OK;
}

static sl_status read_cb(void *ctx, uint64_t offset, void *buf, uint64_t n) { return read_at(ctx, offset, buf, n); }

/* Parse and check the header and the section table; fills ents (count entries). */
static sl_status read_table(reader *r, sls_entry **out_ents, uint32_t *out_count)
{
    *out_ents = NULL;
    *out_count = 0;
    uint8_t head[SLS_HEADER_SIZE] = {0};
    sl_status st = SL_OK;
    if (r->size >= SLS_HEADER_SIZE && (st = read_at(r, 0, head, SLS_HEADER_SIZE)) != SL_OK)
        return st;
    static const sl_container_format fmt = {k_magic, ".slscene", SLS_MAJOR, SLS_MINOR, SLS_HASH_SEED, SLS_MAX_SECTIONS};
    sl_container_header ch;
    if ((st = sl_container_check_header(head, r->size, &fmt, r->name, &ch, r->err)) != SL_OK)
        return st;
    r->minor = ch.minor;
    r->flags = ch.flags;
    const uint32_t count = ch.count, entry_size = ch.entry_size;
    const uint64_t table_offset = ch.table_offset, table_size = ch.table_size;
    uint8_t *table = sl_alloc(r->a, table_size ? (size_t)table_size : 1);
    sls_entry *ents = sl_calloc(r->a, count ? count : 1, sizeof *ents);
    sl_container_span *ranges = sl_calloc(r->a, (size_t)count + 2, sizeof *ranges);
    if (!table || !ents || !ranges) {
        st = sl_fail(r->err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory reading the section table", r->name);
        goto done;
    }
    st = read_at(r, table_offset, table, table_size);
    if (st != SL_OK)
        goto done;
    if ((st = sl_container_check_table(table, &ch, SLS_HASH_SEED, r->name, r->err)) != SL_OK)
        goto done;
    uint32_t nranges = 0;
    ranges[nranges++] = (sl_container_span){0, ch.header_size, "header", -1};
    ranges[nranges++] = (sl_container_span){table_offset, table_offset + table_size, "section table", -2};
    for (uint32_t i = 0; i < count; i++) {
        const uint8_t *p = table + (size_t)i * entry_size;
        uint64_t at = table_offset + (uint64_t)i * entry_size;
        sls_entry *e = &ents[i];
        memcpy(e->raw_tag, p + E_TAG, 4);
        for (int k = 0; k < 4; k++)
            e->tag[k] = (p[E_TAG + k] >= 0x20 && p[E_TAG + k] < 0x7f && p[E_TAG + k] != '\'') ? (char)p[E_TAG + k] : '?';
        e->tag[4] = 0;
        e->elem = rd32(p + E_ELEM);
        e->count = rd64(p + E_COUNT);
        e->offset = rd64(p + E_OFFSET);
        e->size = rd64(p + E_SIZE);
        e->hash = rd64(p + E_HASH);
        /* a section newer than the file's minor version is as unknown as any other tag */
        for (size_t d = 0; d < SLS_NDEFS; d++)
            if (memcmp(k_defs[d].tag, e->raw_tag, 4) == 0 && k_defs[d].since_minor <= r->minor)
                e->def = &k_defs[d];
        uint64_t bytes;
        if (e->offset % SLS_ALIGN) {
            st = bad_at(r, at + E_OFFSET, "section '%s': offset %llu is not %u-byte aligned", e->tag,
                        (unsigned long long)e->offset, SLS_ALIGN);
        } else if (e->offset > r->size || e->size > r->size - e->offset) {
            st = bad_at(r, at + E_OFFSET, "section '%s': %llu bytes at offset %llu run past the end of the file (%llu bytes)",
                        e->tag, (unsigned long long)e->size, (unsigned long long)e->offset,
                        (unsigned long long)r->size);
        } else if (__builtin_mul_overflow(e->count, (uint64_t)e->elem, &bytes) || bytes != e->size) {
            st = bad_at(r, at + E_COUNT, "section '%s': %llu elements of %u bytes do not make %llu bytes", e->tag,
                        (unsigned long long)e->count, e->elem, (unsigned long long)e->size);
        } else if (!e->def && r->minor <= SLS_MINOR) {
            st = bad_at(r, at + E_TAG, "unknown section '%s' in a version %u.%u file", e->tag, SLS_MAJOR, r->minor);
        } else if (e->def && e->elem != e->def->elem) {
            st = bad_at(r, at + E_ELEM, "section '%s' (%s): element size %u, expected %u", e->tag, e->def->what,
                        e->elem, e->def->elem);
        } else if (e->def && e->count > e->def->max_count) {
            st = bad_at(r, at + E_COUNT, "section '%s' (%s): %llu elements is more than the %llu allowed", e->tag,
                        e->def->what, (unsigned long long)e->count, (unsigned long long)e->def->max_count);
        } else if (e->def && (e->def->kind == K_TERRAIN || e->def->kind == K_BSP) && e->count != 1) {
            st = bad_at(r, at + E_COUNT, "section '%s' (%s): %llu records, expected exactly 1", e->tag, e->def->what,
                        (unsigned long long)e->count);
        }
        if (st != SL_OK)
            goto done;
        for (uint32_t j = 0; j < i && e->def; j++)
            if (ents[j].def == e->def) {
                st = bad_at(r, at + E_TAG, "section '%s' appears twice", e->tag);
                goto done;
            }
        if (e->size)
            ranges[nranges++] = (sl_container_span){e->offset, e->offset + e->size, e->tag, (int)i};
    }
    /* no two non-empty sections (nor the header and the table) share a byte; the rest is zero */
    if ((st = sl_container_check_layout(ranges, nranges, r->size, r->base, read_cb, r, r->name, r->err)) != SL_OK)
        goto done;
    /* presence rules */
    for (size_t d = 0; d < SLS_NDEFS; d++) {
        const sec_def *def = &k_defs[d];
        bool present = false;
        for (uint32_t i = 0; i < count; i++)
            present |= ents[i].def == def;
        bool terrain = r->flags & SLS_FLAG_TERRAIN, bsp = r->flags & SLS_FLAG_BSP;
        const char *why = NULL;
        if (!present && (def->need == N_REQUIRED || (def->need == N_TERRAIN && terrain) || (def->need == N_BSP_HEAD && bsp)))
            why = "required section is missing";
        else if (present && def->need == N_TERRAIN && !terrain)
            why = "present but the header has no terrain flag";
        else if (present && (def->need == N_BSP || def->need == N_BSP_HEAD) && !bsp)
            why = "present but the header has no bsp flag";
        else if (def->need == N_LEVELS) {
            bool all = true, none = true;
            for (size_t d2 = 0; d2 < SLS_NDEFS; d2++) {
                if (k_defs[d2].need != N_LEVELS)
                    continue;
                bool here = false;
                for (uint32_t i = 0; i < count; i++)
                    if (ents[i].def == &k_defs[d2]) {
                        here = true;
                        if (d2 == d && memcmp(def->tag, "OLVL", 4) == 0 && ents[i].count == 0)
                            why = "present but holds no level (a scene without levels has no level sections)";
                    }
                all &= here;
                none &= !here;
            }
            if (!all && !none)
                why = "the occluder level sections OLVL, OLFP and OLXY come together or not at all";
        }
        if (why) {
            st = sl_fail(r->err, SL_ERROR_FORMAT, "%s: section '%s' (%s): %s", r->name, def->tag, def->what, why);
            goto done;
        }
    }
done:
    sl_free(r->a, table, table_size ? (size_t)table_size : 1);
    sl_free(r->a, ranges, ((size_t)count + 2) * sizeof *ranges);
    if (st != SL_OK) {
        sl_free(r->a, ents, (count ? count : 1) * sizeof *ents);
        return st;
    }
    *out_ents = ents;
    *out_count = count;
    return SL_OK;
}

/* Shared by every entry point. On success the scene owns `map` (may be empty). */
static sl_status load(reader *r, sl_mapping *map, sl_scene *out)
{
    *out = NULL;
    sls_entry *ents;
    uint32_t count;
    sl_status st = read_table(r, &ents, &count);
    if (st != SL_OK) {
        sl_file_unmap(map);
        return st;
    }
    struct sl_scene_t *s;
    st = sl_scene_create(r->a, &s, r->err);
    if (st != SL_OK) {
        sl_file_unmap(map);
        sl_free(r->a, ents, (count ? count : 1) * sizeof *ents);
        return st;
    }
    s->mapping = *map; /* from here on, sl_scene_destroy unmaps */
    map->data = NULL, map->size = 0;
    r->total = 0;
    for (uint32_t i = 0; i < count; i++)
        r->total += ents[i].def ? ents[i].size : 0;
    /* the writer's order, so a pread load reads the file front to back */
    for (size_t d = 0; d < SLS_NDEFS && st == SL_OK; d++) {
        const sls_entry *e = NULL;
        for (uint32_t i = 0; i < count; i++)
            if (ents[i].def == &k_defs[d])
                e = &ents[i];
        if (!e)
            continue;
        switch (e->def->kind) {
        case K_ARRAY:
        case K_WRITABLE: st = load_array(r, s, e); break;
        case K_TERRAIN: st = load_terrain(r, s, e); break;
        case K_BSP: st = load_bsp_header(r, s, e); break;
        case K_META: st = load_meta(r, s, e); break;
        }
    }
    sl_free(r->a, ents, (count ? count : 1) * sizeof *ents);
    if (st == SL_OK && !sl_progress_report(r->progress, "validating scene", 0, 1))
        st = sl_fail(r->err, SL_ERROR_CANCELLED, "%s: cancelled", r->name);
    if (st == SL_OK && (st = sl_scene_names_load(s, r->err)) != SL_OK)
        sl_error_prefix(r->err, "%s", r->name);
    if (st == SL_OK && (st = sl_scene_validate(s, r->err)) != SL_OK)
        sl_error_prefix(r->err, "%s", r->name);
    if (st == SL_OK && (st = sl_scene_levels_load(s, r->err)) != SL_OK)
        sl_error_prefix(r->err, "%s", r->name);
    if (st == SL_OK && (st = sl_scene_motions_load(s, r->err)) != SL_OK)
        sl_error_prefix(r->err, "%s", r->name);
    if (st == SL_OK)
        st = check_semantics(r, s);
    if (st != SL_OK) {
        sl_scene_destroy(s);
        return st;
    }
    sl_progress_report(r->progress, "validating scene", 1, 1);
    *out = s;
    return SL_OK;
}

/* Texture paths of a loaded file are relative to the file's folder (docs/slscene-format.md). */
static sl_status set_base_dir_of(const char *path, sl_scene *out, sl_error *err)
{
    sl_status st = sl_scene_set_base_dir_of(*out, path, err);
    if (st != SL_OK) {
        sl_scene_destroy(*out);
        *out = NULL;
    }
    return st;
}

sl_status sl_scene_load(const char *path, const sl_load_options *opt, const sl_allocator *alloc, sl_scene *out,
                        sl_error *err)
{
    if (!path || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_load: NULL argument");
    *out = NULL;
    sl_load_options defaults;
    memset(&defaults, 0, sizeof defaults);
    if (!opt)
        opt = &defaults;
    reader r;
    memset(&r, 0, sizeof r);
    r.name = path;
    r.a = sl_alloc_or_default(alloc);
    r.verify = !opt->skip_checksums;
    r.progress = &opt->progress;
    r.err = err;
    r.fd = -1;
    sl_mapping map = {NULL, 0};
    if (opt->map && !opt->no_mmap) {
        sl_status st = sl_file_map(path, &map, err);
        if (st != SL_OK)
            return st;
        r.base = map.data;
        r.size = map.size;
        r.borrow = true;
        /* the loader reads every section once in file order: ask for read-ahead */
        madvise(map.data, map.size, MADV_WILLNEED);
        st = load(&r, &map, out);
        return st == SL_OK ? set_base_dir_of(path, out, err) : st;
    }
    sl_status ost = sl_file_open_read(path, &r.fd, &r.size, err); /* a FIFO is refused, not waited on */
    if (ost != SL_OK)
        return ost;
    sl_status st = load(&r, &map, out);
    close(r.fd);
    return st == SL_OK ? set_base_dir_of(path, out, err) : st;
}

sl_status sl_scene_load_memory(const void *data, size_t size, const char *name, const sl_allocator *alloc, sl_scene *out,
                               sl_error *err)
{
    if (!out || (!data && size))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_scene_load_memory: NULL argument");
    *out = NULL;
    static const uint8_t empty[1] = {0};
    reader r;
    memset(&r, 0, sizeof r);
    r.name = name ? name : "<memory>";
    r.base = data ? data : empty;
    r.size = size;
    r.borrow = false; /* the caller keeps its bytes: copy every section */
    r.verify = true;
    r.a = sl_alloc_or_default(alloc);
    r.err = err;
    r.fd = -1;
    sl_mapping none = {NULL, 0};
    return load(&r, &none, out);
}
