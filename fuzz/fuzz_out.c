/* SPDX-License-Identifier: MIT */
/* fuzz_out.c -- libFuzzer harness: any message type from untrusted bytes, as the tools
 * decode the daemon's outputs (listen, bench-daemon: samples_t, harmonics_t, status_t) and
 * the daemon its commands. Byte 0 picks the type of afm_wire_all; the rest goes through
 * afm_wire_decode (length check, lcm-gen's decoder). The oracle: what decodes re-encodes
 * (lcm-gen's encoder) to exactly the same bytes, so the check and the decoder agree on the
 * layout and no byte is misread. */
#include "transport/afm_lcm_wire.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (size < 1) return 0;
    int nt = 0;
    while (afm_wire_all[nt])
        nt++;
    const afm_wire_type *t = afm_wire_all[data[0] % nt];
    union {
        char b[4096];
        double d;
        void *p;
    } m;
    if (t->size > sizeof m.b) abort();
    if (afm_wire_decode(t, data + 1, size - 1, &m, NULL, 0) != 0) return 0;
    int n = t->encoded_size(&m);
    uint8_t *buf = malloc(n > 0 ? (size_t)n : 1);
    if (!buf) abort();
    int w = t->encode(buf, n, &m);
    if (w != (int)(size - 1) || memcmp(buf, data + 1, size - 1) != 0) abort();
    free(buf);
    afm_wire_free(t, &m);
    return 0;
}
