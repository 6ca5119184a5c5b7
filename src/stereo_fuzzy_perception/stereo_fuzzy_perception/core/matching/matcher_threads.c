/*
 * The window matcher kernel's work items (image bands, then row bands) on POSIX threads
 * (window_matcher_kernel.h has the overview).
 */
#include "window_matcher_kernel.h"

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
void run_threads(matcher_call *call, int64_t threads)
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
