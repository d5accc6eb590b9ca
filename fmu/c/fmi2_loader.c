/* The FMU's binary as the host loads it: finds a Python, then loads the implementation
 * (fmi2_python.c, compiled beside it as <name>-python.so) and forwards every FMI call.
 *
 * Why a separate loader: the implementation needs CPython's shared library. Linked
 * against it, the binary cannot even be loaded where that library is missing, and the
 * host only sees a dlopen error. This file needs nothing but libc and libdl, so
 * fmi2Instantiate can always run and say, through the FMI logger with fmi2Error, what
 * is missing and what to install.
 *
 * Where the Python comes from:
 * - a Python host (fmpy, ...): its own interpreter, which must be the Python version the
 *   FMU was built for (checked: another version is an fmi2Error, not a crash);
 * - a C host: the shared library of the environment named by DFA_FMU_PYTHON (a virtual
 *   environment's folder or a python executable); without the variable, the Python that
 *   built the FMU (resources/python.txt, then the build's library folder), then the
 *   system's search path. The implementation then starts that environment's interpreter
 *   (fmi2_python.c, choose_python).
 *
 * Compiled by fmu/build.py with DFA_PY_MAJOR, DFA_PY_MINOR, DFA_LIBPYTHON (the shared
 * library's file name) and DFA_LIBDIR (its folder at build time).
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <limits.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "fmi2Functions.h"
#include "fmi2_common.h"

#define STR2(x) #x
#define STR(x) STR2(x)

/* every function the implementation exports, in one list (X-macro) */
#define FMI2_FUNCTIONS(X)                                                                                          \
    X(SetDebugLogging) X(Instantiate) X(FreeInstance) X(SetupExperiment) X(EnterInitializationMode)             \
    X(ExitInitializationMode) X(Terminate) X(Reset) X(GetReal) X(GetInteger) X(GetBoolean) X(GetString)          \
    X(SetReal) X(SetInteger) X(SetBoolean) X(SetString) X(GetFMUstate) X(SetFMUstate) X(FreeFMUstate)            \
    X(SerializedFMUstateSize) X(SerializeFMUstate) X(DeSerializeFMUstate) X(GetDirectionalDerivative)           \
    X(SetRealInputDerivatives) X(GetRealOutputDerivatives) X(DoStep) X(CancelStep) X(GetStatus) X(GetRealStatus) \
    X(GetIntegerStatus) X(GetBooleanStatus) X(GetStringStatus)

static struct {
#define FIELD(f) fmi2##f##TYPE *f;
    FMI2_FUNCTIONS(FIELD)
#undef FIELD
} impl;
static int loaded; /* impl is complete */
static pthread_mutex_t load_lock = PTHREAD_MUTEX_INITIALIZER;

/* The folder where the shared library of the Python at `path` (a venv folder or a
 * python executable) lives: a venv's base installation (pyvenv.cfg's home), else the
 * executable's own installation (<prefix>/bin/python -> <prefix>/lib). */
static int libdir_of(const char *path, char *out, size_t n)
{
    char exe[PATH_MAX], cfg[PATH_MAX], real[PATH_MAX];
    if (!python_of(path, exe, sizeof exe, cfg, sizeof cfg)) return 0;
    FILE *f = fopen(cfg, "r");
    if (f) {
        char line[PATH_MAX], home[PATH_MAX] = {0};
        while (fgets(line, sizeof line, f)) {
            char *eq = strchr(line, '=');
            if (strncmp(line, "home", 4) == 0 && eq) {
                char *v = eq + 1;
                while (*v == ' ') v++;
                v[strcspn(v, "\r\n")] = 0;
                snprintf(home, sizeof home, "%s", v);
            }
        }
        fclose(f);
        if (home[0]) {
            snprintf(out, n, "%s/../lib", home);
            return 1;
        }
    }
    if (!realpath(exe, real)) return 0;
    char *s = strrchr(real, '/');
    if (!s) return 0;
    *s = 0;
    snprintf(out, n, "%s/../lib", real);
    return 1;
}

/* Load libpython into the global scope (C hosts). Returns 1, or 0 with msg filled. */
static int load_python(const char *resources, char *msg, size_t n)
{
    const char *lib = DFA_LIBPYTHON;
    const char *env = getenv("DFA_FMU_PYTHON");
    char tried[3 * PATH_MAX] = "", dir[PATH_MAX], path[PATH_MAX];
    const char *err = "";
    char *recorded = NULL;
    const char *cands[3];
    int nc = 0;
    if (env && env[0]) { /* named explicitly: that one or nothing */
        if (!libdir_of(env, dir, sizeof dir)) {
            snprintf(msg, n, "fmi2Instantiate: DFA_FMU_PYTHON names %s: no Python there; set DFA_FMU_PYTHON to a "
                             "Python %d.%d environment (a virtual environment's folder or its python) with the FMU's "
                             "runtime dependencies (resources/RUNTIME.txt)", env, DFA_PY_MAJOR, DFA_PY_MINOR);
            return 0;
        }
        cands[nc++] = strdup(dir);
    } else {
        recorded = first_line(resources, "python.txt");
        if (recorded && libdir_of(recorded, dir, sizeof dir)) cands[nc++] = strdup(dir);
        cands[nc++] = strdup(DFA_LIBDIR);
        cands[nc++] = NULL; /* the system's search path */
    }
    int ok = 0;
    for (int i = 0; i < nc && !ok; i++) {
        if (cands[i]) snprintf(path, sizeof path, "%s/%s", cands[i], lib);
        else snprintf(path, sizeof path, "%s", lib);
        ok = dlopen(path, RTLD_NOW | RTLD_GLOBAL) != NULL;
        if (!ok) {
            const char *e = dlerror();
            err = e ? e : "";
            size_t k = strlen(tried);
            snprintf(tried + k, sizeof tried - k, "%s%s", k ? ", " : "", path);
        }
    }
    for (int i = 0; i < nc; i++) free((void *)cands[i]);
    if (!ok)
        snprintf(msg, n, "fmi2Instantiate: this FMU runs on CPython %d.%d and needs its shared library %s, which "
                         "could not be loaded (tried %s; %s): install CPython %d.%d with its shared library (built "
                         "with --enable-shared; Debian/Ubuntu: libpython%d.%d) and, in an environment of it, the FMU's "
                         "runtime dependencies (resources/RUNTIME.txt); name that environment in DFA_FMU_PYTHON%s%s",
                 DFA_PY_MAJOR, DFA_PY_MINOR, lib, tried, err, DFA_PY_MAJOR, DFA_PY_MINOR, DFA_PY_MAJOR, DFA_PY_MINOR,
                 recorded ? " (without it: the Python that built the FMU, " : "", recorded ? recorded : "");
    if (!ok && recorded) strncat(msg, ")", n - strlen(msg) - 1);
    free(recorded);
    return ok;
}

/* A Python already in the process (a Python host, or an earlier instance): is it ours? */
static int python_present(char *msg, size_t n)
{
    const char *(*version)(void) = (const char *(*)(void))dlsym(RTLD_DEFAULT, "Py_GetVersion");
    if (!version) return 0;
    int major = 0, minor = 0;
    if (sscanf(version(), "%d.%d", &major, &minor) == 2 && (major != DFA_PY_MAJOR || minor != DFA_PY_MINOR))
        snprintf(msg, n, "fmi2Instantiate: this FMU was built for Python %d.%d; the host runs Python %d.%d: run it "
                         "from a Python %d.%d host, or rebuild it there (dfa fmu build)", DFA_PY_MAJOR, DFA_PY_MINOR,
                 major, minor, DFA_PY_MAJOR, DFA_PY_MINOR);
    return 1;
}

/* Load Python (if needed) and the implementation; 1 on success, else 0 with msg. */
static int load(const char *resources, char *msg, size_t n)
{
    msg[0] = 0;
    if (!python_present(msg, n)) {
        if (!load_python(resources, msg, n)) return 0;
    } else if (msg[0]) {
        return 0;
    }
    Dl_info info;
    char path[PATH_MAX];
    if (!dladdr((void *)&load, &info) || !info.dli_fname) {
        snprintf(msg, n, "fmi2Instantiate: cannot find the FMU's binary folder");
        return 0;
    }
    snprintf(path, sizeof path, "%s", info.dli_fname);
    char *dot = strrchr(path, '.');
    if (dot && strcmp(dot, ".so") == 0) *dot = 0;
    strncat(path, "-python.so", sizeof path - strlen(path) - 1);
    void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        snprintf(msg, n, "fmi2Instantiate: cannot load the FMU's implementation %s: %s", path, dlerror());
        return 0;
    }
#define LOOKUP(f)                                                                          \
    if (!(impl.f = (fmi2##f##TYPE *)dlsym(h, "fmi2" #f))) {                                \
        snprintf(msg, n, "fmi2Instantiate: %s has no fmi2" #f " (a broken FMU)", path); \
        return 0;                                                                          \
    }
    FMI2_FUNCTIONS(LOOKUP)
#undef LOOKUP
    return 1;
}

/* ------------------------------------------------------------------ the FMI functions */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resourceLocation,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean loggingOn)
{
    pthread_mutex_lock(&load_lock);
    if (!loaded) {
        char msg[4 * PATH_MAX], *res = NULL;
        if (resourceLocation) res = uri_to_path(resourceLocation); /* to read python.txt */
        int ok = load(res ? res : ".", msg, sizeof msg);
        free(res);
        if (ok) __atomic_store_n(&loaded, 1, __ATOMIC_RELEASE);
        else {
            memset(&impl, 0, sizeof impl);
            pthread_mutex_unlock(&load_lock);
            log_escaped(cb, name, fmi2Error, "logStatusError", msg);
            return NULL;
        }
    }
    pthread_mutex_unlock(&load_lock);
    return impl.Instantiate(name, type, guid, resourceLocation, cb, visible, loggingOn);
}

/* Before a successful instantiation there is no instance: every call with one is refused
 * (fmi2Error), as the implementation refuses unknown instances. */
#define READY(fail) \
    if (!__atomic_load_n(&loaded, __ATOMIC_ACQUIRE)) return fail;

void fmi2FreeInstance(fmi2Component c)
{
    READY()
    impl.FreeInstance(c);
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[])
{
    READY(fmi2Error) return impl.SetDebugLogging(c, on, n, cats);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDefined, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDefined, fmi2Real stop)
{
    READY(fmi2Error) return impl.SetupExperiment(c, tolDefined, tol, start, stopDefined, stop);
}

#define SIMPLE(f) \
    fmi2Status fmi2##f(fmi2Component c) { READY(fmi2Error) return impl.f(c); }
SIMPLE(EnterInitializationMode)
SIMPLE(ExitInitializationMode)
SIMPLE(Terminate)
SIMPLE(Reset)
SIMPLE(CancelStep)

#define ACCESS(f, T)                                                                     \
    fmi2Status fmi2##f(fmi2Component c, const fmi2ValueReference vr[], size_t n, T v[]) \
    {                                                                                    \
        READY(fmi2Error) return impl.f(c, vr, n, v);                                     \
    }
ACCESS(GetReal, fmi2Real)
ACCESS(GetInteger, fmi2Integer)
ACCESS(GetBoolean, fmi2Boolean)
ACCESS(GetString, fmi2String)
ACCESS(SetReal, const fmi2Real)
ACCESS(SetInteger, const fmi2Integer)
ACCESS(SetBoolean, const fmi2Boolean)
ACCESS(SetString, const fmi2String)

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { READY(fmi2Error) return impl.GetFMUstate(c, s); }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { READY(fmi2Error) return impl.SetFMUstate(c, s); }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { READY(fmi2Error) return impl.FreeFMUstate(c, s); }

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *size)
{
    READY(fmi2Error) return impl.SerializedFMUstateSize(c, s, size);
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte out[], size_t size)
{
    READY(fmi2Error) return impl.SerializeFMUstate(c, s, out, size);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte in[], size_t size, fmi2FMUstate *s)
{
    READY(fmi2Error) return impl.DeSerializeFMUstate(c, in, size, s);
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real dz[])
{
    READY(fmi2Error) return impl.GetDirectionalDerivative(c, u, nu, z, nz, dv, dz);
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    READY(fmi2Error) return impl.SetRealInputDerivatives(c, vr, n, order, value);
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[])
{
    READY(fmi2Error) return impl.GetRealOutputDerivatives(c, vr, n, order, value);
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior)
{
    READY(fmi2Error) return impl.DoStep(c, t, h, noSetPrior);
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v)
{
    READY(fmi2Error) return impl.GetStatus(c, s, v);
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v)
{
    READY(fmi2Error) return impl.GetRealStatus(c, s, v);
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v)
{
    READY(fmi2Error) return impl.GetIntegerStatus(c, s, v);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v)
{
    READY(fmi2Error) return impl.GetBooleanStatus(c, s, v);
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v)
{
    READY(fmi2Error) return impl.GetStringStatus(c, s, v);
}
