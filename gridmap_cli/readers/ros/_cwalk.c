/* gridmap's compiled record walks: the per-record loops of the MCAP and ROS 1 bag integrity
 * checks (mcap_integrity.py, bag_integrity.py), over one chunk's decompressed records.
 *
 * An hour of sonar holds about 680,000 records; walking them in Python cost 0.15 s (MCAP) and
 * 1 s (bag) of a 1 s build. These walks only find where the first problem is, or that there
 * is none: the Python walk then reads the damaged record again and words the error, so every
 * message stays the reference's own. gridmap_cli/readers/ros/walk.py is the Python side.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

static uint32_t u32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t u64(const unsigned char *p)
{
    return (uint64_t)u32(p) | (uint64_t)u32(p + 4) << 32;
}

/* mcap_records(data, allowed, message_opcode, message_fixed) -> offset of the first record
 * that overruns the data, has an opcode not in `allowed`, or is a message record shorter than
 * `message_fixed`; -1 when every record is sound. */
static PyObject *mcap_records(PyObject *self, PyObject *args)
{
    (void)self;
    Py_buffer data, allowed;
    int message_opcode;
    unsigned long long message_fixed;
    if (!PyArg_ParseTuple(args, "y*y*iK", &data, &allowed, &message_opcode, &message_fixed))
        return NULL;
    unsigned char ok[256] = {0};
    for (Py_ssize_t i = 0; i < allowed.len; i++)
        ok[((const unsigned char *)allowed.buf)[i]] = 1;
    const unsigned char *p = data.buf;
    Py_ssize_t end = data.len, pos = 0, bad = -1;
    while (pos < end) {
        if (end - pos < 9) {
            bad = pos;
            break;
        }
        int opcode = p[pos];
        uint64_t length = u64(p + pos + 1);
        if (length > (uint64_t)(end - pos - 9) || !ok[opcode] ||
            (opcode == message_opcode && length < message_fixed)) {
            bad = pos;
            break;
        }
        pos += 9 + (Py_ssize_t)length;
    }
    PyBuffer_Release(&data);
    PyBuffer_Release(&allowed);
    return PyLong_FromSsize_t(bad);
}

/* The op of a bag record's header fields (`len name=value` each), or -1 when a field
 * overruns the header, lacks '=', or no 1-byte `op` field is there (the last one counts, as
 * in a dict). */
static int bag_op(const unsigned char *h, uint32_t hlen)
{
    int op = -1;
    uint32_t i = 0;
    while (i < hlen) {
        if (hlen - i < 4)
            return -1;
        uint32_t n = u32(h + i);
        if (n > hlen - i - 4)
            return -1;
        const unsigned char *field = h + i + 4;
        const unsigned char *eq = memchr(field, '=', n);
        if (eq == NULL)
            return -1;
        if (eq - field == 2 && field[0] == 'o' && field[1] == 'p')
            op = n == 4 ? field[3] : -2;
        i += 4 + n;
    }
    return op < 0 ? -1 : op;
}

/* bag_records(data, known_ops, common_op) -> (bad, others): the offset of the first record
 * whose lengths overrun the data or whose header is damaged or of an op not in `known_ops`
 * (-1 when none), and the offsets of the sound records before it whose op is not
 * `common_op` (message data), for the Python side to look at. */
static PyObject *bag_records(PyObject *self, PyObject *args)
{
    (void)self;
    Py_buffer data, known;
    int common_op;
    if (!PyArg_ParseTuple(args, "y*y*i", &data, &known, &common_op))
        return NULL;
    unsigned char ok[256] = {0};
    for (Py_ssize_t i = 0; i < known.len; i++)
        ok[((const unsigned char *)known.buf)[i]] = 1;
    PyObject *others = PyList_New(0);
    if (others == NULL)
        goto fail;
    const unsigned char *p = data.buf;
    Py_ssize_t end = data.len, pos = 0, bad = -1;
    while (pos < end) {
        if (end - pos < 8) {
            bad = pos;
            break;
        }
        uint32_t hlen = u32(p + pos);
        if ((Py_ssize_t)hlen > end - pos - 8) {
            bad = pos;
            break;
        }
        int op = bag_op(p + pos + 4, hlen);
        uint32_t dlen = u32(p + pos + 4 + hlen);
        if (op < 0 || !ok[op] || (Py_ssize_t)dlen > end - pos - 8 - (Py_ssize_t)hlen) {
            bad = pos;
            break;
        }
        if (op != common_op) {
            PyObject *at = PyLong_FromSsize_t(pos);
            if (at == NULL || PyList_Append(others, at) != 0) {
                Py_XDECREF(at);
                goto fail;
            }
            Py_DECREF(at);
        }
        pos += 8 + (Py_ssize_t)hlen + (Py_ssize_t)dlen;
    }
    PyBuffer_Release(&data);
    PyBuffer_Release(&known);
    return Py_BuildValue("(nN)", bad, others);
fail:
    Py_XDECREF(others);
    PyBuffer_Release(&data);
    PyBuffer_Release(&known);
    return NULL;
}

static PyMethodDef methods[] = {
    {"mcap_records", mcap_records, METH_VARARGS,
     "Offset of the first unsound record of an MCAP chunk's data, or -1."},
    {"bag_records", bag_records, METH_VARARGS,
     "(offset of the first unsound record of a bag chunk or -1, offsets of the other-op "
     "records before it)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    .m_base = PyModuleDef_HEAD_INIT,
    .m_name = "_cwalk",
    .m_doc = "gridmap's compiled record walks (see gridmap_cli/readers/ros/walk.py).",
    .m_size = -1,
    .m_methods = methods,
};

PyMODINIT_FUNC PyInit__cwalk(void)
{
    return PyModule_Create(&module);
}
