/* SPDX-License-Identifier: MIT */
/* cmd_in.c -- the receive thread: commands from the transport are checked against the
 * daemon's copy of the config; the models that damping/geometry changes, SIGHUP reloads and
 * dithers under the internal AM Z loop bring are built on the build worker
 * (build_worker.c: off the real-time threads and off this one, the commands behind waiting
 * in order in the hold ring); everything goes to the RT thread in order through cmd_q; each
 * change of the config or of tone 0 of the drive asks for A0 anew (a0_track.c). Also
 * destroys what the RT thread swapped out, and counts every message once (twind.h,
 * "Accounting"). */
#include "twind.h"

#include <stdio.h>
#include <string.h>
#include <math.h>
#include <time.h>

#define MODEL_WAIT_MS 20 /* longest wait for the model change in flight before the next */
#define QUEUE_WAIT_MS 50 /* longest wait for room in a full cmd_q before a refusal */
#define IDLE_POLL_MS 50  /* no stream: block in the transport's poll this long at most */

/* Count one reason (counter may be NULL: counted elsewhere) and print it, at most
 * TWIND_REASON_LINES_PER_S lines a second; the rest are summed up by main. */
static void count_reason(twind *d, long long *counter, char *last, const char *what,
                         const char *reason) {
    double now = twind_mono_now();
    pthread_mutex_lock(&d->lock);
    if (counter) (*counter)++;
    snprintf(last, AFM_IO_REASON_LEN, "%s", reason);
    if (now - d->lines_t0 >= 1.0) {
        d->lines_t0 = now;
        d->lines_n = 0;
    }
    bool print = !d->opt.quiet && d->lines_n < TWIND_REASON_LINES_PER_S;
    if (print)
        d->lines_n++;
    else if (!d->opt.quiet)
        d->lines_quiet++;
    pthread_mutex_unlock(&d->lock);
    if (print) fprintf(stderr, "afmtwind: %s: %s\n", what, reason);
}

void twind_refuse(twind *d, const char *reason) {
    count_reason(d, &d->refused, d->last_refusal, "refused", reason);
}

void twind_reject_order(twind *d, const char *reason, int64_t order) {
    count_reason(d, &d->rejected, d->last_reject, "rejected", reason);
    double now = twind_mono_now();
    pthread_mutex_lock(&d->lock);
    d->last_reject_order = order;
    d->last_reject_mono = now;
    pthread_mutex_unlock(&d->lock);
}

void twind_reject(twind *d, const char *reason) {
    twind_reject_order(d, reason, d->order);
}

/* A reason about a decoded command ends with " [seq N]" (not reloads: seq < 0), so that a
 * sender (afmtwin send --wait) finds the rejection of its own command in the status. */
static const char *tag_seq(char *buf, size_t len, const char *reason, int64_t seq) {
    if (seq < 0) return reason;
    snprintf(buf, len, "%.*s [seq %lld]", (int)(len - 32), reason, (long long)seq);
    return buf;
}

static void reject_cmd(twind *d, const afm_cmd *c, const char *reason) {
    char b[AFM_IO_REASON_LEN];
    twind_reject_order(d, tag_seq(b, sizeof b, reason, c->seq), d->cmd_order);
}

static void refuse_cmd(twind *d, const afm_cmd *c, const char *reason) {
    char b[AFM_IO_REASON_LEN];
    twind_refuse(d, tag_seq(b, sizeof b, reason, c->seq));
}

static void count_received(twind *d) {
    pthread_mutex_lock(&d->lock);
    d->received++;
    pthread_mutex_unlock(&d->lock);
    d->order++;
}

/* Push a command (and its model) to the RT thread. The queue holds CMD_Q_LEN commands
 * (afmtwind.c: 0.8 s of a 10 kHz stream, far more than the lag a resync drops); full, the
 * receive thread waits up to QUEUE_WAIT_MS for room (the commands behind wait in the
 * transport), then refuses (the RT thread is stopped or far behind). The RT thread never
 * waits on it. */
static int enqueue(twind *d, const afm_cmd *c, afm_runner_model *m, const char *what) {
    twind_cmd_item it = {.cmd = *c, .model = m, .order = d->cmd_order};
    bool in = afm_spsc_push(&d->cmd_q, &it);
    for (int i = 0; !in && i < QUEUE_WAIT_MS * 10; i++) {
        if (atomic_load_explicit(&d->stop, memory_order_acquire)) break;
        struct timespec ts = {0, 100000L};
        nanosleep(&ts, NULL);
        in = afm_spsc_push(&d->cmd_q, &it);
    }
    if (!in) {
        char why[AFM_IO_REASON_LEN];
        snprintf(why, sizeof why, "%s: command queue full (%zu waiting); not applied", what,
                 afm_spsc_capacity(&d->cmd_q));
        afm_runner_model_destroy(&m);
        refuse_cmd(d, c, why);
        return -1;
    }
    sem_post(&d->cmd_sem); /* wakes an idle RT thread (lockstep, paused); never blocks */
    return 0;
}

/* Wait (up to wait_ms) until the rt thread has taken or refused every model change sent;
 * then, if the last one was refused, put the shadow back. true when none is in flight. */
static bool model_changes_settled(twind *d, int wait_ms) {
    for (int i = 0;; i++) {
        if (atomic_load_explicit(&d->mc_done, memory_order_acquire) ==
            atomic_load_explicit(&d->mc_sent, memory_order_relaxed))
            break;
        if (i >= wait_ms * 20) return false;
        struct timespec ts = {0, 50000L};
        nanosleep(&ts, NULL);
    }
    if (d->mc_unchecked) {
        if (!atomic_load_explicit(&d->mc_last_ok, memory_order_acquire)) {
            d->shadow = d->shadow_before;
            d->shadow_model = d->shadow_model_before;
            twind_a0_request(d, &d->shadow, &d->drive_now, true);
        }
        d->mc_unchecked = false;
    }
    return true;
}

/* Enqueue a model change (param or reload) leading to next (with model m, or NULL: the
 * model stays); the shadow follows once it is in the queue. */
static int enqueue_model_change(twind *d, const afm_cmd *c, afm_runner_model *m,
                                const afm_config *next, const char *what) {
    d->shadow_before = d->shadow;
    d->shadow_model_before = d->shadow_model;
    atomic_fetch_add_explicit(&d->mc_sent, 1, memory_order_relaxed); /* before rt can see it */
    const afm_modal *mm = afm_runner_model_modal(m);
    if (mm) d->shadow_model = *mm; /* m travels to the rt thread: copy first */
    if (enqueue(d, c, m, what)) {
        atomic_fetch_sub_explicit(&d->mc_sent, 1, memory_order_relaxed);
        d->shadow_model = d->shadow_model_before;
        return -1;
    }
    d->shadow = *next;
    d->mc_unchecked = true;
    return 0;
}

/* The drive after a dither command, as afm_runner applies it: tones the command names set,
 * running tones it leaves out fall silent (amplitude 0, still running). */
static void follow_dither(twind *d, const afm_cmd_dither *c) {
    afm_cmd_dither *r = &d->drive_now;
    for (int j = 0; j < c->n_tones; j++) {
        r->frequency_hz[j] = c->frequency_hz[j];
        r->amplitude_m[j] = c->amplitude_m[j];
        if (j >= r->n_tones) r->phase_rad[j] = c->phase_rad[j];
    }
    for (int j = c->n_tones; j < r->n_tones; j++)
        r->amplitude_m[j] = 0;
    if (c->n_tones > r->n_tones) r->n_tones = c->n_tones;
    d->drive_gen++;
}

static void drive_from_config(twind *d, const afm_cfg_drive *dr) {
    memset(&d->drive_now, 0, sizeof d->drive_now);
    d->drive_now.n_tones = dr->n_tones;
    for (int j = 0; j < dr->n_tones && j < AFM_MAX_TONES; j++) {
        d->drive_now.frequency_hz[j] = dr->tones[j].frequency_hz;
        d->drive_now.amplitude_m[j] = dr->tones[j].amplitude_m;
        d->drive_now.phase_rad[j] = dr->tones[j].phase_rad;
    }
    d->drive_gen++;
}

/* A dither applied: the receive thread's copy of the drive follows, and A0 is asked for
 * anew if tone 0 changed (a0_track.c). */
static void dither_queued(twind *d, const afm_cmd *c) {
    follow_dither(d, &c->u.dither);
    twind_a0_request(d, &d->shadow, &d->drive_now, false);
}

/* A param applied: A0 is asked for anew unless only Z moved (A0 is at Z = 1 um whatever the
 * set-point). */
static void param_queued(twind *d, afm_param_effect eff) {
    if (eff != AFM_PARAM_SEPARATION) twind_a0_request(d, &d->shadow, &d->drive_now, true);
}

/* Hand a command's model to the build worker: the command waits for it, and the commands
 * after it in the hold ring (held_resume). */
static void build_submit(twind *d, const afm_cmd *c, twind_build_kind kind, const afm_config *cfg,
                         const afm_cmd_dither *drive, bool new_chain, afm_param_effect eff) {
    d->bw.waiting = (twind_held){.cmd = *c, .order = d->cmd_order};
    d->bw.eff = eff;
    twind_bw_submit(d, kind, cfg, drive, new_chain);
}

/* One command, in arrival order (d->cmd_order its order): checked against the shadow and
 * queued for the RT thread; one that needs a model (a param of damping or geometry, a dither
 * that moves the internal AM loop's A0) goes to the build worker (build_worker.c) and waits
 * there, and the commands after it wait in the hold ring (held_resume). */
static int handle_cmd(twind *d, const afm_cmd *c) {
    char err[AFM_ERR_LEN], why[AFM_IO_REASON_LEN];
    const char *kind = afm_cmd_kind_name(c->kind);
    if (c->kind == AFM_CMD_TICK && d->opt.mode != TWIND_LOCKSTEP) {
        snprintf(why, sizeof why, "tick: the daemon runs in %s mode, not lockstep",
                 twind_mode_name(d->opt.mode));
        reject_cmd(d, c, why);
        return -1;
    }
    if (c->kind != AFM_CMD_PARAM) {
        /* A dither that moves tone 0 under the internal AM Z loop brings the new free
         * amplitude A0 (the loop's reference), computed off the real-time threads and off
         * this one: on the A0 worker, the dither and what follows it waiting meanwhile. */
        if (afm_runner_dither_moves_a0(&d->shadow, &d->drive_now, c)) {
            build_submit(d, c, TWIND_BUILD_A0, &d->shadow, &c->u.dither, false,
                         AFM_PARAM_SEPARATION /* unused */);
            return 0;
        }
        if (enqueue(d, c, NULL, kind)) return -1;
        if (c->kind == AFM_CMD_DITHER) dither_queued(d, c);
        return 0;
    }
    if (!model_changes_settled(d, MODEL_WAIT_MS)) {
        refuse_cmd(d, c,
                   "param: the twin is still applying the previous model change; not "
                   "applied");
        return -1;
    }
    afm_config next = d->shadow;
    afm_param_effect eff;
    if (afm_param_apply(&next, &c->u.param, &eff, err, sizeof err)) {
        reject_cmd(d, c, err);
        return -1;
    }
    bool new_chain = false;
    if (afm_runner_cmd_needs_model(&d->shadow, c, &new_chain)) {
        build_submit(d, c, TWIND_BUILD_MODEL, &next, &d->drive_now, new_chain, eff);
        return 0;
    }
    if (enqueue_model_change(d, c, NULL, &next, kind)) return -1;
    param_queued(d, eff);
    return 0;
}

static void reload_built(twind *d, afm_runner_model *m, const char *err);

/* The build in flight is done: its command goes to the RT thread with the model, or is
 * rejected with the build's reason. */
static void build_done(twind *d, afm_runner_model *m, const char *err) {
    twind_bw *b = &d->bw;
    const afm_cmd *c = &b->waiting.cmd;
    const char *kind = afm_cmd_kind_name(c->kind);
    char why[AFM_IO_REASON_LEN];
    d->cmd_order = b->waiting.order;
    switch (b->kind) {
    case TWIND_BUILD_A0:
        if (!m) {
            snprintf(why, sizeof why, "dither: cannot compute the new A0: %.200s", err);
            reject_cmd(d, c, why);
        } else if (enqueue(d, c, m, kind) == 0) {
            dither_queued(d, c);
        }
        break;
    case TWIND_BUILD_MODEL:
        if (!m) {
            snprintf(why, sizeof why, "param: cannot build the new model: %.200s", err);
            reject_cmd(d, c, why);
        } else if (enqueue_model_change(d, c, m, b->cfg, kind) == 0) {
            param_queued(d, b->eff);
        }
        break;
    case TWIND_BUILD_RELOAD:
        reload_built(d, m, err);
        break;
    }
}

/* The build in flight: once done (waiting up to wait_ms), its command goes to the RT thread
 * (build_done), then the held commands in order, until the ring is empty or one of them
 * starts another build. */
static void held_resume(twind *d, int wait_ms) {
    twind_bw *b = &d->bw;
    while (b->busy) {
        afm_runner_model *m = NULL;
        char err[AFM_ERR_LEN];
        if (!twind_bw_take(d, wait_ms, &m, err, sizeof err)) return;
        build_done(d, m, err);
        while (!b->busy && b->held_n > 0) {
            twind_held h = b->held[b->held_head];
            b->held_head = (b->held_head + 1) % TWIND_HELD_LEN;
            b->held_n--;
            d->cmd_order = h.order;
            handle_cmd(d, &h.cmd);
        }
    }
}

/* At shutdown: the build in flight and the commands behind it are refused (counted: the
 * accounting stays whole). */
static void held_drop(twind *d) {
    twind_bw *b = &d->bw;
    if (!b->busy) return;
    afm_runner_model *m = NULL;
    char err[AFM_ERR_LEN], why[AFM_IO_REASON_LEN];
    while (!twind_bw_take(d, 100, &m, err, sizeof err)) {
    }
    afm_runner_model_destroy(&m);
    d->cmd_order = b->waiting.order;
    snprintf(why, sizeof why, "%s: the daemon stopped before its model was built",
             b->kind == TWIND_BUILD_RELOAD ? "reload" : afm_cmd_kind_name(b->waiting.cmd.kind));
    if (b->kind == TWIND_BUILD_RELOAD)
        twind_refuse(d, why);
    else
        refuse_cmd(d, &b->waiting.cmd, why);
    for (; b->held_n > 0; b->held_n--) {
        twind_held *h = &b->held[b->held_head];
        b->held_head = (b->held_head + 1) % TWIND_HELD_LEN;
        refuse_cmd(d, &h->cmd, "the daemon stopped while the command waited for a model build");
    }
}

/* Lockstep: a tick whose seq is that of the last tick received is the client's re-send
 * (its completion did not come in time: lost, or late): never run again (a duplicate must not
 * change the model), counted, and the publisher asked to publish that completion again
 * (publish.c: if it was published; otherwise it is still to come). true if c is one. */
static bool tick_resent(twind *d, const afm_cmd *c) {
    if (c->kind != AFM_CMD_TICK || d->opt.mode != TWIND_LOCKSTEP) return false;
    if (!d->tick_seen || c->seq != d->last_tick_seq) {
        d->tick_seen = true;
        d->last_tick_seq = c->seq;
        return false;
    }
    atomic_fetch_add_explicit(&d->tick_resends, 1, memory_order_relaxed);
    atomic_store_explicit(&d->republish_seq, c->seq, memory_order_relaxed);
    atomic_fetch_add_explicit(&d->republish_req, 1, memory_order_release);
    sem_post(&d->out_sem); /* wakes the publisher; never blocks */
    return true;
}

static int on_cmd(void *ctx, const afm_cmd *c) {
    twind *d = ctx;
    twind_bw *b = &d->bw;
    count_received(d);
    if (tick_resent(d, c)) return 0;
    /* Behind a build in flight: in order, in the hold ring; a full ring waits for the build
     * (as every command did before the worker). */
    while (b->busy && b->held_n == TWIND_HELD_LEN &&
           !atomic_load_explicit(&d->stop, memory_order_acquire))
        held_resume(d, 100);
    if (b->busy) {
        if (b->held_n == TWIND_HELD_LEN) { /* stopping */
            d->cmd_order = d->order;
            refuse_cmd(d, c, "the daemon stopped while the command waited for a model build");
            return -1;
        }
        b->held[(b->held_head + b->held_n) % TWIND_HELD_LEN] =
            (twind_held){.cmd = *c, .order = d->order};
        b->held_n++;
        return 0;
    }
    d->cmd_order = d->order;
    return handle_cmd(d, c);
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
    return (afm_cmd_limits){.sample_rate_hz = d->shadow.sim.sample_rate_hz,
                            .model = &d->shadow_model};
}

static unsigned drive(void *ctx, afm_cmd_dither *out) {
    twind *d = ctx;
    *out = d->drive_now;
    return d->drive_gen;
}

afm_io_sink twind_sink(twind *d) {
    d->shadow_model = *afm_sim_model(afm_runner_sim(d->runner));
    drive_from_config(d, &d->shadow.drive);
    return (afm_io_sink){
        .ctx = d, .on_cmd = on_cmd, .on_reject = on_reject, .limits = limits, .drive = drive};
}

/* SIGHUP: load and check the file, build the twin on the build worker (reload_built), swap
 * at a block boundary. A bad config keeps the running one and says why. */
static void do_reload(twind *d) {
    static afm_config next; /* receive thread only; large for a stack frame */
    char err[AFM_ERR_LEN], why[AFM_IO_REASON_LEN];
    d->order++;
    d->cmd_order = d->order;
    if (afm_config_load(d->opt.config_path, &next, err, sizeof err)) {
        snprintf(why, sizeof why, "reload: %.200s; keeping the running config", err);
        twind_reject(d, why);
        return;
    }
    if (!model_changes_settled(d, MODEL_WAIT_MS)) {
        twind_refuse(d, "reload: the twin is still applying the previous model change; "
                        "send SIGHUP again");
        return;
    }
    afm_cmd c = {.kind = AFM_CMD_RELOAD, .seq = -1}; /* a reload keeps seq_applied */
    build_submit(d, &c, TWIND_BUILD_RELOAD, &next, NULL, true,
                 AFM_PARAM_SEPARATION /* unused */); /* its drive */
}

/* The reloaded config's model (or NULL, err why not): to the RT thread. */
static void reload_built(twind *d, afm_runner_model *m, const char *err) {
    char why[AFM_IO_REASON_LEN];
    if (!m) {
        snprintf(why, sizeof why, "reload: %.60s: %.150s; keeping the running config",
                 d->opt.config_path, err);
        twind_reject_order(d, why, d->cmd_order);
        return;
    }
    const afm_config *next = d->bw.cfg;
    if (enqueue_model_change(d, &d->bw.waiting.cmd, m, next, "reload")) return;
    drive_from_config(d, &next->drive);
    twind_a0_request(d, &d->shadow, &d->drive_now, true);
    if (!d->opt.quiet) fprintf(stderr, "afmtwind: reloaded %s\n", d->opt.config_path);
}

static void drain_side_queues(twind *d) {
    afm_runner_model *m;
    while (afm_spsc_pop(&d->trash_q, &m)) /* rejected by the RT thread */
        afm_runner_model_destroy(&m);
    while (afm_runner_take_trash(d->runner, &m)) /* swapped out, via the chain thread */
        afm_runner_model_destroy(&m);
    twind_reason r;
    char b[AFM_IO_REASON_LEN];
    while (afm_spsc_pop(&d->rtrej_q, &r)) /* counted by the rt thread (snapshot.refused) */
        count_reason(d, NULL, d->last_refusal, "refused", tag_seq(b, sizeof b, r.reason, r.seq));
    model_changes_settled(d, 0); /* a refused model change: the shadow goes back now */
}

/* The receive thread. With no stream it blocks in the transport's poll and takes each
 * message as it arrives. While messages keep coming (some came in the last turn) it sleeps
 * to the next batch instant (every opt.batch_s, absolute, so that handling does not
 * stretch the period) and takes all that came meanwhile with a zero timeout: a 10 kHz
 * stream then costs 1 / batch_s wake-ups a second (4000 at the default 250 us) instead of
 * one per message, each a context switch on a core the integrator or the output chain
 * needs (tens of us on a virtual machine). A command waits at most batch_s longer; the RT
 * thread applies what is queued at its next ring item as before, so the rule that places
 * commands in model time is unchanged. Lockstep never batches: a tick's round trip is its
 * throughput. */
void *twind_recv_main(void *arg) {
    twind_thread_name("afm-recv");
    twind *d = arg;
    twind_rt_setup_aux(d->opt.rt_priority - 10, d->opt.aux_cpu);
    long batch_ns = d->opt.mode == TWIND_LOCKSTEP ? 0 : (long)llround(d->opt.batch_s * 1e9);
    struct timespec next;
    clock_gettime(CLOCK_MONOTONIC, &next);
    bool stream = false;
    int64_t order0 = d->order;
    while (!atomic_load_explicit(&d->stop, memory_order_acquire)) {
        if (stream) {
            struct timespec now;
            clock_gettime(CLOCK_MONOTONIC, &now);
            next.tv_nsec += batch_ns;
            while (next.tv_nsec >= 1000000000L) {
                next.tv_nsec -= 1000000000L;
                next.tv_sec++;
            }
            if (next.tv_sec < now.tv_sec ||
                (next.tv_sec == now.tv_sec && next.tv_nsec < now.tv_nsec))
                next = now; /* behind (handling took longer): no catching up in a burst */
            else
                clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &next, NULL);
        }
        /* a build in flight: look for its end every millisecond at least */
        int idle_ms = d->bw.busy ? 1 : IDLE_POLL_MS;
        if (d->io->ops->poll(d->io, stream ? 0 : idle_ms) < 0) {
            struct timespec ts = {0, 50000000L}; /* transport trouble: do not spin */
            nanosleep(&ts, NULL);
        }
        if (!stream) clock_gettime(CLOCK_MONOTONIC, &next); /* the first of a stream */
        stream = batch_ns > 0 && d->order != order0;
        order0 = d->order;
        held_resume(d, 0);
        /* a reload waits for the build in flight (whose model is of the config before) */
        if (!d->bw.busy && atomic_exchange(&d->reload, 0)) do_reload(d);
        drain_side_queues(d);
    }
    held_drop(d);
    /* After the RT and chain threads have stopped: whatever they left behind. */
    while (!atomic_load_explicit(&d->rt_done, memory_order_acquire) ||
           !atomic_load_explicit(&d->chain_done, memory_order_acquire)) {
        struct timespec ts = {0, 1000000L};
        nanosleep(&ts, NULL);
    }
    drain_side_queues(d);
    return NULL;
}
