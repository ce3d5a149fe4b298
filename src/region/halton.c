/* Halton sequences with Cranley-Patterson rotation (see halton.h). */
#include "halton.h"

#include "core/sl_core.h"

static const uint32_t g_primes[SL_HALTON_MAX_DIMS] = {2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53};

uint32_t sl_halton_prime(uint32_t k) { return g_primes[k < SL_HALTON_MAX_DIMS ? k : SL_HALTON_MAX_DIMS - 1]; }

/* The scale of the mirrored integer for base b: D digits with b^D <= 2^64 - 1, top = b^(D-1),
 * inv = 1 / b^D (as a double). */
static void base_params(uint32_t b, uint32_t *D, uint64_t *top, double *inv)
{
    uint64_t p = 1;
    uint32_t d = 0;
    while (p <= UINT64_MAX / b) {
        p *= b;
        d++;
    }
    *D = d;
    *top = p / b;
    *inv = 1.0 / (double)p;
}

/* The mirrored integer as a double in [0, 1): the same operations in both paths, so that the
 * sequence and sl_radical_inverse agree bit for bit. */
static double to_unit(uint64_t mirrored, double inv)
{
    double v = (double)mirrored * inv;
    return v < 1.0 ? v : 0x1.fffffffffffffp-1;
}

double sl_radical_inverse(uint32_t base, uint64_t index)
{
    if (base < 2)
        base = 2;
    uint32_t D;
    uint64_t scale;
    double inv;
    base_params(base, &D, &scale, &inv);
    uint64_t m = 0;
    for (uint32_t j = 0; j < D && index > 0; j++) {
        m += (index % base) * scale;
        index /= base;
        scale /= base;
    }
    return to_unit(m, inv);
}

void sl_halton_init(sl_halton *h, uint32_t dims, bool rotate, uint64_t seed, uint64_t stream)
{
    memset(h, 0, sizeof *h);
    h->dims = SL_CLAMP(dims, 1u, SL_HALTON_MAX_DIMS);
    h->index = 1;
    /* the digits of index 1: a single 1 */
    for (uint32_t k = 0; k < h->dims; k++) {
        base_params(g_primes[k], &h->ndigits[k], &h->top[k], &h->inv[k]);
        h->digits[k][0] = 1;
        h->mirrored[k] = h->top[k];
    }
    if (rotate) {
        sl_rng r;
        sl_rng_seed(&r, seed, stream);
        for (uint32_t k = 0; k < h->dims; k++)
            h->shift[k] = sl_rng_double(&r);
    }
}

void sl_halton_next(sl_halton *h, double *out)
{
    for (uint32_t k = 0; k < h->dims; k++) {
        uint32_t b = g_primes[k];
        double v = to_unit(h->mirrored[k], h->inv[k]) + h->shift[k];
        out[k] = v >= 1.0 ? v - 1.0 : v;
        /* increment the index's digits with carry, keeping the mirrored integer in step (a carry
         * happens with probability 1/b per digit: amortised O(1)); past b^D points, never reached,
         * the dimension wraps around to 0 */
        const uint32_t D = h->ndigits[k];
        uint64_t scale = h->top[k];
        for (uint32_t j = 0; j < D; j++) {
            if (h->digits[k][j] + 1u < b) {
                h->digits[k][j]++;
                h->mirrored[k] += scale;
                break;
            }
            h->mirrored[k] -= (uint64_t)(b - 1) * scale;
            h->digits[k][j] = 0;
            scale /= b;
        }
    }
    h->index++;
}
