/* Forced include (g++ -include) for building Intel's Masked Occlusion Culling (MOC) from a checkout
 * outside this repository (CMake option SL_MOC_DIR, docs/rasterizer.md). Not part of Sightline.
 *
 * MOC's CompilerSpecific.inl defines __cpuidex and _xgetbv for GCC/clang, but the compilers' headers
 * already have them: GCC 12 declares both (__cpuidex in <cpuid.h>, _xgetbv in <xsaveintrin.h> via
 * <immintrin.h>: "redefinition of __cpuidex", "ambiguating new declaration of _xgetbv"), clang 14
 * defines _xgetbv as a macro ("redefinition of '__builtin_ia32_xgetbv'"). This
 * header includes the system headers first (their include guards then make MOC's own includes of them
 * no-ops) and renames MOC's two definitions, and the calls to them, to names of their own. MOC's files
 * are compiled unchanged. */
#ifndef SL_MOC_COMPAT_H
#define SL_MOC_COMPAT_H
#include <cpuid.h>
#include <immintrin.h>
#define __cpuidex sl_moc_compat_cpuidex
#define _xgetbv sl_moc_compat_xgetbv
#endif
