/*
 * Counter -- an Integer output with time events that asks to terminate at t_stop.
 *   every `period` s (time events): ticks += 1, count += step (when `enabled`)
 *   der(x) = count + rate (x: continuous state and output), half = count / 2 (discrete Real output),
 *   even = count is even (Boolean output); at t >= t_stop: terminateSimulation.
 */
#define MODEL_GUID "{c0a7e1f2-0001-4000-8000-000000000001}"
#define N_VARS 11
#define N_STATES 1
#define N_INDICATORS 0
#include "mini_fmu.h"

enum { COUNT, X, DER_X, PERIOD, T_STOP, HALF, EVEN, STEP, ENABLED, TICKS, RATE };
static const Var VARS[N_VARS] = {
    {"count", T_INTEGER, K_CALC, 0}, {"x", T_REAL, K_STATE, 0}, {"der(x)", T_REAL, K_CALC, 0},
    {"period", T_REAL, K_PARAM, 1.0}, {"t_stop", T_REAL, K_PARAM, 9.0}, {"half", T_REAL, K_CALC, 0},
    {"even", T_BOOLEAN, K_CALC, 1}, {"step", T_INTEGER, K_PARAM, 1}, {"enabled", T_BOOLEAN, K_PARAM, 1},
    {"ticks", T_INTEGER, K_CALC, 0}, {"rate", T_REAL, K_PARAM, 0}};
static const fmi2ValueReference STATES[N_STATES] = {X};

#define EPS 1e-9

static void schedule(Instance *m)
{
    double tick = (m->v[TICKS] + 1.0) * m->v[PERIOD];
    m->next_event = tick < m->v[T_STOP] ? tick : m->v[T_STOP];
}

static void model_initialize(Instance *m) { schedule(m); }

static void model_outputs(Instance *m)
{
    m->v[DER_X] = m->v[COUNT] + m->v[RATE];
    m->v[HALF] = m->v[COUNT] / 2.0;
    m->v[EVEN] = fmod(m->v[COUNT], 2.0) == 0.0;
}

static int model_derivatives(Instance *m, double *dx)
{
    dx[0] = m->v[COUNT] + m->v[RATE];
    return 0;
}

static void model_indicators(Instance *m, double *z) { (void)m; (void)z; }

static void model_event(Instance *m, fmi2EventInfo *info)
{
    if (m->time >= (m->v[TICKS] + 1.0) * m->v[PERIOD] - EPS) {
        m->v[TICKS] += 1.0;
        if (m->v[ENABLED] != 0.0) m->v[COUNT] += m->v[STEP];
        logf_(m, fmi2OK, "t = %g: tick %g, count = %g", m->time, m->v[TICKS], m->v[COUNT]);
    }
    if (m->time >= m->v[T_STOP] - EPS) {
        info->terminateSimulation = fmi2True;
        logf_(m, fmi2OK, "t = %g: t_stop reached, asking to terminate", m->time);
    }
    schedule(m);
}
