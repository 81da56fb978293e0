/*
 * The model-independent part of heliostep's FMI Model Exchange layers, written once for FMI 2.0
 * (fmi2_model_exchange.c) and FMI 3.0 (fmi3_model_exchange.c): the instance and its state
 * machine, the checks of states and arguments, the evaluation of a model's generated equations
 * ("equations.h", described by "model.h") and the bodies of the entry points. Each layer holds
 * only its version's signatures; it includes this file after defining its version's names:
 *   Status, ValueReference     fmiXStatus and fmiXValueReference
 *   STATUS_OK, STATUS_ERROR    fmiXOK and fmiXError
 *   FMI_PREFIX                 "fmi2" or "fmi3", the start of every entry point's name
 *   INSTANCE_LOGGER            the Instance fields that hold the logger callback
 *   TIME_VARIABLE              1 where time has a value reference (N_REALS, read only)
 *   PARAMETER_NOT_SETTABLE, STATE_NOT_SETTABLE   the messages of those refusals (%s: the name)
 * and defines deliver_message(), which calls its logger.
 *
 * The generated equations provide
 *   model_eval(t, x, u, p, guess)  -> (computed, residual)   explicit, or two Newton steps from guess
 *   model_solve(t, x, u, p, guess) -> (computed, residual)   converge, then two Newton steps
 *   model_scale(t, x, u, p)        -> scale                  the size of each equation's terms
 *   model_state_part(t, x, u, p)   -> the computed variables that depend on no input
 *   model_rest(t, x, u, p, part)   -> the other computed variables from those
 *   model_start(p)                 -> x0
 * where "computed" holds the state derivatives, the algebraic variables and the calculated
 * parameters and "residual" the model's residual at that solution (checked here, against the
 * scale). The previous solution is the guess; model_solve is the fallback when model_eval's
 * residual is not small, from the previous solution and then from zero.
 *
 * Every real variable lives in one array r[], indexed by its value reference:
 *   [0, OFF_X)        parameters (settable, tunable)
 *   [OFF_X, OFF_U)    continuous states
 *   [OFF_U, OFF_C)    inputs
 *   [OFF_C, N_REALS)  computed: derivatives, algebraic variables, calculated parameters
 *
 * Every entry point runs between BEGIN_FUNCTION and END_FUNCTION: it checks the instance's state
 * and then its arguments before it changes anything, and every error leaves through END_FUNCTION
 * with fmiXError and a message to the logger: a bad call never crashes the host.
 */

#ifndef HELIOSTEP_MODEL_EXCHANGE_CORE_H
#define HELIOSTEP_MODEL_EXCHANGE_CORE_H

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "equations.h"
#include "model.h"

#define OFF_X (N_PARAMETERS)
#define OFF_U (OFF_X + N_STATES)
#define OFF_C (OFF_U + N_INPUTS)
#define N_REALS (OFF_C + N_COMPUTED)
#define TIME_VR (N_REALS)

/* An equation's residual is trusted when |F_i| <= RESIDUAL_RTOL * scale_i + RESIDUAL_ATOL, where
 * scale_i (from the generated code) is the size of the terms that equation balances, in its
 * own units: one absolute tolerance would be too loose for some equations, too tight for others. */
#define RESIDUAL_RTOL 1e-8
#define RESIDUAL_ATOL 1e-10

/* The states of FMI 2.0's and 3.0's Model Exchange state machines (FMI 3.0, section 3.2). */
typedef enum {
    Instantiated = 1 << 0,
    InitializationMode = 1 << 1,
    EventMode = 1 << 2,
    ContinuousTimeMode = 1 << 3,
    Terminated = 1 << 4,
    ErrorState = 1 << 5
} ModelState;

#define ANY_STATE (Instantiated | InitializationMode | EventMode | ContinuousTimeMode | Terminated | ErrorState)
#define READABLE (InitializationMode | EventMode | ContinuousTimeMode | Terminated | ErrorState)
#define WRITABLE (Instantiated | InitializationMode | EventMode | ContinuousTimeMode)

typedef void *(*Allocate)(size_t count, size_t size);
typedef void (*Release)(void *pointer);

typedef struct {
    INSTANCE_LOGGER             /* the version's logger callback and its environment */
    Allocate allocate;          /* the instance's memory: zeroed, as calloc's */
    Release release;
    char *instance_name;
    int logging_on;
    ModelState state;
    double time;
    int computed_valid;   /* every computed variable is up to date */
    int state_part_valid; /* those that depend on no input (IN_STATE_PART) are up to date */
    double r[N_REALS];
    double guess[N_COMPUTED + 1];
    double computed[N_COMPUTED + 1];
    double residual[N_UNKNOWNS + 1];
    double scale[N_UNKNOWNS + 1];
    const casadi_real **arg;
    casadi_real **res;
    casadi_int *iw;
    casadi_real *w;
} Instance;

/* ---------------------------------------------------------------- logging, checks and the entry points' frame */

/* Hands a message to the host's logger (defined by each layer: the callbacks differ by version). */
static void deliver_message(Instance *inst, Status status, const char *category, const char *message);

static void log_message(Instance *inst, Status status, const char *category, const char *format, ...) {
    char message[512];
    va_list args;
    if (!inst) return;
    if (status == STATUS_OK && !inst->logging_on) return;
    va_start(args, format);
    vsnprintf(message, sizeof message, format, args);
    va_end(args);
    deliver_message(inst, status, category, message);
}

#define LOG_ERROR(inst, ...) log_message((inst), STATUS_ERROR, "logStatusError", __VA_ARGS__)

static const char *state_name(ModelState state) {
    switch (state) {
    case Instantiated: return "instantiated";
    case InitializationMode: return "initialization mode";
    case EventMode: return "event mode";
    case ContinuousTimeMode: return "continuous-time mode";
    case Terminated: return "terminated";
    default: return "error";
    }
}

/* Checks that the instance exists and is in one of the allowed states. */
static int invalid_state(Instance *inst, const char *function, int allowed) {
    if (!inst) return 1;
    if (!(inst->state & allowed)) {
        LOG_ERROR(inst, "%s: not allowed in %s", function, state_name(inst->state));
        return 1;
    }
    return 0;
}

/* Logs an error and refuses the call (fmiXError): the state is left as it is. */
#define REFUSE(inst, ...) (LOG_ERROR(inst, __VA_ARGS__), STATUS_ERROR)
/* Logs an error and puts the instance in the error state (fmiXError). */
#define FAIL(inst, ...) (LOG_ERROR(inst, __VA_ARGS__), enter_error_state(inst))

/* After an error the instance is in the error state (FMI 2.0 and 3.0 state machines, as the
 * Reference FMUs do): only Get*, Terminate, Reset, FreeInstance and SetDebugLogging are
 * allowed, and nothing computed before is trusted any more. An illegal call sequence or an
 * argument of the wrong shape is refused without changing the state. */
static Status enter_error_state(Instance *inst) {
    inst->state = ErrorState;
    inst->computed_valid = inst->state_part_valid = 0;
    return STATUS_ERROR;
}

/* A check whose error puts the instance in the error state. */
static Status failing(Instance *inst, Status status) {
    return status == STATUS_OK ? status : enter_error_state(inst);
}

static Status not_null(Instance *inst, const char *function, const char *name, const void *pointer) {
    return pointer ? STATUS_OK : REFUSE(inst, "%s: argument %s must not be NULL", function, name);
}

static Status size_is(Instance *inst, const char *function, const char *name, size_t given, size_t expected) {
    if (given == expected) return STATUS_OK;
    return REFUSE(inst, "%s: %s is %lu, the model has %lu", function, name, (unsigned long)given, (unsigned long)expected);
}

static int invalid_vr(Instance *inst, const char *function, ValueReference vr) {
    if (vr < N_REALS) return 0;
    LOG_ERROR(inst, "%s: invalid value reference %u (the model has %u real variables)", function, vr, (unsigned)N_REALS);
    return 1;
}

/* Opens the entry point FMI_PREFIX NAME, whose first argument is instance: it gives the body inst,
 * function (the name, for messages) and status, and refuses a call on no instance or in a state
 * not among ALLOWED. Every step after it runs through CALL; END_FUNCTION returns the status. */
#define BEGIN_FUNCTION(NAME, ALLOWED)                    \
    Instance *const inst = (Instance *)instance;        \
    const char *const function = FMI_PREFIX #NAME;      \
    Status status = STATUS_OK;                          \
    if (invalid_state(inst, function, (ALLOWED))) {     \
        status = STATUS_ERROR;                          \
        goto END;                                       \
    }

/* Runs a check or a step of an entry point: any status but OK ends the call with it. */
#define CALL(step)                         \
    do {                                   \
        status = (step);                   \
        if (status != STATUS_OK) goto END; \
    } while (0)

/* Ends the call with fmiXOK when there is nothing to do (e.g. no values asked for). */
#define RETURN_OK_IF(condition) \
    do {                        \
        if (condition) goto END; \
    } while (0)

#define END_FUNCTION() \
    END:               \
    return status;

/* The argument checks, named as the entry point's parameters are. */
#define NOT_NULL(argument) not_null(inst, function, #argument, (argument))
#define SIZE_IS(argument, expected) size_is(inst, function, #argument, (argument), (expected))
#define FINITE(argument) \
    (isfinite(argument) ? STATUS_OK : REFUSE(inst, "%s: %s = %g is not finite", function, #argument, (argument)))
/* n value references and n values: none asked for ends the call, a missing array is refused. */
#define CHECK_VALUES(references, values, n) \
    RETURN_OK_IF((n) == 0);                 \
    CALL(NOT_NULL(references));             \
    CALL(NOT_NULL(values))
/* An array of n values, n == expected: none asked for ends the call; a missing one is refused,
 * or puts the instance in the error state where ON_NULL is FAILING. */
#define REFUSING(check) (check)
#define FAILING(check) failing(inst, (check))
#define CHECK_ARRAY(array, n, expected, ON_NULL) \
    CALL(SIZE_IS(n, expected));                  \
    RETURN_OK_IF((n) == 0);                      \
    CALL(ON_NULL(NOT_NULL(array)))

/* ---------------------------------------------------------------- evaluation */

typedef int (*EquationFunction)(const casadi_real **, casadi_real **, casadi_int *, casadi_real *, int);

/* Values below TINY (e.g. a phase current decaying as exp(-t/18 us) for 0.1 s reaches 1e-155 A)
 * are zero for the physics of any SI quantity, but the generated QR factorisation of the Newton
 * step squares them: below sqrt(DBL_MIN) ~ 1.5e-154 the squares underflow to zero and the
 * Householder step returns 0/0 = NaN. They are flushed to zero before every evaluation. */
#define TINY 1e-100

static void flush_tiny(double *values, int n) {
    for (int i = 0; i < n; i++) {
        if (values[i] != 0.0 && fabs(values[i]) < TINY) values[i] = 0.0;
    }
}

/* The generated functions' first arguments: t, x, u, p (p: the parameters at the start of r). */
static void set_known_arguments(Instance *inst) {
    inst->arg[0] = &inst->time;
    inst->arg[1] = inst->r + OFF_X;
    inst->arg[2] = inst->r + OFF_U;
    inst->arg[3] = inst->r;
}

/* Whether residual[k], of equation equation[k] (NULL: of equation k), k < n, is trusted (see
 * RESIDUAL_RTOL): the scale (model_scale, at the known arguments set) is computed only for a
 * residual the absolute bound does not pass. */
static int residuals_trusted(Instance *inst, const double *residual, int n, const int *equation) {
    int scaled = 0;
    for (int k = 0; k < n; k++) {
        if (fabs(residual[k]) <= RESIDUAL_ATOL) continue;
        if (!scaled) {
            inst->res[0] = inst->scale;
            if (model_scale(inst->arg, inst->res, inst->iw, inst->w, 0)) return 0;
            scaled = 1;
        }
        if (!(fabs(residual[k]) <= RESIDUAL_RTOL * fabs(inst->scale[equation ? equation[k] : k]) + RESIDUAL_ATOL))
            return 0;
    }
    return 1;
}

static int eval_equations(Instance *inst, EquationFunction equations, const double *guess, int newton) {
    if (newton) { /* only the Newton step's QR factorisation needs it */
        flush_tiny(inst->r + OFF_X, N_STATES + N_INPUTS);
        flush_tiny(inst->guess, N_COMPUTED);
    }
    set_known_arguments(inst);
    inst->arg[4] = guess;
    inst->res[0] = inst->computed;
    inst->res[1] = inst->residual;
    if (equations(inst->arg, inst->res, inst->iw, inst->w, 0)) return 0;
    return residuals_trusted(inst, inst->residual, N_UNKNOWNS, NULL);
}

/* Calculated start values of the states (those bound to parameters). */
static void compute_state_starts(Instance *inst) {
    double x0[N_STATES + 1];
    inst->arg[0] = inst->r;
    inst->res[0] = x0;
    model_start(inst->arg, inst->res, inst->iw, inst->w, 0);
    for (int i = 0; i < N_STATES; i++) {
        if (STATE_START_CALCULATED[i]) inst->r[OFF_X + i] = x0[i];
    }
}

/* The computed variables outside the state part from its values (model_rest, see
 * heliostep/fmu/export.py rest_evaluation: model_eval's expressions with the part's values in them,
 * the same bits for the shipped models), when the state part is up to date, e.g. after the master
 * read a mechanics model's angle and then set its torque. Its equations' residuals are checked as
 * model_eval's are (residuals_trusted). Returns 1 when done; 0 leaves it to the full evaluation (no rest, the state
 * part not valid, initializing, or a residual or value not trusted: the full one reports it). */
static int update_rest(Instance *inst) {
#if N_REST
    double part[N_STATE_PART], rest[N_REST], residual[N_REST];
    if (!inst->state_part_valid || (inst->state & (Instantiated | InitializationMode))) return 0;
    for (int j = 0; j < N_STATE_PART; j++) part[j] = inst->r[OFF_C + STATE_PART_INDEX[j]];
    set_known_arguments(inst);
    inst->arg[4] = part;
    inst->res[0] = rest;
    inst->res[1] = residual;
    if (model_rest(inst->arg, inst->res, inst->iw, inst->w, 0)) return 0;
    for (int k = 0; k < N_REST; k++) {
        if (!isfinite(rest[k])) return 0;
    }
    if (!residuals_trusted(inst, residual, N_REST, REST_EQUATION)) return 0;
    for (int k = 0; k < N_REST; k++) inst->r[OFF_C + REST_INDEX[k]] = rest[k];
    inst->computed_valid = 1;
    return 1;
#else
    (void)inst;
    return 0;
#endif
}

/* Brings the computed variables up to date; logs and returns STATUS_ERROR if that fails. */
static Status update(Instance *inst, const char *function) {
    static const double zeros[N_COMPUTED + 1] = {0};
    if (inst->computed_valid) return STATUS_OK;
    if (update_rest(inst)) return STATUS_OK;
    if (inst->state & (Instantiated | InitializationMode)) compute_state_starts(inst);
    /* the previous solution is the Newton iteration's guess (an explicit model_eval needs none) */
    if (!EXPLICIT_EVAL) memcpy(inst->guess, inst->r + OFF_C, sizeof(double) * N_COMPUTED);
    if (!eval_equations(inst, model_eval, inst->guess, !EXPLICIT_EVAL) &&
        !(EXPLICIT_EVAL && (memcpy(inst->guess, inst->r + OFF_C, sizeof(double) * N_COMPUTED), 0)) &&
        !eval_equations(inst, model_solve, inst->guess, 1) && !eval_equations(inst, model_solve, zeros, 1)) {
        return FAIL(inst, "%s: the model equations could not be solved at t = %g", function, inst->time);
    }
    for (int i = 0; i < N_COMPUTED; i++) {
        if (!isfinite(inst->computed[i])) {
            return FAIL(inst, "%s: %s is not finite at t = %g", function, VARIABLE_NAMES[OFF_C + i], inst->time);
        }
    }
    memcpy(inst->r + OFF_C, inst->computed, sizeof(double) * N_COMPUTED);
    inst->computed_valid = inst->state_part_valid = 1;
    return STATUS_OK;
}

/* The largest work sizes of the generated functions (CasADi's *_work), for the instance's buffers. */
static void work_sizes(casadi_int *sz_arg, casadi_int *sz_res, casadi_int *sz_iw, casadi_int *sz_w) {
    casadi_int n_arg, n_res, n_iw, n_w;
    int (*const sizes[])(casadi_int *, casadi_int *, casadi_int *, casadi_int *) = {
        model_eval_work, model_solve_work, model_scale_work,
#if N_STATE_PART
        model_state_part_work,
#endif
#if N_REST
        model_rest_work,
#endif
    };
    model_start_work(sz_arg, sz_res, sz_iw, sz_w);
    for (size_t f = 0; f < sizeof(sizes) / sizeof(sizes[0]); f++) {
        sizes[f](&n_arg, &n_res, &n_iw, &n_w);
        if (*sz_arg < n_arg) *sz_arg = n_arg;
        if (*sz_res < n_res) *sz_res = n_res;
        if (*sz_iw < n_iw) *sz_iw = n_iw;
        if (*sz_w < n_w) *sz_w = n_w;
    }
}

/* Brings the computed variables that depend on no input up to date (model_state_part, the
 * straight-line code of only those: e.g. a mechanics model's angle and speed while its torque
 * input is new), or everything where the model has no such part or is initializing. */
static Status update_state_part(Instance *inst, const char *function) {
#if N_STATE_PART
    double part[N_STATE_PART];
    if (inst->computed_valid || inst->state_part_valid) return STATUS_OK;
    if (inst->state & (Instantiated | InitializationMode)) return update(inst, function);
    set_known_arguments(inst);
    inst->res[0] = part;
    if (model_state_part(inst->arg, inst->res, inst->iw, inst->w, 0)) return update(inst, function);
    for (int j = 0; j < N_STATE_PART; j++) {
        if (!isfinite(part[j])) return update(inst, function); /* the full evaluation reports it */
    }
    for (int j = 0; j < N_STATE_PART; j++) inst->r[OFF_C + STATE_PART_INDEX[j]] = part[j];
    inst->state_part_valid = 1;
    return STATUS_OK;
#else
    return update(inst, function);
#endif
}

/* ---------------------------------------------------------------- the entry points' bodies */

static void invalidate(Instance *inst) { inst->computed_valid = inst->state_part_valid = 0; }

static void reset_values(Instance *inst) {
    memcpy(inst->r, START_VALUES, sizeof(double) * N_REALS);
    inst->time = 0;
    invalidate(inst);
}

static void free_instance(Instance *inst) {
    if (!inst) return;
    Release release = inst->release;
    void *parts[] = {inst->instance_name, (void *)inst->arg, inst->res, inst->iw, inst->w, inst};
    for (size_t i = 0; i < sizeof(parts) / sizeof(parts[0]); i++) {
        if (parts[i]) release(parts[i]);
    }
}

/* A new instance in the Instantiated state, its memory from allocate (zeroed, as calloc's) and
 * release; NULL when out of memory. */
static Instance *new_instance(const char *name, int logging_on, Allocate allocate, Release release) {
    casadi_int sz_arg, sz_res, sz_iw, sz_w;
    Instance *inst = (Instance *)allocate(1, sizeof(Instance));
    if (!inst) return NULL;
    inst->allocate = allocate;
    inst->release = release;
    inst->logging_on = logging_on;
    inst->state = Instantiated;
    inst->instance_name = (char *)allocate(strlen(name) + 1, 1);
    work_sizes(&sz_arg, &sz_res, &sz_iw, &sz_w);
    inst->arg = (const casadi_real **)allocate((size_t)sz_arg + 1, sizeof(casadi_real *));
    inst->res = (casadi_real **)allocate((size_t)sz_res + 1, sizeof(casadi_real *));
    inst->iw = (casadi_int *)allocate((size_t)sz_iw + 1, sizeof(casadi_int));
    inst->w = (casadi_real *)allocate((size_t)sz_w + 1, sizeof(casadi_real));
    if (!inst->instance_name || !inst->arg || !inst->res || !inst->iw || !inst->w) {
        free_instance(inst);
        return NULL;
    }
    strcpy(inst->instance_name, name);
    reset_values(inst);
    return inst;
}

static void enter_initialization_mode(Instance *inst) {
    inst->state = InitializationMode;
    invalidate(inst);
}

static Status exit_initialization_mode(Instance *inst, const char *function) {
    Status status;
    invalidate(inst);
    status = update(inst, function);
    if (status != STATUS_OK) return status;
    inst->state = EventMode;
    return STATUS_OK;
}

static void reset(Instance *inst) {
    inst->state = Instantiated;
    reset_values(inst);
}

static void set_time(Instance *inst, double time) {
    inst->time = time;
    invalidate(inst);
}

/* Whether vr is the independent variable time (FMI 3.0 only: TIME_VARIABLE). */
static int is_time(ValueReference vr) { return TIME_VARIABLE && vr == TIME_VR; }

static Status get_reals(Instance *inst, const char *function, const ValueReference vr[], size_t nvr, double value[]) {
    for (size_t i = 0; i < nvr; i++) { /* every reference is checked before anything is read */
        if (!is_time(vr[i]) && invalid_vr(inst, function, vr[i])) return enter_error_state(inst);
    }
    if (inst->state & InitializationMode) compute_state_starts(inst);
    for (size_t i = 0; i < nvr; i++) {
        if (is_time(vr[i])) {
            value[i] = inst->time;
            continue;
        }
        if (vr[i] >= OFF_C &&
            (IN_STATE_PART[vr[i] - OFF_C] ? update_state_part(inst, function) : update(inst, function)) != STATUS_OK)
            return STATUS_ERROR;
        value[i] = inst->r[vr[i]];
    }
    return STATUS_OK;
}

static Status set_reals(Instance *inst, const char *function, const ValueReference vr[], size_t nvr, const double value[]) {
    int inputs_only = 1;
    for (size_t i = 0; i < nvr; i++) { /* every reference and value is checked first: a refused call writes nothing */
        ValueReference ref = vr[i];
        if (is_time(ref))
            return FAIL(inst, "%s: time is the independent variable (set through " FMI_PREFIX "SetTime)", function);
        if (invalid_vr(inst, function, ref)) return enter_error_state(inst);
        if (ref >= OFF_C) return FAIL(inst, "%s: %s is computed by the model and cannot be set", function, VARIABLE_NAMES[ref]);
        if (ref < OFF_X && !(inst->state & (Instantiated | InitializationMode | EventMode)))
            return FAIL(inst, "%s: " PARAMETER_NOT_SETTABLE, function, VARIABLE_NAMES[ref]);
        if (ref >= OFF_X && ref < OFF_U &&
            (STATE_START_CALCULATED[ref - OFF_X] || !(inst->state & (Instantiated | InitializationMode))))
            return FAIL(inst, "%s: " STATE_NOT_SETTABLE, function, VARIABLE_NAMES[ref]);
        if (!isfinite(value[i])) return FAIL(inst, "%s: value of %s is not finite", function, VARIABLE_NAMES[ref]);
    }
    for (size_t i = 0; i < nvr; i++) {
        inst->r[vr[i]] = value[i];
        inputs_only &= vr[i] >= OFF_U;
    }
    inst->computed_valid = 0;
    if (!inputs_only) inst->state_part_valid = 0; /* a new input leaves the state part as it is */
    return STATUS_OK;
}

/* The models have real variables only: a value reference of another type is refused. */
static Status no_variables(Instance *inst, const char *function, size_t nvr) {
    if (nvr == 0) return STATUS_OK;
    return REFUSE(inst, "%s: invalid value reference (the model has no variables of this type)", function);
}

/* The whole body of an entry point of an optional feature the FMUs do not support. */
#define UNSUPPORTED(NAME)                                                        \
    BEGIN_FUNCTION(NAME, ANY_STATE)                                              \
    CALL(REFUSE(inst, "%s: not supported by this FMU", function));               \
    END_FUNCTION()

static Status set_continuous_states(Instance *inst, const char *function, const double x[], size_t nx) {
    for (size_t i = 0; i < nx; i++) {
        if (!isfinite(x[i])) return FAIL(inst, "%s: %s = %g is not finite", function, VARIABLE_NAMES[OFF_X + i], x[i]);
    }
    memcpy(inst->r + OFF_X, x, sizeof(double) * nx);
    invalidate(inst);
    return STATUS_OK;
}

static Status get_derivatives(Instance *inst, const char *function, double derivatives[], size_t nx) {
    if (update(inst, function) != STATUS_OK) return STATUS_ERROR;
    memcpy(derivatives, inst->r + OFF_C, sizeof(double) * nx);
    return STATUS_OK;
}

static void get_continuous_states(Instance *inst, double x[], size_t nx) {
    if (inst->state & InitializationMode) compute_state_starts(inst);
    memcpy(x, inst->r + OFF_X, sizeof(double) * nx);
}

#endif
