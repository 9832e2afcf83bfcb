/* SPDX-License-Identifier: MIT */
/* cmd_plot_approach.c -- `afmtwin plot approach`: approach curves of `afmtwin approach
 * --json` (amplitude and phase lag, peak force, mean force and dissipated energies against Z,
 * approach and retract, jumps marked, unsettled steps drawn apart) and, for `--mode fm`,
 * the frequency shift, the drive and the amplitude against Z. A file of its own: the
 * largest kind, sharing only the data sets, the JSON reader and the layout of cmd_plot.h.
 * Phases are the lag of the deflection behind the drive (90 deg free at resonance). */
#include "cmd_plot.h"
#include "plot_info.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- approach ---- */

#define APPROACH_COLS 13
#define APPROACH_HEADER                                                                            \
    "Z[nm] amplitude[nm] lag[deg] repulsive_peak[nN] attractive_peak[nN] "                         \
    "dissipated[eV] indentation[nm] max_force[nN] min_force[nN] virial[eV] "                       \
    "periodicity[periods] settled[0/1] squeeze_dissipated[eV]"

typedef struct {
    plot_set *app, *ret, *jump, *pm, *um;
    plot_info *pi;
    int jumps[2]; /* approach, retract */
    bool squeeze; /* a record with squeeze film dissipation (E_sq is drawn) */
} approach_ctx;

static int approach_row(const cJSON *o, void *vctx) {
    approach_ctx *c = vctx;
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(o, "jump");
    if (j) {
        bool ret = plot_str_is(j, "direction", "retract");
        /* a change of regime with no jump of the branch (a crossover) gets no arrow; files
         * from before the key existed had only jumps */
        bool sharp = !cJSON_GetObjectItemCaseSensitive(j, "sharp") || plot_is_true(j, "sharp");
        double row[8] = {plot_num(j, "z_before_m") * 1e9,
                         plot_num(j, "z_after_m") * 1e9,
                         plot_num(j, "amplitude_before_m") * 1e9,
                         plot_num(j, "amplitude_after_m") * 1e9,
                         plot_num(j, "phase_before_deg"),
                         plot_num(j, "phase_after_deg"),
                         ret ? 1 : 0,
                         sharp ? 1 : 0};
        c->jumps[ret] += sharp;
        return plot_set_row(c->jump, row);
    }
    double z = plot_num(o, "z_m");
    if (isnan(z)) return plot_err("%s", "an approach record without z_m (approach --json?)");
    plot_info_z(c->pi, z);
    if (!isfinite(c->pi->a0_m)) {
        c->pi->a0_m = plot_num(o, "free_amplitude_m");
        c->pi->a0_lag_deg = plot_num(o, "free_phase_lag_deg");
    }
    bool ret = plot_str_is(o, "direction", "retract"), settled = plot_is_true(o, "settled");
    double fmax = plot_num(o, "peak_force_n") * 1e9, fmin = plot_num(o, "attractive_force_n") * 1e9,
           p = plot_num(o, "periodicity"),
           esq = plot_num(o, "squeeze_dissipated_energy_j") / PLOT_EV;
    if (isfinite(esq) && esq != 0.0) c->squeeze = true;
    double row[APPROACH_COLS] = {z * 1e9,
                                 plot_num(o, "amplitude_m") * 1e9,
                                 plot_num(o, "phase_lag_deg"),
                                 plot_clip_pos(fmax),
                                 plot_clip_neg(fmin),
                                 plot_num(o, "dissipated_energy_j") / PLOT_EV,
                                 plot_num(o, "indentation_m") * 1e9,
                                 fmax,
                                 fmin,
                                 plot_num(o, "virial_j") / PLOT_EV,
                                 p,
                                 settled ? 1 : 0,
                                 esq};
    if (settled && p > 1 && plot_set_row(c->pm, row)) return -1;
    /* `afmtwin curve` records (from a daemon log) carry neither settled nor periodicity:
     * nothing was judged, so nothing is marked unsettled (every point was, before) */
    const bool judged = cJSON_GetObjectItemCaseSensitive(o, "settled") != NULL;
    if (judged && (!settled || p == 0) && plot_set_row(c->um, row)) return -1;
    return plot_set_row(ret ? c->ret : c->app, row);
}

/* ---- approach --mode fm ---- */

#define FM_COLS 8
#define FM_HEADER                                                                                  \
    "Z[nm] frequency_shift[Hz] drive_amplitude[pm] amplitude[nm] amplitude_setpoint[nm] "          \
    "dissipated[eV] locked[0/1] settled[0/1]"

typedef struct {
    plot_set *app, *ret, *un;
    plot_info *pi;
    double f_free_hz, a_set_m, drive_far_m, z_far_m; /* drive_far: at the largest Z */
} fm_ctx;

static int fm_row(const cJSON *o, void *vctx) {
    fm_ctx *c = vctx;
    if (cJSON_GetObjectItemCaseSensitive(o, "jump")) return 0; /* FM approach has none */
    double z = plot_num(o, "z_m");
    if (isnan(z)) return plot_err("%s", "an approach record without z_m (approach --json?)");
    if (!plot_str_is(o, "mode", "fm"))
        return plot_err("%s", "an am record among fm records: one approach --json output");
    plot_info_z(c->pi, z);
    bool locked = plot_is_true(o, "locked"), settled = plot_is_true(o, "settled");
    double drive = plot_num(o, "drive_amplitude_m");
    if (isnan(c->z_far_m) || z > c->z_far_m) {
        c->z_far_m = z;
        c->drive_far_m = drive;
    }
    c->f_free_hz = plot_num(o, "free_frequency_hz");
    c->a_set_m = plot_num(o, "amplitude_setpoint_m");
    double row[FM_COLS] = {z * 1e9,          plot_num(o, "frequency_shift_hz"),
                           drive * 1e12,     plot_num(o, "amplitude_m") * 1e9,
                           c->a_set_m * 1e9, plot_num(o, "dissipated_energy_j") / PLOT_EV,
                           locked ? 1 : 0,   settled ? 1 : 0};
    if ((!locked || !settled) && plot_set_row(c->un, row)) return -1;
    return plot_set_row(plot_str_is(o, "direction", "retract") ? c->ret : c->app, row);
}

/* An FM approach (afmtwin approach --mode fm): the PLL holds the lag at its set-point and the
 * amplitude controller the amplitude, so what changes with Z is the frequency shift (the
 * force gradient), the drive the amplitude needs (the dissipation channel) and E_ts; the held
 * amplitude is drawn against its set-point as the check that the loops held. */
static int load_approach_fm(const plot_opts *o, plot_data *d, FILE *gp) {
    fm_ctx c = {plot_curve_new(d, "A", "approach", FM_HEADER, FM_COLS),
                plot_curve_new(d, "R", "retract", FM_HEADER, FM_COLS),
                plot_set_new(d, "U", FM_HEADER, FM_COLS),
                &d->info,
                NAN,
                NAN,
                NAN,
                NAN};
    if (!c.app || !c.ret || !c.un || plot_each_json(o->in[0], fm_row, &c)) return -1;
    if (c.app->n + c.ret->n == 0) return plot_err("%s: no approach records", o->in[0]);
    d->info.no_drive = true; /* tone 0 is the PLL's: the note says where it started */
    snprintf(d->note, sizeof d->note,
             "FM: lag held by the PLL, amplitude %.4g nm by the amplitude loop; f_free %.1f Hz; "
             "drive %.4g pm at Z %.3g nm",
             c.a_set_m * 1e9, c.f_free_hz, c.drive_far_m * 1e12, c.z_far_m * 1e9);
    fprintf(gp, "set style line 1 lc rgb '#0072b2' lw 1.5 pt 7 ps 0.6\n"
                "set style line 2 lc rgb '#009e73' lw 1.5 pt 6 ps 0.7\n"
                "set style line 3 lc rgb 'black' lw 1 dt 2\n"
                "set style line 12 lc rgb 'black' lw 1.5 pt 2 ps 1.6\n");
    if (!o->title && c.app->n && c.ret->n)
        snprintf(d->title, sizeof d->title, "approach and retract curve");
    plot_key k = {0};
    if (c.app->n) plot_key_add(&k, "with linespoints ls 1", "approach");
    if (c.ret->n) plot_key_add(&k, "with linespoints ls 2", "retract");
    if (c.un->n) plot_key_add(&k, "with points ls 12", "not locked or not settled");
    plot_key_add(&k, "with lines ls 3", "amplitude set-point");
    const double l = PX_LEFT / d->W, r = 1 - PX_RIGHT / d->W;
    double top = plot_figure(gp, d, &k, l, r);
    /* the drive against the drive at the largest Z (its change is the dissipation channel),
     * and the amplitude against its set-point (did the loop hold?), both in ppm: in pm and nm
     * the changes are below the tick labels' digits */
    char drive_rel[64];
    snprintf(drive_rel, sizeof drive_rel, "(($3 / %.17g - 1) * 1e6)", c.drive_far_m * 1e12);
    static const struct {
        const char *ylab;
        const char *using;
    } panel[4] = {{"frequency shift f - f_free (Hz)", "2"},
                  {"drive change (ppm)", NULL},
                  {"amplitude / set-point - 1 (ppm)", "(($4 / $5 - 1) * 1e6)"},
                  {"E_ts tip-sample (eV)", "6"}};
    for (int p = 0; p < 4; p++) {
        plot_grid_cell(gp, d, p, false, l, r, top, "separation Z (nm)");
        fprintf(gp, "set ytics autofreq\nset offsets 0, 0, graph 0.05, graph 0.05\n");
        fprintf(gp, "set ylabel '%s'\n%s", panel[p].ylab,
                p != 2 ? "set xzeroaxis lt -1 lw 0.5\n" : "unset xzeroaxis\n");
        const char *sep = "plot ", *u = panel[p].using ? panel[p].using : drive_rel;
        if (c.app->n) {
            fprintf(gp, "%s$A using 1:%s with linespoints ls 1 notitle", sep, u);
            sep = ", ";
        }
        if (c.ret->n) {
            fprintf(gp, "%s$R using 1:%s with linespoints ls 2 notitle", sep, u);
            sep = ", ";
        }
        if (p == 2) fprintf(gp, ", 0 with lines ls 3 notitle");
        if (c.un->n) fprintf(gp, ", $U using 1:%s with points ls 12 notitle", u);
        fprintf(gp, "\n");
    }
    fprintf(gp, "unset multiplot\n");
    return 0;
}

/* The first record's mode: an FM approach is drawn by load_approach_fm. */
static int first_mode(const cJSON *o, void *vctx) {
    bool *fm = vctx;
    if (cJSON_GetObjectItemCaseSensitive(o, "z_m")) {
        *fm = plot_str_is(o, "mode", "fm");
        return 1; /* stop */
    }
    return 0;
}

int load_approach(const plot_opts *o, plot_data *d, FILE *gp) {
    bool fm = false;
    if (plot_each_json(o->in[0], first_mode, &fm) < 0) return -1;
    if (fm) return load_approach_fm(o, d, gp);
    approach_ctx c = {
        plot_curve_new(d, "A", "approach", APPROACH_HEADER, APPROACH_COLS),
        plot_curve_new(d, "R", "retract", APPROACH_HEADER, APPROACH_COLS),
        plot_set_new(d, "J",
                     "Z_before[nm] Z_after[nm] amplitude_before[nm] amplitude_after[nm] "
                     "lag_before[deg] lag_after[deg] retract[0/1] sharp[0/1]",
                     8),
        plot_set_new(d, "PM", APPROACH_HEADER, APPROACH_COLS),
        plot_set_new(d, "UM", APPROACH_HEADER, APPROACH_COLS),
        &d->info,
        {0, 0},
        false};
    if (!c.app || !c.ret || !c.jump || !c.pm || !c.um || plot_each_json(o->in[0], approach_row, &c))
        return -1;
    if (c.app->n + c.ret->n == 0) return plot_err("%s: no approach records", o->in[0]);
    fprintf(gp, "set style line 1 lc rgb '#0072b2' lw 1.5 pt 7 ps 0.6\n"
                "set style line 2 lc rgb '#009e73' lw 1.5 pt 6 ps 0.7\n"
                "set style line 3 lc rgb '#0072b2' lw 1.5 pt 7 ps 0.6 dt 2\n"
                "set style line 4 lc rgb '#009e73' lw 1.5 pt 6 ps 0.7 dt 2\n"
                "set style line 5 lc rgb 'red' lw 2.5\n"
                "set style line 6 lc rgb '#e69f00' lw 2.5\n"
                "set style line 11 lc rgb 'red' lw 1.5 pt 6 ps 1.8\n"
                "set style line 12 lc rgb 'black' lw 1.5 pt 2 ps 1.6\n"
                "set style arrow 1 head filled size screen 0.012,20 ls 5\n"
                "set style arrow 2 head filled size screen 0.012,20 ls 6\n");
    /* the default title says when the curve has its retract too */
    if (!o->title && c.app->n && c.ret->n)
        snprintf(d->title, sizeof d->title, "approach and retract curve");
    plot_key k = {0};
    if (c.app->n) plot_key_add(&k, "with linespoints ls 1", "approach");
    if (c.ret->n) plot_key_add(&k, "with linespoints ls 2", "retract");
    if (c.jumps[0]) plot_key_add(&k, "with vectors arrowstyle 1", "jump on approach");
    if (c.jumps[1]) plot_key_add(&k, "with vectors arrowstyle 2", "jump on retract");
    if (c.pm->n) plot_key_add(&k, "with points ls 11", "period p > 1");
    if (c.um->n) plot_key_add(&k, "with points ls 12", "not settled (or periodicity 0)");
    plot_key_add(&k, "with lines lw 1.5 lc rgb 'black'", "force: repulsive peak max(F, 0)");
    plot_key_add(&k, "with lines lw 1.5 dt 2 lc rgb 'black'", "force: attractive peak min(F, 0)");
    snprintf(d->note, sizeof d->note, "%s",
             c.squeeze ? "energy per period: E_ts dissipated by the tip-sample forces (0 if "
                         "conservative), E_sq by the squeeze film on the beam"
                       : "E_ts: the energy the tip-sample forces dissipate per period (0 for "
                         "conservative forces, but for the integration's noise)");
    snprintf(d->note2, sizeof d->note2, "%s", PLOT_LAG_NOTE);
    const double l = PX_LEFT / d->W, r = 1 - PX_RIGHT / d->W;
    double top = plot_figure(gp, d, &k, l, r);
    /* 2 x 2 panels; with a squeeze film the last cell holds E_ts over E_sq */
    static const struct {
        const char *ylab;
        int col, col2; /* a second column, drawn dashed (0: none) */
    } panel[5] = {{"amplitude (nm)", 2, 0},
                  {"phase lag (deg)", 3, 0},
                  {"tip-sample force peaks (nN)", 4, 5},
                  {"E_ts tip-sample (eV)", 6, 0},
                  {"E_sq (eV)", 13, 0}};
    for (int p = 0; p < (c.squeeze ? 5 : 4); p++) {
        double px = plot_grid_cell(gp, d, p, c.squeeze, l, r, top, "separation Z (nm)");
        const char *ylab = c.squeeze && p == 3 ? "E_ts (eV)" : panel[p].ylab;
        fprintf(gp, "set ytics autofreq\n");
        if (c.squeeze && p >= 3) {
            plot_set *const all[2] = {c.app, c.ret};
            plot_short_ytics(gp, all, 2, panel[p].col - 1, px);
        }
        /* room for the jump arrows' heads over and under the curves */
        fprintf(gp, "set offsets 0, 0, graph %g, graph %g\n", p < 2 ? 0.06 : 0.0,
                p < 2 ? 0.06 : 0.0);
        fprintf(gp, "set ylabel '%s'\n%s", ylab,
                p >= 2 ? "set xzeroaxis lt -1 lw 0.5\n" : "unset xzeroaxis\n");
        const char *sep = "plot ";
        for (int pass = 0; pass < (panel[p].col2 ? 2 : 1); pass++) {
            int col = pass ? panel[p].col2 : panel[p].col;
            if (c.app->n) {
                fprintf(gp, "%s$A using 1:%d with linespoints ls %d notitle", sep, col,
                        1 + 2 * pass);
                sep = ", ";
            }
            if (c.ret->n) {
                fprintf(gp, "%s$R using 1:%d with linespoints ls %d notitle", sep, col,
                        2 + 2 * pass);
                sep = ", ";
            }
            if (c.pm->n) fprintf(gp, ", $PM using 1:%d with points ls 11 notitle", col);
            if (c.um->n) fprintf(gp, ", $UM using 1:%d with points ls 12 notitle", col);
        }
        /* the jumps: from the last point on the old branch to the first on the new one */
        for (int dir = 0; dir < 2 && p < 2; dir++)
            if (c.jumps[dir])
                fprintf(gp,
                        ", $J using 1:($7 == %d && $8 == 1 ? $%d : 1/0):($2 - $1):($%d - $%d) "
                        "with vectors "
                        "arrowstyle %d notitle",
                        dir, 3 + 2 * p, 4 + 2 * p, 3 + 2 * p, dir + 1);
        fprintf(gp, "\n");
    }
    fprintf(gp, "unset multiplot\n");
    return 0;
}
