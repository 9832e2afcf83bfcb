/* SPDX-License-Identifier: MIT */
/* a0_track.c -- the free amplitude A0 (runner/afm_a0.h) at the drive in force, kept current
 * for the status (free_amplitude_m, amplitude_ratio) on a worker thread of its own: A0 is a
 * short settled simulation (~0.1 s on config/default.conf), too long for the real-time
 * threads and long enough to delay commands on the receive thread.
 *
 * The receive thread asks (twind_a0_request) after every change of the config (SIGHUP
 * reload, param) or of tone 0 of the drive (dither); the worker computes the newest request
 * and drops results that a later request made stale. A hand-over between the rt schemes
 * (scheme.c; their steady amplitudes differ by ~2e-4) asks again too (twind_a0_scheme, from
 * the status). Until the newest is done the status
 * says NaN (not known), never the A0 of a drive no longer in force. The worker runs at the
 * receive thread's SCHED_FIFO priority (main's when it starts the worker: above the output
 * chain; at SCHED_FIFO 1 it starved whenever the chain was behind), at most A0_DUTY of the
 * time (it waits after each computation). One computation
 * costs the real-time threads ~5 % of real time in the second it runs on this 2-core VM
 * (test_collapse: real-time factor min 0.92-0.95 against 0.999 without; once 0.88, below its 0.9),
 * so the recomputation is opt-in (afmtwind --a0-track). Without it no worker is started: the
 * start-up (first) A0 stands until the drive or the model changes, then the status says NaN. */
#include "twind.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* cfg with tone 0 of drive (the tones the dither commands set), the rt scheme of the start. */
static void request_config(afm_config *out, const afm_config *cfg, const afm_cmd_dither *drive,
                           afm_rt_scheme_kind scheme) {
    *out = *cfg;
    out->sim.rt_scheme = scheme;
    if (drive && drive->n_tones >= 1) {
        out->drive.tones[0].frequency_hz = drive->frequency_hz[0];
        out->drive.tones[0].amplitude_m = drive->amplitude_m[0];
    }
}

int twind_a0_compute(const afm_config *cfg, afm_a0 *out, char *err, size_t errlen) {
    if (cfg->drive.n_tones >= 1 && cfg->drive.tones[0].amplitude_m == 0) {
        memset(out, 0, sizeof *out); /* a silent tone 0: the lever rests */
        out->lag_deg = out->linear_lag_deg = NAN;
        out->z_m = AFM_A0_Z_M;
        out->settled = true;
        return 0;
    }
    return afm_a0_compute(cfg, out, err, errlen);
}

#define A0_DUTY 0.1       /* the worker's largest share of one core */
#define A0_WAIT_MAX_S 2.0 /* the longest pause between two computations */

static double now_s(clockid_t clk) {
    struct timespec t;
    clock_gettime(clk, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void *a0_main(void *arg) {
    twind_thread_name("afm-a0");
    /* the receive thread's priority, which main had when it created this thread
     * (start_transports): at SCHED_FIFO 1 it starved while the chain was behind real time
     * (test_a0 at load 4-6: A0 still NaN 10 s after a dither), and A0_DUTY already bounds
     * what it takes from the chain */
    twind *d = arg;
    twind_a0 *a = &d->a0;
    char err[AFM_ERR_LEN];
    pthread_mutex_lock(&a->mu);
    for (;;) {
        while (!a->stop && a->done_gen == a->req_gen)
            pthread_cond_wait(&a->cv, &a->mu);
        if (a->stop) break;
        unsigned gen = a->req_gen;
        *a->work = *a->req;
        pthread_mutex_unlock(&a->mu);
        afm_a0 r;
        err[0] = '\0';
        const double t0 = now_s(CLOCK_MONOTONIC);
        int rc = twind_a0_compute(a->work, &r, err, sizeof err);
        const double busy_s = now_s(CLOCK_MONOTONIC) - t0;
        pthread_mutex_lock(&a->mu);
        if (gen == a->req_gen) { /* else stale: a later request waits */
            a->amplitude_m = rc ? NAN : r.amplitude_m;
            a->lag_deg = rc ? NAN : r.lag_deg;
            a->computed++;
            a->done_gen = gen;
            if (rc && !d->opt.quiet)
                fprintf(stderr, "afmtwind: warning: A0 not computed: %s\n", err);
        }
        /* At most A0_DUTY of one core: requests come with every dither and param (a
         * controller may send 1000 a second), and a worker kept busy on the second core
         * took the real-time threads below real time (test_soak: real-time factor 0.77-0.84
         * against >= 0.9) although it runs at normal priority. Later requests wait (the
         * newest is computed); a stop does not. */
        double wait_s = fmin(busy_s * (1.0 / A0_DUTY - 1.0), A0_WAIT_MAX_S);
        struct timespec until;
        clock_gettime(CLOCK_REALTIME, &until);
        double frac = until.tv_nsec * 1e-9 + wait_s;
        until.tv_sec += (time_t)frac;
        until.tv_nsec = (long)((frac - floor(frac)) * 1e9);
        while (!a->stop && pthread_cond_timedwait(&a->cv, &a->mu, &until) != ETIMEDOUT) {
        }
    }
    pthread_mutex_unlock(&a->mu);
    return NULL;
}

int twind_a0_start(twind *d, const afm_config *cfg, afm_rt_scheme_kind scheme,
                   const afm_a0 *first) {
    twind_a0 *a = &d->a0;
    a->req = malloc(sizeof *a->req);
    a->work = malloc(sizeof *a->work);
    if (!a->req || !a->work) return -1;
    a->scheme = scheme;
    request_config(a->req, cfg, NULL, scheme);
    a->fe_hz = cfg->drive.tones[0].frequency_hz;
    a->ae_m = cfg->drive.tones[0].amplitude_m;
    a->amplitude_m = first->amplitude_m;
    a->lag_deg = first->lag_deg;
    a->req_gen = a->done_gen = 0;
    if (pthread_mutex_init(&a->mu, NULL)) return -1;
    if (pthread_cond_init(&a->cv, NULL)) {
        pthread_mutex_destroy(&a->mu);
        return -1;
    }
    a->started = true;              /* from here twind_a0_stop cleans up */
    if (!d->opt.a0_track) return 0; /* no worker: requests only mark A0 unknown */
    if (pthread_create(&a->th, NULL, a0_main, d)) {
        a->started = false;
        pthread_cond_destroy(&a->cv);
        pthread_mutex_destroy(&a->mu);
        return -1;
    }
    a->worker = true;
    return 0;
}

void twind_a0_request(twind *d, const afm_config *cfg, const afm_cmd_dither *drive,
                      bool cfg_changed) {
    twind_a0 *a = &d->a0;
    if (!a->started) return;
    double fe =
        drive && drive->n_tones >= 1 ? drive->frequency_hz[0] : cfg->drive.tones[0].frequency_hz;
    double ae =
        drive && drive->n_tones >= 1 ? drive->amplitude_m[0] : cfg->drive.tones[0].amplitude_m;
    if (!cfg_changed && fe == a->fe_hz && ae == a->ae_m) return; /* tone 0 as before */
    a->fe_hz = fe;
    a->ae_m = ae;
    pthread_mutex_lock(&a->mu);
    if (a->worker) request_config(a->req, cfg, drive, a->scheme);
    a->req_gen++; /* without a worker (no --a0-track): unknown from now on */
    pthread_cond_signal(&a->cv);
    pthread_mutex_unlock(&a->mu);
}

void twind_a0_scheme(twind *d, bool accurate) {
    twind_a0 *a = &d->a0;
    if (!a->started) return;
    const afm_rt_scheme_kind k = accurate ? AFM_RT_SCHEME_ACCURATE : AFM_RT_SCHEME_FAST;
    pthread_mutex_lock(&a->mu);
    if (k != a->scheme) { /* a hand-over: the same request on the other scheme */
        a->scheme = k;
        a->req->sim.rt_scheme = k;
        a->req_gen++;
        pthread_cond_signal(&a->cv);
    }
    pthread_mutex_unlock(&a->mu);
}

double twind_a0_now(twind *d) {
    twind_a0 *a = &d->a0;
    if (!a->started) return NAN;
    pthread_mutex_lock(&a->mu);
    double v = a->done_gen == a->req_gen ? a->amplitude_m : NAN;
    pthread_mutex_unlock(&a->mu);
    return v;
}

void twind_a0_stop(twind *d) {
    twind_a0 *a = &d->a0;
    if (a->started) {
        if (a->worker) {
            pthread_mutex_lock(&a->mu);
            a->stop = true;
            pthread_cond_signal(&a->cv);
            pthread_mutex_unlock(&a->mu);
            pthread_join(a->th, NULL); /* waits for a computation in progress (~0.1 s) */
            a->worker = false;
        }
        pthread_cond_destroy(&a->cv);
        pthread_mutex_destroy(&a->mu);
        a->started = false;
    }
    free(a->req);
    free(a->work);
    a->req = a->work = NULL;
}
