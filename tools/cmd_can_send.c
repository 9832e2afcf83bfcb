/* SPDX-License-Identifier: MIT */
/* cmd_can_send.c -- `afmtwin can-send`: encodes one command into frames of the CAN map
 * (the config's `can` group, docs/can.md), checks them with the daemon's own decoder, prints
 * them in cansend's format (123#DEADBEEF) and, with --interface, sends them on a raw
 * SocketCAN socket. */
#define _DEFAULT_SOURCE /* struct ifreq */
#include "afmtwin_cmds.h"
#include "opts.h"

#include "transport/afm_can_codec.h"
#include "config/afm_config.h"

#include <errno.h>
#include <linux/can/raw.h>
#include <math.h>
#include <net/if.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#define MAX_FRAMES 3

static void usage(FILE *f) {
    fprintf(f,
            "usage: afmtwin can-send KIND [OPTIONS] [--config FILE] [--interface IF]\n\n"
            "Encodes one command into CAN frames of the map in FILE's `can` group (default\n"
            "map when FILE has none; docs/can.md), checks them with the daemon's decoder and\n"
            "prints them one a line in cansend's format, e.g. `200#0000000000EB0302`, so\n"
            "that can-utils' cansend can send them too. --interface IF sends them on IF.\n\n"
            "kinds:\n"
            "  dither --tone J [--freq HZ] [--amp M] [--phase RAD]\n"
            "        one frame per value given; a phase only sets the start of a tone that\n"
            "        is not running yet (it goes first)\n"
            "  setpoint --z M [--ramp M_S]     Z setpoint, ramp 0 (default) steps\n"
            "  enable | disable                run / pause the twin\n"
            "  heartbeat [--state N]           the driver's heartbeat (state byte, default 5)\n\n"
            "options:\n"
            "  --config FILE     the daemon's config (default config/default.conf)\n"
            "  --interface IF    send on IF (e.g. can0, vcan0) instead of only printing\n"
            "  --fd              send as CAN FD frames (needs can.fd = true)\n"
            "  --no-check        print/send even frames the daemon would reject\n"
            "  --help            this text\n\n" AFMT_OPT_SI_HELP
            "Exit status 0 ok, 1 socket failure, 2 bad usage or a frame the daemon would\n"
            "reject (the reason is printed).\n");
}

static int send_frames(const char *ifname, const struct canfd_frame *f, int n, bool fd) {
    int s = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (s < 0) {
        fprintf(stderr, "afmtwin can-send: socket(PF_CAN): %s\n", strerror(errno));
        return 1;
    }
    struct ifreq ifr;
    memset(&ifr, 0, sizeof ifr);
    snprintf(ifr.ifr_name, sizeof ifr.ifr_name, "%s", ifname);
    int on = 1;
    struct sockaddr_can a = {.can_family = AF_CAN};
    if (ioctl(s, SIOCGIFINDEX, &ifr) < 0) {
        fprintf(stderr, "afmtwin can-send: %s: %s\n", ifname, strerror(errno));
        goto fail;
    }
    a.can_ifindex = ifr.ifr_ifindex;
    if (fd && setsockopt(s, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) < 0) {
        fprintf(stderr, "afmtwin can-send: CAN FD: %s\n", strerror(errno));
        goto fail;
    }
    if (bind(s, (struct sockaddr *)&a, sizeof a) < 0) {
        fprintf(stderr, "afmtwin can-send: bind %s: %s\n", ifname, strerror(errno));
        goto fail;
    }
    for (int i = 0; i < n; i++) {
        size_t len = fd ? CANFD_MTU : CAN_MTU;
        if (write(s, &f[i], len) != (ssize_t)len) {
            fprintf(stderr, "afmtwin can-send: write on %s: %s\n", ifname, strerror(errno));
            goto fail;
        }
    }
    close(s);
    return 0;
fail:
    close(s);
    return 1;
}

int afm_cmd_can_send(int argc, char **argv) {
    const char *cfg_path = "config/default.conf", *ifname = NULL;
    bool fd = false, no_check = false;
    double tone = -1, freq = NAN, amp = NAN, phase = NAN, z = NAN, ramp = 0, state = 5;
    if (argc < 2 || !strcmp(argv[1], "--help")) {
        usage(argc < 2 ? stderr : stdout);
        return argc < 2 ? 2 : 0;
    }
    const char *kind = argv[1];
    const afmt_opt opts[] = {
        AFMT_FLAG("--fd", &fd),
        AFMT_FLAG("--no-check", &no_check),
        AFMT_STRING("--config", &cfg_path),
        AFMT_STRING("--interface", &ifname),
        AFMT_FN("--tone", afmt_opt_any_number, &tone, "a number"),
        AFMT_FN_UNIT("--freq", afmt_opt_any_freq, &freq,
                     "a number (Hz, or with a suffix: kHz, MHz, GHz)", AFMT_UNIT_HZ),
        AFMT_FN_UNIT("--amp", afmt_opt_any_length, &amp,
                     "a number (m, or with a suffix: mm, um, nm, pm, fm)", AFMT_UNIT_M),
        AFMT_FN("--phase", afmt_opt_any_number, &phase, "a number"),
        AFMT_FN_UNIT("--z", afmt_opt_any_length, &z,
                     "a number (m, or with a suffix: mm, um, nm, pm, fm)", AFMT_UNIT_M),
        AFMT_FN("--ramp", afmt_opt_any_number, &ramp, "a number"),
        AFMT_FN("--state", afmt_opt_any_number, &state, "a number"),
        AFMT_OPTS_END,
    };
    int prc = afmt_opts_parse("can-send", opts, argc, argv, 2);
    if (prc == AFMT_OPTS_HELP) usage(stdout);
    if (prc) return prc == AFMT_OPTS_HELP ? 0 : 2;
    bool check = !no_check;
    static afm_config cfg;
    char err[AFM_ERR_LEN];
    if (afmt_config_load("can-send", cfg_path, &cfg)) return 2;
    const afm_cfg_can *m = &cfg.can; /* the default map when the file has no can group */
    struct canfd_frame f[MAX_FRAMES];
    int n = 0, rc = 0;
    if (!strcmp(kind, "dither")) {
        if (tone < 0 || tone != floor(tone)) {
            fprintf(stderr, "afmtwin can-send: dither needs --tone J (0..%d)\n", AFM_MAX_TONES - 1);
            return 2;
        }
        if (isnan(freq) && isnan(amp) && isnan(phase)) {
            fprintf(stderr, "afmtwin can-send: dither needs --freq, --amp and/or --phase\n");
            return 2;
        }
        if (!isnan(phase))
            rc |= afm_can_encode(m, AFM_CAN_DITHER_PHASE, (int)tone, phase, 0, &f[n++], err,
                                 sizeof err);
        if (!rc && !isnan(freq))
            rc |= afm_can_encode(m, AFM_CAN_DITHER_FREQUENCY, (int)tone, freq, 0, &f[n++], err,
                                 sizeof err);
        if (!rc && !isnan(amp))
            rc |= afm_can_encode(m, AFM_CAN_DITHER_AMPLITUDE, (int)tone, amp, 0, &f[n++], err,
                                 sizeof err);
    } else if (!strcmp(kind, "setpoint")) {
        if (isnan(z)) {
            fprintf(stderr, "afmtwin can-send: setpoint needs --z M\n");
            return 2;
        }
        rc = afm_can_encode(m, AFM_CAN_SETPOINT, 0, z, ramp, &f[n++], err, sizeof err);
    } else if (!strcmp(kind, "enable") || !strcmp(kind, "disable")) {
        rc = afm_can_encode(m, AFM_CAN_ENABLE, 0, kind[0] == 'e', 0, &f[n++], err, sizeof err);
    } else if (!strcmp(kind, "heartbeat")) {
        rc = afm_can_encode(m, AFM_CAN_HEARTBEAT, 0, state, 0, &f[n++], err, sizeof err);
    } else {
        fprintf(stderr, "afmtwin can-send: unknown kind '%s' (see --help)\n", kind);
        return 2;
    }
    if (rc) {
        fprintf(stderr, "afmtwin can-send: %s\n", err);
        return 2;
    }
    if (fd && !m->fd && check) {
        fprintf(stderr, "afmtwin can-send: --fd, but the map has can.fd = false (the daemon "
                        "would not read FD frames)\n");
        return 2;
    }
    /* The daemon's decoder, from the config's registers, frame after frame. */
    afm_can_state st, next;
    afm_can_state_init(&st, &cfg.drive);
    static afm_modal model;
    afm_cmd_limits lim = {.sample_rate_hz = cfg.sim.sample_rate_hz, .model = &model};
    if (afm_model_build(&cfg.model, &model, err, sizeof err)) {
        fprintf(stderr, "afmtwin can-send: %s\n", err);
        return 2;
    }
    afm_cfg_can mm = *m;
    mm.fd = mm.fd || fd;
    for (int i = 0; i < n && check; i++) {
        afm_cmd c;
        if (afm_can_decode(&mm, &st, &f[i], fd, &lim, &c, &next, NULL, err, sizeof err) ==
            AFM_CAN_R_REJECT) {
            fprintf(stderr, "afmtwin can-send: the daemon would reject this: %s\n", err);
            return 2;
        }
        st = next;
    }
    for (int i = 0; i < n; i++) {
        char txt[160];
        afm_can_format(&f[i], fd, txt, sizeof txt);
        printf("%s\n", txt);
    }
    return ifname ? send_frames(ifname, f, n, fd) : 0;
}
