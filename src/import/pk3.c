/* Quake III .pk3 archives: plain zip files read through libzip. The archive is memory-mapped and
 * opened from the mapped bytes, so files and in-memory archives (tests, fuzzing) share one path.
 * Every entry's declared uncompressed size is checked against a limit before anything is
 * allocated, and the bytes read must match it exactly (libzip checks the CRC at the end). */
#include "pk3.h"
#include "source_meta.h"

#include "core/escape.h"
#include "core/sl_core.h"

#include <stdlib.h>
#include <strings.h>
#include <zip.h>

bool sl_pk3_is_zip(const void *head, size_t size)
{
    const unsigned char *h = head;
    return size >= 4 && h[0] == 'P' && h[1] == 'K' && ((h[2] == 3 && h[3] == 4) || (h[2] == 5 && h[3] == 6));
}

static bool ends_with_nocase(const char *s, const char *suffix)
{
    size_t n = strlen(s), k = strlen(suffix);
    return n >= k && strcasecmp(s + n - k, suffix) == 0;
}

bool sl_pk3_entry_name(const char *map, char *out, size_t cap)
{
    if (!map || !map[0] || cap == 0)
        return false;
    const char *base = map;
    if (strncasecmp(base, "maps/", 5) == 0)
        base += 5;
    int n;
    if (strchr(base, '/')) {
        /* a map in a subfolder or another folder: the full entry path, ".bsp" optional, as
         * sl_pk3_list_maps lists it (Nexuiz's maps/_init/_init.bsp) */
        size_t len = strlen(map);
        if (ends_with_nocase(map, ".bsp"))
            len -= 4;
        else if (strchr(strrchr(map, '/'), '.'))
            return false; /* another kind of file (textures/x.jpg) */
        if (len == 0 || map[len - 1] == '/')
            return false;
        n = snprintf(out, cap, "%.*s.bsp", (int)SL_MIN(len, (size_t)INT32_MAX), map);
    } else {
        size_t len = strlen(base);
        if (ends_with_nocase(base, ".bsp"))
            len -= 4;
        if (len == 0)
            return false;
        n = snprintf(out, cap, "maps/%.*s.bsp", (int)SL_MIN(len, (size_t)INT32_MAX), base);
    }
    return n > 0 && (size_t)n < cap;
}

/* Little-endian fields of the zip headers. */
static uint32_t zip_u16(const uint8_t *p) { return (uint32_t)p[0] | (uint32_t)p[1] << 8; }
static uint32_t zip_u32(const uint8_t *p) { return zip_u16(p) | zip_u16(p + 2) << 16; }

typedef struct zip_name {
    const uint8_t *p;
    uint32_t len;
} zip_name;

static int zip_name_cmp(const void *a, const void *b)
{
    const zip_name *x = a, *y = b;
    int c = memcmp(x->p, y->p, SL_MIN(x->len, y->len));
    return c ? c : (x->len > y->len) - (x->len < y->len);
}

/* libzip refuses an archive holding two entries of one name with its bare "File already
 * exists". Find that name in the central directory (the lowest in byte order when several are
 * doubled, so the message is deterministic) and write it, escaped, into out; false when the
 * directory cannot be walked (zip64, damage), and the caller falls back on libzip's text. */
static bool pk3_find_duplicate(const uint8_t *d, size_t size, const sl_allocator *a, char *out, size_t cap)
{
    if (size < 22)
        return false;
    size_t eocd = SIZE_MAX;
    for (size_t back = 0; back <= 65535 && back + 22 <= size; back++) {
        const uint8_t *p = d + size - 22 - back;
        if (zip_u32(p) == 0x06054b50u && zip_u16(p + 20) == back) {
            eocd = size - 22 - back;
            break;
        }
    }
    if (eocd == SIZE_MAX)
        return false;
    uint32_t entries = zip_u16(d + eocd + 10), cd = zip_u32(d + eocd + 16);
    if (cd > eocd || entries == 0)
        return false;
    zip_name *names = sl_alloc(a, (size_t)entries * sizeof *names);
    if (!names)
        return false;
    size_t at = cd;
    uint32_t n = 0;
    for (; n < entries; n++) {
        if (eocd - at < 46 || zip_u32(d + at) != 0x02014b50u)
            break;
        uint32_t nl = zip_u16(d + at + 28), xl = zip_u16(d + at + 30), cl = zip_u16(d + at + 32);
        if (eocd - at - 46 < (size_t)nl + xl + cl)
            break;
        names[n] = (zip_name){d + at + 46, nl};
        at += 46 + (size_t)nl + xl + cl;
    }
    bool found = false;
    if (n == entries) {
        qsort(names, n, sizeof *names, zip_name_cmp);
        for (uint32_t i = 1; i < n && !found; i++) {
            if (zip_name_cmp(&names[i - 1], &names[i]) != 0)
                continue;
            found = true;
            size_t o = 0;
            for (uint32_t k = 0; k < names[i].len && o + 5 < cap; k++) {
                uint8_t ch = names[i].p[k];
                if (ch >= 0x20 && ch < 0x7f && ch != '\\')
                    out[o++] = (char)ch;
                else
                    o += (size_t)snprintf(out + o, cap - o, "\\x%02x", ch);
            }
            out[o] = 0;
        }
    }
    sl_free(a, names, (size_t)entries * sizeof *names);
    return found;
}

/* Open an archive held in memory; the bytes must outlive the returned handle. */
static sl_status pk3_open(const void *data, size_t size, const char *archive, const sl_allocator *a, zip_t **out,
                          sl_error *err)
{
    *out = NULL;
    if (!sl_pk3_is_zip(data, size))
        return sl_fail(err, SL_ERROR_FORMAT, "%s: offset 0: not a zip archive (no \"PK\" signature)", archive);
    zip_error_t ze;
    zip_error_init(&ze);
    zip_source_t *src = zip_source_buffer_create(data, size, 0, &ze);
    if (!src) {
        sl_status st = sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: libzip: %s", archive, zip_error_strerror(&ze));
        zip_error_fini(&ze);
        return st;
    }
    zip_t *z = zip_open_from_source(src, ZIP_RDONLY | ZIP_CHECKCONS, &ze);
    if (!z) {
        int code = zip_error_code_zip(&ze);
        char dup[256];
        if (code == ZIP_ER_EXISTS && pk3_find_duplicate(data, size, a, dup, sizeof dup)) {
            zip_error_fini(&ze);
            zip_source_free(src);
            return sl_fail(err, SL_ERROR_FORMAT, "%s: duplicate entry %s: an archive may not hold two entries of one name",
                           archive, dup);
        }
        sl_status st = sl_fail(err, code == ZIP_ER_MEMORY ? SL_ERROR_OUT_OF_MEMORY : SL_ERROR_FORMAT,
                               "%s: not a readable zip archive: %s", archive, zip_error_strerror(&ze));
        zip_error_fini(&ze);
        zip_source_free(src);
        return st;
    }
    zip_error_fini(&ze);
    *out = z;
    return SL_OK;
}

/* Index and name of each .bsp entry in archive order; fn may be NULL (just counting). */
static uint32_t pk3_each_map(zip_t *z, void (*fn)(void *user, const char *entry), void *user, zip_int64_t *first)
{
    zip_int64_t n = zip_get_num_entries(z, 0);
    uint32_t count = 0;
    if (first)
        *first = -1;
    for (zip_int64_t i = 0; i < n; i++) {
        const char *name = zip_get_name(z, (zip_uint64_t)i, 0);
        if (!name || !name[0] || name[strlen(name) - 1] == '/' || !ends_with_nocase(name, ".bsp"))
            continue;
        if (first && *first < 0)
            *first = i;
        count++;
        if (fn)
            fn(user, name);
    }
    return count;
}

/* The archive's map names (NAME of maps/NAME.bsp, escaped) for a message, into out: with
 * wanted == NULL the first dozen ("a, b, c ... and N more"), else those close to the entry name
 * `wanted` ("a, b or c"; "" when none is). */
typedef struct pk3_names {
    char names[64][48];
    const char *list[64];
    uint32_t count, total;
} pk3_names;

static void pk3_collect_name(void *user, const char *entry)
{
    pk3_names *n = user;
    n->total++;
    if (n->count == 64)
        return;
    const char *base = strrchr(entry, '/');
    base = base ? base + 1 : entry;
    size_t len = strlen(base);
    if (len >= 4)
        len -= 4; /* ".bsp" */
    char raw[48];
    snprintf(raw, sizeof raw, "%.*s", (int)(len < 40 ? len : 40), base);
    sl_escape_text(raw, 40, n->names[n->count], sizeof n->names[n->count]);
    n->list[n->count] = n->names[n->count];
    n->count++;
}

static void pk3_map_names(zip_t *z, const char *wanted, char *out, size_t size)
{
    out[0] = 0;
    pk3_names names = {.count = 0, .total = 0}, *n = &names; /* 3.5 KB on the stack: no allocation for a message */
    pk3_each_map(z, pk3_collect_name, n, NULL);
    if (wanted) {
        const char *base = strrchr(wanted, '/');
        base = base ? base + 1 : wanted;
        char want[64];
        size_t len = strlen(base);
        snprintf(want, sizeof want, "%.*s", (int)(len >= 4 ? (len - 4 < 60 ? len - 4 : 60) : len), base);
        sl_text_suggest(want, n->list, n->count, out, size);
    } else {
        size_t used = 0;
        uint32_t shown = n->count < 12 ? n->count : 12;
        for (uint32_t i = 0; i < shown && used < size; i++) {
            int w = snprintf(out + used, size - used, "%s%s", i ? ", " : "", n->list[i]);
            if (w < 0)
                break;
            used += (size_t)w;
        }
        if (n->total > shown && used < size)
            snprintf(out + used, size - used, " ... and %u more", n->total - shown);
    }
}

sl_status sl_pk3_list_maps_memory(const void *data, size_t size, const char *archive_name,
                                  void (*fn)(void *user, const char *entry), void *user, sl_error *err)
{
    if (!data || !fn)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pk3_list_maps: NULL argument");
    const char *archive = archive_name ? archive_name : "<memory>";
    zip_t *z;
    sl_status st = pk3_open(data, size, archive, sl_default_allocator(), &z, err);
    if (st != SL_OK)
        return st;
    pk3_each_map(z, fn, user, NULL);
    zip_discard(z);
    return SL_OK;
}

/* Read entry idx whole into memory from `a`, refusing entries larger than max_bytes. */
static sl_status pk3_read_entry(zip_t *z, zip_int64_t idx, const char *archive, const char *raw_entry, size_t max_bytes,
                                const sl_allocator *a, uint8_t **out, size_t *out_size, sl_error *err)
{
    *out = NULL;
    *out_size = 0;
    /* the entry's name comes from the archive: escaped for every message (control bytes, bad UTF-8) */
    char shown[300];
    sl_escape_text(raw_entry, 200, shown, sizeof shown);
    const char *entry = shown;
    zip_stat_t zs;
    zip_stat_init(&zs);
    if (zip_stat_index(z, (zip_uint64_t)idx, 0, &zs) != 0 || !(zs.valid & ZIP_STAT_SIZE))
        return sl_fail(err, SL_ERROR_FORMAT, "%s: entry %s: cannot read its size: %s", archive, entry, zip_strerror(z));
    if (zs.size > max_bytes)
        return sl_fail(err, SL_ERROR_LIMIT, "%s: entry %s: uncompressed size %llu exceeds the limit of %zu bytes",
                       archive, entry, (unsigned long long)zs.size, max_bytes);
    size_t n = (size_t)zs.size;
    uint8_t *buf = sl_alloc(a, n ? n : 1);
    if (!buf)
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: entry %s: cannot allocate %zu bytes", archive, entry, n);
    zip_file_t *f = zip_fopen_index(z, (zip_uint64_t)idx, 0);
    if (!f) {
        sl_free(a, buf, n ? n : 1);
        return sl_fail(err, SL_ERROR_FORMAT, "%s: entry %s: cannot open: %s", archive, entry, zip_strerror(z));
    }
    size_t got = 0;
    sl_status st = SL_OK;
    while (got < n) {
        zip_int64_t r = zip_fread(f, buf + got, n - got);
        if (r < 0) {
            st = sl_fail(err, SL_ERROR_FORMAT, "%s: entry %s: offset %zu: %s", archive, entry, got, zip_file_strerror(f));
            break;
        }
        if (r == 0) {
            st = sl_fail(err, SL_ERROR_FORMAT, "%s: entry %s: data ends after %zu of its %zu bytes", archive, entry, got, n);
            break;
        }
        got += (size_t)r;
    }
    if (st == SL_OK) {
        /* one more read reaches the end of the stream, where libzip verifies the CRC */
        uint8_t extra;
        zip_int64_t r = zip_fread(f, &extra, 1);
        if (r < 0)
            st = sl_fail(err, SL_ERROR_FORMAT, "%s: entry %s: %s", archive, entry, zip_file_strerror(f));
        else if (r > 0)
            st = sl_fail(err, SL_ERROR_FORMAT, "%s: entry %s: data is longer than its declared %zu bytes", archive, entry, n);
    }
    zip_fclose(f);
    if (st != SL_OK) {
        sl_free(a, buf, n ? n : 1);
        return st;
    }
    *out = buf;
    *out_size = n;
    return SL_OK;
}

sl_status sl_pk3_import_memory(const void *data, size_t size, const char *archive_name, const char *map,
                               size_t max_entry_bytes, uint64_t max_triangles, const sl_import_options *opt,
                               const sl_allocator *alloc, sl_scene *out, sl_error *err)
{
    if (!out)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_import_q3bsp: out is NULL");
    *out = NULL;
    if (!data)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_import_q3bsp: data is NULL");
    const sl_allocator *a = sl_alloc_or_default(alloc);
    const char *archive = archive_name ? archive_name : "<memory>";
    zip_t *z;
    sl_status st = pk3_open(data, size, archive, a, &z, err);
    if (st != SL_OK)
        return st;

    zip_int64_t idx;
    char wanted[1024] = "";
    if (!map || !map[0]) {
        uint32_t count = pk3_each_map(z, NULL, NULL, &idx);
        if (count != 1) {
            char names[400];
            pk3_map_names(z, NULL, names, sizeof names);
            zip_discard(z);
            if (!count)
                return sl_fail(err, SL_ERROR_NOT_FOUND, "%s: the archive holds no maps (no maps/NAME.bsp entry)", archive);
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT,
                           "%s: the archive holds %u maps (%s); name the one to import (sightline: --map NAME; "
                           "all of them: sightline import %s --list-maps)",
                           archive, count, names, archive);
        }
    } else {
        if (!sl_pk3_entry_name(map, wanted, sizeof wanted)) {
            zip_discard(z);
            char shown[300];
            return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "%s: \"%s\" is not a map name (NAME or maps/NAME.bsp)",
                           archive, sl_escape_text(map, 200, shown, sizeof shown));
        }
        idx = zip_name_locate(z, wanted, ZIP_FL_NOCASE);
        if (idx < 0) {
            char near[400];
            pk3_map_names(z, wanted, near, sizeof near);
            zip_discard(z);
            char shown[300];
            sl_escape_text(wanted, 200, shown, sizeof shown);
            if (near[0])
                return sl_fail(err, SL_ERROR_NOT_FOUND, "%s: entry %s not found (did you mean %s?)", archive, shown, near);
            return sl_fail(err, SL_ERROR_NOT_FOUND, "%s: entry %s not found (no map of that name or close to it)",
                           archive, shown);
        }
    }
    const char *entry = zip_get_name(z, (zip_uint64_t)idx, 0);
    if (!entry)
        entry = wanted;

    /* messages from the map reader name "archive:entry" */
    size_t name_len = strlen(archive) + strlen(entry) + 2;
    char *name = sl_alloc(a, name_len);
    if (!name) {
        zip_discard(z);
        return sl_fail(err, SL_ERROR_OUT_OF_MEMORY, "%s: out of memory", archive);
    }
    snprintf(name, name_len, "%s:%s", archive, entry);

    uint8_t *bytes;
    size_t nbytes;
    st = pk3_read_entry(z, idx, archive, entry, max_entry_bytes, a, &bytes, &nbytes, err);
    zip_discard(z);
    if (st == SL_OK) {
        st = sl_q3bsp_import_memory_limited(bytes, nbytes, name, opt, max_triangles, alloc, out, err);
        sl_free(a, bytes, nbytes ? nbytes : 1);
        /* `entry` died with the archive handle: its copy in `name` follows "archive:" (the map
         * reader escapes the name in its messages) */
        if (st == SL_OK && (st = sl_scene_set_source_entry(*out, archive, name + strlen(archive) + 1, err)) != SL_OK) {
            sl_scene_destroy(*out);
            *out = NULL;
        }
    }
    sl_free(a, name, name_len);
    return st;
}

sl_status sl_pk3_list_maps(const char *pk3_path, void (*fn)(void *user, const char *entry), void *user, sl_error *err)
{
    if (!pk3_path || !fn)
        return sl_fail(err, SL_ERROR_INVALID_ARGUMENT, "sl_pk3_list_maps: NULL argument");
    sl_mapping m;
    sl_status st = sl_file_map(pk3_path, &m, err);
    if (st != SL_OK)
        return st;
    st = sl_pk3_list_maps_memory(m.data, m.size, pk3_path, fn, user, err);
    sl_file_unmap(&m);
    return st;
}
