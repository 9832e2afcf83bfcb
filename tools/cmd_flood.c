/* SPDX-License-Identifier: MIT */
/* cmd_flood.c -- `afmtwin flood`: a bounded flood of junk on the daemon's command channels,
 * with valid setpoints mixed in, to show that bad bytes change nothing, crash nothing and
 * are all counted (status: received = applied + rejected + refused + dropped).
 *
 * Junk kinds, each built from real messages (lcm-gen's encoders) and then broken:
 *   random     random bytes (0..300) on a random command channel
 *   truncated  a valid message cut short
 *   wrongtype  a valid message of another type (wrong fingerprint for the channel)
 *   values     valid layouts with NaN, inf and out-of-range values (a 5e-324 Hz tone, four
 *              tones of 1 um, Z = -1, unknown or repeated parameter names, step -5, ...)
 *   lengths    crafted counts and lengths (the 33-byte dither with n_tones 127, n_tones -3,
 *              a param string length of 0xffffffff, a param n of 30000, names with control
 *              characters)
 * Valid setpoints (Z 40 / 41 nm by turns, seq counting up from --seq0) go out at
 * --valid-rate. The flood is paced by the wall clock in 1 ms slices at --rate (at most
 * 200000 messages a second) and stops after --seconds (at most 600). It prints what it
 * sent per kind, the rate it reached, and the first and last valid seq, so a caller can
 * check that every valid command was applied. */
#include "afmtwin_cmds.h"
#include "lcm_tool.h"
#include "opts.h"

#include "afmtwin_control_t.h"
#include "afmtwin_dither_t.h"
#include "afmtwin_param_t.h"
#include "afmtwin_setpoint_t.h"
#include "afmtwin_tick_t.h"

#include <lcm/lcm.h>
#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

enum { K_RANDOM, K_TRUNC, K_WRONG, K_VALUES, K_LENGTHS, N_KINDS };
static const char *const kind_name[N_KINDS] = {"random", "truncated", "wrongtype", "values",
                                               "lengths"};

typedef struct {
    double rate, seconds, valid_rate;
    bool want[N_KINDS];
    int valid_param; /* valid commands: beam-length params (a model build each), not Z */
    const char *url, *prefix;
    unsigned seed;
    long long seq0;
    afmt_channels ch; /* target t (0..4: dither .. tick) is ch.cmd[AFM_CMD_DITHER + t] */
} flood_opts;

static uint64_t rng;
static uint32_t rnd(void) { /* xorshift64* */
    rng ^= rng >> 12;
    rng ^= rng << 25;
    rng ^= rng >> 27;
    return (uint32_t)((rng * 2685821657736338717ULL) >> 32);
}

static void flood_usage(FILE *f) {
    fprintf(f,
            "usage: afmtwin flood [--rate N] [--seconds S] [--kinds LIST] [--valid-rate R]\n"
            "                     [--valid-kind K] [--seq0 N] [--seed N] [--lcm-url URL]\n"
            "                     [--prefix NAME_]\n\n"
            "Sends a bounded flood of junk to the daemon's command channels, with valid\n"
            "setpoints mixed in, and prints what it sent. For robustness tests: the daemon must\n"
            "reject the junk, count every message and apply every valid command.\n\n"
            "options:\n"
            "  --rate N        junk messages a second (default 20000, at most 200000)\n"
            "  --seconds S     how long (default 5, at most 600)\n"
            "  --kinds LIST    comma-separated subset of random,truncated,wrongtype,values,\n"
            "                  lengths (default all, mixed)\n"
            "  --valid-rate R  valid setpoints a second among the junk (default 10; 0: none)\n"
            "  --valid-kind K  setpoint (default: Z 40 / 41 nm) or param (model.beam.length_m\n"
            "                  225 / 226 um: the daemon builds a model for each, slowly)\n"
            "  --seq0 N        seq of the first valid setpoint (default: wall-clock us)\n"
            "  --seed N        junk generator seed (default 1)\n"
            "  --lcm-url URL   the daemon's command URL (default: LCM_DEFAULT_URL or LCM's)\n"
            "  --prefix NAME_  channel prefix (default %s)\n"
            "  --help          this text\n\n"
            "Output: one line 'flood: sent N junk (random a, truncated b, ...) + V valid "
            "(seq F..L) in S s'.\nExit status 0 sent, 1 LCM failure, 2 bad usage.\n",
            AFMT_DEFAULT_PREFIX);
}

/* A valid message of channel type t (0..4) into b; its length. */
static int valid_msg(int t, uint8_t *b, int cap) {
    static double f[4] = {338112, 2.07e6, 3e5, 1e6}, a[4] = {0.087e-9, 1e-11, 0, 0}, p[4] = {0};
    static const char *names[2] = {"forces.vdw_contact.hamaker_j", "forces.radius_m"};
    static double v[2] = {1.3e-19, 1e-8};
    switch (t) {
    case 0: {
        afmtwin_dither_t m = {.utime = 1,
                              .seq = 1,
                              .n_tones = 1 + (int8_t)(rnd() % 2),
                              .frequency_hz = f,
                              .amplitude_m = a,
                              .phase_rad = p};
        return afmtwin_dither_t_encode(b, 0, cap, &m);
    }
    case 1: {
        afmtwin_setpoint_t m = {.utime = 1, .seq = 1, .separation_m = 40e-9};
        return afmtwin_setpoint_t_encode(b, 0, cap, &m);
    }
    case 2: {
        afmtwin_param_t m = {.utime = 1,
                             .seq = 1,
                             .n = 1 + (int16_t)(rnd() % 2),
                             .name = (char **)names,
                             .value = v};
        return afmtwin_param_t_encode(b, 0, cap, &m);
    }
    case 3: {
        afmtwin_control_t m = {.utime = 1, .seq = 1, .action = AFMTWIN_CONTROL_T_RESET};
        return afmtwin_control_t_encode(b, 0, cap, &m);
    }
    default: {
        afmtwin_tick_t m = {.utime = 1, .seq = 1, .n_samples = 1000};
        return afmtwin_tick_t_encode(b, 0, cap, &m);
    }
    }
}

/* Valid layouts, invalid values; channel type into *t. */
static int bad_values(int *t, uint8_t *b, int cap) {
    double f[4] = {338112, 338112, 338112, 338112}, a[4] = {1e-6, 1e-6, 1e-6, 1e-6}, p[4] = {0};
    const char *nm[2] = {"forces.nope", "forces.radius_m"};
    double v[2] = {NAN, 1e-8};
    switch (rnd() % 8) {
    case 0: { /* four tones of 1 um: each within its limit, the sum not */
        afmtwin_dither_t m = {.n_tones = 4, .frequency_hz = f, .amplitude_m = a, .phase_rad = p};
        *t = 0;
        return afmtwin_dither_t_encode(b, 0, cap, &m);
    }
    case 1: { /* 5e-324 Hz, NaN, inf */
        f[0] = (double[]){5e-324, NAN, INFINITY, -1, 8e6}[rnd() % 5];
        a[0] = 1e-10;
        afmtwin_dither_t m = {.n_tones = 1, .frequency_hz = f, .amplitude_m = a, .phase_rad = p};
        *t = 0;
        return afmtwin_dither_t_encode(b, 0, cap, &m);
    }
    case 2: {
        afmtwin_setpoint_t m = {.separation_m = (double[]){-1, NAN, 2e-3, INFINITY}[rnd() % 4]};
        *t = 1;
        return afmtwin_setpoint_t_encode(b, 0, cap, &m);
    }
    case 3: {
        afmtwin_setpoint_t m = {.separation_m = 40e-9, .ramp_rate_m_s = 10};
        *t = 1;
        return afmtwin_setpoint_t_encode(b, 0, cap, &m);
    }
    case 4: { /* unknown name; NaN value; the same name twice */
        static const char *nan_names[2] = {"forces.radius_m", "drive.separation_m"};
        int k = rnd() % 3;
        if (k == 2) nm[0] = nm[1];
        afmtwin_param_t m = {.n = 2, .name = (char **)(k == 1 ? nan_names : nm), .value = v};
        *t = 2;
        return afmtwin_param_t_encode(b, 0, cap, &m);
    }
    case 5: {
        afmtwin_control_t m = {.action = (int8_t)(rnd() % 2 ? 9 : AFMTWIN_CONTROL_T_STEP),
                               .n_samples = -5};
        *t = 3;
        return afmtwin_control_t_encode(b, 0, cap, &m);
    }
    case 6: { /* a tick (the daemon is not in lockstep), or 0 samples */
        afmtwin_tick_t m = {.n_samples = rnd() % 2 ? 0 : 1000};
        *t = 4;
        return afmtwin_tick_t_encode(b, 0, cap, &m);
    }
    default: { /* a valid dither at the resonance with 1 um: ~0.66 mm free amplitude */
        f[0] = 338112;
        afmtwin_dither_t m = {.n_tones = 1, .frequency_hz = f, .amplitude_m = a, .phase_rad = p};
        *t = 0;
        return afmtwin_dither_t_encode(b, 0, cap, &m);
    }
    }
}

static void put_be32(uint8_t *p, uint32_t v) {
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (24 - 8 * i));
}

/* Crafted counts and lengths. */
static int bad_lengths(int *t, uint8_t *b, int cap) {
    int n;
    switch (rnd() % 5) {
    case 0: /* the 33-byte dither with n_tones 127 (leaked ~1 KB each before issue 13) */
        n = valid_msg(0, b, cap);
        b[24] = 127;
        *t = 0;
        return 33;
    case 1: /* n_tones -3: lcm_malloc((size_t)-24) */
        n = valid_msg(0, b, cap);
        b[24] = 0xfd;
        *t = 0;
        return n;
    case 2: /* param string length 0xffffffff or 0x7fffffff */
        n = valid_msg(2, b, cap);
        put_be32(b + 26, rnd() % 2 ? 0xffffffffu : 0x7fffffffu);
        *t = 2;
        return n;
    case 3: /* param n = 30000 in a 2-name body */
        n = valid_msg(2, b, cap);
        b[24] = 0x75;
        b[25] = 0x30;
        *t = 2;
        return n;
    default: { /* names with control characters (echoed in the reason: must be quoted) */
        const char *nm[1] = {"forces.\x1b[31mred\x1b[0m\n\rx"};
        afmtwin_param_t m = {.n = 1, .name = (char **)nm, .value = (double[]){1}};
        *t = 2;
        return afmtwin_param_t_encode(b, 0, cap, &m);
    }
    }
}

static int junk(int kind, int *t, uint8_t *b, int cap) {
    int n;
    switch (kind) {
    case K_RANDOM:
        n = (int)(rnd() % 301);
        for (int i = 0; i < n; i++)
            b[i] = (uint8_t)rnd();
        *t = (int)(rnd() % 5);
        return n;
    case K_TRUNC:
        *t = (int)(rnd() % 5);
        n = valid_msg(*t, b, cap);
        return (int)(rnd() % (unsigned)n);
    case K_WRONG: {
        int src = (int)(rnd() % 5);
        *t = (src + 1 + (int)(rnd() % 4)) % 5;
        return valid_msg(src, b, cap);
    }
    case K_VALUES:
        return bad_values(t, b, cap);
    default:
        return bad_lengths(t, b, cap);
    }
}

static void sleep_until(double t) {
    double now = afmt_mono_s();
    if (t <= now) return;
    struct timespec ts = {(time_t)(t - now), (long)((t - now - floor(t - now)) * 1e9)};
    nanosleep(&ts, NULL);
}

/* --valid-kind setpoint|param: what the valid commands are (1: param). */
static const afmt_choice valid_kind_choices[] = {{"setpoint", 0}, {"param", 1}, {NULL, 0}};

static int parse_kinds(const char *v, void *dest) {
    return afmt_parse_subset(v, kind_name, N_KINDS, true, dest);
}

int afm_cmd_flood(int argc, char **argv) {
    flood_opts o = {.rate = 20000,
                    .seconds = 5,
                    .valid_rate = 10,
                    .prefix = AFMT_DEFAULT_PREFIX,
                    .seed = 1,
                    .seq0 = -1};
    for (int i = 0; i < N_KINDS; i++)
        o.want[i] = true;
    const afmt_opt opts[] = {
        AFMT_DOUBLE("--rate", &o.rate, 1, 200000, "1..200000 messages a second"),
        AFMT_DOUBLE_ABOVE("--seconds", &o.seconds, 0, 600, "seconds in (0, 600]"),
        AFMT_DOUBLE("--valid-rate", &o.valid_rate, 0, 10000, "0..10000 a second"),
        AFMT_NUMBER("--seq0", AFMT_OPT_LLONG, &o.seq0, 0, 9e15 - 1, "an integer in 0..9e15 - 1"),
        AFMT_NUMBER("--seed", AFMT_OPT_UINT, &o.seed, 0, 4e9 - 1, "an integer in 0..4e9 - 1"),
        AFMT_CHOICE("--valid-kind", &o.valid_param, valid_kind_choices),
        AFMT_FN("--kinds", parse_kinds, o.want, "a comma-separated subset of the kinds (or all)"),
        AFMT_STRING("--lcm-url", &o.url),
        AFMT_STRING("--prefix", &o.prefix),
        AFMT_OPTS_END,
    };
    int prc = afmt_opts_parse("flood", opts, argc, argv, 1);
    if (prc == AFMT_OPTS_HELP) flood_usage(stdout);
    if (prc) return prc == AFMT_OPTS_HELP ? 0 : 2;
    char err[256];
    if (afmt_channels_init(&o.ch, o.prefix, err, sizeof err)) {
        fprintf(stderr, "afmtwin flood: %s\n", err);
        return 2;
    }
    int kinds[N_KINDS], nk = 0;
    for (int i = 0; i < N_KINDS; i++)
        if (o.want[i]) kinds[nk++] = i;
    lcm_t *lcm = lcm_create(o.url);
    if (!lcm) {
        fprintf(stderr, "afmtwin flood: cannot open LCM on '%s'\n", o.url ? o.url : "(default)");
        return 1;
    }
    rng = 0x9E3779B97F4A7C15ULL ^ ((uint64_t)o.seed << 1 | 1);
    long long seq = o.seq0 >= 0 ? o.seq0 : (long long)afmt_wall_us();
    long long sent[N_KINDS] = {0}, total = 0, valid = 0, failed = 0;
    long long first_seq = -1, last_seq = -1;
    static uint8_t b[65536];
    /* Paced by the wall clock in 1 ms slices: what is due by now goes out now (a sender
     * kept off the CPU catches up in bursts), and it stops at t0 + seconds whatever it
     * reached: the rate printed is the one achieved. */
    double t0 = afmt_mono_s(), slice = 1e-3;
    for (long long s = 1;; s++) {
        double el = afmt_mono_s() - t0;
        if (el >= o.seconds) break;
        long long due = (long long)(el * o.rate), vdue = (long long)(el * o.valid_rate);
        /* the valid ones first: a sender kept off the CPU spends its slice on the junk
         * burst, and would otherwise reach the end of the run with none sent */
        while (valid < vdue && afmt_mono_s() - t0 < o.seconds) {
            int n, ch = 1;
            if (o.valid_param) {
                static const char *len_name[1] = {"model.beam.length_m"};
                double len = valid % 2 ? 226e-6 : 225e-6;
                afmtwin_param_t m = {.utime = afmt_wall_us(),
                                     .seq = seq,
                                     .n = 1,
                                     .name = (char **)len_name,
                                     .value = &len};
                n = afmtwin_param_t_encode(b, 0, (int)sizeof b, &m);
                ch = 2;
            } else {
                afmtwin_setpoint_t m = {
                    .utime = afmt_wall_us(), .seq = seq, .separation_m = valid % 2 ? 41e-9 : 40e-9};
                n = afmtwin_setpoint_t_encode(b, 0, (int)sizeof b, &m);
            }
            if (lcm_publish(lcm, o.ch.cmd[AFM_CMD_DITHER + ch], b, (unsigned)n) < 0) failed++;
            if (first_seq < 0) first_seq = seq;
            last_seq = seq++;
            valid++;
        }
        while (total < due && ((total & 63) || afmt_mono_s() - t0 < o.seconds)) {
            int k = kinds[rnd() % (unsigned)nk], t = 0;
            int n = junk(k, &t, b, (int)sizeof b);
            if (lcm_publish(lcm, o.ch.cmd[AFM_CMD_DITHER + t], b, (unsigned)n) < 0) failed++;
            sent[k]++;
            total++;
        }
        sleep_until(t0 + (double)s * slice);
    }
    double dt = afmt_mono_s() - t0;
    lcm_destroy(lcm);
    printf("flood: sent %lld junk (", total);
    for (int i = 0, first = 1; i < N_KINDS; i++)
        if (o.want[i]) {
            printf("%s%s %lld", first ? "" : ", ", kind_name[i], sent[i]);
            first = 0;
        }
    printf(") + %lld valid (seq %lld..%lld) in %.3f s (%.0f msg/s); %lld publish failures\n", valid,
           first_seq, last_seq, dt, (double)(total + valid) / dt, failed);
    return failed ? 1 : 0;
}
