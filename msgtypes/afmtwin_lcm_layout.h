/* SPDX-License-Identifier: MIT */
/* afmtwin_lcm_layout.h -- where the twin's LCM traffic goes: the default URLs and the
 * channel names, for clients (installed with the generated headers; the daemon and the
 * afmtwin tool use the same definitions).
 *
 * Three udpm ports on one multicast group (LCM's default group):
 *   PORT     (7667) commands in:  PREFIX + DITHER, SETPOINT, PARAM, CONTROL, TICK
 *   PORT + 1 (7668) outputs:      PREFIX + HARMONICS, STATUS, TICK_DONE (~1 kHz, ~0.5 MB/s)
 *   PORT + 2 (7669) sample stream: PREFIX + SAMPLES (every decimated sample, ~14 MB/s on
 *                                  config/default.conf)
 * so that a controller or a logger of the status and harmonics never receives the sample
 * flood, and the daemon's command socket carries commands only. Other LCM providers (memq,
 * file) carry everything on one URL. The daemon's --lcm-url gives PORT, --lcm-out-url and
 * --lcm-samples-url override the derived ones.
 *
 * Every output message carries msg_seq: 0 for the first message the daemon published on its
 * channel, +1 for each one after, so a jump is a lost message. */
#ifndef AFMTWIN_LCM_LAYOUT_H
#define AFMTWIN_LCM_LAYOUT_H

#define AFMTWIN_DEFAULT_URL "udpm://239.255.76.67:7667?ttl=0" /* LCM's own default */
#define AFMTWIN_DEFAULT_OUT_URL "udpm://239.255.76.67:7668?ttl=0"
#define AFMTWIN_DEFAULT_SAMPLES_URL "udpm://239.255.76.67:7669?ttl=0"
#define AFMTWIN_OUT_PORT_OFFSET 1     /* outputs: command port + 1 */
#define AFMTWIN_SAMPLES_PORT_OFFSET 2 /* sample stream: command port + 2 */

#define AFMTWIN_DEFAULT_PREFIX "AFMTWIN_" /* afmtwind --prefix */
/* Commands (dither_t, setpoint_t, param_t, control_t, tick_t, scan_t) */
#define AFMTWIN_CHAN_DITHER "DITHER"
#define AFMTWIN_CHAN_SETPOINT "SETPOINT"
#define AFMTWIN_CHAN_PARAM "PARAM"
#define AFMTWIN_CHAN_CONTROL "CONTROL"
#define AFMTWIN_CHAN_TICK "TICK"
#define AFMTWIN_CHAN_SCAN "SCAN" /* scan_t: the tip's lateral position (issue 18) */
/* Outputs (harmonics_t, status_t, tick_done_t; samples_t on the sample URL) */
#define AFMTWIN_CHAN_HARMONICS "HARMONICS"
#define AFMTWIN_CHAN_STATUS "STATUS"
#define AFMTWIN_CHAN_TICK_DONE "TICK_DONE"
#define AFMTWIN_CHAN_SAMPLES "SAMPLES"

#endif
