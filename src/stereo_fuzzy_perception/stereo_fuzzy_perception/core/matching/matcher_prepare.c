/*
 * The window matcher kernel's image preparation (window_matcher_kernel.h has the overview):
 * float32 rows padded by reflection and each window's terms from running sums.
 */
#include "window_matcher_kernel.h"

/* --- image preparation -------------------------------------------------------------------- */

static inline int64_t reflect(int64_t index, int64_t size)
{
    /* Mirror an index into 0..size-1 without repeating the edge (BORDER_REFLECT_101). */
    if (index < 0) return -index;
    if (index >= size) return 2 * (size - 1) - index;
    return index;
}

static inline __attribute__((always_inline)) void load_row(
    const image_source *source, int64_t width, int64_t row, float *out)
{
    const float gain = source->gain, shift = source->shift;
    switch (source->kind) {
    case PIXELS_UINT8: {
        const uint8_t *pixels = (const uint8_t *)source->pixels + row * width;
        for (int64_t x = 0; x < width; ++x) out[x] = (float)pixels[x] * gain - shift;
        break;
    }
    case PIXELS_UINT16: {
        const uint16_t *pixels = (const uint16_t *)source->pixels + row * width;
        for (int64_t x = 0; x < width; ++x) out[x] = (float)pixels[x] * gain - shift;
        break;
    }
    case PIXELS_FLOAT32: {
        const float *pixels = (const float *)source->pixels + row * width;
        for (int64_t x = 0; x < width; ++x) out[x] = pixels[x] * gain - shift;
        break;
    }
    }
}


/* Per column of one row, from its window sums: scale = 1 / sqrt(energy), 0 where textureless,
 * and term = offset (window sum * scale) or mean for Eq. 8, 0 for Eq. 7. Inlined with constant
 * flags, so that each variant is a loop without branches. A window is textured exactly where
 * its scale is positive: the texture threshold's energy is positive (FLAT_STD), and so is the
 * energy of a textured window. */
static inline __attribute__((always_inline)) void window_terms(
    int zero_mean, int offset_term, int64_t width, double count, double textured_energy,
    const double *restrict window_sum, const double *restrict window_square,
    float *restrict scale_row, float *restrict term_row)
{
    for (int64_t x = 0; x < width; ++x) {
        const double window = window_sum[x], squares = window_square[x];
        double deviation = squares - window * window / count;
        deviation = deviation > 0.0 ? deviation : 0.0;
        const double energy = zero_mean ? deviation : squares;
        const int usable = (deviation >= textured_energy) & (energy > 0.0);
        const double inverse = 1.0 / sqrt(usable ? energy : 1.0);
        const double scale = usable ? inverse : 0.0;
        scale_row[x] = (float)scale;
        term_row[x] = !zero_mean ? 0.0f
            : offset_term ? (float)(window * scale) : (float)(window / count);
    }
}

/* Write one band of an image's float32 intensities (rows padded by reflection) and window
 * terms. Window sums come from running float64 column sums, windows reflected at the image
 * edges; per pixel: offset = count * mean * scale, mean = window mean (Eq. 8 only), scale =
 * 1 / sqrt(energy) with energy the sum of squared deviations (Eq. 8) or of squares (Eq. 7), 0
 * where the window is textureless; texture = the window's standard deviation reaches the
 * threshold. Columns are stored reversed when `reverse` (the right image). One of offset_out
 * and mean_out is NULL; texture_out may be. */
CLONED_FOR_SIMD void prepare_band(
    const matcher_call *call, const image_source *source, int reverse, int64_t y_first,
    int64_t y_stop, float *padded_out, float *offset_out, float *mean_out, float *scale_out,
    uint8_t *texture_out, const prepare_memory *memory)
{
    const int64_t height = call->height, width = call->width, radius = call->radius;
    const int64_t size = 2 * radius + 1;
    const double count = (double)(size * size);
    const int zero_mean = call->zero_mean;
    double *restrict column_sum = memory->column_sum;
    double *restrict column_square = memory->column_square;
    double *restrict window_sum = memory->window_sum;
    double *restrict window_square = memory->window_square;
    float *restrict row = memory->row, *restrict other_row = memory->other_row;

    /* Padded rows y_first + r .. y_stop + r - 1, and the r rows above and below the region's
     * rows for its first and last band: padded row p holds image row p - r, reflected. */
    const int64_t region_stop = call->roi_y + call->roi_height;
    const int64_t padded_first = y_first == call->roi_y ? y_first : y_first + radius;
    const int64_t padded_stop = y_stop == region_stop ? y_stop + 2 * radius : y_stop + radius;
    for (int64_t padded_row = padded_first; padded_row < padded_stop; ++padded_row) {
        float *restrict out = padded_out + padded_row * width;
        load_row(source, width, reflect(padded_row - radius, height), row);
        if (reverse)
            for (int64_t x = 0; x < width; ++x) out[width - 1 - x] = row[x];
        else
            memcpy(out, row, (size_t)width * sizeof(float));
    }
    /* Column sums of image column x at index x + r, with r + 1 reflected columns on each side:
     * the running sums along a row then need no edge test per pixel. */
    for (int64_t i = 0; i < width + 2 * radius + 1; ++i) column_sum[i] = column_square[i] = 0.0;
    for (int64_t step = -radius; step <= radius; ++step) {
        load_row(source, width, reflect(y_first + step, height), row);
        for (int64_t x = 0; x < width; ++x) {
            const double value = row[x];
            column_sum[x + radius] += value;
            column_square[x + radius] += value * value;
        }
    }
    for (int64_t y = y_first; y < y_stop; ++y) {
        for (int64_t index = -radius; index < 0; ++index) {
            column_sum[index + radius] = column_sum[-index + radius];
            column_square[index + radius] = column_square[-index + radius];
        }
        for (int64_t index = width; index < width + radius + 1; ++index) {
            column_sum[index + radius] = column_sum[2 * (width - 1) - index + radius];
            column_square[index + radius] = column_square[2 * (width - 1) - index + radius];
        }
        double total = 0.0, square_total = 0.0;
        for (int64_t index = 0; index < size; ++index) {
            total += column_sum[index];
            square_total += column_square[index];
        }
        for (int64_t x = 0; x < width; ++x) { /* running window sums along the row */
            window_sum[x] = total;
            window_square[x] = square_total;
            total += column_sum[x + size] - column_sum[x];
            square_total += column_square[x + size] - column_square[x];
        }
        /* The terms in loops of their own, forward and without branches, so that they
         * vectorise (the square root and the divisions dominate this part); then stored. */
        float *restrict scale_row = row, *restrict term_row = other_row;
        const int offset_term = offset_out != NULL; /* else the mean */
        if (!zero_mean)
            window_terms(0, 0, width, count, call->textured_energy, window_sum, window_square,
                         scale_row, term_row);
        else if (offset_term)
            window_terms(1, 1, width, count, call->textured_energy, window_sum, window_square,
                         scale_row, term_row);
        else
            window_terms(1, 0, width, count, call->textured_energy, window_sum, window_square,
                         scale_row, term_row);
        float *restrict term_out = offset_term ? offset_out : mean_out;
        const int64_t at = y * width;
        if (reverse) {
            for (int64_t x = 0; x < width; ++x) scale_out[at + width - 1 - x] = scale_row[x];
            for (int64_t x = 0; x < width; ++x) term_out[at + width - 1 - x] = term_row[x];
        } else {
            memcpy(scale_out + at, scale_row, (size_t)width * sizeof(float));
            memcpy(term_out + at, term_row, (size_t)width * sizeof(float));
        }
        if (texture_out)
            for (int64_t x = 0; x < width; ++x)
                texture_out[at + (reverse ? width - 1 - x : x)] = scale_row[x] > 0.0f;
        if (y + 1 < y_stop) {
            load_row(source, width, reflect(y + radius + 1, height), row);
            load_row(source, width, reflect(y - radius, height), other_row);
            for (int64_t x = 0; x < width; ++x) {
                const double entering = row[x], leaving = other_row[x];
                column_sum[x + radius] += entering - leaving;
                column_square[x + radius] += entering * entering - leaving * leaving;
            }
        }
    }
}

/* Initial outputs of rows y_first..y_stop-1: NaN disparity and score, and the status of every
 * pixel the correlation does not decide. */
void initialise_outputs(const matcher_call *call, int64_t y_first, int64_t y_stop)
{
    const int64_t width = call->width;
    const int64_t roi_x_end = call->roi_x + call->roi_width;
    const int64_t roi_y_end = call->roi_y + call->roi_height;
    for (int64_t y = y_first; y < y_stop; ++y) {
        float *disparity = call->disparity_out + y * width, *score = call->score_out + y * width;
        uint8_t *status = call->status_out + y * width;
        for (int64_t x = 0; x < width; ++x) disparity[x] = score[x] = NAN;
        if (y < call->roi_y || y >= roi_y_end) {
            memset(status, OUTSIDE_ROI, (size_t)width);
            continue;
        }
        memset(status, OUTSIDE_ROI, (size_t)call->roi_x);
        memset(status + call->roi_x, y % call->row_step ? SKIPPED_ROW : NO_CANDIDATE,
               (size_t)call->roi_width);
        memset(status + roi_x_end, OUTSIDE_ROI, (size_t)(width - roi_x_end));
    }
}
