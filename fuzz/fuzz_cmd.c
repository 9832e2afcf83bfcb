/* SPDX-License-Identifier: MIT */
/* fuzz_cmd.c -- libFuzzer harness: command messages as the daemon's receive thread takes
 * them. Byte 0 picks the kind (dither .. tick) and whether the limits carry the model; the
 * rest is the message body: afm_cmd_decode (wire check, lcm-gen's decoder, validation),
 * then, for what is accepted, afm_cmd_validate must agree and a param is applied to a copy
 * of the config (afm_param_apply, as on_cmd does). Run from the repository root
 * (config/default.conf); `make fuzz`, tests/fuzz.sh. */
#include "transport/afm_cmd_lcm.h"
#include "config/afm_config.h"
#include "beam/afm_model.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static afm_config cfg;
static afm_modal model;

int LLVMFuzzerInitialize(int *argc, char ***argv) {
    (void)argc;
    (void)argv;
    char err[AFM_ERR_LEN];
    if (afm_config_load("config/default.conf", &cfg, err, sizeof err) ||
        afm_model_build(&cfg.model, &model, err, sizeof err)) {
        fprintf(stderr, "fuzz_cmd: %s (run from the repository root)\n", err);
        exit(1);
    }
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (size < 1) return 0;
    afm_cmd_kind kind = (afm_cmd_kind)(1 + data[0] % 5);
    afm_cmd_limits lim = {.sample_rate_hz = cfg.sim.sample_rate_hz,
                          .model = data[0] & 0x80 ? &model : NULL};
    afm_cmd c;
    char err[AFM_ERR_LEN];
    if (afm_cmd_decode(kind, data + 1, size - 1, &lim, &c, err, sizeof err) != 0) return 0;
    if (c.kind != kind || afm_cmd_validate(&c, &lim, err, sizeof err) != 0) abort();
    if (kind == AFM_CMD_PARAM) {
        static afm_config t;
        t = cfg;
        afm_param_effect e;
        afm_param_apply(&t, &c.u.param, &e, err, sizeof err);
    }
    return 0;
}
