/*
 * sanitizer_canary.c: proves that a -DLCG_SANITIZE=ON build really checks the generated code.
 * It calls one generated library's rhs (double precision) wrongly on purpose, as a caller might:
 *
 *   sanitizer_canary heap   xdot holds n - 1 values instead of 2 n: rhs writes past the end of a
 *                           heap block while it stores qd, before anything can fail
 *                           (AddressSanitizer: heap-buffer-overflow)
 *   sanitizer_canary align  x at an address that is not a multiple of 8: rhs loads misaligned
 *                           doubles (UndefinedBehaviorSanitizer: "load of misaligned address"),
 *                           which x86 executes without complaint when unsanitized
 *   sanitizer_canary none   the same call done right: exits 0
 *
 * Under the sanitizers the first two must abort with the sanitizer's report; unsanitized they
 * may well exit 0. Configured by CMakeLists.txt: LCG_CANARY_HEADER ("lcg_<model>.h"),
 * LCG_CANARY_PREFIX (lcg_<model>), LCG_CANARY_MACRO (LCG_<MODEL>).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include LCG_CANARY_HEADER

#define LCG_PASTE_(a, b) a##b
#define LCG_PASTE(a, b) LCG_PASTE_(a, b)
#define N_STATE LCG_PASTE(LCG_CANARY_MACRO, _N_STATE)
#define N_PARAMS LCG_PASTE(LCG_CANARY_MACRO, _N_PARAMS)
#define RHS LCG_PASTE(LCG_CANARY_PREFIX, _rhs)

int main(int argc, char **argv)
{
    const char *mode = argc > 1 ? argv[1] : "";
    double x[N_STATE], p[N_PARAMS > 0 ? N_PARAMS : 1];
    unsigned char *bytes = malloc(sizeof x + 1);
    double *xdot;
    int i, status;
    if (!bytes || (strcmp(mode, "heap") && strcmp(mode, "align") && strcmp(mode, "none"))) {
        fprintf(stderr, "usage: %s heap|align|none\n", argv[0]);
        free(bytes);
        return 2;
    }
    for (i = 0; i < N_STATE; ++i) x[i] = 0.1 * (i + 1);
    for (i = 0; i < (N_PARAMS > 0 ? N_PARAMS : 1); ++i) p[i] = 1.0;
    memcpy(bytes + 1, x, sizeof x);  /* the same values, one byte off the alignment of double */
    xdot = malloc(sizeof(double) * (strcmp(mode, "heap") == 0 ? N_STATE / 2 - 1 : N_STATE));
    if (strcmp(mode, "align") == 0) {
        status = RHS(0.0, (const double *)(void *)(bytes + 1), p, xdot);
    } else {
        status = RHS(0.0, x, p, xdot);
    }
    printf("%s: rhs returned %d\n", mode, status);
    free(xdot);
    free(bytes);
    return 0;
}
