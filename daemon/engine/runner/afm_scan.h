/* SPDX-License-Identifier: MIT */
/* afm_scan.h -- imaging a sample offline (issue 18): the tip rasters over the surface while
 * the reference controller (afm_pi: PI on the lock-in amplitude, acting on Z) holds the
 * set-point, and every pixel reports what an AM-AFM images (controller height, amplitude
 * error, phase, peak force, dissipated energy) beside the truth under the tip (height and
 * material region).
 *
 * The raster: lines of `pixels` pixels along x, trace (x growing) then retrace, at
 * line_rate_hz (trace + retrace per second); the slow axis y moves continuously, one line
 * pitch per line, as on a real scanner. Every update_samples samples the tip's lateral
 * position is taken at the middle of the next update, the integrator gets the separation
 * Z - z_s(x, y) and the forces of the material there, the estimators (lock-in at tone 0,
 * afm_cycle) take the samples, and the controller moves Z. Before the first line the tip
 * engages at the scan origin for engage_s.
 *
 * Phase: the lock-in's lag of the deflection behind the drive (90 deg free at resonance).
 * Heights: height_m is the controller's Z less its value at the end of the engage, plus the
 * true height at the origin, so that a perfect controller images z_s exactly.
 *
 * Layer runner/ (5) (uses afm_sim, afm_surface, afm_lockin, afm_cycle, afm_pi). Allocates
 * its estimators per run; not real-time (the daemon's scan is the runner's job). */
#ifndef AFM_SCAN_H
#define AFM_SCAN_H

#include "config/afm_config.h"
#include "forces/afm_force.h"
#include "forces/afm_surface.h"
#include "integrators/afm_sim.h"
#include "runner/afm_pi.h"

#include <stdbool.h>
#include <stddef.h>

/* The ranges afm_scan_run accepts (afmtwin scan's options use the same). */
#define AFM_SCAN_PIXELS_MAX 100000
#define AFM_SCAN_LINES_MAX 100000
#define AFM_SCAN_LINE_RATE_MAX_HZ 1e4
#define AFM_SCAN_SIZE_MAX_M 1e-3
#define AFM_SCAN_ORIGIN_MAX_M 1.0 /* |x0|, |y0| */
#define AFM_SCAN_ENGAGE_MAX_S 10.0
#define AFM_SCAN_UPDATE_MAX 4096 /* samples per update */

typedef struct {
    double x0_m, y0_m;         /* the first pixel of the first line */
    double size_x_m, size_y_m; /* scan size (size_y 0: the same line again and again) */
    int pixels, lines;         /* per line (>= 2), lines (>= 1) */
    double line_rate_hz;       /* trace + retrace per second, > 0 */
    double engage_s;           /* dwell at the origin before the first line, >= 0 */
    int update_samples;        /* position / controller update period (samples), >= 1 */
} afm_scan_cfg;

typedef struct {
    int line, pixel; /* pixel index along the scan direction (0 = left end) */
    bool retrace;
    double x_m, y_m;                    /* the tip's position at the pixel's middle */
    double true_height_m;               /* z_s there */
    int material;                       /* region there (0 = the forces group's sample) */
    double height_m;                    /* the controller's image (see above) */
    double z_m;                         /* the controller's Z, mean over the pixel */
    double amplitude_m;                 /* lock-in amplitude, mean over the pixel */
    double error_m;                     /* set-point less amplitude, mean over the pixel */
    double phase_lag_deg;               /* lock-in lag, mean over the pixel */
    double peak_force_n;                /* mean over the periods that ended in the pixel */
    double dissipated_energy_j;         /* per period, mean over those periods (tip-sample) */
    double squeeze_dissipated_energy_j; /* the squeeze film's, the same way (afm_cycle.h) */
    double free_amplitude_m; /* A0 (runner/afm_a0.h; the set-point is its setpoint_ratio) */
    int periods;             /* drive periods that ended in the pixel */
} afm_scan_pixel;

typedef void (*afm_scan_on_pixel)(void *ctx, const afm_scan_pixel *px);

/* The twin for a scan of cfg's sample: cfg->forces becomes material 0's (with the terms of
 * every material on: afm_surface_material_forces), then afm_twin_create (the model into m).
 * NULL with err on failure. */
afm_sim *afm_scan_twin_create(afm_config *cfg, afm_modal *m, char *err, size_t errlen);

/* Image the sample: s and m from afm_scan_twin_create(cfg) (its separation is the approach's
 * start), surf from cfg->sample; the materials derive from cfg->forces, the lock-in is
 * cfg->lockin. on_pixel gets every pixel in scan order. 0, or -1 with err (bad scan
 * parameters, a failed simulation). */
int afm_scan_run(afm_sim *s, const afm_config *cfg, const afm_modal *m, const afm_surface *surf,
                 const afm_scan_cfg *sc, const afm_pi_cfg *pc, afm_scan_on_pixel on_pixel,
                 void *ctx, char *err, size_t errlen);

/* The tip's lateral position at time t_s after the first line's start. */
void afm_scan_position(const afm_scan_cfg *sc, double t_s, double *x_m, double *y_m, int *line,
                       int *pixel, bool *retrace);

#endif
