/* SPDX-License-Identifier: MIT */
/* test_cmd.c -- command decoding and validation (afm_cmd): every kind of bad input the
 * daemon must reject (NaN, inf, out-of-range values, unknown and malformed parameter names,
 * truncated and malformed bodies, the wrong message type on a channel, trailing bytes),
 * each with a reason; valid commands decode to the right values, and afm_cmd_encode (the
 * daemon's --applied-log) gives each one back as a body that decodes to it bit for bit;
 * afm_param_apply changes a config only when the whole result is valid and the name fits it. */
#include "transport/afm_cmd_lcm.h"
#include "afmtwin_control_t.h"
#include "afmtwin_dither_t.h"
#include "afmtwin_param_t.h"
#include "afmtwin_scan_t.h"
#include "afmtwin_setpoint_t.h"
#include "afmtwin_tick_t.h"
#include "check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const afm_cmd_limits lim = {.sample_rate_hz = 14.06e6};
static unsigned char buf[65536];
static int buf_len;

/* Decode buf as kind; expect rejection (want_ok 0) with `needle` in the reason. */
static void expect(afm_cmd_kind kind, int want_ok, const char *needle, const char *what) {
    afm_cmd c;
    char err[AFM_ERR_LEN] = "";
    int rc = afm_cmd_decode(kind, buf, (size_t)buf_len, &lim, &c, err, sizeof err);
    char name[AFM_ERR_LEN + 300];
    if (want_ok) {
        snprintf(name, sizeof name, "%s: accepted (%s)", what, rc ? err : "ok");
        check_true(rc == 0, name);
        if (rc == 0) { /* encoded again (--applied-log), it decodes to the same bits */
            static unsigned char b2[65536];
            afm_cmd c2;
            int n2 = afm_cmd_encode(&c, b2, (int)sizeof b2);
            int rc2 =
                n2 > 0 ? afm_cmd_decode(kind, b2, (size_t)n2, &lim, &c2, err, sizeof err) : -1;
            snprintf(name, sizeof name, "%s: encoded again (%d bytes, %s %d), decodes to the same",
                     what, n2, afm_cmd_channel_suffix(kind), buf_len);
            check_true(rc2 == 0 && memcmp(&c, &c2, sizeof c) == 0, name);
        }
    } else {
        snprintf(name, sizeof name, "%s: rejected: \"%s\"", what, err);
        check_true(rc == -1 && err[0] && (!needle || strstr(err, needle)), name);
    }
}

static void dither(int n, double f0, double a0, double p0, const char *needle, int ok,
                   const char *what) {
    /* room for the 5 tones of the n_tones = 5 case (the encoder reads n values) */
    double f[5] = {f0, 300e3, 300e3, 300e3, 300e3}, a[5] = {a0, 1e-10, 1e-10, 1e-10, 1e-10},
           p[5] = {p0, 0, 0, 0, 0};
    afmtwin_dither_t m = {.utime = 1,
                          .seq = 7,
                          .n_tones = (int8_t)n,
                          .frequency_hz = f,
                          .amplitude_m = a,
                          .phase_rad = p};
    buf_len = afmtwin_dither_t_encode(buf, 0, sizeof buf, &m);
    expect(AFM_CMD_DITHER, ok, needle, what);
}

static void setpoint(double z, double rate, const char *needle, int ok, const char *what) {
    afmtwin_setpoint_t m = {.utime = 1, .seq = 8, .separation_m = z, .ramp_rate_m_s = rate};
    buf_len = afmtwin_setpoint_t_encode(buf, 0, sizeof buf, &m);
    expect(AFM_CMD_SETPOINT, ok, needle, what);
}

static void param(int n, const char **names, const double *values, const char *needle, int ok,
                  const char *what) {
    afmtwin_param_t m = {
        .utime = 1, .seq = 9, .n = (int16_t)n, .name = (char **)names, .value = (double *)values};
    buf_len = afmtwin_param_t_encode(buf, 0, sizeof buf, &m);
    expect(AFM_CMD_PARAM, ok, needle, what);
}

static void control(int action, long long n, const char *needle, int ok, const char *what) {
    afmtwin_control_t m = {.utime = 1, .seq = 10, .action = (int8_t)action, .n_samples = n};
    buf_len = afmtwin_control_t_encode(buf, 0, sizeof buf, &m);
    expect(AFM_CMD_CONTROL, ok, needle, what);
}

static void tick(long long n, const char *needle, int ok, const char *what) {
    afmtwin_tick_t m = {.utime = 1, .seq = 11, .n_samples = n};
    buf_len = afmtwin_tick_t_encode(buf, 0, sizeof buf, &m);
    expect(AFM_CMD_TICK, ok, needle, what);
}

/* A scan command (every field set) through expect: decoded, encoded again, decoded. */
static void test_scan_encode(void) {
    afmtwin_scan_t m = {.utime = 3,
                        .seq = 12,
                        .mode = AFMTWIN_SCAN_T_RASTER,
                        .x_m = -1e-6,
                        .y_m = 2e-7,
                        .size_x_m = 1e-6,
                        .size_y_m = 5e-7,
                        .lines = 16,
                        .pixels = 64,
                        .line_rate_hz = 2.5};
    buf_len = afmtwin_scan_t_encode(buf, 0, sizeof buf, &m);
    expect(AFM_CMD_SCAN, 1, NULL, "scan raster");
    afm_cmd r = {.kind = AFM_CMD_RELOAD};
    check_true(afm_cmd_encode(&r, buf, (int)sizeof buf) == -1 &&
                   afm_cmd_channel_suffix(AFM_CMD_RELOAD) == NULL,
               "a reload comes from no message: not encoded");
    afm_cmd d = {.kind = AFM_CMD_DITHER, .u.dither = {.n_tones = 1}};
    check_true(afm_cmd_encode(&d, buf, 10) == -1, "encode into too small a buffer: -1");
}

static void test_dither(void) {
    dither(1, 338112, 0.087e-9, 0, NULL, 1, "dither one tone");
    dither(4, 338112, 0.087e-9, 1.0, NULL, 1, "dither four tones");
    dither(1, NAN, 1e-10, 0, "non-finite", 0, "dither NaN frequency");
    dither(1, 3e5, INFINITY, 0, "non-finite", 0, "dither inf amplitude");
    dither(1, 3e5, 1e-10, NAN, "non-finite", 0, "dither NaN phase");
    dither(0, 3e5, 1e-10, 0, "n_tones", 0, "dither 0 tones");
    dither(5, 3e5, 1e-10, 0, "n_tones", 0, "dither 5 tones");
    dither(1, 3e5, 1e-10, 0, NULL, 1, "dither before its n_tones is set to -3");
    buf[24] = 0xfd; /* int8 n_tones = -3 (lcm-gen cannot encode it) */
    expect(AFM_CMD_DITHER, 0, NULL, "dither n_tones -3");
    dither(1, 3e5, 2e-6, 0, "amplitude", 0, "dither absurd amplitude 2 um");
    dither(1, 3e5, -1e-10, 0, "amplitude", 0, "dither negative amplitude");
    dither(1, 0, 1e-10, 0, "frequency", 0, "dither frequency 0");
    dither(1, -5, 1e-10, 0, "frequency", 0, "dither negative frequency");
    dither(1, 7.03e6, 1e-10, 0, "half the sample rate", 0, "dither frequency at fs/2");
    /* issue 13: a frequency of 5e-324 Hz was accepted; four tones of 1 um each were, each
     * within its limit, their sum never bounded */
    dither(1, 5e-324, 1e-10, 0, "must be >= 1", 0, "dither frequency 5e-324 Hz");
    dither(1, 0.5, 1e-10, 0, "must be >= 1", 0, "dither frequency 0.5 Hz");
    {
        double f4[4] = {338112, 338112, 338112, 338112}, a4[4] = {1e-6, 1e-6, 1e-6, 1e-6},
               p4[4] = {0};
        afmtwin_dither_t m4 = {
            .n_tones = 4, .frequency_hz = f4, .amplitude_m = a4, .phase_rad = p4};
        buf_len = afmtwin_dither_t_encode(buf, 0, sizeof buf, &m4);
        expect(AFM_CMD_DITHER, 0, "add up to 4e-06 m", "dither 4 tones x 1 um (sum 4 um)");
        a4[0] = a4[1] = 0.5e-6;
        a4[2] = a4[3] = 0;
        buf_len = afmtwin_dither_t_encode(buf, 0, sizeof buf, &m4);
        expect(AFM_CMD_DITHER, 1, NULL, "dither 2 x 0.5 um (sum 1 um, no model)");
    }
    dither(1, 8e6, 1e-10, 0, "half the sample rate", 0, "dither frequency above fs/2");
    /* decoded values */
    double f[2] = {338112, 1e6}, a[2] = {1e-10, 2e-11}, p[2] = {0.5, 1.5};
    afmtwin_dither_t m = {
        .utime = 123, .seq = 42, .n_tones = 2, .frequency_hz = f, .amplitude_m = a, .phase_rad = p};
    buf_len = afmtwin_dither_t_encode(buf, 0, sizeof buf, &m);
    afm_cmd c;
    char err[AFM_ERR_LEN];
    check_true(afm_cmd_decode(AFM_CMD_DITHER, buf, (size_t)buf_len, &lim, &c, err, sizeof err) ==
                       0 &&
                   c.kind == AFM_CMD_DITHER && c.seq == 42 && c.utime == 123 &&
                   c.u.dither.n_tones == 2 && c.u.dither.frequency_hz[1] == 1e6 &&
                   c.u.dither.amplitude_m[1] == 2e-11 && c.u.dither.phase_rad[1] == 1.5,
               "dither values decoded exactly");
    /* without a sample rate only f > 0 is checked */
    c.u.dither.frequency_hz[0] = 9e6;
    check_true(afm_cmd_validate(&c, NULL, err, sizeof err) == 0,
               "dither 9 MHz valid without limits");
    check_true(afm_cmd_validate(&c, &lim, err, sizeof err) == -1,
               "dither 9 MHz invalid at 14.06 MHz");
}

/* The limits that need the model (afm_cmd_check_drive): default.conf's NCHV cantilever,
 * f1 = 338.1 kHz. Its predicted free amplitude at 0.087 nm is what the simulator reaches:
 * `afmtwin sweep --from 338112 --to 338112` on default.conf with separation_m = 1e-3 gives
 * a steady lock-in amplitude of 57.249 nm. */
static void test_model_limits(void) {
    afm_config cfg;
    afm_modal m;
    char err[AFM_ERR_LEN];
    if (afm_config_load("config/default.conf", &cfg, err, sizeof err) ||
        afm_model_build(&cfg.model, &m, err, sizeof err)) {
        check_true(false, err);
        return;
    }
    afm_cmd_limits ml = {.sample_rate_hz = 14.06e6, .model = &m};
    afm_cmd c = {.kind = AFM_CMD_DITHER,
                 .u.dither = {.n_tones = 1, .frequency_hz = {338112}, .amplitude_m = {0.087e-9}}};
    double free_m = 0;
    afm_cmd_check_drive(&m, 1, c.u.dither.frequency_hz, c.u.dither.amplitude_m, &free_m, err,
                        sizeof err);
    printf("  0.087 nm at 338.112 kHz: predicted free amplitude %.5g nm\n", free_m * 1e9);
    check_rel(free_m, 57.249e-9, 0.005, "predicted free amplitude = the simulated 57.249 nm");
    check_true(afm_cmd_validate(&c, &ml, err, sizeof err) == 0,
               "tapping drive valid with the model");
    c.u.dither.amplitude_m[0] = 1e-6; /* at resonance: ~0.66 mm free, past 100 um */
    check_true(afm_cmd_validate(&c, &ml, err, sizeof err) == -1 && strstr(err, "free tip"),
               "1 um at resonance: the predicted free amplitude (~0.66 mm) rejected");
    check_true(afm_cmd_validate(&c, &lim, err, sizeof err) == 0,
               "... accepted without a model (only the model knows the gain)");
    c.u.dither.amplitude_m[0] = 1e-10;
    c.u.dither.frequency_hz[0] = 6.9e6; /* below Nyquist and 4 x the top mode (21 MHz) */
    check_true(afm_cmd_validate(&c, &ml, err, sizeof err) == 0,
               "6.9 MHz valid on a model whose top mode is 21 MHz");
    /* the lumped 300 kHz model of thesis-1dof.conf: 4 x 300 kHz = 1.2 MHz */
    afm_config l1;
    afm_modal m1;
    if (afm_config_load("config/thesis-1dof.conf", &l1, err, sizeof err) ||
        afm_model_build(&l1.model, &m1, err, sizeof err)) {
        check_true(false, err);
        return;
    }
    ml.model = &m1;
    c.u.dither.frequency_hz[0] = 2e6;
    char name[AFM_ERR_LEN + 100];
    int rc = afm_cmd_validate(&c, &ml, err, sizeof err);
    snprintf(name, sizeof name, "2 MHz on a 300 kHz lumped model: rejected (%s)", err);
    check_true(rc == -1 && strstr(err, "model's range"), name);
    c.u.dither.frequency_hz[0] = 1.1e6;
    check_true(afm_cmd_validate(&c, &ml, err, sizeof err) == 0, "1.1 MHz on it: valid");
}

static void test_setpoint(void) {
    setpoint(40e-9, 0, NULL, 1, "setpoint step");
    setpoint(40e-9, 1e-6, NULL, 1, "setpoint ramp");
    setpoint(0, 0, NULL, 1, "setpoint Z = 0");
    setpoint(-1e-9, 0, "separation", 0, "setpoint negative Z");
    setpoint(2e-3, 0, "separation", 0, "setpoint Z 2 mm");
    setpoint(NAN, 0, "non-finite", 0, "setpoint NaN Z");
    setpoint(-INFINITY, 0, "non-finite", 0, "setpoint -inf Z");
    setpoint(40e-9, -1, "ramp", 0, "setpoint negative ramp");
    setpoint(40e-9, NAN, "non-finite", 0, "setpoint NaN ramp");
    setpoint(40e-9, 10, "ramp", 0, "setpoint ramp 10 m/s");
}

static void test_param(void) {
    const char *n1[] = {"forces.vdw_contact.hamaker_j"};
    const char *n2[] = {"model.damping_ratio[0]", "model.beam.length_m"};
    const char *n3[] = {"forces.viscoelastic.eta_pa_s", "forces.viscoelastic.eta_pa_s"};
    double v1[] = {1e-19}, v2[] = {0.002, 120e-6};
    param(1, n1, v1, NULL, 1, "param hamaker");
    param(2, n2, v2, NULL, 1, "param damping and length");
    const char *bad[] = {"forces.nope"};
    param(1, bad, v1, "unknown parameter 'forces.nope'", 0, "param unknown name");
    const char *idx1[] = {"model.damping_ratio[99]"};
    param(1, idx1, (double[]){0.01}, "index 99 out of range", 0, "param index out of range");
    const char *idx2[] = {"forces.radius_m[0]"};
    param(1, idx2, (double[]){1e-8}, "takes no index", 0, "param index on a scalar");
    const char *idx3[] = {"model.damping_ratio"};
    param(1, idx3, (double[]){0.01}, "needs an index", 0, "param array without index");
    const char *idx4[] = {"model.damping_ratio[x]"};
    param(1, idx4, (double[]){0.01}, "bad index", 0, "param malformed index");
    const char *idx5[] = {"model.damping_ratio[1]]"};
    param(1, idx5, (double[]){0.01}, "bad index", 0, "param trailing bracket");
    const char *empty[] = {""};
    param(1, empty, v1, "empty", 0, "param empty name");
    param(2, n3, (double[]){100, 200}, "given twice", 0, "param same name twice");
    param(1, n1, (double[]){NAN}, "not a finite", 0, "param NaN value");
    param(1, n1, (double[]){1e-10}, "out of range", 0, "param hamaker 1e-10 J");
    const char *dmp[] = {"model.damping_ratio[0]"};
    param(1, dmp, (double[]){1.5}, "out of range", 0, "param damping 1.5");
    param(1, dmp, (double[]){0.0}, "out of range", 0, "param damping 0");
    const char *names16[17];
    double vals16[17];
    for (int i = 0; i < 17; i++) {
        names16[i] = "forces.radius_m";
        vals16[i] = 1e-8;
    }
    param(17, names16, vals16, "not in 1..16", 0, "param 17 names");
    param(0, names16, vals16, "not in 1..16", 0, "param 0 names");
    char longname[200];
    memset(longname, 'a', sizeof longname - 1);
    longname[sizeof longname - 1] = 0;
    const char *ln[] = {longname};
    param(1, ln, v1, "too long", 0, "param 199-character name");
    /* a string without its terminator (crafted: length 4, bytes "abcd") */
    const char *ok1[] = {"abc"};
    afmtwin_param_t m = {.seq = 1, .n = 1, .name = (char **)ok1, .value = v1};
    buf_len = afmtwin_param_t_encode(buf, 0, sizeof buf, &m);
    /* layout: 8 hash, 8 utime, 8 seq, 2 n, 4 len, "abc\0", 8 value */
    buf[26 + 4 + 3] = 'd';
    expect(AFM_CMD_PARAM, 0, "not a proper string", "param name without NUL");
    buf_len = afmtwin_param_t_encode(buf, 0, sizeof buf, &m);
    buf[26] = 0x7f; /* length 2 GB */
    expect(AFM_CMD_PARAM, 0, "bad length", "param name length 2 GB");
}

static void test_control_tick(void) {
    control(AFMTWIN_CONTROL_T_RUN, 0, NULL, 1, "control run");
    control(AFMTWIN_CONTROL_T_PAUSE, 0, NULL, 1, "control pause");
    control(AFMTWIN_CONTROL_T_RESET, 0, NULL, 1, "control reset");
    control(AFMTWIN_CONTROL_T_STEP, 1000, NULL, 1, "control step 1000");
    control(0, 0, "unknown action", 0, "control action 0");
    control(9, 0, "unknown action", 0, "control action 9");
    control(AFMTWIN_CONTROL_T_STEP, 0, "n_samples", 0, "control step 0");
    control(AFMTWIN_CONTROL_T_STEP, -5, "n_samples", 0, "control step -5");
    control(AFMTWIN_CONTROL_T_STEP, 2000000000LL, "n_samples", 0, "control step 2e9");
    tick(1, NULL, 1, "tick 1");
    tick(0, "n_samples", 0, "tick 0");
    tick(-1, "n_samples", 0, "tick -1");
    tick(1000000001LL, "n_samples", 0, "tick 1e9 + 1");
}

static void test_malformed(void) {
    afmtwin_setpoint_t sp = {.seq = 1, .separation_m = 40e-9};
    int full = afmtwin_setpoint_t_encode(buf, 0, sizeof buf, &sp);
    buf_len = full;
    expect(AFM_CMD_DITHER, 0, "wrong message type", "setpoint bytes on the dither channel");
    expect(AFM_CMD_PARAM, 0, "wrong message type", "setpoint bytes on the param channel");
    buf_len = full - 3;
    expect(AFM_CMD_SETPOINT, 0, "truncated", "setpoint truncated by 3 bytes");
    buf_len = 5;
    expect(AFM_CMD_SETPOINT, 0, "truncated", "5 bytes (no fingerprint)");
    buf_len = 0;
    expect(AFM_CMD_TICK, 0, "truncated", "empty message");
    buf_len = full + 4;
    expect(AFM_CMD_SETPOINT, 0, "trailing", "setpoint with 4 trailing bytes");
    double f[1] = {3e5}, a[1] = {1e-10}, p[1] = {0};
    afmtwin_dither_t d = {
        .seq = 1, .n_tones = 1, .frequency_hz = f, .amplitude_m = a, .phase_rad = p};
    full = afmtwin_dither_t_encode(buf, 0, sizeof buf, &d);
    buf_len = full - 8;
    expect(AFM_CMD_DITHER, 0, "truncated", "dither missing its phase");
    buf_len = full;
    buf[24] = 100; /* n_tones 100: arrays run past the end */
    expect(AFM_CMD_DITHER, 0, NULL, "dither n_tones 100 in a 1-tone body");
    const char *nm[] = {"forces.radius_m", "drive.separation_m"};
    afmtwin_param_t pm = {.seq = 1, .n = 2, .name = (char **)nm, .value = (double[]){1e-8, 4e-8}};
    full = afmtwin_param_t_encode(buf, 0, sizeof buf, &pm);
    for (int cut = 9; cut < full; cut += 7) { /* every truncation: rejected, nothing leaks */
        buf_len = cut;
        afm_cmd c;
        char err[AFM_ERR_LEN];
        if (afm_cmd_decode(AFM_CMD_PARAM, buf, (size_t)cut, &lim, &c, err, sizeof err) != -1) {
            check_true(false, "param truncated: rejected");
            return;
        }
    }
    check_true(true, "param truncated at every 7th byte: all rejected");
    srand(1);
    int accepted_garbage = 0;
    for (int trial = 0; trial < 2000; trial++) { /* random bytes after a valid fingerprint */
        buf_len = 8 + rand() % 200;
        afmtwin_param_t_encode(buf, 0, sizeof buf, &pm);
        for (int i = 8; i < buf_len; i++)
            buf[i] = (unsigned char)rand();
        afm_cmd c;
        char err[AFM_ERR_LEN];
        for (int k = AFM_CMD_DITHER; k <= AFM_CMD_TICK; k++)
            if (afm_cmd_decode((afm_cmd_kind)k, buf, (size_t)buf_len, &lim, &c, err, sizeof err) ==
                0)
                accepted_garbage++;
    }
    check_true(accepted_garbage == 0, "2000 random bodies x 5 kinds: none accepted, no crash");
}

static void test_apply(void) {
    afm_config cfg, before;
    char err[AFM_ERR_LEN];
    if (afm_config_load("config/default.conf", &cfg, err, sizeof err)) {
        check_true(false, err);
        return;
    }
    before = cfg;
    afm_cmd c;
    const char *names[] = {"forces.vdw_contact.hamaker_j", "model.damping_ratio[4]"};
    afmtwin_param_t pm = {
        .seq = 1, .n = 2, .name = (char **)names, .value = (double[]){2e-19, 0.05}};
    buf_len = afmtwin_param_t_encode(buf, 0, sizeof buf, &pm);
    check_true(afm_cmd_decode(AFM_CMD_PARAM, buf, (size_t)buf_len, &lim, &c, err, sizeof err) == 0,
               "param decoded");
    afm_param_effect e;
    check_true(afm_param_apply(&cfg, &c.u.param, &e, err, sizeof err) == 0 &&
                   cfg.forces.hamaker_j == 2e-19 && cfg.model.damping_ratio[4] == 0.05 &&
                   e == AFM_PARAM_DAMPING,
               "apply hamaker + damping[4]: both set, effect DAMPING");
    check_true(afm_param_get(&cfg, c.u.param.entry[1], 4) == 0.05, "afm_param_get reads it back");
    /* damping past the list materialises the last value for the modes in between */
    cfg = before;
    int ent, idx;
    afm_param_lookup("model.quality_factor[1]", &ent, &idx, err, sizeof err);
    afm_cmd_param p = {.n = 1, .entry = {ent}, .index = {idx}, .value = {1000}};
    check_true(afm_param_apply(&cfg, &p, &e, err, sizeof err) == 0 &&
                   cfg.model.damping_ratio[1] == 1.0 / 2000,
               "quality_factor[1] = 1000 -> damping_ratio[1] = 5e-4");
    /* index past the model's modes (kept_modes 3 -> 5 modes) */
    cfg = before;
    afm_param_lookup("model.damping_ratio[5]", &ent, &idx, err, sizeof err);
    p = (afm_cmd_param){.n = 1, .entry = {ent}, .index = {idx}, .value = {0.01}};
    check_true(afm_param_apply(&cfg, &p, &e, err, sizeof err) == -1 && strstr(err, "5 modes") &&
                   !memcmp(&cfg, &before, sizeof cfg),
               "damping_ratio[5] on a 5-mode model: rejected, config unchanged");
    /* a term that is off */
    afm_param_lookup("forces.capillary.surface_energy_j_m2", &ent, &idx, err, sizeof err);
    p = (afm_cmd_param){.n = 1, .entry = {ent}, .index = {idx}, .value = {0.07}};
    check_true(afm_param_apply(&cfg, &p, &e, err, sizeof err) == -1 && strstr(err, "capillary") &&
                   !memcmp(&cfg, &before, sizeof cfg),
               "capillary parameter while capillary is off: rejected, config unchanged");
    afm_param_lookup("model.lumped.stiffness_n_m", &ent, &idx, err, sizeof err);
    p = (afm_cmd_param){.n = 1, .entry = {ent}, .index = {idx}, .value = {40}};
    check_true(afm_param_apply(&cfg, &p, &e, err, sizeof err) == -1 && strstr(err, "lumped") &&
                   !memcmp(&cfg, &before, sizeof cfg),
               "lumped parameter on a beam model: rejected, config unchanged");
    /* one good and one bad name: nothing applied */
    int e1, i1, e2, i2;
    afm_param_lookup("forces.radius_m", &e1, &i1, err, sizeof err);
    afm_param_lookup("forces.squeeze.kappa", &e2, &i2, err, sizeof err);
    p = (afm_cmd_param){.n = 2, .entry = {e1, e2}, .index = {i1, i2}, .value = {9e-9, 0.5}};
    check_true(afm_param_apply(&cfg, &p, &e, err, sizeof err) == -1 && strstr(err, "starr") &&
                   !memcmp(&cfg, &before, sizeof cfg),
               "radius ok + Starr kappa on a linear squeeze: all rejected, config unchanged");
    afm_param_lookup("model.beam.height_m", &e1, &i1, err, sizeof err);
    p = (afm_cmd_param){.n = 1, .entry = {e1}, .index = {i1}, .value = {3e-6}};
    check_true(afm_param_apply(&cfg, &p, &e, err, sizeof err) == 0 && e == AFM_PARAM_GEOMETRY &&
                   cfg.model.beam.height_m[0] == 3e-6 && cfg.model.beam.height_m[1] == 3e-6,
               "model.beam.height_m (no index) sets both ends, effect GEOMETRY");
    int n;
    const afm_param_def *t = afm_param_table(&n);
    printf("  %d parameter names, e.g. %s, %s\n", n, t[0].name, t[n - 1].name);
    check_true(n >= 20, "parameter table has the force, damping and geometry names");
}

int main(void) {
    test_dither();
    test_model_limits();
    test_setpoint();
    test_param();
    test_control_tick();
    test_scan_encode();
    test_malformed();
    test_apply();
    return check_done();
}
