/*
 * drive_model.c: runs one generated library the way a user would, so that a sanitized build
 * (CMakeLists.txt, -DLCG_SANITIZE=ON) checks its steppers and drivers, not only its kernels:
 *
 *   1. the kernels mass_matrix, forcing, accel and rhs at the initial state;
 *   2. per compiled method, STEPS steps of <prefix>_step_<method> with a work array of exactly
 *      <MACRO>_WORK_<METHOD> values (constrained models: projected after every step);
 *   3. per method, <prefix>_simulate over STEPS steps, every output recorded (energy, points,
 *      constraint residuals and multipliers where the library has them), projection on;
 *   4. per method, <prefix>_sweep over MEMBERS identical members, with the trajectories;
 *   5. an unknown method number, which must come back as LCG_UNKNOWN_METHOD;
 *   6. simulate and sweep with arguments out of range (n_steps < 0, stride < 1, t0 or h not
 *      finite), which must come back as LCG_BAD_ARGUMENT with nothing written (the outputs are
 *      sized by n_steps / stride), and the step functions at a time that is not finite.
 *
 * Every buffer is allocated with exactly the size the header documents (AddressSanitizer
 * catches a write one past it) and filled with NaN first, so a value read before it is written
 * turns up as a non-finite result. Checks: every status is LCG_OK, every step is done, every
 * value written is finite, identical members give identical results. Exit status 0 on success.
 *
 * Configured by the header LCG_DRIVE_VALUES (written by tests/native_build/test_sanitize.py),
 * which includes the library's header and defines
 *   LCG_DRIVE_NAME                     the library's name, a string
 *   LCG_DRIVE_PREFIX, LCG_DRIVE_MACRO  the library's function and macro prefixes
 *   LCG_DRIVE_REAL                     double or float
 *   LCG_DRIVE_N_CONSTRAINTS            m (0: unconstrained)
 *   LCG_DRIVE_HAS_ENERGY               1 when the library has an energy function
 *   LCG_DRIVE_METHODS(X)               X(name, NAME) for each compiled method
 *   LCG_DRIVE_X0, LCG_DRIVE_P          braced initializers: a consistent state, the parameters
 *   LCG_DRIVE_H                        the step size
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include LCG_DRIVE_VALUES

#define LCG_PASTE_(a, b) a##b
#define LCG_PASTE(a, b) LCG_PASTE_(a, b)
#define FN(suffix) LCG_PASTE(LCG_DRIVE_PREFIX, suffix)
#define MAC(suffix) LCG_PASTE(LCG_DRIVE_MACRO, suffix)

#define N MAC(_N)
#define N_STATE MAC(_N_STATE)
#define N_P (MAC(_N_PARAMS) > 0 ? MAC(_N_PARAMS) : 1)
#define N_POINT_VALUES (3 * MAC(_N_POINTS))
#define M LCG_DRIVE_N_CONSTRAINTS
#define STEPS 300L
#define STRIDE 7L
#define N_OUT (STEPS / STRIDE + 1)
#define MEMBERS 3

typedef LCG_DRIVE_REAL real;
typedef int (*step_function)(real *t, real *x, const real *p, real h, real *work);

static const real x0_values[N_STATE] = LCG_DRIVE_X0;
static const real p_values[N_P] = LCG_DRIVE_P;

/* count values, every one NaN (count 0: a valid pointer to nothing); exits when out of memory */
static real *nans(long count)
{
    real *block = malloc(sizeof(real) * (size_t)(count > 0 ? count : 1));
    long i;
    if (!block) {
        fprintf(stderr, "out of memory\n");
        exit(2);
    }
    for (i = 0; i < count; ++i) block[i] = (real)NAN;
    return block;
}

static real *copy(const real *values, long count)
{
    real *block = nans(count);
    memcpy(block, values, sizeof(real) * (size_t)count);
    return block;
}

/* 1 and a message unless every values[i] is finite */
static int nonfinite(const char *what, const real *values, long count)
{
    long i;
    for (i = 0; i < count; ++i) {
        if (!isfinite(values[i])) {
            printf("FAIL %s[%ld] = %g is not finite\n", what, i, (double)values[i]);
            return 1;
        }
    }
    return 0;
}

static int bad_status(const char *what, int status)
{
    if (status == LCG_OK) return 0;
    printf("FAIL %s returned status %d\n", what, status);
    return 1;
}

static int drive_kernels(void)
{
    real *x = copy(x0_values, N_STATE), *p = copy(p_values, N_P);
    real *mass = nans(N * N), *forcing = nans(N), *accel = nans(N), *xdot = nans(N_STATE);
    int failures = 0;
    FN(_mass_matrix)(0, x, p, mass);
    FN(_forcing)(0, x, p, forcing);
    failures += bad_status("accel", FN(_accel)(0, x, p, accel));
    failures += bad_status("rhs", FN(_rhs)(0, x, p, xdot));
    failures += nonfinite("M", mass, N * N) + nonfinite("F", forcing, N) + nonfinite("ud", accel, N);
    failures += nonfinite("xdot", xdot, N_STATE);
    free(x), free(p), free(mass), free(forcing), free(accel), free(xdot);
    return failures;
}

static int drive_steps(const char *name, step_function step, long work_size)
{
    real *x = copy(x0_values, N_STATE), *p = copy(p_values, N_P), *work = nans(work_size);
    real t = 0;
    long k;
    int status = LCG_OK;
    for (k = 0; k < STEPS && status == LCG_OK; ++k) {
        status = step(&t, x, p, LCG_DRIVE_H, work);
#if LCG_DRIVE_N_CONSTRAINTS > 0
        if (status == LCG_OK) status = FN(_project)(t, x, p);
#endif
    }
    if (status != LCG_OK) printf("FAIL step_%s: status %d at step %ld\n", name, status, k);
    status = status != LCG_OK || nonfinite("step x", x, N_STATE);
    free(x), free(p), free(work);
    return status;
}

static int drive_simulate(const char *name, int method)
{
    real *x0 = copy(x0_values, N_STATE), *p = copy(p_values, N_P), *work = nans(MAC(_WORK_SIZE));
    real *t_out = nans(N_OUT), *x_out = nans(N_OUT * N_STATE), *energy = nans(N_OUT);
    real *points = nans(N_OUT * N_POINT_VALUES);
    real *residuals = M ? nans(N_OUT * 2 * M) : NULL, *multipliers = M ? nans(N_OUT * (M + N)) : NULL;
    long done = -1;
    int failures = bad_status(name, FN(_simulate)(method, 0, x0, p, LCG_DRIVE_H, STEPS, STRIDE, 1, t_out, x_out,
                                                  energy, points, residuals, multipliers, work, &done));
    if (done != STEPS) {
        printf("FAIL %s: %ld of %ld steps\n", name, done, STEPS);
        ++failures;
    }
    failures += nonfinite("simulate t", t_out, N_OUT) + nonfinite("simulate x", x_out, N_OUT * N_STATE);
    failures += LCG_DRIVE_HAS_ENERGY ? nonfinite("simulate energy", energy, N_OUT) : 0;
    failures += nonfinite("simulate points", points, N_OUT * N_POINT_VALUES);
    failures += M ? nonfinite("simulate residuals", residuals, N_OUT * 2 * M) : 0;
    failures += M ? nonfinite("simulate multipliers", multipliers, N_OUT * (M + N)) : 0;
    free(x0), free(p), free(work), free(t_out), free(x_out), free(energy), free(points);
    free(residuals), free(multipliers);
    return failures;
}

/* member m's n values of a per-member array equal member 0's, bit for bit (identical inputs) */
static int members_differ(const char *what, const real *values, long n)
{
    int m;
    for (m = 1; m < MEMBERS; ++m) {
        if (memcmp(values, values + m * n, sizeof(real) * (size_t)n) != 0) {
            printf("FAIL sweep %s: member %d differs from member 0\n", what, m);
            return 1;
        }
    }
    return 0;
}

static int drive_sweep(const char *name, int method)
{
    real *x0s = nans(MEMBERS * N_STATE), *ps = nans(MEMBERS * N_P), *work = nans(MAC(_WORK_SIZE));
    real *x_final = nans(MEMBERS * N_STATE), *q_max = nans(MEMBERS * N), *drift = nans(MEMBERS);
    real *traj = nans(MEMBERS * N_OUT * N_STATE);
    long done[MEMBERS];
    int status[MEMBERS], m, failures = 0;
    for (m = 0; m < MEMBERS; ++m) {
        memcpy(x0s + m * N_STATE, x0_values, sizeof x0_values);
        memcpy(ps + m * N_P, p_values, sizeof p_values);
    }
    FN(_sweep)(method, MEMBERS, x0s, ps, 0, LCG_DRIVE_H, STEPS, STRIDE, 1, 1, x_final, q_max, drift, status, done,
               traj, work);
    for (m = 0; m < MEMBERS; ++m) {
        failures += bad_status(name, status[m]);
        if (done[m] != STEPS) {
            printf("FAIL sweep %s: member %d did %ld of %ld steps\n", name, m, done[m], STEPS);
            ++failures;
        }
    }
    failures += nonfinite("sweep x_final", x_final, MEMBERS * N_STATE) + nonfinite("sweep q_max", q_max, MEMBERS * N);
    failures += LCG_DRIVE_HAS_ENERGY ? nonfinite("sweep energy_error", drift, MEMBERS) : 0;
    failures += nonfinite("sweep traj", traj, MEMBERS * N_OUT * N_STATE);
    failures += members_differ("x_final", x_final, N_STATE) + members_differ("traj", traj, N_OUT * N_STATE);
    free(x0s), free(ps), free(work), free(x_final), free(q_max), free(drift), free(traj);
    return failures;
}

static int drive_unknown_method(void)
{
    real *x0 = copy(x0_values, N_STATE), *p = copy(p_values, N_P), *work = nans(MAC(_WORK_SIZE));
    real *t_out = nans(N_OUT), *x_out = nans(N_OUT * N_STATE);
    long done = -1;
    const int status = FN(_simulate)(-1, 0, x0, p, LCG_DRIVE_H, STEPS, STRIDE, 0, t_out, x_out, NULL, NULL, NULL,
                                     NULL, work, &done);
    const int failed = status != LCG_UNKNOWN_METHOD || done != 0;
    if (failed) printf("FAIL method -1: status %d after %ld steps, want LCG_UNKNOWN_METHOD after 0\n", status, done);
    free(x0), free(p), free(work), free(t_out), free(x_out);
    return failed;
}

/* n_steps < 0, stride < 1, t0 or h not finite: LCG_BAD_ARGUMENT, no step done, no sample written
 * (each output holds NaN only: a caller sizing by the header allocates n_steps / stride + 1 <= 0
 * samples, or none for stride 0); an unknown method with n_steps = 0: LCG_UNKNOWN_METHOD; the step
 * function at a time that is not finite: LCG_BAD_ARGUMENT, t and x as they were */
static int drive_bad_arguments(int method, step_function step, long work_size)
{
    real *x0 = copy(x0_values, N_STATE), *p = copy(p_values, N_P), *work = nans(MAC(_WORK_SIZE));
    real *t_out = nans(1), *x_out = nans(N_STATE), *x_final = nans(N_STATE), *q_max = nans(N), *drift = nans(1);
    real *step_work = nans(work_size), *x = copy(x0_values, N_STATE), t = (real)NAN;
    const int methods[6] = {method, method, method, method, method, -1};
    const long n_steps[6] = {-5, STEPS, STEPS, STEPS, STEPS, 0}, strides[6] = {1, 1, 0, -3, 1, 1};
    const real h[6] = {LCG_DRIVE_H, (real)NAN, LCG_DRIVE_H, LCG_DRIVE_H, LCG_DRIVE_H, LCG_DRIVE_H};
    const real t0[6] = {0, 0, 0, 0, (real)INFINITY, 0};
    long done = -1, member_done = -1;
    int i, failures = 0, member_status = -1;
    for (i = 0; i < 6; ++i) {
        const int want = methods[i] == -1 ? LCG_UNKNOWN_METHOD : LCG_BAD_ARGUMENT;
        const int status = FN(_simulate)(methods[i], t0[i], x0, p, h[i], n_steps[i], strides[i], 0, t_out, x_out,
                                         NULL, NULL, NULL, NULL, work, &done);
        if (status != want || done != 0 || !isnan(t_out[0]) || !isnan(x_out[0])) {
            printf("FAIL simulate case %d: status %d after %ld steps, t_out[0] %g; want %d, nothing written\n", i,
                   status, done, (double)t_out[0], want);
            ++failures;
        }
        FN(_sweep)(methods[i], 1, x0, p, t0[i], h[i], n_steps[i], strides[i], 1, 1, x_final, q_max, drift,
                   &member_status, &member_done, x_out, work);
        if (member_status != want || member_done != 0 || !isnan(x_out[0]) || !isnan(x_final[0])) {
            printf("FAIL sweep case %d: status %d after %ld steps; want %d, nothing written\n", i, member_status,
                   member_done, want);
            ++failures;
        }
    }
    i = step(&t, x, p, LCG_DRIVE_H, step_work);
    if (i != LCG_BAD_ARGUMENT || !isnan(t) || memcmp(x, x0_values, sizeof x0_values) != 0) {
        printf("FAIL step at t = NaN: status %d; want LCG_BAD_ARGUMENT, t and x as they were\n", i);
        ++failures;
    }
    free(x0), free(p), free(work), free(t_out), free(x_out), free(x_final), free(q_max), free(drift);
    free(step_work), free(x);
    return failures;
}

#define DRIVE_METHOD(name, NAME)                                                         \
    failures += drive_steps(#name, FN(_step_##name), MAC(_WORK_##NAME));                 \
    failures += drive_simulate("simulate " #name, MAC(_METHOD_##NAME));                  \
    failures += drive_sweep(#name, MAC(_METHOD_##NAME));                                 \
    failures += drive_bad_arguments(MAC(_METHOD_##NAME), FN(_step_##name), MAC(_WORK_##NAME));  \
    ++methods;

int main(void)
{
    int failures = drive_kernels(), methods = 0;
    LCG_DRIVE_METHODS(DRIVE_METHOD)
    failures += drive_unknown_method();
    printf("%s: %d methods, %ld steps each, %d failures\n", LCG_DRIVE_NAME, methods, STEPS, failures);
    return failures != 0;
}
