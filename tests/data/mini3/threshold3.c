/* Threshold3 (FMI 3.0 Model Exchange): a first-order lag tau dy/dt = u - y (u a Float64 input,
 * y a Float64 output and state, y(0) = y0) with a state event where y crosses level: above
 * (Boolean output) says y has reached level from below (and not fallen back to it), crossings (Int32 output) counts the crossings.
 * For u = 1, y0 = 0: y = 1 - exp(-t / tau), the crossing at t = tau ln(1 / (1 - level)). */
#define MODEL_TOKEN "{c0a7e1f2-3002-4000-8000-000000000002}"
#define N_VARS 10
#define N_STATES 1
#define N_INDICATORS 1
#include "mini3_fmu.h"

enum { TIME, U, Y, DER_Y, ABOVE, CROSSINGS, TAU, LEVEL, Y0, Z };
static const Var VARS[N_VARS] = {{T_F64, 0}, {T_F64, 1.0}, {T_F64, 0}, {T_F64, 0}, {T_BOOL, 0},
                                 {T_I32, 0}, {T_F64, 0.5}, {T_F64, 0.5}, {T_F64, 0.0}, {T_F64, 0}};
static const fmi3ValueReference STATES[1] = {Y};

static void model_initialize(Instance *m) { m->v[Y] = m->v[Y0]; m->v[ABOVE] = m->v[Y] > m->v[LEVEL]; }
static void model_outputs(Instance *m) { m->v[TIME] = m->time; m->v[DER_Y] = (m->v[U] - m->v[Y]) / m->v[TAU]; m->v[Z] = m->v[Y] - m->v[LEVEL]; }
static void model_derivatives(Instance *m, double *dx) { dx[0] = m->v[DER_Y]; }
static void model_indicators(Instance *m, double *z) { z[0] = m->v[Y] - m->v[LEVEL]; }
static void model_event(Instance *m)
{
    /* at the event y may sit on the level itself (z = 0): reaching it is the up-crossing, falling
     * below it the down-crossing (so a repeated event iteration at y = level changes nothing) */
    bool was_above = m->v[ABOVE] != 0.0;
    if (was_above ? m->v[Y] < m->v[LEVEL] : m->v[Y] >= m->v[LEVEL]) {
        m->v[ABOVE] = !was_above;
        m->v[CROSSINGS] += 1;
    }
}
