/* Replays recorded calls of gistools' C kernel and writes what they returned and wrote: the test of the Windows
 * ABI (tests/test_kernel_windows.py) builds this driver natively and with MinGW-w64 (a static .exe run under Wine),
 * gives both the same calls and compares their outputs byte for byte.
 *
 * usage: driver CALLS OUT
 *
 * CALLS, a sequence of calls (little-endian, as both x86-64 ABIs), each:
 *   int32 length, the entry point's name; int32 the argument count; then per argument an int32 tag and its value:
 *     'i' an integer (int64, converted to the parameter's integer type)   'd' a double (8 bytes)
 *     'a' an array (int64 byte count, then the bytes)                      'n' NULL
 *     'v' a pointer into an earlier 'a' argument (int32 its position, int64 a byte offset): strided record views
 * OUT, per call: the return value (8 bytes: the int64 or double; zeros for void), then each 'a' argument as the call
 * left it (int64 byte count, the bytes), in argument order.
 *
 * Every array is copied into its own allocation between guard bytes: a call that writes outside an array stops the
 * driver with an error (exit 3). The calls themselves are in thunks.h, which the test writes from
 * csrc/gistools_kernel.h (one `call_NAME(Arg *, unsigned char ret[8])` per entry point, and the table THUNKS), so
 * the driver follows the header. Files are opened in binary mode: no newline translation on Windows.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gistools_kernel.h"

typedef struct {
    int64_t i;
    double d;
    void *p;
} Arg;

typedef struct {
    const char *name;
    int nargs;
    void (*call)(Arg *a, unsigned char *ret);
} Thunk;

#include "thunks.h"

#define MAX_ARGS 64
#define GUARD 64 /* bytes each side of an array (a multiple of 16: arrays keep malloc's alignment) */
#define GUARD_BYTE 0xA5

static void fail(int code, const char *what, const char *name) {
    fprintf(stderr, "driver: %s%s%s\n", what, name ? ": " : "", name ? name : "");
    exit(code);
}

static void get(void *p, size_t n, FILE *f) {
    if (n && fread(p, 1, n, f) != n) fail(2, "truncated call file", NULL);
}

static void put(const void *p, size_t n, FILE *f) {
    if (n && fwrite(p, 1, n, f) != n) fail(2, "cannot write the output file", NULL);
}

static int guards_intact(const unsigned char *buf, int64_t size) {
    for (int k = 0; k < GUARD; k++)
        if (buf[k] != GUARD_BYTE || buf[GUARD + size + k] != GUARD_BYTE) return 0;
    return 1;
}

int main(int argc, char **argv) {
    if (argc != 3) fail(1, "usage: driver CALLS OUT", NULL);
    FILE *in = fopen(argv[1], "rb"), *out = fopen(argv[2], "wb");
    if (!in || !out) fail(1, "cannot open", in ? argv[2] : argv[1]);
    int32_t len;
    while (fread(&len, sizeof len, 1, in) == 1) {
        char name[128];
        if (len <= 0 || len >= (int32_t)sizeof name) fail(2, "bad name length", NULL);
        get(name, (size_t)len, in);
        name[len] = 0;
        const Thunk *t = NULL;
        for (size_t k = 0; k < sizeof THUNKS / sizeof THUNKS[0]; k++)
            if (!strcmp(THUNKS[k].name, name)) t = &THUNKS[k];
        if (!t) fail(2, "no such entry point", name);
        int32_t nargs;
        get(&nargs, sizeof nargs, in);
        if (nargs != t->nargs || nargs > MAX_ARGS) fail(2, "wrong argument count", name);
        Arg a[MAX_ARGS];
        unsigned char *buf[MAX_ARGS];
        int64_t size[MAX_ARGS];
        for (int32_t k = 0; k < nargs; k++) {
            int32_t tag, j;
            int64_t off;
            memset(&a[k], 0, sizeof a[k]);
            buf[k] = NULL;
            size[k] = -1;
            get(&tag, sizeof tag, in);
            switch (tag) {
            case 'i':
                get(&a[k].i, 8, in);
                break;
            case 'd':
                get(&a[k].d, 8, in);
                break;
            case 'n':
                break;
            case 'a':
                get(&size[k], 8, in);
                if (size[k] < 0) fail(2, "negative array size", name);
                buf[k] = (unsigned char *)malloc((size_t)size[k] + 2 * GUARD);
                if (!buf[k]) fail(2, "out of memory", name);
                memset(buf[k], GUARD_BYTE, (size_t)size[k] + 2 * GUARD);
                a[k].p = buf[k] + GUARD;
                get(a[k].p, (size_t)size[k], in);
                break;
            case 'v':
                get(&j, sizeof j, in);
                get(&off, sizeof off, in);
                if (j < 0 || j >= k || !buf[j] || off < 0 || off > size[j]) fail(2, "bad view", name);
                a[k].p = buf[j] + GUARD + off;
                break;
            default:
                fail(2, "bad argument tag", name);
            }
        }
        unsigned char ret[8] = {0};
        t->call(a, ret);
        put(ret, sizeof ret, out);
        for (int32_t k = 0; k < nargs; k++) {
            if (!buf[k]) continue;
            if (!guards_intact(buf[k], size[k])) fail(3, "the call wrote outside an array", name);
            put(&size[k], 8, out);
            put(buf[k] + GUARD, (size_t)size[k], out);
            free(buf[k]);
        }
    }
    if (fclose(out) != 0) fail(2, "cannot write the output file", NULL);
    fclose(in);
    return 0;
}
