/* gistools' C kernel: every entry point, declared once.
 *
 * This header is included by each part of the kernel (the compiler checks each definition against it) and is
 * read by cffi (gistools/kernel_build.py), which compiles a module whose wrappers check every call from Python
 * against it: a wrong argument count or type is a TypeError, not corrupted memory. Keep it plain C (no macros):
 * cffi parses it. Arrays are C-contiguous; a `const` array is only read. Sizes and indices are int64_t.
 */

/* TIN: Delaunay triangulation of integer points (tin.c) and its linear interpolation */
double gt_quantise(int64_t n, const double *v, double v0, double scale, int64_t *out);
int64_t gt_delaunay(int64_t n, const int64_t *xin, const int64_t *yin, int32_t *triangles, int64_t *repeats);
int64_t gt_rasterize(int64_t ntri, const int32_t *tri, const double *u, const double *v, const double *z,
                     int32_t width, int32_t height, double max_edge2, double *out, const double *box, uint8_t *exact);
int64_t gt_tin_grid(int64_t n, const int64_t *ix, const int64_t *iy, const double *u, const double *v,
                    const double *z, int32_t width, int32_t height, double max_edge2, double *out, int64_t *repeats,
                    const double *box, uint8_t *exact);
int64_t gt_tin_at(int64_t ntri, const int32_t *tri, const double *vx, const double *vy, const double *vz, int64_t nv,
                  int64_t nq, const double *qx, const double *qy, double *out);
void gt_plane_residuals(int64_t n, const double *x, const double *y, const double *z, int64_t ntri,
                        const int32_t *tri, double *sums, double *out);

/* grid morphology of the ground filters (morphology.c) */
void gt_cross_filter(const double *in, double *out, double *work, int64_t rows, int64_t cols, int32_t is_max,
                     int32_t iterations);
int64_t gt_fill_rings(double *z, double *prev, int64_t rows, int64_t cols, int32_t rings);
void gt_progressive(const double *z, uint8_t *obj, double *work, int64_t rows, int64_t cols, double cell,
                    double slope_z, int32_t max_radius);
int64_t gt_fill_front(double *z, int64_t rows, int64_t cols, int32_t rings, int64_t cap, int64_t *work, uint8_t *mark,
                      double *vals);
void gt_bilinear(const double *surf, int64_t rows, int64_t cols, int64_t n, const double *x, const double *y,
                 double cell, int64_t col0, int64_t row_top, double *out);
void gt_slope_threshold(const double *z, int64_t rows, int64_t cols, double cell, double z_per_xy, double threshold,
                        double scalar, double *out);
int64_t gt_raised_patches(const double *z, int64_t rows, int64_t cols, int32_t reach, double step, double cell,
                          double patch, int64_t floor_cells, int64_t *work, uint8_t *roof);

/* points to grid cells (grid.c) */
void gt_cell_index(int64_t n, const double *x, const double *y, double cell, int64_t col0, int64_t row_top,
                   int64_t width, int64_t height, int64_t *out);
void gt_cell_min(int64_t n, const int64_t *flat, const double *z, double *out);
void gt_cell_mean(int64_t n, const int64_t *flat, const double *z, const uint8_t *on, int64_t ncells, double *sum,
                  int64_t *count, double *out);
void gt_cell_sort(int64_t n, const int64_t *cell, const double *v, int64_t ncells, int64_t *start, int64_t *pos,
                  double *out);
void gt_cell_moments(int64_t ncells, const int64_t *start, const double *v, double *sum, double *ssd, double *sq);
void gt_cell_percentile(int64_t ncells, const int64_t *start, const double *v, double p, double *out);
void gt_max_with_class(int64_t n, const int64_t *cell, const double *z, const uint8_t *cls, const uint8_t *bare,
                       int64_t ncells, double *dsm, uint8_t *top, double *cm, uint8_t *tc);

/* pass 1 of the rasters over LAS point records (scan.c) */
void gt_scan_chunk(int64_t n, const char *X, int64_t xstride, const char *Y, int64_t ystride, const char *Z,
                   int64_t zstride, const double *so, const double *gp, int64_t *cell, const uint8_t *cls,
                   const uint8_t *rn, const uint8_t *withheld, const uint8_t *surface, const uint8_t *bare,
                   int64_t ncells, double *dsm, uint8_t *top, double *cm, uint8_t *tc, int64_t *by_class,
                   int64_t *by_return, int64_t *bare_first, int32_t *first_cell, float *first_z, int64_t gclass,
                   int64_t wclass, int64_t *gcount, int64_t *wcount, const double *edges, int32_t *grec,
                   int64_t *gidx, int32_t *hrec, uint8_t *hside, double *boxes, int64_t *counts);
