/* SPDX-License-Identifier: MIT */
/* test_can_codec.c -- the CAN message map (afm_can_codec.h): every signal encoded and
 * decoded with the default map (scaled, little-endian) and with float32 / big-endian /
 * 29-bit maps, and bad frames (unknown id, wrong length, out of range, NaN, remote, FD
 * on a classic map) rejected with nothing changed; the `can` config group's checks. */
#include "check.h"

#include "transport/afm_can_codec.h"
#include "config/afm_config.h"

#include <linux/can/error.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const afm_cmd_limits lim = {.sample_rate_hz = 14.06e6};

static afm_cfg_can default_map(void) {
    afm_config c;
    afm_config_defaults(&c);
    c.can.enabled = true;
    return c.can;
}

static afm_can_state start_state(void) {
    afm_cfg_drive d = {.separation_m = 30e-9, .n_tones = 1};
    d.tones[0] = (afm_cfg_tone){.amplitude_m = 0.087e-9, .frequency_hz = 338112.0};
    afm_can_state s;
    afm_can_state_init(&s, &d);
    return s;
}

/* Decode f; returns the result and fills cmd/next. */
static afm_can_result dec(const afm_cfg_can *m, const afm_can_state *s, const struct canfd_frame *f,
                          bool fd, afm_cmd *cmd, afm_can_state *next, char *err) {
    return afm_can_decode(m, s, f, fd, &lim, cmd, next, NULL, err, AFM_ERR_LEN);
}

static void test_round_trips(const afm_cfg_can *m, const char *tag) {
    char what[160], err[AFM_ERR_LEN];
    struct canfd_frame f;
    afm_cmd c;
    afm_can_state s = start_state(), n;
    /* Quantisation: half a bit of the scale (scaled) or float32's 2^-24 relative. */
    bool flt = m->encoding == AFM_CAN_FLOAT32;

    check_true(afm_can_encode(m, AFM_CAN_DITHER_FREQUENCY, 0, 300123.45, 0, &f, err, sizeof err) ==
                       0 &&
                   f.len == 8 && f.data[0] == 0,
               "encode dither_frequency");
    snprintf(what, sizeof what, "%s: dither_frequency -> dither command", tag);
    check_true(dec(m, &s, &f, false, &c, &n, err) == AFM_CAN_R_COMMAND && c.kind == AFM_CMD_DITHER,
               what);
    snprintf(what, sizeof what, "%s: frequency tone 0", tag);
    check_abs(c.u.dither.frequency_hz[0], 300123.45, flt ? 300123.45 * 6e-8 : 0.005, what);
    snprintf(what, sizeof what, "%s: amplitude of tone 0 kept from the registers", tag);
    check_rel(c.u.dither.amplitude_m[0], 0.087e-9, 1e-15, what);
    check_true(c.u.dither.n_tones == 1, "one tone");
    s = n;

    afm_can_encode(m, AFM_CAN_DITHER_AMPLITUDE, 0, 12.5e-9, 0, &f, err, sizeof err);
    snprintf(what, sizeof what, "%s: dither_amplitude -> dither command", tag);
    check_true(dec(m, &s, &f, false, &c, &n, err) == AFM_CAN_R_COMMAND, what);
    snprintf(what, sizeof what, "%s: amplitude tone 0", tag);
    check_abs(c.u.dither.amplitude_m[0], 12.5e-9, flt ? 12.5e-9 * 6e-8 : 0.5e-15, what);
    snprintf(what, sizeof what, "%s: frequency of tone 0 kept", tag);
    check_abs(c.u.dither.frequency_hz[0], 300123.45, flt ? 0.02 : 0.005, what);
    s = n;

    /* A second tone: its start phase first (stored), then frequency, then amplitude. */
    afm_can_encode(m, AFM_CAN_DITHER_PHASE, 1, -1.25, 0, &f, err, sizeof err);
    snprintf(what, sizeof what, "%s: dither_phase of a tone not running -> stored", tag);
    check_true(dec(m, &s, &f, false, &c, &n, err) == AFM_CAN_R_STORED, what);
    check_abs(n.dither.phase_rad[1], -1.25, flt ? 1e-7 : 0.5e-6, "stored phase of tone 1");
    s = n;
    afm_can_encode(m, AFM_CAN_DITHER_FREQUENCY, 1, 2.1e6, 0, &f, err, sizeof err);
    check_true(dec(m, &s, &f, false, &c, &n, err) == AFM_CAN_R_COMMAND && c.u.dither.n_tones == 2,
               "tone 1 frequency starts tone 1 (2 tones)");
    check_abs(c.u.dither.phase_rad[1], -1.25, flt ? 1e-7 : 0.5e-6, "tone 1 starts at the phase");
    s = n;
    afm_can_encode(m, AFM_CAN_DITHER_PHASE, 1, 0.5, 0, &f, err, sizeof err);
    check_true(dec(m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT &&
                   strstr(err, "phase-continuous"),
               "phase of a running tone rejected (phase-continuous drive)");

    afm_can_encode(m, AFM_CAN_SETPOINT, 0, 25.5e-9, 2e-6, &f, err, sizeof err);
    snprintf(what, sizeof what, "%s: setpoint -> setpoint command", tag);
    check_true(dec(m, &s, &f, false, &c, &n, err) == AFM_CAN_R_COMMAND &&
                   c.kind == AFM_CMD_SETPOINT,
               what);
    check_abs(c.u.setpoint.separation_m, 25.5e-9, flt ? 25.5e-9 * 6e-8 : 0.5e-12, "separation");
    check_abs(c.u.setpoint.ramp_rate_m_s, 2e-6, flt ? 2e-6 * 6e-8 : 0.5e-9, "ramp rate");

    afm_can_encode(m, AFM_CAN_ENABLE, 0, 0, 0, &f, err, sizeof err);
    check_true(f.len == 1 && dec(m, &s, &f, false, &c, &n, err) == AFM_CAN_R_COMMAND &&
                   c.kind == AFM_CMD_CONTROL && c.u.control.action == AFM_CTL_PAUSE,
               "enable 0 -> control pause");
    afm_can_encode(m, AFM_CAN_ENABLE, 0, 1, 0, &f, err, sizeof err);
    check_true(dec(m, &s, &f, false, &c, &n, err) == AFM_CAN_R_COMMAND &&
                   c.u.control.action == AFM_CTL_RUN,
               "enable 1 -> control run");
    afm_can_encode(m, AFM_CAN_HEARTBEAT, 0, 5, 0, &f, err, sizeof err);
    int hb = -1;
    check_true(afm_can_decode(m, &s, &f, false, &lim, &c, &n, &hb, err, sizeof err) ==
                       AFM_CAN_R_HEARTBEAT &&
                   hb == 5,
               "heartbeat decoded with its state byte");
}

static void test_bad_frames(void) {
    afm_cfg_can m = default_map();
    afm_can_state s = start_state(), n, before = s;
    afm_cmd c;
    char err[AFM_ERR_LEN];
    struct canfd_frame f;
    memset(&n, 0x5a, sizeof n);

    memset(&f, 0, sizeof f);
    f.can_id = 0x123;
    f.len = 8;
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT &&
                   strstr(err, "unknown frame id") && strstr(err, "0x123"),
               "unknown id rejected, named");
    printf("  reason: %s\n", err);
    f.can_id = 0x200 | CAN_EFF_FLAG;
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT && strstr(err, "29-bit"),
               "29-bit frame on an 11-bit map rejected");

    afm_can_encode(&m, AFM_CAN_DITHER_FREQUENCY, 0, 300e3, 0, &f, err, sizeof err);
    f.len = 5;
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT &&
                   strstr(err, "length 5, want 8"),
               "wrong length rejected");
    printf("  reason: %s\n", err);
    afm_can_encode(&m, AFM_CAN_ENABLE, 0, 1, 0, &f, err, sizeof err);
    f.len = 2;
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT, "enable of length 2");
    afm_can_encode(&m, AFM_CAN_HEARTBEAT, 0, 1, 0, &f, err, sizeof err);
    f.len = 0;
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT, "empty heartbeat");

    /* out of range: Nyquist of 14.06 MHz is 7.03 MHz */
    afm_can_encode(&m, AFM_CAN_DITHER_FREQUENCY, 0, 8e6, 0, &f, err, sizeof err);
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT &&
                   strstr(err, "half the sample rate"),
               "frequency above Nyquist rejected (afm_cmd_validate's reason)");
    printf("  reason: %s\n", err);
    afm_can_encode(&m, AFM_CAN_DITHER_FREQUENCY, 0, 0, 0, &f, err, sizeof err);
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT, "frequency 0 rejected");
    afm_can_encode(&m, AFM_CAN_DITHER_AMPLITUDE, 0, 2e-6, 0, &f, err, sizeof err);
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT && strstr(err, "amplitude"),
               "amplitude 2 um rejected");
    afm_can_encode(&m, AFM_CAN_DITHER_AMPLITUDE, 2, 1e-9, 0, &f, err, sizeof err);
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT &&
                   strstr(err, "no frequency"),
               "amplitude for a tone with no frequency rejected");
    afm_can_encode(&m, AFM_CAN_DITHER_FREQUENCY, 0, 300e3, 0, &f, err, sizeof err);
    f.data[0] = 4;
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT && strstr(err, "tone 4"),
               "tone 4 rejected");
    afm_can_encode(&m, AFM_CAN_DITHER_PHASE, 1, 0, 0, &f, err, sizeof err);
    f.data[4] = 0xff, f.data[5] = 0xff, f.data[6] = 0xff, f.data[7] = 0x7f; /* +2147 rad */
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT && strstr(err, "2 pi"),
               "phase beyond 2 pi rejected");
    afm_can_encode(&m, AFM_CAN_SETPOINT, 0, 2e-3, 0, &f, err, sizeof err);
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT &&
                   strstr(err, "separation_m"),
               "separation 2 mm rejected");
    afm_can_encode(&m, AFM_CAN_SETPOINT, 0, 20e-9, 1.5, &f, err, sizeof err);
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT && strstr(err, "ramp_rate"),
               "ramp 1.5 m/s rejected");
    afm_can_encode(&m, AFM_CAN_ENABLE, 0, 1, 0, &f, err, sizeof err);
    f.data[0] = 2;
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT, "enable byte 2 rejected");
    afm_can_encode(&m, AFM_CAN_SETPOINT, 0, 20e-9, 0, &f, err, sizeof err);
    f.can_id |= CAN_RTR_FLAG;
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT && strstr(err, "remote"),
               "remote frame rejected");
    f.can_id &= ~CAN_RTR_FLAG;
    check_true(dec(&m, &s, &f, true, &c, &n, err) == AFM_CAN_R_REJECT && strstr(err, "FD"),
               "CAN FD frame on a classic map rejected");
    f.can_id = CAN_ERR_FLAG | CAN_ERR_BUSOFF;
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT,
               "error frame not a command");

    /* NaN with float32 encoding */
    afm_cfg_can mf = m;
    mf.encoding = AFM_CAN_FLOAT32;
    afm_can_encode(&mf, AFM_CAN_SETPOINT, 0, 20e-9, 0, &f, err, sizeof err);
    float nanf = NAN;
    memcpy(f.data, &nanf, 4);
    check_true(dec(&mf, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT && strstr(err, "NaN"),
               "NaN separation rejected");
    printf("  reason: %s\n", err);
    afm_can_encode(&mf, AFM_CAN_DITHER_FREQUENCY, 0, 300e3, 0, &f, err, sizeof err);
    float inf = INFINITY;
    memcpy(f.data + 4, &inf, 4);
    check_true(dec(&mf, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT, "inf frequency rejected");
    afm_can_encode(&mf, AFM_CAN_DITHER_AMPLITUDE, 0, -1e-9, 0, &f, err, sizeof err);
    check_true(dec(&mf, &s, &f, false, &c, &n, err) == AFM_CAN_R_REJECT,
               "negative float amplitude rejected");

    check_true(memcmp(&s, &before, sizeof s) == 0, "registers unchanged by every rejection");

    /* encoder refuses what the signal cannot carry */
    check_true(afm_can_encode(&m, AFM_CAN_DITHER_AMPLITUDE, 0, -1e-9, 0, &f, err, sizeof err) < 0,
               "encode: negative amplitude does not fit a u32");
    check_true(afm_can_encode(&m, AFM_CAN_DITHER_FREQUENCY, 0, NAN, 0, &f, err, sizeof err) < 0,
               "encode: NaN refused");
    check_true(afm_can_encode(&m, AFM_CAN_DITHER_FREQUENCY, 7, 1e3, 0, &f, err, sizeof err) < 0,
               "encode: tone 7 refused");
    check_true(afm_can_encode(&m, AFM_CAN_ENABLE, 0, 3, 0, &f, err, sizeof err) < 0,
               "encode: enable 3 refused");
}

static void test_layout(void) {
    afm_cfg_can m = default_map();
    struct canfd_frame f;
    char err[AFM_ERR_LEN], txt[160];
    /* 338112 Hz = 33811200 * 0.01 Hz = 0x0203EB00, little-endian at bytes 4..7 */
    afm_can_encode(&m, AFM_CAN_DITHER_FREQUENCY, 0, 338112.0, 0, &f, err, sizeof err);
    afm_can_format(&f, false, txt, sizeof txt);
    check_true(strcmp(txt, "200#0000000000EB0302") == 0,
               "dither_frequency 338112 Hz = 200#0000000000EB0302");
    printf("  %s\n", txt);
    afm_cfg_can mb = m;
    mb.big_endian = true;
    afm_can_encode(&mb, AFM_CAN_DITHER_FREQUENCY, 0, 338112.0, 0, &f, err, sizeof err);
    afm_can_format(&f, false, txt, sizeof txt);
    check_true(strcmp(txt, "200#000000000203EB00") == 0, "big-endian: 200#000000000203EB00");
    /* 30 nm = 30000 pm = 0x7530 */
    afm_can_encode(&m, AFM_CAN_SETPOINT, 0, 30e-9, 0, &f, err, sizeof err);
    afm_can_format(&f, false, txt, sizeof txt);
    check_true(strcmp(txt, "210#3075000000000000") == 0, "setpoint 30 nm = 210#3075000000000000");
    afm_can_format(&f, true, txt, sizeof txt);
    check_true(strcmp(txt, "210##03075000000000000") == 0, "FD text form 210##0...");
    afm_cfg_can me = m;
    me.extended_ids = true;
    me.id[AFM_CAN_ENABLE] = 0x18FF0120;
    afm_can_encode(&me, AFM_CAN_ENABLE, 0, 1, 0, &f, err, sizeof err);
    afm_can_format(&f, false, txt, sizeof txt);
    check_true(strcmp(txt, "18FF0120#01") == 0, "29-bit enable = 18FF0120#01");
    afm_cmd c;
    afm_can_state s = start_state(), n;
    check_true(afm_can_decode(&me, &s, &f, false, &lim, &c, &n, NULL, err, sizeof err) ==
                   AFM_CAN_R_COMMAND,
               "29-bit enable decoded with a 29-bit map");
    /* CAN FD frames carry the same payloads when can.fd = true */
    afm_cfg_can mfd = m;
    mfd.fd = true;
    afm_can_encode(&mfd, AFM_CAN_SETPOINT, 0, 30e-9, 0, &f, err, sizeof err);
    check_true(afm_can_decode(&mfd, &s, &f, true, &lim, &c, &n, NULL, err, sizeof err) ==
                       AFM_CAN_R_COMMAND &&
                   fabs(c.u.setpoint.separation_m - 30e-9) < 1e-18,
               "CAN FD setpoint frame decoded with can.fd = true");
}

static int load_text(const char *text, afm_config *c, char *err) {
    char path[] = "/tmp/afm-can-cfg-XXXXXX";
    int fd = mkstemp(path);
    if (fd < 0) return -2;
    FILE *f = fdopen(fd, "w");
    fputs("model = { kind = \"lumped\"; lumped = { stiffness_n_m = 40.0; resonance_hz = 3.0e5; };"
          " quality_factor = [400.0]; };\n"
          "drive = { separation_m = 30e-9; tones = ( { amplitude_m = 1e-9; frequency_hz = 3.0e5; } "
          "); };\n",
          f);
    fputs(text, f);
    fclose(f);
    int rc = afm_config_load(path, c, err, AFM_ERR_LEN);
    unlink(path);
    return rc;
}

static void test_config(void) {
    afm_config c;
    char err[AFM_ERR_LEN];
    check_true(load_text("", &c, err) == 0 && !c.can.enabled, "no can group: CAN off");
    check_true(load_text("can = { interface = \"vcan0\"; };\n", &c, err) == 0 && c.can.enabled &&
                   strcmp(c.can.interface, "vcan0") == 0 && c.can.id[AFM_CAN_SETPOINT] == 0x210 &&
                   c.can.heartbeat_timeout_s == 0.5,
               "can group with the default map");
    check_true(load_text("can = { interface = \"can1\"; fd = true; byte_order = \"big\"; "
                         "encoding = \"float32\"; heartbeat_timeout_s = 0.2; "
                         "ids = { setpoint = 0x300; heartbeat = 0x77F; }; "
                         "scale = { separation_m = 1e-11; }; };\n",
                         &c, err) == 0 &&
                   c.can.fd && c.can.big_endian && c.can.encoding == AFM_CAN_FLOAT32 &&
                   c.can.id[AFM_CAN_SETPOINT] == 0x300 && c.can.scale_separation_m == 1e-11,
               "can group with every key");
    const struct {
        const char *text, *want;
    } bad[] = {
        {"can = { interface = \"vcan0\"; ids = { setpoint = 0x200; }; };\n", "also the id of"},
        {"can = { interface = \"vcan0\"; ids = { setpoint = 0x800; }; };\n", "11-bit"},
        {"can = { interface = \"vcan0\"; ids = { setpont = 0x210; }; };\n", "unknown key"},
        {"can = { interface = \"a/b\"; };\n", "interface name"},
        {"can = { interface = \"vcan0\"; byte_order = \"middle\"; };\n", "not one of"},
        {"can = { interface = \"vcan0\"; heartbeat_timeout_s = -1.0; };\n", "heartbeat_timeout_s"},
        {"can = { interface = \"vcan0\"; scale = { amplitude_m = 0.0; }; };\n", "per bit"},
        {"can = { interface = \"vcan0\"; reconnect_min_s = 2.0; reconnect_max_s = 1.0; };\n",
         "reconnect_max_s"},
        {"can = { interface = \"vcan0\"; fd = 1; };\n", "true or false"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char what[200];
        int rc = load_text(bad[i].text, &c, err);
        snprintf(what, sizeof what, "bad can config rejected: %s", bad[i].want);
        check_true(rc == -1 && strstr(err, bad[i].want) && strstr(err, "key 'can."), what);
        printf("  %s\n", err);
    }
}

/* issue 13: the transport's registers followed nothing but CAN. After an LCM dither that
 * started tone 1 at 1 MHz and changed tone 0's frequency, a CAN amplitude frame for tone 0
 * sent the whole dither from stale registers (tone 0 back at 338 kHz, tone 1 stopped).
 * afm_can_state_sync takes the running drive (the transport calls it when the daemon's
 * drive changed); start phases stored for tones not running stay the driver's. */
static void test_sync(void) {
    afm_cfg_can m = default_map();
    char err[AFM_ERR_LEN];
    struct canfd_frame f;
    afm_cmd c;
    afm_can_state s = start_state(), n;
    afm_can_encode(&m, AFM_CAN_DITHER_PHASE, 2, 0.5, 0, &f, err, sizeof err);
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_STORED, "phase of tone 2 stored");
    s = n;
    afm_cmd_dither lcm = {
        .n_tones = 2, .frequency_hz = {340000, 1e6}, .amplitude_m = {1e-10, 2e-11}};
    afm_can_state stale = s;
    afm_can_state_sync(&s, &lcm);
    afm_can_encode(&m, AFM_CAN_DITHER_AMPLITUDE, 0, 0.2e-9, 0, &f, err, sizeof err);
    check_true(dec(&m, &stale, &f, false, &c, &n, err) == AFM_CAN_R_COMMAND &&
                   c.u.dither.n_tones == 1 && c.u.dither.frequency_hz[0] == 338112.0,
               "unsynced registers: the frame would send tone 0 at 338 kHz and stop tone 1");
    check_true(dec(&m, &s, &f, false, &c, &n, err) == AFM_CAN_R_COMMAND &&
                   c.u.dither.n_tones == 2 && c.u.dither.frequency_hz[0] == 340000 &&
                   c.u.dither.frequency_hz[1] == 1e6 && c.u.dither.amplitude_m[1] == 2e-11 &&
                   fabs(c.u.dither.amplitude_m[0] - 0.2e-9) < 1e-15,
               "synced: tone 0's new amplitude, LCM's frequencies, tone 1 still running");
    check_true(s.dither.phase_rad[2] == n.dither.phase_rad[2] &&
                   fabs(s.dither.phase_rad[2] - 0.5) < 1e-6,
               "the start phase stored for tone 2 survives the sync");
}

int main(void) {
    afm_cfg_can m = default_map();
    test_sync();
    test_round_trips(&m, "scaled LE");
    afm_cfg_can mf = m;
    mf.encoding = AFM_CAN_FLOAT32;
    mf.big_endian = true;
    test_round_trips(&mf, "float32 BE");
    afm_cfg_can me = m;
    me.extended_ids = true;
    me.id[AFM_CAN_DITHER_FREQUENCY] = 0x18FF0100;
    test_round_trips(&me, "29-bit ids");
    test_bad_frames();
    test_layout();
    test_config();
    return check_done();
}
