/* SPDX-License-Identifier: MIT */
/* hil_pi.c -- a hardware-in-the-loop client of afmtwind, as a controller developer would
 * write one: a PI loop that holds the tapping amplitude at a set-point by moving Z.
 *
 * It reads the lock-in amplitude of each published drive period (HARMONICS, on the output
 * URL), measures the free amplitude A0 first, then commands Z (SETPOINT, on the command URL)
 * after every period that ran with its last command (seq_applied) so that the amplitude is
 * ratio x A0:
 *     e = A - A_set,   Z = Zi - kp e,   dZi/dt = -ki e   (t: model time of the periods)
 * A above the set-point moves the tip towards the sample (Z down). It exits 0 once the mean
 * amplitude over the last --hold seconds of model time is within --tol of the set-point, 1
 * if it is not locked within --seconds of model time, 2 on bad usage or LCM failure.
 *
 * A0 is afmtwin's one free amplitude (README, "Free amplitude"): harmonic 1 of the deflection
 * far from the sample, at the drive in force. The client measures it as the daemon's
 * lock-in amplitude at Z = 1 um (no tip force reaches that far; the squeeze film of the beam
 * stays as it is there), which afmtwind prints as A0 on start-up; then it returns to the
 * start Z. (At the start Z the lever may already tap: its amplitude there is not A0.)
 *
 * Built only from installed files: cc hil_pi.c $(pkg-config --cflags --libs afmtwin). */
#include "afmtwin_harmonics_t.h"
#include "afmtwin_lcm_layout.h"
#include "afmtwin_setpoint_t.h"
#include "afmtwin_status_t.h"

#include <lcm/lcm.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/time.h>

#define A0_Z_M 1e-6      /* where A0 is measured: Z far from the sample */
#define A0_SETTLE_S 0.02 /* model time the lever rings in there first (~50 time constants) */
#define A0_PERIODS 50    /* records averaged for A0 after that */
#define SEQ0 5000000     /* our setpoint commands: seq 5e6 (to A0_Z_M), 5e6 + 1, ... */
#define WAIT_MAX 50      /* records waited for our last command before updating anyway */

typedef struct {
    double ratio, kp, ki, seconds, hold_s, tol;
    lcm_t *cmd;
    char ch_setpoint[128];
    int64_t seq;
    /* state */
    int n_free, n_a0; /* records heard while measuring A0, and averaged */
    double t_far;     /* model time of the first record at A0_Z_M (NAN before) */
    double a0_sum, a0, a_set, z0, zi, z, t_start, t_last;
    int have_z0, waited;
    double hold_sum, hold_t0;
    long hold_n, records;
    int done, locked;
} pi_ctx;

static int64_t now_us(void) {
    struct timeval tv;
    gettimeofday(&tv, NULL);
    return (int64_t)tv.tv_sec * 1000000 + tv.tv_usec;
}

static void send_z(pi_ctx *c, double z_m) {
    afmtwin_setpoint_t m = {
        .utime = now_us(), .seq = c->seq++, .separation_m = z_m, .ramp_rate_m_s = 0};
    afmtwin_setpoint_t_publish(c->cmd, c->ch_setpoint, &m);
}

static void on_status(const lcm_recv_buf_t *rb, const char *ch, const afmtwin_status_t *m,
                      void *user) {
    (void)rb;
    (void)ch;
    pi_ctx *c = user;
    if (!c->have_z0) {
        c->z0 = c->zi = c->z = m->separation_m;
        c->have_z0 = 1;
        send_z(c, A0_Z_M); /* seq SEQ0: retract to measure A0 */
    }
}

static void on_harmonics(const lcm_recv_buf_t *rb, const char *ch, const afmtwin_harmonics_t *m,
                         void *user) {
    (void)rb;
    (void)ch;
    pi_ctx *c = user;
    double a = m->lockin_amplitude_m;
    if (!c->have_z0 || c->done || !isfinite(a)) return;
    if (c->n_a0 < A0_PERIODS) { /* A0 first, at Z = A0_Z_M, before any PI command */
        c->n_free++;
        if (m->seq_applied < SEQ0) return; /* the retract is not applied yet */
        if (isnan(c->t_far)) c->t_far = m->t_s;
        if (m->t_s - c->t_far < A0_SETTLE_S) return;
        c->a0_sum += a;
        if (++c->n_a0 == A0_PERIODS) {
            c->a0 = c->a0_sum / A0_PERIODS;
            c->a_set = c->ratio * c->a0;
            send_z(c, c->z0); /* back to the start Z: the PI starts there */
            c->t_start = c->t_last = m->t_s;
            printf("A0 %.4f nm (free amplitude: lock-in at Z %.0f nm); set-point %.4f nm "
                   "(A/A0 %.4f); PI from Z %.3f nm\n",
                   c->a0 * 1e9, A0_Z_M * 1e9, c->a_set * 1e9, c->ratio, c->z0 * 1e9);
        }
        return;
    }
    double dt = m->t_s - c->t_last;
    if (dt <= 0) return;
    c->records++;
    /* Update only on a period that ran with the last Z sent (its seq_applied): the records
     * and the commands travel in wall time (the daemon's threads, LCM, this process), so on
     * a loaded machine a command may land several periods after the one it answered; a loop
     * updating on every record would then integrate the same error again and again and
     * ring. Waiting makes the delay one period whatever the load; the model time integrated
     * at once is capped (0.5 / ki) so that a long wait never makes one large step. A lost
     * command (UDP) is waited for at most WAIT_MAX records. */
    double e = a - c->a_set;
    if (m->seq_applied == c->seq - 1 || ++c->waited >= WAIT_MAX) {
        c->waited = 0;
        c->t_last = m->t_s;
        c->zi -= c->ki * e * fmin(dt, 0.5 / fmax(c->ki, 1e-30));
        if (c->zi < 0) c->zi = 0; /* anti-windup: Z stays in 0 .. start Z */
        if (c->zi > c->z0) c->zi = c->z0;
        c->z = fmin(fmax(c->zi - c->kp * e, 0), c->z0);
        send_z(c, c->z);
    }
    double t = m->t_s - c->t_start;
    /* lock test: the mean amplitude over a window of hold_s of model time */
    if (c->hold_n == 0) c->hold_t0 = m->t_s;
    c->hold_sum += a;
    c->hold_n++;
    if (m->t_s - c->hold_t0 >= c->hold_s) {
        double mean = c->hold_sum / c->hold_n, rel = (mean - c->a_set) / c->a_set;
        printf("t %.3f s: amplitude %.4f nm, A/A0 %.4f (mean of %ld periods), set-point %.4f "
               "nm, error %+.3f %%, Z %.3f nm\n",
               t, mean * 1e9, mean / c->a0, c->hold_n, c->a_set * 1e9, 100 * rel, c->z * 1e9);
        c->hold_n = 0;
        c->hold_sum = 0;
        if (fabs(rel) <= c->tol) {
            c->locked = c->done = 1;
            printf("locked: amplitude %.4f nm, A/A0 %.4f, set-point %.4f nm, error %+.3f %% "
                   "(tolerance %.2f %%), Z %.3f nm, after %.3f s of model time\n",
                   mean * 1e9, mean / c->a0, c->a_set * 1e9, 100 * rel, 100 * c->tol, c->z * 1e9,
                   t);
        }
    }
    if (t >= c->seconds) c->done = 1;
}

static void usage(FILE *f) {
    fprintf(f, "usage: hil_pi [--lcm-url URL] [--lcm-out-url URL] [--prefix NAME_]\n"
               "              [--ratio R] [--kp KP] [--ki KI_PER_S] [--seconds S] [--hold S]\n"
               "              [--tol FRACTION] [--timeout S]\n"
               "Holds afmtwind's tapping amplitude at A/A0 = R (default 0.8) with a PI loop on\n"
               "Z; A0, the free amplitude, is measured first as the lock-in amplitude at Z 1 um\n"
               "(what afmtwind prints as A0 at start-up), then Z returns to where it was\n"
               "(defaults kp 0.2, ki 200 /s; --seconds 2 and --hold 0.1 s of model\n"
               "time, --tol 0.01). URLs default to " AFMTWIN_DEFAULT_URL " (commands)\n"
               "and " AFMTWIN_DEFAULT_OUT_URL " (outputs). Exit 0 locked, 1 not locked\n"
               "(or nothing heard within --timeout wall seconds, default 10), 2 usage/LCM.\n");
}

int main(int argc, char **argv) {
    pi_ctx c = {
        .ratio = 0.8, .kp = 0.2, .ki = 200, .seconds = 2, .hold_s = 0.1, .tol = 0.01, .t_far = NAN};
    const char *url = AFMTWIN_DEFAULT_URL, *out_url = AFMTWIN_DEFAULT_OUT_URL;
    const char *prefix = AFMTWIN_DEFAULT_PREFIX;
    double timeout_s = 10;
    for (int i = 1; i < argc; i += 2) { /* every option takes a value (--help returns) */
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        double *num = !strcmp(a, "--ratio")     ? &c.ratio
                      : !strcmp(a, "--kp")      ? &c.kp
                      : !strcmp(a, "--ki")      ? &c.ki
                      : !strcmp(a, "--seconds") ? &c.seconds
                      : !strcmp(a, "--hold")    ? &c.hold_s
                      : !strcmp(a, "--tol")     ? &c.tol
                      : !strcmp(a, "--timeout") ? &timeout_s
                                                : NULL;
        if (!strcmp(a, "--help")) {
            usage(stdout);
            return 0;
        } else if (num && v) {
            char *end;
            *num = strtod(v, &end);
            if (*end || end == v || !(*num >= 0)) {
                fprintf(stderr, "hil_pi: %s wants a number >= 0, got '%s'\n", a, v);
                return 2;
            }
        } else if (!strcmp(a, "--lcm-url") && v) {
            url = v;
        } else if (!strcmp(a, "--lcm-out-url") && v) {
            out_url = v;
        } else if (!strcmp(a, "--prefix") && v) {
            prefix = v;
        } else {
            usage(stderr);
            return 2;
        }
    }
    if (!(c.ratio > 0 && c.ratio < 1)) {
        fprintf(stderr, "hil_pi: --ratio wants 0 < R < 1\n");
        return 2;
    }
    c.seq = SEQ0;
    snprintf(c.ch_setpoint, sizeof c.ch_setpoint, "%s%s", prefix, AFMTWIN_CHAN_SETPOINT);
    char ch_h[128], ch_s[128];
    snprintf(ch_h, sizeof ch_h, "%s%s", prefix, AFMTWIN_CHAN_HARMONICS);
    snprintf(ch_s, sizeof ch_s, "%s%s", prefix, AFMTWIN_CHAN_STATUS);
    lcm_t *in = lcm_create(out_url);
    c.cmd = in ? lcm_create(url) : NULL;
    if (!in || !c.cmd) {
        fprintf(stderr, "hil_pi: cannot open LCM (%s, %s)\n", url, out_url);
        return 2;
    }
    afmtwin_status_t_subscribe(in, ch_s, on_status, &c);
    afmtwin_harmonics_t_subscription_t *hs =
        afmtwin_harmonics_t_subscribe(in, ch_h, on_harmonics, &c);
    afmtwin_harmonics_t_subscription_set_queue_capacity(hs, 10000);
    struct timeval t0, t;
    gettimeofday(&t0, NULL);
    long last_records = -1;
    while (!c.done) {
        int r = lcm_handle_timeout(in, 200);
        gettimeofday(&t, NULL);
        double wall = (double)(t.tv_sec - t0.tv_sec) + 1e-6 * (double)(t.tv_usec - t0.tv_usec);
        if (r < 0) {
            fprintf(stderr, "hil_pi: LCM receive failed\n");
            break;
        }
        if (wall > timeout_s) { /* a wall-time limit, reset while records come */
            if (c.records + c.n_free == last_records) {
                fprintf(stderr,
                        "hil_pi: nothing from the twin for %g s (is afmtwind running on "
                        "these URLs?)\n",
                        timeout_s);
                break;
            }
            last_records = c.records + c.n_free;
            t0 = t;
        }
    }
    if (c.have_z0) send_z(&c, c.z0); /* leave the twin where it was */
    if (!c.locked) printf("not locked within %.3f s of model time\n", c.seconds);
    lcm_destroy(c.cmd);
    lcm_destroy(in);
    return c.locked ? 0 : 1;
}
