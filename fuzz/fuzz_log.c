/* SPDX-License-Identifier: MIT */
/* fuzz_log.c -- libFuzzer harness: LCM log files (afm_lcm_log, what `afmtwin replay` and
 * `listen --log` read) from untrusted bytes, held in memory (fmemopen). Every event the
 * reader returns lies within the file, its channel is a proper string, and each event's
 * data go on through the command decoder as replay does. */
#include "transport/afm_cmd_lcm.h"
#include "transport/afm_lcm_log.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (size < 1) return 0;
    FILE *f = fmemopen((void *)data, size, "rb");
    if (!f) return 0;
    char err[AFM_ERR_LEN];
    afm_lcm_log *l = afm_lcm_log_from_file(f, 1u << 20, err, sizeof err);
    if (!l) return 0;
    afm_lcm_log_event ev;
    size_t total = 0;
    while (afm_lcm_log_next(l, &ev, err, sizeof err) > 0) {
        size_t cl = strlen(ev.channel);
        total += 28 + cl + ev.datalen;
        if (cl < 1 || cl > AFM_LCM_LOG_MAX_CHANNEL || total > size || ev.offset < 0 ||
            (size_t)ev.offset + 28 + cl + ev.datalen > size)
            abort();
        afm_cmd c;
        afm_cmd_limits lim = {.sample_rate_hz = 14.06e6};
        afm_cmd_decode((afm_cmd_kind)(1 + ev.datalen % 5), ev.data, ev.datalen, &lim, &c, err,
                       sizeof err);
    }
    afm_lcm_log_close(&l);
    return 0;
}
