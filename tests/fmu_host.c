/* A minimal non-Python FMI 2.0 co-simulation host: dlopen the FMU binary with RTLD_NOW
 * (as Modelica tools and the FMU Compliance Checker do), run the life cycle through a
 * few steps and print the stroke. No libpython is preloaded: the binary must load it.
 * Also the benchmarks' C host (benchmarks/bench_fmu.py): it prints the wall time of
 * instantiate + initialize and of the steps.
 *
 * usage: fmu_host BINARY.so RESOURCE_URI GUID VR_VOLTAGE VR_FORCE VR_STROKE NSTEPS DT [U1 U2]
 * (U1, U2: the two inputs' values, default 6000 and 5; the two input references may be
 * the same variable, for an FMU with one input)
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

typedef void *fmi2Component;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Boolean;
typedef int fmi2Status;
typedef struct {
    void (*logger)(void *, const char *, fmi2Status, const char *, const char *, ...);
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(void *, fmi2Status);
    void *componentEnvironment;
} fmi2CallbackFunctions;

static void logger(void *env, const char *name, fmi2Status st, const char *cat, const char *msg, ...) {
    va_list ap;
    va_start(ap, msg);
    fprintf(stderr, "[%s %d %s] ", name, st, cat);
    vfprintf(stderr, msg, ap);
    fprintf(stderr, "\n");
    va_end(ap);
}

#define LOAD(T, name) T name = (T)dlsym(lib, #name); if (!name) { printf("missing %s\n", #name); return 3; }

typedef fmi2Component (*inst_t)(const char *, int, const char *, const char *, const fmi2CallbackFunctions *,
                                fmi2Boolean, fmi2Boolean);
typedef fmi2Status (*setup_t)(fmi2Component, fmi2Boolean, fmi2Real, fmi2Real, fmi2Boolean, fmi2Real);
typedef fmi2Status (*comp_t)(fmi2Component);
typedef void (*free_t)(fmi2Component);
typedef fmi2Status (*real_t)(fmi2Component, const fmi2ValueReference *, size_t, fmi2Real *);
typedef fmi2Status (*setreal_t)(fmi2Component, const fmi2ValueReference *, size_t, const fmi2Real *);
typedef fmi2Status (*step_t)(fmi2Component, fmi2Real, fmi2Real, fmi2Boolean);

int main(int argc, char **argv) {
    if (argc != 9 && argc != 11) { printf("usage\n"); return 2; }
    double t0 = now();
    void *lib = dlopen(argv[1], RTLD_NOW);
    if (!lib) { printf("dlopen failed: %s\n", dlerror()); return 1; }
    LOAD(inst_t, fmi2Instantiate) LOAD(setup_t, fmi2SetupExperiment)
    LOAD(comp_t, fmi2EnterInitializationMode) LOAD(comp_t, fmi2ExitInitializationMode)
    LOAD(setreal_t, fmi2SetReal) LOAD(real_t, fmi2GetReal) LOAD(step_t, fmi2DoStep)
    LOAD(comp_t, fmi2Terminate) LOAD(free_t, fmi2FreeInstance)
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = fmi2Instantiate("host", 1, argv[3], argv[2], &cb, 0, 1);
    if (!c) { printf("instantiate failed\n"); return 4; }
    fmi2ValueReference vin[2] = {(fmi2ValueReference)atoi(argv[4]), (fmi2ValueReference)atoi(argv[5])};
    fmi2ValueReference vx = (fmi2ValueReference)atoi(argv[6]);
    int n = atoi(argv[7]);
    double dt = atof(argv[8]), t = 0.0, x = -1.0;
    fmi2Real u[2] = {argc == 11 ? atof(argv[9]) : 6000.0, argc == 11 ? atof(argv[10]) : 5.0};
    if (fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) > 1) { printf("setup failed\n"); return 5; }
    if (fmi2EnterInitializationMode(c) > 1 || fmi2SetReal(c, vin, 2, u) > 1 || fmi2ExitInitializationMode(c) > 1) {
        printf("initialization failed\n"); return 6;
    }
    double t1 = now();
    for (int k = 0; k < n; k++) {
        if (fmi2SetReal(c, vin, 2, u) > 1 || fmi2DoStep(c, t, dt, 1) > 1 || fmi2GetReal(c, &vx, 1, &x) > 1) {
            printf("step %d failed\n", k);
            return 7;
        }
        t += dt;
    }
    double t2 = now();
    if (fmi2GetReal(c, &vx, 1, &x) > 1) { printf("getReal failed\n"); return 8; }
    printf("stroke %.17g\n", x);
    if (fmi2Terminate(c) > 1) { printf("terminate failed\n"); return 9; }
    fmi2FreeInstance(c);
    printf("freed\n");
    printf("seconds: instantiate+initialize %.6f steps %.6f\n", t1 - t0, t2 - t1);
    fflush(stdout);
    return 0;
}
