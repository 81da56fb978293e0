/*
 * Switch -- a Boolean mode switched on state events (a relay with hysteresis).
 *   der(x) = on ? up : -down; when on and x reaches high: on := false; when off and x
 *   reaches 0: on := true; switches counts the changes (Integer output).
 *   From x = 0, on: x = high at t = high/up, 0 again high/down later, and so on.
 */
#define MODEL_GUID "{c0a7e1f2-0003-4000-8000-000000000003}"
#define N_VARS 7
#define N_STATES 1
#define N_INDICATORS 1
#include "mini_fmu.h"

enum { X, DER_X, ON, SWITCHES, UP, DOWN, HIGH };
static const Var VARS[N_VARS] = {
    {"x", T_REAL, K_STATE, 0}, {"der(x)", T_REAL, K_CALC, 0}, {"on", T_BOOLEAN, K_CALC, 1},
    {"switches", T_INTEGER, K_CALC, 0}, {"up", T_REAL, K_PARAM, 1.0}, {"down", T_REAL, K_PARAM, 2.0},
    {"high", T_REAL, K_PARAM, 1.0}};
static const fmi2ValueReference STATES[N_STATES] = {X};

#define TOL 1e-7

static void model_initialize(Instance *m) { (void)m; }

static void model_outputs(Instance *m) { m->v[DER_X] = m->v[ON] != 0.0 ? m->v[UP] : -m->v[DOWN]; }

static int model_derivatives(Instance *m, double *dx)
{
    dx[0] = m->v[DER_X];
    return 0;
}

static void model_indicators(Instance *m, double *z)
{
    z[0] = m->v[ON] != 0.0 ? m->v[HIGH] - m->v[X] : m->v[X];
}

static void model_event(Instance *m, fmi2EventInfo *info)
{
    (void)info;
    if (m->v[ON] != 0.0 && m->v[X] >= m->v[HIGH] - TOL) {
        m->v[ON] = 0.0;
        m->v[SWITCHES] += 1.0;
        logf_(m, fmi2OK, "t = %.9g: off", m->time);
    } else if (m->v[ON] == 0.0 && m->v[X] <= TOL) {
        m->v[ON] = 1.0;
        m->v[SWITCHES] += 1.0;
        logf_(m, fmi2OK, "t = %.9g: on", m->time);
    }
}
