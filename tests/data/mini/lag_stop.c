/*
 * LagStop -- the Lag (lag.c: T dy/dt = u - y, e = u - y) as an FMI 2.0 Co-Simulation slave that stops
 * at t_stop: the step that would pass t_stop integrates up to it and returns fmi2Discard, and the slave
 * then says fmi2Terminated (if says_terminated is 1) with fmi2LastSuccessfulTime = t_stop, as FMI 2.0
 * (section 4.2.3) has a slave ask to end the simulation. With says_terminated = 0 the step is only
 * discarded. Exported for Model Exchange too (no stop there).
 */
#define MODEL_GUID "{c0a7e1f2-0008-4000-8000-000000000008}"
#define N_VARS 7
#define N_STATES 1
#define N_INDICATORS 0
#define MINI_CS_STOP(m) ((m)->v[5]) /* t_stop (the header comes before the enum below) */
#define MINI_CS_SAYS_TERMINATED(m) ((m)->v[6] != 0.0) /* says_terminated */
#include "mini_fmu.h"

enum { U, Y, E, DER_Y, T, T_STOP, SAYS_TERMINATED };
static const Var VARS[N_VARS] = {
    {"u", T_REAL, K_CIN, 0},     {"y", T_REAL, K_STATE, 0},      {"e", T_REAL, K_CALC, 0},
    {"der(y)", T_REAL, K_CALC, 0}, {"T", T_REAL, K_PARAM, 0.5}, {"t_stop", T_REAL, K_PARAM, 1e300},
    {"says_terminated", T_INTEGER, K_PARAM, 1}};
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
