/* The record ports' fast paths in C: seal a core's field dict into 16 bytes, check 16 bytes
 * into a field dict.
 *
 * `Port(spec)` is the C twin of the straight-line Python that records/fast_paths.py generates
 * for one schema and integrity mode (compile_port_paths): the same checks in the same order,
 * the same bytes, the same dict (keys in field order, the enum names' own str objects, ints).
 * Like that Python, seal and check return None for anything they are not sure of, and the
 * caller's general path (records/schema.py) then decides and names the error; so the choice
 * of C or Python changes only speed (test/test_record_codec_kernel.py holds the two alike).
 * records/compiled_paths.py builds the spec from the schema.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#define RECORD_LENGTH 16
#define MAX_FIELDS (8 * RECORD_LENGTH)  /* one bit each at most */

enum { KIND_INT = 0, KIND_FLAG = 1, KIND_ENUM = 2 };

typedef struct {
    PyObject *name;     /* the field's name (key of the dicts) */
    int index;          /* first byte, 0-based */
    int two;            /* two bytes, little-endian */
    int lo_bit;
    long long mask;     /* (1 << width) - 1 */
    int width;
    int kind;           /* KIND_INT, KIND_FLAG or KIND_ENUM */
    int sign;           /* s16le or twos_complement */
    long long lo, hi;   /* valid raw values (outside `special`) */
    PyObject *special;  /* frozenset of raw values also valid, or NULL */
    PyObject *codes;    /* enum: name -> code */
    PyObject *names;    /* enum: code -> name */
    int range_check;    /* unpacking can give a raw value outside lo..hi */
} FieldSpec;

typedef struct {
    PyObject_HEAD
    Py_ssize_t n;
    FieldSpec *fields;
    int e2e;            /* bytes 15-16: counter and CRC-8 */
    int protected;      /* bytes 15-16 belong to the protection (00H without e2e) */
    int crc_start;
    int xorout;
    unsigned char table[256];
    int spare_bytes;    /* bytes whose spare bits are checked */
    unsigned char spare[RECORD_LENGTH];
} Port;

static void port_dealloc(Port *self)
{
    for (Py_ssize_t k = 0; k < self->n; k++) {
        Py_XDECREF(self->fields[k].name);
        Py_XDECREF(self->fields[k].special);
        Py_XDECREF(self->fields[k].codes);
        Py_XDECREF(self->fields[k].names);
    }
    PyMem_Free(self->fields);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

/* A value of a spec tuple as a C long long (an error set on anything else). */
static long long item_ll(PyObject *tuple, Py_ssize_t i)
{
    PyObject *v = PyTuple_GET_ITEM(tuple, i);
    if (!PyLong_Check(v)) {
        PyErr_SetString(PyExc_TypeError, "Port spec: an integer expected");
        return -1;
    }
    return PyLong_AsLongLong(v);
}

static PyObject *optional(PyObject *v)
{
    if (v == Py_None)
        return NULL;
    Py_INCREF(v);
    return v;
}

/* Port((fields, e2e, protected, crc_start, xorout, table, spare)): fields a tuple of
 * (name, index, two, lo_bit, mask, width, kind, sign, lo, hi, special|None, codes|None,
 * names|None, range_check); table 256 bytes; spare a bytes of the spare masks to check. */
static PyObject *port_new(PyTypeObject *type, PyObject *args, PyObject *kwargs)
{
    PyObject *fields, *table, *spare;
    int e2e, protected, crc_start, xorout;
    if (kwargs != NULL && PyDict_GET_SIZE(kwargs)) {
        PyErr_SetString(PyExc_TypeError, "Port takes no keyword arguments");
        return NULL;
    }
    if (!PyArg_ParseTuple(args, "O!ppiiSS", &PyTuple_Type, &fields, &e2e, &protected,
                          &crc_start, &xorout, &table, &spare))
        return NULL;
    if (PyBytes_GET_SIZE(table) != 256 || PyBytes_GET_SIZE(spare) > RECORD_LENGTH) {
        PyErr_SetString(PyExc_ValueError, "Port spec: a 256-byte table, at most 16 spare masks");
        return NULL;
    }
    Port *self = (Port *)type->tp_alloc(type, 0);
    if (self == NULL)
        return NULL;
    Py_ssize_t n = PyTuple_GET_SIZE(fields);
    if (n > MAX_FIELDS) {
        PyErr_SetString(PyExc_ValueError, "Port spec: more fields than bits in a record");
        Py_DECREF(self);
        return NULL;
    }
    self->fields = PyMem_Calloc(n ? n : 1, sizeof(FieldSpec));
    if (self->fields == NULL) {
        Py_DECREF(self);
        return PyErr_NoMemory();
    }
    self->n = n;
    self->e2e = e2e;
    self->protected = protected;
    self->crc_start = crc_start & 0xFF;
    self->xorout = xorout & 0xFF;
    memcpy(self->table, PyBytes_AS_STRING(table), 256);
    self->spare_bytes = (int)PyBytes_GET_SIZE(spare);
    memcpy(self->spare, PyBytes_AS_STRING(spare), self->spare_bytes);
    for (Py_ssize_t k = 0; k < n; k++) {
        PyObject *t = PyTuple_GET_ITEM(fields, k);
        FieldSpec *f = &self->fields[k];
        if (!PyTuple_Check(t) || PyTuple_GET_SIZE(t) != 14
                || !PyUnicode_CheckExact(PyTuple_GET_ITEM(t, 0))) {
            PyErr_SetString(PyExc_TypeError, "Port spec: a field is a tuple of 14, name first");
            Py_DECREF(self);
            return NULL;
        }
        f->name = Py_NewRef(PyTuple_GET_ITEM(t, 0));
        f->index = (int)item_ll(t, 1);
        f->two = (int)item_ll(t, 2);
        f->lo_bit = (int)item_ll(t, 3);
        f->mask = item_ll(t, 4);
        f->width = (int)item_ll(t, 5);
        f->kind = (int)item_ll(t, 6);
        f->sign = (int)item_ll(t, 7);
        f->lo = item_ll(t, 8);
        f->hi = item_ll(t, 9);
        f->special = optional(PyTuple_GET_ITEM(t, 10));
        f->codes = optional(PyTuple_GET_ITEM(t, 11));
        f->names = optional(PyTuple_GET_ITEM(t, 12));
        f->range_check = (int)item_ll(t, 13);
        if (PyErr_Occurred()) {
            Py_DECREF(self);
            return NULL;
        }
        if (f->index < 0 || f->index + (f->two ? 2 : 1) > RECORD_LENGTH || f->width < 1
                || f->width > 16 || f->lo_bit < 0 || f->lo_bit + (f->two ? 0 : f->width) > 8
                || (f->kind == KIND_ENUM && (f->codes == NULL || f->names == NULL))
                || (f->special != NULL && !PyFrozenSet_Check(f->special))) {
            PyErr_Format(PyExc_ValueError, "Port spec: field %R does not fit a record", f->name);
            Py_DECREF(self);
            return NULL;
        }
    }
    return (PyObject *)self;
}

/* Is `v` (an exact int, `x` its value unless `overflow`) a value field `f` may carry? */
static int valid_raw(FieldSpec *f, PyObject *v, long long x, int overflow)
{
    if (!overflow && f->lo <= x && x <= f->hi)
        return 1;
    if (f->special == NULL)
        return 0;
    return PySet_Contains(f->special, v);  /* -1: an error is set */
}

/* seal(values, counter) -> 16 bytes, or None (records/fast_paths.py, compile_port_paths). */
static PyObject *port_seal(Port *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "seal(values, counter)");
        return NULL;
    }
    PyObject *values = args[0];
    /* a plain dict only: a Mapping's __missing__ could answer for a name not in it */
    if (!PyDict_CheckExact(values) || PyDict_GET_SIZE(values) != self->n)
        Py_RETURN_NONE;
    unsigned char out[RECORD_LENGTH] = {0};
    PyObject *given[MAX_FIELDS];  /* borrowed: no Python code runs while they are held */
    long long raw[MAX_FIELDS];
    for (Py_ssize_t k = 0; k < self->n; k++) {  /* every name first, as the Python does */
        given[k] = PyDict_GetItemWithError(values, self->fields[k].name);
        if (given[k] == NULL) {
            if (PyErr_Occurred())
                return NULL;
            Py_RETURN_NONE;
        }
    }
    for (Py_ssize_t k = 0; k < self->n; k++) {
        FieldSpec *f = &self->fields[k];
        PyObject *v = given[k];
        long long x;
        int overflow = 0;
        if (f->kind == KIND_ENUM) {
            if (!PyUnicode_CheckExact(v))
                Py_RETURN_NONE;
            PyObject *code = PyDict_GetItemWithError(f->codes, v);
            if (code == NULL) {
                if (PyErr_Occurred())
                    return NULL;
                Py_RETURN_NONE;
            }
            x = PyLong_AsLongLongAndOverflow(code, &overflow);
            if (overflow || (x == -1 && PyErr_Occurred()))
                return NULL;
        } else {
            if (f->kind == KIND_FLAG && PyBool_Check(v)) {  /* cores pass bools for flags */
                x = v == Py_True;
            } else {
                if (!PyLong_CheckExact(v))
                    Py_RETURN_NONE;
                x = PyLong_AsLongLongAndOverflow(v, &overflow);
                if (x == -1 && PyErr_Occurred())
                    return NULL;
            }
            int ok = valid_raw(f, v, x, overflow);
            if (ok < 0)
                return NULL;
            if (!ok || overflow)  /* a special value is small: an overflow is never one */
                Py_RETURN_NONE;
        }
        raw[k] = x;
    }
    for (Py_ssize_t k = 0; k < self->n; k++) {
        FieldSpec *f = &self->fields[k];
        long long x = raw[k];
        if (f->two) {  /* Python's & on a negative int: its two's complement, as here */
            out[f->index] |= (unsigned char)(x & 0xFF);
            out[f->index + 1] |= (unsigned char)((x & 0xFFFF) >> 8);
        } else {
            out[f->index] |= (unsigned char)((x & f->mask) << f->lo_bit);
        }
    }
    if (self->e2e) {
        int overflow = 0;
        if (!PyLong_Check(args[1]))  /* an int (or bool) counter, as the Python takes it */
            Py_RETURN_NONE;
        long long counter = PyLong_AsLongLongAndOverflow(args[1], &overflow);
        if (counter == -1 && PyErr_Occurred())
            return NULL;
        if (overflow || counter < 0 || counter > 255)
            Py_RETURN_NONE;
        unsigned char c = self->table[self->crc_start ^ out[0]];
        for (int i = 1; i < 14; i++)
            c = self->table[c ^ out[i]];
        out[14] = (unsigned char)counter;
        out[15] = self->table[c ^ out[14]] ^ self->xorout;
    } else if (self->protected) {
        out[14] = out[15] = 0;
    }
    return PyBytes_FromStringAndSize((const char *)out, RECORD_LENGTH);
}

/* check(data) -> the field dict, or None (records/fast_paths.py, compile_port_paths). */
static PyObject *port_check(Port *self, PyObject *data)
{
    if (!PyBytes_CheckExact(data) || PyBytes_GET_SIZE(data) != RECORD_LENGTH)
        Py_RETURN_NONE;
    const unsigned char *d = (const unsigned char *)PyBytes_AS_STRING(data);
    if (self->e2e) {
        unsigned char c = self->table[self->crc_start ^ d[0]];
        for (int i = 1; i < 15; i++)
            c = self->table[c ^ d[i]];
        if (d[15] != (c ^ self->xorout))
            Py_RETURN_NONE;
    } else if (self->protected && (d[14] || d[15])) {
        Py_RETURN_NONE;
    }
    for (int i = 0; i < self->spare_bytes; i++)
        if (d[i] & self->spare[i])
            Py_RETURN_NONE;
    PyObject *out = PyDict_New();
    if (out == NULL)
        return NULL;
    for (Py_ssize_t k = 0; k < self->n; k++) {
        FieldSpec *f = &self->fields[k];
        long long v;
        if (f->two) {
            v = d[f->index] | d[f->index + 1] << 8;
            if (f->sign && (v & 0x8000))
                v -= 0x10000;
        } else {
            v = (d[f->index] >> f->lo_bit) & f->mask;
            if (f->sign && (v >> (f->width - 1)))
                v -= 1LL << f->width;
        }
        PyObject *value = PyLong_FromLongLong(v);
        if (value == NULL)
            goto fail;
        if (f->kind == KIND_ENUM) {
            PyObject *name = PyDict_GetItemWithError(f->names, value);
            Py_DECREF(value);
            if (name == NULL) {
                if (PyErr_Occurred())
                    goto fail;
                Py_DECREF(out);
                Py_RETURN_NONE;
            }
            value = Py_NewRef(name);
        } else if (f->range_check) {
            int ok = valid_raw(f, value, v, 0);
            if (ok <= 0) {
                Py_DECREF(value);
                if (ok < 0)
                    goto fail;
                Py_DECREF(out);
                Py_RETURN_NONE;
            }
        }
        int err = PyDict_SetItem(out, f->name, value);
        Py_DECREF(value);
        if (err < 0)
            goto fail;
    }
    return out;
fail:
    Py_DECREF(out);
    return NULL;
}

static PyMethodDef port_methods[] = {
    {"seal", (PyCFunction)(void (*)(void))port_seal, METH_FASTCALL,
     "seal(values, counter) -> 16 bytes, or None for the general path to judge."},
    {"check", (PyCFunction)port_check, METH_O,
     "check(data) -> the field dict, or None for the general path to judge."},
    {NULL, NULL, 0, NULL},
};

static PyTypeObject PortType = {
    PyVarObject_HEAD_INIT(NULL, 0)
    .tp_name = "agv_nodes.records._codec.Port",
    .tp_doc = "One schema's seal and check in one integrity mode (records/compiled_paths.py).",
    .tp_basicsize = sizeof(Port),
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_new = port_new,
    .tp_dealloc = (destructor)port_dealloc,
    .tp_methods = port_methods,
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_codec",
    "The record ports' fast paths in C (agv_nodes.records.compiled_paths).", -1, NULL,
};

PyMODINIT_FUNC PyInit__codec(void)
{
    if (PyType_Ready(&PortType) < 0)
        return NULL;
    PyObject *m = PyModule_Create(&module);
    if (m == NULL)
        return NULL;
    if (PyModule_AddObjectRef(m, "Port", (PyObject *)&PortType) < 0) {
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
