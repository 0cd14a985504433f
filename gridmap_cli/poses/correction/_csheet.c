/* GICP of planar laser scans as small_gicp registers them lifted to a thin sheet, without the
 * lift (gridmap_cli/poses/correction/sheet_gicp.py): each planar point stands for its copies at
 * three heights one layer apart, each copy with small_gicp's regularised covariance of its k
 * nearest copies, and Levenberg-Marquardt runs on SE(2) with small_gicp's GICP cost and steps.
 * A copy's nearest copies are copies of the point's nearest planar points, and a source copy's
 * nearest target copy is the planar nearest point on the nearest layer, so one planar kd-tree
 * query stands for three in 3-D. The tests hold it to small_gicp on the sheet itself.
 *
 * The kd-tree is implicit: the points are reordered so that the node of a range [lo, hi) is its
 * middle item, mid = lo + (hi - lo) / 2, split along dims[mid]; items before it are not greater
 * along that axis, items after it not smaller. Building returns the order and the split axes;
 * the caller keeps the reordered points and hands both arrays back to every query.
 *
 * Arrays arrive through the buffer protocol (contiguous float64 / int64 / uint8, checked here),
 * so the module needs no numpy headers. Built with -ffp-contract=off: no fused multiply-adds.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

/* most neighbours a covariance may take */
#define MAX_K 64
/* the normal's share of a regularised covariance: a plane in GICP's sense */
#define FLAT 1e-3

typedef struct {
    const double *p;      /* (n, 2) points in tree order */
    const uint8_t *dim;   /* (n,) split axis of each node */
    Py_ssize_t n;
} Tree;

/* ---- building ---------------------------------------------------------------------------- */

static void select_nth(int64_t *idx, const double *pts, int d, Py_ssize_t lo, Py_ssize_t hi,
                       Py_ssize_t k)
{
    /* Hoare's partition around the middle item's value until the k-th item is in place */
    while (hi - lo > 1) {
        double pivot = pts[2 * idx[lo + (hi - lo) / 2] + d];
        Py_ssize_t i = lo, j = hi - 1;
        while (i <= j) {
            while (pts[2 * idx[i] + d] < pivot)
                i++;
            while (pts[2 * idx[j] + d] > pivot)
                j--;
            if (i <= j) {
                int64_t t = idx[i];
                idx[i] = idx[j];
                idx[j] = t;
                i++;
                j--;
            }
        }
        if (k <= j)
            hi = j + 1;
        else if (k >= i)
            lo = i;
        else
            return;
    }
}

static void build(int64_t *idx, uint8_t *dims, const double *pts, Py_ssize_t lo, Py_ssize_t hi)
{
    while (hi - lo > 0) {
        Py_ssize_t mid = lo + (hi - lo) / 2;
        double minx = INFINITY, maxx = -INFINITY, miny = INFINITY, maxy = -INFINITY;
        for (Py_ssize_t i = lo; i < hi; i++) {
            const double *q = pts + 2 * idx[i];
            minx = q[0] < minx ? q[0] : minx;
            maxx = q[0] > maxx ? q[0] : maxx;
            miny = q[1] < miny ? q[1] : miny;
            maxy = q[1] > maxy ? q[1] : maxy;
        }
        int d = (maxy - miny) > (maxx - minx) ? 1 : 0;
        select_nth(idx, pts, d, lo, hi, mid);
        dims[mid] = (uint8_t)d;
        build(idx, dims, pts, lo, mid);
        lo = mid + 1;
    }
}

/* ---- queries ----------------------------------------------------------------------------- */

/* the nearest item to (qx, qy) within sqrt(*best) (inclusive): *best and *arg updated */
static void nearest(const Tree *t, Py_ssize_t lo, Py_ssize_t hi, double qx, double qy,
                    double *best, Py_ssize_t *arg)
{
    while (hi > lo) {
        Py_ssize_t mid = lo + (hi - lo) / 2;
        const double *p = t->p + 2 * mid;
        double dx = qx - p[0], dy = qy - p[1];
        double d2 = dx * dx + dy * dy;
        if (d2 < *best || (*arg < 0 && d2 <= *best)) {
            *best = d2;
            *arg = mid;
        }
        double diff = t->dim[mid] ? dy : dx;
        if (diff < 0) {
            nearest(t, lo, mid, qx, qy, best, arg);
            if (diff * diff > *best)
                return;
            lo = mid + 1;
        } else {
            nearest(t, mid + 1, hi, qx, qy, best, arg);
            if (diff * diff > *best)
                return;
            hi = mid;
        }
    }
}

typedef struct {
    int k, found;
    double d2[MAX_K];
    Py_ssize_t arg[MAX_K];
} Knn;

static void knn_offer(Knn *h, double d2, Py_ssize_t arg)
{
    if (h->found == h->k && d2 >= h->d2[h->k - 1])
        return;
    int i = h->found < h->k ? h->found++ : h->k - 1;
    /* ties keep the earlier item first: insertion after equal distances */
    while (i > 0 && h->d2[i - 1] > d2) {
        h->d2[i] = h->d2[i - 1];
        h->arg[i] = h->arg[i - 1];
        i--;
    }
    h->d2[i] = d2;
    h->arg[i] = arg;
}

static void knn(const Tree *t, Py_ssize_t lo, Py_ssize_t hi, double qx, double qy, Knn *h)
{
    while (hi > lo) {
        Py_ssize_t mid = lo + (hi - lo) / 2;
        const double *p = t->p + 2 * mid;
        double dx = qx - p[0], dy = qy - p[1];
        knn_offer(h, dx * dx + dy * dy, mid);
        double diff = t->dim[mid] ? dy : dx;
        if (diff < 0) {
            knn(t, lo, mid, qx, qy, h);
            if (h->found == h->k && diff * diff > h->d2[h->k - 1])
                return;
            lo = mid + 1;
        } else {
            knn(t, mid + 1, hi, qx, qy, h);
            if (h->found == h->k && diff * diff > h->d2[h->k - 1])
                return;
            hi = mid;
        }
    }
}

/* ---- the sheet: the planar points as small_gicp sees a scan lifted to three layers -------- */

/* small_gicp registers a planar scan as a thin sheet, each point at three heights one layer
 * apart, each copy with the regularised covariance of its k nearest copies in 3-D. Those
 * neighbours are copies of the point's k nearest planar points (a copy of a farther point is
 * farther on every layer), so one planar query per point gives all three layers. */
#define LAYERS 3
/* six entries of a symmetric 3x3: xx xy xz yy yz zz */
#define SYM 6

/* the unit eigenvector of the least eigenvalue of the symmetric a (3x3, row-major), by
 * cyclic Jacobi rotations */
static void least_eigenvector(const double *a_in, double *n)
{
    double a[9], v[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    for (int i = 0; i < 9; i++)
        a[i] = a_in[i];
    for (int sweep = 0; sweep < 50; sweep++) {
        double off = a[1] * a[1] + a[2] * a[2] + a[5] * a[5];
        double diag = a[0] * a[0] + a[4] * a[4] + a[8] * a[8];
        if (off <= 1e-30 * diag || off == 0.0)
            break;
        for (int p = 0; p < 2; p++) {
            for (int q = p + 1; q < 3; q++) {
                double apq = a[3 * p + q];
                if (apq == 0.0)
                    continue;
                double app = a[3 * p + p], aqq = a[3 * q + q];
                double theta = 0.5 * (aqq - app) / apq;
                double t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1.0));
                double c = 1.0 / sqrt(t * t + 1.0), s = t * c;
                for (int k = 0; k < 3; k++) {
                    double akp = a[3 * k + p], akq = a[3 * k + q];
                    a[3 * k + p] = c * akp - s * akq;
                    a[3 * k + q] = s * akp + c * akq;
                }
                for (int k = 0; k < 3; k++) {
                    double apk = a[3 * p + k], aqk = a[3 * q + k];
                    a[3 * p + k] = c * apk - s * aqk;
                    a[3 * q + k] = s * apk + c * aqk;
                }
                for (int k = 0; k < 3; k++) {
                    double vkp = v[3 * k + p], vkq = v[3 * k + q];
                    v[3 * k + p] = c * vkp - s * vkq;
                    v[3 * k + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    int least = 0;
    for (int i = 1; i < 3; i++)
        if (a[4 * i] < a[4 * least])
            least = i;
    double norm = sqrt(v[least] * v[least] + v[3 + least] * v[3 + least] +
                       v[6 + least] * v[6 + least]);
    n[0] = v[least] / norm;
    n[1] = v[3 + least] / norm;
    n[2] = v[6 + least] / norm;
}

/* the regularised covariance (SYM) of the k nearest copies to layer `layer` of a point whose
 * planar neighbours are h (sorted): a plane, 1 along it and FLAT along its normal */
static void sheet_cov(const Tree *t, const Knn *h, int k, int layer, double layer_m, double *out)
{
    double d2[MAX_K * LAYERS];
    int which[MAX_K * LAYERS], count = 0;
    /* the k least of the candidates (neighbour, layer), ties in the order offered */
    for (int j = 0; j < h->found; j++) {
        for (int l = 0; l < LAYERS; l++) {
            double dz = (l - layer) * layer_m, d = h->d2[j] + dz * dz;
            if (count == k && d >= d2[k - 1])
                continue;
            int i = count < k ? count++ : k - 1;
            while (i > 0 && d2[i - 1] > d) {
                d2[i] = d2[i - 1];
                which[i] = which[i - 1];
                i--;
            }
            d2[i] = d;
            which[i] = LAYERS * j + l;
        }
    }
    double m[3] = {0, 0, 0}, c[9] = {0};
    for (int i = 0; i < count; i++) {
        const double *p = t->p + 2 * h->arg[which[i] / LAYERS];
        m[0] += p[0];
        m[1] += p[1];
        m[2] += (which[i] % LAYERS - 1) * layer_m;
    }
    for (int a = 0; a < 3; a++)
        m[a] /= count;
    for (int i = 0; i < count; i++) {
        const double *p = t->p + 2 * h->arg[which[i] / LAYERS];
        double q[3] = {p[0] - m[0], p[1] - m[1], (which[i] % LAYERS - 1) * layer_m - m[2]};
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++)
                c[3 * a + b] += q[a] * q[b];
    }
    double n[3];
    least_eigenvector(c, n);
    double f = 1.0 - FLAT;
    out[0] = 1.0 - f * n[0] * n[0];
    out[1] = -f * n[0] * n[1];
    out[2] = -f * n[0] * n[2];
    out[3] = 1.0 - f * n[1] * n[1];
    out[4] = -f * n[1] * n[2];
    out[5] = 1.0 - f * n[2] * n[2];
}

/* ---- registration ------------------------------------------------------------------------ */

typedef struct {
    const Tree *target;
    const double *tcov;   /* (m, LAYERS, SYM) */
    const double *src;    /* (k, 2) */
    const double *scov;   /* (k, LAYERS, SYM) */
    Py_ssize_t k;
    double max_sq;
    int pair[LAYERS];     /* the target layer each source layer meets */
    double dz[LAYERS];    /* its height above the source layer */
    Py_ssize_t *match;    /* (k,) */
    double *info;         /* (k, LAYERS, SYM); a layer past the distance has info[0] NaN */
} SheetProblem;

/* the inverse of the symmetric m (SYM) into w (SYM); 0 if singular */
static int inverse_sym(const double *m, double *w)
{
    double a = m[0], b = m[1], c = m[2], d = m[3], e = m[4], f = m[5];
    double c00 = d * f - e * e, c01 = c * e - b * f, c02 = b * e - c * d;
    double det = a * c00 + b * c01 + c * c02;
    if (det == 0.0)
        return 0;
    w[0] = c00 / det;
    w[1] = c01 / det;
    w[2] = c02 / det;
    w[3] = (a * f - c * c) / det;
    w[4] = (b * c - a * e) / det;
    w[5] = (a * d - b * b) / det;
    return 1;
}

static double sheet_error_term(const double *w, double ex, double ey, double ez)
{
    return 0.5 * (ex * (w[0] * ex + w[1] * ey + w[2] * ez) + ey * (w[1] * ex + w[3] * ey + w[4] * ez) +
                  ez * (w[2] * ex + w[4] * ey + w[5] * ez));
}

static Py_ssize_t sheet_linearize(SheetProblem *pr, const double *pose, double *H, double *b,
                                  double *e)
{
    double c = cos(pose[2]), s = sin(pose[2]);
    Py_ssize_t inliers = 0;
    for (int i = 0; i < 9; i++)
        H[i] = 0.0;
    b[0] = b[1] = b[2] = 0.0;
    *e = 0.0;
    for (Py_ssize_t i = 0; i < pr->k; i++) {
        const double *p = pr->src + 2 * i;
        double rx = c * p[0] - s * p[1], ry = s * p[0] + c * p[1];
        double qx = rx + pose[0], qy = ry + pose[1];
        double best = pr->max_sq;
        Py_ssize_t j = -1;
        nearest(pr->target, 0, pr->target->n, qx, qy, &best, &j);
        pr->match[i] = j;
        if (j < 0)
            continue;
        inliers++;
        const double *tp = pr->target->p + 2 * j;
        double ex = tp[0] - qx, ey = tp[1] - qy;
        double J[2][3] = {{ry, -c, s}, {-rx, -s, -c}};
        for (int l = 0; l < LAYERS; l++) {
            double *w = pr->info + (LAYERS * i + l) * SYM;
            double ez = pr->dz[l];
            if (best + ez * ez > pr->max_sq) {
                w[0] = NAN;
                continue;
            }
            const double *sc = pr->scov + (LAYERS * i + l) * SYM;
            const double *tc = pr->tcov + (LAYERS * j + pr->pair[l]) * SYM;
            /* R C R^T of the source's covariance (R a turn about z), plus the target's */
            double m[SYM];
            m[0] = c * c * sc[0] - 2.0 * c * s * sc[1] + s * s * sc[3] + tc[0];
            m[1] = c * s * (sc[0] - sc[3]) + (c * c - s * s) * sc[1] + tc[1];
            m[2] = c * sc[2] - s * sc[4] + tc[2];
            m[3] = s * s * sc[0] + 2.0 * c * s * sc[1] + c * c * sc[3] + tc[3];
            m[4] = s * sc[2] + c * sc[4] + tc[4];
            m[5] = sc[5] + tc[5];
            if (!inverse_sym(m, w)) {
                w[0] = NAN;
                continue;
            }
            /* the residual's height is the layers' and does not move with the pose */
            double gx = w[0] * ex + w[1] * ey + w[2] * ez;
            double gy = w[1] * ex + w[3] * ey + w[4] * ez;
            double WJ[2][3];
            for (int col = 0; col < 3; col++) {
                WJ[0][col] = w[0] * J[0][col] + w[1] * J[1][col];
                WJ[1][col] = w[1] * J[0][col] + w[3] * J[1][col];
            }
            for (int r = 0; r < 3; r++) {
                for (int col = 0; col < 3; col++)
                    H[3 * r + col] += J[0][r] * WJ[0][col] + J[1][r] * WJ[1][col];
                b[r] += J[0][r] * gx + J[1][r] * gy;
            }
            *e += sheet_error_term(w, ex, ey, ez);
        }
    }
    return inliers;
}

static double sheet_error_at(const SheetProblem *pr, const double *pose)
{
    double c = cos(pose[2]), s = sin(pose[2]);
    double e = 0.0;
    for (Py_ssize_t i = 0; i < pr->k; i++) {
        Py_ssize_t j = pr->match[i];
        if (j < 0)
            continue;
        const double *p = pr->src + 2 * i, *tp = pr->target->p + 2 * j;
        double ex = tp[0] - (c * p[0] - s * p[1] + pose[0]);
        double ey = tp[1] - (s * p[0] + c * p[1] + pose[1]);
        for (int l = 0; l < LAYERS; l++) {
            const double *w = pr->info + (LAYERS * i + l) * SYM;
            if (isnan(w[0]))
                continue;
            e += sheet_error_term(w, ex, ey, pr->dz[l]);
        }
    }
    return e;
}

/* the error at pose with the correspondences and information of the last linearisation */
static int solve3(const double *A, const double *b, double *x)
{
    double l00 = A[0];
    if (!(l00 > 0))
        return 0;
    l00 = sqrt(l00);
    double l10 = A[3] / l00, l20 = A[6] / l00;
    double d1 = A[4] - l10 * l10;
    if (!(d1 > 0))
        return 0;
    double l11 = sqrt(d1);
    double l21 = (A[7] - l20 * l10) / l11;
    double d2 = A[8] - l20 * l20 - l21 * l21;
    if (!(d2 > 0))
        return 0;
    double l22 = sqrt(d2);
    double y0 = -b[0] / l00;
    double y1 = (-b[1] - l10 * y0) / l11;
    double y2 = (-b[2] - l20 * y0 - l21 * y1) / l22;
    x[2] = y2 / l22;
    x[1] = (y1 - l21 * x[2]) / l11;
    x[0] = (y0 - l10 * x[1] - l20 * x[2]) / l00;
    return 1;
}

/* pose composed on the right with the exponential of delta (theta, x, y) */
static void retract(const double *pose, const double *delta, double *out)
{
    double th = delta[0], vx, vy;
    if (fabs(th) < 1e-10) {
        vx = delta[1];
        vy = delta[2];
    } else {
        double a = sin(th) / th, bb = (1.0 - cos(th)) / th;
        vx = a * delta[1] - bb * delta[2];
        vy = bb * delta[1] + a * delta[2];
    }
    double c = cos(pose[2]), s = sin(pose[2]);
    out[0] = pose[0] + c * vx - s * vy;
    out[1] = pose[1] + s * vx + c * vy;
    out[2] = pose[2] + th;
}



/* ---- Levenberg-Marquardt on SE(2) ------------------------------------------------------- */

typedef struct {
    int iterations, converged;
    Py_ssize_t inliers;
    double error;
} Outcome;

/* pose (3,) overwritten with the result; hess (9,) receives H at the last linearisation.
 * As small_gicp runs it: lambda from 1e-3, ten times up on a step that does not lower the
 * error (ten tries), ten times down on one that does. */
static Outcome levenberg_marquardt(SheetProblem *pr, double *pose, int max_iterations,
                                   double rot_eps, double trans_eps, double *hess)
{
    double H[9] = {0}, b[3] = {0}, e = 0.0, lambda = 1e-3;
    int converged = 0, iterations = 0;
    Py_ssize_t inliers = 0;
    for (int it = 0; it < max_iterations && !converged; it++) {
        inliers = sheet_linearize(pr, pose, H, b, &e);
        int success = 0;
        for (int inner = 0; inner < 10; inner++) {
            double A[9], delta[3] = {0.0, 0.0, 0.0}, moved[3];
            for (int i = 0; i < 9; i++)
                A[i] = H[i];
            A[0] += lambda;
            A[4] += lambda;
            A[8] += lambda;
            if (!solve3(A, b, delta))
                delta[0] = delta[1] = delta[2] = 0.0;
            retract(pose, delta, moved);
            if (sheet_error_at(pr, moved) < e) {
                converged = fabs(delta[0]) <= rot_eps && hypot(delta[1], delta[2]) <= trans_eps;
                pose[0] = moved[0];
                pose[1] = moved[1];
                pose[2] = moved[2];
                lambda /= 10.0;
                success = 1;
                break;
            }
            lambda *= 10.0;
        }
        iterations = it;
        for (int i = 0; i < 9; i++)
            hess[i] = H[i];
        if (!success)
            break;
    }
    Outcome out = {iterations, converged, inliers, e};
    return out;
}

/* ---- the Python face --------------------------------------------------------------------- */

static int take(PyObject *obj, Py_buffer *view, Py_ssize_t itemsize, int writable,
                const char *name)
{
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) != 0)
        return -1;
    if (view->itemsize != itemsize) {
        PyErr_Format(PyExc_ValueError, "%s: expected items of %zd bytes", name, itemsize);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

/* take every buffer of a call; on failure release those taken */
static int take_all(int n, PyObject **objs, Py_buffer *views, const Py_ssize_t *sizes,
                    const int *writable, const char **names)
{
    for (int i = 0; i < n; i++)
        if (take(objs[i], &views[i], sizes[i], writable[i], names[i])) {
            for (int j = 0; j < i; j++)
                PyBuffer_Release(&views[j]);
            return -1;
        }
    return 0;
}

static void release_all(int n, Py_buffer *views)
{
    for (int i = 0; i < n; i++)
        PyBuffer_Release(&views[i]);
}

/* kdtree(points, order, dims): points (n, 2) float64; order (n,) int64 and dims (n,) uint8
 * are filled: the tree order of the points and each node's split axis. */
static PyObject *py_kdtree(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *o[3];
    if (!PyArg_ParseTuple(args, "OOO", &o[0], &o[1], &o[2]))
        return NULL;
    Py_buffer v[3];
    const Py_ssize_t sizes[3] = {8, 8, 1};
    const int writable[3] = {0, 1, 1};
    const char *names[3] = {"points", "order", "dims"};
    if (take_all(3, o, v, sizes, writable, names))
        return NULL;
    Py_ssize_t n = v[0].len / 16;
    if (v[0].len != 16 * n || v[1].len != 8 * n || v[2].len != n) {
        release_all(3, v);
        PyErr_SetString(PyExc_ValueError, "kdtree: points (n, 2), order (n,), dims (n,)");
        return NULL;
    }
    int64_t *idx = v[1].buf;
    for (Py_ssize_t i = 0; i < n; i++)
        idx[i] = i;
    build(idx, v[2].buf, v[0].buf, 0, n);
    release_all(3, v);
    Py_RETURN_NONE;
}

/* covariances(points, dims, k, out): for every point of the tree (points in tree order), the
 * regularised covariance of its k nearest points (itself included) into out (n, 3). */


/* nearest(points, dims, queries, radius, out): the distance from each query (q, 2) to the
 * nearest tree point within radius (inclusive) into out (q,), inf where none is. */
static PyObject *py_nearest(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *o[4];
    double radius;
    if (!PyArg_ParseTuple(args, "OOOdO", &o[0], &o[1], &o[2], &radius, &o[3]))
        return NULL;
    Py_buffer v[4];
    const Py_ssize_t sizes[4] = {8, 1, 8, 8};
    const int writable[4] = {0, 0, 0, 1};
    const char *names[4] = {"points", "dims", "queries", "out"};
    if (take_all(4, o, v, sizes, writable, names))
        return NULL;
    Py_ssize_t n = v[1].len, q = v[3].len / 8;
    if (v[0].len != 16 * n || v[2].len != 16 * q || v[3].len != 8 * q) {
        release_all(4, v);
        PyErr_SetString(PyExc_ValueError, "nearest: points (n, 2), queries (q, 2), out (q,)");
        return NULL;
    }
    Tree t = {v[0].buf, v[1].buf, n};
    const double *qs = v[2].buf;
    double *out = v[3].buf;
    for (Py_ssize_t i = 0; i < q; i++) {
        double best = radius * radius;
        Py_ssize_t j = -1;
        nearest(&t, 0, n, qs[2 * i], qs[2 * i + 1], &best, &j);
        out[i] = j < 0 ? INFINITY : sqrt(best);
    }
    release_all(4, v);
    Py_RETURN_NONE;
}

/* sheet_covariances(points, dims, k, layer_m, out): for every point of the tree (points in tree
 * order) and each of the three layers of its sheet (heights -layer_m, 0, layer_m), the
 * regularised covariance of the k nearest copies, into out (n, 3, 6: xx xy xz yy yz zz). */
static PyObject *py_sheet_covariances(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *o[3];
    int k;
    double layer_m;
    if (!PyArg_ParseTuple(args, "OOidO", &o[0], &o[1], &k, &layer_m, &o[2]))
        return NULL;
    if (k < 1 || k > MAX_K) {
        PyErr_Format(PyExc_ValueError, "sheet_covariances: k must be 1 to %d", MAX_K);
        return NULL;
    }
    Py_buffer v[3];
    const Py_ssize_t sizes[3] = {8, 1, 8};
    const int writable[3] = {0, 0, 1};
    const char *names[3] = {"points", "dims", "out"};
    if (take_all(3, o, v, sizes, writable, names))
        return NULL;
    Py_ssize_t n = v[1].len;
    if (v[0].len != 16 * n || v[2].len != 8 * LAYERS * SYM * n) {
        release_all(3, v);
        PyErr_SetString(PyExc_ValueError,
                        "sheet_covariances: points (n, 2), dims (n,), out (n, 3, 6)");
        return NULL;
    }
    Tree t = {v[0].buf, v[1].buf, n};
    double *out = v[2].buf;
    Knn h;
    h.k = k;
    for (Py_ssize_t i = 0; i < n; i++) {
        h.found = 0;
        knn(&t, 0, n, t.p[2 * i], t.p[2 * i + 1], &h);
        for (int l = 0; l < LAYERS; l++)
            sheet_cov(&t, &h, k, l, layer_m, out + (LAYERS * i + l) * SYM);
    }
    release_all(3, v);
    Py_RETURN_NONE;
}

/* align_sheet(tpoints, tdims, tcov, t_layer_m, spoints, scov, s_layer_m, pose, max_distance,
 *             max_iterations, rotation_eps, translation_eps, hessian)
 * GICP of the source sheet onto the target sheet (covariances (n, 3, 6) as sheet_covariances
 * gives them) from pose (3,) float64, overwritten with the result: each source layer meets the
 * nearest target layer, at the planar nearest point within max_distance in 3-D. hessian (9,)
 * receives H at the last linearisation (theta, x, y; a turn and a shift on the right of the
 * pose). Returns (iterations, converged, inliers, error). */
static PyObject *py_align_sheet(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *o[7];
    double t_layer, s_layer, max_distance, rot_eps, trans_eps;
    int max_iterations;
    if (!PyArg_ParseTuple(args, "OOOdOOdOdiddO", &o[0], &o[1], &o[2], &t_layer, &o[3], &o[4],
                          &s_layer, &o[5], &max_distance, &max_iterations, &rot_eps, &trans_eps,
                          &o[6]))
        return NULL;
    Py_buffer v[7];
    const Py_ssize_t sizes[7] = {8, 1, 8, 8, 8, 8, 8};
    const int writable[7] = {0, 0, 0, 0, 0, 1, 1};
    const char *names[7] = {"tpoints", "tdims", "tcov", "spoints", "scov", "pose", "hessian"};
    if (take_all(7, o, v, sizes, writable, names))
        return NULL;
    Py_ssize_t m = v[1].len, k = v[3].len / 16;
    if (v[0].len != 16 * m || v[2].len != 8 * LAYERS * SYM * m || v[3].len != 16 * k ||
        v[4].len != 8 * LAYERS * SYM * k || v[5].len != 24 || v[6].len != 72) {
        release_all(7, v);
        PyErr_SetString(PyExc_ValueError, "align_sheet: arrays of mismatched shapes");
        return NULL;
    }
    Tree t = {v[0].buf, v[1].buf, m};
    SheetProblem pr;
    pr.target = &t;
    pr.tcov = v[2].buf;
    pr.src = v[3].buf;
    pr.scov = v[4].buf;
    pr.k = k;
    pr.max_sq = max_distance * max_distance;
    for (int l = 0; l < LAYERS; l++) {
        double zs = (l - 1) * s_layer, best = INFINITY;
        for (int lt = 0; lt < LAYERS; lt++) {
            double zt = (lt - 1) * t_layer;
            if (fabs(zt - zs) < best) {
                best = fabs(zt - zs);
                pr.pair[l] = lt;
                pr.dz[l] = zt - zs;
            }
        }
    }
    pr.match = malloc(sizeof(Py_ssize_t) * (size_t)(k + 1));
    pr.info = malloc(sizeof(double) * (size_t)(LAYERS * SYM * k + 1));
    if (pr.match == NULL || pr.info == NULL) {
        free(pr.match);
        free(pr.info);
        release_all(7, v);
        return PyErr_NoMemory();
    }
    Outcome out = levenberg_marquardt(&pr, v[5].buf, max_iterations, rot_eps, trans_eps,
                                      v[6].buf);
    free(pr.match);
    free(pr.info);
    release_all(7, v);
    return Py_BuildValue("(iind)", out.iterations, out.converged, out.inliers, out.error);
}


static PyMethodDef methods[] = {
    {"kdtree", py_kdtree, METH_VARARGS, "Order planar points into an implicit kd-tree."},
    {"nearest", py_nearest, METH_VARARGS, "Distances to the nearest tree point in a radius."},
    {"sheet_covariances", py_sheet_covariances, METH_VARARGS,
     "Regularised covariances of the three layers of a planar sheet."},
    {"align_sheet", py_align_sheet, METH_VARARGS, "GICP of planar sheets on SE(2)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_csheet", NULL, -1, methods,
                                    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__csheet(void) { return PyModule_Create(&module); }
