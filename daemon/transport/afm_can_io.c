/* SPDX-License-Identifier: MIT */
/* afm_can_io.c -- the CAN transport of the daemon (interface in afm_io.h, map in
 * afm_can_codec.h and docs/can.md): a SocketCAN raw socket on the configured interface,
 * read on the daemon's receive thread (a non-real-time thread; the real-time thread never
 * sees CAN), decoded frames handed to the same sink as LCM's.
 *
 * Health, kept under `lock` for the publish thread (annotate_status):
 *  - error frames (all classes, CAN_RAW_ERR_FILTER = CAN_ERR_MASK) are counted; controller
 *    warnings, error-passive and bus-off set the bus state, CAN_ERR_CRTL_ACTIVE and
 *    CAN_ERR_RESTARTED clear it;
 *  - a read error (ENETDOWN: interface down, ENODEV: interface gone, ...) closes the socket;
 *    it is re-opened with a backoff doubling from can.reconnect_min_s to reconnect_max_s,
 *    once the interface exists and is up;
 *  - the heartbeat frame must come every can.heartbeat_timeout_s (if > 0).
 * In every state but "ok" (and "error-warning") the twin holds the last commands it took,
 * and can_state says so: nothing is reset or replayed when the bus comes back. */
#define _DEFAULT_SOURCE /* struct ifreq, IFF_UP */
#include "transport/afm_can_codec.h"
#include "transport/afm_io.h"

#include <errno.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <math.h>
#include <net/if.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#define MAX_FRAMES_PER_POLL 512 /* then let the other transports have a turn */

typedef enum { BUS_OK = 0, BUS_WARNING = 1, BUS_PASSIVE = 2, BUS_OFF = 3 } bus_state;

typedef struct {
    afm_io io;
    afm_cfg_can map;
    char channel[40];             /* "CAN vcan0", the channel name of rejections */
    int sock;                     /* -1 while closed */
    afm_can_state regs;           /* the driver's registers as the twin took them */
    unsigned regs_gen;            /* sink->drive's number when regs last followed it */
    double retry_at_s, backoff_s; /* CLOCK_MONOTONIC */
    bool lost;                    /* had a socket and lost it: the next open is a reconnect */
    double last_hb_s;             /* < 0: no heartbeat yet */
    bus_state bus;
    /* shared with annotate_status */
    pthread_mutex_t lock;
    int64_t frames, rejected, errors, reconnects;
    char down[160]; /* why the socket is closed ("" when open) */
    char last_reject[AFM_IO_REASON_LEN];
} can_io;

static double mono_s(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int64_t wall_us(void) {
    struct timespec t;
    clock_gettime(CLOCK_REALTIME, &t);
    return (int64_t)t.tv_sec * 1000000 + t.tv_nsec / 1000;
}

/* Open, configure and bind the socket; 0, or -1 with why. */
static int open_socket(can_io *c, char *why, size_t len) {
    int s = socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
    if (s < 0) {
        snprintf(why, len, "socket(PF_CAN): %s", strerror(errno));
        return -1;
    }
    struct ifreq ifr;
    memset(&ifr, 0, sizeof ifr);
    snprintf(ifr.ifr_name, sizeof ifr.ifr_name, "%s", c->map.interface);
    if (ioctl(s, SIOCGIFINDEX, &ifr) < 0) {
        snprintf(why, len, "%s: %s", c->map.interface, strerror(errno));
        goto fail;
    }
    int ifindex = ifr.ifr_ifindex;
    if (ioctl(s, SIOCGIFFLAGS, &ifr) < 0 || !(ifr.ifr_flags & IFF_UP)) {
        snprintf(why, len, "%s: interface is down", c->map.interface);
        goto fail;
    }
    can_err_mask_t em = CAN_ERR_MASK;
    if (setsockopt(s, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &em, sizeof em) < 0) {
        snprintf(why, len, "CAN_RAW_ERR_FILTER: %s", strerror(errno));
        goto fail;
    }
    int on = 1;
    if (c->map.fd && setsockopt(s, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) < 0) {
        snprintf(why, len, "CAN_RAW_FD_FRAMES (can.fd = true): %s", strerror(errno));
        goto fail;
    }
    struct sockaddr_can addr;
    memset(&addr, 0, sizeof addr);
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifindex;
    if (bind(s, (struct sockaddr *)&addr, sizeof addr) < 0) {
        snprintf(why, len, "bind %s: %s", c->map.interface, strerror(errno));
        goto fail;
    }
    c->sock = s;
    return 0;
fail:
    close(s);
    return -1;
}

static void try_open(can_io *c, double now) {
    char why[160];
    int rc = open_socket(c, why, sizeof why);
    pthread_mutex_lock(&c->lock);
    if (rc == 0) {
        c->down[0] = '\0';
        c->bus = BUS_OK;
        c->backoff_s = c->map.reconnect_min_s;
        if (c->lost) c->reconnects++;
        c->lost = false;
    } else {
        snprintf(c->down, sizeof c->down, "%s", why);
        c->retry_at_s = now + c->backoff_s;
        c->backoff_s = fmin(2.0 * c->backoff_s, c->map.reconnect_max_s);
    }
    pthread_mutex_unlock(&c->lock);
}

static void lose(can_io *c, int e, double now) {
    close(c->sock);
    c->sock = -1;
    pthread_mutex_lock(&c->lock);
    c->errors++;
    c->lost = true;
    snprintf(c->down, sizeof c->down, "%s: %s%s", c->map.interface, strerror(e),
             e == ENETDOWN ? " (ENETDOWN)"
             : e == ENODEV ? " (ENODEV)"
                           : "");
    c->backoff_s = c->map.reconnect_min_s;
    c->retry_at_s = now + c->backoff_s;
    pthread_mutex_unlock(&c->lock);
}

static void on_error_frame(can_io *c, const struct canfd_frame *f) {
    canid_t id = f->can_id;
    pthread_mutex_lock(&c->lock);
    c->errors++;
    if (id & CAN_ERR_CRTL) {
        uint8_t d1 = f->len > 1 ? f->data[1] : 0;
        if (d1 & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE)) {
            if (c->bus < BUS_PASSIVE) c->bus = BUS_PASSIVE;
        } else if (d1 & (CAN_ERR_CRTL_RX_WARNING | CAN_ERR_CRTL_TX_WARNING)) {
            if (c->bus < BUS_WARNING) c->bus = BUS_WARNING;
        }
#ifdef CAN_ERR_CRTL_ACTIVE
        if (d1 & CAN_ERR_CRTL_ACTIVE) c->bus = BUS_OK;
#endif
    }
    if (id & CAN_ERR_BUSOFF) c->bus = BUS_OFF;
    if (id & CAN_ERR_RESTARTED) c->bus = BUS_OK;
    pthread_mutex_unlock(&c->lock);
}

static void count_reject(can_io *c, const char *why) {
    pthread_mutex_lock(&c->lock);
    c->rejected++;
    snprintf(c->last_reject, sizeof c->last_reject, "%s", why);
    pthread_mutex_unlock(&c->lock);
}

static void on_frame(can_io *c, const struct canfd_frame *f, bool fd, double now) {
    if (f->can_id & CAN_ERR_FLAG) {
        on_error_frame(c, f);
        return;
    }
    pthread_mutex_lock(&c->lock);
    c->frames++;
    pthread_mutex_unlock(&c->lock);
    const afm_io_sink *sink = &c->io.sink;
    afm_cmd_limits lim = sink->limits ? sink->limits(sink->ctx) : (afm_cmd_limits){0};
    afm_cmd cmd;
    afm_can_state next;
    char err[AFM_IO_REASON_LEN];
    if (sink->drive) { /* LCM dithers and reloads change the drive too: follow them */
        afm_cmd_dither running;
        unsigned gen = sink->drive(sink->ctx, &running);
        if (gen != c->regs_gen) {
            afm_can_state_sync(&c->regs, &running);
            c->regs_gen = gen;
        }
    }
    switch (afm_can_decode(&c->map, &c->regs, f, fd, &lim, &cmd, &next, NULL, err, sizeof err)) {
    case AFM_CAN_R_REJECT:
        count_reject(c, err);
        sink->on_reject(sink->ctx, c->channel, err);
        break;
    case AFM_CAN_R_COMMAND:
        cmd.utime = wall_us();
        cmd.seq = cmd.utime; /* as `afmtwin send`: later commands have larger numbers */
        if (sink->on_cmd(sink->ctx, &cmd) == 0)
            c->regs = next;
        else
            count_reject(c, "refused by the daemon (its reason is in last_reject)");
        break;
    case AFM_CAN_R_STORED:
        c->regs = next;
        break;
    case AFM_CAN_R_HEARTBEAT:
        pthread_mutex_lock(&c->lock);
        c->last_hb_s = now;
        pthread_mutex_unlock(&c->lock);
        break;
    }
}

static void read_frames(can_io *c) {
    for (int i = 0; i < MAX_FRAMES_PER_POLL && c->sock >= 0; i++) {
        struct canfd_frame f;
        ssize_t n = read(c->sock, &f, sizeof f);
        double now = mono_s();
        if (n < 0) {
            if (errno == EINTR) continue;
            if (errno != EAGAIN && errno != EWOULDBLOCK) lose(c, errno, now);
            return;
        }
        if (n == CAN_MTU || n == CANFD_MTU) {
            on_frame(c, &f, n == CANFD_MTU, now);
        } else {
            pthread_mutex_lock(&c->lock);
            c->errors++;
            pthread_mutex_unlock(&c->lock);
        }
    }
}

static bool hb_ok_at(const can_io *c, double now) {
    if (c->map.heartbeat_timeout_s <= 0) return true;
    return c->last_hb_s >= 0 && now - c->last_hb_s <= c->map.heartbeat_timeout_s;
}

static int cio_wait_fd(afm_io *io, int *max_wait_ms) {
    can_io *c = io->impl;
    double now = mono_s(), wait = -1;
    if (c->sock < 0) {
        wait = fmax(0.0, c->retry_at_s - now);
    } else if (c->map.heartbeat_timeout_s > 0 && hb_ok_at(c, now)) {
        wait = c->last_hb_s + c->map.heartbeat_timeout_s - now; /* wake to see it lapse */
    }
    if (max_wait_ms) *max_wait_ms = wait < 0 ? -1 : (int)ceil(wait * 1e3) + 1;
    return c->sock;
}

static int cio_poll(afm_io *io, int timeout_ms) {
    can_io *c = io->impl;
    if (c->sock < 0 && mono_s() >= c->retry_at_s) try_open(c, mono_s());
    int max_ms;
    int fd = cio_wait_fd(io, &max_ms);
    int wait = timeout_ms;
    if (max_ms >= 0 && (wait < 0 || max_ms < wait)) wait = max_ms;
    if (wait > 0) {
        struct pollfd p = {.fd = fd, .events = POLLIN};
        poll(fd >= 0 ? &p : NULL, fd >= 0 ? 1 : 0, wait);
    }
    if (c->sock < 0 && mono_s() >= c->retry_at_s) try_open(c, mono_s());
    read_frames(c);
    return 0;
}

static int cio_nothing_samples(afm_io *io, const afm_io_samples *s) {
    (void)io;
    (void)s;
    return 0;
}

static int cio_nothing_harmonics(afm_io *io, const afm_io_harmonics *h) {
    (void)io;
    (void)h;
    return 0;
}

static int cio_nothing_status(afm_io *io, const afm_io_status *s) {
    (void)io;
    (void)s;
    return 0;
}

static void cio_annotate(afm_io *io, afm_io_status *s) {
    can_io *c = io->impl;
    double now = mono_s();
    pthread_mutex_lock(&c->lock);
    bool hb = hb_ok_at(c, now);
    const char *word = "ok";
    bool hold = true;
    char down[200] = "";
    if (c->down[0]) {
        snprintf(down, sizeof down, "down (%s)", c->down);
        word = down;
    } else if (c->bus == BUS_OFF) {
        word = "bus-off";
    } else if (c->bus == BUS_PASSIVE) {
        word = "error-passive";
    } else if (!hb) {
        word = c->last_hb_s < 0 ? "no-heartbeat (none yet)" : "no-heartbeat";
    } else {
        word = c->bus == BUS_WARNING ? "error-warning" : "ok";
        hold = false;
    }
    snprintf(s->can_state, sizeof s->can_state, "%s%s", word,
             hold ? "; holding last commands" : "");
    s->can_frames = c->frames;
    s->can_rejected = c->rejected;
    s->can_errors = c->errors;
    s->can_reconnects = c->reconnects;
    snprintf(s->can_last_reject, sizeof s->can_last_reject, "%s", c->last_reject);
    s->heartbeat_ok = hb && !c->down[0];
    pthread_mutex_unlock(&c->lock);
}

static void cio_destroy(afm_io *io) {
    can_io *c = io->impl;
    if (c->sock >= 0) close(c->sock);
    pthread_mutex_destroy(&c->lock);
    free(c);
}

static const afm_io_ops can_ops = {
    .name = "can",
    .poll = cio_poll,
    .publish_samples = cio_nothing_samples,
    .publish_harmonics = cio_nothing_harmonics,
    .publish_status = cio_nothing_status,
    .destroy = cio_destroy,
    .wait_fd = cio_wait_fd,
    .annotate_status = cio_annotate,
};

afm_io *afm_can_io_create(const afm_cfg_can *can, const afm_cfg_drive *drive,
                          const afm_io_sink *sink, char *err, size_t errlen) {
    if (!can || !drive || !sink || !sink->on_cmd || !sink->on_reject) {
        snprintf(err, errlen, "afm_can_io_create: NULL argument");
        return NULL;
    }
    /* The map was checked by the config loader (afm_config_check.c); what this file
     * relies on is checked again. */
    if (!can->interface[0] || !(can->reconnect_min_s > 0) ||
        !(can->reconnect_max_s >= can->reconnect_min_s) || !(can->heartbeat_timeout_s >= 0) ||
        drive->n_tones < 1 || drive->n_tones > AFM_MAX_TONES) {
        snprintf(err, errlen,
                 "CAN map: bad interface, reconnect or heartbeat settings, or "
                 "drive (run afm_config_validate first)");
        return NULL;
    }
    can_io *c = calloc(1, sizeof *c);
    if (!c) {
        snprintf(err, errlen, "out of memory");
        return NULL;
    }
    c->io.ops = &can_ops;
    c->io.sink = *sink;
    c->io.impl = c;
    c->map = *can;
    snprintf(c->channel, sizeof c->channel, "CAN %s", can->interface);
    c->sock = -1;
    c->last_hb_s = -1;
    c->backoff_s = can->reconnect_min_s;
    afm_can_state_init(&c->regs, drive);
    pthread_mutex_init(&c->lock, NULL);
    try_open(c, mono_s()); /* a missing interface is retried by poll */
    return &c->io;
}
