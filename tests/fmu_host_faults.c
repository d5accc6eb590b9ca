/* A hostile FMI 2.0 host: calls every fmi2 function of the FMU binary with NULL
 * arguments, unknown instance and state pointers, in wrong states, after errors, after
 * fmi2FreeInstance, and with a Python fault injected at each entry point of the test
 * slave (tests/fmu_faulty.py, switched through its fault.txt). The process must survive
 * all of it; every check prints "ok SCENARIO: what" or "FAIL SCENARIO: what ...", and
 * the last line is "done".
 *
 * usage: fmu_host_faults BINARY.so URI_FAULTY DIR_FAULTY URI_BAD_MODULE URI_BAD_PARAMS
 *        VR_VOLTAGE VR_FORCE VR_STROKE VR_RHO_L VR_RHO_F VR_N VR_SCHEME VR_LAND
 */
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2FunctionTypes.h" /* types only: the functions come from dlsym */

static char g_log[65536];
static int g_nlog;

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status st, fmi2String cat, fmi2String msg, ...)
{
    (void)env, (void)name, (void)cat;
    char line[4096];
    va_list ap;
    va_start(ap, msg);
    vsnprintf(line, sizeof line, msg, ap);
    va_end(ap);
    size_t k = strlen(g_log);
    snprintf(g_log + k, sizeof g_log - k, "[%d] %s\n", st, line);
    g_nlog++;
}

static void mark(void) { g_log[0] = 0; g_nlog = 0; }
static int logged(const char *s) { return strstr(g_log, s) != NULL; }

static const char *g_scen = "";
static int g_fail;

static void check(int cond, const char *what, int status)
{
    if (cond) {
        printf("ok %s: %s\n", g_scen, what);
    } else {
        g_fail++;
        char last[300];
        size_t n = strlen(g_log);
        snprintf(last, sizeof last, "%s", n > 290 ? g_log + n - 290 : g_log);
        for (char *p = last; *p; p++)
            if (*p == '\n') *p = '|';
        printf("FAIL %s: %s (status %d, log: %s)\n", g_scen, what, status, last);
    }
    fflush(stdout);
}

/* status and log: `st` equals `want` and, if given, the log since the call holds `text` */
#define EXPECT(call, want, text, what)                                           \
    do {                                                                         \
        mark();                                                                  \
        int st_ = (int)(call);                                                   \
        check(st_ == (want) && (!(text) || logged(text)), what, st_);            \
    } while (0)

#define F(name) static name##TYPE *name;
F(fmi2Instantiate) F(fmi2FreeInstance) F(fmi2SetDebugLogging) F(fmi2SetupExperiment)
F(fmi2EnterInitializationMode) F(fmi2ExitInitializationMode) F(fmi2Terminate) F(fmi2Reset) F(fmi2GetReal)
F(fmi2GetInteger) F(fmi2GetBoolean) F(fmi2GetString) F(fmi2SetReal) F(fmi2SetInteger) F(fmi2SetBoolean)
F(fmi2SetString) F(fmi2GetFMUstate) F(fmi2SetFMUstate) F(fmi2FreeFMUstate) F(fmi2SerializedFMUstateSize)
F(fmi2SerializeFMUstate) F(fmi2DeSerializeFMUstate) F(fmi2GetDirectionalDerivative) F(fmi2SetRealInputDerivatives)
F(fmi2GetRealOutputDerivatives) F(fmi2DoStep) F(fmi2CancelStep) F(fmi2GetStatus) F(fmi2GetRealStatus)
F(fmi2GetIntegerStatus) F(fmi2GetBooleanStatus) F(fmi2GetStringStatus) F(fmi2GetTypesPlatform) F(fmi2GetVersion)
#undef F

static fmi2CallbackFunctions CB = {logger, calloc, free, NULL, NULL};
static const char *URI, *DIR_, *URI_BAD_MODULE, *URI_BAD_PARAMS;
static fmi2ValueReference VOLT, FORCE, STROKE, RHO_L, RHO_F, NN, SCHEME, LAND;
static const double H = 1e-3;

static void set_fault(const char *text)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/fault.txt", DIR_);
    FILE *f = fopen(path, "w");
    if (f) {
        fputs(text, f);
        fclose(f);
    }
}

static fmi2Component inst(const char *uri) { return fmi2Instantiate("faults", fmi2CoSimulation, "", uri, &CB, 0, 0); }

/* an instance in stepComplete at t = 0 (no fault) */
static fmi2Component running(void)
{
    set_fault("");
    fmi2Component c = inst(URI);
    if (!c) return NULL;
    fmi2SetupExperiment(c, 0, 0, 0.0, 0, 0);
    fmi2EnterInitializationMode(c);
    fmi2ExitInitializationMode(c);
    return c;
}

static int step_ok(fmi2Component c, double t)
{
    fmi2Real u[2] = {6000.0, 5.0};
    fmi2ValueReference vin[2] = {VOLT, FORCE};
    return fmi2SetReal(c, vin, 2, u) == fmi2OK && fmi2DoStep(c, t, H, fmi2True) == fmi2OK;
}

/* ------------------------------------------------------------------ generic abuse */
static void every_function(fmi2Component c, const char *what)
{
    fmi2ValueReference vr = 0;
    fmi2Real r = 0;
    fmi2Integer i = 0;
    fmi2Boolean b = 0;
    fmi2String s = NULL;
    fmi2Status stv;
    fmi2FMUstate fs = NULL;
    size_t sz = 0;
    char buf[64];
    int bad = 0;
    bad += fmi2SetDebugLogging(c, 1, 0, NULL) != fmi2Error;
    bad += fmi2SetupExperiment(c, 0, 0, 0, 0, 0) != fmi2Error;
    bad += fmi2EnterInitializationMode(c) != fmi2Error;
    bad += fmi2ExitInitializationMode(c) != fmi2Error;
    bad += fmi2Terminate(c) != fmi2Error;
    bad += fmi2Reset(c) != fmi2Error;
    bad += fmi2GetReal(c, &vr, 1, &r) != fmi2Error;
    bad += fmi2GetInteger(c, &vr, 1, &i) != fmi2Error;
    bad += fmi2GetBoolean(c, &vr, 1, &b) != fmi2Error;
    bad += fmi2GetString(c, &vr, 1, &s) != fmi2Error;
    bad += fmi2SetReal(c, &vr, 1, &r) != fmi2Error;
    bad += fmi2SetInteger(c, &vr, 1, &i) != fmi2Error;
    bad += fmi2SetBoolean(c, &vr, 1, &b) != fmi2Error;
    bad += fmi2SetString(c, &vr, 1, &s) != fmi2Error;
    bad += fmi2GetFMUstate(c, &fs) != fmi2Error;
    bad += fmi2SetFMUstate(c, fs) != fmi2Error;
    bad += fmi2FreeFMUstate(c, &fs) != fmi2Error;
    bad += fmi2SerializedFMUstateSize(c, fs, &sz) != fmi2Error;
    bad += fmi2SerializeFMUstate(c, fs, buf, sizeof buf) != fmi2Error;
    bad += fmi2DeSerializeFMUstate(c, buf, sizeof buf, &fs) != fmi2Error;
    bad += fmi2GetDirectionalDerivative(c, &vr, 1, &vr, 1, &r, &r) != fmi2Error;
    bad += fmi2SetRealInputDerivatives(c, &vr, 1, &i, &r) != fmi2Error;
    bad += fmi2GetRealOutputDerivatives(c, &vr, 1, &i, &r) != fmi2Error;
    bad += fmi2DoStep(c, 0, H, 1) != fmi2Error;
    bad += fmi2CancelStep(c) != fmi2Error;
    bad += fmi2GetStatus(c, fmi2DoStepStatus, &stv) != fmi2Error;
    bad += fmi2GetRealStatus(c, fmi2LastSuccessfulTime, &r) != fmi2Error;
    bad += fmi2GetIntegerStatus(c, fmi2DoStepStatus, &i) != fmi2Error;
    bad += fmi2GetBooleanStatus(c, fmi2Terminated, &b) != fmi2Error;
    bad += fmi2GetStringStatus(c, fmi2PendingStatus, &s) != fmi2Error;
    fmi2FreeInstance(c);
    check(bad == 0 && fs == NULL, what, bad);
}

static void scen_invalid_instances(void)
{
    g_scen = "invalid_instance";
    every_function(NULL, "every function with a NULL instance returns fmi2Error");
    int junk[64] = {0};
    every_function((fmi2Component)junk, "every function with a pointer that is no instance returns fmi2Error");
    fmi2Component c = running();
    fmi2FreeInstance(c);
    every_function(c, "every function after fmi2FreeInstance returns fmi2Error");
    check(strcmp(fmi2GetVersion(), "2.0") == 0 && fmi2GetTypesPlatform() != NULL, "version and platform", 0);
}

static void scen_instantiate(void)
{
    g_scen = "instantiate";
    set_fault("");
    fmi2Component first = inst(URI); /* imports the slave module from URI's resources */
    check(first != NULL, "instantiate", 0);
    fmi2FreeInstance(first);
    mark();
    check(fmi2Instantiate("x", fmi2ModelExchange, "", URI, &CB, 0, 0) == NULL && logged("co-simulation only"),
          "model exchange is refused", 0);
    mark();
    check(fmi2Instantiate("x", fmi2CoSimulation, "", NULL, &CB, 0, 0) == NULL, "NULL resource location", 0);
    mark();
    check(fmi2Instantiate("x", fmi2CoSimulation, "", "file:///no/such/dir", &CB, 0, 0) == NULL &&
              logged("slavemodule.txt"), "missing resources", 0);
    mark();
    check(inst(URI_BAD_MODULE) == NULL && logged("fmi2Instantiate") && logged("no_such_module"),
          "bad slavemodule.txt: NULL and a log line, no crash", 0);
    mark();
    check(inst(URI_BAD_PARAMS) == NULL && logged("bogus_key"),
          "unknown key in dfa_params.toml: NULL and a log line naming it", 0);
    set_fault("");
    fmi2Component c = fmi2Instantiate(NULL, fmi2CoSimulation, NULL, URI, NULL, 0, 0);
    check(c != NULL, "NULL name, GUID and callbacks: runs silently", 0);
    if (c) {
        EXPECT(fmi2DoStep(c, 0, H, 1), fmi2Error, NULL, "a refused call without a logger");
        fmi2FreeInstance(c);
    }
    fmi2CallbackFunctions nolog = {NULL, calloc, free, NULL, NULL};
    c = fmi2Instantiate("x", fmi2CoSimulation, "", URI, &nolog, 0, 0);
    check(c != NULL, "NULL logger: runs silently", 0);
    fmi2FreeInstance(c);
    set_fault("__init__ raise");
    mark();
    check(inst(URI) == NULL && logged("injected fault in __init__"), "__init__ raises: NULL and a log line", 0);
    set_fault("");
    c = inst(URI);
    check(c != NULL, "instantiates again once the fault is gone", 0);
    fmi2FreeInstance(c);
}

static void scen_arguments(void)
{
    g_scen = "arguments";
    set_fault("");
    fmi2Component c = inst(URI);
    if (!c) return check(0, "instantiate", 0);
    fmi2ValueReference vr[2] = {RHO_L, 99999};
    fmi2Real r[2] = {1e12, 1e12};
    fmi2Integer iv = 5;
    fmi2String sv = NULL;
    EXPECT(fmi2GetReal(c, vr, 1, r), fmi2Error, "not allowed in state instantiated", "get in instantiated");
    EXPECT(fmi2SetupExperiment(c, 1, -1.0, 0, 0, 0), fmi2Error, "tolerance", "negative tolerance");
    EXPECT(fmi2SetupExperiment(c, 0, 0, NAN, 0, 0), fmi2Error, "startTime", "NaN start time");
    EXPECT(fmi2SetupExperiment(c, 0, 0, 1.0, 1, 0.5), fmi2Error, "stopTime", "stop before start");
    EXPECT(fmi2ExitInitializationMode(c), fmi2Error, "allowed in: initializationMode", "exit before enter");
    EXPECT(fmi2DoStep(c, 0, H, 1), fmi2Error, "not allowed in state instantiated", "doStep before init");
    EXPECT(fmi2SetupExperiment(c, 0, 0, 0.0, 1, 0.01), fmi2OK, NULL, "setup with stop time 0.01 s");
    EXPECT(fmi2EnterInitializationMode(c), fmi2OK, NULL, "enter");
    EXPECT(fmi2SetDebugLogging(c, 1, 2, NULL), fmi2Error, "categories", "debug logging, NULL categories");
    EXPECT(fmi2SetReal(c, NULL, 1, r), fmi2Error, "vr[] is NULL", "setReal, NULL vr");
    EXPECT(fmi2SetReal(c, vr, 1, NULL), fmi2Error, "value[] is NULL", "setReal, NULL values");
    EXPECT(fmi2GetReal(c, NULL, 1, r), fmi2Error, "vr[] is NULL", "getReal, NULL vr");
    EXPECT(fmi2GetInteger(c, &NN, 1, NULL), fmi2Error, "value[] is NULL", "getInteger, NULL values");
    EXPECT(fmi2GetBoolean(c, NULL, 1, NULL), fmi2Error, "is NULL", "getBoolean, NULL arrays");
    EXPECT(fmi2GetString(c, &SCHEME, 1, NULL), fmi2Error, "is NULL", "getString, NULL values");
    EXPECT(fmi2SetInteger(c, NULL, 1, &iv), fmi2Error, "is NULL", "setInteger, NULL vr");
    EXPECT(fmi2SetBoolean(c, &LAND, 1, NULL), fmi2Error, "is NULL", "setBoolean, NULL values");
    EXPECT(fmi2SetString(c, &SCHEME, 1, &sv), fmi2Error, "value[0]", "setString, NULL string");
    EXPECT(fmi2SetReal(c, NULL, 0, NULL), fmi2OK, NULL, "n = 0 with NULL arrays");
    EXPECT(fmi2SetReal(c, vr, 2, r), fmi2Error, "value reference 99999", "unknown value reference");
    EXPECT(fmi2GetInteger(c, &RHO_L, 1, &iv), fmi2Error, "not Integer", "type mismatch names the variable");
    EXPECT(fmi2SetReal(c, &STROKE, 1, r), fmi2Error, "it is an output", "set on an output");
    r[0] = NAN;
    EXPECT(fmi2SetReal(c, &VOLT, 1, r), fmi2Error, "finite", "NaN input");
    r[0] = -1.0;
    EXPECT(fmi2SetReal(c, &RHO_L, 1, r), fmi2Error, "rho_l", "parameter out of range");
    /* all or nothing: rho_l is valid, rho_f is not; rho_l keeps its value */
    fmi2ValueReference two[2] = {RHO_L, RHO_F};
    fmi2Real vals[2] = {3e12, -5.0}, back = 0, before = 0;
    fmi2GetReal(c, &RHO_L, 1, &before);
    EXPECT(fmi2SetReal(c, two, 2, vals), fmi2Error, "rho_f", "second of two values refused");
    fmi2GetReal(c, &RHO_L, 1, &back);
    check(back == before, "the first of them was set back", 0);
    EXPECT(fmi2ExitInitializationMode(c), fmi2OK, NULL, "exit");
    r[0] = 1e12;
    EXPECT(fmi2SetReal(c, &RHO_L, 1, r), fmi2Error, "fixed parameter", "fixed parameter after init");
    fmi2Status stv;
    EXPECT(fmi2GetStatus(c, fmi2DoStepStatus, &stv), fmi2Discard, NULL, "getStatus: not available");
    EXPECT(fmi2GetRealStatus(c, fmi2LastSuccessfulTime, NULL), fmi2Error, "value is NULL", "getRealStatus NULL");
    EXPECT(fmi2CancelStep(c), fmi2Error, "stepInProgress", "cancelStep");
    EXPECT(fmi2DoStep(c, 0, 0.0, 1), fmi2Error, "communicationStepSize", "h = 0");
    EXPECT(fmi2DoStep(c, 0, -H, 1), fmi2Error, "communicationStepSize", "h < 0");
    EXPECT(fmi2DoStep(c, NAN, H, 1), fmi2Error, "finite", "NaN time");
    EXPECT(fmi2DoStep(c, 0, INFINITY, 1), fmi2Error, "finite", "infinite step");
    EXPECT(fmi2DoStep(c, 0.5, H, 1), fmi2Error, "expected the end of the previous step", "wrong time");
    EXPECT(fmi2DoStep(c, 0, 0.02, 1), fmi2Error, "stopTime", "past the stop time");
    check(step_ok(c, 0.0) && step_ok(c, H), "after all that, the instance steps on", 0);
    fmi2Real t = 0;
    EXPECT(fmi2GetRealStatus(c, fmi2LastSuccessfulTime, &t), fmi2OK, NULL, "last successful time");
    check(fabs(t - 2 * H) < 1e-15, "last successful time is 2 ms", 0);
    EXPECT(fmi2Terminate(c), fmi2OK, NULL, "terminate");
    EXPECT(fmi2DoStep(c, 2 * H, H, 1), fmi2Error, "not allowed in state terminated", "doStep after terminate");
    EXPECT(fmi2Terminate(c), fmi2Error, "terminated", "terminate twice");
    r[0] = 1.0;
    EXPECT(fmi2SetReal(c, &VOLT, 1, r), fmi2Error, "terminated", "set after terminate");
    EXPECT(fmi2GetReal(c, &STROKE, 1, &t), fmi2OK, NULL, "get after terminate");
    EXPECT(fmi2Reset(c), fmi2OK, NULL, "reset");
    EXPECT(fmi2SetupExperiment(c, 0, 0, 0, 0, 0), fmi2OK, NULL, "set up again after reset");
    fmi2FreeInstance(c);
}

static void scen_states(void)
{
    g_scen = "states";
    fmi2Component c = inst(URI), d = running();
    if (!c || !d) return check(0, "instantiate", 0);
    fmi2FMUstate s = NULL, s2 = NULL, foreign = NULL, junk = (fmi2FMUstate)&s;
    EXPECT(fmi2GetFMUstate(c, NULL), fmi2Error, "FMUstate is NULL", "getFMUstate(NULL)");
    EXPECT(fmi2GetFMUstate(c, &junk), fmi2Error, "not a live FMU state", "getFMUstate over an unknown pointer");
    EXPECT(fmi2SetFMUstate(c, junk), fmi2Error, "not a live FMU state", "setFMUstate(unknown pointer)");
    EXPECT(fmi2SetFMUstate(c, NULL), fmi2Error, "not a live FMU state", "setFMUstate(NULL)");
    EXPECT(fmi2FreeFMUstate(c, NULL), fmi2Error, "is NULL", "freeFMUstate(NULL)");
    EXPECT(fmi2FreeFMUstate(c, &s), fmi2OK, NULL, "freeFMUstate(&NULL) is ignored");
    EXPECT(fmi2GetFMUstate(d, &foreign), fmi2OK, NULL, "a state of another instance");
    EXPECT(fmi2SetFMUstate(c, foreign), fmi2Error, "not a live FMU state", "... is refused");
    /* a state saved during initialization, restored during initialization */
    fmi2SetupExperiment(c, 0, 0, 0, 0, 0);
    fmi2EnterInitializationMode(c);
    fmi2Real v = 1e12, got = 0;
    fmi2SetReal(c, &RHO_L, 1, &v);
    EXPECT(fmi2GetFMUstate(c, &s), fmi2OK, NULL, "get state in initializationMode");
    v = 3e12;
    fmi2SetReal(c, &RHO_L, 1, &v);
    EXPECT(fmi2SetFMUstate(c, s), fmi2OK, NULL, "restore it in initializationMode");
    fmi2GetReal(c, &RHO_L, 1, &got);
    check(got == 1e12, "the restored parameter is not discarded", 0);
    EXPECT(fmi2ExitInitializationMode(c), fmi2OK, NULL, "exit after the restore");
    check(step_ok(c, 0.0), "step", 0);
    EXPECT(fmi2GetFMUstate(c, &s2), fmi2OK, NULL, "get state in stepComplete");
    size_t n = 0;
    EXPECT(fmi2SerializedFMUstateSize(c, s2, NULL), fmi2Error, "size is NULL", "size(NULL)");
    EXPECT(fmi2SerializedFMUstateSize(c, junk, &n), fmi2Error, "not a live", "size of an unknown state");
    EXPECT(fmi2SerializedFMUstateSize(c, s2, &n), fmi2OK, NULL, "serialized size");
    char *buf = (char *)malloc(n + 16);
    EXPECT(fmi2SerializeFMUstate(c, s2, buf, n - 1), fmi2Error, "buffer of", "buffer too small");
    EXPECT(fmi2SerializeFMUstate(c, s2, NULL, n), fmi2Error, "is NULL", "NULL buffer");
    EXPECT(fmi2SerializeFMUstate(c, s2, buf, n), fmi2OK, NULL, "serialize");
    fmi2FMUstate r = NULL;
    EXPECT(fmi2DeSerializeFMUstate(c, NULL, n, &r), fmi2Error, "is NULL", "deserialize NULL");
    EXPECT(fmi2DeSerializeFMUstate(c, buf, n - 1, &r), fmi2Error, "truncated", "deserialize truncated");
    EXPECT(fmi2DeSerializeFMUstate(c, buf, 10, &r), fmi2Error, "header", "deserialize 10 bytes");
    buf[n / 2] ^= 0x40;
    EXPECT(fmi2DeSerializeFMUstate(c, buf, n, &r), fmi2Error, "checksum", "deserialize a flipped bit");
    buf[n / 2] ^= 0x40;
    EXPECT(fmi2DeSerializeFMUstate(c, buf, n, NULL), fmi2Error, "FMUstate is NULL", "deserialize into NULL");
    EXPECT(fmi2DeSerializeFMUstate(c, buf, n, &junk), fmi2Error, "not a live", "deserialize over unknown");
    check(r == NULL, "no state handed out for refused bytes", 0);
    EXPECT(fmi2DeSerializeFMUstate(c, buf, n, &r), fmi2OK, NULL, "deserialize");
    EXPECT(fmi2DeSerializeFMUstate(c, buf, n, &r), fmi2OK, NULL, "deserialize over a live state");
    check(step_ok(c, H), "step on", 0);
    EXPECT(fmi2Terminate(c), fmi2OK, NULL, "terminate");
    EXPECT(fmi2SetFMUstate(c, r), fmi2OK, NULL, "restore the deserialized state after terminate");
    check(step_ok(c, H), "stepComplete again: steps on from 1 ms", 0);
    fmi2FMUstate copy = s2;
    EXPECT(fmi2FreeFMUstate(c, &s2), fmi2OK, NULL, "free");
    check(s2 == NULL, "free sets the pointer to NULL", 0);
    EXPECT(fmi2FreeFMUstate(c, &copy), fmi2Error, "not a live", "double free");
    EXPECT(fmi2SetFMUstate(c, copy), fmi2Error, "not a live", "set a freed state");
    EXPECT(fmi2SerializedFMUstateSize(c, copy, &n), fmi2Error, "not a live", "serialize a freed state");
    free(buf);
    fmi2FreeInstance(c); /* frees s and r with it */
    fmi2FreeInstance(d);
    check(1, "free instances holding live states", 0);
}

/* ------------------------------------------------------------------ injected faults */
static void scen_mode_faults(void)
{
    g_scen = "setup_experiment";
    set_fault("");
    fmi2Component c = inst(URI);
    if (!c) return check(0, "instantiate", 0);
    set_fault("setup_experiment raise");
    EXPECT(fmi2SetupExperiment(c, 0, 0, 0, 0, 0), fmi2Error, "injected fault in setup_experiment", "raises");
    set_fault("");
    EXPECT(fmi2SetupExperiment(c, 0, 0, 0, 0, 0), fmi2OK, NULL, "still instantiated: set up again");
    g_scen = "enter_initialization_mode";
    set_fault("enter_initialization_mode raise");
    EXPECT(fmi2EnterInitializationMode(c), fmi2Error, "injected fault", "raises");
    EXPECT(fmi2ExitInitializationMode(c), fmi2Error, "not allowed in state instantiated", "still instantiated");
    set_fault("");
    EXPECT(fmi2EnterInitializationMode(c), fmi2OK, NULL, "enters once the fault is gone");
    g_scen = "exit_initialization_mode";
    set_fault("exit_initialization_mode raise");
    EXPECT(fmi2ExitInitializationMode(c), fmi2Error, "injected fault", "raises");
    fmi2Real v = 1e12;
    EXPECT(fmi2SetReal(c, &RHO_L, 1, &v), fmi2OK, NULL, "still initializationMode: a parameter can be set");
    set_fault("");
    EXPECT(fmi2ExitInitializationMode(c), fmi2OK, NULL, "exits once the fault is gone");
    check(step_ok(c, 0), "and steps", 0);
    g_scen = "terminate";
    set_fault("terminate raise");
    EXPECT(fmi2Terminate(c), fmi2Error, "injected fault in terminate", "raises");
    set_fault("");
    EXPECT(fmi2DoStep(c, H, H, 1), fmi2Error, "not allowed in state error", "error state: no doStep");
    EXPECT(fmi2GetReal(c, &STROKE, 1, &v), fmi2OK, NULL, "error state: getters work");
    EXPECT(fmi2Reset(c), fmi2OK, NULL, "error state: reset works");
    fmi2FreeInstance(c);
}

static void scen_do_step(void)
{
    fmi2Component c = running();
    if (!c) return check(0, "instantiate", 0);
    fmi2FMUstate s = NULL;
    fmi2Real x0 = 0, x = 0;
    check(step_ok(c, 0.0), "first step", 0);
    fmi2GetFMUstate(c, &s);
    fmi2GetReal(c, &STROKE, 1, &x0);
    g_scen = "do_step";
    set_fault("do_step raise");
    EXPECT(fmi2DoStep(c, H, H, 1), fmi2Error, "fmi2DoStep over [0.001, 0.002] s failed: injected fault",
           "raises: fmi2Error naming the step");
    set_fault("");
    EXPECT(fmi2DoStep(c, H, H, 1), fmi2Error, "not allowed in state error", "error state: doStep refused");
    EXPECT(fmi2SetReal(c, &VOLT, 1, &x), fmi2Error, "not allowed in state error", "error state: setReal refused");
    EXPECT(fmi2Terminate(c), fmi2Error, "state error", "error state: terminate refused");
    EXPECT(fmi2GetReal(c, &STROKE, 1, &x), fmi2OK, NULL, "error state: getReal works");
    EXPECT(fmi2SetFMUstate(c, s), fmi2OK, NULL, "error state: restore the state saved in stepComplete");
    fmi2GetReal(c, &STROKE, 1, &x);
    check(x == x0, "the restored stroke", 0);
    check(step_ok(c, H), "stepComplete again: steps on", 0);
    g_scen = "do_step_solver";
    set_fault("do_step solver");
    EXPECT(fmi2DoStep(c, 2 * H, H, 1), fmi2Error, "stopped at t = ", "a real solver failure");
    check(logged("over [0.002, 0.003") && logged("on the way from 0.002 s to 0.003 s"),
          "the message gives the step's times", 0);
    set_fault("");
    EXPECT(fmi2SetFMUstate(c, s), fmi2OK, NULL, "restore");
    check(step_ok(c, H), "steps on after the restore", 0);
    g_scen = "do_step_wrong_type";
    set_fault("do_step wrong_type");
    EXPECT(fmi2DoStep(c, 2 * H, H, 1), fmi2Error, "expected True or False", "do_step returns a str");
    set_fault("do_step none");
    EXPECT(fmi2DoStep(c, 2 * H, H, 1), fmi2Error, "not allowed in state error", "... error state");
    EXPECT(fmi2SetFMUstate(c, s), fmi2OK, NULL, "restore");
    EXPECT(fmi2DoStep(c, H, H, 1), fmi2Error, "returned a NoneType", "do_step returns None");
    EXPECT(fmi2SetFMUstate(c, s), fmi2OK, NULL, "restore");
    g_scen = "do_step_false";
    set_fault("do_step false");
    EXPECT(fmi2DoStep(c, H, H, 1), fmi2Discard, "did not complete", "do_step returns False: fmi2Discard");
    set_fault("");
    EXPECT(fmi2DoStep(c, H, H, 1), fmi2Error, "not allowed in state stepFailed", "stepFailed: doStep refused");
    fmi2Boolean term = 0;
    EXPECT(fmi2GetBooleanStatus(c, fmi2Terminated, &term), fmi2OK, NULL, "stepFailed: status query");
    check(term == fmi2True, "fmi2Terminated is true in stepFailed", 0);
    EXPECT(fmi2Terminate(c), fmi2OK, NULL, "stepFailed: terminate");
    fmi2FreeInstance(c);
}

static void scen_getters(void)
{
    static const char *names[4] = {"get_real", "get_integer", "get_boolean", "get_string"};
    static const char *modes[4] = {"raise", "wrong_type", "wrong_length", "not_a_list"};
    for (int k = 0; k < 4; k++) {
        g_scen = names[k];
        fmi2Component c = running();
        if (!c) return check(0, "instantiate", 0);
        for (int m = 0; m < 4; m++) {
            char fault[64], what[96];
            snprintf(fault, sizeof fault, "%s %s", names[k], modes[m]);
            set_fault(fault);
            fmi2Real r;
            fmi2Integer i;
            fmi2Boolean b;
            fmi2String s;
            mark();
            int st = k == 0 ? fmi2GetReal(c, &RHO_L, 1, &r)
                   : k == 1 ? fmi2GetInteger(c, &NN, 1, &i)
                   : k == 2 ? fmi2GetBoolean(c, &LAND, 1, &b)
                            : fmi2GetString(c, &SCHEME, 1, &s);
            snprintf(what, sizeof what, "%s: fmi2Error with a log line", modes[m]);
            check(st == fmi2Error && g_nlog > 0 && logged(names[k][4] == 'r' ? "fmi2GetReal" : "fmi2Get"), what, st);
        }
        set_fault("");
        check(step_ok(c, 0.0), "the instance steps on", 0);
        fmi2FreeInstance(c);
    }
}

static void scen_setters(void)
{
    static const char *names[4] = {"set_real", "set_integer", "set_boolean", "set_string"};
    for (int k = 0; k < 4; k++) {
        g_scen = names[k];
        set_fault("");
        fmi2Component c = inst(URI);
        if (!c) return check(0, "instantiate", 0);
        fmi2SetupExperiment(c, 0, 0, 0, 0, 0);
        fmi2EnterInitializationMode(c);
        fmi2Real r = 1e12, r0 = 0, r1 = 0;
        fmi2Integer i = 41, i0 = 0, i1 = 0;
        fmi2Boolean b = fmi2False, b0 = 0, b1 = 0;
        fmi2String s = "paper", s0 = NULL, s1 = NULL;
        char old_s[64] = "";
        fmi2GetReal(c, &RHO_L, 1, &r0);
        fmi2GetInteger(c, &NN, 1, &i0);
        fmi2GetBoolean(c, &LAND, 1, &b0);
        fmi2GetString(c, &SCHEME, 1, &s0);
        if (s0) snprintf(old_s, sizeof old_s, "%s", s0);
        char fault[64];
        snprintf(fault, sizeof fault, "%s raise", names[k]);
        set_fault(fault);
        mark();
        int st = k == 0 ? fmi2SetReal(c, &RHO_L, 1, &r)
               : k == 1 ? fmi2SetInteger(c, &NN, 1, &i)
               : k == 2 ? fmi2SetBoolean(c, &LAND, 1, &b)
                        : fmi2SetString(c, &SCHEME, 1, &s);
        check(st == fmi2Error && logged("injected fault"), "raises: fmi2Error with a log line", st);
        set_fault("");
        fmi2GetReal(c, &RHO_L, 1, &r1);
        fmi2GetInteger(c, &NN, 1, &i1);
        fmi2GetBoolean(c, &LAND, 1, &b1);
        fmi2GetString(c, &SCHEME, 1, &s1);
        check(r1 == r0 && i1 == i0 && b1 == b0 && s1 && strcmp(s1, old_s) == 0, "nothing changed", 0);
        EXPECT(fmi2ExitInitializationMode(c), fmi2OK, NULL, "still initializationMode: exits");
        fmi2FreeInstance(c);
    }
}

static void scen_state_faults(void)
{
    g_scen = "_get_fmu_state";
    fmi2Component c = running();
    if (!c) return check(0, "instantiate", 0);
    check(step_ok(c, 0.0), "first step", 0);
    fmi2FMUstate s = NULL, t = NULL;
    size_t n = 0;
    fmi2GetFMUstate(c, &t);
    g_scen = "_get_fmu_state";
    set_fault("_get_fmu_state raise");
    EXPECT(fmi2GetFMUstate(c, &s), fmi2Error, "injected fault in _get_fmu_state", "raises");
    check(s == NULL, "no state handed out", 0);
    EXPECT(fmi2GetFMUstate(c, &t), fmi2Error, "injected fault", "raises while overwriting a state");
    set_fault("");
    EXPECT(fmi2SetFMUstate(c, t), fmi2OK, NULL, "the state to overwrite is intact");
    check(step_ok(c, H), "steps on", 0);
    g_scen = "_set_fmu_state";
    set_fault("_set_fmu_state raise");
    EXPECT(fmi2SetFMUstate(c, t), fmi2Error, "injected fault in _set_fmu_state", "raises");
    set_fault("");
    check(step_ok(c, 2 * H), "nothing changed: steps on from 2 ms", 0);
    g_scen = "_fmu_state_to_bytes";
    set_fault("_fmu_state_to_bytes raise");
    EXPECT(fmi2SerializedFMUstateSize(c, t, &n), fmi2Error, "injected fault", "raises");
    set_fault("_fmu_state_to_bytes wrong_type");
    EXPECT(fmi2SerializedFMUstateSize(c, t, &n), fmi2Error, "expected bytes", "returns a str");
    set_fault("");
    EXPECT(fmi2SerializedFMUstateSize(c, t, &n), fmi2OK, NULL, "serializes once the fault is gone");
    char *buf = (char *)malloc(n);
    EXPECT(fmi2SerializeFMUstate(c, t, buf, n), fmi2OK, NULL, "serialize");
    g_scen = "_fmu_state_from_bytes";
    fmi2FMUstate r = NULL;
    set_fault("_fmu_state_from_bytes raise");
    EXPECT(fmi2DeSerializeFMUstate(c, buf, n, &r), fmi2Error, "injected fault", "raises");
    set_fault("_fmu_state_from_bytes wrong_type");
    EXPECT(fmi2DeSerializeFMUstate(c, buf, n, &r), fmi2Error, "FMU state: expected a dict", "returns 42: refused");
    check(r == NULL, "no state handed out", 0);
    set_fault("");
    EXPECT(fmi2DeSerializeFMUstate(c, buf, n, &r), fmi2OK, NULL, "deserializes once the fault is gone");
    EXPECT(fmi2SetFMUstate(c, r), fmi2OK, NULL, "and restores");
    check(step_ok(c, H), "steps on from 1 ms", 0);
    free(buf);
    fmi2FreeInstance(c);
}

static void scen_log_queue(void)
{
    g_scen = "log_queue";
    fmi2Component c = running();
    if (!c) return check(0, "instantiate", 0);
    set_fault("log_queue bad_entries");
    EXPECT(fmi2DoStep(c, 0, H, 1), fmi2Warning, "status out of range", "bad messages: fmi2Warning, logged");
    check(logged("unreadable message") || logged("not a status") || g_nlog >= 2, "bad entries passed on", 0);
    set_fault("log_queue not_a_list");
    EXPECT(fmi2DoStep(c, H, H, 1), fmi2Warning, "expected a list", "log_queue not a list: fmi2Warning");
    set_fault("");
    EXPECT(fmi2DoStep(c, 2 * H, H, 1), fmi2Warning, "expected a list", "stays a warning while broken");
    EXPECT(fmi2Reset(c), fmi2OK, NULL, "reset repairs it");
    fmi2FreeInstance(c);
}

int main(int argc, char **argv)
{
    if (argc != 14) {
        printf("usage\n");
        return 2;
    }
    void *lib = dlopen(argv[1], RTLD_NOW);
    if (!lib) {
        printf("dlopen failed: %s\n", dlerror());
        return 1;
    }
#define F(name)                                                \
    name = (name##TYPE *)dlsym(lib, #name);                    \
    if (!name) {                                               \
        printf("missing %s\n", #name);                         \
        return 3;                                              \
    }
    F(fmi2Instantiate) F(fmi2FreeInstance) F(fmi2SetDebugLogging) F(fmi2SetupExperiment)
    F(fmi2EnterInitializationMode) F(fmi2ExitInitializationMode) F(fmi2Terminate) F(fmi2Reset) F(fmi2GetReal)
    F(fmi2GetInteger) F(fmi2GetBoolean) F(fmi2GetString) F(fmi2SetReal) F(fmi2SetInteger) F(fmi2SetBoolean)
    F(fmi2SetString) F(fmi2GetFMUstate) F(fmi2SetFMUstate) F(fmi2FreeFMUstate) F(fmi2SerializedFMUstateSize)
    F(fmi2SerializeFMUstate) F(fmi2DeSerializeFMUstate) F(fmi2GetDirectionalDerivative)
    F(fmi2SetRealInputDerivatives) F(fmi2GetRealOutputDerivatives) F(fmi2DoStep) F(fmi2CancelStep)
    F(fmi2GetStatus) F(fmi2GetRealStatus) F(fmi2GetIntegerStatus) F(fmi2GetBooleanStatus) F(fmi2GetStringStatus)
    F(fmi2GetTypesPlatform) F(fmi2GetVersion)
#undef F
    URI = argv[2], DIR_ = argv[3], URI_BAD_MODULE = argv[4], URI_BAD_PARAMS = argv[5];
    fmi2ValueReference *vrs[8] = {&VOLT, &FORCE, &STROKE, &RHO_L, &RHO_F, &NN, &SCHEME, &LAND};
    for (int i = 0; i < 8; i++) *vrs[i] = (fmi2ValueReference)strtoul(argv[6 + i], NULL, 10);
    scen_instantiate();
    scen_invalid_instances();
    scen_arguments();
    scen_states();
    scen_mode_faults();
    scen_do_step();
    scen_getters();
    scen_setters();
    scen_state_faults();
    scen_log_queue();
    set_fault("");
    printf("done %d failed\n", g_fail);
    fflush(stdout);
    return 0;
}
