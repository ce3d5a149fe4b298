/* Internal: reading and writing the little-endian integers of Sightline's binary files (.slscene,
 * .slpvs, the bake journal) at any alignment, written once (issue 13: slscene.c, pvs_file.c and
 * pvs_build.c each had their own). The formats are little-endian and these read host order: the
 * build refuses a big-endian machine. */
#ifndef SL_CORE_BYTES_H
#define SL_CORE_BYTES_H

#include <stdint.h>
#include <string.h>

#if !defined(__BYTE_ORDER__) || __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "Sightline's file formats are little-endian; this build reads them in host order"
#endif

static inline uint32_t rd32(const uint8_t *p)
{
    uint32_t v;
    memcpy(&v, p, sizeof v);
    return v;
}
static inline uint64_t rd64(const uint8_t *p)
{
    uint64_t v;
    memcpy(&v, p, sizeof v);
    return v;
}
static inline void wr32(uint8_t *p, uint32_t v) { memcpy(p, &v, sizeof v); }
static inline void wr64(uint8_t *p, uint64_t v) { memcpy(p, &v, sizeof v); }

#endif
