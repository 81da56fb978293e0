/*
 * Rescale -- a decaying state whose nominal changes at a time event.
 *   der(x) = -x; time events every `period` s; at the first one at or after t_switch the nominal
 *   of x becomes `small` and fmi2NewDiscreteStates says nominalsOfContinuousStatesChanged (at
 *   no other event). `nominal_reads` counts the calls of fmi2GetNominalsOfContinuousStates.
 */
#define MODEL_GUID "{c0a7e1f2-0005-4000-8000-000000000005}"
#define N_VARS 7
#define N_STATES 1
#define N_INDICATORS 0
#define MODEL_NOMINALS
#include "mini_fmu.h"

enum { X, DER_X, PERIOD, T_SWITCH, SMALL, READS, SWITCHED };
static const Var VARS[N_VARS] = {
    {"x", T_REAL, K_STATE, 1.0}, {"der(x)", T_REAL, K_CALC, 0}, {"period", T_REAL, K_PARAM, 0.25},
    {"t_switch", T_REAL, K_PARAM, 1.0}, {"small", T_REAL, K_PARAM, 1e-4},
    {"nominal_reads", T_INTEGER, K_CALC, 0}, {"switched", T_BOOLEAN, K_CALC, 0}};
static const fmi2ValueReference STATES[N_STATES] = {X};

#define EPS 1e-9

static void schedule(Instance *m) { m->next_event = (floor(m->time / m->v[PERIOD] + EPS) + 1.0) * m->v[PERIOD]; }

static void model_initialize(Instance *m) { schedule(m); }

static void model_outputs(Instance *m) { m->v[DER_X] = -m->v[X]; }

static int model_derivatives(Instance *m, double *dx)
{
    dx[0] = -m->v[X];
    return 0;
}

static void model_indicators(Instance *m, double *z) { (void)m; (void)z; }

static void model_event(Instance *m, fmi2EventInfo *info)
{
    if (m->v[SWITCHED] == 0.0 && m->time >= m->v[T_SWITCH] - EPS) {
        m->v[SWITCHED] = 1.0;
        info->nominalsOfContinuousStatesChanged = fmi2True;
        logf_(m, fmi2OK, "t = %g: the nominal of x is now %g", m->time, m->v[SMALL]);
    }
    schedule(m);
}

static void model_nominals(Instance *m, double *nominals)
{
    m->v[READS] += 1.0;
    nominals[0] = m->v[SWITCHED] != 0.0 ? m->v[SMALL] : 1.0;
}
