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
 *
 * Also here: the TIN's linear interpolation at grid cell centres (gt_rasterize, gt_tin_grid) and at points
 * (gt_tin_at). Called through cffi (gistools/kernel.py); every entry point's prototype is in gistools_kernel.h.
 */
#include "common.h"
#include "int128.h"


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
    /* each of the permanent's six products below is at most m^2 (m the largest squared length): a determinant
     * beyond 6e-13 m^2 is conclusive without it */
    double m = ap > bp ? ap : bp;
    m = m > cp ? m : cp;
    double quick = 6e-13 * m * m;
    if (det > quick) return 1;
    if (det < -quick) return -1;
    double perm = fabs(Dx) * (fabs(Ey * cp) + fabs(bp * Fy)) + fabs(Dy) * (fabs(Ex * cp) + fabs(bp * Fx)) +
                  ap * (fabs(Ex * Fy) + fabs(Ey * Fx));
    double bound = 1e-13 * perm;
    if (det > bound) return 1;
    if (det < -bound) return -1;
    return incircle_exact_sign(dx, dy, ex, ey, fx, fy);
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
    /* the queries' buckets first (those outside the extent in a last bucket, left NaN): only buckets that hold a
     * query take triangles (a few queries in a large TIN: the lists stay small; each bucket's triangles and their
     * order are the same, so are the values) */
    for (int64_t i = 0; i < nq; i++) qstart[query_bucket(qx[i], qy[i], x0, y0, x1, y1, b, nbx, nby) + 1]++;
    for (int64_t k = 0; k <= nb; k++) qstart[k + 1] += qstart[k];
    /* the triangles' buckets (by bounding box): count, then fill with vertex triplets */
    for (int64_t t = 0; t < ntri; t++) {
        int64_t c0, c1, r0, r1;
        tri_buckets(tri + 3 * t, vx, vy, x0, y0, b, nbx, nby, &c0, &c1, &r0, &r1);
        for (int64_t r = r0; r <= r1; r++)
            for (int64_t c = c0; c <= c1; c++)
                if (qstart[r * nbx + c + 1] > qstart[r * nbx + c]) start[r * nbx + c + 1]++;
    }
    for (int64_t k = 0; k < nb; k++) start[k + 1] += start[k];
    int32_t *list = malloc((size_t)(start[nb] > 0 ? start[nb] : 1) * 3 * sizeof(int32_t));
    if (!list) goto oom;
    memcpy(fill, start, (size_t)nb * sizeof(int64_t));
    for (int64_t t = 0; t < ntri; t++) {
        int64_t c0, c1, r0, r1;
        tri_buckets(tri + 3 * t, vx, vy, x0, y0, b, nbx, nby, &c0, &c1, &r0, &r1);
        for (int64_t r = r0; r <= r1; r++)
            for (int64_t c = c0; c <= c1; c++)
                if (qstart[r * nbx + c + 1] > qstart[r * nbx + c])
                    memcpy(list + 3 * fill[r * nbx + c]++, tri + 3 * t, 3 * sizeof(int32_t));
    }
    /* the queries by bucket */
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


/* Each point's height above the least-squares plane through its Delaunay neighbours, itself left out
 * (lidar/ground.py plane_residuals; its numpy form makes the same float64 operations in the same order). Each of
 * the ntri triangles `tri` is taken clockwise; its directed edges a -> b (0 -> 1, 1 -> 2, 2 -> 0) add b's offsets
 * from a to a's sums (count, dx, dy, dz, dx dx, dx dy, dy dy, dx dz, dy dz: 9 doubles a point in the caller's
 * `sums`), so an inner vertex meets each neighbour once and a hull vertex all but one. `out` (n): the plane's
 * height at the point below the point, NaN with fewer than 3 edges or neighbours that do not span a plane. */
void gt_plane_residuals(int64_t n, const double *x, const double *y, const double *z, int64_t ntri,
                        const int32_t *tri, double *sums, double *out) {
    memset(sums, 0, (size_t)n * 9 * sizeof(double));
    for (int64_t t = 0; t < ntri; t++) {
        int64_t v[3] = {tri[3 * t], tri[3 * t + 1], tri[3 * t + 2]};
        double area = (x[v[1]] - x[v[0]]) * (y[v[2]] - y[v[0]]) - (x[v[2]] - x[v[0]]) * (y[v[1]] - y[v[0]]);
        if (area > 0) {
            int64_t keep = v[1];
            v[1] = v[2];
            v[2] = keep;
        }
        for (int k = 0; k < 3; k++) {
            int64_t a = v[k], b = v[(k + 1) % 3];
            double dx = x[b] - x[a], dy = y[b] - y[a], dz = z[b] - z[a];
            double *s = sums + 9 * a;
            s[0] += 1.0;
            s[1] += dx;
            s[2] += dy;
            s[3] += dz;
            s[4] += dx * dx;
            s[5] += dx * dy;
            s[6] += dy * dy;
            s[7] += dx * dz;
            s[8] += dy * dz;
        }
    }
    for (int64_t i = 0; i < n; i++) {
        const double *s = sums + 9 * i;
        double s1 = s[0], sx = s[1], sy = s[2], sz = s[3], sxx = s[4], sxy = s[5], syy = s[6], sxz = s[7], syz = s[8];
        double minor = sxx * syy - sxy * sxy;
        double det = s1 * minor - sx * (sx * syy - sxy * sy) + sy * (sx * sxy - sxx * sy);
        double det0 = sz * minor - sx * (sxz * syy - sxy * syz) + sy * (sxz * sxy - sxx * syz);
        double floor_ = s1 * sxx * syy;
        if (floor_ < 1e-300) floor_ = 1e-300;
        out[i] = (s1 >= 3 && fabs(det) > 1e-9 * floor_) ? -det0 / det : NAN;
    }
}
