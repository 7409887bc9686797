/* The world's hottest loops in C: the Electruk's substeps, the guide-wire pickup's field and the
 * marker sensor's optics.
 *
 * Each function does the arithmetic of its Python original (agv_nodes/world/kernels.py names
 * them) in the same order, on IEEE doubles with no contraction into fused multiply-adds
 * (-ffp-contract=off in setup.py) and the same C library functions CPython's math module
 * calls: the results are bit for bit those of the Python code (test/test_world_kernels.py).
 * The pickup's sums over many segments are numpy's pairwise summation, as the Python code
 * sums them with numpy there.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>

#define ELECTRUK_ARGS 29

/* Python's math.hypot is CPython's own (more accurate), which differs from the C library's
 * hypot in the last bit of about one pair in five hundred: where the Python code calls it, so
 * do these (a failure leaves an exception set and returns NaN; callers check at the end). */
static PyObject *math_hypot;

static double py_hypot(double x, double y)
{
    PyObject *args[2] = {PyFloat_FromDouble(x), PyFloat_FromDouble(y)};
    PyObject *r = NULL;
    if (args[0] != NULL && args[1] != NULL)
        r = PyObject_Vectorcall(math_hypot, args, 2, NULL);
    Py_XDECREF(args[0]);
    Py_XDECREF(args[1]);
    if (r == NULL)
        return NAN;
    double out = PyFloat_AsDouble(r);
    Py_DECREF(r);
    return out;
}
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
    for (Py_ssize_t i = 0; i < n; i++) {
        /* the scalar path filters with math.hypot, numpy's with the C library's */
        double distance = scalar ? py_hypot(mx[i] - x, my[i] - y) : hypot(mx[i] - x, my[i] - y);
        if (distance - 0.5 * length[i] < reach)
            keep[k++] = i;
    }
    if (PyErr_Occurred()) {
        PyMem_Free(keep);
        PyMem_Free(terms);
        PyBuffer_Release(&view);
        return NULL;
    }
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

/* -- the marker sensor's optics (agv_nodes/world/marker_sensor.py, MarkerSensorModel._look) -- */
#define EDGE_ON (-0.2)
#define PSI_CUT 8.5

/* Python's x ** 2 is the C library's pow(x, 2.0), which differs from x * x in the last bit of
 * about one square in a thousand; the compiler would turn a pow(x, 2.0) it can see into x * x,
 * so the call goes through a pointer it cannot see through. */
static double (*volatile py_pow)(double, double) = pow;

static double psi(double z)
{
    if (z >= PSI_CUT)
        return z;
    if (z <= -PSI_CUT)
        return 0.0;
    return z * 0.5 * (1.0 + erf(z / sqrt(2.0))) + 1.0 / sqrt(2.0 * M_PI) * exp(-0.5 * z * z);
}

static double cdf(double z, double a, double b)
{
    if (z <= -b)
        return 0.0;
    if (z < -a)
        return py_pow(z + b, 2.0) / (2.0 * (b - a));
    if (z <= a)
        return (b - a) / 2.0 + (z + a);
    if (z < b)
        return (a + b) - py_pow(b - z, 2.0) / (2.0 * (b - a));
    return a + b;
}

static void ray(double ax, double ay, double fx, double fy, double x_off, double *rx, double *ry)
{
    double x = ax + fx * x_off, y = ay + fy * x_off;
    double norm = py_hypot(x, y);
    *rx = x / norm;
    *ry = y / norm;
}

/* The white runs of one card row, blurred, over the patch [lo, hi] (m along the card). */
static double row_cover(const double *runs, long n, double lo, double hi, double sigma)
{
    double cover = 0.0;
    for (long r = 0; r < n; r++) {
        double ra = runs[2 * r], rb = runs[2 * r + 1];
        if (sigma <= 0.0) {  /* max(0.0, min(b, hi) - max(a, lo)), as Python picks */
            double top = hi < rb ? hi : rb, bottom = lo > ra ? lo : ra;
            double d = top - bottom;
            cover += 0.0 < d ? d : 0.0;
            continue;
        }
        double z1 = (rb - lo) / sigma;
        if (z1 <= -PSI_CUT)
            continue;
        double z2 = (rb - hi) / sigma, z3 = (ra - lo) / sigma, z4 = (ra - hi) / sigma;
        if (z4 >= PSI_CUT)
            cover += sigma * (z1 - z2 - z3 + z4);
        else
            cover += sigma * (psi(z1) - psi(z2) - psi(z3) + psi(z4));
    }
    return cover;
}

/* marker_look(cards, optics, lx, ly, heading, height)
 * cards: float64 buffer, per card: cx, cy, nx, ny, ex, ey, card height, half card length,
 *        runs in row 1 (n1), runs in row 2 (n2), then n1 and n2 (start, end) pairs;
 * optics: float64 buffer: focus, base blur, defocus blur, aperture width, aperture height,
 *         flat height, row pitch / 2, element height, the 8 detector offsets, the indices of
 *         the outermost two.
 * -> [(detector, (illumination, white fraction)), ...] in card order */
static PyObject *marker_look(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    if (nargs != 6) {
        PyErr_Format(PyExc_TypeError, "marker_look takes 6 arguments (%zd given)", nargs);
        return NULL;
    }
    double lx = PyFloat_AsDouble(args[2]), ly = PyFloat_AsDouble(args[3]);
    double heading = PyFloat_AsDouble(args[4]), height = PyFloat_AsDouble(args[5]);
    if (PyErr_Occurred())
        return NULL;
    Py_buffer cv, ov;
    if (PyObject_GetBuffer(args[0], &cv, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0)
        return NULL;
    if (PyObject_GetBuffer(args[1], &ov, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) {
        PyBuffer_Release(&cv);
        return NULL;
    }
    PyObject *seen = NULL;
    if (cv.format == NULL || strcmp(cv.format, "d") != 0 || ov.format == NULL
            || strcmp(ov.format, "d") != 0 || ov.len != 18 * (Py_ssize_t)sizeof(double)) {
        PyErr_SetString(PyExc_TypeError, "marker_look: float64 cards and 18 optics values");
        goto done;
    }
    const double *o = (const double *)ov.buf;
    double focus = o[0], blur = o[1], defocus = o[2], width = o[3], aperture = o[4];
    double flat = o[5], up = o[6], element_height = o[7];
    const double *offsets = o + 8;
    int first = (int)o[16], last = (int)o[17];
    const double *c = (const double *)cv.buf, *end = c + cv.len / (Py_ssize_t)sizeof(double);
    seen = PyList_New(0);
    if (seen == NULL)
        goto done;
    int have_outer = 0, have_rays = 0;
    double fx = 0.0, fy = 0.0, axx = 0.0, axy = 0.0, r1x = 0.0, r1y = 0.0, r2x = 0.0, r2y = 0.0;
    double rays[8][2];
    while (c < end) {
        double cx = c[0], cy = c[1], nx = c[2], ny = c[3], ex = c[4], ey = c[5];
        double card_height = c[6], half_card = c[7];
        long n1 = (long)c[8], n2 = (long)c[9];
        const double *runs1 = c + 10, *runs2 = c + 10 + 2 * n1;
        c += 10 + 2 * (n1 + n2);
        double dx = cx - lx, dy = cy - ly;
        if (dx * dx + dy * dy > 0.36)
            continue;
        if (!have_outer) {
            fx = cos(heading);
            fy = sin(heading);
            axx = fy * focus;
            axy = -fx * focus;
            ray(axx, axy, fx, fy, offsets[first], &r1x, &r1y);
            ray(axx, axy, fx, fy, offsets[last], &r2x, &r2y);
            have_outer = 1;
        }
        double den1 = r1x * nx + r1y * ny, den2 = r2x * nx + r2y * ny;
        if (den1 <= EDGE_ON && den2 <= EDGE_ON) {
            double dn = dx * nx + dy * ny;
            double t1 = dn / den1, t2 = dn / den2;
            double u1 = (lx + t1 * r1x - cx) * ex + (ly + t1 * r1y - cy) * ey;
            double u2 = (lx + t2 * r2x - cx) * ex + (ly + t2 * r2y - cy) * ey;
            double incidence = den1 > den2 ? -den1 : -den2;
            if (0.3 > incidence)
                incidence = 0.3;
            double widest = width * (t1 > t2 ? t1 : t2) / focus / incidence;
            double reach = half_card + 0.02 + widest * (1.0 + 1e-9) + 1e-9;
            if ((u1 > reach && u2 > reach) || (u1 < -reach && u2 < -reach))
                continue;
        }
        double lift = card_height + height;
        if (!have_rays) {
            for (int d = 0; d < 8; d++)
                ray(axx, axy, fx, fy, offsets[d], &rays[d][0], &rays[d][1]);
            have_rays = 1;
        }
        for (int d = 0; d < 8; d++) {
            double rx = rays[d][0], ry = rays[d][1];
            double denom = rx * nx + ry * ny;
            if (denom > EDGE_ON)
                continue;
            double t = (dx * nx + dy * ny) / denom;
            if (!(0.05 < t && t < 0.8))
                continue;
            double u = (lx + t * rx - cx) * ex + (ly + t * ry - cy) * ey;
            double cos_inc = -denom;
            double scale = t / focus;
            double w = width * scale / (0.3 > cos_inc ? 0.3 : cos_inc);
            if (fabs(u) > half_card + w + 0.02)
                continue;
            double sigma = py_hypot(blur, defocus * (t - focus));
            double lo = u - w / 2.0, hi = u + w / 2.0;
            double v = (d < 4 ? up : -up) * scale - lift;
            double b = aperture * scale / 2.0;
            double a = flat * b;
            double middle = cdf(0.0 - v, a, b);
            double weights[2] = {(cdf(element_height - v, a, b) - middle) / (a + b),
                                 (middle - cdf(-element_height - v, a, b)) / (a + b)};
            const double *row_runs[2] = {runs1, runs2};
            long row_n[2] = {n1, n2};
            double white_cover = 0.0;
            for (int r = 0; r < 2; r++) {
                if (weights[r] <= 1e-6)
                    continue;
                double cover = row_cover(row_runs[r], row_n[r], lo, hi, sigma);
                white_cover += weights[r] * cover / w;
            }
            PyObject *item = Py_BuildValue("(i(dd))", d, py_pow(focus / t, 2.0) * cos_inc,
                                           white_cover);
            if (item == NULL || PyList_Append(seen, item) < 0) {
                Py_XDECREF(item);
                Py_CLEAR(seen);
                goto done;
            }
            Py_DECREF(item);
        }
    }
done:
    if (seen != NULL && PyErr_Occurred())
        Py_CLEAR(seen);
    PyBuffer_Release(&cv);
    PyBuffer_Release(&ov);
    return seen;
}

static PyMethodDef methods[] = {
    {"electruk_step", (PyCFunction)(void (*)(void))electruk_step, METH_FASTCALL,
     "The Electruk's substeps (agv_nodes.world.kernels.electruk_step)."},
    {"wire_lateral", (PyCFunction)(void (*)(void))wire_lateral, METH_FASTCALL,
     "The pickup's lateral field at two points (agv_nodes.world.kernels.wire_lateral)."},
    {"marker_look", (PyCFunction)(void (*)(void))marker_look, METH_FASTCALL,
     "The marker sensor's detectors that see a card (MarkerSensorModel._look)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_kernels",
    "The world's hot loops in C (agv_nodes.world.kernels).", -1, methods,
};

PyMODINIT_FUNC PyInit__kernels(void)
{
    PyObject *math = PyImport_ImportModule("math");
    if (math == NULL)
        return NULL;
    math_hypot = PyObject_GetAttrString(math, "hypot");
    Py_DECREF(math);
    if (math_hypot == NULL)
        return NULL;
    return PyModule_Create(&module);
}
