/*
 * The window matcher kernel's Python interface: argument parsing, the workspace layout,
 * the module and its constants (window_matcher_kernel.h has the overview).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "window_matcher_kernel.h"

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
