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
#define DFA_WHERE "fmi2Instantiate"
#include "loader_common.h"

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

/* The implementation's functions (h, at path) into impl; 1 on success, else 0 with msg. */
static int lookup(void *h, const char *path, char *msg, size_t n)
{
#define LOOKUP(f) DFA_LOOKUP(fmi2, f)
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
    char msg[4 * PATH_MAX];
    if (!ensure_loaded(resourceLocation, uri_to_path, lookup, &impl, sizeof impl, msg, sizeof msg)) {
        log_escaped(cb, name, fmi2Error, "logStatusError", msg);
        return NULL;
    }
    return impl.Instantiate(name, type, guid, resourceLocation, cb, visible, loggingOn);
}

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
