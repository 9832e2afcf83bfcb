/* SPDX-License-Identifier: MIT */
/* afm_can_codec.h -- the CAN message map of a piezo driver (docs/can.md): frames (struct
 * canfd_frame layout, classic CAN or CAN FD) to validated afm_cmd commands and back.
 *
 * Pure functions, no sockets: the map comes from the config (afm_cfg_can), the driver's
 * register view (afm_can_state) is passed in and a new one handed back, which the caller
 * keeps only if the command was taken. A rejected frame changes nothing.
 *
 * Frames (lengths are exact; 4-byte values in can.byte_order; "value" is a u32 times its
 * scale, the phase an i32 times its scale, or with encoding = "float32" an IEEE float in SI):
 *   dither_frequency  len 8  [tone][0][0][0][frequency Hz]   -> dither command
 *   dither_amplitude  len 8  [tone][0][0][0][amplitude m]    -> dither command
 *   dither_phase      len 8  [tone][0][0][0][phase rad]      -> stored: the starting phase of
 *                     a tone that is not running yet (the drive is phase-continuous, so the
 *                     phase of a running tone cannot change: rejected with that reason)
 *   setpoint          len 8  [separation m][ramp rate m/s]   -> setpoint command (ramp 0: step)
 *   enable            len 1  [1 enable | 0 disable]          -> control RUN | PAUSE
 *   heartbeat         len 1  [driver state, any]             -> heartbeat (no command)
 * A dither frame for tone j sets that register and sends the whole dither (all tones up to
 * the highest running one, as afm_cmd_dither wants); a frequency or amplitude for tone j at
 * or past the running tones starts tones n..j, which must have frequencies by then.
 * Rejected, with a reason naming the id and signal: unknown ids (and 11/29-bit format not
 * the map's), remote frames, error frames, FD frames when can.fd is false, wrong lengths,
 * tones past AFM_MAX_TONES-1, NaN/inf floats, enable bytes other than 0/1, phases outside
 * [-2 pi, 2 pi], and everything afm_cmd_validate rejects (with the running sample rate). */
#ifndef AFM_CAN_CODEC_H
#define AFM_CAN_CODEC_H

#include "runner/afm_cmd.h"
#include "config/afm_config.h"

#include <linux/can.h>
#include <stdbool.h>
#include <stddef.h>

#define AFM_CAN_MAX_PHASE_RAD 6.283185307179586 /* |start phase| limit (2 pi) */

typedef enum {
    AFM_CAN_R_REJECT = -1,  /* err says why; nothing changed */
    AFM_CAN_R_COMMAND = 0,  /* *cmd is a validated command; keep *next if it is taken */
    AFM_CAN_R_STORED = 1,   /* a start phase stored in *next; no command */
    AFM_CAN_R_HEARTBEAT = 2 /* the driver's heartbeat; *state_byte says its state */
} afm_can_result;

/* The driver's registers as the twin last took them from CAN. */
typedef struct {
    afm_cmd_dither dither; /* n_tones running; f, A and start phase per tone (all 4 kept) */
} afm_can_state;

/* Registers from the config's drive (what the twin starts with). */
void afm_can_state_init(afm_can_state *s, const afm_cfg_drive *d);
/* Follow the drive the twin runs now (after dithers from other transports, reloads):
 * frequency and amplitude of the running tones and their count; the registers of tones
 * not running (and every start phase) stay as the driver set them. */
void afm_can_state_sync(afm_can_state *s, const afm_cmd_dither *running);

/* "dither_frequency", ... (the config's key under can.ids); "?" out of range. */
const char *afm_can_signal_name(afm_can_signal sig);
/* The signal a frame id belongs to (id with CAN_EFF_FLAG for 29-bit frames), or -1. */
int afm_can_signal_of(const afm_cfg_can *map, canid_t id);

/* Decode one frame. fd: f came as a CAN FD frame (CANFD_MTU). lim: the running sample rate
 * (NULL: frequency only checked for > 0). On AFM_CAN_R_COMMAND, *cmd (seq and utime 0: the
 * transport stamps them) and *next (the registers after the command); on AFM_CAN_R_STORED
 * *next; on AFM_CAN_R_HEARTBEAT *state_byte (may be NULL). state and next may be the same
 * object only if the caller does not need to undo. */
afm_can_result afm_can_decode(const afm_cfg_can *map, const afm_can_state *state,
                              const struct canfd_frame *f, bool fd, const afm_cmd_limits *lim,
                              afm_cmd *cmd, afm_can_state *next, int *state_byte, char *err,
                              size_t errlen);

/* Encode one frame of signal sig into *f (zeroed first; can_id with CAN_EFF_FLAG when the
 * map uses 29-bit ids; len as above). Values in SI: dither signals use tone and v0;
 * setpoint v0 = separation m, v1 = ramp rate m/s; enable v0 = 1 or 0; heartbeat v0 = the
 * state byte 0..255. Checks that the value fits the signal (raw range, finite, tone,
 * enable 0/1) -- the twin's own limits are afm_can_decode's job. 0, or -1 with err. */
int afm_can_encode(const afm_cfg_can *map, afm_can_signal sig, int tone, double v0, double v1,
                   struct canfd_frame *f, char *err, size_t errlen);

/* cansend's text form of a frame: "123#DEADBEEF", "12345678#..." for 29-bit ids, and
 * "123##0DEADBEEF" for a CAN FD frame (flags nibble 0). buf of at least 150 bytes. */
void afm_can_format(const struct canfd_frame *f, bool fd, char *buf, size_t len);

#endif
