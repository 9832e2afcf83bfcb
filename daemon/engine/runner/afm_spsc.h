/* SPDX-License-Identifier: MIT */
/* afm_spsc.h -- a bounded lock-free single-producer single-consumer queue of fixed-size
 * items (C11 atomics): how commands reach the real-time thread and outputs leave it.
 *
 * Exactly one thread pushes and exactly one thread pops (they may be the same). Push and
 * pop never block, lock or allocate: push fails when full, pop when empty. Items are
 * copied in and out, or written and read in place (reserve/commit, peek/release) for
 * large items. Memory order: the producer's item stores happen-before the consumer's loads
 * (release on the write index, acquire on reading it), and the consumer's loads finish
 * before the slot is handed back (release on the read index).
 *
 * Capacity is rounded up to a power of two; indices run freely (size_t wrap-around is
 * harmless because only differences are used). Allocation in init only. */
#ifndef AFM_SPSC_H
#define AFM_SPSC_H

#include <stdatomic.h>
#include <stdbool.h>
#include <stddef.h>
#include <string.h>

typedef struct {
    /* producer and consumer indices on separate cache lines (no false sharing) */
    _Alignas(64) atomic_size_t head; /* next slot to write (producer owns) */
    _Alignas(64) atomic_size_t tail; /* next slot to read (consumer owns) */
    _Alignas(64) size_t mask;        /* capacity - 1 */
    size_t item_size;                /* bytes per item */
    size_t stride;                   /* bytes per slot (item_size rounded up to 64) */
    unsigned char *slots;
} afm_spsc;

/* capacity >= 1 items of item_size >= 1 bytes. 0, or -1 with err. */
int afm_spsc_init(afm_spsc *q, size_t capacity, size_t item_size, char *err, size_t errlen);
void afm_spsc_destroy(afm_spsc *q);

static inline size_t afm_spsc_capacity(const afm_spsc *q) {
    return q->mask + 1;
}

/* Items waiting (exact for either side's own view; a snapshot for anyone else). */
static inline size_t afm_spsc_count(afm_spsc *q) {
    size_t h = atomic_load_explicit(&q->head, memory_order_acquire);
    size_t t = atomic_load_explicit(&q->tail, memory_order_acquire);
    return h - t;
}

/* Producer: a slot to fill in place, or NULL when full. Nothing is visible to the consumer
 * until afm_spsc_commit. */
static inline void *afm_spsc_reserve(afm_spsc *q) {
    size_t h = atomic_load_explicit(&q->head, memory_order_relaxed);
    size_t t = atomic_load_explicit(&q->tail, memory_order_acquire);
    if (h - t > q->mask) return NULL;
    return q->slots + (h & q->mask) * q->stride;
}
static inline void afm_spsc_commit(afm_spsc *q) {
    size_t h = atomic_load_explicit(&q->head, memory_order_relaxed);
    atomic_store_explicit(&q->head, h + 1, memory_order_release);
}

/* Producer: copy item in. false when full (nothing changed). */
static inline bool afm_spsc_push(afm_spsc *q, const void *item) {
    void *slot = afm_spsc_reserve(q);
    if (!slot) return false;
    memcpy(slot, item, q->item_size);
    afm_spsc_commit(q);
    return true;
}

/* Consumer: the oldest item in place, or NULL when empty; valid until afm_spsc_release. */
static inline void *afm_spsc_peek(afm_spsc *q) {
    size_t t = atomic_load_explicit(&q->tail, memory_order_relaxed);
    size_t h = atomic_load_explicit(&q->head, memory_order_acquire);
    if (h == t) return NULL;
    return q->slots + (t & q->mask) * q->stride;
}
static inline void afm_spsc_release(afm_spsc *q) {
    size_t t = atomic_load_explicit(&q->tail, memory_order_relaxed);
    atomic_store_explicit(&q->tail, t + 1, memory_order_release);
}

/* Consumer: copy the oldest item out. false when empty. */
static inline bool afm_spsc_pop(afm_spsc *q, void *item) {
    void *slot = afm_spsc_peek(q);
    if (!slot) return false;
    memcpy(item, slot, q->item_size);
    afm_spsc_release(q);
    return true;
}

#endif
