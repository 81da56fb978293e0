/* heliostep's FMI 3.0 adapter: FMI 2.0-shaped calls on an FMI 3.0 Model Exchange instance.
 *
 * The compiled kernel (kernel.c) and the master's hot path call every FMU through fmi2-shaped
 * function pointers with one component handle. For an FMI 3.0 instance that handle is an
 * hs3_adapter (the fmi3Instance and its fmi3* functions) and the pointers are the functions
 * below: fmi3GetFloat64/SetFloat64/GetInt32/SetInt32 get their extra nValues (= nvr, scalar
 * variables only), fmi3GetBoolean/SetBoolean their C bool values converted from/to int, and the
 * calls of the same shape in both standards (fmi3SetTime, fmi3SetContinuousStates,
 * fmi3GetContinuousStates, fmi3GetContinuousStateDerivatives, fmi3GetEventIndicators) are
 * passed through. fmi3Status has fmi2Status's codes (OK 0 ... Fatal 4). One kernel serves both.
 *
 * Slots (heliostep.cosim.fmi3_types): every FMI 3.0 variable the master exchanges that is not a
 * Float64, Int32 or Boolean scalar (an array element, a Float32, an Int8 ... UInt64, an
 * enumeration) has a value reference of the master's own at or past slot_base; hs3_get_real and
 * hs3_set_real resolve it through the slot table (type code, FMI 3.0 value reference, element,
 * array size) to the typed fmi3Get/fmi3Set call, the element converted to or from a double (an
 * array is got whole, and set whole with its other elements as they were). A call with no slot
 * goes straight to fmi3GetFloat64/fmi3SetFloat64 as before.
 */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define HS3_MAX_BOOLEANS 256
/* type codes: Float64 0, Float32 1, Int8 2, UInt8 3, Int16 4, UInt16 5, Int32 6, UInt32 7, Int64 8,
 * UInt64 9, Boolean 10 (an enumeration is Int64) */
#define HS3_N_TYPES 11

typedef int (*time_t3)(void *, double);
typedef int (*x_in_t3)(void *, const double *, size_t);
typedef int (*x_out_t3)(void *, double *, size_t);
typedef int (*get_f64_t3)(void *, const unsigned int *, size_t, double *, size_t);
typedef int (*set_f64_t3)(void *, const unsigned int *, size_t, const double *, size_t);
typedef int (*get_i32_t3)(void *, const unsigned int *, size_t, int *, size_t);
typedef int (*set_i32_t3)(void *, const unsigned int *, size_t, const int *, size_t);
typedef int (*get_bool_t3)(void *, const unsigned int *, size_t, bool *, size_t);
typedef int (*set_bool_t3)(void *, const unsigned int *, size_t, const bool *, size_t);

typedef struct {
    void *instance;
    time_t3 set_time;
    x_in_t3 set_states;
    x_out_t3 get_states, get_derivatives, get_event_indicators;
    get_f64_t3 get_float64;
    set_f64_t3 set_float64;
    get_i32_t3 get_int32;
    set_i32_t3 set_int32;
    get_bool_t3 get_boolean;
    set_bool_t3 set_boolean;
    unsigned int slot_base;  /* the first slot's value reference */
    size_t n_slots;
    const long long *slots;  /* n_slots rows of (type code, FMI 3.0 value reference, element, size) */
    void *scratch;           /* room for the largest array (8 bytes a value) */
    void *typed_get[HS3_N_TYPES], *typed_set[HS3_N_TYPES]; /* fmi3Get/SetFloat64 ... Boolean by type code */
} hs3_adapter;

#define A ((hs3_adapter *)adapter)

int hs3_set_time(void *adapter, double t) { return A->set_time(A->instance, t); }
int hs3_set_states(void *adapter, const double *x, size_t n) { return A->set_states(A->instance, x, n); }
int hs3_get_states(void *adapter, double *x, size_t n) { return A->get_states(A->instance, x, n); }
int hs3_get_derivatives(void *adapter, double *dx, size_t n) { return A->get_derivatives(A->instance, dx, n); }
int hs3_get_event_indicators(void *adapter, double *z, size_t n) {
    return A->get_event_indicators(A->instance, z, n);
}
typedef int (*typed_t3)(void *, const unsigned int *, size_t, void *, size_t);

static int has_slot(const hs3_adapter *a, const unsigned int *vrs, size_t n) {
    for (size_t k = 0; k < n; k++)
        if (vrs[k] >= a->slot_base) return 1;
    return 0;
}

/* the slot's row, or NULL for an unknown value reference */
static const long long *slot_row(const hs3_adapter *a, unsigned int vr) {
    size_t k = vr - a->slot_base;
    if (k >= a->n_slots || a->slots[4 * k] < 0) return NULL;
    return a->slots + 4 * k;
}

#define ROUNDED(T, LO, HI) ((T)(x < (LO) ? (LO) : x > (HI) ? (HI) : x >= 0 ? x + 0.5 : x - 0.5))

static int slot_get(hs3_adapter *a, unsigned int vr, double *v) {
    const long long *s = slot_row(a, vr);
    if (!s) return 3;
    unsigned int ref = (unsigned int)s[1];
    size_t e = (size_t)s[2];
    int status = ((typed_t3)a->typed_get[s[0]])(a->instance, &ref, 1, a->scratch, (size_t)s[3]);
    if (status > 1) return status;
    switch (s[0]) {
    case 0: *v = ((double *)a->scratch)[e]; break;
    case 1: *v = ((float *)a->scratch)[e]; break;
    case 2: *v = ((int8_t *)a->scratch)[e]; break;
    case 3: *v = ((uint8_t *)a->scratch)[e]; break;
    case 4: *v = ((int16_t *)a->scratch)[e]; break;
    case 5: *v = ((uint16_t *)a->scratch)[e]; break;
    case 6: *v = ((int32_t *)a->scratch)[e]; break;
    case 7: *v = ((uint32_t *)a->scratch)[e]; break;
    case 8: *v = (double)((int64_t *)a->scratch)[e]; break;
    case 9: *v = (double)((uint64_t *)a->scratch)[e]; break;
    default: *v = ((bool *)a->scratch)[e] ? 1.0 : 0.0; break;
    }
    return status;
}

static int slot_set(hs3_adapter *a, unsigned int vr, double x) {
    const long long *s = slot_row(a, vr);
    if (!s) return 3;
    unsigned int ref = (unsigned int)s[1];
    size_t e = (size_t)s[2], size = (size_t)s[3];
    if (size > 1) { /* the array's other elements as they are */
        int status = ((typed_t3)a->typed_get[s[0]])(a->instance, &ref, 1, a->scratch, size);
        if (status > 1) return status;
    }
    switch (s[0]) {
    case 0: ((double *)a->scratch)[e] = x; break;
    case 1: ((float *)a->scratch)[e] = (float)x; break;
    case 2: ((int8_t *)a->scratch)[e] = ROUNDED(int8_t, -128.0, 127.0); break;
    case 3: ((uint8_t *)a->scratch)[e] = ROUNDED(uint8_t, 0.0, 255.0); break;
    case 4: ((int16_t *)a->scratch)[e] = ROUNDED(int16_t, -32768.0, 32767.0); break;
    case 5: ((uint16_t *)a->scratch)[e] = ROUNDED(uint16_t, 0.0, 65535.0); break;
    case 6: ((int32_t *)a->scratch)[e] = ROUNDED(int32_t, -2147483648.0, 2147483647.0); break;
    case 7: ((uint32_t *)a->scratch)[e] = ROUNDED(uint32_t, 0.0, 4294967295.0); break;
    case 8: ((int64_t *)a->scratch)[e] = ROUNDED(int64_t, -9223372036854775808.0, 9223372036854774784.0); break;
    case 9: ((uint64_t *)a->scratch)[e] = ROUNDED(uint64_t, 0.0, 18446744073709549568.0); break;
    default: ((bool *)a->scratch)[e] = x != 0.0; break;
    }
    return ((typed_t3)a->typed_set[s[0]])(a->instance, &ref, 1, a->scratch, size);
}

int hs3_get_real(void *adapter, const unsigned int *vrs, size_t n, double *v) {
    if (!has_slot(A, vrs, n)) return A->get_float64(A->instance, vrs, n, v, n);
    int worst = 0;
    for (size_t k = 0; k < n; k++) {
        int status = vrs[k] < A->slot_base ? A->get_float64(A->instance, vrs + k, 1, v + k, 1)
                                           : slot_get(A, vrs[k], v + k);
        if (status > 1) return status;
        worst = status > worst ? status : worst;
    }
    return worst;
}
int hs3_set_real(void *adapter, const unsigned int *vrs, size_t n, const double *v) {
    if (!has_slot(A, vrs, n)) return A->set_float64(A->instance, vrs, n, v, n);
    int worst = 0;
    for (size_t k = 0; k < n; k++) {
        int status = vrs[k] < A->slot_base ? A->set_float64(A->instance, vrs + k, 1, v + k, 1)
                                           : slot_set(A, vrs[k], v[k]);
        if (status > 1) return status;
        worst = status > worst ? status : worst;
    }
    return worst;
}
int hs3_get_integer(void *adapter, const unsigned int *vrs, size_t n, int *v) {
    return A->get_int32(A->instance, vrs, n, v, n);
}
int hs3_set_integer(void *adapter, const unsigned int *vrs, size_t n, const int *v) {
    return A->set_int32(A->instance, vrs, n, v, n);
}
int hs3_get_boolean(void *adapter, const unsigned int *vrs, size_t n, int *v) {
    bool values[HS3_MAX_BOOLEANS];
    size_t done = 0;
    while (done < n) { /* in chunks: no allocation on the hot path */
        size_t chunk = n - done < HS3_MAX_BOOLEANS ? n - done : HS3_MAX_BOOLEANS;
        int status = A->get_boolean(A->instance, vrs + done, chunk, values, chunk);
        if (status > 1) return status;
        for (size_t i = 0; i < chunk; i++) v[done + i] = values[i] ? 1 : 0;
        done += chunk;
    }
    return 0;
}
int hs3_set_boolean(void *adapter, const unsigned int *vrs, size_t n, const int *v) {
    bool values[HS3_MAX_BOOLEANS];
    size_t done = 0;
    while (done < n) {
        size_t chunk = n - done < HS3_MAX_BOOLEANS ? n - done : HS3_MAX_BOOLEANS;
        for (size_t i = 0; i < chunk; i++) values[i] = v[done + i] != 0;
        int status = A->set_boolean(A->instance, vrs + done, chunk, values, chunk);
        if (status > 1) return status;
        done += chunk;
    }
    return 0;
}
