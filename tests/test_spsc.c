/* SPDX-License-Identifier: MIT */
/* test_spsc.c -- the lock-free SPSC queue (afm_spsc): capacity rounding, full and empty
 * behaviour, then a two-thread stress: 4 million items through a 64-slot queue (producer and
 * consumer contend on nearly every item), in order, none lost or duplicated, and every
 * item's payload intact (a torn read would break the checksum); the same with in-place
 * reserve/commit and peek/release. */
#include "runner/afm_spsc.h"
#include "check.h"

#include <pthread.h>
#include <sched.h>
#include <stdint.h>
#include <stdio.h>

#define N_ITEMS 4000000ULL

typedef struct {
    uint64_t seq;
    uint64_t payload[5]; /* 48 bytes: several stores per item */
    uint64_t sum;
} item;

static void fill(item *it, uint64_t i) {
    it->seq = i;
    it->sum = i;
    for (int k = 0; k < 5; k++) {
        it->payload[k] = i * 2654435761ULL + (uint64_t)k;
        it->sum ^= it->payload[k];
    }
}

static bool intact(const item *it) {
    uint64_t s = it->seq;
    for (int k = 0; k < 5; k++)
        s ^= it->payload[k];
    return s == it->sum;
}

typedef struct {
    afm_spsc *q;
    int in_place;
} arg;

static void *producer(void *p) {
    arg *a = p;
    item it;
    for (uint64_t i = 0; i < N_ITEMS; i++) {
        if (a->in_place) {
            item *slot;
            while ((slot = afm_spsc_reserve(a->q)) == NULL)
                sched_yield();
            fill(slot, i);
            afm_spsc_commit(a->q);
        } else {
            fill(&it, i);
            while (!afm_spsc_push(a->q, &it))
                sched_yield();
        }
    }
    return NULL;
}

static void stress(int in_place) {
    afm_spsc q;
    char err[256];
    afm_spsc_init(&q, 64, sizeof(item), err, sizeof err);
    arg a = {&q, in_place};
    pthread_t t;
    pthread_create(&t, NULL, producer, &a);
    uint64_t expect = 0, bad_order = 0, torn = 0;
    item it;
    while (expect < N_ITEMS) {
        const item *p;
        if (in_place) {
            p = afm_spsc_peek(&q);
            if (!p) {
                sched_yield();
                continue;
            }
        } else {
            if (!afm_spsc_pop(&q, &it)) {
                sched_yield();
                continue;
            }
            p = &it;
        }
        if (p->seq != expect) bad_order++;
        if (!intact(p)) torn++;
        expect = p->seq + 1;
        if (in_place) afm_spsc_release(&q);
    }
    pthread_join(t, NULL);
    char name[200];
    snprintf(name, sizeof name,
             "%s: %llu items in order (out of order %llu, torn %llu), queue empty after",
             in_place ? "reserve/commit + peek/release" : "push/pop", (unsigned long long)N_ITEMS,
             (unsigned long long)bad_order, (unsigned long long)torn);
    check_true(bad_order == 0 && torn == 0 && afm_spsc_count(&q) == 0 && !afm_spsc_pop(&q, &it),
               name);
    afm_spsc_destroy(&q);
}

int main(void) {
    afm_spsc q;
    char err[256];
    check_true(afm_spsc_init(&q, 0, 8, err, sizeof err) == -1, "capacity 0 rejected");
    check_true(afm_spsc_init(&q, 5, 0, err, sizeof err) == -1, "item size 0 rejected");
    check_true(afm_spsc_init(&q, 5, sizeof(int), err, sizeof err) == 0 &&
                   afm_spsc_capacity(&q) == 8,
               "capacity 5 rounds up to 8");
    int v, ok = 1;
    check_true(!afm_spsc_pop(&q, &v) && afm_spsc_peek(&q) == NULL, "empty: pop and peek fail");
    for (int i = 0; i < 8; i++)
        ok &= afm_spsc_push(&q, &i);
    check_true(ok && afm_spsc_count(&q) == 8, "8 pushes fill it");
    v = 99;
    check_true(!afm_spsc_push(&q, &v) && afm_spsc_reserve(&q) == NULL,
               "full: push and reserve fail");
    for (int i = 0; i < 8; i++)
        ok &= afm_spsc_pop(&q, &v) && v == i;
    check_true(ok && afm_spsc_count(&q) == 0, "8 pops return them in order");
    /* wrap-around many times */
    for (int i = 0; i < 1000; i++) {
        ok &= afm_spsc_push(&q, &i);
        ok &= afm_spsc_pop(&q, &v) && v == i;
    }
    check_true(ok, "1000 push/pop pairs across the wrap");
    afm_spsc_destroy(&q);
    afm_spsc_destroy(&q); /* twice is harmless */
    stress(0);
    stress(1);
    return check_done();
}
