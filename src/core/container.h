/* Internal: the section container that .slscene and .slpvs files share (docs/slscene-format.md,
 * docs/pvs.md), written once (issue 13: slscene.c and pvs_file.c each laid it out and wrote it):
 *   a 64-byte header: u8[8] magic, u32 version_major, u32 version_minor, u32 flags,
 *     u32 header_size (64), u32 section_count, u32 entry_size (48), u64 table_offset (64),
 *     u64 file_size, u64 XXH3-64 of the table, u64 XXH3-64 of header bytes 0..55;
 *   the table: one 48-byte entry a section: u8[4] tag, u32 element size, u64 count, u64 offset,
 *     u64 size, u64 XXH3-64 of the section's bytes, u64 reserved (0);
 *   the sections in table order, each on a 64-byte boundary, the gaps and the tail zero.
 * Every checksum uses the format's seed. The readers share the container's checks, written once
 * here (issue 13: slscene.c and pvs_file.c each checked the header, the table and the padding):
 * sl_container_check_header, sl_container_check_table and sl_container_check_layout; each reader
 * keeps its own sections' rules (tags, element sizes, presence, flags). Messages name the file and
 * the offset: "NAME: offset N: why". */
#ifndef SL_CORE_CONTAINER_H
#define SL_CORE_CONTAINER_H

#include "sl_core.h"

#include <stdarg.h>

#define SL_CONTAINER_HEADER 64u
#define SL_CONTAINER_ENTRY 48u
#define SL_CONTAINER_ALIGN 64u

typedef struct sl_container_section {
    char tag[4];
    uint32_t elem;        /* element size (1 for bytes) */
    uint64_t count;       /* elements */
    const void *data;     /* size bytes (may be NULL when size is 0) */
    uint64_t size;
} sl_container_section;

/* Write the n sections (at most 64) to path atomically (sl_atomic_open ... commit: a failed write
 * leaves no file and never a partial one); or, when fd >= 0, straight through to that open file
 * descriptor from its offset (left open; path is its name in messages). */
sl_status sl_container_write(const sl_allocator *a, const char *path, int fd, const uint8_t magic[8], uint32_t major,
                             uint32_t minor, uint32_t flags, uint64_t seed, const sl_container_section *secs, size_t n,
                             sl_error *err);

/* SL_ERROR_FORMAT with "NAME: offset N: why" (the readers' messages about a byte of the file). */
sl_status sl_container_fail_at(sl_error *err, const char *name, uint64_t offset, const char *fmt, ...) SL_PRINTF(4, 5);
sl_status sl_container_vfail_at(sl_error *err, const char *name, uint64_t offset, const char *fmt, va_list ap);

/* What a format's reader expects of the container. */
typedef struct sl_container_format {
    const uint8_t *magic;   /* 8 bytes */
    const char *what;       /* in "bad magic: not a WHAT file" (".slscene") */
    uint32_t major, minor;  /* the reader's version: a newer major is SL_ERROR_UNSUPPORTED */
    uint64_t seed;          /* of the checksums */
    uint32_t max_sections;
} sl_container_format;

/* The header's fields, checked. table_size = count * entry_size. */
typedef struct sl_container_header {
    uint32_t major, minor, flags, header_size, count, entry_size;
    uint64_t table_offset, table_size, file_size, table_hash;
} sl_container_header;

/* Check the first 64 bytes of a file of `size` bytes (head may hold fewer when size < 64): the
 * size, magic, version (1 .. the reader's major), header checksum, header size (64..4096, within
 * the file), entry size (48..4096), the stored file size against the real one, the section count
 * and that the table lies within the file. Fills *h. */
sl_status sl_container_check_header(const uint8_t *head, uint64_t size, const sl_container_format *fmt,
                                    const char *name, sl_container_header *h, sl_error *err);

/* The section table's checksum (table: its table_size bytes). */
sl_status sl_container_check_table(const uint8_t *table, const sl_container_header *h, uint64_t seed, const char *name,
                                   sl_error *err);

/* A byte range of the file: the header, the table or a non-empty section; `what` names it in
 * messages ("header", "section table", a tag), `order` breaks ties of equal begin. */
typedef struct sl_container_span {
    uint64_t begin, end;
    const char *what;
    int order;
} sl_container_span;

/* The layout rule: no two spans share a byte, and every byte of [0, size) outside them is zero
 * (with the checksums, any corrupted byte of a file is then noticed). Sorts spans. The gaps are
 * read from bytes (the whole file) or, when bytes is NULL, through read(ctx, offset, buf, n). */
sl_status sl_container_check_layout(sl_container_span *spans, size_t n, uint64_t size, const uint8_t *bytes,
                                    sl_status (*read)(void *ctx, uint64_t offset, void *buf, uint64_t n), void *ctx,
                                    const char *name, sl_error *err);

#endif
