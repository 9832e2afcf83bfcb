/* SPDX-License-Identifier: MIT */
/* afm_lcm_drops.c -- LCM's queue drops (by interposing lcm_try_enqueue_message) and the
 * kernel's socket drops (/proc/self/net/udp); contract in afm_lcm_drops.h. */
#define _GNU_SOURCE
#include "transport/afm_lcm_drops.h"

#include <dirent.h>
#include <dlfcn.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define WATCHES 4

typedef struct {
    _Atomic(lcm_t *) lcm;
    int n;
    const char *const *channel;
    atomic_llong drops[AFM_LCM_DROPS_CHANNELS];
} watch;

static watch watches[WATCHES];
static atomic_llong calls; /* every call that came through here (the self-test) */

/* liblcm's internal provider API (lcm_internal.h), exported from liblcm.so. */
int lcm_try_enqueue_message(lcm_t *lcm, const char *channel);

typedef int (*try_enqueue_fn)(lcm_t *, const char *);

static try_enqueue_fn real_try_enqueue(void) {
    static _Atomic(try_enqueue_fn) fn;
    try_enqueue_fn f = atomic_load(&fn);
    if (!f) {
        void *p = dlsym(RTLD_NEXT, "lcm_try_enqueue_message");
        memcpy(&f, &p, sizeof f);
        atomic_store(&fn, f);
    }
    return f;
}

int lcm_try_enqueue_message(lcm_t *lcm, const char *channel) {
    try_enqueue_fn f = real_try_enqueue();
    int kept = f ? f(lcm, channel) : 1;
    atomic_fetch_add_explicit(&calls, 1, memory_order_relaxed);
    if (kept) return kept;
    for (int w = 0; w < WATCHES; w++) {
        watch *x = &watches[w];
        if (atomic_load_explicit(&x->lcm, memory_order_acquire) != lcm) continue;
        for (int i = 0; i < x->n; i++)
            if (!strcmp(channel, x->channel[i]))
                atomic_fetch_add_explicit(&x->drops[i], 1, memory_order_relaxed);
    }
    return kept;
}

int afm_lcm_drops_watch(lcm_t *lcm, const char *const *channels, int n) {
    if (!lcm || n < 0 || n > AFM_LCM_DROPS_CHANNELS) return -1;
    for (int w = 0; w < WATCHES; w++) {
        watch *x = &watches[w];
        if (atomic_load(&x->lcm)) continue;
        x->n = n;
        x->channel = channels;
        for (int i = 0; i < AFM_LCM_DROPS_CHANNELS; i++)
            atomic_store(&x->drops[i], 0);
        atomic_store_explicit(&x->lcm, lcm, memory_order_release);
        return w;
    }
    return -1;
}

void afm_lcm_drops_unwatch(int id) {
    if (id >= 0 && id < WATCHES) atomic_store(&watches[id].lcm, NULL);
}

long long afm_lcm_drops_queue(int id, int i) {
    if (id < 0 || id >= WATCHES || i < 0 || i >= AFM_LCM_DROPS_CHANNELS) return 0;
    return atomic_load_explicit(&watches[id].drops[i], memory_order_relaxed);
}

static void nothing(const lcm_recv_buf_t *rb, const char *ch, void *u) {
    (void)rb;
    (void)ch;
    (void)u;
}

bool afm_lcm_drops_visible(void) {
    static atomic_int result; /* 0 unknown, 1 visible, -1 not */
    int r = atomic_load(&result);
    if (r) return r > 0;
    /* A message published on a memq instance goes through lcm_try_enqueue_message: if it
     * passes here, so do udpm's. */
    long long before = atomic_load(&calls);
    lcm_t *l = lcm_create("memq://");
    if (l) {
        lcm_subscribe(l, "AFM_LCM_DROPS_SELF_TEST", nothing, NULL);
        lcm_publish(l, "AFM_LCM_DROPS_SELF_TEST", "x", 1);
        while (lcm_handle_timeout(l, 0) > 0) {
        }
        lcm_destroy(l);
    }
    r = atomic_load(&calls) > before ? 1 : -1;
    atomic_store(&result, r);
    return r > 0;
}

int afm_udp_sockets(unsigned long *inode, int max) {
    DIR *dir = opendir("/proc/self/fd");
    if (!dir) return 0;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(dir)) != NULL && n < max) {
        char path[300], link[64];
        snprintf(path, sizeof path, "/proc/self/fd/%s", e->d_name);
        ssize_t k = readlink(path, link, sizeof link - 1);
        if (k <= 0) continue;
        link[k] = 0;
        unsigned long ino;
        if (sscanf(link, "socket:[%lu]", &ino) == 1) inode[n++] = ino;
    }
    closedir(dir);
    return n;
}

/* One /proc/net/udp-format file: drops of our sockets on port. */
static long long drops_in(const char *file, const unsigned long *inode, int n, int port,
                          int *found) {
    FILE *f = fopen(file, "r");
    if (!f) return -1;
    char line[512];
    long long sum = 0;
    if (!fgets(line, sizeof line, f)) { /* header */
        fclose(f);
        return 0;
    }
    while (fgets(line, sizeof line, f)) {
        char local[64];
        unsigned long ino;
        long long drops;
        /* sl local rem st tx:rx tr:tm retr uid timeout inode ref ptr drops */
        if (sscanf(line, "%*s %63s %*s %*s %*s %*s %*s %*s %*s %lu %*s %*s %lld", local, &ino,
                   &drops) != 3)
            continue;
        const char *colon = strrchr(local, ':');
        if (!colon || (int)strtol(colon + 1, NULL, 16) != port) continue;
        for (int i = 0; i < n; i++)
            if (inode[i] == ino) {
                sum += drops;
                (*found)++;
            }
    }
    fclose(f);
    return sum;
}

long long afm_udp_drops(const unsigned long *inode, int n, int port) {
    int found = 0;
    long long a = drops_in("/proc/self/net/udp", inode, n, port, &found);
    long long b = drops_in("/proc/self/net/udp6", inode, n, port, &found);
    if (a < 0 && b < 0) return -1;
    return (a > 0 ? a : 0) + (b > 0 ? b : 0);
}
