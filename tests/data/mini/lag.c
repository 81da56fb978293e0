/*
 * Lag -- a first-order lag T dy/dt = u - y (y: its state and output, no direct feedthrough) and the
 * lag error e = u - y (direct feedthrough of u). Exported for both Model Exchange and Co-Simulation
 * (fmi2DoStep in mini_fmu.h: fixed-step RK4 inside): the tests' CS FMU and its ME twin. For a ramp
 * input u = a t from y(0) = 0: y(t) = a (t - T (1 - exp(-t / T))).
 */
#define MODEL_GUID "{c0a7e1f2-0007-4000-8000-000000000007}"
#define N_VARS 5
#define N_STATES 1
#define N_INDICATORS 0
#include "mini_fmu.h"

enum { U, Y, E, DER_Y, T };
static const Var VARS[N_VARS] = {
    {"u", T_REAL, K_CIN, 0}, {"y", T_REAL, K_STATE, 0}, {"e", T_REAL, K_CALC, 0},
    {"der(y)", T_REAL, K_CALC, 0}, {"T", T_REAL, K_PARAM, 0.5}};
static const fmi2ValueReference STATES[N_STATES] = {Y};

static void model_initialize(Instance *m) { (void)m; }

static void model_outputs(Instance *m)
{
    m->v[E] = m->v[U] - m->v[Y];
    m->v[DER_Y] = m->v[E] / m->v[T];
}

static int model_derivatives(Instance *m, double *dx)
{
    dx[0] = m->v[DER_Y];
    return 0;
}

static void model_indicators(Instance *m, double *z) { (void)m; (void)z; }

static void model_event(Instance *m, fmi2EventInfo *info) { (void)m; (void)info; }
