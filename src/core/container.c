/* The section container of .slscene and .slpvs files (container.h). */
#include "container.h"

#include "bytes.h"

#include <stdarg.h>
#include <stdlib.h>

static inline uint64_t align_up(uint64_t v) { return (v + SL_CONTAINER_ALIGN - 1) & ~(uint64_t)(SL_CONTAINER_ALIGN - 1); }

sl_status sl_container_write(const sl_allocator *a, const char *path, int fd, const uint8_t magic[8], uint32_t major,
                             uint32_t minor, uint32_t flags, uint64_t seed, const sl_container_section *secs, size_t n,
                             sl_error *err)
{
    enum { MAX = 64 };
    if (n > MAX)
        return sl_fail(err, SL_ERROR_INTERNAL, "%s: %zu sections, at most %d", path, n, MAX);
    uint8_t head[SL_CONTAINER_HEADER + MAX * SL_CONTAINER_ENTRY];
    memset(head, 0, sizeof head);
    uint8_t *table = head + SL_CONTAINER_HEADER;
    uint64_t table_size = (uint64_t)n * SL_CONTAINER_ENTRY, offset[MAX];
    uint64_t at = align_up(SL_CONTAINER_HEADER + table_size);
    for (size_t i = 0; i < n; i++) {
        uint8_t *e = table + i * SL_CONTAINER_ENTRY;
        offset[i] = at;
        memcpy(e + 0, secs[i].tag, 4);
        wr32(e + 4, secs[i].elem);
        wr64(e + 8, secs[i].count);
        wr64(e + 16, at);
        wr64(e + 24, secs[i].size);
        wr64(e + 32, sl_hash64(secs[i].size ? secs[i].data : "", (size_t)secs[i].size, seed));
        at = align_up(at + secs[i].size);
    }
    uint64_t file_size = at;
    memcpy(head, magic, 8);
    wr32(head + 8, major);
    wr32(head + 12, minor);
    wr32(head + 16, flags);
    wr32(head + 20, SL_CONTAINER_HEADER);
    wr32(head + 24, (uint32_t)n);
    wr32(head + 28, SL_CONTAINER_ENTRY);
    wr64(head + 32, SL_CONTAINER_HEADER);
    wr64(head + 40, file_size);
    wr64(head + 48, sl_hash64(table, (size_t)table_size, seed));
    wr64(head + 56, sl_hash64(head, 56, seed));

    sl_atomic_file f;
    sl_status st = fd >= 0 ? sl_atomic_open_fd(a, fd, path, &f, err) : sl_atomic_open(a, path, &f, err);
    if (st != SL_OK)
        return st;
    static const uint8_t zeros[SL_CONTAINER_ALIGN] = {0};
    uint64_t pos = SL_CONTAINER_HEADER + table_size;
    sl_atomic_write(&f, head, (size_t)pos);
    for (size_t i = 0; i < n; i++) {
        sl_atomic_write(&f, zeros, (size_t)(offset[i] - pos));
        if (secs[i].size)
            sl_atomic_write(&f, secs[i].data, (size_t)secs[i].size);
        pos = offset[i] + secs[i].size;
    }
    sl_atomic_write(&f, zeros, (size_t)(file_size - pos));
    return sl_atomic_commit(&f, err); /* removes the temporary file itself on failure */
}

/* ---- reading ---- */

sl_status sl_container_vfail_at(sl_error *err, const char *name, uint64_t offset, const char *fmt, va_list ap)
{
    char why[400];
    vsnprintf(why, sizeof why, fmt, ap);
    return sl_fail(err, SL_ERROR_FORMAT, "%s: offset %llu: %s", name, (unsigned long long)offset, why);
}

sl_status sl_container_fail_at(sl_error *err, const char *name, uint64_t offset, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    sl_status st = sl_container_vfail_at(err, name, offset, fmt, ap);
    va_end(ap);
    return st;
}

#define bad sl_container_fail_at

/* Field offsets of the header. */
enum { C_MAJOR = 8, C_MINOR = 12, C_FLAGS = 16, C_HEADER = 20, C_COUNT = 24, C_ENTRY = 28, C_TABLE = 32,
       C_FILE = 40, C_TABLE_HASH = 48, C_HASH = 56 };

sl_status sl_container_check_header(const uint8_t *head, uint64_t size, const sl_container_format *fmt,
                                    const char *name, sl_container_header *h, sl_error *err)
{
    memset(h, 0, sizeof *h);
    if (size < SL_CONTAINER_HEADER)
        return bad(err, name, 0, "truncated: the file has %llu bytes, shorter than the %u-byte header",
                   (unsigned long long)size, SL_CONTAINER_HEADER);
    if (memcmp(head, fmt->magic, 8) != 0)
        return bad(err, name, 0, "bad magic: not a %s file", fmt->what);
    h->major = rd32(head + C_MAJOR);
    h->minor = rd32(head + C_MINOR);
    if (h->major > fmt->major)
        return sl_fail(err, SL_ERROR_UNSUPPORTED,
                       "%s: offset %u: format version %u.%u is newer than this reader (%u.%u): upgrade Sightline", name,
                       C_MAJOR, h->major, h->minor, fmt->major, fmt->minor);
    if (h->major < 1)
        return bad(err, name, C_MAJOR, "format version %u.%u does not exist", h->major, h->minor);
    uint64_t hh = sl_hash64(head, C_HASH, fmt->seed);
    if (hh != rd64(head + C_HASH))
        return bad(err, name, C_HASH, "header checksum mismatch (stored %016llx, computed %016llx)",
                   (unsigned long long)rd64(head + C_HASH), (unsigned long long)hh);
    h->flags = rd32(head + C_FLAGS);
    h->header_size = rd32(head + C_HEADER);
    h->count = rd32(head + C_COUNT);
    h->entry_size = rd32(head + C_ENTRY);
    h->table_offset = rd64(head + C_TABLE);
    h->file_size = rd64(head + C_FILE);
    h->table_hash = rd64(head + C_TABLE_HASH);
    /* newer minor versions may grow the header and the entries; never shrink them */
    if (h->header_size < SL_CONTAINER_HEADER || h->header_size > 4096 || h->header_size > size)
        return bad(err, name, C_HEADER, "header size %u is outside 64..4096 or the file", h->header_size);
    if (h->entry_size < SL_CONTAINER_ENTRY || h->entry_size > 4096)
        return bad(err, name, C_ENTRY, "section entry size %u is outside 48..4096", h->entry_size);
    if (h->file_size > size)
        return bad(err, name, C_FILE, "truncated: expected %llu bytes, file has %llu", (unsigned long long)h->file_size,
                   (unsigned long long)size);
    if (h->file_size < size)
        return bad(err, name, C_FILE, "extended: expected %llu bytes, file has %llu (appended to)",
                   (unsigned long long)h->file_size, (unsigned long long)size);
    if (h->count > fmt->max_sections)
        return bad(err, name, C_COUNT, "%u sections is more than the %u allowed", h->count, fmt->max_sections);
    h->table_size = (uint64_t)h->count * h->entry_size;
    if (h->table_offset < h->header_size || h->table_offset > size || h->table_size > size - h->table_offset)
        return bad(err, name, C_TABLE, "section table (%llu bytes at %llu) lies outside the file",
                   (unsigned long long)h->table_size, (unsigned long long)h->table_offset);
    return SL_OK;
}

sl_status sl_container_check_table(const uint8_t *table, const sl_container_header *h, uint64_t seed, const char *name,
                                   sl_error *err)
{
    uint64_t th = sl_hash64(table, (size_t)h->table_size, seed);
    if (th != h->table_hash)
        return bad(err, name, h->table_offset, "section table checksum mismatch (stored %016llx, computed %016llx)",
                   (unsigned long long)h->table_hash, (unsigned long long)th);
    return SL_OK;
}

static int cmp_span(const void *x, const void *y)
{
    const sl_container_span *a = x, *b = y;
    return a->begin < b->begin ? -1 : a->begin > b->begin ? 1 : (a->order > b->order) - (a->order < b->order);
}

sl_status sl_container_check_layout(sl_container_span *spans, size_t n, uint64_t size, const uint8_t *bytes,
                                    sl_status (*read)(void *ctx, uint64_t offset, void *buf, uint64_t n), void *ctx,
                                    const char *name, sl_error *err)
{
    qsort(spans, n, sizeof *spans, cmp_span);
    for (size_t i = 1; i < n; i++)
        if (spans[i].begin < spans[i - 1].end)
            return bad(err, name, spans[i].begin, "'%s' overlaps '%s'", spans[i].what, spans[i - 1].what);
    uint8_t buf[4096];
    for (size_t i = 0; i <= n; i++) {
        uint64_t begin = i ? spans[i - 1].end : 0, end = i < n ? spans[i].begin : size;
        while (begin < end) {
            uint64_t k = end - begin < sizeof buf ? end - begin : sizeof buf;
            const uint8_t *p = bytes ? bytes + begin : buf;
            if (!bytes) {
                sl_status st = read(ctx, begin, buf, k);
                if (st != SL_OK)
                    return st;
            }
            for (uint64_t j = 0; j < k; j++)
                if (p[j])
                    return bad(err, name, begin + j, "padding byte is not zero");
            begin += k;
        }
    }
    return SL_OK;
}
