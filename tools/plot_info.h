/* SPDX-License-Identifier: MIT */
/* plot_info.h -- what the title of an `afmtwin plot` picture says about the run: the config
 * (its model's f0, Q and k) and the drive (fe, Ae, the free amplitude A0, Z), gathered from
 * the config file (--config), the overrides the run was given (--fe, --ae, --z of plot) and
 * what the records themselves carry (the swept fe or Z, A0, the continuation parameter).
 *
 * Values the records carry win over the command line, which wins over the config. The
 * config's fe is trusted only where the records do not contradict it: approach records
 * carry the free response at the drive (A0 and its lag), and a lag that the model does not
 * have at the config's fe means the run drove elsewhere (fe is then left out, and Ae too).
 * The config's Ae gives way to Ae = A0 / |G(fe)| where the records carry an A0 it does not
 * give. */
#ifndef AFMT_PLOT_INFO_H
#define AFMT_PLOT_INFO_H

#include "beam/afm_model.h"
#include "forces/afm_force.h"

#include <stdbool.h>
#include <stddef.h>

typedef struct {
    /* --config (config "" without) */
    char config[128]; /* the file's name without its directories */
    bool have_model;
    afm_modal model;
    bool have_forces; /* forces: the config's (for the squeeze film in A0) */
    afm_force_params forces;
    double cfg_fe_hz, cfg_ae_m, cfg_z_m; /* tone 0 and the separation */
    /* the run's overrides as given to plot (NAN: not given) */
    double opt_fe_hz, opt_ae_m, opt_z_m;
    /* what the records carry (NAN, "": nothing) */
    double a0_m, a0_lag_deg;   /* the free amplitude and its lag at the drive */
    double fe_lo_hz, fe_hi_hz; /* the drive frequencies of the records */
    double z_lo_m, z_hi_m;     /* the separations of the records */
    char param[32];            /* the continuation parameter and its range (SI) */
    double p_lo, p_hi;
    double temperature_k, seconds; /* a thermal tune */
    /* what the kind leaves out of the line */
    bool no_drive; /* thermal: no drive at all */
    bool no_z;     /* scan: Z is the controller's */
} plot_info;

/* Everything unknown. */
void plot_info_init(plot_info *pi);

/* Read FILE (the run's --config) into pi: its name, model and drive. 0, or -1 with the
 * reason on stderr. */
int plot_info_config(plot_info *pi, const char *path);

/* Widen the range of drive frequencies (Hz) or separations (m) the records carry by v
 * (NAN ignored). */
void plot_info_fe(plot_info *pi, double fe_hz);
void plot_info_z(plot_info *pi, double z_m);
/* The continuation parameter NAME took the value v (SI). */
void plot_info_param(plot_info *pi, const char *name, double v);

/* The line under the title: "CONFIG: f0 .., Q .., k .. N/m; drive fe .., Ae .., A0 ..;
 * Z .." with what is known; "" when nothing is. */
void plot_info_line(const plot_info *pi, char *out, size_t n);

/* The free amplitude A0 per unit drive amplitude and its lag (deg) at f_hz: the model's
 * linear response with the config's squeeze film at Z 1 um (runner/afm_a0.h, within 1e-5 of
 * A0 on the accurate scheme): 0, or -1 without a model. */
int plot_info_free(const plot_info *pi, double f_hz, double *gain, double *lag_deg);

/* The note under the title of every picture that draws a phase: the project's one convention
 * (README "Conventions"), so that a reader of the picture alone knows which phase it is. */
#define PLOT_LAG_NOTE                                                                              \
    "phase lag: of the deflection behind the drive, 90 deg when free at resonance, below 90 "      \
    "repulsive"

#endif
