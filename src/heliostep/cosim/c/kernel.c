/* heliostep's compiled co-simulation kernel (see heliostep/cosim/kernel.py).
 *
 * hs_rhs, hs_root: CVODE's right-hand side and root function for N connected Model Exchange
 *   FMUs: set time and states, copy the continuous Real connections in the master's
 *   propagation order, read derivatives or event indicators, all through the FMUs' own fmi2*
 *   function pointers.
 * hs_advance: CVODE in one-step mode up to a stop time, recording a row (time, master inputs,
 *   every FMU's traced outputs) after each internal step and, where asked, at the output times
 *   passed on the way from CVODE's interpolating polynomial (CVodeGetDky), into a buffer the
 *   master drains: heliostep's one loop over internal steps, whichever right-hand side CVODE
 *   calls (hs_rhs, or the master's Python callbacks, which then hand the kernel a prepare
 *   function that sets up the FMUs for each row: kernel.h, prepare_t).
 *
 * Algebraic loops (torn connections) are solved inside propagate by Newton's method (solve_loop),
 * the rest of the system as without them; a loop that fails records LOOP_FAILED and how.
 *
 * An FMI status worse than fmi2Warning stops the evaluation: the status, the instance, the
 * function and the time are recorded, and every further evaluation is refused until the master
 * has collected the error.
 *
 * The structures and codes are in kernel.h; hs_describe reports their layout for the test that
 * checks the ctypes mirror in kernel.py.
 */
#include <math.h>
#include <string.h>
#include <stdlib.h>

#include "kernel.h"

static int fail(hs_kernel *k, int status, long unit, long function, double t) {
    k->status = status;
    k->failed_unit = unit;
    k->failed_function = function;
    k->failed_time = t;
    return -1;
}

/* the call, after noting it in the supervisor's record (if any); an error stops the evaluation */
#define CHECK(call, unit_, function_) \
    do { \
        int s_; \
        if (k->where) { \
            k->where->unit = (unit_); k->where->function = (function_); k->where->time = t; k->where->calls++; \
        } \
        s_ = (call); \
        if (s_ > 1) return fail(k, s_, (unit_), (function_), t); \
    } while (0)

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

static int copy_links(hs_kernel *k, double t, long first, long end) {
    long j;
    for (j = first; j < end; j++) {
        hs_link *l = &k->links[j];
        hs_unit *s = &k->units[l->source], *d = &k->units[l->target];
        CHECK(s->get_real(s->component, l->source_vrs, (size_t)l->n, l->buffer), l->source, F_GET_REAL);
        if (l->factor) {
            long i;
            for (i = 0; i < l->n; i++) {
                /* (factor, offset) = (1, 0) leaves the value as it is; no fused multiply-add (the Python
                   link rounds the product first too): volatile keeps the product a double */
                volatile double product = l->factor[i] * l->buffer[i];
                if (l->factor[i] != 1.0 || l->offset[i] != 0.0) l->buffer[i] = product + l->offset[i];
            }
        }
        CHECK(d->set_real(d->component, l->target_vrs, (size_t)l->n, l->buffer), l->target, F_SET_REAL);
    }
    return 0;
}

/* ---------------------------------------------------------------- algebraic loops
 * Newton's method on the torn inputs, the twin of heliostep/cosim/loops.py LoopSolver.solve: the
 * same evaluations of r, the same convergence test and step size of the differences. It copies the
 * connections that do not depend on v once per solve, not in each evaluation (the same values).
 * One difference, rounding: the linear solve is Gaussian elimination with partial pivoting here
 * (LAPACK's gesv there: the same for one torn input). The check that a loop has a unique solution
 * is the Python solver's alone: its first solve, at initialization, comes before this kernel runs. */

static int loop_fail(hs_kernel *k, long failure, double t) {
    k->loop->failure = failure;
    k->loop->failed_time = t;
    return fail(k, LOOP_FAILED, -1, -1, t);
}

/* r = y(v) - v, every FMU left evaluated at v */
static int loop_residual(hs_kernel *k, double t, const double *v, double *r) {
    hs_loop *L = k->loop;
    long j;
    for (j = 0; j < L->n; j++) {
        hs_unit *u = &k->units[L->target_units[j]];
        CHECK(u->set_real(u->component, L->target_vrs + j, 1, v + j), L->target_units[j], F_SET_REAL);
    }
    if (copy_links(k, t, L->first_link, k->n_links)) return -1;
    for (j = 0; j < L->n; j++) {
        hs_unit *u = &k->units[L->source_units[j]];
        CHECK(u->get_real(u->component, L->source_vrs + j, 1, r + j), L->source_units[j], F_GET_REAL);
        r[j] -= v[j];
    }
    return 0;
}

/* forward differences of r at v into J (column-major: J[i + n j] = dr_i / dv_j), each step 1e-7 of the
 * larger of |v|, |y(v)| = |v + r| and 1 */
static int loop_jacobian(hs_kernel *k, double t, const double *v, const double *r, double *J, double *vp, double *rp) {
    long n = k->loop->n, i, j;
    for (j = 0; j < n; j++) {
        double size = fabs(v[j]) > 1.0 ? fabs(v[j]) : 1.0, h;
        if (fabs(v[j] + r[j]) > size) size = fabs(v[j] + r[j]);
        h = 1e-7 * size;
        memcpy(vp, v, (size_t)n * sizeof(double));
        vp[j] += h;
        if (loop_residual(k, t, vp, rp)) return -1;
        for (i = 0; i < n; i++) J[i + n * j] = (rp[i] - r[i]) / h;
    }
    return 0;
}

/* A (n x n, column-major, overwritten) times x = b (overwritten with x), partial pivoting.
 * Returns 0, or -1 for a zero pivot (singular). */
static int gauss(double *A, double *b, long n) {
    long i, j, c, p;
    for (c = 0; c < n; c++) {
        for (p = c, i = c + 1; i < n; i++)
            if (fabs(A[i + n * c]) > fabs(A[p + n * c])) p = i;
        if (A[p + n * c] == 0.0 || !isfinite(A[p + n * c])) return -1;
        if (p != c) {
            for (j = 0; j < n; j++) {
                double s = A[c + n * j]; A[c + n * j] = A[p + n * j]; A[p + n * j] = s;
            }
            { double s = b[c]; b[c] = b[p]; b[p] = s; }
        }
        for (i = c + 1; i < n; i++) {
            double f = A[i + n * c] / A[c + n * c];
            for (j = c; j < n; j++) A[i + n * j] -= f * A[c + n * j];
            b[i] -= f * b[c];
        }
    }
    for (i = n - 1; i >= 0; i--) { /* back substitution */
        for (j = i + 1; j < n; j++) b[i] -= A[i + n * j] * b[j];
        b[i] /= A[i + n * i];
    }
    return 0;
}

static int solve_loop(hs_kernel *k, double t) {
    hs_loop *L = k->loop;
    long n = L->n, i, iteration;
    double *v = L->work, *r = v + n, *vp = r + n, *rp = vp + n, *J = rp + n;
    memcpy(v, L->v, (size_t)n * sizeof(double));
    L->solves++;
    if (copy_links(k, t, 0, L->first_link)) return -1; /* the connections that do not depend on v */
    if (loop_residual(k, t, v, r)) return -1;
    for (iteration = 0; iteration <= L->max_iterations; iteration++) {
        int converged = 1, finite = 1;
        for (i = 0; i < n; i++) {
            if (!(fabs(r[i]) <= L->atol + L->rtol * fabs(v[i]))) converged = 0;
            if (!isfinite(r[i])) finite = 0;
        }
        if (converged) {
            memcpy(L->v, v, (size_t)n * sizeof(double));
            L->iterations += iteration;
            if (iteration > L->most_iterations) L->most_iterations = iteration;
            return 0;
        }
        if (iteration == L->max_iterations || !finite) break;
        if (loop_jacobian(k, t, v, r, J, vp, rp)) return -1;
        memcpy(rp, r, (size_t)n * sizeof(double));
        if (gauss(J, rp, n)) return loop_fail(k, LOOP_SINGULAR, t);
        for (i = 0; i < n; i++) v[i] = v[i] + -rp[i];
        if (loop_residual(k, t, v, r)) return -1;
    }
    return loop_fail(k, LOOP_NO_CONVERGENCE, t); /* v and r: the last iterate and its residual */
}

/* the continuous Real connections, with the loops solved when the system has any */
static int propagate(hs_kernel *k, double t) {
    if (k->loop && k->loop->n) return solve_loop(k, t);
    return copy_links(k, t, 0, k->n_links);
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

/* the FMUs at (t, x) with their connections propagated: for recording a solver step (the
 * master's own preparation where it propagates itself, not after the last step: `final`) */
static int hs_prepare(hs_kernel *k, double t, const double *x, int final) {
    if (k->status) return -1;
    if (k->prepare) return final ? 0 : (k->prepare(t, k->discrete ? NULL : x, k->prepare_user) ? -1 : 0);
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
static int read_row(hs_kernel *k, double t, double *row, long stride) {
    long i, j;
    row[0] = t;
    for (j = 0; j < k->n_inputs; j++) row[(1 + j) * stride] = k->inputs[j];
    for (i = 0; i < k->n_units; i++) {
        hs_unit *u = &k->units[i];
        hs_outputs *o = &u->real_outputs;
        if (o->n) {
            CHECK(u->get_real(u->component, o->vrs, (size_t)o->n, k->scratch), i, F_GET_REAL);
            for (j = 0; j < o->n; j++) row[o->columns[j] * stride] = k->scratch[j];
        }
        o = &u->integer_outputs;
        if (o->n) {
            CHECK(u->get_integer(u->component, o->vrs, (size_t)o->n, o->ints), i, F_GET_INTEGER);
            for (j = 0; j < o->n; j++) row[o->columns[j] * stride] = (double)o->ints[j];
        }
        o = &u->boolean_outputs;
        if (o->n) {
            CHECK(u->get_boolean(u->component, o->vrs, (size_t)o->n, o->ints), i, F_GET_BOOLEAN);
            for (j = 0; j < o->n; j++) row[o->columns[j] * stride] = o->ints[j] ? 1.0 : 0.0;
        }
    }
    return 0;
}

#define CV_ONE_STEP 2
#define CV_TSTOP_RETURN 1
#define CV_ROOT_RETURN 2

/* CVODE in one-step mode towards a->t_stop (its stop time already set), recording rows.
 *
 * After each internal step: the rows at the output times grid[a->next_output...] passed on the
 * way (interpolated, kind 1; only with a->interpolate), then, unless the step is the last one
 * (a root, the stop time), the row at the step (kind 0). Rows go to row a->n_rows... of the
 * column-major buffer rows (kernel.h) with their kinds, up to a->capacity rows: when it is full the
 * call returns ADVANCE_FULL and the next call goes on where it stopped. On every return but a
 * failure the FMUs hold the solution at the time reached (a->t_reached). a->steps counts the
 * internal steps (refused past a->max_steps: ADVANCE_MAX_STEPS), a->cvode_flag is the last flag.
 */
int hs_advance(hs_kernel *k, hs_advance_args *a) {
    double t;
    int final;
    long outputs = 0; /* output-time rows recorded in this call */
    for (;;) {
        if (k->status) return ADVANCE_FMU_FAILED;
        if (!k->pending) {
            int flag;
            if (a->steps >= a->max_steps) return ADVANCE_MAX_STEPS;
            flag = k->cvode(a->cvode_mem, a->t_stop, a->y, &t, CV_ONE_STEP);
            a->steps++;
            a->cvode_flag = flag;
            if (flag < 0) return k->status ? ADVANCE_FMU_FAILED : ADVANCE_CVODE_FAILED;
            k->pending = 1;
            k->step_time = t;
            k->step_flag = flag;
        }
        t = k->step_time;
        a->t_reached = t;
        final = k->step_flag == CV_ROOT_RETURN || k->step_flag == CV_TSTOP_RETURN || t >= a->t_stop;
        if (a->interpolate) {
            /* Output times up to the step: those within rounding (eps) of a last step are left to
             * the master, which records the row at the time reached; after any other step they are
             * taken here (at most the step's own time: CVODE interpolates only over the last step,
             * so an output a rounding error past this one could not be reached after the next). */
            double eps = 1e-12 * (fabs(t) > 1.0 ? fabs(t) : 1.0);
            while (a->next_output < a->n_grid
                   && (final ? a->grid[a->next_output] < t - eps : a->grid[a->next_output] <= t + eps)) {
                double g = a->grid[a->next_output];
                if (a->n_rows >= a->capacity || outputs >= a->max_outputs) return ADVANCE_FULL;
                if (!k->discrete && k->get_dky(a->cvode_mem, g < t ? g : t, 0, a->dky) < 0) return ADVANCE_DKY_FAILED;
                if (hs_prepare(k, g, k->discrete ? NULL : k->data(a->dky), 0)) return ADVANCE_FMU_FAILED;
                if (read_row(k, g, a->rows + a->n_rows, a->capacity)) return ADVANCE_FMU_FAILED;
                a->kinds[a->n_rows] = 1;
                a->n_rows++;
                outputs++;
                a->next_output++;
            }
        }
        if (final) {
            k->pending = 0;
            if (hs_prepare(k, t, k->data(a->y), 1)) return ADVANCE_FMU_FAILED;
            return k->step_flag == CV_ROOT_RETURN ? ADVANCE_ROOT : ADVANCE_REACHED;
        }
        if (a->n_rows >= a->capacity) return ADVANCE_FULL;
        if (hs_prepare(k, t, k->data(a->y), 0)) return ADVANCE_FMU_FAILED;
        if (read_row(k, t, a->rows + a->n_rows, a->capacity)) return ADVANCE_FMU_FAILED;
        a->kinds[a->n_rows] = 0;
        a->n_rows++;
        k->pending = 0;
    }
}

#define SIZE(s) {#s, (long)sizeof(s)}
#define FIELD(s, f) {#s "." #f, (long)offsetof(s, f)}
#define CODE(c) {#c, (long)(c)}

static const struct { const char *name; long value; } layout[] = {
    SIZE(hs_outputs), FIELD(hs_outputs, n), FIELD(hs_outputs, vrs), FIELD(hs_outputs, columns),
    FIELD(hs_outputs, ints),
    SIZE(hs_unit), FIELD(hs_unit, component), FIELD(hs_unit, set_time), FIELD(hs_unit, set_states),
    FIELD(hs_unit, get_derivatives), FIELD(hs_unit, get_event_indicators), FIELD(hs_unit, get_real),
    FIELD(hs_unit, set_real), FIELD(hs_unit, get_integer), FIELD(hs_unit, get_boolean), FIELD(hs_unit, nx),
    FIELD(hs_unit, x_offset), FIELD(hs_unit, nz), FIELD(hs_unit, z_offset), FIELD(hs_unit, real_outputs),
    FIELD(hs_unit, integer_outputs), FIELD(hs_unit, boolean_outputs),
    SIZE(hs_where), FIELD(hs_where, unit), FIELD(hs_where, function), FIELD(hs_where, calls),
    FIELD(hs_where, stop), FIELD(hs_where, time),
    SIZE(hs_link), FIELD(hs_link, source), FIELD(hs_link, target), FIELD(hs_link, n), FIELD(hs_link, source_vrs),
    FIELD(hs_link, target_vrs), FIELD(hs_link, buffer), FIELD(hs_link, factor), FIELD(hs_link, offset),
    SIZE(hs_kernel), FIELD(hs_kernel, n_units), FIELD(hs_kernel, units), FIELD(hs_kernel, n_links),
    FIELD(hs_kernel, links), FIELD(hs_kernel, data), FIELD(hs_kernel, discrete), FIELD(hs_kernel, nx),
    FIELD(hs_kernel, rhs_count), FIELD(hs_kernel, status), FIELD(hs_kernel, failed_unit),
    FIELD(hs_kernel, failed_function), FIELD(hs_kernel, failed_time), FIELD(hs_kernel, cvode),
    FIELD(hs_kernel, get_dky), FIELD(hs_kernel, n_inputs), FIELD(hs_kernel, row_width), FIELD(hs_kernel, inputs),
    FIELD(hs_kernel, scratch), FIELD(hs_kernel, pending), FIELD(hs_kernel, step_time), FIELD(hs_kernel, step_flag),
    FIELD(hs_kernel, prepare), FIELD(hs_kernel, prepare_user), FIELD(hs_kernel, where), FIELD(hs_kernel, loop),
    SIZE(hs_loop), FIELD(hs_loop, n), FIELD(hs_loop, first_link), FIELD(hs_loop, target_units), FIELD(hs_loop, source_units),
    FIELD(hs_loop, target_vrs), FIELD(hs_loop, source_vrs), FIELD(hs_loop, v), FIELD(hs_loop, work),
    FIELD(hs_loop, rtol), FIELD(hs_loop, atol), FIELD(hs_loop, max_iterations),
    FIELD(hs_loop, solves), FIELD(hs_loop, iterations), FIELD(hs_loop, most_iterations), FIELD(hs_loop, failure),
    FIELD(hs_loop, failed_time),
    SIZE(hs_advance_args), FIELD(hs_advance_args, cvode_mem), FIELD(hs_advance_args, y),
    FIELD(hs_advance_args, dky), FIELD(hs_advance_args, t_stop), FIELD(hs_advance_args, grid),
    FIELD(hs_advance_args, n_grid), FIELD(hs_advance_args, interpolate), FIELD(hs_advance_args, rows),
    FIELD(hs_advance_args, kinds), FIELD(hs_advance_args, capacity), FIELD(hs_advance_args, max_steps),
    FIELD(hs_advance_args, max_outputs),
    FIELD(hs_advance_args, next_output), FIELD(hs_advance_args, n_rows), FIELD(hs_advance_args, steps),
    FIELD(hs_advance_args, t_reached), FIELD(hs_advance_args, cvode_flag),
    CODE(F_SET_TIME), CODE(F_SET_STATES), CODE(F_GET_REAL), CODE(F_SET_REAL), CODE(F_GET_DERIVATIVES),
    CODE(F_GET_EVENT_INDICATORS), CODE(F_GET_INTEGER), CODE(F_GET_BOOLEAN),
    CODE(ADVANCE_REACHED), CODE(ADVANCE_ROOT), CODE(ADVANCE_FULL), CODE(ADVANCE_MAX_STEPS),
    CODE(ADVANCE_CVODE_FAILED), CODE(ADVANCE_FMU_FAILED), CODE(ADVANCE_DKY_FAILED),
    CODE(LOOP_FAILED), CODE(LOOP_NO_CONVERGENCE), CODE(LOOP_SINGULAR),
};

long hs_describe(const char *name) {
    size_t i;
    for (i = 0; i < sizeof(layout) / sizeof(layout[0]); i++)
        if (strcmp(layout[i].name, name) == 0) return layout[i].value;
    return -1;
}

/* ================================================================ events: hs_event
 * The fixed work of one event of the master (heliostep/cosim/master.py _Run._event) in one call,
 * the FMI calls in the order the Python path makes them (heliostep/cosim/events.py event_iteration
 * and discrete_fixed_point, CoupledSystem.row, CVodeIntegrator.reset):
 *   (prepare) fmi2SetTime on every unit and the continuous Real connections copied;
 *   the row before (read_row);
 *   fmi2EnterEventMode on every unit;
 *   (new inputs) each master input's value from input_time on (the values of its piecewise-constant
 *     signal at searchsorted(times, input_time, 'right')) and fmi2SetReal into its target;
 *   the outputs read, the connections copied, fmi2NewDiscreteStates on each unit once;
 *   when a unit's fmi2EventInfo has any flag set (a new round needed, terminate, the states or their
 *     nominals changed, a next time event), EVENT_GENERAL: the master goes on in Python from that unit
 *     (events.py Resume), nothing after it called here;
 *   the outputs read again: changed, EVENT_CHANGED (the master goes on with the next round in Python);
 *   else fmi2EnterContinuousTimeMode on every unit, the states into CVODE's vector, CVodeReInit and
 *   the row after: EVENT_DONE.
 * Only for FMI 2.0 units with all connections continuous Real, no algebraic loop, Real input targets
 * (heliostep/cosim/fast_events.py decides); an FMI status worse than fmi2Warning is recorded as in
 * hs_rhs (EVENT_FAILED). Everything here is this section's own: it calls read_row and copy_links and
 * changes nothing above. */

typedef int (*status_only_t)(fmi2Component);
typedef int (*new_discrete_t)(fmi2Component, void *);
typedef int (*reinit_t)(void *, double, void *);

/* fmi2EventInfo (fmi2Boolean is int) */
typedef struct {
    int new_discrete_states_needed, terminate_simulation, nominals_changed, values_changed, next_event_time_defined;
    double next_event_time;
} hs_event_info;

typedef struct {
    status_only_t enter_event_mode, enter_continuous_time_mode;
    new_discrete_t new_discrete_states;
    get_x_t get_states;
} hs_event_unit;

/* set once per run */
typedef struct {
    hs_event_unit *units;           /* as many as hs_kernel.units */
    long n_inputs;                  /* the master inputs (hs_kernel.n_inputs) */
    double *inputs;                 /* their current values (the array hs_kernel.inputs points to) */
    const double *const *times;     /* per input: its change times, sorted */
    const long *n_times;
    const double *const *values;    /* per input: n_times + 1 values */
    long n_targets;                 /* inputs set into an FMU, in the master's order */
    const long *target_input, *target_unit;
    const unsigned int *target_vr;
    long n_outputs;                 /* the traced outputs: the row from column 1 + n_inputs on */
    double *work;                   /* 2 rows */
    reinit_t reinit;                /* CVodeReInit */
    long f_enter_event, f_new_discrete, f_enter_continuous, f_get_states; /* codes for the record (watch.FUNCTIONS) */
} hs_events;

/* one call */
typedef struct {
    double t, input_time;
    int new_inputs, prepare;
    void *cvode_mem, *y;
    double *rows;                   /* 2 rows: before and after */
    /* updated */
    long recorded;                  /* rows recorded */
    long entered, continued;        /* units in event mode / back in continuous-time mode */
    long unit;                      /* EVENT_GENERAL: the unit whose event info asks for more */
    hs_event_info info;             /* and that info */
    double *outputs;                /* EVENT_GENERAL: the outputs before the round; EVENT_CHANGED: after it */
    int cvode_flag;
} hs_event_args;

enum { EVENT_DONE = 0, EVENT_GENERAL = 1, EVENT_CHANGED = 2, EVENT_FAILED = -1, EVENT_REINIT_FAILED = -2 };

/* numpy's searchsorted(times, x, side='right'): the number of times <= x */
static long events_after(const double *times, long n, double x) {
    long low = 0, high = n;
    while (low < high) {
        long mid = low + (high - low) / 2;
        if (!(x < times[mid])) low = mid + 1;
        else high = mid;
    }
    return low;
}

static int events_round(hs_kernel *k, hs_events *e, hs_event_args *a) {
    double t = a->t, *before = e->work, *after = e->work + k->row_width;
    long i, j, first = 1 + k->n_inputs;
    if (read_row(k, t, before, 1)) return EVENT_FAILED;
    if (copy_links(k, t, 0, k->n_links)) return EVENT_FAILED;
    for (i = 0; i < k->n_units; i++) {
        hs_event_info info = {0, 0, 0, 0, 0, 0.0};
        CHECK(e->units[i].new_discrete_states(k->units[i].component, &info), i, e->f_new_discrete);
        if (info.new_discrete_states_needed || info.terminate_simulation || info.nominals_changed
            || info.values_changed || info.next_event_time_defined) {
            a->unit = i;
            a->info = info;
            memcpy(a->outputs, before + first, (size_t)e->n_outputs * sizeof(double));
            return EVENT_GENERAL;
        }
    }
    if (read_row(k, t, after, 1)) return EVENT_FAILED;
    for (j = 0; j < e->n_outputs; j++)
        if (!(after[first + j] == before[first + j])) { /* numpy's array_equal: NaN differs */
            memcpy(a->outputs, after + first, (size_t)e->n_outputs * sizeof(double));
            return EVENT_CHANGED;
        }
    return EVENT_DONE;
}

int hs_event(hs_kernel *k, hs_events *e, hs_event_args *a) {
    double t = a->t;
    long i, j;
    int outcome;
    a->entered = a->continued = a->recorded = 0;
    if (k->status) return EVENT_FAILED;
    if (a->prepare) {
        for (i = 0; i < k->n_units; i++) CHECK(k->units[i].set_time(k->units[i].component, t), i, F_SET_TIME);
        if (copy_links(k, t, 0, k->n_links)) return EVENT_FAILED;
    }
    if (read_row(k, t, a->rows, 1)) return EVENT_FAILED;
    a->recorded = 1;
    for (i = 0; i < k->n_units; i++) {
        CHECK(e->units[i].enter_event_mode(k->units[i].component), i, e->f_enter_event);
        a->entered = i + 1;
    }
    if (a->new_inputs) {
        for (j = 0; j < e->n_inputs; j++)
            e->inputs[j] = e->values[j][events_after(e->times[j], e->n_times[j], a->input_time)];
        for (j = 0; j < e->n_targets; j++) {
            hs_unit *u = &k->units[e->target_unit[j]];
            CHECK(u->set_real(u->component, e->target_vr + j, 1, e->inputs + e->target_input[j]), e->target_unit[j],
                  F_SET_REAL);
        }
    }
    outcome = events_round(k, e, a);
    if (outcome != EVENT_DONE) return outcome;
    for (i = 0; i < k->n_units; i++) {
        CHECK(e->units[i].enter_continuous_time_mode(k->units[i].component), i, e->f_enter_continuous);
        a->continued = i + 1;
    }
    if (!k->discrete) {
        double *x = k->data(a->y);
        for (i = 0; i < k->n_units; i++) {
            hs_unit *u = &k->units[i];
            if (u->nx) CHECK(e->units[i].get_states(u->component, x + u->x_offset, (size_t)u->nx), i, e->f_get_states);
        }
    }
    a->cvode_flag = e->reinit(a->cvode_mem, t, a->y);
    if (a->cvode_flag != 0) return EVENT_REINIT_FAILED;
    if (read_row(k, t, a->rows + k->row_width, 1)) return EVENT_FAILED;
    a->recorded = 2;
    return EVENT_DONE;
}

/* every unit's states from (set) or into (!set) x: CoupledSystem.set_x / get_x in one call, the same FMI
 * calls; t: the instances' time (for the record and an error) */
int hs_event_states(hs_kernel *k, hs_events *e, double *x, int set, double t) {
    long i;
    if (k->status) return EVENT_FAILED;
    for (i = 0; i < k->n_units; i++) {
        hs_unit *u = &k->units[i];
        if (!u->nx) continue;
        if (set) CHECK(u->set_states(u->component, x + u->x_offset, (size_t)u->nx), i, F_SET_STATES);
        else CHECK(e->units[i].get_states(u->component, x + u->x_offset, (size_t)u->nx), i, e->f_get_states);
    }
    return EVENT_DONE;
}

/* this section's layout, for the test of the ctypes mirror (heliostep/cosim/fast_events.py) */
static const struct { const char *name; long value; } event_layout[] = {
    SIZE(hs_event_info), FIELD(hs_event_info, next_event_time_defined), FIELD(hs_event_info, next_event_time),
    SIZE(hs_event_unit), FIELD(hs_event_unit, enter_continuous_time_mode), FIELD(hs_event_unit, new_discrete_states),
    FIELD(hs_event_unit, get_states),
    SIZE(hs_events), FIELD(hs_events, units), FIELD(hs_events, n_inputs), FIELD(hs_events, inputs),
    FIELD(hs_events, times), FIELD(hs_events, n_times), FIELD(hs_events, values), FIELD(hs_events, n_targets),
    FIELD(hs_events, target_input), FIELD(hs_events, target_unit), FIELD(hs_events, target_vr),
    FIELD(hs_events, n_outputs), FIELD(hs_events, work), FIELD(hs_events, reinit), FIELD(hs_events, f_enter_event),
    FIELD(hs_events, f_new_discrete), FIELD(hs_events, f_enter_continuous), FIELD(hs_events, f_get_states),
    SIZE(hs_event_args), FIELD(hs_event_args, t), FIELD(hs_event_args, input_time), FIELD(hs_event_args, new_inputs),
    FIELD(hs_event_args, prepare), FIELD(hs_event_args, cvode_mem), FIELD(hs_event_args, y),
    FIELD(hs_event_args, rows), FIELD(hs_event_args, recorded), FIELD(hs_event_args, entered), FIELD(hs_event_args, continued),
    FIELD(hs_event_args, unit), FIELD(hs_event_args, info), FIELD(hs_event_args, outputs),
    FIELD(hs_event_args, cvode_flag),
    CODE(EVENT_DONE), CODE(EVENT_GENERAL), CODE(EVENT_CHANGED), CODE(EVENT_FAILED), CODE(EVENT_REINIT_FAILED),
};

long hs_event_describe(const char *name) {
    size_t i;
    for (i = 0; i < sizeof(event_layout) / sizeof(event_layout[0]); i++)
        if (strcmp(event_layout[i].name, name) == 0) return event_layout[i].value;
    return -1;
}
/* ================================================================ end of events */
