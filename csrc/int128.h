/* The exact sign of the in-circle determinant in 128-bit integers: the compiler's __int128 where it has one (GCC,
 * Clang), else two 64-bit words (MSVC), the same result. Define GISTOOLS_PORTABLE_INT128 to build the portable
 * form anywhere (the tests compare the two). Inputs: coordinate differences of at most 2^30 in magnitude (the
 * caller quantises the points to that span), so every intermediate fits in 128 bits. */
#ifndef GISTOOLS_INT128_H
#define GISTOOLS_INT128_H

#include <stdint.h>

#if defined(__SIZEOF_INT128__) && !defined(GISTOOLS_PORTABLE_INT128)

static int incircle_exact_sign(int64_t dx, int64_t dy, int64_t ex, int64_t ey, int64_t fx, int64_t fy) {
    typedef __int128 i128;
    i128 AP = (i128)dx * dx + (i128)dy * dy, BP = (i128)ex * ex + (i128)ey * ey, CP = (i128)fx * fx + (i128)fy * fy;
    i128 T1 = (i128)ey * CP - BP * fy, T2 = (i128)ex * CP - BP * fx, T3 = (i128)ex * fy - (i128)ey * fx;
    i128 D = dx * T1 - dy * T2 + AP * T3;
    return (D > 0) - (D < 0);
}

#else

/* a 128-bit two's complement integer in two words; arithmetic modulo 2^128 (exact while results fit) */
typedef struct {
    uint64_t lo, hi;
} s128;

static s128 s128_of(int64_t a) {
    s128 r = {(uint64_t)a, a < 0 ? UINT64_MAX : 0};
    return r;
}

static s128 s128_add(s128 a, s128 b) {
    s128 r = {a.lo + b.lo, a.hi + b.hi};
    r.hi += r.lo < a.lo; /* carry */
    return r;
}

static s128 s128_neg(s128 a) {
    s128 r = {~a.lo, ~a.hi}, one = {1, 0};
    return s128_add(r, one);
}

static s128 s128_sub(s128 a, s128 b) { return s128_add(a, s128_neg(b)); }

/* the full 128-bit product of two unsigned 64-bit words */
static s128 u64_mul(uint64_t a, uint64_t b) {
    uint64_t a0 = a & 0xffffffffu, a1 = a >> 32, b0 = b & 0xffffffffu, b1 = b >> 32;
    uint64_t p00 = a0 * b0, p01 = a0 * b1, p10 = a1 * b0, p11 = a1 * b1;
    uint64_t mid = (p00 >> 32) + (p01 & 0xffffffffu) + (p10 & 0xffffffffu);
    s128 r = {(p00 & 0xffffffffu) | (mid << 32), p11 + (p01 >> 32) + (p10 >> 32) + (mid >> 32)};
    return r;
}

/* a * b modulo 2^128, b sign-extended: the product's two's complement bits */
static s128 s128_mul(s128 a, int64_t b) {
    uint64_t blo = (uint64_t)b, bhi = b < 0 ? UINT64_MAX : 0;
    s128 r = u64_mul(a.lo, blo);
    r.hi += a.hi * blo + a.lo * bhi;
    return r;
}

static int s128_sign(s128 a) {
    if ((int64_t)a.hi < 0) return -1;
    return (a.hi | a.lo) != 0;
}

static int incircle_exact_sign(int64_t dx, int64_t dy, int64_t ex, int64_t ey, int64_t fx, int64_t fy) {
    /* |differences| <= 2^30: the squares' sums and T3 are below 2^62 and fit in 64 bits; the rest needs 128 */
    int64_t AP = dx * dx + dy * dy, BP = ex * ex + ey * ey, CP = fx * fx + fy * fy, T3 = ex * fy - ey * fx;
    s128 T1 = s128_sub(s128_mul(s128_of(CP), ey), s128_mul(s128_of(BP), fy));
    s128 T2 = s128_sub(s128_mul(s128_of(CP), ex), s128_mul(s128_of(BP), fx));
    s128 D = s128_add(s128_sub(s128_mul(T1, dx), s128_mul(T2, dy)), s128_mul(s128_of(AP), T3));
    return s128_sign(D);
}

#endif
#endif
