/* FMI 2.0 co-simulation binary for a pythonfmu slave class (compiled by fmu/build.py in
 * place of pythonfmu's own export library).
 *
 * Why our own: pythonfmu 0.7's library turns every Python exception into fmi2Fatal and
 * destroys the instance, so an invalid parameter value kills the simulation, and it
 * finalizes the interpreter from a library destructor, which crashes Python hosts at
 * exit. Here an exception becomes fmi2Error with its message in the log, and the
 * instance stays usable (FMI 2.0: after fmi2Error the master may reset, restore a
 * saved state, or free it). The Python side is pythonfmu's Fmi2Slave API unchanged.
 *
 * Fast path: a slave may expose `_c_real_vrs` (a tuple of value references) and
 * `_c_real_buf` (a writable float64 buffer of the same length). fmi2GetReal and
 * fmi2SetReal on those references then read and write the buffer without entering
 * Python; writes reject NaN and infinity with fmi2Error. The slave keeps the buffer
 * alive and in step with its attributes.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define NFAST 64

typedef struct {
    PyObject *cls;
    PyObject *slave;
    fmi2CallbackFunctions cb;
    char *name;
    char *resources;
    int logging;
    int visible;
    PyObject *strings; /* keeps the last fmi2GetString results alive */
    /* fast path */
    Py_buffer buf;
    int has_buf;
    fmi2ValueReference fast_vr[NFAST];
    int nfast;
} Comp;

static void emit(const fmi2CallbackFunctions *cb, const char *name, fmi2Status st, const char *cat, const char *msg)
{
    /* the message is passed as the format string (hosts such as fmpy do not format):
     * double every '%' so hosts that do format print it unchanged */
    if (!cb || !cb->logger) return;
    size_t n = strlen(msg), k = 0;
    char *esc = (char *)malloc(2 * n + 1);
    if (!esc) return;
    for (size_t i = 0; i < n; i++) {
        esc[k++] = msg[i];
        if (msg[i] == '%') esc[k++] = '%';
    }
    esc[k] = 0;
    cb->logger(cb->componentEnvironment, name ? name : "", st, cat, esc);
    free(esc);
}

static void drain_log(Comp *c)
{
    PyObject *q = PyObject_GetAttrString(c->slave, "log_queue");
    if (!q || !PyList_Check(q)) {
        Py_XDECREF(q);
        PyErr_Clear();
        return;
    }
    Py_ssize_t n = PyList_Size(q);
    for (Py_ssize_t i = 0; i < n; i++) {
        PyObject *m = PyList_GetItem(q, i);
        PyObject *st = PyObject_GetAttrString(m, "status");
        PyObject *cat = PyObject_GetAttrString(m, "category");
        PyObject *msg = PyObject_GetAttrString(m, "msg");
        PyObject *dbg = PyObject_GetAttrString(m, "debug");
        PyErr_Clear();
        long status = st ? PyLong_AsLong(st) : fmi2OK;
        PyErr_Clear();
        int debug = dbg ? PyObject_IsTrue(dbg) == 1 : 0;
        const char *cs = (cat && PyUnicode_Check(cat)) ? PyUnicode_AsUTF8(cat) : "";
        const char *ms = (msg && PyUnicode_Check(msg)) ? PyUnicode_AsUTF8(msg) : "";
        PyErr_Clear();
        if (c->logging || !debug) emit(&c->cb, c->name, (fmi2Status)status, cs ? cs : "", ms ? ms : "");
        Py_XDECREF(st);
        Py_XDECREF(cat);
        Py_XDECREF(msg);
        Py_XDECREF(dbg);
    }
    PyList_SetSlice(q, 0, n, NULL);
    Py_DECREF(q);
    PyErr_Clear();
}

/* Pass on the slave's log, then the pending Python exception as fmi2Error
 * ("where: message"), and clear it. */
static fmi2Status fail(Comp *c, const char *where)
{
    PyObject *type, *value, *tb;
    PyErr_Fetch(&type, &value, &tb); /* drain_log must not see (and clear) it */
    drain_log(c);
    PyErr_NormalizeException(&type, &value, &tb);
    const char *text = NULL;
    PyObject *s = value ? PyObject_Str(value) : NULL;
    if (s) text = PyUnicode_AsUTF8(s);
    if (!text) text = "unknown error";
    PyErr_Clear();
    size_t n = strlen(where) + strlen(text) + 4;
    char *msg = (char *)malloc(n);
    if (msg) {
        snprintf(msg, n, "%s: %s", where, text);
        emit(&c->cb, c->name, fmi2Error, "logStatusError", msg);
        free(msg);
    }
    Py_XDECREF(s);
    Py_XDECREF(type);
    Py_XDECREF(value);
    Py_XDECREF(tb);
    return fmi2Error;
}

/* The outcome of a call returning `res` (stolen), after the slave's log. */
static fmi2Status finish(Comp *c, const char *where, PyObject *res)
{
    if (!res) return fail(c, where);
    drain_log(c);
    Py_DECREF(res);
    return fmi2OK;
}

static void release_buffer(Comp *c)
{
    if (c->has_buf) PyBuffer_Release(&c->buf);
    c->has_buf = 0;
    c->nfast = 0;
}

/* Pick up the slave's fast-path buffer, if it offers one. */
static void attach_buffer(Comp *c)
{
    release_buffer(c);
    PyObject *vrs = PyObject_GetAttrString(c->slave, "_c_real_vrs");
    PyObject *buf = PyObject_GetAttrString(c->slave, "_c_real_buf");
    if (vrs && buf && PyTuple_Check(vrs) && PyTuple_Size(vrs) <= NFAST &&
        PyObject_GetBuffer(buf, &c->buf, PyBUF_WRITABLE | PyBUF_C_CONTIGUOUS) == 0) {
        if (c->buf.len == (Py_ssize_t)(PyTuple_Size(vrs) * sizeof(double))) {
            c->has_buf = 1;
            c->nfast = (int)PyTuple_Size(vrs);
            for (int i = 0; i < c->nfast; i++)
                c->fast_vr[i] = (fmi2ValueReference)PyLong_AsUnsignedLong(PyTuple_GetItem(vrs, i));
        } else {
            PyBuffer_Release(&c->buf);
        }
    }
    Py_XDECREF(vrs);
    Py_XDECREF(buf);
    PyErr_Clear();
}

static int fast_index(const Comp *c, fmi2ValueReference vr)
{
    for (int i = 0; i < c->nfast; i++)
        if (c->fast_vr[i] == vr) return i;
    return -1;
}

static PyObject *new_slave(Comp *c)
{
    PyObject *args = PyTuple_New(0);
    PyObject *kw = Py_BuildValue("{s:s,s:s,s:O}", "instance_name", c->name, "resources", c->resources, "visible",
                                 c->visible ? Py_True : Py_False);
    PyObject *slave = (args && kw) ? PyObject_Call(c->cls, args, kw) : NULL;
    Py_XDECREF(args);
    Py_XDECREF(kw);
    return slave;
}

static char *read_line(const char *dir, const char *file)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, file);
    FILE *f = fopen(path, "r");
    if (!f) return NULL;
    char line[512] = {0};
    if (!fgets(line, sizeof line, f)) line[0] = 0;
    fclose(f);
    line[strcspn(line, "\r\n")] = 0;
    return strdup(line);
}

/* file URI -> path: strip the scheme and host part, decode %XX */
static char *uri_to_path(const char *uri)
{
    const char *p = uri;
    if (strncmp(p, "file://", 7) == 0) {
        p += 7;
        if (strncmp(p, "localhost/", 10) == 0) p += 9;
    } else if (strncmp(p, "file:", 5) == 0) {
        p += 5;
    }
    char *out = (char *)malloc(strlen(p) + 1);
    size_t k = 0;
    for (size_t i = 0; p[i]; i++) {
        if (p[i] == '%' && p[i + 1] && p[i + 2]) {
            char hex[3] = {p[i + 1], p[i + 2], 0};
            out[k++] = (char)strtol(hex, NULL, 16);
            i += 2;
        } else {
            out[k++] = p[i];
        }
    }
    while (k > 1 && out[k - 1] == '/') k--;
    out[k] = 0;
    return out;
}

static void ensure_python(void)
{
    if (Py_IsInitialized()) return;
    /* a C host: make libpython's symbols global so that extension modules (NumPy)
     * resolve them, then start an interpreter that lives until the process ends (no
     * finalization: extension modules' exit handlers must not run after it) */
    Dl_info info;
    if (dladdr((void *)&Py_InitializeEx, &info) && info.dli_fname)
        dlopen(info.dli_fname, RTLD_NOW | RTLD_GLOBAL | RTLD_NOLOAD);
    Py_InitializeEx(0);
    PyEval_SaveThread();
}

#define GIL_BEGIN PyGILState_STATE gil_ = PyGILState_Ensure();
#define GIL_END PyGILState_Release(gil_);
#define COMP Comp *c = (Comp *)comp; if (!c) return fmi2Error;

/* ------------------------------------------------------------------ common functions */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean on, size_t n, const fmi2String cats[])
{
    COMP
    (void)n;
    (void)cats;
    c->logging = on ? 1 : 0;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resourceLocation,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean loggingOn)
{
    (void)guid;
    if (type != fmi2CoSimulation) {
        emit(cb, name, fmi2Error, "logStatusError", "fmi2Instantiate: this FMU supports co-simulation only");
        return NULL;
    }
    if (!resourceLocation) {
        emit(cb, name, fmi2Error, "logStatusError", "fmi2Instantiate: no fmuResourceLocation given");
        return NULL;
    }
    Comp *c = (Comp *)calloc(1, sizeof(Comp));
    if (!c) return NULL;
    c->cb = *cb;
    c->name = strdup(name ? name : "");
    c->resources = uri_to_path(resourceLocation);
    c->logging = loggingOn ? 1 : 0;
    c->visible = visible ? 1 : 0;
    char *module = read_line(c->resources, "slavemodule.txt");
    char *clsname = read_line(c->resources, "slaveclass.txt");
    if (!module || !clsname || !module[0] || !clsname[0]) {
        emit(cb, name, fmi2Error, "logStatusError",
             "fmi2Instantiate: resources/slavemodule.txt or slaveclass.txt missing (fmuResourceLocation wrong?)");
        free(module);
        free(clsname);
        free(c->name);
        free(c->resources);
        free(c);
        return NULL;
    }
    ensure_python();
    GIL_BEGIN
    PyObject *sys_path = PySys_GetObject("path"); /* borrowed */
    PyObject *dir = PyUnicode_FromString(c->resources);
    if (sys_path && dir && !PySequence_Contains(sys_path, dir)) PyList_Insert(sys_path, 0, dir);
    Py_XDECREF(dir);
    PyObject *mod = PyImport_ImportModule(module);
    if (mod) {
        c->cls = PyObject_GetAttrString(mod, clsname);
        Py_DECREF(mod);
    }
    if (c->cls) c->slave = new_slave(c);
    if (!c->slave) {
        fail(c, "fmi2Instantiate");
        Py_XDECREF(c->cls);
        GIL_END
        free(module);
        free(clsname);
        free(c->name);
        free(c->resources);
        free(c);
        return NULL;
    }
    drain_log(c);
    attach_buffer(c);
    GIL_END
    free(module);
    free(clsname);
    return (fmi2Component)c;
}

void fmi2FreeInstance(fmi2Component comp)
{
    Comp *c = (Comp *)comp;
    if (!c) return;
    GIL_BEGIN
    release_buffer(c);
    Py_XDECREF(c->slave);
    Py_XDECREF(c->cls);
    Py_XDECREF(c->strings);
    GIL_END
    free(c->name);
    free(c->resources);
    free(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean tolDefined, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDefined, fmi2Real stop)
{
    COMP
    GIL_BEGIN
    PyObject *ptol = tolDefined ? PyFloat_FromDouble(tol) : (Py_INCREF(Py_None), Py_None);
    PyObject *pstop = stopDefined ? PyFloat_FromDouble(stop) : (Py_INCREF(Py_None), Py_None);
    PyObject *r = PyObject_CallMethod(c->slave, "setup_experiment", "dOO", start, pstop, ptol);
    Py_XDECREF(ptol);
    Py_XDECREF(pstop);
    fmi2Status st = finish(c, "fmi2SetupExperiment", r);
    GIL_END
    return st;
}

static fmi2Status call0(fmi2Component comp, const char *method, const char *where)
{
    COMP
    GIL_BEGIN
    fmi2Status st = finish(c, where, PyObject_CallMethod(c->slave, method, NULL));
    GIL_END
    return st;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    return call0(c, "enter_initialization_mode", "fmi2EnterInitializationMode");
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    return call0(c, "exit_initialization_mode", "fmi2ExitInitializationMode");
}

fmi2Status fmi2Terminate(fmi2Component c) { return call0(c, "terminate", "fmi2Terminate"); }

fmi2Status fmi2Reset(fmi2Component comp)
{
    COMP
    GIL_BEGIN
    fmi2Status st = fmi2OK;
    PyObject *fresh = new_slave(c);
    if (!fresh) {
        st = fail(c, "fmi2Reset");
    } else {
        release_buffer(c);
        Py_DECREF(c->slave);
        c->slave = fresh;
        drain_log(c);
        attach_buffer(c);
    }
    GIL_END
    return st;
}

/* ------------------------------------------------------------------ variables */
static PyObject *vr_list(const fmi2ValueReference vr[], size_t n)
{
    PyObject *l = PyList_New((Py_ssize_t)n);
    for (size_t i = 0; l && i < n; i++) PyList_SET_ITEM(l, i, PyLong_FromUnsignedLong(vr[i]));
    return l;
}

/* get_<kind>(vrs) -> list; convert each item with `conv` into out[i] */
static PyObject *get_list(Comp *c, const char *method, const fmi2ValueReference vr[], size_t n)
{
    PyObject *vrs = vr_list(vr, n);
    PyObject *r = vrs ? PyObject_CallMethod(c->slave, method, "O", vrs) : NULL;
    Py_XDECREF(vrs);
    if (r && (!PySequence_Check(r) || PySequence_Size(r) != (Py_ssize_t)n)) {
        Py_DECREF(r);
        PyErr_SetString(PyExc_TypeError, "the slave returned the wrong number of values");
        return NULL;
    }
    return r;
}

fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Real value[])
{
    COMP
    if (c->has_buf) {
        const double *b = (const double *)c->buf.buf;
        size_t i = 0;
        for (; i < n; i++) {
            int k = fast_index(c, vr[i]);
            if (k < 0) break;
            value[i] = b[k];
        }
        if (i == n) return fmi2OK;
    }
    GIL_BEGIN
    PyObject *r = get_list(c, "get_real", vr, n);
    for (size_t i = 0; r && i < n; i++) {
        PyObject *it = PySequence_GetItem(r, (Py_ssize_t)i);
        value[i] = it ? PyFloat_AsDouble(it) : 0.0;
        Py_XDECREF(it);
    }
    if (r && PyErr_Occurred()) {
        Py_DECREF(r);
        r = NULL;
    }
    fmi2Status st = finish(c, "fmi2GetReal", r);
    GIL_END
    return st;
}

fmi2Status fmi2GetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Integer value[])
{
    COMP
    GIL_BEGIN
    PyObject *r = get_list(c, "get_integer", vr, n);
    for (size_t i = 0; r && i < n; i++) {
        PyObject *it = PySequence_GetItem(r, (Py_ssize_t)i);
        value[i] = it ? (fmi2Integer)PyLong_AsLong(it) : 0;
        Py_XDECREF(it);
    }
    if (r && PyErr_Occurred()) {
        Py_DECREF(r);
        r = NULL;
    }
    fmi2Status st = finish(c, "fmi2GetInteger", r);
    GIL_END
    return st;
}

fmi2Status fmi2GetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[])
{
    COMP
    GIL_BEGIN
    PyObject *r = get_list(c, "get_boolean", vr, n);
    for (size_t i = 0; r && i < n; i++) {
        PyObject *it = PySequence_GetItem(r, (Py_ssize_t)i);
        value[i] = (it && PyObject_IsTrue(it) == 1) ? fmi2True : fmi2False;
        Py_XDECREF(it);
    }
    fmi2Status st = finish(c, "fmi2GetBoolean", r);
    GIL_END
    return st;
}

fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2String value[])
{
    COMP
    GIL_BEGIN
    PyObject *r = get_list(c, "get_string", vr, n);
    PyObject *keep = r ? PyList_New((Py_ssize_t)n) : NULL;
    for (size_t i = 0; keep && i < n; i++) {
        PyObject *it = PySequence_GetItem(r, (Py_ssize_t)i);
        PyObject *b = it ? PyUnicode_AsUTF8String(it) : NULL;
        Py_XDECREF(it);
        if (!b) {
            Py_CLEAR(keep);
            break;
        }
        value[i] = PyBytes_AsString(b);
        PyList_SET_ITEM(keep, i, b);
    }
    if (r && !keep) {
        Py_DECREF(r);
        r = NULL;
    }
    if (keep) {
        Py_XDECREF(c->strings);
        c->strings = keep; /* valid until the next call, as FMI 2.0 asks */
    }
    fmi2Status st = finish(c, "fmi2GetString", r);
    GIL_END
    return st;
}

static fmi2Status set_list(Comp *c, const char *method, const char *where, const fmi2ValueReference vr[], size_t n,
                           PyObject *values)
{
    PyObject *vrs = vr_list(vr, n);
    PyObject *r = (vrs && values) ? PyObject_CallMethod(c->slave, method, "OO", vrs, values) : NULL;
    Py_XDECREF(vrs);
    Py_XDECREF(values);
    return finish(c, where, r);
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Real value[])
{
    COMP
    if (c->has_buf) {
        size_t i = 0;
        int idx[NFAST];
        for (; i < n && i < NFAST; i++) {
            idx[i] = fast_index(c, vr[i]);
            if (idx[i] < 0) break;
        }
        if (i == n) {
            for (i = 0; i < n; i++) {
                if (!isfinite(value[i])) {
                    char msg[128];
                    snprintf(msg, sizeof msg, "fmi2SetReal: value reference %u got %g, expected a finite number",
                             vr[i], value[i]);
                    emit(&c->cb, c->name, fmi2Error, "logStatusError", msg);
                    return fmi2Error;
                }
            }
            double *b = (double *)c->buf.buf;
            for (i = 0; i < n; i++) b[idx[i]] = value[i];
            return fmi2OK;
        }
    }
    GIL_BEGIN
    PyObject *vals = PyList_New((Py_ssize_t)n);
    for (size_t i = 0; vals && i < n; i++) PyList_SET_ITEM(vals, i, PyFloat_FromDouble(value[i]));
    fmi2Status st = set_list(c, "set_real", "fmi2SetReal", vr, n, vals);
    GIL_END
    return st;
}

fmi2Status fmi2SetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Integer value[])
{
    COMP
    GIL_BEGIN
    PyObject *vals = PyList_New((Py_ssize_t)n);
    for (size_t i = 0; vals && i < n; i++) PyList_SET_ITEM(vals, i, PyLong_FromLong(value[i]));
    fmi2Status st = set_list(c, "set_integer", "fmi2SetInteger", vr, n, vals);
    GIL_END
    return st;
}

fmi2Status fmi2SetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Boolean value[])
{
    COMP
    GIL_BEGIN
    PyObject *vals = PyList_New((Py_ssize_t)n);
    for (size_t i = 0; vals && i < n; i++) PyList_SET_ITEM(vals, i, PyBool_FromLong(value[i]));
    fmi2Status st = set_list(c, "set_boolean", "fmi2SetBoolean", vr, n, vals);
    GIL_END
    return st;
}

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2String value[])
{
    COMP
    GIL_BEGIN
    PyObject *vals = PyList_New((Py_ssize_t)n);
    for (size_t i = 0; vals && i < n; i++)
        PyList_SET_ITEM(vals, i, PyUnicode_DecodeUTF8(value[i] ? value[i] : "", strlen(value[i] ? value[i] : ""),
                                                      "replace"));
    fmi2Status st = set_list(c, "set_string", "fmi2SetString", vr, n, vals);
    GIL_END
    return st;
}

/* ------------------------------------------------------------------ FMU state */
fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *state)
{
    COMP
    GIL_BEGIN
    PyObject *s = PyObject_CallMethod(c->slave, "_get_fmu_state", NULL);
    fmi2Status st = fmi2OK;
    if (!s) {
        st = fail(c, "fmi2GetFMUstate");
    } else {
        drain_log(c);
        if (*state) Py_DECREF((PyObject *)*state); /* FMI 2.0: overwrite a given state */
        *state = (fmi2FMUstate)s;
    }
    GIL_END
    return st;
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate state)
{
    COMP
    if (!state) return fmi2Error;
    GIL_BEGIN
    fmi2Status st = finish(c, "fmi2SetFMUstate", PyObject_CallMethod(c->slave, "_set_fmu_state", "O", (PyObject *)state));
    GIL_END
    return st;
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *state)
{
    COMP
    if (!state || !*state) return fmi2OK;
    GIL_BEGIN
    Py_DECREF((PyObject *)*state);
    *state = NULL;
    GIL_END
    return fmi2OK;
}

static PyObject *state_bytes(Comp *c, fmi2FMUstate state)
{
    return PyObject_CallMethod(c->cls, "_fmu_state_to_bytes", "O", (PyObject *)state);
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate state, size_t *size)
{
    COMP
    GIL_BEGIN
    PyObject *b = state_bytes(c, state);
    if (b && PyBytes_Check(b)) *size = (size_t)PyBytes_Size(b);
    fmi2Status st = finish(c, "fmi2SerializedFMUstateSize", b);
    GIL_END
    return st;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate state, fmi2Byte out[], size_t size)
{
    COMP
    GIL_BEGIN
    PyObject *b = state_bytes(c, state);
    if (b && PyBytes_Check(b)) {
        if ((size_t)PyBytes_Size(b) > size) {
            Py_DECREF(b);
            b = NULL;
            PyErr_SetString(PyExc_ValueError, "buffer smaller than fmi2SerializedFMUstateSize");
        } else {
            memcpy(out, PyBytes_AsString(b), (size_t)PyBytes_Size(b));
        }
    }
    fmi2Status st = finish(c, "fmi2SerializeFMUstate", b);
    GIL_END
    return st;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte in[], size_t size, fmi2FMUstate *state)
{
    COMP
    GIL_BEGIN
    PyObject *b = PyBytes_FromStringAndSize(in, (Py_ssize_t)size);
    PyObject *s = b ? PyObject_CallMethod(c->cls, "_fmu_state_from_bytes", "O", b) : NULL;
    Py_XDECREF(b);
    fmi2Status st = fmi2OK;
    if (!s) {
        st = fail(c, "fmi2DeSerializeFMUstate");
    } else {
        drain_log(c);
        *state = (fmi2FMUstate)s;
    }
    GIL_END
    return st;
}

/* ------------------------------------------------------------------ co-simulation */
fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior)
{
    COMP
    (void)noSetPrior;
    GIL_BEGIN
    PyObject *r = PyObject_CallMethod(c->slave, "do_step", "dd", t, h);
    fmi2Status st;
    if (!r) {
        st = fail(c, "fmi2DoStep");
    } else {
        drain_log(c);
        st = PyObject_IsTrue(r) == 1 ? fmi2OK : fmi2Discard;
        Py_DECREF(r);
    }
    GIL_END
    return st;
}

fmi2Status fmi2CancelStep(fmi2Component comp)
{
    COMP
    emit(&c->cb, c->name, fmi2Error, "logStatusError", "fmi2CancelStep: doStep is synchronous, nothing to cancel");
    return fmi2Error;
}

static fmi2Status unsupported(fmi2Component comp, const char *what)
{
    COMP
    emit(&c->cb, c->name, fmi2Error, "logStatusError", what);
    return fmi2Error;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real dz[])
{
    (void)u, (void)nu, (void)z, (void)nz, (void)dv, (void)dz;
    return unsupported(c, "fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative=false)");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr, (void)n, (void)order, (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives: inputs are held constant (canInterpolateInputs=false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[])
{
    (void)vr, (void)n, (void)order, (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives: not provided (maxOutputDerivativeOrder=0)");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    (void)s, (void)value;
    return unsupported(c, "fmi2GetStatus: doStep is synchronous, no pending status");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    (void)s, (void)value;
    return unsupported(c, "fmi2GetRealStatus: doStep is synchronous, no pending status");
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    (void)s, (void)value;
    return unsupported(c, "fmi2GetIntegerStatus: doStep is synchronous, no pending status");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    (void)s, (void)value;
    return unsupported(c, "fmi2GetBooleanStatus: doStep is synchronous, no pending status");
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    (void)s, (void)value;
    return unsupported(c, "fmi2GetStringStatus: doStep is synchronous, no pending status");
}
