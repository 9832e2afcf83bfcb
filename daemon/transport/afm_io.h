/* SPDX-License-Identifier: MIT */
/* afm_io.h -- the daemon's transport interface: a small vtable, as LCM's providers, so
 * that LCM (afm_lcm_io.c) and later CAN (issue 6) plug in the same way.
 *
 * Inbound, a transport decodes and validates each message (afm_cmd_decode) and hands the
 * daemon either a command (sink->on_cmd) or a rejection with its reason
 * (sink->on_reject); it never touches the twin itself. Outbound, it publishes the records
 * below, which carry plain numbers (no engine handles), each with utime and seq_applied.
 *
 * Threads: `poll` runs on the receive thread only (and calls the sink there); the publish
 * functions run on the publish thread only. A transport must allow these two to run at
 * the same time (LCM does). Nothing here is called from the real-time thread. */
#ifndef AFM_IO_H
#define AFM_IO_H

#include "estimators/afm_chain.h"
#include "runner/afm_cmd.h"
#include "runner/afm_runner.h"

#include <stdint.h>

#define AFM_IO_MAX_BLOCK 2048 /* samples per samples record */
#define AFM_IO_REASON_LEN 256 /* rejection reasons in status */

typedef struct {
    int64_t utime; /* publish time stamp, us (wall clock; model time in replay) */
    int64_t seq_applied;
    int stream;  /* output stream index */
    double t0_s; /* model time of the first sample */
    double rate_hz;
    int decimation;                  /* R: rate_hz = the sample rate / R */
    double passband_hz, stopband_hz; /* the stream's low-pass (afm_chain_block) */
    int n;                           /* 1..AFM_IO_MAX_BLOCK */
    float deflection_m[AFM_IO_MAX_BLOCK];
    float obd_m[AFM_IO_MAX_BLOCK];
    int32_t obd_counts[AFM_IO_MAX_BLOCK]; /* 0 without ADC */
    float force_n[AFM_IO_MAX_BLOCK];
    afm_runner_oppoint op; /* Z and the tones they were made at */
} afm_io_samples;

/* What a harmonics record publishes of a finished afm_chain_period (not its deferred steps:
 * ~2 KB a record in the publisher's queue). */
typedef struct {
    afm_harm_result harm;
    afm_cycle_metrics cycle;
    double lockin_amplitude_m, lockin_phase_deg;
} afm_io_period;

typedef struct {
    int64_t utime;
    int64_t seq_applied;
    double fe_hz;          /* tone 0 frequency when the period ended */
    afm_io_period p;       /* t_s = p.cycle.t_start_s */
    afm_runner_oppoint op; /* Z and the tones of the period */
} afm_io_harmonics;

typedef struct {
    int64_t utime;
    int64_t seq_applied;
    double model_time_s;
    double realtime_factor;
    int64_t overruns;
    double lag_s;
    int64_t received, rejected;
    char last_reject[AFM_IO_REASON_LEN];
    int64_t blowups;
    const char *mode; /* "realtime", "freerun", "lockstep" */
    int running;
    double separation_m, fe_hz, amplitude_m;
    /* Pipeline health (issue 5 follow-up): commands applied by the twin, realtime
     * backlogs dropped (lag beyond the bound), and the output-chain stage: times the
     * integrator found its ring full (chain behind) and how far it trails (s). */
    int64_t applied;
    int64_t resyncs;
    int64_t chain_stalls;
    double chain_lag_s;
    /* CAN input (issue 6): filled by the CAN transport's annotate_status; all zero (and
     * can_state "") when the daemon has no CAN transport. */
    char can_state[AFM_IO_REASON_LEN]; /* "ok", or "<state> ...; holding last commands" */
    int64_t can_frames;                /* data frames received (accepted and rejected) */
    int64_t can_rejected;              /* frames rejected (codec or daemon) */
    int64_t can_errors;                /* error frames and socket errors */
    int64_t can_reconnects;            /* socket re-opened after a loss */
    char can_last_reject[AFM_IO_REASON_LEN];
    int heartbeat_ok; /* 1: heartbeat within can.heartbeat_timeout_s (or not monitored) */
    /* Accounting (issue 13): received = applied + rejected + refused + dropped (+ commands
     * still queued). refused: valid commands the daemon could not take (its command queue
     * full, the twin's refusal); dropped: lost before any handler (LCM's queues, the
     * kernel's socket buffer; the LCM transport's annotate_status fills them). */
    int64_t refused;
    char last_refusal[AFM_IO_REASON_LEN];
    int64_t dropped;
    char last_drop[AFM_IO_REASON_LEN];
    /* Lockstep re-sends: ticks received again with the last tick's seq (never run again;
     * received = applied + rejected + refused + dropped + tick_resends), and the completions
     * published again for them. */
    int64_t tick_resends, republished;
    int auto_paused; /* 1: paused itself after recurring blow-ups (pause_reason) */
    char pause_reason[AFM_IO_REASON_LEN * 2];
    /* Issue 12: what the twin does, and whether it keeps up. */
    double realtime_factor_1s; /* over the last second of running (paused/idle excluded) */
    double resync_skipped_s;   /* model time skipped by resyncs (total) */
    double lockin_amplitude_m; /* the last period's lock-in amplitude and phase LAG behind */
    double lockin_phase_deg;   /* the drive (90 free at resonance), and peak force */
    double peak_force_n;
    double last_reject_age_s; /* wall seconds since last_reject; -1: none */
    int last_reject_old;      /* 1: a command or reload received after it was applied */
    /* Issue 28: the rt integrator's scheme in force ("accurate", "fast"; "" offline), why,
     * hand-overs between them, and the model time each has run since start. */
    char rt_scheme[16];
    char rt_scheme_reason[AFM_IO_REASON_LEN];
    int64_t scheme_handovers;
    double model_s_accurate, model_s_fast;
    /* Issue 32: internal FM control (fm_control and fm_drive "none", fm_lock_state "", NaN
     * without it); fm_drive "pll" or "self", the config's fm.drive. */
    const char *fm_control;
    const char *fm_drive;
    const char *fm_lock_state;
    double fm_frequency_hz, fm_reference_hz, fm_frequency_shift_hz, fm_phase_error_deg;
    double fm_drive_amplitude_m, fm_amplitude_m, fm_amplitude_setpoint_m;
    int64_t fm_tone_changes;
    /* Issue 30: the last period's energy taken by the squeeze film on the beam (J; NaN
     * before the first period), beside peak_force_n, which is the tip-sample force's. */
    double squeeze_dissipated_energy_j;
    /* Issue 18: the sample under the tip (runner's status; 0, "hold", -1 without one). */
    int sample_on;
    double tip_x_m, tip_y_m, true_height_m;
    int material;
    const char *scan_mode; /* "hold", "move", "velocity", "raster" */
    int scan_line, scan_pixel, scan_retrace;
    /* Issue 18: internal AM Z control (am_control "none", NaN without it). */
    const char *am_control;
    double am_z_m, am_error_m, am_setpoint_m, am_amplitude_m;
    /* Issue 30: A0 at the drive in force and A/A0 (NaN while A0 is not known). */
    double free_amplitude_m, amplitude_ratio;
} afm_io_status;

/* Lockstep (and STEP) completion: the tick or step command seq's samples are all run and
 * every output they produced is published (tick_done_t). */
typedef struct {
    int64_t utime;
    int64_t seq;
    int64_t samples;
    double model_time_s;
    int64_t n_samples_msgs, n_harmonics_msgs;  /* published since the previous completion */
    uint64_t samples_digest, harmonics_digest; /* afm_lcm_digest of those messages */
} afm_io_tick_done;

/* What a transport calls on the receive thread. */
typedef struct {
    void *ctx;
    /* A decoded and validated command. Return 0 if taken, -1 with a reason in err if the
     * daemon refuses it (the transport then counts nothing more: the daemon did). */
    int (*on_cmd)(void *ctx, const afm_cmd *c);
    /* A message the transport rejected (malformed, wrong type, invalid values). */
    void (*on_reject)(void *ctx, const char *channel, const char *reason);
    /* Limits for afm_cmd_decode (the running sample rate and model). */
    afm_cmd_limits (*limits)(void *ctx);
    /* Optional: the drive the twin runs after every command taken so far, from any
     * transport (a transport that keeps registers of its own, like CAN's, follows it);
     * returns a number that changes whenever the drive does. */
    unsigned (*drive)(void *ctx, afm_cmd_dither *out);
} afm_io_sink;

typedef struct afm_io afm_io;

typedef struct {
    const char *name;
    /* Wait up to timeout_ms for inbound messages and dispatch them to the sink. 0 ok (also
     * on timeout), -1 on a transport failure. */
    int (*poll)(afm_io *io, int timeout_ms);
    int (*publish_samples)(afm_io *io, const afm_io_samples *s);
    int (*publish_harmonics)(afm_io *io, const afm_io_harmonics *h);
    int (*publish_status)(afm_io *io, const afm_io_status *s);
    void (*destroy)(afm_io *io);
    /* Optional (NULL: none). wait_fd: the descriptor that becomes readable when poll(io, 0)
     * has work (-1: none now, e.g. while reconnecting), and in *max_wait_ms how long the
     * caller may wait before calling poll(io, 0) anyway (-1: no limit) -- for afm_io_mux.
     * Receive thread only. annotate_status: adds the transport's own fields to a status
     * record; any non-real-time thread. */
    int (*wait_fd)(afm_io *io, int *max_wait_ms);
    void (*annotate_status)(afm_io *io, afm_io_status *s);
    /* Optional (NULL: the transport has no outputs): a completion, publish thread only. */
    int (*publish_tick_done)(afm_io *io, const afm_io_tick_done *d);
} afm_io_ops;

struct afm_io {
    const afm_io_ops *ops;
    afm_io_sink sink;
    void *impl;
};

/* LCM transport: two LCM instances, so that the command socket carries commands only
 * (with udpm every member of a group and port receives everything sent to it, the
 * daemon's own output flood included). Commands on url (NULL: LCM's default, i.e.
 * $LCM_DEFAULT_URL or udpm://239.255.76.67:7667?ttl=0), channels prefix + DITHER,
 * SETPOINT, PARAM, CONTROL, TICK, SCAN, every one subscribed raw so that any bytes on it are
 * decoded and judged here; outputs HARMONICS, STATUS, TICK_DONE on out_url (NULL: derived
 * from url by afm_lcm_out_url), SAMPLES on samples_url (NULL: afm_lcm_samples_url), each
 * message numbered per channel (msg_seq). NULL with err. */
afm_io *afm_lcm_io_create(const char *url, const char *out_url, const char *samples_url,
                          const char *prefix, const afm_io_sink *sink, char *err, size_t errlen);

/* CAN transport (afm_can_io.c, issue 6): a SocketCAN raw socket on can->interface with the
 * message map of afm_can_codec.h; dither registers start from drive. Inbound only: the
 * publish functions do nothing, annotate_status fills the can_* fields. The interface
 * need not exist yet (it is retried with backoff). NULL with err (bad map, no memory). */
afm_io *afm_can_io_create(const afm_cfg_can *can, const afm_cfg_drive *drive,
                          const afm_io_sink *sink, char *err, size_t errlen);

/* Several transports as one (afm_io_mux.c): poll waits on all their wait_fd descriptors
 * and polls each; publishing goes to all; annotate_status asks all (the daemon annotates
 * the status record when it fills it), the status is published by all. Takes ownership of
 * io[0..n-1] (destroyed with it, also on failure). n 1..4. */
afm_io *afm_io_mux_create(afm_io *const *io, int n, char *err, size_t errlen);

static inline void afm_io_destroy(afm_io **io) {
    if (io && *io) {
        (*io)->ops->destroy(*io);
        *io = NULL;
    }
}

#endif
