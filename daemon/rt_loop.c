/* SPDX-License-Identifier: MIT */
/* rt_loop.c -- the real-time (integrator) thread: commands in at block boundaries, one block
 * of the twin integrated into the runner's ring for the chain thread, then wait for the
 * block's absolute deadline or a command, whichever comes first (realtime mode).
 *
 * The block is run one ring item (AFM_RUNNER_SLOT_SAMPLES) at a time, with the chain
 * thread woken and the command queue read after each, so that a command reaches the
 * outputs about one item after it arrives, not one block.
 *
 * Commands during the wait (the setpoint -> first samples latency; docs/realtime.md, "A
 * command's latency"): the integrator runs a block in a fraction of its wall time, then
 * waits, ahead of wall time, for the block's deadline; a command that came then waited
 * for the deadline too (up to a block: the median of bench-daemon's latency was 1.02 ms at
 * --block-us 1000). The wait is now sem_clockwait on cmd_sem (posted with every command
 * queued) with the same absolute deadline: a command wakes the loop, which applies it and
 * runs on at once, but never further ahead of wall time than one block (the lead the
 * block rhythm allowed before): the turn runs what fits under that, at least one item,
 * first waiting (clock_nanosleep) until one item fits. So a command costs one wake-up of
 * this thread; without commands it wakes once a block as before, and a stream of
 * commands at most once per batch of the receive thread.
 *
 * Never blocks, locks or allocates: queues are lock-free SPSC, the runner allocates nothing
 * after create, clock_nanosleep and the waits on cmd_sem are the only waits (their deadlines
 * are absolute, so jitter does not accumulate), sem_post the only signal. Pacing in
 * realtime mode: model time is tied to
 * CLOCK_MONOTONIC by an origin (wall = origin + samples dt / speed); the deadline of a
 * block is the wall time its last sample represents. A block that ends after its deadline
 * is an overrun; the loop then runs on without sleeping to catch up (lag_s says how far
 * behind it is). Resync: when the lag passes max_lag_s, the backlog is dropped (the origin
 * moves to now), counted in resyncs and reported in status; so a twin that cannot keep up
 * runs as fast as it can with a bounded lag instead of a lag that grows without end.
 * When the chain thread is behind (the ring is full) the runner advances less than asked:
 * the loop naps (an eighth of the ring, 20-200 us) and tries again (counted in
 * status.chain_stalls); the naps do not count as busy.
 * Pausing (or waiting for ticks) re-anchors the origin, so nothing is "caught up" later;
 * then the thread waits on cmd_sem (posted with every command queued), so that a tick or a
 * run starts as soon as it arrives. The real-time factor of the status is model time over
 * wall time of the last second of running turns (RTF_BUCKETS buckets of RTF_BUCKET_S,
 * sliding): paused and idle turns do not count, a turn that fell behind does.
 * Sharing the CPU: at SCHED_FIFO 80 a loop that never waits (a twin behind real time whose
 * chain keeps up, or freerun) keeps every thread below it off its CPU: where the receive,
 * publish and main threads share it (`--aux-cpu` = `--cpu`, or one core) no command was
 * taken, nothing published and SIGTERM not handled (measured: a pinned daemon behind real
 * time ran on for 10 minutes). So after SHARE_AFTER_S without a wait the loop naps
 * SHARE_NAP_NS: at most 2 % of a twin that is behind anyway, nothing while it keeps up. */
#define _GNU_SOURCE /* sem_clockwait (glibc 2.30) */
#include "twind.h"

#include <errno.h>

#include <limits.h>
#include <math.h>
#include <string.h>
#include <time.h>

#define TRASH_PENDING 16
#define IDLE_WAIT_NS 10000000L /* no budget: wait this long for a command at most (heartbeat) */
/* Ring full: let the chain thread work an eighth of the ring's model time, within these
 * bounds (issue 12: the 20 us nap of before woke this thread ~26 000 times a second while the
 * chain was behind, and where the two shared a core each wake-up preempted the chain; the
 * ring still holds 7/8 of its items for the chain when the nap ends). */
#define CHAIN_WAIT_MIN_NS 20000L
#define CHAIN_WAIT_MAX_NS 200000L
#define SHARE_AFTER_S 0.05
#define SHARE_NAP_NS 1000000L
#define RTF_BUCKETS 10
#define RTF_BUCKET_S 0.1

typedef struct {
    twind *d;
    afm_runner *r;
    twind_snapshot snap;
    afm_runner_model *trash[TRASH_PENDING];
    int n_trash;
    double busy_acc, busy_t0; /* busy: the turns' wall time less the naps for the chain */
    /* real-time factor: wall and model seconds of running turns, per bucket */
    double rtf_wall[RTF_BUCKETS], rtf_model[RTF_BUCKETS], cur_wall, cur_model;
    int rtf_next, rtf_full;
    double last_end;  /* wall time at the end of the previous turn */
    double waited_at; /* wall time this thread last waited (any wait) */
} rt_ctx;

/* A running turn that ended at `now` and advanced model_s: into the buckets; rtf_1s from
 * the last whole second of them. */
static void rtf_account(rt_ctx *c, double now, double model_s) {
    c->cur_wall += now - c->last_end;
    c->cur_model += model_s;
    if (c->cur_wall < RTF_BUCKET_S) return;
    c->rtf_wall[c->rtf_next] = c->cur_wall;
    c->rtf_model[c->rtf_next] = c->cur_model;
    c->rtf_next = (c->rtf_next + 1) % RTF_BUCKETS;
    if (c->rtf_full < RTF_BUCKETS) c->rtf_full++;
    c->cur_wall = c->cur_model = 0;
    if (c->rtf_full < RTF_BUCKETS) return;
    double w = 0, m = 0;
    for (int i = 0; i < RTF_BUCKETS; i++) {
        w += c->rtf_wall[i];
        m += c->rtf_model[i];
    }
    c->snap.rtf_1s = m / w;
}

static void ts_add(struct timespec *t, double s) {
    if (!(s < 1e9)) s = 1e9; /* 31 years: no llround overflow, whatever the sample rate */
    if (s < -1e9) s = -1e9;
    long long ns = (long long)t->tv_nsec + llround(s * 1e9);
    t->tv_sec += (time_t)(ns / 1000000000LL);
    ns %= 1000000000LL;
    if (ns < 0) {
        ns += 1000000000LL;
        t->tv_sec--;
    }
    t->tv_nsec = (long)ns;
}

static double ts_sec(const struct timespec *t) {
    return (double)t->tv_sec + 1e-9 * (double)t->tv_nsec;
}

/* Models of commands this thread rejected go back to the receive thread for destruction
 * (swapped-out ones come from the runner's trash, via the chain thread). */
static void trash(rt_ctx *c, afm_runner_model *m) {
    if (!m) return;
    if (c->n_trash < TRASH_PENDING) c->trash[c->n_trash++] = m;
    /* else: leaked rather than blocking; cannot happen with TRASH_PENDING >> rejects/block */
}

static void flush_trash(rt_ctx *c) {
    while (c->n_trash > 0 && afm_spsc_push(&c->d->trash_q, &c->trash[c->n_trash - 1]))
        c->n_trash--;
}

/* The twin refused a valid command: counted here (exact), the reason to the receive
 * thread (best effort: a full queue loses the reason, counted too, never the count). */
static void rt_reject(rt_ctx *c, const afm_cmd *cmd, const char *why, int64_t order) {
    twind_reason r = {.order = order, .seq = cmd->seq};
    c->snap.refused++;
    size_t n = strlen(why);
    const char *kind = afm_cmd_kind_name(cmd->kind);
    size_t k = strlen(kind);
    if (k + 2 + n >= sizeof r.reason) n = sizeof r.reason - k - 3;
    memcpy(r.reason, kind, k);
    r.reason[k] = ':';
    r.reason[k + 1] = ' ';
    memcpy(r.reason + k + 2, why, n);
    r.reason[k + 2 + n] = '\0';
    if (!afm_spsc_push(&c->d->rtrej_q, &r)) c->snap.reasons_lost++; /* never the loop */
}

/* A model swapped in (damping, geometry, reload) starts in its config's scheme: the one in
 * force goes on at the same sample (without this, the rest of the turn ran in the config's
 * until twind_scheme_turn handed it back: --scheme fast ran accurate samples), and the applied
 * log says so after the command, so that a replay follows. */
static void keep_scheme(rt_ctx *c, long long sample) {
    twind *d = c->d;
    if (!d->scheme.rt) return;
    bool acc = !strcmp(afm_sim_scheme_name(afm_runner_sim(c->r)), "accurate");
    if (acc != d->scheme.accurate && afm_runner_set_scheme(c->r, d->scheme.accurate) == 0)
        twind_applied_scheme(d, d->scheme.accurate, sample);
}

static void apply_commands(rt_ctx *c) {
    twind_cmd_item *it;
    while ((it = afm_spsc_peek(&c->d->cmd_q)) != NULL) {
        char err[AFM_ERR_LEN];
        afm_runner_model *m = it->model;
        int rc = afm_runner_apply(c->r, &it->cmd, m ? &m : NULL, err, sizeof err);
        if (rc == AFM_RUNNER_EBUSY) break; /* the chain is behind: this one again next item */
        if (rc != 0) {
            rt_reject(c, &it->cmd, err, it->order);
        } else {
            c->snap.last_applied_order = it->order;
            afm_runner_status st = {0};
            if (c->d->applied.log) { /* --applied-log: at the samples run before it */
                afm_runner_status_get(c->r, &st);
                twind_applied_cmd(c->d, &it->cmd, st.samples);
            }
            if (it->model) keep_scheme(c, st.samples);
        }
        trash(c, m); /* unused (rejected); NULL when applied (it went to the chain thread) */
        afm_cmd_kind k = it->cmd.kind;
        afm_spsc_release(&c->d->cmd_q);
        if (k == AFM_CMD_PARAM || k == AFM_CMD_RELOAD) { /* the receive thread waits on it */
            atomic_store_explicit(&c->d->mc_last_ok, rc == 0, memory_order_relaxed);
            atomic_fetch_add_explicit(&c->d->mc_done, 1, memory_order_release);
        }
    }
    flush_trash(c);
}

/* After SHARE_AFTER_S of running without a wait, one nap of SHARE_NAP_NS for the threads
 * below this one on its CPU (the top comment). */
static void share_cpu(rt_ctx *c) {
    struct timespec n;
    clock_gettime(CLOCK_MONOTONIC, &n);
    if (ts_sec(&n) - c->waited_at < SHARE_AFTER_S) return;
    struct timespec w = {0, SHARE_NAP_NS};
    clock_nanosleep(CLOCK_MONOTONIC, 0, &w, NULL);
    clock_gettime(CLOCK_MONOTONIC, &n);
    c->waited_at = ts_sec(&n);
}

/* Until the absolute CLOCK_MONOTONIC deadline or a queued command, whichever is first: ahead
 * of wall time (realtime mode) to the block's deadline, and idle (paused, waiting for ticks)
 * for IDLE_WAIT_NS. The posts of commands taken while running are stale: dropped first; then
 * the wait only if none is queued (one queued after the check posts, the wait returns at
 * once). */
static void wait_deadline(twind *d, const struct timespec *deadline) {
    while (sem_trywait(&d->cmd_sem) == 0) {
    }
    if (afm_spsc_peek(&d->cmd_q)) return;
    while (sem_clockwait(&d->cmd_sem, CLOCK_MONOTONIC, deadline) != 0 && errno == EINTR) {
    }
}

void *twind_rt_main(void *arg) {
    twind_thread_name("afm-rt");
    twind *d = arg;
    rt_ctx c = {.d = d, .r = d->runner};
    c.snap.scheme_accurate = d->scheme.accurate;
    twind_rt_setup_thread(d->opt.rt_priority, d->opt.cpu, d->rt_warn, sizeof d->rt_warn);
    struct timespec origin, now, deadline;
    clock_gettime(CLOCK_MONOTONIC, &origin);
    long long origin_samples = 0;
    double speed = d->opt.speed > 0 ? d->opt.speed : 1.0;
    c.busy_t0 = c.last_end = c.waited_at = ts_sec(&origin);
    long chain_wait_ns = (long)(d->opt.ring_s / 8 * 1e9);
    if (chain_wait_ns < CHAIN_WAIT_MIN_NS) chain_wait_ns = CHAIN_WAIT_MIN_NS;
    if (chain_wait_ns > CHAIN_WAIT_MAX_NS) chain_wait_ns = CHAIN_WAIT_MAX_NS;
    while (!atomic_load_explicit(&d->stop, memory_order_acquire)) {
        apply_commands(&c);
        double dt = afm_sim_dt(afm_runner_sim(c.r)); /* a reload may change the rate */
        long long block = llround(d->opt.block_s * speed / dt);
        if (block < 1) block = 1;
        long long budget = afm_runner_budget(c.r);
        afm_runner_status st;
        if (budget <= 0) {
            /* paused or waiting for ticks: nothing to run; a completion that waited for ring
             * space goes in; wait for the next command; re-anchor pacing */
            afm_runner_run(c.r, 0);
            sem_post(&d->chain_sem);
            afm_runner_status_get(c.r, &st);
            c.snap.st = st;
            c.snap.heartbeat++;
            c.snap.lag_s = 0;
            twind_snap_write(d, &c.snap);
            struct timespec ts; /* IDLE_WAIT_NS at most: a heartbeat, the stop flag */
            clock_gettime(CLOCK_MONOTONIC, &ts);
            ts_add(&ts, IDLE_WAIT_NS * 1e-9);
            wait_deadline(d, &ts);
            clock_gettime(CLOCK_MONOTONIC, &origin);
            origin_samples = st.samples;
            c.last_end = c.waited_at = ts_sec(&origin);
            continue;
        }
        struct timespec t_start;
        clock_gettime(CLOCK_MONOTONIC, &t_start);
        /* A whole block, one ring item at a time: the chain thread starts on each item as
         * soon as it is made, and commands that arrive meanwhile apply at the next item
         * (73 us of model time at 14.06 MHz) instead of the next block. */
        long long left = block < budget ? block : budget;
        if (d->opt.mode == TWIND_REALTIME) {
            /* Ahead of wall time (a turn woken early by a command): no further than one
             * block ahead; at least one item (or the block), waiting for room if need be. */
            double ahead_s = ts_sec(&origin) +
                             (double)(c.snap.st.samples - origin_samples) * dt / speed -
                             ts_sec(&t_start);
            long long cap = llround((d->opt.block_s - ahead_s) * speed / dt);
            if (cap < left) {
                long long least = left < AFM_RUNNER_SLOT_SAMPLES ? left : AFM_RUNNER_SLOT_SAMPLES;
                if (cap < least) {
                    struct timespec until = origin;
                    ts_add(&until,
                           (double)(c.snap.st.samples + least - origin_samples) * dt / speed -
                               d->opt.block_s);
                    clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &until, NULL);
                    apply_commands(&c); /* those that came meanwhile: at this item too */
                    clock_gettime(CLOCK_MONOTONIC, &t_start);
                    cap = least;
                }
                left = cap;
            }
        }
        double napped = 0; /* waiting for ring space is not busy */
        while (left > 0 && !atomic_load_explicit(&d->stop, memory_order_relaxed)) {
            long long piece = left < AFM_RUNNER_SLOT_SAMPLES ? left : AFM_RUNNER_SLOT_SAMPLES;
            long long adv = afm_runner_run(c.r, piece);
            if (adv > 0) sem_post(&d->chain_sem); /* wakes the chain thread; never blocks */
            left -= adv;
            if (left <= 0) break;
            if (afm_runner_budget(c.r) <= 0) break; /* budget used up (step / tick) */
            if (adv < piece) {                      /* the chain thread is behind: let it work */
                struct timespec w = {0, chain_wait_ns}, n0, n1;
                clock_gettime(CLOCK_MONOTONIC, &n0);
                clock_nanosleep(CLOCK_MONOTONIC, 0, &w, NULL);
                clock_gettime(CLOCK_MONOTONIC, &n1);
                napped += ts_sec(&n1) - ts_sec(&n0);
                c.waited_at = ts_sec(&n1);
                continue;
            }
            apply_commands(&c);
            long long b2 = afm_runner_budget(c.r);
            if (b2 <= 0) break; /* paused by a command */
            if (left > b2) left = b2;
        }
        long long before = c.snap.st.samples;
        afm_runner_status_get(c.r, &st);
        clock_gettime(CLOCK_MONOTONIC, &now);
        double busy = ts_sec(&now) - ts_sec(&t_start) - napped;
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
            ts_add(&deadline, (double)(st.samples - origin_samples) * dt / speed);
            double late = ts_sec(&now) - ts_sec(&deadline);
            c.snap.lag_s = late > 0 ? late : 0;
            if (late > 0) c.snap.overruns++;
            twind_scheme_turn(d, c.r, &c.snap, late, (double)(st.samples - before) * dt,
                              ts_sec(&now));
            if (late > d->opt.max_lag_s) {
                /* Resync: drop the backlog of deadlines; model time goes on from here. */
                c.snap.resyncs++;
                c.snap.resync_dropped_s += late * speed;
                origin = now;
                origin_samples = st.samples;
                late = 0;
            }
            twind_snap_write(d, &c.snap);
            if (late < 0) {
                wait_deadline(d, &deadline);
                clock_gettime(CLOCK_MONOTONIC, &now);
                c.waited_at = ts_sec(&now);
            }
        } else {
            c.snap.lag_s = 0;
            twind_scheme_turn(d, c.r, &c.snap, 0.0, (double)(st.samples - before) * dt,
                              ts_sec(&now));
            twind_snap_write(d, &c.snap);
        }
        share_cpu(&c);
        clock_gettime(CLOCK_MONOTONIC, &now); /* after the sleep: the turn's whole wall time */
        rtf_account(&c, ts_sec(&now), (double)(st.samples - before) * dt);
        c.last_end = ts_sec(&now);
    }
    flush_trash(&c);
    atomic_store_explicit(&d->rt_done, 1, memory_order_release);
    sem_post(&d->chain_sem);
    return NULL;
}
