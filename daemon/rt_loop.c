/* SPDX-License-Identifier: MIT */
/* rt_loop.c -- the real-time thread: commands in at block boundaries, one block of the twin,
 * outputs out, then sleep to the block's absolute deadline (realtime mode).
 *
 * Never blocks, locks or allocates: queues are lock-free SPSC, the runner allocates nothing
 * after create, clock_nanosleep is the only wait (its deadline is absolute, so jitter does
 * not accumulate). Pacing in realtime mode: model time is tied to CLOCK_MONOTONIC by an
 * origin (wall = origin + samples dt); the deadline of a block is the wall time its last
 * sample represents. A block that ends after its deadline is an overrun; the loop then
 * runs on without sleeping until it has caught up (lag_s says how far behind it is).
 * Pausing (or waiting for ticks) re-anchors the origin, so nothing is "caught up" later. */
#include "twind.h"

#include <limits.h>
#include <math.h>
#include <string.h>
#include <time.h>

#define PERIODS_PER_TAKE 64
#define TRASH_PENDING 16
#define LOCKSTEP_IDLE_NS 20000L /* lockstep without budget: look for ticks every 20 us */

typedef struct {
    twind *d;
    afm_runner *r;
    twind_snapshot snap;
    long long period_count;  /* periods seen (for harmonics_every) */
    afm_runner_model *trash[TRASH_PENDING];
    int n_trash;
    double busy_acc, busy_t0;
} rt_ctx;

static void ts_add(struct timespec *t, double s) {
    long long ns = (long long)t->tv_nsec + llround(s * 1e9);
    t->tv_sec += (time_t)(ns / 1000000000LL);
    ns %= 1000000000LL;
    if (ns < 0) {
        ns += 1000000000LL;
        t->tv_sec--;
    }
    t->tv_nsec = (long)ns;
}

static double ts_sec(const struct timespec *t) { return (double)t->tv_sec + 1e-9 * (double)t->tv_nsec; }

static void trash(rt_ctx *c, afm_runner_model *m) {
    if (!m) return;
    if (c->n_trash < TRASH_PENDING) c->trash[c->n_trash++] = m;
    /* else: leaked rather than blocking; cannot happen with TRASH_PENDING >> swaps/block */
}

static void flush_trash(rt_ctx *c) {
    while (c->n_trash > 0 && afm_spsc_push(&c->d->trash_q, &c->trash[c->n_trash - 1]))
        c->n_trash--;
}

static void rt_reject(rt_ctx *c, const afm_cmd *cmd, const char *why) {
    twind_reason r;
    size_t n = strlen(why);
    const char *kind = afm_cmd_kind_name(cmd->kind);
    size_t k = strlen(kind);
    if (k + 2 + n >= sizeof r.reason) n = sizeof r.reason - k - 3;
    memcpy(r.reason, kind, k);
    r.reason[k] = ':';
    r.reason[k + 1] = ' ';
    memcpy(r.reason + k + 2, why, n);
    r.reason[k + 2 + n] = '\0';
    afm_spsc_push(&c->d->rtrej_q, &r); /* full: the reason is lost, never the loop */
}

static void apply_commands(rt_ctx *c) {
    twind_cmd_item *it;
    while ((it = afm_spsc_peek(&c->d->cmd_q)) != NULL) {
        char err[AFM_ERR_LEN];
        afm_runner_model *m = it->model;
        if (afm_runner_apply(c->r, &it->cmd, m ? &m : NULL, err, sizeof err) != 0)
            rt_reject(c, &it->cmd, err);
        trash(c, m); /* swapped out (applied), or unused (rejected) */
        afm_spsc_release(&c->d->cmd_q);
    }
    flush_trash(c);
}

static void push_outputs(rt_ctx *c) {
    twind *d = c->d;
    afm_runner_status st;
    afm_runner_status_get(c->r, &st);
    int64_t now_us = twind_utime_now();
    for (int s = 0; s < afm_runner_n_streams(c->r); s++) {
        afm_chain_block b;
        while (afm_runner_take_block(c->r, s, &b, AFM_IO_MAX_BLOCK) > 0) {
            afm_io_samples *o = afm_spsc_reserve(&d->samples_q);
            if (!o) {
                c->snap.samples_dropped++;
                continue;
            }
            o->utime = now_us;
            o->seq_applied = st.seq_applied;
            o->stream = s;
            o->t0_s = b.t_s[0];
            o->rate_hz = b.rate_hz;
            o->n = b.n;
            for (int i = 0; i < b.n; i++) {
                o->deflection_m[i] = (float)b.x_m[i];
                o->obd_m[i] = (float)b.obd_m[i];
                o->obd_counts[i] = b.obd_counts ? (int32_t)lrint(b.obd_counts[i]) : 0;
                o->force_n[i] = (float)b.f_n[i];
            }
            afm_spsc_commit(&d->samples_q);
        }
    }
    /* Harmonics: every k-th period, k chosen so that at most harmonics_max_hz go out. */
    int every = d->opt.harmonics_every;
    if (every <= 0) {
        double f = st.fe_hz / (d->opt.harmonics_max_hz > 0 ? d->opt.harmonics_max_hz : 1000.0);
        every = f > 1 ? (int)ceil(f) : 1;
    }
    afm_chain_period p[PERIODS_PER_TAKE];
    int n;
    while ((n = afm_runner_take_periods(c->r, p, PERIODS_PER_TAKE)) > 0) {
        for (int i = 0; i < n; i++) {
            if (c->period_count++ % every != 0) continue;
            afm_io_harmonics *h = afm_spsc_reserve(&d->harm_q);
            if (!h) {
                c->snap.harm_dropped++;
                continue;
            }
            h->utime = now_us;
            h->seq_applied = st.seq_applied;
            h->fe_hz = st.fe_hz;
            h->p = p[i];
            afm_spsc_commit(&d->harm_q);
        }
    }
    sem_post(&d->out_sem); /* wakes the publisher; never blocks */
}

void *twind_rt_main(void *arg) {
    twind *d = arg;
    rt_ctx c = {.d = d, .r = d->runner};
    twind_rt_setup_thread(d->opt.rt_priority, d->opt.cpu, d->rt_warn, sizeof d->rt_warn);
    struct timespec origin, now, deadline;
    clock_gettime(CLOCK_MONOTONIC, &origin);
    long long origin_samples = 0;
    double dt = afm_sim_dt(afm_runner_sim(c.r));
    c.busy_t0 = ts_sec(&origin);
    while (!atomic_load_explicit(&d->stop, memory_order_acquire)) {
        apply_commands(&c);
        dt = afm_sim_dt(afm_runner_sim(c.r)); /* a reload may change the rate */
        long long block = llround(d->opt.block_s / dt);
        if (block < 1) block = 1;
        long long budget = afm_runner_budget(c.r);
        afm_runner_status st;
        if (budget <= 0) {
            /* paused or waiting for ticks: nothing to run; re-anchor pacing */
            afm_runner_status_get(c.r, &st);
            c.snap.st = st;
            c.snap.heartbeat++;
            c.snap.lag_s = 0;
            twind_snap_write(d, &c.snap);
            struct timespec ts = {0, d->opt.mode == TWIND_LOCKSTEP ? LOCKSTEP_IDLE_NS : 1000000L};
            clock_nanosleep(CLOCK_MONOTONIC, 0, &ts, NULL);
            clock_gettime(CLOCK_MONOTONIC, &origin);
            origin_samples = st.samples;
            continue;
        }
        struct timespec t_start;
        clock_gettime(CLOCK_MONOTONIC, &t_start);
        afm_runner_run(c.r, block);
        push_outputs(&c);
        afm_runner_status_get(c.r, &st);
        clock_gettime(CLOCK_MONOTONIC, &now);
        double busy = ts_sec(&now) - ts_sec(&t_start);
        c.busy_acc += busy;
        if (ts_sec(&now) - c.busy_t0 >= 1.0) {
            c.snap.busy_fraction = c.busy_acc / (ts_sec(&now) - c.busy_t0);
            c.busy_acc = 0;
            c.busy_t0 = ts_sec(&now);
        }
        c.snap.st = st;
        c.snap.blocks++;
        c.snap.heartbeat++;
        if (d->opt.mode == TWIND_REALTIME) {
            deadline = origin;
            ts_add(&deadline, (double)(st.samples - origin_samples) * dt);
            double late = ts_sec(&now) - ts_sec(&deadline);
            c.snap.lag_s = late > 0 ? late : 0;
            if (late > 0) c.snap.overruns++;
            twind_snap_write(d, &c.snap);
            if (late < 0) clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &deadline, NULL);
        } else {
            c.snap.lag_s = 0;
            twind_snap_write(d, &c.snap);
        }
    }
    flush_trash(&c);
    atomic_store_explicit(&d->rt_done, 1, memory_order_release);
    sem_post(&d->out_sem);
    return NULL;
}
