/* SPDX-License-Identifier: MIT */
/* msg_examples.h -- example LCM messages, encoded by lcm-gen's encoders, that the wire and
 * decoder tests (test_wire.c) break in known places and the fuzzers start from (their seed
 * generator, fuzz/seeds.c). Each writes into b (cap bytes) and returns the length. */
#ifndef AFM_TEST_MSG_EXAMPLES_H
#define AFM_TEST_MSG_EXAMPLES_H

#include <stdint.h>

/* Byte offsets inside the examples (hash 8 bytes first). */
#define EX_DITHER_N_TONES_AT 24  /* int8 n_tones */
#define EX_PARAM_N_AT 24         /* int16 n */
#define EX_PARAM_NAME0_LEN_AT 26 /* int32 length of name[0] */
#define EX_SAMPLES_N_AT 41       /* int32 n */
#define EX_STATUS_REJECT_AT 72   /* int32 length of last_reject */

/* samples_t: stream 1, n 3, deflection 1 2 3, obd 4 5 6, counts 1 -2 3, force 7 8 9. */
int ex_samples(uint8_t *b, int cap);
/* harmonics_t: n 2 (k 1, 3). */
int ex_harmonics(uint8_t *b, int cap);
/* status_t with every string set; last_reject as given. */
int ex_status(uint8_t *b, int cap, const char *last_reject);
/* dither_t of n_tones (1..4): 338.112 kHz 0.087 nm, 2.07 MHz 10 pm, then silent tones. */
int ex_dither(uint8_t *b, int cap, int n_tones);
/* param_t: forces.radius_m = 1e-8, drive.separation_m = 3e-8 (n = 2). */
int ex_param(uint8_t *b, int cap);

#endif
