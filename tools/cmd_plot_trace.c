/* SPDX-License-Identifier: MIT */
/* cmd_plot_trace.c -- `afmtwin plot trace`: the sample stream of an LCM log of the daemon's
 * outputs (deflection, OBD, force, the gap) over model time, lost messages shaded. A file of
 * its own because it reads an LCM log (samples_t), not the tools' JSON lines, and shares only
 * the data sets and the layout (cmd_plot.h) with the other kinds. */
#include "cmd_plot.h"

#include "transport/afm_lcm_log.h"
#include "transport/afm_lcm_wire.h"
#include "afmtwin_lcm_layout.h"
#include "afmtwin_samples_t.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* ---- trace ---- */

/* Samples-channel messages that never arrived (a jump in msg_seq, msg_seq lo..hi) while the
 * stream had no samples from t_lo to t_hi (model time, s; t_hi NAN: the log ended first). */
typedef struct {
    long long lo, hi;
    double t_lo, t_hi;
} trace_gap;
#define TRACE_MAX_GAPS 256

typedef struct {
    int blocks, decimation;
    double rate_hz, pass_hz, stop_hz, fe_hz; /* the last block's (fe: tone 0, NAN: none) */
    double t_first, t_end;                   /* the stream's first and last sample + 1 */
    long long lost;                          /* messages lost in the whole log */
    /* samples stamped before model time 0: the filter's start-up (each sample's time is its
     * source sample's less the filter's group delay, so the first ones fall before the run
     * started, made from the filter's empty history); not drawn */
    long long n_pre;
    double pre_s; /* the earliest one's distance before 0: the delay */
    int n_gaps;
    trace_gap gap[TRACE_MAX_GAPS];
} trace_ctx;

/* The stream's rate and filter as two lines of the title (and of the data files); sparse:
 * drawn as points. */
static void trace_note(const trace_ctx *c, int stream, bool sparse, char *l1, char *l2, size_t n) {
    int k = snprintf(l1, n, "stream %d: %.6g kHz (decimation %d)", stream, c->rate_hz / 1e3,
                     c->decimation);
    if (c->fe_hz > 0 && k > 0 && (size_t)k < n)
        k += snprintf(l1 + k, n - (size_t)k, ", %.3g samples per drive period",
                      c->rate_hz / c->fe_hz);
    if (sparse && k > 0 && (size_t)k < n)
        snprintf(l1 + k, n - (size_t)k, ": points, too few for the waveform");
    if (c->pass_hz > 0)
        snprintf(l2, n,
                 "every channel (force too) low-pass %.6g kHz, -80 dB from %.6g kHz: force "
                 "peaks are in the harmonics",
                 c->pass_hz / 1e3, c->stop_hz / 1e3);
    else
        snprintf(l2, n, "not filtered (decimation %d)", c->decimation);
}

int load_trace(const plot_opts *o, plot_data *d, FILE *gp) {
    char err[256];
    afm_lcm_log *lg = afm_lcm_log_open(o->in[0], 0, err, sizeof err);
    if (!lg) return plot_err("cannot read the log: %s", err);
    plot_set *s = plot_curve_new(d, "T", "",
                                 "t[ms] deflection[nm] obd[nm] force[nN] gap[nm] msg_seq[index] "
                                 "run[index] rate[Hz] passband[Hz]",
                                 9);
    if (!s) return -1;
    s->seg_col = 6; /* a run of samples with no lost message inside: never joined across */
    static trace_ctx c;
    memset(&c, 0, sizeof c);
    c.t_first = c.t_end = c.fe_hz = NAN;
    double t0 = isnan(o->t_from_s) ? -HUGE_VAL : o->t_from_s;
    double t1 = isnan(o->t_to_s) ? HUGE_VAL : o->t_to_s;
    afm_lcm_log_event ev;
    long long prev_seq = -1, lost_lo = -1, lost_hi = -1; /* lost since the stream's last block */
    int rr, run = 0;
    long events = 0; /* of any channel: none, and the file is no LCM log */
    while ((rr = afm_lcm_log_next(lg, &ev, err, sizeof err)) > 0) {
        events++;
        if (!afm_lcm_log_channel_is(ev.channel, AFMTWIN_CHAN_SAMPLES)) continue;
        afmtwin_samples_t m;
        if (afm_wire_decode(&afm_wire_samples_t, ev.data, (int)ev.datalen, &m, err, sizeof err))
            continue; /* not a samples_t: skipped, as listen does */
        if (prev_seq >= 0 && m.msg_seq > prev_seq + 1) {
            c.lost += m.msg_seq - prev_seq - 1;
            if (lost_lo < 0) lost_lo = prev_seq + 1;
            lost_hi = m.msg_seq - 1;
        }
        if (m.msg_seq > prev_seq) prev_seq = m.msg_seq;
        if (m.stream == o->stream && m.n > 0 && m.rate_hz > 0) {
            if (lost_lo >= 0 && isfinite(c.t_end) && m.t0_s > c.t_end + 0.5 / m.rate_hz) {
                if (c.n_gaps < TRACE_MAX_GAPS)
                    c.gap[c.n_gaps++] = (trace_gap){lost_lo, lost_hi, c.t_end, m.t0_s};
                run++;
            }
            lost_lo = lost_hi = -1;
            if (isnan(c.t_first)) c.t_first = m.t0_s;
            c.t_end = m.t0_s + m.n / m.rate_hz;
            c.rate_hz = m.rate_hz;
            c.decimation = m.decimation;
            c.pass_hz = m.passband_hz;
            c.stop_hz = m.stopband_hz;
            double a = isnan(o->t_from_s) ? fmax(c.t_first, 0.0) : t0;
            double b = isnan(o->t_to_s) ? a + 2e-3 : t1;
            for (int i = 0; i < m.n; i++) {
                double t = m.t0_s + i / m.rate_hz;
                if (t < 0) { /* the filter's start-up, before the run (trace_ctx) */
                    c.n_pre++;
                    c.pre_s = fmax(c.pre_s, -t);
                    continue;
                }
                if (t < a || t > b) continue;
                if (m.n_tones > 0) c.fe_hz = m.tone_frequency_hz[0];
                double row[9] = {t * 1e3,
                                 m.deflection_m[i] * 1e9,
                                 m.obd_m[i] * 1e9,
                                 m.force_n[i] * 1e9,
                                 isnan(o->z_m) ? NAN : (m.deflection_m[i] + o->z_m) * 1e9,
                                 (double)m.msg_seq,
                                 run,
                                 m.rate_hz,
                                 m.passband_hz};
                if (plot_set_row(s, row)) break;
            }
            c.blocks++;
        }
        afm_wire_free(&afm_wire_samples_t, &m);
    }
    long long skipped = afm_lcm_log_skipped(lg);
    afm_lcm_log_close(&lg);
    if (events == 0) return plot_not_lcm_log(o->in[0], skipped, rr < 0 ? err : NULL);
    if (lost_lo >= 0 && c.n_gaps < TRACE_MAX_GAPS) /* lost after the stream's last block */
        c.gap[c.n_gaps++] = (trace_gap){lost_lo, lost_hi, c.t_end, NAN};
    const double a = isnan(o->t_from_s) ? fmax(c.t_first, 0.0) : t0;
    const double b = isnan(o->t_to_s) ? a + 2e-3 : t1;
    if (s->n == 0) {
        for (int g = 0; g < c.n_gaps; g++) {
            const trace_gap *q = &c.gap[g];
            if (q->t_lo <= b && (isnan(q->t_hi) || q->t_hi >= a)) {
                fprintf(stderr,
                        "afmtwin plot: %s: the window %.6f..%.6f ms falls in a gap of lost "
                        "messages: %lld samples messages (msg_seq %lld to %lld) never reached "
                        "the log, and stream %d has no samples from %.6f ms to ",
                        o->in[0], a * 1e3, b * 1e3, q->hi - q->lo + 1, q->lo, q->hi, o->stream,
                        q->t_lo * 1e3);
                if (isnan(q->t_hi))
                    fprintf(stderr, "the end of the log\n");
                else
                    fprintf(stderr, "%.6f ms\n", q->t_hi * 1e3);
                return -1;
            }
        }
        if (c.blocks == 0)
            fprintf(stderr, "afmtwin plot: %s: no samples of stream %d in the log\n", o->in[0],
                    o->stream);
        else
            fprintf(stderr,
                    "afmtwin plot: %s: no samples of stream %d in the window %.6f..%.6f ms (%d "
                    "blocks from %.6f to %.6f ms, %lld messages lost)\n",
                    o->in[0], o->stream, a * 1e3, b * 1e3, c.blocks, c.t_first * 1e3, c.t_end * 1e3,
                    c.lost);
        return -1;
    }
    /* the daemon's drive is what it was sent, not the config's: only --fe and --ae */
    d->info.cfg_fe_hz = d->info.cfg_ae_m = NAN;
    if (isnan(c.fe_hz) && o->fe_hz > 0) c.fe_hz = o->fe_hz;
    /* a waveform only where the stream resolves the drive's period; else its points */
    const bool sparse = !(c.fe_hz > 0) || c.rate_hz / c.fe_hz < 10;
    trace_note(&c, o->stream, sparse, d->note, d->note2, sizeof d->note);
    const char *with = sparse ? "with points" : "with linespoints";
    fprintf(gp, "set style line 1 lc rgb '#0072b2' lw 1.5 pt 7 ps 0.8\nset style line 2 lc rgb "
                "'#e69f00' lw 1.5 dt 2 pt 6 ps 1.0\nset style line 3 lc rgb '#009e73' lw 1.5 pt 7 "
                "ps 0.8\nset style line 4 lc rgb '#d55e00' lw 1.5 pt 7 ps 0.8\n");
    const bool gap = !isnan(o->z_m);
    plot_key k = {0};
    char w[128], lab[96];
    snprintf(w, sizeof w, "%s ls 1", with);
    plot_key_add(&k, w, "tip deflection xr");
    snprintf(w, sizeof w, "%s ls 2", with);
    plot_key_add(&k, w, "OBD signal");
    if (gap) {
        snprintf(w, sizeof w, "%s ls 3", with);
        plot_key_add(&k, w, "gap xr + Z");
    }
    snprintf(w, sizeof w, "%s ls 4", with);
    if (c.pass_hz > 0)
        snprintf(lab, sizeof lab, "tip-sample force, low-pass %.4g kHz", c.pass_hz / 1e3);
    else
        snprintf(lab, sizeof lab, "tip-sample force");
    plot_key_add(&k, w, lab);
    /* lost messages inside the window: shaded, named in the legend */
    int shown = 0;
    for (int g = 0; g < c.n_gaps; g++) {
        const trace_gap *q = &c.gap[g];
        double hi = isnan(q->t_hi) ? b : q->t_hi;
        if (q->t_lo > b || hi < a) continue;
        fprintf(gp,
                "set object %d rect from %.9g, graph 0 to %.9g, graph 1 fc rgb '#cccccc' fs "
                "solid 0.5 noborder behind\n",
                100 + g, fmax(q->t_lo, a) * 1e3, fmin(hi, b) * 1e3);
        if (shown++ == 0) {
            snprintf(lab, sizeof lab, "lost messages (msg_seq %lld to %lld%s)", q->lo, q->hi,
                     c.n_gaps > g + 1 ? ", ..." : "");
            plot_key_add(&k, "with boxes fc rgb '#cccccc' fs solid 0.5 noborder", lab);
        }
    }
    /* the time axis says the filter's delay is off the times (no samples before the start) */
    char xl[128] = "model time (ms)";
    if (c.n_pre > 0)
        snprintf(xl, sizeof xl,
                 "model time (ms), less the %.3g us delay of the filter (its %lld samples before 0 "
                 "not drawn)",
                 c.pre_s * 1e6, c.n_pre);
    const double l = PX_LEFT / d->W, r = 1 - PX_RIGHT / d->W, b0 = PX_BOTTOM / d->H,
                 g = PX_GAP / d->H;
    double top = plot_figure(gp, d, &k, l, r);
    const int n = gap ? 3 : 2;
    int i = 0;
    plot_stack(gp, i, n, l, r, b0, top, g);
    plot_shared_x(gp, i++, n, xl);
    fprintf(gp,
            "set ylabel 'deflection (nm)'\nplot $T using 1:2 %s ls 1 notitle, $T using 1:3 %s "
            "ls 2 notitle\n",
            with, with);
    if (gap) {
        plot_stack(gp, i, n, l, r, b0, top, g);
        plot_shared_x(gp, i++, n, xl);
        fprintf(gp, "set ylabel 'gap (nm)'\nplot $T using 1:5 %s ls 3 notitle\n", with);
    }
    plot_stack(gp, i, n, l, r, b0, top, g);
    plot_shared_x(gp, i, n, xl);
    fprintf(gp, "set ylabel 'force (nN)'\nplot $T using 1:4 %s ls 4 notitle\nunset multiplot\n",
            with);
    return 0;
}
