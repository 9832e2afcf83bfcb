/* SPDX-License-Identifier: MIT */
/* afm_can_codec.c -- CAN frames of the piezo-driver map to afm_cmd commands and back
 * (contract in afm_can_codec.h, frame layouts in docs/can.md). */
#include "transport/afm_can_codec.h"
#include "config/afm_err.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

static const char *const sig_names[AFM_CAN_N_SIGNALS] = {
    "dither_frequency", "dither_amplitude", "dither_phase", "setpoint", "enable", "heartbeat"};

const char *afm_can_signal_name(afm_can_signal sig) {
    return (int)sig >= 0 && sig < AFM_CAN_N_SIGNALS ? sig_names[sig] : "?";
}

static size_t signal_len(afm_can_signal sig) {
    return sig == AFM_CAN_ENABLE || sig == AFM_CAN_HEARTBEAT ? 1 : 8;
}

void afm_can_state_init(afm_can_state *s, const afm_cfg_drive *d) {
    memset(s, 0, sizeof *s);
    s->dither.n_tones = d->n_tones;
    for (int j = 0; j < d->n_tones && j < AFM_MAX_TONES; j++) {
        s->dither.frequency_hz[j] = d->tones[j].frequency_hz;
        s->dither.amplitude_m[j] = d->tones[j].amplitude_m;
        s->dither.phase_rad[j] = d->tones[j].phase_rad;
    }
}

void afm_can_state_sync(afm_can_state *s, const afm_cmd_dither *running) {
    int n = running->n_tones < AFM_MAX_TONES ? running->n_tones : AFM_MAX_TONES;
    for (int j = 0; j < n; j++) {
        s->dither.frequency_hz[j] = running->frequency_hz[j];
        s->dither.amplitude_m[j] = running->amplitude_m[j];
    }
    s->dither.n_tones = n; /* the start phases of the tones not running stay the driver's */
}

int afm_can_signal_of(const afm_cfg_can *map, canid_t id) {
    bool eff = (id & CAN_EFF_FLAG) != 0;
    if (eff != map->extended_ids) return -1;
    canid_t raw = id & (eff ? CAN_EFF_MASK : CAN_SFF_MASK);
    for (int i = 0; i < AFM_CAN_N_SIGNALS; i++)
        if (map->id[i] == raw) return i;
    return -1;
}

static uint32_t get_u32(const uint8_t *b, bool big) {
    if (big) return (uint32_t)b[0] << 24 | (uint32_t)b[1] << 16 | (uint32_t)b[2] << 8 | b[3];
    return (uint32_t)b[3] << 24 | (uint32_t)b[2] << 16 | (uint32_t)b[1] << 8 | b[0];
}

static void put_u32(uint8_t *b, uint32_t v, bool big) {
    for (int i = 0; i < 4; i++)
        b[big ? 3 - i : i] = (uint8_t)(v >> (8 * i));
}

/* Scale (SI per bit) of a 4-byte value: which = 0 the first, 1 the second of the frame. */
static double scale_of(const afm_cfg_can *m, afm_can_signal sig, int which) {
    switch (sig) {
    case AFM_CAN_DITHER_FREQUENCY:
        return m->scale_frequency_hz;
    case AFM_CAN_DITHER_AMPLITUDE:
        return m->scale_amplitude_m;
    case AFM_CAN_DITHER_PHASE:
        return m->scale_phase_rad;
    case AFM_CAN_SETPOINT:
        return which ? m->scale_ramp_m_s : m->scale_separation_m;
    default:
        return 1.0;
    }
}

/* The 4-byte value at b in SI; -1 for a float that is NaN or infinite. */
static int get_value(const afm_cfg_can *m, afm_can_signal sig, int which, const uint8_t *b,
                     double *out) {
    uint32_t u = get_u32(b, m->big_endian);
    if (m->encoding == AFM_CAN_FLOAT32) {
        float f;
        memcpy(&f, &u, sizeof f);
        *out = f;
        return isfinite(f) ? 0 : -1;
    }
    double raw = sig == AFM_CAN_DITHER_PHASE ? (double)(int32_t)u : (double)u;
    *out = raw * scale_of(m, sig, which);
    return 0;
}

static int put_value(const afm_cfg_can *m, afm_can_signal sig, int which, double v, uint8_t *b,
                     const char *what, char *err, size_t errlen) {
    if (!isfinite(v)) {
        afm_err_set(err, errlen, "%s: %s is not a finite number", afm_can_signal_name(sig), what);
        return -1;
    }
    uint32_t u;
    if (m->encoding == AFM_CAN_FLOAT32) {
        if (fabs(v) > FLT_MAX) {
            afm_err_set(err, errlen, "%s: %s %g does not fit a float32", afm_can_signal_name(sig),
                        what, v);
            return -1;
        }
        float f = (float)v;
        memcpy(&u, &f, sizeof u);
    } else {
        double s = scale_of(m, sig, which), raw = nearbyint(v / s);
        bool is_signed = sig == AFM_CAN_DITHER_PHASE;
        double lo = is_signed ? (double)INT32_MIN : 0.0;
        double hi = is_signed ? (double)INT32_MAX : (double)UINT32_MAX;
        if (!(raw >= lo && raw <= hi)) {
            afm_err_set(err, errlen,
                        "%s: %s %g is outside what the signal carries (%g .. %g at "
                        "%g per bit)",
                        afm_can_signal_name(sig), what, v, lo * s, hi * s, s);
            return -1;
        }
        u = is_signed ? (uint32_t)(int32_t)raw : (uint32_t)raw;
    }
    put_u32(b, u, m->big_endian);
    return 0;
}

static void id_text(canid_t id, char *buf, size_t len) {
    if (id & CAN_EFF_FLAG)
        snprintf(buf, len, "0x%08X", (unsigned)(id & CAN_EFF_MASK));
    else
        snprintf(buf, len, "0x%03X", (unsigned)(id & CAN_SFF_MASK));
}

/* A dither frame (frequency or amplitude) for tone t with value v: the new registers and
 * the whole dither command. */
static afm_can_result dither_cmd(afm_can_signal sig, int t, double v, const afm_can_state *st,
                                 const afm_cmd_limits *lim, afm_cmd *cmd, afm_can_state *next,
                                 const char *pre, char *err, size_t errlen) {
    afm_can_state n = *st;
    afm_cmd_dither *d = &n.dither;
    if (sig == AFM_CAN_DITHER_FREQUENCY)
        d->frequency_hz[t] = v;
    else
        d->amplitude_m[t] = v;
    if (t >= d->n_tones) {
        for (int j = d->n_tones; j <= t; j++)
            if (!(d->frequency_hz[j] > 0)) {
                afm_err_set(err, errlen,
                            "%s: tone %d would start tone %d, which has no frequency "
                            "yet (send tone %d's dither_frequency first)",
                            pre, t, j, j);
                return AFM_CAN_R_REJECT;
            }
        d->n_tones = t + 1;
    }
    afm_cmd c;
    memset(&c, 0, sizeof c);
    c.kind = AFM_CMD_DITHER;
    c.u.dither = *d;
    char why[AFM_ERR_LEN];
    if (afm_cmd_validate(&c, lim, why, sizeof why)) {
        afm_err_set(err, errlen, "%s: %s", pre, why);
        return AFM_CAN_R_REJECT;
    }
    *cmd = c;
    *next = n;
    return AFM_CAN_R_COMMAND;
}

afm_can_result afm_can_decode(const afm_cfg_can *map, const afm_can_state *state,
                              const struct canfd_frame *f, bool fd, const afm_cmd_limits *lim,
                              afm_cmd *cmd, afm_can_state *next, int *state_byte, char *err,
                              size_t errlen) {
    char idt[16], pre[64];
    if (!map || !state || !f || !cmd || !next) {
        afm_err_set(err, errlen, "afm_can_decode: NULL argument");
        return AFM_CAN_R_REJECT;
    }
    id_text(f->can_id, idt, sizeof idt);
    if (f->can_id & CAN_ERR_FLAG) {
        afm_err_set(err, errlen, "id %s: error frame, not a command", idt);
        return AFM_CAN_R_REJECT;
    }
    if (f->can_id & CAN_RTR_FLAG) {
        afm_err_set(err, errlen, "id %s: remote (RTR) frame, not a command", idt);
        return AFM_CAN_R_REJECT;
    }
    if (fd && !map->fd) {
        afm_err_set(err, errlen, "id %s: CAN FD frame, but can.fd = false", idt);
        return AFM_CAN_R_REJECT;
    }
    int s = afm_can_signal_of(map, f->can_id);
    if (s < 0) {
        bool other = ((f->can_id & CAN_EFF_FLAG) != 0) != map->extended_ids;
        afm_err_set(err, errlen, "id %s: unknown frame id (%s)", idt,
                    other ? (map->extended_ids ? "an 11-bit id; the map uses 29-bit ids"
                                               : "a 29-bit id; the map uses 11-bit ids")
                          : "not in the can.ids map");
        return AFM_CAN_R_REJECT;
    }
    afm_can_signal sig = (afm_can_signal)s;
    snprintf(pre, sizeof pre, "id %s %s", idt, sig_names[sig]);
    size_t want = signal_len(sig);
    if (f->len != want) {
        afm_err_set(err, errlen, "%s: length %u, want %zu", pre, (unsigned)f->len, want);
        return AFM_CAN_R_REJECT;
    }
    const uint8_t *b = f->data;
    switch (sig) {
    case AFM_CAN_DITHER_FREQUENCY:
    case AFM_CAN_DITHER_AMPLITUDE:
    case AFM_CAN_DITHER_PHASE: {
        int t = b[0];
        double v;
        if (t >= AFM_MAX_TONES) {
            afm_err_set(err, errlen, "%s: tone %d not in 0..%d", pre, t, AFM_MAX_TONES - 1);
            return AFM_CAN_R_REJECT;
        }
        if (get_value(map, sig, 0, b + 4, &v)) {
            afm_err_set(err, errlen, "%s: tone %d value is NaN or infinite", pre, t);
            return AFM_CAN_R_REJECT;
        }
        if (sig != AFM_CAN_DITHER_PHASE)
            return dither_cmd(sig, t, v, state, lim, cmd, next, pre, err, errlen);
        if (!(fabs(v) <= AFM_CAN_MAX_PHASE_RAD)) {
            afm_err_set(err, errlen, "%s: tone %d phase %g rad not in -2 pi .. 2 pi", pre, t, v);
            return AFM_CAN_R_REJECT;
        }
        if (t < state->dither.n_tones) {
            afm_err_set(err, errlen,
                        "%s: tone %d is running; the drive is phase-continuous, so a "
                        "phase only sets the start of a tone not yet running",
                        pre, t);
            return AFM_CAN_R_REJECT;
        }
        *next = *state;
        next->dither.phase_rad[t] = v;
        return AFM_CAN_R_STORED;
    }
    case AFM_CAN_SETPOINT: {
        double z, r;
        if (get_value(map, sig, 0, b, &z) || get_value(map, sig, 1, b + 4, &r)) {
            afm_err_set(err, errlen, "%s: value is NaN or infinite", pre);
            return AFM_CAN_R_REJECT;
        }
        afm_cmd c;
        memset(&c, 0, sizeof c);
        c.kind = AFM_CMD_SETPOINT;
        c.u.setpoint.separation_m = z;
        c.u.setpoint.ramp_rate_m_s = r;
        char why[AFM_ERR_LEN];
        if (afm_cmd_validate(&c, lim, why, sizeof why)) {
            afm_err_set(err, errlen, "%s: %s", pre, why);
            return AFM_CAN_R_REJECT;
        }
        *cmd = c;
        *next = *state;
        return AFM_CAN_R_COMMAND;
    }
    case AFM_CAN_ENABLE: {
        if (b[0] > 1) {
            afm_err_set(err, errlen, "%s: byte 0x%02X is neither 1 (enable) nor 0 (disable)", pre,
                        b[0]);
            return AFM_CAN_R_REJECT;
        }
        afm_cmd c;
        memset(&c, 0, sizeof c);
        c.kind = AFM_CMD_CONTROL;
        c.u.control.action = b[0] ? AFM_CTL_RUN : AFM_CTL_PAUSE;
        *cmd = c;
        *next = *state;
        return AFM_CAN_R_COMMAND;
    }
    case AFM_CAN_HEARTBEAT:
        if (state_byte) *state_byte = b[0];
        *next = *state;
        return AFM_CAN_R_HEARTBEAT;
    case AFM_CAN_N_SIGNALS:
        break;
    }
    afm_err_set(err, errlen, "%s: no decoder", pre);
    return AFM_CAN_R_REJECT;
}

int afm_can_encode(const afm_cfg_can *map, afm_can_signal sig, int tone, double v0, double v1,
                   struct canfd_frame *f, char *err, size_t errlen) {
    if (!map || !f || (int)sig < 0 || sig >= AFM_CAN_N_SIGNALS) {
        afm_err_set(err, errlen, "afm_can_encode: bad argument");
        return -1;
    }
    memset(f, 0, sizeof *f);
    f->can_id = map->extended_ids ? (map->id[sig] & CAN_EFF_MASK) | CAN_EFF_FLAG
                                  : map->id[sig] & CAN_SFF_MASK;
    f->len = (uint8_t)signal_len(sig);
    switch (sig) {
    case AFM_CAN_DITHER_FREQUENCY:
    case AFM_CAN_DITHER_AMPLITUDE:
    case AFM_CAN_DITHER_PHASE:
        if (tone < 0 || tone >= AFM_MAX_TONES) {
            afm_err_set(err, errlen, "%s: tone %d not in 0..%d", sig_names[sig], tone,
                        AFM_MAX_TONES - 1);
            return -1;
        }
        f->data[0] = (uint8_t)tone;
        return put_value(map, sig, 0, v0, f->data + 4,
                         sig == AFM_CAN_DITHER_FREQUENCY   ? "frequency"
                         : sig == AFM_CAN_DITHER_AMPLITUDE ? "amplitude"
                                                           : "phase",
                         err, errlen);
    case AFM_CAN_SETPOINT:
        return put_value(map, sig, 0, v0, f->data, "separation", err, errlen) ||
                       put_value(map, sig, 1, v1, f->data + 4, "ramp rate", err, errlen)
                   ? -1
                   : 0;
    case AFM_CAN_ENABLE:
        if (v0 != 0 && v0 != 1) {
            afm_err_set(err, errlen, "enable: %g is neither 1 (enable) nor 0 (disable)", v0);
            return -1;
        }
        f->data[0] = (uint8_t)v0;
        return 0;
    case AFM_CAN_HEARTBEAT:
        if (!(v0 >= 0 && v0 <= 255) || v0 != floor(v0)) {
            afm_err_set(err, errlen, "heartbeat: state %g is not a byte 0..255", v0);
            return -1;
        }
        f->data[0] = (uint8_t)v0;
        return 0;
    case AFM_CAN_N_SIGNALS:
        break;
    }
    return -1;
}

void afm_can_format(const struct canfd_frame *f, bool fd, char *buf, size_t len) {
    size_t n = 0;
    int w;
    if (f->can_id & CAN_EFF_FLAG)
        w = snprintf(buf, len, "%08X#", (unsigned)(f->can_id & CAN_EFF_MASK));
    else
        w = snprintf(buf, len, "%03X#", (unsigned)(f->can_id & CAN_SFF_MASK));
    if (w < 0 || (size_t)w >= len) return;
    n = (size_t)w;
    if (fd) {
        w = snprintf(buf + n, len - n, "#%X", (unsigned)(f->flags & 0xF));
        if (w < 0 || (size_t)w >= len - n) return;
        n += (size_t)w;
    }
    unsigned l = f->len <= CANFD_MAX_DLEN ? f->len : CANFD_MAX_DLEN;
    for (unsigned i = 0; i < l && n + 3 <= len; i++) {
        snprintf(buf + n, len - n, "%02X", f->data[i]);
        n += 2;
    }
}
