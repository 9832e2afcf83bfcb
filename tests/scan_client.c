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
 *                     --to X1 --speed V [--engage S] [--dwell S] --out FILE
 *
 * The PI (hil_pi's): e = A - A_set, Z = Zi - kp e, dZi/dt = -ki e, Z in 0 .. 1 um; A_set =
 * ratio x A0, A0 the lock-in amplitude at Z = 1 um (README, "Free amplitude"). Exit 0 when
 * done, 1 when the twin went silent for 10 s, 2 on bad usage or LCM failure. */
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

typedef struct {
    double ratio, kp, ki, x0, x1, speed, engage_s, dwell_s;
    lcm_t *cmd;
    char ch_setpoint[128], ch_scan[128];
    int64_t seq;
    FILE *out;
    int phase; /* 0 wait status, 1 A0, 2 engage, 3 moving, 4 dwell, 5 done */
    double t_far, a0_sum, a0, a_set, z0, zi, z, t_phase, t_last;
    int n_a0;
    long records;
} img_ctx;

static int64_t now_us(void) {
    struct timeval tv;
    gettimeofday(&tv, NULL);
    return (int64_t)tv.tv_sec * 1000000 + tv.tv_usec;
}

static void send_z(img_ctx *c, double z_m) {
    afmtwin_setpoint_t m = {.utime = now_us(), .seq = c->seq++, .separation_m = z_m};
    afmtwin_setpoint_t_publish(c->cmd, c->ch_setpoint, &m);
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

static void on_harmonics(const lcm_recv_buf_t *rb, const char *ch, const afmtwin_harmonics_t *m,
                         void *user) {
    (void)rb;
    (void)ch;
    img_ctx *c = user;
    double a = m->lockin_amplitude_m;
    c->records++;
    if (c->phase == 0 || c->phase == 5 || !isfinite(a)) return;
    if (c->phase == 1) { /* A0 at Z = 1 um */
        if (m->seq_applied < SEQ0) return;
        if (isnan(c->t_far)) c->t_far = m->t_s;
        if (m->t_s - c->t_far < A0_SETTLE_S) return;
        c->a0_sum += a;
        if (++c->n_a0 == A0_PERIODS) {
            c->a0 = c->a0_sum / A0_PERIODS;
            c->a_set = c->ratio * c->a0;
            send_z(c, c->z0);
            c->phase = 2;
            c->t_phase = c->t_last = m->t_s;
            printf("A0 %.5f nm; set-point %.5f nm; PI from Z %.4f nm at x %.6g nm\n", c->a0 * 1e9,
                   c->a_set * 1e9, c->z0 * 1e9, c->x0 * 1e9);
        }
        return;
    }
    double dt = m->t_s - c->t_last;
    if (dt <= 0) return;
    c->t_last = m->t_s;
    double e = a - c->a_set;
    c->zi = fmin(fmax(c->zi - c->ki * e * dt, 0.0), A0_Z_M);
    c->z = fmin(fmax(c->zi - c->kp * e, 0.0), A0_Z_M);
    send_z(c, c->z);
    if (c->phase == 2 && m->t_s - c->t_phase >= c->engage_s) {
        send_move(c->cmd, c->ch_scan, SEQ_MOVE, c->x1, 0.0, c->speed);
        c->phase = 3;
    }
    if (c->phase >= 3)
        fprintf(c->out, "%.9f %.9e %.9e %.9e %.9e %.9e %d\n", m->t_s, m->tip_x_m, m->tip_y_m,
                m->true_height_m, m->separation_m, a, m->material);
    if (c->phase == 3 && m->tip_x_m == c->x1) {
        c->phase = 4;
        c->t_phase = m->t_s;
    }
    if (c->phase == 4 && m->t_s - c->t_phase >= c->dwell_s) c->phase = 5;
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
        if (lcm_handle_timeout(in, 200) < 0) {
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
    printf("%s: %ld records, phase %d, Z %.4f nm\n", rc ? "stopped" : "done", c.records, c.phase,
           c.z * 1e9);
    lcm_destroy(c.cmd);
    lcm_destroy(in);
    return rc;
}
