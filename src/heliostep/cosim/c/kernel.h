/* heliostep's compiled co-simulation kernel: the structures and codes shared by kernel.c and
 * heliostep/cosim/kernel.py (whose ctypes Structures mirror these; tests/cosim/test_kernel_layout.py
 * checks every size, field offset and code against hs_describe below).
 *
 * The master fills an hs_kernel (the FMUs' handles and fmi2* function pointers, the continuous
 * Real connections in propagation order, the row layout) and passes it to CVODE as user data
 * for hs_rhs / hs_root, and to hs_advance with an hs_advance_args.
 */
#ifndef HELIOSTEP_KERNEL_H
#define HELIOSTEP_KERNEL_H

#include <stddef.h>

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
/* The master's own preparation of the FMUs at (t, x) for a row of hs_advance, replacing the
 * kernel's (set time and states, propagate the continuous Real connections) where the master
 * propagates itself (non-Real or torn connections, the Python right-hand side): x is
 * NULL for a system without states. It is not called after the last internal step (the master
 * sets the states itself then). Returns 0, or -1 after recording its error on the master's side. */
typedef int (*prepare_t)(double t, const double *x, void *user);

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
    const double *factor, *offset;  /* per value, buffer[i] = factor[i] * buffer[i] + offset[i] on its way
                                       (a connection's linear transformation); NULL: copied as they are */
} hs_link;

/* The torn inputs of a system's algebraic loops, solved at every propagation (kernel.c, solve_loop):
 * Newton's method on r(v) = y(v) - v, v the torn inputs (set with fmi2SetReal), y the torn
 * sources' outputs (read with fmi2GetReal after the connections that depend on v are copied), a forward-
 * difference Jacobian, starting from the last solution (v, shared with heliostep/cosim/loops.py, whose
 * first solve at initialization checked the loop has a unique solution). A failed solve leaves its last
 * iterate and residual in work[0 .. n) and work[n .. 2 n). */
typedef struct {
    long n;                                   /* torn inputs */
    long first_link;                          /* hs_kernel.links[first_link...] depend on them: copied
                                                 in every evaluation of r, those before once per solve */
    const long *target_units, *source_units;  /* per torn connection: its target's and source's unit */
    const unsigned int *target_vrs, *source_vrs;
    double *v;                                /* the torn inputs: the starting guess, then the solution */
    double *work;                             /* n n + 4 n doubles */
    double rtol, atol;                        /* converged when |r| <= atol + rtol |v| */
    long max_iterations;
    long solves, iterations, most_iterations;
    long failure;                             /* 0, LOOP_NO_CONVERGENCE or LOOP_SINGULAR */
    double failed_time;
} hs_loop;

/* a supervisor's record of the FMI call in progress (heliostep/cosim/watch.py, Record) */
typedef struct {
    long long unit, function, calls, stop; /* unit index, F_* code, calls begun, stop asked */
    double time;                           /* the time of the call [s] */
} hs_where;

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
    prepare_t prepare;        /* NULL: the kernel prepares the FMUs itself */
    void *prepare_user;
    /* NULL, or a supervisor's record: before every FMI call the unit's index, the F_* code, the
     * time and a count of the calls begun are stored there */
    hs_where *where;
    hs_loop *loop;            /* NULL, or the algebraic loops solved at every propagation */
} hs_kernel;

/* One call of hs_advance: what the caller sets, then what hs_advance updates. */
typedef struct {
    /* set by the caller */
    void *cvode_mem;
    void *y;                  /* CVODE's state vector */
    void *dky;                /* a vector for interpolated states */
    double t_stop;            /* CVODE's stop time (already set with CVodeSetStopTime) */
    const double *grid;       /* the output times */
    long n_grid;
    int interpolate;          /* record the output times passed on the way */
    double *rows;             /* capacity rows, column-major: column c of row r at rows[c * capacity + r]
                                 (each column contiguous, for the monitor's numpy) */
    long *kinds;              /* per row: 0 an internal step, 1 an output time */
    long capacity;
    long max_steps;           /* internal steps allowed in all calls towards t_stop */
    long max_outputs;         /* output-time rows one call records before it returns ADVANCE_FULL */
    /* updated by hs_advance */
    long next_output;         /* index into grid of the next output time to record */
    long n_rows;              /* rows recorded (the caller empties the buffer between calls) */
    long steps;               /* internal steps taken */
    double t_reached;
    int cvode_flag;           /* the last flag CVode returned */
} hs_advance_args;

/* the FMI function of a failed evaluation (hs_kernel.failed_function) */
enum { F_SET_TIME, F_SET_STATES, F_GET_REAL, F_SET_REAL, F_GET_DERIVATIVES, F_GET_EVENT_INDICATORS,
       F_GET_INTEGER, F_GET_BOOLEAN };

/* hs_kernel.status of a loop that failed (hs_loop.failure says how); FMI statuses are 0-5 */
enum { LOOP_FAILED = 100, LOOP_NO_CONVERGENCE = 1, LOOP_SINGULAR = 2 };

/* what hs_advance returns */
enum { ADVANCE_REACHED = 0, ADVANCE_ROOT = 1, ADVANCE_FULL = 2, ADVANCE_MAX_STEPS = 3,
       ADVANCE_CVODE_FAILED = -1, ADVANCE_FMU_FAILED = -2, ADVANCE_DKY_FAILED = -3 };

int hs_rhs(double t, void *y, void *ydot, void *user_data);
int hs_root(double t, void *y, double *gout, void *user_data);
int hs_advance(hs_kernel *k, hs_advance_args *a);
/* sizeof("hs_unit"), offsetof("hs_unit.nx") or the value of a code ("ADVANCE_ROOT"); -1 if unknown */
long hs_describe(const char *name);

#endif
