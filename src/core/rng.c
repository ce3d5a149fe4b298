/* PCG32 (O'Neill 2014): small, fast, and the same sequence on every platform, so generators and
 * samplers seeded alike produce byte-identical output. */
#include "sl_core.h"

void sl_rng_seed(sl_rng *r, uint64_t seed, uint64_t stream)
{
    r->state = 0;
    r->inc = (stream << 1u) | 1u;
    sl_rng_u32(r);
    r->state += seed;
    sl_rng_u32(r);
}

uint32_t sl_rng_u32(sl_rng *r)
{
    uint64_t old = r->state;
    r->state = old * 6364136223846793005ULL + r->inc;
    uint32_t xorshifted = (uint32_t)(((old >> 18u) ^ old) >> 27u);
    uint32_t rot = (uint32_t)(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((-rot) & 31));
}

float sl_rng_float(sl_rng *r) { return (float)(sl_rng_u32(r) >> 8) * (1.0f / 16777216.0f); }

double sl_rng_double(sl_rng *r)
{
    uint64_t hi = sl_rng_u32(r) >> 5, lo = sl_rng_u32(r) >> 6;
    return (double)(hi * 67108864u + lo) * (1.0 / 9007199254740992.0);
}

float sl_rng_range(sl_rng *r, float lo, float hi) { return lo + (hi - lo) * sl_rng_float(r); }

uint32_t sl_rng_below(sl_rng *r, uint32_t n)
{
    /* Lemire's rejection keeps the result unbiased */
    uint32_t threshold = (uint32_t)(-n) % n;
    for (;;) {
        uint32_t x = sl_rng_u32(r);
        if (x >= threshold)
            return x % n;
    }
}
