/*
 * Cubic Lagrange resampling onto a uniform grid: the compiled kernel of
 * rv_te_bench.core.spectrum._lagrange4_uniform (issue 23, offline analysis).
 *
 * The same IEEE operations in the same order as the numpy path of that function, so the
 * result is bit for bit the same (checked by tests/core/test_spectrum_kernel.py):
 *
 *   d1[i] = (y[i+1] - y[i]) / dx[i]            (dx[i] = x[i+1] - x[i] when dx is None)
 *   d2[i] = (d1[i+1] - d1[i]) / (x[i+2] - x[i])
 *   d3[i] = (d2[i+1] - d2[i]) / (x[i+3] - x[i])
 *   j(m)  = clip((number of nodes with x * (1/spacing) <= m) - 2, 0, n - 4)
 *   xq    = (double)m * spacing
 *   out[m] = ((((xq - x[j+2]) * d3[j] + d2[j]) * (xq - x[j+1]) + d1[j]) * (xq - x[j])) + y[j]
 *
 * (The numpy path counts nodes with min(ceil(x / spacing), n_grid) <= m; for a whole m <
 * n_grid that is the same condition.) Build with -ffp-contract=off: a fused multiply-add
 * would round differently from numpy. The loop runs without the GIL, so the spectra of an
 * offline analysis can run on a second core (core/stream.py).
 *
 * No numpy headers: the arrays come through the buffer protocol (1-D, C-contiguous,
 * float64), so the module builds with only a C compiler and Python's headers.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdlib.h>

static int
get_f64(PyObject *obj, Py_buffer *view, int writable, const char *name, Py_ssize_t *n)
{
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, view, flags) != 0) {
        return -1;
    }
    if (view->ndim != 1 || view->itemsize != 8 || view->format == NULL
            || !(view->format[0] == 'd' && view->format[1] == '\0')) {
        PyErr_Format(PyExc_TypeError, "%s must be a 1-D contiguous float64 array "
                     "(got format %s, %d dimensions)", name,
                     view->format ? view->format : "?", view->ndim);
        PyBuffer_Release(view);
        return -1;
    }
    *n = view->shape[0];
    return 0;
}

static void
resample(const double *x, const double *y, const double *dx, Py_ssize_t n,
         double spacing, Py_ssize_t n_grid, double *out, double *d1, double *d2, double *d3)
{
    const double inv = 1.0 / spacing;
    Py_ssize_t i, m, p = 0;
    for (i = 0; i < n - 1; i++) {
        d1[i] = (y[i + 1] - y[i]) / (dx != NULL ? dx[i] : x[i + 1] - x[i]);
    }
    for (i = 0; i < n - 2; i++) {
        d2[i] = (d1[i + 1] - d1[i]) / (x[i + 2] - x[i]);
    }
    for (i = 0; i < n - 3; i++) {
        d3[i] = (d2[i + 1] - d2[i]) / (x[i + 3] - x[i]);
    }
    for (m = 0; m < n_grid; m++) {
        const double mf = (double)m;
        Py_ssize_t j;
        double xq, acc;
        while (p < n && x[p] * inv <= mf) {
            p++;
        }
        j = p - 2;
        if (j < 0) {
            j = 0;
        }
        if (j > n - 4) {
            j = n - 4;
        }
        xq = mf * spacing;
        acc = xq - x[j + 2];
        acc *= d3[j];
        acc += d2[j];
        acc *= xq - x[j + 1];
        acc += d1[j];
        acc *= xq - x[j];
        out[m] = acc + y[j];
    }
}

PyDoc_STRVAR(lagrange4_uniform_doc,
"lagrange4_uniform(x, y, dx, spacing, out)\n--\n\n"
"Cubic Lagrange interpolation of (x, y) at 0, spacing, ..., (len(out) - 1) spacing into out.\n\n"
"x increases strictly from 0 (not checked here: the caller validates); dx is x's steps\n"
"(len(x) - 1 values) or None; at least 4 nodes. Bit-identical to the numpy path of\n"
"rv_te_bench.core.spectrum._lagrange4_uniform. Runs without the GIL.");

static PyObject *
lagrange4_uniform(PyObject *Py_UNUSED(module), PyObject *args)
{
    PyObject *xo, *yo, *dxo, *outo;
    double spacing;
    Py_buffer xb, yb, dxb, ob;
    Py_ssize_t n, ny, ndx = 0, n_grid;
    double *work = NULL;
    PyObject *result = NULL;
    int have_dx;

    if (!PyArg_ParseTuple(args, "OOOdO:lagrange4_uniform", &xo, &yo, &dxo, &spacing, &outo)) {
        return NULL;
    }
    have_dx = dxo != Py_None;
    if (get_f64(xo, &xb, 0, "x", &n) != 0) {
        return NULL;
    }
    if (get_f64(yo, &yb, 0, "y", &ny) != 0) {
        goto release_x;
    }
    if (have_dx && get_f64(dxo, &dxb, 0, "dx", &ndx) != 0) {
        goto release_y;
    }
    if (get_f64(outo, &ob, 1, "out", &n_grid) != 0) {
        goto release_dx;
    }
    if (n < 4 || ny != n || (have_dx && ndx < n - 1)) {
        PyErr_Format(PyExc_ValueError, "need len(x) = len(y) >= 4 and len(dx) >= len(x) - 1, "
                     "got %zd, %zd, %zd", n, ny, ndx);
        goto release_out;
    }
    if (!(spacing > 0.0)) {
        PyErr_Format(PyExc_ValueError, "spacing must be > 0, got %R", PyTuple_GET_ITEM(args, 3));
        goto release_out;
    }
    work = (double *)PyMem_RawMalloc(sizeof(double) * 3 * (size_t)n);
    if (work == NULL) {
        PyErr_NoMemory();
        goto release_out;
    }
    Py_BEGIN_ALLOW_THREADS
    resample((const double *)xb.buf, (const double *)yb.buf,
             have_dx ? (const double *)dxb.buf : NULL, n, spacing, n_grid,
             (double *)ob.buf, work, work + n, work + 2 * n);
    Py_END_ALLOW_THREADS
    PyMem_RawFree(work);
    result = Py_NewRef(Py_None);
release_out:
    PyBuffer_Release(&ob);
release_dx:
    if (have_dx) {
        PyBuffer_Release(&dxb);
    }
release_y:
    PyBuffer_Release(&yb);
release_x:
    PyBuffer_Release(&xb);
    return result;
}

static PyMethodDef methods[] = {
    {"lagrange4_uniform", lagrange4_uniform, METH_VARARGS, lagrange4_uniform_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_lagrange",
    "Compiled kernel of rv_te_bench.core.spectrum (cubic Lagrange resampling).", -1, methods,
};

PyMODINIT_FUNC
PyInit__lagrange(void)
{
    return PyModule_Create(&module);
}
