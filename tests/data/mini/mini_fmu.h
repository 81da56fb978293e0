/*
 * mini_fmu.h -- the FMI 2.0 Model Exchange boilerplate shared by the small hand-written test
 * FMUs in this folder (Counter, PassThrough, Switch).  A model file defines its variable table
 * and a few hooks, then includes this file, which implements every fmi2 function with the
 * state machine checked (Reference-FMUs style):
 *
 *   VARS[N_VARS]        name, type (Real/Integer/Boolean), kind, start value; the value
 *                       reference of a variable is its index.  All values live in v[] as doubles.
 *   kinds               K_PARAM (settable before initialization), K_CIN (continuous input:
 *                       settable in every mode but Terminated), K_DIN (discrete input: only
 *                       before initialization, in initialization and event mode), K_CALC
 *                       (computed, not settable), K_STATE (continuous state, settable via
 *                       fmi2SetContinuousStates only).
 *   STATES[N_STATES]    value references of the continuous states.
 *   model_outputs(m)                 computed variables from states, inputs, parameters
 *   model_derivatives(m, dx)         returns 0, or non-zero (after logging) for an error
 *   model_indicators(m, z)
 *   model_event(m, info)             the discrete part, in event mode
 *   model_initialize(m, info)        at fmi2ExitInitializationMode (e.g. the first time event)
 *
 * Every log message goes to the logger with the componentEnvironment given at instantiation.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

typedef enum { T_REAL, T_INTEGER, T_BOOLEAN } VarType;
typedef enum { K_PARAM, K_CIN, K_DIN, K_CALC, K_STATE } VarKind;
typedef struct { const char *name; VarType type; VarKind kind; double start; } Var;

enum { M_INSTANTIATED = 1, M_INIT = 2, M_EVENT = 4, M_CONT = 8, M_TERMINATED = 16, M_ERROR = 32 };
#define M_ANY 63
#define M_READABLE (M_INIT | M_EVENT | M_CONT | M_TERMINATED | M_ERROR)

typedef struct Instance {
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    char name[128];
    int mode;
    double time;
    double v[N_VARS];
    double next_event; /* the model's next time event (or a negative value: none) */
    int cs;            /* instantiated for Co-Simulation (fmi2DoStep integrates the states itself) */
    int cs_terminated; /* a step ended at the model's stop time (MINI_CS_STOP): fmi2Terminated */
} Instance;

static void logf_(Instance *m, fmi2Status status, const char *format, ...)
{
    char text[512];
    va_list args;
    if (m == NULL || m->logger == NULL) return;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    m->logger(m->env, m->name, status, status >= fmi2Error ? "logStatusError" : "logEvents", "%s", text);
}

static fmi2Status fail(Instance *m, const char *format, ...)
{
    char text[512];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    logf_(m, fmi2Error, "%s", text);
    m->mode = M_ERROR;
    return fmi2Error;
}

static int allowed(Instance *m, const char *function, int modes)
{
    if (m == NULL) return 0;
    if (!(m->mode & modes)) {
        /* an illegal call sequence: refused, the instance stays in its mode */
        logf_(m, fmi2Error, "%s: not allowed in mode %d", function, m->mode);
        return 0;
    }
    return 1;
}

/* the model's tables (defined after this header: tentative definitions) and hooks */
static const Var VARS[N_VARS];
static const fmi2ValueReference STATES[N_STATES];
static void model_outputs(Instance *m);
static int model_derivatives(Instance *m, double *dx);
static void model_indicators(Instance *m, double *z);
static void model_event(Instance *m, fmi2EventInfo *info);
static void model_initialize(Instance *m);
#ifdef MODEL_NOMINALS
static void model_nominals(Instance *m, double *nominals); /* else every nominal is 1 */
#endif

/* ------------------------------------------------------------------ common */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[])
{
    (void)on; (void)n; (void)cats;
    return allowed((Instance *)c, "fmi2SetDebugLogging", M_ANY) ? fmi2OK : fmi2Error;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible, fmi2Boolean logging)
{
    Instance *m;
    int k;
    (void)resources; (void)visible; (void)logging;
    if (functions == NULL || (type != fmi2ModelExchange && type != fmi2CoSimulation) || guid == NULL ||
        strcmp(guid, MODEL_GUID) != 0) {
        if (functions && functions->logger)
            functions->logger(functions->componentEnvironment, name, fmi2Error, "logStatusError",
                              "fmi2Instantiate: wrong type or GUID");
        return NULL;
    }
    m = (Instance *)calloc(1, sizeof(Instance));
    if (m == NULL) return NULL;
    m->logger = functions->logger;
    m->env = functions->componentEnvironment;
    snprintf(m->name, sizeof m->name, "%s", name ? name : "");
    m->mode = M_INSTANTIATED;
    for (k = 0; k < N_VARS; k++) m->v[k] = VARS[k].start;
    m->next_event = -1.0;
    m->cs = type == fmi2CoSimulation;
    return m;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean td, fmi2Real tol, fmi2Real start,
                               fmi2Boolean sd, fmi2Real stop)
{
    Instance *m = (Instance *)c;
    (void)td; (void)tol; (void)sd; (void)stop;
    if (!allowed(m, "fmi2SetupExperiment", M_INSTANTIATED)) return fmi2Error;
    m->time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (!allowed(m, "fmi2EnterInitializationMode", M_INSTANTIATED)) return fmi2Error;
    m->mode = M_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (!allowed(m, "fmi2ExitInitializationMode", M_INIT)) return fmi2Error;
    model_initialize(m);
    model_outputs(m);
    m->mode = m->cs ? M_CONT : M_EVENT; /* Co-Simulation: stepComplete, inputs settable, fmi2DoStep */
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (!allowed(m, "fmi2Terminate", M_EVENT | M_CONT | M_ERROR)) return fmi2Error;
    logf_(m, fmi2OK, "fmi2Terminate at t = %g", m->time);
    m->mode = M_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    Instance *m = (Instance *)c;
    int k;
    if (!allowed(m, "fmi2Reset", M_ANY)) return fmi2Error;
    for (k = 0; k < N_VARS; k++) m->v[k] = VARS[k].start;
    m->mode = M_INSTANTIATED;
    m->next_event = -1.0;
    return fmi2OK;
}

/* ------------------------------------------------------------------ get / set */
static const char *TYPE_NAMES[] = {"Real", "Integer", "Boolean"};

static fmi2Status check_refs(Instance *m, const char *function, const fmi2ValueReference vr[], size_t n,
                             VarType type, int set)
{
    size_t k;
    if (!allowed(m, function, set ? M_ANY & ~M_TERMINATED & ~M_ERROR : M_READABLE)) return fmi2Error;
    for (k = 0; k < n; k++) {
        const Var *var;
        int modes;
        if (vr[k] >= N_VARS) return fail(m, "%s: invalid value reference %u", function, vr[k]);
        var = &VARS[vr[k]];
        if (var->type != type)
            return fail(m, "%s: %s (value reference %u) is a %s variable", function, var->name, vr[k],
                        TYPE_NAMES[var->type]);
        if (!set) continue;
        switch (var->kind) {
        case K_PARAM: modes = M_INSTANTIATED | M_INIT; break;
        case K_CIN: modes = M_INSTANTIATED | M_INIT | M_EVENT | M_CONT; break;
        case K_DIN: modes = M_INSTANTIATED | M_INIT | M_EVENT | (m->cs ? M_CONT : 0); break;
        default: return fail(m, "%s: %s is computed by the model and cannot be set", function, var->name);
        }
        if (!(m->mode & modes))
            return fail(m, "%s: %s can only be set after instantiation, in initialization mode%s "
                        "(mode %d)", function, var->name, var->kind == K_PARAM ? "" : " or event mode", m->mode);
    }
    return fmi2OK;
}

#define GETTER(NAME, CTYPE, TYPE, CONVERT)                                                        \
    fmi2Status NAME(fmi2Component c, const fmi2ValueReference vr[], size_t n, CTYPE value[])      \
    {                                                                                            \
        Instance *m = (Instance *)c;                                                             \
        size_t k;                                                                                \
        if (check_refs(m, #NAME, vr, n, TYPE, 0) != fmi2OK) return fmi2Error;                    \
        model_outputs(m);                                                                        \
        for (k = 0; k < n; k++) value[k] = CONVERT(m->v[vr[k]]);                                 \
        return fmi2OK;                                                                           \
    }
#define SETTER(NAME, CTYPE, TYPE, CONVERT)                                                        \
    fmi2Status NAME(fmi2Component c, const fmi2ValueReference vr[], size_t n, const CTYPE value[]) \
    {                                                                                            \
        Instance *m = (Instance *)c;                                                             \
        size_t k;                                                                                \
        if (check_refs(m, #NAME, vr, n, TYPE, 1) != fmi2OK) return fmi2Error;                    \
        for (k = 0; k < n; k++) m->v[vr[k]] = CONVERT(value[k]);                                 \
        return fmi2OK;                                                                           \
    }
#define AS_REAL(x) ((double)(x))
#define AS_INT(x) ((fmi2Integer)lround(x))
#define AS_BOOL(x) ((x) != 0 ? fmi2True : fmi2False)
#define AS_BOOL_D(x) ((x) ? 1.0 : 0.0)
GETTER(fmi2GetReal, fmi2Real, T_REAL, AS_REAL)
GETTER(fmi2GetInteger, fmi2Integer, T_INTEGER, AS_INT)
GETTER(fmi2GetBoolean, fmi2Boolean, T_BOOLEAN, AS_BOOL)
SETTER(fmi2SetReal, fmi2Real, T_REAL, AS_REAL)
SETTER(fmi2SetInteger, fmi2Integer, T_INTEGER, AS_REAL)
SETTER(fmi2SetBoolean, fmi2Boolean, T_BOOLEAN, AS_BOOL_D)

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String value[])
{
    (void)vr; (void)value;
    return n == 0 ? fmi2OK : fail((Instance *)c, "fmi2GetString: the model has no String variables");
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String value[])
{
    (void)vr; (void)value;
    return n == 0 ? fmi2OK : fail((Instance *)c, "fmi2SetString: the model has no String variables");
}

/* ------------------------------------------------------------------ unsupported */
#define UNSUPPORTED(...) { return fail((Instance *)c, "%s is not supported", __func__); }
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; UNSUPPORTED() }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)s; UNSUPPORTED() }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; UNSUPPORTED() }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) { (void)s; (void)n; UNSUPPORTED() }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) { (void)s; (void)b; (void)n; UNSUPPORTED() }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) { (void)s; (void)b; (void)n; UNSUPPORTED() }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real du[],
                                        fmi2Real dz[])
{ (void)u; (void)nu; (void)z; (void)nz; (void)du; (void)dz; UNSUPPORTED() }

/* ------------------------------------------------------------------ model exchange */
fmi2Status fmi2EnterEventMode(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (!allowed(m, "fmi2EnterEventMode", M_EVENT | M_CONT)) return fmi2Error;
    m->mode = M_EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info)
{
    Instance *m = (Instance *)c;
    if (!allowed(m, "fmi2NewDiscreteStates", M_EVENT)) return fmi2Error;
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = fmi2False;
    model_event(m, info);
    model_outputs(m);
    info->nextEventTimeDefined = m->next_event >= 0.0;
    info->nextEventTime = m->next_event >= 0.0 ? m->next_event : 0.0;
    return m->mode == M_ERROR ? fmi2Error : fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c)
{
    Instance *m = (Instance *)c;
    if (!allowed(m, "fmi2EnterContinuousTimeMode", M_EVENT)) return fmi2Error;
    m->mode = M_CONT;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSet, fmi2Boolean *enter,
                                       fmi2Boolean *terminate)
{
    Instance *m = (Instance *)c;
    (void)noSet;
    if (!allowed(m, "fmi2CompletedIntegratorStep", M_CONT)) return fmi2Error;
    *enter = fmi2False;
    *terminate = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time)
{
    Instance *m = (Instance *)c;
    if (!allowed(m, "fmi2SetTime", M_EVENT | M_CONT)) return fmi2Error;
    m->time = time;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx)
{
    Instance *m = (Instance *)c;
    size_t k;
    if (!allowed(m, "fmi2SetContinuousStates", M_CONT)) return fmi2Error;
    if (nx != N_STATES) return fail(m, "fmi2SetContinuousStates: nx = %u, expected %d", (unsigned)nx, N_STATES);
    for (k = 0; k < nx; k++) m->v[STATES[k]] = x[k];
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx)
{
    Instance *m = (Instance *)c;
    size_t k;
    if (!allowed(m, "fmi2GetContinuousStates", M_READABLE)) return fmi2Error;
    if (nx != N_STATES) return fail(m, "fmi2GetContinuousStates: nx = %u, expected %d", (unsigned)nx, N_STATES);
    for (k = 0; k < nx; k++) x[k] = m->v[STATES[k]];
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x[], size_t nx)
{
    size_t k;
    if (!allowed((Instance *)c, "fmi2GetNominalsOfContinuousStates", M_ANY)) return fmi2Error;
    for (k = 0; k < nx; k++) x[k] = 1.0;
#ifdef MODEL_NOMINALS
    if (nx == N_STATES) model_nominals((Instance *)c, x);
#endif
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real dx[], size_t nx)
{
    Instance *m = (Instance *)c;
    if (!allowed(m, "fmi2GetDerivatives", M_READABLE)) return fmi2Error;
    if (nx != N_STATES) return fail(m, "fmi2GetDerivatives: nx = %u, expected %d", (unsigned)nx, N_STATES);
    model_outputs(m);
    if (model_derivatives(m, dx) != 0) {
        m->mode = M_ERROR;
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real z[], size_t nz)
{
    Instance *m = (Instance *)c;
    if (!allowed(m, "fmi2GetEventIndicators", M_READABLE)) return fmi2Error;
    if (nz != N_INDICATORS) return fail(m, "fmi2GetEventIndicators: nz = %u, expected %d", (unsigned)nz, N_INDICATORS);
    model_outputs(m);
    model_indicators(m, z);
    return fmi2OK;
}

/* ------------------------------------------------------------------ co-simulation
 * fmi2DoStep integrates the continuous states over the communication step with the classical
 * fourth-order Runge-Kutta method at a fixed internal step of at most MINI_CS_STEP seconds, the
 * inputs held; time events and state events are not handled inside a step (the CS twins of the
 * tests have none).
 *
 * A model may define MINI_CS_STOP(m), its stop time [s], and MINI_CS_SAYS_TERMINATED(m): a step
 * that would pass the stop time integrates up to it and returns fmi2Discard; the slave then says
 * fmi2Terminated (fmi2GetBooleanStatus) if MINI_CS_SAYS_TERMINATED(m), and its
 * fmi2LastSuccessfulTime (fmi2GetRealStatus) is the stop time (FMI 2.0.4, section 4.2.3). A step
 * after that is an error. */
#ifndef MINI_CS_STEP
#define MINI_CS_STEP 1e-3
#endif

static int cs_derivatives(Instance *m, const double *x, double *dx)
{
    int k;
    for (k = 0; k < N_STATES; k++) m->v[STATES[k]] = x[k];
    model_outputs(m);
    return model_derivatives(m, dx);
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior)
{
    Instance *m = (Instance *)c;
    double x[N_STATES + 1], y[N_STATES + 1], k1[N_STATES + 1], k2[N_STATES + 1], k3[N_STATES + 1],
        k4[N_STATES + 1];
    int n, step, k;
    (void)noSetPrior;
    if (!allowed(m, "fmi2DoStep", M_CONT) || !m->cs) return fail(m, "fmi2DoStep: not a Co-Simulation instance");
    if (!(h > 0.0)) return fail(m, "fmi2DoStep: communication step size %g, expected > 0", h);
    if (fabs(t - m->time) > 1e-9 * (1.0 + fabs(t)))
        return fail(m, "fmi2DoStep: communication point %.17g, the FMU is at %.17g", t, m->time);
    if (m->cs_terminated) return fail(m, "fmi2DoStep: the slave stopped at t = %g (fmi2Discard)", m->time);
#ifdef MINI_CS_STOP
    if (t + h > MINI_CS_STOP(m) + 1e-12 * (1.0 + fabs(t))) {
        m->cs_terminated = 1;
        h = MINI_CS_STOP(m) > t ? MINI_CS_STOP(m) - t : 0.0; /* integrated up to the stop time, then discarded */
    }
#endif
    n = (int)ceil(h / MINI_CS_STEP - 1e-9);
    for (k = 0; k < N_STATES; k++) x[k] = m->v[STATES[k]];
    for (step = 0; step < n && N_STATES > 0; step++) {
        double dt = h / n;
        int failed = cs_derivatives(m, x, k1);
        for (k = 0; k < N_STATES; k++) y[k] = x[k] + 0.5 * dt * k1[k];
        failed |= cs_derivatives(m, y, k2);
        for (k = 0; k < N_STATES; k++) y[k] = x[k] + 0.5 * dt * k2[k];
        failed |= cs_derivatives(m, y, k3);
        for (k = 0; k < N_STATES; k++) y[k] = x[k] + dt * k3[k];
        failed |= cs_derivatives(m, y, k4);
        if (failed) return fail(m, "fmi2DoStep: the derivatives failed at t = %g", m->time + step * dt);
        for (k = 0; k < N_STATES; k++) x[k] += dt / 6.0 * (k1[k] + 2.0 * k2[k] + 2.0 * k3[k] + k4[k]);
    }
    for (k = 0; k < N_STATES; k++) m->v[STATES[k]] = x[k];
    m->time = t + h;
    model_outputs(m);
    if (m->cs_terminated) {
        logf_(m, fmi2Discard, "fmi2DoStep: stopped at t = %g, before the communication point", m->time);
        return fmi2Discard;
    }
    return fmi2OK;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer order[], const fmi2Real value[])
{ (void)vr; (void)n; (void)order; (void)value; UNSUPPORTED() }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer order[], fmi2Real value[])
{ (void)vr; (void)n; (void)order; (void)value; UNSUPPORTED() }
fmi2Status fmi2CancelStep(fmi2Component c) { UNSUPPORTED() }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) { (void)s; (void)value; UNSUPPORTED() }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    Instance *m = (Instance *)c;
    if (!allowed(m, "fmi2GetRealStatus", M_READABLE) || !m->cs || value == NULL || s != fmi2LastSuccessfulTime)
        UNSUPPORTED()
    *value = m->time;
    return fmi2OK;
}
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) { (void)s; (void)value; UNSUPPORTED() }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    Instance *m = (Instance *)c;
    if (!allowed(m, "fmi2GetBooleanStatus", M_READABLE) || !m->cs || value == NULL || s != fmi2Terminated)
        UNSUPPORTED()
#ifdef MINI_CS_SAYS_TERMINATED
    *value = m->cs_terminated && MINI_CS_SAYS_TERMINATED(m) ? fmi2True : fmi2False;
#else
    *value = m->cs_terminated ? fmi2True : fmi2False;
#endif
    return fmi2OK;
}
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) { (void)s; (void)value; UNSUPPORTED() }
