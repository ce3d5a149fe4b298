/* Export of a scene through assimp (OBJ, glTF 2.0, GLB, PLY, STL, COLLADA, FBX, ...).
 *
 * The aiScene is built in memory by hand: one root node, one child node per object carrying the
 * object's transform, one aiMesh per (Sightline mesh, colour) pair so that instanced meshes stay
 * shared, and one material per distinct colour. Every block of it comes from an arena on the
 * scene's allocator and is released here; assimp only reads it (its exporter works on a copy),
 * so aiReleaseImport must never see it.
 *
 * Output is atomic even though assimp writes the files itself: it is handed a custom aiFileIO
 * whose files are sl_atomic temporaries. Side files (OBJ's .mtl, glTF's .bin) are opened by
 * assimp under their final names, so the references inside the main file are right; nothing is
 * renamed into place until the exporter has succeeded, side files go first and the main file
 * last, and on any failure every temporary (and any side file already moved) is removed. */
#include "scene/scene_internal.h"
#include "sightline/import.h"

#include <assimp/cexport.h>
#include <assimp/cfileio.h>
#include <assimp/material.h>
#include <assimp/scene.h>
#include <assimp/version.h>

#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <sys/stat.h>
#include <unistd.h>

/* The first element of an AI_MATKEY_* triple ("key", type, index). */
#define SL_MATKEY_(key, type, index) key
#define SL_MATKEY(...) SL_MATKEY_(__VA_ARGS__)

/* ---- an arena for the aiScene: every block is recorded and freed together ---- */

typedef struct arena_block { void *p; size_t size; } arena_block;
typedef struct arena {
    const sl_allocator *a;
    sl_array blocks;            /* arena_block */
} arena;

static void *arena_calloc(arena *ar, size_t n, size_t size)
{
    size_t bytes;
    if (!sl_mul_size(n, size, &bytes))
        return NULL;
    if (bytes == 0)
        bytes = 1;
    void *p = sl_calloc(ar->a, 1, bytes);
    if (!p)
        return NULL;
    arena_block b = {p, bytes};
    if (!sl_array_push(ar->a, &ar->blocks, sizeof b, &b, 1)) {
        sl_free(ar->a, p, bytes);
        return NULL;
    }
    return p;
}

static void arena_free(arena *ar)
{
    for (size_t i = 0; i < ar->blocks.count; i++) {
        arena_block *b = &SL_AT(ar->blocks, arena_block, i);
        sl_free(ar->a, b->p, b->size);
    }
    sl_array_free(ar->a, &ar->blocks, sizeof(arena_block));
}

/* ---- formats ---- */

/* Export ids assimp lists that cannot honour the no-partial-output rule or do not work. */
static const struct { const char *id, *why; } refused_formats[] = {
    {"3mf", "assimp's 3MF exporter writes its zip archive directly, bypassing the atomic writer"},
    {"pbrt", "assimp 5.2's pbrt exporter crashes on scenes without a camera"},
};

static const char *refused_reason(const char *id)
{
    for (size_t i = 0; i < SL_COUNTOF(refused_formats); i++)
        if (!strcmp(refused_formats[i].id, id))
            return refused_formats[i].why;
    return NULL;
}

/* Resolve the export id: the given one (checked against assimp's list) or the one for the path's
 * extension (.gltf means glTF 2.0 text, .glb binary glTF 2.0). */
static sl_status resolve_format(const char *path, const char *format, char *id, size_t size, sl_error *err)
{
    char ext[32] = "";
    if (!format) {
        const char *slash = strrchr(path, '/'), *dot = strrchr(path, '.');
        if (dot && (!slash || dot > slash) && dot[1]) {
            size_t k = 0;
            for (const char *p = dot + 1; *p && k + 1 < sizeof ext; p++)
                ext[k++] = (char)tolower((unsigned char)*p);
            ext[k] = 0;
        }
        if (!ext[0])
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: no file extension to choose the export format from; name one", path);
        if (!strcmp(ext, "gltf"))
            format = "gltf2";
        else if (!strcmp(ext, "glb"))
            format = "glb2";
    }
    bool found = false;
    size_t n = aiGetExportFormatCount();
    for (size_t i = 0; i < n && !found; i++) {
        const struct aiExportFormatDesc *d = aiGetExportFormatDescription(i);
        if (!d)
            continue;
        const char *cand = format ? d->id : d->fileExtension;
        if (cand && !strcmp(cand, format ? format : ext)) {
            snprintf(id, size, "%s", d->id);
            found = true;
        }
        aiReleaseExportFormatDescription(d);
    }
    if (!found) {
        if (format)
            return sl_fail(err, SL_ERROR_NOT_FOUND, "%s: unknown export format '%s' (sightline export --list-formats)", path, format);
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "%s: no assimp exporter writes .%s files (sightline export --list-formats)", path,
                       ext);
    }
    const char *why = refused_reason(id);
    if (why)
        return sl_fail(err, SL_ERROR_UNSUPPORTED, "%s: export format '%s' is not supported: %s", path, id, why);
    return SL_OK;
}

/* ---- the same bytes for the same scene ---- */

/* Overwrite the n bytes after the first `key` in [p, end) with `value` when they are exactly n
 * characters of [0-9:T-] (a COLLADA xs:dateTime). */
static void replace_date(uint8_t *p, size_t size, const char *key, const char *value)
{
    size_t kl = strlen(key), vl = strlen(value);
    uint8_t *at = memmem(p, size, key, kl);
    if (!at || (size_t)(at - p) + kl + vl > size)
        return;
    uint8_t *v = at + kl;
    for (size_t i = 0; i < vl; i++)
        if (!isdigit(v[i]) && v[i] != '-' && v[i] != ':' && v[i] != 'T')
            return;
    memcpy(v, value, vl);
}

/* COLLADA and FBX files carry the time they were written (<created>/<modified>; FBX's
 * CreationTimeStamp Year..Millisecond): replaced by 1970-01-01 00:00:00, in place and at the same
 * length, so that exporting the same scene twice gives the same bytes. FBX's FileId and
 * CreationTime are constants in assimp 5.2 already. */
static void normalize_timestamps(const char *format, const sl_allocator *a, sl_array *mem)
{
    uint8_t *p = mem->data;
    size_t size = mem->count;
    if (!p)
        return;
    if (!strcmp(format, "collada")) {
        replace_date(p, size, "<created>", "1970-01-01T00:00:00");
        replace_date(p, size, "<modified>", "1970-01-01T00:00:00");
        return;
    }
    static const struct { const char *name; int32_t value; } fields[] = {
        {"Year", 1970}, {"Month", 1}, {"Day", 1}, {"Hour", 0}, {"Minute", 0}, {"Second", 0}, {"Millisecond", 0},
    };
    uint8_t *ts = memmem(p, size, "CreationTimeStamp", 17);
    if (!ts)
        return;
    size_t left = size - (size_t)(ts - p);
    size_t window = SL_MIN(left, (size_t)1024); /* the node's children follow at once */
    if (!strcmp(format, "fbx")) {
        /* binary: each child is a node record ending in its name (length byte, name) followed by
         * one property of type 'I' (int32, little-endian) */
        for (size_t k = 0; k < SL_COUNTOF(fields); k++) {
            size_t nl = strlen(fields[k].name);
            for (size_t i = 1; i + nl + 5 <= window; i++)
                if (ts[i - 1] == nl && !memcmp(ts + i, fields[k].name, nl) && ts[i + nl] == 'I') {
                    uint32_t v = (uint32_t)fields[k].value;
                    uint8_t le[4] = {(uint8_t)v, (uint8_t)(v >> 8), (uint8_t)(v >> 16), (uint8_t)(v >> 24)};
                    memcpy(ts + i + nl + 1, le, 4);
                    break;
                }
        }
        return;
    }
    /* ASCII FBX: "Name: digits" lines, the digits replaced (the length may change: nothing in
     * an ASCII FBX file points at byte offsets); a value that cannot shrink in place is left as is
     * unless the array can grow */
    size_t ts_at = (size_t)(ts - p);
    for (size_t k = 0; k < SL_COUNTOF(fields); k++) {
        char key[24], digits[16];
        snprintf(key, sizeof key, "\t%s: ", fields[k].name);
        size_t kl = strlen(key);
        p = mem->data;
        size_t win = SL_MIN(mem->count - ts_at, (size_t)1024);
        uint8_t *at = memmem(p + ts_at, win, key, kl);
        if (!at)
            continue;
        size_t v = (size_t)(at - p) + kl, e = v;
        while (e < mem->count && isdigit(p[e]))
            e++;
        size_t width = e - v, dl = (size_t)snprintf(digits, sizeof digits, "%d", (int)fields[k].value);
        if (!width)
            continue;
        if (dl > width) {
            if (!sl_array_push(a, mem, 1, NULL, dl - width))
                continue;
            p = mem->data;
            memmove(p + v + dl, p + e, mem->count - (dl - width) - e);
        } else if (dl < width) {
            memmove(p + v + dl, p + e, mem->count - e);
            mem->count -= width - dl;
        }
        memcpy(p + v, digits, dl);
    }
}

/* ---- file output through sl_atomic ---- */

typedef struct out_file {
    struct aiFile file;         /* handed to assimp; file.UserData points back here */
    sl_atomic_file af;
    bool committed;
    int errnum;                 /* errno of the first failed write, 0 if none */
    /* COLLADA and FBX are held in memory and written on commit, once the time of writing that
     * assimp puts into them has been replaced by a fixed one (normalize_timestamps) */
    bool buffered;
    const sl_allocator *alloc;
    sl_array mem;               /* uint8_t */
    size_t pos;
} out_file;

typedef struct export_io {
    struct aiFileIO io;         /* io.UserData points back here */
    const sl_allocator *a;
    const char *format;         /* assimp export id */
    sl_array files;             /* out_file *, in the order assimp opened them */
    sl_error err;               /* first failure seen inside a callback */
    bool failed;
} export_io;

static out_file *file_of(struct aiFile *f) { return (out_file *)(void *)f->UserData; }

static void write_failed(out_file *of, int e)
{
    if (!of->errnum)
        of->errnum = e ? e : EIO;
    of->af.failed = true;
}

static size_t io_write(struct aiFile *f, const char *buf, size_t size, size_t count)
{
    out_file *of = file_of(f);
    if (of->af.failed || !size || !count)
        return 0;
    if (of->buffered) {
        size_t bytes, end;
        if (!sl_mul_size(size, count, &bytes) || !sl_add_size(of->pos, bytes, &end)) {
            write_failed(of, EFBIG);
            return 0;
        }
        if (end > of->mem.count && !sl_array_push(of->alloc, &of->mem, 1, NULL, end - of->mem.count)) {
            write_failed(of, ENOMEM);
            return 0;
        }
        memcpy((uint8_t *)of->mem.data + of->pos, buf, bytes);
        of->pos = end;
        return count;
    }
    errno = 0;
    size_t n = fwrite(buf, size, count, of->af.fp);
    if (n != count)
        write_failed(of, errno);
    return n;
}

static size_t io_read(struct aiFile *f, char *buf, size_t size, size_t count)
{
    (void)f, (void)buf, (void)size, (void)count;
    return 0; /* output files are never read back */
}

static size_t io_tell(struct aiFile *f)
{
    out_file *of = file_of(f);
    if (of->buffered)
        return of->pos;
    long p = ftell(of->af.fp);
    return p < 0 ? 0 : (size_t)p;
}

static size_t io_size(struct aiFile *f)
{
    out_file *of = file_of(f);
    if (of->buffered)
        return of->mem.count;
    struct stat st;
    errno = 0;
    if (fflush(of->af.fp) != 0 || fstat(fileno(of->af.fp), &st) != 0) {
        write_failed(of, errno);
        return 0;
    }
    return (size_t)st.st_size;
}

static enum aiReturn io_seek(struct aiFile *f, size_t offset, enum aiOrigin origin)
{
    out_file *of = file_of(f);
    if (of->buffered) {
        size_t base = origin == aiOrigin_SET ? 0 : origin == aiOrigin_CUR ? of->pos : of->mem.count;
        size_t target = base + offset; /* negative offsets arrive wrapped around */
        if (target > of->mem.count)
            return aiReturn_FAILURE;
        of->pos = target;
        return aiReturn_SUCCESS;
    }
    int whence = origin == aiOrigin_SET ? SEEK_SET : origin == aiOrigin_CUR ? SEEK_CUR : SEEK_END;
    if (offset > (size_t)LONG_MAX || fseek(of->af.fp, (long)offset, whence) != 0)
        return aiReturn_FAILURE;
    return aiReturn_SUCCESS;
}

static void io_flush(struct aiFile *f)
{
    out_file *of = file_of(f);
    errno = 0;
    if (!of->buffered && fflush(of->af.fp) != 0)
        write_failed(of, errno);
}

static struct aiFile *io_open(struct aiFileIO *io, const char *name, const char *mode)
{
    export_io *x = (export_io *)(void *)io->UserData;
    /* an existence probe ("rb") finds nothing: exporters only create files */
    if (!name || !mode || (!strchr(mode, 'w') && !strchr(mode, 'a')))
        return NULL;
    out_file *of = sl_calloc(x->a, 1, sizeof *of);
    if (!of || !sl_array_reserve(x->a, &x->files, sizeof of, 1)) {
        sl_free(x->a, of, sizeof *of);
        if (!x->failed)
            sl_fail(&x->err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", name);
        x->failed = true;
        return NULL;
    }
    sl_error e;
    if (sl_atomic_open(x->a, name, &of->af, &e) != SL_OK) {
        if (!x->failed)
            x->err = e;
        x->failed = true;
        sl_free(x->a, of, sizeof *of);
        return NULL;
    }
    of->file.ReadProc = io_read;
    of->file.WriteProc = io_write;
    of->file.TellProc = io_tell;
    of->file.FileSizeProc = io_size;
    of->file.SeekProc = io_seek;
    of->file.FlushProc = io_flush;
    of->file.UserData = (aiUserData)(void *)of;
    of->buffered = !strcmp(x->format, "collada") || !strncmp(x->format, "fbx", 3);
    of->alloc = x->a;
    sl_array_push(x->a, &x->files, sizeof of, &of, 1);
    return &of->file;
}

static void io_close(struct aiFileIO *io, struct aiFile *f)
{
    /* the temporary stays open until every file of the export is complete: see finish_files */
    (void)io, (void)f;
}

/* Commit (ok) or abort every file. Side files are moved into place before the main file; when a
 * commit fails, the side files already moved are removed again. */
static sl_status finish_files(export_io *x, const char *path, bool ok, sl_error *err)
{
    sl_status st = SL_OK;
    size_t n = x->files.count;
    out_file **files = x->files.data;
    if (ok) {
        for (size_t i = 0; i < n && ok; i++) {
            out_file *of = files[i];
            if (of->buffered && !of->af.failed) {
                normalize_timestamps(x->format, x->a, &of->mem);
                errno = 0;
                sl_atomic_write(&of->af, of->mem.data, of->mem.count);
                if (of->af.failed)
                    write_failed(of, errno);
            }
            if (of->af.failed)
                ok = false, st = sl_fail(err, SL_ERROR_IO, "%s: write failed: %s (assimp's '%s' exporter was writing it)",
                                         of->af.path, strerror(of->errnum ? of->errnum : EIO), x->format);
        }
        for (int pass = 0; pass < 2 && ok; pass++)
            for (size_t i = 0; i < n && ok; i++) {
                out_file *of = files[i];
                bool main_file = !strcmp(of->af.path, path);
                if (main_file != (pass == 1))
                    continue;
                char *name = sl_strdup(x->a, of->af.path);
                if (!name) {
                    ok = false;
                    st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
                } else if ((st = sl_atomic_commit(&of->af, err)) != SL_OK) {
                    ok = false;
                } else {
                    of->committed = true;
                    /* remember the final name for a roll-back (the atomic file has released it) */
                    of->af.path = name;
                    name = NULL;
                }
                sl_strfree(x->a, name);
            }
    }
    for (size_t i = 0; i < n; i++) {
        out_file *of = files[i];
        if (of->committed) {
            if (!ok && !of->af.direct) /* a device written through is never unlinked */
                unlink(of->af.path);
            sl_strfree(x->a, of->af.path);
        } else {
            sl_atomic_abort(&of->af);
        }
        sl_array_free(x->a, &of->mem, 1);
        sl_free(x->a, of, sizeof *of);
    }
    sl_array_free(x->a, &x->files, sizeof(out_file *));
    return st;
}

/* ---- building the aiScene ---- */

static void set_ai_string(struct aiString *s, const char *text)
{
    size_t n = strlen(text);
    if (n > MAXLEN - 1)
        n = MAXLEN - 1;
    s->length = (ai_uint32)n;
    memcpy(s->data, text, n);
    s->data[n] = 0;
}

/* A material property as aiMaterial::AddProperty stores it. */
static struct aiMaterialProperty *make_property(arena *ar, const char *key, enum aiPropertyTypeInfo type, const void *data,
                                               size_t size)
{
    struct aiMaterialProperty *p = arena_calloc(ar, 1, sizeof *p);
    char *d = arena_calloc(ar, 1, size);
    if (!p || !d)
        return NULL;
    set_ai_string(&p->mKey, key);
    p->mType = type;
    p->mDataLength = (unsigned int)size;
    memcpy(d, data, size);
    p->mData = d;
    return p;
}

/* Material for colour 0xRRGGBBAA: name, diffuse colour, opacity. */
static struct aiMaterial *make_material(arena *ar, uint32_t color)
{
    struct aiMaterial *m = arena_calloc(ar, 1, sizeof *m);
    struct aiMaterialProperty **props = arena_calloc(ar, 3, sizeof *props);
    if (!m || !props)
        return NULL;
    char name[32];
    snprintf(name, sizeof name, "color_%08x", (unsigned)color);
    /* strings are stored as a 32-bit length, the bytes and a terminating zero */
    uint32_t len = (uint32_t)strlen(name);
    char sdata[4 + sizeof name];
    memcpy(sdata, &len, 4);
    memcpy(sdata + 4, name, len + 1);
    ai_real rgba[4] = {(ai_real)((color >> 24) & 255) / 255, (ai_real)((color >> 16) & 255) / 255,
                       (ai_real)((color >> 8) & 255) / 255, (ai_real)(color & 255) / 255};
    props[0] = make_property(ar, SL_MATKEY(AI_MATKEY_NAME), aiPTI_String, sdata, 4 + (size_t)len + 1);
    props[1] = make_property(ar, SL_MATKEY(AI_MATKEY_COLOR_DIFFUSE), aiPTI_Float, rgba, sizeof rgba);
    props[2] = make_property(ar, SL_MATKEY(AI_MATKEY_OPACITY), aiPTI_Float, &rgba[3], sizeof rgba[3]);
    if (!props[0] || !props[1] || !props[2])
        return NULL;
    m->mProperties = props;
    m->mNumProperties = m->mNumAllocated = 3;
    return m;
}

/* Sightline Z-up to the output frame: identity, or -90° about X, (x,y,z) -> (x,z,-y), for Y-up. */
static inline void to_output(bool yup, const float *in, struct aiVector3D *out)
{
    out->x = in[0];
    out->y = yup ? in[2] : in[1];
    out->z = yup ? -in[1] : in[2];
}

static struct aiMesh *make_mesh(arena *ar, const sl_mesh_view *mv, uint32_t material, const char *name, bool yup)
{
    struct aiMesh *m = arena_calloc(ar, 1, sizeof *m);
    struct aiVector3D *v = arena_calloc(ar, mv->vertex_count, sizeof *v);
    struct aiVector3D *nrm = mv->normals ? arena_calloc(ar, mv->vertex_count, sizeof *nrm) : NULL;
    struct aiFace *faces = arena_calloc(ar, mv->triangle_count, sizeof *faces);
    unsigned int *idx = arena_calloc(ar, 3 * (size_t)mv->triangle_count, sizeof *idx);
    if (!m || !v || (mv->normals && !nrm) || !faces || !idx)
        return NULL;
    for (uint32_t i = 0; i < mv->vertex_count; i++) {
        to_output(yup, mv->positions + 3 * (size_t)i, &v[i]);
        if (nrm)
            to_output(yup, mv->normals + 3 * (size_t)i, &nrm[i]);
    }
    for (uint32_t t = 0; t < mv->triangle_count; t++) {
        memcpy(idx + 3 * (size_t)t, mv->indices + 3 * (size_t)t, 3 * sizeof *idx);
        faces[t].mNumIndices = 3;
        faces[t].mIndices = idx + 3 * (size_t)t;
    }
    m->mPrimitiveTypes = aiPrimitiveType_TRIANGLE;
    m->mNumVertices = mv->vertex_count;
    m->mVertices = v;
    m->mNormals = nrm;
    m->mNumFaces = mv->triangle_count;
    m->mFaces = faces;
    m->mMaterialIndex = material;
    set_ai_string(&m->mName, name);
    return m;
}

/* Does a face share a vertex with another (or use one twice)? Also true when out of memory (the
 * flag then only costs assimp a MakeVerboseFormat). */
static bool mesh_shares_vertices(const sl_allocator *a, const struct aiMesh *m)
{
    if ((uint64_t)3 * m->mNumFaces > m->mNumVertices)
        return true;
    uint8_t *seen = sl_calloc(a, m->mNumVertices ? m->mNumVertices : 1, 1);
    if (!seen)
        return true;
    bool shared = false;
    for (unsigned int f = 0; f < m->mNumFaces && !shared; f++)
        for (unsigned int k = 0; k < m->mFaces[f].mNumIndices && !shared; k++) {
            unsigned int v = m->mFaces[f].mIndices[k];
            shared = seen[v]++ != 0;
        }
    sl_free(a, seen, m->mNumVertices ? m->mNumVertices : 1);
    return shared;
}

/* Object transform in the output frame: Q·T·Q⁻¹ with Q the Z-up to Y-up rotation. */
static struct aiMatrix4x4 node_matrix(const sl_affine *t, bool yup)
{
    float m[12];
    memcpy(m, t->m, sizeof m);
    if (yup) {
        /* rows of Q·T: (r0, r2, -r1); then columns of (Q·T)·Q⁻¹: (c0, c2, -c1) */
        float q[12];
        for (int j = 0; j < 4; j++) {
            q[0 + j] = m[0 + j];
            q[4 + j] = m[8 + j];
            q[8 + j] = -m[4 + j];
        }
        for (int i = 0; i < 3; i++) {
            m[i * 4 + 0] = q[i * 4 + 0];
            m[i * 4 + 1] = q[i * 4 + 2];
            m[i * 4 + 2] = -q[i * 4 + 1];
            m[i * 4 + 3] = q[i * 4 + 3];
        }
    }
    struct aiMatrix4x4 r = {m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8], m[9], m[10], m[11], 0, 0, 0, 1};
    return r;
}

/* Open-addressing map from a 64-bit key to a dense index. */
typedef struct key_map {
    uint64_t *keys;
    uint32_t *values;
    size_t cap;
} key_map;

static bool key_map_init(const sl_allocator *a, key_map *m, size_t n)
{
    m->cap = 16;
    while (m->cap < 2 * n)
        m->cap *= 2;
    m->keys = sl_alloc(a, m->cap * sizeof *m->keys);
    m->values = sl_alloc(a, m->cap * sizeof *m->values);
    if (!m->keys || !m->values)
        return false;
    for (size_t i = 0; i < m->cap; i++)
        m->values[i] = SL_NONE;
    return true;
}

static void key_map_free(const sl_allocator *a, key_map *m)
{
    sl_free(a, m->keys, m->cap * sizeof *m->keys);
    sl_free(a, m->values, m->cap * sizeof *m->values);
}

/* Slot of key: either holding it, or the empty slot where it belongs. */
static size_t key_map_slot(const key_map *m, uint64_t key)
{
    size_t mask = m->cap - 1;
    size_t slot = (size_t)(sl_hash64(&key, sizeof key, 0) & mask);
    while (m->values[slot] != SL_NONE && m->keys[slot] != key)
        slot = (slot + 1) & mask;
    return slot;
}

typedef struct export_counts {
    uint32_t meshes, materials, nodes;
} export_counts;

/* share: one aiMesh per (mesh, colour), referenced by every node that uses it; otherwise one
 * aiMesh per object, named after it (OBJ names its groups after meshes, not nodes, and has no
 * instancing to lose). */
static sl_status build_ai_scene(sl_scene s, bool yup, bool share, arena *ar, struct aiScene **out, export_counts *counts,
                                sl_error *err)
{
    const sl_allocator *a = ar->a;
    uint32_t no = sl_scene_object_count(s);
    sl_status st = SL_OK;
    key_map mesh_map = {0}, mat_map = {0};
    if (!key_map_init(a, &mesh_map, no) || !key_map_init(a, &mat_map, no)) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "export: out of memory (%u objects)", no);
        goto done;
    }
    struct aiScene *sc = arena_calloc(ar, 1, sizeof *sc);
    struct aiNode *root = arena_calloc(ar, 1, sizeof *root);
    struct aiNode **children = arena_calloc(ar, no, sizeof *children);
    struct aiMesh **meshes = arena_calloc(ar, no, sizeof *meshes);
    struct aiMaterial **mats = arena_calloc(ar, no, sizeof *mats);
    if (!sc || !root || !children || !meshes || !mats) {
        st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "export: out of memory (%u objects)", no);
        goto done;
    }
    set_ai_string(&root->mName, "sightline");
    root->mTransformation.a1 = root->mTransformation.b2 = root->mTransformation.c3 = root->mTransformation.d4 = 1;
    uint32_t nmesh = 0, nmat = 0, nnode = 0;
    for (uint32_t o = 0; o < no; o++) {
        sl_object_view ov = sl_scene_object(s, o);
        sl_mesh_view mv = sl_scene_mesh(s, ov.mesh);
        if (mv.triangle_count == 0)
            continue; /* nothing to draw, and some exporters choke on empty meshes */
        size_t ms = key_map_slot(&mat_map, ov.color);
        if (mat_map.values[ms] == SL_NONE) {
            if (!(mats[nmat] = make_material(ar, ov.color))) {
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "export: out of memory");
                goto done;
            }
            mat_map.keys[ms] = ov.color;
            mat_map.values[ms] = nmat++;
        }
        /* one aiMesh per (mesh, colour): instancing survives wherever the colours agree */
        uint64_t key = share ? (uint64_t)ov.mesh << 32 | ov.color : o;
        size_t slot = key_map_slot(&mesh_map, key);
        char name[48];
        snprintf(name, sizeof name, "o%u_%s", o, sl_object_kind_name(ov.kind));
        if (mesh_map.values[slot] == SL_NONE) {
            char mesh_name[48];
            if (share)
                snprintf(mesh_name, sizeof mesh_name, "mesh%u_%08x", ov.mesh, (unsigned)ov.color);
            else
                snprintf(mesh_name, sizeof mesh_name, "%s", name);
            if (!(meshes[nmesh] = make_mesh(ar, &mv, mat_map.values[ms], mesh_name, yup))) {
                st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "export: out of memory (mesh %u, %u vertices)", ov.mesh, mv.vertex_count);
                goto done;
            }
            mesh_map.keys[slot] = key;
            mesh_map.values[slot] = nmesh++;
        }
        struct aiNode *n = arena_calloc(ar, 1, sizeof *n);
        unsigned int *mi = arena_calloc(ar, 1, sizeof *mi);
        if (!n || !mi) {
            st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "export: out of memory");
            goto done;
        }
        set_ai_string(&n->mName, name);
        n->mTransformation = node_matrix(&ov.transform, yup);
        n->mParent = root;
        *mi = mesh_map.values[slot];
        n->mMeshes = mi;
        n->mNumMeshes = 1;
        children[nnode++] = n;
    }
    if (nnode == 0) {
        st = sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "export: the scene has no objects with triangles");
        goto done;
    }
    root->mChildren = children;
    root->mNumChildren = nnode;
    sc->mRootNode = root;
    sc->mMeshes = meshes;
    sc->mNumMeshes = nmesh;
    sc->mMaterials = mats;
    sc->mNumMaterials = nmat;
    /* vertices shared between faces: tells the exporter to run MakeVerboseFormat. Only when some
     * vertex really is shared: assimp 5.2 skips MakeVerboseFormat for a scene that is verbose
     * already but keeps the flag, and then GenFaceNormals (STL, OBJ) throws "post-processing order
     * mismatch" and the export fails without a word (a one-triangle scene did) */
    bool shared = false;
    for (uint32_t i = 0; i < nmesh && !shared; i++)
        shared = mesh_shares_vertices(a, meshes[i]);
    sc->mFlags = shared ? AI_SCENE_FLAGS_NON_VERBOSE_FORMAT : 0;
    *out = sc;
    counts->meshes = nmesh, counts->materials = nmat, counts->nodes = nnode;
done:
    key_map_free(a, &mesh_map);
    key_map_free(a, &mat_map);
    return st;
}

sl_status sl_export_assimp(sl_scene scene, const char *path, const char *format, sl_up_axis up_axis, sl_error *err)
{
    if (!scene || !path || !path[0])
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_export_assimp: NULL argument");
    if (up_axis != SL_UP_Y && up_axis != SL_UP_Z)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_export_assimp: bad up axis %d", (int)up_axis);
    char id[64];
    sl_status st = resolve_format(path, format, id, sizeof id, err);
    if (st != SL_OK)
        return st;
    /* glTF is Y-up by definition; everything else follows the caller */
    bool yup = up_axis == SL_UP_Y || !strncmp(id, "gltf", 4) || !strncmp(id, "glb", 3);

    const sl_allocator *a = &scene->alloc;
    arena ar = {a, {0}};
    struct aiScene *sc = NULL;
    export_counts counts;
    bool share = strcmp(id, "obj") != 0 && strcmp(id, "objnomtl") != 0;
    if ((st = build_ai_scene(scene, yup, share, &ar, &sc, &counts, err)) != SL_OK) {
        sl_error_prefix(err, "%s", path);
        arena_free(&ar);
        return st;
    }

    export_io x;
    memset(&x, 0, sizeof x);
    x.a = a;
    x.format = id;
    x.io.OpenProc = io_open;
    x.io.CloseProc = io_close;
    x.io.UserData = (aiUserData)(void *)&x;
    enum aiReturn r = aiExportSceneEx(sc, id, path, &x.io, 0);
    arena_free(&ar);
    bool ok = r == aiReturn_SUCCESS && !x.failed && x.files.count > 0;
    if (!ok) {
        if (x.failed) {
            st = x.err.status;
            if (err)
                *err = x.err;
        }
        else if (r != aiReturn_SUCCESS)
            /* assimp's C interface keeps the exporter's reason to itself; say what is known */
            st = sl_fail(err, SL_ERROR_IO,
                         "%s: assimp's '%s' exporter failed (%zu file%s opened, no write error; assimp %u.%u does not "
                         "tell the reason through its C interface)",
                         path, id, x.files.count, x.files.count == 1 ? "" : "s", aiGetVersionMajor(), aiGetVersionMinor());
        else
            st = sl_fail(err, SL_ERROR_INTERNAL, "%s: assimp's '%s' exporter wrote no file", path, id);
    }
    sl_status fst = finish_files(&x, path, ok, ok ? err : NULL);
    return ok ? fst : st;
}
