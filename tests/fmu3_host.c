/* A minimal non-Python FMI 3.0 co-simulation host (tests/fmu3_cases.py): dlopen the FMU
 * binary with RTLD_NOW (no libpython preloaded: the binary must load it), make a few
 * calls a careless host makes (each must return fmi3Error, never crash), run the life
 * cycle through NSTEPS steps at 6 kV, 5 N and print the stroke.
 *
 * usage: fmu3_host BINARY.so RESOURCE_DIR TOKEN VR_VOLTAGE VR_FORCE VR_STROKE VR_N NSTEPS DT
 * prints "abuse ok" (or "abuse FAIL <what>"), "stroke <x>", "freed"
 */
#include <dlfcn.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

typedef void *fmi3Instance;
typedef uint32_t fmi3ValueReference;
typedef int fmi3Status; /* fmi3OK 0 ... fmi3Error 3 */
typedef void (*logger_t)(void *, fmi3Status, const char *, const char *);

static void logger(void *env, fmi3Status st, const char *cat, const char *msg)
{
    (void)env;
    fprintf(stderr, "[host %d %s] %s\n", st, cat, msg);
}

#define LOAD(T, name) T name = (T)dlsym(lib, #name); if (!name) { printf("missing %s\n", #name); return 3; }
#define EXPECT_ERROR(call, what) if ((call) != 3) { printf("abuse FAIL %s\n", what); abuse_ok = 0; }

typedef fmi3Instance (*inst_t)(const char *, const char *, const char *, bool, bool, bool, bool,
                               const fmi3ValueReference *, size_t, void *, logger_t, void *);
typedef fmi3Status (*init_t)(fmi3Instance, bool, double, double, bool, double);
typedef fmi3Status (*comp_t)(fmi3Instance);
typedef void (*free_t)(fmi3Instance);
typedef fmi3Status (*f64_t)(fmi3Instance, const fmi3ValueReference *, size_t, double *, size_t);
typedef fmi3Status (*setf64_t)(fmi3Instance, const fmi3ValueReference *, size_t, const double *, size_t);
typedef fmi3Status (*i8_t)(fmi3Instance, const fmi3ValueReference *, size_t, int8_t *, size_t);
typedef fmi3Status (*step_t)(fmi3Instance, double, double, bool, bool *, bool *, bool *, double *);

int main(int argc, char **argv)
{
    if (argc != 10) { printf("usage\n"); return 2; }
    void *lib = dlopen(argv[1], RTLD_NOW);
    if (!lib) { printf("dlopen failed: %s\n", dlerror()); return 1; }
    LOAD(inst_t, fmi3InstantiateCoSimulation) LOAD(init_t, fmi3EnterInitializationMode)
    LOAD(comp_t, fmi3ExitInitializationMode) LOAD(setf64_t, fmi3SetFloat64) LOAD(f64_t, fmi3GetFloat64)
    LOAD(i8_t, fmi3GetInt8) LOAD(step_t, fmi3DoStep) LOAD(comp_t, fmi3EnterEventMode)
    LOAD(comp_t, fmi3Terminate) LOAD(free_t, fmi3FreeInstance)
    int abuse_ok = 1;
    /* before any instance exists, and with instances that are not */
    EXPECT_ERROR(fmi3ExitInitializationMode(NULL), "exit(NULL) before instantiation")
    fmi3Instance c = fmi3InstantiateCoSimulation("host", argv[3], argv[2], false, true, false, false, NULL, 0, NULL,
                                                 logger, NULL);
    if (!c) { printf("instantiate failed\n"); return 4; }
    fmi3ValueReference vin[2] = {(fmi3ValueReference)atoi(argv[4]), (fmi3ValueReference)atoi(argv[5])};
    fmi3ValueReference vx = (fmi3ValueReference)atoi(argv[6]), vn = (fmi3ValueReference)atoi(argv[7]);
    int n = atoi(argv[8]);
    double dt = atof(argv[9]), t = 0.0, x = -1.0, u[2] = {6000.0, 5.0}, big[2] = {2e6, 5.0}, lst = 0.0;
    bool ehn, term, early;
    int8_t i8;
    int dummy;
    EXPECT_ERROR(fmi3ExitInitializationMode((fmi3Instance)&dummy), "a pointer that is no instance")
    EXPECT_ERROR(fmi3DoStep(c, 0.0, dt, true, &ehn, &term, &early, &lst), "doStep before initialization")
    EXPECT_ERROR(fmi3GetInt8(c, &vn, 1, &i8, 1), "fmi3GetInt8 on an Int32")
    EXPECT_ERROR(fmi3GetFloat64(c, vin, 2, NULL, 2), "NULL values")
    if (fmi3EnterInitializationMode(c, false, 0.0, 0.0, false, 0.0) > 1) { printf("enter failed\n"); return 5; }
    EXPECT_ERROR(fmi3SetFloat64(c, vin, 2, big, 2), "voltage 2 MV (out of range)")
    EXPECT_ERROR(fmi3SetFloat64(c, vin, 2, u, 1), "nValues != nValueReferences")
    if (fmi3SetFloat64(c, vin, 2, u, 2) > 1 || fmi3ExitInitializationMode(c) > 1) {
        printf("initialization failed\n");
        return 6;
    }
    EXPECT_ERROR(fmi3DoStep(c, 0.0, dt, true, NULL, &term, &early, &lst), "doStep with a NULL flag")
    EXPECT_ERROR(fmi3EnterEventMode(c), "enterEventMode (no event mode)")
    printf(abuse_ok ? "abuse ok\n" : "abuse done\n");
    for (int k = 0; k < n; k++) {
        if (fmi3SetFloat64(c, vin, 2, u, 2) > 1 || fmi3DoStep(c, t, dt, true, &ehn, &term, &early, &lst) > 1 ||
            fmi3GetFloat64(c, &vx, 1, &x, 1) > 1 || ehn || term || early || lst != t + dt) {
            printf("step %d failed\n", k);
            return 7;
        }
        t += dt;
    }
    printf("stroke %.17g\n", x);
    if (fmi3Terminate(c) > 1) { printf("terminate failed\n"); return 9; }
    fmi3FreeInstance(c);
    fmi3FreeInstance(c); /* twice: ignored */
    printf("freed\n");
    fflush(stdout);
    return 0;
}
