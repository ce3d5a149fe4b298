/* Quake III Arena map importer (IBSP version 46, as written by q3map/q3map2).
 *
 * The file is a 144-byte header (magic "IBSP", version 46, 17 lump directory entries) and 17
 * lumps of fixed-size little-endian records. Everything is validated before any of it is used:
 * lump bounds, record sizes, every cross-reference (faces -> shaders, drawverts, meshverts; leaves
 * -> leaffaces, leafbrushes, clusters; nodes -> planes, nodes, leaves; models -> faces, brushes),
 * patch sizes and finite coordinates. A bad map fails with SL_ERROR_FORMAT and a message
 * "<name>: lump <k> (<lump>): <element> <i>: <reason>".
 *
 * What becomes of it (docs/quake3-import.md has the long version):
 *  - geometry: polygons and meshes are triangle lists through meshverts, patches are 3x3
 *    biquadratic Bezier pieces tessellated at opt->bezier_level; billboards (flares) are skipped;
 *    units are scaled by 1/32 m (Quake III is Z-up already); triangles are turned counter-clockwise
 *    seen from the front, Sightline's convention (Quake III's meshverts are clockwise);
 *  - objects: each face belongs to exactly one object. Faces of brush entities (models 1..) form
 *    their own objects; every other face belongs to the first leaf (lowest index) of the world's
 *    tree that references it, or to the world's left-over group when no leaf does. A group is cut
 *    by class (opaque solid / sky / other) and then split spatially into objects of about
 *    split_triangles;
 *  - BSP: planes, nodes, leaves, the per-leaf object lists and the map's own cluster PVS, as-is,
 *    except the leaves the world's tree does not reach (q3map's brush-model leaves): no cluster,
 *    no objects (q3_mark_world_leaves);
 *  - metadata: source, map name, counts, spawn points ("q3.spawns", metres), the vis far plane.
 */
#include "pk3.h"
#include "scene/scene_internal.h"
#include "source_meta.h"

#include "core/escape.h"

#include <math.h>
#include <stdlib.h>
#include <strings.h>

enum {
    Q3_ENTITIES,
    Q3_SHADERS,
    Q3_PLANES,
    Q3_NODES,
    Q3_LEAVES,
    Q3_LEAFFACES,
    Q3_LEAFBRUSHES,
    Q3_MODELS,
    Q3_BRUSHES,
    Q3_BRUSHSIDES,
    Q3_DRAWVERTS,
    Q3_MESHVERTS,
    Q3_EFFECTS,
    Q3_FACES,
    Q3_LIGHTMAPS,
    Q3_LIGHTVOLS,
    Q3_VISDATA,
    Q3_LUMP_COUNT
};

static const struct {
    const char *name;
    uint32_t record; /* bytes per record; 1 for the free-form lumps */
} q3_lumps[Q3_LUMP_COUNT] = {
    {"entities", 1},  {"shaders", 72},   {"planes", 16},     {"nodes", 36},      {"leaves", 48},
    {"leaffaces", 4}, {"leafbrushes", 4}, {"models", 40},    {"brushes", 12},    {"brushsides", 8},
    {"drawverts", 44}, {"meshverts", 4},  {"effects", 72},   {"faces", 104},     {"lightmaps", 128 * 128 * 3},
    {"lightvols", 8}, {"visdata", 1},
};

#define Q3_VERSION 46
#define Q3_HEADER_BYTES (8 + 8 * Q3_LUMP_COUNT)
#define Q3_DEFAULT_SCALE (1.0f / 32.0f)
#define Q3_DEFAULT_BEZIER_LEVEL 8u
#define Q3_MAX_BEZIER_LEVEL 64u
#define Q3_DEFAULT_SPLIT 2048u

enum { Q3_FACE_POLYGON = 1, Q3_FACE_PATCH = 2, Q3_FACE_MESH = 3, Q3_FACE_BILLBOARD = 4 };

/* Shader contents and surface flags (Quake III's surfaceflags.h values, stored in the map). */
enum {
    Q3_CONTENTS_SOLID = 0x1,
    Q3_CONTENTS_LAVA = 0x8,
    Q3_CONTENTS_SLIME = 0x10,
    Q3_CONTENTS_WATER = 0x20,
    Q3_CONTENTS_FOG = 0x40,
    Q3_CONTENTS_TRANSLUCENT = 0x20000000
};
enum { Q3_SURF_SKY = 0x4, Q3_SURF_NODRAW = 0x80, Q3_SURF_NONSOLID = 0x4000, Q3_SURF_ALPHASHADOW = 0x10000 };

/* Object classes: a group of faces is cut along these before the spatial split, so that every
 * object is homogeneous and its OCCLUDER flag is exact. */
enum { Q3_CLASS_SOLID = 0, Q3_CLASS_SKY = 1, Q3_CLASS_OTHER = 2, Q3_CLASS_COUNT = 3 };

typedef struct q3_shader {
    char name[65];
    int32_t flags, contents;
} q3_shader;

typedef struct q3_face {
    int32_t shader, type, first_vertex, vertex_count, first_meshvert, meshvert_count, width, height;
    uint32_t tris, verts;   /* output sizes after tessellation (a polygon or mesh keeps only the
                               vertices its meshverts use); 0 for faces that draw nothing */
    uint32_t source;        /* owning group (leaf, world left-overs or brush model); SL_NONE: none */
    uint32_t object;        /* object id once emitted, else SL_NONE */
    uint32_t cls;           /* Q3_CLASS_* */
    float centre[3];        /* centre of the bounds of its (control) vertices, metres */
} q3_face;

typedef struct q3_key {
    float key;
    uint32_t face;
} q3_key;

typedef struct q3_ctx {
    const char *name;       /* for messages: `source` escaped (a pk3 entry's name comes from the archive) */
    const char *source;     /* as given: the file or "archive:entry", for the metadata */
    char shown[600];
    sl_error *err;
    const sl_allocator *a;
    const sl_progress *progress;
    const uint8_t *data;
    size_t size;
    const uint8_t *lump[Q3_LUMP_COUNT];
    uint32_t count[Q3_LUMP_COUNT];
    float scale;
    uint32_t level, split;
    uint64_t max_triangles;
    bool ratio_bound;  /* max_triangles is q3_ratio_limit's bound, not the caller's budget */

    q3_shader *shaders;
    q3_face *faces;
    uint64_t total_tris;
    uint32_t patch_count, drawn_faces;
    int32_t vis_clusters, vis_bytes; /* -1: no visdata */

    sl_scene scene;
    uint32_t solid_objects, sky_objects, see_through_objects;
    sl_array sky_list;  /* char: comma-separated sky object ids */

    /* scratch reused for every object */
    sl_array pos, nrm, idx;   /* float, float, uint32 */
    sl_array shader_tris;     /* uint32 pairs (shader, triangles) for the dominant shader */
    q3_key *keys;
    /* per drawvert: the last face (stamp) that used it and its index in that face's output, so a
     * face emits only the vertices its meshverts use, in O(meshverts) */
    uint32_t *stamp, *remap;
    /* per leaf: 1 when the world's tree (node 0 down) reaches it; see q3_mark_world_leaves */
    uint8_t *world_leaf;
} q3_ctx;

/* ---- little-endian record readers (records may sit at any alignment) ---- */

static inline uint32_t rd_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static inline int32_t rd_i32(const uint8_t *p) { return (int32_t)rd_u32(p); }
static inline float rd_f32(const uint8_t *p)
{
    uint32_t v = rd_u32(p);
    float f;
    memcpy(&f, &v, sizeof f);
    return f;
}
static inline const uint8_t *rec(const q3_ctx *c, int lump, uint32_t i)
{
    return c->lump[lump] + (size_t)i * q3_lumps[lump].record;
}

/* Format failure naming the lump: "<name>: lump <k> (<lump>): <message>". */
static sl_status q3_bad(q3_ctx *c, int lump, const char *fmt, ...) SL_PRINTF(3, 4);
static sl_status q3_bad(q3_ctx *c, int lump, const char *fmt, ...)
{
    char msg[384];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return sl_fail(c->err, SL_ERROR_FORMAT, "%s: lump %d (%s): %s", c->name, lump, q3_lumps[lump].name, msg);
}

static sl_status q3_oom(q3_ctx *c, const char *what)
{
    return sl_fail(c->err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory (%s)", c->name, what);
}

/* A half-open index range [first, first+count) inside [0, limit), without overflow. */
static inline bool range_ok(int32_t first, int32_t count, uint32_t limit)
{
    return first >= 0 && count >= 0 && (uint64_t)first + (uint64_t)count <= limit;
}

/* ---- header and lumps ---- */

static sl_status q3_read_header(q3_ctx *c)
{
    if (c->size < Q3_HEADER_BYTES)
        return sl_fail(c->err, SL_ERROR_FORMAT, "%s: offset 0: %zu bytes is shorter than the %d-byte IBSP header", c->name,
                       c->size, Q3_HEADER_BYTES);
    if (memcmp(c->data, "IBSP", 4) != 0) {
        char magic[5];
        for (int i = 0; i < 4; i++)
            magic[i] = c->data[i] >= 0x20 && c->data[i] < 0x7f && c->data[i] != '"' ? (char)c->data[i] : '?';
        magic[4] = 0;
        return sl_fail(c->err, SL_ERROR_FORMAT, "%s: offset 0: not a Quake III map (magic \"%s\", expected \"IBSP\")",
                       c->name, magic);
    }
    int32_t version = rd_i32(c->data + 4);
    if (version != Q3_VERSION)
        return sl_fail(c->err, SL_ERROR_UNSUPPORTED,
                       "%s: offset 4: IBSP version %d is not supported (only %d, Quake III Arena)", c->name, version,
                       Q3_VERSION);
    for (int k = 0; k < Q3_LUMP_COUNT; k++) {
        int32_t off = rd_i32(c->data + 8 + 8 * k), len = rd_i32(c->data + 12 + 8 * k);
        if (off < 0)
            return q3_bad(c, k, "header offset %d: negative lump offset %d", 8 + 8 * k, off);
        if (len < 0)
            return q3_bad(c, k, "header offset %d: negative lump length %d", 12 + 8 * k, len);
        if ((uint64_t)off + (uint64_t)len > c->size)
            return q3_bad(c, k, "offset %d + length %d runs past the end of the file (%zu bytes)", off, len, c->size);
        if ((uint32_t)len % q3_lumps[k].record)
            return q3_bad(c, k, "length %d is not a multiple of its %u-byte records", len, q3_lumps[k].record);
        c->lump[k] = c->data + off;
        c->count[k] = (uint32_t)len / q3_lumps[k].record;
    }
    return SL_OK;
}

static sl_status q3_read_shaders(q3_ctx *c)
{
    uint32_t n = c->count[Q3_SHADERS];
    c->shaders = sl_calloc(c->a, n ? n : 1, sizeof *c->shaders);
    if (!c->shaders)
        return q3_oom(c, "shaders");
    for (uint32_t i = 0; i < n; i++) {
        const uint8_t *r = rec(c, Q3_SHADERS, i);
        q3_shader *s = &c->shaders[i];
        /* the name is NUL-padded but need not be NUL-terminated */
        size_t len = strnlen((const char *)r, 64);
        memcpy(s->name, r, len);
        s->name[len] = 0;
        s->flags = rd_i32(r + 64);
        s->contents = rd_i32(r + 68);
    }
    return SL_OK;
}

static sl_status q3_check_planes(q3_ctx *c)
{
    for (uint32_t i = 0; i < c->count[Q3_PLANES]; i++) {
        const uint8_t *r = rec(c, Q3_PLANES, i);
        float v[4] = {rd_f32(r), rd_f32(r + 4), rd_f32(r + 8), rd_f32(r + 12)};
        if (!sl_finite3(v) || !isfinite(v[3]) || !isfinite(v[3] * c->scale))
            return q3_bad(c, Q3_PLANES, "plane %u: normal or distance is not finite", i);
    }
    return SL_OK;
}

/* Node and leaf boxes are integers in the file, but times a large unit_scale they can overflow
 * to infinity, which sl_scene_set_bsp refuses: say so against the lump and the element. */
static sl_status q3_check_boxes(q3_ctx *c)
{
    static const int lumps[2] = {Q3_NODES, Q3_LEAVES};
    static const uint32_t first[2] = {12, 8};
    static const char *const what[2] = {"node", "leaf"};
    for (int t = 0; t < 2; t++)
        for (uint32_t i = 0; i < c->count[lumps[t]]; i++) {
            const uint8_t *r = rec(c, lumps[t], i) + first[t];
            for (int k = 0; k < 6; k++)
                if (!isfinite((float)rd_i32(r + 4 * k) * c->scale))
                    return q3_bad(c, lumps[t], "%s %u: %s.%c (%d) is not finite once scaled by %g", what[t], i,
                                  k < 3 ? "mins" : "maxs", "xyz"[k % 3], rd_i32(r + 4 * k), (double)c->scale);
        }
    return SL_OK;
}

static sl_status q3_check_drawverts(q3_ctx *c)
{
    for (uint32_t i = 0; i < c->count[Q3_DRAWVERTS]; i++) {
        const uint8_t *r = rec(c, Q3_DRAWVERTS, i);
        float p[3] = {rd_f32(r), rd_f32(r + 4), rd_f32(r + 8)};
        float n[3] = {rd_f32(r + 28), rd_f32(r + 32), rd_f32(r + 36)};
        float q[3] = {p[0] * c->scale, p[1] * c->scale, p[2] * c->scale};
        if (!sl_finite3(p) || !sl_finite3(q))
            return q3_bad(c, Q3_DRAWVERTS, "vertex %u: position is not finite", i);
        if (!sl_finite3(n))
            return q3_bad(c, Q3_DRAWVERTS, "vertex %u: normal is not finite", i);
    }
    return SL_OK;
}

static bool q3_is_sky(const q3_shader *s) { return (s->flags & Q3_SURF_SKY) || strcasestr(s->name, "sky"); }

/* See-through (docs/import-export.md, "Quake III maps"): a shader marked translucent (surfaceparm
 * trans: alpha-tested grates and foliage, blended glass), water or fog, an alpha-shadow surface or
 * one that is never drawn (nodraw): it can be seen through, so it never hides anything. */
static bool q3_see_through(const q3_shader *s)
{
    return (s->contents & (Q3_CONTENTS_TRANSLUCENT | Q3_CONTENTS_WATER | Q3_CONTENTS_FOG)) ||
           (s->flags & (Q3_SURF_NODRAW | Q3_SURF_ALPHASHADOW));
}

/* Opaque solid: may hide what is behind it. Meshes (misc_model) never count: they are detail,
 * often alpha-tested foliage, and not sealed. */
static uint32_t q3_classify(const q3_shader *s, int32_t type)
{
    if (q3_is_sky(s))
        return Q3_CLASS_SKY;
    const int32_t see_through = Q3_CONTENTS_LAVA | Q3_CONTENTS_SLIME | Q3_CONTENTS_WATER | Q3_CONTENTS_FOG |
                                Q3_CONTENTS_TRANSLUCENT;
    const int32_t not_drawn = Q3_SURF_NODRAW | Q3_SURF_NONSOLID | Q3_SURF_ALPHASHADOW;
    if ((type == Q3_FACE_POLYGON || type == Q3_FACE_PATCH) && (s->contents & Q3_CONTENTS_SOLID) &&
        !(s->contents & see_through) && !(s->flags & not_drawn))
        return Q3_CLASS_SOLID;
    return Q3_CLASS_OTHER;
}

/* The output may grow at most this much per input byte: 65536 triangles plus
 * size * max(level^2, 8) / 32. Faces own disjoint vertex and meshvert runs in maps q3map writes,
 * so a patch yields at most 2 level^2 triangles per 3x3 piece, i.e. per 4 control points (176
 * bytes): level^2 / 88 per byte, and a polygon at most one per 12 bytes of meshverts; the bound
 * leaves more than twice that. Faces sharing one run (one 99x99 patch referenced by 200 faces)
 * could otherwise turn a 455 KB file into 61.5 M triangles (1.47 GB). */
static uint64_t q3_ratio_limit(size_t size, uint32_t level)
{
    uint64_t per = SL_MAX((uint64_t)level * level, 8u);
    return 65536u + (uint64_t)size / 32u * per + (uint64_t)size % 32u * per / 32u;
}

static sl_status q3_too_many(q3_ctx *c, uint32_t face)
{
    if (c->ratio_bound)
        return sl_fail(c->err, SL_ERROR_LIMIT,
                       "%s: lump %d (faces): face %u: the map needs more than %llu triangles at bezier level %u, the "
                       "limit for a %zu-byte map (65536 + bytes x max(level^2, 8) / 32; faces sharing one patch or "
                       "meshvert run multiply the output)",
                       c->name, Q3_FACES, face, (unsigned long long)c->max_triangles, c->level, c->size);
    return sl_fail(c->err, SL_ERROR_LIMIT, "%s: lump %d (faces): face %u: the map needs more than %llu triangles at bezier level %u",
                   c->name, Q3_FACES, face, (unsigned long long)c->max_triangles, c->level);
}

static inline void q3_grow(float lo[3], float hi[3], const uint8_t *vertex)
{
    for (int k = 0; k < 3; k++) {
        float x = rd_f32(vertex + 4 * k);
        lo[k] = SL_MIN(lo[k], x);
        hi[k] = SL_MAX(hi[k], x);
    }
}

static sl_status q3_read_faces(q3_ctx *c)
{
    uint32_t n = c->count[Q3_FACES], nv = c->count[Q3_DRAWVERTS], nm = c->count[Q3_MESHVERTS];
    c->faces = sl_calloc(c->a, n ? n : 1, sizeof *c->faces);
    c->stamp = sl_calloc(c->a, nv ? nv : 1, sizeof *c->stamp);
    c->remap = sl_calloc(c->a, nv ? nv : 1, sizeof *c->remap);
    if (!c->faces || !c->stamp || !c->remap)
        return q3_oom(c, "faces");
    for (uint32_t i = 0; i < n; i++) {
        const uint8_t *r = rec(c, Q3_FACES, i);
        q3_face *f = &c->faces[i];
        f->shader = rd_i32(r);
        f->type = rd_i32(r + 8);
        f->first_vertex = rd_i32(r + 12);
        f->vertex_count = rd_i32(r + 16);
        f->first_meshvert = rd_i32(r + 20);
        f->meshvert_count = rd_i32(r + 24);
        f->width = rd_i32(r + 96);
        f->height = rd_i32(r + 100);
        f->source = f->object = SL_NONE;
        if (f->shader < 0 || (uint32_t)f->shader >= c->count[Q3_SHADERS])
            return q3_bad(c, Q3_FACES, "face %u: shader %d out of range (%u shaders)", i, f->shader, c->count[Q3_SHADERS]);
        /* the effect (fog volume) index at r+4 is not used, and not checked: shipped maps
         * (OpenArena's aggressor.bsp) carry dangling ones */
        if (f->type < Q3_FACE_POLYGON || f->type > Q3_FACE_BILLBOARD)
            return q3_bad(c, Q3_FACES, "face %u: unknown surface type %d (1 polygon, 2 patch, 3 mesh, 4 billboard)", i,
                          f->type);
        if (!range_ok(f->first_vertex, f->vertex_count, nv))
            return q3_bad(c, Q3_FACES, "face %u: vertex range %d+%d outside the %u drawverts", i, f->first_vertex,
                          f->vertex_count, nv);
        if (!range_ok(f->first_meshvert, f->meshvert_count, nm))
            return q3_bad(c, Q3_FACES, "face %u: meshvert range %d+%d outside the %u meshverts", i, f->first_meshvert,
                          f->meshvert_count, nm);
        uint64_t tris = 0, verts = 0;
        float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        if (f->type == Q3_FACE_POLYGON || f->type == Q3_FACE_MESH) {
            if (f->meshvert_count % 3)
                return q3_bad(c, Q3_FACES, "face %u: %d meshverts is not a whole number of triangles", i,
                              f->meshvert_count);
            tris = (uint64_t)f->meshvert_count / 3;
            /* checked before the loop, which faces sharing meshverts could otherwise repeat at will */
            if (c->total_tris + tris > c->max_triangles)
                return q3_too_many(c, i);
            for (int32_t k = 0; k < f->meshvert_count; k++) {
                int32_t m = rd_i32(rec(c, Q3_MESHVERTS, (uint32_t)(f->first_meshvert + k)));
                if (m < 0 || m >= f->vertex_count)
                    return q3_bad(c, Q3_FACES, "face %u: meshvert %d = %d outside the face's %d vertices", i,
                                  f->first_meshvert + k, m, f->vertex_count);
                uint32_t g = (uint32_t)(f->first_vertex + m);
                if (c->stamp[g] != 2 * i + 1) {
                    c->stamp[g] = 2 * i + 1;
                    verts++;
                    q3_grow(lo, hi, rec(c, Q3_DRAWVERTS, g));
                }
            }
        } else if (f->type == Q3_FACE_PATCH) {
            if (f->width < 3 || f->height < 3 || !(f->width & 1) || !(f->height & 1))
                return q3_bad(c, Q3_FACES, "face %u: patch size %dx%d is not odd and at least 3x3", i, f->width,
                              f->height);
            if ((uint64_t)f->width * (uint64_t)f->height != (uint64_t)f->vertex_count)
                return q3_bad(c, Q3_FACES, "face %u: patch size %dx%d does not match its %d control points", i,
                              f->width, f->height, f->vertex_count);
            uint64_t gw = (uint64_t)(f->width - 1) / 2 * c->level + 1, gh = (uint64_t)(f->height - 1) / 2 * c->level + 1;
            tris = 2 * (gw - 1) * (gh - 1);
            verts = gw * gh;
            if (c->total_tris + tris > c->max_triangles)
                return q3_too_many(c, i);
            /* the control points bound the surface (Bezier convex hull) */
            for (int32_t v = 0; v < f->vertex_count; v++)
                q3_grow(lo, hi, rec(c, Q3_DRAWVERTS, (uint32_t)(f->first_vertex + v)));
            c->patch_count++;
        }
        c->total_tris += tris;
        f->tris = (uint32_t)tris;
        f->verts = (uint32_t)verts;
        if (tris)
            c->drawn_faces++;
        f->cls = q3_classify(&c->shaders[f->shader], f->type);
        for (int k = 0; k < 3; k++)
            f->centre[k] = tris ? 0.5f * (lo[k] + hi[k]) * c->scale : 0.0f;
    }
    return SL_OK;
}

static sl_status q3_check_refs(q3_ctx *c)
{
    uint32_t nf = c->count[Q3_FACES], nb = c->count[Q3_BRUSHES];
    for (uint32_t i = 0; i < c->count[Q3_LEAFFACES]; i++) {
        int32_t f = rd_i32(rec(c, Q3_LEAFFACES, i));
        if (f < 0 || (uint32_t)f >= nf)
            return q3_bad(c, Q3_LEAFFACES, "leafface %u: face %d out of range (%u faces)", i, f, nf);
    }
    for (uint32_t i = 0; i < c->count[Q3_LEAFBRUSHES]; i++) {
        int32_t b = rd_i32(rec(c, Q3_LEAFBRUSHES, i));
        if (b < 0 || (uint32_t)b >= nb)
            return q3_bad(c, Q3_LEAFBRUSHES, "leafbrush %u: brush %d out of range (%u brushes)", i, b, nb);
    }
    if (c->count[Q3_MODELS] == 0)
        return q3_bad(c, Q3_MODELS, "no world model (model 0)");
    uint64_t model_faces = 0;
    for (uint32_t i = 0; i < c->count[Q3_MODELS]; i++) {
        const uint8_t *r = rec(c, Q3_MODELS, i);
        int32_t f0 = rd_i32(r + 24), fn = rd_i32(r + 28), b0 = rd_i32(r + 32), bn = rd_i32(r + 36);
        if (!range_ok(f0, fn, nf))
            return q3_bad(c, Q3_MODELS, "model %u: face range %d+%d outside the %u faces", i, f0, fn, nf);
        /* models own disjoint face runs; the bound keeps the work linear in the file size */
        model_faces += (uint64_t)fn;
        if (model_faces > nf)
            return q3_bad(c, Q3_MODELS, "model %u: the models hold more faces than the %u in the lump", i, nf);
        if (!range_ok(b0, bn, nb))
            return q3_bad(c, Q3_MODELS, "model %u: brush range %d+%d outside the %u brushes", i, b0, bn, nb);
    }
    for (uint32_t i = 0; i < nb; i++) {
        const uint8_t *r = rec(c, Q3_BRUSHES, i);
        int32_t s0 = rd_i32(r), sn = rd_i32(r + 4), sh = rd_i32(r + 8);
        if (!range_ok(s0, sn, c->count[Q3_BRUSHSIDES]))
            return q3_bad(c, Q3_BRUSHES, "brush %u: side range %d+%d outside the %u brushsides", i, s0, sn,
                          c->count[Q3_BRUSHSIDES]);
        if (sh < 0 || (uint32_t)sh >= c->count[Q3_SHADERS])
            return q3_bad(c, Q3_BRUSHES, "brush %u: shader %d out of range (%u shaders)", i, sh, c->count[Q3_SHADERS]);
    }
    for (uint32_t i = 0; i < c->count[Q3_BRUSHSIDES]; i++) {
        const uint8_t *r = rec(c, Q3_BRUSHSIDES, i);
        int32_t pl = rd_i32(r), sh = rd_i32(r + 4);
        if (pl < 0 || (uint32_t)pl >= c->count[Q3_PLANES])
            return q3_bad(c, Q3_BRUSHSIDES, "brushside %u: plane %d out of range (%u planes)", i, pl, c->count[Q3_PLANES]);
        if (sh < 0 || (uint32_t)sh >= c->count[Q3_SHADERS])
            return q3_bad(c, Q3_BRUSHSIDES, "brushside %u: shader %d out of range (%u shaders)", i, sh,
                          c->count[Q3_SHADERS]);
    }
    for (uint32_t i = 0; i < c->count[Q3_EFFECTS]; i++) {
        int32_t b = rd_i32(rec(c, Q3_EFFECTS, i) + 64);
        if (b < -1 || (b >= 0 && (uint32_t)b >= nb))
            return q3_bad(c, Q3_EFFECTS, "effect %u: brush %d out of range (%u brushes)", i, b, nb);
    }
    return SL_OK;
}

static sl_status q3_check_vis(q3_ctx *c)
{
    c->vis_clusters = c->vis_bytes = -1;
    uint32_t len = c->count[Q3_VISDATA];
    if (len == 0)
        return SL_OK;
    if (len < 8)
        return q3_bad(c, Q3_VISDATA, "%u bytes cannot hold the 8-byte vis header", len);
    int32_t nvec = rd_i32(c->lump[Q3_VISDATA]), sz = rd_i32(c->lump[Q3_VISDATA] + 4);
    if (nvec < 0 || sz < 0)
        return q3_bad(c, Q3_VISDATA, "negative cluster count %d or row size %d", nvec, sz);
    if (8 + (uint64_t)nvec * (uint64_t)sz > len)
        return q3_bad(c, Q3_VISDATA, "%d clusters x %d bytes do not fit in %u bytes", nvec, sz, len);
    if ((uint64_t)sz * 8 < (uint64_t)nvec)
        return q3_bad(c, Q3_VISDATA, "rows of %d bytes cannot hold %d cluster bits", sz, nvec);
    c->vis_clusters = nvec;
    c->vis_bytes = sz;
    return SL_OK;
}

static sl_status q3_check_leaves(q3_ctx *c, uint32_t *cluster_count)
{
    int32_t max_cluster = -1;
    uint64_t refs = 0;
    for (uint32_t i = 0; i < c->count[Q3_LEAVES]; i++) {
        const uint8_t *r = rec(c, Q3_LEAVES, i);
        int32_t cluster = rd_i32(r), f0 = rd_i32(r + 32), fn = rd_i32(r + 36), b0 = rd_i32(r + 40), bn = rd_i32(r + 44);
        if (cluster < -1 || (c->vis_clusters >= 0 && cluster >= c->vis_clusters))
            return q3_bad(c, Q3_LEAVES, "leaf %u: cluster %d out of range (%d clusters in the vis data)", i, cluster,
                          c->vis_clusters >= 0 ? c->vis_clusters : 0);
        /* without vis data a cluster is a leaf's group: there cannot be more than leaves */
        if (c->vis_clusters < 0 && cluster >= 0 && (uint32_t)cluster >= c->count[Q3_LEAVES])
            return q3_bad(c, Q3_LEAVES, "leaf %u: cluster %d out of range (no vis data, %u leaves)", i, cluster,
                          c->count[Q3_LEAVES]);
        if (!range_ok(f0, fn, c->count[Q3_LEAFFACES]))
            return q3_bad(c, Q3_LEAVES, "leaf %u: leafface range %d+%d outside the %u leaffaces", i, f0, fn,
                          c->count[Q3_LEAFFACES]);
        if (!range_ok(b0, bn, c->count[Q3_LEAFBRUSHES]))
            return q3_bad(c, Q3_LEAVES, "leaf %u: leafbrush range %d+%d outside the %u leafbrushes", i, b0, bn,
                          c->count[Q3_LEAFBRUSHES]);
        max_cluster = SL_MAX(max_cluster, cluster);
        /* q3map gives each leaf its own run of leaffaces; overlapping runs that add up to more
         * than the lump would let a small file demand quadratic work */
        refs += (uint64_t)fn;
        if (refs > c->count[Q3_LEAFFACES])
            return q3_bad(c, Q3_LEAVES, "leaf %u: the leaves reference more leaffaces than the %u in the lump", i,
                          c->count[Q3_LEAFFACES]);
    }
    /* without vis data the clusters still exist; there is just no PVS to go with them */
    *cluster_count = c->vis_clusters >= 0 ? (uint32_t)c->vis_clusters : (uint32_t)max_cluster + 1u;
    return SL_OK;
}

/* ---- nodes ---- */

/* Marks the leaves the world's tree reaches from node 0 (without nodes: leaf 0, where a point
 * lookup lands). q3map also writes one leaf per brush model (doors, platforms: models 1 and up),
 * which no node references and whose cluster field is left at 0 although they are in no cluster;
 * taken at face value they would tie the brush models' faces to cluster 0, so that the map's PVS
 * would hide a door from every cluster that does not see cluster 0, and would add the models'
 * boxes to cluster 0's volume. Unreached leaves therefore get cluster -1 and no objects.
 * Out-of-range children are skipped here (q3_convert_nodes reports them); each node is pushed
 * once, so a cycle cannot loop and the stack holds at most n entries. */
static sl_status q3_mark_world_leaves(q3_ctx *c)
{
    uint32_t n = c->count[Q3_NODES], nl = c->count[Q3_LEAVES];
    c->world_leaf = sl_calloc(c->a, nl ? nl : 1, 1);
    if (!c->world_leaf)
        return q3_oom(c, "world leaves");
    if (n == 0) {
        if (nl)
            c->world_leaf[0] = 1;
        return SL_OK;
    }
    uint8_t *seen = sl_calloc(c->a, n, 1);
    uint32_t *stack = sl_alloc(c->a, (size_t)n * sizeof *stack);
    if (!seen || !stack) {
        sl_free(c->a, seen, n);
        sl_free(c->a, stack, (size_t)n * sizeof *stack);
        return q3_oom(c, "world leaves");
    }
    size_t top = 0;
    stack[top++] = 0;
    seen[0] = 1;
    while (top) {
        const uint8_t *r = rec(c, Q3_NODES, stack[--top]);
        for (int k = 0; k < 2; k++) {
            int32_t ch = rd_i32(r + 4 + 4 * k);
            if (ch >= 0 && (uint32_t)ch < n && !seen[ch]) {
                seen[ch] = 1;
                stack[top++] = (uint32_t)ch;
            } else if (ch < 0 && (uint64_t)(-(int64_t)ch - 1) < nl) {
                c->world_leaf[-(int64_t)ch - 1] = 1;
            }
        }
    }
    sl_free(c->a, seen, n);
    sl_free(c->a, stack, (size_t)n * sizeof *stack);
    return SL_OK;
}

/* Converts the nodes. Sightline wants every child node index above its parent's (so a descent
 * always terminates); q3map writes nodes in pre-order, which satisfies that, but any other order
 * is renumbered here in pre-order from the root. Nodes unreachable from the root are dropped; a
 * node reached twice (a cycle or shared subtree) is a format error. */
static sl_status q3_convert_nodes(q3_ctx *c, sl_bsp_node **out, uint32_t *out_count)
{
    uint32_t n = c->count[Q3_NODES], nl = c->count[Q3_LEAVES], np = c->count[Q3_PLANES];
    *out = NULL;
    *out_count = 0;
    if (n == 0)
        return SL_OK;
    bool ordered = true;
    for (uint32_t i = 0; i < n; i++) {
        const uint8_t *r = rec(c, Q3_NODES, i);
        int32_t plane = rd_i32(r);
        if (plane < 0 || (uint32_t)plane >= np)
            return q3_bad(c, Q3_NODES, "node %u: plane %d out of range (%u planes)", i, plane, np);
        for (int k = 0; k < 2; k++) {
            int32_t ch = rd_i32(r + 4 + 4 * k);
            if (ch >= 0 ? (uint32_t)ch >= n : (uint64_t)(-(int64_t)ch - 1) >= nl)
                return q3_bad(c, Q3_NODES, "node %u: child %d out of range (%u nodes, %u leaves)", i, ch, n, nl);
            if (ch >= 0 && (uint32_t)ch <= i)
                ordered = false;
        }
    }
    uint32_t *map = NULL, *stack = NULL;
    size_t stack_cap = 2 * (size_t)n + 1;
    uint32_t count = n;
    if (!ordered) {
        map = sl_alloc(c->a, (size_t)n * sizeof *map);
        stack = sl_alloc(c->a, stack_cap * sizeof *stack);
        if (!map || !stack) {
            sl_free(c->a, map, (size_t)n * sizeof *map);
            sl_free(c->a, stack, stack_cap * sizeof *stack);
            return q3_oom(c, "node order");
        }
        for (uint32_t i = 0; i < n; i++)
            map[i] = SL_NONE;
        size_t top = 0;
        uint32_t next = 0;
        stack[top++] = 0;
        /* each node is numbered once and pushes at most two children: the stack never overflows */
        while (top) {
            uint32_t i = stack[--top];
            if (map[i] != SL_NONE) {
                sl_free(c->a, map, (size_t)n * sizeof *map);
                sl_free(c->a, stack, stack_cap * sizeof *stack);
                return q3_bad(c, Q3_NODES, "node %u is reached twice from the root: the nodes do not form a tree", i);
            }
            map[i] = next++;
            const uint8_t *r = rec(c, Q3_NODES, i);
            for (int k = 1; k >= 0; k--) {
                int32_t ch = rd_i32(r + 4 + 4 * k);
                if (ch >= 0)
                    stack[top++] = (uint32_t)ch;
            }
        }
        count = next;
        sl_free(c->a, stack, stack_cap * sizeof *stack);
    }
    sl_bsp_node *nodes = sl_calloc(c->a, count, sizeof *nodes);
    if (!nodes) {
        sl_free(c->a, map, (size_t)n * sizeof *map);
        return q3_oom(c, "nodes");
    }
    for (uint32_t i = 0; i < n; i++) {
        uint32_t j = map ? map[i] : i;
        if (j == SL_NONE)
            continue;
        const uint8_t *r = rec(c, Q3_NODES, i);
        sl_bsp_node *d = &nodes[j];
        d->plane = (uint32_t)rd_i32(r);
        for (int k = 0; k < 2; k++) {
            int32_t ch = rd_i32(r + 4 + 4 * k);
            d->children[k] = ch >= 0 && map ? (int32_t)map[ch] : ch;
        }
        d->bounds.min = (sl_vec3){(float)rd_i32(r + 12) * c->scale, (float)rd_i32(r + 16) * c->scale,
                                  (float)rd_i32(r + 20) * c->scale};
        d->bounds.max = (sl_vec3){(float)rd_i32(r + 24) * c->scale, (float)rd_i32(r + 28) * c->scale,
                                  (float)rd_i32(r + 32) * c->scale};
    }
    sl_free(c->a, map, (size_t)n * sizeof *map);
    *out = nodes;
    *out_count = count;
    return SL_OK;
}

/* ---- geometry ---- */

static void q3_normal(q3_ctx *c, const q3_face *f, const float in[3], float out[3])
{
    float l = sqrtf(in[0] * in[0] + in[1] * in[1] + in[2] * in[2]);
    if (l > 1e-12f && isfinite(l)) {
        out[0] = in[0] / l, out[1] = in[1] / l, out[2] = in[2] / l;
        return;
    }
    /* degenerate vertex normal: fall back on the face's plane normal, then on +z */
    const uint8_t *r = rec(c, Q3_FACES, (uint32_t)(f - c->faces));
    float fn[3] = {rd_f32(r + 84), rd_f32(r + 88), rd_f32(r + 92)};
    l = sqrtf(fn[0] * fn[0] + fn[1] * fn[1] + fn[2] * fn[2]);
    if (l > 1e-12f && isfinite(l)) {
        out[0] = fn[0] / l, out[1] = fn[1] / l, out[2] = fn[2] / l;
    } else {
        out[0] = 0, out[1] = 0, out[2] = 1;
    }
}

/* Append the vertices a polygon or mesh face uses (in first-use order) and its triangles,
 * turned counter-clockwise. */
static void q3_emit_soup(q3_ctx *c, const q3_face *f, float *pos, float *nrm, uint32_t *idx, uint32_t base)
{
    const uint32_t stamp = 2 * (uint32_t)(f - c->faces) + 2; /* differs from read_faces' 2i+1 */
    uint32_t next = 0;
    for (int32_t k = 0; k < f->meshvert_count; k++) {
        uint32_t g = (uint32_t)(f->first_vertex + rd_i32(rec(c, Q3_MESHVERTS, (uint32_t)(f->first_meshvert + k))));
        if (c->stamp[g] != stamp) {
            c->stamp[g] = stamp;
            c->remap[g] = next;
            const uint8_t *r = rec(c, Q3_DRAWVERTS, g);
            float n[3] = {rd_f32(r + 28), rd_f32(r + 32), rd_f32(r + 36)};
            for (int j = 0; j < 3; j++)
                pos[3 * (size_t)next + j] = rd_f32(r + 4 * j) * c->scale;
            q3_normal(c, f, n, nrm + 3 * (size_t)next);
            next++;
        }
        /* Quake III meshverts are clockwise seen from the front: swap the last two corners */
        static const int slot[3] = {0, 2, 1};
        idx[3 * (k / 3) + slot[k % 3]] = base + c->remap[g];
    }
}

/* Tessellate a patch: a width x height grid of control points is (width-1)/2 x (height-1)/2
 * biquadratic Bezier pieces sharing their edges; each piece becomes level x level quads on one
 * shared vertex grid, so neighbouring pieces share their seam vertices. Along the control grid's
 * rows (index i, then row j) the triangle (i,j),(i+1,j),(i,j+1) faces the front. */
static void q3_emit_patch(q3_ctx *c, const q3_face *f, float *pos, float *nrm, uint32_t *idx, uint32_t base)
{
    const uint32_t w = (uint32_t)f->width, L = c->level;
    const uint32_t npx = (uint32_t)(f->width - 1) / 2, npy = (uint32_t)(f->height - 1) / 2;
    const uint32_t gw = npx * L + 1, gh = npy * L + 1;
    for (uint32_t gy = 0; gy < gh; gy++) {
        uint32_t py = SL_MIN(gy / L, npy - 1);
        /* evaluated in double: a weighted sum of floats near FLT_MAX must not overflow */
        double t = (double)(gy - py * L) / (double)L;
        double bt[3] = {(1 - t) * (1 - t), 2 * t * (1 - t), t * t};
        for (uint32_t gx = 0; gx < gw; gx++) {
            uint32_t px = SL_MIN(gx / L, npx - 1);
            double s = (double)(gx - px * L) / (double)L;
            double bs[3] = {(1 - s) * (1 - s), 2 * s * (1 - s), s * s};
            double p[3] = {0, 0, 0}, n[3] = {0, 0, 0};
            for (uint32_t j = 0; j < 3; j++)
                for (uint32_t i = 0; i < 3; i++) {
                    uint32_t cp = (2 * py + j) * w + 2 * px + i;
                    const uint8_t *r = rec(c, Q3_DRAWVERTS, (uint32_t)f->first_vertex + cp);
                    double wgt = bt[j] * bs[i];
                    for (int k = 0; k < 3; k++) {
                        p[k] += wgt * rd_f32(r + 4 * k);
                        n[k] += wgt * rd_f32(r + 28 + 4 * k);
                    }
                }
            size_t v = (size_t)gy * gw + gx;
            float nf[3];
            for (int k = 0; k < 3; k++) {
                pos[3 * v + k] = (float)(p[k] * c->scale);
                nf[k] = (float)n[k];
            }
            q3_normal(c, f, nf, nrm + 3 * v);
        }
    }
    size_t t = 0;
    for (uint32_t y = 0; y + 1 < gh; y++)
        for (uint32_t x = 0; x + 1 < gw; x++) {
            uint32_t v00 = base + y * gw + x, v10 = v00 + 1, v01 = v00 + gw, v11 = v01 + 1;
            idx[t++] = v00, idx[t++] = v10, idx[t++] = v01;
            idx[t++] = v10, idx[t++] = v11, idx[t++] = v01;
        }
}

static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

static int cmp_pair(const void *a, const void *b) { return cmp_u32(a, b); }

/* Deterministic colour from a shader name, each channel in [48, 255] so nothing is near black. */
static uint32_t q3_shader_color(const q3_shader *s)
{
    uint64_t h = sl_hash64(s->name, strlen(s->name), 0x71335f5348414452ull);
    uint32_t rgb[3];
    for (int k = 0; k < 3; k++)
        rgb[k] = 48 + (uint32_t)((h >> (8 * k)) & 0xff) * 207 / 255;
    return rgb[0] << 24 | rgb[1] << 16 | rgb[2] << 8 | 0xffu;
}

/* The shader covering the most triangles of the object (ties: the lower shader index). */
static sl_status q3_dominant_shader(q3_ctx *c, const uint32_t *faces, uint32_t n, uint32_t *out)
{
    c->shader_tris.count = 0;
    uint32_t *pairs = sl_array_push(c->a, &c->shader_tris, 2 * sizeof(uint32_t), NULL, n);
    if (!pairs)
        return q3_oom(c, "object shaders");
    for (uint32_t i = 0; i < n; i++) {
        pairs[2 * i] = (uint32_t)c->faces[faces[i]].shader;
        pairs[2 * i + 1] = c->faces[faces[i]].tris;
    }
    qsort(pairs, n, 2 * sizeof(uint32_t), cmp_pair);
    uint64_t best = 0, run = 0;
    *out = pairs[0];
    for (uint32_t i = 0; i < n; i++) {
        run = (i && pairs[2 * i] == pairs[2 * i - 2]) ? run + pairs[2 * i + 1] : pairs[2 * i + 1];
        if (run > best) {
            best = run;
            *out = pairs[2 * i];
        }
    }
    return SL_OK;
}

/* Build one object from a list of faces of one group and class. */
static sl_status q3_emit_object(q3_ctx *c, const uint32_t *faces, uint32_t n, uint32_t source, uint32_t cls)
{
    uint64_t nv = 0, nt = 0;
    for (uint32_t i = 0; i < n; i++) {
        nv += c->faces[faces[i]].verts;
        nt += c->faces[faces[i]].tris;
    }
    c->pos.count = c->nrm.count = c->idx.count = 0;
    float *pos = sl_array_push(c->a, &c->pos, sizeof(float), NULL, 3 * nv);
    float *nrm = sl_array_push(c->a, &c->nrm, sizeof(float), NULL, 3 * nv);
    uint32_t *idx = sl_array_push(c->a, &c->idx, sizeof(uint32_t), NULL, 3 * nt);
    if (!pos || !nrm || !idx)
        return q3_oom(c, "object mesh");
    uint32_t base = 0;
    size_t tri = 0;
    for (uint32_t i = 0; i < n; i++) {
        const q3_face *f = &c->faces[faces[i]];
        if (f->type == Q3_FACE_PATCH)
            q3_emit_patch(c, f, pos + 3 * (size_t)base, nrm + 3 * (size_t)base, idx + 3 * tri, base);
        else
            q3_emit_soup(c, f, pos + 3 * (size_t)base, nrm + 3 * (size_t)base, idx + 3 * tri, base);
        base += f->verts;
        tri += f->tris;
    }
    uint32_t shader = 0;
    sl_status st = q3_dominant_shader(c, faces, n, &shader);
    if (st != SL_OK)
        return st;
    sl_mesh_desc md = {pos, nrm, (uint32_t)nv, idx, (uint32_t)nt, NULL};
    uint32_t mesh, object;
    st = sl_scene_add_mesh(c->scene, &md, &mesh, c->err);
    if (st != SL_OK) {
        /* the scene refuses what the checks above let through only for extreme coordinates
         * (finite control points whose scaled surface is not): still the file's fault */
        sl_error_prefix(c->err, "%s: lump %d (faces): face %u", c->name, Q3_FACES, faces[0]);
        if (st == SL_ERROR_INVALID_ARGUMENT && c->err)
            c->err->status = SL_ERROR_FORMAT;
        return st == SL_ERROR_INVALID_ARGUMENT ? SL_ERROR_FORMAT : st;
    }
    /* brush entities (doors, platforms) move in the game: never trusted as occluders */
    bool world = source <= c->count[Q3_LEAVES];
    /* one see-through face makes the whole object see-through (it never hides anything) */
    bool see_through = false;
    for (uint32_t i = 0; i < n && !see_through && cls == Q3_CLASS_OTHER; i++)
        see_through = q3_see_through(&c->shaders[c->faces[faces[i]].shader]);
    sl_object_desc od = {mesh, NULL, q3_shader_color(&c->shaders[shader]), SL_KIND_BSP_FACES,
                         see_through ? SL_OBJECT_SEE_THROUGH : cls == Q3_CLASS_SOLID && world ? SL_OBJECT_OCCLUDER : 0, 0};
    st = sl_scene_add_object(c->scene, &od, &object, c->err);
    if (st != SL_OK) {
        sl_error_prefix(c->err, "%s", c->name);
        return st;
    }
    for (uint32_t i = 0; i < n; i++)
        c->faces[faces[i]].object = object;
    if (od.flags & SL_OBJECT_OCCLUDER)
        c->solid_objects++;
    c->see_through_objects += see_through;
    if (cls == Q3_CLASS_SKY) {
        char buf[16];
        int len = snprintf(buf, sizeof buf, "%s%u", c->sky_objects ? "," : "", object);
        if (!sl_array_push(c->a, &c->sky_list, 1, buf, (size_t)len))
            return q3_oom(c, "sky list");
        c->sky_objects++;
    }
    return SL_OK;
}

static int cmp_key(const void *a, const void *b)
{
    const q3_key *x = a, *y = b;
    if (x->key != y->key)
        return x->key < y->key ? -1 : 1;
    return (x->face > y->face) - (x->face < y->face);
}

/* Split a list of faces into spatially compact objects of about c->split triangles: sort by face
 * centre along the longest axis of the centres' bounds and cut at the triangle-weighted median,
 * kept within the middle half of the list so that the recursion depth stays logarithmic. A face
 * is never cut, so one face larger than the budget is an object of its own. */
static sl_status q3_emit_group(q3_ctx *c, uint32_t *faces, uint32_t n, uint32_t source, uint32_t cls)
{
    uint64_t total = 0;
    for (uint32_t i = 0; i < n; i++)
        total += c->faces[faces[i]].tris;
    if (n == 1 || total <= c->split)
        return q3_emit_object(c, faces, n, source, cls);
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            lo[k] = SL_MIN(lo[k], c->faces[faces[i]].centre[k]);
            hi[k] = SL_MAX(hi[k], c->faces[faces[i]].centre[k]);
        }
    int axis = 0;
    for (int k = 1; k < 3; k++)
        if (hi[k] - lo[k] > hi[axis] - lo[axis])
            axis = k;
    for (uint32_t i = 0; i < n; i++)
        c->keys[i] = (q3_key){c->faces[faces[i]].centre[axis], faces[i]};
    qsort(c->keys, n, sizeof *c->keys, cmp_key);
    for (uint32_t i = 0; i < n; i++)
        faces[i] = c->keys[i].face;
    uint64_t acc = 0;
    uint32_t k = 0;
    while (k < n && 2 * acc < total)
        acc += c->faces[faces[k++]].tris;
    uint32_t margin = SL_MAX(1u, n / 4);
    k = SL_CLAMP(k, margin, n - margin);
    sl_status st = q3_emit_group(c, faces, k, source, cls);
    return st != SL_OK ? st : q3_emit_group(c, faces + k, n - k, source, cls);
}

/* Assign every drawn face to a group and emit the groups' objects: leaves first (in index
 * order), then the world's left-over faces, then one group per brush model. */
static sl_status q3_build_objects(q3_ctx *c)
{
    const uint32_t nf = c->count[Q3_FACES], nl = c->count[Q3_LEAVES], nmod = c->count[Q3_MODELS];
    const uint32_t world_rest = nl, nsrc = nl + nmod;
    /* brush models own their faces first: they are entities, not part of the world's leaves */
    for (uint32_t m = 1; m < nmod; m++) {
        const uint8_t *r = rec(c, Q3_MODELS, m);
        int32_t f0 = rd_i32(r + 24), fn = rd_i32(r + 28);
        for (int32_t f = f0; f < f0 + fn; f++)
            if (c->faces[f].tris && c->faces[f].source == SL_NONE)
                c->faces[f].source = nl + m;
    }
    for (uint32_t l = 0; l < nl; l++) {
        if (!c->world_leaf[l])
            continue;
        const uint8_t *r = rec(c, Q3_LEAVES, l);
        int32_t f0 = rd_i32(r + 32), fn = rd_i32(r + 36);
        for (int32_t k = f0; k < f0 + fn; k++) {
            q3_face *f = &c->faces[rd_i32(rec(c, Q3_LEAFFACES, (uint32_t)k))];
            if (f->tris && f->source == SL_NONE)
                f->source = l;
        }
    }
    for (uint32_t f = 0; f < nf; f++)
        if (c->faces[f].tris && c->faces[f].source == SL_NONE)
            c->faces[f].source = world_rest;

    /* counting sort of the drawn faces by (group, class), face order kept within each */
    size_t nbuckets = (size_t)nsrc * Q3_CLASS_COUNT;
    uint32_t *start = sl_calloc(c->a, nbuckets + 1, sizeof *start);
    uint32_t *order = sl_alloc(c->a, (size_t)(c->drawn_faces ? c->drawn_faces : 1) * sizeof *order);
    c->keys = sl_alloc(c->a, (size_t)(c->drawn_faces ? c->drawn_faces : 1) * sizeof *c->keys);
    sl_status st = SL_OK;
    if (!start || !order || !c->keys) {
        st = q3_oom(c, "face groups");
        goto done;
    }
    for (uint32_t f = 0; f < nf; f++)
        if (c->faces[f].tris)
            start[(size_t)c->faces[f].source * Q3_CLASS_COUNT + c->faces[f].cls + 1]++;
    for (size_t b = 0; b < nbuckets; b++)
        start[b + 1] += start[b];
    for (uint32_t f = 0; f < nf; f++)
        if (c->faces[f].tris)
            order[start[(size_t)c->faces[f].source * Q3_CLASS_COUNT + c->faces[f].cls]++] = f;
    /* start[b] now holds the end of bucket b: walk the buckets with a running begin */
    uint32_t begin = 0;
    for (size_t b = 0; b < nbuckets && st == SL_OK; b++) {
        uint32_t end = start[b];
        if (end > begin)
            st = q3_emit_group(c, order + begin, end - begin, (uint32_t)(b / Q3_CLASS_COUNT), (uint32_t)(b % Q3_CLASS_COUNT));
        begin = end;
        if (st == SL_OK && b % 1024 == 0 && !sl_progress_report(c->progress, "q3 objects", b, nbuckets))
            st = sl_fail(c->err, SL_ERROR_CANCELLED, "%s: cancelled", c->name);
    }
done:
    sl_free(c->a, start, (nbuckets + 1) * sizeof *start);
    sl_free(c->a, order, (size_t)(c->drawn_faces ? c->drawn_faces : 1) * sizeof *order);
    sl_free(c->a, c->keys, (size_t)(c->drawn_faces ? c->drawn_faces : 1) * sizeof *c->keys);
    c->keys = NULL;
    return st;
}

/* ---- BSP ---- */

static sl_status q3_set_bsp(q3_ctx *c, uint32_t cluster_count)
{
    const uint32_t nl = c->count[Q3_LEAVES], np = c->count[Q3_PLANES];
    sl_bsp_desc d;
    memset(&d, 0, sizeof d);
    sl_plane *planes = sl_alloc(c->a, (size_t)(np ? np : 1) * sizeof *planes);
    sl_bsp_leaf *leaves = sl_calloc(c->a, nl ? nl : 1, sizeof *leaves);
    sl_bsp_node *nodes = NULL;
    uint32_t node_count = 0;
    sl_array lo = {0};
    sl_status st = SL_OK;
    if (!planes || !leaves) {
        st = q3_oom(c, "bsp");
        goto done;
    }
    /* Quake III: normal . p = dist; front (child 0) where normal . p - dist >= 0 */
    for (uint32_t i = 0; i < np; i++) {
        const uint8_t *r = rec(c, Q3_PLANES, i);
        planes[i] = (sl_plane){rd_f32(r), rd_f32(r + 4), rd_f32(r + 8), -rd_f32(r + 12) * c->scale};
    }
    st = q3_convert_nodes(c, &nodes, &node_count);
    if (st != SL_OK)
        goto done;
    for (uint32_t l = 0; l < nl; l++) {
        const uint8_t *r = rec(c, Q3_LEAVES, l);
        sl_bsp_leaf *leaf = &leaves[l];
        leaf->cluster = c->world_leaf[l] ? rd_i32(r) : -1;
        leaf->area = rd_i32(r + 4);
        leaf->bounds.min = (sl_vec3){(float)rd_i32(r + 8) * c->scale, (float)rd_i32(r + 12) * c->scale,
                                     (float)rd_i32(r + 16) * c->scale};
        leaf->bounds.max = (sl_vec3){(float)rd_i32(r + 20) * c->scale, (float)rd_i32(r + 24) * c->scale,
                                     (float)rd_i32(r + 28) * c->scale};
        /* the objects holding any face this leaf references, sorted and deduplicated */
        size_t first = lo.count;
        int32_t f0 = rd_i32(r + 32), fn = c->world_leaf[l] ? rd_i32(r + 36) : 0;
        for (int32_t k = f0; k < f0 + fn; k++) {
            uint32_t obj = c->faces[rd_i32(rec(c, Q3_LEAFFACES, (uint32_t)k))].object;
            if (obj != SL_NONE && !sl_array_push(c->a, &lo, sizeof(uint32_t), &obj, 1)) {
                st = q3_oom(c, "leaf objects");
                goto done;
            }
        }
        size_t n = lo.count - first, u = 0;
        if (n) {
            uint32_t *list = (uint32_t *)lo.data + first;
            qsort(list, n, sizeof *list, cmp_u32);
            for (size_t i = 0; i < n; i++)
                if (u == 0 || list[i] != list[u - 1])
                    list[u++] = list[i];
        }
        lo.count = first + u;
        if (lo.count > UINT32_MAX) {
            st = sl_fail(c->err, SL_ERROR_LIMIT, "%s: too many leaf objects", c->name);
            goto done;
        }
        leaf->first_object = (uint32_t)first;
        leaf->object_count = (uint32_t)u;
    }
    d.planes = planes;
    d.plane_count = np;
    d.nodes = nodes;
    d.node_count = node_count;
    d.leaves = leaves;
    d.leaf_count = nl;
    d.leaf_objects = lo.data;
    d.leaf_object_count = (uint32_t)lo.count;
    d.cluster_count = cluster_count;
    if (c->vis_clusters >= 0) {
        d.cluster_bytes = (uint32_t)c->vis_bytes;
        d.pvs = c->vis_clusters > 0 && c->vis_bytes > 0 ? c->lump[Q3_VISDATA] + 8 : NULL;
    }
    st = sl_scene_set_bsp(c->scene, &d, c->err);
    if (st != SL_OK) {
        /* everything was validated above: a refusal here means the two checks disagree */
        sl_error_prefix(c->err, "%s", c->name);
        if (st == SL_ERROR_INVALID_ARGUMENT)
            st = c->err ? (c->err->status = SL_ERROR_FORMAT) : SL_ERROR_FORMAT;
    }
done:
    sl_free(c->a, planes, (size_t)(np ? np : 1) * sizeof *planes);
    sl_free(c->a, leaves, (size_t)(nl ? nl : 1) * sizeof *leaves);
    sl_free(c->a, nodes, (size_t)node_count * sizeof *nodes);
    sl_array_free(c->a, &lo, sizeof(uint32_t));
    return st;
}

/* ---- entities ---- */

/* Locale-independent decimal parser for entity values ("-128 256.5 1e2"); advances *s. */
static bool q3_parse_number(const char **s, double *out)
{
    const char *p = *s;
    while (*p == ' ' || *p == '\t')
        p++;
    double sign = 1, v = 0, scale = 1;
    if (*p == '-' || *p == '+')
        sign = *p++ == '-' ? -1 : 1;
    int digits = 0;
    while (*p >= '0' && *p <= '9')
        v = v * 10 + (*p++ - '0'), digits++;
    if (*p == '.') {
        p++;
        while (*p >= '0' && *p <= '9')
            v = v * 10 + (*p++ - '0'), scale *= 10, digits++;
    }
    if (!digits)
        return false;
    v /= scale;
    if (*p == 'e' || *p == 'E') {
        p++;
        int es = 1, e = 0;
        if (*p == '-' || *p == '+')
            es = *p++ == '-' ? -1 : 1;
        if (!(*p >= '0' && *p <= '9'))
            return false;
        while (*p >= '0' && *p <= '9')
            e = SL_MIN(e * 10 + (*p++ - '0'), 400);
        v *= pow(10.0, es * e);
    }
    *out = sign * v;
    *s = p;
    return isfinite(*out);
}

/* One quoted token or brace from the entity text; false at the end or on malformed text. */
static bool q3_entity_token(const char **p, const char *end, char *tok, size_t cap)
{
    const char *s = *p;
    while (s < end && *s && (*s == ' ' || *s == '\t' || *s == '\n' || *s == '\r'))
        s++;
    if (s >= end || !*s)
        return false;
    if (*s == '{' || *s == '}') {
        tok[0] = *s, tok[1] = 0;
        *p = s + 1;
        return true;
    }
    if (*s != '"')
        return false;
    s++;
    size_t n = 0;
    while (s < end && *s && *s != '"') {
        if (n + 1 < cap)
            tok[n++] = *s;
        s++;
    }
    if (s >= end || *s != '"')
        return false;
    tok[n] = 0;
    *p = s + 1;
    return true;
}

/* Copy a string, truncated to cap-1 bytes. */
static void q3_copy(char *dst, size_t cap, const char *src)
{
    size_t n = strnlen(src, cap - 1);
    memcpy(dst, src, n);
    dst[n] = 0;
}

static bool q3_is_spawn(const char *classname)
{
    /* Quake III's deathmatch, single-player and CTF spawns; Nexuiz's (and Xonotic's) team
     * spawns and race starts: team-only and race maps have no other */
    static const char *const spawns[] = {"info_player_deathmatch", "info_player_start", "team_CTF_redplayer",
                                         "team_CTF_blueplayer",    "team_CTF_redspawn", "team_CTF_bluespawn",
                                         "info_player_team1",      "info_player_team2", "info_player_team3",
                                         "info_player_team4",      "info_player_race"};
    for (size_t i = 0; i < SL_COUNTOF(spawns); i++)
        if (strcasecmp(classname, spawns[i]) == 0)
            return true;
    return false;
}

/* Read the entity text for spawn points (appended to *spawns as "x y z;...", metres), the
 * worldspawn message and its "_farplanedist" (q3map2's vis drops clusters farther than that, for
 * maps whose fog hides them: *farplane in units, 0 without). The entity text is informative only:
 * reading stops quietly at the first malformed token, keeping what came before. */
static sl_status q3_read_entities(q3_ctx *c, sl_array *spawns, uint32_t *spawn_count, uint32_t *entity_count,
                                  char *title, size_t title_cap, double *farplane)
{
    const char *p = (const char *)c->lump[Q3_ENTITIES], *end = p + c->count[Q3_ENTITIES];
    char tok[256], key[256], classname[64] = "", origin[128] = "", message[256] = "", far[64] = "";
    bool in_entity = false;
    *spawn_count = *entity_count = 0;
    *farplane = 0;
    title[0] = 0;
    while (q3_entity_token(&p, end, tok, sizeof tok)) {
        if (!in_entity) {
            if (strcmp(tok, "{") != 0)
                break;
            in_entity = true;
            classname[0] = origin[0] = message[0] = far[0] = 0;
            continue;
        }
        if (strcmp(tok, "}") == 0) {
            in_entity = false;
            ++*entity_count;
            double v[3];
            const char *s = origin;
            if (q3_is_spawn(classname) && q3_parse_number(&s, &v[0]) && q3_parse_number(&s, &v[1]) &&
                q3_parse_number(&s, &v[2])) {
                char buf[96];
                int len = snprintf(buf, sizeof buf, "%s%.4f %.4f %.4f", *spawn_count ? ";" : "", v[0] * c->scale,
                                   v[1] * c->scale, v[2] * c->scale);
                if (len > 0 && (size_t)len < sizeof buf) {
                    if (!sl_array_push(c->a, spawns, 1, buf, (size_t)len))
                        return q3_oom(c, "spawns");
                    ++*spawn_count;
                }
            }
            if (strcasecmp(classname, "worldspawn") == 0 && message[0] && !title[0])
                q3_copy(title, title_cap, message);
            s = far;
            if (strcasecmp(classname, "worldspawn") == 0 && q3_parse_number(&s, &v[0]) && v[0] > 0 && v[0] < 1e9)
                *farplane = v[0];
            continue;
        }
        if (tok[0] == '{' && !tok[1])
            break;
        memcpy(key, tok, sizeof key);
        if (!q3_entity_token(&p, end, tok, sizeof tok) || ((tok[0] == '{' || tok[0] == '}') && !tok[1]))
            break;
        if (strcasecmp(key, "classname") == 0)
            q3_copy(classname, sizeof classname, tok);
        else if (strcasecmp(key, "origin") == 0)
            q3_copy(origin, sizeof origin, tok);
        else if (strcasecmp(key, "message") == 0)
            q3_copy(message, sizeof message, tok);
        else if (strcasecmp(key, "_farplanedist") == 0)
            q3_copy(far, sizeof far, tok);
    }
    /* titles sometimes carry line breaks or control bytes */
    for (char *t = title; *t; t++)
        if ((unsigned char)*t < 0x20 || *t == 0x7f)
            *t = ' ';
    return SL_OK;
}

/* ---- metadata ---- */

static sl_status q3_meta(q3_ctx *c, const char *key, const char *fmt, ...) SL_PRINTF(3, 4);
static sl_status q3_meta(q3_ctx *c, const char *key, const char *fmt, ...)
{
    char buf[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    return sl_scene_set_meta(c->scene, key, buf, c->err);
}

static sl_status q3_set_metadata(q3_ctx *c, uint32_t cluster_count)
{
    sl_array spawns = {0};
    uint32_t spawn_count, entity_count;
    char title[256];
    double farplane;
    sl_status st = q3_read_entities(c, &spawns, &spawn_count, &entity_count, title, sizeof title, &farplane);
    if (st != SL_OK)
        goto done;
    char nul = 0;
    if (!sl_array_push(c->a, &spawns, 1, &nul, 1) || !sl_array_push(c->a, &c->sky_list, 1, &nul, 1)) {
        st = q3_oom(c, "metadata");
        goto done;
    }
    /* the map name: the last path component (after '/' or the archive's ':'), without ".bsp" */
    const char *base = c->source;
    for (const char *s = c->source; *s; s++)
        if (*s == '/' || *s == ':' || *s == '\\')
            base = s + 1;
    size_t len = strlen(base);
    if (len > 4 && strcasecmp(base + len - 4, ".bsp") == 0)
        len -= 4;
    sl_scene_stats stats;
    sl_scene_get_stats(c->scene, &stats);
    if ((st = sl_scene_set_source(c->scene, c->source, c->data, c->size, c->err)) != SL_OK ||
        (st = q3_meta(c, "importer", "quake3-ibsp46")) != SL_OK ||
        (st = q3_meta(c, "q3.map", "%.*s", (int)SL_MIN(len, 200u), base)) != SL_OK ||
        (st = q3_meta(c, "q3.unit_scale", "%.9g", (double)c->scale)) != SL_OK ||
        (st = q3_meta(c, "q3.bezier_level", "%u", c->level)) != SL_OK ||
        (st = q3_meta(c, "q3.entities_bytes", "%u", c->count[Q3_ENTITIES])) != SL_OK ||
        (st = q3_meta(c, "q3.entities", "%u", entity_count)) != SL_OK ||
        (st = q3_meta(c, "q3.shaders", "%u", c->count[Q3_SHADERS])) != SL_OK ||
        (st = q3_meta(c, "q3.faces", "%u", c->count[Q3_FACES])) != SL_OK ||
        (st = q3_meta(c, "q3.patches", "%u", c->patch_count)) != SL_OK ||
        (st = q3_meta(c, "q3.models", "%u", c->count[Q3_MODELS])) != SL_OK ||
        (st = q3_meta(c, "q3.nodes", "%u", c->count[Q3_NODES])) != SL_OK ||
        (st = q3_meta(c, "q3.leaves", "%u", c->count[Q3_LEAVES])) != SL_OK ||
        (st = q3_meta(c, "q3.clusters", "%u", cluster_count)) != SL_OK ||
        (st = q3_meta(c, "q3.has_vis", "%s", c->vis_clusters > 0 ? "yes" : "no")) != SL_OK ||
        (st = q3_meta(c, "q3.triangles", "%llu", (unsigned long long)stats.triangle_count)) != SL_OK ||
        (st = q3_meta(c, "q3.occluder_objects", "%u", c->solid_objects)) != SL_OK ||
        (st = q3_meta(c, "q3.see_through_objects", "%u", c->see_through_objects)) != SL_OK ||
        (st = q3_meta(c, "q3.spawn_count", "%u", spawn_count)) != SL_OK ||
        (st = sl_scene_set_meta(c->scene, "q3.spawns", spawns.data, c->err)) != SL_OK ||
        (st = sl_scene_set_meta(c->scene, "q3.sky_objects", c->sky_list.data, c->err)) != SL_OK)
        goto done;
    if (title[0])
        st = sl_scene_set_meta(c->scene, "q3.title", title, c->err);
    if (st == SL_OK && farplane > 0)
        st = q3_meta(c, "q3.farplanedist", "%.4f", farplane * c->scale);
done:
    sl_array_free(c->a, &spawns, 1);
    return st;
}

/* ---- entry points ---- */

sl_import_options sl_import_defaults(void)
{
    sl_import_options o;
    memset(&o, 0, sizeof o);
    return o;
}

static sl_status q3_import(q3_ctx *c)
{
    sl_status st;
    uint32_t cluster_count = 0;
    if ((st = q3_read_header(c)) != SL_OK || (st = q3_read_shaders(c)) != SL_OK || (st = q3_check_planes(c)) != SL_OK ||
        (st = q3_check_boxes(c)) != SL_OK ||
        (st = q3_check_drawverts(c)) != SL_OK || (st = q3_read_faces(c)) != SL_OK || (st = q3_check_refs(c)) != SL_OK ||
        (st = q3_check_vis(c)) != SL_OK || (st = q3_check_leaves(c, &cluster_count)) != SL_OK ||
        (st = q3_mark_world_leaves(c)) != SL_OK)
        return st;
    if (!sl_progress_report(c->progress, "q3 objects", 0, 1))
        return sl_fail(c->err, SL_ERROR_CANCELLED, "%s: cancelled", c->name);
    if ((st = sl_scene_create(c->a, &c->scene, c->err)) != SL_OK || (st = q3_build_objects(c)) != SL_OK ||
        (st = q3_set_bsp(c, cluster_count)) != SL_OK || (st = q3_set_metadata(c, cluster_count)) != SL_OK)
        return st;
    if (!sl_progress_report(c->progress, "q3 objects", 1, 1))
        return sl_fail(c->err, SL_ERROR_CANCELLED, "%s: cancelled", c->name);
    return SL_OK;
}

sl_status sl_q3bsp_import_memory_limited(const void *data, size_t size, const char *name,
                                         const sl_import_options *opt, uint64_t max_triangles,
                                         const sl_allocator *alloc, sl_scene *out, sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_import_q3bsp_memory: out is NULL");
    *out = NULL;
    if (!data && size)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_import_q3bsp_memory: data is NULL");
    sl_import_options o = opt ? *opt : sl_import_defaults();
    q3_ctx c;
    memset(&c, 0, sizeof c);
    c.source = name ? name : "<memory>";
    c.name = sl_escape_text(c.source, 500, c.shown, sizeof c.shown);
    c.err = err;
    c.a = sl_alloc_or_default(alloc);
    c.progress = &o.progress;
    c.data = data;
    c.size = size;
    c.scale = o.unit_scale == 0 ? Q3_DEFAULT_SCALE : o.unit_scale;
    c.level = o.bezier_level ? o.bezier_level : Q3_DEFAULT_BEZIER_LEVEL;
    c.split = o.split_triangles ? o.split_triangles : Q3_DEFAULT_SPLIT;
    c.max_triangles = SL_MIN(max_triangles, (uint64_t)UINT32_MAX / 3);
    if (!isfinite(c.scale) || c.scale <= 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: unit_scale %g is not a positive finite number", c.name,
                       (double)c.scale);
    if (c.level > Q3_MAX_BEZIER_LEVEL)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: bezier_level %u exceeds the maximum %u", c.name, c.level,
                       Q3_MAX_BEZIER_LEVEL);
    uint64_t ratio = q3_ratio_limit(size, c.level);
    if (ratio < c.max_triangles) {
        c.max_triangles = ratio;
        c.ratio_bound = true;
    }
    sl_status st = q3_import(&c);
    sl_free(c.a, c.shaders, (size_t)(c.count[Q3_SHADERS] ? c.count[Q3_SHADERS] : 1) * sizeof *c.shaders);
    sl_free(c.a, c.faces, (size_t)(c.count[Q3_FACES] ? c.count[Q3_FACES] : 1) * sizeof *c.faces);
    sl_array_free(c.a, &c.pos, sizeof(float));
    sl_array_free(c.a, &c.nrm, sizeof(float));
    sl_array_free(c.a, &c.idx, sizeof(uint32_t));
    sl_array_free(c.a, &c.shader_tris, 2 * sizeof(uint32_t));
    sl_array_free(c.a, &c.sky_list, 1);
    sl_free(c.a, c.stamp, (size_t)(c.count[Q3_DRAWVERTS] ? c.count[Q3_DRAWVERTS] : 1) * sizeof *c.stamp);
    sl_free(c.a, c.remap, (size_t)(c.count[Q3_DRAWVERTS] ? c.count[Q3_DRAWVERTS] : 1) * sizeof *c.remap);
    sl_free(c.a, c.world_leaf, c.count[Q3_LEAVES] ? c.count[Q3_LEAVES] : 1);
    if (st != SL_OK) {
        sl_scene_destroy(c.scene);
        return st;
    }
    *out = c.scene;
    return SL_OK;
}

sl_status sl_import_q3bsp_memory(const void *data, size_t size, const char *name, const sl_import_options *opt,
                                 const sl_allocator *alloc, sl_scene *out, sl_error *err)
{
    return sl_q3bsp_import_memory_limited(data, size, name, opt, SL_Q3_MAX_TRIANGLES, alloc, out, err);
}

sl_status sl_import_q3bsp(const char *path, const char *map, const sl_import_options *opt, const sl_allocator *alloc,
                          sl_scene *out, sl_error *err)
{
    if (!path || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_import_q3bsp: NULL argument");
    *out = NULL;
    sl_mapping m;
    sl_status st = sl_file_map(path, &m, err);
    if (st != SL_OK)
        return st;
    /* a .pk3 is recognised by its zip signature, whatever its file name */
    if (sl_pk3_is_zip(m.data, m.size))
        st = sl_pk3_import_memory(m.data, m.size, path, map, SL_PK3_MAX_ENTRY_BYTES, SL_Q3_MAX_TRIANGLES, opt, alloc,
                                  out, err);
    else
        st = sl_import_q3bsp_memory(m.data, m.size, path, opt, alloc, out, err);
    sl_file_unmap(&m);
    return st;
}
