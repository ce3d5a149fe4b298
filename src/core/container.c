/* The section container of .slscene and .slpvs files (container.h). */
#include "container.h"

#include "bytes.h"

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
