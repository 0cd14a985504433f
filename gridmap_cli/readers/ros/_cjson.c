/* gridmap's compiled JSON matcher: the compact layout gridmap writes for its own JSON channels
 * (gridmap_cli/readers/ros/mcap/json_bulk.py), message by message over one chunk's messages.
 *
 * The numpy matcher in json_bulk.py stays the reference: this one takes a message only where
 * the numpy one would, and flags every other message; the Python side then gives the whole
 * chunk to the numpy matcher, so the fallbacks and errors are the reference's own. Numbers
 * are read to the same bits as Python's `float` of the same text (what `json` gives): exactly
 * in double arithmetic where that is provably correctly rounded (Clinger's fast path), else by
 * PyOS_string_to_double, Python's own parser.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <float.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "_cjson.h"

enum { F_INT = 0, F_NUM = 1, F_STR = 2, LITERAL = -1 };
#define MAX_PARTS 32

/* the longest field of each kind, as json_bulk._WIDTH: stamps of up to 9 digits (and a sign),
 * numbers of up to 32 characters, names of up to 64 */
static const Py_ssize_t WIDTH[3] = {10, 32, 64};

typedef struct {
    int kind; /* LITERAL or a field kind */
    const char *text;
    Py_ssize_t len;
} Part;

/* a field's text ends at the first " , } or NUL (json_bulk._stop) */
static const unsigned char *field_end(const unsigned char *p, const unsigned char *limit)
{
    for (; p < limit; p++)
        if (*p == '"' || *p == ',' || *p == '}' || *p == 0)
            return p;
    return NULL;
}

/* JSON's integer grammar (-?(0|[1-9][0-9]*)), at most 9 digits: its value, or -1 if not. */
static int read_int(const unsigned char *s, Py_ssize_t n, int64_t *out)
{
    Py_ssize_t i = 0;
    int negative = n > 0 && s[0] == '-';
    i += negative;
    if (i == n || n - i > 9 || (s[i] == '0' && n - i > 1))
        return -1;
    int64_t v = 0;
    for (; i < n; i++) {
        if (s[i] < '0' || s[i] > '9')
            return -1;
        v = v * 10 + (s[i] - '0');
    }
    *out = negative ? -v : v;
    return 0;
}

static const double POW10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                 1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
#define EXACT_MAX ((uint64_t)1 << 53)

/* Python's float of a number's text (what json gives for it): 0, -1 if Python's parser does
 * not take all of it, -2 with an exception set. */
static int python_float(const unsigned char *s, Py_ssize_t n, double *out)
{
    char text[40];
    if (n >= (Py_ssize_t)sizeof text)
        return -1;
    memcpy(text, s, (size_t)n);
    text[n] = 0;
    char *end;
    double v = PyOS_string_to_double(text, &end, NULL);
    if (v == -1.0 && PyErr_Occurred())
        return -2;
    if (end != text + n)
        return -1;
    *out = v;
    return 0;
}

/* A JSON number (-?(0|[1-9][0-9]*)(\.[0-9]+)?([eE][+-]?[0-9]+)?) or NaN / Infinity /
 * -Infinity as Python's json writes them, read as Python's float reads its text: 0 and the
 * value; -1 if the text is none of these; -2 with an exception set. */
static int read_num(const unsigned char *s, Py_ssize_t n, double *out)
{
    if ((n == 3 && memcmp(s, "NaN", 3) == 0) || (n == 8 && memcmp(s, "Infinity", 8) == 0) ||
        (n == 9 && memcmp(s, "-Infinity", 9) == 0))
        return python_float(s, n, out);
    int negative = n > 0 && s[0] == '-';
    Py_ssize_t i = negative;
    if (i == n || s[i] < '0' || s[i] > '9' ||
        (s[i] == '0' && i + 1 < n && s[i + 1] >= '0' && s[i + 1] <= '9'))
        return -1;
    uint64_t w = 0;  /* the first 19 significant digits */
    int digits = 0;  /* significant digits seen */
    long scale = 0;  /* w * 10^scale is the value before the exponent (when digits <= 19) */
    int integer = 1; /* no fraction, no exponent: json reads an int */
    for (; i < n && s[i] >= '0' && s[i] <= '9'; i++) {
        if (digits < 19) {
            w = w * 10 + (uint64_t)(s[i] - '0');
            digits += w != 0;
        } else {
            digits++;
            scale++;
        }
    }
    if (i < n && s[i] == '.') {
        integer = 0;
        if (++i == n || s[i] < '0' || s[i] > '9')
            return -1;
        for (; i < n && s[i] >= '0' && s[i] <= '9'; i++) {
            if (digits < 19) {
                w = w * 10 + (uint64_t)(s[i] - '0');
                digits += w != 0;
                scale--;
            } else {
                digits++;
            }
        }
    }
    long exponent = 0;
    if (i < n && (s[i] == 'e' || s[i] == 'E')) {
        integer = 0;
        int minus = ++i < n && s[i] == '-';
        if (i < n && (s[i] == '+' || s[i] == '-'))
            i++;
        if (i == n || s[i] < '0' || s[i] > '9')
            return -1;
        for (; i < n && s[i] >= '0' && s[i] <= '9'; i++)
            if (exponent < 100000)
                exponent = exponent * 10 + (s[i] - '0');
        if (minus)
            exponent = -exponent;
    }
    if (i != n)
        return -1;
    if (digits == 0) { /* every digit zero; json reads the int -0 as 0, a float -0 as -0.0 */
        *out = negative && !integer ? -0.0 : 0.0;
        return 0;
    }
#if defined(FLT_EVAL_METHOD) && FLT_EVAL_METHOD == 0
    /* w and 10^|e| both exact doubles: one IEEE operation, so correctly rounded, as Python's
     * parser rounds (Clinger's fast path); only where doubles are evaluated as doubles */
    long e = scale + exponent;
    if (digits <= 19 && w <= EXACT_MAX && e >= -22 && e <= 22) {
        double v = e >= 0 ? (double)w * POW10[e] : (double)w / POW10[-e];
        *out = negative ? -v : v;
        return 0;
    }
#endif
    return python_float(s, n, out);
}

/* Distinct names of a field, first seen first: an open-addressing table of their indexes. */
typedef struct {
    Py_ssize_t *slot; /* index + 1 into first/len, 0 when empty */
    size_t mask;
    const unsigned char **first;
    Py_ssize_t *len;
    Py_ssize_t count;
} Names;

static int names_init(Names *t, Py_ssize_t n)
{
    size_t size = 16;
    while (size < 2 * (size_t)n)
        size <<= 1;
    t->slot = calloc(size, sizeof *t->slot);
    t->first = malloc(((size_t)n + 1) * sizeof *t->first);
    t->len = malloc(((size_t)n + 1) * sizeof *t->len);
    t->mask = size - 1;
    t->count = 0;
    return t->slot && t->first && t->len ? 0 : -1;
}

static void names_free(Names *t)
{
    free(t->slot);
    free(t->first);
    free(t->len);
}

static Py_ssize_t names_index(Names *t, const unsigned char *s, Py_ssize_t n)
{
    uint64_t h = 1469598103934665603ULL; /* FNV-1a */
    for (Py_ssize_t i = 0; i < n; i++)
        h = (h ^ s[i]) * 1099511628211ULL;
    size_t at = (size_t)h & t->mask;
    for (;; at = (at + 1) & t->mask) {
        Py_ssize_t k = t->slot[at];
        if (k == 0)
            break;
        if (t->len[k - 1] == n && memcmp(t->first[k - 1], s, (size_t)n) == 0)
            return k - 1;
    }
    t->first[t->count] = s;
    t->len[t->count] = n;
    t->slot[at] = ++t->count;
    return t->count - 1;
}

static PyObject *names_list(const Names *t)
{
    PyObject *out = PyList_New(t->count);
    for (Py_ssize_t i = 0; out != NULL && i < t->count; i++) {
        PyObject *name = PyUnicode_DecodeASCII((const char *)t->first[i], t->len[i], NULL);
        if (name == NULL) {
            Py_CLEAR(out);
            break;
        }
        PyList_SET_ITEM(out, i, name);
    }
    return out;
}

/* One message against the layout: 1 if it has it (its numbers written at `row`, its names'
 * places in name_at / name_len by field), 0 if not, -1 with an exception set. */
static int match(const unsigned char *p, const unsigned char *end, const Part *parts,
                 int nparts, void **outs, Py_ssize_t row, const unsigned char **name_at,
                 Py_ssize_t *name_len)
{
    int field = 0;
    for (int k = 0; k < nparts; k++) {
        const Part *part = &parts[k];
        if (part->kind == LITERAL) {
            if (end - p < part->len || memcmp(p, part->text, (size_t)part->len) != 0)
                return 0;
            p += part->len;
            continue;
        }
        Py_ssize_t width = WIDTH[part->kind];
        const unsigned char *stop = field_end(p, end - p > width ? p + width + 1 : end);
        if (stop == NULL)
            return 0;
        Py_ssize_t n = stop - p;
        if (part->kind == F_INT) {
            if (read_int(p, n, (int64_t *)outs[field] + row) != 0)
                return 0;
        } else if (part->kind == F_NUM) {
            int got = read_num(p, n, (double *)outs[field] + row);
            if (got != 0)
                return got == -2 ? -1 : 0;
        } else {
            for (Py_ssize_t i = 0; i < n; i++) /* printable ASCII but " and \ (no escapes) */
                if (p[i] < 0x20 || p[i] > 0x7e || p[i] == '\\')
                    return 0;
            name_at[field] = p;
            name_len[field] = n;
        }
        field++;
        p = stop;
    }
    return p == end;
}

/* json_compact(data, offset, length, layout, outs, ok) -> names
 *
 * data: a chunk's bytes; offset, length: each message's place in it (int64, N); layout: the
 * literal texts (bytes) and fields (0 integer, 1 number, 2 name) in turn, each field followed
 * by a literal; outs: one writable buffer of N 8-byte values a field (int64 for integers and
 * names' indexes, float64 for numbers); ok: a writable buffer of N bytes, 1 where a message
 * has the layout, else 0 (and its values are unset). Returns a list a field: the distinct
 * names of a name field, first seen first, or None. */
PyObject *gridmap_json_compact(PyObject *self, PyObject *args)
{
    (void)self;
    Py_buffer data, offset, length, ok;
    PyObject *layout, *out_objs;
    if (!PyArg_ParseTuple(args, "y*y*y*O!O!w*", &data, &offset, &length, &PyTuple_Type, &layout,
                          &PyTuple_Type, &out_objs, &ok))
        return NULL;
    PyObject *result = NULL;
    Part parts[MAX_PARTS];
    Py_buffer outs[MAX_PARTS];
    void *out_ptrs[MAX_PARTS];
    Names names[MAX_PARTS];
    int nparts = (int)PyTuple_GET_SIZE(layout), nfields = 0, nouts = 0, nnames = 0;
    Py_ssize_t n = offset.len / 8;
    if (nparts > MAX_PARTS || offset.len != length.len || offset.len % 8 || ok.len != n) {
        PyErr_SetString(PyExc_ValueError, "json_compact: bad layout or array sizes");
        goto done;
    }
    for (int k = 0; k < nparts; k++) {
        PyObject *item = PyTuple_GET_ITEM(layout, k);
        if (PyBytes_Check(item)) {
            parts[k] = (Part){LITERAL, PyBytes_AS_STRING(item), PyBytes_GET_SIZE(item)};
            continue;
        }
        long kind = PyLong_AsLong(item);
        if (kind < F_INT || kind > F_STR || k + 1 >= nparts ||
            !PyBytes_Check(PyTuple_GET_ITEM(layout, k + 1)) ||
            PyBytes_GET_SIZE(PyTuple_GET_ITEM(layout, k + 1)) == 0) {
            if (!PyErr_Occurred())
                PyErr_SetString(PyExc_ValueError, "json_compact: a field not followed by text");
            goto done;
        }
        parts[k] = (Part){(int)kind, NULL, 0};
        nfields++;
    }
    if (PyTuple_GET_SIZE(out_objs) != nfields) {
        PyErr_SetString(PyExc_ValueError, "json_compact: one output a field");
        goto done;
    }
    for (; nouts < nfields; nouts++) {
        if (PyObject_GetBuffer(PyTuple_GET_ITEM(out_objs, nouts), &outs[nouts],
                               PyBUF_WRITABLE | PyBUF_C_CONTIGUOUS) != 0)
            goto done;
        out_ptrs[nouts] = outs[nouts].buf;
        if (outs[nouts].len != n * 8) {
            nouts++;
            PyErr_SetString(PyExc_ValueError, "json_compact: outputs of N 8-byte values");
            goto done;
        }
    }
    for (int k = 0, f = 0; k < nparts; k++) {
        if (parts[k].kind == LITERAL)
            continue;
        names[f].slot = NULL;
        names[f].first = NULL;
        names[f].len = NULL;
        if (parts[k].kind == F_STR && names_init(&names[f], n) != 0) {
            nnames = f + 1;
            PyErr_NoMemory();
            goto done;
        }
        nnames = ++f;
    }
    const unsigned char *buf = data.buf;
    const int64_t *at = offset.buf, *len = length.buf;
    unsigned char *good = ok.buf;
    const unsigned char *name_at[MAX_PARTS];
    Py_ssize_t name_len[MAX_PARTS];
    for (Py_ssize_t i = 0; i < n; i++) {
        good[i] = 0;
        if (at[i] < 0 || len[i] < 0 || at[i] > data.len || len[i] > data.len - at[i])
            continue;
        const unsigned char *p = buf + at[i];
        int got = match(p, p + len[i], parts, nparts, out_ptrs, i, name_at, name_len);
        if (got < 0)
            goto done;
        if (got == 0)
            continue;
        for (int f = 0; f < nfields; f++) /* once the whole message matched */
            if (names[f].slot != NULL)
                ((int64_t *)out_ptrs[f])[i] = names_index(&names[f], name_at[f], name_len[f]);
        good[i] = 1;
    }
    result = PyList_New(nfields);
    for (int f = 0; result != NULL && f < nfields; f++) {
        PyObject *item = names[f].slot ? names_list(&names[f]) : (Py_INCREF(Py_None), Py_None);
        if (item == NULL)
            Py_CLEAR(result);
        else
            PyList_SET_ITEM(result, f, item);
    }
done:
    for (int f = 0; f < nnames; f++)
        names_free(&names[f]);
    for (int f = 0; f < nouts; f++)
        PyBuffer_Release(&outs[f]);
    PyBuffer_Release(&data);
    PyBuffer_Release(&offset);
    PyBuffer_Release(&length);
    PyBuffer_Release(&ok);
    return result;
}
