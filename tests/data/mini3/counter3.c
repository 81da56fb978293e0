/* Counter3 (FMI 3.0 Model Exchange): count (Int32 output) steps by one at the time events
 * k * period; odd (Boolean output) is count's parity; x (Float64 output, state) has
 * der(x) = scale (a Float32 parameter); it asks to terminate at the first event at or after t_stop. */
#define MODEL_TOKEN "{c0a7e1f2-3001-4000-8000-000000000001}"
#define N_VARS 8
#define N_STATES 1
#define N_INDICATORS 0
#include "mini3_fmu.h"

enum { TIME, COUNT, ODD, X, DER_X, PERIOD, T_STOP, SCALE };
static const Var VARS[N_VARS] = {{T_F64, 0}, {T_I32, 0}, {T_BOOL, 0}, {T_F64, 0},
                                 {T_F64, 0}, {T_F64, 1.0}, {T_F64, 4.5}, {T_F32, 1.0}};
static const fmi3ValueReference STATES[1] = {X};

static void model_initialize(Instance *m) { m->next_event = m->time + m->v[PERIOD]; }
static void model_outputs(Instance *m) { m->v[TIME] = m->time; m->v[ODD] = fmod(m->v[COUNT], 2.0) != 0.0; m->v[DER_X] = m->v[SCALE]; }
static void model_derivatives(Instance *m, double *dx) { dx[0] = m->v[SCALE]; }
static void model_indicators(Instance *m, double *z) { (void)m; (void)z; }
static void model_event(Instance *m)
{
    if (m->time >= m->next_event - 1e-9) {
        m->v[COUNT] += 1;
        m->next_event += m->v[PERIOD];
    }
    if (m->time >= m->v[T_STOP] - 1e-9) m->terminate = true;
}
