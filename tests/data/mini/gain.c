/*
 * Gain -- direct feedthrough y = k*u + b (continuous), and der(s) = y (s: its integral); in full
 * y = k*u + b + a*u*u + c, the quadratic term (parameter a) and the input c adding nothing at 0.
 * Two Gains connected both ways form an algebraic loop with the closed-form solution
 * u1 = (k2*b1 + b2) / (1 - k1*k2); a quadratic one fed back through a linear one a non-linear loop.
 */
#define MODEL_GUID "{c0a7e1f2-0004-4000-8000-000000000004}"
#define N_VARS 8
#define N_STATES 1
#define N_INDICATORS 0
#include "mini_fmu.h"

enum { U, Y, K, B, S, DER_S, A, C };
static const Var VARS[N_VARS] = {
    {"u", T_REAL, K_CIN, 0}, {"y", T_REAL, K_CALC, 0}, {"k", T_REAL, K_PARAM, 0.5},
    {"b", T_REAL, K_PARAM, 1.0}, {"s", T_REAL, K_STATE, 0}, {"der(s)", T_REAL, K_CALC, 0},
    {"a", T_REAL, K_PARAM, 0}, {"c", T_REAL, K_CIN, 0}};
static const fmi2ValueReference STATES[N_STATES] = {S};

static void model_initialize(Instance *m) { (void)m; }

static void model_outputs(Instance *m)
{
    m->v[Y] = m->v[K] * m->v[U] + m->v[B] + m->v[A] * m->v[U] * m->v[U] + m->v[C]; /* a = c = 0: k u + b */
    m->v[DER_S] = m->v[Y];
}

static int model_derivatives(Instance *m, double *dx)
{
    dx[0] = m->v[DER_S];
    return 0;
}

static void model_indicators(Instance *m, double *z) { (void)m; (void)z; }

static void model_event(Instance *m, fmi2EventInfo *info) { (void)m; (void)info; }
