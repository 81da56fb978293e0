/*
 * Faulty -- misbehaves on request inside fmi2GetDerivatives once time >= t_fault (for the tests of
 * supervised runs, issue 22): der(x) = 1 (x: its time since the start) until then, and then by
 * `fault`: 0 none, 1 SIGSEGV (a write through a null pointer), 2 abort(), 3 exit(0), 4 exit(3),
 * 5 hang (an endless loop that calls nothing). A time event every `period` s makes the master stop
 * (and hand its rows on) regularly.
 */
#define MODEL_GUID "{c0a7e1f2-0006-4000-8000-000000000006}"
#define N_VARS 5
#define N_STATES 1
#define N_INDICATORS 0
#include "mini_fmu.h"

enum { X, DER_X, FAULT, T_FAULT, PERIOD };
static const Var VARS[N_VARS] = {
    {"x", T_REAL, K_STATE, 0}, {"der(x)", T_REAL, K_CALC, 1.0}, {"fault", T_INTEGER, K_PARAM, 0},
    {"t_fault", T_REAL, K_PARAM, 1.0}, {"period", T_REAL, K_PARAM, 0.5}};
static const fmi2ValueReference STATES[N_STATES] = {X};

static void model_initialize(Instance *m) { m->next_event = m->v[PERIOD]; }

static void model_outputs(Instance *m) { m->v[DER_X] = 1.0; }

static volatile int *nowhere = NULL;
static volatile unsigned long spins = 0;

static int model_derivatives(Instance *m, double *dx)
{
    if (m->mode == M_CONT && m->time >= m->v[T_FAULT]) {
        switch ((int)m->v[FAULT]) {
        case 1: *nowhere = 1; break;
        case 2: abort();
        case 3: exit(0);
        case 4: exit(3);
        case 5: for (;;) spins++;
        default: break;
        }
    }
    dx[0] = m->v[DER_X];
    return 0;
}

static void model_indicators(Instance *m, double *z) { (void)m; (void)z; }

static void model_event(Instance *m, fmi2EventInfo *info)
{
    (void)info;
    while (m->next_event <= m->time + 1e-9) m->next_event += m->v[PERIOD];
}
