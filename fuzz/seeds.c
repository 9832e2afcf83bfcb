/* SPDX-License-Identifier: MIT */
/* seeds.c -- writes the seed corpora of the fuzz harnesses (fuzz_*.c) into DIR/<harness>/:
 * the valid messages, frames and logs the unit tests use (tests/test_cmd.c, test_wire.c,
 * test_can_codec.c) and the crafted inputs of issue 13, in each harness's input format.
 * The config harness's seeds are the files of config/ and tests/bad-configs/ (tests/fuzz.sh
 * copies them). Usage: seeds DIR. */
#include "transport/afm_can_codec.h"
#include "config/afm_config.h"
#include "transport/afm_lcm_wire.h"
#include "../tests/msg_examples.h"
#include "afmtwin_control_t.h"
#include "afmtwin_dither_t.h"
#include "afmtwin_harmonics_t.h"
#include "afmtwin_param_t.h"
#include "afmtwin_samples_t.h"
#include "afmtwin_setpoint_t.h"
#include "afmtwin_status_t.h"
#include "afmtwin_tick_t.h"

#include <lcm/eventlog.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static const char *dir;
static int written;

static void put(const char *harness, const char *name, const void *a, size_t na, const void *b,
                size_t nb) {
    char path[600];
    snprintf(path, sizeof path, "%s/%s", dir, harness);
    mkdir(path, 0755);
    snprintf(path, sizeof path, "%s/%s/%s", dir, harness, name);
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(a, 1, na, f) != na || (nb && fwrite(b, 1, nb, f) != nb)) {
        fprintf(stderr, "seeds: cannot write %s\n", path);
        exit(1);
    }
    fclose(f);
    written++;
}

static uint8_t buf[65536];

/* A command seed (fuzz_cmd: kind byte, then the body) and the same as a fuzz_out seed. */
static void cmd_seed(afm_cmd_kind kind, const char *name, int len) {
    uint8_t k = (uint8_t)(kind - 1), km = k | 0x80;
    char n2[80];
    put("cmd", name, &k, 1, buf, (size_t)len);
    snprintf(n2, sizeof n2, "%s-model", name);
    put("cmd", n2, &km, 1, buf, (size_t)len);
}

static void out_seed(const afm_wire_type *t, const char *name, int len) {
    uint8_t i = 0;
    while (afm_wire_all[i] && afm_wire_all[i] != t)
        i++;
    put("out", name, &i, 1, buf, (size_t)len);
}

static void commands(void) {
    int n = ex_dither(buf, sizeof buf, 1);
    cmd_seed(AFM_CMD_DITHER, "dither-1", n);
    out_seed(&afm_wire_dither_t, "dither-1", n);
    n = ex_dither(buf, sizeof buf, 4);
    cmd_seed(AFM_CMD_DITHER, "dither-4", n);
    n = ex_dither(buf, sizeof buf, 1);
    buf[EX_DITHER_N_TONES_AT] = 127; /* issue 13: the 33-byte dither that leaked */
    cmd_seed(AFM_CMD_DITHER, "dither-leak-33", 33);
    buf[EX_DITHER_N_TONES_AT] = 0xfd; /* n_tones -3 */
    cmd_seed(AFM_CMD_DITHER, "dither-n-3", n);
    n = ex_param(buf, sizeof buf);
    cmd_seed(AFM_CMD_PARAM, "param-2", n);
    afmtwin_setpoint_t sp = {.utime = 1, .seq = 8, .separation_m = 40e-9, .ramp_rate_m_s = 1e-6};
    n = afmtwin_setpoint_t_encode(buf, 0, sizeof buf, &sp);
    cmd_seed(AFM_CMD_SETPOINT, "setpoint-ramp", n);
    out_seed(&afm_wire_setpoint_t, "setpoint", n);
    const char *names[3] = {"forces.vdw_contact.hamaker_j", "model.damping_ratio[0]",
                            "model.beam.length_m"};
    double v[3] = {1e-19, 0.002, 120e-6};
    afmtwin_param_t pm = {.utime = 1, .seq = 9, .n = 3, .name = (char **)names, .value = v};
    n = afmtwin_param_t_encode(buf, 0, sizeof buf, &pm);
    cmd_seed(AFM_CMD_PARAM, "param-3", n);
    out_seed(&afm_wire_param_t, "param-3", n);
    for (int act = 1; act <= 4; act++) {
        afmtwin_control_t c = {.utime = 1, .seq = 10, .action = (int8_t)act, .n_samples = 1000};
        n = afmtwin_control_t_encode(buf, 0, sizeof buf, &c);
        char nm[32];
        snprintf(nm, sizeof nm, "control-%d", act);
        cmd_seed(AFM_CMD_CONTROL, nm, n);
        if (act == 4) out_seed(&afm_wire_control_t, nm, n);
    }
    afmtwin_tick_t tk = {.utime = 1, .seq = 11, .n_samples = 14060};
    n = afmtwin_tick_t_encode(buf, 0, sizeof buf, &tk);
    cmd_seed(AFM_CMD_TICK, "tick", n);
    out_seed(&afm_wire_tick_t, "tick", n);
}

static void outputs(void) {
    int n = ex_samples(buf, sizeof buf);
    out_seed(&afm_wire_samples_t, "samples-3", n);
    buf[EX_SAMPLES_N_AT] = 0x40; /* issue 13: n = 0x40000003 */
    out_seed(&afm_wire_samples_t, "samples-n-huge", n);
    n = ex_harmonics(buf, sizeof buf);
    out_seed(&afm_wire_harmonics_t, "harmonics-2", n);
    n = ex_status(buf, sizeof buf, "dither: truncated");
    out_seed(&afm_wire_status_t, "status", n);
    memset(buf + EX_STATUS_REJECT_AT, 0xff, 4); /* issue 13: string length 0xffffffff */
    out_seed(&afm_wire_status_t, "status-strlen", n);
}

static void can_frames(void) {
    afm_config cfg;
    afm_config_defaults(&cfg);
    cfg.can.enabled = true;
    struct {
        afm_can_signal sig;
        int tone;
        double v0, v1;
    } sigs[] = {{AFM_CAN_DITHER_FREQUENCY, 0, 338112, 0},
                {AFM_CAN_DITHER_AMPLITUDE, 0, 0.1e-9, 0},
                {AFM_CAN_DITHER_PHASE, 1, 0.5, 0},
                {AFM_CAN_SETPOINT, 0, 30e-9, 1e-6},
                {AFM_CAN_ENABLE, 0, 1, 0},
                {AFM_CAN_HEARTBEAT, 0, 5, 0}};
    for (int mapi = 0; mapi < 3; mapi++) {
        afm_cfg_can m = cfg.can;
        if (mapi == 1) {
            m.encoding = AFM_CAN_FLOAT32;
            m.big_endian = true;
        } else if (mapi == 2) {
            m.extended_ids = true;
            m.id[AFM_CAN_DITHER_FREQUENCY] = 0x18FF0100;
        }
        for (size_t i = 0; i < sizeof sigs / sizeof sigs[0]; i++) {
            struct canfd_frame f;
            char err[AFM_ERR_LEN];
            if (afm_can_encode(&m, sigs[i].sig, sigs[i].tone, sigs[i].v0, sigs[i].v1, &f, err,
                               sizeof err))
                continue;
            uint8_t hdr[8] = {(uint8_t)mapi, 4};
            memcpy(hdr + 2, &f.can_id, 4);
            hdr[6] = f.len;
            hdr[7] = f.flags;
            char nm[40];
            snprintf(nm, sizeof nm, "map%d-%s", mapi, afm_can_signal_name(sigs[i].sig));
            put("can", nm, hdr, 8, f.data, f.len);
        }
    }
}

static void logs(void) {
    char path[600];
    snprintf(path, sizeof path, "%s/log", dir);
    mkdir(path, 0755);
    snprintf(path, sizeof path, "%s/log/three-events", dir);
    remove(path);
    lcm_eventlog_t *l = lcm_eventlog_create(path, "w");
    if (!l) {
        fprintf(stderr, "seeds: cannot write %s\n", path);
        exit(1);
    }
    afmtwin_setpoint_t sp = {.seq = 2, .separation_m = 40e-9};
    int n1 = ex_dither(buf, sizeof buf, 1);
    lcm_eventlog_event_t ev = {
        .timestamp = 0, .channellen = 14, .datalen = n1, .channel = "AFMTWIN_DITHER", .data = buf};
    lcm_eventlog_write_event(l, &ev);
    int n2 = afmtwin_setpoint_t_encode(buf, 0, sizeof buf, &sp);
    ev = (lcm_eventlog_event_t){.timestamp = 1000,
                                .channellen = 16,
                                .datalen = n2,
                                .channel = "AFMTWIN_SETPOINT",
                                .data = buf};
    lcm_eventlog_write_event(l, &ev);
    ev = (lcm_eventlog_event_t){
        .timestamp = 2000, .channellen = 1, .datalen = 0, .channel = "X", .data = buf};
    lcm_eventlog_write_event(l, &ev);
    lcm_eventlog_destroy(l);
    written++;
    /* issue 13: an event announcing 0x7fffffff data bytes */
    uint8_t ev7[28 + 1] = {0xED, 0xA1, 0xDA, 0x01};
    ev7[23] = 1;
    ev7[24] = 0x7f;
    ev7[25] = ev7[26] = ev7[27] = 0xff;
    ev7[28] = 'X';
    put("log", "datalen-7fffffff", ev7, sizeof ev7, NULL, 0);
}

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: seeds DIR\n");
        return 2;
    }
    dir = argv[1];
    mkdir(dir, 0755);
    commands();
    outputs();
    can_frames();
    logs();
    printf("seeds: %d files in %s\n", written, dir);
    return 0;
}
