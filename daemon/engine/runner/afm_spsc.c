/* SPDX-License-Identifier: MIT */
/* afm_spsc.c -- allocation for the lock-free SPSC queue (contract in afm_spsc.h). */
#include "runner/afm_spsc.h"

#include <stdio.h>
#include <stdlib.h>

int afm_spsc_init(afm_spsc *q, size_t capacity, size_t item_size, char *err, size_t errlen) {
    if (capacity < 1 || capacity > ((size_t)1 << 30) || item_size < 1 ||
        item_size > ((size_t)1 << 26)) {
        if (err && errlen)
            snprintf(err, errlen, "spsc: capacity %zu or item size %zu out of range", capacity,
                     item_size);
        return -1;
    }
    size_t cap = 1;
    while (cap < capacity)
        cap <<= 1;
    /* Slots aligned for any item type (64: also keeps large items on cache lines). */
    size_t stride = (item_size + 63) & ~(size_t)63;
    unsigned char *slots = aligned_alloc(64, cap * stride);
    if (!slots) {
        if (err && errlen)
            snprintf(err, errlen, "spsc: cannot allocate %zu x %zu bytes", cap, stride);
        return -1;
    }
    memset(slots, 0, cap * stride);
    atomic_init(&q->head, 0);
    atomic_init(&q->tail, 0);
    q->mask = cap - 1;
    q->item_size = item_size;
    q->stride = stride;
    q->slots = slots;
    return 0;
}

void afm_spsc_destroy(afm_spsc *q) {
    if (!q) return;
    free(q->slots);
    q->slots = NULL;
}
