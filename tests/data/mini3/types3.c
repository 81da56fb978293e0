/* Types3 (FMI 3.0 Model Exchange), written for heliostep's tests: a pass-through of every FMI 3.0
 * variable type and of an array, with a few generators to connect it to (its modelDescription is
 * types3.xml beside this file; the value references are the enum below).
 *
 * Pass-through: T_out = T_in for T in Float32, Float64, Int8, UInt8, Int16, UInt16, Int32, UInt32,
 * Int64, UInt64, Boolean, String, Binary, Enumeration; a_out[i,j] = a_in[i,j] + offset[i,j] for the
 * 2 x 3 Float64 arrays (row-major, as FMI 3.0 serializes arrays).
 * Generators: x (Float64 [2], states) with der(x) = rates; count8 (Int8) = count8_start + the number
 * of time events k * period so far, wrapping as an Int8 does (127 + 1 = -128); ramp32 (Float32) =
 * (float)(slope * time); tick_text (String) = "<greeting> <count8>" (greeting a String parameter,
 * "tick"); tick_bytes (Binary) = count8 as a byte followed by tag (a Binary parameter, {0xA5}).
 * Every get/set checks its value references, types and nValues (the number of values of all
 * arrays), as FMI 3.0 asks; an array is set and got whole. */
#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "fmi3Functions.h"

#define TOKEN "{c0a7e1f2-3003-4000-8000-000000000003}"
enum {
    TIME, F32_IN, F32_OUT, F64_IN, F64_OUT, I8_IN, I8_OUT, U8_IN, U8_OUT, I16_IN, I16_OUT, U16_IN, U16_OUT,
    I32_IN, I32_OUT, U32_IN, U32_OUT, I64_IN, I64_OUT, U64_IN, U64_OUT, BOOL_IN, BOOL_OUT, STR_IN, STR_OUT,
    BIN_IN, BIN_OUT, ENUM_IN, ENUM_OUT, A_IN, A_OUT, OFFSET, X, DER_X, RATES, PERIOD, COUNT8, COUNT8_START,
    RAMP32, SLOPE, TICK_TEXT, TICK_BYTES, GREETING, TAG, N_VR
};
typedef enum { F32, F64, I8, U8, I16, U16, I32, U32, I64, U64, BOOL, STR, BIN } Kind;
/* each value reference: its kind, its number of elements and its first slot in the kind's storage */
static const struct { Kind kind; int size; int slot; bool settable; } VR[N_VR] = {
    [TIME] = {F64, 1, 0, false}, [F32_IN] = {F32, 1, 0, true}, [F32_OUT] = {F32, 1, 1, false},
    [F64_IN] = {F64, 1, 1, true}, [F64_OUT] = {F64, 1, 2, false}, [I8_IN] = {I8, 1, 0, true},
    [I8_OUT] = {I8, 1, 1, false}, [U8_IN] = {U8, 1, 0, true}, [U8_OUT] = {U8, 1, 1, false},
    [I16_IN] = {I16, 1, 0, true}, [I16_OUT] = {I16, 1, 1, false}, [U16_IN] = {U16, 1, 0, true},
    [U16_OUT] = {U16, 1, 1, false}, [I32_IN] = {I32, 1, 0, true}, [I32_OUT] = {I32, 1, 1, false},
    [U32_IN] = {U32, 1, 0, true}, [U32_OUT] = {U32, 1, 1, false}, [I64_IN] = {I64, 1, 0, true},
    [I64_OUT] = {I64, 1, 1, false}, [U64_IN] = {U64, 1, 0, true}, [U64_OUT] = {U64, 1, 1, false},
    [BOOL_IN] = {BOOL, 1, 0, true}, [BOOL_OUT] = {BOOL, 1, 1, false}, [STR_IN] = {STR, 1, 0, true},
    [STR_OUT] = {STR, 1, 1, false}, [BIN_IN] = {BIN, 1, 0, true}, [BIN_OUT] = {BIN, 1, 1, false},
    [ENUM_IN] = {I64, 1, 2, true}, [ENUM_OUT] = {I64, 1, 3, false}, [A_IN] = {F64, 6, 3, true},
    [A_OUT] = {F64, 6, 9, false}, [OFFSET] = {F64, 6, 15, true}, [X] = {F64, 2, 21, false},
    [DER_X] = {F64, 2, 23, false}, [RATES] = {F64, 2, 25, true}, [PERIOD] = {F64, 1, 27, true},
    [COUNT8] = {I8, 1, 2, false}, [COUNT8_START] = {I8, 1, 3, true}, [RAMP32] = {F32, 1, 2, false},
    [SLOPE] = {F32, 1, 3, true}, [TICK_TEXT] = {STR, 1, 2, false}, [TICK_BYTES] = {BIN, 1, 2, false},
    [GREETING] = {STR, 1, 3, true}, [TAG] = {BIN, 1, 3, true},
};
#define MAX_BINARY 64

typedef struct {
    float f32[4];
    double f64[28];
    int8_t i8[4];
    uint8_t u8[2];
    int16_t i16[2];
    uint16_t u16[2];
    int32_t i32[2];
    uint32_t u32[2];
    int64_t i64[4];
    uint64_t u64[2];
    bool b[2];
    char str[4][64];
    uint8_t bin[4][MAX_BINARY];
    size_t bin_size[4];
    double time, next_event;
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
} Instance;

#define M ((Instance *)instance)

static void log_error(Instance *m, const char *message) {
    if (m->log) m->log(m->env, fmi3Error, "logStatusError", message);
}

static void set_starts(Instance *m) {
    static const double offset[6] = {11, 12, 13, 21, 22, 23};
    memset(m, 0, offsetof(Instance, time));
    for (int k = 0; k < 6; k++) m->f64[VR[OFFSET].slot + k] = offset[k];
    m->f64[VR[RATES].slot] = 1.0;
    m->f64[VR[RATES].slot + 1] = -0.5;
    m->f64[VR[PERIOD].slot] = 0.25;
    m->i8[VR[COUNT8_START].slot] = 120;
    m->f32[VR[SLOPE].slot] = 0.1f;
    m->i64[VR[ENUM_IN].slot] = 1;
    strcpy(m->str[0], "none");
    m->bin[0][0] = 0xA5;
    m->bin_size[0] = 1;
    strcpy(m->str[3], "tick");
    m->bin[3][0] = 0xA5;
    m->bin_size[3] = 1;
    m->next_event = INFINITY;
}

/* every output from the inputs, parameters, states and time */
static void outputs(Instance *m) {
    m->f64[0] = m->time;
    m->f32[1] = m->f32[0];
    m->f64[2] = m->f64[1];
    m->i8[1] = m->i8[0];
    m->u8[1] = m->u8[0];
    m->i16[1] = m->i16[0];
    m->u16[1] = m->u16[0];
    m->i32[1] = m->i32[0];
    m->u32[1] = m->u32[0];
    m->i64[1] = m->i64[0];
    m->u64[1] = m->u64[0];
    m->b[1] = m->b[0];
    strcpy(m->str[1], m->str[0]);
    memcpy(m->bin[1], m->bin[0], m->bin_size[0]);
    m->bin_size[1] = m->bin_size[0];
    m->i64[VR[ENUM_OUT].slot] = m->i64[VR[ENUM_IN].slot];
    for (int k = 0; k < 6; k++) m->f64[VR[A_OUT].slot + k] = m->f64[VR[A_IN].slot + k] + m->f64[VR[OFFSET].slot + k];
    for (int k = 0; k < 2; k++) m->f64[VR[DER_X].slot + k] = m->f64[VR[RATES].slot + k];
    m->f32[VR[RAMP32].slot] = (float)((double)m->f32[VR[SLOPE].slot] * m->time);
    int8_t count = m->i8[VR[COUNT8].slot];
    snprintf(m->str[2], sizeof m->str[2], "%.40s %d", m->str[3], (int)count);
    m->bin[2][0] = (uint8_t)count;
    memcpy(m->bin[2] + 1, m->bin[3], m->bin_size[3] < MAX_BINARY ? m->bin_size[3] : MAX_BINARY - 1);
    m->bin_size[2] = 1 + (m->bin_size[3] < MAX_BINARY ? m->bin_size[3] : MAX_BINARY - 1);
}

/* a value reference's storage check: known, of the kind, settable when setting; counts its values */
static bool check(Instance *m, const fmi3ValueReference vr[], size_t n, size_t nv, Kind kind, bool set) {
    size_t values = 0;
    for (size_t k = 0; k < n; k++) {
        if (vr[k] >= N_VR || VR[vr[k]].kind != kind || (set && !VR[vr[k]].settable)) {
            log_error(m, "bad value reference (unknown, of another type, or not settable)");
            return false;
        }
        values += (size_t)VR[vr[k]].size;
    }
    if (values != nv) {
        log_error(m, "nValues is not the number of values of the variables");
        return false;
    }
    return true;
}

#define ACCESS(TYPE, KIND, FIELD)                                                                            \
    FMI3_Export fmi3Status fmi3Get##TYPE(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,     \
                                         fmi3##TYPE values[], size_t nv) {                                   \
        if (!check(M, vr, n, nv, KIND, false)) return fmi3Error;                                             \
        outputs(M);                                                                                          \
        size_t j = 0;                                                                                        \
        for (size_t k = 0; k < n; k++)                                                                       \
            for (int e = 0; e < VR[vr[k]].size; e++) values[j++] = M->FIELD[VR[vr[k]].slot + e];             \
        return fmi3OK;                                                                                       \
    }                                                                                                        \
    FMI3_Export fmi3Status fmi3Set##TYPE(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,     \
                                         const fmi3##TYPE values[], size_t nv) {                             \
        if (!check(M, vr, n, nv, KIND, true)) return fmi3Error;                                              \
        size_t j = 0;                                                                                        \
        for (size_t k = 0; k < n; k++)                                                                       \
            for (int e = 0; e < VR[vr[k]].size; e++) M->FIELD[VR[vr[k]].slot + e] = values[j++];             \
        return fmi3OK;                                                                                       \
    }
ACCESS(Float32, F32, f32)
ACCESS(Float64, F64, f64)
ACCESS(Int8, I8, i8)
ACCESS(UInt8, U8, u8)
ACCESS(Int16, I16, i16)
ACCESS(UInt16, U16, u16)
ACCESS(Int32, I32, i32)
ACCESS(UInt32, U32, u32)
ACCESS(Int64, I64, i64)
ACCESS(UInt64, U64, u64)
ACCESS(Boolean, BOOL, b)

FMI3_Export fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                                     fmi3String values[], size_t nv) {
    if (!check(M, vr, n, nv, STR, false)) return fmi3Error;
    outputs(M);
    for (size_t k = 0; k < n; k++) values[k] = M->str[VR[vr[k]].slot];
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                                     const fmi3String values[], size_t nv) {
    if (!check(M, vr, n, nv, STR, true)) return fmi3Error;
    for (size_t k = 0; k < n; k++) {
        if (!values[k] || strlen(values[k]) >= sizeof M->str[0]) { log_error(M, "String too long"); return fmi3Error; }
        strcpy(M->str[VR[vr[k]].slot], values[k]);
    }
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                                     size_t sizes[], fmi3Binary values[], size_t nv) {
    if (!check(M, vr, n, nv, BIN, false)) return fmi3Error;
    outputs(M);
    for (size_t k = 0; k < n; k++) {
        values[k] = M->bin[VR[vr[k]].slot];
        sizes[k] = M->bin_size[VR[vr[k]].slot];
    }
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t n,
                                     const size_t sizes[], const fmi3Binary values[], size_t nv) {
    if (!check(M, vr, n, nv, BIN, true)) return fmi3Error;
    for (size_t k = 0; k < n; k++) {
        if (sizes[k] > MAX_BINARY || (sizes[k] && !values[k])) { log_error(M, "Binary too long"); return fmi3Error; }
        memcpy(M->bin[VR[vr[k]].slot], values[k], sizes[k]);
        M->bin_size[VR[vr[k]].slot] = sizes[k];
    }
    return fmi3OK;
}

FMI3_Export const char *fmi3GetVersion(void) { return fmi3Version; }
FMI3_Export fmi3Status fmi3SetDebugLogging(fmi3Instance i, fmi3Boolean on, size_t n, const fmi3String c[]) {
    (void)i; (void)on; (void)n; (void)c;
    return fmi3OK;
}
FMI3_Export fmi3Instance fmi3InstantiateModelExchange(fmi3String name, fmi3String token, fmi3String resources,
                                                      fmi3Boolean visible, fmi3Boolean logging,
                                                      fmi3InstanceEnvironment env, fmi3LogMessageCallback log) {
    (void)name; (void)resources; (void)visible; (void)logging;
    if (strcmp(token, TOKEN) != 0) {
        if (log) log(env, fmi3Error, "logStatusError", "wrong instantiation token");
        return NULL;
    }
    Instance *m = calloc(1, sizeof(Instance));
    if (!m) return NULL;
    set_starts(m);
    m->env = env;
    m->log = log;
    return m;
}
FMI3_Export void fmi3FreeInstance(fmi3Instance instance) { free(instance); }
FMI3_Export fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean td, fmi3Float64 tol,
                                                   fmi3Float64 start, fmi3Boolean sd, fmi3Float64 stop) {
    (void)td; (void)tol; (void)sd; (void)stop;
    M->time = start;
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    M->i8[VR[COUNT8].slot] = M->i8[VR[COUNT8_START].slot];
    M->next_event = M->time + M->f64[VR[PERIOD].slot];
    outputs(M);
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3EnterEventMode(fmi3Instance instance) { (void)instance; return fmi3OK; }
FMI3_Export fmi3Status fmi3Terminate(fmi3Instance instance) { (void)instance; return fmi3OK; }
FMI3_Export fmi3Status fmi3Reset(fmi3Instance instance) {
    fmi3InstanceEnvironment env = M->env;
    fmi3LogMessageCallback log = M->log;
    set_starts(M);
    M->env = env;
    M->log = log;
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *need, fmi3Boolean *terminate,
                                                fmi3Boolean *nominals, fmi3Boolean *values, fmi3Boolean *defined,
                                                fmi3Float64 *next) {
    if (M->time >= M->next_event - 1e-9) {
        M->i8[VR[COUNT8].slot] = (int8_t)(uint8_t)((uint8_t)M->i8[VR[COUNT8].slot] + 1u); /* wraps: 127 + 1 = -128 */
        M->next_event += M->f64[VR[PERIOD].slot];
    }
    outputs(M);
    *need = false;
    *terminate = false;
    *nominals = false;
    *values = false;
    *defined = true;
    *next = M->next_event;
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) { (void)instance; return fmi3OK; }
FMI3_Export fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean nosave, fmi3Boolean *enter,
                                                   fmi3Boolean *terminate) {
    (void)instance; (void)nosave;
    *enter = false;
    *terminate = false;
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 t) { M->time = t; return fmi3OK; }
FMI3_Export fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[], size_t n) {
    if (n != 2) return fmi3Error;
    for (size_t k = 0; k < n; k++) M->f64[VR[X].slot + k] = x[k];
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    if (n != 2) return fmi3Error;
    for (size_t k = 0; k < n; k++) x[k] = M->f64[VR[X].slot + k];
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 dx[], size_t n) {
    if (n != 2) return fmi3Error;
    outputs(M);
    for (size_t k = 0; k < n; k++) dx[k] = M->f64[VR[DER_X].slot + k];
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 z[], size_t n) {
    (void)instance; (void)z;
    return n == 0 ? fmi3OK : fmi3Error;
}
FMI3_Export fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t n) {
    (void)instance;
    for (size_t k = 0; k < n; k++) x[k] = 1.0;
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *n) {
    (void)instance;
    *n = 0;
    return fmi3OK;
}
FMI3_Export fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *n) {
    (void)instance;
    *n = 2;
    return fmi3OK;
}
