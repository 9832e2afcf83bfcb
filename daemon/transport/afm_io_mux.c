/* SPDX-License-Identifier: MIT */
/* afm_io_mux.c -- several transports as one afm_io (LCM and CAN side by side): one poll(2)
 * over their descriptors on the receive thread, outputs and status to all of them. */
#include "transport/afm_io.h"

#include <poll.h>
#include <stdio.h>
#include <stdlib.h>

#define MUX_MAX 4

typedef struct {
    afm_io io;
    int n;
    afm_io *child[MUX_MAX];
} mux_io;

static int mux_poll(afm_io *io, int timeout_ms) {
    mux_io *m = io->impl;
    struct pollfd p[MUX_MAX];
    int np = 0, wait = timeout_ms, rc = 0;
    bool all_fds = true;
    for (int i = 0; i < m->n; i++) {
        afm_io *c = m->child[i];
        int max_ms = -1, fd = c->ops->wait_fd ? c->ops->wait_fd(c, &max_ms) : -1;
        if (!c->ops->wait_fd) all_fds = false;
        if (fd >= 0) p[np++] = (struct pollfd){.fd = fd, .events = POLLIN};
        if (max_ms >= 0 && (wait < 0 || max_ms < wait)) wait = max_ms;
    }
    if (!all_fds) {
        /* A transport without a descriptor: share the time out between them. */
        int slice = timeout_ms < 0 ? 50 : timeout_ms / m->n;
        for (int i = 0; i < m->n; i++)
            if (m->child[i]->ops->poll(m->child[i], m->child[i]->ops->wait_fd ? 0 : slice) < 0)
                rc = -1;
        return rc;
    }
    if (wait != 0) poll(np ? p : NULL, (nfds_t)np, wait);
    for (int i = 0; i < m->n; i++)
        if (m->child[i]->ops->poll(m->child[i], 0) < 0) rc = -1;
    return rc;
}

static int mux_samples(afm_io *io, const afm_io_samples *s) {
    mux_io *m = io->impl;
    int rc = 0;
    for (int i = 0; i < m->n; i++)
        if (m->child[i]->ops->publish_samples(m->child[i], s) < 0) rc = -1;
    return rc;
}

static int mux_harmonics(afm_io *io, const afm_io_harmonics *h) {
    mux_io *m = io->impl;
    int rc = 0;
    for (int i = 0; i < m->n; i++)
        if (m->child[i]->ops->publish_harmonics(m->child[i], h) < 0) rc = -1;
    return rc;
}

static void mux_annotate(afm_io *io, afm_io_status *s) {
    mux_io *m = io->impl;
    for (int i = 0; i < m->n; i++)
        if (m->child[i]->ops->annotate_status) m->child[i]->ops->annotate_status(m->child[i], s);
}

/* The record comes annotated (the daemon calls annotate_status when it fills it). */
static int mux_status(afm_io *io, const afm_io_status *s) {
    mux_io *m = io->impl;
    int rc = 0;
    for (int i = 0; i < m->n; i++)
        if (m->child[i]->ops->publish_status(m->child[i], s) < 0) rc = -1;
    return rc;
}

static int mux_tick_done(afm_io *io, const afm_io_tick_done *d) {
    mux_io *m = io->impl;
    int rc = 0;
    for (int i = 0; i < m->n; i++)
        if (m->child[i]->ops->publish_tick_done &&
            m->child[i]->ops->publish_tick_done(m->child[i], d) < 0)
            rc = -1;
    return rc;
}

static int mux_wait_fd(afm_io *io, int *max_wait_ms) {
    /* Only one descriptor could be handed on: a mux inside a mux is polled by time. */
    (void)io;
    if (max_wait_ms) *max_wait_ms = 10;
    return -1;
}

static void mux_destroy(afm_io *io) {
    mux_io *m = io->impl;
    for (int i = 0; i < m->n; i++)
        afm_io_destroy(&m->child[i]);
    free(m);
}

static const afm_io_ops mux_ops = {
    .name = "mux",
    .poll = mux_poll,
    .publish_samples = mux_samples,
    .publish_harmonics = mux_harmonics,
    .publish_status = mux_status,
    .destroy = mux_destroy,
    .wait_fd = mux_wait_fd,
    .annotate_status = mux_annotate,
    .publish_tick_done = mux_tick_done,
};

afm_io *afm_io_mux_create(afm_io *const *io, int n, char *err, size_t errlen) {
    mux_io *m = NULL;
    if (!io || n < 1 || n > MUX_MAX) {
        snprintf(err, errlen, "afm_io_mux_create: 1 to %d transports, got %d", MUX_MAX, n);
        goto fail;
    }
    m = calloc(1, sizeof *m);
    if (!m) {
        snprintf(err, errlen, "out of memory");
        goto fail;
    }
    m->io.ops = &mux_ops;
    m->io.impl = m;
    m->io.sink = io[0]->sink;
    m->n = n;
    for (int i = 0; i < n; i++)
        m->child[i] = io[i];
    return &m->io;
fail:
    for (int i = 0; io && i < n && i < MUX_MAX; i++) {
        afm_io *c = io[i];
        afm_io_destroy(&c);
    }
    return NULL;
}
