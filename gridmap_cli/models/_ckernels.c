/* gridmap's compiled mapping kernels: the inner loops of the sonar cone (standard and
 * error-aware) and of the ray model, over one batch of readings.
 *
 * Each kernel repeats its numpy reference (gridmap_cli/models/sector.py, standard.py, ray.py,
 * error_aware.py) operation for operation, in the same order, so that the grids are equal bit
 * for bit: the per-reading trigonometry stays in numpy; here the row and span arithmetic is
 * plain IEEE +, -, *, /, sqrt, floor and ceil (built with -ffp-contract=off: no fused
 * multiply-adds), and float evidence goes into a per-batch difference array in the order
 * np.bincount adds it (every run's start, then every run's end), which is then added to the
 * running sums as SpanSums.add does. Integer counts are exact in any order.
 *
 * Arrays arrive through the buffer protocol (contiguous float64 / int64, checked here), so the
 * module needs no numpy headers to build. gridmap_cli/models/kernels.py is the Python side.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* ---- buffers ------------------------------------------------------------------------- */

typedef struct {
    Py_buffer view;
    int held;
} Buf;

/* Take a contiguous buffer of `n` 8-byte items (n < 0: any length); writable when asked. */
static int take(PyObject *obj, Buf *b, Py_ssize_t n, int writable, const char *name)
{
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, &b->view, flags) != 0)
        return -1;
    b->held = 1;
    if (b->view.itemsize != 8 || (n >= 0 && b->view.len != n * 8)) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd items of 8 bytes, got %zd bytes",
                     name, n, b->view.len);
        return -1;
    }
    return 0;
}

static void release(Buf *bufs, int count)
{
    for (int i = 0; i < count; i++)
        if (bufs[i].held)
            PyBuffer_Release(&bufs[i].view);
}

#define F64(b) ((const double *)(b).view.buf)
#define I64(b) ((const int64_t *)(b).view.buf)

/* ---- the sector geometry (sector.py) ---------------------------------------------- */

/* x-extent of {dx : a dx + b dy >= 0}: lo > hi when empty (sector.py _half_plane). */
static inline void half_plane(double a, double b, double dy, double *lo, double *hi)
{
    if (a == 0.0) {
        if (b * dy >= 0.0) {
            *lo = -INFINITY;
            *hi = INFINITY;
        } else {
            *lo = INFINITY;
            *hi = -INFINITY;
        }
        return;
    }
    double bound = (-b * dy) / a;
    if (a > 0.0) {
        *lo = bound;
        *hi = INFINITY;
    } else {
        *lo = -INFINITY;
        *hi = bound;
    }
}

/* The column span of the wedge extent [lo_m, hi_m] cut by the disk of radius r in a row dy
 * from the apex (SectorRows.spans); returns 0 when the run is empty. */
static inline int span(double lo_m, double hi_m, double dy, double r, double sx, double ox,
                       double res, int64_t width, int64_t *c0, int64_t *c1)
{
    double d2 = r * r - dy * dy;
    double half = sqrt(d2 > 0.0 ? d2 : 0.0);
    double lo = lo_m > -half ? lo_m : -half;
    double hi = hi_m < half ? hi_m : half;
    double c0f = ceil((sx + lo - ox) / res - 0.5);
    double c1f = floor((sx + hi - ox) / res - 0.5);
    if (!(d2 >= 0.0 && r > 0.0 && c0f <= c1f && c1f >= 0.0 && c0f <= (double)(width - 1)))
        return 0;
    double top = (double)(width - 1);
    *c0 = (int64_t)(c0f < 0.0 ? 0.0 : (c0f > top ? top : c0f));
    *c1 = (int64_t)(c1f < 0.0 ? 0.0 : (c1f > top ? top : c1f));
    return 1;
}

/* The wedge's extent in one row (sector_rows: right of the left edge, left of the right). */
static inline void wedge(double sin_r, double cos_r, double sin_l, double cos_l, double dy,
                         double *lo, double *hi)
{
    double lo1, hi1, lo2, hi2;
    half_plane(-sin_r, cos_r, dy, &lo1, &hi1);
    half_plane(sin_l, -cos_l, dy, &lo2, &hi2);
    *lo = lo1 > lo2 ? lo1 : lo2;
    *hi = hi1 < hi2 ? hi1 : hi2;
}

/* ---- difference arrays ------------------------------------------------------------- */

/* A float delta over the index range [base, base + size) of a difference array, with the
 * run ends held back until every start is in (np.bincount's order). */
typedef struct {
    double *delta;
    int64_t base, size;
    int64_t *end_at;
    double *end_value;
    int64_t ends, cap;
} Delta;

static int delta_open(Delta *d, int64_t base, int64_t size, int64_t max_ends)
{
    memset(d, 0, sizeof *d);
    d->base = base;
    d->size = size > 0 ? size : 0;
    d->cap = max_ends > 0 ? max_ends : 0;
    d->delta = calloc((size_t)d->size + 1, sizeof(double));
    d->end_at = malloc(((size_t)d->cap + 1) * sizeof(int64_t));
    d->end_value = malloc(((size_t)d->cap + 1) * sizeof(double));
    if (!d->delta || !d->end_at || !d->end_value) {
        PyErr_NoMemory();
        return -1;
    }
    return 0;
}

static inline void delta_run(Delta *d, int64_t start, int64_t end, double value)
{
    d->delta[start - d->base] += value;
    d->end_at[d->ends] = end;
    d->end_value[d->ends] = -value;
    d->ends++;
}

/* The held-back ends, then the delta into the running sums. */
static void delta_close(Delta *d, double *sums)
{
    for (int64_t k = 0; k < d->ends; k++)
        d->delta[d->end_at[k] - d->base] += d->end_value[k];
    for (int64_t k = 0; k < d->size; k++)
        sums[d->base + k] += d->delta[k];
}

static void delta_free(Delta *d)
{
    free(d->delta);
    free(d->end_at);
    free(d->end_value);
}

/* The index range of the difference array that rows j0[m] .. j0[m] + counts[m] - 1 touch. */
static void row_range(const int64_t *j0, const int64_t *counts, Py_ssize_t m, int64_t stride,
                      int64_t *base, int64_t *size, int64_t *rows)
{
    int64_t lo = INT64_MAX, hi = -1, total = 0;
    for (Py_ssize_t i = 0; i < m; i++) {
        if (counts[i] <= 0)
            continue;
        total += counts[i];
        if (j0[i] < lo)
            lo = j0[i];
        if (j0[i] + counts[i] - 1 > hi)
            hi = j0[i] + counts[i] - 1;
    }
    if (hi < 0) {
        *base = 0;
        *size = 0;
    } else {
        *base = lo * stride;
        *size = (hi - lo + 1) * stride;
    }
    *rows = total;
}

/* ---- the standard sonar cone (standard.py accumulate_sectors_numpy) ------------------ */

static PyObject *sector_batch(PyObject *self, PyObject *args)
{
    (void)self;
    double ox, oy, res;
    int64_t width, height;
    PyObject *o[14];
    if (!PyArg_ParseTuple(args, "dddLLOOOOOOOOOOOOOO", &ox, &oy, &res, &width, &height, &o[0],
                          &o[1], &o[2], &o[3], &o[4], &o[5], &o[6], &o[7], &o[8], &o[9], &o[10],
                          &o[11], &o[12], &o[13]))
        return NULL;
    Buf b[14] = {0};
    PyObject *result = NULL;
    Delta outer = {0}, inner = {0};
    int64_t stride = width + 1;
    if (take(o[0], &b[0], -1, 0, "x") != 0)
        goto done;
    Py_ssize_t m = b[0].view.len / 8;
    static const char *names[] = {"x",     "y",       "sin_r",         "cos_r",
                                  "sin_l", "cos_l",   "j0",            "counts",
                                  "outer_m", "outer_value", "inner_m", "inner_value"};
    for (int i = 1; i < 12; i++)
        if (take(o[i], &b[i], m, 0, names[i]) != 0)
            goto done;
    if (take(o[12], &b[12], height * stride, 1, "value_sums") != 0 ||
        take(o[13], &b[13], height * stride, 1, "count_sums") != 0)
        goto done;
    const double *x = F64(b[0]), *y = F64(b[1]), *sin_r = F64(b[2]), *cos_r = F64(b[3]),
                 *sin_l = F64(b[4]), *cos_l = F64(b[5]), *outer_m = F64(b[8]),
                 *outer_value = F64(b[9]), *inner_m = F64(b[10]), *inner_value = F64(b[11]);
    const int64_t *j0 = I64(b[6]), *counts = I64(b[7]);
    double *value_sums = (double *)b[12].view.buf;
    int64_t *count_sums = (int64_t *)b[13].view.buf;

    int64_t base, size, rows;
    row_range(j0, counts, m, stride, &base, &size, &rows);
    if (delta_open(&outer, base, size, rows) != 0 || delta_open(&inner, base, size, rows) != 0)
        goto done;
    long long cells = 0;
    for (Py_ssize_t i = 0; i < m; i++) {
        if (counts[i] <= 0)
            continue;
        double r_out = outer_m[i], v_out = outer_value[i];
        double r_in = inner_m[i], v_in = inner_value[i];
        for (int64_t k = 0; k < counts[i]; k++) {
            int64_t row = j0[i] + k;
            double dy = oy + ((double)row + 0.5) * res - y[i];
            double lo, hi;
            int64_t c0, c1;
            wedge(sin_r[i], cos_r[i], sin_l[i], cos_l[i], dy, &lo, &hi);
            int64_t at = row * stride;
            if (span(lo, hi, dy, r_out, x[i], ox, res, width, &c0, &c1)) {
                count_sums[at + c0] += 1;
                count_sums[at + c1 + 1] -= 1;
                cells += c1 - c0 + 1;
                if (v_out != 0.0)
                    delta_run(&outer, at + c0, at + c1 + 1, v_out);
            }
            if (span(lo, hi, dy, r_in, x[i], ox, res, width, &c0, &c1))
                delta_run(&inner, at + c0, at + c1 + 1, v_in);
        }
    }
    delta_close(&outer, value_sums);
    delta_close(&inner, value_sums);
    result = PyLong_FromLongLong(cells);
done:
    delta_free(&outer);
    delta_free(&inner);
    release(b, 14);
    return result;
}

/* ---- the error-aware sonar cone (error_aware.py ErrorAwareSonarModel.runs, add_runs) -- */

/* One trust class's readings: the echo ring (free_m, look_m] of the wide wedge (the wide disk
 * of look_m, +1, less that of free_m, -1, over the ring's rows), looked at with the reading's
 * weight and hit with weight * hit; and the narrow wedge up to free_m (+1), looked through.
 * The runs go in the reference's order: every part's starts, part by part, then the ends. */
static PyObject *spread_batch(PyObject *self, PyObject *args)
{
    (void)self;
    double ox, oy, res;
    int64_t width, height;
    PyObject *o[21];
    if (!PyArg_ParseTuple(args, "dddLLOOOOOOOOOOOOOOOOOOOOO", &ox, &oy, &res, &width, &height,
                          &o[0], &o[1], &o[2], &o[3], &o[4], &o[5], &o[6], &o[7], &o[8], &o[9],
                          &o[10], &o[11], &o[12], &o[13], &o[14], &o[15], &o[16], &o[17],
                          &o[18], &o[19], &o[20]))
        return NULL;
    Buf b[21] = {0};
    PyObject *result = NULL;
    Delta looks = {0}, hits = {0};
    int64_t stride = width + 1;
    if (take(o[0], &b[0], -1, 0, "x") != 0)
        goto done;
    Py_ssize_t m = b[0].view.len / 8;
    static const char *names[] = {"x",       "y",       "wide_sin_r", "wide_cos_r",
                                  "wide_sin_l", "wide_cos_l", "wide_j0", "wide_counts",
                                  "narrow_sin_r", "narrow_cos_r", "narrow_sin_l",
                                  "narrow_cos_l", "narrow_j0", "narrow_counts", "look_m",
                                  "free_m",  "weight",  "hit"};
    for (int i = 1; i < 18; i++)
        if (take(o[i], &b[i], m, 0, names[i]) != 0)
            goto done;
    if (take(o[18], &b[18], height * stride, 1, "look_sums") != 0 ||
        take(o[19], &b[19], height * stride, 1, "hit_sums") != 0 ||
        take(o[20], &b[20], height * stride, 1, "seen_sums") != 0)
        goto done;
    const double *x = F64(b[0]), *y = F64(b[1]);
    const double *trig[2][4] = {{F64(b[2]), F64(b[3]), F64(b[4]), F64(b[5])},
                                {F64(b[8]), F64(b[9]), F64(b[10]), F64(b[11])}};
    const int64_t *j0[2] = {I64(b[6]), I64(b[12])}, *counts[2] = {I64(b[7]), I64(b[13])};
    const double *look_m = F64(b[14]), *free_m = F64(b[15]), *weight = F64(b[16]),
                 *hit = F64(b[17]);
    double *look_sums = (double *)b[18].view.buf, *hit_sums = (double *)b[19].view.buf;
    int64_t *seen_sums = (int64_t *)b[20].view.buf;

    int64_t base[2], size[2], rows[2];
    for (int w = 0; w < 2; w++)
        row_range(j0[w], counts[w], m, stride, &base[w], &size[w], &rows[w]);
    int64_t lo_at = base[0], hi_at = base[0] + size[0];
    if (size[0] == 0 || (size[1] > 0 && base[1] < lo_at))
        lo_at = base[1];
    if (size[0] == 0 || (size[1] > 0 && base[1] + size[1] > hi_at))
        hi_at = base[1] + size[1];
    if (size[0] == 0 && size[1] == 0)
        lo_at = hi_at = 0;
    int64_t max_runs = 2 * rows[0] + rows[1];
    if (delta_open(&looks, lo_at, hi_at - lo_at, max_runs) != 0 ||
        delta_open(&hits, lo_at, hi_at - lo_at, max_runs) != 0)
        goto done;

    /* part: (wedge, radius, sign, in the ring) */
    static const int part_wedge[3] = {0, 0, 1}, part_sign[3] = {1, -1, 1};
    static const int part_ring[3] = {1, 1, 0};
    long long cells = 0;
    for (int p = 0; p < 3; p++) {
        int w = part_wedge[p];
        const double *radius = p == 0 ? look_m : free_m;
        for (Py_ssize_t i = 0; i < m; i++) {
            if (counts[w][i] <= 0)
                continue;
            double look = part_sign[p] * weight[i];
            double hit_mass = look * hit[i];
            for (int64_t k = 0; k < counts[w][i]; k++) {
                int64_t row = j0[w][i] + k;
                double dy = oy + ((double)row + 0.5) * res - y[i];
                double lo, hi;
                int64_t c0, c1;
                wedge(trig[w][0][i], trig[w][1][i], trig[w][2][i], trig[w][3][i], dy, &lo, &hi);
                if (!span(lo, hi, dy, radius[i], x[i], ox, res, width, &c0, &c1))
                    continue;
                int64_t at = row * stride;
                seen_sums[at + c0] += part_sign[p];
                seen_sums[at + c1 + 1] -= part_sign[p];
                delta_run(&looks, at + c0, at + c1 + 1, look);
                if (part_ring[p])
                    delta_run(&hits, at + c0, at + c1 + 1, hit_mass);
                if (p == 0)
                    cells += c1 - c0 + 1;
            }
        }
    }
    delta_close(&looks, look_sums);
    delta_close(&hits, hit_sums);
    result = PyLong_FromLongLong(cells);
done:
    delta_free(&looks);
    delta_free(&hits);
    release(b, 21);
    return result;
}

/* ---- the ray model's free runs (ray.py row_runs) ------------------------------------- */

static PyObject *ray_batch(PyObject *self, PyObject *args)
{
    (void)self;
    int64_t width;
    int clip;
    double l_free;
    PyObject *o[10];
    if (!PyArg_ParseTuple(args, "LOOOOOOOOpdOO", &width, &o[0], &o[1], &o[2], &o[3], &o[4],
                          &o[5], &o[6], &o[7], &clip, &l_free, &o[8], &o[9]))
        return NULL;
    Buf b[10] = {0};
    PyObject *result = NULL;
    Delta delta = {0};
    int64_t stride = width + 1;
    if (take(o[0], &b[0], -1, 0, "ra") != 0)
        goto done;
    Py_ssize_t n = b[0].view.len / 8;
    static const char *names[] = {"ra", "rb", "p_lo", "counts", "off", "slope", "ua", "ub"};
    for (int i = 1; i < 8; i++)
        if (take(o[i], &b[i], n, 0, names[i]) != 0)
            goto done;
    if (take(o[8], &b[8], -1, 1, "value_sums") != 0 ||
        take(o[9], &b[9], b[8].view.len / 8, 1, "count_sums") != 0)
        goto done;
    if (b[8].view.len / 8 % stride != 0) {
        PyErr_SetString(PyExc_ValueError, "value_sums: not a whole number of grid rows");
        goto done;
    }
    const int64_t *ra = I64(b[0]), *rb = I64(b[1]), *p_lo = I64(b[2]), *counts = I64(b[3]);
    const double *off = F64(b[4]), *slope = F64(b[5]), *ua = F64(b[6]), *ub = F64(b[7]);
    double *value_sums = (double *)b[8].view.buf;
    int64_t *count_sums = (int64_t *)b[9].view.buf;

    int64_t lo_row = INT64_MAX, hi_row = -1, runs = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        if (counts[i] <= 0)
            continue;
        runs += counts[i];
        int64_t first = ra[i] + p_lo[i], last = ra[i] + p_lo[i] + counts[i] - 1;
        if (first < lo_row)
            lo_row = first;
        if (last > hi_row)
            hi_row = last;
    }
    int64_t base = hi_row < 0 ? 0 : lo_row * stride;
    int64_t size = hi_row < 0 ? 0 : (hi_row - lo_row + 1) * stride;
    if (delta_open(&delta, base, size, runs) != 0)
        goto done;
    long long cells = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t count = counts[i];
        if (count <= 0)
            continue;
        int64_t p_hi = p_lo[i] + count - 1;
        for (int64_t p = p_lo[i]; p <= p_hi; p++) {
            double pf = (double)p;
            double u_in = (pf + off[i]) * slope[i] + ua[i];
            double u_out = (pf + 1.0 + off[i]) * slope[i] + ua[i];
            if (p == p_lo[i] && p_lo[i] == 0)
                u_in = ua[i];
            if (p == p_hi && ra[i] + p_hi == rb[i])
                u_out = ub[i];
            int64_t c_in = (int64_t)floor(u_in), c_out = (int64_t)floor(u_out);
            int64_t col0 = c_in < c_out ? c_in : c_out;
            int64_t col1 = c_in < c_out ? c_out : c_in;
            if (clip) {
                if (col1 < 0 || col0 > width - 1)
                    continue;
                if (col0 < 0)
                    col0 = 0;
                if (col1 > width - 1)
                    col1 = width - 1;
            }
            int64_t at = (ra[i] + p) * stride;
            count_sums[at + col0] += 1;
            count_sums[at + col1 + 1] -= 1;
            cells += col1 - col0 + 1;
            delta_run(&delta, at + col0, at + col1 + 1, l_free);
        }
    }
    delta_close(&delta, value_sums);
    result = PyLong_FromLongLong(cells);
done:
    delta_free(&delta);
    release(b, 10);
    return result;
}

static PyMethodDef methods[] = {
    {"sector_batch", sector_batch, METH_VARARGS,
     "One batch of nested sonar sectors into the running difference arrays; returns the "
     "outer sectors' cells."},
    {"spread_batch", spread_batch, METH_VARARGS,
     "One trust class's error-aware sonar readings into the looks, hits and seen difference "
     "arrays; returns the echo rings' cells."},
    {"ray_batch", ray_batch, METH_VARARGS,
     "One chunk of rays' free runs into the running difference arrays; returns the cells."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    .m_base = PyModuleDef_HEAD_INIT,
    .m_name = "_ckernels",
    .m_doc = "gridmap's compiled mapping kernels (see gridmap_cli/models/kernels.py).",
    .m_size = -1,
    .m_methods = methods,
};

PyMODINIT_FUNC PyInit__ckernels(void)
{
    return PyModule_Create(&module);
}
