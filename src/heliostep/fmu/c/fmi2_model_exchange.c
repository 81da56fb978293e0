/*
 * heliostep's FMI 2.0 Model Exchange layer, written once for every model.
 *
 * A model contributes only two generated files: "model.h" (sizes, start values, names and
 * the layout of the value references) and the CasADi-generated equations ("equations.h"),
 * which provide
 *   model_eval(t, x, u, p, guess)  -> (computed, residual)   explicit, or two Newton steps from guess
 *   model_solve(t, x, u, p, guess) -> (computed, residual)   converge, then two Newton steps
 *   model_scale(t, x, u, p)        -> scale                  the size of each equation's terms
 *   model_state_part(t, x, u, p)   -> the computed variables that depend on no input (explicit
 *                                     models with such variables only: N_STATE_PART > 0)
 *   model_start(p)                 -> x0
 * where "computed" holds the state derivatives, the algebraic variables and the calculated
 * parameters, solved from the model's implicit residual (in straight-line code where the
 * equations sort one unknown at a time, else by a Newton iteration inside the generated code),
 * and "residual" is the residual at that solution (checked here, against the scale). The
 * previous solution is the guess; model_solve is the fallback when model_eval's residual
 * is not small (first call, large jumps), from the previous solution and then from zero.
 *
 * Every real variable lives in one array r[], indexed by its value reference:
 *   [0, OFF_X)        parameters (settable, tunable)
 *   [OFF_X, OFF_U)    continuous states
 *   [OFF_U, OFF_C)    inputs
 *   [OFF_C, N_REALS)  computed: derivatives, algebraic variables, calculated parameters
 * The instance, these checks and the evaluation are in "model_exchange_core.h", shared with
 * the FMI 3.0 layer (fmi3_model_exchange.c); this file holds the FMI 2.0 API.
 *
 * Every function checks the instance state against the FMI 2.0 state machine, every value
 * reference against the layout, and reports problems through the logger with fmi2Error:
 * a bad call never crashes the host.
 */

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "equations.h"
#include "model.h"

typedef fmi2Status Status;
typedef fmi2ValueReference ValueReference;
#define STATUS_OK fmi2OK
#define STATUS_ERROR fmi2Error
#define INSTANCE_LOGGER fmi2CallbackFunctions functions;

#include "model_exchange_core.h"

static void deliver_message(Instance *inst, Status status, const char *category, const char *message) {
    if (inst->functions.logger)
        inst->functions.logger(inst->functions.componentEnvironment, inst->instance_name, status, category, message);
}

/* ---------------------------------------------------------------- life cycle */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

static void *allocate(const fmi2CallbackFunctions *functions, size_t count, size_t size) {
    if (functions->allocateMemory) return functions->allocateMemory(count, size);
    return calloc(count, size);
}

static void release(const fmi2CallbackFunctions *functions, void *pointer) {
    if (!pointer) return;
    if (functions->freeMemory) functions->freeMemory(pointer);
    else free(pointer);
}

static void reset_values(Instance *inst) {
    memcpy(inst->r, START_VALUES, sizeof(double) * N_REALS);
    inst->time = 0;
    inst->computed_valid = inst->state_part_valid = 0;
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories, const fmi2String categories[]) {
    Instance *inst = (Instance *)c;
    (void)categories;
    (void)nCategories;
    if (invalid_state(inst, "fmi2SetDebugLogging", ANY_STATE)) return fmi2Error;
    inst->logging_on = loggingOn;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    casadi_int sz_arg, sz_res, sz_iw, sz_w;
    Instance *inst;
    (void)fmuResourceLocation;
    (void)visible;
    if (!functions || !functions->logger) return NULL;
    if (!instanceName || !instanceName[0]) {
        functions->logger(functions->componentEnvironment, "?", fmi2Error, "logStatusError",
                          "fmi2Instantiate: missing instance name");
        return NULL;
    }
    if (fmuType != fmi2ModelExchange) {
        functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                          "fmi2Instantiate: " MODEL_IDENTIFIER_STRING " supports Model Exchange only");
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, MODEL_GUID) != 0) {
        functions->logger(functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
                          "fmi2Instantiate: GUID does not match " MODEL_GUID);
        return NULL;
    }
    inst = (Instance *)allocate(functions, 1, sizeof(Instance));
    if (!inst) return NULL;
    inst->functions = *functions;
    inst->logging_on = loggingOn;
    inst->state = Instantiated;
    inst->instance_name = (char *)allocate(functions, strlen(instanceName) + 1, 1);
    work_sizes(&sz_arg, &sz_res, &sz_iw, &sz_w);
    inst->arg = (const casadi_real **)allocate(functions, (size_t)sz_arg + 1, sizeof(casadi_real *));
    inst->res = (casadi_real **)allocate(functions, (size_t)sz_res + 1, sizeof(casadi_real *));
    inst->iw = (casadi_int *)allocate(functions, (size_t)sz_iw + 1, sizeof(casadi_int));
    inst->w = (casadi_real *)allocate(functions, (size_t)sz_w + 1, sizeof(casadi_real));
    if (!inst->instance_name || !inst->arg || !inst->res || !inst->iw || !inst->w) {
        functions->logger(functions->componentEnvironment, instanceName, fmi2Fatal, "logStatusFatal",
                          "fmi2Instantiate: out of memory");
        release(functions, inst->instance_name);
        release(functions, (void *)inst->arg);
        release(functions, inst->res);
        release(functions, inst->iw);
        release(functions, inst->w);
        release(functions, inst);
        return NULL;
    }
    strcpy(inst->instance_name, instanceName);
    reset_values(inst);
    return inst;
}

void fmi2FreeInstance(fmi2Component c) {
    Instance *inst = (Instance *)c;
    fmi2CallbackFunctions functions;
    if (!inst) return;
    functions = inst->functions;
    release(&functions, inst->instance_name);
    release(&functions, (void *)inst->arg);
    release(&functions, inst->res);
    release(&functions, inst->iw);
    release(&functions, inst->w);
    release(&functions, inst);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    Instance *inst = (Instance *)c;
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (invalid_state(inst, "fmi2SetupExperiment", Instantiated)) return fmi2Error;
    inst->time = startTime;
    inst->computed_valid = inst->state_part_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (invalid_state(inst, "fmi2EnterInitializationMode", Instantiated)) return fmi2Error;
    inst->state = InitializationMode;
    inst->computed_valid = inst->state_part_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    fmi2Status status;
    if (invalid_state(inst, "fmi2ExitInitializationMode", InitializationMode)) return fmi2Error;
    inst->computed_valid = inst->state_part_valid = 0;
    status = update(inst, "fmi2ExitInitializationMode");
    if (status != fmi2OK) return status;
    inst->state = EventMode;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (invalid_state(inst, "fmi2Terminate", EventMode | ContinuousTimeMode | ErrorState)) return fmi2Error;
    inst->state = Terminated;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (invalid_state(inst, "fmi2Reset", ANY_STATE)) return fmi2Error;
    inst->state = Instantiated;
    reset_values(inst);
    return fmi2OK;
}

/* ---------------------------------------------------------------- get and set */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    if (invalid_state(inst, "fmi2GetReal", READABLE)) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    if (null_argument(inst, "fmi2GetReal", "vr", vr) || null_argument(inst, "fmi2GetReal", "value", value)) return fmi2Error;
    if (inst->state & InitializationMode) compute_state_starts(inst);
    for (size_t i = 0; i < nvr; i++) {  /* every reference is checked before anything is read */
        if (invalid_vr(inst, "fmi2GetReal", vr[i])) return enter_error_state(inst);
    }
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] >= OFF_C && (IN_STATE_PART[vr[i] - OFF_C] ? update_state_part(inst, "fmi2GetReal")
                                                           : update(inst, "fmi2GetReal")) != fmi2OK)
            return fmi2Error;
        value[i] = inst->r[vr[i]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Instance *inst = (Instance *)c;
    if (invalid_state(inst, "fmi2SetReal", Instantiated | InitializationMode | EventMode | ContinuousTimeMode)) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    if (null_argument(inst, "fmi2SetReal", "vr", vr) || null_argument(inst, "fmi2SetReal", "value", value)) return fmi2Error;
    /* validate every reference and value first: a rejected call writes nothing */
    for (size_t i = 0; i < nvr; i++) {
        fmi2ValueReference ref = vr[i];
        if (invalid_vr(inst, "fmi2SetReal", ref)) return enter_error_state(inst);
        if (ref >= OFF_C) {
            LOG_ERROR(inst, "fmi2SetReal: %s is computed by the model and cannot be set", VARIABLE_NAMES[ref]);
            return enter_error_state(inst);
        }
        if (ref < OFF_X && !(inst->state & (Instantiated | InitializationMode | EventMode))) {
            LOG_ERROR(inst, "fmi2SetReal: parameter %s can only be set before initialization or in event mode", VARIABLE_NAMES[ref]);
            return enter_error_state(inst);
        }
        if (ref >= OFF_X && ref < OFF_U &&
            (STATE_START_CALCULATED[ref - OFF_X] || !(inst->state & (Instantiated | InitializationMode)))) {
            LOG_ERROR(inst, "fmi2SetReal: state %s can only be set through fmi2SetContinuousStates", VARIABLE_NAMES[ref]);
            return enter_error_state(inst);
        }
        if (!isfinite(value[i])) {
            LOG_ERROR(inst, "fmi2SetReal: value of %s is not finite", VARIABLE_NAMES[ref]);
            return enter_error_state(inst);
        }
    }
    int inputs_only = 1;
    for (size_t i = 0; i < nvr; i++) {
        inst->r[vr[i]] = value[i];
        inputs_only &= vr[i] >= OFF_U;
    }
    inst->computed_valid = 0;
    if (!inputs_only) inst->state_part_valid = 0; /* a new input leaves the state part as it is */
    return fmi2OK;
}

/* The model has no Integer, Boolean or String variables: any value reference is invalid. */
static fmi2Status no_such_variables(fmi2Component c, const char *function, size_t nvr) {
    Instance *inst = (Instance *)c;
    if (invalid_state(inst, function, ANY_STATE)) return fmi2Error;
    if (nvr == 0) return fmi2OK;
    LOG_ERROR(inst, "%s: invalid value reference (the model has no variables of this type)", function);
    return fmi2Error;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    (void)vr; (void)value;
    return no_such_variables(c, "fmi2GetInteger", nvr);
}
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    (void)vr; (void)value;
    return no_such_variables(c, "fmi2GetBoolean", nvr);
}
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    (void)vr; (void)value;
    return no_such_variables(c, "fmi2GetString", nvr);
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    (void)vr; (void)value;
    return no_such_variables(c, "fmi2SetInteger", nvr);
}
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    (void)vr; (void)value;
    return no_such_variables(c, "fmi2SetBoolean", nvr);
}
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    (void)vr; (void)value;
    return no_such_variables(c, "fmi2SetString", nvr);
}

/* ---------------------------------------------------------------- unsupported optional features */

static fmi2Status unsupported(fmi2Component c, const char *function) {
    Instance *inst = (Instance *)c;
    if (inst) LOG_ERROR(inst, "%s: not supported by this FMU", function);
    return fmi2Error;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    (void)FMUstate;
    return unsupported(c, "fmi2GetFMUstate");
}
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    (void)FMUstate;
    return unsupported(c, "fmi2SetFMUstate");
}
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    (void)FMUstate;
    return unsupported(c, "fmi2FreeFMUstate");
}
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    (void)FMUstate; (void)size;
    return unsupported(c, "fmi2SerializedFMUstateSize");
}
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size) {
    (void)FMUstate; (void)serializedState; (void)size;
    return unsupported(c, "fmi2SerializeFMUstate");
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size, fmi2FMUstate *FMUstate) {
    (void)serializedState; (void)size; (void)FMUstate;
    return unsupported(c, "fmi2DeSerializeFMUstate");
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}

/* ---------------------------------------------------------------- model exchange */

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (invalid_state(inst, "fmi2EnterEventMode", EventMode | ContinuousTimeMode)) return fmi2Error;
    inst->state = EventMode;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *eventInfo) {
    Instance *inst = (Instance *)c;
    if (invalid_state(inst, "fmi2NewDiscreteStates", EventMode)) return fmi2Error;
    if (null_argument(inst, "fmi2NewDiscreteStates", "eventInfo", eventInfo)) return fmi2Error;
    eventInfo->newDiscreteStatesNeeded = fmi2False;
    eventInfo->terminateSimulation = fmi2False;
    eventInfo->nominalsOfContinuousStatesChanged = fmi2False;
    eventInfo->valuesOfContinuousStatesChanged = fmi2False;
    eventInfo->nextEventTimeDefined = fmi2False;
    eventInfo->nextEventTime = 0;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    Instance *inst = (Instance *)c;
    if (invalid_state(inst, "fmi2EnterContinuousTimeMode", EventMode)) return fmi2Error;
    inst->state = ContinuousTimeMode;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    Instance *inst = (Instance *)c;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (invalid_state(inst, "fmi2CompletedIntegratorStep", ContinuousTimeMode)) return fmi2Error;
    if (null_argument(inst, "fmi2CompletedIntegratorStep", "enterEventMode", enterEventMode) ||
        null_argument(inst, "fmi2CompletedIntegratorStep", "terminateSimulation", terminateSimulation)) return fmi2Error;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    Instance *inst = (Instance *)c;
    if (invalid_state(inst, "fmi2SetTime", InitializationMode | EventMode | ContinuousTimeMode)) return fmi2Error;
    inst->time = time;
    inst->computed_valid = inst->state_part_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    Instance *inst = (Instance *)c;
    if (invalid_state(inst, "fmi2SetContinuousStates", EventMode | ContinuousTimeMode)) return fmi2Error;
    if (wrong_size(inst, "fmi2SetContinuousStates", "nx", nx, N_STATES)) return fmi2Error;
    if (nx == 0) return fmi2OK;
    if (null_argument(inst, "fmi2SetContinuousStates", "x", x)) return enter_error_state(inst);
    for (size_t i = 0; i < nx; i++) {
        if (!isfinite(x[i])) {
            LOG_ERROR(inst, "fmi2SetContinuousStates: %s = %g is not finite", VARIABLE_NAMES[OFF_X + i], x[i]);
            return enter_error_state(inst);
        }
    }
    memcpy(inst->r + OFF_X, x, sizeof(double) * nx);
    inst->computed_valid = inst->state_part_valid = 0;
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx) {
    Instance *inst = (Instance *)c;
    if (invalid_state(inst, "fmi2GetDerivatives", READABLE)) return fmi2Error;
    if (wrong_size(inst, "fmi2GetDerivatives", "nx", nx, N_STATES)) return fmi2Error;
    if (nx == 0) return fmi2OK;
    if (null_argument(inst, "fmi2GetDerivatives", "derivatives", derivatives)) return enter_error_state(inst);
    if (update(inst, "fmi2GetDerivatives") != fmi2OK) return fmi2Error;
    memcpy(derivatives, inst->r + OFF_C, sizeof(double) * nx);
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
    Instance *inst = (Instance *)c;
    (void)eventIndicators;
    if (invalid_state(inst, "fmi2GetEventIndicators", READABLE)) return fmi2Error;
    if (wrong_size(inst, "fmi2GetEventIndicators", "ni", ni, 0)) return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    Instance *inst = (Instance *)c;
    if (invalid_state(inst, "fmi2GetContinuousStates", READABLE)) return fmi2Error;
    if (wrong_size(inst, "fmi2GetContinuousStates", "nx", nx, N_STATES)) return fmi2Error;
    if (nx == 0) return fmi2OK;
    if (null_argument(inst, "fmi2GetContinuousStates", "x", x)) return fmi2Error;
    if (inst->state & InitializationMode) compute_state_starts(inst);
    memcpy(x, inst->r + OFF_X, sizeof(double) * nx);
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    Instance *inst = (Instance *)c;
    if (invalid_state(inst, "fmi2GetNominalsOfContinuousStates", ANY_STATE)) return fmi2Error;
    if (wrong_size(inst, "fmi2GetNominalsOfContinuousStates", "nx", nx, N_STATES)) return fmi2Error;
    if (nx == 0) return fmi2OK;
    if (null_argument(inst, "fmi2GetNominalsOfContinuousStates", "x_nominal", x_nominal)) return fmi2Error;
    memcpy(x_nominal, STATE_NOMINALS, sizeof(double) * nx);
    return fmi2OK;
}
