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
 * block later (not in lockstep); (iv) when the integrator is idle, after IDLE_WAIT_NS without
 * items; and (v) when a tick or step budget is
 * used up (the runner's completion marker): then the completion follows the outputs into
 * done_q, with the counts of records committed before it, for the publisher to send once
 * those are out. The last period record of every push is finished (amplitude and phase) for
 * the status line's lock-in and peak force. */
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
    long long samples_recs, harm_recs; /* records committed to samples_q, harm_q */
} chain_ctx;

/* The next period records to look at into p, op (the count; 0: none waiting): the ones
 * before the next published one (every k-th) are skipped uncopied (issue 12: the chain
 * publishes one in hundreds, and copying the others cost ~7 instructions a sample), but not
 * the newest waiting (the status's). One at a time then, unless every one is published. */
static int take_periods(chain_ctx *c, int every, afm_chain_period *p, afm_runner_oppoint *op) {
    int w = afm_runner_periods_waiting(c->r);
    long long to_pub = (every - c->period_count % every) % every;
    if (w > 1 && to_pub > 0)
        c->period_count += afm_runner_skip_periods(c->r, to_pub < w - 1 ? (int)to_pub : w - 1);
    return afm_runner_take_periods_raw_op(c->r, p, op, every == 1 ? PERIODS_PER_TAKE : 1);
}

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
            afm_io_samples_from_block(o, &b, now_us, st.seq_applied, &st.op);
            afm_spsc_commit(&d->samples_q);
            c->samples_recs++;
        }
    }
    /* Harmonics: every k-th period, k chosen so that at most harmonics_max_hz go out. */
    int every = afm_io_harmonics_every(d->opt.harmonics_every, st.fe_hz, d->opt.harmonics_max_hz);
    afm_chain_period p[PERIODS_PER_TAKE];
    afm_runner_oppoint op[PERIODS_PER_TAKE]; /* each period's own (its item's) */
    int n, newest = -1; /* p[newest]: the newest record taken (a take of 0 leaves p alone) */
    bool finished = false;
    while ((n = take_periods(c, every, p, op)) > 0) {
        newest = n - 1;
        finished = false;
        for (int i = 0; i < n; i++) {
            if (c->period_count++ % every != 0) continue;
            afm_runner_period_finish(c->r, &p[i]); /* the polar form of the published ones */
            finished = i == newest;
            afm_io_harmonics *h = afm_spsc_reserve(&d->harm_q);
            if (!h) {
                c->snap.harm_dropped++;
                continue;
            }
            afm_io_harmonics_from_period(h, &p[i], st.fe_hz, now_us, st.seq_applied, &op[i]);
            afm_spsc_commit(&d->harm_q);
            c->harm_recs++;
        }
    }
    if (newest >= 0) { /* the newest period, for the status */
        if (!finished) afm_runner_period_finish(c->r, &p[newest]);
        c->snap.have_period = true;
        c->snap.lockin_amplitude_m = p[newest].lockin_amplitude_m;
        c->snap.lockin_phase_deg = p[newest].lockin_phase_deg;
        c->snap.peak_force_n = p[newest].cycle.peak_force_n;
        c->snap.squeeze_dissipated_energy_j = p[newest].cycle.squeeze_dissipated_energy_j;
    }
    c->snap.st = st;
    c->pushed_seq = st.seq_applied;
    c->pushed_t_s = st.t_s;
    c->waiting = false;
    twind_csnap_write(d, &c->snap);
    sem_post(&d->out_sem); /* wakes the publisher; never blocks */
}

/* Rules (i)-(iii) of the header: push now? In lockstep (i) and (ii) only: the completion
 * (v) hands out the rest, and every push is a wake-up of the publisher in the tick's round
 * trip. */
static bool push_due(chain_ctx *c) {
    afm_runner_chain_status st;
    afm_runner_chain_status_get(c->r, &st);
    if (c->d->opt.mode == TWIND_LOCKSTEP)
        return st.t_s - c->pushed_t_s >= c->d->opt.block_s || afm_runner_chain_seq_next(c->r);
    return st.seq_applied != c->pushed_seq || st.t_s - c->pushed_t_s >= c->d->opt.block_s ||
           afm_runner_chain_seq_next(c->r);
}

static double mono(void) {
    return twind_mono_now();
}

/* busy seconds since the last call, at time now: the busy fraction over each second */
static void busy_account(chain_ctx *c, double busy, double now) {
    c->busy_acc += busy;
    if (now - c->busy_t0 < 1.0) return;
    c->snap.busy_fraction = c->busy_acc / (now - c->busy_t0);
    c->busy_acc = 0;
    c->busy_t0 = now;
    twind_csnap_write(c->d, &c->snap);
}

void *twind_chain_main(void *arg) {
    twind_thread_name("afm-chain");
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
        double t0 = mono(), t1 = t0;
        int n;
        for (;;) {
            /* Before a reset (which clears the chain's queues) or a later command's samples,
             * what waits goes out first: also when that item came after the chain slept
             * (push_due below sees only an item already queued). */
            if (afm_runner_chain_seq_next(c.r)) push_outputs(&c);
            if ((n = afm_runner_chain_run(c.r, 1)) <= 0) break;
            c.waiting = true;
            afm_runner_done dn;
            if (afm_runner_take_done(c.r, &dn)) { /* (v) */
                push_outputs(&c);
                twind_done_item it = {dn, c.samples_recs, c.harm_recs};
                afm_spsc_push(&d->done_q, &it); /* full: lost (1024 waiting), never blocks */
                sem_post(&d->out_sem);
            } else if (push_due(&c)) {
                push_outputs(&c);
            }
            t1 = mono(); /* busy time item by item: the loop may not end for long when behind */
            busy_account(&c, t1 - t0, t1);
            t0 = t1;
        }

        t1 = mono();
        busy_account(&c, t1 - t0, t1);
        if (atomic_load_explicit(&d->rt_done, memory_order_acquire)) {
            /* The integrator has stopped: take what it left, then stop. */
            while (afm_runner_chain_run(c.r, ITEMS_PER_TURN) > 0)
                push_outputs(&c);
            break;
        }
        struct timespec ts = twind_deadline_in(IDLE_WAIT_NS);
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
