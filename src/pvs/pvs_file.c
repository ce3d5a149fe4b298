/* The .slpvs file: writer, reader and decoder of per-cell visible sets. Byte layout and checks:
 * docs/pvs.md ("The .slpvs format"); keep the two in step.
 *
 * Shape, after .slscene (docs/slscene-format.md): a 64-byte header, a table of 48-byte section
 * entries, sections aligned to 64 bytes with an XXH3-64 checksum each. Sections:
 *   PVSH  one 64-byte record: counts, keys, encoding
 *   CELL  the view cells, 64-byte sl_viewcell records
 *   SETS  per cell: set size, offset of its varint stream inside its block's decompressed bytes
 *   BLKS  per block of block_cells cells: offset and size of its zstd frame in DATA, decompressed
 *         size, XXH3-64 of the frame
 *   DATA  the zstd frames, back to back
 *   META  "key=value" lines (build method, options, timings)
 *   MREG  (1.2, optional) the motion-region hierarchy, 48-byte node records
 *   MVIS  (1.2, with MREG) one zstd frame: per cell a row of node marks, (nodes + 7) / 8 bytes
 * Neighbouring cells see much the same objects, so a block of consecutive cells compresses well,
 * and decoding one cell costs one block (cached).
 *
 * Load reads the file into memory (or maps it on request, SL_PVS_OPEN_MAP) and validates
 * everything except DATA, whose frames are checked (checksum,
 * exact decompressed size, varint stream of exactly the stated count, ids ascending and below the
 * object count) when a block is first decoded; sl_pvs_verify checks DATA whole. No byte is trusted
 * before it is checked: offsets and sizes are overflow-checked against the file, counts against
 * the sections that hold them. */
#include "pvs_codec.h"
#include "viewcells_internal.h"

#include "core/bytes.h"
#include "core/container.h"
#include "scene/scene_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the .slpvs reader maps little-endian records directly"
#endif

#define PVS_MAJOR 1u
#define PVS_MINOR 2u /* 1.1: PVSH holds the scene key format (2); 1.0 files have format 1. 1.2: motion
                        regions (MREG, MVIS); a file without them is still written as 1.1 */
#define PVS_MINOR_REGIONS 2u
#define PVS_HEADER 64u
#define PVS_ENTRY 48u
#define PVS_ALIGN 64u
#define PVS_MAX_SECTIONS 64u
#define PVS_BLOCK_CELLS 32u
#define PVS_MAX_BLOCK_CELLS 4096u
#define PVS_MAX_RAW (1u << 28) /* 256 MiB decoded per block: bounds what a small hostile file can make us allocate */
#define PVS_ENCODING_VARINT_ZSTD 1u
#define PVS_ZSTD_LEVEL 12
#define PVS_HEAD_REC 64u
#define PVS_SET_REC 8u
#define PVS_BLOCK_REC 32u
#define PVS_REGION_REC 48u

_Static_assert(sizeof(sl_viewcell) == 64, "sl_viewcell is the 64-byte CELL record");
_Static_assert(offsetof(sl_viewcell, tri) == 8 && offsetof(sl_viewcell, z_min) == 32 &&
                   offsetof(sl_viewcell, bounds) == 40,
               "sl_viewcell field offsets are those of the CELL record");

static const uint8_t k_magic[8] = {'S', 'L', 'P', 'V', 'S', 0, 0, 0};

enum { H_MAGIC = 0, H_MAJOR = 8, H_MINOR = 12, H_FLAGS = 16, H_HEADER_SIZE = 20, H_SECTIONS = 24, H_ENTRY = 28,
       H_TABLE = 32, H_FILE_SIZE = 40, H_TABLE_HASH = 48, H_HEADER_HASH = 56 };
enum { E_TAG = 0, E_ELEM = 4, E_COUNT = 8, E_OFFSET = 16, E_SIZE = 24, E_HASH = 32, E_RESERVED = 40 };
/* PVSH record */
enum { P_CELLS = 0, P_OBJECTS = 4, P_BLOCK_CELLS = 8, P_BLOCKS = 12, P_SCENE_KEY = 16, P_CELLS_KEY = 24,
       P_VISIBLE = 32, P_ENCODING = 40, P_MAX_RAW = 44, P_KEY_VERSION = 48, P_RESERVED = 52 };
enum { P_RESERVED_1_0 = 48 }; /* where the reserved bytes began in format 1.0 */
/* BLKS record */
enum { B_OFFSET = 0, B_CSIZE = 8, B_RSIZE = 12, B_HASH = 16, B_RESERVED = 24 };
/* MREG record */
enum { R_BOX = 0, R_FIRST = 24, R_CHILDREN = 28, R_PARENT = 32, R_RESERVED = 36 };

enum { S_PVSH, S_CELL, S_SETS, S_BLKS, S_DATA, S_META, S_MREG, S_MVIS, S_COUNT };
enum { S_COUNT_1_1 = S_MREG }; /* the sections of a file without regions */
static const struct {
    char tag[5];
    uint32_t elem;
    bool required;
} k_secs[S_COUNT] = {
    {"PVSH", PVS_HEAD_REC, true}, {"CELL", 64, true},  {"SETS", PVS_SET_REC, true},
    {"BLKS", PVS_BLOCK_REC, true}, {"DATA", 1, true}, {"META", 1, false},
    {"MREG", PVS_REGION_REC, false}, {"MVIS", 1, false},
};

/* ---- motion regions: the rules a hierarchy and its rows obey (writer and reader alike) ---- */

static size_t region_row_bytes(uint32_t count) { return ((size_t)count + 7) / 8; }

static bool box_inside(const sl_aabb *in, const sl_aabb *out)
{
    return in->min.x >= out->min.x && in->min.y >= out->min.y && in->min.z >= out->min.z && in->max.x <= out->max.x &&
           in->max.y <= out->max.y && in->max.z <= out->max.z;
}

/* The hierarchy's rules; false with the node and the reason when one is broken. */
static bool regions_check(const sl_pvs_region *n, uint32_t count, uint32_t *bad, char *why, size_t wn)
{
    for (uint32_t i = 0; i < count; i++) {
        const sl_aabb *b = &n[i].box;
        *bad = i;
        const float *f = &b->min.x;
        for (int k = 0; k < 6; k++)
            if (!isfinite(f[k])) {
                snprintf(why, wn, "its box is not finite");
                return false;
            }
        if (b->min.x > b->max.x || b->min.y > b->max.y || b->min.z > b->max.z) {
            snprintf(why, wn, "its box is empty (min above max)");
            return false;
        }
        uint32_t p = n[i].parent;
        if (i == 0 ? p != SL_NONE : p >= i) {
            snprintf(why, wn, i == 0 ? "the root has a parent (%u)" : "its parent %u does not come before it", p);
            return false;
        }
        if (i > 0 && (i < n[p].first_child || i - n[p].first_child >= n[p].child_count)) {
            snprintf(why, wn, "its parent %u does not list it among its children", p);
            return false;
        }
        uint32_t f0 = n[i].first_child, c = n[i].child_count;
        if (c == 0 ? f0 != 0 : (f0 <= i || f0 > count || c > count - f0)) {
            snprintf(why, wn, "children [%u, +%u) are not after it inside the %u nodes", f0, c, count);
            return false;
        }
        for (uint32_t j = f0; j < f0 + c; j++) {
            if (n[j].parent != i) {
                snprintf(why, wn, "its child %u names another parent (%u)", j, n[j].parent);
                return false;
            }
            if (!box_inside(&n[j].box, b)) {
                snprintf(why, wn, "the box of its child %u is not inside its own", j);
                return false;
            }
        }
    }
    return true;
}

/* A row's rules: a marked node's parent is marked, bits past count are zero. */
static bool region_row_check(const sl_pvs_region *n, uint32_t count, const uint8_t *row, uint32_t *bad, char *why,
                             size_t wn)
{
    for (uint32_t i = 1; i < count; i++)
        if ((row[i >> 3] >> (i & 7) & 1) && !(row[n[i].parent >> 3] >> (n[i].parent & 7) & 1)) {
            *bad = i;
            snprintf(why, wn, "node %u is marked but its parent %u is not", i, n[i].parent);
            return false;
        }
    size_t rb = region_row_bytes(count);
    if (count % 8 && (row[rb - 1] >> (count % 8)) != 0) {
        *bad = count;
        snprintf(why, wn, "bits past the %u nodes are set", count);
        return false;
    }
    return true;
}


/* ---- zstd through the handle's allocator ---- */

static void *zstd_alloc(void *user, size_t size)
{
    size_t total;
    if (!sl_add_size(size, 16, &total))
        return NULL;
    uint8_t *p = sl_alloc(user, total);
    if (!p)
        return NULL;
    memcpy(p, &total, sizeof total);
    return p + 16;
}

static void zstd_free(void *user, void *ptr)
{
    if (!ptr)
        return;
    uint8_t *p = (uint8_t *)ptr - 16;
    size_t total;
    memcpy(&total, p, sizeof total);
    sl_free(user, p, total);
}

ZSTD_customMem sl_zstd_mem(const sl_allocator *a)
{
    ZSTD_customMem m = {zstd_alloc, zstd_free, (void *)a};
    return m;
}

/* ---- the scene key ----
 *
 * Format 2 (SL_PVS_SCENE_KEY_VERSION) hashes everything a baking method or the region oracle
 * reads: the meshes (records, positions, indices), every object's mesh, kind and flags, and for
 * static objects their transform and world box; footprints, occluders (with their transforms),
 * the terrain, the streets and the whole BSP (planes, nodes, leaves, leaf objects, cluster PVS).
 * Left out: normals, colours, metadata, and where dynamic objects are (they move; the PVS does
 * not depend on it). Each array is hashed whole with its length (XXH3-64 chained by seed), so the
 * key costs one pass over the scene's bytes. Format 1 hashed boxes, kinds and counts only. */

static uint64_t hash_bytes(const void *data, size_t size, uint64_t h)
{
    uint64_t n = size;
    h = sl_hash64(&n, sizeof n, h);
    return size ? sl_hash64(data, size, h) : h;
}

static uint64_t hash_array(const sl_array *arr, size_t elem, uint64_t h)
{
    return hash_bytes(arr->data, arr->count * elem, h);
}

static uint64_t hash_transform(const struct sl_scene_t *s, uint32_t t, uint64_t h)
{
    sl_affine m = sl_affine_identity();
    if (t != SL_NONE && t < s->transforms.count)
        m = sl_scene_transforms(s)[t];
    return sl_hash64(m.m, sizeof m.m, h);
}

uint64_t sl_pvs_scene_key(sl_scene scene)
{
    if (!scene)
        return 0;
    const struct sl_scene_t *s = scene;
    uint32_t version = SL_PVS_SCENE_KEY_VERSION;
    uint64_t h = sl_hash64(&version, sizeof version, 0x534c505653ull);
    /* geometry */
    h = hash_array(&s->meshes, sizeof(sl_mesh_rec), h);
    h = hash_array(&s->positions, sizeof(float), h);
    h = hash_array(&s->indices, sizeof(uint32_t), h);
    /* objects */
    uint32_t n = sl_scene_object_count(scene);
    h = sl_hash64(&n, sizeof n, h);
    const sl_object_rec *objs = sl_scene_objects(s);
    const sl_aabb *bounds = sl_scene_object_bounds_array(scene);
    for (uint32_t i = 0; i < n; i++) {
        uint32_t rec[4] = {objs[i].mesh, objs[i].kind, objs[i].flags, 0};
        bool dynamic = (objs[i].flags & SL_OBJECT_DYNAMIC) != 0;
        rec[3] = dynamic ? 0 : 1;
        h = sl_hash64(rec, sizeof rec, h);
        if (!dynamic) {
            h = hash_transform(s, objs[i].transform, h);
            h = sl_hash64(&bounds[i], sizeof bounds[i], h);
        }
    }
    /* footprints */
    uint32_t nf = (uint32_t)s->footprints.count;
    h = sl_hash64(&nf, sizeof nf, h);
    for (uint32_t i = 0; i < nf; i++) {
        const sl_footprint_rec *f = &SL_AT(s->footprints, sl_footprint_rec, i);
        uint32_t u[3] = {f->first_vertex, f->vertex_count, f->object};
        float z[2] = {f->base_z, f->roof_z};
        h = sl_hash64(u, sizeof u, h);
        h = sl_hash64(z, sizeof z, h);
    }
    h = hash_array(&s->footprint_xy, sizeof(float), h);
    /* occluders */
    uint32_t no = (uint32_t)s->occluders.count;
    h = sl_hash64(&no, sizeof no, h);
    for (uint32_t i = 0; i < no; i++) {
        const sl_occluder_rec *o = &SL_AT(s->occluders, sl_occluder_rec, i);
        uint32_t u[2] = {o->mesh, o->object};
        h = sl_hash64(u, sizeof u, h);
        h = hash_transform(s, o->transform, h);
    }
    /* terrain */
    {
        uint32_t t[3] = {s->has_terrain ? 1u : 0u, s->has_terrain ? s->terrain_nx : 0, s->has_terrain ? s->terrain_ny : 0};
        h = sl_hash64(t, sizeof t, h);
        if (s->has_terrain) {
            float g[3] = {s->terrain_origin_x, s->terrain_origin_y, s->terrain_cell};
            h = sl_hash64(g, sizeof g, h);
            h = hash_array(&s->terrain_heights, sizeof(float), h);
        }
    }
    /* streets */
    h = hash_array(&s->street_polys, sizeof(sl_polygon_rec), h);
    h = hash_array(&s->street_xy, sizeof(float), h);
    h = hash_array(&s->street_nodes, sizeof(sl_street_node), h);
    h = hash_array(&s->street_edges, sizeof(sl_street_edge), h);
    /* BSP */
    {
        uint32_t b[3] = {s->has_bsp ? 1u : 0u, s->has_bsp ? s->bsp_cluster_count : 0, s->has_bsp ? s->bsp_cluster_bytes : 0};
        h = sl_hash64(b, sizeof b, h);
        if (s->has_bsp) {
            h = hash_array(&s->bsp_planes, sizeof(sl_plane), h);
            h = hash_array(&s->bsp_nodes, sizeof(sl_bsp_node), h);
            h = hash_array(&s->bsp_leaves, sizeof(sl_bsp_leaf), h);
            h = hash_array(&s->bsp_leaf_objects, sizeof(uint32_t), h);
            h = hash_array(&s->bsp_pvs, 1, h);
        }
    }
    return h;
}

/* ============================================================================================
 * Writer
 * ============================================================================================ */

typedef struct wsec {
    const void *data;
    uint64_t count, size;
} wsec;

sl_status sl_pvs_write(const char *path, sl_viewcells cells, uint32_t object_count, uint64_t scene_key,
                       const uint64_t *offsets, const uint32_t *ids, const char *meta, sl_error *err)
{
    return sl_pvs_write_regions(path, cells, object_count, scene_key, offsets, ids, meta, NULL, err);
}

/* The MREG records and the MVIS frame of the regions (checked first). */
static sl_status encode_regions(const sl_allocator *a, const sl_pvs_regions *r, uint32_t nc, ZSTD_CCtx *cctx,
                                uint8_t **recs, uint8_t **frame, size_t *frame_size, size_t *frame_cap, sl_error *err)
{
    if (r->count > SL_PVS_MAX_REGIONS)
        return sl_fail(err, SL_ERROR_LIMIT, "sl_pvs_write_regions: %u regions exceed %u", r->count, SL_PVS_MAX_REGIONS);
    if (!r->nodes || !r->visible)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_write_regions: nodes and visible must not be NULL");
    uint32_t bad;
    char why[160];
    if (!regions_check(r->nodes, r->count, &bad, why, sizeof why))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_write_regions: region %u: %s", bad, why);
    const size_t rb = region_row_bytes(r->count);
    if ((uint64_t)nc * rb > SL_PVS_MAX_REGION_MARK_BYTES)
        return sl_fail(err, SL_ERROR_LIMIT, "sl_pvs_write_regions: %u cells of %u regions make %llu bytes of marks (at most %u)",
                       nc, r->count, (unsigned long long)nc * rb, SL_PVS_MAX_REGION_MARK_BYTES);
    for (uint32_t c = 0; c < nc; c++)
        if (!region_row_check(r->nodes, r->count, r->visible + (size_t)c * rb, &bad, why, sizeof why))
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_write_regions: cell %u: %s", c, why);
    *recs = sl_calloc(a, (size_t)r->count, PVS_REGION_REC);
    *frame_cap = ZSTD_compressBound((size_t)nc * rb);
    *frame = sl_alloc(a, *frame_cap);
    if (!*recs || !*frame)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "sl_pvs_write_regions: out of memory for %u regions", r->count);
    for (uint32_t i = 0; i < r->count; i++) {
        uint8_t *q = *recs + (size_t)i * PVS_REGION_REC;
        memcpy(q + R_BOX, &r->nodes[i].box, sizeof(sl_aabb));
        wr32(q + R_FIRST, r->nodes[i].first_child);
        wr32(q + R_CHILDREN, r->nodes[i].child_count);
        wr32(q + R_PARENT, r->nodes[i].parent);
    }
    size_t cs = ZSTD_compressCCtx(cctx, *frame, *frame_cap, r->visible, (size_t)nc * rb, PVS_ZSTD_LEVEL);
    if (ZSTD_isError(cs))
        return sl_fail(err, SL_ERROR_INTERNAL, "pvs: zstd failed on the region marks: %s", ZSTD_getErrorName(cs));
    *frame_size = cs;
    return SL_OK;
}

sl_status sl_pvs_write_regions(const char *path, sl_viewcells cells, uint32_t object_count, uint64_t scene_key,
                               const uint64_t *offsets, const uint32_t *ids, const char *meta,
                               const sl_pvs_regions *regions, sl_error *err)
{
    if (!path || !cells || !offsets)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_write: path, cells and offsets must not be NULL");
    uint32_t nc = sl_viewcells_count(cells);
    const sl_allocator *a = &cells->alloc;
    if (regions && regions->count == 0)
        regions = NULL;
    uint8_t *region_recs = NULL, *region_frame = NULL;
    size_t region_frame_size = 0, region_frame_cap = 0;
    if (offsets[0] != 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_write: offsets[0] is %llu, not 0",
                       (unsigned long long)offsets[0]);
    uint64_t total = offsets[nc];
    if (total && !ids)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_write: ids is NULL");
    for (uint32_t c = 0; c < nc; c++) {
        if (offsets[c + 1] < offsets[c] || offsets[c + 1] - offsets[c] > object_count)
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_write: cell %u: bad set range", c);
        for (uint64_t k = offsets[c]; k < offsets[c + 1]; k++)
            if (ids[k] >= object_count || (k > offsets[c] && ids[k] <= ids[k - 1]))
                return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                               "sl_pvs_write: cell %u: entry %llu (object %u) is out of range or out of order", c,
                               (unsigned long long)(k - offsets[c]), ids[k]);
    }
    size_t meta_len = meta ? strlen(meta) : 0;
    uint32_t nb = (nc + PVS_BLOCK_CELLS - 1) / PVS_BLOCK_CELLS;
    sl_status st = SL_OK;
    uint8_t head_rec[PVS_HEAD_REC];
    uint8_t *sets = sl_calloc(a, (size_t)nc + 1, PVS_SET_REC);
    uint8_t *blks = sl_calloc(a, (size_t)nb + 1, PVS_BLOCK_REC);
    sl_array data = {0}; /* uint8 */
    uint8_t *raw = NULL;
    size_t raw_cap = 0;
    ZSTD_CCtx *cctx = ZSTD_createCCtx_advanced(sl_zstd_mem(a));
    if (!sets || !blks || !cctx) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs: out of memory writing %s", path);
        goto done;
    }
    uint32_t max_raw = 0;
    for (uint32_t b = 0; b < nb && st == SL_OK; b++) {
        uint32_t c0 = b * PVS_BLOCK_CELLS, c1 = SL_MIN(nc, c0 + PVS_BLOCK_CELLS);
        uint64_t need = 5 * (offsets[c1] - offsets[c0]);
        if (need > PVS_MAX_RAW) {
            st = sl_fail(err, SL_ERROR_LIMIT, "pvs: block %u of %s is too large (%llu bytes)", b, path,
                         (unsigned long long)need);
            break;
        }
        if (need + 1 > raw_cap) {
            uint8_t *p = sl_realloc(a, raw, raw_cap, (size_t)need + 1);
            if (!p) {
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs: out of memory writing %s", path);
                break;
            }
            raw = p;
            raw_cap = (size_t)need + 1;
        }
        size_t at = 0;
        for (uint32_t c = c0; c < c1; c++) {
            uint32_t n = (uint32_t)(offsets[c + 1] - offsets[c]);
            wr32(sets + (size_t)c * PVS_SET_REC, n);
            wr32(sets + (size_t)c * PVS_SET_REC + 4, (uint32_t)at);
            at += sl_pvs_encode(ids + offsets[c], n, raw + at);
        }
        size_t bound = ZSTD_compressBound(at);
        size_t start = data.count;
        if (!sl_array_reserve(a, &data, 1, bound)) {
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs: out of memory writing %s", path);
            break;
        }
        size_t cs = ZSTD_compressCCtx(cctx, (uint8_t *)data.data + start, bound, raw, at, PVS_ZSTD_LEVEL);
        if (ZSTD_isError(cs)) {
            st = sl_fail(err, SL_ERROR_INTERNAL, "pvs: zstd failed on block %u: %s", b, ZSTD_getErrorName(cs));
            break;
        }
        data.count += cs;
        uint8_t *br = blks + (size_t)b * PVS_BLOCK_REC;
        wr64(br + B_OFFSET, start);
        wr32(br + B_CSIZE, (uint32_t)cs);
        wr32(br + B_RSIZE, (uint32_t)at);
        wr64(br + B_HASH, sl_hash64((uint8_t *)data.data + start, cs, 0));
        max_raw = SL_MAX(max_raw, (uint32_t)at);
    }
    if (st == SL_OK && regions)
        st = encode_regions(a, regions, nc, cctx, &region_recs, &region_frame, &region_frame_size, &region_frame_cap,
                            err);
    if (st != SL_OK)
        goto done;
    memset(head_rec, 0, sizeof head_rec);
    wr32(head_rec + P_CELLS, nc);
    wr32(head_rec + P_OBJECTS, object_count);
    wr32(head_rec + P_BLOCK_CELLS, PVS_BLOCK_CELLS);
    wr32(head_rec + P_BLOCKS, nb);
    wr64(head_rec + P_SCENE_KEY, scene_key);
    wr64(head_rec + P_CELLS_KEY, sl_viewcells_key(cells));
    wr64(head_rec + P_VISIBLE, total);
    wr32(head_rec + P_ENCODING, PVS_ENCODING_VARINT_ZSTD);
    wr32(head_rec + P_MAX_RAW, max_raw);
    wr32(head_rec + P_KEY_VERSION, SL_PVS_SCENE_KEY_VERSION);

    wsec secs[S_COUNT] = {
        {head_rec, 1, PVS_HEAD_REC},
        {sl_viewcells_data(cells), nc, (uint64_t)nc * 64},
        {sets, nc, (uint64_t)nc * PVS_SET_REC},
        {blks, nb, (uint64_t)nb * PVS_BLOCK_REC},
        {data.data, data.count, data.count},
        {meta, meta_len, meta_len},
        {region_recs, regions ? regions->count : 0, regions ? (uint64_t)regions->count * PVS_REGION_REC : 0},
        {region_frame, region_frame_size, region_frame_size},
    };
    const int nsec = regions ? S_COUNT : S_COUNT_1_1;
    sl_container_section cs[S_COUNT];
    for (int i = 0; i < nsec; i++) {
        memcpy(cs[i].tag, k_secs[i].tag, 4);
        cs[i].elem = k_secs[i].elem;
        cs[i].count = secs[i].count;
        cs[i].data = secs[i].data;
        cs[i].size = secs[i].size;
    }
    st = sl_container_write(a, path, -1, k_magic, PVS_MAJOR, regions ? PVS_MINOR_REGIONS : 1u, 0, 0, cs, (size_t)nsec,
                            err); /* container.h */
done:
    if (regions) {
        sl_free(a, region_recs, (size_t)regions->count * PVS_REGION_REC);
        sl_free(a, region_frame, region_frame_cap);
    }
    ZSTD_freeCCtx(cctx);
    sl_free(a, raw, raw_cap);
    sl_array_free(a, &data, 1);
    sl_free(a, sets, ((size_t)nc + 1) * PVS_SET_REC);
    sl_free(a, blks, ((size_t)nb + 1) * PVS_BLOCK_REC);
    return st;
}

/* ============================================================================================
 * Reader
 * ============================================================================================ */

struct sl_pvs_t {
    sl_allocator alloc;
    char *name;
    sl_mapping map;             /* when mapped */
    uint8_t *owned;             /* when loaded from memory */
    size_t owned_size;
    const uint8_t *bytes;
    uint64_t size;
    uint32_t minor;
    uint64_t off[S_COUNT], len[S_COUNT], hash[S_COUNT];
    bool present[S_COUNT];
    uint32_t cell_count, object_count, block_cells, block_count, max_raw;
    uint64_t scene_key, cells_key, visible_total;
    uint32_t key_version;
    const uint8_t *sets, *blks, *data;
    sl_viewcells cells;
    char *meta;                 /* NUL-terminated copy */
    char *meta_lines;           /* the same with '\n' replaced by NUL */
    size_t meta_size;
    /* decoding cache */
    ZSTD_DCtx *dctx;
    uint8_t *block;             /* max_raw bytes (at least 1) */
    uint32_t cached;            /* block held in `block`, or SL_NONE */
    uint8_t *checked;           /* per block: checksum verified */
    /* motion regions (1.2): validated copies */
    uint32_t region_count;
    sl_pvs_region *regions;
    uint8_t *region_rows;       /* cell_count rows of region_row_bytes(region_count) */
    size_t region_rows_size;
};

/* Format an error naming the file and offset. */
#define FAIL_AT(err, p, offset, ...) sl_container_fail_at(err, (p)->name, (uint64_t)(offset), __VA_ARGS__)

void sl_pvs_destroy(sl_pvs p)
{
    if (!p)
        return;
    const sl_allocator *a = &p->alloc;
    sl_viewcells_destroy(p->cells);
    ZSTD_freeDCtx(p->dctx);
    sl_free(a, p->block, (size_t)p->max_raw + 1);
    sl_free(a, p->checked, (size_t)p->block_count + 1);
    sl_free(a, p->regions, (size_t)p->region_count * sizeof(sl_pvs_region));
    sl_free(a, p->region_rows, p->region_rows_size);
    sl_free(a, p->meta, p->meta_size + 1);
    sl_free(a, p->meta_lines, p->meta_size + 1);
    sl_file_unmap(&p->map);
    sl_free(a, p->owned, p->owned_size);
    sl_strfree(a, p->name);
    sl_free(a, p, sizeof *p);
}

static bool zero_bytes(const uint8_t *p, uint64_t n)
{
    for (uint64_t i = 0; i < n; i++)
        if (p[i])
            return false;
    return true;
}

/* Header and section table. */
static sl_status read_structure(struct sl_pvs_t *p, sl_error *err)
{
    const uint8_t *b = p->bytes;
    static const sl_container_format fmt = {k_magic, ".slpvs", PVS_MAJOR, PVS_MINOR, 0, PVS_MAX_SECTIONS};
    sl_container_header ch;
    sl_status st = sl_container_check_header(b, p->size, &fmt, p->name, &ch, err);
    if (st != SL_OK)
        return st;
    const uint32_t major = ch.major, minor = ch.minor, header_size = ch.header_size, nsec = ch.count;
    const uint32_t entry = ch.entry_size;
    const uint64_t table = ch.table_offset, tsize = ch.table_size;
    p->minor = minor;
    if (ch.flags != 0 && minor <= PVS_MINOR)
        return FAIL_AT(err, p, H_FLAGS, "unknown flags %08x", ch.flags);
    if ((st = sl_container_check_table(b + table, &ch, 0, p->name, err)) != SL_OK)
        return st;
    bool seen[S_COUNT] = {false};
    /* the header, the table and the non-empty sections: they neither overlap nor leave non-zero gaps */
    sl_container_span spans[PVS_MAX_SECTIONS + 2];
    char tags[PVS_MAX_SECTIONS][5];
    uint32_t nspans = 0;
    spans[nspans++] = (sl_container_span){0, header_size, "header", -1};
    spans[nspans++] = (sl_container_span){table, table + tsize, "section table", -2};
    for (uint32_t i = 0; i < nsec; i++) {
        const uint8_t *e = b + table + (uint64_t)i * entry;
        uint64_t eo = table + (uint64_t)i * entry;
        char tag[5] = {(char)e[0], (char)e[1], (char)e[2], (char)e[3], 0};
        for (int k = 0; k < 4; k++)
            if (tag[k] < 0x20 || tag[k] > 0x7e)
                tag[k] = '?';
        uint32_t elem = rd32(e + E_ELEM);
        uint64_t count = rd64(e + E_COUNT), off = rd64(e + E_OFFSET), size = rd64(e + E_SIZE);
        if (rd64(e + E_RESERVED) != 0)
            return FAIL_AT(err, p, eo + E_RESERVED, "section '%s': reserved field is not zero", tag);
        if (off % PVS_ALIGN || off < table + tsize || off > p->size || size > p->size - off)
            return FAIL_AT(err, p, eo + E_OFFSET, "section '%s' at %llu (%llu bytes) is misaligned or outside the file",
                           tag, (unsigned long long)off, (unsigned long long)size);
        if (elem == 0 || count > UINT64_MAX / elem || count * elem != size)
            return FAIL_AT(err, p, eo + E_SIZE, "section '%s': %llu elements of %u bytes do not make %llu bytes", tag,
                           (unsigned long long)count, elem, (unsigned long long)size);
        int k = -1;
        for (int s = 0; s < S_COUNT; s++)
            if (memcmp(e + E_TAG, k_secs[s].tag, 4) == 0)
                k = s;
        if (k >= S_COUNT_1_1 && minor < PVS_MINOR_REGIONS)
            k = -1; /* the region sections came with 1.2 */
        if (k < 0) {
            if (minor <= PVS_MINOR)
                return FAIL_AT(err, p, eo, "unknown section '%s' in a version %u.%u file", tag, major, minor);
        } else {
            if (seen[k])
                return FAIL_AT(err, p, eo, "section '%s' appears twice", tag);
            if (elem != k_secs[k].elem)
                return FAIL_AT(err, p, eo + E_ELEM, "section '%s' has %u-byte elements, expected %u", tag, elem,
                               k_secs[k].elem);
            seen[k] = true;
            p->present[k] = true;
            p->off[k] = off;
            p->len[k] = size;
            p->hash[k] = rd64(e + E_HASH);
            /* DATA is checked block by block (or by sl_pvs_verify); everything else now */
            if (k != S_DATA) {
                uint64_t h = sl_hash64(b + off, (size_t)size, 0);
                if (h != p->hash[k])
                    return FAIL_AT(err, p, off, "section '%s': checksum mismatch (stored %016llx, computed %016llx)", tag,
                                   (unsigned long long)p->hash[k], (unsigned long long)h);
            }
        }
        memcpy(tags[i], tag, sizeof tags[i]);
        if (size)
            spans[nspans++] = (sl_container_span){off, off + size, tags[i], (int)i};
    }
    for (int s = 0; s < S_COUNT; s++)
        if (k_secs[s].required && !seen[s])
            return FAIL_AT(err, p, table, "required section '%s' is missing", k_secs[s].tag);
    /* a newer minor version may use the header's bytes past 64 */
    if (!zero_bytes(b + PVS_HEADER, header_size - PVS_HEADER) && minor <= PVS_MINOR)
        return FAIL_AT(err, p, PVS_HEADER, "header padding is not zero");
    return sl_container_check_layout(spans, nspans, p->size, b, NULL, NULL, p->name, err);
}

/* MREG and MVIS: the hierarchy and every cell's row, decoded and checked now (they are small
 * beside the sets: a bit per node and cell). */
static sl_status read_regions(struct sl_pvs_t *p, sl_error *err)
{
    if (!p->present[S_MREG] && !p->present[S_MVIS])
        return SL_OK;
    if (!p->present[S_MREG] || !p->present[S_MVIS])
        return FAIL_AT(err, p, p->present[S_MREG] ? p->off[S_MREG] : p->off[S_MVIS],
                       "section '%s' comes without '%s'", p->present[S_MREG] ? "MREG" : "MVIS",
                       p->present[S_MREG] ? "MVIS" : "MREG");
    uint64_t n = p->len[S_MREG] / PVS_REGION_REC;
    if (n == 0 || n > SL_PVS_MAX_REGIONS)
        return FAIL_AT(err, p, p->off[S_MREG], "section 'MREG' holds %llu regions (1..%u)", (unsigned long long)n,
                       SL_PVS_MAX_REGIONS);
    const uint8_t *r = p->bytes + p->off[S_MREG];
    p->regions = sl_calloc(&p->alloc, (size_t)n, sizeof(sl_pvs_region));
    if (!p->regions)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for %llu regions", p->name, (unsigned long long)n);
    p->region_count = (uint32_t)n;
    for (uint32_t i = 0; i < p->region_count; i++) {
        const uint8_t *q = r + (size_t)i * PVS_REGION_REC;
        if (!zero_bytes(q + R_RESERVED, PVS_REGION_REC - R_RESERVED))
            return FAIL_AT(err, p, p->off[S_MREG] + (uint64_t)i * PVS_REGION_REC + R_RESERVED,
                           "region %u: reserved bytes are not zero", i);
        memcpy(&p->regions[i].box, q + R_BOX, sizeof(sl_aabb));
        p->regions[i].first_child = rd32(q + R_FIRST);
        p->regions[i].child_count = rd32(q + R_CHILDREN);
        p->regions[i].parent = rd32(q + R_PARENT);
    }
    uint32_t bad;
    char why[160];
    if (!regions_check(p->regions, p->region_count, &bad, why, sizeof why))
        return FAIL_AT(err, p, p->off[S_MREG] + (uint64_t)bad * PVS_REGION_REC, "region %u: %s", bad, why);
    const size_t rb = region_row_bytes(p->region_count);
    const uint64_t want = (uint64_t)p->cell_count * rb;
    if (want > PVS_MAX_RAW)
        return FAIL_AT(err, p, p->off[S_MREG], "%u cells of %u regions make %llu bytes of marks (at most %u)",
                       p->cell_count, p->region_count, (unsigned long long)want, PVS_MAX_RAW);
    const uint8_t *f = p->bytes + p->off[S_MVIS];
    unsigned long long fcs = ZSTD_getFrameContentSize(f, (size_t)p->len[S_MVIS]);
    if (fcs != want)
        return FAIL_AT(err, p, p->off[S_MVIS], "section 'MVIS' %s, expected one of %llu bytes",
                       fcs == ZSTD_CONTENTSIZE_ERROR || fcs == ZSTD_CONTENTSIZE_UNKNOWN ? "is not a zstd frame of stated size"
                                                                                       : "states another decoded size",
                       (unsigned long long)want);
    p->region_rows_size = (size_t)want + 1;
    p->region_rows = sl_alloc(&p->alloc, p->region_rows_size);
    if (!p->region_rows)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for the region marks", p->name);
    size_t got = ZSTD_decompressDCtx(p->dctx, p->region_rows, (size_t)want, f, (size_t)p->len[S_MVIS]);
    if (ZSTD_isError(got) || got != want)
        return FAIL_AT(err, p, p->off[S_MVIS], "section 'MVIS' does not decode: %s",
                       ZSTD_isError(got) ? ZSTD_getErrorName(got) : "short frame");
    for (uint32_t c = 0; c < p->cell_count; c++)
        if (!region_row_check(p->regions, p->region_count, p->region_rows + (size_t)c * rb, &bad, why, sizeof why))
            return FAIL_AT(err, p, p->off[S_MVIS], "cell %u's region marks: %s", c, why);
    return SL_OK;
}

/* PVSH, CELL, SETS, BLKS, META: counts, ranges and cross references. */
static sl_status read_tables(struct sl_pvs_t *p, sl_error *err)
{
    const uint8_t *b = p->bytes;
    if (p->len[S_PVSH] != PVS_HEAD_REC)
        return FAIL_AT(err, p, p->off[S_PVSH], "section 'PVSH' must hold exactly one record");
    const uint8_t *h = b + p->off[S_PVSH];
    uint64_t ho = p->off[S_PVSH];
    p->cell_count = rd32(h + P_CELLS);
    p->object_count = rd32(h + P_OBJECTS);
    p->block_cells = rd32(h + P_BLOCK_CELLS);
    p->block_count = rd32(h + P_BLOCKS);
    p->scene_key = rd64(h + P_SCENE_KEY);
    p->cells_key = rd64(h + P_CELLS_KEY);
    p->visible_total = rd64(h + P_VISIBLE);
    p->max_raw = rd32(h + P_MAX_RAW);
    if (rd32(h + P_ENCODING) != PVS_ENCODING_VARINT_ZSTD)
        return FAIL_AT(err, p, ho + P_ENCODING, "unknown set encoding %u", rd32(h + P_ENCODING));
    /* 1.0 had no key format field (its keys are format 1); 1.1 and later state theirs */
    uint32_t reserved_at = p->minor == 0 ? P_RESERVED_1_0 : P_RESERVED;
    p->key_version = p->minor == 0 ? 1u : rd32(h + P_KEY_VERSION);
    if (p->key_version == 0)
        return FAIL_AT(err, p, ho + P_KEY_VERSION, "scene key format 0 does not exist");
    if (!zero_bytes(h + reserved_at, PVS_HEAD_REC - reserved_at))
        return FAIL_AT(err, p, ho + reserved_at, "reserved bytes of 'PVSH' are not zero");
    if (p->object_count == UINT32_MAX)
        return FAIL_AT(err, p, ho + P_OBJECTS, "object count %u is out of range", p->object_count);
    if (p->block_cells == 0 || p->block_cells > PVS_MAX_BLOCK_CELLS)
        return FAIL_AT(err, p, ho + P_BLOCK_CELLS, "%u cells per block is outside 1..%u", p->block_cells,
                       PVS_MAX_BLOCK_CELLS);
    uint64_t want_blocks = ((uint64_t)p->cell_count + p->block_cells - 1) / p->block_cells;
    if (p->block_count != want_blocks)
        return FAIL_AT(err, p, ho + P_BLOCKS, "%u blocks for %u cells of %u per block (expected %llu)", p->block_count,
                       p->cell_count, p->block_cells, (unsigned long long)want_blocks);
    if (p->max_raw > PVS_MAX_RAW)
        return FAIL_AT(err, p, ho + P_MAX_RAW, "largest block of %u bytes exceeds %u", p->max_raw, PVS_MAX_RAW);
    if (p->len[S_CELL] != (uint64_t)p->cell_count * 64)
        return FAIL_AT(err, p, p->off[S_CELL], "section 'CELL' holds %llu bytes, not %u cells",
                       (unsigned long long)p->len[S_CELL], p->cell_count);
    if (p->len[S_SETS] != (uint64_t)p->cell_count * PVS_SET_REC)
        return FAIL_AT(err, p, p->off[S_SETS], "section 'SETS' holds %llu bytes, not %u cells",
                       (unsigned long long)p->len[S_SETS], p->cell_count);
    if (p->len[S_BLKS] != (uint64_t)p->block_count * PVS_BLOCK_REC)
        return FAIL_AT(err, p, p->off[S_BLKS], "section 'BLKS' holds %llu bytes, not %u blocks",
                       (unsigned long long)p->len[S_BLKS], p->block_count);
    p->sets = b + p->off[S_SETS];
    p->blks = b + p->off[S_BLKS];
    p->data = b + p->off[S_DATA];
    /* blocks: contiguous frames covering DATA exactly; the largest decoded size is stated exactly */
    uint64_t at = 0;
    uint32_t largest = 0;
    for (uint32_t k = 0; k < p->block_count; k++) {
        const uint8_t *r = p->blks + (uint64_t)k * PVS_BLOCK_REC;
        uint64_t ro = p->off[S_BLKS] + (uint64_t)k * PVS_BLOCK_REC;
        uint64_t off = rd64(r + B_OFFSET);
        uint32_t cs = rd32(r + B_CSIZE), rs = rd32(r + B_RSIZE);
        if (off != at || cs == 0 || cs > p->len[S_DATA] - at)
            return FAIL_AT(err, p, ro, "block %u: frame at %llu (%u bytes) does not follow the previous one inside 'DATA'",
                           k, (unsigned long long)off, cs);
        if (rs > p->max_raw)
            return FAIL_AT(err, p, ro + B_RSIZE, "block %u: %u decoded bytes exceed the stated largest %u", k, rs,
                           p->max_raw);
        if (rd64(r + B_RESERVED) != 0)
            return FAIL_AT(err, p, ro + B_RESERVED, "block %u: reserved field is not zero", k);
        unsigned long long fcs = ZSTD_getFrameContentSize(p->data + off, cs);
        if (fcs != rs)
            return FAIL_AT(err, p, p->off[S_DATA] + off, "block %u: the zstd frame %s, the table says %u bytes", k,
                           fcs == ZSTD_CONTENTSIZE_ERROR ? "is not a zstd frame" : "states another decoded size", rs);
        largest = SL_MAX(largest, rs);
        at += cs;
    }
    if (largest != p->max_raw)
        return FAIL_AT(err, p, ho + P_MAX_RAW, "largest block stated as %u bytes, the blocks say %u", p->max_raw, largest);
    if (at != p->len[S_DATA])
        return FAIL_AT(err, p, p->off[S_DATA], "blocks cover %llu of the %llu bytes of 'DATA'", (unsigned long long)at,
                       (unsigned long long)p->len[S_DATA]);
    /* sets: per block, streams in cell order from 0, each with room for its ids */
    uint64_t total = 0;
    for (uint32_t c = 0; c < p->cell_count; c++) {
        uint64_t so = p->off[S_SETS] + (uint64_t)c * PVS_SET_REC;
        uint32_t n = rd32(p->sets + (uint64_t)c * PVS_SET_REC), o = rd32(p->sets + (uint64_t)c * PVS_SET_REC + 4);
        uint32_t blk = c / p->block_cells;
        uint32_t rs = rd32(p->blks + (uint64_t)blk * PVS_BLOCK_REC + B_RSIZE);
        bool first = c % p->block_cells == 0;
        bool last = c + 1 == p->cell_count || (c + 1) % p->block_cells == 0;
        uint32_t end = last ? rs : rd32(p->sets + (uint64_t)(c + 1) * PVS_SET_REC + 4);
        if (n > p->object_count)
            return FAIL_AT(err, p, so, "cell %u: %u visible objects of %u", c, n, p->object_count);
        if ((first && o != 0) || o > end || end > rs)
            return FAIL_AT(err, p, so + 4, "cell %u: stream [%u, %u) is not inside its block's %u bytes in order", c, o,
                           end, rs);
        if ((uint64_t)end - o < n || (uint64_t)end - o > 5ull * n)
            return FAIL_AT(err, p, so, "cell %u: %u ids cannot take %u bytes", c, n, end - o);
        total += n;
    }
    if (total != p->visible_total)
        return FAIL_AT(err, p, ho + P_VISIBLE, "sets hold %llu ids, the header says %llu", (unsigned long long)total,
                       (unsigned long long)p->visible_total);
    /* META: text without NUL */
    const uint8_t *m = b + p->off[S_META];
    for (uint64_t i = 0; i < p->len[S_META]; i++)
        if (m[i] == 0)
            return FAIL_AT(err, p, p->off[S_META] + i, "metadata holds a NUL byte");
    p->meta_size = (size_t)p->len[S_META];
    p->meta = sl_alloc(&p->alloc, p->meta_size + 1);
    p->meta_lines = sl_alloc(&p->alloc, p->meta_size + 1);
    if (!p->meta || !p->meta_lines)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", p->name);
    memcpy(p->meta, m, p->meta_size);
    p->meta[p->meta_size] = 0;
    for (size_t i = 0; i <= p->meta_size; i++)
        p->meta_lines[i] = p->meta[i] == '\n' ? 0 : p->meta[i];
    /* cells (the records are validated and copied) */
    sl_status st = sl_viewcells_create((const sl_viewcell *)(b + p->off[S_CELL]), p->cell_count, &p->alloc, &p->cells,
                                       err);
    if (st != SL_OK) {
        sl_error_prefix(err, "%s: section 'CELL' at offset %llu", p->name, (unsigned long long)p->off[S_CELL]);
        return st;
    }
    if (sl_viewcells_key(p->cells) != p->cells_key)
        return FAIL_AT(err, p, ho + P_CELLS_KEY, "the cells' key does not match the header");
    /* the block buffer is allocated at the first decode */
    p->checked = sl_calloc(&p->alloc, (size_t)p->block_count + 1, 1);
    p->dctx = ZSTD_createDCtx_advanced(sl_zstd_mem(&p->alloc));
    if (!p->checked || !p->dctx)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", p->name);
    p->cached = SL_NONE;
    return read_regions(p, err);
}

static sl_status open_common(struct sl_pvs_t *p, sl_pvs *out, sl_error *err)
{
    sl_status st = read_structure(p, err);
    if (st == SL_OK)
        st = read_tables(p, err);
    if (st != SL_OK) {
        sl_pvs_destroy(p);
        return st;
    }
    *out = p;
    return SL_OK;
}

static struct sl_pvs_t *new_pvs(const sl_allocator *alloc, const char *name)
{
    alloc = sl_alloc_or_default(alloc);
    struct sl_pvs_t *p = sl_calloc(alloc, 1, sizeof *p);
    if (!p)
        return NULL;
    p->alloc = *alloc;
    p->name = sl_strdup(alloc, name);
    if (!p->name) {
        sl_free(alloc, p, sizeof *p);
        return NULL;
    }
    p->cached = SL_NONE;
    return p;
}

/* Read the whole file into a 64-byte aligned buffer of the handle's allocator (the CELL records
 * are read in place). A file that shrinks while it is read (rewritten in place by another
 * process) is reported as truncated; one that grows is read up to the size it had at open. */
static sl_status read_file(struct sl_pvs_t *p, const char *path, sl_error *err)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (fd < 0)
        return sl_fail(err, errno == ENOENT ? SL_ERROR_NOT_FOUND : SL_ERROR_IO, "%s: cannot open: %s", path,
                       strerror(errno));
    struct stat sb;
    if (fstat(fd, &sb) != 0 || !S_ISREG(sb.st_mode)) {
        close(fd);
        return sl_fail(err, SL_ERROR_IO, "%s: not a regular file", path);
    }
    if (sb.st_size == 0) {
        close(fd);
        return sl_container_fail_at(err, path, 0, "truncated: the file is empty (a .slpvs has at least %u bytes)", PVS_HEADER);
    }
    if ((uint64_t)sb.st_size > SIZE_MAX - PVS_ALIGN) {
        close(fd);
        return sl_fail(err, SL_ERROR_LIMIT, "%s: file of %llu bytes is too large", path, (unsigned long long)sb.st_size);
    }
    size_t n = (size_t)sb.st_size;
    p->owned = sl_alloc_aligned(&p->alloc, n, PVS_ALIGN);
    if (!p->owned) {
        close(fd);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for %zu bytes", path, n);
    }
    p->owned_size = n;
    size_t at = 0;
    while (at < n) {
        ssize_t got = pread(fd, p->owned + at, n - at, (off_t)at);
        if (got < 0 && errno == EINTR)
            continue;
        if (got < 0) {
            int e = errno;
            close(fd);
            return sl_fail(err, SL_ERROR_IO, "%s: offset %zu: read failed: %s", path, at, strerror(e));
        }
        if (got == 0) {
            /* the file lost bytes since fstat: someone truncated or is rewriting it */
            uint64_t now = fstat(fd, &sb) == 0 ? (uint64_t)sb.st_size : (uint64_t)at;
            close(fd);
            return sl_container_fail_at(err, path, at, "truncated while reading: expected %zu bytes, file has %llu", n,
                           (unsigned long long)now);
        }
        at += (size_t)got;
    }
    close(fd);
    p->bytes = p->owned;
    p->size = n;
    return SL_OK;
}

sl_status sl_pvs_open(const char *path, uint32_t flags, const sl_allocator *alloc, sl_pvs *out, sl_error *err)
{
    if (!path || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_open: path and out must not be NULL");
    *out = NULL;
    if (flags & ~(uint32_t)SL_PVS_OPEN_MAP)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_open: unknown flags %08x", flags);
    struct sl_pvs_t *p = new_pvs(alloc, path);
    if (!p)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    sl_status st;
    if (flags & SL_PVS_OPEN_MAP) {
        st = sl_file_map(path, &p->map, err);
        p->bytes = p->map.data;
        p->size = p->map.size;
    } else {
        st = read_file(p, path, err);
    }
    if (st != SL_OK) {
        sl_pvs_destroy(p);
        return st;
    }
    return open_common(p, out, err);
}

sl_status sl_pvs_load(const char *path, const sl_allocator *alloc, sl_pvs *out, sl_error *err)
{
    return sl_pvs_open(path, 0, alloc, out, err);
}

sl_status sl_pvs_load_memory(const void *data, size_t size, const char *name, const sl_allocator *alloc, sl_pvs *out,
                             sl_error *err)
{
    if ((!data && size) || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_load_memory: data and out must not be NULL");
    *out = NULL;
    struct sl_pvs_t *p = new_pvs(alloc, name ? name : "(memory)");
    if (!p)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs: out of memory");
    /* a 64-byte aligned copy: the CELL records are read in place */
    p->owned_size = size ? size : 1;
    p->owned = sl_alloc_aligned(&p->alloc, p->owned_size, PVS_ALIGN);
    if (!p->owned) {
        p->owned_size = 0;
        sl_pvs_destroy(p);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "pvs: out of memory for %zu bytes", size);
    }
    if (size)
        memcpy(p->owned, data, size);
    p->bytes = p->owned;
    p->size = size;
    return open_common(p, out, err);
}

/* ---- queries ---- */

void sl_pvs_get_info(sl_pvs p, sl_pvs_info *info)
{
    if (!info)
        return;
    memset(info, 0, sizeof *info);
    if (!p)
        return;
    info->version_major = PVS_MAJOR;
    info->version_minor = p->minor;
    info->cell_count = p->cell_count;
    info->object_count = p->object_count;
    info->block_cells = p->block_cells;
    info->block_count = p->block_count;
    info->scene_key = p->scene_key;
    info->cells_key = p->cells_key;
    info->scene_key_version = p->key_version;
    info->visible_total = p->visible_total;
    info->file_size = p->size;
    info->data_bytes = p->len[S_DATA];
    info->min_visible = p->cell_count ? UINT32_MAX : 0;
    double culled = 0;
    for (uint32_t c = 0; c < p->cell_count; c++) {
        uint32_t n = rd32(p->sets + (uint64_t)c * PVS_SET_REC);
        info->min_visible = SL_MIN(info->min_visible, n);
        info->max_visible = SL_MAX(info->max_visible, n);
        culled += p->object_count ? 1.0 - (double)n / p->object_count : 0.0;
    }
    for (uint32_t k = 0; k < p->block_count; k++)
        info->raw_bytes += rd32(p->blks + (uint64_t)k * PVS_BLOCK_REC + B_RSIZE);
    info->mean_visible = p->cell_count ? (double)p->visible_total / p->cell_count : 0;
    info->region_count = p->region_count;
    if (p->region_count && p->cell_count) {
        uint64_t marked = 0;
        for (size_t i = 0; i < (size_t)p->cell_count * region_row_bytes(p->region_count); i++)
            marked += (uint64_t)__builtin_popcount(p->region_rows[i]);
        info->mean_regions_visible = (double)marked / p->cell_count;
    }
    info->mean_culled = p->cell_count ? culled / p->cell_count : 0;
}

sl_status sl_pvs_check_scene(sl_pvs p, sl_scene scene, sl_error *err)
{
    if (!p || !scene)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_check_scene: pvs and scene must not be NULL");
    const char *m = sl_pvs_meta(p, "method");
    char how[160];
    snprintf(how, sizeof how, "sightline pvs build SCENE%s%s -o %s", m ? " --method " : "", m ? m : "", p->name);
    if (p->key_version < SL_PVS_SCENE_KEY_VERSION)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "%s was baked with an older scene key (format %u; this build uses format %u, which also covers "
                       "triangles and BSP data); bake it again: %s",
                       p->name, p->key_version, SL_PVS_SCENE_KEY_VERSION, how);
    if (p->key_version > SL_PVS_SCENE_KEY_VERSION)
        return sl_fail(err, SL_ERROR_UNSUPPORTED,
                       "%s was baked with a newer scene key (format %u; this build knows format %u): upgrade Sightline",
                       p->name, p->key_version, SL_PVS_SCENE_KEY_VERSION);
    uint32_t n = sl_scene_object_count(scene);
    uint64_t key = sl_pvs_scene_key(scene);
    if (p->object_count != n || p->scene_key != key)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                       "%s was not baked for this scene, but for another scene (%u objects, scene key %016llx; this scene has "
                       "%u objects, key %016llx): bake it again for this scene: %s",
                       p->name, p->object_count, (unsigned long long)p->scene_key, n, (unsigned long long)key, how);
    return SL_OK;
}

sl_viewcells sl_pvs_cells(sl_pvs p) { return p ? p->cells : NULL; }

uint32_t sl_pvs_region_count(sl_pvs p) { return p ? p->region_count : 0; }

const sl_pvs_region *sl_pvs_region_nodes(sl_pvs p) { return p ? p->regions : NULL; }

const uint8_t *sl_pvs_region_row(sl_pvs p, uint32_t cell)
{
    if (!p || !p->region_count || cell >= p->cell_count)
        return NULL;
    return p->region_rows + (size_t)cell * region_row_bytes(p->region_count);
}

bool sl_pvs_region_box_visible(sl_pvs p, const uint8_t *row, const sl_aabb *box)
{
    if (!p || !p->region_count || !row || !box)
        return true;
    const sl_pvs_region *n = p->regions;
    if (!box_inside(box, &n[0].box))
        return true;
    uint32_t at = 0;
    for (;;) {
        if (!(row[at >> 3] >> (at & 7) & 1))
            return false;
        /* every child holding the box must be marked; go on in the first */
        uint32_t next = SL_NONE;
        for (uint32_t j = n[at].first_child; j < n[at].first_child + n[at].child_count; j++)
            if (box_inside(box, &n[j].box)) {
                if (!(row[j >> 3] >> (j & 7) & 1))
                    return false;
                if (next == SL_NONE)
                    next = j;
            }
        if (next == SL_NONE)
            return true;
        at = next;
    }
}

const char *sl_pvs_meta_text(sl_pvs p) { return p ? p->meta : ""; }

const char *sl_pvs_meta(sl_pvs p, const char *key)
{
    if (!p || !key || !*key)
        return NULL;
    /* lines holds the metadata with every '\n' turned into NUL: each line is a C string */
    size_t klen = strlen(key);
    for (size_t at = 0; at < p->meta_size;) {
        const char *line = p->meta_lines + at;
        size_t len = strlen(line);
        if (len > klen && memcmp(line, key, klen) == 0 && line[klen] == '=')
            return line + klen + 1;
        at += len + 1;
    }
    return NULL;
}

uint32_t sl_pvs_cell_count(sl_pvs p, uint32_t cell)
{
    if (!p || cell >= p->cell_count)
        return 0;
    return rd32(p->sets + (uint64_t)cell * PVS_SET_REC);
}

/* A decoder: a zstd context and one decompressed block. The handle has one (sl_pvs_cell_set, one
 * thread at a time); each sl_pvs_cursor has its own, so that cursors run in parallel. The handle's
 * other fields are read-only after opening, except `checked`, read and written atomically. */
typedef struct pvs_decoder {
    ZSTD_DCtx *dctx;
    uint8_t *block;             /* max_raw + 1 bytes, allocated at the first decode */
    uint32_t cached;            /* block held in `block`, or SL_NONE */
} pvs_decoder;

/* Decompress block k into d, checking its checksum on its first use by anyone. */
static sl_status load_block(const struct sl_pvs_t *p, pvs_decoder *d, uint32_t k, sl_error *err)
{
    if (d->cached == k)
        return SL_OK;
    d->cached = SL_NONE;
    if (!d->block) {
        d->block = sl_alloc(&p->alloc, (size_t)p->max_raw + 1);
        if (!d->block)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for a block of %u bytes", p->name, p->max_raw);
    }
    const uint8_t *r = p->blks + (uint64_t)k * PVS_BLOCK_REC;
    uint64_t off = rd64(r + B_OFFSET);
    uint32_t cs = rd32(r + B_CSIZE), rs = rd32(r + B_RSIZE);
    const uint8_t *frame = p->data + off;
    if (!__atomic_load_n(&p->checked[k], __ATOMIC_ACQUIRE)) {
        uint64_t h = sl_hash64(frame, cs, 0);
        if (h != rd64(r + B_HASH))
            return FAIL_AT(err, p, p->off[S_DATA] + off, "block %u: checksum mismatch (stored %016llx, computed %016llx)",
                           k, (unsigned long long)rd64(r + B_HASH), (unsigned long long)h);
    }
    size_t got = ZSTD_decompressDCtx(d->dctx, d->block, (size_t)p->max_raw + 1, frame, cs);
    if (ZSTD_isError(got) || got != rs)
        return FAIL_AT(err, p, p->off[S_DATA] + off, "block %u: the zstd frame %s (%zu bytes, expected %u)", k,
                       ZSTD_isError(got) ? ZSTD_getErrorName(got) : "decodes to the wrong size",
                       ZSTD_isError(got) ? (size_t)0 : got, rs);
    __atomic_store_n(&p->checked[k], 1, __ATOMIC_RELEASE);
    d->cached = k;
    return SL_OK;
}

static sl_status cell_set(const struct sl_pvs_t *p, pvs_decoder *d, const char *who, uint32_t cell, uint32_t *out_ids,
                          uint32_t capacity, uint32_t *count, sl_error *err)
{
    if (count)
        *count = 0;
    if (!p || !count || (!out_ids && capacity))
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: pvs and count must not be NULL", who);
    if (cell >= p->cell_count)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: cell %u does not exist (%u cells)", p->name, cell,
                       p->cell_count);
    uint32_t n = rd32(p->sets + (uint64_t)cell * PVS_SET_REC), o = rd32(p->sets + (uint64_t)cell * PVS_SET_REC + 4);
    if (n > capacity)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: cell %u holds %u objects, capacity is %u", p->name, cell, n,
                       capacity);
    uint32_t k = cell / p->block_cells;
    sl_status st = load_block(p, d, k, err);
    if (st != SL_OK)
        return st;
    uint32_t rs = rd32(p->blks + (uint64_t)k * PVS_BLOCK_REC + B_RSIZE);
    bool last = cell + 1 == p->cell_count || (cell + 1) % p->block_cells == 0;
    uint32_t end = last ? rs : rd32(p->sets + (uint64_t)(cell + 1) * PVS_SET_REC + 4);
    if (!sl_pvs_decode(d->block + o, d->block + end, n, p->object_count, out_ids))
        return FAIL_AT(err, p, p->off[S_DATA] + rd64(p->blks + (uint64_t)k * PVS_BLOCK_REC + B_OFFSET),
                       "cell %u: its set (%u ids, bytes %u..%u of block %u) is malformed", cell, n, o, end, k);
    *count = n;
    return SL_OK;
}

sl_status sl_pvs_cell_set(sl_pvs p, uint32_t cell, uint32_t *out_ids, uint32_t capacity, uint32_t *count, sl_error *err)
{
    if (!p) {
        if (count)
            *count = 0;
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_cell_set: pvs and count must not be NULL");
    }
    pvs_decoder d = {p->dctx, p->block, p->cached};
    sl_status st = cell_set(p, &d, "sl_pvs_cell_set", cell, out_ids, capacity, count, err);
    p->block = d.block;
    p->cached = d.cached;
    return st;
}

/* ---- cursors: one decoder each, for queries from many threads at once ---- */

struct sl_pvs_cursor_t {
    const struct sl_pvs_t *pvs;
    pvs_decoder d;
};

sl_status sl_pvs_cursor_create(sl_pvs pvs, sl_pvs_cursor *out, sl_error *err)
{
    if (out)
        *out = NULL;
    if (!pvs || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_cursor_create: pvs and out must not be NULL");
    struct sl_pvs_cursor_t *c = sl_calloc(&pvs->alloc, 1, sizeof *c);
    if (c)
        c->d.dctx = ZSTD_createDCtx_advanced(sl_zstd_mem(&pvs->alloc));
    if (!c || !c->d.dctx) {
        if (c)
            sl_free(&pvs->alloc, c, sizeof *c);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory for a cursor", pvs->name);
    }
    c->pvs = pvs;
    c->d.cached = SL_NONE;
    *out = c;
    return SL_OK;
}

void sl_pvs_cursor_destroy(sl_pvs_cursor c)
{
    if (!c)
        return;
    const sl_allocator *a = &c->pvs->alloc;
    ZSTD_freeDCtx(c->d.dctx);
    sl_free(a, c->d.block, (size_t)c->pvs->max_raw + 1);
    sl_free(a, c, sizeof *c);
}

sl_status sl_pvs_cursor_cell_set(sl_pvs_cursor c, uint32_t cell, uint32_t *out_ids, uint32_t capacity, uint32_t *count,
                                 sl_error *err)
{
    if (!c) {
        if (count)
            *count = 0;
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_cursor_cell_set: cursor and count must not be NULL");
    }
    return cell_set(c->pvs, &c->d, "sl_pvs_cursor_cell_set", cell, out_ids, capacity, count, err);
}

sl_status sl_pvs_verify(sl_pvs p, sl_error *err)
{
    if (!p)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pvs_verify: pvs is NULL");
    uint64_t h = sl_hash64(p->bytes + p->off[S_DATA], (size_t)p->len[S_DATA], 0);
    if (h != p->hash[S_DATA])
        return FAIL_AT(err, p, p->off[S_DATA], "section 'DATA': checksum mismatch (stored %016llx, computed %016llx)",
                       (unsigned long long)p->hash[S_DATA], (unsigned long long)h);
    uint32_t cap = 0;
    for (uint32_t c = 0; c < p->cell_count; c++)
        cap = SL_MAX(cap, sl_pvs_cell_count(p, c));
    uint32_t *ids = sl_alloc(&p->alloc, ((size_t)cap + 1) * sizeof(uint32_t));
    if (!ids)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", p->name);
    sl_status st = SL_OK;
    for (uint32_t c = 0; c < p->cell_count && st == SL_OK; c++) {
        uint32_t n;
        /* force the checksum of every block to be checked again */
        if (c % p->block_cells == 0) {
            __atomic_store_n(&p->checked[c / p->block_cells], 0, __ATOMIC_RELEASE);
            p->cached = SL_NONE;
        }
        st = sl_pvs_cell_set(p, c, ids, cap, &n, err);
    }
    sl_free(&p->alloc, ids, ((size_t)cap + 1) * sizeof(uint32_t));
    return st;
}
