/* SPDX-License-Identifier: MIT */
/* cmd_listen.c -- `afmtwin listen`: subscribes to the twin's output channels (samples,
 * harmonics, status, tick_done) and prints each message as text or as one JSON object per
 * line; follows each channel's msg_seq and reports lost messages as they show and at exit. */
#include "afmtwin_cmds.h"
#include "json_out.h"
#include "lcm_tool.h"
#include "opts.h"

#include "config/afm_config.h"
#include "config/afm_err.h"
#include "transport/afm_lcm_log.h"
#include "transport/afm_lcm_wire.h"

#include "afmtwin_harmonics_t.h"
#include "afmtwin_samples_t.h"
#include "afmtwin_status_t.h"
#include "afmtwin_tick_done_t.h"

#include <cjson/cJSON.h>
#include <lcm/lcm.h>
#include <math.h>
#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define LISTEN_QUEUE 10000 /* messages a subscription may hold while we print */

enum { N_OUT = AFMT_N_OUT };

/* Reports on stderr, at most BAD_LINES_PER_S a second (a flood of junk or of gaps must not
 * flood the terminal too): the ones left out are counted in quiet and said in a line of
 * their own when the next second starts. */
#define BAD_LINES_PER_S 5
#define LISTEN_EV_J 1.602176634e-19 /* J per eV (the energies on the text lines) */
typedef struct {
    double t0;     /* start of the current second */
    int in_second; /* reports in it */
    long quiet;    /* left out (since the last "... and N more" line) */
} listen_throttle;

typedef struct {
    bool json, full;
    long count;       /* 0: no limit */
    double timeout_s; /* 0: none */
    bool want[N_OUT];
    const char *url, *out_url, *samples_url, *prefix, *log;
    long got;                  /* messages printed */
    long bad;                  /* messages that did not decode */
    listen_throttle bad_lines; /* their reports on stderr */
    afmt_channels ch;
    /* msg_seq per channel: the last one seen (-1: none yet), messages lost in gaps, gaps */
    int64_t last_seq[N_OUT];
    long long lost[N_OUT], gaps[N_OUT], restarts[N_OUT], n_ch[N_OUT];
    listen_throttle gap_lines; /* gap reports on stderr */
} listen_ctx;

static volatile sig_atomic_t listen_stop;
static void on_signal(int sig) {
    (void)sig;
    listen_stop = 1;
}

static void listen_usage(FILE *f) {
    fprintf(f,
            "usage: afmtwin listen [--json] [--full] [--count N] [--channels LIST]\n"
            "                      [--timeout S] [--lcm-url URL] [--lcm-out-url URL]\n"
            "                      [--lcm-samples-url URL] [--prefix NAME_]\n"
            "       afmtwin listen --log FILE [--json] [--full] [--count N] [--channels LIST]\n"
            "                      [--prefix NAME_]\n\n"
            "Prints what the twin (afmtwind, or `afmtwin replay` through lcm-logplayer)\n"
            "publishes: samples blocks, per-period harmonics, the 10 Hz status and the\n"
            "completions of ticks and steps (tick_done).\n\n"
            "options:\n"
            "  --json           one JSON object per message and line, with every field of the\n"
            "                   message plus \"channel\" and \"type\"; samples carry summary\n"
            "                   statistics (min, max, mean, rms of deflection_m, obd_m, force_n)\n"
            "                   and the arrays only with --full\n"
            "  --full           also print the sample arrays of samples messages\n"
            "  --count N        exit after N messages (N >= 1); exit status 1 if the timeout\n"
            "                   comes first\n"
            "  --channels LIST  comma-separated subset of samples,harmonics,status,tick_done\n"
            "                   (default all)\n"
            "  --timeout S      exit after S seconds (S > 0; default: run until N messages or a\n"
            "                   signal); exit status 1 if nothing arrived by then\n"
            "  --lcm-url URL    the twin's command URL, as given to afmtwind (default:\n"
            "                   LCM_DEFAULT_URL or LCM's default); the outputs are read from\n"
            "                   the output URL derived from it (udpm: port + 1; the samples\n"
            "                   from port + 2, opened only when samples are wanted)\n"
            "  --lcm-out-url URL  read harmonics, status, tick_done from this URL instead\n"
            "                   (afmtwind --lcm-out-url)\n"
            "  --lcm-samples-url URL  read the samples from this URL (afmtwind\n"
            "                   --lcm-samples-url)\n"
            "  --prefix NAME_   channel-name prefix of the twin (default %s)\n"
            "  --log FILE       read the messages from an LCM log (lcm-logger's format, e.g.\n"
            "                   `afmtwin replay --out`) instead of the network, to its end\n"
            "  --help           this text\n\n"
            "Channels: PREFIX + %s, %s, %s, %s. Text output: one line per message.\n"
            "Lost messages: every output message carries msg_seq (per channel, +1 each); a\n"
            "jump is reported on stderr as it shows (at most 5 lines a second) and summed up\n"
            "at exit, with the messages received per channel (stderr).\n"
            "Status: rtf(1 s) is model over wall time of the last second of running; the\n"
            "lock-in phase is the LAG of the deflection behind the drive (90 deg for a free\n"
            "cantilever at resonance, below 90 in the repulsive regime).\n"
            "Exit status 0 ok (also on SIGINT and SIGTERM, after the summary), 1 LCM\n"
            "failure, --count not reached, or nothing at all received within --timeout;\n"
            "2 bad usage.\n",
            AFMT_DEFAULT_PREFIX, AFMT_CHAN_SAMPLES, AFMT_CHAN_HARMONICS, AFMT_CHAN_STATUS,
            AFMT_CHAN_TICK_DONE);
}

/* ---- samples: summary statistics of a float array ---- */
typedef struct {
    double min, max, mean, rms;
} arr_stats;

static arr_stats stats_f(const float *v, int n) {
    arr_stats s = {NAN, NAN, NAN, NAN};
    if (n <= 0 || !v) return s;
    double sum = 0, sq = 0;
    s.min = s.max = v[0];
    for (int i = 0; i < n; i++) {
        double x = v[i];
        if (x < s.min) s.min = x;
        if (x > s.max) s.max = x;
        sum += x;
        sq += x * x;
    }
    s.mean = sum / n;
    s.rms = sqrt(sq / n);
    return s;
}

/* 64-bit integers exactly (cJSON numbers are doubles: seq numbers of 1e15 and more would
 * print rounded or in exponent form). */
static void json_int(cJSON *o, const char *k, int64_t v) {
    char buf[32];
    snprintf(buf, sizeof buf, "%lld", (long long)v);
    cJSON_AddRawToObject(o, k, buf);
}

/* A string field from the network, as printable ASCII (afm_err_printable); a missing
 * (NULL) string as "". */
#define SHOW_LEN 1024
static const char *show(char *buf, const char *v) {
    return afm_err_printable(buf, SHOW_LEN, v ? v : "", SHOW_LEN);
}

static void json_str(cJSON *o, const char *k, const char *v) {
    char b[SHOW_LEN];
    cJSON_AddStringToObject(o, k, show(b, v));
}

static void json_stats(cJSON *o, const char *k, arr_stats s) {
    cJSON *j = cJSON_AddObjectToObject(o, k);
    afmt_json_num(j, "min", s.min);
    afmt_json_num(j, "max", s.max);
    afmt_json_num(j, "mean", s.mean);
    afmt_json_num(j, "rms", s.rms);
}

static void json_farr(cJSON *o, const char *k, const float *v, int n) {
    cJSON *a = cJSON_AddArrayToObject(o, k);
    for (int i = 0; i < n; i++)
        cJSON_AddItemToArray(a, isfinite(v[i]) ? cJSON_CreateNumber(v[i]) : cJSON_CreateNull());
}

static void json_darr(cJSON *o, const char *k, const double *v, int n) {
    cJSON *a = cJSON_AddArrayToObject(o, k);
    for (int i = 0; i < n; i++)
        cJSON_AddItemToArray(a, isfinite(v[i]) ? cJSON_CreateNumber(v[i]) : cJSON_CreateNull());
}

/* The lock-in at tone 0 and the peak force of the last period, as harmonics and status
 * both carry them. */
static void json_lockin(cJSON *o, double amplitude_m, double phase_deg, double peak_force_n) {
    afmt_json_num(o, "lockin_amplitude_m", amplitude_m);
    afmt_json_num(o, "lockin_phase_deg", phase_deg);
    afmt_json_num(o, "peak_force_n", peak_force_n);
}

/* The sample under the tip (issue 18), as harmonics and status both carry it. */
static void json_tip(cJSON *o, double x_m, double y_m, double true_height_m, int material) {
    afmt_json_num(o, "tip_x_m", x_m);
    afmt_json_num(o, "tip_y_m", y_m);
    afmt_json_num(o, "true_height_m", true_height_m);
    json_int(o, "material", material);
}

/* The same on a text line, after sep. */
static void print_tip(const char *sep, double x_m, double y_m, double true_height_m, int material) {
    printf("%stip (%.6g, %.6g) nm over z_s %.5g nm, material %d", sep, x_m * 1e9, y_m * 1e9,
           true_height_m * 1e9, material);
}

static cJSON *json_head(const char *channel, const char *type, int64_t utime, int64_t msg_seq) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "channel", channel);
    cJSON_AddStringToObject(o, "type", type);
    json_int(o, "utime", utime);
    json_int(o, "msg_seq", msg_seq);
    return o;
}

/* The operating point a record was made at: separation_m, tones [{frequency_hz,
 * amplitude_m}]. */
/* harmonics_t.fm_lock_state (afm_fm_lock) as the status's fm_lock_state says it */
static const char *fm_lock_name(int s) {
    return s == 0 ? "acquiring" : s == 1 ? "locked" : s == 2 ? "lost" : "?";
}

/* harmonics_t.fm_drive (afm_fm_drive) as the status's fm_drive says it */
static const char *fm_drive_name(int d) {
    return d == 0 ? "pll" : d == 1 ? "self" : "?";
}

static void json_oppoint(cJSON *o, double z_m, int n, const double *f_hz, const double *a_m) {
    afmt_json_num(o, "separation_m", z_m);
    cJSON *t = cJSON_AddArrayToObject(o, "tones");
    for (int i = 0; i < n; i++) {
        cJSON *e = cJSON_CreateObject();
        afmt_json_num(e, "frequency_hz", f_hz[i]);
        afmt_json_num(e, "amplitude_m", a_m[i]);
        cJSON_AddItemToArray(t, e);
    }
}

static void print_samples(const listen_ctx *c, const char *channel, const afmtwin_samples_t *m) {
    arr_stats sx = stats_f(m->deflection_m, m->n), so = stats_f(m->obd_m, m->n),
              sf = stats_f(m->force_n, m->n);
    if (c->json) {
        cJSON *o = json_head(channel, "samples", m->utime, m->msg_seq);
        json_int(o, "seq_applied", m->seq_applied);
        cJSON_AddNumberToObject(o, "stream", m->stream);
        afmt_json_num(o, "t0_s", m->t0_s);
        afmt_json_num(o, "rate_hz", m->rate_hz);
        cJSON_AddNumberToObject(o, "decimation", m->decimation);
        afmt_json_num(o, "passband_hz", m->passband_hz);
        afmt_json_num(o, "stopband_hz", m->stopband_hz);
        cJSON_AddNumberToObject(o, "n", m->n);
        json_stats(o, "deflection_m", sx);
        json_stats(o, "obd_m", so);
        json_stats(o, "force_n", sf);
        json_oppoint(o, m->separation_m, m->n_tones, m->tone_frequency_hz, m->tone_amplitude_m);
        if (c->full) {
            cJSON *a = cJSON_AddObjectToObject(o, "data");
            json_farr(a, "deflection_m", m->deflection_m, m->n);
            json_farr(a, "obd_m", m->obd_m, m->n);
            cJSON *ca = cJSON_AddArrayToObject(a, "obd_counts");
            for (int i = 0; i < m->n; i++)
                cJSON_AddItemToArray(ca, cJSON_CreateNumber(m->obd_counts[i]));
            json_farr(a, "force_n", m->force_n, m->n);
        }
        afmt_json_emit(o);
        return;
    }
    char lp[64] = "unfiltered";
    if (m->passband_hz > 0)
        snprintf(lp, sizeof lp, "low-pass %.6g Hz, -80 dB from %.6g Hz", m->passband_hz,
                 m->stopband_hz);
    printf("samples   seq %lld stream %d t0 %.9f s rate %.6g Hz, %s, n %d Z %.4g nm: deflection "
           "%.4g..%.4g nm (rms %.4g), obd %.4g..%.4g nm, force %.4g..%.4g nN\n",
           (long long)m->seq_applied, m->stream, m->t0_s, m->rate_hz, lp, m->n,
           m->separation_m * 1e9, sx.min * 1e9, sx.max * 1e9, sx.rms * 1e9, so.min * 1e9,
           so.max * 1e9, sf.min * 1e9, sf.max * 1e9);
    if (c->full)
        for (int i = 0; i < m->n; i++)
            printf("  %d %.9g %.9g %d %.9g\n", i, m->deflection_m[i], m->obd_m[i], m->obd_counts[i],
                   m->force_n[i]);
}

static void print_harmonics(const listen_ctx *c, const char *channel,
                            const afmtwin_harmonics_t *m) {
    if (c->json) {
        cJSON *o = json_head(channel, "harmonics", m->utime, m->msg_seq);
        json_int(o, "seq_applied", m->seq_applied);
        afmt_json_num(o, "t_s", m->t_s);
        afmt_json_num(o, "fe_hz", m->fe_hz);
        cJSON_AddNumberToObject(o, "n", m->n);
        cJSON *k = cJSON_AddArrayToObject(o, "k");
        for (int i = 0; i < m->n; i++)
            cJSON_AddItemToArray(k, cJSON_CreateNumber(m->k[i]));
        json_darr(o, "deflection_amplitude_m", m->deflection_amplitude_m, m->n);
        json_darr(o, "deflection_phase_deg", m->deflection_phase_deg, m->n);
        json_darr(o, "deflection_lag_deg", m->deflection_lag_deg, m->n);
        json_darr(o, "force_amplitude_n", m->force_amplitude_n, m->n);
        json_darr(o, "force_phase_deg", m->force_phase_deg, m->n);
        json_darr(o, "phase_diff_deg", m->phase_diff_deg, m->n);
        json_lockin(o, m->lockin_amplitude_m, m->lockin_phase_deg, m->peak_force_n);
        afmt_json_num(o, "min_deflection_m", m->min_deflection_m);
        afmt_json_num(o, "indentation_m", m->indentation_m);
        afmt_json_num(o, "contact_time_s", m->contact_time_s);
        afmt_json_num(o, "pre_contact_velocity_m_s", m->pre_contact_velocity_m_s);
        afmt_json_num(o, "dissipated_energy_j", m->dissipated_energy_j);
        afmt_json_num(o, "mean_deflection_m", m->mean_deflection_m);
        afmt_json_num(o, "squeeze_dissipated_energy_j", m->squeeze_dissipated_energy_j);
        json_oppoint(o, m->separation_m, m->n_tones, m->tone_frequency_hz, m->tone_amplitude_m);
        json_tip(o, m->tip_x_m, m->tip_y_m, m->true_height_m, m->material);
        if (m->fm_lock_state >= 0) { /* issue 32: the internal FM loops */
            json_str(o, "fm_lock_state", fm_lock_name(m->fm_lock_state));
            json_str(o, "fm_drive", fm_drive_name(m->fm_drive));
            afmt_json_num(o, "fm_frequency_shift_hz", m->fm_frequency_shift_hz);
            afmt_json_num(o, "fm_phase_error_deg", m->fm_phase_error_deg);
        }
        afmt_json_emit(o);
        return;
    }
    printf("harmonics seq %lld t %.9f s Z %.4g nm fe %.6g Hz lock-in %.5g nm %.3f deg (lag), "
           "peak force %.4g nN, min deflection %.4g nm, contact %.4g ns, E_ts %.4g eV, E_sq %.4g "
           "eV",
           (long long)m->seq_applied, m->t_s, m->separation_m * 1e9, m->fe_hz,
           m->lockin_amplitude_m * 1e9, m->lockin_phase_deg, m->peak_force_n * 1e9,
           m->min_deflection_m * 1e9, m->contact_time_s * 1e9, m->dissipated_energy_j / LISTEN_EV_J,
           m->squeeze_dissipated_energy_j / LISTEN_EV_J);
    for (int i = 0; i < m->n; i++)
        printf("%s k%d %.4g nm %.2f deg (lag)", i ? "," : ";", m->k[i],
               m->deflection_amplitude_m[i] * 1e9, m->deflection_lag_deg[i]);
    if (m->tip_x_m != 0 || m->tip_y_m != 0 || m->true_height_m != 0 || m->material != 0)
        print_tip("; ", m->tip_x_m, m->tip_y_m, m->true_height_m, m->material);
    if (m->fm_lock_state >= 0)
        printf("; FM (%s) %s, shift %.6g Hz, phase error %.4g deg", fm_drive_name(m->fm_drive),
               fm_lock_name(m->fm_lock_state), m->fm_frequency_shift_hz, m->fm_phase_error_deg);
    printf("\n");
}

static void print_status(const listen_ctx *c, const char *channel, const afmtwin_status_t *m) {
    if (c->json) {
        cJSON *o = json_head(channel, "status", m->utime, m->msg_seq);
        json_int(o, "seq_applied", m->seq_applied);
        afmt_json_num(o, "model_time_s", m->model_time_s);
        afmt_json_num(o, "realtime_factor", m->realtime_factor);
        json_int(o, "overruns", m->overruns);
        afmt_json_num(o, "lag_s", m->lag_s);
        json_int(o, "received", m->received);
        json_int(o, "rejected", m->rejected);
        json_str(o, "last_reject", m->last_reject);
        json_int(o, "blowups", m->blowups);
        json_str(o, "mode", m->mode);
        cJSON_AddNumberToObject(o, "running", m->running);
        afmt_json_num(o, "separation_m", m->separation_m);
        afmt_json_num(o, "fe_hz", m->fe_hz);
        afmt_json_num(o, "amplitude_m", m->amplitude_m);
        json_int(o, "applied", m->applied);
        json_int(o, "resyncs", m->resyncs);
        json_int(o, "chain_stalls", m->chain_stalls);
        afmt_json_num(o, "chain_lag_s", m->chain_lag_s);
        json_str(o, "can_state", m->can_state);
        json_int(o, "can_frames", m->can_frames);
        json_int(o, "can_rejected", m->can_rejected);
        json_int(o, "can_errors", m->can_errors);
        json_int(o, "can_reconnects", m->can_reconnects);
        json_str(o, "can_last_reject", m->can_last_reject);
        cJSON_AddNumberToObject(o, "heartbeat_ok", m->heartbeat_ok);
        json_int(o, "refused", m->refused);
        json_str(o, "last_refusal", m->last_refusal);
        json_int(o, "dropped", m->dropped);
        json_str(o, "last_drop", m->last_drop);
        json_int(o, "tick_resends", m->tick_resends); /* lockstep re-sends */
        json_int(o, "republished", m->republished);
        cJSON_AddNumberToObject(o, "auto_paused", m->auto_paused);
        json_str(o, "pause_reason", m->pause_reason);
        afmt_json_num(o, "realtime_factor_1s", m->realtime_factor_1s);
        afmt_json_num(o, "resync_skipped_s", m->resync_skipped_s);
        json_lockin(o, m->lockin_amplitude_m, m->lockin_phase_deg, m->peak_force_n);
        afmt_json_num(o, "last_reject_age_s", m->last_reject_age_s);
        cJSON_AddNumberToObject(o, "last_reject_old", m->last_reject_old);
        json_str(o, "rt_scheme", m->rt_scheme);
        json_str(o, "rt_scheme_reason", m->rt_scheme_reason);
        json_int(o, "scheme_handovers", m->scheme_handovers);
        afmt_json_num(o, "model_s_accurate", m->model_s_accurate);
        afmt_json_num(o, "model_s_fast", m->model_s_fast);
        json_str(o, "fm_control", m->fm_control); /* issue 32 */
        json_str(o, "fm_drive", m->fm_drive);
        json_str(o, "fm_lock_state", m->fm_lock_state);
        afmt_json_num(o, "fm_frequency_hz", m->fm_frequency_hz);
        afmt_json_num(o, "fm_reference_hz", m->fm_reference_hz);
        afmt_json_num(o, "fm_frequency_shift_hz", m->fm_frequency_shift_hz);
        afmt_json_num(o, "fm_phase_error_deg", m->fm_phase_error_deg);
        afmt_json_num(o, "fm_drive_amplitude_m", m->fm_drive_amplitude_m);
        afmt_json_num(o, "fm_amplitude_m", m->fm_amplitude_m);
        afmt_json_num(o, "fm_amplitude_setpoint_m", m->fm_amplitude_setpoint_m);
        json_int(o, "fm_tone_changes", m->fm_tone_changes);
        afmt_json_num(o, "squeeze_dissipated_energy_j",
                      m->squeeze_dissipated_energy_j); /* issue 30 */
        json_int(o, "sample_on", m->sample_on);        /* issue 18: the sample under the tip */
        json_tip(o, m->tip_x_m, m->tip_y_m, m->true_height_m, m->material);
        json_str(o, "scan_mode", m->scan_mode);
        json_int(o, "scan_line", m->scan_line);
        json_int(o, "scan_pixel", m->scan_pixel);
        json_int(o, "scan_retrace", m->scan_retrace);
        json_str(o, "am_control", m->am_control);
        afmt_json_num(o, "am_z_m", m->am_z_m);
        afmt_json_num(o, "am_error_m", m->am_error_m);
        afmt_json_num(o, "am_setpoint_m", m->am_setpoint_m);
        afmt_json_num(o, "am_amplitude_m", m->am_amplitude_m);
        afmt_json_num(o, "free_amplitude_m", m->free_amplitude_m); /* issue 30: A0, A/A0 */
        afmt_json_num(o, "amplitude_ratio", m->amplitude_ratio);
        afmt_json_emit(o);
        return;
    }
    char lr[SHOW_LEN], mode[SHOW_LEN], cs[SHOW_LEN], clr[SHOW_LEN];
    show(lr, m->last_reject);
    show(mode, m->mode);
    show(cs, m->can_state);
    show(clr, m->can_last_reject);
    char lf[SHOW_LEN], ld[SHOW_LEN], pr[SHOW_LEN];
    show(lf, m->last_refusal);
    show(ld, m->last_drop);
    show(pr, m->pause_reason);
    /* A0 is NaN from a change of the drive or the model until it is computed again, which
     * only afmtwind --a0-track does (README, "Free amplitude A0"): say so, not "nan". */
    char a0s[96];
    if (isfinite(m->free_amplitude_m))
        snprintf(a0s, sizeof a0s, "A0 %.6g nm, A/A0 %.4f", m->free_amplitude_m * 1e9,
                 m->amplitude_ratio);
    else
        snprintf(a0s, sizeof a0s,
                 "A0 not known (drive or model changed; afmtwind --a0-track "
                 "recomputes it)");
    printf("status    seq %lld t %.6f s %s %s rtf(1 s) %.4g lag %.3g s resyncs %lld (%.4g s "
           "skipped) chain lag %.3g s overruns %lld | lock-in %.4g nm, phase lag %.2f deg, peak "
           "force %.4g nN, E_sq %.4g eV, %s | Z %.4g nm fe %.6g Hz Ae %.4g nm | "
           "received %lld applied "
           "%lld rejected %lld refused %lld%s%s%s dropped %lld%s%s%s blowups %lld",
           (long long)m->seq_applied, m->model_time_s, mode[0] ? mode : "?",
           m->auto_paused ? "PAUSED ITSELF"
           : m->running   ? "running"
                          : "paused",
           m->realtime_factor_1s, m->lag_s, (long long)m->resyncs, m->resync_skipped_s,
           m->chain_lag_s, (long long)m->overruns, m->lockin_amplitude_m * 1e9, m->lockin_phase_deg,
           m->peak_force_n * 1e9, m->squeeze_dissipated_energy_j / LISTEN_EV_J, a0s,
           m->separation_m * 1e9, m->fe_hz, m->amplitude_m * 1e9, (long long)m->received,
           (long long)m->applied, (long long)m->rejected, (long long)m->refused,
           lf[0] ? " (last: " : "", lf, lf[0] ? ")" : "", (long long)m->dropped, ld[0] ? " (" : "",
           ld, ld[0] ? ")" : "", (long long)m->blowups);
    if (lr[0])
        printf(" (last rejected %.1f s ago%s: %s)", m->last_reject_age_s,
               m->last_reject_old ? ", old: later commands applied" : "", lr);
    if (m->tick_resends > 0)
        printf(" | lockstep: %lld ticks re-sent, %lld completions published again",
               (long long)m->tick_resends, (long long)m->republished);
    if (m->rt_scheme && m->rt_scheme[0]) /* one line per message: the reason is in --json */
        printf(" | rt scheme %s, %lld handovers", m->rt_scheme, (long long)m->scheme_handovers);
    if (m->fm_control && strcmp(m->fm_control, "internal") == 0) {
        char fl[SHOW_LEN], fd[SHOW_LEN];
        show(fl, m->fm_lock_state);
        show(fd, m->fm_drive);
        printf(
            " | FM (%s) %s: shift %.4f Hz (f %.6f Hz, ref %.6f Hz) phase error %.3f deg drive %.4g "
            "pm A %.4g nm",
            fd, fl, m->fm_frequency_shift_hz, m->fm_frequency_hz, m->fm_reference_hz,
            m->fm_phase_error_deg, m->fm_drive_amplitude_m * 1e12, m->fm_amplitude_m * 1e9);
    }
    if (m->am_control && strcmp(m->am_control, "internal") == 0) /* issue 18 */
        printf(" | AM Z loop: Z %.5g nm error %.4g nm (set-point %.4g nm, A %.4g nm)",
               m->am_z_m * 1e9, m->am_error_m * 1e9, m->am_setpoint_m * 1e9,
               m->am_amplitude_m * 1e9);
    if (m->sample_on) { /* issue 18 */
        char sm[SHOW_LEN];
        show(sm, m->scan_mode);
        print_tip(" | ", m->tip_x_m, m->tip_y_m, m->true_height_m, m->material);
        printf(", scan %s", sm);
        if (m->scan_line >= 0)
            printf(" line %d pixel %d %s", m->scan_line, m->scan_pixel,
                   m->scan_retrace ? "retrace" : "trace");
    }
    printf("\n");
    if (m->auto_paused) printf("          %s\n", pr);
    if (cs[0] && strcmp(cs, "off") != 0)
        printf("          CAN %s, heartbeat %s, frames %lld rejected %lld errors %lld reconnects "
               "%lld%s%s%s\n",
               cs, m->heartbeat_ok ? "ok" : "missing", (long long)m->can_frames,
               (long long)m->can_rejected, (long long)m->can_errors, (long long)m->can_reconnects,
               clr[0] ? " (last: " : "", clr, clr[0] ? ")" : "");
}

/* The reports left out since the last line, if any. */
static void throttle_flush(const listen_throttle *t, const char *what) {
    if (t->quiet) fprintf(stderr, "afmtwin listen: ... and %ld more %s\n", t->quiet, what);
}

/* Whether one more report may go to stderr now (else it is counted in t->quiet); what: the
 * reports, for the "... and N more WHAT" line. */
static bool throttle_pass(listen_throttle *t, const char *what) {
    double now = afmt_mono_s();
    if (now - t->t0 >= 1.0) {
        throttle_flush(t, what);
        t->quiet = 0;
        t->t0 = now;
        t->in_second = 0;
    }
    if (t->in_second++ < BAD_LINES_PER_S) return true;
    t->quiet++;
    return false;
}

/* A message that does not decode: counted, and reported on stderr (throttled). */
static void report_bad(listen_ctx *c, const char *channel, uint32_t size, const char *type,
                       const char *why) {
    c->bad++;
    if (!throttle_pass(&c->bad_lines, "that did not decode")) return;
    fprintf(stderr, "afmtwin listen: %s: %u bytes that do not decode as %s (%s; ignored)\n",
            channel, size, type, why);
}

/* msg_seq of channel k: a jump forward is lost messages (reported, throttled as report_bad);
 * a jump back is a restarted publisher (said once per restart). */
static void track_seq(listen_ctx *c, int k, int64_t seq) {
    int64_t last = c->last_seq[k];
    c->last_seq[k] = seq;
    c->n_ch[k]++;
    if (last < 0 || seq == last + 1) return;
    if (seq <= last) {
        c->restarts[k]++;
        fprintf(stderr, "afmtwin listen: %s: msg_seq %lld after %lld: the publisher restarted\n",
                c->ch.out[k], (long long)seq, (long long)last);
        return;
    }
    long long lost = (long long)(seq - last - 1);
    c->lost[k] += lost;
    c->gaps[k]++;
    if (!throttle_pass(&c->gap_lines, "gaps (summary at exit)")) return;
    fprintf(stderr, "afmtwin listen: %s: %lld messages lost (msg_seq %lld -> %lld)\n", c->ch.out[k],
            lost, (long long)last, (long long)seq);
}

/* At exit, on stderr: messages per channel, lost ones and gaps, undecodable ones (seconds <
 * 0: from a log). */
static void print_summary(const listen_ctx *c, double seconds) {
    if (seconds >= 0)
        fprintf(stderr, "afmtwin listen: %ld messages in %.3g s:", c->got, seconds);
    else
        fprintf(stderr, "afmtwin listen: %ld messages from %s:", c->got, c->log);
    long long lost = 0;
    for (int k = 0; k < N_OUT; k++) {
        if (!c->want[k]) continue;
        lost += c->lost[k];
        fprintf(stderr, " %s %lld", afmt_out_names[k], c->n_ch[k]);
        if (c->lost[k]) fprintf(stderr, " (%lld lost in %lld gaps)", c->lost[k], c->gaps[k]);
        if (c->restarts[k]) fprintf(stderr, " (%lld restarts)", c->restarts[k]);
    }
    fprintf(stderr, "; %lld lost, %ld did not decode\n", lost, c->bad);
}

static void print_done(const listen_ctx *c, const char *channel, const afmtwin_tick_done_t *m) {
    if (c->json) {
        cJSON *o = json_head(channel, "tick_done", m->utime, m->msg_seq);
        json_int(o, "seq", m->seq);
        json_int(o, "samples", m->samples);
        afmt_json_num(o, "model_time_s", m->model_time_s);
        json_int(o, "n_samples_msgs", m->n_samples_msgs);
        json_int(o, "n_harmonics_msgs", m->n_harmonics_msgs);
        char dg[24];
        snprintf(dg, sizeof dg, "%016llx", (unsigned long long)m->samples_digest);
        cJSON_AddStringToObject(o, "samples_digest", dg);
        snprintf(dg, sizeof dg, "%016llx", (unsigned long long)m->harmonics_digest);
        cJSON_AddStringToObject(o, "harmonics_digest", dg);
        afmt_json_emit(o);
        return;
    }
    printf("tick_done seq %lld samples %lld t %.9f s: %lld samples messages (digest %016llx), "
           "%lld harmonics (digest %016llx)\n",
           (long long)m->seq, (long long)m->samples, m->model_time_s, (long long)m->n_samples_msgs,
           (unsigned long long)m->samples_digest, (long long)m->n_harmonics_msgs,
           (unsigned long long)m->harmonics_digest);
}

/* One handler for all channels: the channel name says the type. The bytes are checked
 * before lcm-gen's decoder sees them (afm_lcm_wire.h); a message that does not decode
 * (wrong type, truncated, crafted lengths) is reported on stderr and not counted. */
static void on_message(const lcm_recv_buf_t *rb, const char *channel, void *user) {
    listen_ctx *c = user;
    if (c->count > 0 && c->got >= c->count) return;
    int k = -1;
    for (int i = 0; i < N_OUT; i++)
        if (c->want[i] && !strcmp(channel, c->ch.out[i])) k = i;
    if (k < 0) return;
    static const afm_wire_type *const types[N_OUT] = {&afm_wire_samples_t, &afm_wire_harmonics_t,
                                                      &afm_wire_status_t, &afm_wire_tick_done_t};
    union {
        afmtwin_samples_t samples;
        afmtwin_harmonics_t harmonics;
        afmtwin_status_t status;
        afmtwin_tick_done_t done;
    } m;
    char why[AFM_ERR_LEN];
    if (afm_wire_decode(types[k], rb->data, rb->data_size, &m, why, sizeof why)) {
        report_bad(c, channel, rb->data_size, types[k]->name, why);
        return;
    }
    track_seq(c, k,
              k == AFMT_OUT_SAMPLES     ? m.samples.msg_seq
              : k == AFMT_OUT_HARMONICS ? m.harmonics.msg_seq
              : k == AFMT_OUT_STATUS    ? m.status.msg_seq
                                        : m.done.msg_seq);
    if (k == AFMT_OUT_SAMPLES)
        print_samples(c, channel, &m.samples);
    else if (k == AFMT_OUT_HARMONICS)
        print_harmonics(c, channel, &m.harmonics);
    else if (k == AFMT_OUT_STATUS)
        print_status(c, channel, &m.status);
    else
        print_done(c, channel, &m.done);
    afm_wire_free(types[k], &m);
    fflush(stdout);
    c->got++;
}

/* Messages from a log file, in order, through the same handler. Every event header is
 * checked before anything is allocated for it (afm_lcm_log.h). */
static void print_summary(const listen_ctx *c, double seconds);

static int listen_log(listen_ctx *c) {
    char err[AFM_ERR_LEN];
    afm_lcm_log *l = afm_lcm_log_open(c->log, 0, err, sizeof err);
    if (!l) {
        fprintf(stderr, "afmtwin listen: cannot read log: %s\n", err);
        return 1;
    }
    afm_lcm_log_event ev;
    int r = 1;
    while ((c->count == 0 || c->got < c->count) &&
           (r = afm_lcm_log_next(l, &ev, err, sizeof err)) > 0) {
        lcm_recv_buf_t rb = {.data = (void *)ev.data,
                             .data_size = ev.datalen,
                             .recv_utime = ev.timestamp,
                             .lcm = NULL};
        on_message(&rb, ev.channel, c);
    }
    long long skipped = afm_lcm_log_skipped(l);
    afm_lcm_log_close(&l);
    throttle_flush(&c->gap_lines, "gaps");
    print_summary(c, -1);
    throttle_flush(&c->bad_lines, "that did not decode");
    if (skipped > 0)
        fprintf(stderr, "afmtwin listen: %s: skipped %lld bytes that are no LCM event\n", c->log,
                skipped);
    if (r < 0) {
        fprintf(stderr, "afmtwin listen: %s: %s; stopped after %ld messages\n", c->log, err,
                c->got);
        return 1;
    }
    if (c->count > 0 && c->got < c->count) {
        fprintf(stderr, "afmtwin listen: the log ended after %ld of %ld messages\n", c->got,
                c->count);
        return 1;
    }
    return 0;
}

int afm_cmd_listen(int argc, char **argv) {
    listen_ctx c = {.prefix = AFMT_DEFAULT_PREFIX};
    for (int i = 0; i < N_OUT; i++) {
        c.want[i] = true;
        c.last_seq[i] = -1;
    }
    const afmt_opt opts[] = {
        AFMT_FLAG("--json", &c.json),
        AFMT_FLAG("--full", &c.full),
        AFMT_LONG("--count", &c.count, 1, 1e12, "an integer >= 1"),
        AFMT_DOUBLE_ABOVE("--timeout", &c.timeout_s, 0, 1e7, "seconds > 0"),
        AFMT_FN("--channels", afmt_opt_channels, c.want, AFMT_OPT_CHANNELS_WANTS),
        AFMT_LCM_OPTS(&c.url, &c.out_url, &c.samples_url, &c.prefix),
        AFMT_STRING("--log", &c.log),
        AFMT_OPTS_END,
    };
    int prc = afmt_opts_parse("listen", opts, argc, argv, 1);
    if (prc == AFMT_OPTS_HELP) listen_usage(stdout);
    if (prc) return prc == AFMT_OPTS_HELP ? 0 : 2;
    char err[256];
    if (afmt_channels_init(&c.ch, c.prefix, err, sizeof err)) {
        fprintf(stderr, "afmtwin listen: %s\n", err);
        return 2;
    }
    if (c.log) return listen_log(&c);
    afmt_lcm o;
    int orc = afmt_lcm_open(&o, c.url, c.out_url, c.samples_url,
                            c.want[AFMT_OUT_SAMPLES] ? AFMT_OPEN_SAMPLES : 0, err, sizeof err);
    if (orc) {
        fprintf(stderr, "afmtwin listen: %s\n", err);
        return orc == -1 ? 2 : 1;
    }
    for (int i = 0; i < N_OUT; i++) {
        if (!c.want[i]) continue;
        lcm_subscription_t *sub = lcm_subscribe(afmt_lcm_of(&o, i), c.ch.out[i], on_message, &c);
        if (!sub) {
            fprintf(stderr, "afmtwin listen: cannot subscribe to %s\n", c.ch.out[i]);
            afmt_lcm_close(&o);
            return 1;
        }
        /* the daemon publishes in bursts (one block's outputs at once) */
        lcm_subscription_set_queue_capacity(sub, LISTEN_QUEUE);
    }
    struct sigaction sa = {.sa_handler = on_signal}; /* no SA_RESTART: the wait ends at once */
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    double t0 = afmt_mono_s(), t_end = c.timeout_s > 0 ? t0 + c.timeout_s : INFINITY;
    int rc = 0;
    while (!listen_stop && (c.count == 0 || c.got < c.count)) {
        double left = t_end - afmt_mono_s();
        if (left <= 0) break;
        int ms = left > 0.2 ? 200 : (int)ceil(left * 1e3);
        if (afmt_lcm_handle(&o, ms) < 0 && !listen_stop) {
            fprintf(stderr, "afmtwin listen: LCM receive failed\n");
            rc = 1;
            break;
        }
    }
    throttle_flush(&c.bad_lines, "that did not decode");
    throttle_flush(&c.gap_lines, "gaps");
    if (listen_stop) {
        fprintf(stderr, "afmtwin listen: stopped by a signal\n");
    } else if (rc == 0 && c.count > 0 && c.got < c.count) {
        fprintf(stderr, "afmtwin listen: timed out after %ld of %ld messages\n", c.got, c.count);
        rc = 1;
    } else if (rc == 0 && c.got == 0) {
        fprintf(stderr,
                "afmtwin listen: nothing received within %g s (is afmtwind running on these "
                "URLs, with this prefix?)\n",
                c.timeout_s);
        rc = 1;
    }
    print_summary(&c, afmt_mono_s() - t0);
    afmt_lcm_close(&o);
    return rc;
}
