/* SPDX-License-Identifier: MIT */
/* cmd_send.c -- `afmtwin send`: builds one command message (dither, setpoint, param,
 * control, tick, scan), checks it with the daemon's own validation and publishes it on LCM or
 * appends it to an LCM log; `send raw` publishes arbitrary bytes (for bad-input tests). */
#include "afmtwin_cmds.h"
#include "opts.h"
#include "lcm_tool.h"
#include "send_wait.h"

#include "transport/afm_cmd_lcm.h"
#include "config/afm_config.h"

#include "afmtwin_control_t.h"
#include "afmtwin_dither_t.h"
#include "afmtwin_param_t.h"
#include "afmtwin_scan_t.h"
#include "afmtwin_setpoint_t.h"
#include "afmtwin_tick_t.h"

#include <lcm/eventlog.h>
#include <lcm/lcm.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SEND_MAX_BYTES 65536
#define SEND_MAX_PARAMS 16
#define SEND_WAIT_S 3.0 /* --wait: default wait for the status and for the answer */

/* The config the limits come from when no --config is given: $AFMTWIN_CONFIG, else the
 * service's (make install: SYSCONFDIR/afmtwin/afmtwind.conf). */
#ifndef AFMT_SERVICE_CONF
#define AFMT_SERVICE_CONF "/etc/afmtwin/afmtwind.conf"
#endif

typedef struct {
    const char *url, *out_url, *prefix, *channel, *log, *config;
    bool wait;
    double wait_s;
    double log_time_s; /* NAN: wall clock */
    int64_t seq, utime;
    bool have_seq, have_utime;
    bool no_check, check_only, quiet;
    long truncate; /* < 0: whole message */
} send_common;

static void send_usage(FILE *f) {
    fprintf(
        f,
        "usage: afmtwin send KIND [OPTIONS] [COMMON OPTIONS]\n\n"
        "Publishes one command to the twin (afmtwind) on LCM. Before publishing, the\n"
        "message is checked with the daemon's own validation: a value the daemon would\n"
        "reject is reported with the daemon's reason and nothing is sent (exit 2).\n\n"
        "kinds:\n"
        "  dither --freq HZ[,HZ..] --amp M[,M..] [--phase RAD[,RAD..]]\n"
        "        base excitation tones (1..4): frequency 1 <= HZ < sample rate / 2 and at\n"
        "        most 4 x the model's highest mode, amplitude 0 <= M <= 1e-6 m with all\n"
        "        tones together <= 1e-6 m and a predicted free tip amplitude <= 100 um\n"
        "        (README, 'Bad input'), start phase of new tones (rad, default 0);\n"
        "        e.g. send dither --freq 338.112kHz --amp 0.087nm\n"
        "  setpoint --z M [--ramp M_S]\n"
        "        tip-sample separation Z, 0 <= M <= 1e-3 m; --ramp > 0 ramps to it at that\n"
        "        rate (m/s), 0 (default) steps; e.g. send setpoint --z 30nm --ramp 1e-6\n"
        "  param NAME=VALUE [NAME=VALUE ...]\n"
        "        live change of 1..16 config parameters by key path, e.g.\n"
        "        send param forces.viscoelastic.eta_pa_s=400 forces.vdw_contact.hamaker_j=1e-19\n"
        "  control run|pause|reset|step [--n N]\n"
        "        run, pause, reset to rest, or advance N samples (step, 1 <= N <= 1e9)\n"
        "  tick --n N\n"
        "        lockstep mode: advance N samples (1 <= N <= 1e9); e.g. send tick --n 14060\n"
        "  scan hold|move|velocity|raster [--x M] [--y M] [--speed M_S] [--vx M_S]\n"
        "       [--vy M_S] [--size-x M] [--size-y M] [--lines N] [--pixels N]\n"
        "       [--line-rate HZ]\n"
        "        move the tip over the config's sample (scan_t; refused without a sample\n"
        "        group): hold stops it; move goes to --x, --y (|x|, |y| <= 1 m, both\n"
        "        required) at --speed (0 .. 0.1 m/s; 0, the default, jumps); velocity\n"
        "        moves at --vx, --vy (m/s, |v| <= 0.1) from where the tip is; raster jumps\n"
        "        to --x, --y (default 0, 0) and runs --lines lines (1..1e5, default 1) of\n"
        "        --size-x (default 400nm) along x, trace then retrace, at --line-rate\n"
        "        (lines per second, <= 10kHz, default 10), the slow axis moving --size-y\n"
        "        (default 0) over the lines, --pixels per line (2..1e5, default 64) for\n"
        "        the status; afmtwin scan's raster (README, 'Scanning');\n"
        "        e.g. send scan raster --x 100nm --size-x 300nm --lines 4 --line-rate 5\n"
        "  raw --channel NAME --hex HEX\n"
        "        publish the bytes HEX as they are (no validation; for bad-input tests)\n\n"
        "common options:\n"
        "  --lcm-url URL     the twin's command URL, as given to afmtwind --lcm-url\n"
        "                    (default: LCM_DEFAULT_URL or LCM's default)\n"
        "  --prefix NAME_    channel-name prefix of the twin (default %s)\n"
        "  --seq N           command sequence number (default: wall-clock microseconds,\n"
        "                    so that later commands have larger numbers)\n"
        "  --utime US        sender time stamp in the message (default: wall clock, us)\n"
        "  --config FILE     the daemon's config, for the limits that depend on it (sample\n"
        "                    rate, modes); default $AFMTWIN_CONFIG, else the service's\n"
        "                    " AFMT_SERVICE_CONF "; none readable: exit 2\n"
        "  --check           validate only; print 'ok' and the config used and exit 0, or\n"
        "                    the reason and exit 2\n"
        "  --wait            after sending, wait for the daemon's status: exit 0 when it\n"
        "                    echoes this seq as applied, 1 with the daemon's reason when it\n"
        "                    rejected or refused the command, or when no answer came\n"
        "  --wait-timeout S  how long --wait waits for a first status and then for the\n"
        "                    answer (default %.0f s)\n"
        "  --lcm-out-url URL the daemon's output URL, for --wait (default: derived from\n"
        "                    --lcm-url, udpm port + 1)\n"
        "  --no-check        publish even what the daemon would reject (bad-input tests)\n"
        "  --channel NAME    publish on NAME instead of PREFIX + the kind's channel\n"
        "                    (e.g. a message of the wrong type on a channel)\n"
        "  --truncate N      publish only the first N bytes of the encoded message\n"
        "  --log FILE        append the message to the LCM log FILE (lcm-logger format)\n"
        "                    instead of publishing\n"
        "  --log-time S      event time stamp in the log, seconds (default: wall clock);\n"
        "                    replay applies an event at model time t - t(first event)\n"
        "  --quiet           print nothing on success\n"
        "  --help            this text\n\n" AFMT_OPT_SI_HELP
        "Exit status 0 sent (with --wait: applied), 1 LCM or file failure (with --wait:\n"
        "rejected, refused or no answer), 2 bad usage, no config, or a value the daemon\n"
        "would reject.\n\n",
        AFMT_DEFAULT_PREFIX, SEND_WAIT_S);
    int n;
    const afm_param_def *d = afm_param_table(&n);
    fprintf(f, "live parameters (send param NAME=VALUE; [i]: one element, the bare name: all):\n");
    for (int i = 0; i < n; i++) {
        char nm[96];
        snprintf(nm, sizeof nm, "%s%s", d[i].name, d[i].n_index ? "[i]" : "");
        fprintf(f, "  %-44s %c%g, %g%c %s\n", nm, d[i].min_open ? '(' : '[', d[i].min, d[i].max,
                d[i].max_open ? ')' : ']', d[i].unit);
    }
}

static int parse_i64(const char *s, int64_t lo, int64_t hi, int64_t *v) {
    char *end;
    if (!s || !*s) return -1;
    long long x = strtoll(s, &end, 10);
    if (*end || x < lo || x > hi) return -1;
    *v = x;
    return 0;
}

/* The kind-specific options: dither, setpoint, control, tick (param and raw take their own
 * positional arguments). NAN / -1: not given. */
typedef struct {
    double freq[AFM_MAX_TONES], amp[AFM_MAX_TONES], phase[AFM_MAX_TONES];
    int n_freq, n_amp, n_phase;
    double z, ramp;
    bool have_z;
    int64_t n;
    bool have_n;
    const char *action;
    const char *names[SEND_MAX_PARAMS];
    double values[SEND_MAX_PARAMS];
    char name_buf[SEND_MAX_PARAMS][AFM_CMD_NAME_LEN * 2];
    int n_params;
    const char *hex;
    /* scan: its mode word, positions and sizes (m), speeds (m/s), counts, line rate */
    const char *mode;
    double x, y, speed, vx, vy, size_x, size_y, line_rate;
    int64_t lines, pixels;
    bool have_x, have_y, have_size_x, have_lines, have_pixels, have_line_rate;
} send_args;

static int parse_seq(const char *v, void *dest) {
    send_common *o = dest;
    o->have_seq = true;
    return parse_i64(v, INT64_MIN, INT64_MAX, &o->seq);
}

static int parse_utime(const char *v, void *dest) {
    send_common *o = dest;
    o->have_utime = true;
    return parse_i64(v, INT64_MIN, INT64_MAX, &o->utime);
}

static int parse_n(const char *v, void *dest) {
    send_args *a = dest;
    a->have_n = true;
    return parse_i64(v, INT64_MIN, INT64_MAX, &a->n);
}

static int parse_x(const char *v, void *dest) {
    send_args *a = dest;
    a->have_x = true;
    return afmt_opt_any_length(v, &a->x);
}

static int parse_y(const char *v, void *dest) {
    send_args *a = dest;
    a->have_y = true;
    return afmt_opt_any_length(v, &a->y);
}

static int parse_size_x(const char *v, void *dest) {
    send_args *a = dest;
    a->have_size_x = true;
    return afmt_opt_any_length(v, &a->size_x);
}

/* --lines, --pixels: an integer (the daemon checks the range; int32 on the wire). */
static int parse_lines(const char *v, void *dest) {
    send_args *a = dest;
    a->have_lines = true;
    return parse_i64(v, INT32_MIN, INT32_MAX, &a->lines);
}

static int parse_pixels(const char *v, void *dest) {
    send_args *a = dest;
    a->have_pixels = true;
    return parse_i64(v, INT32_MIN, INT32_MAX, &a->pixels);
}

static int parse_line_rate(const char *v, void *dest) {
    send_args *a = dest;
    a->have_line_rate = true;
    return afmt_opt_any_freq(v, &a->line_rate);
}

static int parse_z(const char *v, void *dest) {
    send_args *a = dest;
    a->have_z = true;
    return afmt_opt_any_length(v, &a->z);
}

/* --freq, --amp, --phase: 1..AFM_MAX_TONES comma-separated numbers. */
static int parse_freq(const char *v, void *dest) {
    send_args *a = dest;
    return (a->n_freq = afmt_parse_si_list(v, AFMT_UNIT_HZ, a->freq, AFM_MAX_TONES)) < 1 ? -1 : 0;
}

static int parse_amp(const char *v, void *dest) {
    send_args *a = dest;
    return (a->n_amp = afmt_parse_si_list(v, AFMT_UNIT_M, a->amp, AFM_MAX_TONES)) < 1 ? -1 : 0;
}

static int parse_phase(const char *v, void *dest) {
    send_args *a = dest;
    return (a->n_phase = afmt_parse_list(v, a->phase, AFM_MAX_TONES)) < 1 ? -1 : 0;
}

/* param's NAME=VALUE words (at most SEND_MAX_PARAMS). */
static int add_param(const char *s, void *dest) {
    send_args *a = dest;
    const char *eq = strchr(s, '=');
    if (!eq || eq == s || a->n_params >= SEND_MAX_PARAMS ||
        (size_t)(eq - s) >= sizeof a->name_buf[0]) {
        fprintf(stderr, "afmtwin send param: want NAME=VALUE (at most %d), got '%s'\n",
                SEND_MAX_PARAMS, s);
        return AFMT_OPT_REPORTED;
    }
    int k = a->n_params;
    memcpy(a->name_buf[k], s, (size_t)(eq - s));
    a->name_buf[k][eq - s] = 0;
    if (afmt_opt_any_number(eq + 1, &a->values[k])) {
        fprintf(stderr, "afmtwin send param: %s wants a number, got '%s'\n", a->name_buf[k],
                eq + 1);
        return AFMT_OPT_REPORTED;
    }
    a->names[k] = a->name_buf[k];
    a->n_params++;
    return 0;
}

/* Common and kind options; positional words go to the param list or the control action. */
static int parse_args(int argc, char **argv, const char *kind, send_common *o, send_args *a) {
    afmt_opt opts[] = {
        AFMT_STRING("--lcm-url", &o->url),
        AFMT_STRING("--prefix", &o->prefix),
        AFMT_STRING("--channel", &o->channel),
        AFMT_STRING("--config", &o->config),
        AFMT_STRING("--lcm-out-url", &o->out_url),
        AFMT_DOUBLE_ABOVE("--wait-timeout", &o->wait_s, 0, 3600, "seconds in (0, 3600]"),
        AFMT_STRING("--log", &o->log),
        AFMT_DOUBLE("--log-time", &o->log_time_s, 0, 9e12, "seconds >= 0"),
        AFMT_FN("--seq", parse_seq, o, "an integer"),
        AFMT_FN("--utime", parse_utime, o, "an integer"),
        AFMT_LONG("--truncate", &o->truncate, 0, SEND_MAX_BYTES, "a byte count >= 0"),
        AFMT_FN_UNIT("--freq", parse_freq, a,
                     "1..4 comma-separated numbers (Hz, or with a suffix: kHz, MHz, GHz)",
                     AFMT_UNIT_HZ),
        AFMT_FN_UNIT("--amp", parse_amp, a,
                     "1..4 comma-separated numbers (m, or with a suffix: mm, um, nm, pm, fm)",
                     AFMT_UNIT_M),
        AFMT_FN("--phase", parse_phase, a, "1..4 comma-separated numbers (rad)"),
        AFMT_FN_UNIT("--z", parse_z, a, "a number (m, or with a suffix: mm, um, nm, pm, fm)",
                     AFMT_UNIT_M),
        AFMT_FN("--ramp", afmt_opt_any_number, &a->ramp, "a number (m/s)"),
        AFMT_FN("--n", parse_n, a, "an integer"),
        AFMT_FN_UNIT("--x", parse_x, a, "a number (m, or with a suffix: mm, um, nm, pm, fm)",
                     AFMT_UNIT_M),
        AFMT_FN_UNIT("--y", parse_y, a, "a number (m, or with a suffix: mm, um, nm, pm, fm)",
                     AFMT_UNIT_M),
        AFMT_FN("--speed", afmt_opt_any_number, &a->speed, "a number (m/s)"),
        AFMT_FN("--vx", afmt_opt_any_number, &a->vx, "a number (m/s)"),
        AFMT_FN("--vy", afmt_opt_any_number, &a->vy, "a number (m/s)"),
        AFMT_FN_UNIT("--size-x", parse_size_x, a,
                     "a number (m, or with a suffix: mm, um, nm, pm, fm)", AFMT_UNIT_M),
        AFMT_FN_UNIT("--size-y", afmt_opt_any_length, &a->size_y,
                     "a number (m, or with a suffix: mm, um, nm, pm, fm)", AFMT_UNIT_M),
        AFMT_FN("--lines", parse_lines, a, "an integer"),
        AFMT_FN("--pixels", parse_pixels, a, "an integer"),
        AFMT_FN_UNIT("--line-rate", parse_line_rate, a,
                     "a number (Hz, or with a suffix: kHz, MHz, GHz)", AFMT_UNIT_HZ),
        AFMT_STRING("--hex", &a->hex),
        AFMT_FLAG("--no-check", &o->no_check),
        AFMT_FLAG("--check", &o->check_only),
        AFMT_FLAG("--wait", &o->wait),
        AFMT_FLAG("--quiet", &o->quiet),
        AFMT_OPTS_END, /* control's ACTION or param's NAME=VALUE words */
        AFMT_OPTS_END,
    };
    _Static_assert(AFM_MAX_TONES == 4, "the tone lists' error texts");
    afmt_opt *words = &opts[sizeof opts / sizeof opts[0] - 2];
    if (!strcmp(kind, "control"))
        *words = (afmt_opt)AFMT_ARG("ACTION", &a->action);
    else if (!strcmp(kind, "param"))
        *words = (afmt_opt)AFMT_ARG_FN("NAME=VALUE", add_param, a, NULL);
    else if (!strcmp(kind, "scan"))
        *words = (afmt_opt)AFMT_ARG("MODE", &a->mode);
    char tool[64];
    snprintf(tool, sizeof tool, "send %s", kind);
    int rc = afmt_opts_parse(tool, opts, argc, argv, 2);
    return rc == AFMT_OPTS_OK ? 0 : 2; /* --help was answered before */
}

/* Build and encode the message of kind into buf. Returns the byte count, -2 on bad usage
 * (message printed). */
static int build(const char *kind, const send_common *o, send_args *a, uint8_t *buf, int cap,
                 afm_cmd_kind *ck) {
    int64_t utime = o->have_utime ? o->utime : afmt_wall_us();
    int64_t seq = o->have_seq ? o->seq : afmt_wall_us();
    if (!strcmp(kind, "dither")) {
        if (a->n_freq < 1 || a->n_amp < 1) {
            fprintf(stderr, "afmtwin send dither: --freq and --amp are required\n");
            return -2;
        }
        if (a->n_amp != a->n_freq || (a->n_phase && a->n_phase != a->n_freq)) {
            fprintf(stderr, "afmtwin send dither: --freq, --amp (and --phase) need one value "
                            "per tone\n");
            return -2;
        }
        for (int j = a->n_phase; j < a->n_freq; j++)
            a->phase[j] = 0.0;
        afmtwin_dither_t m = {.utime = utime,
                              .seq = seq,
                              .n_tones = (int8_t)a->n_freq,
                              .frequency_hz = a->freq,
                              .amplitude_m = a->amp,
                              .phase_rad = a->phase};
        *ck = AFM_CMD_DITHER;
        return AFMT_ENCODE(afmtwin_dither_t, &m, buf, cap);
    }
    if (!strcmp(kind, "setpoint")) {
        if (!a->have_z) {
            fprintf(stderr, "afmtwin send setpoint: --z is required\n");
            return -2;
        }
        afmtwin_setpoint_t m = {
            .utime = utime, .seq = seq, .separation_m = a->z, .ramp_rate_m_s = a->ramp};
        *ck = AFM_CMD_SETPOINT;
        return AFMT_ENCODE(afmtwin_setpoint_t, &m, buf, cap);
    }
    if (!strcmp(kind, "param")) {
        if (a->n_params < 1) {
            fprintf(stderr, "afmtwin send param: give at least one NAME=VALUE\n");
            return -2;
        }
        afmtwin_param_t m = {.utime = utime,
                             .seq = seq,
                             .n = (int16_t)a->n_params,
                             .name = (char **)a->names,
                             .value = a->values};
        *ck = AFM_CMD_PARAM;
        return AFMT_ENCODE(afmtwin_param_t, &m, buf, cap);
    }
    if (!strcmp(kind, "control")) {
        static const char *const names[] = {"run", "pause", "reset", "step"};
        static const int8_t codes[] = {AFMTWIN_CONTROL_T_RUN, AFMTWIN_CONTROL_T_PAUSE,
                                       AFMTWIN_CONTROL_T_RESET, AFMTWIN_CONTROL_T_STEP};
        int k = -1;
        for (int i = 0; i < 4 && a->action; i++)
            if (!strcmp(a->action, names[i])) k = i;
        if (k < 0) {
            fprintf(stderr, "afmtwin send control: want run, pause, reset or step, got '%s'\n",
                    a->action ? a->action : "");
            return -2;
        }
        if (codes[k] == AFMTWIN_CONTROL_T_STEP && !a->have_n) {
            fprintf(stderr, "afmtwin send control step: --n N is required\n");
            return -2;
        }
        afmtwin_control_t m = {
            .utime = utime, .seq = seq, .action = codes[k], .n_samples = a->have_n ? a->n : 0};
        *ck = AFM_CMD_CONTROL;
        return AFMT_ENCODE(afmtwin_control_t, &m, buf, cap);
    }
    if (!strcmp(kind, "tick")) {
        if (!a->have_n) {
            fprintf(stderr, "afmtwin send tick: --n N is required\n");
            return -2;
        }
        afmtwin_tick_t m = {.utime = utime, .seq = seq, .n_samples = a->n};
        *ck = AFM_CMD_TICK;
        return AFMT_ENCODE(afmtwin_tick_t, &m, buf, cap);
    }
    if (!strcmp(kind, "scan")) {
        static const char *const names[] = {"hold", "move", "velocity", "raster"};
        static const int8_t codes[] = {AFMTWIN_SCAN_T_HOLD, AFMTWIN_SCAN_T_MOVE,
                                       AFMTWIN_SCAN_T_VELOCITY, AFMTWIN_SCAN_T_RASTER};
        int k = -1;
        for (int i = 0; i < 4 && a->mode; i++)
            if (!strcmp(a->mode, names[i])) k = i;
        if (k < 0) {
            fprintf(stderr, "afmtwin send scan: want hold, move, velocity or raster, got '%s'\n",
                    a->mode ? a->mode : "");
            return -2;
        }
        if (codes[k] == AFMTWIN_SCAN_T_MOVE && !(a->have_x && a->have_y)) {
            fprintf(stderr, "afmtwin send scan move: --x and --y are required\n");
            return -2;
        }
        bool raster = codes[k] == AFMTWIN_SCAN_T_RASTER;
        afmtwin_scan_t m = {.utime = utime,
                            .seq = seq,
                            .mode = codes[k],
                            .x_m = a->x,
                            .y_m = a->y,
                            .speed_m_s = a->speed,
                            .vx_m_s = a->vx,
                            .vy_m_s = a->vy,
                            /* a raster's defaults: afmtwin scan's */
                            .size_x_m = raster && !a->have_size_x ? 4e-7 : a->size_x,
                            .size_y_m = a->size_y,
                            .lines = (int32_t)(raster && !a->have_lines ? 1 : a->lines),
                            .pixels = (int32_t)(raster && !a->have_pixels ? 64 : a->pixels),
                            .line_rate_hz = raster && !a->have_line_rate ? 10.0 : a->line_rate};
        *ck = AFM_CMD_SCAN;
        return AFMT_ENCODE(afmtwin_scan_t, &m, buf, cap);
    }
    if (!strcmp(kind, "raw")) {
        if (!a->hex || !o->channel) {
            fprintf(stderr, "afmtwin send raw: --channel and --hex are required\n");
            return -2;
        }
        int n = afmt_parse_hex(a->hex, buf, cap);
        if (n < 0) {
            fprintf(stderr,
                    "afmtwin send raw: --hex wants pairs of hex digits (at most %d bytes)\n", cap);
            return -2;
        }
        *ck = 0;
        return n;
    }
    fprintf(stderr,
            "afmtwin send: unknown kind '%s' (dither, setpoint, param, control, tick, scan, "
            "raw)\n",
            kind);
    return -2;
}

/* The daemon's checks: decode + validate the bytes as it would (afm_cmd_decode, with the
 * config's sample rate and model in the limits: afm_limits.h), and for param, apply to a
 * copy of the config (names that do not fit it). 0, or -1 with err. */
/* The config the limits come from (see AFMT_SERVICE_CONF): NULL with err if none. */
static const char *config_path(const send_common *o, char *err, size_t errlen) {
    if (o->config) return o->config;
    const char *env = getenv("AFMTWIN_CONFIG");
    if (env && *env) return env;
    FILE *f = fopen(AFMT_SERVICE_CONF, "r");
    if (f) {
        fclose(f);
        return AFMT_SERVICE_CONF;
    }
    snprintf(err, errlen,
             "no config to check against: the service's %s is not readable and neither "
             "--config nor AFMTWIN_CONFIG is given (or --no-check to send unchecked)",
             AFMT_SERVICE_CONF);
    return NULL;
}

static int daemon_check(afm_cmd_kind ck, const uint8_t *buf, int n, const send_common *o, char *err,
                        size_t errlen) {
    static afm_config cfg; /* large: not on the stack */
    afm_cmd_limits lim = {.sample_rate_hz = 0.0};
    bool have_cfg = false;
    const char *path = o->config;
    static afm_modal model; /* the limits that need the model: its modes and tip response */
    if (path) {
        if (afm_config_load(path, &cfg, err, errlen)) return -2;
        if (afm_model_build(&cfg.model, &model, err, errlen)) return -2;
        lim.sample_rate_hz = cfg.sim.sample_rate_hz;
        lim.model = &model;
        have_cfg = true;
    }
    afm_cmd c;
    if (afm_cmd_decode(ck, buf, (size_t)n, &lim, &c, err, errlen)) return -1;
    if (ck == AFM_CMD_PARAM && have_cfg && afm_param_apply(&cfg, &c.u.param, NULL, err, errlen))
        return -1;
    return 0;
}

static int emit(const send_common *o, const char *channel, const uint8_t *buf, int n) {
    if (o->log) {
        lcm_eventlog_t *l = lcm_eventlog_create(o->log, "a");
        if (!l) {
            fprintf(stderr, "afmtwin send: cannot open log '%s' for appending\n", o->log);
            return 1;
        }
        int64_t t_us =
            isnan(o->log_time_s) ? afmt_wall_us() : (int64_t)llround(o->log_time_s * 1e6);
        int rc = afmt_log_write(l, t_us, channel, buf, n);
        lcm_eventlog_destroy(l);
        if (rc) {
            fprintf(stderr, "afmtwin send: writing to log '%s' failed\n", o->log);
            return 1;
        }
        return 0;
    }
    lcm_t *lcm = lcm_create(o->url);
    if (!lcm) {
        fprintf(stderr, "afmtwin send: cannot open LCM on '%s'\n", o->url ? o->url : "(default)");
        return 1;
    }
    int rc = lcm_publish(lcm, channel, buf, (unsigned)n);
    lcm_destroy(lcm);
    if (rc) {
        fprintf(stderr, "afmtwin send: publishing on %s failed\n", channel);
        return 1;
    }
    return 0;
}

int afm_cmd_send(int argc, char **argv) {
    if (argc < 2 || !strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
        send_usage(argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    const char *kind = argv[1];
    for (int i = 2; i < argc; i++)
        if (!strcmp(argv[i], "--help") || !strcmp(argv[i], "-h")) {
            send_usage(stdout);
            return 0;
        }
    send_common o = {
        .prefix = AFMT_DEFAULT_PREFIX, .log_time_s = NAN, .truncate = -1, .wait_s = SEND_WAIT_S};
    static send_args a; /* zeroed */
    memset(&a, 0, sizeof a);
    int rc = parse_args(argc, argv, kind, &o, &a);
    if (rc) return rc;
    if (!o.have_seq) { /* wall-clock microseconds: later commands have larger numbers */
        o.seq = afmt_wall_us();
        o.have_seq = true;
    }
    static uint8_t buf[SEND_MAX_BYTES];
    afm_cmd_kind ck = 0;
    int n = build(kind, &o, &a, buf, sizeof buf, &ck);
    if (n == -2) return 2;
    if (n < 0) {
        fprintf(stderr, "afmtwin send %s: the message does not encode (too large?)\n", kind);
        return 2;
    }
    char channel[AFMT_CHAN_LEN], err[AFM_ERR_LEN];
    afmt_channels ch;
    if (o.channel) {
        snprintf(channel, sizeof channel, "%s", o.channel);
    } else if (afmt_channels_init(&ch, o.prefix, err, sizeof err)) {
        fprintf(stderr, "afmtwin send: %s\n", err);
        return 2;
    } else {
        snprintf(channel, sizeof channel, "%s", ch.cmd[ck]);
    }
    if (ck && !o.no_check) {
        if (!(o.config = config_path(&o, err, sizeof err))) {
            fprintf(stderr, "afmtwin send %s: %s\n", kind, err);
            return 2;
        }
        int v = daemon_check(ck, buf, n, &o, err, sizeof err);
        if (v) {
            fprintf(stderr, "afmtwin send %s: %s%s\n", kind,
                    v == -1 ? "the daemon would reject: " : "", err);
            return 2;
        }
    }
    if (o.check_only) {
        if (!o.quiet) printf("ok (checked against %s)\n", o.config ? o.config : "no config");
        return 0;
    }
    if (o.wait && o.log) {
        fprintf(stderr, "afmtwin send: --wait and --log do not go together\n");
        return 2;
    }
    send_wait *w = NULL;
    if (o.wait && !(w = send_wait_open(o.url, o.out_url, o.prefix, o.wait_s, err, sizeof err))) {
        fprintf(stderr, "afmtwin send %s: %s\n", kind, err);
        return 1;
    }
    if (o.truncate >= 0 && o.truncate < n) n = (int)o.truncate;
    rc = emit(&o, channel, buf, n);
    if (rc == 0 && !o.quiet)
        printf("%s %s %d bytes on %s%s%s%s\n", o.log ? "logged" : "sent", kind, n, channel,
               o.config ? " (checked against " : "", o.config ? o.config : "", o.config ? ")" : "");
    if (rc == 0 && w) {
        int r = send_wait_result(w, o.seq, channel, o.wait_s, err, sizeof err);
        if (r == 0 && !o.quiet)
            printf("applied: the daemon's status echoes seq %lld\n", (long long)o.seq);
        if (r != 0) fprintf(stderr, "afmtwin send %s: seq %lld %s\n", kind, (long long)o.seq, err);
        rc = r == 0 ? 0 : 1;
    }
    send_wait_destroy(&w);
    return rc;
}
