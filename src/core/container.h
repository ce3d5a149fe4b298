/* Internal: the section container that .slscene and .slpvs files share (docs/slscene-format.md,
 * docs/pvs.md), written once (issue 13: slscene.c and pvs_file.c each laid it out and wrote it):
 *   a 64-byte header: u8[8] magic, u32 version_major, u32 version_minor, u32 flags,
 *     u32 header_size (64), u32 section_count, u32 entry_size (48), u64 table_offset (64),
 *     u64 file_size, u64 XXH3-64 of the table, u64 XXH3-64 of header bytes 0..55;
 *   the table: one 48-byte entry a section: u8[4] tag, u32 element size, u64 count, u64 offset,
 *     u64 size, u64 XXH3-64 of the section's bytes, u64 reserved (0);
 *   the sections in table order, each on a 64-byte boundary, the gaps and the tail zero.
 * Every checksum uses the format's seed. The readers stay with their formats (each checks its own
 * sections and versions). */
#ifndef SL_CORE_CONTAINER_H
#define SL_CORE_CONTAINER_H

#include "sl_core.h"

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

#endif
