/* SPDX-License-Identifier: MIT */
/* afm_pi.h -- the reference Z controller of an AM-AFM (issue 18): a PI loop on the lock-in
 * amplitude that moves the separation Z so that the amplitude stays at set-point ratio x free
 * amplitude, with the slew limit and range of a Z piezo. An amplitude below the set-point
 * (the tip taps harder: the surface came up) retracts (Z grows); above it approaches.
 *
 *   e = A_set - A (m);  Z = Z_i + kp e,  dZ_i/dt = ki e,  |dZ/dt| <= z_rate_max, Z in range.
 *
 * Layer runner/ (5) (no dependencies). No allocation; one update is a few flops. */
#ifndef AFM_PI_H
#define AFM_PI_H

/* The gains and slew limits afm_scan_run accepts. */
#define AFM_PI_KP_MAX 1e3
#define AFM_PI_KI_MAX_HZ 1e8
#define AFM_PI_Z_RATE_MAX_M_S 10.0

typedef struct {
    double kp;             /* proportional gain (m of Z per m of amplitude error), >= 0 */
    double ki_hz;          /* integral gain (1/s: Z moves ki e per second), > 0 */
    double setpoint_ratio; /* A_set / A_free, 0 < r < 1 */
    double z_rate_max_m_s; /* the piezo's slew limit, > 0 */
    double z_min_m, z_max_m;
} afm_pi_cfg;

typedef struct {
    afm_pi_cfg c;
    double a_set_m; /* set-point amplitude */
    double z_i_m;   /* the integrator */
    double z_m;     /* the output */
    double e_m;     /* the last error */
} afm_pi;

/* Start at Z = z0_m with set-point c->setpoint_ratio * a_free_m. */
void afm_pi_init(afm_pi *p, const afm_pi_cfg *c, double a_free_m, double z0_m);

/* One update with the measured amplitude a_m after dt_s; returns the new Z (m). A
 * non-finite a_m changes nothing. */
double afm_pi_update(afm_pi *p, double a_m, double dt_s);

#endif
