/* SPDX-License-Identifier: MIT */
/* cmd_scan.c -- `afmtwin scan`: image the config's sample offline with the reference
 * controller (issue 18; afm_scan.h): a raster of lines, a PI loop on the lock-in amplitude
 * acting on Z, and per pixel the controller's height beside the true height, the amplitude
 * error, the phase (lag of the deflection behind the drive, 90 deg free at resonance), the
 * peak force and the energy dissipated per period. */
#include "afmtwin_cmds.h"

#include "config/afm_config.h"
#include "forces/afm_surface.h"
#include "runner/afm_scan.h"
#include "runner/afm_twin.h"
#include "json_out.h"
#include "opts.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    const char *config;
    afm_scan_cfg sc;
    afm_pi_cfg pc;
    int integrator; /* -1: the config's */
    bool json;
} scan_opts;

static void scan_usage(FILE *f) {
    fprintf(f, "usage: afmtwin scan --config FILE [--size-x M] [--size-y M] [--x0 M] [--y0 M]\n"
               "                    [--pixels N] [--lines N] [--line-rate HZ] [--engage S]\n"
               "                    [--setpoint R] [--kp K] [--ki HZ] [--z-rate M_S]\n"
               "                    [--update N] [--integrator rt|reference] [--json]\n\n"
               "Image the sample of the config's `sample` group offline, as an AM-AFM does: the\n"
               "tip rasters lines along x (trace, then retrace), the slow axis y moving one line\n"
               "pitch per line, while a PI loop on the lock-in amplitude (the config's lockin\n"
               "group) moves Z to hold set-point x free amplitude (the free amplitude is measured\n"
               "first, 1 um off the surface); the tip engages at the origin first. The gap is\n"
               "d = x cos(alpha) + Z - z_s(x_tip, y_tip) with the material under the tip.\n"
               "Per pixel: the controller's height (Z less its value after the engage, plus the\n"
               "true height at the origin: a perfect loop images z_s), the true height and\n"
               "material there, the amplitude and its error (set-point less amplitude), the\n"
               "phase: lag of the deflection behind the drive (90 deg free at resonance), the\n"
               "peak force and the energy dissipated per drive period (means over the pixel).\n\n"
               "options:\n"
               "  --config FILE    libconfig model file with a sample group (config/README.md)\n"
               "  --size-x M       scan length along x (default 4e-7 m)\n"
               "  --size-y M       scan length along y (default 0: one line again and again)\n"
               "  --x0 M, --y0 M   the scan's origin (default 0, 0)\n"
               "  --pixels N       pixels per line, 2..100000 (default 64)\n"
               "  --lines N        lines, 1..100000 (default 1)\n"
               "  --line-rate HZ   lines (trace + retrace) per second (default 10)\n"
               "  --engage S       dwell at the origin before the first line (default 0.02 s)\n"
               "  --setpoint R     amplitude set-point as a fraction of the free amplitude,\n"
               "                   0 < R < 1 (default 0.8)\n"
               "  --kp K           proportional gain, m of Z per m of error (default 0)\n"
               "  --ki HZ          integral gain, 1/s (default 2000)\n"
               "  --z-rate M_S     slew limit of Z, the piezo's (default 1e-3 m/s)\n"
               "  --update N       samples per controller update (default 64: 4.6 us at\n"
               "                   14.06 MHz, the daemon's ramp grid)\n"
               "  --integrator NAME  rt (the daemon's) or reference (CVODE); default the config's\n"
               "  --json           one JSON object per pixel and line: line, pixel, retrace, x_m,\n"
               "                   y_m, true_height_m, material, height_m, z_m, amplitude_m,\n"
               "                   error_m, phase_lag_deg, peak_force_n, dissipated_energy_j,\n"
               "                   periods, free_amplitude_m\n"
               "  --help           this text\n\n"
               "Exit status 0 ok, 1 simulation failure, 2 bad usage or bad input.\n");
}

/* --integrator: rt or reference into an int (AFM_INTEGRATOR_*). */
static int opt_scan_integrator(const char *v, void *dest) {
    int *k = dest;
    *k = !strcmp(v, "rt")          ? AFM_INTEGRATOR_RT
         : !strcmp(v, "reference") ? AFM_INTEGRATOR_REFERENCE
                                   : -1;
    return *k < 0 ? -1 : 0;
}

/* 1 help, 0 ok, -1 bad usage (said). The ranges are afm_scan's (AFM_SCAN_*, AFM_PI_*). */
static int parse_args(int argc, char **argv, scan_opts *o) {
    *o = (scan_opts){.sc = {.size_x_m = 4e-7,
                            .pixels = 64,
                            .lines = 1,
                            .line_rate_hz = 10,
                            .engage_s = 0.02,
                            .update_samples = 64},
                     .pc = {.kp = 0,
                            .ki_hz = 2000,
                            .setpoint_ratio = 0.8,
                            .z_rate_max_m_s = 1e-3,
                            .z_min_m = 0,
                            .z_max_m = 1e-5},
                     .integrator = -1};
    const afmt_opt opts[] = {
        AFMT_FLAG("--json", &o->json),
        AFMT_STRING("--config", &o->config),
        AFMT_DOUBLE_ABOVE("--size-x", &o->sc.size_x_m, 0, AFM_SCAN_SIZE_MAX_M, NULL),
        AFMT_DOUBLE("--size-y", &o->sc.size_y_m, 0, AFM_SCAN_SIZE_MAX_M, NULL),
        AFMT_DOUBLE("--x0", &o->sc.x0_m, -AFM_SCAN_ORIGIN_MAX_M, AFM_SCAN_ORIGIN_MAX_M, NULL),
        AFMT_DOUBLE("--y0", &o->sc.y0_m, -AFM_SCAN_ORIGIN_MAX_M, AFM_SCAN_ORIGIN_MAX_M, NULL),
        AFMT_INT("--pixels", &o->sc.pixels, 2, AFM_SCAN_PIXELS_MAX, NULL),
        AFMT_INT("--lines", &o->sc.lines, 1, AFM_SCAN_LINES_MAX, NULL),
        AFMT_DOUBLE_ABOVE("--line-rate", &o->sc.line_rate_hz, 0, AFM_SCAN_LINE_RATE_MAX_HZ, NULL),
        AFMT_DOUBLE("--engage", &o->sc.engage_s, 0, AFM_SCAN_ENGAGE_MAX_S, NULL),
        AFMT_INT("--update", &o->sc.update_samples, 1, AFM_SCAN_UPDATE_MAX, NULL),
        AFMT_DOUBLE_ABOVE("--setpoint", &o->pc.setpoint_ratio, 0, 0.999999, "(0, 1)"),
        AFMT_DOUBLE("--kp", &o->pc.kp, 0, AFM_PI_KP_MAX, NULL),
        AFMT_DOUBLE_ABOVE("--ki", &o->pc.ki_hz, 0, AFM_PI_KI_MAX_HZ, NULL),
        AFMT_DOUBLE_ABOVE("--z-rate", &o->pc.z_rate_max_m_s, 0, AFM_PI_Z_RATE_MAX_M_S, NULL),
        AFMT_FN("--integrator", opt_scan_integrator, &o->integrator, "rt or reference"),
        AFMT_OPTS_END,
    };
    int rc = afmt_opts_parse("scan", opts, argc, argv, 1);
    if (rc) return rc == AFMT_OPTS_HELP ? 1 : -1;
    if (!o->config) {
        fprintf(stderr, "afmtwin scan: --config is required\n");
        return -1;
    }
    return 0;
}

static void print_pixel(void *ctx, const afm_scan_pixel *p) {
    const scan_opts *o = ctx;
    if (o->json) {
        cJSON *j = cJSON_CreateObject();
        cJSON_AddNumberToObject(j, "line", p->line);
        cJSON_AddNumberToObject(j, "pixel", p->pixel);
        cJSON_AddBoolToObject(j, "retrace", p->retrace);
        cJSON_AddNumberToObject(j, "x_m", p->x_m);
        cJSON_AddNumberToObject(j, "y_m", p->y_m);
        cJSON_AddNumberToObject(j, "true_height_m", p->true_height_m);
        cJSON_AddNumberToObject(j, "material", p->material);
        cJSON_AddNumberToObject(j, "height_m", p->height_m);
        cJSON_AddNumberToObject(j, "z_m", p->z_m);
        cJSON_AddNumberToObject(j, "amplitude_m", p->amplitude_m);
        cJSON_AddNumberToObject(j, "error_m", p->error_m);
        cJSON_AddNumberToObject(j, "phase_lag_deg", p->phase_lag_deg);
        if (isfinite(p->peak_force_n)) {
            cJSON_AddNumberToObject(j, "peak_force_n", p->peak_force_n);
            cJSON_AddNumberToObject(j, "dissipated_energy_j", p->dissipated_energy_j);
        } else {
            cJSON_AddNullToObject(j, "peak_force_n");
            cJSON_AddNullToObject(j, "dissipated_energy_j");
        }
        cJSON_AddNumberToObject(j, "periods", p->periods);
        cJSON_AddNumberToObject(j, "free_amplitude_m", p->free_amplitude_m);
        afmt_json_emit(j);
        return;
    }
    printf("%5d %6d %2s %10.3f %10.3f %9.4f %3d %9.4f %9.4f %9.4f %9.3f %10.4f %10.4f\n", p->line,
           p->pixel, p->retrace ? "R" : "T", p->x_m * 1e9, p->y_m * 1e9, p->true_height_m * 1e9,
           p->material, p->height_m * 1e9, p->amplitude_m * 1e9, p->error_m * 1e9, p->phase_lag_deg,
           p->peak_force_n * 1e9, p->dissipated_energy_j / 1.602176634e-19);
}

int afm_cmd_scan(int argc, char **argv) {
    scan_opts o;
    int rc = afmt_opts_done("scan", parse_args(argc, argv, &o), scan_usage);
    if (rc >= 0) return rc;
    static afm_config cfg;
    static afm_modal m;
    char err[AFM_ERR_LEN];
    if (afm_config_load(o.config, &cfg, err, sizeof err) != 0) {
        fprintf(stderr, "afmtwin scan: %s\n", err);
        return 2;
    }
    if (o.integrator >= 0) cfg.sim.integrator = (afm_integrator_kind)o.integrator;
    if (!cfg.sample.enabled)
        fprintf(stderr, "afmtwin scan: %s has no sample group: a flat, uniform sample\n", o.config);
    afm_surface *surf = NULL;
    if (afm_surface_create(&surf, &cfg.sample, cfg.forces.radius_m, err, sizeof err) != 0) {
        fprintf(stderr, "afmtwin scan: %s\n", err);
        return 2;
    }
    afm_sim *sim = afm_scan_twin_create(&cfg, &m, err, sizeof err);
    if (!sim) {
        fprintf(stderr, "afmtwin scan: %s\n", err);
        afm_surface_destroy(&surf);
        return 1;
    }
    if (!o.json)
        printf("# afmtwin scan %s: integrator %s (scheme %s), %d x %d pixels, %.4g x %.4g nm, %g "
               "lines/s, "
               "set-point %g, ki %g 1/s, kp %g; phase: lag of the deflection behind the drive "
               "(90 deg free at resonance)\n"
               "# line pixel T/R  x_nm  y_nm  true_nm  material  height_nm  A_nm  error_nm  "
               "lag_deg  peak_force_nN  E_diss_eV\n",
               o.config, afm_sim_integrator_name(sim), afm_sim_scheme_name(sim), o.sc.pixels,
               o.sc.lines, o.sc.size_x_m * 1e9, o.sc.size_y_m * 1e9, o.sc.line_rate_hz,
               o.pc.setpoint_ratio, o.pc.ki_hz, o.pc.kp);
    rc = afm_scan_run(sim, &cfg, &m, surf, &o.sc, &o.pc, print_pixel, &o, err, sizeof err);
    if (rc) fprintf(stderr, "afmtwin %s\n", err);
    afm_sim_destroy(&sim);
    afm_surface_destroy(&surf);
    return rc ? (strstr(err, "simulation failed") ? 1 : 2) : 0;
}
