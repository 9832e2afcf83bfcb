/* SPDX-License-Identifier: MIT */
/* afm_cmd.h -- the twin's command vocabulary: the internal command (one tagged union for
 * every inbound message, whatever the transport), its validation, and the table of live
 * parameter names. Decoding from the wire is the transports' job: LCM in
 * daemon/transport/afm_cmd_lcm.h, CAN in daemon/transport/afm_can_codec.h.
 *
 * Pure functions: nothing here keeps state, and a rejected command changes nothing. The
 * daemon (afmtwind), the replay tool and `afmtwin send` all use them, so that `send` exits
 * non-zero on exactly the values the daemon would reject.
 *
 * Pipeline in the daemon's receive thread:
 *   bytes --afm_cmd_decode (transport)--> afm_cmd (decoded AND validated, or rejected with a
 * reason)
 *         --(param only) afm_param_apply on the daemon's copy of the config--> queue.
 *
 * Validation (afm_cmd_validate), each with a reason naming the field, e.g.
 *   "dither: tone 1 frequency_hz 8e+06 must be >= 1 and < 7.03e+06 (half the sample rate)":
 *  - every double finite (NaN, inf rejected);
 *  - dither (the plausibility limits of afm_limits.h): n_tones 1..AFM_MAX_TONES, each
 *    amplitude 0..AFM_LIM_TONE_AMPLITUDE_MAX_M and their sum at most
 *    AFM_LIM_DRIVE_AMPLITUDE_MAX_M, AFM_LIM_FREQUENCY_MIN_HZ <= frequency < sample_rate/2
 *    (no upper bound when the limits give no sample rate), phase finite; with a model in
 *    the limits also frequency <= AFM_LIM_MODEL_RANGE x its highest mode and the free tip
 *    amplitude the drive predicts at most AFM_LIM_FREE_AMPLITUDE_MAX_M (afm_cmd_check_drive);
 *  - setpoint: separation 0..AFM_LIM_SEPARATION_MAX_M, ramp rate 0..AFM_LIM_RAMP_MAX_M_S;
 *  - param: n 1..AFM_CMD_MAX_PARAMS, every name in the table (afm_param_lookup), every
 *    value within the entry's range; the same name twice is rejected;
 *  - control: action RUN/PAUSE/RESET/STEP, STEP's n_samples 1..AFM_CMD_MAX_STEP;
 *  - tick: n_samples 1..AFM_CMD_MAX_STEP;
 *  - scan (issue 18): mode HOLD/MOVE/VELOCITY/RASTER; positions within
 *    AFM_CMD_SCAN_POS_MAX_M of 0 (a raster's far corner too), speeds 0..AFM_CMD_SCAN_SPEED_MAX_M_S,
 *    a raster's size, lines, pixels and line rate within afm_scan.h's AFM_SCAN_* ranges.
 * Whether a param change fits the running config (e.g. a beam parameter on a lumped model,
 * a capillary parameter while capillary forces are off) needs the config:
 * afm_param_apply says so. */
#ifndef AFM_CMD_H
#define AFM_CMD_H

#include "config/afm_config.h"
#include "config/afm_limits.h"
#include "beam/afm_model.h"

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define AFM_CMD_MAX_PARAMS 16         /* names per param message */
#define AFM_CMD_MAX_STEP 1000000000LL /* STEP and tick n_samples upper bound */
#define AFM_CMD_NAME_LEN 64           /* longest param name + 1 */

typedef enum {
    AFM_CMD_DITHER = 1,
    AFM_CMD_SETPOINT = 2,
    AFM_CMD_PARAM = 3,
    AFM_CMD_CONTROL = 4,
    AFM_CMD_TICK = 5,
    AFM_CMD_RELOAD = 6, /* internal (SIGHUP): never decoded from a message */
    AFM_CMD_SCAN = 7    /* the tip's lateral motion (issue 18; scan_t) */
} afm_cmd_kind;

/* Values of afmtwin_control_t.action (checked against the generated constants). */
typedef enum {
    AFM_CTL_RUN = 1,
    AFM_CTL_PAUSE = 2,
    AFM_CTL_RESET = 3,
    AFM_CTL_STEP = 4
} afm_cmd_action;

/* How a parameter takes effect. */
typedef enum {
    AFM_PARAM_SEPARATION = 0, /* drive.separation_m: a setpoint step, at once */
    AFM_PARAM_FORCE = 1,      /* tip-sample force constants: at once, no allocation */
    AFM_PARAM_DAMPING = 2,    /* modal damping: a new simulator on the same modes is built
                                 off the real-time thread; the state carries over */
    AFM_PARAM_GEOMETRY = 3    /* beam or lumped model: model rebuilt off the real-time
                                 thread, swapped in at a block boundary, starts at rest */
} afm_param_effect;

typedef struct {
    int n_tones; /* 1..AFM_MAX_TONES */
    double frequency_hz[AFM_MAX_TONES];
    double amplitude_m[AFM_MAX_TONES];
    double phase_rad[AFM_MAX_TONES]; /* used only by tones this command starts */
} afm_cmd_dither;

typedef struct {
    double separation_m;  /* target Z, m */
    double ramp_rate_m_s; /* 0: step; > 0: ramp at this rate */
} afm_cmd_setpoint;

typedef struct {
    int n;
    int entry[AFM_CMD_MAX_PARAMS];    /* index into afm_param_table() */
    int index[AFM_CMD_MAX_PARAMS];    /* array element ([i]), -1 for a scalar name */
    double value[AFM_CMD_MAX_PARAMS]; /* in the name's unit (degrees for *_deg) */
} afm_cmd_param;

typedef struct {
    int action;          /* afm_cmd_action */
    long long n_samples; /* STEP: samples to advance */
} afm_cmd_control;

typedef struct {
    long long n_samples; /* lockstep: samples to advance */
} afm_cmd_tick;

/* Values of afmtwin_scan_t.mode (checked against the generated constants). */
typedef enum {
    AFM_SCAN_HOLD = 0,     /* stop where the tip is */
    AFM_SCAN_MOVE = 1,     /* to (x, y) at speed (0: at once) */
    AFM_SCAN_VELOCITY = 2, /* at (vx, vy) from where the tip is */
    AFM_SCAN_RASTER = 3    /* lines of trace + retrace (runner/afm_scan.h's raster) */
} afm_scan_mode;

/* "hold", "move", "velocity", "raster" ("?" for another value). */
const char *afm_scan_mode_name(int mode);

#define AFM_CMD_SCAN_POS_MAX_M 1.0     /* |x|, |y| of any position (= AFM_SCAN_ORIGIN_MAX_M) */
#define AFM_CMD_SCAN_SPEED_MAX_M_S 0.1 /* MOVE speed, |VELOCITY| (m/s; a piezo scanner: mm/s) */

typedef struct {
    int mode;                  /* afm_scan_mode */
    double x_m, y_m;           /* MOVE: target; RASTER: the first line's start (m) */
    double speed_m_s;          /* MOVE: 0 (jump) .. AFM_CMD_SCAN_SPEED_MAX_M_S */
    double vx_m_s, vy_m_s;     /* VELOCITY (m/s) */
    double size_x_m, size_y_m; /* RASTER (m) */
    int lines, pixels;         /* RASTER */
    double line_rate_hz;       /* RASTER: trace + retrace per second */
} afm_cmd_lateral;

typedef struct {
    afm_cmd_kind kind;
    int64_t seq;   /* sender's sequence number; outputs echo the last one applied */
    int64_t utime; /* sender's time stamp, microseconds */
    union {
        afm_cmd_dither dither;
        afm_cmd_setpoint setpoint;
        afm_cmd_param param;
        afm_cmd_control control;
        afm_cmd_tick tick;
        afm_cmd_lateral scan;
    } u;
} afm_cmd;

/* What validation needs to know about the running twin. sample_rate_hz <= 0: unknown
 * (dither frequencies then have no upper bound); model NULL: unknown (no model range, no
 * predicted free amplitude). */
typedef struct {
    double sample_rate_hz;
    const afm_modal *model; /* the running model (modal frequencies, tip response) */
} afm_cmd_limits;

/* "dither", "setpoint", ... ("?" for an unknown kind). */
const char *afm_cmd_kind_name(afm_cmd_kind k);

/* Check c; 0, or -1 with the reason in err. */
int afm_cmd_validate(const afm_cmd *c, const afm_cmd_limits *lim, char *err, size_t errlen);

/* The model-dependent drive limits: n tones at f_hz, a_m against the model m (frequency at
 * most AFM_LIM_MODEL_RANGE x the highest mode; free tip amplitude sum_j a_j |G(f_j)| at
 * most AFM_LIM_FREE_AMPLITUDE_MAX_M, into *free_m when not NULL). For a dither command and
 * for a config's drive (afm_runner_model_build). 0, or -1 with err. No allocation. */
int afm_cmd_check_drive(const afm_modal *m, int n, const double *f_hz, const double *a_m,
                        double *free_m, char *err, size_t errlen);
/* The same for the tones of a config's drive ("drive.tones: ..."). */
int afm_cmd_check_cfg_drive(const afm_modal *m, const afm_cfg_drive *d, char *err, size_t errlen);

/* ---- parameter names ------------------------------------------------------------------ */

typedef struct {
    const char *name; /* config key path, e.g. "forces.vdw_contact.hamaker_j" */
    int n_index;      /* 0: scalar; else the name takes [0 .. n_index-1] (and, if
                         scalar_ok, also the bare name: sets every element) */
    bool scalar_ok;
    double min, max; /* allowed values, inclusive unless *_open */
    bool min_open, max_open;
    afm_param_effect effect;
    const char *unit;
} afm_param_def;

/* The table (n entries into *n). Static data, valid for the life of the program. */
const afm_param_def *afm_param_table(int *n);

/* Resolve "model.damping_ratio[2]" -> entry, index 2; "forces.radius_m" -> entry, -1.
 * 0, or -1 with "unknown parameter 'x' (known: ...)" or a bad index in err. */
int afm_param_lookup(const char *name, int *entry, int *index, char *err, size_t errlen);

/* The canonical name of (entry, index) into buf. */
void afm_param_name(int entry, int index, char *buf, size_t len);

/* Apply the validated param command p to *cfg: cfg is changed only if the result passes
 * afm_config_validate and every parameter fits the config (a force term that is switched
 * off, a beam name on a lumped model, ... are rejected with a reason). *effect (may be
 * NULL) receives the strongest effect among the names (GEOMETRY > DAMPING > FORCE >
 * SEPARATION). Allocates nothing: usable on the real-time thread. 0 or -1 with err. */
int afm_param_apply(afm_config *cfg, const afm_cmd_param *p, afm_param_effect *effect, char *err,
                    size_t errlen);

/* Current value of (entry, index) in cfg (in the name's unit); NAN for a bad entry. */
double afm_param_get(const afm_config *cfg, int entry, int index);

#endif
