/* The position sensor's arithmetic per snapshot in C: SUBT, TOTAL and THRESH, and the sequence
 * decoder's running sum (agv_nodes/position_sensor/core.py, PositionSensorCore.sample and
 * _sequence_levels; agv_nodes/position_sensor/kernels.py).
 *
 * The state stays the core's own Python lists of Python ints (OLDEST's row, TOTAL, each
 * detector's held decision, the sequence sum's row and total), updated here exactly as the
 * Python code updates them, so either code can take over at any snapshot
 * (test/test_position_sensor_kernel.py). Every input is read and checked, and every result
 * made, before any list is written: bad input raises TypeError or ValueError (a zero band,
 * ZeroDivisionError, as in Python) and leaves the state as it was.
 *
 * Integers are limited to |v| <= 2**53: ADC counts and their running sums are far inside it,
 * the C sums of such values cannot overflow 64 bits, and each converts to a double exactly.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#define DETECTORS 8
#define INT_LIMIT 9007199254740992LL /* 2**53 */

/* The 8 items of a list or tuple of `what` (ints or floats); NULL with an error set if it is
 * not one or does not hold 8. */
static PyObject **eight_items(PyObject *seq, const char *name, const char *what)
{
    if (!PyList_Check(seq) && !PyTuple_Check(seq)) {
        PyErr_Format(PyExc_TypeError, "%s must be a list or tuple of %d %s, not %.100s", name,
                     DETECTORS, what, Py_TYPE(seq)->tp_name);
        return NULL;
    }
    if (PySequence_Fast_GET_SIZE(seq) != DETECTORS) {
        PyErr_Format(PyExc_ValueError, "%s must hold %d values (%zd given)", name, DETECTORS,
                     PySequence_Fast_GET_SIZE(seq));
        return NULL;
    }
    return PySequence_Fast_ITEMS(seq);
}

/* Read the 8 ints of a list or tuple (`none_ok`: None reads as -1, for a held decision). */
static int read_ints(PyObject *seq, const char *name, long long out[DETECTORS], int none_ok)
{
    PyObject **items = eight_items(seq, name, "ints");
    if (items == NULL)
        return -1;
    for (int d = 0; d < DETECTORS; d++) {
        PyObject *v = items[d];
        if (none_ok && v == Py_None) {
            out[d] = -1;
            continue;
        }
        if (!PyLong_Check(v)) {
            PyErr_Format(PyExc_TypeError, "%s[%d] must be an int%s, not %.100s", name, d,
                         none_ok ? " or None" : "", Py_TYPE(v)->tp_name);
            return -1;
        }
        int overflow;
        long long x = PyLong_AsLongLongAndOverflow(v, &overflow);
        if (x == -1 && PyErr_Occurred())
            return -1;
        if (overflow || x > INT_LIMIT || x < -INT_LIMIT) {
            PyErr_Format(PyExc_ValueError, "%s[%d] is outside +-2**53", name, d);
            return -1;
        }
        if (none_ok && x != 0 && x != 1) {
            PyErr_Format(PyExc_ValueError, "%s[%d] must be 0, 1 or None (%lld given)", name, d,
                         x);
            return -1;
        }
        out[d] = x;
    }
    return 0;
}

/* Read the 8 floats of a list or tuple. */
static int read_doubles(PyObject *seq, const char *name, double out[DETECTORS])
{
    PyObject **items = eight_items(seq, name, "floats");
    if (items == NULL)
        return -1;
    for (int d = 0; d < DETECTORS; d++) {
        if (!PyFloat_Check(items[d])) {
            PyErr_Format(PyExc_TypeError, "%s[%d] must be a float, not %.100s", name, d,
                         Py_TYPE(items[d])->tp_name);
            return -1;
        }
        out[d] = PyFloat_AS_DOUBLE(items[d]);
    }
    return 0;
}

/* A list the kernel writes to (read_ints checks it holds 8). */
static int check_state(PyObject *list, const char *name)
{
    if (!PyList_CheckExact(list)) {
        PyErr_Format(PyExc_TypeError, "%s must be a list, not %.100s", name,
                     Py_TYPE(list)->tp_name);
        return -1;
    }
    return 0;
}

/* Put new[d] in list[d] for each d, keeping the old items in `old` for the caller to release
 * once every list is written (releasing one could run code that changes a list). */
static void swap_in(PyObject *list, PyObject *new[DETECTORS], PyObject *old[DETECTORS])
{
    for (int d = 0; d < DETECTORS; d++) {
        old[d] = PyList_GET_ITEM(list, d);
        PyList_SET_ITEM(list, d, new[d]);
    }
}

static void release(PyObject *refs[], int n)
{
    for (int i = 0; i < n; i++)
        Py_DECREF(refs[i]);
}

/* Each list the kernel is about to write still holds 8: an allocation may run the garbage
 * collector, and a finalizer any code. */
static int still_eight(PyObject *const lists[], int n)
{
    for (int i = 0; i < n; i++) {
        if (PyList_GET_SIZE(lists[i]) != DETECTORS) {
            PyErr_SetString(PyExc_RuntimeError, "a state list changed size during the call");
            return -1;
        }
    }
    return 0;
}

/* The call's end: with its result made and every list still of 8, put the new items in the
 * lists (new[i] into lists[i]) and drop the old; else drop the new and the result. */
static PyObject *commit(PyObject *out, PyObject *const lists[], int n,
                        PyObject *new[][DETECTORS])
{
    PyObject *old[3][DETECTORS];
    if (out == NULL || still_eight(lists, n) < 0) {
        Py_XDECREF(out);
        release(&new[0][0], n * DETECTORS);
        return NULL;
    }
    for (int i = 0; i < n; i++)
        swap_in(lists[i], new[i], old[i]);
    release(&old[0][0], n * DETECTORS);
    return out;
}

/* Make the 8 ints, each within the limit; on failure none is kept. */
static int make_ints(const long long v[DETECTORS], const char *name, PyObject *out[DETECTORS])
{
    for (int d = 0; d < DETECTORS; d++) {
        if (v[d] > INT_LIMIT || v[d] < -INT_LIMIT) {
            PyErr_Format(PyExc_ValueError, "%s[%d] would be outside +-2**53", name, d);
            out[d] = NULL;
        } else {
            out[d] = PyLong_FromLongLong(v[d]);
        }
        if (out[d] == NULL) {
            release(out, d);
            return -1;
        }
    }
    return 0;
}

/* Python's `v >> 8`: a floor, for a negative v too. */
static long long high_byte(long long v)
{
    return v >= 0 ? v / 256 : -((-v + 255) / 256);
}

/* thresh(lit, dark, row, totals, white, black, held, as_listed, hold)
 *     -> (code, valid, decisive)
 * One snapshot's SUBT (x = lit - dark, clamped at 0), TOTAL (totals += x - row; row := x) and
 * THRESH: WHITE if TOTAL > THRON (white), BLACK if TOTAL <= THROFF (black; as_listed: their high
 * bytes only), else held's last decision when `hold`, else the snapshot is invalid. Each
 * decision shifts a bit into CODE, detector 1 first; WHITE and BLACK set held to 1 and 0. */
static PyObject *thresh(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 9) {
        PyErr_Format(PyExc_TypeError, "thresh takes 9 arguments (%zd given)", nargs);
        return NULL;
    }
    /* first, as a __bool__ could run code that changes the lists */
    int as_listed = PyObject_IsTrue(args[7]), hold = PyObject_IsTrue(args[8]);
    if (as_listed < 0 || hold < 0)
        return NULL;
    PyObject *row_list = args[2], *total_list = args[3], *held_list = args[6];
    long long lit[DETECTORS], dark[DETECTORS], row[DETECTORS], total[DETECTORS];
    long long white[DETECTORS], black[DETECTORS], held[DETECTORS];
    if (check_state(row_list, "row") < 0 || check_state(total_list, "totals") < 0
            || check_state(held_list, "held") < 0
            || read_ints(args[0], "lit", lit, 0) < 0 || read_ints(args[1], "dark", dark, 0) < 0
            || read_ints(row_list, "row", row, 0) < 0
            || read_ints(total_list, "totals", total, 0) < 0
            || read_ints(args[4], "white", white, 0) < 0
            || read_ints(args[5], "black", black, 0) < 0
            || read_ints(held_list, "held", held, 1) < 0)
        return NULL;
    long code = 0;
    int valid = 1, decisive = 1, decided[DETECTORS];
    for (int d = 0; d < DETECTORS; d++) {
        long long x = lit[d] - dark[d];
        if (x < 0)  /* SUBT clamp */
            x = 0;
        total[d] += x - row[d];
        row[d] = x;
        decided[d] = 1;
        if (total[d] > white[d]) {
            code = code << 1 | 1;
            held[d] = 1;
        } else if (as_listed ? high_byte(total[d]) <= high_byte(black[d])
                             : total[d] <= black[d]) {
            code = code << 1;
            held[d] = 0;
        } else {
            decided[d] = 0;
            if (hold && held[d] >= 0) {
                code = code << 1 | (long)held[d];  /* in the band: the last decision */
                decisive = 0;
            } else {
                valid = 0;
            }
        }
    }
    PyObject *new[3][DETECTORS];
    if (make_ints(row, "row", new[0]) < 0)
        return NULL;
    if (make_ints(total, "totals", new[1]) < 0) {
        release(new[0], DETECTORS);
        return NULL;
    }
    for (int d = 0; d < DETECTORS; d++) {  /* an undecided detector keeps its item */
        new[2][d] = decided[d] ? PyLong_FromLong((long)held[d])  /* 0 or 1: never fails */
                               : PyList_GET_ITEM(held_list, d);
        if (!decided[d])
            Py_INCREF(new[2][d]);
    }
    PyObject *out = Py_BuildValue("(lOO)", code, valid ? Py_True : Py_False,
                                  decisive ? Py_True : Py_False);
    PyObject *const lists[3] = {row_list, total_list, held_list};
    return commit(out, lists, 3, new);
}

/* levels(x, seq_row, seq_total, seq_black, seq_band) -> [8 floats]
 * The sequence decoder's running sum: seq_total += x - seq_row; seq_row := x (x's own items,
 * as Python's `row[:] = x`); each level (seq_total - seq_black) / seq_band, in band units
 * (0 THROFF, 1 THRON). */
static PyObject *levels(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 5) {
        PyErr_Format(PyExc_TypeError, "levels takes 5 arguments (%zd given)", nargs);
        return NULL;
    }
    PyObject *row_list = args[1], *total_list = args[2];
    long long x[DETECTORS], row[DETECTORS], total[DETECTORS];
    double black[DETECTORS], band[DETECTORS];
    if (check_state(row_list, "seq_row") < 0 || check_state(total_list, "seq_total") < 0
            || read_ints(args[0], "x", x, 0) < 0 || read_ints(row_list, "seq_row", row, 0) < 0
            || read_ints(total_list, "seq_total", total, 0) < 0
            || read_doubles(args[3], "seq_black", black) < 0
            || read_doubles(args[4], "seq_band", band) < 0)
        return NULL;
    for (int d = 0; d < DETECTORS; d++) {
        if (band[d] == 0.0) {  /* as Python's float division */
            PyErr_SetString(PyExc_ZeroDivisionError, "float division by zero");
            return NULL;
        }
        total[d] = total[d] + x[d] - row[d];
    }
    PyObject *new[2][DETECTORS];
    if (make_ints(total, "seq_total", new[1]) < 0)
        return NULL;
    PyObject **x_items = PySequence_Fast_ITEMS(args[0]);  /* before any allocation */
    for (int d = 0; d < DETECTORS; d++) {
        new[0][d] = x_items[d];
        Py_INCREF(new[0][d]);
    }
    PyObject *out = PyList_New(DETECTORS);
    for (int d = 0; out != NULL && d < DETECTORS; d++) {
        /* Python's (t - b) / band, t an int and b and band floats: t converted to a double
         * (exactly, |t| <= 2**53), one subtraction, one division, each rounded to a double
         * and none fused (-ffp-contract=off): the same bits as the Python code. */
        PyObject *level = PyFloat_FromDouble(((double)total[d] - black[d]) / band[d]);
        if (level == NULL)
            Py_CLEAR(out);
        else
            PyList_SET_ITEM(out, d, level);
    }
    PyObject *const lists[2] = {row_list, total_list};
    return commit(out, lists, 2, new);
}

static PyMethodDef methods[] = {
    {"thresh", (PyCFunction)(void (*)(void))thresh, METH_FASTCALL,
     "thresh(lit, dark, row, totals, white, black, held, as_listed, hold) -> (code, valid, "
     "decisive): one snapshot's SUBT, TOTAL and THRESH (PositionSensorCore.sample)."},
    {"levels", (PyCFunction)(void (*)(void))levels, METH_FASTCALL,
     "levels(x, seq_row, seq_total, seq_black, seq_band) -> 8 floats: the sequence decoder's "
     "running sum in band units (PositionSensorCore._sequence_levels)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_thresh",
    "The position sensor's arithmetic per snapshot in C (agv_nodes.position_sensor.kernels).",
    -1, methods,
};

PyMODINIT_FUNC PyInit__thresh(void)
{
    return PyModule_Create(&module);
}
