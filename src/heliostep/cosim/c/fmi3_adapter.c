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
 */
#include <stdbool.h>
#include <stddef.h>

#define HS3_MAX_BOOLEANS 256

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
} hs3_adapter;

#define A ((hs3_adapter *)adapter)

int hs3_set_time(void *adapter, double t) { return A->set_time(A->instance, t); }
int hs3_set_states(void *adapter, const double *x, size_t n) { return A->set_states(A->instance, x, n); }
int hs3_get_states(void *adapter, double *x, size_t n) { return A->get_states(A->instance, x, n); }
int hs3_get_derivatives(void *adapter, double *dx, size_t n) { return A->get_derivatives(A->instance, dx, n); }
int hs3_get_event_indicators(void *adapter, double *z, size_t n) {
    return A->get_event_indicators(A->instance, z, n);
}
int hs3_get_real(void *adapter, const unsigned int *vrs, size_t n, double *v) {
    return A->get_float64(A->instance, vrs, n, v, n);
}
int hs3_set_real(void *adapter, const unsigned int *vrs, size_t n, const double *v) {
    return A->set_float64(A->instance, vrs, n, v, n);
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
