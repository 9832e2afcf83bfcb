/* SPDX-License-Identifier: MIT */
/* build_worker.c -- the models that commands bring, built on a worker thread started at
 * start-up instead of on the receive thread (issue 18), so that the receive thread keeps
 * taking commands from the transport meanwhile (a 10 kHz stream does not pile up in the
 * socket's buffer behind a geometry rebuild). Three kinds of job:
 *  - A0: the A0 that a dither of tone 0 brings under the internal AM Z loop (am.control =
 *    "internal": afm_runner_model_a0, a settled simulation of ~0.1 s);
 *  - MODEL: the model of a damping or geometry change (afmpar; afm_runner_model_build_at at
 *    the drive in force, a new output chain when the change needs one);
 *  - RELOAD: the model of the config file a SIGHUP reloads (its own drive, checked against
 *    the new model's limits).
 *
 * The receive thread (cmd_in.c) submits one job at a time: the config, the drive and the
 * command. The command and every command after it wait in order in the receive thread's
 * hold ring until the job is done; then the command goes to the RT thread with its model
 * (or is rejected with the build's reason) and the held commands follow as if they had just
 * arrived. What the RT thread is given, and in which order, is what the blocking build
 * gave: replay and lockstep stay identical. The worker runs at SCHED_FIFO 1
 * (twind_rt_setup_build: below every thread of the daemon, above ordinary processes); it
 * allocates the model, as the receive thread did; the real-time threads never wait on it.
 * Only the worker and the receive thread take its mutex. */
#include "twind.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The job's model (worker thread, outside the mutex: the job is the worker's meanwhile). */
static afm_runner_model *build_job(twind_bw *b, char *err, size_t errlen) {
    if (b->kind == TWIND_BUILD_A0) return afm_runner_model_a0(b->cfg, &b->drive, err, errlen);
    afm_runner_model *m = afm_runner_model_build_at(b->cfg, b->new_chain,
                                                    b->has_drive ? &b->drive : NULL, err, errlen);
    if (m && b->kind == TWIND_BUILD_RELOAD &&
        afm_cmd_check_cfg_drive(afm_runner_model_modal(m), &b->cfg->drive, err, errlen))
        afm_runner_model_destroy(&m);
    return m;
}

static void *bw_main(void *arg) {
    twind *d = arg;
    twind_bw *b = &d->bw;
    twind_thread_name("afm-build");
    twind_rt_setup_build(1, true); /* SCHED_FIFO 1 for good */
    pthread_mutex_lock(&b->mu);
    for (;;) {
        while (!b->stop && !b->queued)
            pthread_cond_wait(&b->cv, &b->mu);
        if (b->stop) break;
        b->queued = false;
        pthread_mutex_unlock(&b->mu);
        char err[AFM_ERR_LEN] = "";
        afm_runner_model *m = build_job(b, err, sizeof err);
        pthread_mutex_lock(&b->mu);
        b->model = m;
        memcpy(b->err, err, sizeof b->err);
        b->done = true;
        pthread_cond_broadcast(&b->cv);
    }
    pthread_mutex_unlock(&b->mu);
    return NULL;
}

int twind_bw_start(twind *d) {
    twind_bw *b = &d->bw;
    b->cfg = malloc(sizeof *b->cfg);
    b->held = calloc(TWIND_HELD_LEN, sizeof *b->held);
    if (!b->cfg || !b->held) return -1;
    if (pthread_mutex_init(&b->mu, NULL)) return -1;
    if (pthread_cond_init(&b->cv, NULL)) {
        pthread_mutex_destroy(&b->mu);
        return -1;
    }
    b->started = true;
    if (pthread_create(&b->th, NULL, bw_main, d)) {
        b->started = false;
        pthread_cond_destroy(&b->cv);
        pthread_mutex_destroy(&b->mu);
        return -1;
    }
    return 0;
}

void twind_bw_submit(twind *d, twind_build_kind kind, const afm_config *cfg,
                     const afm_cmd_dither *drive, bool new_chain) {
    twind_bw *b = &d->bw;
    pthread_mutex_lock(&b->mu);
    *b->cfg = *cfg; /* the worker is idle: no job in flight (b->busy was false) */
    b->kind = kind;
    b->has_drive = drive != NULL;
    if (drive) b->drive = *drive;
    b->new_chain = new_chain;
    b->model = NULL;
    b->done = false;
    b->queued = true;
    b->busy = true;
    pthread_cond_signal(&b->cv);
    pthread_mutex_unlock(&b->mu);
}

bool twind_bw_take(twind *d, int wait_ms, afm_runner_model **m, char *err, size_t errlen) {
    twind_bw *b = &d->bw;
    pthread_mutex_lock(&b->mu);
    if (!b->done && wait_ms > 0) {
        struct timespec until = twind_deadline_in((long)wait_ms * 1000000L);
        while (!b->done && !b->stop && pthread_cond_timedwait(&b->cv, &b->mu, &until) == 0) {
        }
    }
    bool done = b->done;
    if (done) {
        *m = b->model;
        snprintf(err, errlen, "%s", b->err);
        b->model = NULL;
        b->done = false;
        b->busy = false;
    }
    pthread_mutex_unlock(&b->mu);
    return done;
}

void twind_bw_stop(twind *d) {
    twind_bw *b = &d->bw;
    if (b->started) {
        pthread_mutex_lock(&b->mu);
        b->stop = true;
        pthread_cond_broadcast(&b->cv);
        pthread_mutex_unlock(&b->mu);
        pthread_join(b->th, NULL); /* waits for a build in progress (~0.1 s) */
        afm_runner_model_destroy(&b->model);
        pthread_cond_destroy(&b->cv);
        pthread_mutex_destroy(&b->mu);
        b->started = false;
    }
    free(b->cfg);
    free(b->held);
    b->cfg = NULL;
    b->held = NULL;
}
