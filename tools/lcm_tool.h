/* SPDX-License-Identifier: MIT */
/* lcm_tool.h -- what the LCM subcommands of `afmtwin` (send, listen, replay, bench-daemon)
 * share: channel names, strict number parsing, hex decoding, checked subscriptions, wall and
 * monotonic clocks. */
#ifndef AFMT_LCM_TOOL_H
#define AFMT_LCM_TOOL_H

#include "transport/afm_lcm_wire.h"

#include <lcm/lcm.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define AFMT_CHAN_LEN 128

/* Channel names: PREFIX + suffix. The daemon's defaults (afmtwind --prefix overrides). */
#define AFMT_DEFAULT_PREFIX "AFMTWIN_"
#define AFMT_CHAN_DITHER "DITHER"
#define AFMT_CHAN_SETPOINT "SETPOINT"
#define AFMT_CHAN_PARAM "PARAM"
#define AFMT_CHAN_CONTROL "CONTROL"
#define AFMT_CHAN_TICK "TICK"
#define AFMT_CHAN_SAMPLES "SAMPLES"
#define AFMT_CHAN_HARMONICS "HARMONICS"
#define AFMT_CHAN_STATUS "STATUS"
#define AFMT_CHAN_TICK_DONE "TICK_DONE"

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

double afmt_mono_s(void);   /* CLOCK_MONOTONIC, seconds */
int64_t afmt_wall_us(void); /* CLOCK_REALTIME, microseconds since the epoch */

#endif
