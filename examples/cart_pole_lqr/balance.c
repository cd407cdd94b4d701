/*
 * balance.c: an embedded control loop around a lagcodegen plant. The cart-pole starts 0.2 rad
 * from upright; every step the controller sets the cart force r = -K x from the state and the
 * plant advances one RK4 step with r held (x+ = step(x, r, p)). K is the discrete LQR gain that
 * examples/cart_pole_lqr.py computed from the plant's own step Jacobians.
 *
 * cart_pole_plant.h (written by examples/cart_pole_lqr.py --emit DIR) includes the emitted
 * header and defines the scalar type, the step function, the gain and the run. C99, no malloc.
 * Exit status 0 when the pole and the cart have settled, 1 when not, 2 when a step failed.
 */
#include <math.h>
#include <stdio.h>

#include "cart_pole_plant.h"

int main(void)
{
    static const plant_real gain[PLANT_N_STATE] = PLANT_GAIN;
    static const plant_real p[PLANT_N_PARAMS] = PLANT_PARAMS;
    plant_real x[PLANT_N_STATE] = PLANT_X0;
    plant_real work[PLANT_WORK];
    plant_real t = 0, r[1];
    long k;
    int i, status;
    for (k = 0; k < PLANT_STEPS; ++k) {
        plant_real force = 0;
        for (i = 0; i < PLANT_N_STATE; ++i) force -= gain[i] * x[i];
        r[0] = force;
        status = PLANT_STEP(&t, x, r, p, PLANT_H, work);
        if (status != LCG_OK) {
            printf("step %ld failed with status %d\n", k, status);
            return 2;
        }
    }
    printf("t = %.3f: cart %.3e m, pole %.3e rad, speeds %.3e m/s, %.3e rad/s\n", (double)t, (double)x[0],
           (double)x[1], (double)x[2], (double)x[3]);
    return fabs((double)x[1]) < PLANT_SETTLED && fabs((double)x[0]) < PLANT_SETTLED ? 0 : 1;
}
