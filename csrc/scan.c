/* Pass 1 of the rasters over a chunk of LAS point records, in one pass (lidar/scan.py). */
#include "cells.h"

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
