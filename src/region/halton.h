/* Halton low-discrepancy sequences (Halton 1960; Niederreiter 1992) for the samplers of the region
 * layer: guided visibility sampling draws its random rays from them (Wonka et al. 2006, section
 * 5.3.1: u = xi1, v = xi2, phi = 2 pi xi3, theta = asin xi4 with independent Halton sequences).
 *
 * Dimension k of point i is the radical inverse of i in the k-th prime base. A sequence may carry
 * a Cranley-Patterson rotation (a per-dimension shift modulo 1) drawn from a seed, so that distinct
 * seeds (or cells) get distinct but equally well distributed point sets. Pure functions of
 * (dims, seed, stream, index): deterministic on every platform. */
#ifndef SL_REGION_HALTON_H
#define SL_REGION_HALTON_H

#include <stdbool.h>
#include <stdint.h>

/* Most dimensions of one sequence (the first SL_HALTON_MAX_DIMS primes are the bases). */
#define SL_HALTON_MAX_DIMS 16u

/* The k-th prime (k < SL_HALTON_MAX_DIMS): 2, 3, 5, 7, 11 ... */
uint32_t sl_halton_prime(uint32_t k);

/* Radical inverse of index in base (>= 2): the digits of index mirrored about the radix point,
 * in [0, 1). */
double sl_radical_inverse(uint32_t base, uint64_t index);

/* Most base-b digits an index may have in any dimension: b^digits must fit in 64 bits. */
#define SL_HALTON_MAX_DIGITS 64u

/* A multi-dimensional Halton sequence with an optional rotation. Each dimension keeps the digits
 * of the index and their mirrored value as an integer, so the next point costs an amortised
 * constant number of integer additions (no divisions) and equals sl_radical_inverse exactly. */
typedef struct sl_halton {
    uint32_t dims;
    uint64_t index;                     /* next point's index (starts at 1: point 0 is all zeros) */
    double shift[SL_HALTON_MAX_DIMS];   /* Cranley-Patterson shifts in [0, 1); all 0 unrotated */
    uint64_t mirrored[SL_HALTON_MAX_DIMS];                  /* sum of digit_j * b^(D-1-j) */
    uint64_t top[SL_HALTON_MAX_DIMS];                       /* b^(D-1) */
    double inv[SL_HALTON_MAX_DIMS];                         /* 1 / b^D */
    uint32_t ndigits[SL_HALTON_MAX_DIMS];                   /* D */
    uint8_t digits[SL_HALTON_MAX_DIMS][SL_HALTON_MAX_DIGITS];
} sl_halton;

/* Start a sequence of dims (1..SL_HALTON_MAX_DIMS, clamped) dimensions. rotate: shifts drawn from
 * PCG32 seeded with (seed, stream); otherwise the plain sequence (seed and stream unused). */
void sl_halton_init(sl_halton *h, uint32_t dims, bool rotate, uint64_t seed, uint64_t stream);

/* Write the next point (h->dims values in [0, 1)) to out and advance. */
void sl_halton_next(sl_halton *h, double *out);

#endif
