/* FMI 2.0 co-simulation binary for a pythonfmu slave class (compiled by fmu/build.py in
 * place of pythonfmu's own export library). The Python side is pythonfmu's Fmi2Slave API
 * unchanged; every slave (the actuator and both companions) runs on this file.
 *
 * Why our own: pythonfmu 0.7's library turns every Python exception into fmi2Fatal and
 * destroys the instance, and it finalizes the interpreter from a library destructor,
 * which crashes Python hosts at exit.
 *
 * What this file guarantees: it never crashes its host. Every pointer from the host is
 * checked before use, every Python exception becomes fmi2Error with its message logged,
 * and the instance follows one FMI 2.0 state machine (TABLE below) kept here, in C:
 *
 * - A call REJECTED for its arguments or its state (not allowed now, a NULL array, an
 *   unknown value reference, a set on an output, a NaN, h <= 0, a time that does not
 *   continue the run, a value the slave refuses) returns fmi2Error and changes nothing:
 *   the instance stays in its state and can be used on. FMI 2.0 (section 2.1.3) lets an
 *   FMU require a reset or a restore after any fmi2Error; this is more lenient, and a
 *   master that resets or restores still works.
 * - A call that FAILS while computing (the slave raises inside do_step or terminate)
 *   puts the instance in the error state: then getters, the FMU-state functions,
 *   fmi2SetFMUstate (back to a state saved earlier), fmi2Reset and fmi2FreeInstance are
 *   accepted, as FMI 2.0 section 4.2.4's table allows in the error state.
 *
 * Fast path: a slave may expose `_c_real_vrs` (a tuple of value references) and
 * `_c_real_buf` (a writable float64 buffer of the same length, kept for the slave's
 * lifetime). fmi2GetReal / fmi2SetReal on those references read and write the buffer
 * without entering Python; the access rules are checked from per-reference flags.
 *
 * Fast steps: a slave may also expose `_c_step_buf` (a writable float64 buffer kept for
 * its lifetime) describing a step it has already computed past the current time; then
 * fmi2DoStep evaluates the outputs in C when the step ends within it (see fast_step).
 * The actuator's free stepping (land_on_communication_points = false) takes one solver
 * step across many communication points: without this every point cost a call into
 * Python (10-40 us), 2-9x the whole per-step cost of fmpy's master.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <dlfcn.h>
#include <math.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "fmi2Functions.h"
#include "fmi2_common.h"

/* The FMI version this file is compiled for: 2 (default: the FMI 2.0 binary, exporting
 * the fmi2 functions below), or 3 when fmi3_python.c includes it (its FMI 3.0 functions
 * call the ones below, and the Python side is pythonfmu3's Fmi3Slave API). The version
 * changes names only: the functions' names in messages, the state names, the Python
 * methods and variable classes read, the host's logger and the serialization's magic. */
#ifndef DFA_FMI
#define DFA_FMI 2
#endif
#if DFA_FMI == 3
#include "fmi3Functions.h"
#define FMI_NAME(n2, n3) n3
#else
#define FMI_NAME(n2, n3) n2
#endif
#define API_INSTANTIATE FMI_NAME("fmi2Instantiate", "fmi3InstantiateCoSimulation")

/* ------------------------------------------------------------------ state machine */
/* FMI 2.0.x, section 4.2.4 "State Machine of Calling Sequence from Master to Slave".
 * stepInProgress and stepCanceled are never entered: doStep is synchronous. */
enum {
    ST_INSTANTIATED = 1 << 0,
    ST_INIT = 1 << 1,
    ST_STEP_COMPLETE = 1 << 2,
    ST_STEP_FAILED = 1 << 3,
    ST_TERMINATED = 1 << 4,
    ST_ERROR = 1 << 5,
    ST_STEP_IN_PROGRESS = 1 << 6, /* never entered: only to name what the table asks */
};
#define ST_ANY (ST_INSTANTIATED | ST_INIT | ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED | ST_ERROR)
#define ST_GET (ST_INIT | ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED | ST_ERROR)
#define ST_SET (ST_INSTANTIATED | ST_INIT | ST_STEP_COMPLETE)

static const char *STATE_NAMES[] = {"instantiated", "initializationMode", FMI_NAME("stepComplete", "stepMode"),
                                    FMI_NAME("stepFailed", "stepDiscarded"), "terminated", "error",
                                    "stepInProgress"};

enum Fn {
    F_SetDebugLogging, F_SetupExperiment, F_EnterInitializationMode, F_ExitInitializationMode, F_Terminate, F_Reset,
    F_GetReal, F_GetInteger, F_GetBoolean, F_GetString, F_SetReal, F_SetInteger, F_SetBoolean, F_SetString,
    F_GetFMUstate, F_SetFMUstate, F_FreeFMUstate, F_SerializedFMUstateSize, F_SerializeFMUstate,
    F_DeSerializeFMUstate, F_GetDirectionalDerivative, F_SetRealInputDerivatives, F_GetRealOutputDerivatives,
    F_DoStep, F_CancelStep, F_GetStatus, F_GetRealStatus, F_GetIntegerStatus, F_GetBooleanStatus,
    F_GetStringStatus, NFN
};

/* The states in which each function may be called (FMI 2.0.x section 4.2.4's table;
 * fmi2SetXXX is further narrowed per variable, see set_mask). Instantiate and
 * FreeInstance, allowed in every state, have no row. */
static const struct {
    const char *name;
    unsigned allowed;
} TABLE[NFN] = {
    [F_SetDebugLogging] = {FMI_NAME("fmi2SetDebugLogging", "fmi3SetDebugLogging"), ST_ANY},
    [F_SetupExperiment] = {FMI_NAME("fmi2SetupExperiment", "fmi3EnterInitializationMode"), ST_INSTANTIATED},
    [F_EnterInitializationMode] = {FMI_NAME("fmi2EnterInitializationMode", "fmi3EnterInitializationMode"), ST_INSTANTIATED},
    [F_ExitInitializationMode] = {FMI_NAME("fmi2ExitInitializationMode", "fmi3ExitInitializationMode"), ST_INIT},
    [F_Terminate] = {FMI_NAME("fmi2Terminate", "fmi3Terminate"), ST_STEP_COMPLETE | ST_STEP_FAILED},
    [F_Reset] = {FMI_NAME("fmi2Reset", "fmi3Reset"), ST_ANY},
    [F_GetReal] = {FMI_NAME("fmi2GetReal", "fmi3GetFloat64"), ST_GET},
    [F_GetInteger] = {FMI_NAME("fmi2GetInteger", "fmi3GetInt32"), ST_GET},
    [F_GetBoolean] = {FMI_NAME("fmi2GetBoolean", "fmi3GetBoolean"), ST_GET},
    [F_GetString] = {FMI_NAME("fmi2GetString", "fmi3GetString"), ST_GET},
    [F_SetReal] = {FMI_NAME("fmi2SetReal", "fmi3SetFloat64"), ST_SET},
    [F_SetInteger] = {FMI_NAME("fmi2SetInteger", "fmi3SetInt32"), ST_SET},
    [F_SetBoolean] = {FMI_NAME("fmi2SetBoolean", "fmi3SetBoolean"), ST_SET},
    [F_SetString] = {FMI_NAME("fmi2SetString", "fmi3SetString"), ST_SET},
    [F_GetFMUstate] = {FMI_NAME("fmi2GetFMUstate", "fmi3GetFMUState"), ST_ANY},
    [F_SetFMUstate] = {FMI_NAME("fmi2SetFMUstate", "fmi3SetFMUState"), ST_ANY},
    [F_FreeFMUstate] = {FMI_NAME("fmi2FreeFMUstate", "fmi3FreeFMUState"), ST_ANY},
    [F_SerializedFMUstateSize] = {FMI_NAME("fmi2SerializedFMUstateSize", "fmi3SerializedFMUStateSize"), ST_ANY},
    [F_SerializeFMUstate] = {FMI_NAME("fmi2SerializeFMUstate", "fmi3SerializeFMUState"), ST_ANY},
    [F_DeSerializeFMUstate] = {FMI_NAME("fmi2DeSerializeFMUstate", "fmi3DeserializeFMUState"), ST_ANY},
    [F_GetDirectionalDerivative] = {FMI_NAME("fmi2GetDirectionalDerivative", "fmi3GetDirectionalDerivative"), ST_GET},
    [F_SetRealInputDerivatives] = {FMI_NAME("fmi2SetRealInputDerivatives", "fmi2SetRealInputDerivatives"), ST_SET},
    [F_GetRealOutputDerivatives] = {FMI_NAME("fmi2GetRealOutputDerivatives", "fmi3GetOutputDerivatives"),
                                    ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED | ST_ERROR},
    [F_DoStep] = {FMI_NAME("fmi2DoStep", "fmi3DoStep"), ST_STEP_COMPLETE},
    [F_CancelStep] = {FMI_NAME("fmi2CancelStep", "fmi2CancelStep"), ST_STEP_IN_PROGRESS},
    [F_GetStatus] = {FMI_NAME("fmi2GetStatus", "fmi2GetStatus"), ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED},
    [F_GetRealStatus] = {FMI_NAME("fmi2GetRealStatus", "fmi2GetRealStatus"), ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED},
    [F_GetIntegerStatus] = {FMI_NAME("fmi2GetIntegerStatus", "fmi2GetIntegerStatus"), ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED},
    [F_GetBooleanStatus] = {FMI_NAME("fmi2GetBooleanStatus", "fmi2GetBooleanStatus"), ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED},
    [F_GetStringStatus] = {FMI_NAME("fmi2GetStringStatus", "fmi2GetStringStatus"), ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED},
};

static const char *state_name(unsigned s)
{
    for (int i = 0; i < 7; i++)
        if (s == (1u << i)) return STATE_NAMES[i];
    return "unknown";
}

static void states_text(unsigned mask, char *out, size_t n)
{
    out[0] = 0;
    for (int i = 0; i < 7; i++) {
        if (!(mask & (1u << i))) continue;
        size_t k = strlen(out);
        snprintf(out + k, n - k, "%s%s", k ? ", " : "", STATE_NAMES[i]);
    }
    if (!out[0]) snprintf(out, n, "none");
}

/* ------------------------------------------------------------------ instance */
enum { K_NONE, K_REAL, K_INTEGER, K_BOOLEAN, K_STRING };
static const char *KIND_NAMES[] = {"unknown", FMI_NAME("Real", "Float64"), FMI_NAME("Integer", "Int32"), "Boolean",
                                   "String"};
#define MAX_VR 1000000u /* a larger value reference table is refused at instantiation */
#define STATE_MAGIC 0x46535441u

typedef struct {
    unsigned char kind;
    unsigned char set_mask; /* states in which fmi2SetXXX may write it */
    unsigned char fast_set; /* set_mask if it is in the fast-path buffer, else 0 */
    int fast;               /* index into the fast-path buffer, or -1 */
    double lo, hi;          /* a Real's accepted range (the variable's min/max attributes; +-inf) */
    char *name;
    const char *why;        /* why it cannot be set (in messages) */
} Var;

typedef struct Comp Comp;

typedef struct State {
    uint32_t magic;
    Comp *owner;
    PyObject *py;  /* the slave's state object */
    PyObject *ser; /* its serialization, made on demand */
    unsigned st;
    double time, start, stop;
    int stop_defined;
    struct State *next;
} State;

struct Comp {
    PyObject *cls;
    PyObject *slave;
    fmi2CallbackFunctions cb; /* FMI 2.0: the host's callbacks */
#if DFA_FMI == 3
    fmi3LogMessageCallback log3; /* FMI 3.0: the host's logger and its environment */
    fmi3InstanceEnvironment env3;
#endif
    char *name;
    char *resources;
    int logging;
    int visible;
    PyObject *strings; /* keeps the last fmi2GetString results alive */
    unsigned st;       /* state machine */
    double time, start, stop;
    int stop_defined;
    Var *vars;
    size_t nvars;
    Py_buffer buf;
    int has_buf;
    Py_buffer sbuf; /* the slave's fast-step buffer (_c_step_buf) */
    int has_sbuf;
    State *states; /* live FMU states handed out by this instance */
    Comp *next;
};

/* registry of live instances: a pointer the host passes is used only if found here.
 * The fast path must not pay for a lock: each thread remembers the last instance it
 * found, valid while no instance has been freed since (g_gen counts frees). */
static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;
static Comp *g_comps;
static unsigned long g_gen = 1;
static __thread struct {
    const void *comp;
    unsigned long gen;
} tl; /* one thread-local block: one TLS lookup */

static void registry_add(Comp *c)
{
    pthread_mutex_lock(&g_lock);
    c->next = g_comps;
    g_comps = c;
    pthread_mutex_unlock(&g_lock);
}

static int registry_remove(Comp *c)
{
    int found = 0;
    pthread_mutex_lock(&g_lock);
    for (Comp **p = &g_comps; *p; p = &(*p)->next) {
        if (*p == c) {
            *p = c->next;
            found = 1;
            __atomic_add_fetch(&g_gen, 1, __ATOMIC_RELEASE); /* every thread's remembered instance */
            break;
        }
    }
    pthread_mutex_unlock(&g_lock);
    return found;
}

static Comp *registry_find(const void *comp)
{
    if (comp && comp == tl.comp && __atomic_load_n(&g_gen, __ATOMIC_ACQUIRE) == tl.gen) return (Comp *)comp;
    Comp *c;
    pthread_mutex_lock(&g_lock);
    unsigned long gen = g_gen;
    for (c = g_comps; c && (const void *)c != comp; c = c->next) {
    }
    pthread_mutex_unlock(&g_lock);
    if (c) {
        tl.comp = c;
        tl.gen = gen;
    }
    return c;
}

/* ------------------------------------------------------------------ logging */
static const char *CATS[] = {"logAll", "logStatusWarning", "logStatusDiscard", "logStatusError", "logStatusFatal"};

/* One message to the host's logger: FMI 2.0's (which may format it: '%' escaped) or FMI
 * 3.0's (the message as it is). The statuses' values are the same in both. */
static void host_log(Comp *c, fmi2Status st, const char *cat, const char *msg)
{
#if DFA_FMI == 3
    if (c->log3) c->log3(c->env3, (fmi3Status)st, cat, msg);
#else
    log_escaped(&c->cb, c->name, st, cat, msg);
#endif
}

static fmi2Status logf_(Comp *c, fmi2Status st, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static fmi2Status logf_(Comp *c, fmi2Status st, const char *fmt, ...)
{
    char msg[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    host_log(c, st, CATS[st <= fmi2Fatal ? st : 0], msg);
    return st;
}

/* Pass on the slave's log queue; returns the highest status in it (a slave that logs a
 * warning makes the call return fmi2Warning). Works on a copy of the queue, so that
 * whatever Python runs while reading the messages cannot pull items from under us. */
static fmi2Status drain_log(Comp *c)
{
    if (!c->slave) return fmi2OK;
    fmi2Status worst = fmi2OK;
    PyObject *q = PyObject_GetAttrString(c->slave, "log_queue");
    if (!q || !PyList_Check(q)) {
        int present = q != NULL;
        Py_XDECREF(q);
        PyErr_Clear();
        if (present) logf_(c, fmi2Warning, "log queue: expected a list; messages lost");
        return present ? fmi2Warning : fmi2OK;
    }
    PyObject *items = PyList_GetSlice(q, 0, PyList_GET_SIZE(q));
    if (items) PyList_SetSlice(q, 0, PyList_GET_SIZE(items), NULL);
    Py_DECREF(q);
    PyErr_Clear();
    for (Py_ssize_t i = 0; items && i < PyList_GET_SIZE(items); i++) {
        PyObject *m = PyList_GET_ITEM(items, i);
        PyObject *st = PyObject_GetAttrString(m, "status");
        PyErr_Clear();
        long status = st ? PyLong_AsLong(st) : -1;
        PyErr_Clear();
        PyObject *dbg = PyObject_GetAttrString(m, "debug");
        PyErr_Clear();
        int debug = dbg ? PyObject_IsTrue(dbg) == 1 : 0;
        PyErr_Clear();
        PyObject *cat = PyObject_GetAttrString(m, "category");
        PyObject *msg = PyObject_GetAttrString(m, "msg");
        PyErr_Clear();
        PyObject *smsg = msg ? PyObject_Str(msg) : NULL;
        PyErr_Clear();
        const char *cs = (cat && PyUnicode_Check(cat)) ? PyUnicode_AsUTF8(cat) : NULL;
        PyErr_Clear();
        const char *ms = smsg ? PyUnicode_AsUTF8(smsg) : NULL;
        PyErr_Clear();
        if (status < fmi2OK || status > fmi2Fatal) {
            logf_(c, fmi2Warning, "log queue: message with status %ld (expected 0..4): %s", status,
                  ms ? ms : "(unreadable message)");
            status = fmi2Warning;
        } else if (c->logging || !debug) {
            host_log(c, (fmi2Status)status, cs ? cs : CATS[status], ms ? ms : "(unreadable message)");
        }
        if (status > (long)worst) worst = (fmi2Status)status;
        Py_XDECREF(st);
        Py_XDECREF(dbg);
        Py_XDECREF(cat);
        Py_XDECREF(msg);
        Py_XDECREF(smsg);
    }
    Py_XDECREF(items);
    PyErr_Clear();
    return worst;
}

/* Pass on the slave's log, then the pending Python exception as fmi2Error
 * ("where: message"), and clear it. */
static fmi2Status fail(Comp *c, const char *where)
{
    PyObject *type, *value, *tb;
    PyErr_Fetch(&type, &value, &tb); /* drain_log must not see (and clear) it */
    drain_log(c);
    PyErr_NormalizeException(&type, &value, &tb);
    PyObject *s = value ? PyObject_Str(value) : NULL;
    const char *text = s ? PyUnicode_AsUTF8(s) : NULL;
    PyErr_Clear();
    if ((!text || !text[0]) && type && PyType_Check(type)) text = ((PyTypeObject *)type)->tp_name;
    if (!text || !text[0]) text = "unknown error";
    size_t n = strlen(where) + strlen(text) + 4;
    char *msg = (char *)malloc(n);
    if (msg) {
        snprintf(msg, n, "%s: %s", where, text);
        host_log(c, fmi2Error, "logStatusError", msg);
        free(msg);
    }
    Py_XDECREF(s);
    Py_XDECREF(type);
    Py_XDECREF(value);
    Py_XDECREF(tb);
    return fmi2Error;
}

/* The outcome of a Python call returning `res` (stolen): fmi2Error if it raised, else
 * fmi2OK or fmi2Warning after the slave's log. */
static fmi2Status finish(Comp *c, const char *where, PyObject *res)
{
    if (!res) return fail(c, where);
    fmi2Status st = drain_log(c);
    Py_DECREF(res);
    return st > fmi2Warning ? fmi2Warning : st;
}

/* ------------------------------------------------------------------ entry checks */
/* The instance behind `comp` if it is live and `fn` is allowed in its state; else NULL
 * (and a log line when there is an instance to log through). */
static Comp *enter(fmi2Component comp, enum Fn fn)
{
    Comp *c = registry_find(comp);
    if (!c) return NULL; /* not an instance of this library, or freed: nothing to log through */
    if (!(c->st & TABLE[fn].allowed)) {
        char allowed[160];
        states_text(TABLE[fn].allowed, allowed, sizeof allowed);
        logf_(c, fmi2Error, "%s: not allowed in state %s (allowed in: %s)", TABLE[fn].name, state_name(c->st),
              allowed);
        return NULL;
    }
    return c;
}

#define ENTER(fn)                              \
    Comp *c = enter(comp, F_##fn);             \
    if (!c) return fmi2Error;
#define NEED(ptr, what)                                                                  \
    if (!(ptr)) return logf_(c, fmi2Error, "%s: %s is NULL", TABLE[fn_].name, what);

#define GIL_BEGIN PyGILState_STATE gil_ = PyGILState_Ensure();
#define GIL_END PyGILState_Release(gil_);

/* Every value reference known and of `kind`; with `set`, settable in the current state
 * (and, for Reals, finite). Logs the first offending reference. */
static int check_vrs(Comp *c, enum Fn fn, const fmi2ValueReference vr[], size_t n, int kind, int set,
                     const fmi2Real *reals)
{
    for (size_t i = 0; i < n; i++) {
        const Var *v = vr[i] < c->nvars ? &c->vars[vr[i]] : NULL;
        if (!v || v->kind == K_NONE) {
            logf_(c, fmi2Error, "%s: value reference %u (vr[%zu]) is not a variable of this FMU", TABLE[fn].name,
                  vr[i], i);
            return 0;
        }
        if (v->kind != kind) {
            logf_(c, fmi2Error, "%s: value reference %u (%s) is a %s variable, not %s", TABLE[fn].name, vr[i],
                  v->name, KIND_NAMES[v->kind], KIND_NAMES[kind]);
            return 0;
        }
        if (set && !(v->set_mask & c->st)) {
            char allowed[160];
            states_text(v->set_mask, allowed, sizeof allowed);
            logf_(c, fmi2Error, "%s: value reference %u (%s) cannot be set in state %s: %s (settable in: %s)",
                  TABLE[fn].name, vr[i], v->name, state_name(c->st), v->why, allowed);
            return 0;
        }
        if (reals && !isfinite(reals[i])) {
            logf_(c, fmi2Error, "%s: value reference %u (%s) got %g, expected a finite number", TABLE[fn].name,
                  vr[i], v->name, reals[i]);
            return 0;
        }
        if (reals && !(reals[i] >= v->lo && reals[i] <= v->hi)) {
            logf_(c, fmi2Error, "%s: value reference %u (%s) got %g, expected %g <= value <= %g", TABLE[fn].name,
                  vr[i], v->name, reals[i], v->lo, v->hi);
            return 0;
        }
    }
    return 1;
}

/* ------------------------------------------------------------------ slave loading */
static PyObject *enum_name(PyObject *var, const char *attr)
{
    PyObject *e = PyObject_GetAttrString(var, attr);
    if (!e) return NULL;
    if (e == Py_None) return e;
    PyObject *n = PyObject_GetAttrString(e, "name");
    Py_DECREF(e);
    return n;
}

static int name_is(PyObject *s, const char *text)
{
    return s && PyUnicode_Check(s) && PyUnicode_CompareWithASCIIString(s, text) == 0;
}

/* When a variable may be set (FMI 2.0.x section 4.2.4, the table's conditions for
 * fmi2SetXXX): instantiated: initial exact or approx, or an input (inputs carry a start
 * value); initializationMode: initial exact, or an input; stepComplete: tunable
 * parameters and inputs. Never: constants, outputs, calculated variables. */
static void set_mask(Var *v, PyObject *caus, PyObject *varia, PyObject *init)
{
    int input = name_is(caus, "input"), param = name_is(caus, "parameter");
    int exact = name_is(init, "exact") || (init == Py_None && param);
    int approx = name_is(init, "approx");
    v->set_mask = 0;
    if (name_is(varia, "constant")) {
        v->why = "it is a constant";
    } else if (name_is(caus, "output")) {
        v->why = "it is an output";
    } else if (name_is(caus, "independent")) {
        v->why = "it is the independent variable";
    } else if (!input && !exact && !approx) {
        v->why = "it is calculated";
    } else {
        if (exact || approx || input) v->set_mask |= ST_INSTANTIATED;
        if (exact || input) v->set_mask |= ST_INIT;
        if (input || (param && name_is(varia, "tunable"))) v->set_mask |= ST_STEP_COMPLETE;
        v->why = input ? "inputs are set before or between steps" : "it is a fixed parameter";
    }
}

static void free_vars(Var *vars, size_t n)
{
    for (size_t i = 0; vars && i < n; i++) free(vars[i].name);
    free(vars);
}

/* A numeric attribute of a pythonfmu variable (the slave may give a Real `min`/`max`),
 * or `dflt`. */
static double bound(PyObject *var, const char *attr, double dflt)
{
    PyObject *b = PyObject_GetAttrString(var, attr);
    double x = (b && b != Py_None) ? PyFloat_AsDouble(b) : dflt;
    Py_XDECREF(b);
    if (PyErr_Occurred() || isnan(x)) {
        PyErr_Clear();
        x = dflt;
    }
    return x;
}

/* The slave's variable table (slave.vars: value reference -> pythonfmu variable), read
 * once, so that access checks need no Python. */
static int read_vars(PyObject *slave, Var **out, size_t *nout)
{
    PyObject *mod = PyImport_ImportModule(FMI_NAME("pythonfmu.variables", "pythonfmu3.variables"));
    PyObject *vars = PyObject_GetAttrString(slave, "vars");
    PyObject *items = vars ? PyMapping_Items(vars) : NULL;
    PyObject *classes[5] = {NULL};
    static const char **cls_names = KIND_NAMES; /* the pythonfmu(3) variable classes' names */
    Var *table = NULL;
    size_t n = 0;
    int ok = mod && items != NULL;
    for (int k = 1; ok && k < 5; k++) ok = (classes[k] = PyObject_GetAttrString(mod, cls_names[k])) != NULL;
    for (Py_ssize_t i = 0; ok && i < PyList_GET_SIZE(items); i++) {
        PyObject *key = PyTuple_GetItem(PyList_GET_ITEM(items, i), 0);
        unsigned long vr = key ? PyLong_AsUnsignedLong(key) : (unsigned long)-1;
        if (PyErr_Occurred() || vr >= MAX_VR) {
            PyErr_Clear();
            PyErr_Format(PyExc_ValueError, "slave.vars: keys must be value references below %u", MAX_VR);
            ok = 0;
            break;
        }
        if (vr >= n) {
            Var *t = (Var *)realloc(table, (vr + 1) * sizeof(Var));
            if (!t) {
                PyErr_NoMemory();
                ok = 0;
                break;
            }
            memset(t + n, 0, (vr + 1 - n) * sizeof(Var));
            for (size_t k = n; k <= vr; k++) t[k].fast = -1, t[k].lo = -INFINITY, t[k].hi = INFINITY;
            table = t;
            n = vr + 1;
        }
    }
    for (Py_ssize_t i = 0; ok && i < PyList_GET_SIZE(items); i++) {
        PyObject *pair = PyList_GET_ITEM(items, i);
        unsigned long vr = PyLong_AsUnsignedLong(PyTuple_GET_ITEM(pair, 0));
        PyObject *var = PyTuple_GET_ITEM(pair, 1);
        Var *v = &table[vr];
        for (int k = 1; k < 5 && !v->kind; k++)
            if (PyObject_IsInstance(var, classes[k]) == 1) v->kind = (unsigned char)k;
        PyObject *name = PyObject_GetAttrString(var, "name");
        PyObject *caus = enum_name(var, "causality"), *varia = enum_name(var, "variability");
        PyObject *init = enum_name(var, "initial");
        const char *s = (name && PyUnicode_Check(name)) ? PyUnicode_AsUTF8(name) : NULL;
        if (!v->kind || !s || !caus || !varia || !init) {
            Py_XDECREF(name), Py_XDECREF(caus), Py_XDECREF(varia), Py_XDECREF(init);
            PyErr_Clear();
            PyErr_Format(PyExc_TypeError, "slave.vars[%lu]: not a %s %s/%s/Boolean/String variable", vr,
                         FMI_NAME("pythonfmu", "pythonfmu3"), KIND_NAMES[K_REAL], KIND_NAMES[K_INTEGER]);
            ok = 0;
            break;
        }
        v->name = strdup(s);
        v->fast = -1;
        v->lo = bound(var, "min", -INFINITY);
        v->hi = bound(var, "max", INFINITY);
        set_mask(v, caus, varia, init);
        Py_DECREF(name), Py_DECREF(caus), Py_DECREF(varia), Py_DECREF(init);
        if (!v->name) {
            PyErr_NoMemory();
            ok = 0;
        }
    }
    if (ok && !items) ok = 0;
    for (int k = 1; k < 5; k++) Py_XDECREF(classes[k]);
    Py_XDECREF(mod);
    Py_XDECREF(vars);
    Py_XDECREF(items);
    if (!ok) {
        free_vars(table, n);
        if (!PyErr_Occurred()) PyErr_SetString(PyExc_TypeError, "slave.vars: unreadable");
        return 0;
    }
    *out = table;
    *nout = n;
    return 1;
}

/* The slave's fast-path buffer, if it offers a valid one: every listed reference a
 * Real of the table, the buffer float64, C-contiguous, writable, of matching length. */
static void attach_buffer(PyObject *slave, Var *vars, size_t nvars, Py_buffer *buf, int *has_buf)
{
    *has_buf = 0;
    PyObject *vrs = PyObject_GetAttrString(slave, "_c_real_vrs");
    PyObject *obj = PyObject_GetAttrString(slave, "_c_real_buf");
    PyErr_Clear();
    if (vrs && obj && PyTuple_Check(vrs) &&
        PyObject_GetBuffer(obj, buf, PyBUF_WRITABLE | PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) == 0) {
        Py_ssize_t n = PyTuple_GET_SIZE(vrs);
        int ok = buf->itemsize == 8 && buf->format && strcmp(buf->format, "d") == 0 && buf->len == n * 8;
        for (Py_ssize_t i = 0; ok && i < n; i++) {
            unsigned long vr = PyLong_AsUnsignedLong(PyTuple_GET_ITEM(vrs, i));
            ok = !PyErr_Occurred() && vr < nvars && vars[vr].kind == K_REAL && vars[vr].fast < 0;
            if (ok) {
                vars[vr].fast = (int)i;
                vars[vr].fast_set = vars[vr].set_mask;
            }
        }
        if (ok) {
            *has_buf = 1;
        } else {
            for (size_t i = 0; i < nvars; i++) vars[i].fast = -1, vars[i].fast_set = 0;
            PyBuffer_Release(buf);
        }
    }
    Py_XDECREF(vrs);
    Py_XDECREF(obj);
    PyErr_Clear();
}

/* The slave's fast-step buffer (_c_step_buf), if it offers one: float64, C-contiguous,
 * writable, at least the header long. Its contents are checked at every use. */
static void attach_step_buffer(PyObject *slave, Py_buffer *sbuf, int *has_sbuf)
{
    *has_sbuf = 0;
    PyObject *obj = PyObject_GetAttrString(slave, "_c_step_buf");
    PyErr_Clear();
    if (obj && PyObject_GetBuffer(obj, sbuf, PyBUF_WRITABLE | PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) == 0) {
        if (sbuf->itemsize == 8 && sbuf->format && strcmp(sbuf->format, "d") == 0 && sbuf->len >= 10 * 8)
            *has_sbuf = 1;
        else
            PyBuffer_Release(sbuf);
    }
    Py_XDECREF(obj);
    PyErr_Clear();
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

/* Make `slave` (stolen) the instance's slave with its variable table and buffer; on
 * failure (Python error set) the instance keeps what it had. */
static int install_slave(Comp *c, PyObject *slave)
{
    Var *vars;
    size_t n;
    if (!read_vars(slave, &vars, &n)) {
        Py_DECREF(slave);
        return 0;
    }
    Py_buffer buf, sbuf;
    int has_buf, has_sbuf;
    attach_buffer(slave, vars, n, &buf, &has_buf);
    attach_step_buffer(slave, &sbuf, &has_sbuf);
    if (c->has_buf) PyBuffer_Release(&c->buf);
    if (c->has_sbuf) PyBuffer_Release(&c->sbuf);
    free_vars(c->vars, c->nvars);
    Py_XDECREF(c->slave);
    c->slave = slave;
    c->vars = vars;
    c->nvars = n;
    c->buf = buf;
    c->has_buf = has_buf;
    c->sbuf = sbuf;
    c->has_sbuf = has_sbuf;
    return 1;
}

/* The Python environment a C host runs the slave in: the variable DFA_FMU_PYTHON (a
 * virtual environment's folder, or a python executable), else the interpreter that
 * built the FMU (resources/python.txt). Returns a malloc'ed path of a python executable,
 * or NULL after logging why none can be used. A Python host never gets here: the slave
 * runs in the host's own interpreter and environment. */
static char *choose_python(Comp *c)
{
    const char *env = getenv("DFA_FMU_PYTHON");
    char *recorded = first_line(c->resources, "python.txt");
    const char *from = env && env[0] ? "DFA_FMU_PYTHON" : "resources/python.txt (the Python that built the FMU)";
    const char *path = env && env[0] ? env : recorded;
    if (!path || !path[0]) {
        free(recorded);
        logf_(c, fmi2Error, API_INSTANTIATE ": no Python environment: set DFA_FMU_PYTHON to a Python %d.%d "
                            "environment with the FMU's runtime dependencies (resources/RUNTIME.txt)",
              PY_MAJOR_VERSION, PY_MINOR_VERSION);
        return NULL;
    }
    char exe[PATH_MAX], cfg[PATH_MAX];
    if (!python_of(path, exe, sizeof exe, cfg, sizeof cfg)) {
        logf_(c, fmi2Error, API_INSTANTIATE ": %s names %s: no Python there; set DFA_FMU_PYTHON to a Python %d.%d "
                            "environment (a virtual environment's folder or its python) with the FMU's runtime "
                            "dependencies (resources/RUNTIME.txt)", from, exe, PY_MAJOR_VERSION, PY_MINOR_VERSION);
        free(recorded);
        return NULL;
    }
    /* a virtual environment states its Python's version: it must be this binary's */
    FILE *f = fopen(cfg, "r");
    if (f) {
        char line[512];
        int major = 0, minor = 0;
        while (fgets(line, sizeof line, f))
            if (sscanf(line, "version = %d.%d", &major, &minor) == 2 || sscanf(line, "version_info = %d.%d", &major,
                                                                                 &minor) == 2)
                break;
        fclose(f);
        if (major && (major != PY_MAJOR_VERSION || minor != PY_MINOR_VERSION)) {
            logf_(c, fmi2Error, API_INSTANTIATE ": %s names %s, a Python %d.%d environment; this FMU's binary embeds "
                                "Python %d.%d: name a Python %d.%d environment", from, path, major, minor,
                  PY_MAJOR_VERSION, PY_MINOR_VERSION, PY_MAJOR_VERSION, PY_MINOR_VERSION);
            free(recorded);
            return NULL;
        }
    }
    free(recorded);
    return strdup(exe);
}

/* A C host: start the interpreter of the chosen environment (its pyvenv.cfg makes the
 * environment's site-packages the path, as running its python would), after making
 * libpython's symbols global so that extension modules (NumPy) resolve them. It lives
 * until the process ends (no finalization: extension modules' exit handlers must not
 * run after it). Returns 0 after logging when there is no usable Python. */
static int ensure_python(Comp *c)
{
    if (Py_IsInitialized()) return 1;
    char *exe = choose_python(c);
    if (!exe) return 0;
    Dl_info info;
    if (dladdr((void *)&Py_InitializeEx, &info) && info.dli_fname)
        dlopen(info.dli_fname, RTLD_NOW | RTLD_GLOBAL | RTLD_NOLOAD);
    PyConfig config;
    PyConfig_InitPythonConfig(&config);
    config.install_signal_handlers = 0;
    config.parse_argv = 0;
    PyStatus status = PyConfig_SetBytesString(&config, &config.program_name, exe);
    if (!PyStatus_Exception(status)) status = Py_InitializeFromConfig(&config);
    PyConfig_Clear(&config);
    if (PyStatus_Exception(status)) {
        logf_(c, fmi2Error, API_INSTANTIATE ": starting Python %d.%d for %s failed: %s", PY_MAJOR_VERSION,
              PY_MINOR_VERSION, exe, status.err_msg ? status.err_msg : "unknown error");
        free(exe);
        return 0;
    }
    free(exe);
    PyEval_SaveThread();
    return 1;
}

/* ------------------------------------------------------------------ FMU states */
static State *find_state(Comp *c, const void *s)
{
    for (State *p = c->states; p; p = p->next)
        if ((const void *)p == s) return p;
    return NULL;
}

static void drop_state(Comp *c, State *s)
{
    for (State **p = &c->states; *p; p = &(*p)->next) {
        if (*p == s) {
            *p = s->next;
            break;
        }
    }
    Py_XDECREF(s->py);
    Py_XDECREF(s->ser);
    s->magic = 0;
    free(s);
}

/* ------------------------------------------------------------------ common functions */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component comp, fmi2Boolean on, size_t n, const fmi2String cats[])
{
    ENTER(SetDebugLogging)
    enum Fn fn_ = F_SetDebugLogging;
    if (n > 0) NEED(cats, "categories[]")
    for (size_t i = 0; i < n; i++)
        if (!cats[i]) return logf_(c, fmi2Error, "%s: categories[%zu] is NULL",
                                   TABLE[F_SetDebugLogging].name, i);
    c->logging = on ? 1 : 0;
    return fmi2OK;
}

static void free_comp(Comp *c)
{
    free(c->name);
    free(c->resources);
    free(c);
}

static Comp *instantiate(Comp *c);

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resourceLocation,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean loggingOn)
{
    (void)guid;
    if (type != fmi2CoSimulation) {
        log_escaped(cb, name, fmi2Error, "logStatusError", "fmi2Instantiate: this FMU supports co-simulation only");
        return NULL;
    }
    if (!resourceLocation) {
        log_escaped(cb, name, fmi2Error, "logStatusError", "fmi2Instantiate: no fmuResourceLocation given");
        return NULL;
    }
    Comp *c = (Comp *)calloc(1, sizeof(Comp));
    if (!c) return NULL;
    if (cb) c->cb = *cb; /* without callbacks the instance runs, silently */
    c->name = strdup(name ? name : "");
    c->resources = uri_to_path(resourceLocation);
    c->logging = loggingOn ? 1 : 0;
    c->visible = visible ? 1 : 0;
    if (!c->name || !c->resources) {
        log_escaped(cb, name, fmi2Error, "logStatusError", "fmi2Instantiate: out of memory");
        free_comp(c);
        return NULL;
    }
    return (fmi2Component)instantiate(c);
}

/* Make the slave of c (which has its name, resources folder, logging, visibility and the
 * host's logger): find its class (resources/slavemodule.txt, slaveclass.txt), start
 * Python if the host has none, instantiate. Returns c, registered, or NULL after logging
 * why (c freed). */
static Comp *instantiate(Comp *c)
{
    char *module = first_line(c->resources, "slavemodule.txt");
    char *clsname = first_line(c->resources, "slaveclass.txt");
    if (!module || !clsname || !module[0] || !clsname[0]) {
        logf_(c, fmi2Error, API_INSTANTIATE ": %s/slavemodule.txt or slaveclass.txt missing or empty "
                            "(fmuResourceLocation wrong?)", c->resources);
        free(module);
        free(clsname);
        free_comp(c);
        return NULL;
    }
    if (!ensure_python(c)) {
        free(module);
        free(clsname);
        free_comp(c);
        return NULL;
    }
    GIL_BEGIN
    PyObject *sys_path = PySys_GetObject("path"); /* borrowed */
    PyObject *dir = PyUnicode_FromString(c->resources);
    if (sys_path && PyList_Check(sys_path) && dir && PySequence_Contains(sys_path, dir) == 0)
        PyList_Insert(sys_path, 0, dir);
    Py_XDECREF(dir);
    PyErr_Clear();
    PyObject *mod = PyImport_ImportModule(module);
    if (mod) {
        c->cls = PyObject_GetAttrString(mod, clsname);
        Py_DECREF(mod);
    }
    PyObject *slave = c->cls ? new_slave(c) : NULL;
    int ok = slave && install_slave(c, slave);
    if (!ok) {
        fail(c, API_INSTANTIATE); /* c->slave is NULL: drain_log skips the queue */
        Py_XDECREF(c->cls);
    } else {
        drain_log(c);
    }
    GIL_END
    free(module);
    free(clsname);
    if (!ok) {
        free_comp(c);
        return NULL;
    }
    c->st = ST_INSTANTIATED;
    registry_add(c);
    return c;
}

void fmi2FreeInstance(fmi2Component comp)
{
    Comp *c = (Comp *)comp;
    if (!c || !registry_remove(c)) return; /* unknown or already freed: nothing to do */
    GIL_BEGIN
    while (c->states) drop_state(c, c->states);
    if (c->has_buf) PyBuffer_Release(&c->buf);
    if (c->has_sbuf) PyBuffer_Release(&c->sbuf);
    Py_XDECREF(c->slave);
    Py_XDECREF(c->cls);
    Py_XDECREF(c->strings);
    GIL_END
    free_vars(c->vars, c->nvars);
    free_comp(c);
}

fmi2Status fmi2SetupExperiment(fmi2Component comp, fmi2Boolean tolDefined, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDefined, fmi2Real stop)
{
    ENTER(SetupExperiment)
    if (tolDefined && !(isfinite(tol) && tol > 0))
        return logf_(c, fmi2Error, "%s: tolerance = %g, expected a finite number > 0", TABLE[F_SetupExperiment].name,
                     tol);
    if (!isfinite(start))
        return logf_(c, fmi2Error, "%s: startTime = %g, expected a finite time", TABLE[F_SetupExperiment].name, start);
    if (stopDefined && !(isfinite(stop) && stop >= start))
        return logf_(c, fmi2Error, "%s: stopTime = %g, expected a finite time >= startTime = %g",
                     TABLE[F_SetupExperiment].name, stop, start);
    GIL_BEGIN
    PyObject *ptol = tolDefined ? PyFloat_FromDouble(tol) : (Py_INCREF(Py_None), Py_None);
    PyObject *pstop = stopDefined ? PyFloat_FromDouble(stop) : (Py_INCREF(Py_None), Py_None);
    PyObject *r = (ptol && pstop) ? PyObject_CallMethod(c->slave, "setup_experiment", "dOO", start, pstop, ptol) : NULL;
    Py_XDECREF(ptol);
    Py_XDECREF(pstop);
    fmi2Status st = finish(c, TABLE[F_SetupExperiment].name, r);
    GIL_END
    if (st <= fmi2Warning) {
        c->start = c->time = start;
        c->stop = stop;
        c->stop_defined = stopDefined ? 1 : 0;
    }
    return st;
}

/* A mode change: the slave's method, then the new state. If the slave raises, the
 * state becomes `on_raise` (0: unchanged; the slave's method must then leave its
 * object as it was, as the actuator's do). */
static fmi2Status transition(fmi2Component comp, enum Fn fn, const char *method, unsigned next, unsigned on_raise)
{
    Comp *c = enter(comp, fn);
    if (!c) return fmi2Error;
    GIL_BEGIN
    fmi2Status st = finish(c, TABLE[fn].name, PyObject_CallMethod(c->slave, method, NULL));
    GIL_END
    if (st <= fmi2Warning) c->st = next;
    else if (on_raise) c->st = on_raise;
    return st;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component comp)
{
    return transition(comp, F_EnterInitializationMode, "enter_initialization_mode", ST_INIT, 0);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component comp)
{
    return transition(comp, F_ExitInitializationMode, "exit_initialization_mode", ST_STEP_COMPLETE, 0);
}

fmi2Status fmi2Terminate(fmi2Component comp)
{
    return transition(comp, F_Terminate, "terminate", ST_TERMINATED, ST_ERROR);
}

fmi2Status fmi2Reset(fmi2Component comp)
{
    ENTER(Reset)
    GIL_BEGIN
    fmi2Status st = fmi2OK;
    PyObject *fresh = new_slave(c);
    PyObject *old = c->slave;
    Py_XINCREF(old);
    if (!fresh || !install_slave(c, fresh)) {
        st = fail(c, TABLE[F_Reset].name);
    } else {
        st = drain_log(c);
        Py_CLEAR(c->strings);
    }
    Py_XDECREF(old);
    GIL_END
    if (st > fmi2Warning) return st;
    c->st = ST_INSTANTIATED;
    c->time = c->start = c->stop = 0.0;
    c->stop_defined = 0;
    return st;
}

/* ------------------------------------------------------------------ variables */
static PyObject *vr_list(const fmi2ValueReference vr[], size_t n)
{
    PyObject *l = PyList_New((Py_ssize_t)n);
    for (size_t i = 0; l && i < n; i++) {
        PyObject *x = PyLong_FromUnsignedLong(vr[i]);
        if (!x) {
            Py_CLEAR(l);
            break;
        }
        PyList_SET_ITEM(l, i, x);
    }
    return l;
}

static const char *GETTERS[] = {NULL, FMI_NAME("get_real", "get_float64"), FMI_NAME("get_integer", "get_int32"),
                                "get_boolean", "get_string"};
static const char *SETTERS[] = {NULL, FMI_NAME("set_real", "set_float64"), FMI_NAME("set_integer", "set_int32"),
                                "set_boolean", "set_string"};

/* get_<kind>(vrs) as a list or tuple of exactly n items (new reference), else NULL
 * with a Python error set */
static PyObject *py_get(Comp *c, int kind, const fmi2ValueReference vr[], size_t n)
{
    PyObject *vrs = vr_list(vr, n);
    PyObject *r = vrs ? PyObject_CallMethod(c->slave, GETTERS[kind], "O", vrs) : NULL;
    Py_XDECREF(vrs);
    if (!r) return NULL;
    PyObject *seq = PySequence_Fast(r, "");
    Py_DECREF(r);
    if (!seq || PySequence_Fast_GET_SIZE(seq) != (Py_ssize_t)n) {
        Py_XDECREF(seq);
        PyErr_Clear();
        PyErr_Format(PyExc_TypeError, "slave.%s returned %s, expected a list of %zu values", GETTERS[kind],
                     seq ? "a list of another length" : "no list", n);
        return NULL;
    }
    return seq;
}

/* Convert item i of a getter's result into out (a C array of the kind's type). */
static int convert(int kind, PyObject *it, void *out, size_t i, PyObject *keep)
{
    switch (kind) {
    case K_REAL: {
        if (!PyFloat_Check(it) && !PyLong_Check(it) && !PyNumber_Check(it)) break;
        double x = PyFloat_AsDouble(it);
        if (x == -1.0 && PyErr_Occurred()) return 0;
        ((fmi2Real *)out)[i] = x;
        return 1;
    }
    case K_INTEGER: {
        if (PyBool_Check(it) || PyFloat_Check(it)) break;
        long x = PyLong_AsLong(it);
        if (x == -1 && PyErr_Occurred()) return 0;
        if (x < INT32_MIN || x > INT32_MAX) {
            PyErr_Format(PyExc_OverflowError, "value %ld does not fit a 32-bit fmi2Integer", x);
            return 0;
        }
        ((fmi2Integer *)out)[i] = (fmi2Integer)x;
        return 1;
    }
    case K_BOOLEAN:
        if (!PyBool_Check(it)) break;
        ((fmi2Boolean *)out)[i] = it == Py_True ? fmi2True : fmi2False;
        return 1;
    case K_STRING: {
        if (!PyUnicode_Check(it)) break;
        PyObject *b = PyUnicode_AsUTF8String(it);
        if (!b) return 0;
        PyList_SET_ITEM(keep, i, b);
        ((fmi2String *)out)[i] = PyBytes_AS_STRING(b);
        return 1;
    }
    }
    PyErr_Format(PyExc_TypeError, "value %zu is a %s, expected a %s", i, Py_TYPE(it)->tp_name, KIND_NAMES[kind]);
    return 0;
}

static fmi2Status get_values(fmi2Component comp, enum Fn fn, int kind, const fmi2ValueReference vr[], size_t n,
                             void *value)
{
    Comp *c = enter(comp, fn);
    if (!c) return fmi2Error;
    enum Fn fn_ = fn;
    if (n == 0) return fmi2OK;
    NEED(vr, "vr[]")
    NEED(value, "value[]")
    if (kind == K_REAL && c->has_buf) { /* fast path: every reference a buffered Real */
        const double *b = (const double *)c->buf.buf;
        size_t i = 0;
        for (; i < n && vr[i] < c->nvars && c->vars[vr[i]].fast >= 0; i++)
            ((fmi2Real *)value)[i] = b[c->vars[vr[i]].fast];
        if (i == n) return fmi2OK;
    }
    if (!check_vrs(c, fn, vr, n, kind, 0, NULL)) return fmi2Error;
    GIL_BEGIN
    PyObject *r = py_get(c, kind, vr, n);
    PyObject *keep = (r && kind == K_STRING) ? PyList_New((Py_ssize_t)n) : NULL;
    int ok = r && (kind != K_STRING || keep);
    for (size_t i = 0; ok && i < n; i++) ok = convert(kind, PySequence_Fast_GET_ITEM(r, i), value, i, keep);
    if (ok && keep) {
        Py_XDECREF(c->strings);
        c->strings = keep; /* valid until the next call, as FMI 2.0 asks */
        keep = NULL;
    }
    Py_XDECREF(keep);
    if (!ok) Py_CLEAR(r);
    fmi2Status st = finish(c, TABLE[fn].name, r);
    GIL_END
    return st;
}

fmi2Status fmi2GetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Real value[])
{
    return get_values(comp, F_GetReal, K_REAL, vr, n, value);
}

fmi2Status fmi2GetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Integer value[])
{
    return get_values(comp, F_GetInteger, K_INTEGER, vr, n, value);
}

fmi2Status fmi2GetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2Boolean value[])
{
    return get_values(comp, F_GetBoolean, K_BOOLEAN, vr, n, value);
}

fmi2Status fmi2GetString(fmi2Component comp, const fmi2ValueReference vr[], size_t n, fmi2String value[])
{
    return get_values(comp, F_GetString, K_STRING, vr, n, value);
}

static PyObject *py_values(int kind, const void *value, size_t n)
{
    PyObject *l = PyList_New((Py_ssize_t)n);
    for (size_t i = 0; l && i < n; i++) {
        PyObject *x = NULL;
        switch (kind) {
        case K_REAL: x = PyFloat_FromDouble(((const fmi2Real *)value)[i]); break;
        case K_INTEGER: x = PyLong_FromLong(((const fmi2Integer *)value)[i]); break;
        case K_BOOLEAN: x = PyBool_FromLong(((const fmi2Boolean *)value)[i] != fmi2False); break;
        case K_STRING: {
            const char *s = ((const fmi2String *)value)[i];
            x = PyUnicode_DecodeUTF8(s, (Py_ssize_t)strlen(s), "strict");
            break;
        }
        }
        if (!x) {
            Py_CLEAR(l);
            break;
        }
        PyList_SET_ITEM(l, i, x);
    }
    return l;
}

/* set_<kind>(vrs, values) through Python, all or nothing: pythonfmu sets one variable
 * after the other, so when one is refused, the ones before it are set back to the
 * values read before the call. If that fails too, the slave is in an unknown state:
 * the instance goes to the error state. */
static fmi2Status py_set(Comp *c, enum Fn fn, int kind, const fmi2ValueReference vr[], size_t n, const void *value)
{
    const char *where = TABLE[fn].name;
    PyObject *vrs = vr_list(vr, n);
    PyObject *vals = vrs ? py_values(kind, value, n) : NULL;
    if (!vals) {
        Py_XDECREF(vrs);
        return fail(c, where);
    }
    PyObject *old = py_get(c, kind, vr, n);
    if (!old) {
        Py_DECREF(vrs);
        Py_DECREF(vals);
        return fail(c, where); /* nothing was set */
    }
    PyObject *r = PyObject_CallMethod(c->slave, SETTERS[kind], "OO", vrs, vals);
    if (!r) {
        PyObject *type, *val, *tb;
        PyErr_Fetch(&type, &val, &tb);
        PyObject *now = py_get(c, kind, vr, n);
        int same = now && PyObject_RichCompareBool(now, old, Py_EQ) == 1;
        PyObject *undo = same ? (Py_INCREF(Py_None), Py_None)
                              : PyObject_CallMethod(c->slave, SETTERS[kind], "OO", vrs, old);
        Py_XDECREF(now);
        PyErr_Clear();
        if (!undo) {
            c->st = ST_ERROR;
            logf_(c, fmi2Error, "%s: the values set before the refused one could not be set back; the instance is "
                                "now in the error state (restore a saved state or reset)", where);
        }
        Py_XDECREF(undo);
        PyErr_Restore(type, val, tb);
    }
    Py_DECREF(vrs);
    Py_DECREF(vals);
    Py_DECREF(old);
    return finish(c, where, r);
}

static fmi2Status set_values(fmi2Component comp, enum Fn fn, int kind, const fmi2ValueReference vr[], size_t n,
                             const void *value)
{
    Comp *c = enter(comp, fn);
    if (!c) return fmi2Error;
    enum Fn fn_ = fn;
    if (n == 0) return fmi2OK;
    NEED(vr, "vr[]")
    NEED(value, "value[]")
    if (kind == K_REAL && c->has_buf) { /* fast path: buffered Reals, settable now, finite, in range */
        const fmi2Real *x = (const fmi2Real *)value;
        size_t i = 0;
        for (; i < n && vr[i] < c->nvars && (c->vars[vr[i]].fast_set & c->st) && isfinite(x[i]) &&
               x[i] >= c->vars[vr[i]].lo && x[i] <= c->vars[vr[i]].hi; i++) {
        }
        if (i == n) {
            double *b = (double *)c->buf.buf;
            for (i = 0; i < n; i++) b[c->vars[vr[i]].fast] = x[i];
            return fmi2OK;
        }
    }
    if (!check_vrs(c, fn, vr, n, kind, 1, kind == K_REAL ? (const fmi2Real *)value : NULL)) return fmi2Error;
    if (kind == K_STRING) {
        for (size_t i = 0; i < n; i++)
            if (!((const fmi2String *)value)[i])
                return logf_(c, fmi2Error, "%s: value[%zu] (value reference %u) is NULL",
                             TABLE[F_SetString].name, i, vr[i]);
    }
    GIL_BEGIN
    fmi2Status st = py_set(c, fn, kind, vr, n, value);
    GIL_END
    return st;
}

fmi2Status fmi2SetReal(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Real value[])
{
    return set_values(comp, F_SetReal, K_REAL, vr, n, value);
}

fmi2Status fmi2SetInteger(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Integer value[])
{
    return set_values(comp, F_SetInteger, K_INTEGER, vr, n, value);
}

fmi2Status fmi2SetBoolean(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2Boolean value[])
{
    return set_values(comp, F_SetBoolean, K_BOOLEAN, vr, n, value);
}

fmi2Status fmi2SetString(fmi2Component comp, const fmi2ValueReference vr[], size_t n, const fmi2String value[])
{
    return set_values(comp, F_SetString, K_STRING, vr, n, value);
}

/* ------------------------------------------------------------------ FMU state */
/* *state on entry: NULL (a new state) or a state of this instance (overwritten, as
 * FMI 2.0 section 2.1.8 allows); anything else is refused without being read. */
static State *state_slot(Comp *c, enum Fn fn, fmi2FMUstate *state, int *fresh)
{
    *fresh = 0;
    if (!state) {
        logf_(c, fmi2Error, "%s: FMUstate is NULL", TABLE[fn].name);
        return NULL;
    }
    if (*state) {
        State *s = find_state(c, *state);
        if (!s) logf_(c, fmi2Error, "%s: *FMUstate = %p is not a live FMU state of this instance (expected NULL or "
                                    "a state it returned)", TABLE[fn].name, *state);
        return s;
    }
    State *s = (State *)calloc(1, sizeof(State));
    if (!s) logf_(c, fmi2Error, "%s: out of memory", TABLE[fn].name);
    *fresh = s != NULL;
    return s;
}

static void fill_state(Comp *c, State *s, int fresh, PyObject *py, unsigned st, double time, double start,
                       double stop, int stop_defined, fmi2FMUstate *out)
{
    Py_XDECREF(s->py);
    Py_CLEAR(s->ser);
    s->py = py;
    s->st = st;
    s->time = time;
    s->start = start;
    s->stop = stop;
    s->stop_defined = stop_defined;
    if (fresh) {
        s->magic = STATE_MAGIC;
        s->owner = c;
        s->next = c->states;
        c->states = s;
    }
    *out = (fmi2FMUstate)s;
}

static State *known_state(Comp *c, enum Fn fn, fmi2FMUstate state)
{
    State *s = state ? find_state(c, state) : NULL;
    if (!s) logf_(c, fmi2Error, "%s: FMUstate = %p is not a live FMU state of this instance (freed, or from "
                                "another instance)", TABLE[fn].name, state);
    return s;
}

fmi2Status fmi2GetFMUstate(fmi2Component comp, fmi2FMUstate *state)
{
    ENTER(GetFMUstate)
    int fresh;
    State *s = state_slot(c, F_GetFMUstate, state, &fresh);
    if (!s) return fmi2Error;
    GIL_BEGIN
    PyObject *py = PyObject_CallMethod(c->slave, "_get_fmu_state", NULL);
    fmi2Status st = py ? drain_log(c) : fail(c, TABLE[F_GetFMUstate].name);
    if (py) fill_state(c, s, fresh, py, c->st, c->time, c->start, c->stop, c->stop_defined, state);
    else if (fresh) free(s);
    GIL_END
    return st > fmi2Warning && py ? fmi2Warning : st;
}

fmi2Status fmi2SetFMUstate(fmi2Component comp, fmi2FMUstate state)
{
    ENTER(SetFMUstate)
    State *s = known_state(c, F_SetFMUstate, state);
    if (!s) return fmi2Error;
    GIL_BEGIN
    /* the slave validates the whole state before it assigns anything (atomic) */
    fmi2Status st = finish(c, TABLE[F_SetFMUstate].name, PyObject_CallMethod(c->slave, "_set_fmu_state", "O", s->py));
    GIL_END
    if (st <= fmi2Warning) {
        c->st = s->st;
        c->time = s->time;
        c->start = s->start;
        c->stop = s->stop;
        c->stop_defined = s->stop_defined;
    }
    return st;
}

fmi2Status fmi2FreeFMUstate(fmi2Component comp, fmi2FMUstate *state)
{
    ENTER(FreeFMUstate)
    enum Fn fn_ = F_FreeFMUstate;
    NEED(state, "FMUstate")
    if (!*state) return fmi2OK; /* FMI 2.0: freeing a NULL state is ignored */
    State *s = known_state(c, F_FreeFMUstate, *state);
    if (!s) return fmi2Error;
    GIL_BEGIN
    drop_state(c, s);
    GIL_END
    *state = NULL;
    return fmi2OK;
}

/* Serialized state: a 56-byte header, then the slave's bytes (its
 * _fmu_state_to_bytes). Header, little-endian: magic "FMI2PYST" ("FMI3PYST" in the FMI 3.0
 * binary: a state of one version is refused by the other), u32 format version,
 * u32 state-machine state, f64 time, f64 start time, f64 stop time, u32 stop defined,
 * u32 CRC-32 of everything else (header and payload), u64 payload length. */
#define SER_MAGIC FMI_NAME("FMI2PYST", "FMI3PYST")
#define SER_VERSION 1u
#define SER_HEAD 56
#define SER_MAX ((size_t)1 << 30)

static uint32_t crc32_update(uint32_t crc, const unsigned char *p, size_t n)
{
    crc = ~crc;
    for (size_t i = 0; i < n; i++) {
        crc ^= p[i];
        for (int k = 0; k < 8; k++) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return ~crc;
}

static uint32_t ser_crc(const unsigned char *b, size_t n)
{
    return crc32_update(crc32_update(0, b, 44), b + 48, n - 48);
}

static void put_u32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(v >> (8 * i));
}

static void put_u64(unsigned char *p, uint64_t v)
{
    for (int i = 0; i < 8; i++) p[i] = (unsigned char)(v >> (8 * i));
}

static void put_f64(unsigned char *p, double x)
{
    uint64_t v;
    memcpy(&v, &x, 8);
    put_u64(p, v);
}

static uint32_t get_u32(const unsigned char *p)
{
    uint32_t v = 0;
    for (int i = 0; i < 4; i++) v |= (uint32_t)p[i] << (8 * i);
    return v;
}

static uint64_t get_u64(const unsigned char *p)
{
    uint64_t v = 0;
    for (int i = 0; i < 8; i++) v |= (uint64_t)p[i] << (8 * i);
    return v;
}

static double get_f64(const unsigned char *p)
{
    uint64_t v = get_u64(p);
    double x;
    memcpy(&x, &v, 8);
    return x;
}

/* The serialized state (a bytes object, cached in the state), or NULL with an error. */
static PyObject *serialized(Comp *c, State *s)
{
    if (s->ser) return s->ser;
    PyObject *payload = PyObject_CallMethod(c->slave, "_fmu_state_to_bytes", "O", s->py);
    if (payload && !PyBytes_Check(payload)) {
        PyErr_Format(PyExc_TypeError, "slave._fmu_state_to_bytes returned a %s, expected bytes",
                     Py_TYPE(payload)->tp_name);
        Py_CLEAR(payload);
    }
    if (!payload) return NULL;
    size_t np = (size_t)PyBytes_GET_SIZE(payload);
    if (np > SER_MAX) {
        Py_DECREF(payload);
        PyErr_Format(PyExc_ValueError, "serialized state of %zu bytes exceeds the limit of %zu", np, SER_MAX);
        return NULL;
    }
    PyObject *out = PyBytes_FromStringAndSize(NULL, (Py_ssize_t)(SER_HEAD + np));
    if (out) {
        unsigned char *b = (unsigned char *)PyBytes_AS_STRING(out);
        memcpy(b, SER_MAGIC, 8);
        put_u32(b + 8, SER_VERSION);
        put_u32(b + 12, s->st);
        put_f64(b + 16, s->time);
        put_f64(b + 24, s->start);
        put_f64(b + 32, s->stop);
        put_u32(b + 40, (uint32_t)s->stop_defined);
        put_u64(b + 48, np);
        memcpy(b + SER_HEAD, PyBytes_AS_STRING(payload), np);
        put_u32(b + 44, ser_crc(b, SER_HEAD + np));
    }
    Py_DECREF(payload);
    s->ser = out;
    return out;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component comp, fmi2FMUstate state, size_t *size)
{
    ENTER(SerializedFMUstateSize)
    enum Fn fn_ = F_SerializedFMUstateSize;
    NEED(size, "size")
    State *s = known_state(c, fn_, state);
    if (!s) return fmi2Error;
    GIL_BEGIN
    PyObject *b = serialized(c, s);
    if (b) *size = (size_t)PyBytes_GET_SIZE(b);
    fmi2Status st = b ? drain_log(c) : fail(c, TABLE[F_SerializedFMUstateSize].name);
    GIL_END
    return st;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component comp, fmi2FMUstate state, fmi2Byte out[], size_t size)
{
    ENTER(SerializeFMUstate)
    enum Fn fn_ = F_SerializeFMUstate;
    NEED(out, "serializedState[]")
    State *s = known_state(c, fn_, state);
    if (!s) return fmi2Error;
    GIL_BEGIN
    PyObject *b = serialized(c, s);
    fmi2Status st;
    if (!b) {
        st = fail(c, TABLE[fn_].name);
    } else if ((size_t)PyBytes_GET_SIZE(b) > size) {
        st = logf_(c, fmi2Error, "%s: buffer of %zu bytes, the state needs %zd (%s)", TABLE[fn_].name, size,
                   PyBytes_GET_SIZE(b), TABLE[F_SerializedFMUstateSize].name);
    } else {
        memcpy(out, PyBytes_AS_STRING(b), (size_t)PyBytes_GET_SIZE(b));
        st = drain_log(c);
    }
    GIL_END
    return st;
}

/* Check the header of serialized bytes; returns the error text or NULL. */
static const char *check_header(const unsigned char *b, size_t size)
{
    if (size < SER_HEAD) return "shorter than the header (truncated, or not a serialized state)";
    if (memcmp(b, SER_MAGIC, 8) != 0) return "not a serialized state of this FMU (bad magic)";
    if (get_u32(b + 8) != SER_VERSION) return "unknown format version (expected 1)";
    if (get_u64(b + 48) != size - SER_HEAD) return "length does not match its header (truncated or extended)";
    if (get_u32(b + 44) != ser_crc(b, size)) return "checksum mismatch (corrupted)";
    uint32_t st = get_u32(b + 12);
    if (!(st & ST_ANY) || (st & (st - 1))) return "invalid state-machine state";
    if (!isfinite(get_f64(b + 16)) || !isfinite(get_f64(b + 24)) || get_u32(b + 40) > 1 ||
        (get_u32(b + 40) && !isfinite(get_f64(b + 32))))
        return "invalid time fields";
    return NULL;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component comp, const fmi2Byte in[], size_t size, fmi2FMUstate *state)
{
    ENTER(DeSerializeFMUstate)
    enum Fn fn_ = F_DeSerializeFMUstate;
    NEED(in, "serializedState[]")
    if (size > SER_MAX)
        return logf_(c, fmi2Error, "%s: %zu bytes, more than the limit of %zu", TABLE[fn_].name, size, SER_MAX);
    const unsigned char *b = (const unsigned char *)in;
    const char *bad = check_header(b, size);
    if (bad) return logf_(c, fmi2Error, "%s: %zu bytes: %s", TABLE[fn_].name, size, bad);
    int fresh;
    State *s = state_slot(c, fn_, state, &fresh);
    if (!s) return fmi2Error;
    GIL_BEGIN
    PyObject *payload = PyBytes_FromStringAndSize((const char *)b + SER_HEAD, (Py_ssize_t)(size - SER_HEAD));
    PyObject *py = payload ? PyObject_CallMethod(c->slave, "_fmu_state_from_bytes", "O", payload) : NULL;
    Py_XDECREF(payload);
    /* a slave that can check a state before it is used says so early */
    if (py && PyObject_HasAttrString(c->slave, "_validate_fmu_state")) {
        PyObject *r = PyObject_CallMethod(c->slave, "_validate_fmu_state", "O", py);
        if (!r) Py_CLEAR(py);
        Py_XDECREF(r);
    }
    fmi2Status st = py ? drain_log(c) : fail(c, TABLE[fn_].name);
    if (py) fill_state(c, s, fresh, py, get_u32(b + 12), get_f64(b + 16), get_f64(b + 24), get_f64(b + 32),
                       (int)get_u32(b + 40), state);
    else if (fresh) free(s);
    GIL_END
    return st > fmi2Warning && py ? fmi2Warning : st;
}

/* ------------------------------------------------------------------ co-simulation */
/* A step the slave has already computed. _c_step_buf holds
 *   [0] valid (1.0), [1] t0 and [2] h0: the slave's interpolation step, [3] t_reached,
 *   [4] lo, [5] hi: bounds of the first output, [6] the communication time (written here,
 *   read by the slave when it next runs), [7] n_in, [8] n_out, [9] rtol,
 *   then the n_in inputs the step was computed with, then a, b, c (n_out each).
 * The inputs are the first n_in entries of the fast-path buffer, the outputs the next
 * n_out. If the inputs are those the step was computed with (within the slave's relative
 * tolerance rtol, by the slave's own test) and it ends at or before t_reached, the outputs
 * become a + s (b + s c) at s = (t + h - t0)/h0, the first clamped to [lo, hi]: the same
 * operations, in the same order, as the slave's own do_step (bitwise equal results).
 * Returns 1 if it stepped. No Python, no GIL: the buffers are the slave's, kept alive by
 * our references, and only this instance's calls touch them. */
static int fast_step(Comp *c, double t, double h)
{
    if (!c->has_sbuf || !c->has_buf) return 0;
    double *s = (double *)c->sbuf.buf, *b = (double *)c->buf.buf;
    size_t ns = (size_t)c->sbuf.len / 8, nb = (size_t)c->buf.len / 8;
    if (s[0] != 1.0 || !(s[7] >= 0.0 && s[7] <= (double)nb) || !(s[8] >= 1.0 && s[8] <= (double)nb)) return 0;
    size_t ni = (size_t)s[7], no = (size_t)s[8];
    if ((double)ni != s[7] || (double)no != s[8] || ni + no > nb || 10 + ni + 3 * no > ns) return 0;
    for (size_t i = 0; i < ni; i++) /* the slave's same_input: |a - b| <= rtol max(|a|, |b|) */
        if (!(fabs(b[i] - s[10 + i]) <= s[9] * fmax(fabs(b[i]), fabs(s[10 + i])))) return 0;
    double target = t + h;
    if (!(target <= s[3]) || !(s[2] > 0.0)) return 0;
    double sv = (target - s[1]) / s[2];
    const double *A = s + 10 + ni, *B = A + no, *C = B + no;
    for (size_t k = 0; k < no; k++) b[ni + k] = A[k] + sv * (B[k] + sv * C[k]);
    double y = b[ni];
    y = s[4] > y ? s[4] : y; /* Python's min(max(y, lo), hi), -0.0 included */
    y = s[5] < y ? s[5] : y;
    b[ni] = y;
    s[6] = target;
    return 1;
}

fmi2Status fmi2DoStep(fmi2Component comp, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior)
{
    ENTER(DoStep)
    (void)noSetPrior;
    const char *fn = TABLE[F_DoStep].name;
    /* rejected before Python sees them: the instance stays in stepComplete */
    if (!isfinite(t) || !isfinite(h) || !(h > 0) || !isfinite(t + h))
        return logf_(c, fmi2Error, "%s: currentCommunicationPoint = %g s, communicationStepSize = %g s; "
                                   "expected finite values with communicationStepSize > 0", fn, t, h);
    if (fabs(t - c->time) > 1e-9 * fmax(1.0, fabs(c->time)))
        return logf_(c, fmi2Error, "%s: currentCommunicationPoint = %.17g s, expected the end of the "
                                   "previous step, %.17g s", fn, t, c->time);
    if (c->stop_defined && t + h > c->stop + 1e-9 * fmax(1.0, fabs(c->stop)))
        return logf_(c, fmi2Error, "%s: the step ends at %.17g s, after stopTime = %.17g s", fn, t + h,
                     c->stop);
    if (fast_step(c, t, h)) {
        c->time = t + h;
        return fmi2OK;
    }
    GIL_BEGIN
    PyObject *r = PyObject_CallMethod(c->slave, "do_step", "dd", t, h);
    fmi2Status st;
    if (!r) {
        /* an exception marked fmi_rejected (the slave refused the step before changing
         * anything: an input it cannot take) leaves the instance in stepComplete */
        PyObject *type, *val, *tb;
        PyErr_Fetch(&type, &val, &tb);
        PyErr_NormalizeException(&type, &val, &tb);
        PyObject *flag = val ? PyObject_GetAttrString(val, "fmi_rejected") : NULL;
        int rejected = flag && PyObject_IsTrue(flag) == 1;
        Py_XDECREF(flag);
        PyErr_Clear();
        PyErr_Restore(type, val, tb);
        char where[200];
        snprintf(where, sizeof where, rejected ? "%s over [%.17g, %.17g] s refused (nothing changed)"
                                               : "%s over [%.17g, %.17g] s failed", fn, t, t + h);
        st = fail(c, where);
        if (!rejected) c->st = ST_ERROR;
    } else if (!PyBool_Check(r)) {
        st = drain_log(c);
        st = logf_(c, fmi2Error, "%s over [%.17g, %.17g] s: slave.do_step returned a %s, expected True or False; "
                                 "the instance is now in the error state", fn, t, t + h, Py_TYPE(r)->tp_name);
        c->st = ST_ERROR;
    } else if (r == Py_True) {
        st = drain_log(c);
        if (st > fmi2Warning) st = fmi2Warning;
        c->time = t + h;
    } else {
        drain_log(c);
        st = logf_(c, fmi2Discard, "%s over [%.17g, %.17g] s: the slave did not complete the step "
                                   "(%s: get values, restore a state, terminate or reset)", fn, t, t + h,
                   state_name(ST_STEP_FAILED));
        c->st = ST_STEP_FAILED;
    }
    Py_XDECREF(r);
    GIL_END
    return st;
}

fmi2Status fmi2CancelStep(fmi2Component comp)
{
    ENTER(CancelStep) /* never allowed: doStep is synchronous, no step is ever in progress */
    return fmi2Error;
}

static fmi2Status unsupported(fmi2Component comp, enum Fn fn, const char *why)
{
    Comp *c = enter(comp, fn);
    if (!c) return fmi2Error;
    return logf_(c, fmi2Error, "%s: %s", TABLE[fn].name, why);
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component comp, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real dz[])
{
    (void)u, (void)nu, (void)z, (void)nz, (void)dv, (void)dz;
    return unsupported(comp, F_GetDirectionalDerivative, "not provided (providesDirectionalDerivative=false)");
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    (void)vr, (void)n, (void)order, (void)value;
    return unsupported(comp, F_SetRealInputDerivatives, "inputs are held constant (canInterpolateInputs=false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component comp, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[])
{
    (void)vr, (void)n, (void)order, (void)value;
    return unsupported(comp, F_GetRealOutputDerivatives, "not provided (maxOutputDerivativeOrder=0)");
}

/* Status queries (FMI 2.0.x section 4.2.3): the last successful time is known here;
 * everything else is fmi2Discard, "not able to return the required status". */
static fmi2Status status_query(fmi2Component comp, enum Fn fn, fmi2StatusKind s, void *value, int kind)
{
    Comp *c = enter(comp, fn);
    if (!c) return fmi2Error;
    enum Fn fn_ = fn;
    NEED(value, "value")
    if (kind == K_REAL && s == fmi2LastSuccessfulTime) {
        *(fmi2Real *)value = c->time;
        return fmi2OK;
    }
    if (kind == K_BOOLEAN && s == fmi2Terminated) {
        *(fmi2Boolean *)value = c->st == ST_STEP_FAILED ? fmi2True : fmi2False;
        return fmi2OK;
    }
    return logf_(c, fmi2Discard, "%s: status kind %d not available (doStep is synchronous)", TABLE[fn].name, (int)s);
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    return status_query(c, F_GetStatus, s, value, K_NONE);
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    return status_query(c, F_GetRealStatus, s, value, K_REAL);
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    return status_query(c, F_GetIntegerStatus, s, value, K_INTEGER);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    return status_query(c, F_GetBooleanStatus, s, value, K_BOOLEAN);
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    return status_query(c, F_GetStringStatus, s, value, K_STRING);
}
