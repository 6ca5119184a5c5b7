/*
 * The window matcher kernel's correlation of a row band and its per-pixel decisions
 * (window_matcher_kernel.h has the overview).
 */
#include "window_matcher_kernel.h"

/* --- correlation -------------------------------------------------------------------------- */

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

/* Decide pixel x of row y from its scores (row_scores[x]) and the row's right_best. */
static inline void decide_pixel(const matcher_call *call, int64_t x, int64_t y, int32_t peak,
                                const int32_t *restrict row_scores,
                                const int32_t *restrict right_best)
{
    const int64_t width = call->width, range = call->disparity_range, at = y * width + x;
    const float score_one = SCORE_ONE;
    if (peak == NO_SCORE) {
        call->status_out[at] = NO_CANDIDATE;
        return;
    }
    call->score_out[at] = (float)((double)peak / (double)score_one);
    if (!call->texture_ok[at]) {
        call->status_out[at] = LOW_TEXTURE;
        return;
    }
    if ((double)peak < (double)(call->min_score * score_one)) {
        call->status_out[at] = LOW_SCORE;
        return;
    }
    const int32_t *restrict scores = row_scores + x * range;
    int32_t chosen = (int32_t)range; /* the first disparity reaching the peak */
    for (int64_t lane = 0; lane < range; ++lane) {
        const int32_t candidate = scores[lane] >= peak ? (int32_t)lane : (int32_t)range;
        chosen = candidate < chosen ? candidate : chosen;
    }
    if (call->uniqueness_ratio > 0.0f) {
        int32_t second = NO_SCORE; /* best score more than 1 px from the chosen one */
        for (int64_t i = 0; i < chosen - 1; ++i) second = scores[i] > second ? scores[i] : second;
        for (int64_t i = chosen + 2; i < range; ++i)
            second = scores[i] > second ? scores[i] : second;
        if ((double)score_one - second
                <= ((double)score_one - peak) * (1.0 + (double)call->uniqueness_ratio)) {
            call->status_out[at] = NOT_UNIQUE;
            return;
        }
    }
    const int64_t lr_max_diff = call->lr_max_diff;
    if (lr_max_diff >= 0) {
        /* The right pixel's own best must be reached within lr_max_diff of chosen: candidate
         * (x + step, chosen + step) meets the same right pixel. */
        const int64_t right_x = x - call->min_disparity - chosen;
        int32_t near = NO_SCORE;
        for (int64_t step = -lr_max_diff; step <= lr_max_diff; ++step) {
            const int64_t neighbour = x + step, index = chosen + step;
            if (call->x_begin <= neighbour && neighbour < call->x_end && 0 <= index
                    && index < range) {
                const int32_t value = row_scores[neighbour * range + index];
                near = value > near ? value : near;
            }
        }
        if (near < right_best[width - 1 - right_x]) {
            call->status_out[at] = LR_INCONSISTENT;
            return;
        }
    }
    double offset_px = 0.0;
    if (call->subpixel && 0 < chosen && chosen < range - 1) {
        const int32_t below = scores[chosen - 1], above = scores[chosen + 1];
        if (below != NO_SCORE && above != NO_SCORE) {
            const double curvature = (double)below + (double)above - 2.0 * peak;
            if (curvature < 0.0) {
                offset_px = 0.5 * (double)(below - above) / curvature;
                offset_px = offset_px > 0.5 ? 0.5 : (offset_px < -0.5 ? -0.5 : offset_px);
            }
        }
    }
    call->status_out[at] = VALID;
    call->disparity_out[at] = (float)((double)(call->min_disparity + chosen) + offset_px);
}

/* Match rows y_first..y_stop-1 of the region (columns x_begin..x_end-1, inside r..W-1-r) and
 * decide columns out_x_begin..out_x_end-1 of the rows with y % row_step == 0; the other rows
 * only advance the running column sums. */
CLONED_FOR_SIMD void correlate_band(const matcher_call *call, int64_t y_first,
                                           int64_t y_stop, char *memory)
{
    const geometry g = {call->width, call->radius, call->min_disparity, call->disparity_range};
    const int64_t width = call->width, radius = call->radius, range = call->disparity_range;
    const int64_t x_begin = call->x_begin, x_end = call->x_end;
    const float score_one = SCORE_ONE;
    const float *restrict left_padded = call->left_padded;
    const float *restrict right_reversed = call->right_reversed;
    float *restrict column_sums = (float *)take(&memory, (size_t)(width * range) * 4);
    int32_t *restrict row_scores = (int32_t *)take(&memory, (size_t)(width * range) * 4);
    float *restrict window_sums = (float *)take(&memory, (size_t)range * 4);
    int32_t *restrict right_best = (int32_t *)take(&memory, (size_t)width * 4);
    int32_t *restrict best_score = (int32_t *)take(&memory, (size_t)width * 4);
    for (int64_t i = 0; i < width * range; ++i) {
        column_sums[i] = 0.0f; /* lanes whose right column is outside the image stay 0 */
        row_scores[i] = NO_SCORE;
    }
    for (int64_t i = 0; i < range; ++i) window_sums[i] = 0.0f;
    for (int64_t i = 0; i < width; ++i) best_score[i] = NO_SCORE;
    for (int64_t y = y_first; y < y_stop; ++y) {
        const int first_row = y == y_first;
        if (y % call->row_step != 0) {
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
        const float *restrict scale = call->left_scale + y * width;
        const float *restrict offset = call->left_offset + y * width;
        for (int64_t x = x_begin; x < x_end; ++x) {
            best_score[x] = score_pixel(
                x, y, first_row, x_begin, left_padded, right_reversed, scale[x] * score_one,
                offset[x] * score_one, call->right_mean + y * width,
                call->right_scale + y * width, column_sums, window_sums, row_scores + x * range,
                right_best, g);
        }
        /* Decisions, once every candidate of the row (and so every right pixel's best) is in. */
        for (int64_t x = call->out_x_begin; x < call->out_x_end; ++x)
            decide_pixel(call, x, y, best_score[x], row_scores, right_best);
    }
}
