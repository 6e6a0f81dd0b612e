/* Grid morphology of the ground filters (lidar/ground.py: SMRF, the progressive filter, gap filling). */
#include "common.h"

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
            double *GT_RESTRICT row = x + b * w;
            const double *GT_RESTRICT src = x + (b + s) * w + d * s;
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

/* ------------------------------------------------------------------ raised ground patches (lidar/ground.py)
 * The cells of patches standing above all the ground around them, as lidar.ground._raised_cells_numpy finds them
 * (the same comparisons on the same float64 values). `z`: the lowest ground point of each cell, NaN (or any value
 * that is not finite) where empty.
 * Cells up to `reach` cells apart are one patch when |dz| <= step * distance (cells); a patch's extent is its
 * longest side (cell count - 1) x `cell`; the pairs of cells of two patches vote the higher one down, counting only
 * lower patches of `floor_cells` cells or more or at least `patch` wide; a patch narrower than `patch` with at least
 * 8 votes, 90 % of them down, is raised: roof[i] = 1 on its cells. `work` holds 8 * rows * cols int64.
 * Union-find with path halving: the patches do not depend on the order of the unions. Returns the roof cells. */
static int64_t uf_find(int64_t *parent, int64_t i) {
    while (parent[i] != i) {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    return i;
}

int64_t gt_raised_patches(const double *z, int64_t rows, int64_t cols, int32_t reach, double step, double cell,
                          double patch, int64_t floor_cells, int64_t *work, uint8_t *roof) {
    int64_t n = rows * cols, count = 0;
    int64_t *parent = work, *size = work + n, *lo_c = work + 2 * n, *hi_c = work + 3 * n, *lo_r = work + 4 * n,
            *hi_r = work + 5 * n, *down = work + 6 * n, *up = work + 7 * n;
    for (int64_t i = 0; i < n; i++) {
        parent[i] = i;
        roof[i] = 0;
        size[i] = down[i] = up[i] = 0;
        lo_c[i] = lo_r[i] = INT64_MAX;
        hi_c[i] = hi_r[i] = INT64_MIN;
    }
#define EXTENT(p) ((double)((hi_c[p] - lo_c[p]) > (hi_r[p] - lo_r[p]) ? (hi_c[p] - lo_c[p]) : (hi_r[p] - lo_r[p])) * cell)
    /* every pair of filled cells within reach, twice: pass 0 joins the pairs whose heights differ by at most step
     * per cell of distance into patches; pass 1 (each patch's size and bounding cells known at its root) lets the
     * pairs of two patches vote, the higher one down */
    for (int pass = 0; pass < 2; pass++) {
        if (pass == 1) {
            for (int64_t i = 0; i < n; i++) {
                if (!isfinite(z[i]))
                    continue;
                int64_t p = uf_find(parent, i), r = i / cols, c = i % cols;
                parent[i] = p;
                size[p]++;
                if (c < lo_c[p]) lo_c[p] = c;
                if (c > hi_c[p]) hi_c[p] = c;
                if (r < lo_r[p]) lo_r[p] = r;
                if (r > hi_r[p]) hi_r[p] = r;
            }
        }
        for (int64_t r = 0; r < rows; r++) {
            for (int64_t c = 0; c < cols; c++) {
                int64_t a = r * cols + c;
                if (!isfinite(z[a]))
                    continue;
                for (int32_t dr = 0; dr <= reach; dr++) {
                    for (int32_t dc = -reach; dc <= reach; dc++) {
                        if ((dr == 0 && dc <= 0) || r + dr >= rows || c + dc < 0 || c + dc >= cols)
                            continue;
                        int64_t b = a + (int64_t)dr * cols + dc;
                        if (!isfinite(z[b]))
                            continue;
                        if (pass == 0) {
                            if (!(fabs(z[a] - z[b]) <= step * sqrt((double)(dr * dr + dc * dc))))
                                continue;
                            int64_t ra = uf_find(parent, a), rb = uf_find(parent, b);
                            if (ra < rb)
                                parent[rb] = ra;
                            else if (rb < ra)
                                parent[ra] = rb;
                            continue;
                        }
                        int64_t la = parent[a], lb = parent[b];
                        if (la == lb)
                            continue;
                        int64_t higher = z[a] - z[b] > 0 ? la : lb, lower = higher == la ? lb : la;
                        if (size[lower] >= floor_cells || EXTENT(lower) >= patch) {
                            down[higher]++;
                            up[lower]++;
                        }
                    }
                }
            }
        }
    }
    for (int64_t i = 0; i < n; i++) {
        if (!isfinite(z[i]))
            continue;
        int64_t p = parent[i], total = down[p] + up[p];
        if (total >= 8 && (double)down[p] >= 0.9 * (double)total && EXTENT(p) < patch) {
            roof[i] = 1;
            count++;
        }
    }
#undef EXTENT
    return count;
}
