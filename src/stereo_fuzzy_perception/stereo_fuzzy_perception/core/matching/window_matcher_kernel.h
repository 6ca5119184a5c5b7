/*
 * The window-correlation matcher's kernel, whole: image preparation, the correlation of row
 * bands on worker threads and the per-pixel decisions, behind one Python function, correlate()
 * (window_matcher.py explains the method and calls it; nothing else does). triangulate() turns
 * its disparities into the rows a PointCloud2 carries (triangulation.py calls it).
 *
 * This header is what its translation units share (setup.py compiles them into one extension
 * module): window_matcher_kernel.c (the Python interface: argument parsing, workspace layout,
 * the module and its constants), matcher_prepare.c (image preparation), matcher_correlate.c
 * (correlation and decisions of a row band), matcher_threads.c (work items on POSIX threads)
 * and matcher_triangulate.c (disparities to points).
 *
 * One technology, one call: the arguments are parsed here by keyword, so a caller that passes
 * a wrong name, type or buffer gets a TypeError or ValueError instead of a crash, and the
 * status codes and constants the Python side needs are exported from the tables here
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
#ifndef WINDOW_MATCHER_KERNEL_H
#define WINDOW_MATCHER_KERNEL_H

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

/* MatchStatus (matcher_config.py): why a pixel has, or has no, disparity. The one definition;
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

/* The preparation's running sums and row buffers, in a thread's part of the workspace. */
typedef struct {
    double *column_sum, *column_square, *window_sum, *window_square;
    float *row, *other_row;
} prepare_memory;

/* A rectified left camera's projection, for triangulate_row. */
typedef struct {
    double fx, fy, cx, cy, tx, ty, numerator, principal_shift, r[9];
} projection;

/* --- workspace layout --------------------------------------------------------------------- */

static inline size_t aligned(size_t bytes) { return (bytes + ALIGNMENT - 1) / ALIGNMENT * ALIGNMENT; }

/* Bytes the parts shared by the threads take, with room to align the buffer's start. */
static inline size_t shared_bytes(int64_t height, int64_t width, int64_t radius)
{
    const size_t image = (size_t)(height * width);
    return ALIGNMENT + 2 * aligned((size_t)((height + 2 * radius) * width) * sizeof(float))
        + 4 * aligned(image * sizeof(float)) + aligned(image);
}

static inline size_t per_thread_bytes(int64_t width, int64_t radius, int64_t range)
{
    return 2 * aligned((size_t)(width * range) * 4) + aligned((size_t)range * 4)
        + 2 * aligned((size_t)width * 4) + 2 * aligned((size_t)(width + 2 * radius + 1) * 8)
        + 2 * aligned((size_t)width * 8) + 2 * aligned((size_t)width * 4);
}

static inline char *take(char **cursor, size_t bytes)
{
    char *part = *cursor;
    *cursor += aligned(bytes);
    return part;
}

/* Functions one translation unit defines for another; not exported from the module. */
#pragma GCC visibility push(hidden)
/* matcher_prepare.c */
void prepare_band(const matcher_call *call, const image_source *source, int reverse,
                  int64_t y_first, int64_t y_stop, float *padded_out, float *offset_out,
                  float *mean_out, float *scale_out, uint8_t *texture_out,
                  const prepare_memory *memory);
void initialise_outputs(const matcher_call *call, int64_t y_first, int64_t y_stop);
/* matcher_correlate.c */
void correlate_band(const matcher_call *call, int64_t y_first, int64_t y_stop, char *memory);
/* matcher_threads.c */
void run_threads(matcher_call *call, int64_t threads);
/* matcher_triangulate.c */
int64_t triangulate_row(const projection *p, const float *restrict disparity,
                        const float *restrict score, int64_t v, int64_t width, int64_t stride,
                        float *restrict scratch, float *restrict out);
#pragma GCC visibility pop

#endif
