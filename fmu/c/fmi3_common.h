/* What the FMI 3.0 FMU's two binaries share (fmi3_loader.c: finds a Python and forwards
 * the FMI 3.0 calls; fmi3_python.c: the implementation): the version, a log line through
 * the host's logger before there is an instance, reading resourcePath, and refusing the
 * interface types this FMU does not provide (model exchange, scheduled execution), which
 * need no Python. Static: each binary gets its own copy; the fmi3 functions are exported
 * by each binary. See fmi2_common.h for what both FMI versions share. */
#ifndef DFA_FMI3_COMMON_H
#define DFA_FMI3_COMMON_H

#include <stdlib.h>
#include <string.h>

#include "fmi2_common.h" /* uri_to_path */
#include "fmi3Functions.h"

const char *fmi3GetVersion(void) { return fmi3Version; }

/* A log line through a logger before there is an instance. */
static void log_early(fmi3LogMessageCallback log, fmi3InstanceEnvironment env, const char *msg)
{
    if (log) log(env, fmi3Error, "logStatusError", msg);
}

/* resourcePath (FMI 3.0: a path, ending in a separator) -> a malloc'ed path without the
 * trailing separator; a file URI (from a host that passes one) is read as fmi2 does. */
static char *resource_dir(const char *path)
{
    if (strncmp(path, "file:", 5) == 0) return uri_to_path(path);
    char *out = strdup(path);
    if (!out) return NULL;
    size_t k = strlen(out);
    while (k > 1 && out[k - 1] == '/') out[--k] = 0;
    return out;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resourcePath,
                                          fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment env,
                                          fmi3LogMessageCallback logMessage)
{
    (void)name, (void)token, (void)resourcePath, (void)visible, (void)loggingOn;
    log_early(logMessage, env, "fmi3InstantiateModelExchange: this FMU supports co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String name, fmi3String token, fmi3String resourcePath,
                                               fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment env, fmi3LogMessageCallback logMessage,
                                               fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)name, (void)token, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    log_early(logMessage, env, "fmi3InstantiateScheduledExecution: this FMU supports co-simulation only");
    return NULL;
}

#endif
