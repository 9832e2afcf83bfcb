/* SPDX-License-Identifier: MIT */
/* fm_pll.c -- an outside frequency-modulation (FM-AFM) controller for afmtwind, as a
 * controller developer would write one: a phase-locked loop that keeps the cantilever on its
 * (shifted) resonance by moving tone 0's frequency, and a PI loop that keeps its amplitude by
 * moving tone 0's drive amplitude; both over LCM, the twin's drive in the loop.
 *
 * Phase detector: the lock-in phase of each published drive period (HARMONICS on the output
 * URL: lockin_phase_deg, the LAG of the deflection behind the drive, 90 deg at resonance).
 *     e = lag - 90 deg,  f = f_c + df_i - kp e,  d(df_i)/dt = -ki e   (t: the records' model
 *     time; above resonance the lag exceeds 90, so e > 0 lowers f)
 *     ea = A_set - A,    drive = d_i + akp ea,  d(d_i)/dt = aki ea
 * Gains from --q (Q of mode 1), --f0 (its resonance, where the NCO starts) and --gain (tip
 * per drive amplitude at resonance; Q for a lumped lever): envelope time constant
 * tau = Q / (pi f0), phase slope K = 360 Q / (pi f0) deg/Hz, ki = 2 pi bw / K, kp = ki tau
 * (a first-order loop of bandwidth bw), likewise for the amplitude with K = gain.
 *
 * Commands: one dither command (tone 0: the NCO's frequency and the drive) every 1/--rate
 * wall seconds (default 10 kHz) on the command URL, seq SEQ0, SEQ0 + 1, ...: the twin applies
 * each phase-continuously. The loops update at every harmonics record (<= 1000/s by default);
 * commands in between repeat the latest values. It prints the lock and, at exit, the commands
 * it sent, which the daemon's status counts as applied.
 *
 * Exit 0 once locked (|e| <= --lock-deg and the amplitude within --tol over --hold s of model
 * time) and after streaming --after more wall seconds; 1 if not locked within --seconds of
 * model time (or nothing heard within --timeout wall seconds); 2 on bad usage or LCM failure.
 *
 * Scheduling on the daemon's machine: SCHED_FIFO just below the daemon's integrator thread and
 * above its other threads (chrt -f 75 at afmtwind's default --rt-priority 80): the commands go
 * out in 1 ms bursts that end before the daemon's LCM thread (70) reads them, one wake-up a
 * burst; above the integrator every burst preempts it, below the LCM thread every send wakes
 * it (docs/realtime.md, "Command intake under a 10 kHz controller").
 *
 * Built only from installed files: cc fm_pll.c $(pkg-config --cflags --libs afmtwin). */
#include "afmtwin_dither_t.h"
#include "afmtwin_harmonics_t.h"
#include "afmtwin_lcm_layout.h"

#include <lcm/lcm.h>
#include <math.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define SEQ0 6000000 /* our dither commands: seq 6e6, 6e6 + 1, ... */
#define PI 3.14159265358979323846

typedef struct {
    /* options */
    double f0, q, gain, a_set, bw, abw, lock_deg, tol, hold_s, seconds, rate, after, timeout;
    /* gains */
    double kp, ki, akp, aki;
    /* state */
    double f, df_i, drive, drive_i, e, a, t_last, t_first, t_in;
    long records;
    int locked;
    double t_lock;
    double e_max_after; /* largest |e| after the lock */
} fm_ctx;

static double mono_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double clampd(double v, double lo, double hi) {
    return v < lo ? lo : v > hi ? hi : v;
}

static void on_harmonics(const lcm_recv_buf_t *rb, const char *ch, const afmtwin_harmonics_t *m,
                         void *user) {
    (void)rb;
    (void)ch;
    fm_ctx *c = user;
    double a = m->lockin_amplitude_m, lag = m->lockin_phase_deg;
    if (!isfinite(a) || !isfinite(lag) || m->seq_applied < SEQ0) return; /* not ours yet */
    if (c->records++ == 0) {
        c->t_first = c->t_last = m->t_s;
        return;
    }
    double dt = m->t_s - c->t_last;
    if (!(dt > 0)) return;
    c->t_last = m->t_s;
    /* PLL: PI on the phase error, the NCO kept within +-5 kHz of f0 (anti-windup) */
    c->e = remainder(lag - 90.0, 360.0);
    c->df_i = clampd(c->df_i - c->ki * c->e * dt, -5e3, 5e3);
    c->f = c->f0 + clampd(c->df_i - c->kp * c->e, -5e3, 5e3);
    /* amplitude: PI on the lock-in amplitude, the drive within 0 .. 1e-6 m */
    c->a = a;
    double ea = c->a_set - a;
    c->drive_i = clampd(c->drive_i + c->aki * ea * dt, 0, 1e-6);
    c->drive = clampd(c->drive_i + c->akp * ea, 0, 1e-6);
    /* lock: inside the window for hold_s of model time */
    int inside = fabs(c->e) <= c->lock_deg && fabs(ea) <= c->tol * c->a_set;
    c->t_in = inside ? c->t_in + dt : 0;
    if (c->locked) {
        if (fabs(c->e) > c->e_max_after) c->e_max_after = fabs(c->e);
    } else if (c->t_in >= c->hold_s) {
        c->locked = 1;
        c->t_lock = m->t_s - c->t_first;
        printf("locked after %.4f s of model time: f %.4f Hz (%+.4f Hz from f0), phase error "
               "%+.4f deg, amplitude %.5g nm (set-point %.5g nm), drive %.5g pm\n",
               c->t_lock, c->f, c->f - c->f0, c->e, a * 1e9, c->a_set * 1e9, c->drive * 1e12);
        fflush(stdout);
    }
}

static void usage(FILE *f) {
    fprintf(f, "usage: fm_pll --f0 HZ --q Q --amplitude M [--gain G] [--drive M]\n"
               "              [--bandwidth HZ] [--amplitude-bandwidth HZ] [--rate HZ]\n"
               "              [--lock-deg DEG] [--tol FRACTION] [--hold S] [--seconds S]\n"
               "              [--after S] [--timeout S] [--lcm-url URL] [--lcm-out-url URL]\n"
               "              [--prefix NAME_]\n"
               "An outside FM-AFM controller of afmtwind: a PLL on the lock-in phase of each\n"
               "published drive period (held at 90 deg: the resonance) moves tone 0's frequency,\n"
               "a PI on the lock-in amplitude (held at --amplitude) its drive; a dither command\n"
               "with both every 1/--rate s (default 10000/s). Gains from mode 1's --f0 and --q\n"
               "and --gain (tip per drive at resonance; default Q: a lumped lever) for loop\n"
               "bandwidths of --bandwidth (default 30 Hz) and --amplitude-bandwidth (15 Hz);\n"
               "--drive the first drive amplitude (default amplitude / gain). Locked: |phase\n"
               "error| <= --lock-deg (1) and the amplitude within --tol (0.01) for --hold s\n"
               "(0.05) of model time; then it streams --after more wall seconds (default 5).\n"
               "Exit 0 locked, 1 not locked within --seconds (2) of model time or nothing heard\n"
               "for --timeout (5) wall seconds, 2 usage/LCM. URLs default to " AFMTWIN_DEFAULT_URL
               "\n(commands) and " AFMTWIN_DEFAULT_OUT_URL " (outputs).\n");
}

int main(int argc, char **argv) {
    fm_ctx c = {.f0 = NAN,
                .q = NAN,
                .gain = NAN,
                .a_set = NAN,
                .bw = 30,
                .abw = 15,
                .lock_deg = 1,
                .tol = 0.01,
                .hold_s = 0.05,
                .seconds = 2,
                .rate = 10000,
                .after = 5,
                .timeout = 5,
                .drive = NAN};
    const char *url = AFMTWIN_DEFAULT_URL, *out_url = AFMTWIN_DEFAULT_OUT_URL;
    const char *prefix = AFMTWIN_DEFAULT_PREFIX;
    for (int i = 1; i < argc; i += 2) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        double *num = !strcmp(a, "--f0")                    ? &c.f0
                      : !strcmp(a, "--q")                   ? &c.q
                      : !strcmp(a, "--gain")                ? &c.gain
                      : !strcmp(a, "--amplitude")           ? &c.a_set
                      : !strcmp(a, "--drive")               ? &c.drive
                      : !strcmp(a, "--bandwidth")           ? &c.bw
                      : !strcmp(a, "--amplitude-bandwidth") ? &c.abw
                      : !strcmp(a, "--lock-deg")            ? &c.lock_deg
                      : !strcmp(a, "--tol")                 ? &c.tol
                      : !strcmp(a, "--hold")                ? &c.hold_s
                      : !strcmp(a, "--seconds")             ? &c.seconds
                      : !strcmp(a, "--rate")                ? &c.rate
                      : !strcmp(a, "--after")               ? &c.after
                      : !strcmp(a, "--timeout")             ? &c.timeout
                                                            : NULL;
        if (!strcmp(a, "--help")) {
            usage(stdout);
            return 0;
        } else if (num && v) {
            char *end;
            *num = strtod(v, &end);
            if (*end || end == v || !(*num >= 0) || !isfinite(*num)) {
                fprintf(stderr, "fm_pll: %s wants a finite number >= 0, got '%s'\n", a, v);
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
    if (!(c.f0 > 0) || !(c.q > 0) || !(c.a_set > 0) || !(c.rate >= 1 && c.rate <= 1e5) ||
        !(c.bw > 0) || !(c.abw > 0)) {
        fprintf(stderr, "fm_pll: --f0, --q, --amplitude must be > 0; --rate in 1..1e5; "
                        "bandwidths > 0\n");
        return 2;
    }
    if (!(c.gain > 0)) c.gain = c.q;
    if (!(c.drive >= 0)) c.drive = c.a_set / c.gain;
    double tau = c.q / (PI * c.f0), k_phi = 360.0 * c.q / (PI * c.f0);
    c.ki = 2 * PI * c.bw / k_phi;
    c.kp = c.ki * tau;
    c.aki = 2 * PI * c.abw / c.gain;
    c.akp = c.aki * tau;
    c.f = c.f0;
    c.drive_i = c.drive;
    char ch_d[128], ch_h[128];
    snprintf(ch_d, sizeof ch_d, "%s%s", prefix, AFMTWIN_CHAN_DITHER);
    snprintf(ch_h, sizeof ch_h, "%s%s", prefix, AFMTWIN_CHAN_HARMONICS);
    lcm_t *in = lcm_create(out_url), *cmd = in ? lcm_create(url) : NULL;
    if (!in || !cmd) {
        fprintf(stderr, "fm_pll: cannot open LCM (%s, %s)\n", url, out_url);
        return 2;
    }
    afmtwin_harmonics_t_subscription_t *hs =
        afmtwin_harmonics_t_subscribe(in, ch_h, on_harmonics, &c);
    afmtwin_harmonics_t_subscription_set_queue_capacity(hs, 10000);
    printf("fm_pll: f0 %.3f Hz, Q %g, gain %g; PLL kp %.4g Hz/deg ki %.4g Hz/(deg s) (%g Hz), "
           "amplitude kp %.4g ki %.4g /s (%g Hz); set-point %.5g nm; %g commands/s\n",
           c.f0, c.q, c.gain, c.kp, c.ki, c.bw, c.akp, c.aki, c.abw, c.a_set * 1e9, c.rate);
    fflush(stdout);
    int fd = lcm_get_fileno(in);
    const double period = 1.0 / c.rate;
    double t0 = mono_s(), next = t0, t_heard = t0, t_lock_wall = NAN;
    long sent = 0, send_errors = 0, late = 0, records_seen = 0;
    int rc = 1;
    for (;;) {
        double now = mono_s();
        if (now >= next) { /* one command: tone 0 at the NCO's frequency and the drive */
            double fr[1] = {c.f}, am[1] = {c.drive}, ph[1] = {0};
            afmtwin_dither_t m = {.utime = (int64_t)(now * 1e6),
                                  .seq = SEQ0 + sent,
                                  .n_tones = 1,
                                  .frequency_hz = fr,
                                  .amplitude_m = am,
                                  .phase_rad = ph};
            if (afmtwin_dither_t_publish(cmd, ch_d, &m) == 0)
                sent++;
            else
                send_errors++;
            next += period;
            if (next < now - 100 * period) { /* far behind: count it, do not burst */
                late++;
                next = now + period;
            }
            continue;
        }
        /* wait for outputs until the next command is due, rounded up to whole ms: rounding
         * down polls with 0 and spins, which at SCHED_FIFO starves the twin on a small box */
        int ms = (int)ceil((next - now) * 1e3);
        struct pollfd p = {.fd = fd, .events = POLLIN};
        if (poll(&p, 1, ms) > 0 && (p.revents & POLLIN)) {
            if (lcm_handle(in) != 0) {
                fprintf(stderr, "fm_pll: LCM receive failed\n");
                rc = 2;
                break;
            }
        }
        now = mono_s();
        if (c.records != records_seen) {
            records_seen = c.records;
            t_heard = now;
        }
        if (now - t_heard > c.timeout) {
            fprintf(stderr,
                    "fm_pll: nothing from the twin for %g s (is afmtwind running on "
                    "these URLs?)\n",
                    c.timeout);
            break;
        }
        if (c.locked && isnan(t_lock_wall)) t_lock_wall = now;
        if (c.locked && now - t_lock_wall >= c.after) {
            rc = 0;
            break;
        }
        if (!c.locked && c.records > 1 && c.t_last - c.t_first > c.seconds) {
            printf("not locked within %.3f s of model time: f %.4f Hz, phase error %+.3f deg, "
                   "amplitude %.5g nm\n",
                   c.seconds, c.f, c.e, c.a * 1e9);
            break;
        }
    }
    printf("sent %ld commands (seq %d..%ld) in %.3f s (%.0f/s), %ld send errors, %ld times far "
           "behind; %ld records; after the lock: largest |phase error| %.4f deg; final f %.4f "
           "Hz (%+.4f Hz from f0), drive %.5g pm, amplitude %.5g nm\n",
           sent, SEQ0, SEQ0 + sent - 1, mono_s() - t0, sent / (mono_s() - t0), send_errors, late,
           c.records, c.e_max_after, c.f, c.f - c.f0, c.drive * 1e12, c.a * 1e9);
    lcm_destroy(cmd);
    lcm_destroy(in);
    return rc;
}
