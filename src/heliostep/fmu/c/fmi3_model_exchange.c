/*
 * heliostep's FMI 3.0 Model Exchange layer, written once for every model, beside the FMI 2.0
 * layer (fmi2_model_exchange.c). Both compile the same generated "model.h" and "equations.h"
 * of a model and share its evaluation core, "model_exchange_core.h" (the layout of r[], the
 * state and argument checks, the residual check, update(), update_state_part()), written once
 * for both versions. What differs is the API, here:
 *   - fmi3InstantiateModelExchange checks the instantiation token (the FMI 2.0 GUID) and logs
 *     through fmi3LogMessageCallback; memory is the C library's (FMI 3.0 has no memory callbacks);
 *   - fmi3EnterInitializationMode takes the experiment (FMI 2.0's fmi2SetupExperiment);
 *   - fmi3UpdateDiscreteStates returns its flags one by one (no discrete states: all false);
 *   - fmi3GetFloat64/fmi3SetFloat64 take nValues (every variable is a scalar: nValues == nvr);
 *   - every other variable type, clocks, Co-Simulation and Scheduled Execution are refused.
 *
 * Every real variable lives in one array r[], indexed by its value reference:
 *   [0, OFF_X)        parameters (settable, tunable)
 *   [OFF_X, OFF_U)    continuous states
 *   [OFF_U, OFF_C)    inputs
 *   [OFF_C, N_REALS)  computed: derivatives, algebraic variables, calculated parameters
 * and the independent variable "time" has the value reference N_REALS (read only).
 *
 * Every function checks the instance state against the FMI 3.0 Model Exchange state machine
 * (Instantiated -> InitializationMode -> EventMode <-> ContinuousTimeMode -> Terminated;
 * FMI 3.0 standard, section 3.2), every argument and value reference before it
 * changes anything, and reports problems through the logger with fmi3Error: a bad call
 * never crashes the host.
 */

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "equations.h"
#include "model.h"

typedef fmi3Status Status;
typedef fmi3ValueReference ValueReference;
#define STATUS_OK fmi3OK
#define STATUS_ERROR fmi3Error
#define INSTANCE_LOGGER                        \
    fmi3InstanceEnvironment environment;       \
    fmi3LogMessageCallback log_message_callback;

#include "model_exchange_core.h"

static void deliver_message(Instance *inst, Status status, const char *category, const char *message) {
    if (inst->log_message_callback) inst->log_message_callback(inst->environment, status, category, message);
}

/* ---------------------------------------------------------------- life cycle */

#define TIME_VR (N_REALS) /* the independent variable */

const char *fmi3GetVersion(void) { return fmi3Version; }

static void release(void *pointer) { free(pointer); }

static void reset_values(Instance *inst) {
    memcpy(inst->r, START_VALUES, sizeof(double) * N_REALS);
    inst->time = 0;
    inst->computed_valid = inst->state_part_valid = 0;
}

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    Instance *inst = (Instance *)instance;
    (void)categories;
    (void)nCategories;
    if (invalid_state(inst, "fmi3SetDebugLogging", ANY_STATE)) return fmi3Error;
    inst->logging_on = loggingOn;
    return fmi3OK;
}

static void free_instance(Instance *inst) {
    if (!inst) return;
    release(inst->instance_name);
    release((void *)inst->arg);
    release(inst->res);
    release(inst->iw);
    release(inst->w);
    release(inst);
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    casadi_int sz_arg, sz_res, sz_iw, sz_w;
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
    inst = (Instance *)calloc(1, sizeof(Instance));
    if (!inst) return NULL;
    inst->environment = instanceEnvironment;
    inst->log_message_callback = logMessage;
    inst->logging_on = loggingOn;
    inst->state = Instantiated;
    inst->instance_name = (char *)calloc(strlen(instanceName) + 1, 1);
    work_sizes(&sz_arg, &sz_res, &sz_iw, &sz_w);
    inst->arg = (const casadi_real **)calloc((size_t)sz_arg + 1, sizeof(casadi_real *));
    inst->res = (casadi_real **)calloc((size_t)sz_res + 1, sizeof(casadi_real *));
    inst->iw = (casadi_int *)calloc((size_t)sz_iw + 1, sizeof(casadi_int));
    inst->w = (casadi_real *)calloc((size_t)sz_w + 1, sizeof(casadi_real));
    if (!inst->instance_name || !inst->arg || !inst->res || !inst->iw || !inst->w) {
        logMessage(instanceEnvironment, fmi3Fatal, "logStatusFatal", "fmi3InstantiateModelExchange: out of memory");
        free_instance(inst);
        return NULL;
    }
    strcpy(inst->instance_name, instanceName);
    reset_values(inst);
    return inst;
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
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateCoSimulation: " MODEL_IDENTIFIER_STRING " supports Model Exchange only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    if (logMessage)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateScheduledExecution: " MODEL_IDENTIFIER_STRING " supports Model Exchange only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) { free_instance((Instance *)instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    Instance *inst = (Instance *)instance;
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (invalid_state(inst, "fmi3EnterInitializationMode", Instantiated)) return fmi3Error;
    if (!isfinite(startTime)) {
        LOG_ERROR(inst, "fmi3EnterInitializationMode: startTime = %g is not finite", startTime);
        return fmi3Error;
    }
    inst->time = startTime;
    inst->state = InitializationMode;
    inst->computed_valid = inst->state_part_valid = 0;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    Instance *inst = (Instance *)instance;
    fmi3Status status;
    if (invalid_state(inst, "fmi3ExitInitializationMode", InitializationMode)) return fmi3Error;
    inst->computed_valid = inst->state_part_valid = 0;
    status = update(inst, "fmi3ExitInitializationMode");
    if (status != fmi3OK) return status;
    inst->state = EventMode;
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    Instance *inst = (Instance *)instance;
    if (invalid_state(inst, "fmi3EnterEventMode", EventMode | ContinuousTimeMode)) return fmi3Error;
    inst->state = EventMode;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    Instance *inst = (Instance *)instance;
    if (invalid_state(inst, "fmi3Terminate", EventMode | ContinuousTimeMode | ErrorState)) return fmi3Error;
    inst->state = Terminated;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    Instance *inst = (Instance *)instance;
    if (invalid_state(inst, "fmi3Reset", ANY_STATE)) return fmi3Error;
    inst->state = Instantiated;
    reset_values(inst);
    return fmi3OK;
}

/* ---------------------------------------------------------------- get and set */

/* Every variable is a scalar: as many values as value references. */
static int wrong_count(Instance *inst, const char *function, size_t nvr, size_t nValues) {
    return wrong_size(inst, function, "nValues", nValues, nvr);
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 value[],
                          size_t nValues) {
    Instance *inst = (Instance *)instance;
    if (invalid_state(inst, "fmi3GetFloat64", READABLE)) return fmi3Error;
    if (wrong_count(inst, "fmi3GetFloat64", nvr, nValues)) return fmi3Error;
    if (nvr == 0) return fmi3OK;
    if (null_argument(inst, "fmi3GetFloat64", "valueReferences", vr) ||
        null_argument(inst, "fmi3GetFloat64", "values", value)) return fmi3Error;
    for (size_t i = 0; i < nvr; i++) { /* every reference is checked before anything is read */
        if (vr[i] != TIME_VR && invalid_vr(inst, "fmi3GetFloat64", vr[i])) return enter_error_state(inst);
    }
    if (inst->state & InitializationMode) compute_state_starts(inst);
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] == TIME_VR) {
            value[i] = inst->time;
            continue;
        }
        if (vr[i] >= OFF_C && (IN_STATE_PART[vr[i] - OFF_C] ? update_state_part(inst, "fmi3GetFloat64")
                                                           : update(inst, "fmi3GetFloat64")) != fmi3OK)
            return fmi3Error;
        value[i] = inst->r[vr[i]];
    }
    return fmi3OK;
}

/* The reason a value of variable ref cannot be set in the instance's state, or NULL. */
static const char *not_settable(Instance *inst, fmi3ValueReference ref) {
    if (ref == TIME_VR) return "is the independent variable (set through fmi3SetTime)";
    if (ref >= OFF_C) return "is computed by the model and cannot be set";
    if (ref < OFF_X && !(inst->state & (Instantiated | InitializationMode | EventMode)))
        return "is a parameter: it can only be set before initialization or in event mode";
    if (ref >= OFF_X && ref < OFF_U &&
        (STATE_START_CALCULATED[ref - OFF_X] || !(inst->state & (Instantiated | InitializationMode))))
        return "is a state: it can only be set through fmi3SetContinuousStates";
    return NULL;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 value[],
                          size_t nValues) {
    Instance *inst = (Instance *)instance;
    if (invalid_state(inst, "fmi3SetFloat64", Instantiated | InitializationMode | EventMode | ContinuousTimeMode))
        return fmi3Error;
    if (wrong_count(inst, "fmi3SetFloat64", nvr, nValues)) return fmi3Error;
    if (nvr == 0) return fmi3OK;
    if (null_argument(inst, "fmi3SetFloat64", "valueReferences", vr) ||
        null_argument(inst, "fmi3SetFloat64", "values", value)) return fmi3Error;
    /* validate every reference and value first: a rejected call writes nothing */
    for (size_t i = 0; i < nvr; i++) {
        const char *reason;
        if (vr[i] != TIME_VR && invalid_vr(inst, "fmi3SetFloat64", vr[i])) return enter_error_state(inst);
        reason = not_settable(inst, vr[i]);
        if (reason) {
            LOG_ERROR(inst, "fmi3SetFloat64: %s %s", vr[i] == TIME_VR ? "time" : VARIABLE_NAMES[vr[i]], reason);
            return enter_error_state(inst);
        }
        if (!isfinite(value[i])) {
            LOG_ERROR(inst, "fmi3SetFloat64: value of %s is not finite", VARIABLE_NAMES[vr[i]]);
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
    return fmi3OK;
}

/* The model has Float64 variables only: any value reference of another type is invalid. */
static fmi3Status no_such_variables(fmi3Instance instance, const char *function, size_t nvr) {
    Instance *inst = (Instance *)instance;
    if (invalid_state(inst, function, ANY_STATE)) return fmi3Error;
    if (nvr == 0) return fmi3OK;
    LOG_ERROR(inst, "%s: invalid value reference (the model has no variables of this type)", function);
    return fmi3Error;
}

#define NO_SUCH_GETTER(NAME, TYPE)                                                                                  \
    fmi3Status fmi3Get##NAME(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, TYPE value[],      \
                             size_t nValues) {                                                                    \
        (void)vr; (void)value; (void)nValues;                                                                     \
        return no_such_variables(instance, "fmi3Get" #NAME, nvr);                                                 \
    }
#define NO_SUCH_SETTER(NAME, TYPE)                                                                                  \
    fmi3Status fmi3Set##NAME(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const TYPE value[], \
                             size_t nValues) {                                                                    \
        (void)vr; (void)value; (void)nValues;                                                                     \
        return no_such_variables(instance, "fmi3Set" #NAME, nvr);                                                 \
    }
#define NO_SUCH_TYPE(NAME, TYPE) NO_SUCH_GETTER(NAME, TYPE) NO_SUCH_SETTER(NAME, TYPE)

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

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                         fmi3Binary value[], size_t nValues) {
    (void)vr; (void)valueSizes; (void)value; (void)nValues;
    return no_such_variables(instance, "fmi3GetBinary", nvr);
}
fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const size_t valueSizes[],
                         const fmi3Binary value[], size_t nValues) {
    (void)vr; (void)valueSizes; (void)value; (void)nValues;
    return no_such_variables(instance, "fmi3SetBinary", nvr);
}
fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Clock value[]) {
    (void)vr; (void)value;
    return no_such_variables(instance, "fmi3GetClock", nvr);
}
fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock value[]) {
    (void)vr; (void)value;
    return no_such_variables(instance, "fmi3SetClock", nvr);
}

/* ---------------------------------------------------------------- unsupported optional features */

static fmi3Status unsupported(fmi3Instance instance, const char *function) {
    Instance *inst = (Instance *)instance;
    if (inst) LOG_ERROR(inst, "%s: not supported by this FMU", function);
    return fmi3Error;
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    (void)valueReference; (void)nDependencies;
    return unsupported(instance, "fmi3GetNumberOfVariableDependencies");
}
fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent; (void)elementIndicesOfDependent; (void)independents; (void)elementIndicesOfIndependents;
    (void)dependencyKinds; (void)nDependencies;
    return unsupported(instance, "fmi3GetVariableDependencies");
}
fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    (void)FMUState;
    return unsupported(instance, "fmi3GetFMUState");
}
fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    (void)FMUState;
    return unsupported(instance, "fmi3SetFMUState");
}
fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    (void)FMUState;
    return unsupported(instance, "fmi3FreeFMUState");
}
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    (void)FMUState; (void)size;
    return unsupported(instance, "fmi3SerializedFMUStateSize");
}
fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size) {
    (void)FMUState; (void)serializedState; (void)size;
    return unsupported(instance, "fmi3SerializeFMUState");
}
fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) {
    (void)serializedState; (void)size; (void)FMUState;
    return unsupported(instance, "fmi3DeserializeFMUState");
}
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed; (void)sensitivity;
    (void)nSensitivity;
    return unsupported(instance, "fmi3GetDirectionalDerivative");
}
fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns; (void)seed; (void)nSeed; (void)sensitivity;
    (void)nSensitivity;
    return unsupported(instance, "fmi3GetAdjointDerivative");
}
fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    return unsupported(instance, "fmi3EnterConfigurationMode");
}
fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    return unsupported(instance, "fmi3ExitConfigurationMode");
}
fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    (void)vr; (void)nvr; (void)intervals; (void)qualifiers;
    return unsupported(instance, "fmi3GetIntervalDecimal");
}
fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions; (void)qualifiers;
    return unsupported(instance, "fmi3GetIntervalFraction");
}
fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               fmi3Float64 shifts[]) {
    (void)vr; (void)nvr; (void)shifts;
    return unsupported(instance, "fmi3GetShiftDecimal");
}
fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions;
    return unsupported(instance, "fmi3GetShiftFraction");
}
fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  const fmi3Float64 intervals[]) {
    (void)vr; (void)nvr; (void)intervals;
    return unsupported(instance, "fmi3SetIntervalDecimal");
}
fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions;
    return unsupported(instance, "fmi3SetIntervalFraction");
}
fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               const fmi3Float64 shifts[]) {
    (void)vr; (void)nvr; (void)shifts;
    return unsupported(instance, "fmi3SetShiftDecimal");
}
fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)vr; (void)nvr; (void)counters; (void)resolutions;
    return unsupported(instance, "fmi3SetShiftFraction");
}
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    return unsupported(instance, "fmi3EvaluateDiscreteStates");
}
fmi3Status fmi3EnterStepMode(fmi3Instance instance) { return unsupported(instance, "fmi3EnterStepMode"); }
fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    (void)vr; (void)nvr; (void)orders; (void)values; (void)nValues;
    return unsupported(instance, "fmi3GetOutputDerivatives");
}
fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint, fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean *eventHandlingNeeded,
                      fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    (void)currentCommunicationPoint; (void)communicationStepSize; (void)noSetFMUStatePriorToCurrentPoint;
    (void)eventHandlingNeeded; (void)terminateSimulation; (void)earlyReturn; (void)lastSuccessfulTime;
    return unsupported(instance, "fmi3DoStep");
}
fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    (void)clockReference; (void)activationTime;
    return unsupported(instance, "fmi3ActivateModelPartition");
}

/* ---------------------------------------------------------------- model exchange */

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    Instance *inst = (Instance *)instance;
    const char *function = "fmi3UpdateDiscreteStates";
    if (invalid_state(inst, function, EventMode)) return fmi3Error;
    if (null_argument(inst, function, "discreteStatesNeedUpdate", discreteStatesNeedUpdate) ||
        null_argument(inst, function, "terminateSimulation", terminateSimulation) ||
        null_argument(inst, function, "nominalsOfContinuousStatesChanged", nominalsOfContinuousStatesChanged) ||
        null_argument(inst, function, "valuesOfContinuousStatesChanged", valuesOfContinuousStatesChanged) ||
        null_argument(inst, function, "nextEventTimeDefined", nextEventTimeDefined) ||
        null_argument(inst, function, "nextEventTime", nextEventTime))
        return fmi3Error;
    *discreteStatesNeedUpdate = fmi3False; /* the models have no discrete states */
    *terminateSimulation = fmi3False;
    *nominalsOfContinuousStatesChanged = fmi3False;
    *valuesOfContinuousStatesChanged = fmi3False;
    *nextEventTimeDefined = fmi3False;
    *nextEventTime = 0;
    return fmi3OK;
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    Instance *inst = (Instance *)instance;
    if (invalid_state(inst, "fmi3EnterContinuousTimeMode", EventMode)) return fmi3Error;
    inst->state = ContinuousTimeMode;
    return fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    Instance *inst = (Instance *)instance;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (invalid_state(inst, "fmi3CompletedIntegratorStep", ContinuousTimeMode)) return fmi3Error;
    if (null_argument(inst, "fmi3CompletedIntegratorStep", "enterEventMode", enterEventMode) ||
        null_argument(inst, "fmi3CompletedIntegratorStep", "terminateSimulation", terminateSimulation))
        return fmi3Error;
    *enterEventMode = fmi3False;
    *terminateSimulation = fmi3False;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    Instance *inst = (Instance *)instance;
    if (invalid_state(inst, "fmi3SetTime", EventMode | ContinuousTimeMode)) return fmi3Error;
    if (!isfinite(time)) {
        LOG_ERROR(inst, "fmi3SetTime: time = %g is not finite", time);
        return fmi3Error;
    }
    inst->time = time;
    inst->computed_valid = inst->state_part_valid = 0;
    return fmi3OK;
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[], size_t nx) {
    Instance *inst = (Instance *)instance;
    if (invalid_state(inst, "fmi3SetContinuousStates", EventMode | ContinuousTimeMode)) return fmi3Error;
    if (wrong_size(inst, "fmi3SetContinuousStates", "nContinuousStates", nx, N_STATES)) return fmi3Error;
    if (nx == 0) return fmi3OK;
    if (null_argument(inst, "fmi3SetContinuousStates", "continuousStates", x)) return enter_error_state(inst);
    for (size_t i = 0; i < nx; i++) {
        if (!isfinite(x[i])) {
            LOG_ERROR(inst, "fmi3SetContinuousStates: %s = %g is not finite", VARIABLE_NAMES[OFF_X + i], x[i]);
            return enter_error_state(inst);
        }
    }
    memcpy(inst->r + OFF_X, x, sizeof(double) * nx);
    inst->computed_valid = inst->state_part_valid = 0;
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[], size_t nx) {
    Instance *inst = (Instance *)instance;
    if (invalid_state(inst, "fmi3GetContinuousStateDerivatives", READABLE)) return fmi3Error;
    if (wrong_size(inst, "fmi3GetContinuousStateDerivatives", "nContinuousStates", nx, N_STATES)) return fmi3Error;
    if (nx == 0) return fmi3OK;
    if (null_argument(inst, "fmi3GetContinuousStateDerivatives", "derivatives", derivatives))
        return enter_error_state(inst);
    if (update(inst, "fmi3GetContinuousStateDerivatives") != fmi3OK) return fmi3Error;
    memcpy(derivatives, inst->r + OFF_C, sizeof(double) * nx);
    return fmi3OK;
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t ni) {
    Instance *inst = (Instance *)instance;
    (void)eventIndicators;
    if (invalid_state(inst, "fmi3GetEventIndicators", READABLE)) return fmi3Error;
    if (wrong_size(inst, "fmi3GetEventIndicators", "nEventIndicators", ni, 0)) return fmi3Error;
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t nx) {
    Instance *inst = (Instance *)instance;
    if (invalid_state(inst, "fmi3GetContinuousStates", READABLE)) return fmi3Error;
    if (wrong_size(inst, "fmi3GetContinuousStates", "nContinuousStates", nx, N_STATES)) return fmi3Error;
    if (nx == 0) return fmi3OK;
    if (null_argument(inst, "fmi3GetContinuousStates", "continuousStates", x)) return fmi3Error;
    if (inst->state & InitializationMode) compute_state_starts(inst);
    memcpy(x, inst->r + OFF_X, sizeof(double) * nx);
    return fmi3OK;
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t nx) {
    Instance *inst = (Instance *)instance;
    if (invalid_state(inst, "fmi3GetNominalsOfContinuousStates", ANY_STATE)) return fmi3Error;
    if (wrong_size(inst, "fmi3GetNominalsOfContinuousStates", "nContinuousStates", nx, N_STATES)) return fmi3Error;
    if (nx == 0) return fmi3OK;
    if (null_argument(inst, "fmi3GetNominalsOfContinuousStates", "nominals", nominals)) return fmi3Error;
    memcpy(nominals, STATE_NOMINALS, sizeof(double) * nx);
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    Instance *inst = (Instance *)instance;
    if (invalid_state(inst, "fmi3GetNumberOfEventIndicators", ANY_STATE)) return fmi3Error;
    if (null_argument(inst, "fmi3GetNumberOfEventIndicators", "nEventIndicators", nEventIndicators)) return fmi3Error;
    *nEventIndicators = 0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    Instance *inst = (Instance *)instance;
    if (invalid_state(inst, "fmi3GetNumberOfContinuousStates", ANY_STATE)) return fmi3Error;
    if (null_argument(inst, "fmi3GetNumberOfContinuousStates", "nContinuousStates", nContinuousStates))
        return fmi3Error;
    *nContinuousStates = N_STATES;
    return fmi3OK;
}
