/* gridmap's compiled JSON matcher (_cjson.c), a function of the _cwalk extension. */
#ifndef GRIDMAP_CJSON_H
#define GRIDMAP_CJSON_H
#include <Python.h>

PyObject *gridmap_json_compact(PyObject *self, PyObject *args);

#endif
