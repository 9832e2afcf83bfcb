/* SPDX-License-Identifier: MIT */
/* fuzz_config.c -- libFuzzer harness: config text through the loader (afm_config_parse:
 * libconfig's parser, then every group's keys, types and the plausibility checks). Inputs
 * with an @include are skipped: libconfig would open the file named. A config that loads
 * must pass afm_config_validate again. */
#include "config/afm_config.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (size > 65536) return 0;
    char *text = malloc(size + 1);
    if (!text) return 0;
    memcpy(text, data, size);
    text[size] = 0;
    if (!strstr(text, "@include")) {
        static afm_config cfg;
        char err[AFM_ERR_LEN];
        if (afm_config_parse(text, "fuzz.conf", &cfg, err, sizeof err) == 0 &&
            afm_config_validate(&cfg, err, sizeof err) != 0)
            abort();
    }
    free(text);
    return 0;
}
