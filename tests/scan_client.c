/* SPDX-License-Identifier: MIT */
/* scan_client.c -- the LCM client of tests/test_scan_daemon.sh (issue 18): sends one scan_t
 * command as given (bad values included, to see the daemon refuse them), or images a step as
 * an outside AM-AFM controller would: a PI loop on the lock-in amplitude of each published
 * drive period that moves Z (setpoint_t), while a scan_t MOVE carries the tip across the
 * sample at a constant speed; every period record after the move starts is written out
 * (model time, tip x, y, the daemon's true height there, stage Z, amplitude) for the script
 * to compare the controller's image with the truth.
 *
 *   scan_client send --lcm-url U [--seq N] --mode M [--x X] [--y Y] [--speed V] [--vx V]
 *                    [--vy V] [--size-x S] [--size-y S] [--lines N] [--pixels N] [--rate HZ]
 *   scan_client image --lcm-url U --lcm-out-url U [--ratio R] [--kp KP] [--ki KI] --from X0
 *                     --to X1 --speed V [--engage S] [--dwell S] [--lag-ms MS] [--no-wait]
 *                     --out FILE
 *
 * The PI (hil_pi's): e = A - A_set, Z = Zi - kp e, dZi/dt = -ki e, Z in 0 .. 1 um; A_set =
 * ratio x A0, A0 the lock-in amplitude at Z = 1 um (README, "Free amplitude"). Exit 0 when
 * done, 1 when the twin went silent for 10 s, 2 on bad usage or LCM failure.
 *
 * The controller owns the scanner as an instrument's does: it updates on a record only once
 * that record's seq_applied is the last command it sent (the record's period ran with its Z
 * and x), integrates at most DT_MAX of model time per update, and steps the tip (scan_t MOVE
 * at once) by speed x that time before each Z; engage and dwell run on that clock too. So
 * every update sees its previous command in effect and the image does not depend on how
 * fast the commands travel. The loop before (--no-wait, kept to compare) updated on every
 * record while the twin moved the tip at the speed on its own clock: its delay was the
 * transport's, in wall time -- the records reach the client after the chain and publish
 * threads (SCHED_FIFO 70 and 60) and LCM, its commands the twin after the receive thread --
 * so under load (other real-time threads on the two cores) a command landed many records
 * after the record it answered (measured: up to 14 ms of model time at --speed 0.25, the
 * twin at 0.33 of it), the tip ran on over the edge uncontrolled and the step imaged 4.24 nm
 * once instead of 3. A lost command (UDP) is waited for at most WAIT_MAX records. The done
 * line reports the updates, the waits and the longest command-to-record delay. */
#include "afmtwin_harmonics_t.h"
#include "afmtwin_lcm_layout.h"
#include "afmtwin_scan_t.h"
#include "afmtwin_setpoint_t.h"
#include "afmtwin_status_t.h"

#include <lcm/lcm.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/time.h>

#define A0_Z_M 1e-6      /* where A0 is measured */
#define A0_SETTLE_S 0.01 /* model time the lever rings in there first (Q 100: ~100 taus) */
#define A0_PERIODS 50    /* records averaged for A0 */
#define SEQ0 7000000     /* our setpoints: 7e6, 7e6 + 1, ...; the move: SEQ_MOVE */
#define SEQ_MOVE 7900000
#define DT_MAX 1e-3 /* model time one update integrates and scans at most: the record period */
#define WAIT_MAX 50 /* records waited for a command before updating anyway */
#define LAG_Q 4096  /* records held back at most (--lag-ms) */

typedef struct {
    double ratio, kp, ki, x0, x1, speed, engage_s, dwell_s;
    lcm_t *cmd;
    char ch_setpoint[128], ch_scan[128];
    int64_t seq;
    FILE *out;
    int phase; /* 0 wait status, 1 A0, 2 engage, 3 moving, 4 dwell, 5 done */
    double t_far, a0_sum, a0, a_set, z0, zi, z, t_last;
    double tc, tc_phase; /* the controller's clock (model time integrated), at a phase's start */
    double x;            /* the tip's x commanded (the scanner's, without --no-wait) */
    int n_a0;
    long records;
    /* the wait for our own command: the last seq sent, records waited */
    int no_wait;
    int64_t last_seq;
    double t_ring[256]; /* model time (record answered) each setpoint was sent at, by seq */
    int64_t seen;       /* the newest of our setpoints seen applied */
    int waited;
    long updates, waits_total, wait_max, timeouts;
    double delay_max_s; /* model time from a command to the first record that ran with it */
    /* --lag-ms: records held back before they are handled */
    int64_t lag_us;
    afmtwin_harmonics_t *q[LAG_Q];
    int64_t q_due[LAG_Q];
    int q_head, q_n;
} img_ctx;

static int64_t now_us(void) {
    struct timeval tv;
    gettimeofday(&tv, NULL);
    return (int64_t)tv.tv_sec * 1000000 + tv.tv_usec;
}

static void send_z(img_ctx *c, double z_m) {
    afmtwin_setpoint_t m = {.utime = now_us(), .seq = c->seq++, .separation_m = z_m};
    afmtwin_setpoint_t_publish(c->cmd, c->ch_setpoint, &m);
    c->last_seq = m.seq;
    c->t_ring[m.seq % 256] = c->t_last;
}

static void send_move(lcm_t *l, const char *ch, int64_t seq, double x, double y, double v) {
    afmtwin_scan_t m = {.utime = now_us(),
                        .seq = seq,
                        .mode = AFMTWIN_SCAN_T_MOVE,
                        .x_m = x,
                        .y_m = y,
                        .speed_m_s = v};
    afmtwin_scan_t_publish(l, ch, &m);
}

static void on_status(const lcm_recv_buf_t *rb, const char *ch, const afmtwin_status_t *m,
                      void *user) {
    (void)rb;
    (void)ch;
    img_ctx *c = user;
    if (c->phase != 0) return;
    c->z0 = c->zi = c->z = m->separation_m;
    send_move(c->cmd, c->ch_scan, SEQ0 - 1, c->x0, 0.0, 0.0); /* the tip to the start */
    send_z(c, A0_Z_M);
    c->phase = 1;
}

static void handle(img_ctx *c, const afmtwin_harmonics_t *m) {
    double a = m->lockin_amplitude_m;
    if (c->phase == 0 || c->phase == 5 || !isfinite(a)) return;
    if (c->phase == 1) { /* A0 at Z = 1 um */
        if (m->seq_applied < SEQ0) return;
        if (isnan(c->t_far)) c->t_far = m->t_s;
        if (m->t_s - c->t_far < A0_SETTLE_S) return;
        c->a0_sum += a;
        if (++c->n_a0 == A0_PERIODS) {
            c->a0 = c->a0_sum / A0_PERIODS;
            c->a_set = c->ratio * c->a0;
            c->phase = 2;
            c->t_last = m->t_s;
            c->tc_phase = c->tc;
            send_z(c, c->z0);
            c->seen = c->last_seq - 1; /* the delays from here */
            printf("A0 %.5f nm; set-point %.5f nm; PI from Z %.4f nm at x %.6g nm\n", c->a0 * 1e9,
                   c->a_set * 1e9, c->z0 * 1e9, c->x0 * 1e9);
        }
        return;
    }
    double dt = m->t_s - c->t_last;
    if (dt <= 0) return;
    if (c->phase >= 3) /* the image: every record, whether the loop updates on it or not */
        fprintf(c->out, "%.9f %.9e %.9e %.9e %.9e %.9e %d\n", m->t_s, m->tip_x_m, m->tip_y_m,
                m->true_height_m, m->separation_m, a, m->material);
    const int64_t sa = m->seq_applied; /* the loop's delay: command to its first record */
    if (sa >= SEQ0 && sa < SEQ_MOVE && sa > c->seen && c->seq - sa <= 256) {
        c->seen = sa;
        if (m->t_s - c->t_ring[sa % 256] > c->delay_max_s)
            c->delay_max_s = m->t_s - c->t_ring[sa % 256];
    }
    if (m->seq_applied != c->last_seq) { /* our last command has not run yet */
        c->waits_total++;
        if (!c->no_wait && ++c->waited < WAIT_MAX) return;
        if (!c->no_wait) c->timeouts++;
    }
    if (c->waited > c->wait_max) c->wait_max = c->waited;
    c->waited = 0;
    c->t_last = m->t_s;
    c->updates++;
    double e = a - c->a_set;
    /* the controller's clock: model time, at most DT_MAX an update (--no-wait: model time) */
    const double dti = c->no_wait ? dt : fmin(dt, DT_MAX);
    c->tc += dti;
    c->zi = fmin(fmax(c->zi - c->ki * e * dti, 0.0), A0_Z_M);
    c->z = fmin(fmax(c->zi - c->kp * e, 0.0), A0_Z_M);
    if (c->phase == 3 && !c->no_wait) { /* the scanner: the tip a step on, then Z */
        c->x = fmin(c->x + c->speed * dti, c->x1);
        c->t_ring[c->seq % 256] = c->t_last;
        send_move(c->cmd, c->ch_scan, c->seq++, c->x, 0.0, 0.0);
    }
    send_z(c, c->z);
    if (c->phase == 2 && c->tc - c->tc_phase >= c->engage_s) {
        c->phase = 3;
        c->x = c->x0;
        if (c->no_wait) { /* the old loop: the twin moves the tip at the speed on its own */
            send_move(c->cmd, c->ch_scan, SEQ_MOVE, c->x1, 0.0, c->speed);
            c->last_seq = SEQ_MOVE;
        }
    }
    if (c->phase == 3 && m->tip_x_m == c->x1) {
        c->phase = 4;
        c->tc_phase = c->tc;
    }
    if (c->phase == 4 && c->tc - c->tc_phase >= c->dwell_s) c->phase = 5;
}

/* --lag-ms: each record is handled that long after it arrived (a slow transport, made on
 * purpose: the test's stand-in for a loaded machine); without it at once. */
static void on_harmonics(const lcm_recv_buf_t *rb, const char *ch, const afmtwin_harmonics_t *m,
                         void *user) {
    (void)rb;
    (void)ch;
    img_ctx *c = user;
    c->records++;
    if (c->lag_us <= 0) {
        handle(c, m);
        return;
    }
    if (c->q_n == LAG_Q) { /* full: the oldest handled now */
        handle(c, c->q[c->q_head]);
        afmtwin_harmonics_t_destroy(c->q[c->q_head]);
        c->q_head = (c->q_head + 1) % LAG_Q;
        c->q_n--;
    }
    int k = (c->q_head + c->q_n) % LAG_Q;
    c->q[k] = afmtwin_harmonics_t_copy(m);
    c->q_due[k] = now_us() + c->lag_us;
    c->q_n++;
}

/* Handle the queued records that are due; the wait until the next one (ms, at most 200). */
static int lag_drain(img_ctx *c) {
    int64_t now = now_us();
    while (c->q_n > 0 && c->q_due[c->q_head] <= now) {
        handle(c, c->q[c->q_head]);
        afmtwin_harmonics_t_destroy(c->q[c->q_head]);
        c->q_head = (c->q_head + 1) % LAG_Q;
        c->q_n--;
    }
    if (c->q_n == 0) return c->lag_us > 0 ? 1 : 200;
    int64_t w = (c->q_due[c->q_head] - now + 999) / 1000; /* whole ms, rounded up */
    return w < 1 ? 1 : (w > 200 ? 200 : (int)w);
}

static int num(const char *a, const char *v, double *out) {
    char *end;
    if (!v) return -1;
    *out = strtod(v, &end);
    if (*end || end == v) {
        fprintf(stderr, "scan_client: %s wants a number, got '%s'\n", a, v);
        return -1;
    }
    return 0;
}

int main(int argc, char **argv) {
    if (argc < 2 || (strcmp(argv[1], "send") && strcmp(argv[1], "image"))) {
        fprintf(stderr, "usage: scan_client send|image ... (see the top of scan_client.c)\n");
        return 2;
    }
    int image = !strcmp(argv[1], "image");
    const char *url = AFMTWIN_DEFAULT_URL, *out_url = AFMTWIN_DEFAULT_OUT_URL, *out = NULL;
    double seq = 1, mode = 0, x = 0, y = 0, speed = 0, vx = 0, vy = 0, sx = 0, sy = 0, lines = 0,
           pixels = 0, rate = 0;
    img_ctx c = {
        .ratio = 0.8, .kp = 0.2, .ki = 300, .engage_s = 0.05, .dwell_s = 0.05, .t_far = NAN};
    for (int i = 2; i < argc; i += 2) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        double *d = !strcmp(a, "--seq")      ? &seq
                    : !strcmp(a, "--mode")   ? &mode
                    : !strcmp(a, "--x")      ? &x
                    : !strcmp(a, "--y")      ? &y
                    : !strcmp(a, "--speed")  ? &speed
                    : !strcmp(a, "--vx")     ? &vx
                    : !strcmp(a, "--vy")     ? &vy
                    : !strcmp(a, "--size-x") ? &sx
                    : !strcmp(a, "--size-y") ? &sy
                    : !strcmp(a, "--lines")  ? &lines
                    : !strcmp(a, "--pixels") ? &pixels
                    : !strcmp(a, "--rate")   ? &rate
                    : !strcmp(a, "--ratio")  ? &c.ratio
                    : !strcmp(a, "--kp")     ? &c.kp
                    : !strcmp(a, "--ki")     ? &c.ki
                    : !strcmp(a, "--from")   ? &c.x0
                    : !strcmp(a, "--to")     ? &c.x1
                    : !strcmp(a, "--engage") ? &c.engage_s
                    : !strcmp(a, "--dwell")  ? &c.dwell_s
                                             : NULL;
        if (d) {
            if (num(a, v, d)) return 2;
        } else if (!strcmp(a, "--lcm-url") && v) {
            url = v;
        } else if (!strcmp(a, "--lcm-out-url") && v) {
            out_url = v;
        } else if (!strcmp(a, "--out") && v) {
            out = v;
        } else if (!strcmp(a, "--lag-ms") && v) {
            double ms;
            if (num(a, v, &ms) || !(ms >= 0 && ms <= 1000)) return 2;
            c.lag_us = (int64_t)(ms * 1000);
        } else if (!strcmp(a, "--no-wait")) {
            c.no_wait = 1;
            i--; /* no value */
        } else {
            fprintf(stderr, "scan_client: unknown option '%s'\n", a);
            return 2;
        }
    }
    char ch_scan[128], ch_h[128], ch_s[128];
    snprintf(ch_scan, sizeof ch_scan, "%s%s", AFMTWIN_DEFAULT_PREFIX, AFMTWIN_CHAN_SCAN);
    if (!image) {
        lcm_t *l = lcm_create(url);
        if (!l) return 2;
        afmtwin_scan_t m = {.utime = now_us(),
                            .seq = (int64_t)seq,
                            .mode = (int8_t)mode,
                            .x_m = x,
                            .y_m = y,
                            .speed_m_s = speed,
                            .vx_m_s = vx,
                            .vy_m_s = vy,
                            .size_x_m = sx,
                            .size_y_m = sy,
                            .lines = (int32_t)lines,
                            .pixels = (int32_t)pixels,
                            .line_rate_hz = rate};
        int rc = afmtwin_scan_t_publish(l, ch_scan, &m);
        lcm_destroy(l);
        return rc < 0 ? 2 : 0;
    }
    c.speed = speed;
    if (!out || !(c.speed > 0)) {
        fprintf(stderr, "scan_client image: --out FILE and --speed V > 0 are required\n");
        return 2;
    }
    c.out = fopen(out, "w");
    if (!c.out) return 2;
    c.seq = SEQ0;
    snprintf(c.ch_scan, sizeof c.ch_scan, "%s", ch_scan);
    snprintf(c.ch_setpoint, sizeof c.ch_setpoint, "%s%s", AFMTWIN_DEFAULT_PREFIX,
             AFMTWIN_CHAN_SETPOINT);
    snprintf(ch_h, sizeof ch_h, "%s%s", AFMTWIN_DEFAULT_PREFIX, AFMTWIN_CHAN_HARMONICS);
    snprintf(ch_s, sizeof ch_s, "%s%s", AFMTWIN_DEFAULT_PREFIX, AFMTWIN_CHAN_STATUS);
    lcm_t *in = lcm_create(out_url);
    c.cmd = in ? lcm_create(url) : NULL;
    if (!in || !c.cmd) return 2;
    afmtwin_status_t_subscribe(in, ch_s, on_status, &c);
    afmtwin_harmonics_t_subscription_t *hs =
        afmtwin_harmonics_t_subscribe(in, ch_h, on_harmonics, &c);
    afmtwin_harmonics_t_subscription_set_queue_capacity(hs, 10000);
    long last = -1;
    int rc = 0;
    int64_t t_check = now_us();
    while (c.phase != 5) {
        if (lcm_handle_timeout(in, lag_drain(&c)) < 0) {
            rc = 2;
            break;
        }
        if (now_us() - t_check > 10000000) { /* bounded: 10 s without a record ends it */
            if (c.records == last) {
                fprintf(stderr, "scan_client: nothing from the twin for 10 s\n");
                rc = 1;
                break;
            }
            last = c.records;
            t_check = now_us();
        }
    }
    fclose(c.out);
    printf("%s: %ld records, phase %d, Z %.4f nm; %ld PI updates (%s), %ld records waited for "
           "a command (at most %ld in a row, %ld gave up), command to its first record <= %.3f "
           "ms of model time\n",
           rc ? "stopped" : "done", c.records, c.phase, c.z * 1e9, c.updates,
           c.no_wait ? "every record" : "each after its last command ran", c.waits_total,
           c.wait_max, c.timeouts, c.delay_max_s * 1e3);
    lcm_destroy(c.cmd);
    lcm_destroy(in);
    return rc;
}
