/* SPDX-License-Identifier: MIT */
/* twind.h -- what the daemon's modules share: the daemon state, the queue items between
 * its threads, the real-time thread's published snapshot, and each module's entry points.
 *
 * Threads and who owns what:
 *  - main (afmtwind.c): arguments, start-up and shutdown in order, signals (sigtimedwait),
 *    the status line on stderr once a second, sd_notify.
 *  - receive (cmd_in.c): transport poll; decoded commands checked against the daemon's copy
 *    of the config (shadow), all pushed into cmd_q (its only producer) in arrival order;
 *    destroys what the RT thread swapped out (trash_q) and counts the RT thread's rare
 *    rejections (rtrej_q).
 *  - build (build_worker.c): the models that damping/geometry changes, SIGHUP reloads and
 *    dithers under the internal AM Z loop bring, one at a time at SCHED_FIFO 1; the command
 *    and those after it wait in the receive thread's hold ring meanwhile.
 *  - rt (rt_loop.c): the runner's integrator stage. Pops cmd_q before every ring item,
 *    integrates a block into the runner's ring (afm_runner, pipelined), paces realtime
 *    mode (waits for a block's deadline or a command: cmd_sem), updates the snapshot
 *    (seqlock). Never blocks, locks or allocates.
 *  - chain (chain_loop.c): the runner's output-chain stage, on a second core. Takes the
 *    ring's sample blocks through OBD, decimators and estimators, pushes samples
 *    (samples_q) and harmonics (harm_q), updates its own snapshot. Never blocks, locks or
 *    allocates (it sleeps on chain_sem when the ring is empty).
 *  - a0 (a0_track.c): the free amplitude A0 at the drive in force, recomputed on a worker
 *    at normal priority when the receive thread asks (config or tone 0 changed).
 *  - publish (publish.c): pops samples_q and harm_q, publishes them, and the status at
 *    10 Hz; the completions of ticks and steps (done_q) once the outputs before them are
 *    out; the final status at shutdown.
 * Counters the receive thread owns (received, rejected, refused, last reasons) sit behind
 * `lock`, which only the non-real-time threads take.
 *
 * Accounting: every command message that reaches the daemon is counted once, in received,
 * and ends in exactly one of applied (by the twin), rejected (malformed or invalid: the
 * receive thread), refused (valid, but not taken: the command queue full, or the twin
 * refusing it: rt thread) or dropped (lost before any handler: LCM's queues, the socket;
 * the transport counts those), or, in lockstep, tick_resends (a tick with the last tick's
 * seq: a client's re-send, never run twice) -- so received = applied + rejected + refused +
 * dropped + tick_resends once the queue has drained. The rt thread never refuses for back-pressure:
 * a command that does not fit the ring now stays at the head of cmd_q and is applied a ring item
 * later.
 *
 * Model changes (param, reload) go one at a time: the receive thread folds each into its
 * shadow config only after the rt thread has taken or refused the one before (mc_sent /
 * mc_done, mc_last_ok), and puts the shadow back if it was refused, so a rebuilt model
 * never starts from values the twin refused. */
#ifndef TWIND_H
#define TWIND_H

#include "transport/afm_io.h"
#include "transport/afm_io_records.h"
#include "runner/afm_a0.h"
#include "runner/afm_runner.h"
#include "runner/afm_spsc.h"

#include <pthread.h>
#include <semaphore.h>
#include <stdatomic.h>
#include <stdint.h>
#include <time.h>

typedef enum { TWIND_REALTIME = 0, TWIND_FREERUN = 1, TWIND_LOCKSTEP = 2 } twind_mode;
/* --scheme (scheme.c): CONFIG (no option: the config's sim.rt_scheme, auto by default),
 * auto (measure, accurate where it fits, hand over under overload), adaptive (accurate,
 * hand over under overload and back), accurate or fast (forced). */
typedef enum {
    TWIND_SCHEME_CONFIG = 0,
    TWIND_SCHEME_AUTO,
    TWIND_SCHEME_ADAPTIVE,
    TWIND_SCHEME_ACCURATE,
    TWIND_SCHEME_FAST
} twind_scheme;

typedef struct {
    const char *config_path;
    const char *lcm_url;         /* commands; NULL: LCM's default */
    const char *lcm_out_url;     /* outputs; NULL: derived from lcm_url (udpm: port + 1) */
    const char *lcm_samples_url; /* the sample stream; NULL: derived (udpm: port + 2) */
    const char *prefix;          /* channel prefix, default "AFMTWIN_" */
    twind_mode mode;
    int cpu;             /* pin the RT thread to this CPU; -1: no pinning */
    int chain_cpu;       /* pin the chain thread to this CPU; -1: no pinning */
    int aux_cpu;         /* pin the receive and publish threads (and LCM's) here; -1: none */
    double speed;        /* realtime: model seconds per wall second asked (1) */
    double max_lag_s;    /* realtime: lag beyond which the backlog is dropped (resync) */
    double ring_s;       /* runner ring between the two stages, model seconds */
    int rt_priority;     /* SCHED_FIFO priority 1..99 */
    int lcm_priority;    /* LCM's receive thread; 0: rt_priority - 10 (the receive thread's) */
    double block_s;      /* real-time block length (s) */
    double batch_s;      /* receive thread: at most one wake-up per batch_s under a stream */
    double exit_after_s; /* > 0: stop after this long (tests) */
    double start_s;      /* model time at start (tests of a twin up that long; default 0) */
    int harmonics_every; /* publish every k-th period; 0: auto (at most harmonics_max_hz) */
    double harmonics_max_hz;
    int quiet;    /* no status line */
    int a0_track; /* --a0-track: recompute A0 after drive and model changes (a0_track.c) */
    twind_scheme scheme;
    const char *applied_log; /* --applied-log FILE (applied_log.c); NULL: none */
} twind_opts;

/* scheme.c's choice: main thread before start, then the rt thread's. */
typedef struct {
    bool accurate;               /* the scheme the rt thread keeps in force */
    bool rt;                     /* the rt integrator (else no schemes) */
    bool handover;               /* to fast under overload, and back (auto, adaptive) */
    double ns_accurate, ns_fast; /* auto: measured worst-state cost per sample */
    double t_switch_s, hold_s;   /* last hand-over (monotonic s), hold-off before going back */
    char reason[160];            /* why, at start */
    char from[64];               /* what asked: "--scheme fast", "--scheme config: sim.rt_scheme
                                    auto" (no option: the config's) */
} twind_scheme_state;

/* cmd_q item: a validated command and, for damping/geometry/reload, the model to swap in.
 * The RT thread hands models back through trash_q (what was swapped out, or the unused
 * model of a command it rejected). order: the receive thread's count of inbound events
 * (commands, rejects, reloads) at this one, so that a rejection can be told old once a
 * later event was applied. */
typedef struct {
    afm_cmd cmd;
    afm_runner_model *model;
    int64_t order;
} twind_cmd_item;

typedef struct {
    char reason[AFM_IO_REASON_LEN];
    int64_t order; /* of the command the RT thread rejected */
    int64_t seq;   /* its seq (tagged onto the reason by the receive thread) */
} twind_reason;

/* applied_log.c's queue item (rt -> receive thread): a command the twin applied, or a
 * scheme hand-over (scheme >= 0: 1 accurate, 0 fast), with the samples run before it. */
typedef struct {
    int64_t sample;
    int scheme; /* -1: a command */
    afm_cmd cmd;
} twind_applied;
struct _lcm_eventlog_t;
typedef struct {
    afm_spsc q;
    struct _lcm_eventlog_t *log;         /* NULL: no --applied-log */
    atomic_llong lost;                   /* rt: pushes that found q full */
    pthread_t th;                        /* the writer (afm-log) */
    atomic_int stop;                     /* main -> writer */
    long long written, unlogged, failed; /* the writer (main at the end) */
} twind_applied_log;

/* Lines of rejections and refusals on stderr: at most this many a second, the rest
 * counted and summed up once a second by main (the status has every one). */
#define TWIND_REASON_LINES_PER_S 5
/* done_q item: a tick or step completion (afm_runner_take_done) and how many samples and
 * harmonics records the chain thread had committed to the publisher before it. */
typedef struct {
    afm_runner_done d;
    long long samples_recs, harm_recs;
} twind_done_item;

/* What the RT thread publishes after every block (seqlock: readers retry while seq is odd
 * or changed under them). */
typedef struct {
    afm_runner_status st;
    long long blocks;           /* blocks run */
    long long overruns;         /* realtime blocks that ended after their deadline */
    double lag_s;               /* wall clock minus model time (realtime mode) */
    long long resyncs;          /* realtime: backlogs dropped because lag > max_lag_s */
    double resync_dropped_s;    /* model time not run because of them (wall seconds x speed) */
    long long heartbeat;        /* increases every loop turn (watchdog) */
    double busy_fraction;       /* compute time / wall time over the last second */
    long long refused;          /* commands the twin refused (exact; reasons via rtrej_q) */
    long long reasons_lost;     /* ... whose reason did not fit rtrej_q */
    double rtf_1s;              /* model s / wall s over the last second of running; 0 at first */
    int64_t last_applied_order; /* twind_cmd_item.order of the last command applied */
    /* the rt scheme in force (scheme.c): hand-overs, model time run by each, why */
    bool scheme_accurate;
    long long scheme_handovers;
    double model_s_accurate, model_s_fast;
    char scheme_reason[160]; /* "" until the first hand-over: then twind.scheme.reason */
} twind_snapshot;

/* What the chain thread publishes (its own seqlock). */
typedef struct {
    afm_runner_chain_status st;
    long long samples_dropped; /* sample records lost to a full samples_q */
    long long harm_dropped;    /* harmonics records lost to a full harm_q */
    double busy_fraction;
    bool have_period; /* the last period record seen (finished), for the status line */
    double lockin_amplitude_m, lockin_phase_deg, peak_force_n;
    double squeeze_dissipated_energy_j; /* the squeeze film's, beside the tip-sample force */
} twind_chain_snapshot;

/* a0_track.c's state: the request (receive thread, under mu), the result (worker, under
 * mu), read by the publish thread. done_gen == req_gen: amplitude_m is the A0 of the
 * newest request. */
typedef struct {
    pthread_t th;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    bool started, stop;
    bool worker;               /* the thread runs (--a0-track) */
    afm_config *req, *work;    /* the newest request; the worker's copy of it */
    afm_rt_scheme_kind scheme; /* A0 on the rt scheme in force (the start's, then hand-overs) */
    unsigned req_gen, done_gen;
    long long computed; /* A0s computed since start (the start-up one not counted) */
    double fe_hz, ae_m; /* receive thread: tone 0 of the newest request */
    double amplitude_m; /* A0 (m); NaN when it could not be computed */
    double lag_deg;
} twind_a0;

/* build_worker.c's state: one job at a time (the receive thread submits and takes, the
 * worker builds; under mu), and the receive thread's hold ring of the commands that came
 * after the one whose model is being built (the receive thread's alone). */
#define TWIND_HELD_LEN 4096 /* commands held behind a build (0.4 s of a 10 kHz stream) */
typedef struct {
    afm_cmd cmd;
    int64_t order; /* its twind_cmd_item.order: when it arrived */
} twind_held;
typedef enum {
    TWIND_BUILD_A0,     /* a dither's A0 under the internal AM Z loop (afm_runner_model_a0) */
    TWIND_BUILD_MODEL,  /* a damping / geometry param's model, at the drive in force */
    TWIND_BUILD_RELOAD, /* a SIGHUP's config file, its own drive */
} twind_build_kind;
typedef struct {
    pthread_t th;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    bool started, stop;
    bool busy;         /* receive thread: a job submitted and not taken */
    bool queued, done; /* under mu: waiting for the worker; its result ready */
    /* the job: */
    twind_build_kind kind;
    afm_config *cfg;      /* the config to build (after the command) */
    afm_cmd_dither drive; /* the drive (A0: the dither; MODEL: the drive in force) */
    bool has_drive;       /* false: the config's (RELOAD) */
    bool new_chain;       /* MODEL: a new output chain (afm_runner_cmd_needs_model) */
    afm_runner_model *model;
    char err[AFM_ERR_LEN];
    /* receive thread only: the command in flight (with its param effect) and those behind */
    twind_held waiting;
    afm_param_effect eff;
    twind_held *held;
    int held_head, held_n;
} twind_bw;

typedef struct {
    twind_opts opt;
    afm_runner *runner; /* the RT thread's after start */
    afm_io *io;
    afm_spsc cmd_q, trash_q, rtrej_q, samples_q, harm_q, done_q;
    sem_t out_sem;         /* posted by the chain thread after pushing outputs */
    sem_t chain_sem;       /* posted by the RT thread after a block went into the ring */
    sem_t cmd_sem;         /* posted by the receive thread after a command went into cmd_q */
    atomic_int stop;       /* set by main: all threads finish */
    atomic_int rt_done;    /* set by the RT thread when it has left its loop */
    atomic_int chain_done; /* set by the chain thread when it has left its loop */
    atomic_int reload;     /* set by main on SIGHUP, taken by the receive thread */
    /* snapshot */
    atomic_uint snap_seq, csnap_seq;
    twind_snapshot snap;
    twind_chain_snapshot csnap;
    /* receive-side counters (lock) */
    pthread_mutex_t lock;
    long long received, rejected, refused; /* refused here: command queue full */
    char last_reject[AFM_IO_REASON_LEN], last_refusal[AFM_IO_REASON_LEN];
    long long lines_quiet;     /* reason lines not printed (throttled); main sums them up */
    double lines_t0;           /* start of the current second of reason lines */
    int lines_n;               /* lines printed in it */
    int64_t last_reject_order; /* order of the rejected event (see twind_cmd_item) */
    double last_reject_mono;   /* CLOCK_MONOTONIC when it was rejected */
    /* receive thread only */
    int64_t order;            /* inbound events so far */
    afm_config shadow;        /* the config after all queued commands */
    afm_modal shadow_model;   /* its model (command limits: afm_cmd_limits.model) */
    afm_config shadow_before; /* both before the model change in flight */
    afm_modal shadow_model_before;
    bool mc_unchecked;              /* a model change in flight, its outcome not seen yet */
    afm_cmd_dither drive_now;       /* the drive after all queued dithers (CAN registers) */
    unsigned drive_gen;             /* changes with it */
    atomic_ullong mc_sent, mc_done; /* model changes queued / taken or refused by rt */
    atomic_int mc_last_ok;          /* rt: 1 if the last one was applied */
    twind_scheme_state scheme;      /* main thread, then the rt thread only */
    twind_a0 a0;                    /* a0_track.c */
    twind_bw bw;                    /* build_worker.c */
    int64_t cmd_order;              /* receive thread: order of the command being handled */
    /* Lockstep re-sends (cmd_in.c on_cmd): a tick whose seq is that of the last tick received
     * is a client's re-send after a lost or late completion: never run again; the publisher
     * publishes the last completion again if it names that seq (publish.c). */
    bool tick_seen;             /* receive thread: a tick was received */
    int64_t last_tick_seq;      /* receive thread: its seq */
    atomic_llong tick_resends;  /* re-sent ticks received (status) */
    atomic_llong republish_req; /* receive -> publisher: +1 per re-send, seq below */
    atomic_llong republish_seq; /* the seq whose completion is asked for again */
    atomic_llong republished;   /* completions published again (status) */
    twind_applied_log applied;  /* --applied-log (applied_log.c) */
    /* RT scheduling result, for the start-up report */
    char rt_warn[512];
} twind;

/* applied_log.c (--applied-log). open: main, before the threads (the log's first event: the
 * scheme in force at sample 0; starts the writer thread); 0, or -1 with err. cmd and scheme:
 * the rt thread, after a command applied / a hand-over, with the samples run before it (never
 * block); the writer writes them. close: main, after the threads stopped: the writer stopped,
 * the rest written, and a line on stderr (incomplete: said so). All do nothing without the
 * option. */
int twind_applied_open(twind *d, bool accurate, char *err, size_t errlen);
void twind_applied_cmd(twind *d, const afm_cmd *c, long long sample);
void twind_applied_scheme(twind *d, bool accurate, long long sample);
void twind_applied_close(twind *d);

/* twind_clock.c */
const char *twind_mode_name(twind_mode m);

/* twind_opts.c: argv into o (defaults first); -1 after saying what is wrong on stderr.
 * --help and --version print on stdout and exit 0. */
int twind_parse_args(int argc, char **argv, twind_opts *o);

/* rt_setup.c: mlockall (on the calling process), SCHED_FIFO and CPU affinity for the
 * calling thread. Each failure is described in warn (appended), never fatal. */
void twind_rt_setup_process(char *warn, size_t len);
void twind_rt_setup_thread(int priority, int cpu, char *warn, size_t len);
/* The publish and receive threads: SCHED_FIFO at a lower priority when permitted, so that
 * outputs and commands are not starved by ordinary processes, and pinned to cpu (>= 0);
 * silent (the RT thread warns). */
void twind_rt_setup_aux(int priority, int cpu);
/* For model builds (FEM, reduction, filter design: ~20 ms for a geometry change; the build
 * worker, build_worker.c, for good): the lowest real-time priority while building (building
 * true), so that it takes only the time the integrator and chain threads leave but no
 * ordinary process delays it; back to SCHED_FIFO priority after. */
void twind_rt_setup_build(int priority, bool building);
/* The calling thread's name (top -H, ps -L, /proc/PID/task/TID/comm): afm-rt, afm-chain,
 * afm-recv, afm-pub, afm-a0, afm-build; LCM's receive thread keeps the process's name. */
void twind_thread_name(const char *name);

/* scheme.c: resolve d->opt.scheme for cfg (measuring both schemes for auto, main thread,
 * before the threads start) into d->scheme and cfg->sim.rt_scheme. 0, or -1 with err. */
int twind_scheme_choose(twind *d, afm_config *cfg, char *err, size_t errlen);
/* rt thread, after each turn: account model_s to the scheme in force, hand over on
 * overload (late_s: the lag) or back when the margin returned, keep the runner's sim in
 * the chosen scheme. */
void twind_scheme_turn(twind *d, afm_runner *r, twind_snapshot *snap, double late_s, double model_s,
                       double now_s);
const char *twind_scheme_opt_name(twind_scheme s);

/* rt_loop.c: the real-time thread (arg: twind *). */
void *twind_rt_main(void *arg);
/* chain_loop.c: the output-chain thread (arg: twind *). */
void *twind_chain_main(void *arg);

/* cmd_in.c: the sink the transport calls, and the receive thread (arg: twind *). */
afm_io_sink twind_sink(twind *d);
void *twind_recv_main(void *arg);
/* Count a rejection (malformed, invalid) or a refusal (valid, not taken) with its reason
 * (non-RT threads); stderr lines throttled (TWIND_REASON_LINES_PER_S). twind_reject names
 * the receive thread's current event, twind_reject_order the event of that order. */
void twind_reject(twind *d, const char *reason);
void twind_reject_order(twind *d, const char *reason, int64_t order);
void twind_refuse(twind *d, const char *reason);

/* publish.c: the publish thread (arg: twind *), and one status record from the snapshot.
 * The real-time factor is model time over wall time since the caller's previous call
 * (state in *rs, zero-initialised); once the RT thread has stopped it keeps the last value
 * (the interval of the final status would count the shutdown). */
typedef struct {
    double wall, model, rtf;
} twind_rtf_state;
void *twind_pub_main(void *arg);
void twind_status_fill(twind *d, afm_io_status *st, twind_rtf_state *rs);

/* a0_track.c. twind_a0_compute: A0 of cfg (afm_a0_compute; 0 for a silent tone 0), any
 * non-rt thread. twind_a0_start (main, before the threads): the worker, with first the A0
 * of cfg already computed; -1 if it cannot start. twind_a0_request (receive thread): A0 of
 * cfg with tone 0 of drive (NULL: cfg's own), recomputed if cfg_changed or tone 0 differs
 * from the last request. twind_a0_now (any thread): the newest request's A0 (m), NaN
 * while it is being computed or could not be. twind_a0_stop (main, at the end). */
int twind_a0_compute(const afm_config *cfg, afm_a0 *out, char *err, size_t errlen);
int twind_a0_start(twind *d, const afm_config *cfg, afm_rt_scheme_kind scheme, const afm_a0 *first);
void twind_a0_request(twind *d, const afm_config *cfg, const afm_cmd_dither *drive,
                      bool cfg_changed);
double twind_a0_now(twind *d);
/* The rt scheme in force (any non-rt thread, from the status): A0 is recomputed on it after
 * a hand-over. */
void twind_a0_scheme(twind *d, bool accurate);
void twind_a0_stop(twind *d);

/* build_worker.c: the models commands bring (A0 under the internal AM Z loop, damping and
 * geometry params, SIGHUP reloads), built on a worker thread. twind_bw_start (main, before
 * the threads; allocates the job and the hold ring): -1 if it cannot start. twind_bw_submit
 * (receive thread, no job in flight): build a model of kind from cfg at drive (NULL: the
 * config's), with a new output chain if new_chain (MODEL). twind_bw_take (receive thread):
 * true once the job is done (waiting up to wait_ms), with *m the model or NULL and err the
 * reason. twind_bw_stop (main, after the threads). */
int twind_bw_start(twind *d);
void twind_bw_submit(twind *d, twind_build_kind kind, const afm_config *cfg,
                     const afm_cmd_dither *drive, bool new_chain);
bool twind_bw_take(twind *d, int wait_ms, afm_runner_model **m, char *err, size_t errlen);
void twind_bw_stop(twind *d);

/* notify.c: sd_notify wrappers (no-ops outside systemd). */
void twind_notify_ready(void);
void twind_notify_status(const char *text);
void twind_notify_watchdog(void);
void twind_notify_stopping(void);

/* Seqlock snapshot access (one writer each: the RT thread, the chain thread). */
#define TWIND_SEQLOCK_WRITE(seqp, dst, src)                                                        \
    do {                                                                                           \
        unsigned q_ = atomic_load_explicit(seqp, memory_order_relaxed);                            \
        atomic_store_explicit(seqp, q_ + 1, memory_order_relaxed);                                 \
        atomic_thread_fence(memory_order_release);                                                 \
        *(dst) = *(src);                                                                           \
        atomic_store_explicit(seqp, q_ + 2, memory_order_release);                                 \
    } while (0)
#define TWIND_SEQLOCK_READ(seqp, dst, src)                                                         \
    for (;;) {                                                                                     \
        unsigned a_ = atomic_load_explicit(seqp, memory_order_acquire);                            \
        if (a_ & 1u) continue;                                                                     \
        *(dst) = *(src);                                                                           \
        atomic_thread_fence(memory_order_acquire);                                                 \
        if (atomic_load_explicit(seqp, memory_order_relaxed) == a_) break;                         \
    }
static inline void twind_snap_write(twind *d, const twind_snapshot *s) {
    TWIND_SEQLOCK_WRITE(&d->snap_seq, &d->snap, s);
}
static inline void twind_snap_read(twind *d, twind_snapshot *s) {
    TWIND_SEQLOCK_READ(&d->snap_seq, s, &d->snap);
}
static inline void twind_csnap_write(twind *d, const twind_chain_snapshot *s) {
    TWIND_SEQLOCK_WRITE(&d->csnap_seq, &d->csnap, s);
}
static inline void twind_csnap_read(twind *d, twind_chain_snapshot *s) {
    TWIND_SEQLOCK_READ(&d->csnap_seq, s, &d->csnap);
}

/* twind_clock.c: wall clock now (CLOCK_REALTIME, us) for utime stamps, and CLOCK_MONOTONIC in s. */
int64_t twind_utime_now(void);
double twind_mono_now(void);
/* sem_timedwait's deadline (CLOCK_REALTIME) ns from now. */
struct timespec twind_deadline_in(long ns);

#endif
