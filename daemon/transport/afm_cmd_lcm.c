/* SPDX-License-Identifier: MIT */
/* afm_cmd_lcm.c -- inbound LCM messages into afm_cmd: fingerprint, decode (the C types
 * lcm-gen makes from the msgtypes directory, behind the length checks of afm_lcm_wire.h) and
 * validation (contract in afm_cmd.h). */
#include "transport/afm_cmd_lcm.h"
#include "config/afm_err.h"
#include "transport/afm_lcm_wire.h"

#include "afmtwin_control_t.h"
#include "afmtwin_dither_t.h"
#include "afmtwin_param_t.h"
#include "afmtwin_scan_t.h"
#include "afmtwin_setpoint_t.h"
#include "afmtwin_tick_t.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

_Static_assert(AFMTWIN_CONTROL_T_RUN == AFM_CTL_RUN && AFMTWIN_CONTROL_T_PAUSE == AFM_CTL_PAUSE &&
                   AFMTWIN_CONTROL_T_RESET == AFM_CTL_RESET &&
                   AFMTWIN_CONTROL_T_STEP == AFM_CTL_STEP,
               "control_t actions and afm_cmd_action must agree");
_Static_assert(AFMTWIN_SCAN_T_HOLD == AFM_SCAN_HOLD && AFMTWIN_SCAN_T_MOVE == AFM_SCAN_MOVE &&
                   AFMTWIN_SCAN_T_VELOCITY == AFM_SCAN_VELOCITY &&
                   AFMTWIN_SCAN_T_RASTER == AFM_SCAN_RASTER,
               "scan_t modes and afm_scan_mode must agree");

static int from_dither(const afmtwin_dither_t *m, afm_cmd *c, char *err, size_t errlen) {
    if (m->n_tones < 1 || m->n_tones > AFM_MAX_TONES) {
        afm_err_set(err, errlen, "dither: n_tones %d not in 1..%d", m->n_tones, AFM_MAX_TONES);
        return -1;
    }
    c->u.dither.n_tones = m->n_tones;
    for (int j = 0; j < m->n_tones; j++) {
        c->u.dither.frequency_hz[j] = m->frequency_hz[j];
        c->u.dither.amplitude_m[j] = m->amplitude_m[j];
        c->u.dither.phase_rad[j] = m->phase_rad[j];
    }
    return 0;
}

static int from_param(const afmtwin_param_t *m, afm_cmd *c, char *err, size_t errlen) {
    if (m->n < 1 || m->n > AFM_CMD_MAX_PARAMS) {
        afm_err_set(err, errlen, "param: n %d not in 1..%d", m->n, AFM_CMD_MAX_PARAMS);
        return -1;
    }
    c->u.param.n = m->n;
    for (int i = 0; i < m->n; i++) {
        char why[AFM_ERR_LEN];
        if (afm_param_lookup(m->name[i], &c->u.param.entry[i], &c->u.param.index[i], why,
                             sizeof why)) {
            afm_err_set(err, errlen, "param: %s", why);
            return -1;
        }
        c->u.param.value[i] = m->value[i];
    }
    return 0;
}

int afm_cmd_from_msg(afm_cmd_kind kind, const void *msg, const afm_cmd_limits *lim, afm_cmd *c,
                     char *err, size_t errlen) {
    if (!msg || !c) {
        afm_err_set(err, errlen, "no message");
        return -1;
    }
    memset(c, 0, sizeof *c);
    c->kind = kind;
    switch (kind) {
    case AFM_CMD_DITHER: {
        const afmtwin_dither_t *m = msg;
        c->seq = m->seq;
        c->utime = m->utime;
        if (from_dither(m, c, err, errlen)) return -1;
        break;
    }
    case AFM_CMD_SETPOINT: {
        const afmtwin_setpoint_t *m = msg;
        c->seq = m->seq;
        c->utime = m->utime;
        c->u.setpoint.separation_m = m->separation_m;
        c->u.setpoint.ramp_rate_m_s = m->ramp_rate_m_s;
        break;
    }
    case AFM_CMD_PARAM: {
        const afmtwin_param_t *m = msg;
        c->seq = m->seq;
        c->utime = m->utime;
        if (from_param(m, c, err, errlen)) return -1;
        break;
    }
    case AFM_CMD_CONTROL: {
        const afmtwin_control_t *m = msg;
        c->seq = m->seq;
        c->utime = m->utime;
        c->u.control.action = m->action;
        c->u.control.n_samples = m->n_samples;
        break;
    }
    case AFM_CMD_TICK: {
        const afmtwin_tick_t *m = msg;
        c->seq = m->seq;
        c->utime = m->utime;
        c->u.tick.n_samples = m->n_samples;
        break;
    }
    case AFM_CMD_SCAN: {
        const afmtwin_scan_t *m = msg;
        c->seq = m->seq;
        c->utime = m->utime;
        c->u.scan = (afm_cmd_lateral){.mode = m->mode,
                                      .x_m = m->x_m,
                                      .y_m = m->y_m,
                                      .speed_m_s = m->speed_m_s,
                                      .vx_m_s = m->vx_m_s,
                                      .vy_m_s = m->vy_m_s,
                                      .size_x_m = m->size_x_m,
                                      .size_y_m = m->size_y_m,
                                      .lines = m->lines,
                                      .pixels = m->pixels,
                                      .line_rate_hz = m->line_rate_hz};
        break;
    }
    default:
        afm_err_set(err, errlen, "%s commands do not come from messages", afm_cmd_kind_name(kind));
        return -1;
    }
    return afm_cmd_validate(c, lim, err, errlen);
}

const char *afm_cmd_channel_suffix(afm_cmd_kind kind) {
    switch (kind) {
    case AFM_CMD_DITHER:
        return "DITHER";
    case AFM_CMD_SETPOINT:
        return "SETPOINT";
    case AFM_CMD_PARAM:
        return "PARAM";
    case AFM_CMD_CONTROL:
        return "CONTROL";
    case AFM_CMD_TICK:
        return "TICK";
    case AFM_CMD_SCAN:
        return "SCAN";
    default:
        return NULL;
    }
}

int afm_cmd_encode(const afm_cmd *c, void *buf, int cap) {
    switch (c->kind) {
    case AFM_CMD_DITHER: {
        const afm_cmd_dither *q = &c->u.dither;
        afmtwin_dither_t m = {.utime = c->utime,
                              .seq = c->seq,
                              .n_tones = (int8_t)q->n_tones,
                              .frequency_hz = (double *)q->frequency_hz,
                              .amplitude_m = (double *)q->amplitude_m,
                              .phase_rad = (double *)q->phase_rad};
        if (afmtwin_dither_t_encoded_size(&m) > cap) return -1;
        return afmtwin_dither_t_encode(buf, 0, cap, &m);
    }
    case AFM_CMD_SETPOINT: {
        afmtwin_setpoint_t m = {.utime = c->utime,
                                .seq = c->seq,
                                .separation_m = c->u.setpoint.separation_m,
                                .ramp_rate_m_s = c->u.setpoint.ramp_rate_m_s};
        if (afmtwin_setpoint_t_encoded_size(&m) > cap) return -1;
        return afmtwin_setpoint_t_encode(buf, 0, cap, &m);
    }
    case AFM_CMD_PARAM: {
        const afm_cmd_param *q = &c->u.param;
        char names[AFM_CMD_MAX_PARAMS][AFM_CMD_NAME_LEN];
        char *np[AFM_CMD_MAX_PARAMS];
        double v[AFM_CMD_MAX_PARAMS];
        int n = q->n < AFM_CMD_MAX_PARAMS ? q->n : AFM_CMD_MAX_PARAMS;
        for (int i = 0; i < n; i++) {
            afm_param_name(q->entry[i], q->index[i], names[i], sizeof names[i]);
            np[i] = names[i];
            v[i] = q->value[i];
        }
        afmtwin_param_t m = {
            .utime = c->utime, .seq = c->seq, .n = (int16_t)n, .name = np, .value = v};
        if (afmtwin_param_t_encoded_size(&m) > cap) return -1;
        return afmtwin_param_t_encode(buf, 0, cap, &m);
    }
    case AFM_CMD_CONTROL: {
        afmtwin_control_t m = {.utime = c->utime,
                               .seq = c->seq,
                               .action = (int8_t)c->u.control.action,
                               .n_samples = c->u.control.n_samples};
        if (afmtwin_control_t_encoded_size(&m) > cap) return -1;
        return afmtwin_control_t_encode(buf, 0, cap, &m);
    }
    case AFM_CMD_TICK: {
        afmtwin_tick_t m = {.utime = c->utime, .seq = c->seq, .n_samples = c->u.tick.n_samples};
        if (afmtwin_tick_t_encoded_size(&m) > cap) return -1;
        return afmtwin_tick_t_encode(buf, 0, cap, &m);
    }
    case AFM_CMD_SCAN: {
        const afm_cmd_lateral *q = &c->u.scan;
        afmtwin_scan_t m = {.utime = c->utime,
                            .seq = c->seq,
                            .mode = (int8_t)q->mode,
                            .x_m = q->x_m,
                            .y_m = q->y_m,
                            .speed_m_s = q->speed_m_s,
                            .vx_m_s = q->vx_m_s,
                            .vy_m_s = q->vy_m_s,
                            .size_x_m = q->size_x_m,
                            .size_y_m = q->size_y_m,
                            .lines = q->lines,
                            .pixels = q->pixels,
                            .line_rate_hz = q->line_rate_hz};
        if (afmtwin_scan_t_encoded_size(&m) > cap) return -1;
        return afmtwin_scan_t_encode(buf, 0, cap, &m);
    }
    default:
        return -1;
    }
}

/* The wire type of each command kind (afm_lcm_wire.h). */
static const afm_wire_type *wire_type(afm_cmd_kind kind) {
    switch (kind) {
    case AFM_CMD_DITHER:
        return &afm_wire_dither_t;
    case AFM_CMD_SETPOINT:
        return &afm_wire_setpoint_t;
    case AFM_CMD_PARAM:
        return &afm_wire_param_t;
    case AFM_CMD_CONTROL:
        return &afm_wire_control_t;
    case AFM_CMD_TICK:
        return &afm_wire_tick_t;
    case AFM_CMD_SCAN:
        return &afm_wire_scan_t;
    default:
        return NULL;
    }
}

int afm_cmd_decode(afm_cmd_kind kind, const void *data, size_t len, const afm_cmd_limits *lim,
                   afm_cmd *c, char *err, size_t errlen) {
    const char *kn = afm_cmd_kind_name(kind);
    const afm_wire_type *t = wire_type(kind);
    if (!t) {
        afm_err_set(err, errlen, "%s commands do not come from messages", kn);
        return -1;
    }
    /* The largest command type; the checked decode frees what it allocated on every path,
     * and afm_wire_free after afm_cmd_from_msg frees the rest. */
    union {
        afmtwin_dither_t dither;
        afmtwin_setpoint_t setpoint;
        afmtwin_param_t param;
        afmtwin_control_t control;
        afmtwin_tick_t tick;
        afmtwin_scan_t scan;
    } m;
    char why[AFM_ERR_LEN];
    if (afm_wire_decode(t, data, len, &m, why, sizeof why)) {
        afm_err_set(err, errlen, "%s: %s", kn, why);
        return -1;
    }
    int rc = afm_cmd_from_msg(kind, &m, lim, c, err, errlen);
    afm_wire_free(t, &m);
    return rc;
}
