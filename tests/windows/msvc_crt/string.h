/* The declarations of the Microsoft C runtime's <string.h> that gistools' kernel uses (see math.h here). */
#pragma once
#include <stddef.h>
void *__cdecl memcpy(void *_Dst, void const *_Src, size_t _Size);
void *__cdecl memset(void *_Dst, int _Val, size_t _Size);
