/* SPDX-License-Identifier: MIT */
/* publish.c -- the publish thread: samples and harmonics records from the RT thread's rings
 * out through the transport, the completions of ticks and steps right after the outputs
 * committed before them (with the digest of the messages since the previous completion,
 * afm_lcm_digest), and the status at 10 Hz (and once more at shutdown). The last completion
 * is kept: a lockstep client's re-sent tick (cmd_in.c) asks for it again. */
#include "twind.h"

#include "runner/afm_fm.h"
#include "transport/afm_lcm_encode.h"

#include <errno.h>
#include <sched.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#define STATUS_PERIOD_S 0.1
#define DRAIN_ROUNDS 64 /* per loop: then the status, and a yield */

void twind_status_fill(twind *d, afm_io_status *o, twind_rtf_state *rs) {
    twind_snapshot s;
    twind_chain_snapshot cs;
    twind_snap_read(d, &s);
    twind_csnap_read(d, &cs);
    double wall = twind_mono_now();
    memset(o, 0, sizeof *o);
    o->utime = twind_utime_now();
    o->seq_applied = s.st.seq_applied;
    o->model_time_s = s.st.t_s;
    if (!atomic_load_explicit(&d->rt_done, memory_order_acquire)) {
        if (rs->wall > 0 && wall > rs->wall) rs->rtf = (s.st.t_s - rs->model) / (wall - rs->wall);
        rs->wall = wall;
        rs->model = s.st.t_s;
    }
    o->realtime_factor = rs->rtf;
    o->overruns = s.overruns;
    o->lag_s = s.lag_s;
    /* The transports' own fields first (CAN state; what LCM dropped before any handler). */
    if (d->io && d->io->ops->annotate_status) d->io->ops->annotate_status(d->io, o);
    pthread_mutex_lock(&d->lock);
    o->received = d->received + o->dropped; /* dropped ones were received, then lost */
    o->rejected = d->rejected;
    o->refused = d->refused + s.refused; /* queue full here; the twin's own refusals */
    snprintf(o->last_reject, sizeof o->last_reject, "%s", d->last_reject);
    snprintf(o->last_refusal, sizeof o->last_refusal, "%s", d->last_refusal);
    pthread_mutex_unlock(&d->lock);
    o->auto_paused = s.st.auto_paused;
    afm_runner_pause_reason(&s.st, o->pause_reason, sizeof o->pause_reason);
    o->blowups = s.st.blowups;
    o->mode = twind_mode_name(d->opt.mode);
    o->running = s.st.running;
    o->separation_m = s.st.separation_m;
    o->fe_hz = s.st.fe_hz;
    o->amplitude_m = s.st.amplitude_m;
    o->applied = s.st.applied;
    o->tick_resends = atomic_load_explicit(&d->tick_resends, memory_order_relaxed);
    o->republished = atomic_load_explicit(&d->republished, memory_order_relaxed);
    o->resyncs = s.resyncs;
    o->chain_stalls = s.st.stalls;
    double lag = s.st.t_s - cs.st.t_s; /* model time integrated but not yet through the chain */
    o->chain_lag_s = lag > 0 ? lag : 0;
    o->realtime_factor_1s = s.rtf_1s;
    o->resync_skipped_s = s.resync_dropped_s;
    o->lockin_amplitude_m = cs.have_period ? cs.lockin_amplitude_m : NAN;
    o->lockin_phase_deg = cs.have_period ? cs.lockin_phase_deg : NAN;
    o->peak_force_n = cs.have_period ? cs.peak_force_n : NAN;
    o->squeeze_dissipated_energy_j = cs.have_period ? cs.squeeze_dissipated_energy_j : NAN;
    if (d->scheme.rt) {
        snprintf(o->rt_scheme, sizeof o->rt_scheme, "%s", s.scheme_accurate ? "accurate" : "fast");
        snprintf(o->rt_scheme_reason, sizeof o->rt_scheme_reason, "%s",
                 s.scheme_reason[0] ? s.scheme_reason : d->scheme.reason);
    } else {
        snprintf(o->rt_scheme, sizeof o->rt_scheme, "-");
        snprintf(o->rt_scheme_reason, sizeof o->rt_scheme_reason, "%s", d->scheme.reason);
    }
    o->scheme_handovers = s.scheme_handovers;
    o->model_s_accurate = s.model_s_accurate;
    o->model_s_fast = s.model_s_fast;
    o->fm_control = s.st.fm_on ? "internal" : "none"; /* issue 32 */
    o->fm_drive = s.st.fm_on ? afm_fm_drive_name((afm_fm_drive)s.st.fm_drive) : "none";
    o->fm_lock_state = s.st.fm_on ? afm_fm_lock_name((afm_fm_lock)s.st.fm_lock) : "";
    o->fm_frequency_hz = s.st.fm_frequency_hz;
    o->fm_reference_hz = s.st.fm_reference_hz;
    o->fm_frequency_shift_hz = s.st.fm_frequency_hz - s.st.fm_reference_hz;
    o->fm_phase_error_deg = s.st.fm_phase_error_deg;
    o->fm_drive_amplitude_m = s.st.fm_drive_m;
    o->fm_amplitude_m = s.st.fm_amplitude_m;
    o->fm_amplitude_setpoint_m = s.st.fm_amplitude_setpoint_m;
    o->fm_tone_changes = s.st.fm_tone_changes;
    o->sample_on = s.st.sample_on; /* issue 18 */
    o->tip_x_m = s.st.tip_x_m;
    o->tip_y_m = s.st.tip_y_m;
    o->true_height_m = s.st.true_height_m;
    o->material = s.st.material;
    o->scan_mode = afm_scan_mode_name(s.st.scan_mode);
    o->scan_line = s.st.scan_line;
    o->scan_pixel = s.st.scan_pixel;
    o->scan_retrace = s.st.scan_retrace;
    o->am_control = s.st.am_on ? "internal" : "none";
    o->am_z_m = s.st.am_z_m;
    o->am_error_m = s.st.am_error_m;
    o->am_setpoint_m = s.st.am_setpoint_m;
    o->am_amplitude_m = s.st.am_amplitude_m;
    if (d->scheme.rt && s.blocks > 0) /* the rt thread has written its scheme: hand-overs */
        twind_a0_scheme(d, s.scheme_accurate);
    o->free_amplitude_m = twind_a0_now(d); /* issue 30: NaN while being recomputed */
    o->amplitude_ratio =
        o->free_amplitude_m > 0 ? o->lockin_amplitude_m / o->free_amplitude_m : NAN;
    pthread_mutex_lock(&d->lock);
    o->last_reject_age_s = d->last_reject[0] ? wall - d->last_reject_mono : -1.0;
    o->last_reject_old = d->last_reject[0] && s.last_applied_order > d->last_reject_order;
    pthread_mutex_unlock(&d->lock);
}

/* What the publisher keeps between calls: records published, and the digest of those since
 * the last completion. */
typedef struct {
    long long samples_recs, harm_recs;
    afm_lcm_digest dg;
    bool have_last;
    afm_io_tick_done last;   /* the last completion published */
    long long republish_req; /* the receive thread's requests seen */
} pub_state;

/* A re-sent tick (cmd_in.c) asks for the completion of its seq again: published again, as it
 * was (counts and digests of the outputs before it; a new utime and message number), if it
 * is the last one published; otherwise that completion is still to come (the tick is
 * running, or the outputs before it are) and comes once, or the seq is not the last one
 * (the client moved on): nothing. */
static void republish(twind *d, pub_state *p) {
    long long req = atomic_load_explicit(&d->republish_req, memory_order_acquire);
    if (req == p->republish_req) return;
    p->republish_req = req;
    int64_t seq = atomic_load_explicit(&d->republish_seq, memory_order_relaxed);
    if (!p->have_last || p->last.seq != seq) return;
    afm_io_tick_done td = p->last;
    td.utime = twind_utime_now();
    if (d->io->ops->publish_tick_done) d->io->ops->publish_tick_done(d->io, &td);
    atomic_fetch_add_explicit(&d->republished, 1, memory_order_relaxed);
}

/* The waiting records and completions, at most DRAIN_ROUNDS rounds of one of each, in the
 * order the chain thread committed them: a record only while no completion committed before
 * it waits, a completion once the records committed before it are out (its counts), with the
 * digest of the messages since the previous one. Records are peeked before the completion
 * queue, so a completion committed before a record is always seen first. Bounded, so that a
 * backlog that never empties (the publisher behind) still leaves the loop its status and a
 * yield. true when it stopped at the bound with work left. */
static bool drain(twind *d, pub_state *p) {
    int rounds = 0;
    bool progress = true;
    for (; progress && rounds < DRAIN_ROUNDS; rounds++) {
        progress = false;
        twind_done_item *it;
        afm_io_samples *s = afm_spsc_peek(&d->samples_q);
        it = afm_spsc_peek(&d->done_q);
        if (s && (!it || p->samples_recs < it->samples_recs)) {
            d->io->ops->publish_samples(d->io, s);
            afmtwin_samples_t m;
            afm_lcm_samples_msg(s, &m);
            afm_lcm_digest_samples(&p->dg, &m);
            afm_spsc_release(&d->samples_q);
            p->samples_recs++;
            progress = true;
        }
        afm_io_harmonics *h = afm_spsc_peek(&d->harm_q);
        it = afm_spsc_peek(&d->done_q);
        if (h && (!it || p->harm_recs < it->harm_recs)) {
            d->io->ops->publish_harmonics(d->io, h);
            afm_lcm_harm_buf b;
            afmtwin_harmonics_t m;
            afm_lcm_harmonics_msg(h, &b, &m);
            afm_lcm_digest_harmonics(&p->dg, &m);
            afm_spsc_release(&d->harm_q);
            p->harm_recs++;
            progress = true;
        }
        it = afm_spsc_peek(&d->done_q);
        if (it && p->samples_recs >= it->samples_recs && p->harm_recs >= it->harm_recs) {
            afm_io_tick_done td = {.utime = twind_utime_now(),
                                   .seq = it->d.seq,
                                   .samples = it->d.samples,
                                   .model_time_s = it->d.t_s,
                                   .n_samples_msgs = p->dg.n_samples_msgs,
                                   .n_harmonics_msgs = p->dg.n_harmonics_msgs,
                                   .samples_digest = afm_lcm_digest_samples_final(&p->dg),
                                   .harmonics_digest = p->dg.harmonics};
            if (d->io->ops->publish_tick_done) d->io->ops->publish_tick_done(d->io, &td);
            p->last = td;
            p->have_last = true;
            afm_lcm_digest_init(&p->dg);
            afm_spsc_release(&d->done_q);
            progress = true;
        }
    }
    return progress;
}

void *twind_pub_main(void *arg) {
    twind_thread_name("afm-pub");
    twind *d = arg;
    twind_rt_setup_aux(d->opt.rt_priority - 10, d->opt.aux_cpu);
    twind_rtf_state rs = {0, 0, 0};
    double next_status = twind_mono_now();
    static afm_io_status st; /* large (reason strings) */
    pub_state ps = {0};
    afm_lcm_digest_init(&ps.dg);
    for (bool more = false;;) {
        if (!more) { /* (with work left from the last loop: no wait) */
            struct timespec ts = twind_deadline_in(20000000L);
            while (sem_timedwait(&d->out_sem, &ts) != 0 && errno == EINTR) {
            }
        }
        while (sem_trywait(&d->out_sem) == 0) { /* the posts so far: the drain sees their items */
        }
        more = drain(d, &ps);
        republish(d, &ps);
        double now = twind_mono_now();
        if (now >= next_status) {
            twind_status_fill(d, &st, &rs);
            d->io->ops->publish_status(d->io, &st);
            next_status += STATUS_PERIOD_S;
            if (next_status < now) next_status = now + STATUS_PERIOD_S;
        }
        if (atomic_load_explicit(&d->chain_done, memory_order_acquire)) break;
        /* Behind (its semaphore already posted again) it would never block, and at SCHED_FIFO
         * the receive and main threads of its priority on its CPU would wait for it for as
         * long as it has work: a daemon pinned beside its integrator (--aux-cpu = --cpu) that
         * fell behind took commands and SIGTERM minutes late. To the tail of its priority. */
        sched_yield();
    }
    while (drain(d, &ps)) {
    }
    twind_status_fill(d, &st, &rs);
    d->io->ops->publish_status(d->io, &st); /* the final status */
    return NULL;
}
