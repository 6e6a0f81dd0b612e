/* What every part of gistools' C kernel shares: the standard headers, the vectorisation and prefetch hints. */
#ifndef GISTOOLS_COMMON_H
#define GISTOOLS_COMMON_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "gistools_kernel.h"

/* the grid loops (and the quantisation: nearbyint inline) also built for AVX2, chosen at load time where the CPU
 * has it (GCC / Clang on x86-64 Linux) */
#if defined(__x86_64__) && defined(__linux__) && (defined(__clang__) || (defined(__GNUC__) && __GNUC__ >= 6))
#define SIMD_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define SIMD_CLONES
#endif

/* C99's restrict, in the spelling every compiler of the kernel takes: MSVC's C compiler knows it as __restrict (its
 * `restrict` keyword needs /std:c11); the kernel's sources write GT_RESTRICT, never the keyword */
#if defined(_MSC_VER)
#define GT_RESTRICT __restrict
#else
#define GT_RESTRICT restrict
#endif

/* a hint to fetch the cache line of *p (GCC / Clang; nothing elsewhere) */
#if defined(__GNUC__) || defined(__clang__)
#define PREFETCH(p) __builtin_prefetch(p)
#else
#define PREFETCH(p) ((void)(p))
#endif

/* min / max of finite doubles (fmin / fmax are library calls without -ffast-math, for NaN rules not needed here) */
static inline double dmin(double a, double b) { return a < b ? a : b; }
static inline double dmax(double a, double b) { return a > b ? a : b; }

#endif
