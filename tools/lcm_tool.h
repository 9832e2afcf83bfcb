/* SPDX-License-Identifier: MIT */
/* lcm_tool.h -- the LCM plumbing of `afmtwin`'s subcommands (send, listen, replay, lockstep,
 * soak, flood, bench-daemon) in one place: the daemon's channel names for a prefix, the
 * --channels lists, its LCM instances (commands, outputs, the sample stream) opened at once
 * and read together, encoding a generated message, writing an event to a log, checked
 * subscriptions, wall and monotonic clocks; plus the strict number and hex parsing of their
 * options. */
#ifndef AFMT_LCM_TOOL_H
#define AFMT_LCM_TOOL_H

#include "afmtwin_lcm_layout.h"
#include "runner/afm_cmd.h"
#include "transport/afm_lcm_wire.h"

#include <lcm/eventlog.h>
#include <lcm/lcm.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define AFMT_CHAN_LEN 128

/* Channel names: PREFIX + suffix (afmtwin_lcm_layout.h; afmtwind --prefix overrides). */
#define AFMT_DEFAULT_PREFIX AFMTWIN_DEFAULT_PREFIX
#define AFMT_CHAN_DITHER AFMTWIN_CHAN_DITHER
#define AFMT_CHAN_SETPOINT AFMTWIN_CHAN_SETPOINT
#define AFMT_CHAN_PARAM AFMTWIN_CHAN_PARAM
#define AFMT_CHAN_CONTROL AFMTWIN_CHAN_CONTROL
#define AFMT_CHAN_TICK AFMTWIN_CHAN_TICK
#define AFMT_CHAN_SCAN AFMTWIN_CHAN_SCAN
#define AFMT_CHAN_SAMPLES AFMTWIN_CHAN_SAMPLES
#define AFMT_CHAN_HARMONICS AFMTWIN_CHAN_HARMONICS
#define AFMT_CHAN_STATUS AFMTWIN_CHAN_STATUS
#define AFMT_CHAN_TICK_DONE AFMTWIN_CHAN_TICK_DONE

/* PREFIX + SUFFIX into out (AFMT_CHAN_LEN). The prefix: 1..63 characters of [A-Za-z0-9_]
 * (LCM channel names are matched as regular expressions by subscribers, so nothing else is
 * safe). 0, or -1 with err. */
int afmt_channel(const char *prefix, const char *suffix, char *out, char *err, size_t errlen);

/* The daemon's outputs, in the order of --channels lists and of afmt_channels.out. */
enum { AFMT_OUT_SAMPLES, AFMT_OUT_HARMONICS, AFMT_OUT_STATUS, AFMT_OUT_TICK_DONE, AFMT_N_OUT };
/* Their names in --channels lists: "samples", "harmonics", "status", "tick_done". */
extern const char *const afmt_out_names[AFMT_N_OUT];

/* Every channel of a twin with one prefix: cmd[k] for command kind k (AFM_CMD_DITHER ..
 * AFM_CMD_TICK and AFM_CMD_SCAN; cmd[0] is the bare prefix, cmd[AFM_CMD_RELOAD] "": no
 * message), out[AFMT_OUT_*] for the outputs. */
typedef struct {
    char cmd[AFM_CMD_SCAN + 1][AFMT_CHAN_LEN];
    char out[AFMT_N_OUT][AFMT_CHAN_LEN];
} afmt_channels;
/* All names for prefix (afmt_channel's rules). 0, or -1 with err. */
int afmt_channels_init(afmt_channels *c, const char *prefix, char *err, size_t errlen);
/* The command kind whose channel is name in c, or 0 (not a command channel). */
afm_cmd_kind afmt_channels_kind(const afmt_channels *c, const char *name);

/* A --channels LIST of outputs (afmt_out_names, "all" for every one when all_ok) into
 * want[AFMT_N_OUT]. 0, or -1 (an unknown or empty item). */
int afmt_parse_outputs(const char *s, bool all_ok, bool *want);

/* The daemon's LCM instances as a client uses them, for --lcm-url URL, --lcm-out-url
 * OUT_URL and --lcm-samples-url SAMPLES_URL (each may be NULL: derived as the daemon does,
 * afm_lcm_urls and afm_lcm_samples_urls: udpm port + 1 and + 2): out on the output URL
 * (harmonics, status, tick_done), samples on the sample stream's (its own instance for udpm,
 * the same as out otherwise), cmd on the command URL (what the twin takes; never subscribed
 * here). samples and cmd only when asked for (what: AFMT_OPEN_*), else NULL. Subscribe each
 * output on afmt_lcm_of(l, AFMT_OUT_*). */
typedef struct {
    lcm_t *cmd, *out, *samples;
} afmt_lcm;
enum { AFMT_OPEN_CMD = 1, AFMT_OPEN_SAMPLES = 2 };
/* 0, -1 (a bad URL: usage) or -2 (lcm_create failed), with err; on error nothing is open. */
int afmt_lcm_open(afmt_lcm *l, const char *url, const char *out_url, const char *samples_url,
                  int what, char *err, size_t errlen);
/* The instance that carries output out_kind (AFMT_OUT_*). */
lcm_t *afmt_lcm_of(const afmt_lcm *l, int out_kind);
/* Wait up to timeout_ms for out or samples; handle what is there, samples first (all that
 * wait, so that samples published before a tick_done are handled before it whenever both
 * are in). > 0 something handled, 0 timeout, < 0 LCM failed. */
int afmt_lcm_handle(afmt_lcm *l, int timeout_ms);
/* Handle the samples that arrived by now (none waited for). */
void afmt_lcm_drain_samples(afmt_lcm *l);
/* Destroy what is open (the subscriptions with it). */
void afmt_lcm_close(afmt_lcm *l);

/* Encode msg of generated type T (e.g. afmtwin_dither_t) into buf of cap bytes: byte count,
 * or -1 when it does not fit. */
#define AFMT_ENCODE(T, msg, buf, cap)                                                              \
    (T##_encoded_size(msg) > (cap) ? -1 : T##_encode((buf), 0, (cap), (msg)))

/* One event into an LCM log (lcm-logger's format): 0, or -1 (write failed). */
int afmt_log_write(lcm_eventlog_t *log, int64_t utime_us, const char *channel, const void *data,
                   int len);

/* Whole-string number: 0, or -1 (empty, trailing junk, out of range). Accepts nan/inf
 * spellings, so that callers can test the validation of non-finite values. */
int afmt_parse_double(const char *s, double *v);
/* Comma-separated list of up to max numbers: count, or -1. */
int afmt_parse_list(const char *s, double *v, int max);
/* A comma-separated subset of names[0..n) into want[0..n) (the rest false): 0, or -1 (an
 * unknown or empty item, nothing given). "all" stands for every name when all_ok. */
int afmt_parse_subset(const char *s, const char *const *names, int n, bool all_ok, bool *want);
/* Hex string (pairs of hex digits, optional spaces) into buf: byte count, or -1. */
int afmt_parse_hex(const char *s, uint8_t *buf, int cap);

/* A subscription that hands fn only messages that pass afm_wire_decode (checked before
 * lcm-gen's decoder runs, freed after fn returns); the others are counted in bad. s must
 * live as long as the subscription. 0, or -1 (lcm_subscribe failed). */
typedef struct {
    const afm_wire_type *type;
    void (*fn)(const void *msg, void *user); /* msg: the generated struct of type */
    void *user;
    long bad;
} afmt_checked_sub;
int afmt_subscribe_checked(lcm_t *lcm, const char *channel, afmt_checked_sub *s, int capacity);

double afmt_mono_s(void);   /* CLOCK_MONOTONIC, seconds */
int64_t afmt_wall_us(void); /* CLOCK_REALTIME, microseconds since the epoch */

#endif
