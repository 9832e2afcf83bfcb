/* SPDX-License-Identifier: MIT */
/* applied_log.c -- `afmtwind --applied-log FILE`: every command the twin applied, in order,
 * stamped with the sample at which it applied, as an LCM log that `afmtwin replay --applied`
 * runs again bit for bit. Why: lcm-logger stamps a command with the wall time it arrived,
 * and the rt thread applies it at its next ring item (later while the output chain is
 * behind), so a replay by arrival times reproduces a real-time run only to rounding of the
 * drive (~1e-8 of the lock-in under a 10 kHz FM stream); the sample is what decides.
 *
 * The rt thread pushes each applied command (a copy) with the samples run before it onto
 * applied_q, and each scheme hand-over; it never waits: a full queue is counted (the log is
 * then incomplete, and the daemon says so at the end). A writer thread of its own (afm-log,
 * SCHED_OTHER on any CPU: file I/O can block, and no real-time thread may wait on a disk;
 * in the receive thread, a 10 kHz stream's 60 s log stalled command intake under load) writes
 * them every WRITER_NAP_NS: the event's time stamp is the sample count, the channel PREFIX + the
 * command's kind, the body the command encoded again (afm_cmd_encode: bit for bit). The scheme in
 * force is an event on PREFIX "SCHEME" (one byte: 1 accurate, 0 fast), at sample 0 for the start,
 * at every hand-over and at the last sample the twin ran (the end of the log). A SIGHUP reload
 * comes from no message: counted, not in the log (a replay cannot follow it; the daemon says so).
 */
#define _GNU_SOURCE /* pthread_setaffinity_np, CPU_SET for the writer */
#include "twind.h"
#include "transport/afm_cmd_lcm.h"

#include <lcm/eventlog.h>

#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#define APPLIED_Q_LEN 65536 /* 6.5 s of a 10 kHz stream (~20 MB) for a writer held off the CPU */
#define APPLIED_MSG_MAX 4096
#define WRITER_NAP_NS 5000000L /* 5 ms between drains */

/* One event into the file (the writer thread afm-log, or main before it starts and after it
 * is joined: never two at once). */
static void write_event(twind *d, int64_t sample, const char *suffix, const void *body, int len) {
    char ch[128];
    snprintf(ch, sizeof ch, "%s%s", d->opt.prefix ? d->opt.prefix : "AFMTWIN_", suffix);
    lcm_eventlog_event_t ev = {.eventnum = d->applied.written,
                               .timestamp = sample,
                               .channellen = (int32_t)strlen(ch),
                               .datalen = len,
                               .channel = ch,
                               .data = (void *)body};
    if (lcm_eventlog_write_event(d->applied.log, &ev) == 0)
        d->applied.written++;
    else
        d->applied.failed++;
}

static void drain(twind *d);

/* The writer: ordinary scheduling on every CPU (main, which starts it, is SCHED_FIFO and may
 * be pinned: the rt thread's core must not carry file I/O), a drain every WRITER_NAP_NS. */
static void *writer_main(void *arg) {
    twind *d = arg;
    twind_thread_name("afm-log");
    struct sched_param sp = {.sched_priority = 0};
    (void)pthread_setschedparam(pthread_self(), SCHED_OTHER, &sp);
    cpu_set_t all;
    CPU_ZERO(&all);
    for (int i = 0; i < CPU_SETSIZE; i++)
        CPU_SET(i, &all);
    (void)pthread_setaffinity_np(pthread_self(), sizeof all, &all);
    while (!atomic_load_explicit(&d->applied.stop, memory_order_acquire)) {
        drain(d);
        struct timespec w = {0, WRITER_NAP_NS};
        nanosleep(&w, NULL);
    }
    return NULL;
}

int twind_applied_open(twind *d, bool accurate, char *err, size_t errlen) {
    if (!d->opt.applied_log) return 0;
    if (d->opt.start_s > 0) {
        snprintf(err, errlen,
                 "--applied-log: not with --start-time (a replay's samples count from 0)");
        return -1;
    }
    if (afm_spsc_init(&d->applied.q, APPLIED_Q_LEN, sizeof(twind_applied), err, errlen)) return -1;
    d->applied.log = lcm_eventlog_create(d->opt.applied_log, "w");
    if (!d->applied.log) {
        snprintf(err, errlen, "--applied-log: cannot write '%s'", d->opt.applied_log);
        afm_spsc_destroy(&d->applied.q);
        return -1;
    }
    uint8_t b = accurate;
    write_event(d, 0, "SCHEME", &b, 1);
    if (pthread_create(&d->applied.th, NULL, writer_main, d) != 0) {
        snprintf(err, errlen, "--applied-log: cannot start its writer thread");
        lcm_eventlog_destroy(d->applied.log);
        d->applied.log = NULL;
        afm_spsc_destroy(&d->applied.q);
        return -1;
    }
    return 0;
}

void twind_applied_cmd(twind *d, const afm_cmd *c, long long sample) {
    if (!d->applied.log) return;
    twind_applied a = {.sample = sample, .scheme = -1, .cmd = *c};
    if (!afm_spsc_push(&d->applied.q, &a))
        atomic_fetch_add_explicit(&d->applied.lost, 1, memory_order_relaxed);
}

void twind_applied_scheme(twind *d, bool accurate, long long sample) {
    if (!d->applied.log) return;
    twind_applied a = {.sample = sample, .scheme = accurate};
    if (!afm_spsc_push(&d->applied.q, &a))
        atomic_fetch_add_explicit(&d->applied.lost, 1, memory_order_relaxed);
}

static void drain(twind *d) {
    static twind_applied a; /* the writer's (main's after it stopped) */
    static uint8_t body[APPLIED_MSG_MAX];
    while (afm_spsc_pop(&d->applied.q, &a)) {
        if (a.scheme >= 0) {
            uint8_t b = (uint8_t)a.scheme;
            write_event(d, a.sample, "SCHEME", &b, 1);
            continue;
        }
        const char *suffix = afm_cmd_channel_suffix(a.cmd.kind);
        int len = suffix ? afm_cmd_encode(&a.cmd, body, (int)sizeof body) : -1;
        if (len < 0) {
            d->applied.unlogged++; /* a reload */
            continue;
        }
        write_event(d, a.sample, suffix, body, len);
    }
}

void twind_applied_close(twind *d) {
    if (!d->applied.log) return;
    atomic_store_explicit(&d->applied.stop, 1, memory_order_release);
    pthread_join(d->applied.th, NULL);
    drain(d);
    /* the last event: the scheme in force at the last sample run, so that a replay runs as
     * far as the twin did (its --tail on top) */
    twind_snapshot s;
    twind_snap_read(d, &s);
    uint8_t b = s.scheme_accurate;
    write_event(d, s.st.samples, "SCHEME", &b, 1);
    lcm_eventlog_destroy(d->applied.log);
    d->applied.log = NULL;
    afm_spsc_destroy(&d->applied.q);
    long long lost = atomic_load(&d->applied.lost);
    fprintf(stderr,
            "afmtwind: --applied-log %s: %lld events (the commands applied, at their samples, "
            "and the scheme)%s",
            d->opt.applied_log, d->applied.written,
            lost || d->applied.unlogged || d->applied.failed ? "; INCOMPLETE:" : "\n");
    if (lost || d->applied.unlogged || d->applied.failed)
        fprintf(stderr,
                " %lld lost to a full queue, %lld reloads (no message), %lld writes failed: "
                "`afmtwin replay --applied` of it will differ from this run\n",
                lost, d->applied.unlogged, d->applied.failed);
}
