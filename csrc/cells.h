/* A point's grid cell and the DSM's per-cell maximum with its class: shared by grid.c and scan.c. */
#ifndef GISTOOLS_CELLS_H
#define GISTOOLS_CELLS_H

#include "common.h"

/* the flat cell index (row * width + col) of (x, y), -1 outside the grid: col0, top (row_top - 1), width and
 * height as doubles (grid.cell_index's float64 operations) */
static inline int64_t cell_of(double x, double y, double cell, double c0, double top, double w, double h) {
    double c = floor(x / cell) - c0;
    double r = top - floor(y / cell);
    return (c >= 0 && c < w && r >= 0 && r < h) ? (int64_t)(r * w + c) : -1;
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

#endif
