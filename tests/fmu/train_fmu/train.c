/* A small FMI 2.0 co-simulation FMU for navsim's tests: longitudinal train dynamics.
 *
 *   m dv/dt = F_traction - (A + B v + C v^2)   for v > 0 (Davis resistance),
 *   ds/dt = v,
 * with the train held at rest while the traction does not overcome A. Integrated with
 * classical Runge-Kutta on ten sub-steps per communication step. Outputs: s (m), v (m/s),
 * a (m/s^2, the right-hand side at the end of the step). Written for navsim; no code
 * from elsewhere. Compile: gcc -shared -fPIC -I<fmi2 headers> train.c -o TrainModel.so -lm
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "fmi2Functions.h"

enum { VR_S, VR_V, VR_A, VR_F, VR_MASS, VR_DA, VR_DB, VR_DC, VR_S0, VR_V0, NVR };

typedef struct {
    double x[NVR];
    double time;
    fmi2CallbackFunctions cb;
    char *name;
} Train;

static double accel(const Train *t, double v) {
    double F = t->x[VR_F], m = t->x[VR_MASS];
    double r = t->x[VR_DA] + t->x[VR_DB] * v + t->x[VR_DC] * v * v;
    if (v <= 0.0 && F <= t->x[VR_DA]) return 0.0;
    return (F - r) / m;
}

static void outputs(Train *t) { t->x[VR_A] = accel(t, t->x[VR_V]); }

static void log_error(Train *t, const char *msg) {
    if (t->cb.logger) t->cb.logger(t->cb.componentEnvironment, t->name, fmi2Error, "logStatusError", msg);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[]) { return fmi2OK; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String res,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging) {
    if (type != fmi2CoSimulation) return NULL;
    Train *t = calloc(1, sizeof(Train));
    if (!t) return NULL;
    t->cb = *cb;
    t->name = strdup(name ? name : "train");
    t->x[VR_MASS] = 4.0e5; t->x[VR_DA] = 6.0e3; t->x[VR_DB] = 100.0; t->x[VR_DC] = 8.0;
    t->x[VR_F] = 0.0; t->x[VR_S0] = 0.0; t->x[VR_V0] = 10.0;
    return t;
}

void fmi2FreeInstance(fmi2Component c) {
    Train *t = c;
    if (!t) return;
    free(t->name);
    free(t);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDef, fmi2Real stop) {
    ((Train *)c)->time = start;
    return fmi2OK;
}
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Train *t = c;
    if (!(t->x[VR_MASS] > 0.0)) { log_error(t, "mass must be > 0"); return fmi2Error; }
    t->x[VR_S] = t->x[VR_S0];
    t->x[VR_V] = t->x[VR_V0];
    outputs(t);
    return fmi2OK;
}
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { ((Train *)c)->time = 0.0; return fmi2OK; }

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    Train *t = c;
    for (size_t i = 0; i < n; i++) { if (vr[i] >= NVR) return fmi2Error; v[i] = t->x[vr[i]]; }
    return fmi2OK;
}
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    Train *t = c;
    for (size_t i = 0; i < n; i++) { if (vr[i] >= NVR) return fmi2Error; t->x[vr[i]] = v[i]; }
    return fmi2OK;
}
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) { return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) { return n ? fmi2Error : fmi2OK; }

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t0, fmi2Real h, fmi2Boolean noSet) {
    Train *t = c;
    if (!(h > 0.0)) { log_error(t, "step size must be > 0"); return fmi2Error; }
    const int n = 10;
    double dt = h / n, s = t->x[VR_S], v = t->x[VR_V];
    for (int k = 0; k < n; k++) {  /* classical RK4 on (s, v) */
        double k1s = v, k1v = accel(t, v);
        double k2s = v + 0.5 * dt * k1v, k2v = accel(t, k2s);
        double k3s = v + 0.5 * dt * k2v, k3v = accel(t, k3s);
        double k4s = v + dt * k3v, k4v = accel(t, k4s);
        s += dt / 6.0 * (k1s + 2 * k2s + 2 * k3s + k4s);
        v += dt / 6.0 * (k1v + 2 * k2v + 2 * k3v + k4v);
        if (v < 0.0) v = 0.0;
    }
    t->x[VR_S] = s; t->x[VR_V] = v;
    outputs(t);
    t->time = t0 + h;
    return fmi2OK;
}
fmi2Status fmi2CancelStep(fmi2Component c) { return fmi2Error; }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v) { return fmi2Error; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v) { return fmi2Error; }
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v) { return fmi2Error; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v) { return fmi2Error; }
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v) { return fmi2Error; }
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { return fmi2Error; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) { return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) { return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) { return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dz[], fmi2Real du[]) { return fmi2Error; }
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer o[], const fmi2Real v[]) { return fmi2Error; }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer o[], fmi2Real v[]) { return fmi2Error; }
