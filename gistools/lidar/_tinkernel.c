/*
 * Delaunay triangulation of 2-D points and its linear interpolation at grid cell centres.
 *
 * The triangulation is the sweep-hull algorithm of Delaunator (Mapbox, ISC licence; this is a
 * port of its published algorithm, v4/v5): points sorted by distance from a seed circumcircle
 * are added outside a convex hull kept in a linked list with an angular hash, and triangles are
 * legalised by edge flips. The predicates are exact: coordinates are integers spanning at most
 * 2^30 steps (the caller quantises them; the largest span for which the arithmetic below stays
 * exact), orientation is evaluated in 64-bit integers, the in-circle test in doubles with an error
 * bound and, when that is not conclusive, in 128-bit integers. So the result is a Delaunay triangulation of the quantised points whatever their
 * degeneracy (collinear, cocircular, repeated).
 *
 * Called through ctypes (gistools/lidar/tin.py); the Python module init only makes the
 * shared object importable and locatable.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef __int128 i128;

/* the grid loops (and the quantisation: nearbyint inline) also built for AVX2, chosen at load time where the CPU
 * has it (GCC / Clang on x86-64 Linux) */
#if defined(__x86_64__) && defined(__linux__) && (defined(__clang__) || (defined(__GNUC__) && __GNUC__ >= 6))
#define SIMD_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define SIMD_CLONES
#endif

/* a hint to fetch the cache line of *p (GCC / Clang; nothing elsewhere) */
#if defined(__GNUC__) || defined(__clang__)
#define PREFETCH(p) __builtin_prefetch(p)
#else
#define PREFETCH(p) ((void)(p))
#endif


/* sign of cross(q - p, r - p): > 0 when p, q, r turn counter-clockwise */
static inline int ccw(int64_t px, int64_t py, int64_t qx, int64_t qy, int64_t rx, int64_t ry) {
    int64_t d = (qx - px) * (ry - py) - (qy - py) * (rx - px);
    return (d > 0) - (d < 0);
}

/* sign of the in-circle determinant of (a, b, c) and p: > 0 when p is inside the circle of a
 * counter-clockwise a, b, c */
static int incircle(int64_t ax, int64_t ay, int64_t bx, int64_t by, int64_t cx, int64_t cy, int64_t px, int64_t py) {
    int64_t dx = ax - px, dy = ay - py, ex = bx - px, ey = by - py, fx = cx - px, fy = cy - py;
    double Dx = (double)dx, Dy = (double)dy, Ex = (double)ex, Ey = (double)ey, Fx = (double)fx, Fy = (double)fy;
    double ap = Dx * Dx + Dy * Dy, bp = Ex * Ex + Ey * Ey, cp = Fx * Fx + Fy * Fy;
    double t1 = Ey * cp - bp * Fy, t2 = Ex * cp - bp * Fx, t3 = Ex * Fy - Ey * Fx;
    double det = Dx * t1 - Dy * t2 + ap * t3;
    double perm = fabs(Dx) * (fabs(Ey * cp) + fabs(bp * Fy)) + fabs(Dy) * (fabs(Ex * cp) + fabs(bp * Fx)) +
                  ap * (fabs(Ex * Fy) + fabs(Ey * Fx));
    double bound = 1e-13 * perm;
    if (det > bound) return 1;
    if (det < -bound) return -1;
    i128 AP = (i128)dx * dx + (i128)dy * dy, BP = (i128)ex * ex + (i128)ey * ey, CP = (i128)fx * fx + (i128)fy * fy;
    i128 T1 = (i128)ey * CP - BP * fy, T2 = (i128)ex * CP - BP * fx, T3 = (i128)ex * fy - (i128)ey * fx;
    i128 D = dx * T1 - dy * T2 + AP * T3;
    return (D > 0) - (D < 0);
}

typedef struct {
    const int64_t *p; /* coordinates in insertion order, interleaved x, y */
    int32_t *tri, *half;
    int64_t tlen;
    int32_t *hprev, *hnext, *htri, *hhash;
    int32_t hsize, hstart;
    double cx, cy;
    int32_t *stack;
    int64_t scap;
} Del;

static inline int32_t hash_key(const Del *d, double x, double y) {
    double dx = x - d->cx, dy = y - d->cy;
    double s = fabs(dx) + fabs(dy);
    double p = s > 0 ? dx / s : 0;
    double a = (dy > 0 ? 3 - p : 1 + p) / 4; /* pseudo-angle in [0, 1] */
    int32_t k = (int32_t)floor(a * d->hsize);
    return ((k % d->hsize) + d->hsize) % d->hsize;
}

static inline void link_he(Del *d, int64_t a, int64_t b) {
    d->half[a] = (int32_t)b;
    if (b != -1) d->half[b] = (int32_t)a;
}

static inline int64_t add_tri(Del *d, int32_t i0, int32_t i1, int32_t i2, int64_t a, int64_t b, int64_t c) {
    int64_t t = d->tlen;
    d->tri[t] = i0;
    d->tri[t + 1] = i1;
    d->tri[t + 2] = i2;
    link_he(d, t, a);
    link_he(d, t + 1, b);
    link_he(d, t + 2, c);
    d->tlen += 3;
    return t;
}

static int push(Del *d, int64_t *n, int32_t v) {
    if (*n >= d->scap) {
        int64_t cap = d->scap * 2;
        int32_t *s = (int32_t *)realloc(d->stack, (size_t)cap * sizeof(int32_t));
        if (!s) return -1;
        d->stack = s;
        d->scap = cap;
    }
    d->stack[(*n)++] = v;
    return 0;
}

/* Flip edges from half-edge a until the Delaunay condition holds; returns the half-edge the
 * caller tracks (as Delaunator's _legalize). Triangles are clockwise in a y-up frame. */
static int64_t legalize(Del *d, int64_t a) {
    int64_t n = 0, ar = 0;
    for (;;) {
        int64_t b = d->half[a];
        int64_t a0 = a - a % 3;
        ar = a0 + (a + 2) % 3;
        if (b == -1) {
            if (n == 0) break;
            a = d->stack[--n];
            continue;
        }
        int64_t b0 = b - b % 3;
        int64_t al = a0 + (a + 1) % 3;
        int64_t bl = b0 + (b + 2) % 3;
        int32_t p0 = d->tri[ar], pr = d->tri[a], pl = d->tri[al], p1 = d->tri[bl];
        /* (p0, pr, pl) is clockwise: p1 inside its circle <=> incircle(p0, pl, pr, p1) > 0 */
        const int64_t *P = d->p;
        int illegal = incircle(P[2 * p0], P[2 * p0 + 1], P[2 * pl], P[2 * pl + 1], P[2 * pr], P[2 * pr + 1], P[2 * p1], P[2 * p1 + 1]) > 0;
        if (illegal) {
            d->tri[a] = p1;
            d->tri[b] = p0;
            int32_t hbl = d->half[bl];
            if (hbl == -1) { /* the flipped edge was on the hull: fix the hull's triangle reference */
                int32_t e = d->hstart;
                do {
                    if (d->htri[e] == bl) {
                        d->htri[e] = (int32_t)a;
                        break;
                    }
                    e = d->hprev[e];
                } while (e != d->hstart);
            }
            link_he(d, a, hbl);
            link_he(d, b, d->half[ar]);
            link_he(d, ar, bl);
            int64_t br = b0 + (b + 1) % 3;
            if (push(d, &n, (int32_t)br)) return -2;
        } else {
            if (n == 0) break;
            a = d->stack[--n];
        }
    }
    return ar;
}

/* sort (key, id) pairs by key: LSD radix sort on the key's bits (keys >= 0) from bit `shift0` up; stable */
typedef struct {
    uint64_t key;
    int32_t id;
} Pair;

static int radix_sort_from(Pair *a, int64_t n, int shift0) {
    Pair *tmp = (Pair *)malloc((size_t)n * sizeof(Pair));
    if (!tmp) return -1;
    enum { BITS = 11, BUCKETS = 1 << BITS };
    int64_t *count = (int64_t *)malloc(BUCKETS * sizeof(int64_t));
    if (!count) {
        free(tmp);
        return -1;
    }
    uint64_t maxkey = 0;
    for (int64_t i = 0; i < n; i++)
        if (a[i].key > maxkey) maxkey = a[i].key;
    Pair *src = a, *dst = tmp;
    for (int shift = shift0; shift < 64 && (maxkey >> shift); shift += BITS) {
        memset(count, 0, BUCKETS * sizeof(int64_t));
        for (int64_t i = 0; i < n; i++) count[(src[i].key >> shift) & (BUCKETS - 1)]++;
        int64_t s = 0;
        for (int k = 0; k < BUCKETS; k++) {
            int64_t c = count[k];
            count[k] = s;
            s += c;
        }
        for (int64_t i = 0; i < n; i++) dst[count[(src[i].key >> shift) & (BUCKETS - 1)]++] = src[i];
        Pair *t = src;
        src = dst;
        dst = t;
    }
    if (src != a) memcpy(a, src, (size_t)n * sizeof(Pair));
    free(tmp);
    free(count);
    return 0;
}

/* by key, equal keys in input order (as a radix sort on the whole key), in half its passes: a radix sort on the
 * high 32 bits, then each run of equal high bits (short: they hold 20 bits of a double's mantissa) in order by a
 * stable insertion sort. Runs longer than 32 (keys this close: points on a circle) get the whole radix sort. */
static int sort_by_key(Pair *a, int64_t n) {
    if (radix_sort_from(a, n, 32)) return -1;
    int64_t run = 1, longest = 1;
    for (int64_t i = 1; i < n; i++) {
        run = (a[i].key >> 32) == (a[i - 1].key >> 32) ? run + 1 : 1;
        if (run > longest) longest = run;
    }
    if (longest > 32) return radix_sort_from(a, n, 0);
    for (int64_t i = 1; i < n; i++) {
        if (a[i].key >= a[i - 1].key) continue; /* (a smaller key in order by the high bits shares them) */
        Pair p = a[i];
        int64_t j = i - 1;
        while (j >= 0 && a[j].key > p.key) {
            a[j + 1] = a[j];
            j--;
        }
        a[j + 1] = p;
    }
    return 0;
}

static double circumradius2(double ax, double ay, double bx, double by, double cx, double cy) {
    double dx = bx - ax, dy = by - ay, ex = cx - ax, ey = cy - ay;
    double bl = dx * dx + dy * dy, cl = ex * ex + ey * ey, dd = dx * ey - dy * ex;
    if (dd == 0) return INFINITY;
    double x = (ey * bl - dy * cl) * 0.5 / dd, y = (dx * cl - ex * bl) * 0.5 / dd;
    return x * x + y * y;
}

/* The triangulation; triangles index the insertion order, which *order_out gives (input index per position). */
static int64_t triangulate(int64_t n, const int64_t *xin, const int64_t *yin, int32_t *triangles, int64_t *repeats,
                           Pair **order_out) {
    *repeats = 0;
    *order_out = NULL;
    if (n < 3) return 0;
    int64_t result = -1;
    Pair *order = NULL;
    int64_t *pts = NULL;
    int32_t *half = NULL, *hprev = NULL, *hnext = NULL, *htri = NULL, *hhash = NULL, *stack = NULL;
    /* seed: the point nearest the bounding-box centre, its nearest neighbour, and the point making
     * the smallest circumcircle with them */
    int64_t minx = xin[0], maxx = xin[0], miny = yin[0], maxy = yin[0];
    for (int64_t i = 1; i < n; i++) {
        if (xin[i] < minx) minx = xin[i];
        if (xin[i] > maxx) maxx = xin[i];
        if (yin[i] < miny) miny = yin[i];
        if (yin[i] > maxy) maxy = yin[i];
    }
    double bcx = 0.5 * ((double)minx + (double)maxx), bcy = 0.5 * ((double)miny + (double)maxy);
    int64_t i0 = 0, i1 = -1, i2 = -1;
    double best = INFINITY;
    for (int64_t i = 0; i < n; i++) {
        double dx = (double)xin[i] - bcx, dy = (double)yin[i] - bcy, dd = dx * dx + dy * dy;
        if (dd < best) {
            best = dd;
            i0 = i;
        }
    }
    best = INFINITY;
    for (int64_t i = 0; i < n; i++) {
        if (xin[i] == xin[i0] && yin[i] == yin[i0]) continue;
        double dx = (double)(xin[i] - xin[i0]), dy = (double)(yin[i] - yin[i0]), dd = dx * dx + dy * dy;
        if (dd < best) {
            best = dd;
            i1 = i;
        }
    }
    if (i1 < 0) return 0; /* all points at one position */
    best = INFINITY;
    for (int64_t i = 0; i < n; i++) {
        if (ccw(xin[i0], yin[i0], xin[i1], yin[i1], xin[i], yin[i]) == 0) continue;
        double r = circumradius2((double)xin[i0], (double)yin[i0], (double)xin[i1], (double)yin[i1], (double)xin[i],
                                 (double)yin[i]);
        if (r < best) {
            best = r;
            i2 = i;
        }
    }
    if (i2 < 0) return 0; /* collinear */
    if (ccw(xin[i0], yin[i0], xin[i1], yin[i1], xin[i2], yin[i2]) > 0) { /* seed clockwise (y-up) */
        int64_t t = i1;
        i1 = i2;
        i2 = t;
    }
    /* circumcentre of the seed */
    double ax = (double)xin[i0], ay = (double)yin[i0];
    double dx = (double)xin[i1] - ax, dy = (double)yin[i1] - ay, ex = (double)xin[i2] - ax, ey = (double)yin[i2] - ay;
    double bl = dx * dx + dy * dy, cl = ex * ex + ey * ey, dd = dx * ey - dy * ex;
    double ccx = ax + (ey * bl - dy * cl) * 0.5 / dd, ccy = ay + (dx * cl - ex * bl) * 0.5 / dd;

    /* insertion order: by squared distance from the seed's circumcentre (seed first) */
    order = (Pair *)malloc((size_t)n * sizeof(Pair));
    if (!order) goto done;
    for (int64_t i = 0; i < n; i++) {
        double qx = (double)xin[i] - ccx, qy = (double)yin[i] - ccy;
        double q = qx * qx + qy * qy;
        uint64_t key;
        memcpy(&key, &q, sizeof key); /* non-negative doubles sort as their bit patterns */
        order[i].key = key;
        order[i].id = (int32_t)i;
    }
    if (sort_by_key(order, n)) goto done;
    pts = (int64_t *)malloc((size_t)n * 2 * sizeof(int64_t));
    int64_t maxhe = 3 * (2 * n);
    half = (int32_t *)malloc((size_t)maxhe * sizeof(int32_t));
    hprev = (int32_t *)malloc((size_t)n * sizeof(int32_t));
    hnext = (int32_t *)malloc((size_t)n * sizeof(int32_t));
    htri = (int32_t *)malloc((size_t)n * sizeof(int32_t));
    int32_t hsize = (int32_t)ceil(sqrt((double)n));
    hhash = (int32_t *)malloc((size_t)hsize * sizeof(int32_t));
    stack = (int32_t *)malloc(1024 * sizeof(int32_t));
    if (!pts || !half || !hprev || !hnext || !htri || !hhash || !stack) goto done;
    int32_t s0 = -1, s1 = -1, s2 = -1; /* the seed's positions in insertion order */
    for (int64_t k = 0; k < n; k++) {
        int32_t id = order[k].id;
        pts[2 * k] = xin[id];
        pts[2 * k + 1] = yin[id];
        if (id == i0) s0 = (int32_t)k;
        if (id == i1) s1 = (int32_t)k;
        if (id == i2) s2 = (int32_t)k;
    }
#define X(k) pts[2 * (k)]
#define Y(k) pts[2 * (k) + 1]
#define FAIL            \
    do {                \
        stack = d.stack; \
        goto done;      \
    } while (0)
    Del d = {pts, triangles, half, 0, hprev, hnext, htri, hhash, hsize, s0, ccx, ccy, stack, 1024};
    for (int32_t k = 0; k < hsize; k++) hhash[k] = -1;
    hnext[s0] = hprev[s2] = s1;
    hnext[s1] = hprev[s0] = s2;
    hnext[s2] = hprev[s1] = s0;
    htri[s0] = 0;
    htri[s1] = 1;
    htri[s2] = 2;
    hhash[hash_key(&d, (double)X(s0), (double)Y(s0))] = s0;
    hhash[hash_key(&d, (double)X(s1), (double)Y(s1))] = s1;
    hhash[hash_key(&d, (double)X(s2), (double)Y(s2))] = s2;
    add_tri(&d, s0, s1, s2, -1, -1, -1);

    int64_t xp = 0, yp = 0;
    int32_t key_next = hash_key(&d, (double)X(0), (double)Y(0));
    for (int64_t k = 0; k < n; k++) {
        int32_t i = (int32_t)k;
        int64_t x = X(k), y = Y(k);
        int32_t key = key_next; /* this point's hash key */
        /* The sweep's time is the latency of its loads from the hull where a point lands (a random angle: not in
         * L1). The next point's start on the hull is looked up now and its records fetched at the end of this
         * insertion, while they are not needed yet (hints only: the hash may change meanwhile). */
        int32_t ahead = -1;
        if (k + 1 < n) {
            key_next = hash_key(&d, (double)X(k + 1), (double)Y(k + 1));
            ahead = hhash[key_next];
        }
        if (k > 0 && x == xp && y == yp) { /* a repeat of the previous point */
            (*repeats)++;
            continue;
        }
        xp = x;
        yp = y;
        if (i == s0 || i == s1 || i == s2) continue;
        /* a visible hull edge, found from the angular hash */
        int32_t start = 0;
        for (int32_t j = 0; j < hsize; j++) {
            start = hhash[(key + j) % hsize];
            if (start != -1 && start != hnext[start]) break;
        }
        start = hprev[start];
        int32_t e = start, q;
        /* hull edges run clockwise: e -> q is visible from the point when (point, e, q) turns counter-clockwise */
        while (q = hnext[e], ccw(x, y, X(e), Y(e), X(q), Y(q)) <= 0) {
            e = q;
            if (e == start) {
                e = -1;
                break;
            }
        }
        if (e == -1) { /* on or inside the hull: a repeated point */
            (*repeats)++;
            continue;
        }
        int64_t t = add_tri(&d, e, i, hnext[e], -1, -1, htri[e]);
        int64_t r = legalize(&d, t + 2);
        if (r < -1) FAIL;
        htri[i] = (int32_t)r;
        htri[e] = (int32_t)t;
        int32_t nn = hnext[e];
        while (q = hnext[nn], ccw(x, y, X(nn), Y(nn), X(q), Y(q)) > 0) {
            t = add_tri(&d, nn, i, q, htri[i], -1, htri[nn]);
            r = legalize(&d, t + 2);
            if (r < -1) FAIL;
            htri[i] = (int32_t)r;
            hnext[nn] = nn; /* removed from the hull */
            nn = q;
        }
        if (e == start) {
            while (q = hprev[e], ccw(x, y, X(q), Y(q), X(e), Y(e)) > 0) {
                t = add_tri(&d, q, i, e, -1, htri[e], htri[q]);
                if (legalize(&d, t + 2) < -1) FAIL;
                htri[q] = (int32_t)t;
                hnext[e] = e;
                e = q;
            }
        }
        d.hstart = hprev[i] = e;
        hnext[e] = hprev[nn] = i;
        hnext[i] = nn;
        hhash[key] = i;
        hhash[hash_key(&d, (double)X(e), (double)Y(e))] = e;
        if (ahead >= 0) {
            int32_t h = hprev[ahead], ht = htri[h];
            PREFETCH(&pts[2 * h]);
            PREFETCH(&hnext[h]);
            PREFETCH(&half[ht]);
            PREFETCH(&triangles[ht]);
        }
    }
    result = d.tlen / 3;
    stack = d.stack;
    *order_out = order; /* the caller maps insertion positions to input indices, and frees it */
    order = NULL;
done:
    free(order);
    free(pts);
    free(half);
    free(hprev);
    free(hnext);
    free(htri);
    free(hhash);
    free(stack);
    return result;
}

/*
 * Delaunay triangles of n points with integer coordinates (differences below 2^30 after the
 * caller's quantisation). triangles: room for 3 * (2n) int32 vertex indices (into the input order).
 * Returns the number of triangles (0 when all points are collinear or repeated), -1 when
 * memory runs out. Repeated points: one of them is used, the others are in no triangle; *repeats
 * is set to the number left out.
 */
int64_t gt_delaunay(int64_t n, const int64_t *xin, const int64_t *yin, int32_t *triangles, int64_t *repeats) {
    Pair *order = NULL;
    int64_t m = triangulate(n, xin, yin, triangles, repeats, &order);
    if (m > 0)
        for (int64_t k = 0; k < 3 * m; k++) triangles[k] = order[triangles[k]].id; /* back to input indices */
    free(order);
    return m;
}

/* integer coordinates of v: rint((v - v0) * scale); returns the largest distance to an integer */
SIMD_CLONES double gt_quantise(int64_t n, const double *v, double v0, double scale, int64_t *out) {
    double worst = 0;
    for (int64_t i = 0; i < n; i++) {
        double r = (v[i] - v0) * scale;
        double q = nearbyint(r);
        double e = fabs(r - q);
        if (e > worst) worst = e;
        out[i] = (int64_t)q;
    }
    return worst;
}

int64_t gt_rasterize(int64_t ntri, const int32_t *tri, const double *u, const double *v, const double *z, int32_t width,
                     int32_t height, double max_edge2, double *out, const double *box, uint8_t *exact);

/*
 * The TIN of (x, y, z) evaluated at the cell centres of a grid: gt_delaunay + repeats merged
 * (mean z) + gt_rasterize, with every array in insertion order (cache friendly). ix, iy: integer
 * coordinates; u, v: positions in cell units (see gt_rasterize); out: height x width; box, exact:
 * see gt_rasterize. Returns the number of triangles (-1: out of memory); *repeats: points merged
 * into another.
 */
int64_t gt_tin_grid(int64_t n, const int64_t *ix, const int64_t *iy, const double *u, const double *v, const double *z,
                    int32_t width, int32_t height, double max_edge2, double *out, int64_t *repeats, const double *box,
                    uint8_t *exact) {
    int64_t result = -1;
    Pair *order = NULL;
    int32_t *tri = (int32_t *)malloc((size_t)(6 * (n > 0 ? n : 1)) * sizeof(int32_t));
    double *us = NULL, *vs = NULL, *zs = NULL, *cnt = NULL;
    uint8_t *used = NULL;
    if (!tri) return -1;
    int64_t m = triangulate(n, ix, iy, tri, repeats, &order);
    if (m <= 0) {
        result = m;
        goto done;
    }
    us = (double *)malloc((size_t)n * sizeof(double));
    vs = (double *)malloc((size_t)n * sizeof(double));
    zs = (double *)malloc((size_t)n * sizeof(double));
    if (!us || !vs || !zs) goto done;
    for (int64_t k = 0; k < n; k++) {
        int32_t id = order[k].id;
        us[k] = u[id];
        vs[k] = v[id];
        zs[k] = z[id];
    }
    if (*repeats > 0) { /* a repeat takes no part: its z joins the mean of the copy that does */
        used = (uint8_t *)calloc((size_t)n, 1);
        cnt = (double *)malloc((size_t)n * sizeof(double));
        if (!used || !cnt) goto done;
        for (int64_t k = 0; k < 3 * m; k++) used[tri[k]] = 1;
        for (int64_t k = 0; k < n; k++) cnt[k] = 1;
        for (int64_t k = 0; k < n; k++) {
            if (used[k]) continue;
            int64_t master = -1; /* a used point at the same position has the same key: search the run of equal keys */
            for (int64_t j = k - 1; j >= 0 && order[j].key == order[k].key; j--)
                if (used[j] && ix[order[j].id] == ix[order[k].id] && iy[order[j].id] == iy[order[k].id]) {
                    master = j;
                    break;
                }
            for (int64_t j = k + 1; master < 0 && j < n && order[j].key == order[k].key; j++)
                if (used[j] && ix[order[j].id] == ix[order[k].id] && iy[order[j].id] == iy[order[k].id]) master = j;
            if (master < 0) continue;
            zs[master] += zs[k];
            cnt[master] += 1;
        }
        for (int64_t k = 0; k < n; k++)
            if (cnt[k] > 1) zs[k] /= cnt[k];
    }
    gt_rasterize(m, tri, us, vs, zs, width, height, max_edge2, out, box, exact);
    result = m;
done:
    free(order);
    free(tri);
    free(us);
    free(vs);
    free(zs);
    free(cnt);
    free(used);
    return result;
}

/*
 * Linear interpolation of z over triangles at the cell centres they cover. u, v: positions in
 * cell units from the grid's west / north edge (a centre is at col + 0.5, row + 0.5). A centre
 * on an edge (barycentric weights >= -1e-9) takes the value of the last triangle holding it.
 * Triangles with an edge longer than sqrt(max_edge2) (cell units; < 0: no limit) are skipped.
 * out: height x width, row-major; only covered cells are written. Returns the cells written.
 *
 * box (u0, v0, u1, v1; or NULL) and exact (height x width, or NULL): when the points given are
 * all the points inside the box, a triangle whose circumcircle lies inside the box is a Delaunay
 * triangle of every larger point set too; exact[cell] is set to 1 for the centres such triangles
 * hold (whether written or skipped for a long edge), so the caller knows which cells a TIN of a
 * wider area would give the same value (or nodata).
 */
/* min / max of finite doubles (fmin / fmax are library calls without -ffast-math, for NaN rules not needed here) */
static inline double dmin(double a, double b) { return a < b ? a : b; }
static inline double dmax(double a, double b) { return a > b ? a : b; }
/* (int64_t)floor(a) and (int64_t)ceil(a) of a finite a within int64 range, without the library call (baseline
 * x86-64 has no rounding instruction): a triangle's range of centres, four per triangle */
static inline int64_t ifloor(double a) {
    int64_t i = (int64_t)a; /* toward zero */
    return i - (a < (double)i);
}
static inline int64_t iceil(double a) {
    int64_t i = (int64_t)a;
    return i + (a > (double)i);
}

int64_t gt_rasterize(int64_t ntri, const int32_t *tri, const double *u, const double *v, const double *z, int32_t width,
                     int32_t height, double max_edge2, double *out, const double *box, uint8_t *exact) {
    int64_t written = 0;
    const double eps = -1e-9;
    for (int64_t t = 0; t < ntri; t++) {
        if (t + 16 < ntri) { /* the vertices of a triangle ahead: in sweep order, a ring of the sweep apart */
            const int32_t *ahead = tri + 3 * (t + 16);
            for (int k = 0; k < 3; k++) {
                PREFETCH(&u[ahead[k]]);
                PREFETCH(&v[ahead[k]]);
            }
        }
        int32_t a = tri[3 * t], b = tri[3 * t + 1], c = tri[3 * t + 2];
        double ax = u[a], ay = v[a], bx = u[b], by = v[b], cx = u[c], cy = v[c];
        double xmin = dmin(ax, dmin(bx, cx)), xmax = dmax(ax, dmax(bx, cx));
        double ymin = dmin(ay, dmin(by, cy)), ymax = dmax(ay, dmax(by, cy));
        int64_t r0 = iceil(ymin - 0.5), r1 = ifloor(ymax - 0.5);
        int64_t c0 = iceil(xmin - 0.5), c1 = ifloor(xmax - 0.5);
        if (r1 < r0 || c1 < c0) continue; /* no centre in the bounding box: most triangles */
        if (r0 < 0) r0 = 0;
        if (r1 > height - 1) r1 = height - 1;
        if (c0 < 0) c0 = 0;
        if (c1 > width - 1) c1 = width - 1;
        if (r1 < r0 || c1 < c0) continue;
        int write = 1, safe = 0;
        if (max_edge2 >= 0) {
            double e1 = (ax - bx) * (ax - bx) + (ay - by) * (ay - by);
            double e2 = (bx - cx) * (bx - cx) + (by - cy) * (by - cy);
            double e3 = (cx - ax) * (cx - ax) + (cy - ay) * (cy - ay);
            if (dmax(e1, dmax(e2, e3)) > max_edge2) write = 0;
        }
        double det = (by - cy) * (ax - cx) + (cx - bx) * (ay - cy);
        if (det == 0) continue;
        if (exact) { /* circumcircle inside the box, with a margin for rounding */
            double dx = bx - ax, dy = by - ay, ex = cx - ax, ey = cy - ay;
            double bl = dx * dx + dy * dy, cl = ex * ex + ey * ey, dd = dx * ey - dy * ex;
            double ox = ax + (ey * bl - dy * cl) * 0.5 / dd, oy = ay + (dx * cl - ex * bl) * 0.5 / dd;
            double r = sqrt((ox - ax) * (ox - ax) + (oy - ay) * (oy - ay)) * (1 + 1e-9) + 1e-9;
            safe = ox - r > box[0] && oy - r > box[1] && ox + r < box[2] && oy + r < box[3];
        }
        if (!write && !safe) continue;
        double inv = 1.0 / det;
        double za = z[a], zb = z[b], zc = z[c];
        const int narrow = c1 - c0 <= 2; /* at most 3 centres a row: each tested, without the edge crossings */
        for (int64_t r = r0; r <= r1; r++) {
            double py = r + 0.5 - cy;
            int64_t k0 = c0, k1 = c1;
            if (!narrow) {
                /* the columns of this row inside the triangle: from the edges the row line crosses */
                double lo = INFINITY, hi = -INFINITY, yy = r + 0.5;
                const double px_[3] = {ax, bx, cx}, py_[3] = {ay, by, cy};
                for (int k = 0; k < 3; k++) {
                    double x1 = px_[k], y1 = py_[k], x2 = px_[(k + 1) % 3], y2 = py_[(k + 1) % 3];
                    if ((y1 - yy) * (y2 - yy) > 0) continue;
                    if (y1 == y2) {
                        lo = dmin(lo, dmin(x1, x2));
                        hi = dmax(hi, dmax(x1, x2));
                    } else {
                        double xx = x1 + (yy - y1) * (x2 - x1) / (y2 - y1);
                        lo = dmin(lo, xx);
                        hi = dmax(hi, xx);
                    }
                }
                if (!(hi >= lo)) continue;
                k0 = (int64_t)ceil(lo - 0.5) - 1; /* one spare column each side: a centre a cell outside the */
                k1 = (int64_t)floor(hi - 0.5) + 1; /* triangle fails the weight test below by far */
                if (k0 < c0) k0 = c0;
                if (k1 > c1) k1 = c1;
            }
            for (int64_t col = k0; col <= k1; col++) {
                double px = col + 0.5 - cx;
                double w1 = ((by - cy) * px + (cx - bx) * py) * inv;
                double w2 = ((cy - ay) * px + (ax - cx) * py) * inv;
                double w3 = 1.0 - w1 - w2;
                if (w1 >= eps && w2 >= eps && w3 >= eps) {
                    if (write) {
                        out[r * (int64_t)width + col] = w1 * za + w2 * zb + w3 * zc;
                        written++;
                    }
                    if (safe) exact[r * (int64_t)width + col] = 1;
                }
            }
        }
    }
    return written;
}

/* ------------------------------------------------------------------ grid morphology (lidar/ground.py: SMRF)
 * `iterations` grey dilations (is_max = 1) or erosions (0) of a rows x cols row-major grid by the 4-neighbour
 * cross (a diamond of radius `iterations`); edges use the neighbours they have. `out` and `work` are
 * caller-owned arrays of the same size; the result is in `out`. Values are finite (the caller fills gaps).
 */
SIMD_CLONES static void cross_row(const double *row, const double *up, const double *down, double *o, int64_t cols, int is_max) {
    /* up / down: the rows above and below, or the row itself at the grid's edge (max(x, x) = x) */
    if (cols == 1) {
        double v = row[0];
        v = is_max ? dmax(v, dmax(up[0], down[0])) : dmin(v, dmin(up[0], down[0]));
        o[0] = v;
        return;
    }
    if (is_max) {
        o[0] = dmax(dmax(row[0], row[1]), dmax(up[0], down[0]));
        for (int64_t c = 1; c < cols - 1; c++)
            o[c] = dmax(dmax(dmax(row[c - 1], row[c]), row[c + 1]), dmax(up[c], down[c]));
        o[cols - 1] = dmax(dmax(row[cols - 2], row[cols - 1]), dmax(up[cols - 1], down[cols - 1]));
    } else {
        o[0] = dmin(dmin(row[0], row[1]), dmin(up[0], down[0]));
        for (int64_t c = 1; c < cols - 1; c++)
            o[c] = dmin(dmin(dmin(row[c - 1], row[c]), row[c + 1]), dmin(up[c], down[c]));
        o[cols - 1] = dmin(dmin(row[cols - 2], row[cols - 1]), dmin(up[cols - 1], down[cols - 1]));
    }
}

void gt_cross_filter(const double *in, double *out, double *work, int64_t rows, int64_t cols, int32_t is_max,
                     int32_t iterations) {
    int64_t n = rows * cols;
    const double *src = in;
    double *bufs[2] = {out, work};
    int which = (iterations % 2 == 1) ? 0 : 1; /* ping-pong so that the last pass lands in out */
    if (iterations <= 0) {
        memcpy(out, in, (size_t)n * sizeof(double));
        return;
    }
    for (int32_t it = 0; it < iterations; it++) {
        double *dst = bufs[which];
        for (int64_t r = 0; r < rows; r++) {
            const double *row = src + r * cols;
            cross_row(row, r > 0 ? row - cols : row, r < rows - 1 ? row + cols : row, dst + r * cols, cols, is_max);
        }
        src = dst;
        which ^= 1;
    }
}

/* Ring-by-ring gap filling (lidar/ground.py fill_gaps): each NaN cell with a filled 8-neighbour takes the mean of
 * its filled neighbours, summed in the order NW, N, NE, W, E, SW, S, SE, from the grid as it was before the
 * ring; up to `rings` rings. `prev` is caller-owned scratch of the same size. Returns the cells still empty. */
int64_t gt_fill_rings(double *z, double *prev, int64_t rows, int64_t cols, int32_t rings) {
    int64_t n = rows * cols, left = 0;
    for (int64_t i = 0; i < n; i++) left += isnan(z[i]) ? 1 : 0;
    for (int32_t ring = 0; ring < rings && left > 0; ring++) {
        memcpy(prev, z, (size_t)n * sizeof(double));
        int64_t filled = 0;
        for (int64_t r = 0; r < rows; r++) {
            for (int64_t c = 0; c < cols; c++) {
                int64_t i = r * cols + c;
                if (!isnan(prev[i])) continue;
                double sum = 0.0;
                int cnt = 0;
                for (int dr = -1; dr <= 1; dr++) {
                    int64_t rr = r + dr;
                    if (rr < 0 || rr >= rows) continue;
                    for (int dc = -1; dc <= 1; dc++) {
                        int64_t cc = c + dc;
                        if ((dr == 0 && dc == 0) || cc < 0 || cc >= cols) continue;
                        double v = prev[rr * cols + cc];
                        if (!isnan(v)) {
                            sum += v;
                            cnt++;
                        }
                    }
                }
                if (cnt) {
                    z[i] = sum / cnt;
                    filled++;
                }
            }
        }
        if (!filled) break;
        left -= filled;
    }
    return left;
}

/* `iterations` cross dilations (is_max) or erosions of rows [r0, r1) of `in` into the same rows of `out`, through a
 * stripe of the rows around them held in `a` / `b` (each (r1 - r0 + 2 * iterations) * cols doubles), so that the
 * passes run in cache. Each pass computes the rows the previous one left valid: at the grid's own edges every row,
 * at the stripe's cut one row fewer on that side; after `iterations` passes rows [r0, r1) are exact. */
static void cross_stripe(const double *in, double *out, double *a, double *b, int64_t rows, int64_t cols, int64_t r0,
                         int64_t r1, int32_t is_max, int32_t iterations) {
    int64_t lo = r0 - iterations < 0 ? 0 : r0 - iterations;
    int64_t hi = r1 + iterations > rows ? rows : r1 + iterations;
    memcpy(a, in + lo * cols, (size_t)((hi - lo) * cols) * sizeof(double));
    double *src = a, *dst = b;
    for (int32_t k = 1; k <= iterations; k++) {
        int64_t from = lo == 0 ? 0 : lo + k, to = hi == rows ? rows : hi - k;
        for (int64_t r = from; r < to; r++) {
            const double *row = src + (r - lo) * cols;
            cross_row(row, r > 0 ? row - cols : row, r < rows - 1 ? row + cols : row, dst + (r - lo) * cols, cols, is_max);
        }
        double *t = src;
        src = dst;
        dst = t;
    }
    memcpy(out + r0 * cols, src + (r0 - lo) * cols, (size_t)((r1 - r0) * cols) * sizeof(double));
}

#define SQUARE45_FROM 6 /* the radius from which the decomposition is the cheaper (measured) */

/* obj[i] = 1 where the opened surface drops by more than thr from the previous one, cells [i0, i1). */
static void mark_drops(const double *prev, const double *open, uint8_t *obj, int64_t i0, int64_t i1, double thr) {
    for (int64_t i = i0; i < i1; i++) {
        if (prev[i] - open[i] > thr) obj[i] = 1;
    }
}

/* Forward running maxima along a diagonal, in place: X[b][c] = max over s in [0, len) of X[b + s][c + d * s]
 * (d = -1 or +1), by doubling (shifts 1, 2, 4, ... then the rest, windows overlapping); reads past the buffer are
 * skipped (the caller never uses the cells that would need them). */
SIMD_CLONES static void diagonal_max(double *x, int64_t h, int64_t w, int64_t len, int d) {
    int64_t m = 1;
    while (m < len) {
        int64_t s = 2 * m <= len ? m : len - m;
        for (int64_t b = 0; b + s < h; b++) {
            double *restrict row = x + b * w;
            const double *restrict src = x + (b + s) * w + d * s;
            int64_t c0 = d < 0 ? s : 0, c1 = d < 0 ? w : w - s;
            for (int64_t c = c0; c < c1; c++) row[c] = dmax(row[c], src[c]);
        }
        m += s;
    }
}

/* The grey dilation of rows [r0, r1) by the square of half-width `hw` turned 45 degrees, {(s + t, t - s): |s|, |t| <=
 * hw} (the even points of the diamond of radius 2 hw), as two diagonal running maxima over a copy of the rows
 * around them padded with -inf; cells outside the grid take no part (as in cross_row). `buf` holds
 * (r1 - r0 + 4 hw) * (cols + 4 hw) doubles. */
static void square45_stripe(const double *in, double *out, double *buf, int64_t rows, int64_t cols, int64_t r0, int64_t r1,
                            int64_t hw) {
    int64_t p = 2 * hw, h = r1 - r0 + 2 * p, w = cols + 2 * p;
    for (int64_t b = 0; b < h; b++) {
        double *row = buf + b * w;
        int64_t r = r0 - p + b;
        for (int64_t c = 0; c < p; c++) row[c] = -INFINITY;
        for (int64_t c = cols + p; c < w; c++) row[c] = -INFINITY;
        if (r < 0 || r >= rows) {
            for (int64_t c = p; c < cols + p; c++) row[c] = -INFINITY;
        } else {
            memcpy(row + p, in + r * cols, (size_t)cols * sizeof(double));
        }
    }
    diagonal_max(buf, h, w, 2 * hw + 1, -1);
    diagonal_max(buf, h, w, 2 * hw + 1, +1);
    for (int64_t b = 0; b < r1 - r0; b++) memcpy(out + (r0 + b) * cols, buf + b * w + p, (size_t)cols * sizeof(double));
}

/* The progressive morphological filter of SMRF (lidar/ground.py progressive_filter) in one call: for radius
 * 1 ... max_radius, the surface eroded by the diamond of that radius (one more cross erosion each step) and dilated
 * back `radius` times; obj[i] = 1 where the opened surface drops by more than slope_z * cell * radius from the
 * previous one. The dilations run stripe by stripe (cross_stripe), the same values as whole-grid passes.
 * `work` holds 4 * rows * cols doubles. */
void gt_progressive(const double *z, uint8_t *obj, double *work, int64_t rows, int64_t cols, double cell, double slope_z,
                    int32_t max_radius) {
    int64_t n = rows * cols;
    double *prev = work, *eros = work + n, *open = work + 2 * n, *tmp = work + 3 * n;
    int64_t stripe = 128, sq_stripe = 64;
    size_t buf = (size_t)((stripe + 2 * (int64_t)max_radius) * cols);
    size_t sq_buf = (size_t)((sq_stripe + 2 * (int64_t)max_radius) * (cols + 2 * (int64_t)max_radius));
    double *a = malloc(buf * sizeof(double)), *b = malloc(buf * sizeof(double)), *sq = malloc(sq_buf * sizeof(double));
    if (!a || !b || !sq) { /* no memory for stripes: whole-grid passes */
        free(a);
        free(b);
        free(sq);
        a = NULL;
        sq = NULL;
    }
    memcpy(prev, z, (size_t)n * sizeof(double));
    memcpy(eros, z, (size_t)n * sizeof(double));
    for (int32_t radius = 1; radius <= max_radius; radius++) {
        double thr = slope_z * cell * radius, *t;
        gt_cross_filter(eros, open, tmp, rows, cols, 0, 1); /* the erosion by one more cross, into the free buffer */
        t = eros;
        eros = open;
        open = t;
        if (!a) {
            gt_cross_filter(eros, open, tmp, rows, cols, 1, radius);
            mark_drops(prev, open, obj, 0, n, thr);
        } else if (radius >= SQUARE45_FROM) {
            /* the diamond of radius r = the 45-degree square of half-width (r - 1) / 2, then one cross (r odd) or
             * two (r even): a dozen cheap passes instead of r crosses; stripe by stripe, the square's rows (and the
             * ones the crosses read around them) in tmp, the crosses into open, the drops marked while in cache */
            int64_t hw = (radius - 1) / 2;
            int32_t crosses = radius - 2 * (int32_t)hw;
            for (int64_t r0 = 0; r0 < rows; r0 += sq_stripe) {
                int64_t r1 = r0 + sq_stripe < rows ? r0 + sq_stripe : rows;
                int64_t lo = r0 - crosses > 0 ? r0 - crosses : 0, hi = r1 + crosses < rows ? r1 + crosses : rows;
                square45_stripe(eros, tmp, sq, rows, cols, lo, hi, hw);
                cross_stripe(tmp, open, a, b, rows, cols, r0, r1, 1, crosses);
                mark_drops(prev, open, obj, r0 * cols, r1 * cols, thr);
            }
        } else {
            for (int64_t r0 = 0; r0 < rows; r0 += stripe) {
                int64_t r1 = r0 + stripe < rows ? r0 + stripe : rows;
                cross_stripe(eros, open, a, b, rows, cols, r0, r1, 1, radius);
                mark_drops(prev, open, obj, r0 * cols, r1 * cols, thr);
            }
        }
        t = prev;
        prev = open;
        open = t;
    }
    free(a);
    free(b);
    free(sq);
}

/* fill_gaps' rings by their fronts: the same values as gt_fill_rings (each ring: every NaN cell with a filled
 * 8-neighbour takes the mean of its filled neighbours as the grid was before the ring, summed NW, N, NE, W, E, SW, S,
 * SE), but each ring after the first visits only the cells next to the last one. `cap`: the grid's empty cells;
 * `work` holds 2 * cap int64, `vals` cap doubles, `mark` rows * cols bytes (caller-owned). Returns the cells still
 * empty (-1 when rings <= 0). */
static int64_t front_neighbours(const double *z, const uint8_t *mark, int64_t rows, int64_t cols, int64_t i, int64_t *out,
                                int want_empty) {
    int64_t r = i / cols, c = i % cols, k = 0;
    for (int dr = -1; dr <= 1; dr++) {
        int64_t rr = r + dr;
        if (rr < 0 || rr >= rows) continue;
        for (int dc = -1; dc <= 1; dc++) {
            int64_t cc = c + dc;
            if ((dr == 0 && dc == 0) || cc < 0 || cc >= cols) continue;
            int64_t j = rr * cols + cc;
            if (want_empty ? (isnan(z[j]) && !mark[j]) : !isnan(z[j])) out[k++] = j;
        }
    }
    return k;
}

static inline int cell_mean8(const double *z, int64_t rows, int64_t cols, int64_t r, int64_t c, double *mean) {
    double sum = 0.0;
    int cnt = 0;
    if (r > 0 && r < rows - 1 && c > 0 && c < cols - 1) { /* inside: the 8 neighbours, NW ... SE, no bounds tests */
        const double *up = z + (r - 1) * cols + c, *mid = up + cols, *down = mid + cols;
        double v[8] = {up[-1], up[0], up[1], mid[-1], mid[1], down[-1], down[0], down[1]};
        for (int k = 0; k < 8; k++) {
            if (!isnan(v[k])) {
                sum += v[k];
                cnt++;
            }
        }
        if (cnt) *mean = sum / cnt;
        return cnt;
    }
    for (int dr = -1; dr <= 1; dr++) {
        int64_t rr = r + dr;
        if (rr < 0 || rr >= rows) continue;
        for (int dc = -1; dc <= 1; dc++) {
            int64_t cc = c + dc;
            if ((dr == 0 && dc == 0) || cc < 0 || cc >= cols) continue;
            double v = z[rr * cols + cc];
            if (!isnan(v)) {
                sum += v;
                cnt++;
            }
        }
    }
    if (cnt) *mean = sum / cnt;
    return cnt;
}

int64_t gt_fill_front(double *z, int64_t rows, int64_t cols, int32_t rings, int64_t cap, int64_t *work, uint8_t *mark,
                      double *vals) {
    int64_t n = rows * cols, nfront = 0, left = 0, nb[8];
    int64_t *front = work, *next = work + cap;
    if (rings <= 0) return -1;
    memset(mark, 0, (size_t)n);
    /* the first ring over the whole grid (most empty cells of a sparse lattice are in it) */
    for (int64_t r = 0; r < rows; r++) {
        for (int64_t c = 0; c < cols; c++) {
            int64_t i = r * cols + c;
            if (!isnan(z[i])) continue;
            left++;
            if (cell_mean8(z, rows, cols, r, c, &vals[nfront])) {
                front[nfront++] = i;
                mark[i] = 1;
            }
        }
    }
    for (int32_t ring = 0; nfront > 0; ring++) {
        for (int64_t f = 0; f < nfront; f++) z[front[f]] = vals[f];
        left -= nfront;
        if (ring + 1 >= rings) break;
        int64_t nnext = 0;
        for (int64_t f = 0; f < nfront; f++) { /* the next front: empty neighbours of the cells just filled */
            int64_t k = front_neighbours(z, mark, rows, cols, front[f], nb, 1);
            for (int64_t j = 0; j < k; j++) {
                mark[nb[j]] = 1;
                next[nnext++] = nb[j];
            }
        }
        for (int64_t f = 0; f < nnext; f++) /* their means, from the grid before this ring */
            cell_mean8(z, rows, cols, next[f] / cols, next[f] % cols, &vals[f]);
        int64_t *t = front;
        front = next;
        next = t;
        nfront = nnext;
    }
    return left;
}

/* Bilinear values of a rows x cols surface (cell centres at col + 0.5, row + 0.5) at n points given in CRS units:
 * u = x / cell - col0, v = row_top - y / cell, clamped to the centres (lidar/ground.py _bilinear_at / _bilinear: the
 * same operations in the same order, so the same values). */
void gt_bilinear(const double *surf, int64_t rows, int64_t cols, int64_t n, const double *x, const double *y,
                 double cell, int64_t col0, int64_t row_top, double *out) {
    int64_t cmax = cols - 2 > 0 ? cols - 2 : 0, rmax = rows - 2 > 0 ? rows - 2 : 0;
    int64_t dc = cols > 1 ? 1 : 0, dr = rows > 1 ? cols : 0;
    for (int64_t k = 0; k < n; k++) {
        double fu = x[k] / cell - (double)col0 - 0.5, fv = ((double)row_top - y[k] / cell) - 0.5;
        fu = fu > 0 ? fu : 0;
        fu = fu < (double)(cols - 1) ? fu : (double)(cols - 1);
        fv = fv > 0 ? fv : 0;
        fv = fv < (double)(rows - 1) ? fv : (double)(rows - 1);
        int64_t c0 = (int64_t)fu, r0 = (int64_t)fv;
        c0 = c0 < cmax ? c0 : cmax;
        r0 = r0 < rmax ? r0 : rmax;
        double tu = fu - (double)c0, tv = fv - (double)r0;
        int64_t i = r0 * cols + c0;
        double top = surf[i] * (1 - tu) + surf[i + dc] * tu;
        double bottom = surf[i + dr] * (1 - tu) + surf[i + dr + dc] * tu;
        out[k] = top * (1 - tv) + bottom * tv;
    }
}

/* SMRF's per-cell threshold: threshold + scalar * |gradient| / z_per_xy, the gradient as numpy.gradient gives it
 * (central differences inside, one-sided at the edges, spacing `cell`; 0 along an axis of one cell); the length
 * as sqrt(gx^2 + gy^2), not hypot (a tenth of the time; gradients are far from overflow). */
void gt_slope_threshold(const double *z, int64_t rows, int64_t cols, double cell, double z_per_xy, double threshold,
                        double scalar, double *out) {
    for (int64_t r = 0; r < rows; r++) {
        for (int64_t c = 0; c < cols; c++) {
            int64_t i = r * cols + c;
            double gx = 0.0, gy = 0.0;
            if (cols > 1)
                gx = c == 0 ? (z[i + 1] - z[i]) / cell
                     : c == cols - 1 ? (z[i] - z[i - 1]) / cell : (z[i + 1] - z[i - 1]) / (2. * cell);
            if (rows > 1)
                gy = r == 0 ? (z[i + cols] - z[i]) / cell
                     : r == rows - 1 ? (z[i] - z[i - cols]) / cell : (z[i + cols] - z[i - cols]) / (2. * cell);
            out[i] = threshold + scalar * (sqrt(gx * gx + gy * gy) / z_per_xy);
        }
    }
}

/* Mean z of the points with on[k] per cell (NaN where none), summed in point order as numpy.bincount does. */
void gt_cell_mean(int64_t n, const int64_t *flat, const double *z, const uint8_t *on, int64_t ncells, double *sum,
                  int64_t *count, double *out) {
    memset(sum, 0, (size_t)ncells * sizeof(double));
    memset(count, 0, (size_t)ncells * sizeof(int64_t));
    for (int64_t k = 0; k < n; k++) {
        if (!on[k]) continue;
        sum[flat[k]] += z[k];
        count[flat[k]]++;
    }
    for (int64_t i = 0; i < ncells; i++) out[i] = count[i] > 0 ? sum[i] / (double)count[i] : NAN;
}

/* the flat cell index (row * width + col) of (x, y), -1 outside the grid: col0, top (row_top - 1), width and
 * height as doubles (grid.cell_index's float64 operations) */
static inline int64_t cell_of(double x, double y, double cell, double c0, double top, double w, double h) {
    double c = floor(x / cell) - c0;
    double r = top - floor(y / cell);
    return (c >= 0 && c < w && r >= 0 && r < h) ? (int64_t)(r * w + c) : -1;
}

/* Flat cell index (row * width + col) of each point, -1 outside the grid (grid.cell_index): the same float64
 * operations as its numpy form, in one pass. */
SIMD_CLONES void gt_cell_index(int64_t n, const double *x, const double *y, double cell, int64_t col0, int64_t row_top,
                               int64_t width, int64_t height, int64_t *out) {
    const double c0 = (double)col0, top = (double)(row_top - 1), w = (double)width, h = (double)height;
    for (int64_t i = 0; i < n; i++) out[i] = cell_of(x[i], y[i], cell, c0, top, w, h);
}

/* one point (cell c, z v, class k) into a call's maxima cm and top classes tc: higher wins; on a tie the last bare
 * one, else the last one */
static inline void top_add(double *cm, uint8_t *tc, const uint8_t *bare, int64_t c, double v, uint8_t k) {
    if (v > cm[c]) {
        cm[c] = v;
        tc[c] = k;
    } else if (v == cm[c] && (bare[k] || !bare[tc[c]])) {
        tc[c] = k;
    }
}

/* a call's maxima and top classes merged into dsm / top: higher, or equal and bare, takes the call's class */
static void top_merge(int64_t ncells, const double *cm, const uint8_t *tc, const uint8_t *bare, double *dsm,
                      uint8_t *top) {
    for (int64_t c = 0; c < ncells; c++) {
        if (cm[c] == -INFINITY) continue; /* no point of this call */
        if (cm[c] > dsm[c] || (cm[c] == dsm[c] && bare[tc[c]])) top[c] = tc[c];
        if (cm[c] > dsm[c]) dsm[c] = cm[c];
    }
}

/* The DSM's per-cell maximum of z and the class of the point giving it (lidar/accumulate.py max_with_class, the
 * same result): the points (flat cell, z, class) of one call first make the call's own maxima `cm` and top classes
 * `tc` (ties among the call's points: the last bare one, i.e. bare[class], else the last one), then these are merged
 * into `dsm` / `top` (higher, or equal and bare: the call's class). cm (doubles) and tc (bytes) are caller-owned
 * scratch of ncells, filled here. */
void gt_max_with_class(int64_t n, const int64_t *cell, const double *z, const uint8_t *cls, const uint8_t *bare,
                       int64_t ncells, double *dsm, uint8_t *top, double *cm, uint8_t *tc) {
    for (int64_t c = 0; c < ncells; c++) cm[c] = -INFINITY;
    for (int64_t i = 0; i < n; i++) top_add(cm, tc, bare, cell[i], z[i], cls[i]);
    top_merge(ncells, cm, tc, bare, dsm, top);
}

/* the i-th int32 of a field at a byte stride (point records of 34 bytes leave it unaligned: memcpy, one load) */
static inline int32_t las_int(const char *base, int64_t i, int64_t stride) {
    int32_t v;
    memcpy(&v, base + i * stride, sizeof v);
    return v;
}

/* Pass 1 of the rasters over one chunk of points (lidar/scan.py scan_chunk; the same result as its numpy form, one
 * pass instead of about fifteen). Per point: class and return-number counts (all points); for the usable ones (cell
 * >= 0, not withheld): a surface first return (surface[class], return number <= 1) goes into the DSM (with `top`:
 * the class of its highest point, by top_add / top_merge as in gt_max_with_class, cm / tc their scratch; without:
 * the max), and with `bare_first` its first-return record (bare ones counted per cell, the others' cell and float32
 * z listed); a ground point (class `gclass`) is counted per cell, its LAS integers X, Y, Z listed in `grec` (and its
 * index in `gidx` when given), and again in `hrec` with its halo strip in `hside` when it lies in one (1 west, 2
 * east, 3 south, 4 north; `edges`: west + b, east - b, south + b, north - b); it grows the extents `boxes` (5 x
 * (west, south, east, north): all ground, then the strips); a water point (class `wclass`) is counted per cell. X,
 * Y, Z: the LAS integers at a byte stride (laspy's views of the point records); `so`: their scales and offsets
 * (x, y, z scale, then x, y, z offset): x = X * xscale + xoffset, as laspy scales them. Each point's flat cell
 * index (-1 outside the grid; `gp`: cell size, col0, row_top, width, height, as gt_cell_index) goes into `cell`.
 * counts: first-return records, ground points, points outside the grid, halo records. Null `gcount`: no ground or
 * water work; null `bare_first`: no first-return records. */
SIMD_CLONES void gt_scan_chunk(int64_t n, const char *X, int64_t xstride, const char *Y, int64_t ystride, const char *Z,
                   int64_t zstride, const double *so, const double *gp, int64_t *cell, const uint8_t *cls,
                   const uint8_t *rn, const uint8_t *withheld, const uint8_t *surface, const uint8_t *bare, int64_t ncells, double *dsm, uint8_t *top, double *cm, uint8_t *tc,
                   int64_t *by_class, int64_t *by_return, int64_t *bare_first, int32_t *first_cell, float *first_z,
                   int64_t gclass, int64_t wclass, int64_t *gcount, int64_t *wcount, const double *edges, int32_t *grec,
                   int64_t *gidx, int32_t *hrec, uint8_t *hside, double *boxes, int64_t *counts) {
    int64_t nf = 0, ng = 0, nout = 0, nh = 0;
    const double xscale = so[0], yscale = so[1], zscale = so[2], xoffset = so[3], yoffset = so[4], zoffset = so[5];
    const double size = gp[0], c0 = gp[1], top_row = gp[2] - 1, w = gp[3], h = gp[4];
    if (top)
        for (int64_t c = 0; c < ncells; c++) cm[c] = -INFINITY;
    for (int64_t i = 0; i < n; i++) {
        uint8_t k = cls[i], r = rn[i];
        by_class[k]++;
        by_return[r < 15 ? r : 15]++;
        double px = (double)las_int(X, i, xstride) * xscale + xoffset;
        double py = (double)las_int(Y, i, ystride) * yscale + yoffset;
        int64_t c = cell[i] = cell_of(px, py, size, c0, top_row, w, h);
        if (c < 0) {
            nout++;
            continue;
        }
        if (withheld[i]) continue;
        if (surface[k] && r <= 1) {
            double v = (double)las_int(Z, i, zstride) * zscale + zoffset;
            if (bare_first) {
                if (bare[k]) {
                    bare_first[c]++;
                } else {
                    first_cell[nf] = (int32_t)c;
                    first_z[nf++] = (float)v;
                }
            }
            if (top) {
                top_add(cm, tc, bare, c, v, k);
            } else if (v > dsm[c]) {
                dsm[c] = v;
            }
        }
        if (!gcount) continue;
        if (k == wclass) wcount[c]++;
        if (k != gclass) continue;
        gcount[c]++;
        int32_t rec[3] = {las_int(X, i, xstride), las_int(Y, i, ystride), las_int(Z, i, zstride)};
        memcpy(grec + 3 * ng, rec, sizeof rec);
        if (gidx) gidx[ng] = i;
        ng++;
        uint8_t sd = px < edges[0] ? 1 : px > edges[1] ? 2 : py < edges[2] ? 3 : py > edges[3] ? 4 : 0;
        if (sd) {
            memcpy(hrec + 3 * nh, rec, sizeof rec);
            hside[nh++] = sd;
        }
        for (int b = 0; b < (sd ? 2 : 1); b++) {
            double *bx = boxes + 4 * (b ? sd : 0);
            if (px < bx[0]) bx[0] = px;
            if (py < bx[1]) bx[1] = py;
            if (px > bx[2]) bx[2] = px;
            if (py > bx[3]) bx[3] = py;
        }
    }
    if (top) top_merge(ncells, cm, tc, bare, dsm, top);
    counts[0] = nf;
    counts[1] = ng;
    counts[2] = nout;
    counts[3] = nh;
}

/* Per-cell minimum of z into out (which holds +inf where no point is yet), flat cell index per point. */
void gt_cell_min(int64_t n, const int64_t *flat, const double *z, double *out) {
    for (int64_t i = 0; i < n; i++) {
        if (z[i] < out[flat[i]]) out[flat[i]] = z[i];
    }
}

/* the bucket columns c0..c1 and rows r0..r1 a triangle's bounding box spans */
static void tri_buckets(const int32_t *v, const double *vx, const double *vy, double x0, double y0, double b, int64_t nbx,
                        int64_t nby, int64_t *c0, int64_t *c1, int64_t *r0, int64_t *r1) {
    double tx0 = fmin(fmin(vx[v[0]], vx[v[1]]), vx[v[2]]), tx1 = fmax(fmax(vx[v[0]], vx[v[1]]), vx[v[2]]);
    double ty0 = fmin(fmin(vy[v[0]], vy[v[1]]), vy[v[2]]), ty1 = fmax(fmax(vy[v[0]], vy[v[1]]), vy[v[2]]);
    *c0 = (int64_t)((tx0 - x0) / b);
    *c1 = (int64_t)((tx1 - x0) / b);
    *r0 = (int64_t)((ty0 - y0) / b);
    *r1 = (int64_t)((ty1 - y0) / b);
    if (*c1 >= nbx) *c1 = nbx - 1;
    if (*r1 >= nby) *r1 = nby - 1;
}

/* the bucket of a query point, nb (the last) when it lies outside the extent */
static inline int64_t query_bucket(double px, double py, double x0, double y0, double x1, double y1, double b, int64_t nbx,
                                   int64_t nby) {
    if (!(px >= x0 && px <= x1 && py >= y0 && py <= y1)) return nbx * nby;
    int64_t c = (int64_t)((px - x0) / b), r = (int64_t)((py - y0) / b);
    return (r < nby ? r : nby - 1) * nbx + (c < nbx ? c : nbx - 1);
}

/* Linear interpolation of a TIN (triangles ``tri``, vertex coordinates vx, vy in local units, heights vz) at nq query
 * points (qx, qy): out[i] = the value of the triangle holding the point, NaN outside every triangle. Triangles are
 * put into buckets of a grid over the vertices' extent (about two triangles' width a bucket, by their bounding
 * boxes; each entry holds the triangle's three vertices), the queries are taken bucket by bucket (a counting sort,
 * so a bucket's triangles stay in cache), and a query takes the triangle of its bucket it is most inside (on an
 * edge, either neighbour gives the same value). Returns 0, or -1 when memory runs out. */
int64_t gt_tin_at(int64_t ntri, const int32_t *tri, const double *vx, const double *vy, const double *vz, int64_t nv,
                  int64_t nq, const double *qx, const double *qy, double *out) {
    for (int64_t i = 0; i < nq; i++) out[i] = NAN;
    if (ntri == 0 || nv == 0 || nq == 0) return 0;
    double x0 = vx[0], y0 = vy[0], x1 = vx[0], y1 = vy[0];
    for (int64_t i = 1; i < nv; i++) {
        if (vx[i] < x0) x0 = vx[i];
        if (vx[i] > x1) x1 = vx[i];
        if (vy[i] < y0) y0 = vy[i];
        if (vy[i] > y1) y1 = vy[i];
    }
    double area = (x1 - x0) * (y1 - y0);
    double b = sqrt((area > 0 ? area : 1.0) / (double)ntri) * 2.0;
    if (!(b > 0)) b = 1.0;
    int64_t nbx = (int64_t)((x1 - x0) / b) + 1, nby = (int64_t)((y1 - y0) / b) + 1;
    while (nbx * nby > 4 * ntri + 16) {
        b *= 1.5;
        nbx = (int64_t)((x1 - x0) / b) + 1;
        nby = (int64_t)((y1 - y0) / b) + 1;
    }
    int64_t nb = nbx * nby;
    int64_t *start = calloc((size_t)(nb + 1), sizeof(int64_t));
    int64_t *qstart = calloc((size_t)(nb + 2), sizeof(int64_t));
    int64_t *fill = malloc((size_t)(nb + 1) * sizeof(int64_t));
    int64_t *qorder = malloc((size_t)nq * sizeof(int64_t));
    if (!start || !qstart || !fill || !qorder) goto oom;
    /* the triangles' buckets (by bounding box): count, then fill with vertex triplets */
    for (int64_t t = 0; t < ntri; t++) {
        int64_t c0, c1, r0, r1;
        tri_buckets(tri + 3 * t, vx, vy, x0, y0, b, nbx, nby, &c0, &c1, &r0, &r1);
        for (int64_t r = r0; r <= r1; r++)
            for (int64_t c = c0; c <= c1; c++) start[r * nbx + c + 1]++;
    }
    for (int64_t k = 0; k < nb; k++) start[k + 1] += start[k];
    int32_t *list = malloc((size_t)(start[nb] > 0 ? start[nb] : 1) * 3 * sizeof(int32_t));
    if (!list) goto oom;
    memcpy(fill, start, (size_t)nb * sizeof(int64_t));
    for (int64_t t = 0; t < ntri; t++) {
        int64_t c0, c1, r0, r1;
        tri_buckets(tri + 3 * t, vx, vy, x0, y0, b, nbx, nby, &c0, &c1, &r0, &r1);
        for (int64_t r = r0; r <= r1; r++)
            for (int64_t c = c0; c <= c1; c++) memcpy(list + 3 * fill[r * nbx + c]++, tri + 3 * t, 3 * sizeof(int32_t));
    }
    /* the queries by bucket (those outside the extent in a last bucket, left NaN) */
    for (int64_t i = 0; i < nq; i++) qstart[query_bucket(qx[i], qy[i], x0, y0, x1, y1, b, nbx, nby) + 1]++;
    for (int64_t k = 0; k <= nb; k++) qstart[k + 1] += qstart[k];
    memcpy(fill, qstart, (size_t)(nb + 1) * sizeof(int64_t));
    for (int64_t i = 0; i < nq; i++) qorder[fill[query_bucket(qx[i], qy[i], x0, y0, x1, y1, b, nbx, nby)]++] = i;
    for (int64_t k = 0; k < nb; k++) {
        for (int64_t a = qstart[k]; a < qstart[k + 1]; a++) {
            int64_t i = qorder[a];
            double px = qx[i], py = qy[i];
            double best = -1e-9, value = NAN;
            for (int64_t j = start[k]; j < start[k + 1]; j++) {
                const int32_t *v = list + 3 * j;
                double ax = vx[v[0]], ay = vy[v[0]], bx = vx[v[1]], by = vy[v[1]], cx = vx[v[2]], cy = vy[v[2]];
                double d = (by - cy) * (ax - cx) + (cx - bx) * (ay - cy);
                if (d == 0) continue;
                double l1 = ((by - cy) * (px - cx) + (cx - bx) * (py - cy)) / d;
                double l2 = ((cy - ay) * (px - cx) + (ax - cx) * (py - cy)) / d;
                double l3 = 1.0 - l1 - l2;
                double m = fmin(fmin(l1, l2), l3);
                if (m > best) {
                    best = m;
                    value = l1 * vz[v[0]] + l2 * vz[v[1]] + l3 * vz[v[2]];
                    if (m >= 0) break;
                }
            }
            out[i] = value;
        }
    }
    free(list);
    free(start);
    free(qstart);
    free(fill);
    free(qorder);
    return 0;
oom:
    free(start);
    free(qstart);
    free(fill);
    free(qorder);
    return -1;
}

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_tinkernel",
                                    "Compiled Delaunay triangulation, TIN rasterisation and grid morphology (called through ctypes).", -1,
                                    NULL};

PyMODINIT_FUNC PyInit__tinkernel(void) { return PyModule_Create(&module); }
