/* What the FMU's two binaries share (fmi2_loader.c: finds a Python and forwards the FMI
 * calls; fmi2_python.c: the implementation): logging through the host's callback, reading
 * the resources folder's files and URI, and naming a Python environment's executable and
 * its pyvenv.cfg. Static: each binary gets its own copy and exports nothing more. */
#ifndef DFA_FMI2_COMMON_H
#define DFA_FMI2_COMMON_H

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "fmi2Functions.h"

/* Log msg through the host's logger. The message is passed as the format string (hosts
 * such as fmpy do not format it): every '%' is doubled, so hosts that do format print it
 * unchanged. */
static void log_escaped(const fmi2CallbackFunctions *cb, const char *name, fmi2Status st, const char *cat,
                        const char *msg)
{
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

/* The first line of dir/file (malloc'ed), or NULL when it is missing or empty. */
static char *first_line(const char *dir, const char *file)
{
    char path[PATH_MAX];
    if (snprintf(path, sizeof path, "%s/%s", dir, file) >= (int)sizeof path) return NULL;
    FILE *f = fopen(path, "r");
    if (!f) return NULL;
    char line[PATH_MAX] = {0};
    if (!fgets(line, sizeof line, f)) line[0] = 0;
    fclose(f);
    line[strcspn(line, "\r\n")] = 0;
    return line[0] ? strdup(line) : NULL;
}

static int hexval(char ch)
{
    if (ch >= '0' && ch <= '9') return ch - '0';
    if (ch >= 'a' && ch <= 'f') return ch - 'a' + 10;
    if (ch >= 'A' && ch <= 'F') return ch - 'A' + 10;
    return -1;
}

/* file URI -> path (malloc'ed): strip the scheme and host part, decode %XX (a malformed
 * escape, or one that would put a NUL in the path, stays literal) */
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
    if (!out) return NULL;
    size_t k = 0;
    for (size_t i = 0; p[i]; i++) {
        int hi = p[i] == '%' && p[i + 1] ? hexval(p[i + 1]) : -1;
        int lo = hi >= 0 && p[i + 2] ? hexval(p[i + 2]) : -1;
        if (lo >= 0 && (hi || lo)) {
            out[k++] = (char)(hi * 16 + lo);
            i += 2;
        } else {
            out[k++] = p[i];
        }
    }
    while (k > 1 && out[k - 1] == '/') k--;
    out[k] = 0;
    return out;
}

/* The python executable a name of an environment means (a virtual environment's folder:
 * its bin/python3; else the name itself) into exe, and its pyvenv.cfg's path (there only
 * for a virtual environment) into cfg. Returns whether the executable exists. */
static int python_of(const char *path, char *exe, size_t n_exe, char *cfg, size_t n_cfg)
{
    struct stat sb;
    int is_dir = stat(path, &sb) == 0 && S_ISDIR(sb.st_mode);
    snprintf(exe, n_exe, is_dir ? "%s/bin/python3" : "%s", path);
    const char *slash = strrchr(exe, '/');
    snprintf(cfg, n_cfg, "%.*s/../pyvenv.cfg", slash ? (int)(slash - exe) : 1, slash ? exe : ".");
    return stat(exe, &sb) == 0;
}

#endif
