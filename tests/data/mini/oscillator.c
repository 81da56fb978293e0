/*
 * Oscillator -- a mass on a spring and damper to the wall, pushed by an input force F, and the force
 * F_c of a coupling spring and damper to another mass at x_in, v_in (direct feedthrough of x_in and
 * v_in), which it feels too:
 *
 *     dx/dt = v,   m dv/dt = -c x - d v + F - F_c,   F_c = c_c (x - x_in) + d_c (v - v_in).
 *
 * Two instances split a two-mass oscillator into two FMUs (the first with c_c = d_c = 0, pushed by the
 * second's F_c; the second reading the first's x and v): the Co-Simulation system the benchmark and the
 * libcosim oracle run. Exported for Model Exchange and Co-Simulation (fmi2DoStep in mini_fmu.h: fixed-step
 * RK4 inside, the inputs held). x starts at x0.
 */
#define MODEL_GUID "{c0a7e1f2-0009-4000-8000-000000000009}"
#define N_VARS 14
#define N_STATES 2
#define N_INDICATORS 0
#include "mini_fmu.h"

enum { F, X_IN, V_IN, X, V, F_C, DER_X, DER_V, M, C, D, C_C, D_C, X0 };
static const Var VARS[N_VARS] = {
    {"F", T_REAL, K_CIN, 0},      {"x_in", T_REAL, K_CIN, 0},  {"v_in", T_REAL, K_CIN, 0},
    {"x", T_REAL, K_STATE, 0},    {"v", T_REAL, K_STATE, 0},   {"F_c", T_REAL, K_CALC, 0},
    {"der(x)", T_REAL, K_CALC, 0}, {"der(v)", T_REAL, K_CALC, 0}, {"m", T_REAL, K_PARAM, 1.0},
    {"c", T_REAL, K_PARAM, 100.0}, {"d", T_REAL, K_PARAM, 0.0}, {"c_c", T_REAL, K_PARAM, 0.0},
    {"d_c", T_REAL, K_PARAM, 0.0}, {"x0", T_REAL, K_PARAM, 0.0}};
static const fmi2ValueReference STATES[N_STATES] = {X, V};

static void model_initialize(Instance *m) { m->v[X] = m->v[X0]; }

static void model_outputs(Instance *m)
{
    m->v[F_C] = m->v[C_C] * (m->v[X] - m->v[X_IN]) + m->v[D_C] * (m->v[V] - m->v[V_IN]);
    m->v[DER_X] = m->v[V];
    m->v[DER_V] = (-m->v[C] * m->v[X] - m->v[D] * m->v[V] + m->v[F] - m->v[F_C]) / m->v[M];
}

static int model_derivatives(Instance *m, double *dx)
{
    dx[0] = m->v[DER_X];
    dx[1] = m->v[DER_V];
    return 0;
}

static void model_indicators(Instance *m, double *z) { (void)m; (void)z; }

static void model_event(Instance *m, fmi2EventInfo *info) { (void)m; (void)info; }
