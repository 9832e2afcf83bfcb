/* SPDX-License-Identifier: MIT */
/* afm_cmd_lcm.c -- inbound LCM messages into afm_cmd: fingerprint, decode (the C types
 * lcm-gen makes from the msgtypes directory) and validation (contract in afm_cmd.h). */
#include "afm_cmd.h"
#include "afm_err.h"

#include "afmtwin_control_t.h"
#include "afmtwin_dither_t.h"
#include "afmtwin_param_t.h"
#include "afmtwin_setpoint_t.h"
#include "afmtwin_tick_t.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

_Static_assert(AFMTWIN_CONTROL_T_RUN == AFM_CTL_RUN && AFMTWIN_CONTROL_T_PAUSE == AFM_CTL_PAUSE &&
                   AFMTWIN_CONTROL_T_RESET == AFM_CTL_RESET &&
                   AFMTWIN_CONTROL_T_STEP == AFM_CTL_STEP,
               "control_t actions and afm_cmd_action must agree");

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
    default:
        afm_err_set(err, errlen, "%s commands do not come from messages", afm_cmd_kind_name(kind));
        return -1;
    }
    return afm_cmd_validate(c, lim, err, errlen);
}

/* The fingerprint lcm-gen puts in the first 8 bytes (big-endian). */
static int64_t fingerprint(const void *data) {
    const unsigned char *b = data;
    uint64_t v = 0;
    for (int i = 0; i < 8; i++)
        v = (v << 8) | b[i];
    return (int64_t)v;
}

static uint32_t be_u32(const unsigned char *b) {
    return (uint32_t)b[0] << 24 | (uint32_t)b[1] << 16 | (uint32_t)b[2] << 8 | b[3];
}

/* lcm-gen's decode of a string array neither checks the terminator nor survives a failure
 * half-way (the cleanup would free uninitialised pointers), so param bodies are walked here
 * first: hash, utime, seq, int16 n, n strings (int32 length incl. NUL, bytes), n doubles. */
static int param_precheck(const unsigned char *b, size_t len, char *err, size_t errlen) {
    size_t pos = 24;
    if (len < pos + 2) goto trunc;
    int n = (int16_t)((uint16_t)b[pos] << 8 | b[pos + 1]);
    pos += 2;
    if (n < 1 || n > AFM_CMD_MAX_PARAMS) {
        afm_err_set(err, errlen, "param: n %d not in 1..%d", n, AFM_CMD_MAX_PARAMS);
        return -1;
    }
    for (int i = 0; i < n; i++) {
        if (len < pos + 4) goto trunc;
        uint32_t l = be_u32(b + pos);
        pos += 4;
        if (l < 1 || l > 4096) {
            afm_err_set(err, errlen, "param: name %d has a bad length %u", i, (unsigned)l);
            return -1;
        }
        if (len < pos + l) goto trunc;
        if (b[pos + l - 1] != 0 || memchr(b + pos, 0, l - 1)) {
            afm_err_set(err, errlen, "param: name %d is not a proper string", i);
            return -1;
        }
        pos += l;
    }
    if (len < pos + 8 * (size_t)n) goto trunc;
    return 0;
trunc:
    afm_err_set(err, errlen, "param: malformed or truncated message (%zu bytes)", len);
    return -1;
}

/* Decode one type: the generated decode, cleanup, and the common checks. */
#define DECODE(T, kindname)                                                                        \
    do {                                                                                           \
        T m;                                                                                       \
        memset(&m, 0, sizeof m);                                                                   \
        if (fingerprint(data) != __##T##_get_hash()) {                                             \
            afm_err_set(err, errlen,                                                               \
                        "%s: wrong message type on this channel (fingerprint %016llx)", kindname,  \
                        (unsigned long long)fingerprint(data));                                    \
            return -1;                                                                             \
        }                                                                                          \
        if (kind == AFM_CMD_PARAM && param_precheck(data, len, err, errlen)) return -1;            \
        int used = T##_decode(data, 0, (int)len, &m);                                              \
        if (used < 0) {                                                                            \
            afm_err_set(err, errlen, "%s: malformed or truncated message (%zu bytes)", kindname,   \
                        len);                                                                      \
            return -1;                                                                             \
        }                                                                                          \
        int rc = 0;                                                                                \
        if ((size_t)used != len) {                                                                 \
            afm_err_set(err, errlen, "%s: %zu trailing bytes after the message", kindname,         \
                        len - (size_t)used);                                                       \
            rc = -1;                                                                               \
        } else {                                                                                   \
            rc = afm_cmd_from_msg(kind, &m, lim, c, err, errlen);                                  \
        }                                                                                          \
        T##_decode_cleanup(&m);                                                                    \
        return rc;                                                                                 \
    } while (0)

int afm_cmd_decode(afm_cmd_kind kind, const void *data, size_t len, const afm_cmd_limits *lim,
                   afm_cmd *c, char *err, size_t errlen) {
    const char *kn = afm_cmd_kind_name(kind);
    if (!data || len < 8) {
        afm_err_set(err, errlen, "%s: truncated message (%zu bytes, no fingerprint)", kn, len);
        return -1;
    }
    if (len > (1u << 24)) {
        afm_err_set(err, errlen, "%s: message too large (%zu bytes)", kn, len);
        return -1;
    }
    switch (kind) {
    case AFM_CMD_DITHER:
        DECODE(afmtwin_dither_t, kn);
    case AFM_CMD_SETPOINT:
        DECODE(afmtwin_setpoint_t, kn);
    case AFM_CMD_PARAM:
        DECODE(afmtwin_param_t, kn);
    case AFM_CMD_CONTROL:
        DECODE(afmtwin_control_t, kn);
    case AFM_CMD_TICK:
        DECODE(afmtwin_tick_t, kn);
    default:
        break;
    }
    afm_err_set(err, errlen, "%s commands do not come from messages", kn);
    return -1;
}
