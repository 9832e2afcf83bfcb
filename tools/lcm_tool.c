/* SPDX-License-Identifier: MIT */
/* lcm_tool.c -- helpers shared by the LCM subcommands (see lcm_tool.h). */
#include "lcm_tool.h"

#include "cli/afm_opts.h"
#include "transport/afm_lcm_url.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

int afmt_channel(const char *prefix, const char *suffix, char *out, char *err, size_t errlen) {
    size_t n = prefix ? strlen(prefix) : 0;
    if (n < 1 || n > 63) {
        snprintf(err, errlen, "channel prefix must have 1..63 characters, got %zu", n);
        return -1;
    }
    for (size_t i = 0; i < n; i++)
        if (!isalnum((unsigned char)prefix[i]) && prefix[i] != '_') {
            snprintf(err, errlen, "channel prefix '%s': only letters, digits and '_' allowed",
                     prefix);
            return -1;
        }
    snprintf(out, AFMT_CHAN_LEN, "%s%s", prefix, suffix);
    return 0;
}

const char *const afmt_out_names[AFMT_N_OUT] = {"samples", "harmonics", "status", "tick_done"};

int afmt_channels_init(afmt_channels *c, const char *prefix, char *err, size_t errlen) {
    static const char *const cmd_sfx[AFM_CMD_SCAN + 1] = {
        [AFM_CMD_DITHER] = AFMT_CHAN_DITHER, [AFM_CMD_SETPOINT] = AFMT_CHAN_SETPOINT,
        [AFM_CMD_PARAM] = AFMT_CHAN_PARAM,   [AFM_CMD_CONTROL] = AFMT_CHAN_CONTROL,
        [AFM_CMD_TICK] = AFMT_CHAN_TICK,     [AFM_CMD_SCAN] = AFMT_CHAN_SCAN};
    static const char *const out_sfx[AFMT_N_OUT] = {AFMT_CHAN_SAMPLES, AFMT_CHAN_HARMONICS,
                                                    AFMT_CHAN_STATUS, AFMT_CHAN_TICK_DONE};
    if (afmt_channel(prefix, "", c->cmd[0], err, errlen)) return -1;
    c->cmd[AFM_CMD_RELOAD][0] = '\0'; /* SIGHUP's: no channel */
    for (int k = AFM_CMD_DITHER; k <= AFM_CMD_SCAN; k++)
        if (k != AFM_CMD_RELOAD && afmt_channel(prefix, cmd_sfx[k], c->cmd[k], err, errlen))
            return -1;
    for (int i = 0; i < AFMT_N_OUT; i++)
        if (afmt_channel(prefix, out_sfx[i], c->out[i], err, errlen)) return -1;
    return 0;
}

afm_cmd_kind afmt_channels_kind(const afmt_channels *c, const char *name) {
    for (int k = AFM_CMD_DITHER; k <= AFM_CMD_SCAN; k++)
        if (k != AFM_CMD_RELOAD && !strcmp(name, c->cmd[k])) return (afm_cmd_kind)k;
    return 0;
}

int afmt_parse_outputs(const char *s, bool all_ok, bool *want) {
    return afmt_parse_subset(s, afmt_out_names, AFMT_N_OUT, all_ok, want);
}

int afmt_lcm_open(afmt_lcm *l, const char *url, const char *out_url, const char *samples_url,
                  int what, char *err, size_t errlen) {
    char cmd_u[AFM_LCM_URL_LEN], out_u[AFM_LCM_URL_LEN], smp_u[AFM_LCM_URL_LEN];
    *l = (afmt_lcm){0};
    if (afm_lcm_urls(url, out_url, cmd_u, out_u, sizeof cmd_u, err, errlen) ||
        afm_lcm_samples_urls(cmd_u, samples_url, smp_u, sizeof smp_u, err, errlen))
        return -1;
    const char *failed = NULL;
    if (!(l->out = lcm_create(out_u)))
        failed = out_u;
    else if ((what & AFMT_OPEN_SAMPLES) &&
             !(l->samples = strcmp(smp_u, out_u) ? lcm_create(smp_u) : l->out))
        failed = smp_u;
    else if ((what & AFMT_OPEN_CMD) && !(l->cmd = lcm_create(cmd_u)))
        failed = cmd_u;
    if (failed) {
        snprintf(err, errlen, "cannot open LCM on '%.200s' (for udpm: is there a multicast route?)",
                 failed);
        afmt_lcm_close(l);
        return -2;
    }
    return 0;
}

lcm_t *afmt_lcm_of(const afmt_lcm *l, int out_kind) {
    return out_kind == AFMT_OUT_SAMPLES ? l->samples : l->out;
}

#define DRAIN_MAX 4096 /* samples messages handled in one go at most */

void afmt_lcm_drain_samples(afmt_lcm *l) {
    if (!l->samples || l->samples == l->out) return;
    for (int i = 0; i < DRAIN_MAX && lcm_handle_timeout(l->samples, 0) > 0; i++) {
    }
}

int afmt_lcm_handle(afmt_lcm *l, int timeout_ms) {
    if (!l->samples || l->samples == l->out) return lcm_handle_timeout(l->out, timeout_ms);
    struct pollfd p[2] = {{.fd = lcm_get_fileno(l->samples), .events = POLLIN},
                          {.fd = lcm_get_fileno(l->out), .events = POLLIN}};
    int n = poll(p, 2, timeout_ms);
    if (n <= 0) return n < 0 && errno != EINTR ? -1 : 0;
    if (p[0].revents) afmt_lcm_drain_samples(l);
    if (p[1].revents && lcm_handle_timeout(l->out, 0) < 0) return -1;
    return 1;
}

void afmt_lcm_close(afmt_lcm *l) {
    if (l->cmd) lcm_destroy(l->cmd);
    if (l->samples && l->samples != l->out) lcm_destroy(l->samples);
    if (l->out) lcm_destroy(l->out);
    *l = (afmt_lcm){0};
}

int afmt_log_write(lcm_eventlog_t *log, int64_t utime_us, const char *channel, const void *data,
                   int len) {
    lcm_eventlog_event_t ev = {.timestamp = utime_us,
                               .channellen = (int32_t)strlen(channel),
                               .datalen = len,
                               .channel = (char *)channel,
                               .data = (void *)data};
    return lcm_eventlog_write_event(log, &ev) ? -1 : 0;
}

int afmt_parse_double(const char *s, double *v) {
    return afm_opts_parse_double(s, v);
}

int afmt_parse_list(const char *s, double *v, int max) {
    char buf[512];
    if (!s || strlen(s) >= sizeof buf) return -1;
    strcpy(buf, s);
    int n = 0;
    char *save = NULL;
    for (char *t = strtok_r(buf, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
        if (n >= max || afmt_parse_double(t, &v[n])) return -1;
        n++;
    }
    return n;
}

int afmt_parse_subset(const char *s, const char *const *names, int n, bool all_ok, bool *want) {
    char buf[256];
    if (!s || strlen(s) >= sizeof buf) return -1;
    strcpy(buf, s);
    for (int i = 0; i < n; i++)
        want[i] = false;
    int got = 0;
    char *save = NULL;
    for (char *t = strtok_r(buf, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
        int k = -1;
        for (int i = 0; i < n; i++)
            if (!strcmp(t, names[i])) k = i;
        if (k < 0 && !(all_ok && !strcmp(t, "all"))) return -1;
        for (int i = 0; i < n; i++)
            if (i == k || k < 0) want[i] = true;
        got++;
    }
    return got ? 0 : -1;
}

static int hexval(int c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

int afmt_parse_hex(const char *s, uint8_t *buf, int cap) {
    int n = 0;
    while (*s) {
        if (isspace((unsigned char)*s)) {
            s++;
            continue;
        }
        int hi = hexval(s[0]), lo = s[1] ? hexval(s[1]) : -1;
        if (hi < 0 || lo < 0 || n >= cap) return -1;
        buf[n++] = (uint8_t)(hi * 16 + lo);
        s += 2;
    }
    return n;
}

static void on_checked(const lcm_recv_buf_t *rb, const char *channel, void *user) {
    (void)channel;
    afmt_checked_sub *s = user;
    union {
        char bytes[4096];
        double align_d;
        void *align_p;
        int64_t align_i;
    } m;
    if (s->type->size > sizeof m.bytes ||
        afm_wire_decode(s->type, rb->data, rb->data_size, &m, NULL, 0)) {
        s->bad++;
        return;
    }
    s->fn(&m, s->user);
    afm_wire_free(s->type, &m);
}

int afmt_subscribe_checked(lcm_t *lcm, const char *channel, afmt_checked_sub *s, int capacity) {
    lcm_subscription_t *sub = lcm_subscribe(lcm, channel, on_checked, s);
    if (!sub) return -1;
    if (capacity > 0) lcm_subscription_set_queue_capacity(sub, capacity);
    return 0;
}

double afmt_mono_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int64_t afmt_wall_us(void) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (int64_t)ts.tv_sec * 1000000 + ts.tv_nsec / 1000;
}
