/* SPDX-License-Identifier: MIT */
/* cmd_in.c -- the receive thread: commands from the transport are checked against the
 * daemon's copy of the config, models for damping/geometry changes and SIGHUP reloads are
 * built here (off the real-time thread), and everything goes to the RT thread in order
 * through cmd_q. Also destroys what the RT thread swapped out. */
#include "twind.h"

#include <stdio.h>
#include <string.h>

void twind_reject_order(twind *d, const char *reason, int64_t order) {
    double now = twind_mono_now();
    pthread_mutex_lock(&d->lock);
    d->rejected++;
    snprintf(d->last_reject, sizeof d->last_reject, "%s", reason);
    d->last_reject_order = order;
    d->last_reject_mono = now;
    pthread_mutex_unlock(&d->lock);
    if (!d->opt.quiet) fprintf(stderr, "afmtwind: rejected: %s\n", reason);
}

void twind_reject(twind *d, const char *reason) {
    twind_reject_order(d, reason, d->order);
}

static void count_received(twind *d) {
    pthread_mutex_lock(&d->lock);
    d->received++;
    pthread_mutex_unlock(&d->lock);
    d->order++;
}

/* Push a command (and its model) to the RT thread; the queue never blocks: a full queue
 * is a rejection (the RT thread is far behind). */
static int enqueue(twind *d, const afm_cmd *c, afm_runner_model *m, const char *what) {
    twind_cmd_item it = {.cmd = *c, .model = m, .order = d->order};
    if (!afm_spsc_push(&d->cmd_q, &it)) {
        char why[AFM_IO_REASON_LEN];
        snprintf(why, sizeof why, "%s: command queue full (%zu waiting)", what,
                 afm_spsc_capacity(&d->cmd_q));
        afm_runner_model_destroy(&m);
        twind_reject(d, why);
        return -1;
    }
    sem_post(&d->cmd_sem); /* wakes an idle RT thread (lockstep, paused); never blocks */
    return 0;
}

/* A model off the real-time threads, at normal priority (twind_rt_setup_build). */
static afm_runner_model *build(twind *d, const afm_config *cfg, bool new_chain, char *err,
                               size_t errlen) {
    twind_rt_setup_build(d->opt.rt_priority - 10, true);
    afm_runner_model *m = afm_runner_model_build(cfg, new_chain, err, errlen);
    twind_rt_setup_build(d->opt.rt_priority - 10, false);
    return m;
}

static int on_cmd(void *ctx, const afm_cmd *c) {
    twind *d = ctx;
    char err[AFM_ERR_LEN], why[AFM_IO_REASON_LEN];
    count_received(d);
    const char *kind = afm_cmd_kind_name(c->kind);
    if (c->kind == AFM_CMD_TICK && d->opt.mode != TWIND_LOCKSTEP) {
        snprintf(why, sizeof why, "tick: the daemon runs in %s mode, not lockstep",
                 twind_mode_name(d->opt.mode));
        twind_reject(d, why);
        return -1;
    }
    if (c->kind != AFM_CMD_PARAM) return enqueue(d, c, NULL, kind);
    afm_config next = d->shadow;
    afm_param_effect eff;
    if (afm_param_apply(&next, &c->u.param, &eff, err, sizeof err)) {
        twind_reject(d, err);
        return -1;
    }
    afm_runner_model *m = NULL;
    if (eff >= AFM_PARAM_DAMPING) {
        m = build(d, &next, eff == AFM_PARAM_GEOMETRY, err, sizeof err);
        if (!m) {
            snprintf(why, sizeof why, "param: cannot build the new model: %.200s", err);
            twind_reject(d, why);
            return -1;
        }
    }
    if (enqueue(d, c, m, kind)) return -1;
    d->shadow = next;
    return 0;
}

static void on_reject(void *ctx, const char *channel, const char *reason) {
    twind *d = ctx;
    char why[AFM_IO_REASON_LEN];
    count_received(d);
    snprintf(why, sizeof why, "%s: %s", channel, reason);
    twind_reject(d, why);
}

static afm_cmd_limits limits(void *ctx) {
    twind *d = ctx;
    return (afm_cmd_limits){.sample_rate_hz = d->shadow.sim.sample_rate_hz};
}

afm_io_sink twind_sink(twind *d) {
    return (afm_io_sink){.ctx = d, .on_cmd = on_cmd, .on_reject = on_reject, .limits = limits};
}

/* SIGHUP: load and check the file, build the twin off the RT thread, swap at a block
 * boundary. A bad config keeps the running one and says why. */
static void do_reload(twind *d) {
    static afm_config next; /* receive thread only; large for a stack frame */
    char err[AFM_ERR_LEN], why[AFM_IO_REASON_LEN];
    d->order++;
    if (afm_config_load(d->opt.config_path, &next, err, sizeof err)) {
        snprintf(why, sizeof why, "reload: %.200s; keeping the running config", err);
        twind_reject(d, why);
        return;
    }
    afm_runner_model *m = build(d, &next, true, err, sizeof err);
    if (!m) {
        snprintf(why, sizeof why, "reload: %.60s: %.150s; keeping the running config",
                 d->opt.config_path, err);
        twind_reject(d, why);
        return;
    }
    afm_cmd c = {.kind = AFM_CMD_RELOAD, .seq = -1}; /* a reload keeps seq_applied */
    if (enqueue(d, &c, m, "reload")) return;
    d->shadow = next;
    if (!d->opt.quiet) fprintf(stderr, "afmtwind: reloaded %s\n", d->opt.config_path);
}

static void drain_side_queues(twind *d) {
    afm_runner_model *m;
    while (afm_spsc_pop(&d->trash_q, &m)) /* rejected by the RT thread */
        afm_runner_model_destroy(&m);
    while (afm_runner_take_trash(d->runner, &m)) /* swapped out, via the chain thread */
        afm_runner_model_destroy(&m);
    twind_reason r;
    while (afm_spsc_pop(&d->rtrej_q, &r))
        twind_reject_order(d, r.reason, r.order);
}

void *twind_recv_main(void *arg) {
    twind *d = arg;
    twind_rt_setup_aux(d->opt.rt_priority - 10, d->opt.aux_cpu);
    while (!atomic_load_explicit(&d->stop, memory_order_acquire)) {
        if (d->io->ops->poll(d->io, 50) < 0) {
            struct timespec ts = {0, 50000000L}; /* transport trouble: do not spin */
            nanosleep(&ts, NULL);
        }
        if (atomic_exchange(&d->reload, 0)) do_reload(d);
        drain_side_queues(d);
    }
    /* After the RT and chain threads have stopped: whatever they left behind. */
    while (!atomic_load_explicit(&d->rt_done, memory_order_acquire) ||
           !atomic_load_explicit(&d->chain_done, memory_order_acquire)) {
        struct timespec ts = {0, 1000000L};
        nanosleep(&ts, NULL);
    }
    drain_side_queues(d);
    return NULL;
}
