/* heliostep's compiled co-simulation kernel (see heliostep/cosim/kernel.py).
 *
 * hs_rhs, hs_root: CVODE's right-hand side and root function for N connected Model Exchange
 *   FMUs: set time and states, copy the continuous Real connections in the master's
 *   propagation order, read derivatives or event indicators, all through the FMUs' own fmi2*
 *   function pointers.
 * hs_advance: CVODE in one-step mode up to a stop time, recording a row (time, master inputs,
 *   every FMU's traced outputs) after each internal step and, where asked, at the output times
 *   passed on the way from CVODE's interpolating polynomial (CVodeGetDky), into a buffer the
 *   master drains: the loop over internal steps runs here, not in Python.
 *
 * An FMI status worse than fmi2Warning stops the evaluation: the status, the instance, the
 * function and the time are recorded, and every further evaluation is refused until the master
 * has collected the error.
 */
#include <stddef.h>
#include <math.h>

typedef void *fmi2Component;
typedef int (*set_time_t)(fmi2Component, double);
typedef int (*set_x_t)(fmi2Component, const double *, size_t);
typedef int (*get_x_t)(fmi2Component, double *, size_t);
typedef int (*get_real_t)(fmi2Component, const unsigned int *, size_t, double *);
typedef int (*set_real_t)(fmi2Component, const unsigned int *, size_t, const double *);
typedef int (*get_int_t)(fmi2Component, const unsigned int *, size_t, int *);
typedef double *(*data_t)(void *);
typedef int (*cvode_t)(void *, double, void *, double *, int);
typedef int (*get_dky_t)(void *, double, int, void *);

/* one group of outputs of one FMI type, read into the row at the given columns */
typedef struct {
    long n;
    const unsigned int *vrs;
    const long *columns;
    int *ints; /* buffer for Integer/Enumeration/Boolean values (NULL for Real) */
} hs_outputs;

typedef struct {
    fmi2Component component;
    set_time_t set_time;
    set_x_t set_states;
    get_x_t get_derivatives;
    get_x_t get_event_indicators;
    get_real_t get_real;
    set_real_t set_real;
    get_int_t get_integer;
    get_int_t get_boolean;
    long nx, x_offset, nz, z_offset;
    hs_outputs real_outputs, integer_outputs, boolean_outputs;
} hs_unit;

typedef struct {
    long source, target, n;
    const unsigned int *source_vrs, *target_vrs;
    double *buffer;
} hs_link;

typedef struct {
    long n_units;
    hs_unit *units;
    long n_links;
    hs_link *links;
    data_t data;              /* N_VGetArrayPointer */
    long discrete, nx;
    long rhs_count;
    long status, failed_unit, failed_function;
    double failed_time;
    /* recording (hs_advance) */
    cvode_t cvode;
    get_dky_t get_dky;
    long n_inputs, row_width;
    const double *inputs;     /* the master inputs' current values */
    double *scratch;          /* one row: where a row is assembled */
    long pending;             /* an internal step taken whose rows are not all recorded */
    double step_time;
    int step_flag;
} hs_kernel;

enum { F_SET_TIME, F_SET_STATES, F_GET_REAL, F_SET_REAL, F_GET_DERIVATIVES, F_GET_EVENT_INDICATORS,
       F_GET_INTEGER, F_GET_BOOLEAN };

static int fail(hs_kernel *k, int status, long unit, long function, double t) {
    k->status = status;
    k->failed_unit = unit;
    k->failed_function = function;
    k->failed_time = t;
    return -1;
}

#define CHECK(call, unit, function) \
    do { int s_ = (call); if (s_ > 1) return fail(k, s_, (unit), (function), t); } while (0)

/* set time (and states), propagate the continuous connections */
static int evaluate(hs_kernel *k, double t, const double *x) {
    long i;
    for (i = 0; i < k->n_units; i++) {
        hs_unit *u = &k->units[i];
        CHECK(u->set_time(u->component, t), i, F_SET_TIME);
    }
    if (k->discrete) return 0;
    for (i = 0; i < k->n_units; i++) {
        hs_unit *u = &k->units[i];
        if (u->nx) CHECK(u->set_states(u->component, x + u->x_offset, (size_t)u->nx), i, F_SET_STATES);
    }
    return 0;
}

static int propagate(hs_kernel *k, double t) {
    long j;
    for (j = 0; j < k->n_links; j++) {
        hs_link *l = &k->links[j];
        hs_unit *s = &k->units[l->source], *d = &k->units[l->target];
        CHECK(s->get_real(s->component, l->source_vrs, (size_t)l->n, l->buffer), l->source, F_GET_REAL);
        CHECK(d->set_real(d->component, l->target_vrs, (size_t)l->n, l->buffer), l->target, F_SET_REAL);
    }
    return 0;
}

int hs_rhs(double t, void *y, void *ydot, void *user_data) {
    hs_kernel *k = (hs_kernel *)user_data;
    double *x = k->data(y), *dx = k->data(ydot);
    long i;
    if (k->status) return -1;
    if (evaluate(k, t, x)) return -1;
    if (k->discrete) {
        for (i = 0; i < k->nx; i++) dx[i] = 0.0;
        return 0;
    }
    k->rhs_count++;
    if (propagate(k, t)) return -1;
    for (i = 0; i < k->n_units; i++) {
        hs_unit *u = &k->units[i];
        if (u->nx) CHECK(u->get_derivatives(u->component, dx + u->x_offset, (size_t)u->nx), i, F_GET_DERIVATIVES);
    }
    return 0;
}

/* the FMUs at (t, x) with their connections propagated: for recording a solver step */
static int hs_prepare(hs_kernel *k, double t, const double *x) {
    if (k->status) return -1;
    if (evaluate(k, t, x)) return -1;
    return propagate(k, t);
}

int hs_root(double t, void *y, double *gout, void *user_data) {
    hs_kernel *k = (hs_kernel *)user_data;
    long i;
    if (k->status) return -1;
    if (evaluate(k, t, k->data(y))) return -1;
    if (propagate(k, t)) return -1;
    for (i = 0; i < k->n_units; i++) {
        hs_unit *u = &k->units[i];
        if (u->nz)
            CHECK(u->get_event_indicators(u->component, gout + u->z_offset, (size_t)u->nz), i,
                  F_GET_EVENT_INDICATORS);
    }
    return 0;
}

/* the row at t of the prepared FMUs: time, master inputs, every unit's outputs */
static int read_row(hs_kernel *k, double t, double *row) {
    long i, j;
    row[0] = t;
    for (j = 0; j < k->n_inputs; j++) row[1 + j] = k->inputs[j];
    for (i = 0; i < k->n_units; i++) {
        hs_unit *u = &k->units[i];
        hs_outputs *o = &u->real_outputs;
        if (o->n) {
            CHECK(u->get_real(u->component, o->vrs, (size_t)o->n, k->scratch), i, F_GET_REAL);
            for (j = 0; j < o->n; j++) row[o->columns[j]] = k->scratch[j];
        }
        o = &u->integer_outputs;
        if (o->n) {
            CHECK(u->get_integer(u->component, o->vrs, (size_t)o->n, o->ints), i, F_GET_INTEGER);
            for (j = 0; j < o->n; j++) row[o->columns[j]] = (double)o->ints[j];
        }
        o = &u->boolean_outputs;
        if (o->n) {
            CHECK(u->get_boolean(u->component, o->vrs, (size_t)o->n, o->ints), i, F_GET_BOOLEAN);
            for (j = 0; j < o->n; j++) row[o->columns[j]] = o->ints[j] ? 1.0 : 0.0;
        }
    }
    return 0;
}

enum { ADVANCE_REACHED = 0, ADVANCE_ROOT = 1, ADVANCE_FULL = 2, ADVANCE_MAX_STEPS = 3,
       ADVANCE_CVODE_FAILED = -1, ADVANCE_FMU_FAILED = -2, ADVANCE_DKY_FAILED = -3 };
#define CV_ONE_STEP 2
#define CV_TSTOP_RETURN 1
#define CV_ROOT_RETURN 2

/* CVODE in one-step mode towards t_stop (its stop time already set), recording rows.
 *
 * After each internal step: the rows at the output times grid[*next_output...] passed on the
 * way (interpolated, kind 1; only with `interpolate`), then, unless the step is the last one
 * (a root, the stop time), the row at the step (kind 0). Rows go to rows[*n_rows...] (row_width
 * doubles each) with their kinds, up to `capacity` rows: when the buffer is full the call
 * returns ADVANCE_FULL and the next call goes on where it stopped. On every return but a
 * failure the FMUs hold the solution at the time reached (*t_reached). `steps` counts the
 * internal steps (refused past max_steps: ADVANCE_MAX_STEPS), `cvode_flag` the last flag.
 */
int hs_advance(hs_kernel *k, void *cvode_mem, void *y, void *dky, double t_stop,
               const double *grid, long n_grid, long *next_output, int interpolate,
               double *rows, long *kinds, long capacity, long *n_rows,
               double *t_reached, long *steps, long max_steps, int *cvode_flag) {
    double t;
    int final;
    for (;;) {
        if (k->status) return ADVANCE_FMU_FAILED;
        if (!k->pending) {
            int flag;
            if (*steps >= max_steps) return ADVANCE_MAX_STEPS;
            flag = k->cvode(cvode_mem, t_stop, y, &t, CV_ONE_STEP);
            (*steps)++;
            *cvode_flag = flag;
            if (flag < 0) return k->status ? ADVANCE_FMU_FAILED : ADVANCE_CVODE_FAILED;
            k->pending = 1;
            k->step_time = t;
            k->step_flag = flag;
        }
        t = k->step_time;
        *t_reached = t;
        final = k->step_flag == CV_ROOT_RETURN || k->step_flag == CV_TSTOP_RETURN || t >= t_stop;
        if (interpolate) {
            /* Output times up to the step: those within rounding (eps) of a last step are left to
             * the master, which records the row at the time reached; after any other step they are
             * taken here (at most the step's own time: CVODE interpolates only over the last step,
             * so an output a rounding error past this one could not be reached after the next). */
            double eps = 1e-12 * (fabs(t) > 1.0 ? fabs(t) : 1.0);
            while (*next_output < n_grid && (final ? grid[*next_output] < t - eps : grid[*next_output] <= t + eps)) {
                double g = grid[*next_output];
                if (*n_rows >= capacity) return ADVANCE_FULL;
                if (!k->discrete && k->get_dky(cvode_mem, g < t ? g : t, 0, dky) < 0) return ADVANCE_DKY_FAILED;
                if (hs_prepare(k, g, k->discrete ? NULL : k->data(dky))) return ADVANCE_FMU_FAILED;
                if (read_row(k, g, rows + *n_rows * k->row_width)) return ADVANCE_FMU_FAILED;
                kinds[*n_rows] = 1;
                (*n_rows)++;
                (*next_output)++;
            }
        }
        if (final) {
            k->pending = 0;
            if (hs_prepare(k, t, k->data(y))) return ADVANCE_FMU_FAILED;
            return k->step_flag == CV_ROOT_RETURN ? ADVANCE_ROOT : ADVANCE_REACHED;
        }
        if (*n_rows >= capacity) return ADVANCE_FULL;
        if (hs_prepare(k, t, k->data(y))) return ADVANCE_FMU_FAILED;
        if (read_row(k, t, rows + *n_rows * k->row_width)) return ADVANCE_FMU_FAILED;
        kinds[*n_rows] = 0;
        (*n_rows)++;
        k->pending = 0;
    }
}
