/* The world's two hottest loops in C: the Electruk's substeps and the guide-wire pickup's field.
 *
 * Each function does the arithmetic of its Python original (agv_nodes/world/kernels.py), in
 * the same order, on IEEE doubles with no contraction into fused multiply-adds
 * (-ffp-contract=off in setup.py) and the same C library functions CPython's math module
 * calls: the results are bit for bit those of the Python code (test/test_world_kernels.py).
 * The pickup's sums over many segments are numpy's pairwise summation, as the Python code
 * sums them with numpy there.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#define ELECTRUK_ARGS 29
#define PW_BLOCKSIZE 128

/* electruk_step(n, dt, field_gain, decay, m_eff, coulomb, viscous_per_speed, target, driven,
 *               v_arm, radius, gear, k_phi, resistance, limit, wheelbase, motors_k_phi,
 *               steering, demand, rate, flux, current, steer, x, y, heading, distance, v, yaw)
 * -> (flux, current, steer, x, y, heading, distance, v, yaw) */
static PyObject *electruk_step(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    double a[ELECTRUK_ARGS];
    if (nargs != ELECTRUK_ARGS) {
        PyErr_Format(PyExc_TypeError, "electruk_step takes %d arguments (%zd given)",
                     ELECTRUK_ARGS, nargs);
        return NULL;
    }
    for (Py_ssize_t i = 0; i < nargs; i++) {
        a[i] = PyFloat_AsDouble(args[i]);
        if (a[i] == -1.0 && PyErr_Occurred())
            return NULL;
    }
    long n = (long)a[0];
    double dt = a[1], field_gain = a[2], decay = a[3], m_eff = a[4], coulomb = a[5];
    double viscous_per_speed = a[6], target = a[7];
    int driven = a[8] != 0.0;
    double v_arm = a[9], radius = a[10], gear = a[11], k_phi = a[12], resistance = a[13];
    double limit = a[14], wheelbase = a[15], motors_k_phi = a[16];
    int steering = a[17] != 0.0;
    double demand = a[18], rate = a[19];
    double flux = a[20], current = a[21], steer = a[22], x = a[23], y = a[24];
    double heading = a[25], distance = a[26], v = a[27], yaw = a[28];
    double tan_of = steer, tan_steer = tan(steer);
    for (long k = 0; k < n; k++) {
        flux += (target - flux) * field_gain;
        double back_emf = k_phi * flux * (v / radius * gear);
        if (driven) {
            double i_ss = (v_arm - back_emf) / resistance;
            current = i_ss + (current - i_ss) * decay;
        } else {
            current *= decay;
        }
        if (current < 0.0)
            current = 0.0;
        if (current > limit)
            current = limit;
        if (current < 1e-6)
            current = 0.0;
        double drive_force = motors_k_phi * flux * current * gear / radius;
        int held = -coulomb <= drive_force && drive_force <= coulomb;
        double v_new;
        if (v == 0.0 && held) {
            v_new = 0.0;
        } else {
            double direction = copysign(1.0, v != 0.0 ? v : drive_force);
            v_new = v + (drive_force - direction * coulomb - viscous_per_speed * v) / m_eff * dt;
            if (v != 0.0 && held && copysign(1.0, v_new) != direction)
                v_new = 0.0;
        }
        if (steering) {
            double delta = demand - steer;
            if (delta < -rate)
                delta = -rate;
            if (delta > rate)
                delta = rate;
            steer += delta;
            if (steer != tan_of || steer == 0.0) {
                tan_of = steer;
                tan_steer = tan(steer);
            }
        }
        double v_mid = 0.5 * (v + v_new);
        yaw = v_mid * tan_steer / wheelbase;
        double h_mid = heading + 0.5 * yaw * dt;
        x += v_mid * cos(h_mid) * dt;
        y += v_mid * sin(h_mid) * dt;
        heading += yaw * dt;
        distance += v_mid * dt;
        v = v_new;
    }
    return Py_BuildValue("(ddddddddd)", flux, current, steer, x, y, heading, distance, v, yaw);
}

/* numpy's pairwise sum of n doubles (numpy/_core/src/umath/loops_utils.h.src) */
static double pairwise_sum(const double *a, Py_ssize_t n)
{
    if (n < 8) {
        double res = -0.0;
        for (Py_ssize_t i = 0; i < n; i++)
            res += a[i];
        return res;
    }
    if (n <= PW_BLOCKSIZE) {
        double r[8];
        Py_ssize_t i;
        for (int j = 0; j < 8; j++)
            r[j] = a[j];
        for (i = 8; i < n - (n % 8); i += 8)
            for (int j = 0; j < 8; j++)
                r[j] += a[i + j];
        double res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
        for (; i < n; i++)
            res += a[i];
        return res;
    }
    Py_ssize_t n2 = n / 2;
    n2 -= n2 % 8;
    return pairwise_sum(a, n2) + pairwise_sum(a + n2, n - n2);
}

/* wire_lateral(rows, x, y, lx, ly, p0x, p0y, p1x, p1y, h, reach, scalar)
 * rows: a C-contiguous float64 buffer of 8 rows (ax, ay, ux, uy, length, current, mx, my) of
 * n candidate segments each; the lateral field at the two coil points, from the segments whose
 * middle is within reach (less half their length) of (x, y).
 * scalar: the sums run segment by segment and h scales the lateral (the Python scalar path);
 * else numpy's: pairwise sums, h scaling each component. -> (left, right) */
static PyObject *wire_lateral(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 12) {
        PyErr_Format(PyExc_TypeError, "wire_lateral takes 12 arguments (%zd given)", nargs);
        return NULL;
    }
    double d[11];
    for (int i = 1; i < 12; i++) {
        d[i - 1] = PyFloat_AsDouble(args[i]);
        if (d[i - 1] == -1.0 && PyErr_Occurred())
            return NULL;
    }
    double x = d[0], y = d[1], lx = d[2], ly = d[3];
    double px_[2] = {d[4], d[6]}, py_[2] = {d[5], d[7]};
    double h = d[8], reach = d[9];
    int scalar = d[10] != 0.0;
    Py_buffer view;
    if (PyObject_GetBuffer(args[0], &view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
        return NULL;
    if (view.itemsize != sizeof(double) || view.format == NULL || strcmp(view.format, "d") != 0
            || view.len % (8 * sizeof(double)) != 0) {
        PyBuffer_Release(&view);
        PyErr_SetString(PyExc_TypeError, "wire_lateral: rows must be 8 rows of float64");
        return NULL;
    }
    const double *rows = (const double *)view.buf;
    Py_ssize_t n = view.len / (Py_ssize_t)(8 * sizeof(double));
    const double *ax = rows, *ay = rows + n, *ux = rows + 2 * n, *uy = rows + 3 * n;
    const double *length = rows + 4 * n, *cur = rows + 5 * n, *mx = rows + 6 * n;
    const double *my = rows + 7 * n;
    double h2 = h * h, four_pi = 4 * M_PI;
    double out[2];
    double *terms = NULL;
    Py_ssize_t *keep = PyMem_Malloc((n ? n : 1) * sizeof(Py_ssize_t));
    if (!scalar)
        terms = PyMem_Malloc((n ? 2 * n : 1) * sizeof(double));
    if (keep == NULL || (!scalar && terms == NULL)) {
        PyMem_Free(keep);
        PyMem_Free(terms);
        PyBuffer_Release(&view);
        return PyErr_NoMemory();
    }
    Py_ssize_t k = 0;
    for (Py_ssize_t i = 0; i < n; i++)
        if (hypot(mx[i] - x, my[i] - y) - 0.5 * length[i] < reach)
            keep[k++] = i;
    for (int p = 0; p < 2; p++) {
        double bx = 0.0, by = 0.0;
        for (Py_ssize_t j = 0; j < k; j++) {
            Py_ssize_t i = keep[j];
            double rx = px_[p] - ax[i], ry = py_[p] - ay[i];
            double along = rx * ux[i] + ry * uy[i];
            double qx = rx - along * ux[i], qy = ry - along * uy[i];
            double rho2 = qx * qx + qy * qy + h2;
            double beyond = along - length[i];
            double mag = cur[i] * (along / sqrt(along * along + rho2)
                                   - beyond / sqrt(beyond * beyond + rho2)) / (four_pi * rho2);
            if (scalar) {
                bx += mag * uy[i];
                by -= mag * ux[i];
            } else {
                terms[j] = mag * uy[i];
                terms[k + j] = mag * ux[i];
            }
        }
        if (scalar) {
            out[p] = (bx * lx + by * ly) * h;
        } else if (k == 0) {
            out[p] = 0.0 * lx + 0.0 * ly;
        } else {
            bx = (0.0 + pairwise_sum(terms, k)) * h;
            by = -(0.0 + pairwise_sum(terms + k, k)) * h;
            out[p] = bx * lx + by * ly;
        }
    }
    PyMem_Free(keep);
    PyMem_Free(terms);
    PyBuffer_Release(&view);
    return Py_BuildValue("(dd)", out[0], out[1]);
}

static PyMethodDef methods[] = {
    {"electruk_step", (PyCFunction)(void (*)(void))electruk_step, METH_FASTCALL,
     "The Electruk's substeps (agv_nodes.world.kernels.electruk_step)."},
    {"wire_lateral", (PyCFunction)(void (*)(void))wire_lateral, METH_FASTCALL,
     "The pickup's lateral field at two points (agv_nodes.world.kernels.wire_lateral)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_kernels",
    "The world's hot loops in C (agv_nodes.world.kernels).", -1, methods,
};

PyMODINIT_FUNC PyInit__kernels(void)
{
    return PyModule_Create(&module);
}
