/* A minimal FMI 2.0 co-simulation master in C: a non-Python host for the tests.

     native_host UNZIPDIR MODEL_ID GUID STEPS STEP_SIZE [r:VR=VALUE ...] [o:VR ...] [maps] [exit|dlclose] [grid]

   Loads UNZIPDIR/binaries/linux64/MODEL_ID.so, sets every r:VR=VALUE (Real) before initialization
   and before every step, steps STEPS times by STEP_SIZE (s) from 0 and prints, after the
   initialization and after every step, one CSV line: the time, then each o:VR (Real) with 17
   significant digits. With "maps", the shared objects of the process that belong to Python
   (libpython, numpy, ...) are written to stderr after the initialization. Exit 1 on any failure,
   with the reason and the FMU's log on stderr. Build: cc -o native_host native_host.c -ldl

   It leaves with _exit after freeing the instance: a process that loaded a pythonfmu binary
   aborts in its exit handlers ("free(): corrupted unsorted chunks", PythonFMU issue 229), after
   every result has been written. With "exit" it returns from main like an ordinary host (exit
   handlers run), with "dlclose" it also unloads the FMU's library first (as fmusim does): how
   often that aborts is measured in docs/masters.md. With "grid" the step size is computed as
   (k+1)*h - k*h, as fmusim and libcosim do (it differs from h by rounding on most steps). */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef void *fmi2Component;
typedef unsigned int fmi2ValueReference;
typedef int fmi2Status; /* 0 ok, 1 warning, 2 discard, 3 error, 4 fatal, 5 pending */
typedef struct {
    void (*logger)(void *, const char *, fmi2Status, const char *, const char *, ...);
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(void *, fmi2Status);
    void *componentEnvironment;
} fmi2CallbackFunctions;

typedef fmi2Component (*Instantiate)(const char *, int, const char *, const char *,
                                     const fmi2CallbackFunctions *, int, int);
typedef fmi2Status (*Setup)(fmi2Component, int, double, double, int, double);
typedef fmi2Status (*Plain)(fmi2Component);
typedef fmi2Status (*RealIO)(fmi2Component, const fmi2ValueReference *, size_t, double *);
typedef fmi2Status (*DoStep)(fmi2Component, double, double, int);

static void logger(void *env, const char *name, fmi2Status status, const char *category,
                   const char *message, ...) {
    va_list args;
    (void)env;
    fprintf(stderr, "[%s %d %s] ", name, status, category);
    va_start(args, message);
    vfprintf(stderr, message, args);
    va_end(args);
    fputc('\n', stderr);
}

static void *symbol(void *lib, const char *name) {
    void *f = dlsym(lib, name);
    if (!f) {
        fprintf(stderr, "native_host: %s not found: %s\n", name, dlerror());
        exit(1);
    }
    return f;
}

static void check(fmi2Status status, const char *what) {
    if (status > 1) {
        fprintf(stderr, "native_host: %s returned status %d\n", what, status);
        exit(1);
    }
}

static void print_python_maps(void) {
    char line[4096];
    FILE *f = fopen("/proc/self/maps", "r");
    while (f && fgets(line, sizeof line, f)) {
        char *path = strchr(line, '/');
        if (path && (strstr(path, "python") || strstr(path, "numpy")) && strstr(path, ".so"))
            fprintf(stderr, "map: %s", path);
    }
    if (f) fclose(f);
}

int main(int argc, char **argv) {
    if (argc < 6) {
        fprintf(stderr, "usage: native_host UNZIPDIR MODEL_ID GUID STEPS STEP_SIZE [r:VR=VALUE] [o:VR] [maps] [exit|dlclose] [grid]\n");
        return 1;
    }
    const char *dir = argv[1], *id = argv[2], *guid = argv[3];
    long steps = atol(argv[4]);
    double h = atof(argv[5]);
    fmi2ValueReference in_vr[64], out_vr[256];
    double in_val[64], out_val[256];
    size_t n_in = 0, n_out = 0;
    int maps = 0, leave_mode = 0, grid = 0; /* leave_mode 0 _exit, 1 return from main, 2 dlclose */
    for (int i = 6; i < argc; i++) {
        if (strncmp(argv[i], "r:", 2) == 0 && n_in < 64) {
            in_vr[n_in] = (fmi2ValueReference)strtoul(argv[i] + 2, NULL, 10);
            in_val[n_in++] = atof(strchr(argv[i], '=') + 1);
        } else if (strncmp(argv[i], "o:", 2) == 0 && n_out < 256) {
            out_vr[n_out++] = (fmi2ValueReference)strtoul(argv[i] + 2, NULL, 10);
        } else if (strcmp(argv[i], "maps") == 0) {
            maps = 1;
        } else if (strcmp(argv[i], "exit") == 0) {
            leave_mode = 1;
        } else if (strcmp(argv[i], "dlclose") == 0) {
            leave_mode = 2;
        } else if (strcmp(argv[i], "grid") == 0) {
            grid = 1;
        }
    }

    char path[4096], uri[4096];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, id);
    snprintf(uri, sizeof uri, "file://%s/resources", dir);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "native_host: cannot load %s: %s\n", path, dlerror());
        return 1;
    }
    Instantiate instantiate = (Instantiate)symbol(lib, "fmi2Instantiate");
    Setup setup = (Setup)symbol(lib, "fmi2SetupExperiment");
    Plain enter = (Plain)symbol(lib, "fmi2EnterInitializationMode");
    Plain leave = (Plain)symbol(lib, "fmi2ExitInitializationMode");
    Plain terminate = (Plain)symbol(lib, "fmi2Terminate");
    void (*free_instance)(fmi2Component) = (void (*)(fmi2Component))symbol(lib, "fmi2FreeInstance");
    RealIO set_real = (RealIO)symbol(lib, "fmi2SetReal");
    RealIO get_real = (RealIO)symbol(lib, "fmi2GetReal");
    DoStep do_step = (DoStep)symbol(lib, "fmi2DoStep");

    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = instantiate("host", 1 /* fmi2CoSimulation */, guid, uri, &cb, 0, 1);
    if (!c) {
        fprintf(stderr, "native_host: fmi2Instantiate failed\n");
        return 1;
    }
    check(setup(c, 0, 0.0, 0.0, 0, 0.0), "fmi2SetupExperiment");
    check(enter(c), "fmi2EnterInitializationMode");
    if (n_in) check(set_real(c, in_vr, n_in, in_val), "fmi2SetReal");
    check(leave(c), "fmi2ExitInitializationMode");
    if (maps) print_python_maps();
    for (long k = 0; k <= steps; k++) {
        if (k > 0) {
            if (n_in) check(set_real(c, in_vr, n_in, in_val), "fmi2SetReal");
            check(do_step(c, (k - 1) * h, grid ? k * h - (k - 1) * h : h, 1), "fmi2DoStep");
        }
        if (n_out) check(get_real(c, out_vr, n_out, out_val), "fmi2GetReal");
        printf("%.17g", k * h);
        for (size_t j = 0; j < n_out; j++) printf(",%.17g", out_val[j]);
        putchar('\n');
    }
    fflush(stdout);
    check(terminate(c), "fmi2Terminate");
    free_instance(c);
    fflush(stderr);
    if (leave_mode == 2) dlclose(lib);
    if (leave_mode) return 0;
    _exit(0);
}
