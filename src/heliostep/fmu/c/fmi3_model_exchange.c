/*
 * heliostep's FMI 3.0 Model Exchange layer, compiled with every model's generated "model.h" and
 * "equations.h": the FMI 3.0 signatures around the bodies in "model_exchange_core.h", which the
 * FMI 2.0 layer (fmi2_model_exchange.c) shares. What is FMI 3.0's own: the instantiation token
 * (FMI 2.0's GUID), memory from the C library (FMI 3.0 has no memory callbacks), the experiment
 * given to fmi3EnterInitializationMode, the independent variable time with a value reference
 * (N_REALS, read only), flags returned one by one, and nValues beside the value references
 * (every variable is a scalar). Other variable types, clocks, Co-Simulation and Scheduled
 * Execution are refused.
 */

#include "fmi3Functions.h"

typedef fmi3Status Status;
typedef fmi3ValueReference ValueReference;
#define STATUS_OK fmi3OK
#define STATUS_ERROR fmi3Error
#define FMI_PREFIX "fmi3"
#define INSTANCE_LOGGER                  \
    fmi3InstanceEnvironment environment; \
    fmi3LogMessageCallback log_message_callback;
#define TIME_VARIABLE 1
#define PARAMETER_NOT_SETTABLE "%s is a parameter: it can only be set before initialization or in event mode"
#define STATE_NOT_SETTABLE "%s is a state: it can only be set through fmi3SetContinuousStates"

#include "model_exchange_core.h"

static void deliver_message(Instance *inst, Status status, const char *category, const char *message) {
    if (inst->log_message_callback) inst->log_message_callback(inst->environment, status, category, message);
}

/* ---------------------------------------------------------------- life cycle */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    BEGIN_FUNCTION(SetDebugLogging, ANY_STATE)
    (void)nCategories;
    (void)categories;
    inst->logging_on = loggingOn;
    END_FUNCTION()
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    Instance *inst;
    (void)resourcePath;
    (void)visible;
    if (!logMessage) return NULL;
    if (!instanceName || !instanceName[0]) {
        logMessage(instanceEnvironment, fmi3Error, "logStatusError", "fmi3InstantiateModelExchange: missing instance name");
        return NULL;
    }
    if (!instantiationToken || strcmp(instantiationToken, MODEL_GUID) != 0) {
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateModelExchange: instantiation token does not match " MODEL_GUID);
        return NULL;
    }
    inst = new_instance(instanceName, loggingOn, calloc, free);
    if (!inst) {
        logMessage(instanceEnvironment, fmi3Fatal, "logStatusFatal", "fmi3InstantiateModelExchange: out of memory");
        return NULL;
    }
    inst->environment = instanceEnvironment;
    inst->log_message_callback = logMessage;
    return inst;
}

/* Refuses an instantiation of another interface type, by its name. */
static fmi3Instance model_exchange_only(fmi3InstanceEnvironment environment, fmi3LogMessageCallback logMessage,
                                        const char *message) {
    if (logMessage) logMessage(environment, fmi3Error, "logStatusError", message);
    return NULL;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)eventModeUsed; (void)earlyReturnAllowed; (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables; (void)intermediateUpdate;
    return model_exchange_only(instanceEnvironment, logMessage,
                               "fmi3InstantiateCoSimulation: " MODEL_IDENTIFIER_STRING " supports Model Exchange only");
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    return model_exchange_only(instanceEnvironment, logMessage,
                               "fmi3InstantiateScheduledExecution: " MODEL_IDENTIFIER_STRING
                               " supports Model Exchange only");
}

void fmi3FreeInstance(fmi3Instance instance) { free_instance((Instance *)instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    BEGIN_FUNCTION(EnterInitializationMode, Instantiated)
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    CALL(FINITE(startTime));
    set_time(inst, startTime);
    enter_initialization_mode(inst);
    END_FUNCTION()
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    BEGIN_FUNCTION(ExitInitializationMode, InitializationMode)
    CALL(exit_initialization_mode(inst, function));
    END_FUNCTION()
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    BEGIN_FUNCTION(EnterEventMode, EventMode | ContinuousTimeMode)
    inst->state = EventMode;
    END_FUNCTION()
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    BEGIN_FUNCTION(Terminate, EventMode | ContinuousTimeMode | ErrorState)
    inst->state = Terminated;
    END_FUNCTION()
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    BEGIN_FUNCTION(Reset, ANY_STATE)
    reset(inst);
    END_FUNCTION()
}

/* ---------------------------------------------------------------- get and set */

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Float64 values[], size_t nValues) {
    BEGIN_FUNCTION(GetFloat64, READABLE)
    CALL(SIZE_IS(nValues, nValueReferences));
    CHECK_VALUES(valueReferences, values, nValueReferences);
    CALL(get_reals(inst, function, valueReferences, nValueReferences, values));
    END_FUNCTION()
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Float64 values[], size_t nValues) {
    BEGIN_FUNCTION(SetFloat64, WRITABLE)
    CALL(SIZE_IS(nValues, nValueReferences));
    CHECK_VALUES(valueReferences, values, nValueReferences);
    CALL(set_reals(inst, function, valueReferences, nValueReferences, values));
    END_FUNCTION()
}

#define NO_VARIABLES(NAME, TYPE, CONST)                                                                     \
    fmi3Status fmi3##NAME(fmi3Instance instance, const fmi3ValueReference valueReferences[],               \
                          size_t nValueReferences, CONST TYPE values[], size_t nValues) {                 \
        BEGIN_FUNCTION(NAME, ANY_STATE)                                                                     \
        (void)valueReferences;                                                                              \
        (void)values;                                                                                       \
        (void)nValues;                                                                                      \
        CALL(no_variables(inst, function, nValueReferences));                                               \
        END_FUNCTION()                                                                                      \
    }
#define NO_SUCH_TYPE(NAME, TYPE) NO_VARIABLES(Get##NAME, TYPE, ) NO_VARIABLES(Set##NAME, TYPE, const)

NO_SUCH_TYPE(Float32, fmi3Float32)
NO_SUCH_TYPE(Int8, fmi3Int8)
NO_SUCH_TYPE(UInt8, fmi3UInt8)
NO_SUCH_TYPE(Int16, fmi3Int16)
NO_SUCH_TYPE(UInt16, fmi3UInt16)
NO_SUCH_TYPE(Int32, fmi3Int32)
NO_SUCH_TYPE(UInt32, fmi3UInt32)
NO_SUCH_TYPE(Int64, fmi3Int64)
NO_SUCH_TYPE(UInt64, fmi3UInt64)
NO_SUCH_TYPE(Boolean, fmi3Boolean)
NO_SUCH_TYPE(String, fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues) {
    BEGIN_FUNCTION(GetBinary, ANY_STATE)
    (void)valueReferences; (void)valueSizes; (void)values; (void)nValues;
    CALL(no_variables(inst, function, nValueReferences));
    END_FUNCTION()
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues) {
    BEGIN_FUNCTION(SetBinary, ANY_STATE)
    (void)valueReferences; (void)valueSizes; (void)values; (void)nValues;
    CALL(no_variables(inst, function, nValueReferences));
    END_FUNCTION()
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Clock values[]) {
    BEGIN_FUNCTION(GetClock, ANY_STATE)
    (void)valueReferences; (void)values;
    CALL(no_variables(inst, function, nValueReferences));
    END_FUNCTION()
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Clock values[]) {
    BEGIN_FUNCTION(SetClock, ANY_STATE)
    (void)valueReferences; (void)values;
    CALL(no_variables(inst, function, nValueReferences));
    END_FUNCTION()
}

/* ---------------------------------------------------------------- unsupported optional features */

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference; (void)nDependencies;
    UNSUPPORTED(GetNumberOfVariableDependencies)
}
fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent; (void)elementIndicesOfDependent; (void)independents; (void)elementIndicesOfIndependents;
    (void)dependencyKinds; (void)nDependencies;
    UNSUPPORTED(GetVariableDependencies)
}
fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    (void)FMUState;
    UNSUPPORTED(GetFMUState)
}
fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    (void)FMUState;
    UNSUPPORTED(SetFMUState)
}
fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    (void)FMUState;
    UNSUPPORTED(FreeFMUState)
}
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    (void)FMUState; (void)size;
    UNSUPPORTED(SerializedFMUStateSize)
}
fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size) {
    (void)FMUState; (void)serializedState; (void)size;
    UNSUPPORTED(SerializeFMUState)
}
fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) {
    (void)serializedState; (void)size; (void)FMUState;
    UNSUPPORTED(DeserializeFMUState)
}
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed; (void)sensitivity;
    (void)nSensitivity;
    UNSUPPORTED(GetDirectionalDerivative)
}
fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed; (void)sensitivity;
    (void)nSensitivity;
    UNSUPPORTED(GetAdjointDerivative)
}
fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    UNSUPPORTED(EnterConfigurationMode)
}
fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    UNSUPPORTED(ExitConfigurationMode)
}
fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    (void)vr; (void)nvr; (void)intervals; (void)qualifiers;
    UNSUPPORTED(GetIntervalDecimal)
}
fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions; (void)qualifiers;
    UNSUPPORTED(GetIntervalFraction)
}
fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               fmi3Float64 shifts[]) {
    (void)vr; (void)nvr; (void)shifts;
    UNSUPPORTED(GetShiftDecimal)
}
fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions;
    UNSUPPORTED(GetShiftFraction)
}
fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  const fmi3Float64 intervals[]) {
    (void)vr; (void)nvr; (void)intervals;
    UNSUPPORTED(SetIntervalDecimal)
}
fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions;
    UNSUPPORTED(SetIntervalFraction)
}
fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               const fmi3Float64 shifts[]) {
    (void)vr; (void)nvr; (void)shifts;
    UNSUPPORTED(SetShiftDecimal)
}
fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions;
    UNSUPPORTED(SetShiftFraction)
}
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    UNSUPPORTED(EvaluateDiscreteStates)
}
fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    UNSUPPORTED(EnterStepMode)
}
fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    (void)vr; (void)nvr; (void)orders; (void)values; (void)nValues;
    UNSUPPORTED(GetOutputDerivatives)
}
fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    (void)currentCommunicationPoint; (void)communicationStepSize; (void)noSetFMUStatePriorToCurrentPoint;
    (void)eventHandlingNeeded; (void)terminateSimulation; (void)earlyReturn; (void)lastSuccessfulTime;
    UNSUPPORTED(DoStep)
}
fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference; (void)activationTime;
    UNSUPPORTED(ActivateModelPartition)
}

/* ---------------------------------------------------------------- model exchange */

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    BEGIN_FUNCTION(UpdateDiscreteStates, EventMode)
    CALL(NOT_NULL(discreteStatesNeedUpdate));
    CALL(NOT_NULL(terminateSimulation));
    CALL(NOT_NULL(nominalsOfContinuousStatesChanged));
    CALL(NOT_NULL(valuesOfContinuousStatesChanged));
    CALL(NOT_NULL(nextEventTimeDefined));
    CALL(NOT_NULL(nextEventTime));
    *discreteStatesNeedUpdate = *terminateSimulation = fmi3False; /* the models have no discrete states */
    *nominalsOfContinuousStatesChanged = *valuesOfContinuousStatesChanged = *nextEventTimeDefined = fmi3False;
    *nextEventTime = 0;
    END_FUNCTION()
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    BEGIN_FUNCTION(EnterContinuousTimeMode, EventMode)
    inst->state = ContinuousTimeMode;
    END_FUNCTION()
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    BEGIN_FUNCTION(CompletedIntegratorStep, ContinuousTimeMode)
    (void)noSetFMUStatePriorToCurrentPoint;
    CALL(NOT_NULL(enterEventMode));
    CALL(NOT_NULL(terminateSimulation));
    *enterEventMode = *terminateSimulation = fmi3False;
    END_FUNCTION()
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    BEGIN_FUNCTION(SetTime, EventMode | ContinuousTimeMode)
    CALL(FINITE(time));
    set_time(inst, time);
    END_FUNCTION()
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    BEGIN_FUNCTION(SetContinuousStates, EventMode | ContinuousTimeMode)
    CHECK_ARRAY(continuousStates, nContinuousStates, N_STATES, FAILING);
    CALL(set_continuous_states(inst, function, continuousStates, nContinuousStates));
    END_FUNCTION()
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    BEGIN_FUNCTION(GetContinuousStateDerivatives, READABLE)
    CHECK_ARRAY(derivatives, nContinuousStates, N_STATES, FAILING);
    CALL(get_derivatives(inst, function, derivatives, nContinuousStates));
    END_FUNCTION()
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators) {
    BEGIN_FUNCTION(GetEventIndicators, READABLE)
    (void)eventIndicators;
    CALL(SIZE_IS(nEventIndicators, 0));
    END_FUNCTION()
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates) {
    BEGIN_FUNCTION(GetContinuousStates, READABLE)
    CHECK_ARRAY(continuousStates, nContinuousStates, N_STATES, REFUSING);
    get_continuous_states(inst, continuousStates, nContinuousStates);
    END_FUNCTION()
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t nContinuousStates) {
    BEGIN_FUNCTION(GetNominalsOfContinuousStates, ANY_STATE)
    CHECK_ARRAY(nominals, nContinuousStates, N_STATES, REFUSING);
    memcpy(nominals, STATE_NOMINALS, sizeof(double) * nContinuousStates);
    END_FUNCTION()
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    BEGIN_FUNCTION(GetNumberOfEventIndicators, ANY_STATE)
    CALL(NOT_NULL(nEventIndicators));
    *nEventIndicators = 0;
    END_FUNCTION()
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    BEGIN_FUNCTION(GetNumberOfContinuousStates, ANY_STATE)
    CALL(NOT_NULL(nContinuousStates));
    *nContinuousStates = N_STATES;
    END_FUNCTION()
}
