/* SPDX-License-Identifier: MIT */
/* publish.c -- the publish thread: samples and harmonics records from the RT thread's rings
 * out through the transport, and the status at 10 Hz (and once more at shutdown). */
#include "twind.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#define STATUS_PERIOD_S 0.1

void twind_status_fill(twind *d, afm_io_status *o, twind_rtf_state *rs) {
    twind_snapshot s;
    twind_chain_snapshot cs;
    twind_snap_read(d, &s);
    twind_csnap_read(d, &cs);
    double wall = twind_mono_now();
    memset(o, 0, sizeof *o);
    o->utime = twind_utime_now();
    o->seq_applied = s.st.seq_applied;
    o->model_time_s = s.st.t_s;
    if (!atomic_load_explicit(&d->rt_done, memory_order_acquire)) {
        if (rs->wall > 0 && wall > rs->wall) rs->rtf = (s.st.t_s - rs->model) / (wall - rs->wall);
        rs->wall = wall;
        rs->model = s.st.t_s;
    }
    o->realtime_factor = rs->rtf;
    o->overruns = s.overruns;
    o->lag_s = s.lag_s;
    /* The transports' own fields first (CAN state; what LCM dropped before any handler). */
    if (d->io && d->io->ops->annotate_status) d->io->ops->annotate_status(d->io, o);
    pthread_mutex_lock(&d->lock);
    o->received = d->received + o->dropped; /* dropped ones were received, then lost */
    o->rejected = d->rejected;
    o->refused = d->refused + s.refused; /* queue full here; the twin's own refusals */
    snprintf(o->last_reject, sizeof o->last_reject, "%s", d->last_reject);
    snprintf(o->last_refusal, sizeof o->last_refusal, "%s", d->last_refusal);
    pthread_mutex_unlock(&d->lock);
    o->auto_paused = s.st.auto_paused;
    afm_runner_pause_reason(&s.st, o->pause_reason, sizeof o->pause_reason);
    o->blowups = s.st.blowups;
    o->mode = twind_mode_name(d->opt.mode);
    o->running = s.st.running;
    o->separation_m = s.st.separation_m;
    o->fe_hz = s.st.fe_hz;
    o->amplitude_m = s.st.amplitude_m;
    o->applied = s.st.applied;
    o->resyncs = s.resyncs;
    o->chain_stalls = s.st.stalls;
    double lag = s.st.t_s - cs.st.t_s; /* model time integrated but not yet through the chain */
    o->chain_lag_s = lag > 0 ? lag : 0;
}

static int drain(twind *d) {
    int n = 0;
    afm_io_samples *s;
    afm_io_harmonics *h;
    while ((s = afm_spsc_peek(&d->samples_q)) != NULL) {
        d->io->ops->publish_samples(d->io, s);
        afm_spsc_release(&d->samples_q);
        n++;
    }
    while ((h = afm_spsc_peek(&d->harm_q)) != NULL) {
        d->io->ops->publish_harmonics(d->io, h);
        afm_spsc_release(&d->harm_q);
        n++;
    }
    return n;
}

void *twind_pub_main(void *arg) {
    twind *d = arg;
    twind_rt_setup_aux(d->opt.rt_priority - 10);
    twind_rtf_state rs = {0, 0, 0};
    double next_status = twind_mono_now();
    afm_io_status st;
    for (;;) {
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts); /* sem_timedwait takes CLOCK_REALTIME */
        ts.tv_nsec += 20000000L;
        if (ts.tv_nsec >= 1000000000L) {
            ts.tv_sec++;
            ts.tv_nsec -= 1000000000L;
        }
        while (sem_timedwait(&d->out_sem, &ts) != 0 && errno == EINTR) {
        }
        drain(d);
        double now = twind_mono_now();
        if (now >= next_status) {
            twind_status_fill(d, &st, &rs);
            d->io->ops->publish_status(d->io, &st);
            next_status += STATUS_PERIOD_S;
            if (next_status < now) next_status = now + STATUS_PERIOD_S;
        }
        if (atomic_load_explicit(&d->chain_done, memory_order_acquire)) break;
    }
    drain(d);
    twind_status_fill(d, &st, &rs);
    d->io->ops->publish_status(d->io, &st); /* the final status */
    return NULL;
}
