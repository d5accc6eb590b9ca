/* What the FMU's loaders share (fmi2_loader.c, fmi3_loader.c: the library a host loads,
 * needing only libc and libdl): finding and loading a Python's shared library for a C
 * host, checking the version of a Python already in the process, loading the
 * implementation (<name>-python.so, compiled from fmi2_python.c or fmi3_python.c) beside
 * the loader once, at the first instantiation, and refusing calls before that. Messages
 * start with DFA_WHERE, the instantiating function's name, which the includer defines.
 * See fmi2_loader.c's header for where the Python comes from.
 *
 * Compiled by fmu/build.py with DFA_PY_MAJOR, DFA_PY_MINOR, DFA_LIBPYTHON (the shared
 * library's file name) and DFA_LIBDIR (its folder at build time). */
#ifndef DFA_LOADER_COMMON_H
#define DFA_LOADER_COMMON_H

#ifndef DFA_WHERE
#error "define DFA_WHERE (the instantiating function's name) before including loader_common.h"
#endif

#include <dlfcn.h>
#include <limits.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

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
            snprintf(msg, n, DFA_WHERE ": DFA_FMU_PYTHON names %s: no Python there; set DFA_FMU_PYTHON to a "
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
        snprintf(msg, n, DFA_WHERE ": this FMU runs on CPython %d.%d and needs its shared library %s, which "
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
        snprintf(msg, n, DFA_WHERE ": this FMU was built for Python %d.%d; the host runs Python %d.%d: run it "
                         "from a Python %d.%d host, or rebuild it there (dfa fmu build)", DFA_PY_MAJOR, DFA_PY_MINOR,
                 major, minor, DFA_PY_MAJOR, DFA_PY_MINOR);
    return 1;
}

/* Load Python (if the process has none) and the implementation <this library>-python.so
 * (its file name into path); returns its handle, or NULL with msg filled. */
static void *load_implementation(const char *resources, char *msg, size_t n, char *path, size_t npath)
{
    msg[0] = 0;
    if (!python_present(msg, n)) {
        if (!load_python(resources, msg, n)) return NULL;
    } else if (msg[0]) {
        return NULL;
    }
    Dl_info info;
    if (!dladdr((void *)&load_implementation, &info) || !info.dli_fname) {
        snprintf(msg, n, DFA_WHERE ": cannot find the FMU's binary folder");
        return NULL;
    }
    snprintf(path, npath, "%s", info.dli_fname);
    char *dot = strrchr(path, '.');
    if (dot && strcmp(dot, ".so") == 0) *dot = 0;
    strncat(path, "-python.so", npath - strlen(path) - 1);
    void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!h) snprintf(msg, n, DFA_WHERE ": cannot load the FMU's implementation %s: %s", path, dlerror());
    return h;
}

/* The includer's table of the implementation's functions (`impl`) is complete: set once,
 * under load_lock, by ensure_loaded. */
static int loaded;
static pthread_mutex_t load_lock = PTHREAD_MUTEX_INITIALIZER;

/* In the includer's lookup function (h: the implementation's handle, path: its file, msg
 * and n: the message buffer): impl.f = the implementation's function <prefix><f>, else
 * return 0 with msg naming the missing one. */
#define DFA_LOOKUP(prefix, f)                                                              \
    if (!(impl.f = (prefix##f##TYPE *)dlsym(h, #prefix #f))) {                             \
        snprintf(msg, n, DFA_WHERE ": %s has no " #prefix #f " (a broken FMU)", path);     \
        return 0;                                                                          \
    }

/* At instantiation: the first time, load Python (if the process has none) and the
 * implementation, and fill the includer's table of its functions with lookup (table,
 * size: that table, cleared when anything is missing). resources: the instantiation's
 * resource location (NULL: none), made a folder by to_dir (malloc'ed) to read python.txt
 * from. Returns 1 (at once once loaded), or 0 with msg filled. */
static int ensure_loaded(const char *resources, char *(*to_dir)(const char *),
                         int (*lookup)(void *h, const char *path, char *msg, size_t n), void *table, size_t size,
                         char *msg, size_t n)
{
    int ok = 1;
    pthread_mutex_lock(&load_lock);
    if (!loaded) {
        char path[PATH_MAX], *res = resources ? to_dir(resources) : NULL;
        void *h = load_implementation(res ? res : ".", msg, n, path, sizeof path);
        free(res);
        ok = h && lookup(h, path, msg, n);
        if (ok) __atomic_store_n(&loaded, 1, __ATOMIC_RELEASE);
        else memset(table, 0, size);
    }
    pthread_mutex_unlock(&load_lock);
    return ok;
}

/* Before a successful instantiation there is no instance: every call with one is refused
 * (fmi2Error, fmi3Error: `fail`), as the implementation refuses unknown instances. */
#define READY(fail) \
    if (!__atomic_load_n(&loaded, __ATOMIC_ACQUIRE)) return fail;

#endif
