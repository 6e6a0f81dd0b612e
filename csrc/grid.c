/* Points to grid cells: the cell of each point, per-cell minimum, mean, and maximum with its class. */
#include "cells.h"

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


/* Flat cell index (row * width + col) of each point, -1 outside the grid (grid.cell_index): the same float64
 * operations as its numpy form, in one pass. */
SIMD_CLONES void gt_cell_index(int64_t n, const double *x, const double *y, double cell, int64_t col0, int64_t row_top,
                               int64_t width, int64_t height, int64_t *out) {
    const double c0 = (double)col0, top = (double)(row_top - 1), w = (double)width, h = (double)height;
    for (int64_t i = 0; i < n; i++) out[i] = cell_of(x[i], y[i], cell, c0, top, w, h);
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

/* Per-cell minimum of z into out (which holds +inf where no point is yet), flat cell index per point. */
void gt_cell_min(int64_t n, const int64_t *flat, const double *z, double *out) {
    for (int64_t i = 0; i < n; i++) {
        if (z[i] < out[flat[i]]) out[flat[i]] = z[i];
    }
}


/* a goes before b in numpy's order: ascending, NaN after every number (equal values, -0.0 and 0.0 among them, and
 * NaNs keep their order: neither goes before the other) */
static inline int before(double a, double b) { return a < b || (isnan(b) && !isnan(a)); }

/* a[0..m) in numpy's order, stable: equal values keep their input order */
static void insertion_sort(double *a, int64_t m) {
    for (int64_t i = 1; i < m; i++) {
        double x = a[i];
        int64_t j = i - 1;
        while (j >= 0 && before(x, a[j])) {
            a[j + 1] = a[j];
            j--;
        }
        a[j + 1] = x;
    }
}

#define SORT_RUN 24 /* a cell of up to this many values: an insertion sort (a cell holds a few dozen points) */

/* a[0..m) in numpy's order, stable: runs of SORT_RUN by insertion, then merged pairwise (bottom-up), between a and
 * tmp (m doubles). Written out rather than the C library's qsort, which is not stable everywhere (msvcrt's is not:
 * the signs of zeros and the NaNs' bits would come out in another order on Windows). */
static void merge_sort(double *a, double *tmp, int64_t m) {
    for (int64_t lo = 0; lo < m; lo += SORT_RUN) insertion_sort(a + lo, m - lo < SORT_RUN ? m - lo : SORT_RUN);
    double *src = a, *dst = tmp;
    for (int64_t w = SORT_RUN; w < m; w *= 2) {
        for (int64_t lo = 0; lo < m; lo += 2 * w) {
            int64_t mid = lo + w < m ? lo + w : m, hi = lo + 2 * w < m ? lo + 2 * w : m, i = lo, j = mid, k = lo;
            while (i < mid && j < hi) dst[k++] = before(src[j], src[i]) ? src[j++] : src[i++]; /* ties: the left */
            while (i < mid) dst[k++] = src[i++];
            while (j < hi) dst[k++] = src[j++];
        }
        double *t = src;
        src = dst;
        dst = t;
    }
    if (src != a) memcpy(a, src, (size_t)m * sizeof(double));
}

/* The values of each cell, ascending (metrics' medians and percentiles): out holds the values of cell 0, then cell
 * 1, ..., each ascending with NaN last, as v[numpy.lexsort((v, cell))] bit for bit (a stable order: equal values,
 * -0.0 and 0.0 among them, in point order); start[c] is where cell c begins (start[ncells] = n). A counting sort
 * by cell (cells 0..ncells-1), then each cell's values sorted in place, stably (merge_sort: the same order with
 * every C library). start (ncells + 1) and pos (ncells, scratch) are caller-owned; the merges' scratch (the longest
 * cell) is allocated here: without memory for it, insertion sorts (the same order, slower). */
void gt_cell_sort(int64_t n, const int64_t *cell, const double *v, int64_t ncells, int64_t *start, int64_t *pos,
                  double *out) {
    memset(start, 0, (size_t)(ncells + 1) * sizeof(int64_t));
    for (int64_t k = 0; k < n; k++) start[cell[k] + 1]++;
    int64_t longest = 0;
    for (int64_t c = 0; c < ncells; c++) {
        if (start[c + 1] > longest) longest = start[c + 1];
        start[c + 1] += start[c];
    }
    memcpy(pos, start, (size_t)ncells * sizeof(int64_t));
    for (int64_t k = 0; k < n; k++) out[pos[cell[k]]++] = v[k];
    double *tmp = longest > SORT_RUN ? (double *)malloc((size_t)longest * sizeof(double)) : NULL;
    for (int64_t c = 0; c < ncells; c++) {
        int64_t m = start[c + 1] - start[c];
        if (m > SORT_RUN && tmp)
            merge_sort(out + start[c], tmp, m);
        else
            insertion_sort(out + start[c], m);
    }
    free(tmp);
}


/* numpy's pairwise sum of a[0..n) (numpy/_core/src/umath/loops_utils.h, PW_BLOCKSIZE 128): below 8 values one
 * running sum from -0.0, up to 128 eight running sums added as ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
 * and then the rest, above that the two halves (the first a multiple of 8) summed apart. */
static double pairwise_sum(const double *a, int64_t n) {
    if (n < 8) {
        double res = -0.0;
        for (int64_t i = 0; i < n; i++) res += a[i];
        return res;
    }
    if (n <= 128) {
        double r[8];
        int64_t i;
        for (int j = 0; j < 8; j++) r[j] = a[j];
        for (i = 8; i < n - (n % 8); i += 8)
            for (int j = 0; j < 8; j++) r[j] += a[i + j];
        double res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
        for (; i < n; i++) res += a[i];
        return res;
    }
    int64_t n2 = n / 2;
    n2 -= n2 % 8;
    return pairwise_sum(a, n2) + pairwise_sum(a + n2, n - n2);
}

/* The sum of a run of values as numpy.add.reduceat gives it: the first value plus the pairwise sum of the others. */
static inline double run_sum(const double *a, int64_t m) { return a[0] + pairwise_sum(a + 1, m - 1); }

/* Per cell of values grouped by cell (gt_cell_sort's out and start, start[ncells] = n): the sum of its values and
 * the sum of their squared deviations from the cell's mean (sum / count), numpy.add.reduceat's sums bit for bit
 * (metrics' sd and mean; a NaN among them gives NaN, of one bit pattern); 0 where a cell has no value. sq: scratch
 * of at least the longest cell's length. */
void gt_cell_moments(int64_t ncells, const int64_t *start, const double *v, double *sum, double *ssd, double *sq) {
    for (int64_t c = 0; c < ncells; c++) {
        int64_t s = start[c], m = start[c + 1] - s;
        if (m <= 0) {
            sum[c] = ssd[c] = 0.0;
            continue;
        }
        double total = run_sum(v + s, m), mean = total / (double)m;
        for (int64_t i = 0; i < m; i++) {
            double d = v[s + i] - mean;
            sq[i] = d * d;
        }
        double squares = run_sum(sq, m);
        sum[c] = isnan(total) ? NAN : total; /* one NaN: which operand's bits a sum keeps is the compiler's choice */
        ssd[c] = isnan(squares) ? NAN : squares;
    }
}

/* The p-th percentile (0..100) of each cell's ascending values (gt_cell_sort's out and start), linear between the
 * two nearest ranks as numpy.percentile's default: rank p / 100 (count - 1); NaN where a cell has no value (one bit
 * pattern, as every NaN result). */
void gt_cell_percentile(int64_t ncells, const int64_t *start, const double *v, double p, double *out) {
    const double q = p / 100.0;
    for (int64_t c = 0; c < ncells; c++) {
        int64_t s = start[c], m = start[c + 1] - s;
        if (m <= 0) {
            out[c] = NAN;
            continue;
        }
        double rank = q * (double)(m - 1), lo = floor(rank), hi = ceil(rank);
        double a = v[s + (int64_t)lo], b = v[s + (int64_t)hi];
        double r = a + (b - a) * (rank - lo);
        out[c] = isnan(r) ? NAN : r;
    }
}
