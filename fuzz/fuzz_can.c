/* SPDX-License-Identifier: MIT */
/* fuzz_can.c -- libFuzzer harness: CAN frames through the codec (afm_can_decode), as the
 * CAN transport hands them over. Byte 0 picks the map (default scaled little-endian,
 * float32 big-endian, 29-bit ids) and byte 1 the frame kind (classic / FD) and whether the
 * registers run two tones; then the frame: can_id (4 bytes), len, flags and up to 64 data
 * bytes (len as given, even past 64: the codec must not trust it). A command must pass
 * afm_cmd_validate again; the frame is formatted as cansend text too. */
#include "transport/afm_can_codec.h"
#include "config/afm_config.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (size < 8) return 0;
    static afm_config cfg;
    static bool init;
    if (!init) {
        afm_config_defaults(&cfg);
        cfg.can.enabled = true;
        init = true;
    }
    afm_cfg_can map = cfg.can;
    switch (data[0] % 3) {
    case 1:
        map.encoding = AFM_CAN_FLOAT32;
        map.big_endian = true;
        break;
    case 2:
        map.extended_ids = true;
        map.id[AFM_CAN_DITHER_FREQUENCY] = 0x18FF0100;
        break;
    }
    bool fd = data[1] & 1;
    map.fd = data[1] & 2;
    afm_cfg_drive drive = {.separation_m = 30e-9, .n_tones = data[1] & 4 ? 2 : 1};
    drive.tones[0] = (afm_cfg_tone){.amplitude_m = 0.087e-9, .frequency_hz = 338112};
    drive.tones[1] = (afm_cfg_tone){.amplitude_m = 1e-11, .frequency_hz = 2.07e6};
    afm_can_state st, next;
    afm_can_state_init(&st, &drive);
    struct canfd_frame f;
    memset(&f, 0, sizeof f);
    memcpy(&f.can_id, data + 2, 4);
    f.len = data[6];
    f.flags = data[7];
    size_t n = size - 8 < sizeof f.data ? size - 8 : sizeof f.data;
    memcpy(f.data, data + 8, n);
    afm_cmd_limits lim = {.sample_rate_hz = 14.06e6};
    afm_cmd c;
    int byte;
    char err[AFM_ERR_LEN];
    afm_can_result r = afm_can_decode(&map, &st, &f, fd, &lim, &c, &next, &byte, err, sizeof err);
    if (r == AFM_CAN_R_COMMAND && afm_cmd_validate(&c, &lim, err, sizeof err) != 0) abort();
    char text[160];
    afm_can_format(&f, fd, text, sizeof text);
    return 0;
}
