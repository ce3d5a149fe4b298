/* Checksums through xxHash (libxxhash): XXH3 runs at memory speed, so an 8M-triangle .slscene
 * is verified on every load without a visible cost. */
#include "sl_core.h"

#include <xxhash.h>

uint64_t sl_hash64(const void *data, size_t size, uint64_t seed) { return XXH3_64bits_withSeed(data, size, seed); }
