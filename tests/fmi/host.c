/* A minimal FMI 2.0 Co-Simulation host in C: no Python of its own.
 *
 * It dlopens an FMU's binary, instantiates it, steps it and prints one integer output,
 * as a C or C++ simulation tool would. The FMU's log messages go to standard output.
 *
 *   host BINARY RESOURCE_URI GUID VR STEPS STEP_SIZE
 *
 * prints "value <VR's Integer value after STEPS steps of STEP_SIZE seconds>" and exits 0;
 * on a failure, one line naming the call, exit status 1 (2: the binary did not load).
 * Built by tests/fmi/test_fmu_c_host.py with gcc; the FMI 2.0 types are declared here so
 * that no FMI header is needed.
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

typedef void *fmi2Component;
typedef int fmi2Status;
typedef int fmi2Boolean;
typedef unsigned int fmi2ValueReference;

typedef struct {
    void (*logger)(void *, const char *, fmi2Status, const char *, const char *, ...);
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(void *, fmi2Status);
    void *componentEnvironment;
} fmi2CallbackFunctions;

typedef fmi2Component (*Instantiate)(const char *, int, const char *, const char *,
                                     const fmi2CallbackFunctions *, fmi2Boolean, fmi2Boolean);
typedef fmi2Status (*SetupExperiment)(fmi2Component, fmi2Boolean, double, double, fmi2Boolean,
                                      double);
typedef fmi2Status (*OneArg)(fmi2Component);
typedef fmi2Status (*DoStep)(fmi2Component, double, double, fmi2Boolean);
typedef fmi2Status (*GetInteger)(fmi2Component, const fmi2ValueReference *, size_t, int *);
typedef void (*FreeInstance)(fmi2Component);

static void logger(void *env, const char *instance, fmi2Status status, const char *category,
                   const char *message, ...) {
    va_list args;
    (void)env;
    printf("log %s %d %s: ", instance, status, category);
    va_start(args, message);
    vprintf(message, args);
    va_end(args);
    printf("\n");
}

static void *symbol(void *lib, const char *name) {
    void *f = dlsym(lib, name);
    if (f == NULL) {
        printf("missing %s\n", name);
        exit(1);
    }
    return f;
}

#define CHECK(call, what)                        \
    if ((call) != 0) {                           \
        printf("%s failed\n", what);             \
        return 1;                                \
    }

int main(int argc, char **argv) {
    if (argc != 7) {
        printf("usage: host BINARY RESOURCE_URI GUID VR STEPS STEP_SIZE\n");
        return 1;
    }
    void *lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (lib == NULL) {
        printf("dlopen failed: %s\n", dlerror());
        return 2;
    }
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    Instantiate instantiate = (Instantiate)symbol(lib, "fmi2Instantiate");
    fmi2Component c = instantiate("host", 1 /* fmi2CoSimulation */, argv[3], argv[2], &cb, 0, 1);
    if (c == NULL) {
        printf("fmi2Instantiate failed\n");
        return 1;
    }
    CHECK(((SetupExperiment)symbol(lib, "fmi2SetupExperiment"))(c, 0, 0.0, 0.0, 0, 0.0),
          "fmi2SetupExperiment");
    CHECK(((OneArg)symbol(lib, "fmi2EnterInitializationMode"))(c), "fmi2EnterInitializationMode");
    CHECK(((OneArg)symbol(lib, "fmi2ExitInitializationMode"))(c), "fmi2ExitInitializationMode");
    DoStep step = (DoStep)symbol(lib, "fmi2DoStep");
    long steps = atol(argv[5]);
    double h = atof(argv[6]);
    for (long i = 0; i < steps; i++) {
        fmi2Status s = step(c, (double)i * h, h, 1);
        if (s > 1) { /* above fmi2Warning */
            printf("fmi2DoStep failed: status %d\n", s);
            return 1;
        }
    }
    fmi2ValueReference vr = (fmi2ValueReference)atol(argv[4]);
    int value = 0;
    CHECK(((GetInteger)symbol(lib, "fmi2GetInteger"))(c, &vr, 1, &value), "fmi2GetInteger");
    printf("value %d\n", value);
    CHECK(((OneArg)symbol(lib, "fmi2Terminate"))(c), "fmi2Terminate");
    ((FreeInstance)symbol(lib, "fmi2FreeInstance"))(c);
    /* unload the FMU as importers do (its wrapper ends the Python it started here) */
    if (dlclose(lib) != 0) {
        printf("dlclose failed: %s\n", dlerror());
        return 1;
    }
    return 0;
}
