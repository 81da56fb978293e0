/*
 * PassThrough -- copies a continuous, a discrete Real, an Integer and a Boolean input to
 * outputs (direct feedthrough) and integrates the continuous one: der(integral) = u_c.
 * The discrete inputs may only be set in initialization or event mode (fmi2Error otherwise).
 * fmi2GetDerivatives fails (fmi2Error with a message) once |u_c| > u_max.
 */
#define MODEL_GUID "{c0a7e1f2-0002-4000-8000-000000000002}"
#define N_VARS 11
#define N_STATES 1
#define N_INDICATORS 0
#include "mini_fmu.h"

enum { U_C, U_D, U_I, U_B, Y_C, Y_D, Y_I, Y_B, INTEGRAL, DER_INTEGRAL, U_MAX };
static const Var VARS[N_VARS] = {
    {"u_c", T_REAL, K_CIN, 0}, {"u_d", T_REAL, K_DIN, 0}, {"u_i", T_INTEGER, K_DIN, 0},
    {"u_b", T_BOOLEAN, K_DIN, 0}, {"y_c", T_REAL, K_CALC, 0}, {"y_d", T_REAL, K_CALC, 0},
    {"y_i", T_INTEGER, K_CALC, 0}, {"y_b", T_BOOLEAN, K_CALC, 0}, {"integral", T_REAL, K_STATE, 0},
    {"der(integral)", T_REAL, K_CALC, 0}, {"u_max", T_REAL, K_PARAM, 1e300}};
static const fmi2ValueReference STATES[N_STATES] = {INTEGRAL};

static void model_initialize(Instance *m) { (void)m; }

static void model_outputs(Instance *m)
{
    m->v[Y_C] = m->v[U_C];
    m->v[Y_D] = m->v[U_D];
    m->v[Y_I] = m->v[U_I];
    m->v[Y_B] = m->v[U_B];
    m->v[DER_INTEGRAL] = m->v[U_C];
}

static int model_derivatives(Instance *m, double *dx)
{
    if (fabs(m->v[U_C]) > m->v[U_MAX]) {
        logf_(m, fmi2Error, "u_c = %.6f exceeds u_max = %g at t = %.6f", m->v[U_C], m->v[U_MAX], m->time);
        return 1;
    }
    dx[0] = m->v[U_C];
    return 0;
}

static void model_indicators(Instance *m, double *z) { (void)m; (void)z; }

static void model_event(Instance *m, fmi2EventInfo *info) { (void)m; (void)info; }
