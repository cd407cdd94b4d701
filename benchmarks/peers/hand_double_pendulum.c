/*
 * hand_double_pendulum.c: a hand-written, hand-optimized planar double pendulum, the peer that
 * lagcodegen's generated kernels are measured against (benchmarks/bench_kernels.py,
 * benchmarks/bench_integrators.py). Not generated; edit freely, then rerun the benchmarks, which
 * check it against lagcodegen's compiled rhs before timing.
 *
 * Model (same as lagcodegen.catalog.double_pendulum()): point masses m1, m2 on massless rods
 * l1, l2, gravity g, absolute angles q1, q2 from the downward vertical, speeds u_i = qd_i.
 * With s = sin(q1 - q2), c = cos(q1 - q2) the equations M(q) ud = F(q, u) read
 *
 *     M = [[(m1 + m2) l1^2,  m2 l1 l2 c],      F = [-m2 l1 l2 s u2^2 - (m1 + m2) g l1 sin q1,
 *          [m2 l1 l2 c,      m2 l2^2   ]]           m2 l1 l2 s u1^2 - m2 g l2 sin q2]
 *
 * and det M = m2 l1^2 l2^2 (m1 + m2 s^2) > 0, so Cramer's rule gives, with mu = m1 + m2,
 *
 *     ud1 = (-m2 s (l2 u2^2 + l1 c u1^2) - mu g sin q1 + m2 g c sin q2) / (l1 (m1 + m2 s^2))
 *     ud2 = (mu (l1 s u1^2 - g sin q2) + c (m2 l2 s u2^2 + mu g sin q1)) / (l2 (m1 + m2 s^2))
 *
 * The optimizations a careful hand-writer makes: sin and cos of q1 and q2 only (gcc fuses each
 * pair into one sincos call), s and c by the angle-difference identities (6 flops instead of two
 * more libm calls), the 2 x 2 solve folded into the closed form (one common denominator, two
 * divisions), and in the RK4 loop the parameter products hoisted out of the step loop.
 *
 * C99, <math.h> only, no globals: reentrant like the generated code.
 * x = (q1, q2, u1, u2), p = (m1, m2, l1, l2, g): the generated code's orders.
 */
#include <math.h>

/* Parameter products that do not change during a run. */
typedef struct {
    double m1, m2, mu, l1, l2, mu_g, m2_g;
} hand_dp_consts;

static hand_dp_consts hand_dp_make_consts(const double *p)
{
    hand_dp_consts k;
    k.m1 = p[0];
    k.m2 = p[1];
    k.mu = p[0] + p[1];
    k.l1 = p[2];
    k.l2 = p[3];
    k.mu_g = (p[0] + p[1]) * p[4];
    k.m2_g = p[1] * p[4];
    return k;
}

/* Accelerations (ud1, ud2) at (q1, q2, u1, u2): the closed form in the header comment. */
static inline void hand_dp_accel(const hand_dp_consts *k, double q1, double q2, double u1, double u2,
                                 double *ud1, double *ud2)
{
    const double s1 = sin(q1), c1 = cos(q1);
    const double s2 = sin(q2), c2 = cos(q2);
    const double s = s1 * c2 - c1 * s2;    /* sin(q1 - q2) */
    const double c = c1 * c2 + s1 * s2;    /* cos(q1 - q2) */
    const double l1u1 = k->l1 * (u1 * u1);
    const double l2u2 = k->l2 * (u2 * u2);
    const double m2s = k->m2 * s;
    const double den = k->m1 + m2s * s;
    const double g1 = k->mu_g * s1;        /* (m1 + m2) g sin q1 */
    *ud1 = (k->m2_g * c * s2 - g1 - m2s * (l2u2 + l1u1 * c)) / (k->l1 * den);
    *ud2 = (k->mu * (s * l1u1) - k->mu_g * s2 + c * (m2s * l2u2 + g1)) / (k->l2 * den);
}

/* First-order right-hand side xdot = f(t, x), 4 values (t unused: autonomous). */
void hand_dp_rhs(double t, const double *x, const double *p, double *xdot)
{
    const hand_dp_consts k = hand_dp_make_consts(p);
    (void)t;
    xdot[0] = x[2];
    xdot[1] = x[3];
    hand_dp_accel(&k, x[0], x[1], x[2], x[3], &xdot[2], &xdot[3]);
}

/* n_steps classical Runge-Kutta steps of size h from x0; the final state goes to x_out_final.
 * Stages are kept in registers: qd of a stage is the stage's u, so only ud is evaluated. */
void hand_dp_rk4_run(const double *x0, const double *p, double h, long n_steps, double *x_out_final)
{
    const hand_dp_consts k = hand_dp_make_consts(p);
    const double h2 = 0.5 * h, h6 = h / 6.0;
    double q1 = x0[0], q2 = x0[1], u1 = x0[2], u2 = x0[3];
    long step;
    for (step = 0; step < n_steps; ++step) {
        double a1, a2, b1, b2, c1, c2, d1, d2;
        hand_dp_accel(&k, q1, q2, u1, u2, &a1, &a2);
        const double u1b = u1 + h2 * a1, u2b = u2 + h2 * a2;
        hand_dp_accel(&k, q1 + h2 * u1, q2 + h2 * u2, u1b, u2b, &b1, &b2);
        const double u1c = u1 + h2 * b1, u2c = u2 + h2 * b2;
        hand_dp_accel(&k, q1 + h2 * u1b, q2 + h2 * u2b, u1c, u2c, &c1, &c2);
        const double u1d = u1 + h * c1, u2d = u2 + h * c2;
        hand_dp_accel(&k, q1 + h * u1c, q2 + h * u2c, u1d, u2d, &d1, &d2);
        q1 += h6 * (u1 + 2.0 * (u1b + u1c) + u1d);
        q2 += h6 * (u2 + 2.0 * (u2b + u2c) + u2d);
        u1 += h6 * (a1 + 2.0 * (b1 + c1) + d1);
        u2 += h6 * (a2 + 2.0 * (b2 + c2) + d2);
    }
    x_out_final[0] = q1;
    x_out_final[1] = q2;
    x_out_final[2] = u1;
    x_out_final[3] = u2;
}
