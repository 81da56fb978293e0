/*
 * BouncingBall -- a small, hand-written FMI 2.0 Model Exchange FMU, written the
 * way another tool would export one, so that heliostep's master can be tested
 * against an FMU with events of every kind.  Plain C99, no dependencies beyond
 * the FMI 2.0 headers and libm.
 *
 *   states      h [m] (height, starts at the parameter h0), v [m/s] (start 0)
 *   equations   der(h) = v,  der(v) = -g + f       (f: input acceleration)
 *   state event event indicator z = h; when h reaches the floor (h <= 0) moving
 *               down (v < 0):  v := -e*v, h := 0, bounce_count += 1.  Once the
 *               rebound speed drops below V_MIN the ball lies still (h = v = 0,
 *               der(h) = der(v) = 0, z = 1) so the indicator cannot chatter.
 *               While it lies still the input f is ignored (a "sticky" floor).
 *   time event  at t = t_kick: v := v + KICK_DV (announced via nextEventTime
 *               from fmi2NewDiscreteStates, also right after initialization);
 *               a kick ends the resting phase.  A kick time before the start
 *               time is skipped.
 *
 * Every call is checked against the FMI 2.0 Model Exchange state machine and
 * its arguments; a wrong call returns fmi2Error with a logged message and leaves
 * the instance unchanged (it never crashes on bad input).  FMU state get/set
 * and directional derivatives are not supported (fmi2Error with a message).
 * Co-Simulation functions are not exported (the FMU is Model Exchange only).
 */

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "fmi2Functions.h"

#define MODEL_IDENTIFIER "BouncingBall"
#define MODEL_GUID "{5b7e3c9a-2f41-4d8e-9c1a-7e0b6d2f4a13}"

#define N_STATES 2
#define N_EVENT_INDICATORS 1
#define KICK_DV 2.0   /* velocity added by the kick [m/s] */
/* Rebound speed below which the ball lies still [m/s].  Much smaller values let the
 * last, tiny bounces drown in the integrator's absolute error (1e-6 m at the usual
 * tolerances), and the ball then chatters on the floor or falls through it. */
#define V_MIN 0.1
#define TIME_RTOL 1e-10 /* relative tolerance for "the time event is due" */

/* value references (see modelDescription.xml) */
enum {
    VR_TIME = 0,
    VR_H = 1,
    VR_DER_H = 2,
    VR_V = 3,
    VR_DER_V = 4,
    VR_G = 5,
    VR_E = 6,
    VR_H0 = 7,
    VR_T_KICK = 8,
    VR_F = 9,
    VR_HEIGHT = 10,
    VR_BOUNCE_COUNT = 11,
    N_REALS = 12
};

static const char *const VARIABLE_NAMES[N_REALS] = {
    "time", "h", "der(h)", "v", "der(v)", "g", "e", "h0", "t_kick", "f", "height", "bounce_count"
};

/* the modes of the FMI 2.0 Model Exchange state machine (bit masks) */
typedef enum {
    MODE_INSTANTIATED = 1 << 0,
    MODE_INITIALIZATION = 1 << 1,
    MODE_EVENT = 1 << 2,
    MODE_CONTINUOUS_TIME = 1 << 3,
    MODE_TERMINATED = 1 << 4,
    MODE_ERROR = 1 << 5
} Mode;

#define MODE_ANY (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT | MODE_CONTINUOUS_TIME \
                  | MODE_TERMINATED | MODE_ERROR)
#define MODE_INITIALIZED (MODE_EVENT | MODE_CONTINUOUS_TIME)
#define MODE_READABLE (MODE_INITIALIZATION | MODE_INITIALIZED | MODE_TERMINATED | MODE_ERROR)

/* log categories (as declared in modelDescription.xml) */
enum { LOG_EVENTS, LOG_STATUS_WARNING, LOG_STATUS_ERROR, LOG_CALLS, N_CATEGORIES };
static const char *const CATEGORY_NAMES[N_CATEGORIES] = {
    "logEvents", "logStatusWarning", "logStatusError", "logCalls"
};

typedef struct {
    /* callbacks (copied: the caller's struct need not outlive fmi2Instantiate) */
    fmi2CallbackLogger logger;
    fmi2CallbackAllocateMemory allocateMemory;
    fmi2CallbackFreeMemory freeMemory;
    fmi2ComponentEnvironment componentEnvironment;
    char *instanceName;
    fmi2Boolean loggingOn;
    fmi2Boolean categories[N_CATEGORIES];
    int mode; /* one of Mode */

    /* parameters and input */
    fmi2Real g, e, h0, t_kick, f;
    /* continuous states and time */
    fmi2Real time, h, v;
    /* discrete states */
    fmi2Real bounce_count;
    fmi2Boolean resting; /* the ball lies still on the floor */
    fmi2Boolean kicked;  /* the time event has happened (or was skipped) */
} Instance;

/* ------------------------------------------------------------------ logging */

static void logMessage(const Instance *inst, fmi2Status status, int category, const char *format, ...)
{
    char text[512];
    char escaped[2 * sizeof text];
    va_list args;
    size_t i, j;

    if (inst == NULL || inst->logger == NULL) {
        return;
    }
    /* errors and warnings are always reported; everything else only when asked for */
    if (status < fmi2Warning && !(inst->loggingOn && inst->categories[category])) {
        return;
    }
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    /* the logger treats the message as a format string: escape every '%' */
    for (i = 0, j = 0; text[i] != '\0' && j + 2 < sizeof escaped; i++) {
        if (text[i] == '%') {
            escaped[j++] = '%';
        }
        escaped[j++] = text[i];
    }
    escaped[j] = '\0';
    inst->logger(inst->componentEnvironment, inst->instanceName, status, CATEGORY_NAMES[category],
                 escaped);
}

#define LOG_ERROR(inst, ...) logMessage((inst), fmi2Error, LOG_STATUS_ERROR, __VA_ARGS__)
#define LOG_WARNING(inst, ...) logMessage((inst), fmi2Warning, LOG_STATUS_WARNING, __VA_ARGS__)

static const char *modeName(int mode)
{
    switch (mode) {
    case MODE_INSTANTIATED: return "Instantiated";
    case MODE_INITIALIZATION: return "Initialization Mode";
    case MODE_EVENT: return "Event Mode";
    case MODE_CONTINUOUS_TIME: return "Continuous-Time Mode";
    case MODE_TERMINATED: return "Terminated";
    case MODE_ERROR: return "Error";
    }
    return "unknown";
}

/* NULL instance: nothing to log to; wrong mode: log and refuse */
static int invalidMode(const Instance *inst, const char *function, int allowed)
{
    if (inst == NULL) {
        return 1;
    }
    if (!(inst->mode & allowed)) {
        LOG_ERROR(inst, "%s: illegal call sequence: not allowed in %s.", function, modeName(inst->mode));
        return 1;
    }
    logMessage(inst, fmi2OK, LOG_CALLS, "%s", function);
    return 0;
}

static int nullPointer(const Instance *inst, const char *function, const char *argument, const void *p)
{
    if (p == NULL) {
        LOG_ERROR(inst, "%s: invalid argument %s = NULL.", function, argument);
        return 1;
    }
    return 0;
}

static int invalidNumber(const Instance *inst, const char *function, const char *argument, size_t n,
                         size_t expected)
{
    if (n != expected) {
        LOG_ERROR(inst, "%s: invalid argument %s = %lu (expected %lu).", function, argument,
                  (unsigned long)n, (unsigned long)expected);
        return 1;
    }
    return 0;
}

/* ------------------------------------------------------------------ the model */

static void setStartValues(Instance *inst)
{
    inst->g = 9.81;
    inst->e = 0.7;
    inst->h0 = 1.0;
    inst->t_kick = 0.5;
    inst->f = 0.0;
    inst->time = 0.0;
    inst->h = inst->h0; /* initial="calculated": h = h0 */
    inst->v = 0.0;
    inst->bounce_count = 0.0;
    inst->resting = fmi2False;
    inst->kicked = fmi2False;
}

static void derivatives(const Instance *inst, fmi2Real *der_h, fmi2Real *der_v)
{
    if (inst->resting) {
        *der_h = 0.0;
        *der_v = 0.0;
    } else {
        *der_h = inst->v;
        *der_v = -inst->g + inst->f;
    }
}

static fmi2Real eventIndicator(const Instance *inst)
{
    return inst->resting ? 1.0 : inst->h;
}

/* has time reached eventTime (within a relative tolerance, for masters stopping just short)? */
static int timeReached(fmi2Real time, fmi2Real eventTime)
{
    return time >= eventTime - TIME_RTOL * fmax(1.0, fabs(eventTime));
}

/* is time clearly past eventTime? */
static int timeMissed(fmi2Real time, fmi2Real eventTime)
{
    return time > eventTime + TIME_RTOL * fmax(1.0, fabs(eventTime));
}

static fmi2Real getValue(const Instance *inst, fmi2ValueReference vr)
{
    fmi2Real der_h, der_v;

    derivatives(inst, &der_h, &der_v);
    switch (vr) {
    case VR_TIME: return inst->time;
    case VR_H: return inst->h;
    case VR_DER_H: return der_h;
    case VR_V: return inst->v;
    case VR_DER_V: return der_v;
    case VR_G: return inst->g;
    case VR_E: return inst->e;
    case VR_H0: return inst->h0;
    case VR_T_KICK: return inst->t_kick;
    case VR_F: return inst->f;
    case VR_HEIGHT: return inst->h;
    case VR_BOUNCE_COUNT: return inst->bounce_count;
    }
    return 0.0; /* not reached: value references are checked by the caller */
}

/* May vr be set to value in the current mode?  Logs the reason when not. */
static int checkSet(const Instance *inst, fmi2ValueReference vr, fmi2Real value)
{
    const int beforeInit = MODE_INSTANTIATED | MODE_INITIALIZATION;
    int allowed;

    if (vr >= N_REALS) {
        LOG_ERROR(inst, "fmi2SetReal: invalid value reference %u.", vr);
        return 0;
    }
    switch (vr) {
    case VR_G: case VR_E: case VR_H0: case VR_T_KICK: /* fixed parameters */
    case VR_V:                                        /* state with initial="exact" */
        allowed = beforeInit;
        break;
    case VR_F: /* continuous input */
        allowed = beforeInit | MODE_INITIALIZED;
        break;
    default:
        LOG_ERROR(inst, "fmi2SetReal: variable %s (value reference %u) cannot be set.",
                  VARIABLE_NAMES[vr], vr);
        return 0;
    }
    if (!(inst->mode & allowed)) {
        LOG_ERROR(inst, "fmi2SetReal: variable %s (value reference %u) cannot be set in %s.",
                  VARIABLE_NAMES[vr], vr, modeName(inst->mode));
        return 0;
    }
    if (!isfinite(value)) {
        LOG_ERROR(inst, "fmi2SetReal: variable %s: value %g is not finite.", VARIABLE_NAMES[vr], value);
        return 0;
    }
    if ((vr == VR_E && (value < 0.0 || value > 1.0)) || (vr == VR_H0 && value < 0.0)) {
        LOG_ERROR(inst, "fmi2SetReal: variable %s: value %g is out of range (%s).", VARIABLE_NAMES[vr],
                  value, vr == VR_E ? "0 <= e <= 1" : "h0 >= 0");
        return 0;
    }
    return 1;
}

static void setValue(Instance *inst, fmi2ValueReference vr, fmi2Real value)
{
    switch (vr) {
    case VR_G: inst->g = value; break;
    case VR_E: inst->e = value; break;
    case VR_H0:
        inst->h0 = value;
        inst->h = value; /* still before/in initialization: h is calculated from h0 */
        break;
    case VR_T_KICK: inst->t_kick = value; break;
    case VR_V: inst->v = value; break;
    case VR_F: inst->f = value; break;
    default: break;
    }
}

/* the discrete part of the model, evaluated in Event Mode */
static fmi2Status updateDiscreteStates(Instance *inst, fmi2EventInfo *eventInfo)
{
    fmi2Boolean changed = fmi2False;
    fmi2Status status = fmi2OK;

    /* state event: the ball reached the floor moving down (or lies on it without speed) */
    if (!inst->resting && inst->h <= 0.0 && inst->v <= 0.0) {
        const fmi2Real v_impact = inst->v;
        if (v_impact < 0.0) {
            inst->bounce_count += 1.0;
        }
        inst->h = 0.0;
        inst->v = -inst->e * v_impact;
        if (inst->v < V_MIN) {
            inst->v = 0.0;
            inst->resting = fmi2True;
        }
        changed = fmi2True;
        logMessage(inst, fmi2OK, LOG_EVENTS,
                   "t = %.17g: state event, impact at v = %.17g, rebound v = %.17g, bounce_count = %g%s",
                   inst->time, v_impact, inst->v, inst->bounce_count,
                   inst->resting ? " (the ball now lies still)" : "");
    }

    /* time event: the kick */
    if (!inst->kicked && timeReached(inst->time, inst->t_kick)) {
        if (timeMissed(inst->time, inst->t_kick)) {
            status = fmi2Warning;
            LOG_WARNING(inst, "fmi2NewDiscreteStates: the time event at t_kick = %.17g was missed; "
                        "the kick is applied late, at t = %.17g.", inst->t_kick, inst->time);
        }
        inst->v += KICK_DV;
        inst->resting = fmi2False;
        inst->kicked = fmi2True;
        changed = fmi2True;
        logMessage(inst, fmi2OK, LOG_EVENTS, "t = %.17g: time event, kick to v = %.17g", inst->time,
                   inst->v);
    }

    eventInfo->newDiscreteStatesNeeded = fmi2False;
    eventInfo->terminateSimulation = fmi2False;
    eventInfo->nominalsOfContinuousStatesChanged = fmi2False;
    eventInfo->valuesOfContinuousStatesChanged = changed;
    eventInfo->nextEventTimeDefined = inst->kicked ? fmi2False : fmi2True;
    eventInfo->nextEventTime = inst->kicked ? 0.0 : inst->t_kick;
    return status;
}

/* ------------------------------------------------------------------ common functions */

const char *fmi2GetTypesPlatform(void)
{
    return fmi2TypesPlatform;
}

const char *fmi2GetVersion(void)
{
    return fmi2Version;
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    Instance *inst = (Instance *)c;
    size_t i;
    int k;
    fmi2Boolean selected[N_CATEGORIES];

    if (invalidMode(inst, "fmi2SetDebugLogging", MODE_ANY)) {
        return fmi2Error;
    }
    if (nCategories > 0 && nullPointer(inst, "fmi2SetDebugLogging", "categories[]", categories)) {
        return fmi2Error;
    }
    for (k = 0; k < N_CATEGORIES; k++) {
        selected[k] = nCategories == 0;
    }
    for (i = 0; i < nCategories; i++) {
        int found = 0;
        for (k = 0; k < N_CATEGORIES && categories[i] != NULL; k++) {
            if (strcmp(categories[i], CATEGORY_NAMES[k]) == 0) {
                selected[k] = fmi2True;
                found = 1;
            }
        }
        if (!found) {
            LOG_ERROR(inst, "fmi2SetDebugLogging: unknown log category \"%s\".",
                      categories[i] ? categories[i] : "(null)");
            return fmi2Error;
        }
    }
    inst->loggingOn = loggingOn ? fmi2True : fmi2False;
    for (k = 0; k < N_CATEGORIES; k++) {
        if (selected[k]) {
            inst->categories[k] = inst->loggingOn;
        }
    }
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    Instance probe; /* for logging before the instance exists */
    Instance *inst;
    size_t length;
    int k;

    (void)fmuResourceLocation; /* no resources */
    (void)visible;

    if (functions == NULL || functions->logger == NULL) {
        return NULL; /* nobody to tell */
    }
    memset(&probe, 0, sizeof probe);
    probe.logger = functions->logger;
    probe.componentEnvironment = functions->componentEnvironment;
    probe.instanceName = (char *)(instanceName ? instanceName : "?");

    if (instanceName == NULL || instanceName[0] == '\0') {
        LOG_ERROR(&probe, "fmi2Instantiate: missing instance name.");
        return NULL;
    }
    if (functions->allocateMemory == NULL || functions->freeMemory == NULL) {
        LOG_ERROR(&probe, "fmi2Instantiate: the callbacks allocateMemory and freeMemory are required.");
        return NULL;
    }
    if (fmuType != fmi2ModelExchange) {
        LOG_ERROR(&probe, "fmi2Instantiate: %s supports Model Exchange only (fmuType = %d).",
                  MODEL_IDENTIFIER, (int)fmuType);
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, MODEL_GUID) != 0) {
        LOG_ERROR(&probe, "fmi2Instantiate: wrong GUID %s (expected %s).", fmuGUID ? fmuGUID : "(null)",
                  MODEL_GUID);
        return NULL;
    }

    inst = (Instance *)functions->allocateMemory(1, sizeof(Instance));
    if (inst == NULL) {
        LOG_ERROR(&probe, "fmi2Instantiate: out of memory.");
        return NULL;
    }
    memset(inst, 0, sizeof *inst);
    length = strlen(instanceName);
    inst->instanceName = (char *)functions->allocateMemory(length + 1, sizeof(char));
    if (inst->instanceName == NULL) {
        functions->freeMemory(inst);
        LOG_ERROR(&probe, "fmi2Instantiate: out of memory.");
        return NULL;
    }
    memcpy(inst->instanceName, instanceName, length + 1);
    inst->logger = functions->logger;
    inst->allocateMemory = functions->allocateMemory;
    inst->freeMemory = functions->freeMemory;
    inst->componentEnvironment = functions->componentEnvironment;
    inst->loggingOn = loggingOn ? fmi2True : fmi2False;
    for (k = 0; k < N_CATEGORIES; k++) {
        inst->categories[k] = inst->loggingOn;
    }
    inst->mode = MODE_INSTANTIATED;
    setStartValues(inst);
    logMessage(inst, fmi2OK, LOG_CALLS, "fmi2Instantiate: %s (GUID %s)", MODEL_IDENTIFIER, MODEL_GUID);
    return inst;
}

void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = (Instance *)c;
    fmi2CallbackFreeMemory freeMemory;

    if (inst == NULL) {
        return;
    }
    logMessage(inst, fmi2OK, LOG_CALLS, "fmi2FreeInstance");
    freeMemory = inst->freeMemory;
    freeMemory(inst->instanceName);
    freeMemory(inst);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    Instance *inst = (Instance *)c;

    (void)toleranceDefined; /* the model has no internal solver */
    (void)tolerance;
    if (invalidMode(inst, "fmi2SetupExperiment", MODE_INSTANTIATED)) {
        return fmi2Error;
    }
    if (!isfinite(startTime)) {
        LOG_ERROR(inst, "fmi2SetupExperiment: startTime = %g is not finite.", startTime);
        return fmi2Error;
    }
    if (stopTimeDefined && !(stopTime >= startTime)) {
        LOG_ERROR(inst, "fmi2SetupExperiment: stopTime = %g is before startTime = %g.", stopTime, startTime);
        return fmi2Error;
    }
    inst->time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    Instance *inst = (Instance *)c;

    if (invalidMode(inst, "fmi2EnterInitializationMode", MODE_INSTANTIATED)) {
        return fmi2Error;
    }
    inst->h = inst->h0;
    inst->mode = MODE_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    Instance *inst = (Instance *)c;

    if (invalidMode(inst, "fmi2ExitInitializationMode", MODE_INITIALIZATION)) {
        return fmi2Error;
    }
    inst->h = inst->h0;
    inst->bounce_count = 0.0;
    inst->resting = fmi2False;
    /* a kick scheduled before the start time never happens */
    inst->kicked = timeMissed(inst->time, inst->t_kick);
    inst->mode = MODE_EVENT;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    Instance *inst = (Instance *)c;

    if (invalidMode(inst, "fmi2Terminate", MODE_INITIALIZED)) {
        return fmi2Error;
    }
    inst->mode = MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    Instance *inst = (Instance *)c;

    if (invalidMode(inst, "fmi2Reset", MODE_ANY)) {
        return fmi2Error;
    }
    setStartValues(inst);
    inst->mode = MODE_INSTANTIATED;
    return fmi2OK;
}

/* ------------------------------------------------------------------ getters and setters */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    Instance *inst = (Instance *)c;
    size_t i;

    if (invalidMode(inst, "fmi2GetReal", MODE_READABLE)) {
        return fmi2Error;
    }
    if (nvr == 0) {
        return fmi2OK;
    }
    if (nullPointer(inst, "fmi2GetReal", "vr[]", vr) || nullPointer(inst, "fmi2GetReal", "value[]", value)) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (vr[i] >= N_REALS) {
            LOG_ERROR(inst, "fmi2GetReal: invalid value reference %u.", vr[i]);
            return fmi2Error;
        }
    }
    for (i = 0; i < nvr; i++) {
        value[i] = getValue(inst, vr[i]);
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    Instance *inst = (Instance *)c;
    size_t i;

    if (invalidMode(inst, "fmi2SetReal", MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_INITIALIZED)) {
        return fmi2Error;
    }
    if (nvr == 0) {
        return fmi2OK;
    }
    if (nullPointer(inst, "fmi2SetReal", "vr[]", vr) || nullPointer(inst, "fmi2SetReal", "value[]", value)) {
        return fmi2Error;
    }
    /* all or nothing: check every element before changing anything */
    for (i = 0; i < nvr; i++) {
        if (!checkSet(inst, vr[i], value[i])) {
            return fmi2Error;
        }
    }
    for (i = 0; i < nvr; i++) {
        setValue(inst, vr[i], value[i]);
    }
    return fmi2OK;
}

/* the model has no Integer, Boolean or String variables: only empty requests are valid */
static fmi2Status noVariables(Instance *inst, const char *function, const char *type, int allowed,
                              const fmi2ValueReference vr[], size_t nvr)
{
    if (invalidMode(inst, function, allowed)) {
        return fmi2Error;
    }
    if (nvr == 0) {
        return fmi2OK;
    }
    if (nullPointer(inst, function, "vr[]", vr)) {
        return fmi2Error;
    }
    LOG_ERROR(inst, "%s: invalid value reference %u (the model has no %s variables).", function, vr[0], type);
    return fmi2Error;
}

#define MODE_SETTABLE_DISCRETE (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_EVENT)

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[])
{
    (void)value;
    return noVariables((Instance *)c, "fmi2GetInteger", "Integer", MODE_READABLE, vr, nvr);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[])
{
    (void)value;
    return noVariables((Instance *)c, "fmi2GetBoolean", "Boolean", MODE_READABLE, vr, nvr);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[])
{
    (void)value;
    return noVariables((Instance *)c, "fmi2GetString", "String", MODE_READABLE, vr, nvr);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[])
{
    (void)value;
    return noVariables((Instance *)c, "fmi2SetInteger", "Integer", MODE_SETTABLE_DISCRETE, vr, nvr);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[])
{
    (void)value;
    return noVariables((Instance *)c, "fmi2SetBoolean", "Boolean", MODE_SETTABLE_DISCRETE, vr, nvr);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[])
{
    (void)value;
    return noVariables((Instance *)c, "fmi2SetString", "String", MODE_SETTABLE_DISCRETE, vr, nvr);
}

/* ------------------------------------------------------------------ unsupported optional features */

static fmi2Status notSupported(Instance *inst, const char *function, const char *capability)
{
    if (invalidMode(inst, function, MODE_ANY)) {
        return fmi2Error;
    }
    LOG_ERROR(inst, "%s: not supported by %s (%s=\"false\").", function, MODEL_IDENTIFIER, capability);
    return fmi2Error;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    (void)FMUstate;
    return notSupported((Instance *)c, "fmi2GetFMUstate", "canGetAndSetFMUstate");
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    (void)FMUstate;
    return notSupported((Instance *)c, "fmi2SetFMUstate", "canGetAndSetFMUstate");
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    (void)FMUstate;
    return notSupported((Instance *)c, "fmi2FreeFMUstate", "canGetAndSetFMUstate");
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    (void)FMUstate;
    (void)size;
    return notSupported((Instance *)c, "fmi2SerializedFMUstateSize", "canSerializeFMUstate");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size)
{
    (void)FMUstate;
    (void)serializedState;
    (void)size;
    return notSupported((Instance *)c, "fmi2SerializeFMUstate", "canSerializeFMUstate");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    (void)serializedState;
    (void)size;
    (void)FMUstate;
    return notSupported((Instance *)c, "fmi2DeSerializeFMUstate", "canSerializeFMUstate");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    return notSupported((Instance *)c, "fmi2GetDirectionalDerivative", "providesDirectionalDerivative");
}

/* ------------------------------------------------------------------ Model Exchange */

fmi2Status fmi2EnterEventMode(fmi2Component c)
{
    Instance *inst = (Instance *)c;

    if (invalidMode(inst, "fmi2EnterEventMode", MODE_INITIALIZED)) {
        return fmi2Error;
    }
    inst->mode = MODE_EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *eventInfo)
{
    Instance *inst = (Instance *)c;

    if (invalidMode(inst, "fmi2NewDiscreteStates", MODE_EVENT)) {
        return fmi2Error;
    }
    if (nullPointer(inst, "fmi2NewDiscreteStates", "eventInfo", eventInfo)) {
        return fmi2Error;
    }
    return updateDiscreteStates(inst, eventInfo);
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c)
{
    Instance *inst = (Instance *)c;

    if (invalidMode(inst, "fmi2EnterContinuousTimeMode", MODE_EVENT)) {
        return fmi2Error;
    }
    inst->mode = MODE_CONTINUOUS_TIME;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation)
{
    Instance *inst = (Instance *)c;

    (void)noSetFMUStatePriorToCurrentPoint;
    if (invalidMode(inst, "fmi2CompletedIntegratorStep", MODE_CONTINUOUS_TIME)) {
        return fmi2Error;
    }
    if (nullPointer(inst, "fmi2CompletedIntegratorStep", "enterEventMode", enterEventMode)
        || nullPointer(inst, "fmi2CompletedIntegratorStep", "terminateSimulation", terminateSimulation)) {
        return fmi2Error;
    }
    *enterEventMode = fmi2False; /* no step events */
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time)
{
    Instance *inst = (Instance *)c;

    if (invalidMode(inst, "fmi2SetTime", MODE_INITIALIZED)) {
        return fmi2Error;
    }
    if (!isfinite(time)) {
        LOG_ERROR(inst, "fmi2SetTime: time = %g is not finite.", time);
        return fmi2Error;
    }
    inst->time = time;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx)
{
    Instance *inst = (Instance *)c;

    if (invalidMode(inst, "fmi2SetContinuousStates", MODE_CONTINUOUS_TIME)) {
        return fmi2Error;
    }
    if (invalidNumber(inst, "fmi2SetContinuousStates", "nx", nx, N_STATES)
        || nullPointer(inst, "fmi2SetContinuousStates", "x[]", x)) {
        return fmi2Error;
    }
    if (!isfinite(x[0]) || !isfinite(x[1])) {
        LOG_ERROR(inst, "fmi2SetContinuousStates: states (h, v) = (%g, %g) are not finite.", x[0], x[1]);
        return fmi2Error;
    }
    inst->h = x[0];
    inst->v = x[1];
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real der_x[], size_t nx)
{
    Instance *inst = (Instance *)c;

    if (invalidMode(inst, "fmi2GetDerivatives", MODE_READABLE)) {
        return fmi2Error;
    }
    if (invalidNumber(inst, "fmi2GetDerivatives", "nx", nx, N_STATES)
        || nullPointer(inst, "fmi2GetDerivatives", "derivatives[]", der_x)) {
        return fmi2Error;
    }
    derivatives(inst, &der_x[0], &der_x[1]);
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni)
{
    Instance *inst = (Instance *)c;

    if (invalidMode(inst, "fmi2GetEventIndicators", MODE_READABLE)) {
        return fmi2Error;
    }
    if (invalidNumber(inst, "fmi2GetEventIndicators", "ni", ni, N_EVENT_INDICATORS)
        || nullPointer(inst, "fmi2GetEventIndicators", "eventIndicators[]", eventIndicators)) {
        return fmi2Error;
    }
    eventIndicators[0] = eventIndicator(inst);
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx)
{
    Instance *inst = (Instance *)c;

    if (invalidMode(inst, "fmi2GetContinuousStates", MODE_READABLE)) {
        return fmi2Error;
    }
    if (invalidNumber(inst, "fmi2GetContinuousStates", "nx", nx, N_STATES)
        || nullPointer(inst, "fmi2GetContinuousStates", "x[]", x)) {
        return fmi2Error;
    }
    x[0] = inst->h;
    x[1] = inst->v;
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx)
{
    Instance *inst = (Instance *)c;

    if (invalidMode(inst, "fmi2GetNominalsOfContinuousStates", MODE_ANY)) {
        return fmi2Error;
    }
    if (invalidNumber(inst, "fmi2GetNominalsOfContinuousStates", "nx", nx, N_STATES)
        || nullPointer(inst, "fmi2GetNominalsOfContinuousStates", "x_nominal[]", x_nominal)) {
        return fmi2Error;
    }
    x_nominal[0] = 1.0;
    x_nominal[1] = 1.0;
    return fmi2OK;
}
