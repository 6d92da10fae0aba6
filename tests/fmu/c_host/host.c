/* A minimal FMI 2.0 co-simulation host with no Python of its own (tests/fmu/test_c_host.py).
 *
 *   host FMU_DIR GUID MODEL_IDENTIFIER STEPS STEP_SIZE VR_SEED VR_OUT [misuse]
 *
 * Loads FMU_DIR/binaries/linux64/MODEL_IDENTIFIER.so, instantiates it, sets the integer
 * parameter VR_SEED to 7, runs STEPS steps of STEP_SIZE and prints the real VR_OUT after
 * each step as "t value". With "misuse" it then makes the calls the FMI state machine
 * forbids and prints each status: a parameter set after initialisation, a second
 * exitInitializationMode, doStep after terminate, and freeInstance twice. Exit code 0
 * when every call behaved (status ok where it must be, no crash), 1 otherwise.
 */
#include <dlfcn.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...)
{
    (void)env;
    fprintf(stderr, "[%s status %d %s] %s\n", name, (int)status, category ? category : "", message);
}

#define LOAD(type, name)                                                       \
    type* name = (type*)dlsym(lib, #name);                                     \
    if (!name) { fprintf(stderr, "missing %s\n", #name); return 1; }

int main(int argc, char** argv)
{
    if (argc < 8) { fprintf(stderr, "usage: host FMU_DIR GUID ID STEPS H VR_SEED VR_OUT [misuse]\n"); return 2; }
    const char* dir = argv[1];
    int steps = atoi(argv[4]);
    double h = atof(argv[5]);
    fmi2ValueReference vr_seed = (fmi2ValueReference)atoi(argv[6]), vr_out = (fmi2ValueReference)atoi(argv[7]);
    int misuse = argc > 8 && strcmp(argv[8], "misuse") == 0;
    char path[4096], uri[4200];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, argv[3]);
    void* lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) { fprintf(stderr, "dlopen: %s\n", dlerror()); return 1; }
    LOAD(fmi2InstantiateTYPE, fmi2Instantiate)
    LOAD(fmi2SetupExperimentTYPE, fmi2SetupExperiment)
    LOAD(fmi2EnterInitializationModeTYPE, fmi2EnterInitializationMode)
    LOAD(fmi2ExitInitializationModeTYPE, fmi2ExitInitializationMode)
    LOAD(fmi2SetIntegerTYPE, fmi2SetInteger)
    LOAD(fmi2GetRealTYPE, fmi2GetReal)
    LOAD(fmi2DoStepTYPE, fmi2DoStep)
    LOAD(fmi2TerminateTYPE, fmi2Terminate)
    LOAD(fmi2FreeInstanceTYPE, fmi2FreeInstance)
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    snprintf(uri, sizeof uri, "file://%s/resources", dir);
    fmi2Component c = fmi2Instantiate("host", fmi2CoSimulation, argv[2], uri, &cb, fmi2False, fmi2True);
    if (!c) { fprintf(stderr, "instantiate failed\n"); return 1; }
    int bad = 0;
    fmi2Integer seed = 7;
    bad |= fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK;
    bad |= fmi2EnterInitializationMode(c) != fmi2OK;
    bad |= fmi2SetInteger(c, &vr_seed, 1, &seed) != fmi2OK;
    bad |= fmi2ExitInitializationMode(c) != fmi2OK;
    for (int k = 0; k < steps && !bad; k++) {
        fmi2Real y;
        bad |= fmi2DoStep(c, k * h, h, fmi2True) != fmi2OK;
        bad |= fmi2GetReal(c, &vr_out, 1, &y) != fmi2OK;
        printf("%.17g %.17g\n", (k + 1) * h, y);
    }
    if (misuse) {
        fmi2Status s1 = fmi2SetInteger(c, &vr_seed, 1, &seed);
        fmi2Status s2 = fmi2ExitInitializationMode(c);
        fmi2Status s3 = fmi2Terminate(c);
        fmi2Status s4 = fmi2DoStep(c, steps * h, h, fmi2True);
        printf("misuse set-parameter %d exit-init-again %d terminate %d step-after-terminate %d\n", s1, s2, s3, s4);
        bad |= s1 == fmi2OK || s2 == fmi2OK || s3 != fmi2OK || s4 == fmi2OK;
        fmi2FreeInstance(c);
        fmi2FreeInstance(c); /* a second free of the same instance */
        printf("freed twice\n");
    } else {
        bad |= fmi2Terminate(c) != fmi2OK;
        fmi2FreeInstance(c);
    }
    fflush(stdout);
    return bad;
}
