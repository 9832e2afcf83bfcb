/* SPDX-License-Identifier: MIT */
/* cmd_lockstep.c -- `afmtwin lockstep`: the co-simulating controller's side of lockstep mode.
 * Runs a command log against `afmtwind --mode lockstep` over LCM, waiting for each tick's
 * completion (tick_done_t) before the next command, and checks the outputs bit for bit
 * against `afmtwin replay --lockstep` of the same sequence; or (--bench) measures how many
 * ticks a second the pair sustains.
 *
 * The sequence: a log with tick commands is sent as it is; a log without (e.g. one recorded
 * from a real-time run) is turned into one: before each command, ticks (at most --tick-us of
 * model time each) up to the sample count its log time gives, round((t - t_first) x rate),
 * while the twin runs (paused, model time stands still; a step waits for its completion).
 * Completions: every tick and step is waited for (--timeout), and the samples and harmonics
 * messages received since the previous completion must match its counts and digests
 * (afm_lcm_digest): nothing lost. --check then replays the sequence as sent (written to
 * --sequence, or a temporary log) in this process and compares every completion: seq,
 * samples, model time, the samples digest, and the harmonics digest when --harmonics-every
 * gives the daemon's setting (its automatic choice depends on when outputs are taken). */
#define _GNU_SOURCE /* sched_setaffinity, CPU_SET */
#include "afmtwin_cmds.h"
#include "lcm_tool.h"
#include "opts.h"

#include "transport/afm_cmd_lcm.h"
#include "config/afm_config.h"
#include "transport/afm_lcm_encode.h"

#include "afmtwin_tick_t.h"

#include <errno.h>
#include <lcm/eventlog.h>
#include <lcm/lcm.h>
#include <math.h>
#include <sched.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define LS_TICK_SEQ0 1000000000000LL /* seq of the ticks this tool makes: 1e12, 1e12 + 1, ... */
#define LS_MAX_EVENTS 2000000
#ifdef SCHED_RESET_ON_FORK
#define LS_RESET_ON_FORK SCHED_RESET_ON_FORK
#else
#define LS_RESET_ON_FORK 0x40000000 /* Linux's value (sched.h hides it without _GNU_SOURCE) */
#endif

typedef struct {
    int kind; /* afm_cmd_kind */
    int64_t t_us;
    int len;
    uint8_t *data;
} ls_event;

/* longest wait for the samples a completion counts (they come on another socket, read by
 * another LCM thread: late when that thread is not scheduled; 0.5 s was seen to fall short
 * once on a loaded machine, with no datagram dropped by the kernel) */
#define LS_SAMPLES_WAIT_S 2.0
/* A tick whose completion has not come is sent again (same seq: afmtwind runs it if it never
 * got it, or publishes its completion again) after LS_RESEND0_S, then at doubling intervals
 * of at most LS_RESEND_MAX_S, until --timeout. */
#define LS_RESEND0_S 0.2
#define LS_RESEND_MAX_S 1.6

/* Output channels whose msg_seq (per-channel message number) is followed: a gap is that
 * many messages lost on the way (or still to come, out of order). */
enum { LS_CH_SAMPLES, LS_CH_HARMONICS, LS_CH_DONE, LS_N_CH };

typedef struct {
    int64_t seq, samples;
    double t_s;
    uint64_t sd, hd;
    long long h_end; /* harmonics messages received before it (ls_hrec index) */
} ls_done;

/* One harmonics message, as much of it as tells where a completion's digest came from when
 * it differs from replay's (--check prints the first record and field that differ). */
#define LS_HREC_K 4
typedef struct {
    int64_t seq_applied;
    int n;
    double v[13 + 4 * LS_HREC_K]; /* ls_hrec_names order */
} ls_hrec;

static const char *const ls_hrec_names[] = {"t_s",
                                            "fe_hz",
                                            "lockin_amplitude_m",
                                            "lockin_phase_deg",
                                            "peak_force_n",
                                            "min_deflection_m",
                                            "indentation_m",
                                            "contact_time_s",
                                            "pre_contact_velocity_m_s",
                                            "dissipated_energy_j",
                                            "mean_deflection_m",
                                            "squeeze_dissipated_energy_j",
                                            "separation_m",
                                            "deflection_amplitude_m[0]",
                                            "deflection_amplitude_m[1]",
                                            "deflection_amplitude_m[2]",
                                            "deflection_amplitude_m[3]",
                                            "deflection_phase_deg[0]",
                                            "deflection_phase_deg[1]",
                                            "deflection_phase_deg[2]",
                                            "deflection_phase_deg[3]",
                                            "force_amplitude_n[0]",
                                            "force_amplitude_n[1]",
                                            "force_amplitude_n[2]",
                                            "force_amplitude_n[3]",
                                            "force_phase_deg[0]",
                                            "force_phase_deg[1]",
                                            "force_phase_deg[2]",
                                            "force_phase_deg[3]"};

static void ls_hrec_of(const afmtwin_harmonics_t *m, ls_hrec *r) {
    memset(r, 0, sizeof *r);
    r->seq_applied = m->seq_applied;
    r->n = m->n;
    const double head[] = {m->t_s,
                           m->fe_hz,
                           m->lockin_amplitude_m,
                           m->lockin_phase_deg,
                           m->peak_force_n,
                           m->min_deflection_m,
                           m->indentation_m,
                           m->contact_time_s,
                           m->pre_contact_velocity_m_s,
                           m->dissipated_energy_j,
                           m->mean_deflection_m,
                           m->squeeze_dissipated_energy_j,
                           m->separation_m};
    memcpy(r->v, head, sizeof head);
    for (int i = 0; i < m->n && i < LS_HREC_K; i++) {
        r->v[13 + i] = m->deflection_amplitude_m[i];
        r->v[13 + LS_HREC_K + i] = m->deflection_phase_deg[i];
        r->v[13 + 2 * LS_HREC_K + i] = m->force_amplitude_n[i];
        r->v[13 + 3 * LS_HREC_K + i] = m->force_phase_deg[i];
    }
}

typedef struct {
    /* options */
    const char *in, *config, *url, *out_url, *samples_url, *prefix, *sequence, *out;
    double tick_us, tail_s, timeout_s, bench_s, until_s;
    int harmonics_every, rt_priority, cpu;
    bool check, bench, quiet, json;
    /* LCM */
    afmt_lcm lcm; /* commands out; harmonics, status, tick_done in; the samples on their URL */
    afmt_channels ch;
    lcm_eventlog_t *seq_log, *out_log;
    /* what came back */
    bool status_seen; /* the daemon is up */
    afm_lcm_digest dg;
    bool done_seen, done_seen_ever;
    afmtwin_tick_done_t last;
    long long n_samples_msgs, n_harm_msgs, n_dones, mismatched, bad_msgs;
    ls_done *dones;
    long long n_cap;
    ls_hrec *hrecs; /* every harmonics message received (for --check's diagnosis) */
    long long n_hrecs, hrec_cap;
    /* lost, late and re-sent */
    int64_t next_msg_seq[LS_N_CH]; /* the msg_seq expected next (-1: none seen yet) */
    long long msg_gaps[LS_N_CH];   /* messages missing in the msg_seq of each channel */
    long long msg_behind[LS_N_CH]; /* messages that came after a later one */
    uint8_t last_tick[64];         /* the last tick sent, as sent (re-sent as it is) */
    int last_tick_len;
    int64_t last_tick_seq;
    long long resends;      /* ticks sent again */
    long long resent_waits; /* waits that needed a re-send */
    long long dones_again;  /* completions of a seq already completed: ignored */
    int64_t again_seq;      /* the seq of the last of them */
    long long log_resends;  /* ticks in the log with the last tick's seq */
    /* state of the twin as this client drives it */
    int64_t tick_seq;
    long long samples;      /* run by this client so far */
    long long abs_samples;  /* the daemon's count at the last completion (-1: none yet) */
    long long paused_ticks; /* tick budget sent while paused: runs, and completes, after RUN */
    int64_t paused_tick_seq;
    bool running;
    double rate_hz;
    double wall_waiting; /* wall seconds spent waiting for completions */
} ls_ctx;

static void ls_usage(FILE *f) {
    fprintf(
        f,
        "usage: afmtwin lockstep --in LOG [--config FILE] [--tick-us US] [--tail S] [--check]\n"
        "                        [--harmonics-every K] [--sequence LOG] [--out LOG]\n"
        "                        [--lcm-url URL] [--lcm-out-url URL] [--prefix NAME_]\n"
        "                        [--until S] [--timeout S] [--rt-priority N] [--cpu N]\n"
        "                        [--quiet]\n"
        "       afmtwin lockstep --bench S --tick-us US [--json] [LCM options]\n\n"
        "Drives afmtwind --mode lockstep as a co-simulating controller does: each tick is\n"
        "sent, then its completion (PREFIX + TICK_DONE) awaited before anything else goes out;\n"
        "the outputs received in between must match the completion's counts and digests.\n\n"
        "The sequence: a log with tick commands (afmtwin send --log) is sent as it is; a log\n"
        "without ticks (e.g. recorded from a real-time run) is turned into one: before each\n"
        "command, ticks of at most --tick-us up to the sample count of its log time,\n"
        "round((t - t_first) x rate); paused, model time stands still; a step is waited for.\n"
        "Ticks made here have seq 1e12, 1e12 + 1, ...\n\n"
        "Lost or late datagrams: a tick whose completion has not come within 0.2 s is sent\n"
        "again with the SAME seq, then at doubling intervals (at most 1.6 s) until\n"
        "--timeout. afmtwind takes a tick whose seq is that of the last tick it received as\n"
        "such a re-send: it never runs it again (the model does not move), and publishes\n"
        "that tick's completion again if it was already published (it was lost, or is late).\n"
        "A completion that repeats the last one (seq, samples, model time) is ignored here.\n"
        "Re-sends are not written to --sequence (replay --lockstep absorbs a repeated tick\n"
        "too); a tick in the log with the last tick's seq is sent and its completion awaited\n"
        "again. Commands other than ticks are not re-sent. The summary counts re-sends and\n"
        "the messages missing per output channel (gaps in msg_seq).\n\n"
        "options:\n"
        "  --in LOG          the commands (lcm-logger format; channels PREFIX + DITHER,\n"
        "                    SETPOINT, PARAM, CONTROL, TICK, SCAN)\n"
        "  --config FILE     the daemon's config, for its sample rate and for --check\n"
        "                    (default config/default.conf)\n"
        "  --tick-us US      model time per tick made here, 1..1e6 us (default 1000)\n"
        "  --tail S          model seconds ticked after the last command (default 0.01)\n"
        "  --until S         only the commands logged in the first S seconds (after the\n"
        "                    first one), then the tail\n"
        "  --check           replay the sequence as sent (afmtwin replay --lockstep, in this\n"
        "                    process) and compare every completion bit for bit: seq, samples,\n"
        "                    model time, samples digest, and the harmonics digest when\n"
        "                    --harmonics-every is given\n"
        "  --harmonics-every K  the daemon's --harmonics-every (its automatic choice is not\n"
        "                    reproducible: harmonics are then not compared with replay)\n"
        "  --sequence LOG    write the sequence sent (with the ticks) to LOG\n"
        "  --out LOG         write the outputs received to LOG\n"
        "  --lcm-url URL     the daemon's command URL (default: LCM_DEFAULT_URL or LCM's)\n"
        "  --lcm-out-url URL its output URL (default: derived, udpm port + 1)\n"
        "  --lcm-samples-url URL  its samples URL (default: derived, udpm port + 2)\n"
        "  --prefix NAME_    channel prefix (default %s)\n"
        "  --timeout S       longest wait for a completion (default 10)\n"
        "  --rt-priority N   SCHED_FIFO priority of this client when permitted (default 90:\n"
        "                    above the daemon's threads, as a controller on the same host\n"
        "                    must run; 0: normal scheduling)\n"
        "  --cpu N           run on CPU N only (with afmtwind --aux-cpu N: the hand-overs of\n"
        "                    a tick's round trip stay on one core, several times faster than\n"
        "                    a wake-up across cores on a VM)\n"
        "  --bench S         no log: tick for S seconds of wall time, report ticks/s and the\n"
        "                    real-time factor (model over wall time)\n"
        "  --json            (--bench) one JSON object on stdout\n"
        "  --quiet           no summary\n"
        "  --help            this text\n\n"
        "Exit status 0 all completions came and matched, 1 a completion was missing, outputs\n"
        "were lost or differ from replay, LCM failed; 2 bad usage or an unreadable log.\n",
        AFMT_DEFAULT_PREFIX);
}

/* ---- outputs in ------------------------------------------------------------------------ */

static void log_out(ls_ctx *c, const lcm_recv_buf_t *rb, const char *channel) {
    if (!c->out_log) return;
    afmt_log_write(c->out_log, rb->recv_utime, channel, rb->data, (int)rb->data_size);
}

/* msg_seq of a message on channel ch: a jump forward is messages missing, one behind came
 * late (after a later one). */
static void follow_msg_seq(ls_ctx *c, int ch, int64_t msg_seq) {
    int64_t *next = &c->next_msg_seq[ch];
    if (*next >= 0 && msg_seq > *next) c->msg_gaps[ch] += msg_seq - *next;
    if (*next >= 0 && msg_seq < *next) {
        c->msg_behind[ch]++;
        return;
    }
    *next = msg_seq + 1;
}

static void on_samples(const lcm_recv_buf_t *rb, const char *channel, void *user) {
    ls_ctx *c = user;
    afmtwin_samples_t m;
    if (afmtwin_samples_t_decode(rb->data, 0, (int)rb->data_size, &m) < 0) {
        c->bad_msgs++;
        return;
    }
    follow_msg_seq(c, LS_CH_SAMPLES, m.msg_seq);
    afm_lcm_digest_samples(&c->dg, &m);
    c->n_samples_msgs++;
    afmtwin_samples_t_decode_cleanup(&m);
    log_out(c, rb, channel);
}

static void on_harmonics(const lcm_recv_buf_t *rb, const char *channel, void *user) {
    ls_ctx *c = user;
    afmtwin_harmonics_t m;
    if (afmtwin_harmonics_t_decode(rb->data, 0, (int)rb->data_size, &m) < 0) {
        c->bad_msgs++;
        return;
    }
    follow_msg_seq(c, LS_CH_HARMONICS, m.msg_seq);
    afm_lcm_digest_harmonics(&c->dg, &m);
    c->n_harm_msgs++;
    if (c->hrecs && c->n_hrecs == c->hrec_cap) { /* grown; the diagnosis only: lose it */
        ls_hrec *g = realloc(c->hrecs, (size_t)(2 * c->hrec_cap) * sizeof *g);
        if (g) c->hrecs = g;
        if (g) c->hrec_cap *= 2;
    }
    if (c->hrecs && c->n_hrecs < c->hrec_cap) ls_hrec_of(&m, &c->hrecs[c->n_hrecs++]);
    afmtwin_harmonics_t_decode_cleanup(&m);
    log_out(c, rb, channel);
}

static void on_status(const lcm_recv_buf_t *rb, const char *channel, void *user) {
    (void)rb;
    (void)channel;
    ((ls_ctx *)user)->status_seen = true;
}

/* A completion: what came since the previous one must be what it says was published. One
 * that names the last completion's seq, samples and model time again is that completion
 * again (published again for a re-sent tick, after the first came late): counted, ignored. */
static void on_done(const lcm_recv_buf_t *rb, const char *channel, void *user) {
    ls_ctx *c = user;
    afmtwin_tick_done_t m;
    if (afmtwin_tick_done_t_decode(rb->data, 0, (int)rb->data_size, &m) < 0) {
        c->bad_msgs++;
        return;
    }
    follow_msg_seq(c, LS_CH_DONE, m.msg_seq);
    if (c->n_dones > 0 && m.seq == c->last.seq && m.samples == c->last.samples &&
        m.model_time_s == c->last.model_time_s) {
        c->dones_again++;
        c->again_seq = m.seq;
        return;
    }
    /* The samples come on their own socket: those published before this completion may
     * still be on their way (LCM's receive threads); wait for them, bounded. */
    for (double t0 = afmt_mono_s(); c->lcm.samples != c->lcm.out &&
                                    c->dg.n_samples_msgs < m.n_samples_msgs &&
                                    afmt_mono_s() - t0 < LS_SAMPLES_WAIT_S;)
        if (lcm_handle_timeout(c->lcm.samples, 10) < 0) break;
    uint64_t sd = afm_lcm_digest_samples_final(&c->dg), hd = c->dg.harmonics;
    if (m.n_samples_msgs != c->dg.n_samples_msgs || m.n_harmonics_msgs != c->dg.n_harmonics_msgs ||
        (uint64_t)m.samples_digest != sd || (uint64_t)m.harmonics_digest != hd) {
        if (c->mismatched++ < 5)
            fprintf(stderr,
                    "afmtwin lockstep: completion seq %lld: the daemon published %lld samples "
                    "and %lld harmonics messages, %lld and %lld arrived (digests %s; missing by "
                    "msg_seq so far: %lld samples, %lld harmonics messages)\n",
                    (long long)m.seq, (long long)m.n_samples_msgs, (long long)m.n_harmonics_msgs,
                    (long long)c->dg.n_samples_msgs, (long long)c->dg.n_harmonics_msgs,
                    (uint64_t)m.samples_digest == sd && (uint64_t)m.harmonics_digest == hd
                        ? "equal"
                        : "differ",
                    c->msg_gaps[LS_CH_SAMPLES], c->msg_gaps[LS_CH_HARMONICS]);
    }
    afm_lcm_digest_init(&c->dg);
    if (c->n_dones < c->n_cap)
        c->dones[c->n_dones] = (ls_done){m.seq,
                                         m.samples,
                                         m.model_time_s,
                                         (uint64_t)m.samples_digest,
                                         (uint64_t)m.harmonics_digest,
                                         c->n_hrecs};
    c->n_dones++;
    c->last = m;
    c->done_seen = c->done_seen_ever = true;
    log_out(c, rb, channel);
}

/* ---- commands out ---------------------------------------------------------------------- */

static void seq_log_write(ls_ctx *c, const char *channel, const void *data, int len) {
    if (!c->seq_log) return;
    afmt_log_write(c->seq_log, llround((double)c->samples / c->rate_hz * 1e6), channel, data, len);
}

/* Send a command (and write it to the sequence); a tick is kept, with its seq, for re-sends. */
static int publish(ls_ctx *c, int kind, const void *data, int len) {
    seq_log_write(c, c->ch.cmd[kind], data, len);
    if (kind == AFM_CMD_TICK && len <= (int)sizeof c->last_tick) {
        afmtwin_tick_t t;
        if (afmtwin_tick_t_decode(data, 0, len, &t) >= 0) {
            memcpy(c->last_tick, data, (size_t)len);
            c->last_tick_len = len;
            c->last_tick_seq = t.seq;
        }
    }
    return lcm_publish(c->lcm.cmd, c->ch.cmd[kind], data, (unsigned)len) < 0 ? -1 : 0;
}

/* The last tick once more, as it was sent (not into the sequence: the twin runs it once). */
static void resend_tick(ls_ctx *c) {
    if (lcm_publish(c->lcm.cmd, c->ch.cmd[AFM_CMD_TICK], c->last_tick,
                    (unsigned)c->last_tick_len) == 0)
        c->resends++;
}

/* Wait for a completion of seq: a new one, or (again) that completion published again for a
 * re-sent tick. While seq is the last tick sent, the tick is re-sent after LS_RESEND0_S, then
 * at doubling intervals (a lost tick then runs; a lost completion comes again). 0, or -1 on
 * timeout or LCM failure. */
static int await_done(ls_ctx *c, int64_t seq, bool again) {
    double t0 = afmt_mono_s(), gap = LS_RESEND0_S, next = t0 + gap;
    long long again0 = c->dones_again;
    bool resent = false;
    for (;;) {
        if (!again && c->done_seen && c->last.seq == seq) break;
        if (again && c->dones_again > again0 && c->again_seq == seq) break;
        double now = afmt_mono_s(), left = c->timeout_s - (now - t0);
        if (left <= 0) {
            fprintf(stderr,
                    "afmtwin lockstep: no completion of seq %lld within %g s%s (is afmtwind "
                    "running in lockstep mode on these URLs, with this prefix?)\n",
                    (long long)seq, c->timeout_s, resent ? ", the tick re-sent" : "");
            return -1;
        }
        bool may_resend = c->last_tick_len > 0 && c->last_tick_seq == seq;
        if (may_resend && now >= next) {
            resend_tick(c);
            resent = true;
            gap = fmin(2 * gap, LS_RESEND_MAX_S);
            next = now + gap;
        }
        double wait_s = fmin(left, may_resend ? next - now : 0.2);
        if (afmt_lcm_handle(&c->lcm, (int)ceil(fmax(wait_s, 1e-3) * 1e3)) < 0) return -1;
    }
    c->resent_waits += resent;
    c->wall_waiting += afmt_mono_s() - t0;
    return 0;
}

/* Wait for the completion of seq (the last one sent), which runs n samples. 0, or -1 on
 * timeout. */
static int wait_done(ls_ctx *c, int64_t seq, long long n) {
    if (await_done(c, seq, false)) return -1;
    c->done_seen = false;
    if (c->abs_samples >= 0 && c->last.samples != c->abs_samples + n) {
        fprintf(stderr, "afmtwin lockstep: completion of seq %lld at %lld samples, expected %lld\n",
                (long long)seq, (long long)c->last.samples, c->abs_samples + n);
        c->mismatched++;
    }
    c->abs_samples = c->last.samples;
    c->samples += n;
    return 0;
}

static int tick(ls_ctx *c, long long n) {
    afmtwin_tick_t t = {.utime = afmt_wall_us(), .seq = c->tick_seq++, .n_samples = n};
    int len = afmtwin_tick_t_encoded_size(&t);
    uint8_t buf[64];
    if (len > (int)sizeof buf || afmtwin_tick_t_encode(buf, 0, len, &t) < 0) return -1;
    if (publish(c, AFM_CMD_TICK, buf, len)) return -1;
    return wait_done(c, t.seq, n);
}

/* Tick while running until `target` samples (in pieces of --tick-us). */
static int tick_to(ls_ctx *c, long long target) {
    long long piece = llround(c->tick_us * 1e-6 * c->rate_hz);
    if (piece < 1) piece = 1;
    while (c->running && c->samples < target) {
        long long n = target - c->samples < piece ? target - c->samples : piece;
        if (tick(c, n)) return -1;
    }
    return 0;
}

/* One command of the log: sent raw; its effect on running / budgets followed here. */
static int send_event(ls_ctx *c, const ls_event *e) {
    afm_cmd cmd;
    char err[AFM_ERR_LEN];
    afm_cmd_limits lim = {.sample_rate_hz = c->rate_hz};
    bool ok = afm_cmd_decode((afm_cmd_kind)e->kind, e->data, (size_t)e->len, &lim, &cmd, err,
                             sizeof err) == 0;
    /* a tick with the last tick's seq: a re-send (afmtwind runs it once); once that tick
     * has completed, its completion comes again */
    bool resend =
        ok && cmd.kind == AFM_CMD_TICK && c->last_tick_len > 0 && cmd.seq == c->last_tick_seq;
    if (publish(c, e->kind, e->data, e->len)) return -1;
    if (!ok) return 0; /* the daemon rejects it too */
    if (resend) {
        c->log_resends++;
        return c->done_seen_ever && c->last.seq == cmd.seq ? await_done(c, cmd.seq, true) : 0;
    }
    if (cmd.kind == AFM_CMD_CONTROL) {
        switch (cmd.u.control.action) {
        case AFM_CTL_RUN:
            c->running = true;
            if (c->paused_ticks > 0) { /* the ticks sent while paused run now */
                long long n = c->paused_ticks;
                c->paused_ticks = 0;
                return wait_done(c, c->paused_tick_seq, n);
            }
            break;
        case AFM_CTL_PAUSE:
            c->running = false;
            break;
        case AFM_CTL_STEP:
            c->running = false;
            return wait_done(c, cmd.seq, cmd.u.control.n_samples);
        case AFM_CTL_RESET:
            break;
        }
    } else if (cmd.kind == AFM_CMD_TICK && c->running) {
        return wait_done(c, cmd.seq, cmd.u.tick.n_samples);
    } else if (cmd.kind == AFM_CMD_TICK) { /* paused: the budget waits for RUN */
        c->paused_ticks += cmd.u.tick.n_samples;
        c->paused_tick_seq = cmd.seq;
    }
    return 0;
}

/* ---- the log --------------------------------------------------------------------------- */

static int read_log(ls_ctx *c, ls_event **evs, long long *n, bool *has_ticks) {
    lcm_eventlog_t *l = lcm_eventlog_create(c->in, "r");
    if (!l) {
        fprintf(stderr, "afmtwin lockstep: cannot read log '%s'\n", c->in);
        return -1;
    }
    long long cap = 1024;
    *evs = malloc((size_t)cap * sizeof **evs);
    *n = 0;
    *has_ticks = false;
    lcm_eventlog_event_t *ev;
    while (*evs && *n < LS_MAX_EVENTS && (ev = lcm_eventlog_read_next_event(l)) != NULL) {
        int kind = afmt_channels_kind(&c->ch, ev->channel);
        if (kind) {
            if (*n == cap) {
                ls_event *g = realloc(*evs, (size_t)(cap *= 2) * sizeof **evs);
                if (!g) break;
                *evs = g;
            }
            ls_event *e = &(*evs)[(*n)++];
            e->kind = kind;
            e->t_us = ev->timestamp;
            e->len = ev->datalen;
            e->data = malloc((size_t)(ev->datalen > 0 ? ev->datalen : 1));
            if (e->data) memcpy(e->data, ev->data, (size_t)ev->datalen);
            *has_ticks |= kind == AFM_CMD_TICK;
        }
        lcm_eventlog_free_event(ev);
    }
    lcm_eventlog_destroy(l);
    return *evs ? 0 : -1;
}

/* ---- --check: the same sequence through replay ----------------------------------------- */

/* Completion i differs: the first of its harmonics records that differs from replay's (rep,
 * n_rep of them), field by field; or the counts. */
static void explain_harmonics(const ls_ctx *c, long long i, const ls_hrec *rep, long long n_rep) {
    long long h0 = i > 0 ? c->dones[i - 1].h_end : 0, h1 = c->dones[i].h_end;
    if (h1 > c->n_hrecs || h1 - h0 < 0) return; /* records beyond the kept ones */
    if (h1 - h0 != n_rep)
        fprintf(stderr, "afmtwin lockstep:   its harmonics messages: daemon %lld, replay %lld\n",
                h1 - h0, n_rep);
    for (long long j = 0; j < n_rep && j < h1 - h0; j++) {
        const ls_hrec *a = &c->hrecs[h0 + j], *b = &rep[j];
        bool shown = false;
        if (a->seq_applied != b->seq_applied || a->n != b->n) {
            fprintf(stderr,
                    "afmtwin lockstep:   harmonics message %lld of it: seq_applied %lld/%lld, n "
                    "%d/%d\n",
                    j, (long long)a->seq_applied, (long long)b->seq_applied, a->n, b->n);
            shown = true;
        }
        for (size_t f = 0; f < sizeof a->v / sizeof a->v[0]; f++) {
            if (memcmp(&a->v[f], &b->v[f], sizeof a->v[f]) == 0) continue;
            fprintf(stderr,
                    "afmtwin lockstep:   harmonics message %lld of it (t_s %.9f): %s daemon "
                    "%.17g, replay %.17g\n",
                    j, a->v[0], ls_hrec_names[f], a->v[f], b->v[f]);
            shown = true;
        }
        if (shown) return; /* the first that differs */
    }
}

static int check_with_replay(ls_ctx *c, const char *seq_path) {
    char out[] = "/tmp/afmtwin-lockstep-replay.XXXXXX";
    int fd = mkstemp(out);
    if (fd < 0) return -1;
    close(fd);
    char k[32];
    snprintf(k, sizeof k, "%d", c->harmonics_every > 0 ? c->harmonics_every : 1);
    char *argv[] = {"replay",
                    "--config",
                    (char *)c->config,
                    "--in",
                    (char *)seq_path,
                    "--out",
                    out,
                    "--lockstep",
                    "--prefix",
                    (char *)c->prefix,
                    "--channels",
                    "tick_done,harmonics",
                    "--harmonics-every",
                    k,
                    "--quiet",
                    NULL};
    int rc = afm_cmd_replay((int)(sizeof argv / sizeof argv[0]) - 1, argv);
    if (rc != 0) {
        fprintf(stderr, "afmtwin lockstep: replay of the sequence failed (%d)\n", rc);
        unlink(out);
        return -1;
    }
    lcm_eventlog_t *l = lcm_eventlog_create(out, "r");
    long long i = 0, diff = 0, n_rep = 0, rep_cap = 4096;
    ls_hrec *rep = malloc((size_t)rep_cap * sizeof *rep); /* replay's, since the last completion */
    lcm_eventlog_event_t *ev;
    while (l && (ev = lcm_eventlog_read_next_event(l)) != NULL) {
        afmtwin_tick_done_t m;
        afmtwin_harmonics_t h;
        if (!strcmp(ev->channel, c->ch.out[AFMT_OUT_HARMONICS]) &&
            afmtwin_harmonics_t_decode(ev->data, 0, ev->datalen, &h) >= 0) {
            if (rep && n_rep < rep_cap) ls_hrec_of(&h, &rep[n_rep++]);
            afmtwin_harmonics_t_decode_cleanup(&h);
        } else if (!strcmp(ev->channel, c->ch.out[AFMT_OUT_TICK_DONE]) &&
                   afmtwin_tick_done_t_decode(ev->data, 0, ev->datalen, &m) >= 0) {
            if (i < c->n_dones && i < c->n_cap) {
                const ls_done *d = &c->dones[i];
                bool same = d->seq == m.seq && d->samples == m.samples &&
                            d->t_s == m.model_time_s && d->sd == (uint64_t)m.samples_digest &&
                            (c->harmonics_every <= 0 || d->hd == (uint64_t)m.harmonics_digest);
                if (!same && diff++ < 5) {
                    fprintf(stderr,
                            "afmtwin lockstep: completion %lld differs from replay: seq %lld/%lld "
                            "samples %lld/%lld t %.9f/%.9f digests %016llx/%016llx "
                            "%016llx/%016llx\n",
                            i, (long long)d->seq, (long long)m.seq, (long long)d->samples,
                            (long long)m.samples, d->t_s, m.model_time_s, (unsigned long long)d->sd,
                            (unsigned long long)m.samples_digest, (unsigned long long)d->hd,
                            (unsigned long long)m.harmonics_digest);
                    if (c->harmonics_every > 0 && d->hd != (uint64_t)m.harmonics_digest && rep)
                        explain_harmonics(c, i, rep, n_rep);
                }
            }
            i++;
            n_rep = 0;
            afmtwin_tick_done_t_decode_cleanup(&m);
        }
        lcm_eventlog_free_event(ev);
    }
    free(rep);
    if (l) lcm_eventlog_destroy(l);
    unlink(out);
    if (i != c->n_dones) {
        fprintf(stderr, "afmtwin lockstep: replay completed %lld times, the daemon %lld\n", i,
                c->n_dones);
        diff++;
    }
    if (c->abs_samples != c->samples)
        fprintf(stderr,
                "afmtwin lockstep: the daemon had run %lld samples before this client: "
                "start it fresh for --check (replay starts at 0)\n",
                c->abs_samples - c->samples);
    if (!c->quiet)
        printf("afmtwin lockstep: vs afmtwin replay --lockstep of the same sequence: %lld of %lld "
               "completions identical (seq, samples, model time, samples digest%s)\n",
               i - diff > 0 ? i - diff : 0, c->n_dones,
               c->harmonics_every > 0 ? ", harmonics digest" : "; harmonics not compared");
    return diff ? -1 : 0;
}

/* ---- driver ---------------------------------------------------------------------------- */

/* What was lost, late or sent again (after the summary; the daemon's status has its side:
 * tick_resends, republished, dropped). */
static void print_resends(const ls_ctx *c) {
    printf("afmtwin lockstep: %lld ticks re-sent (%lld waits needed it), %lld completions came "
           "again (ignored), %lld re-sent ticks in the log; messages missing by msg_seq: "
           "samples %lld, harmonics %lld, completions %lld; after a later one: %lld, %lld, "
           "%lld\n",
           c->resends, c->resent_waits, c->dones_again, c->log_resends, c->msg_gaps[LS_CH_SAMPLES],
           c->msg_gaps[LS_CH_HARMONICS], c->msg_gaps[LS_CH_DONE], c->msg_behind[LS_CH_SAMPLES],
           c->msg_behind[LS_CH_HARMONICS], c->msg_behind[LS_CH_DONE]);
}

/* --bench S: the benchmark mode, for S seconds. */
static int parse_bench(const char *v, void *dest) {
    ls_ctx *c = dest;
    double d;
    if (afmt_parse_double(v, &d) || !(d > 0 && d <= 3600)) return -1;
    c->bench = true;
    c->bench_s = d;
    return 0;
}

static int parse_opts(ls_ctx *c, int argc, char **argv) {
    const afmt_opt opts[] = {
        AFMT_FLAG("--check", &c->check),
        AFMT_FLAG("--quiet", &c->quiet),
        AFMT_FLAG("--json", &c->json),
        AFMT_STRING("--in", &c->in),
        AFMT_STRING("--config", &c->config),
        AFMT_STRING("--sequence", &c->sequence),
        AFMT_STRING("--out", &c->out),
        AFMT_LCM_OPTS(&c->url, &c->out_url, &c->samples_url, &c->prefix),
        AFMT_DOUBLE("--tick-us", &c->tick_us, 1, 1e6, "1..1e6 us"),
        AFMT_DOUBLE("--tail", &c->tail_s, 0, 1e4, "seconds in 0..1e4"),
        AFMT_DOUBLE_ABOVE("--timeout", &c->timeout_s, 0, 1e4, "seconds in (0, 1e4]"),
        AFMT_INT("--cpu", &c->cpu, 0, 1023, "a CPU number in 0..1023"),
        AFMT_DOUBLE_ABOVE("--until", &c->until_s, 0, 1e6, "model seconds in (0, 1e6]"),
        AFMT_FN("--bench", parse_bench, c, "seconds in (0, 3600]"),
        AFMT_INT("--harmonics-every", &c->harmonics_every, 1, 1e9, "an integer >= 1"),
        AFMT_INT("--rt-priority", &c->rt_priority, 0, 99, "a SCHED_FIFO priority in 0..99"),
        AFMT_OPTS_END,
    };
    int rc = afmt_opts_parse("lockstep", opts, argc, argv, 1);
    if (rc == AFMT_OPTS_HELP) ls_usage(stdout);
    if (rc) return rc;
    if (!c->bench && !c->in) {
        fprintf(stderr, "afmtwin lockstep: --in LOG (or --bench S) is required (see --help)\n");
        return 2;
    }
    return 0;
}

static int open_lcm(ls_ctx *c, char *err, size_t errlen) {
    if (afmt_channels_init(&c->ch, c->prefix, err, errlen)) return 2;
    /* Above the daemon's SCHED_FIFO threads and on --cpu (before lcm_create: LCM's own thread
     * inherits both; the priority is not passed on to children). */
    if (c->cpu >= 0) {
        cpu_set_t set;
        CPU_ZERO(&set);
        CPU_SET(c->cpu, &set);
        if (sched_setaffinity(0, sizeof set, &set) != 0 && !c->quiet)
            fprintf(stderr, "afmtwin lockstep: cannot pin to CPU %d (%s)\n", c->cpu,
                    strerror(errno));
    }
    if (c->rt_priority > 0) {
        struct sched_param p = {.sched_priority = c->rt_priority};
        if (sched_setscheduler(0, SCHED_FIFO | LS_RESET_ON_FORK, &p) != 0 && !c->quiet)
            fprintf(stderr,
                    "afmtwin lockstep: SCHED_FIFO %d refused (%s): running at normal "
                    "priority\n",
                    c->rt_priority, strerror(errno));
    }
    int orc = afmt_lcm_open(&c->lcm, c->url, c->out_url, c->samples_url,
                            AFMT_OPEN_CMD | AFMT_OPEN_SAMPLES, err, errlen);
    if (orc) return orc == -1 ? 2 : 1;
    lcm_subscription_t *s[4] = {
        lcm_subscribe(c->lcm.samples, c->ch.out[AFMT_OUT_SAMPLES], on_samples, c),
        lcm_subscribe(c->lcm.out, c->ch.out[AFMT_OUT_HARMONICS], on_harmonics, c),
        lcm_subscribe(c->lcm.out, c->ch.out[AFMT_OUT_TICK_DONE], on_done, c),
        lcm_subscribe(c->lcm.out, c->ch.out[AFMT_OUT_STATUS], on_status, c)};
    for (int i = 0; i < 4; i++) {
        if (!s[i]) {
            snprintf(err, errlen, "cannot subscribe to the outputs");
            return 1;
        }
        lcm_subscription_set_queue_capacity(s[i], 100000);
    }
    /* the daemon is up when its status (10 Hz) arrives: nothing is sent before */
    double t0 = afmt_mono_s();
    while (!c->status_seen && afmt_mono_s() - t0 < c->timeout_s)
        afmt_lcm_handle(&c->lcm, 100);
    if (!c->status_seen) {
        snprintf(err, errlen,
                 "no status from the daemon within %g s (is afmtwind running on "
                 "these URLs, with this prefix?)",
                 c->timeout_s);
        return 1;
    }
    return 0;
}

static int run_bench(ls_ctx *c) {
    long long piece = llround(c->tick_us * 1e-6 * c->rate_hz);
    if (piece < 1) piece = 1;
    /* the daemon's current sample count: one tick, then count from its completion */
    if (tick(c, piece)) return 1;
    long long s0 = c->samples, ticks = 0;
    double t0 = afmt_mono_s();
    while (afmt_mono_s() - t0 < c->bench_s) {
        if (tick(c, piece)) return 1;
        ticks++;
    }
    double wall = afmt_mono_s() - t0, model = (double)(c->samples - s0) / c->rate_hz;
    if (c->json)
        printf("{\"tick_us\":%.6g,\"tick_samples\":%lld,\"ticks\":%lld,\"wall_s\":%.6g,"
               "\"ticks_per_s\":%.6g,\"realtime_factor\":%.6g,\"mismatched\":%lld}\n",
               c->tick_us, piece, ticks, wall, ticks / wall, model / wall, c->mismatched);
    else
        printf("  lockstep ticks of %g us (%lld samples): %lld ticks in %.2f s = %.0f ticks/s, "
               "%.3f x real time; completions matched their outputs: %s\n",
               c->tick_us, piece, ticks, wall, ticks / wall, model / wall,
               c->mismatched ? "NO" : "all");
    return c->mismatched ? 1 : 0;
}

int afm_cmd_lockstep(int argc, char **argv) {
    static ls_ctx c;
    memset(&c, 0, sizeof c);
    c.config = "config/default.conf";
    c.prefix = AFMT_DEFAULT_PREFIX;
    c.tick_us = 1000;
    c.tail_s = 0.01;
    c.timeout_s = 10;
    c.rt_priority = 90;
    c.cpu = -1;
    c.tick_seq = LS_TICK_SEQ0;
    c.running = true;
    c.abs_samples = -1;
    for (int i = 0; i < LS_N_CH; i++)
        c.next_msg_seq[i] = -1;
    int rc = parse_opts(&c, argc, argv);
    if (rc) return rc == 1 ? 0 : rc;
    static afm_config cfg;
    char err[AFM_ERR_LEN];
    if (afmt_config_load("lockstep", c.config, &cfg)) return 2;
    c.rate_hz = cfg.sim.sample_rate_hz;
    afm_lcm_digest_init(&c.dg);
    c.n_cap = 1000000;
    c.dones = malloc((size_t)c.n_cap * sizeof *c.dones);
    if (!c.dones) return 1;
    if (c.check) { /* --check's diagnosis of a differing completion (~250 B a message) */
        c.hrec_cap = 65536;
        c.hrecs = malloc((size_t)c.hrec_cap * sizeof *c.hrecs);
        if (!c.hrecs) c.hrec_cap = 0;
    }
    rc = open_lcm(&c, err, sizeof err);
    if (rc) {
        fprintf(stderr, "afmtwin lockstep: %s\n", err);
        goto out;
    }
    if (c.bench) {
        rc = run_bench(&c);
        goto out;
    }
    ls_event *evs = NULL;
    long long n = 0;
    bool has_ticks;
    if (read_log(&c, &evs, &n, &has_ticks)) {
        rc = 2;
        goto out;
    }
    char seq_tmp[] = "/tmp/afmtwin-lockstep-seq.XXXXXX";
    const char *seq_path = c.sequence;
    if (!seq_path && c.check) {
        int fd = mkstemp(seq_tmp);
        if (fd >= 0) close(fd);
        seq_path = seq_tmp;
    }
    if (seq_path) c.seq_log = lcm_eventlog_create(seq_path, "w");
    if (c.out) c.out_log = lcm_eventlog_create(c.out, "w");
    double w0 = afmt_mono_s();
    int64_t t_first = n > 0 ? evs[0].t_us : 0;
    if (c.until_s > 0 && !has_ticks) /* the commands of the first until_s seconds */
        for (long long i = 0; i < n; i++)
            if ((double)(evs[i].t_us - t_first) > c.until_s * 1e6) {
                for (long long j = i; j < n; j++)
                    free(evs[j].data);
                n = i;
                break;
            }
    rc = 0;
    for (long long i = 0; i < n && rc == 0; i++) {
        if (!has_ticks) {
            double dt_us = (double)(evs[i].t_us - t_first);
            rc = tick_to(&c, dt_us > 0 ? llround(dt_us * 1e-6 * c.rate_hz) : 0);
        }
        if (rc == 0) rc = send_event(&c, &evs[i]);
    }
    if (rc == 0 && !has_ticks && n > 0) {
        double end_us = (double)(evs[n - 1].t_us - t_first) + c.tail_s * 1e6;
        rc = tick_to(&c, llround(end_us * 1e-6 * c.rate_hz));
    }
    double wall = afmt_mono_s() - w0;
    if (c.seq_log) lcm_eventlog_destroy(c.seq_log);
    if (c.out_log) lcm_eventlog_destroy(c.out_log);
    c.seq_log = c.out_log = NULL;
    for (long long i = 0; i < n; i++)
        free(evs[i].data);
    free(evs);
    if (!c.quiet)
        printf("afmtwin lockstep: %lld commands%s, %lld completions, model time %.6f s in %.3f s "
               "(%.3g x real time, %.0f%% of it waiting for completions); %lld samples and %lld "
               "harmonics messages, %s\n",
               n, has_ticks ? " (ticks as logged)" : " (ticks made from log times)", c.n_dones,
               (double)c.samples / c.rate_hz, wall, wall > 0 ? c.samples / c.rate_hz / wall : 0,
               wall > 0 ? 100 * c.wall_waiting / wall : 0, c.n_samples_msgs, c.n_harm_msgs,
               c.mismatched || c.bad_msgs ? "SOME NOT MATCHING their completions"
                                          : "all matching their completions");
    if (!c.quiet) print_resends(&c);
    if (rc == 0 && (c.mismatched || c.bad_msgs)) rc = 1;
    if (rc == 0 && c.check && check_with_replay(&c, seq_path)) rc = 1;
    if (seq_path == seq_tmp) unlink(seq_tmp);
out:
    afmt_lcm_close(&c.lcm);
    free(c.dones);
    free(c.hrecs);
    return rc < 0 ? 1 : rc;
}
