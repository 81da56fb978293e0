/*
 * Lag3 -- a first-order lag T dy/dt = u - y (y: its state and output, no direct feedthrough) and the lag
 * error e = u - y (direct feedthrough of u), as one FMI 3.0 binary exporting both Model Exchange and
 * Co-Simulation: the tests' FMI 3.0 CS FMU and its ME twin, the same equations. Written for heliostep's
 * tests against fmpy's FMI 3.0 headers (fmi3Functions.h); every other FMI 3.0 function is in
 * ../mini3/fmi3_stubs.c.
 *
 * Co-Simulation (FMI 3.0 standard, section 4): fmi3DoStep integrates with the input held over the step,
 * fixed-step classical Runge-Kutta (RK4) at the internal step h_int (the step divided into
 * ceil(step / h_int) equal parts). For a held u the exact step is y + (u - y) (1 - exp(-dt / T)); RK4's
 * local error is (dt / T)^5 / 120 of (u - y): 2.7e-16 at dt = 1 ms, T = 0.5 s.
 *
 * The doStep flags, for the importer's tests: once a step ends at or after t_stop, the step returns
 * with misbehave = 0: terminateSimulation; 1: eventHandlingNeeded (though instantiated with
 * eventModeUsed = false, unless the importer asked for event mode); 2: the step ends early at t_stop
 * (earlyReturn, lastSuccessfulTime = t_stop), whether the importer allowed early returns or not.
 * State machine: Instantiated -> (EnterInitializationMode) Initialization -> (ExitInitializationMode)
 * Step Mode (CS) or Event Mode (ME) ... Terminated; a call out of its state is fmi3Error with a message.
 */
#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi3Functions.h"

#ifndef LAG3_TOKEN
#define LAG3_TOKEN "{c0a7e1f2-3101-4000-8000-000000000101}"
#endif

enum { VR_TIME, VR_U, VR_Y, VR_DER_Y, VR_E, VR_T, VR_H_INT, VR_T_STOP, VR_MISBEHAVE, N_VARS };
typedef enum { INSTANTIATED = 1, INITIALIZATION = 2, EVENT = 4, CONTINUOUS = 8, STEP = 16, TERMINATED = 32,
               FAILED = 64 } State;

typedef struct {
    double u, y, T, h_int, t_stop, time;
    int misbehave;
    bool cs, event_mode_used, early_return_allowed;
    State state;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Lag;

static void say(Lag *m, fmi3Status status, const char *format, ...)
{
    char text[256];
    va_list args;
    if (m == NULL || m->log == NULL) return;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    m->log(m->env, status, status >= fmi3Error ? "logStatusError" : "logEvents", text);
}

/* refused unless the instance is in one of the states `allowed`; the state stays as it was */
static bool in_state(Lag *m, const char *function, int allowed)
{
    if (m == NULL) return false;
    if (!(m->state & allowed)) {
        say(m, fmi3Error, "%s: not allowed in state %d", function, (int)m->state);
        return false;
    }
    return true;
}

static fmi3Status failed(Lag *m, const char *format, const char *what, double value)
{
    say(m, fmi3Error, format, what, value);
    m->state = FAILED;
    return fmi3Error;
}

static Lag *instantiate(fmi3String token, bool cs, fmi3InstanceEnvironment env, fmi3LogMessageCallback log)
{
    Lag *m;
    if (token == NULL || strcmp(token, LAG3_TOKEN) != 0) {
        if (log) log(env, fmi3Error, "logStatusError", "wrong instantiation token");
        return NULL;
    }
    m = calloc(1, sizeof(Lag));
    if (m == NULL) return NULL;
    m->T = 0.5; m->h_int = 1e-3; m->t_stop = 1e9;
    m->cs = cs; m->state = INSTANTIATED; m->env = env; m->log = log;
    return m;
}

FMI3_Export const char *fmi3GetVersion(void) { return fmi3Version; }

FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean on, size_t n, const fmi3String c[])
{
    (void)instance; (void)on; (void)n; (void)c;
    return fmi3OK;
}

FMI3_Export fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resources,
    fmi3Boolean visible, fmi3Boolean logging, fmi3InstanceEnvironment env, fmi3LogMessageCallback log)
{
    (void)name; (void)resources; (void)visible; (void)logging;
    return instantiate(token, false, env, log);
}

FMI3_Export fmi3Instance fmi3InstantiateCoSimulation(fmi3String name, fmi3String token, fmi3String resources,
    fmi3Boolean visible, fmi3Boolean logging, fmi3Boolean event_mode_used, fmi3Boolean early_return_allowed,
    const fmi3ValueReference required[], size_t n_required, fmi3InstanceEnvironment env,
    fmi3LogMessageCallback log, fmi3IntermediateUpdateCallback update)
{
    Lag *m;
    (void)name; (void)resources; (void)visible; (void)logging; (void)required; (void)n_required; (void)update;
    m = instantiate(token, true, env, log);
    if (m != NULL) {
        m->event_mode_used = event_mode_used;
        m->early_return_allowed = early_return_allowed;
    }
    return m;
}

FMI3_Export void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

#define M ((Lag *)instance)

FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean tolerance_defined,
    fmi3Float64 tolerance, fmi3Float64 start, fmi3Boolean stop_defined, fmi3Float64 stop)
{
    (void)tolerance_defined; (void)tolerance; (void)stop_defined; (void)stop;
    if (!in_state(M, "fmi3EnterInitializationMode", INSTANTIATED)) return fmi3Error;
    M->time = start;
    M->state = INITIALIZATION;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    if (!in_state(M, "fmi3ExitInitializationMode", INITIALIZATION)) return fmi3Error;
    M->state = M->cs ? STEP : EVENT;
    say(M, fmi3OK, "initialized at t = %g (%s)", M->time, M->cs ? "Co-Simulation" : "Model Exchange");
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3EnterEventMode(fmi3Instance instance)
{
    if (!in_state(M, "fmi3EnterEventMode", M->cs ? STEP : (EVENT | CONTINUOUS))) return fmi3Error;
    M->state = EVENT;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3EnterStepMode(fmi3Instance instance)
{
    if (!M->cs || !in_state(M, "fmi3EnterStepMode", EVENT)) return fmi3Error;
    M->state = STEP;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3Terminate(fmi3Instance instance)
{
    if (!in_state(M, "fmi3Terminate", EVENT | CONTINUOUS | STEP | FAILED)) return fmi3Error;
    M->state = TERMINATED;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3Reset(fmi3Instance instance)
{
    bool cs = M->cs;
    fmi3InstanceEnvironment env = M->env;
    fmi3LogMessageCallback log = M->log;
    memset(M, 0, sizeof(Lag));
    M->T = 0.5; M->h_int = 1e-3; M->t_stop = 1e9;
    M->cs = cs; M->env = env; M->log = log; M->state = INSTANTIATED;
    return fmi3OK;
}

static double value_of(Lag *m, fmi3ValueReference vr)
{
    switch (vr) {
    case VR_TIME: return m->time;
    case VR_U: return m->u;
    case VR_Y: return m->y;
    case VR_DER_Y: return (m->u - m->y) / m->T;
    case VR_E: return m->u - m->y;
    case VR_T: return m->T;
    case VR_H_INT: return m->h_int;
    default: return m->t_stop;
    }
}

FMI3_Export fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
    fmi3Float64 values[], size_t n_values)
{
    size_t k;
    if (!in_state(M, "fmi3GetFloat64", ~INSTANTIATED)) return fmi3Error;
    if (n_values != n) return failed(M, "%s: nValues %g differs from nValueReferences", "fmi3GetFloat64", n_values);
    for (k = 0; k < n; k++) {
        if (vr[k] >= VR_MISBEHAVE) return failed(M, "%s: no Float64 variable of value reference %g", "fmi3GetFloat64", vr[k]);
        values[k] = value_of(M, vr[k]);
    }
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
    const fmi3Float64 values[], size_t n_values)
{
    size_t k;
    bool setup = (M->state & (INSTANTIATED | INITIALIZATION)) != 0;
    if (!in_state(M, "fmi3SetFloat64", INSTANTIATED | INITIALIZATION | EVENT | CONTINUOUS | STEP)) return fmi3Error;
    if (n_values != n) return failed(M, "%s: nValues %g differs from nValueReferences", "fmi3SetFloat64", n_values);
    for (k = 0; k < n; k++) {
        double v = values[k];
        if (!isfinite(v)) return failed(M, "%s: a value that is not finite (%g)", "fmi3SetFloat64", v);
        if (vr[k] == VR_U) M->u = v;
        else if (vr[k] == VR_Y && setup) M->y = v;
        else if (vr[k] == VR_T && setup && v > 0) M->T = v;
        else if (vr[k] == VR_H_INT && setup && v > 0) M->h_int = v;
        else if (vr[k] == VR_T_STOP && setup) M->t_stop = v;
        else return failed(M, "%s: value reference %g cannot be set now (or not to that value)", "fmi3SetFloat64", vr[k]);
    }
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
    fmi3Int32 values[], size_t n_values)
{
    size_t k;
    if (!in_state(M, "fmi3GetInt32", ~INSTANTIATED) || n_values != n) return fmi3Error;
    for (k = 0; k < n; k++) {
        if (vr[k] != VR_MISBEHAVE) return failed(M, "%s: no Int32 variable of value reference %g", "fmi3GetInt32", vr[k]);
        values[k] = M->misbehave;
    }
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
    const fmi3Int32 values[], size_t n_values)
{
    size_t k;
    if (!in_state(M, "fmi3SetInt32", INSTANTIATED | INITIALIZATION) || n_values != n) return fmi3Error;
    for (k = 0; k < n; k++) {
        if (vr[k] != VR_MISBEHAVE) return failed(M, "%s: no Int32 variable of value reference %g", "fmi3SetInt32", vr[k]);
        M->misbehave = values[k];
    }
    return fmi3OK;
}

/* ------------------------------------------------------------------ Co-Simulation */

static double rk4(double y, double u, double T, double dt)
{
    double k1 = (u - y) / T;
    double k2 = (u - (y + 0.5 * dt * k1)) / T;
    double k3 = (u - (y + 0.5 * dt * k2)) / T;
    double k4 = (u - (y + dt * k3)) / T;
    return y + dt / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
}

FMI3_Export fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 point, fmi3Float64 step,
    fmi3Boolean no_set_state_prior, fmi3Boolean *event_handling_needed, fmi3Boolean *terminate,
    fmi3Boolean *early_return, fmi3Float64 *last_successful_time)
{
    double target = point + step, dt;
    long parts, k;
    bool early = false, at_stop;
    (void)no_set_state_prior;
    if (!M->cs || !in_state(M, "fmi3DoStep", STEP)) return fmi3Error;
    if (!(step > 0)) return failed(M, "%s: communicationStepSize %g is not positive", "fmi3DoStep", step);
    if (fabs(point - M->time) > 1e-9 * fmax(1.0, fabs(point)))
        return failed(M, "%s: currentCommunicationPoint %.17g is not the FMU's time", "fmi3DoStep", point);
    if (M->misbehave == 2 && M->t_stop > point && M->t_stop < target) {
        target = M->t_stop; /* an early return, whether allowed or not (the importer's test) */
        early = true;
    }
    parts = (long)ceil((target - point) / M->h_int - 1e-9);
    if (parts < 1) parts = 1;
    dt = (target - point) / (double)parts;
    for (k = 0; k < parts; k++) M->y = rk4(M->y, M->u, M->T, dt);
    M->time = target;
    at_stop = target >= M->t_stop - 1e-9 * fmax(1.0, fabs(M->t_stop));
    *early_return = early;
    *last_successful_time = target;
    *terminate = at_stop && M->misbehave == 0;
    *event_handling_needed = at_stop && M->misbehave == 1;
    if (*terminate) say(M, fmi3OK, "terminateSimulation at t = %g (t_stop)", target);
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
    const fmi3Int32 orders[], fmi3Float64 values[], size_t n_values)
{
    (void)vr; (void)n; (void)orders; (void)values; (void)n_values;
    say(M, fmi3Error, "fmi3GetOutputDerivatives: not provided");
    return fmi3Error;
}

/* ------------------------------------------------------------------ Model Exchange */

FMI3_Export fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *need, fmi3Boolean *terminate,
    fmi3Boolean *nominals, fmi3Boolean *values, fmi3Boolean *defined, fmi3Float64 *next)
{
    if (!in_state(M, "fmi3UpdateDiscreteStates", EVENT)) return fmi3Error;
    *need = false; *terminate = false; *nominals = false; *values = false; *defined = false; *next = 0.0;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance)
{
    if (M->cs || !in_state(M, "fmi3EnterContinuousTimeMode", EVENT)) return fmi3Error;
    M->state = CONTINUOUS;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean no_set_state_prior,
    fmi3Boolean *enter, fmi3Boolean *terminate)
{
    (void)no_set_state_prior;
    if (!in_state(M, "fmi3CompletedIntegratorStep", CONTINUOUS)) return fmi3Error;
    *enter = false; *terminate = false;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 t)
{
    if (M->cs || !in_state(M, "fmi3SetTime", EVENT | CONTINUOUS)) return fmi3Error;
    M->time = t;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[], size_t n)
{
    if (M->cs || n != 1 || !in_state(M, "fmi3SetContinuousStates", CONTINUOUS)) return fmi3Error;
    M->y = x[0];
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t n)
{
    if (M->cs || n != 1 || !in_state(M, "fmi3GetContinuousStates", ~INSTANTIATED)) return fmi3Error;
    x[0] = M->y;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 dx[], size_t n)
{
    if (M->cs || n != 1 || !in_state(M, "fmi3GetContinuousStateDerivatives", ~INSTANTIATED)) return fmi3Error;
    dx[0] = (M->u - M->y) / M->T;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 z[], size_t n)
{
    (void)instance; (void)z;
    return n == 0 ? fmi3OK : fmi3Error;
}

FMI3_Export fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t n)
{
    size_t k;
    (void)instance;
    for (k = 0; k < n; k++) x[k] = 1.0;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *n)
{
    (void)instance;
    *n = 0;
    return fmi3OK;
}

FMI3_Export fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *n)
{
    *n = M->cs ? 0 : 1;
    return fmi3OK;
}
