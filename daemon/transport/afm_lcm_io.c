/* SPDX-License-Identifier: MIT */
/* afm_lcm_io.c -- the LCM transport of the daemon (interface in afm_io.h): raw
 * subscriptions on the command channels, outputs published as the generated types. */
#include "afm_io.h"

#include "afmtwin_harmonics_t.h"
#include "afmtwin_samples_t.h"
#include "afmtwin_status_t.h"

#include <lcm/lcm.h>
#include <math.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CH_LEN 96

typedef struct lcm_io lcm_io;

typedef struct {
    lcm_io *owner;
    afm_cmd_kind kind;
    char channel[CH_LEN];
} in_channel;

struct lcm_io {
    afm_io io;
    lcm_t *lcm;
    in_channel in[5];
    char ch_samples[CH_LEN], ch_harmonics[CH_LEN], ch_status[CH_LEN];
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
    /* lcm_handle_timeout returns > 0 after handling, 0 on timeout, < 0 on error. */
    return lcm_handle_timeout(l->lcm, timeout_ms) < 0 ? -1 : 0;
}

static int lio_samples(afm_io *io, const afm_io_samples *s) {
    lcm_io *l = io->impl;
    afmtwin_samples_t m = {
        .utime = s->utime,
        .seq_applied = s->seq_applied,
        .stream = (int8_t)s->stream,
        .t0_s = s->t0_s,
        .rate_hz = s->rate_hz,
        .n = s->n,
        .deflection_m = (float *)s->deflection_m,
        .obd_m = (float *)s->obd_m,
        .obd_counts = (int32_t *)s->obd_counts,
        .force_n = (float *)s->force_n,
    };
    return afmtwin_samples_t_publish(l->lcm, l->ch_samples, &m) < 0 ? -1 : 0;
}

static int lio_harmonics(afm_io *io, const afm_io_harmonics *h) {
    lcm_io *l = io->impl;
    const afm_harm_result *r = &h->p.harm;
    const afm_cycle_metrics *c = &h->p.cycle;
    int n = r->n_harmonics;
    int16_t k[AFM_MAX_HARMONICS];
    double xa[AFM_MAX_HARMONICS], xp[AFM_MAX_HARMONICS], fa[AFM_MAX_HARMONICS];
    double fp[AFM_MAX_HARMONICS], pd[AFM_MAX_HARMONICS];
    for (int i = 0; i < n; i++) {
        k[i] = (int16_t)r->h[i].k;
        xa[i] = r->h[i].x_amp_m;
        xp[i] = r->h[i].x_phase_deg;
        fa[i] = r->h[i].f_amp_n;
        fp[i] = r->h[i].f_phase_deg;
        pd[i] = r->h[i].phase_diff_deg;
    }
    afmtwin_harmonics_t m = {
        .utime = h->utime,
        .seq_applied = h->seq_applied,
        .t_s = c->t_start_s,
        .fe_hz = h->fe_hz,
        .n = (int8_t)n,
        .k = k,
        .deflection_amplitude_m = xa,
        .deflection_phase_deg = xp,
        .force_amplitude_n = fa,
        .force_phase_deg = fp,
        .phase_diff_deg = pd,
        .lockin_amplitude_m = h->p.lockin_amplitude_m,
        .lockin_phase_deg = h->p.lockin_phase_deg,
        .peak_force_n = c->peak_force_n,
        .min_deflection_m = c->min_deflection_m,
        .indentation_m = c->indentation_m,
        .contact_time_s = c->contact_time_s,
        .pre_contact_velocity_m_s = c->pre_contact_velocity_m_s,
        .dissipated_energy_j = c->dissipated_energy_j,
        .mean_deflection_m = c->mean_deflection_m,
    };
    return afmtwin_harmonics_t_publish(l->lcm, l->ch_harmonics, &m) < 0 ? -1 : 0;
}

static int lio_status(afm_io *io, const afm_io_status *s) {
    lcm_io *l = io->impl;
    afmtwin_status_t m = {
        .utime = s->utime,
        .seq_applied = s->seq_applied,
        .model_time_s = s->model_time_s,
        .realtime_factor = s->realtime_factor,
        .overruns = s->overruns,
        .lag_s = s->lag_s,
        .received = s->received,
        .rejected = s->rejected,
        .last_reject = (char *)s->last_reject,
        .blowups = s->blowups,
        .mode = (char *)s->mode,
        .running = (int8_t)s->running,
        .separation_m = s->separation_m,
        .fe_hz = s->fe_hz,
        .amplitude_m = s->amplitude_m,
    };
    return afmtwin_status_t_publish(l->lcm, l->ch_status, &m) < 0 ? -1 : 0;
}

static void lio_destroy(afm_io *io) {
    lcm_io *l = io->impl;
    if (l->lcm) lcm_destroy(l->lcm);
    free(l);
}

static const afm_io_ops lcm_ops = {
    .name = "lcm",
    .poll = lio_poll,
    .publish_samples = lio_samples,
    .publish_harmonics = lio_harmonics,
    .publish_status = lio_status,
    .destroy = lio_destroy,
};

afm_io *afm_lcm_io_create(const char *url, const char *prefix, const afm_io_sink *sink,
                          char *err, size_t errlen) {
    static const struct {
        afm_cmd_kind kind;
        const char *name;
    } ins[5] = {{AFM_CMD_DITHER, "DITHER"},
                {AFM_CMD_SETPOINT, "SETPOINT"},
                {AFM_CMD_PARAM, "PARAM"},
                {AFM_CMD_CONTROL, "CONTROL"},
                {AFM_CMD_TICK, "TICK"}};
    if (!prefix) prefix = "AFMTWIN_";
    if (strlen(prefix) > 64 || strpbrk(prefix, " \t\n.*?[]()") != NULL) {
        snprintf(err, errlen, "bad channel prefix '%s' (at most 64 characters, no spaces or "
                 "regex characters)", prefix);
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
    l->lcm = lcm_create(url);
    if (!l->lcm) {
        snprintf(err, errlen, "lcm_create(%s) failed (for udpm: is there a multicast route? "
                 "see README, 'Running the daemon')", url ? url : "default URL");
        free(l);
        return NULL;
    }
    for (int i = 0; i < 5; i++) {
        in_channel *ic = &l->in[i];
        ic->owner = l;
        ic->kind = ins[i].kind;
        snprintf(ic->channel, sizeof ic->channel, "%s%s", prefix, ins[i].name);
        lcm_subscription_t *sub = lcm_subscribe(l->lcm, ic->channel, on_raw, ic);
        if (!sub) {
            snprintf(err, errlen, "cannot subscribe to %s", ic->channel);
            lio_destroy(&l->io);
            return NULL;
        }
        lcm_subscription_set_queue_capacity(sub, 1000);
    }
    snprintf(l->ch_samples, sizeof l->ch_samples, "%sSAMPLES", prefix);
    snprintf(l->ch_harmonics, sizeof l->ch_harmonics, "%sHARMONICS", prefix);
    snprintf(l->ch_status, sizeof l->ch_status, "%sSTATUS", prefix);
    return &l->io;
}
