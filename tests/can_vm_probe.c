/* SPDX-License-Identifier: MIT */
/* can_vm_probe.c -- the CAN transport against a real kernel CAN stack: run inside the VM of
 * tests/test_can_vm.sh (vcan0 up, root), statically linked with the engine. Frames sent on
 * vcan0 from a second raw socket go through afm_can_io into a twin (afm_runner, commands
 * applied as the daemon's RT thread applies them); checks that they change its dither,
 * setpoint and run state, that bad frames are rejected and counted with nothing changed,
 * and that a missing heartbeat, error frames (bus-off), the interface going down and being
 * deleted are reported, with reconnection and the last commands held.
 * usage: can_vm_probe CONFIG   (prints check lines and "N passed, N failed") */
#define _DEFAULT_SOURCE
#include "check.h"

#include "transport/afm_can_codec.h"
#include "transport/afm_io.h"
#include "runner/afm_runner.h"

#include <linux/can/error.h>
#include <net/if.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

typedef struct {
    afm_runner *r;
    double fs;
    int applied, refused, rejected;
} probe;

static int on_cmd(void *ctx, const afm_cmd *c) {
    probe *p = ctx;
    char err[AFM_ERR_LEN];
    if (afm_runner_apply(p->r, c, NULL, err, sizeof err)) {
        printf("  runner refused: %s\n", err);
        p->refused++;
        return -1;
    }
    p->applied++;
    return 0;
}

static void on_reject(void *ctx, const char *channel, const char *reason) {
    probe *p = ctx;
    p->rejected++;
    printf("  rejected on %s: %s\n", channel, reason);
}

static afm_cmd_limits limits(void *ctx) {
    probe *p = ctx;
    return (afm_cmd_limits){.sample_rate_hz = p->fs};
}

static int tx_open(void) {
    int s = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (s < 0) return -1;
    struct ifreq ifr;
    memset(&ifr, 0, sizeof ifr);
    snprintf(ifr.ifr_name, sizeof ifr.ifr_name, "vcan0");
    if (ioctl(s, SIOCGIFINDEX, &ifr) < 0) {
        close(s);
        return -1;
    }
    struct sockaddr_can a = {.can_family = AF_CAN, .can_ifindex = ifr.ifr_ifindex};
    if (bind(s, (struct sockaddr *)&a, sizeof a) < 0) {
        close(s);
        return -1;
    }
    return s;
}

static int tx(int s, const struct canfd_frame *f) {
    return write(s, f, CAN_MTU) == CAN_MTU ? 0 : -1;
}

static void send_sig(int s, const afm_cfg_can *m, afm_can_signal sig, int tone, double v0,
                     double v1) {
    struct canfd_frame f;
    char err[AFM_ERR_LEN], txt[160];
    if (afm_can_encode(m, sig, tone, v0, v1, &f, err, sizeof err)) {
        printf("  encode failed: %s\n", err);
        return;
    }
    afm_can_format(&f, false, txt, sizeof txt);
    printf("  send %s (%s)\n", txt, afm_can_signal_name(sig));
    if (tx(s, &f)) perror("  write");
}

static void pump(afm_io *io, double seconds) {
    struct timespec t0, t;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    do {
        io->ops->poll(io, 10);
        clock_gettime(CLOCK_MONOTONIC, &t);
    } while ((double)(t.tv_sec - t0.tv_sec) + 1e-9 * (double)(t.tv_nsec - t0.tv_nsec) < seconds);
}

static void status(afm_io *io, afm_io_status *st) {
    memset(st, 0, sizeof *st);
    io->ops->annotate_status(io, st);
    printf("  can_state '%s' frames %lld rejected %lld errors %lld reconnects %lld hb %d\n",
           st->can_state, (long long)st->can_frames, (long long)st->can_rejected,
           (long long)st->can_errors, (long long)st->can_reconnects, st->heartbeat_ok);
}

static int sh(const char *cmd) {
    printf("  $ %s\n", cmd);
    return system(cmd);
}

int main(int argc, char **argv) {
    static afm_config cfg;
    char err[AFM_ERR_LEN];
    if (argc < 2 || afm_config_load(argv[1], &cfg, err, sizeof err)) {
        printf("can_vm_probe: %s\n", argc < 2 ? "usage: can_vm_probe CONFIG" : err);
        return 2;
    }
    check_true(cfg.can.enabled && strcmp(cfg.can.interface, "vcan0") == 0,
               "config has a can group on vcan0");
    probe p = {.fs = cfg.sim.sample_rate_hz};
    p.r = afm_runner_create(&cfg, 256, false, err, sizeof err);
    if (!p.r) {
        printf("can_vm_probe: runner: %s\n", err);
        return 2;
    }
    afm_io_sink sink = {.ctx = &p, .on_cmd = on_cmd, .on_reject = on_reject, .limits = limits};
    afm_io *io = afm_can_io_create(&cfg.can, &cfg.drive, &sink, err, sizeof err);
    int s = tx_open();
    if (!io || s < 0) {
        printf("can_vm_probe: %s\n", !io ? err : "cannot open the sending socket on vcan0");
        return 2;
    }
    const afm_cfg_can *m = &cfg.can;
    afm_io_status st;
    afm_runner_status rs;

    pump(io, 0.05);
    status(io, &st);
    check_true(strstr(st.can_state, "no-heartbeat") != NULL && !st.heartbeat_ok,
               "socket open, no heartbeat yet: said so");

    send_sig(s, m, AFM_CAN_HEARTBEAT, 0, 5, 0);
    pump(io, 0.05);
    status(io, &st);
    check_true(strcmp(st.can_state, "ok") == 0 && st.heartbeat_ok, "heartbeat seen: ok");

    /* dither and setpoint through the bus into the twin */
    send_sig(s, m, AFM_CAN_DITHER_FREQUENCY, 0, 251234.56, 0);
    send_sig(s, m, AFM_CAN_DITHER_AMPLITUDE, 0, 7.5e-9, 0);
    send_sig(s, m, AFM_CAN_SETPOINT, 0, 12e-9, 0);
    send_sig(s, m, AFM_CAN_HEARTBEAT, 0, 5, 0);
    pump(io, 0.1);
    afm_runner_run(p.r, 2000);
    afm_runner_status_get(p.r, &rs);
    check_abs(rs.fe_hz, 251234.56, 0.005, "twin's tone 0 frequency from CAN (0.01 Hz/bit)");
    check_abs(rs.amplitude_m, 7.5e-9, 0.5e-15, "twin's tone 0 amplitude from CAN (1 fm/bit)");
    check_abs(rs.separation_m, 12e-9, 0.5e-12, "twin's Z setpoint from CAN (1 pm/bit)");
    check_true(rs.samples >= 2000, "twin runs with them");
    send_sig(s, m, AFM_CAN_ENABLE, 0, 0, 0);
    pump(io, 0.05);
    afm_runner_status_get(p.r, &rs);
    check_true(!rs.running, "enable 0 pauses the twin");
    send_sig(s, m, AFM_CAN_ENABLE, 0, 1, 0);
    pump(io, 0.05);
    afm_runner_status_get(p.r, &rs);
    check_true(rs.running, "enable 1 runs it again");

    /* bad frames: rejected, counted, nothing changed */
    status(io, &st);
    long long rej0 = st.can_rejected;
    int prej = p.rejected;
    struct canfd_frame f;
    memset(&f, 0, sizeof f);
    f.can_id = 0x123;
    f.len = 8;
    tx(s, &f); /* unknown id */
    afm_can_encode(m, AFM_CAN_SETPOINT, 0, 40e-9, 0, &f, err, sizeof err);
    f.len = 6;
    tx(s, &f);                                            /* wrong length */
    send_sig(s, m, AFM_CAN_DITHER_FREQUENCY, 0, 8e6, 0);  /* above Nyquist */
    send_sig(s, m, AFM_CAN_DITHER_AMPLITUDE, 0, 3e-6, 0); /* too large */
    send_sig(s, m, AFM_CAN_SETPOINT, 0, 2e-3, 0);         /* Z beyond 1 mm */
    pump(io, 0.1);
    status(io, &st);
    afm_runner_status_get(p.r, &rs);
    check_true(st.can_rejected - rej0 == 5 && p.rejected - prej == 5,
               "5 bad frames rejected and counted (transport and daemon sink)");
    check_true(strstr(st.can_last_reject, "separation_m") != NULL, "last reject reported");
    check_true(rs.fe_hz == 251234.56 || (rs.fe_hz > 251234.55 && rs.fe_hz < 251234.57),
               "dither unchanged by bad frames");
    check_abs(rs.separation_m, 12e-9, 0.5e-12, "Z unchanged by bad frames");

    /* heartbeat lapses: reported, commands held */
    pump(io, m->heartbeat_timeout_s + 0.15);
    status(io, &st);
    check_true(!st.heartbeat_ok && strstr(st.can_state, "no-heartbeat") &&
                   strstr(st.can_state, "holding last commands"),
               "missing heartbeat reported, last commands held");
    afm_runner_status_get(p.r, &rs);
    check_abs(rs.amplitude_m, 7.5e-9, 0.5e-15, "amplitude held without heartbeat");
    send_sig(s, m, AFM_CAN_HEARTBEAT, 0, 5, 0);
    pump(io, 0.05);

    /* error frames from the controller: bus-off, then restarted */
    memset(&f, 0, sizeof f);
    f.can_id = CAN_ERR_FLAG | CAN_ERR_BUSOFF;
    f.len = CAN_ERR_DLC;
    tx(s, &f);
    pump(io, 0.05);
    status(io, &st);
    check_true(strstr(st.can_state, "bus-off") && st.can_errors >= 1,
               "bus-off error frame reported");
    f.can_id = CAN_ERR_FLAG | CAN_ERR_RESTARTED;
    tx(s, &f);
    send_sig(s, m, AFM_CAN_HEARTBEAT, 0, 5, 0);
    pump(io, 0.05);
    status(io, &st);
    check_true(strcmp(st.can_state, "ok") == 0, "controller restarted: ok again");

    /* interface down (ENETDOWN) and up again: reconnect */
    sh("ip link set vcan0 down");
    pump(io, 0.1);
    status(io, &st);
    check_true(strstr(st.can_state, "down") && strstr(st.can_state, "holding last commands"),
               "interface down reported, last commands held");
    sh("ip link set vcan0 up");
    pump(io, 3 * m->reconnect_max_s);
    close(s); /* the sender's socket holds the ENETDOWN too: a fresh one */
    s = tx_open();
    send_sig(s, m, AFM_CAN_HEARTBEAT, 0, 5, 0);
    send_sig(s, m, AFM_CAN_SETPOINT, 0, 20e-9, 1e-6);
    pump(io, 0.1);
    status(io, &st);
    afm_runner_status_get(p.r, &rs);
    check_true(st.can_reconnects == 1 && strcmp(st.can_state, "ok") == 0,
               "reconnected after the interface came back");
    check_abs(rs.separation_target_m, 20e-9, 0.5e-12, "setpoint after reconnect reaches the twin");

    /* interface deleted (ENODEV) and created again */
    close(s);
    sh("ip link del vcan0");
    pump(io, 0.1);
    status(io, &st);
    check_true(strstr(st.can_state, "down") != NULL, "interface deleted reported");
    sh("ip link add dev vcan0 type vcan && ip link set vcan0 up");
    pump(io, 3 * m->reconnect_max_s);
    s = tx_open();
    send_sig(s, m, AFM_CAN_HEARTBEAT, 0, 5, 0);
    send_sig(s, m, AFM_CAN_DITHER_FREQUENCY, 0, 260e3, 0);
    pump(io, 0.1);
    status(io, &st);
    afm_runner_status_get(p.r, &rs);
    check_true(st.can_reconnects == 2 && strcmp(st.can_state, "ok") == 0,
               "reconnected after the interface was re-created");
    check_abs(rs.fe_hz, 260e3, 0.005, "dither after re-creation reaches the twin");
    check_true(p.refused == 0, "the runner refused nothing the codec passed");

    afm_io_destroy(&io);
    close(s);
    afm_runner_destroy(&p.r);
    return check_done();
}
