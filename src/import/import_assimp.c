/* Import of any format assimp reads (OBJ, glTF 2.0/GLB, PLY, FBX, COLLADA, 3DS, ...).
 *
 * The node tree becomes the object list: every node that carries meshes is one object, its meshes
 * merged into one Sightline mesh. A set of meshes referenced by several nodes (glTF instancing,
 * COLLADA instance_geometry) stays one shared Sightline mesh with one transform per object; a set
 * used once has its world transform baked into the vertices, so that most objects keep the
 * identity transform the cullers like best.
 *
 * Coordinates: the file is taken as Y-up unless opt->up_axis says Z-up; Y-up is rotated +90°
 * about X, (x,y,z) -> (x,-z,y), and everything is multiplied by opt->unit_scale. Shared meshes
 * store B·v with B = rotation·scale, and their objects carry B·W·B⁻¹ (W the node's world
 * matrix), so that object transform · mesh vertex = B·W·v for both kinds. See
 * docs/import-export.md. */
#include "scene/scene_internal.h"
#include "source_meta.h"
#include "assimp_io.h"
#include "core/escape.h"
#include "split.h"
#include "import_isolate.h"
#include "sightline/import.h"

#include <assimp/cimport.h>
#include <assimp/metadata.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <assimp/version.h>

#include <ctype.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

/* A 3x4 row-major affine map in double precision (products of deep node chains stay accurate). */
typedef struct dmat { double m[12]; } dmat;

/* A node with meshes, found by the walk, in depth-first order. */
typedef struct node_rec {
    const struct aiNode *node;
    dmat world;                 /* node to file-root coordinates */
    uint32_t group;             /* mesh set it references */
    uint32_t index;             /* depth-first index among all nodes (for names) */
} node_rec;

/* A distinct set of aiMesh indices (a node's mMeshes list). */
typedef struct mesh_group {
    const unsigned int *meshes;
    uint32_t count;
    uint64_t hash;
    uint32_t refs;              /* nodes referencing the set */
    uint32_t first_mesh;        /* Sightline meshes built for a shared set (pieces when split) */
    uint32_t mesh_count;
    bool built;
} mesh_group;

typedef struct import_ctx {
    const char *path;
    const struct aiScene *ai;
    const sl_import_options *opt;
    const sl_allocator *a;
    sl_scene scene;
    dmat basis;                 /* B: up-axis rotation times unit scale */
    double scale;
    sl_array nodes;             /* node_rec */
    sl_array groups;            /* mesh_group */
    uint32_t *table;            /* open-addressing hash of groups, SL_NONE = empty */
    size_t table_cap;
    /* scratch for merging a node's meshes */
    sl_array pos, nrm;          /* float */
    sl_array idx;               /* uint32 */
    uint64_t triangles;         /* objects' triangles added so far */
} import_ctx;

/* ---- small matrix helpers ---- */

static dmat dmat_identity(void)
{
    dmat r = {{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0}};
    return r;
}

static dmat dmat_from_ai(const struct aiMatrix4x4 *t)
{
    dmat r = {{t->a1, t->a2, t->a3, t->a4, t->b1, t->b2, t->b3, t->b4, t->c1, t->c2, t->c3, t->c4}};
    return r;
}

/* a·b (apply b first). */
static dmat dmat_mul(const dmat *a, const dmat *b)
{
    dmat r;
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 4; j++) {
            double v = a->m[i * 4 + 0] * b->m[0 * 4 + j] + a->m[i * 4 + 1] * b->m[1 * 4 + j] + a->m[i * 4 + 2] * b->m[2 * 4 + j];
            r.m[i * 4 + j] = v + (j == 3 ? a->m[i * 4 + 3] : 0.0);
        }
    }
    return r;
}

static bool dmat_finite(const dmat *a)
{
    for (int i = 0; i < 12; i++)
        if (!isfinite(a->m[i]))
            return false;
    return true;
}

static double dmat_det3(const dmat *a)
{
    const double *m = a->m;
    return m[0] * (m[5] * m[10] - m[6] * m[9]) - m[1] * (m[4] * m[10] - m[6] * m[8]) + m[2] * (m[4] * m[9] - m[5] * m[8]);
}

/* Cofactor matrix of the linear part: maps normals (it is det · inverse-transpose, so it works for
 * singular matrices too; the caller fixes the sign for mirroring maps). */
static void dmat_cofactor3(const dmat *a, double c[9])
{
    const double *m = a->m;
    c[0] = m[5] * m[10] - m[6] * m[9];
    c[1] = m[6] * m[8] - m[4] * m[10];
    c[2] = m[4] * m[9] - m[5] * m[8];
    c[3] = m[2] * m[9] - m[1] * m[10];
    c[4] = m[0] * m[10] - m[2] * m[8];
    c[5] = m[1] * m[8] - m[0] * m[9];
    c[6] = m[1] * m[6] - m[2] * m[5];
    c[7] = m[2] * m[4] - m[0] * m[6];
    c[8] = m[0] * m[5] - m[1] * m[4];
}

/* ---- names and colours ---- */

/* "position.y is NaN" / "normal.x is +inf": the first non-finite component of v. */
static const char *nonfinite_component(const char *attribute, const struct aiVector3D *v, char *buf, size_t size)
{
    const float c[3] = {v->x, v->y, v->z};
    for (int i = 0; i < 3; i++)
        if (!isfinite(c[i])) {
            snprintf(buf, size, "%s.%c is %s", attribute, "xyz"[i], isnan(c[i]) ? "NaN" : c[i] > 0 ? "+inf" : "-inf");
            return buf;
        }
    snprintf(buf, size, "%s is not finite", attribute);
    return buf;
}

static const char *node_name(const struct aiNode *n) { return n->mName.length ? n->mName.data : "(unnamed)"; }

static void mesh_label(const struct aiScene *ai, unsigned int mi, char *buf, size_t size)
{
    const struct aiMesh *m = ai->mMeshes[mi];
    if (m->mName.length)
        snprintf(buf, size, "mesh '%.100s' (#%u)", m->mName.data, mi);
    else
        snprintf(buf, size, "mesh #%u", mi);
}

static uint8_t unit_to_byte(float v)
{
    if (!(v > 0))
        return 0;
    if (v >= 1)
        return 255;
    return (uint8_t)lrintf(v * 255.0f);
}

/* A pleasant, deterministic colour for a name: hue from its hash, fixed saturation and value. */
static uint32_t hash_color(const char *name, uint32_t index)
{
    uint64_t h = sl_hash64(name, strlen(name), 0x51647c1e0ull + index);
    float hue = (float)(h & 0xffff) / 65536.0f * 6.0f, s = 0.45f, v = 0.85f;
    int sector = (int)hue;
    float f = hue - (float)sector, p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
    float r, g, b;
    switch (sector % 6) {
    case 0: r = v, g = t, b = p; break;
    case 1: r = q, g = v, b = p; break;
    case 2: r = p, g = v, b = t; break;
    case 3: r = p, g = q, b = v; break;
    case 4: r = t, g = p, b = v; break;
    default: r = v, g = p, b = q; break;
    }
    return (uint32_t)unit_to_byte(r) << 24 | (uint32_t)unit_to_byte(g) << 16 | (uint32_t)unit_to_byte(b) << 8 | 0xffu;
}

/* Diffuse (or PBR base) colour of a material as 0xRRGGBBAA; false when the material has none or
 * is assimp's placeholder for files without materials. */
static bool material_color(const struct aiMaterial *mat, uint32_t *out)
{
    struct aiString name;
    if (aiGetMaterialString(mat, AI_MATKEY_NAME, &name) == aiReturn_SUCCESS && !strcmp(name.data, AI_DEFAULT_MATERIAL_NAME))
        return false;
    struct aiColor4D c;
    if (aiGetMaterialColor(mat, AI_MATKEY_COLOR_DIFFUSE, &c) != aiReturn_SUCCESS &&
        aiGetMaterialColor(mat, AI_MATKEY_BASE_COLOR, &c) != aiReturn_SUCCESS)
        return false;
    float alpha = c.a;
    ai_real opacity;
    if (aiGetMaterialFloatArray(mat, AI_MATKEY_OPACITY, &opacity, NULL) == aiReturn_SUCCESS && opacity < alpha)
        alpha = opacity;
    *out = (uint32_t)unit_to_byte(c.r) << 24 | (uint32_t)unit_to_byte(c.g) << 16 | (uint32_t)unit_to_byte(c.b) << 8 |
           unit_to_byte(alpha);
    return true;
}

/* Colour of a node: the material of its largest triangle mesh, else a hash of its name. */
static uint32_t node_color(const import_ctx *c, const node_rec *nr)
{
    const struct aiNode *n = nr->node;
    unsigned int best = UINT32_MAX, best_faces = 0;
    for (unsigned int i = 0; i < n->mNumMeshes; i++) {
        const struct aiMesh *m = c->ai->mMeshes[n->mMeshes[i]];
        if ((m->mPrimitiveTypes & aiPrimitiveType_TRIANGLE) && (best == UINT32_MAX || m->mNumFaces > best_faces))
            best = n->mMeshes[i], best_faces = m->mNumFaces;
    }
    uint32_t color;
    if (best != UINT32_MAX) {
        unsigned int mi = c->ai->mMeshes[best]->mMaterialIndex;
        if (mi < c->ai->mNumMaterials && c->ai->mMaterials[mi] && material_color(c->ai->mMaterials[mi], &color))
            return color;
    }
    return hash_color(n->mName.data, n->mName.length ? 0 : nr->index + 1);
}

/* ---- the node walk ---- */

static uint64_t group_hash(const unsigned int *meshes, uint32_t count)
{
    return sl_hash64(meshes, (size_t)count * sizeof *meshes, count);
}

/* Find or add the group of a mesh set. */
static sl_status group_of(import_ctx *c, const struct aiNode *n, uint32_t *out, sl_error *err)
{
    uint64_t h = group_hash(n->mMeshes, n->mNumMeshes);
    size_t mask = c->table_cap - 1;
    for (size_t slot = (size_t)h & mask;; slot = (slot + 1) & mask) {
        uint32_t g = c->table[slot];
        if (g == SL_NONE) {
            mesh_group rec = {n->mMeshes, n->mNumMeshes, h, 0, 0, 0, false};
            if (!sl_array_push(c->a, &c->groups, sizeof rec, &rec, 1))
                return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", c->path);
            c->table[slot] = (uint32_t)(c->groups.count - 1);
            *out = c->table[slot];
            return SL_OK;
        }
        const mesh_group *gr = &SL_AT(c->groups, mesh_group, g);
        if (gr->hash == h && gr->count == n->mNumMeshes && !memcmp(gr->meshes, n->mMeshes, (size_t)gr->count * sizeof *gr->meshes)) {
            *out = g;
            return SL_OK;
        }
    }
}

/* Depth-first walk with an explicit stack (hostile files may nest deeply); collects nodes with
 * meshes and their world matrices. */
static sl_status walk_nodes(import_ctx *c, sl_error *err)
{
    typedef struct walk_item { const struct aiNode *node; dmat parent; } walk_item;
    sl_array stack = {0};
    sl_status st = SL_OK;
    walk_item root = {c->ai->mRootNode, dmat_identity()};
    uint32_t visited = 0;
    if (!sl_array_push(c->a, &stack, sizeof root, &root, 1))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", c->path);
    while (stack.count) {
        walk_item it = SL_AT(stack, walk_item, stack.count - 1);
        stack.count--;
        const struct aiNode *n = it.node;
        if (++visited > (1u << 30)) {
            st = sl_fail(err, SL_ERROR_LIMIT, "%s: more than 2^30 nodes", c->path);
            break;
        }
        dmat local = dmat_from_ai(&n->mTransformation);
        dmat world = dmat_mul(&it.parent, &local);
        if (!dmat_finite(&world)) {
            st = sl_fail(err, SL_ERROR_FORMAT, "%s: node '%s': transform is not finite", c->path, node_name(n));
            break;
        }
        if (n->mNumMeshes) {
            for (unsigned int i = 0; i < n->mNumMeshes; i++)
                if (n->mMeshes[i] >= c->ai->mNumMeshes || !c->ai->mMeshes[n->mMeshes[i]]) {
                    st = sl_fail(err, SL_ERROR_FORMAT, "%s: node '%s': mesh index %u out of range (%u meshes)", c->path,
                                 node_name(n), n->mMeshes[i], c->ai->mNumMeshes);
                    goto out;
                }
            node_rec rec = {n, world, 0, visited - 1};
            if (!sl_array_push(c->a, &c->nodes, sizeof rec, &rec, 1)) {
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", c->path);
                break;
            }
        }
        /* push children in reverse so that they pop in file order */
        for (unsigned int i = n->mNumChildren; i-- > 0;) {
            if (!n->mChildren[i])
                continue;
            walk_item child = {n->mChildren[i], world};
            if (!sl_array_push(c->a, &stack, sizeof child, &child, 1)) {
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", c->path);
                goto out;
            }
        }
    }
out:
    sl_array_free(c->a, &stack, sizeof(walk_item));
    if (st != SL_OK)
        return st;

    /* group nodes by mesh set; the table is at least twice the node count, a power of two */
    size_t cap = 16;
    while (cap < 2 * c->nodes.count)
        cap *= 2;
    c->table = sl_alloc(c->a, cap * sizeof(uint32_t));
    if (!c->table)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory (%zu nodes)", c->path, c->nodes.count);
    c->table_cap = cap;
    for (size_t i = 0; i < cap; i++)
        c->table[i] = SL_NONE;
    for (size_t i = 0; i < c->nodes.count; i++) {
        node_rec *nr = &SL_AT(c->nodes, node_rec, i);
        if ((st = group_of(c, nr->node, &nr->group, err)) != SL_OK)
            return st;
        SL_AT(c->groups, mesh_group, nr->group).refs++;
    }
    return SL_OK;
}

/* ---- building meshes ---- */

/* Merge the triangle meshes of a node into the scratch arrays, mapped by m (positions) and its
 * cofactor (normals). Fails on non-finite input or output, naming the node and mesh. */
static sl_status merge_meshes(import_ctx *c, const node_rec *nr, const dmat *m, bool *has_normals, sl_error *err)
{
    const struct aiNode *n = nr->node;
    c->pos.count = c->nrm.count = c->idx.count = 0;
    double cof[9];
    dmat_cofactor3(m, cof);
    double det = dmat_det3(m);
    if (det < 0)
        for (int i = 0; i < 9; i++)
            cof[i] = -cof[i];
    bool normals = true;
    for (unsigned int k = 0; k < n->mNumMeshes; k++)
        if (!c->ai->mMeshes[n->mMeshes[k]]->mNormals)
            normals = false;
    uint64_t nv = 0;
    for (unsigned int k = 0; k < n->mNumMeshes; k++) {
        unsigned int mi = n->mMeshes[k];
        const struct aiMesh *am = c->ai->mMeshes[mi];
        if (!(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE) || !am->mNumFaces)
            continue;
        char label[160];
        if (nv + am->mNumVertices > UINT32_MAX) {
            mesh_label(c->ai, mi, label, sizeof label);
            return sl_fail(err, SL_ERROR_LIMIT, "%s: node '%s': more than 2^32-1 vertices (at %s)", c->path, node_name(n), label);
        }
        if (!am->mNumVertices || !am->mVertices || !am->mFaces) {
            mesh_label(c->ai, mi, label, sizeof label);
            return sl_fail(err, SL_ERROR_FORMAT, "%s: node '%s': %s has faces but no vertices", c->path, node_name(n), label);
        }
        uint32_t base = (uint32_t)nv;
        float *dp = sl_array_push(c->a, &c->pos, sizeof(float), NULL, 3 * (size_t)am->mNumVertices);
        float *dn = normals ? sl_array_push(c->a, &c->nrm, sizeof(float), NULL, 3 * (size_t)am->mNumVertices) : NULL;
        if (!dp || (normals && !dn))
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory (%u vertices)", c->path, am->mNumVertices);
        for (unsigned int v = 0; v < am->mNumVertices; v++) {
            const struct aiVector3D *p = &am->mVertices[v];
            if (!isfinite(p->x) || !isfinite(p->y) || !isfinite(p->z)) {
                char what[48];
                mesh_label(c->ai, mi, label, sizeof label);
                return sl_fail(err, SL_ERROR_FORMAT, "%s: node '%s': %s: vertex %u: %s (%g %g %g)", c->path, node_name(n), label,
                               v, nonfinite_component("position", p, what, sizeof what), (double)p->x, (double)p->y,
                               (double)p->z);
            }
            const double *r = m->m;
            for (int i = 0; i < 3; i++) {
                double w = r[i * 4] * p->x + r[i * 4 + 1] * p->y + r[i * 4 + 2] * p->z + r[i * 4 + 3];
                dp[3 * (size_t)v + i] = (float)w;
            }
            if (!sl_finite3(dp + 3 * (size_t)v)) {
                const float *q = dp + 3 * (size_t)v;
                struct aiVector3D w = {q[0], q[1], q[2]};
                char what[48];
                mesh_label(c->ai, mi, label, sizeof label);
                return sl_fail(err, SL_ERROR_FORMAT, "%s: node '%s': %s: vertex %u: %s after the node transform", c->path,
                               node_name(n), label, v, nonfinite_component("position", &w, what, sizeof what));
            }
            if (dn) {
                const struct aiVector3D *q = &am->mNormals[v];
                double w[3];
                for (int i = 0; i < 3; i++)
                    w[i] = cof[i * 3] * q->x + cof[i * 3 + 1] * q->y + cof[i * 3 + 2] * q->z;
                double l = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
                /* a degenerate normal (zero, NaN) becomes +z rather than failing the import */
                if (!(l > 0) || !isfinite(l))
                    w[0] = 0, w[1] = 0, w[2] = 1, l = 1;
                for (int i = 0; i < 3; i++)
                    dn[3 * (size_t)v + i] = (float)(w[i] / l);
            }
        }
        uint32_t *di = sl_array_push(c->a, &c->idx, sizeof(uint32_t), NULL, 3 * (size_t)am->mNumFaces);
        if (!di)
            return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory (%u faces)", c->path, am->mNumFaces);
        size_t kept = 0;
        for (unsigned int f = 0; f < am->mNumFaces; f++) {
            const struct aiFace *face = &am->mFaces[f];
            if (face->mNumIndices != 3)
                continue; /* SortByPType leaves none; a stray point or line is not a triangle */
            for (int j = 0; j < 3; j++) {
                unsigned int vi = face->mIndices[j];
                if (vi >= am->mNumVertices) {
                    mesh_label(c->ai, mi, label, sizeof label);
                    return sl_fail(err, SL_ERROR_FORMAT, "%s: node '%s': %s: face %u: index %u out of range (%u vertices)",
                                   c->path, node_name(n), label, f, vi, am->mNumVertices);
                }
            }
            /* a mirroring transform flips the winding back so that front faces stay front faces */
            uint32_t i0 = base + face->mIndices[0], i1 = base + face->mIndices[1], i2 = base + face->mIndices[2];
            di[kept++] = i0;
            di[kept++] = det < 0 ? i2 : i1;
            di[kept++] = det < 0 ? i1 : i2;
        }
        c->idx.count -= 3 * (size_t)am->mNumFaces - kept;
        nv += am->mNumVertices;
    }
    if (c->idx.count / 3 > UINT32_MAX)
        return sl_fail(err, SL_ERROR_LIMIT, "%s: node '%s': more than 2^32-1 triangles", c->path, node_name(n));
    *has_normals = normals;
    return SL_OK;
}

/* Add the merged scratch mesh to the scene, split into pieces when asked; the new meshes are
 * first..first+count-1. */
static sl_status add_meshes(import_ctx *c, const node_rec *nr, bool has_normals, uint32_t *first, uint32_t *count, sl_error *err)
{
    uint32_t nv = (uint32_t)(c->pos.count / 3), nt = (uint32_t)(c->idx.count / 3);
    const float *nrm = has_normals ? c->nrm.data : NULL;
    sl_status st;
    *first = sl_scene_mesh_count(c->scene);
    *count = 0;
    uint32_t target = c->opt->split_triangles;
    if (target == 0 || nt <= target) {
        sl_mesh_desc d = {c->pos.data, nrm, nv, c->idx.data, nt, NULL};
        if ((st = sl_scene_add_mesh(c->scene, &d, NULL, err)) != SL_OK) {
            sl_error_prefix(err, "%s: node '%s'", c->path, node_name(nr->node));
            return st;
        }
        *count = 1;
        return SL_OK;
    }
    sl_split_result r;
    if ((st = sl_split_mesh(c->pos.data, nrm, nv, c->idx.data, nt, target, c->a, &r, err)) != SL_OK) {
        sl_error_prefix(err, "%s: node '%s'", c->path, node_name(nr->node));
        return st;
    }
    for (uint32_t p = 0; p < r.piece_count; p++) {
        const sl_split_piece *pc = &r.pieces[p];
        sl_mesh_desc d = {r.positions + 3 * (size_t)pc->first_vertex, r.normals ? r.normals + 3 * (size_t)pc->first_vertex : NULL,
                          pc->vertex_count, r.indices + 3 * (size_t)pc->first_triangle, pc->triangle_count, NULL};
        if ((st = sl_scene_add_mesh(c->scene, &d, NULL, err)) != SL_OK) {
            sl_error_prefix(err, "%s: node '%s': piece %u", c->path, node_name(nr->node), p);
            sl_split_free(c->a, &r);
            return st;
        }
    }
    *count = r.piece_count;
    sl_split_free(c->a, &r);
    return SL_OK;
}

static sl_status add_objects(import_ctx *c, const node_rec *nr, uint32_t first, uint32_t count, const dmat *transform,
                             sl_error *err)
{
    sl_affine t;
    for (int i = 0; i < 12; i++)
        t.m[i] = (float)transform->m[i];
    uint32_t color = node_color(c, nr);
    for (uint32_t k = 0; k < count; k++) {
        sl_object_desc d = {first + k, &t, color, SL_KIND_IMPORTED, 0, 0};
        sl_status st = sl_scene_add_object(c->scene, &d, NULL, err);
        if (st != SL_OK) {
            sl_error_prefix(err, "%s: node '%s'", c->path, node_name(nr->node));
            return st;
        }
        c->triangles += sl_scene_mesh(c->scene, first + k).triangle_count;
    }
    return SL_OK;
}

/* One object (or one per piece) per node with meshes. */
static sl_status build_objects(import_ctx *c, sl_error *err)
{
    dmat basis_inv = dmat_identity();
    /* B = s·R with R a rotation, so B⁻¹ = Rᵀ/s = Bᵀ/s² */
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            basis_inv.m[i * 4 + j] = c->basis.m[j * 4 + i] / (c->scale * c->scale);
    sl_progress prog = c->opt->progress;
    for (size_t i = 0; i < c->nodes.count; i++) {
        if ((i & 255) == 0 && !sl_progress_report(&prog, "import: nodes", i, c->nodes.count))
            return sl_fail(err, SL_ERROR_CANCELLED, "%s: import cancelled", c->path);
        const node_rec *nr = &SL_AT(c->nodes, node_rec, i);
        mesh_group *g = &SL_AT(c->groups, mesh_group, nr->group);
        sl_status st;
        bool has_normals = false;
        if (g->refs == 1) {
            /* used once: bake B·W into the vertices, identity object transform */
            dmat m = dmat_mul(&c->basis, &nr->world);
            uint32_t first, count;
            if ((st = merge_meshes(c, nr, &m, &has_normals, err)) != SL_OK)
                return st;
            if (c->idx.count == 0)
                continue; /* only points or lines: nothing to see */
            if ((st = add_meshes(c, nr, has_normals, &first, &count, err)) != SL_OK)
                return st;
            dmat id = dmat_identity();
            if ((st = add_objects(c, nr, first, count, &id, err)) != SL_OK)
                return st;
            continue;
        }
        if (!g->built) {
            /* shared: the mesh stores B·v once, for every node that references the set */
            g->built = true;
            if ((st = merge_meshes(c, nr, &c->basis, &has_normals, err)) != SL_OK)
                return st;
            if (c->idx.count && (st = add_meshes(c, nr, has_normals, &g->first_mesh, &g->mesh_count, err)) != SL_OK)
                return st;
        }
        if (!g->mesh_count)
            continue;
        dmat bw = dmat_mul(&c->basis, &nr->world);
        dmat t = dmat_mul(&bw, &basis_inv);
        if ((st = add_objects(c, nr, g->first_mesh, g->mesh_count, &t, err)) != SL_OK)
            return st;
    }
    sl_progress_report(&prog, "import: nodes", c->nodes.count, c->nodes.count);
    return SL_OK;
}

/* The first node (depth-first) that references aiMesh mi, or NULL. */
static const struct aiNode *node_with_mesh(const struct aiScene *ai, unsigned int mi, const sl_allocator *a)
{
    sl_array stack = {0};
    const struct aiNode *found = NULL;
    if (!ai->mRootNode || !sl_array_push(a, &stack, sizeof ai->mRootNode, &ai->mRootNode, 1))
        return NULL;
    while (stack.count && !found) {
        const struct aiNode *n = SL_AT(stack, const struct aiNode *, --stack.count);
        for (unsigned int i = 0; i < n->mNumMeshes && !found; i++)
            if (n->mMeshes[i] == mi)
                found = n;
        for (unsigned int i = n->mNumChildren; i-- > 0 && !found;)
            if (n->mChildren[i] && !sl_array_push(a, &stack, sizeof n, &n->mChildren[i], 1))
                break;
    }
    sl_array_free(a, &stack, sizeof(const struct aiNode *));
    return found;
}

/* Reject non-finite vertex positions in the raw meshes, naming the node and the mesh. */
static sl_status check_finite(const char *path, const struct aiScene *ai, const sl_allocator *a, sl_error *err)
{
    for (unsigned int mi = 0; mi < ai->mNumMeshes; mi++) {
        const struct aiMesh *m = ai->mMeshes[mi];
        if (!m || !m->mVertices)
            continue;
        for (unsigned int v = 0; v < m->mNumVertices; v++) {
            const struct aiVector3D *p = &m->mVertices[v];
            if (isfinite(p->x) && isfinite(p->y) && isfinite(p->z))
                continue;
            char label[160], what[48];
            mesh_label(ai, mi, label, sizeof label);
            const struct aiNode *n = node_with_mesh(ai, mi, a);
            return sl_fail(err, SL_ERROR_FORMAT, "%s: node '%s': %s: vertex %u: %s (%g %g %g)", path, n ? node_name(n) : "(none)",
                           label, v, nonfinite_component("position", p, what, sizeof what), (double)p->x, (double)p->y,
                           (double)p->z);
        }
    }
    return SL_OK;
}

/* ---- PLY element counts, checked before assimp allocates for them ---- */

/* Smallest size of one value of a PLY scalar type, 0 for an unknown type. */
static unsigned ply_type_size(const char *t)
{
    static const struct { const char *name; unsigned size; } types[] = {
        {"char", 1},  {"int8", 1},   {"uchar", 1},  {"uint8", 1},   {"short", 2},   {"int16", 2},  {"ushort", 2},
        {"uint16", 2}, {"int", 4},   {"int32", 4},  {"uint", 4},    {"uint32", 4},  {"float", 4},  {"float32", 4},
        {"double", 8}, {"float64", 8},
    };
    for (size_t i = 0; i < SL_COUNTOF(types); i++)
        if (!strcmp(t, types[i].name))
            return types[i].size;
    return 0;
}

typedef struct ply_element {
    char name[64];
    uint64_t count;
    uint64_t min_bytes;         /* smallest encoding of one element */
} ply_element;

/* Check the element counts a PLY header declares against what the rest of the file can hold (an
 * element needs at least its scalar sizes and list counts in binary, two characters a value in
 * ASCII) and against the vertex limit of a mesh, so that a hostile header fails with the numbers
 * instead of std::bad_alloc. The header itself is checked strictly (known keywords and types, a
 * property after its element), since assimp 5.2 reads out of bounds on some malformed ones. Files
 * that are not PLY are left to assimp. */
static sl_status ply_check(const char *path, uint64_t file_size, const sl_allocator *a, sl_error *err)
{
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
    if (fd < 0)
        return SL_OK; /* assimp reports it */
    enum { HEADER_MAX = 1 << 20 };
    char *buf = sl_alloc(a, HEADER_MAX + 1);
    if (!buf) {
        close(fd);
        return SL_OK;
    }
    size_t n = 0;
    while (n < HEADER_MAX) {
        ssize_t r = read(fd, buf + n, HEADER_MAX - n);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            break;
        n += (size_t)r;
        if (n >= 3 && strncasecmp(buf, "ply", 3) != 0)
            break;
        if (memmem(buf, n, "end_header", 10))
            break;
    }
    close(fd);
    buf[n] = 0;
    sl_status st = SL_OK;
    /* assimp's PLY reader takes any file starting with "ply" in any case ("Ply" too: a fuzzed
     * "Ply" header without end_header made assimp 5.2 loop for ever) */
    if (n < 3 || strncasecmp(buf, "ply", 3) != 0)
        goto done;
    bool binary = false, have_format = false;
    ply_element el[64];
    uint32_t ne = 0, line_no = 1;
    size_t header_end = 0;
    const char *bad = NULL; /* what is wrong with line line_no (never the file's own text) */
    for (char *line = buf; line < buf + n; line_no++) {
        char *eol = memchr(line, '\n', (size_t)(buf + n - line));
        if (!eol)
            break; /* no end_header: below */
        *eol = 0;
        char *save = NULL, *kw = strtok_r(line, " \t\r", &save);
        char *next = eol + 1;
        line = next;
        if (line_no == 1) {
            if (!kw || strcasecmp(kw, "ply") || strtok_r(NULL, " \t\r", &save)) {
                bad = "the first line must be 'ply'";
                break;
            }
            continue;
        }
        if (!kw || !strcmp(kw, "comment") || !strcmp(kw, "obj_info"))
            continue;
        if (!strcmp(kw, "end_header")) {
            header_end = (size_t)(next - buf);
            break;
        }
        if (!strcmp(kw, "format")) {
            const char *f = strtok_r(NULL, " \t\r", &save);
            if (!f || (strcmp(f, "ascii") && strcmp(f, "binary_little_endian") && strcmp(f, "binary_big_endian")))
                bad = "unknown format (ascii, binary_little_endian or binary_big_endian)";
            binary = f && strcmp(f, "ascii") != 0;
            have_format = true;
        } else if (!strcmp(kw, "element")) {
            const char *name = strtok_r(NULL, " \t\r", &save), *count = strtok_r(NULL, " \t\r", &save);
            char *end;
            errno = 0;
            unsigned long long v = count ? strtoull(count, &end, 10) : 0;
            if (!name || !count || *end || errno || count[0] == '-' || count[0] == '+') {
                bad = "element needs a name and a count";
            } else if (ne == SL_COUNTOF(el)) {
                bad = "more than 64 elements";
            } else {
                snprintf(el[ne].name, sizeof el[ne].name, "%s", name);
                el[ne].count = v;
                el[ne].min_bytes = 0;
                ne++;
            }
        } else if (!strcmp(kw, "property")) {
            const char *t = strtok_r(NULL, " \t\r", &save);
            unsigned size = 0;
            if (t && !strcmp(t, "list")) {
                const char *ct = strtok_r(NULL, " \t\r", &save), *it = strtok_r(NULL, " \t\r", &save);
                size = ct && it && ply_type_size(it) ? ply_type_size(ct) : 0; /* the count; a list may be empty */
            } else if (t) {
                size = ply_type_size(t);
            }
            if (!ne)
                bad = "property before any element";
            else if (!size || !strtok_r(NULL, " \t\r", &save))
                bad = "property needs a known type and a name";
            else
                el[ne - 1].min_bytes += binary ? size : 2;
        } else {
            /* assimp skips header lines it does not know (Blender 2.47 wrote a bare "Created by
             * Blender3D ..." line, e.g. assimp-testmodels' Wuson.ply): so do we, when they are text */
            for (const char *c = kw; c < eol && !bad; c++)
                if (*c && (*c < 0x20 || *c > 0x7e) && *c != '\t' && *c != '\r')
                    bad = "unknown keyword in a line that is not text";
        }
        if (bad)
            break;
    }
    if (!bad && !header_end) /* assimp 5.2 loops for ever on such a file (fuzz/fuzz_assimp.c) */
        bad = n >= HEADER_MAX ? "no end_header in the first MiB" : "no end_header before the end of the file";
    if (!bad && !have_format)
        bad = "no format line", line_no = 2;
    if (bad) {
        /* assimp 5.2 reads past its buffers on some malformed headers (found by fuzz/fuzz_assimp.c) */
        st = sl_fail(err, SL_ERROR_FORMAT, "%s: PLY header line %u: %s", path, line_no, bad);
        goto done;
    }
    uint64_t left = file_size > header_end ? file_size - header_end : 0, need = 0;
    for (uint32_t i = 0; i < ne; i++) {
        char name[100];
        sl_escape_text(el[i].name, 60, name, sizeof name);
        if (!strcmp(el[i].name, "vertex") && el[i].count > UINT32_MAX) {
            st = sl_fail(err, SL_ERROR_LIMIT, "%s: element vertex: %llu declared, more than the 2^32-1 vertices a mesh can hold",
                         path, (unsigned long long)el[i].count);
            goto done;
        }
        uint64_t each = el[i].min_bytes ? el[i].min_bytes : 1;
        uint64_t room = left > need ? (left - need) / each : 0;
        if (el[i].count > room) {
            st = sl_fail(err, SL_ERROR_FORMAT,
                         "%s: element %s: %llu declared, the file can hold at most %llu (%llu bytes after the header, at least "
                         "%llu bytes each%s)",
                         path, name, (unsigned long long)el[i].count, (unsigned long long)room, (unsigned long long)left,
                         (unsigned long long)each, i ? ", after the elements before it" : "");
            goto done;
        }
        need += el[i].count * each;
    }
done:
    sl_free(a, buf, HEADER_MAX + 1);
    return st;
}

/* ---- assimp's messages ---- */

/* An import failure with assimp's reason, escaped and cut short: assimp quotes tokens of the file
 * in some messages, and the file is untrusted. std::bad_alloc is said as what it is. */
static sl_status assimp_failure(const char *path, sl_error *err)
{
    const char *msg = aiGetErrorString();
    if (!msg || !msg[0])
        return sl_fail(err, SL_ERROR_FORMAT, "%s: assimp could not read the file", path);
    if (strstr(msg, "bad_alloc"))
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: assimp ran out of memory reading the file (std::bad_alloc)", path);
    char safe[300];
    sl_escape_text(msg, 200, safe, sizeof safe);
    return sl_fail(err, SL_ERROR_FORMAT, "%s: %s", path, safe);
}

/* Every face has indices, and every index names a vertex of its mesh. */
static sl_status check_faces(const char *path, const struct aiScene *ai, sl_error *err)
{
    for (unsigned int mi = 0; mi < ai->mNumMeshes; mi++) {
        const struct aiMesh *m = ai->mMeshes[mi];
        if (!m || !m->mNumFaces)
            continue;
        char label[160];
        if (!m->mFaces) {
            mesh_label(ai, mi, label, sizeof label);
            return sl_fail(err, SL_ERROR_FORMAT, "%s: %s: %u faces but no face array", path, label, m->mNumFaces);
        }
        for (unsigned int f = 0; f < m->mNumFaces; f++) {
            const struct aiFace *face = &m->mFaces[f];
            if (!face->mNumIndices || !face->mIndices) {
                mesh_label(ai, mi, label, sizeof label);
                return sl_fail(err, SL_ERROR_FORMAT, "%s: %s: face %u has no vertex indices", path, label, f);
            }
            for (unsigned int k = 0; k < face->mNumIndices; k++)
                if (face->mIndices[k] >= m->mNumVertices) {
                    mesh_label(ai, mi, label, sizeof label);
                    return sl_fail(err, SL_ERROR_FORMAT, "%s: %s: face %u: index %u out of range (%u vertices)", path, label,
                                   f, face->mIndices[k], m->mNumVertices);
                }
        }
    }
    return SL_OK;
}

/* ---- entry point ---- */

/* Lowercase extension of a path (without the dot) into buf; "" when there is none. */
static void path_extension(const char *path, char *buf, size_t size)
{
    const char *slash = strrchr(path, '/'), *dot = strrchr(path, '.');
    buf[0] = 0;
    if (!dot || (slash && dot < slash) || !dot[1])
        return;
    size_t k = 0;
    for (const char *p = dot + 1; *p && k + 1 < size; p++)
        buf[k++] = (char)tolower((unsigned char)*p);
    buf[k] = 0;
}

/* A string entry of the file's scene metadata (SourceAsset_Format ...), or NULL. */
static const char *scene_meta_string(const struct aiScene *ai, const char *key)
{
    const struct aiMetadata *md = ai->mMetaData;
    if (!md || !md->mKeys || !md->mValues)
        return NULL;
    for (unsigned int i = 0; i < md->mNumProperties; i++)
        if (!strcmp(md->mKeys[i].data, key) && md->mValues[i].mType == AI_AISTRING && md->mValues[i].mData)
            return ((const struct aiString *)md->mValues[i].mData)->data;
    return NULL;
}

static sl_status set_metadata(import_ctx *c, sl_error *err)
{
    /* "gltf (glTF2 Importer 2.0)": the extension, and the importer assimp actually used (the
     * extension alone cannot tell glTF 1 from glTF 2) with the format version when it says */
    char ext[32], buf[200];
    path_extension(c->path, ext, sizeof ext);
    const char *importer = scene_meta_string(c->ai, "SourceAsset_Format");
    const char *version = scene_meta_string(c->ai, "SourceAsset_FormatVersion");
    const char *generator = scene_meta_string(c->ai, "SourceAsset_Generator");
    if (importer)
        snprintf(buf, sizeof buf, "%.16s (%.100s%s%.20s)", ext[0] ? ext : "?", importer, version ? " " : "", version ? version : "");
    else
        snprintf(buf, sizeof buf, "%s", ext[0] ? ext : "unknown");
    char assimp_version[32], scale[32];
    snprintf(assimp_version, sizeof assimp_version, "%u.%u.%u", aiGetVersionMajor(), aiGetVersionMinor(),
             aiGetVersionPatch());
    snprintf(scale, sizeof scale, "%.9g", c->scale);
    sl_status st;
    if ((st = sl_scene_set_source_file(c->scene, c->path, err)) != SL_OK ||
        (st = sl_scene_set_meta(c->scene, "importer", "assimp", err)) != SL_OK ||
        (st = sl_scene_set_meta(c->scene, "assimp.version", assimp_version, err)) != SL_OK ||
        (st = sl_scene_set_meta(c->scene, "assimp.format", buf, err)) != SL_OK ||
        (st = sl_scene_set_meta(c->scene, "assimp.up_axis", c->opt->up_axis == SL_UP_Z ? "z" : "y", err)) != SL_OK ||
        (st = sl_scene_set_meta(c->scene, "assimp.unit_scale", scale, err)) != SL_OK)
        return st;
    if (generator && generator[0] && (st = sl_scene_set_meta(c->scene, "assimp.generator", generator, err)) != SL_OK)
        return st;
    if (c->opt->split_triangles) {
        snprintf(buf, sizeof buf, "%u", c->opt->split_triangles);
        if ((st = sl_scene_set_meta(c->scene, "assimp.split_triangles", buf, err)) != SL_OK)
            return st;
    }
    return SL_OK;
}

/* The import itself, in this process: sl_import_assimp calls it here or in a child process
 * (import_isolate.c). */
sl_status sl_import_assimp_check(const char *path, const sl_import_options *opt, const sl_allocator *alloc, sl_error *err)
{
    if (opt->up_axis != SL_UP_Y && opt->up_axis != SL_UP_Z)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_import_assimp: bad up axis %d", (int)opt->up_axis);
    if (!isfinite(opt->unit_scale) || opt->unit_scale < 0)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_import_assimp: unit scale %g must be positive", (double)opt->unit_scale);

    /* assimp's own message for a missing file is vague; say what is wrong first */
    struct stat sb;
    if (stat(path, &sb) != 0)
        return sl_fail(err, errno == ENOENT ? SL_ERROR_NOT_FOUND : SL_ERROR_IO, "%s: cannot open: %s", path, strerror(errno));
    if (!S_ISREG(sb.st_mode))
        return sl_fail(err, SL_ERROR_IO, "%s: not a regular file (%s)", path, sl_file_kind_name(sb.st_mode));
    uint64_t max_file = opt->max_file_bytes ? opt->max_file_bytes : SL_ASSIMP_MAX_FILE_BYTES;
    if ((uint64_t)sb.st_size > max_file)
        return sl_fail(err, SL_ERROR_LIMIT, "%s: %llu bytes, more than the limit of %llu", path, (unsigned long long)sb.st_size,
                       (unsigned long long)max_file);

    return ply_check(path, (uint64_t)sb.st_size, sl_alloc_or_default(alloc), err);
}

sl_status sl_import_assimp_in_process(const char *path, const sl_import_options *opt, const sl_allocator *alloc,
                                      sl_scene *out, sl_error *err)
{
    if (!path || !out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_import_assimp: NULL argument");
    *out = NULL;
    sl_import_options defaults;
    memset(&defaults, 0, sizeof defaults);
    if (!opt)
        opt = &defaults;
    sl_status st = sl_import_assimp_check(path, opt, alloc, err);
    if (st != SL_OK)
        return st;
    return sl_import_assimp_checked(path, opt, alloc, out, err);
}

sl_status sl_import_assimp_checked(const char *path, const sl_import_options *opt, const sl_allocator *alloc,
                                   sl_scene *out, sl_error *err)
{
    *out = NULL;
    sl_status st;
    const sl_allocator *a = sl_alloc_or_default(alloc);
    uint64_t max_file = opt->max_file_bytes ? opt->max_file_bytes : SL_ASSIMP_MAX_FILE_BYTES;
    import_ctx c;
    memset(&c, 0, sizeof c);
    c.path = path;
    c.opt = opt;
    c.a = a;
    c.scale = opt->unit_scale > 0 ? opt->unit_scale : 1.0;
    c.basis = dmat_identity();
    if (opt->up_axis == SL_UP_Y) {
        /* +90° about X: (x,y,z) -> (x,-z,y) */
        dmat r = {{1, 0, 0, 0, 0, 0, -1, 0, 0, 1, 0, 0}};
        c.basis = r;
    }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            c.basis.m[i * 4 + j] *= c.scale;

    sl_progress prog = opt->progress;
    if (!sl_progress_report(&prog, "import: reading", 0, 1))
        return sl_fail(err, SL_ERROR_CANCELLED, "%s: import cancelled", path);

    /* Triangulate polygons, share identical vertices, drop point and line primitives, drop what
     * culling never reads (texture coordinates, colours, tangents, bones, animations, textures,
     * lights, cameras) so that more vertices join, and validate what the importer produced.
     * Normals: the file's own where it has them; otherwise sl_scene_add_mesh computes
     * area-weighted vertex normals after the join. assimp's GenSmoothNormals would do the same
     * with an angle limit, but costs ~5 s per million triangles (SpatialSort over unjoined
     * vertices, measured on a 980k-triangle OBJ: 7.2 s of post-processing with it, 2.4 s
     * without). */
    /* every file assimp opens, the model included, goes through the confined IO system */
    sl_aio *io = sl_alloc(a, sizeof *io);
    if (!io)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    if ((st = sl_aio_init(io, path, opt->allow_external, opt->allow_external_count, max_file, a, err)) != SL_OK) {
        sl_free(a, io, sizeof *io);
        return st;
    }
    struct aiPropertyStore *props = aiCreatePropertyStore();
    if (!props) {
        sl_aio_free(io);
        sl_free(a, io, sizeof *io);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    }
    aiSetImportPropertyInteger(props, AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
    aiSetImportPropertyInteger(props, AI_CONFIG_PP_RVC_FLAGS,
                               aiComponent_TEXCOORDS | aiComponent_COLORS | aiComponent_TANGENTS_AND_BITANGENTS |
                                   aiComponent_BONEWEIGHTS | aiComponent_ANIMATIONS | aiComponent_TEXTURES | aiComponent_LIGHTS |
                                   aiComponent_CAMERAS);
    /* read and validate first, without post-processing: JoinIdenticalVertices would merge a NaN
     * vertex into a finite one and hide it */
    const struct aiScene *ai = aiImportFileExWithProperties(path, aiProcess_ValidateDataStructure, &io->io, props);
    aiReleasePropertyStore(props);
    /* a refused reference fails the import even where assimp carried on without it (a missing
     * OBJ material library is only a warning to assimp) */
    if (io->refused) {
        char shown[200];
        st = sl_fail(err, io->refused_status, "%s: %s", sl_escape_text(path, 150, shown, sizeof shown), io->refused_message);
    } else if (!ai) {
        st = assimp_failure(path, err);
    }
    sl_aio_free(io);
    sl_free(a, io, sizeof *io);
    if (st != SL_OK) {
        if (ai)
            aiReleaseImport(ai);
        return st;
    }
    if ((st = check_finite(path, ai, a, err)) != SL_OK) {
        aiReleaseImport(ai);
        return st;
    }
    /* assimp 5.2 frees the scene twice when a post-processing step fails (aiApplyPostProcessing
     * releases what the failed step already deleted), so rule out the one failure valid input
     * can cause: SortByPType removing every mesh because none has triangles or polygons */
    bool any_faces = false;
    for (unsigned int mi = 0; mi < ai->mNumMeshes && !any_faces; mi++)
        any_faces = ai->mMeshes[mi] && ai->mMeshes[mi]->mNumFaces &&
                    (ai->mMeshes[mi]->mPrimitiveTypes & (aiPrimitiveType_TRIANGLE | aiPrimitiveType_POLYGON));
    if (!any_faces) {
        st = sl_fail(err, SL_ERROR_FORMAT, "%s: no triangles (%u meshes, only points and lines)", path, ai->mNumMeshes);
        aiReleaseImport(ai);
        return st;
    }
    /* ... and the faces that pass the first validation but fail the one after post-processing
     * (double free, found by fuzz/fuzz_assimp.c): a face without indices, an index past the
     * vertices */
    if ((st = check_faces(path, ai, err)) != SL_OK) {
        aiReleaseImport(ai);
        return st;
    }
    unsigned int flags = aiProcess_RemoveComponent | aiProcess_Triangulate | aiProcess_JoinIdenticalVertices |
                         aiProcess_SortByPType | aiProcess_ValidateDataStructure;
    /* on failure assimp releases the scene itself */
    ai = aiApplyPostProcessing(ai, flags);
    if (!ai)
        return sl_fail(err, SL_ERROR_FORMAT, "%s: assimp post-processing failed (triangulation or validation)", path);
    c.ai = ai;
    sl_progress_report(&prog, "import: reading", 1, 1);
    if (!ai->mRootNode) {
        st = sl_fail(err, SL_ERROR_FORMAT, "%s: no triangles (the file has no scene graph)", path);
        goto fail;
    }
    if ((st = sl_scene_create(a, &c.scene, err)) != SL_OK)
        goto fail;
    if ((st = walk_nodes(&c, err)) != SL_OK || (st = build_objects(&c, err)) != SL_OK)
        goto fail;
    if (c.triangles == 0) {
        st = sl_fail(err, SL_ERROR_FORMAT, "%s: no triangles (%u meshes, none with triangles reachable from the root node)", path,
                     ai->mNumMeshes);
        goto fail;
    }
    if ((st = set_metadata(&c, err)) != SL_OK)
        goto fail;
    *out = c.scene;
    c.scene = NULL;
fail:
    aiReleaseImport(ai);
    sl_scene_destroy(c.scene);
    sl_array_free(a, &c.nodes, sizeof(node_rec));
    sl_array_free(a, &c.groups, sizeof(mesh_group));
    sl_free(a, c.table, c.table_cap * sizeof(uint32_t));
    sl_array_free(a, &c.pos, sizeof(float));
    sl_array_free(a, &c.nrm, sizeof(float));
    sl_array_free(a, &c.idx, sizeof(uint32_t));
    return st;
}
