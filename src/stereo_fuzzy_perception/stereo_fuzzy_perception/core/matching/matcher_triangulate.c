/*
 * The window matcher kernel's triangulation of one row of disparities into points
 * (window_matcher_kernel.h has the overview; triangulation.py explains the geometry).
 */
#include "window_matcher_kernel.h"

/* Write the points of row v (every stride-th column) to `out` and return how many: first each
 * sampled column's point, branch-free so that it vectorises (three divisions a point), then the
 * valid ones packed. scratch holds 4 floats per sampled column. */
CLONED_FOR_SIMD int64_t triangulate_row(
    const projection *p, const float *restrict disparity, const float *restrict score, int64_t v,
    int64_t width, int64_t stride, float *restrict scratch, float *restrict out)
{
    const int64_t columns = (width + stride - 1) / stride;
    float *restrict optical_x = scratch, *restrict optical_y = scratch + columns;
    float *restrict optical_z = scratch + 2 * columns, *restrict keep = scratch + 3 * columns;
    const double r0 = p->r[0], r1 = p->r[1], r2 = p->r[2], r3 = p->r[3], r4 = p->r[4];
    const double r5 = p->r[5], r6 = p->r[6], r7 = p->r[7], r8 = p->r[8];
    for (int64_t k = 0; k < columns; ++k) {
        const double u = (double)(k * stride), d = disparity[k * stride];
        const double effective = d - p->principal_shift;
        const int in_front = effective > 0.0; /* false for NaN (no match) and behind */
        const double z = p->numerator / (in_front ? effective : 1.0);
        const double x = ((u - p->cx) * z - p->tx) / p->fx;
        const double y = (((double)v - p->cy) * z - p->ty) / p->fy;
        /* optical <- rectified is R^T: for a row vector, p_optical = p_rectified R. */
        optical_x[k] = (float)(x * r0 + y * r3 + z * r6);
        optical_y[k] = (float)(x * r1 + y * r4 + z * r7);
        optical_z[k] = (float)(x * r2 + y * r5 + z * r8);
        keep[k] = in_front ? 1.0f : 0.0f;
    }
    int64_t count = 0;
    for (int64_t k = 0; k < columns; ++k) {
        if (keep[k] == 0.0f) continue;
        const int64_t u = k * stride;
        float *point = out + 7 * count++;
        point[0] = optical_x[k];
        point[1] = optical_y[k];
        point[2] = optical_z[k];
        point[3] = (float)u;
        point[4] = (float)v;
        point[5] = (float)((double)u - (double)disparity[u]);
        point[6] = score[u];
    }
    return count;
}
