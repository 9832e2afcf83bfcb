/* SPDX-License-Identifier: MIT */
/* afm_lcm_encode.c -- output records to generated LCM messages (contract in
 * afm_lcm_encode.h). */
#include "transport/afm_lcm_encode.h"

#include <string.h>

void afm_lcm_samples_msg(const afm_io_samples *s, afmtwin_samples_t *m) {
    *m = (afmtwin_samples_t){
        .utime = s->utime,
        .seq_applied = s->seq_applied,
        .stream = (int8_t)s->stream,
        .t0_s = s->t0_s,
        .rate_hz = s->rate_hz,
        .n = s->n,
        .deflection_m = (float *)s->deflection_m,
        .obd_m = (float *)s->obd_m,
        .obd_counts = (int32_t *)s->obd_counts,
        .force_n = (float *)s->force_n,
        .separation_m = s->op.z_m,
        .n_tones = (int8_t)s->op.n_tones,
        .tone_frequency_hz = (double *)s->op.freq_hz,
        .tone_amplitude_m = (double *)s->op.amp_m,
        .decimation = s->decimation,
        .passband_hz = s->passband_hz,
        .stopband_hz = s->stopband_hz,
    };
}

void afm_lcm_harmonics_msg(const afm_io_harmonics *h, afm_lcm_harm_buf *b, afmtwin_harmonics_t *m) {
    const afm_harm_result *r = &h->p.harm;
    const afm_cycle_metrics *c = &h->p.cycle;
    int n = r->n_harmonics;
    if (n < 0) n = 0;
    if (n > AFM_MAX_HARMONICS) n = AFM_MAX_HARMONICS;
    for (int i = 0; i < n; i++) {
        b->k[i] = (int16_t)r->h[i].k;
        b->xa[i] = r->h[i].x_amp_m;
        b->xp[i] = r->h[i].x_phase_deg;
        b->xl[i] = afm_orbit_lag_deg(r->h[i].x_phase_deg);
        b->fa[i] = r->h[i].f_amp_n;
        b->fp[i] = r->h[i].f_phase_deg;
        b->pd[i] = r->h[i].phase_diff_deg;
    }
    *m = (afmtwin_harmonics_t){
        .utime = h->utime,
        .seq_applied = h->seq_applied,
        .t_s = c->t_start_s,
        .fe_hz = h->fe_hz,
        .n = (int8_t)n,
        .k = b->k,
        .deflection_amplitude_m = b->xa,
        .deflection_phase_deg = b->xp,
        .deflection_lag_deg = b->xl,
        .force_amplitude_n = b->fa,
        .force_phase_deg = b->fp,
        .phase_diff_deg = b->pd,
        .lockin_amplitude_m = h->p.lockin_amplitude_m,
        .lockin_phase_deg = h->p.lockin_phase_deg,
        .peak_force_n = c->peak_force_n,
        .min_deflection_m = c->min_deflection_m,
        .indentation_m = c->indentation_m,
        .contact_time_s = c->contact_time_s,
        .pre_contact_velocity_m_s = c->pre_contact_velocity_m_s,
        .dissipated_energy_j = c->dissipated_energy_j,
        .mean_deflection_m = c->mean_deflection_m,
        .squeeze_dissipated_energy_j = c->squeeze_dissipated_energy_j,
        .separation_m = h->op.z_m,
        .n_tones = (int8_t)h->op.n_tones,
        .tone_frequency_hz = (double *)h->op.freq_hz,
        .tone_amplitude_m = (double *)h->op.amp_m,
        .tip_x_m = h->op.tip_x_m, /* issue 18 */
        .tip_y_m = h->op.tip_y_m,
        .true_height_m = h->op.true_height_m,
        .material = (int8_t)h->op.material,
        .fm_lock_state = (int8_t)h->op.fm_lock, /* issue 32 */
        .fm_drive = (int8_t)h->op.fm_drive,
        .fm_frequency_shift_hz = h->op.fm_shift_hz,
        .fm_phase_error_deg = h->op.fm_phase_error_deg,
    };
}

void afm_lcm_status_msg(const afm_io_status *s, afmtwin_status_t *m) {
    *m = (afmtwin_status_t){
        .utime = s->utime,
        .seq_applied = s->seq_applied,
        .model_time_s = s->model_time_s,
        .realtime_factor = s->realtime_factor,
        .overruns = s->overruns,
        .lag_s = s->lag_s,
        .received = s->received,
        .rejected = s->rejected,
        .last_reject = (char *)s->last_reject,
        .blowups = s->blowups,
        .mode = (char *)(s->mode ? s->mode : ""),
        .running = (int8_t)s->running,
        .separation_m = s->separation_m,
        .fe_hz = s->fe_hz,
        .amplitude_m = s->amplitude_m,
        .applied = s->applied,
        .resyncs = s->resyncs,
        .chain_stalls = s->chain_stalls,
        .chain_lag_s = s->chain_lag_s,
        .can_state = (char *)(s->can_state[0] ? s->can_state : "off"), /* issue 6 */
        .can_frames = s->can_frames,
        .can_rejected = s->can_rejected,
        .can_errors = s->can_errors,
        .can_reconnects = s->can_reconnects,
        .can_last_reject = (char *)s->can_last_reject,
        .heartbeat_ok = (int8_t)s->heartbeat_ok,
        .refused = s->refused, /* issue 13 */
        .last_refusal = (char *)s->last_refusal,
        .dropped = s->dropped,
        .last_drop = (char *)s->last_drop,
        .auto_paused = (int8_t)s->auto_paused,
        .pause_reason = (char *)s->pause_reason,
        .realtime_factor_1s = s->realtime_factor_1s,
        .resync_skipped_s = s->resync_skipped_s,
        .lockin_amplitude_m = s->lockin_amplitude_m,
        .lockin_phase_deg = s->lockin_phase_deg,
        .peak_force_n = s->peak_force_n,
        .last_reject_age_s = s->last_reject_age_s,
        .last_reject_old = (int8_t)s->last_reject_old,
        .rt_scheme = (char *)s->rt_scheme,
        .rt_scheme_reason = (char *)s->rt_scheme_reason,
        .scheme_handovers = s->scheme_handovers,
        .model_s_accurate = s->model_s_accurate,
        .model_s_fast = s->model_s_fast,
        .fm_control = (char *)(s->fm_control ? s->fm_control : "none"), /* issue 32 */
        .fm_drive = (char *)(s->fm_drive ? s->fm_drive : "none"),
        .fm_lock_state = (char *)(s->fm_lock_state ? s->fm_lock_state : ""),
        .fm_frequency_hz = s->fm_frequency_hz,
        .fm_reference_hz = s->fm_reference_hz,
        .fm_frequency_shift_hz = s->fm_frequency_shift_hz,
        .fm_phase_error_deg = s->fm_phase_error_deg,
        .fm_drive_amplitude_m = s->fm_drive_amplitude_m,
        .fm_amplitude_m = s->fm_amplitude_m,
        .fm_amplitude_setpoint_m = s->fm_amplitude_setpoint_m,
        .fm_tone_changes = s->fm_tone_changes,
        .squeeze_dissipated_energy_j = s->squeeze_dissipated_energy_j, /* issue 30 */
        .sample_on = (int8_t)s->sample_on,                             /* issue 18 */
        .tip_x_m = s->tip_x_m,
        .tip_y_m = s->tip_y_m,
        .true_height_m = s->true_height_m,
        .material = (int8_t)s->material,
        .scan_mode = (char *)(s->scan_mode ? s->scan_mode : "hold"),
        .scan_line = s->scan_line,
        .scan_pixel = s->scan_pixel,
        .scan_retrace = (int8_t)s->scan_retrace,
        .am_control = (char *)(s->am_control ? s->am_control : "none"),
        .am_z_m = s->am_z_m,
        .am_error_m = s->am_error_m,
        .am_setpoint_m = s->am_setpoint_m,
        .am_amplitude_m = s->am_amplitude_m,
        .free_amplitude_m = s->free_amplitude_m, /* issue 30 */
        .amplitude_ratio = s->amplitude_ratio,
        .tick_resends = s->tick_resends, /* lockstep re-sends */
        .republished = s->republished,
    };
}

void afm_lcm_tick_done_msg(const afm_io_tick_done *d, afmtwin_tick_done_t *m) {
    *m = (afmtwin_tick_done_t){.utime = d->utime,
                               .seq = d->seq,
                               .samples = d->samples,
                               .model_time_s = d->model_time_s,
                               .n_samples_msgs = d->n_samples_msgs,
                               .n_harmonics_msgs = d->n_harmonics_msgs,
                               .samples_digest = (int64_t)d->samples_digest,
                               .harmonics_digest = (int64_t)d->harmonics_digest};
}

/* ---- digest ---- */

#define DIGEST_SEED 0xcbf29ce484222325ULL

/* One 64-bit word into h: xor, multiply by the FNV prime, fold the high half down (the
 * multiply alone would leave the low bits of h depending on the low bits of the words only). */
static inline uint64_t mix(uint64_t h, uint64_t w) {
    h = (h ^ w) * 0x100000001b3ULL;
    return h ^ (h >> 29);
}

static inline uint64_t bits_d(double v) {
    uint64_t u;
    memcpy(&u, &v, sizeof u);
    return u;
}

static inline uint64_t bits_f(float v) {
    uint32_t u;
    memcpy(&u, &v, sizeof u);
    return u;
}

void afm_lcm_digest_init(afm_lcm_digest *d) {
    for (int i = 0; i < AFM_LCM_DIGEST_STREAMS; i++)
        d->stream[i] = DIGEST_SEED;
    d->harmonics = DIGEST_SEED;
    d->n_samples_msgs = d->n_harmonics_msgs = 0;
}

void afm_lcm_digest_samples(afm_lcm_digest *d, const afmtwin_samples_t *m) {
    int s = m->stream >= 0 && m->stream < AFM_LCM_DIGEST_STREAMS ? m->stream : 0;
    uint64_t h = d->stream[s];
    for (int i = 0; i < m->n; i++) {
        h = mix(h, (uint64_t)m->seq_applied);
        h = mix(h, bits_f(m->deflection_m[i]) | bits_f(m->obd_m[i]) << 32);
        h = mix(h, (uint64_t)(uint32_t)m->obd_counts[i] | bits_f(m->force_n[i]) << 32);
    }
    d->stream[s] = h;
    d->n_samples_msgs++;
}

void afm_lcm_digest_harmonics(afm_lcm_digest *d, const afmtwin_harmonics_t *m) {
    uint64_t h = d->harmonics;
    h = mix(h, (uint64_t)m->seq_applied);
    h = mix(h, bits_d(m->t_s));
    h = mix(h, bits_d(m->fe_hz));
    h = mix(h, (uint64_t)m->n);
    for (int i = 0; i < m->n; i++) {
        h = mix(h, (uint64_t)(uint16_t)m->k[i]);
        h = mix(h, bits_d(m->deflection_amplitude_m[i]));
        h = mix(h, bits_d(m->deflection_phase_deg[i]));
        h = mix(h, bits_d(m->force_amplitude_n[i]));
        h = mix(h, bits_d(m->force_phase_deg[i]));
        h = mix(h, bits_d(m->phase_diff_deg[i]));
    }
    const double rest[] = {
        m->lockin_amplitude_m,         m->lockin_phase_deg,    m->peak_force_n,
        m->min_deflection_m,           m->indentation_m,       m->contact_time_s,
        m->pre_contact_velocity_m_s,   m->dissipated_energy_j, m->mean_deflection_m,
        m->squeeze_dissipated_energy_j};
    for (size_t i = 0; i < sizeof rest / sizeof rest[0]; i++)
        h = mix(h, bits_d(rest[i]));
    d->harmonics = h;
    d->n_harmonics_msgs++;
}

uint64_t afm_lcm_digest_samples_final(const afm_lcm_digest *d) {
    uint64_t h = DIGEST_SEED;
    for (int i = 0; i < AFM_LCM_DIGEST_STREAMS; i++)
        h = mix(h, d->stream[i]);
    return h;
}
