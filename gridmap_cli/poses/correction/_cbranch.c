/* The correlative search's branch and bound (gridmap_cli/poses/correction/correlative.py) in C.
 *
 * It repeats the numpy reference step for step, so that it returns the same pose and score bit
 * for bit: a score is the float32 sum of the grid's cells under the points, summed in numpy's
 * pairwise order (8 running sums in blocks of 128, halves above), over float32 of the point
 * count; the roots are visited by decreasing bound, ties in the order they were made; each
 * node's children are tried in the order numpy's argsort puts their scores, given by the
 * caller as a table (a tie's order is the sort's own: tied scores at the end pick the pose).
 *
 * Arrays arrive through the buffer protocol (contiguous float32 / int32 / int64, checked here),
 * so the module needs no numpy headers. Built with -ffp-contract=off: no fused multiply-adds.
 *
 * A score reads one grid cell per point, scattered over the grid: the points' cells come as
 * 32-bit indices (half the memory traffic of numpy's int64), and where the processor has AVX2,
 * a block's 8 running sums are one vector filled by gathers. Each lane adds the same
 * values in the same order as the scalar code, so every sum is the same bit for bit.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#if defined(__x86_64__)
#include <immintrin.h>
#endif

#define MAX_LEVELS 16
#define BLOCK 128

/* numpy's pairwise float32 sum of g[idx[i]] (i < n): 8 accumulators up to BLOCK items, then
 * halves cut at a multiple of 8. */
static float pairwise(const float *g, const int32_t *idx, Py_ssize_t n)
{
    if (n < 8) {
        float res = 0.0f;
        for (Py_ssize_t i = 0; i < n; i++)
            res += g[idx[i]];
        return res;
    }
    if (n <= BLOCK) {
        float r[8];
        Py_ssize_t i;
        for (int j = 0; j < 8; j++)
            r[j] = g[idx[j]];
        for (i = 8; i < n - (n % 8); i += 8)
            for (int j = 0; j < 8; j++)
                r[j] += g[idx[i + j]];
        float res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
        for (; i < n; i++)
            res += g[idx[i]];
        return res;
    }
    Py_ssize_t n2 = n / 2;
    n2 -= n2 % 8;
    return pairwise(g, idx, n2) + pairwise(g, idx + n2, n - n2);
}

static int use_avx2 = 0;

#if defined(__x86_64__)
/* pairwise() with a block's 8 accumulators as the 8 lanes of one vector. It repeats pairwise()'s
 * small case and halving so that the whole walk is compiled for AVX2: with one walk calling
 * either block sum (an AVX2 function cannot be inlined into a generic one) the search measured
 * a tenth slower. */
__attribute__((target("avx2"))) static float pairwise_avx2(const float *g, const int32_t *idx,
                                                           Py_ssize_t n)
{
    if (n < 8) {
        float res = 0.0f;
        for (Py_ssize_t i = 0; i < n; i++)
            res += g[idx[i]];
        return res;
    }
    if (n <= BLOCK) {
        __m256 acc = _mm256_i32gather_ps(g, _mm256_loadu_si256((const __m256i *)idx), 4);
        Py_ssize_t i;
        for (i = 8; i < n - (n % 8); i += 8)
            acc = _mm256_add_ps(
                acc, _mm256_i32gather_ps(g, _mm256_loadu_si256((const __m256i *)(idx + i)), 4));
        float r[8];
        _mm256_storeu_ps(r, acc);
        float res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
        for (; i < n; i++)
            res += g[idx[i]];
        return res;
    }
    Py_ssize_t n2 = n / 2;
    n2 -= n2 % 8;
    return pairwise_avx2(g, idx, n2) + pairwise_avx2(g, idx + n2, n - n2);
}
#endif

typedef struct {
    const float *level[MAX_LEVELS + 1];
    Py_ssize_t size;   /* cells in each level */
    int64_t width;     /* cells in a row */
    Py_ssize_t k;      /* points */
    const unsigned char *order; /* argsort table: [n][code] -> 4 indices */
} Grid;

static float score(const Grid *gr, int lv, const int32_t *cells, int64_t du, int64_t dv)
{
    const float *g = gr->level[lv] + (du * gr->width + dv);
#if defined(__x86_64__)
    if (use_avx2)
        return pairwise_avx2(g, cells, gr->k) / (float)gr->k;
#endif
    return pairwise(g, cells, gr->k) / (float)gr->k;
}

/* The argsort order of n <= 4 scores, from the caller's table keyed by their dense ranks. */
static const unsigned char *order_of(const Grid *gr, const float *s, int n)
{
    int code = 0;
    for (int i = 0; i < n; i++) {
        int rank = 0;
        for (int j = 0; j < n; j++) {
            int below = s[j] < s[i];
            for (int m = 0; m < j && below; m++)
                if (s[m] == s[j])
                    below = 0; /* count each distinct value once */
            rank += below;
        }
        code = code * 4 + rank;
    }
    return gr->order + ((n - 1) * 256 + code) * 4;
}

typedef struct {
    double bound;
    int64_t u, v;
    int lv;
} Node;

/* Depth-first below one root: the best leaf above *floor, written to best_u/v; 1 if found. */
static int descend(const Grid *gr, const int32_t *cells, int64_t u0, int64_t v0, int top,
                   int64_t reach, double *floor, int64_t *best_u, int64_t *best_v, Node *stack)
{
    int found = 0, depth = 0;
    stack[depth++] = (Node){INFINITY, u0, v0, top};
    while (depth) {
        Node node = stack[--depth];
        if (node.bound <= *floor)
            continue;
        int64_t h = (int64_t)1 << (node.lv - 1);
        int64_t ku[4], kv[4];
        float s[4];
        int n = 0;
        const int64_t du[4] = {0, h, 0, h}, dv[4] = {0, 0, h, h};
        for (int c = 0; c < 4; c++) {
            int64_t u = node.u + du[c], v = node.v + dv[c];
            if (llabs(u) <= reach && llabs(v) <= reach) {
                ku[n] = u;
                kv[n] = v;
                n++;
            }
        }
        if (n == 0)
            continue;
        for (int c = 0; c < n; c++)
            s[c] = score(gr, node.lv - 1, cells, ku[c], kv[c]);
        const unsigned char *ord = order_of(gr, s, n);
        for (int c = 0; c < n; c++) {
            int m = ord[c];
            if ((double)s[m] <= *floor)
                continue;
            if (node.lv - 1 == 0) {
                *floor = s[m];
                *best_u = ku[m];
                *best_v = kv[m];
                found = 1;
            } else {
                stack[depth++] = (Node){s[m], ku[m], kv[m], node.lv - 1};
            }
        }
    }
    return found;
}

typedef struct {
    double bound;
    Py_ssize_t index;
} Root;

static int by_bound(const void *a, const void *b)
{
    const Root *x = a, *y = b;
    if (x->bound != y->bound)
        return x->bound > y->bound ? -1 : 1;
    return (x->index > y->index) - (x->index < y->index);
}

static int take(PyObject *obj, Py_buffer *view, Py_ssize_t itemsize, const char *name)
{
    if (PyObject_GetBuffer(obj, view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) != 0)
        return -1;
    if (view->itemsize != itemsize) {
        PyErr_Format(PyExc_ValueError, "%s: expected items of %zd bytes", name, itemsize);
        PyBuffer_Release(view);
        return -1;
    }
    return 0;
}

/* search(levels, width, cells, turns, tiles, reach, min_score, order)
 * levels: sequence of top+1 float32 grids (flat, equal sizes); width: cells in a row;
 * cells: int32 (turns * K) flat fine cells of the points at each heading; tiles: int64 (R * 2)
 * the root offsets; reach: the window in cells; order: bytes, the argsort table.
 * Returns (score, turn, u, v) of the best pose scoring above min_score, or None. */
static PyObject *search(PyObject *self, PyObject *args)
{
    (void)self;
    PyObject *levels, *cells_obj, *tiles_obj, *order_obj;
    long long width, reach;
    Py_ssize_t turns;
    double min_score;
    if (!PyArg_ParseTuple(args, "OLOnOLdO", &levels, &width, &cells_obj, &turns, &tiles_obj,
                          &reach, &min_score, &order_obj))
        return NULL;
    Py_ssize_t nlev = PySequence_Length(levels);
    if (nlev < 2 || nlev > MAX_LEVELS + 1 || turns < 1) {
        PyErr_SetString(PyExc_ValueError, "search: 2 to 17 levels and one turn or more");
        return NULL;
    }
    Py_buffer views[MAX_LEVELS + 1], cv, tv, ov;
    int held = 0, ok = 0;
    Grid gr;
    PyObject *result = NULL;
    Root *roots = NULL;
    Node *stack = NULL;
    double best = min_score;
    Py_ssize_t best_turn = -1;
    int64_t best_u = 0, best_v = 0;
    for (; held < nlev; held++) {
        PyObject *item = PySequence_GetItem(levels, held);
        if (item == NULL)
            goto done;
        int bad = take(item, &views[held], 4, "levels");
        Py_DECREF(item);
        if (bad)
            goto done;
        gr.level[held] = views[held].buf;
        if (held && views[held].len != views[0].len) {
            PyErr_SetString(PyExc_ValueError, "search: levels of different sizes");
            held++;
            goto done;
        }
    }
    if (take(cells_obj, &cv, 4, "cells"))
        goto done;
    if (take(tiles_obj, &tv, 8, "tiles")) {
        PyBuffer_Release(&cv);
        goto done;
    }
    if (PyObject_GetBuffer(order_obj, &ov, PyBUF_SIMPLE) != 0) {
        PyBuffer_Release(&cv);
        PyBuffer_Release(&tv);
        goto done;
    }
    ok = 1;
    gr.size = views[0].len / 4;
    gr.width = width;
    gr.k = cv.len / 4 / turns;
    gr.order = ov.buf;
    int top = (int)nlev - 1;
    Py_ssize_t ntiles = tv.len / 16;
    const int32_t *cells = cv.buf;
    const int64_t *tiles = tv.buf;
    if (ov.len != 4 * 256 * 4 || gr.k < 1 || gr.k * turns * 4 != cv.len) {
        PyErr_SetString(PyExc_ValueError, "search: bad order table or cells");
        goto done;
    }
    /* every cell read must lie on the grid: the points' cells moved by the farthest offset */
    int64_t span = reach + ((int64_t)1 << top);
    int64_t lowest = INT64_MAX, highest = INT64_MIN;
    for (Py_ssize_t i = 0; i < gr.k * turns; i++) {
        lowest = cells[i] < lowest ? cells[i] : lowest;
        highest = cells[i] > highest ? cells[i] : highest;
    }
    if (lowest - span * (width + 1) < 0 || highest + span * (width + 1) >= gr.size) {
        PyErr_SetString(PyExc_ValueError, "search: the window reaches off the grid");
        goto done;
    }
    if (gr.size > INT32_MAX) {
        PyErr_SetString(PyExc_ValueError, "search: a grid of 2^31 cells or more");
        goto done;
    }
    roots = malloc(sizeof(Root) * (size_t)(turns * ntiles + 1));
    stack = malloc(sizeof(Node) * (size_t)(4 * (top + 1) + 4));
    if (roots == NULL || stack == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t t = 0; t < turns; t++)
        for (Py_ssize_t m = 0; m < ntiles; m++) {
            Py_ssize_t r = t * ntiles + m;
            roots[r].bound = score(&gr, top, cells + t * gr.k, tiles[2 * m], tiles[2 * m + 1]);
            roots[r].index = r;
        }
    qsort(roots, (size_t)(turns * ntiles), sizeof(Root), by_bound);
    for (Py_ssize_t r = 0; r < turns * ntiles; r++) {
        if (roots[r].bound <= best)
            break;
        Py_ssize_t t = roots[r].index / ntiles, m = roots[r].index % ntiles;
        int64_t u = 0, v = 0;
        if (descend(&gr, cells + t * gr.k, tiles[2 * m], tiles[2 * m + 1], top, reach, &best, &u,
                    &v, stack)) {
            best_turn = t;
            best_u = u;
            best_v = v;
        }
    }
    if (best_turn < 0) {
        Py_INCREF(Py_None);
        result = Py_None;
    } else {
        result = Py_BuildValue("(dnLL)", best, best_turn, (long long)best_u, (long long)best_v);
    }
done:
    free(roots);
    free(stack);
    for (int i = 0; i < held; i++)
        PyBuffer_Release(&views[i]);
    if (ok) {
        PyBuffer_Release(&cv);
        PyBuffer_Release(&tv);
        PyBuffer_Release(&ov);
    }
    return result;
}

/* vectors(on): use the AVX2 sums where the processor has them (on true) or the scalar ones
 * (on false; the tests compare both); returns whether the AVX2 sums are now in use. */
static PyObject *vectors(PyObject *self, PyObject *arg)
{
    (void)self;
    int on = PyObject_IsTrue(arg);
    if (on < 0)
        return NULL;
    use_avx2 = 0;
#if defined(__x86_64__)
    use_avx2 = on && __builtin_cpu_supports("avx2");
#endif
    return PyBool_FromLong(use_avx2);
}

static PyMethodDef methods[] = {
    {"search", search, METH_VARARGS, "Branch and bound over a pooled likelihood grid."},
    {"vectors", vectors, METH_O, "Use the AVX2 sums where there are any; whether they are used."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_cbranch", NULL, -1, methods,
                                    NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__cbranch(void)
{
#if defined(__x86_64__)
    __builtin_cpu_init();
    use_avx2 = __builtin_cpu_supports("avx2");
#endif
    return PyModule_Create(&module);
}
