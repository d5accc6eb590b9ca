/* FMI 3.0 co-simulation binary for a pythonfmu3 slave class (compiled by fmu/build.py for
 * `dfa fmu build --fmi 3`, in place of pythonfmu3's own library). The Python side is
 * pythonfmu3's Fmi3Slave API unchanged (the actuator: fmu/dfa_actuator3.py).
 *
 * Why our own: pythonfmu3 0.3.4's library (C++) reports every Python exception (a value
 * the slave refuses, an unknown value reference) as fmi3Fatal and releases the slave's
 * Python objects while keeping its pointers to them: the next call, or the host's exit,
 * uses freed memory (fmpy: a segmentation fault at exit). Its unimplemented functions
 * (fmi3GetInt8, fmi3GetClock, ...) throw C++ exceptions through the C API, which aborts
 * the host. It keeps no state machine, checks no argument, drops fmi3EnterInitialization-
 * Mode's start and stop time, and leaves libpython undeclared (a C host cannot load it).
 *
 * How: this file compiles fmi2_python.c for FMI 3.0 (DFA_FMI 3: the instance registry,
 * state machine, argument checks, Python calls, fast path, FMU states and serialization
 * of the FMI 2.0 binary, with FMI 3.0's function and state names and pythonfmu3's Python
 * API) and maps every FMI 3.0 function onto it, so both binaries give the same
 * guarantees (see fmi2_python.c's header and the README's table). FMI 3.0 specifics:
 * - fmi3EnterInitializationMode takes the experiment (FMI 2.0's fmi2SetupExperiment):
 *   checked and passed to the slave's setup_experiment, then enter_initialization_mode.
 * - Float64, Int32, Boolean (a C bool, converted) and String variables, all scalars
 *   (nValues must equal nValueReferences); a call for another type (Float32, Int8, ...,
 *   Binary, Clock) is fmi3Error naming the variable's type.
 * - No event mode (hasEventMode = false: instantiating with eventModeUsed = true is
 *   refused), no intermediate update, no early return, no clocks, no structural
 *   parameters, no model exchange or scheduled execution: each of those functions
 *   returns fmi3Error with a log line. doStep sets eventHandlingNeeded, earlyReturn to
 *   false and lastSuccessfulTime to the time reached; terminateSimulation is true only
 *   when the slave did not complete the step (fmi3Discard).
 * - The host's logger gets the message as it is (FMI 3.0 loggers do not format).
 */
#define DFA_FMI 3
#include "fmi2_python.c"

#include <stdbool.h>

#include "fmi3_common.h" /* fmi3GetVersion, log_early, resource_dir, the other interface types */

/* A function this FMU does not provide: fmi3Error, and a log line on a live instance. */
static fmi3Status refuse(fmi3Instance inst, const char *fn, const char *why)
{
    Comp *c = registry_find(inst);
    if (c) logf_(c, fmi2Error, "%s: %s", fn, why);
    return fmi3Error;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resourcePath,
                                         fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
                                         fmi3Boolean earlyReturnAllowed, const fmi3ValueReference required[],
                                         size_t nRequired, fmi3InstanceEnvironment env,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)token, (void)earlyReturnAllowed, (void)required, (void)intermediateUpdate;
    if (eventModeUsed) {
        log_early(logMessage, env, API_INSTANTIATE ": eventModeUsed = true, but this FMU has no event mode "
                                              "(hasEventMode = false): instantiate it with eventModeUsed = false");
        return NULL;
    }
    if (nRequired > 0) {
        log_early(logMessage, env, API_INSTANTIATE ": requiredIntermediateVariables given, but this FMU provides no "
                                              "intermediate update (providesIntermediateUpdate = false)");
        return NULL;
    }
    if (!resourcePath) {
        log_early(logMessage, env, API_INSTANTIATE ": no resourcePath given");
        return NULL;
    }
    Comp *c = (Comp *)calloc(1, sizeof(Comp));
    if (!c) return NULL;
    c->log3 = logMessage; /* without a logger the instance runs, silently */
    c->env3 = env;
    c->name = strdup(name ? name : "");
    c->resources = resource_dir(resourcePath);
    c->logging = loggingOn ? 1 : 0;
    c->visible = visible ? 1 : 0;
    if (!c->name || !c->resources) {
        log_early(logMessage, env, API_INSTANTIATE ": out of memory");
        free_comp(c);
        return NULL;
    }
    return (fmi3Instance)instantiate(c);
}

void fmi3FreeInstance(fmi3Instance inst) { fmi2FreeInstance(inst); }

fmi3Status fmi3SetDebugLogging(fmi3Instance inst, fmi3Boolean on, size_t n, const fmi3String cats[])
{
    return (fmi3Status)fmi2SetDebugLogging(inst, on ? fmi2True : fmi2False, n, cats);
}

/* ------------------------------------------------------------------ modes */
fmi3Status fmi3EnterInitializationMode(fmi3Instance inst, fmi3Boolean tolDefined, fmi3Float64 tol,
                                       fmi3Float64 start, fmi3Boolean stopDefined, fmi3Float64 stop)
{
    /* the experiment first (checked, then the slave's setup_experiment): refused, the
     * instance stays in instantiated with nothing changed */
    fmi2Status st = fmi2SetupExperiment(inst, tolDefined ? fmi2True : fmi2False, tol, start,
                                        stopDefined ? fmi2True : fmi2False, stop);
    if (st > fmi2Warning) return (fmi3Status)st;
    fmi2Status st2 = fmi2EnterInitializationMode(inst);
    return (fmi3Status)(st2 > st ? st2 : st);
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance inst) { return (fmi3Status)fmi2ExitInitializationMode(inst); }
fmi3Status fmi3Terminate(fmi3Instance inst) { return (fmi3Status)fmi2Terminate(inst); }
fmi3Status fmi3Reset(fmi3Instance inst) { return (fmi3Status)fmi2Reset(inst); }

#define NO_EVENT_MODE "this FMU has no event mode (hasEventMode = false)"
fmi3Status fmi3EnterEventMode(fmi3Instance inst) { return refuse(inst, "fmi3EnterEventMode", NO_EVENT_MODE); }
fmi3Status fmi3EnterStepMode(fmi3Instance inst) { return refuse(inst, "fmi3EnterStepMode", NO_EVENT_MODE); }
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance inst)
{
    return refuse(inst, "fmi3EvaluateDiscreteStates", NO_EVENT_MODE);
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance inst, fmi3Boolean *needUpdate, fmi3Boolean *terminate,
                                    fmi3Boolean *nominalsChanged, fmi3Boolean *valuesChanged,
                                    fmi3Boolean *nextDefined, fmi3Float64 *nextTime)
{
    (void)needUpdate, (void)terminate, (void)nominalsChanged, (void)valuesChanged, (void)nextDefined, (void)nextTime;
    return refuse(inst, "fmi3UpdateDiscreteStates", NO_EVENT_MODE);
}

#define NO_STRUCTURAL "this FMU has no structural parameters (no configuration mode)"
fmi3Status fmi3EnterConfigurationMode(fmi3Instance inst)
{
    return refuse(inst, "fmi3EnterConfigurationMode", NO_STRUCTURAL);
}
fmi3Status fmi3ExitConfigurationMode(fmi3Instance inst)
{
    return refuse(inst, "fmi3ExitConfigurationMode", NO_STRUCTURAL);
}

/* ------------------------------------------------------------------ variables */
/* Every variable of this FMU is a scalar: nValues must be nValueReferences. */
static int scalars(fmi3Instance inst, enum Fn fn, size_t nvr, size_t nValues)
{
    if (nValues == nvr) return 1;
    Comp *c = registry_find(inst);
    if (c) logf_(c, fmi2Error, "%s: nValues = %zu, expected nValueReferences = %zu (every variable of this FMU is a "
                               "scalar)", TABLE[fn].name, nValues, nvr);
    return 0;
}

fmi3Status fmi3GetFloat64(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[],
                          size_t nValues)
{
    if (!scalars(inst, F_GetReal, nvr, nValues)) return fmi3Error;
    return (fmi3Status)fmi2GetReal(inst, vr, nvr, values);
}

fmi3Status fmi3SetFloat64(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 values[],
                          size_t nValues)
{
    if (!scalars(inst, F_SetReal, nvr, nValues)) return fmi3Error;
    return (fmi3Status)fmi2SetReal(inst, vr, nvr, values);
}

/* fmi3Int32 is fmi2Integer (int32 on the platforms this builds for) */
fmi3Status fmi3GetInt32(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, fmi3Int32 values[],
                        size_t nValues)
{
    if (!scalars(inst, F_GetInteger, nvr, nValues)) return fmi3Error;
    return (fmi3Status)fmi2GetInteger(inst, vr, nvr, (fmi2Integer *)values);
}

fmi3Status fmi3SetInt32(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 values[],
                        size_t nValues)
{
    if (!scalars(inst, F_SetInteger, nvr, nValues)) return fmi3Error;
    return (fmi3Status)fmi2SetInteger(inst, vr, nvr, (const fmi2Integer *)values);
}

fmi3Status fmi3GetString(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, fmi3String values[],
                         size_t nValues)
{
    if (!scalars(inst, F_GetString, nvr, nValues)) return fmi3Error;
    return (fmi3Status)fmi2GetString(inst, vr, nvr, values);
}

fmi3Status fmi3SetString(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, const fmi3String values[],
                         size_t nValues)
{
    if (!scalars(inst, F_SetString, nvr, nValues)) return fmi3Error;
    return (fmi3Status)fmi2SetString(inst, vr, nvr, values);
}

/* Booleans: fmi3Boolean is a C bool, fmi2Boolean an int: through a buffer of ints. */
static fmi2Boolean *bool_buffer(fmi3Instance inst, enum Fn fn, size_t n)
{
    fmi2Boolean *b = n <= SIZE_MAX / sizeof(fmi2Boolean) ? (fmi2Boolean *)malloc(n * sizeof(fmi2Boolean)) : NULL;
    Comp *c = b ? NULL : registry_find(inst);
    if (c) logf_(c, fmi2Error, "%s: out of memory for %zu values", TABLE[fn].name, n);
    return b;
}

fmi3Status fmi3GetBoolean(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, fmi3Boolean values[],
                          size_t nValues)
{
    if (!scalars(inst, F_GetBoolean, nvr, nValues)) return fmi3Error;
    if (nvr == 0 || !values) return (fmi3Status)fmi2GetBoolean(inst, vr, nvr, NULL); /* its checks and message */
    fmi2Boolean *b = bool_buffer(inst, F_GetBoolean, nvr);
    if (!b) return fmi3Error;
    fmi2Status st = fmi2GetBoolean(inst, vr, nvr, b);
    if (st <= fmi2Warning)
        for (size_t i = 0; i < nvr; i++) values[i] = b[i] != fmi2False;
    free(b);
    return (fmi3Status)st;
}

fmi3Status fmi3SetBoolean(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, const fmi3Boolean values[],
                          size_t nValues)
{
    if (!scalars(inst, F_SetBoolean, nvr, nValues)) return fmi3Error;
    if (nvr == 0 || !values) return (fmi3Status)fmi2SetBoolean(inst, vr, nvr, NULL);
    fmi2Boolean *b = bool_buffer(inst, F_SetBoolean, nvr);
    if (!b) return fmi3Error;
    for (size_t i = 0; i < nvr; i++) b[i] = values[i] ? fmi2True : fmi2False;
    fmi2Status st = fmi2SetBoolean(inst, vr, nvr, b);
    free(b);
    return (fmi3Status)st;
}

/* A type this FMU has no variables of: fmi3Error naming the first reference's type
 * (nothing read or written). No references: nothing to do. */
static fmi3Status other_type(fmi3Instance inst, const char *fn, const char *type, const fmi3ValueReference vr[],
                             size_t nvr)
{
    Comp *c = registry_find(inst);
    if (!c) return fmi3Error;
    if (nvr == 0) return fmi3OK;
    if (!vr) return (fmi3Status)logf_(c, fmi2Error, "%s: valueReferences[] is NULL", fn);
    const Var *v = vr[0] < c->nvars ? &c->vars[vr[0]] : NULL;
    if (!v || v->kind == K_NONE)
        return (fmi3Status)logf_(c, fmi2Error, "%s: value reference %u (vr[0]) is not a variable of this FMU", fn,
                                 vr[0]);
    return (fmi3Status)logf_(c, fmi2Error, "%s: value reference %u (%s) is a variable of type %s, not %s (this FMU has "
                                           "no %s variables)", fn, vr[0], v->name, KIND_NAMES[v->kind], type, type);
}

#define OTHER_TYPE(T, CT)                                                                                         \
    fmi3Status fmi3Get##T(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, CT values[], size_t nv)  \
    {                                                                                                             \
        (void)values, (void)nv;                                                                                   \
        return other_type(inst, "fmi3Get" #T, #T, vr, nvr);                                                       \
    }                                                                                                             \
    fmi3Status fmi3Set##T(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, const CT values[],       \
                          size_t nv)                                                                              \
    {                                                                                                             \
        (void)values, (void)nv;                                                                                   \
        return other_type(inst, "fmi3Set" #T, #T, vr, nvr);                                                       \
    }
OTHER_TYPE(Float32, fmi3Float32)
OTHER_TYPE(Int8, fmi3Int8)
OTHER_TYPE(UInt8, fmi3UInt8)
OTHER_TYPE(Int16, fmi3Int16)
OTHER_TYPE(UInt16, fmi3UInt16)
OTHER_TYPE(UInt32, fmi3UInt32)
OTHER_TYPE(Int64, fmi3Int64)
OTHER_TYPE(UInt64, fmi3UInt64)

fmi3Status fmi3GetBinary(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, size_t sizes[],
                         fmi3Binary values[], size_t nv)
{
    (void)sizes, (void)values, (void)nv;
    return other_type(inst, "fmi3GetBinary", "Binary", vr, nvr);
}

fmi3Status fmi3SetBinary(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, const size_t sizes[],
                         const fmi3Binary values[], size_t nv)
{
    (void)sizes, (void)values, (void)nv;
    return other_type(inst, "fmi3SetBinary", "Binary", vr, nvr);
}

fmi3Status fmi3GetClock(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, fmi3Clock values[])
{
    (void)values;
    return other_type(inst, "fmi3GetClock", "Clock", vr, nvr);
}

fmi3Status fmi3SetClock(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock values[])
{
    (void)values;
    return other_type(inst, "fmi3SetClock", "Clock", vr, nvr);
}

/* ------------------------------------------------------------------ clocks (none) */
#define NO_CLOCKS "this FMU has no clocks"
fmi3Status fmi3GetIntervalDecimal(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 iv[],
                                  fmi3IntervalQualifier q[])
{
    (void)vr, (void)nvr, (void)iv, (void)q;
    return refuse(inst, "fmi3GetIntervalDecimal", NO_CLOCKS);
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 cn[],
                                   fmi3UInt64 res[], fmi3IntervalQualifier q[])
{
    (void)vr, (void)nvr, (void)cn, (void)res, (void)q;
    return refuse(inst, "fmi3GetIntervalFraction", NO_CLOCKS);
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 sh[])
{
    (void)vr, (void)nvr, (void)sh;
    return refuse(inst, "fmi3GetShiftDecimal", NO_CLOCKS);
}

fmi3Status fmi3GetShiftFraction(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 cn[],
                                fmi3UInt64 res[])
{
    (void)vr, (void)nvr, (void)cn, (void)res;
    return refuse(inst, "fmi3GetShiftFraction", NO_CLOCKS);
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr,
                                  const fmi3Float64 iv[])
{
    (void)vr, (void)nvr, (void)iv;
    return refuse(inst, "fmi3SetIntervalDecimal", NO_CLOCKS);
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr,
                                   const fmi3UInt64 cn[], const fmi3UInt64 res[])
{
    (void)vr, (void)nvr, (void)cn, (void)res;
    return refuse(inst, "fmi3SetIntervalFraction", NO_CLOCKS);
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 sh[])
{
    (void)vr, (void)nvr, (void)sh;
    return refuse(inst, "fmi3SetShiftDecimal", NO_CLOCKS);
}

fmi3Status fmi3SetShiftFraction(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr,
                                const fmi3UInt64 cn[], const fmi3UInt64 res[])
{
    (void)vr, (void)nvr, (void)cn, (void)res;
    return refuse(inst, "fmi3SetShiftFraction", NO_CLOCKS);
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance inst, fmi3ValueReference clock, fmi3Float64 t)
{
    (void)clock, (void)t;
    return refuse(inst, "fmi3ActivateModelPartition", "this FMU supports co-simulation only");
}

/* ------------------------------------------------------------------ dependencies, derivatives */
fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance inst, fmi3ValueReference vr, size_t *n)
{
    (void)vr, (void)n;
    return refuse(inst, "fmi3GetNumberOfVariableDependencies",
                  "not provided (the model description's ModelStructure lists them)");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance inst, fmi3ValueReference dependent, size_t ei[],
                                       fmi3ValueReference independents[], size_t eii[], fmi3DependencyKind kinds[],
                                       size_t n)
{
    (void)dependent, (void)ei, (void)independents, (void)eii, (void)kinds, (void)n;
    return refuse(inst, "fmi3GetVariableDependencies",
                  "not provided (the model description's ModelStructure lists them)");
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance inst, const fmi3ValueReference u[], size_t nu,
                                        const fmi3ValueReference k[], size_t nk, const fmi3Float64 seed[],
                                        size_t ns, fmi3Float64 sens[], size_t nsens)
{
    (void)u, (void)nu, (void)k, (void)nk, (void)seed, (void)ns, (void)sens, (void)nsens;
    return (fmi3Status)unsupported(inst, F_GetDirectionalDerivative,
                                   "not provided (providesDirectionalDerivative = false)");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance inst, const fmi3ValueReference u[], size_t nu,
                                    const fmi3ValueReference k[], size_t nk, const fmi3Float64 seed[], size_t ns,
                                    fmi3Float64 sens[], size_t nsens)
{
    (void)u, (void)nu, (void)k, (void)nk, (void)seed, (void)ns, (void)sens, (void)nsens;
    return refuse(inst, "fmi3GetAdjointDerivative", "not provided (providesAdjointDerivatives = false)");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance inst, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nv)
{
    (void)vr, (void)nvr, (void)orders, (void)values, (void)nv;
    return (fmi3Status)unsupported(inst, F_GetRealOutputDerivatives, "not provided (maxOutputDerivativeOrder = 0)");
}

/* ------------------------------------------------------------------ FMU states */
fmi3Status fmi3GetFMUState(fmi3Instance inst, fmi3FMUState *state)
{
    return (fmi3Status)fmi2GetFMUstate(inst, (fmi2FMUstate *)state);
}

fmi3Status fmi3SetFMUState(fmi3Instance inst, fmi3FMUState state) { return (fmi3Status)fmi2SetFMUstate(inst, state); }

fmi3Status fmi3FreeFMUState(fmi3Instance inst, fmi3FMUState *state)
{
    return (fmi3Status)fmi2FreeFMUstate(inst, (fmi2FMUstate *)state);
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance inst, fmi3FMUState state, size_t *size)
{
    return (fmi3Status)fmi2SerializedFMUstateSize(inst, state, size);
}

fmi3Status fmi3SerializeFMUState(fmi3Instance inst, fmi3FMUState state, fmi3Byte out[], size_t size)
{
    return (fmi3Status)fmi2SerializeFMUstate(inst, state, (fmi2Byte *)out, size);
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance inst, const fmi3Byte in[], size_t size, fmi3FMUState *state)
{
    return (fmi3Status)fmi2DeSerializeFMUstate(inst, (const fmi2Byte *)in, size, (fmi2FMUstate *)state);
}

/* ------------------------------------------------------------------ co-simulation */
fmi3Status fmi3DoStep(fmi3Instance inst, fmi3Float64 t, fmi3Float64 h, fmi3Boolean noSetPrior,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime)
{
    Comp *c = registry_find(inst);
    if (!c) return fmi3Error;
    const char *null = !eventHandlingNeeded ? "eventHandlingNeeded" : !terminateSimulation ? "terminateSimulation"
                     : !earlyReturn       ? "earlyReturn"
                     : !lastSuccessfulTime ? "lastSuccessfulTime"
                                           : NULL;
    if (null) return (fmi3Status)logf_(c, fmi2Error, "fmi3DoStep: %s is NULL", null);
    *eventHandlingNeeded = false;
    *terminateSimulation = false;
    *earlyReturn = false;
    fmi2Status st = fmi2DoStep(inst, t, h, noSetPrior ? fmi2True : fmi2False);
    *lastSuccessfulTime = c->time; /* the end of the last completed step (doStep never frees c) */
    if (st == fmi2Discard) *terminateSimulation = true;
    return (fmi3Status)st;
}

/* ------------------------------------------------------------------ model exchange (not provided) */
#define CS_ONLY "this FMU supports co-simulation only"
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance inst)
{
    return refuse(inst, "fmi3EnterContinuousTimeMode", CS_ONLY);
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance inst, fmi3Boolean noSetPrior, fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation)
{
    (void)noSetPrior, (void)enterEventMode, (void)terminateSimulation;
    return refuse(inst, "fmi3CompletedIntegratorStep", CS_ONLY);
}

fmi3Status fmi3SetTime(fmi3Instance inst, fmi3Float64 time)
{
    (void)time;
    return refuse(inst, "fmi3SetTime", CS_ONLY);
}

fmi3Status fmi3SetContinuousStates(fmi3Instance inst, const fmi3Float64 x[], size_t n)
{
    (void)x, (void)n;
    return refuse(inst, "fmi3SetContinuousStates", CS_ONLY);
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance inst, fmi3Float64 dx[], size_t n)
{
    (void)dx, (void)n;
    return refuse(inst, "fmi3GetContinuousStateDerivatives", CS_ONLY);
}

fmi3Status fmi3GetEventIndicators(fmi3Instance inst, fmi3Float64 z[], size_t n)
{
    (void)z, (void)n;
    return refuse(inst, "fmi3GetEventIndicators", CS_ONLY);
}

fmi3Status fmi3GetContinuousStates(fmi3Instance inst, fmi3Float64 x[], size_t n)
{
    (void)x, (void)n;
    return refuse(inst, "fmi3GetContinuousStates", CS_ONLY);
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance inst, fmi3Float64 nominals[], size_t n)
{
    (void)nominals, (void)n;
    return refuse(inst, "fmi3GetNominalsOfContinuousStates", CS_ONLY);
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance inst, size_t *n)
{
    (void)n;
    return refuse(inst, "fmi3GetNumberOfEventIndicators", CS_ONLY);
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance inst, size_t *n)
{
    (void)n;
    return refuse(inst, "fmi3GetNumberOfContinuousStates", CS_ONLY);
}
