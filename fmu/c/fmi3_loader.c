/* The FMI 3.0 FMU's binary as the host loads it: finds a Python, then loads the
 * implementation (fmi3_python.c, compiled beside it as <name>-python.so) and forwards
 * every FMI 3.0 call. The FMI 3.0 counterpart of fmi2_loader.c (see its header: why a
 * separate loader, where the Python comes from); what they share is loader_common.h,
 * what it shares with fmi3_python.c fmi3_common.h.
 * Needs nothing but libc and libdl: fmi3InstantiateCoSimulation can always run and say,
 * through the host's logger with fmi3Error, what is missing.
 *
 * Compiled by fmu/build.py with DFA_PY_MAJOR, DFA_PY_MINOR, DFA_LIBPYTHON and DFA_LIBDIR.
 */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <limits.h>
#include <pthread.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2_common.h" /* first_line, uri_to_path, python_of */
#include "fmi3_common.h" /* fmi3GetVersion, log_early, resource_dir, the other interface types */
#define DFA_WHERE "fmi3InstantiateCoSimulation"
#include "loader_common.h"

/* every function the implementation exports but instantiation and freeing, with its
 * parameters and the arguments passed on (X-macro) */
#define FMI3_FORWARDED(X)                                                                                           \
    X(SetDebugLogging, (fmi3Instance i, fmi3Boolean on, size_t n, const fmi3String cats[]), (i, on, n, cats))       \
    X(EnterInitializationMode, (fmi3Instance i, fmi3Boolean tolDefined, fmi3Float64 tol, fmi3Float64 start,         \
          fmi3Boolean stopDefined, fmi3Float64 stop), (i, tolDefined, tol, start, stopDefined, stop))               \
    X(ExitInitializationMode, (fmi3Instance i), (i))                                                                \
    X(EnterEventMode, (fmi3Instance i), (i))                                                                        \
    X(Terminate, (fmi3Instance i), (i))                                                                             \
    X(Reset, (fmi3Instance i), (i))                                                                                 \
    X(GetFloat32, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3Float32 v[], size_t nv), (i, vr,  \
          nvr, v, nv))                                                                                              \
    X(GetFloat64, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 v[], size_t nv), (i, vr,  \
          nvr, v, nv))                                                                                              \
    X(GetInt8, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3Int8 v[], size_t nv), (i, vr, nvr,   \
          v, nv))                                                                                                   \
    X(GetUInt8, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3UInt8 v[], size_t nv), (i, vr,      \
          nvr, v, nv))                                                                                              \
    X(GetInt16, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3Int16 v[], size_t nv), (i, vr,      \
          nvr, v, nv))                                                                                              \
    X(GetUInt16, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3UInt16 v[], size_t nv), (i, vr,    \
          nvr, v, nv))                                                                                              \
    X(GetInt32, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3Int32 v[], size_t nv), (i, vr,      \
          nvr, v, nv))                                                                                              \
    X(GetUInt32, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3UInt32 v[], size_t nv), (i, vr,    \
          nvr, v, nv))                                                                                              \
    X(GetInt64, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3Int64 v[], size_t nv), (i, vr,      \
          nvr, v, nv))                                                                                              \
    X(GetUInt64, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 v[], size_t nv), (i, vr,    \
          nvr, v, nv))                                                                                              \
    X(GetBoolean, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3Boolean v[], size_t nv), (i, vr,  \
          nvr, v, nv))                                                                                              \
    X(GetString, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3String v[], size_t nv), (i, vr,    \
          nvr, v, nv))                                                                                              \
    X(GetBinary, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, size_t sz[], fmi3Binary v[], size_t    \
          nv), (i, vr, nvr, sz, v, nv))                                                                             \
    X(GetClock, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3Clock v[]), (i, vr, nvr, v))        \
    X(SetFloat32, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3Float32 v[], size_t nv),    \
          (i, vr, nvr, v, nv))                                                                                      \
    X(SetFloat64, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 v[], size_t nv),    \
          (i, vr, nvr, v, nv))                                                                                      \
    X(SetInt8, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3Int8 v[], size_t nv), (i, vr,  \
          nvr, v, nv))                                                                                              \
    X(SetUInt8, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3UInt8 v[], size_t nv), (i,    \
          vr, nvr, v, nv))                                                                                          \
    X(SetInt16, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3Int16 v[], size_t nv), (i,    \
          vr, nvr, v, nv))                                                                                          \
    X(SetUInt16, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3UInt16 v[], size_t nv), (i,  \
          vr, nvr, v, nv))                                                                                          \
    X(SetInt32, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 v[], size_t nv), (i,    \
          vr, nvr, v, nv))                                                                                          \
    X(SetUInt32, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3UInt32 v[], size_t nv), (i,  \
          vr, nvr, v, nv))                                                                                          \
    X(SetInt64, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3Int64 v[], size_t nv), (i,    \
          vr, nvr, v, nv))                                                                                          \
    X(SetUInt64, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3UInt64 v[], size_t nv), (i,  \
          vr, nvr, v, nv))                                                                                          \
    X(SetBoolean, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3Boolean v[], size_t nv),    \
          (i, vr, nvr, v, nv))                                                                                      \
    X(SetString, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3String v[], size_t nv), (i,  \
          vr, nvr, v, nv))                                                                                          \
    X(SetBinary, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const size_t sz[], const fmi3Binary    \
          v[], size_t nv), (i, vr, nvr, sz, v, nv))                                                                 \
    X(SetClock, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock v[]), (i, vr, nvr, v))  \
    X(GetNumberOfVariableDependencies, (fmi3Instance i, fmi3ValueReference vr1, size_t* n), (i, vr1, n))            \
    X(GetVariableDependencies, (fmi3Instance i, fmi3ValueReference dep, size_t ei[], fmi3ValueReference ind[],      \
          size_t eii[], fmi3DependencyKind kinds[], size_t n), (i, dep, ei, ind, eii, kinds, n))                    \
    X(GetFMUState, (fmi3Instance i, fmi3FMUState* s), (i, s))                                                       \
    X(SetFMUState, (fmi3Instance i, fmi3FMUState s), (i, s))                                                        \
    X(FreeFMUState, (fmi3Instance i, fmi3FMUState* s), (i, s))                                                      \
    X(SerializedFMUStateSize, (fmi3Instance i, fmi3FMUState s, size_t* n), (i, s, n))                               \
    X(SerializeFMUState, (fmi3Instance i, fmi3FMUState s, fmi3Byte b[], size_t n), (i, s, b, n))                    \
    X(DeserializeFMUState, (fmi3Instance i, const fmi3Byte b[], size_t n, fmi3FMUState* s), (i, b, n, s))           \
    X(GetDirectionalDerivative, (fmi3Instance i, const fmi3ValueReference u[], size_t nu, const fmi3ValueReference  \
          k[], size_t nk, const fmi3Float64 seed[], size_t ns, fmi3Float64 sens[], size_t nsens), (i, u, nu, k,     \
          nk, seed, ns, sens, nsens))                                                                               \
    X(GetAdjointDerivative, (fmi3Instance i, const fmi3ValueReference u[], size_t nu, const fmi3ValueReference      \
          k[], size_t nk, const fmi3Float64 seed[], size_t ns, fmi3Float64 sens[], size_t nsens), (i, u, nu, k,     \
          nk, seed, ns, sens, nsens))                                                                               \
    X(EnterConfigurationMode, (fmi3Instance i), (i))                                                                \
    X(ExitConfigurationMode, (fmi3Instance i), (i))                                                                 \
    X(GetIntervalDecimal, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 iv[],             \
          fmi3IntervalQualifier q[]), (i, vr, nvr, iv, q))                                                          \
    X(GetIntervalFraction, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 cn[], fmi3UInt64  \
          res[], fmi3IntervalQualifier q[]), (i, vr, nvr, cn, res, q))                                              \
    X(GetShiftDecimal, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 sh[]), (i, vr, nvr,  \
          sh))                                                                                                      \
    X(GetShiftFraction, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 cn[], fmi3UInt64     \
          res[]), (i, vr, nvr, cn, res))                                                                            \
    X(SetIntervalDecimal, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 iv[]), (i,  \
          vr, nvr, iv))                                                                                             \
    X(SetIntervalFraction, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3UInt64 cn[],       \
          const fmi3UInt64 res[]), (i, vr, nvr, cn, res))                                                           \
    X(SetShiftDecimal, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 sh[]), (i,     \
          vr, nvr, sh))                                                                                             \
    X(SetShiftFraction, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3UInt64 cn[], const    \
          fmi3UInt64 res[]), (i, vr, nvr, cn, res))                                                                 \
    X(EvaluateDiscreteStates, (fmi3Instance i), (i))                                                                \
    X(UpdateDiscreteStates, (fmi3Instance i, fmi3Boolean* a, fmi3Boolean* ts, fmi3Boolean* c, fmi3Boolean* d,       \
          fmi3Boolean* e, fmi3Float64* f), (i, a, ts, c, d, e, f))                                                  \
    X(EnterContinuousTimeMode, (fmi3Instance i), (i))                                                               \
    X(CompletedIntegratorStep, (fmi3Instance i, fmi3Boolean nsp, fmi3Boolean* eem, fmi3Boolean* ts), (i, nsp, eem,  \
          ts))                                                                                                      \
    X(SetTime, (fmi3Instance i, fmi3Float64 t), (i, t))                                                             \
    X(SetContinuousStates, (fmi3Instance i, const fmi3Float64 x[], size_t n), (i, x, n))                            \
    X(GetContinuousStateDerivatives, (fmi3Instance i, fmi3Float64 dx[], size_t n), (i, dx, n))                      \
    X(GetEventIndicators, (fmi3Instance i, fmi3Float64 z[], size_t n), (i, z, n))                                   \
    X(GetContinuousStates, (fmi3Instance i, fmi3Float64 x[], size_t n), (i, x, n))                                  \
    X(GetNominalsOfContinuousStates, (fmi3Instance i, fmi3Float64 nom[], size_t n), (i, nom, n))                    \
    X(GetNumberOfEventIndicators, (fmi3Instance i, size_t* n), (i, n))                                              \
    X(GetNumberOfContinuousStates, (fmi3Instance i, size_t* n), (i, n))                                             \
    X(EnterStepMode, (fmi3Instance i), (i))                                                                         \
    X(GetOutputDerivatives, (fmi3Instance i, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 ord[],      \
          fmi3Float64 v[], size_t nv), (i, vr, nvr, ord, v, nv))                                                    \
    X(DoStep, (fmi3Instance i, fmi3Float64 t, fmi3Float64 h, fmi3Boolean nsp, fmi3Boolean* ehn, fmi3Boolean* ts,    \
          fmi3Boolean* er, fmi3Float64* lst), (i, t, h, nsp, ehn, ts, er, lst))                                     \
    X(ActivateModelPartition, (fmi3Instance i, fmi3ValueReference clk, fmi3Float64 t), (i, clk, t))                 

static struct {
    fmi3InstantiateCoSimulationTYPE *InstantiateCoSimulation;
    fmi3FreeInstanceTYPE *FreeInstance;
#define FIELD(f, params, args) fmi3##f##TYPE *f;
    FMI3_FORWARDED(FIELD)
#undef FIELD
} impl;

/* The implementation's functions (h, at path) into impl; 1 on success, else 0 with msg. */
static int lookup(void *h, const char *path, char *msg, size_t n)
{
#define LOOKUP(f, params, args) DFA_LOOKUP(fmi3, f)
    LOOKUP(InstantiateCoSimulation, , )
    LOOKUP(FreeInstance, , )
    FMI3_FORWARDED(LOOKUP)
#undef LOOKUP
    return 1;
}

/* ------------------------------------------------------------------ the FMI functions */
fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resourcePath,
                                         fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
                                         fmi3Boolean earlyReturnAllowed, const fmi3ValueReference required[],
                                         size_t nRequired, fmi3InstanceEnvironment env,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    char msg[4 * PATH_MAX];
    if (!ensure_loaded(resourcePath, resource_dir, lookup, &impl, sizeof impl, msg, sizeof msg)) {
        log_early(logMessage, env, msg);
        return NULL;
    }
    return impl.InstantiateCoSimulation(name, token, resourcePath, visible, loggingOn, eventModeUsed,
                                        earlyReturnAllowed, required, nRequired, env, logMessage, intermediateUpdate);
}

void fmi3FreeInstance(fmi3Instance i)
{
    READY()
    impl.FreeInstance(i);
}

#define FORWARD(f, params, args) \
    fmi3Status fmi3##f params { READY(fmi3Error) return impl.f args; }
FMI3_FORWARDED(FORWARD)
#undef FORWARD
