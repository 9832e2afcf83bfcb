/* SPDX-License-Identifier: MIT */
/* cmd_scan.c -- `afmtwin scan`: image the config's sample offline with the reference
 * controller (issue 18; afm_scan.h): a raster of lines, a PI loop on the lock-in amplitude
 * acting on Z, and per pixel the controller's height beside the true height, the amplitude
 * error, the phase (lag of the deflection behind the drive, 90 deg free at resonance), the
 * peak force and the energy dissipated per period. With --gsf every image also goes to a
 * Gwyddion Simple Field file, trace and retrace apart (issue 30; gsf_write.h). */
#include "afmtwin_cmds.h"

#include "config/afm_config.h"
#include "forces/afm_surface.h"
#include "runner/afm_scan.h"
#include "runner/afm_twin.h"
#include "gsf_write.h"
#include "json_out.h"
#include "opts.h"

#include <cjson/cJSON.h>
#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct gsf_out gsf_out;

typedef struct {
    const char *config;
    afm_scan_cfg sc;
    afm_pi_cfg pc;
    int integrator; /* -1: the config's */
    bool json;
    const char *gsf_prefix; /* --gsf */
    gsf_out *gsf;           /* its files while the scan runs */
    afmt_progress pg;       /* on stderr, terminals only */
} scan_opts;

static void scan_usage(FILE *f) {
    fprintf(f, "usage: afmtwin scan --config FILE [--size-x M] [--size-y M] [--x0 M] [--y0 M]\n"
               "                    [--pixels N] [--lines N] [--line-rate HZ] [--engage S]\n"
               "                    [--setpoint R] [--kp K] [--ki HZ] [--z-rate M_S]\n"
               "                    [--update N] [--integrator rt|reference] [--json]\n"
               "                    [--gsf PREFIX]\n\n"
               "Image the sample of the config's `sample` group offline, as an AM-AFM does: the\n"
               "tip rasters lines along x (trace, then retrace), the slow axis y moving one line\n"
               "pitch per line, while a PI loop on the lock-in amplitude (the config's lockin\n"
               "group) moves Z to hold set-point x A0 (A0, the free amplitude: harmonic 1 at Z 1\n"
               "um with the gap-dependent tip forces off and the squeeze film on, as approach and\n"
               "the daemon; the lever rings up there first); the tip engages at the origin\n"
               "first. The gap is\n"
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
               "  --setpoint R     amplitude set-point as a fraction of A0 (the free amplitude),\n"
               "                   0 < R < 1 (default the config's am.setpoint_ratio, 0.8)\n"
               "  --kp K           proportional gain, m of Z per m of error (default am.kp, 0)\n"
               "  --ki HZ          integral gain, 1/s (default am.ki_hz, 2000)\n"
               "  --z-rate M_S     slew limit of Z, the piezo's (default am.z_rate_max_m_s,\n"
               "                   1e-3 m/s); Z stays in am.z_min_m .. am.z_max_m (0 .. 10 um)\n"
               "  --update N       samples per controller update (default 64: 4.6 us at\n"
               "                   14.06 MHz, the daemon's ramp grid)\n"
               "  --integrator NAME  rt (the daemon's) or reference (CVODE); default the config's\n"
               "  --json           one JSON object per pixel and line: line, pixel, retrace, x_m,\n"
               "                   y_m, true_height_m, material, height_m, z_m, amplitude_m,\n"
               "                   error_m, phase_lag_deg, peak_force_n, dissipated_energy_j,\n"
               "                   squeeze_dissipated_energy_j, periods, free_amplitude_m;\n"
               "                   peak force and dissipation are the tip-sample force's, the\n"
               "                   squeeze film's dissipation (air on the beam) apart\n"
               "  --gsf PREFIX     also write each image as a Gwyddion Simple Field file, as AFM\n"
               "                   software opens it: PREFIX-NAME-trace.gsf and\n"
               "                   PREFIX-NAME-retrace.gsf for NAME height, true-height, z,\n"
               "                   amplitude, error (m), phase (lag, deg), peak-force (N),\n"
               "                   dissipation (the tip-sample force's, J per period),\n"
               "                   squeeze-dissipation (the squeeze film's, J per period) and\n"
               "                   material (region index); a\n"
               "                   row per line, x0 and y0 its offsets, size-x wide and lines x\n"
               "                   line pitch high (square pixels without a slow axis); NaN\n"
               "                   where a pixel has no value\n"
               "  --help           this text\n\n" AFMT_OPT_SI_HELP
               "Progress on stderr (terminals only).\n"
               "Exit status 0 ok, 1 simulation failure or a .gsf file not written, 2 bad usage\n"
               "or bad input (a .gsf file that cannot be created).\n");
}

/* --integrator: rt or reference into an int (AFM_INTEGRATOR_*). */
static const afmt_choice scan_integrator_choices[] = {
    {"rt", AFM_INTEGRATOR_RT}, {"reference", AFM_INTEGRATOR_REFERENCE}, {NULL, 0}};

/* 1 help, 0 ok, -1 bad usage (said). The ranges are afm_scan's (AFM_SCAN_*, AFM_PI_*). */
static int parse_args(int argc, char **argv, scan_opts *o) {
    *o = (scan_opts){.sc = {.size_x_m = 4e-7,
                            .pixels = 64,
                            .lines = 1,
                            .line_rate_hz = 10,
                            .engage_s = 0.02,
                            .update_samples = 64},
                     /* NAN: the config's am group's (or its defaults), below */
                     .pc = {.kp = NAN,
                            .ki_hz = NAN,
                            .setpoint_ratio = NAN,
                            .z_rate_max_m_s = NAN,
                            .z_min_m = NAN,
                            .z_max_m = NAN},
                     .integrator = -1};
    const afmt_opt opts[] = {
        AFMT_FLAG("--json", &o->json),
        AFMT_STRING("--config", &o->config),
        AFMT_STRING("--gsf", &o->gsf_prefix),
        AFMT_LENGTH_ABOVE("--size-x", &o->sc.size_x_m, 0, AFM_SCAN_SIZE_MAX_M, NULL),
        AFMT_LENGTH("--size-y", &o->sc.size_y_m, 0, AFM_SCAN_SIZE_MAX_M, NULL),
        AFMT_LENGTH("--x0", &o->sc.x0_m, -AFM_SCAN_ORIGIN_MAX_M, AFM_SCAN_ORIGIN_MAX_M, NULL),
        AFMT_LENGTH("--y0", &o->sc.y0_m, -AFM_SCAN_ORIGIN_MAX_M, AFM_SCAN_ORIGIN_MAX_M, NULL),
        AFMT_INT("--pixels", &o->sc.pixels, 2, AFM_SCAN_PIXELS_MAX, NULL),
        AFMT_INT("--lines", &o->sc.lines, 1, AFM_SCAN_LINES_MAX, NULL),
        AFMT_FREQ_ABOVE("--line-rate", &o->sc.line_rate_hz, 0, AFM_SCAN_LINE_RATE_MAX_HZ, NULL),
        AFMT_DOUBLE("--engage", &o->sc.engage_s, 0, AFM_SCAN_ENGAGE_MAX_S, NULL),
        AFMT_INT("--update", &o->sc.update_samples, 1, AFM_SCAN_UPDATE_MAX, NULL),
        AFMT_DOUBLE_ABOVE("--setpoint", &o->pc.setpoint_ratio, 0, 0.999999, "(0, 1)"),
        AFMT_DOUBLE("--kp", &o->pc.kp, 0, AFM_PI_KP_MAX, NULL),
        AFMT_DOUBLE_ABOVE("--ki", &o->pc.ki_hz, 0, AFM_PI_KI_MAX_HZ, NULL),
        AFMT_DOUBLE_ABOVE("--z-rate", &o->pc.z_rate_max_m_s, 0, AFM_PI_Z_RATE_MAX_M_S, NULL),
        AFMT_CHOICE("--integrator", &o->integrator, scan_integrator_choices),
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

/* --gsf: the images, one per channel and direction (gsf_write.h), in SI units. */
static const struct {
    const char *name, *title, *z_units; /* PREFIX-name-trace.gsf, ...-retrace.gsf */
    size_t off;                         /* the value in afm_scan_pixel: a double, */
    bool is_int;                        /* or an int (material) */
} gsf_chan[] = {
    {"height", "Height", "m", offsetof(afm_scan_pixel, height_m), false},
    {"true-height", "True height", "m", offsetof(afm_scan_pixel, true_height_m), false},
    {"z", "Z", "m", offsetof(afm_scan_pixel, z_m), false},
    {"amplitude", "Amplitude", "m", offsetof(afm_scan_pixel, amplitude_m), false},
    {"error", "Amplitude error", "m", offsetof(afm_scan_pixel, error_m), false},
    {"phase", "Phase lag", "deg", offsetof(afm_scan_pixel, phase_lag_deg), false},
    {"peak-force", "Peak force", "N", offsetof(afm_scan_pixel, peak_force_n), false},
    {"dissipation", "Dissipated energy", "J", offsetof(afm_scan_pixel, dissipated_energy_j), false},
    {"squeeze-dissipation", "Squeeze-film dissipated energy", "J",
     offsetof(afm_scan_pixel, squeeze_dissipated_energy_j), false},
    {"material", "Material", "", offsetof(afm_scan_pixel, material), true},
};
#define GSF_NCHAN ((int)(sizeof gsf_chan / sizeof gsf_chan[0]))
static const char *const gsf_dir[2] = {"trace", "retrace"};

struct gsf_out {
    int pixels, lines;
    FILE *f[GSF_NCHAN][2]; /* [channel][retrace] */
    char *path[GSF_NCHAN][2];
    float *row;      /* the line being scanned: [retrace][channel][pixel], NaN until imaged */
    int line;        /* its index; the rows before it are written */
    int write_errno; /* the first write error, 0 none */
};

static float *gsf_row(gsf_out *g, int retrace, int ch) {
    return g->row + ((size_t)retrace * GSF_NCHAN + (size_t)ch) * (size_t)g->pixels;
}

/* Write the current line's rows to every file, then start the next line. */
static void gsf_next_line(gsf_out *g) {
    for (int d = 0; d < 2; d++)
        for (int c = 0; c < GSF_NCHAN; c++) {
            float *r = gsf_row(g, d, c);
            if (!g->write_errno && afmt_gsf_write_values(g->f[c][d], r, (size_t)g->pixels))
                g->write_errno = errno ? errno : EIO;
            for (int i = 0; i < g->pixels; i++)
                r[i] = NAN;
        }
    g->line++;
}

static void gsf_pixel(gsf_out *g, const afm_scan_pixel *p) {
    if (p->line < g->line || p->line >= g->lines || p->pixel < 0 || p->pixel >= g->pixels) return;
    while (g->line < p->line)
        gsf_next_line(g);
    for (int c = 0; c < GSF_NCHAN; c++) {
        const char *v = (const char *)p + gsf_chan[c].off;
        double x;
        if (gsf_chan[c].is_int) {
            int k;
            memcpy(&k, v, sizeof k);
            x = k;
        } else
            memcpy(&x, v, sizeof x);
        gsf_row(g, p->retrace, c)[p->pixel] = (float)x;
    }
}

/* Close every file; remove them all when `keep` is false. -1 when one did not close well. */
static int gsf_close(gsf_out *g, bool keep) {
    int rc = 0;
    for (int c = 0; c < GSF_NCHAN; c++)
        for (int d = 0; d < 2; d++) {
            if (g->f[c][d] && fclose(g->f[c][d]) != 0) rc = -1;
            if (!keep && g->path[c][d]) remove(g->path[c][d]);
            free(g->path[c][d]);
        }
    free(g->row);
    free(g);
    return rc;
}

/* Create the files of --gsf and write their headers: the image is the scan's raster, x along
 * the lines (pixel i spans x0 + [i, i+1) size_x / pixels), a row per line (line j spans y0 +
 * [j, j+1) pitch while it is traced and retraced; the pitch is size_y / (lines - 1), or with
 * no slow axis the pixel's width). NULL with a message. */
static gsf_out *gsf_open(const char *prefix, const afm_scan_cfg *sc) {
    gsf_out *g = calloc(1, sizeof *g);
    size_t n = (size_t)sc->pixels * 2 * GSF_NCHAN;
    if (!g || !(g->row = malloc(n * sizeof *g->row))) {
        fprintf(stderr, "afmtwin scan: --gsf: out of memory\n");
        free(g);
        return NULL;
    }
    for (size_t i = 0; i < n; i++)
        g->row[i] = NAN;
    g->pixels = sc->pixels;
    g->lines = sc->lines;
    double dx = sc->size_x_m / sc->pixels;
    double pitch = sc->lines > 1 && sc->size_y_m > 0 ? sc->size_y_m / (sc->lines - 1) : dx;
    for (int c = 0; c < GSF_NCHAN; c++)
        for (int d = 0; d < 2; d++) {
            char title[64];
            snprintf(title, sizeof title, "%s (%s)", gsf_chan[c].title, gsf_dir[d]);
            afmt_gsf_header h = {.xres = sc->pixels,
                                 .yres = sc->lines,
                                 .xreal = sc->size_x_m,
                                 .yreal = sc->lines * pitch,
                                 .xoffset = sc->x0_m,
                                 .yoffset = sc->y0_m,
                                 .xy_units = "m",
                                 .z_units = gsf_chan[c].z_units,
                                 .title = title};
            size_t len = strlen(prefix) + strlen(gsf_chan[c].name) + 16;
            char *path = g->path[c][d] = malloc(len);
            if (!path) {
                fprintf(stderr, "afmtwin scan: --gsf: out of memory\n");
                gsf_close(g, false);
                return NULL;
            }
            snprintf(path, len, "%s-%s-%s.gsf", prefix, gsf_chan[c].name, gsf_dir[d]);
            if (!(g->f[c][d] = fopen(path, "wb")) || afmt_gsf_write_header(g->f[c][d], &h)) {
                fprintf(stderr, "afmtwin scan: cannot write %s: %s\n", path, strerror(errno));
                if (!g->f[c][d]) {
                    free(path);
                    g->path[c][d] = NULL;
                }
                gsf_close(g, false);
                return NULL;
            }
        }
    return g;
}

/* The scan is over: the rows not yet written (NaN for lines it did not reach), then close.
 * 0, or -1 with a message and no files left. */
static int gsf_finish(gsf_out *g) {
    while (g->line < g->lines)
        gsf_next_line(g);
    int e = g->write_errno;
    const char *bad = g->path[0][0];
    for (int c = 0; c < GSF_NCHAN && !e; c++)
        for (int d = 0; d < 2 && !e; d++)
            if (fflush(g->f[c][d]) != 0 || ferror(g->f[c][d])) {
                e = errno ? errno : EIO;
                bad = g->path[c][d];
            }
    if (e) {
        fprintf(stderr, "afmtwin scan: cannot write %s: %s (no .gsf file kept)\n", bad,
                strerror(e));
        gsf_close(g, false);
        return -1;
    }
    if (gsf_close(g, true)) {
        fprintf(stderr, "afmtwin scan: cannot close the .gsf files of %s\n", bad);
        return -1;
    }
    return 0;
}

static void print_pixel_row(const scan_opts *o, const afm_scan_pixel *p);

/* afm_scan_run's callback: the progress, the .gsf files, the row. */
static void print_pixel(void *ctx, const afm_scan_pixel *p) {
    scan_opts *o = ctx;
    afmt_progress_update(&o->pg, "scan: line %d/%d %s, pixel %d/%d", p->line + 1, o->sc.lines,
                         p->retrace ? "retrace" : "trace", p->pixel + 1, o->sc.pixels);
    if (o->gsf) gsf_pixel(o->gsf, p);
    afmt_progress_hide(&o->pg);
    print_pixel_row(o, p);
    afmt_progress_redraw(&o->pg);
}

static void print_pixel_row(const scan_opts *o, const afm_scan_pixel *p) {
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
            cJSON_AddNumberToObject(j, "squeeze_dissipated_energy_j",
                                    p->squeeze_dissipated_energy_j);
        } else {
            cJSON_AddNullToObject(j, "peak_force_n");
            cJSON_AddNullToObject(j, "dissipated_energy_j");
            cJSON_AddNullToObject(j, "squeeze_dissipated_energy_j");
        }
        cJSON_AddNumberToObject(j, "periods", p->periods);
        cJSON_AddNumberToObject(j, "free_amplitude_m", p->free_amplitude_m);
        afmt_json_emit(j);
        return;
    }
    printf("%5d %6d %2s %10.3f %10.3f %9.4f %3d %9.4f %9.4f %9.4f %9.3f %10.4f %10.4f %10.3f\n",
           p->line, p->pixel, p->retrace ? "R" : "T", p->x_m * 1e9, p->y_m * 1e9,
           p->true_height_m * 1e9, p->material, p->height_m * 1e9, p->amplitude_m * 1e9,
           p->error_m * 1e9, p->phase_lag_deg, p->peak_force_n * 1e9,
           p->dissipated_energy_j / 1.602176634e-19,
           p->squeeze_dissipated_energy_j / 1.602176634e-19);
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
    /* the controller: the options given, else the config's am group (the daemon's with
     * am.control = "internal"), else its defaults */
    if (isnan(o.pc.kp)) o.pc.kp = cfg.am.kp;
    if (isnan(o.pc.ki_hz)) o.pc.ki_hz = cfg.am.ki_hz;
    if (isnan(o.pc.setpoint_ratio)) o.pc.setpoint_ratio = cfg.am.setpoint_ratio;
    if (isnan(o.pc.z_rate_max_m_s)) o.pc.z_rate_max_m_s = cfg.am.z_rate_max_m_s;
    o.pc.z_min_m = cfg.am.z_min_m;
    o.pc.z_max_m = cfg.am.z_max_m;
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
               "lag_deg  peak_force_nN  E_diss_eV  E_sq_eV\n",
               o.config, afm_sim_integrator_name(sim), afm_sim_scheme_name(sim), o.sc.pixels,
               o.sc.lines, o.sc.size_x_m * 1e9, o.sc.size_y_m * 1e9, o.sc.line_rate_hz,
               o.pc.setpoint_ratio, o.pc.ki_hz, o.pc.kp);
    if (o.gsf_prefix && !(o.gsf = gsf_open(o.gsf_prefix, &o.sc))) {
        afm_sim_destroy(&sim);
        afm_surface_destroy(&surf);
        return 2;
    }
    afmt_progress_init(&o.pg);
    /* the per-period metrics from the integrator's record (afmt_step_events; afm_scan runs at
     * most AFM_SCAN_UPDATE_MAX samples before it reads them) */
    afm_step_events *ev_ring = afmt_step_events_ring(sim, AFM_SCAN_UPDATE_MAX);
    rc = afm_scan_run(sim, &cfg, &m, surf, &o.sc, &o.pc, print_pixel, &o, err, sizeof err);
    afmt_progress_end(&o.pg);
    if (rc) fprintf(stderr, "afmtwin %s\n", err);
    afm_sim_destroy(&sim);
    free(ev_ring);
    afm_surface_destroy(&surf);
    if (o.gsf) {
        if (rc)
            gsf_close(o.gsf, false);
        else if (gsf_finish(o.gsf))
            return 1;
    }
    return rc ? (strstr(err, "simulation failed") ? 1 : 2) : 0;
}
