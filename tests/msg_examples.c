/* SPDX-License-Identifier: MIT */
/* msg_examples.c -- see msg_examples.h. */
#include "msg_examples.h"

#include "afmtwin_dither_t.h"
#include "afmtwin_harmonics_t.h"
#include "afmtwin_param_t.h"
#include "afmtwin_samples_t.h"
#include "afmtwin_status_t.h"

int ex_samples(uint8_t *b, int cap) {
    float x[3] = {1, 2, 3}, o[3] = {4, 5, 6}, f[3] = {7, 8, 9};
    int32_t cnt[3] = {1, -2, 3};
    afmtwin_samples_t s = {.utime = 5, .seq_applied = 6, .stream = 1, .t0_s = 0.5};
    s.rate_hz = 1e6;
    s.n = 3;
    s.deflection_m = x;
    s.obd_m = o;
    s.obd_counts = cnt;
    s.force_n = f;
    double tf[1] = {3e5}, ta[1] = {3e-11};
    s.separation_m = 2e-8;
    s.n_tones = 1;
    s.tone_frequency_hz = tf;
    s.tone_amplitude_m = ta;
    return afmtwin_samples_t_encode(b, 0, cap, &s);
}

int ex_harmonics(uint8_t *b, int cap) {
    int16_t k[2] = {1, 3};
    double amp[2] = {5e-8, 1e-10}, ph[2] = {90, 10};
    afmtwin_harmonics_t h = {.n = 2, .k = k, .lockin_amplitude_m = 5e-8};
    h.deflection_amplitude_m = h.force_amplitude_n = amp;
    h.deflection_phase_deg = h.deflection_lag_deg = h.force_phase_deg = h.phase_diff_deg = ph;
    double tf[1] = {3e5}, ta[1] = {3e-11};
    h.separation_m = 2e-8;
    h.n_tones = 1;
    h.tone_frequency_hz = tf;
    h.tone_amplitude_m = ta;
    return afmtwin_harmonics_t_encode(b, 0, cap, &h);
}

int ex_status(uint8_t *b, int cap, const char *last_reject) {
    afmtwin_status_t st = {.received = 3, .applied = 2, .rejected = 1};
    st.last_reject = (char *)last_reject;
    st.mode = "realtime";
    st.can_state = "off";
    st.can_last_reject = st.last_refusal = st.last_drop = st.pause_reason = "";
    st.rt_scheme = st.rt_scheme_reason = "";
    st.fm_control = st.fm_drive = "none";
    st.fm_lock_state = "";
    st.scan_mode = "hold"; /* issue 18 */
    st.am_control = "none";
    return afmtwin_status_t_encode(b, 0, cap, &st);
}

int ex_dither(uint8_t *b, int cap, int n_tones) {
    double f[4] = {338112, 2.07e6, 3e5, 1e6}, a[4] = {0.087e-9, 1e-11, 0, 0}, p[4] = {0};
    afmtwin_dither_t d = {.utime = 1, .seq = 7, .n_tones = (int8_t)n_tones};
    d.frequency_hz = f;
    d.amplitude_m = a;
    d.phase_rad = p;
    return afmtwin_dither_t_encode(b, 0, cap, &d);
}

int ex_param(uint8_t *b, int cap) {
    const char *names[2] = {"forces.radius_m", "drive.separation_m"};
    double v[2] = {1e-8, 3e-8};
    afmtwin_param_t m = {.utime = 1, .seq = 9, .n = 2, .name = (char **)names, .value = v};
    return afmtwin_param_t_encode(b, 0, cap, &m);
}
