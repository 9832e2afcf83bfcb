/* SPDX-License-Identifier: MIT */
/* afmtwind.c -- the daemon's main: start-up in order (config, memory lock,
 * runner, queues, transport, threads), signals, the once-a-second status line, and a clean
 * shutdown in reverse order. */
#include "twind.h"

#include "runner/afm_a0.h"
#include "transport/afm_lcm_url.h"

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* 0.8 s of a 10 kHz command stream (2.6 MB): a burst after a model build, an RT thread
 * that fell behind by max_lag_s and the 50 ms a throttled SCHED_FIFO thread can lose all
 * fit; was 256 (25 ms), which refused 2705 of a 10 kHz stream's 600 000 commands */
#define CMD_Q_LEN 8192
#define TRASH_Q_LEN 64
#define RTREJ_Q_LEN 64
#define SAMPLES_Q_LEN 256 /* records of up to AFM_IO_MAX_BLOCK samples (~8 MB in all) */
#define HARM_Q_LEN 4096
#define DONE_Q_LEN 1024

/* The stderr status line: whether the twin keeps up (the real-time factor of the last second
 * of running, resyncs and the model time they skipped, the chain's lag), what the cantilever
 * does (lock-in amplitude and phase lag of the last period, its peak force, A0 and A/A0) and the
 * command bookkeeping, with the last rejection marked old once a later command was applied. */
static void status_line(twind *d, twind_rtf_state *rs, char *buf, size_t len) {
    static afm_io_status s; /* main thread only; large (reason strings) */
    twind_status_fill(d, &s, rs);
    twind_snapshot snap;
    twind_chain_snapshot cs;
    twind_snap_read(d, &snap);
    twind_csnap_read(d, &cs);
    snprintf(
        buf, len,
        "t %.6f s  rtf(1 s) %.3f  busy %.0f%%/%.0f%%  lag %.4f s  overruns %lld  resyncs %lld "
        "(%.4f s skipped)  chain stalls %lld lag %.4f s  lock-in %.4g nm, phase lag %.1f deg  "
        "peak force %.4g nN  A0 %.6g nm A/A0 %.4f  rx %lld  applied %lld  rej %lld  ref %lld  drop "
        "%lld  blowups "
        "%lld  seq %lld  Z %.3f nm  fe %.1f Hz  A %.4g nm  scheme %s (%lld handovers; "
        "%.0f%% of model time accurate)  %s",
        s.model_time_s, s.realtime_factor_1s, 100.0 * snap.busy_fraction, 100.0 * cs.busy_fraction,
        s.lag_s, (long long)s.overruns, (long long)s.resyncs, s.resync_skipped_s,
        (long long)s.chain_stalls, s.chain_lag_s, s.lockin_amplitude_m * 1e9, s.lockin_phase_deg,
        s.peak_force_n * 1e9, s.free_amplitude_m * 1e9, s.amplitude_ratio, (long long)s.received,
        (long long)s.applied, (long long)s.rejected, (long long)s.refused, (long long)s.dropped,
        (long long)s.blowups, (long long)s.seq_applied, s.separation_m * 1e9, s.fe_hz,
        s.amplitude_m * 1e9, s.rt_scheme, (long long)s.scheme_handovers,
        s.model_s_accurate + s.model_s_fast > 0
            ? 100.0 * s.model_s_accurate / (s.model_s_accurate + s.model_s_fast)
            : 0.0,
        s.auto_paused ? "PAUSED ITSELF (blow-ups)"
        : s.running   ? "running"
                      : "paused");
    if (s.last_reject[0]) {
        size_t n = strlen(buf);
        snprintf(buf + n, len - n, "  last rejected %.1f s ago%s: %.160s", s.last_reject_age_s,
                 s.last_reject_old ? " (old: later commands applied)" : "", s.last_reject);
    }
    if (cs.samples_dropped || cs.harm_dropped || cs.st.chain.periods_dropped) {
        size_t n = strlen(buf);
        snprintf(buf + n, len - n, "  DROPPED: %lld sample blocks, %lld harmonics, %lld periods",
                 cs.samples_dropped, cs.harm_dropped, cs.st.chain.periods_dropped);
    }
    if (s.can_state[0]) { /* a CAN transport is running */
        size_t n = strlen(buf);
        snprintf(buf + n, len - n,
                 "  CAN %s, heartbeat %s, frames %lld rej %lld errors %lld reconnects %lld",
                 s.can_state, s.heartbeat_ok ? "ok" : "missing", (long long)s.can_frames,
                 (long long)s.can_rejected, (long long)s.can_errors, (long long)s.can_reconnects);
    }
}

/* The runner for cfg: --block-us as a whole number of samples (1 .. 2^20), --ring-us as
 * whole ring slots (4 .. 4096), into *block and *ring; at --start-time. 0, or -1 with err. */
static int start_runner(twind *d, const afm_config *cfg, long long *block, long long *ring,
                        char *err, size_t errlen) {
    *block = llround(d->opt.block_s * cfg->sim.sample_rate_hz);
    if (*block < 1) *block = 1;
    if (*block > (1 << 20)) *block = 1 << 20;
    *ring = llround(d->opt.ring_s * cfg->sim.sample_rate_hz / AFM_RUNNER_SLOT_SAMPLES);
    if (*ring < 4) *ring = 4;
    if (*ring > 4096) *ring = 4096;
    d->runner = afm_runner_create_pipelined(cfg, (int)*block, d->opt.mode == TWIND_LOCKSTEP, true,
                                            (int)*ring, err, errlen);
    if (!d->runner) return -1;
    if (d->opt.start_s > 0 && afm_runner_set_time(d->runner, d->opt.start_s, err, errlen))
        return -1;
    return 0;
}

/* The lock, semaphores and queues between the threads (twind.h). 0, or -1 with err. */
static int start_queues(twind *d, char *err, size_t errlen) {
    pthread_mutex_init(&d->lock, NULL);
    sem_init(&d->out_sem, 0, 0);
    sem_init(&d->chain_sem, 0, 0);
    sem_init(&d->cmd_sem, 0, 0);
    if (afm_spsc_init(&d->cmd_q, CMD_Q_LEN, sizeof(twind_cmd_item), err, errlen) ||
        afm_spsc_init(&d->trash_q, TRASH_Q_LEN, sizeof(afm_runner_model *), err, errlen) ||
        afm_spsc_init(&d->rtrej_q, RTREJ_Q_LEN, sizeof(twind_reason), err, errlen) ||
        afm_spsc_init(&d->samples_q, SAMPLES_Q_LEN, sizeof(afm_io_samples), err, errlen) ||
        afm_spsc_init(&d->harm_q, HARM_Q_LEN, sizeof(afm_io_harmonics), err, errlen) ||
        afm_spsc_init(&d->done_q, DONE_Q_LEN, sizeof(twind_done_item), err, errlen))
        return -1;
    return 0;
}

/* The transports into d->io: LCM, and CAN beside it when the config enables it (polled on
 * the same receive thread through afm_io_mux, issue 6). sink must outlive d->io. 0, or -1
 * with err. */
static int start_transports(twind *d, const afm_config *cfg, const afm_io_sink *sink, char *err,
                            size_t errlen) {
    /* The transports may start threads of their own (LCM's receive thread, which wakes for
     * every datagram): they inherit a real-time priority from here (--lcm-priority, default
     * the receive thread's), or a busy integrator and chain would keep them off the CPU for
     * whole blocks (at SCHED_OTHER, measured: commands p99 ~1 ms late). Below the output
     * chain it would not preempt the chain for each datagram of a stream, but it starves
     * whenever the chain is behind, and the socket drops commands (docs/realtime.md,
     * "Command intake": 91 724 of 589 142 dropped at 55). Main goes back to the receive
     * thread's priority after. */
    int lcm_prio = d->opt.lcm_priority > 0 ? d->opt.lcm_priority : d->opt.rt_priority - 10;
    twind_rt_setup_aux(lcm_prio, d->opt.aux_cpu);
    d->io = afm_lcm_io_create(d->opt.lcm_url, d->opt.lcm_out_url, d->opt.lcm_samples_url,
                              d->opt.prefix, sink, err, errlen);
    twind_rt_setup_aux(d->opt.rt_priority - 10, d->opt.aux_cpu);
    if (!d->io) return -1;
    if (!cfg->can.enabled) return 0;
    afm_io *both[2] = {d->io, afm_can_io_create(&cfg->can, &cfg->drive, sink, err, errlen)};
    if (!both[1]) return -1;
    d->io = afm_io_mux_create(both, 2, err, errlen);
    if (!d->io) return -1;
    afm_io_status st = {0};
    d->io->ops->annotate_status(d->io, &st);
    fprintf(stderr, "afmtwind: CAN input on %s (%s frames, %s ids): %s\n", cfg->can.interface,
            cfg->can.fd ? "classic and FD" : "classic", cfg->can.extended_ids ? "29-bit" : "11-bit",
            st.can_state);
    return 0;
}

/* The four threads (twind.h), integrator last. 0, or -1 (then some may be running). */
typedef struct {
    pthread_t rt, chain, recv, pub;
} twind_threads;
static int start_threads(twind *d, twind_threads *t) {
    if (pthread_create(&t->recv, NULL, twind_recv_main, d) ||
        pthread_create(&t->pub, NULL, twind_pub_main, d) ||
        pthread_create(&t->chain, NULL, twind_chain_main, d) ||
        pthread_create(&t->rt, NULL, twind_rt_main, d))
        return -1;
    return 0;
}

/* Stop and join them, integrator first; destroy the commands that came too late. */
static void stop_threads(twind *d, twind_threads *t) {
    atomic_store(&d->stop, 1);
    pthread_join(t->rt, NULL);
    pthread_join(t->chain, NULL);
    pthread_join(t->pub, NULL);
    pthread_join(t->recv, NULL);
    twind_cmd_item it;
    while (afm_spsc_pop(&d->cmd_q, &it))
        afm_runner_model_destroy(&it.model);
}

/* The scheme A0 is computed on: the one the rt thread starts with (the config's without the
 * rt integrator). */
static afm_rt_scheme_kind a0_scheme(const twind *d, const afm_config *cfg) {
    if (!d->scheme.rt) return cfg->sim.rt_scheme;
    return d->scheme.accurate ? AFM_RT_SCHEME_ACCURATE : AFM_RT_SCHEME_FAST;
}

/* A0, the free amplitude (runner/afm_a0.h), of cfg on the scheme the rt thread starts with:
 * what the lock-in reads at Z = 1 um. Computed before real time starts (a short
 * simulation); the status's free_amplitude_m then follows the drive (a0_track.c). NAN with
 * err on failure. */
static afm_a0 started_a0(const twind *d, const afm_config *cfg, char *err, size_t errlen) {
    afm_config *c = malloc(sizeof *c);
    afm_a0 a0 = {.amplitude_m = NAN, .lag_deg = NAN};
    if (!c) {
        snprintf(err, errlen, "out of memory");
        return a0;
    }
    *c = *cfg;
    c->sim.rt_scheme = a0_scheme(d, cfg);
    if (twind_a0_compute(c, &a0, err, errlen)) a0.amplitude_m = a0.lag_deg = NAN;
    free(c);
    return a0;
}

/* The start-up line: config, mode, integrator, sample rate (MHz), block (samples, us), the
 * chain's ring, channels and the three LCM URLs (commands, outputs, samples); then the
 * scheme, and A0. */
static void print_started(const twind *d, double fs_hz, long long block, long long ring,
                          const afm_a0 *a0, const char *a0_err) {
    char cmd_u[AFM_LCM_URL_LEN], out_u[AFM_LCM_URL_LEN], smp_u[AFM_LCM_URL_LEN], err[AFM_ERR_LEN];
    if (afm_lcm_urls(d->opt.lcm_url, d->opt.lcm_out_url, cmd_u, out_u, sizeof cmd_u, err,
                     sizeof err) || /* cannot fail here: the transport resolved them already */
        afm_lcm_samples_urls(cmd_u, d->opt.lcm_samples_url, smp_u, sizeof smp_u, err, sizeof err))
        snprintf(smp_u, sizeof smp_u, "?");
    fprintf(stderr,
            "afmtwind: %s, %s mode, %s integrator at %.6g MHz, block %lld samples (%.0f us), "
            "output chain on a second thread (ring %lld x %d samples), channels %s*, LCM "
            "commands %s, outputs %s, samples %s\n",
            d->opt.config_path, twind_mode_name(d->opt.mode),
            afm_sim_integrator_name(afm_runner_sim(d->runner)), fs_hz * 1e-6, block,
            (double)block / fs_hz * 1e6, ring, AFM_RUNNER_SLOT_SAMPLES, d->opt.prefix, cmd_u, out_u,
            smp_u);
    fprintf(stderr, "afmtwind: rt scheme %s (%s): %s\n",
            afm_sim_scheme_name(afm_runner_sim(d->runner)), d->scheme.from, d->scheme.reason);
    if (isfinite(a0->amplitude_m))
        fprintf(stderr,
                "afmtwind: free amplitude A0 %.6f nm, lag %.4f deg (harmonic 1 at Z %.0f nm, "
                "gap-dependent tip forces off, squeeze film on, scheme %s): the status's "
                "free_amplitude_m, and amplitude_ratio = lock-in amplitude / A0, follow the "
                "drive\n",
                a0->amplitude_m * 1e9, a0->lag_deg, a0->z_m * 1e9,
                afm_sim_scheme_name(afm_runner_sim(d->runner)));
    else
        fprintf(stderr, "afmtwind: warning: free amplitude A0 not computed: %s\n", a0_err);
}

/* The sample streams of AFMTWIN_SAMPLES: rate, decimation and the low-pass every channel
 * (the force too) went through, as each samples_t message also says (issue 30: a trace at
 * 2.6 samples per period with its force filtered must not pass for a waveform). */
static void print_streams(const afm_config *cfg) {
    const afm_cfg_output *o = &cfg->output;
    fprintf(stderr, "afmtwind: sample streams (%d):", o->n_outputs);
    for (int i = 0; i < o->n_outputs; i++) {
        double rate = cfg->sim.sample_rate_hz / o->decimation[i], pass, stop;
        afm_chain_band(rate, o->decimation[i], o->passband_fraction, &pass, &stop);
        if (pass > 0)
            fprintf(stderr,
                    "%s %d: %.6g kHz (decimation %d), every channel low-pass %.6g kHz (-80 dB "
                    "from %.6g kHz)",
                    i ? ";" : "", i, rate * 1e-3, o->decimation[i], pass * 1e-3, stop * 1e-3);
        else
            fprintf(stderr, "%s %d: %.6g kHz, not filtered", i ? ";" : "", i, rate * 1e-3);
    }
    fputc('\n', stderr);
}

/* What the once-a-second report remembers from the last one. */
typedef struct {
    twind_rtf_state rs;  /* real-time factor over the last second */
    long long last_beat; /* the rt thread's heartbeat: the watchdog is fed only if it moved */
    long long last_resyncs, last_blowups;
    bool was_auto_paused, warned_rt;
} twind_watch;

/* Once a second: the status line (stderr unless --quiet, and to systemd), and, also with
 * --quiet, resyncs, blow-ups, an automatic pause and the rejections not printed; the
 * watchdog is fed while the rt thread's loop turns. */
static void report_second(twind *d, twind_watch *w) {
    char line[1024];
    status_line(d, &w->rs, line, sizeof line);
    if (!d->opt.quiet) fprintf(stderr, "afmtwind: %s\n", line);
    twind_notify_status(line);
    twind_snapshot s;
    twind_snap_read(d, &s);
    if (s.resyncs != w->last_resyncs) /* never silently, also with --quiet */
        fprintf(stderr,
                "afmtwind: warning: more than %.0f ms behind real time: dropped the "
                "backlog %lld time(s) in the last second (%lld in all, %.4f s of model time "
                "skipped)\n",
                d->opt.max_lag_s * 1e3, s.resyncs - w->last_resyncs, s.resyncs, s.resync_dropped_s);
    w->last_resyncs = s.resyncs;
    /* Blow-ups and the pause they lead to: loudly, also with --quiet. */
    if (s.st.blowups != w->last_blowups)
        fprintf(stderr,
                "afmtwind: warning: %lld numerical blow-up(s) in the last second (%lld in all; "
                "the state was reset to rest each time, last at model time %.6f s)\n",
                s.st.blowups - w->last_blowups, s.st.blowups, s.st.last_blowup_t_s);
    w->last_blowups = s.st.blowups;
    if (s.st.auto_paused && !w->was_auto_paused) {
        char why[2 * AFM_IO_REASON_LEN];
        afm_runner_pause_reason(&s.st, why, sizeof why);
        fprintf(stderr, "afmtwind: PAUSED: %s\n", why);
    }
    w->was_auto_paused = s.st.auto_paused;
    /* Rejections and refusals beyond TWIND_REASON_LINES_PER_S lines a second. */
    pthread_mutex_lock(&d->lock);
    long long quiet = d->lines_quiet;
    d->lines_quiet = 0;
    pthread_mutex_unlock(&d->lock);
    if (quiet > 0)
        fprintf(stderr,
                "afmtwind: ... and %lld more rejections/refusals in the last second, not "
                "printed (all are counted in the status: rejected, refused, last_reject, "
                "last_refusal)\n",
                quiet);
    if (s.heartbeat != w->last_beat) twind_notify_watchdog(); /* only while the loop turns */
    w->last_beat = s.heartbeat;
}

/* Main's loop until SIGTERM, SIGINT or --exit-after: SIGHUP asks the receive thread to
 * reload the config, each quiet second reports (report_second). */
static void run_until_stopped(twind *d, const sigset_t *sigs, twind_watch *w) {
    double t_start = twind_mono_now();
    for (;;) {
        struct timespec one = {1, 0};
        int sig = sigtimedwait(sigs, NULL, &one);
        if (!w->warned_rt && d->rt_warn[0]) { /* the RT thread sets up its scheduling at start */
            fprintf(stderr, "afmtwind: warning: %s\n", d->rt_warn);
            w->warned_rt = true;
        }
        if (sig == SIGTERM || sig == SIGINT) {
            fprintf(stderr, "afmtwind: %s: stopping\n", sig == SIGTERM ? "SIGTERM" : "SIGINT");
            return;
        }
        if (sig == SIGHUP) {
            fprintf(stderr, "afmtwind: SIGHUP: reloading %s\n", d->opt.config_path);
            atomic_store(&d->reload, 1);
            continue;
        }
        report_second(d, w);
        if (d->opt.exit_after_s > 0 && twind_mono_now() - t_start >= d->opt.exit_after_s) {
            fprintf(stderr, "afmtwind: --exit-after %g s: stopping\n", d->opt.exit_after_s);
            return;
        }
    }
}

/* Everything start-up made, in reverse order (each destroy accepts what was never made). */
static void release(twind *d) {
    twind_applied_close(d);
    twind_bw_stop(d);
    twind_a0_stop(d);
    afm_io_destroy(&d->io);
    afm_spsc_destroy(&d->done_q);
    afm_spsc_destroy(&d->harm_q);
    afm_spsc_destroy(&d->samples_q);
    afm_spsc_destroy(&d->rtrej_q);
    afm_spsc_destroy(&d->trash_q);
    afm_spsc_destroy(&d->cmd_q);
    sem_destroy(&d->out_sem);
    sem_destroy(&d->chain_sem);
    sem_destroy(&d->cmd_sem);
    afm_runner_destroy(&d->runner);
}

int main(int argc, char **argv) {
    static twind d; /* large (config copies); zero-initialised */
    char err[AFM_ERR_LEN];
    if (twind_parse_args(argc, argv, &d.opt)) {
        fprintf(stderr, "(afmtwind --help describes every option)\n");
        return 2;
    }
    afm_config cfg;
    if (afm_config_load(d.opt.config_path, &cfg, err, sizeof err)) {
        fprintf(stderr, "afmtwind: %s\n", err);
        return 1;
    }
    d.shadow = cfg;
    if (cfg.sample.enabled)
        fprintf(stderr,
                "afmtwind: %s: a sample under the tip (issue 18): the tip starts at (0, 0); "
                "scan_t commands on %sSCAN move it\n",
                d.opt.config_path, d.opt.prefix ? d.opt.prefix : "AFMTWIN_");

    /* Signals go to main only (sigtimedwait); threads inherit the mask. */
    sigset_t sigs;
    sigemptyset(&sigs);
    sigaddset(&sigs, SIGTERM);
    sigaddset(&sigs, SIGINT);
    sigaddset(&sigs, SIGHUP);
    pthread_sigmask(SIG_BLOCK, &sigs, NULL);

    twind_rt_setup_process(d.rt_warn, sizeof d.rt_warn);
    if (twind_scheme_choose(&d, &cfg, err, sizeof err)) {
        fprintf(stderr, "afmtwind: %s: measuring the schemes: %s\n", d.opt.config_path, err);
        return 1;
    }
    char a0_err[AFM_ERR_LEN] = "";
    const afm_a0 a0 = started_a0(&d, &cfg, a0_err, sizeof a0_err);
    long long block, ring;
    if (start_runner(&d, &cfg, &block, &ring, err, sizeof err)) {
        fprintf(stderr, "afmtwind: %s: %s\n", d.opt.config_path, err);
        return 1;
    }
    afm_io_sink sink = twind_sink(&d);
    if (start_queues(&d, err, sizeof err) || start_transports(&d, &cfg, &sink, err, sizeof err)) {
        fprintf(stderr, "afmtwind: %s\n", err);
        release(&d);
        return 1;
    }
    /* the scheme the runner starts in (the config's, as scheme.c resolved it) */
    bool acc0 = !strcmp(afm_sim_scheme_name(afm_runner_sim(d.runner)), "accurate");
    if (twind_applied_open(&d, acc0, err, sizeof err)) {
        fprintf(stderr, "afmtwind: %s\n", err);
        release(&d);
        return 1;
    }
    if (twind_a0_start(&d, &cfg, a0_scheme(&d, &cfg), &a0) || twind_bw_start(&d)) {
        fprintf(stderr, "afmtwind: cannot start the A0 threads\n");
        release(&d);
        return 1;
    }
    twind_threads t;
    if (start_threads(&d, &t)) {
        fprintf(stderr, "afmtwind: cannot start threads\n");
        exit(1); /* threads may be running: no orderly way back */
    }
    print_started(&d, cfg.sim.sample_rate_hz, block, ring, &a0, a0_err);
    print_streams(&cfg);
    twind_notify_ready();

    twind_watch w = {.last_beat = -1};
    run_until_stopped(&d, &sigs, &w);
    twind_notify_stopping();
    stop_threads(&d, &t);
    twind_applied_close(&d);
    char line[1024];
    status_line(&d, &w.rs, line, sizeof line);
    fprintf(stderr, "afmtwind: final: %s\n", line);
    release(&d);
    return 0;
}
