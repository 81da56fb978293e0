/* The FMI 3.0 Model Exchange boilerplate shared by the mini FMI 3.0 test FMUs (counter3.c,
 * threshold3.c): every variable is kept as a double in v[] (Int32 and Boolean too), the model file
 * defines VARS, STATES and the model_* functions, this file the fmi3* functions heliostep and
 * fmpy.simulate_fmu call. Written for heliostep's tests against fmpy's FMI 3.0 headers. */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi3Functions.h"

typedef enum { T_F64, T_F32, T_I32, T_I8, T_BOOL } Type;
typedef struct { Type type; double start; } Var;

typedef struct {
    double v[N_VARS];
    double time, next_event;
    bool terminate, in_init;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Instance;

static const Var VARS[N_VARS];
static const fmi3ValueReference STATES[N_STATES > 0 ? N_STATES : 1];
static void model_initialize(Instance *m);
static void model_outputs(Instance *m);
static void model_derivatives(Instance *m, double *dx);
static void model_indicators(Instance *m, double *z);
static void model_event(Instance *m); /* sets m->terminate, m->next_event (INFINITY: none) */

#define M ((Instance *)instance)
#define CHECK_VR(vr) if ((vr) >= N_VARS) { if (M->log) M->log(M->env, fmi3Error, "logStatusError", "bad value reference"); return fmi3Error; }

FMI3_Export const char *fmi3GetVersion(void) { return fmi3Version; }
FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance i, fmi3Boolean on, size_t n, const fmi3String c[]) {
    (void)i; (void)on; (void)n; (void)c; return fmi3OK;
}
FMI3_Export fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resources,
    fmi3Boolean visible, fmi3Boolean logging, fmi3InstanceEnvironment env, fmi3LogMessageCallback log) {
    (void)name; (void)resources; (void)visible; (void)logging;
    if (strcmp(token, MODEL_TOKEN) != 0) { if (log) log(env, fmi3Error, "logStatusError", "wrong instantiation token"); return NULL; }
    Instance *m = calloc(1, sizeof(Instance));
    for (int k = 0; k < N_VARS; k++) m->v[k] = VARS[k].start;
    m->env = env; m->log = log; m->next_event = INFINITY;
    return m;
}
FMI3_Export void fmi3FreeInstance(fmi3Instance instance) { free(instance); }
FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean td, fmi3Float64 tol,
    fmi3Float64 start, fmi3Boolean sd, fmi3Float64 stop) {
    (void)td; (void)tol; (void)sd; (void)stop; M->time = start; M->in_init = true; return fmi3OK;
}
FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    M->in_init = false; model_initialize(M); model_outputs(M);
    if (M->log) M->log(M->env, fmi3OK, "logEvents", "initialized");
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3EnterEventMode(fmi3Instance instance) { (void)instance; return fmi3OK; }
FMI3_Export fmi3Status fmi3Terminate(fmi3Instance instance) { (void)instance; return fmi3OK; }
FMI3_Export fmi3Status fmi3Reset(fmi3Instance instance) {
    for (int k = 0; k < N_VARS; k++) M->v[k] = VARS[k].start;
    M->next_event = INFINITY; M->terminate = false; return fmi3OK;
}
#define GETTER(NAME, CT, TYPE_OK)                                                                              \
    FMI3_Export fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, CT values[],    \
                                size_t nv) {                                                                   \
        if (nv != n) return fmi3Error;                                                                         \
        model_outputs(M);                                                                                      \
        for (size_t k = 0; k < n; k++) { CHECK_VR(vr[k]); if (!(TYPE_OK)) return fmi3Error; values[k] = (CT)M->v[vr[k]]; } \
        return fmi3OK;                                                                                         \
    }
#define SETTER(NAME, CT, TYPE_OK)                                                                              \
    FMI3_Export fmi3Status NAME(fmi3Instance instance, const fmi3ValueReference vr[], size_t n, const CT values[], \
                                size_t nv) {                                                                   \
        if (nv != n) return fmi3Error;                                                                         \
        for (size_t k = 0; k < n; k++) { CHECK_VR(vr[k]); if (!(TYPE_OK)) return fmi3Error; M->v[vr[k]] = (double)values[k]; } \
        return fmi3OK;                                                                                         \
    }
GETTER(fmi3GetFloat64, fmi3Float64, VARS[vr[k]].type == T_F64)
SETTER(fmi3SetFloat64, fmi3Float64, VARS[vr[k]].type == T_F64)
GETTER(fmi3GetFloat32, fmi3Float32, VARS[vr[k]].type == T_F32)
SETTER(fmi3SetFloat32, fmi3Float32, VARS[vr[k]].type == T_F32)
GETTER(fmi3GetInt32, fmi3Int32, VARS[vr[k]].type == T_I32)
SETTER(fmi3SetInt32, fmi3Int32, VARS[vr[k]].type == T_I32)
GETTER(fmi3GetInt8, fmi3Int8, VARS[vr[k]].type == T_I8)
SETTER(fmi3SetInt8, fmi3Int8, VARS[vr[k]].type == T_I8)
GETTER(fmi3GetBoolean, fmi3Boolean, VARS[vr[k]].type == T_BOOL)
SETTER(fmi3SetBoolean, fmi3Boolean, VARS[vr[k]].type == T_BOOL)

FMI3_Export fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *need, fmi3Boolean *terminate,
    fmi3Boolean *nominals, fmi3Boolean *values, fmi3Boolean *defined, fmi3Float64 *next) {
    model_event(M); model_outputs(M);
    *need = false; *terminate = M->terminate; *nominals = false; *values = false;
    *defined = isfinite(M->next_event); *next = *defined ? M->next_event : 0.0;
    if (M->terminate && M->log) M->log(M->env, fmi3OK, "logEvents", "terminating");
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) { (void)instance; return fmi3OK; }
FMI3_Export fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean nosave, fmi3Boolean *enter,
    fmi3Boolean *terminate) {
    (void)instance; (void)nosave; *enter = false; *terminate = false; return fmi3OK;
}
FMI3_Export fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 t) { M->time = t; return fmi3OK; }
FMI3_Export fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[], size_t n) {
    if (n != N_STATES) return fmi3Error;
    for (size_t k = 0; k < n; k++) M->v[STATES[k]] = x[k];
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    if (n != N_STATES) return fmi3Error;
    for (size_t k = 0; k < n; k++) x[k] = M->v[STATES[k]];
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 dx[], size_t n) {
    if (n != N_STATES) return fmi3Error;
    model_outputs(M); model_derivatives(M, dx); return fmi3OK;
}
FMI3_Export fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 z[], size_t n) {
    if (n != N_INDICATORS) return fmi3Error;
    model_outputs(M); model_indicators(M, z); return fmi3OK;
}
FMI3_Export fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    (void)instance; for (size_t k = 0; k < n; k++) x[k] = 1.0; return fmi3OK;
}
FMI3_Export fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *n) { (void)instance; *n = N_INDICATORS; return fmi3OK; }
FMI3_Export fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *n) { (void)instance; *n = N_STATES; return fmi3OK; }
