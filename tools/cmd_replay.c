/* SPDX-License-Identifier: MIT */
/* cmd_replay.c -- `afmtwin replay`: runs the commands of an LCM log through the twin
 * (afm_runner) in model time, as fast as possible, and writes the outputs (samples,
 * harmonics, status) to an LCM log, bit-identical on every run.
 *
 * Time: a command logged at time t applies when the twin has run
 * ceil_B(round((t - t_first) * speed * rate)) samples since the start, ceil_B rounding up to
 * a multiple of the block size B (commands apply at block boundaries, as in the daemon);
 * t_first is the time of the first command in the log, speed --speed (1: a log of wall time
 * by a daemon at --speed 1). While the twin is paused (control
 * pause) model time stands still and commands apply in log order without advancing it.
 * With --lockstep the twin advances only by the log's tick commands and log times do not
 * matter. Output events carry model time (us) as their time stamp and utime: nothing from
 * the wall clock enters the output. When a tick (or, paused, a step) budget is used up, a
 * tick_done event follows the outputs, with the digest of the samples and harmonics
 * messages since the previous one, as the daemon publishes it (afm_lcm_digest). */
#include "afmtwin_cmds.h"
#include "lcm_tool.h"
#include "opts.h"

#include "transport/afm_cmd_lcm.h"
#include "config/afm_config.h"
#include "transport/afm_io.h"
#include "runner/afm_a0.h"
#include "runner/afm_fm.h"
#include "runner/afm_runner.h"

#include "transport/afm_io_records.h"
#include "transport/afm_lcm_encode.h"
#include "transport/afm_lcm_log.h"

#include <lcm/eventlog.h>
#include <limits.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define REPLAY_DEFAULT_BLOCK 1024    /* samples per block: 72.8 us at 14.06 MHz */
#define REPLAY_STATUS_INTERVAL_S 0.1 /* status every 0.1 s of model time, as the daemon's 10 Hz */
#define REPLAY_PERIODS_MAX 256
/* A command logged more than this long after the first one: the log's time stamps are
 * broken (or not lcm-logger's), and replaying the gap would run for days. */
#define REPLAY_MAX_SPAN_S 1e6

enum {
    OUT_SAMPLES = AFMT_OUT_SAMPLES,
    OUT_HARMONICS = AFMT_OUT_HARMONICS,
    OUT_STATUS = AFMT_OUT_STATUS,
    OUT_DONE = AFMT_OUT_TICK_DONE,
    N_OUT = AFMT_N_OUT
};

typedef struct {
    const char *config, *in, *out, *prefix;
    int block;
    int harmonics_every;     /* write every k-th period's harmonics; 0: automatic */
    double harmonics_max_hz; /* the automatic k: at most this many records a second */
    double tail_s;
    double speed; /* model seconds per logged second (the daemon's --speed) */
    bool lockstep, quiet;
    bool applied; /* --applied: the log is afmtwind --applied-log's (time stamps: samples) */
    bool want[N_OUT];
} replay_opts;

typedef struct {
    replay_opts o;
    afm_runner *r;
    lcm_eventlog_t *log;
    afmt_channels ch;
    long long status_every, next_status; /* samples */
    long long received, rejected, applied, skipped, written;
    bool tick_seen;         /* --lockstep: a tick was received, */
    int64_t last_tick_seq;  /* ... with this seq */
    long long tick_resends; /* ticks with the last tick's seq: absorbed, as afmtwind does */
    char last_reject[AFM_IO_REASON_LEN];
    long long period_count; /* periods seen (harmonics_every) */
    int64_t msg_seq[N_OUT]; /* next msg_seq per output channel, as the daemon numbers them */
    afm_lcm_digest dg;      /* of the messages since the last tick_done */
    bool have_period;
    double lockin_amplitude_m, lockin_phase_deg, peak_force_n; /* the last period's */
    double squeeze_dissipated_energy_j;                        /* ... and its E_sq */
    /* A0 at the drive in force (issue 30): recomputed when tone 0 or the config changed */
    bool a0_dirty;
    double a0_m, a0_fe_hz, a0_ae_m;
    int write_failed;
    uint8_t *buf;
    int cap;
    afm_io_samples rec; /* large: one per context */
    afm_chain_period periods[REPLAY_PERIODS_MAX];
    afm_runner_oppoint period_ops[REPLAY_PERIODS_MAX]; /* each period's own (its item's) */
    afmt_progress pg; /* on stderr, terminals only (not with --quiet) */
} replay_ctx;

static void replay_usage(FILE *f) {
    fprintf(f,
            "usage: afmtwin replay --config FILE --in LOG --out LOG [--prefix NAME_]\n"
            "                      [--block N] [--tail S] [--speed X] [--lockstep | --applied]\n"
            "                      [--channels LIST]\n"
            "                      [--harmonics-every K | --harmonics-max-hz F] [--quiet]\n\n"
            "Runs the commands recorded in an LCM log (lcm-logger's format, e.g. a logged\n"
            "sweep, or one written with `afmtwin send --log`) through the twin of --config in\n"
            "model time, as fast as the machine allows, and writes what the daemon would\n"
            "publish (samples, harmonics, status) to another LCM log. The output is\n"
            "bit-identical on every run: its time stamps are model time, never the wall clock.\n\n"
            "Timing: a command logged at time t applies once the twin has run\n"
            "round((t - t_first) x speed x sample rate) samples, rounded up to a whole block;\n"
            "t_first is the first command's time, speed --speed. Paused (control pause), model\n"
            "time stands still and commands apply in log order. Events on other channels are\n"
            "skipped; commands the daemon would reject are counted and reported in status, as\n"
            "the daemon does.\n\n"
            "options:\n"
            "  --config FILE    the twin's config (libconfig; see config/README.md)\n"
            "  --in LOG         input log: commands on PREFIX + DITHER, SETPOINT, PARAM,\n"
            "                   CONTROL, TICK, SCAN\n"
            "  --out LOG        output log (overwritten): PREFIX + SAMPLES, HARMONICS, STATUS\n"
            "  --prefix NAME_   channel-name prefix (default %s)\n"
            "  --block N        samples per block, 1..1048576 (default %d): commands apply and\n"
            "                   outputs are taken at block boundaries\n"
            "  --tail S         model seconds to run after the last command (default 0.01)\n"
            "  --speed X        model seconds per second of log time, 1e-3..1e3 (default 1): X\n"
            "                   for a log of the commands a daemon at --speed X received\n"
            "  --lockstep       the twin advances only by the log's tick commands (applied in\n"
            "                   log order; log times are ignored). A tick whose seq is that\n"
            "                   of the last tick is a client's re-send: not run again, no\n"
            "                   completion (afmtwind publishes the last one again)\n"
            "  --applied        the log is one afmtwind --applied-log wrote: its time stamps\n"
            "                   are sample counts; each command applies after exactly that\n"
            "                   many samples (no block rounding, --speed unused) and the\n"
            "                   scheme follows its PREFIX SCHEME events: the daemon's\n"
            "                   outputs bit for bit, in real time or not\n"
            "  --channels LIST  outputs to write, comma-separated subset of\n"
            "                   samples,harmonics,status,tick_done (default all)\n"
            "  --harmonics-every K  write every K-th period's harmonics (1: all, ~185 MB per\n"
            "                   model second with the samples at 338 kHz; the daemon's\n"
            "                   --harmonics-every K gives the same records)\n"
            "  --harmonics-max-hz F  default: K chosen as the daemon does, the smallest with at\n"
            "                   most F records a second at the drive frequency (default %.0f)\n"
            "  --quiet          no summary (and no progress) on stderr\n"
            "  --help           this text\n\n"
            "Status messages come every %.1f s of model time and at the end; in them mode is\n"
            "\"replay\" (or \"lockstep\"), realtime_factor and lag_s are 0. When a tick (or,\n"
            "paused, a step) budget is used up a tick_done event follows its outputs, with the\n"
            "digest of the samples and harmonics messages since the previous one, as afmtwind\n"
            "publishes it. Progress on stderr (terminals only).\n"
            "Exit status 0 ok, 1 simulation or file failure, 2 bad usage, a bad\n"
            "config or an unreadable log.\n",
            AFMT_DEFAULT_PREFIX, REPLAY_DEFAULT_BLOCK, AFM_IO_HARMONICS_MAX_HZ,
            REPLAY_STATUS_INTERVAL_S);
}

/* ---- output: events stamped with model time ---------------------------------------- */

static int64_t model_us(double t_s) {
    return (int64_t)llround(t_s * 1e6);
}

static void write_event(replay_ctx *x, int ch, int64_t utime, int n) {
    if (n < 0) {
        x->write_failed = 1;
        return;
    }
    if (afmt_log_write(x->log, utime, x->ch.out[ch], x->buf, n))
        x->write_failed = 1;
    else
        x->written++;
}

/* Encode generated type T into x->buf (grown as needed) and write it. */
#define WRITE_MSG(x, T, ch, msg)                                                                   \
    do {                                                                                           \
        int need_ = T##_encoded_size(msg);                                                         \
        if (need_ > (x)->cap) {                                                                    \
            uint8_t *nb_ = realloc((x)->buf, (size_t)need_);                                       \
            if (!nb_) {                                                                            \
                (x)->write_failed = 1;                                                             \
                break;                                                                             \
            }                                                                                      \
            (x)->buf = nb_;                                                                        \
            (x)->cap = need_;                                                                      \
        }                                                                                          \
        (msg)->msg_seq = (x)->msg_seq[ch]++;                                                       \
        write_event((x), (ch), (msg)->utime, T##_encode((x)->buf, 0, (x)->cap, (msg)));            \
    } while (0)

static void emit_samples(replay_ctx *x, int64_t seq) {
    for (int st = 0; st < afm_runner_n_streams(x->r); st++) {
        afm_chain_block b;
        while (afm_runner_take_block(x->r, st, &b, AFM_IO_MAX_BLOCK) > 0) {
            afm_runner_chain_status cs;
            afm_runner_chain_status_get(x->r, &cs);
            afm_io_samples_from_block(&x->rec, &b, model_us(b.t_s[0]), seq, &cs.op);
            afmtwin_samples_t m;
            afm_lcm_samples_msg(&x->rec, &m);
            afm_lcm_digest_samples(&x->dg, &m); /* also when not written: tick_done has it */
            if (!x->o.want[OUT_SAMPLES]) continue;
            WRITE_MSG(x, afmtwin_samples_t, OUT_SAMPLES, &m);
        }
    }
}

static void emit_harmonics(replay_ctx *x, const afm_runner_status *st) {
    int np;
    while ((np = afm_runner_take_periods_op(x->r, x->periods, x->period_ops, REPLAY_PERIODS_MAX)) >
           0) {
        const afm_chain_period *last = &x->periods[np - 1];
        x->have_period = true;
        x->lockin_amplitude_m = last->lockin_amplitude_m;
        x->lockin_phase_deg = last->lockin_phase_deg;
        x->peak_force_n = last->cycle.peak_force_n;
        x->squeeze_dissipated_energy_j = last->cycle.squeeze_dissipated_energy_j;
        int every = afm_io_harmonics_every(x->o.harmonics_every, st->fe_hz, x->o.harmonics_max_hz);
        for (int p = 0; p < np; p++) {
            if (x->period_count++ % every != 0) continue;
            const afm_cycle_metrics *c = &x->periods[p].cycle;
            afm_io_harmonics h;
            afm_io_harmonics_from_period(&h, &x->periods[p], st->fe_hz,
                                         model_us(c->t_start_s + c->duration_s), st->seq_applied,
                                         &x->period_ops[p]);
            afm_lcm_harm_buf buf;
            afmtwin_harmonics_t m;
            afm_lcm_harmonics_msg(&h, &buf, &m);
            afm_lcm_digest_harmonics(&x->dg, &m);
            if (!x->o.want[OUT_HARMONICS]) continue;
            WRITE_MSG(x, afmtwin_harmonics_t, OUT_HARMONICS, &m);
        }
    }
}

/* A0 (runner/afm_a0.h) of the running config at tone 0 of st's drive, as the daemon's
 * status has it: recomputed (a short simulation, here in line: replay is offline) only when
 * tone 0 or the config changed since the last one. Under internal FM the loops move tone 0
 * every period: A0 stays that of the commanded drive, as in the daemon. NaN if it fails. */
static double replay_a0(replay_ctx *x, const afm_runner_status *st) {
    const afm_config *cfg = afm_runner_config(x->r);
    double fe = st->fe_hz, ae = st->amplitude_m;
    if (st->fm_on) { /* the commanded drive: the config's tone 0 */
        fe = cfg->drive.tones[0].frequency_hz;
        ae = cfg->drive.tones[0].amplitude_m;
    }
    if (!x->a0_dirty && fe == x->a0_fe_hz && ae == x->a0_ae_m) return x->a0_m;
    static afm_config c; /* large */
    c = *cfg;
    c.drive.tones[0].frequency_hz = fe;
    c.drive.tones[0].amplitude_m = ae;
    afm_a0 a;
    char err[AFM_ERR_LEN];
    if (ae == 0)
        x->a0_m = 0; /* a silent tone 0: the lever rests */
    else
        x->a0_m = afm_a0_compute(&c, &a, err, sizeof err) ? NAN : a.amplitude_m;
    x->a0_fe_hz = fe;
    x->a0_ae_m = ae;
    x->a0_dirty = false;
    return x->a0_m;
}

static void emit_status(replay_ctx *x, const afm_runner_status *st) {
    if (!x->o.want[OUT_STATUS]) return;
    static afm_io_status s; /* large (reason strings) */
    memset(&s, 0, sizeof s);
    s.utime = model_us(st->t_s);
    s.seq_applied = st->seq_applied;
    s.model_time_s = st->t_s;
    s.received = x->received;
    s.rejected = x->rejected;
    s.tick_resends = x->tick_resends;
    snprintf(s.last_reject, sizeof s.last_reject, "%s", x->last_reject);
    s.blowups = st->blowups;
    s.mode = x->o.lockstep ? "lockstep" : "replay";
    s.running = st->running ? 1 : 0;
    s.separation_m = st->separation_m;
    s.fe_hz = st->fe_hz;
    s.amplitude_m = st->amplitude_m;
    s.applied = st->applied;
    s.lockin_amplitude_m = x->have_period ? x->lockin_amplitude_m : NAN;
    s.lockin_phase_deg = x->have_period ? x->lockin_phase_deg : NAN;
    s.peak_force_n = x->have_period ? x->peak_force_n : NAN;
    s.squeeze_dissipated_energy_j = x->have_period ? x->squeeze_dissipated_energy_j : NAN;
    s.free_amplitude_m = replay_a0(x, st); /* issue 30 */
    s.amplitude_ratio = s.free_amplitude_m > 0 ? s.lockin_amplitude_m / s.free_amplitude_m : NAN;
    s.last_reject_age_s = -1.0; /* no wall clock in replay */
    snprintf(s.rt_scheme, sizeof s.rt_scheme, "%s", afm_sim_scheme_name(afm_runner_sim(x->r)));
    snprintf(s.rt_scheme_reason, sizeof s.rt_scheme_reason,
             "replay: the config's (offline: accurate)");
    s.sample_on = st->sample_on; /* issue 18: the tip, the sample, the AM Z loop */
    s.tip_x_m = st->tip_x_m;
    s.tip_y_m = st->tip_y_m;
    s.true_height_m = st->true_height_m;
    s.material = st->material;
    s.scan_mode = afm_scan_mode_name(st->scan_mode);
    s.scan_line = st->scan_line;
    s.scan_pixel = st->scan_pixel;
    s.scan_retrace = st->scan_retrace;
    s.am_control = st->am_on ? "internal" : "none";
    s.am_z_m = st->am_z_m;
    s.am_error_m = st->am_error_m;
    s.am_setpoint_m = st->am_setpoint_m;
    s.am_amplitude_m = st->am_amplitude_m;
    s.fm_control = st->fm_on ? "internal" : "none"; /* issue 32: as the daemon's publish.c */
    s.fm_drive = st->fm_on ? afm_fm_drive_name((afm_fm_drive)st->fm_drive) : "none";
    s.fm_lock_state = st->fm_on ? afm_fm_lock_name((afm_fm_lock)st->fm_lock) : "";
    s.fm_frequency_hz = st->fm_frequency_hz;
    s.fm_reference_hz = st->fm_reference_hz;
    s.fm_frequency_shift_hz = st->fm_frequency_hz - st->fm_reference_hz;
    s.fm_phase_error_deg = st->fm_phase_error_deg;
    s.fm_drive_amplitude_m = st->fm_drive_m;
    s.fm_amplitude_m = st->fm_amplitude_m;
    s.fm_amplitude_setpoint_m = st->fm_amplitude_setpoint_m;
    s.fm_tone_changes = st->fm_tone_changes;
    afmtwin_status_t m;
    afm_lcm_status_msg(&s, &m);
    WRITE_MSG(x, afmtwin_status_t, OUT_STATUS, &m);
}

/* A completion the runner passed: after the outputs before it, with their digest. */
static void emit_done(replay_ctx *x) {
    afm_runner_done dn;
    if (!afm_runner_take_done(x->r, &dn)) return;
    if (x->o.want[OUT_DONE]) {
        afm_io_tick_done td = {.utime = model_us(dn.t_s),
                               .seq = dn.seq,
                               .samples = dn.samples,
                               .model_time_s = dn.t_s,
                               .n_samples_msgs = x->dg.n_samples_msgs,
                               .n_harmonics_msgs = x->dg.n_harmonics_msgs,
                               .samples_digest = afm_lcm_digest_samples_final(&x->dg),
                               .harmonics_digest = x->dg.harmonics};
        afmtwin_tick_done_t m;
        afm_lcm_tick_done_msg(&td, &m);
        WRITE_MSG(x, afmtwin_tick_done_t, OUT_DONE, &m);
    }
    afm_lcm_digest_init(&x->dg);
}

/* Take every waiting output (and a completion after them); a status when its time has come
 * (or force). */
static void emit_all(replay_ctx *x, bool force_status) {
    afm_runner_status st;
    afm_runner_status_get(x->r, &st);
    emit_harmonics(x, &st);
    emit_samples(x, st.seq_applied);
    emit_done(x);
    if (force_status || st.samples >= x->next_status) {
        emit_status(x, &st);
        while (x->next_status <= st.samples)
            x->next_status += x->status_every;
    }
}

/* Run block by block until `target` samples since the start (or the twin cannot advance:
 * paused, or out of tick budget). */
static void run_to(replay_ctx *x, long long target) {
    afm_runner_status st;
    afm_runner_status_get(x->r, &st);
    long long s = st.samples;
    while (s < target && !x->write_failed) {
        long long n = x->o.block - s % x->o.block; /* to the next block boundary */
        if (n > target - s) n = target - s;
        long long adv = afm_runner_run(x->r, n);
        s += adv;
        if (s % x->o.block == 0 || adv < n) emit_all(x, false);
        afmt_progress_update(&x->pg, "replay: model time %.4f s, %lld commands, %lld output events",
                             (double)s / afm_runner_config(x->r)->sim.sample_rate_hz, x->received,
                             x->written);
        if (adv < n) break;
    }
}

/* ---- input ------------------------------------------------------------------------ */

static void reject(replay_ctx *x, const char *channel, const char *why) {
    x->rejected++;
    snprintf(x->last_reject, sizeof x->last_reject, "%.60s: %.190s", channel, why);
}

/* --lockstep: a tick whose seq is that of the last tick is a client's re-send (afmtwind's
 * rule, daemon/cmd_in.c): absorbed, counted; the twin does not move. true if c is one. */
static bool tick_resent(replay_ctx *x, const afm_cmd *c) {
    if (!x->o.lockstep || c->kind != AFM_CMD_TICK) return false;
    if (x->tick_seen && c->seq == x->last_tick_seq) {
        x->tick_resends++;
        return true;
    }
    x->tick_seen = true;
    x->last_tick_seq = c->seq;
    return false;
}

static void apply_event(replay_ctx *x, afm_cmd_kind kind, const afm_lcm_log_event *ev) {
    const afm_config *cfg = afm_runner_config(x->r);
    afm_cmd_limits lim = {.sample_rate_hz = cfg->sim.sample_rate_hz,
                          .model = afm_sim_model(afm_runner_sim(x->r))};
    afm_cmd c;
    char err[AFM_ERR_LEN];
    x->received++;
    if (afm_cmd_decode(kind, ev->data, ev->datalen, &lim, &c, err, sizeof err)) {
        reject(x, ev->channel, err);
        return;
    }
    if (tick_resent(x, &c)) return;
    afm_runner_model *model = NULL;
    bool new_chain = false;
    /* the drive in force (tone 0 as given), as the daemon follows it (cmd_in.c drive_now) */
    const afm_drive *dr = afm_sim_drive(afm_runner_sim(x->r));
    afm_cmd_dither now = {.n_tones = dr->n};
    if (dr->n >= 1) {
        now.frequency_hz[0] = dr->freq_hz[0];
        now.amplitude_m[0] = dr->amp_m[0];
    }
    if (afm_runner_cmd_needs_model(cfg, &c, &new_chain)) {
        static afm_config t; /* large */
        t = *cfg;
        if (afm_param_apply(&t, &c.u.param, NULL, err, sizeof err) ||
            !(model = afm_runner_model_build_at(&t, new_chain, &now, err, sizeof err))) {
            reject(x, ev->channel, err);
            return;
        }
    } else if (afm_runner_dither_moves_a0(cfg, &now, &c) &&
               !(model = afm_runner_model_a0(cfg, &c.u.dither, err, sizeof err))) {
        reject(x, ev->channel, err);
        return;
    }
    /* Outputs so far carry the old seq_applied. */
    emit_all(x, false);
    if (afm_runner_apply(x->r, &c, &model, err, sizeof err))
        reject(x, ev->channel, err);
    else {
        x->applied++;
        if (c.kind == AFM_CMD_PARAM || c.kind == AFM_CMD_RELOAD) x->a0_dirty = true;
    }
    afm_runner_model_destroy(&model);
}

/* --applied: one event of an afmtwind --applied-log log. The twin runs to the event's sample
 * count (exactly), then the command applies, or the scheme (PREFIX SCHEME, one byte) is handed
 * over. Counts that go backwards are no such log. 0, or -1 with the reason in bad. */
static int applied_event(replay_ctx *x, const afm_lcm_log_event *ev, long long *last, char *bad,
                         size_t badlen) {
    if (ev->timestamp < *last || ev->timestamp > (int64_t)1 << 62) {
        snprintf(bad, badlen,
                 "event %lld at byte %lld: sample %lld after sample %lld: not a log of "
                 "afmtwind --applied-log",
                 (long long)ev->eventnum, ev->offset, (long long)ev->timestamp, *last);
        return -1;
    }
    *last = ev->timestamp;
    run_to(x, *last);
    char sch[AFMT_CHAN_LEN];
    snprintf(sch, sizeof sch, "%sSCHEME", x->o.prefix);
    if (!strcmp(ev->channel, sch)) {
        if (ev->datalen != 1) {
            snprintf(bad, badlen, "event %lld: %s with %d bytes (1 expected)",
                     (long long)ev->eventnum, sch, (int)ev->datalen);
            return -1;
        }
        emit_all(x, false);
        afm_runner_set_scheme(x->r, ((const uint8_t *)ev->data)[0] == 1); /* none: no schemes */
        return 0;
    }
    afm_cmd_kind kind = afmt_channels_kind(&x->ch, ev->channel);
    if (!kind)
        x->skipped++;
    else
        apply_event(x, kind, ev);
    return 0;
}

/* --harmonics-max-hz: a rate cap instead of --harmonics-every (which it resets to 0). */
static int parse_max_hz(const char *v, void *dest) {
    replay_opts *o = dest;
    double d;
    if (afmt_parse_si(v, AFMT_UNIT_HZ, &d) < 0 || !(d >= 1) || d > 1e9) return -1;
    o->harmonics_max_hz = d;
    o->harmonics_every = 0;
    return 0;
}

static int parse_opts(int argc, char **argv, replay_opts *o) {
    const afmt_opt opts[] = {
        AFMT_FLAG("--lockstep", &o->lockstep),
        AFMT_FLAG("--applied", &o->applied),
        AFMT_FLAG("--quiet", &o->quiet),
        AFMT_STRING("--config", &o->config),
        AFMT_STRING("--in", &o->in),
        AFMT_STRING("--out", &o->out),
        AFMT_STRING("--prefix", &o->prefix),
        AFMT_INT("--block", &o->block, 1, 1048576, "an integer in 1..1048576"),
        AFMT_INT("--harmonics-every", &o->harmonics_every, 1, 1e9, "an integer >= 1"),
        AFMT_FN_UNIT("--harmonics-max-hz", parse_max_hz, o,
                     "1..1e9 Hz (or with a suffix: kHz, MHz, GHz)", AFMT_UNIT_HZ),
        AFMT_DOUBLE("--tail", &o->tail_s, 0, 1e4, "seconds in 0..1e4"),
        AFMT_DOUBLE("--speed", &o->speed, 1e-3, 1e3, "a number in 1e-3..1e3"),
        AFMT_FN("--channels", afmt_opt_channels, o->want, AFMT_OPT_CHANNELS_WANTS),
        AFMT_OPTS_END,
    };
    int rc = afmt_opts_parse("replay", opts, argc, argv, 1);
    if (rc == AFMT_OPTS_HELP) replay_usage(stdout);
    if (rc) return rc;
    if (!o->config || !o->in || !o->out) {
        fprintf(stderr, "afmtwin replay: --config, --in and --out are required (see --help)\n");
        return 2;
    }
    if (o->applied && o->lockstep) {
        fprintf(stderr, "afmtwin replay: --applied and --lockstep exclude each other\n");
        return 2;
    }
    if (!strcmp(o->in, o->out)) {
        fprintf(stderr, "afmtwin replay: --in and --out name the same file\n");
        return 2;
    }
    return 0;
}

int afm_cmd_replay(int argc, char **argv) {
    static replay_ctx x; /* large: the samples record */
    memset(&x, 0, sizeof x);
    x.o = (replay_opts){.prefix = AFMT_DEFAULT_PREFIX,
                        .block = REPLAY_DEFAULT_BLOCK,
                        .harmonics_every = 0,
                        .harmonics_max_hz = AFM_IO_HARMONICS_MAX_HZ,
                        .tail_s = 0.01,
                        .speed = 1.0,
                        .want = {true, true, true, true}};
    afm_lcm_digest_init(&x.dg);
    x.a0_dirty = true;
    int rc = parse_opts(argc, argv, &x.o);
    if (rc) return rc == 1 ? 0 : rc;
    char err[AFM_ERR_LEN];
    if (afmt_channels_init(&x.ch, x.o.prefix, err, sizeof err)) goto usage_err;

    static afm_config cfg;
    if (afm_config_load(x.o.config, &cfg, err, sizeof err)) goto usage_err;
    afm_lcm_log *in = afm_lcm_log_open(x.o.in, 0, err, sizeof err);
    if (!in) {
        fprintf(stderr, "afmtwin replay: cannot read log: %s\n", err);
        return 2;
    }
    x.r = afm_runner_create(&cfg, x.o.block, x.o.lockstep, err, sizeof err);
    if (!x.r) {
        afm_lcm_log_close(&in);
        fprintf(stderr, "afmtwin replay: %s\n", err);
        return 1;
    }
    x.log = lcm_eventlog_create(x.o.out, "w");
    if (!x.log) {
        fprintf(stderr, "afmtwin replay: cannot write log '%s'\n", x.o.out);
        afm_lcm_log_close(&in);
        afm_runner_destroy(&x.r);
        return 1;
    }
    double rate = cfg.sim.sample_rate_hz;
    x.status_every = llround(REPLAY_STATUS_INTERVAL_S * rate);
    x.next_status = 0;
    double wall0 = afmt_mono_s();
    afmt_progress_init(&x.pg);
    if (x.o.quiet) x.pg.tty = false;
    emit_all(&x, true); /* status at model time 0 */

    bool have_first = false;
    int64_t t_first = 0;
    long long last_target = 0, events = 0, backwards = 0;
    afm_lcm_log_event ev;
    int r;
    char bad[AFM_ERR_LEN] = "";
    while (!x.write_failed && (r = afm_lcm_log_next(in, &ev, err, sizeof err)) != 0) {
        if (r < 0) {
            snprintf(bad, sizeof bad, "%s", err);
            break;
        }
        events++;
        if (x.o.applied) {
            if (applied_event(&x, &ev, &last_target, bad, sizeof bad)) break;
            continue;
        }
        afm_cmd_kind kind = afmt_channels_kind(&x.ch, ev.channel);
        if (!kind) {
            x.skipped++;
            continue;
        }
        if (!have_first) {
            have_first = true;
            t_first = ev.timestamp;
        }
        if (!x.o.lockstep) {
            /* samples since the start, rounded up to a block boundary; the gap in 64-bit
             * integers without overflow, and bounded before it is turned into samples */
            int64_t gap_us;
            if (__builtin_sub_overflow(ev.timestamp, t_first, &gap_us) ||
                (double)gap_us > REPLAY_MAX_SPAN_S * 1e6) {
                snprintf(bad, sizeof bad,
                         "event %lld at byte %lld: time stamp %lld us is more than %g s after "
                         "the first command's (%lld us): not a replayable log",
                         (long long)ev.eventnum, ev.offset, (long long)ev.timestamp,
                         REPLAY_MAX_SPAN_S, (long long)t_first);
                break;
            }
            if (gap_us < 0) backwards++; /* applies now, in log order */
            double n_d = gap_us > 0 ? (double)gap_us * 1e-6 * x.o.speed * rate : 0.0; /* < 1e18 */
            long long k = n_d < 9e18 ? llround(n_d) : LLONG_MAX - x.o.block;
            k = (k + x.o.block - 1) / x.o.block * x.o.block;
            if (k > last_target) last_target = k;
            run_to(&x, last_target);
        }
        apply_event(&x, kind, &ev);
        if (x.o.lockstep) {
            afm_runner_status st;
            afm_runner_status_get(x.r, &st);
            long long b = afm_runner_budget(x.r);
            if (b > 0 && b < (1LL << 60)) run_to(&x, st.samples + b);
        }
    }
    afmt_progress_end(&x.pg); /* before the messages; the tail may draw it again */
    long long junk = afm_lcm_log_skipped(in);
    afm_lcm_log_close(&in);
    if (bad[0]) {
        fprintf(stderr, "afmtwin replay: %s: %s (%lld events read before it)\n", x.o.in, bad,
                events);
        lcm_eventlog_destroy(x.log);
        free(x.buf);
        afm_runner_destroy(&x.r);
        return 2;
    }
    if (junk > 0)
        fprintf(stderr, "afmtwin replay: %s: skipped %lld bytes that are no LCM event\n", x.o.in,
                junk);
    if (backwards > 0)
        fprintf(stderr,
                "afmtwin replay: %lld commands carry a time stamp before the first command's; "
                "they applied at once, in log order\n",
                backwards);
    if (!x.o.lockstep) {
        long long tail = llround(x.o.tail_s * rate);
        long long end = last_target + tail;
        if (!x.o.applied) end = (end + x.o.block - 1) / x.o.block * x.o.block;
        run_to(&x, end);
    }
    emit_all(&x, true); /* final status */
    afmt_progress_end(&x.pg);
    afm_runner_status st;
    afm_runner_status_get(x.r, &st);
    lcm_eventlog_destroy(x.log);
    free(x.buf);
    afm_runner_destroy(&x.r);
    if (x.write_failed) {
        fprintf(stderr, "afmtwin replay: writing '%s' failed\n", x.o.out);
        return 1;
    }
    if (!x.o.quiet) {
        double wall = afmt_mono_s() - wall0;
        fprintf(stderr,
                "afmtwin replay: %lld events: %lld commands applied, %lld rejected%s%s%s, %lld "
                "re-sent ticks absorbed, %lld on other channels skipped; model time %.6f s in %.3f "
                "s (%.3gx real time), %lld "
                "output events, %lld blow-ups\n",
                events, x.applied, x.rejected, x.rejected ? " (last: " : "",
                x.rejected ? x.last_reject : "", x.rejected ? ")" : "", x.tick_resends, x.skipped,
                st.t_s, wall, wall > 0 ? st.t_s / wall : 0.0, x.written, st.blowups);
    }
    return 0;
usage_err:
    fprintf(stderr, "afmtwin replay: %s\n", err);
    return 2;
}
