/*
 * heliostep's FMI 2.0 Model Exchange layer, compiled with every model's generated "model.h" and
 * "equations.h": the FMI 2.0 signatures around the bodies in "model_exchange_core.h", which the
 * FMI 3.0 layer (fmi3_model_exchange.c) shares.
 */

#include "fmi2Functions.h"

typedef fmi2Status Status;
typedef fmi2ValueReference ValueReference;
#define STATUS_OK fmi2OK
#define STATUS_ERROR fmi2Error
#define FMI_PREFIX "fmi2"
#define INSTANCE_LOGGER fmi2CallbackFunctions functions;
#define TIME_VARIABLE 0
#define PARAMETER_NOT_SETTABLE "parameter %s can only be set before initialization or in event mode"
#define STATE_NOT_SETTABLE "state %s can only be set through fmi2SetContinuousStates"

#include "model_exchange_core.h"

static void deliver_message(Instance *inst, Status status, const char *category, const char *message) {
    if (inst->functions.logger)
        inst->functions.logger(inst->functions.componentEnvironment, inst->instance_name, status, category, message);
}

/* ---------------------------------------------------------------- life cycle */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component instance, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    BEGIN_FUNCTION(SetDebugLogging, ANY_STATE)
    (void)nCategories;
    (void)categories;
    inst->logging_on = loggingOn;
    END_FUNCTION()
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
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
    inst = new_instance(instanceName, loggingOn, functions->allocateMemory ? functions->allocateMemory : calloc,
                        functions->freeMemory ? functions->freeMemory : free);
    if (!inst) {
        functions->logger(functions->componentEnvironment, instanceName, fmi2Fatal, "logStatusFatal",
                          "fmi2Instantiate: out of memory");
        return NULL;
    }
    inst->functions = *functions;
    return inst;
}

void fmi2FreeInstance(fmi2Component instance) { free_instance((Instance *)instance); }

fmi2Status fmi2SetupExperiment(fmi2Component instance, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    BEGIN_FUNCTION(SetupExperiment, Instantiated)
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    set_time(inst, startTime);
    END_FUNCTION()
}

fmi2Status fmi2EnterInitializationMode(fmi2Component instance) {
    BEGIN_FUNCTION(EnterInitializationMode, Instantiated)
    enter_initialization_mode(inst);
    END_FUNCTION()
}

fmi2Status fmi2ExitInitializationMode(fmi2Component instance) {
    BEGIN_FUNCTION(ExitInitializationMode, InitializationMode)
    CALL(exit_initialization_mode(inst, function));
    END_FUNCTION()
}

fmi2Status fmi2Terminate(fmi2Component instance) {
    BEGIN_FUNCTION(Terminate, EventMode | ContinuousTimeMode | ErrorState)
    inst->state = Terminated;
    END_FUNCTION()
}

fmi2Status fmi2Reset(fmi2Component instance) {
    BEGIN_FUNCTION(Reset, ANY_STATE)
    reset(inst);
    END_FUNCTION()
}

/* ---------------------------------------------------------------- get and set */

fmi2Status fmi2GetReal(fmi2Component instance, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    BEGIN_FUNCTION(GetReal, READABLE)
    CHECK_VALUES(vr, value, nvr);
    CALL(get_reals(inst, function, vr, nvr, value));
    END_FUNCTION()
}

fmi2Status fmi2SetReal(fmi2Component instance, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    BEGIN_FUNCTION(SetReal, WRITABLE)
    CHECK_VALUES(vr, value, nvr);
    CALL(set_reals(inst, function, vr, nvr, value));
    END_FUNCTION()
}

#define NO_VARIABLES(NAME, TYPE)                                                                              \
    fmi2Status fmi2##NAME(fmi2Component instance, const fmi2ValueReference vr[], size_t nvr, TYPE value[]) { \
        BEGIN_FUNCTION(NAME, ANY_STATE)                                                                       \
        (void)vr;                                                                                             \
        (void)value;                                                                                          \
        CALL(no_variables(inst, function, nvr));                                                              \
        END_FUNCTION()                                                                                        \
    }

NO_VARIABLES(GetInteger, fmi2Integer)
NO_VARIABLES(GetBoolean, fmi2Boolean)
NO_VARIABLES(GetString, fmi2String)
NO_VARIABLES(SetInteger, const fmi2Integer)
NO_VARIABLES(SetBoolean, const fmi2Boolean)
NO_VARIABLES(SetString, const fmi2String)

/* ---------------------------------------------------------------- unsupported optional features */

fmi2Status fmi2GetFMUstate(fmi2Component instance, fmi2FMUstate *FMUstate) {
    (void)FMUstate;
    UNSUPPORTED(GetFMUstate)
}
fmi2Status fmi2SetFMUstate(fmi2Component instance, fmi2FMUstate FMUstate) {
    (void)FMUstate;
    UNSUPPORTED(SetFMUstate)
}
fmi2Status fmi2FreeFMUstate(fmi2Component instance, fmi2FMUstate *FMUstate) {
    (void)FMUstate;
    UNSUPPORTED(FreeFMUstate)
}
fmi2Status fmi2SerializedFMUstateSize(fmi2Component instance, fmi2FMUstate FMUstate, size_t *size) {
    (void)FMUstate; (void)size;
    UNSUPPORTED(SerializedFMUstateSize)
}
fmi2Status fmi2SerializeFMUstate(fmi2Component instance, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size) {
    (void)FMUstate; (void)serializedState; (void)size;
    UNSUPPORTED(SerializeFMUstate)
}
fmi2Status fmi2DeSerializeFMUstate(fmi2Component instance, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    (void)serializedState; (void)size; (void)FMUstate;
    UNSUPPORTED(DeSerializeFMUstate)
}
fmi2Status fmi2GetDirectionalDerivative(fmi2Component instance, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown; (void)dvKnown; (void)dvUnknown;
    UNSUPPORTED(GetDirectionalDerivative)
}

/* ---------------------------------------------------------------- model exchange */

fmi2Status fmi2EnterEventMode(fmi2Component instance) {
    BEGIN_FUNCTION(EnterEventMode, EventMode | ContinuousTimeMode)
    inst->state = EventMode;
    END_FUNCTION()
}

fmi2Status fmi2NewDiscreteStates(fmi2Component instance, fmi2EventInfo *eventInfo) {
    BEGIN_FUNCTION(NewDiscreteStates, EventMode)
    CALL(NOT_NULL(eventInfo));
    eventInfo->newDiscreteStatesNeeded = fmi2False; /* the models have no discrete states */
    eventInfo->terminateSimulation = fmi2False;
    eventInfo->nominalsOfContinuousStatesChanged = fmi2False;
    eventInfo->valuesOfContinuousStatesChanged = fmi2False;
    eventInfo->nextEventTimeDefined = fmi2False;
    eventInfo->nextEventTime = 0;
    END_FUNCTION()
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component instance) {
    BEGIN_FUNCTION(EnterContinuousTimeMode, EventMode)
    inst->state = ContinuousTimeMode;
    END_FUNCTION()
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component instance, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    BEGIN_FUNCTION(CompletedIntegratorStep, ContinuousTimeMode)
    (void)noSetFMUStatePriorToCurrentPoint;
    CALL(NOT_NULL(enterEventMode));
    CALL(NOT_NULL(terminateSimulation));
    *enterEventMode = *terminateSimulation = fmi2False;
    END_FUNCTION()
}

fmi2Status fmi2SetTime(fmi2Component instance, fmi2Real time) {
    BEGIN_FUNCTION(SetTime, InitializationMode | EventMode | ContinuousTimeMode)
    set_time(inst, time);
    END_FUNCTION()
}

fmi2Status fmi2SetContinuousStates(fmi2Component instance, const fmi2Real x[], size_t nx) {
    BEGIN_FUNCTION(SetContinuousStates, EventMode | ContinuousTimeMode)
    CHECK_ARRAY(x, nx, N_STATES, FAILING);
    CALL(set_continuous_states(inst, function, x, nx));
    END_FUNCTION()
}

fmi2Status fmi2GetDerivatives(fmi2Component instance, fmi2Real derivatives[], size_t nx) {
    BEGIN_FUNCTION(GetDerivatives, READABLE)
    CHECK_ARRAY(derivatives, nx, N_STATES, FAILING);
    CALL(get_derivatives(inst, function, derivatives, nx));
    END_FUNCTION()
}

fmi2Status fmi2GetEventIndicators(fmi2Component instance, fmi2Real eventIndicators[], size_t ni) {
    BEGIN_FUNCTION(GetEventIndicators, READABLE)
    (void)eventIndicators;
    CALL(SIZE_IS(ni, 0));
    END_FUNCTION()
}

fmi2Status fmi2GetContinuousStates(fmi2Component instance, fmi2Real x[], size_t nx) {
    BEGIN_FUNCTION(GetContinuousStates, READABLE)
    CHECK_ARRAY(x, nx, N_STATES, REFUSING);
    get_continuous_states(inst, x, nx);
    END_FUNCTION()
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component instance, fmi2Real x_nominal[], size_t nx) {
    BEGIN_FUNCTION(GetNominalsOfContinuousStates, ANY_STATE)
    CHECK_ARRAY(x_nominal, nx, N_STATES, REFUSING);
    memcpy(x_nominal, STATE_NOMINALS, sizeof(double) * nx);
    END_FUNCTION()
}
