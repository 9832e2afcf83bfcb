/* SPDX-License-Identifier: MIT */
/* twind_clock.c -- the clocks every daemon thread stamps and waits with (utime of the
 * messages, CLOCK_MONOTONIC for rates, sem_timedwait deadlines) and the mode's name: small
 * shared utilities, here so that cmd_in.c, publish.c and the loops need not call back into
 * afmtwind.c. */
#include "twind.h"

#include <time.h>

const char *twind_mode_name(twind_mode m) {
    switch (m) {
    case TWIND_REALTIME:
        return "realtime";
    case TWIND_FREERUN:
        return "freerun";
    case TWIND_LOCKSTEP:
        return "lockstep";
    }
    return "?";
}

int64_t twind_utime_now(void) {
    struct timespec t;
    clock_gettime(CLOCK_REALTIME, &t);
    return (int64_t)t.tv_sec * 1000000 + t.tv_nsec / 1000;
}

struct timespec twind_deadline_in(long ns) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    ts.tv_nsec += ns;
    while (ts.tv_nsec >= 1000000000L) {
        ts.tv_sec++;
        ts.tv_nsec -= 1000000000L;
    }
    return ts;
}

double twind_mono_now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}
