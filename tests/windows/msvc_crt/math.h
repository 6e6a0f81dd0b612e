/* The declarations of the Microsoft C runtime's <math.h> that gistools' kernel uses, as the Windows SDK writes
 * them (INFINITY and NAN included), for the MSVC-mode compile of the tests (clang --driver-mode=cl): the kernel's C
 * is checked by a compiler front end in Microsoft's dialect, against the runtime's own spellings. */
#pragma once
#define _HUGE_ENUF 1e+300
#define INFINITY ((float)(_HUGE_ENUF * _HUGE_ENUF))
#define NAN (-(float)(INFINITY * 0.0F))
double __cdecl sqrt(double _X);
double __cdecl floor(double _X);
double __cdecl ceil(double _X);
double __cdecl fabs(double _X);
double __cdecl fmin(double _X, double _Y);
double __cdecl fmax(double _X, double _Y);
double __cdecl nearbyint(double _X);
int __cdecl _dclass(double _X);
#define FP_INFINITE 1
#define FP_NAN 2
#define fpclassify(_X) _dclass((double)(_X))
#define isnan(_X) (fpclassify(_X) == FP_NAN)
#define isfinite(_X) (fpclassify(_X) <= 0)
