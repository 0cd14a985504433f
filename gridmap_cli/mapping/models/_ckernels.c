/* gridmap's compiled mapping kernels: the inner loops of the sonar cone and of the ray model
 * over one batch of readings (the error-aware models of fading.py map through them too, with
 * faded evidence).
 *
 * Each kernel repeats its numpy reference (gridmap_cli/mapping/models/sector.py, standard.py,
 * ray.py) operation for operation, in the same order, so that the grids are equal bit for bit:
 * the per-reading trigonometry stays in numpy; here the row and span arithmetic is plain IEEE
 * +, -, *, /, sqrt, floor and ceil (built with -ffp-contract=off: no fused multiply-adds).
 * The sums are integers (grid.py): each run's evidence is rounded once to a fixed-point int64
 * (rint(value * scale), as LogOddsAccumulator.add_values rounds it) and added straight into the
 * running difference arrays, counts into uint32 ones; integer sums are exact in any order and
 * wrap modulo 2**64 / 2**32 like numpy's, so no per-batch scratch is needed. The sums may be a
 * window of rows (row0 ..): rows outside it are skipped.
 *
 * Arrays arrive through the buffer protocol (contiguous float64 / int64 / uint32, checked here),
 * so the module needs no numpy headers to build. gridmap_cli/mapping/models/kernels.py is the Python side.
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

/* Take a contiguous buffer of `n` items of `size` bytes (n < 0: any length); writable when
 * asked. */
static int take_sized(PyObject *obj, Buf *b, Py_ssize_t n, Py_ssize_t size, int writable,
                      const char *name)
{
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, &b->view, flags) != 0)
        return -1;
    b->held = 1;
    if (b->view.itemsize != size || (n >= 0 && b->view.len != n * size)) {
        PyErr_Format(PyExc_ValueError, "%s: expected %zd items of %zd bytes, got %zd bytes",
                     name, n, size, b->view.len);
        return -1;
    }
    return 0;
}

static int take(PyObject *obj, Buf *b, Py_ssize_t n, int writable, const char *name)
{
    return take_sized(obj, b, n, 8, writable, name);
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

/* grid.py VALUE_LIMIT: the largest |evidence| of one update the fixed-point sums take. */
#define VALUE_LIMIT 64.0

/* The fixed-point evidence of a run (LogOddsAccumulator.add_values: np.rint(value * scale));
 * returns 0 and sets ValueError for a value outside +-VALUE_LIMIT or not finite. */
static int fixed(double value, double scale, uint64_t *q)
{
    if (!(fabs(value) <= VALUE_LIMIT)) {
        PyErr_Format(PyExc_ValueError, "log-odds evidence %g outside +-%g", value, VALUE_LIMIT);
        return 0;
    }
    *q = (uint64_t)(int64_t)rint(value * scale);
    return 1;
}

/* One run [start, end) of a difference array: + q at start, - q at end (modulo 2**64). */
static inline void add_run(uint64_t *sums, int64_t start, int64_t end, uint64_t q)
{
    sums[start] += q;
    sums[end] -= q;
}

/* ---- the standard sonar cone (standard.py accumulate_sectors_numpy) ------------------ */

static PyObject *sector_batch(PyObject *self, PyObject *args)
{
    (void)self;
    double ox, oy, res, scale;
    int64_t width, height, row0;
    PyObject *o[14];
    if (!PyArg_ParseTuple(args, "dddLLOOOOOOOOOOOOdLOO", &ox, &oy, &res, &width, &height,
                          &o[0], &o[1], &o[2], &o[3], &o[4], &o[5], &o[6], &o[7], &o[8], &o[9],
                          &o[10], &o[11], &scale, &row0, &o[12], &o[13]))
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
    if (take(o[12], &b[12], -1, 1, "value_sums") != 0)
        goto done;
    Py_ssize_t cells_held = b[12].view.len / 8;
    if (cells_held % stride != 0 || row0 < 0 || row0 + cells_held / stride > height) {
        PyErr_SetString(PyExc_ValueError, "value_sums: not a window of whole grid rows");
        goto done;
    }
    if (take_sized(o[13], &b[13], cells_held, 4, 1, "count_sums") != 0)
        goto done;
    int64_t row1 = row0 + cells_held / stride;
    const double *x = F64(b[0]), *y = F64(b[1]), *sin_r = F64(b[2]), *cos_r = F64(b[3]),
                 *sin_l = F64(b[4]), *cos_l = F64(b[5]), *outer_m = F64(b[8]),
                 *outer_value = F64(b[9]), *inner_m = F64(b[10]), *inner_value = F64(b[11]);
    const int64_t *j0 = I64(b[6]), *counts = I64(b[7]);
    uint64_t *value_sums = (uint64_t *)b[12].view.buf;
    uint32_t *count_sums = (uint32_t *)b[13].view.buf;

    long long cells = 0;
    for (Py_ssize_t i = 0; i < m; i++) {
        if (counts[i] <= 0)
            continue;
        double r_out = outer_m[i], v_out = outer_value[i];
        double r_in = inner_m[i];
        uint64_t q_out, q_in;
        if (!fixed(v_out, scale, &q_out) || !fixed(inner_value[i], scale, &q_in))
            goto done;
        int64_t k0 = row0 - j0[i] > 0 ? row0 - j0[i] : 0;
        int64_t k1 = row1 - j0[i] < counts[i] ? row1 - j0[i] : counts[i];
        for (int64_t k = k0; k < k1; k++) {
            int64_t row = j0[i] + k;
            double dy = oy + ((double)row + 0.5) * res - y[i];
            double lo, hi;
            int64_t c0, c1;
            wedge(sin_r[i], cos_r[i], sin_l[i], cos_l[i], dy, &lo, &hi);
            int64_t at = (row - row0) * stride;
            if (span(lo, hi, dy, r_out, x[i], ox, res, width, &c0, &c1)) {
                count_sums[at + c0] += 1u;
                count_sums[at + c1 + 1] -= 1u;
                cells += c1 - c0 + 1;
                if (q_out != 0)
                    add_run(value_sums, at + c0, at + c1 + 1, q_out);
            }
            if (span(lo, hi, dy, r_in, x[i], ox, res, width, &c0, &c1))
                add_run(value_sums, at + c0, at + c1 + 1, q_in);
        }
    }
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

static PyObject *ray_batch(PyObject *self, PyObject *args)
{
    (void)self;
    int64_t width, row0;
    int clip;
    double l_free, scale;
    PyObject *o[10];
    if (!PyArg_ParseTuple(args, "LOOOOOOOOpddLOO", &width, &o[0], &o[1], &o[2], &o[3], &o[4],
                          &o[5], &o[6], &o[7], &clip, &l_free, &scale, &row0, &o[8], &o[9]))
        return NULL;
    Buf b[10] = {0};
    PyObject *result = NULL;
    int64_t stride = width + 1;
    uint64_t q;
    if (!fixed(l_free, scale, &q))
        return NULL;
    if (take(o[0], &b[0], -1, 0, "ra") != 0)
        goto done;
    Py_ssize_t n = b[0].view.len / 8;
    static const char *names[] = {"ra", "rb", "p_lo", "counts", "off", "slope", "ua", "ub"};
    for (int i = 1; i < 8; i++)
        if (take(o[i], &b[i], n, 0, names[i]) != 0)
            goto done;
    if (take(o[8], &b[8], -1, 1, "value_sums") != 0 ||
        take_sized(o[9], &b[9], b[8].view.len / 8, 4, 1, "count_sums") != 0)
        goto done;
    if (b[8].view.len / 8 % stride != 0 || row0 < 0) {
        PyErr_SetString(PyExc_ValueError, "value_sums: not a whole number of grid rows");
        goto done;
    }
    int64_t row1 = row0 + b[8].view.len / 8 / stride;
    RayRows r = {I64(b[0]), I64(b[1]), I64(b[2]), I64(b[3]),
                 F64(b[4]), F64(b[5]), F64(b[6]), F64(b[7])};
    uint64_t *value_sums = (uint64_t *)b[8].view.buf;
    uint32_t *count_sums = (uint32_t *)b[9].view.buf;
    long long cells = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t p0 = r.p_lo[i], p1 = r.p_lo[i] + r.counts[i];
        if (row0 - r.ra[i] > p0)
            p0 = row0 - r.ra[i];
        if (row1 - r.ra[i] < p1)
            p1 = row1 - r.ra[i];
        for (int64_t p = p0; p < p1; p++) {
            int64_t col0, col1;
            if (!ray_run(&r, i, p, clip, width, &col0, &col1))
                continue;
            int64_t at = (r.ra[i] + p - row0) * stride;
            count_sums[at + col0] += 1u;
            count_sums[at + col1 + 1] -= 1u;
            cells += col1 - col0 + 1;
            add_run(value_sums, at + col0, at + col1 + 1, q);
        }
    }
    result = PyLong_FromLongLong(cells);
done:
    release(b, 10);
    return result;
}

/* Rays' runs with a whole-number value per ray (evaluation/spread_map.py spread_layer): each
 * run adds its ray's value to one int64 difference array and 1 to another, as SpanSums.add
 * does with np.add.at; integer sums, so any order gives the same grid. */
static PyObject *ray_sums(PyObject *self, PyObject *args)
{
    (void)self;
    int64_t width;
    int clip;
    PyObject *o[11];
    if (!PyArg_ParseTuple(args, "LOOOOOOOOpOOO", &width, &o[0], &o[1], &o[2], &o[3], &o[4],
                          &o[5], &o[6], &o[7], &clip, &o[8], &o[9], &o[10]))
        return NULL;
    Buf b[11] = {0};
    PyObject *result = NULL;
    int64_t stride = width + 1;
    if (take(o[0], &b[0], -1, 0, "ra") != 0)
        goto done;
    Py_ssize_t n = b[0].view.len / 8;
    static const char *names[] = {"ra", "rb", "p_lo", "counts", "off", "slope", "ua", "ub",
                                  "value"};
    for (int i = 1; i < 9; i++)
        if (take(o[i], &b[i], n, 0, names[i]) != 0)
            goto done;
    if (take(o[9], &b[9], -1, 1, "value_sums") != 0 ||
        take(o[10], &b[10], b[9].view.len / 8, 1, "count_sums") != 0)
        goto done;
    if (b[9].view.len / 8 % stride != 0) {
        PyErr_SetString(PyExc_ValueError, "value_sums: not a whole number of grid rows");
        goto done;
    }
    int64_t rows = b[9].view.len / 8 / stride;
    RayRows r = {I64(b[0]), I64(b[1]), I64(b[2]), I64(b[3]),
                 F64(b[4]), F64(b[5]), F64(b[6]), F64(b[7])};
    const int64_t *value = I64(b[8]);
    /* unsigned: the sums wrap like numpy's int64 instead of overflowing */
    uint64_t *value_sums = (uint64_t *)b[9].view.buf;
    uint64_t *count_sums = (uint64_t *)b[10].view.buf;
    long long runs = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t p0 = r.p_lo[i], p1 = r.p_lo[i] + r.counts[i];
        if (-r.ra[i] > p0)
            p0 = -r.ra[i];
        if (rows - r.ra[i] < p1)
            p1 = rows - r.ra[i];
        for (int64_t p = p0; p < p1; p++) {
            int64_t col0, col1;
            if (!ray_run(&r, i, p, clip, width, &col0, &col1))
                continue;
            int64_t at = (r.ra[i] + p) * stride;
            value_sums[at + col0] += (uint64_t)value[i];
            value_sums[at + col1 + 1] -= (uint64_t)value[i];
            count_sums[at + col0] += 1u;
            count_sums[at + col1 + 1] -= 1u;
            runs++;
        }
    }
    result = PyLong_FromLongLong(runs);
done:
    release(b, 11);
    return result;
}

/* ---- cones and rays moved by a sampled track (mapping/expected.py) ------------------ */

/* Check the per-key motion arrays (cos, sin: keys items; txy: tx then ty, 2 keys) and the
 * whole grid's sums; returns the key count, or -1 with an exception set. */
static Py_ssize_t take_motion(PyObject **o, Buf *b, Py_ssize_t width, Py_ssize_t height)
{
    if (take(o[0], &b[0], -1, 0, "cos") != 0)
        return -1;
    Py_ssize_t keys = b[0].view.len / 8;
    if (take(o[1], &b[1], keys, 0, "sin") != 0 || take(o[2], &b[2], 2 * keys, 0, "txy") != 0 ||
        take(o[3], &b[3], height * (width + 1), 1, "value_sums") != 0 ||
        take_sized(o[4], &b[4], height * (width + 1), 4, 1, "count_sums") != 0)
        return -1;
    return keys;
}

/* Every sector moved by its key pose's rigid motion (p -> R p + t; its edges' directions
 * turned by the angle-sum formulas), its rows found and mapped as cast_sectors_numpy does. */
static PyObject *moved_sector_batch(PyObject *self, PyObject *args)
{
    (void)self;
    double ox, oy, res, scale;
    int64_t width, height;
    PyObject *o[16];
    if (!PyArg_ParseTuple(args, "dddLLOOOOOOOOOOOOOOdOO", &ox, &oy, &res, &width, &height,
                          &o[0], &o[1], &o[2], &o[3], &o[4], &o[5], &o[6], &o[7], &o[8],
                          &o[9], &o[10], &o[11], &o[12], &o[13], &scale, &o[14], &o[15]))
        return NULL;
    Buf b[16] = {0};
    PyObject *result = NULL;
    int64_t stride = width + 1;
    if (take(o[0], &b[0], -1, 0, "x") != 0)
        goto done;
    Py_ssize_t m = b[0].view.len / 8;
    static const char *names[] = {"x",       "y",           "sin_r",   "cos_r",
                                  "sin_l",   "cos_l",       "outer_m", "outer_value",
                                  "inner_m", "inner_value", "owner"};
    for (int i = 1; i < 11; i++)
        if (take(o[i], &b[i], m, 0, names[i]) != 0)
            goto done;
    PyObject *mo[5] = {o[11], o[12], o[13], o[14], o[15]};
    Py_ssize_t keys = take_motion(mo, &b[11], width, height);
    if (keys < 0)
        goto done;
    const double *x = F64(b[0]), *y = F64(b[1]), *sin_r = F64(b[2]), *cos_r = F64(b[3]),
                 *sin_l = F64(b[4]), *cos_l = F64(b[5]), *outer_m = F64(b[6]),
                 *outer_value = F64(b[7]), *inner_m = F64(b[8]), *inner_value = F64(b[9]);
    const int64_t *owner = I64(b[10]);
    const double *kc = F64(b[11]), *ks = F64(b[12]), *txy = F64(b[13]);
    uint64_t *value_sums = (uint64_t *)b[14].view.buf;
    uint32_t *count_sums = (uint32_t *)b[15].view.buf;
    long long cells = 0;
    for (Py_ssize_t i = 0; i < m; i++) {
        int64_t k = owner[i];
        if (k < 0 || k >= keys) {
            PyErr_SetString(PyExc_ValueError, "owner: index out of range");
            goto done;
        }
        uint64_t q_out, q_in;
        if (!fixed(outer_value[i], scale, &q_out) || !fixed(inner_value[i], scale, &q_in))
            goto done;
        double c = kc[k], s = ks[k];
        double mx = c * x[i] - s * y[i] + txy[k];
        double my = s * x[i] + c * y[i] + txy[keys + k];
        double sr = sin_r[i] * c + cos_r[i] * s, cr = cos_r[i] * c - sin_r[i] * s;
        double sl = sin_l[i] * c + cos_l[i] * s, cl = cos_l[i] * c - sin_l[i] * s;
        double reach = outer_m[i];
        double y_r = my + reach * sr, y_l = my + reach * sl;
        double ymin = my, ymax = my;
        ymin = y_r < ymin ? y_r : ymin;
        ymin = y_l < ymin ? y_l : ymin;
        ymax = y_r > ymax ? y_r : ymax;
        ymax = y_l > ymax ? y_l : ymax;
        if (cr >= 0.0 && cl <= 0.0) /* the wedge holds +y: the arc bulges up */
            ymax = my + reach;
        if (cr <= 0.0 && cl >= 0.0)
            ymin = my - reach;
        double lo = ceil((ymin - oy) / res - 0.5), hi = floor((ymax - oy) / res - 0.5);
        lo = lo < 0.0 ? 0.0 : (lo > (double)height ? (double)height : lo);
        hi = hi < -1.0 ? -1.0 : (hi > (double)(height - 1) ? (double)(height - 1) : hi);
        int64_t j0 = (int64_t)lo, j1 = (int64_t)hi;
        if (!(reach > 0.0))
            continue;
        for (int64_t row = j0; row <= j1; row++) {
            double dy = oy + ((double)row + 0.5) * res - my;
            double wlo, whi;
            int64_t c0, c1;
            wedge(sr, cr, sl, cl, dy, &wlo, &whi);
            int64_t at = row * stride;
            if (span(wlo, whi, dy, reach, mx, ox, res, width, &c0, &c1)) {
                count_sums[at + c0] += 1u;
                count_sums[at + c1 + 1] -= 1u;
                cells += c1 - c0 + 1;
                if (q_out != 0)
                    add_run(value_sums, at + c0, at + c1 + 1, q_out);
            }
            if (span(wlo, whi, dy, inner_m[i], mx, ox, res, width, &c0, &c1))
                add_run(value_sums, at + c0, at + c1 + 1, q_in);
        }
    }
    result = PyLong_FromLongLong(cells);
done:
    release(b, 16);
    return result;
}

/* Every segment moved by its key pose's rigid motion, walked as ray.py's ray_rows and
 * row_runs walk it: l_free in every cell crossed, l_end in the end cell of an echo (in the
 * grid), as cast_rays_numpy adds them. */
static PyObject *moved_ray_batch(PyObject *self, PyObject *args)
{
    (void)self;
    double ox, oy, res, l_free, l_end, scale;
    int64_t width, height;
    PyObject *o[11];
    if (!PyArg_ParseTuple(args, "dddLLOOOOOOOOOdddOO", &ox, &oy, &res, &width, &height, &o[0],
                          &o[1], &o[2], &o[3], &o[4], &o[5], &o[6], &o[7], &o[8], &l_free,
                          &l_end, &scale, &o[9], &o[10]))
        return NULL;
    Buf b[11] = {0};
    PyObject *result = NULL;
    int64_t stride = width + 1;
    uint64_t q_free, q_end;
    if (!fixed(l_free, scale, &q_free) || !fixed(l_end - l_free, scale, &q_end))
        return NULL;
    if (take(o[0], &b[0], -1, 0, "x0") != 0)
        goto done;
    Py_ssize_t n = b[0].view.len / 8;
    static const char *names[] = {"x0", "y0", "x1", "y1", "echo", "owner"};
    for (int i = 1; i < 6; i++)
        if (take(o[i], &b[i], n, 0, names[i]) != 0)
            goto done;
    PyObject *mo[5] = {o[6], o[7], o[8], o[9], o[10]};
    Py_ssize_t keys = take_motion(mo, &b[6], width, height);
    if (keys < 0)
        goto done;
    const double *x0 = F64(b[0]), *y0 = F64(b[1]), *x1 = F64(b[2]), *y1 = F64(b[3]);
    const int64_t *echo = I64(b[4]), *owner = I64(b[5]);
    const double *cs = F64(b[6]), *sn = F64(b[7]), *txy = F64(b[8]);
    uint64_t *value_sums = (uint64_t *)b[9].view.buf;
    uint32_t *count_sums = (uint32_t *)b[10].view.buf;
    long long cells = 0;
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
        int64_t ra = (int64_t)ra_f, rb = (int64_t)floor(b_v);
        int64_t p_lo = -ra > 0 ? -ra : 0;
        int64_t top = rb < height - 1 ? rb : height - 1;
        int64_t count = top - ra - p_lo + 1;
        int active = echo[i] != 0 || u0 != u1 || v0 != v1;
        if (!active || count < 0)
            count = 0;
        double dv = b_v - a_v;
        double slope = dv > 0.0 ? (b_u - a_u) / dv : 0.0, off = ra_f - a_v;
        RayRows r = {&ra, &rb, &p_lo, &count, &off, &slope, &a_u, &b_u};
        for (int64_t p = p_lo; p < p_lo + count; p++) {
            int64_t col0, col1;
            if (!ray_run(&r, 0, p, 1, width, &col0, &col1))
                continue;
            int64_t at = (ra + p) * stride;
            count_sums[at + col0] += 1u;
            count_sums[at + col1 + 1] -= 1u;
            cells += col1 - col0 + 1;
            add_run(value_sums, at + col0, at + col1 + 1, q_free);
        }
        if (echo[i]) {
            int64_t col = (int64_t)floor(u1), row = (int64_t)floor(v1);
            if (col >= 0 && col < width && row >= 0 && row < height)
                add_run(value_sums, row * stride + col, row * stride + col + 1, q_end);
        }
    }
    result = PyLong_FromLongLong(cells);
done:
    release(b, 11);
    return result;
}

static PyMethodDef methods[] = {
    {"sector_batch", sector_batch, METH_VARARGS,
     "One batch of nested sonar sectors into the running difference arrays; returns the "
     "outer sectors' cells."},
    {"ray_batch", ray_batch, METH_VARARGS,
     "One chunk of rays' free runs into the running difference arrays; returns the cells."},
    {"ray_sums", ray_sums, METH_VARARGS,
     "One chunk of rays' runs, each adding its ray's int64 value and a count of 1 to two "
     "running int64 difference arrays; returns the runs."},
    {"moved_sector_batch", moved_sector_batch, METH_VARARGS,
     "One batch of sonar sectors moved by a sampled track's key-pose motions into the running "
     "difference arrays; returns the outer sectors' cells."},
    {"moved_ray_batch", moved_ray_batch, METH_VARARGS,
     "One batch of rays moved by a sampled track's key-pose motions, free runs and end cells, "
     "into the running difference arrays; returns the free runs' cells."},
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
