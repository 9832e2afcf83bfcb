/* SPDX-License-Identifier: MIT */
/* lcm_tool.h -- what the LCM subcommands of `afmtwin` (send, listen, replay, bench-daemon)
 * share: channel names, strict number parsing, hex decoding, checked subscriptions, wall and
 * monotonic clocks. */
#ifndef AFMT_LCM_TOOL_H
#define AFMT_LCM_TOOL_H

#include "afm_lcm_wire.h"
#include "afmtwin_lcm_layout.h"

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
#define AFMT_CHAN_SAMPLES AFMTWIN_CHAN_SAMPLES
#define AFMT_CHAN_HARMONICS AFMTWIN_CHAN_HARMONICS
#define AFMT_CHAN_STATUS AFMTWIN_CHAN_STATUS
#define AFMT_CHAN_TICK_DONE AFMTWIN_CHAN_TICK_DONE

/* PREFIX + SUFFIX into out (AFMT_CHAN_LEN). The prefix: 1..63 characters of [A-Za-z0-9_]
 * (LCM channel names are matched as regular expressions by subscribers, so nothing else is
 * safe). 0, or -1 with err. */
int afmt_channel(const char *prefix, const char *suffix, char *out, char *err, size_t errlen);

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

/* The daemon's outputs as a client reads them: harmonics, status and tick_done on out, the
 * sample stream on samples (its own LCM instance for udpm, the same one otherwise; NULL when
 * not wanted). Subscribe the SAMPLES channel on samples, the others on out. */
typedef struct {
    lcm_t *out, *samples;
} afmt_outputs;
/* url: the daemon's command URL (NULL: LCM_DEFAULT_URL or LCM's); out_url, samples_url:
 * overrides of the derived ones (NULL: derived). 0, or -1 with err (nothing left open). */
int afmt_outputs_open(afmt_outputs *o, const char *url, const char *out_url,
                      const char *samples_url, bool want_samples, char *err, size_t errlen);
/* Wait up to timeout_ms for either; handle what is there, samples first (all that wait, so
 * that samples published before a tick_done are handled before it whenever both are in).
 * > 0 something handled, 0 timeout, < 0 LCM failed. */
int afmt_outputs_handle(afmt_outputs *o, int timeout_ms);
/* Handle the samples that arrived by now (none waited for). */
void afmt_outputs_drain_samples(afmt_outputs *o);
void afmt_outputs_close(afmt_outputs *o);

double afmt_mono_s(void);   /* CLOCK_MONOTONIC, seconds */
int64_t afmt_wall_us(void); /* CLOCK_REALTIME, microseconds since the epoch */

#endif
