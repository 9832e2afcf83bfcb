/* SPDX-License-Identifier: MIT */
/* cmd_plot_fm.c -- `afmtwin plot fm`: the FM channels of an LCM log's harmonics records
 * (shift, drive, amplitude, phase error, lock state) over model time. A file of its own
 * because it reads an LCM log (harmonics_t), not the tools' JSON lines, and shares only the
 * data sets and the layout (cmd_plot.h) with the other kinds. */
#include "cmd_plot.h"

#include "transport/afm_lcm_log.h"
#include "transport/afm_lcm_wire.h"
#include "afmtwin_harmonics_t.h"
#include "afmtwin_lcm_layout.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* ---- fm: the daemon's FM channels over time ---- */

/* Rows of the harmonics records of an LCM log (the daemon's or replay's), model time in
 * --from..--to (default the whole log). With the internal loops (fm_lock_state >= 0) the
 * shift is the loops' (tone 0 less the NCO's centre) and the phase error theirs; under an
 * outside controller (no loops) tone 0's frequency less the first record's, and the
 * lock-in's lag (90 deg free at resonance). */
#define FM_TRACE_COLS 8
#define FM_TRACE_HEADER                                                                            \
    "t[ms] frequency_shift[Hz] drive_amplitude[pm] amplitude[nm] phase[deg] lock_state[-1..2] "    \
    "Z[nm] msg_seq[index]"

int load_fm(const plot_opts *o, plot_data *d, FILE *gp) {
    char err[256];
    afm_lcm_log *lg = afm_lcm_log_open(o->in[0], 0, err, sizeof err);
    if (!lg) return plot_err("cannot read the log: %s", err);
    plot_set *s = plot_curve_new(d, "F", "", FM_TRACE_HEADER, FM_TRACE_COLS);
    if (!s) {
        afm_lcm_log_close(&lg);
        return -1;
    }
    const double a = isnan(o->t_from_s) ? -HUGE_VAL : o->t_from_s;
    const double b = isnan(o->t_to_s) ? HUGE_VAL : o->t_to_s;
    afm_lcm_log_event ev;
    int rr, records = 0, internal = -1, n_acq = 0, n_lost = 0;
    long events = 0; /* of any channel: none, and the file is no LCM log */
    double f_first = NAN, ph_set = NAN;
    while ((rr = afm_lcm_log_next(lg, &ev, err, sizeof err)) > 0) {
        events++;
        if (!afm_lcm_log_channel_is(ev.channel, AFMTWIN_CHAN_HARMONICS)) continue;
        afmtwin_harmonics_t m;
        if (afm_wire_decode(&afm_wire_harmonics_t, ev.data, (int)ev.datalen, &m, err, sizeof err))
            continue; /* not a harmonics_t: skipped, as listen does */
        records++;
        if (internal < 0) internal = m.fm_lock_state >= 0;
        double f0 = m.n_tones > 0 ? m.tone_frequency_hz[0] : NAN;
        if (isnan(f_first)) f_first = f0;
        if (m.t_s >= a && m.t_s <= b) {
            double shift = internal ? m.fm_frequency_shift_hz : f0 - f_first;
            double phase = internal ? m.fm_phase_error_deg : m.lockin_phase_deg;
            if (internal && m.fm_lock_state == 1 && isfinite(m.fm_phase_error_deg))
                ph_set = m.lockin_phase_deg - m.fm_phase_error_deg; /* the last locked one */
            n_acq += internal && m.fm_lock_state == 0;
            n_lost += internal && m.fm_lock_state == 2;
            double row[FM_TRACE_COLS] = {m.t_s * 1e3,
                                         shift,
                                         m.n_tones > 0 ? m.tone_amplitude_m[0] * 1e12 : NAN,
                                         m.lockin_amplitude_m * 1e9,
                                         phase,
                                         (double)m.fm_lock_state,
                                         m.separation_m * 1e9,
                                         (double)m.msg_seq};
            if (plot_set_row(s, row)) {
                afm_wire_free(&afm_wire_harmonics_t, &m);
                break;
            }
        }
        afm_wire_free(&afm_wire_harmonics_t, &m);
    }
    long long skipped = afm_lcm_log_skipped(lg);
    afm_lcm_log_close(&lg);
    if (events == 0) return plot_not_lcm_log(o->in[0], skipped, rr < 0 ? err : NULL);
    if (rr < 0)
        fprintf(stderr, "afmtwin plot: %s: %s (the records before it are drawn)\n", o->in[0], err);
    if (s->n == 0) {
        if (records == 0)
            return plot_err("%s: no harmonics records in the log (log the daemon's outputs: "
                            "lcm-logger on --lcm-out-url, or afmtwin replay --out)",
                            o->in[0]);
        fprintf(stderr, "afmtwin plot: %s: no harmonics record in the window (%d in the log)\n",
                o->in[0], records);
        return -1;
    }
    d->info.cfg_fe_hz = d->info.cfg_ae_m = NAN; /* the drive is the loops' or the commands' */
    if (internal)
        snprintf(d->note, sizeof d->note,
                 "internal loops: shift = tone 0 - the NCO's centre; phase error = lock-in lag "
                 "(90 deg free at resonance) - set-point%s",
                 isfinite(ph_set) ? "" : " (no record locked)");
    else
        snprintf(d->note, sizeof d->note,
                 "no internal loops (outside controller): tone 0 - its first record's %.9g Hz; "
                 "lock-in lag behind the drive (90 deg free at resonance)",
                 f_first);
    /* the set-point read back from a record (its lock-in lag less its error): the loops' own
     * lock-in and the published (OBD) one differ by a few mdeg, so "90.0043" would be
     * noise; one decimal is what the config's set-point means */
    if (internal && isfinite(ph_set))
        snprintf(d->note2, sizeof d->note2, "phase set-point %.1f deg (lag)", ph_set);
    fprintf(gp, "set style line 1 lc rgb '#0072b2' lw 1.5 pt 7 ps 0.5\nset style line 2 lc rgb "
                "'#e69f00' lw 2 pt 6 ps 1.0\nset style line 3 lc rgb '#d55e00' lw 2 pt 2 ps "
                "1.2\n");
    plot_key k = {0};
    plot_key_add(&k, "with linespoints ls 1", internal ? "locked" : "harmonics records");
    if (n_acq) plot_key_add(&k, "with points ls 2", "acquiring");
    if (n_lost) plot_key_add(&k, "with points ls 3", "lost");
    const double l = PX_LEFT / d->W, r = 1 - PX_RIGHT / d->W, b0 = PX_BOTTOM / d->H,
                 g = PX_GAP / d->H;
    double top = plot_figure(gp, d, &k, l, r);
    static const struct {
        int col;
        const char *label_int, *label_ext;
    } panel[] = {{2, "shift (Hz)", "tone 0 - first (Hz)"},
                 {3, "drive (pm)", "drive (pm)"},
                 {4, "amplitude (nm)", "amplitude (nm)"},
                 {5, "phase error (deg)", "lag (deg)"}};
    const int n = 4;
    const double px = ((top - b0) - (n - 1) * g) / n * d->H; /* a panel's height */
    /* time up to the last record: gnuplot's round tics left 60 ms of records on a 70 ms axis */
    fprintf(gp, "set autoscale xfixmax\n");
    for (int i = 0; i < n; i++) {
        plot_stack(gp, i, n, l, r, b0, top, g);
        plot_shared_x(gp, i, n, "model time (ms)");
        plot_short_ytics(gp, &s, 1, panel[i].col - 1, px);
        fprintf(gp, "set ylabel '%s'\nplot $F using 1:%d with linespoints ls 1 notitle",
                internal ? panel[i].label_int : panel[i].label_ext, panel[i].col);
        if (n_acq)
            fprintf(gp, ", $F using 1:($6 == 0 ? $%d : 1/0) with points ls 2 notitle",
                    panel[i].col);
        if (n_lost)
            fprintf(gp, ", $F using 1:($6 == 2 ? $%d : 1/0) with points ls 3 notitle",
                    panel[i].col);
        fputc('\n', gp);
    }
    fprintf(gp, "unset multiplot\n");
    return 0;
}
