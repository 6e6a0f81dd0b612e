/* The declarations of the Microsoft C runtime's <stdlib.h> that gistools' kernel uses (see math.h here). */
#pragma once
#include <stddef.h>
void *__cdecl malloc(size_t _Size);
void *__cdecl calloc(size_t _Count, size_t _Size);
void *__cdecl realloc(void *_Block, size_t _Size);
void __cdecl free(void *_Block);
