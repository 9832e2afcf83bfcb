/* SPDX-License-Identifier: MIT */
/* chain_loop.c -- the output-chain thread: the second stage of the real-time pipeline.
 * Takes the sample blocks the integrator thread put into the runner's ring through the
 * output chain (OBD, decimators, estimators: afm_runner_chain_run), and pushes samples and
 * harmonics records to the publish thread's rings.
 *
 * Never locks or allocates; its only wait is sem_timedwait on chain_sem while the ring is
 * empty (the integrator posts it after every ring item), so it sleeps exactly when there
 * is nothing to do. Records carry the seq_applied of the samples they come from: the runner
 * stops before samples of a later command, and the records waiting are pushed first.
 *
 * When outputs go out: items are processed one at a time as they arrive, and what they
 * produced is handed to the publisher (i) once a block (block_s of model time) has
 * accumulated, (ii) right before samples of a later command (so no message mixes two
 * commands), and (iii) right after the first item of a new command, so that a controller
 * sees the effect of its command about one item (73 us) after it is applied rather than a
 * block later; and (iv) when the integrator is idle: in lockstep whenever the ring is
 * empty (the ticks so far are done), otherwise after IDLE_WAIT_NS without items. */
#include "twind.h"

#include <errno.h>
#include <math.h>
#include <string.h>
#include <time.h>

#define PERIODS_PER_TAKE 64
#define ITEMS_PER_TURN 8       /* ring items (8 x 1024 samples) per turn at stop */
#define IDLE_WAIT_NS 10000000L /* look at the stop flag every 10 ms when idle */

typedef struct {
    twind *d;
    afm_runner *r;
    twind_chain_snapshot snap;
    long long period_count; /* periods seen (for harmonics_every) */
    int64_t pushed_seq;     /* seq_applied at the last push */
    double pushed_t_s;      /* model time of the last sample processed at the last push */
    bool waiting;           /* items processed since the last push */
    double busy_acc, busy_t0;
} chain_ctx;

static void push_outputs(chain_ctx *c) {
    twind *d = c->d;
    afm_runner_chain_status st;
    afm_runner_chain_status_get(c->r, &st);
    int64_t now_us = twind_utime_now();
    for (int s = 0; s < afm_runner_n_streams(c->r); s++) {
        afm_chain_block b;
        while (afm_runner_take_block(c->r, s, &b, AFM_IO_MAX_BLOCK) > 0) {
            afm_io_samples *o = afm_spsc_reserve(&d->samples_q);
            if (!o) {
                c->snap.samples_dropped++;
                continue;
            }
            afm_io_samples_from_block(o, &b, now_us, st.seq_applied);
            afm_spsc_commit(&d->samples_q);
        }
    }
    /* Harmonics: every k-th period, k chosen so that at most harmonics_max_hz go out. */
    int every = d->opt.harmonics_every;
    if (every <= 0) {
        double f = st.fe_hz / (d->opt.harmonics_max_hz > 0 ? d->opt.harmonics_max_hz : 1000.0);
        every = f > 1 ? (f < 1e9 ? (int)ceil(f) : 1000000000) : 1; /* no int overflow */
    }
    afm_chain_period p[PERIODS_PER_TAKE];
    int n;
    while ((n = afm_runner_take_periods_raw(c->r, p, PERIODS_PER_TAKE)) > 0) {
        for (int i = 0; i < n; i++) {
            if (c->period_count++ % every != 0) continue;
            afm_runner_period_finish(c->r, &p[i]); /* the polar form of the published ones */
            afm_io_harmonics *h = afm_spsc_reserve(&d->harm_q);
            if (!h) {
                c->snap.harm_dropped++;
                continue;
            }
            afm_io_harmonics_from_period(h, &p[i], st.fe_hz, now_us, st.seq_applied);
            afm_spsc_commit(&d->harm_q);
        }
    }
    c->snap.st = st;
    c->pushed_seq = st.seq_applied;
    c->pushed_t_s = st.t_s;
    c->waiting = false;
    twind_csnap_write(d, &c->snap);
    sem_post(&d->out_sem); /* wakes the publisher; never blocks */
}

/* Rules (i)-(iii) of the header: push now? */
static bool push_due(chain_ctx *c) {
    afm_runner_chain_status st;
    afm_runner_chain_status_get(c->r, &st);
    return st.seq_applied != c->pushed_seq || st.t_s - c->pushed_t_s >= c->d->opt.block_s ||
           afm_runner_chain_seq_next(c->r);
}

static double mono(void) {
    return twind_mono_now();
}

void *twind_chain_main(void *arg) {
    twind *d = arg;
    chain_ctx c = {.d = d, .r = d->runner, .pushed_seq = -1};
    char warn[256] = "";
    /* Below the publish and receive threads (rt_priority - 10): on a two-core machine the
     * two pipeline stages fill both cores when behind, and outputs and commands must still
     * get through; the integrator stays on top. */
    twind_rt_setup_thread(d->opt.rt_priority > 21 ? d->opt.rt_priority - 20 : 1, d->opt.chain_cpu,
                          warn, sizeof warn);
    c.busy_t0 = mono();
    afm_runner_chain_status_get(c.r, &c.snap.st);
    twind_csnap_write(d, &c.snap);
    for (;;) {
        double t0 = mono();
        int n, any = 0;
        while ((n = afm_runner_chain_run(c.r, 1)) > 0) {
            any = 1;
            c.waiting = true;
            if (push_due(&c)) push_outputs(&c);
        }
        /* (iv) in lockstep: the ring is empty, so the ticks so far are all done */
        if (c.waiting && d->opt.mode == TWIND_LOCKSTEP) push_outputs(&c);
        double t1 = mono();
        if (any) c.busy_acc += t1 - t0;
        if (t1 - c.busy_t0 >= 1.0) {
            c.snap.busy_fraction = c.busy_acc / (t1 - c.busy_t0);
            c.busy_acc = 0;
            c.busy_t0 = t1;
            twind_csnap_write(d, &c.snap);
        }
        if (atomic_load_explicit(&d->rt_done, memory_order_acquire)) {
            /* The integrator has stopped: take what it left, then stop. */
            while (afm_runner_chain_run(c.r, ITEMS_PER_TURN) > 0)
                push_outputs(&c);
            break;
        }
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts); /* sem_timedwait takes CLOCK_REALTIME */
        ts.tv_nsec += IDLE_WAIT_NS;
        if (ts.tv_nsec >= 1000000000L) {
            ts.tv_sec++;
            ts.tv_nsec -= 1000000000L;
        }
        int w;
        while ((w = sem_timedwait(&d->chain_sem, &ts)) != 0 && errno == EINTR) {
        }
        /* (iv): nothing came for IDLE_WAIT_NS (paused, single steps) */
        if (w != 0 && c.waiting) push_outputs(&c);
    }
    push_outputs(&c);
    atomic_store_explicit(&d->chain_done, 1, memory_order_release);
    sem_post(&d->out_sem);
    return NULL;
}
