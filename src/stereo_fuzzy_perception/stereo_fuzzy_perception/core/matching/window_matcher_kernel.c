/*
 * The window-correlation matcher's kernel, whole: image preparation, the correlation of row
 * bands on worker threads and the per-pixel decisions, behind one Python function, correlate()
 * (window_matcher.py explains the method and calls it; nothing else does). triangulate() turns
 * its disparities into the rows a PointCloud2 carries (triangulation.py calls it).
 *
 * One technology, one call: the arguments are parsed here by keyword, so a caller that passes
 * a wrong name, type or buffer gets a TypeError or ValueError instead of a crash, and the
 * status codes and constants the Python side needs are exported from the tables below
 * (STATUS_CODES, FLAT_STD); test_window_matcher.py checks them against the Python enum.
 *
 * Exactness: every sum over an 8-bit image is a sum of integers below 2^24, exact in float32
 * (the correlation's running sums) and float64 (the window statistics), so results do not
 * depend on how rows are split into bands. No fused multiply-add (-ffp-contract=off in
 * setup.py), so the vectorised and scalar loops round alike on every CPU; target_clones picks
 * an AVX-512 (x86-64-v4) or AVX2 body where the CPU has one. Scores are int32 fixed point
 * (1.0 = SCORE_ONE): integer maxima vectorise, and 2^-24 is finer than float32 resolves a score
 * anyway.
 *
 * Threads: correlate() releases the GIL and runs the work on `threads` POSIX threads (the
 * calling one included) started for the call and joined before it returns: no pool spins
 * between calls, nothing to keep safe across fork. Work items (image bands, then row bands)
 * are taken from an atomic counter, so a thread the OS delays leaves its work to the others.
 *
 * Workspace (one caller-owned byte buffer, workspace_bytes() long, kept between calls so that
 * its pages are not faulted in again for every pair), W = width, D = disparity_range, r =
 * radius, each part 64-byte aligned:
 *   left_padded, right_reversed: (H + 2r, W) float32 intensities, rows padded by reflection,
 *     the right image's columns reversed so that candidates are contiguous in the disparity;
 *   left_scale, left_offset, right_mean_reversed, right_scale_reversed: (H, W) float32 window
 *     terms; texture_ok: (H, W) uint8;
 *   per thread: column_sums (W, D) float32, row_scores (W, D) int32, window_sums (D) float32,
 *     right_best, best_score (W) int32 (the band being correlated), and the preparation's
 *     float64 running sums and float32 row buffers.
 * Disparity index i means disparity min_disparity + i; left x meets right x - min_disparity - i,
 * stored at column W - 1 - (x - min_disparity - i) of the reversed arrays.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <string.h>

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define CLONED_FOR_SIMD \
    __attribute__((target_clones("arch=x86-64-v4", "avx2", "default")))
#else
#define CLONED_FOR_SIMD
#endif

/* MatchStatus (window_matcher.py): why a pixel has, or has no, disparity. The one definition;
 * exported to Python as STATUS_CODES. */
#define MATCH_STATUSES(X) \
    X(VALID, 0) X(OUTSIDE_ROI, 1) X(NO_CANDIDATE, 2) X(LOW_TEXTURE, 3) X(LOW_SCORE, 4) \
    X(NOT_UNIQUE, 5) X(LR_INCONSISTENT, 6) X(SKIPPED_ROW, 7)
#define STATUS_ENUM(name, value) name = value,
enum match_status { MATCH_STATUSES(STATUS_ENUM) };

/* Scores inside the kernel: 1.0 = SCORE_ONE; NO_SCORE marks "no candidate", below every score. */
#define SCORE_ONE ((float)(1 << 24))
#define NO_SCORE (-3 * (1 << 24))
/* Windows whose standard deviation is below this [grey levels] are flat whatever the threshold. */
#define FLAT_STD 1e-3
#define MAX_THREADS 64
#define ALIGNMENT 64

typedef enum { PIXELS_UINT8, PIXELS_UINT16, PIXELS_FLOAT32 } pixel_kind;

typedef struct {
    const void *pixels;
    pixel_kind kind;
    float gain, shift; /* intensity = float32(pixel) * gain - shift, each rounded to float32 */
} image_source;

typedef struct {
    int64_t width, radius, min_disparity, disparity_range;
} geometry;

/* Everything one call works on; threads share it read-only except through the work counters
 * and the rows each item owns. */
typedef struct {
    image_source left, right;
    int64_t height, width, radius, min_disparity, disparity_range;
    int zero_mean, subpixel;
    double textured_energy;
    float min_score, uniqueness_ratio;
    int64_t lr_max_diff, row_step;
    int64_t roi_x, roi_y, roi_width, roi_height;
    int64_t x_begin, x_end, out_x_begin, out_x_end; /* columns correlated / decided */
    int64_t prepare_bands, bands;
    float *left_padded, *right_reversed, *left_scale, *left_offset, *right_mean, *right_scale;
    uint8_t *texture_ok;
    char *thread_memory;
    size_t thread_stride;
    float *disparity_out, *score_out;
    uint8_t *status_out;
    atomic_long next_prepare, next_band;
    int64_t prepared_items; /* finished preparation items, under `lock` */
    pthread_mutex_t lock;
    pthread_cond_t all_prepared;
} matcher_call;

/* --- workspace layout --------------------------------------------------------------------- */

static size_t aligned(size_t bytes) { return (bytes + ALIGNMENT - 1) / ALIGNMENT * ALIGNMENT; }

/* Bytes the parts shared by the threads take, with room to align the buffer's start. */
static size_t shared_bytes(int64_t height, int64_t width, int64_t radius)
{
    const size_t image = (size_t)(height * width);
    return ALIGNMENT + 2 * aligned((size_t)((height + 2 * radius) * width) * sizeof(float))
        + 4 * aligned(image * sizeof(float)) + aligned(image);
}

static size_t per_thread_bytes(int64_t width, int64_t radius, int64_t range)
{
    return 2 * aligned((size_t)(width * range) * 4) + aligned((size_t)range * 4)
        + 2 * aligned((size_t)width * 4) + 2 * aligned((size_t)(width + 2 * radius + 1) * 8)
        + 2 * aligned((size_t)width * 8) + 2 * aligned((size_t)width * 4);
}

static char *take(char **cursor, size_t bytes)
{
    char *part = *cursor;
    *cursor += aligned(bytes);
    return part;
}

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

typedef struct {
    double *column_sum, *column_square, *window_sum, *window_square;
    float *row, *other_row;
} prepare_memory;

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
CLONED_FOR_SIMD static void prepare_band(
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
static void initialise_outputs(const matcher_call *call, int64_t y_first, int64_t y_stop)
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
CLONED_FOR_SIMD static void correlate_band(const matcher_call *call, int64_t y_first,
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

/* --- threads ------------------------------------------------------------------------------ */

static void band_rows(int64_t first, int64_t rows, int64_t bands, int64_t band, int64_t *y_first,
                      int64_t *y_stop)
{
    const int64_t per_band = (rows + bands - 1) / bands;
    *y_first = first + band * per_band;
    *y_stop = first + rows < *y_first + per_band ? first + rows : *y_first + per_band;
}

typedef struct {
    matcher_call *call;
    int64_t index;
} worker_argument;

static void *work(void *argument_pointer)
{
    const worker_argument *argument = argument_pointer;
    matcher_call *call = argument->call;
    char *memory = call->thread_memory + (size_t)argument->index * call->thread_stride;
    char *cursor = memory + 2 * aligned((size_t)(call->width * call->disparity_range) * 4)
        + aligned((size_t)call->disparity_range * 4) + 2 * aligned((size_t)call->width * 4);
    const size_t sums = (size_t)(call->width + 2 * call->radius + 1) * 8;
    prepare_memory prepare;
    prepare.column_sum = (double *)take(&cursor, sums);
    prepare.column_square = (double *)take(&cursor, sums);
    prepare.window_sum = (double *)take(&cursor, (size_t)call->width * 8);
    prepare.window_square = (double *)take(&cursor, (size_t)call->width * 8);
    prepare.row = (float *)take(&cursor, (size_t)call->width * 4);
    prepare.other_row = (float *)take(&cursor, (size_t)call->width * 4);

    /* 1. The region's rows of both images, in bands: left ones (with the outputs of a band of
     * the whole image's rows) then right ones. Rows outside the region are never read. */
    const int64_t prepare_items = 2 * call->prepare_bands;
    for (int64_t item; (item = atomic_fetch_add(&call->next_prepare, 1)) < prepare_items;) {
        const int right = item >= call->prepare_bands;
        const int64_t band = item % call->prepare_bands;
        int64_t y_first, y_stop;
        band_rows(call->roi_y, call->roi_height, call->prepare_bands, band, &y_first, &y_stop);
        if (y_first < y_stop && right) {
            prepare_band(call, &call->right, 1, y_first, y_stop, call->right_reversed, NULL,
                         call->right_mean, call->right_scale, NULL, &prepare);
        } else if (!right) {
            if (y_first < y_stop)
                prepare_band(call, &call->left, 0, y_first, y_stop, call->left_padded,
                             call->left_offset, NULL, call->left_scale, call->texture_ok,
                             &prepare);
            band_rows(0, call->height, call->prepare_bands, band, &y_first, &y_stop);
            if (y_first < y_stop) initialise_outputs(call, y_first, y_stop);
        }
        pthread_mutex_lock(&call->lock);
        if (++call->prepared_items == prepare_items) pthread_cond_broadcast(&call->all_prepared);
        pthread_mutex_unlock(&call->lock);
    }
    /* Correlating a band reads its neighbours' prepared rows: wait until every band is in. */
    pthread_mutex_lock(&call->lock);
    while (call->prepared_items < prepare_items)
        pthread_cond_wait(&call->all_prepared, &call->lock);
    pthread_mutex_unlock(&call->lock);
    /* 2. Row bands of the region. */
    if (call->out_x_begin >= call->out_x_end) return NULL;
    for (int64_t band; (band = atomic_fetch_add(&call->next_band, 1)) < call->bands;) {
        int64_t y_first, y_stop;
        band_rows(call->roi_y, call->roi_height, call->bands, band, &y_first, &y_stop);
        if (y_first < y_stop) correlate_band(call, y_first, y_stop, memory);
    }
    return NULL;
}

/* Run `work` on `threads` threads, the calling one included; fewer when the OS refuses one
 * (the work items then fall to the threads there are). */
static void run_threads(matcher_call *call, int64_t threads)
{
    pthread_t handles[MAX_THREADS];
    worker_argument arguments[MAX_THREADS];
    int64_t started = 1;
    for (int64_t index = 0; index < threads; ++index)
        arguments[index] = (worker_argument){call, index};
    for (; started < threads; ++started)
        if (pthread_create(&handles[started], NULL, work, &arguments[started]) != 0) break;
    work(&arguments[0]);
    for (int64_t index = 1; index < started; ++index) pthread_join(handles[index], NULL);
}

/* --- Python interface --------------------------------------------------------------------- */

typedef struct {
    Py_buffer view;
    int held;
} buffer_hold;

static void release_all(buffer_hold *holds, int count)
{
    for (int index = 0; index < count; ++index)
        if (holds[index].held) PyBuffer_Release(&holds[index].view);
}

/* Borrow a C-contiguous buffer; `formats` lists the accepted struct codes ("B", "H", "f"). */
static int hold(PyObject *object, buffer_hold *hold, const char *name, int writable, int ndim,
                const char *formats)
{
    const int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(object, &hold->view, flags) != 0) {
        PyErr_Format(PyExc_TypeError, "%s must be a C-contiguous%s array", name,
                     writable ? " writable" : "");
        return -1;
    }
    hold->held = 1;
    const char *format = hold->view.format ? hold->view.format : "B";
    if (*format == '@' || *format == '=' || *format == '<') ++format;
    if (hold->view.ndim != ndim || strlen(format) != 1 || !strchr(formats, *format)) {
        PyErr_Format(PyExc_TypeError, "%s must be a %dD array of struct code(s) %s, not %dD %s",
                     name, ndim, formats, hold->view.ndim, hold->view.format);
        return -1;
    }
    return 0;
}

static void image_of(const buffer_hold *hold, float shift, image_source *source)
{
    const char *format = hold->view.format;
    const char code = format[strlen(format) - 1];
    source->pixels = hold->view.buf;
    source->shift = shift;
    source->gain = 1.0f;
    source->kind = code == 'B' ? PIXELS_UINT8 : code == 'H' ? PIXELS_UINT16 : PIXELS_FLOAT32;
    if (source->kind == PIXELS_UINT16) source->gain = (float)(255.0 / 65535.0);
}

static PyObject *workspace_bytes(PyObject *self, PyObject *args, PyObject *kwargs)
{
    static char *keywords[] = {"height", "width", "radius", "disparity_range", "threads", NULL};
    Py_ssize_t height, width, radius, range, threads;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(args, kwargs, "$nnnnn", keywords, &height, &width, &radius,
                                     &range, &threads))
        return NULL;
    if (height < 1 || width < 1 || radius < 0 || range < 1 || threads < 1) {
        PyErr_SetString(PyExc_ValueError, "sizes must be positive");
        return NULL;
    }
    return PyLong_FromSize_t(shared_bytes(height, width, radius)
                             + (size_t)threads * per_thread_bytes(width, radius, range));
}

static PyObject *correlate(PyObject *self, PyObject *args, PyObject *kwargs)
{
    static char *keywords[] = {
        "left", "right", "disparity", "score", "status", "workspace", "zero_mean", "radius",
        "min_disparity", "disparity_range", "texture_threshold", "min_score",
        "uniqueness_ratio", "lr_max_diff", "subpixel", "roi", "row_step", "bands", "threads",
        NULL};
    PyObject *objects[6];
    int zero_mean, subpixel;
    Py_ssize_t radius, min_disparity, range, lr_max_diff, row_step, bands, threads;
    Py_ssize_t roi_x, roi_y, roi_width, roi_height;
    double texture_threshold, min_score, uniqueness_ratio;
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(
            args, kwargs, "OOOOOO$pnnndddnp(nnnn)nnn", keywords, &objects[0], &objects[1],
            &objects[2], &objects[3], &objects[4], &objects[5], &zero_mean, &radius,
            &min_disparity, &range, &texture_threshold, &min_score, &uniqueness_ratio,
            &lr_max_diff, &subpixel, &roi_x, &roi_y, &roi_width, &roi_height, &row_step, &bands,
            &threads))
        return NULL;
    static const char *names[] = {"left", "right", "disparity", "score", "status", "workspace"};
    static const char *formats[] = {"BHf", "BHf", "f", "f", "B", "B"};
    buffer_hold holds[6];
    memset(holds, 0, sizeof holds);
    for (int index = 0; index < 6; ++index) {
        if (hold(objects[index], &holds[index], names[index], index >= 2, index == 5 ? 1 : 2,
                 formats[index]) != 0) {
            release_all(holds, 6);
            return NULL;
        }
    }
    const Py_ssize_t height = holds[0].view.shape[0], width = holds[0].view.shape[1];
    const char *problem = NULL;
    for (int index = 1; index < 5; ++index)
        if (holds[index].view.shape[0] != height || holds[index].view.shape[1] != width)
            problem = "images and outputs must have one shape";
    if (radius < 1 || 2 * radius + 1 > height || 2 * radius + 1 > width)
        problem = "the window must fit the image";
    if (range < 1 || min_disparity < -4096 || min_disparity > 4096)
        problem = "disparities out of range";
    if (roi_x < 0 || roi_y < 0 || roi_width < 1 || roi_height < 1 || roi_x + roi_width > width
            || roi_y + roi_height > height)
        problem = "roi must lie inside the image";
    if (row_step < 1 || bands < 1 || threads < 1 || threads > MAX_THREADS)
        problem = "row_step, bands and threads must be positive (threads at most 64)";
    if (!problem && (size_t)holds[5].view.len < shared_bytes(height, width, radius)
                                                 + (size_t)threads
                                                       * per_thread_bytes(width, radius, range))
        problem = "workspace is shorter than workspace_bytes()";
    if (problem) {
        PyErr_SetString(PyExc_ValueError, problem);
        release_all(holds, 6);
        return NULL;
    }

    matcher_call call;
    memset(&call, 0, sizeof call);
    image_of(&holds[0], zero_mean ? 128.0f : 0.0f, &call.left);
    image_of(&holds[1], zero_mean ? 128.0f : 0.0f, &call.right);
    call.height = height;
    call.width = width;
    call.radius = radius;
    call.min_disparity = min_disparity;
    call.disparity_range = range;
    call.zero_mean = zero_mean;
    call.subpixel = subpixel;
    const Py_ssize_t size = 2 * radius + 1;
    const double flat = texture_threshold > FLAT_STD * (1.0 + 1e-9) ? texture_threshold
                                                                     : FLAT_STD * (1.0 + 1e-9);
    /* The window's standard deviation sqrt(deviation / count) reaches the threshold (and is not
     * flat) where the deviation reaches this. */
    call.textured_energy = (double)(size * size) * pow(flat, 2.0);
    call.min_score = (float)min_score;
    call.uniqueness_ratio = (float)uniqueness_ratio;
    call.lr_max_diff = lr_max_diff;
    call.row_step = row_step;
    call.roi_x = roi_x;
    call.roi_y = roi_y;
    call.roi_width = roi_width;
    call.roi_height = roi_height;
    /* The left-right check needs every candidate of the right pixels the region reaches. */
    const int64_t reach = lr_max_diff >= 0 ? range - 1 : 0;
    call.x_begin = roi_x - reach > radius ? roi_x - reach : radius;
    call.x_end = roi_x + roi_width + reach < width - radius ? roi_x + roi_width + reach
                                                            : width - radius;
    call.out_x_begin = roi_x > radius ? roi_x : radius;
    call.out_x_end = roi_x + roi_width < width - radius ? roi_x + roi_width : width - radius;
    call.prepare_bands = 2 * threads < roi_height ? 2 * threads : roi_height;
    call.bands = bands < roi_height ? bands : roi_height;
    char *cursor = (char *)holds[5].view.buf;
    cursor += (ALIGNMENT - (uintptr_t)cursor % ALIGNMENT) % ALIGNMENT;
    const size_t padded = (size_t)((height + 2 * radius) * width) * sizeof(float);
    const size_t plane = (size_t)(height * width) * sizeof(float);
    call.left_padded = (float *)take(&cursor, padded);
    call.right_reversed = (float *)take(&cursor, padded);
    call.left_scale = (float *)take(&cursor, plane);
    call.left_offset = (float *)take(&cursor, plane);
    call.right_mean = (float *)take(&cursor, plane);
    call.right_scale = (float *)take(&cursor, plane);
    call.texture_ok = (uint8_t *)take(&cursor, (size_t)(height * width));
    call.thread_memory = cursor;
    call.thread_stride = per_thread_bytes(width, radius, range);
    call.disparity_out = holds[2].view.buf;
    call.score_out = holds[3].view.buf;
    call.status_out = holds[4].view.buf;
    atomic_init(&call.next_prepare, 0);
    atomic_init(&call.next_band, 0);
    pthread_mutex_init(&call.lock, NULL);
    pthread_cond_init(&call.all_prepared, NULL);
    Py_BEGIN_ALLOW_THREADS
    run_threads(&call, threads);
    Py_END_ALLOW_THREADS
    pthread_cond_destroy(&call.all_prepared);
    pthread_mutex_destroy(&call.lock);
    release_all(holds, 6);
    Py_RETURN_NONE;
}

typedef struct {
    double fx, fy, cx, cy, tx, ty, numerator, principal_shift, r[9];
} projection;

/* Write the points of row v (every stride-th column) to `out` and return how many: first each
 * sampled column's point, branch-free so that it vectorises (three divisions a point), then the
 * valid ones packed. scratch holds 4 floats per sampled column. */
CLONED_FOR_SIMD static int64_t triangulate_row(
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

/* Triangulate the valid pixels of every stride-th row and column (triangulation.py explains
 * the geometry) into `points`, one (x, y, z, u_left, v_left, u_right, score) float32 row per
 * point, in row-major pixel order; return the number of points. */
static PyObject *triangulate(PyObject *self, PyObject *args, PyObject *kwargs)
{
    static char *keywords[] = {"disparity", "score", "points", "stride", "fx", "fy", "cx", "cy",
                               "tx", "ty", "numerator", "principal_shift", "rotation", NULL};
    PyObject *objects[3];
    Py_ssize_t stride;
    double fx, fy, cx, cy, tx, ty, numerator, principal_shift, r[9];
    (void)self;
    if (!PyArg_ParseTupleAndKeywords(
            args, kwargs, "OOO$ndddddddd(ddddddddd)", keywords, &objects[0], &objects[1],
            &objects[2], &stride, &fx, &fy, &cx, &cy, &tx, &ty, &numerator, &principal_shift,
            &r[0], &r[1], &r[2], &r[3], &r[4], &r[5], &r[6], &r[7], &r[8]))
        return NULL;
    static const char *names[] = {"disparity", "score", "points"};
    buffer_hold holds[3];
    memset(holds, 0, sizeof holds);
    for (int index = 0; index < 3; ++index) {
        if (hold(objects[index], &holds[index], names[index], index == 2, 2, "f") != 0) {
            release_all(holds, 3);
            return NULL;
        }
    }
    const Py_ssize_t height = holds[0].view.shape[0], width = holds[0].view.shape[1];
    const char *problem = NULL;
    if (stride < 1) problem = "stride must be >= 1";
    else if (holds[1].view.shape[0] != height || holds[1].view.shape[1] != width)
        problem = "disparity and score must have one shape";
    else if (holds[2].view.shape[1] != 7
             || holds[2].view.shape[0] < ((height + stride - 1) / stride)
                                             * ((width + stride - 1) / stride))
        problem = "points must be (n, 7) with a row for every sampled pixel";
    if (problem) {
        PyErr_SetString(PyExc_ValueError, problem);
        release_all(holds, 3);
        return NULL;
    }
    const float *disparity = holds[0].view.buf, *score = holds[1].view.buf;
    float *out = holds[2].view.buf;
    const projection geometry = {fx, fy, cx, cy, tx, ty, numerator, principal_shift,
                                 {r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]}};
    const Py_ssize_t columns = (width + stride - 1) / stride;
    float *scratch = PyMem_Malloc((size_t)(4 * columns) * sizeof(float));
    if (!scratch) {
        release_all(holds, 3);
        return PyErr_NoMemory();
    }
    Py_ssize_t count = 0;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t v = 0; v < height; v += stride)
        count += triangulate_row(&geometry, disparity + v * width, score + v * width, v, width,
                                 stride, scratch, out + 7 * count);
    Py_END_ALLOW_THREADS
    PyMem_Free(scratch);
    release_all(holds, 3);
    return PyLong_FromSsize_t(count);
}

static PyMethodDef kernel_methods[] = {
    {"correlate", (PyCFunction)(void (*)(void))correlate, METH_VARARGS | METH_KEYWORDS,
     "Match a rectified pair into disparity, score and status (window_matcher.match)."},
    {"triangulate", (PyCFunction)(void (*)(void))triangulate, METH_VARARGS | METH_KEYWORDS,
     "Triangulate valid disparities into (x, y, z, u_left, v_left, u_right, score) rows."},
    {"workspace_bytes", (PyCFunction)(void (*)(void))workspace_bytes,
     METH_VARARGS | METH_KEYWORDS, "Bytes of the workspace correlate() needs."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef kernel_module = {
    PyModuleDef_HEAD_INIT, "_window_matcher_kernel",
    "The window-correlation matcher's kernel (window_matcher_kernel.c).", -1, kernel_methods,
    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__window_matcher_kernel(void)
{
    PyObject *module = PyModule_Create(&kernel_module);
    PyObject *codes = module ? PyDict_New() : NULL;
    if (!codes) goto fail;
#define STATUS_ENTRY(name, value)                                                  \
    {                                                                              \
        PyObject *code = PyLong_FromLong(value);                                   \
        if (!code || PyDict_SetItemString(codes, #name, code) < 0) {               \
            Py_XDECREF(code);                                                      \
            goto fail;                                                             \
        }                                                                          \
        Py_DECREF(code);                                                           \
    }
    MATCH_STATUSES(STATUS_ENTRY)
#undef STATUS_ENTRY
    if (PyModule_AddObjectRef(module, "STATUS_CODES", codes) < 0
            || PyModule_AddObject(module, "FLAT_STD", PyFloat_FromDouble(FLAT_STD)) < 0
            || PyModule_AddIntConstant(module, "MAX_THREADS", MAX_THREADS) < 0)
        goto fail;
    Py_DECREF(codes);
    return module;
fail:
    Py_XDECREF(codes);
    Py_XDECREF(module);
    return NULL;
}
