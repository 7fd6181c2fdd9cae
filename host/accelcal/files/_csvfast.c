/* accelcal.files._csvfast: a recording CSV piece's plain rows parsed into float64 columns, the
 * GIL released (files/csvpieces.py `parse`, its fast path in front of Arrow's reader).
 *
 * Only the plain form is taken: fields -?digits(.digits)? separated by ',', exactly the number of
 * columns asked for on every line, lines ending "\n" or "\r\n" (the piece's last may have none).
 * Anything else (quotes, spaces, exponents, '+', ".5", "1.", empty fields, blank lines, nan/inf,
 * another column count, more digits than the exact path takes) and the piece is not ours: parse()
 * returns None and the caller gives the piece to Arrow, whose answers and errors stay as they were.
 *
 * Values are correctly rounded, as Arrow's (fast_float) are, by Clinger's exact path: the digits
 * as an integer m < 2^53 (exact as a double) and f <= 22 digits after the point (10^f exact as a
 * double), so m / 10^f is one IEEE division, correctly rounded; the sign is applied after, so
 * "-0.000" is -0.0 as in Arrow.  Built without -ffast-math (setuptools' defaults); on x86-64 and
 * arm64 doubles are computed in double precision (no x87 excess precision). */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define MAX_COLS 64
#define MAX_DIGITS 19           /* 10^19 - 1 < 2^64: the digits cannot wrap before being counted */
#define MAX_FRACTION 22         /* 10^22 is the largest power of ten exact as a double */
#define EXACT_LIMIT (UINT64_C(1) << 53)

static const double POW10[MAX_FRACTION + 1] = {
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11,
    1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

#define NOT_PLAIN (-2)
#define NO_ROOM (-1)         /* parse() returns it as is */

/* Rows of text[0:n], which ends in '\n' (so every scan below stops at or before it: no bounds
 * checks within a line), into out[c][row0 + ...]; the number of rows, NOT_PLAIN, or NO_ROOM when
 * the columns have room for fewer rows. */
static Py_ssize_t
plain_rows(const char *text, Py_ssize_t n, int ncols, double **out, Py_ssize_t row0,
           Py_ssize_t capacity)
{
    const unsigned char *p = (const unsigned char *)text, *end = p + n;
    Py_ssize_t row = row0;
    while (p < end) {
        if (row >= capacity)
            return NO_ROOM;
        for (int c = 0; c < ncols; c++) {
            int negative = (*p == '-');
            p += negative;
            const unsigned char *first = p;
            uint64_t m = 0;
            unsigned d;
            while ((d = (unsigned)*p - '0') < 10) {
                m = m * 10 + d;
                p++;
            }
            Py_ssize_t whole = p - first;
            Py_ssize_t fraction = 0;
            if (*p == '.') {
                const unsigned char *point = ++p;
                while ((d = (unsigned)*p - '0') < 10) {
                    m = m * 10 + d;
                    p++;
                }
                fraction = p - point;
                if (fraction == 0)                  /* "1." */
                    return NOT_PLAIN;
            }
            if (whole == 0 || whole + fraction > MAX_DIGITS || fraction > MAX_FRACTION ||
                m >= EXACT_LIMIT)
                return NOT_PLAIN;
            double v = (double)m / POW10[fraction];
            out[c][row] = negative ? -v : v;
            if (c + 1 < ncols) {
                if (*p != ',')
                    return NOT_PLAIN;
                p++;
            }
        }
        if (*p == '\r')
            p++;
        if (*p != '\n')
            return NOT_PLAIN;
        p++;
        row++;
    }
    return row - row0;
}

/* The last '\n' of [p, end), or NULL (memrchr is a GNU extension); a line is short. */
static const char *
last_newline(const char *p, const char *end)
{
    while (end > p)
        if (*--end == '\n')
            return end;
    return NULL;
}

static PyObject *
csvfast_lines(PyObject *self, PyObject *arg)
{
    Py_buffer text;
    if (PyObject_GetBuffer(arg, &text, PyBUF_SIMPLE) < 0)
        return NULL;
    Py_ssize_t count = 0;
    Py_BEGIN_ALLOW_THREADS
    /* a plain loop the compiler vectorises: memchr per line costs a call every ~37 bytes */
    const unsigned char *p = text.buf;
    for (Py_ssize_t i = 0; i < text.len; i++)
        count += p[i] == '\n';
    Py_END_ALLOW_THREADS
    PyBuffer_Release(&text);
    return PyLong_FromSsize_t(count);
}

/* parse(text, skip_header, columns) -> rows, None (not plain) or -1 (no room for them all). */
static PyObject *
csvfast_parse(PyObject *self, PyObject *args)
{
    Py_buffer text;
    int skip;
    PyObject *columns;
    if (!PyArg_ParseTuple(args, "y*pO", &text, &skip, &columns))
        return NULL;
    PyObject *seq = PySequence_Fast(columns, "columns must be a sequence of float64 buffers");
    if (seq == NULL) {
        PyBuffer_Release(&text);
        return NULL;
    }
    Py_ssize_t ncols = PySequence_Fast_GET_SIZE(seq);
    Py_buffer views[MAX_COLS];
    double *out[MAX_COLS];
    Py_ssize_t held = 0, capacity = PY_SSIZE_T_MAX;
    PyObject *result = NULL;
    if (ncols < 1 || ncols > MAX_COLS) {
        PyErr_SetString(PyExc_ValueError, "between 1 and 64 columns");
        goto done;
    }
    for (; held < ncols; held++) {
        Py_buffer *v = &views[held];
        if (PyObject_GetBuffer(PySequence_Fast_GET_ITEM(seq, held), v,
                               PyBUF_WRITABLE | PyBUF_FORMAT | PyBUF_C_CONTIGUOUS) < 0)
            goto done;
        if (v->itemsize != 8 || v->format == NULL || strcmp(v->format, "d") != 0) {
            held++;
            PyErr_SetString(PyExc_TypeError, "columns must be float64 buffers");
            goto done;
        }
        out[held] = v->buf;
        if (v->len / 8 < capacity)
            capacity = v->len / 8;
    }

    Py_ssize_t rows = NOT_PLAIN;
    int no_memory = 0;
    Py_BEGIN_ALLOW_THREADS
    const char *p = text.buf, *end = p + text.len;
    int plain = 1;
    if (skip) {                 /* the header line; a quoted one may span lines: Arrow's */
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        plain = memchr(p, '"', (size_t)((nl ? nl : end) - p)) == NULL;
        p = nl ? nl + 1 : end;
    }
    if (plain) {
        /* the rows up to the last line end in place; a last line without one copied with it */
        const char *nl = last_newline(p, end);
        const char *body_end = nl ? nl + 1 : p;
        rows = plain_rows(p, body_end - p, (int)ncols, out, 0, capacity);
        if (rows >= 0 && body_end < end && end[-1] == '\r')
            rows = NOT_PLAIN;   /* a lone '\r' ends it: not a line end taken here */
        else if (rows >= 0 && body_end < end) {
            Py_ssize_t tail = end - body_end;
            char *copy = malloc((size_t)tail + 1);
            if (copy == NULL)
                no_memory = 1;
            else {
                memcpy(copy, body_end, (size_t)tail);
                copy[tail] = '\n';
                Py_ssize_t more = plain_rows(copy, tail + 1, (int)ncols, out, rows, capacity);
                rows = more < 0 ? more : rows + more;
                free(copy);
            }
        }
    }
    Py_END_ALLOW_THREADS
    if (no_memory)
        PyErr_NoMemory();
    else if (rows == NOT_PLAIN)
        result = Py_NewRef(Py_None);
    else
        result = PyLong_FromSsize_t(rows);

done:
    for (Py_ssize_t k = 0; k < held; k++)
        PyBuffer_Release(&views[k]);
    Py_DECREF(seq);
    PyBuffer_Release(&text);
    return result;
}

static PyMethodDef csvfast_methods[] = {
    {"lines", csvfast_lines, METH_O,
     "lines(text) -> the number of '\\n' in the buffer (the GIL released)."},
    {"parse", csvfast_parse, METH_VARARGS,
     "parse(text, skip_header, columns) -> rows, or None when the text is not plain CSV, or -1\n"
     "when the columns have room for fewer rows than it has (lines(text) + 1 is always enough).\n\n"
     "columns: one writable float64 buffer per column; row i of column c goes to columns[c][i].\n"
     "skip_header: skip the first line.\n"
     "Values are correctly rounded (Clinger's exact path) or the text is not taken."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef csvfast_module = {
    PyModuleDef_HEAD_INIT, "_csvfast",
    "A recording CSV piece's plain rows parsed into float64 columns, the GIL released.",
    -1, csvfast_methods};

PyMODINIT_FUNC
PyInit__csvfast(void)
{
    return PyModule_Create(&csvfast_module);
}
