/* gridmap's compiled mapping kernels: the inner loops of the sonar cone and of the ray model
 * over one batch of readings (the error-aware models of fading.py map through them too, with
 * faded evidence).
 *
 * Each kernel repeats its numpy reference (gridmap_cli/mapping/models/sector.py, standard.py,
 * ray.py) operation for operation, in the same order, so that the grids are equal bit for bit:
 * the per-reading trigonometry stays in numpy; here the row and span arithmetic is plain IEEE
 * +, -, *, /, sqrt, floor and ceil (built with -ffp-contract=off: no fused multiply-adds), and
 * float evidence goes into a per-batch difference array in the order np.bincount adds it
 * (every run's start, then every run's end), which is then added to the running sums as
 * SpanSums.add does. Integer counts are exact in any order.
 *
 * Arrays arrive through the buffer protocol (contiguous float64 / int64, checked here), so the
 * module needs no numpy headers to build. gridmap_cli/mapping/models/kernels.py is the Python side.
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
 * run ends held back until every start is in (np.bincount's order). The reference then adds
 * the whole delta to the sums. Where a batch has few runs for the range it spans, only the
 * indices they touched are added (the others would add +0.0), so a small batch on a large
 * grid costs its runs, not the grid.
 *
 * The buffers are kept between calls (two slots: a kernel holds at most two deltas), the
 * delta zeroed again after use: allocating a grid-sized delta per batch cost a page fault per
 * 4 KiB each time (3 of 9 s of system time on a large laser map). Calls hold the GIL. */
typedef struct {
    double *delta;
    int64_t *start_at, *end_at;
    double *end_value;
    size_t delta_cap, runs_cap, starts_cap;
} Scratch;

static Scratch scratch[2];

typedef struct {
    double *delta;
    int64_t base, size;
    int64_t *start_at, *end_at;
    double *end_value;
    int64_t runs;
    int sparse; /* few runs for the range: starts are kept, and only touched entries move */
} Delta;

static int delta_open(Delta *d, int slot, int64_t base, int64_t size, int64_t max_runs)
{
    Scratch *s = &scratch[slot];
    memset(d, 0, sizeof *d);
    d->base = base;
    d->size = size > 0 ? size : 0;
    size_t runs = (size_t)(max_runs > 0 ? max_runs : 0) + 1;
    d->sparse = (int64_t)runs < d->size / 32;
    if ((size_t)d->size + 1 > s->delta_cap) {
        free(s->delta);
        s->delta_cap = (size_t)d->size + 1;
        s->delta = calloc(s->delta_cap, sizeof(double)); /* zero; kept zero after each use */
    }
    if (runs > s->runs_cap) {
        free(s->end_at);
        free(s->end_value);
        s->runs_cap = runs;
        s->end_at = malloc(runs * sizeof(int64_t));
        s->end_value = malloc(runs * sizeof(double));
    }
    if (d->sparse && runs > s->starts_cap) {
        free(s->start_at);
        s->starts_cap = runs;
        s->start_at = malloc(runs * sizeof(int64_t));
    }
    if (!s->delta || (d->sparse && !s->start_at) || !s->end_at || !s->end_value) {
        free(s->delta);
        free(s->start_at);
        free(s->end_at);
        free(s->end_value);
        memset(s, 0, sizeof *s);
        PyErr_NoMemory();
        return -1;
    }
    d->delta = s->delta;
    d->start_at = s->start_at;
    d->end_at = s->end_at;
    d->end_value = s->end_value;
    return 0;
}

static inline void delta_run(Delta *d, int64_t start, int64_t end, double value)
{
    d->delta[start - d->base] += value;
    if (d->sparse)
        d->start_at[d->runs] = start;
    d->end_at[d->runs] = end;
    d->end_value[d->runs] = -value;
    d->runs++;
}

/* Move one touched entry of the delta into the sums (an index touched twice moves once). */
static inline void delta_move(Delta *d, int64_t at, double *sums)
{
    double *v = &d->delta[at - d->base];
    if (*v != 0.0)
        sums[at] += *v;
    *v = 0.0;
}

/* The held-back ends, then the delta into the running sums, leaving the delta zero. */
static void delta_close(Delta *d, double *sums)
{
    for (int64_t k = 0; k < d->runs; k++)
        d->delta[d->end_at[k] - d->base] += d->end_value[k];
    if (d->sparse) {
        for (int64_t k = 0; k < d->runs; k++) {
            delta_move(d, d->start_at[k], sums);
            delta_move(d, d->end_at[k], sums);
        }
        return;
    }
    for (int64_t k = 0; k < d->size; k++) {
        sums[d->base + k] += d->delta[k];
        d->delta[k] = 0.0;
    }
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

/* The rows of every sector into the difference arrays (sector_batch's loop; the moved
 * sectors' too). Returns the outer sectors' cells, or -1 with an exception set. */
static long long sector_core(double ox, double oy, double res, int64_t width, Py_ssize_t m,
                             const double *x, const double *y, const double *sin_r,
                             const double *cos_r, const double *sin_l, const double *cos_l,
                             const int64_t *j0, const int64_t *counts, const double *outer_m,
                             const double *outer_value, const double *inner_m,
                             const double *inner_value, double *value_sums,
                             int64_t *count_sums)
{
    int64_t stride = width + 1;
    Delta outer = {0}, inner = {0};
    int64_t base, size, rows;
    row_range(j0, counts, m, stride, &base, &size, &rows);
    if (delta_open(&outer, 0, base, size, rows) != 0 ||
        delta_open(&inner, 1, base, size, rows) != 0)
        return -1;
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
    return cells;
}


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

    long long cells = sector_core(ox, oy, res, width, m, x, y, sin_r, cos_r, sin_l, cos_l, j0,
                                  counts, outer_m, outer_value, inner_m, inner_value,
                                  value_sums, count_sums);
    if (cells < 0)
        goto done;
    result = PyLong_FromLongLong(cells);
done:
    release(b, 14);
    return result;
}

/* ---- the ray model's free runs (ray.py row_runs) ------------------------------------- */

/* What ray.py's RayRows holds, per segment. */
typedef struct {
    const int64_t *ra, *rb, *p_lo, *counts;
    const double *off, *slope, *ua, *ub;
} RayRows;

/* The run of segment i in its row ra + p (row_runs); returns 0 when clipping drops it. */
static inline int ray_run(const RayRows *r, Py_ssize_t i, int64_t p, int clip, int64_t width,
                          int64_t *col0, int64_t *col1)
{
    int64_t p_hi = r->p_lo[i] + r->counts[i] - 1;
    double pf = (double)p;
    double u_in = (pf + r->off[i]) * r->slope[i] + r->ua[i];
    double u_out = (pf + 1.0 + r->off[i]) * r->slope[i] + r->ua[i];
    if (p == r->p_lo[i] && r->p_lo[i] == 0)
        u_in = r->ua[i];
    if (p == p_hi && r->ra[i] + p_hi == r->rb[i])
        u_out = r->ub[i];
    int64_t c_in = (int64_t)floor(u_in), c_out = (int64_t)floor(u_out);
    *col0 = c_in < c_out ? c_in : c_out;
    *col1 = c_in < c_out ? c_out : c_in;
    if (clip) {
        if (*col1 < 0 || *col0 > width - 1)
            return 0;
        if (*col0 < 0)
            *col0 = 0;
        if (*col1 > width - 1)
            *col1 = width - 1;
    }
    return 1;
}

/* The index range of the difference array the segments' rows touch, and their run count. */
static void ray_range(const RayRows *r, Py_ssize_t n, int64_t stride, int64_t *base,
                      int64_t *size, int64_t *runs)
{
    int64_t lo_row = INT64_MAX, hi_row = -1, total = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        if (r->counts[i] <= 0)
            continue;
        total += r->counts[i];
        int64_t first = r->ra[i] + r->p_lo[i], last = first + r->counts[i] - 1;
        if (first < lo_row)
            lo_row = first;
        if (last > hi_row)
            hi_row = last;
    }
    *base = hi_row < 0 ? 0 : lo_row * stride;
    *size = hi_row < 0 ? 0 : (hi_row - lo_row + 1) * stride;
    *runs = total;
}

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
    RayRows r = {I64(b[0]), I64(b[1]), I64(b[2]), I64(b[3]),
                 F64(b[4]), F64(b[5]), F64(b[6]), F64(b[7])};
    double *value_sums = (double *)b[8].view.buf;
    int64_t *count_sums = (int64_t *)b[9].view.buf;
    int64_t base, size, runs;
    ray_range(&r, n, stride, &base, &size, &runs);
    if (delta_open(&delta, 0, base, size, runs) != 0)
        goto done;
    long long cells = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        for (int64_t p = r.p_lo[i]; p < r.p_lo[i] + r.counts[i]; p++) {
            int64_t col0, col1;
            if (!ray_run(&r, i, p, clip, width, &col0, &col1))
                continue;
            int64_t at = (r.ra[i] + p) * stride;
            count_sums[at + col0] += 1;
            count_sums[at + col1 + 1] -= 1;
            cells += col1 - col0 + 1;
            delta_run(&delta, at + col0, at + col1 + 1, l_free);
        }
    }
    delta_close(&delta, value_sums);
    result = PyLong_FromLongLong(cells);
done:
    release(b, 10);
    return result;
}

/* ---- sonar cones moved by a sampled track (mapping/expected.py cast_sectors_numpy) ---- */

/* Every sector moved by its key pose's rigid motion (p -> R p + t; its edges' directions
 * turned by the angle-sum formulas), its rows found as cast_sectors_numpy finds them, then
 * mapped as sector_batch maps them. */
static PyObject *moved_sector_batch(PyObject *self, PyObject *args)
{
    (void)self;
    double ox, oy, res;
    int64_t width, height;
    PyObject *o[16];
    if (!PyArg_ParseTuple(args, "dddLLOOOOOOOOOOOOOOOO", &ox, &oy, &res, &width, &height,
                          &o[0], &o[1], &o[2], &o[3], &o[4], &o[5], &o[6], &o[7], &o[8],
                          &o[9], &o[10], &o[11], &o[12], &o[13], &o[14], &o[15]))
        return NULL;
    Buf b[16] = {0};
    PyObject *result = NULL;
    int64_t stride = width + 1;
    double *mx = NULL, *my = NULL, *sr = NULL, *cr = NULL, *sl = NULL, *cl = NULL;
    int64_t *j0 = NULL, *counts = NULL;
    if (take(o[0], &b[0], -1, 0, "x") != 0)
        goto done;
    Py_ssize_t m = b[0].view.len / 8;
    static const char *names[] = {"x",       "y",           "sin_r",   "cos_r",
                                  "sin_l",   "cos_l",       "outer_m", "outer_value",
                                  "inner_m", "inner_value", "owner"};
    for (int i = 1; i < 11; i++)
        if (take(o[i], &b[i], m, 0, names[i]) != 0)
            goto done;
    if (take(o[11], &b[11], -1, 0, "cos") != 0)
        goto done;
    Py_ssize_t keys = b[11].view.len / 8;
    if (take(o[12], &b[12], keys, 0, "sin") != 0 ||
        take(o[13], &b[13], 2 * keys, 0, "txy") != 0 ||
        take(o[14], &b[14], height * stride, 1, "value_sums") != 0 ||
        take(o[15], &b[15], height * stride, 1, "count_sums") != 0)
        goto done;
    const double *x = F64(b[0]), *y = F64(b[1]), *sin_r = F64(b[2]), *cos_r = F64(b[3]),
                 *sin_l = F64(b[4]), *cos_l = F64(b[5]), *outer_m = F64(b[6]);
    const int64_t *owner = I64(b[10]);
    const double *kc = F64(b[11]), *ks = F64(b[12]), *txy = F64(b[13]);
    size_t sz = (size_t)(m > 0 ? m : 1);
    mx = malloc(sz * 8), my = malloc(sz * 8), sr = malloc(sz * 8), cr = malloc(sz * 8);
    sl = malloc(sz * 8), cl = malloc(sz * 8), j0 = malloc(sz * 8), counts = malloc(sz * 8);
    if (!mx || !my || !sr || !cr || !sl || !cl || !j0 || !counts) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t i = 0; i < m; i++) {
        int64_t k = owner[i];
        if (k < 0 || k >= keys) {
            PyErr_SetString(PyExc_ValueError, "owner: index out of range");
            goto done;
        }
        double c = kc[k], s = ks[k];
        mx[i] = c * x[i] - s * y[i] + txy[k];
        my[i] = s * x[i] + c * y[i] + txy[keys + k];
        sr[i] = sin_r[i] * c + cos_r[i] * s;
        cr[i] = cos_r[i] * c - sin_r[i] * s;
        sl[i] = sin_l[i] * c + cos_l[i] * s;
        cl[i] = cos_l[i] * c - sin_l[i] * s;
        double reach = outer_m[i];
        double y_r = my[i] + reach * sr[i], y_l = my[i] + reach * sl[i];
        double ymin = my[i], ymax = my[i];
        ymin = y_r < ymin ? y_r : ymin;
        ymin = y_l < ymin ? y_l : ymin;
        ymax = y_r > ymax ? y_r : ymax;
        ymax = y_l > ymax ? y_l : ymax;
        if (cr[i] >= 0.0 && cl[i] <= 0.0) /* the wedge holds +y: the arc bulges up */
            ymax = my[i] + reach;
        if (cr[i] <= 0.0 && cl[i] >= 0.0)
            ymin = my[i] - reach;
        double lo = ceil((ymin - oy) / res - 0.5), hi = floor((ymax - oy) / res - 0.5);
        lo = lo < 0.0 ? 0.0 : (lo > (double)height ? (double)height : lo);
        hi = hi < -1.0 ? -1.0 : (hi > (double)(height - 1) ? (double)(height - 1) : hi);
        j0[i] = (int64_t)lo;
        int64_t n = (int64_t)hi - j0[i] + 1;
        counts[i] = reach > 0.0 && n > 0 ? n : 0;
    }
    long long cells = sector_core(ox, oy, res, width, m, mx, my, sr, cr, sl, cl, j0, counts,
                                  outer_m, F64(b[7]), F64(b[8]), F64(b[9]),
                                  (double *)b[14].view.buf, (int64_t *)b[15].view.buf);
    if (cells >= 0)
        result = PyLong_FromLongLong(cells);
done:
    free(mx), free(my), free(sr), free(cr), free(sl), free(cl), free(j0), free(counts);
    release(b, 16);
    return result;
}

/* ---- rays moved by a sampled track (mapping/expected.py cast_rays_numpy) -------------- */

/* Every segment moved by its key pose's rigid motion (p -> R p + t: cos, sin, tx, ty per key,
 * indexed by owner), walked as ray.py's ray_rows and row_runs walk it, its free runs into
 * the difference arrays with l_free and its end cell (echo, in the grid) with l_end - l_free,
 * in the order the numpy reference adds them: the free runs' delta, then the end cells'. */
static PyObject *moved_ray_batch(PyObject *self, PyObject *args)
{
    (void)self;
    double ox, oy, res, l_free, l_end;
    int64_t width, height;
    PyObject *o[11];
    if (!PyArg_ParseTuple(args, "dddLLOOOOOOOOOddOO", &ox, &oy, &res, &width, &height, &o[0],
                          &o[1], &o[2], &o[3], &o[4], &o[5], &o[6], &o[7], &o[8], &l_free,
                          &l_end, &o[9], &o[10]))
        return NULL;
    Buf b[11] = {0};
    PyObject *result = NULL;
    Delta free_runs = {0}, ends = {0};
    int64_t stride = width + 1;
    int64_t *ra = NULL, *rb = NULL, *p_lo = NULL, *cnt = NULL;
    double *off = NULL, *slope = NULL, *ua = NULL, *ub = NULL;
    int64_t *end_at = NULL;
    if (take(o[0], &b[0], -1, 0, "x0") != 0)
        goto done;
    Py_ssize_t n = b[0].view.len / 8;
    static const char *names[] = {"x0", "y0", "x1", "y1", "echo", "owner"};
    for (int i = 1; i < 6; i++)
        if (take(o[i], &b[i], n, 0, names[i]) != 0)
            goto done;
    if (take(o[6], &b[6], -1, 0, "cos") != 0)
        goto done;
    Py_ssize_t keys = b[6].view.len / 8;
    /* o[8] holds the key poses' tx, then their ty */
    if (take(o[7], &b[7], keys, 0, "sin") != 0 || take(o[8], &b[8], 2 * keys, 0, "txy") != 0 ||
        take(o[9], &b[9], height * stride, 1, "value_sums") != 0 ||
        take(o[10], &b[10], height * stride, 1, "count_sums") != 0)
        goto done;
    const double *x0 = F64(b[0]), *y0 = F64(b[1]), *x1 = F64(b[2]), *y1 = F64(b[3]);
    const int64_t *echo = I64(b[4]), *owner = I64(b[5]);
    const double *cs = F64(b[6]), *sn = F64(b[7]), *txy = F64(b[8]);
    double *value_sums = (double *)b[9].view.buf;
    int64_t *count_sums = (int64_t *)b[10].view.buf;
    size_t sz = (size_t)(n > 0 ? n : 1);
    ra = malloc(sz * 8), rb = malloc(sz * 8), p_lo = malloc(sz * 8), cnt = malloc(sz * 8);
    off = malloc(sz * 8), slope = malloc(sz * 8), ua = malloc(sz * 8), ub = malloc(sz * 8);
    end_at = malloc(sz * 8);
    if (!ra || !rb || !p_lo || !cnt || !off || !slope || !ua || !ub || !end_at) {
        PyErr_NoMemory();
        goto done;
    }
    int64_t n_end = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t k = owner[i];
        if (k < 0 || k >= keys) {
            PyErr_SetString(PyExc_ValueError, "owner: index out of range");
            goto done;
        }
        double c = cs[k], s = sn[k], tx = txy[k], ty = txy[keys + k];
        double ax = c * x0[i] - s * y0[i] + tx, ay = s * x0[i] + c * y0[i] + ty;
        double bx = c * x1[i] - s * y1[i] + tx, by = s * x1[i] + c * y1[i] + ty;
        double u0 = (ax - ox) / res, v0 = (ay - oy) / res;
        double u1 = (bx - ox) / res, v1 = (by - oy) / res;
        int down = v1 < v0;
        double a_u = down ? u1 : u0, a_v = down ? v1 : v0;
        double b_u = down ? u0 : u1, b_v = down ? v0 : v1;
        double ra_f = floor(a_v);
        ra[i] = (int64_t)ra_f;
        rb[i] = (int64_t)floor(b_v);
        p_lo[i] = -ra[i] > 0 ? -ra[i] : 0;
        int64_t top = rb[i] < height - 1 ? rb[i] : height - 1;
        int64_t p_hi = top - ra[i];
        int active = echo[i] != 0 || u0 != u1 || v0 != v1;
        int64_t count = p_hi - p_lo[i] + 1;
        cnt[i] = active && count > 0 ? count : 0;
        double dv = b_v - a_v;
        slope[i] = dv > 0.0 ? (b_u - a_u) / dv : 0.0;
        off[i] = ra_f - a_v;
        ua[i] = a_u;
        ub[i] = b_u;
        if (echo[i]) {
            int64_t col = (int64_t)floor(u1), row = (int64_t)floor(v1);
            if (col >= 0 && col < width && row >= 0 && row < height)
                end_at[n_end++] = row * stride + col;
        }
    }
    RayRows r = {ra, rb, p_lo, cnt, off, slope, ua, ub};
    int64_t base, size, runs;
    ray_range(&r, n, stride, &base, &size, &runs);
    if (delta_open(&free_runs, 0, base, size, runs) != 0)
        goto done;
    long long cells = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        for (int64_t p = r.p_lo[i]; p < r.p_lo[i] + r.counts[i]; p++) {
            int64_t col0, col1;
            if (!ray_run(&r, i, p, 1, width, &col0, &col1))
                continue;
            int64_t at = (r.ra[i] + p) * stride;
            count_sums[at + col0] += 1;
            count_sums[at + col1 + 1] -= 1;
            cells += col1 - col0 + 1;
            delta_run(&free_runs, at + col0, at + col1 + 1, l_free);
        }
    }
    delta_close(&free_runs, value_sums);
    if (n_end > 0) {
        int64_t lo = end_at[0], hi = end_at[0];
        for (int64_t k = 1; k < n_end; k++) {
            lo = end_at[k] < lo ? end_at[k] : lo;
            hi = end_at[k] > hi ? end_at[k] : hi;
        }
        if (delta_open(&ends, 1, lo, hi - lo + 2, n_end) != 0)
            goto done;
        double v = l_end - l_free;
        for (int64_t k = 0; k < n_end; k++)
            delta_run(&ends, end_at[k], end_at[k] + 1, v);
        delta_close(&ends, value_sums);
    }
    result = PyLong_FromLongLong(cells);
done:
    free(ra), free(rb), free(p_lo), free(cnt), free(off), free(slope), free(ua), free(ub);
    free(end_at);
    release(b, 11);
    return result;
}

static PyMethodDef methods[] = {
    {"sector_batch", sector_batch, METH_VARARGS,
     "One batch of nested sonar sectors into the running difference arrays; returns the "
     "outer sectors' cells."},
    {"ray_batch", ray_batch, METH_VARARGS,
     "One chunk of rays' free runs into the running difference arrays; returns the cells."},
    {"moved_sector_batch", moved_sector_batch, METH_VARARGS,
     "One batch of sonar sectors moved by a sampled track's key-pose motions into the running "
     "difference arrays; returns the outer sectors' cells."},
    {"moved_ray_batch", moved_ray_batch, METH_VARARGS,
     "One batch of rays moved by a sampled track's key-pose motions, free runs and end "
     "cells into the running difference arrays; returns the free runs' cells."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    .m_base = PyModuleDef_HEAD_INIT,
    .m_name = "_ckernels",
    .m_doc = "gridmap's compiled mapping kernels (see gridmap_cli/mapping/models/kernels.py).",
    .m_size = -1,
    .m_methods = methods,
};

PyMODINIT_FUNC PyInit__ckernels(void)
{
    return PyModule_Create(&module);
}
