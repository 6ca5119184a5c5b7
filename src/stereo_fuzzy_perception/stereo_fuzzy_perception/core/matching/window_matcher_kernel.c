/*
 * The matcher's inner kernel: window correlation of one band of rows (correlation.py explains
 * the method; this file is its per-band loop, called from the numba kernel _correlate_bands).
 *
 * Why C: the same loops compiled by numba spent more time on each pixel's bookkeeping (slice
 * bounds, runtime alias checks before every vectorised loop) than on the 64 disparities
 * themselves; with `restrict` pointers the per-pixel cost is a few instructions and one pair
 * takes about a quarter less time. Results are bit-identical to the numba kernel it replaced:
 * the same float32 operations in the same order, no fused multiply-add (-ffp-contract=off in
 * setup.py), integer maxima.
 *
 * Built by colcon (setup.py) as the extension module stereo_fuzzy_perception.core.matching._window_matcher_kernel
 * and called through ctypes. target_clones: an AVX2 body for CPUs that have it, a baseline one
 * for those that do not, chosen when the library loads.
 *
 * Layout (all arrays C-contiguous, W = width, D = disparity_range, r = radius):
 *   left_padded, right_reversed: (H + 2r, W) float32 intensities, rows padded by reflection,
 *     the right image's columns reversed so that candidates are contiguous in the disparity;
 *   left_scale, left_offset, right_mean_reversed, right_scale_reversed: (H, W) float32 window
 *     terms; texture_ok: (H, W) bool (one byte);
 *   column_sums: (W, D) float32, row_scores: (W, D) int32, window_sums: (D) float32,
 *     right_best, best_score: (W) int32: the band's working memory;
 *   disparity_out, score_out: (H, W) float32, status_out: (H, W) uint8 (MatchStatus codes).
 * Disparity index i means disparity min_disparity + i; left x meets right x - min_disparity - i,
 * stored at column W - 1 - (x - min_disparity - i) of the reversed arrays.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define CLONED_FOR_AVX2 __attribute__((target_clones("avx2", "default")))
#else
#define CLONED_FOR_AVX2
#endif

/* correlation.py's _NO_SCORE: "no candidate", below every score (1.0 = 2^24). */
#define NO_SCORE (-3 * (1 << 24))

/* MatchStatus codes (correlation.py). */
enum { VALID = 0, NO_CANDIDATE = 2, LOW_TEXTURE = 3, LOW_SCORE = 4, NOT_UNIQUE = 5,
       LR_INCONSISTENT = 6 };

typedef struct {
    int64_t width, radius, min_disparity, disparity_range;
} geometry;

/* Bring the cross-term sums of `column` to window rows y-r..y+r (padded rows y..y+2r):
 * sums[i] = sum over the window rows of left[row, column] * right[row, column - min_d - i], for
 * the i whose right column is inside the image (the others stay as they are, 0). */
static inline __attribute__((always_inline)) void update_column(
    float *restrict column_sums, int64_t column, const float *restrict left_padded,
    const float *restrict right_reversed, int64_t y, int first_row, geometry g)
{
    int64_t low = column - g.min_disparity - g.width + 1;
    int64_t high = column - g.min_disparity;
    if (low < 0) low = 0;
    if (high > g.disparity_range - 1) high = g.disparity_range - 1;
    if (low > high) return;
    const int64_t count = high - low + 1;
    const int64_t start = g.width - 1 - column + g.min_disparity + low;
    float *restrict sums = column_sums + column * g.disparity_range + low;
    if (first_row) {
        for (int64_t lane = 0; lane < count; ++lane) sums[lane] = 0.0f;
        for (int64_t row = y; row < y + 2 * g.radius + 1; ++row) {
            const float value = left_padded[row * g.width + column];
            const float *restrict part = right_reversed + row * g.width + start;
            for (int64_t lane = 0; lane < count; ++lane) sums[lane] += value * part[lane];
        }
        return;
    }
    const int64_t entering = y + 2 * g.radius, leaving = y - 1;
    const float new_value = left_padded[entering * g.width + column];
    const float old_value = left_padded[leaving * g.width + column];
    const float *restrict new_part = right_reversed + entering * g.width + start;
    const float *restrict old_part = right_reversed + leaving * g.width + start;
    for (int64_t lane = 0; lane < count; ++lane)
        sums[lane] += new_value * new_part[lane] - old_value * old_part[lane];
}

/* Score every candidate of pixel x on row y into row_scores[x], fold them into right_best (the
 * best score of each right pixel) and return the pixel's best score. */
static inline __attribute__((always_inline)) int32_t score_pixel(
    int64_t x, int64_t y, int first_row, int64_t x_begin, const float *restrict left_padded,
    const float *restrict right_reversed, float scale, float offset,
    const float *restrict means, const float *restrict scales, float *restrict column_sums,
    float *restrict window_sums, int32_t *restrict scores, int32_t *restrict right_best,
    geometry g)
{
    const int64_t width = g.width, radius = g.radius, min_d = g.min_disparity;
    const int64_t range = g.disparity_range;
    const int64_t newest = x + radius;
    int64_t low = x - min_d - (width - 1 - radius);
    int64_t high = x - min_d - radius;
    if (low < 0) low = 0;
    if (high > range - 1) high = range - 1;
    float *restrict added = column_sums + newest * range;
    int32_t peak = NO_SCORE;
    if (!first_row && x > x_begin && low == 0 && high == range - 1) {
        /* Interior pixel, every disparity valid: one pass updates the newest column, slides
         * the window and scores. */
        const int64_t entering = y + 2 * radius, leaving = y - 1;
        const float new_value = left_padded[entering * width + newest];
        const float old_value = left_padded[leaving * width + newest];
        const int64_t start = width - 1 - newest + min_d;
        const int64_t base = width - 1 - x + min_d;
        const float *restrict new_part = right_reversed + entering * width + start;
        const float *restrict old_part = right_reversed + leaving * width + start;
        const float *restrict mean_part = means + base;
        const float *restrict scale_part = scales + base;
        int32_t *restrict best_part = right_best + base;
        const float *restrict removed = column_sums + (x - radius - 1) * range;
        for (int64_t lane = 0; lane < range; ++lane) {
            const float column_total =
                added[lane] + (new_value * new_part[lane] - old_value * old_part[lane]);
            added[lane] = column_total;
            const float window = window_sums[lane] + (column_total - removed[lane]);
            window_sums[lane] = window;
            const int32_t score =
                (int32_t)((window * scale - offset * mean_part[lane]) * scale_part[lane]);
            scores[lane] = score;
            peak = score > peak ? score : peak;
            best_part[lane] = score > best_part[lane] ? score : best_part[lane];
        }
        return peak;
    }
    /* Near the image's edges (some candidates outside), or the band's first row or column. */
    if (!first_row)
        update_column(column_sums, newest, left_padded, right_reversed, y, 0, g);
    if (x == x_begin) {
        for (int64_t i = 0; i < range; ++i) window_sums[i] = 0.0f;
        for (int64_t column = x - radius; column <= newest; ++column) {
            const float *restrict sums = column_sums + column * range;
            for (int64_t i = 0; i < range; ++i) window_sums[i] += sums[i];
        }
    } else {
        const float *restrict removed = column_sums + (x - radius - 1) * range;
        for (int64_t i = 0; i < range; ++i) window_sums[i] += added[i] - removed[i];
    }
    for (int64_t i = 0; i < range; ++i) scores[i] = NO_SCORE;
    const int64_t base = width - 1 - x + min_d;
    for (int64_t i = low; i <= high; ++i) {
        const int32_t score =
            (int32_t)((window_sums[i] * scale - offset * means[base + i]) * scales[base + i]);
        scores[i] = score;
        peak = score > peak ? score : peak;
        right_best[base + i] = score > right_best[base + i] ? score : right_best[base + i];
    }
    return peak;
}

CLONED_FOR_AVX2 void stereo_fuzzy_correlate_band(
    const float *restrict left_padded, const float *restrict right_reversed,
    const float *restrict left_scale, const float *restrict left_offset,
    const float *restrict right_mean_reversed, const float *restrict right_scale_reversed,
    const uint8_t *restrict texture_ok, int64_t width, int64_t radius, int64_t min_disparity,
    int64_t disparity_range, int64_t x_begin, int64_t x_end, int64_t y_first, int64_t y_stop,
    int64_t out_x_begin, int64_t out_x_end, float min_score, float uniqueness_ratio,
    int64_t lr_max_diff, int64_t subpixel, int64_t row_step, float score_one,
    float *restrict column_sums, int32_t *restrict row_scores, float *restrict window_sums,
    int32_t *restrict right_best, int32_t *restrict best_score, float *restrict disparity_out,
    float *restrict score_out, uint8_t *restrict status_out)
{
    const geometry g = {width, radius, min_disparity, disparity_range};
    const int64_t range = disparity_range;
    for (int64_t i = 0; i < width * range; ++i) {
        column_sums[i] = 0.0f; /* lanes whose right column is outside the image stay 0 */
        row_scores[i] = NO_SCORE;
    }
    for (int64_t i = 0; i < range; ++i) window_sums[i] = 0.0f;
    for (int64_t i = 0; i < width; ++i) best_score[i] = NO_SCORE;
    for (int64_t y = y_first; y < y_stop; ++y) {
        const int first_row = y == y_first;
        if (y % row_step != 0) {
            /* No point is taken from this row: only bring the column sums to it. */
            for (int64_t column = x_begin - radius; column < x_end + radius; ++column)
                update_column(column_sums, column, left_padded, right_reversed, y, first_row, g);
            continue;
        }
        for (int64_t column = 0; column < width; ++column) right_best[column] = NO_SCORE;
        /* Columns the pixel loop does not bring up to date itself. */
        const int64_t ready_end = first_row ? x_end + radius : x_begin + radius;
        for (int64_t column = x_begin - radius; column < ready_end; ++column)
            update_column(column_sums, column, left_padded, right_reversed, y, first_row, g);
        for (int64_t x = x_begin; x < x_end; ++x) {
            best_score[x] = score_pixel(
                x, y, first_row, x_begin, left_padded, right_reversed,
                left_scale[y * width + x] * score_one, left_offset[y * width + x] * score_one,
                right_mean_reversed + y * width, right_scale_reversed + y * width, column_sums,
                window_sums, row_scores + x * range, right_best, g);
        }
        /* Decisions, once every candidate of the row (and so every right pixel's best) is in. */
        for (int64_t x = out_x_begin; x < out_x_end; ++x) {
            const int32_t peak = best_score[x];
            const int64_t at = y * width + x;
            if (peak == NO_SCORE) {
                status_out[at] = NO_CANDIDATE;
                continue;
            }
            score_out[at] = (float)((double)peak / (double)score_one);
            if (!texture_ok[at]) {
                status_out[at] = LOW_TEXTURE;
                continue;
            }
            if ((double)peak < (double)(min_score * score_one)) {
                status_out[at] = LOW_SCORE;
                continue;
            }
            const int32_t *restrict scores = row_scores + x * range;
            int32_t chosen = (int32_t)range; /* the first disparity reaching the peak */
            for (int64_t lane = 0; lane < range; ++lane) {
                const int32_t candidate = scores[lane] >= peak ? (int32_t)lane : (int32_t)range;
                chosen = candidate < chosen ? candidate : chosen;
            }
            if (uniqueness_ratio > 0.0f) {
                int32_t second = NO_SCORE; /* best score more than 1 px from the chosen one */
                for (int64_t i = 0; i < chosen - 1; ++i)
                    second = scores[i] > second ? scores[i] : second;
                for (int64_t i = chosen + 2; i < range; ++i)
                    second = scores[i] > second ? scores[i] : second;
                if ((double)score_one - second
                        <= ((double)score_one - peak) * (1.0 + (double)uniqueness_ratio)) {
                    status_out[at] = NOT_UNIQUE;
                    continue;
                }
            }
            if (lr_max_diff >= 0) {
                /* The right pixel's own best must be reached within lr_max_diff of chosen:
                 * candidate (x + step, chosen + step) meets the same right pixel. */
                const int64_t right_x = x - min_disparity - chosen;
                int32_t near = NO_SCORE;
                for (int64_t step = -lr_max_diff; step <= lr_max_diff; ++step) {
                    const int64_t neighbour = x + step, index = chosen + step;
                    if (x_begin <= neighbour && neighbour < x_end && 0 <= index && index < range) {
                        const int32_t value = row_scores[neighbour * range + index];
                        near = value > near ? value : near;
                    }
                }
                if (near < right_best[width - 1 - right_x]) {
                    status_out[at] = LR_INCONSISTENT;
                    continue;
                }
            }
            double offset_px = 0.0;
            if (subpixel && 0 < chosen && chosen < range - 1) {
                const int32_t below = scores[chosen - 1], above = scores[chosen + 1];
                if (below != NO_SCORE && above != NO_SCORE) {
                    const double curvature = (double)below + (double)above - 2.0 * peak;
                    if (curvature < 0.0) {
                        offset_px = 0.5 * (double)(below - above) / curvature;
                        offset_px = offset_px > 0.5 ? 0.5 : (offset_px < -0.5 ? -0.5 : offset_px);
                    }
                }
            }
            status_out[at] = VALID;
            disparity_out[at] = (float)((double)(min_disparity + chosen) + offset_px);
        }
    }
}

/* An importable module, so that setuptools builds and installs it like any extension; Python
 * code reaches correlate_band through ctypes (numba can call ctypes functions, not modules). */
static struct PyModuleDef window_matcher_kernel_module = {
    PyModuleDef_HEAD_INIT, "_window_matcher_kernel",
    "C kernel of the window-correlation matcher; used through ctypes by correlation.py.", -1,
    NULL, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__window_matcher_kernel(void) { return PyModule_Create(&window_matcher_kernel_module); }
