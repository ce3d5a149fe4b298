/* AVX2 kernels of the occlusion rasterizer. One 256-bit register holds the 8 pixel rows of a tile
 * row (coverage spans, row masks) or the 8 subtiles of a tile (masks, depths); the row masks are
 * turned into subtile masks with one byte shuffle. The front end and the small-triangle setup
 * work on 8 triangles at a time (raster_batch.h); small triangles then take raster_small8.h's
 * raster_cols (one to three tiles wide: a fixed number of tiles per tile row) or raster_small_ymm,
 * the others the general kernel raster_avx2. Same results as raster_scalar.c, bit for bit: exact coverage, the same float
 * operations in the same order, and no FMA (the target is "avx2" alone and contraction is off).
 * Compiled for the baseline; run only when __builtin_cpu_supports("avx2"). */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#endif

#include "raster/raster_internal.h"

#if defined(SL_RT_X86)
#define AVX2 __attribute__((target("avx2")))
#define SL_RT_T AVX2
#define SL_RT_NAME(n) n##_avx2
#define SL_RT_W 8
#include "raster/raster_simd8.h"
#include "raster/raster_lanes.h"
#include "raster/raster_batch.h"
#include "raster/raster_small8.h"

AVX2 static void raster_avx2(const sl_rt_target *tg, const sl_rt_tri *t, int32_t tx0, int32_t tx1, int32_t ty0,
                             int32_t ty1)
{
    general_ymm(tg, t, tx0, tx1, ty0, ty1);
}


/* Set up prims in groups of 8: small ones take raster_cols or raster_small_ymm, the others the reference setup and
 * the general kernel. */
AVX2 static void render_avx2(const sl_rt_target *tg, int mode, const sl_rt_prim *p, uint32_t n, int32_t tx0,
                             int32_t tx1, int32_t ty0, int32_t ty1)
{
    for (uint32_t i = 0; i < n; i += 8) {
        uint32_t k = n - i < 8 ? n - i : 8;
        small_lanes s;
        unsigned empty, small = setup_lanes(p + i, k, mode, &s, &empty);
        for (uint32_t l = 0; l < k; l++) {
            if (small >> l & 1) {
                small_tri st;
                if (!small_load(&s, (int)l, tx0, tx1, ty0, ty1, &st))
                    continue;
                if (st.tx1 - st.tx0 == 1)
                    raster_cols(tg, &st, 1);
                else if (st.tx1 - st.tx0 == 2)
                    raster_cols(tg, &st, 2);
                else if (st.tx1 - st.tx0 == 3)
                    raster_cols(tg, &st, 3);
                else
                    raster_small_ymm(tg, &st);
            } else if (!(empty >> l & 1)) {
                sl_rt_render_each(raster_avx2, tg, mode, p + i + l, 1, tx0, tx1, ty0, ty1);
            }
        }
    }
}

const sl_rt_kernels sl_rt_kernels_avx2 = {SL_RASTER_ISA_AVX2, raster_avx2, query_avx2, rect_avx2, front_avx2,
                                          render_avx2};

#endif
