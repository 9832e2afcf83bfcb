/* SPDX-License-Identifier: MIT */
/* afm_cmd_lcm.h -- decoding of the LCM command messages (the generated afmtwin_*_t types)
 * into the engine's afm_cmd (runner/afm_cmd.h), validated on the way. The daemon's LCM
 * transport, the replay and lockstep tools and `afmtwin send` use it. */
#ifndef AFM_CMD_LCM_H
#define AFM_CMD_LCM_H

#include "runner/afm_cmd.h"

#include <stddef.h>

/* Decode one LCM message body (what lcm hands a subscriber: rbuf->data, rbuf->data_size)
 * of the given kind into c and validate it. Rejected (-1, reason in err, c unspecified):
 * a wrong fingerprint (another message type on this channel), a truncated or malformed
 * body (lcm's decode returned < 0), trailing bytes, and everything afm_cmd_validate
 * rejects. May allocate temporarily (lcm's decode does); not for the real-time thread. */
int afm_cmd_decode(afm_cmd_kind kind, const void *data, size_t len, const afm_cmd_limits *lim,
                   afm_cmd *c, char *err, size_t errlen);

/* The same from an already decoded message (pointer to the generated struct, e.g.
 * const afmtwin_dither_t *): copies and validates. Declared with void * so this header
 * does not pull in the generated headers; msg must be the type that kind names. */
int afm_cmd_from_msg(afm_cmd_kind kind, const void *msg, const afm_cmd_limits *lim, afm_cmd *c,
                     char *err, size_t errlen);

/* The channel suffix of a command kind ("DITHER", "SETPOINT", "PARAM", "CONTROL", "TICK",
 * "SCAN"), or NULL for a kind that comes from no message (reload). */
const char *afm_cmd_channel_suffix(afm_cmd_kind kind);

/* The inverse of afm_cmd_decode: c (a decoded, valid command) as the LCM message body that
 * decodes to it again, into buf (cap bytes). Its length, or -1 for a kind that comes from no
 * message (reload) or a buf too small. Every field round-trips bit for bit (param names by
 * afm_param_name). Allocates nothing; not for the real-time thread (lcm's encode). */
int afm_cmd_encode(const afm_cmd *c, void *buf, int cap);

#endif
