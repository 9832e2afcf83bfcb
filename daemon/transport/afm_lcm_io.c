/* SPDX-License-Identifier: MIT */
/* afm_lcm_io.c -- the LCM transport of the daemon (interface in afm_io.h): raw
 * subscriptions on the command channels of one LCM instance, outputs published as the
 * generated types (afm_lcm_encode.h) on a second one and the sample stream on a third, so
 * that the command socket never carries the daemon's own outputs and a subscriber of the
 * status or harmonics never gets the samples (afm_lcm_url.h). Each output channel numbers
 * its messages (msg_seq). */
#include "transport/afm_io.h"
#include "transport/afm_cmd_lcm.h"

#include "transport/afm_lcm_drops.h"
#include "transport/afm_lcm_encode.h"
#include "transport/afm_lcm_url.h"

#include <lcm/lcm.h>
#include <math.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CH_LEN 96
#define QUEUE_CAPACITY 1000 /* messages LCM may hold per command channel */
#define POLL_BATCH 512      /* messages handled per poll at most */

typedef struct lcm_io lcm_io;

typedef struct {
    lcm_io *owner;
    afm_cmd_kind kind;
    char channel[CH_LEN];
} in_channel;

struct lcm_io {
    afm_io io;
    lcm_t *lcm;         /* commands (subscribed) */
    lcm_t *out;         /* outputs (publish only: LCM opens no receive socket for it) */
    lcm_t *samples;     /* the sample stream (publish only); == out when the URLs are equal */
    int64_t msg_seq[4]; /* next msg_seq of samples, harmonics, status, tick_done */
    in_channel in[6];
    char ch_samples[CH_LEN], ch_harmonics[CH_LEN], ch_status[CH_LEN], ch_done[CH_LEN];
    /* Drops before the handler (afm_lcm_drops.h): LCM's queues, the kernel's socket. */
    int watch;              /* -1: none */
    const char *watched[6]; /* the in[] channel names */
    int port;               /* udpm command port; 0: not udpm */
    unsigned long sock[AFM_LCM_DROPS_SOCKETS];
    int n_sock;
    long long sock_drops0; /* at start */
};

static void on_raw(const lcm_recv_buf_t *rbuf, const char *channel, void *user) {
    in_channel *ic = user;
    const afm_io_sink *sink = &ic->owner->io.sink;
    afm_cmd c;
    char err[AFM_ERR_LEN];
    afm_cmd_limits lim = sink->limits ? sink->limits(sink->ctx) : (afm_cmd_limits){0};
    if (afm_cmd_decode(ic->kind, rbuf->data, rbuf->data_size, &lim, &c, err, sizeof err)) {
        sink->on_reject(sink->ctx, channel, err);
        return;
    }
    sink->on_cmd(sink->ctx, &c);
}

static int lio_poll(afm_io *io, int timeout_ms) {
    lcm_io *l = io->impl;
    /* lcm_handle_timeout returns > 0 after handling one message, 0 on timeout, < 0 on
     * error. Whatever else is queued already goes now too (up to POLL_BATCH): one wakeup
     * for a burst, not one per message. */
    int rc = lcm_handle_timeout(l->lcm, timeout_ms);
    for (int i = 0; rc > 0 && i < POLL_BATCH; i++)
        rc = lcm_handle_timeout(l->lcm, 0);
    return rc < 0 ? -1 : 0;
}

static int lio_samples(afm_io *io, const afm_io_samples *s) {
    lcm_io *l = io->impl;
    afmtwin_samples_t m;
    afm_lcm_samples_msg(s, &m);
    m.msg_seq = l->msg_seq[0]++;
    return afmtwin_samples_t_publish(l->samples, l->ch_samples, &m) < 0 ? -1 : 0;
}

static int lio_harmonics(afm_io *io, const afm_io_harmonics *h) {
    lcm_io *l = io->impl;
    afm_lcm_harm_buf b;
    afmtwin_harmonics_t m;
    afm_lcm_harmonics_msg(h, &b, &m);
    m.msg_seq = l->msg_seq[1]++;
    return afmtwin_harmonics_t_publish(l->out, l->ch_harmonics, &m) < 0 ? -1 : 0;
}

static int lio_status(afm_io *io, const afm_io_status *s) {
    lcm_io *l = io->impl;
    afmtwin_status_t m;
    afm_lcm_status_msg(s, &m);
    m.msg_seq = l->msg_seq[2]++;
    return afmtwin_status_t_publish(l->out, l->ch_status, &m) < 0 ? -1 : 0;
}

static int lio_tick_done(afm_io *io, const afm_io_tick_done *d) {
    lcm_io *l = io->impl;
    afmtwin_tick_done_t m;
    afm_lcm_tick_done_msg(d, &m);
    m.msg_seq = l->msg_seq[3]++;
    return afmtwin_tick_done_t_publish(l->out, l->ch_done, &m) < 0 ? -1 : 0;
}

static int lio_wait_fd(afm_io *io, int *max_wait_ms) {
    lcm_io *l = io->impl;
    if (max_wait_ms) *max_wait_ms = -1;
    return lcm_get_fileno(l->lcm);
}

/* Messages lost before on_raw: LCM's subscription queues (per channel) and the kernel's
 * receive buffer of the command socket. Sets dropped and last_drop. */
static void lio_annotate(afm_io *io, afm_io_status *s) {
    lcm_io *l = io->impl;
    long long q = 0, worst = 0;
    int wi = 0;
    for (int i = 0; i < 6; i++) {
        long long d = afm_lcm_drops_queue(l->watch, i);
        q += d;
        if (d > worst) {
            worst = d;
            wi = i;
        }
    }
    long long k = 0;
    if (l->port > 0 && l->n_sock > 0) {
        long long now = afm_udp_drops(l->sock, l->n_sock, l->port);
        if (now >= l->sock_drops0) k = now - l->sock_drops0;
    }
    s->dropped = q + k;
    if (!afm_lcm_drops_visible())
        snprintf(s->last_drop, sizeof s->last_drop,
                 "LCM's queue drops are not visible with this liblcm; kernel drops %lld", k);
    else if (q + k == 0)
        s->last_drop[0] = 0;
    else
        snprintf(s->last_drop, sizeof s->last_drop,
                 "LCM dropped %lld messages (full subscription queues of %d; most on %s: %lld), "
                 "the kernel %lld (full receive buffer of the command socket)",
                 q, QUEUE_CAPACITY, l->in[wi].channel, worst, k);
}

static void lio_destroy(afm_io *io) {
    lcm_io *l = io->impl;
    afm_lcm_drops_unwatch(l->watch);
    if (l->lcm) lcm_destroy(l->lcm);
    if (l->samples && l->samples != l->out) lcm_destroy(l->samples);
    if (l->out) lcm_destroy(l->out);
    free(l);
}

static const afm_io_ops lcm_ops = {
    .name = "lcm",
    .poll = lio_poll,
    .publish_samples = lio_samples,
    .publish_harmonics = lio_harmonics,
    .publish_status = lio_status,
    .destroy = lio_destroy,
    .wait_fd = lio_wait_fd,
    .annotate_status = lio_annotate,
    .publish_tick_done = lio_tick_done,
};

afm_io *afm_lcm_io_create(const char *url, const char *out_url, const char *samples_url,
                          const char *prefix, const afm_io_sink *sink, char *err, size_t errlen) {
    static const afm_cmd_kind ins[6] = {AFM_CMD_DITHER,  AFM_CMD_SETPOINT, AFM_CMD_PARAM,
                                        AFM_CMD_CONTROL, AFM_CMD_TICK,     AFM_CMD_SCAN};
    if (!prefix) prefix = "AFMTWIN_";
    if (strlen(prefix) > 64 || strpbrk(prefix, " \t\n.*?[]()") != NULL) {
        snprintf(err, errlen,
                 "bad channel prefix '%s' (at most 64 characters, no spaces or "
                 "regex characters)",
                 prefix);
        return NULL;
    }
    lcm_io *l = calloc(1, sizeof *l);
    if (!l) {
        snprintf(err, errlen, "out of memory");
        return NULL;
    }
    l->io.ops = &lcm_ops;
    l->io.sink = *sink;
    l->io.impl = l;
    l->watch = -1;
    char cmd_u[AFM_LCM_URL_LEN], out_u[AFM_LCM_URL_LEN], smp_u[AFM_LCM_URL_LEN];
    if (afm_lcm_urls(url, out_url, cmd_u, out_u, sizeof cmd_u, err, errlen) ||
        afm_lcm_samples_urls(cmd_u, samples_url, smp_u, sizeof smp_u, err, errlen)) {
        free(l);
        return NULL;
    }
    unsigned long before[AFM_LCM_DROPS_SOCKETS * 8];
    int n_before = afm_udp_sockets(before, (int)(sizeof before / sizeof before[0]));
    l->lcm = lcm_create(cmd_u);
    l->out = l->lcm ? lcm_create(out_u) : NULL;
    l->samples = !l->out ? NULL : strcmp(smp_u, out_u) ? lcm_create(smp_u) : l->out;
    if (!l->lcm || !l->out || !l->samples) {
        snprintf(err, errlen,
                 "lcm_create(%s) failed (for udpm: is there a multicast route? "
                 "see README, 'Running the daemon')",
                 !l->lcm   ? cmd_u
                 : !l->out ? out_u
                           : smp_u);
        lio_destroy(&l->io);
        return NULL;
    }
    for (int i = 0; i < 6; i++) {
        in_channel *ic = &l->in[i];
        ic->owner = l;
        ic->kind = ins[i];
        snprintf(ic->channel, sizeof ic->channel, "%s%s", prefix, afm_cmd_channel_suffix(ins[i]));
        lcm_subscription_t *sub = lcm_subscribe(l->lcm, ic->channel, on_raw, ic);
        if (!sub) {
            snprintf(err, errlen, "cannot subscribe to %s", ic->channel);
            lio_destroy(&l->io);
            return NULL;
        }
        lcm_subscription_set_queue_capacity(sub, QUEUE_CAPACITY);
        l->watched[i] = ic->channel;
    }
    l->watch = afm_lcm_drops_watch(l->lcm, l->watched, 6);
    afm_lcm_drops_visible(); /* the self-test, now rather than on the first status */
    /* The sockets LCM opened (udpm binds its receive socket to the command port). */
    if (!strncmp(cmd_u, "udpm://", 7)) {
        const char *c = strchr(cmd_u + 7, ':');
        l->port = c ? atoi(c + 1) : 7667;
        unsigned long after[AFM_LCM_DROPS_SOCKETS * 8];
        int n_after = afm_udp_sockets(after, (int)(sizeof after / sizeof after[0]));
        for (int i = 0; i < n_after && l->n_sock < AFM_LCM_DROPS_SOCKETS; i++) {
            bool old_one = false;
            for (int j = 0; j < n_before; j++)
                old_one |= after[i] == before[j];
            if (!old_one) l->sock[l->n_sock++] = after[i];
        }
        long long d0 = afm_udp_drops(l->sock, l->n_sock, l->port);
        l->sock_drops0 = d0 > 0 ? d0 : 0;
    }
    snprintf(l->ch_samples, sizeof l->ch_samples, "%sSAMPLES", prefix);
    snprintf(l->ch_harmonics, sizeof l->ch_harmonics, "%sHARMONICS", prefix);
    snprintf(l->ch_status, sizeof l->ch_status, "%sSTATUS", prefix);
    snprintf(l->ch_done, sizeof l->ch_done, "%sTICK_DONE", prefix);
    return &l->io;
}
