/* SPDX-License-Identifier: MIT */
/* lcm_tool.c -- helpers shared by the LCM subcommands (see lcm_tool.h). */
#include "lcm_tool.h"

#include "afm_lcm_url.h"

#include <ctype.h>
#include <poll.h>
#include <errno.h>
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

int afmt_parse_double(const char *s, double *v) {
    if (!s || !*s) return -1;
    char *end;
    errno = 0;
    double x = strtod(s, &end);
    if (*end || end == s || errno == ERANGE) return -1;
    *v = x;
    return 0;
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

int afmt_outputs_open(afmt_outputs *o, const char *url, const char *out_url,
                      const char *samples_url, bool want_samples, char *err, size_t errlen) {
    char cmd_u[AFM_LCM_URL_LEN], out_u[AFM_LCM_URL_LEN], smp_u[AFM_LCM_URL_LEN];
    *o = (afmt_outputs){0};
    if (afm_lcm_urls(url, out_url, cmd_u, out_u, sizeof cmd_u, err, errlen) ||
        afm_lcm_samples_urls(cmd_u, samples_url, smp_u, sizeof smp_u, err, errlen))
        return -1;
    o->out = lcm_create(out_u);
    if (o->out && want_samples) o->samples = strcmp(smp_u, out_u) ? lcm_create(smp_u) : o->out;
    if (!o->out || (want_samples && !o->samples)) {
        snprintf(err, errlen, "cannot open LCM on '%s' (for udpm: is there a multicast route?)",
                 o->out ? smp_u : out_u);
        afmt_outputs_close(o);
        return -1;
    }
    return 0;
}

#define DRAIN_MAX 4096 /* samples messages handled in one go at most */

void afmt_outputs_drain_samples(afmt_outputs *o) {
    if (!o->samples || o->samples == o->out) return;
    for (int i = 0; i < DRAIN_MAX && lcm_handle_timeout(o->samples, 0) > 0; i++) {
    }
}

int afmt_outputs_handle(afmt_outputs *o, int timeout_ms) {
    if (!o->samples || o->samples == o->out) return lcm_handle_timeout(o->out, timeout_ms);
    struct pollfd p[2] = {{.fd = lcm_get_fileno(o->samples), .events = POLLIN},
                          {.fd = lcm_get_fileno(o->out), .events = POLLIN}};
    int n = poll(p, 2, timeout_ms);
    if (n <= 0) return n < 0 && errno != EINTR ? -1 : 0;
    if (p[0].revents) afmt_outputs_drain_samples(o);
    if (p[1].revents && lcm_handle_timeout(o->out, 0) < 0) return -1;
    return 1;
}

void afmt_outputs_close(afmt_outputs *o) {
    if (o->samples && o->samples != o->out) lcm_destroy(o->samples);
    if (o->out) lcm_destroy(o->out);
    *o = (afmt_outputs){0};
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
