/* SPDX-License-Identifier: MIT */
/* rt_setup.c -- real-time privileges for the daemon: locked memory, SCHED_FIFO and CPU
 * pinning, each when permitted (CAP_IPC_LOCK / CAP_SYS_NICE or rlimits), else a warning. */
#define _GNU_SOURCE /* pthread_setaffinity_np, CPU_SET */
#include "twind.h"

#include <errno.h>
#include <pthread.h>
#include <sched.h>
#include <stdio.h>
#include <string.h>
#include <sys/mman.h>

static void append(char *warn, size_t len, const char *fmt, const char *what, int e) {
    size_t n = strlen(warn);
    if (n + 2 >= len) return;
    snprintf(warn + n, len - n, fmt, what, strerror(e));
}

void twind_rt_setup_process(char *warn, size_t len) {
    if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
        append(warn, len, "%s failed (%s): pages may fault in the loop; ", "mlockall", errno);
}

void twind_rt_setup_thread(int priority, int cpu, char *warn, size_t len) {
    struct sched_param sp = {.sched_priority = priority};
    int e = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    if (e != 0)
        append(warn, len, "%s failed (%s): running with normal scheduling; ", "SCHED_FIFO", e);
    if (cpu >= 0) {
        cpu_set_t set;
        CPU_ZERO(&set);
        CPU_SET(cpu, &set);
        e = pthread_setaffinity_np(pthread_self(), sizeof set, &set);
        if (e != 0) append(warn, len, "%s failed (%s); ", "CPU pinning", e);
    }
    /* Touch the stack the loop will use, so that it is resident (and locked). */
    volatile char stack[256 * 1024];
    memset((char *)stack, 0, sizeof stack);
}

void twind_rt_setup_aux(int priority, int cpu) {
    struct sched_param sp = {.sched_priority = priority > 1 ? priority : 1};
    (void)pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp); /* the RT thread warned */
    if (cpu >= 0) {
        cpu_set_t set;
        CPU_ZERO(&set);
        CPU_SET(cpu, &set);
        (void)pthread_setaffinity_np(pthread_self(), sizeof set, &set);
    }
}

void twind_rt_setup_build(int priority, bool building) {
    if (!building) {
        twind_rt_setup_aux(priority, -1); /* the pinning stays */
        return;
    }
    /* SCHED_FIFO 1: below every thread of the daemon, above ordinary processes (at SCHED_OTHER
     * a build on a loaded machine took hundreds of ms, and the commands behind it waited) */
    struct sched_param sp = {.sched_priority = 1};
    if (pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) != 0) {
        sp.sched_priority = 0;
        (void)pthread_setschedparam(pthread_self(), SCHED_OTHER, &sp);
    }
}

void twind_thread_name(const char *name) {
    (void)pthread_setname_np(pthread_self(), name); /* 15 characters at most; diagnostics */
}
